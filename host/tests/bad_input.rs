//! Every subcommand on bad input, as a careful new user would try it: each case must exit
//! with the documented code (1 for an error, 2 for bad arguments, 0 when only standard
//! output was closed), print one line naming the file and the problem, leave no partial
//! output and never write over its input.

use std::{
    ffi::OsString,
    fs,
    path::{Path, PathBuf},
    process::{Command, Output, Stdio},
    sync::OnceLock,
};

use riseg::io::image::{Gray8Image, Gray16Image, read_gray16, write_gray8, write_gray16};
use riseg::testkit::png::png_declaring;

fn riseg() -> Command {
    Command::new(env!("CARGO_BIN_EXE_riseg"))
}

/// One generated loose scene with one push (frames 0 and 1), made once per test run.
fn dataset() -> &'static Path {
    static DATA: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    let (_, data) = DATA.get_or_init(|| {
        let dir = tempfile::tempdir().expect("temp dir");
        let data = dir.path().join("data");
        let out = riseg()
            .args([
                "gen", "--scenes", "1", "--pushes", "1", "--seed", "5", "--out",
            ])
            .arg(&data)
            .output()
            .expect("run riseg gen");
        assert!(out.status.success(), "{}", text(&out.stderr));
        (dir, data)
    });
    data
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn copy_tree(from: &Path, to: &Path) {
    fs::create_dir_all(to).expect("test setup");
    for entry in fs::read_dir(from).expect("test setup") {
        let entry = entry.expect("test setup");
        let target = to.join(entry.file_name());
        if entry.file_type().expect("test setup").is_dir() {
            copy_tree(&entry.path(), &target);
        } else {
            fs::copy(entry.path(), &target).expect("test setup");
        }
    }
}

/// A case's own folder: `work/data/scene_000` (a copy of the dataset) and room for outputs.
struct Work {
    _dir: tempfile::TempDir,
    root: PathBuf,
}

impl Work {
    fn new() -> Self {
        let dir = tempfile::tempdir().expect("temp dir");
        let root = dir.path().to_path_buf();
        copy_tree(dataset(), &root.join("data"));
        Self { _dir: dir, root }
    }
    fn data(&self) -> PathBuf {
        self.root.join("data")
    }
    fn scene(&self) -> PathBuf {
        self.data().join("scene_000")
    }
    fn file(&self, rel: &str) -> PathBuf {
        self.scene().join(rel)
    }
    fn out(&self, name: &str) -> PathBuf {
        self.root.join(name)
    }
}

fn run(args: &[OsString]) -> Output {
    riseg().args(args).output().expect("riseg runs")
}

fn os(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Vec<OsString> {
    args.iter().map(|a| a.as_ref().to_owned()).collect()
}

/// Asserts the run failed with `code` and one stderr line holding every needle; returns
/// the line.
#[track_caller]
fn assert_fails(case: &str, out: &Output, code: i32, needles: &[&str]) -> String {
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(code), "{case}: {stderr}");
    if code == 1 {
        let lines: Vec<&str> = stderr.lines().collect();
        assert_eq!(lines.len(), 1, "{case}: one line expected:\n{stderr}");
        assert!(lines[0].starts_with("error: "), "{case}: {stderr}");
    }
    for needle in needles {
        assert!(
            stderr.contains(needle),
            "{case}: {needle:?} not in:\n{stderr}"
        );
    }
    stderr
}

/// Replaces frame 0's depth with one value everywhere.
fn flat_depth(w: &Work, raw: u16) {
    let path = w.file("depth/000000.png");
    let depth = read_gray16(&path).expect("test setup");
    write_gray16(&path, &depth.map(|_| raw)).expect("test setup");
}

/// `segment` on frame 0 of the case's scene, writing `out`.
fn segment(w: &Work, out: &Path) -> Output {
    run(&os(&[
        &"segment",
        &"--scene",
        &w.scene(),
        &"--frame",
        &"0",
        &"-o",
        &out,
    ]))
}

