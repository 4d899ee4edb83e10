//! [`OnnxFlow`]: a RAFT / SEA-RAFT / NeuFlow-style optical flow network from an ONNX file,
//! as a [`FlowEstimator`] (the tensor contract is in the [module docs](super)).

use std::{path::Path, sync::Mutex};

use ort::value::TensorElementType;
use riseg_core::ImageView;

use super::{
    OnnxError,
    fit::Fit,
    model::{Dim, Expected, Model, Output, fixed_size},
    sidecar::{self, FlowSidecar, Normalisation},
};
use crate::flow::{FlowError, FlowEstimator, check_pair};
use crate::io::image::FlowImage;

/// A learned optical flow behind the contract in the [module docs](super).
///
/// The session sits behind a mutex ([`FlowEstimator::estimate`] takes `&self`): calls
/// from several threads run one at a time.
#[derive(Debug)]
pub struct OnnxFlow {
    model: Mutex<Model>,
    sidecar: FlowSidecar,
    normalisation: Normalisation,
    fixed: Option<(usize, usize)>,
}

impl OnnxFlow {
    /// Loads `path` with its sidecar (`path` with extension `.json`, optional) and checks
    /// the model's declared inputs and output against the contract.
    ///
    /// # Errors
    /// [`OnnxError`] naming the file (model or sidecar) and the problem.
    pub fn load(path: &Path) -> Result<Self, OnnxError> {
        let sidecar: FlowSidecar = sidecar::read(path)?;
        let normalisation = sidecar::check_common(
            path,
            sidecar.mean,
            sidecar.std,
            sidecar.input_size,
            sidecar.pad_multiple,
        )?;
        let image = [Dim::Is(1), Dim::Is(3), Dim::Any("H"), Dim::Any("W")];
        let inputs = [&sidecar.first_input, &sidecar.second_input].map(|name| Expected {
            name,
            ty: TensorElementType::Float32,
            dims: &image,
        });
        let output = Expected {
            name: &sidecar.flow_output,
            ty: TensorElementType::Float32,
            dims: &[Dim::Is(1), Dim::Is(2), Dim::Any("H"), Dim::Any("W")],
        };
        let (model, shapes) = Model::load(path, &inputs, &[output])?;
        let fixed = fixed_size(path, sidecar.input_size, &shapes)?;
        Ok(Self {
            model: Mutex::new(model),
            sidecar,
            normalisation,
            fixed,
        })
    }

    fn infer(
        &self,
        first: ImageView<'_, [u8; 3]>,
        second: ImageView<'_, [u8; 3]>,
    ) -> Result<FlowImage, OnnxError> {
        let (w, h) = first.size();
        let fit = Fit::new((w, h), self.fixed, self.sidecar.pad_multiple);
        let (iw, ih) = fit.input;
        let n = &self.normalisation;
        let planes = |image: ImageView<'_, [u8; 3]>| {
            fit.input_planes(
                |x, y| -> [f32; 3] {
                    let p = image.get(x, y).copied().unwrap_or_default();
                    core::array::from_fn(|c| n.apply(c, f32::from(p[c])))
                },
                true,
            )
        };
        let inputs = vec![
            (
                self.sidecar.first_input.as_str(),
                [1, 3, ih, iw],
                planes(first),
            ),
            (
                self.sidecar.second_input.as_str(),
                [1, 3, ih, iw],
                planes(second),
            ),
        ];
        let name = self.sidecar.flow_output.as_str();
        let mut model = self.model.lock().map_err(|_| {
            OnnxError::Runtime("an earlier inference panicked; load the model again".to_owned())
        })?;
        let out = model.run(inputs, &[name])?.into_iter().next();
        let bad = |problem: String| OnnxError::Model {
            path: model.path.clone(),
            problem,
        };
        let Some(Output::F32(shape, values)) = out else {
            return Err(bad(format!("output `{name}` is not float32")));
        };
        let (ow, oh, ratio) = fit.output_grid(&shape[2..], name).map_err(&bad)?;
        let plane = ow * oh;
        // Output-grid pixels -> model-input pixels (·ratio) -> frame pixels (/scale).
        let to_frame = ratio as f32 / fit.scale;
        let dx = fit.sample_back(&values[..plane], (ow, oh), ratio);
        let dy = fit.sample_back(&values[plane..2 * plane], (ow, oh), ratio);
        let flow = dx
            .into_iter()
            .zip(dy)
            .map(|(dx, dy)| [dx * to_frame, dy * to_frame])
            .collect();
        FlowImage::from_vec(w, h, flow).map_err(|e| bad(e.to_string()))
    }
}

impl FlowEstimator for OnnxFlow {
    /// # Errors
    /// [`FlowError::SizeMismatch`] / [`FlowError::Empty`] for bad image pairs,
    /// [`FlowError::Onnx`] if inference fails or the output breaks the contract.
    fn estimate(
        &self,
        first: ImageView<'_, [u8; 3]>,
        second: ImageView<'_, [u8; 3]>,
    ) -> Result<FlowImage, FlowError> {
        check_pair(first.size(), second.size())?;
        Ok(self.infer(first, second)?)
    }
}
