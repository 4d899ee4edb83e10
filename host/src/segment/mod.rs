//! Static (single-frame) instance segmentation of a tabletop RGB-D frame: the labels RISeg
//! starts from and the 0-255 heatmap FindAction chooses pushes from.
//!
//! # Contract
//! - Input: an [`RgbdFrame`] (8-bit RGB and depth in metres, same size, row-major, pixel
//!   `(x, y)` at `y·width + x`; depth `<= 0` or not finite means "no reading") and the
//!   camera's [`Intrinsics`].
//! - Output: a [`Segmentation`] of the same size: `labels` (`0` = background, `1..=n` the
//!   segments, consecutive) and `heatmap` (0-255), calibrated to the paper's FindAction
//!   thresholds `l_u = 150`, `l_l = 120`:
//!   - `>= 150` ([`HEAT_CERTAIN`]): surely inside one separate object;
//!   - `120..=149` ([`HEAT_UNCERTAIN`]): object pixels where objects touch or depth is
//!     unsure (creases, contacts between segments, holes in depth);
//!   - `< 120`: the table and everything that is not an object.
//! - Every [`StaticSegmenter`] returns a [`SegmentError`] for bad input (sizes that do not
//!   match, bad intrinsics, a scene it cannot handle) and never panics.
//!
//! [`ClassicalSegmenter`] is the built-in implementation (table-plane fit, height above the
//! table, region growing over depth and normal continuity); a learned model (UCN,
//! MSMFormer through ONNX, `crate::onnx::OnnxSegmenter` with the feature `onnx`) implements
//! the same trait.

mod classical;
mod edt;
mod geometry;
mod grow;
mod heat;
mod params;
mod plane;
pub mod viz;

use riseg_core::Intrinsics;

use crate::io::image::{Gray8Image, Gray16Image};

pub use classical::{ClassicalOutput, ClassicalSegmenter};
pub use params::SegmenterParams;
pub use plane::TablePlane;

/// Pixels a chunk of the scans that skip runs of pixels with nothing to do: one test
/// without branches a chunk (the compiler vectorises it), then the pixels one by one.
pub(super) const CHUNK_PX: usize = 16;

/// Union-find over `u32` indices (roots are the smallest index), shared with
/// [`crate::eval::ceiling`].
pub(crate) use grow::{find as union_find_root, union as union_find_join};

/// Heatmap values at or above this are "certain" object pixels (the paper's `l_u`): the
/// heatmap is calibrated to FindAction's [`riseg_core::Config::certain_from`].
pub const HEAT_CERTAIN: u8 = riseg_core::Config::PAPER.certain_from;
/// Heatmap values in `HEAT_UNCERTAIN..HEAT_CERTAIN` are "uncertain" (the paper's `l_l`,
/// [`riseg_core::Config::uncertain_from`]).
pub const HEAT_UNCERTAIN: u8 = riseg_core::Config::PAPER.uncertain_from;

/// Why a segmenter could not segment a frame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SegmentError {
    /// The frame has no pixels.
    #[error("the frame is empty ({width}x{height})")]
    Empty {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
    },
    /// More pixels than 32-bit pixel indices can address.
    #[error("the frame is too large ({width}x{height}): at most 2^32 - 1 pixels")]
    TooLarge {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
    },
    /// A buffer does not hold `width·height` pixels.
    #[error("{what} has {got} pixels, a {width}x{height} frame needs {needed}")]
    SizeMismatch {
        /// Which buffer ("rgb", "depth").
        what: &'static str,
        /// Frame width, pixels.
        width: usize,
        /// Frame height, pixels.
        height: usize,
        /// Pixels needed.
        needed: usize,
        /// Pixels given.
        got: usize,
    },
    /// The intrinsics are not finite or a focal length is not positive.
    #[error("invalid camera intrinsics: {0}")]
    Intrinsics(#[from] riseg_core::Error),
    /// A [`SegmenterParams`] field is out of its documented range.
    #[error("invalid segmenter parameter `{name}`: {reason}")]
    BadParams {
        /// The field.
        name: &'static str,
        /// The allowed range.
        reason: &'static str,
    },
    /// No plane with enough support was found, so there is no table to stand objects on.
    #[error(
        "no table plane found: best plane has {inliers} of {candidates} sampled depth points, \
         needs {needed} (is the table in view and is depth valid?)"
    )]
    NoTablePlane {
        /// Sampled points on the best plane.
        inliers: usize,
        /// Sampled points with valid depth.
        candidates: usize,
        /// Points the plane needs.
        needed: usize,
    },
    /// More segments than `u16` labels can hold.
    #[error("{count} segments do not fit in 16-bit labels")]
    TooManySegments {
        /// Segments found.
        count: usize,
    },
    /// An ONNX segmenter failed ([`crate::onnx::OnnxSegmenter`]).
    #[cfg(feature = "onnx")]
    #[error(transparent)]
    Onnx(#[from] crate::onnx::OnnxError),
}

