//! Variational refinement (DIS, section 2.3): a few fixed-point iterations that lower
//!
//! ```text
//! E(u) = Σ_x  δ·Ψ((I1(x + u) − I0(x))²)  +  α·Ψ(|∇u_x|² + |∇u_y|²),   Ψ(s²) = √(s² + ε²)
//! ```
//!
//! Each outer iteration warps the second image by the current flow, linearises the data
//! term (`Iz + Ix·du + Iy·dv`, gradients averaged over both images), freezes the robust
//! weights (lagged diffusivity) and solves the resulting sparse linear system for the
//! increment `(du, dv)` with a few red-black SOR sweeps, then adds the increment.
//! Pixels warped outside the second image keep only the smoothness term.
//!
//! Red-black order makes every half-sweep a set of independent pixel updates, so rows run
//! in parallel and the result does not depend on the thread count. To keep those updates
//! contiguous, the solver stores each colour (`(x + y) mod 2`) in its own plane:
//! pixel `(x, y)` lives at row `y + 1`, slot `x / 2 + 1` of plane `(x + y) mod 2`, with a
//! zero guard row/slot on every side. All four neighbours of a pixel lie in the other
//! plane, at slots `k + s`, `k + s + 1` (left, right; `s = (x + y) mod 2` of the *plane
//! row*, `k = x / 2`) and slot `k + 1` of the rows above and below.

use super::pyramid::Padded;
use rayon::prelude::*;

/// Settings of the refinement.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RefineSettings {
    pub outer_iters: usize,
    pub sor_iters: usize,
    pub sor_omega: f32,
    pub alpha: f32,
    pub delta: f32,
}

/// Charbonnier epsilon of the data term, intensity units (0-255 scale).
const EPS_DATA: f32 = 1.0;
/// Charbonnier epsilon of the smoothness term, pixels per pixel.
const EPS_SMOOTH: f32 = 0.05;

/// The level's images the refinement reads.
pub(crate) struct RefineInput<'a> {
    pub w: usize,
    pub h: usize,
    pub i0: &'a [f32],
    pub gx0: &'a [f32],
    pub gy0: &'a [f32],
    /// The second image and its gradients, padded alike (one tap serves all three).
    pub i1: &'a Padded,
    pub gx1: &'a Padded,
    pub gy1: &'a Padded,
}

/// Geometry of the two colour planes.
#[derive(Debug, Clone, Copy)]
struct Split {
    w: usize,
    h: usize,
    /// Plane row stride: `ceil(w / 2)` slots plus two guards.
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

    fn len(&self) -> usize {
        self.ps * (self.h + 2)
    }

    /// Parity `s` of plane `c`'s row `y`: its pixels sit at `x = 2k + s`.
    fn parity(c: usize, y: usize) -> usize {
        (c + y) & 1
    }

    /// Pixels in plane `c`'s row `y`.
    fn count(&self, c: usize, y: usize) -> usize {
        (self.w + 1 - Self::parity(c, y)) / 2
    }
}

/// Frozen per-pixel system of one outer iteration:
/// `a11·du + a12·dv − Σ w_q·du_q = b1`, `a12·du + a22·dv − Σ w_q·dv_q = b2`.
#[derive(Debug, Clone, Copy, Default)]
struct Coef {
    /// Edge weights to the left, right, upper and lower neighbours (0 across the border).
    wl: f32,
    wr: f32,
    wu: f32,
    wd: f32,
    a12: f32,
    inv11: f32,
    inv22: f32,
    b1: f32,
    b2: f32,
}

/// Refines `flow` (`w x h`, row-major) in place.
pub(crate) fn refine(inp: &RefineInput<'_>, flow: &mut [[f32; 2]], s: &RefineSettings) {
    if s.outer_iters == 0 {
        return;
    }
    let sp = Split::new(inp.w, inp.h);
    let mut uv = [vec![[0.0f32; 2]; sp.len()], vec![[0.0f32; 2]; sp.len()]];
    let mut duv = [vec![[0.0f32; 2]; sp.len()], vec![[0.0f32; 2]; sp.len()]];
    let mut psi = [vec![0.0f32; sp.len()], vec![0.0f32; sp.len()]];
    let mut coef = [
        vec![Coef::default(); sp.len()],
        vec![Coef::default(); sp.len()],
    ];
    scatter(&sp, flow, &mut uv);
    for _ in 0..s.outer_iters {
        for (c, p) in psi.iter_mut().enumerate() {
            smoothness_weights(&sp, c, &uv, p, s.alpha);
        }
        for (c, cf) in coef.iter_mut().enumerate() {
            build_system(&sp, c, inp, &uv, &psi, cf, s.delta);
        }
        for d in &mut duv {
            d.fill([0.0; 2]);
        }
        for _ in 0..s.sor_iters {
            for (c, cf) in coef.iter().enumerate() {
                let (mine, other) = if c == 0 {
                    let (a, b) = duv.split_at_mut(1);
                    (&mut a[0], &b[0])
                } else {
                    let (a, b) = duv.split_at_mut(1);
                    (&mut b[0], &a[0])
                };
                sor_half_sweep(&sp, c, cf, mine, other, s.sor_omega);
            }
        }
        for (u, d) in uv.iter_mut().zip(&duv) {
            for (a, b) in u.iter_mut().zip(d) {
                a[0] += b[0];
                a[1] += b[1];
            }
        }
    }
    gather(&sp, &uv, flow);
}

