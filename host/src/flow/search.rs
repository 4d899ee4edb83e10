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
//! Patch rows are independent tasks; within a row, a patch may start from its left
//! neighbour's result (spatial propagation) when that matches better than the coarser
//! level's flow. The result does not depend on the thread count.

use super::pyramid::Padded;
use rayon::prelude::*;

/// Top-left corners of patches of side `size` every `stride` pixels along a side of
/// `len >= size` pixels; the last patch is moved in so that it ends at the border.
pub(crate) fn positions(len: usize, size: usize, stride: usize) -> Vec<usize> {
    let last = len - size;
    let mut v: Vec<usize> = (0..=last).step_by(stride).collect();
    if v.last() != Some(&last) {
        v.push(last);
    }
    v
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
}

/// The first image of a level with its gradients (unpadded, row-major, `w x h`).
pub(crate) struct Template<'a> {
    pub w: usize,
    pub i0: &'a [f32],
    pub gx: &'a [f32],
    pub gy: &'a [f32],
}

/// Sums over one patch at one displacement.
#[derive(Debug, Clone, Copy)]
struct Stats {
    r: f32,
    gxr: f32,
    gyr: f32,
    rr: f32,
}

/// Lane-wise accumulation over the patch (4 lanes, so the loop vectorises while the
/// summation order stays fixed).
#[inline]
fn stats(
    t: &Template<'_>,
    i1: &Padded,
    px: usize,
    py: usize,
    u: f32,
    v: f32,
    size: usize,
) -> Stats {
    let tap = i1.tap(px as f32 + u, py as f32 + v, size);
    let (w00, w01, w10, w11) = (tap.w00, tap.w01, tap.w10, tap.w11);
    let mut r = [0.0f32; 4];
    let mut gxr = [0.0f32; 4];
    let mut gyr = [0.0f32; 4];
    let mut rr = [0.0f32; 4];
    for row in 0..size {
        let a = &i1.data[tap.index + row * i1.stride..][..size + 1];
        let b = &i1.data[tap.index + (row + 1) * i1.stride..][..size + 1];
        let off = (py + row) * t.w + px;
        let ti = &t.i0[off..][..size];
        let gx = &t.gx[off..][..size];
        let gy = &t.gy[off..][..size];
        let it = a[..size]
            .chunks_exact(4)
            .zip(a[1..].chunks_exact(4))
            .zip(b[..size].chunks_exact(4))
            .zip(b[1..].chunks_exact(4))
            .zip(ti.chunks_exact(4))
            .zip(gx.chunks_exact(4).zip(gy.chunks_exact(4)));
        for (((((a0, a1), b0), b1), tc), (gxc, gyc)) in it {
            for k in 0..4 {
                let d = w00 * a0[k] + w01 * a1[k] + w10 * b0[k] + w11 * b1[k] - tc[k];
                r[k] += d;
                gxr[k] += gxc[k] * d;
                gyr[k] += gyc[k] * d;
                rr[k] += d * d;
            }
        }
    }
    let sum = |s: [f32; 4]| (s[0] + s[1]) + (s[2] + s[3]);
    Stats {
        r: sum(r),
        gxr: sum(gxr),
        gyr: sum(gyr),
        rr: sum(rr),
    }
}

/// Per-patch constants: the Gauss-Newton normal matrix inverse and the mean gradient.
struct PatchModel {
    inv: [f32; 3],
    mgx: f32,
    mgy: f32,
    n: f32,
}

impl PatchModel {
    fn new(t: &Template<'_>, px: usize, py: usize, size: usize, mean_norm: bool) -> Self {
        let mut sxx = 0.0f32;
        let mut sxy = 0.0f32;
        let mut syy = 0.0f32;
        let mut sx = 0.0f32;
        let mut sy = 0.0f32;
        for row in 0..size {
            let off = (py + row) * t.w + px;
            for (&gx, &gy) in t.gx[off..][..size].iter().zip(&t.gy[off..][..size]) {
                sxx += gx * gx;
                sxy += gx * gy;
                syy += gy * gy;
                sx += gx;
                sy += gy;
            }
        }
        let n = (size * size) as f32;
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
        Self { inv, mgx, mgy, n }
    }

    /// SSD at a displacement from its stats (mean-normalised when the model is).
    fn ssd(&self, s: &Stats, mean_norm: bool) -> f32 {
        if mean_norm {
            s.rr - s.r * s.r / self.n
        } else {
            s.rr
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

/// Searches every patch of one level. `init` is the dense flow (`w x h`) the search starts
/// from (the coarser level's result, zero at the coarsest). Returns one [`PatchFlow`] per
/// grid patch, row-major over `(ys, xs)`.
pub(crate) fn search_level(
    t: &Template<'_>,
    i1: &Padded,
    init: &[[f32; 2]],
    xs: &[usize],
    ys: &[usize],
    s: &SearchSettings,
) -> Vec<PatchFlow> {
    let mut out = vec![PatchFlow::default(); xs.len() * ys.len()];
    let size = s.size;
    let mn = s.mean_normalization;
    let stop2 = s.stop_px * s.stop_px;
    out.par_chunks_mut(xs.len())
        .zip(ys.par_iter())
        .for_each(|(row_out, &py)| {
            let mut left: Option<(f32, f32)> = None;
            for (o, &px) in row_out.iter_mut().zip(xs) {
                let model = PatchModel::new(t, px, py, size, mn);
                let c = init[(py + size / 2) * t.w + px + size / 2];
                let (mut u, mut v) = (c[0], c[1]);
                let mut st = stats(t, i1, px, py, u, v, size);
                let mut best = (model.ssd(&st, mn), u, v, st.r);
                if let Some((lu, lv)) = left.filter(|_| s.propagation) {
                    let ls = stats(t, i1, px, py, lu, lv, size);
                    let e = model.ssd(&ls, mn);
                    if e < best.0 {
                        best = (e, lu, lv, ls.r);
                        (u, v, st) = (lu, lv, ls);
                    }
                }
                for _ in 0..s.iters {
                    let (du, dv) = model.step(&st, mn);
                    u -= du;
                    v -= dv;
                    st = stats(t, i1, px, py, u, v, size);
                    let e = model.ssd(&st, mn);
                    if e < best.0 {
                        best = (e, u, v, st.r);
                    }
                    if du * du + dv * dv < stop2 {
                        break;
                    }
                }
                let (_, bu, bv, br) = best;
                *o = PatchFlow {
                    u: bu,
                    v: bv,
                    offset: if mn { br / model.n } else { 0.0 },
                };
                left = Some((bu, bv));
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_cover_the_side() {
        assert_eq!(positions(20, 8, 4), vec![0, 4, 8, 12]);
        assert_eq!(positions(21, 8, 4), vec![0, 4, 8, 12, 13]);
        assert_eq!(positions(8, 8, 3), vec![0]);
    }
}
