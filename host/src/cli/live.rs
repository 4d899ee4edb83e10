//! `riseg run --live`: Algorithm 1 on devices, recorded as a scene folder.
//!
//! # Contract
//!
//! - Devices: `--camera sim --robot sim` (the simulator, one shared scene; the same code
//!   path as real devices) or `--camera realsense --robot franka` (features `realsense`,
//!   `franka`; a binary built without one says which feature to build). `--calib FILE` is
//!   the hand-eye calibration ([`HandEye`]), required for real devices; with the simulator
//!   it replaces the simulator's true camera pose.
//! - Output in `--out OUT`: the recording `OUT/scene_live/` (the scene folder format,
//!   written through [`RecordingCamera`], so `riseg run --scene OUT/scene_live` replays it
//!   to the same masks) and the run's masks `OUT/pred/scene_live/label/NNNNNN.png`, the
//!   layout `riseg eval` reads. `OUT/scene_live` must not exist.
//! - Stops: no push qualifies, the push budget, a refused push (never sent), a camera or
//!   robot error, or Ctrl-C (the run ends before the next push; the push in progress, if
//!   any, finishes: the arm's own stop button is the immediate stop). Whatever ended the
//!   run, the frames captured so far are written.
//! - `--dry-run`: captures frame 0, plans and prints its push in the camera and robot
//!   frames, and stops; nothing is sent to the robot (no robot connection is made).

use core::sync::atomic::{AtomicBool, Ordering};
use std::{
    path::{Path, PathBuf},
    sync::Arc,
};

use anyhow::{Context as _, bail};
use clap::{Args, ValueEnum};
use riseg_core::action::Push;

use crate::{
    cli::LayoutArg,
    io::{
        image::{Gray16Image, write_gray16},
        scene::{LABEL_DIR, frame_file_name},
    },
    rig::{
        calib::HandEye,
        camera::Camera,
        episode::{Decision, EpisodeError, EpisodeFrame, run_episode},
        record::RecordingCamera,
        robot::{PushCommand, PushGeometry, PushLimits, Robot, RobotError, RobotSetup},
        tracker::{Settings, Tracker},
    },
    sim::{SimConfig, SimRig, SimScene},
};

/// The recording's folder name in `--out`.
pub const SCENE_NAME: &str = "scene_live";
/// The masks' folder in `--out` (then `SCENE_NAME/label/`).
pub const PRED_DIR: &str = "pred";
/// What `on_frame` returns to end a dry run after its plan.
const DRY_RUN_DONE: &str = "dry run: planned, nothing sent";

/// `--camera`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(in crate::cli) enum CameraKind {
    /// The simulator's renderer.
    Sim,
    /// Intel RealSense D415 (feature `realsense`).
    Realsense,
}

/// `--robot`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(in crate::cli) enum RobotKind {
    /// The simulator's pusher.
    Sim,
    /// Franka Emika Panda over FCI (feature `franka`).
    Franka,
}

/// The `--live` options of `riseg run`.
#[derive(Debug, Clone, Args)]
pub(in crate::cli) struct LiveArgs {
    /// Which camera.
    #[arg(long, value_enum, default_value_t = CameraKind::Sim)]
    camera: CameraKind,
    /// Which robot.
    #[arg(long, value_enum, default_value_t = RobotKind::Sim)]
    robot: RobotKind,
    /// Hand-eye calibration JSON: {"robot_from_camera": 4x4 rows, metres}.
    #[arg(long, value_name = "FILE")]
    calib: Option<PathBuf>,
    /// Plan and print frame 0's push; send nothing.
    #[arg(long)]
    dry_run: bool,
    /// Simulator: scene family.
    #[arg(long, value_enum, default_value_t = LayoutArg::Packed)]
    layout: LayoutArg,
    /// Simulator: scene seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// RealSense: colour and depth size, WIDTHxHEIGHT.
    #[arg(long, value_name = "WxH", default_value = "640x480", value_parser = parse_size)]
    camera_size: (u32, u32),
    /// RealSense: frames per second.
    #[arg(long, default_value_t = 30)]
    camera_fps: u32,
    /// RealSense: fill depth holes (off: filled holes are invented geometry).
    #[arg(long)]
    hole_filling: bool,
    /// Franka: the controller's FCI address.
    #[arg(long, value_name = "HOST", default_value = "172.16.0.2")]
    robot_ip: String,
    /// Franka: the push workspace box in the robot base frame, metres:
    /// XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX.
    #[arg(long, value_name = "BOX", default_value = "0.30,0.70,-0.25,0.25,0.0,0.30", value_parser = parse_box)]
    workspace_m: [f32; 6],
    /// Franka: height of the table top in the robot base frame, metres (`riseg calib check
    /// --scene` measures it).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    table_z_m: f32,
    /// Franka: longest push, approach included, metres.
    #[arg(long, default_value_t = 0.05)]
    max_push_len_m: f32,
}

