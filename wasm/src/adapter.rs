//! The one module that names riseg's (host) types: a recorded scene replayed exactly as
//! `riseg run` replays it, stage by stage, with every output as a plain slice or array.
//!
//! # Contract
//!
//! - [`Replay::open`] reads a scene folder from files in memory with riseg's own reader
//!   ([`Scene::read_in`]): the same rules and the same error messages (file, then
//!   problem) as `riseg run` on disk.
//! - Frames are observed in order `0, 1, …`. For frame `t`: [`Replay::segment`], then
//!   (`t > 0`) [`Replay::flow`], then [`Replay::update`]; each is one stage, so the caller can
//!   time it. `segment` and `flow` call the tracker's own segmenter and flow estimator
//!   exactly as [`Tracker::observe`](riseg::rig::tracker::Tracker::observe) does, and
//!   `update` hands their outputs to [`Tracker::observe_given`]: the masks are
//!   bit-identical to `riseg run`'s (the browser tests compare digests). A stage called out
//!   of order is an error that says what to call, never a wrong result.
//! - After `update(t)` the outputs of frame `t` (static labels and heatmap, RISeg's mask,
//!   the flow into `t`, the body frames of the step, FindAction's push, the metrics) stay
//!   readable until the next `update`.
//! - Errors are riseg's messages as text.

use std::{
    collections::{HashMap, HashSet},
    path::Path,
};

use riseg::{
    draw::{label_colour, overlay_labels},
    eval::metrics::image_metrics,
    flow::DisFlow,
    flow::{FlowEstimator as _, viz::flow_to_rgb},
    io::{files::MemoryFiles, image::FlowImage, scene::Scene},
    rig::{
        camera::{CameraFrame, SceneReplay},
        episode::{action_motion_px, find_action_on},
        tracker::{GivenInputs, Observation, Settings, Tracker},
        workspace::ActionBuf,
    },
    segment::{ClassicalSegmenter, Segmentation, StaticSegmenter as _, viz::heat_colour},
};
use riseg_core::action::ActionReport;

/// Floats per body frame in [`Replay::body_frames`].
pub(crate) const BODY_FRAME_FLOATS: usize = 8;

/// Numbers per [`Replay::metrics`] result.
pub(crate) const METRICS_LEN: usize = 10;

/// Pixels of margin around the objects in [`Replay::crop_box`].
const CROP_MARGIN_PX: usize = 40;

/// Colour keys at or above this are segments that match no reference object
/// ([`colour_keys`]).
const UNMATCHED_KEY: u32 = 1000;

/// A scene folder's files, collected before [`Replay::open`].
#[derive(Debug, Default)]
pub(crate) struct SceneFiles(MemoryFiles);

impl SceneFiles {
    /// Adds the file `path` (relative, `/`-separated, e.g. `scene_000/rgb/000000.png`).
    pub(crate) fn add(&mut self, path: &str, bytes: Vec<u8>) {
        self.0.insert(path, bytes);
    }
}

/// A recorded scene and the tracker replaying it (module docs).
#[derive(Debug)]
pub(crate) struct Replay {
    scene: Scene,
    tracker: Tracker<ClassicalSegmenter, DisFlow>,
    /// The frame `segment`, `flow` and `update` work on next.
    next: usize,
    pending_seg: Option<Segmentation>,
    pending_flow: Option<FlowImage>,
    /// Frame `next − 1` and what the tracker made of it.
    last: Option<(CameraFrame, Observation)>,
    action: Option<ActionReport>,
    action_buf: Option<ActionBuf>,
}

impl Replay {
    /// Reads the scene folder `dir` from `files` and a tracker with `riseg run`'s defaults.
    pub(crate) fn open(files: &SceneFiles, dir: &str) -> Result<Self, String> {
        let scene = Scene::read_in(&files.0, Path::new(dir)).map_err(|e| e.to_string())?;
        let tracker = Tracker::from_settings(&Settings::default()).map_err(|e| e.to_string())?;
        Ok(Self {
            scene,
            tracker,
            next: 0,
            pending_seg: None,
            pending_flow: None,
            last: None,
            action: None,
            action_buf: None,
        })
    }

