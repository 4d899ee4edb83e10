//! `riseg segment` end to end: outputs on a synthetic frame, and errors that name the bad
//! file without leaving outputs behind.

use std::{
    fs,
    path::{Path, PathBuf},
    process::{Command, Output},
};

use riseg::segment::{files, synthetic::SyntheticTabletop};

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
        files::write_rgb8(&dir.join("rgb.png"), 320, 240, &t.rgb).expect("test setup");
        let mm: Vec<u16> = t
            .depth_m
            .iter()
            .map(|z| (z * 1000.0).round() as u16)
            .collect();
        files::write_gray16(&dir.join("depth.png"), 320, 240, &mm).expect("test setup");
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
    let labels = files::read_gray16(&scene.path("labels.png")).unwrap();
    assert_eq!(labels.size(), (320, 240));
    let segments = labels.pixels.iter().copied().max().unwrap();
    assert!(segments >= 3, "{segments} segments");
    let heat = files::read_png(&scene.path("heat.png")).unwrap();
    assert!(matches!(heat, image::DynamicImage::ImageLuma8(_)));
    let heat = heat.into_luma8();
    assert!(heat.pixels().any(|p| p.0[0] >= 150) && heat.pixels().any(|p| p.0[0] < 120));
    let viz = files::read_rgb8(&scene.path("viz.png")).unwrap();
    assert_eq!(viz.size(), (960, 240));
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
    files::write_gray8(&scene.path("depth8.png"), 320, 240, &[100; 320 * 240]).unwrap();
    let out = scene.run("rgb.png", "depth8.png");
    scene.assert_fails_naming(&out, "depth8.png", "16-bit");
    // Depth of another size than the colour image and the camera.
    files::write_gray16(&scene.path("small.png"), 160, 120, &[600; 160 * 120]).unwrap();
    let out = scene.run("rgb.png", "small.png");
    scene.assert_fails_naming(&out, "small.png", "320x240");
    // Colour that is a depth image.
    let out = scene.run("depth.png", "depth.png");
    scene.assert_fails_naming(&out, "depth.png", "8-bit RGB");
}
