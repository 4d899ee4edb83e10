//! Patch inverse search (DIS, Kroeger et al. 2016, section 2.1): on one pyramid level, each
//! patch of a regular grid on the first image finds the translation that best matches the
//! second image, by inverse-compositional Gauss-Newton on the patch SSD.
//!
//! Inverse compositional: the Jacobian and the 2x2 Hessian come from the *first* image's
//! gradients, so they are computed once per patch; each iteration only warps the second
//! image. The warp is a pure translation, so one set of bilinear weights serves the whole
//! patch. With mean normalisation the SSD is taken after subtracting each patch's mean
//! (robust to brightness change). Iterations stop early once a step is shorter than
//! `stop_px`; the patch keeps the lowest-SSD estimate it saw (the initial guess included).
//!
//! Spatial propagation (as in DIS): after the first descent, four sweeps (rightwards along
//! rows, downwards along columns, leftwards, upwards) let each patch restart from its
//! predecessor's flow when that matches better. Each sweep runs its lines as independent
//! tasks and each line in order, so the result does not depend on the thread count.

use super::pyramid::Padded;
use crate::par::*;
use wide::f32x4;

/// Top-left corners of patches of side `size` every `stride` pixels along a side of
/// `len >= size` pixels, into `out`; the last patch is moved in so that it ends at the
/// border.
pub(crate) fn positions(len: usize, size: usize, stride: usize, out: &mut Vec<usize>) {
    let last = len - size;
    out.clear();
    out.extend((0..=last).step_by(stride));
    if out.last() != Some(&last) {
        out.push(last);
    }
}

/// The patch grid of one level: top-left corners along x and y, and the patch side.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Grid<'a> {
    pub xs: &'a [usize],
    pub ys: &'a [usize],
    pub size: usize,
}

/// One patch's result: its flow and the mean of `second - first` over the patch at that
/// flow (the brightness offset mean normalisation removes; zero without it).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PatchFlow {
    pub u: f32,
    pub v: f32,
    pub offset: f32,
}

/// Settings of one level's search.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SearchSettings {
    /// Patch side, pixels; a multiple of 4.
    pub size: usize,
    pub iters: usize,
    pub stop_px: f32,
    pub mean_normalization: bool,
    pub propagation: bool,
    /// Weight of the anchor penalty `anchor · n · |d - d_start|²` added to a patch's SSD
    /// (`n` pixels, `d_start` the flow the patch started from); 0 = none.
    pub anchor: f32,
    /// Flows every patch also starts from after its own search (from a motion hint, pixels
    /// of the level; the first `candidates.0` entries); the patch keeps the best, refined,
    /// if it matches better.
    pub candidates: (usize, [[f32; 2]; MAX_CANDIDATES]),
}

/// Most hint candidates one level tries per patch.
pub(crate) const MAX_CANDIDATES: usize = 4;

/// The first image of a level with its gradients (unpadded, row-major, `w x h`).
pub(crate) struct Template<'a> {
    pub w: usize,
    pub i0: &'a [f32],
    pub gx: &'a [f32],
    pub gy: &'a [f32],
}

/// The buffers of one level's search, kept by the estimator between levels and estimates
/// (their contents are garbage between calls): the per-patch constants and states, row-
/// major over the grid, and both transposed for the column sweeps of the propagation.
#[derive(Debug, Default)]
pub(crate) struct SearchScratch {
    models: Vec<PatchModel>,
    models_t: Vec<PatchModel>,
    state: Vec<State>,
    state_t: Vec<State>,
}

impl SearchScratch {
    /// Room for `patches` patches in every buffer (their contents are dropped). Reserved
    /// for the finest grid before the coarsest level, each buffer is allocated once
    /// instead of once per level: the coarser levels' allocations would be faulted in and
    /// then left behind.
    pub(crate) fn reserve(&mut self, patches: usize) {
        clear_with_room(&mut self.models, patches);
        clear_with_room(&mut self.models_t, patches);
        clear_with_room(&mut self.state, patches);
        clear_with_room(&mut self.state_t, patches);
    }
}

/// `v` emptied, with room for `len` values.
pub(crate) fn clear_with_room<T>(v: &mut Vec<T>, len: usize) {
    v.clear();
    v.reserve(len);
}

/// `out` made to hold exactly `items` (`len` of them): grown at most once, by one
/// reservation of room for at least `len` (`Vec::reserve` may allocate more), and never
/// by the copies of repeated doubling (each copy faults in fresh pages).
pub(crate) fn refill<T>(out: &mut Vec<T>, len: usize, items: impl Iterator<Item = T>) {
    clear_with_room(out, len);
    out.extend(items);
}

