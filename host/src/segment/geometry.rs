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

use super::{CHUNK_PX, RgbdFrame, SegmenterParams};
use crate::par::*;
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

/// Back-projects row `y` of `frame` into the planes `x`, `y`, `z` (`w` pixels): a pixel
/// with a depth reading (finite, positive) gives its point, others `[0, 0, NO_READING]`.
/// Branch-free, since pixels without depth come and go along a row.
fn back_project_row(
    frame: &RgbdFrame<'_>,
    k: &Intrinsics,
    y: usize,
    [ox, oy, oz]: [&mut [f32]; 3],
) {
    let w = frame.width();
    let z_row = &frame.depth_m()[y * w..(y + 1) * w];
    let (ox, oy, oz) = (&mut ox[..w], &mut oy[..w], &mut oz[..w]);
    let (ifx, ify) = (1.0 / k.fx, 1.0 / k.fy);
    let yc = (y as f32 - k.cy) * ify;
    for (x, &z) in z_row.iter().enumerate() {
        let m = mask((z > 0.0) & (z < f32::INFINITY));
        ox[x] = keep((x as f32 - k.cx) * ifx * z, m);
        oy[x] = keep(yc * z, m);
        oz[x] = pick(z, NO_READING, m);
    }
}

/// The depth of a pixel without a reading in the smoothing's own buffers (the rows it
/// reads and the result of its row pass): no comparison with it holds, so a tap without
/// a reading fails the depth test by itself.
const NO_READING: f32 = f32::NAN;

/// The smoothed points of every row as three planes (x, y, z), each `pad` zero pixels
/// wider on both sides than the image: what [`normals`] reads, with no bounds tests at the
/// image's left and right edges (a padding pixel has no reading).
#[derive(Debug, Default)]
pub(super) struct RowPlanes {
    pad: usize,
    /// Padded row width, `w + 2·pad`.
    wp: usize,
    /// Row `y` at `3·wp·y`: x plane, y plane, z plane.
    data: Vec<f32>,
}

impl RowPlanes {
    /// Sizes the planes for `h` rows of `w` pixels padded by `pad`, zeroing them only
    /// when the size changes: the padding is never written, the rest always.
    fn resize(&mut self, w: usize, h: usize, pad: usize) {
        if (self.pad, self.wp, self.data.len()) != (pad, w + 2 * pad, 3 * (w + 2 * pad) * h) {
            self.pad = pad;
            self.wp = w + 2 * pad;
            self.data.clear();
            self.data.resize(3 * self.wp * h, 0.0);
        }
    }

    /// The x, y and z planes of row `y`, without the padding.
    pub(super) fn row_xyz(&self, y: usize) -> [&[f32]; 3] {
        let (row, w) = (self.row(y), self.wp - 2 * self.pad);
        core::array::from_fn(|k| &row[k * self.wp + self.pad..k * self.wp + self.pad + w])
    }

    /// Planes of row `y`, padded.
    fn row(&self, y: usize) -> &[f32] {
        &self.data[3 * self.wp * y..3 * self.wp * (y + 1)]
    }
}

/// Scratch of [`smooth_points`], reused across frames.
#[derive(Debug, Default)]
pub(super) struct SmoothScratch {
    /// The row pass's result: per row, the x, y and z planes (`3·w` values).
    tmp: Vec<f32>,
    /// The smoothed points as padded row planes, for [`normals`].
    pub(super) planes: RowPlanes,
}

/// Per-row scratch of the smoothing: a padded input row, window sums and tolerances.
#[derive(Debug, Default)]
struct RowScratch {
    /// Padded row planes x, y, z of the row pass's input (`w + 2r` each; z is
    /// [`NO_READING`] where there is none).
    row: [Vec<f32>; 3],
    /// Window sums x, y, z and count, and each centre's depth tolerance.
    sums: WindowSums,
}

impl RowScratch {
    fn with_width(w: usize, r: usize) -> Self {
        Self {
            // The padding has no reading.
            row: [
                vec![0.0; w + 2 * r],
                vec![0.0; w + 2 * r],
                vec![NO_READING; w + 2 * r],
            ],
            sums: WindowSums {
                acc: core::array::from_fn(|_| vec![0.0; w]),
                jump: vec![0.0; w],
            },
        }
    }
}

