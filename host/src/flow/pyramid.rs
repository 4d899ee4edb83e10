//! Image pyramids and the per-level images the estimator reads: 2x2 box downsampling,
//! central-difference gradients, border-replicated copies for clamped bilinear sampling,
//! and bilinear flow upsampling.
//!
//! Level `l + 1` pixel `(i, j)` is the mean of level-`l` pixels `2i..=2i+1, 2j..=2j+1`, so
//! its centre sits at `(2i + 0.5, 2j + 0.5)` in level-`l` coordinates and displacements
//! scale by exactly 2 between levels.

use super::luma_of;
use super::pool::{Lent, Pool};
use crate::par::*;
use riseg_core::ImageView;

/// A plain row-major `f32` plane.
#[derive(Debug, Clone)]
pub(crate) struct Plane {
    pub w: usize,
    pub h: usize,
    pub data: Lent<f32>,
}

/// Half the size (floor), each pixel the mean of a 2x2 block of `src` (`w x h`).
pub(crate) fn downsample(src: &[f32], w: usize, h: usize, pool: &Pool) -> Plane {
    let (w2, h2) = (w / 2, h / 2);
    let mut data = pool.scratch(w2 * h2);
    if w2 > 0 {
        data.par_chunks_mut(w2).enumerate().for_each(|(y, out)| {
            let r0 = &src[2 * y * w..][..2 * w2];
            let r1 = &src[(2 * y + 1) * w..][..2 * w2];
            for ((o, a), b) in out
                .iter_mut()
                .zip(r0.chunks_exact(2))
                .zip(r1.chunks_exact(2))
            {
                *o = 0.25 * (a[0] + a[1] + b[0] + b[1]);
            }
        });
    }
    Plane { w: w2, h: h2, data }
}

/// The luma of `rgb` ([`super::luma`]) in a buffer of `pool`, row-major.
pub(crate) fn luma_plane(rgb: ImageView<'_, [u8; 3]>, pool: &Pool) -> Lent<f32> {
    let w = rgb.width();
    let mut data = pool.scratch(w * rgb.height());
    if w > 0 {
        data.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
            if let Some(row) = rgb.row(y) {
                for (o, p) in out.iter_mut().zip(row) {
                    *o = luma_of(p);
                }
            }
        });
    }
    data
}

/// [`downsample`] of the luma of `rgb` ([`super::luma`]), converting each pixel as it
/// is read: the same values, bit for bit, without the full-resolution luma image.
pub(crate) fn downsample_luma(rgb: ImageView<'_, [u8; 3]>, pool: &Pool) -> Plane {
    let (w2, h2) = (rgb.width() / 2, rgb.height() / 2);
    let mut data = pool.scratch(w2 * h2);
    if w2 > 0 {
        data.par_chunks_mut(w2).enumerate().for_each(|(y, out)| {
            let (Some(r0), Some(r1)) = (rgb.row(2 * y), rgb.row(2 * y + 1)) else {
                return;
            };
            for ((o, a), b) in out
                .iter_mut()
                .zip(r0.chunks_exact(2))
                .zip(r1.chunks_exact(2))
            {
                *o = 0.25 * (luma_of(&a[0]) + luma_of(&a[1]) + luma_of(&b[0]) + luma_of(&b[1]));
            }
        });
    }
    Plane { w: w2, h: h2, data }
}

/// Central-difference gradients `(d/dx, d/dy)` of `src` (`w x h`, both `>= 1`), one-sided
/// (half-weighted) at the border.
pub(crate) fn gradients(src: &[f32], w: usize, h: usize, pool: &Pool) -> (Lent<f32>, Lent<f32>) {
    let mut gx = pool.scratch(w * h);
    let mut gy = pool.scratch(w * h);
    gx.par_chunks_mut(w)
        .zip(gy.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (ox, oy))| {
            let row = &src[y * w..][..w];
            let up = &src[y.saturating_sub(1) * w..][..w];
            let down = &src[(y + 1).min(h - 1) * w..][..w];
            for ((o, a), b) in oy.iter_mut().zip(up).zip(down) {
                *o = 0.5 * (b - a);
            }
            if w >= 2 {
                ox[0] = 0.5 * (row[1] - row[0]);
                ox[w - 1] = 0.5 * (row[w - 1] - row[w - 2]);
                for (o, pair) in ox[1..w - 1].iter_mut().zip(row.windows(3)) {
                    *o = 0.5 * (pair[2] - pair[0]);
                }
            } else {
                ox.fill(0.0);
            }
        });
    (gx, gy)
}

/// A plane copied into a larger buffer with `pad` replicated pixels on every side, so that
/// bilinear taps at clamped positions never leave the buffer.
#[derive(Debug, Clone)]
pub(crate) struct Padded {
    pub w: usize,
    pub h: usize,
    pub pad: usize,
    pub stride: usize,
    pub data: Lent<f32>,
}

