//! CorrectMask: carry the accumulated mask to `t+1`, intersect it with the new static mask,
//! and split segments whose frames fell into two or more motion groups.
//!
//! Contract, in order:
//! 1. **Carry.** Every labelled pixel of the accumulated mask at `t` with a depth reading is
//!    splatted to its rounded flow target; where two labels land on one pixel the nearer
//!    depth (at `t`) wins. Each target remembers its source pixel.
//! 2. **Intersect.** The static mask at `t+1` decides foreground. Foreground pixels are
//!    keyed by (carried label, static label); the 4-connected components of equal keys are
//!    the segments, so a split in either mask is kept. Segments smaller than
//!    [`Config::min_segment_px`] join their largest neighbouring segment. Within one
//!    static segment, a component keeps its own segment only when its carried label is an
//!    object and it holds at least a third of that label's carried foreground pixels (the
//!    static mask merged that object with another; a third, not a half, so an object that
//!    a push left behind while its segment's other object moved away stays apart);
//!    slivers that flow errors carry across a boundary, and pixels nothing was carried
//!    to, join the largest component of their static segment.
//! 3. **Seed.** Each grouped frame marks its three tracked pixels at `t+1` with its group.
//!    A group counts in a segment when it has the seeds of at least
//!    [`Config::min_group_frames`] frames there (three pixels each; fewer are frames that
//!    flow errors carried across a boundary). A segment where two or more groups count is
//!    split; others are left as they are.
//!    Groups that did not move all count as one static group with the identity motion, so
//!    frames that stayed still never split a segment between them.
//! 4. **Grow.** A moving group's rigid motion `M` is the least-squares fit (Kabsch) to the
//!    points of all its frames at `t` and `t+1`. In a split segment, regions grow
//!    breadth-first from the seeds to
//!    4-neighbours whose observed flow matches the flow the group's rigid motion predicts
//!    (back-project the source pixel at `t`, move it by the group's `M`, project; residual
//!    within [`Config::grow_tol_px`]). A pixel that several groups explain goes to the one
//!    with the smallest residual. Rotations are handled because `M` is a full rigid motion.
//! 5. **Label.** Every group but the largest (most seeds) of a split segment gets a new
//!    label; the largest keeps the segment's label, and so do pixels no group explains.
//! 6. **Merge** (over-segmentation, beyond the paper). Two moving groups whose frames lay
//!    in different segments at `t` and in different static segments at `t+1`, but whose
//!    twists are closer than [`Config::merge_twist_m`], are one body that the static
//!    segmenter cut in two: their labels unite. Splits accumulate: two segments of the
//!    accumulated mask that one static segment holds were split by motion evidence once
//!    (the static mask alone never separated them), and moving alike later is no evidence
//!    of one body, so they never merge here.
//! 7. **Components.** The output segments are the 4-connected components of these labels
//!    (two objects that both stayed still share the zero motion but not a region, and
//!    merged labels that do not touch stay apart), and components smaller than
//!    [`Config::min_segment_px`] join their largest neighbour.
//!
//! Output labels are distinct positive ids, increasing in scan order of the final segments
//! (with gaps where small fragments merged away); background is `0`.

use nalgebra::{Point3, Translation3};
use wide::{f32x8, i32x8};

use crate::{
    Config, Error, ImageView, Intrinsics, Pose,
    error::{Buffer, check_len},
    frames::{BodyFrame, MotionInput},
    group::GroupInfo,
    image::{MAX_DEPTH_M, valid_depth},
    math::Real,
    se3::fit_rigid_motion,
    union_find::{find, union},
};

/// Most segments one step can hold (labels are `u16`, `0` is background).
pub const MAX_SEGMENTS: usize = u16::MAX as usize;

/// Largest image width or height CorrectMask accepts, pixels.
pub const MAX_SIDE_PX: usize = 0xFFFF;

const NONE: u32 = u32::MAX;
/// Growth decision: the pixel has no observation.
const HOLE: u32 = u32::MAX - 1;

/// The frame groups CorrectMask seeds from (outputs of CreateFrames and GroupBFIFs).
#[derive(Debug, Clone, Copy)]
pub struct FrameGroups<'a> {
    /// The frames.
    pub frames: &'a [BodyFrame],
    /// Group of each frame, or [`NO_GROUP`](crate::group::NO_GROUP).
    pub frame_group: &'a [u16],
    /// The groups; twists are in the space frame at `space_origin`.
    pub groups: &'a [GroupInfo],
    /// Origin of the space frame the twists are expressed in, camera frame.
    pub space_origin: Point3<Real>,
}

/// Scratch for [`correct_mask`]. Contents are garbage after the call.
#[derive(Debug)]
pub struct MaskScratch<'a> {
    /// Per-pixel keys: splat depth bits, then segment keys, then growth states (each
    /// pixel's decision, then the group that claimed it), then labels; `width·height`.
    pub key: &'a mut [u32],
    /// Source pixel at `t` of each pixel at `t+1`; `width·height`.
    pub source: &'a mut [u32],
    /// Segment id of each pixel; `width·height`.
    pub segment: &'a mut [u32],
    /// Breadth-first queue; `width·height`.
    pub queue: &'a mut [u32],
    /// Per-segment sizes, merge targets and keys; [`MAX_SEGMENTS`]` + 1` each.
    pub segment_size: &'a mut [u32],
    /// See [`MaskScratch::segment_size`].
    pub segment_target: &'a mut [u32],
    /// See [`MaskScratch::segment_size`].
    pub segment_key: &'a mut [u32],
    /// One entry per (segment, group) pair with seeds there; three per frame.
    pub seeds: &'a mut [SegmentSeeds],
    /// Rigid motion of each group in the camera frame; one per frame.
    pub motions: &'a mut [Pose],
}

/// One group's seeds in one segment (step 3), then the label its region gets (step 5).
/// Entries sort by segment, then group.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord)]
pub struct SegmentSeeds {
    /// Segment id (step 2).
    pub segment: u32,
    /// The group the seeds are from (moving groups by id, every still group as the first one).
    pub group: u32,
    /// Seed pixels: three per frame of the group whose tracked pixels lie in the segment.
    pub seeds: u32,
    /// Label of the group's region in a split segment (step 5); unused otherwise.
    pub label: u32,
}

/// Element counts [`MaskScratch`] needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MaskScratchLen {
    /// Length of each per-pixel slice.
    pub pixels: usize,
    /// Length of each per-segment slice.
    pub segments: usize,
    /// Length of [`MaskScratch::seeds`].
    pub seeds: usize,
    /// Length of [`MaskScratch::motions`].
    pub motions: usize,
}

impl MaskScratchLen {
    /// Lengths for a `width × height` image and up to `frames` frames.
    #[must_use]
    pub const fn new(width: usize, height: usize, frames: usize) -> Self {
        Self {
            pixels: width.saturating_mul(height),
            segments: MAX_SEGMENTS + 1,
            seeds: frames.saturating_mul(3),
            motions: frames,
        }
    }

    /// Bytes the scratch takes.
    #[must_use]
    pub const fn bytes(&self) -> usize {
        // key, source, segment and queue (u32) per pixel; size, target and key (u32) per
        // segment.
        self.pixels
            .saturating_mul(4 * size_of::<u32>())
            .saturating_add(self.segments.saturating_mul(3 * size_of::<u32>()))
            .saturating_add(self.seeds.saturating_mul(size_of::<SegmentSeeds>()))
            .saturating_add(self.motions.saturating_mul(size_of::<Pose>()))
    }
}

/// What [`correct_mask`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MaskReport {
    /// Segments after intersecting the carried and static masks.
    pub segments: usize,
    /// Segments that two or more groups split.
    pub split_segments: usize,
    /// Label unions made by the same-motion merge (step 6).
    pub merged_segments: usize,
    /// Largest label written.
    pub max_label: u16,
}

/// CorrectMask: writes the corrected mask at `t+1` into `labels_t1` (row-major, packed).
///
/// # Errors
/// [`Error::SizeMismatch`] if `static_t1` differs in size from `input` or the group slices
/// disagree; [`Error::BadImageLayout`] if a side exceeds [`MAX_SIDE_PX`]; [`Error::BufferTooSmall`] if `labels_t1` or a scratch slice is shorter than
/// [`MaskScratchLen`] says (nothing is written then); [`Error::TooManyLabels`] if the
/// segments do not fit `u16` labels; [`Error::BadConfig`] if `cfg` fails [`Config::check`].
pub fn correct_mask(
    input: &MotionInput<'_>,
    static_t1: &ImageView<'_, u16>,
    groups: &FrameGroups<'_>,
    cfg: &Config,
    scratch: &mut MaskScratch<'_>,
    labels_t1: &mut [u16],
) -> Result<MaskReport, Error> {
    // Every pixel outside the static foreground's bounding box is background at `t+1`
    // whatever was carried there, so every per-pixel step works in that window.
    let window = Grid::of_foreground(static_t1);
    correct_mask_in(window, input, static_t1, groups, cfg, scratch, labels_t1)
}

/// [`correct_mask`] working in `grid`, a window of the image that holds every non-zero
/// pixel of `static_t1`: scratch is indexed by window pixel, and `labels_t1[..m]` holds
/// window labels until the output is written. (`queue` stays whole: step 2 also indexes
/// it by static label.)
fn correct_mask_in(
    grid: Grid,
    input: &MotionInput<'_>,
    static_t1: &ImageView<'_, u16>,
    groups: &FrameGroups<'_>,
    cfg: &Config,
    scratch: &mut MaskScratch<'_>,
    labels_t1: &mut [u16],
) -> Result<MaskReport, Error> {
    cfg.check()?;
    let (width, height) = input.size();
    if static_t1.size() != (width, height) || groups.frame_group.len() != groups.frames.len() {
        return Err(Error::SizeMismatch);
    }
    if width > MAX_SIDE_PX || height > MAX_SIDE_PX {
        return Err(Error::BadImageLayout);
    }
    let need = MaskScratchLen::new(width, height, groups.frames.len());
    let n = need.pixels;
    check_len(Buffer::Labels, n, labels_t1.len())?;
    for len in [
        scratch.key.len(),
        scratch.source.len(),
        scratch.segment.len(),
    ] {
        check_len(Buffer::Pixels, n, len)?;
    }
    check_len(Buffer::Queue, n, scratch.queue.len())?;
    for len in [
        scratch.segment_size.len(),
        scratch.segment_target.len(),
        scratch.segment_key.len(),
    ] {
        check_len(Buffer::Segments, need.segments, len)?;
    }
    check_len(Buffer::Seeds, need.seeds, scratch.seeds.len())?;
    check_len(Buffer::Groups, groups.groups.len(), scratch.motions.len())?;
    let labels_t1 = &mut labels_t1[..n];
    if grid.x0 + grid.width > width || grid.y0 + grid.height > height {
        return Err(Error::SizeMismatch);
    }
    let m = grid.width * grid.height;
    let source = &mut scratch.source[..m];
    let segment = &mut scratch.segment[..m];
    let queue = &mut scratch.queue[..n];
    let mut segs = Segments {
        size: &mut *scratch.segment_size,
        target: &mut *scratch.segment_target,
        key: &mut *scratch.segment_key,
    };

    let key = &mut scratch.key[..m];

    // 1. Carry: labels_t1 temporarily holds the carried labels.
    splat(input, grid, key, source, &mut labels_t1[..m]);

    // 2. Intersect.
    let count = intersect(
        grid,
        labels_t1,
        static_t1,
        cfg.min_segment_px,
        key,
        (segment, queue),
        &mut segs,
    )?;

    // 3. Seed: (segment, group, count) runs.
    // A group counts in a segment only with the seeds of a group's worth of frames
    // there: a few frames that flow errors carried across a boundary split nothing.
    let min_seeds = 3 * cfg.min_group_frames.max(1);
    let seed_count = collect_seeds(grid, groups, segment, min_seeds, &mut *scratch.seeds);
    let seeds = &mut scratch.seeds[..seed_count];
    let motions = &mut scratch.motions[..groups.groups.len()];
    group_motions(groups, motions);

    // 4. Grow, in every segment with two or more groups.
    grow_regions(
        grid,
        input,
        cfg,
        groups,
        Regions {
            segment,
            seeds,
            motions,
            source,
        },
        (key, queue),
    );

    // 5. Label.
    let (next, split_segments) = label_split_segments(seeds, count)?;
    let window_labels = &mut labels_t1[..m];
    label_pixels(
        grid,
        static_t1,
        (segment, &*seeds),
        key,
        window_labels,
        segs.key,
    );
    let merged_segments = merge_same_motion(
        seeds,
        groups,
        segs.key,
        cfg,
        next,
        segs.target,
        window_labels,
    );
    if merged_segments > 0 {
        for (k, &l) in key.iter_mut().zip(window_labels.iter()) {
            *k = u32::from(l);
        }
    }
    label_segments(grid, key, cfg.min_segment_px, segment, queue, &mut segs)?;
    // Each output pixel written once: background outside the window, segment ids inside.
    let mut max_label = 0;
    for (y, out_row) in labels_t1.chunks_mut(width.max(1)).enumerate() {
        let (left, rest) = out_row.split_at_mut(grid.x0.min(out_row.len()));
        let (inside, right) = rest.split_at_mut(grid.width.min(rest.len()));
        left.fill(0);
        right.fill(0);
        let window_row = y
            .checked_sub(grid.y0)
            .and_then(|wy| segment.get(wy * grid.width..(wy + 1) * grid.width));
        let Some(seg_row) = window_row else {
            inside.fill(0);
            continue;
        };
        for (out, &seg) in inside.iter_mut().zip(seg_row) {
            *out = seg as u16;
            max_label = max_label.max(*out);
        }
    }
    Ok(MaskReport {
        segments: count,
        split_segments,
        merged_segments,
        max_label,
    })
}

#[derive(Debug, Clone, Copy)]
struct Grid {
    /// Image column of the window's first column.
    x0: usize,
    /// Image row of the window's first row.
    y0: usize,
    width: usize,
    height: usize,
}

/// The window CorrectMask works in (see [`correct_mask`]): indices and packed pixels are
/// window coordinates; [`Grid::locate`] takes image coordinates.
///
/// Pixels travel through queues and the source map as packed `x | y << 16` (no division
/// per pixel to recover the column); hence the 65 535 px limit on each side.
impl Grid {
    /// The bounding box of the non-zero pixels of `labels` (empty when there are none).
    fn of_foreground(labels: &ImageView<'_, u16>) -> Self {
        let (width, height) = labels.size();
        let (mut x0, mut x1, mut y0, mut y1) = (width, 0, height, 0);
        for y in 0..height {
            let Some(row) = labels.row(y) else {
                break;
            };
            // Whole-row test first: it vectorises, and most rows are background.
            if row.iter().fold(0, |any, &l| any | l) == 0 {
                continue;
            }
            // Background chunks at either end are skipped whole (a branch-free test
            // each), then the first and last labels are found pixel by pixel.
            let (lead, _) = row.as_chunks::<SPLAT_CHUNK>();
            let lead_px = SPLAT_CHUNK
                * lead
                    .iter()
                    .take_while(|c| all_background::<SPLAT_CHUNK>(c.as_slice()))
                    .count();
            let (_, trail) = row.as_rchunks::<SPLAT_CHUNK>();
            let trail_px = SPLAT_CHUNK
                * trail
                    .iter()
                    .rev()
                    .take_while(|c| all_background::<SPLAT_CHUNK>(c.as_slice()))
                    .count();
            let first = row
                .get(lead_px..)
                .and_then(|r| r.iter().position(|&l| l != 0))
                .map_or(0, |x| lead_px + x);
            let last = row
                .get(..row.len().saturating_sub(trail_px))
                .and_then(|r| r.iter().rposition(|&l| l != 0))
                .unwrap_or(0);
            x0 = x0.min(first);
            x1 = x1.max(last + 1);
            y0 = y0.min(y);
            y1 = y + 1;
        }
        if y1 == 0 {
            return Self::whole(0, 0);
        }
        Self {
            x0,
            y0,
            width: x1 - x0,
            height: y1 - y0,
        }
    }

    /// The window of a whole `width × height` image.
    const fn whole(width: usize, height: usize) -> Self {
        Self {
            x0: 0,
            y0: 0,
            width,
            height,
        }
    }

