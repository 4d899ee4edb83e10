//! Steps 1-2 of FindAction: pixel classes and systematic sampling of each class.

use crate::{
    Config,
    image::{ImageView, valid_depth},
    math::Real,
    rng::Pcg32,
};

/// Pixel class of one heatmap value.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Class {
    Certain,
    Uncertain,
    Other,
}

fn class_of(heat: u8, cfg: &Config) -> Class {
    if heat >= cfg.certain_from {
        Class::Certain
    } else if heat >= cfg.uncertain_from {
        Class::Uncertain
    } else {
        Class::Other
    }
}

/// Uniform in `0..n` (`0` when `n == 0`), from 64 random bits.
pub(super) fn below_usize(rng: &mut Pcg32, n: usize) -> usize {
    let r = (u64::from(rng.next_u32()) << 32) | u64::from(rng.next_u32());
    ((u128::from(r) * n as u128) >> 64) as usize
}

/// Sample coordinates as three planes of equal length.
pub(super) struct Planes<'a> {
    pub(super) x: &'a mut [Real],
    pub(super) y: &'a mut [Real],
    pub(super) z: &'a mut [Real],
}

/// Read-only view of the first samples of [`Planes`].
pub(super) struct Samples<'a> {
    pub(super) x: &'a [Real],
    pub(super) y: &'a [Real],
    pub(super) z: &'a [Real],
}

impl<'a> Planes<'a> {
    /// Splits `buf` into three planes of `n` entries; `None` if it is shorter than `3·n`.
    pub(super) fn split(buf: &'a mut [Real], n: usize) -> Option<Self> {
        let (x, rest) = buf.split_at_mut_checked(n)?;
        let (y, rest) = rest.split_at_mut_checked(n)?;
        let z = rest.get_mut(..n)?;
        Some(Self { x, y, z })
    }

    pub(super) fn prefix(&self, n: usize) -> Samples<'_> {
        let n = n.min(self.x.len()).min(self.y.len()).min(self.z.len());
        Samples {
            x: self.x.get(..n).unwrap_or(&[]),
            y: self.y.get(..n).unwrap_or(&[]),
            z: self.z.get(..n).unwrap_or(&[]),
        }
    }
}

impl Samples<'_> {
    pub(super) const fn len(&self) -> usize {
        self.x.len()
    }

    pub(super) fn get(&self, i: usize) -> Option<[Real; 2]> {
        Some([*self.x.get(i)?, *self.y.get(i)?])
    }
}

/// Systematic sampling: of `total` items offered in order, keeps the items at
/// `⌊(m·total + offset) / take⌋`, `m = 0..take`, with `offset` uniform in `0..total`
/// (all items when `total <= take`). Each item is kept with probability `take / total`.
struct Sampler {
    pub(super) total: usize,
    pub(super) take: usize,
    pub(super) offset: usize,
    /// Slot of the next kept item (= items kept so far).
    pub(super) next_slot: usize,
    /// Index (among offered items) of the next kept item.
    pub(super) next_index: usize,
    /// Items offered so far.
    pub(super) seen: usize,
}

impl Sampler {
    pub(super) fn new(total: usize, cap: usize, rng: &mut Pcg32) -> Self {
        let take = total.min(cap);
        let offset = below_usize(rng, total);
        let mut s = Self {
            total,
            take,
            offset,
            next_slot: 0,
            next_index: 0,
            seen: 0,
        };
        s.next_index = s.index_of(0);
        s
    }

    fn index_of(&self, slot: usize) -> usize {
        if self.total <= self.take {
            slot
        } else {
            let i = (slot as u128 * self.total as u128 + self.offset as u128) / self.take as u128;
            usize::try_from(i).unwrap_or(usize::MAX)
        }
    }

    /// Whether the next kept item lies among the next `count` offered items.
    const fn wants_any_of(&self, count: usize) -> bool {
        self.next_slot < self.take && self.next_index < self.seen.saturating_add(count)
    }

