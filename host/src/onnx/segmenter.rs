//! [`OnnxSegmenter`]: a UCN / MSMFormer / Mask2Former-style instance segmenter from an ONNX
//! file, as a [`StaticSegmenter`] (the tensor contract is in the [module docs](super)).

use std::path::Path;

use ort::value::TensorElementType;
use riseg_core::Intrinsics;

use super::{
    OnnxError,
    fit::Fit,
    model::{Dim, Expected, Model, Output, fixed_size},
    sidecar::{self, DepthKind, Normalisation, SegmenterSidecar},
};
use crate::io::image::{Gray8Image, Gray16Image};
use crate::segment::{RgbdFrame, SegmentError, Segmentation, StaticSegmenter};

/// What the model outputs.
#[derive(Debug, Clone)]
enum Outputs {
    /// Per-instance mask logits `[1,K,H,W]` and scores `[1,K]`.
    Masks { masks: String, scores: String },
    /// A label map `[1,H,W]`.
    Labels(String),
}

/// A learned static segmenter behind the contract in the [module docs](super).
#[derive(Debug)]
pub struct OnnxSegmenter {
    model: Model,
    sidecar: SegmenterSidecar,
    normalisation: Normalisation,
    fixed: Option<(usize, usize)>,
    outputs: Outputs,
}

impl OnnxSegmenter {
    /// Loads `path` with its sidecar (`path` with extension `.json`, optional) and checks
    /// the model's declared inputs and outputs against the contract.
    ///
    /// # Errors
    /// [`OnnxError`] naming the file (model or sidecar) and the problem: no ONNX Runtime,
    /// not a model, a missing tensor, or a tensor of the wrong type or shape.
    pub fn load(path: &Path) -> Result<Self, OnnxError> {
        let sidecar: SegmenterSidecar = sidecar::read(path)?;
        let normalisation = sidecar::check_common(
            path,
            sidecar.mean,
            sidecar.std,
            sidecar.input_size,
            sidecar.pad_multiple,
        )?;
        if !(0.0..=1.0).contains(&sidecar.score_threshold) {
            return Err(OnnxError::Sidecar {
                path: sidecar::sidecar_path(path),
                problem: "`score_threshold` must be 0 to 1".to_owned(),
            });
        }
        let mut inputs = vec![Expected {
            name: &sidecar.rgb_input,
            ty: TensorElementType::Float32,
            dims: &[Dim::Is(1), Dim::Is(3), Dim::Any("H"), Dim::Any("W")],
        }];
        if let Some(depth) = &sidecar.depth_input {
            inputs.push(Expected {
                name: depth,
                ty: TensorElementType::Float32,
                dims: match sidecar.depth_kind {
                    DepthKind::Depth => &[Dim::Is(1), Dim::Is(1), Dim::Any("H"), Dim::Any("W")],
                    DepthKind::Xyz => &[Dim::Is(1), Dim::Is(3), Dim::Any("H"), Dim::Any("W")],
                },
            });
        }
        let outputs = match &sidecar.labels_output {
            Some(labels) => Outputs::Labels(labels.clone()),
            None => Outputs::Masks {
                masks: sidecar.masks_output.clone(),
                scores: sidecar.scores_output.clone(),
            },
        };
        let expected_outputs = match &outputs {
            Outputs::Labels(labels) => vec![Expected {
                name: labels,
                ty: TensorElementType::Int64,
                dims: &[Dim::Is(1), Dim::Any("H"), Dim::Any("W")],
            }],
            Outputs::Masks { masks, scores } => vec![
                Expected {
                    name: masks,
                    ty: TensorElementType::Float32,
                    dims: &[Dim::Is(1), Dim::Any("K"), Dim::Any("H"), Dim::Any("W")],
                },
                Expected {
                    name: scores,
                    ty: TensorElementType::Float32,
                    dims: &[Dim::Is(1), Dim::Any("K")],
                },
            ],
        };
        let (model, shapes) = Model::load(path, &inputs, &expected_outputs)?;
        let fixed = fixed_size(path, sidecar.input_size, &shapes)?;
        Ok(Self {
            model,
            sidecar,
            normalisation,
            fixed,
            outputs,
        })
    }