/// Sums over one patch at one displacement.
#[derive(Debug, Clone, Copy)]
struct Stats {
    r: f32,
    gxr: f32,
    gyr: f32,
    rr: f32,
}

/// Largest patch side the search supports (`FlowParams` validates against it).
pub(crate) const MAX_PATCH_PX: usize = 32;

/// Lanes of the patch loops: patch sides are multiples of 4, so every patch row splits into
/// [`f32x4`] groups.
pub(crate) const LANES: usize = 4;

/// Runs `$body` with the const `$n` set to the patch side `$size` (a multiple of 4 in
/// `4..=32`, as `FlowParams` validates; anything else runs as 32), so that every loop over
/// a patch has a length known at compile time.
macro_rules! with_patch_size {
    ($size:expr, $n:ident => $body:expr) => {
        match $size {
            4 => {
                const $n: usize = 4;
                $body
            }
            8 => {
                const $n: usize = 8;
                $body
            }
            12 => {
                const $n: usize = 12;
                $body
            }
            16 => {
                const $n: usize = 16;
                $body
            }
            20 => {
                const $n: usize = 20;
                $body
            }
            24 => {
                const $n: usize = 24;
                $body
            }
            28 => {
                const $n: usize = 28;
                $body
            }
            _ => {
                const $n: usize = 32;
                $body
            }
        }
    };
}
pub(crate) use with_patch_size;

/// The first `N` values of `s` as lane groups.
#[inline]
pub(crate) fn lanes<const N: usize>(s: &[f32]) -> &[[f32; LANES]] {
    s[..N].as_chunks::<LANES>().0
}

/// The first `N` values of `s` as mutable lane groups.
#[inline]
pub(crate) fn lanes_mut<const N: usize>(s: &mut [f32]) -> &mut [[f32; LANES]] {
    s[..N].as_chunks_mut::<LANES>().0
}

/// Sums over the `N x N` patch. Column-wise accumulators (one lane per column) keep the
/// summation order fixed: each column sums its rows top to bottom, then the columns are
/// added left to right.
#[inline]
fn stats<const N: usize>(
    t: &Template<'_>,
    i1: &Padded,
    (px, py): (usize, usize),
    (u, v): (f32, f32),
) -> Stats {
    let tap = i1.tap(px as f32 + u, py as f32 + v, N);
    let [w00, w01, w10, w11] = [tap.w00, tap.w01, tap.w10, tap.w11].map(f32x4::splat);
    // The three planes cut to one length, so that one bounds check serves all three rows.
    let len = t.i0.len().min(t.gx.len()).min(t.gy.len());
    let (i0, gx, gy) = (&t.i0[..len], &t.gx[..len], &t.gy[..len]);
    // Row `k` of the block of I1 the samples read, as lane groups from its first and its
    // second value; each row serves as the lower row of one patch row and the upper of
    // the next.
    let block = |k: usize| {
        let s = &i1.data[tap.index + k * i1.stride..][..=N];
        (lanes::<N>(s), lanes::<N>(&s[1..]))
    };
    // Per lane group: the column sums of r, gx·r, gy·r and r².
    let mut acc = [[f32x4::ZERO; 4]; MAX_PATCH_PX / LANES];
    let acc = &mut acc[..N / LANES];
    let mut upper = block(0);
    for row in 0..N {
        let lower = block(row + 1);
        let off = (py + row) * t.w + px;
        let (ti, gx, gy) = (
            lanes::<N>(&i0[off..]),
            lanes::<N>(&gx[off..]),
            lanes::<N>(&gy[off..]),
        );
        for (g, [r, gxr, gyr, rr]) in acc.iter_mut().enumerate() {
            let at = |s: &[[f32; LANES]]| f32x4::new(s[g]);
            let d = w00 * at(upper.0) + w01 * at(upper.1) + w10 * at(lower.0) + w11 * at(lower.1)
                - at(ti);
            *r += d;
            *gxr += at(gx) * d;
            *gyr += at(gy) * d;
            *rr += d * d;
        }
        upper = lower;
    }
    // The four sums side by side: each group's lanes, transposed, are added in column
    // order (the order of a sequential sum over the columns).
    let mut sum = f32x4::splat(-0.0);
    for a in acc.iter() {
        for column in f32x4::transpose(*a) {
            sum += column;
        }
    }
    let [r, gxr, gyr, rr] = sum.to_array();
    Stats { r, gxr, gyr, rr }
}

