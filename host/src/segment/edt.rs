//! Exact Euclidean distance transform (Felzenszwalb & Huttenlocher 2012): for every pixel,
//! the squared distance in pixels to the nearest pixel of a set, in `O(width·height)`.
//!
//! Contract: [`squared_distance`] works in a window of the image and writes
//! `f32::INFINITY` everywhere in it when the set has no pixel there. The distances up to
//! the caller's limit are exact (integers in `f32`), so the result does not depend on the
//! order of the work; farther ones are only known to lie beyond the limit.
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

impl Window {
    /// The window's rows, each with its columns.
    pub(super) fn rows(self) -> impl Iterator<Item = (usize, core::ops::Range<usize>)> {
        (self.y0..self.y1).map(move |y| (y, self.x0..self.x1))
    }
}

/// Squared distance (px²) from each pixel of `win` to the nearest pixel of `win` with
/// `in_set(i)`, into `out` (row-major, `w` pixels a row; pixels outside `win` are left as
/// they are), exact up to `limit_px`; a pixel farther than `limit_px` from the set gets a
/// value above `limit_px²` (possibly infinity). For a pixel whose nearest set pixel lies
/// in `win` this is its distance in the whole image. Rows run in parallel with the
/// `threads` feature, with the same result.
///
/// Down the columns, distances beyond `limit_px` are infinity: a pixel within `limit_px`
/// of its nearest set pixel is within it vertically too, so its distance stays exact,
/// while fewer samples enter the row pass.
pub(super) fn squared_distance(
    w: usize,
    win: Window,
    limit_px: f32,
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
    let step = |run: f32| {
        let next = run + 1.0;
        if next > limit_px { f32::INFINITY } else { next }
    };
    s.run.clear();
    s.run.resize(ww, f32::INFINITY);
    for y in y0..y1 {
        let row = &mut out[y * w + x0..y * w + x1];
        for (x, (o, run)) in row.iter_mut().zip(s.run.iter_mut()).enumerate() {
            *run = if in_set(y * w + x0 + x) {
                0.0
            } else {
                step(*run)
            };
            *o = *run;
        }
    }
    s.run.fill(f32::INFINITY);
    for y in (y0..y1).rev() {
        let row = &mut out[y * w + x0..y * w + x1];
        for (o, run) in row.iter_mut().zip(s.run.iter_mut()) {
            *run = if *o == 0.0 { 0.0 } else { step(*run) };
            *o = o.min(*run);
        }
    }
    // Along the rows: the lower envelope of the column distances squared.
    out[y0 * w..y1 * w].par_chunks_mut(w).for_each_init(
        || (vec![0.0f32; ww], Vec::with_capacity(ww)),
        |(f, pieces), row| {
            let row = &mut row[x0..x1];
            for (f, &d) in f.iter_mut().zip(row.iter()) {
                *f = d * d;
            }
            envelope(f, row, pieces);
        },
    );
}

/// A parabola `(x − p)² + f(p)` of the lower envelope, lowest from the position
/// `from_num / from_den` on (`from_den > 0`; the first one from −∞, `from_den = 0`).
/// All are integers, exact in `f64` (below 2⁵³ for any image of up to 2¹⁶ pixels a side,
/// products included).
#[derive(Debug, Clone, Copy)]
struct Piece {
    p: usize,
    /// `f(p) + p²`.
    c: f64,
    from_num: f64,
    from_den: f64,
}

/// 1-D transform: `d[q] = min_p (q − p)² + f[p]` over finite `f[p]` (integers); infinity if
/// none. The envelope is built in exact arithmetic: the parabolas of `p < q` meet at
/// `((f(q) + q²) − (f(p) + p²)) / (2 (q − p))`, and two such fractions are compared by
/// cross-multiplying, without a division. A sample `f(q) = 0` is lowest everywhere from
/// `q` on (`(x − q)² ≤ (x − p)² + f(p)` for `x ≥ q > p`): the positions up to `q` are
/// written then and the envelope starts again from `q` alone (a run of zeros, as in the
/// background, costs little).
fn envelope(f: &[f32], d: &mut [f32], pieces: &mut Vec<Piece>) {
    pieces.clear();
    // Positions before `done` are written.
    let mut done = 0;
    for (q, &fq) in f.iter().enumerate() {
        if !fq.is_finite() {
            continue;
        }
        let qf = q as f64;
        let c = f64::from(fq) + qf * qf;
        let from_zero = Piece {
            p: q,
            c,
            from_num: -1.0,
            from_den: 0.0,
        };
        if fq == 0.0 && done == q {
            // Right after another zero (the envelope is that zero alone).
            d[q] = 0.0;
            pieces.clear();
            pieces.push(from_zero);
            done = q + 1;
            continue;
        }
        let (mut num, mut den) = (-1.0, 0.0);
        while let Some(top) = pieces.last() {
            (num, den) = (c - top.c, 2.0 * (qf - top.p as f64));
            // Where `q` takes over from `top` is not after where `top` took over: `top`
            // is nowhere lowest.
            if num * top.from_den <= top.from_num * den {
                pieces.pop();
                (num, den) = (-1.0, 0.0);
            } else {
                break;
            }
        }
        pieces.push(Piece {
            p: q,
            c,
            from_num: num,
            from_den: den,
        });
        if fq == 0.0 {
            write_envelope(pieces, f, &mut d[..=q], done);
            pieces.clear();
            pieces.push(from_zero);
            done = q + 1;
        }
    }
    if pieces.is_empty() {
        d.fill(f32::INFINITY);
    } else {
        write_envelope(pieces, f, d, done);
    }
}

/// Writes the envelope `pieces` of the samples `f` at the positions `done..d.len()`: each
/// piece at the integer positions after its start (the quotient is exact enough not to
/// cross an integer) up to the next piece's start.
fn write_envelope(pieces: &[Piece], f: &[f32], d: &mut [f32], done: usize) {
    let len = d.len();
    let start = |piece: &Piece| {
        let at = piece.from_num / piece.from_den;
        if piece.from_den == 0.0 || at < 0.0 {
            done
        } else {
            // `at ≥ 0`: truncation is the floor.
            ((at as usize).min(len) + 1).clamp(done, len)
        }
    };
    for (k, piece) in pieces.iter().enumerate() {
        let (from, to) = (start(piece), pieces.get(k + 1).map_or(len, start));
        let (p, fp) = (piece.p as f32, f[piece.p]);
        for (q, dq) in (from..to).zip(&mut d[from..to]) {
            let dp = q as f32 - p;
            *dq = dp * dp + fp;
        }
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
        let set_pixel = |i: usize| set.contains(&(i % w, i / w));
        squared_distance(w, all, f32::INFINITY, set_pixel, &mut s, &mut out);
        let exact = brute(w, h, &set);
        assert_eq!(out, exact);
        // Within a limit the distances stay exact; beyond it they stay beyond it.
        squared_distance(w, all, 4.5, set_pixel, &mut s, &mut out);
        for (&d, &e) in out.iter().zip(&exact) {
            assert!(
                if e <= 4.5 * 4.5 {
                    d == e
                } else {
                    d > 4.5 * 4.5
                },
                "{d} {e}"
            );
        }
        squared_distance(w, all, f32::INFINITY, |_| false, &mut s, &mut out);
        assert!(out.iter().all(|v| v.is_infinite()));
    }
}
