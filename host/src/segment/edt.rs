//! Exact Euclidean distance transform (Felzenszwalb & Huttenlocher 2012): for every pixel,
//! the squared distance in pixels to the nearest pixel of a set, in `O(width·height)`.
//!
//! Contract: [`squared_distance`] works in a window of the image and writes
//! `f32::INFINITY` everywhere in it when the set has no pixel there. The distances are
//! exact (integers in `f32`), so the result does not depend on the order of the work.
//! Down the columns the distance to the nearest set pixel is found by two scans (down and
//! up); along the rows, the 1-D transform is the lower envelope of the parabolas
//! `(q − p)² + f(p)` over the squared column distances `f(p)` (samples at infinity are
//! skipped, so no huge sentinels enter the arithmetic). Every pass reads memory in order.

use crate::par::*;

/// Column scratch for [`squared_distance`], reused across calls (the row pass allocates
/// its line buffers once per parallel task).
#[derive(Debug, Default)]
pub(super) struct EdtScratch {
    run: Vec<f32>,
}

/// A rectangle of pixels: columns `x0..x1`, rows `y0..y1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Window {
    pub(super) x0: usize,
    pub(super) x1: usize,
    pub(super) y0: usize,
    pub(super) y1: usize,
}

/// Squared distance (px²) from each pixel of `win` to the nearest pixel of `win` with
/// `in_set(i)`, into `out` (row-major, `w` pixels a row; pixels outside `win` are left as
/// they are). For a pixel whose nearest set pixel lies in `win` this is its distance in
/// the whole image. Rows run in parallel with the `threads` feature, with the same result.
pub(super) fn squared_distance(
    w: usize,
    win: Window,
    in_set: impl Fn(usize) -> bool,
    s: &mut EdtScratch,
    out: &mut [f32],
) {
    let Window { x0, x1, y0, y1 } = win;
    if x0 >= x1 || y0 >= y1 {
        return;
    }
    let ww = x1 - x0;
    // Down the columns: distance to the nearest set pixel in the same column, by one scan
    // down and one up, a row at a time so memory is read in order.
    s.run.clear();
    s.run.resize(ww, f32::INFINITY);
    for y in y0..y1 {
        let row = &mut out[y * w + x0..y * w + x1];
        for (x, (o, run)) in row.iter_mut().zip(s.run.iter_mut()).enumerate() {
            *run = if in_set(y * w + x0 + x) {
                0.0
            } else {
                *run + 1.0
            };
            *o = *run;
        }
    }
    s.run.fill(f32::INFINITY);
    for y in (y0..y1).rev() {
        let row = &mut out[y * w + x0..y * w + x1];
        for (o, run) in row.iter_mut().zip(s.run.iter_mut()) {
            *run = if *o == 0.0 { 0.0 } else { *run + 1.0 };
            *o = o.min(*run);
        }
    }
    // Along the rows: the lower envelope of the column distances squared.
    out[y0 * w..y1 * w].par_chunks_mut(w).for_each_init(
        || (vec![0.0f32; ww], vec![0usize; ww], vec![0.0f32; ww + 1]),
        |(f, roots, bounds), row| {
            let row = &mut row[x0..x1];
            for (f, &d) in f.iter_mut().zip(row.iter()) {
                *f = d * d;
            }
            envelope(f, row, roots, bounds);
        },
    );
}

/// 1-D transform: `d[q] = min_p (q − p)² + f[p]` over finite `f[p]`; infinity if none.
fn envelope(f: &[f32], d: &mut [f32], roots: &mut [usize], bounds: &mut [f32]) {
    let mut k = 0usize;
    for (q, &fq) in f.iter().enumerate() {
        if !fq.is_finite() {
            continue;
        }
        let qf = q as f32;
        let mut s = f32::NEG_INFINITY;
        while k > 0 {
            let p = roots[k - 1];
            let pf = p as f32;
            s = ((fq + qf * qf) - (f[p] + pf * pf)) / (2.0 * (qf - pf));
            if s <= bounds[k - 1] {
                k -= 1;
                s = f32::NEG_INFINITY;
            } else {
                break;
            }
        }
        roots[k] = q;
        bounds[k] = s;
        k += 1;
    }
    if k == 0 {
        d.fill(f32::INFINITY);
        return;
    }
    bounds[k] = f32::INFINITY;
    let mut j = 0;
    for (q, dq) in d.iter_mut().enumerate() {
        let qf = q as f32;
        while bounds[j + 1] < qf {
            j += 1;
        }
        let p = roots[j];
        let dp = qf - p as f32;
        *dq = dp * dp + f[p];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(w: usize, h: usize, set: &[(usize, usize)]) -> Vec<f32> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                set.iter()
                    .map(|&(sx, sy)| (x - sx as f32).powi(2) + (y - sy as f32).powi(2))
                    .fold(f32::INFINITY, f32::min)
            })
            .collect()
    }

    #[test]
    fn matches_brute_force_and_handles_an_empty_set() {
        let (w, h) = (23, 17);
        let set = [(0, 0), (5, 9), (22, 3), (11, 16), (12, 16)];
        let mut out = vec![0.0; w * h];
        let mut s = EdtScratch::default();
        let all = Window {
            x0: 0,
            x1: w,
            y0: 0,
            y1: h,
        };
        squared_distance(w, all, |i| set.contains(&(i % w, i / w)), &mut s, &mut out);
        assert_eq!(out, brute(w, h, &set));
        squared_distance(w, all, |_| false, &mut s, &mut out);
        assert!(out.iter().all(|v| v.is_infinite()));
    }
}
