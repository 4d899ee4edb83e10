//! Time per call of the ONNX adapters on a 640x480 frame with the tiny test models, whose
//! own inference is a 1x1 or 8x8 convolution: what it prints is mostly the adapters'
//! overhead (normalising and laying out the inputs, sampling the outputs back).
//!
//! ```sh
//! python3 host/tests/onnx/make_models.py /tmp/riseg-onnx
//! cargo run --release -p riseg --features onnx --example onnx_adapter_time -- /tmp/riseg-onnx
//! ```

use std::{path::PathBuf, time::Instant};

use riseg::{
    flow::FlowEstimator as _,
    io::image::RgbImage,
    onnx::{OnnxFlow, OnnxSegmenter},
    segment::{RgbdFrame, StaticSegmenter as _},
};
use riseg_core::Intrinsics;

const CALLS: usize = 20;

/// Median milliseconds of `CALLS` calls of `f`.
fn median_ms(mut f: impl FnMut()) -> f64 {
    f(); // warm-up: the first run of a session allocates
    let mut times: Vec<f64> = (0..CALLS)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[CALLS / 2]
}

fn main() -> Result<(), Box<dyn core::error::Error>> {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .ok_or("usage: onnx_adapter_time MODELS_DIR")?,
    );
    let (w, h) = (640, 480);
    let first = RgbImage::from_fn(w, h, |x, y| [(x % 256) as u8, (y % 256) as u8, 128]);
    let second = RgbImage::from_fn(w, h, |x, y| [((x + 2) % 256) as u8, (y % 256) as u8, 128]);
    let depth: Vec<f32> = (0..w * h)
        .map(|i| 0.5 + 0.1 * (i % w) as f32 / w as f32)
        .collect();
    let k = Intrinsics::new(615.0, 615.0, 319.5, 239.5)?;

    let flow = OnnxFlow::load(&dir.join("flow_const.onnx"))?;
    let flow_ms = median_ms(|| {
        flow.estimate(first.view(), second.view()).expect("flow");
    });
    let mut seg = OnnxSegmenter::load(&dir.join("seg_masks.onnx"))?;
    let frame = RgbdFrame::new(w, h, first.as_slice(), &depth)?;
    let seg_ms = median_ms(|| {
        seg.segment(&frame, &k).expect("segment");
    });
    println!(
        "640x480, median of {CALLS} calls: OnnxFlow {flow_ms:.1} ms (flow_const.onnx), OnnxSegmenter {seg_ms:.1} ms (seg_masks.onnx, K = 2)"
    );
    Ok(())
}
