//! `riseg segment` end to end: outputs on a synthetic frame (given as three files, or as a
//! frame of a scene folder), and errors that name the bad file without leaving outputs
//! behind.

use std::{
    fs,
    path::{Path, PathBuf},
    process::{Command, Output},
};

use riseg::{
    io::image::{Gray8Image, Gray16Image, Image, RgbImage},
    io::scene::{self, SceneCamera},
    testkit::segment::SyntheticTabletop,
};

struct Scene {
    dir: PathBuf,
}

impl Scene {
    /// A synthetic frame written as `rgb.png`, `depth.png` (millimetres) and
    /// `scene_camera.json` in a fresh folder.
    fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("riseg-cli-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("test setup");
        let t = SyntheticTabletop::boxes(320, 240, 3).expect("test setup");
        let k = t.intrinsics;
        let rgb = Image::from_vec(320, 240, t.rgb.clone()).expect("test setup");
        riseg::io::image::write_rgb8(&dir.join("rgb.png"), &rgb).expect("test setup");
        let mm: Vec<u16> = t
            .depth_m
            .iter()
            .map(|z| (z * 1000.0).round() as u16)
            .collect();
        let depth = Image::from_vec(320, 240, mm).expect("test setup");
        riseg::io::image::write_gray16(&dir.join("depth.png"), &depth).expect("test setup");
        fs::write(
            dir.join("scene_camera.json"),
            format!(
                r#"{{"width": 320, "height": 240, "fx": {}, "fy": {}, "cx": {}, "cy": {},
                    "depth_unit_m": 0.001}}"#,
                k.fx, k.fy, k.cx, k.cy
            ),
        )
        .expect("test setup");
        Self { dir }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// Runs `riseg segment` with `rgb`, `depth` (file names in the folder) and the camera,
    /// writing `labels.png`, `heat.png` and `viz.png`.
    fn run(&self, rgb: &str, depth: &str) -> Output {
        Command::new(env!("CARGO_BIN_EXE_riseg"))
            .arg("segment")
            .arg("--rgb")
            .arg(self.path(rgb))
            .arg("--depth")
            .arg(self.path(depth))
            .arg("--camera")
            .arg(self.path("scene_camera.json"))
            .arg("-o")
            .arg(self.path("labels.png"))
            .arg("--heatmap")
            .arg(self.path("heat.png"))
            .arg("--viz")
            .arg(self.path("viz.png"))
            .output()
            .expect("test setup")
    }

    /// Asserts a failure whose message names `file`, and that no output was written.
    fn assert_fails_naming(&self, out: &Output, file: &str, problem: &str) {
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "expected failure, got {stderr}");
        assert!(
            stderr.contains(file) && stderr.contains(problem),
            "stderr should name {file} and say {problem:?}: {stderr}"
        );
        for output in ["labels.png", "heat.png", "viz.png"] {
            assert!(!self.path(output).exists(), "{output} written on failure");
        }
        assert_no_temporaries(&self.dir);
    }
}

impl Drop for Scene {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.dir);
    }
}

fn assert_no_temporaries(dir: &Path) {
    for entry in fs::read_dir(dir).expect("test setup") {
        let name = entry.expect("test setup").file_name();
        assert!(
            !name.to_string_lossy().contains(".tmp"),
            "temporary file {name:?} left"
        );
    }
}

#[test]
fn segment_writes_labels_heatmap_and_picture() {
    let scene = Scene::new("ok");
    let out = scene.run("rgb.png", "depth.png");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("segments"));
    let labels = riseg::io::image::read_gray16(&scene.path("labels.png")).unwrap();
    assert_eq!((labels.width(), labels.height()), (320, 240));
    let segments = labels.as_slice().iter().copied().max().unwrap();
    assert!(segments >= 3, "{segments} segments");
    let heat = image::open(scene.path("heat.png")).unwrap();
    assert!(matches!(heat, image::DynamicImage::ImageLuma8(_)));
    let heat = heat.into_luma8();
    assert!(heat.pixels().any(|p| p.0[0] >= 150) && heat.pixels().any(|p| p.0[0] < 120));
    let viz = riseg::io::image::read_rgb8(&scene.path("viz.png")).unwrap();
    assert_eq!((viz.width(), viz.height()), (960, 240));
    assert_no_temporaries(&scene.dir);
}

#[test]
fn bad_inputs_are_errors_naming_the_file() {
    let scene = Scene::new("bad");
    // Missing file.
    let out = scene.run("nope.png", "depth.png");
    scene.assert_fails_naming(&out, "nope.png", "not found");
    // Corrupt PNG.
    fs::write(scene.path("corrupt.png"), b"\x89PNG\r\n\x1a\n garbage").unwrap();
    let out = scene.run("rgb.png", "corrupt.png");
    scene.assert_fails_naming(&out, "corrupt.png", "corrupt");
    // Wrong bit depth: 8-bit depth.
    let depth8 = Gray8Image::from_vec(320, 240, vec![100; 320 * 240]).unwrap();
    riseg::io::image::write_gray8(&scene.path("depth8.png"), &depth8).unwrap();
    let out = scene.run("rgb.png", "depth8.png");
    scene.assert_fails_naming(&out, "depth8.png", "16-bit");
    // Depth of another size than the colour image and the camera.
    let small = Gray16Image::from_vec(160, 120, vec![600; 160 * 120]).unwrap();
    riseg::io::image::write_gray16(&scene.path("small.png"), &small).unwrap();
    let out = scene.run("rgb.png", "small.png");
    scene.assert_fails_naming(&out, "small.png", "320x240");
    // Colour that is a depth image.
    let out = scene.run("depth.png", "depth.png");
    scene.assert_fails_naming(&out, "depth.png", "8-bit RGB");
}

