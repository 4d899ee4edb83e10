//! Densification (DIS, section 2.2): each pixel's flow is the weighted mean of the flows of
//! the patches that cover it, a patch weighing `1 / max(1, |d|)` where `d` is its
//! photometric residual at that pixel (`second(x + u) - first(x)`, less the patch's
//! brightness offset under mean normalisation).
//!
//! Output rows are independent tasks and each pixel sums its patches in grid order, so the
//! result does not depend on the thread count.

use super::pyramid::Padded;
use super::search::{PatchFlow, Template};
use rayon::prelude::*;

/// Dense `w x h` flow from the patch flows of one level (`patches` row-major over
/// `(ys, xs)`, patch side `size`; the grid covers every pixel).
pub(crate) fn densify(
    t: &Template<'_>,
    i1: &Padded,
    patches: &[PatchFlow],
    xs: &[usize],
    ys: &[usize],
    size: usize,
    h: usize,
) -> Vec<[f32; 2]> {
    let w = t.w;
    let mut flow = vec![[0.0f32; 2]; w * h];
    let mut weight = vec![0.0f32; w * h];
    flow.par_chunks_mut(w)
        .zip(weight.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (acc, wsum))| {
            let first = ys.partition_point(|&py| py + size <= y);
            let t_row = &t.i0[y * w..][..w];
            for (j, &py) in ys.iter().enumerate().skip(first) {
                if py > y {
                    break;
                }
                let r = y - py;
                for (&px, p) in xs.iter().zip(&patches[j * xs.len()..][..xs.len()]) {
                    let tap = i1.tap(px as f32 + p.u, py as f32 + p.v, size);
                    let a = &i1.data[tap.index + r * i1.stride..][..size + 1];
                    let b = &i1.data[tap.index + (r + 1) * i1.stride..][..size + 1];
                    let tc = &t_row[px..][..size];
                    let ac = &mut acc[px..][..size];
                    let wc = &mut wsum[px..][..size];
                    let it = a[..size]
                        .iter()
                        .zip(&a[1..])
                        .zip(b[..size].iter().zip(&b[1..]))
                        .zip(tc)
                        .zip(ac.iter_mut().zip(wc.iter_mut()));
                    for ((((a0, a1), (b0, b1)), tv), (av, wv)) in it {
                        let s = tap.w00 * a0 + tap.w01 * a1 + tap.w10 * b0 + tap.w11 * b1;
                        let d = (s - tv - p.offset).abs();
                        let lambda = 1.0 / d.max(1.0);
                        *wv += lambda;
                        av[0] += lambda * p.u;
                        av[1] += lambda * p.v;
                    }
                }
            }
            for (av, &wv) in acc.iter_mut().zip(wsum.iter()) {
                if wv > 0.0 {
                    let inv = 1.0 / wv;
                    av[0] *= inv;
                    av[1] *= inv;
                }
            }
        });
    flow
}
