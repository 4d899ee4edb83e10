//! Writes image pairs with exact ground-truth flow into a folder, then times riseg's DIS
//! flow on them on one thread and prints endpoint errors. Two kinds of pairs, 640x480:
//! `--kind textured` (default), textured rigid objects on a textured background moved by
//! `riseg::testkit::flow`; `--kind sim`, the first push of the simulator's loose scenes
//! (the frames `riseg gen` writes, colour rounded to 8 bits; flow unknown where a pixel
//! has no 3-D point, 1e10 in the `.flo`, is skipped); `--kind packed`, the same with the
//! packed family's look-alike boxes (`riseg gen --layout packed`). Pair `i` uses seed
//! `--seed + i`.
//!
//! ```sh
//! cargo run --release -p riseg --example flow_pairs -- /tmp/flow-pairs --pairs 6 --runs 7
//! ```
//!
//! Files per pair `i` (two digits): `pair_i_a.png`, `pair_i_b.png` (8-bit RGB),
//! `pair_i_gt.flo` (Middlebury), `pair_i_mask.png` (8-bit gray, 255 on moving-object pixels
//! of the first image). `bench/flow_vs_opencv.py` reads the same files.
//!
//! Output: one tab-separated row per method: name, mean EPE on moving-object pixels, mean
//! EPE on all pixels (both in pixels, averaged over pairs), and the mean over pairs of the
//! median time of `--runs` runs (milliseconds, after one warm-up run). The time covers
//! `FlowEstimator::estimate` on the decoded RGB images, RGB-to-luma conversion included.

use anyhow::{Context as _, Result};
use clap::Parser;
use riseg::flow::{DisFlow, FlowEstimator as _, FlowParams};
use riseg::io::image::{
    FlowImage, Gray8Image, RgbImage, read_flo, read_gray8, read_rgb8, write_flo, write_gray8,
    write_rgb8,
};
use riseg::testkit::flow::FlowScene;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Debug, Parser)]
struct Args {
    /// Folder for the pairs (created if missing).
    dir: PathBuf,
    /// Number of pairs.
    #[arg(long, default_value_t = 6)]
    pairs: usize,
    /// Timed runs per pair and method (the median is reported).
    #[arg(long, default_value_t = 7)]
    runs: usize,
    /// Seed of the first pair (pair `i` uses `seed + i`).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// riseg presets to run, comma-separated; a `+anchor` suffix (`medium+anchor`) runs the
    /// preset with `coarse_anchor = 4`, `coarsest_propagation = false`, and `+noanchor`
    /// with `coarse_anchor = 0`, `coarsest_propagation = true`; `+edge` turns on the
    /// edge-aware refinement and robust densification (`smoothness_edge_grey = 12`,
    /// `densify_outlier_per_grey = 0.5`, `smoothness = 30`); `+KEY=VALUE` (repeatable,
    /// `medium+smoothness=30+sor_iters=5`) sets `FlowParams` fields by their `[flow]` names.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "ultrafast,fast,medium,fine"
    )]
    presets: Vec<String>,
    /// Print one row per pair as well.
    #[arg(long)]
    per_pair: bool,
    /// Also write each preset's flow of pair `i` as `pair_i_riseg-PRESET.flo` into the
    /// folder (for error maps against `pair_i_gt.flo`).
    #[arg(long)]
    write_flow: bool,
    /// Which pairs: `textured` (rigid textured objects), `sim` (simulator pushes, loose
    /// layout) or `packed` (simulator pushes, packed layout).
    #[arg(long, default_value = "textured")]
    kind: String,
}

/// One pair to write: both images, the true flow, the moving mask (255 moving, 0 not).
struct Written {
    first: RgbImage,
    second: RgbImage,
    flow: FlowImage,
    moving: Gray8Image,
}

fn textured_pair(w: usize, h: usize, seed: u64) -> Result<Written> {
    let p = FlowScene::random_objects(w, h, seed).render();
    let moving = p
        .labels
        .iter()
        .zip(p.flow.as_slice())
        .map(|(&l, v)| {
            if l > 0 && (v[0] != 0.0 || v[1] != 0.0) {
                255
            } else {
                0
            }
        })
        .collect();
    let moving = Gray8Image::from_vec(w, h, moving)?;
    Ok(Written {
        first: p.first,
        second: p.second,
        flow: p.flow,
        moving,
    })
}

/// Frames 0 and 1 of the simulated scene `seed` of `layout` (one scripted push), with the
/// exact flow; moving = object pixels whose true flow is known and longer than 0.1 px.
fn sim_pair(seed: u64, layout: riseg::sim::Layout) -> Result<Written> {
    let g = riseg::cli::generate::generate_scene(seed, layout, 1)?;
    let s = &g.scene;
    let (w, h) = (s.camera.width, s.camera.height);
    let flow = s
        .flow
        .as_ref()
        .and_then(|f| f.first())
        .context("the generated scene has no flow")?
        .clone();
    let labels = s
        .labels
        .as_ref()
        .and_then(|l| l.first())
        .context("the generated scene has no labels")?;
    let moving = labels
        .as_slice()
        .iter()
        .zip(flow.as_slice())
        .map(|(&l, v)| {
            let known = v[0].abs() < 1e9 && v[1].abs() < 1e9;
            if l > 0 && known && v[0].hypot(v[1]) > 0.1 {
                255
            } else {
                0
            }
        })
        .collect();
    let moving = Gray8Image::from_vec(w, h, moving)?;
    let rgb = |t: usize| s.rgb.get(t).cloned();
    Ok(Written {
        first: rgb(0).context("frame 0")?,
        second: rgb(1).context("frame 1")?,
        flow,
        moving,
    })
}

