//! `riseg segment`: one RGB-D frame through the built-in classical segmenter or an ONNX
//! model (`--segmenter`).

use std::path::PathBuf;

use crate::cli::config::ConfigArg;
use crate::cli::models::{AnySegmenter, ModelArg, parse_model};
use crate::io::image::{read_gray16, read_rgb8, read_sized};
use crate::io::scene::{self, SceneCamera};
use crate::segment::{RgbdFrame, SegmenterParams, viz};
use anyhow::{Context as _, bail};
use clap::Args;

#[derive(Debug, Args)]
#[command(group(
    clap::ArgGroup::new("input")
        .required(true)
        .args(["scene", "rgb"])
))]
pub(super) struct SegmentArgs {
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
    /// Seed of the table-plane RANSAC (same inputs and seed, same output) [default: 1, or
    /// segmenter.seed of --config].
    #[arg(long)]
    seed: Option<u64>,
    /// Static segmenter: `builtin` (classical, no weights) or PATH.onnx (feature `onnx`;
    /// tensor contract below).
    #[arg(long, value_name = "builtin|PATH.onnx", default_value = "builtin", value_parser = parse_model)]
    segmenter: ModelArg,
    /// Settings file (TOML): its [segmenter] section replaces the segmenter's defaults
    /// (the other sections are checked, not used). See `riseg config --help`.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
}

/// The camera, colour and depth files of `riseg segment`, from either input form.
pub(super) fn segment_inputs(args: &SegmentArgs) -> anyhow::Result<(PathBuf, PathBuf, PathBuf)> {
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

pub(super) fn command(args: &SegmentArgs) -> anyhow::Result<()> {
    let params = ConfigArg::from(args.config.clone())
        .load()?
        .settings()
        .segmenter;
    let (camera_path, rgb_path, depth_path) = segment_inputs(args)?;
    let camera = SceneCamera::read(&camera_path)?;
    let (width, height) = (camera.width, camera.height);
    let rgb = read_sized(&rgb_path, width, height, read_rgb8)?;
    let depth = read_sized(&depth_path, width, height, read_gray16)?;

    let depth_m: Vec<f32> = depth
        .as_slice()
        .iter()
        .map(|&d| camera.depth_m(d))
        .collect();
    if !depth_m
        .iter()
        .any(|&z| riseg_core::image::valid_depth(z).is_some())
    {
        bail!(
            "{}: no depth reading: every pixel is 0 (no return), 65535 (saturated) or \
             beyond {} m",
            depth_path.display(),
            riseg_core::image::MAX_DEPTH_M
        );
    }
    let (w, h) = (width, height);
    let frame = RgbdFrame::new(w, h, rgb.as_slice(), &depth_m)?;
    let mut segmenter = args.segmenter.segmenter(SegmenterParams {
        seed: args.seed.unwrap_or(params.seed),
        ..params
    })?;
    let context = || format!("segmenting {}", rgb_path.display());
    // The built-in segmenter also reports the table plane it found.
    let (seg, plane) = match &mut segmenter {
        AnySegmenter::Builtin(classical) => {
            let out = classical
                .segment_detailed(&frame, &camera.intrinsics())
                .with_context(context)?;
            let (n, offset_m) = (out.plane.normal, out.plane.offset_m);
            let plane = format!(
                "; table plane normal ({:.3}, {:.3}, {:.3}), camera {offset_m:.3} m above it",
                n.x, n.y, n.z
            );
            (out.segmentation, plane)
        }
        #[cfg(feature = "onnx")]
        onnx @ AnySegmenter::Onnx(_) => (
            crate::segment::StaticSegmenter::segment(onnx, &frame, &camera.intrinsics())
                .with_context(context)?,
            String::new(),
        ),
    };
    let seg = &seg;

    // Derived outputs: atomic, not flushed to disk (`Durability`'s contract).
    let derived = crate::io::Durability::Derived;
    crate::io::image::write_gray16_as(&args.output, &seg.labels, derived)?;
    if let Some(path) = &args.heatmap {
        crate::io::image::write_gray8_as(path, &seg.heatmap, derived)?;
    }
    if let Some(path) = &args.viz {
        crate::io::image::write_rgb8_as(path, &viz::side_by_side(&rgb, seg), derived)?;
    }
    say!(
        "{} segments{plane}; labels -> {}\n",
        seg.segment_count(),
        args.output.display()
    )?;
    Ok(())
}
