//! Times the parts of one push cycle for `bench/speed.sh`: medians over `--runs` runs after
//! one warm-up, milliseconds, one process. Prints tab-separated rows
//! `table <TAB> case <TAB> column <TAB> value` for the script to lay out.
//!
//! ```sh
//! # The push cycle on the first push of every scene of `riseg gen` datasets:
//! cargo run --release --example speed -- cycle /tmp/packed /tmp/loose --runs 15
//! # How UpdateMask's stages grow with the image and the number of frames:
//! cargo run --release --example speed -- scaling --runs 15
//! # A one-shot `riseg flow` process against the warm estimate on one pair:
//! cargo run --release --example speed -- oneshot target/release/riseg a.png b.png \
//!     --out /tmp/f.flo --runs 15
//! ```
//!
//! `cycle`: per dataset (its folder name is the case), the median over scenes of each
//! part's median time: the static segmenter on frame 1 and the built-in flow (MEDIUM, the
//! loop's preset) from frame 0 to 1, each on a rayon pool of 1 and of 2 threads; UpdateMask
//! (frames, twists, grouping, mask) with the dataset's exact flow, the static segmentation
//! of frame 0 as the accumulated mask; FindAction on frame 1. `cycle_1t` is the sum of
//! segment, flow, UpdateMask and FindAction on one thread, `cycle_2t` the same with
//! segment and flow on two. UpdateMask and FindAction are single-threaded by design (riseg-core).
//!
//! `scaling`: UpdateMask stage by stage on [`SyntheticStep`] (touching boxes) at 320x240,
//! 640x480 and 1280x720 with 250, 1000 and 4000 frame samples, one thread, and the bytes
//! of riseg-core's workspace from [`WorkspaceLen::bytes`].
//!
//! `oneshot`: per thread count (1 and 2), the wall time of a whole `riseg flow FIRST SECOND
//! -o OUT --threads N` process (spawn to exit, as a shell sees it) against the warm estimate
//! on the same pair with the same thread count in this process: the built-in flow MEDIUM
//! (`riseg flow`'s default preset) on an estimator that has run once, luma conversion
//! included, as the CLI runs it; the images are read as the CLI reads them. The two are
//! timed alternately, one of each per run, so that load on the machine shifts both alike;
//! the medians are reported. Each run times the process twice: writing over the flow the
//! last run left at OUT (`process`: the rename deletes the old file, whose blocks ext4
//! allocated at that run's own rename over a file; on a file system mounted with `discard`
//! freeing them waits for a TRIM, ~2.3 ms here) and writing OUT's sibling `*.new.flo`,
//! removed before the run outside the timing (`process_new`, the figure `bench/speed.sh`
//! judges). `decode` is the median time of decoding both
//! PNGs here one after the other, to one value per pixel, as the CLI reads them; `start` the
//! wall time of a `riseg --version` process (spawn, load, exit: what every process pays).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{Context as _, Result, bail};
use clap::{Parser, Subcommand};
use riseg::{
    flow::{DisFlow, FlowEstimator as _, FlowParams},
    io::{
        image::{read_png_as_rgb8, read_png_as_rgb8_mapped},
        scene::Scene,
    },
    rig::workspace::{ActionBuf, WorkspaceBuf},
    segment::{ClassicalSegmenter, RgbdFrame, SegmenterParams, StaticSegmenter as _},
    testkit::SyntheticStep,
};
use riseg_core::{
    Config, ImageView,
    action::find_action,
    frames::MotionInput,
    pipeline::{Stage, WorkspaceLen, update_mask_observed},
};

#[derive(Debug, Parser)]
struct Args {
    #[command(subcommand)]
    what: What,
    /// Timed runs per measurement (the median is reported), after one warm-up run.
    #[arg(long, default_value_t = 15, global = true)]
    runs: usize,
}

