//! The motion ceiling: the best mask a method that starts from the static segmentation
//! and splits objects by how they moved can reach after the pushes made so far.
//!
//! RISeg is judged as a share of it: a push that moves two touching objects alike shows
//! nothing that could separate them, and no motion-based method should be blamed for
//! leaving them merged.
//!
//! # Contract
//!
//! [`MotionCeiling::next_frame`] takes the frames of one scene in order, frame `t` being
//! the scene after `t` pushes, each a [`CeilingFrame`]: the ground-truth instance labels
//! `G_t` (0 = background), the static segmentation `S_t` of the same image (0 =
//! background), both row-major `width · height`, and every object's true pose
//! `P_a(t)` (world frame; every non-zero label of `G_t` needs one). It returns the
//! ceiling mask of frame `t`: `G_t` with each merged group of objects relabelled to the
//! smallest ground-truth label in the group, background 0. The mask of frame `t` depends
//! on frames `0..=t` only, and on nothing else (no clocks, no randomness).
//!
//! Two objects `a`, `b` (labels of `G_t`) are **joined** in frame `t` when all of:
//!
//! 1. **Static segmentation merged them in every frame so far**: for every `s` in `0..=t`
//!    both are visible in `G_s` and [`static_segments`] gives them the same non-zero
//!    label: the static label covering the most of the object's visible pixels (the
//!    plurality, ties to the smaller label; a plurality of background means the static
//!    segmenter missed the object, which is never merged with another).
//! 2. **Every push so far moved them alike** ([`same_motion`]): for every push `s` in
//!    `1..=t`, with `M_a = P_a(s) · P_a(s−1)⁻¹` the world motion of `a` (likewise
//!    `M_b`), the rotation between them, `angle(R_a⁻¹ · R_b)`, is at most
//!    [`CeilingParams::rot_floor_rad`], and at both objects' centres `c` (the body
//!    origins `P_a(s−1)` and `P_b(s−1)`, world frame), `‖M_a·c − M_b·c‖` is at most
//!    [`CeilingParams::trans_floor_m`]. An object that did not move has `M = I`, so two
//!    objects that both stayed put moved alike; an object **moved** ([`moved`]) when its
//!    motion is not alike with `I`.
//! 3. **They touch in `G_t`** ([`touching_pairs`]): along one row or one column, a pixel
//!    of `a` and a pixel of `b` are separated by at most [`CeilingParams::touch_gap_px`]
//!    background pixels (0: 4-adjacent).
//!
//! Merged groups grow from the joined pairs, most alike first (the smallest worst
//! disagreement of the two motions over the pushes so far, as a multiple of the floors;
//! ties by labels), and a joined pair unites two groups only if every pair of objects
//! across them meets conditions 1 and 2. So three objects in a row whose neighbours are
//! joined form one group even if the outer two do not touch, but never when the outer
//! two moved differently: a group holds no two objects that some push moved differently
//! (a motion-based method has evidence to split those), and the middle one joins the
//! neighbour it moved more alike. Every object outside a group keeps its own label.
//!
//! Condition 1 is an equivalence (a plurality label is a function of the object); only
//! condition 2's floor is not transitive, which is why a union is checked across groups.
//!
//! # Poses
//!
//! A scene folder records the true poses in `poses.json` (format and rules in
//! [`crate::io::scene`]; read into [`Scene::poses`](crate::io::scene::Scene::poses), and given
//! per frame in a captured frame's `truth_poses`). The simulator's frames carry them too.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::Point3;
use riseg_core::Pose;

use crate::{
    io::scene::ObjectPose,
    segment::{union_find_join, union_find_root},
};

/// When two motions count as the same, and when two objects touch (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CeilingParams {
    /// Largest disagreement of two motions at either object's centre, metres.
    pub trans_floor_m: f32,
    /// Largest rotation between two motions, radians.
    pub rot_floor_rad: f32,
    /// Most background pixels between two objects that still touch, along a row or
    /// column (0: only 4-adjacent pixels).
    pub touch_gap_px: usize,
}

