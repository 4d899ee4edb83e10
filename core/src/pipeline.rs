//! One UpdateMask step (Algorithm 3) over a caller-owned [`Workspace`], and the loop state
//! of Algorithm 1. No I/O: the caller brings images and executes pushes.
//!
//! A step is CreateFrames → CalcBFIFs → GroupBFIFs (twist groups, then groups that two
//! rigid motions explain split: [`crate::split`]) → CorrectMask; each stage is also
//! callable on its own ([`create_frames`], [`compute_twists`], [`group_frames`],
//! [`correct_mask`]) for per-stage timing or display. In a step, CalcBFIFs costs nothing:
//! CreateFrames checks each frame by its twist and hands that twist over, bit for bit
//! what [`compute_twists`] gives.
//!
//! [`create_frames`]: crate::frames::create_frames
//! [`compute_twists`]: crate::frames::compute_twists

use crate::{
    Config, Error, ImageView, Twist,
    error::{Buffer, check_len},
    frames::{BodyFrame, FrameSample, FrameSet, MotionInput, create_frames_with_twists},
    group::{GroupInfo, GroupScratch, GroupScratchLen, Grouping, group_frames},
    mask::{FrameGroups, MaskReport, MaskScratch, MaskScratchLen, correct_mask},
    split::split_mixed_groups,
};

/// All scratch and intermediate buffers of one step. Intermediate results (frames, twists,
/// groups) stay readable after [`update_mask`] for display.
#[derive(Debug)]
pub struct Workspace<'a> {
    /// CreateFrames scratch; [`Config::frame_samples`] entries.
    pub samples: &'a mut [FrameSample],
    /// Frames; [`Config::frame_samples`] entries.
    pub frames: &'a mut [BodyFrame],
    /// Twist of each frame; [`Config::frame_samples`] entries.
    pub twists: &'a mut [Twist],
    /// Accumulated-mask label of each frame; [`Config::frame_samples`] entries.
    pub frame_labels: &'a mut [u16],
    /// Group of each frame; [`Config::frame_samples`] entries.
    pub frame_group: &'a mut [u16],
    /// Groups; [`Config::frame_samples`] entries.
    pub groups: &'a mut [GroupInfo],
    /// GroupBFIFs scratch.
    pub group: GroupScratch<'a>,
    /// CorrectMask scratch.
    pub mask: MaskScratch<'a>,
}

impl Workspace<'_> {
    /// Checks every slice against `len`.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`] naming the first slice that is too short.
    pub fn check(&self, len: &WorkspaceLen) -> Result<(), Error> {
        let n = len.frames;
        check_len(Buffer::Samples, n, self.samples.len())?;
        check_len(Buffer::Frames, n, self.frames.len())?;
        for l in [
            self.twists.len(),
            self.frame_labels.len(),
            self.frame_group.len(),
        ] {
            check_len(Buffer::FrameScratch, n, l)?;
        }
        check_len(Buffer::Groups, n, self.groups.len())?;
        let g = &self.group;
        check_len(Buffer::PairDist, len.group.pair_bin, g.pair_bin.len())?;
        for l in [g.parent.len(), g.links.len(), g.attach.len()] {
            check_len(Buffer::FrameScratch, len.group.per_frame, l)?;
        }
        check_len(
            Buffer::FrameScratch,
            len.group.twist_lanes,
            g.twist_lanes.len(),
        )?;
        let m = &self.mask;
        let px = len.mask.pixels;
        for l in [m.key.len(), m.source.len(), m.segment.len()] {
            check_len(Buffer::Pixels, px, l)?;
        }
        check_len(Buffer::Queue, px, m.queue.len())?;
        for l in [
            m.segment_size.len(),
            m.segment_target.len(),
            m.segment_key.len(),
        ] {
            check_len(Buffer::Segments, len.mask.segments, l)?;
        }
        check_len(Buffer::Seeds, len.mask.seeds, m.seeds.len())?;
        check_len(Buffer::Groups, len.mask.motions, m.motions.len())
    }
}

