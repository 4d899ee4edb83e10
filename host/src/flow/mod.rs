//! Dense optical flow: the [`FlowEstimator`] trait, the flow field type, and a hand-written
//! DIS-class estimator ([`DisFlow`]) that needs no model weights.
//!
//! # Contract
//! - A flow maps the **first** image to the **second**: the pixel at `(x, y)` in `first`
//!   shows the same scene point as `(x + dx, y + dy)` in `second`. Pixel centres sit at
//!   integer coordinates; `dx`, `dy` are in pixels, `dy` grows downwards.
//! - A flow is a [`FlowImage`]: `[dx, dy]` per pixel, row-major, `width · height` entries,
//!   the layout of a Middlebury `.flo` file body ([`crate::io::image::read_flo`] /
//!   [`crate::io::image::write_flo`] read and write it). Estimators borrow their images as
//!   riseg-core [`ImageView`]s and return an owned flow.
//! - Unknown flow: a vector with a component of magnitude [`UNKNOWN_FLOW_MIN_PX`] or more
//!   (the Middlebury convention, as `.flo` files store it) or a non-finite one (how flows
//!   in memory mark it) carries no information ([`is_known_flow`]).
//! - Estimators never panic on caller input: two images of different size, an empty image,
//!   an image smaller than one patch, non-finite pixels or bad parameters are a
//!   [`FlowError`].
//! - [`DisFlow`] is deterministic: the same images and parameters give bit-identical flow
//!   whatever the number of threads (every parallel task writes its own output and no sum
//!   crosses tasks).
//!
//! # Modules
//! [`dis`] holds the estimator and its presets; [`crate::testkit::flow`] (test support) makes image pairs with exact
//! ground truth; [`viz`] draws a flow with the Middlebury colour wheel.

pub mod dis;
pub mod viz;

mod boundary;
mod densify;
mod pool;
mod pyramid;
mod search;
mod variational;

pub use dis::{DisFlow, FlowParams};

use riseg_core::ImageView;

use crate::io::image::{FlowImage, Image};

