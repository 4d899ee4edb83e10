//! The sidecar file next to a model (`seg.onnx` -> `seg.json`): tensor names, input
//! normalisation and input size. Every key is optional; an absent file means all defaults.
//! Unknown keys are an error (a typo must not silently fall back to a default).

use std::path::{Path, PathBuf};

use serde::{Deserialize, de::DeserializeOwned};

use super::OnnxError;

/// Per-channel colour normalisation: the model sees `(pixel / 255 - mean) / std`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Normalisation {
    /// Mean per channel (R, G, B), on the 0-1 scale.
    pub mean: [f32; 3],
    /// Standard deviation per channel (R, G, B), on the 0-1 scale; positive.
    pub std: [f32; 3],
}

impl Normalisation {
    /// ImageNet statistics (Mask2Former, MSMFormer, UCN).
    pub const IMAGENET: Self = Self {
        mean: [0.485, 0.456, 0.406],
        std: [0.229, 0.224, 0.225],
    };
    /// Raw 0-255 values, as RAFT-style flow networks take them.
    pub const RAW_0_255: Self = Self {
        mean: [0.0; 3],
        std: [1.0 / 255.0; 3],
    };

    /// The model's input value of a colour channel `c` of 8-bit value `value`.
    #[must_use]
    pub fn apply(&self, c: usize, value: f32) -> f32 {
        (value / 255.0 - self.mean[c]) / self.std[c]
    }
}

/// How depth enters a segmenter (`depth_kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DepthKind {
    /// `[1,1,H,W]`: depth along the optical axis, metres, 0 = no reading.
    Depth,
    /// `[1,3,H,W]`: the organised point cloud X, Y, Z in the camera frame (X right, Y down,
    /// Z forward), metres, 0 = no reading (UCN's input).
    Xyz,
}

/// A segmenter's sidecar ([`super::OnnxSegmenter`]); `Default` is the contract's defaults.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SegmenterSidecar {
    /// Colour input name.
    pub rgb_input: String,
    /// Depth input name; `None`: the model takes colour only.
    pub depth_input: Option<String>,
    /// What the depth input holds.
    pub depth_kind: DepthKind,
    /// Label-map output name (`[1,H,W]` int64); when set, masks and scores are not read.
    pub labels_output: Option<String>,
    /// Mask-logit output name (`[1,K,H,W]` float32).
    pub masks_output: String,
    /// Instance-score output name (`[1,K]` float32, 0-1).
    pub scores_output: String,
    /// Colour normalisation mean (0-1 scale, R, G, B).
    pub mean: [f32; 3],
    /// Colour normalisation standard deviation (0-1 scale, R, G, B).
    pub std: [f32; 3],
    /// Fixed input `[width, height]`, pixels; `None`: the model's declared size, or the
    /// frame's size padded to `pad_multiple` if the model's is dynamic.
    pub input_size: Option<[usize; 2]>,
    /// A dynamic input's sides are padded up to a multiple of this, pixels.
    pub pad_multiple: usize,
    /// Instances scoring below this are dropped (0-1).
    pub score_threshold: f32,
}

impl Default for SegmenterSidecar {
    fn default() -> Self {
        Self {
            rgb_input: "rgb".to_owned(),
            depth_input: None,
            depth_kind: DepthKind::Depth,
            labels_output: None,
            masks_output: "masks".to_owned(),
            scores_output: "scores".to_owned(),
            mean: Normalisation::IMAGENET.mean,
            std: Normalisation::IMAGENET.std,
            input_size: None,
            pad_multiple: 32,
            score_threshold: 0.5,
        }
    }
}

/// A flow network's sidecar ([`super::OnnxFlow`]); `Default` is the contract's defaults.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FlowSidecar {
    /// First image's input name.
    pub first_input: String,
    /// Second image's input name.
    pub second_input: String,
    /// Flow output name (`[1,2,H,W]` or `[1,2,H/r,W/r]` float32).
    pub flow_output: String,
    /// Colour normalisation mean (0-1 scale, R, G, B).
    pub mean: [f32; 3],
    /// Colour normalisation standard deviation (0-1 scale, R, G, B).
    pub std: [f32; 3],
    /// Fixed input `[width, height]`, pixels (see [`SegmenterSidecar::input_size`]).
    pub input_size: Option<[usize; 2]>,
    /// A dynamic input's sides are padded up to a multiple of this, pixels.
    pub pad_multiple: usize,
}

impl Default for FlowSidecar {
    fn default() -> Self {
        Self {
            first_input: "image1".to_owned(),
            second_input: "image2".to_owned(),
            flow_output: "flow".to_owned(),
            mean: Normalisation::RAW_0_255.mean,
            std: Normalisation::RAW_0_255.std,
            input_size: None,
            pad_multiple: 8,
        }
    }
}

/// The sidecar path of `model`: the same name with extension `.json`.
#[must_use]
pub fn sidecar_path(model: &Path) -> PathBuf {
    model.with_extension("json")
}

/// Reads the sidecar of `model` if it exists, else the defaults; `(sidecar, its path)`.
pub(super) fn read<T: DeserializeOwned + Default>(model: &Path) -> Result<T, OnnxError> {
    let path = sidecar_path(model);
    let bad = |problem: String| OnnxError::Sidecar {
        path: path.clone(),
        problem,
    };
    match std::fs::read(&path) {
        Ok(bytes) => serde_json::from_slice(&bytes).map_err(|e| bad(e.to_string())),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(T::default()),
        Err(e) => Err(bad(e.to_string())),
    }
}

/// Checks the fields both sidecars share; the error names the sidecar of `model`.
pub(super) fn check_common(
    model: &Path,
    mean: [f32; 3],
    std: [f32; 3],
    input_size: Option<[usize; 2]>,
    pad_multiple: usize,
) -> Result<Normalisation, OnnxError> {
    let bad = |problem: &str| OnnxError::Sidecar {
        path: sidecar_path(model),
        problem: problem.to_owned(),
    };
    if !mean.iter().all(|m| m.is_finite()) {
        return Err(bad("`mean` must be finite"));
    }
    if !std.iter().all(|s| s.is_finite() && *s > 0.0) {
        return Err(bad("`std` must be finite and positive"));
    }
    if input_size.is_some_and(|[w, h]| w == 0 || h == 0 || w > 16_384 || h > 16_384) {
        return Err(bad(
            "`input_size` must be [width, height], 1 to 16384 pixels each",
        ));
    }
    if !(1..=1024).contains(&pad_multiple) {
        return Err(bad("`pad_multiple` must be 1 to 1024"));
    }
    Ok(Normalisation { mean, std })
}
