//! `image_metrics` at 640×480 on seeded label maps: a typical tabletop (6 touching objects,
//! predicted shifted by (2, 1) px with two of them merged) and an over-segmented
//! prediction (the same ground truth against a 16×12 grid of 40 px cells).
//!
//! `cargo bench -p riseg --bench metrics`

use core::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use riseg::eval::metrics::image_metrics;
use riseg_core::rng::Pcg32;

const WIDTH: usize = 640;
const HEIGHT: usize = 480;

/// Six ellipses of 25-45 px radius in a row across the table, most touching a neighbour.
fn tabletop(seed: u64) -> Vec<u16> {
    let mut rng = Pcg32::new(seed);
    let mut labels = vec![0u16; WIDTH * HEIGHT];
    for object in 1..=6u16 {
        let cx = 160.0 + 55.0 * f32::from(object) + rng.unit() * 20.0;
        let cy = 200.0 + rng.unit() * 80.0;
        let (rx, ry) = (25.0 + rng.unit() * 20.0, 25.0 + rng.unit() * 20.0);
        for (i, label) in labels.iter_mut().enumerate() {
            let dx = ((i % WIDTH) as f32 - cx) / rx;
            let dy = ((i / WIDTH) as f32 - cy) / ry;
            if dx * dx + dy * dy <= 1.0 {
                *label = object;
            }
        }
    }
    labels
}

fn bench_metrics(c: &mut Criterion) {
    let gt = tabletop(7);
    let shifted_merged: Vec<u16> = (0..WIDTH * HEIGHT)
        .map(|i| {
            let (x, y) = (i % WIDTH, i / WIDTH);
            let label = if x >= 2 && y >= 1 {
                gt[i - WIDTH - 2]
            } else {
                0
            };
            if label == 2 { 1 } else { label }
        })
        .collect();
    let grid: Vec<u16> = (0..WIDTH * HEIGHT)
        .map(|i| {
            let cell = (i / WIDTH / 40) * 16 + (i % WIDTH) / 40 + 1;
            if gt[i] == 0 { 0 } else { cell as u16 }
        })
        .collect();

    c.bench_function("image_metrics 640x480, 6 objects, shifted + merged", |b| {
        b.iter(|| image_metrics(black_box(&gt), black_box(&shifted_merged), WIDTH, HEIGHT))
    });
    c.bench_function("image_metrics 640x480, 6 objects vs grid fragments", |b| {
        b.iter(|| image_metrics(black_box(&gt), black_box(&grid), WIDTH, HEIGHT))
    });
}

criterion_group!(benches, bench_metrics);
criterion_main!(benches);
