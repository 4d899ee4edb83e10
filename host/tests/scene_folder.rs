//! The scene folder reader and writer: round trip, and every kind of bad folder gives an
//! error whose message names the file at fault; read from memory, the same folder gives
//! the same scene or the same message.

#![allow(
    clippy::unwrap_used,
    reason = "test helpers: a panic is the failure report"
)]

use std::{
    fs,
    path::{Path, PathBuf},
};

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use riseg::{
    io::files::MemoryFiles,
    io::image::{FlowImage, Gray16Image, RgbImage, write_gray16},
    io::scene::{ObjectPose, PushAction, Scene, SceneCamera, SceneError, list_scenes},
    rig::camera::SceneReplay,
};
use riseg_core::Pose;

const W: usize = 8;
const H: usize = 6;

/// A valid 3-frame scene (2 pushes) with labels, flow and the poses of two objects.
fn small_scene() -> Scene {
    let frames = 3;
    Scene {
        camera: SceneCamera {
            width: W,
            height: H,
            fx: 615.0,
            fy: 615.0,
            cx: 3.5,
            cy: 2.5,
            depth_unit_m: 0.001,
        },
        rgb: (0..frames)
            .map(|t| RgbImage::from_fn(W, H, |x, y| [x as u8 * 20, y as u8 * 30, t as u8]))
            .collect(),
        depth: (0..frames)
            .map(|t| Gray16Image::from_fn(W, H, |x, _| if x == 0 { 0 } else { 600 + t as u16 }))
            .collect(),
        labels: Some(
            (0..frames)
                .map(|_| Gray16Image::from_fn(W, H, |x, _| u16::from(x > 3)))
                .collect(),
        ),
        flow: Some(
            (0..frames - 1)
                .map(|t| FlowImage::from_fn(W, H, |x, _| [x as f32 * 0.1, t as f32]))
                .collect(),
        ),
        actions: (1..frames as u32)
            .map(|push| PushAction {
                push,
                start_px: [4.0, 3.0],
                start_cam_m: [0.0, 0.0, 0.6],
                direction_cam: [1.0, 0.0, 0.0],
                length_m: 0.02,
            })
            .collect(),
        poses: Some(
            (0..frames)
                .map(|t| {
                    (1..=2_u16)
                        .map(|label| ObjectPose {
                            label,
                            world_from_object: Pose::from_parts(
                                Translation3::new(0.01 * t as f32, -0.05 * f32::from(label), 0.02),
                                UnitQuaternion::from_axis_angle(
                                    &Vector3::z_axis(),
                                    0.3 * t as f32 + f32::from(label),
                                ),
                            ),
                        })
                        .collect()
                })
                .collect(),
        ),
    }
}

/// A fresh folder under Cargo's scratch space for integration tests.
fn temp_root(tag: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("scene-folder-{tag}"));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

/// Every file below `dir`, in memory under the same paths.
fn in_memory(dir: &Path) -> MemoryFiles {
    fn add(files: &mut MemoryFiles, dir: &Path) {
        for entry in fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                add(files, &path);
            } else {
                files.insert(path.clone(), fs::read(&path).unwrap());
            }
        }
    }
    let mut files = MemoryFiles::new();
    add(&mut files, dir);
    files
}

