//! `riseg bench`: the paper's experiment (Table 1) on simulated scenes.
//!
//! # Contract
//!
//! Scene `i` of seed `S` is the simulator's scene [`scene_seed`]`(S, i)` of the configured
//! scene family ([`BenchConfig::layout`]; the next attempt seed when no placement fits, as
//! `riseg gen` does). On each scene one episode of
//! Algorithm 1 runs ([`crate::rig::episode::run_episode`]) with the built-in segmenter and flow: the loop picks
//! its own pushes, at most [`Config::max_pushes`]. Every captured frame `t` is scored
//! against the simulator's ground truth three times: the static segmentation of that frame
//! (the `static` rows), the accumulated RISeg mask (the `riseg` rows; at `t = 0` both are
//! the static segmentation), and the motion ceiling of the episode's frames `0..=t`
//! ([`crate::eval::ceiling`], [`BenchConfig::ceiling`]; the `ceiling` rows), computed from the
//! same static segmentations and the simulator's true object poses. Row `t` averages the
//! scenes that reached frame `t`; RISeg's share of the ceiling at push `t` is the ratio of
//! the two rows' objects-found percentages. Timing is the
//! median over steps of each stage (segmentation over all frames, the other stages over
//! the frames after a push), with the flow on one thread.
//!
//! Each push `t` (frame `t − 1` → `t`, chosen by FindAction) is also classed by what it
//! did to the static segmentation it started from ([`moved_part_of_a_segment`]): it
//! **moved part of a merged segment** when some segment of frame `t − 1`'s static
//! segmentation that holds at least two objects (an object belongs to the segment covering
//! most of its visible pixels in frame `t − 1`: the ceiling's [`static_segments`]) holds
//! both an object that moved (its true motion exceeds the ceiling's floors: [`moved`])
//! and an object that did not move alike with it ([`same_motion`]). Only such a push shows
//! motion anything to split: a push that moves a merged segment as one piece, or moves
//! only objects the static segmentation already separated, does not. Per push index `t`,
//! [`BenchReport::partial_push_share`] is the fraction of the pushes `t` made that did.
//!
//! Scenes run in parallel on a fixed set of worker threads ([`run_bench`]; memory and
//! threads stay flat in the number of scenes) and are merged in scene order: the tables
//! are the same for a seed whatever the thread count; only the times vary.

use core::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::{
    collections::BTreeMap,
    sync::{Mutex, PoisonError},
};

use riseg_core::{Config, Pose};
use serde::{Deserialize, Serialize};

use crate::{
    cli::config::Settings,
    cli::eval::{EvalReport, PushReport, write_ceiling_shares},
    cli::models::Models,
    eval::ceiling::{
        CeilingFrame, CeilingParams, MotionCeiling, moved, poses_by_label, same_motion,
        static_segments,
    },
    eval::metrics::{ImageMetrics, MetricsError, PushAverages, image_metrics},
    flow::{FlowError, FlowParams},
    io::scene::ObjectPose,
    rig::episode::{EpisodeError, EpisodeFrame, Stop, run_episode},
    rig::tracker::{StageTimes, TrackError},
    segment::{SegmentError, SegmenterParams},
    sim::{Layout, SimConfig, SimError, SimRig, SimScene, first_usable_seed, scene_seed},
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
    /// The motion ceiling's floors (also those of [`moved_part_of_a_segment`]).
    pub ceiling: CeilingParams,
}

