//! `riseg demo`: one simulated scene through the whole loop, with pictures and a report.
//!
//! # Contract
//!
//! [`run_demo`] builds the simulated scene of `seed` in the scene family `layout`
//! ([`default_seed`] gives each family's default scene), runs one episode of Algorithm 1 with
//! the built-in segmenter and flow ([`crate::rig::episode::run_episode`]), scores each frame against the
//! simulator's ground truth, and writes into the output folder:
//! - `frame_N.png` for each frame `N` (the scene after `N` pushes), four panels:
//!   top left the static segmentation, top right the RISeg mask with FindAction's certain
//!   cluster centres (white dots) and the push chosen on this frame (yellow arrow, from the
//!   tool's start to its end), bottom left the body frames of the step that led to this
//!   frame coloured by twist group (grey: frames in no group or in a static group),
//!   bottom right the optical flow from the previous frame on the Middlebury colour wheel;
//! - `report.md`: the per-push table, the pictures, and where the scene stands among the
//!   23 scenes of its family in `riseg bench` (objects found: lowest, median, highest).
//!
//! Files are written atomically; the folder is created if missing and files of an earlier
//! demo in it are replaced.

use core::fmt::Write as _;
use std::path::Path;

use riseg_core::{Intrinsics, action::Push};

use crate::{
    cli::bench::{BenchConfig, SceneResult, run_bench_with, score_frame},
    cli::config::Settings,
    cli::eval::PushReport,
    cli::models::Models,
    draw::{Clip, PUSH_COLOUR, arrow, body_frame_colour, dot, line, overlay_labels},
    eval::metrics::PushAverages,
    flow::viz::flow_to_rgb,
    io::{
        image::{RgbImage, write_rgb8},
        write_atomic,
    },
    rig::episode::{Decision, EpisodeFrame, Stop, run_episode},
    rig::robot::PushCommand,
    rig::tracker::Observation,
    sim::{Layout, SimConfig, SimRig, SimScene},
};

/// The default loose demo scene: six objects; the static segmenter merges two pairs of
/// them, and after three pushes RISeg has every object while the static segmenter still
/// merges two.
pub const DEMO_SEED: u64 = 2;
/// The default packed demo scene (the default demo): five look-alike boxes flush in a 2x3
/// grid less one, which the static segmenter merges into one segment. Picked as a typical
/// packed scene (in most, nothing is found at push 0), not a favourable one.
pub const PACKED_DEMO_SEED: u64 = 0;
/// The default mixed demo scene: three look-alike boxes in an L with two balls against
/// them; the static segmenter finds the balls and merges the boxes, as in a typical mixed
/// scene.
pub const MIXED_DEMO_SEED: u64 = 0;

/// The default demo scene of a family: [`DEMO_SEED`], [`PACKED_DEMO_SEED`] or
/// [`MIXED_DEMO_SEED`].
#[must_use]
pub const fn default_seed(layout: Layout) -> u64 {
    match layout {
        Layout::Loose => DEMO_SEED,
        Layout::Packed => PACKED_DEMO_SEED,
        Layout::Mixed => MIXED_DEMO_SEED,
    }
}

/// What the demo measured on one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct DemoFrame {
    /// Frame index (pushes made before it).
    pub t: usize,
    /// The static segmentation's scores.
    pub static_row: PushReport,
    /// RISeg's scores.
    pub riseg_row: PushReport,
    /// The picture's file name inside the output folder.
    pub picture: String,
    /// The push made after this frame, robot frame, if any.
    pub push: Option<PushCommand>,
}

/// The demo's result.
#[derive(Debug, Clone, PartialEq)]
pub struct DemoReport {
    /// The simulator seed.
    pub seed: u64,
    /// The scene family.
    pub layout: Layout,
    /// One entry per frame.
    pub frames: Vec<DemoFrame>,
    /// Why the loop stopped.
    pub stop: Stop,
}

