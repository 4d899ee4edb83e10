//! GroupBFIFs, second pass: split a group whose frames two rigid motions explain far
//! better than one.
//!
//! One frame's twist comes from three points a few centimetres apart, so its noise is a
//! few millimetres (depth noise alone gives about 1.5 mm at 0.6 m); two bodies whose
//! motions differ by less than a few times that (a pushed box that turned 5 degrees more
//! than the box beside it, a neighbour dragged 4 mm) fall into one twist group. A group's
//! hundreds of points pin its least-squares motion down to a fraction of a millimetre,
//! so the points can tell what single twists cannot.
//!
//! Contract, for each group (including the ones this pass creates), in id order:
//! - Fit one rigid motion to all points of its frames (at `t` and `t+1`, camera frame).
//!   Start two parts from the sign of each frame's mean miss (averaged with its nearest
//!   frames') along the misses' principal axis, then alternate: fit each part's motion,
//!   move each frame to the motion that misses its three points least, until nothing
//!   moves (at most [`MAX_ROUNDS`]). Nearness is between the frames' first pixels at `t`.
//! - Keep the split only when each part has at least [`MIN_PART_FRAMES_PER_GROUP`] times
//!   [`Config::min_group_frames`] frames, the two motions move either part's centroid
//!   apart by at least [`MIN_SPLIT_GAP_M`], the mean miss falls to at most
//!   [`MAX_MISS_RATIO`] of the single motion's, and the parts are places: frames mostly
//!   have their nearest frames in their own part ([`MIN_COHERENCE`]).
//! - The part with the larger motion at its centroid gets a new group id (appended); the
//!   other keeps the id. Each part's twist is its fitted motion in the space frame; a
//!   part is moving when its twist reaches [`Config::static_below_m`] or its motion moves
//!   its centroid by [`MIN_MOTION_GAP_M`].
//! - Last, every group still not moving whose fitted motion moves its centroid by
//!   [`MIN_MOTION_GAP_M`] is moving, with that motion's twist.
//!
//! Frames of [`NO_GROUP`] are never touched. Deterministic, no
//! heap, no panics: every index is checked.

use core::hint::select_unpredictable;

use nalgebra::{Matrix3, Point3, Translation3, Vector3};

use crate::{
    Config, Pose, Twist,
    frames::BodyFrame,
    group::{GroupInfo, NO_GROUP},
    math::Real,
    se3::fit_rigid_motion,
};

/// Most reassignment rounds per split.
pub const MAX_ROUNDS: usize = 8;
/// Each part needs this many times [`Config::min_group_frames`] frames (the seeds
/// CorrectMask asks of a group in a segment).
pub const MIN_PART_FRAMES_PER_GROUP: u32 = 3;
/// How far a fitted motion must move a group's points (their centroid) for the group to
/// count as moving, metres: the motion ceiling's floor (`riseg bench`). A group's fit
/// rests on hundreds of points, so its noise is a small share of this even with the depth
/// noise of a D415 (about 1 mm per point).
pub const MIN_MOTION_GAP_M: Real = 0.001;
/// Smallest distance the two parts' motions put between one point (either part's
/// centroid) for a split to stand, metres: half the ceiling's floor
/// ([`MIN_MOTION_GAP_M`]), because the fitted gap reads low. On the `packed` family's
/// scripted scenes with exact flow, four pairs whose true motions differ by 1.03-1.30 mm
/// at their centres fitted 0.76-0.88 mm, while the tried splits of one body's noise
/// fitted 0.15-0.41 mm (and failed the miss and coherence tests as well).
pub const MIN_SPLIT_GAP_M: Real = 0.0005;
/// The split must bring the mean miss of the points to at most this share of the single
/// motion's.
pub const MAX_MISS_RATIO: Real = 0.9;
/// Each part must be a place, not a scatter: on average at least this share of a
/// frame's [`NEIGHBOURS`] nearest frames of the group (by position at `t`) fall in its
/// part. Two bodies give nearly 1; splitting one body's noise gives about one half.
pub const MIN_COHERENCE: Real = 0.8;
/// Neighbours per frame in the coherence test.
pub const NEIGHBOURS: usize = 4;
/// Neighbours a frame's miss is averaged with before the first split.
const SMOOTH_NEIGHBOURS: usize = 8;
/// Entries of [`split_mixed_groups`]' `misses` scratch per frame: a frame's miss and its
/// smoothed miss, three components each (in the alternation the raw half holds, one
/// entry per frame, each member's mean point miss under its part's motion).
pub const MISS_SCRATCH_PER_FRAME: usize = 6;

