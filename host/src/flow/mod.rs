//! Dense optical flow: the [`FlowEstimator`] trait, the flow field type, and a hand-written
//! DIS-class estimator ([`DisFlow`]) that needs no model weights.
//!
//! # Contract
//! - A flow maps the **first** image to the **second**: the pixel at `(x, y)` in `first`
//!   shows the same scene point as `(x + dx, y + dy)` in `second`. Pixel centres sit at
//!   integer coordinates; `dx`, `dy` are in pixels, `dy` grows downwards.
//! - [`Flow`] stores `[dx, dy]` per pixel, row-major, `width · height` entries: the layout
//!   of a Middlebury `.flo` file body ([`Flow::from_image`], [`Flow::to_image`] and
//!   [`crate::io::image::read_flo`] / [`crate::io::image::write_flo`] read and write those).
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

mod densify;
mod pool;
mod pyramid;
mod search;
mod variational;

pub use dis::{DisFlow, FlowParams};

use crate::io::image::FlowImage;

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
    /// A flow too large for an owned image (a side above `u32::MAX`).
    #[error("flow {width}x{height} is too large for an image")]
    TooLarge {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
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

/// `width · height`, or `None` on overflow.
fn area(width: usize, height: usize) -> Option<usize> {
    width.checked_mul(height)
}

fn check_len(width: usize, height: usize, per_pixel: usize, len: usize) -> Result<(), FlowError> {
    let needed = area(width, height).and_then(|n| n.checked_mul(per_pixel));
    if needed == Some(len) {
        Ok(())
    } else {
        Err(FlowError::BadLength {
            width,
            height,
            len,
            needed: needed.unwrap_or(usize::MAX),
        })
    }
}

/// A borrowed 8-bit RGB image, row-major, 3 bytes per pixel, no row padding: the layout of
/// `image::RgbImage::as_raw` and of a decoded 8-bit RGB PNG.
#[derive(Debug, Clone, Copy)]
pub struct RgbView<'a> {
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) data: &'a [u8],
}

impl<'a> RgbView<'a> {
    /// Wraps `data` as a `width x height` RGB image.
    ///
    /// # Errors
    /// [`FlowError::BadLength`] if `data.len() != 3 · width · height`.
    pub fn new(width: usize, height: usize, data: &'a [u8]) -> Result<Self, FlowError> {
        check_len(width, height, 3, data.len())?;
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// Width, pixels.
    #[must_use]
    pub const fn width(&self) -> usize {
        self.width
    }

    /// Height, pixels.
    #[must_use]
    pub const fn height(&self) -> usize {
        self.height
    }

    /// The interleaved bytes.
    #[must_use]
    pub const fn as_bytes(&self) -> &'a [u8] {
        self.data
    }
}

/// A grayscale `f32` image, row-major, no padding. Estimators expect values on a 0-255
/// scale (their thresholds are in those units).
#[derive(Debug, Clone, PartialEq)]
pub struct GrayF32 {
    width: usize,
    height: usize,
    data: Vec<f32>,
}

impl GrayF32 {
    /// Wraps `data` as a `width x height` image.
    ///
    /// # Errors
    /// [`FlowError::BadLength`] if `data.len() != width · height`.
    pub fn new(width: usize, height: usize, data: Vec<f32>) -> Result<Self, FlowError> {
        check_len(width, height, 1, data.len())?;
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// Luma (ITU-R BT.601 weights: 0.299 R + 0.587 G + 0.114 B), 0-255.
    #[must_use]
    pub fn from_rgb(rgb: RgbView<'_>) -> Self {
        let data = rgb
            .data
            .chunks_exact(3)
            .map(|p| 0.299 * f32::from(p[0]) + 0.587 * f32::from(p[1]) + 0.114 * f32::from(p[2]))
            .collect();
        Self {
            width: rgb.width,
            height: rgb.height,
            data,
        }
    }

    /// Width, pixels.
    #[must_use]
    pub const fn width(&self) -> usize {
        self.width
    }

    /// Height, pixels.
    #[must_use]
    pub const fn height(&self) -> usize {
        self.height
    }

    /// The pixel values, row-major.
    #[must_use]
    pub fn as_slice(&self) -> &[f32] {
        &self.data
    }
}

/// A dense flow field: `[dx, dy]` pixels per pixel of the first image, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Flow {
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) data: Vec<[f32; 2]>,
}