fn parse_size(text: &str) -> Result<(u32, u32), String> {
    text.split_once('x')
        .and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?)))
        .filter(|&(w, h)| w > 0 && h > 0)
        .ok_or_else(|| format!("expected WIDTHxHEIGHT such as 640x480, got {text:?}"))
}

fn parse_box(text: &str) -> Result<[f32; 6], String> {
    let v: Vec<f32> = text
        .split(',')
        .map(|s| s.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{text:?}: {e}"))?;
    let b: [f32; 6] = v
        .try_into()
        .map_err(|_| format!("expected six numbers XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX, got {text:?}"))?;
    if (0..3).any(|a| b[2 * a] >= b[2 * a + 1] || b[2 * a].is_nan() || b[2 * a + 1].is_nan()) {
        return Err(format!("{text:?}: each minimum must be below its maximum"));
    }
    Ok(b)
}

/// A robot that is never moved: the limits a dry run plans against.
#[derive(Debug)]
struct PlanOnly(PushLimits);

impl Robot for PlanOnly {
    fn limits(&self) -> PushLimits {
        self.0
    }

    fn execute(&mut self, _cmd: &PushCommand) -> Result<(), RobotError> {
        Err(RobotError("dry run: pushes are not sent".into()))
    }
}

/// `riseg run --live` (module docs).
pub(in crate::cli) fn command(
    args: &LiveArgs,
    settings: &Settings,
    out: &Path,
) -> anyhow::Result<()> {
    let calib = args.calib.as_deref().map(HandEye::read).transpose()?;
    match (args.camera, args.robot) {
        (CameraKind::Sim, RobotKind::Sim) => {
            let sim =
                SimScene::with_config(args.seed, SimConfig::D415.with_layout(args.layout.layout()))
                    .with_context(|| format!("building simulated scene {}", args.seed))?;
            let mut rig = SimRig::new(sim);
            if let Some(c) = calib {
                rig.setup.robot_from_camera = c.robot_from_camera;
            }
            if args.dry_run {
                let mut robot = PlanOnly(rig.robot.limits());
                run(&mut rig.camera, &mut robot, &rig.setup, args, settings, out)
            } else {
                run(
                    &mut rig.camera,
                    &mut rig.robot,
                    &rig.setup,
                    args,
                    settings,
                    out,
                )
            }
        }
        (CameraKind::Realsense, RobotKind::Franka) => {
            let Some(calib) = calib else {
                bail!(
                    "--camera realsense --robot franka needs --calib FILE (the hand-eye calibration)"
                );
            };
            real::run_real(args, &calib, settings, out)
        }
        (camera, robot) => bail!(
            "--camera {camera:?} with --robot {robot:?}: the camera and the robot must see one \
             table: sim with sim, or realsense with franka"
        ),
    }
}

impl LiveArgs {
    /// The Franka push limits of these options.
    fn franka_limits(&self) -> PushLimits {
        let b = self.workspace_m;
        PushLimits {
            workspace_min_m: [b[0], b[2], b[4]],
            workspace_max_m: [b[1], b[3], b[5]],
            max_push_len_m: self.max_push_len_m,
        }
    }

    /// How a fingertip-sized tool meets the objects on the real table.
    const fn franka_geometry(&self) -> PushGeometry {
        PushGeometry {
            table_z_m: self.table_z_m,
            approach_m: 0.02,
            min_height_m: 0.01,
        }
    }
}

#[cfg(all(feature = "realsense", feature = "franka"))]
mod real {
    use super::{LiveArgs, PlanOnly, run};
    use crate::rig::{
        calib::HandEye,
        franka::{Franka, FrankaConfig},
        realsense::{RealSense, RealSenseConfig},
        robot::RobotSetup,
        tracker::Settings,
    };

    pub(super) fn run_real(
        args: &LiveArgs,
        calib: &HandEye,
        settings: &Settings,
        out: &std::path::Path,
    ) -> anyhow::Result<()> {
        let (width, height) = args.camera_size;
        let mut camera = RealSense::open(RealSenseConfig {
            width,
            height,
            fps: args.camera_fps,
            hole_filling: args.hole_filling,
            ..RealSenseConfig::default()
        })?;
        let setup = RobotSetup {
            robot_from_camera: calib.robot_from_camera,
            geometry: args.franka_geometry(),
        };
        let limits = args.franka_limits();
        if args.dry_run {
            return run(
                &mut camera,
                &mut PlanOnly(limits),
                &setup,
                args,
                settings,
                out,
            );
        }
        let mut robot = Franka::connect(FrankaConfig::new(&args.robot_ip, limits))?;
        run(&mut camera, &mut robot, &setup, args, settings, out)
    }
}

#[cfg(not(all(feature = "realsense", feature = "franka")))]
mod real {
    use super::LiveArgs;
    use crate::rig::{calib::HandEye, tracker::Settings};

    pub(super) fn run_real(
        args: &LiveArgs,
        _calib: &HandEye,
        _settings: &Settings,
        _out: &std::path::Path,
    ) -> anyhow::Result<()> {
        // Touch what only the real rig uses, so both builds use the same options.
        let _ = (args.franka_limits(), args.franka_geometry());
        let missing: Vec<&str> = [
            (cfg!(feature = "realsense"), "realsense"),
            (cfg!(feature = "franka"), "franka"),
        ]
        .into_iter()
        .filter(|(on, _)| !on)
        .map(|(_, name)| name)
        .collect();
        anyhow::bail!(
            "this riseg was built without the {} feature{}: rebuild with \
             `cargo build --release --features realsense,franka`",
            missing.join(" and "),
            if missing.len() > 1 { "s" } else { "" }
        )
    }
}

/// The loop on `camera` and `robot`, recorded (module docs).
fn run<C: Camera, R: Robot>(
    camera: &mut C,
    robot: &mut R,
    setup: &RobotSetup,
    args: &LiveArgs,
    settings: &Settings,
    out: &Path,
) -> anyhow::Result<()> {
    let scene_dir = out.join(SCENE_NAME);
    if scene_dir.exists() {
        bail!(
            "{} exists; live runs never overwrite a recording",
            scene_dir.display()
        );
    }
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let stop = Arc::new(AtomicBool::new(false));
    // A second Ctrl-C exits at once (registered first: it sees the flag the first set);
    // the first asks the loop to stop before its next push.
    signal_hook::flag::register_conditional_shutdown(
        signal_hook::consts::SIGINT,
        130,
        Arc::clone(&stop),
    )
    .and_then(|_| signal_hook::flag::register(signal_hook::consts::SIGINT, Arc::clone(&stop)))
    .context("installing the Ctrl-C handler")?;
    let mut tracker = Tracker::from_settings(settings)?;
    let mut camera = RecordingCamera::new(camera);
    let mut pushes: Vec<Push> = Vec::new();
    let mut masks: Vec<Vec<u16>> = Vec::new();
    let result = run_episode(
        &mut camera,
        robot,
        &mut tracker,
        setup,
        |f: &EpisodeFrame<'_>| {
            masks.push(f.observation.mask.clone());
            report(f).map_err(|e| format!("{e:#}"))?;
            if let Decision::Push { push, command } = f.decision {
                // The recording keeps the finger's travel, the length the flow's motion
                // hint used, so that a replay gives the same hints (`action_motion_px`).
                pushes.push(Push {
                    length_m: command.length_m,
                    ..push
                });
                if args.dry_run {
                    return Err(DRY_RUN_DONE.into());
                }
            }
            if stop.load(Ordering::Relaxed) {
                return Err("interrupted (Ctrl-C) before the next push".into());
            }
            Ok(())
        },
    );
    let kept = write_recording(&camera, &pushes, &masks, out)?;
    match result {
        Ok(summary) => {
            say!(
                "stopped: {:?} after {} pushes; {kept}\n",
                summary.stop,
                summary.pushes.len()
            )?;
            Ok(())
        }
        Err(EpisodeError::Caller(msg)) if msg == DRY_RUN_DONE => {
            say!("{DRY_RUN_DONE}; {kept}\n")?;
            Ok(())
        }
        Err(e) => Err(anyhow::Error::new(e).context(format!("the live run stopped; {kept}"))),
    }
}

