//! `riseg run`: RISeg over recorded scenes whose pushes already happened, writing the
//! masks in the layout `riseg eval` reads.
//!
//! Frame 0's mask is its static segmentation; every later frame's mask comes from the
//! [`Tracker`] (flow from the previous frame, the new static segmentation, UpdateMask).
//! A scene's masks are all computed before any is written, and each PNG is written
//! atomically: a scene whose folder, input files or tracking fail writes no mask, and no
//! failure leaves a half-written file.
//!
//! # Inputs from files
//!
//! The static segmentation and the flow can be read from files ([`InputDirs`]) instead of
//! computed by the tracker's segmenter and flow estimator: MSMFormer/UCN labels or RAFT
//! flow computed elsewhere, or a dataset's exact flow, which takes flow errors out of a
//! diagnosis. For the scene folder named `S`:
//!
//! ```text
//! FLOW/S/flow/NNNNNN.flo      flow from frame t = NNNNNN to t + 1 (Middlebury .flo, pixels)
//! STATIC/S/label/NNNNNN.png   static labels of frame t: 8- or 16-bit grey, 0 = background
//! STATIC/S/heat/NNNNNN.png    its 0-255 heatmap, 8-bit grey (optional, per frame)
//! ```
//!
//! These are the names of a scene folder's own `flow/` and `label/` ([`crate::io::scene`]),
//! so a dataset `riseg gen` wrote is a valid `FLOW` (its exact flow) and `STATIC` (its
//! ground truth as the static segmentation). Rules:
//! - Every file must have the size `S/scene_camera.json` gives, and every frame its files
//!   (a heatmap excepted); other files are ignored.
//! - Flow: a vector with a component of magnitude `1e9` or more (Middlebury's "unknown") or
//!   a non-finite one becomes `[NaN, NaN]` ([`FlowImage::with_unknown_as_nan`](crate::io::image::FlowImage::with_unknown_as_nan)). riseg-core uses no
//!   information from it: CreateFrames drops a frame whose tracked point has non-finite
//!   flow (`riseg_core::frames`), and CorrectMask's carry step moves a label only to a
//!   target inside the image, which a NaN target is not (`riseg_core::mask`). The core
//!   treats a raw `1e10` the same way (its target lies off the image; a test pins this),
//!   so NaN changes no mask; it makes "unknown" explicit to every other reader of the flow,
//!   such as a drawing of it.
//! - Labels: ids are renumbered `1..=n` in increasing order, as a [`Segmentation`] requires
//!   (ids that already are `1..=n` are unchanged).
//! - Heatmap: without a heat file, a frame's heatmap is [`HEAT_CERTAIN`] on labelled
//!   pixels and `0` elsewhere: labels carry no uncertainty and none is invented (so
//!   FindAction would find no uncertain region). `riseg run` itself uses no heatmap (the
//!   pushes already happened); it is checked and kept for the [`Observation`]'s static
//!   segmentation.
//!
//! Design: [`InputDirs::read_scene`] reads and checks a scene's files before the scene is
//! tracked (a bad file costs no computation), and [`replay_scene`] hands each frame's
//! inputs to [`Tracker::observe_given`]. The tracker has one code path whether a stage's
//! output is computed or given; file-backed [`StaticSegmenter`] and [`FlowEstimator`]
//! types would instead have to be told, out of band, which scene and frame each call
//! serves, and every mix of given and computed stages would be another tracker type.
//!
//! [`Observation`]: crate::rig::tracker::Observation

use std::{
    ffi::OsStr,
    path::{Path, PathBuf},
};

use crate::{
    flow::FlowEstimator,
    io::image::{
        Gray16Image, ImageIoError, ImageProblem, ImageSizeError, read_flo, read_gray_widened,
        read_gray8, read_sized, write_gray16,
    },
    io::scene::{
        FLOW_DIR, HEAT_DIR, LABEL_DIR, PushAction, Scene, SceneCamera, SceneError, frame_file,
        frame_file_name,
    },
    rig::camera::{CameraFrame, SceneReplay},
    rig::episode::action_motion_px,
    rig::tracker::{GivenInputs, Observation, TrackError, Tracker},
    segment::{HEAT_CERTAIN, Segmentation, StaticSegmenter},
};

