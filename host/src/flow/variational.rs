//! Variational refinement (DIS, section 2.3): lowers
//!
//! ```text
//! E(du) = Σ_x  δ·Ψ((Iz + Ix·du + Iy·dv)²)  +  α·Ψ(|∇(u + du)|² + |∇(v + dv)|²),
//! Ψ(s²) = √(s² + ε²)
//! ```
//!
//! around the current flow `u`. Each of `fixed_point_iters` iterations adds the increment
//! found so far to `u`, warps the second image by `u` (temporal difference `Iz`, gradients
//! `Ix`, `Iy` averaged over both images), freezes the robust weights (lagged
//! diffusivity) and runs `sor_iters` red-black SOR sweeps on the resulting linear system
//! for the new increment. Pixels warped outside the second image keep only the smoothness
//! term. The result is `u + du`.
//!
//! Edge-aware smoothness (with `edge_grey > 0`): the smoothness weight between two
//! neighbours `p`, `q` is multiplied by `1 / (1 + ((I0(q) − I0(p)) / edge_grey)²)`, so the
//! flow diffuses less across image edges (object outlines, the seams between packed boxes),
//! where motion boundaries lie. The factors depend on the first image only and are
//! computed once per call.
//!
//! Red-black order makes every half-sweep a set of independent pixel updates, so rows run
//! in parallel and the result does not depend on the thread count. To keep those updates
//! contiguous (and vectorisable), each colour (`(x + y) mod 2`) has its own planes: pixel
//! `(x, y)` lives at slot `x / 2 + 1` of row `y + 1` of colour `(x + y) mod 2`, with zero
//! guard rows and slots on every side. With `s = (x + y) mod 2` and `k = x / 2`, the four
//! neighbours lie in the other colour at slots `k + s` (left) and `k + s + 1` (right) of
//! the same row and slot `k + 1` of the rows above and below.

use super::pool::{Lent, Pool};
use crate::par::*;
use wide::f32x4;

/// Settings of the refinement.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RefineSettings {
    pub fixed_point_iters: usize,
    pub sor_iters: usize,
    pub sor_omega: f32,
    pub alpha: f32,
    pub delta: f32,
    /// Image step (grey levels, 0-255) that halves the smoothness weight across it; 0 =
    /// uniform weight.
    pub edge_grey: f32,
}

/// Charbonnier epsilon of the data term, intensity units (0-255 scale).
const EPS_DATA: f32 = 1.0;
/// Charbonnier epsilon of the smoothness term, pixels per pixel.
const EPS_SMOOTH: f32 = 0.05;

/// The level's images the refinement reads. The buffers are lent to it: only the warps
/// read the gradients and the second image, and after the last one the refinement gives
/// them back to the pool. With one fixed-point iteration the buffers it makes after the
/// first warp (the increments, and at full resolution the smoothness weights) reuse their
/// pages; with more, those are made before the last warp and later requests to the pool
/// reuse them.
pub(crate) struct RefineInput<'a> {
    pub w: usize,
    pub h: usize,
    pub i0: &'a [f32],
    /// The first image's gradients ([`super::pyramid::gradients`]).
    pub gx0: Lent<f32>,
    pub gy0: Lent<f32>,
    /// The second image and its gradients, interleaved.
    pub second: Warpable,
}

impl RefineInput<'_> {
    /// Gives the lent buffers back to `pool`.
    fn recycle(self, pool: &Pool) {
        pool.put(self.gx0);
        pool.put(self.gy0);
        pool.put(self.second.data);
    }
}

/// Values per pixel of a [`Warpable`].
const CHANNELS: usize = 3;

/// The second image and its gradients interleaved per pixel as `[I1, ∂I1/∂x, ∂I1/∂y]`
/// (one bilinear tap reads all three as the first lanes of one [`f32x4`] load, whose
/// fourth lane is the next pixel's `I1` and is not used), row-major with the last column
/// and row repeated once so that a tap at the last pixel stays inside, and one value more
/// at the end for the last load's fourth lane. The gradients are those of
/// [`super::pyramid::gradients`], bit for bit. The values live in a flat buffer of the
/// level's [`Pool`]; [`Warpable::recycle`] gives it back.
#[derive(Debug, Clone)]
pub(crate) struct Warpable {
    /// Pixels per buffer row (`w + 1`).
    stride: usize,
    data: Lent<f32>,
}

impl Warpable {
    /// `i1` (`w x h`, `w, h >= 1`) interleaved with its central-difference gradients.
    pub fn new(i1: &[f32], (w, h): (usize, usize), pool: &Pool) -> Self {
        let stride = w + 1;
        let body = CHANNELS * stride * (h + 1);
        let mut data = pool.scratch(body + 1);
        let (rows, last) = data.split_at_mut(body);
        last.fill(0.0);
        rows.par_chunks_mut(CHANNELS * stride)
            .enumerate()
            .for_each(|(yy, out)| {
                let out = out.as_chunks_mut::<CHANNELS>().0;
                let y = yy.min(h - 1);
                let row = &i1[y * w..][..w];
                let up = &i1[y.saturating_sub(1) * w..][..w];
                let down = &i1[(y + 1).min(h - 1) * w..][..w];
                // As `gradients`: half the central difference, one-sided at the ends.
                let at = |x: usize, left: usize, right: usize| {
                    [
                        row[x],
                        0.5 * (row[right] - row[left]),
                        0.5 * (down[x] - up[x]),
                    ]
                };
                if w >= 2 {
                    out[0] = at(0, 0, 1);
                    out[w - 1] = at(w - 1, w - 2, w - 1);
                    let inner = out[1..w - 1].iter_mut().zip(row.windows(3));
                    for ((o, three), (&u, &d)) in inner.zip(up[1..].iter().zip(&down[1..])) {
                        *o = [three[1], 0.5 * (three[2] - three[0]), 0.5 * (d - u)];
                    }
                } else {
                    out[0] = [row[0], 0.0, 0.5 * (down[0] - up[0])];
                }
                out[w] = out[w - 1];
            });
        Self { stride, data }
    }