/// Splits the groups `groups[..count]` of `frames` (module docs), appending new groups
/// after `count` while `groups` has room; `side` is scratch with one entry per frame and
/// `misses` with [`MISS_SCRATCH_PER_FRAME`] (frames past either are left out).
/// Returns the new group count.
pub fn split_mixed_groups(
    frames: &[BodyFrame],
    space_origin: &Point3<Real>,
    cfg: &Config,
    frame_group: &mut [u16],
    groups: &mut [GroupInfo],
    count: usize,
    (side, misses): (&mut [u32], &mut [Real]),
) -> usize {
    let n = frames
        .len()
        .min(frame_group.len())
        .min(side.len())
        .min(misses.len() / MISS_SCRATCH_PER_FRAME);
    let (frames, frame_group, side, misses) = (
        frames.get(..n).unwrap_or(&[]),
        frame_group.get_mut(..n).unwrap_or(&mut []),
        side.get_mut(..n).unwrap_or(&mut []),
        misses
            .get_mut(..n * MISS_SCRATCH_PER_FRAME)
            .unwrap_or(&mut []),
    );
    // Frames in row order (as CreateFrames writes them) let the neighbour searches walk
    // a list of members only (`nearest_listed`, `nearest_packed`), with the same result.
    let row_order = n < 1 << 31
        && frames.windows(2).all(|w| match w {
            [a, b] => a.px_t[0][1] <= b.px_t[0][1],
            _ => true,
        });
    let capacity = groups.len().min(usize::from(NO_GROUP));
    let mut count = count.min(capacity);
    let mut g = 0;
    while g < count {
        if count < capacity
            && let Some(new) = split_one(
                frames,
                cfg,
                frame_group,
                (side, &mut *misses),
                (g, row_order),
            )
        {
            let new_id = count as u16;
            for (fg, &s) in frame_group.iter_mut().zip(side.iter()) {
                if usize::from(*fg) == g && s == 1 {
                    *fg = new_id;
                }
            }
            let label = groups.get(g).map_or(0, |info| info.label);
            let info = |part: &Part| GroupInfo {
                frames: part.frames,
                label,
                ..fitted(&part.motion, part.moved_m, space_origin, cfg)
            };
            if let Some(slot) = groups.get_mut(g) {
                *slot = info(&new.keep);
            }
            if let Some(slot) = groups.get_mut(count) {
                *slot = info(&new.split);
            }
            count += 1;
            continue; // look at the kept part again: a third body may remain
        }
        g += 1;
    }
    // A still group whose points moved by the motion gap moved: a box dragged 3 mm has
    // a twist below the noise floor, but its fit is certain, and CorrectMask must grow
    // it by that motion, not the identity.
    for (id, info) in groups.iter_mut().enumerate().take(count) {
        if info.moving {
            continue;
        }
        let all = part_points(frames, frame_group, id, None, side);
        let (mut centroid, mut n) = (Vector3::zeros(), 0.0);
        for (a, _) in all.clone() {
            centroid += a.coords;
            n += 1.0;
        }
        let Some(motion) = fit_rigid_motion(all) else {
            continue;
        };
        let c = Point3::from(centroid / n);
        let moved_m = (motion * c - c).norm();
        if moved_m >= MIN_MOTION_GAP_M {
            *info = GroupInfo {
                frames: info.frames,
                label: info.label,
                ..fitted(&motion, moved_m, space_origin, cfg)
            };
        }
    }
    count
}

/// The twist (space frame at `space_origin`) of a fitted camera-frame `motion`, and
/// whether it moved: its twist reaches [`Config::static_below_m`] or it moves the fitted
/// points' centroid by `moved_m` >= [`MIN_MOTION_GAP_M`]. Frames and label are left
/// default.
fn fitted(motion: &Pose, moved_m: Real, space_origin: &Point3<Real>, cfg: &Config) -> GroupInfo {
    let to_space = Translation3::from(-space_origin.coords);
    let twist = Twist::log(&(to_space * motion * to_space.inverse()));
    let moving = twist.norm_squared(cfg.length_scale_m) >= cfg.static_below_m * cfg.static_below_m
        || moved_m >= MIN_MOTION_GAP_M;
    GroupInfo {
        twist,
        moving,
        ..GroupInfo::default()
    }
}

/// One part of an accepted split.
#[derive(Debug, Clone, Copy)]
struct Part {
    motion: Pose,
    frames: u32,
    /// How far the part's motion moves its centroid, metres.
    moved_m: Real,
}

/// An accepted split of one group: `keep` stays, `split` (frames with `side == 1`) gets
/// a new id.
#[derive(Debug, Clone, Copy)]
struct Split {
    keep: Part,
    split: Part,
}

