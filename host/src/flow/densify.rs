//! Densification (DIS, section 2.2): each pixel's flow is the weighted mean of the flows of
//! the patches that cover it, a patch weighing `1 / max(1, |d|)` where `d` is its
//! photometric residual at that pixel (`second(x + u) - first(x)`, less the patch's
//! brightness offset under mean normalisation).
//!
//! Output rows are independent tasks and each pixel sums its patches in grid order, so the
//! result does not depend on the thread count.

use super::pool::Pool;
use super::pyramid::{Padded, Tap};
use super::search::{Grid, PatchFlow, Template};
use crate::par::*;

/// Runs `$body` with the const `$n` set to the patch side `$size` (a multiple of 4 in
/// `4..=32`, as `FlowParams` validates; anything else runs as 32), so that every loop over
/// a patch row has a length known at compile time.
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

/// Dense `w x h` flow from the patch flows of one level (`patches` row-major over the
/// grid, which covers every pixel).
pub(crate) fn densify(
    t: &Template<'_>,
    i1: &Padded,
    patches: &[PatchFlow],
    grid: &Grid<'_>,
    h: usize,
    pool: &Pool,
    flows: &Pool<[f32; 2]>,
) -> Vec<[f32; 2]> {
    with_patch_size!(grid.size, N => densify_n::<N>(t, i1, patches, grid, h, pool, flows))
}

/// [`densify`] for patches of side `N` (`grid.size`).
fn densify_n<const N: usize>(
    t: &Template<'_>,
    i1: &Padded,
    patches: &[PatchFlow],
    grid: &Grid<'_>,
    h: usize,
    pool: &Pool,
    flows: &Pool<[f32; 2]>,
) -> Vec<[f32; 2]> {
    let (xs, ys, size) = (grid.xs, grid.ys, N);
    let w = t.w;
    // Sums of weight, weight·u and weight·v in separate planes (element-wise loops).
    // Each patch's bilinear taps, computed once (every row of the patch reuses them).
    let taps: Vec<Tap> = ys
        .iter()
        .flat_map(|&py| xs.iter().map(move |&px| (px, py)))
        .zip(patches)
        .map(|((px, py), p)| i1.tap(px as f32 + p.u, py as f32 + p.v, size))
        .collect();
    let mut sums = pool.zeroed(3 * w * h);
    sums.par_chunks_mut(3 * w)
        .enumerate()
        .for_each(|(y, chunk)| {
            let (sw, rest) = chunk.split_at_mut(w);
            let (su, sv) = rest.split_at_mut(w);
            let first = ys.partition_point(|&py| py + size <= y);
            let t_row = &t.i0[y * w..][..w];
            for (j, &py) in ys.iter().enumerate().skip(first) {
                if py > y {
                    break;
                }
                let r = y - py;
                let row_patches = &patches[j * xs.len()..][..xs.len()];
                let row_taps = &taps[j * xs.len()..][..xs.len()];
                for ((&px, p), tap) in xs.iter().zip(row_patches).zip(row_taps) {
                    let a = &i1.data[tap.index + r * i1.stride..][..=N];
                    let b = &i1.data[tap.index + (r + 1) * i1.stride..][..=N];
                    let (a0, a1, b0, b1) = (&a[..N], &a[1..], &b[..N], &b[1..]);
                    let tc = &t_row[px..][..N];
                    let (cw, cu, cv) = (&mut sw[px..][..N], &mut su[px..][..N], &mut sv[px..][..N]);
                    for k in 0..N {
                        let s =
                            tap.w00 * a0[k] + tap.w01 * a1[k] + tap.w10 * b0[k] + tap.w11 * b1[k];
                        let d = (s - tc[k] - p.offset).abs();
                        let lambda = 1.0 / d.max(1.0);
                        cw[k] += lambda;
                        cu[k] += lambda * p.u;
                        cv[k] += lambda * p.v;
                    }
                }
            }
        });
    let mut flow = flows.scratch(w * h);
    flow.par_chunks_mut(w)
        .zip(sums.par_chunks(3 * w))
        .for_each(|(out, chunk)| {
            let (sw, rest) = chunk.split_at(w);
            let (su, sv) = rest.split_at(w);
            for (((o, &wt), &u), &v) in out.iter_mut().zip(sw).zip(su).zip(sv) {
                let inv = if wt > 0.0 { 1.0 / wt } else { 0.0 };
                *o = [u * inv, v * inv];
            }
        });
    pool.put(sums);
    flow
}
