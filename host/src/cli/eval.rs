//! `riseg eval`: predicted label maps scored against a dataset's ground truth with the
//! UOIS metrics of [`crate::eval::metrics`], averaged per push index.
//!
//! # Folder layout
//!
//! ```text
//! DATASET/scene_000/label/000000.png   ground truth, 16-bit grey, instance ids, 0 = background
//!                         000001.png   frame t = the scene after t pushes
//! PRED/scene_000/label/000000.png      the prediction for the same frame, same size, 16-bit
//! ```
//!
//! Every `scene_*` folder of `DATASET` must have a `label/` folder holding at least one
//! `<frame number>.png` (other files there are ignored), and `PRED` must have the same
//! file for each (extra files in `PRED` are ignored). The frame number is the push index the image is averaged under. Any
//! missing, unreadable, non-16-bit or mis-sized label map is an [`EvalError`] that names
//! the file; nothing is skipped silently.
//!
//! # Contract
//!
//! [`find_frame_pairs`] lists the work and checks that every prediction exists;
//! [`evaluate`] reads and scores each pair and averages per push into an [`EvalReport`],
//! whose numbers are percentages; [`EvalReport`] prints as a table (`Display`) and
//! writes JSON atomically ([`EvalReport::write_json`]).
//!
//! # Motion ceiling
//!
//! When every scene folder of `DATASET` has a `poses.json` (the objects' true poses,
//! format in [`crate::io::scene`]; [`dataset_poses`] says whether they do),
//! [`evaluate_ceiling`] scores the motion ceiling of every ground-truth frame the same
//! way: each scene is read as a scene folder ([`Scene::read`], which checks `poses.json`
//! too: colour, depth, labels and poses are needed), every frame is segmented by the given
//! static segmenter, and [`MotionCeiling`] turns the labels, static segmentations and poses
//! of frames `0..=t` ([`SceneReplay::frame`]) into the ceiling mask of frame `t`.
//! The rows go to [`EvalReport::ceiling`]; the table then also prints the prediction's
//! share of the ceiling per push (the ratio of the objects-found percentages).

use core::fmt;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::{
    eval::ceiling::{CeilingError, CeilingParams, MotionCeiling},
    eval::metrics::{self, ImageMetrics, MetricsError, MetricsRow, Prf, PushAverages},
    io::image::{ImageIoError, read_gray16},
    io::scene::{LABEL_DIR, POSES_FILE, Scene, SceneError, frame_file_name, list_scenes},
    io::write_atomic,
    rig::camera::SceneReplay,
    segment::{SegmentError, StaticSegmenter},
};

/// Why an evaluation failed. Every variant names the file or folder at fault; the
/// underlying error, if any, is the [`std::error::Error::source`] (print the chain, e.g.
/// anyhow's `{:#}`, to see both).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EvalError {
    /// A file or folder could not be read or written.
    #[error("{}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The operating system's error.
        source: io::Error,
    },
    /// The dataset folder has no `scene_*` folder.
    #[error("{}: no scene_* folders (expected DATASET/scene_000/label/000000.png, ...)", root.display())]
    NoScenes {
        /// The dataset folder.
        root: PathBuf,
    },
    /// A scene has no ground-truth label maps.
    #[error("{}: no ground-truth label maps (expected label/000000.png, ...)", scene.display())]
    NoGroundTruth {
        /// The scene folder.
        scene: PathBuf,
    },
    /// A PNG in a `label/` folder is not named by a frame number.
    #[error("{}: a label map must be named by its frame number in six digits, like 000000.png", path.display())]
    BadFrameName {
        /// The file.
        path: PathBuf,
    },
    /// The prediction for a ground-truth frame does not exist.
    #[error("{}: missing prediction (PRED must mirror the dataset's scene_*/label/ files)", path.display())]
    MissingPrediction {
        /// The prediction file that should exist.
        path: PathBuf,
    },
    /// A label map is missing, not a readable PNG, or not 16-bit greyscale (the message
    /// names the file and the problem).
    #[error(transparent)]
    Image(#[from] ImageIoError),
    /// A prediction's size differs from its ground truth's.
    #[error(
        "{}: {width}x{height} labels, but the ground truth is {gt_width}x{gt_height}",
        path.display()
    )]
    SizeMismatch {
        /// The prediction file.
        path: PathBuf,
        /// The prediction's width in pixels.
        width: usize,
        /// The prediction's height in pixels.
        height: usize,
        /// The ground truth's width in pixels.
        gt_width: usize,
        /// The ground truth's height in pixels.
        gt_height: usize,
    },
    /// The metrics refused the pair (too many objects).
    #[error("{}: cannot score this prediction", path.display())]
    Metrics {
        /// The prediction file (for the motion ceiling, the ground-truth label map).
        path: PathBuf,
        /// Why.
        source: MetricsError,
    },
    /// A scene folder could not be read for the motion ceiling (a malformed `poses.json`
    /// or one that does not fit its scene is named here, by [`Scene::read`]).
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The motion ceiling refused a scene's poses: an object of the ground truth has none.
    #[error("{}", path.display())]
    Poses {
        /// The scene's `poses.json`.
        path: PathBuf,
        /// Why.
        source: CeilingError,
    },
    /// The static segmenter failed on a frame of a scene.
    #[error("{}: static segmentation of frame {frame}", scene.display())]
    Segment {
        /// The scene folder.
        scene: PathBuf,
        /// The frame.
        frame: usize,
        /// Why.
        source: SegmentError,
    },
}