#[derive(Debug, Subcommand)]
enum What {
    /// The push cycle on the first push of each scene of the given `riseg gen` datasets.
    Cycle {
        /// Dataset folders (scenes with `flow/`, as `riseg gen` writes them).
        datasets: Vec<PathBuf>,
    },
    /// UpdateMask's stages at three image sizes and three frame counts.
    Scaling,
    /// A one-shot `riseg flow` process against the warm estimate on one pair.
    Oneshot {
        /// The `riseg` binary.
        riseg: PathBuf,
        /// First image (PNG).
        first: PathBuf,
        /// Second image (PNG).
        second: PathBuf,
        /// Where the processes write their flow (overwritten by every run; its sibling
        /// `*.new.flo` is written fresh by every run and removed at the end).
        #[arg(long, value_name = "OUT.flo")]
        out: PathBuf,
    },
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// Median milliseconds of `runs` calls of `f` after one warm-up call.
fn time_ms(runs: usize, mut f: impl FnMut() -> Result<()>) -> Result<f64> {
    f()?;
    let mut ms = Vec::with_capacity(runs);
    for _ in 0..runs {
        let start = Instant::now();
        f()?;
        ms.push(start.elapsed().as_secs_f64() * 1e3);
    }
    Ok(median(ms))
}

/// Stage names of UpdateMask, in order.
const STAGES: [&str; 4] = ["frames", "twists", "grouping", "mask"];

/// Median per-stage milliseconds of `runs` UpdateMask steps (after one warm-up), and the
/// median of their totals.
fn update_mask_ms(
    input: &MotionInput<'_>,
    static_t1: &ImageView<'_, u16>,
    cfg: &Config,
    runs: usize,
) -> Result<([f64; 4], f64)> {
    let (w, h) = input.size();
    let mut buf = WorkspaceBuf::new(cfg, w, h);
    let mut out = vec![0u16; w * h];
    let mut per_stage: [Vec<f64>; 4] = Default::default();
    let mut totals = Vec::with_capacity(runs);
    for run in 0..=runs {
        let mut spent = [0.0; 4];
        let start = Instant::now();
        let mut clock = Instant::now();
        update_mask_observed(input, static_t1, cfg, &mut buf.view(), &mut out, |stage| {
            let i = match stage {
                Stage::Frames => 0,
                Stage::Twists => 1,
                Stage::Grouping => 2,
                Stage::Mask => 3,
            };
            spent[i] = clock.elapsed().as_secs_f64() * 1e3;
            clock = Instant::now();
        })?;
        let total = start.elapsed().as_secs_f64() * 1e3;
        if run > 0 {
            for (v, s) in per_stage.iter_mut().zip(spent) {
                v.push(s);
            }
            totals.push(total);
        }
    }
    Ok((per_stage.map(median), median(totals)))
}

fn pool(threads: usize) -> Result<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("cannot build a thread pool")
}