impl CeilingParams {
    /// 1 mm, 1.5 degrees, 2 pixels (the simulator's touch gap, 2 mm, is about 2 px at
    /// 0.6 m with a 615 px focal length). The rotation floor is the translation floor at
    /// an object's rim: 1.5° turns a point 4 cm from the centre by 1 mm. (At 0.5°, two
    /// boxes of one pushed row that each turned by a quarter degree the opposite way, a
    /// difference of 0.25 mm at their rims, far below what a camera resolves, counted as
    /// separable.)
    pub const DEFAULT: Self = Self {
        trans_floor_m: 0.001,
        rot_floor_rad: 1.5_f32.to_radians(),
        touch_gap_px: 2,
    };

    /// [`Self::DEFAULT`] with the translation floor `trans_floor_m` and the rotation floor
    /// scaled with it (so it stays the translation floor at an object's rim), e.g. a
    /// stricter yardstick for a method that resolves motions finer than 1 mm.
    #[must_use]
    pub fn with_floor_m(trans_floor_m: f32) -> Self {
        let d = Self::DEFAULT;
        Self {
            trans_floor_m,
            rot_floor_rad: d.rot_floor_rad * (trans_floor_m / d.trans_floor_m),
            ..d
        }
    }
}

impl Default for CeilingParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Why a ceiling could not be computed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CeilingError {
    /// A label map does not hold `width · height` labels.
    #[error("frame {frame}: the {what} has {got} labels, expected {width}x{height}")]
    Size {
        /// Frame index.
        frame: usize,
        /// `"ground truth"` or `"static segmentation"`.
        what: &'static str,
        /// Labels given.
        got: usize,
        /// Image width, pixels.
        width: usize,
        /// Image height, pixels.
        height: usize,
    },
    /// An object of the ground truth has no pose, or two.
    #[error("frame {frame}: {reason}")]
    FramePoses {
        /// Frame index.
        frame: usize,
        /// What is wrong, naming the label.
        reason: String,
    },
}

/// One frame of a scene, as the ceiling needs it (module docs). A captured frame lends
/// one with `rig::camera::CameraFrame::ceiling_frame`.
#[derive(Debug, Clone, Copy)]
pub struct CeilingFrame<'a> {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Ground-truth instance labels, row-major, 0 = background.
    pub truth: &'a [u16],
    /// The static segmentation of the same image, row-major, 0 = background.
    pub static_labels: &'a [u16],
    /// Every object's true pose, world frame.
    pub poses: &'a [ObjectPose],
}

/// The motion ceiling of one scene, frame after frame (module docs).
#[derive(Debug, Clone)]
pub struct MotionCeiling {
    params: CeilingParams,
    /// Frames seen so far.
    frames: usize,
    /// Object pairs `(a, b)`, `a < b`, that met conditions 1 and 2 in every frame so far,
    /// with their worst disagreement over the pushes so far ([`disagreement`]).
    candidates: BTreeMap<(u16, u16), f32>,
    /// The poses of the previous frame, by label.
    previous: BTreeMap<u16, Pose>,
}

impl MotionCeiling {
    /// A new scene: the next frame is frame 0.
    #[must_use]
    pub const fn new(params: CeilingParams) -> Self {
        Self {
            params,
            frames: 0,
            candidates: BTreeMap::new(),
            previous: BTreeMap::new(),
        }
    }

