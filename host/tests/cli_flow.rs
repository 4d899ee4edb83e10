//! `riseg flow` end to end: a generated pair in, a .flo and a colour-wheel PNG out, and
//! the errors for bad input name the file.

use riseg::io::image::{RgbImage, read_flo, write_rgb8};
use std::path::{Path, PathBuf};
use std::process::Command;

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("riseg-cli-flow-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("temporary folder");
    d
}

fn save(path: &Path, rgb: &RgbImage) {
    write_rgb8(path, rgb).expect("PNG written");
}

fn riseg(args: &[&Path]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_riseg"))
        .arg("flow")
        .args(args)
        .output()
        .expect("riseg runs")
}

#[test]
fn writes_flo_and_viz() {
    let d = dir("ok");
    let pair = riseg::testkit::flow::translated(160, 120, 9, [2.5, -1.5]);
    let (a, b) = (d.join("a.png"), d.join("b.png"));
    save(&a, &pair.first);
    save(&b, &pair.second);
    let (out, viz) = (d.join("out.flo"), d.join("viz.png"));
    let o = riseg(&[&a, &b, Path::new("-o"), &out, Path::new("--viz"), &viz]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let flow = read_flo(&out).unwrap();
    assert_eq!((flow.width(), flow.height()), (160, 120));
    let epe = flow.mean_epe(&pair.flow, Some(&pair.interior)).unwrap();
    assert!(epe < 0.5, "EPE {epe}");
    let picture = image::open(&viz).unwrap();
    assert_eq!((picture.width(), picture.height()), (160, 120));
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn bad_input_is_an_error_naming_the_file() {
    let d = dir("bad");
    let pair = riseg::testkit::flow::translated(64, 48, 2, [1.0, 0.0]);
    let a = d.join("a.png");
    save(&a, &pair.first);
    let small = d.join("small.png");
    save(
        &small,
        &RgbImage::from_fn(32, 48, |x, y| pair.first.as_slice()[y * 64 + x]),
    );
    let corrupt = d.join("corrupt.png");
    std::fs::write(&corrupt, b"\x89PNG\r\n\x1a\nnot really a png").unwrap();
    let missing = d.join("missing.png");
    let out = d.join("out.flo");
    for (second, expect) in [
        (&small, "small.png"),
        (&corrupt, "corrupt.png"),
        (&missing, "missing.png"),
    ] {
        let o = riseg(&[&a, second, Path::new("-o"), &out]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{expect}: succeeded");
        assert!(err.contains(expect), "{expect}: {err}");
        assert!(!out.exists(), "{expect}: an output was written");
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn help_teaches_the_format_and_presets() {
    let o = Command::new(env!("CARGO_BIN_EXE_riseg"))
        .args(["flow", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&o.stdout);
    for needle in [
        "202021.25",
        "row-major",
        "ultrafast",
        "medium",
        "colour wheel",
    ] {
        assert!(help.contains(needle), "{needle} missing from:\n{help}");
    }
}

/// Without the `onnx` feature a model path is refused with how to build with it (clap's
/// usage error, exit code 2), for every command that takes `--segmenter` or `--flow`.
#[cfg(not(feature = "onnx"))]
#[test]
fn a_model_path_without_the_onnx_feature_says_how_to_build_it() {
    for args in [
        &[
            "flow",
            "a.png",
            "b.png",
            "-o",
            "f.flo",
            "--flow",
            "raft.onnx",
        ][..],
        &[
            "segment",
            "--scene",
            "s",
            "--frame",
            "0",
            "-o",
            "l.png",
            "--segmenter",
            "m.onnx",
        ],
        &["run", "--scene", "s", "--out", "o", "--flow", "raft.onnx"],
        &["demo", "--segmenter", "m.onnx"],
        &["bench", "--flow", "raft.onnx"],
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_riseg"))
            .args(args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains("built without ONNX support") && stderr.contains("--features onnx"),
            "{args:?}: {stderr}"
        );
    }
}
