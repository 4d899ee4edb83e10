//! The JS API: wasm-bindgen wrappers of [`crate::adapter`], one per call of the crate
//! docs' contract (feature `js`, which the browser build turns on).

use crate::adapter::{self, BODY_FRAME_FLOATS, METRICS_LEN, Replay};
use wasm_bindgen::prelude::*;

#[wasm_bindgen]
extern "C" {
    #[wasm_bindgen(js_namespace = console, js_name = error)]
    fn console_error(message: &str);
}

/// Prints a panic's message with `console.error` (the module then traps).
fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| console_error(&info.to_string())));
}

/// riseg's message as a JS exception.
fn js(message: String) -> JsError {
    JsError::new(&message)
}

/// The files of one scene folder, by path, before [`Session::open`] reads them.
#[wasm_bindgen]
#[derive(Debug, Default)]
pub struct SceneFiles(adapter::SceneFiles);

#[wasm_bindgen]
impl SceneFiles {
    /// No files.
    #[wasm_bindgen(constructor)]
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds the file `path` (`/`-separated, e.g. `scene_000/rgb/000000.png`) with its bytes.
    pub fn add(&mut self, path: &str, bytes: Vec<u8>) {
        self.0.add(path, bytes);
    }
}

/// Numbers per body frame in [`Session::body_frames`].
#[wasm_bindgen(js_name = BODY_FRAME_FLOATS)]
#[must_use]
pub fn body_frame_floats() -> usize {
    BODY_FRAME_FLOATS
}

/// Numbers per result of [`Session::metrics_static`] and [`Session::metrics_riseg`].
#[wasm_bindgen(js_name = METRICS_LEN)]
#[must_use]
pub fn metrics_len() -> usize {
    METRICS_LEN
}

/// riseg's colour `[r, g, b]` of a colour key (the labels the pictures are drawn with;
/// [`Session::colour_keys`]).
#[wasm_bindgen(js_name = keyColour)]
#[must_use]
pub fn key_colour(key: u16) -> Vec<u8> {
    adapter::key_colour(key).to_vec()
}

/// A recorded scene replayed by RISeg, stage by stage (crate docs).
#[wasm_bindgen]
#[derive(Debug)]
pub struct Session(Replay);

#[wasm_bindgen]
impl Session {
    /// Reads and checks the scene folder `dir` among `files`, with `riseg run`'s settings.
    ///
    /// # Errors
    /// riseg's message naming the file at fault and its problem.
    pub fn open(files: &SceneFiles, dir: &str) -> Result<Self, JsError> {
        install_panic_hook();
        Replay::open(&files.0, dir).map(Self).map_err(js)
    }

    /// Image width, pixels.
    #[wasm_bindgen(getter)]
    #[must_use]
    pub fn width(&self) -> usize {
        self.0.width()
    }

    /// Image height, pixels.
    #[wasm_bindgen(getter)]
    #[must_use]
    pub fn height(&self) -> usize {
        self.0.height()
    }

    /// Number of frames (pushes + 1).
    #[wasm_bindgen(getter)]
    #[must_use]
    pub fn frames(&self) -> usize {
        self.0.frames()
    }

    /// Whether the scene has ground-truth labels (then the metrics can be computed).
    #[wasm_bindgen(getter, js_name = hasTruth)]
    #[must_use]
    pub fn has_truth(&self) -> bool {
        self.0.has_truth()
    }

    /// The frame [`Session::update`] observes next.
    #[wasm_bindgen(getter, js_name = nextFrame)]
    #[must_use]
    pub fn next_frame(&self) -> usize {
        self.0.next_frame()
    }

    /// Starts again from frame 0.
    pub fn restart(&mut self) {
        self.0.restart();
    }

    /// Stage 1: the built-in static segmenter on frame `t`.
    ///
    /// # Errors
    /// Out of order, or the segmenter's error.
    pub fn segment(&mut self, t: usize) -> Result<(), JsError> {
        self.0.segment(t).map_err(js)
    }