/// Where a (clamped) bilinear sample reads: the top-left tap's index and the weights.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tap {
    pub index: usize,
    pub w00: f32,
    pub w01: f32,
    pub w10: f32,
    pub w11: f32,
}

impl Padded {
    /// Copies `src` (`w x h`, both `>= 1`) with `pad >= 1` replicated border pixels.
    pub fn new(src: &[f32], w: usize, h: usize, pad: usize, pool: &Pool) -> Self {
        let stride = w + 2 * pad;
        let mut data = pool.scratch(stride * (h + 2 * pad));
        data.par_chunks_mut(stride)
            .enumerate()
            .for_each(|(py, out)| {
                let y = py.saturating_sub(pad).min(h - 1);
                let row = &src[y * w..][..w];
                let (left, rest) = out.split_at_mut(pad);
                let (mid, right) = rest.split_at_mut(w);
                left.fill(row[0]);
                mid.copy_from_slice(row);
                right.fill(row[w - 1]);
            });
        Self {
            w,
            h,
            pad,
            stride,
            data,
        }
    }

    /// Bilinear taps for a `size x size` block whose top-left corner is at `(x, y)` in
    /// image coordinates, with the corner clamped so that every tap stays in the buffer
    /// (`size <= w` and `size <= h` must hold). NaN clamps to the low corner.
    #[inline]
    pub fn tap(&self, x: f32, y: f32, size: usize) -> Tap {
        let pad = self.pad as f32;
        // `max` maps NaN to 0; positions are non-negative, so `as usize` is `floor`.
        let px = (x + pad)
            .max(0.0)
            .min((self.w + 2 * self.pad - size - 1) as f32);
        let py = (y + pad)
            .max(0.0)
            .min((self.h + 2 * self.pad - size - 1) as f32);
        // Both are below 2^31 (buffer sides), and `i32` conversions are single instructions.
        let (ix, iy) = (px as i32, py as i32);
        let (fx, fy) = (px - ix as f32, py - iy as f32);
        let (ix, iy) = (ix.unsigned_abs() as usize, iy.unsigned_abs() as usize);
        Tap {
            index: iy * self.stride + ix,
            w00: (1.0 - fx) * (1.0 - fy),
            w01: fx * (1.0 - fy),
            w10: (1.0 - fx) * fy,
            w11: fx * fy,
        }
    }

    /// The bilinear value at image position `(x, y)` (clamped into the padded buffer).
    #[cfg(test)]
    pub fn sample(&self, x: f32, y: f32) -> f32 {
        let t = self.tap(x, y, 1);
        self.sample_at(&t)
    }

    /// The value of a precomputed tap.
    #[cfg(test)]
    pub fn sample_at(&self, t: &Tap) -> f32 {
        let d = &self.data[t.index..][..self.stride + 2];
        t.w00 * d[0] + t.w01 * d[1] + t.w10 * d[self.stride] + t.w11 * d[self.stride + 1]
    }
}