/// The per-part medians of one scene's first push, in the order of [`CYCLE_PARTS`].
fn scene_cycle(dir: &Path, runs: usize) -> Result<Vec<f64>> {
    let scene = Scene::read(dir).with_context(|| format!("reading {}", dir.display()))?;
    let Some(flows) = scene.flow.as_ref().filter(|f| !f.is_empty()) else {
        bail!("{} has no flow/ (make it with riseg gen)", dir.display());
    };
    let (w, h) = (scene.rgb[0].width(), scene.rgb[0].height());
    let k = scene.camera.intrinsics();
    let depth: Vec<Vec<f32>> = scene.depth[..2]
        .iter()
        .map(|d| {
            d.as_slice()
                .iter()
                .map(|&r| scene.camera.depth_m(r))
                .collect()
        })
        .collect();
    let cfg = Config::PAPER;
    let mut seg = ClassicalSegmenter::new(SegmenterParams::default())?;
    let frame = |t: usize| RgbdFrame::new(w, h, scene.rgb[t].as_slice(), &depth[t]);
    let static_t = seg.segment(&frame(0)?, &k)?;
    let static_t1 = seg.segment(&frame(1)?, &k)?;

    let mut parts = Vec::new();
    for threads in [1, 2] {
        let pool = pool(threads)?;
        parts.push(pool.install(|| {
            time_ms(runs, || {
                seg.segment(&frame(1)?, &k)?;
                Ok(())
            })
        })?);
    }
    let flow = DisFlow::new(FlowParams::MEDIUM)?;
    for threads in [1, 2] {
        let pool = pool(threads)?;
        parts.push(pool.install(|| {
            time_ms(runs, || {
                flow.estimate(scene.rgb[0].view(), scene.rgb[1].view())?;
                Ok(())
            })
        })?);
    }
    let input = MotionInput::new(
        static_t.labels.view(),
        ImageView::packed(w, h, &depth[0])?,
        ImageView::packed(w, h, &depth[1])?,
        flows[0].view(),
        k,
    )?;
    let (stages, update) = update_mask_ms(&input, &static_t1.labels.view(), &cfg, runs)?;
    parts.extend(stages);
    parts.push(update);
    let mut action = ActionBuf::new(&cfg, w, h);
    let mask = static_t1.labels.view();
    let depth_t1 = ImageView::packed(w, h, &depth[1])?;
    parts.push(time_ms(runs, || {
        find_action(
            &static_t1.heatmap.view(),
            &depth_t1,
            &mask,
            &k,
            &cfg,
            action.view(),
        )?;
        Ok(())
    })?);
    Ok(parts)
}

/// Columns of the `cycle` table, in the order [`scene_cycle`] measures them.
const CYCLE_PARTS: [&str; 10] = [
    "segment_1t",
    "segment_2t",
    "flow_1t",
    "flow_2t",
    "frames",
    "twists",
    "grouping",
    "mask",
    "update_mask",
    "find_action",
];

