//! CreateFrames and CalcBFIFs: sample labelled pixels, build small body frames on them,
//! track the frames through the flow, and compute each frame's spatial twist.
//!
//! Contract:
//! - Sampling is seeded and stratified: the eligible pixels (label ≠ 0, valid depth at `t`)
//!   are split, in row-major order, into `n` equal runs and one pixel is drawn from each.
//!   Every eligible pixel is equally likely, no pixel is drawn twice, and the samples come
//!   out sorted by row, which the neighbour search uses.
//! - Each sample is the origin of at most one frame. The other two points are sampled
//!   pixels with the same label, within [`Config::frame_max_side_m`] of each other and at
//!   least [`Config::frame_min_side_m`] apart; the second point is the farthest such
//!   sample, the third the one that makes the largest triangle. Triangles whose angle at
//!   the origin has a sine below [`Config::frame_min_sin`] are not used.
//! - Points are tracked by the flow at their pixel. Depth at `t` (at the pixel) and at
//!   `t+1` (at the tracked position) is denoised by a local plane fit over a small window
//!   (`local_depth`): a frame's rotation comes from millimetre depth differences across
//!   a few centimetres, so raw single-pixel readings (about 1 mm noise at 0.6 m) would
//!   give a still object a twist as large as a push's. A frame with a missing reading at `t+1` (no depth, a depth edge,
//!   outside the image, non-finite flow) is dropped, not guessed, and so is a frame whose
//!   triangle changes a side by more than [`Config::frame_rigid_tol_m`] (not rigid).
//! - The space frame is fixed at the centroid of the sampled points at `t` with the camera's
//!   axes (DESIGN.md §3): rotation noise times a 60 cm lever arm to the camera would swamp
//!   the linear part of the twist.

use core::{hint::select_unpredictable, ops::RangeInclusive};

use nalgebra::{Point3, Vector3};
use wide::{f32x4, u32x4, u64x2};

use crate::{
    Config, Error, ImageView, Intrinsics, Twist,
    error::{Buffer, check_len},
    image::{MAX_DEPTH_M, valid_depth},
    math::{Real, sqrt4},
    rng::Pcg32,
    se3::{spatial_twist, try_frame_from_points},
};

/// The observations one UpdateMask step reads: the accumulated mask, depth before and after
/// the push, and the forward flow from `t` to `t+1`, all of one size.
#[derive(Debug, Clone, Copy)]
pub struct MotionInput<'a> {
    /// Accumulated mask at `t` (`0` = background).
    pub labels_t: ImageView<'a, u16>,
    /// Depth at `t`, metres.
    pub depth_t: ImageView<'a, f32>,
    /// Depth at `t+1`, metres.
    pub depth_t1: ImageView<'a, f32>,
    /// Forward flow `t → t+1`, `[dx, dy]` pixels.
    pub flow: ImageView<'a, [f32; 2]>,
    /// Camera intrinsics (both images).
    pub intrinsics: Intrinsics,
}

impl<'a> MotionInput<'a> {
    /// Bundles the observations after checking that they agree.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if the images differ in size; the errors of
    /// [`Intrinsics::check`] for bad intrinsics.
    pub fn new(
        labels_t: ImageView<'a, u16>,
        depth_t: ImageView<'a, f32>,
        depth_t1: ImageView<'a, f32>,
        flow: ImageView<'a, [f32; 2]>,
        intrinsics: Intrinsics,
    ) -> Result<Self, Error> {
        let size = labels_t.size();
        if depth_t.size() != size || depth_t1.size() != size || flow.size() != size {
            return Err(Error::SizeMismatch);
        }
        intrinsics.check()?;
        Ok(Self {
            labels_t,
            depth_t,
            depth_t1,
            flow,
            intrinsics,
        })
    }

    /// `(width, height)` of every image.
    #[must_use]
    pub const fn size(&self) -> (usize, usize) {
        self.labels_t.size()
    }
}

/// One sampled pixel; scratch of [`create_frames`] (callers only allocate these).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameSample {
    px: [u32; 2],
    /// [`column_key`] of the column `px[0]` and the key: the label, plus [`UNTRACKED`] if
    /// the flow lost the point. One compare tests both, and one more the column, in
    /// [`build_frame`]'s scan.
    column_key: u64,
    px_t1: [Real; 2],
    p_t: Point3<Real>,
    p_t1: Point3<Real>,
}

impl FrameSample {
    /// An unused sample, for sizing scratch arrays (`[FrameSample::EMPTY; N]`).
    pub const EMPTY: Self = Self {
        px: [0, 0],
        column_key: column_key(0, UNTRACKED),
        px_t1: [0.0, 0.0],
        p_t: Point3::new(0.0, 0.0, 0.0),
        p_t1: Point3::new(0.0, 0.0, 0.0),
    };
}

/// Flag of a [`FrameSample`]'s key: the point has no position at `t+1`.
const UNTRACKED: u32 = 1 << 16;

/// A column `x` in the low half, a sample's key in the high half. For `x_lo` and `span`
/// below 2³¹, `column_key(x, key) - column_key(x_lo, k) <= span` (wrapping) holds exactly
/// when `key == k` and `x - x_lo <= span` (wrapping) do: a different key moves the
/// difference by at least 2³² minus less than 2³¹.
const fn column_key(x: u32, key: u32) -> u64 {
    x as u64 | (key as u64) << 32
}

/// Bound below which [`column_key`]'s single compare is exact.
const COLUMN_KEY_EXACT_BELOW: u32 = 1 << 31;

impl FrameSample {
    const fn key(&self) -> u32 {
        (self.column_key >> 32) as u32
    }

    const fn label(&self) -> u16 {
        self.key() as u16
    }

    const fn tracked(&self) -> bool {
        self.key() & UNTRACKED == 0
    }
}

impl Default for FrameSample {
    fn default() -> Self {
        Self::EMPTY
    }
}

/// A body frame on three points of one segment, at `t` and tracked to `t+1`.
///
/// Point 0 is the origin, point 1 gives the x axis, point 2 the plane
/// ([`try_frame_from_points`]). Points are in the camera frame, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyFrame {
    /// Pixels `[u, v]` of the three points at `t`.
    pub px_t: [[u32; 2]; 3],
    /// Where the flow carries them at `t+1`, pixels.
    pub px_t1: [[Real; 2]; 3],
    /// The three points at `t`, camera frame.
    pub p_t: [Point3<Real>; 3],
    /// The three points at `t+1`, camera frame.
    pub p_t1: [Point3<Real>; 3],
    /// Label of the accumulated mask at the points (all three share it).
    pub label: u16,
}

impl BodyFrame {
    /// An unused frame, for sizing output arrays.
    pub const EMPTY: Self = Self {
        px_t: [[0; 2]; 3],
        px_t1: [[0.0; 2]; 3],
        p_t: [Point3::new(0.0, 0.0, 0.0); 3],
        p_t1: [Point3::new(0.0, 0.0, 0.0); 3],
        label: 0,
    };

    /// The spatial twist (BFIF) of this frame in the space frame whose origin is
    /// `space_origin` (camera coordinates) and whose axes are the camera's; `None` if a
    /// triangle is degenerate.
    #[must_use]
    pub fn twist(&self, space_origin: &Point3<Real>) -> Option<Twist> {
        let o = space_origin.coords;
        let [a, b, c] = self.p_t;
        let [a1, b1, c1] = self.p_t1;
        let space_from_body_t = try_frame_from_points(&(a - o), &(b - o), &(c - o))?;
        let space_from_body_t1 = try_frame_from_points(&(a1 - o), &(b1 - o), &(c1 - o))?;
        let twist = spatial_twist(&space_from_body_t, &space_from_body_t1);
        twist.is_finite().then_some(twist)
    }
}

impl Default for BodyFrame {
    fn default() -> Self {
        Self::EMPTY
    }
}

/// What [`create_frames`] produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameSet {
    /// Frames written to the front of the output slice.
    pub count: usize,
    /// Pixels sampled (at most [`Config::frame_samples`]).
    pub sampled: usize,
    /// Origin of the space frame (centroid of the sampled points at `t`), camera frame.
    pub space_origin: Point3<Real>,
}

/// CreateFrames: samples `cfg.frame_samples` labelled pixels and builds at most one frame
/// on each; writes the frames to the front of `frames`.
///
/// `samples` and `frames` each need [`Config::frame_samples`] entries. Deterministic for
/// `cfg.seed`.
///
/// # Errors
/// [`Error::BufferTooSmall`] if `samples` or `frames` is too short (nothing is written);
/// [`Error::BadConfig`] if `cfg` fails [`Config::check`].
pub fn create_frames(
    input: &MotionInput<'_>,
    cfg: &Config,
    samples: &mut [FrameSample],
    frames: &mut [BodyFrame],
) -> Result<FrameSet, Error> {
    create_frames_with_twists(input, cfg, samples, frames, |_, _| {})
}

/// [`create_frames`], handing each kept frame's twist to `on_twist(place, twist)` (its
/// place in `frames`): the twist a frame is checked with is the one [`compute_twists`]
/// gives it, so [`crate::pipeline::update_mask`] takes CalcBFIFs from here instead of
/// computing every twist twice.
///
/// # Errors
/// As [`create_frames`].
pub(crate) fn create_frames_with_twists(
    input: &MotionInput<'_>,
    cfg: &Config,
    samples: &mut [FrameSample],
    frames: &mut [BodyFrame],
    mut on_twist: impl FnMut(usize, Twist),
) -> Result<FrameSet, Error> {
    cfg.check()?;
    let n = cfg.frame_samples;
    check_len(Buffer::Samples, n, samples.len())?;
    check_len(Buffer::Frames, n, frames.len())?;
    let sampled = sample_pixels(input, cfg, &mut samples[..n]);
    let samples = &samples[..sampled];

    let mut sum = Vector3::zeros();
    for s in samples {
        sum += s.p_t.coords;
    }
    let space_origin = if sampled > 0 {
        Point3::from(sum / sampled as Real)
    } else {
        Point3::origin()
    };

    let mut count = 0;
    let mut scratch = TriangleScratch::new();
    let mut packed = [0; PACKED_ON_STACK];
    let packed = pack_keys(samples, input.size().0, &mut packed);
    let mut rows = [0; INDEXED_ROWS + 1];
    let rows = index_rows(samples, input.size().1, &mut rows);
    for (i, origin) in samples.iter().enumerate() {
        if !origin.tracked() {
            continue;
        }
        let index = SampleIndex { packed, rows };
        let Some(frame) = build_frame(input, cfg, samples, index, i, &mut scratch) else {
            continue;
        };
        let Some(twist) = frame.twist(&space_origin) else {
            continue;
        };
        if let Some(slot) = frames.get_mut(count) {
            *slot = frame;
            on_twist(count, twist);
            count += 1;
        }
    }
    Ok(FrameSet {
        count,
        sampled,
        space_origin,
    })
}

