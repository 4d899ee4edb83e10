//! The ONNX adapters (feature `onnx`) on tiny models that `tests/onnx/make_models.py`
//! writes at test time (PyPI `onnx`), run by the onnxruntime wheel's library: exact outputs
//! through the adapters, every load and run error naming its file, and `riseg run` with the
//! models equal to `riseg run` fed the same results as files.
//!
//! Needs python3 with `onnx` and `onnxruntime` (CI installs them: `.ci/run`). Without them
//! every test here FAILS with the reason; a developer may set `RISEG_SKIP_ONNX_TESTS=1` to
//! skip them instead (ignored when `CI` is set).

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
    flow::{FlowError, FlowEstimator as _},
    io::image::{FlowImage, RgbImage, read_flo, write_flo, write_rgb8},
    onnx::{OnnxError, OnnxFlow, OnnxSegmenter},
    segment::{RgbdFrame, StaticSegmenter as _},
};
use riseg_core::{ImageView, Intrinsics};

/// The generated models, or `None` when skipping is allowed and they cannot be made.
fn models() -> Option<&'static Path> {
    static MODELS: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    let made = MODELS.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("onnx-models");
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/onnx/make_models.py");
        let _ = fs::remove_dir_all(&dir);
        let out = Command::new("python3")
            .arg(&script)
            .arg(&dir)
            .output()
            .map_err(|e| format!("cannot run python3: {e}"))?;
        if !out.status.success() {
            return Err(format!(
                "{} failed (is the PyPI `onnx` package installed?): {}",
                script.display(),
                String::from_utf8_lossy(&out.stderr)
            ));
        }
        let ort = Command::new("python3")
            .args(["-c", "import onnxruntime"])
            .status()
            .map_err(|e| e.to_string())?;
        if !ort.success() && std::env::var_os("ORT_DYLIB_PATH").is_none() {
            return Err("python3 cannot import onnxruntime and ORT_DYLIB_PATH is unset".into());
        }
        Ok(dir)
    });
    match made {
        Ok(dir) => Some(dir),
        Err(why)
            if std::env::var_os("RISEG_SKIP_ONNX_TESTS").is_some()
                && std::env::var_os("CI").is_none() =>
        {
            eprintln!("skipped (RISEG_SKIP_ONNX_TESTS): {why}");
            None
        }
        Err(why) => panic!(
            "ONNX tests need python3 with onnx and onnxruntime \
             (python3 -m pip install onnx==1.23.2 onnxruntime==1.32.0): {why}"
        ),
    }
}

fn riseg(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_riseg"));
    command.args(args);
    for (k, v) in env {
        command.env(k, v);
    }
    command.output().expect("running the riseg binary")
}

fn text(path: &Path) -> &str {
    path.to_str().expect("temporary paths are UTF-8")
}

/// A `width × height` image whose pixel `(x, y)` is `f(x, y)`.
fn rgb(width: usize, height: usize, f: impl Fn(usize, usize) -> [u8; 3]) -> RgbImage {
    RgbImage::from_fn(width, height, f)
}

fn pattern(x: usize, y: usize) -> [u8; 3] {
    let v = |k: usize| u8::try_from((x * 37 + y * 11 + k * 53) % 256).unwrap();
    [v(0), v(1), v(2)]
}

const K: Intrinsics = Intrinsics {
    fx: 600.0,
    fy: 600.0,
    cx: 2.0,
    cy: 1.0,
};

#[test]
fn constant_coarse_flow_is_upsampled_and_rescaled() {
    let Some(dir) = models() else { return };
    let flow = OnnxFlow::load(&dir.join("flow_const.onnx")).unwrap();
    // 37x21 pads to 40x24; the model's 5x3 coarse output is (0.25, -0.125) coarse pixels.
    let (a, b) = (rgb(37, 21, pattern), rgb(37, 21, |x, y| pattern(y, x)));
    let out = flow.estimate(a.view(), b.view()).unwrap();
    assert_eq!(out.size(), (37, 21));
    assert!(out.as_slice().iter().all(|&v| v == [2.0, -1.0]));
}

#[test]
fn affine_flow_reads_the_right_images_and_channels() {
    let Some(dir) = models() else { return };
    let flow = OnnxFlow::load(&dir.join("flow_affine.onnx")).unwrap();
    let (a, b) = (
        rgb(13, 9, pattern),
        rgb(13, 9, |x, y| pattern(x + 3, y + 1)),
    );
    let out = flow.estimate(a.view(), b.view()).unwrap();
    for y in 0..9 {
        for x in 0..13 {
            let want = [
                0.01 * f32::from(a.get(x, y).unwrap()[0]),
                -0.02 * f32::from(b.get(x, y).unwrap()[1]),
            ];
            let got = *out.get(x, y).unwrap();
            assert!(
                (got[0] - want[0]).abs() < 1e-4 && (got[1] - want[1]).abs() < 1e-4,
                "({x}, {y}): {got:?} vs {want:?}"
            );
        }
    }
}

