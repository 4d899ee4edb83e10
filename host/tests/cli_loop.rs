//! The loop's commands as a user runs them: `riseg demo`, `riseg bench --json`, `riseg run`.

use std::process::{Command, Output};

fn riseg() -> Command {
    Command::new(env!("CARGO_BIN_EXE_riseg"))
}

/// Runs `cmd` and checks it succeeded (its stderr in the failure message).
fn succeeds(cmd: &mut Command) -> Output {
    let out = cmd.output().expect("run riseg");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

#[test]
fn the_default_command_is_the_demo_and_it_writes_pictures_and_a_report() {
    let dir = tempfile::tempdir().expect("temp dir");
    // Left by an earlier, longer run: replaced (removed); the user's own file stays.
    let earlier = dir.path().join("riseg-demo");
    std::fs::create_dir_all(&earlier).expect("demo folder");
    std::fs::write(earlier.join("frame_9.png"), b"stale").expect("stale frame");
    std::fs::write(earlier.join("notes.txt"), b"mine").expect("user file");
    let out = succeeds(riseg().current_dir(dir.path()));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("| push |"), "{stdout}");
    let demo = dir.path().join("riseg-demo");
    let report = std::fs::read_to_string(demo.join("report.md")).expect("report.md");
    let pictures: Vec<_> = report
        .lines()
        .filter_map(|l| {
            l.strip_prefix("![frame ")?
                .split_once("](")?
                .1
                .strip_suffix(')')
        })
        .collect();
    assert!(!pictures.is_empty(), "{report}");
    // The scene is placed among the 23 scenes of its family: three rows of lowest <=
    // median <= highest objects found.
    assert!(
        report.contains("## This scene among 23 packed scenes"),
        "{report}"
    );
    let spread: Vec<[f64; 3]> = report
        .lines()
        .filter(|l| {
            l.starts_with("| static, push 0")
                || l.starts_with("| RISeg")
                || l.starts_with("| ceiling")
        })
        .map(|l| {
            let cells: Vec<f64> = l.split('|').filter_map(|c| c.trim().parse().ok()).collect();
            [cells[0], cells[1], cells[2]]
        })
        .collect();
    assert_eq!(spread.len(), 3, "{report}");
    for [lo, mid, hi] in spread {
        assert!(lo <= mid && mid <= hi && hi <= 100.0, "{report}");
    }
    for p in &pictures {
        let img = image::open(demo.join(p)).expect("picture").to_rgb8();
        assert_eq!(img.dimensions(), (1280, 960), "{p}");
    }
    assert!(!demo.join("frame_9.png").exists(), "a stale frame stayed");
    assert_eq!(
        std::fs::read(demo.join("notes.txt")).expect("notes"),
        b"mine"
    );
}

#[test]
fn bench_json_has_the_table_one_shape() {
    let dir = tempfile::tempdir().expect("temp dir");
    let json = dir.path().join("bench.json");
    let out = succeeds(
        riseg()
            .args(["bench", "--scenes", "1", "--seed", "4", "--json"])
            .arg(&json),
    );
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&json).expect("json")).expect("valid json");
    for key in ["static", "riseg", "ceiling"] {
        let rows = v[key].as_array().expect("rows");
        assert!(!rows.is_empty(), "{v}");
        assert_eq!(rows[0]["push"], 0);
        assert!(rows[0]["overlap"]["f"].is_number() && rows[0]["objects_f75_pct"].is_number());
    }
    // One share per push index; no push led to frame 0.
    let shares = v["partial_push_share"].as_array().expect("shares");
    assert_eq!(
        shares.len(),
        v["riseg"].as_array().expect("rows").len(),
        "{v}"
    );
    assert!(shares[0].is_null(), "{v}");
    for share in &shares[1..] {
        assert!(
            share.as_f64().is_some_and(|s| (0.0..=1.0).contains(&s)),
            "{v}"
        );
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        stdout
            .matches("pushes that moved part of a merged segment at push ")
            .count(),
        shares.len() - 1,
        "{stdout}"
    );
    let help = riseg()
        .args(["bench", "--help"])
        .output()
        .expect("run riseg");
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(
        help.contains("moved part of a merged segment") && help.contains("partial_push_share"),
        "{help}"
    );
    let timing = v["timing_ms"].as_object().expect("timing");
    for stage in ["segment", "flow", "frames", "twists", "grouping", "mask"] {
        assert!(
            timing[stage].as_f64().is_some_and(|ms| ms >= 0.0),
            "{stage}: {v}"
        );
    }
}