/// CalcBFIFs: the spatial twist of each frame in the space frame at `space_origin`.
/// Frames are those [`create_frames`] kept, so none is degenerate; should one be, its
/// twist is zero.
///
/// # Errors
/// [`Error::BufferTooSmall`] if `twists` is shorter than `frames`.
pub fn compute_twists(
    frames: &[BodyFrame],
    space_origin: &Point3<Real>,
    twists: &mut [Twist],
) -> Result<(), Error> {
    check_len(Buffer::FrameScratch, frames.len(), twists.len())?;
    for (frame, twist) in frames.iter().zip(twists.iter_mut()) {
        *twist = frame.twist(space_origin).unwrap_or(Twist::ZERO);
    }
    Ok(())
}

/// Pixels counted at once when skipping ahead to the next sample.
const SKIP_CHUNK_PX: usize = 64;
/// Pixels counted at once when skipping ahead within a chunk that holds the next sample:
/// only the parts that hold samples are visited pixel by pixel.
const SKIP_PART_PX: usize = 8;

/// Rows whose counts of eligible pixels [`sample_pixels`] keeps from its first pass (on
/// the stack, 2 bytes a row), so that the second skips them whole; rows past these, and
/// from the first whose count exceeds `u16`, are counted again, chunk by chunk.
const COUNTED_ROWS: usize = 512;

/// Eligible pixels (labelled, with a depth reading at `t`) among a run of a row. Counts
/// without branches so that it vectorises; the same test as [`valid_depth`].
fn count_eligible(labels: &[u16], depths: &[f32]) -> u32 {
    let eligible =
        |(&label, &z): (&u16, &f32)| u32::from((label != 0) & (z > 0.0) & (z <= MAX_DEPTH_M));
    labels.iter().zip(depths).map(eligible).sum::<u32>()
}

/// Calls `f(x, y, label, depth_m)` for the eligible pixel (labelled, with a depth reading
/// at `t`) of rank `from` in row-major order, then for the one of the rank `f` returns
/// (larger), and so on until `f` returns `None`; rows of which `counted` holds the count
/// (from the top) and runs of pixels before the wanted rank are counted in bulk, not
/// visited.
fn for_each_eligible_from(
    input: &MotionInput<'_>,
    counted: &[u16],
    mut from: u64,
    mut f: impl FnMut(usize, usize, u16, Real) -> Option<u64>,
) {
    let mut rank = 0u64;
    for y in 0..input.size().1 {
        if let Some(&here) = counted.get(y)
            && rank + u64::from(here) <= from
        {
            rank += u64::from(here);
            continue;
        }
        let (Some(labels), Some(depths)) = (input.labels_t.row(y), input.depth_t.row(y)) else {
            return;
        };
        for (c, (labels, depths)) in labels
            .chunks(SKIP_CHUNK_PX)
            .zip(depths.chunks(SKIP_CHUNK_PX))
            .enumerate()
        {
            let here = u64::from(count_eligible(labels, depths));
            if rank + here <= from {
                rank += here;
                continue;
            }
            // Parts of the chunk before the wanted rank are counted too (a fixed length
            // counts in a few vector steps); the rest is visited.
            let x = c * SKIP_CHUNK_PX;
            let (label_parts, label_rest) = labels.as_chunks::<SKIP_PART_PX>();
            let (depth_parts, depth_rest) = depths.as_chunks::<SKIP_PART_PX>();
            for (p, (labels, depths)) in label_parts.iter().zip(depth_parts).enumerate() {
                let here = u64::from(count_eligible(labels, depths));
                if rank + here <= from {
                    rank += here;
                    continue;
                }
                let x = x + p * SKIP_PART_PX;
                if !visit_eligible(x, y, labels, depths, (&mut rank, &mut from), &mut f) {
                    return;
                }
            }
            let x = x + label_parts.len() * SKIP_PART_PX;
            if !visit_eligible(x, y, label_rest, depth_rest, (&mut rank, &mut from), &mut f) {
                return;
            }
        }
    }
}

/// [`for_each_eligible_from`] pixel by pixel over a run of row `y` from column `x`:
/// counts the eligible pixels in `rank` and calls `f` at rank `from`, which it then
/// moves on; false once `f` returned `None`.
#[inline]
fn visit_eligible(
    x: usize,
    y: usize,
    labels: &[u16],
    depths: &[f32],
    (rank, from): (&mut u64, &mut u64),
    f: &mut impl FnMut(usize, usize, u16, Real) -> Option<u64>,
) -> bool {
    for (i, (&label, &z)) in labels.iter().zip(depths).enumerate() {
        if label == 0 {
            continue;
        }
        let Some(z) = valid_depth(z) else { continue };
        if *rank == *from {
            match f(x + i, y, label, z) {
                Some(next) => *from = next,
                None => return false,
            }
        }
        *rank += 1;
    }
    true
}

/// Stratified seeded sampling; returns how many samples were written (sorted row-major).
fn sample_pixels(input: &MotionInput<'_>, cfg: &Config, out: &mut [FrameSample]) -> usize {
    sample_pixels_counting::<COUNTED_ROWS>(input, cfg, out)
}

/// [`sample_pixels`], keeping the counts of at most the first `ROWS` rows; tests use a
/// small `ROWS` to reach the rows counted again.
fn sample_pixels_counting<const ROWS: usize>(
    input: &MotionInput<'_>,
    cfg: &Config,
    out: &mut [FrameSample],
) -> usize {
    let mut counts = [0u16; ROWS];
    // The leading rows whose counts are kept.
    let mut counted_rows = 0;
    let mut total: u64 = 0;
    for y in 0..input.size().1 {
        if let (Some(labels), Some(depths)) = (input.labels_t.row(y), input.depth_t.row(y)) {
            let here = count_eligible(labels, depths);
            total += u64::from(here);
            if counted_rows == y
                && let (Some(slot), Ok(here)) = (counts.get_mut(y), u16::try_from(here))
            {
                *slot = here;
                counted_rows += 1;
            }
        }
    }
    let counted = counts.get(..counted_rows).unwrap_or(&[]);
    let want = (out.len() as u64).min(total);
    if want == 0 {
        return 0;
    }
    let mut rng = Pcg32::new(cfg.seed);
    // Stratum i covers ranks [i·total/want, (i+1)·total/want); one draw in each.
    let target = |i: u64, rng: &mut Pcg32| {
        let lo = i * total / want;
        let hi = (i + 1) * total / want;
        lo + u64::from(rng.below(u32::try_from(hi - lo).unwrap_or(u32::MAX)))
    };
    let mut taken: u64 = 0;
    let first = target(0, &mut rng);
    let k = &input.intrinsics;
    // Called exactly at each drawn rank; returns the next one (ranks only grow: stratum
    // i+1 starts where stratum i ends).
    for_each_eligible_from(input, counted, first, |x, y, label, z| {
        if let Some(slot) = out.get_mut(taken as usize) {
            let (u, v) = (x as Real, y as Real);
            let z = local_depth(&input.depth_t, u, v, cfg).unwrap_or(z);
            *slot = track(input, cfg, x, y, label, k.back_project(u, v, z));
        }
        taken += 1;
        (taken < want).then(|| target(taken, &mut rng))
    });
    taken as usize
}

fn track(
    input: &MotionInput<'_>,
    cfg: &Config,
    x: usize,
    y: usize,
    label: u16,
    p_t: Point3<Real>,
) -> FrameSample {
    let mut sample = FrameSample {
        px: [x as u32, y as u32],
        column_key: column_key(x as u32, u32::from(label) | UNTRACKED),
        p_t,
        ..FrameSample::EMPTY
    };
    let Some([dx, dy]) = input.flow.get(x, y).copied() else {
        return sample;
    };
    let (u1, v1) = (x as Real + dx, y as Real + dy);
    if let Some(z1) = local_depth(&input.depth_t1, u1, v1, cfg) {
        sample.column_key = column_key(x as u32, u32::from(label));
        sample.px_t1 = [u1, v1];
        sample.p_t1 = input.intrinsics.back_project(u1, v1, z1);
    }
    sample
}

/// Depth at a sub-pixel position, denoised: a least-squares plane `z = a + b·dx + c·dy`
/// through the readings of the `(2r+1)²` window around the nearest pixel
/// (`r` = [`Config::depth_window_px`]) that lie within [`Config::depth_window_tol_m`] of the
/// bilinear depth there, evaluated at the position. On a surface the plane keeps the
/// slope and averages the sensor noise of the window; readings of another surface (past
/// an edge) are left out by the tolerance. `None` where [`bilinear_depth`] is `None`;
/// the bilinear depth itself when the window has no well-posed plane.
fn local_depth(depth: &ImageView<'_, f32>, u: Real, v: Real, cfg: &Config) -> Option<Real> {
    let z_ref = bilinear_depth(depth, u, v, cfg.depth_edge_m)?;
    let r = cfg.depth_window_px as i64;
    if r == 0 {
        return Some(z_ref);
    }
    // `u` and `v` are finite and not negative here: truncation rounds down.
    let (xc, yc) = ((u + 0.5) as i64, (v + 0.5) as i64);
    let tol = cfg.depth_window_tol_m;
    // The window clipped to the image.
    let (width, height) = depth.size();
    let columns = (xc - r).max(0)..=(xc + r).min(width as i64 - 1);
    let rows = (yc - r).max(0)..=(yc + r).min(height as i64 - 1);
    let window = (columns, rows);
    // Rounding is monotone and NaN fails: when `z_ref` lies farther than `tol` from both
    // limits of [`valid_depth`], every depth within `tol` of it is a reading.
    let (sums_a, sums_b, syz) = if z_ref > tol && MAX_DEPTH_M - z_ref > tol {
        plane_sums::<false>(depth, window, [u, v, z_ref], tol)
    } else {
        plane_sums::<true>(depth, window, [u, v, z_ref], tol)
    };
    let [n, sx, sy, sz] = sums_a.to_array();
    let [sxx, syy, sxy, sxz] = sums_b.to_array();
    // Solve [[n sx sy] [sx sxx sxy] [sy sxy syy]] (a b c) = (sz sxz syz) for a (Cramer).
    let det = n * (sxx * syy - sxy * sxy) - sx * (sx * syy - sxy * sy) + sy * (sx * sxy - sxx * sy);
    if !(n >= 6.0 && det.abs() > 1e-3 * n * n * n) {
        return Some(z_ref);
    }
    let det_a =
        sz * (sxx * syy - sxy * sxy) - sx * (sxz * syy - sxy * syz) + sy * (sxz * sxy - sxx * syz);
    let a = det_a / det;
    Some(z_ref + a).filter(|z| z.is_finite() && *z > 0.0)
}

