//! Steps 5-6 of FindAction: incremental k-means of the uncertain samples and the elbow
//! rule that picks `k`.

use heapless::Vec as FixedVec;
use nalgebra::{Point3, Vector3};

use super::*;
use crate::{
    Intrinsics, MAX_CLUSTERS,
    math::{Real, ln},
    rng::Pcg32,
};

/// Lloyd stops when an update would move the centres by less than this in total
/// (root of the summed squared shifts), pixels: the push is planned at pixel resolution.
pub(super) const LLOYD_TOL_PX: Real = 0.25;
/// Smallest normalised drop below the chord that counts as an elbow.
const KNEE_MIN: Real = 0.01;

type Centres = [[Real; 2]; MAX_CLUSTERS];

/// `2 + ⌊ln k⌋` for `k <= 20`: candidates per new centre in greedy k-means++.
const fn seeding_trials(k: usize) -> usize {
    2 + (k >= 3) as usize + (k >= 8) as usize
}

/// Squared pixel distance from `(x, y)` to `c`.
#[inline]
pub(super) fn dist2_to(x: Real, y: Real, c: [Real; 2]) -> Real {
    let (dx, dy) = (x - c[0], y - c[1]);
    dx * dx + dy * dy
}

/// Sum with eight interleaved accumulators combined in a fixed order: vectorises, and
/// is still the same on every target (no reassociation is left to the compiler).
fn lane_sum(v: &[Real]) -> Real {
    let mut acc = [0.0 as Real; 8];
    let chunks = v.chunks_exact(8);
    let tail = chunks.remainder();
    for chunk in chunks {
        for (a, &d) in acc.iter_mut().zip(chunk) {
            *a += d;
        }
    }
    let [a0, a1, a2, a3, a4, a5, a6, a7] = acc;
    let mut total = ((a0 + a4) + (a1 + a5)) + ((a2 + a6) + (a3 + a7));
    for &d in tail {
        total += d;
    }
    total
}

/// k-means over caller scratch (`dist2`, `nearest`: exactly one entry per sample).
pub(super) struct KMeans<'s> {
    pub(super) dist2: &'s mut [Real],
    pub(super) nearest: &'s mut [u32],
    pub(super) iters: u32,
}