/// Tries to split group `g` (module docs); on success `side` marks the frames of the part
/// that moves away with `1`. `row_order`: the frames are in row order (and fewer than
/// `2^31`), so neighbours may be searched among a list of the members.
fn split_one(
    frames: &[BodyFrame],
    cfg: &Config,
    frame_group: &[u16],
    (side, misses): (&mut [u32], &mut [Real]),
    (g, row_order): (usize, bool),
) -> Option<Split> {
    let is_member = |i: usize| frame_group.get(i).is_some_and(|&fg| usize::from(fg) == g);
    let min_part = MIN_PART_FRAMES_PER_GROUP.saturating_mul(cfg.min_group_frames.max(1));
    let members = (0..frames.len()).filter(|&i| is_member(i)).count() as u32;
    if members < 2 * min_part {
        return None;
    }
    let one = fit_rigid_motion(part_points(frames, frame_group, g, None, side))?;
    let miss = |m: &Pose, f: &BodyFrame| -> Vector3<Real> {
        f.p_t
            .iter()
            .zip(&f.p_t1)
            .fold(Vector3::zeros(), |acc, (a, b)| acc + (m * a - b))
            / 3.0
    };
    let frame_miss = |m: &Pose, f: &BodyFrame| -> Real {
        f.p_t
            .iter()
            .zip(&f.p_t1)
            .map(|(a, b)| (m * a - b).norm())
            .sum::<Real>()
            / 3.0
    };
    // Principal axis of the misses, each averaged with its frame's nearest neighbours
    // (one frame's miss is mostly depth noise, a neighbourhood's is its body's): the
    // first part is the frames on its positive side. Each member's miss and smoothed
    // miss are computed once, into `misses` (the raw ones, then the smoothed ones).
    let (raw, smooth) = misses.split_at_mut(misses.len() / 2);
    let stored = |misses: &[Real], i: usize| {
        let m = misses.get(miss_slot(i)?)?;
        Some(Vector3::new(*m.first()?, *m.get(1)?, *m.get(2)?))
    };
    let store = |misses: &mut [Real], i: usize, e: Vector3<Real>| {
        if let Some(m) = miss_slot(i).and_then(|r| misses.get_mut(r)) {
            m.copy_from_slice(e.as_slice());
        }
    };
    // With the frames in row order and first pixels below 2^16, the members' first
    // pixels are listed in `side` (free until the first parts are set below), packed as
    // `u | v << 16`, and searched among themselves ([`nearest_packed`]); the misses are
    // then stored by place in that list (`slot`), else by frame index.
    let packed = row_order
        && frames
            .iter()
            .enumerate()
            .filter(|&(i, _)| is_member(i))
            .all(|(_, f)| f.px_t[0].iter().all(|&c| c < 1 << 16));
    let slot = |p: usize, i: usize| if packed { p } else { i };
    let mut listed = 0;
    for (p, (i, f)) in frames
        .iter()
        .enumerate()
        .filter(|&(i, _)| is_member(i))
        .enumerate()
    {
        store(raw, slot(p, i), miss(&one, f));
        if packed && let Some(entry) = side.get_mut(listed) {
            let [u, v] = f.px_t[0];
            *entry = u | v << 16;
            listed += 1;
        }
    }
    let members_listed = side.get(..listed).unwrap_or(&[]);
    let (mut sum, mut outer, mut total_miss) = (Vector3::zeros(), Matrix3::zeros(), 0.0);
    for (p, (i, f)) in frames
        .iter()
        .enumerate()
        .filter(|&(i, _)| is_member(i))
        .enumerate()
    {
        // Neighbours as slots: places in the list, or frame indices.
        let near = if packed {
            nearest_packed::<SMOOTH_NEIGHBOURS>(members_listed, p)
        } else {
            nearest::<SMOOTH_NEIGHBOURS>(frames, &is_member, i)
        };
        let own = stored(raw, slot(p, i)).unwrap_or_else(|| miss(&one, f));
        let (sum_near, n) = near
            .iter()
            .filter_map(|&(_, j)| stored(raw, j))
            .fold((own, 1.0), |(sum, n), e| (sum + e, n + 1.0));
        let e = sum_near / n;
        store(smooth, slot(p, i), e);
        sum += e;
        outer += e * e.transpose();
        total_miss += frame_miss(&one, f);
    }
    let count = members as Real;
    let mean = sum / count;
    let cov = outer / count - mean * mean.transpose();
    let axis = principal_axis(&cov)?;
    // The list in `side` is done with; `p` counts the members for their slots.
    let mut p = 0;
    for (i, s) in side.iter_mut().enumerate() {
        let member = is_member(i);
        *s = u32::from(
            member && stored(smooth, slot(p, i)).is_some_and(|e| (e - mean).dot(&axis) > 0.0),
        );
        p += usize::from(member);
    }
    let mut fits = (one, one);
    for _ in 0..MAX_ROUNDS {
        fits = (
            fit_rigid_motion(part_points(frames, frame_group, g, Some(0), side))?,
            fit_rigid_motion(part_points(frames, frame_group, g, Some(1), side))?,
        );
        let mut changed = false;
        for (i, (s, f)) in side.iter_mut().zip(frames).enumerate() {
            if !is_member(i) {
                continue;
            }
            let (miss0, miss1) = (frame_miss(&fits.0, f), frame_miss(&fits.1, f));
            let best = u32::from(miss1 < miss0);
            changed |= best != *s;
            *s = best;
            // Free since the smoothing: the miss of the frame's part, for the split's mean.
            if let Some(m) = raw.get_mut(i) {
                *m = if best == 1 { miss1 } else { miss0 };
            }
        }
        if !changed {
            break;
        }
    }
    // The final parts, their sizes, centroids and misses.
    let (mut sizes, mut centroid, mut split_miss) = ([0u32; 2], [Vector3::zeros(); 2], 0.0);
    for (i, (&s, f)) in side.iter().zip(frames).enumerate() {
        if !is_member(i) {
            continue;
        }
        let k = usize::from(s == 1);
        sizes[k] += 1;
        centroid[k] += f.p_t.iter().fold(Vector3::zeros(), |acc, p| acc + p.coords) / 3.0;
        // The last round's fits are the final ones, and so are its misses.
        split_miss += raw.get(i).copied().unwrap_or(Real::INFINITY);
    }
    if sizes[0] < min_part || sizes[1] < min_part {
        return None;
    }
    let c = [
        Point3::from(centroid[0] / sizes[0] as Real),
        Point3::from(centroid[1] / sizes[1] as Real),
    ];
    let gap_m = c
        .iter()
        .map(|p| (fits.0 * p - fits.1 * p).norm())
        .fold(0.0, Real::max);
    if gap_m < MIN_SPLIT_GAP_M
        || split_miss > MAX_MISS_RATIO * total_miss
        || if row_order {
            coherence_listed(frames, &is_member, side)
        } else {
            coherence(frames, &is_member, side)
        } < MIN_COHERENCE
    {
        return None;
    }
    let moved = |m: &Pose, p: &Point3<Real>| (m * p - p).norm();
    let parts = [
        Part {
            motion: fits.0,
            frames: sizes[0],
            moved_m: moved(&fits.0, &c[0]),
        },
        Part {
            motion: fits.1,
            frames: sizes[1],
            moved_m: moved(&fits.1, &c[1]),
        },
    ];
    // The part that moved more leaves: flip the sides if that is part 0.
    if parts[0].moved_m > parts[1].moved_m {
        for (i, s) in side.iter_mut().enumerate() {
            if is_member(i) {
                *s ^= 1;
            }
        }
        return Some(Split {
            keep: parts[1],
            split: parts[0],
        });
    }
    Some(Split {
        keep: parts[0],
        split: parts[1],
    })
}

