//! `riseg_core::pipeline::update_mask` on small arbitrary scenes: labels, depth at `t` and
//! `t+1`, flow, the static mask at `t+1`, intrinsics and a config near the paper's.
//!
//! Contract checked: no panic for any input; on `Ok`, background of the static mask stays
//! background, no label exceeds the reported `max_label`, at most `frame_samples` frames,
//! and the space origin is finite (depth past `MAX_DEPTH_M` is no reading and
//! `Intrinsics::check` bounds the camera, so every accepted input keeps it finite).

#![no_main]

use arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use riseg::rig::workspace::WorkspaceBuf;
use riseg_core::{ImageView, frames::MotionInput, pipeline::update_mask};
use riseg_fuzz::{blocky, config, depth_m, flow_px, intrinsics, labels, many, size};

fn run(u: &mut Unstructured<'_>) -> Result<()> {
    let cfg = config(u)?;
    let (w, h) = size(u)?;
    let k = intrinsics(u, w, h)?;
    let n = w * h;
    let max_label = u.int_in_range(0..=6)?;
    let block = u.int_in_range(1..=6)?;
    let mut labels_t = labels(u, n, max_label)?;
    blocky(&mut labels_t, w, block);
    let mut static_t1 = labels(u, n, max_label)?;
    blocky(&mut static_t1, w, block);
    let depth_t = many(u, n, depth_m)?;
    let depth_t1 = many(u, n, depth_m)?;
    let flow = many(u, n, flow_px)?;
    let Ok(input) = MotionInput::new(
        ImageView::packed(w, h, &labels_t).expect("packed labels"),
        ImageView::packed(w, h, &depth_t).expect("packed depth"),
        ImageView::packed(w, h, &depth_t1).expect("packed depth"),
        ImageView::packed(w, h, &flow).expect("packed flow"),
        k,
    ) else {
        return Ok(());
    };
    let mut buf = WorkspaceBuf::new(&cfg, w, h);
    let mut out = vec![0u16; buf.len().mask.pixels];
    let static_view = ImageView::packed(w, h, &static_t1).expect("packed labels");
    if let Ok(report) = update_mask(&input, &static_view, &cfg, &mut buf.view(), &mut out) {
        for (&o, &s) in out.iter().zip(&static_t1) {
            assert!(s != 0 || o == 0, "background became label {o}");
            assert!(o <= report.mask.max_label, "label {o} above max_label");
        }
        assert!(report.frames.count <= cfg.frame_samples);
        let origin = report.frames.space_origin;
        assert!(
            origin.coords.iter().all(|c| c.is_finite()),
            "origin {origin:?}, {k:?}"
        );
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let _ = run(&mut Unstructured::new(data));
});