/// One ground-truth frame and the prediction to score against it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FramePair {
    /// The scene folder's name, e.g. `scene_000`.
    pub scene: String,
    /// The frame number: how many pushes the scene has had.
    pub push: u32,
    /// `DATASET/<scene>/label/<frame>.png`.
    pub gt: PathBuf,
    /// `PRED/<scene>/label/<frame>.png`.
    pub pred: PathBuf,
}

/// Lists every ground-truth frame of `gt_root` with its prediction under `pred_root`,
/// scenes and frames in name order.
///
/// # Errors
/// [`EvalError::NoScenes`], [`EvalError::NoGroundTruth`], [`EvalError::BadFrameName`],
/// [`EvalError::MissingPrediction`] as their names say; [`EvalError::Io`] if a folder
/// cannot be listed.
pub fn find_frame_pairs(gt_root: &Path, pred_root: &Path) -> Result<Vec<FramePair>, EvalError> {
    let mut scenes: Vec<(String, PathBuf)> = list_dir(gt_root)?
        .into_iter()
        .filter(|path| path.is_dir())
        .filter_map(|path| {
            let name = path.file_name()?.to_str()?.to_owned();
            name.starts_with("scene_").then_some((name, path))
        })
        .collect();
    if scenes.is_empty() {
        return Err(EvalError::NoScenes {
            root: gt_root.to_owned(),
        });
    }
    scenes.sort();

    let mut pairs = Vec::new();
    for (scene, scene_dir) in scenes {
        let label_dir = scene_dir.join("label");
        if !label_dir.is_dir() {
            return Err(EvalError::NoGroundTruth { scene: scene_dir });
        }
        let mut frames = Vec::new();
        for gt in list_dir(&label_dir)? {
            if gt.extension().and_then(|e| e.to_str()) != Some("png") {
                continue;
            }
            let push = gt
                .file_stem()
                .and_then(|s| s.to_str())
                .filter(|s| s.len() == 6 && s.bytes().all(|b| b.is_ascii_digit()))
                .and_then(|s| s.parse::<u32>().ok())
                .ok_or_else(|| EvalError::BadFrameName { path: gt.clone() })?;
            frames.push((push, gt));
        }
        if frames.is_empty() {
            return Err(EvalError::NoGroundTruth { scene: scene_dir });
        }
        frames.sort();
        for (push, gt) in frames {
            let mut pred = pred_root.join(&scene).join("label");
            if let Some(name) = gt.file_name() {
                pred.push(name);
            }
            if !pred.is_file() {
                return Err(EvalError::MissingPrediction { path: pred });
            }
            pairs.push(FramePair {
                scene: scene.clone(),
                push,
                gt,
                pred,
            });
        }
    }
    Ok(pairs)
}

/// The entries of a folder (any order).
fn list_dir(dir: &Path) -> Result<Vec<PathBuf>, EvalError> {
    let io_error = |source| EvalError::Io {
        path: dir.to_owned(),
        source,
    };
    fs::read_dir(dir)
        .map_err(io_error)?
        .map(|entry| entry.map(|e| e.path()).map_err(io_error))
        .collect()
}