/// The mean share of each member frame's [`NEIGHBOURS`] nearest member frames that share
/// its `side`.
fn coherence(frames: &[BodyFrame], is_member: &impl Fn(usize) -> bool, side: &[u32]) -> Real {
    let (mut same, mut total) = (0u32, 0u32);
    for (i, &si) in side.iter().enumerate().take(frames.len()) {
        if !is_member(i) {
            continue;
        }
        for &(_, j) in &nearest::<NEIGHBOURS>(frames, is_member, i) {
            if let Some(&sj) = side.get(j) {
                total += 1;
                same += u32::from(sj == si);
            }
        }
    }
    if total == 0 {
        return 0.0;
    }
    same as Real / total as Real
}

/// [`coherence`] for frames in row order (fewer than `2^31`), searching neighbours among a
/// list of the members ([`nearest_listed`]), which is built in `side` itself: member `i`
/// with side `s` is listed as `2i + s`, in index order (an entry never lands past the
/// member it lists, so compacting in place reads each side before it is overwritten).
/// `side` is restored before returning (non-members read 0 then, as they do after the
/// split's first parts are set).
fn coherence_listed(
    frames: &[BodyFrame],
    is_member: &impl Fn(usize) -> bool,
    side: &mut [u32],
) -> Real {
    let n = side.len().min(frames.len());
    let mut listed = 0;
    for i in 0..n {
        if is_member(i)
            && let Some(&s) = side.get(i)
            && let Some(slot) = side.get_mut(listed)
        {
            *slot = ((i as u32) << 1) | (s & 1);
            listed += 1;
        }
    }
    let members = side.get(..listed).unwrap_or(&[]);
    let (mut same, mut total) = (0u32, 0u32);
    for (p, &e) in members.iter().enumerate() {
        for &(_, q) in &nearest_listed::<NEIGHBOURS>(frames, members, 1, p) {
            if let Some(&f) = members.get(q) {
                total += 1;
                same += u32::from((f ^ e) & 1 == 0);
            }
        }
    }
    // Back to one side per frame: the entries are spread out from the last, so each is
    // read before its place is written.
    let mut next = n;
    for p in (0..listed).rev() {
        let e = side.get(p).copied().unwrap_or(0);
        let i = (e >> 1) as usize;
        for s in side.get_mut(i..next).unwrap_or(&mut []) {
            *s = 0;
        }
        if let Some(s) = side.get_mut(i) {
            *s = e & 1;
        }
        next = i;
    }
    for s in side.get_mut(..next).unwrap_or(&mut []) {
        *s = 0;
    }
    if total == 0 {
        return 0.0;
    }
    same as Real / total as Real
}

/// Where frame `i`'s three miss components are in a misses scratch; `None` when the
/// offset overflows, as for [`nearest`]'s `usize::MAX` (no neighbour).
fn miss_slot(i: usize) -> Option<core::ops::Range<usize>> {
    let start = i.checked_mul(3)?;
    Some(start..start.checked_add(3)?)
}

/// The `K` member frames nearest frame `i` (by their first pixels at `t`), nearest
/// first, as `(squared distance, index)`; missing ones have index `usize::MAX`.
///
/// CreateFrames writes frames in row order, so the search walks out from `i` in both
/// directions and stops once the row gap alone exceeds the `K`-th distance so far: about
/// `O(√m)` per frame instead of `O(m)`. Frames out of row order only make it less exact.
fn nearest<const K: usize>(
    frames: &[BodyFrame],
    is_member: &impl Fn(usize) -> bool,
    i: usize,
) -> [(Real, usize); K] {
    let both = |j| (j, j);
    let (before, after) = ((0..i).rev().map(both), (i + 1..frames.len()).map(both));
    let pixel = |j: usize| frames.get(j).map(|f| f.px_t[0]);
    nearest_among(pixel, i, (before, after), is_member)
}