/// Runs the demo (module docs); `on_frame` sees each frame as it is done, and an error it
/// returns ends the demo.
///
/// # Errors
/// Any failure of the simulator, the loop, writing a file or `on_frame`, with what failed.
pub fn run_demo(
    out: &Path,
    seed: u64,
    layout: Layout,
    settings: &Settings,
    models: &Models,
    mut on_frame: impl FnMut(&EpisodeFrame<'_>) -> anyhow::Result<()>,
) -> anyhow::Result<DemoReport> {
    use anyhow::Context as _;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let sim = SimScene::with_config(seed, SimConfig::D415.with_layout(layout))
        .with_context(|| format!("building simulated {layout} scene {seed}"))?;
    let mut rig = SimRig::new(sim);
    let mut tracker = models.tracker(settings, None)?;
    let mut frames = Vec::new();
    let summary = run_episode(
        &mut rig.camera,
        &mut rig.robot,
        &mut tracker,
        &rig.setup,
        |f: &EpisodeFrame<'_>| {
            let done = demo_frame(out, f).map_err(|e| format!("{e:#}"))?;
            frames.push(done);
            on_frame(f).map_err(|e| format!("{e:#}"))
        },
    )?;
    let report = DemoReport {
        seed,
        layout,
        frames,
        stop: summary.stop,
    };
    let mut md = markdown(&report);
    md.push('\n');
    md.push_str(&bench_spread(&report, settings, models)?);
    let path = out.join("report.md");
    write_atomic(&path, md.as_bytes()).with_context(|| format!("writing {}", path.display()))?;
    remove_stale_frames(out, report.frames.len())?;
    Ok(report)
}

fn demo_frame(out: &Path, f: &EpisodeFrame<'_>) -> anyhow::Result<DemoFrame> {
    let (s, r) = score_frame(f)?;
    let row = |m| {
        let mut avg = PushAverages::new();
        avg.add(f.t as u32, m);
        avg.rows().first().map(PushReport::from)
    };
    let (Some(static_row), Some(riseg_row)) = (row(&s), row(&r)) else {
        anyhow::bail!("no metrics for frame {}", f.t);
    };
    let picture = format!("frame_{}.png", f.t);
    write_rgb8(&out.join(&picture), &panels(f))?;
    Ok(DemoFrame {
        t: f.t,
        static_row,
        riseg_row,
        picture,
        push: match f.decision {
            Decision::Push { command, .. } => Some(command),
            Decision::Stop(_) => None,
        },
    })
}

