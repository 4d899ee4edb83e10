//! Learned models from ONNX files (feature `onnx`): [`OnnxSegmenter`] (a UCN / MSMFormer /
//! Mask2Former-style static segmenter) and [`OnnxFlow`] (a RAFT-style optical flow),
//! through ONNX Runtime (`ort`, loading the shared library at run time).
//!
//! # Finding ONNX Runtime
//! `ORT_DYLIB_PATH` (a `libonnxruntime.so` / `.dylib` / `onnxruntime.dll`, 1.17 or newer),
//! else the `capi/` folder of the `onnxruntime` Python wheel `python3` imports
//! (`python3 -m pip install onnxruntime==1.32.0`). A missing or unusable library is an
//! [`OnnxError::Runtime`] saying what to install.
//!
//! # Tensor contract
//! All tensors are NCHW with batch 1; names are the sidecar's (defaults in brackets).
//!
//! **Segmenter** ([`OnnxSegmenter`], [`SegmenterSidecar`]):
//! - in `rgb_input` \[`rgb`\]: float32 `[1,3,H,W]`, R, G, B, `(pixel/255 − mean)/std`
//!   (default ImageNet mean `[0.485,0.456,0.406]`, std `[0.229,0.224,0.225]`);
//! - optional in `depth_input` \[none\]: float32, `depth_kind` `"depth"` `[1,1,H,W]`
//!   metres along the optical axis, or `"xyz"` `[1,3,H,W]` the organised point cloud
//!   (camera frame, X right, Y down, Z forward, metres, as UCN takes it); 0 = no reading;
//! - out, either `masks_output` \[`masks`\] float32 `[1,K,h,w]` mask logits with
//!   `scores_output` \[`scores`\] float32 `[1,K]` instance scores 0-1 (Mask2Former /
//!   MSMFormer style), or, when `labels_output` is set, int64 `[1,h,w]` instance ids
//!   (`<= 0` background).
//!
//! Labels: instances scoring below `score_threshold` \[0.5\] are dropped; an instance
//! claims the pixels where its mask probability `sigmoid(logit)` exceeds 0.5; among the
//! claimants the highest `score·probability` wins. Labels are renumbered `1..=n`
//! (instances by decreasing score; label-map ids by increasing id).
//!
//! Heatmap (0-255, FindAction's bands, see [`crate::segment`]), derived from the model's
//! own confidences as RISeg derives it from MSMFormer's: with `c` the winner's
//! `score·probability` and `c₂` the largest `score·probability` of any other kept instance
//! at that pixel, the margin `m = c − c₂` says how sure the model is which object the pixel
//! belongs to. Object pixels: `m < 0.5` gives `120 + 60·m` (at most 149, uncertain: two
//! instances compete, as where touching objects meet); `m >= 0.5` gives
//! `150 + 210·(m − 0.5)` (certain). Background pixels: `100·c₂` (at most 50, below the
//! uncertain band). A label map carries no confidence: its labelled pixels are 255 and
//! the rest 0, so FindAction finds no uncertain region; export masks and scores for it.
//!
//! **Flow** ([`OnnxFlow`], [`FlowSidecar`]):
//! - in `first_input` \[`image1`\], `second_input` \[`image2`\]: float32 `[1,3,H,W]`,
//!   `(pixel/255 − mean)/std`, default mean 0 and std 1/255 (raw 0-255, as RAFT takes it);
//! - out `flow_output` \[`flow`\]: float32 `[1,2,H/r,W/r]`, `(dx, dy)` from the first image
//!   to the second (see [`crate::flow`]) in pixels of its own grid, for a whole `r`
//!   (1, or 8 for RAFT's coarse flow): upsampled bilinearly and multiplied by `r`. NaN
//!   or infinite outputs are an error.
//!
//! **Sizes** (both): with a fixed input size (the sidecar's `input_size` `[W, H]`, else the
//! model's declared `H`, `W`), the frame is scaled to fit with its aspect kept, at the top
//! left; otherwise it keeps its size and is padded to a multiple of `pad_multiple` (32 for
//! the segmenter, 8 for the flow). Padding repeats the edge pixels. Outputs are sampled back
//! to the frame (labels: nearest; logits and flow: bilinear; flow rescaled to frame pixels).
//!
//! # Sidecar
//! `model.onnx` reads `model.json` next to it if present: a JSON object with any of the
//! keys above (unknown keys are an error). At load, the model's declared inputs and outputs
//! are checked against the contract: a missing tensor, an extra input, a wrong element type,
//! rank or fixed dimension is an [`OnnxError::Model`] naming the file, the tensor, and the
//! expected and declared type and shape.

mod fit;
mod flow;
mod model;
mod runtime;
mod segmenter;
mod sidecar;

use std::path::PathBuf;

pub use flow::OnnxFlow;
pub use segmenter::OnnxSegmenter;
pub use sidecar::{DepthKind, FlowSidecar, Normalisation, SegmenterSidecar, sidecar_path};

/// Why an ONNX model could not be loaded or run.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum OnnxError {
    /// ONNX Runtime itself is missing or unusable; the message says what to install.
    #[error("{0}")]
    Runtime(String),
    /// The model file is missing, not ONNX, breaks the tensor contract, or failed to run.
    #[error("{}: {problem}", path.display())]
    Model {
        /// The `.onnx` file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// The sidecar file is unreadable or holds a bad value.
    #[error("{}: {problem}", path.display())]
    Sidecar {
        /// The `.json` file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
}