    pub(crate) fn width(&self) -> usize {
        self.scene.camera.width
    }

    pub(crate) fn height(&self) -> usize {
        self.scene.camera.height
    }

    pub(crate) fn frames(&self) -> usize {
        self.scene.frames()
    }

    pub(crate) fn has_truth(&self) -> bool {
        self.scene.labels.is_some()
    }

    /// The frame `update` observes next.
    pub(crate) const fn next_frame(&self) -> usize {
        self.next
    }

    fn frame(&self, t: usize) -> Result<CameraFrame, String> {
        SceneReplay::frame(&self.scene, t)
            .ok_or_else(|| format!("frame {t}: the scene has {} frames", self.frames()))
    }

    fn expect_next(&self, t: usize, stage: &str) -> Result<(), String> {
        if t == self.next {
            Ok(())
        } else {
            Err(format!(
                "{stage} of frame {t}: frames run in order and the next is frame {}",
                self.next
            ))
        }
    }

    /// Starts the replay again from frame 0.
    pub(crate) fn restart(&mut self) {
        self.tracker.reset();
        self.next = 0;
        self.pending_seg = None;
        self.pending_flow = None;
        self.last = None;
        self.action = None;
    }

    /// The static segmentation of frame `t` (stage 1).
    pub(crate) fn segment(&mut self, t: usize) -> Result<(), String> {
        self.expect_next(t, "segmentation")?;
        let frame = self.frame(t)?;
        let rgbd = frame.rgbd().map_err(|e| e.to_string())?;
        let seg = self
            .tracker
            .segmenter_mut()
            .segment(&rgbd, &frame.intrinsics)
            .map_err(|e| format!("frame {t}: static segmentation: {e}"))?;
        self.pending_seg = Some(seg);
        Ok(())
    }

    /// The flow from frame `t − 1` to frame `t` (stage 2; `t > 0`).
    pub(crate) fn flow(&mut self, t: usize) -> Result<(), String> {
        self.expect_next(t, "flow")?;
        let Some(prev) = t.checked_sub(1) else {
            return Err("flow of frame 0: the first frame has no previous frame".into());
        };
        let rgb = |t: usize| {
            self.scene
                .rgb
                .get(t)
                .map(|image| image.view())
                .ok_or_else(|| format!("frame {t}: the scene has {} frames", self.frames()))
        };
        // The recorded push that made frame t is the flow's motion hint, as in `riseg run`.
        let hint = self
            .scene
            .actions
            .get(prev)
            .and_then(|a| action_motion_px(a, &self.scene.camera.intrinsics()));
        let estimator = self.tracker.flow_estimator();
        let (a, b) = (rgb(prev)?, rgb(t)?);
        let flow = match hint {
            Some(h) => estimator.estimate_with_hint(a, b, h),
            None => estimator.estimate(a, b),
        }
        .map_err(|e| format!("frame {t}: optical flow: {e}"))?;
        self.pending_flow = Some(flow);
        Ok(())
    }

    /// UpdateMask with the static segmentation and flow of `segment` and `flow` (stage 3).
    pub(crate) fn update(&mut self, t: usize) -> Result<(), String> {
        self.expect_next(t, "update")?;
        let Some(static_seg) = self.pending_seg.take() else {
            return Err(format!("update of frame {t}: call segment({t}) first"));
        };
        let flow = self.pending_flow.take();
        if t > 0 && flow.is_none() {
            self.pending_seg = Some(static_seg);
            return Err(format!("update of frame {t}: call flow({t}) first"));
        }
        let frame = self.frame(t)?;
        let given = GivenInputs {
            static_seg: Some(static_seg),
            flow,
        };
        let observation = self
            .tracker
            .observe_given(frame.clone(), given)
            .map_err(|e| format!("frame {t}: {e}"))?;
        self.last = Some((frame, observation));
        self.action = None;
        self.next += 1;
        Ok(())
    }

    fn observed(&self) -> Result<&(CameraFrame, Observation), String> {
        self.last
            .as_ref()
            .ok_or_else(|| "no frame observed yet: call update first".to_owned())
    }