/// Removes the `frame_N.png` pictures with `N >= frames` that an earlier, longer demo run
/// left in `out`, so the folder shows this run only. Other files are not touched.
fn remove_stale_frames(out: &Path, frames: usize) -> anyhow::Result<()> {
    use anyhow::Context as _;
    let stale = |name: &str| {
        name.strip_prefix("frame_")
            .and_then(|n| n.strip_suffix(".png"))
            .filter(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
            .and_then(|n| n.parse::<usize>().ok())
            .is_some_and(|n| n >= frames)
    };
    let listing = std::fs::read_dir(out).with_context(|| format!("listing {}", out.display()))?;
    for entry in listing {
        let path = entry
            .with_context(|| format!("listing {}", out.display()))?
            .path();
        if path.file_name().and_then(|n| n.to_str()).is_some_and(stale) {
            std::fs::remove_file(&path)
                .with_context(|| format!("removing the stale {}", path.display()))?;
        }
    }
    Ok(())
}

const WHITE: [u8; 3] = [255, 255, 255];

/// The four-panel picture of one frame (module docs).
#[must_use]
pub fn panels(f: &EpisodeFrame<'_>) -> RgbImage {
    let (w, h) = f.frame.size();
    let obs: &Observation = f.observation;
    let static_panel = overlay_labels(&f.frame.rgb, obs.static_seg.labels.as_slice());
    let mut riseg_panel = overlay_labels(&f.frame.rgb, &obs.mask);
    let clip = Clip::all(&riseg_panel);
    for c in f.action.certain() {
        dot(&mut riseg_panel, clip, c.centre_px, WHITE, 2);
    }
    if let Decision::Push { push, command } = f.decision {
        draw_push(&mut riseg_panel, &f.frame.intrinsics, &push, &command);
    }
    let dim = f.frame.rgb.map(|c| c.map(|v| v / 3));
    let mut frames_panel = dim.clone();
    let mut flow_panel = dim;
    if let Some(step) = &obs.step {
        let clip = Clip::all(&frames_panel);
        for g in &step.frames {
            let colour = body_frame_colour(g.group, g.moving);
            let px = g.frame.px_t1;
            line(&mut frames_panel, clip, px[0], px[1], colour, 1);
            line(&mut frames_panel, clip, px[0], px[2], colour, 1);
            dot(&mut frames_panel, clip, px[0], colour, 1);
        }
        flow_panel = flow_to_rgb(&step.flow, None);
    }
    RgbImage::from_fn(2 * w, 2 * h, |x, y| {
        let (col, row) = (x / w, y / h);
        let (lx, ly) = (x % w, y % h);
        let tile = match (col, row) {
            (0, 0) => &static_panel,
            (1, 0) => &riseg_panel,
            (0, _) => &frames_panel,
            _ => &flow_panel,
        };
        tile.get(lx, ly).copied().unwrap_or_default()
    })
}

/// Draws the tool's path, projected through the camera: from the object's edge (the push's
/// start) backed off by the approach (the command's length beyond FindAction's), along the
/// push direction, to the end of the push; a dot at the start if it does not project.
fn draw_push(img: &mut RgbImage, intrinsics: &Intrinsics, push: &Push, command: &PushCommand) {
    let clip = Clip::all(img);
    let approach_m = command.length_m - push.length_m;
    let from = push.start_cam_m - push.direction_cam * approach_m;
    let to = push.start_cam_m + push.direction_cam * push.length_m;
    match (intrinsics.project(&from), intrinsics.project(&to)) {
        (Some(a), Some(b)) => arrow(img, clip, [a.x, a.y], [b.x, b.y], PUSH_COLOUR, 3),
        _ => dot(img, clip, push.start_px, PUSH_COLOUR, 3),
    }
}

/// The report's markdown (module docs).
#[must_use]
pub fn markdown(report: &DemoReport) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# riseg demo: simulated {} scene {}\n",
        report.layout, report.seed
    );
    let _ = writeln!(
        md,
        "The loop of Algorithm 1 on one simulated table ({}; D415-like RGB-D camera), with \
         the built-in static segmenter and optical flow. Frame N is the scene after N \
         pushes. Scores are percent against the simulator's ground truth.\n",
        family_text(report.layout)
    );
    md.push_str(&table(report));
    let _ = writeln!(md, "\nThe loop stopped: {}.\n", stop_text(&report.stop));
    let _ = writeln!(
        md,
        "Each picture: top left the static segmentation; top right RISeg's mask with the \
         certain cluster centres (white) and the push chosen on this frame (yellow arrow, \
         the tool's path); bottom left the body frames of the last step coloured by twist \
         group (grey: static or ungrouped); bottom right the optical flow from the previous \
         frame (hue = direction, saturation = length). Frame 0 has no step yet, so its \
         bottom panels show only the dimmed colour image.\n"
    );
    for f in &report.frames {
        let _ = writeln!(md, "## Frame {}\n", f.t);
        if let Some(p) = &f.push {
            let s = p.start_robot_m;
            let d = p.direction_robot;
            let _ = writeln!(
                md,
                "Push sent: start ({:.3}, {:.3}, {:.3}) m, direction ({:.2}, {:.2}, {:.2}), \
                 {:.3} m (robot frame).\n",
                s.x, s.y, s.z, d.x, d.y, d.z, p.length_m
            );
        }
        let _ = writeln!(md, "![frame {}]({})\n", f.t, f.picture);
    }
    md
}

/// Scenes of the family the demo's report compares its scene with (`riseg bench
/// --layout L --scenes 23 --seed 1`).
pub const SPREAD_SCENES: usize = 23;