    /// Skips `count` items, none of which is kept (see [`Sampler::wants_any_of`]).
    pub(super) const fn skip(&mut self, count: usize) {
        self.seen = self.seen.saturating_add(count);
    }

    /// Offers the next item; returns the slot to store it in if it is kept.
    fn offer(&mut self) -> Option<usize> {
        let index = self.seen;
        self.seen = self.seen.saturating_add(1);
        if self.next_slot < self.take && index == self.next_index {
            let slot = self.next_slot;
            self.next_slot += 1;
            self.next_index = self.index_of(self.next_slot);
            Some(slot)
        } else {
            None
        }
    }
}

/// Counts the certain and uncertain pixels with a depth reading in one row (branch-free,
/// so it vectorises).
fn count_row(heat: &[u8], depth: &[Real], cfg: &Config) -> (usize, usize) {
    let (certain_from, uncertain_from) = (cfg.certain_from, cfg.uncertain_from);
    let (mut certain, mut uncertain) = (0usize, 0usize);
    // u32 lane counters, flushed every 2^16 pixels.
    for (hc, dc) in heat.chunks(1 << 16).zip(depth.chunks(1 << 16)) {
        let (mut c, mut u) = (0u32, 0u32);
        for (&h, &z) in hc.iter().zip(dc) {
            // `0 < z < ∞` on the bits: one unsigned compare; NaN and negatives fail.
            let valid = z.to_bits().wrapping_sub(1) < Real::INFINITY.to_bits() - 1;
            c += u32::from(valid & (h >= certain_from));
            u += u32::from(valid & (h >= uncertain_from) & (h < certain_from));
        }
        certain += c as usize;
        uncertain += u as usize;
    }
    (certain, uncertain)
}

/// Draws the samples of both classes; returns how many of each were stored.
///
/// The first pass counts each row's class pixels into `row_counts` (pairs certain,
/// uncertain); the second visits pixel by pixel only the rows that hold a kept sample.
pub(super) fn sample_classes<'a>(
    heatmap: &ImageView<'_, u8>,
    depth: &ImageView<'_, Real>,
    cfg: &Config,
    rng: &mut Pcg32,
    certain: &mut Planes<'a>,
    uncertain: &mut Planes<'a>,
    row_counts: &mut [u32],
) -> (usize, usize) {
    let rows = || (0..heatmap.height()).filter_map(|y| Some((y, heatmap.row(y)?, depth.row(y)?)));
    let (mut n_certain, mut n_uncertain) = (0usize, 0usize);
    for ((_, heat_row, depth_row), counts) in rows().zip(row_counts.chunks_exact_mut(2)) {
        let (c, u) = count_row(heat_row, depth_row, cfg);
        n_certain += c;
        n_uncertain += u;
        // A saturated count (rows wider than u32::MAX) is recounted below.
        counts[0] = u32::try_from(c).unwrap_or(u32::MAX);
        counts[1] = u32::try_from(u).unwrap_or(u32::MAX);
    }
    let mut certain_sampler = Sampler::new(n_certain, certain.x.len(), rng);
    let mut uncertain_sampler = Sampler::new(n_uncertain, uncertain.x.len(), rng);
    for ((y, heat_row, depth_row), counts) in rows().zip(row_counts.chunks_exact(2)) {
        let (c, u) = match *counts {
            [c, u] if c < u32::MAX && u < u32::MAX => (c as usize, u as usize),
            _ => count_row(heat_row, depth_row, cfg),
        };
        if !certain_sampler.wants_any_of(c) && !uncertain_sampler.wants_any_of(u) {
            certain_sampler.skip(c);
            uncertain_sampler.skip(u);
            continue;
        }
        for (x, (&heat, &z)) in heat_row.iter().zip(depth_row).enumerate() {
            let Some(z) = valid_depth(z) else { continue };
            let (sampler, planes) = match class_of(heat, cfg) {
                Class::Certain => (&mut certain_sampler, &mut *certain),
                Class::Uncertain => (&mut uncertain_sampler, &mut *uncertain),
                Class::Other => continue,
            };
            if let Some(slot) = sampler.offer()
                && let (Some(px), Some(py), Some(pz)) = (
                    planes.x.get_mut(slot),
                    planes.y.get_mut(slot),
                    planes.z.get_mut(slot),
                )
            {
                (*px, *py, *pz) = (x as Real, y as Real, z);
            }
        }
    }
    (certain_sampler.next_slot, uncertain_sampler.next_slot)
}

