//! The `riseg` subcommands, one module each, and what only commands use.
//!
//! Exit codes: 0 success (also when standard output is closed early, e.g. `riseg eval ... |
//! head`: what was cut is the reader's choice); 1 an error, printed to stderr as one line
//! naming the file and the problem; 2 bad arguments (clap's usage message).

/// `print!` that returns an error (naming standard output) instead of panicking when
/// standard output is closed or full; `?` it.
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::cli::write_stdout(format_args!($($arg)*))
    };
}

pub mod bench;
mod calib;
pub mod config;
pub mod demo;
pub mod eval;
mod flow;
pub mod generate;
pub mod live;
pub mod models;
pub mod preview;
pub mod record;
pub mod run;
mod segment;

use std::{
    io::{self, Write as _},
    process::ExitCode,
};

use anyhow::Context as _;

use clap::{Parser, Subcommand, ValueEnum};

use crate::sim::Layout;

const EXIT_CODES: &str = "\
Exit codes: 0 success (also when standard output is closed early, as by `| head`); \
1 an error, printed on stderr as one line naming the file and the problem (nothing is \
left half-written, no input is overwritten); 2 bad arguments.";

/// RISeg: robot interactive object segmentation via body frame-invariant features.
///
/// A robot looks at touching objects on a table with an RGB-D camera; a static segmenter
/// merges them; riseg makes a few 2 cm pushes, samples small body frames on the objects,
/// groups them by their spatial twists and splits what moved differently.
#[derive(Debug, Parser)]
#[command(name = "riseg", version, about, long_about, after_help = EXIT_CODES)]
struct Cli {
    /// More diagnostics on stderr: -v notes what runs, -vv adds debugging detail. Without
    /// it, RUST_LOG sets the level and modules (RUST_LOG=riseg=debug); warnings by default.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the whole loop on a simulated scene and write a report (the default command).
    #[command(long_about = demo::DEMO_HELP, after_long_help = models::MODELS_HELP)]
    Demo(demo::DemoArgs),
    /// Score predicted label maps against a dataset's ground truth (UOIS metrics).
    ///
    /// Prints one line per push index with the overlap and boundary precision, recall and
    /// F-measure and the share of objects found with F > 75 %, as in the UOIS papers and
    /// RISeg's Table 1. All numbers are percentages, averaged over the images of that push.
    #[command(after_long_help = eval::EVAL_HELP)]
    Eval(eval::EvalArgs),
    /// Make a simulated dataset: scenes of touching objects, pushed, with ground truth.
    ///
    /// Each scene is a table with 4-6 objects seen by a D415-like RGB-D camera (640x480,
    /// fx = fy = 615, depth noise 1 mm at 0.6 m) 0.60 m above the table, tilted 15 degrees.
    /// The scene is recorded, then pushed --pushes times by 2 cm (rapier3d physics), and
    /// recorded again after each push. The same --seed and --layout always give the same
    /// files, byte for byte.
    ///
    /// Scene families (--layout):
    ///
    ///   loose   4-6 objects of mixed shapes (a two-shape family of boxes, cylinders,
    ///           capsules, spheres, rounded boxes), 3-7 cm, similar colours, most touching
    ///           a neighbour. Shapes and heights differ, so the static segmenter already
    ///           finds most objects: the easy regime. Each push moves one object of a
    ///           touching pair across the line joining the pair.
    ///   packed  4-6 look-alike boxes of one size (4-7 cm footprint), one height and one
    ///           texture, flush in a grid (2x2, 1x4, 1x5, 2x3, 2x2+1, ...) with 0.2-0.8 mm
    ///           gaps, or (one scene in four) same-height cans in rows or hex-packed. At
    ///           push 0 nothing tells them apart, so a static segmenter merges them: the
    ///           regime RISeg exists for (the paper's static model found under 20 % of
    ///           objects). Each push shears the pack: an outer object, row or column slides
    ///           along a face it shares with a neighbour; the rest stays.
    ///   mixed   a flush pack of 2-4 look-alike boxes plus 1-3 loose objects against or
    ///           near it; pushes shear as in packed.
    ///
    /// Output layout (the scene folder format every riseg command reads):
    ///
    ///   OUT/scene_000/scene_camera.json  intrinsics and depth unit (0.001 m)
    ///   OUT/scene_000/rgb/000000.png     8-bit colour; frame t = after t pushes
    ///   OUT/scene_000/depth/000000.png   16-bit depth in millimetres, 0 = no reading
    ///   OUT/scene_000/label/000000.png   16-bit instance ids, 0 = table (ground truth)
    ///   OUT/scene_000/flow/000000.flo    exact flow from frame t to t+1 (Middlebury)
    ///   OUT/scene_000/actions.json       the pushes, in the camera frame
    ///   OUT/scene_000/poses.json         every object's pose in every frame, world
    ///                                    (table) frame, z up: {"frames": [[{"label": 1,
    ///                                    "translation_m": [x, y, z], "rotation_xyzw":
    ///                                    [qx, qy, qz, qw]}, ...], ...]}
    ///   OUT/preview/scene_000.png        colour | depth | labels, initial over last
    ///                                    frame, pushes drawn as arrows
    ///
    /// Scenes are written to a hidden folder and renamed when complete; existing scene
    /// folders are never overwritten.
    ///
    /// Example: riseg gen --scenes 23 --seed 1 --layout packed --out data/packed23
    #[command(verbatim_doc_comment)]
    Gen(generate::GenArgs),
    /// Segment one RGB-D frame with the built-in classical segmenter (no model weights) or
    /// an ONNX model (--segmenter PATH.onnx)
    ///
    /// The built-in segmenter fits the table plane, keeps what stands on it, grows regions over depth and normal
    /// continuity, and writes 16-bit instance labels (0 = background, 1..n = segments by
    /// decreasing area) and, if asked, the 8-bit heatmap FindAction uses: >= 150 surely
    /// inside one object, 120-149 where objects touch or depth is unsure, < 120 the table.
    ///
    /// The frame is either frame T of a scene folder (--scene DIR --frame T reads
    /// DIR/scene_camera.json, DIR/rgb/00000T.png and DIR/depth/00000T.png), or three files
    /// (--rgb, --depth and --camera); exactly one of the two forms.
    ///
    /// Examples:
    ///   riseg segment --scene data/sim23/scene_000 --frame 0 -o labels.png
    ///   riseg segment --rgb rgb/000000.png --depth depth/000000.png \
    ///     --camera scene_camera.json -o labels.png --heatmap heat.png --viz check.png
    ///
    /// scene_camera.json: {"width": 640, "height": 480, "fx": 615.0, "fy": 615.0,
    /// "cx": 319.5, "cy": 239.5, "depth_unit_m": 0.001}
    #[command(verbatim_doc_comment, after_long_help = models::MODELS_HELP)]
    Segment(segment::SegmentArgs),
    /// Dense optical flow from FIRST.png to SECOND.png with the built-in DIS estimator or an
    /// ONNX model (--flow PATH.onnx).
    #[command(long_about = flow::FLOW_HELP, after_long_help = models::MODELS_HELP)]
    Flow(flow::FlowArgs),
    /// The paper's experiment (Table 1) on simulated scenes: static segmenter, RISeg and
    /// the motion ceiling.
    #[command(long_about = bench::BENCH_HELP, after_long_help = models::MODELS_HELP)]
    Bench(bench::BenchArgs),
    /// Run RISeg on recorded scenes (the pushes already happened) and write its masks.
    #[command(long_about = run::RUN_HELP, after_long_help = models::MODELS_HELP)]
    Run(run::RunArgs),
    /// Check a hand-eye calibration file: where the camera and the table sit in the robot
    /// frame.
    ///
    /// Example:
    ///   riseg calib check --calib hand_eye.json --scene out/rig/scene_live
    #[command(verbatim_doc_comment)]
    Calib(calib::CalibArgs),
    /// Print every setting --config can change, with its default (`riseg config --print`).
    ///
    /// `riseg config --print` writes every setting with its default, meaning and unit, as
    /// TOML.
    ///
    /// A settings file has optional sections [core] (the algorithm: riseg-core's Config),
    /// [segmenter] (the built-in static segmenter) and [flow] (the built-in optical flow);
    /// every key is optional and a missing key keeps its default. demo, bench, run and eval
    /// read all three sections, segment [segmenter], flow [flow] (over its --preset).
    ///
    /// Example:
    ///   riseg config --print > riseg.toml   (edit, then)
    ///   riseg bench --config riseg.toml
    #[command(verbatim_doc_comment)]
    Config(config::ConfigCmdArgs),
}

