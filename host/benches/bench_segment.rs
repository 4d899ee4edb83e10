//! The classical static segmenter at 640×480: a synthetic tabletop (boxes, exact
//! geometry) and, when the shared data folder is present, a real RealSense frame, each on
//! a pool of one thread and of two (the segmenter's rows run in parallel with the
//! `threads` feature; without it both pools measure one thread).
//!
//! `cargo bench -p riseg --bench bench_segment`

use core::hint::black_box;
use std::path::PathBuf;

use criterion::{Criterion, criterion_group, criterion_main};
use riseg::{
    segment::{ClassicalSegmenter, RgbdFrame, SegmenterParams, StaticSegmenter},
    testkit::segment::SyntheticTabletop,
};
use riseg_core::Intrinsics;

fn segment(c: &mut Criterion) {
    let mut g = c.benchmark_group("segment_640x480");
    let mut seg = ClassicalSegmenter::new(SegmenterParams::default()).expect("params");
    let pools = [1, 2].map(|threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        (if threads == 1 { "" } else { "_2_threads" }, pool)
    });

    let t = SyntheticTabletop::boxes(640, 480, 1).expect("scene");
    let frame = RgbdFrame::new(t.width, t.height, &t.rgb, &t.depth_m).expect("frame");
    for (suffix, pool) in &pools {
        g.bench_function(format!("synthetic_boxes{suffix}"), |b| {
            pool.install(|| b.iter(|| seg.segment(black_box(&frame), &t.intrinsics)));
        });
    }

    let root = std::env::var_os("RISEG_SHARED_DATA").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data")),
        PathBuf::from,
    );
    let demo = root.join("ucn-demo/data/demo");
    match (
        riseg::io::image::read_rgb8(&demo.join("000000-color.png")),
        riseg::io::image::read_gray16(&demo.join("000000-depth.png")),
    ) {
        (Ok(rgb), Ok(depth)) => {
            let depth_m: Vec<f32> = depth
                .as_slice()
                .iter()
                .map(|&d| f32::from(d) * 1e-3)
                .collect();
            let frame = RgbdFrame::new(640, 480, rgb.as_slice(), &depth_m).expect("frame");
            let k = Intrinsics::new(612.937, 613.173, 322.549, 248.158).expect("intrinsics");
            for (suffix, pool) in &pools {
                g.bench_function(format!("realsense_ucn_000000{suffix}"), |b| {
                    pool.install(|| b.iter(|| seg.segment(black_box(&frame), &k)));
                });
            }
        }
        _ => println!("skipping the real frame: {} not found", demo.display()),
    }
    g.finish();
}

criterion_group!(benches, segment);
criterion_main!(benches);
