//! Scene seeds: how a dataset seed becomes one simulator seed per scene, and the retry
//! loop `riseg gen` and `riseg bench` share when a seed gives no usable scene.
//!
//! Scene `i` of dataset seed `S` starts from [`scene_seed`]`(S, i)`. Attempt 1 of a scene
//! seed `s` simulates `s` itself, attempt `k > 1` simulates `scene_seed(s, k − 1)`
//! ([`attempt_seed`]), at most [`MAX_SCENE_ATTEMPTS`] attempts. All of it is
//! deterministic, so a dataset seed names the same scenes on every machine.

/// Simulation attempts per scene before a caller gives up.
pub const MAX_SCENE_ATTEMPTS: u32 = 20;

/// The seed of scene `index` in a dataset with seed `dataset_seed` (splitmix64 of both).
#[must_use]
pub fn scene_seed(dataset_seed: u64, index: usize) -> u64 {
    let mut z = dataset_seed ^ (index as u64).wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The simulator seed of attempt `attempt` (counted from 0) at scene seed `seed`: `seed`
/// itself first, then [`scene_seed`]`(seed, attempt)`.
#[must_use]
pub fn attempt_seed(seed: u64, attempt: u32) -> u64 {
    if attempt == 0 {
        seed
    } else {
        scene_seed(seed, attempt as usize)
    }
}

/// The first usable attempt found by [`first_usable_seed`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Seeded<T> {
    /// What the accepted attempt built.
    pub value: T,
    /// The simulator seed of that attempt ([`attempt_seed`]).
    pub seed: u64,
    /// Attempts made, that one included (1 = the first was usable).
    pub attempts: u32,
}

/// Runs `attempt` on the attempt seeds of scene seed `seed` in order ([`attempt_seed`])
/// until one is usable, at most [`MAX_SCENE_ATTEMPTS`] times. `attempt` returns
/// `Ok(Ok(value))` for a usable scene, `Ok(Err(reason))` for an unusable one (try the
/// next seed) and `Err(e)` for a failure that ends the search.
///
/// # Errors
/// The first `Err(e)` of `attempt`. `Ok(Err(reason))` with the last reason when every
/// attempt was unusable.
pub fn first_usable_seed<T, R, E>(
    seed: u64,
    mut attempt: impl FnMut(u64) -> Result<Result<T, R>, E>,
) -> Result<Result<Seeded<T>, R>, E> {
    let mut n = 0;
    loop {
        let s = attempt_seed(seed, n);
        n += 1;
        match attempt(s)? {
            Ok(value) => {
                return Ok(Ok(Seeded {
                    value,
                    seed: s,
                    attempts: n,
                }));
            }
            Err(reason) if n >= MAX_SCENE_ATTEMPTS => return Ok(Err(reason)),
            Err(_) => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn attempts_follow_the_seed_sequence() {
        let mut tried = Vec::new();
        let found = first_usable_seed(7, |s| {
            tried.push(s);
            Ok::<_, ()>(if tried.len() == 3 { Ok(s) } else { Err(()) })
        })
        .unwrap()
        .unwrap();
        assert_eq!(tried, [7, scene_seed(7, 1), scene_seed(7, 2)]);
        assert_eq!(
            (found.value, found.seed, found.attempts),
            (tried[2], tried[2], 3)
        );
    }

    #[test]
    fn gives_up_with_the_last_reason_or_stops_at_an_error() {
        let mut n = 0;
        let out = first_usable_seed(1, |_| {
            n += 1;
            Ok::<Result<(), u32>, ()>(Err(n))
        });
        assert_eq!(out, Ok(Err(MAX_SCENE_ATTEMPTS)));
        let mut calls = 0;
        let out = first_usable_seed(1, |_| {
            calls += 1;
            Err::<Result<(), ()>, _>("broken")
        });
        assert_eq!((out, calls), (Err("broken"), 1));
    }
}