/// A scene folder with one synthetic frame (frame 0, no pushes), written with the scene
/// module.
fn write_scene(dir: &Path) {
    let t = SyntheticTabletop::boxes(320, 240, 3).expect("test setup");
    let k = t.intrinsics;
    let scene = scene::Scene {
        camera: SceneCamera {
            width: 320,
            height: 240,
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
            depth_unit_m: 0.001,
        },
        rgb: vec![RgbImage::from_vec(320, 240, t.rgb.clone()).expect("test setup")],
        depth: vec![
            Gray16Image::from_vec(
                320,
                240,
                t.depth_m
                    .iter()
                    .map(|z| (z * 1000.0).round() as u16)
                    .collect(),
            )
            .expect("test setup"),
        ],
        labels: None,
        flow: None,
        actions: Vec::new(),
        poses: None,
    };
    scene.write(dir).expect("test setup");
}

fn segment_scene(scene_dir: &Path, frame: &str, out: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_riseg"))
        .args(["segment", "--scene"])
        .arg(scene_dir)
        .args(["--frame", frame, "-o"])
        .arg(out.join("labels.png"))
        .arg("--heatmap")
        .arg(out.join("heat.png"))
        .output()
        .expect("test setup")
}

#[test]
fn segment_reads_a_frame_of_a_scene_folder() {
    let tmp = std::env::temp_dir().join(format!("riseg-cli-scene-{}", std::process::id()));
    let _ = fs::remove_dir_all(&tmp);
    fs::create_dir_all(&tmp).expect("test setup");
    let scene_dir = tmp.join("scene_000");
    write_scene(&scene_dir);

    let out = segment_scene(&scene_dir, "0", &tmp);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let labels = image::open(tmp.join("labels.png")).unwrap();
    assert!(matches!(labels, image::DynamicImage::ImageLuma16(_)));
    assert_eq!((labels.width(), labels.height()), (320, 240));
    let segments = labels.into_luma16().pixels().map(|p| p.0[0]).max().unwrap();
    assert!(segments >= 3, "{segments} segments");
    let heat = image::open(tmp.join("heat.png")).unwrap();
    assert!(matches!(heat, image::DynamicImage::ImageLuma8(_)));
    assert_eq!((heat.width(), heat.height()), (320, 240));
    // Same frame through the three-file form: same labels.
    let (rgb, depth) = scene::frame_paths(&scene_dir, 0);
    let files = Command::new(env!("CARGO_BIN_EXE_riseg"))
        .arg("segment")
        .arg("--rgb")
        .arg(&rgb)
        .arg("--depth")
        .arg(&depth)
        .arg("--camera")
        .arg(scene_dir.join(scene::CAMERA_FILE))
        .arg("-o")
        .arg(tmp.join("labels_files.png"))
        .output()
        .expect("test setup");
    assert!(files.status.success());
    assert_eq!(
        fs::read(tmp.join("labels.png")).unwrap(),
        fs::read(tmp.join("labels_files.png")).unwrap()
    );

    // A frame the scene does not have: the error names the missing file, nothing written.
    for name in ["labels.png", "heat.png"] {
        fs::remove_file(tmp.join(name)).unwrap();
    }
    let out = segment_scene(&scene_dir, "7", &tmp);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("000007.png") && stderr.contains("not found"),
        "{stderr}"
    );
    assert!(!tmp.join("labels.png").exists() && !tmp.join("heat.png").exists());
    // A folder that is no scene: the error names the camera file.
    let out = segment_scene(&tmp, "0", &tmp);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains(scene::CAMERA_FILE), "{stderr}");
    fs::remove_dir_all(&tmp).unwrap();
}

#[test]
fn input_forms_are_exclusive_and_complete() {
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_riseg"))
            .arg("segment")
            .args(args)
            .args(["-o", "never.png"])
            .output()
            .expect("test setup");
        assert!(!out.status.success(), "{args:?} should be refused");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    // Neither form.
    assert!(run(&[]).contains("required"));
    // Both forms.
    let both = run(&[
        "--scene", "s", "--frame", "0", "--rgb", "a.png", "--depth", "b.png", "--camera", "c.json",
    ]);
    assert!(both.contains("cannot be used with"), "{both}");
    // Half a form.
    assert!(run(&["--scene", "s"]).contains("--frame"));
    assert!(run(&["--rgb", "a.png", "--depth", "b.png"]).contains("--camera"));
    assert!(!Path::new("never.png").exists());
}