    /// The values a bilinear tap at pixel `at` reads, as the first three lanes of four
    /// vectors: pixels `at`, `at + 1` (top) and `at + stride`, `at + stride + 1` (bottom);
    /// `None` past the end.
    #[inline]
    fn quad(&self, at: usize) -> Option<[f32x4; 4]> {
        let pair = |i: usize| {
            let s = self.data.get(i..i + 2 * CHANNELS + 1)?;
            let (a, b) = (
                s.first_chunk::<4>()?,
                s.get(CHANNELS..)?.first_chunk::<4>()?,
            );
            Some((f32x4::new(*a), f32x4::new(*b)))
        };
        let (p00, p01) = pair(CHANNELS * at)?;
        let (p10, p11) = pair(CHANNELS * (at + self.stride))?;
        Some([p00, p01, p10, p11])
    }
}

/// Geometry of the colour planes.
#[derive(Debug, Clone, Copy)]
struct Split {
    w: usize,
    h: usize,
    /// Slots per plane row: `ceil(w / 2)` plus two guards.
    ps: usize,
}

impl Split {
    fn new(w: usize, h: usize) -> Self {
        Self {
            w,
            h,
            ps: w.div_ceil(2) + 2,
        }
    }

    /// Parity `s` of colour `c`'s row `y`: its pixels sit at `x = 2k + s`.
    fn parity(c: usize, y: usize) -> usize {
        (c + y) & 1
    }

    /// Pixels of colour `c` in row `y`.
    fn count(&self, c: usize, y: usize) -> usize {
        (self.w + 1 - Self::parity(c, y)) / 2
    }

    /// Values of `n` planes of one colour ([`Planes`]), guard rows and slots included.
    fn len(&self, n: usize) -> usize {
        self.ps * n * (self.h + 2)
    }
}

/// `n` planes of one colour, row-interleaved: image row `y` holds plane `j` at
/// `data[((y + 1)·n + j)·ps ..][.. ps]`, so one contiguous chunk has every plane of a row.
/// The values live in a buffer [`refine`] lends (several sets of planes share one).
#[derive(Debug)]
struct Planes<'a> {
    ps: usize,
    n: usize,
    data: &'a mut [f32],
}

impl<'a> Planes<'a> {
    /// `n` planes of each colour (colour 0 first) at the front of `values`, which holds at
    /// least `2 · sp.len(n)`, and the values after them.
    fn pair(sp: &Split, n: usize, values: &'a mut [f32]) -> ([Self; 2], &'a mut [f32]) {
        let (c0, rest) = values.split_at_mut(sp.len(n));
        let (c1, rest) = rest.split_at_mut(sp.len(n));
        let planes = |data| Self { ps: sp.ps, n, data };
        ([planes(c0), planes(c1)], rest)
    }

    /// Plane `j` of buffer row `yy` (`yy = y + 1`; 0 and `h + 1` are the guard rows).
    #[inline]
    fn row(&self, yy: usize, j: usize) -> &[f32] {
        &self.data[(yy * self.n + j) * self.ps..][..self.ps]
    }

    /// `n` values of plane `j` of buffer row `yy` from slot `start`.
    #[inline]
    fn span(&self, yy: usize, j: usize, start: usize, n: usize) -> &[f32] {
        &self.row(yy, j)[start..][..n]
    }

    /// The chunks of image rows `0..h` (guard rows excluded), in parallel, to read.
    fn rows(&self, h: usize) -> crate::par::Chunks<'_, f32> {
        let c = self.n * self.ps;
        self.data[c..(h + 1) * c].par_chunks(c)
    }

    /// The chunks of image rows `0..h` (guard rows excluded), in parallel.
    fn rows_mut(&mut self, h: usize) -> crate::par::ChunksMut<'_, f32> {
        let c = self.n * self.ps;
        self.data[c..(h + 1) * c].par_chunks_mut(c)
    }
}

/// Where [`refine`] keeps the smoothness weights.
enum Weights<'p> {
    /// A buffer of the plane pool.
    Values(Lent<f32>),
    /// A buffer of the flow pool (at the pyramid levels; the flow's, given back just
    /// before, is among the candidates), with that pool, which lends the refined flow when
    /// the weights go back to it.
    Pairs(Lent<[f32; 2]>, &'p Pool<[f32; 2]>),
}

impl Weights<'_> {
    fn values(&mut self) -> &mut [f32] {
        match self {
            Self::Values(v) => v,
            Self::Pairs(p, _) => bytemuck::cast_slice_mut(&mut p[..]),
        }
    }
}