/// Element counts of every [`Workspace`] slice for a config and image size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WorkspaceLen {
    /// Length of each per-frame slice (`samples` … `groups`).
    pub frames: usize,
    /// GroupBFIFs scratch lengths.
    pub group: GroupScratchLen,
    /// CorrectMask scratch lengths.
    pub mask: MaskScratchLen,
}

impl WorkspaceLen {
    /// Lengths for `cfg` at `width × height`.
    #[must_use]
    pub const fn for_config(cfg: &Config, width: usize, height: usize) -> Self {
        let n = cfg.frame_samples;
        Self {
            frames: n,
            group: GroupScratchLen::for_frames(n),
            mask: MaskScratchLen::new(width, height, n),
        }
    }

    /// Bytes the whole workspace takes.
    #[must_use]
    pub const fn bytes(&self) -> usize {
        // samples, frames, twists, frame_labels and frame_group (u16 each), groups.
        let per_frame = size_of::<FrameSample>()
            + size_of::<BodyFrame>()
            + size_of::<Twist>()
            + 2 * size_of::<u16>()
            + size_of::<GroupInfo>();
        self.frames
            .saturating_mul(per_frame)
            .saturating_add(self.group.bytes())
            .saturating_add(self.mask.bytes())
    }
}

/// What one step did, stage by stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepReport {
    /// CreateFrames.
    pub frames: FrameSet,
    /// GroupBFIFs.
    pub grouping: Grouping,
    /// CorrectMask.
    pub mask: MaskReport,
}

/// The stages of one [`update_mask`] step, in order, as reported to the observer of
/// [`update_mask_observed`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// CreateFrames finished.
    Frames,
    /// CalcBFIFs (the twists) finished: in a step they come with the frames, so this
    /// follows [`Stage::Frames`] at once.
    Twists,
    /// GroupBFIFs finished.
    Grouping,
    /// CorrectMask finished.
    Mask,
}

/// UpdateMask (Algorithm 3): from the accumulated mask at `t` (in `input`), the static mask
/// at `t+1` and the flow, writes the corrected mask at `t+1` to `labels_t1`.
///
/// # Errors
/// [`Error::BufferTooSmall`] if a workspace slice is shorter than [`WorkspaceLen`] says
/// (checked up front, nothing written); otherwise the errors of the stages.
pub fn update_mask(
    input: &MotionInput<'_>,
    static_t1: &ImageView<'_, u16>,
    cfg: &Config,
    ws: &mut Workspace<'_>,
    labels_t1: &mut [u16],
) -> Result<StepReport, Error> {
    update_mask_observed(input, static_t1, cfg, ws, labels_t1, |_| {})
}

/// [`update_mask`], calling `on_stage` as each stage finishes (a host reads a clock there
/// for per-stage timing; the core itself has none).
///
/// # Errors
/// As [`update_mask`].
pub fn update_mask_observed(
    input: &MotionInput<'_>,
    static_t1: &ImageView<'_, u16>,
    cfg: &Config,
    ws: &mut Workspace<'_>,
    labels_t1: &mut [u16],
    mut on_stage: impl FnMut(Stage),
) -> Result<StepReport, Error> {
    cfg.check()?;
    let (width, height) = input.size();
    ws.check(&WorkspaceLen::for_config(cfg, width, height))?;
    // CreateFrames checks each frame by its twist: that is CalcBFIFs' result, kept.
    let twists_out = &mut *ws.twists;
    let frames = create_frames_with_twists(input, cfg, ws.samples, ws.frames, |at, twist| {
        if let Some(slot) = twists_out.get_mut(at) {
            *slot = twist;
        }
    })?;
    on_stage(Stage::Frames);
    let count = frames.count;
    let (Some(frame_list), Some(twists), Some(labels)) = (
        ws.frames.get(..count),
        ws.twists.get_mut(..count),
        ws.frame_labels.get_mut(..count),
    ) else {
        return Err(Error::BufferTooSmall {
            buffer: Buffer::Frames,
            needed: count,
            got: 0,
        });
    };
    on_stage(Stage::Twists);
    for (l, f) in labels.iter_mut().zip(frame_list) {
        *l = f.label;
    }
    let frame_group = ws.frame_group.get_mut(..count).unwrap_or(&mut []);
    let mut grouping = group_frames(twists, labels, cfg, &mut ws.group, frame_group, ws.groups)?;
    let twist_groups = grouping.count;
    grouping.count = split_mixed_groups(
        frame_list,
        &frames.space_origin,
        cfg,
        frame_group,
        ws.groups,
        twist_groups,
        (&mut *ws.group.parent, &mut *ws.group.twist_lanes),
    );
    grouping.mixed_splits = grouping.count.saturating_sub(twist_groups);
    on_stage(Stage::Grouping);
    let groups = FrameGroups {
        frames: frame_list,
        frame_group,
        groups: ws.groups.get(..grouping.count).unwrap_or(&[]),
        space_origin: frames.space_origin,
    };
    let mask = correct_mask(input, static_t1, &groups, cfg, &mut ws.mask, labels_t1)?;
    on_stage(Stage::Mask);
    Ok(StepReport {
        frames,
        grouping,
        mask,
    })
}