    /// The ceiling mask of the next frame (module docs).
    ///
    /// # Errors
    /// [`CeilingError::Size`] if a label map does not hold `width · height` labels;
    /// [`CeilingError::FramePoses`] if a label of the ground truth has no pose or two.
    pub fn next_frame(&mut self, frame: &CeilingFrame<'_>) -> Result<Vec<u16>, CeilingError> {
        let t = self.frames;
        for (what, labels) in [
            ("ground truth", frame.truth),
            ("static segmentation", frame.static_labels),
        ] {
            if Some(labels.len()) != frame.width.checked_mul(frame.height) {
                return Err(CeilingError::Size {
                    frame: t,
                    what,
                    got: labels.len(),
                    width: frame.width,
                    height: frame.height,
                });
            }
        }
        let segment_of = static_segments(frame.truth, frame.static_labels);
        let poses = poses_by_label(frame.poses, segment_of.keys().copied())
            .map_err(|reason| CeilingError::FramePoses { frame: t, reason })?;
        let merged = |a: &u16, b: &u16| matches!((segment_of.get(a), segment_of.get(b)), (Some(&sa), Some(&sb)) if sa == sb && sa != 0);
        if t == 0 {
            let objects: Vec<u16> = segment_of.keys().copied().collect();
            self.candidates = objects
                .iter()
                .enumerate()
                .flat_map(|(i, a)| objects[i + 1..].iter().map(move |b| (*a, *b)))
                .filter(|(a, b)| merged(a, b))
                .map(|pair| (pair, 0.0))
                .collect();
        } else {
            let params = self.params;
            let previous = &self.previous;
            // Both objects of a candidate were visible in the previous frame, and are in
            // this one when `merged` holds, so all four poses exist.
            self.candidates.retain(|(a, b), worst| {
                merged(a, b)
                    && match (previous.get(a), poses.get(a), previous.get(b), poses.get(b)) {
                        (Some(a0), Some(a1), Some(b0), Some(b1)) => {
                            *worst = worst.max(disagreement([a0, a1], [b0, b1], &params));
                            same_motion([a0, a1], [b0, b1], &params)
                        }
                        _ => false,
                    }
            });
        }
        self.previous = poses;
        self.frames += 1;
        let touching = touching_pairs(
            frame.truth,
            frame.width,
            frame.height,
            self.params.touch_gap_px,
        );
        Ok(merge_objects(frame.truth, &self.candidates, &touching))
    }
}

/// The static segment of each object visible in `truth`: the label of `static_labels`
/// covering the most of its pixels (ties to the smaller label; 0 when background covers
/// the most). Both maps row-major, same length.
#[must_use]
pub fn static_segments(truth: &[u16], static_labels: &[u16]) -> BTreeMap<u16, u16> {
    let mut counts: BTreeMap<(u16, u16), usize> = BTreeMap::new();
    // Runs of one (object, segment) pair are counted at once: labels come in spans.
    let mut run: Option<((u16, u16), usize)> = None;
    for pair in truth.iter().copied().zip(static_labels.iter().copied()) {
        match &mut run {
            Some((p, n)) if *p == pair => *n += 1,
            _ => {
                if let Some((p, n)) = run.replace((pair, 1)) {
                    *counts.entry(p).or_default() += n;
                }
            }
        }
    }
    if let Some((p, n)) = run {
        *counts.entry(p).or_default() += n;
    }
    let mut segment_of: BTreeMap<u16, (u16, usize)> = BTreeMap::new();
    // Keys ascend by (object, segment): a later segment wins only with strictly more.
    for ((object, segment), n) in counts {
        if object == 0 {
            continue;
        }
        let best = segment_of.entry(object).or_insert((segment, n));
        if n > best.1 {
            *best = (segment, n);
        }
    }
    segment_of.into_iter().map(|(o, (s, _))| (o, s)).collect()
}

/// Whether two objects moved alike between two frames (module docs, condition 2): `a`
/// and `b` are each `[pose before, pose after]`, world frame.
#[must_use]
pub fn same_motion(a: [&Pose; 2], b: [&Pose; 2], params: &CeilingParams) -> bool {
    let (angle_rad, apart_m) = motion_gaps(a, b);
    angle_rad <= params.rot_floor_rad && apart_m <= params.trans_floor_m
}

/// How far apart two motions are (`a`, `b` as in [`same_motion`]): the rotation between
/// them, radians, and the larger distance between their images of either object's
/// centre, metres.
#[must_use]
pub fn motion_gaps(a: [&Pose; 2], b: [&Pose; 2]) -> (f32, f32) {
    let motion_a = a[1] * a[0].inverse();
    let motion_b = b[1] * b[0].inverse();
    // 2·atan2(|v|, |w|) of the quaternion between them: unlike nalgebra's acos form, it
    // keeps its precision for the fractions of a degree compared here.
    let between = motion_a.rotation.rotation_to(&motion_b.rotation);
    let angle_rad = 2.0 * libm::atan2f(between.imag().norm(), between.w.abs());
    let apart_m = [a[0], b[0]]
        .iter()
        .map(|before| {
            let centre = Point3::from(before.translation.vector);
            (motion_a * centre - motion_b * centre).norm()
        })
        .fold(0.0, f32::max);
    (angle_rad, apart_m)
}