    /// Window row `y` of `image` (empty if out of range).
    fn static_row<'v>(&self, image: &ImageView<'v, u16>, y: usize) -> &'v [u16] {
        image
            .row(self.y0 + y)
            .and_then(|row| row.get(self.x0..self.x0 + self.width))
            .unwrap_or(&[])
    }

    const fn pack(x: usize, y: usize) -> u32 {
        (x as u32) | ((y as u32) << 16)
    }

    const fn unpack(p: u32) -> (usize, usize) {
        ((p & 0xFFFF) as usize, (p >> 16) as usize)
    }

    /// The window pixel nearest image point `px`: `(index, packed)`, if inside the window.
    /// (`round` each coordinate and test it against the window, as [`round_index`] does
    /// it: in integers.)
    fn locate(&self, px: [Real; 2]) -> Option<(usize, u32)> {
        let x = round_index(px[0], self.x0 + self.width)?.checked_sub(self.x0)?;
        let y = round_index(px[1], self.y0 + self.height)?.checked_sub(self.y0)?;
        Some((y * self.width + x, Self::pack(x, y)))
    }
}

/// The rigid motion (camera frame) that best carries the points of every frame of group
/// `id` from `t` to `t+1`, by least squares (Kabsch: the SVD of the points' cross-covariance,
/// with the reflection removed), refitted once without the points it misses by more than
/// `max(1 mm, 2.5 × the mean miss)` (a few frames at a boundary would pull the fit). One
/// frame's twist spans only its own triangle, a few centimetres; extrapolated across a
/// pack its rotation noise misses the flow by pixels, so growth would stop short. `None`
/// with fewer than two frames or a degenerate fit.
fn fit_motion(groups: &FrameGroups<'_>, id: usize) -> Option<Pose> {
    let members = || {
        groups
            .frames
            .iter()
            .zip(groups.frame_group)
            .filter(move |(_, g)| usize::from(**g) == id)
            .flat_map(|(f, _)| f.p_t.iter().zip(f.p_t1.iter()))
    };
    let miss = |m: &Pose, a: &Point3<Real>, b: &Point3<Real>| (m * a - b).norm();
    let first = fit_rigid_motion(members())?;
    let (mut count, mut total) = (0.0, 0.0);
    for (a, b) in members() {
        count += 1.0;
        total += miss(&first, a, b);
    }
    let limit = (2.5 * total / count).max(1e-3);
    fit_rigid_motion(members().filter(|(a, b)| miss(&first, a, b) <= limit)).or(Some(first))
}

/// Step 2 (module docs): the segments of the (carried, static) keys, small ones joined to
/// their largest neighbour and fragments to the largest component of their static
/// segment. Writes segment ids (`1..=count`, `0` background) to `segment`; returns
/// `count`. `key` and `queue` are scratch of one entry per pixel.
///
/// # Errors
/// [`Error::TooManyLabels`] with more than [`MAX_SEGMENTS`] segments.
fn intersect(
    grid: Grid,
    carried: &[u16],
    static_t1: &ImageView<'_, u16>,
    min_px: u32,
    key: &mut [u32],
    (segment, queue): (&mut [u32], &mut [u32]),
    segs: &mut Segments<'_>,
) -> Result<usize, Error> {
    for (y, (keys, carried)) in key
        .chunks_mut(grid.width.max(1))
        .zip(carried.chunks(grid.width.max(1)))
        .enumerate()
    {
        let statics = grid.static_row(static_t1, y);
        for ((k, &c), &s) in keys.iter_mut().zip(carried).zip(statics) {
            // Zero where the static label is zero (branch-free, so it vectorises).
            *k = ((u32::from(c) << 16) | u32::from(s)) & 0u32.wrapping_sub(u32::from(s != 0));
        }
    }
    let count = label_segments(grid, key, min_px, segment, queue, segs)?;
    absorb_fragments(segment, count, min_px, queue, segs);
    Ok(count)
}

/// What step 4 grows over: segment ids, the seed entries, the groups' motions and each
/// pixel's source at `t` (step 1).
struct Regions<'r> {
    segment: &'r [u32],
    seeds: &'r [SegmentSeeds],
    motions: &'r [Pose],
    source: &'r [u32],
}

/// Step 4 (module docs): in every segment where two or more groups count, regions grow
/// breadth-first from the groups' seed pixels to 4-neighbours that the group's motion
/// explains best (within [`Config::grow_tol_px`]); pixels without an observation pass
/// for any region. Leaves in `key` each pixel's [`Growth`] state, from which
/// [`Growth::claim`] reads `group + 1` of the region that claimed it (`0`: none).
/// `queue` is scratch of one entry per pixel.
fn grow_regions(
    grid: Grid,
    input: &MotionInput<'_>,
    cfg: &Config,
    groups: &FrameGroups<'_>,
    regions: Regions<'_>,
    (key, queue): (&mut [u32], &mut [u32]),
) {
    let Regions { segment, seeds, .. } = regions;
    // A split segment has seeds of two or more groups, so some pixel seeds.
    let split = seeds
        .windows(2)
        .any(|w| matches!(w, [a, b] if a.segment == b.segment));
    if !split {
        // Nothing grows.
        key.fill(Growth::CLOSED);
        return;
    }
    // Each pixel's best explaining group, computed for every pixel of a split segment
    // before growing, eight pixels at a time (see [`Growth`]). Growth reaches nearly all
    // of them (90 % of the split segments' pixels over `riseg bench` packed and loose,
    // seed 1), so deciding them in a batch costs less than deciding each on first reach.
    decide_pixels(input, cfg, regions, key);
    let mut tail = 0;
    // Consecutive seeds often fall in one segment: the last segment's entries are kept.
    let mut entries = SegmentEntries::new(seeds);
    for (frame, &g) in groups.frames.iter().zip(groups.frame_group) {
        let Some(g) = seed_group(groups, g) else {
            continue;
        };
        for px in frame.px_t1 {
            let Some((i, packed)) = grid.locate(px) else {
                continue;
            };
            let seg = segment.get(i).copied().unwrap_or(0);
            let run = entries.of(seg);
            if seg == 0 || run.len() < 2 || !run.iter().any(|s| s.group == u32::from(g)) {
                continue;
            }
            if let (Some(k), Some(q)) = (key.get_mut(i), queue.get_mut(tail))
                && Growth::seed(k, g + 1)
            {
                *q = packed;
                tail += 1;
            }
        }
    }
    grow_from_seeds(grid, segment, key, queue, tail);
}

/// A pixel's state while step 4 grows, in `key` (one compare tells a neighbour whether a
/// region may take it):
/// - `seg << 16 | (group + 1)`: unclaimed, in split segment `seg`, explained best by
///   `group` (only its region may take it);
/// - `seg << 16`: unclaimed, in split segment `seg`, without an observation (any region
///   of the segment may take it);
/// - [`Growth::CLOSED`]: unclaimed and no region may take it (no group explains it, or
///   it lies outside the split segments);
/// - `group + 1` (`1..=0xFFFF`): claimed by `group`'s region.
///
/// Segment ids are non-zero, so open states are at least `1 << 16` and never a claim.
struct Growth;

impl Growth {
    const CLOSED: u32 = 0;

    /// The open state of a pixel of split segment `seg` with decision `decision`
    /// (`group + 1`, `0` for none, [`HOLE`] for no observation).
    const fn open(seg: u32, decision: u32) -> u32 {
        match decision {
            HOLE => seg << 16,
            d => Self::decided(seg, d),
        }
    }

    /// [`Growth::open`] for a decision of an observed pixel (`group + 1`, `0` for none),
    /// without a branch: which group explains a pixel is a coin flip to a predictor (the
    /// branch was 4.6 K mispredictions a synthetic step in callgrind's simulation).
    const fn decided(seg: u32, decision: u32) -> u32 {
        ((seg << 16) | decision) & 0u32.wrapping_sub((decision != 0) as u32)
    }

    /// The open states of eight pixels of split segment `seg` with decisions `claims`
    /// (`group + 1`, `0` for none; integers as floats) where `seen` (a lane mask) says
    /// they have an observation, [`HOLE`] where not: [`Growth::open`] on each lane,
    /// side by side.
    fn open_lanes(seg: u32, claims: f32x8, seen: f32x8) -> [u32; PIXEL_LANES] {
        // Exact: integers below 2^16, and `-1` (no claim is negative) for a hole.
        let d = seen.select(claims, f32x8::splat(-1.0)).fast_trunc_int();
        // The bits of `seg << 16` (an `i32` of the same bits).
        let open = i32x8::splat((seg << 16) as i32);
        let decided = (open | d) & !d.simd_eq(i32x8::ZERO);
        d.simd_eq(i32x8::splat(-1))
            .select(open, decided)
            .to_array()
            .map(|s| s as u32)
    }

    /// `group + 1` of the region that claimed a pixel in state `state`, `0` if none.
    const fn claim(state: u32) -> u16 {
        if state < 1 << 16 { state as u16 } else { 0 }
    }

    /// Whether every state of `states` has claim `claim` (branch-free on [`RUN_LANES`]
    /// states, so it vectorises).
    fn all_claim(states: &[u32], claim: u16) -> bool {
        match <&[u32; RUN_LANES]>::try_from(states) {
            Ok(lanes) => lanes
                .iter()
                .fold(true, |all, &state| all & (Self::claim(state) == claim)),
            Err(_) => states.iter().all(|&state| Self::claim(state) == claim),
        }
    }

    /// A seed of the region with claim `claim` (`group + 1`) takes an unclaimed pixel
    /// whatever its decision; `false` if the pixel is claimed already.
    const fn seed(state: &mut u32, claim: u16) -> bool {
        let free = Self::claim(*state) == 0;
        if free {
            *state = claim as u32;
        }
        free
    }
}

/// Step 4's breadth-first growth from the `tail` claimed seed pixels at the front of
/// `queue` (packed window pixels), over [`Growth`] states in `key`: each region takes
/// the 4-neighbours of its pixels whose state it may take, in queue order. Branch-free per
/// neighbour: the queue slot is written whether or not the neighbour is taken. Not
/// inlined: inlined into its caller, the loop ran about 0.4 M more instructions per
/// synthetic step (callgrind).
#[inline(never)]
fn grow_from_seeds(
    grid: Grid,
    segment: &[u32],
    key: &mut [u32],
    queue: &mut [u32],
    mut tail: usize,
) {
    let width = grid.width;
    // One length for both maps, so one bounds check covers a pixel in both. Cut to the
    // window, the maps also end the growth at its last row: a pixel there has no row below
    // because the lookup a row on fails (and `p + (1 << 16)` stays in range, the height
    // being at most `MAX_SIDE_PX`).
    let m = (width * grid.height).min(segment.len()).min(key.len());
    let (Some(segment), Some(key)) = (segment.get(..m), key.get_mut(..m)) else {
        return;
    };
    let last_x = width.saturating_sub(1) as u32;
    let mut head = 0;
    while head < tail {
        let Some(&p) = queue.get(head) else { break };
        head += 1;
        let x = p & 0xFFFF;
        let i = (p >> 16) as usize * width + x as usize;
        let (Some(&seg), Some(&mine)) = (segment.get(i), key.get(i)) else {
            continue;
        };
        let (hole, explained) = (seg << 16, (seg << 16) | mine);
        let mut visit = |j: usize, pj: u32| {
            let Some(k) = key.get_mut(j) else { return };
            let take = (*k == hole) | (*k == explained);
            // `tail` < `queue.len()` while a pixel is left to take (each is taken once).
            if let Some(q) = queue.get_mut(tail) {
                *q = pj;
            }
            *k = if take { mine } else { *k };
            tail += usize::from(take);
        };
        // Left, right, up, down: the order the queue grows in. A window pixel (`x` below
        // `width`) has a row above when its index is a row or more (the same test as a
        // packed row above 0; this one also guards `i - width`, and cost 0.7 M fewer
        // instructions a synthetic step in callgrind), and a row below when the index a
        // row on lies in the window (otherwise the lookup fails).
        if x > 0 {
            visit(i - 1, p - 1);
        }
        if x < last_x {
            visit(i + 1, p + 1);
        }
        if i >= width {
            visit(i - width, p - (1 << 16));
        }
        visit(i + width, p + (1 << 16));
    }
}

/// Pixels whose growth decisions are computed side by side.
const PIXEL_LANES: usize = 8;

/// Up to [`PIXEL_LANES`] observed pixels of one segment, as structure-of-arrays.
#[derive(Debug, Clone, Copy)]
struct PixelBatch {
    /// Back-projected source point at `t`, camera frame: `x`, `y`, `z` lanes.
    p: [[Real; PIXEL_LANES]; 3],
    /// Observed pixel at `t+1` (source pixel plus flow): `u`, `v` lanes.
    observed: [[Real; PIXEL_LANES]; 2],
    /// Window index of each lane's pixel.
    index: [usize; PIXEL_LANES],
    /// Lanes in use.
    len: usize,
}

impl PixelBatch {
    /// Unused lanes hold a point at 1 m on the optical axis (their results are dropped).
    const EMPTY: Self = Self {
        p: [[0.0; PIXEL_LANES], [0.0; PIXEL_LANES], [1.0; PIXEL_LANES]],
        observed: [[0.0; PIXEL_LANES]; 2],
        index: [0; PIXEL_LANES],
        len: 0,
    };

    /// Adds a pixel; `false` (and nothing added) when the batch is full.
    fn push(&mut self, index: usize, p: [Real; 3], observed: [Real; 2]) -> bool {
        let lane = self.len;
        if lane >= PIXEL_LANES {
            return false;
        }
        self.set(lane, index, p, observed);
        self.len += 1;
        true
    }

    /// Puts a pixel in lane `lane` (nothing if out of range); leaves `len` as it is.
    fn set(&mut self, lane: usize, index: usize, p: [Real; 3], observed: [Real; 2]) {
        if let Some(slot) = self.index.get_mut(lane) {
            *slot = index;
        }
        for (lanes, v) in self.p.iter_mut().zip(p) {
            if let Some(l) = lanes.get_mut(lane) {
                *l = v;
            }
        }
        for (lanes, v) in self.observed.iter_mut().zip(observed) {
            if let Some(l) = lanes.get_mut(lane) {
                *l = v;
            }
        }
    }

    /// Each lane's decision against `candidates` (seed entries of one segment, in order):
    /// `group + 1` of the candidate with the smallest squared reprojection residual within
    /// `tol2` whose moved point lies in front of the camera (on an exact tie, the later
    /// candidate), `0` if none. Per lane, operation for operation nalgebra's
    /// `Isometry3 * Point3` (rotation `p + w·a + q×a` with `a = 2 q×p`, then the
    /// translation) and the pinhole projection, so each lane with a finite point equals
    /// the scalar computation bit for bit (a test checks); the identity motion skips the
    /// rotation and translation, which leave such a point's residual as it is.
    fn decide(
        &self,
        candidates: &[SegmentSeeds],
        motions: &[Pose],
        k: &Intrinsics,
        tol2: Real,
    ) -> [u32; PIXEL_LANES] {
        let [px, py, pz] = self.p;
        let [ou, ov] = self.observed;
        let lanes = ObservedLanes {
            p: [f32x8::new(px), f32x8::new(py), f32x8::new(pz)],
            observed: [f32x8::new(ou), f32x8::new(ov)],
        };
        let moves = candidates
            .iter()
            .filter_map(|entry| CandidateMotion::of(entry, motions));
        lanes.decide(moves, k, tol2)
    }
}

/// A number of a candidate's motion as [`ObservedLanes::decide`] reads it. Where lanes
/// are vector registers (`cfg(vector_lanes)`: SSE2, wasm's simd128, NEON on aarch64) it
/// is put in every lane once per segment rather than once per batch: 0.28 M fewer
/// instructions a synthetic 640×480 step (callgrind). Elsewhere (the Cortex-M4F
/// firmware) lanes are arrays, eight copies cost eight loads, and it stays one number:
/// as eight, 0.16 M more instructions a firmware step.
#[cfg(vector_lanes)]
type MotionLanes = f32x8;
/// See the other [`MotionLanes`].
#[cfg(not(vector_lanes))]
type MotionLanes = Real;