/// Loop state of Algorithm 1: counts pushes and decides when to stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RisegLoop {
    pushes_done: u32,
    max_pushes: u32,
    finished: bool,
}

impl RisegLoop {
    /// A loop that will make at most `cfg.max_pushes` pushes.
    #[must_use]
    pub const fn new(cfg: &Config) -> Self {
        Self {
            pushes_done: 0,
            max_pushes: cfg.max_pushes,
            finished: false,
        }
    }

    /// Takes FindAction's result for the current image: returns the push to execute, or
    /// `None` when the loop stops (no action qualifies, or the push budget is spent). Once
    /// stopped it stays stopped.
    pub fn next<A>(&mut self, action: Option<A>) -> Option<A> {
        if self.finished || self.pushes_done >= self.max_pushes {
            self.finished = true;
            return None;
        }
        match action {
            Some(a) => {
                self.pushes_done += 1;
                Some(a)
            }
            None => {
                self.finished = true;
                None
            }
        }
    }

    /// Pushes handed out so far.
    #[must_use]
    pub const fn pushes_done(&self) -> u32 {
        self.pushes_done
    }

    /// Whether the loop has stopped.
    #[must_use]
    pub const fn is_finished(&self) -> bool {
        self.finished
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use std::{vec, vec::Vec};

    use nalgebra::{Translation3, Vector3};

    use super::*;
    use crate::{
        Pose,
        frames::{compute_twists, create_frames},
        synth::{
            SynthBox,
            fixture::{Rendered, box_at, render, spin_about},
        },
        test_workspace::WorkspaceBuf,
    };

    /// `r`'s depth and flow with the mask `labels_t` (`r`'s size).
    fn input_over<'a>(r: &'a Rendered, labels_t: &'a [u16]) -> MotionInput<'a> {
        let (w, h) = (r.width, r.height);
        MotionInput::new(
            ImageView::packed(w, h, labels_t).unwrap(),
            ImageView::packed(w, h, &r.depth_t).unwrap(),
            ImageView::packed(w, h, &r.depth_t1).unwrap(),
            ImageView::packed(w, h, &r.flow).unwrap(),
            r.intrinsics,
        )
        .unwrap()
    }

    /// Runs one step from the accumulated mask `labels_t` and the static mask `static_t1`
    /// over `r`'s depth and flow; returns the corrected mask.
    fn step_with(
        r: &Rendered,
        labels_t: &[u16],
        static_t1: &[u16],
        cfg: &Config,
        on_stage: impl FnMut(Stage),
    ) -> (Vec<u16>, StepReport) {
        let (w, h) = (r.width, r.height);
        let input = input_over(r, labels_t);
        let mut ws = WorkspaceBuf::new(cfg, w, h);
        let mut out = vec![0u16; w * h];
        let static_t1 = ImageView::packed(w, h, static_t1).unwrap();
        let report =
            update_mask_observed(&input, &static_t1, cfg, &mut ws.view(), &mut out, on_stage)
                .unwrap();
        (out, report)
    }

    /// Runs one step with the whole foreground as one segment at `t` and at `t+1` (the
    /// static segmenter merged everything); returns the corrected mask.
    fn step_merged(r: &Rendered, cfg: &Config) -> (Vec<u16>, StepReport) {
        let merged_t: Vec<u16> = r.labels_t.iter().map(|&l| u16::from(l != 0)).collect();
        let merged_t1: Vec<u16> = r.labels_t1.iter().map(|&l| u16::from(l != 0)).collect();
        step_with(r, &merged_t, &merged_t1, cfg, |_| {})
    }

    /// For each true object, the best IoU any predicted label reaches.
    fn best_ious(truth: &[u16], predicted: &[u16]) -> Vec<(u16, f64)> {
        let mut ids: Vec<u16> = truth.iter().copied().filter(|&l| l != 0).collect();
        ids.sort_unstable();
        ids.dedup();
        let mut pred_ids: Vec<u16> = predicted.iter().copied().filter(|&l| l != 0).collect();
        pred_ids.sort_unstable();
        pred_ids.dedup();
        ids.iter()
            .map(|&t| {
                let best = pred_ids
                    .iter()
                    .map(|&p| {
                        let both = truth
                            .iter()
                            .zip(predicted)
                            .filter(|(a, b)| **a == t && **b == p);
                        let either = truth
                            .iter()
                            .zip(predicted)
                            .filter(|(a, b)| **a == t || **b == p);
                        both.count() as f64 / either.count().max(1) as f64
                    })
                    .fold(0.0, f64::max);
                (t, best)
            })
            .collect()
    }

    fn distinct_labels(labels: &[u16]) -> usize {
        let mut ids: Vec<u16> = labels.iter().copied().filter(|&l| l != 0).collect();
        ids.sort_unstable();
        ids.dedup();
        ids.len()
    }

    /// Boxes in a row along x, touching, each a little nearer the camera than the one
    /// before so that rotated corners occlude rather than intersect.
    fn row(motions: &[Pose]) -> Vec<SynthBox> {
        motions
            .iter()
            .enumerate()
            .map(|(i, m)| {
                let x = (i as f32 - (motions.len() as f32 - 1.0) / 2.0) * 0.06;
                let mut b = box_at(x, 0.0, 0.6 - 0.005 * i as f32, [0.03, 0.035], i as u16 + 1);
                b.motion = *m;
                b
            })
            .collect()
    }

    fn slide_y(m: f32) -> Pose {
        Translation3::new(0.0, m, 0.0).into()
    }

    /// Adds roughly normal noise (Irwin-Hall, standard deviation `sigma_m`) to every
    /// depth reading of both frames, as a D415 has at 0.6 m (about 1 mm).
    fn add_depth_noise(r: &mut Rendered, sigma_m: crate::math::Real, seed: u64) {
        let mut rng = crate::rng::Pcg32::new(seed);
        for z in r.depth_t.iter_mut().chain(r.depth_t1.iter_mut()) {
            if *z > 0.0 {
                *z += ((0..12).map(|_| rng.unit()).sum::<crate::math::Real>() - 6.0) * sigma_m;
            }
        }
    }

    #[test]
    fn two_boxes_pushed_alike_but_one_turned_three_degrees_more_are_split_under_depth_noise() {
        // Both slide 2 cm; the second also turns 3 degrees about its centre: at most
        // about 1 mm at its rim, within one frame's twist noise under 1 mm depth noise,
        // but its motion moves the first box's centroid 3 mm away from the first's.
        let boxes = row(&[slide_y(0.02), Pose::identity()]);
        let centre = boxes[1].camera_from_box.translation.vector;
        let turn = slide_y(0.02) * spin_about(centre, 3f32.to_radians());
        let mut r = render(&row(&[slide_y(0.02), turn]), 320, 240);
        add_depth_noise(&mut r, 0.001, 11);
        let (out, report) = step_merged(&r, &Config::PAPER);
        assert_eq!(distinct_labels(&out), 2, "{report:?}");
        for (id, iou) in best_ious(&r.labels_t1, &out) {
            assert!(iou >= 0.9, "object {id}: IoU {iou:.3} ({report:?})");
        }
    }

    #[test]
    fn two_touching_boxes_one_rotating_are_split() {
        let boxes = row(&[slide_y(0.01), Pose::identity()]);
        let centre = boxes[1].camera_from_box.translation.vector;
        let boxes = row(&[slide_y(0.01), spin_about(centre, 10f32.to_radians())]);
        let r = render(&boxes, 320, 240);
        let (out, report) = step_merged(&r, &Config::PAPER);
        assert_eq!(report.mask.split_segments, 1, "{report:?}");
        for (id, iou) in best_ious(&r.labels_t1, &out) {
            assert!(iou >= 0.95, "object {id}: IoU {iou:.3} ({report:?})");
        }
    }

    #[test]
    fn three_touching_boxes_static_sliding_rotating_are_split() {
        let probe = row(&[Pose::identity(); 3]);
        let centre = probe[2].camera_from_box.translation.vector;
        let boxes = row(&[
            Pose::identity(),
            slide_y(-0.012),
            spin_about(centre, -8f32.to_radians()),
        ]);
        let r = render(&boxes, 320, 240);
        let (out, report) = step_merged(&r, &Config::PAPER);
        assert_eq!(distinct_labels(&out), 3, "{report:?}");
        for (id, iou) in best_ious(&r.labels_t1, &out) {
            assert!(iou >= 0.95, "object {id}: IoU {iou:.3} ({report:?})");
        }
    }

    #[test]
    fn the_observer_sees_each_stage_once_in_order_and_the_result_is_unchanged() {
        let r = render(&row(&[slide_y(0.01), Pose::identity()]), 160, 120);
        let cfg = Config::PAPER;
        let (plain, plain_report) = step_merged(&r, &cfg);
        let merged_t: Vec<u16> = r.labels_t.iter().map(|&l| u16::from(l != 0)).collect();
        let merged_t1: Vec<u16> = r.labels_t1.iter().map(|&l| u16::from(l != 0)).collect();
        let mut seen = Vec::new();
        let observed = step_with(&r, &merged_t, &merged_t1, &cfg, |s| seen.push(s));
        assert_eq!(
            seen,
            [Stage::Frames, Stage::Twists, Stage::Grouping, Stage::Mask]
        );
        assert_eq!(observed, (plain, plain_report));
    }

    #[test]
    fn the_step_keeps_the_twists_calc_bfifs_computes() {
        let r = render(&row(&[slide_y(0.01), Pose::identity()]), 160, 120);
        let (w, h) = (r.width, r.height);
        let cfg = Config::PAPER;
        let input = input_over(&r, &r.labels_t);
        let mut ws = WorkspaceBuf::new(&cfg, w, h);
        let mut view = ws.view();
        let mut out = vec![0u16; w * h];
        let static_t1 = ImageView::packed(w, h, &r.labels_t1).unwrap();
        let report = update_mask(&input, &static_t1, &cfg, &mut view, &mut out).unwrap();
        let n = report.frames.count;
        assert!(n > 20, "{report:?}");
        let mut expected = vec![Twist::ZERO; n];
        compute_twists(
            &view.frames[..n],
            &report.frames.space_origin,
            &mut expected,
        )
        .unwrap();
        assert_eq!(&view.twists[..n], &expected[..]);
    }

    #[test]
    fn frames_in_two_static_groups_do_not_split_their_segment() {
        use crate::{group::GroupInfo, mask::FrameGroups};
        let r = render(&row(&[Pose::identity(); 2]), 160, 120);
        let (w, h) = (r.width, r.height);
        let cfg = Config::PAPER;
        let merged: Vec<u16> = r.labels_t.iter().map(|&l| u16::from(l != 0)).collect();
        let input = input_over(&r, &merged);
        let mut ws = WorkspaceBuf::new(&cfg, w, h);
        let mut view = ws.view();
        let set = create_frames(&input, &cfg, view.samples, view.frames).unwrap();
        let frames = &view.frames[..set.count];
        assert!(frames.len() > 20, "{set:?}");
        // Both groups stand still; the split between them runs diagonally across the row.
        let frame_group: Vec<u16> = frames
            .iter()
            .map(|f| u16::from(f.px_t[0][0] + f.px_t[0][1] > (w + h) as u32 / 2))
            .collect();
        let still = GroupInfo {
            frames: 1,
            twist: Twist::ZERO,
            moving: false,
            label: 1,
        };
        let groups = FrameGroups {
            frames,
            frame_group: &frame_group,
            groups: &[still, still],
            space_origin: set.space_origin,
        };
        let mut out = vec![0u16; w * h];
        let static_t1 = ImageView::packed(w, h, &merged).unwrap();
        let report =
            correct_mask(&input, &static_t1, &groups, &cfg, &mut view.mask, &mut out).unwrap();
        assert_eq!(report.split_segments, 0, "{report:?}");
        assert_eq!(distinct_labels(&out), 1);
    }

    #[test]
    fn a_sliver_carried_across_a_boundary_joins_the_object_it_landed_on() {
        let r = render(&row(&[Pose::identity(); 2]), 320, 240);
        let (w, h) = (r.width, r.height);
        // The accumulated mask is right except for a 10 px strip of box 1 along the
        // boundary that carries box 2's label, as flow errors at a boundary do.
        let right_edge_of_1 = (0..w)
            .filter(|&x| (0..h).any(|y| r.labels_t[y * w + x] == 1))
            .max()
            .unwrap();
        let carried: Vec<u16> = (0..w * h)
            .map(|i| {
                let (x, l) = (i % w, r.labels_t[i]);
                if l == 1 && x + 10 > right_edge_of_1 {
                    2
                } else {
                    l
                }
            })
            .collect();
        let sliver = carried
            .iter()
            .zip(&r.labels_t)
            .filter(|(c, t)| c != t)
            .count();
        assert!(
            sliver >= 2 * Config::PAPER.min_segment_px as usize,
            "{sliver} px"
        );
        let (out, _) = step_with(&r, &carried, &r.labels_t1, &Config::PAPER, |_| {});
        assert_eq!(distinct_labels(&out), 2);
        for (id, iou) in best_ious(&r.labels_t1, &out) {
            assert!(iou >= 0.99, "object {id}: IoU {iou:.3}");
        }
    }

    /// One sliding box that the accumulated and the static masks both cut in two halves.
    fn over_segmented_slide(cfg: &Config) -> (Vec<u16>, StepReport) {
        let boxes = [box_at(0.0, 0.0, 0.6, [0.05, 0.035], 1)];
        let mut boxes = boxes;
        boxes[0].motion = slide_y(0.012);
        let r = render(&boxes, 320, 240);
        let (w, h) = (r.width, r.height);
        let halves = |labels: &[u16]| -> Vec<u16> {
            let mid = {
                let xs: Vec<usize> = (0..w * h)
                    .filter(|&i| labels[i] != 0)
                    .map(|i| i % w)
                    .collect();
                (xs.iter().min().unwrap() + xs.iter().max().unwrap()) / 2
            };
            (0..w * h)
                .map(|i| match labels[i] {
                    0 => 0,
                    _ if i % w < mid => 1,
                    _ => 2,
                })
                .collect()
        };
        let (split_t, split_t1) = (halves(&r.labels_t), halves(&r.labels_t1));
        step_with(&r, &split_t, &split_t1, cfg, |_| {})
    }

    #[test]
    fn two_segments_moving_with_one_twist_merge() {
        let on = Config {
            merge_twist_m: 0.002,
            ..Config::PAPER
        };
        let (out, report) = over_segmented_slide(&on);
        assert!(report.grouping.count >= 2, "{report:?}");
        assert_eq!(report.mask.merged_segments, 1, "{report:?}");
        assert_eq!(distinct_labels(&out), 1, "{report:?}");
        // With the merge off, the two halves stay apart.
        let off = Config {
            merge_twist_m: 0.0,
            ..Config::PAPER
        };
        let (out, report) = over_segmented_slide(&off);
        assert_eq!(report.mask.merged_segments, 0);
        assert_eq!(distinct_labels(&out), 2);
    }

    /// Look-alike box tops of one height, flush in a `cols × rows` grid (6 cm pitch, 0.2 mm
    /// gaps), box `i` (row-major, label `i + 1`) moved by `motions[i]`.
    fn pack(cols: usize, rows: usize, motions: &[Pose]) -> Vec<SynthBox> {
        (0..cols * rows)
            .map(|i| {
                let (c, r) = ((i % cols) as f32, (i / cols) as f32);
                let x = (c - (cols as f32 - 1.0) / 2.0) * 0.06;
                let y = (r - (rows as f32 - 1.0) / 2.0) * 0.06;
                let mut b = box_at(x, y, 0.6, [0.0299, 0.0299], i as u16 + 1);
                b.motion = motions[i];
                b
            })
            .collect()
    }

    /// For each group of true objects that should share one label, the best IoU a
    /// predicted label reaches with their union.
    fn group_ious(truth: &[u16], predicted: &[u16], groups: &[&[u16]]) -> Vec<f64> {
        let merged: Vec<u16> = truth
            .iter()
            .map(|&l| {
                groups
                    .iter()
                    .position(|g| g.contains(&l))
                    .map_or(0, |g| g as u16 + 1)
            })
            .collect();
        best_ious(&merged, predicted)
            .into_iter()
            .map(|(_, iou)| iou)
            .collect()
    }

    #[test]
    fn a_two_by_two_pack_with_one_column_sheared_becomes_two_segments() {
        // Column 2 (boxes 2 and 4) slides 2 cm along the face it shares with column 1.
        let still = Pose::identity();
        let shear = slide_y(0.02);
        let r = render(&pack(2, 2, &[still, shear, still, shear]), 320, 240);
        let (out, report) = step_merged(&r, &Config::PAPER);
        assert_eq!(distinct_labels(&out), 2, "{report:?}");
        for iou in group_ious(&r.labels_t1, &out, &[&[1, 3], &[2, 4]]) {
            assert!(iou >= 0.95, "IoU {iou:.3} ({report:?})");
        }
    }

    #[test]
    fn a_row_of_five_with_alternating_motions_gets_five_segments() {
        let still = Pose::identity();
        let boxes = pack(
            5,
            1,
            &[still, slide_y(0.015), still, slide_y(-0.015), still],
        );
        let r = render(&boxes, 320, 240);
        let (out, report) = step_merged(&r, &Config::PAPER);
        assert_eq!(distinct_labels(&out), 5, "{report:?}");
        for (id, iou) in best_ious(&r.labels_t1, &out) {
            assert!(iou >= 0.95, "object {id}: IoU {iou:.3} ({report:?})");
        }
    }

    #[test]
    fn a_two_by_three_pack_with_one_corner_box_pushed_splits_it_off() {
        let still = Pose::identity();
        let mut motions = [still; 6];
        motions[5] = slide_y(0.02);
        let r = render(&pack(3, 2, &motions), 320, 240);
        let (out, report) = step_merged(&r, &Config::PAPER);
        assert_eq!(distinct_labels(&out), 2, "{report:?}");
        for iou in group_ious(&r.labels_t1, &out, &[&[1, 2, 3, 4, 5], &[6]]) {
            assert!(iou >= 0.95, "IoU {iou:.3} ({report:?})");
        }
    }

    #[test]
    fn a_split_stays_split_when_a_later_push_moves_both_parts_alike() {
        // Push 1 shears column 2 off column 1; push 2 slides the whole pack along x. One
        // shared motion is no evidence of one body: the two columns stay two segments,
        // although the static mask still merges them.
        let still = Pose::identity();
        let shear = slide_y(0.02);
        let first = pack(2, 2, &[still, shear, still, shear]);
        let r1 = render(&first, 320, 240);
        let (split, _) = step_merged(&r1, &Config::PAPER);
        assert_eq!(distinct_labels(&split), 2);
        let slide: Pose = Translation3::new(0.012, 0.0, 0.0).into();
        let second: Vec<SynthBox> = first
            .iter()
            .map(|b| SynthBox {
                camera_from_box: b.motion * b.camera_from_box,
                motion: slide,
                ..*b
            })
            .collect();
        let r2 = render(&second, 320, 240);
        let merged_t1: Vec<u16> = r2.labels_t1.iter().map(|&l| u16::from(l != 0)).collect();
        // With the over-segmentation merge on: it must not undo a split made by motion.
        let merge_on = Config {
            merge_twist_m: 0.002,
            ..Config::PAPER
        };
        let (out, report) = step_with(&r2, &split, &merged_t1, &merge_on, |_| {});
        assert_eq!(distinct_labels(&out), 2, "{report:?}");
        for iou in group_ious(&r2.labels_t1, &out, &[&[1, 3], &[2, 4]]) {
            assert!(iou >= 0.95, "IoU {iou:.3} ({report:?})");
        }
    }

    #[test]
    fn nothing_moved_changes_nothing() {
        let r = render(&row(&[Pose::identity(); 3]), 320, 240);
        let (out, report) = step_merged(&r, &Config::PAPER);
        let merged: Vec<u16> = r.labels_t1.iter().map(|&l| u16::from(l != 0)).collect();
        assert_eq!(out, merged, "{report:?}");
    }

    #[test]
    fn parts_moving_with_one_motion_are_not_split() {
        let m = spin_about(Vector3::new(0.0, 0.0, 0.6), 6f32.to_radians()) * slide_y(0.008);
        let r = render(&row(&[m, m]), 320, 240);
        let (out, report) = step_merged(&r, &Config::PAPER);
        assert_eq!(distinct_labels(&out), 1, "{report:?}");
    }

    #[test]
    fn a_rotating_box_alone_stays_whole() {
        // 10 degrees about its centre: flow differs by about 6 px across the box, which a
        // raw flow-difference threshold would cut; its twist is one.
        let probe = row(&[Pose::identity()]);
        let centre = probe[0].camera_from_box.translation.vector;
        let r = render(&row(&[spin_about(centre, 10f32.to_radians())]), 320, 240);
        let (out, report) = step_merged(&r, &Config::PAPER);
        assert_eq!(distinct_labels(&out), 1, "{report:?}");
        assert!(report.grouping.count >= 1);
    }

    #[test]
    fn same_inputs_and_seed_give_the_same_mask_digest() {
        let probe = row(&[Pose::identity(); 2]);
        let centre = probe[1].camera_from_box.translation.vector;
        let r = render(&row(&[slide_y(0.01), spin_about(centre, 0.1)]), 320, 240);
        let digest = |labels: &[u16]| {
            labels.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &l| {
                (h ^ u64::from(l)).wrapping_mul(0x0100_0000_01b3)
            })
        };
        let (a, _) = step_merged(&r, &Config::PAPER);
        let (b, _) = step_merged(&r, &Config::PAPER);
        assert_eq!(digest(&a), digest(&b));
        assert_ne!(
            digest(&a),
            digest(
                &r.labels_t1
                    .iter()
                    .map(|&l| u16::from(l != 0))
                    .collect::<Vec<_>>()
            )
        );
    }