#[test]
fn scene_round_trips_and_is_written_atomically() {
    let root = temp_root("roundtrip");
    let scene = small_scene();
    let dir = root.join("scene_000");
    scene.write(&dir).unwrap();
    assert_eq!(Scene::read(&dir).unwrap(), scene);
    assert_eq!(Scene::read_in(&in_memory(&dir), &dir).unwrap(), scene);
    // Only the finished scene is in the dataset folder, no temporary left behind.
    let names: Vec<String> = fs::read_dir(&root)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["scene_000"]);
    assert_eq!(list_scenes(&root).unwrap(), core::slice::from_ref(&dir));

    // Never overwritten.
    let e = scene.write(&dir).unwrap_err();
    assert!(matches!(e, SceneError::Exists { .. }), "{e}");
    // An inconsistent scene is refused before anything is written.
    let mut bad = scene.clone();
    bad.actions.pop();
    let e = bad.write(&root.join("scene_001")).unwrap_err();
    assert!(e.to_string().contains("actions.json"), "{e}");
    assert!(!root.join("scene_001").exists());
    let mut bad = scene.clone();
    if let Some(poses) = &mut bad.poses {
        poses[1][0].label = 0;
    }
    let e = bad.write(&root.join("scene_001")).unwrap_err();
    assert!(
        e.to_string().contains("poses.json") && e.to_string().contains("label 0"),
        "{e}"
    );
    assert!(!root.join("scene_001").exists());
    assert_eq!(fs::read_dir(&root).unwrap().count(), 1);

    // A scene without the optional parts, and a single frame without actions.json.
    let mut bare = scene.clone();
    bare.labels = None;
    bare.flow = None;
    bare.poses = None;
    bare.write(&root.join("scene_002")).unwrap();
    assert_eq!(Scene::read(&root.join("scene_002")).unwrap(), bare);
    let mut single = bare;
    single.rgb.truncate(1);
    single.depth.truncate(1);
    single.actions.clear();
    let single_dir = root.join("scene_003");
    single.write(&single_dir).unwrap();
    fs::remove_file(single_dir.join("actions.json")).unwrap();
    assert_eq!(Scene::read(&single_dir).unwrap(), single);
    assert_eq!(
        Scene::read_in(&in_memory(&single_dir), &single_dir).unwrap(),
        single
    );
    fs::remove_dir_all(&root).unwrap();
}

/// Writes a fresh valid scene, applies `damage`, reads it, and checks that the error
/// message names `file` (relative to the scene folder) and says `problem`.
fn assert_bad(root: &Path, case: &str, damage: impl FnOnce(&Path), file: &str, problem: &str) {
    let dir = root.join(case);
    small_scene().write(&dir).unwrap();
    damage(&dir);
    let message = match Scene::read(&dir) {
        Ok(_) => panic!("{case}: a damaged scene was read without error"),
        Err(e) => e.to_string(),
    };
    println!("{case}: {message}");
    let from_memory = match Scene::read_in(&in_memory(&dir), &dir) {
        Ok(_) => panic!("{case}: a damaged scene was read from memory without error"),
        Err(e) => e.to_string(),
    };
    assert_eq!(from_memory, message, "{case}: read from memory");
    let named = dir.join(file);
    assert!(
        message.starts_with(&named.display().to_string()),
        "{case}: message does not start with {}: {message}",
        named.display()
    );
    assert!(message.contains(problem), "{case}: {message}");
}

#[test]
fn replayed_frames_carry_the_scenes_labels_and_poses() {
    let scene = small_scene();
    for t in 0..scene.frames() {
        let frame = SceneReplay::frame(&scene, t).unwrap();
        assert_eq!(frame.truth.as_ref(), scene.labels.as_ref().unwrap().get(t));
        assert_eq!(
            frame.truth_poses.as_ref(),
            scene.poses.as_ref().unwrap().get(t)
        );
    }
    assert!(SceneReplay::frame(&scene, scene.frames()).is_none());
    let mut bare = scene;
    bare.labels = None;
    bare.poses = None;
    let frame = SceneReplay::frame(&bare, 1).unwrap();
    assert_eq!((frame.truth, frame.truth_poses), (None, None));
}