fn cycle(datasets: &[PathBuf], runs: usize) -> Result<()> {
    for dataset in datasets {
        let case = dataset.file_name().map_or_else(
            || dataset.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        let mut scenes = riseg::io::scene::list_scenes(dataset)?;
        scenes.sort();
        let mut columns: Vec<Vec<f64>> = vec![Vec::new(); CYCLE_PARTS.len()];
        for dir in &scenes {
            for (c, v) in columns.iter_mut().zip(scene_cycle(dir, runs)?) {
                c.push(v);
            }
        }
        let medians: Vec<f64> = columns.into_iter().map(median).collect();
        for (name, v) in CYCLE_PARTS.iter().zip(&medians) {
            println!("cycle\t{case}\t{name}\t{v:.3}");
        }
        let part = |name: &str| {
            CYCLE_PARTS
                .iter()
                .position(|p| *p == name)
                .map_or(f64::NAN, |i| medians[i])
        };
        let rest = part("update_mask") + part("find_action");
        println!(
            "cycle\t{case}\tcycle_1t\t{:.3}",
            part("segment_1t") + part("flow_1t") + rest
        );
        println!(
            "cycle\t{case}\tcycle_2t\t{:.3}",
            part("segment_2t") + part("flow_2t") + rest
        );
        println!("cycle\t{case}\tscenes\t{}", scenes.len());
    }
    Ok(())
}

fn scaling(runs: usize) -> Result<()> {
    for (w, h) in [(320, 240), (640, 480), (1280, 720)] {
        let step = SyntheticStep::touching_boxes(w, h)?;
        let input = step.input()?;
        let static_t1 = step.static_t1()?;
        for n in [250, 1000, 4000] {
            let mut cfg = Config::PAPER;
            cfg.frame_samples = n;
            let (stages, total) = update_mask_ms(&input, &static_t1, &cfg, runs)?;
            let case = format!("{w}x{h} n={n}");
            for (name, v) in STAGES.iter().zip(stages) {
                println!("scaling\t{case}\t{name}\t{v:.3}");
            }
            println!("scaling\t{case}\ttotal\t{total:.3}");
            let bytes = WorkspaceLen::for_config(&cfg, w, h).bytes();
            println!("scaling\t{case}\tworkspace_bytes\t{bytes}");
        }
    }
    Ok(())
}

/// Thread counts of the `oneshot` comparison.
const ONESHOT_THREADS: [usize; 2] = [1, 2];

fn oneshot(riseg: &Path, first: &Path, second: &Path, out: &Path, runs: usize) -> Result<()> {
    let a = read_png_as_rgb8(first)?;
    let b = read_png_as_rgb8(second)?;
    let fresh = out.with_extension("new.flo");
    let mut decode = Vec::with_capacity(runs);
    for _ in 0..runs {
        let start = Instant::now();
        for path in [first, second] {
            read_png_as_rgb8_mapped(path, |&[_, green, _]| f32::from(green))?;
        }
        decode.push(start.elapsed().as_secs_f64() * 1e3);
    }
    println!("oneshot\tdecode\tpair\t{:.3}", median(decode));
    // The cost of any `riseg` process, whatever it does: spawn, load, `--version`, exit.
    let mut start_exit = Vec::with_capacity(runs);
    for _ in 0..=runs {
        let start = Instant::now();
        let output = Command::new(riseg)
            .arg("--version")
            .output()
            .with_context(|| format!("running {}", riseg.display()))?;
        if !output.status.success() {
            bail!("{} --version failed: {}", riseg.display(), output.status);
        }
        start_exit.push(start.elapsed().as_secs_f64() * 1e3);
    }
    // The first run loads the binary into the page cache.
    println!(
        "oneshot\tstart\tprocess\t{:.3}",
        median(start_exit.split_off(1))
    );
    for threads in ONESHOT_THREADS {
        let flow = DisFlow::new(FlowParams::MEDIUM)?.with_threads(threads)?;
        let process = |to: &Path| -> Result<()> {
            let status = Command::new(riseg)
                .arg("flow")
                .args([first, second])
                .arg("-o")
                .arg(to)
                .args(["--threads", &threads.to_string()])
                .status()
                .with_context(|| format!("running {}", riseg.display()))?;
            if !status.success() {
                bail!("{} flow failed: {status}", riseg.display());
            }
            Ok(())
        };
        // Warm-ups: the estimator's buffers, the binary in the page cache.
        flow.estimate(a.view(), b.view())?;
        process(out)?;
        let mut warm = Vec::with_capacity(runs);
        let (mut over, mut new) = (Vec::with_capacity(runs), Vec::with_capacity(runs));
        for _ in 0..runs {
            let start = Instant::now();
            flow.estimate(a.view(), b.view())?;
            warm.push(start.elapsed().as_secs_f64() * 1e3);
            let start = Instant::now();
            process(out)?;
            over.push(start.elapsed().as_secs_f64() * 1e3);
            remove_if_there(&fresh)?;
            let start = Instant::now();
            process(&fresh)?;
            new.push(start.elapsed().as_secs_f64() * 1e3);
        }
        remove_if_there(&fresh)?;
        println!("oneshot\t{threads}t\twarm\t{:.3}", median(warm));
        println!("oneshot\t{threads}t\tprocess\t{:.3}", median(over));
        println!("oneshot\t{threads}t\tprocess_new\t{:.3}", median(new));
    }
    Ok(())
}

/// Removes `path` if it exists.
fn remove_if_there(path: &Path) -> Result<()> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            Err(e).with_context(|| format!("removing {}", path.display()))
        }
        _ => Ok(()),
    }
}

fn main() -> Result<()> {
    let args = Args::parse();
    let runs = args.runs.max(1);
    match &args.what {
        What::Cycle { datasets } => cycle(datasets, runs),
        What::Scaling => scaling(runs),
        What::Oneshot {
            riseg,
            first,
            second,
            out,
        } => oneshot(riseg, first, second, out, runs),
    }
}