impl BenchConfig {
    /// What every command runs without `--config` ([`Settings::default`]: the paper's
    /// settings, the built-in segmenter and DIS "medium"), on [`Layout::Loose`] scenes.
    #[must_use]
    pub fn new(scenes: usize, seed: u64) -> Self {
        let Settings {
            core,
            segmenter,
            flow,
        } = Settings::default();
        Self {
            scenes,
            seed,
            layout: Layout::Loose,
            core,
            segmenter,
            flow,
            ceiling: CeilingParams::DEFAULT,
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
    /// Per push made, in order (entry `t − 1` for push `t`): whether it moved part of a
    /// merged segment (module docs).
    pub partial_pushes: Vec<bool>,
    /// Stage times per frame.
    pub times: Vec<StageTimes>,
    /// Why the episode ended.
    pub stop: Stop,
}

/// Median milliseconds per step of each stage.
pub type Timing = BTreeMap<String, f64>;

/// The benchmark's result; its JSON form is `{"static": [ROW, ...], "riseg": [ROW, ...],
/// "ceiling": [ROW, ...], "ceiling_floor_m": 0.001, "partial_push_share": [null, 0.25, ...],
/// "timing_ms": {"segment": .., "flow": .., "frames": .., "twists": .., "grouping": ..,
/// "mask": ..}}` with ROW as in `riseg eval --json`.
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
    /// The translation floor the ceiling was scored at, metres
    /// ([`CeilingParams::trans_floor_m`]; reports without it were scored at the default).
    #[serde(default = "default_ceiling_floor_m")]
    pub ceiling_floor_m: f32,
    /// Per push index `t`, one entry per row: the fraction of the pushes `t` made (one per
    /// scene that reached frame `t`, the rows' `images`) that moved part of a merged
    /// segment (module docs); `None` (JSON `null`) for push 0, which no push led to.
    #[serde(default)]
    pub partial_push_share: Vec<Option<f64>>,
    /// Median time per step of each stage, milliseconds.
    pub timing_ms: Timing,
}

/// Runs one scene's episode and scores every frame.
///
/// # Errors
/// [`BenchError`] from the simulator or the loop.
pub fn run_scene(cfg: &BenchConfig, scene: usize) -> Result<SceneResult, BenchError> {
    run_scene_with(cfg, &Models::default(), scene)
}

/// [`run_scene`] with the static segmenter and flow `models` (the built-in ones take
/// their settings from `cfg`; ONNX models are loaded for the scene).
///
/// # Errors
/// [`BenchError`] from loading a model, the simulator or the loop.
pub fn run_scene_with(
    cfg: &BenchConfig,
    models: &Models,
    scene: usize,
) -> Result<SceneResult, BenchError> {
    let (sim, sim_seed) = place_scene(scene_seed(cfg.seed, scene), cfg.layout)
        .map_err(|source| BenchError::Sim { scene, source })?;
    let mut rig = SimRig::new(sim);
    let settings = Settings {
        core: cfg.core,
        segmenter: cfg.segmenter,
        flow: cfg.flow,
    };
    let mut tracker = models.tracker(&settings, Some(1))?;
    let mut static_metrics = Vec::new();
    let mut riseg_metrics = Vec::new();
    let mut ceiling_metrics = Vec::new();
    let mut ceiling = MotionCeiling::new(cfg.ceiling);
    let mut partial_pushes = Vec::new();
    // The previous frame's ground truth, static segmentation and poses.
    let mut previous: Option<PushStart> = None;
    let mut times = Vec::new();
    let summary = run_episode(
        &mut rig.camera,
        &mut rig.robot,
        &mut tracker,
        &rig.setup,
        |f: &EpisodeFrame<'_>| {
            let (s, r) = score_frame(f).map_err(|e| format!("scoring frame {}: {e}", f.t))?;
            static_metrics.push(s);
            riseg_metrics.push(r);
            ceiling_metrics.push(
                score_ceiling(&mut ceiling, f)
                    .map_err(|e| format!("motion ceiling of frame {}: {e}", f.t))?,
            );
            let start = PushStart::of(f)?;
            if let Some(before) = &previous {
                partial_pushes.push(
                    moved_part_of_a_segment(&before.frame(), &start.poses, &cfg.ceiling)
                        .map_err(|e| format!("push {}: {e}", f.t))?,
                );
            }
            previous = Some(start);
            times.push(f.observation.times);
            Ok(())
        },
    )
    .map_err(|source| BenchError::Episode { scene, source })?;
    Ok(SceneResult {
        scene,
        sim_seed,
        static_metrics,
        riseg_metrics,
        ceiling_metrics,
        partial_pushes,
        times,
        stop: summary.stop,
    })
}

/// What [`moved_part_of_a_segment`] needs of the frame a push starts from, owned.
struct PushStart {
    width: usize,
    height: usize,
    truth: Vec<u16>,
    static_labels: Vec<u16>,
    poses: Vec<ObjectPose>,
}