    /// Runs the model on `frame` and decodes its outputs at the frame's size.
    fn infer(&mut self, frame: &RgbdFrame<'_>, k: &Intrinsics) -> Result<Segmentation, OnnxError> {
        let (w, h) = (frame.width(), frame.height());
        let fit = Fit::new((w, h), self.fixed, self.sidecar.pad_multiple);
        let (iw, ih) = fit.input;
        let (rgb, depth_m) = (frame.rgb(), frame.depth_m());
        let n = &self.normalisation;
        let colour = fit.input_planes(
            |x, y| -> [f32; 3] {
                let p = rgb[y * w + x];
                core::array::from_fn(|c| n.apply(c, f32::from(p[c])))
            },
            true,
        );
        let mut inputs = vec![(self.sidecar.rgb_input.as_str(), [1, 3, ih, iw], colour)];
        if let Some(name) = &self.sidecar.depth_input {
            let z = |x: usize, y: usize| riseg_core::image::valid_depth(depth_m[y * w + x]);
            let (shape, planes) = match self.sidecar.depth_kind {
                DepthKind::Depth => (
                    [1, 1, ih, iw],
                    fit.input_planes(|x, y| [z(x, y).unwrap_or(0.0)], false),
                ),
                DepthKind::Xyz => (
                    [1, 3, ih, iw],
                    fit.input_planes(
                        |x, y| {
                            z(x, y).map_or([0.0; 3], |z| {
                                let p = k.back_project(x as f32, y as f32, z);
                                [p.x, p.y, p.z]
                            })
                        },
                        false,
                    ),
                ),
            };
            inputs.push((name.as_str(), shape, planes));
        }
        let path = self.model.path.clone();
        let bad = |problem: String| OnnxError::Model {
            path: path.clone(),
            problem,
        };
        match &self.outputs {
            Outputs::Labels(name) => {
                let mut out = self.model.run(inputs, &[name.as_str()])?.into_iter();
                let Some(Output::I64(shape, ids)) = out.next() else {
                    return Err(bad(format!("output `{name}` is not int64")));
                };
                let (ow, oh, ratio) = fit.output_grid(&shape[1..], name).map_err(&bad)?;
                let ids: Vec<i64> = fit
                    .nearest_back((ow, oh), ratio)
                    .into_iter()
                    .map(|i| ids[i])
                    .collect();
                labels_from_ids(w, h, &ids).map_err(bad)
            }
            Outputs::Masks { masks, scores } => {
                let mut out = self
                    .model
                    .run(inputs, &[masks.as_str(), scores.as_str()])?
                    .into_iter();
                let (Some(Output::F32(mshape, logits)), Some(Output::F32(sshape, scores_k))) =
                    (out.next(), out.next())
                else {
                    return Err(bad(format!(
                        "outputs `{masks}`, `{scores}` are not float32"
                    )));
                };
                let count = mshape.get(1).copied().unwrap_or(0);
                if sshape.get(1) != Some(&count) {
                    return Err(bad(format!(
                        "output `{scores}` has {:?} instances, `{masks}` has {count}",
                        sshape.get(1)
                    )));
                }
                let (ow, oh, ratio) = fit.output_grid(&mshape[2..], masks).map_err(&bad)?;
                let plane = ow * oh;
                let mut kept: Vec<(f32, Vec<f32>)> = Vec::new();
                for (i, &score) in scores_k.iter().enumerate() {
                    if score >= self.sidecar.score_threshold {
                        let probs = fit
                            .sample_back(&logits[i * plane..(i + 1) * plane], (ow, oh), ratio)
                            .into_iter()
                            .map(sigmoid)
                            .collect();
                        kept.push((score.min(1.0), probs));
                    }
                }
                // Highest score first: ties in score·probability go to the better instance.
                kept.sort_by(|a, b| b.0.total_cmp(&a.0));
                labels_from_instances(w, h, &kept).map_err(bad)
            }
        }
    }
}

impl StaticSegmenter for OnnxSegmenter {
    /// # Errors
    /// [`SegmentError::Intrinsics`] for bad intrinsics, [`SegmentError::Onnx`] if inference
    /// fails or the outputs break the contract (the message names the model file).
    fn segment(
        &mut self,
        frame: &RgbdFrame<'_>,
        intrinsics: &Intrinsics,
    ) -> Result<Segmentation, SegmentError> {
        intrinsics.check()?;
        Ok(self.infer(frame, intrinsics)?)
    }
}

fn sigmoid(logit: f32) -> f32 {
    1.0 / (1.0 + libm::expf(-logit))
}

