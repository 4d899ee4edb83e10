//! The Python classes: `Config` (riseg-core's settings), `Intrinsics`, `Push` (FindAction's
//! answer) and `Scene` (a scene folder in memory).
//!
//! `Config` goes through riseg-core's own serde names (those of `riseg config --print`'s
//! `[core]` section): a field is read as an attribute, set by a keyword of the constructor
//! or of `replace`, and an unknown name or an out-of-range value is a `ValueError`. Values
//! print as the `f32` they are (`0.03`, not `0.029999999329447746`).

use numpy::{PyArray2, PyArray3};
use pyo3::{
    exceptions::{PyAttributeError, PyValueError},
    prelude::*,
    types::{PyBool, PyDict, PyFloat},
};
use riseg::{
    io::scene::Scene as HostScene,
    rig::{camera::SceneReplay, episode::action_motion_px},
};
use serde_json::{Map, Value};

use crate::{
    RisegError,
    arrays::{to_numpy, to_numpy_n},
};

/// riseg-core's settings; `Config()` is the paper's defaults with seed 0, as every `riseg`
/// command runs. Fields are attributes (`Config().push_len_m`); set them with keywords:
/// `Config(seed=7, max_pushes=2)` or `cfg.replace(seed=7)`.
#[pyclass(frozen, eq, module = "riseg")]
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Config(pub(crate) riseg_core::Config);

impl Config {
    /// The fields by name, numbers as their shortest decimal (serde_json prints an `f32`
    /// as the `f32` it is).
    fn fields(&self) -> PyResult<Map<String, Value>> {
        let text =
            serde_json::to_string(&self.0).map_err(|e| PyValueError::new_err(e.to_string()))?;
        match serde_json::from_str(&text) {
            Ok(Value::Object(map)) => Ok(map),
            _ => Err(PyValueError::new_err(
                "Config did not serialise to an object",
            )),
        }
    }

    /// `self` with the fields of `overrides` replaced.
    fn with(&self, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let mut map = self.fields()?;
        for (key, value) in overrides.into_iter().flatten() {
            let key: String = key.extract()?;
            if !map.contains_key(&key) {
                return Err(PyValueError::new_err(format!(
                    "Config has no field {key:?}"
                )));
            }
            let number = if value.is_instance_of::<PyBool>() {
                None
            } else if value.is_instance_of::<PyFloat>() {
                value
                    .extract::<f64>()
                    .ok()
                    .and_then(serde_json::Number::from_f64)
            } else {
                value.extract::<u64>().ok().map(serde_json::Number::from)
            };
            let Some(number) = number else {
                return Err(PyValueError::new_err(format!(
                    "Config.{key}: expected a number (a non-negative int for counts), got {}",
                    value.repr()?
                )));
            };
            map.insert(key, Value::Number(number));
        }
        let cfg: riseg_core::Config = serde_json::from_value(Value::Object(map))
            .map_err(|e| PyValueError::new_err(format!("Config: {e}")))?;
        cfg.check()
            .map_err(|e| PyValueError::new_err(format!("Config: {e}")))?;
        Ok(Self(cfg))
    }
}

/// JSON number as a Python int or float.
fn py_number<'py>(py: Python<'py>, value: &Value) -> PyResult<Bound<'py, PyAny>> {
    match value {
        Value::Number(n) => match (n.as_u64(), n.as_f64()) {
            (Some(i), _) => Ok(i.into_pyobject(py)?.into_any()),
            (None, Some(f)) => Ok(f.into_pyobject(py)?.into_any()),
            (None, None) => Err(PyValueError::new_err("not a number")),
        },
        other => Err(PyValueError::new_err(format!("not a number: {other}"))),
    }
}

#[pymethods]
impl Config {
    /// The paper's defaults, with the keyword fields replaced.
    #[new]
    #[pyo3(signature = (**overrides))]
    fn new(overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Self(riseg_core::Config::PAPER).with(overrides)
    }