/// [`nearest`] for the member at place `p` of `members` (the member frames, ascending,
/// frame `i` listed as `i << shift` plus bits below), walking the list instead of all
/// frames; returns places in `members`, not frame indices. The same neighbours when the
/// frames are in row order: a walk outward then meets growing row gaps, so the first frame
/// [`nearest`] stops at, member or not, has every later member past the bound too.
fn nearest_listed<const K: usize>(
    frames: &[BodyFrame],
    members: &[u32],
    shift: u32,
    p: usize,
) -> [(Real, usize); K] {
    let Some(&i) = members.get(p) else {
        return [(Real::INFINITY, usize::MAX); K];
    };
    let index = move |(q, &e): (usize, &u32)| (q, (e >> shift) as usize);
    let before = members.iter().enumerate().take(p).rev().map(index);
    let after = members.iter().enumerate().skip(p + 1).map(index);
    let pixel = |j: usize| frames.get(j).map(|f| f.px_t[0]);
    nearest_among(pixel, (i >> shift) as usize, (before, after), &|_| true)
}

/// [`nearest_listed`] over a list of the members' first pixels at `t`, each packed as
/// `u | v << 16`: the same walk and neighbours, without reading the frames.
fn nearest_packed<const K: usize>(members: &[u32], p: usize) -> [(Real, usize); K] {
    let (Some(&e), Some(before), Some(after)) =
        (members.get(p), members.get(..p), members.get(p + 1..))
    else {
        return [(Real::INFINITY, usize::MAX); K];
    };
    let before = before
        .iter()
        .enumerate()
        .rev()
        .map(|(q, &e)| (q, e as usize));
    let after = (after.iter().enumerate()).map(|(k, &e)| (p + 1 + k, e as usize));
    let pixel = |e: usize| Some([(e & 0xFFFF) as u32, (e >> 16) as u32]);
    nearest_among(pixel, e as usize, (before, after), &|_| true)
}

/// The search of [`nearest`]: visits the `(id, frame)`s of `before` (walking back from
/// frame `i`), then those of `after`, each until a row gap exceeds the `K`-th distance so
/// far, and keeps the ids of the `K` nearest that are members. `pixel` gives a frame's
/// first pixel at `t` (`None` ends a walk).
fn nearest_among<const K: usize>(
    pixel: impl Fn(usize) -> Option<[u32; 2]>,
    i: usize,
    (before, after): (
        impl Iterator<Item = (usize, usize)>,
        impl Iterator<Item = (usize, usize)>,
    ),
    is_member: &impl Fn(usize) -> bool,
) -> [(Real, usize); K] {
    let mut near = [(Real::INFINITY, usize::MAX); K];
    let Some([u, v]) = pixel(i) else {
        return near;
    };
    let (u, v) = (u as Real, v as Real);
    let visit = |(id, j): (usize, usize), near: &mut [(Real, usize); K]| -> bool {
        let Some([uj, vj]) = pixel(j) else {
            return false;
        };
        let (du, dv) = (uj as Real - u, vj as Real - v);
        let worst = near.last().map_or(Real::INFINITY, |w| w.0);
        if dv * dv > worst {
            return false;
        }
        let d = du * du + dv * dv;
        // One not nearer than the last moves nothing.
        if d < worst && is_member(j) {
            insert(near, (d, id));
        }
        true
    };
    for j in before {
        if !visit(j, &mut near) {
            break;
        }
    }
    for j in after {
        if !visit(j, &mut near) {
            break;
        }
    }
    near
}

/// Inserts `entry` into `near`, a list sorted by distance (ascending, no NaN), carrying
/// it from the first slot on and swapping it with each slot's entry that is strictly
/// farther. So it lands after the entries of equal distance, and behind it each run of
/// equal distances turns by one (its first entry moves to its end); the last run's first
/// entry drops out. The order of equal distances shows in the smoothed misses' sums.
/// By selects: where it lands is a coin flip.
fn insert<const K: usize>(near: &mut [(Real, usize); K], mut entry: (Real, usize)) {
    for slot in near.iter_mut() {
        let nearer = entry.0 < slot.0;
        (*slot, entry) = select_unpredictable(nearer, (entry, *slot), (*slot, entry));
    }
}

/// The point pairs (`t`, `t+1`) of the frames of group `g`, of one part (`side`) or all.
fn part_points<'a>(
    frames: &'a [BodyFrame],
    frame_group: &'a [u16],
    g: usize,
    part: Option<u32>,
    side: &'a [u32],
) -> impl Iterator<Item = (&'a Point3<Real>, &'a Point3<Real>)> + Clone + 'a {
    frames
        .iter()
        .zip(frame_group)
        .zip(side)
        .filter(move |((_, fg), s)| usize::from(**fg) == g && part.is_none_or(|p| **s == p))
        .flat_map(|((f, _), _)| f.p_t.iter().zip(f.p_t1.iter()))
}

