//! The `riseg` command line.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use clap::{Args, Parser, Subcommand};
use riseg::segment::{
    ClassicalSegmenter, RgbdFrame, SegmenterParams,
    files::{self, FileError},
    viz,
};

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
    ///
    /// Needs the simulator, built-in segmenter and flow, which later releases add; until
    /// then this command says so and exits with an error.
    Demo,
    /// Segment one RGB-D frame with the built-in classical segmenter (no model weights)
    ///
    /// Fits the table plane, keeps what stands on it, grows regions over depth and normal
    /// continuity, and writes 16-bit instance labels (0 = background, 1..n = segments by
    /// decreasing area) and, if asked, the 8-bit heatmap FindAction uses: >= 150 surely
    /// inside one object, 120-149 where objects touch or depth is unsure, < 120 the table.
    ///
    /// Example:
    ///   riseg segment --rgb rgb/000000.png --depth depth/000000.png \
    ///     --camera scene_camera.json -o labels.png --heatmap heat.png --viz check.png
    ///
    /// scene_camera.json: {"width": 640, "height": 480, "fx": 615.0, "fy": 615.0,
    /// "cx": 319.5, "cy": 239.5, "depth_unit_m": 0.001}
    #[command(verbatim_doc_comment)]
    Segment(SegmentArgs),
}

#[derive(Debug, Args)]
struct SegmentArgs {
    /// Colour image: 8-bit RGB PNG (an alpha channel is ignored).
    #[arg(long, value_name = "PNG")]
    rgb: PathBuf,
    /// Depth image aligned to the colour image: 16-bit greyscale PNG in the camera file's
    /// `depth_unit_m` units (usually millimetres), 0 = no reading.
    #[arg(long, value_name = "PNG")]
    depth: PathBuf,
    /// Camera file (scene_camera.json): width, height, fx, fy, cx, cy (pixels) and
    /// depth_unit_m (metres per depth unit).
    #[arg(long, value_name = "JSON")]
    camera: PathBuf,
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

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command.unwrap_or(Command::Demo) {
        Command::Demo => anyhow::bail!(
            "the demo is not built yet: it needs the simulator, the built-in segmenter and \
             flow (see README.md, 'State of each part'); riseg-core's algorithm is usable as a \
             library today"
        ),
        Command::Segment(args) => segment(&args),
    }
}

fn check_size(path: &Path, expected: (u32, u32), found: (u32, u32)) -> Result<(), FileError> {
    if expected == found {
        Ok(())
    } else {
        Err(FileError::wrong_size(path, expected, found))
    }
}

fn segment(args: &SegmentArgs) -> anyhow::Result<()> {
    let camera = files::read_scene_camera(&args.camera)?;
    let rgb = files::read_rgb8(&args.rgb)?;
    let depth = files::read_gray16(&args.depth)?;
    let size = (camera.width, camera.height);
    check_size(&args.rgb, size, rgb.size())?;
    check_size(&args.depth, size, depth.size())?;

    let depth_m: Vec<f32> = depth
        .pixels
        .iter()
        .map(|&d| f32::from(d) * camera.depth_unit_m)
        .collect();
    let (w, h) = (camera.width as usize, camera.height as usize);
    let frame = RgbdFrame::new(w, h, &rgb.pixels, &depth_m)?;
    let intrinsics = camera
        .intrinsics()
        .with_context(|| format!("{}: invalid intrinsics", args.camera.display()))?;
    let mut segmenter = ClassicalSegmenter::new(SegmenterParams {
        seed: args.seed,
        ..SegmenterParams::default()
    })?;
    let out = segmenter
        .segment_detailed(&frame, &intrinsics)
        .with_context(|| format!("segmenting {}", args.rgb.display()))?;
    let seg = &out.segmentation;

    files::write_gray16(&args.output, camera.width, camera.height, &seg.labels)?;
    if let Some(path) = &args.heatmap {
        files::write_gray8(path, camera.width, camera.height, &seg.heatmap)?;
    }
    if let Some(path) = &args.viz {
        let picture = viz::side_by_side(&rgb.pixels, seg);
        files::write_rgb8(path, 3 * camera.width, camera.height, &picture)?;
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
