//! `riseg bench`: the paper's experiment (Table 1) on simulated scenes.
//!
//! # Contract
//!
//! Scene `i` of seed `S` is the simulator's scene [`scene_seed`]`(S, i)` of the configured
//! scene family ([`BenchConfig::layout`]; the next attempt seed when no placement fits, as
//! `riseg gen` does). On each scene one episode of
//! Algorithm 1 runs ([`crate::episode::run_episode`]) with the built-in segmenter and flow: the loop picks
//! its own pushes, at most [`Config::max_pushes`]. Every captured frame `t` is scored
//! against the simulator's ground truth three times: the static segmentation of that frame
//! (the `static` rows), the accumulated RISeg mask (the `riseg` rows; at `t = 0` both are
//! the static segmentation), and the motion ceiling of the episode's frames `0..=t`
//! ([`crate::ceiling`], [`CeilingParams::DEFAULT`]; the `ceiling` rows), computed from the
//! same static segmentations and the simulator's true object poses. Row `t` averages the
//! scenes that reached frame `t`; RISeg's share of the ceiling at push `t` is the ratio of
//! the two rows' objects-found percentages. Timing is the
//! median over steps of each stage (segmentation over all frames, the other stages over
//! the frames after a push), with the flow on one thread.
//!
//! Scenes run in parallel (rayon) and are merged in scene order: the tables are the same
//! for a seed whatever the thread count; only the times vary.

use std::collections::BTreeMap;

use rayon::prelude::*;
use riseg_core::Config;
use serde::{Deserialize, Serialize};

use crate::{
    ceiling::{CeilingFrame, CeilingParams, MotionCeiling},
    episode::{EpisodeError, EpisodeFrame, Stop},
    eval::{EvalReport, PushReport, write_ceiling_shares},
    flow::{DisFlow, FlowError, FlowParams},
    generate::{MAX_ATTEMPTS, scene_seed},
    metrics::{ImageMetrics, MetricsError, PushAverages, image_metrics},
    segment::{ClassicalSegmenter, SegmentError, SegmenterParams},
    sim::{Layout, SimConfig, SimError, SimRig, SimScene},
    tracker::{StageTimes, TrackError, Tracker},
};

/// Why a benchmark failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BenchError {
    /// The simulator failed, or no attempt placed the objects.
    #[error("scene {scene}: simulator: {source}")]
    Sim {
        /// Scene index.
        scene: usize,
        /// The cause.
        source: SimError,
    },
    /// The loop failed.
    #[error("scene {scene}: {source}")]
    Episode {
        /// Scene index.
        scene: usize,
        /// The cause.
        source: EpisodeError,
    },
    /// The segmenter or flow could not be built.
    #[error("setting up: {0}")]
    Setup(String),
}

impl From<SegmentError> for BenchError {
    fn from(e: SegmentError) -> Self {
        Self::Setup(e.to_string())
    }
}

impl From<FlowError> for BenchError {
    fn from(e: FlowError) -> Self {
        Self::Setup(e.to_string())
    }
}

impl From<TrackError> for BenchError {
    fn from(e: TrackError) -> Self {
        Self::Setup(e.to_string())
    }
}

/// What to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BenchConfig {
    /// Number of scenes.
    pub scenes: usize,
    /// Dataset seed.
    pub seed: u64,
    /// Scene family.
    pub layout: Layout,
    /// riseg-core settings.
    pub core: Config,
    /// Static segmenter settings.
    pub segmenter: SegmenterParams,
    /// Optical flow preset.
    pub flow: FlowParams,
}

impl BenchConfig {
    /// The paper's settings, the built-in segmenter and DIS "medium", on
    /// [`Layout::Loose`] scenes.
    #[must_use]
    pub fn new(scenes: usize, seed: u64) -> Self {
        Self {
            scenes,
            seed,
            layout: Layout::Loose,
            core: Config::PAPER,
            segmenter: SegmenterParams::default(),
            flow: FlowParams::MEDIUM,
        }
    }
}

/// One scene's episode, scored.
#[derive(Debug, Clone)]
pub struct SceneResult {
    /// Scene index.
    pub scene: usize,
    /// The simulator seed used.
    pub sim_seed: u64,
    /// Static segmentation metrics per frame.
    pub static_metrics: Vec<ImageMetrics>,
    /// RISeg mask metrics per frame.
    pub riseg_metrics: Vec<ImageMetrics>,
    /// Motion ceiling metrics per frame.
    pub ceiling_metrics: Vec<ImageMetrics>,
    /// Stage times per frame.
    pub times: Vec<StageTimes>,
    /// Why the episode ended.
    pub stop: Stop,
}

