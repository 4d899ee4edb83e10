//! `riseg eval` on tiny PNG datasets written into a temporary folder: the binary end to
//! end (table, JSON, errors naming the file) and the library's per-push averaging; and the
//! motion ceiling on a dataset `riseg gen` made, with its own `poses.json` or one written
//! here.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

use riseg::cli::eval::{self, EvalError, EvalReport};
use riseg::io::scene::{POSES_FILE, Scene};

const W: u32 = 24;
const H: u32 = 16;

/// Frame `push` of a scene: two touching rectangles that drift apart by `push` px.
fn frame_labels(push: u32) -> Vec<u16> {
    let mut labels = vec![0u16; (W * H) as usize];
    for y in 3..12 {
        for x in 2..10 {
            labels[(y * W + x) as usize] = 1;
        }
        for x in 10 + push..18 + push {
            labels[(y * W + x) as usize] = 2;
        }
    }
    labels
}

fn write_png16(path: &Path, width: u32, height: u32, labels: Vec<u16>) {
    let folder = path.parent().expect("a label path has a folder");
    std::fs::create_dir_all(folder).expect("creating the label folder");
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(width, height, labels)
        .expect("width · height labels")
        .save(path)
        .expect("writing a 16-bit PNG");
}

fn label_path(root: &Path, scene: &str, push: u32) -> PathBuf {
    root.join(scene)
        .join("label")
        .join(format!("{push:06}.png"))
}

/// `root/scene_000` and `root/scene_001`, frames 0-2 each.
fn write_dataset(root: &Path) {
    for scene in ["scene_000", "scene_001"] {
        for push in 0..3 {
            write_png16(&label_path(root, scene, push), W, H, frame_labels(push));
        }
    }
}