/// One RGB-D frame, borrowed. Construction checks the sizes, so a frame always describes
/// its buffers.
#[derive(Debug, Clone, Copy)]
pub struct RgbdFrame<'a> {
    width: usize,
    height: usize,
    rgb: &'a [[u8; 3]],
    depth_m: &'a [f32],
}

impl<'a> RgbdFrame<'a> {
    /// A frame of `width × height` pixels: `rgb` 8-bit colour, `depth_m` depth along the
    /// optical axis in metres (`<= 0` or not finite: no reading), both row-major.
    ///
    /// # Errors
    /// [`SegmentError::Empty`] for a zero size, [`SegmentError::TooLarge`] beyond
    /// `u32::MAX` pixels, [`SegmentError::SizeMismatch`] if a buffer does not hold
    /// `width·height` pixels.
    pub fn new(
        width: usize,
        height: usize,
        rgb: &'a [[u8; 3]],
        depth_m: &'a [f32],
    ) -> Result<Self, SegmentError> {
        let needed = width.checked_mul(height);
        if needed == Some(0) {
            return Err(SegmentError::Empty { width, height });
        }
        let Some(needed) = needed.filter(|&n| u32::try_from(n).is_ok_and(|n| n < u32::MAX)) else {
            return Err(SegmentError::TooLarge { width, height });
        };
        for (what, got) in [("rgb", rgb.len()), ("depth", depth_m.len())] {
            if got != needed {
                return Err(SegmentError::SizeMismatch {
                    what,
                    width,
                    height,
                    needed,
                    got,
                });
            }
        }
        Ok(Self {
            width,
            height,
            rgb,
            depth_m,
        })
    }

    /// Width, pixels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height, pixels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Colour, row-major.
    #[must_use]
    pub fn rgb(&self) -> &'a [[u8; 3]] {
        self.rgb
    }

    /// Depth in metres, row-major; `<= 0` or not finite where there is no reading.
    #[must_use]
    pub fn depth_m(&self) -> &'a [f32] {
        self.depth_m
    }
}

/// A static segmentation: instance labels and the FindAction heatmap, same size as the frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Segmentation {
    /// Instance labels: `0` background, `1..=n` segments (consecutive).
    pub labels: Gray16Image,
    /// Objectness/uncertainty heatmap, 0-255 (see the module docs for the bands), the
    /// labels' size.
    pub heatmap: Gray8Image,
}

impl Segmentation {
    /// `(width, height)`, pixels.
    #[must_use]
    pub const fn size(&self) -> (usize, usize) {
        self.labels.size()
    }

    /// Number of segments (the largest label).
    #[must_use]
    pub fn segment_count(&self) -> usize {
        self.labels
            .as_slice()
            .iter()
            .copied()
            .max()
            .map_or(0, usize::from)
    }
}

/// Anything that turns one RGB-D frame into labels and a heatmap: the built-in
/// [`ClassicalSegmenter`], or a learned model.
///
/// `&mut self` lets an implementation keep scratch buffers (or an inference session) across
/// frames.
pub trait StaticSegmenter {
    /// Segments `frame`, seen through `intrinsics`.
    ///
    /// # Errors
    /// [`SegmentError`] when the input is invalid or the scene cannot be segmented; the
    /// implementation says which variants it returns.
    fn segment(
        &mut self,
        frame: &RgbdFrame<'_>,
        intrinsics: &Intrinsics,
    ) -> Result<Segmentation, SegmentError>;
}