/// The sums of [`local_depth`]'s normal equations over the readings of `window`
/// (columns, rows) within `tol` of `z_ref`, in offsets from `(u, v)` and from `z_ref`:
/// `[n, sx, sy, sz]` and `[sxx, syy, sxy, sxz]` as lanes, and `syz`. Each lane adds its
/// terms in pixel order, as one sum per variable would. `CHECK_READING` tests each depth
/// with [`valid_depth`] too (needless when the tolerance implies it).
#[inline(always)]
fn plane_sums<const CHECK_READING: bool>(
    depth: &ImageView<'_, f32>,
    (columns, rows): (RangeInclusive<i64>, RangeInclusive<i64>),
    [u, v, z_ref]: [Real; 3],
    tol: Real,
) -> (f32x4, f32x4, Real) {
    let (mut sums_a, mut sums_b, mut syz) = (f32x4::ZERO, f32x4::ZERO, 0.0);
    let (x_lo, x_hi) = (*columns.start(), *columns.end());
    // Row slices, in the same order as pixel by pixel.
    for y in rows {
        let Some(run) = depth
            .row(y as usize)
            .and_then(|row| row.get(x_lo as usize..=x_hi as usize))
        else {
            continue;
        };
        let dy = y as Real - v;
        for (x, &z) in (x_lo..).zip(run) {
            let dz = z - z_ref;
            let reading = !CHECK_READING || ((z > 0.0) & (z <= MAX_DEPTH_M));
            if !(reading & (dz.abs() <= tol)) {
                continue;
            }
            let dx = x as Real - u;
            sums_a += f32x4::new([1.0, dx, dy, dz]);
            sums_b += f32x4::new([dx, dy, dx, dx]) * f32x4::new([dx, dy, dy, dz]);
            syz += dy * dz;
        }
    }
    (sums_a, sums_b, syz)
}

/// Depth at a sub-pixel position from its four neighbours; `None` if any is missing, the
/// position is outside the image, or the four span more than `edge_m` (a depth edge).
fn bilinear_depth(depth: &ImageView<'_, f32>, u: Real, v: Real, edge_m: Real) -> Option<Real> {
    if !(u.is_finite() && v.is_finite()) || u < 0.0 || v < 0.0 {
        return None;
    }
    // Not negative: truncation rounds down (and saturates far outside any image).
    let (x0, y0) = (u as usize, v as usize);
    // Exact while the place fits `usize` (2^32 on the firmware and wasm32); past that the
    // saturated place finds no pixel.
    let (fx, fy) = (u - x0 as Real, v - y0 as Real);
    // At the last row/column the far neighbour has zero weight; reuse the near one.
    let x1 = if fx > 0.0 { x0.saturating_add(1) } else { x0 };
    let y1 = if fy > 0.0 { y0.saturating_add(1) } else { y0 };
    let (row0, row1) = (depth.row(y0)?, depth.row(y1)?);
    let z00 = valid_depth(*row0.get(x0)?)?;
    let z10 = valid_depth(*row0.get(x1)?)?;
    let z01 = valid_depth(*row1.get(x0)?)?;
    let z11 = valid_depth(*row1.get(x1)?)?;
    // Readings are never NaN: plain comparisons pick as `min` and `max` do.
    let (min, max) = (
        |a: Real, b: Real| if b < a { b } else { a },
        |a: Real, b: Real| if b > a { b } else { a },
    );
    let lo = min(min(min(z00, z10), z01), z11);
    let hi = max(max(max(z00, z10), z01), z11);
    if hi - lo > edge_m {
        return None;
    }
    let top = z00 + (z10 - z00) * fx;
    let bottom = z01 + (z11 - z01) * fx;
    Some(top + (bottom - top) * fy)
}

/// Samples whose [`packed_key`]s [`create_frames`] keeps on its stack (4 bytes each) for
/// [`build_frame`]'s scan, which then reads four keys a vector instead of one sample's
/// [`column_key`] at a time; past this many samples it reads the samples.
const PACKED_ON_STACK: usize = 1024;

/// Columns a [`packed_key`] holds: images wider than this are scanned by sample.
const PACKED_COLUMNS: usize = 1 << 15;

/// A sample's column `x` (below [`PACKED_COLUMNS`]) in the low half and its label in the
/// high half; label zero (no origin has it) if the flow lost the point. For `x_lo` and
/// `span` below 2¹⁵, `packed_key(x, l) - packed_key(x_lo, k) <= span` (wrapping) holds
/// exactly when `l == k` and `x - x_lo <= span` (wrapping) do: a different label moves
/// the difference by a multiple of 2¹⁶ that leaves it between 2¹⁵ and 2³², unwrapped.
const fn packed_key(x: u32, label: u16) -> u32 {
    x | (label as u32) << 16
}

/// The [`packed_key`]s of `samples`, written to the front of `packed`; `None` if they do
/// not fit it or the image is wider than [`PACKED_COLUMNS`].
fn pack_keys<'p>(
    samples: &[FrameSample],
    width: usize,
    packed: &'p mut [u32],
) -> Option<&'p [u32]> {
    if width > PACKED_COLUMNS {
        return None;
    }
    let packed = packed.get_mut(..samples.len())?;
    for (key, s) in packed.iter_mut().zip(samples) {
        let label = if s.tracked() { s.label() } else { 0 };
        *key = packed_key(s.px[0], label);
    }
    Some(packed)
}

/// Image rows whose first samples [`create_frames`] keeps on its stack (2 bytes a row)
/// for [`build_frame`] to find an origin's window by two reads instead of two binary
/// searches; taller images are searched.
const INDEXED_ROWS: usize = 1024;

/// `first[y]`, for each row `y` of an image `height` rows tall and `y = height`: the
/// place of the first of `samples` (sorted by row, as sampled) in row `y` or below, the
/// same place as a binary search finds; written to the front of `first`. `None` if the
/// image is taller than `first` has room for, a sample lies below it, or places do not
/// fit `u16`.
fn index_rows<'r>(
    samples: &[FrameSample],
    height: usize,
    first: &'r mut [u16],
) -> Option<&'r [u16]> {
    let first = first.get_mut(..=height)?;
    u16::try_from(samples.len()).ok()?;
    let mut place = 0;
    for (y, slot) in first.iter_mut().enumerate() {
        while samples.get(place).is_some_and(|s| (s.px[1] as usize) < y) {
            place += 1;
        }
        *slot = place as u16;
    }
    (place == samples.len()).then_some(first)
}

/// The places `first..last` of the samples in rows `ys`: from the rows' first samples
/// `rows` ([`index_rows`]) if given, else by binary search. `None` only if `rows` is
/// empty (an index has a row past the last, so it never is).
fn rows_window(
    samples: &[FrameSample],
    rows: Option<&[u16]>,
    ys: RangeInclusive<i64>,
) -> Option<(usize, usize)> {
    let (y_lo, y_hi) = (*ys.start(), *ys.end());
    let Some(rows) = rows else {
        return Some((
            samples.partition_point(|s| i64::from(s.px[1]) < y_lo),
            samples.partition_point(|s| i64::from(s.px[1]) <= y_hi),
        ));
    };
    let last = rows.len().checked_sub(1)?;
    let first_at = |y: i64| {
        let row = usize::try_from(y.max(0)).map_or(last, |y| y.min(last));
        rows.get(row).copied()
    };
    Some((
        usize::from(first_at(y_lo)?),
        usize::from(first_at(y_hi.saturating_add(1))?),
    ))
}

/// What [`create_frames`] keeps on its stack to speed up [`build_frame`]: the samples'
/// [`packed_key`]s if [`pack_keys`] could write them, the first sample of each row if
/// [`index_rows`] could.
#[derive(Clone, Copy)]
struct SampleIndex<'a> {
    packed: Option<&'a [u32]>,
    rows: Option<&'a [u16]>,
}

/// The frame with origin `samples[i]`, or `None` if no good triangle exists.
fn build_frame(
    input: &MotionInput<'_>,
    cfg: &Config,
    samples: &[FrameSample],
    index: SampleIndex<'_>,
    i: usize,
    scratch: &mut TriangleScratch,
) -> Option<BodyFrame> {
    build_frame_listing::<LISTED_ON_STACK, { !LANES }>(input, cfg, samples, index, i, scratch)
}

/// Scratch of [`build_frame`] for the candidates of one origin, on the stack of
/// [`create_frames`] once for all origins (filling it for each would cost more than the
/// search): an origin reads only the entries it wrote.
struct TriangleScratch {
    /// Window places of the listed candidates.
    listed: [u16; LISTED_ON_STACK],
    /// Distance of each listed candidate from the origin (zero if outside the limits).
    dist: [Real; LISTED_ON_STACK],
    /// Each listed candidate's point at `t`, component by component (`x` NaN once it is
    /// out of the running for the third point).
    kept: [[Real; LISTED_ON_STACK]; 3],
}

impl TriangleScratch {
    const fn new() -> Self {
        Self {
            listed: [0; LISTED_ON_STACK],
            dist: [0.0; LISTED_ON_STACK],
            kept: [[0.0; LISTED_ON_STACK]; 3],
        }
    }
}

/// [`build_frame`], listing fewer than `CAP` candidates (a power of two, at most
/// [`LISTED_ON_STACK`]) before it falls back to [`best_triangle`], and pruning the third
/// point's candidates if `PRUNE` ([`third_point_of_kept`]); tests use a small `CAP` to
/// reach the fallback, and both ways of the third point's pass.
fn build_frame_listing<const CAP: usize, const PRUNE: bool>(
    input: &MotionInput<'_>,
    cfg: &Config,
    samples: &[FrameSample],
    SampleIndex { packed, rows }: SampleIndex<'_>,
    i: usize,
    scratch: &mut TriangleScratch,
) -> Option<BodyFrame> {
    const { assert!(CAP.is_power_of_two() && CAP <= LISTED_ON_STACK) };
    let o = samples.get(i)?;
    let k = &input.intrinsics;
    let max_side = cfg.frame_max_side_m;
    // Points within max_side of the origin are at most this many pixels away.
    let near_z = (o.p_t.z - max_side).max(1e-3);
    let reach = max_side * k.fx.max(k.fy) / near_z + 1.0;
    let reach_px = if reach.is_finite() && reach < 1e6 {
        reach as i64
    } else {
        i64::MAX / 4
    };
    let (ox, oy) = (i64::from(o.px[0]), i64::from(o.px[1]));
    let (first, last) = rows_window(samples, rows, oy - reach_px..=oy + reach_px)?;
    let window = samples.get(first..last)?;
    // Columns within reach as one unsigned range test: `x - x_lo <= x_span`.
    let x_lo = (ox - reach_px).clamp(0, i64::from(u32::MAX)) as u32;
    let x_span = ((ox + reach_px).clamp(0, i64::from(u32::MAX)) as u32).saturating_sub(x_lo);
    let key = u32::from(o.label());
    // Tracked, same label, columns within reach. (The origin itself passes: the listing
    // skips its place, the fallback its pixel.)
    let candidate = |s: &FrameSample| (s.px[0].wrapping_sub(x_lo) <= x_span) & (s.key() == key);
    // The window's candidates, listed without a branch per sample (the column test is a
    // coin flip for the branch predictor), in two runs around the origin's place (no
    // other sample has its pixel): from the packed keys where there are some, else from
    // the samples. A write at `CAP` wraps and overwrites the first entry (the mask only
    // spares a bounds check); such a list is not used. Window places fit `u16` (checked
    // first).
    if window.len() <= 1 << 16 {
        let own = i.wrapping_sub(first).min(window.len());
        let count = if let Some(keys) = packed.and_then(|p| p.get(first..last)) {
            // Below `PACKED_COLUMNS` every column and `x_lo` are; so is the span clipped.
            let base = packed_key(x_lo, o.label());
            let span = x_span.min(PACKED_COLUMNS as u32 - 1);
            let one = |k: &u32| k.wrapping_sub(base) <= span;
            if KEY_LANES {
                let (base, span) = (u32x4::splat(base), u32x4::splat(span));
                list::<CAP, _>(around(keys, own), window, scratch, one, |f| {
                    packed_bits(f, base, span)
                })
            } else {
                list::<CAP, _>(around(keys, own), window, scratch, one, |f| {
                    four_bits(f, one)
                })
            }
        } else if x_lo < COLUMN_KEY_EXACT_BELOW && x_span < COLUMN_KEY_EXACT_BELOW {
            let (base, span) = (column_key(x_lo, key), u64::from(x_span));
            let one = |s: &FrameSample| s.column_key.wrapping_sub(base) <= span;
            if KEY_LANES {
                let low = u32x4::new([x_lo, key, x_lo, key]);
                let limit = u32x4::new([x_span, 0, x_span, 0]);
                list::<CAP, _>(around(window, own), window, scratch, one, |f| {
                    keyed_bits(f, low, limit)
                })
            } else {
                list::<CAP, _>(around(window, own), window, scratch, one, |f| {
                    four_bits(f, one)
                })
            }
        } else {
            list::<CAP, _>(around(window, own), window, scratch, candidate, |f| {
                four_bits(f, candidate)
            })
        };
        // At `CAP` the next write already wrapped.
        if count < CAP {
            return best_triangle_listed::<PRUNE>(o, window, count, scratch, cfg);
        }
    }
    best_triangle(
        o,
        window.iter().filter(|s| candidate(s) && s.px != o.px),
        cfg,
    )
}