    #[test]
    fn loop_stops_without_action_or_after_the_budget() {
        let mut cfg = Config::PAPER;
        cfg.max_pushes = 2;
        let mut l = RisegLoop::new(&cfg);
        assert_eq!(l.next(Some(1)), Some(1));
        assert_eq!(l.next(Some(2)), Some(2));
        assert_eq!(l.next(Some(3)), None);
        assert!(l.is_finished());
        let mut l = RisegLoop::new(&cfg);
        assert_eq!(l.next::<u8>(None), None);
        assert_eq!(l.next(Some(1)), None);
        assert_eq!(l.pushes_done(), 0);
    }

    #[test]
    fn short_workspace_is_an_error_before_anything_is_written() {
        let r = render(&row(&[Pose::identity()]), 64, 48);
        let cfg = Config::PAPER;
        let mut buf = WorkspaceBuf::new(&cfg, 64, 48);
        let mut ws = buf.view();
        ws.mask.queue = &mut core::mem::take(&mut ws.mask.queue)[..10];
        let input = input_over(&r, &r.labels_t);
        let mut out = vec![7u16; 64 * 48];
        let static_t1 = ImageView::packed(64, 48, &r.labels_t1).unwrap();
        let err = update_mask(&input, &static_t1, &cfg, &mut ws, &mut out);
        assert!(matches!(
            err,
            Err(Error::BufferTooSmall {
                buffer: Buffer::Queue,
                ..
            })
        ));
        assert!(out.iter().all(|&l| l == 7));
    }
}
