//! Steps 8-10 of FindAction: the walk out of the pushed cluster and the push itself.

use super::*;
use crate::{
    Config, Intrinsics,
    math::{Real, round, sqrt},
    rng::Pcg32,
};

/// Step of the walk from a cluster centre out of its object, pixels.
const WALK_STEP_PX: Real = 0.5;

/// Walks from `from` along the unit `dir` (pixels); returns the first point that is not
/// object after the walk has been in cluster `pushed`. `None` when the image border, or
/// another cluster after `pushed`, comes first.
fn walk_out(
    map: &RegionMap<'_>,
    pushed: usize,
    from: [Real; 2],
    dir: [Real; 2],
) -> Option<[Real; 2]> {
    let (width, height) = map.heatmap.size();
    // 0.5 px steps over width + height pixels cover the image diagonal.
    let steps = width
        .saturating_add(height)
        .saturating_mul(2)
        .saturating_add(4);
    let mut entered = false;
    let mut last: Option<(i64, i64)> = None;
    for s in 0..steps {
        let t = s as Real * WALK_STEP_PX;
        let p = [from[0] + t * dir[0], from[1] + t * dir[1]];
        let pixel = (round(p[0]) as i64, round(p[1]) as i64);
        if last == Some(pixel) {
            continue;
        }
        last = Some(pixel);
        match map.at(pixel.0, pixel.1) {
            Px::Off => return None,
            Px::Cluster(q) if q == pushed => entered = true,
            Px::Cluster(_) if entered => return None,
            Px::Background if entered => return Some(p),
            Px::Cluster(_) | Px::Object | Px::Background => {}
        }
    }
    None
}

/// The push for `pair` (module docs, steps 8-10), with the pair as pushed: the pair's
/// pushed cluster first, then the other one.
pub(super) fn plan_push(
    map: &RegionMap<'_>,
    pair: &Pair,
    intrinsics: &Intrinsics,
    cfg: &Config,
    rng: &mut Pcg32,
) -> Option<(Pair, Push)> {
    let side: Real = if rng.below(2) == 0 { 1.0 } else { -1.0 };
    for (pushed, other) in [(pair.pushed, pair.other), (pair.other, pair.pushed)] {
        let (Some(ci), Some(cj)) = (map.clusters.get(pushed), map.clusters.get(other)) else {
            continue;
        };
        let dx = cj.centre_px[0] - ci.centre_px[0];
        let dy = cj.centre_px[1] - ci.centre_px[1];
        let len = sqrt(dx * dx + dy * dy);
        if len.is_nan() || len <= 1e-3 {
            continue;
        }
        let perp = [-dy / len * side, dx / len * side];
        let Some(start_px) = walk_out(map, pushed, ci.centre_px, perp)
            .or_else(|| walk_out(map, pushed, ci.centre_px, [-perp[0], -perp[1]]))
        else {
            continue;
        };
        let start_cam_m = intrinsics.back_project(start_px[0], start_px[1], ci.centre_cam_m.z);
        let towards = ci.centre_cam_m - start_cam_m;
        let norm = towards.norm();
        if !(norm > 0.0 && norm.is_finite()) {
            continue;
        }
        let direction_cam = towards / norm;
        if !direction_cam.iter().all(|v| v.is_finite()) {
            continue;
        }
        let push = Push {
            start_px,
            target_px: ci.centre_px,
            start_cam_m,
            direction_cam,
            length_m: cfg.push_len_m,
        };
        return Some((
            Pair {
                pushed,
                other,
                ..*pair
            },
            push,
        ));
    }
    None
}
