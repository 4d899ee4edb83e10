//! Per-pixel geometry from depth: back-projected points, an edge-aware smoothing of them,
//! surface normals and concave creases.
//!
//! Contract: all buffers are row-major `width·height` (the caller sizes them). A point
//! `[0, 0, 0]` (z = 0) means "no reading"; a normal `[0, 0, 0]` means "no normal". Normals
//! are unit vectors facing the camera (`n · p < 0`).
//!
//! Only neighbours on the centre pixel's surface enter the smoothing, the normals and the
//! crease test, so nothing is averaged across an occlusion edge or a step between two
//! objects: for the smoothing, depths within [`SegmenterParams::depth_jump_at_m`] of the
//! centre's; for the normals and creases (`r` pixels apart), within `r` times that.

use super::{RgbdFrame, SegmenterParams};
use riseg_core::Intrinsics;

/// Crease flag: a concave bend sharper than `crease_soft_deg` (heatmap source).
pub(super) const CREASE_SOFT: u8 = 1;
/// Crease flag: the bend blocks region growing.
pub(super) const CREASE_BLOCK: u8 = 2;

pub(super) type P3 = [f32; 3];

pub(super) fn sub(a: P3, b: P3) -> P3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(super) fn dot(a: P3, b: P3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(super) fn cross(a: P3, b: P3) -> P3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Back-projects every pixel with a depth reading; `[0, 0, 0]` elsewhere.
pub(super) fn back_project(frame: &RgbdFrame<'_>, k: &Intrinsics, out: &mut [P3]) {
    let w = frame.width();
    let (ifx, ify) = (1.0 / k.fx, 1.0 / k.fy);
    for (y, (row_out, row_z)) in out
        .chunks_exact_mut(w)
        .zip(frame.depth_m().chunks_exact(w))
        .enumerate()
    {
        let yc = (y as f32 - k.cy) * ify;
        for (x, (o, &z)) in row_out.iter_mut().zip(row_z).enumerate() {
            *o = if z.is_finite() && z > 0.0 {
                [(x as f32 - k.cx) * ifx * z, yc * z, z]
            } else {
                [0.0; 3]
            };
        }
    }
}

/// Scratch of [`smooth_points`], reused across frames.
#[derive(Debug, Default)]
pub(super) struct SmoothScratch {
    /// The row pass's result.
    tmp: Vec<P3>,
    /// Column sums of one output row (x, y, z, count).
    acc: Vec<[f32; 4]>,
    /// Depth tolerance of each centre pixel of one row.
    jump: Vec<f32>,
}

/// Edge-aware smoothing of the points: the mean of the points within
/// `smooth_radius_px` along the row whose depth is within
/// [`SegmenterParams::depth_jump_at_m`] of the centre's, then the same along the column of
/// that result (a separable bilateral filter with a box kernel: steps larger than the
/// tolerance stay sharp).
pub(super) fn smooth_points(
    w: usize,
    h: usize,
    raw: &[P3],
    params: &SegmenterParams,
    scratch: &mut SmoothScratch,
    out: &mut [P3],
) {
    let SmoothScratch { tmp, acc, jump } = scratch;
    tmp.clear();
    tmp.resize(w * h, [0.0; 3]);
    let r = params.smooth_radius_px;
    let add = |s: &mut [f32; 4], q: P3| *s = [s[0] + q[0], s[1] + q[1], s[2] + q[2], s[3] + 1.0];
    let mean = |s: [f32; 4]| [s[0] / s[3], s[1] / s[3], s[2] / s[3]];
    // Along rows.
    for (row_in, row_out) in raw.chunks_exact(w).zip(tmp.chunks_exact_mut(w)) {
        for (x, o) in row_out.iter_mut().enumerate() {
            let c = row_in[x];
            if c[2] <= 0.0 {
                *o = [0.0; 3];
                continue;
            }
            let jump = params.depth_jump_at_m(c[2]);
            let mut sum = [0.0f32; 4];
            for &q in &row_in[x.saturating_sub(r)..=(x + r).min(w - 1)] {
                if q[2] > 0.0 && (q[2] - c[2]).abs() <= jump {
                    add(&mut sum, q);
                }
            }
            // sum[3] >= 1: the centre itself always qualifies.
            *o = mean(sum);
        }
    }
    // Along columns, a row at a time (contiguous memory): `acc[x]` sums column x, and
    // `jump[x]` is the tolerance of the centre (infinitely negative where it has no reading).
    acc.clear();
    acc.resize(w, [0.0; 4]);
    jump.clear();
    jump.resize(w, 0.0);
    for y in 0..h {
        acc.fill([0.0; 4]);
        let centre = &tmp[y * w..(y + 1) * w];
        for (j, c) in jump.iter_mut().zip(centre) {
            *j = if c[2] > 0.0 {
                params.depth_jump_at_m(c[2])
            } else {
                f32::NEG_INFINITY
            };
        }
        for yy in y.saturating_sub(r)..=(y + r).min(h - 1) {
            let row = &tmp[yy * w..(yy + 1) * w];
            for (((s, &c), &q), &j) in acc.iter_mut().zip(centre).zip(row).zip(jump.iter()) {
                if q[2] > 0.0 && (q[2] - c[2]).abs() <= j {
                    add(s, q);
                }
            }
        }
        for ((o, &s), &c) in out[y * w..(y + 1) * w]
            .iter_mut()
            .zip(acc.iter())
            .zip(centre)
        {
            *o = if c[2] > 0.0 { mean(s) } else { [0.0; 3] };
        }
    }
}

/// Clears the flags of 8-connected flagged regions (creases, steps) whose area (sum of
/// `px_area_m2`) is below `min_area_m2`: specks of depth noise, not the long lines where
/// objects meet. `queue` and `seen` are scratch.
pub(super) fn drop_small_regions(
    w: usize,
    h: usize,
    px_area_m2: &[f32],
    min_area_m2: f32,
    crease: &mut [u8],
    queue: &mut Vec<u32>,
    seen: &mut Vec<bool>,
) {
    seen.clear();
    seen.resize(w * h, false);
    for start in 0..w * h {
        if crease[start] == 0 || seen[start] {
            continue;
        }
        queue.clear();
        queue.push(start as u32);
        seen[start] = true;
        let mut area = 0.0;
        let mut head = 0;
        while let Some(&i) = queue.get(head) {
            head += 1;
            let i = i as usize;
            area += px_area_m2[i];
            let (x, y) = (i % w, i / w);
            for yy in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                for xx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                    let j = yy * w + xx;
                    if crease[j] != 0 && !seen[j] {
                        seen[j] = true;
                        queue.push(j as u32);
                    }
                }
            }
        }
        if area < min_area_m2 {
            for &i in queue.iter() {
                crease[i as usize] = 0;
            }
        }
    }
}