    /// The index of the last observed frame.
    pub(crate) fn observed_t(&self) -> Result<usize, String> {
        self.observed()?;
        Ok(self.next - 1)
    }

    /// FindAction on the last observed frame, as the loop runs it (stage 4).
    pub(crate) fn find_action(&mut self) -> Result<(), String> {
        let (frame, observation) = self
            .last
            .as_ref()
            .ok_or("no frame observed yet: call update first")?;
        let cfg = *self.tracker.config();
        let report = find_action_on(frame, observation, &cfg, &mut self.action_buf)
            .map_err(|e| format!("FindAction: {e}"))?;
        self.action = Some(report);
        Ok(())
    }

    /// FindAction's push on the last observed frame: `[start x, y, target x, y]` pixels,
    /// `None` when it found none (or was not run).
    pub(crate) fn chosen_push(&self) -> Option<[f32; 4]> {
        let push = self.action.as_ref()?.push()?;
        Some([
            push.start_px[0],
            push.start_px[1],
            push.target_px[0],
            push.target_px[1],
        ])
    }

    /// The recorded push that turned frame `t − 1` into frame `t` (`actions.json`): its start
    /// and end in the image of frame `t − 1`, `[x0, y0, x1, y1]` pixels; `None` for frame 0 or
    /// an end behind the camera.
    pub(crate) fn recorded_push(&self, t: usize) -> Option<[f32; 4]> {
        let action = self.scene.actions.get(t.checked_sub(1)?)?;
        let k = self.scene.camera.intrinsics();
        let [x, y, z] = action.start_cam_m;
        let [dx, dy, dz] = action.direction_cam;
        let l = action.length_m;
        let end = k.project(&nalgebra::Point3::new(x + l * dx, y + l * dy, z + l * dz))?;
        Some([action.start_px[0], action.start_px[1], end.x, end.y])
    }

    /// The static labels of the last observed frame.
    pub(crate) fn static_labels(&self) -> Result<&[u16], String> {
        Ok(self.observed()?.1.static_seg.labels.as_slice())
    }

    /// The static heatmap (0-255) of the last observed frame.
    pub(crate) fn heatmap(&self) -> Result<&[u8], String> {
        Ok(self.observed()?.1.static_seg.heatmap.as_slice())
    }

    /// RISeg's accumulated mask of the last observed frame.
    pub(crate) fn mask(&self) -> Result<&[u16], String> {
        Ok(&self.observed()?.1.mask)
    }

    /// The flow into the last observed frame, `(dx, dy)` interleaved; empty on frame 0.
    pub(crate) fn flow_field(&self) -> Result<&[f32], String> {
        let step = self.observed()?.1.step.as_ref();
        Ok(step.map_or(&[][..], |s| s.flow.as_slice().as_flattened()))
    }

    /// The body frames of the last step, [`BODY_FRAME_FLOATS`] numbers each: the three
    /// corners `[x, y]` at the previous frame, the twist group (`-1`: none) and whether the
    /// group moved (`1`) or not (`0`).
    pub(crate) fn body_frames(&self) -> Result<Vec<f32>, String> {
        let Some(step) = &self.observed()?.1.step else {
            return Ok(Vec::new());
        };
        Ok(step
            .frames
            .iter()
            .flat_map(|f| {
                let [a, b, c] = f.frame.px_t.map(|p| p.map(|v| v as f32));
                let group = f.group.map_or(-1.0, f32::from);
                [
                    a[0],
                    a[1],
                    b[0],
                    b[1],
                    c[0],
                    c[1],
                    group,
                    f32::from(u8::from(f.moving)),
                ]
            })
            .collect())
    }

    /// The ground-truth labels of frame `t`, if the scene has them.
    pub(crate) fn truth(&self, t: usize) -> Option<&[u16]> {
        Some(self.scene.labels.as_ref()?.get(t)?.as_slice())
    }