/// Reads both label maps of `pair` and computes their metrics.
///
/// # Errors
/// [`EvalError::Image`] if either file is not a 16-bit greyscale PNG
/// ([`read_gray16`]); [`EvalError::SizeMismatch`] if the
/// prediction's size differs from the ground truth's; [`EvalError::Metrics`] if the
/// metrics refuse the pair.
pub fn frame_metrics(pair: &FramePair) -> Result<ImageMetrics, EvalError> {
    let gt = read_gray16(&pair.gt)?;
    let pred = read_gray16(&pair.pred)?;
    if pred.size() != gt.size() {
        return Err(EvalError::SizeMismatch {
            path: pair.pred.clone(),
            width: pred.width(),
            height: pred.height(),
            gt_width: gt.width(),
            gt_height: gt.height(),
        });
    }
    let (width, height) = gt.size();
    metrics::image_metrics(gt.as_slice(), pred.as_slice(), width, height).map_err(|source| {
        EvalError::Metrics {
            path: pair.pred.clone(),
            source,
        }
    })
}

/// Scores every pair and averages per push index; calls `on_image` after each image
/// (for a progress bar).
///
/// # Errors
/// The first error of [`frame_metrics`].
pub fn evaluate(pairs: &[FramePair], mut on_image: impl FnMut()) -> Result<EvalReport, EvalError> {
    let mut averages = PushAverages::new();
    for pair in pairs {
        averages.add(pair.push, &frame_metrics(pair)?);
        on_image();
    }
    Ok(EvalReport::from_rows(&averages.rows()))
}

/// Precision, recall and F-measure in percent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PrfPct {
    /// Precision, 0–100.
    pub p: f64,
    /// Recall, 0–100.
    pub r: f64,
    /// F-measure, 0–100.
    pub f: f64,
}

impl From<Prf> for PrfPct {
    fn from(prf: Prf) -> Self {
        Self {
            p: 100.0 * prf.precision,
            r: 100.0 * prf.recall,
            f: 100.0 * prf.f_measure,
        }
    }
}

/// The mean metrics of one push index, in percent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PushReport {
    /// Push index (frame number).
    pub push: u32,
    /// Images averaged.
    pub images: usize,
    /// Overlap P / R / F.
    pub overlap: PrfPct,
    /// Boundary P / R / F.
    pub boundary: PrfPct,
    /// Mean share of ground-truth objects matched with overlap F > 75 %.
    pub objects_f75_pct: f64,
}

impl From<&MetricsRow> for PushReport {
    fn from(row: &MetricsRow) -> Self {
        Self {
            push: row.push,
            images: row.images,
            overlap: row.overlap.into(),
            boundary: row.boundary.into(),
            objects_f75_pct: 100.0 * row.objects_detected_share,
        }
    }
}

/// The result of `riseg eval`: one [`PushReport`] per push index, in push order. Its
/// JSON form is `{"pushes": [ROW, ...]}`, ROW = `{"push": 0, "images": 23, "overlap":
/// {"p": .., "r": .., "f": ..}, "boundary": {..}, "objects_f75_pct": ..}`, with
/// `"ceiling": [ROW, ...]` and `"ceiling_floor_m": 0.001` beside `"pushes"` when the
/// motion ceiling was scored.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalReport {
    /// One entry per push index.
    pub pushes: Vec<PushReport>,
    /// The motion ceiling of the same frames (module docs), when it was scored.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ceiling: Option<Vec<PushReport>>,
    /// The translation floor the ceiling was scored at, metres
    /// ([`CeilingParams::trans_floor_m`]), when it was scored.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ceiling_floor_m: Option<f32>,
}

impl EvalReport {
    /// The report of averaged rows, converted to percent, without a ceiling.
    #[must_use]
    pub fn from_rows(rows: &[MetricsRow]) -> Self {
        Self {
            pushes: rows.iter().map(PushReport::from).collect(),
            ceiling: None,
            ceiling_floor_m: None,
        }
    }

    /// Writes the report as pretty JSON to `path`, atomically: a temporary file in the
    /// same folder is written, flushed and renamed over `path`, so a reader never sees a
    /// half-written report.
    ///
    /// # Errors
    /// [`EvalError::Io`] naming `path` if it cannot be written.
    pub fn write_json(&self, path: &Path) -> Result<(), EvalError> {
        let io_error = |source| EvalError::Io {
            path: path.to_owned(),
            source,
        };
        let mut json = serde_json::to_vec_pretty(self).map_err(|e| io_error(e.into()))?;
        json.push(b'\n');
        write_atomic(path, &json).map_err(io_error)
    }
}