/// A candidate group's motion as [`ObservedLanes::decide`] applies it, read from its
/// [`Pose`] once per segment rather than once per batch.
#[derive(Debug, Clone, Copy, Default)]
struct CandidateMotion {
    /// Rotation quaternion: `i`, `j`, `k`, `w`.
    q: [MotionLanes; 4],
    /// Translation.
    t: [MotionLanes; 3],
    /// The candidate's claim (`group + 1`), exact as a float: below 2^16.
    claim: MotionLanes,
    /// Whether the motion is the identity (see [`ObservedLanes::decide`]).
    still: bool,
}

impl CandidateMotion {
    /// The motion of seed entry `entry`'s group; `None` if `motions` has none.
    fn of(entry: &SegmentSeeds, motions: &[Pose]) -> Option<Self> {
        let m = motions.get(entry.group as usize)?;
        let q = m.rotation.quaternion();
        let t = m.translation.vector;
        Some(Self {
            q: [q.i, q.j, q.k, q.w].map(MotionLanes::from),
            t: [t.x, t.y, t.z].map(MotionLanes::from),
            claim: MotionLanes::from((entry.group + 1) as Real),
            still: q.w == 1.0 && [q.i, q.j, q.k, t.x, t.y, t.z] == [0.0; 6],
        })
    }
}

/// Most candidates of one segment whose motions [`decide_pixels`] keeps at hand; a
/// segment with more reads them per batch.
const HELD_CANDIDATES: usize = 8;

/// The candidates' motions of the segment last decided, in entry order.
struct HeldMotions {
    /// The segment, `0` for none.
    seg: u32,
    /// Motions held, `usize::MAX` if the segment's are not.
    len: usize,
    motions: [CandidateMotion; HELD_CANDIDATES],
}

/// [`PIXEL_LANES`] observed pixels as vector lanes: back-projected source points at `t`
/// (`x`, `y`, `z`) and observed pixels at `t+1` (`u`, `v`).
#[derive(Debug, Clone, Copy)]
struct ObservedLanes {
    p: [f32x8; 3],
    observed: [f32x8; 2],
}

impl ObservedLanes {
    /// The observations of eight pixels with sources `sources` (packed pixels at `t`, or
    /// [`NONE`]), and a mask of the lanes that have one: as `decide_pixels`'s
    /// per-pixel rule computes them (the same operations per lane, so the same bits), with
    /// the depth test done on all lanes at once. Lanes without an observation hold
    /// values to be dropped.
    fn gather(
        input: &MotionInput<'_>,
        (inv_fx, inv_fy): (Real, Real),
        sources: &[u32; PIXEL_LANES],
    ) -> (Self, f32x8) {
        let [u, v, z, dx, dy] = Self::source_lanes(input, sources);
        let k = input.intrinsics;
        let splat = f32x8::splat;
        // valid_depth on each lane: NaN fails both comparisons, infinities one.
        let seen = z.simd_gt(f32x8::ZERO) & z.simd_le(splat(MAX_DEPTH_M));
        let lanes = Self {
            p: [
                (u - splat(k.cx)) * z * splat(inv_fx),
                (v - splat(k.cy)) * z * splat(inv_fy),
                z,
            ],
            observed: [u + dx, v + dy],
        };
        (lanes, seen)
    }

    /// Source column, row, depth and flow of each of eight pixels; depth `0` where a
    /// lookup fails.
    fn source_lanes(input: &MotionInput<'_>, sources: &[u32; PIXEL_LANES]) -> [f32x8; 5] {
        // Where a push moved a whole stretch of pixels alike (most batches),
        // the eight sources are eight neighbours along one row at `t`: their depths and
        // flows are read as two slices, not pixel by pixel. (Lane `l` holding `s0 + l`
        // is eight pixels of one row when the row's slice exists: a column carried into
        // the row bits would lie past the row's end, as sides are below 2^16.)
        let [s0, ..] = *sources;
        let run = sources
            .iter()
            .zip(0u32..)
            .fold(true, |run, (&s, l)| run & (s == s0.wrapping_add(l)));
        let (sx, sy) = Grid::unpack(s0);
        let row = |y| {
            let depth = input.depth_t.row(y)?.get(sx..sx + PIXEL_LANES)?;
            let flow = input.flow.row(y)?.get(sx..sx + PIXEL_LANES)?;
            Some((
                <&[Real; PIXEL_LANES]>::try_from(depth).ok()?,
                <&[[Real; 2]; PIXEL_LANES]>::try_from(flow).ok()?,
            ))
        };
        if run && let Some((depth, flow)) = row(sy) {
            // Exact: coordinates below 2^16.
            let u = f32x8::splat(Real::from(sx as u16))
                + f32x8::new([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
            return [
                u,
                f32x8::splat(Real::from(sy as u16)),
                f32x8::new(*depth),
                f32x8::new(flow.map(|f| f[0])),
                f32x8::new(flow.map(|f| f[1])),
            ];
        }
        let [mut u, mut v, mut z, mut dx, mut dy] = [[0.0; PIXEL_LANES]; 5];
        // Otherwise the lanes mostly share one or two source rows (a turn): a row's slices
        // are looked up when the row changes. The unpacked `NONE` is (0xFFFF, 0xFFFF),
        // outside every image (sides are at most `MAX_SIDE_PX`), so its lookups fail and
        // its depth stays 0: no observation.
        let mut rows: (usize, &[Real], &[[Real; 2]]) = (usize::MAX, &[], &[]);
        for ((&s, (ul, vl)), (zl, (dxl, dyl))) in sources
            .iter()
            .zip(u.iter_mut().zip(&mut v))
            .zip(z.iter_mut().zip(dx.iter_mut().zip(&mut dy)))
        {
            let (sx, sy) = Grid::unpack(s);
            if sy != rows.0 {
                rows = (
                    sy,
                    input.depth_t.row(sy).unwrap_or(&[]),
                    input.flow.row(sy).unwrap_or(&[]),
                );
            }
            if let (Some(&depth), Some(&[fx, fy])) = (rows.1.get(sx), rows.2.get(sx)) {
                // Exact: coordinates below 2^16.
                (*ul, *vl) = (Real::from(sx as u16), Real::from(sy as u16));
                (*zl, *dxl, *dyl) = (depth, fx, fy);
            }
        }
        [u, v, z, dx, dy].map(f32x8::new)
    }

    /// Each lane's decision against the candidates' motions `moves`, in entry order, as
    /// [`PixelBatch::decide`] says.
    fn decide(
        &self,
        moves: impl IntoIterator<Item = CandidateMotion>,
        k: &Intrinsics,
        tol2: Real,
    ) -> [u32; PIXEL_LANES] {
        // Exact: the claims are integers below 2^16.
        self.best_claims(moves, k, tol2)
            .fast_trunc_int()
            .to_array()
            .map(|c| c as u32)
    }

    /// [`ObservedLanes::decide`]'s decisions as floats (integers below 2^16).
    fn best_claims(
        &self,
        moves: impl IntoIterator<Item = CandidateMotion>,
        k: &Intrinsics,
        tol2: Real,
    ) -> f32x8 {
        let [px, py, pz] = self.p;
        let [ou, ov] = self.observed;
        let two = f32x8::splat(2.0);
        let (fx, fy, cx, cy) = (
            f32x8::splat(k.fx),
            f32x8::splat(k.fy),
            f32x8::splat(k.cx),
            f32x8::splat(k.cy),
        );
        let front = f32x8::splat(1e-6);
        let mut best = f32x8::splat(tol2);
        // Claims are below 2^16, exact as f32.
        let mut best_claim = f32x8::ZERO;
        // A candidate's numbers in every lane (see [`MotionLanes`]).
        let lanes = f32x8::from;
        for m in moves {
            // The identity (every group that did not move) leaves a finite point as it is:
            // each sum of the general form below adds zeros to it, so only the sign of a
            // zero coordinate can differ, and that never reaches the residual (a test
            // checks the decisions).
            let (x, y, z) = if m.still {
                (px, py, pz)
            } else {
                let [qi, qj, qk, qw] = m.q;
                let [qi, qj, qk, qw] = [lanes(qi), lanes(qj), lanes(qk), lanes(qw)];
                let [tx, ty, tz] = m.t;
                let [tx, ty, tz] = [lanes(tx), lanes(ty), lanes(tz)];
                let ax = (qj * pz - qk * py) * two;
                let ay = (qk * px - qi * pz) * two;
                let az = (qi * py - qj * px) * two;
                (
                    ax * qw + (qj * az - qk * ay) + px + tx,
                    ay * qw + (qk * ax - qi * az) + py + ty,
                    az * qw + (qi * ay - qj * ax) + pz + tz,
                )
            };
            let inv_z = f32x8::ONE / z;
            let ex = fx * x * inv_z + cx - ou;
            let ey = fy * y * inv_z + cy - ov;
            let r2 = ex * ex + ey * ey;
            let take = z.simd_gt(front) & r2.simd_le(best);
            best = take.select(r2, best);
            best_claim = take.select(lanes(m.claim), best_claim);
        }
        best_claim
    }
}

/// Step 4's decisions: writes to `key` the open [`Growth`] state of every pixel of a
/// segment with two or more seed entries (see [`grow_regions`]), and
/// [`Growth::CLOSED`] for every other pixel.
fn decide_pixels(input: &MotionInput<'_>, cfg: &Config, regions: Regions<'_>, key: &mut [u32]) {
    let Regions {
        segment,
        seeds,
        motions,
        source,
    } = regions;
    let k = input.intrinsics;
    let (inv_fx, inv_fy) = (1.0 / k.fx, 1.0 / k.fy);
    let tol2 = cfg.grow_tol_px * cfg.grow_tol_px;
    // A pixel's source point at `t` and observed pixel at `t+1`, from its source `s`
    // (`None`: no observation).
    let observe = |s: u32| {
        if s == NONE {
            return None;
        }
        let (sx, sy) = Grid::unpack(s);
        let z = input.depth_t.get(sx, sy).copied().and_then(valid_depth)?;
        let [dx, dy] = input.flow.get(sx, sy).copied()?;
        let (u, v) = (sx as Real, sy as Real);
        let p = [(u - k.cx) * z * inv_fx, (v - k.cy) * z * inv_fy, z];
        Some((p, [u + dx, v + dy]))
    };
    let mut entries = SegmentEntries::new(seeds);
    let mut batch = PixelBatch::EMPTY;
    let mut batch_candidates: &[SegmentSeeds] = &[];
    let flush = |batch: &mut PixelBatch, candidates: &[SegmentSeeds], key: &mut [u32]| {
        if batch.len == 0 {
            return;
        }
        let decisions = batch.decide(candidates, motions, &k, tol2);
        let seg = candidates.first().map_or(0, |c| c.segment);
        for (&j, &d) in batch.index.iter().zip(&decisions).take(batch.len) {
            if let Some(slot) = key.get_mut(j) {
                *slot = Growth::decided(seg, d);
            }
        }
        batch.len = 0;
    };
    let mut held = HeldMotions {
        seg: 0,
        len: 0,
        motions: [CandidateMotion::default(); HELD_CANDIDATES],
    };
    // A segment whose pixels all close (background, or fewer than two entries): runs of
    // it close eight pixels at once.
    let mut closed = 0u32;
    for (c, (seg_chunk, source_chunk)) in segment
        .chunks(RUN_LANES)
        .zip(source.chunks(RUN_LANES))
        .enumerate()
    {
        let j0 = c * RUN_LANES;
        if all_equal(seg_chunk, closed) {
            if let Some(slots) = key.get_mut(j0..j0 + seg_chunk.len()) {
                fill_run(slots, Growth::CLOSED);
            }
            continue;
        }
        // Eight pixels of one segment (most of a split segment's chunks): observed and
        // decided as one batch of their own, lane by lane, with no bookkeeping per pixel
        // (a lane's decision does not depend on the other lanes). Fixed-size arrays, so
        // the lane loops unroll without bounds checks.
        let seg = seg_chunk.first().copied().unwrap_or(0);
        if seg_chunk.len() == PIXEL_LANES
            && all_equal(seg_chunk, seg)
            && let Ok(sources) = <&[u32; PIXEL_LANES]>::try_from(source_chunk)
            && let Some(slots) = key
                .get_mut(j0..j0 + PIXEL_LANES)
                .and_then(|s| <&mut [u32; PIXEL_LANES]>::try_from(s).ok())
        {
            let candidates = if seg == 0 { &[] } else { entries.of(seg) };
            if candidates.len() < 2 {
                slots.fill(Growth::CLOSED);
                closed = seg;
                continue;
            }
            if held.seg != seg {
                held.seg = seg;
                // `usize::MAX` (no slice): the segment's motions are read per batch.
                held.len = usize::MAX;
                if candidates.len() <= HELD_CANDIDATES
                    && candidates
                        .iter()
                        .zip(&mut held.motions)
                        .all(|(entry, slot)| {
                            CandidateMotion::of(entry, motions)
                                .map(|m| *slot = m)
                                .is_some()
                        })
                {
                    held.len = candidates.len();
                }
            }
            let (lanes, seen) = ObservedLanes::gather(input, (inv_fx, inv_fy), sources);
            let claims = match held.motions.get(..held.len) {
                Some(moves) => lanes.best_claims(moves.iter().copied(), &k, tol2),
                None => lanes.best_claims(
                    candidates
                        .iter()
                        .filter_map(|entry| CandidateMotion::of(entry, motions)),
                    &k,
                    tol2,
                ),
            };
            *slots = Growth::open_lanes(seg, claims, seen);
            continue;
        }
        for (j, (&seg, &s)) in (j0..).zip(seg_chunk.iter().zip(source_chunk)) {
            let candidates = if seg == 0 { &[] } else { entries.of(seg) };
            if candidates.len() < 2 {
                if let Some(slot) = key.get_mut(j) {
                    *slot = Growth::CLOSED;
                }
                closed = seg;
                continue;
            }
            let Some((p, observed)) = observe(s) else {
                if let Some(slot) = key.get_mut(j) {
                    *slot = Growth::open(seg, HOLE);
                }
                continue;
            };
            if batch.len > 0 && !core::ptr::eq(candidates, batch_candidates) {
                flush(&mut batch, batch_candidates, key);
            }
            batch_candidates = candidates;
            if !batch.push(j, p, observed) {
                flush(&mut batch, batch_candidates, key);
                batch.push(j, p, observed);
            }
        }
    }
    flush(&mut batch, batch_candidates, key);
}

/// Step 5's pixels: writes to `window_labels` each pixel's label (its claiming group's
/// entry label in `seeds`, else its segment id) and to `key` the same label, and to
/// `static_of` each segment's static label. `key` holds [`Growth`] states on entry.
fn label_pixels(
    grid: Grid,
    static_t1: &ImageView<'_, u16>,
    (segment, seeds): (&[u32], &[SegmentSeeds]),
    key: &mut [u32],
    window_labels: &mut [u16],
    static_of: &mut [u32],
) {
    let mut entries = SegmentEntries::new(seeds);
    let row_len = grid.width.max(1);
    // Runs of pixels repeat one (segment, claim): look its label up once per run.
    let mut run = (0u32, 0u16, 0u16);
    for (y, ((out_row, seg_row), key_row)) in window_labels
        .chunks_mut(row_len)
        .zip(segment.chunks(row_len))
        .zip(key.chunks_mut(row_len))
        .enumerate()
    {
        let static_row = grid.static_row(static_t1, y);
        // Whole chunks as arrays (no length to work out per chunk), then the row's rest.
        let (out8, out_rest) = out_row.as_chunks_mut::<RUN_LANES>();
        let (seg8, seg_rest) = seg_row.as_chunks::<RUN_LANES>();
        let (key8, key_rest) = key_row.as_chunks_mut::<RUN_LANES>();
        let chunks = out8
            .iter_mut()
            .zip(seg8)
            .zip(key8.iter_mut())
            .map(|((o, s), k)| (o.as_mut_slice(), s.as_slice(), k.as_mut_slice()));
        for (c, (out_chunk, seg_chunk, key_chunk)) in chunks
            .chain((!seg_rest.is_empty()).then_some((out_rest, seg_rest, key_rest)))
            .enumerate()
        {
            let x0 = c * RUN_LANES;
            // Inside a run (one segment, one claim), eight pixels at once; the segment's
            // static label is the one its last pixel here writes.
            if all_equal(seg_chunk, run.0) && Growth::all_claim(key_chunk, run.1) {
                fill_run(out_chunk, run.2);
                fill_run(key_chunk, u32::from(run.2));
                let statics = static_row.get(x0..(x0 + seg_chunk.len()).min(static_row.len()));
                if let (Some(slot), Some(&st)) = (
                    static_of.get_mut(run.0 as usize),
                    statics.and_then(<[u16]>::last),
                ) {
                    *slot = u32::from(st);
                }
                continue;
            }
            for (x, ((out, &seg), k)) in (x0..).zip(
                out_chunk
                    .iter_mut()
                    .zip(seg_chunk)
                    .zip(key_chunk.iter_mut()),
            ) {
                let c = Growth::claim(*k);
                if (seg, c) != (run.0, run.1) {
                    let mut label = seg as u16;
                    if c != 0 {
                        let g = u32::from(c - 1);
                        if let Some(entry) = entries.of(seg).iter().find(|s| s.group == g) {
                            label = entry.label as u16;
                        }
                    }
                    run = (seg, c, label);
                }
                *out = run.2;
                *k = u32::from(run.2);
                // The static label of each segment (segments never span two static
                // segments: step 2 keys by the static label and absorbs fragments only
                // within their static segment).
                if let (Some(slot), Some(&st)) =
                    (static_of.get_mut(seg as usize), static_row.get(x))
                {
                    *slot = u32::from(st);
                }
            }
        }
    }
}

/// Step 3, motions: each moving group's rigid motion in the camera frame ([`fit_motion`],
/// or its twist when the fit fails), the identity for groups that did not move.
fn group_motions(groups: &FrameGroups<'_>, motions: &mut [Pose]) {
    let to_camera = Translation3::from(groups.space_origin.coords);
    for (id, (m, g)) in motions.iter_mut().zip(groups.groups).enumerate() {
        *m = if g.moving {
            fit_motion(groups, id)
                .unwrap_or_else(|| to_camera * g.twist.exp() * to_camera.inverse())
        } else {
            Pose::identity()
        };
    }
}

/// Step 5 (module docs): in every segment with two or more groups, the group with the
/// most seeds keeps the segment's id as its label and every other group gets a new label
/// from `count + 1` on, in seed order. Returns the next free label and how many segments
/// were split.
///
/// # Errors
/// [`Error::TooManyLabels`] if the labels do not fit `u16`.
fn label_split_segments(seeds: &mut [SegmentSeeds], count: usize) -> Result<(u32, usize), Error> {
    let mut next = u32::try_from(count).map_err(|_| Error::TooManyLabels)? + 1;
    let mut split_segments = 0;
    let mut start = 0;
    while start < seeds.len() {
        let seg = seeds.get(start).map_or(0, |s| s.segment);
        let run = groups_in(seeds, seg);
        let end = start + run.len().max(1);
        if run.len() >= 2 {
            split_segments += 1;
            let largest = run
                .iter()
                .max_by_key(|s| (s.seeds, u32::MAX - s.group))
                .map_or(NONE, |s| s.group);
            for entry in seeds.get_mut(start..end).unwrap_or(&mut []) {
                entry.label = if entry.group == largest {
                    seg
                } else {
                    next += 1;
                    next - 1
                };
            }
        }
        start = end;
    }
    if next > MAX_SEGMENTS as u32 + 1 {
        return Err(Error::TooManyLabels);
    }
    Ok((next, split_segments))
}

/// Per-segment scratch arrays.
struct Segments<'a> {
    size: &'a mut [u32],
    target: &'a mut [u32],
    key: &'a mut [u32],
}

/// Forward splat into the window `grid` (targets outside it are never read).
/// `depth_bits` holds the winning depth's `f32` bits: for positive floats the bit patterns
/// order like the values, so `u32` comparison is depth comparison. Pixels go in scan
/// order (on equal depth the first wins), eight at a time where labels are not all
/// background: their targets are computed side by side ([`SplatTarget::eight`], equal to
/// [`SplatTarget::pixel`] on each; a test checks), then written one by one in order.
fn splat(
    input: &MotionInput<'_>,
    grid: Grid,
    depth_bits: &mut [u32],
    source: &mut [u32],
    carried: &mut [u16],
) {
    let (width, height) = input.size();
    depth_bits.fill(u32::MAX);
    source.fill(NONE);
    carried.fill(0);
    if grid.width == 0 {
        return;
    }
    // One length for the three maps, so one bounds check covers a target in all three.
    let len = depth_bits.len().min(source.len()).min(carried.len());
    let (Some(depth_bits), Some(source), Some(carried)) = (
        depth_bits.get_mut(..len),
        source.get_mut(..len),
        carried.get_mut(..len),
    ) else {
        return;
    };
    let mut target = SplatTarget {
        grid,
        size: (width, height),
        depth_bits,
        source,
        carried,
    };
    for y in 0..height {
        let (Some(labels), Some(depths), Some(flows)) = (
            input.labels_t.row(y),
            input.depth_t.row(y),
            input.flow.row(y),
        ) else {
            continue;
        };
        // Most of the image is background at `t`: skip it a block, then a chunk, at a
        // time.
        for (b, block) in labels.chunks(SPLAT_BLOCK).enumerate() {
            if all_background::<SPLAT_BLOCK>(block) {
                continue;
            }
            for (c, labels) in block.chunks(SPLAT_CHUNK).enumerate() {
                if all_background::<SPLAT_CHUNK>(labels) {
                    continue;
                }
                let x0 = b * SPLAT_BLOCK + c * SPLAT_CHUNK;
                let (Some(depths), Some(flows)) = (
                    depths.get(x0..x0 + labels.len()),
                    flows.get(x0..x0 + labels.len()),
                ) else {
                    continue;
                };
                let mut x = x0;
                let (labels8, labels_rest) = labels.as_chunks::<SPLAT_LANES>();
                let (depths8, depths_rest) = depths.as_chunks::<SPLAT_LANES>();
                let (flows8, flows_rest) = flows.as_chunks::<SPLAT_LANES>();
                for ((l, d), f) in labels8.iter().zip(depths8).zip(flows8) {
                    target.eight(x, y, l, d, f);
                    x += SPLAT_LANES;
                }
                for (i, ((&label, &z), &flow)) in labels_rest
                    .iter()
                    .zip(depths_rest)
                    .zip(flows_rest)
                    .enumerate()
                {
                    target.pixel(x + i, y, label, z, flow);
                }
            }
        }
    }
}

/// Pixels of a label row [`splat`] skips at once when all are background (and the
/// foreground window's scan, at either end of a row).
const SPLAT_CHUNK: usize = 16;

/// Pixels of a label row [`splat`] tests first, as one branch-free test (it vectorises):
/// 0.14 to 0.17 M fewer instructions a 640×480 step in callgrind than 16-label chunks
/// alone. A multiple of [`SPLAT_CHUNK`].
const SPLAT_BLOCK: usize = 4 * SPLAT_CHUNK;

/// Whether every label of `labels` is background (branch-free on exactly `N` labels, so
/// it vectorises: on a slice of unknown length the same fold ran one label at a time,
/// 0.8 M instructions a 640×480 step in callgrind).
#[inline]
fn all_background<const N: usize>(labels: &[u16]) -> bool {
    match <&[u16; N]>::try_from(labels) {
        Ok(chunk) => chunk.iter().fold(0, |any, &l| any | l) == 0,
        Err(_) => labels.iter().all(|&l| l == 0),
    }
}

/// Pixels whose splat targets are computed side by side.
const SPLAT_LANES: usize = 8;

/// What [`splat`] writes: the window and its per-pixel maps.
struct SplatTarget<'a> {
    grid: Grid,
    /// Image size.
    size: (usize, usize),
    depth_bits: &'a mut [u32],
    source: &'a mut [u32],
    carried: &'a mut [u16],
}