/// How unalike two motions are (`a`, `b` as in [`same_motion`]), as a multiple of the
/// floors: the larger of the rotation between them over the rotation floor and their
/// distance at the centres over the translation floor (a gap over a zero floor is
/// infinite). Orders the joined pairs of a ceiling (module docs).
#[must_use]
pub fn disagreement(a: [&Pose; 2], b: [&Pose; 2], params: &CeilingParams) -> f32 {
    let (angle_rad, apart_m) = motion_gaps(a, b);
    let over = |gap: f32, floor: f32| {
        if floor > 0.0 {
            gap / floor
        } else if gap > 0.0 {
            f32::INFINITY
        } else {
            0.0
        }
    };
    over(angle_rad, params.rot_floor_rad).max(over(apart_m, params.trans_floor_m))
}

/// Whether an object moved between two frames beyond the floors of [`same_motion`]: its
/// motion, `[pose before, pose after]` (world frame), is not alike with staying put.
#[must_use]
pub fn moved(pose: [&Pose; 2], params: &CeilingParams) -> bool {
    !same_motion(pose, [pose[0], pose[0]], params)
}

/// Object pairs `(a, b)`, `a < b`, of `truth` (row-major `width × height`) that touch: on
/// one row or one column, a pixel of `a` and one of `b` with at most `gap_px` background
/// pixels between them.
#[must_use]
pub fn touching_pairs(
    truth: &[u16],
    width: usize,
    height: usize,
    gap_px: usize,
) -> BTreeSet<(u16, u16)> {
    let mut pairs = BTreeSet::new();
    let mut scan = |line: &mut dyn Iterator<Item = u16>| {
        let mut last: Option<(u16, usize)> = None;
        for (i, label) in line.enumerate() {
            if label == 0 {
                continue;
            }
            if let Some((other, at)) = last
                && other != label
                && i - at - 1 <= gap_px
            {
                pairs.insert((other.min(label), other.max(label)));
            }
            last = Some((label, i));
        }
    };
    for row in truth.chunks_exact(width.max(1)).take(height) {
        scan(&mut row.iter().copied());
    }
    for x in 0..width {
        scan(&mut truth.iter().skip(x).step_by(width).take(height).copied());
    }
    pairs
}

/// `truth` with each merged group relabelled to its smallest label: the `candidates`
/// (pairs meeting conditions 1 and 2, with their worst disagreement) that also touch are
/// joined most alike first, each only if every pair across the two groups it unites is a
/// candidate (module docs).
fn merge_objects(
    truth: &[u16],
    candidates: &BTreeMap<(u16, u16), f32>,
    touching: &BTreeSet<(u16, u16)>,
) -> Vec<u16> {
    let mut joined: Vec<((u16, u16), f32)> = candidates
        .iter()
        .filter(|(pair, _)| touching.contains(pair))
        .map(|(&pair, &worst)| (pair, worst))
        .collect();
    joined.sort_by(|(p, x), (q, y)| x.total_cmp(y).then(p.cmp(q)));
    let mut parent: Vec<u32> = (0..=u32::from(u16::MAX)).collect();
    // The members of each group, by its root.
    let mut members: BTreeMap<u32, Vec<u16>> = BTreeMap::new();
    for ((a, b), _) in joined {
        let (ra, rb) = (
            union_find_root(&mut parent, u32::from(a)),
            union_find_root(&mut parent, u32::from(b)),
        );
        if ra == rb {
            continue;
        }
        let group = |r: u32, l: u16| members.get(&r).cloned().unwrap_or_else(|| vec![l]);
        let (ga, gb) = (group(ra, a), group(rb, b));
        let alike = ga.iter().all(|&x| {
            gb.iter()
                .all(|&y| candidates.contains_key(&(x.min(y), x.max(y))))
        });
        if alike {
            union_find_join(&mut parent, ra, rb);
            members.remove(&ra);
            members.remove(&rb);
            members.insert(ra.min(rb), [ga, gb].concat());
        }
    }
    // Roots are the smallest index of their tree, and every index is a u16 label.
    let mut root = |label: u16| union_find_root(&mut parent, u32::from(label)) as u16;
    truth.iter().map(|&label| root(label)).collect()
}