/// `true` if `q` is a reading on the same surface as `c`, `sep` pixels away.
fn same_surface(c: P3, q: P3, sep: usize, params: &SegmenterParams) -> bool {
    q[2] > 0.0 && (q[2] - c[2]).abs() <= params.depth_jump_at_m(c[2]) * sep as f32
}

/// The difference across pixel `i` along a line with neighbours `lo` and `hi` (if they are
/// in the image): central where both are on the surface, one-sided where one is.
fn difference(pts: &[P3], i: usize, lo: Option<usize>, hi: Option<usize>) -> P3 {
    let c = pts[i];
    let on = |j: Option<usize>| j.map(|j| pts[j]).filter(|&q| q[2] > 0.0);
    match (on(lo), on(hi)) {
        (Some(a), Some(b)) => sub(b, a),
        (None, Some(b)) => sub(b, c),
        (Some(a), None) => sub(c, a),
        (None, None) => [0.0; 3],
    }
}

/// Unit normals facing the camera from cross products of point differences
/// `±normal_radius_px` apart; `[0, 0, 0]` where either direction has no surface neighbour.
pub(super) fn normals(w: usize, h: usize, pts: &[P3], params: &SegmenterParams, out: &mut [P3]) {
    let r = params.normal_radius_px;
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let c = pts[i];
            out[i] = [0.0; 3];
            if c[2] <= 0.0 {
                continue;
            }
            let pick = |j: usize| Some(j).filter(|&j| same_surface(c, pts[j], r, params));
            let left = x.checked_sub(r).and_then(|xx| pick(y * w + xx));
            let right = Some(x + r)
                .filter(|&xx| xx < w)
                .and_then(|xx| pick(y * w + xx));
            let up = y.checked_sub(r).and_then(|yy| pick(yy * w + x));
            let down = Some(y + r)
                .filter(|&yy| yy < h)
                .and_then(|yy| pick(yy * w + x));
            let du = difference(pts, i, left, right);
            let dv = difference(pts, i, up, down);
            let mut n = cross(dv, du);
            let len = dot(n, n).sqrt();
            if len.is_nan() || len <= 1e-12 {
                continue;
            }
            if dot(n, c) > 0.0 {
                n = [-n[0], -n[1], -n[2]];
            }
            out[i] = [n[0] / len, n[1] / len, n[2] / len];
        }
    }
}