#[test]
fn segment_refuses_every_bad_frame_naming_the_file() {
    type Break = fn(&Work);
    let cases: [(&str, Break, &[&str]); 12] = [
        (
            "missing rgb",
            |w| fs::remove_file(w.file("rgb/000000.png")).unwrap(),
            &["rgb/000000.png", "file not found"],
        ),
        (
            "empty rgb",
            |w| fs::write(w.file("rgb/000000.png"), b"").unwrap(),
            &["rgb/000000.png", "corrupt"],
        ),
        (
            "truncated rgb",
            |w| {
                let p = w.file("rgb/000000.png");
                let bytes = fs::read(&p).unwrap();
                fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
            },
            &["rgb/000000.png", "corrupt"],
        ),
        (
            "huge header",
            |w| fs::write(w.file("depth/000000.png"), png_declaring(100_000, 100_000)).unwrap(),
            &["depth/000000.png", "found 100000x100000"],
        ),
        (
            "8-bit depth",
            |w| {
                let p = w.file("depth/000000.png");
                write_gray8(&p, &Gray8Image::from_fn(640, 480, |_, _| 9)).unwrap();
            },
            &["depth/000000.png", "16-bit greyscale"],
        ),
        (
            "mis-sized depth",
            |w| {
                let p = w.file("depth/000000.png");
                write_gray16(&p, &Gray16Image::from_fn(320, 240, |_, _| 600)).unwrap();
            },
            &["depth/000000.png", "expected 640x480"],
        ),
        (
            "zero depth",
            |w| flat_depth(w, 0),
            &["depth/000000.png", "no depth reading"],
        ),
        (
            "saturated depth",
            |w| flat_depth(w, u16::MAX),
            &["depth/000000.png", "no depth reading"],
        ),
        (
            "unknown camera field",
            |w| {
                let p = w.file("scene_camera.json");
                let json = fs::read_to_string(&p).unwrap();
                fs::write(&p, json.replacen('{', "{\"fov\": 1,", 1)).unwrap();
            },
            &["scene_camera.json", "unknown field `fov`"],
        ),
        (
            "missing camera field",
            |w| {
                let p = w.file("scene_camera.json");
                let mut json: serde_json::Value =
                    serde_json::from_str(&fs::read_to_string(&p).unwrap()).unwrap();
                json.as_object_mut().unwrap().remove("fx");
                fs::write(&p, json.to_string()).unwrap();
            },
            &["scene_camera.json", "missing field `fx`"],
        ),
        (
            "absurd intrinsics",
            |w| {
                let p = w.file("scene_camera.json");
                let mut json: serde_json::Value =
                    serde_json::from_str(&fs::read_to_string(&p).unwrap()).unwrap();
                json["fx"] = serde_json::json!(0.6);
                fs::write(&p, json.to_string()).unwrap();
            },
            &["scene_camera.json", "focal lengths"],
        ),
        (
            "huge camera",
            |w| {
                let p = w.file("scene_camera.json");
                let mut json: serde_json::Value =
                    serde_json::from_str(&fs::read_to_string(&p).unwrap()).unwrap();
                json["width"] = serde_json::json!(16_000);
                json["height"] = serde_json::json!(16_000);
                fs::write(&p, json.to_string()).unwrap();
            },
            &["scene_camera.json", "16000x16000"],
        ),
    ];
    for (case, break_it, needles) in cases {
        let w = Work::new();
        break_it(&w);
        let out = w.out("labels.png");
        assert_fails(case, &segment(&w, &out), 1, needles);
        assert!(!out.exists(), "{case}: an output was written");
    }
}