#[test]
fn fixed_input_size_scales_the_flow_back_to_frame_pixels() {
    let Some(dir) = models() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let model = tmp.path().join("small.onnx");
    fs::copy(dir.join("flow_affine.onnx"), &model).unwrap();
    fs::write(tmp.path().join("small.json"), r#"{"input_size": [10, 10]}"#).unwrap();
    let flow = OnnxFlow::load(&model).unwrap();
    // 20x10 is scaled by 1/2 into the 10x10 input: model pixels are two frame pixels.
    let (a, b) = (
        rgb(20, 10, |_, _| [100, 0, 0]),
        rgb(20, 10, |_, _| [0, 50, 0]),
    );
    let out = flow.estimate(a.view(), b.view()).unwrap();
    for v in out.as_slice() {
        assert!(
            (v[0] - 2.0).abs() < 1e-4 && (v[1] + 2.0).abs() < 1e-4,
            "{v:?}"
        );
    }
}

#[test]
fn mask_logits_and_scores_give_labels_and_the_margin_heatmap() {
    let Some(dir) = models() else { return };
    let mut seg = OnnxSegmenter::load(&dir.join("seg_masks.onnx")).unwrap();
    // Depth 0.50: both instances claim, 0.9 beats 0.8 by 0.1 (uncertain, 126); 0.56: only
    // the second (certain, 150 + 210·0.3 = 213); 0.60: neither (background); 0 (no
    // reading) is fed as 0 m, so both claim again.
    let depth = [0.50, 0.56, 0.60, 0.0, 0.50, 0.56, 0.60, 0.0];
    let colour = [[10, 20, 30]; 8];
    let frame = RgbdFrame::new(4, 2, &colour, &depth).unwrap();
    let out = seg.segment(&frame, &K).unwrap();
    assert_eq!(out.labels.as_slice(), &[1, 2, 0, 1, 1, 2, 0, 1]);
    assert_eq!(
        out.heatmap.as_slice(),
        &[126, 213, 0, 126, 126, 213, 0, 126]
    );
}

#[test]
fn label_map_output_is_renumbered() {
    let Some(dir) = models() else { return };
    let mut seg = OnnxSegmenter::load(&dir.join("seg_labels.onnx")).unwrap();
    let colour = [[200, 0, 0], [50, 0, 0], [129, 0, 0], [127, 0, 0]];
    let frame = RgbdFrame::new(2, 2, &colour, &[0.5; 4]).unwrap();
    let out = seg.segment(&frame, &K).unwrap();
    assert_eq!(out.labels.as_slice(), &[1, 0, 1, 0]);
    assert_eq!(out.heatmap.as_slice(), &[255, 0, 255, 0]);
}

/// The message of loading `name` from the models as a flow.
fn flow_load_error(dir: &Path, name: &str) -> String {
    let error: OnnxError = OnnxFlow::load(&dir.join(name)).unwrap_err();
    let message = error.to_string();
    assert!(message.contains(name), "{message}");
    message
}

#[test]
fn contract_errors_name_the_file_the_tensor_and_the_shapes() {
    let Some(dir) = models() else { return };
    let m = flow_load_error(dir, "bad_rank.onnx");
    assert!(
        m.contains(
            "input `image1`: expected float32 [1, 3, H, W], the model declares float32 [1, ?, ?]"
        ),
        "{m}"
    );
    let m = flow_load_error(dir, "bad_dtype.onnx");
    assert!(
        m.contains("input `image1`") && m.contains("declares float64 [1, 3, ?, ?]"),
        "{m}"
    );
    let m = flow_load_error(dir, "no_output.onnx");
    assert!(
        m.contains("output `flow`: no such output") && m.contains("`motion`"),
        "{m}"
    );
    let m = flow_load_error(dir, "not_onnx.onnx");
    assert!(m.contains("not a model ONNX Runtime can load"), "{m}");
    let m = flow_load_error(dir, "absent.onnx");
    assert!(m.ends_with("absent.onnx: no such file"), "{m}");
    // A segmenter is not a flow model (and the reverse): here its sidecar already says so.
    let m = OnnxFlow::load(&dir.join("seg_masks.onnx"))
        .unwrap_err()
        .to_string();
    assert!(
        m.contains("seg_masks.json: unknown field `depth_input`"),
        "{m}"
    );
    let m = OnnxSegmenter::load(&dir.join("flow_const.onnx"))
        .unwrap_err()
        .to_string();
    assert!(
        m.contains("flow_const.onnx") && m.contains("is not in the contract"),
        "{m}"
    );
}

#[test]
fn a_model_without_its_sidecar_or_with_a_bad_one_is_refused() {
    let Some(dir) = models() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let model = tmp.path().join("seg.onnx");
    fs::copy(dir.join("seg_masks.onnx"), &model).unwrap();
    // No sidecar: the defaults feed no depth, so the model's depth input is unexplained.
    let m = OnnxSegmenter::load(&model).unwrap_err().to_string();
    assert!(
        m.contains("seg.onnx: input `depth` is not in the contract"),
        "{m}"
    );
    for (json, want) in [
        (
            r#"{"depth_input": "depth", "colour": 1}"#,
            "unknown field `colour`",
        ),
        (
            r#"{"depth_input": "depth", "std": [1, 0, 1]}"#,
            "`std` must be finite and positive",
        ),
        (
            r#"{"depth_input": "depth", "depth_kind": "xyz"}"#,
            "input `depth`: expected float32 [1, 3, H, W], the model declares float32 [1, 1, ?, ?]",
        ),
        (
            r#"{"depth_input": "depth", "scores_output": "conf"}"#,
            "output `conf`: no such output",
        ),
    ] {
        fs::write(tmp.path().join("seg.json"), json).unwrap();
        let m = OnnxSegmenter::load(&model).unwrap_err().to_string();
        assert!(m.contains("seg.") && m.contains(want), "{json}: {m}");
    }
}

#[test]
fn nan_output_is_an_error_naming_the_model() {
    let Some(dir) = models() else { return };
    let flow = OnnxFlow::load(&dir.join("nan_flow.onnx")).unwrap();
    let a = rgb(16, 8, pattern);
    let error = flow.estimate(a.view(), a.view()).unwrap_err();
    assert!(matches!(error, FlowError::Onnx(_)), "{error:?}");
    let m = error.to_string();
    assert!(
        m.contains("nan_flow.onnx: output `flow` holds NaN or infinity"),
        "{m}"
    );
    // Mismatched sizes are caught before inference.
    let b = rgb(8, 8, pattern);
    assert!(matches!(
        flow.estimate(a.view(), b.view()),
        Err(FlowError::SizeMismatch { .. })
    ));
    let empty = ImageView::<[u8; 3]>::packed(0, 0, &[]).unwrap();
    assert!(flow.estimate(empty, empty).is_err());
}

#[test]
fn cli_flow_with_a_model_and_runtime_errors() {
    let Some(dir) = models() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let (first, second, out) = (
        tmp.path().join("a.png"),
        tmp.path().join("b.png"),
        tmp.path().join("f.flo"),
    );
    write_rgb8(&first, &rgb(24, 16, pattern)).unwrap();
    write_rgb8(&second, &rgb(24, 16, pattern)).unwrap();
    let model = dir.join("flow_const.onnx");
    let args = [
        "flow",
        text(&first),
        text(&second),
        "-o",
        text(&out),
        "--flow",
        text(&model),
    ];
    let run = riseg(&args, &[]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(
        read_flo(&out)
            .unwrap()
            .as_slice()
            .iter()
            .all(|&v| v == [2.0, -1.0])
    );

    // No library at ORT_DYLIB_PATH, or a file that is not one: one line saying what to install.
    let absent = tmp.path().join("libonnxruntime.so");
    let not_a_library = dir.join("not_onnx.onnx");
    for (lib, want) in [
        (&absent, "is not a file"),
        (&not_a_library, "cannot load ONNX Runtime from"),
    ] {
        let run = riseg(&args, &[("ORT_DYLIB_PATH", text(lib))]);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains(want) && stderr.contains("pip install onnxruntime"),
            "{stderr}"
        );
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}

#[test]
fn run_help_documents_the_four_sources_and_they_conflict() {
    let help = riseg(&["run", "--help"], &[]);
    let help = String::from_utf8_lossy(&help.stdout);
    for flag in [
        "--segmenter",
        "--flow ",
        "--static-dir",
        "--flow-dir",
        "Tensor contract",
    ] {
        assert!(help.contains(flag), "{flag} missing from run --help");
    }
    for (a, b) in [("--segmenter", "--static-dir"), ("--flow", "--flow-dir")] {
        let run = riseg(
            &["run", "--scene", "s", "--out", "o", a, "x.onnx", b, "d"],
            &[],
        );
        assert_eq!(run.status.code(), Some(2), "{a} with {b}");
        assert!(String::from_utf8_lossy(&run.stderr).contains("cannot be used with"));
    }
    let run = riseg(
        &[
            "flow", "a.png", "b.png", "-o", "f.flo", "--flow", "model.pt",
        ],
        &[],
    );
    assert_eq!(run.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&run.stderr)
            .contains("expected `builtin` or the path of an .onnx file")
    );
}

/// `riseg gen` of one packed scene with two pushes.
fn dataset(root: &Path) -> PathBuf {
    let data = root.join("data");
    let args = [
        "gen", "--scenes", "1", "--pushes", "2", "--seed", "1", "--layout", "packed",
    ];
    let run = riseg(&[&args[..], &["--out", text(&data)]].concat(), &[]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    data
}

/// The masks `riseg run` wrote for scene_000, frames 0-2.
fn masks(out: &Path) -> Vec<Vec<u8>> {
    (0..3)
        .map(|t| fs::read(out.join(format!("scene_000/label/{t:06}.png"))).unwrap())
        .collect()
}

#[test]
fn run_with_models_equals_run_with_their_results_as_files() {
    let Some(dir) = models() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let data = dataset(tmp.path());
    let scene = data.join("scene_000");
    let (seg, flow) = (dir.join("seg_masks.onnx"), dir.join("flow_const.onnx"));
    // The constant flow and the ONNX segmentation, as files.
    let given = tmp.path().join("given");
    let camera: serde_json::Value =
        serde_json::from_slice(&fs::read(scene.join("scene_camera.json")).unwrap()).unwrap();
    let size = |k: &str| usize::try_from(camera[k].as_u64().unwrap()).unwrap();
    let (w, h) = (size("width"), size("height"));
    fs::create_dir_all(given.join("scene_000/flow")).unwrap();
    for t in 0..3 {
        let constant = FlowImage::from_vec(w, h, vec![[2.0, -1.0]; w * h]).unwrap();
        write_flo(&given.join(format!("scene_000/flow/{t:06}.flo")), &constant).unwrap();
        let (label, heat) = (
            given.join(format!("scene_000/label/{t:06}.png")),
            given.join(format!("scene_000/heat/{t:06}.png")),
        );
        fs::create_dir_all(label.parent().unwrap()).unwrap();
        fs::create_dir_all(heat.parent().unwrap()).unwrap();
        let frame = t.to_string();
        let run = riseg(
            &[
                "segment",
                "--scene",
                text(&scene),
                "--frame",
                &frame,
                "-o",
                text(&label),
                "--heatmap",
                text(&heat),
                "--segmenter",
                text(&seg),
            ],
            &[],
        );
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
    }
    let scene_arg = ["run", "--scene", text(&scene), "--out"];
    let run_with = |out: &Path, extra: &[&str]| {
        let run = riseg(&[&scene_arg[..], &[text(out)], extra].concat(), &[]);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        masks(out)
    };
    // Built-in segmenter: the ONNX constant flow equals that flow read from files.
    let onnx_flow = run_with(&tmp.path().join("a"), &["--flow", text(&flow)]);
    let file_flow = run_with(&tmp.path().join("b"), &["--flow-dir", text(&given)]);
    assert_eq!(onnx_flow, file_flow);
    // Both models equal both as files.
    let both = run_with(
        &tmp.path().join("c"),
        &["--segmenter", text(&seg), "--flow", text(&flow)],
    );
    let files = run_with(
        &tmp.path().join("d"),
        &["--static-dir", text(&given), "--flow-dir", text(&given)],
    );
    assert_eq!(both, files);
    // And the models change the result (the test can fail).
    let builtin = run_with(&tmp.path().join("e"), &[]);
    assert_ne!(builtin, onnx_flow);
}

#[test]
fn bench_and_demo_take_the_models() {
    let Some(dir) = models() else { return };
    let (seg, flow) = (dir.join("seg_masks.onnx"), dir.join("flow_const.onnx"));
    let models = ["--segmenter", text(&seg), "--flow", text(&flow)];
    let bench = riseg(
        &[&["bench", "--scenes", "1", "--seed", "1"][..], &models].concat(),
        &[],
    );
    assert!(
        bench.status.success(),
        "{}",
        String::from_utf8_lossy(&bench.stderr)
    );
    // A model that breaks the contract stops the command with its file named.
    let bad = dir.join("bad_rank.onnx");
    let demo = riseg(&["demo", "--flow", text(&bad), "--out", "unused"], &[]);
    assert_eq!(demo.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&demo.stderr).contains("bad_rank.onnx: input `image1`"));
}