/// `all` in two runs with their first places, before and after place `own`, which is
/// left out.
fn around<T>(all: &[T], own: usize) -> [(usize, &[T]); 2] {
    let (before, from_own) = all.split_at(own.min(all.len()));
    let after = from_own.get(1..).unwrap_or(&[]);
    [(0, before), (own + 1, after)]
}

/// Writes the places of the entries of `runs` (each with its first place in `window`:
/// the samples or their keys) that pass `candidate` to `scratch.listed`, and the points
/// at `t` of those samples to `scratch.kept`, in order; returns how many passed. The test
/// runs without a branch per entry: the results of a word of [`WORD_BITS`] entries are
/// packed first, then only its set bits are visited. A write at `CAP` wraps (see
/// [`build_frame_listing`]).
#[inline]
fn list<const CAP: usize, T>(
    runs: [(usize, &[T]); 2],
    window: &[FrameSample],
    scratch: &mut TriangleScratch,
    candidate: impl Fn(&T) -> bool,
    four: impl Fn(&[T; 4]) -> usize,
) -> usize {
    let mut count = 0;
    for (start, run) in runs {
        let (words, rest) = run.as_chunks::<WORD_BITS>();
        for (first, word) in (start..).step_by(WORD_BITS).zip(words) {
            let bits = candidate_bits(word, &candidate, &four);
            count = emit::<CAP>(scratch, count, first, bits, window);
        }
        let first = start + words.len() * WORD_BITS;
        let bits = candidate_bits(rest, &candidate, &four);
        count = emit::<CAP>(scratch, count, first, bits, window);
    }
    count
}

/// Samples whose candidate tests [`list`] packs into one word.
const WORD_BITS: usize = usize::BITS as usize;

/// Bit `b` set when `chunk[b]` (at most [`WORD_BITS`] samples) passes `candidate`;
/// `four` gives the bits of four samples at once (the first in bit 0).
#[inline]
fn candidate_bits<T>(
    chunk: &[T],
    candidate: impl Fn(&T) -> bool,
    four: impl Fn(&[T; 4]) -> usize,
) -> usize {
    // Each sample enters at the top and moves down as the later ones enter.
    let (fours, rest) = chunk.as_chunks::<4>();
    let bits = fours
        .iter()
        .fold(0usize, |bits, f| bits >> 4 | four(f) << (WORD_BITS - 4));
    let bits = rest.iter().fold(bits, |bits, s| {
        bits >> 1 | usize::from(candidate(s)) << (WORD_BITS - 1)
    });
    bits >> ((WORD_BITS - chunk.len()) % WORD_BITS)
}

/// The bits of four samples (the first in bit 0), each tested by `candidate`.
#[inline]
fn four_bits<T>([a, b, c, d]: &[T; 4], candidate: impl Fn(&T) -> bool) -> usize {
    let bit = |s| usize::from(candidate(s));
    bit(a) | bit(b) << 1 | bit(c) << 2 | bit(d) << 3
}

/// Whether `wide` has vector lanes on this target (elsewhere it runs them one by one;
/// `build.rs` sets the cfg).
const LANES: bool = cfg!(vector_lanes);

/// Whether [`build_frame`] tests the column keys of samples on vector lanes, two at a
/// time: only where there are [`LANES`] and the low half of a `u64` comes first.
const KEY_LANES: bool = LANES && cfg!(target_endian = "little");

/// [`four_bits`] for the [`column_key`] test, on lanes: a sample's key as its two 32-bit
/// halves (column, key) less `low` (`x_lo`, the key) must be at most `limit` (the
/// column span, zero), wrapping; the same test as the one compare of the whole key.
#[inline]
fn keyed_bits([a, b, c, d]: &[FrameSample; 4], low: u32x4, limit: u32x4) -> usize {
    let pair = |a: &FrameSample, b: &FrameSample| {
        // Little-endian: the low half of each key first.
        let halves: u32x4 = wide::bytemuck::cast(u64x2::new([a.column_key, b.column_key]));
        let outside = (halves - low).simd_gt(limit);
        usize::from(PAIR_INSIDE[outside.to_bitmask() as usize % 16])
    };
    pair(a, b) | pair(c, d) << 2
}

/// [`four_bits`] for the [`packed_key`] test, on lanes: a key less `base` must be at
/// most `span`, wrapping.
#[inline]
fn packed_bits(keys: &[u32; 4], base: u32x4, span: u32x4) -> usize {
    let outside = (u32x4::new(*keys) - base).simd_gt(span);
    !outside.to_bitmask() as usize & 0b1111
}

/// For the lanes of two samples that failed [`keyed_bits`]' test (bits 0 and 1 the first
/// sample's, 2 and 3 the second's), which samples pass (bit 0 the first).
const PAIR_INSIDE: [u8; 16] = {
    let mut table = [0; 16];
    let mut failed = 0;
    while failed < 16 {
        table[failed] = (failed & 3 == 0) as u8 | ((failed >> 2 == 0) as u8) << 1;
        failed += 1;
    }
    table
};

/// Lists sample `window[first + b]` for each set bit `b` of `bits`, from the lowest, at
/// `count` onwards ([`list`]); returns the new count.
#[inline]
fn emit<const CAP: usize>(
    scratch: &mut TriangleScratch,
    mut count: usize,
    first: usize,
    mut bits: usize,
    window: &[FrameSample],
) -> usize {
    let TriangleScratch {
        listed,
        kept: [xs, ys, zs],
        ..
    } = scratch;
    while bits != 0 {
        let b = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        let Some(s) = window.get(first + b) else {
            break;
        };
        let slot = count & (CAP - 1);
        listed[slot] = (first + b) as u16;
        xs[slot] = s.p_t.x;
        ys[slot] = s.p_t.y;
        zs[slot] = s.p_t.z;
        count += 1;
    }
    count
}

/// Room for the candidates [`build_frame`] lists on the stack (2 bytes an entry, and 4
/// for each one's distance in [`best_triangle_listed`]); from this many on, the window is
/// scanned by [`best_triangle`] instead.
const LISTED_ON_STACK: usize = 512;
const _: () = assert!(LISTED_ON_STACK.is_power_of_two());

/// Relative slack on the bound `|a|·|b|` of a triangle's doubled area `|a × b|` in
/// [`third_point_of_kept`]: far above the few units in the last place by which the
/// rounded cross product's norm can exceed the rounded product of the norms.
const AREA_BOUND_SLACK: Real = 1.001;
/// Smallest side and bound [`third_point_of_kept`] prunes with: below it, rounding
/// near the subnormals is no longer relative, and every candidate is computed.
const AREA_BOUND_MIN: Real = 1e-15;
/// Largest bound [`third_point_of_kept`] prunes with: above it, the squares inside the
/// norms could overflow.
const AREA_BOUND_MAX: Real = 1e18;

/// Whether sides `dj`, `db` are in the range where [`AREA_BOUND_SLACK`] bounds the
/// rounded `|a × b|`.
fn prunable(dj: Real, db: Real) -> bool {
    dj >= AREA_BOUND_MIN
        && db >= AREA_BOUND_MIN
        && (AREA_BOUND_MIN..=AREA_BOUND_MAX).contains(&(dj * db))
}

/// [`best_triangle`] over `window[k]` for `k` in the first `count` entries of
/// `scratch.listed` (in that order; the origin's place is not listed), bit for bit, with
/// their points in `scratch.kept` as [`list`] wrote them; one pass, four candidates
/// at a time, finds the second point and drops the candidates outside the side limits,
/// the other looks for the third point among the rest, four at a time too. Each lane
/// keeps the earliest of its best; the earliest of the lanes' equal best wins, as a scan
/// in order picks. `PRUNE` as [`third_point_of_kept`]. Inlined where there are
/// [`LANES`] (fewer instructions there; more on the firmware).
#[cfg_attr(vector_lanes, inline(always))]
fn best_triangle_listed<const PRUNE: bool>(
    o: &FrameSample,
    window: &[FrameSample],
    count: usize,
    scratch: &mut TriangleScratch,
    cfg: &Config,
) -> Option<BodyFrame> {
    let TriangleScratch {
        listed,
        dist,
        kept: [xs, ys, zs],
    } = scratch;
    let listed = listed.get(..count)?;
    // A NaN coordinate fails every test below: so are the places after the last
    // candidate (up to a multiple of four) left out.
    let fours = count.div_ceil(4);
    for x in xs.get_mut(count..fours * 4).unwrap_or(&mut []) {
        *x = Real::NAN;
    }
    let (min_side, max_side) = (cfg.frame_min_side_m, cfg.frame_max_side_m);
    let splat = f32x4::splat;
    let [ox, oy, oz] = [o.p_t.x, o.p_t.y, o.p_t.z].map(splat);
    let (min4, max4) = (splat(min_side), splat(max_side));
    // The second point: the farthest candidate within the side limits. The distance of
    // each is kept (zero for one outside, whose `x` turns NaN).
    let mut farthest = splat(Real::NEG_INFINITY);
    let mut farthest_at = splat(0.0);
    let mut at = f32x4::new([0.0, 1.0, 2.0, 3.0]);
    let (x4, _) = xs.as_chunks_mut::<4>();
    let (y4, _) = ys.as_chunks::<4>();
    let (z4, _) = zs.as_chunks::<4>();
    let (d4, _) = dist.as_chunks_mut::<4>();
    for (((x, y), z), d) in x4.iter_mut().zip(y4).zip(z4).zip(d4).take(fours) {
        let here = at;
        at += splat(4.0);
        let sx = f32x4::new(*x);
        let (dx, dy, dz) = (sx - ox, f32x4::new(*y) - oy, f32x4::new(*z) - oz);
        let db = sqrt4((dx * dx + dy * dy) + dz * dz);
        let keep = db.simd_ge(min4) & db.simd_le(max4);
        let farther = keep & db.simd_gt(farthest);
        farthest = farther.select(db, farthest);
        farthest_at = farther.select(here, farthest_at);
        *d = keep.select(db, splat(0.0)).to_array();
        *x = keep.select(sx, splat(Real::NAN)).to_array();
    }
    let (dj, j_at) = earliest_largest(farthest, farthest_at);
    if dj == Real::NEG_INFINITY {
        return None;
    }
    let j = window.get(usize::from(*listed.get(j_at)?))?;
    // The second point is not the third.
    if let Some(x) = xs.get_mut(j_at) {
        *x = Real::NAN;
    }
    let best = third_point_of_kept::<PRUNE>(o, (j, dj), [&*xs, &*ys, &*zs], dist, fours, cfg);
    let kk = window.get(usize::from(*listed.get(best.1)?))?;
    triangle_frame(o, j, (kk, best.0), cfg)
}