impl SplatTarget<'_> {
    /// Carries `label` from image pixel `(x, y)` at depth `z` to window pixel `(wx, wy)`
    /// if it is nearer than what landed there before.
    #[inline]
    fn put(&mut self, (wx, wy): (usize, usize), (x, y): (usize, usize), label: u16, z: Real) {
        let i = wy * self.grid.width + wx;
        if let (Some(d), Some(s), Some(c)) = (
            self.depth_bits.get_mut(i),
            self.source.get_mut(i),
            self.carried.get_mut(i),
        ) && z.to_bits() < *d
        {
            *d = z.to_bits();
            *s = Grid::pack(x, y);
            *c = label;
        }
    }

    /// One pixel: a labelled pixel with a depth reading goes to its rounded flow target,
    /// if that lies in the window.
    #[inline]
    fn pixel(&mut self, x: usize, y: usize, label: u16, z: Real, [dx, dy]: [Real; 2]) {
        if label == 0 {
            return;
        }
        let Some(z) = valid_depth(z) else {
            return;
        };
        let (width, height) = self.size;
        let (Some(u), Some(v)) = (
            round_index(x as Real + dx, width),
            round_index(y as Real + dy, height),
        ) else {
            return;
        };
        let (Some(wx), Some(wy)) = (
            u.checked_sub(self.grid.x0)
                .filter(|&wx| wx < self.grid.width),
            v.checked_sub(self.grid.y0)
                .filter(|&wy| wy < self.grid.height),
        ) else {
            return;
        };
        self.put((wx, wy), (x, y), label, z);
    }

    /// [`SplatTarget::pixel`] on pixels `x0..x0 + 8` of row `y`, in order, with the
    /// targets computed side by side in floats: the same sums, and the rounding and
    /// bounds of [`round_index`] on exact integers below 2^24.
    fn eight(
        &mut self,
        x0: usize,
        y: usize,
        labels: &[u16; SPLAT_LANES],
        depths: &[Real; SPLAT_LANES],
        flows: &[[Real; 2]; SPLAT_LANES],
    ) {
        let z = f32x8::new(*depths);
        // valid_depth: NaN fails both comparisons, infinities one.
        let has_depth = z.simd_gt(f32x8::ZERO) & z.simd_le(f32x8::splat(MAX_DEPTH_M));
        // Exact: integers below 2^24 (no conversion per lane).
        let xs = f32x8::splat(x0 as Real) + f32x8::new([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
        let u = xs + f32x8::new(flows.map(|f| f[0]));
        let v = f32x8::splat(y as Real) + f32x8::new(flows.map(|f| f[1]));
        let (wx, in_x) = window_coordinate(u, self.grid.x0, self.grid.width);
        let (wy, in_y) = window_coordinate(v, self.grid.y0, self.grid.height);
        // Labelled lanes (background ones carry nothing), as bits.
        let labelled = labels
            .iter()
            .zip(0..)
            .fold(0, |bits, (&label, l)| bits | (u32::from(label != 0) << l));
        let mut lanes = (has_depth & in_x & in_y).to_bitmask() & labelled;
        if lanes == 0 {
            return;
        }
        // Exact: the kept lanes hold integers in 0..65 535.
        let (wx, wy) = (
            wx.fast_trunc_int().to_array(),
            wy.fast_trunc_int().to_array(),
        );
        while lanes != 0 {
            let l = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            let (Some(&label), Some(&z), Some(&wx), Some(&wy)) =
                (labels.get(l), depths.get(l), wx.get(l), wy.get(l))
            else {
                continue;
            };
            self.put((wx as usize, wy as usize), (x0 + l, y), label, z);
        }
    }
}

/// Per lane, `round(v) - origin` (as [`round_index`] rounds) and whether it lies in
/// `0..len`: exact, since every term is an integer below 2^24 where it counts.
#[inline]
fn window_coordinate(v: f32x8, origin: usize, len: usize) -> (f32x8, f32x8) {
    // Beyond 2^23 (or NaN) `round` returns `v`, outside the window.
    let finite = v.abs().simd_lt(f32x8::splat(8_388_608.0));
    // `trunc` through integers, exact where `finite` (elsewhere the lane is dropped),
    // without `trunc`'s handling of values past `i32`: 0.08 to 0.18 M fewer instructions
    // a 640×480 step in callgrind.
    let t = v.fast_trunc_int().round_float();
    let rest = v - t;
    let r = t + (rest.simd_ge(f32x8::splat(0.5)) & f32x8::ONE)
        - (rest.simd_le(f32x8::splat(-0.5)) & f32x8::ONE);
    let w = r - f32x8::splat(origin as Real);
    let inside = finite & w.simd_ge(f32x8::ZERO) & w.simd_lt(f32x8::splat(len as Real));
    (w, inside)
}

/// `round(v)` as an index if it lies in `0..limit` (`limit` at most [`MAX_SIDE_PX`]), in
/// integers: the same test as `round(v) >= 0.0 && round(v) < limit as Real` (a test
/// checks), without the saturating float-to-integer conversions.
#[inline]
fn round_index(v: Real, limit: usize) -> Option<usize> {
    // Beyond 2^23 (or NaN) `round` returns `v`, outside `0..limit` (limit < 2^23).
    if v.is_nan() || v.abs() >= 8_388_608.0 {
        return None;
    }
    // Exact: |v| < 2^23 fits i32, and v minus its truncation is representable.
    let t = v as i32;
    let rest = v - t as Real;
    let r = t + i32::from(rest >= 0.5) - i32::from(rest <= -0.5);
    usize::try_from(r).ok().filter(|&r| r < limit)
}

/// 4-connected components of equal non-zero `key`, then components smaller than `min_px`
/// join their largest neighbour. Writes final segment ids (`1..=count`, `0` background)
/// to `segment` and each segment's key to `segs.key`. Ids increase in scan order of each
/// component's first pixel. `queue` is scratch of one entry per pixel.
///
/// Two passes (union-find over provisional labels), not a flood fill: a pixel takes its
/// left or upper neighbour's provisional label when the keys match, and the two labels
/// unite when both match. The smaller label stays the root, and labels are made in scan
/// order, so each component's root is the label of its first pixel and every parent
/// link points to a smaller label.
fn label_segments(
    grid: Grid,
    key: &[u32],
    min_px: u32,
    segment: &mut [u32],
    queue: &mut [u32],
    segs: &mut Segments<'_>,
) -> Result<usize, Error> {
    let width = grid.width;
    let n = (width * grid.height).min(key.len()).min(segment.len());
    let (Some(key), Some(segment)) = (key.get(..n), segment.get_mut(..n)) else {
        return Ok(0);
    };
    let parent = queue;
    if width == 0 || parent.len() < n {
        return Ok(0);
    }
    // Pass 1: provisional labels into `segment`: `l + 1` for union-find element `l` (0 is
    // background).
    let mut made = 0u32;
    for y in 0..grid.height {
        let row = y * width;
        let Some((above, here)) = segment.split_at_mut_checked(row) else {
            break;
        };
        let (Some(here), Some(keys)) = (here.get_mut(..width), key.get(row..row + width)) else {
            break;
        };
        // The row above; the first row has none (its own keys stand in, unread).
        let has_above = y > 0;
        let (above, keys_above) = if has_above {
            let (Some(a), Some(ka)) = (above.get(row - width..), key.get(row - width..row)) else {
                break;
            };
            (a, ka)
        } else {
            (keys, keys)
        };
        let mut scan = RowScan::new(has_above);
        let (here8, here_rest) = here.as_chunks_mut::<RUN_LANES>();
        let (keys8, keys_rest) = keys.as_chunks::<RUN_LANES>();
        let (above8, above_rest) = above.as_chunks::<RUN_LANES>();
        let (keys_above8, keys_above_rest) = keys_above.as_chunks::<RUN_LANES>();
        for ((l8, k8), (ka8, la8)) in here8
            .iter_mut()
            .zip(keys8)
            .zip(keys_above8.iter().zip(above8))
        {
            if scan.continues(k8, ka8, la8) {
                *l8 = [scan.left.1; RUN_LANES];
                continue;
            }
            for ((l, &k), (&ka, &la)) in l8.iter_mut().zip(k8).zip(ka8.iter().zip(la8)) {
                *l = scan.pixel(parent, &mut made, k, ka, la);
            }
        }
        for ((l, &k), (&ka, &la)) in here_rest
            .iter_mut()
            .zip(keys_rest)
            .zip(keys_above_rest.iter().zip(above_rest))
        {
            *l = scan.pixel(parent, &mut made, k, ka, la);
        }
    }
    // Final ids in order of the roots (first pixels in scan order); parents are smaller,
    // so a parent's slot already holds its final id when an element is reached.
    let mut count = 0usize;
    for p in 0..made as usize {
        let Some(&up) = parent.get(p) else {
            break;
        };
        let id = if up as usize == p {
            count += 1;
            count as u32
        } else {
            parent.get(up as usize).copied().unwrap_or(0)
        };
        if let Some(slot) = parent.get_mut(p) {
            *slot = id;
        }
    }
    if count > MAX_SEGMENTS {
        return Err(Error::TooManyLabels);
    }
    for t in segs.size.iter_mut().take(count + 1) {
        *t = 0;
    }
    // Final ids, sizes and keys, a run of equal labels at a time (a component's pixels
    // all hold its key).
    let (mut last, mut id) = (0u32, 0u32);
    let mut run = 0u32;
    let (segment8, segment_rest) = segment.as_chunks_mut::<RUN_LANES>();
    let (key8, key_rest) = key.as_chunks::<RUN_LANES>();
    let chunks = segment8
        .iter_mut()
        .zip(key8)
        .map(|(s, k)| (s.as_mut_slice(), k.as_slice()));
    for (s_chunk, k_chunk) in chunks.chain([(segment_rest, key_rest)]) {
        // Inside a run, eight pixels at once.
        if s_chunk.len() == RUN_LANES && all_equal(s_chunk, last) {
            fill_run(s_chunk, id);
            run += RUN_LANES as u32;
            continue;
        }
        for (s, &k) in s_chunk.iter_mut().zip(k_chunk) {
            if *s != last {
                last = *s;
                if let Some(size) = segs.size.get_mut(id as usize) {
                    *size += run;
                }
                run = 0;
                id = match last.checked_sub(1) {
                    Some(l) => parent.get(l as usize).copied().unwrap_or(0),
                    None => 0,
                };
                if let (true, Some(kk)) = (id != 0, segs.key.get_mut(id as usize)) {
                    *kk = k;
                }
            }
            *s = id;
            run += 1;
        }
    }
    if let Some(size) = segs.size.get_mut(id as usize) {
        *size += run;
    }
    if let Some(size) = segs.size.get_mut(0) {
        *size = 0;
    }
    join_small_segments(grid, segment, count, min_px, segs);
    Ok(count)
}

/// Pixels CorrectMask's per-pixel passes take at once inside a run (a run of equal
/// entries, where nothing but the run's own value is written).
const RUN_LANES: usize = 8;

/// Whether every entry of `chunk` equals `v` (branch-free on [`RUN_LANES`] entries, so
/// it vectorises).
#[inline]
fn all_equal(chunk: &[u32], v: u32) -> bool {
    match <&[u32; RUN_LANES]>::try_from(chunk) {
        Ok(lanes) => lanes.iter().fold(0, |any, &x| any | (x ^ v)) == 0,
        Err(_) => chunk.iter().all(|&x| x == v),
    }
}

/// Sets every entry of `chunk` to `v` (one store of [`RUN_LANES`] entries where it can:
/// `fill` on a slice of unknown length stores them one at a time).
#[inline]
fn fill_run<T: Copy>(chunk: &mut [T], v: T) {
    match <&mut [T; RUN_LANES]>::try_from(&mut *chunk) {
        Ok(lanes) => *lanes = [v; RUN_LANES],
        Err(_) => chunk.fill(v),
    }
}

/// Pass 1 of [`label_segments`] along one row.
struct RowScan {
    has_above: bool,
    /// (key, provisional label) of the pixel to the left.
    left: (u32, u32),
    /// The label above last united with (or taken by) the current run: runs above
    /// repeat one label over many pixels, so each pair of runs unites once.
    joined_up: u32,
}

impl RowScan {
    const fn new(has_above: bool) -> Self {
        Self {
            has_above,
            left: (0, 0),
            joined_up: 0,
        }
    }

    /// The provisional label of a pixel with key `k`, whose upper neighbour has key `ka`
    /// and label `la`; makes a label (`made`) or unites two in `parent` as needed.
    #[inline]
    fn pixel(&mut self, parent: &mut [u32], made: &mut u32, k: u32, ka: u32, la: u32) -> u32 {
        if k == 0 {
            self.left = (0, 0);
            return 0;
        }
        let up = if self.has_above && ka == k { la } else { 0 };
        let label = if self.left.0 == k {
            if up != 0 && up != self.left.1 && up != self.joined_up {
                union(parent, self.left.1 as usize - 1, up as usize - 1);
                self.joined_up = up;
            }
            self.left.1
        } else if up != 0 {
            self.joined_up = up;
            up
        } else {
            if let Some(p) = parent.get_mut(*made as usize) {
                *p = *made;
            }
            *made += 1;
            self.joined_up = 0;
            *made
        };
        self.left = (k, label);
        label
    }

    /// Whether [`RowScan::pixel`] on these eight pixels would give each the label to the
    /// left and change nothing: every key is the left key (background included), and no
    /// upper neighbour of that key brings a label not yet united with the run.
    #[inline]
    fn continues(
        &self,
        keys: &[u32; RUN_LANES],
        keys_above: &[u32; RUN_LANES],
        labels_above: &[u32; RUN_LANES],
    ) -> bool {
        let (lk, ll, ju) = (self.left.0, self.left.1, self.joined_up);
        let above = self.has_above;
        keys.iter()
            .zip(keys_above)
            .zip(labels_above)
            .fold(true, |ok, ((&k, &ka), &la)| {
                ok & (k == lk) & (!above | (ka != lk) | (la == 0) | (la == ll) | (la == ju))
            })
    }
}

/// Components smaller than `min_px` join their largest neighbouring component, by
/// (size, id); merges only go to a larger component, so following targets always ends.
fn join_small_segments(
    grid: Grid,
    segment: &mut [u32],
    count: usize,
    min_px: u32,
    segs: &mut Segments<'_>,
) {
    let sizes = segs.size.get(..=count).unwrap_or(&[]);
    if !sizes.iter().skip(1).any(|&s| s < min_px) {
        return;
    }
    let target = segs.target.get_mut(..=count).unwrap_or(&mut []);
    target.fill(NONE);
    let ranked = |s: u32| (sizes.get(s as usize).copied().unwrap_or(0), s);
    // Each small component's target is its largest-ranked larger neighbour: a maximum,
    // so only the pixels of small components need looking at, in any order.
    let mut offer = |small: u32, big: u32| {
        if big == small || big == 0 || ranked(big) <= ranked(small) {
            return;
        }
        if let Some(t) = target.get_mut(small as usize)
            && (*t == NONE || ranked(big) > ranked(*t))
        {
            *t = big;
        }
    };
    let width = grid.width.max(1);
    let len = segment.len();
    let (mut last, mut small) = (0u32, false);
    for (y, row) in segment.chunks(width).enumerate() {
        // Vertical pairs only between whole rows.
        let whole = row.len() == width;
        let up = y > 0 && whole;
        let down = whole && (y + 2) * width <= len;
        for (c, chunk) in row.chunks(RUN_LANES).enumerate() {
            // Inside a run of a component that is not small, eight pixels at once.
            if !small && all_equal(chunk, last) {
                continue;
            }
            for (x, &a) in (c * RUN_LANES..).zip(chunk) {
                if a != last {
                    last = a;
                    small = a != 0 && ranked(a).0 < min_px;
                }
                if !small {
                    continue;
                }
                let i = y * width + x;
                let near = [
                    (x > 0).then(|| i - 1),
                    (x + 1 < row.len()).then_some(i + 1),
                    up.then(|| i - width),
                    down.then_some(i + width),
                ];
                for j in near.into_iter().flatten() {
                    if let Some(&b) = segment.get(j) {
                        offer(a, b);
                    }
                }
            }
        }
    }
    // Follow each chain once per segment (targets of smaller ids are final by then),
    // then relabel pixels.
    if let Some(t) = target.get_mut(0) {
        *t = 0;
    }
    for s in 1..=count as u32 {
        let mut id = s;
        for _ in 0..=count {
            match target.get(id as usize) {
                Some(&t) if t != NONE && t != id => id = t,
                _ => break,
            }
        }
        if let Some(t) = target.get_mut(s as usize) {
            *t = id;
        }
    }
    relabel_runs(segment, |s| target.get(s as usize).copied().unwrap_or(s));
}

/// Replaces each entry `s` of `segment` by `map(s)`; `map` is called once per run of equal
/// entries (and once ahead of them for `0`).
fn relabel_runs(segment: &mut [u32], mut map: impl FnMut(u32) -> u32) {
    let (mut last, mut into) = (0u32, map(0));
    let (chunks, rest) = segment.as_chunks_mut::<RUN_LANES>();
    for chunk in chunks.iter_mut().map(|c| c.as_mut_slice()).chain([rest]) {
        // Inside a run, eight pixels at once.
        if chunk.len() == RUN_LANES && all_equal(chunk, last) {
            fill_run(chunk, into);
            continue;
        }
        for s in chunk {
            if *s != last {
                last = *s;
                into = map(last);
            }
            *s = into;
        }
    }
}

/// Step 2's fragment rule: a component of (carried, static) keeps its own segment only
/// when it holds at least `1 / OBJECT_SHARE` of the carried label's foreground pixels.
/// A half let an object that a push left behind (40 % of its carried label, the rest
/// moved away) join whichever other object was largest there, undoing an earlier split
/// (`riseg bench --layout packed --seed 2`, scene 22).
const OBJECT_SHARE: u32 = 3;

/// Step 2, fragments: within one static segment, a component keeps its own segment only
/// when its carried label is an object (non-zero) and the component holds at least a third
/// ([`OBJECT_SHARE`]) of that label's carried foreground pixels (it is the object the static mask merged with
/// another). Slivers that flow errors carry across a boundary, and pixels nothing was
/// carried to, join the largest component of their static segment instead. `dominant`
/// (indexed by static label) and `segs.target` (indexed by carried label) are scratch.
fn absorb_fragments(
    segment: &mut [u32],
    count: usize,
    min_px: u32,
    dominant: &mut [u32],
    segs: &mut Segments<'_>,
) {
    let carried_of = |k: u32| (k >> 16) as usize;
    let static_of = |k: u32| (k & 0xFFFF) as usize;
    // Only the labels the segments' keys hold are read: clear up to the largest of each
    // (not all 65 536 entries of both tables every step).
    let (mut carried_max, mut static_max) = (0, 0);
    for &k in segs.key.iter().skip(1).take(count) {
        carried_max = carried_max.max(carried_of(k));
        static_max = static_max.max(static_of(k));
    }
    for t in segs.target.iter_mut().take(carried_max + 1) {
        *t = 0;
    }
    for s in dominant.iter_mut().take(static_max + 1) {
        *s = NONE;
    }
    for i in 1..=count {
        let (Some(&size), Some(&k)) = (segs.size.get(i), segs.key.get(i)) else {
            continue;
        };
        if let Some(t) = segs.target.get_mut(carried_of(k)) {
            *t = t.saturating_add(size);
        }
        if size < min_px {
            continue;
        }
        if let Some(d) = dominant.get_mut(static_of(k)) {
            let current = if *d == NONE {
                0
            } else {
                segs.size.get(*d as usize).copied().unwrap_or(0)
            };
            if *d == NONE || size > current {
                *d = i as u32;
            }
        }
    }
    // segs.key now maps each component to the segment it becomes.
    for i in 1..=count {
        let (Some(&size), Some(&k)) = (segs.size.get(i), segs.key.get(i)) else {
            continue;
        };
        let carried = carried_of(k);
        let total = segs.target.get(carried).copied().unwrap_or(0);
        let object = carried != 0 && size.saturating_mul(OBJECT_SHARE) >= total;
        let into = match dominant.get(static_of(k)) {
            Some(&d) if d != NONE && !object => d,
            _ => i as u32,
        };
        if let Some(slot) = segs.key.get_mut(i) {
            *slot = into;
        }
    }
    relabel_runs(segment, |s| match s {
        0 => 0,
        s => segs.key.get(s as usize).copied().unwrap_or(s),
    });
}

/// Step 6 (module docs): unites the labels of moving groups from different segments at
/// `t` and in different static segments at `t+1` (`static_of` maps a segment to its static
/// label) whose twists are closer than [`Config::merge_twist_m`], relabelling `labels`
/// (labels below `next`); `parent` is scratch of at least `next` entries. Returns the
/// merges made.
fn merge_same_motion(
    seeds: &[SegmentSeeds],
    groups: &FrameGroups<'_>,
    static_of: &[u32],
    cfg: &Config,
    next: u32,
    parent: &mut [u32],
    labels: &mut [u16],
) -> usize {
    if cfg.merge_twist_m <= 0.0 || cfg.merge_twist_m.is_nan() {
        return 0;
    }
    let Some(parent) = parent.get_mut(..next as usize) else {
        return 0;
    };
    for (i, p) in parent.iter_mut().enumerate() {
        *p = i as u32;
    }
    // The output label of a seed entry, and its group if that group moved.
    let moving = |e: &SegmentSeeds| {
        let g = groups.groups.get(e.group as usize).filter(|g| g.moving)?;
        let label = if groups_in(seeds, e.segment).len() >= 2 {
            e.label
        } else {
            e.segment
        };
        Some((label, g))
    };
    let mut merges = 0;
    for (i, a) in seeds.iter().enumerate() {
        let Some((la, ga)) = moving(a) else { continue };
        for b in seeds.get(i + 1..).unwrap_or(&[]) {
            let Some((lb, gb)) = moving(b) else { continue };
            let static_label = |e: &SegmentSeeds| static_of.get(e.segment as usize).copied();
            if ga.label == gb.label
                || static_label(a) == static_label(b)
                || ga.twist.distance(&gb.twist, cfg.length_scale_m) >= cfg.merge_twist_m
            {
                continue;
            }
            if union(parent, la as usize, lb as usize) {
                merges += 1;
            }
        }
    }
    if merges > 0 {
        for l in labels.iter_mut() {
            *l = find(parent, usize::from(*l)) as u16;
        }
    }
    merges
}

/// The group a frame of group `g` seeds: `None` for [`crate::group::NO_GROUP`]; every group that did
/// not move seeds as the first such group (with the identity motion), so that frames that
/// all stayed still never split a segment, whichever static groups they fell into.
/// (A group id of [`NO_GROUP`](crate::group::NO_GROUP) never seeds, however many groups
/// there are: `group + 1` must fit `u16`, see [`Growth`].)
fn seed_group(groups: &FrameGroups<'_>, g: u16) -> Option<u16> {
    let info = groups.groups.get(usize::from(g))?;
    let seeds = if info.moving {
        Some(g)
    } else {
        groups
            .groups
            .iter()
            .position(|i| !i.moving)
            .and_then(|i| u16::try_from(i).ok())
    };
    seeds.filter(|&s| s != crate::group::NO_GROUP)
}

/// Writes sorted `(segment, group, seed count)` entries of the grouped frames' tracked
/// pixels to the front of `seeds`, one per pair with at least `min_seeds`; returns how many.
fn collect_seeds(
    grid: Grid,
    groups: &FrameGroups<'_>,
    segment: &[u32],
    min_seeds: u32,
    seeds: &mut [SegmentSeeds],
) -> usize {
    let mut len = 0;
    for (frame, &g) in groups.frames.iter().zip(groups.frame_group) {
        let Some(g) = seed_group(groups, g) else {
            continue;
        };
        for px in frame.px_t1 {
            let seg = grid
                .locate(px)
                .and_then(|(i, _)| segment.get(i).copied())
                .unwrap_or(0);
            if let (true, Some(slot)) = (seg != 0, seeds.get_mut(len)) {
                *slot = SegmentSeeds {
                    segment: seg,
                    group: u32::from(g),
                    seeds: 1,
                    label: seg,
                };
                len += 1;
            }
        }
    }
    let Some(seeds) = seeds.get_mut(..len) else {
        return 0;
    };
    // Entries of one (segment, group) are equal here (one seed each, the segment's
    // label), so sorting by that pair alone, one integer compare, orders them as `Ord`.
    seeds.sort_unstable_by_key(|s| (u64::from(s.segment) << 32) | u64::from(s.group));
    // Collapse equal (segment, group) entries, summing counts.
    let mut out = 0usize;
    for i in 0..seeds.len() {
        let Some(&entry) = seeds.get(i) else {
            break;
        };
        match out.checked_sub(1).and_then(|p| seeds.get_mut(p)) {
            Some(prev) if (prev.segment, prev.group) == (entry.segment, entry.group) => {
                prev.seeds += entry.seeds;
            }
            _ => {
                if let Some(slot) = seeds.get_mut(out) {
                    *slot = entry;
                }
                out += 1;
            }
        }
    }
    let mut kept = 0;
    for i in 0..out {
        let Some(&entry) = seeds.get(i) else { break };
        if entry.seeds >= min_seeds {
            if let Some(slot) = seeds.get_mut(kept) {
                *slot = entry;
            }
            kept += 1;
        }
    }
    kept
}

/// [`groups_in`] for pixels visited segment by segment: the last segment's entries are
/// kept, so a run of pixels of one segment searches once.
struct SegmentEntries<'s> {
    seeds: &'s [SegmentSeeds],
    last: Option<(u32, &'s [SegmentSeeds])>,
}

impl<'s> SegmentEntries<'s> {
    const fn new(seeds: &'s [SegmentSeeds]) -> Self {
        Self { seeds, last: None }
    }

    fn of(&mut self, seg: u32) -> &'s [SegmentSeeds] {
        match self.last {
            Some((s, run)) if s == seg => run,
            _ => {
                let run = groups_in(self.seeds, seg);
                self.last = Some((seg, run));
                run
            }
        }
    }
}