/// Row-major flow into the two colour planes.
fn scatter(sp: &Split, flow: &[[f32; 2]], uv: &mut [Vec<[f32; 2]>; 2]) {
    for (c, plane) in uv.iter_mut().enumerate() {
        for y in 0..sp.h {
            let s = Split::parity(c, y);
            let row = &mut plane[(y + 1) * sp.ps + 1..][..sp.count(c, y)];
            let src = &flow[y * sp.w..][..sp.w];
            for (k, o) in row.iter_mut().enumerate() {
                *o = src[2 * k + s];
            }
        }
    }
}

/// The two colour planes back into a row-major flow.
fn gather(sp: &Split, uv: &[Vec<[f32; 2]>; 2], flow: &mut [[f32; 2]]) {
    for (c, plane) in uv.iter().enumerate() {
        for y in 0..sp.h {
            let s = Split::parity(c, y);
            let row = &plane[(y + 1) * sp.ps + 1..][..sp.count(c, y)];
            let dst = &mut flow[y * sp.w..][..sp.w];
            for (k, v) in row.iter().enumerate() {
                dst[2 * k + s] = *v;
            }
        }
    }
}

/// `α / √(|∇u|² + |∇v|² + ε²)` for every pixel of plane `c` (forward differences, zero
/// across the border).
fn smoothness_weights(sp: &Split, c: usize, uv: &[Vec<[f32; 2]>; 2], psi: &mut [f32], alpha: f32) {
    let (mine, other) = (&uv[c], &uv[1 - c]);
    let ps = sp.ps;
    psi[ps..(sp.h + 1) * ps]
        .par_chunks_mut(ps)
        .enumerate()
        .for_each(|(y, out)| {
            let s = Split::parity(c, y);
            let row = (y + 1) * ps;
            for k in 0..sp.count(c, y) {
                let x = 2 * k + s;
                let p = mine[row + k + 1];
                let mut g2 = EPS_SMOOTH * EPS_SMOOTH;
                if x + 1 < sp.w {
                    let r = other[row + k + s + 1];
                    g2 += (r[0] - p[0]).powi(2) + (r[1] - p[1]).powi(2);
                }
                if y + 1 < sp.h {
                    let d = other[row + ps + k + 1];
                    g2 += (d[0] - p[0]).powi(2) + (d[1] - p[1]).powi(2);
                }
                out[k + 1] = alpha / g2.sqrt();
            }
        });
}

