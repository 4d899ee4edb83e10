//! `--config FILE` and `riseg config --print` as a user runs them.

use std::path::Path;
use std::process::{Command, Output};

fn riseg() -> Command {
    Command::new(env!("CARGO_BIN_EXE_riseg"))
}

fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn failing(out: &Output) -> String {
    assert!(!out.status.success(), "succeeded");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// `riseg bench` on one scene, with `extra` arguments; the JSON report less its timings,
/// the stdout and the stderr.
fn bench_one(dir: &Path, name: &str, extra: &[&str]) -> (serde_json::Value, String, String) {
    let json = dir.join(format!("{name}.json"));
    let out = riseg()
        .args([
            "bench", "--scenes", "1", "--seed", "4", "--layout", "packed",
        ])
        .args(extra)
        .arg("--json")
        .arg(&json)
        .output()
        .expect("run riseg");
    // Less the timings.
    let stdout: String = ok(&out)
        .lines()
        .filter(|l| !l.starts_with("median ms per step"))
        .map(|l| format!("{l}\n"))
        .collect();
    let mut v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&json).expect("json")).expect("valid json");
    v.as_object_mut().expect("object").remove("timing_ms");
    (v, stdout, String::from_utf8_lossy(&out.stderr).into_owned())
}

#[test]
fn printed_defaults_run_as_no_config_and_one_key_changes_the_run() {
    let dir = tempfile::tempdir().expect("temp dir");
    let printed = ok(&riseg()
        .args(["config", "--print"])
        .output()
        .expect("run riseg"));
    assert!(printed.contains("\n[core]\n") && printed.contains("\nmax_pushes = 3\n"));
    let defaults = dir.path().join("defaults.toml");
    std::fs::write(&defaults, &printed).expect("write");
    let one_push = dir.path().join("one.toml");
    std::fs::write(&one_push, "[core]\nmax_pushes = 1\n").expect("write");

    let (plain, plain_out, plain_err) = bench_one(dir.path(), "plain", &[]);
    let defaults_arg = defaults.to_str().expect("utf-8 path");
    let (same, same_out, same_err) =
        bench_one(dir.path(), "same", &["-v", "--config", defaults_arg]);
    assert_eq!(plain, same);
    assert_eq!(plain_out, same_out);
    // Quiet by default; -v tells which settings ran and what was written.
    assert!(!plain_err.contains("info:"), "{plain_err}");
    assert!(
        same_err.contains("info: config ") && same_err.contains("the defaults"),
        "{same_err}"
    );
    assert!(same_err.contains("info: wrote "), "{same_err}");

    // The default run of this scene makes more than one push; max_pushes = 1 stops at one.
    let pushes = |v: &serde_json::Value| v["riseg"].as_array().expect("rows").len() - 1;
    assert!(pushes(&plain) > 1, "{plain}");
    let (one, one_out, _) = bench_one(
        dir.path(),
        "one",
        &["--config", one_push.to_str().expect("utf-8 path")],
    );
    assert_eq!(pushes(&one), 1, "{one}");
    assert!(one_out.contains("pushes per scene: 1\n"), "{one_out}");
}

#[test]
fn bad_files_are_errors_naming_the_file_section_and_key() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cases = [
        (
            "typo.toml",
            "[core]\nmax_pushez = 1\n",
            "[core] max_pushez: unknown field",
        ),
        (
            "type.toml",
            "[segmenter]\nseed = \"x\"\n",
            "[segmenter] seed: invalid type",
        ),
        (
            "range.toml",
            "[core]\ncertain_from = 100\n",
            "[core] certain_from = 100: out of range",
        ),
        ("flow.toml", "[flow]\nsor_omega = 2.5\n", "[flow] "),
    ];
    for (name, text, want) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, text).expect("write");
        for command in [
            &["bench", "--scenes", "1"][..],
            &["run", "--scene", "no_such_scene", "--out", "x"],
            &["flow", "a.png", "b.png", "-o", "c.flo"],
        ] {
            let err = failing(
                &riseg()
                    .args(command)
                    .arg("--config")
                    .arg(&path)
                    .output()
                    .expect("run riseg"),
            );
            assert!(
                err.contains(&format!("error: {}: {want}", path.display())),
                "{command:?} {name}: {err}"
            );
        }
    }
    let gone = dir.path().join("gone.toml");
    let err = failing(
        &riseg()
            .args(["demo", "--config"])
            .arg(&gone)
            .output()
            .expect("run riseg"),
    );
    assert!(
        err.contains(&format!("reading config file {}", gone.display())),
        "{err}"
    );
}
