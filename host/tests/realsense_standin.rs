//! The RealSense driver against a C stand-in for the librealsense2 API subset it calls
//! (`tests/standin/librealsense2_standin.c`), compiled here with the system's `cc` into
//! shared libraries the driver loads as it would librealsense2: frames and intrinsics
//! arrive exactly, missing library, wrong library and no device are distinct errors, and an
//! unplugged camera mid-stream stops the loop with a clear error.

#![allow(
    clippy::unwrap_used,
    reason = "test helpers: a panic is the failure report"
)]

use std::path::{Path, PathBuf};
use std::process::Command;

use riseg::rig::{
    camera::Camera,
    episode::{EpisodeError, run_episode},
    realsense::{RealSense, RealSenseConfig, RealSenseError},
    record::RecordingCamera,
    robot::{PushCommand, PushGeometry, PushLimits, Robot, RobotError, RobotSetup},
    tracker::{Settings, Tracker},
};
use riseg_core::Pose;

/// Compiles the stand-in with `defines` into `dir/name.so`.
fn standin(dir: &Path, name: &str, defines: &[&str]) -> PathBuf {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/standin/librealsense2_standin.c");
    let out = dir.join(format!("{name}.so"));
    let status = Command::new("cc")
        .args(["-shared", "-fPIC", "-O1", "-Wall", "-Werror", "-o"])
        .arg(&out)
        .args(defines)
        .arg(&src)
        .status()
        .expect("a C compiler `cc` on PATH (Debian: apt-get install gcc)");
    assert!(status.success(), "cc failed on {}", src.display());
    out
}

fn config(library: PathBuf) -> RealSenseConfig {
    RealSenseConfig {
        library: Some(library),
        width: 64,
        height: 48,
        fps: 30,
        warmup_frames: 2,
        settle_frames: 1,
        ..RealSenseConfig::default()
    }
}

/// The stand-in's content of frameset `k` (see the C file): colour and depth in metres.
fn expected(x: usize, y: usize, k: usize) -> ([u8; 3], f32) {
    let rgb = [(x + k) as u8, y as u8, (x * y + 7 * k) as u8];
    let raw = if x == 1 { 0 } else { 300 + x + 2 * y + k };
    (rgb, raw as f32 * 0.001f32)
}

#[test]
fn frames_arrive_aligned_exactly_with_the_colour_intrinsics() {
    let dir = tempfile::tempdir().unwrap();
    let mut cam = RealSense::open(config(standin(dir.path(), "ok", &[]))).unwrap();
    // Warm-up took framesets 1 and 2; each capture drops one settle frameset first.
    for k in [4, 6] {
        let f = cam.capture().unwrap();
        assert_eq!(f.size(), (64, 48));
        assert_eq!(
            (
                f.intrinsics.fx,
                f.intrinsics.fy,
                f.intrinsics.cx,
                f.intrinsics.cy
            ),
            (615.5, 616.25, 31.625, 24.125)
        );
        for y in 0..48 {
            for x in 0..64 {
                let (rgb, depth_m) = expected(x, y, k);
                assert_eq!(
                    f.rgb.as_slice()[y * 64 + x],
                    rgb,
                    "colour ({x}, {y}) of frameset {k}"
                );
                // Aligned: unaligned stand-in depth is 10 m off.
                assert_eq!(
                    f.depth_m.as_slice()[y * 64 + x],
                    depth_m,
                    "depth ({x}, {y})"
                );
            }
        }
        assert!(f.truth.is_none() && f.truth_poses.is_none());
    }
}

#[test]
fn hole_filling_is_off_by_default_and_fills_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let lib = standin(dir.path(), "holes", &[]);
    let mut plain = RealSense::open(config(lib.clone())).unwrap();
    assert_eq!(plain.capture().unwrap().depth_m.as_slice()[1], 0.0);
    drop(plain);
    let mut filled = RealSense::open(RealSenseConfig {
        hole_filling: true,
        ..config(lib)
    })
    .unwrap();
    assert_eq!(
        filled.capture().unwrap().depth_m.as_slice()[1],
        4242.0 * 0.001f32
    );
}