/// One line per frame on standard output.
fn report(f: &EpisodeFrame<'_>) -> anyhow::Result<()> {
    match f.decision {
        Decision::Push { push, command } => say!(
            "frame {}: push from pixel ({:.0}, {:.0}), camera ({:.3}, {:.3}, {:.3}) m; robot \
             start ({:.3}, {:.3}, {:.3}) m, direction ({:.2}, {:.2}, {:.2}), {:.3} m\n",
            f.t,
            push.start_px[0],
            push.start_px[1],
            push.start_cam_m.x,
            push.start_cam_m.y,
            push.start_cam_m.z,
            command.start_robot_m.x,
            command.start_robot_m.y,
            command.start_robot_m.z,
            command.direction_robot.x,
            command.direction_robot.y,
            command.direction_robot.z,
            command.length_m
        ),
        Decision::Stop(stop) => say!("frame {}: stop: {stop:?}\n", f.t),
    }
}

/// Writes the recording and the masks (module docs); returns a sentence saying where.
fn write_recording<C: Camera>(
    camera: &RecordingCamera<C>,
    pushes: &[Push],
    masks: &[Vec<u16>],
    out: &Path,
) -> anyhow::Result<String> {
    let Some(scene) = camera.scene(pushes) else {
        return Ok("no frame was captured, nothing recorded".into());
    };
    let dir = out.join(SCENE_NAME);
    scene.write(&dir)?;
    let label_dir = out.join(PRED_DIR).join(SCENE_NAME).join(LABEL_DIR);
    std::fs::create_dir_all(&label_dir)
        .with_context(|| format!("creating {}", label_dir.display()))?;
    for (t, mask) in masks.iter().enumerate().take(scene.frames()) {
        let image = Gray16Image::from_vec(scene.camera.width, scene.camera.height, mask.clone())?;
        write_gray16(&label_dir.join(frame_file_name(t, "png")), &image)?;
    }
    Ok(format!(
        "recording of {} frames in {}, masks in {}",
        scene.frames(),
        dir.display(),
        label_dir.display()
    ))
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;
    use crate::rig::camera::{CameraError, CameraFrame};

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        live: LiveArgs,
    }

    /// A camera that is unplugged after `frames` captures.
    struct Unplugged<C> {
        inner: C,
        frames: usize,
    }

    impl<C: Camera> Camera for Unplugged<C> {
        fn capture(&mut self) -> Result<CameraFrame, CameraError> {
            if self.frames == 0 {
                return Err(CameraError("test camera: unplugged".into()));
            }
            self.frames -= 1;
            self.inner.capture()
        }
    }

    #[test]
    fn a_camera_lost_after_a_push_ends_the_run_with_its_recording_kept() {
        let args = Cli::parse_from(["live"]).live;
        let mut rig = SimRig::new(SimScene::new(0).unwrap());
        let mut camera = Unplugged {
            inner: &mut rig.camera,
            frames: 1,
        };
        let out = tempfile::tempdir().unwrap();
        let err = run(
            &mut camera,
            &mut rig.robot,
            &rig.setup,
            &args,
            &Settings::default(),
            out.path(),
        )
        .unwrap_err();
        let text = format!("{err:#}");
        assert!(
            text.contains("test camera: unplugged") && text.contains("recording of 1 frames"),
            "{text}"
        );
        // The push after frame 0 was made; the recording holds frame 0 and no action.
        assert_eq!(rig.robot.pushes().len(), 1);
        let scene = crate::io::scene::Scene::read(&out.path().join(SCENE_NAME)).unwrap();
        assert_eq!((scene.frames(), scene.actions.len()), (1, 0));
        assert!(
            out.path()
                .join(PRED_DIR)
                .join(SCENE_NAME)
                .join(LABEL_DIR)
                .join(frame_file_name(0, "png"))
                .exists()
        );
    }
}