/// `--layout`: the simulator's scene families by name.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub(super) enum LayoutArg {
    /// Mixed shapes touching; the static segmenter finds most objects.
    Loose,
    /// Look-alike boxes or cans packed flush; the static segmenter merges them.
    Packed,
    /// A flush pack of look-alike boxes with loose objects against it.
    Mixed,
}

impl LayoutArg {
    const fn layout(self) -> Layout {
        match self {
            Self::Loose => Layout::Loose,
            Self::Packed => Layout::Packed,
            Self::Mixed => Layout::Mixed,
        }
    }
}

/// The `riseg` binary: parses the arguments and runs the command; errors go to stderr.
#[must_use]
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    init_logger(cli.verbose);
    let result = match cli
        .command
        .unwrap_or_else(|| Command::Demo(demo::DemoArgs::default()))
    {
        Command::Demo(args) => demo::command(&args),
        Command::Eval(args) => eval::command(&args),
        Command::Gen(args) => generate::command(&args),
        Command::Segment(args) => segment::command(&args),
        Command::Flow(args) => flow::command(&args),
        Command::Bench(args) => bench::command(&args),
        Command::Run(args) => run::command(&args),
        Command::Config(args) => config::command(&args),
        Command::Calib(args) => calib::command(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) if closed_stdout(&error) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {}", error_text(&error));
            ExitCode::FAILURE
        }
    }
}

