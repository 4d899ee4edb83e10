//! Densification (DIS, section 2.2): each pixel's flow is the weighted mean of the flows of
//! the patches that cover it, a patch weighing `1 / max(1, |d| + κ·d²)` where `d` is its
//! photometric residual at that pixel (`second(x + u) - first(x)`, less the patch's
//! brightness offset under mean normalisation; grey levels) and `κ` (per grey level) is
//! `FlowParams::densify_outlier_per_grey`. DIS's own weight is `κ = 0`; `κ > 0` lets a
//! patch that straddles a motion boundary count less on the side it does not match.
//!
//! Output rows are independent tasks and each pixel sums its patches in grid order, so the
//! result does not depend on the thread count.

use super::pool::{Lent, Pool};
use super::pyramid::{Padded, Tap};
use super::search::{Grid, LANES, PatchFlow, lanes, lanes_mut, refill, with_patch_size};
use wide::f32x4;

/// One in every lane.
const ONE: f32x4 = f32x4::splat(1.0);
use crate::par::*;

/// Dense `w x h` flow from the patch flows of one level (`patches` row-major over the
/// grid, which covers every pixel), `first` the level's first image and its width;
/// `outlier_per_grey` is the weight's `κ`. The flow is lent by `flows`; `taps` is scratch
/// (garbage after the call), kept by the caller between calls.
#[allow(clippy::too_many_arguments)] // the level's inputs, its pool, scratch and one setting
pub(crate) fn densify(
    first: (&[f32], usize),
    i1: &Padded,
    patches: &[PatchFlow],
    grid: &Grid<'_>,
    h: usize,
    outlier_per_grey: f32,
    flows: &Pool<[f32; 2]>,
    taps: &mut Vec<Tap>,
) -> Lent<[f32; 2]> {
    with_patch_size!(grid.size, N => densify_n::<N>(first, i1, patches, grid, h, outlier_per_grey, flows, taps))
}

/// [`densify`] for patches of side `N` (`grid.size`).
#[allow(clippy::too_many_arguments)] // densify's arguments, passed through
fn densify_n<const N: usize>(
    (i0, w): (&[f32], usize),
    i1: &Padded,
    patches: &[PatchFlow],
    grid: &Grid<'_>,
    h: usize,
    outlier_per_grey: f32,
    flows: &Pool<[f32; 2]>,
    taps: &mut Vec<Tap>,
) -> Lent<[f32; 2]> {
    let (xs, ys, size) = (grid.xs, grid.ys, N);
    // Each patch's bilinear taps, computed once (every row of the patch reuses them).
    refill(
        taps,
        patches.len(),
        ys.iter()
            .flat_map(|&py| xs.iter().map(move |&px| (px, py)))
            .zip(patches)
            .map(|((px, py), p)| i1.tap(px as f32 + p.u, py as f32 + p.v, size)),
    );
    let (taps, data) = (&*taps, &*i1.data);
    let kappa = f32x4::splat(outlier_per_grey);
    // Each output row sums weight, weight·u and weight·v over its patches in a row of
    // three planes of its own (element-wise loops), then divides into the flow: no plane
    // of sums, so nothing to zero-fill or fault in at the image's size.
    let mut flow = flows.scratch(w * h);
    flow.par_chunks_mut(w).enumerate().for_each_init(
        || vec![0.0f32; 3 * w],
        |sums, (y, out)| {
            sums.fill(0.0);
            let (sw, rest) = sums.split_at_mut(w);
            let (su, sv) = rest.split_at_mut(w);
            // All three rows cut to `w`: one bounds check serves them all.
            let (sw, su, sv) = (&mut sw[..w], &mut su[..w], &mut sv[..w]);
            let first = ys.partition_point(|&py| py + size <= y);
            let t_row = &i0[y * w..][..w];
            for (j, &py) in ys.iter().enumerate().skip(first) {
                if py > y {
                    break;
                }
                let r = y - py;
                let row_patches = &patches[j * xs.len()..][..xs.len()];
                let row_taps = &taps[j * xs.len()..][..xs.len()];
                for ((&px, p), tap) in xs.iter().zip(row_patches).zip(row_taps) {
                    let a = &data[tap.index + r * i1.stride..][..=N];
                    let b = &data[tap.index + (r + 1) * i1.stride..][..=N];
                    let (a0, a1) = (lanes::<N>(a), lanes::<N>(&a[1..]));
                    let (b0, b1) = (lanes::<N>(b), lanes::<N>(&b[1..]));
                    let tc = lanes::<N>(&t_row[px..]);
                    let (cw, cu, cv) = (
                        lanes_mut::<N>(&mut sw[px..]),
                        lanes_mut::<N>(&mut su[px..]),
                        lanes_mut::<N>(&mut sv[px..]),
                    );
                    let [w00, w01, w10, w11] =
                        [tap.w00, tap.w01, tap.w10, tap.w11].map(f32x4::splat);
                    let (offset, u, v) =
                        (f32x4::splat(p.offset), f32x4::splat(p.u), f32x4::splat(p.v));
                    for (g, ((cw, cu), cv)) in cw.iter_mut().zip(cu).zip(cv).enumerate() {
                        let at = |s: &[[f32; LANES]]| f32x4::new(s[g]);
                        let s = w00 * at(a0) + w01 * at(a1) + w10 * at(b0) + w11 * at(b1);
                        let d = (s - at(tc) - offset).abs();
                        let lambda = ONE / (d + kappa * d * d).max(ONE);
                        *cw = (f32x4::new(*cw) + lambda).to_array();
                        *cu = (f32x4::new(*cu) + lambda * u).to_array();
                        *cv = (f32x4::new(*cv) + lambda * v).to_array();
                    }
                }
            }
            for (((o, &wt), &u), &v) in out.iter_mut().zip(&*sw).zip(&*su).zip(&*sv) {
                let inv = if wt > 0.0 { 1.0 / wt } else { 0.0 };
                *o = [u * inv, v * inv];
            }
        },
    );
    flow
}