/// Why a run failed; every variant names the scene folder or file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RunError {
    /// The scene could not be read.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A flow or static segmentation file of a frame could not be used.
    #[error("{scene}, frame {frame}: {what}: {source}")]
    Input {
        /// The scene folder.
        scene: PathBuf,
        /// The frame the file was for.
        frame: usize,
        /// Which input.
        what: InputKind,
        /// The file and its problem.
        source: ImageIoError,
    },
    /// Tracking failed on a frame.
    #[error("{scene}, frame {frame}: {source}")]
    Track {
        /// The scene folder.
        scene: PathBuf,
        /// The frame that failed.
        frame: usize,
        /// The cause.
        source: TrackError,
    },
    /// A mask could not be written.
    #[error(transparent)]
    Write(#[from] ImageIoError),
    /// A mask did not match the scene's image size.
    #[error("{path}: {source}")]
    MaskSize {
        /// The mask file.
        path: PathBuf,
        /// The cause.
        source: ImageSizeError,
    },
    /// The output folder could not be made.
    #[error("creating {path}: {source}")]
    CreateDir {
        /// The folder.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// A per-frame input read from a file ([`InputDirs`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum InputKind {
    /// The flow from the previous frame to this one.
    #[error("flow from the previous frame")]
    Flow,
    /// The static labels.
    #[error("static labels")]
    Labels,
    /// The static heatmap.
    #[error("static heatmap")]
    Heatmap,
}

/// Where `riseg run` reads inputs instead of computing them (module docs); `None` computes.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct InputDirs {
    /// Holds `<scene>/flow/NNNNNN.flo`, the flow from frame `t` to `t + 1`.
    pub flow: Option<PathBuf>,
    /// Holds `<scene>/label/NNNNNN.png` and optionally `<scene>/heat/NNNNNN.png`.
    pub statics: Option<PathBuf>,
}

impl InputDirs {
    /// Reads and checks the given inputs of every frame of `scene`, read from the folder
    /// `dir` (module docs): one [`GivenInputs`] per frame, all empty when no folder is set.
    ///
    /// # Errors
    /// [`RunError::Input`] for the first frame and input whose file is missing, corrupt, of
    /// the wrong bit depth or not the size of `scene.camera`.
    pub fn read_scene(&self, dir: &Path, scene: &Scene) -> Result<Vec<GivenInputs>, RunError> {
        let name = scene_name(dir);
        let failed = |frame, what, source| RunError::Input {
            scene: dir.to_owned(),
            frame,
            what,
            source,
        };
        (0..scene.frames())
            .map(|t| {
                let static_seg = self
                    .statics
                    .as_ref()
                    .map(|statics| read_static(&statics.join(name), &scene.camera, t))
                    .transpose()
                    .map_err(|(what, e)| failed(t, what, e))?;
                let flow = match (&self.flow, t.checked_sub(1)) {
                    (Some(flows), Some(prev)) => {
                        let path = frame_file(&flows.join(name), FLOW_DIR, prev, "flo");
                        let image =
                            read_sized(&path, scene.camera.width, scene.camera.height, read_flo)
                                .map_err(|e| failed(t, InputKind::Flow, e))?;
                        Some(image.with_unknown_as_nan())
                    }
                    _ => None,
                };
                Ok(GivenInputs { static_seg, flow })
            })
            .collect()
    }
}

/// The name of the scene folder `dir` (the whole path if it has none, such as `..`).
fn scene_name(dir: &Path) -> &OsStr {
    dir.file_name().unwrap_or(dir.as_os_str())
}

/// Frame `t`'s labels (renumbered `1..=n`) and heatmap from the static folder `dir` of
/// one scene (module docs); an error says which of the two files failed.
fn read_static(
    dir: &Path,
    camera: &SceneCamera,
    t: usize,
) -> Result<Segmentation, (InputKind, ImageIoError)> {
    let path = frame_file(dir, LABEL_DIR, t, "png");
    let mut labels = read_sized(&path, camera.width, camera.height, read_gray_widened)
        .map_err(|e| (InputKind::Labels, e))?;
    renumber(labels.as_mut_slice());
    let path = frame_file(dir, HEAT_DIR, t, "png");
    let heatmap = match read_sized(&path, camera.width, camera.height, read_gray8) {
        Ok(heat) => heat,
        Err(e) if matches!(e.problem, ImageProblem::Missing) => {
            labels.map(|&l| if l == 0 { 0 } else { HEAT_CERTAIN })
        }
        Err(e) => return Err((InputKind::Heatmap, e)),
    };
    Ok(Segmentation { labels, heatmap })
}

/// Renumbers the non-zero ids of `labels` to `1..=n` in increasing order; `0` stays `0`.
fn renumber(labels: &mut [u16]) {
    let mut new_id = vec![0u16; usize::from(u16::MAX) + 1];
    for &l in labels.iter().filter(|&&l| l != 0) {
        new_id[usize::from(l)] = 1;
    }
    let mut next = 0u16;
    for id in new_id.iter_mut().skip(1).filter(|id| **id != 0) {
        next += 1;
        *id = next;
    }
    for l in labels {
        *l = new_id[usize::from(*l)];
    }
}