/// Most scenes one `gen` or `bench` run makes: a bound on time and disk a typo cannot
/// exceed (a scene is about 2 MB on disk).
pub const MAX_SCENES: usize = 10_000;
/// Most worker threads `--threads` starts.
pub const MAX_THREADS: usize = 256;

/// Parses `--scenes`: 1 to [`MAX_SCENES`].
fn scene_count(text: &str) -> Result<usize, String> {
    bounded(text, 1, MAX_SCENES)
}

/// Most pushes `gen` scripts per scene.
pub const MAX_PUSHES: usize = 20;

/// Parses `--pushes`: 0 to [`MAX_PUSHES`].
fn push_count(text: &str) -> Result<usize, String> {
    bounded(text, 0, MAX_PUSHES)
}

/// Parses `--threads`: 0 (every core) to [`MAX_THREADS`].
fn thread_count(text: &str) -> Result<usize, String> {
    bounded(text, 0, MAX_THREADS)
}

/// Largest `--ceiling-floor-mm`: beyond a centimetre every push counts as alike.
pub const MAX_CEILING_FLOOR_MM: f32 = 10.0;

/// Parses `--ceiling-floor-mm`: above 0 up to [`MAX_CEILING_FLOOR_MM`].
fn ceiling_floor_mm(text: &str) -> Result<f32, String> {
    match text.parse::<f32>() {
        Ok(mm) if mm > 0.0 && mm <= MAX_CEILING_FLOOR_MM => Ok(mm),
        _ => Err(format!(
            "expected millimetres above 0 and at most {MAX_CEILING_FLOOR_MM}"
        )),
    }
}

fn bounded(text: &str, min: usize, max: usize) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if (min..=max).contains(&n) => Ok(n),
        _ => Err(format!("expected a whole number from {min} to {max}")),
    }
}

/// Writes `text` to standard output and flushes it (see [`say!`]).
pub(crate) fn write_stdout(text: core::fmt::Arguments<'_>) -> anyhow::Result<()> {
    let mut out = io::stdout().lock();
    out.write_fmt(text)
        .and_then(|()| out.flush())
        .context("writing to standard output")
}

/// Whether `error` is standard output closed by its reader (a broken pipe).
fn closed_stdout(error: &anyhow::Error) -> bool {
    error.chain().any(|cause| {
        cause
            .downcast_ref::<io::Error>()
            .is_some_and(|e| e.kind() == io::ErrorKind::BrokenPipe)
    })
}

/// Sends `log` records to stderr as `level: message`: warnings and errors by default,
/// `-v` info, `-vv` debug, `-vvv` trace; without `-v`, `RUST_LOG` decides (env_logger's
/// syntax, `RUST_LOG=riseg::cli::bench=debug`).
fn init_logger(verbose: u8) {
    use std::io::Write as _;
    let mut logger = env_logger::Builder::new();
    logger.format(|out, record| {
        writeln!(
            out,
            "{}: {}",
            record.level().as_str().to_ascii_lowercase(),
            record.args()
        )
    });
    match (verbose, std::env::var("RUST_LOG")) {
        (0, Ok(filters)) => logger.parse_filters(&filters),
        (0, Err(_)) => logger.filter_level(log::LevelFilter::Warn),
        (1, _) => logger.filter_level(log::LevelFilter::Info),
        (2, _) => logger.filter_level(log::LevelFilter::Debug),
        _ => logger.filter_level(log::LevelFilter::Trace),
    };
    // Only fails when a logger is already set (not in the binary).
    let _ = logger.try_init();
}

/// `error` and its causes joined by ": ", each cause once: many of riseg's errors already
/// end with their cause's message (`"{path}: {source}"`), which anyhow's `{:#}` would
/// repeat.
fn error_text(error: &anyhow::Error) -> String {
    let mut text = error.to_string();
    for cause in error.chain().skip(1) {
        let cause = cause.to_string();
        if !text.ends_with(&cause) {
            text.push_str(": ");
            text.push_str(&cause);
        }
    }
    text
}
