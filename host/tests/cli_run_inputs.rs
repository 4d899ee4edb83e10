//! `riseg run --flow-dir DIR --static-dir DIR`: flow and static segmentation read from files
//! instead of computed. One tiny dataset (`riseg gen --scenes 1 --pushes 1`) is made per
//! test binary and shared; every test writes into its own temporary folder.
//!
//! That a file is really used is shown by equality with the in-memory replay given the same
//! flow, for two flows (the dataset's exact flow and zero flow) whose results differ.

#![allow(
    clippy::unwrap_used,
    reason = "test helpers: a panic is the failure report"
)]

use std::{
    fs,
    path::{Path, PathBuf},
    process::{Command, Output},
    sync::OnceLock,
};

use riseg::{
    cli::run::{InputDirs, replay_scene},
    flow::{DisFlow, FlowParams, UNKNOWN_FLOW_MIN_PX},
    io::image::{FlowImage, Gray8Image, Gray16Image},
    io::scene::{Scene, frame_file},
    rig::tracker::{GivenInputs, TrackError, Tracker},
    rig::workspace::WorkspaceBuf,
    segment::{ClassicalSegmenter, HEAT_CERTAIN, SegmenterParams},
    testkit::SyntheticStep,
};
use riseg_core::{Config, ImageView, frames::MotionInput, pipeline::update_mask};

const SCENE: &str = "scene_000";

fn riseg(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_riseg"))
        .args(args)
        .output()
        .expect("running the riseg binary")
}

fn path_arg(path: &Path) -> &str {
    path.to_str().expect("temporary paths are UTF-8")
}

/// The shared dataset: one scene, two frames, with its exact flow and ground truth.
fn dataset() -> &'static Path {
    static DATASET: OnceLock<PathBuf> = OnceLock::new();
    DATASET.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-run-inputs-dataset");
        let _ = fs::remove_dir_all(&dir);
        let out = riseg(&[
            "gen",
            "--scenes",
            "1",
            "--pushes",
            "1",
            "--seed",
            "1",
            "--out",
            path_arg(&dir),
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        dir
    })
}

fn scene() -> Scene {
    Scene::read(&dataset().join(SCENE)).unwrap()
}

/// `riseg run --scene DATASET/scene_000 --out OUT` plus `extra`.
fn run(out: &Path, extra: &[&str]) -> Output {
    let scene_dir = dataset().join(SCENE);
    let mut args = vec![
        "run",
        "--scene",
        path_arg(&scene_dir),
        "--out",
        path_arg(out),
    ];
    args.extend_from_slice(extra);
    riseg(&args)
}

/// The masks `riseg run` wrote for the scene, by frame.
fn written_masks(out: &Path, frames: usize) -> Vec<Vec<u16>> {
    (0..frames)
        .map(|t| {
            riseg::io::image::read_gray16(&frame_file(&out.join(SCENE), "label", t, "png"))
                .unwrap()
                .into_vec()
        })
        .collect()
}

/// The tracker `riseg run` uses.
fn tracker() -> Tracker<ClassicalSegmenter, DisFlow> {
    Tracker::new(
        ClassicalSegmenter::new(SegmenterParams::default()).unwrap(),
        DisFlow::new(FlowParams::MEDIUM).unwrap(),
        Config::PAPER,
    )
    .unwrap()
}

/// The in-memory replay of the scene with the built-in stages and `flow` given for frame 1.
fn replay_with_flow(scene: &Scene, flow: FlowImage) -> Vec<Vec<u16>> {
    let given = vec![
        GivenInputs::default(),
        GivenInputs {
            flow: Some(flow),
            ..GivenInputs::default()
        },
    ];
    replay_scene(&mut tracker(), scene, given, |_| {}).unwrap()
}

/// A flow folder holding `flow` as the scene's only `.flo`.
fn flow_dir_with(root: &Path, flow: &FlowImage) -> PathBuf {
    let dir = root.join("flows");
    let file = frame_file(&dir.join(SCENE), "flow", 0, "flo");
    fs::create_dir_all(file.parent().unwrap()).unwrap();
    riseg::io::image::write_flo(&file, flow).unwrap();
    dir
}