#[test]
fn a_lower_ceiling_floor_separates_motions_the_default_floor_joins() {
    // A pack: the static segmenter merges its look-alike boxes.
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("packed");
    let gen_args = [
        "gen", "--layout", "packed", "--scenes", "1", "--pushes", "1",
    ];
    let out = riseg(
        &[
            &gen_args[..],
            &["--seed", "1", "--out", data.to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let scene = data.join("scene_000");
    let labels = object_labels(&scene);
    // Object l moves 2 cm + 0.7 mm · l: neighbours in label order differ by 0.7 mm, below
    // the default 1 mm floor and above a 0.5 mm one.
    write_poses(&scene, &labels, 2, |l| 0.02 + 0.0007 * f64::from(l));
    let ceiling_at = |floor_mm: Option<&str>| {
        let json = dir.path().join("floor.json");
        let mut args = vec!["eval", "--gt", data.to_str().unwrap(), "--pred"];
        args.extend([data.to_str().unwrap(), "--json", json.to_str().unwrap()]);
        if let Some(mm) = floor_mm {
            args.extend(["--ceiling-floor-mm", mm]);
        }
        let out = riseg(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let report: EvalReport =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        // The report says which floor it was scored at, in the file and the table.
        let floor_m = report.ceiling_floor_m.expect("the ceiling's floor");
        let stdout = String::from_utf8_lossy(&out.stdout);
        let heading = format!("motion ceiling at a {:.2} mm floor", floor_m * 1e3);
        assert!(stdout.contains(&heading), "{heading:?} in {stdout}");
        let want_mm: f32 = floor_mm.unwrap_or("1").parse().unwrap();
        assert!((floor_m * 1e3 - want_mm).abs() < 1e-6, "{floor_m} m");
        report.ceiling.expect("a ceiling")[1].objects_f75_pct
    };
    assert_eq!(
        ceiling_at(Some("0.5")),
        100.0,
        "every motion apart: the ground truth"
    );
    let default = ceiling_at(None);
    assert!(
        default < 100.0,
        "at 1 mm some touching pair stays merged: {default}"
    );
    assert_eq!(ceiling_at(Some("1")), default);
    for bad in ["0", "-1", "nan", "11"] {
        let out = riseg(&[
            "eval",
            "--gt",
            data.to_str().unwrap(),
            "--pred",
            data.to_str().unwrap(),
            &format!("--ceiling-floor-mm={bad}"),
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{bad}");
        assert!(
            stderr.contains("--ceiling-floor-mm") && stderr.contains("millimetres above 0"),
            "{bad}: {stderr}"
        );
    }
}

fn riseg(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_riseg"))
        .args(args)
        .output()
        .expect("running the riseg binary")
}

fn eval_cli(gt: &Path, pred: &Path, json: Option<&Path>) -> Output {
    let mut args = vec![
        "eval".to_owned(),
        "--gt".to_owned(),
        gt.display().to_string(),
        "--pred".to_owned(),
        pred.display().to_string(),
    ];
    if let Some(json) = json {
        args.extend(["--json".to_owned(), json.display().to_string()]);
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    riseg(&args)
}

#[test]
fn a_dataset_against_itself_scores_100_everywhere() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    write_dataset(&data);
    let json = dir.path().join("out").join("metrics.json");
    std::fs::create_dir_all(json.parent().unwrap()).unwrap();

    let out = eval_cli(&data, &data, Some(&json));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");

    let stdout = String::from_utf8_lossy(&out.stdout);
    let rows: Vec<&str> = stdout.lines().skip(2).collect();
    assert_eq!(rows.len(), 3, "{stdout}");
    for (push, row) in rows.iter().enumerate() {
        let fields: Vec<&str> = row.split(['|', ' ']).filter(|s| !s.is_empty()).collect();
        assert_eq!(fields[..2], [push.to_string(), "2".to_owned()], "{row}");
        assert!(fields[2..].iter().all(|f| *f == "100.0"), "{row}");
    }

    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let pushes = report["pushes"].as_array().unwrap();
    assert_eq!(pushes.len(), 3);
    for (n, push) in pushes.iter().enumerate() {
        assert_eq!(push["push"], n);
        assert_eq!(push["images"], 2);
        for key in ["overlap", "boundary"] {
            for prf in ["p", "r", "f"] {
                assert_eq!(push[key][prf], 100.0, "{key}.{prf} of push {n}");
            }
        }
        assert_eq!(push["objects_f75_pct"], 100.0);
    }
    // Without poses.json there is no ceiling, and a note says why.
    assert!(report.get("ceiling").is_none(), "{report}");
    assert!(!stdout.contains("motion ceiling"), "{stdout}");
    assert!(
        stderr.contains("motion ceiling not scored") && stderr.contains("has no poses.json"),
        "{stderr}"
    );
    // Written by rename: no temporary file is left beside the report.
    let names: Vec<_> = std::fs::read_dir(json.parent().unwrap())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["metrics.json"]);
}

#[test]
fn scores_are_averaged_per_push() {
    let dir = tempfile::tempdir().unwrap();
    let (data, pred) = (dir.path().join("data"), dir.path().join("pred"));
    write_dataset(&data);
    write_dataset(&pred);
    // In scene_001, frame 1 predicts nothing: P = 1, R = 0, F = 0, 0 objects detected.
    write_png16(
        &label_path(&pred, "scene_001", 1),
        W,
        H,
        vec![0; (W * H) as usize],
    );

    let pairs = eval::find_frame_pairs(&data, &pred).unwrap();
    assert_eq!(pairs.len(), 6);
    let mut images = 0;
    let report = eval::evaluate(&pairs, || images += 1).unwrap();
    assert_eq!(images, 6);
    let push1 = report.pushes[1];
    assert_eq!((push1.push, push1.images), (1, 2));
    // Mean of a perfect image (100) and the empty prediction.
    assert_eq!(
        (push1.overlap.p, push1.overlap.r, push1.overlap.f),
        (100.0, 50.0, 50.0)
    );
    assert_eq!(push1.objects_f75_pct, 50.0);
    assert_eq!(report.pushes[0].overlap.f, 100.0);
    assert_eq!(report.pushes[2].boundary.f, 100.0);

    let table = report.to_string();
    assert!(table.contains("objects F>75"), "{table}");
    let reread: EvalReport =
        serde_json::from_str(&serde_json::to_string(&report).unwrap()).unwrap();
    assert_eq!(reread, report);
}

/// Runs the CLI on `data` against `pred` and returns its stderr, asserting failure.
fn failing_eval(data: &Path, pred: &Path) -> String {
    let out = eval_cli(data, pred, None);
    assert!(!out.status.success());
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn a_mis_sized_prediction_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let (data, pred) = (dir.path().join("data"), dir.path().join("pred"));
    write_dataset(&data);
    write_dataset(&pred);
    let bad = label_path(&pred, "scene_001", 2);
    write_png16(&bad, W + 1, H, vec![0; ((W + 1) * H) as usize]);

    let stderr = failing_eval(&data, &pred);
    assert!(stderr.contains(&bad.display().to_string()), "{stderr}");
    assert!(
        stderr.contains("25x16 labels, but the ground truth is 24x16"),
        "{stderr}"
    );
}

#[test]
fn a_missing_prediction_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let (data, pred) = (dir.path().join("data"), dir.path().join("pred"));
    write_dataset(&data);
    write_dataset(&pred);
    let gone = label_path(&pred, "scene_000", 1);
    std::fs::remove_file(&gone).unwrap();

    let stderr = failing_eval(&data, &pred);
    assert!(stderr.contains(&gone.display().to_string()), "{stderr}");
    assert!(stderr.contains("missing prediction"), "{stderr}");
}

#[test]
fn an_8_bit_or_corrupt_prediction_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let (data, pred) = (dir.path().join("data"), dir.path().join("pred"));
    write_dataset(&data);
    write_dataset(&pred);
    let eight_bit = label_path(&pred, "scene_000", 0);
    image::GrayImage::new(W, H).save(&eight_bit).unwrap();
    let stderr = failing_eval(&data, &pred);
    assert!(
        stderr.contains(&eight_bit.display().to_string()),
        "{stderr}"
    );
    assert!(
        stderr.contains("expected 16-bit greyscale PNG, found 8-bit greyscale"),
        "{stderr}"
    );

    write_dataset(&pred);
    let corrupt = label_path(&pred, "scene_001", 0);
    std::fs::write(&corrupt, b"\x89PNG\r\n\x1a\nnot really").unwrap();
    let err = eval::evaluate(&eval::find_frame_pairs(&data, &pred).unwrap(), || {}).unwrap_err();
    assert!(
        matches!(&err, EvalError::Image(e) if e.path == corrupt),
        "{err}"
    );
    let stderr = failing_eval(&data, &pred);
    assert!(stderr.contains(&corrupt.display().to_string()), "{stderr}");
    assert!(stderr.contains("corrupt or unsupported PNG"), "{stderr}");
}

#[test]
fn a_dataset_without_scenes_or_labels_is_an_error_naming_the_folder() {
    let dir = tempfile::tempdir().unwrap();
    let err = eval::find_frame_pairs(dir.path(), dir.path()).unwrap_err();
    assert!(matches!(err, EvalError::NoScenes { .. }), "{err}");

    let scene = dir.path().join("scene_000");
    std::fs::create_dir_all(scene.join("rgb")).unwrap();
    let err = eval::find_frame_pairs(dir.path(), dir.path()).unwrap_err();
    assert!(
        matches!(&err, EvalError::NoGroundTruth { scene: s } if *s == scene),
        "{err}"
    );

    let odd = scene.join("label").join("first.png");
    write_png16(&odd, 2, 2, vec![0; 4]);
    let err = eval::find_frame_pairs(dir.path(), dir.path()).unwrap_err();
    assert!(
        matches!(&err, EvalError::BadFrameName { path } if *path == odd),
        "{err}"
    );
}

#[test]
fn eval_help_explains_the_columns_and_the_layout() {
    let out = riseg(&["eval", "--help"]);
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    for needle in [
        "DATASET/scene_000/label/000000.png",
        "PRED/scene_000/label/000000.png",
        "overlap P",
        "boundary P/R",
        "objects F>75",
        "--json",
        "poses.json",
        "\"rotation_xyzw\"",
        "motion ceiling",
    ] {
        assert!(help.contains(needle), "missing {needle:?} in:\n{help}");
    }
}

/// A one-scene, one-push dataset made by `riseg gen` (once per test binary); tests copy it.
fn generated_scene() -> &'static Path {
    static DATASET: OnceLock<PathBuf> = OnceLock::new();
    DATASET.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("eval-cli-ceiling");
        let _ = std::fs::remove_dir_all(&dir);
        let out = riseg(&[
            "gen",
            "--scenes",
            "1",
            "--pushes",
            "1",
            "--seed",
            "5",
            "--out",
            &dir.display().to_string(),
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        dir
    })
}

/// A private copy of the generated dataset under `root`; returns the dataset folder and its
/// scene folder.
fn copy_of_generated(root: &Path) -> (PathBuf, PathBuf) {
    fn copy_dir(from: &Path, to: &Path) {
        std::fs::create_dir_all(to).expect("creating a folder of the copy");
        for entry in std::fs::read_dir(from).expect("listing the generated dataset") {
            let path = entry.expect("a folder entry").path();
            let dest = to.join(path.file_name().expect("an entry has a name"));
            if path.is_dir() {
                copy_dir(&path, &dest);
            } else {
                std::fs::copy(&path, &dest).expect("copying a file");
            }
        }
    }
    let data = root.join("data");
    copy_dir(generated_scene(), &data);
    (data.clone(), data.join("scene_000"))
}

/// The labels of the scene's objects (every frame).
fn object_labels(scene_dir: &Path) -> BTreeSet<u16> {
    let scene = Scene::read(scene_dir).expect("the generated scene reads");
    scene
        .labels
        .expect("the generated scene has labels")
        .iter()
        .flat_map(|l| l.as_slice().iter().copied())
        .filter(|&l| l != 0)
        .collect()
}

/// A poses.json for `frames` frames: object `l` starts at `(0.1 l, 0, 0)` and after push `t`
/// has moved by `step_m(l) · t` along x, unrotated.
fn write_poses(
    scene_dir: &Path,
    labels: &BTreeSet<u16>,
    frames: usize,
    step_m: impl Fn(u16) -> f64,
) {
    let frames: Vec<serde_json::Value> = (0..frames)
        .map(|t| {
            labels
                .iter()
                .map(|&l| {
                    let x = 0.1 * f64::from(l) + step_m(l) * t as f64;
                    serde_json::json!({
                        "label": l,
                        "translation_m": [x, 0.0, 0.02],
                        "rotation_xyzw": [0.0, 0.0, 0.0, 1.0],
                    })
                })
                .collect()
        })
        .collect();
    let json = serde_json::json!({ "frames": frames });
    std::fs::write(scene_dir.join(POSES_FILE), json.to_string()).expect("writing poses.json");
}

#[test]
fn a_generated_dataset_has_a_ceiling_from_its_own_poses_and_none_without_them() {
    let dir = tempfile::tempdir().unwrap();
    let (data, scene) = copy_of_generated(dir.path());
    assert!(scene.join(POSES_FILE).is_file(), "riseg gen writes poses");
    let json = dir.path().join("metrics.json");
    let out = eval_cli(&data, &data, Some(&json));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(!stderr.contains("not scored"), "{stderr}");
    let report: EvalReport =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let ceiling = report.ceiling.as_ref().expect("a ceiling in the JSON");
    let pushes: Vec<_> = ceiling.iter().map(|row| (row.push, row.images)).collect();
    assert_eq!(pushes, [(0, 1), (1, 1)], "{report:?}");

    // Without poses.json there is no ceiling, and a note names the scene.
    std::fs::remove_file(scene.join(POSES_FILE)).unwrap();
    let out = eval_cli(&data, &data, Some(&json));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "motion ceiling not scored: {} has no poses.json",
            scene.display()
        )),
        "{stderr}"
    );
    let report: EvalReport =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(report.ceiling.is_none(), "{report:?}");
    assert_eq!(
        eval::dataset_poses(&data).unwrap(),
        eval::DatasetPoses::Missing(scene.clone())
    );
    // Asked anyway, the ceiling names the missing file.
    let mut segmenter = riseg::segment::ClassicalSegmenter::new(Default::default()).unwrap();
    let e = eval::evaluate_ceiling(
        core::slice::from_ref(&scene),
        &mut segmenter,
        &riseg::eval::ceiling::CeilingParams::DEFAULT,
        || {},
    )
    .unwrap_err()
    .to_string();
    assert_eq!(
        e,
        format!("{}: not found", scene.join(POSES_FILE).display())
    );
}