/// Per-patch constants: the Gauss-Newton normal matrix inverse and the mean gradient.
#[derive(Debug, Clone, Copy, Default)]
struct PatchModel {
    inv: [f32; 3],
    mgx: f32,
    mgy: f32,
    n: f32,
    /// The flow the patch starts from (the anchor's centre).
    start: [f32; 2],
}

impl PatchModel {
    fn new<const N: usize>(t: &Template<'_>, px: usize, py: usize, mean_norm: bool) -> Self {
        // Column-wise sums (one lane per column), then a fixed-order total.
        let mut cols = [[f32x4::ZERO; 5]; MAX_PATCH_PX / LANES];
        let cols = &mut cols[..N / LANES];
        // Both planes cut to one length: one bounds check serves both rows.
        let len = t.gx.len().min(t.gy.len());
        let (gx, gy) = (&t.gx[..len], &t.gy[..len]);
        for row in 0..N {
            let off = (py + row) * t.w + px;
            let (gx, gy) = (lanes::<N>(&gx[off..]), lanes::<N>(&gy[off..]));
            for (g, [cxx, cxy, cyy, cx, cy]) in cols.iter_mut().enumerate() {
                let (gx, gy) = (f32x4::new(gx[g]), f32x4::new(gy[g]));
                *cxx += gx * gx;
                *cxy += gx * gy;
                *cyy += gy * gy;
                *cx += gx;
                *cy += gy;
            }
        }
        let [sxx, sxy, syy, sx, sy] =
            core::array::from_fn(|j| cols.iter().flat_map(|c| c[j].to_array()).sum::<f32>());
        let n = (N * N) as f32;
        let (mgx, mgy) = if mean_norm {
            (sx / n, sy / n)
        } else {
            (0.0, 0.0)
        };
        let hxx = sxx - n * mgx * mgx;
        let hxy = sxy - n * mgx * mgy;
        let hyy = syy - n * mgy * mgy;
        // Tikhonov term (gradient units squared per pixel): keeps flat patches still.
        let reg = 1e-2 * n;
        let (a, b, c) = (hxx + reg, hxy, hyy + reg);
        let det = a * c - b * b;
        let inv = if det > 0.0 && det.is_finite() {
            [c / det, -b / det, a / det]
        } else {
            [0.0; 3]
        };
        Self {
            inv,
            mgx,
            mgy,
            n,
            start: [0.0; 2],
        }
    }

    /// SSD at a displacement from its stats (mean-normalised when the model is), for the
    /// model's `N x N` patch. Where `n = N²` is a power of two, `r² / n` is the product
    /// with `1 / n`, bit for bit, without a division's latency on every evaluation.
    fn ssd<const N: usize>(&self, s: &Stats, mean_norm: bool) -> f32 {
        if !mean_norm {
            return s.rr;
        }
        let square = s.r * s.r;
        if (N * N).is_power_of_two() {
            s.rr - square * (1.0 / (N * N) as f32)
        } else {
            s.rr - square / self.n
        }
    }

    /// The Gauss-Newton step (to subtract from the displacement).
    fn step(&self, s: &Stats, mean_norm: bool) -> (f32, f32) {
        let (bx, by) = if mean_norm {
            (s.gxr - self.mgx * s.r, s.gyr - self.mgy * s.r)
        } else {
            (s.gxr, s.gyr)
        };
        (
            self.inv[0] * bx + self.inv[1] * by,
            self.inv[1] * bx + self.inv[2] * by,
        )
    }
}

/// The anchor penalty of a patch at flow `(u, v)`: `anchor · n · |(u, v) - start|²`, in the
/// units of the SSD. On look-alike objects (a row of identical boxes) a shift by one
/// object's width matches about as well as the true small motion; at the coarse levels,
/// where a patch covers several objects and their texture is blurred away, a search or a
/// neighbour's flow can land on such a copy, and the finer levels cannot undo it. The
/// penalty makes a patch leave its starting flow only for a clearly better match.
fn anchor_penalty(m: &PatchModel, anchor: f32, u: f32, v: f32) -> f32 {
    let (du, dv) = (u - m.start[0], v - m.start[1]);
    anchor * m.n * (du * du + dv * dv)
}

/// A neighbour's flow closer than this (pixels of the level) to a patch's own is not
/// worth an evaluation.
const PROPAGATION_MIN_PX: f32 = 0.05;

/// Everything one search of `N x N` patches needs besides a patch's position and start.
struct Ctx<'a, const N: usize> {
    t: &'a Template<'a>,
    i1: &'a Padded,
    s: &'a SearchSettings,
}