/// Unit eigenvector of the largest eigenvalue of a symmetric 3×3 matrix, by power
/// iteration from the column of largest norm; `None` for a zero or non-finite matrix.
fn principal_axis(m: &Matrix3<Real>) -> Option<Vector3<Real>> {
    let mut v = (0..3)
        .map(|k| m.column(k).into_owned())
        .max_by(|a, b| a.norm_squared().total_cmp(&b.norm_squared()))?;
    for _ in 0..32 {
        let next = m * v;
        let norm = next.norm();
        if !(norm.is_finite() && norm > 0.0) {
            return None;
        }
        v = next / norm;
    }
    Some(v)
}

#[cfg(test)]
mod tests {
    use nalgebra::{UnitQuaternion, Vector3};

    use super::*;
    use crate::rng::Pcg32;

    /// A frame on the plane z = 0.6 m around `(x, y)`, carried by `motion`, with `noise_m`
    /// of uniform noise on every coordinate at `t+1`.
    fn frame(rng: &mut Pcg32, x: Real, y: Real, motion: &Pose, noise_m: Real) -> BodyFrame {
        let p_t = [
            Point3::new(x, y, 0.6),
            Point3::new(x + 0.02, y, 0.6),
            Point3::new(x, y + 0.02, 0.6),
        ];
        let mut noisy = |p: &Point3<Real>| {
            let mut e = || (rng.unit() - 0.5) * 2.0 * noise_m;
            motion * p + Vector3::new(e(), e(), e())
        };
        let p_t1 = [noisy(&p_t[0]), noisy(&p_t[1]), noisy(&p_t[2])];
        let px = |p: &Point3<Real>| {
            [
                (600.0 * p.x / p.z + 320.0) as u32,
                (600.0 * p.y / p.z + 240.0) as u32,
            ]
        };
        BodyFrame {
            px_t: [px(&p_t[0]), px(&p_t[1]), px(&p_t[2])],
            p_t,
            p_t1,
            label: 1,
            ..BodyFrame::EMPTY
        }
    }

    /// `per_body` frames on each of two boxes side by side (x < 0: body 0, x > 0: body
    /// 1), all in group 0; returns the frames and each frame's body.
    fn two_boxes(
        motions: [Pose; 2],
        noise_m: Real,
        per_body: usize,
    ) -> ([BodyFrame; 200], [u8; 200]) {
        let mut rng = Pcg32::new(7);
        let mut frames = [BodyFrame::EMPTY; 200];
        let mut body = [0u8; 200];
        for (i, (f, b)) in frames
            .iter_mut()
            .zip(body.iter_mut())
            .take(2 * per_body)
            .enumerate()
        {
            *b = u8::from(i % 2 == 1);
            let x = rng.unit() * 0.04 - if *b == 0 { 0.045 } else { -0.005 };
            let y = rng.unit() * 0.06 - 0.03;
            *f = frame(&mut rng, x, y, &motions[usize::from(*b)], noise_m);
        }
        // In row order, as CreateFrames writes them.
        let n = 2 * per_body;
        for i in 1..n {
            let mut j = i;
            while j > 0 && frames[j - 1].px_t[0][1] > frames[j].px_t[0][1] {
                frames.swap(j - 1, j);
                body.swap(j - 1, j);
                j -= 1;
            }
        }
        (frames, body)
    }

    /// Runs the pass on `frames`, all in group 0 (`first`), with room for `capacity`
    /// groups.
    fn run_with(
        frames: &[BodyFrame],
        first: GroupInfo,
        capacity: usize,
    ) -> (usize, [u16; 200], [GroupInfo; 8]) {
        let mut frame_group = [0u16; 200];
        let mut groups = [GroupInfo::default(); 8];
        groups[0] = first;
        let mut side = [0u32; 200];
        let mut misses = [0.0; 200 * MISS_SCRATCH_PER_FRAME];
        let count = split_mixed_groups(
            frames,
            &Point3::new(0.0, 0.0, 0.6),
            &Config::PAPER,
            &mut frame_group[..frames.len()],
            &mut groups[..capacity],
            1,
            (&mut side, &mut misses),
        );
        (count, frame_group, groups)
    }

    /// [`run_with`] a moving group 0 and room for 8 groups.
    fn run(frames: &[BodyFrame]) -> (usize, [u16; 200], [GroupInfo; 8]) {
        let moving = GroupInfo {
            frames: frames.len() as u32,
            moving: true,
            label: 1,
            ..GroupInfo::default()
        };
        run_with(frames, moving, 8)
    }

    /// A still group 0 of 160 frames.
    const STILL: GroupInfo = GroupInfo {
        frames: 160,
        twist: Twist::ZERO,
        moving: false,
        label: 1,
    };

    fn push(dx_m: Real, yaw_deg: Real) -> Pose {
        Pose::from_parts(
            Translation3::new(dx_m, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_deg.to_radians()),
        )
    }

