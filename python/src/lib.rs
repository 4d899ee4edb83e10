//! `riseg` for Python: riseg-core's UpdateMask and FindAction, riseg's built-in segmenter
//! and optical flow, the UOIS metrics and the scene folder reader, over numpy arrays.
//!
//! # Contract
//!
//! - Images are numpy arrays, row-major `(H, W)` or `(H, W, C)`: colour `uint8 (H, W, 3)`,
//!   depth `float32 (H, W)` in metres (`<= 0` or NaN: no reading), labels `uint16 (H, W)`
//!   (0 = background), heatmap `uint8 (H, W)` (0-255), flow `float32 (H, W, 2)` as
//!   `(dx, dy)` pixels from the first image to the second (NaN: unknown).
//! - C-contiguous inputs are read in place; outputs are new arrays that own riseg's buffer
//!   (no copy). Wrong dtype or shape: `ValueError` naming the argument (`arrays`).
//! - Every function computes exactly what `riseg run` computes from the same inputs: each
//!   is one call of the host or core function `riseg run` calls, with the same defaults
//!   (`Config()` is riseg-core's `Config::PAPER`, seed 0). The heavy calls release the GIL.
//! - riseg's own errors are `RisegError` with riseg's message; an invalid `Config` value
//!   is a `ValueError`.

mod arrays;
mod types;

use std::path::PathBuf;

use arrays::{Pixels, image, same_size, to_numpy, to_numpy_n};
use numpy::{PyArray2, PyArray3};
use pyo3::{create_exception, exceptions::PyRuntimeError, prelude::*, types::PyDict};
use riseg::{
    eval::metrics::image_metrics,
    flow::{DisFlow, FlowEstimator as _, FlowParams},
    io::scene::Scene as HostScene,
    rig::workspace::{ActionBuf, WorkspaceBuf},
    segment::{ClassicalSegmenter, RgbdFrame, SegmenterParams, StaticSegmenter as _},
};
use riseg_core::{ImageView, action::find_action as core_find_action, frames::MotionInput};
use types::{Config, Intrinsics, Push, Scene};

create_exception!(
    riseg,
    RisegError,
    PyRuntimeError,
    "An error riseg reports (its message says what and where)."
);

/// riseg's error as a [`RisegError`] with riseg's message, after `context`.
pub(crate) fn riseg_err(context: &str, error: impl core::fmt::Display) -> PyErr {
    RisegError::new_err(format!("{context}: {error}"))
}

/// `segment`'s labels and heatmap.
type LabelsAndHeat<'py> = (Bound<'py, PyArray2<u16>>, Bound<'py, PyArray2<u8>>);

/// The built-in classical static segmenter (`riseg segment`) on one RGB-D frame.
///
/// Returns `(labels, heatmap)`: `uint16 (H, W)` instance ids `1..n` (0 = background) and
/// the `uint8 (H, W)` 0-255 heatmap FindAction reads.
#[pyfunction]
fn segment<'py>(
    py: Python<'py>,
    rgb: &Bound<'py, PyAny>,
    depth_m: &Bound<'py, PyAny>,
    intrinsics: &Intrinsics,
) -> PyResult<LabelsAndHeat<'py>> {
    let rgb = image::<u8>("rgb", "uint8", Some(3), rgb)?;
    let depth = image::<f32>("depth_m", "float32", None, depth_m)?;
    same_size(&[
        ("rgb", rgb.width, rgb.height),
        ("depth_m", depth.width, depth.height),
    ])?;
    let (w, h) = (rgb.width, rgb.height);
    let (rgb_px, depth_px, k) = (rgb.pixels::<3>(), depth.values(), intrinsics.0);
    let seg = py
        .detach(|| {
            let frame = RgbdFrame::new(w, h, rgb_px, depth_px)?;
            ClassicalSegmenter::new(SegmenterParams::default())?.segment(&frame, &k)
        })
        .map_err(|e| riseg_err("static segmentation", e))?;
    Ok((
        to_numpy(py, w, h, seg.labels.into_vec())?,
        to_numpy(py, w, h, seg.heatmap.into_vec())?,
    ))
}