#[test]
fn outputs_are_written_through_links_into_devices_and_never_half() {
    let w = Work::new();
    // Unwritable: the folder does not exist.
    let missing = w.out("no/such/folder/labels.png");
    assert_fails("missing folder", &segment(&w, &missing), 1, &["labels.png"]);
    // A folder where the file should go.
    fs::create_dir_all(w.out("a-folder")).unwrap();
    assert_fails(
        "folder",
        &segment(&w, &w.out("a-folder")),
        1,
        &["a-folder", "folder"],
    );
    // A full device: a clear error, and the device is still a device.
    if Path::new("/dev/full").exists() {
        let out = segment(&w, Path::new("/dev/full"));
        assert_fails("/dev/full", &out, 1, &["/dev/full", "No space left"]);
        assert!(!fs::metadata("/dev/full").unwrap().is_file());
    }
    // A symbolic link is written through; the link stays.
    #[cfg(unix)]
    {
        let target = w.out("target.png");
        let link = w.out("link.png");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let out = segment(&w, &link);
        assert!(out.status.success(), "{}", text(&out.stderr));
        assert!(
            fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(read_gray16(&target).unwrap().size(), (640, 480));
    }
}

#[test]
fn flow_refuses_bad_images_and_resource_flags() {
    let w = Work::new();
    let (a, b) = (w.file("rgb/000000.png"), w.file("rgb/000001.png"));
    let out = w.out("out.flo");
    let huge = w.out("huge.png");
    fs::write(&huge, png_declaring(20_000, 20_000)).unwrap();
    let empty = w.out("empty.png");
    fs::write(&empty, b"").unwrap();
    for (case, second, needles) in [
        ("huge", &huge, &["huge.png", "declares 20000x20000"][..]),
        ("empty", &empty, &["empty.png", "corrupt"][..]),
        (
            "missing",
            &w.out("none.png"),
            &["none.png", "not found"][..],
        ),
    ] {
        let run = run(&os(&[&"flow", &a, second, &"-o", &out]));
        assert_fails(case, &run, 1, needles);
        assert!(!out.exists(), "{case}: an output was written");
    }
    let threads = run(&os(&[
        &"flow",
        &a,
        &b,
        &"-o",
        &out,
        &"--threads",
        &"100000",
    ]));
    assert_fails("--threads 100000", &threads, 2, &["--threads", "0 to 256"]);
}

#[test]
fn run_reads_only_what_it_uses_and_never_writes_over_its_input() {
    // Bad files run never reads (labels, flow) and a missing actions.json do not stop it.
    let w = Work::new();
    fs::write(w.file("label/000000.png"), b"not a png").unwrap();
    fs::write(w.file("flow/000000.flo"), b"not a flo").unwrap();
    fs::remove_file(w.file("actions.json")).unwrap();
    let pred = w.out("pred");
    let out = run(&os(&[&"run", &"--scene", &w.scene(), &"--out", &pred]));
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(
        read_gray16(&pred.join("scene_000/label/000001.png"))
            .unwrap()
            .size(),
        (640, 480)
    );

    // actions.json is read for the flow's motion hints: missing is fine (above), corrupt
    // is an error naming it, before any mask is written.
    let w = Work::new();
    fs::write(w.file("actions.json"), b"[{\"push\": 0,").unwrap();
    let pred = w.out("pred");
    let out = run(&os(&[&"run", &"--scene", &w.scene(), &"--out", &pred]));
    assert_fails("corrupt actions.json", &out, 1, &["actions.json"]);
    assert!(!pred.join("scene_000/label").exists(), "a mask was written");

    // --out the dataset itself: refused before anything is written.
    let w = Work::new();
    let truth = fs::read(w.file("label/000000.png")).unwrap();
    let out = run(&os(&[&"run", &"--dataset", &w.data(), &"--out", &w.data()]));
    assert_fails("--out the dataset", &out, 1, &["would replace", "label/"]);
    assert_eq!(fs::read(w.file("label/000000.png")).unwrap(), truth);

    // A flow file with NaN: named, nothing written.
    let w = Work::new();
    let flo = w.file("flow/000000.flo");
    let mut bytes = fs::read(&flo).unwrap();
    bytes[12..16].copy_from_slice(&f32::NAN.to_le_bytes());
    fs::write(&flo, bytes).unwrap();
    let pred = w.out("pred");
    let out = run(&os(&[
        &"run",
        &"--scene",
        &w.scene(),
        &"--flow-dir",
        &w.data(),
        &"--out",
        &pred,
    ]));
    assert_fails("NaN flow", &out, 1, &["000000.flo", "not finite"]);
    assert!(!pred.join("scene_000/label").exists(), "masks were written");
}

#[test]
fn eval_and_bench_check_their_json_first_and_survive_a_closed_stdout() {
    let w = Work::new();
    let data = w.data();
    // An extra `0.png` is not a frame: a clear error, not a second frame 0.
    fs::copy(w.file("label/000000.png"), w.file("label/0.png")).unwrap();
    let out = run(&os(&[&"eval", &"--gt", &data, &"--pred", &data]));
    assert_fails("0.png", &out, 1, &["0.png", "six digits"]);
    fs::remove_file(w.file("label/0.png")).unwrap();

    // --json to a folder that does not exist: refused before any work.
    let bad_json = w.out("no/such/report.json");
    for args in [
        os(&[
            &"eval", &"--gt", &data, &"--pred", &data, &"--json", &bad_json,
        ]),
        os(&[&"bench", &"--scenes", &"1", &"--json", &bad_json]),
    ] {
        let out = run(&args);
        assert_fails("--json unwritable", &out, 1, &["report.json"]);
    }

    // Standard output closed by its reader: exit 0, and the --json file is there.
    let json = w.out("report.json");
    let mut child = riseg()
        .args(os(&[
            &"eval", &"--gt", &data, &"--pred", &data, &"--json", &json,
        ]))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(json.is_file());
    // A full standard output is an error.
    if Path::new("/dev/full").exists() {
        let full = riseg()
            .args(["config", "--print"])
            .stdout(fs::File::create("/dev/full").unwrap())
            .output()
            .unwrap();
        assert_fails(
            "stdout full",
            &full,
            1,
            &["standard output", "No space left"],
        );
    }
}

#[test]
fn gen_and_bench_refuse_absurd_counts_and_gen_never_replaces_a_file() {
    let w = Work::new();
    for args in [
        os(&[&"gen", &"--scenes", &"0", &"--out", &w.out("g")]),
        os(&[&"gen", &"--scenes", &"4294967295", &"--out", &w.out("g")]),
        os(&[&"gen", &"--pushes", &"1000", &"--out", &w.out("g")]),
        os(&[&"bench", &"--scenes", &"0"]),
    ] {
        let out = run(&args);
        assert_fails("count", &out, 2, &["expected a whole number"]);
        assert!(!w.out("g").exists());
    }
    // A user's preview where gen would write one: refused, untouched, nothing written.
    let dir = w.out("mine");
    fs::create_dir_all(dir.join("preview")).unwrap();
    fs::write(dir.join("preview/scene_000.png"), b"my picture").unwrap();
    let out = run(&os(&[&"gen", &"--scenes", &"1", &"--out", &dir]));
    assert_fails(
        "existing preview",
        &out,
        1,
        &["scene_000.png", "already exists"],
    );
    assert_eq!(
        fs::read(dir.join("preview/scene_000.png")).unwrap(),
        b"my picture"
    );
    assert!(!dir.join("scene_000").exists());
}

#[test]
fn demo_refuses_an_output_folder_that_is_a_file() {
    let w = Work::new();
    let file = w.out("taken");
    fs::write(&file, b"a user's file").unwrap();
    let out = run(&os(&[&"demo", &"--out", &file]));
    assert_fails("demo --out FILE", &out, 1, &["taken"]);
    assert_eq!(fs::read(&file).unwrap(), b"a user's file");
}

#[test]
fn help_documents_the_exit_codes() {
    let out = riseg().arg("--help").output().expect("riseg runs");
    let help = text(&out.stdout);
    for needle in ["Exit codes: 0 success", "1 an error", "2 bad arguments"] {
        assert!(help.contains(needle), "{needle:?} not in:\n{help}");
    }
}
