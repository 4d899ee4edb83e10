//! The `riseg` command line.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context as _, bail};
use clap::{Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use riseg::cli::bench::{self, BenchConfig};
use riseg::cli::eval::{self, DatasetPoses};
use riseg::cli::generate::{PREVIEW_DIR, scene_dir_name, write_dataset};
use riseg::cli::run::{InputDirs, run_scene};
use riseg::eval::ceiling::CeilingParams;
use riseg::flow::{
    DisFlow, FlowEstimator as _, FlowParams, RgbView,
    flo::{write_atomic, write_flo},
    viz::flow_to_rgb,
};
use riseg::io::image::{Image, ImageIoError};
use riseg::io::scene::{self, SceneCamera};
use riseg::rig::episode::Stop;
use riseg::rig::tracker::Tracker;
use riseg::segment::{ClassicalSegmenter, RgbdFrame, SegmenterParams, viz};
use riseg::sim::Layout;

/// RISeg: robot interactive object segmentation via body frame-invariant features.
///
/// A robot looks at touching objects on a table with an RGB-D camera; a static segmenter
/// merges them; riseg makes a few 2 cm pushes, samples small body frames on the objects,
/// groups them by their spatial twists and splits what moved differently.
#[derive(Debug, Parser)]
#[command(name = "riseg", version, about, long_about)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the whole loop on a simulated scene and write a report (the default command).
    #[command(long_about = DEMO_HELP)]
    Demo(DemoArgs),
    /// Score predicted label maps against a dataset's ground truth (UOIS metrics).
    ///
    /// Prints one line per push index with the overlap and boundary precision, recall and
    /// F-measure and the share of objects found with F > 75 %, as in the UOIS papers and
    /// RISeg's Table 1. All numbers are percentages, averaged over the images of that push.
    #[command(after_long_help = EVAL_HELP)]
    Eval(EvalArgs),
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
    Gen(GenArgs),
    /// Segment one RGB-D frame with the built-in classical segmenter (no model weights)
    ///
    /// Fits the table plane, keeps what stands on it, grows regions over depth and normal
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
    #[command(verbatim_doc_comment)]
    Segment(SegmentArgs),
    /// Dense optical flow from FIRST.png to SECOND.png with the built-in DIS estimator.
    #[command(long_about = FLOW_HELP)]
    Flow(FlowArgs),
    /// The paper's experiment (Table 1) on simulated scenes: static segmenter, RISeg and
    /// the motion ceiling.
    #[command(long_about = BENCH_HELP)]
    Bench(BenchArgs),
    /// Run RISeg on recorded scenes (the pushes already happened) and write its masks.
    #[command(long_about = RUN_HELP)]
    Run(RunArgs),
}

const RUN_HELP: &str = "\
Run RISeg on recorded scenes (the pushes already happened) and write its masks.

For each scene folder (the format `riseg gen` writes and `riseg gen --help` describes: \
scene_camera.json, rgb/NNNNNN.png, depth/NNNNNN.png; label/ and actions.json are not \
needed), frame 0 is segmented by the built-in static segmenter; for every later frame the \
optical flow from the previous frame, the new static segmentation and riseg-core's \
UpdateMask carry the mask forward and split what moved differently. The mask of frame t \
is written to PRED/<scene>/label/<t>.png (16-bit, 0 = background), the layout \
`riseg eval --pred PRED` reads. Each PNG is written atomically, and a scene whose \
folder, input files or tracking fail writes no mask.

Flow and static segmentation from files: --flow-dir and --static-dir replace the \
built-in flow and segmenter by files computed elsewhere (RAFT flow, MSMFormer or UCN \
labels), read for the scene folder named S and frame t (NNNNNN = t, six digits):

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

Examples:
  riseg run --scene data/sim23/scene_004 --out out/pred
  riseg run --dataset data/sim23 --out out/pred && riseg eval --gt data/sim23 --pred out/pred
  riseg run --dataset data/packed --flow-dir data/packed --out out/exact   (exact flow)
  riseg run --dataset data/real --flow-dir raft --static-dir msmformer --out out/learned";