/// The entries of one segment.
fn groups_in(seeds: &[SegmentSeeds], seg: u32) -> &[SegmentSeeds] {
    let from = seeds.partition_point(|s| s.segment < seg);
    let to = seeds.partition_point(|s| s.segment <= seg);
    seeds.get(from..to).unwrap_or(&[])
}

#[cfg(test)]
mod tests {
    use std::{vec, vec::Vec};

    use super::*;
    use crate::math::round;

    fn entry(segment: u32, group: u32, seeds: u32) -> SegmentSeeds {
        SegmentSeeds {
            segment,
            group,
            seeds,
            label: segment,
        }
    }

    /// Runs step 2 on a `width`-wide image; returns the segment ids.
    fn run_intersect(
        width: usize,
        carried: &[u16],
        statics: &[u16],
        min_px: u32,
    ) -> (usize, Vec<u32>) {
        let n = carried.len();
        let grid = Grid::whole(width, n / width);
        let (mut key, mut segment, mut queue) = (vec![0u32; n], vec![0u32; n], vec![0u32; n]);
        let (mut size, mut target, mut seg_key) = (
            vec![0u32; MAX_SEGMENTS + 1],
            vec![0u32; MAX_SEGMENTS + 1],
            vec![0u32; MAX_SEGMENTS + 1],
        );
        let mut segs = Segments {
            size: &mut size,
            target: &mut target,
            key: &mut seg_key,
        };
        let static_t1 = ImageView::packed(width, n / width, statics).unwrap();
        let count = intersect(
            grid,
            carried,
            &static_t1,
            min_px,
            &mut key,
            (&mut segment, &mut queue),
            &mut segs,
        )
        .unwrap();
        (count, segment)
    }

