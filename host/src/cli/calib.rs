//! `riseg calib check`: validates a hand-eye calibration file and prints where the camera
//! and (with `--scene`) the table plane sit in the robot frame, for a sanity check before
//! the first live push.
//!
//! The table plane is the built-in segmenter's fit on one recorded frame (camera frame),
//! moved to the robot frame by the calibration. A correct calibration puts the table level
//! (normal within a few degrees of the robot's +z) at the height the arm touches it.

use std::path::PathBuf;

use anyhow::Context as _;
use clap::{Args, Subcommand};
use nalgebra::{Point3, Vector3};

use crate::{
    cli::config::ConfigArg,
    io::scene::Scene,
    rig::{calib::HandEye, camera::SceneReplay},
    segment::ClassicalSegmenter,
};

/// Tilt of the table normal from the robot's z axis above which the check warns, degrees.
pub const LEVEL_TOLERANCE_DEG: f32 = 5.0;

/// `riseg calib`.
#[derive(Debug, Args)]
pub(in crate::cli) struct CalibArgs {
    #[command(subcommand)]
    action: CalibAction,
}

#[derive(Debug, Subcommand)]
enum CalibAction {
    /// Validate a calibration file and print the camera (and table) in the robot frame.
    Check(CheckArgs),
}

#[derive(Debug, Args)]
struct CheckArgs {
    /// Hand-eye calibration JSON: {"robot_from_camera": [[...4...] x 4]}, metres.
    #[arg(long, value_name = "FILE")]
    calib: PathBuf,
    /// A scene folder recorded by this camera (e.g. `riseg run --live --dry-run`'s): its
    /// table plane is shown in the robot frame.
    #[arg(long, value_name = "DIR")]
    scene: Option<PathBuf>,
    /// Which frame of --scene.
    #[arg(long, default_value_t = 0)]
    frame: usize,
    #[command(flatten)]
    config: ConfigArg,
}

pub(in crate::cli) fn command(args: &CalibArgs) -> anyhow::Result<()> {
    let CalibAction::Check(args) = &args.action;
    let cal = HandEye::read(&args.calib)?;
    let t = cal.robot_from_camera;
    let axis = t.rotation * Vector3::z();
    let down_deg = axis.angle(&-Vector3::z()).to_degrees();
    say!(
        "{}: valid\ncamera at ({:.3}, {:.3}, {:.3}) m in the robot frame, {:.3} m from the base\n\
         optical axis ({:.3}, {:.3}, {:.3}), {down_deg:.1} degrees from straight down\n",
        args.calib.display(),
        t.translation.x,
        t.translation.y,
        t.translation.z,
        t.translation.vector.norm(),
        axis.x,
        axis.y,
        axis.z
    )?;
    let Some(dir) = &args.scene else {
        return Ok(());
    };
    let scene = Scene::read_frames(dir)?;
    let frame = SceneReplay::frame(&scene, args.frame)
        .with_context(|| format!("{}: no frame {}", dir.display(), args.frame))?;
    let settings = args.config.load()?.settings();
    let plane = ClassicalSegmenter::new(settings.segmenter)?
        .segment_detailed(&frame.rgbd()?, &frame.intrinsics)
        .with_context(|| format!("{}, frame {}", dir.display(), args.frame))?
        .plane;
    let normal = t.rotation * plane.normal;
    // Where the optical axis meets the table: camera point s·z with n·p + d = 0.
    let s = -plane.offset_m / plane.normal.z;
    let hit = t * Point3::new(0.0, 0.0, s);
    let tilt_deg = normal.angle(&Vector3::z()).to_degrees();
    say!(
        "table plane: normal ({:.3}, {:.3}, {:.3}) in the robot frame, {tilt_deg:.1} degrees \
         from +z; the camera is {:.3} m above it\n\
         the optical axis meets the table at ({:.3}, {:.3}, {:.3}) m: table height z = {:.3} m \
         (riseg run --live --table-z-m)\n",
        normal.x,
        normal.y,
        normal.z,
        plane.offset_m,
        hit.x,
        hit.y,
        hit.z,
        hit.z
    )?;
    if tilt_deg > LEVEL_TOLERANCE_DEG {
        say!(
            "warning: the table is {tilt_deg:.1} degrees from level in the robot frame (more \
             than {LEVEL_TOLERANCE_DEG}); the calibration's rotation is likely wrong \
             (transposed, or camera_from_robot given as robot_from_camera)\n"
        )?;
    }
    Ok(())
}