impl fmt::Display for EvalReport {
    /// The table `riseg eval` prints: one line per push index, numbers in percent; then,
    /// when scored, the motion ceiling's table and the prediction's share of it.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_table(f, &self.pushes)?;
        if let Some(ceiling) = &self.ceiling {
            write!(f, "\nmotion ceiling")?;
            if let Some(floor_m) = self.ceiling_floor_m {
                write!(f, " at a {:.2} mm floor", floor_m * 1e3)?;
            }
            writeln!(
                f,
                " (ground truth, objects merged where no static segmentation or push could \
                 separate them):"
            )?;
            write_table(f, ceiling)?;
            write_ceiling_shares(f, "prediction", &self.pushes, ceiling)?;
        }
        Ok(())
    }
}

/// One line per push index: overlap and boundary P, R, F and objects found, in percent.
fn write_table(f: &mut fmt::Formatter<'_>, rows: &[PushReport]) -> fmt::Result {
    writeln!(f, "{:13}|{:^23}|{:^23}|", "", "overlap (%)", "boundary (%)")?;
    writeln!(
        f,
        "{:>4} {:>7} |{:>7}{:>7}{:>7}  |{:>7}{:>7}{:>7}  | objects F>75 (%)",
        "push", "images", "P", "R", "F", "P", "R", "F"
    )?;
    for row in rows {
        writeln!(
            f,
            "{:>4} {:>7} |{:>7.1}{:>7.1}{:>7.1}  |{:>7.1}{:>7.1}{:>7.1}  |{:>10.1}",
            row.push,
            row.images,
            row.overlap.p,
            row.overlap.r,
            row.overlap.f,
            row.boundary.p,
            row.boundary.r,
            row.boundary.f,
            row.objects_f75_pct
        )?;
    }
    Ok(())
}

/// One line per push index present in both `rows` and `ceiling`: `"<name> / ceiling,
/// objects F>75 at push t: x.xxx"`, the ratio of the two rows' objects-found percentages
/// (`n/a` when the ceiling finds none).
///
/// # Errors
/// Only the formatter's.
pub fn write_ceiling_shares(
    f: &mut fmt::Formatter<'_>,
    name: &str,
    rows: &[PushReport],
    ceiling: &[PushReport],
) -> fmt::Result {
    for row in rows {
        let Some(top) = ceiling.iter().find(|c| c.push == row.push) else {
            continue;
        };
        write!(f, "{name} / ceiling, objects F>75 at push {}: ", row.push)?;
        if top.objects_f75_pct > 0.0 {
            // Three decimals: a share of 0.895 must not read as the 0.90 it is judged by.
            writeln!(f, "{:.3}", row.objects_f75_pct / top.objects_f75_pct)?;
        } else {
            writeln!(f, "n/a (the ceiling finds no object)")?;
        }
    }
    Ok(())
}

/// Whether a dataset can have a motion ceiling.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DatasetPoses {
    /// Every scene folder has a `poses.json`: the scene folders, in name order.
    All(Vec<PathBuf>),
    /// The first scene folder (in name order) without a `poses.json`.
    Missing(PathBuf),
}

/// Whether every `scene_*` folder of `gt_root` has a `poses.json` (read and checked later,
/// by [`evaluate_ceiling`]).
///
/// # Errors
/// [`EvalError::Scene`] if `gt_root` cannot be listed, [`EvalError::NoScenes`] if it has
/// no scene folder.
pub fn dataset_poses(gt_root: &Path) -> Result<DatasetPoses, EvalError> {
    let scenes = list_scenes(gt_root)?;
    if scenes.is_empty() {
        return Err(EvalError::NoScenes {
            root: gt_root.to_owned(),
        });
    }
    match scenes.iter().find(|s| !s.join(POSES_FILE).exists()) {
        Some(scene) => Ok(DatasetPoses::Missing(scene.clone())),
        None => Ok(DatasetPoses::All(scenes)),
    }
}