    #[test]
    fn a_split_the_static_mask_missed_stays_and_a_carried_sliver_joins_its_host() {
        // One static segment, 8x4. Carried label 1 on the left five columns, 2 on the
        // right three, and a 2-pixel sliver of label 2 carried into the left (a flow
        // error): it joins the largest component of its static segment, the left one.
        #[rustfmt::skip]
        let carried = [
            1, 1, 1, 1, 1, 2, 2, 2,
            1, 2, 2, 1, 1, 2, 2, 2,
            1, 1, 1, 1, 1, 2, 2, 2,
            1, 1, 1, 1, 1, 2, 2, 2,
        ];
        let statics = [1u16; 32];
        let (_, segment) = run_intersect(8, &carried, &statics, 1);
        let left = segment[0];
        let right = segment[7];
        assert_ne!(left, right, "the carried split stays");
        assert_eq!(segment[9], left, "the sliver joins the left object");
        assert_eq!(segment[10], left);
        assert!(segment.iter().all(|&s| s == left || s == right));
    }

    #[test]
    fn an_object_a_push_left_behind_keeps_its_own_segment_apart_from_its_neighbour() {
        // One static segment (a packed block), 10x6. Carried label 1 holds objects A (top
        // left) and C (bottom left); label 2 is object B (right), split from label 1 by an
        // earlier push. The last push moved A up and away from C (a gap row that nothing
        // was carried to), so label 1's pixels fall into two components and C holds 8 of
        // 20 (40 %). C is an object left behind, not a sliver a flow error carried: it
        // must not join B, the largest component there (splits accumulate).
        #[rustfmt::skip]
        let carried = [
            1, 1, 1, 1, 2, 2, 2, 2, 2, 2,
            1, 1, 1, 1, 2, 2, 2, 2, 2, 2,
            1, 1, 1, 1, 2, 2, 2, 2, 2, 2,
            0, 0, 0, 0, 2, 2, 2, 2, 2, 2,
            1, 1, 1, 1, 2, 2, 2, 2, 2, 2,
            1, 1, 1, 1, 2, 2, 2, 2, 2, 2,
        ];
        let statics = [1u16; 60];
        let (_, segment) = run_intersect(10, &carried, &statics, 1);
        let (a, c, b) = (segment[0], segment[40], segment[9]);
        assert_ne!(c, b, "C does not join B: {segment:?}");
        assert_ne!(a, b, "{segment:?}");
    }

    #[test]
    fn a_split_in_the_static_mask_is_kept_and_background_stays_background() {
        // Carried: one label over everything; static: two segments and a background
        // column.
        let carried = [1u16; 12];
        #[rustfmt::skip]
        let statics = [
            1, 1, 0, 2, 2, 2,
            1, 1, 0, 2, 2, 2,
        ];
        let (count, segment) = run_intersect(6, &carried, &statics, 1);
        assert_eq!(count, 2);
        assert_eq!(segment[2], 0);
        assert_eq!(segment[8], 0);
        assert_ne!(segment[0], segment[3]);
    }

    #[test]
    fn a_moving_group_moves_by_its_points_fit_and_a_still_one_by_the_identity() {
        use crate::{Twist, frames::BodyFrame, group::GroupInfo};
        use nalgebra::{UnitQuaternion, Vector3};
        let motion = Pose::from_parts(
            Translation3::new(0.02, -0.01, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.1),
        );
        let frames: Vec<BodyFrame> = (0..8)
            .map(|i| {
                let x = i as Real * 0.01;
                let p_t = [
                    Point3::new(x, 0.0, 0.6),
                    Point3::new(x + 0.02, 0.0, 0.6),
                    Point3::new(x, 0.02, 0.61),
                ];
                BodyFrame {
                    p_t,
                    p_t1: p_t.map(|p| motion * p),
                    ..BodyFrame::EMPTY
                }
            })
            .collect();
        let frame_group = [0u16, 0, 0, 0, 1, 1, 1, 1];
        // The twists are deliberately wrong: a moving group's motion comes from its points.
        let infos = [
            GroupInfo {
                frames: 4,
                twist: Twist::ZERO,
                moving: true,
                label: 1,
            },
            GroupInfo {
                frames: 4,
                twist: Twist::ZERO,
                moving: false,
                label: 1,
            },
        ];
        let groups = FrameGroups {
            frames: &frames,
            frame_group: &frame_group,
            groups: &infos,
            space_origin: Point3::new(0.0, 0.0, 0.6),
        };
        let mut motions = [Pose::identity(); 2];
        group_motions(&groups, &mut motions);
        let p = Point3::new(0.05, 0.03, 0.6);
        assert!((motions[0] * p - motion * p).norm() < 1e-5);
        assert_eq!(motions[1], Pose::identity());
    }

    #[test]
    fn regions_grow_from_their_seeds_to_the_pixels_their_motion_explains_best() {
        use crate::{Intrinsics, Twist, frames::BodyFrame, group::GroupInfo};
        // One segment, 8x1 px at 0.6 m: the two left pixels did not move, the six right
        // ones moved 2 px to the right (2 mm at fx = 600). Group 0 seeds at x = 0, group
        // 1 at x = 7; growth that ignored the motions would meet in the middle.
        let (w, h) = (8, 1);
        let depth = [0.6f32; 8];
        let flow: [[f32; 2]; 8] = core::array::from_fn(|x| [if x < 2 { 0.0 } else { 2.0 }, 0.0]);
        let labels = [1u16; 8];
        let input = MotionInput::new(
            ImageView::packed(w, h, &labels).unwrap(),
            ImageView::packed(w, h, &depth).unwrap(),
            ImageView::packed(w, h, &depth).unwrap(),
            ImageView::packed(w, h, &flow).unwrap(),
            Intrinsics::new(600.0, 600.0, 4.0, 0.0).unwrap(),
        )
        .unwrap();
        let seed_at = |x: Real| BodyFrame {
            px_t1: [[x, 0.0]; 3],
            ..BodyFrame::EMPTY
        };
        let frames = [seed_at(0.0), seed_at(7.0)];
        let moving = GroupInfo {
            frames: 1,
            twist: Twist::ZERO,
            moving: true,
            label: 1,
        };
        let groups = FrameGroups {
            frames: &frames,
            frame_group: &[0, 1],
            groups: &[moving, moving],
            space_origin: Point3::origin(),
        };
        let motions = [
            Pose::identity(),
            Pose::from(Translation3::new(0.002, 0.0, 0.0)),
        ];
        let seeds = [
            SegmentSeeds {
                segment: 1,
                group: 0,
                seeds: 3,
                label: 1,
            },
            SegmentSeeds {
                segment: 1,
                group: 1,
                seeds: 3,
                label: 2,
            },
        ];
        let source: [u32; 8] = core::array::from_fn(|x| Grid::pack(x, 0));
        let (mut key, mut queue) = ([0u32; 8], [0u32; 8]);
        grow_regions(
            Grid::whole(w, h),
            &input,
            &Config::PAPER,
            &groups,
            Regions {
                segment: &[1; 8],
                seeds: &seeds,
                motions: &motions,
                source: &source,
            },
            (&mut key, &mut queue),
        );
        assert_eq!(key.map(Growth::claim), [1, 1, 2, 2, 2, 2, 2, 2]);
    }

    #[test]
    fn the_group_with_most_seeds_keeps_the_segment_and_the_others_get_new_labels() {
        // Segment 1: one group (not split). Segment 2: groups 0, 3, 5 with 30, 90, 45
        // seeds. Segment 4: groups 1 and 2 with equal seeds (the lower id wins).
        let mut seeds = [
            entry(1, 0, 60),
            entry(2, 0, 30),
            entry(2, 3, 90),
            entry(2, 5, 45),
            entry(4, 1, 40),
            entry(4, 2, 40),
        ];
        let (next, split) = label_split_segments(&mut seeds, 4).unwrap();
        assert_eq!(split, 2);
        let labels: [u32; 6] = core::array::from_fn(|i| seeds[i].label);
        assert_eq!(labels, [1, 5, 2, 6, 4, 7]);
        assert_eq!(next, 8);
    }

    #[test]
    fn labels_past_u16_are_an_error() {
        let mut seeds = [entry(1, 0, 10), entry(1, 1, 10)];
        assert_eq!(
            label_split_segments(&mut seeds, MAX_SEGMENTS),
            Err(Error::TooManyLabels)
        );
        assert!(label_split_segments(&mut seeds, MAX_SEGMENTS - 1).is_ok());
    }

