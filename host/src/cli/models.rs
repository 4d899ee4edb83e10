//! `--segmenter` and `--flow`: the built-in static segmenter and optical flow, or learned
//! ones from ONNX files (feature `onnx`, `riseg::onnx`), behind one type each so the
//! commands run either.

use std::path::PathBuf;

use clap::Args;
use riseg_core::{ImageView, Intrinsics};

use crate::flow::{DisFlow, FlowError, FlowEstimator};
use crate::io::image::FlowImage;
use crate::rig::tracker::{Settings, TrackError, Tracker};
use crate::segment::{
    ClassicalSegmenter, RgbdFrame, SegmentError, Segmentation, SegmenterParams, StaticSegmenter,
};

/// What `--segmenter` and `--flow` document in `--help`.
pub(super) const MODELS_HELP: &str = "\
Learned models: --segmenter PATH.onnx and --flow PATH.onnx replace the built-in \
segmenter and flow by ONNX models (riseg built with `--features onnx`; ONNX Runtime from \
ORT_DYLIB_PATH or the onnxruntime Python wheel, `python3 -m pip install \
onnxruntime==1.32.0`). An optional sidecar PATH.json next to each model names its \
tensors and sets normalisation and input size. Tensor contract (batch 1, NCHW):
  segmenter in   rgb [1,3,H,W] float32, (pixel/255 - mean)/std, ImageNet mean/std by
                 default; optional depth [1,1,H,W] metres or xyz [1,3,H,W] camera-frame
                 point cloud, metres (sidecar depth_input, depth_kind)
  segmenter out  masks [1,K,h,w] float32 logits + scores [1,K] float32 0-1, or (sidecar
                 labels_output) a label map [1,h,w] int64, <= 0 background; the 0-255
                 heatmap comes from the winning instance's score x mask probability
                 minus the runner-up's (margin >= 0.5: certain, >= 150)
  flow in        image1, image2 [1,3,H,W] float32, raw 0-255 by default
  flow out       flow [1,2,H/r,W/r] float32, pixels of its own grid (r = 1 or 8, ...):
                 upsampled and multiplied by r
A dynamic input is padded to a multiple of 32 (segmenter) or 8 (flow); a fixed one gets \
the frame scaled to fit. Sidecar keys: rgb_input, depth_input, depth_kind, masks_output, \
scores_output, labels_output, score_threshold, first_input, second_input, flow_output, \
mean, std, input_size [W, H], pad_multiple. See the riseg::onnx docs.";

/// A `--segmenter` or `--flow` value.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum ModelArg {
    /// The built-in model (no weights).
    #[default]
    Builtin,
    /// An ONNX file.
    #[cfg(feature = "onnx")]
    Onnx(PathBuf),
}

/// Parses `builtin` or a path ending in `.onnx`; without the `onnx` feature a path is an
/// error that says how to build with it.
///
/// # Errors
/// Any other value, as a message for clap.
pub fn parse_model(text: &str) -> Result<ModelArg, String> {
    if text == "builtin" {
        return Ok(ModelArg::Builtin);
    }
    let path = PathBuf::from(text);
    if !path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("onnx"))
    {
        return Err("expected `builtin` or the path of an .onnx file".to_owned());
    }
    #[cfg(feature = "onnx")]
    return Ok(ModelArg::Onnx(path));
    #[cfg(not(feature = "onnx"))]
    Err(format!(
        "{}: this riseg was built without ONNX support; rebuild it with `--features onnx` \
         (cargo build --release --features onnx)",
        path.display()
    ))
}

impl ModelArg {
    /// The static segmenter: the built-in one with `params`, or the ONNX model.
    ///
    /// # Errors
    /// Bad `params`, or the model cannot be loaded (the error names the file).
    pub fn segmenter(&self, params: SegmenterParams) -> Result<AnySegmenter, SegmentError> {
        Ok(match self {
            Self::Builtin => AnySegmenter::Builtin(Box::new(ClassicalSegmenter::new(params)?)),
            #[cfg(feature = "onnx")]
            Self::Onnx(path) => AnySegmenter::Onnx(Box::new(
                crate::onnx::OnnxSegmenter::load(path).map_err(SegmentError::Onnx)?,
            )),
        })
    }