/// One replayed frame, as `on_frame` of [`replay_scene`] sees it.
#[derive(Debug, Clone, Copy)]
pub struct ReplayedFrame<'a> {
    /// Frame index: the scene after `t` pushes.
    pub t: usize,
    /// The frame.
    pub frame: &'a CameraFrame,
    /// What the tracker made of it.
    pub observation: &'a Observation,
    /// The recorded push made from this frame (`actions.json`), if the scene has one.
    pub push: Option<&'a PushAction>,
}

/// Replays a recorded scene (the pushes already happened) through `tracker` from frame 0:
/// the accumulated mask of every frame, in order. Frame `t` uses `given[t]`
/// ([`Tracker::observe_given`]); frames past the end of `given` compute everything. The
/// recorded push that made frame `t` (`scene.actions`) is the flow's motion hint
/// ([`action_motion_px`]), as it was in the closed loop that recorded it.
/// `on_frame` sees frame `t` after it is done.
///
/// # Errors
/// The frame that failed and the [`TrackError`].
pub fn replay_scene<S: StaticSegmenter, F: FlowEstimator>(
    tracker: &mut Tracker<S, F>,
    scene: &Scene,
    given: Vec<GivenInputs>,
    mut on_frame: impl FnMut(&ReplayedFrame<'_>),
) -> Result<Vec<Vec<u16>>, (usize, TrackError)> {
    tracker.reset();
    let mut given = given.into_iter();
    let mut masks = Vec::with_capacity(scene.frames());
    let intrinsics = scene.camera.intrinsics();
    for t in 0..scene.frames() {
        let Some(frame) = SceneReplay::frame(scene, t) else {
            break;
        };
        let inputs = given.next().unwrap_or_default();
        // The recorded push that made frame t is the flow's motion hint, as in the live run.
        let hint = t
            .checked_sub(1)
            .and_then(|p| scene.actions.get(p))
            .and_then(|a| action_motion_px(a, &intrinsics));
        tracker.expect_motion_px(hint);
        let observation = tracker.observe_given(frame, inputs).map_err(|e| (t, e))?;
        if let Some(frame) = tracker.last_frame() {
            on_frame(&ReplayedFrame {
                t,
                frame,
                observation: &observation,
                push: scene.actions.get(t),
            });
        }
        masks.push(observation.mask);
    }
    Ok(masks)
}

/// Reads the scene folder `dir` and the inputs `inputs` gives for it, replays it, and
/// writes its masks to `out/<dir's name>/label/NNNNNN.png`; returns how many were written.
/// `on_frame` sees each frame as it is done ([`replay_scene`]).
///
/// # Errors
/// [`RunError`] naming the folder or file that failed; no mask of the scene is written
/// unless the failure is in writing them.
pub fn run_scene<S: StaticSegmenter, F: FlowEstimator>(
    tracker: &mut Tracker<S, F>,
    dir: &Path,
    inputs: &InputDirs,
    out: &Path,
    on_frame: impl FnMut(&ReplayedFrame<'_>),
) -> Result<usize, RunError> {
    let mut scene = Scene::read_frames(dir)?;
    // The recorded pushes give the flow its motion hints (`replay_scene`); a scene without
    // `actions.json` replays without them, a corrupt one is an error naming it.
    scene.actions = Scene::read_actions(dir, scene.frames())?;
    let given = inputs.read_scene(dir, &scene)?;
    let masks = replay_scene(tracker, &scene, given, on_frame).map_err(|(frame, source)| {
        RunError::Track {
            scene: dir.to_owned(),
            frame,
            source,
        }
    })?;
    let label_dir = out.join(scene_name(dir)).join(LABEL_DIR);
    std::fs::create_dir_all(&label_dir).map_err(|source| RunError::CreateDir {
        path: label_dir.clone(),
        source,
    })?;
    let count = masks.len();
    for (t, mask) in masks.into_iter().enumerate() {
        let path = label_dir.join(frame_file_name(t, "png"));
        let image = Gray16Image::from_vec(scene.camera.width, scene.camera.height, mask).map_err(
            |source| RunError::MaskSize {
                path: path.clone(),
                source,
            },
        )?;
        write_gray16(&path, &image)?;
    }
    Ok(count)
}

// --- the `riseg run` command ----------------------------------------------------

mod command {
    use std::path::PathBuf;

    use crate::cli::config::ConfigArg;
    use crate::cli::models::Models;
    use crate::cli::record::{PushArrow, Recording};
    use crate::cli::run::{InputDirs, run_scene};
    use anyhow::{Context as _, bail};
    use clap::Args;
    use indicatif::{ProgressBar, ProgressStyle};

    pub(in crate::cli) const RUN_HELP: &str = "\
Run RISeg on recorded scenes (the pushes already happened) and write its masks.

For each scene folder (the format `riseg gen` writes and `riseg gen --help` describes: \
scene_camera.json, rgb/NNNNNN.png, depth/NNNNNN.png; label/, flow/, actions.json and \
poses.json are not read), frame 0 is segmented by the built-in static segmenter; for every later frame the \
optical flow from the previous frame, the new static segmentation and riseg-core's \
UpdateMask carry the mask forward and split what moved differently. The mask of frame t \
is written to PRED/<scene>/label/<t>.png (16-bit, 0 = background), the layout \
`riseg eval --pred PRED` reads. Each PNG is written atomically, and a scene whose \
folder, input files or tracking fail writes no mask.

Where the static segmentation and the flow come from (four options, two per stage): \
--segmenter builtin|PATH.onnx and --flow builtin|PATH.onnx compute them (builtin: the \
classical segmenter and DIS flow, the default; PATH.onnx: a learned model run by ONNX \
Runtime, riseg built with --features onnx, contract below); --static-dir and --flow-dir \
read them from files computed elsewhere instead (RAFT flow, MSMFormer or UCN labels). \
--static-dir excludes --segmenter and --flow-dir excludes --flow. Files are read for the \
scene folder named S and frame t (NNNNNN = t, six digits):

  FLOW/S/flow/NNNNNN.flo      flow from frame t to t+1 (Middlebury .flo, pixels);
                              a component >= 1e9 is unknown and is not used
  STATIC/S/label/NNNNNN.png   static labels of frame t: 8- or 16-bit grey,
                              0 = background; ids are renumbered 1..n in order
  STATIC/S/heat/NNNNNN.png    optional 0-255 heatmap of frame t, 8-bit grey; without
                              it labelled pixels count as certain (run uses none)

These are the names of a scene folder's own flow/ and label/, so a dataset made by \
`riseg gen` serves as FLOW (its exact flow) and as STATIC (its ground truth). Every file \
must have the size in S/scene_camera.json; a missing, corrupt, mis-sized or (heatmap) \
non-8-bit file stops the run with an error naming the file, the scene and the frame.

Live (--live): the loop on devices, recorded. --camera sim --robot sim runs it on the \
simulator through the same code path as --camera realsense --robot franka (features \
`realsense` and `franka`; --calib FILE, the hand-eye calibration, is required there). \
The recording is written to OUT/scene_live/ (the scene folder format; `riseg run --scene \
OUT/scene_live` replays it to the same masks) and the run's masks to \
OUT/pred/scene_live/label/. --dry-run plans and prints frame 0's push and sends nothing. \
Ctrl-C ends the run before the next push (a second Ctrl-C exits at once); a lost camera \
or robot ends it with an error; the recording is written either way. Before the first \
live push, read the README's checklist (calibration, workspace box, table height, \
emergency stop in reach).

Examples:
  riseg run --scene data/sim23/scene_004 --out out/pred
  riseg run --dataset data/sim23 --out out/pred && riseg eval --gt data/sim23 --pred out/pred
  riseg run --dataset data/packed --flow-dir data/packed --out out/exact   (exact flow)
  riseg run --dataset data/real --flow-dir raft --static-dir msmformer --out out/learned
  riseg run --dataset data/real --segmenter msmformer.onnx --flow raft.onnx --out out/onnx
  riseg run --live --camera sim --robot sim --seed 3 --out out/live
  riseg run --live --camera realsense --robot franka --calib hand_eye.json --dry-run --out out/rig";

    #[derive(Debug, Args)]
    #[command(group(clap::ArgGroup::new("input").required(true).args(["scene", "dataset", "live"])))]
    pub(in crate::cli) struct RunArgs {
        /// One scene folder.
        #[arg(long, value_name = "DIR")]
        scene: Option<PathBuf>,
        /// A dataset: every scene_* folder in it.
        #[arg(long, value_name = "DIR")]
        dataset: Option<PathBuf>,
        /// Run the loop on devices (--camera, --robot) and record it: the recording goes to
        /// OUT/scene_live/, its masks to OUT/pred/scene_live/label/.
        #[arg(long, conflicts_with_all = ["flow_dir", "static_dir"])]
        live: bool,
        #[command(flatten)]
        live_args: crate::cli::live::LiveArgs,
        /// Output folder: masks go to OUT/<scene name>/label/NNNNNN.png.
        #[arg(long, value_name = "PRED")]
        out: PathBuf,
        /// Read the flow from frame t to t+1 of scene S from FLOW/S/flow/<t>.flo (Middlebury)
        /// instead of computing it; a dataset made by `riseg gen` holds its exact flow.
        #[arg(long, value_name = "FLOW", conflicts_with = "flow")]
        flow_dir: Option<PathBuf>,
        /// Read the static labels of frame t of scene S from STATIC/S/label/<t>.png (8- or
        /// 16-bit, 0 = background) and its heatmap from STATIC/S/heat/<t>.png (8-bit, optional)
        /// instead of segmenting.
        #[arg(long, value_name = "STATIC", conflicts_with = "segmenter")]
        static_dir: Option<PathBuf>,
        /// Also record every frame to FILE (a rerun .rrd: images, masks, body frames, the
        /// recorded pushes, flow, stage timings on the `push` timeline, one root entity per
        /// scene); needs riseg built with `--features rerun`.
        #[arg(long, value_name = "FILE.rrd")]
        rerun: Option<PathBuf>,
        #[command(flatten)]
        models: Models,
        #[command(flatten)]
        config: ConfigArg,
    }

    pub(in crate::cli) fn command(args: &RunArgs) -> anyhow::Result<()> {
        if args.live {
            let settings = args.config.load()?.settings();
            return crate::cli::live::command(&args.live_args, &settings, &args.out);
        }
        let scenes = match (&args.scene, &args.dataset) {
            (Some(scene), _) => vec![scene.clone()],
            (None, Some(dataset)) => {
                let scenes = crate::io::scene::list_scenes(dataset)?;
                if scenes.is_empty() {
                    bail!("{}: no scene_* folders", dataset.display());
                }
                scenes
            }
            (None, None) => bail!("give --scene DIR or --dataset DIR"),
        };
        let settings = args.config.load()?.settings();
        let mut tracker = args.models.tracker(&settings, None)?;
        let bar = ProgressBar::new(scenes.len() as u64).with_style(
            ProgressStyle::with_template(
                "{bar:30} {pos}/{len} scenes  {elapsed}  eta {eta}  {msg}",
            )
            .context("progress bar template")?,
        );
        let inputs = InputDirs {
            flow: args.flow_dir.clone(),
            statics: args.static_dir.clone(),
        };
        for dir in &scenes {
            super::refuse_output_over_input(dir, &args.out)?;
        }
        let recording = args.rerun.as_deref().map(Recording::create).transpose()?;
        // rerun reports a failed write at the latest on `finish`; the first error that
        // logging a frame returned is kept and ends the run after its scene.
        let mut log_error = None;
        let mut frames = 0;
        for (done, dir) in scenes.iter().enumerate() {
            let name = dir.file_name().unwrap_or(dir.as_os_str()).to_string_lossy();
            frames += run_scene(&mut tracker, dir, &inputs, &args.out, |f| {
                bar.set_message(format!("{name}: frame {}", f.t));
                let Some(recording) = &recording else {
                    return;
                };
                let push = f
                    .push
                    .and_then(|a| PushArrow::from_action(a, &f.frame.intrinsics));
                if let Err(e) = recording.frame(&name, f.t, f.frame, f.observation, push.as_ref()) {
                    log_error.get_or_insert(e);
                }
            })
            .with_context(|| match done {
                0 => "no masks written".to_owned(),
                _ => format!(
                    "the masks of the {done} scenes before {name} are complete in {}",
                    args.out.display()
                ),
            })?;
            if let Some(e) = log_error.take() {
                return Err(e);
            }
            bar.inc(1);
        }
        recording.map(Recording::finish).transpose()?;
        bar.finish_and_clear();
        say!(
            "wrote {frames} masks of {} scenes to {}\n",
            scenes.len(),
            args.out.display()
        )?;
        Ok(())
    }
}

/// Refuses an output folder where the masks of scene `dir` would land in `dir` itself
/// (`--out` the dataset): they would replace its ground-truth `label/` files.
fn refuse_output_over_input(dir: &Path, out: &Path) -> anyhow::Result<()> {
    let target = out.join(scene_name(dir));
    let same = match (std::fs::canonicalize(&target), std::fs::canonicalize(dir)) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    if same {
        anyhow::bail!(
            "--out {}: the masks of {} would replace its own {LABEL_DIR}/ files; \
             write them to another folder",
            out.display(),
            dir.display()
        );
    }
    Ok(())
}

pub(in crate::cli) use command::*;