/// Scores the motion ceiling of every frame of the scene folders `scenes` (module docs),
/// with static segmentations from `segmenter`; calls `on_frame` after each frame. The rows
/// are in percent, one per push index.
///
/// # Errors
/// [`EvalError::Scene`] naming the file if a scene folder is unreadable or breaks a rule
/// of [`Scene::read`], its `poses.json` included (one whose frame count differs from the
/// scene's, say), or has no `poses.json`; [`EvalError::NoGroundTruth`] if it has no
/// labels; [`EvalError::Poses`] naming a `poses.json` that lacks the pose of an object of
/// the labels; [`EvalError::Segment`] if the segmenter fails; [`EvalError::Metrics`]
/// naming the label map the metrics refuse.
pub fn evaluate_ceiling(
    scenes: &[PathBuf],
    segmenter: &mut impl StaticSegmenter,
    params: &CeilingParams,
    mut on_frame: impl FnMut(),
) -> Result<Vec<PushReport>, EvalError> {
    let mut averages = PushAverages::new();
    for dir in scenes {
        let scene = Scene::read(dir)?;
        if scene.labels.is_none() {
            return Err(EvalError::NoGroundTruth { scene: dir.clone() });
        }
        let poses_path = dir.join(POSES_FILE);
        if scene.poses.is_none() {
            return Err(SceneError::Missing { path: poses_path }.into());
        }
        let mut ceiling = MotionCeiling::new(*params);
        // Every frame has its labels and poses: `Scene::read` checked their counts.
        let frames = (0..scene.frames()).map_while(|t| SceneReplay::frame(&scene, t));
        for (t, frame) in frames.enumerate() {
            let static_seg = frame
                .rgbd()
                .and_then(|rgbd| segmenter.segment(&rgbd, &frame.intrinsics))
                .map_err(|source| EvalError::Segment {
                    scene: dir.clone(),
                    frame: t,
                    source,
                })?;
            let Some(input) = frame.ceiling_frame(static_seg.labels.as_slice()) else {
                return Err(EvalError::NoGroundTruth { scene: dir.clone() });
            };
            let mask = ceiling
                .next_frame(&input)
                // `Scene::read` checked every image's size, so what the ceiling can refuse
                // here is the poses: an object of the labels without one.
                .map_err(|source| EvalError::Poses {
                    path: poses_path.clone(),
                    source,
                })?;
            let scored = metrics::image_metrics(input.truth, &mask, input.width, input.height)
                .map_err(|source| EvalError::Metrics {
                    path: dir.join(LABEL_DIR).join(frame_file_name(t, "png")),
                    source,
                })?;
            averages.add(t as u32, &scored);
            on_frame();
        }
    }
    Ok(EvalReport::from_rows(&averages.rows()).pushes)
}

// --- the `riseg eval` command ----------------------------------------------------

mod command {
    use std::path::PathBuf;

    use crate::cli::config::ConfigArg;
    use crate::cli::eval::{self, DatasetPoses};
    use crate::eval::ceiling::CeilingParams;
    use crate::io::scene::{self};
    use crate::segment::ClassicalSegmenter;
    use anyhow::Context as _;
    use clap::Args;
    use indicatif::{ProgressBar, ProgressStyle};

