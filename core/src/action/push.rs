//! Steps 8-10 of FindAction: the walk out of the pushed cluster and the push itself.

use super::*;
use crate::{
    Config, ImageView, Intrinsics,
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

/// Where the pushed segment of `mask` ends on the way from `target` (the pushed cluster's
/// pixel centre) to `rim` (where the walk left the object; module docs, step 10): walks
/// from `target` towards `rim` in [`WALK_STEP_PX`] steps while the pixel keeps `target`'s
/// label, and returns the last point inside. `rim` when `target` is background in `mask`
/// or off the image, or `rim` is (nearly) `target`.
fn segment_edge(mask: &ImageView<'_, u16>, target: [Real; 2], rim: [Real; 2]) -> [Real; 2] {
    let label_at = |p: [Real; 2]| mask.at(round(p[0]) as i64, round(p[1]) as i64);
    let Some(label) = label_at(target).filter(|&l| l != 0) else {
        return rim;
    };
    let (dx, dy) = (rim[0] - target[0], rim[1] - target[1]);
    let len = sqrt(dx * dx + dy * dy);
    if !(len > 1e-3 && len.is_finite()) {
        return rim;
    }
    let (width, height) = mask.size();
    let step = [WALK_STEP_PX * dx / len, WALK_STEP_PX * dy / len];
    let mut inside = target;
    // 0.5 px steps over width + height pixels cover the image diagonal.
    for i in 1..=width.saturating_add(height).saturating_mul(2) {
        let p = [
            target[0] + step[0] * i as Real,
            target[1] + step[1] * i as Real,
        ];
        if label_at(p) != Some(label) {
            break;
        }
        inside = p;
    }
    inside
}

/// The push for `pair` (module docs, steps 8-10), with the pair as pushed: the pair's
/// pushed cluster first, then the other one.
pub(super) fn push_for_pair(
    map: &RegionMap<'_>,
    mask: &ImageView<'_, u16>,
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
        let Some(rim_px) = walk_out(map, pushed, ci.centre_px, perp)
            .or_else(|| walk_out(map, pushed, ci.centre_px, [-perp[0], -perp[1]]))
        else {
            continue;
        };
        let z_m = ci.centre_cam_m.z;
        let towards = ci.centre_cam_m - intrinsics.back_project(rim_px[0], rim_px[1], z_m);
        let norm = towards.norm();
        if !(norm > 0.0 && norm.is_finite()) {
            continue;
        }
        let direction_cam = towards / norm;
        if !direction_cam.iter().all(|v| v.is_finite()) {
            continue;
        }
        let start_px = segment_edge(mask, ci.centre_px, rim_px);
        let push = Push {
            start_px,
            target_px: ci.centre_px,
            start_cam_m: intrinsics.back_project(start_px[0], start_px[1], z_m),
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