    /// Stage 2: the built-in optical flow from frame `t − 1` to `t` (`t > 0`).
    ///
    /// # Errors
    /// Out of order, frame 0, or the flow's error.
    pub fn flow(&mut self, t: usize) -> Result<(), JsError> {
        self.0.flow(t).map_err(js)
    }

    /// Stage 3: UpdateMask (riseg-core) from the previous mask to frame `t`.
    ///
    /// # Errors
    /// Out of order, a stage missing, or riseg-core's error.
    pub fn update(&mut self, t: usize) -> Result<(), JsError> {
        self.0.update(t).map_err(js)
    }

    /// Stage 4: FindAction (riseg-core) on the last observed frame.
    ///
    /// # Errors
    /// No frame observed yet, or riseg-core's error.
    #[wasm_bindgen(js_name = findAction)]
    pub fn find_action(&mut self) -> Result<(), JsError> {
        self.0.find_action().map_err(js)
    }

    /// RISeg's accumulated mask of the last observed frame (0 = background).
    ///
    /// # Errors
    /// No frame observed yet.
    pub fn mask(&self) -> Result<Vec<u16>, JsError> {
        Ok(self.0.mask().map_err(js)?.to_vec())
    }

    /// The static segmenter's labels of the last observed frame.
    ///
    /// # Errors
    /// No frame observed yet.
    #[wasm_bindgen(js_name = staticLabels)]
    pub fn static_labels(&self) -> Result<Vec<u16>, JsError> {
        Ok(self.0.static_labels().map_err(js)?.to_vec())
    }

    /// The static heatmap (0-255) of the last observed frame.
    ///
    /// # Errors
    /// No frame observed yet.
    pub fn heatmap(&self) -> Result<Vec<u8>, JsError> {
        Ok(self.0.heatmap().map_err(js)?.to_vec())
    }

    /// The flow into the last observed frame, `dx, dy` per pixel, pixels; empty on frame 0.
    ///
    /// # Errors
    /// No frame observed yet.
    #[wasm_bindgen(js_name = flowField)]
    pub fn flow_field(&self) -> Result<Vec<f32>, JsError> {
        Ok(self.0.flow_field().map_err(js)?.to_vec())
    }

    /// The body frames of the last step, `BODY_FRAME_FLOATS()` numbers each: corners
    /// `x0, y0, x1, y1, x2, y2` in the previous frame, twist group (`-1`: none), moved
    /// (`1`) or not (`0`).
    ///
    /// # Errors
    /// No frame observed yet.
    #[wasm_bindgen(js_name = bodyFrames)]
    pub fn body_frames(&self) -> Result<Vec<f32>, JsError> {
        self.0.body_frames().map_err(js)
    }

    /// FindAction's push on the last observed frame, `[start x, y, target x, y]` pixels, or
    /// `undefined` when it found none.
    #[wasm_bindgen(js_name = chosenPush)]
    #[must_use]
    pub fn chosen_push(&self) -> Option<Vec<f32>> {
        self.0.chosen_push().map(|p| p.to_vec())
    }

    /// The recorded push (`actions.json`) that made frame `t` from frame `t − 1`, `[x0, y0,
    /// x1, y1]` pixels in frame `t − 1`, or `undefined` for frame 0.
    #[wasm_bindgen(js_name = recordedPush)]
    #[must_use]
    pub fn recorded_push(&self, t: usize) -> Option<Vec<f32>> {
        self.0.recorded_push(t).map(|p| p.to_vec())
    }

    /// The UOIS metrics of the static labels of the last observed frame against its ground
    /// truth, as `riseg eval` computes them: overlap P, R, F, boundary P, R, F, share of
    /// objects with overlap F > 0.75 (fractions 0-1), objects in the truth, predicted,
    /// detected.
    ///
    /// # Errors
    /// No frame observed yet, or no ground truth.
    #[wasm_bindgen(js_name = metricsStatic)]
    pub fn metrics_static(&self) -> Result<Vec<f64>, JsError> {
        let labels = self.0.static_labels().map_err(js)?;
        Ok(self.0.metrics(labels).map_err(js)?.to_vec())
    }