    /// A step's input of `w × h` pixels whose depth is the same before and after, seen
    /// through a 60 px focal length centred on the image.
    fn still_input<'a>(
        w: usize,
        h: usize,
        labels: &'a [u16],
        depth: &'a [Real],
        flow: &'a [[Real; 2]],
    ) -> MotionInput<'a> {
        MotionInput::new(
            ImageView::packed(w, h, labels).unwrap(),
            ImageView::packed(w, h, depth).unwrap(),
            ImageView::packed(w, h, depth).unwrap(),
            ImageView::packed(w, h, flow).unwrap(),
            Intrinsics::new(60.0, 60.0, w as Real / 2.0, h as Real / 2.0).unwrap(),
        )
        .unwrap()
    }

    /// The flood fill `label_segments` replaced: components in scan order by breadth-first
    /// search, then each small component joins its largest (size, id) neighbour.
    /// Returns the component count (before joining), the segment ids, and each
    /// component's size and key (index 0 unused).
    fn flood_fill_reference(
        width: usize,
        key: &[u32],
        min_px: u32,
    ) -> (usize, Vec<u32>, Vec<u32>, Vec<u32>) {
        let height = key.len() / width;
        let mut segment = vec![0u32; key.len()];
        let mut size = vec![0u32; 1];
        let mut keys = vec![0u32; 1];
        for start in 0..key.len() {
            if key[start] == 0 || segment[start] != 0 {
                continue;
            }
            let id = size.len() as u32;
            let mut queue = vec![start];
            segment[start] = id;
            let mut head = 0;
            while head < queue.len() {
                let i = queue[head];
                head += 1;
                let (x, y) = (i % width, i / width);
                let mut near = Vec::new();
                if x > 0 {
                    near.push(i - 1);
                }
                if x + 1 < width {
                    near.push(i + 1);
                }
                if y > 0 {
                    near.push(i - width);
                }
                if y + 1 < height {
                    near.push(i + width);
                }
                for j in near {
                    if segment[j] == 0 && key[j] == key[start] {
                        segment[j] = id;
                        queue.push(j);
                    }
                }
            }
            size.push(queue.len() as u32);
            keys.push(key[start]);
        }
        let ranked = |s: u32| (size[s as usize], s);
        let mut target: Vec<Option<u32>> = vec![None; size.len()];
        for i in 0..key.len() {
            let (x, y) = (i % width, i / width);
            let right = (x + 1 < width).then(|| i + 1);
            let down = (y + 1 < height).then(|| i + width);
            for j in [right, down].into_iter().flatten() {
                let (a, b) = (segment[i], segment[j]);
                if a == 0 || b == 0 || a == b {
                    continue;
                }
                for (small, big) in [(a, b), (b, a)] {
                    let better = target[small as usize].is_none_or(|t| ranked(big) > ranked(t));
                    if size[small as usize] < min_px && ranked(big) > ranked(small) && better {
                        target[small as usize] = Some(big);
                    }
                }
            }
        }
        let joined = segment
            .iter()
            .map(|&s| {
                let mut id = s;
                while let Some(t) = target[id as usize] {
                    id = t;
                }
                id
            })
            .collect();
        (size.len() - 1, joined, size, keys)
    }

    /// `label_segments` on `key` against [`flood_fill_reference`].
    fn check_labelling(
        width: usize,
        key: &[u32],
        min_px: u32,
    ) -> Result<(), proptest::test_runner::TestCaseError> {
        let height = key.len() / width;
        let key = &key[..width * height];
        let n = key.len();
        let (mut segment, mut queue) = (vec![0u32; n], vec![0u32; n]);
        let (mut size, mut target, mut seg_key) = (
            vec![0u32; MAX_SEGMENTS + 1],
            vec![0u32; MAX_SEGMENTS + 1],
            vec![0u32; MAX_SEGMENTS + 1],
        );
        let mut segs = Segments {
            size: &mut size,
            target: &mut target,
            key: &mut seg_key,
        };
        let count = label_segments(
            Grid::whole(width, height),
            key,
            min_px,
            &mut segment,
            &mut queue,
            &mut segs,
        )
        .unwrap();
        let (expected_count, expected, sizes, keys) = flood_fill_reference(width, key, min_px);
        proptest::prop_assert_eq!(count, expected_count);
        proptest::prop_assert_eq!(&segment, &expected);
        proptest::prop_assert_eq!(&segs.size[1..=count], &sizes[1..]);
        proptest::prop_assert_eq!(&segs.key[1..=count], &keys[1..]);
        Ok(())
    }

    /// A `w × h` map of blocks (`bw × bh` cells, so runs span eight-pixel chunks) of
    /// values below `values`, with single pixels of other values sprinkled in.
    fn blocky(rng: &mut crate::rng::Pcg32, (w, h): (usize, usize), values: u32) -> Vec<u32> {
        let (bw, bh) = (1 + rng.below(24) as usize, 1 + rng.below(6) as usize);
        let cells: Vec<u32> = (0..(w / bw + 1) * (h / bh + 1))
            .map(|_| rng.below(values))
            .collect();
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if rng.below(40) == 0 {
                    rng.below(values)
                } else {
                    cells[(y / bh) * (w / bw + 1) + x / bw]
                }
            })
            .collect()
    }

    proptest::proptest! {
        #[test]
        fn two_pass_labelling_matches_a_flood_fill(
            width in 1usize..24,
            cells in proptest::collection::vec(0u32..4, 1..400),
            min_px in 0u32..6,
        ) {
            proptest::prop_assume!(cells.len() >= width);
            check_labelling(width, &cells, min_px)?;
        }

        /// Blocks of keys, so that most pixels lie inside runs that the passes take eight
        /// at a time (and runs above that bring labels to unite or not).
        #[test]
        fn run_labelling_of_blocks_matches_a_flood_fill(seed in proptest::prelude::any::<u64>()) {
            let mut rng = crate::rng::Pcg32::new(seed);
            let (w, h) = (1 + rng.below(70) as usize, 1 + rng.below(30) as usize);
            let values = 1 + rng.below(4);
            let key = blocky(&mut rng, (w, h), values);
            check_labelling(w, &key, rng.below(40))?;
        }

        /// `relabel_runs` maps every entry as mapping each one by itself does.
        #[test]
        fn relabelling_by_runs_maps_each_entry(seed in proptest::prelude::any::<u64>()) {
            let mut rng = crate::rng::Pcg32::new(seed);
            let (w, h) = (1 + rng.below(70) as usize, 1 + rng.below(10) as usize);
            let mut segment = blocky(&mut rng, (w, h), 6);
            let table: Vec<u32> = (0..5).map(|_| rng.below(9)).collect();
            let map = |s: u32| match s {
                0 => 0,
                s => table.get(s as usize).copied().unwrap_or(s),
            };
            let expected: Vec<u32> = segment.iter().map(|&s| map(s)).collect();
            relabel_runs(&mut segment, map);
            proptest::prop_assert_eq!(segment, expected);
        }
    }

    /// Step 4's growth as first written: separate segment, claim and decision maps (the
    /// decision `HOLE`, `0` or `group + 1`), seeds taken in order when unclaimed.
    fn grow_reference(
        (w, h): (usize, usize),
        segment: &[u32],
        decision: &[u32],
        seeds: &[(usize, u16)],
    ) -> Vec<u16> {
        let mut claim = vec![0u16; w * h];
        let mut queue = std::collections::VecDeque::new();
        for &(i, c) in seeds {
            if claim[i] == 0 {
                claim[i] = c;
                queue.push_back(i);
            }
        }
        while let Some(i) = queue.pop_front() {
            let (x, y) = (i % w, i / w);
            let near = [
                (x > 0).then(|| i - 1),
                (x + 1 < w).then(|| i + 1),
                (y > 0).then(|| i - w),
                (y + 1 < h).then(|| i + w),
            ];
            for j in near.into_iter().flatten() {
                if segment[j] == segment[i]
                    && claim[j] == 0
                    && (decision[j] == HOLE || decision[j] == u32::from(claim[i]))
                {
                    claim[j] = claim[i];
                    queue.push_back(j);
                }
            }
        }
        claim
    }

    proptest::proptest! {
        /// Growth over one state word per pixel ([`Growth`], [`grow_from_seeds`]) claims
        /// exactly what growth over separate segment, claim and decision maps claims:
        /// random segments (ids up to `0xFFFF`), decisions (holes, none, group ids up to
        /// `0xFFFF`) and seeds, some on one pixel.
        #[test]
        fn growth_states_claim_as_separate_maps(seed in proptest::prelude::any::<u64>()) {
            use crate::rng::Pcg32;
            let mut rng = Pcg32::new(seed);
            let (w, h) = (1 + rng.below(24) as usize, 1 + rng.below(16) as usize);
            let ids = [0, 1, 2, 0xFFFF];
            let claims = [1u16, 2, 3, 0xFFFF];
            // Segments in 2x2 blocks, so that regions meet inside them.
            let block: Vec<u32> = (0..w * h).map(|_| ids[rng.below(4) as usize]).collect();
            let segment: Vec<u32> = (0..w * h).map(|i| block[(i % w) / 2 + (i / w) / 2 * w]).collect();
            let decision: Vec<u32> = (0..w * h)
                .map(|_| match rng.below(6) {
                    0 => 0,
                    1 | 2 => HOLE,
                    _ => u32::from(claims[rng.below(4) as usize]),
                })
                .collect();
            let seeds: Vec<(usize, u16)> = (0..rng.below(12))
                .map(|_| (rng.below((w * h) as u32) as usize, claims[rng.below(4) as usize]))
                .filter(|&(i, _)| segment[i] != 0)
                .collect();
            let truth = grow_reference((w, h), &segment, &decision, &seeds);
            let mut key: Vec<u32> = segment
                .iter()
                .zip(&decision)
                .map(|(&s, &d)| if s == 0 { Growth::CLOSED } else { Growth::open(s, d) })
                .collect();
            let mut queue = vec![0u32; w * h];
            let mut tail = 0;
            for &(i, c) in &seeds {
                if Growth::seed(&mut key[i], c) {
                    queue[tail] = Grid::pack(i % w, i / w);
                    tail += 1;
                }
            }
            grow_from_seeds(Grid::whole(w, h), &segment, &mut key, &mut queue, tail);
            let claimed: Vec<u16> = key.iter().map(|&k| Growth::claim(k)).collect();
            proptest::prop_assert_eq!(claimed, truth);
        }
    }

    proptest::proptest! {
        /// CorrectMask in the static foreground's window gives exactly what it gives over
        /// the whole image: random blocks of labels placed anywhere in the image, random
        /// flow (some of it carrying labels out of or into the window), frames seeding
        /// from inside and outside the window, moving and still groups.
        #[test]
        fn the_foreground_window_changes_nothing(seed in proptest::prelude::any::<u64>()) {
            use crate::{Twist, group::GroupInfo, rng::Pcg32, test_workspace::WorkspaceBuf};
            let mut rng = Pcg32::new(seed);
            let (w, h) = (8 + rng.below(40) as usize, 6 + rng.below(30) as usize);
            // A block of objects somewhere in the image, each with a 2x2-pixel grain.
            let (bx, by) = (rng.below(w as u32 / 2) as usize, rng.below(h as u32 / 2) as usize);
            let (bw, bh) = (1 + rng.below((w - bx) as u32) as usize, 1 + rng.below((h - by) as u32) as usize);
            let block = |rng: &mut Pcg32, objects: u32| -> Vec<u16> {
                (0..w * h)
                    .map(|i| {
                        let (x, y) = (i % w, i / w);
                        let inside = (bx..bx + bw).contains(&x) && (by..by + bh).contains(&y);
                        if inside && rng.below(8) != 0 { (1 + (x / 3 + y / 2) as u32 % objects) as u16 } else { 0 }
                    })
                    .collect()
            };
            let objects_t = 1 + rng.below(3);
            let labels_t = block(&mut rng, objects_t);
            let objects_t1 = 1 + rng.below(2);
            let static_t1 = block(&mut rng, objects_t1);
            let depth: Vec<f32> = (0..w * h)
                .map(|_| if rng.below(10) == 0 { 0.0 } else { 0.55 + 0.1 * rng.unit() })
                .collect();
            let flow: Vec<[f32; 2]> = (0..w * h)
                .map(|_| [4.0 * rng.unit() - 2.0, 4.0 * rng.unit() - 2.0])
                .collect();
            let input = still_input(w, h, &labels_t, &depth, &flow);
            let motions = [
                Pose::from_parts(Translation3::new(0.004, 0.0, 0.0), nalgebra::UnitQuaternion::identity()),
                Pose::from_parts(Translation3::new(0.0, -0.004, 0.001), nalgebra::UnitQuaternion::identity()),
                Pose::identity(),
            ];
            let frames: Vec<BodyFrame> = (0..3 + rng.below(30))
                .map(|_| {
                    let px_t1 = core::array::from_fn(|_| {
                        [rng.unit() * (w + 4) as Real - 2.0, rng.unit() * (h + 4) as Real - 2.0]
                    });
                    let p_t: [Point3<Real>; 3] = core::array::from_fn(|_| {
                        Point3::new(0.05 * rng.unit(), 0.05 * rng.unit(), 0.6)
                    });
                    let m = motions[rng.below(3) as usize];
                    BodyFrame { px_t1, p_t, p_t1: p_t.map(|p| m * p), ..BodyFrame::EMPTY }
                })
                .collect();
            let frame_group: Vec<u16> = frames.iter().map(|_| rng.below(3) as u16).collect();
            let info = |moving| GroupInfo { frames: 1, twist: Twist::ZERO, moving, label: 1 };
            let infos = [info(true), info(true), info(false)];
            let groups = FrameGroups {
                frames: &frames,
                frame_group: &frame_group,
                groups: &infos,
                space_origin: Point3::new(0.0, 0.0, 0.6),
            };
            let cfg = Config { min_segment_px: rng.below(4), min_group_frames: 1, ..Config::PAPER };
            let static_view = ImageView::packed(w, h, &static_t1).unwrap();
            let (mut ws_a, mut ws_b) = (WorkspaceBuf::new(&cfg, w, h), WorkspaceBuf::new(&cfg, w, h));
            let (mut windowed, mut whole) = (vec![1u16; w * h], vec![2u16; w * h]);
            let a = correct_mask(&input, &static_view, &groups, &cfg, &mut ws_a.view().mask, &mut windowed);
            let b = correct_mask_in(
                Grid::whole(w, h), &input, &static_view, &groups, &cfg, &mut ws_b.view().mask, &mut whole,
            );
            proptest::prop_assert_eq!(a, b);
            proptest::prop_assert_eq!(windowed, whole);
        }
    }

    proptest::proptest! {
        /// The foreground's window is the bounding box of the non-zero labels, pixel by
        /// pixel: widths past several 16-label chunks, a few labels anywhere (at row ends
        /// and chunk edges too), strided views, empty images.
        #[test]
        fn the_window_is_the_bounding_box_of_the_labels(seed in proptest::prelude::any::<u64>()) {
            let mut rng = crate::rng::Pcg32::new(seed);
            let (w, h) = (1 + rng.below(80) as usize, 1 + rng.below(8) as usize);
            let stride = w + rng.below(3) as usize;
            let mut labels = vec![0u16; stride * h];
            for _ in 0..rng.below(5) {
                let x = match rng.below(4) {
                    0 => 0,
                    1 => w - 1,
                    _ => rng.below(w as u32) as usize,
                };
                labels[rng.below(h as u32) as usize * stride + x] = 1 + rng.below(3) as u16;
            }
            // Past each row's end: never read.
            for y in 0..h {
                for x in w..stride {
                    labels[y * stride + x] = 9;
                }
            }
            let view = ImageView::new(w, h, stride, &labels).unwrap();
            let grid = Grid::of_foreground(&view);
            let on: Vec<(usize, usize)> = (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .filter(|&(x, y)| labels[y * stride + x] != 0)
                .collect();
            let expected = match (on.iter().map(|p| p.0).min(), on.iter().map(|p| p.1).min()) {
                (Some(x0), Some(y0)) => (
                    x0,
                    y0,
                    on.iter().map(|p| p.0).max().unwrap() + 1 - x0,
                    on.iter().map(|p| p.1).max().unwrap() + 1 - y0,
                ),
                _ => (0, 0, 0, 0),
            };
            proptest::prop_assert_eq!((grid.x0, grid.y0, grid.width, grid.height), expected);
        }
    }

    proptest::proptest! {
        /// The splat eight pixels at a time carries exactly what carrying each pixel in
        /// scan order carries: random labels, depths (invalid ones too), flows (half-pixel
        /// ties, NaN, infinities, huge values), image widths (rows that end mid-chunk)
        /// and windows.
        #[test]
        fn splat_lanes_carry_as_pixel_by_pixel(seed in proptest::prelude::any::<u64>()) {
            use crate::rng::Pcg32;
            let mut rng = Pcg32::new(seed);
            let (w, h) = (1 + rng.below(50) as usize, 1 + rng.below(12) as usize);
            let labels: Vec<u16> = (0..w * h)
                .map(|_| if rng.below(3) == 0 { 0 } else { 1 + rng.below(4) as u16 })
                .collect();
            let special = [Real::NAN, Real::INFINITY, -Real::INFINITY, 0.0, -0.0, 1e30, -1e30, 150.0, -1.0];
            let depth: Vec<Real> = (0..w * h)
                .map(|_| match rng.below(8) {
                    0 => special[rng.below(special.len() as u32) as usize],
                    1 => 0.6,
                    _ => 0.3 + rng.unit(),
                })
                .collect();
            let coordinate = |rng: &mut Pcg32| match rng.below(10) {
                0 => special[rng.below(special.len() as u32) as usize],
                1 => rng.below(9) as Real * 0.5 - 2.0,
                2 => 0.49999997 * if rng.below(2) == 0 { 1.0 } else { -1.0 },
                _ => 8.0 * rng.unit() - 4.0,
            };
            let flow: Vec<[Real; 2]> = (0..w * h).map(|_| [coordinate(&mut rng), coordinate(&mut rng)]).collect();
            let input = still_input(w, h, &labels, &depth, &flow);
            let (x0, y0) = (rng.below(w as u32) as usize, rng.below(h as u32) as usize);
            let grid = Grid {
                x0,
                y0,
                width: 1 + rng.below((w - x0) as u32) as usize,
                height: 1 + rng.below((h - y0) as u32) as usize,
            };
            let m = grid.width * grid.height;
            let (mut bits, mut source, mut carried) = (vec![0u32; m], vec![0u32; m], vec![7u16; m]);
            splat(&input, grid, &mut bits, &mut source, &mut carried);
            let (mut bits_1, mut source_1, mut carried_1) = (vec![u32::MAX; m], vec![NONE; m], vec![0u16; m]);
            let mut one = SplatTarget {
                grid,
                size: (w, h),
                depth_bits: &mut bits_1,
                source: &mut source_1,
                carried: &mut carried_1,
            };
            for i in 0..w * h {
                one.pixel(i % w, i / w, labels[i], depth[i], flow[i]);
            }
            proptest::prop_assert_eq!(bits, bits_1);
            proptest::prop_assert_eq!(source, source_1);
            proptest::prop_assert_eq!(carried, carried_1);
        }
    }

    proptest::proptest! {
        /// [`Grid::locate`] (in integers) finds the window pixel the float definition
        /// finds: round each coordinate, subtract the window's origin, test the bounds.
        #[test]
        fn locate_is_the_rounded_pixel_in_the_window(
            origin in (0usize..40, 0usize..40),
            size in (0usize..10, 0usize..10),
            offset in (-3.0f32..12.0, -3.0f32..12.0),
            halves in (-6i32..24, -6i32..24),
        ) {
            let grid = Grid { x0: origin.0, y0: origin.1, width: size.0, height: size.1 };
            // Points near the window: the sizes are small, so its edges are hit often.
            let (ox, oy) = (origin.0 as Real, origin.1 as Real);
            let px = (ox + offset.0, oy + offset.1);
            let reference = |px: [Real; 2]| {
                let (u, v) = (round(px[0]) - grid.x0 as Real, round(px[1]) - grid.y0 as Real);
                let inside =
                    u >= 0.0 && v >= 0.0 && u < grid.width as Real && v < grid.height as Real;
                inside.then(|| {
                    let (x, y) = (u as usize, v as usize);
                    (y * grid.width + x, Grid::pack(x, y))
                })
            };
            // Any point, and the ties halfway between pixels.
            let ties = [ox + halves.0 as Real * 0.5, oy + halves.1 as Real * 0.5];
            for p in [[px.0, px.1], ties, [ties[0], px.1], [Real::NAN, ties[1]], [1e9, 0.0]] {
                proptest::prop_assert_eq!(grid.locate(p), reference(p), "{:?} in {:?}", p, grid);
            }
        }
    }

    /// The splat's target test in integers equals the float one it replaced.
    fn round_index_matches_round(v: Real, limit: usize) {
        let u = round(v);
        let expected = (u >= 0.0 && u < limit as Real).then_some(u as usize);
        assert_eq!(round_index(v, limit), expected, "{v:?} in 0..{limit}");
    }

    #[test]
    fn round_index_is_round_and_the_bounds_test() {
        let edges = [
            0.0,
            -0.0,
            0.49999997,
            0.5,
            -0.49999997,
            -0.5,
            -0.50000006,
            0.50000006,
            1.5,
            2.5,
            -1.5,
            639.4,
            639.5,
            Real::from_bits(639.5_f32.to_bits() - 1),
            640.0,
            65_534.5,
            65_535.0,
            8_388_607.5,
            8_388_608.0,
            -8_388_608.0,
            1e30,
            -1e30,
            Real::INFINITY,
            Real::NEG_INFINITY,
            Real::NAN,
            Real::MIN_POSITIVE,
            -Real::MIN_POSITIVE,
            1e-45,
            -1e-45,
        ];
        for limit in [0, 1, 640, MAX_SIDE_PX] {
            for &v in &edges {
                round_index_matches_round(v, limit);
                round_index_matches_round(-v, limit);
            }
        }
        let mut rng = crate::rng::Pcg32::new(7);
        for _ in 0..200_000 {
            let v = 700.0 * rng.unit() - 30.0;
            round_index_matches_round(v, 640);
            round_index_matches_round(f32::from_bits(rng.below(u32::MAX)), 640);
        }
    }

    proptest::proptest! {
        /// Eight open states side by side are [`Growth::open`] on each lane: segments up
        /// to `0xFFFF` (`seg << 16` past `i32::MAX`), decisions none, some and up to
        /// `0xFFFF`, lanes with and without an observation.
        #[test]
        fn open_lanes_are_open_states(seed in proptest::prelude::any::<u64>()) {
            let mut rng = crate::rng::Pcg32::new(seed);
            let seg = [1, 2, 0x7FFF, 0x8000, 0xFFFF][rng.below(5) as usize];
            let decisions: [u32; PIXEL_LANES] =
                core::array::from_fn(|_| [0, 1, 2, 0xFFFE, 0xFFFF, rng.below(0x1_0000)][rng.below(6) as usize]);
            let seen: [bool; PIXEL_LANES] = core::array::from_fn(|_| rng.below(3) != 0);
            let claims = f32x8::new(decisions.map(|d| d as Real));
            let mask = f32x8::new(seen.map(|s| if s { 1.0 } else { 0.0 })).simd_eq(f32x8::ONE);
            let expected: [u32; PIXEL_LANES] =
                core::array::from_fn(|l| Growth::open(seg, if seen[l] { decisions[l] } else { HOLE }));
            proptest::prop_assert_eq!(Growth::open_lanes(seg, claims, mask), expected);
        }

        /// Growth's eight-pixel decisions equal the scalar rule with nalgebra's
        /// `Isometry3 * Point3` and the pinhole projection, bit for bit: per pixel, the
        /// candidate with the smallest squared residual within tolerance whose moved point
        /// lies in front of the camera, the later one on an exact tie (a repeated motion
        /// makes ties), so vectorising it changed no mask; the identity's shortcut too.
        #[test]
        fn pixel_lanes_decide_as_the_scalar_rule(seed in proptest::prelude::any::<u64>()) {
            use crate::{Intrinsics, rng::Pcg32};
            use nalgebra::{UnitQuaternion, Vector3};
            let mut rng = Pcg32::new(seed);
            let candidates = 1 + rng.below(6) as usize;
            let pixels = 1 + rng.below(PIXEL_LANES as u32) as usize;
            let mut r = |scale: Real| scale * (2.0 * rng.unit() - 1.0);
            let mut motions: Vec<Pose> = (0..candidates)
                .map(|_| {
                    let axis = Vector3::new(r(1.0), r(1.0), r(1.0));
                    Pose::from_parts(
                        Translation3::new(r(0.01), r(0.01), r(0.01)),
                        UnitQuaternion::from_scaled_axis(axis * r(0.05)),
                    )
                })
                .collect();
            if candidates > 1 && r(1.0) > 0.0 {
                motions[candidates - 1] = motions[0];
            }
            if r(1.0) > -0.5 {
                // The still groups' identity, which skips the rotation.
                let i = ((r(1.0).abs() * candidates as Real) as usize).min(candidates - 1);
                motions[i] = Pose::identity();
            }
            if r(1.0) > 0.5 {
                // A motion that throws points behind the camera.
                motions[0] = Pose::from(Translation3::new(0.0, 0.0, -2.0));
            }
            let entries: Vec<SegmentSeeds> = (0..candidates as u32)
                .map(|g| SegmentSeeds { segment: 1, group: g, seeds: 3, label: 1 })
                .collect();
            let k = Intrinsics::new(600.0 + r(50.0), 600.0 + r(50.0), 320.0 + r(5.0), 240.0 + r(5.0)).unwrap();
            let tol2 = 1.0 + r(1.0).abs() * 8.0;
            let mut batch = PixelBatch::EMPTY;
            let mut truth = Vec::new();
            for j in 0..pixels {
                let mut p = [r(0.3), r(0.3), 0.6 + r(0.5)];
                if j % 3 == 0 {
                    // Zero coordinates, whose sign the identity may keep where the
                    // rotation would not.
                    p[j % 2] = if r(1.0) > 0.0 { 0.0 } else { -0.0 };
                }
                // The observation a random candidate predicts, off by up to 3 px.
                let q = motions[j % candidates] * Point3::new(p[0], p[1], p[2]);
                let observed = [k.fx * q.x / q.z + k.cx + r(3.0), k.fy * q.y / q.z + k.cy + r(3.0)];
                proptest::prop_assert!(batch.push(j, p, observed));
                let mut best = (tol2, 0);
                for e in &entries {
                    let q = motions[e.group as usize] * Point3::new(p[0], p[1], p[2]);
                    let inv_z = 1.0 / q.z;
                    let ex = k.fx * q.x * inv_z + k.cx - observed[0];
                    let ey = k.fy * q.y * inv_z + k.cy - observed[1];
                    let r2 = ex * ex + ey * ey;
                    if q.z > 1e-6 && r2 <= best.0 {
                        best = (r2, e.group + 1);
                    }
                }
                truth.push(best.1);
            }
            let decisions = batch.decide(&entries, &motions, &k, tol2);
            proptest::prop_assert_eq!(&decisions[..truth.len()], &truth[..]);
        }
    }

    proptest::proptest! {
        /// The eight-pixel gather observes each lane as the per-pixel rule does, bit for
        /// bit, whichever way the sources lie: eight neighbours along a row (also at the
        /// row's end, where the slice is short), a few rows, anywhere, or none; depth and
        /// flow views with strides of their own.
        #[test]
        fn gathered_lanes_observe_as_pixel_by_pixel(seed in proptest::prelude::any::<u64>()) {
            use crate::rng::Pcg32;
            let mut rng = Pcg32::new(seed);
            let (w, h) = (1 + rng.below(40) as usize, 1 + rng.below(8) as usize);
            let (depth_stride, flow_stride) = (w + rng.below(3) as usize, w + rng.below(3) as usize);
            let depth: Vec<Real> = (0..h * depth_stride)
                .map(|_| match rng.below(10) {
                    0 => 0.0,
                    1 => Real::NAN,
                    _ => 0.3 + rng.unit(),
                })
                .collect();
            let flow: Vec<[Real; 2]> = (0..h * flow_stride)
                .map(|_| [8.0 * rng.unit() - 4.0, 8.0 * rng.unit() - 4.0])
                .collect();
            let labels = vec![1u16; w * h];
            let input = MotionInput::new(
                ImageView::packed(w, h, &labels).unwrap(),
                ImageView::new(w, h, depth_stride, &depth).unwrap(),
                ImageView::new(w, h, depth_stride, &depth).unwrap(),
                ImageView::new(w, h, flow_stride, &flow).unwrap(),
                Intrinsics::new(60.0, 61.0, w as Real / 2.0, h as Real / 2.0).unwrap(),
            )
            .unwrap();
            let k = input.intrinsics;
            let (x0, y0) = (rng.below(w as u32) as usize, rng.below(h as u32) as usize);
            let mut sources = [0u32; PIXEL_LANES];
            let mode = rng.below(4);
            for (l, s) in sources.iter_mut().enumerate() {
                *s = match mode {
                    // Eight neighbours (past the row's end near it).
                    0 => Grid::pack(x0 + l, y0),
                    // Along a row, now and then a row down.
                    1 => Grid::pack((x0 + l).min(w - 1), (y0 + l / 3).min(h - 1)),
                    2 => Grid::pack(rng.below(w as u32 + 2) as usize, rng.below(h as u32) as usize),
                    _ if rng.below(2) == 0 => NONE,
                    _ => Grid::pack(rng.below(w as u32) as usize, rng.below(h as u32) as usize),
                };
            }
            let (inv_fx, inv_fy) = (1.0 / k.fx, 1.0 / k.fy);
            let (lanes, seen) = ObservedLanes::gather(&input, (inv_fx, inv_fy), &sources);
            let seen = seen.to_bitmask();
            let [px, py, pz] = lanes.p.map(f32x8::to_array);
            let [ou, ov] = lanes.observed.map(f32x8::to_array);
            for (l, &s) in sources.iter().enumerate() {
                let (sx, sy) = Grid::unpack(s);
                let truth = (s != NONE)
                    .then(|| {
                        let z = input.depth_t.get(sx, sy).copied().and_then(valid_depth)?;
                        let [dx, dy] = *input.flow.get(sx, sy)?;
                        let (u, v) = (sx as Real, sy as Real);
                        let p = [(u - k.cx) * z * inv_fx, (v - k.cy) * z * inv_fy, z];
                        Some((p, [u + dx, v + dy]))
                    })
                    .flatten();
                proptest::prop_assert_eq!(seen >> l & 1 != 0, truth.is_some(), "lane {}", l);
                if let Some((p, o)) = truth {
                    let got = [px[l], py[l], pz[l], ou[l], ov[l]].map(Real::to_bits);
                    let want = [p[0], p[1], p[2], o[0], o[1]].map(Real::to_bits);
                    proptest::prop_assert_eq!(got, want, "lane {}", l);
                }
            }
        }
    }

    /// Segment entries for segments `1..=segments` of a blocky map: each with `0..=3`
    /// groups (of `groups`), sorted, labels past `segments`.
    fn random_entries(
        rng: &mut crate::rng::Pcg32,
        segments: u32,
        groups: u32,
    ) -> Vec<SegmentSeeds> {
        let mut next = segments + 1;
        let mut entries = Vec::new();
        for seg in 1..=segments {
            let mut g = rng.below(2);
            for _ in 0..rng.below(4) {
                if g >= groups {
                    break;
                }
                entries.push(SegmentSeeds {
                    segment: seg,
                    group: g,
                    seeds: 3,
                    label: next,
                });
                next += 1;
                g += 1 + rng.below(2);
            }
        }
        entries
    }

    proptest::proptest! {
        /// `decide_pixels` (runs of closed segments eight pixels at a time, eight pixels
        /// of one split segment as one batch) writes the states the pixel-by-pixel rule
        /// gives: closed outside segments with two or more entries, a hole without an
        /// observation, else the one-pixel decision.
        #[test]
        fn decisions_by_runs_are_the_pixel_by_pixel_states(seed in proptest::prelude::any::<u64>()) {
            use crate::rng::Pcg32;
            let mut rng = Pcg32::new(seed);
            let (w, h) = (1 + rng.below(60) as usize, 1 + rng.below(12) as usize);
            let n = w * h;
            let segment = blocky(&mut rng, (w, h), 5);
            let groups = 1 + rng.below(4);
            let seeds = random_entries(&mut rng, 4, groups);
            let source: Vec<u32> = (0..n)
                .map(|_| match rng.below(6) {
                    0 => NONE,
                    _ => Grid::pack(rng.below(w as u32) as usize, rng.below(h as u32) as usize),
                })
                .collect();
            let labels = vec![1u16; n];
            let depth: Vec<Real> =
                (0..n).map(|_| if rng.below(8) == 0 { 0.0 } else { 0.5 + 0.2 * rng.unit() }).collect();
            let flow: Vec<[Real; 2]> =
                (0..n).map(|_| [2.0 * rng.unit() - 1.0, 2.0 * rng.unit() - 1.0]).collect();
            let input = still_input(w, h, &labels, &depth, &flow);
            let motions: Vec<Pose> = (0..groups)
                .map(|g| Pose::from(Translation3::new(0.002 * g as Real, -0.001 * g as Real, 0.0)))
                .collect();
            let cfg = Config::PAPER;
            let mut key = vec![7u32; n];
            decide_pixels(
                &input,
                &cfg,
                Regions { segment: &segment, seeds: &seeds, motions: &motions, source: &source },
                &mut key,
            );
            let k = input.intrinsics;
            let expected: Vec<u32> = segment
                .iter()
                .zip(&source)
                .enumerate()
                .map(|(j, (&seg, &s))| {
                    let candidates = if seg == 0 { &[][..] } else { groups_in(&seeds, seg) };
                    if candidates.len() < 2 {
                        return Growth::CLOSED;
                    }
                    let (sx, sy) = Grid::unpack(s);
                    let observation = (s != NONE)
                        .then(|| {
                            let z = input.depth_t.get(sx, sy).copied().and_then(valid_depth)?;
                            let [dx, dy] = *input.flow.get(sx, sy)?;
                            let (u, v) = (sx as Real, sy as Real);
                            let p = [(u - k.cx) * z * (1.0 / k.fx), (v - k.cy) * z * (1.0 / k.fy), z];
                            Some((p, [u + dx, v + dy]))
                        })
                        .flatten();
                    let Some((p, observed)) = observation else {
                        return Growth::open(seg, HOLE);
                    };
                    let mut batch = PixelBatch::EMPTY;
                    batch.push(j, p, observed);
                    let tol2 = cfg.grow_tol_px * cfg.grow_tol_px;
                    Growth::open(seg, batch.decide(candidates, &motions, &k, tol2)[0])
                })
                .collect();
            proptest::prop_assert_eq!(key, expected);
        }

        /// `label_pixels` (runs eight pixels at a time) writes the labels, keys and static
        /// labels the pixel-by-pixel loop wrote.
        #[test]
        fn labels_by_runs_are_the_pixel_by_pixel_labels(seed in proptest::prelude::any::<u64>()) {
            use crate::rng::Pcg32;
            let mut rng = Pcg32::new(seed);
            let (iw, ih) = (1 + rng.below(60) as usize, 1 + rng.below(12) as usize);
            let (x0, y0) = (rng.below(iw as u32) as usize, rng.below(ih as u32) as usize);
            let grid = Grid { x0, y0, width: iw - x0, height: ih - y0 };
            let m = grid.width * grid.height;
            let segment = blocky(&mut rng, (grid.width, grid.height), 5);
            let seeds = random_entries(&mut rng, 4, 4);
            // Claims of blocks of groups, open states and closed pixels.
            let claims = blocky(&mut rng, (grid.width, grid.height), 6);
            let key: Vec<u32> = claims
                .iter()
                .zip(&segment)
                .map(|(&c, &seg)| if c == 5 { (seg << 16) | 1 } else { c })
                .collect();
            let statics: Vec<u16> = blocky(&mut rng, (iw, ih), 4).iter().map(|&v| v as u16).collect();
            let static_t1 = ImageView::packed(iw, ih, &statics).unwrap();
            let (mut labels, mut keys, mut static_of) = (vec![9u16; m], key.clone(), vec![77u32; 8]);
            label_pixels(grid, &static_t1, (&segment, &seeds), &mut keys, &mut labels, &mut static_of);
            // The loop as first written.
            let (mut labels_ref, mut keys_ref, mut static_ref) = (vec![9u16; m], key, vec![77u32; 8]);
            let mut run = (0u32, 0u16, 0u16);
            for i in 0..m {
                let (x, y) = (i % grid.width, i / grid.width);
                let (seg, c) = (segment[i], Growth::claim(keys_ref[i]));
                if (seg, c) != (run.0, run.1) {
                    let mut label = seg as u16;
                    if c != 0
                        && let Some(e) = groups_in(&seeds, seg).iter().find(|s| s.group == u32::from(c - 1))
                    {
                        label = e.label as u16;
                    }
                    run = (seg, c, label);
                }
                labels_ref[i] = run.2;
                keys_ref[i] = u32::from(run.2);
                if let (Some(slot), Some(&st)) =
                    (static_ref.get_mut(seg as usize), grid.static_row(&static_t1, y).get(x))
                {
                    *slot = u32::from(st);
                }
            }
            proptest::prop_assert_eq!(labels, labels_ref);
            proptest::prop_assert_eq!(keys, keys_ref);
            proptest::prop_assert_eq!(static_of, static_ref);
        }
    }
}