    pub(in crate::cli) const EVAL_HELP: &str = "\
Folder layout (PRED mirrors DATASET file for file):
  DATASET/scene_000/label/000000.png   ground truth: 16-bit grey, instance ids, 0 = background
                          000001.png   frame t shows the scene after t pushes: push index t
  PRED/scene_000/label/000000.png      prediction for that frame: same size, 16-bit
Only scene_* folders are read; every ground-truth frame needs its prediction. A missing,
corrupt, non-16-bit or mis-sized prediction stops the run with an error naming the file.

Columns (per image, then the mean over the images of one push index):
  push          the push index (frame number)
  images        how many images were averaged
  overlap P     matched true-positive pixels / predicted object pixels
  overlap R     matched true-positive pixels / ground-truth object pixels
  overlap F     2PR / (P + R)
  boundary P/R  the same over one-pixel object boundaries: a boundary pixel counts when it
                lies within ceil(0.003 x image diagonal) px (3 px at 640x480) of the
                matched object's boundary
  objects F>75  ground-truth objects whose matched prediction has overlap F > 75 %
Objects are matched one-to-one (Hungarian) to maximise the total overlap F (ties go to
the matching with more boundary matches). No
prediction gives P = 100, R = 0; no ground-truth object gives P = 0, R = 100; both empty
give 100.

Motion ceiling: when every DATASET/scene_* folder also has the objects' true poses,
  DATASET/scene_000/poses.json  {\"frames\": [[{\"label\": 1, \"translation_m\": [x, y, z],
                                 \"rotation_xyzw\": [qx, qy, qz, qw]}, ...], ...]}
                                frames[t] = after t pushes, world (table) frame, metres
(and is a whole scene folder: scene_camera.json, rgb/, depth/, label/; see `riseg gen
--help`), a second table scores the motion ceiling of the same frames: the best mask a
method that starts from the static segmentation and splits by motion can reach. It is the
ground truth with two touching objects (at most 2 background pixels apart along a row or
column) merged when every static segmentation of frames 0..t (the built-in segmenter's,
as `riseg run` uses) put them in one segment (the segment covering most of each object)
and every push so far moved them alike (true rigid motions within 1 mm at either
object's centre and 1.5 degrees; --ceiling-floor-mm sets another floor); merges chain
through touching neighbours, most alike first, but a group never holds two objects that
a push moved differently. Below it, per push: prediction / ceiling, the ratio of the
objects-found columns. A malformed
poses.json stops the run with an error naming it; without poses.json in every scene the
ceiling is skipped with a note on stderr.

Example:
  riseg eval --gt data/sim23 --pred out/sim23-static --json static.json";

    #[derive(Debug, Args)]
    pub(in crate::cli) struct EvalArgs {
        /// Dataset with ground truth: DATASET/scene_*/label/<frame>.png.
        #[arg(long, value_name = "DATASET")]
        gt: PathBuf,
        /// Predictions mirroring the dataset: PRED/scene_*/label/<frame>.png.
        #[arg(long, value_name = "PRED")]
        pred: PathBuf,
        /// Also write the table as JSON (percent values) to FILE, atomically:
        /// {"pushes": [ROW..]}, plus "ceiling": [ROW..] when the motion ceiling is scored.
        #[arg(long, value_name = "FILE")]
        json: Option<PathBuf>,
        /// Settings file (TOML): its [segmenter] is the static segmenter of the motion
        /// ceiling (give `riseg run` the same file). See `riseg config --help`.
        #[arg(long, value_name = "FILE")]
        config: Option<PathBuf>,
        #[command(flatten)]
        ceiling: CeilingArg,
    }

    /// The motion ceiling's noise floor, shared by `eval` and `bench`.
    #[derive(Debug, Clone, Copy, Args)]
    pub(in crate::cli) struct CeilingArg {
        /// The motion ceiling's floor: two motions whose images of either object's centre
        /// lie at most MM apart (and whose rotations differ by at most 1.5 degrees per
        /// millimetre) count as one. A lower floor is a stricter yardstick for a method
        /// that resolves finer motion differences.
        #[arg(long, value_name = "MM", default_value_t = 1.0, value_parser = crate::cli::ceiling_floor_mm)]
        ceiling_floor_mm: f32,
    }

    impl CeilingArg {
        /// The ceiling's parameters at this floor.
        pub(in crate::cli) fn params(self) -> CeilingParams {
            CeilingParams::with_floor_m(self.ceiling_floor_mm / 1000.0)
        }
    }

    pub(in crate::cli) fn command(args: &EvalArgs) -> anyhow::Result<()> {
        if let Some(path) = &args.json {
            crate::io::check_writable(path)
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
        let pairs = eval::find_frame_pairs(&args.gt, &args.pred)?;
        let poses = eval::dataset_poses(&args.gt)?;
        // The ceiling scores every ground-truth frame once more (every scene has poses).
        let ceiling_frames = match &poses {
            DatasetPoses::All(_) => pairs.len(),
            DatasetPoses::Missing(_) => 0,
        };
        // Hidden automatically when stderr is not a terminal.
        let bar = ProgressBar::new((pairs.len() + ceiling_frames) as u64).with_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} images  {per_sec}  eta {eta}")
                .context("progress bar template")?,
        );
        // The static segmenter `riseg run` uses.
        let settings = ConfigArg::from(args.config.clone()).load()?.settings();
        let mut segmenter = ClassicalSegmenter::new(settings.segmenter)?;
        let report = eval::evaluate(&pairs, || bar.inc(1)).and_then(|mut report| {
            if let DatasetPoses::All(scenes) = &poses {
                let params = args.ceiling.params();
                let rows = eval::evaluate_ceiling(scenes, &mut segmenter, &params, || bar.inc(1))?;
                report.ceiling = Some(rows);
                report.ceiling_floor_m = Some(params.trans_floor_m);
            }
            Ok(report)
        });
        bar.finish_and_clear();
        let report = report?;
        if let DatasetPoses::Missing(scene) = &poses {
            log::warn!(
                "motion ceiling not scored: {} has no {}",
                scene.display(),
                scene::POSES_FILE
            );
        }
        // The file first: a closed standard output must not lose it.
        if let Some(path) = &args.json {
            report.write_json(path)?;
            log::info!("wrote {}", path.display());
        }
        say!("{report}")
    }
}

pub(in crate::cli) use command::*;
