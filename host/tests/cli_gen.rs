//! `riseg gen` as a user runs it: the scene families on the command line, their help, and
//! the `poses.json` of every scene.

use std::process::Command;

use riseg::io::scene::Scene;

fn riseg() -> Command {
    Command::new(env!("CARGO_BIN_EXE_riseg"))
}

#[test]
fn gen_help_describes_every_scene_family_and_the_poses_file() {
    let out = riseg().args(["gen", "--help"]).output().expect("run riseg");
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    for needle in [
        "--layout",
        "loose   4-6 objects of mixed shapes",
        "packed  4-6 look-alike boxes",
        "mixed   a flush pack of 2-4 look-alike boxes",
        "OUT/scene_000/poses.json",
        "rotation_xyzw",
    ] {
        assert!(
            help.contains(needle),
            "gen --help lacks {needle:?}:\n{help}"
        );
    }
}

#[test]
fn gen_writes_a_packed_scene_with_its_poses_and_refuses_unknown_families() {
    let dir = tempfile::tempdir().expect("temp dir");
    let data = dir.path().join("packed");
    let out = riseg()
        .args([
            "gen", "--layout", "packed", "--scenes", "1", "--pushes", "1",
        ])
        .args(["--seed", "3", "--out"])
        .arg(&data)
        .output()
        .expect("run riseg");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("1 packed scenes"));
    let scene = Scene::read(&data.join("scene_000")).expect("a valid scene folder");
    let poses = scene.poses.expect("poses.json");
    assert_eq!(poses.len(), 2, "one list per frame");
    assert!((4..=6).contains(&poses[0].len()));

    let bad = riseg()
        .args(["gen", "--layout", "stacked", "--out"])
        .arg(dir.path().join("bad"))
        .output()
        .expect("run riseg");
    assert!(!bad.status.success());
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert!(
        stderr.contains("stacked") && stderr.contains("packed"),
        "{stderr}"
    );
}