#[cfg(test)]
mod tests {
    extern crate std;

    use std::{vec, vec::Vec};

    use super::*;

    #[test]
    fn row_skipping_sampler_matches_offering_every_pixel() {
        let (w, h) = (37, 23);
        let mut rng = Pcg32::new(5);
        let heat: Vec<u8> = (0..w * h).map(|_| rng.below(256) as u8).collect();
        let depth: Vec<Real> = (0..w * h)
            .map(|_| [0.6, Real::NAN, 0.0, 0.7][rng.below(4) as usize])
            .collect();
        let (hv, dv) = (
            ImageView::packed(w, h, &heat).unwrap(),
            ImageView::packed(w, h, &depth).unwrap(),
        );
        let cfg = Config::PAPER;
        for cap in [1, 7, 50, 10_000] {
            let mut bufs = [vec![0.0; 3 * cap], vec![0.0; 3 * cap]];
            let [cb, ub] = &mut bufs;
            let (mut cp, mut up) = (
                Planes::split(cb, cap).unwrap(),
                Planes::split(ub, cap).unwrap(),
            );
            let mut rows = vec![0u32; 2 * h];
            let (nc, nu) = sample_classes(
                &hv,
                &dv,
                &cfg,
                &mut Pcg32::new(9),
                &mut cp,
                &mut up,
                &mut rows,
            );
            // Reference: offer every pixel of each class in row-major order.
            let mut rng = Pcg32::new(9);
            let class_px = |want: Class| -> Vec<[Real; 3]> {
                hv.pixels()
                    .filter(|&(x, y, &v)| {
                        class_of(v, &cfg) == want && valid_depth(*dv.get(x, y).unwrap()).is_some()
                    })
                    .map(|(x, y, _)| [x as Real, y as Real, *dv.get(x, y).unwrap()])
                    .collect()
            };
            let (all_c, all_u) = (class_px(Class::Certain), class_px(Class::Uncertain));
            let mut sc = Sampler::new(all_c.len(), cap, &mut rng);
            let mut su = Sampler::new(all_u.len(), cap, &mut rng);
            let want_c: Vec<_> = all_c.iter().filter(|_| sc.offer().is_some()).collect();
            let want_u: Vec<_> = all_u.iter().filter(|_| su.offer().is_some()).collect();
            assert_eq!((nc, nu), (want_c.len(), want_u.len()), "cap {cap}");
            for (i, p) in want_c.iter().enumerate() {
                assert_eq!([cp.x[i], cp.y[i], cp.z[i]], **p, "cap {cap}");
            }
            for (i, p) in want_u.iter().enumerate() {
                assert_eq!([up.x[i], up.y[i], up.z[i]], **p, "cap {cap}");
            }
        }
    }

    #[test]
    fn sampling_keeps_the_requested_count_in_order() {
        let mut rng = Pcg32::new(3);
        for (total, cap) in [(0, 5), (3, 5), (5, 5), (1000, 7), (7, 6), (10_000, 2000)] {
            let mut s = Sampler::new(total, cap, &mut rng);
            let mut kept = Vec::new();
            for i in 0..total {
                if let Some(slot) = s.offer() {
                    assert_eq!(slot, kept.len());
                    kept.push(i);
                }
            }
            assert_eq!(kept.len(), total.min(cap), "total {total} cap {cap}");
            assert!(kept.windows(2).all(|p| p[0] < p[1]));
        }
    }
}