/// The poses by label; every label of `objects` must have exactly one (the error says
/// which label has none, or two).
pub(crate) fn poses_by_label(
    poses: &[ObjectPose],
    objects: impl Iterator<Item = u16>,
) -> Result<BTreeMap<u16, Pose>, String> {
    let mut by_label = BTreeMap::new();
    for p in poses {
        if by_label.insert(p.label, p.world_from_object).is_some() {
            return Err(format!("object {} has two poses", p.label));
        }
    }
    for label in objects {
        if !by_label.contains_key(&label) {
            return Err(format!(
                "object {label} is in the ground truth but has no pose"
            ));
        }
    }
    Ok(by_label)
}

/// A three-object scene shared by the tests of the ceiling and of the bench.
#[cfg(test)]
pub(crate) mod fixture {
    use riseg_core::Pose;

    use crate::io::scene::ObjectPose;

    /// Width of [`row_of_three`], pixels.
    pub(crate) const W: usize = 12;
    /// Height of [`row_of_three`], pixels.
    pub(crate) const H: usize = 3;

    /// 12×3 image: three 3-pixel-wide objects in a row (labels 1, 2, 3), flush, with
    /// background columns at both ends.
    pub(crate) fn row_of_three() -> Vec<u16> {
        let row: [u16; W] = [0, 1, 1, 1, 2, 2, 2, 3, 3, 3, 0, 0];
        row.repeat(H)
    }

    /// Object `label` at `x_m` along the world x axis, unrotated.
    pub(crate) fn at(label: u16, x_m: f32) -> ObjectPose {
        ObjectPose {
            label,
            world_from_object: Pose::translation(x_m, 0.0, 0.0),
        }
    }