impl KMeans<'_> {
    /// Sets `dist2`/`nearest` to each sample's nearest centre (ties: lower index).
    ///
    /// Centre-outer, sample-inner, with selects written as bit masks so the inner loop
    /// vectorises instead of becoming conditional stores.
    fn assign(&mut self, s: &Samples<'_>, centres: &[[Real; 2]]) {
        let Some((&c0, rest)) = centres.split_first() else {
            return;
        };
        for (((&x, &y), d2), nj) in
            s.x.iter()
                .zip(s.y)
                .zip(self.dist2.iter_mut())
                .zip(self.nearest.iter_mut())
        {
            *d2 = dist2_to(x, y, c0);
            *nj = 0;
        }
        for (j, &c) in (1u32..).zip(rest) {
            for (((&x, &y), d2), nj) in
                s.x.iter()
                    .zip(s.y)
                    .zip(self.dist2.iter_mut())
                    .zip(self.nearest.iter_mut())
            {
                let d = dist2_to(x, y, c);
                let mask = u32::from(d < *d2).wrapping_neg();
                *d2 = Real::from_bits((d.to_bits() & mask) | (d2.to_bits() & !mask));
                *nj = (j & mask) | (*nj & !mask);
            }
        }
    }

    /// Member sums `[x, y]` and counts per centre of the current assignment.
    ///
    /// Four interleaved sets of accumulators (samples `i mod 4`), combined in a fixed
    /// order: neighbouring samples mostly share a cluster, and one set would make every
    /// addition wait for the previous one.
    pub(super) fn sums(
        &self,
        s: &Samples<'_>,
    ) -> ([[Real; 2]; MAX_CLUSTERS], [usize; MAX_CLUSTERS]) {
        // Indices are masked to the array size (a power of two): never out of bounds, and
        // the mask is a no-op for real cluster indices (< MAX_CLUSTERS).
        const MASK: usize = MAX_CLUSTERS - 1;
        const _: () = assert!(MAX_CLUSTERS.is_power_of_two());
        let mut sets = [([[0.0 as Real; 2]; MAX_CLUSTERS], [0usize; MAX_CLUSTERS]); 4];
        let (xs, ys, ns) = (
            s.x.chunks_exact(4),
            s.y.chunks_exact(4),
            self.nearest.chunks_exact(4),
        );
        let (xt, yt, nt) = (xs.remainder(), ys.remainder(), ns.remainder());
        for ((xc, yc), nc) in xs.zip(ys).zip(ns) {
            for (((set, &x), &y), &nj) in sets.iter_mut().zip(xc).zip(yc).zip(nc) {
                let (sums, counts) = set;
                let j = nj as usize & MASK;
                sums[j][0] += x;
                sums[j][1] += y;
                counts[j] += 1;
            }
        }
        for (((set, &x), &y), &nj) in sets.iter_mut().zip(xt).zip(yt).zip(nt) {
            let (sums, counts) = set;
            let j = nj as usize & MASK;
            sums[j][0] += x;
            sums[j][1] += y;
            counts[j] += 1;
        }
        let [(s0, c0), (s1, c1), (s2, c2), (s3, c3)] = &sets;
        let sums = core::array::from_fn(|j| {
            let (a, b, c, d) = (s0[j], s1[j], s2[j], s3[j]);
            [(a[0] + b[0]) + (c[0] + d[0]), (a[1] + b[1]) + (c[1] + d[1])]
        });
        let counts = core::array::from_fn(|j| c0[j] + c1[j] + c2[j] + c3[j]);
        (sums, counts)
    }

    /// Lloyd iterations from `centres` until an update would move them by at most
    /// [`LLOYD_TOL_PX`] in total, or `iters` updates were made. Leaves the assignment made
    /// by the final `centres` in `dist2`/`nearest`; returns its inertia (pixels²).
    fn lloyd(&mut self, s: &Samples<'_>, centres: &mut [[Real; 2]]) -> Real {
        self.assign(s, centres);
        for _ in 0..self.iters {
            let (sums, counts) = self.sums(s);
            let mut means: Centres = [[0.0; 2]; MAX_CLUSTERS];
            let mut shift2 = 0.0;
            for (((m, c), sum), &count) in
                means.iter_mut().zip(centres.iter()).zip(&sums).zip(&counts)
            {
                *m = *c;
                if count > 0 {
                    let inv = 1.0 / count as Real;
                    *m = [sum[0] * inv, sum[1] * inv];
                    shift2 += dist2_to(m[0], m[1], *c);
                }
            }
            // Converged: keep the centres that made the current assignment.
            if shift2 <= LLOYD_TOL_PX * LLOYD_TOL_PX {
                break;
            }
            for (c, m) in centres.iter_mut().zip(&means) {
                *c = *m;
            }
            self.assign(s, centres);
        }
        lane_sum(self.dist2)
    }

    /// Greedy k-means++ step: a new centre drawn with probability proportional to
    /// `dist2` (the squared distance to the nearest current centre), best of `trials`
    /// draws by the resulting inertia. `None` when every sample sits on a centre.
    fn draw_centre(&self, s: &Samples<'_>, trials: usize, rng: &mut Pcg32) -> Option<[Real; 2]> {
        let potential = lane_sum(self.dist2);
        if potential.is_nan() || potential <= 0.0 {
            return None;
        }
        let mut best: Option<(Real, [Real; 2])> = None;
        for _ in 0..trials {
            let r = rng.unit() * potential;
            let mut acc = 0.0;
            let mut pick = None;
            for (i, &d2) in self.dist2.iter().enumerate() {
                if d2 > 0.0 {
                    acc += d2;
                    pick = Some(i);
                    if acc > r {
                        break;
                    }
                }
            }
            let c = s.get(pick?)?;
            let mut acc = [0.0 as Real; 8];
            let (xs, ys, ds) = (
                s.x.chunks_exact(8),
                s.y.chunks_exact(8),
                self.dist2.chunks_exact(8),
            );
            let (xt, yt, dt) = (xs.remainder(), ys.remainder(), ds.remainder());
            for ((xc, yc), dc) in xs.zip(ys).zip(ds) {
                for (((a, &x), &y), &d2) in acc.iter_mut().zip(xc).zip(yc).zip(dc) {
                    *a += d2.min(dist2_to(x, y, c));
                }
            }
            let mut pot = lane_sum(&acc);
            for ((&x, &y), &d2) in xt.iter().zip(yt).zip(dt) {
                pot += d2.min(dist2_to(x, y, c));
            }
            if best.is_none_or(|(b, _)| pot < b) {
                best = Some((pot, c));
            }
        }
        best.map(|(_, c)| c)
    }

    /// Clusters one class with the elbow-chosen `k`; returns its non-empty clusters.
    pub(super) fn cluster_class(
        &mut self,
        s: &Samples<'_>,
        intrinsics: &Intrinsics,
        max_clusters: usize,
        rng: &mut Pcg32,
    ) -> FixedVec<Cluster, MAX_CLUSTERS> {
        let mut out = FixedVec::new();
        let n = s.len();
        let k_max = max_clusters.min(MAX_CLUSTERS).min(n);
        let (Some(dist2), Some(nearest), true) = (
            self.dist2.get_mut(..n),
            self.nearest.get_mut(..n),
            k_max > 0,
        ) else {
            return out;
        };
        // Scratch cut to exactly one entry per sample, so whole-slice sums are sample sums.
        let mut km = KMeans {
            dist2,
            nearest,
            iters: self.iters,
        };
        // k = 1 starts from a seeded sample; each further k keeps the converged centres
        // of k − 1 and adds one greedy k-means++ centre (incremental seeding).
        let mut all_centres = [[[0.0 as Real; 2]; MAX_CLUSTERS]; MAX_CLUSTERS];
        let mut inertia = [0.0 as Real; MAX_CLUSTERS];
        let mut centres: Centres = [[0.0; 2]; MAX_CLUSTERS];
        let mut tried = 0;
        for (k0, (centres_k, inertia_k)) in all_centres
            .iter_mut()
            .zip(inertia.iter_mut())
            .take(k_max)
            .enumerate()
        {
            let new = if k0 == 0 {
                s.get(below_usize(rng, n))
            } else {
                km.draw_centre(s, seeding_trials(k0 + 1), rng)
            };
            let (Some(new), Some(slot)) = (new, centres.get_mut(k0)) else {
                break;
            };
            *slot = new;
            let Some(used) = centres.get_mut(..=k0) else {
                break;
            };
            *inertia_k = km.lloyd(s, used);
            *centres_k = centres;
            tried = k0 + 1;
        }
        // Inertia of pixel quantisation: 1/12 px² per axis and sample.
        let noise_floor = n as Real / 6.0;
        let k = elbow(inertia.get(..tried).unwrap_or(&[]), noise_floor);
        let Some(centres) = k
            .checked_sub(1)
            .and_then(|i| all_centres.get(i))
            .and_then(|c| c.get(..k))
        else {
            return out;
        };
        km.assign(s, centres);

        let mut sums = [Vector3::<Real>::zeros(); MAX_CLUSTERS];
        let mut counts = [0usize; MAX_CLUSTERS];
        for (((&x, &y), &z), &nj) in s.x.iter().zip(s.y).zip(s.z).zip(km.nearest.iter()) {
            let j = nj as usize;
            if let (Some(sum), Some(count)) = (sums.get_mut(j), counts.get_mut(j)) {
                *sum += intrinsics.back_project(x, y, z).coords;
                *count += 1;
            }
        }
        for ((c, sum), &count) in centres.iter().zip(&sums).zip(&counts) {
            if count > 0 {
                let cluster = Cluster {
                    centre_px: *c,
                    centre_cam_m: Point3::from(sum / count as Real),
                    samples: u32::try_from(count).unwrap_or(u32::MAX),
                };
                // Capacity is MAX_CLUSTERS and k <= MAX_CLUSTERS, so this cannot fail.
                let _ = out.push(cluster);
            }
        }
        out
    }
}