/// Sums of the points of a window on the centre's surface, for one row of centres.
#[derive(Debug, Default)]
struct WindowSums {
    /// Sums x, y, z and count.
    acc: [Vec<f32>; 4],
    /// Depth tolerance of each centre pixel, infinitely negative where it has no reading.
    jump: Vec<f32>,
}

impl WindowSums {
    /// Clears the sums and sets the tolerances from the centre depths `cz`.
    fn start(&mut self, cz: &[f32], params: &SegmenterParams) {
        for (j, &z) in self.jump.iter_mut().zip(cz) {
            *j = if z > 0.0 {
                params.depth_jump_at_m(z)
            } else {
                f32::NEG_INFINITY
            };
        }
        for a in &mut self.acc {
            a.fill(0.0);
        }
    }

    /// Adds the points of the taps `0..count` (`tap(t)`: the x, y and z planes of tap
    /// `t`, aligned with the centres) whose depth is within the tolerance of the centre
    /// depth `cz` to the sums, in tap order, four taps a pass over the row.
    fn add_taps<'a>(&mut self, count: usize, tap: impl Fn(usize) -> [&'a [f32]; 3], cz: &[f32]) {
        let mut t = 0;
        while t + 4 <= count {
            self.add([tap(t), tap(t + 1), tap(t + 2), tap(t + 3)], cz);
            t += 4;
        }
        match count - t {
            3 => self.add([tap(t), tap(t + 1), tap(t + 2)], cz),
            2 => self.add([tap(t), tap(t + 1)], cz),
            1 => self.add([tap(t)], cz),
            _ => {}
        }
    }

    /// Adds the points of the `N` taps (x, y and z planes aligned with the centres) whose
    /// depth is within the tolerance of the centre depth `cz` to the sums, in tap order. A
    /// skipped point adds `+0.0`, which leaves a sum's bits as they are (a sum that starts
    /// at `+0.0` is never `-0.0`), so this branch-free form (which the compiler vectorises,
    /// with the sums in registers across the taps) sums exactly what a test per point would.
    fn add<const N: usize>(&mut self, taps: [[&[f32]; 3]; N], cz: &[f32]) {
        let w = self.jump.len();
        let [sx, sy, sz, sn] = &mut self.acc;
        let (sx, sy, sz, sn) = (&mut sx[..w], &mut sy[..w], &mut sz[..w], &mut sn[..w]);
        let taps = taps.map(|t| t.map(|plane| &plane[..w]));
        let (cz, jump) = (&cz[..w], &self.jump[..w]);
        for x in 0..w {
            [sx[x], sy[x], sz[x], sn[x]] =
                sum_taps(&taps, x, cz[x], jump[x], [sx[x], sy[x], sz[x], sn[x]]);
        }
    }

    /// [`Self::start`], [`Self::add_taps`] over all `N` taps, then [`Self::means`] in one
    /// pass over the row: the sums start at `+0.0` and take the taps in order in registers,
    /// so the means are bit for bit those of the three calls, without the sums' round trips
    /// through memory. For the window's full width (`N = 2r + 1` taps).
    fn window_means<const N: usize>(
        &mut self,
        taps: [[&[f32]; 3]; N],
        cz: &[f32],
        params: &SegmenterParams,
        [ox, oy, oz]: [&mut [f32]; 3],
        none_z_m: f32,
    ) {
        let w = self.jump.len();
        for (j, &z) in self.jump.iter_mut().zip(cz) {
            *j = if z > 0.0 {
                params.depth_jump_at_m(z)
            } else {
                f32::NEG_INFINITY
            };
        }
        let taps = taps.map(|t| t.map(|plane| &plane[..w]));
        let (cz, jump) = (&cz[..w], &self.jump[..w]);
        let (ox, oy, oz) = (&mut ox[..w], &mut oy[..w], &mut oz[..w]);
        for x in 0..w {
            let [ax, ay, az, an] = sum_taps(&taps, x, cz[x], jump[x], [0.0; 4]);
            let m = mask(cz[x] > 0.0);
            ox[x] = keep(ax / an, m);
            oy[x] = keep(ay / an, m);
            oz[x] = pick(az / an, none_z_m, m);
        }
    }

    /// The means where the centre has a reading, elsewhere zero (z: `none_z_m`), into
    /// `(ox, oy, oz)`.
    fn means(&self, cz: &[f32], [ox, oy, oz]: [&mut [f32]; 3], none_z_m: f32) {
        let w = self.jump.len();
        let [sx, sy, sz, sn] = &self.acc;
        let (sx, sy, sz, sn, cz) = (&sx[..w], &sy[..w], &sz[..w], &sn[..w], &cz[..w]);
        let (ox, oy, oz) = (&mut ox[..w], &mut oy[..w], &mut oz[..w]);
        for x in 0..w {
            let m = mask(cz[x] > 0.0);
            ox[x] = keep(sx[x] / sn[x], m);
            oy[x] = keep(sy[x] / sn[x], m);
            oz[x] = pick(sz[x] / sn[x], none_z_m, m);
        }
    }
}