/// Median milliseconds per step of each stage.
pub type Timing = BTreeMap<String, f64>;

/// The benchmark's result; its JSON form is `{"static": [ROW, ...], "riseg": [ROW, ...],
/// "ceiling": [ROW, ...], "timing_ms": {"segment": .., "flow": .., "frames": .., "twists":
/// .., "grouping": .., "mask": ..}}` with ROW as in `riseg eval --json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BenchReport {
    /// The static segmenter alone, per push.
    #[serde(rename = "static")]
    pub static_rows: Vec<PushReport>,
    /// RISeg's accumulated mask, per push.
    #[serde(rename = "riseg")]
    pub riseg_rows: Vec<PushReport>,
    /// The motion ceiling, per push.
    #[serde(rename = "ceiling")]
    pub ceiling_rows: Vec<PushReport>,
    /// Median time per step of each stage, milliseconds.
    pub timing_ms: Timing,
}

/// Runs one scene's episode and scores every frame.
///
/// # Errors
/// [`BenchError`] from the simulator or the loop.
pub fn run_scene(cfg: &BenchConfig, scene: usize) -> Result<SceneResult, BenchError> {
    let (sim, sim_seed) = place_scene(scene_seed(cfg.seed, scene), cfg.layout)
        .map_err(|source| BenchError::Sim { scene, source })?;
    let mut rig = SimRig::new(sim);
    let mut tracker = Tracker::new(
        ClassicalSegmenter::new(cfg.segmenter)?,
        DisFlow::new(cfg.flow)?.with_threads(1)?,
        cfg.core,
    )?;
    let mut static_metrics = Vec::new();
    let mut riseg_metrics = Vec::new();
    let mut ceiling_metrics = Vec::new();
    let mut ceiling = MotionCeiling::new(CeilingParams::DEFAULT);
    let mut times = Vec::new();
    let summary = rig
        .run(&mut tracker, |f: &EpisodeFrame<'_>| {
            let (s, r) = score_frame(f).map_err(|e| format!("scoring frame {}: {e}", f.t))?;
            static_metrics.push(s);
            riseg_metrics.push(r);
            ceiling_metrics.push(
                score_ceiling(&mut ceiling, f)
                    .map_err(|e| format!("motion ceiling of frame {}: {e}", f.t))?,
            );
            times.push(f.observation.times);
            Ok(())
        })
        .map_err(|source| BenchError::Episode { scene, source })?;
    Ok(SceneResult {
        scene,
        sim_seed,
        static_metrics,
        riseg_metrics,
        ceiling_metrics,
        times,
        stop: summary.stop,
    })
}

/// Metrics of the static segmentation and of the accumulated mask of one frame.
///
/// # Errors
/// [`MetricsError`] when the frame has no ground truth (reported as a size mismatch) or
/// too many objects.
pub fn score_frame(f: &EpisodeFrame<'_>) -> Result<(ImageMetrics, ImageMetrics), MetricsError> {
    let (w, h) = f.frame.size();
    let empty: &[u16] = &[];
    let truth = f.frame.truth.as_ref().map_or(empty, |t| t.as_slice());
    let obs = f.observation;
    Ok((
        image_metrics(truth, &obs.static_seg.labels, w, h)?,
        image_metrics(truth, &obs.mask, w, h)?,
    ))
}

/// The motion ceiling's mask of the frame (fed to `ceiling`, which holds the episode's
/// earlier frames) and its metrics.
///
/// # Errors
/// When the frame has no ground-truth labels or poses, or the ceiling or the metrics
/// refuse it.
fn score_ceiling(
    ceiling: &mut MotionCeiling,
    f: &EpisodeFrame<'_>,
) -> Result<ImageMetrics, String> {
    let (width, height) = f.frame.size();
    let (Some(truth), Some(poses)) = (&f.frame.truth, &f.frame.truth_poses) else {
        return Err("the camera gave no ground-truth labels or no object poses".into());
    };
    let mask = ceiling
        .next_frame(&CeilingFrame {
            width,
            height,
            truth: truth.as_slice(),
            static_labels: &f.observation.static_seg.labels,
            poses,
        })
        .map_err(|e| e.to_string())?;
    image_metrics(truth.as_slice(), &mask, width, height).map_err(|e| e.to_string())
}