#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("input").required(true).args(["scene", "dataset"])))]
struct RunArgs {
    /// One scene folder.
    #[arg(long, value_name = "DIR")]
    scene: Option<PathBuf>,
    /// A dataset: every scene_* folder in it.
    #[arg(long, value_name = "DIR")]
    dataset: Option<PathBuf>,
    /// Output folder: masks go to OUT/<scene name>/label/NNNNNN.png.
    #[arg(long, value_name = "PRED")]
    out: PathBuf,
    /// Read the flow from frame t to t+1 of scene S from FLOW/S/flow/<t>.flo (Middlebury)
    /// instead of computing it; a dataset made by `riseg gen` holds its exact flow.
    #[arg(long, value_name = "FLOW")]
    flow_dir: Option<PathBuf>,
    /// Read the static labels of frame t of scene S from STATIC/S/label/<t>.png (8- or
    /// 16-bit, 0 = background) and its heatmap from STATIC/S/heat/<t>.png (8-bit, optional)
    /// instead of segmenting.
    #[arg(long, value_name = "STATIC")]
    static_dir: Option<PathBuf>,
}

const DEMO_HELP: &str = "\
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
struct DemoArgs {
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
}

impl Default for DemoArgs {
    fn default() -> Self {
        Self {
            layout: LayoutArg::Packed,
            seed: None,
            out: PathBuf::from("riseg-demo"),
        }
    }
}