    /// The UOIS metrics of `labels` against the last observed frame's ground truth, as
    /// `riseg eval` computes them ([`image_metrics`]): overlap P, R, F, boundary P, R, F,
    /// share of objects with overlap F > 0.75 (fractions), then the counts of ground-truth,
    /// predicted and detected objects.
    pub(crate) fn metrics(&self, labels: &[u16]) -> Result<[f64; METRICS_LEN], String> {
        let t = self.observed_t()?;
        let truth = self
            .truth(t)
            .ok_or("the scene has no ground truth (label/)")?;
        let m =
            image_metrics(truth, labels, self.width(), self.height()).map_err(|e| e.to_string())?;
        Ok([
            m.overlap.precision,
            m.overlap.recall,
            m.overlap.f_measure,
            m.boundary.precision,
            m.boundary.recall,
            m.boundary.f_measure,
            m.objects_detected_share,
            m.objects_gt as f64,
            m.objects_pred as f64,
            m.objects_detected as f64,
        ])
    }

    /// `[x0, y0, x1, y1]` (exclusive ends): the box around the last observed frame's
    /// static segmentation and the ground truth of every frame, with a margin, for display.
    pub(crate) fn crop_box(&self) -> Result<[usize; 4], String> {
        let labels = self.static_labels()?;
        let (w, h) = (self.width(), self.height());
        let mut b = [w, h, 0, 0];
        let truth = self.scene.labels.iter().flatten().map(|l| l.as_slice());
        for labels in core::iter::once(labels).chain(truth) {
            for (i, _) in labels.iter().enumerate().filter(|(_, l)| **l != 0) {
                let (x, y) = (i % w, i / w);
                b = [b[0].min(x), b[1].min(y), b[2].max(x + 1), b[3].max(y + 1)];
            }
        }
        if b[0] >= b[2] {
            return Ok([0, 0, w, h]);
        }
        Ok([
            b[0].saturating_sub(CROP_MARGIN_PX),
            b[1].saturating_sub(CROP_MARGIN_PX),
            (b[2] + CROP_MARGIN_PX).min(w),
            (b[3] + CROP_MARGIN_PX).min(h),
        ])
    }

    /// Colour image `t`, RGBA.
    pub(crate) fn rgb_picture(&self, t: usize) -> Result<Vec<u8>, String> {
        let frame = self.scene.rgb.get(t).ok_or("no such frame")?;
        Ok(rgba(frame.as_slice()))
    }

    /// The colour key of each pixel of `labels`, a label map of the last observed frame
    /// ([`colour_keys`]); the reference is the frame's ground truth, or without it RISeg's
    /// mask.
    fn keys(&self, labels: &[u16]) -> Result<Vec<u16>, String> {
        let t = self.observed_t()?;
        let reference = match self.truth(t) {
            Some(truth) => truth,
            None => self.mask()?,
        };
        Ok(colour_keys(labels, reference))
    }

    /// The colour keys present in RISeg's mask of the last observed frame, sorted: one per
    /// object shown, for a legend.
    pub(crate) fn legend_keys(&self) -> Result<Vec<u16>, String> {
        let mut keys = self.keys(self.mask()?)?;
        keys.sort_unstable();
        keys.dedup();
        keys.retain(|&k| k != 0);
        Ok(keys)
    }

    /// `labels` (a label map of the last observed frame) over its colour image, RGBA
    /// ([`overlay_labels`]), each segment in the colour of its key ([`Replay::keys`]).
    pub(crate) fn labels_picture(&self, labels: &[u16]) -> Result<Vec<u8>, String> {
        let rgb = self.observed()?.0.rgb.clone();
        Ok(rgba(overlay_labels(&rgb, &self.keys(labels)?).as_slice()))
    }

    /// The static heatmap of the last observed frame in riseg's heat colours, RGBA.
    pub(crate) fn heat_picture(&self) -> Result<Vec<u8>, String> {
        let heat: Vec<[u8; 3]> = self.heatmap()?.iter().map(|&v| heat_colour(v)).collect();
        Ok(rgba(&heat))
    }

    /// The flow into the last observed frame on riseg's colour wheel, RGBA; empty on
    /// frame 0.
    pub(crate) fn flow_picture(&self) -> Result<Vec<u8>, String> {
        let Some(step) = &self.observed()?.1.step else {
            return Ok(Vec::new());
        };
        Ok(rgba(flow_to_rgb(&step.flow, None).as_slice()))
    }
}