#[test]
fn every_bad_folder_is_an_error_naming_the_file() {
    let root = temp_root("bad");
    let write = |path: PathBuf, bytes: &[u8]| fs::write(path, bytes).unwrap();

    // Missing files and folders.
    assert_bad(
        &root,
        "no_camera",
        |d| fs::remove_file(d.join("scene_camera.json")).unwrap(),
        "scene_camera.json",
        "not found",
    );
    assert_bad(
        &root,
        "no_rgb_dir",
        |d| fs::remove_dir_all(d.join("rgb")).unwrap(),
        "rgb",
        "not found",
    );
    assert_bad(
        &root,
        "no_depth_frame",
        |d| fs::remove_file(d.join("depth/000001.png")).unwrap(),
        "depth/000001.png",
        "not found",
    );
    assert_bad(
        &root,
        "rgb_gap",
        |d| fs::remove_file(d.join("rgb/000001.png")).unwrap(),
        "rgb/000001.png",
        "not found",
    );
    assert_bad(
        &root,
        "no_actions",
        |d| fs::remove_file(d.join("actions.json")).unwrap(),
        "actions.json",
        "not found",
    );

    // Wrong image size.
    assert_bad(
        &root,
        "label_size",
        |d| {
            write_gray16(
                &d.join("label/000001.png"),
                &Gray16Image::from_fn(W - 1, H, |_, _| 1),
            )
            .unwrap()
        },
        "label/000001.png",
        "expected 8x6 pixels, found 7x6",
    );
    // 8-bit depth.
    assert_bad(
        &root,
        "depth_8bit",
        |d| {
            image::GrayImage::new(W as u32, H as u32)
                .save(d.join("depth/000000.png"))
                .unwrap()
        },
        "depth/000000.png",
        "expected 16-bit greyscale PNG, found 8-bit greyscale",
    );
    // Corrupt PNGs: garbage, and a real PNG cut in half.
    assert_bad(
        &root,
        "rgb_garbage",
        |d| write(d.join("rgb/000001.png"), b"not a png at all"),
        "rgb/000001.png",
        "corrupt or unsupported PNG",
    );
    assert_bad(
        &root,
        "depth_truncated",
        |d| {
            let p = d.join("depth/000002.png");
            let bytes = fs::read(&p).unwrap();
            write(p, &bytes[..bytes.len() / 2]);
        },
        "depth/000002.png",
        "corrupt or unsupported PNG",
    );
    // Corrupt flow.
    assert_bad(
        &root,
        "flow_truncated",
        |d| write(d.join("flow/000000.flo"), b"PIEH\x08\x00\x00\x00"),
        "flow/000000.flo",
        "not a valid Middlebury .flo file",
    );

    // Frame counts that disagree.
    assert_bad(
        &root,
        "extra_label",
        |d| {
            fs::copy(d.join("label/000000.png"), d.join("label/000003.png"))
                .map(drop)
                .unwrap()
        },
        "label/000003.png",
        "one frame too many: expected 3",
    );
    assert_bad(
        &root,
        "missing_flow",
        |d| fs::remove_file(d.join("flow/000001.flo")).unwrap(),
        "flow/000001.flo",
        "not found",
    );
    assert_bad(
        &root,
        "extra_flow",
        |d| {
            fs::copy(d.join("flow/000000.flo"), d.join("flow/000002.flo"))
                .map(drop)
                .unwrap()
        },
        "flow/000002.flo",
        "one frame too many: expected 2 (one per push)",
    );
    assert_bad(
        &root,
        "extra_rgb",
        |d| {
            fs::copy(d.join("rgb/000000.png"), d.join("rgb/000003.png"))
                .map(drop)
                .unwrap()
        },
        "depth/000003.png",
        "not found",
    );
    assert_bad(
        &root,
        "too_few_actions",
        |d| {
            write(d.join("actions.json"), br#"[{"push": 1, "start_px": [1, 2], "start_cam_m": [0, 0, 0.6], "direction_cam": [1, 0, 0], "length_m": 0.02}]"#)
        },
        "actions.json",
        "1 pushes listed, expected 2",
    );
    assert_bad(
        &root,
        "misnumbered_actions",
        |d| {
            let text = fs::read_to_string(d.join("actions.json")).unwrap();
            write(
                d.join("actions.json"),
                text.replacen("\"push\": 2", "\"push\": 7", 1).as_bytes(),
            );
        },
        "actions.json",
        "entry 1 has \"push\": 7, expected 2",
    );

    // Malformed JSON and bad values.
    assert_bad(
        &root,
        "camera_json",
        |d| write(d.join("scene_camera.json"), b"{\"width\": 8,"),
        "scene_camera.json",
        "malformed JSON",
    );
    assert_bad(
        &root,
        "camera_field",
        |d| write(d.join("scene_camera.json"), br#"{"width": 8, "height": 6}"#),
        "scene_camera.json",
        "missing field",
    );
    assert_bad(
        &root,
        "actions_json",
        |d| write(d.join("actions.json"), b"[{\"push\": \"one\"}]"),
        "actions.json",
        "malformed JSON",
    );
    assert_bad(
        &root,
        "camera_fx",
        |d| {
            write(d.join("scene_camera.json"), br#"{"width": 8, "height": 6, "fx": 0, "fy": 615, "cx": 3.5, "cy": 2.5, "depth_unit_m": 0.001}"#)
        },
        "scene_camera.json",
        "focal lengths must be positive",
    );
    // Bad poses.json: syntax, frame count, labels, numbers, quaternions.
    let one_pose = |label: i64, t: &str, q: &str| {
        format!(r#"{{"label": {label}, "translation_m": {t}, "rotation_xyzw": {q}}}"#)
    };
    let poses_of = |frames: &[String]| format!(r#"{{"frames": [{}]}}"#, frames.join(", "));
    let good = one_pose(1, "[0, 0, 0.02]", "[0, 0, 0, 1]");
    let frame = |objects: &[&String]| {
        format!(
            "[{}]",
            objects
                .iter()
                .map(|s| s.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    let three = |last: String| poses_of(&[frame(&[&good]), frame(&[&good]), last]);
    let cases = [
        ("poses_json", "{\"frames\": [".to_owned(), "malformed JSON"),
        (
            "poses_field",
            r#"{"frame": []}"#.to_owned(),
            "unknown field `frame`, expected `frames`",
        ),
        (
            "poses_frames",
            poses_of(&[frame(&[&good]), frame(&[&good])]),
            "2 frames of poses, expected 3",
        ),
        (
            "poses_empty",
            poses_of(&[]),
            "0 frames of poses, expected 3",
        ),
        (
            "poses_label0",
            three(frame(&[&one_pose(0, "[0, 0, 0]", "[0, 0, 0, 1]")])),
            "frame 2: label 0",
        ),
        (
            "poses_twice",
            three(frame(&[&good, &good])),
            "frame 2: object 1 listed twice",
        ),
        (
            "poses_norm",
            three(frame(&[&one_pose(1, "[0, 0, 0]", "[0, 0, 0.5, 1]")])),
            "frame 2: object 1: rotation_xyzw has norm 1.118",
        ),
        (
            "poses_infinite",
            three(frame(&[&one_pose(1, "[1e39, 0, 0]", "[0, 0, 0, 1]")])),
            "frame 2: object 1 has a non-finite value",
        ),
        (
            "poses_short",
            three(frame(&[&one_pose(1, "[0, 0]", "[0, 0, 0, 1]")])),
            "malformed JSON",
        ),
    ];
    for (case, text, problem) in cases {
        assert_bad(
            &root,
            case,
            |d| write(d.join("poses.json"), text.as_bytes()),
            "poses.json",
            problem,
        );
    }
    // A quaternion a little off unit length is accepted and normalised.
    let dir = root.join("poses_almost_unit");
    small_scene().write(&dir).unwrap();
    write(
        dir.join("poses.json"),
        three(frame(&[&one_pose(
            2,
            "[0, 0, 0]",
            "[0, 0, 0.0006, 1.0003]",
        )]))
        .as_bytes(),
    );
    let read = Scene::read(&dir).unwrap().poses.unwrap();
    let q = read[2][0].world_from_object.rotation.coords;
    assert!((q.norm() - 1.0).abs() < 1e-6, "{q:?}");

    // The folder itself.
    let e = Scene::read(&root.join("nowhere")).unwrap_err().to_string();
    assert!(e.contains("nowhere") && e.contains("not found"), "{e}");
    fs::remove_dir_all(&root).unwrap();
}