#[test]
fn missing_library_wrong_library_and_no_device_are_distinct_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let missing = RealSense::open(config(dir.path().join("librealsense2.so"))).unwrap_err();
    assert!(
        matches!(missing, RealSenseError::LibraryMissing { .. }),
        "{missing:?}"
    );
    let text = missing.to_string();
    assert!(
        text.contains("librealsense2 not found") && text.contains("RISEG_REALSENSE_LIB"),
        "{text}"
    );

    let other = dir.path().join("other.c");
    std::fs::write(&other, "int not_librealsense(void) { return 0; }\n").unwrap();
    let other_so = dir.path().join("other.so");
    assert!(
        Command::new("cc")
            .args(["-shared", "-fPIC", "-o"])
            .arg(&other_so)
            .arg(&other)
            .status()
            .unwrap()
            .success()
    );
    let wrong = RealSense::open(config(other_so)).unwrap_err();
    assert!(wrong.to_string().contains("has no rs2_"), "{wrong}");

    let none = RealSense::open(config(standin(
        dir.path(),
        "nodev",
        &["-DSTANDIN_DEVICES=0"],
    )))
    .unwrap_err();
    assert!(matches!(none, RealSenseError::NoDevice { .. }), "{none:?}");
    assert!(none.to_string().contains("no device connected"), "{none}");

    let bad_size = RealSense::open(RealSenseConfig {
        width: 0,
        ..config(PathBuf::from("x"))
    })
    .unwrap_err();
    assert!(bad_size.to_string().contains("width 0"), "{bad_size}");
}

#[test]
fn unplugging_mid_stream_is_a_clear_camera_error() {
    let dir = tempfile::tempdir().unwrap();
    // Framesets 1-2 warm up, 3-4 serve the first capture, then the camera is gone.
    let mut cam = RealSense::open(config(standin(
        dir.path(),
        "unplug",
        &["-DSTANDIN_FAIL_AFTER=4"],
    )))
    .unwrap();
    cam.capture().unwrap();
    let err = cam.capture().unwrap_err().to_string();
    for needle in [
        "RealSense",
        "rs2_pipeline_wait_for_frames",
        "Frame didn't arrive",
        "unplugged",
    ] {
        assert!(err.contains(needle), "{needle}: {err}");
    }
}

/// A robot that must never move.
struct Frozen;

impl Robot for Frozen {
    fn limits(&self) -> PushLimits {
        PushLimits {
            workspace_min_m: [0.0; 3],
            workspace_max_m: [1.0; 3],
            max_push_len_m: 0.05,
        }
    }

    fn execute(&mut self, cmd: &PushCommand) -> Result<(), RobotError> {
        panic!("no push may be sent after the camera is lost: {cmd:?}");
    }
}

#[test]
fn a_camera_lost_before_the_first_frame_stops_the_loop_without_a_push() {
    let dir = tempfile::tempdir().unwrap();
    let cam = RealSense::open(config(standin(
        dir.path(),
        "gone",
        &["-DSTANDIN_FAIL_AFTER=2"],
    )))
    .unwrap();
    let mut cam = RecordingCamera::new(cam);
    let mut tracker = Tracker::from_settings(&Settings::default()).unwrap();
    let setup = RobotSetup {
        robot_from_camera: Pose::identity(),
        geometry: PushGeometry {
            table_z_m: 0.0,
            approach_m: 0.02,
            min_height_m: 0.01,
        },
    };
    let err = run_episode(&mut cam, &mut Frozen, &mut tracker, &setup, |_| Ok(())).unwrap_err();
    assert!(matches!(err, EpisodeError::Camera(_)), "{err:?}");
    assert!(err.to_string().contains("unplugged"), "{err}");
    assert_eq!(cam.frames(), 0);
    assert!(cam.scene(&[]).is_none());
}

/// `riseg run --live` with the stand-in as librealsense2: a camera lost at the first
/// capture ends the run with exit code 1, an error naming the camera, and nothing recorded.
#[cfg(all(feature = "cli", feature = "franka"))]
#[test]
fn riseg_run_live_stops_cleanly_when_the_camera_is_lost() {
    let dir = tempfile::tempdir().unwrap();
    let lib = standin(dir.path(), "cli_gone", &["-DSTANDIN_FAIL_AFTER=30"]);
    let cal = dir.path().join("cal.json");
    std::fs::write(
        &cal,
        r#"{"robot_from_camera": [[1, 0, 0, 0.5], [0, -1, 0, 0], [0, 0, -1, 0.6], [0, 0, 0, 1]]}"#,
    )
    .unwrap();
    let out = dir.path().join("rig");
    let o = Command::new(env!("CARGO_BIN_EXE_riseg"))
        .args([
            "run",
            "--live",
            "--camera",
            "realsense",
            "--robot",
            "franka",
            "--dry-run",
        ])
        .arg("--calib")
        .arg(&cal)
        .arg("--out")
        .arg(&out)
        .env("RISEG_REALSENSE_LIB", &lib)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    for needle in [
        "the live run stopped",
        "nothing recorded",
        "RealSense",
        "unplugged",
    ] {
        assert!(stderr.contains(needle), "{needle}: {stderr}");
    }
    assert!(!out.join("scene_live").exists());
}
