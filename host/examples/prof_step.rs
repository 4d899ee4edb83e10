//! One UpdateMask step (no flow: the dataset's exact flow is given) on the first push of a
//! `riseg gen` scene, or without a scene on the bench's synthetic step
//! ([`SyntheticStep::touching_boxes`] at 640×480, as `bench/update_mask.sh` times it),
//! repeated `--runs` times, for instruction counts under callgrind:
//!
//! ```sh
//! riseg gen --layout packed --scenes 1 --pushes 1 --seed 7 --out /tmp/packed
//! cargo build --release --example prof_step
//! valgrind --tool=callgrind target/release/examples/prof_step /tmp/packed/scene_000 --runs 3
//! callgrind_annotate --inclusive=yes callgrind.out.*   # divide by the runs + 1
//! ```
//!
//! In a scene the accumulated mask is the static segmentation of frame 0, as
//! `bench/speed.sh` times it. Prints the step's report and an FNV-1a digest of the output mask, so a change can
//! be checked to leave the step bit-identical.

use std::path::PathBuf;

use anyhow::{Context as _, Result, bail};
use clap::Parser;
use riseg::{
    io::scene::Scene,
    rig::workspace::WorkspaceBuf,
    segment::{ClassicalSegmenter, RgbdFrame, SegmenterParams, StaticSegmenter as _},
    testkit::SyntheticStep,
};
use riseg_core::{Config, ImageView, frames::MotionInput, pipeline::update_mask};

#[derive(Debug, Parser)]
struct Args {
    /// A scene folder written by `riseg gen` (with `flow/`); the synthetic step if absent.
    scene: Option<PathBuf>,
    /// Steps run after the first (which also fills the workspace's pages).
    #[arg(long, default_value_t = 3)]
    runs: usize,
}

fn fnv1a(words: &[u16]) -> u64 {
    words
        .iter()
        .flat_map(|w| w.to_le_bytes())
        .fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
        })
}

fn main() -> Result<()> {
    let args = Args::parse();
    let Some(path) = &args.scene else {
        let step = SyntheticStep::touching_boxes(640, 480)?;
        let (input, static_t1) = (step.input()?, step.static_t1()?);
        return run(&input, &static_t1, args.runs);
    };
    let scene = Scene::read(path).with_context(|| format!("reading {}", path.display()))?;
    let Some(flows) = scene.flow.as_ref().filter(|f| !f.is_empty()) else {
        bail!("{} has no flow/ (make it with riseg gen)", path.display());
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
    let mut seg = ClassicalSegmenter::new(SegmenterParams::default())?;
    let frame = |t: usize| RgbdFrame::new(w, h, scene.rgb[t].as_slice(), &depth[t]);
    let static_t = seg.segment(&frame(0)?, &k)?;
    let static_t1 = seg.segment(&frame(1)?, &k)?;
    let input = MotionInput::new(
        static_t.labels.view(),
        ImageView::packed(w, h, &depth[0])?,
        ImageView::packed(w, h, &depth[1])?,
        flows[0].view(),
        k,
    )?;
    run(&input, &static_t1.labels.view(), args.runs)
}

/// Runs the step `runs + 1` times and prints its report and the output mask's digest.
fn run(input: &MotionInput<'_>, static_t1: &ImageView<'_, u16>, runs: usize) -> Result<()> {
    let cfg = Config::PAPER;
    let (w, h) = input.size();
    let mut buf = WorkspaceBuf::new(&cfg, w, h);
    let mut out = vec![0u16; w * h];
    let mut report = None;
    for _ in 0..=runs {
        report = Some(update_mask(
            input,
            static_t1,
            &cfg,
            &mut buf.view(),
            &mut out,
        )?);
    }
    println!("{report:?}");
    println!("mask digest {:016x}", fnv1a(&out));
    Ok(())
}