/// The smoothing radius the fused window pass ([`WindowSums::window_means`]) is compiled
/// for: the default's. Other radii take the general path, with the same result.
const DEFAULT_SMOOTH_RADIUS_PX: usize = 3;

/// Edge-aware smoothing of the points back-projected from `frame`: the mean of the points
/// within
/// `smooth_radius_px` along the row whose depth is within
/// [`SegmenterParams::depth_jump_at_m`] of the centre's, then the same along the column of
/// that result (a separable bilateral filter with a box kernel: steps larger than the
/// tolerance stay sharp). Sums run in increasing x, then y. Writes `out` and
/// `scratch.planes` (padded by `normal_radius_px`). Rows run in parallel with the
/// `threads` feature, with the same result. A pixel without a reading is `[0, 0, NaN]`
/// ([`NO_READING`]) in the smoothing's own buffers (the back-projected rows and the row
/// pass's result); only the outputs `out` and `scratch.planes` give it `[0, 0, 0]`.
pub(super) fn smooth_points(
    frame: &RgbdFrame<'_>,
    k: &Intrinsics,
    params: &SegmenterParams,
    scratch: &mut SmoothScratch,
    out: &mut [P3],
) {
    let (w, h) = (frame.width(), frame.height());
    let SmoothScratch { tmp, planes } = scratch;
    // Every value is written below.
    tmp.resize(3 * w * h, 0.0);
    let r = params.smooth_radius_px;
    // Along rows.
    tmp.par_chunks_mut(3 * w).enumerate().for_each_init(
        || RowScratch::with_width(w, r),
        |rs, (y, t)| {
            let RowScratch { row, sums } = rs;
            let [rx, ry, rz] = &mut *row;
            back_project_row(frame, k, y, [&mut rx[r..], &mut ry[r..], &mut rz[r..]]);
            let [rx, ry, rz] = &*row;
            let cz = &rz[r..];
            let (tx, t) = t.split_at_mut(w);
            let (ty, tz) = t.split_at_mut(w);
            let tap = |d: usize| [&rx[d..], &ry[d..], &rz[d..]];
            if r == DEFAULT_SMOOTH_RADIUS_PX {
                let taps = core::array::from_fn::<_, { 2 * DEFAULT_SMOOTH_RADIUS_PX + 1 }, _>(tap);
                sums.window_means(taps, cz, params, [tx, ty, tz], NO_READING);
            } else {
                sums.start(cz, params);
                sums.add_taps(2 * r + 1, tap, cz);
                sums.means(cz, [tx, ty, tz], NO_READING);
            }
        },
    );
    // Along columns.
    let pad = params.normal_radius_px;
    planes.resize(w, h, pad);
    let tmp: &[f32] = tmp;
    let wp = planes.wp;
    planes
        .data
        .par_chunks_mut(3 * wp)
        .zip(out.par_chunks_mut(w))
        .enumerate()
        .for_each_init(
            || RowScratch::with_width(w, 0),
            |RowScratch { sums, .. }, (y, (pl, o))| {
                let centre = &tmp[3 * w * y..3 * w * (y + 1)];
                let cz = &centre[2 * w..];
                let first = y.saturating_sub(r);
                let count = (y + r).min(h - 1) + 1 - first;
                let tap = |t: usize| {
                    let q = &tmp[3 * w * (first + t)..3 * w * (first + t + 1)];
                    [&q[..w], &q[w..2 * w], &q[2 * w..]]
                };
                let (px, pl) = pl.split_at_mut(wp);
                let (py, pz) = pl.split_at_mut(wp);
                let (px, py, pz) = (
                    &mut px[pad..pad + w],
                    &mut py[pad..pad + w],
                    &mut pz[pad..pad + w],
                );
                if r == DEFAULT_SMOOTH_RADIUS_PX && count == 2 * r + 1 {
                    let taps =
                        core::array::from_fn::<_, { 2 * DEFAULT_SMOOTH_RADIUS_PX + 1 }, _>(tap);
                    sums.window_means(taps, cz, params, [px, py, pz], 0.0);
                } else {
                    sums.start(cz, params);
                    sums.add_taps(count, tap, cz);
                    sums.means(cz, [px, py, pz], 0.0);
                }
                for (x, o) in o.iter_mut().enumerate() {
                    *o = [px[x], py[x], pz[x]];
                }
            },
        );
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
    let mut next = 0;
    while let Some(start) = next_nonzero(crease, next) {
        next = start + 1;
        if seen[start] {
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

/// The first index from `from` on where `bytes` is not zero. Flags are sparse: runs of
/// zeros are skipped [`CHUNK_PX`] bytes at a time (a test the compiler vectorises).
fn next_nonzero(bytes: &[u8], from: usize) -> Option<usize> {
    let rest = bytes.get(from..)?;
    let mut chunks = rest.chunks_exact(CHUNK_PX);
    let skipped = chunks
        .by_ref()
        .take_while(|c| c.iter().fold(0, |a, &b| a | b) == 0)
        .count();
    let at = from + CHUNK_PX * skipped;
    bytes[at..].iter().position(|&b| b != 0).map(|k| at + k)
}

/// `true` if `q` is a reading on the same surface as `c`, `sep` pixels away.
fn same_surface(c: P3, q: P3, sep: usize, params: &SegmenterParams) -> bool {
    q[2] > 0.0 && (q[2] - c[2]).abs() <= params.depth_jump_at_m(c[2]) * sep as f32
}

/// Unit normals facing the camera from cross products of point differences
/// `±normal_radius_px` apart; `[0, 0, 0]` where either direction has no surface neighbour.
/// Only the rows `y` with `rows(y)` are written (each row's normals depend on the points
/// alone, so a row computed in a later call is the same as in an earlier one).
///
/// Along each direction the difference across a pixel is central where both neighbours
/// `r` pixels away are on its surface (a reading within `r` times
/// [`SegmenterParams::depth_jump_at_m`] of its depth), one-sided where one is. Reads the
/// points from `planes` ([`smooth_points`]); rows run in parallel with the `threads`
/// feature, with the same result.
pub(super) fn normals(
    w: usize,
    h: usize,
    planes: &RowPlanes,
    params: &SegmenterParams,
    rows: impl Fn(usize) -> bool + Sync + Send,
    out: &mut [P3],
) {
    let r = params.normal_radius_px;
    let (pad, wp) = (planes.pad, planes.wp);
    debug_assert!(pad >= r && planes.data.len() == 3 * wp * h);
    let none = vec![0.0f32; 3 * wp];
    out.par_chunks_mut(w).enumerate().for_each_init(
        || vec![0.0f32; 3 * w],
        |soa, (y, o)| {
            if !rows(y) {
                return;
            }
            let row = planes.row(y);
            let up = if y >= r { planes.row(y - r) } else { &none };
            let down = if y + r < h { planes.row(y + r) } else { &none };
            // The x, y, z planes of a padded row, shifted by `dx` pixels.
            fn planes_at(
                row: &[f32],
                (w, wp, pad): (usize, usize, usize),
                dx: isize,
            ) -> [&[f32]; 3] {
                core::array::from_fn(|k| {
                    let start = (k * wp + pad).wrapping_add_signed(dx);
                    &row[start..start + w]
                })
            }
            let at = |row, dx| planes_at(row, (w, wp, pad), dx);
            let ri = r as isize;
            let around = [at(row, -ri), at(row, ri), at(up, 0), at(down, 0)];
            let (nx, rest) = soa.split_at_mut(w);
            let (ny, nz) = rest.split_at_mut(w);
            normals_row(at(row, 0), around, r, params, [nx, ny, nz]);
            for (x, o) in o.iter_mut().enumerate() {
                *o = [nx[x], ny[x], nz[x]];
            }
        },
    );
}

/// `sums` (x, y, z and count) plus the points of `taps` at column `x` whose depth is
/// within `jump` of the centre depth `cz` (a tap without a reading has depth
/// [`NO_READING`]), in tap order (the branch-free form of
/// `WindowSums::add`; inlined so the sums stay in registers).
#[inline(always)]
fn sum_taps<const N: usize>(
    taps: &[[&[f32]; 3]; N],
    x: usize,
    cz: f32,
    jump: f32,
    [mut ax, mut ay, mut az, an]: [f32; 4],
) -> [f32; 4] {
    // The points taken, counted in integers: `an` plus it is exactly what adding 1.0 a
    // point gives (small integers).
    let mut taken = 0u32;
    for [qx, qy, qz] in taps {
        // A tap without a reading is NaN ([`NO_READING`]): the test fails. There is no
        // `qz > 0` test: it is not needed only because every tap depth that is not NaN
        // is above 0, in the row pass a checked input (finite, positive:
        // `back_project_row`) and in the column pass a mean of such depths.
        let m = mask((qz[x] - cz).abs() <= jump);
        ax += keep(qx[x], m);
        ay += keep(qy[x], m);
        az += keep(qz[x], m);
        // `m` is all ones (−1 as an integer) for a point taken.
        taken = taken.wrapping_sub(m);
    }
    [ax, ay, az, an + taken as i32 as f32]
}

/// All ones if `on`, else zero: a lane mask for [`keep`] and [`pick`].
fn mask(on: bool) -> u32 {
    u32::from(on).wrapping_neg()
}

/// `v` where `m` is all ones, `+0.0` where it is zero (a select the compiler vectorises).
fn keep(v: f32, m: u32) -> f32 {
    f32::from_bits(v.to_bits() & m)
}

/// `a` where `m` is all ones, `b` where it is zero.
fn pick(a: f32, b: f32, m: u32) -> f32 {
    f32::from_bits((a.to_bits() & m) | (b.to_bits() & !m))
}

/// One row of [`normals`] as planes: centres `c`, their neighbours `r` pixels to the left,
/// right, up and down in `around`, unit normals into `out` (zero where there is none).
/// Branch-free, so the compiler vectorises it; the same arithmetic as a test per pixel.
fn normals_row(
    c: [&[f32]; 3],
    around: [[&[f32]; 3]; 4],
    r: usize,
    params: &SegmenterParams,
    out: [&mut [f32]; 3],
) {
    let w = c[2].len();
    let c = c.map(|s| &s[..w]);
    let [left, right, up, down] = around.map(|q| q.map(|s| &s[..w]));
    let [ox, oy, oz] = out;
    let (ox, oy, oz) = (&mut ox[..w], &mut oy[..w], &mut oz[..w]);
    for x in 0..w {
        let p = [c[0][x], c[1][x], c[2][x]];
        let tol = params.depth_jump_at_m(p[2]) * r as f32;
        // A neighbour on the surface, or the centre itself.
        let on = |q: &[&[f32]; 3]| {
            let m = mask((q[2][x] > 0.0) & ((q[2][x] - p[2]).abs() <= tol));
            [
                pick(q[0][x], p[0], m),
                pick(q[1][x], p[1], m),
                pick(q[2][x], p[2], m),
            ]
        };
        // Both on: b − a; one: the one-sided difference; none: p − p = 0.
        let du = sub(on(&right), on(&left));
        let dv = sub(on(&down), on(&up));
        let n = cross(dv, du);
        let len = dot(n, n).sqrt();
        // No normal without a reading or for a degenerate (or NaN) cross product.
        let ok = mask((p[2] > 0.0) & (len > 1e-12));
        // Face the camera: flip the sign bit where `n · p > 0`.
        let flip = mask(dot(n, p) > 0.0) & 0x8000_0000;
        let unit = |v: f32| keep(f32::from_bits(v.to_bits() ^ flip) / len, ok);
        ox[x] = unit(n[0]);
        oy[x] = unit(n[1]);
        oz[x] = unit(n[2]);
    }
}

/// The rows `y0..y1` outside which no pixel of `object` (rows of `w` pixels) is set;
/// empty if none is.
pub(super) fn object_rows(w: usize, object: &[bool]) -> core::ops::Range<usize> {
    let any = |row: &[bool]| row.iter().fold(false, |a, &b| a | b);
    let Some(y0) = object.chunks_exact(w).position(any) else {
        return 0..0;
    };
    let after = object.chunks_exact(w).rev().position(any).unwrap_or(0);
    y0..object.len() / w - after
}

/// Inputs of [`creases`]: `width·height` buffers.
#[derive(Debug, Clone)]
pub(super) struct CreaseInput<'a> {
    pub(super) w: usize,
    pub(super) h: usize,
    pub(super) rgb: &'a [[u8; 3]],
    pub(super) pts: &'a [P3],
    pub(super) nrm: &'a [P3],
    pub(super) object: &'a [bool],
    /// The rows outside which `object` is all `false` ([`object_rows`]).
    pub(super) object_rows: core::ops::Range<usize>,
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
        ref object_rows,
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
    // Rows without object pixels stay zero.
    let rows = object_rows.start * w..object_rows.end * w;
    out[rows]
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(k, out)| {
            let y = object_rows.start + k;
            for (x, out) in out.iter_mut().enumerate() {
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
                *out = f;
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fused_window_means_equal_the_three_passes_bit_for_bit() {
        let (w, r) = (37, DEFAULT_SMOOTH_RADIUS_PX);
        let params = SegmenterParams::default();
        // Depths with holes, steps and noise; x and y planes of mixed signs.
        let mut rng = riseg_core::rng::Pcg32::new(7);
        let mut plane = |scale: f32, holes: bool| -> Vec<f32> {
            (0..w + 2 * r)
                .map(|_| {
                    let v = rng.below(1000) as f32 / 1000.0;
                    if holes && rng.below(6) == 0 {
                        NO_READING
                    } else if holes {
                        0.5 + scale * v + 0.02 * (rng.below(3) as f32)
                    } else {
                        scale * (v - 0.5)
                    }
                })
                .collect()
        };
        let row = [plane(0.3, false), plane(0.2, false), plane(0.01, true)];
        let cz = &row[2][r..];
        let tap = |d: usize| [&row[0][d..], &row[1][d..], &row[2][d..]];
        let mut sums = RowScratch::with_width(w, 0).sums;
        let mut general = [vec![0.0; w], vec![0.0; w], vec![0.0; w]];
        sums.start(cz, &params);
        sums.add_taps(2 * r + 1, tap, cz);
        let [gx, gy, gz] = &mut general;
        sums.means(cz, [gx, gy, gz], 0.0);
        let mut fused = [vec![0.0; w], vec![0.0; w], vec![0.0; w]];
        let taps = core::array::from_fn::<_, { 2 * DEFAULT_SMOOTH_RADIUS_PX + 1 }, _>(tap);
        let [fx, fy, fz] = &mut fused;
        sums.window_means(taps, cz, &params, [fx, fy, fz], 0.0);
        let bits =
            |v: &[Vec<f32>; 3]| -> Vec<u32> { v.iter().flatten().map(|f| f.to_bits()).collect() };
        assert_eq!(bits(&fused), bits(&general));
        assert!(general[2].contains(&0.0) && general[2].iter().any(|&z| z > 0.0));
        // A plain reference, one test per tap in tap order, on a copy that marks a missing
        // reading 0.0: it does not share `sum_taps`.
        let z0: Vec<f32> = row[2]
            .iter()
            .map(|&z| if z.is_nan() { 0.0 } else { z })
            .collect();
        let mut plain = [vec![0.0; w], vec![0.0; w], vec![0.0; w]];
        for x in 0..w {
            let cz = z0[x + r];
            if cz <= 0.0 {
                continue;
            }
            let jump = params.depth_jump_at_m(cz);
            let (mut ax, mut ay, mut az, mut an) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
            for t in x..=x + 2 * r {
                let qz = z0[t];
                if qz.is_finite() && qz > 0.0 && (qz - cz).abs() <= jump {
                    ax += row[0][t];
                    ay += row[1][t];
                    az += qz;
                    an += 1.0;
                }
            }
            [plain[0][x], plain[1][x], plain[2][x]] = [ax / an, ay / an, az / an];
        }
        assert_eq!(bits(&fused), bits(&plain));
        for (x, &cz) in z0[r..r + w].iter().enumerate() {
            if cz > 0.0 {
                assert!(fused.iter().all(|p| !p[x].is_nan()), "NaN at x = {x}");
            }
        }
    }
}