/// The first attempt seed from `seed` (as `riseg gen` derives them) whose objects the
/// simulator can place in a scene of `layout`.
fn place_scene(seed: u64, layout: Layout) -> Result<(SimScene, u64), SimError> {
    let config = SimConfig::D415.with_layout(layout);
    let mut last = None;
    for attempt in 0..MAX_ATTEMPTS {
        let attempt_seed = if attempt == 0 {
            seed
        } else {
            scene_seed(seed, attempt as usize)
        };
        match SimScene::with_config(attempt_seed, config) {
            Ok(sim) => return Ok((sim, attempt_seed)),
            Err(e @ SimError::Placement { .. }) => last = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last.unwrap_or(SimError::BadPush("no attempt was made".into())))
}

/// Runs every scene (in parallel) and builds the report; `on_scene` is called as each
/// scene finishes (from worker threads).
///
/// # Errors
/// The first [`BenchError`] in scene order.
pub fn run_bench(
    cfg: &BenchConfig,
    on_scene: impl Fn(&SceneResult) + Sync,
) -> Result<(BenchReport, Vec<SceneResult>), BenchError> {
    let results: Vec<SceneResult> = (0..cfg.scenes)
        .into_par_iter()
        .map(|i| {
            let r = run_scene(cfg, i)?;
            on_scene(&r);
            Ok(r)
        })
        .collect::<Result<_, BenchError>>()?;
    Ok((report(&results), results))
}

/// Table 1 and the stage medians of finished scenes (module docs).
#[must_use]
pub fn report(results: &[SceneResult]) -> BenchReport {
    let mut static_avg = PushAverages::new();
    let mut riseg_avg = PushAverages::new();
    let mut ceiling_avg = PushAverages::new();
    let mut stage: [Vec<f64>; 6] = Default::default();
    for r in results {
        let frames = r
            .static_metrics
            .iter()
            .zip(&r.riseg_metrics)
            .zip(&r.ceiling_metrics);
        for (t, ((s, m), c)) in frames.enumerate() {
            static_avg.add(t as u32, s);
            riseg_avg.add(t as u32, m);
            ceiling_avg.add(t as u32, c);
        }
        for (t, times) in r.times.iter().enumerate() {
            for (k, (all, v)) in stage.iter_mut().zip(times.values()).enumerate() {
                // Segmentation runs on every frame; the other stages from frame 1 on.
                if k == 0 || t > 0 {
                    all.push(v);
                }
            }
        }
    }
    let timing_ms = StageTimes::NAMES
        .iter()
        .zip(stage.iter_mut())
        .map(|(name, v)| ((*name).to_owned(), median(v)))
        .collect();
    BenchReport {
        static_rows: EvalReport::from_rows(&static_avg.rows()).pushes,
        riseg_rows: EvalReport::from_rows(&riseg_avg.rows()).pushes,
        ceiling_rows: EvalReport::from_rows(&ceiling_avg.rows()).pushes,
        timing_ms,
    }
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let mid = v.len() / 2;
    if v.len() % 2 == 1 {
        v[mid]
    } else {
        0.5 * (v[mid - 1] + v[mid])
    }
}

impl core::fmt::Display for BenchReport {
    /// Table 1: static, RISeg and motion ceiling rows side by side per push, RISeg's share
    /// of the ceiling, then the stage medians.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        writeln!(
            f,
            "{:>4} {:>6} | {:^26} | {:^26} | {:^26}",
            "", "", "static segmenter", "RISeg", "motion ceiling"
        )?;
        write!(f, "{:>4} {:>6}", "push", "scenes")?;
        for _ in 0..3 {
            write!(f, " | {:>8}{:>9}{:>9}", "overlap", "boundary", "obj>75")?;
        }
        writeln!(f)?;
        let rows = self
            .static_rows
            .iter()
            .zip(&self.riseg_rows)
            .zip(&self.ceiling_rows);
        for ((s, r), c) in rows {
            write!(f, "{:>4} {:>6}", s.push, s.images)?;
            for row in [s, r, c] {
                write!(
                    f,
                    " | {:>8.1}{:>9.1}{:>9.1}",
                    row.overlap.f, row.boundary.f, row.objects_f75_pct
                )?;
            }
            writeln!(f)?;
        }
        write_ceiling_shares(f, "RISeg", &self.riseg_rows, &self.ceiling_rows)?;
        write!(f, "median ms per step:")?;
        for name in StageTimes::NAMES {
            if let Some(ms) = self.timing_ms.get(name) {
                write!(f, " {name} {ms:.1}")?;
            }
        }
        writeln!(f)
    }
}
