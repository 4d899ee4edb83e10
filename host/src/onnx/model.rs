//! One ONNX session and the checks of its declared inputs and outputs against the contract.

use std::path::{Path, PathBuf};

use ort::{
    session::Session,
    value::{Outlet, Tensor, TensorElementType, ValueType},
};

use super::{OnnxError, runtime, sidecar};

/// One dimension of a contract shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Dim {
    /// Exactly this many (a dynamic model dimension is accepted too).
    Is(i64),
    /// Any size (named in messages).
    Any(&'static str),
}

/// A tensor the contract expects: name, element type, shape.
#[derive(Debug, Clone, Copy)]
pub(super) struct Expected<'a> {
    pub name: &'a str,
    pub ty: TensorElementType,
    pub dims: &'a [Dim],
}

/// An output read back: its shape and values.
#[derive(Debug)]
pub(super) enum Output {
    F32(Vec<usize>, Vec<f32>),
    I64(Vec<usize>, Vec<i64>),
}

/// A loaded model: its file (for messages) and the session.
#[derive(Debug)]
pub(super) struct Model {
    pub path: PathBuf,
    session: Session,
}

impl Model {
    /// Loads `path` and checks its inputs (exactly `inputs`) and outputs (at least
    /// `outputs`); returns the model with each input's declared shape (`-1` = dynamic).
    pub fn load(
        path: &Path,
        inputs: &[Expected<'_>],
        outputs: &[Expected<'_>],
    ) -> Result<(Self, Vec<Vec<i64>>), OnnxError> {
        let bad = |problem: String| OnnxError::Model {
            path: path.to_owned(),
            problem,
        };
        if !path.is_file() {
            return Err(bad("no such file".to_owned()));
        }
        let environment = runtime::environment()?;
        let session = Session::builder(environment)
            .and_then(|mut builder| builder.commit_from_file(path))
            .map_err(|e| bad(format!("not a model ONNX Runtime can load: {e}")))?;
        let declared: Vec<&str> = session.inputs().iter().map(Outlet::name).collect();
        if let Some(extra) = declared
            .iter()
            .find(|name| !inputs.iter().any(|e| e.name == **name))
        {
            return Err(bad(format!(
                "input `{extra}` is not in the contract (expected inputs: {}; the sidecar \
                 names them)",
                names(inputs)
            )));
        }
        let mut shapes = Vec::with_capacity(inputs.len());
        for expected in inputs {
            shapes.push(check(path, "input", session.inputs(), expected)?);
        }
        for expected in outputs {
            check(path, "output", session.outputs(), expected)?;
        }
        Ok((
            Self {
                path: path.to_owned(),
                session,
            },
            shapes,
        ))
    }

    /// Runs the model on `inputs` (`(name, shape, values)`) and reads `outputs` back.
    pub fn run(
        &mut self,
        inputs: Vec<(&str, [usize; 4], Vec<f32>)>,
        outputs: &[&str],
    ) -> Result<Vec<Output>, OnnxError> {
        let path = self.path.clone();
        let bad = |problem: String| OnnxError::Model {
            path: path.clone(),
            problem,
        };
        let mut values = Vec::with_capacity(inputs.len());
        for (name, shape, data) in inputs {
            let tensor = Tensor::from_array((shape, data))
                .map_err(|e| bad(format!("input `{name}`: {e}")))?;
            values.push((name.to_owned(), tensor));
        }
        let results = self
            .session
            .run(values)
            .map_err(|e| bad(format!("inference failed: {e}")))?;
        outputs
            .iter()
            .map(|&name| {
                let value = results
                    .get(name)
                    .ok_or_else(|| bad(format!("output `{name}` missing from the results")))?;
                let shape_of = |shape: &[i64]| {
                    shape
                        .iter()
                        .map(|&d| usize::try_from(d).unwrap_or(0))
                        .collect::<Vec<_>>()
                };
                if let Ok((shape, data)) = value.try_extract_tensor::<f32>() {
                    if data.iter().any(|v| !v.is_finite()) {
                        return Err(bad(format!("output `{name}` holds NaN or infinity")));
                    }
                    return Ok(Output::F32(shape_of(shape), data.to_vec()));
                }
                value
                    .try_extract_tensor::<i64>()
                    .map(|(shape, data)| Output::I64(shape_of(shape), data.to_vec()))
                    .map_err(|e| bad(format!("output `{name}`: {e}")))
            })
            .collect()
    }
}

/// The names of `tensors`, for messages.
fn names(tensors: &[Expected<'_>]) -> String {
    tensors
        .iter()
        .map(|e| format!("`{}`", e.name))
        .collect::<Vec<_>>()
        .join(", ")
}

/// `expected` as text: `float32 [1, 3, H, W]`.
fn contract_text(expected: &Expected<'_>) -> String {
    let dims: Vec<String> = expected
        .dims
        .iter()
        .map(|d| match d {
            Dim::Is(n) => n.to_string(),
            Dim::Any(name) => (*name).to_owned(),
        })
        .collect();
    format!("{} [{}]", type_text(expected.ty), dims.join(", "))
}

/// ONNX's name of an element type (numpy's for the common ones).
fn type_text(ty: TensorElementType) -> String {
    match ty {
        TensorElementType::Float32 => "float32".to_owned(),
        TensorElementType::Float64 => "float64".to_owned(),
        TensorElementType::Float16 => "float16".to_owned(),
        TensorElementType::Int64 => "int64".to_owned(),
        TensorElementType::Int32 => "int32".to_owned(),
        TensorElementType::Uint8 => "uint8".to_owned(),
        other => other.to_string(),
    }
}

/// Checks that `outlets` declare `expected` (type, rank, fixed dimensions); returns its
/// declared shape.
fn check(
    path: &Path,
    kind: &str,
    outlets: &[Outlet],
    expected: &Expected<'_>,
) -> Result<Vec<i64>, OnnxError> {
    let name = expected.name;
    let bad = |problem: String| OnnxError::Model {
        path: path.to_owned(),
        problem: format!("{kind} `{name}`: {problem}"),
    };
    let Some(outlet) = outlets.iter().find(|o| o.name() == name) else {
        let declared: Vec<String> = outlets.iter().map(|o| format!("`{}`", o.name())).collect();
        return Err(bad(format!(
            "no such {kind} (the model's {kind}s: {}; name yours in the sidecar)",
            declared.join(", ")
        )));
    };
    let ValueType::Tensor { ty, shape, .. } = outlet.dtype() else {
        return Err(bad(format!(
            "expected a tensor {}, the model declares {}",
            contract_text(expected),
            outlet.dtype()
        )));
    };
    let fits = *ty == expected.ty
        && shape.len() == expected.dims.len()
        && shape
            .iter()
            .zip(expected.dims)
            .all(|(&got, want)| match want {
                Dim::Is(n) => got == *n || got < 0,
                Dim::Any(_) => true,
            });
    if !fits {
        let dims: Vec<String> = shape
            .iter()
            .map(|&d| if d < 0 { "?".to_owned() } else { d.to_string() })
            .collect();
        return Err(bad(format!(
            "expected {}, the model declares {} [{}]",
            contract_text(expected),
            type_text(*ty),
            dims.join(", ")
        )));
    }
    Ok(shape.to_vec())
}

/// The fixed `(width, height)` of a declared `[N, C, H, W]` shape, if both are fixed.
pub(super) fn declared_size(shape: &[i64]) -> Option<(usize, usize)> {
    match shape {
        [_, _, h, w] if *h > 0 && *w > 0 => {
            Some((usize::try_from(*w).ok()?, usize::try_from(*h).ok()?))
        }
        _ => None,
    }
}

/// The fixed input size: the sidecar's, else the model's declared one (all image inputs
/// must agree), else `None` (dynamic).
pub(super) fn fixed_size(
    path: &Path,
    sidecar_size: Option<[usize; 2]>,
    shapes: &[Vec<i64>],
) -> Result<Option<(usize, usize)>, OnnxError> {
    let declared: Vec<(usize, usize)> = shapes.iter().filter_map(|s| declared_size(s)).collect();
    let wanted = sidecar_size
        .map(|[w, h]| (w, h))
        .or(declared.first().copied());
    if let Some((w, h)) = wanted
        && let Some(&(dw, dh)) = declared.iter().find(|&&d| d != (w, h))
    {
        return Err(OnnxError::Model {
            path: path.to_owned(),
            problem: format!(
                "inputs declare {dw}x{dh} pixels but {w}x{h} is expected (input_size \
                     in {})",
                sidecar::sidecar_path(path).display()
            ),
        });
    }
    Ok(wanted)
}
