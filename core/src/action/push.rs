//! Steps 8-10 of FindAction: the walk out of the pushed cluster and the push itself.

use heapless::Vec as FixedVec;

use super::*;
use crate::{
    Config, ImageView, Intrinsics, MAX_CLUSTERS,
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

/// Most table the line of a push may cross inside the object it pushes, metres (a cut
/// between two packed objects, or where two rounded objects touch): more ends the object.
const CARRY_GAP_MAX_M: Real = 0.005;

/// The push of `pushed` (the other cluster of the pair being `other`) that starts on the
/// side `side_dir` (unit, pixels) of `pushed`'s pixel centre, if a walk that way leaves
/// the object (module docs, steps 9-10); with the push's unit direction in pixels.
fn push_from_side(
    map: &RegionMap<'_>,
    mask: &ImageView<'_, u16>,
    pushed: usize,
    side_dir: [Real; 2],
    intrinsics: &Intrinsics,
    cfg: &Config,
) -> Option<(Push, [Real; 2])> {
    let ci = map.clusters.get(pushed)?;
    let rim_px = walk_out(map, pushed, ci.centre_px, side_dir)?;
    let z_m = ci.centre_cam_m.z;
    let towards = ci.centre_cam_m - intrinsics.back_project(rim_px[0], rim_px[1], z_m);
    let norm = towards.norm();
    if !(norm > 0.0 && norm.is_finite()) {
        return None;
    }
    let direction_cam = towards / norm;
    if !direction_cam.iter().all(|v| v.is_finite()) {
        return None;
    }
    let start_px = segment_edge(mask, ci.centre_px, rim_px);
    let push = Push {
        start_px,
        target_px: ci.centre_px,
        start_cam_m: intrinsics.back_project(start_px[0], start_px[1], z_m),
        direction_cam,
        length_m: cfg.push_len_m,
    };
    Some((push, [-side_dir[0], -side_dir[1]]))
}

/// How far the object goes on from `from` along the unit `dir` (pixels): the distance to
/// the last object pixel before more than `gap_px` of table in a row, or the image border.
fn reach_px(map: &RegionMap<'_>, from: [Real; 2], dir: [Real; 2], gap_px: Real) -> Real {
    let (width, height) = map.heatmap.size();
    // 0.5 px steps over width + height pixels cover the image diagonal.
    let steps = width
        .saturating_add(height)
        .saturating_mul(2)
        .saturating_add(4);
    let mut reach = 0.0;
    for s in 0..steps {
        let t = s as Real * WALK_STEP_PX;
        let p = [from[0] + t * dir[0], from[1] + t * dir[1]];
        match map.at(round(p[0]) as i64, round(p[1]) as i64) {
            Px::Off => break,
            Px::Background => {
                // A NaN gap ends the walk too.
                if gap_px.is_nan() || t - reach > gap_px {
                    break;
                }
            }
            Px::Object | Px::Cluster(_) => reach = t,
        }
    }
    reach
}

/// The clusters a push of `pushed` along the unit `dir` (pixels) is predicted to move, as
/// a bit set (bit `k` = cluster `k`): `pushed` itself and every cluster ahead of it, up to
/// where the object it crosses ends, whose centre lies off the push's line by less than
/// `half_width_px`.
fn moved_set(
    map: &RegionMap<'_>,
    pushed: usize,
    dir: [Real; 2],
    half_width_px: Real,
    gap_px: Real,
) -> u32 {
    let Some(ci) = map.clusters.get(pushed) else {
        return 0;
    };
    let reach = reach_px(map, ci.centre_px, dir, gap_px);
    let mut moved = 0u32;
    for (k, c) in map.clusters.iter().enumerate().take(32) {
        let v = [
            c.centre_px[0] - ci.centre_px[0],
            c.centre_px[1] - ci.centre_px[1],
        ];
        let along = v[0] * dir[0] + v[1] * dir[1];
        let off = (v[0] * dir[1] - v[1] * dir[0]).abs();
        if k == pushed || (along > 0.0 && along <= reach && off < half_width_px) {
            moved |= 1 << k;
        }
    }
    moved
}

/// Pairs of objects of one segment of the accumulated mask (label not background) that
/// the moved set `moved` splits: one of the two moves, the other stays. Segment `l` holds
/// `n = max(c, objects[k])` objects, `c` the clusters with label `l` and `k` the first of
/// them; `m` of its clusters move, each taken as one object, so `m · (n − m)` of its
/// pairs are split (`0` when every object moves). With `objects` all `0` (or shorter than
/// `labels`) this is the number of pairs of clusters of one label that the push splits.
pub(super) fn splits(labels: &[u16], objects: &[u32], moved: u32) -> u32 {
    let mut n = 0u32;
    for (a, &la) in labels.iter().enumerate().take(32) {
        // Each segment once, at its first cluster.
        if la == 0 || labels.iter().take(a).any(|&l| l == la) {
            continue;
        }
        let (mut clusters, mut moving) = (0u32, 0u32);
        for (b, &lb) in labels.iter().enumerate().take(32) {
            if lb == la {
                clusters += 1;
                moving += (moved >> b) & 1;
            }
        }
        let total = clusters.max(objects.get(a).copied().unwrap_or(0));
        n = n.saturating_add(moving.saturating_mul(total.saturating_sub(moving)));
    }
    n
}

/// Most objects the size prior gives one segment (a 2 × 3 pack, as in step 4).
const MAX_SEGMENT_OBJECTS: u32 = 6;

/// The size prior of step 8: for each cluster, how many objects its segment of `mask`
/// (label `labels[k]`) holds by area: the segment's metric area (pixels times `z̄²/(fx·fy)`,
/// `z̄` the mean depth of the segment's clusters' 3-D centres) in units of the smallest
/// such segment, rounded, at most [`MAX_SEGMENT_OBJECTS`]; `0` for background. Objects
/// of one scene look alike, so the smallest segment that holds a cluster is taken as one
/// object.
fn segment_objects(
    mask: &ImageView<'_, u16>,
    labels: &[u16],
    clusters: &[Cluster],
    intrinsics: &Intrinsics,
) -> FixedVec<u32, MAX_CLUSTERS> {
    // Distinct labels, their pixel counts and summed cluster depths.
    let mut seg: FixedVec<(u16, u32, Real, u32), MAX_CLUSTERS> = FixedVec::new();
    for (&l, c) in labels.iter().zip(clusters) {
        if l == 0 {
            continue;
        }
        match seg.iter_mut().find(|s| s.0 == l) {
            Some(s) => {
                s.2 += c.centre_cam_m.z;
                s.3 += 1;
            }
            None => {
                let _ = seg.push((l, 0, c.centre_cam_m.z, 1));
            }
        }
    }
    let mut out: FixedVec<u32, MAX_CLUSTERS> = FixedVec::new();
    if seg.len() < 2 {
        // One segment (or none) is its own unit: the prior adds nothing.
        for _ in labels {
            let _ = out.push(0);
        }
        return out;
    }
    let (_, height) = mask.size();
    // Labels come in runs along a row: look each run's segment up once.
    let mut run: (u16, Option<usize>) = (0, None);
    for y in 0..height {
        let Some(row) = mask.row(y) else { break };
        for &l in row {
            if l != run.0 {
                run = (l, seg.iter().position(|s| s.0 == l));
            }
            if let Some(s) = run.1.and_then(|i| seg.get_mut(i)) {
                s.1 = s.1.saturating_add(1);
            }
        }
    }
    let fxy = intrinsics.fx * intrinsics.fy;
    let area = |s: &(u16, u32, Real, u32)| {
        let z = s.2 / s.3.max(1) as Real;
        s.1 as Real * z * z / fxy
    };
    let unit = seg
        .iter()
        .filter(|s| s.1 > 0)
        .map(area)
        .fold(Real::INFINITY, Real::min);
    for &l in labels {
        let n = seg
            .iter()
            .find(|s| s.0 == l)
            .map(|s| round(area(s) / unit))
            .filter(|n| n.is_finite() && *n >= 1.0)
            .map_or(0, |n| (n as u32).min(MAX_SEGMENT_OBJECTS));
        let _ = out.push(n);
    }
    out
}

/// A candidate's rank: (pairs of clusters split, pairs of objects split by the size prior,
/// `u32::MAX` less the clusters moved); higher is better.
type Key = (u32, u32, u32);

/// The push FindAction makes (module docs, steps 8-10), with its pair as pushed (the
/// pair's pushed cluster first, then the other one). `pairs` are in rank order; each
/// draws one side from `rng`.
///
/// Candidates are enumerated in the paper's order: pairs by rank, in a pair the pushed
/// cluster then the other, the drawn side then the opposite one. With
/// [`Config::push_carry_frac`] `0` the first candidate is made. Otherwise every
/// candidate's moved set is predicted ([`moved_set`]) and the candidate that splits the
/// most pairs of clusters sharing a label of `mask` is made, then the one that moves the
/// fewest clusters, then the earliest; when no candidate splits such a pair, the one that
/// splits the most pairs of objects by the size prior ([`segment_objects`]), in the same
/// order; when none does either, the first.
pub(super) fn choose_push(
    map: &RegionMap<'_>,
    mask: &ImageView<'_, u16>,
    pairs: &[Pair],
    intrinsics: &Intrinsics,
    cfg: &Config,
    rng: &mut Pcg32,
) -> Option<(Pair, Push)> {
    let score = cfg.push_carry_frac > 0.0;
    let mut labels: FixedVec<u16, MAX_CLUSTERS> = FixedVec::new();
    if score {
        for c in map.clusters {
            let label = mask
                .at(round(c.centre_px[0]) as i64, round(c.centre_px[1]) as i64)
                .unwrap_or(0);
            let _ = labels.push(label);
        }
    }
    let objects = if score {
        segment_objects(mask, &labels, map.clusters, intrinsics)
    } else {
        FixedVec::new()
    };
    let mut best: Option<(Key, (Pair, Push))> = None;
    for pair in pairs {
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
            for side_dir in [perp, [-perp[0], -perp[1]]] {
                let Some((push, dir)) =
                    push_from_side(map, mask, pushed, side_dir, intrinsics, cfg)
                else {
                    continue;
                };
                let found = (
                    Pair {
                        pushed,
                        other,
                        ..*pair
                    },
                    push,
                );
                if !score {
                    return Some(found);
                }
                // Metres per pixel at the cluster's depth.
                let m_per_px = ci.centre_cam_m.z / intrinsics.fx;
                let gap_px = CARRY_GAP_MAX_M / m_per_px;
                let moved = moved_set(map, pushed, dir, cfg.push_carry_frac * len, gap_px);
                let split = splits(&labels, &[], moved);
                // A seam pair is only pushed to split a segment (module docs, step 7).
                if split == 0 && is_seam(pair, cfg) {
                    continue;
                }
                // Pairs of objects the size prior says the push splits: only weighed
                // when no candidate splits a pair of clusters.
                let prior = if split > 0 {
                    0
                } else {
                    splits(&labels, &objects, moved)
                };
                // With no split, every candidate ties and the first stays.
                let key = if split > 0 || prior > 0 {
                    (split, prior, u32::MAX - moved.count_ones())
                } else {
                    (0, 0, 0)
                };
                if best.as_ref().is_none_or(|(b, _)| key > *b) {
                    best = Some((key, found));
                }
            }
        }
    }
    best.map(|(_, found)| found)
}
