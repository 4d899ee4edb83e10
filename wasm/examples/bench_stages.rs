//! Native side of `web/bench.sh`: one optical-flow call and one UpdateMask step of
//! riseg-wasm's `Session`, the code the browser runs, on the bundled packed scene (frames 0
//! and 1, 640x480), timed natively. Not a test: it prints the median of several runs.
//!
//! `cargo run --release -p riseg-wasm --features js --example bench_stages [SCENE_DIR] [RUNS]`

use std::{path::Path, time::Instant};

use riseg_wasm::{SceneFiles, Session};

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let dir = args
        .next()
        .unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/../web/scenes/packed").into());
    let runs: usize = args
        .next()
        .map_or(Ok(7), |r| r.parse())
        .map_err(|e| format!("{e}"))?;
    let dir = Path::new(&dir);
    let mut files = SceneFiles::new();
    add_folder(
        &mut files,
        dir,
        dir.file_name().and_then(|n| n.to_str()).unwrap_or("scene"),
    )?;
    let name = dir.file_name().and_then(|n| n.to_str()).unwrap_or("scene");
    // A JsError cannot be made off wasm32: an error panics here, which is fine for a bench.
    let mut session = Session::open(&files, name).map_err(|_| "open failed")?;
    let (mut flow_ms, mut update_ms) = (Vec::new(), Vec::new());
    for _ in 0..runs {
        session.restart();
        session.segment(0).map_err(|_| "segment 0")?;
        session.update(0).map_err(|_| "update 0")?;
        session.segment(1).map_err(|_| "segment 1")?;
        let start = Instant::now();
        session.flow(1).map_err(|_| "flow 1")?;
        flow_ms.push(start.elapsed().as_secs_f64() * 1e3);
        let start = Instant::now();
        session.update(1).map_err(|_| "update 1")?;
        update_ms.push(start.elapsed().as_secs_f64() * 1e3);
    }
    println!(
        "{{\"flow_ms\": {:.2}, \"update_mask_ms\": {:.2}, \"runs\": {runs}}}",
        median(&mut flow_ms),
        median(&mut update_ms)
    );
    Ok(())
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Adds every file below `dir` to `files`, named `prefix/<path below dir>`.
fn add_folder(files: &mut SceneFiles, dir: &Path, prefix: &str) -> Result<(), String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for entry in entries {
        let path = entry.map_err(|e| e.to_string())?.path();
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default();
        let below = format!("{prefix}/{name}");
        if path.is_dir() {
            add_folder(files, &path, &below)?;
        } else {
            let bytes = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
            files.add(&below, bytes);
        }
    }
    Ok(())
}