/// How the demo's scene compares with the bench over [`SPREAD_SCENES`] scenes of its
/// family (seed 1), as a markdown section: for the static segmentation at push 0 and
/// for RISeg and the motion ceiling after the last push of each scene, the lowest,
/// median and highest share of objects found (overlap F > 75) over the scenes.
///
/// # Errors
/// The bench's errors.
pub fn bench_spread(
    report: &DemoReport,
    settings: &Settings,
    models: &Models,
) -> anyhow::Result<String> {
    let cfg = BenchConfig {
        layout: report.layout,
        core: settings.core,
        segmenter: settings.segmenter,
        flow: settings.flow,
        ..BenchConfig::new(SPREAD_SCENES, 1)
    };
    let (_, scenes) = run_bench_with(&cfg, models, |_| {})?;
    let found = |m: Option<&crate::eval::metrics::ImageMetrics>| {
        m.map_or(0.0, |m| 100.0 * m.objects_detected_share)
    };
    let column = |pick: &dyn Fn(&SceneResult) -> f64| {
        let mut v: Vec<f64> = scenes.iter().map(pick).collect();
        v.sort_by(f64::total_cmp);
        let at = |q: f64| {
            v.get(((v.len().max(1) - 1) as f64 * q).round() as usize)
                .copied()
        };
        (at(0.0), at(0.5), at(1.0))
    };
    let rows = [
        (
            "static, push 0",
            column(&|r: &SceneResult| found(r.static_metrics.first())),
        ),
        (
            "RISeg, last push",
            column(&|r: &SceneResult| found(r.riseg_metrics.last())),
        ),
        (
            "ceiling, last push",
            column(&|r: &SceneResult| found(r.ceiling_metrics.last())),
        ),
    ];
    let this = |pick: fn(&DemoFrame) -> f64| report.frames.last().map_or(0.0, pick);
    let mine = [
        report
            .frames
            .first()
            .map_or(0.0, |f| f.static_row.objects_f75_pct),
        this(|f| f.riseg_row.objects_f75_pct),
    ];
    let mut md = String::new();
    let _ = writeln!(
        md,
        "## This scene among {SPREAD_SCENES} {} scenes\n\nObjects found (overlap F > 75, \
         percent) over the scenes of `riseg bench --layout {} --scenes {SPREAD_SCENES} \
         --seed 1`, each after its own last push (the ceiling of this scene is not \
         computed: -):\n",
        report.layout, report.layout
    );
    let _ = writeln!(md, "| | lowest | median | highest | this scene |");
    let _ = writeln!(md, "|---|---:|---:|---:|---:|");
    for (i, (name, (lo, mid, hi))) in rows.iter().enumerate() {
        let fmt = |v: Option<f64>| v.map_or_else(|| "-".into(), |v| format!("{v:.0}"));
        let this_scene = mine
            .get(i)
            .map_or_else(|| "-".into(), |v| format!("{v:.0}"));
        let _ = writeln!(
            md,
            "| {name} | {} | {} | {} | {this_scene} |",
            fmt(*lo),
            fmt(*mid),
            fmt(*hi)
        );
    }
    Ok(md)
}

/// What a scene of `layout` holds, for people.
#[must_use]
pub const fn family_text(layout: Layout) -> &'static str {
    match layout {
        Layout::Loose => "4-6 touching objects of mixed shapes",
        Layout::Packed => {
            "4-6 look-alike boxes or cans packed flush: one size, height and texture, \
             sub-millimetre gaps"
        }
        Layout::Mixed => "a flush pack of 2-4 look-alike boxes with 1-3 loose objects",
    }
}

/// The per-push table (markdown, also readable on a terminal).
#[must_use]
pub fn table(report: &DemoReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| push | static overlap F | static boundary F | static objects F>75 | RISeg overlap F | RISeg boundary F | RISeg objects F>75 |"
    );
    let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|---:|");
    for f in &report.frames {
        let (a, b) = (&f.static_row, &f.riseg_row);
        let _ = writeln!(
            s,
            "| {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
            f.t,
            a.overlap.f,
            a.boundary.f,
            a.objects_f75_pct,
            b.overlap.f,
            b.boundary.f,
            b.objects_f75_pct
        );
    }
    s
}

/// Why the loop stopped, in words.
#[must_use]
pub fn stop_text(stop: &Stop) -> String {
    match stop {
        Stop::NoAction => {
            "FindAction found no pair of certain regions with an uncertain one between them".into()
        }
        Stop::PushBudget => "the push budget was spent".into(),
        Stop::Refused(why) => format!("the planned push was refused: {why}"),
    }
}

// --- the `riseg demo` command ----------------------------------------------------

mod command {
    use std::path::PathBuf;

    use anyhow::Context as _;
    use clap::Args;
    use indicatif::{ProgressBar, ProgressStyle};

    use crate::cli::LayoutArg;
    use crate::cli::config::ConfigArg;
    use crate::cli::models::Models;
    use crate::cli::record::{PushArrow, Recording};
    use crate::rig::episode::Decision;