/// The largest of four lanes' values and its place (`at`, whole numbers), the smallest
/// place among equal ones; `(-∞, ·)` if every value is `-∞`.
fn earliest_largest(value: f32x4, at: f32x4) -> (Real, usize) {
    let mut best = (Real::NEG_INFINITY, usize::MAX);
    for (v, at) in value.to_array().into_iter().zip(at.to_array()) {
        let at = at as usize;
        if v > best.0 || (v == best.0 && at < best.1) {
            best = (v, at);
        }
    }
    best
}

/// [`third_point`] over the first `4·fours` kept candidates (points `xyz`, distances
/// `dist` from `o`; a NaN `x` fails), four lanes at once: the same operations in the same
/// order, lane by lane. Returns (doubled area, place) of the pick: the largest area, the
/// earliest place among equal ones, as a scan in order picks (`-∞` if none).
///
/// If `PRUNE`, four candidates whose bounds `|a|·|b|` on the doubled area lie below the
/// best area so far are skipped. Where the lanes are vectors ([`LANES`]) that saves
/// too few fours to pay for the bound, the largest area of each four and the branch,
/// which the skips make hard to predict; where they run one by one (the firmware) it
/// pays.
fn third_point_of_kept<const PRUNE: bool>(
    o: &FrameSample,
    (j, dj): (&FrameSample, Real),
    xyz: [&[Real; LISTED_ON_STACK]; 3],
    dist: &[Real; LISTED_ON_STACK],
    fours: usize,
    cfg: &Config,
) -> (Real, usize) {
    let (min_side, max_side) = (cfg.frame_min_side_m, cfg.frame_max_side_m);
    let splat = f32x4::splat;
    let a = j.p_t - o.p_t;
    let [ox, oy, oz] = [o.p_t.x, o.p_t.y, o.p_t.z].map(splat);
    let [jx, jy, jz] = [j.p_t.x, j.p_t.y, j.p_t.z].map(splat);
    let [ax, ay, az] = [a.x, a.y, a.z].map(splat);
    let (min4, max4, dj4) = (splat(min_side), splat(max_side), splat(dj));
    let sin_dj = splat(cfg.frame_min_sin * dj);
    // Every kept `db` lies within the side limits, and rounded products are monotone: if
    // both limits are prunable with `dj`, every kept candidate is (a dropped one, with
    // `db` zero, never wins anyway).
    let prune = PRUNE && prunable(dj, min_side) && prunable(dj, max_side);
    // Each lane keeps its own pick (the earliest of its largest areas) and place; `best`
    // is the largest of the lanes' areas (kept only to prune).
    let mut best_area = splat(Real::NEG_INFINITY);
    let mut best_at = splat(0.0);
    let mut best = Real::NEG_INFINITY;
    let mut at = f32x4::new([0.0, 1.0, 2.0, 3.0]);
    let [xs, ys, zs] = xyz.map(|c| c.as_chunks::<4>().0);
    let (ds, _) = dist.as_chunks::<4>();
    for (((x, y), z), db) in xs.iter().zip(ys).zip(zs).zip(ds).take(fours) {
        let here = at;
        at += splat(4.0);
        let db = f32x4::new(*db);
        // `|a × b| <= |a|·|b|`: a candidate whose bound is below the best area so far
        // cannot win (ties keep the earlier one), so four such are skipped before any
        // arithmetic. The slack covers the rounding of both sides (a few units in the
        // last place), which holds while the squares inside the norms are normal numbers.
        if prune
            && (dj4 * db * splat(AREA_BOUND_SLACK))
                .simd_lt(splat(best))
                .all()
        {
            continue;
        }
        let [sx, sy, sz] = [x, y, z].map(|c| f32x4::new(*c));
        let (dx, dy, dz) = (sx - jx, sy - jy, sz - jz);
        let djk = sqrt4((dx * dx + dy * dy) + dz * dz);
        let (bx, by, bz) = (sx - ox, sy - oy, sz - oz);
        let (c0, c1, c2) = (ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx);
        let area = sqrt4((c0 * c0 + c1 * c1) + c2 * c2);
        let larger = djk.simd_ge(min4)
            & djk.simd_le(max4)
            & area.simd_ge(sin_dj * db)
            & area.simd_gt(best_area);
        best_area = larger.select(area, best_area);
        best_at = larger.select(here, best_at);
        if PRUNE {
            // No area is NaN: a plain comparison takes the larger.
            let larger_of = |a: Real, b: Real| if a > b { a } else { b };
            let [a0, a1, a2, a3] = best_area.to_array();
            best = larger_of(larger_of(a0, a1), larger_of(a2, a3));
        }
    }
    earliest_largest(best_area, best_at)
}

/// The frame on origin `o` and the best two of `candidates` (samples of its segment near
/// it), or `None` if no good triangle exists. Picks by selects from a `-∞` start, as
/// [`best_triangle_listed`] does.
fn best_triangle<'s>(
    o: &'s FrameSample,
    candidates: impl Iterator<Item = &'s FrameSample> + Clone,
    cfg: &Config,
) -> Option<BodyFrame> {
    let max_side = cfg.frame_max_side_m;
    let min_side = cfg.frame_min_side_m;
    let mut best_j = (o, Real::NEG_INFINITY);
    for s in candidates.clone() {
        let d = (s.p_t - o.p_t).norm();
        let farther = (d >= min_side) & (d <= max_side) & (d > best_j.1);
        best_j = select_unpredictable(farther, (s, d), best_j);
    }
    let (j, dj) = best_j;
    if dj == Real::NEG_INFINITY {
        return None;
    }
    let mut best_k = (o, Real::NEG_INFINITY);
    for s in candidates {
        let db = (s.p_t - o.p_t).norm();
        best_k = third_point(o, (j, dj), (s, db), best_k, cfg);
    }
    triangle_frame(o, j, best_k, cfg)
}