    /// [`Session::metrics_static`] of RISeg's mask.
    ///
    /// # Errors
    /// No frame observed yet, or no ground truth.
    #[wasm_bindgen(js_name = metricsRiseg)]
    pub fn metrics_riseg(&self) -> Result<Vec<f64>, JsError> {
        let labels = self.0.mask().map_err(js)?;
        Ok(self.0.metrics(labels).map_err(js)?.to_vec())
    }

    /// `[x0, y0, x1, y1]` (exclusive ends): where the objects are, with a margin.
    ///
    /// # Errors
    /// No frame observed yet.
    #[wasm_bindgen(js_name = cropBox)]
    pub fn crop_box(&self) -> Result<Vec<u32>, JsError> {
        let b = self.0.crop_box().map_err(js)?;
        Ok(b.iter().map(|&v| v as u32).collect())
    }

    /// Colour image `t`, RGBA.
    ///
    /// # Errors
    /// No such frame.
    #[wasm_bindgen(js_name = rgbPicture)]
    pub fn rgb_picture(&self, t: usize) -> Result<Vec<u8>, JsError> {
        self.0.rgb_picture(t).map_err(js)
    }

    /// The static labels of the last observed frame over its colour image, RGBA, each
    /// object in the colour of its key ([`Session::colour_keys`]).
    ///
    /// # Errors
    /// No frame observed yet.
    #[wasm_bindgen(js_name = staticPicture)]
    pub fn static_picture(&self) -> Result<Vec<u8>, JsError> {
        let labels = self.0.static_labels().map_err(js)?;
        self.0.labels_picture(labels).map_err(js)
    }

    /// RISeg's mask of the last observed frame over its colour image, RGBA.
    ///
    /// # Errors
    /// No frame observed yet.
    #[wasm_bindgen(js_name = maskPicture)]
    pub fn mask_picture(&self) -> Result<Vec<u8>, JsError> {
        let labels = self.0.mask().map_err(js)?;
        self.0.labels_picture(labels).map_err(js)
    }

    /// The ground truth of the last observed frame over its colour image, RGBA, or
    /// `undefined` without ground truth.
    ///
    /// # Errors
    /// No frame observed yet.
    #[wasm_bindgen(js_name = truthPicture)]
    pub fn truth_picture(&self) -> Result<Option<Vec<u8>>, JsError> {
        let t = self.0.observed_t().map_err(js)?;
        match self.0.truth(t) {
            Some(truth) => self.0.labels_picture(truth).map(Some).map_err(js),
            None => Ok(None),
        }
    }

    /// The static heatmap of the last observed frame, RGBA (riseg's heat colours).
    ///
    /// # Errors
    /// No frame observed yet.
    #[wasm_bindgen(js_name = heatPicture)]
    pub fn heat_picture(&self) -> Result<Vec<u8>, JsError> {
        self.0.heat_picture().map_err(js)
    }

    /// The flow into the last observed frame, RGBA (Middlebury colour wheel); empty on
    /// frame 0.
    ///
    /// # Errors
    /// No frame observed yet.
    #[wasm_bindgen(js_name = flowPicture)]
    pub fn flow_picture(&self) -> Result<Vec<u8>, JsError> {
        self.0.flow_picture().map_err(js)
    }

    /// The colour keys of RISeg's mask of the last observed frame that are present, sorted:
    /// one per object shown, for the legend ([`keyColour`](key_colour) gives each colour).
    /// Objects are keyed by the ground-truth object they overlap most, so one object has
    /// one colour in every panel.
    ///
    /// # Errors
    /// No frame observed yet.
    #[wasm_bindgen(js_name = colourKeys)]
    pub fn colour_keys(&self) -> Result<Vec<u16>, JsError> {
        self.0.legend_keys().map_err(js)
    }
}