#[test]
fn run_names_a_missing_scene_folder_and_writes_nothing() {
    let dir = tempfile::tempdir().expect("temp dir");
    let missing = dir.path().join("no_such_scene");
    let pred = dir.path().join("pred");
    let out = riseg()
        .args(["run", "--scene"])
        .arg(&missing)
        .arg("--out")
        .arg(&pred)
        .output()
        .expect("run riseg");
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("no_such_scene"), "{stderr}");
    assert!(!pred.exists());
    let neither = riseg()
        .args(["run", "--out"])
        .arg(&pred)
        .output()
        .expect("run");
    assert!(!neither.status.success());
}

#[cfg(not(feature = "rerun"))]
#[test]
fn rerun_without_the_feature_says_how_to_build_it_and_writes_nothing() {
    let dir = tempfile::tempdir().expect("temp dir");
    let rrd = dir.path().join("loop.rrd");
    for command in ["run", "demo"] {
        let mut cmd = riseg();
        cmd.arg(command);
        if command == "run" {
            cmd.arg("--scene").arg(dir.path().join("scene_000"));
        }
        let out = cmd
            .arg("--out")
            .arg(dir.path().join("out"))
            .arg("--rerun")
            .arg(&rrd)
            .output()
            .expect("run riseg");
        assert!(!out.status.success(), "{command}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr.contains("loop.rrd") && stderr.contains("--features rerun"),
            "{command}: {stderr}"
        );
        assert!(!rrd.exists(), "{command}");
    }
}

/// `--rerun` with the feature: an unusable path is an error naming it before anything
/// runs; a command that fails leaves no file; one that succeeds leaves the file alone.
#[cfg(feature = "rerun")]
#[test]
fn rerun_file_is_named_when_unwritable_and_appears_only_when_complete() {
    let dir = tempfile::tempdir().expect("temp dir");
    let listing = || {
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .expect("listing")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    };
    let unwritable = dir.path().join("no_such_folder").join("demo.rrd");
    let out = riseg()
        .arg("demo")
        .arg("--out")
        .arg(dir.path().join("demo"))
        .arg("--rerun")
        .arg(&unwritable)
        .output()
        .expect("run riseg");
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(&unwritable.display().to_string()),
        "{stderr}"
    );
    assert!(listing().is_empty(), "{:?}", listing());

    let failed = riseg()
        .args(["run", "--scene"])
        .arg(dir.path().join("no_such_scene"))
        .arg("--out")
        .arg(dir.path().join("pred"))
        .arg("--rerun")
        .arg(dir.path().join("run.rrd"))
        .output()
        .expect("run riseg");
    assert!(!failed.status.success());
    assert!(listing().is_empty(), "{:?}", listing());

    let rrd = dir.path().join("demo.rrd");
    succeeds(
        riseg()
            .arg("demo")
            .arg("--out")
            .arg(dir.path().join("demo"))
            .arg("--rerun")
            .arg(&rrd),
    );
    assert_eq!(listing(), ["demo", "demo.rrd"]);
    // rerun's stream header, and its stream footer (written when the file is closed: the
    // file was renamed into place after that).
    let bytes = std::fs::read(&rrd).expect("recording");
    assert!(bytes.starts_with(b"RRF2"), "not an .rrd file");
    assert!(bytes.ends_with(b"RRF2FOOT\x01\0\0\0"), "no stream footer");
}