/// A static folder with the scene's ground-truth labels, so only the file under test is bad.
fn static_dir_with_truth(root: &Path) -> PathBuf {
    let dir = root.join("statics");
    let labels = dir.join(SCENE).join("label");
    fs::create_dir_all(&labels).unwrap();
    for entry in fs::read_dir(dataset().join(SCENE).join("label")).unwrap() {
        let entry = entry.unwrap();
        fs::copy(entry.path(), labels.join(entry.file_name())).unwrap();
    }
    dir
}

/// The run failed with exit code 1, its error names every one of `needles`, and no mask was
/// written.
fn assert_failed_naming(out: &Output, pred: &Path, needles: &[&str]) {
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    for needle in needles {
        assert!(stderr.contains(needle), "{needle:?} not in: {stderr}");
    }
    assert!(
        !pred.join(SCENE).join("label").exists(),
        "masks were written for a failed scene"
    );
}

#[test]
fn flow_dir_at_the_dataset_uses_its_exact_flow() {
    let tmp = tempfile::tempdir().unwrap();
    let pred = tmp.path().join("pred");
    let out = run(&pred, &["--flow-dir", path_arg(dataset())]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let scene = scene();
    let exact = scene.flow.as_ref().unwrap()[0].clone();
    let masks = written_masks(&pred, scene.frames());
    assert_eq!(masks, replay_with_flow(&scene, exact.with_unknown_as_nan()));
}

#[test]
fn a_zero_flow_dir_gives_the_zero_flow_masks_not_the_exact_ones() {
    let scene = scene();
    let (w, h) = (scene.camera.width, scene.camera.height);
    let zero = FlowImage::from_fn(w, h, |_, _| [0.0; 2]);
    let tmp = tempfile::tempdir().unwrap();
    let pred = tmp.path().join("pred");
    let out = run(
        &pred,
        &["--flow-dir", path_arg(&flow_dir_with(tmp.path(), &zero))],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let masks = written_masks(&pred, scene.frames());
    assert_eq!(masks, replay_with_flow(&scene, zero.with_unknown_as_nan()));
    let exact = scene.flow.as_ref().unwrap()[0].clone();
    let with_exact = replay_with_flow(&scene, exact.with_unknown_as_nan());
    assert_eq!(masks[0], with_exact[0], "frame 0 has no flow");
    assert_ne!(masks[1], with_exact[1], "the flow file made no difference");
}

#[test]
fn static_dir_with_the_ground_truth_gives_it_back_at_frame_0() {
    let tmp = tempfile::tempdir().unwrap();
    let pred = tmp.path().join("pred");
    let out = run(
        &pred,
        &[
            "--static-dir",
            path_arg(dataset()),
            "--flow-dir",
            path_arg(dataset()),
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let scene = scene();
    let truth = scene.labels.as_ref().unwrap();
    let masks = written_masks(&pred, scene.frames());
    assert_eq!(masks[0], truth[0].as_slice());
}

#[test]
fn heatmaps_are_read_when_present_and_derived_from_the_labels_otherwise() {
    let scene = scene();
    let (w, h) = (scene.camera.width, scene.camera.height);
    let tmp = tempfile::tempdir().unwrap();
    let statics = static_dir_with_truth(tmp.path());
    // Labels 3 and 7 only: renumbered 1 and 2.
    let sparse = Gray16Image::from_fn(w, h, |x, _| match x % 3 {
        0 => 0,
        1 => 3,
        _ => 7,
    });
    riseg::io::image::write_gray16(
        &frame_file(&statics.join(SCENE), "label", 1, "png"),
        &sparse,
    )
    .unwrap();
    let heat = Gray8Image::from_fn(w, h, |x, y| ((x + y) % 256) as u8);
    let heat_dir = statics.join(SCENE).join("heat");
    fs::create_dir_all(&heat_dir).unwrap();
    riseg::io::image::write_gray8(&heat_dir.join("000000.png"), &heat).unwrap();

    let dirs = InputDirs {
        flow: None,
        statics: Some(statics),
        pushes: false,
    };
    let given = dirs.read_scene(&dataset().join(SCENE), &scene).unwrap();
    assert_eq!(given.len(), 2);
    assert!(given.iter().all(|g| g.flow.is_none()));
    let frame0 = given[0].static_seg.as_ref().unwrap();
    assert_eq!(frame0.labels, scene.labels.as_ref().unwrap()[0]);
    assert_eq!(frame0.heatmap, heat);
    let frame1 = given[1].static_seg.as_ref().unwrap();
    let renumbered: Vec<u16> = sparse
        .as_slice()
        .iter()
        .map(|&l| [0, 0, 0, 1, 0, 0, 0, 2][usize::from(l)])
        .collect();
    assert_eq!(frame1.labels.as_slice(), renumbered.as_slice());
    let derived: Vec<u8> = renumbered
        .iter()
        .map(|&l| if l == 0 { 0 } else { HEAT_CERTAIN })
        .collect();
    assert_eq!(frame1.heatmap.as_slice(), derived.as_slice());
}

#[test]
fn the_tracker_refuses_given_inputs_that_do_not_fit() {
    let scene = scene();
    let (w, h) = (scene.camera.width, scene.camera.height);
    let flow = |w, h| FlowImage::from_vec(w, h, vec![[0.0; 2]; w * h]).unwrap();
    let first = GivenInputs {
        flow: Some(flow(w, h)),
        ..GivenInputs::default()
    };
    let e = replay_scene(&mut tracker(), &scene, vec![first], |_| {}).unwrap_err();
    assert!(matches!(e, (0, TrackError::FlowWithoutPrevious)), "{e:?}");

    let narrow = GivenInputs {
        flow: Some(flow(w - 1, h)),
        ..GivenInputs::default()
    };
    let e = replay_scene(
        &mut tracker(),
        &scene,
        vec![GivenInputs::default(), narrow],
        |_| {},
    )
    .unwrap_err();
    assert!(
        matches!(e, (1, TrackError::GivenSize { what: "flow", got, .. }) if got == (w - 1, h)),
        "{e:?}"
    );
}

#[test]
fn a_16_bit_heatmap_is_refused_naming_it() {
    let scene = scene();
    let tmp = tempfile::tempdir().unwrap();
    let statics = static_dir_with_truth(tmp.path());
    let heat = frame_file(&statics.join(SCENE), "heat", 0, "png");
    fs::create_dir_all(heat.parent().unwrap()).unwrap();
    let (w, h) = (scene.camera.width, scene.camera.height);
    riseg::io::image::write_gray16(&heat, &Gray16Image::from_fn(w, h, |_, _| 200)).unwrap();
    let pred = tmp.path().join("pred");
    let out = run(&pred, &["--static-dir", path_arg(&statics)]);
    assert_failed_naming(
        &out,
        &pred,
        &[
            path_arg(&heat),
            "frame 0: static heatmap",
            "expected 8-bit greyscale PNG, found 16-bit greyscale",
        ],
    );
}

#[test]
fn a_missing_flow_or_label_file_is_named_with_its_scene_and_frame() {
    let tmp = tempfile::tempdir().unwrap();
    let empty = tmp.path().join("empty");
    fs::create_dir_all(&empty).unwrap();
    let pred = tmp.path().join("pred");

    let out = run(&pred, &["--flow-dir", path_arg(&empty)]);
    let flo = frame_file(&empty.join(SCENE), "flow", 0, "flo");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.matches(path_arg(&flo)).count(), 1, "{stderr}");
    assert_failed_naming(
        &out,
        &pred,
        &[
            SCENE,
            "frame 1: flow from the previous frame",
            &format!("{}: file not found", flo.display()),
        ],
    );

    let out = run(&pred, &["--static-dir", path_arg(&empty)]);
    let png = frame_file(&empty.join(SCENE), "label", 0, "png");
    assert_failed_naming(
        &out,
        &pred,
        &[
            SCENE,
            "frame 0: static labels",
            &format!("{}: file not found", png.display()),
        ],
    );
}

#[test]
fn mis_sized_flow_and_labels_are_named_with_both_sizes() {
    let scene = scene();
    let (w, h) = (scene.camera.width, scene.camera.height);
    let tmp = tempfile::tempdir().unwrap();
    let pred = tmp.path().join("pred");

    let small = FlowImage::from_fn(w / 2, h, |_, _| [0.0; 2]);
    let flows = flow_dir_with(tmp.path(), &small);
    let out = run(&pred, &["--flow-dir", path_arg(&flows)]);
    let flo = frame_file(&flows.join(SCENE), "flow", 0, "flo");
    assert_failed_naming(
        &out,
        &pred,
        &[
            path_arg(&flo),
            &format!("expected {w}x{h} pixels, found {}x{h}", w / 2),
        ],
    );

    let statics = static_dir_with_truth(tmp.path());
    let png = frame_file(&statics.join(SCENE), "label", 1, "png");
    riseg::io::image::write_gray16(&png, &Gray16Image::from_fn(w, h + 1, |_, _| 1)).unwrap();
    let out = run(&pred, &["--static-dir", path_arg(&statics)]);
    assert_failed_naming(
        &out,
        &pred,
        &[
            path_arg(&png),
            "frame 1: static labels",
            &format!("expected {w}x{h} pixels, found {w}x{}", h + 1),
        ],
    );
}

#[test]
fn corrupt_flow_and_label_files_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let pred = tmp.path().join("pred");
    let scene = scene();
    let flows = flow_dir_with(
        tmp.path(),
        &FlowImage::from_fn(scene.camera.width, scene.camera.height, |_, _| [0.0; 2]),
    );
    let flo = frame_file(&flows.join(SCENE), "flow", 0, "flo");
    fs::write(&flo, b"PIEH but not a flow").unwrap();
    let out = run(&pred, &["--flow-dir", path_arg(&flows)]);
    assert_failed_naming(
        &out,
        &pred,
        &[path_arg(&flo), "not a valid Middlebury .flo file"],
    );

    let statics = static_dir_with_truth(tmp.path());
    let png = frame_file(&statics.join(SCENE), "label", 0, "png");
    fs::write(&png, b"\x89PNG\r\n\x1a\ntruncated").unwrap();
    let out = run(&pred, &["--static-dir", path_arg(&statics)]);
    assert_failed_naming(&out, &pred, &[path_arg(&png), "corrupt or unsupported PNG"]);
}

/// riseg-core takes nothing from unknown flow, whether it is marked NaN (as
/// `FlowImage::with_unknown_as_nan` does) or left as Middlebury's 1e10: both give one mask.
#[test]
fn unknown_flow_as_nan_or_as_1e10_gives_the_same_mask() {
    let step = SyntheticStep::touching_boxes(640, 480).unwrap();
    let (w, h) = (step.width, step.height);
    // Unknown on every fifth labelled pixel and on a band across all the boxes.
    let unknown: Vec<bool> = (0..w * h)
        .map(|i| step.merged_t[i] != 0 && (i % 5 == 0 || (200..230).contains(&(i / w))))
        .collect();
    let with = |value: [f32; 2]| -> Vec<[f32; 2]> {
        step.flow
            .iter()
            .zip(&unknown)
            .map(|(&f, &u)| if u { value } else { f })
            .collect()
    };
    let raw = with([10.0 * UNKNOWN_FLOW_MIN_PX, -10.0 * UNKNOWN_FLOW_MIN_PX]);
    let nan = FlowImage::from_vec(w, h, raw.clone())
        .unwrap()
        .with_unknown_as_nan();
    assert!(
        nan.as_slice()
            .iter()
            .zip(&unknown)
            .all(|(v, &u)| u == v[0].is_nan())
    );

    let cfg = Config::PAPER;
    let mut buf = WorkspaceBuf::new(&cfg, w, h);
    let mut mask_of = |flow: &[[f32; 2]]| {
        let input = MotionInput::new(
            ImageView::packed(w, h, &step.merged_t).unwrap(),
            ImageView::packed(w, h, &step.depth_t).unwrap(),
            ImageView::packed(w, h, &step.depth_t1).unwrap(),
            ImageView::packed(w, h, flow).unwrap(),
            step.intrinsics,
        )
        .unwrap();
        let mut mask = vec![0u16; w * h];
        let report = update_mask(
            &input,
            &step.static_t1().unwrap(),
            &cfg,
            &mut buf.view(),
            &mut mask,
        )
        .unwrap();
        (mask, report.frames.count, report.grouping.count)
    };
    let from_raw = mask_of(&raw);
    let from_nan = mask_of(nan.as_slice());
    assert_eq!(from_raw, from_nan);
    assert!(from_nan.1 > 0, "no body frame was built");
}