struct Pair {
    name: String,
    first: RgbImage,
    second: RgbImage,
    truth: FlowImage,
    moving: Vec<bool>,
}

fn load(dir: &Path, name: &str) -> Result<Pair> {
    let rgb = |suffix: &str| read_rgb8(&dir.join(format!("{name}_{suffix}.png")));
    let mask = read_gray8(&dir.join(format!("{name}_mask.png")))?;
    Ok(Pair {
        name: name.to_owned(),
        first: rgb("a")?,
        second: rgb("b")?,
        truth: read_flo(&dir.join(format!("{name}_gt.flo")))?,
        moving: mask.as_slice().iter().map(|&v| v > 127).collect(),
    })
}

/// `params` with the `FlowParams` fields of `assignments` (`key=value` joined by `+`,
/// values in TOML: `smoothness_edge_grey=6+smoothness=30`) set.
fn with_keys(params: FlowParams, assignments: &str) -> Result<FlowParams> {
    let mut table = toml::Table::try_from(params)?;
    for kv in assignments.split('+') {
        let (key, value) = kv
            .split_once('=')
            .with_context(|| format!("{kv:?} is not KEY=VALUE"))?;
        let value: toml::Table = toml::from_str(&format!("v = {value}"))?;
        table.insert(key.to_owned(), value["v"].clone());
    }
    Ok(table.try_into()?)
}

fn main() -> Result<()> {
    let args = Args::parse();
    std::fs::create_dir_all(&args.dir)
        .with_context(|| format!("creating {}", args.dir.display()))?;
    let (w, h) = (640, 480);
    let mut pairs = Vec::new();
    for i in 0..args.pairs {
        let name = format!("pair_{i:02}");
        let seed = args.seed + i as u64;
        let p = match args.kind.as_str() {
            "textured" => textured_pair(w, h, seed)?,
            "sim" => sim_pair(seed, riseg::sim::Layout::Loose)?,
            "packed" => sim_pair(seed, riseg::sim::Layout::Packed)?,
            other => anyhow::bail!("unknown --kind {other:?} (textured, sim or packed)"),
        };
        write_rgb8(&args.dir.join(format!("{name}_a.png")), &p.first)?;
        write_rgb8(&args.dir.join(format!("{name}_b.png")), &p.second)?;
        write_gray8(&args.dir.join(format!("{name}_mask.png")), &p.moving)?;
        write_flo(&args.dir.join(format!("{name}_gt.flo")), &p.flow)?;
        pairs.push(load(&args.dir, &name)?);
    }
    for preset in &args.presets {
        let (name, variant) = preset.split_once('+').unwrap_or((preset.as_str(), ""));
        let mut params =
            FlowParams::preset(name).with_context(|| format!("unknown preset {preset:?}"))?;
        match variant {
            "" => {}
            "anchor" => {
                params.coarse_anchor = 4.0;
                params.coarsest_propagation = false;
            }
            "noanchor" => {
                params.coarse_anchor = 0.0;
                params.coarsest_propagation = true;
            }
            "edge" => {
                params.smoothness_edge_grey = 12.0;
                params.densify_outlier_per_grey = 0.5;
                params.smoothness = 30.0;
            }
            assignments if assignments.contains('=') => params = with_keys(params, assignments)?,
            other => {
                anyhow::bail!(
                    "unknown variant {other:?} in {preset:?} (anchor, noanchor, edge, KEY=VALUE)"
                )
            }
        }
        let est = DisFlow::new(params)?.with_threads(1)?;
        let (mut obj, mut all, mut ms) = (0.0, 0.0, 0.0);
        for p in &pairs {
            let (a, b) = (p.first.view(), p.second.view());
            let mut flow = est.estimate(a, b)?;
            let mut times = Vec::with_capacity(args.runs);
            for _ in 0..args.runs.max(1) {
                let t = Instant::now();
                flow = est.estimate(a, b)?;
                times.push(t.elapsed().as_secs_f64() * 1e3);
            }
            times.sort_by(f64::total_cmp);
            let median = times[times.len() / 2];
            if args.write_flow {
                write_flo(
                    &args.dir.join(format!("{}_riseg-{preset}.flo", p.name)),
                    &flow,
                )?;
            }
            let e_obj = flow.mean_epe(&p.truth, Some(&p.moving))?;
            let e_all = flow.mean_epe(&p.truth, None)?;
            if args.per_pair {
                println!(
                    "riseg-{preset}/{}\t{e_obj:.3}\t{e_all:.3}\t{median:.1}",
                    p.name
                );
            }
            obj += e_obj;
            all += e_all;
            ms += median;
        }
        let n = pairs.len().max(1) as f64;
        println!(
            "riseg-{preset}\t{:.3}\t{:.3}\t{:.1}",
            obj / n,
            all / n,
            ms / n
        );
    }
    Ok(())
}
