//! Writes the bench's UpdateMask step to a directory, for the numpy reference in `bench/`.
//!
//! The step is [`SyntheticStep::touching_boxes`] at 640×480, the same one
//! `benches/bench_update_mask.rs` times. Files:
//!
//! - `depth_t.npy`, `depth_t1.npy`: `float32 (H, W)`, metres;
//! - `merged_t.npy` (accumulated mask), `merged_t1.npy` (static mask), `truth_t1.npy`:
//!   `uint16 (H, W)`;
//! - `flow.npy`: `float32 (H, W, 2)`, `[dx, dy]` pixels;
//! - `riseg_t1.npy`: `uint16 (H, W)`, the mask riseg's own `update_mask` makes of the step;
//! - `intrinsics.json` (`fx fy cx cy width height`) and `config.json` ([`Config::PAPER`]).
//!
//! `cargo run --release -p riseg --example dump_synthetic_step -- DIR`

use std::{fs, path::Path};

use anyhow::{Context, Result, bail};
use riseg::rig::workspace::WorkspaceBuf;
use riseg::testkit::SyntheticStep;
use riseg_core::{Config, pipeline::update_mask};

fn main() -> Result<()> {
    let Some(dir) = std::env::args_os().nth(1) else {
        bail!("usage: dump_synthetic_step DIR");
    };
    let dir = Path::new(&dir);
    fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;

    let step = SyntheticStep::touching_boxes(640, 480)?;
    let (w, h) = (step.width, step.height);
    let cfg = Config::PAPER;
    let mut riseg_t1 = vec![0u16; w * h];
    let mut buf = WorkspaceBuf::new(&cfg, w, h);
    let report = update_mask(
        &step.input()?,
        &step.static_t1()?,
        &cfg,
        &mut buf.view(),
        &mut riseg_t1,
    )?;

    let image = [h, w];
    write_npy(dir, "depth_t", "<f4", &image, &f32_le(&step.depth_t))?;
    write_npy(dir, "depth_t1", "<f4", &image, &f32_le(&step.depth_t1))?;
    write_npy(dir, "merged_t", "<u2", &image, &u16_le(&step.merged_t))?;
    write_npy(dir, "merged_t1", "<u2", &image, &u16_le(&step.merged_t1))?;
    write_npy(dir, "truth_t1", "<u2", &image, &u16_le(&step.truth_t1))?;
    write_npy(dir, "riseg_t1", "<u2", &image, &u16_le(&riseg_t1))?;
    write_npy(
        dir,
        "flow",
        "<f4",
        &[h, w, 2],
        &f32_le(step.flow.as_flattened()),
    )?;

    let k = step.intrinsics;
    let intrinsics = format!(
        "{{\"fx\": {}, \"fy\": {}, \"cx\": {}, \"cy\": {}, \"width\": {w}, \"height\": {h}}}\n",
        k.fx, k.fy, k.cx, k.cy
    );
    write_text(dir, "intrinsics.json", &intrinsics)?;
    write_text(dir, "config.json", &config_json(&cfg))?;
    println!(
        "wrote the {w}x{h} synthetic step to {}; riseg: {} samples, {} frames, {} groups",
        dir.display(),
        report.frames.sampled,
        report.frames.count,
        report.grouping.count
    );
    Ok(())
}

/// The fields of `cfg` that one UpdateMask step reads, as a JSON object.
fn config_json(cfg: &Config) -> String {
    let fields = [
        ("frame_samples", cfg.frame_samples.to_string()),
        ("frame_max_side_m", cfg.frame_max_side_m.to_string()),
        ("frame_min_side_m", cfg.frame_min_side_m.to_string()),
        ("frame_min_sin", cfg.frame_min_sin.to_string()),
        ("depth_edge_m", cfg.depth_edge_m.to_string()),
        ("depth_window_px", cfg.depth_window_px.to_string()),
        ("depth_window_tol_m", cfg.depth_window_tol_m.to_string()),
        ("frame_rigid_tol_m", cfg.frame_rigid_tol_m.to_string()),
        ("length_scale_m", cfg.length_scale_m.to_string()),
        ("static_below_m", cfg.static_below_m.to_string()),
        ("kde_range_m", cfg.kde_range_m.to_string()),
        ("kde_bandwidth_m", cfg.kde_bandwidth_m.to_string()),
        ("link_posterior", cfg.link_posterior.to_string()),
        ("min_group_frames", cfg.min_group_frames.to_string()),
        ("min_segment_px", cfg.min_segment_px.to_string()),
        ("grow_tol_px", cfg.grow_tol_px.to_string()),
        ("merge_twist_m", cfg.merge_twist_m.to_string()),
        ("seed", cfg.seed.to_string()),
    ];
    let body: Vec<String> = fields
        .iter()
        .map(|(name, value)| format!("  \"{name}\": {value}"))
        .collect();
    format!("{{\n{}\n}}\n", body.join(",\n"))
}

fn f32_le(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn u16_le(values: &[u16]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// Writes `dir/name.npy` in NPY format 1.0: magic, version, header length, a Python dict
/// literal padded with spaces to a 64-byte boundary and ended by a newline, then the data.
fn write_npy(dir: &Path, name: &str, descr: &str, shape: &[usize], data: &[u8]) -> Result<()> {
    let dims: Vec<String> = shape.iter().map(ToString::to_string).collect();
    let trailing_comma = if shape.len() == 1 { "," } else { "" };
    let mut header = format!(
        "{{'descr': '{descr}', 'fortran_order': False, 'shape': ({}{trailing_comma}), }}",
        dims.join(", ")
    );
    // Magic (6) + version (2) + header length (2) + header + '\n'.
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat(unpadded.next_multiple_of(64) - unpadded));
    header.push('\n');
    let header_len = u16::try_from(header.len()).context("NPY header too long")?;

    let mut bytes = Vec::with_capacity(10 + header.len() + data.len());
    bytes.extend_from_slice(b"\x93NUMPY\x01\x00");
    bytes.extend_from_slice(&header_len.to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.extend_from_slice(data);
    let path = dir.join(format!("{name}.npy"));
    fs::write(&path, bytes).with_context(|| format!("writing {}", path.display()))
}

fn write_text(dir: &Path, name: &str, text: &str) -> Result<()> {
    let path = dir.join(name);
    fs::write(&path, text).with_context(|| format!("writing {}", path.display()))
}