/// Inputs of [`creases`]: `width·height` buffers.
#[derive(Debug, Clone, Copy)]
pub(super) struct CreaseInput<'a> {
    pub(super) w: usize,
    pub(super) h: usize,
    pub(super) rgb: &'a [[u8; 3]],
    pub(super) pts: &'a [P3],
    pub(super) nrm: &'a [P3],
    pub(super) object: &'a [bool],
}

/// Concave-crease flags ([`CREASE_SOFT`], [`CREASE_BLOCK`]) per object pixel.
///
/// At object pixel `p`, for the pixel pairs `a = p − d`, `b = p + d` with `d = (r, 0)` and
/// `(0, r)` (`r = crease_radius_px`), both on `p`'s surface and with normals, and with the
/// whole support of the measurement on objects (the object pixels `p ± d·R/r`,
/// `R = r + normal_radius_px + smooth_radius_px`, so the corner where an object stands on
/// the table, whose smoothed normals see the table, is no crease): the bend is
/// `θ = acos(n_a · n_b)`; it is concave when `(n_a − n_b) · (p_a − p_b) < 0` (the surfaces
/// face each other, as where two objects meet, rather than away from each other, as at a
/// box's own edge). A concave bend with `θ > crease_soft_deg` is soft; it also blocks when
/// `θ > crease_block_deg`, or when the colours of `a` and `b` differ by more than
/// `crease_colour_diff`.
pub(super) fn creases(inp: &CreaseInput<'_>, params: &SegmenterParams, out: &mut [u8]) {
    let CreaseInput {
        w,
        h,
        rgb,
        pts,
        nrm,
        object,
    } = *inp;
    let r = params.crease_radius_px;
    let reach = r + params.normal_radius_px + params.smooth_radius_px;
    let cos_soft = libm::cosf(params.crease_soft_deg.to_radians());
    let cos_block = libm::cosf(params.crease_block_deg.to_radians());
    out.fill(0);
    if w <= 2 * reach && h <= 2 * reach {
        return;
    }
    let judge = |c: P3, a: usize, b: usize| -> u8 {
        let (pa, pb, na, nb) = (pts[a], pts[b], nrm[a], nrm[b]);
        if na == [0.0; 3] || nb == [0.0; 3] {
            return 0;
        }
        if !same_surface(c, pa, r, params) || !same_surface(c, pb, r, params) {
            return 0;
        }
        let cos = dot(na, nb);
        if cos >= cos_soft || dot(sub(na, nb), sub(pa, pb)) >= 0.0 {
            return 0;
        }
        let colour: u16 = rgb[a]
            .iter()
            .zip(&rgb[b])
            .map(|(&u, &v)| u16::from(u.abs_diff(v)))
            .sum();
        if cos < cos_block || colour > params.crease_colour_diff {
            CREASE_SOFT | CREASE_BLOCK
        } else {
            CREASE_SOFT
        }
    };
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if !object[i] {
                continue;
            }
            let c = pts[i];
            let mut f = 0;
            if x >= reach && x + reach < w && object[i - reach] && object[i + reach] {
                f |= judge(c, i - r, i + r);
            }
            let (up, down) = (i.wrapping_sub(reach * w), i + reach * w);
            if y >= reach && y + reach < h && object[up] && object[down] {
                f |= judge(c, i - r * w, i + r * w);
            }
            out[i] = f;
        }
    }
}
