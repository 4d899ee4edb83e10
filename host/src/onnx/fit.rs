//! Frame <-> model-input geometry: scaling to a fixed input size (aspect kept, content at
//! the top left) or padding a dynamic one to a multiple, and sampling model outputs back
//! at frame pixels (bilinear, also for outputs at `1/r` of the input resolution).
//!
//! Pixel centres sit at integer coordinates; frame pixel `x` maps to model coordinate
//! `(x + 0.5)·s − 0.5` (`s` model pixels per frame pixel) and to output coordinate
//! `(x + 0.5)·s/r − 0.5`. Beyond the content, inputs repeat the edge pixels (as RAFT's
//! padder does). With `s = 1` and `r = 1` both directions are exact copies.

/// How a `frame` maps onto the model's input grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Fit {
    /// Frame `(width, height)`, pixels.
    pub frame: (usize, usize),
    /// Model input `(width, height)`, pixels.
    pub input: (usize, usize),
    /// Model pixels per frame pixel.
    pub scale: f32,
    /// The part of the input that shows the frame, `(width, height)` from the top left.
    content: (usize, usize),
}

impl Fit {
    /// `fixed` `(width, height)`: scaled to fit, aspect kept; `None`: padded to `multiple`.
    pub fn new(frame: (usize, usize), fixed: Option<(usize, usize)>, multiple: usize) -> Self {
        let (w, h) = frame;
        match fixed {
            Some((iw, ih)) => {
                let scale = (iw as f32 / w as f32).min(ih as f32 / h as f32);
                let side = |n: usize, max: usize| {
                    let m = libm::roundf(n as f32 * scale) as usize;
                    m.clamp(1, max)
                };
                Self {
                    frame,
                    input: (iw, ih),
                    scale,
                    content: (side(w, iw), side(h, ih)),
                }
            }
            None => {
                let up = |n: usize| n.div_ceil(multiple.max(1)) * multiple.max(1);
                Self {
                    frame,
                    input: (up(w), up(h)),
                    scale: 1.0,
                    content: frame,
                }
            }
        }
    }

    /// A `[C, H, W]` planar input tensor: `pixel(x, y)` gives frame pixel `(x, y)`'s
    /// channels; `bilinear` interpolates between frame pixels, else the nearest is taken
    /// (depth, so that holes and edges do not blend).
    pub fn input_planes<const C: usize>(
        &self,
        pixel: impl Fn(usize, usize) -> [f32; C],
        bilinear: bool,
    ) -> Vec<f32> {
        let (iw, ih) = self.input;
        let plane = iw * ih;
        let mut out = vec![0.0; C * plane];
        for y in 0..ih {
            let sy = self.source(y.min(self.content.1 - 1), self.frame.1);
            for x in 0..iw {
                let sx = self.source(x.min(self.content.0 - 1), self.frame.0);
                let value = if bilinear {
                    bilinear_at(sx, sy, self.frame, &pixel)
                } else {
                    pixel(nearest(sx, self.frame.0), nearest(sy, self.frame.1))
                };
                for (c, v) in value.into_iter().enumerate() {
                    out[c * plane + y * iw + x] = v;
                }
            }
        }
        out
    }

    /// Frame coordinate of model coordinate `m` along an axis of `n` frame pixels.
    fn source(&self, m: usize, n: usize) -> f32 {
        ((m as f32 + 0.5) / self.scale - 0.5).clamp(0.0, (n - 1) as f32)
    }

    /// How many input pixels one output pixel spans (`r`), for an output grid of
    /// `out` `(width, height)`; `None` unless `out·r` is the input size for one integer `r`.
    pub fn output_ratio(&self, out: (usize, usize)) -> Option<usize> {
        let (iw, ih) = self.input;
        let (ow, oh) = out;
        if ow == 0 || oh == 0 || iw % ow != 0 || ih % oh != 0 || iw / ow != ih / oh {
            return None;
        }
        Some(iw / ow)
    }

    /// The `(width, height, ratio)` of an output whose last two dimensions are `hw`.
    pub fn output_grid(&self, hw: &[usize], name: &str) -> Result<(usize, usize, usize), String> {
        let &[oh, ow] = hw else {
            return Err(format!("output `{name}` has the wrong rank"));
        };
        let ratio = self.output_ratio((ow, oh)).ok_or_else(|| {
            format!(
                "output `{name}` is {ow}x{oh} pixels, which is not the input's {}x{} divided \
                 by a whole number",
                self.input.0, self.input.1
            )
        })?;
        Ok((ow, oh, ratio))
    }