/// A patch's current estimate and its SSD there.
#[derive(Debug, Clone, Copy, Default)]
struct State {
    u: f32,
    v: f32,
    ssd: f32,
    /// Sum of residuals at `(u, v)` (for the brightness offset).
    r: f32,
}

impl<const N: usize> Ctx<'_, N> {
    fn eval(&self, m: &PatchModel, px: usize, py: usize, u: f32, v: f32) -> (State, Stats) {
        let st = stats::<N>(self.t, self.i1, (px, py), (u, v));
        let mut ssd = m.ssd::<N>(&st, self.s.mean_normalization);
        if self.s.anchor > 0.0 {
            ssd += anchor_penalty(m, self.s.anchor, u, v);
        }
        (State { u, v, ssd, r: st.r }, st)
    }

    /// Gauss-Newton from `start` (with its stats); returns the lowest-SSD point visited.
    fn descend(&self, m: &PatchModel, px: usize, py: usize, start: State, st: Stats) -> State {
        let mn = self.s.mean_normalization;
        let stop2 = self.s.stop_px * self.s.stop_px;
        let (mut best, mut st, mut u, mut v) = (start, st, start.u, start.v);
        for _ in 0..self.s.iters {
            let (du, dv) = m.step(&st, mn);
            u -= du;
            v -= dv;
            let (cur, next) = self.eval(m, px, py, u, v);
            st = next;
            if cur.ssd < best.ssd {
                best = cur;
            }
            if du * du + dv * dv < stop2 {
                break;
            }
        }
        best
    }

    /// Tries a neighbour's flow: if it matches better, the patch restarts from it.
    fn propagate(&self, m: &PatchModel, px: usize, py: usize, cur: State, cand: State) -> State {
        let (du, dv) = (cand.u - cur.u, cand.v - cur.v);
        if du * du + dv * dv <= PROPAGATION_MIN_PX * PROPAGATION_MIN_PX {
            return cur;
        }
        let (c, st) = self.eval(m, px, py, cand.u, cand.v);
        if c.ssd < cur.ssd {
            let d = self.descend(m, px, py, c, st);
            if d.ssd < cur.ssd {
                return d;
            }
        }
        cur
    }

    /// Tries the hint `c` as a second hypothesis with its own anchor centre: if the
    /// images match better there than at `cur` (whose SSD carries the anchor around the
    /// patch's start), the patch descends from it and keeps the better result.
    fn try_hint(&self, m: &PatchModel, px: usize, py: usize, cur: State, c: [f32; 2]) -> State {
        let (du, dv) = (c[0] - cur.u, c[1] - cur.v);
        if du * du + dv * dv <= PROPAGATION_MIN_PX * PROPAGATION_MIN_PX {
            return cur;
        }
        let m = PatchModel { start: c, ..*m };
        let (h, st) = self.eval(&m, px, py, c[0], c[1]);
        if h.ssd < cur.ssd {
            let d = self.descend(&m, px, py, h, st);
            if d.ssd < cur.ssd {
                return d;
            }
        }
        cur
    }
}

/// Searches every patch of one level. `init` is the dense flow (`w x h`) the search starts
/// from (the coarser level's result, zero at the coarsest). Writes one [`PatchFlow`] per
/// grid patch, row-major over `(ys, xs)`, into `out`.
///
/// With `s.anchor > 0` every SSD a patch compares carries [`anchor_penalty`] around the
/// flow of `init` at its centre.
///
/// Each patch first descends from `init` at its centre, trying its left neighbour's result
/// as well when propagation is on. With propagation, three more passes follow (downwards
/// along columns, leftwards along rows, upwards along columns): a patch whose neighbour's
/// flow matches better restarts from it. Each pass runs its lines in parallel and each
/// line in order, so the result does not depend on the thread count.
#[allow(clippy::too_many_arguments)] // the level's inputs, settings, scratch and output
pub(crate) fn search_level(
    t: &Template<'_>,
    i1: &Padded,
    init: &[[f32; 2]],
    grid: &Grid<'_>,
    s: &SearchSettings,
    scratch: &mut SearchScratch,
    out: &mut Vec<PatchFlow>,
) {
    with_patch_size!(s.size, N => search_level_n::<N>(t, i1, init, grid, s, scratch, out));
}