/// Bilinear resize of a flow from `src_w x src_h` to `dst_w x dst_h` where one source
/// pixel covers `scale x scale` destination pixels; vectors are multiplied by `scale`.
pub(crate) fn upsample_flow(
    src: &[[f32; 2]],
    src_w: usize,
    src_h: usize,
    dst_w: usize,
    dst_h: usize,
    scale: usize,
    pool: &Pool<[f32; 2]>,
) -> Lent<[f32; 2]> {
    let mut dst = pool.scratch(dst_w * dst_h);
    if src_w == 0 || src_h == 0 || dst_w == 0 {
        dst.fill([0.0; 2]);
        return dst;
    }
    let s = scale as f32;
    let inv = 1.0 / s;
    // Source column and weight of destination column `x`.
    let col = |x: usize| {
        let fx = ((x as f32 + 0.5) * inv - 0.5).clamp(0.0, (src_w - 1) as f32);
        let x0 = fx as usize; // non-negative: truncation is floor
        (x0, (x0 + 1).min(src_w - 1), fx - x0 as f32)
    };
    let lerp =
        |a: [f32; 2], b: [f32; 2], t: f32| [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
    // The general path reads the columns from a table computed once. At scale 2 (between
    // pyramid levels) destination columns `2j + 1` and `2j + 2` lie between source columns
    // `j` and `j + 1` at weights exactly 0.25 and 0.75 (`col` gives the same, in binary
    // fractions without rounding), so the interior is blended pairwise without the table;
    // the edge columns, clamped, still go through `col`.
    let cols: Vec<(usize, usize, f32)> = if scale == 2 {
        Vec::new()
    } else {
        (0..dst_w).map(col).collect()
    };
    // Per output row: blend the two source rows vertically (element-wise), then resample
    // that row horizontally.
    dst.par_chunks_mut(dst_w).enumerate().for_each_init(
        || vec![[0.0f32; 2]; src_w],
        |row, (y, out)| {
            let fy = ((y as f32 + 0.5) * inv - 0.5).clamp(0.0, (src_h - 1) as f32);
            let y0 = fy as usize; // non-negative: truncation is floor
            let y1 = (y0 + 1).min(src_h - 1);
            let ay = fy - y0 as f32;
            let r0 = &src[y0 * src_w..][..src_w];
            let r1 = &src[y1 * src_w..][..src_w];
            for ((v, a), b) in row.iter_mut().zip(r0).zip(r1) {
                *v = [
                    s * (a[0] + ay * (b[0] - a[0])),
                    s * (a[1] + ay * (b[1] - a[1])),
                ];
            }
            if scale == 2 {
                let pairs = out[1..].chunks_exact_mut(2).zip(row.windows(2));
                let interior = 2 * pairs.len();
                for (o, ab) in pairs {
                    o[0] = lerp(ab[0], ab[1], 0.25);
                    o[1] = lerp(ab[0], ab[1], 0.75);
                }
                for x in core::iter::once(0).chain(1 + interior..dst_w) {
                    let (x0, x1, ax) = col(x);
                    out[x] = lerp(row[x0], row[x1], ax);
                }
            } else {
                for (o, &(x0, x1, ax)) in out.iter_mut().zip(&cols) {
                    *o = lerp(row[x0], row[x1], ax);
                }
            }
        },
    );
    dst
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downsample_averages_blocks() {
        let src: Vec<f32> = (0..15).map(|v| v as f32).collect();
        let d = downsample(&src, 5, 3, &Pool::default());
        assert_eq!((d.w, d.h), (2, 1));
        assert_eq!(&d.data[..], [3.0, 5.0]);
    }

    #[test]
    fn gradients_of_a_ramp() {
        let src: Vec<f32> = (0..12)
            .map(|i| (2 * (i % 4) + 3 * (i / 4)) as f32)
            .collect();
        let (gx, gy) = gradients(&src, 4, 3, &Pool::default());
        assert_eq!(gx[5], 2.0);
        assert_eq!(gy[5], 3.0);
        assert_eq!(gx[0], 1.0); // half-weighted one-sided difference at the border
    }

    #[test]
    fn padded_sampling_is_bilinear_and_clamped() {
        let src: Vec<f32> = (0..12).map(|v| v as f32).collect();
        let p = Padded::new(&src, 4, 3, 2, &Pool::default());
        assert_eq!(p.sample(1.0, 1.0), 5.0);
        assert!((p.sample(1.5, 1.25) - 6.5).abs() < 1e-6);
        assert_eq!(p.sample(-10.0, -10.0), 0.0);
        assert_eq!(p.sample(100.0, 100.0), 11.0);
        assert_eq!(p.sample(f32::NAN, 0.0), 0.0);
    }

    #[test]
    fn upsampling_scales_vectors_and_keeps_constants() {
        let src = vec![[1.0, -2.0]; 6];
        let dst = upsample_flow(&src, 3, 2, 6, 4, 2, &Pool::default());
        assert!(dst.iter().all(|v| *v == [2.0, -4.0]));
    }

    #[test]
    fn upsampling_by_two_matches_the_column_formula_bit_for_bit() {
        // The scale-2 path blends interior columns at fixed weights; every output must equal
        // the general formula (source column and weight from the clamped position) exactly,
        // also for odd and cropped destination widths.
        for (src_w, src_h, dst_w, dst_h) in
            [(5, 3, 10, 6), (5, 3, 11, 7), (4, 2, 5, 3), (1, 1, 3, 2)]
        {
            let src: Vec<[f32; 2]> = (0..src_w * src_h)
                .map(|i| {
                    [
                        (i as f32 * 0.37).sin() * 3.1,
                        -(i as f32 * 0.71).cos() * 1.7,
                    ]
                })
                .collect();
            let dst = upsample_flow(&src, src_w, src_h, dst_w, dst_h, 2, &Pool::default());
            let at = |p: usize, n: usize| {
                let f = ((p as f32 + 0.5) * 0.5 - 0.5).clamp(0.0, (n - 1) as f32);
                let p0 = f as usize;
                (p0, (p0 + 1).min(n - 1), f - p0 as f32)
            };
            for y in 0..dst_h {
                let (y0, y1, ay) = at(y, src_h);
                let row = |x: usize| {
                    let (a, b) = (src[y0 * src_w + x], src[y1 * src_w + x]);
                    [
                        2.0 * (a[0] + ay * (b[0] - a[0])),
                        2.0 * (a[1] + ay * (b[1] - a[1])),
                    ]
                };
                for x in 0..dst_w {
                    let (x0, x1, ax) = at(x, src_w);
                    let (a, b) = (row(x0), row(x1));
                    let want = [a[0] + ax * (b[0] - a[0]), a[1] + ax * (b[1] - a[1])];
                    assert_eq!(dst[y * dst_w + x].map(f32::to_bits), want.map(f32::to_bits));
                }
            }
        }
    }
}