    /// A copy with the keyword fields replaced.
    #[pyo3(signature = (**overrides))]
    fn replace(&self, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        self.with(overrides)
    }

    /// Every field by name.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        for (key, value) in self.fields()? {
            dict.set_item(key, py_number(py, &value)?)?;
        }
        Ok(dict)
    }

    fn __getattr__<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        match self.fields()?.get(name) {
            Some(value) => py_number(py, value),
            None => Err(PyAttributeError::new_err(format!(
                "Config has no field {name:?}"
            ))),
        }
    }

    fn __repr__(&self) -> PyResult<String> {
        let fields: Vec<String> = self
            .fields()?
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        Ok(format!("Config({})", fields.join(", ")))
    }
}

/// Pinhole intrinsics, pixels (OpenCV: x right, y down; `(cx, cy)` measured from the
/// centre of the top-left pixel).
#[pyclass(frozen, eq, module = "riseg")]
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Intrinsics(pub(crate) riseg_core::Intrinsics);

#[pymethods]
impl Intrinsics {
    /// Checked intrinsics: finite, positive focal lengths (else `ValueError`).
    #[new]
    fn new(fx: f32, fy: f32, cx: f32, cy: f32) -> PyResult<Self> {
        riseg_core::Intrinsics::new(fx, fy, cx, cy)
            .map(Self)
            .map_err(|e| PyValueError::new_err(format!("Intrinsics: {e}")))
    }

    /// Focal length along x, pixels.
    #[getter]
    const fn fx(&self) -> f32 {
        self.0.fx
    }

    /// Focal length along y, pixels.
    #[getter]
    const fn fy(&self) -> f32 {
        self.0.fy
    }

    /// Principal point x, pixels.
    #[getter]
    const fn cx(&self) -> f32 {
        self.0.cx
    }

    /// Principal point y, pixels.
    #[getter]
    const fn cy(&self) -> f32 {
        self.0.cy
    }

    fn __repr__(&self) -> String {
        let k = self.0;
        format!(
            "Intrinsics(fx={}, fy={}, cx={}, cy={})",
            k.fx, k.fy, k.cx, k.cy
        )
    }
}

/// FindAction's push: where it starts and ends in the image, and in the camera frame.
#[pyclass(frozen, module = "riseg")]
#[derive(Debug, Clone, Copy)]
pub(crate) struct Push(riseg_core::action::Push);

impl From<riseg_core::action::Push> for Push {
    fn from(push: riseg_core::action::Push) -> Self {
        Self(push)
    }
}

#[pymethods]
impl Push {
    /// Start, pixels `(u, v)`.
    #[getter]
    const fn start_px(&self) -> (f32, f32) {
        (self.0.start_px[0], self.0.start_px[1])
    }

    /// Where the pusher ends, pixels `(u, v)`.
    #[getter]
    const fn target_px(&self) -> (f32, f32) {
        (self.0.target_px[0], self.0.target_px[1])
    }

    /// Start, camera frame, metres `(x, y, z)`.
    #[getter]
    fn start_cam_m(&self) -> (f32, f32, f32) {
        let p = self.0.start_cam_m;
        (p.x, p.y, p.z)
    }

    /// Unit push direction, camera frame.
    #[getter]
    fn direction_cam(&self) -> (f32, f32, f32) {
        let d = self.0.direction_cam;
        (d.x, d.y, d.z)
    }

    /// Push length, metres.
    #[getter]
    const fn length_m(&self) -> f32 {
        self.0.length_m
    }

    fn __repr__(&self) -> String {
        format!(
            "Push(start_px={:?}, target_px={:?}, length_m={})",
            self.start_px(),
            self.target_px(),
            self.0.length_m
        )
    }
}

/// A scene folder in memory (`read_scene`): frame `t` is the scene after `t` pushes.
#[pyclass(frozen, module = "riseg")]
#[derive(Debug)]
pub(crate) struct Scene(HostScene);