/// Why a flow call failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FlowError {
    /// The two images (or an estimate and its ground truth) differ in size.
    #[error(
        "sizes differ: first is {first_width}x{first_height}, second is \
         {second_width}x{second_height}"
    )]
    SizeMismatch {
        /// Width of the first operand, pixels.
        first_width: usize,
        /// Height of the first operand, pixels.
        first_height: usize,
        /// Width of the second operand, pixels.
        second_width: usize,
        /// Height of the second operand, pixels.
        second_height: usize,
    },
    /// An image has no pixels.
    #[error("image is empty ({width}x{height})")]
    Empty {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
    },
    /// A pixel buffer's length does not match its width and height.
    #[error("buffer has {len} values, {width}x{height} needs {needed}")]
    BadLength {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
        /// Values the buffer holds.
        len: usize,
        /// Values `width x height` needs (saturated on overflow).
        needed: usize,
    },
    /// The image is smaller than one patch of the estimator.
    #[error("image {width}x{height} is smaller than one {patch_px}x{patch_px} patch")]
    TooSmall {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
        /// Patch side, pixels.
        patch_px: usize,
    },
    /// A parameter is out of its documented range.
    #[error("invalid flow parameters: {0}")]
    InvalidParams(&'static str),
    /// An image holds NaN or infinity.
    #[error("image holds NaN or infinity")]
    NonFinite,
    /// A mask selects no pixel, so a mean over it does not exist.
    #[error("the mask selects no pixel")]
    EmptySelection,
    /// The dedicated thread pool could not be built.
    #[cfg(feature = "threads")]
    #[error("cannot build the flow thread pool")]
    ThreadPool(#[from] rayon::ThreadPoolBuildError),
    /// An ONNX flow network failed ([`crate::onnx::OnnxFlow`]).
    #[cfg(feature = "onnx")]
    #[error(transparent)]
    Onnx(#[from] crate::onnx::OnnxError),
}

/// A flow component of at least this magnitude, pixels, means "unknown" in `.flo` files
/// (the Middlebury convention).
pub const UNKNOWN_FLOW_MIN_PX: f32 = 1e9;

/// Whether `v` is a known flow vector: both components finite and below
/// [`UNKNOWN_FLOW_MIN_PX`] in magnitude.
#[must_use]
pub fn is_known_flow(v: [f32; 2]) -> bool {
    // NaN compares false, so NaN is unknown too.
    v[0].abs() < UNKNOWN_FLOW_MIN_PX && v[1].abs() < UNKNOWN_FLOW_MIN_PX
}

/// Luma (ITU-R BT.601 weights: 0.299 R + 0.587 G + 0.114 B), 0-255, packed row-major: the
/// input of the estimators' grey-level stages (their thresholds are on that scale).
#[must_use]
pub fn luma(rgb: ImageView<'_, [u8; 3]>) -> Image<f32> {
    let (width, height) = rgb.size();
    let mut data = Vec::with_capacity(width.saturating_mul(height));
    // Row by row: a view's rows are contiguous, its stride may not be the width.
    for row in (0..height).filter_map(|y| rgb.row(y)) {
        data.extend(row.iter().map(luma_of));
    }
    Image::from_vec(width, height, data).expect("a view has height rows of width pixels")
}

/// The luma of one pixel, as [`luma`] computes it: `0.299 R + 0.587 G + 0.114 B` in `f32`,
/// the products added left to right. The products come from [`LUMA_PRODUCTS`], bit for bit
/// the `f32` products of the formula.
pub(crate) fn luma_of(p: &[u8; 3]) -> f32 {
    let [r, g, b] = &LUMA_PRODUCTS;
    r[usize::from(p[0])] + g[usize::from(p[1])] + b[usize::from(p[2])]
}

/// `weight · v` in `f32` for every channel value `v`, with the BT.601 weights of R, G and B.
/// Three loads take less time than three conversions and products, though they are more
/// instructions (the compiler gathers the bytes into lanes one by one): the luma of a
/// 640x480 image 0.30 -> 0.19 ms, [`pyramid::downsample_luma`] 0.27 -> 0.17 ms, the decode
/// of a one-shot `riseg flow`'s pair about 0.2 ms less (callgrind: 0.9 M more instructions).
static LUMA_PRODUCTS: [[f32; 256]; 3] = [products(0.299), products(0.587), products(0.114)];

/// `weight · v` for `v` in `0..=255`. Constant evaluation rounds each product to the
/// nearest `f32` as IEEE-754 arithmetic does at run time (not with x87's wider
/// intermediates).
const fn products(weight: f32) -> [f32; 256] {
    let mut table = [0.0; 256];
    let mut v: u8 = 0;
    loop {
        table[v as usize] = weight * v as f32;
        if v == u8::MAX {
            return table;
        }
        v += 1;
    }
}

/// Flow-specific operations on the owned flow image ([`FlowImage`]).
impl Image<[f32; 2]> {
    /// The flow of a Middlebury `.flo` file ([`crate::io::image::read_flo`]) with every
    /// unknown vector ([`is_known_flow`]) replaced by `[NaN, NaN]`, the in-memory mark.
    #[must_use]
    pub fn with_unknown_as_nan(mut self) -> Self {
        for v in self.as_mut_slice() {
            if !is_known_flow(*v) {
                *v = [f32::NAN; 2];
            }
        }
        self
    }

    /// Mean endpoint error `|self - truth|` (pixels) over the pixels `mask` selects (all
    /// pixels when `mask` is `None`) whose true flow is known ([`is_known_flow`]; unknown
    /// pixels are skipped). Summed in `f64` in row-major order.
    ///
    /// # Errors
    /// [`FlowError::SizeMismatch`] if the fields differ in size, [`FlowError::BadLength`]
    /// if `mask` has the wrong length, [`FlowError::EmptySelection`] if it selects nothing.
    pub fn mean_epe(&self, truth: &Self, mask: Option<&[bool]>) -> Result<f64, FlowError> {
        let (width, height) = self.size();
        if (width, height) != truth.size() {
            return Err(FlowError::SizeMismatch {
                first_width: width,
                first_height: height,
                second_width: truth.width(),
                second_height: truth.height(),
            });
        }
        if let Some(m) = mask
            && m.len() != self.as_slice().len()
        {
            return Err(FlowError::BadLength {
                width,
                height,
                len: m.len(),
                needed: self.as_slice().len(),
            });
        }
        let mut sum = 0.0f64;
        let mut count = 0usize;
        for (i, (a, b)) in self.as_slice().iter().zip(truth.as_slice()).enumerate() {
            if is_known_flow(*b) && mask.is_none_or(|m| m[i]) {
                sum += f64::from(libm::hypotf(a[0] - b[0], a[1] - b[1]));
                count += 1;
            }
        }
        if count == 0 {
            Err(FlowError::EmptySelection)
        } else {
            Ok(sum / count as f64)
        }
    }
}

/// Anything that turns two RGB images into a dense flow ([`FlowImage`]) from the first to
/// the second: the built-in [`DisFlow`] today, a learned network (RAFT through ONNX) later.
/// The images are lent, as views of any row stride.
pub trait FlowEstimator {
    /// Flow from `first` to `second`.
    ///
    /// # Errors
    /// [`FlowError::SizeMismatch`] if the images differ in size, [`FlowError::Empty`] if
    /// they have no pixels; implementations document any further cases.
    fn estimate(
        &self,
        first: ImageView<'_, [u8; 3]>,
        second: ImageView<'_, [u8; 3]>,
    ) -> Result<FlowImage, FlowError>;

    /// Flow from `first` to `second` when the caller expects some of the scene to have
    /// moved by about `hint_px` (`[dx, dy]`, pixels): a robot that pushed an object knows
    /// roughly how far and which way it went. The hint is a candidate, not a constraint:
    /// an estimator may try it beside its own guesses and keeps whatever matches the
    /// images best. The default ignores it and calls [`FlowEstimator::estimate`].
    ///
    /// # Errors
    /// As [`FlowEstimator::estimate`].
    fn estimate_with_hint(
        &self,
        first: ImageView<'_, [u8; 3]>,
        second: ImageView<'_, [u8; 3]>,
        hint_px: [f32; 2],
    ) -> Result<FlowImage, FlowError> {
        let _ = hint_px;
        self.estimate(first, second)
    }
}

/// Checks that two images have one non-empty size (each `(width, height)`).
pub(crate) fn check_pair(
    (w0, h0): (usize, usize),
    (w1, h1): (usize, usize),
) -> Result<(), FlowError> {
    if (w0, h0) != (w1, h1) {
        return Err(FlowError::SizeMismatch {
            first_width: w0,
            first_height: h0,
            second_width: w1,
            second_height: h1,
        });
    }
    if w0 == 0 || h0 == 0 {
        return Err(FlowError::Empty {
            width: w0,
            height: h0,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn luma_of_primaries_from_a_strided_view() {
        // Two rows of 2 pixels, stride 3: the third pixel of each row is padding.
        let rgb = [
            [255, 0, 0],
            [0, 255, 0],
            [9, 9, 9],
            [0, 0, 255],
            [255, 255, 255],
        ];
        let g = luma(ImageView::new(2, 2, 3, &rgb).unwrap());
        assert_eq!(g.size(), (2, 2));
        let want = [76.245, 149.685, 29.07, 255.0];
        for (a, b) in g.as_slice().iter().zip(want) {
            assert!((a - b).abs() < 1e-3, "{a} vs {b}");
        }
    }

    /// The table lookup gives the formula's bits for every 8-bit RGB triple.
    #[test]
    fn luma_of_is_the_formula_bit_for_bit() {
        for rg in 0..=u16::MAX {
            let [r, g] = rg.to_be_bytes();
            for b in 0..=u8::MAX {
                let want = 0.299 * f32::from(r) + 0.587 * f32::from(g) + 0.114 * f32::from(b);
                assert_eq!(luma_of(&[r, g, b]).to_bits(), want.to_bits(), "{r} {g} {b}");
            }
        }
    }

    #[test]
    fn middlebury_unknown_becomes_nan() {
        let big = UNKNOWN_FLOW_MIN_PX;
        let image = FlowImage::from_vec(
            5,
            1,
            vec![
                [1.5, -2.0],
                [big, 0.0],
                [0.0, -big],
                [f32::INFINITY, 0.0],
                [0.0, 9e8],
            ],
        )
        .unwrap();
        let flow = image.with_unknown_as_nan();
        assert_eq!((flow.width(), flow.height()), (5, 1));
        let v = flow.as_slice();
        assert_eq!(v[0], [1.5, -2.0]);
        assert_eq!(v[4], [0.0, 9e8]);
        for unknown in &v[1..4] {
            assert!(unknown.iter().all(|c| c.is_nan()), "{unknown:?}");
        }
    }

    #[test]
    fn mean_epe_over_mask_and_errors() {
        let a = FlowImage::from_vec(2, 1, vec![[3.0, 4.0], [0.0, 0.0]]).unwrap();
        let b = FlowImage::from_vec(2, 1, vec![[0.0; 2]; 2]).unwrap();
        assert!((a.mean_epe(&b, None).unwrap() - 2.5).abs() < 1e-9);
        assert!((a.mean_epe(&b, Some(&[true, false])).unwrap() - 5.0).abs() < 1e-9);
        assert!(matches!(
            a.mean_epe(&b, Some(&[false, false])),
            Err(FlowError::EmptySelection)
        ));
        let c = FlowImage::from_vec(1, 2, vec![[0.0; 2]; 2]).unwrap();
        assert!(matches!(
            a.mean_epe(&c, None),
            Err(FlowError::SizeMismatch { .. })
        ));
        assert_eq!(a.get(1, 0), Some(&[0.0, 0.0]));
        assert_eq!(a.get(2, 0), None);
    }
}