    proptest::proptest! {
        /// With frames in row order, the listed neighbour searches and coherence test
        /// ([`nearest_listed`], [`nearest_packed`], [`coherence_listed`]) give what the
        /// walks over all frames give, bit for bit, and the coherence test leaves `side`
        /// as it found it. Pixels sit on a coarse lattice so that ties in distance are
        /// common.
        #[test]
        fn listed_searches_equal_the_walks_over_all_frames(
            cells in proptest::collection::vec((0u32..30, 0u32..30, 0u16..3, 0u32..2), 1..300),
        ) {
            let mut cells = cells;
            cells.sort_by_key(|c| c.1);
            let frames: std::vec::Vec<BodyFrame> = cells
                .iter()
                .map(|&(u, v, _, _)| BodyFrame {
                    px_t: [[u * 4, v * 4]; 3],
                    ..BodyFrame::EMPTY
                })
                .collect();
            let group: std::vec::Vec<u16> = cells.iter().map(|c| c.2).collect();
            let is_member = |i: usize| group.get(i) == Some(&1);
            let members: std::vec::Vec<u32> = (0..frames.len())
                .filter(|&i| is_member(i))
                .map(|i| i as u32)
                .collect();
            let pixels: std::vec::Vec<u32> = members
                .iter()
                .filter_map(|&i| frames.get(i as usize))
                .map(|f| f.px_t[0][0] | f.px_t[0][1] << 16)
                .collect();
            for (p, &i) in members.iter().enumerate() {
                let walk = nearest::<SMOOTH_NEIGHBOURS>(&frames, &is_member, i as usize);
                let to_frames = |near: [(Real, usize); SMOOTH_NEIGHBOURS]| {
                    near.map(|(d, q)| (d, members.get(q).map_or(usize::MAX, |&j| j as usize)))
                };
                let listed = nearest_listed::<SMOOTH_NEIGHBOURS>(&frames, &members, 0, p);
                proptest::prop_assert_eq!(walk, to_frames(listed), "frame {}", i);
                let packed = nearest_packed::<SMOOTH_NEIGHBOURS>(&pixels, p);
                proptest::prop_assert_eq!(walk, to_frames(packed), "frame {} packed", i);
            }
            let side: std::vec::Vec<u32> = cells
                .iter()
                .enumerate()
                .map(|(i, c)| if is_member(i) { c.3 } else { 0 })
                .collect();
            let mut listed_side = side.clone();
            let want = coherence(&frames, &is_member, &side);
            let got = coherence_listed(&frames, &is_member, &mut listed_side);
            proptest::prop_assert_eq!(want.to_bits(), got.to_bits());
            proptest::prop_assert_eq!(side, listed_side);
        }
    }

    /// [`insert`] as its docs tell it: after the entries of equal or smaller distance,
    /// each farther run of equal distances turned by one, cut to `K` entries.
    fn insert_by_runs<const K: usize>(near: &mut [(Real, usize); K], d: Real, id: usize) {
        let j = near.iter().take_while(|e| e.0 <= d).count();
        let mut out: std::vec::Vec<(Real, usize)> = near[..j].to_vec();
        out.push((d, id));
        let mut rest = &near[j..];
        while let Some(&first) = rest.first() {
            let run = rest.iter().take_while(|e| e.0 == first.0).count();
            out.extend_from_slice(&rest[1..run]);
            out.push(first);
            rest = &rest[run..];
        }
        near.copy_from_slice(&out[..K]);
    }

    proptest::proptest! {
        /// [`insert`] does what its docs say, ids included, over any sequence of
        /// insertions of entries nearer than the last (as the search makes them); few
        /// distinct distances make ties, in the middle and at the last slot, common.
        #[test]
        fn insert_turns_runs_of_equal_distance(
            distances in proptest::collection::vec(0u32..6, 1..60),
        ) {
            let mut want = [(Real::INFINITY, usize::MAX); SMOOTH_NEIGHBOURS];
            let mut got = want;
            for (id, &d) in distances.iter().enumerate() {
                let d = d as Real;
                if d < want[SMOOTH_NEIGHBOURS - 1].0 {
                    insert_by_runs(&mut want, d, id);
                    insert(&mut got, (d, id));
                }
                proptest::prop_assert_eq!(want, got);
            }
        }
    }

    #[test]
    fn a_missing_neighbour_has_no_miss_slot() {
        // `nearest` marks a missing neighbour with `usize::MAX`; its `3 * i` overflowed
        // (a panic with overflow checks, found by the update_mask fuzz target).
        assert_eq!(miss_slot(usize::MAX), None);
        assert_eq!(miss_slot(usize::MAX / 3 + 1), None);
        assert_eq!(miss_slot(2), Some(6..9));
    }

    #[test]
    fn two_boxes_pushed_alike_but_turned_apart_become_two_groups() {
        // Both pushed 2 cm; one turned 5 degrees more (about 4 mm of twist: within the
        // twist noise of single frames, far beyond the noise of a fit to 300 points).
        let (frames, body) = two_boxes([push(0.02, 0.0), push(0.02, 5.0)], 0.0015, 80);
        let frames = &frames[..160];
        let (count, frame_group, groups) = run(frames);
        assert_eq!(count, 2);
        // Each box's frames land in one group, and the two boxes in different ones.
        let group_of = |b: u8| {
            let mut n = [0usize; 2];
            for (g, x) in frame_group.iter().zip(&body).take(160) {
                if *x == b && *g < 2 {
                    n[usize::from(*g)] += 1;
                }
            }
            n
        };
        let (a, b) = (group_of(0), group_of(1));
        let pure = |n: [usize; 2]| n[0].max(n[1]);
        assert_ne!(a[0] > a[1], b[0] > b[1], "{a:?} {b:?}");
        assert!(pure(a) >= 78 && pure(b) >= 78, "{a:?} {b:?}");
        assert!(groups[0].moving && groups[1].moving);
        assert_eq!(groups[0].frames + groups[1].frames, 160);
    }