#[test]
fn with_poses_eval_scores_the_motion_ceiling_beside_the_pushes() {
    let dir = tempfile::tempdir().unwrap();
    let (data, scene) = copy_of_generated(dir.path());
    let labels = object_labels(&scene);
    assert!(labels.len() >= 4, "{labels:?}");
    // The push moves every object differently (object l by l cm): after it, nothing can
    // stay merged, so the ceiling of frame 1 is the ground truth itself.
    write_poses(&scene, &labels, 2, |l| 0.01 * f64::from(l));
    let json = dir.path().join("metrics.json");

    let out = eval_cli(&data, &data, Some(&json));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("motion ceiling"), "{stdout}");
    assert!(
        stdout.contains("prediction / ceiling, objects F>75 at push 1: 1.000"),
        "{stdout}"
    );

    let report: EvalReport =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let ceiling = report.ceiling.as_ref().expect("a ceiling in the JSON");
    assert_eq!(ceiling.len(), 2, "{report:?}");
    assert_eq!((ceiling[0].push, ceiling[0].images), (0, 1));
    let after = ceiling[1];
    assert_eq!((after.push, after.images), (1, 1));
    for v in [
        after.overlap.p,
        after.overlap.r,
        after.boundary.f,
        after.objects_f75_pct,
    ] {
        assert_eq!(v, 100.0, "{after:?}");
    }

    // When every object moves alike, the push reveals nothing: frame 1's ceiling can only
    // keep or lose what frame 0's had merged, never split more than the distinct case.
    write_poses(&scene, &labels, 2, |_| 0.02);
    let out = eval_cli(&data, &data, None);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let pairs = eval::find_frame_pairs(&data, &data).unwrap();
    let poses = match eval::dataset_poses(&data).unwrap() {
        eval::DatasetPoses::All(scenes) => scenes,
        eval::DatasetPoses::Missing(s) => panic!("{} has no poses", s.display()),
    };
    assert_eq!(pairs.len(), 2);
    let mut segmenter = riseg::segment::ClassicalSegmenter::new(Default::default()).unwrap();
    let mut frames = 0;
    let alike = eval::evaluate_ceiling(
        &poses,
        &mut segmenter,
        &riseg::eval::ceiling::CeilingParams::DEFAULT,
        || frames += 1,
    )
    .unwrap();
    assert_eq!(frames, 2);
    assert_eq!(
        alike[0], ceiling[0],
        "frame 0 does not depend on the motions"
    );
    assert!(alike[1].objects_f75_pct <= after.objects_f75_pct);
}

#[test]
fn a_malformed_or_mismatched_poses_json_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let (data, scene) = copy_of_generated(dir.path());
    let poses = scene.join(POSES_FILE);
    let labels = object_labels(&scene);

    let expect_error = |says: &str| {
        let out = eval_cli(&data, &data, None);
        assert!(!out.status.success());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(&poses.display().to_string()), "{stderr}");
        assert!(stderr.contains(says), "{stderr} should say {says}");
    };
    std::fs::write(
        &poses,
        r#"{"frames": [[{"label": 1, "translation_m": [0, 0], "rotation_xyzw": [0, 0, 0, 1]}]]}"#,
    )
    .unwrap();
    expect_error("malformed JSON");

    write_poses(&scene, &labels, 1, |_| 0.0);
    expect_error("1 frames of poses, expected 2");

    let first = *labels.first().unwrap();
    let fewer: BTreeSet<u16> = labels.iter().copied().filter(|&l| l != first).collect();
    write_poses(&scene, &fewer, 2, |_| 0.0);
    expect_error(&format!(
        "frame 0: object {first} is in the ground truth but has no pose"
    ));
}