/// The third point's pick after candidate `s` at distance `db` from `o`, for the second
/// point `j` at distance `dj`: `s` replaces `best_k` (sample, doubled area; `-∞` before
/// any) when it is not `j`, its sides are within the limits, the sine at `o` is at least
/// [`Config::frame_min_sin`] and its triangle is larger (ties keep the earlier one). A
/// select, not a branch: the tests wait on square roots, so a mispredicted branch would
/// cost their latency on top of the refill.
#[inline]
fn third_point<'s>(
    o: &FrameSample,
    (j, dj): (&FrameSample, Real),
    (s, db): (&'s FrameSample, Real),
    best_k: (&'s FrameSample, Real),
    cfg: &Config,
) -> (&'s FrameSample, Real) {
    let (min_side, max_side) = (cfg.frame_min_side_m, cfg.frame_max_side_m);
    let djk = (s.p_t - j.p_t).norm();
    let area = (j.p_t - o.p_t).cross(&(s.p_t - o.p_t)).norm();
    let larger = (s.px != j.px)
        & (db >= min_side)
        & (db <= max_side)
        & (djk >= min_side)
        & (djk <= max_side)
        & (area >= cfg.frame_min_sin * dj * db)
        & (area > best_k.1);
    select_unpredictable(larger, (s, area), best_k)
}

/// The frame on `o`, `j` and the third point's pick `best_k` ([`third_point`]), `None`
/// if there is none ([`rigid_frame`] otherwise).
fn triangle_frame(
    o: &FrameSample,
    j: &FrameSample,
    (kk, area): (&FrameSample, Real),
    cfg: &Config,
) -> Option<BodyFrame> {
    if area == Real::NEG_INFINITY {
        return None;
    }
    rigid_frame(o, j, kk, cfg)
}

/// The frame on `o`, `j`, `kk` if no side changes length by [`Config::frame_rigid_tol_m`]
/// or more from `t` to `t+1`.
fn rigid_frame(
    o: &FrameSample,
    j: &FrameSample,
    kk: &FrameSample,
    cfg: &Config,
) -> Option<BodyFrame> {
    let pts = [o, j, kk];
    for (p, q) in [(0, 1), (0, 2), (1, 2)] {
        let before = (pts[p].p_t - pts[q].p_t).norm();
        let after = (pts[p].p_t1 - pts[q].p_t1).norm();
        // NaN fails the check too.
        if (after - before).abs().partial_cmp(&cfg.frame_rigid_tol_m)
            != Some(core::cmp::Ordering::Less)
        {
            return None;
        }
    }
    Some(BodyFrame {
        px_t: [o.px, j.px, kk.px],
        px_t1: [o.px_t1, j.px_t1, kk.px_t1],
        p_t: [o.p_t, j.p_t, kk.p_t],
        p_t1: [o.p_t1, j.p_t1, kk.p_t1],
        label: o.label(),
    })
}

#[cfg(test)]
mod tests {
    use std::vec;

    use nalgebra::{Translation3, Vector3};

    use super::*;
    use crate::Pose;
    use crate::synth::fixture::{Rendered, box_at, render, spin_about};

    fn input(r: &Rendered) -> MotionInput<'_> {
        let (w, h) = (r.width, r.height);
        MotionInput::new(
            ImageView::packed(w, h, &r.labels_t).unwrap(),
            ImageView::packed(w, h, &r.depth_t).unwrap(),
            ImageView::packed(w, h, &r.depth_t1).unwrap(),
            ImageView::packed(w, h, &r.flow).unwrap(),
            r.intrinsics,
        )
        .unwrap()
    }

    fn two_moving_boxes() -> (Rendered, [Pose; 2]) {
        let mut a = box_at(-0.04, 0.0, 0.6, [0.04, 0.03], 1);
        let mut b = box_at(0.04, 0.0, 0.6, [0.04, 0.03], 2);
        a.motion = Translation3::new(0.01, 0.0, 0.0).into();
        b.motion = spin_about(Vector3::new(0.04, 0.0, 0.6), 0.1);
        let m = [a.motion, b.motion];
        (render(&[a, b], 320, 240), m)
    }

    #[test]
    fn every_frame_on_a_body_has_that_bodys_spatial_twist() {
        let (r, motions) = two_moving_boxes();
        let input = input(&r);
        let cfg = Config::PAPER;
        let mut samples = vec![FrameSample::EMPTY; cfg.frame_samples];
        let mut frames = vec![BodyFrame::EMPTY; cfg.frame_samples];
        let set = create_frames(&input, &cfg, &mut samples, &mut frames).unwrap();
        assert!(set.sampled == cfg.frame_samples, "{set:?}");
        assert!(set.count > 500, "{set:?}");
        let mut twists = vec![Twist::ZERO; set.count];
        compute_twists(&frames[..set.count], &set.space_origin, &mut twists).unwrap();
        let to_space = Translation3::from(-set.space_origin.coords);
        for (f, t) in frames[..set.count].iter().zip(&twists) {
            let m = motions[usize::from(f.label) - 1];
            let expected = Twist::log(&(to_space * m * to_space.inverse()));
            assert!(t.distance(&expected, 0.05) < 2e-4, "{t:?} vs {expected:?}");
            for p in 0..3 {
                let side = (f.p_t[p] - f.p_t[(p + 1) % 3]).norm();
                assert!(side <= cfg.frame_max_side_m + 1e-6 && side >= cfg.frame_min_side_m);
            }
        }
    }

    #[test]
    fn sampling_is_seeded_and_never_repeats_a_pixel() {
        let (r, _) = two_moving_boxes();
        let input = input(&r);
        let mut cfg = Config::PAPER;
        let mut a = vec![FrameSample::EMPTY; cfg.frame_samples];
        let mut b = vec![FrameSample::EMPTY; cfg.frame_samples];
        let mut frames = vec![BodyFrame::EMPTY; cfg.frame_samples];
        create_frames(&input, &cfg, &mut a, &mut frames).unwrap();
        create_frames(&input, &cfg, &mut b, &mut frames).unwrap();
        assert_eq!(a, b);
        assert!(
            a.windows(2)
                .all(|w| (w[0].px[1], w[0].px[0]) < (w[1].px[1], w[1].px[0]))
        );
        cfg.seed = 1;
        create_frames(&input, &cfg, &mut b, &mut frames).unwrap();
        assert_ne!(a, b);
    }

    #[test]
    fn rows_with_more_eligible_pixels_than_u16_counts_are_sampled_alike() {
        // Row 1 has 70 000 eligible pixels, rows 0 and 2 a third of that: only the count
        // of row 0 is kept.
        let (width, height) = (70_000, 3);
        let labels: std::vec::Vec<u16> = (0..width * height)
            .map(|i| u16::from((width..2 * width).contains(&i) || i % 3 == 0))
            .collect();
        let depth = vec![0.6f32; width * height];
        let flow = vec![[0.0f32; 2]; width * height];
        let input = MotionInput::new(
            ImageView::packed(width, height, &labels).unwrap(),
            ImageView::packed(width, height, &depth).unwrap(),
            ImageView::packed(width, height, &depth).unwrap(),
            ImageView::packed(width, height, &flow).unwrap(),
            Intrinsics::new(500.0, 500.0, 100.0, 1.0).unwrap(),
        )
        .unwrap();
        let mut cfg = Config::PAPER;
        for (seed, n) in (0..4).flat_map(|seed| [1, 2, 50].map(|n| (seed, n))) {
            cfg.seed = seed;
            let mut kept = vec![FrameSample::EMPTY; n];
            let mut none = vec![FrameSample::EMPTY; n];
            assert_eq!(sample_pixels(&input, &cfg, &mut kept), n);
            assert_eq!(sample_pixels_counting::<0>(&input, &cfg, &mut none), n);
            assert_eq!(kept, none, "seed {seed}, {n} samples");
        }
    }

    #[test]
    fn absurd_depths_are_no_reading_and_do_not_spoil_the_step() {
        let (mut r, _) = two_moving_boxes();
        // Every 7th pixel reads 1e38 m (a decoding error): before MAX_DEPTH_M, its share
        // of the space origin's mean overflowed and every frame of the step was dropped.
        r.depth_t.iter_mut().step_by(7).for_each(|z| *z = 1e38);
        let cfg = Config::PAPER;
        let mut samples = vec![FrameSample::EMPTY; cfg.frame_samples];
        let mut frames = vec![BodyFrame::EMPTY; cfg.frame_samples];
        let set = create_frames(&input(&r), &cfg, &mut samples, &mut frames).unwrap();
        assert!(
            set.space_origin.coords.iter().all(|c| c.is_finite()),
            "{set:?}"
        );
        assert!(
            set.space_origin.z > 0.5 && set.space_origin.z < 0.7,
            "{set:?}"
        );
        assert!(set.count > 500, "{set:?}");
        assert!(samples[..set.sampled].iter().all(|s| s.p_t.z < 1.0));
    }

    #[test]
    fn frames_without_a_reading_at_t1_are_dropped() {
        let (mut r, _) = two_moving_boxes();
        r.depth_t1.iter_mut().for_each(|z| *z = f32::NAN);
        let cfg = Config::PAPER;
        let mut samples = vec![FrameSample::EMPTY; cfg.frame_samples];
        let mut frames = vec![BodyFrame::EMPTY; cfg.frame_samples];
        let set = create_frames(&input(&r), &cfg, &mut samples, &mut frames).unwrap();
        assert_eq!(set.count, 0);
        assert_eq!(set.sampled, cfg.frame_samples);
    }

    #[test]
    fn frames_straddling_bodies_that_moved_apart_are_dropped() {
        // One label over two boxes that move differently: triangles across the seam stretch.
        let (mut r, motions) = two_moving_boxes();
        r.labels_t.iter_mut().for_each(|l| *l = u16::from(*l != 0));
        let cfg = Config::PAPER;
        let mut samples = vec![FrameSample::EMPTY; cfg.frame_samples];
        let mut frames = vec![BodyFrame::EMPTY; cfg.frame_samples];
        let set = create_frames(&input(&r), &cfg, &mut samples, &mut frames).unwrap();
        let to_space = Translation3::from(-set.space_origin.coords);
        let expected = motions.map(|m| Twist::log(&(to_space * m * to_space.inverse())));
        let off = frames[..set.count]
            .iter()
            .filter_map(|f| f.twist(&set.space_origin))
            .filter(|t| expected.iter().all(|e| t.distance(e, 0.05) > 2e-3))
            .count();
        assert!(
            off * 20 < set.count,
            "{off} of {} frames match neither body",
            set.count
        );
    }

    #[test]
    fn bad_inputs_are_errors_not_panics() {
        let (r, _) = two_moving_boxes();
        let input = input(&r);
        let cfg = Config::PAPER;
        let mut samples = vec![FrameSample::EMPTY; 10];
        let mut frames = vec![BodyFrame::EMPTY; cfg.frame_samples];
        assert!(matches!(
            create_frames(&input, &cfg, &mut samples, &mut frames),
            Err(Error::BufferTooSmall {
                buffer: Buffer::Samples,
                ..
            })
        ));
        let small = ImageView::packed(2, 2, &r.depth_t[..4]).unwrap();
        assert_eq!(
            MotionInput::new(
                input.labels_t,
                small,
                input.depth_t1,
                input.flow,
                r.intrinsics
            )
            .err(),
            Some(Error::SizeMismatch)
        );
    }

    /// The frame on origin `o` and the best two of `candidates` (samples of its segment near
    /// it), or `None` if no good triangle exists: the plain scan, branch by branch, that
    /// [`build_frame`]'s passes must agree with.
    fn plain_triangle<'s>(
        o: &'s FrameSample,
        candidates: impl Iterator<Item = &'s FrameSample> + Clone,
        cfg: &Config,
    ) -> Option<BodyFrame> {
        let max_side = cfg.frame_max_side_m;
        let min_side = cfg.frame_min_side_m;
        let mut best_j: Option<(&FrameSample, Real)> = None;
        for s in candidates.clone() {
            let d = (s.p_t - o.p_t).norm();
            if d >= min_side && d <= max_side && best_j.is_none_or(|(_, bd)| d > bd) {
                best_j = Some((s, d));
            }
        }
        let (j, dj) = best_j?;
        let a = j.p_t - o.p_t;
        let mut best_k: Option<(&FrameSample, Real)> = None;
        for s in candidates.filter(|s| s.px != j.px) {
            let b = s.p_t - o.p_t;
            let db = b.norm();
            let djk = (s.p_t - j.p_t).norm();
            if db < min_side || db > max_side || djk < min_side || djk > max_side {
                continue;
            }
            let area = a.cross(&b).norm();
            if area >= cfg.frame_min_sin * dj * db && best_k.is_none_or(|(_, ba)| area > ba) {
                best_k = Some((s, area));
            }
        }
        let (kk, _) = best_k?;
        rigid_frame(o, j, kk, cfg)
    }

    /// [`build_frame`] as it was before the listed fast path: every sample of the row
    /// window that passes the candidate test, straight into [`plain_triangle`].
    fn build_frame_plain(
        input: &MotionInput<'_>,
        cfg: &Config,
        samples: &[FrameSample],
        i: usize,
    ) -> Option<BodyFrame> {
        let o = samples.get(i)?;
        let k = &input.intrinsics;
        let max_side = cfg.frame_max_side_m;
        let near_z = (o.p_t.z - max_side).max(1e-3);
        let reach = max_side * k.fx.max(k.fy) / near_z + 1.0;
        let reach_px = if reach.is_finite() && reach < 1e6 {
            reach as i64
        } else {
            i64::MAX / 4
        };
        let (ox, oy) = (i64::from(o.px[0]), i64::from(o.px[1]));
        let first = samples.partition_point(|s| i64::from(s.px[1]) < oy - reach_px);
        let last = samples.partition_point(|s| i64::from(s.px[1]) <= oy + reach_px);
        let candidate = |s: &&FrameSample| {
            (i64::from(s.px[0]) - ox).abs() <= reach_px
                && s.tracked()
                && s.label() == o.label()
                && s.px != o.px
        };
        plain_triangle(o, samples[first..last].iter().filter(candidate), cfg)
    }

    proptest::proptest! {
        /// The bound [`third_point_of_kept`] prunes with holds for the rounded values:
        /// `|a × b| <= |a|·|b|·AREA_BOUND_SLACK` whenever the sides are [`prunable`],
        /// for any magnitudes and for near-parallel vectors.
        #[test]
        fn rounded_cross_norm_stays_under_the_pruning_bound(
            a in proptest::array::uniform3(-1.0f32..1.0),
            b in proptest::array::uniform3(-1.0f32..1.0),
            scale_a in -12i32..10,
            scale_b in -12i32..10,
            along in 0.0f32..1.0,
        ) {
            let a = Vector3::from(a) * 10f32.powi(scale_a);
            // Part of the time nearly parallel to `a` (cancellation in the cross product).
            let b = Vector3::from(b) * 10f32.powi(scale_b) * (1.0 - along)
                + a * along * 10f32.powi(scale_b - scale_a);
            let bound = a.norm() * b.norm();
            proptest::prop_assume!(prunable(a.norm(), b.norm()));
            proptest::prop_assert!(a.cross(&b).norm() <= bound * AREA_BOUND_SLACK);
        }
    }

    proptest::proptest! {
        /// [`column_key`]'s single compare is the column test and the key test, near the
        /// range's edges and anywhere below [`COLUMN_KEY_EXACT_BELOW`].
        #[test]
        fn column_key_compare_is_the_column_and_key_tests(
            x_lo in proptest::prop_oneof![0u32..100, (1u32 << 31) - 100..1 << 31],
            x_span in proptest::prop_oneof![0u32..100, (1u32 << 31) - 100..1 << 31],
            dx in -200i64..200,
            x_far in 0u32..1 << 31,
            far: bool,
            key in proptest::prop_oneof![0u32..3, (1u32 << 17) - 3..1 << 17],
            other in proptest::prop_oneof![0u32..3, (1u32 << 17) - 3..1 << 17],
        ) {
            let x = if far {
                x_far
            } else {
                (i64::from(x_lo) + dx).clamp(0, (1 << 31) - 1) as u32
            };
            let one = column_key(x, other).wrapping_sub(column_key(x_lo, key))
                <= u64::from(x_span);
            let two = x.wrapping_sub(x_lo) <= x_span && other == key;
            proptest::prop_assert_eq!(one, two);
        }
    }

    proptest::proptest! {
        /// [`packed_key`]'s single compare is the column test and the label test, and
        /// [`packed_bits`] (four keys a vector) passes the keys it passes, near the edges
        /// of the range below [`PACKED_COLUMNS`], for columns below `x_lo` and for labels
        /// that differ a little or a lot.
        #[test]
        fn packed_key_compare_is_the_column_and_label_tests(
            x_lo in proptest::prop_oneof![0u32..100, (1u32 << 15) - 100..1 << 15],
            x_span in proptest::prop_oneof![0u32..100, (1u32 << 15) - 100..1 << 15],
            dx in proptest::array::uniform4(-200i64..200),
            far in proptest::array::uniform4(proptest::option::weighted(0.2, 0u32..1 << 15)),
            labels in proptest::array::uniform4(
                proptest::prop_oneof![0u16..3, u16::MAX - 2..=u16::MAX]
            ),
            label in proptest::prop_oneof![1u16..3, u16::MAX - 2..=u16::MAX],
        ) {
            let columns: [u32; 4] = core::array::from_fn(|i| {
                far[i].unwrap_or_else(|| {
                    (i64::from(x_lo) + dx[i]).clamp(0, (1 << 15) - 1) as u32
                })
            });
            let keys: [u32; 4] = core::array::from_fn(|i| packed_key(columns[i], labels[i]));
            let base = packed_key(x_lo, label);
            let one = |k: &u32| k.wrapping_sub(base) <= x_span;
            for i in 0..4 {
                let two = columns[i].wrapping_sub(x_lo) <= x_span && labels[i] == label;
                proptest::prop_assert_eq!(one(&keys[i]), two, "key {}", i);
            }
            proptest::prop_assert_eq!(
                packed_bits(&keys, u32x4::splat(base), u32x4::splat(x_span)),
                four_bits(&keys, one)
            );
        }
    }

    proptest::proptest! {
        /// [`rows_window`] from the rows' first samples is the binary search's window,
        /// for rows in and past the image, and windows that reach past either edge.
        #[test]
        fn rows_window_is_the_binary_search(
            rows in proptest::collection::vec(0u32..30, 0..80),
            height in 30usize..40,
            y_lo in -50i64..50,
            span in proptest::prop_oneof![0i64..40, proptest::strategy::Just(i64::MAX / 4)],
        ) {
            let mut rows = rows;
            rows.sort_unstable();
            let samples: std::vec::Vec<FrameSample> = rows
                .iter()
                .enumerate()
                .map(|(x, &y)| FrameSample { px: [x as u32, y], ..FrameSample::EMPTY })
                .collect();
            let mut first = [0; 64];
            let indexed = index_rows(&samples, height, &mut first);
            proptest::prop_assert!(indexed.is_some());
            let ys = y_lo..=y_lo + span;
            proptest::prop_assert_eq!(
                rows_window(&samples, indexed, ys.clone()),
                rows_window(&samples, None, ys)
            );
        }
    }

    #[test]
    fn rows_are_indexed_only_when_they_fit() {
        let mut samples = [FrameSample::EMPTY; 3];
        (samples[0].px, samples[1].px, samples[2].px) = ([5, 1], [2, 3], [9, 3]);
        let mut first = [0; 6];
        assert_eq!(
            index_rows(&samples, 5, &mut first),
            Some(&[0, 0, 1, 1, 3, 3][..])
        );
        // No room for 7 entries; a sample below a 3-row image.
        assert_eq!(index_rows(&samples, 6, &mut first), None);
        assert_eq!(index_rows(&samples, 3, &mut first), None);
        // An empty index gives no window (and does not panic); rows past the index's
        // ends read its first or last entry.
        assert_eq!(rows_window(&samples, Some(&[]), 0..=2), None);
        let rows = [0, 0, 1, 1, 3, 3];
        assert_eq!(
            rows_window(&samples, Some(&rows), -9..=i64::MAX),
            Some((0, 3))
        );
    }

    #[test]
    fn keys_are_packed_only_when_they_fit() {
        let mut samples = [FrameSample::EMPTY; 3];
        samples[1].px = [(1 << 15) - 1, 4];
        samples[1].column_key = column_key((1 << 15) - 1, 7);
        let mut keys = [0; 3];
        assert_eq!(
            pack_keys(&samples, 1 << 15, &mut keys),
            Some(&[0, packed_key((1 << 15) - 1, 7), 0][..])
        );
        assert_eq!(pack_keys(&samples, (1 << 15) + 1, &mut keys), None);
        assert_eq!(pack_keys(&samples, 8, &mut keys[..2]), None);
    }

    proptest::proptest! {
        /// [`keyed_bits`] (two samples a vector) passes exactly the samples that
        /// [`column_key`]'s one compare passes, near the range's edges, for columns that
        /// wrap below `x_lo` and for keys that differ a little or a lot.
        #[test]
        fn keyed_bits_are_the_one_compare(
            x_lo in proptest::prop_oneof![0u32..200, (1u32 << 31) - 200..1 << 31],
            x_span in proptest::prop_oneof![0u32..200, (1u32 << 31) - 200..1 << 31],
            dx in proptest::array::uniform4(-300i64..300),
            far in proptest::array::uniform4(proptest::option::weighted(0.2, 0u32..u32::MAX)),
            keys in proptest::array::uniform4(
                proptest::prop_oneof![0u32..3, (1u32 << 17) - 3..1 << 17]
            ),
            key in proptest::prop_oneof![0u32..3, (1u32 << 17) - 3..1 << 17],
        ) {
            let samples: [FrameSample; 4] = core::array::from_fn(|i| {
                let x = far[i]
                    .unwrap_or_else(|| (i64::from(x_lo) + dx[i]).clamp(0, (1 << 32) - 1) as u32);
                FrameSample {
                    column_key: column_key(x, keys[i]),
                    ..FrameSample::EMPTY
                }
            });
            let base = column_key(x_lo, key);
            let one = |s: &FrameSample| s.column_key.wrapping_sub(base) <= u64::from(x_span);
            let low = u32x4::new([x_lo, key, x_lo, key]);
            let limit = u32x4::new([x_span, 0, x_span, 0]);
            proptest::prop_assert_eq!(keyed_bits(&samples, low, limit), four_bits(&samples, one));
        }
    }

    proptest::proptest! {
        /// The listed fast path of [`build_frame`], its fallback past the listing's
        /// capacity (reached with a capacity of 8) and that fallback
        /// ([`best_triangle`]) on every window pick the frame the plain scan picks, bit
        /// for bit. Points sit on a coarse lattice so that equal distances and areas (ties)
        /// are common.
        #[test]
        fn build_frame_picks_what_the_plain_scan_picks(
            cells in proptest::collection::vec(
                (0u32..40, 0u32..40, 1u16..3, proptest::bool::weighted(0.9), 0u8..4),
                3..700,
            ),
            step_m in proptest::sample::select(vec![0.002f32, 0.004, 0.01]),
            focal_px in proptest::sample::select(vec![100.0f32, 2000.0]),
        ) {
            let mut cells = cells;
            cells.sort_by_key(|c| (c.1, c.0));
            cells.dedup_by_key(|c| (c.1, c.0));
            let samples: std::vec::Vec<FrameSample> = cells
                .iter()
                .map(|&(x, y, label, tracked, dz)| {
                    let p_t = Point3::new(
                        x as Real * step_m,
                        y as Real * step_m,
                        0.5 + Real::from(dz) * step_m,
                    );
                    FrameSample {
                        px: [x * 3, y * 3],
                        column_key: column_key(
                            x * 3,
                            u32::from(label) | if tracked { 0 } else { UNTRACKED },
                        ),
                        px_t1: [0.0; 2],
                        p_t,
                        p_t1: p_t + Vector3::new(0.001, 0.0, 0.0),
                    }
                })
                .collect();
            let depth = [0.5f32];
            let (labels, flow) = ([1u16], [[0.0f32; 2]]);
            let input = MotionInput::new(
                ImageView::packed(1, 1, &labels).unwrap(),
                ImageView::packed(1, 1, &depth).unwrap(),
                ImageView::packed(1, 1, &depth).unwrap(),
                ImageView::packed(1, 1, &flow).unwrap(),
                Intrinsics::new(focal_px, focal_px, 0.5, 0.5).unwrap(),
            )
            .unwrap();
            let cfg = Config::PAPER;
            // One scratch for every origin and both capacities, as in `create_frames`.
            let mut scratch = TriangleScratch::new();
            // The scan over packed keys, and over the samples (as past `PACKED_ON_STACK`);
            // the window from the rows' first samples, and by binary search.
            let mut keys = [0; PACKED_ON_STACK];
            let packed = pack_keys(&samples, 120, &mut keys);
            proptest::prop_assert!(packed.is_some());
            let mut first = [0; INDEXED_ROWS + 1];
            let rows = index_rows(&samples, 120, &mut first);
            proptest::prop_assert!(rows.is_some());
            let indices = [
                SampleIndex { packed, rows },
                SampleIndex { packed, rows: None },
                SampleIndex { packed: None, rows },
            ];
            for i in 0..samples.len() {
                let plain = build_frame_plain(&input, &cfg, &samples, i);
                for index in indices {
                    let how = (index.packed.is_some(), index.rows.is_some());
                    proptest::prop_assert_eq!(
                        build_frame(&input, &cfg, &samples, index, i, &mut scratch),
                        plain,
                        "origin {} (packed, rows: {:?})", i, how
                    );
                    proptest::prop_assert_eq!(
                        build_frame_listing::<8, false>(
                            &input, &cfg, &samples, index, i, &mut scratch
                        ),
                        plain,
                        "origin {} (capacity 8; packed, rows: {:?})", i, how
                    );
                    proptest::prop_assert_eq!(
                        build_frame_listing::<LISTED_ON_STACK, true>(
                            &input, &cfg, &samples, index, i, &mut scratch
                        ),
                        plain,
                        "origin {} (pruned; packed, rows: {:?})", i, how
                    );
                }
                let o = &samples[i];
                let same = |s: &&FrameSample| {
                    s.tracked() && s.label() == o.label() && s.px != o.px
                };
                proptest::prop_assert_eq!(
                    best_triangle(o, samples.iter().filter(same), &cfg),
                    plain_triangle(o, samples.iter().filter(same), &cfg),
                    "origin {} (whole set)", i
                );
            }
        }
    }

    /// `x` rounded down, as the plain references index pixels (saturating; NaN gives 0).
    fn floor(x: Real) -> i64 {
        libm::floorf(x) as i64
    }

    /// [`bilinear_depth`] as it was before it read rows: `floor`, `at`, `min` and `max`.
    fn bilinear_depth_plain(
        depth: &ImageView<'_, f32>,
        u: Real,
        v: Real,
        edge_m: Real,
    ) -> Option<Real> {
        if !(u.is_finite() && v.is_finite()) || u < 0.0 || v < 0.0 {
            return None;
        }
        let (x0, y0) = (floor(u), floor(v));
        let (fx, fy) = (u - x0 as Real, v - y0 as Real);
        let x1 = if fx > 0.0 { x0.saturating_add(1) } else { x0 };
        let y1 = if fy > 0.0 { y0.saturating_add(1) } else { y0 };
        let z00 = valid_depth(depth.at(x0, y0)?)?;
        let z10 = valid_depth(depth.at(x1, y0)?)?;
        let z01 = valid_depth(depth.at(x0, y1)?)?;
        let z11 = valid_depth(depth.at(x1, y1)?)?;
        let lo = z00.min(z10).min(z01).min(z11);
        let hi = z00.max(z10).max(z01).max(z11);
        if hi - lo > edge_m {
            return None;
        }
        let top = z00 + (z10 - z00) * fx;
        let bottom = z01 + (z11 - z01) * fx;
        Some(top + (bottom - top) * fy)
    }

    proptest::proptest! {
        // Cheap cases, and a neighbour alone past the edge limit is a rare draw.
        #![proptest_config(proptest::test_runner::Config::with_cases(4096))]
        /// [`bilinear_depth`] gives the plain one's depth bit for bit at any position
        /// (any bits, or near and past the image's edges) and edge limit, with holes and
        /// absurd readings among the neighbours.
        #[test]
        fn bilinear_depth_is_the_plain_one(
            width in 1usize..6,
            cells in proptest::collection::vec((0u8..12, -3i8..=3), 1..36),
            at in proptest::array::uniform2(proptest::prop_oneof![
                3 => -0.2f32..1.2,
                1 => proptest::num::f32::ANY,
                1 => proptest::sample::select(vec![0.0f32, -0.0, 0.2, 0.5, 1.0]),
            ]),
            edge_steps in proptest::prop_oneof![0u8..4, proptest::strategy::Just(255)],
        ) {
            let height = cells.len() / width;
            proptest::prop_assume!(height > 0);
            // Readings a few millimetre steps apart, so that the edge limit decides often.
            let depth: std::vec::Vec<f32> = cells[..width * height]
                .iter()
                .map(|&(kind, step)| match kind {
                    0 => 0.0,
                    1 => f32::NAN,
                    2 => 1e3,
                    _ => 0.6 + f32::from(step) * 0.001,
                })
                .collect();
            let depth = ImageView::packed(width, height, &depth).unwrap();
            // Positions mostly in or just past the image, in pixels.
            let scale = |t: f32, size: usize| {
                if (-0.2..=1.2).contains(&t) { t * size as f32 } else { t }
            };
            let (u, v) = (scale(at[0], width), scale(at[1], height));
            let edge_m = if edge_steps == 255 {
                f32::INFINITY
            } else {
                f32::from(edge_steps) * 0.001
            };
            proptest::prop_assert_eq!(
                bilinear_depth(&depth, u, v, edge_m).map(f32::to_bits),
                bilinear_depth_plain(&depth, u, v, edge_m).map(f32::to_bits)
            );
        }
    }

    /// [`local_depth`] as it was before the sums became lanes: one sum per variable, every
    /// depth tested with [`valid_depth`].
    fn local_depth_plain(
        depth: &ImageView<'_, f32>,
        u: Real,
        v: Real,
        cfg: &Config,
    ) -> Option<Real> {
        let z_ref = bilinear_depth_plain(depth, u, v, cfg.depth_edge_m)?;
        let r = cfg.depth_window_px as i64;
        let (xc, yc) = (floor(u + 0.5), floor(v + 0.5));
        let (mut n, mut sx, mut sy, mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut sz, mut sxz, mut syz) = (0.0, 0.0, 0.0);
        for y in yc - r..=yc + r {
            for x in xc - r..=xc + r {
                let Some(z) = depth.at(x, y).and_then(valid_depth) else {
                    continue;
                };
                let dz = z - z_ref;
                if dz.abs() > cfg.depth_window_tol_m {
                    continue;
                }
                let (dx, dy) = (x as Real - u, y as Real - v);
                n += 1.0;
                sx += dx;
                sy += dy;
                sxx += dx * dx;
                syy += dy * dy;
                sxy += dx * dy;
                sz += dz;
                sxz += dx * dz;
                syz += dy * dz;
            }
        }
        let det =
            n * (sxx * syy - sxy * sxy) - sx * (sx * syy - sxy * sy) + sy * (sx * sxy - sxx * sy);
        if !(n >= 6.0 && det.abs() > 1e-3 * n * n * n) {
            return Some(z_ref);
        }
        let det_a = sz * (sxx * syy - sxy * sxy) - sx * (sxz * syy - sxy * syz)
            + sy * (sxz * sxy - sxx * syz);
        Some(z_ref + det_a / det).filter(|z| z.is_finite() && *z > 0.0)
    }

    proptest::proptest! {
        /// [`local_depth`] gives the plain plane fit's depth bit for bit, for any window
        /// radius and tolerance, near the limits of a depth reading (where the tolerance
        /// does not imply one) and with holes and absurd readings in the window.
        #[test]
        fn local_depth_is_the_plain_plane_fit(
            width in 1usize..12,
            cells in proptest::collection::vec((0u8..8, -1.0f32..1.0), 1..144),
            base_m in proptest::sample::select(vec![0.002f32, 0.6, 99.999]),
            at in proptest::array::uniform2(-0.1f32..1.1),
            radius_px in 1u32..=8,
            tol_m in proptest::sample::select(vec![0.003f32, 0.05, 1.0]),
        ) {
            let height = cells.len() / width;
            proptest::prop_assume!(height > 0);
            let (u, v) = (at[0] * width as f32, at[1] * height as f32);
            let depth: std::vec::Vec<f32> = cells[..width * height]
                .iter()
                .map(|&(kind, noise)| match kind {
                    0 => 0.0,
                    1 => f32::NAN,
                    2 => 1e3,
                    _ => base_m + noise * 0.004,
                })
                .collect();
            let depth = ImageView::packed(width, height, &depth).unwrap();
            let mut cfg = Config::PAPER;
            cfg.depth_window_px = radius_px;
            cfg.depth_window_tol_m = tol_m;
            cfg.depth_edge_m = 1.0;
            proptest::prop_assert_eq!(
                local_depth(&depth, u, v, &cfg).map(f32::to_bits),
                local_depth_plain(&depth, u, v, &cfg).map(f32::to_bits)
            );
        }
    }

    proptest::proptest! {
        /// The row- and chunk-skipping sampler draws exactly the pixels a plain scan over
        /// the list of eligible pixels draws, for any mask, depth holes and seed, with the
        /// counts of every row kept or of only the first few.
        #[test]
        fn sampling_draws_the_ranks_a_plain_scan_draws(
            width in 1usize..150,
            cells in proptest::collection::vec((0u16..3, 0u8..4), 1..3000),
            n in 1usize..60,
            seed: u64,
        ) {
            let height = cells.len() / width;
            proptest::prop_assume!(height > 0);
            let cells = &cells[..width * height];
            let labels: std::vec::Vec<u16> = cells.iter().map(|c| c.0).collect();
            // Depth: a reading, none, NaN or beyond the maximum.
            let depth: std::vec::Vec<f32> = cells
                .iter()
                .map(|c| [0.6, 0.0, f32::NAN, 1e3][usize::from(c.1)])
                .collect();
            let flow = vec![[0.0f32; 2]; cells.len()];
            let input = MotionInput::new(
                ImageView::packed(width, height, &labels).unwrap(),
                ImageView::packed(width, height, &depth).unwrap(),
                ImageView::packed(width, height, &depth).unwrap(),
                ImageView::packed(width, height, &flow).unwrap(),
                Intrinsics::new(500.0, 500.0, 0.5 * width as f32, 0.5 * height as f32).unwrap(),
            )
            .unwrap();
            let mut cfg = Config::PAPER;
            cfg.seed = seed;
            let mut out = vec![FrameSample::EMPTY; n];
            let got = sample_pixels(&input, &cfg, &mut out);
            // With the counts of 3 rows kept, the rows past them are counted again.
            let mut out_3 = vec![FrameSample::EMPTY; n];
            proptest::prop_assert_eq!(sample_pixels_counting::<3>(&input, &cfg, &mut out_3), got);
            proptest::prop_assert_eq!(&out_3, &out);

            let eligible: std::vec::Vec<[u32; 2]> = (0..cells.len())
                .filter(|&i| labels[i] != 0 && valid_depth(depth[i]).is_some())
                .map(|i| [(i % width) as u32, (i / width) as u32])
                .collect();
            let total = eligible.len() as u64;
            let want = (n as u64).min(total);
            let mut rng = Pcg32::new(seed);
            let expected: std::vec::Vec<[u32; 2]> = (0..want)
                .map(|i| {
                    let (lo, hi) = (i * total / want, (i + 1) * total / want);
                    eligible[(lo + u64::from(rng.below((hi - lo) as u32))) as usize]
                })
                .collect();
            proptest::prop_assert_eq!(got as u64, want);
            let drawn: std::vec::Vec<[u32; 2]> = out[..got].iter().map(|s| s.px).collect();
            proptest::prop_assert_eq!(drawn, expected);
        }
    }
}