impl PushStart {
    fn of(f: &EpisodeFrame<'_>) -> Result<Self, String> {
        let frame = f
            .frame
            .ceiling_frame(f.observation.static_seg.labels.as_slice())
            .ok_or_else(|| {
                format!(
                    "frame {}: the camera gave no ground-truth labels or no object poses",
                    f.t
                )
            })?;
        Ok(Self {
            width: frame.width,
            height: frame.height,
            truth: frame.truth.to_vec(),
            static_labels: frame.static_labels.to_vec(),
            poses: frame.poses.to_vec(),
        })
    }

    fn frame(&self) -> CeilingFrame<'_> {
        CeilingFrame {
            width: self.width,
            height: self.height,
            truth: &self.truth,
            static_labels: &self.static_labels,
            poses: &self.poses,
        }
    }
}

/// Whether a push moved part of a merged segment (module docs): `before` is the frame the
/// push started from (its ground truth, static segmentation and true poses), `after` the
/// true poses once it was made. Objects are the labels visible in `before.truth`.
///
/// # Errors
/// When an object visible before the push has no pose, or two, before or after it.
pub fn moved_part_of_a_segment(
    before: &CeilingFrame<'_>,
    after: &[ObjectPose],
    params: &CeilingParams,
) -> Result<bool, String> {
    let segment_of = static_segments(before.truth, before.static_labels);
    let objects = || segment_of.keys().copied();
    let start = poses_by_label(before.poses, objects()).map_err(|e| format!("before: {e}"))?;
    let end = poses_by_label(after, objects()).map_err(|e| format!("after: {e}"))?;
    let mut members: BTreeMap<u16, Vec<[&Pose; 2]>> = BTreeMap::new();
    for (object, &segment) in &segment_of {
        // Segment 0: the static segmenter missed the object, which is in no segment. Both
        // poses exist: `poses_by_label` checked every visible object.
        if let (true, Some(p0), Some(p1)) = (segment != 0, start.get(object), end.get(object)) {
            members.entry(segment).or_default().push([p0, p1]);
        }
    }
    Ok(members.values().filter(|m| m.len() >= 2).any(|motions| {
        motions
            .iter()
            .any(|&a| moved(a, params) && motions.iter().any(|&b| !same_motion(a, b, params)))
    }))
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
        image_metrics(truth, obs.static_seg.labels.as_slice(), w, h)?,
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
    let frame = f
        .frame
        .ceiling_frame(f.observation.static_seg.labels.as_slice())
        .ok_or("the camera gave no ground-truth labels or no object poses")?;
    let mask = ceiling.next_frame(&frame).map_err(|e| e.to_string())?;
    image_metrics(frame.truth, &mask, frame.width, frame.height).map_err(|e| e.to_string())
}

/// The first attempt seed from `seed` ([`first_usable_seed`], as `riseg gen` derives them)
/// whose objects the simulator can place in a scene of `layout`.
fn place_scene(seed: u64, layout: Layout) -> Result<(SimScene, u64), SimError> {
    let config = SimConfig::D415.with_layout(layout);
    let placed = first_usable_seed(seed, |s| match SimScene::with_config(s, config) {
        Ok(sim) => Ok(Ok(sim)),
        Err(e @ SimError::Placement { .. }) => Ok(Err(e)),
        Err(e) => Err(e),
    })?;
    placed.map(|found| (found.value, found.seed))
}

/// Runs every scene and builds the report; `on_scene` is called as each scene finishes
/// (from worker threads).
///
/// Scenes run on as many plain worker threads as rayon's global pool has
/// ([`rayon::current_num_threads`], so `RAYON_NUM_THREADS` applies), each taking the next
/// scene when it finishes one: at most that many scenes are in memory at once, and the
/// thread count does not grow with the number of scenes. (Scenes as rayon tasks would
/// not bound this: a worker waiting for the renderer's or the flow's parallel work steals
/// further scenes and nests them on its stack.) After a scene fails, no new scene starts.
///
/// # Errors
/// The first [`BenchError`] in scene order among the scenes run.
pub fn run_bench(
    cfg: &BenchConfig,
    on_scene: impl Fn(&SceneResult) + Sync,
) -> Result<(BenchReport, Vec<SceneResult>), BenchError> {
    run_bench_with(cfg, &Models::default(), on_scene)
}