impl From<HostScene> for Scene {
    fn from(scene: HostScene) -> Self {
        Self(scene)
    }
}

impl Scene {
    fn frame(&self, t: usize) -> PyResult<riseg::rig::camera::CameraFrame> {
        SceneReplay::frame(&self.0, t).ok_or_else(|| {
            RisegError::new_err(format!(
                "frame {t}: the scene has {} frames",
                self.0.frames()
            ))
        })
    }
}

#[pymethods]
impl Scene {
    /// Number of frames (pushes + 1).
    #[getter]
    fn frames(&self) -> usize {
        self.0.frames()
    }

    /// Image width, pixels.
    #[getter]
    const fn width(&self) -> usize {
        self.0.camera.width
    }

    /// Image height, pixels.
    #[getter]
    const fn height(&self) -> usize {
        self.0.camera.height
    }

    /// The camera's intrinsics.
    #[getter]
    fn intrinsics(&self) -> Intrinsics {
        Intrinsics(self.0.camera.intrinsics())
    }

    /// Whether the scene has ground-truth labels (`label/`).
    #[getter]
    const fn has_truth(&self) -> bool {
        self.0.labels.is_some()
    }

    /// Colour of frame `t`, `uint8 (H, W, 3)`.
    fn rgb<'py>(&self, py: Python<'py>, t: usize) -> PyResult<Bound<'py, PyArray3<u8>>> {
        let frame = self.frame(t)?;
        let (w, h) = frame.size();
        to_numpy_n(py, w, h, frame.rgb.into_vec())
    }

    /// Depth of frame `t` in metres (the scene's depth unit applied; 0 = no reading),
    /// `float32 (H, W)`.
    fn depth_m<'py>(&self, py: Python<'py>, t: usize) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let frame = self.frame(t)?;
        let (w, h) = frame.depth_m.size();
        to_numpy(py, w, h, frame.depth_m.into_vec())
    }

    /// Ground-truth labels of frame `t`, `uint16 (H, W)`, or `None` without `label/`.
    fn labels<'py>(
        &self,
        py: Python<'py>,
        t: usize,
    ) -> PyResult<Option<Bound<'py, PyArray2<u16>>>> {
        let frame = self.frame(t)?;
        frame
            .truth
            .map(|truth| to_numpy(py, truth.width(), truth.height(), truth.into_vec()))
            .transpose()
    }

    /// The recorded pushes (`actions.json`): dicts with `push` (from 1), `start_px`,
    /// `start_cam_m`, `direction_cam` and `length_m`; push `p` made frame `p` from `p − 1`.
    fn actions<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.0
            .actions
            .iter()
            .map(|a| {
                let dict = PyDict::new(py);
                dict.set_item("push", a.push)?;
                dict.set_item("start_px", a.start_px)?;
                dict.set_item("start_cam_m", a.start_cam_m)?;
                dict.set_item("direction_cam", a.direction_cam)?;
                dict.set_item("length_m", a.length_m)?;
                Ok(dict)
            })
            .collect()
    }

    /// The flow's motion hint for frame `t` (`(dx, dy)` pixels, for `flow(..., hint=)`):
    /// the image motion of the recorded push that made frame `t`, as `riseg run` gives it;
    /// `None` for frame 0 or a scene without that push.
    fn motion_hint(&self, t: usize) -> Option<(f32, f32)> {
        let action = self.0.actions.get(t.checked_sub(1)?)?;
        let [x, y] = action_motion_px(action, &self.0.camera.intrinsics())?;
        Some((x, y))
    }

    fn __repr__(&self) -> String {
        format!(
            "Scene({} frames of {}x{}, ground truth: {})",
            self.0.frames(),
            self.0.camera.width,
            self.0.camera.height,
            self.0.labels.is_some()
        )
    }
}