    /// The `misses` scratch is written before it is read: what a caller left in it (here
    /// NaN, zero or huge) never changes the split.
    #[test]
    fn leftovers_in_the_miss_scratch_do_not_matter() {
        let (frames, _) = two_boxes([push(0.02, 0.0), push(0.02, 5.0)], 0.0015, 80);
        let frames = &frames[..160];
        let first = GroupInfo {
            frames: 160,
            moving: true,
            label: 1,
            ..GroupInfo::default()
        };
        let mut results = std::vec::Vec::new();
        for junk in [0.0, Real::NAN, 1e30] {
            let mut frame_group = [0u16; 160];
            let mut groups = [GroupInfo::default(); 8];
            groups[0] = first;
            let mut side = [7u32; 160];
            let mut misses = [junk; 160 * MISS_SCRATCH_PER_FRAME];
            let count = split_mixed_groups(
                frames,
                &Point3::new(0.0, 0.0, 0.6),
                &Config::PAPER,
                &mut frame_group,
                &mut groups,
                1,
                (&mut side, &mut misses),
            );
            results.push((count, frame_group, groups));
        }
        assert_eq!(results[0].0, 2);
        assert!(results.windows(2).all(|w| w[0] == w[1]));
    }

    #[test]
    fn a_neighbour_dragged_a_few_millimetres_leaves_the_still_group() {
        let (frames, body) = two_boxes([Pose::identity(), push(0.004, 0.0)], 0.0015, 80);
        let (count, frame_group, groups) = run_with(&frames[..160], STILL, 8);
        assert_eq!(count, 2);
        // The still box keeps the still group; the dragged one moves.
        for (g, b) in frame_group.iter().zip(&body).take(160) {
            assert_eq!(*g, u16::from(*b));
        }
        assert!(!groups[0].moving && groups[1].moving);
    }

    #[test]
    fn a_still_group_that_moved_three_millimetres_is_moving_and_a_still_one_is_not() {
        for (dx_m, moving) in [(0.003, true), (0.0, false)] {
            let (frames, _) = two_boxes([push(dx_m, 0.0), push(dx_m, 0.0)], 0.0015, 80);
            let (count, _, groups) = run_with(&frames[..160], STILL, 4);
            assert_eq!(count, 1, "one body");
            assert_eq!(groups[0].moving, moving, "{dx_m} m");
            if moving {
                let v = groups[0].twist.v;
                assert!((v.x - dx_m).abs() < 5e-4 && v.y.abs() < 5e-4, "{v:?}");
            }
        }
    }

    #[test]
    fn one_body_with_noisy_points_is_not_split() {
        for noise_m in [0.0005, 0.0015, 0.003] {
            let (frames, _) = two_boxes([push(0.02, 2.0), push(0.02, 2.0)], noise_m, 80);
            let (count, frame_group, _) = run(&frames[..160]);
            assert_eq!(count, 1, "noise {noise_m}");
            assert!(frame_group.iter().all(|&g| g == 0));
        }
    }

    #[test]
    fn bodies_closer_than_the_split_gap_stay_one_group() {
        let (frames, _) = two_boxes([push(0.02, 0.0), push(0.0203, 0.0)], 0.0005, 80);
        assert_eq!(run(&frames[..160]).0, 1);
    }

    #[test]
    fn bodies_whose_pushes_differ_by_the_ceilings_floor_become_two_groups() {
        // 1 mm apart: the motion ceiling separates them, so the split must (the fit's gap
        // reads a little low, which a gate at the floor itself would miss).
        for dx_m in [0.0009, 0.001] {
            let (frames, body) = two_boxes([push(0.02, 0.0), push(0.02 + dx_m, 0.0)], 0.0005, 80);
            let (count, frame_group, _) = run(&frames[..160]);
            assert_eq!(count, 2, "{dx_m} m");
            let wrong = frame_group
                .iter()
                .zip(&body)
                .take(160)
                .filter(|&(&g, &b)| g != u16::from(b))
                .count();
            assert!(
                wrong <= 4 || wrong >= 156,
                "{wrong} frames in the other body's group"
            );
        }
    }

    #[test]
    fn small_groups_and_full_group_tables_are_left_alone() {
        let (frames, _) = two_boxes([push(0.02, 0.0), push(0.02, 10.0)], 0.0005, 10);
        assert_eq!(run(&frames[..20]).0, 1, "20 frames: two parts need 15 each");
        let (frames, _) = two_boxes([push(0.02, 0.0), push(0.02, 10.0)], 0.0005, 80);
        let (count, _, _) = run_with(&frames[..160], STILL, 1);
        assert_eq!(count, 1, "no room for a second group");
    }
}