/// `--layout`: the simulator's scene families by name.
#[derive(Debug, Clone, Copy, ValueEnum)]
enum LayoutArg {
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

const BENCH_HELP: &str = "\
The paper's experiment (its Table 1) on simulated scenes: static segmenter, RISeg and the \
motion ceiling.

Each scene is a table with 4-6 touching objects (the scenes of `riseg gen` with the same \
seed and --layout: loose by default, packed or mixed; see `riseg gen --help`). On each, \
the loop of Algorithm 1 runs with the built-in segmenter and optical flow: FindAction \
picks a push from the static heatmap, the simulated arm makes it, UpdateMask corrects the \
mask; at most 3 pushes, fewer when no push qualifies. Every frame is scored against the \
simulator's ground truth three times: the static segmentation of that frame, RISeg's \
accumulated mask (at push 0 they are the same), and the motion ceiling.

The motion ceiling is the best mask a method that starts from the static segmentation \
and splits by motion can reach after the pushes so far: the ground truth, with two \
touching objects (at most 2 background pixels apart along a row or column) merged when \
every static segmentation so far put them in one segment (the segment covering most of \
each object) and every push so far moved them alike (their true rigid motions agree \
within 1 mm at either object's centre and 1.5 degrees); merges chain through touching \
neighbours. RISeg is judged as a share of it.

Columns (percent, averaged over the scenes that reached that push): overlap F, boundary \
F, and the share of objects found with overlap F > 75 (see `riseg eval --help`). Below \
the table, per push: RISeg / ceiling, the ratio of their objects-found columns; and how \
many of the pushes made at that index moved part of a merged segment: some segment of \
the static segmentation before the push holds two or more objects (an object belongs to \
the segment covering most of it) and the push moved one of them (its true motion \
exceeds 1 mm or 0.5 degree) but not another alike with it. Only such a push gives \
motion something to split; moving a merged segment as one piece, or an object the static \
segmenter already found alone, does not. Then the median milliseconds per step of each \
stage: segment (static segmentation), flow (one thread), frames, twists, grouping, mask \
(riseg-core's UpdateMask stages).

The tables are the same for a seed on any machine and thread count; times vary.

Example:
  riseg bench --scenes 23 --seed 1 --json bench-seed1.json";

#[derive(Debug, Args)]
struct BenchArgs {
    /// Number of scenes.
    #[arg(long, default_value_t = 23)]
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
}

const FLOW_HELP: &str = "\
Dense optical flow from FIRST.png to SECOND.png with the built-in DIS estimator \
(coarse-to-fine patch inverse search, densification, variational refinement; no model \
weights).

The pixel at (x, y) of FIRST shows the same point as (x + dx, y + dy) of SECOND; dx, dy \
are in pixels, y grows downwards. The images are read as PNG (any bit depth and colour \
type; converted to 8-bit RGB, then to luma) and must have one size.

OUTPUT is a Middlebury .flo file, little-endian: the float 202021.25 (bytes \"PIEH\"), \
i32 width, i32 height, then width*height pairs of f32 (dx, dy), row-major. --viz also \
writes the flow as an 8-bit RGB PNG on the Middlebury colour wheel: hue is the direction \
(right red, down yellow, left cyan, up blue), saturation the length relative to the \
largest vector; white is no motion. Outputs are written to a temporary file and renamed, \
so they are never left half-written.

Presets, fastest first (bench/flow.sh measures them against OpenCV's DIS):
  ultrafast  stops at quarter resolution, no refinement: a few ms, coarse boundaries
  fast       stops at half resolution, two refinement iterations per level
  medium     fast with denser patches (default)
  fine       half resolution plus a full-resolution polish: sharpest motion boundaries,
             about twice the time of medium";

#[derive(Debug, clap::Args)]
struct FlowArgs {
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
    /// Speed/accuracy preset.
    #[arg(long, value_enum, default_value_t = Preset::Medium)]
    preset: Preset,
    /// Worker threads; 0 uses every core.
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

/// `FlowParams` presets by name.
#[derive(Debug, Clone, Copy, ValueEnum)]
enum Preset {
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

/// Decodes a PNG into 8-bit RGB; errors name the file.
fn read_rgb(path: &Path) -> anyhow::Result<image::RgbImage> {
    let reader =
        image::ImageReader::open(path).with_context(|| format!("reading {}", path.display()))?;
    let img = reader
        .with_guessed_format()
        .with_context(|| format!("reading {}", path.display()))?
        .decode()
        .with_context(|| format!("decoding {} (expected a PNG image)", path.display()))?;
    Ok(img.to_rgb8())
}

fn view(img: &image::RgbImage) -> anyhow::Result<RgbView<'_>> {
    Ok(RgbView::new(
        img.width() as usize,
        img.height() as usize,
        img.as_raw(),
    )?)
}

fn run_flow(args: &FlowArgs) -> anyhow::Result<()> {
    let first = read_rgb(&args.first)?;
    let second = read_rgb(&args.second)?;
    if first.dimensions() != second.dimensions() {
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
    let estimator = DisFlow::new(args.preset.params())?.with_threads(args.threads)?;
    let flow = estimator
        .estimate(view(&first)?, view(&second)?)
        .with_context(|| {
            format!(
                "flow from {} to {}",
                args.first.display(),
                args.second.display()
            )
        })?;
    write_flo(&args.output, &flow)?;
    if let Some(viz) = &args.viz {
        let rgb = flow_to_rgb(&flow, None);
        let img = image::RgbImage::from_raw(first.width(), first.height(), rgb)
            .context("colour-wheel image size")?;
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .with_context(|| format!("encoding {}", viz.display()))?;
        write_atomic(viz, &png).with_context(|| format!("writing {}", viz.display()))?;
    }
    Ok(())
}

#[derive(Debug, Args)]
#[command(group(
    clap::ArgGroup::new("input")
        .required(true)
        .args(["scene", "rgb"])
))]
struct SegmentArgs {
    /// Scene folder to read the frame from (with --frame): scene_camera.json,
    /// rgb/NNNNNN.png, depth/NNNNNN.png.
    #[arg(long, value_name = "DIR", requires = "frame")]
    scene: Option<PathBuf>,
    /// Frame number in the scene folder: 0 is the initial frame, t the frame after t
    /// pushes.
    #[arg(long, value_name = "T", requires = "scene")]
    frame: Option<usize>,
    /// Colour image: 8-bit RGB PNG (an alpha channel is ignored).
    #[arg(long, value_name = "PNG", requires_all = ["depth", "camera"])]
    rgb: Option<PathBuf>,
    /// Depth image aligned to the colour image: 16-bit greyscale PNG in the camera file's
    /// `depth_unit_m` units (usually millimetres), 0 = no reading.
    #[arg(long, value_name = "PNG", requires_all = ["rgb", "camera"])]
    depth: Option<PathBuf>,
    /// Camera file (scene_camera.json): width, height, fx, fy, cx, cy (pixels) and
    /// depth_unit_m (metres per depth unit).
    #[arg(long, value_name = "JSON", requires_all = ["rgb", "depth"])]
    camera: Option<PathBuf>,
    /// Where to write the labels: 16-bit greyscale PNG, 0 = background.
    #[arg(short = 'o', long = "output", value_name = "PNG")]
    output: PathBuf,
    /// Also write the heatmap: 8-bit greyscale PNG (paper thresholds l_u = 150, l_l = 120).
    #[arg(long, value_name = "PNG")]
    heatmap: Option<PathBuf>,
    /// Also write a picture to check by eye: colour | labels | heatmap (grey < 120,
    /// orange 120-149, green >= 150).
    #[arg(long, value_name = "PNG")]
    viz: Option<PathBuf>,
    /// Seed of the table-plane RANSAC (same inputs and seed, same output).
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

const EVAL_HELP: &str = "\
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
object's centre and 1.5 degrees); merges chain through touching neighbours. Below it, per
push: prediction / ceiling, the ratio of the objects-found columns. A malformed
poses.json stops the run with an error naming it; without poses.json in every scene the
ceiling is skipped with a note on stderr.

Example:
  riseg eval --gt data/sim23 --pred out/sim23-static --json static.json";

#[derive(Debug, Args)]
struct GenArgs {
    /// Number of scenes to make.
    #[arg(long, default_value_t = 1)]
    scenes: usize,
    /// Dataset seed; scene i is simulated from a seed derived from it and i.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output folder (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Pushes per scene; each scene has pushes + 1 frames.
    #[arg(long, default_value_t = 3)]
    pushes: usize,
    /// Scene family: loose, packed or mixed (described above).
    #[arg(long, value_enum, default_value_t = LayoutArg::Loose)]
    layout: LayoutArg,
}

#[derive(Debug, Args)]
struct EvalArgs {
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
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli
        .command
        .unwrap_or_else(|| Command::Demo(DemoArgs::default()))
    {
        Command::Demo(args) => run_demo(&args),
        Command::Eval(args) => run_eval(&args),
        Command::Gen(args) => run_gen(&args),
        Command::Segment(args) => segment(&args),
        Command::Flow(args) => run_flow(&args),
        Command::Bench(args) => run_bench(&args),
        Command::Run(args) => run_recorded(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {}", error_text(&error));
            ExitCode::FAILURE
        }
    }
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

fn run_gen(args: &GenArgs) -> anyhow::Result<()> {
    let GenArgs {
        scenes,
        seed,
        out,
        pushes,
        layout,
    } = args;
    let (scenes, seed, pushes, layout) = (*scenes, *seed, *pushes, layout.layout());
    let bar = ProgressBar::new(scenes as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} scenes  {elapsed}  {msg}")
            .context("progress bar template")?,
    );
    write_dataset(out, scenes, seed, layout, pushes, |i, g| {
        bar.set_message(format!(
            "{}: {} objects, {} pushes",
            scene_dir_name(i),
            g.objects,
            g.pushes.len()
        ));
        bar.inc(1);
    })
    .with_context(|| format!("generating {scenes} {layout} scenes into {}", out.display()))?;
    bar.finish();
    println!(
        "wrote {scenes} {layout} scenes to {}; previews in {}",
        out.display(),
        out.join(PREVIEW_DIR).display()
    );
    Ok(())
}

fn run_demo(args: &DemoArgs) -> anyhow::Result<()> {
    let bar = ProgressBar::new(4).with_style(
        ProgressStyle::with_template("{spinner} {msg} {elapsed}")
            .context("progress bar template")?,
    );
    bar.enable_steady_tick(core::time::Duration::from_millis(120));
    bar.set_message("frame 0: rendering, segmenting");
    let layout = args.layout.layout();
    let seed = args
        .seed
        .unwrap_or_else(|| riseg::cli::demo::default_seed(layout));
    let report = riseg::cli::demo::run_demo(&args.out, seed, layout, |t| {
        bar.set_message(format!(
            "frame {t} done; pushing, rendering frame {}",
            t + 1
        ));
    })
    .with_context(|| format!("demo on simulated {layout} scene {seed}"))?;
    bar.finish_and_clear();
    println!(
        "riseg demo: simulated {layout} scene {}, {} pushes; {}.",
        report.seed,
        report.frames.len().saturating_sub(1),
        riseg::cli::demo::stop_text(&report.stop)
    );
    print!("{}", riseg::cli::demo::table(&report));
    println!(
        "pictures and report: {}",
        args.out.join("report.md").display()
    );
    Ok(())
}

fn run_recorded(args: &RunArgs) -> anyhow::Result<()> {
    let scenes = match (&args.scene, &args.dataset) {
        (Some(scene), _) => vec![scene.clone()],
        (None, Some(dataset)) => {
            let scenes = riseg::io::scene::list_scenes(dataset)?;
            if scenes.is_empty() {
                bail!("{}: no scene_* folders", dataset.display());
            }
            scenes
        }
        (None, None) => bail!("give --scene DIR or --dataset DIR"),
    };
    let mut tracker = Tracker::new(
        ClassicalSegmenter::new(SegmenterParams::default())?,
        DisFlow::new(FlowParams::MEDIUM)?,
        riseg_core::Config::PAPER,
    )?;
    let bar = ProgressBar::new(scenes.len() as u64).with_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} scenes  {elapsed}  eta {eta}  {msg}")
            .context("progress bar template")?,
    );
    let inputs = InputDirs {
        flow: args.flow_dir.clone(),
        statics: args.static_dir.clone(),
    };
    let mut frames = 0;
    for dir in &scenes {
        let name = dir.file_name().unwrap_or(dir.as_os_str()).to_string_lossy();
        frames += run_scene(&mut tracker, dir, &inputs, &args.out, |t| {
            bar.set_message(format!("{name}: frame {t}"));
        })?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    println!(
        "wrote {frames} masks of {} scenes to {}",
        scenes.len(),
        args.out.display()
    );
    Ok(())
}

fn run_bench(args: &BenchArgs) -> anyhow::Result<()> {
    let cfg = BenchConfig {
        layout: args.layout.layout(),
        ..BenchConfig::new(args.scenes, args.seed)
    };
    let bar = ProgressBar::new(args.scenes as u64).with_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} scenes  {elapsed}  eta {eta}  {msg}")
            .context("progress bar template")?,
    );
    let (report, results) = bench::run_bench(&cfg, |r| {
        bar.set_message(format!(
            "scene {}: {} pushes, {:?}",
            r.scene,
            r.times.len().saturating_sub(1),
            r.stop
        ));
        bar.inc(1);
    })?;
    bar.finish_and_clear();
    let refused = results
        .iter()
        .filter(|r| matches!(r.stop, Stop::Refused(_)))
        .count();
    println!(
        "{} {} scenes, seed {}; pushes per scene: {}{}",
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
    );
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
            println!(
                "scene {:>3} (sim seed {:>20}): {}  [{:?}]",
                r.scene,
                r.sim_seed,
                frames.join(" | "),
                r.stop
            );
        }
    }
    print!("{report}");
    if let Some(path) = &args.json {
        let mut json = serde_json::to_vec_pretty(&report).context("encoding the report")?;
        json.push(b'\n');
        write_atomic(path, &json).with_context(|| format!("writing {}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

fn run_eval(args: &EvalArgs) -> anyhow::Result<()> {
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
    let mut segmenter = ClassicalSegmenter::new(SegmenterParams::default())?;
    let report = eval::evaluate(&pairs, || bar.inc(1)).and_then(|mut report| {
        if let DatasetPoses::All(scenes) = &poses {
            let params = CeilingParams::DEFAULT;
            let rows = eval::evaluate_ceiling(scenes, &mut segmenter, &params, || bar.inc(1))?;
            report.ceiling = Some(rows);
        }
        Ok(report)
    });
    bar.finish_and_clear();
    let report = report?;
    if let DatasetPoses::Missing(scene) = &poses {
        eprintln!(
            "motion ceiling not scored: {} has no {}",
            scene.display(),
            scene::POSES_FILE
        );
    }
    print!("{report}");
    if let Some(path) = &args.json {
        report.write_json(path)?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// The camera, colour and depth files of `riseg segment`, from either input form.
fn segment_inputs(args: &SegmentArgs) -> anyhow::Result<(PathBuf, PathBuf, PathBuf)> {
    match (
        &args.scene,
        args.frame,
        &args.rgb,
        &args.depth,
        &args.camera,
    ) {
        (Some(dir), Some(t), None, None, None) => {
            let (rgb, depth) = scene::frame_paths(dir, t);
            Ok((dir.join(scene::CAMERA_FILE), rgb, depth))
        }
        (None, None, Some(rgb), Some(depth), Some(camera)) => {
            Ok((camera.clone(), rgb.clone(), depth.clone()))
        }
        // clap's argument group and `requires` rule the other combinations out.
        _ => bail!("give either --scene DIR --frame T, or --rgb, --depth and --camera"),
    }
}

fn segment(args: &SegmentArgs) -> anyhow::Result<()> {
    let (camera_path, rgb_path, depth_path) = segment_inputs(args)?;
    let camera = SceneCamera::read(&camera_path)?;
    let (width, height) = (camera.width, camera.height);
    let rgb = riseg::io::image::read_rgb8(&rgb_path)?;
    ImageIoError::expect_size(&rgb_path, &rgb, width, height)?;
    let depth = riseg::io::image::read_gray16(&depth_path)?;
    ImageIoError::expect_size(&depth_path, &depth, width, height)?;

    let depth_m: Vec<f32> = depth
        .as_slice()
        .iter()
        .map(|&d| camera.depth_m(d))
        .collect();
    let (w, h) = (width as usize, height as usize);
    let frame = RgbdFrame::new(w, h, rgb.as_slice(), &depth_m)?;
    let mut segmenter = ClassicalSegmenter::new(SegmenterParams {
        seed: args.seed,
        ..SegmenterParams::default()
    })?;
    let out = segmenter
        .segment_detailed(&frame, &camera.intrinsics())
        .with_context(|| format!("segmenting {}", rgb_path.display()))?;
    let seg = &out.segmentation;

    riseg::io::image::write_gray16(
        &args.output,
        &Image::from_vec(width, height, seg.labels.clone())?,
    )?;
    if let Some(path) = &args.heatmap {
        riseg::io::image::write_gray8(path, &Image::from_vec(width, height, seg.heatmap.clone())?)?;
    }
    if let Some(path) = &args.viz {
        let picture = viz::side_by_side(rgb.as_slice(), seg);
        riseg::io::image::write_rgb8(path, &Image::from_vec(3 * width, height, picture)?)?;
    }
    let n = out.plane.normal;
    println!(
        "{} segments; table plane normal ({:.3}, {:.3}, {:.3}), camera {:.3} m above it; \
         labels -> {}",
        seg.segment_count(),
        n.x,
        n.y,
        n.z,
        out.plane.offset_m,
        args.output.display()
    );
    Ok(())
}
