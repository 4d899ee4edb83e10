//! Step 7 of FindAction: which pairs of certain clusters qualify, and their ranking.

use heapless::Vec as FixedVec;
use nalgebra::Point3;

use super::*;
use crate::{
    Config, MAX_CLUSTERS,
    image::ImageView,
    math::{Real, round, sqrt},
};

/// Most table the line between the two centres of a pair may cross, metres: where two
/// rounded objects touch at a point, the line clips the corners of their rims.
const LINE_TABLE_MAX_M: Real = 0.005;
/// Most certain pairs: every pair of [`MAX_CLUSTERS`] clusters.
const MAX_PAIRS: usize = MAX_CLUSTERS * (MAX_CLUSTERS - 1) / 2;

/// What a pixel is to the walk of the push.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Px {
    /// Off the image.
    Off,
    /// Heat below [`Config::uncertain_from`]: not an object.
    Background,
    /// An uncertain pixel, or a certain pixel in no cluster.
    Object,
    /// A certain pixel of this cluster.
    Cluster(usize),
}

/// Which cluster each certain pixel belongs to (module docs, step 9).
pub(super) struct RegionMap<'a> {
    pub(super) heatmap: &'a ImageView<'a, u8>,
    pub(super) runs: Runs<'a>,
    pub(super) row_runs: &'a [u32],
    pub(super) clusters: &'a [Cluster],
    pub(super) region_of: &'a [u32],
    pub(super) cfg: &'a Config,
}

impl RegionMap<'_> {
    pub(super) fn at(&self, x: i64, y: i64) -> Px {
        let Some(heat) = self.heatmap.at(x, y) else {
            return Px::Off;
        };
        if heat < self.cfg.uncertain_from {
            return Px::Background;
        }
        if heat < self.cfg.certain_from {
            return Px::Object;
        }
        // On the image, so both are non-negative.
        let region = self.runs.region_at(self.row_runs, x as usize, y as usize);
        let mut best: Option<(Real, usize)> = None;
        for (i, (c, &r)) in self.clusters.iter().zip(self.region_of).enumerate() {
            if r == region && region != NONE {
                let d = dist2_to(x as Real, y as Real, c.centre_px);
                if best.is_none_or(|(b, _)| d < b) {
                    best = Some((d, i));
                }
            }
        }
        best.map_or(Px::Object, |(_, i)| Px::Cluster(i))
    }
}

/// Whether the straight line between the pixel centres of clusters `i` and `j` stays on
/// object (module docs, step 7): every pixel on it is in `i` or `j`, uncertain, or certain
/// in no cluster, except at most [`LINE_TABLE_MAX_M`] of it (with the line's length taken
/// as `pair_dist_m`) on the table; none is off the image or in a third cluster. `None`
/// when it does not; else whether a pixel on it is uncertain (the line crosses a band or
/// cut of the heatmap).
fn line_on_objects(map: &RegionMap<'_>, i: usize, j: usize, pair_dist_m: Real) -> Option<bool> {
    let (a, b) = (map.clusters.get(i)?, map.clusters.get(j)?);
    let (dx, dy) = (
        b.centre_px[0] - a.centre_px[0],
        b.centre_px[1] - a.centre_px[1],
    );
    let len = sqrt(dx * dx + dy * dy);
    if !len.is_finite() {
        return None;
    }
    // One step per pixel of length; centres lie on the image, so the line is shorter
    // than width + height.
    let (width, height) = map.heatmap.size();
    let steps = (len as usize)
        .saturating_add(1)
        .min(width.saturating_add(height));
    let step_m = pair_dist_m / steps.max(1) as Real;
    let mut table_m = 0.0;
    let mut crossed = false;
    for s in 0..=steps {
        let t = s as Real / steps.max(1) as Real;
        let pixel = (
            round(a.centre_px[0] + t * dx) as i64,
            round(a.centre_px[1] + t * dy) as i64,
        );
        match map.at(pixel.0, pixel.1) {
            Px::Cluster(q) if q == i || q == j => {}
            Px::Object => {
                crossed |= map
                    .heatmap
                    .at(pixel.0, pixel.1)
                    .is_some_and(|h| h < map.cfg.certain_from);
            }
            Px::Background => {
                table_m += step_m;
                if table_m.is_nan() || table_m > LINE_TABLE_MAX_M {
                    return None;
                }
            }
            Px::Cluster(_) | Px::Off => return None,
        }
    }
    Some(crossed)
}