/// The built-in dense optical flow (DIS, `riseg flow`'s medium preset) from `rgb0` to
/// `rgb1`: `float32 (H, W, 2)`, `(dx, dy)` pixels. `hint`, `(dx, dy)` pixels: where a push
/// should have moved something (`Scene.motion_hint(t)`), a candidate the search also tries.
#[pyfunction]
#[pyo3(signature = (rgb0, rgb1, hint = None))]
fn flow<'py>(
    py: Python<'py>,
    rgb0: &Bound<'py, PyAny>,
    rgb1: &Bound<'py, PyAny>,
    hint: Option<(f32, f32)>,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let first = image::<u8>("rgb0", "uint8", Some(3), rgb0)?;
    let second = image::<u8>("rgb1", "uint8", Some(3), rgb1)?;
    same_size(&[
        ("rgb0", first.width, first.height),
        ("rgb1", second.width, second.height),
    ])?;
    let (w, h) = (first.width, first.height);
    let (a, b) = (first.pixels::<3>(), second.pixels::<3>());
    let field = py
        .detach(|| {
            let views =
                ImageView::packed(w, h, a).and_then(|a| Ok((a, ImageView::packed(w, h, b)?)));
            let (a, b) = views.map_err(|e| e.to_string())?;
            let estimator = DisFlow::new(FlowParams::MEDIUM).map_err(|e| e.to_string())?;
            match hint {
                Some((x, y)) => estimator.estimate_with_hint(a, b, [x, y]),
                None => estimator.estimate(a, b),
            }
            .map_err(|e| e.to_string())
        })
        .map_err(|e| riseg_err("optical flow", e))?;
    to_numpy_n(py, w, h, field.into_vec())
}

/// UpdateMask (the paper's Algorithm 3, riseg-core): the accumulated mask carried from
/// frame t to frame t+1 and corrected by the body frames' twists.
///
/// `labels_t`: accumulated mask at t; `depth_t`, `depth_t1`: depth at t and t+1, metres;
/// `flow`: flow from t to t+1; `static_t1`: the static segmentation of t+1;
/// `intrinsics`: the camera's; `config`: the settings and seed (default `Config()`).
/// Returns the mask at t+1, `uint16 (H, W)`.
#[pyfunction]
#[pyo3(signature = (labels_t, depth_t, depth_t1, flow, static_t1, intrinsics, config = None))]
#[allow(clippy::too_many_arguments)]
fn update_mask<'py>(
    py: Python<'py>,
    labels_t: &Bound<'py, PyAny>,
    depth_t: &Bound<'py, PyAny>,
    depth_t1: &Bound<'py, PyAny>,
    flow: &Bound<'py, PyAny>,
    static_t1: &Bound<'py, PyAny>,
    intrinsics: &Intrinsics,
    config: Option<&Config>,
) -> PyResult<Bound<'py, PyArray2<u16>>> {
    let labels = image::<u16>("labels_t", "uint16", None, labels_t)?;
    let d0 = image::<f32>("depth_t", "float32", None, depth_t)?;
    let d1 = image::<f32>("depth_t1", "float32", None, depth_t1)?;
    let fl = image::<f32>("flow", "float32", Some(2), flow)?;
    let st = image::<u16>("static_t1", "uint16", None, static_t1)?;
    let size = |name, p: &Pixels<'_, _>| (name, p.width, p.height);
    same_size(&[
        ("labels_t", labels.width, labels.height),
        size("depth_t", &d0),
        size("depth_t1", &d1),
        size("flow", &fl),
        ("static_t1", st.width, st.height),
    ])?;
    let (w, h) = (labels.width, labels.height);
    let cfg = config.map_or(riseg_core::Config::PAPER, |c| c.0);
    let k = intrinsics.0;
    let (labels, d0, d1, fl, st) = (
        labels.values(),
        d0.values(),
        d1.values(),
        fl.pixels::<2>(),
        st.values(),
    );
    let mask = py
        .detach(|| {
            let input = MotionInput::new(
                ImageView::packed(w, h, labels)?,
                ImageView::packed(w, h, d0)?,
                ImageView::packed(w, h, d1)?,
                ImageView::packed(w, h, fl)?,
                k,
            )?;
            let mut ws = WorkspaceBuf::new(&cfg, w, h);
            let mut mask = vec![0u16; w * h];
            riseg_core::pipeline::update_mask(
                &input,
                &ImageView::packed(w, h, st)?,
                &cfg,
                &mut ws.view(),
                &mut mask,
            )?;
            Ok::<_, riseg_core::Error>(mask)
        })
        .map_err(|e| riseg_err("UpdateMask", e))?;
    to_numpy(py, w, h, mask)
}