    /// The three objects 5 cm apart.
    pub(crate) fn start() -> Vec<ObjectPose> {
        vec![at(1, 0.0), at(2, 0.05), at(3, 0.10)]
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests: a panic is the failure report")]

    use nalgebra::Vector3;

    use super::{fixture::*, *};

    /// The static segmentation that merges every object into segment 7.
    fn all_merged() -> Vec<u16> {
        row_of_three()
            .iter()
            .map(|&l| if l == 0 { 0 } else { 7 })
            .collect()
    }

    /// `poses` with `label` moved by `dx_m` along x.
    fn moved(poses: &[ObjectPose], label: u16, dx_m: f32) -> Vec<ObjectPose> {
        poses
            .iter()
            .map(|p| {
                if p.label == label {
                    at(label, p.world_from_object.translation.x + dx_m)
                } else {
                    *p
                }
            })
            .collect()
    }

    /// Runs the ceiling over frames sharing `truth`, with `statics[t]` and `poses[t]`;
    /// returns the groups of each frame as sets of ground-truth labels.
    fn groups(
        truth: &[u16],
        statics: &[Vec<u16>],
        poses: &[Vec<ObjectPose>],
    ) -> Vec<Vec<Vec<u16>>> {
        let mut ceiling = MotionCeiling::new(CeilingParams::DEFAULT);
        statics
            .iter()
            .zip(poses)
            .map(|(s, p)| {
                let mask = ceiling
                    .next_frame(&CeilingFrame {
                        width: W,
                        height: H,
                        truth,
                        static_labels: s,
                        poses: p,
                    })
                    .unwrap();
                let mut by_id: BTreeMap<u16, BTreeSet<u16>> = BTreeMap::new();
                for (&t, &m) in truth.iter().zip(&mask) {
                    if t != 0 {
                        by_id.entry(m).or_default().insert(t);
                    }
                }
                by_id
                    .into_values()
                    .map(|g| g.into_iter().collect())
                    .collect()
            })
            .collect()
    }

    #[test]
    fn pushes_separate_what_moved_differently_and_nothing_else() {
        let truth = row_of_three();
        let p0 = start();
        let p1 = moved(&p0, 3, 0.02); // push 1 moves object 3 only
        let p2 = moved(&moved(&p1, 1, 0.02), 2, 0.02); // push 2 moves 1 and 2 alike
        let statics = vec![all_merged(); 3];
        let got = groups(&truth, &statics, &[p0, p1, p2]);
        assert_eq!(got[0], [vec![1, 2, 3]]);
        assert_eq!(got[1], [vec![1, 2], vec![3]]);
        assert_eq!(got[2], [vec![1, 2], vec![3]]);
    }

    #[test]
    fn a_group_never_holds_two_objects_that_moved_differently() {
        // Push 1 moves 1 not at all, 2 by 0.7 mm and 3 by 1.6 mm: 1-2 (0.7 mm) and 2-3
        // (0.9 mm) moved alike within the 1 mm floor, 1-3 (1.6 mm) did not. Chaining the
        // alike neighbours would merge all three; 2 goes with 1, which it moved more alike.
        let truth = row_of_three();
        let p0 = start();
        let p1 = moved(&moved(&p0, 2, 0.0007), 3, 0.0016);
        let got = groups(&truth, &vec![all_merged(); 2], &[p0.clone(), p1]);
        assert_eq!(got[1], [vec![1, 2], vec![3]]);
        // 2 moved by 0.9 mm: now more alike with 3 (0.7 mm) than with 1 (0.9 mm).
        let p1 = moved(&moved(&p0, 2, 0.0009), 3, 0.0016);
        let got = groups(&truth, &vec![all_merged(); 2], &[p0, p1]);
        assert_eq!(got[1], [vec![1], vec![2, 3]]);
    }

    #[test]
    fn disagreement_is_the_larger_gap_over_its_floor() {
        // Objects 1 and 2 of the fixture, 5 cm apart, shifted by 20.5 and 20 mm: 0.5 mm
        // apart is half the translation floor.
        let pose = |label, x_m| at(label, x_m).world_from_object;
        let (a0, b0) = (pose(1, 0.0), pose(2, 0.05));
        let (a1, b1) = (pose(1, 0.0205), pose(2, 0.07));
        let d = disagreement([&a0, &a1], [&b0, &b1], &CeilingParams::DEFAULT);
        assert!((d - 0.5).abs() < 1e-3, "{d}");
        // Over a zero floor, no gap is 0 and any gap is infinite.
        let zero = CeilingParams {
            trans_floor_m: 0.0,
            ..CeilingParams::DEFAULT
        };
        assert_eq!(disagreement([&a0, &a0], [&b0, &b0], &zero), 0.0);
        assert_eq!(disagreement([&a0, &a1], [&b0, &b0], &zero), f32::INFINITY);
    }

    #[test]
    fn a_push_that_moves_one_of_a_merged_pair_separates_it() {
        let truth = row_of_three();
        let p0 = start();
        let p1 = moved(&p0, 3, 0.02);
        let p2 = moved(&p1, 1, 0.02); // push 2 moves 1 alone
        let got = groups(&truth, &vec![all_merged(); 3], &[p0, p1, p2]);
        assert_eq!(got[2], [vec![1], vec![2], vec![3]]);
    }

    #[test]
    fn a_static_split_is_never_undone_even_if_the_motions_agree() {
        let truth = row_of_three();
        // Frame 0: the segmenter separates 1 from {2, 3}; later it merges all.
        let split: Vec<u16> = truth
            .iter()
            .map(|&l| [0, 4, 7, 7][usize::from(l)])
            .collect();
        let statics = vec![split, all_merged(), all_merged()];
        let still = start();
        let got = groups(&truth, &statics, &[still.clone(), still.clone(), still]);
        for frame in got {
            assert_eq!(frame, [vec![1], vec![2, 3]]);
        }
    }

    #[test]
    fn objects_that_do_not_touch_are_never_merged_directly() {
        // 1 and 3 with a 3-pixel gap (more than the 2-pixel touch gap); 2 elsewhere.
        let row: [u16; W] = [1, 1, 0, 0, 0, 3, 3, 0, 0, 0, 2, 2];
        let truth = row.repeat(H);
        let merged: Vec<u16> = truth.iter().map(|&l| if l == 0 { 0 } else { 7 }).collect();
        let still = start();
        let got = groups(&truth, &[merged], &[still]);
        assert_eq!(got[0], [vec![1], vec![2], vec![3]]);

        // With a 2-pixel gap they touch.
        let row: [u16; W] = [1, 1, 0, 0, 3, 3, 0, 0, 0, 0, 2, 2];
        let pairs = touching_pairs(&row.repeat(H), W, H, 2);
        assert_eq!(pairs, BTreeSet::from([(1, 3)]));
        // An object in between blocks: 1 and 2 do not touch through 3.
        assert!(!touching_pairs(&row_of_three(), W, H, 2).contains(&(1, 3)));
    }

    #[test]
    fn touching_is_found_along_columns_too() {
        // 2 wide, 5 tall: 1 on top, one background row, 2 below.
        let truth = [1, 1, 1, 1, 0, 0, 2, 2, 2, 2];
        assert_eq!(touching_pairs(&truth, 2, 5, 1), BTreeSet::from([(1, 2)]));
        assert!(touching_pairs(&truth, 2, 5, 0).is_empty());
    }

    #[test]
    fn static_segments_take_the_plurality_and_background_never_merges() {
        // Object 1: 3 px in segment 5, 2 in 6 → 5. Object 2: 2 px of background, 1 of 5.
        let truth = [1, 1, 1, 1, 1, 2, 2, 2];
        let stat = [5, 6, 5, 6, 5, 0, 5, 0];
        assert_eq!(
            static_segments(&truth, &stat),
            BTreeMap::from([(1, 5), (2, 0)])
        );
        // A tie goes to the smaller label.
        assert_eq!(static_segments(&[3, 3], &[9, 4]), BTreeMap::from([(3, 4)]));
        // Both objects mostly background: not merged with each other.
        let truth = [1, 1, 2, 2];
        let stat = [0, 0, 0, 0];
        let got = groups_of(&truth, &stat);
        assert_eq!(got, [vec![1], vec![2]]);
    }

    fn groups_of(truth: &[u16], stat: &[u16]) -> Vec<Vec<u16>> {
        let mut ceiling = MotionCeiling::new(CeilingParams::DEFAULT);
        let poses = [at(1, 0.0), at(2, 0.1)];
        let mask = ceiling
            .next_frame(&CeilingFrame {
                width: truth.len(),
                height: 1,
                truth,
                static_labels: stat,
                poses: &poses,
            })
            .unwrap();
        let mut ids: BTreeMap<u16, Vec<u16>> = BTreeMap::new();
        for (&t, &m) in truth.iter().zip(&mask) {
            let g = ids.entry(m).or_default();
            if !g.contains(&t) {
                g.push(t);
            }
        }
        ids.into_values().collect()
    }

    #[test]
    fn motions_are_compared_at_both_centres_within_the_floors() {
        let p = CeilingParams::DEFAULT;
        let a0 = Pose::translation(0.0, 0.0, 0.0);
        let b0 = Pose::translation(0.05, 0.0, 0.0);
        let shift = |pose: &Pose, dx: f32| Pose::translation(dx, 0.0, 0.0) * pose;
        // Same translation, and one within the floor.
        assert!(same_motion(
            [&a0, &shift(&a0, 0.02)],
            [&b0, &shift(&b0, 0.02)],
            &p
        ));
        assert!(same_motion(
            [&a0, &shift(&a0, 0.0205)],
            [&b0, &shift(&b0, 0.02)],
            &p
        ));
        assert!(!same_motion(
            [&a0, &shift(&a0, 0.0215)],
            [&b0, &shift(&b0, 0.02)],
            &p
        ));
        // Rotating both about a's centre is one rigid motion: the same.
        let turn = |deg: f32| Pose::rotation(Vector3::z() * deg.to_radians());
        assert!(same_motion(
            [&a0, &(turn(10.0) * a0)],
            [&b0, &(turn(10.0) * b0)],
            &p
        ));
        // Each turning in place by 10 degrees: the rotations agree but at b's centre a's
        // motion would carry b 8.7 mm away.
        let in_place = |pose: &Pose, deg: f32| {
            Pose::from_parts(pose.translation, turn(deg).rotation * pose.rotation)
        };
        assert!(!same_motion(
            [&a0, &in_place(&a0, 10.0)],
            [&b0, &in_place(&b0, 10.0)],
            &p
        ));
        // Turning in place by 1.0 and -0.4 degrees (1.4 apart) passes: either turn moves
        // the other's centre, 5 cm away, by at most 0.05 m · 1° ≈ 0.9 mm. By 1.0 and -0.6
        // degrees (1.6 apart) fails on the angle alone.
        let spin = |pose: &Pose, deg: f32| {
            Pose::from_parts(pose.translation, turn(deg).rotation * pose.rotation)
        };
        assert!(same_motion(
            [&a0, &spin(&a0, 1.0)],
            [&b0, &spin(&b0, -0.4)],
            &p
        ));
        assert!(!same_motion(
            [&a0, &spin(&a0, 1.0)],
            [&b0, &spin(&b0, -0.6)],
            &p
        ));
    }

    #[test]
    fn a_lower_floor_separates_what_the_default_floor_joins() {
        let a0 = Pose::translation(0.0, 0.0, 0.0);
        let b0 = Pose::translation(0.05, 0.0, 0.0);
        let shift = |pose: &Pose, dx: f32| Pose::translation(dx, 0.0, 0.0) * pose;
        let spin = |pose: &Pose, deg: f32| {
            Pose::from_parts(
                pose.translation,
                Pose::rotation(Vector3::z() * deg.to_radians()).rotation * pose.rotation,
            )
        };
        // 0.7 mm apart, and in-place turns 1 degree apart (each moving the other's centre
        // by 0.44 mm): alike at 1 mm (1.5 degrees), not at 0.5 mm (0.75 degrees).
        let pushed = ([&a0, &shift(&a0, 0.0207)], [&b0, &shift(&b0, 0.02)]);
        let turned = ([&a0, &spin(&a0, 0.5)], [&b0, &spin(&b0, -0.5)]);
        let (one, half) = (
            CeilingParams::with_floor_m(0.001),
            CeilingParams::with_floor_m(0.0005),
        );
        assert_eq!(one, CeilingParams::DEFAULT);
        assert!((half.rot_floor_rad - 0.75_f32.to_radians()).abs() < 1e-6);
        for (a, b) in [pushed, turned] {
            assert!(same_motion(a, b, &one));
            assert!(!same_motion(a, b, &half));
        }
    }

    #[test]
    fn moved_means_beyond_the_floors_of_staying_put() {
        let p = CeilingParams::DEFAULT;
        let a0 = Pose::translation(0.3, 0.1, 0.02);
        let shift = |dx: f32| Pose::translation(dx, 0.0, 0.0) * a0;
        let spin = |deg: f32| {
            Pose::from_parts(
                a0.translation,
                Pose::rotation(Vector3::z() * deg.to_radians()).rotation,
            )
        };
        assert!(!super::moved([&a0, &a0], &p));
        assert!(!super::moved([&a0, &shift(0.0009)], &p));
        assert!(super::moved([&a0, &shift(0.0011)], &p));
        // Turning in place moves no centre: only the angle decides.
        assert!(!super::moved([&a0, &spin(1.4)], &p));
        assert!(super::moved([&a0, &spin(1.6)], &p));
    }

    #[test]
    fn missing_or_doubled_poses_and_bad_sizes_are_errors() {
        let truth = row_of_three();
        let fault = |static_labels: &[u16], poses: &[ObjectPose]| {
            MotionCeiling::new(CeilingParams::DEFAULT)
                .next_frame(&CeilingFrame {
                    width: W,
                    height: H,
                    truth: &truth,
                    static_labels,
                    poses,
                })
                .unwrap_err()
                .to_string()
        };
        let p = start();
        assert_eq!(
            fault(&truth, &p[..2]),
            "frame 0: object 3 is in the ground truth but has no pose"
        );
        assert_eq!(
            fault(&truth, &[p[0], p[1], p[2], p[0]]),
            "frame 0: object 1 has two poses"
        );
        assert_eq!(
            fault(&truth[1..], &p),
            "frame 0: the static segmentation has 35 labels, expected 12x3"
        );
    }
}