/// [`run_bench`] with the static segmenter and flow `models` ([`run_scene_with`]).
///
/// # Errors
/// The first [`BenchError`] in scene order among the scenes run.
pub fn run_bench_with(
    cfg: &BenchConfig,
    models: &Models,
    on_scene: impl Fn(&SceneResult) + Sync,
) -> Result<(BenchReport, Vec<SceneResult>), BenchError> {
    let workers = rayon::current_num_threads().clamp(1, cfg.scenes.max(1));
    let next_scene = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let slots: Mutex<Vec<Option<Result<SceneResult, BenchError>>>> =
        Mutex::new((0..cfg.scenes).map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| {
                loop {
                    let scene = next_scene.fetch_add(1, Ordering::Relaxed);
                    if scene >= cfg.scenes || failed.load(Ordering::Relaxed) {
                        break;
                    }
                    let result = run_scene_with(cfg, models, scene);
                    match &result {
                        Ok(r) => on_scene(r),
                        Err(_) => failed.store(true, Ordering::Relaxed),
                    }
                    let mut slots = slots.lock().unwrap_or_else(PoisonError::into_inner);
                    if let Some(slot) = slots.get_mut(scene) {
                        *slot = Some(result);
                    }
                }
            });
        }
    });
    let mut results = Vec::with_capacity(cfg.scenes);
    for slot in slots.into_inner().unwrap_or_else(PoisonError::into_inner) {
        match slot {
            Some(Ok(r)) => results.push(r),
            Some(Err(e)) => return Err(e),
            None => {}
        }
    }
    Ok((report(&results, &cfg.ceiling), results))
}

/// The floor of reports written before they recorded it.
fn default_ceiling_floor_m() -> f32 {
    CeilingParams::DEFAULT.trans_floor_m
}