/// [`search_level`] for patches of side `N` (`s.size`).
fn search_level_n<const N: usize>(
    t: &Template<'_>,
    i1: &Padded,
    init: &[[f32; 2]],
    &Grid { xs, ys, .. }: &Grid<'_>,
    s: &SearchSettings,
    scratch: &mut SearchScratch,
    out: &mut Vec<PatchFlow>,
) {
    let (nx, ny) = (xs.len(), ys.len());
    let size = N;
    let mn = s.mean_normalization;
    let ctx = Ctx::<N> { t, i1, s };
    let SearchScratch {
        models,
        models_t,
        state,
        state_t,
    } = scratch;
    refill(
        models,
        nx * ny,
        ys.iter()
            .flat_map(|&py| xs.iter().map(move |&px| (px, py)))
            .map(|(px, py)| {
                let mut m = PatchModel::new::<N>(t, px, py, mn);
                m.start = init[(py + size / 2) * t.w + px + size / 2];
                m
            }),
    );
    // Every state is written by pass 1.
    refill(
        state,
        nx * ny,
        core::iter::repeat_n(State::default(), nx * ny),
    );
    // Pass 1: rows, left to right, from the coarser level's flow.
    state
        .par_chunks_mut(nx)
        .zip(models.par_chunks(nx))
        .zip(ys.par_iter())
        .for_each(|((row, ms), &py)| {
            let mut left: Option<State> = None;
            for ((o, m), &px) in row.iter_mut().zip(ms).zip(xs) {
                let c = init[(py + size / 2) * t.w + px + size / 2];
                let (start, st) = ctx.eval(m, px, py, c[0], c[1]);
                let mut cur = ctx.descend(m, px, py, start, st);
                if let Some(l) = left.filter(|_| s.propagation) {
                    cur = ctx.propagate(m, px, py, cur, l);
                }
                for &h in s.candidates.1.iter().take(s.candidates.0) {
                    cur = ctx.try_hint(m, px, py, cur, h);
                }
                *o = cur;
                left = Some(cur);
            }
        });
    if s.propagation {
        // Pass 2 and 4 work on columns: transpose, sweep, transpose back.
        transpose(state, nx, ny, state_t);
        transpose(models, nx, ny, models_t);
        sweep_lines(&ctx, state_t, models_t, ny, |j, i| (xs[j], ys[i]), false);
        transpose(state_t, ny, nx, state);
        sweep_lines(&ctx, state, models, nx, |j, i| (xs[i], ys[j]), true);
        transpose(state, nx, ny, state_t);
        sweep_lines(&ctx, state_t, models_t, ny, |j, i| (xs[j], ys[i]), true);
        transpose(state_t, ny, nx, state);
    }
    refill(
        out,
        nx * ny,
        state.iter().zip(models.iter()).map(|(st, m)| PatchFlow {
            u: st.u,
            v: st.v,
            offset: if mn { st.r / m.n } else { 0.0 },
        }),
    );
}

/// One propagation pass over lines of `len` patches (line `j`, position `i` is the patch
/// at `pos(j, i)`), forwards or backwards along each line, lines in parallel.
fn sweep_lines<const N: usize>(
    ctx: &Ctx<'_, N>,
    state: &mut [State],
    models: &[PatchModel],
    len: usize,
    pos: impl Fn(usize, usize) -> (usize, usize) + Sync,
    backwards: bool,
) {
    state
        .par_chunks_mut(len)
        .zip(models.par_chunks(len))
        .enumerate()
        .for_each(|(j, (line, ms))| {
            // Forwards: positions 1, 2, ..., len - 1, each after its predecessor;
            // backwards: len - 2, ..., 0, each after its successor.
            for step in 1..len {
                let (i, prev) = if backwards {
                    (len - 1 - step, len - step)
                } else {
                    (step, step - 1)
                };
                let (px, py) = pos(j, i);
                line[i] = ctx.propagate(&ms[i], px, py, line[i], line[prev]);
            }
        });
}

/// `rows x cols` row-major into `cols x rows` row-major, in `out`.
fn transpose<T: Copy>(a: &[T], cols: usize, rows: usize, out: &mut Vec<T>) {
    refill(
        out,
        cols * rows,
        (0..cols).flat_map(|c| (0..rows).map(move |r| a[r * cols + c])),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_cover_the_side() {
        let mut v = vec![7; 9];
        positions(20, 8, 4, &mut v);
        assert_eq!(v, [0, 4, 8, 12]);
        positions(21, 8, 4, &mut v);
        assert_eq!(v, [0, 4, 8, 12, 13]);
        positions(8, 8, 3, &mut v);
        assert_eq!(v, [0]);
    }
}