/// Heatmap of an object pixel whose winning instance beats the runner-up by `margin`
/// (score·probability, 0-1), rounded: `120 + 60·margin` (at most 149) below 0.5
/// (uncertain), `150 + 210·(margin − 0.5)` from 0.5 (certain, 150-255).
fn object_heat(margin: f32) -> u8 {
    let m = margin.clamp(0.0, 1.0);
    let heat = if m < 0.5 {
        (120.0 + libm::roundf(60.0 * m)).min(149.0)
    } else {
        150.0 + libm::roundf(210.0 * (m - 0.5))
    };
    heat.min(255.0) as u8
}

/// Labels and heatmap from instances `(score, mask probability per pixel)`, best first
/// (the derivation is in the [module docs](super)).
fn labels_from_instances(
    w: usize,
    h: usize,
    instances: &[(f32, Vec<f32>)],
) -> Result<Segmentation, String> {
    let mut winner = vec![0usize; w * h];
    let mut heat = vec![0u8; w * h];
    for (p, (win, hot)) in winner.iter_mut().zip(heat.iter_mut()).enumerate() {
        let (mut best, mut best_c, mut second_c) = (None, 0.0f32, 0.0f32);
        for (k, (score, probs)) in instances.iter().enumerate() {
            let c = score * probs[p];
            let claims = probs[p] > 0.5;
            if claims && (best.is_none() || c > best_c) {
                if best.is_some() {
                    second_c = second_c.max(best_c);
                }
                best = Some(k);
                best_c = c;
            } else {
                second_c = second_c.max(c);
            }
        }
        match best {
            Some(k) => {
                *win = k + 1;
                *hot = object_heat(best_c - second_c);
            }
            None => {
                let background = libm::roundf(100.0 * second_c.clamp(0.0, 1.0)) as u8;
                *hot = background;
            }
        }
    }
    let ids: Vec<i64> = winner.iter().map(|&k| k as i64).collect();
    let mut seg = labels_from_ids(w, h, &ids)?;
    seg.heatmap = Gray8Image::from_vec(w, h, heat).map_err(|e| e.to_string())?;
    Ok(seg)
}

/// Labels from instance ids per pixel (`<= 0` background), renumbered `1..=n` in
/// increasing id order; the heatmap is 255 on labelled pixels, 0 elsewhere (a label map
/// carries no confidence).
fn labels_from_ids(w: usize, h: usize, ids: &[i64]) -> Result<Segmentation, String> {
    let mut distinct: Vec<i64> = ids.iter().copied().filter(|&i| i > 0).collect();
    distinct.sort_unstable();
    distinct.dedup();
    if distinct.len() > usize::from(u16::MAX) {
        return Err(format!(
            "{} instances do not fit in 16-bit labels",
            distinct.len()
        ));
    }
    let labels: Vec<u16> = ids
        .iter()
        .map(|&i| {
            distinct
                .binary_search(&i)
                .map_or(0, |rank| u16::try_from(rank + 1).unwrap_or(u16::MAX))
        })
        .collect();
    let heat = labels
        .iter()
        .map(|&l| if l == 0 { 0 } else { 255 })
        .collect();
    Ok(Segmentation {
        labels: Gray16Image::from_vec(w, h, labels).map_err(|e| e.to_string())?,
        heatmap: Gray8Image::from_vec(w, h, heat).map_err(|e| e.to_string())?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heat_bands() {
        assert_eq!(object_heat(0.0), 120);
        assert_eq!(object_heat(0.49), 149);
        assert_eq!(object_heat(0.5), 150);
        assert_eq!(object_heat(1.0), 255);
    }

    #[test]
    fn instances_to_labels_and_heat() {
        // Pixel 0: both claim, 0.9 vs 0.8 -> instance 1, margin 0.1 (uncertain).
        // Pixel 1: only the second claims -> its label, margin 0.8 (certain).
        // Pixel 2: nobody claims -> background.
        let instances = vec![(0.9, vec![1.0, 0.0, 0.0]), (0.8, vec![1.0, 1.0, 0.2])];
        let seg = labels_from_instances(3, 1, &instances).unwrap();
        assert_eq!(seg.labels.as_slice(), &[1, 2, 0]);
        assert_eq!(seg.heatmap.as_slice(), &[126, 213, 16]);
    }

    #[test]
    fn ids_renumbered() {
        let seg = labels_from_ids(4, 1, &[7, -1, 3, 7]).unwrap();
        assert_eq!(seg.labels.as_slice(), &[2, 0, 1, 2]);
        assert_eq!(seg.heatmap.as_slice(), &[255, 0, 255, 255]);
    }
}