/// Table 1 and the stage medians of finished scenes (module docs), whose ceiling was
/// scored with `ceiling`.
#[must_use]
pub fn report(results: &[SceneResult], ceiling: &CeilingParams) -> BenchReport {
    let mut static_avg = PushAverages::new();
    let mut riseg_avg = PushAverages::new();
    let mut ceiling_avg = PushAverages::new();
    // Per push index: (pushes that moved part of a merged segment, pushes).
    let mut partial: BTreeMap<usize, (usize, usize)> = BTreeMap::new();
    let mut stage: [Vec<f64>; 6] = Default::default();
    for r in results {
        for (i, &moved_part) in r.partial_pushes.iter().enumerate() {
            let (k, n) = partial.entry(i + 1).or_default();
            *k += usize::from(moved_part);
            *n += 1;
        }
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
    let riseg_rows = EvalReport::from_rows(&riseg_avg.rows()).pushes;
    let partial_push_share = riseg_rows
        .iter()
        .map(|row| {
            let &(k, n) = partial.get(&(row.push as usize))?;
            Some(k as f64 / n as f64)
        })
        .collect();
    BenchReport {
        static_rows: EvalReport::from_rows(&static_avg.rows()).pushes,
        riseg_rows,
        ceiling_rows: EvalReport::from_rows(&ceiling_avg.rows()).pushes,
        ceiling_floor_m: ceiling.trans_floor_m,
        partial_push_share,
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
    /// of the ceiling, the pushes that moved part of a merged segment, then the stage
    /// medians.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        writeln!(
            f,
            "{:>4} {:>6} | {:^26} | {:^26} | {:^26}",
            "",
            "",
            "static segmenter",
            "RISeg",
            format!("motion ceiling at {:.2} mm", self.ceiling_floor_m * 1e3)
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
        // The pushes of index t are one per scene that reached frame t: the row's images.
        for (row, share) in self.riseg_rows.iter().zip(&self.partial_push_share) {
            if let Some(share) = share {
                let n = row.images;
                writeln!(
                    f,
                    "pushes that moved part of a merged segment at push {}: {} of {n} ({:.1} %)",
                    row.push,
                    (share * n as f64).round() as usize,
                    100.0 * share
                )?;
            }
        }
        write!(f, "median ms per step:")?;
        for name in StageTimes::NAMES {
            if let Some(ms) = self.timing_ms.get(name) {
                write!(f, " {name} {ms:.1}")?;
            }
        }
        writeln!(f)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests: a panic is the failure report")]

    use super::*;
    use crate::eval::ceiling::fixture::{H, W, at, row_of_three as truth, start};

    /// The static segmentation merges 1 and 2 (segment 7) and finds 3 alone (segment 8).
    fn static_labels() -> Vec<u16> {
        truth()
            .iter()
            .map(|&l| [0, 7, 7, 8][usize::from(l)])
            .collect()
    }

    /// The poses after a push that moves each object `l` by `dx_m(l)` along x.
    fn pushed(dx_m: impl Fn(u16) -> f32) -> Vec<ObjectPose> {
        start()
            .iter()
            .map(|p| at(p.label, p.world_from_object.translation.x + dx_m(p.label)))
            .collect()
    }

    fn partial(after: &[ObjectPose]) -> Result<bool, String> {
        let (truth, static_labels, before) = (truth(), static_labels(), start());
        let frame = CeilingFrame {
            width: W,
            height: H,
            truth: &truth,
            static_labels: &static_labels,
            poses: &before,
        };
        moved_part_of_a_segment(&frame, after, &CeilingParams::DEFAULT)
    }

    #[test]
    fn a_push_moved_part_of_a_merged_segment_only_when_it_split_its_motion() {
        // One of the two merged objects moves: partial.
        assert!(partial(&pushed(|l| if l == 1 { 0.02 } else { 0.0 })).unwrap());
        // Both merged objects move, differently: partial.
        assert!(partial(&pushed(|l| [0.0, 0.02, 0.01, 0.0][usize::from(l)])).unwrap());
        // Both merged objects move alike: one piece, not partial (3 moving too or not).
        assert!(!partial(&pushed(|l| if l == 3 { 0.0 } else { 0.02 })).unwrap());
        assert!(!partial(&pushed(|l| if l == 3 { 0.01 } else { 0.02 })).unwrap());
        // The object alone in its segment moves: not partial.
        assert!(!partial(&pushed(|l| if l == 3 { 0.02 } else { 0.0 })).unwrap());
        // Nothing moves beyond the floors: not partial.
        assert!(!partial(&pushed(|l| if l == 1 { 0.0009 } else { 0.0 })).unwrap());
    }

    #[test]
    fn an_object_the_static_segmenter_missed_is_in_no_segment() {
        // Segment 0 "holds" 1 and 2 when the segmenter saw neither: never partial.
        let truth = truth();
        let missed: Vec<u16> = truth.iter().map(|&l| if l == 3 { 8 } else { 0 }).collect();
        let before = start();
        let frame = CeilingFrame {
            width: W,
            height: H,
            truth: &truth,
            static_labels: &missed,
            poses: &before,
        };
        let one_moves = pushed(|l| if l == 1 { 0.02 } else { 0.0 });
        assert!(!moved_part_of_a_segment(&frame, &one_moves, &CeilingParams::DEFAULT).unwrap());
    }

    #[test]
    fn a_visible_object_without_a_pose_is_an_error_naming_it() {
        let after = &pushed(|_| 0.0)[..2];
        assert_eq!(
            partial(after).unwrap_err(),
            "after: object 3 is in the ground truth but has no pose"
        );
    }

    #[test]
    fn the_report_counts_partial_pushes_per_push_index() {
        let frame = image_metrics(&[1], &[1], 1, 1).unwrap();
        let scene = |frames: usize, partial_pushes: Vec<bool>| SceneResult {
            scene: 0,
            sim_seed: 0,
            static_metrics: vec![frame; frames],
            riseg_metrics: vec![frame; frames],
            ceiling_metrics: vec![frame; frames],
            partial_pushes,
            times: Vec::new(),
            stop: Stop::NoAction,
        };
        let floor = CeilingParams::with_floor_m(0.0005);
        let report = report(
            &[
                scene(3, vec![true, false]),
                scene(2, vec![false]),
                scene(3, vec![true, true]),
            ],
            &floor,
        );
        assert_eq!(
            report.partial_push_share,
            [None, Some(2.0 / 3.0), Some(0.5)]
        );
        let table = report.to_string();
        assert!(
            table.contains("pushes that moved part of a merged segment at push 1: 2 of 3 (66.7 %)"),
            "{table}"
        );
        assert!(
            table.contains("pushes that moved part of a merged segment at push 2: 1 of 2 (50.0 %)"),
            "{table}"
        );
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["partial_push_share"][0], serde_json::Value::Null);
        assert_eq!(json["partial_push_share"][2], 0.5);
        // The floor the ceiling was scored at, in the table and the file.
        assert!(table.contains("motion ceiling at 0.50 mm"), "{table}");
        assert_eq!(json["ceiling_floor_m"], serde_json::json!(0.0005_f32));
        // A report from before the floor was recorded reads as the default floor.
        let mut old = json.clone();
        old.as_object_mut().unwrap().remove("ceiling_floor_m");
        let old: BenchReport = serde_json::from_value(old).unwrap();
        assert_eq!(old.ceiling_floor_m, CeilingParams::DEFAULT.trans_floor_m);
    }
}

// --- the `riseg bench` command ----------------------------------------------------

mod command {
    use std::path::PathBuf;

    use crate::cli::bench::{self, BenchConfig};
    use crate::io::{check_writable, write_atomic};
    use crate::rig::episode::Stop;
    use anyhow::Context as _;
    use clap::Args;
    use indicatif::{ProgressBar, ProgressStyle};

    use crate::cli::LayoutArg;
    use crate::cli::config::ConfigArg;
    use crate::cli::eval::CeilingArg;
    use crate::cli::models::Models;

    pub(in crate::cli) const BENCH_HELP: &str = "\
The paper's experiment (its Table 1) on simulated scenes: static segmenter, RISeg and the \
motion ceiling.

Each scene is a table with 4-6 touching objects (the scenes of `riseg gen` with the same \
seed and --layout: loose by default, packed or mixed; see `riseg gen --help`). On each, \
the loop of Algorithm 1 runs with the built-in segmenter and optical flow: FindAction \
picks a push from the static heatmap, the simulated arm makes it, UpdateMask corrects the \
mask; at most 3 pushes (core.max_pushes), fewer when no push qualifies. Every frame is scored against the \
simulator's ground truth three times: the static segmentation of that frame, RISeg's \
accumulated mask (at push 0 they are the same), and the motion ceiling.

The motion ceiling is the best mask a method that starts from the static segmentation \
and splits by motion can reach after the pushes so far: the ground truth, with two \
touching objects (at most 2 background pixels apart along a row or column) merged when \
every static segmentation so far put them in one segment (the segment covering most of \
each object) and every push so far moved them alike (their true rigid motions agree \
within 1 mm at either object's centre and 1.5 degrees; --ceiling-floor-mm sets another \
floor); merges chain through touching \
neighbours, most alike first, but a group never holds two objects that a push moved \
differently. RISeg is judged as a share of it.

Columns (percent, averaged over the scenes that reached that push): overlap F, boundary \
F, and the share of objects found with overlap F > 75 (see `riseg eval --help`). Below \
the table, per push: RISeg / ceiling, the ratio of their objects-found columns; and how \
many of the pushes made at that index moved part of a merged segment: some segment of \
the static segmentation before the push holds two or more objects (an object belongs to \
the segment covering most of it) and the push moved one of them (its true motion \
exceeds the ceiling's floors) but not another alike with it. Only such a push gives \
motion something to split; moving a merged segment as one piece, or an object the static \
segmenter already found alone, does not. Then the median milliseconds per step of each \
stage: segment (static segmentation), flow (one thread), frames, twists, grouping, mask \
(riseg-core's UpdateMask stages).

The tables are the same for a seed on any machine and thread count; times vary.

Example:
  riseg bench --scenes 23 --seed 1 --json bench-seed1.json";

    #[derive(Debug, Args)]
    pub(in crate::cli) struct BenchArgs {
        /// Number of scenes (1 to 10000).
        #[arg(long, default_value_t = 23, value_parser = crate::cli::scene_count)]
        scenes: usize,
        /// Dataset seed (scene i uses the simulator seed `riseg gen` derives from it).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Scene family (see `riseg gen --help`).
        #[arg(long, value_enum, default_value_t = LayoutArg::Loose)]
        layout: LayoutArg,
        /// Also write the report as JSON: {"static": [ROW..], "riseg": [ROW..], "ceiling":
        /// [ROW..], "partial_push_share": [..], "timing_ms": {..}}, ROW as in `riseg eval
        /// --json`; partial_push_share has one entry per row: the fraction of the pushes made
        /// at that push index (one per scene) that moved part of a merged segment (null for
        /// push 0). Written atomically.
        #[arg(long, value_name = "FILE")]
        json: Option<PathBuf>,
        /// Also print one line per scene, one entry per frame: objects found (F > 75) by the
        /// static segmentation -> by RISeg, then by the motion ceiling, and the boundary F of
        /// static -> RISeg ("3/4->4/4 ceil 4/4 b82->97", a leading "*" when the push to
        /// that frame moved part of a merged segment); and why the episode stopped.
        #[arg(long)]
        per_scene: bool,
        #[command(flatten)]
        models: Models,
        #[command(flatten)]
        config: ConfigArg,
        #[command(flatten)]
        ceiling: CeilingArg,
    }

    pub(in crate::cli) fn command(args: &BenchArgs) -> anyhow::Result<()> {
        let settings = args.config.load()?.settings();
        if let Some(path) = &args.json {
            // Before the run, not after it.
            check_writable(path).with_context(|| format!("cannot write {}", path.display()))?;
        }
        let cfg = BenchConfig {
            layout: args.layout.layout(),
            core: settings.core,
            segmenter: settings.segmenter,
            flow: settings.flow,
            ceiling: args.ceiling.params(),
            ..BenchConfig::new(args.scenes, args.seed)
        };
        let bar = ProgressBar::new(args.scenes as u64).with_style(
            ProgressStyle::with_template(
                "{bar:30} {pos}/{len} scenes  {elapsed}  eta {eta}  {msg}",
            )
            .context("progress bar template")?,
        );
        let (report, results) = bench::run_bench_with(&cfg, &args.models, |r| {
            log::info!(
                "scene {} (sim seed {}): {} pushes, {:?}",
                r.scene,
                r.sim_seed,
                r.times.len().saturating_sub(1),
                r.stop
            );
            bar.set_message(format!(
                "scene {}: {} pushes, {:?}",
                r.scene,
                r.times.len().saturating_sub(1),
                r.stop
            ));
            bar.inc(1);
        })?;
        bar.finish_and_clear();
        // The file first: a closed standard output must not lose it.
        if let Some(path) = &args.json {
            let mut json = serde_json::to_vec_pretty(&report).context("encoding the report")?;
            json.push(b'\n');
            write_atomic(path, &json).with_context(|| format!("writing {}", path.display()))?;
            log::info!("wrote {}", path.display());
        }
        let refused = results
            .iter()
            .filter(|r| matches!(r.stop, Stop::Refused(_)))
            .count();
        say!(
            "{} {} scenes, seed {}; pushes per scene: {}{}\n",
            args.scenes,
            cfg.layout,
            args.seed,
            results
                .iter()
                .map(|r| (r.times.len() - 1).to_string())
                .collect::<Vec<_>>()
                .join(" "),
            if refused > 0 {
                format!("; {refused} episodes stopped on a refused push")
            } else {
                String::new()
            }
        )?;
        if args.per_scene {
            for r in &results {
                let frames: Vec<String> = r
                    .static_metrics
                    .iter()
                    .zip(&r.riseg_metrics)
                    .zip(&r.ceiling_metrics)
                    .enumerate()
                    .map(|(t, ((s, m), c))| {
                        // Push t is entry t - 1 of the partial pushes.
                        let partial = t
                            .checked_sub(1)
                            .and_then(|i| r.partial_pushes.get(i))
                            .is_some_and(|&p| p);
                        format!(
                            "{}{}/{}->{}/{} ceil {}/{} b{:.0}->{:.0}",
                            if partial { "*" } else { "" },
                            s.objects_detected,
                            s.objects_gt,
                            m.objects_detected,
                            m.objects_gt,
                            c.objects_detected,
                            c.objects_gt,
                            100.0 * s.boundary.f_measure,
                            100.0 * m.boundary.f_measure
                        )
                    })
                    .collect();
                say!(
                    "scene {:>3} (sim seed {:>20}): {}  [{:?}]\n",
                    r.scene,
                    r.sim_seed,
                    frames.join(" | "),
                    r.stop
                )?;
            }
        }
        say!("{report}")
    }
}

pub(in crate::cli) use command::*;