/// Chooses `k` from the inertia curve `inertia[k − 1] = W(k)`, `k = 1..=K`, by the elbow
/// rule of the module docs (Kneedle on `ln(W + noise_floor)`; `W(2) <= W(1)/2` when
/// `K = 2`). Returns `0` only for an empty curve.
pub(super) fn elbow(inertia: &[Real], noise_floor: Real) -> usize {
    let (Some(&first), Some(&last)) = (inertia.first(), inertia.last()) else {
        return 0;
    };
    match inertia.len() {
        1 => 1,
        2 => {
            if last <= 0.5 * first {
                2
            } else {
                1
            }
        }
        n => {
            let log = |w: Real| ln(w.max(0.0) + noise_floor);
            let (log_first, log_last) = (log(first), log(last));
            let span = log_first - log_last;
            if !(span > 0.0 && span.is_finite()) {
                return 1;
            }
            let x_scale = 1.0 / (n - 1) as Real;
            let mut best_k = 1;
            let mut best_score = KNEE_MIN;
            for (k0, &w) in inertia.iter().enumerate() {
                let x = k0 as Real * x_scale;
                let y = (log(w) - log_last) / span;
                let score = 1.0 - x - y;
                if score > best_score {
                    best_score = score;
                    best_k = k0 + 1;
                }
            }
            best_k
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use std::vec::Vec;

    use super::*;

    #[test]
    fn elbow_rule() {
        assert_eq!(elbow(&[], 0.0), 0);
        assert_eq!(elbow(&[5.0], 0.0), 1);
        assert_eq!(elbow(&[10.0, 4.0], 0.0), 2);
        assert_eq!(elbow(&[10.0, 6.0], 0.0), 1);
        // Three well-separated groups: big drops up to k = 3, then a flat tail.
        let three = [100.0, 60.0, 5.0, 4.0, 3.5, 3.0, 2.5, 2.0];
        assert_eq!(elbow(&three, 0.0), 3);
        // Six touching objects (a measured curve): the raw-curve Kneedle would say 2.
        let six = [1.0, 0.422, 0.315, 0.217, 0.151, 0.09, 0.085, 0.079];
        assert_eq!(elbow(&six, 0.0), 6);
        // Constant ratio (a straight line in log) and a straight line have no elbow;
        // neither has a flat curve.
        let halving: Vec<Real> = (0..8).map(|i| 0.5f32.powi(i)).collect();
        assert_eq!(elbow(&halving, 0.0), 1);
        assert_eq!(elbow(&[8.0, 7.0, 6.0, 5.0, 4.0, 3.0, 2.0, 1.0], 0.0), 1);
        assert_eq!(elbow(&[1.0, 1.0, 1.0], 0.0), 1);
        assert_eq!(elbow(&[Real::NAN, 1.0, 0.0], 1.0), 1);
        // A perfect fit stays finite through the noise floor.
        assert_eq!(elbow(&[100.0, 60.0, 0.0, 0.0, 0.0], 1.0), 3);
    }
}
