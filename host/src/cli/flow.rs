//! `riseg flow`: dense optical flow between two PNG files with the built-in DIS estimator
//! or an ONNX model (`--flow`).

use std::path::PathBuf;

use crate::cli::models::{ModelArg, parse_model};
use crate::flow::{DisFlow, FlowParams, luma_of, viz::flow_to_rgb};
use crate::io::{
    Durability,
    image::{Image, read_png_as_rgb8_mapped, write_flo_as, write_rgb8_as},
};
use anyhow::{Context as _, bail};
use clap::ValueEnum;

pub(super) const FLOW_HELP: &str = "\
Dense optical flow from FIRST.png to SECOND.png with the built-in DIS estimator \
(coarse-to-fine patch inverse search, densification, variational refinement; no model \
weights); --flow PATH.onnx runs a learned flow network instead (contract below).

The pixel at (x, y) of FIRST shows the same point as (x + dx, y + dy) of SECOND; dx, dy \
are in pixels, y grows downwards. The images are read as PNG (any bit depth and colour \
type; converted to 8-bit RGB, then to luma) and must have one size.

OUTPUT is a Middlebury .flo file, little-endian: the float 202021.25 (bytes \"PIEH\"), \
i32 width, i32 height, then width*height pairs of f32 (dx, dy), row-major. --viz also \
writes the flow as an 8-bit RGB PNG on the Middlebury colour wheel: hue is the direction \
(right red, down yellow, left cyan, up blue), saturation the length relative to the \
largest vector; white is no motion. Outputs are written to a temporary file and renamed, \
so they are never left half-written; they are not flushed to disk first (a power loss within \
seconds of the call may leave the old file or none: run the command again).

Presets, fastest first (bench/flow.sh measures them against OpenCV's DIS):
  ultrafast  stops at quarter resolution, no refinement: a few ms, coarse boundaries
  fast       stops at half resolution, two refinement iterations per level
  medium     denser patches, one refinement iteration per level, and motion boundaries
             sharpened at full resolution (default)
  fine       half resolution plus a full-resolution polish: sharpest motion boundaries,
             about twice the time of medium";

#[derive(Debug, clap::Args)]
pub(super) struct FlowArgs {
    /// First image (PNG).
    first: PathBuf,
    /// Second image (PNG), same size as the first.
    second: PathBuf,
    /// Output flow, Middlebury .flo.
    #[arg(short, long, value_name = "OUT.flo")]
    output: PathBuf,
    /// Also write a colour-wheel picture of the flow (PNG).
    #[arg(long, value_name = "OUT.png")]
    viz: Option<PathBuf>,
    /// Optical flow: `builtin` (DIS, --preset) or PATH.onnx (feature `onnx`; tensor
    /// contract below).
    #[arg(long, value_name = "builtin|PATH.onnx", default_value = "builtin", value_parser = parse_model)]
    flow: ModelArg,
    /// Speed/accuracy preset of the built-in flow.
    #[arg(long, value_enum, default_value_t = Preset::Medium)]
    preset: Preset,
    /// Worker threads; 0 uses every core (at most 256).
    #[arg(long, default_value_t = 0, value_parser = crate::cli::thread_count)]
    threads: usize,
    /// Settings file (TOML): its [flow] keys replace those of --preset (the other
    /// sections are checked, not used). See `riseg config --help`.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
}

/// `FlowParams` presets by name.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub(super) enum Preset {
    Ultrafast,
    Fast,
    Medium,
    Fine,
}

impl Preset {
    const fn params(self) -> FlowParams {
        match self {
            Self::Ultrafast => FlowParams::ULTRAFAST,
            Self::Fast => FlowParams::FAST,
            Self::Medium => FlowParams::MEDIUM,
            Self::Fine => FlowParams::FINE,
        }
    }
}

pub(super) fn command(args: &FlowArgs) -> anyhow::Result<()> {
    let params = crate::cli::config::ConfigArg::from(args.config.clone())
        .load()?
        .flow_over(args.preset.params())?;
    // One pool for the whole call, with this thread as one of its workers: with
    // `--threads 1` no thread is started and no work crosses threads; with more, the
    // second image decodes on a worker while this thread decodes the first, and the
    // estimate runs on the same workers. This thread stays in the pool until the process
    // ends (`riseg flow` makes one call per process); the pool lives to the end of the call.
    let _workers = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads)
        .use_current_thread()
        .build()
        .context("cannot start the worker threads")?;
    let flow = match &args.flow {
        // The built-in flow reads only the images' luma: made while decoding, row by row,
        // the RGB images are never held (the flow `estimate` gives on them, bit for bit).
        ModelArg::Builtin => {
            let (first, second) = read_pair(args, luma_of)?;
            let estimator = DisFlow::new(params)?;
            let flow = estimator.estimate_gray(&first, &second);
            // Left to the process's exit, which returns all memory at once: freed here,
            // each large buffer is unmapped by a system call of its own.
            core::mem::forget((estimator, first, second));
            flow
        }
        #[cfg(feature = "onnx")]
        ModelArg::Onnx(_) => {
            let (first, second) = read_pair(args, |&rgb| rgb)?;
            let estimator = args.flow.flow(|| DisFlow::new(params))?;
            crate::flow::FlowEstimator::estimate(&estimator, first.view(), second.view())
        }
    }
    .with_context(|| {
        format!(
            "flow from {} to {}",
            args.first.display(),
            args.second.display()
        )
    })?;
    // Derived outputs: atomic, not flushed to disk (`Durability`'s contract).
    write_flo_as(&args.output, &flow, Durability::Derived)?;
    if let Some(viz) = &args.viz {
        write_rgb8_as(viz, &flow_to_rgb(&flow, None), Durability::Derived)?;
    }
    core::mem::forget(flow);
    Ok(())
}

/// Both images of `args`, each pixel mapped through `pixel` as it is decoded
/// ([`read_png_as_rgb8_mapped`]); the second decodes on a worker when there is one.
///
/// # Errors
/// Either image cannot be read, or the two differ in size.
fn read_pair<T: Send>(
    args: &FlowArgs,
    pixel: impl Fn(&[u8; 3]) -> T + Sync,
) -> anyhow::Result<(Image<T>, Image<T>)> {
    let (first, second) = rayon::join(
        || read_png_as_rgb8_mapped(&args.first, &pixel),
        || read_png_as_rgb8_mapped(&args.second, &pixel),
    );
    let (first, second) = (first?, second?);
    if first.size() != second.size() {
        bail!(
            "{} is {}x{} but {} is {}x{}: the images must have one size",
            args.first.display(),
            first.width(),
            first.height(),
            args.second.display(),
            second.width(),
            second.height()
        );
    }
    Ok((first, second))
}