/// The colour key of each pixel of `labels`: the `reference` label its segment overlaps
/// most, so one object has one colour in every panel. A segment that overlaps no reference
/// object, or whose best reference object a larger segment already took, gets a key of its
/// own (at or above [`UNMATCHED_KEY`]), so a split object shows two colours.
pub(crate) fn colour_keys(labels: &[u16], reference: &[u16]) -> Vec<u16> {
    let mut overlap: HashMap<(u16, u16), u32> = HashMap::new();
    for (&l, &r) in labels.iter().zip(reference).filter(|(l, _)| **l != 0) {
        *overlap.entry((l, r)).or_default() += 1;
    }
    // Largest overlaps first; ties by label, so the result does not depend on hashing.
    let mut pairs: Vec<((u16, u16), u32)> = overlap.into_iter().collect();
    pairs.sort_unstable_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    let mut key: HashMap<u16, u16> = HashMap::new();
    let mut taken: HashSet<u16> = HashSet::new();
    for ((l, r), _) in pairs {
        if r != 0 && !key.contains_key(&l) && taken.insert(r) {
            key.insert(l, r);
        }
    }
    labels
        .iter()
        .map(|&l| match (l, key.get(&l)) {
            (0, _) => 0,
            (_, Some(&r)) => r,
            // Keys above u16::MAX wrap into other unmatched keys only past 64535 labels.
            (_, None) => (UNMATCHED_KEY + u32::from(l)).min(u32::from(u16::MAX)) as u16,
        })
        .collect()
}

/// riseg's colour of the colour key `key` (`[r, g, b]`).
pub(crate) fn key_colour(key: u16) -> [u8; 3] {
    label_colour(key)
}