    /// Output-grid coordinates of every frame pixel, row-major, for an output grid of
    /// `out` `(width, height)` at ratio `ratio` (clamped into the grid).
    fn back_coords(&self, out: (usize, usize), ratio: usize) -> impl Iterator<Item = (f32, f32)> {
        let (w, h) = self.frame;
        let to_out = self.scale / ratio as f32;
        let coord =
            move |p: usize, n: usize| ((p as f32 + 0.5) * to_out - 0.5).clamp(0.0, (n - 1) as f32);
        (0..h).flat_map(move |y| (0..w).map(move |x| (coord(x, out.0), coord(y, out.1))))
    }

    /// Samples `plane` (an output grid of `out` `(width, height)` at ratio `ratio`)
    /// bilinearly at every frame pixel, row-major.
    pub fn sample_back(&self, plane: &[f32], out: (usize, usize), ratio: usize) -> Vec<f32> {
        self.back_coords(out, ratio)
            .map(|(ox, oy)| bilinear_at(ox, oy, out, &|px, py| [plane[py * out.0 + px]])[0])
            .collect()
    }

    /// The index into an output grid of `out` `(width, height)` at ratio `ratio` nearest to
    /// every frame pixel, row-major (for label maps, which must not blend).
    pub fn nearest_back(&self, out: (usize, usize), ratio: usize) -> Vec<usize> {
        self.back_coords(out, ratio)
            .map(|(ox, oy)| nearest(oy, out.1) * out.0 + nearest(ox, out.0))
            .collect()
    }
}

/// The nearest index to `s` on an axis of `n` pixels.
fn nearest(s: f32, n: usize) -> usize {
    let i = libm::roundf(s) as usize;
    i.min(n - 1)
}

/// Bilinear interpolation of `pixel` at `(sx, sy)` (both clamped into the grid of `size`).
fn bilinear_at<const C: usize>(
    sx: f32,
    sy: f32,
    size: (usize, usize),
    pixel: &impl Fn(usize, usize) -> [f32; C],
) -> [f32; C] {
    let (x0, y0) = (sx as usize, sy as usize);
    let (x1, y1) = ((x0 + 1).min(size.0 - 1), (y0 + 1).min(size.1 - 1));
    let (fx, fy) = (sx - x0 as f32, sy - y0 as f32);
    if fx == 0.0 && fy == 0.0 {
        return pixel(x0, y0);
    }
    let (a, b, c, d) = (pixel(x0, y0), pixel(x1, y0), pixel(x0, y1), pixel(x1, y1));
    core::array::from_fn(|i| {
        let top = a[i] + (b[i] - a[i]) * fx;
        let bottom = c[i] + (d[i] - c[i]) * fx;
        top + (bottom - top) * fy
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn padding_copies_and_repeats_the_edge() {
        let fit = Fit::new((3, 2), None, 4);
        assert_eq!(fit.input, (4, 4));
        let planes = fit.input_planes(|x, y| [(y * 3 + x) as f32], true);
        assert_eq!(
            planes,
            [
                0., 1., 2., 2., 3., 4., 5., 5., 3., 4., 5., 5., 3., 4., 5., 5.
            ]
        );
        assert_eq!(fit.output_ratio((4, 4)), Some(1));
        assert_eq!(fit.output_ratio((2, 2)), Some(2));
        assert_eq!(fit.output_ratio((3, 4)), None);
        assert_eq!(fit.output_ratio((4, 2)), None);
        // Back at ratio 1: the content, cropped.
        assert_eq!(
            fit.sample_back(&planes, (4, 4), 1),
            [0., 1., 2., 3., 4., 5.]
        );
    }

    #[test]
    fn fixed_size_keeps_aspect_and_samples_back() {
        let fit = Fit::new((8, 4), Some((4, 4)), 1);
        assert!((fit.scale - 0.5).abs() < 1e-6);
        assert_eq!(fit.content, (4, 2));
        // A plane that is 1 where x_model >= 2: frame pixels x >= 4 land there or blend.
        let plane: Vec<f32> = (0..16)
            .map(|i| if i % 4 >= 2 { 1.0 } else { 0.0 })
            .collect();
        let back = fit.sample_back(&plane, (4, 4), 1);
        assert_eq!(back.len(), 32);
        assert_eq!(back[0], 0.0);
        assert_eq!(back[7], 1.0);
        assert!(back[3] > 0.0 && back[3] < 1.0, "{}", back[3]);
        // A constant 1/2-resolution plane stays constant.
        assert!(
            fit.sample_back(&[2.5; 4], (2, 2), 2)
                .iter()
                .all(|&v| v == 2.5)
        );
        // Nearest: frame x 0-3 -> model x 0-1 -> output column 0 of a 2x2 grid at ratio 2.
        let near = fit.nearest_back((2, 2), 2);
        assert_eq!(&near[..8], &[0, 0, 0, 0, 1, 1, 1, 1]);
    }
}
