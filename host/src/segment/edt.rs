//! Exact Euclidean distance transform (Felzenszwalb & Huttenlocher 2012): for every pixel,
//! the squared distance in pixels to the nearest pixel of a set, in `O(width·height)`.
//!
//! Contract: [`squared_distance`] writes `f32::INFINITY` everywhere when the set is empty.
//! Down the columns the distance to the nearest set pixel is found by two scans (down and
//! up); along the rows, the 1-D transform is the lower envelope of the parabolas
//! `(q − p)² + f(p)` over the squared column distances `f(p)` (samples at infinity are
//! skipped, so no huge sentinels enter the arithmetic). Every pass reads memory in order.

/// Line scratch for [`squared_distance`], reused across calls.
#[derive(Debug, Default)]
pub(super) struct EdtScratch {
    f: Vec<f32>,
    run: Vec<f32>,
    roots: Vec<usize>,
    bounds: Vec<f32>,
}

/// Squared distance (px²) from each pixel to the nearest pixel with `in_set(i)`.
pub(super) fn squared_distance(
    w: usize,
    h: usize,
    in_set: impl Fn(usize) -> bool,
    s: &mut EdtScratch,
    out: &mut [f32],
) {
    // Down the columns: distance to the nearest set pixel in the same column, by one scan
    // down and one up, a row at a time so memory is read in order.
    s.run.clear();
    s.run.resize(w, f32::INFINITY);
    for (y, row) in out.chunks_exact_mut(w).enumerate() {
        for (x, (o, run)) in row.iter_mut().zip(s.run.iter_mut()).enumerate() {
            *run = if in_set(y * w + x) { 0.0 } else { *run + 1.0 };
            *o = *run;
        }
    }
    s.run.fill(f32::INFINITY);
    for row in out.chunks_exact_mut(w).rev() {
        for (o, run) in row.iter_mut().zip(s.run.iter_mut()) {
            *run = if *o == 0.0 { 0.0 } else { *run + 1.0 };
            *o = o.min(*run);
        }
    }
    // Along the rows: the lower envelope of the column distances squared.
    let m = w.max(h);
    s.f.resize(m, 0.0);
    s.roots.resize(m, 0);
    s.bounds.resize(m + 1, 0.0);
    for row in out.chunks_exact_mut(w) {
        for (f, &d) in s.f.iter_mut().zip(row.iter()) {
            *f = d * d;
        }
        envelope(&s.f[..w], row, &mut s.roots, &mut s.bounds);
    }
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
        squared_distance(w, h, |i| set.contains(&(i % w, i / w)), &mut s, &mut out);
        assert_eq!(out, brute(w, h, &set));
        squared_distance(w, h, |_| false, &mut s, &mut out);
        assert!(out.iter().all(|v| v.is_infinite()));
    }
}