/// Refines `flow` (`w x h`, row-major). With `flows` (at the pyramid levels) the flow and
/// system planes and the smoothness weights come from that pool, and the refined flow may
/// come back in another of its buffers (see the comments in the body); without, it is
/// refined in place.
pub(crate) fn refine(
    inp: RefineInput<'_>,
    flow: &mut Lent<[f32; 2]>,
    s: &RefineSettings,
    pool: &Pool,
    flows: Option<&Pool<[f32; 2]>>,
) {
    if s.fixed_point_iters == 0 {
        inp.recycle(pool);
        return;
    }
    let sp = Split::new(inp.w, inp.h);
    // Per colour: flow (u, v), increment (du, dv), smoothness weights to the right and
    // lower neighbour (wr, wd), and the frozen system (a12, 1/a11, 1/a22, b1, b2), whose
    // first three planes hold the warped derivatives (ix, iy, iz) until `system` turns
    // each pixel's into its equations (one buffer less to fault in: one-shot `riseg flow`,
    // 230 pages at level 1). Neighbour reads reach the guards of the flow, increment and
    // weight planes, so those start zeroed; the system is only read where written. The
    // increments and weights are made after the first warp (with one iteration, after the
    // last warp has given its inputs back, whose buffers they may then reuse).
    // The flow and system planes of both colours share one buffer. At the pyramid levels
    // it comes from the flow pool: the full-resolution flow made after the last level
    // then takes it with its pages already faulted in (one-shot `riseg flow` MEDIUM, 640x480:
    // 3136 -> 2653 page faults), as long as it fits in the room of a flow (`w x h` of the
    // full resolution). On very small images (64x48) the buffer with its guards is larger:
    // it is allocated anew and kept in the pool, which costs memory only. Not at full
    // resolution, where it is larger than a flow and would leave the pool as the estimate's
    // flow.
    let front_len = 2 * sp.len(2) + 2 * sp.len(5);
    let (mut front_pairs, mut front_values) = (None, None);
    let front: &mut [f32] = match flows {
        Some(f) => {
            bytemuck::cast_slice_mut(&mut front_pairs.insert(f.scratch(front_len.div_ceil(2)))[..])
        }
        None => &mut front_values.insert(pool.scratch(front_len))[..],
    };
    let (uv_values, sys_values) = front.split_at_mut(2 * sp.len(2));
    uv_values.fill(0.0);
    let (mut uv, _) = Planes::pair(&sp, 2, uv_values);
    let (mut sys, _) = Planes::pair(&sp, 5, sys_values);
    // The increments' and the weights' values, made after the first warp: the increment
    // is zero until the first solve (and `scatter` adds that zero to the flow).
    let mut late: Option<(Lent<f32>, Weights<'_>)> = None;
    for (c, uvc) in uv.iter_mut().enumerate() {
        scatter(&sp, c, flow, uvc);
    }
    let mut edge_values = (s.edge_grey > 0.0).then(|| {
        let mut values = pool.zeroed(2 * sp.len(2));
        let (mut e, _) = Planes::pair(&sp, 2, &mut values);
        for (c, ec) in e.iter_mut().enumerate() {
            edge_factors(&sp, c, inp.i0, s.edge_grey, ec);
        }
        values
    });
    let edges = edge_values
        .as_mut()
        .map(|values| Planes::pair(&sp, 2, values).0);
    let mut warp_input = Some(inp);
    for iter in 0..s.fixed_point_iters {
        if let Some((duv_values, _)) = &mut late {
            let (mut duv, _) = Planes::pair(&sp, 2, duv_values);
            for (uvc, dc) in uv.iter_mut().zip(duv.iter_mut()) {
                absorb(uvc, dc);
            }
        }
        if let Some(inp) = &warp_input {
            for (c, (uvc, sc)) in uv.iter().zip(sys.iter_mut()).enumerate() {
                warp(&sp, c, inp, uvc, sc);
            }
        }
        if iter + 1 == s.fixed_point_iters
            && let Some(inp) = warp_input.take()
        {
            inp.recycle(pool);
        }
        let (duv_values, wts_values) = late.get_or_insert_with(|| {
            let duv = pool.zeroed(2 * sp.len(2));
            let wts = match flows {
                // From `scatter` to `gather` the flow's values live in the planes: its
                // buffer goes back to the flow pool, and the weights take a buffer of
                // that pool (the flow's is among the candidates; `Pool::take` picks)
                // instead of a plane-pool buffer grown for them (one-shot `riseg flow`
                // MEDIUM, 640x480: 2530 -> 2453 page faults).
                Some(f) => {
                    f.put(core::mem::take(flow));
                    Weights::Pairs(f.zeroed(sp.len(2)), f)
                }
                None => Weights::Values(pool.zeroed(2 * sp.len(2))),
            };
            (duv, wts)
        });
        let (duv, _) = &mut Planes::pair(&sp, 2, duv_values);
        let (wts, _) = &mut Planes::pair(&sp, 2, wts_values.values());
        for (c, wc) in wts.iter_mut().enumerate() {
            smoothness(&sp, c, &uv, duv, wc, s.alpha);
            if let Some(e) = &edges {
                apply_edges(&sp, &e[c], wc);
            }
        }
        for (c, sc) in sys.iter_mut().enumerate() {
            system(&sp, c, &uv, &duv[c], wts, sc, s.delta);
        }
        for _ in 0..s.sor_iters {
            for (c, sc) in sys.iter().enumerate() {
                let [d0, d1] = &mut *duv;
                let (mine, other) = if c == 0 { (d0, &*d1) } else { (d1, &*d0) };
                sor_half_sweep(&sp, c, sc, wts, mine, other, s.sor_omega);
            }
        }
    }
    // Made in the first iteration: `fixed_point_iters > 0`.
    if let Some((mut duv_values, wts_values)) = late {
        match wts_values {
            // The flow pool takes the weights back and lends the refined flow (in their
            // buffer or another of its own).
            Weights::Pairs(values, f) => {
                f.put(values);
                *flow = f.scratch(sp.w * sp.h);
            }
            Weights::Values(values) => pool.put(values),
        }
        gather(&sp, &uv, &Planes::pair(&sp, 2, &mut duv_values).0, flow);
        pool.put(duv_values);
    }
    if let (Some(f), Some(values)) = (flows, front_pairs) {
        f.put(values);
    }
    for values in front_values.into_iter().chain(edge_values) {
        pool.put(values);
    }
}

/// The edge-aware factors of colour `c`: `1 / (1 + (ΔI / edge_grey)²)` for the edge to the
/// right neighbour (plane 0) and to the lower one (plane 1) of each pixel, `ΔI` the
/// difference of `i0` (`w x h`, row-major) across that edge; 1 where there is no
/// neighbour (the weight there is 0 anyway).
fn edge_factors(sp: &Split, c: usize, i0: &[f32], edge_grey: f32, out: &mut Planes) {
    let ps = sp.ps;
    let inv = 1.0 / edge_grey;
    let factor = |d: f32| {
        let q = d * inv;
        1.0 / (1.0 + q * q)
    };
    out.rows_mut(sp.h).enumerate().for_each(|(y, chunk)| {
        let s = Split::parity(c, y);
        let n = sp.count(c, y);
        let (er, ed) = chunk.split_at_mut(ps);
        let row = &i0[y * sp.w..][..sp.w];
        let below = (y + 1 < sp.h).then(|| &i0[(y + 1) * sp.w..][..sp.w]);
        for k in 0..n {
            let x = 2 * k + s;
            er[k + 1] = row.get(x + 1).map_or(1.0, |&r| factor(r - row[x]));
            ed[k + 1] = below.map_or(1.0, |b| factor(b[x] - row[x]));
        }
    });
}

/// Multiplies colour `c`'s smoothness weights `wts` by its edge factors `edges`.
fn apply_edges(sp: &Split, edges: &Planes, wts: &mut Planes) {
    let ps = sp.ps;
    wts.rows_mut(sp.h)
        .zip(edges.data[edges.n * ps..].par_chunks(edges.n * ps))
        .for_each(|(w, e)| {
            for (w, e) in w.iter_mut().zip(e) {
                *w *= *e;
            }
        });
}

/// Row-major flow into colour `c`'s `(u, v)` planes, plus the zero increment (`u + 0`, as
/// [`absorb`] adds an increment: a flow of `-0` becomes `+0`).
fn scatter(sp: &Split, c: usize, flow: &[[f32; 2]], uv: &mut Planes) {
    let ps = sp.ps;
    uv.rows_mut(sp.h).enumerate().for_each(|(y, chunk)| {
        let s = Split::parity(c, y);
        let n = sp.count(c, y);
        let (ur, vr) = chunk.split_at_mut(ps);
        let src = &flow[y * sp.w..][..sp.w];
        for k in 0..n {
            let f = src[2 * k + s];
            ur[k + 1] = f[0] + 0.0;
            vr[k + 1] = f[1] + 0.0;
        }
    });
}

/// Moves an increment into its flow (`u += du`, `du = 0`), guards included (both stay 0
/// there).
fn absorb(uv: &mut Planes, duv: &mut Planes) {
    uv.data
        .par_chunks_mut(uv.n * uv.ps)
        .zip(duv.data.par_chunks_mut(duv.n * duv.ps))
        .for_each(|(u, d)| {
            for (u, d) in u.iter_mut().zip(d) {
                *u += *d;
                *d = 0.0;
            }
        });
}

/// Warps the second image by colour `c`'s flow `uv`: `Iz = I1(x + u) − I0(x)`, `Ix`, `Iy`
/// averaged over both images, into the first three planes of `deriv`.
fn warp(sp: &Split, c: usize, inp: &RefineInput<'_>, uv: &Planes, deriv: &mut Planes) {
    let ps = sp.ps;
    let (w, h) = (sp.w, sp.h);
    let (wmax, hmax) = ((w - 1) as f32, (h - 1) as f32);
    let second = &inp.second;
    let stride = second.stride;
    uv.rows(h)
        .zip(deriv.rows_mut(h))
        .enumerate()
        .for_each(|(y, (uvr, der))| {
            let s = Split::parity(c, y);
            let n = sp.count(c, y);
            let (ur, vr) = uvr.split_at(ps);
            let (ixr, rest) = der.split_at_mut(ps);
            let (iyr, rest) = rest.split_at_mut(ps);
            let izr = &mut rest[..ps];
            let (i0, gx0, gy0) = (
                &inp.i0[y * w..][..w],
                &inp.gx0[y * w..][..w],
                &inp.gy0[y * w..][..w],
            );
            // Slot k + 1 holds pixel x = 2k + s.
            let (ur, vr) = (&ur[1..=n], &vr[1..=n]);
            let (ixr, iyr, izr) = (&mut ixr[1..=n], &mut iyr[1..=n], &mut izr[1..=n]);
            for k in 0..n {
                let x = 2 * k + s;
                let (xw, yw) = (x as f32 + ur[k], y as f32 + vr[k]);
                let mut d = [0.0f32; 3];
                if (0.0..=wmax).contains(&xw) && (0.0..=hmax).contains(&yw) {
                    // Inside the image: non-negative, so truncation is floor (and `i32`
                    // conversions are single instructions, `usize` ones are not).
                    let (ix, iy) = (xw as i32, yw as i32);
                    let (ax, ay) = (xw - ix as f32, yw - iy as f32);
                    let at = iy.unsigned_abs() as usize * stride + ix.unsigned_abs() as usize;
                    if let Some([p00, p01, p10, p11]) = second.quad(at) {
                        // All three channels at once, each as `p + t·(q − p)`.
                        let lerp = |p: f32x4, q: f32x4, t: f32| p + f32x4::splat(t) * (q - p);
                        let v = lerp(lerp(p00, p01, ax), lerp(p10, p11, ax), ay).to_array();
                        d = [0.5 * (v[1] + gx0[x]), 0.5 * (v[2] + gy0[x]), v[0] - i0[x]];
                    }
                }
                // Out of view: zero derivatives make the data term vanish.
                [ixr[k], iyr[k], izr[k]] = d;
            }
        });
}

/// `α / √(|∇(u+du)|² + |∇(v+dv)|² + ε²)` for colour `c` (forward differences), stored as
/// the weight of the edge to the right and to the lower neighbour (0 across the border).
fn smoothness(
    sp: &Split,
    c: usize,
    uv: &[Planes; 2],
    duv: &[Planes; 2],
    out: &mut Planes,
    alpha: f32,
) {
    let ps = sp.ps;
    let (uvm, uvo, dm, dov) = (&uv[c], &uv[1 - c], &duv[c], &duv[1 - c]);
    let eps2 = EPS_SMOOTH * EPS_SMOOTH;
    out.rows_mut(sp.h).enumerate().for_each(|(y, chunk)| {
        let s = Split::parity(c, y);
        let n = sp.count(c, y);
        let yy = y + 1;
        let (um, vm) = (&uvm.row(yy, 0)[1..][..n], &uvm.row(yy, 1)[1..][..n]);
        let (dum, dvm) = (&dm.row(yy, 0)[1..][..n], &dm.row(yy, 1)[1..][..n]);
        let (ur, vr) = (&uvo.row(yy, 0)[s + 1..][..n], &uvo.row(yy, 1)[s + 1..][..n]);
        let (dur, dvr) = (&dov.row(yy, 0)[s + 1..][..n], &dov.row(yy, 1)[s + 1..][..n]);
        let (ud, vd) = (&uvo.row(yy + 1, 0)[1..][..n], &uvo.row(yy + 1, 1)[1..][..n]);
        let (dud, dvd) = (&dov.row(yy + 1, 0)[1..][..n], &dov.row(yy + 1, 1)[1..][..n]);
        let (wr, wd) = chunk.split_at_mut(ps);
        let (wr, wd) = (&mut wr[1..][..n], &mut wd[1..][..n]);
        for k in 0..n {
            let (pu, pv) = (um[k] + dum[k], vm[k] + dvm[k]);
            let ux = ur[k] + dur[k] - pu;
            let vx = vr[k] + dvr[k] - pv;
            let uy = ud[k] + dud[k] - pu;
            let vy = vd[k] + dvd[k] - pv;
            let g = alpha / (ux * ux + vx * vx + uy * uy + vy * vy + eps2).sqrt();
            wr[k] = g;
            wd[k] = g;
        }
        // Across the right and bottom borders there is no edge. (The differences read
        // there came from guard slots and only affected these zeroed weights.)
        if n > 0 && 2 * (n - 1) + s + 1 == sp.w {
            let last_g = {
                let k = n - 1;
                let (pu, pv) = (um[k] + dum[k], vm[k] + dvm[k]);
                let uy = ud[k] + dud[k] - pu;
                let vy = vd[k] + dvd[k] - pv;
                alpha / (uy * uy + vy * vy + eps2).sqrt()
            };
            wr[n - 1] = 0.0;
            wd[n - 1] = last_g;
        }
        if y + 1 == sp.h {
            for k in 0..n {
                let (pu, pv) = (um[k] + dum[k], vm[k] + dvm[k]);
                let ux = ur[k] + dur[k] - pu;
                let vx = vr[k] + dvr[k] - pv;
                wd[k] = 0.0;
                if wr[k] != 0.0 {
                    wr[k] = alpha / (ux * ux + vx * vx + eps2).sqrt();
                }
            }
        }
    });
}

/// Freezes the system of colour `c` at the current increment, in `out` (five planes) over
/// the warped derivatives its first three planes hold ([`warp`]): each pixel's are read
/// before its equations are written.
fn system(
    sp: &Split,
    c: usize,
    uv: &[Planes; 2],
    duv: &Planes,
    wts: &[Planes; 2],
    out: &mut Planes,
    delta: f32,
) {
    let ps = sp.ps;
    let (uvm, uvo, wm, wo) = (&uv[c], &uv[1 - c], &wts[c], &wts[1 - c]);
    let eps2 = EPS_DATA * EPS_DATA;
    out.rows_mut(sp.h).enumerate().for_each(|(y, chunk)| {
        let s = Split::parity(c, y);
        let n = sp.count(c, y);
        let yy = y + 1;
        let (du, dv) = (duv.span(yy, 0, 1, n), duv.span(yy, 1, 1, n));
        let (um, vm) = (uvm.span(yy, 0, 1, n), uvm.span(yy, 1, 1, n));
        let (wr, wd) = (wm.span(yy, 0, 1, n), wm.span(yy, 1, 1, n));
        let wl = &wo.row(yy, 0)[s..][..n];
        let wu = &wo.row(yy - 1, 1)[1..][..n];
        let (ul, vl) = (&uvo.row(yy, 0)[s..][..n], &uvo.row(yy, 1)[s..][..n]);
        let (ur, vr) = (&uvo.row(yy, 0)[s + 1..][..n], &uvo.row(yy, 1)[s + 1..][..n]);
        let (uu, vu) = (&uvo.row(yy - 1, 0)[1..][..n], &uvo.row(yy - 1, 1)[1..][..n]);
        let (ud, vd) = (&uvo.row(yy + 1, 0)[1..][..n], &uvo.row(yy + 1, 1)[1..][..n]);
        let mut parts = chunk.chunks_exact_mut(ps).map(|r| &mut r[1..][..n]);
        let (Some(ix_a12), Some(iy_inv11), Some(iz_inv22), Some(b1), Some(b2)) = (
            parts.next(),
            parts.next(),
            parts.next(),
            parts.next(),
            parts.next(),
        ) else {
            return;
        };
        for k in 0..n {
            let (ix, iy, iz) = (ix_a12[k], iy_inv11[k], iz_inv22[k]);
            let r = iz + ix * du[k] + iy * dv[k];
            let pd = delta / (r * r + eps2).sqrt();
            let wsum = wl[k] + wr[k] + wu[k] + wd[k];
            let a11 = pd * ix * ix + wsum;
            let a22 = pd * iy * iy + wsum;
            ix_a12[k] = pd * ix * iy;
            iy_inv11[k] = if a11 > 0.0 { 1.0 / a11 } else { 0.0 };
            iz_inv22[k] = if a22 > 0.0 { 1.0 / a22 } else { 0.0 };
            b1[k] = -pd * ix * iz
                + wl[k] * (ul[k] - um[k])
                + wr[k] * (ur[k] - um[k])
                + wu[k] * (uu[k] - um[k])
                + wd[k] * (ud[k] - um[k]);
            b2[k] = -pd * iy * iz
                + wl[k] * (vl[k] - vm[k])
                + wr[k] * (vr[k] - vm[k])
                + wu[k] * (vu[k] - vm[k])
                + wd[k] * (vd[k] - vm[k]);
        }
    });
}

/// One SOR update of every pixel of colour `c` (its neighbours, in `other`, stay fixed):
/// `du ← du + ω·((b1 + Σ w·du_q − a12·dv)/a11 − du)`, then `dv` likewise.
fn sor_half_sweep(
    sp: &Split,
    c: usize,
    sys: &Planes,
    wts: &[Planes; 2],
    mine: &mut Planes,
    other: &Planes,
    omega: f32,
) {
    let ps = sp.ps;
    let (wm, wo) = (&wts[c], &wts[1 - c]);
    mine.rows_mut(sp.h).enumerate().for_each(|(y, chunk)| {
        let s = Split::parity(c, y);
        let n = sp.count(c, y);
        let yy = y + 1;
        let (a12, inv11, inv22, b1, b2) = (
            sys.span(yy, 0, 1, n),
            sys.span(yy, 1, 1, n),
            sys.span(yy, 2, 1, n),
            sys.span(yy, 3, 1, n),
            sys.span(yy, 4, 1, n),
        );
        let (wr, wd) = (wm.span(yy, 0, 1, n), wm.span(yy, 1, 1, n));
        let wl = &wo.row(yy, 0)[s..][..n];
        let wu = &wo.row(yy - 1, 1)[1..][..n];
        let (dul, dvl) = (&other.row(yy, 0)[s..][..n], &other.row(yy, 1)[s..][..n]);
        let (dur, dvr) = (
            &other.row(yy, 0)[s + 1..][..n],
            &other.row(yy, 1)[s + 1..][..n],
        );
        let (duu, dvu) = (
            &other.row(yy - 1, 0)[1..][..n],
            &other.row(yy - 1, 1)[1..][..n],
        );
        let (dud, dvd) = (
            &other.row(yy + 1, 0)[1..][..n],
            &other.row(yy + 1, 1)[1..][..n],
        );
        let (du, dv) = chunk.split_at_mut(ps);
        let (du, dv) = (&mut du[1..][..n], &mut dv[1..][..n]);
        for k in 0..n {
            let nu = wl[k] * dul[k] + wr[k] * dur[k] + wu[k] * duu[k] + wd[k] * dud[k];
            let nv = wl[k] * dvl[k] + wr[k] * dvr[k] + wu[k] * dvu[k] + wd[k] * dvd[k];
            let u1 = du[k] + omega * ((b1[k] + nu - a12[k] * dv[k]) * inv11[k] - du[k]);
            let v1 = dv[k] + omega * ((b2[k] + nv - a12[k] * u1) * inv22[k] - dv[k]);
            du[k] = u1;
            dv[k] = v1;
        }
    });
}

/// `u + du` from the colour planes back into a row-major flow.
fn gather(sp: &Split, uv: &[Planes; 2], duv: &[Planes; 2], flow: &mut [[f32; 2]]) {
    flow.par_chunks_mut(sp.w).enumerate().for_each(|(y, row)| {
        for c in 0..2 {
            let s = Split::parity(c, y);
            let n = sp.count(c, y);
            let yy = y + 1;
            let (u, v) = (&uv[c].row(yy, 0)[1..][..n], &uv[c].row(yy, 1)[1..][..n]);
            let (du, dv) = (&duv[c].row(yy, 0)[1..][..n], &duv[c].row(yy, 1)[1..][..n]);
            for k in 0..n {
                row[2 * k + s] = [u[k] + du[k], v[k] + dv[k]];
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbour_slots_match_the_module_docs() {
        for (w, h) in [(5, 3), (4, 4), (1, 1), (1, 2), (2, 1)] {
            let sp = Split::new(w, h);
            // Load pixel indices as the flow's u component, in both colours.
            let mut values = vec![0.0; 2 * sp.len(1)];
            let (mut planes, _) = Planes::pair(&sp, 1, &mut values);
            for (c, p) in planes.iter_mut().enumerate() {
                p.rows_mut(h).enumerate().for_each(|(y, row)| {
                    let s = Split::parity(c, y);
                    for k in 0..sp.count(c, y) {
                        row[k + 1] = (y * w + 2 * k + s) as f32;
                    }
                });
            }
            for y in 0..h {
                for x in 0..w {
                    let c = (x + y) & 1;
                    let s = Split::parity(c, y);
                    let (k, yy) = (x / 2, y + 1);
                    let other = &planes[1 - c];
                    assert_eq!(planes[c].row(yy, 0)[k + 1], (y * w + x) as f32);
                    if x > 0 {
                        assert_eq!(other.row(yy, 0)[k + s], (y * w + x - 1) as f32);
                    }
                    if x + 1 < w {
                        assert_eq!(other.row(yy, 0)[k + s + 1], (y * w + x + 1) as f32);
                    }
                    if y > 0 {
                        assert_eq!(other.row(yy - 1, 0)[k + 1], ((y - 1) * w + x) as f32);
                    }
                    if y + 1 < h {
                        assert_eq!(other.row(yy + 1, 0)[k + 1], ((y + 1) * w + x) as f32);
                    }
                }
            }
        }
    }

    #[test]
    fn warpable_holds_the_image_and_its_gradients() {
        let (w, h) = (5, 4);
        let i1: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 11) as f32 * 1.5).collect();
        let pool = Pool::default();
        let (gx, gy) = super::super::pyramid::gradients(&i1, w, h, &pool);
        let second = Warpable::new(&i1, (w, h), &pool);
        for yy in 0..=h {
            for xx in 0..=w {
                let (x, y) = (xx.min(w - 1), yy.min(h - 1));
                let at = CHANNELS * (yy * second.stride + xx);
                let i = y * w + x;
                assert_eq!(&second.data[at..at + CHANNELS], [i1[i], gx[i], gy[i]]);
            }
        }
        assert_eq!(second.data.len(), CHANNELS * (w + 1) * (h + 1) + 1);
        let last = (h - 1) * second.stride + w - 1;
        let [.., p11] = second.quad(last).unwrap();
        assert_eq!(
            p11.to_array()[..CHANNELS],
            [i1[w * h - 1], gx[w * h - 1], gy[w * h - 1]]
        );
        assert!(second.quad(last + 1).is_none());
    }

    /// `flow` in a buffer of a pool of its own.
    fn lent(flow: &[[f32; 2]]) -> Lent<[f32; 2]> {
        let mut v = Pool::default().scratch(flow.len());
        v.copy_from_slice(flow);
        v
    }

    /// A refinement input of the images `i0` and `i1` (`w x h`).
    fn images<'a>(
        i0: &'a [f32],
        i1: &[f32],
        (w, h): (usize, usize),
        pool: &Pool,
    ) -> RefineInput<'a> {
        let (gx0, gy0) = super::super::pyramid::gradients(i0, w, h, pool);
        RefineInput {
            w,
            h,
            i0,
            gx0,
            gy0,
            second: Warpable::new(i1, (w, h), pool),
        }
    }

    #[test]
    fn edge_aware_weights_keep_a_flow_step_on_an_image_edge() {
        // A vertical image edge (0 | 100 grey) between columns 7 and 8 and a flow step
        // (0 | 1 px) on it; no data term, so only the smoothness term moves the flow
        // (measured: the step keeps 0.57 px with uniform weights, over 0.9 edge-aware).
        let (w, h) = (16, 4);
        let i0: Vec<f32> = (0..w * h)
            .map(|i| if i % w < 8 { 0.0 } else { 100.0 })
            .collect();
        let pool = Pool::default();
        let step = |edge_grey: f32| {
            let flow: Vec<[f32; 2]> = (0..w * h)
                .map(|i| [if i % w < 8 { 0.0 } else { 1.0 }, 0.0])
                .collect();
            let s = RefineSettings {
                fixed_point_iters: 2,
                sor_iters: 4,
                sor_omega: 1.6,
                alpha: 20.0,
                delta: 0.0,
                edge_grey,
            };
            let mut flow = lent(&flow);
            refine(images(&i0, &i0, (w, h), &pool), &mut flow, &s, &pool, None);
            flow[w + 8][0] - flow[w + 7][0]
        };
        let (uniform, aware) = (step(0.0), step(10.0));
        assert!(aware > 0.9, "{aware}");
        assert!(uniform < 0.7, "{uniform}");
    }

    #[test]
    fn planes_come_from_the_flow_pool_only_when_it_is_given() {
        // With the flow pool, the flow and system planes and the weights are its buffers,
        // given back holding their last values (not zeros), and the flow may come back in
        // another of its buffers; without it, the flow pool is not used. Either way the
        // refined flow is the same, also when the pools hold buffers of NaN (a value read
        // before it is written would show): odd and even sizes, one and two iterations
        // (the second warps after the weights are made), with and without edge factors.
        // With one spare buffer in the flow pool the planes take it and the weights take
        // the flow's buffer; with two, `Pool::take` picks the other spare or the flow's.
        for (w, h) in [(12, 9), (13, 8), (3, 5)] {
            let i0: Vec<f32> = (0..w * h).map(|k| ((k * 29) % 13) as f32 * 9.0).collect();
            let i1: Vec<f32> = (0..w * h).map(|k| ((k * 17) % 11) as f32 * 10.0).collect();
            let sp = Split::new(w, h);
            let pairs = (2 * sp.len(2) + 2 * sp.len(5)).div_ceil(2);
            for (fixed_point_iters, edge_grey, spares) in [1, 2]
                .into_iter()
                .flat_map(|i| [(i, 0.0), (i, 10.0)])
                .flat_map(|(i, e)| [(i, e, 1), (i, e, 2)])
            {
                let s = RefineSettings {
                    fixed_point_iters,
                    sor_iters: 2,
                    sor_omega: 1.6,
                    alpha: 20.0,
                    delta: 5.0,
                    edge_grey,
                };
                let case = format!(
                    "{w}x{h}, {fixed_point_iters} iterations, edge {edge_grey}, {spares} spares"
                );
                let refined = [false, true].map(|given| {
                    let (pool, flows) = (Pool::default(), Pool::default());
                    // As at a pyramid level: every fresh buffer has room for the planes.
                    flows.reserve_room(pairs);
                    let nan_buffer = || {
                        let mut nan = flows.scratch(pairs);
                        nan.fill([f32::NAN; 2]);
                        nan
                    };
                    // The flow in a buffer of NaN past its `w x h` values.
                    flows.put(nan_buffer());
                    let mut flow = flows.scratch(w * h);
                    for (k, f) in flow.iter_mut().enumerate() {
                        *f = [(k % 7) as f32 * 0.25 - 0.75, (k % 5) as f32 * -0.5 + 1.0];
                    }
                    let inp = images(&i0, &i1, (w, h), &pool);
                    let mut nan = pool.scratch(2 * pairs);
                    nan.fill(f32::NAN);
                    pool.put(nan);
                    let nans: Vec<_> = (0..spares).map(|_| nan_buffer()).collect();
                    for nan in nans {
                        flows.put(nan);
                    }
                    refine(inp, &mut flow, &s, &pool, given.then_some(&flows));
                    let kept: Vec<_> = (0..spares).map(|_| flows.scratch(pairs)).collect();
                    let mut written = kept.iter().flat_map(|k| k.iter().flatten());
                    assert_eq!(written.any(|v| !v.is_nan()), given, "{case}: {given}");
                    flow.iter().map(|f| f.map(f32::to_bits)).collect::<Vec<_>>()
                });
                assert_eq!(refined[0], refined[1], "{case}");
                assert!(
                    refined[0]
                        .iter()
                        .flatten()
                        .all(|&b| f32::from_bits(b).is_finite()),
                    "{case}"
                );
            }
        }
    }

    #[test]
    fn a_smooth_flow_with_no_data_stays() {
        // Flat images: no data term, constant flow is already a minimum.
        let (w, h) = (6, 5);
        let flat = vec![7.0f32; w * h];
        let pool = Pool::default();
        let mut flow = lent(&vec![[0.5f32, -1.25]; w * h]);
        let s = RefineSettings {
            fixed_point_iters: 2,
            sor_iters: 3,
            sor_omega: 1.6,
            alpha: 20.0,
            delta: 5.0,
            edge_grey: 0.0,
        };
        refine(
            images(&flat, &flat, (w, h), &pool),
            &mut flow,
            &s,
            &pool,
            None,
        );
        for v in flow.iter() {
            assert!(
                (v[0] - 0.5).abs() < 1e-6 && (v[1] + 1.25).abs() < 1e-6,
                "{v:?}"
            );
        }
    }
}