/// Linearises the energy around the current flow for every pixel of plane `c`.
fn build_system(
    sp: &Split,
    c: usize,
    inp: &RefineInput<'_>,
    uv: &[Vec<[f32; 2]>; 2],
    psi: &[Vec<f32>; 2],
    coef: &mut [Coef],
    delta: f32,
) {
    let (mine, other) = (&uv[c], &uv[1 - c]);
    let (psi_mine, psi_other) = (&psi[c], &psi[1 - c]);
    let ps = sp.ps;
    let (wmax, hmax) = ((sp.w - 1) as f32, (sp.h - 1) as f32);
    coef[ps..(sp.h + 1) * ps]
        .par_chunks_mut(ps)
        .enumerate()
        .for_each(|(y, out)| {
            let s = Split::parity(c, y);
            let row = (y + 1) * ps;
            for k in 0..sp.count(c, y) {
                let x = 2 * k + s;
                let o = row + k;
                let p = mine[o + 1];
                let own = psi_mine[o + 1];
                let wl = psi_other[o + s];
                let wr = if x + 1 < sp.w { own } else { 0.0 };
                let wu = psi_other[o + 1 - ps];
                let wd = if y + 1 < sp.h { own } else { 0.0 };
                let nl = other[o + s];
                let nr = other[o + s + 1];
                let nu = other[o + 1 - ps];
                let nd = other[o + 1 + ps];
                let su = wl * (nl[0] - p[0])
                    + wr * (nr[0] - p[0])
                    + wu * (nu[0] - p[0])
                    + wd * (nd[0] - p[0]);
                let sv = wl * (nl[1] - p[1])
                    + wr * (nr[1] - p[1])
                    + wu * (nu[1] - p[1])
                    + wd * (nd[1] - p[1]);
                let wsum = wl + wr + wu + wd;
                let i = y * sp.w + x;
                let (xw, yw) = (x as f32 + p[0], y as f32 + p[1]);
                let (mut a11, mut a12, mut a22, mut b1, mut b2) = (wsum, 0.0, wsum, su, sv);
                if (0.0..=wmax).contains(&xw) && (0.0..=hmax).contains(&yw) {
                    let tap = inp.i1.tap(xw, yw, 1);
                    let iz = inp.i1.sample_at(&tap) - inp.i0[i];
                    let ix = 0.5 * (inp.gx1.sample_at(&tap) + inp.gx0[i]);
                    let iy = 0.5 * (inp.gy1.sample_at(&tap) + inp.gy0[i]);
                    let pd = delta / (iz * iz + EPS_DATA * EPS_DATA).sqrt();
                    a11 += pd * ix * ix;
                    a12 = pd * ix * iy;
                    a22 += pd * iy * iy;
                    b1 -= pd * ix * iz;
                    b2 -= pd * iy * iz;
                }
                let inv = |a: f32| if a > 0.0 { 1.0 / a } else { 0.0 };
                out[k + 1] = Coef {
                    wl,
                    wr,
                    wu,
                    wd,
                    a12,
                    inv11: inv(a11),
                    inv22: inv(a22),
                    b1,
                    b2,
                };
            }
        });
}

/// One SOR update of every pixel of plane `c` (its neighbours, in `other`, stay fixed).
fn sor_half_sweep(
    sp: &Split,
    c: usize,
    coef: &[Coef],
    mine: &mut [[f32; 2]],
    other: &[[f32; 2]],
    omega: f32,
) {
    let ps = sp.ps;
    mine[ps..(sp.h + 1) * ps]
        .par_chunks_mut(ps)
        .enumerate()
        .for_each(|(y, out)| {
            let s = Split::parity(c, y);
            let n = sp.count(c, y);
            let row = (y + 1) * ps;
            let cf = &coef[row + 1..][..n];
            let left = &other[row + s..][..n];
            let right = &other[row + s + 1..][..n];
            let up = &other[row - ps + 1..][..n];
            let down = &other[row + ps + 1..][..n];
            let it = out[1..=n]
                .iter_mut()
                .zip(cf)
                .zip(left.iter().zip(right))
                .zip(up.iter().zip(down));
            for (((d, q), (l, r)), (u, dn)) in it {
                let nu = q.wl * l[0] + q.wr * r[0] + q.wu * u[0] + q.wd * dn[0];
                let nv = q.wl * l[1] + q.wr * r[1] + q.wu * u[1] + q.wd * dn[1];
                let du = d[0] + omega * ((q.b1 + nu - q.a12 * d[1]) * q.inv11 - d[0]);
                let dv = d[1] + omega * ((q.b2 + nv - q.a12 * du) * q.inv22 - d[1]);
                *d = [du, dv];
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_round_trip_and_neighbours() {
        for (w, h) in [(5, 3), (4, 4), (1, 1), (1, 2)] {
            let sp = Split::new(w, h);
            let flow: Vec<[f32; 2]> = (0..w * h).map(|i| [i as f32, -(i as f32)]).collect();
            let mut uv = [vec![[0.0; 2]; sp.len()], vec![[0.0; 2]; sp.len()]];
            scatter(&sp, &flow, &mut uv);
            let mut back = vec![[9.0; 2]; w * h];
            gather(&sp, &uv, &mut back);
            assert_eq!(back, flow);
            // The slots named in the module docs hold the four neighbours.
            for y in 0..h {
                for x in 0..w {
                    let c = (x + y) & 1;
                    let s = Split::parity(c, y);
                    let o = (y + 1) * sp.ps + x / 2;
                    let other = &uv[1 - c];
                    if x > 0 {
                        assert_eq!(other[o + s][0], (y * w + x - 1) as f32);
                    }
                    if x + 1 < w {
                        assert_eq!(other[o + s + 1][0], (y * w + x + 1) as f32);
                    }
                    if y > 0 {
                        assert_eq!(other[o + 1 - sp.ps][0], ((y - 1) * w + x) as f32);
                    }
                    if y + 1 < h {
                        assert_eq!(other[o + 1 + sp.ps][0], ((y + 1) * w + x) as f32);
                    }
                }
            }
        }
    }
}