    pub(in crate::cli) const DEMO_HELP: &str = "\
Run the whole loop on a simulated scene and write a report (the default command).

A simulated table with touching objects (by default a packed scene of look-alike boxes or \
cans, --layout; see `riseg gen --help`) is seen by a D415-like RGB-D camera; the built-in \
static segmenter merges some of them. The loop of Algorithm 1 then runs: FindAction picks \
a push between two certain regions with an uncertain one between them, the simulated arm \
makes it (the pixel push becomes a metric push in the camera frame, then a level push in \
the robot frame through the hand-eye transform, checked against the arm's limits), the \
flow and the body frames' twists show what moved differently, and UpdateMask corrects the \
mask. At most 3 pushes.

Prints a table per push (static segmenter vs RISeg: overlap F, boundary F, objects found \
with F > 75, percent against the simulator's ground truth) and writes to --out:
  frame_N.png   the scene after N pushes: static mask | RISeg mask and the next push,
                body frames by twist group | optical flow colour wheel
  report.md     the table and the pictures

Example: riseg demo --seed 3 --out /tmp/riseg-demo";

    #[derive(Debug, Args)]
    pub(in crate::cli) struct DemoArgs {
        /// Scene family (see `riseg gen --help`).
        #[arg(long, value_enum, default_value_t = LayoutArg::Packed)]
        layout: LayoutArg,
        /// Simulated scene seed [default: a typical scene of the family: 2 loose, 0 packed, 0
        /// mixed].
        #[arg(long)]
        seed: Option<u64>,
        /// Output folder (created if missing; earlier demo files in it are replaced).
        #[arg(long, default_value = "riseg-demo")]
        out: PathBuf,
        /// Also record every frame to FILE (a rerun .rrd: images, masks, body frames,
        /// pushes, flow, stage timings on the `push` timeline); needs riseg built with
        /// `--features rerun`.
        #[arg(long, value_name = "FILE.rrd")]
        rerun: Option<PathBuf>,
        #[command(flatten)]
        models: Models,
        #[command(flatten)]
        config: ConfigArg,
    }

    impl Default for DemoArgs {
        fn default() -> Self {
            Self {
                layout: LayoutArg::Packed,
                seed: None,
                out: PathBuf::from("riseg-demo"),
                models: Models::default(),
                rerun: None,
                config: ConfigArg::default(),
            }
        }
    }

    pub(in crate::cli) fn command(args: &DemoArgs) -> anyhow::Result<()> {
        let settings = args.config.load()?.settings();
        let bar = ProgressBar::new(4).with_style(
            ProgressStyle::with_template("{spinner} {msg} {elapsed}")
                .context("progress bar template")?,
        );
        bar.enable_steady_tick(core::time::Duration::from_millis(120));
        bar.set_message("frame 0: rendering, segmenting");
        let layout = args.layout.layout();
        let seed = args
            .seed
            .unwrap_or_else(|| crate::cli::demo::default_seed(layout));
        let recording = args.rerun.as_deref().map(Recording::create).transpose()?;
        let report =
            crate::cli::demo::run_demo(&args.out, seed, layout, &settings, &args.models, |f| {
                bar.set_message(format!(
                    "frame {} done; pushing, rendering frame {}",
                    f.t,
                    f.t + 1
                ));
                let Some(recording) = &recording else {
                    return Ok(());
                };
                let push = match &f.decision {
                    Decision::Push { push, .. } => Some(PushArrow::from_push(push)),
                    Decision::Stop(_) => None,
                };
                recording.frame("demo", f.t, f.frame, f.observation, push.as_ref())
            })
            .with_context(|| format!("demo on simulated {layout} scene {seed}"))?;
        recording.map(Recording::finish).transpose()?;
        bar.finish_and_clear();
        say!(
            "riseg demo: simulated {layout} scene {}, {} pushes; {}.\n",
            report.seed,
            report.frames.len().saturating_sub(1),
            crate::cli::demo::stop_text(&report.stop)
        )?;
        say!("{}", crate::cli::demo::table(&report))?;
        say!(
            "pictures and report: {}\n",
            args.out.join("report.md").display()
        )?;
        Ok(())
    }
}

pub(in crate::cli) use command::*;