    /// The optical flow: `builtin()` or the ONNX model.
    ///
    /// # Errors
    /// `builtin`'s error, or the model cannot be loaded (the error names the file).
    pub fn flow(
        &self,
        builtin: impl FnOnce() -> Result<DisFlow, FlowError>,
    ) -> Result<AnyFlow, FlowError> {
        Ok(match self {
            Self::Builtin => AnyFlow::Builtin(builtin()?),
            #[cfg(feature = "onnx")]
            Self::Onnx(path) => AnyFlow::Onnx(Box::new(
                crate::onnx::OnnxFlow::load(path).map_err(FlowError::Onnx)?,
            )),
        })
    }
}

/// `--segmenter` and `--flow` together (`run`, `demo`, `bench`).
#[derive(Debug, Clone, Default, PartialEq, Eq, Args)]
pub struct Models {
    /// Static segmenter: `builtin` (the classical depth/normal segmenter) or PATH.onnx
    /// (feature `onnx`; contract in the long help).
    #[arg(long, value_name = "builtin|PATH.onnx", default_value = "builtin", value_parser = parse_model)]
    pub segmenter: ModelArg,
    /// Optical flow: `builtin` (DIS) or PATH.onnx (feature `onnx`; contract in the long
    /// help).
    #[arg(long = "flow", value_name = "builtin|PATH.onnx", default_value = "builtin", value_parser = parse_model)]
    pub flow: ModelArg,
}

impl Models {
    /// A tracker running these models with `settings` (the built-in ones take theirs
    /// from it; `flow_threads` as [`DisFlow::with_threads`], `None` for the default).
    ///
    /// # Errors
    /// [`TrackError`] naming the stage that cannot be built.
    pub fn tracker(
        &self,
        settings: &Settings,
        flow_threads: Option<usize>,
    ) -> Result<Tracker<AnySegmenter, AnyFlow>, TrackError> {
        let flow = self.flow.flow(|| {
            let dis = DisFlow::new(settings.flow)?;
            match flow_threads {
                Some(threads) => dis.with_threads(threads),
                None => Ok(dis),
            }
        })?;
        Tracker::new(
            self.segmenter.segmenter(settings.segmenter)?,
            flow,
            settings.core,
        )
    }
}

/// The built-in segmenter or an ONNX one (boxed: the two differ much in size).
#[derive(Debug)]
pub enum AnySegmenter {
    /// [`ClassicalSegmenter`].
    Builtin(Box<ClassicalSegmenter>),
    /// [`crate::onnx::OnnxSegmenter`].
    #[cfg(feature = "onnx")]
    Onnx(Box<crate::onnx::OnnxSegmenter>),
}

impl StaticSegmenter for AnySegmenter {
    fn segment(
        &mut self,
        frame: &RgbdFrame<'_>,
        intrinsics: &Intrinsics,
    ) -> Result<Segmentation, SegmentError> {
        match self {
            Self::Builtin(s) => s.segment(frame, intrinsics),
            #[cfg(feature = "onnx")]
            Self::Onnx(s) => s.segment(frame, intrinsics),
        }
    }
}

/// The built-in flow or an ONNX one.
#[derive(Debug)]
pub enum AnyFlow {
    /// [`DisFlow`].
    Builtin(DisFlow),
    /// [`crate::onnx::OnnxFlow`].
    #[cfg(feature = "onnx")]
    Onnx(Box<crate::onnx::OnnxFlow>),
}

impl FlowEstimator for AnyFlow {
    fn estimate(
        &self,
        first: ImageView<'_, [u8; 3]>,
        second: ImageView<'_, [u8; 3]>,
    ) -> Result<FlowImage, FlowError> {
        match self {
            Self::Builtin(f) => f.estimate(first, second),
            #[cfg(feature = "onnx")]
            Self::Onnx(f) => f.estimate(first, second),
        }
    }

    fn estimate_with_hint(
        &self,
        first: ImageView<'_, [u8; 3]>,
        second: ImageView<'_, [u8; 3]>,
        hint_px: [f32; 2],
    ) -> Result<FlowImage, FlowError> {
        match self {
            Self::Builtin(f) => f.estimate_with_hint(first, second, hint_px),
            #[cfg(feature = "onnx")]
            Self::Onnx(f) => f.estimate_with_hint(first, second, hint_px),
        }
    }
}