/// RGB pixels as RGBA bytes (opaque), as a canvas takes them.
fn rgba(rgb: &[[u8; 3]]) -> Vec<u8> {
    rgb.iter().flat_map(|&[r, g, b]| [r, g, b, 255]).collect()
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use riseg::rig::camera::SceneReplay;

    use super::*;

    /// The bundled scene `web/scenes/<name>`, on disk and as files under `<name>/`, less
    /// the file `skip` (a path below the scene folder).
    fn bundled_without(name: &str, skip: &str) -> (PathBuf, SceneFiles) {
        fn add(files: &mut SceneFiles, dir: &Path, prefix: &str, skip: &str) {
            for entry in std::fs::read_dir(dir).unwrap() {
                let path = entry.unwrap().path();
                let below = format!("{prefix}/{}", path.file_name().unwrap().to_str().unwrap());
                if path.is_dir() {
                    add(files, &path, &below, skip);
                } else if below != skip {
                    files.add(&below, std::fs::read(&path).unwrap());
                }
            }
        }
        let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../web/scenes")
            .join(name);
        let mut files = SceneFiles::default();
        add(&mut files, &dir, name, &format!("{name}/{skip}"));
        (dir, files)
    }

    fn bundled(name: &str) -> (PathBuf, SceneFiles) {
        bundled_without(name, "")
    }

    #[test]
    fn stage_by_stage_gives_the_masks_of_observe() {
        let (dir, files) = bundled("packed");
        let mut replay = Replay::open(&files, "packed").unwrap();
        let scene = Scene::read(&dir).unwrap();
        let mut tracker = Tracker::from_settings(&Settings::default()).unwrap();
        assert_eq!(replay.frames(), 3);
        for t in 0..replay.frames() {
            replay.segment(t).unwrap();
            if t > 0 {
                replay.flow(t).unwrap();
            }
            replay.update(t).unwrap();
            replay.find_action().unwrap();
            // As `riseg run` replays it: the recorded push is the flow's motion hint.
            let hint = t
                .checked_sub(1)
                .and_then(|p| scene.actions.get(p))
                .and_then(|a| action_motion_px(a, &scene.camera.intrinsics()));
            assert_eq!(
                t > 0,
                hint.is_some(),
                "frame {t}: the bundled scene's pushes"
            );
            tracker.expect_motion_px(hint);
            let observed = tracker
                .observe(SceneReplay::frame(&scene, t).unwrap())
                .unwrap();
            assert_eq!(replay.mask().unwrap(), observed.mask, "frame {t}");
            assert_eq!(
                replay.static_labels().unwrap(),
                observed.static_seg.labels.as_slice()
            );
            let frames = replay.body_frames().unwrap();
            assert_eq!(frames.len() % BODY_FRAME_FLOATS, 0);
            assert_eq!(t > 0, !frames.is_empty(), "frame {t}: body frames");
            assert_eq!(t > 0, !replay.flow_field().unwrap().is_empty());
        }
        // The last frame splits the pack: RISeg finds more objects than the static segmenter.
        let truth_objects = |m: [f64; METRICS_LEN]| m[9];
        let statics = replay.metrics(replay.static_labels().unwrap()).unwrap();
        let riseg = replay.metrics(replay.mask().unwrap()).unwrap();
        assert!(
            truth_objects(riseg) > truth_objects(statics),
            "{riseg:?} {statics:?}"
        );
        // Pictures are RGBA of the frame's size.
        let pixels = replay.width() * replay.height();
        assert_eq!(
            replay.labels_picture(replay.mask().unwrap()).unwrap().len(),
            4 * pixels
        );
        assert_eq!(replay.flow_picture().unwrap().len(), 4 * pixels);
        assert_eq!(replay.heat_picture().unwrap().len(), 4 * pixels);
        let [x0, y0, x1, y1] = replay.crop_box().unwrap();
        assert!(x0 < x1 && y0 < y1 && x1 <= replay.width() && y1 <= replay.height());
        assert!(replay.recorded_push(0).is_none() && replay.recorded_push(1).is_some());
    }

    #[test]
    fn stages_out_of_order_say_what_to_call() {
        let (_, files) = bundled("loose");
        let mut replay = Replay::open(&files, "loose").unwrap();
        assert!(replay.mask().unwrap_err().contains("call update first"));
        assert!(
            replay
                .find_action()
                .unwrap_err()
                .contains("no frame observed")
        );
        assert!(
            replay
                .update(0)
                .unwrap_err()
                .contains("call segment(0) first")
        );
        assert!(
            replay
                .segment(1)
                .unwrap_err()
                .contains("the next is frame 0")
        );
        assert!(replay.flow(0).unwrap_err().contains("no previous frame"));
        replay.segment(0).unwrap();
        replay.update(0).unwrap();
        replay.segment(1).unwrap();
        assert!(replay.update(1).unwrap_err().contains("call flow(1) first"));
        // The segmentation is kept: the flow is all that was missing.
        replay.flow(1).unwrap();
        replay.update(1).unwrap();
        replay.restart();
        assert_eq!(replay.next_frame(), 0);
        assert!(replay.mask().is_err());
    }

    #[test]
    fn a_bad_scene_is_riseg_s_message_naming_the_file() {
        let (_, mut files) = bundled("loose");
        files.add("loose/rgb/000001.png", b"not a png".to_vec());
        let e = Replay::open(&files, "loose").unwrap_err();
        assert!(
            e.starts_with("loose/rgb/000001.png: corrupt or unsupported PNG"),
            "{e}"
        );
        let (_, files) = bundled_without("loose", "scene_camera.json");
        let e = Replay::open(&files, "loose").unwrap_err();
        assert_eq!(e, "loose/scene_camera.json: not found");
        let e = Replay::open(&SceneFiles::default(), "loose").unwrap_err();
        assert_eq!(e, "loose: not found");
    }

    #[test]
    fn colour_keys_follow_the_reference_object() {
        // Segment 7 covers objects 1 and 2 (mostly 2); segment 8 is a second piece of 2;
        // segment 9 covers only background.
        let labels = [7, 7, 7, 8, 0, 9];
        let reference = [1, 2, 2, 2, 0, 0];
        let keys = colour_keys(&labels, &reference);
        assert_eq!(keys[..3], [2, 2, 2]);
        assert_eq!(keys[3], 1008, "2 is taken by the larger segment");
        assert_eq!(keys[4], 0);
        assert_eq!(keys[5], 1009);
    }
}
