//! `riseg run --live` on the simulator (the same code path as real devices) and `riseg
//! calib check`: the recording replays to the run's own masks, a dry run sends nothing, and
//! wrong device choices, missing features and bad calibrations are clear errors.

#![allow(
    clippy::unwrap_used,
    reason = "test helpers: a panic is the failure report"
)]

use std::{
    fs,
    path::Path,
    process::{Command, Output},
};

use riseg::{io::scene::Scene, sim::SimScene};

fn riseg(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_riseg"))
        .args(args)
        .output()
        .expect("running the riseg binary")
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn labels(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<_> = fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    files.sort();
    files
}

/// The simulator camera's true pose as a calibration file.
fn sim_calibration(path: &Path) {
    let pose = SimScene::new(0)
        .unwrap()
        .world_from_camera()
        .to_homogeneous();
    let rows: Vec<Vec<f32>> = (0..4)
        .map(|r| (0..4).map(|c| pose[(r, c)]).collect())
        .collect();
    fs::write(
        path,
        serde_json::json!({ "robot_from_camera": rows }).to_string(),
    )
    .unwrap();
}

#[test]
fn a_live_simulated_run_is_recorded_and_its_replay_gives_the_same_masks() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("live");
    let o = riseg(&[
        "run",
        "--live",
        "--camera",
        "sim",
        "--robot",
        "sim",
        "--seed",
        "0",
        "--out",
        out.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    assert!(stdout.contains("frame 0: push from pixel"), "{stdout}");
    assert!(stdout.contains("recording of"), "{stdout}");
    let scene = Scene::read(&out.join("scene_live")).unwrap();
    assert!(scene.frames() >= 2, "at least one push: {stdout}");
    assert_eq!(scene.actions.len(), scene.frames() - 1);
    assert!(
        scene.labels.is_some() && scene.poses.is_some(),
        "the simulator's truth is kept"
    );

    let replay = tmp.path().join("replay");
    let o = riseg(&[
        "run",
        "--scene",
        out.join("scene_live").to_str().unwrap(),
        "--out",
        replay.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{:?}", text(&o));
    let live = labels(&out.join("pred/scene_live/label"));
    assert_eq!(live.len(), scene.frames());
    assert_eq!(
        live,
        labels(&replay.join("scene_live/label")),
        "replay equals the live run"
    );

    // A second run never overwrites the recording.
    let o = riseg(&["run", "--live", "--out", out.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o).1.contains("never overwrite"), "{:?}", text(&o));
}

#[test]
fn a_dry_run_plans_and_prints_one_push_and_moves_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("dry");
    let o = riseg(&[
        "run",
        "--live",
        "--dry-run",
        "--seed",
        "0",
        "--out",
        out.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    assert!(
        stdout.contains("frame 0: push from pixel") && stdout.contains("robot start"),
        "{stdout}"
    );
    assert!(
        stdout.contains("dry run: planned, nothing sent"),
        "{stdout}"
    );
    let scene = Scene::read(&out.join("scene_live")).unwrap();
    assert_eq!((scene.frames(), scene.actions.len()), (1, 0));
}

#[test]
fn device_choices_and_missing_features_are_clear_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("x");
    let o = riseg(&[
        "run",
        "--live",
        "--camera",
        "realsense",
        "--robot",
        "sim",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(
        text(&o)
            .1
            .contains("sim with sim, or realsense with franka"),
        "{:?}",
        text(&o)
    );
    let o = riseg(&[
        "run",
        "--live",
        "--camera",
        "realsense",
        "--robot",
        "franka",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(text(&o).1.contains("needs --calib FILE"), "{:?}", text(&o));
    let cal = tmp.path().join("cal.json");
    sim_calibration(&cal);
    let o = riseg(&[
        "run",
        "--live",
        "--camera",
        "realsense",
        "--robot",
        "franka",
        "--calib",
        cal.to_str().unwrap(),
        "--dry-run",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let stderr = text(&o).1;
    if cfg!(all(feature = "realsense", feature = "franka")) {
        // Built with the drivers: no librealsense2 here (or the stand-in's path is unset).
        assert!(stderr.contains("RealSense"), "{stderr}");
    } else {
        assert!(
            stderr.contains("built without the") && stderr.contains("--features realsense,franka"),
            "{stderr}"
        );
    }
}

#[test]
fn calib_check_places_the_camera_and_the_table_in_the_robot_frame() {
    let tmp = tempfile::tempdir().unwrap();
    let cal = tmp.path().join("cal.json");
    sim_calibration(&cal);
    let out = tmp.path().join("dry");
    assert!(
        riseg(&["run", "--live", "--dry-run", "--out", out.to_str().unwrap()])
            .status
            .success()
    );
    let o = riseg(&[
        "calib",
        "check",
        "--calib",
        cal.to_str().unwrap(),
        "--scene",
        out.join("scene_live").to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    assert!(
        stdout.contains("valid") && stdout.contains("camera at"),
        "{stdout}"
    );
    // The simulator's table is z = 0 and level.
    let z: f32 = stdout
        .split("table height z = ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    assert!(z.abs() < 0.01, "{stdout}");
    assert!(!stdout.contains("warning"), "{stdout}");

    fs::write(
        &cal,
        r#"{"robot_from_camera": [[1,0,0,500],[0,1,0,0],[0,0,1,600],[0,0,0,1]]}"#,
    )
    .unwrap();
    let o = riseg(&["calib", "check", "--calib", cal.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    let stderr = text(&o).1;
    assert!(
        stderr.contains("cal.json") && stderr.contains("millimetres"),
        "{stderr}"
    );
}