/// FindAction (the paper's Algorithm 2, riseg-core): the push between two certain regions
/// of `heatmap` with an uncertain region between them, on the accumulated mask `labels`
/// and depth `depth_m` (metres). Returns a `Push`, or `None` when no pair qualifies (the
/// loop stops).
#[pyfunction]
#[pyo3(signature = (heatmap, labels, depth_m, intrinsics, config = None))]
fn find_action<'py>(
    py: Python<'py>,
    heatmap: &Bound<'py, PyAny>,
    labels: &Bound<'py, PyAny>,
    depth_m: &Bound<'py, PyAny>,
    intrinsics: &Intrinsics,
    config: Option<&Config>,
) -> PyResult<Option<Push>> {
    let heat = image::<u8>("heatmap", "uint8", None, heatmap)?;
    let mask = image::<u16>("labels", "uint16", None, labels)?;
    let depth = image::<f32>("depth_m", "float32", None, depth_m)?;
    same_size(&[
        ("heatmap", heat.width, heat.height),
        ("labels", mask.width, mask.height),
        ("depth_m", depth.width, depth.height),
    ])?;
    let (w, h) = (heat.width, heat.height);
    let cfg = config.map_or(riseg_core::Config::PAPER, |c| c.0);
    let k = intrinsics.0;
    let (heat, mask, depth) = (heat.values(), mask.values(), depth.values());
    let report = py
        .detach(|| {
            let mut buf = ActionBuf::new(&cfg, w, h);
            core_find_action(
                &ImageView::packed(w, h, heat)?,
                &ImageView::packed(w, h, depth)?,
                &ImageView::packed(w, h, mask)?,
                &k,
                &cfg,
                buf.view(),
            )
        })
        .map_err(|e| riseg_err("FindAction", e))?;
    Ok(report.push().map(Push::from))
}

/// The UOIS metrics of one predicted label map against its ground truth, as `riseg eval`
/// computes them (Hungarian matching; fractions 0-1).
///
/// Returns a dict: `overlap_precision`, `overlap_recall`, `overlap_f`,
/// `boundary_precision`, `boundary_recall`, `boundary_f`, `objects_detected_share`
/// (objects with overlap F > 0.75), and the counts `objects_gt`, `objects_pred`,
/// `objects_detected`.
#[pyfunction]
fn metrics<'py>(
    py: Python<'py>,
    pred: &Bound<'py, PyAny>,
    gt: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let p = image::<u16>("pred", "uint16", None, pred)?;
    let g = image::<u16>("gt", "uint16", None, gt)?;
    same_size(&[("pred", p.width, p.height), ("gt", g.width, g.height)])?;
    let m = image_metrics(g.values(), p.values(), p.width, p.height)
        .map_err(|e| riseg_err("metrics", e))?;
    let dict = PyDict::new(py);
    for (key, value) in [
        ("overlap_precision", m.overlap.precision),
        ("overlap_recall", m.overlap.recall),
        ("overlap_f", m.overlap.f_measure),
        ("boundary_precision", m.boundary.precision),
        ("boundary_recall", m.boundary.recall),
        ("boundary_f", m.boundary.f_measure),
        ("objects_detected_share", m.objects_detected_share),
    ] {
        dict.set_item(key, value)?;
    }
    for (key, value) in [
        ("objects_gt", m.objects_gt),
        ("objects_pred", m.objects_pred),
        ("objects_detected", m.objects_detected),
    ] {
        dict.set_item(key, value)?;
    }
    Ok(dict)
}

/// Reads a scene folder (`scene_camera.json`, `rgb/`, `depth/`, optional `label/`,
/// `flow/`, `actions.json`) with riseg's reader: `riseg run`'s rules and messages.
#[pyfunction]
fn read_scene(py: Python<'_>, path: PathBuf) -> PyResult<Scene> {
    py.detach(|| HostScene::read(&path))
        .map(Scene::from)
        .map_err(|e| RisegError::new_err(e.to_string()))
}

/// RISeg: interactive object segmentation by pushing (numpy in, numpy out).
#[pymodule]
fn _riseg(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("RisegError", m.py().get_type::<RisegError>())?;
    m.add_class::<Config>()?;
    m.add_class::<Intrinsics>()?;
    m.add_class::<Push>()?;
    m.add_class::<Scene>()?;
    m.add_function(wrap_pyfunction!(segment, m)?)?;
    m.add_function(wrap_pyfunction!(flow, m)?)?;
    m.add_function(wrap_pyfunction!(update_mask, m)?)?;
    m.add_function(wrap_pyfunction!(find_action, m)?)?;
    m.add_function(wrap_pyfunction!(metrics, m)?)?;
    m.add_function(wrap_pyfunction!(read_scene, m)?)?;
    Ok(())
}