impl Flow {
    /// Wraps `data` as a `width x height` flow.
    ///
    /// # Errors
    /// [`FlowError::BadLength`] if `data.len() != width · height`.
    pub fn new(width: usize, height: usize, data: Vec<[f32; 2]>) -> Result<Self, FlowError> {
        check_len(width, height, 1, data.len())?;
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// The flow of a Middlebury `.flo` file ([`crate::io::image::read_flo`]) unchanged,
    /// unknown vectors (`1e10`) included.
    #[must_use]
    pub fn from_image(image: FlowImage) -> Self {
        let (width, height) = (image.width() as usize, image.height() as usize);
        Self {
            width,
            height,
            data: image.into_vec(),
        }
    }

    /// The flow as an owned image, unchanged (for [`crate::io::image::write_flo`]).
    ///
    /// # Errors
    /// [`FlowError::TooLarge`] if a side exceeds `u32::MAX`.
    pub fn to_image(&self) -> Result<FlowImage, FlowError> {
        let too_large = || FlowError::TooLarge {
            width: self.width,
            height: self.height,
        };
        let width = u32::try_from(self.width).map_err(|_| too_large())?;
        let height = u32::try_from(self.height).map_err(|_| too_large())?;
        FlowImage::from_vec(width, height, self.data.clone()).map_err(|_| too_large())
    }

    /// The flow of a Middlebury `.flo` file ([`crate::io::image::read_flo`]) with every
    /// unknown vector ([`is_known_flow`]) replaced by `[NaN, NaN]`, the in-memory mark.
    #[must_use]
    pub fn from_middlebury(image: FlowImage) -> Self {
        let (width, height) = (image.width() as usize, image.height() as usize);
        let data = image
            .into_vec()
            .into_iter()
            .map(|v| if is_known_flow(v) { v } else { [f32::NAN; 2] })
            .collect();
        Self {
            width,
            height,
            data,
        }
    }

    /// Width, pixels.
    #[must_use]
    pub const fn width(&self) -> usize {
        self.width
    }

    /// Height, pixels.
    #[must_use]
    pub const fn height(&self) -> usize {
        self.height
    }

    /// The `[dx, dy]` vectors, row-major.
    #[must_use]
    pub fn as_slice(&self) -> &[[f32; 2]] {
        &self.data
    }

    /// The `[dx, dy]` vectors, row-major, by value.
    #[must_use]
    pub fn into_vec(self) -> Vec<[f32; 2]> {
        self.data
    }

    /// The vector at `(x, y)`, or `None` outside the field.
    #[must_use]
    pub fn get(&self, x: usize, y: usize) -> Option<[f32; 2]> {
        if x < self.width && y < self.height {
            self.data.get(y * self.width + x).copied()
        } else {
            None
        }
    }

    /// Mean endpoint error `|self - truth|` (pixels) over the pixels `mask` selects (all
    /// pixels when `mask` is `None`) whose true flow is known ([`is_known_flow`]; unknown
    /// pixels are skipped). Summed in `f64` in row-major order.
    ///
    /// # Errors
    /// [`FlowError::SizeMismatch`] if the fields differ in size, [`FlowError::BadLength`]
    /// if `mask` has the wrong length, [`FlowError::EmptySelection`] if it selects nothing.
    pub fn mean_epe(&self, truth: &Self, mask: Option<&[bool]>) -> Result<f64, FlowError> {
        if (self.width, self.height) != (truth.width, truth.height) {
            return Err(FlowError::SizeMismatch {
                first_width: self.width,
                first_height: self.height,
                second_width: truth.width,
                second_height: truth.height,
            });
        }
        if let Some(m) = mask {
            check_len(self.width, self.height, 1, m.len())?;
        }
        let mut sum = 0.0f64;
        let mut count = 0usize;
        for (i, (a, b)) in self.data.iter().zip(&truth.data).enumerate() {
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

/// Anything that turns two RGB images into a dense [`Flow`] from the first to the second:
/// the built-in [`DisFlow`] today, a learned network (RAFT through ONNX) later.
pub trait FlowEstimator {
    /// Flow from `first` to `second`.
    ///
    /// # Errors
    /// [`FlowError::SizeMismatch`] if the images differ in size, [`FlowError::Empty`] if
    /// they have no pixels; implementations document any further cases.
    fn estimate(&self, first: RgbView<'_>, second: RgbView<'_>) -> Result<Flow, FlowError>;
}

/// Checks that two images have one non-empty size.
fn check_pair(w0: usize, h0: usize, w1: usize, h1: usize) -> Result<(), FlowError> {
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
    fn views_check_their_length() {
        assert!(RgbView::new(2, 2, &[0; 12]).is_ok());
        assert!(matches!(
            RgbView::new(2, 2, &[0; 11]),
            Err(FlowError::BadLength { needed: 12, .. })
        ));
        assert!(matches!(
            RgbView::new(usize::MAX, 3, &[]),
            Err(FlowError::BadLength {
                needed: usize::MAX,
                ..
            })
        ));
        assert!(GrayF32::new(3, 1, vec![0.0; 2]).is_err());
        assert!(Flow::new(1, 2, vec![[0.0; 2]; 2]).is_ok());
    }

    #[test]
    fn luma_of_primaries() {
        let rgb = [255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255];
        let g = GrayF32::from_rgb(RgbView::new(4, 1, &rgb).unwrap());
        let want = [76.245, 149.685, 29.07, 255.0];
        for (a, b) in g.as_slice().iter().zip(want) {
            assert!((a - b).abs() < 1e-3, "{a} vs {b}");
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
        let flow = Flow::from_middlebury(image);
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
        let a = Flow::new(2, 1, vec![[3.0, 4.0], [0.0, 0.0]]).unwrap();
        let b = Flow::new(2, 1, vec![[0.0; 2]; 2]).unwrap();
        assert!((a.mean_epe(&b, None).unwrap() - 2.5).abs() < 1e-9);
        assert!((a.mean_epe(&b, Some(&[true, false])).unwrap() - 5.0).abs() < 1e-9);
        assert!(matches!(
            a.mean_epe(&b, Some(&[false, false])),
            Err(FlowError::EmptySelection)
        ));
        let c = Flow::new(1, 2, vec![[0.0; 2]; 2]).unwrap();
        assert!(matches!(
            a.mean_epe(&c, None),
            Err(FlowError::SizeMismatch { .. })
        ));
        assert_eq!(a.get(1, 0), Some([0.0, 0.0]));
        assert_eq!(a.get(2, 0), None);
    }
}