/// Whether `pair` qualified only as a seam pair: no uncertain centre within
/// [`Config::uncertain_max_m`] of it (module docs, step 7).
pub(super) fn is_seam(pair: &Pair, cfg: &Config) -> bool {
    pair.uncertain_dist_m > cfg.uncertain_max_m || pair.uncertain_dist_m.is_nan()
}

/// Whether `i` and `j` are neighbours in the relative neighbourhood graph of the certain
/// 3-D centres: no third centre is closer to both than they are to each other.
fn relative_neighbours(certain: &[Cluster], i: usize, j: usize) -> bool {
    let (Some(ci), Some(cj)) = (certain.get(i), certain.get(j)) else {
        return false;
    };
    let d_ij = (cj.centre_cam_m - ci.centre_cam_m).norm();
    certain.iter().enumerate().all(|(k, c)| {
        k == i
            || k == j
            || !((c.centre_cam_m - ci.centre_cam_m).norm() < d_ij
                && (c.centre_cam_m - cj.centre_cam_m).norm() < d_ij)
    })
}

/// 3-D distance from `p` to the segment `a b`.
fn segment_dist(p: &Point3<Real>, a: &Point3<Real>, b: &Point3<Real>) -> Real {
    let ab = b - a;
    let ap = p - a;
    let len2 = ab.norm_squared();
    let t = if len2 > 0.0 {
        (ap.dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (ap - ab * t).norm()
}

/// Every qualifying certain pair, best first (module docs, step 7).
pub(super) fn rank_pairs(
    map: &RegionMap<'_>,
    uncertain: &[Cluster],
    cfg: &Config,
) -> FixedVec<Pair, MAX_PAIRS> {
    let certain = map.clusters;
    let mut pairs: FixedVec<Pair, MAX_PAIRS> = FixedVec::new();
    for (i, ci) in certain.iter().enumerate() {
        for (j, cj) in certain.iter().enumerate().skip(i + 1) {
            let pair_dist_m = (cj.centre_cam_m - ci.centre_cam_m).norm();
            if pair_dist_m.is_nan() || pair_dist_m > cfg.pair_max_m {
                continue;
            }
            let mut nearest: Option<(Real, usize)> = None;
            for (n, u) in uncertain.iter().enumerate() {
                let d = segment_dist(&u.centre_cam_m, &ci.centre_cam_m, &cj.centre_cam_m);
                if !d.is_nan() && nearest.is_none_or(|(b, _)| d < b) {
                    nearest = Some((d, n));
                }
            }
            // Two pieces of one certain region split by its metric size (step 4) need no
            // cut between them, nor any uncertain centre: the size is the evidence that
            // the region holds two objects.
            let pieces = map
                .region_of
                .get(i)
                .zip(map.region_of.get(j))
                .is_some_and(|(a, b)| a == b && *a != NONE);
            let (uncertain_dist_m, n) = match nearest {
                Some((d, n)) => (d, Some(n)),
                None if pieces => (Real::INFINITY, None),
                None => continue,
            };
            // Beyond d_b only a seam pair, with the push choice of step 8 on.
            let seam = uncertain_dist_m > cfg.uncertain_max_m;
            if seam && cfg.push_carry_frac <= 0.0 {
                continue;
            }
            if !relative_neighbours(certain, i, j) {
                continue;
            }
            match line_on_objects(map, i, j, pair_dist_m) {
                Some(crossed) if crossed || !seam || pieces => {}
                _ => continue,
            }
            let (pushed, other) = if cj.samples < ci.samples {
                (j, i)
            } else {
                (i, j)
            };
            let _ = pairs.push(Pair {
                pushed,
                other,
                uncertain: n,
                pair_dist_m,
                uncertain_dist_m,
            });
        }
    }
    // Nearest uncertain centre first, then the closer pair, then (i, j) order.
    let order = |p: &Pair| (p.pushed.min(p.other), p.pushed.max(p.other));
    pairs.sort_unstable_by(|a, b| {
        a.uncertain_dist_m
            .total_cmp(&b.uncertain_dist_m)
            .then(a.pair_dist_m.total_cmp(&b.pair_dist_m))
            .then(order(a).cmp(&order(b)))
    });
    pairs
}
