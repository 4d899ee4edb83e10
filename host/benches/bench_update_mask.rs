//! UpdateMask without flow at 640×480, n = 1000, stage by stage, one thread.
//!
//! `cargo bench -p riseg --bench bench_update_mask`

use core::hint::black_box;
use criterion::{Criterion, criterion_group, criterion_main};
use riseg::rig::workspace::WorkspaceBuf;
use riseg::testkit::SyntheticStep;
use riseg_core::{
    Config,
    frames::{compute_twists, create_frames},
    group::group_frames,
    mask::{FrameGroups, correct_mask},
    pipeline::update_mask,
};

fn stages(c: &mut Criterion) {
    let step = SyntheticStep::touching_boxes(640, 480).expect("scene");
    let input = step.input().expect("input");
    let static_t1 = step.static_t1().expect("static mask");
    let cfg = Config::PAPER;
    let mut buf = WorkspaceBuf::new(&cfg, 640, 480);
    let mut out = vec![0u16; 640 * 480];

    let mut g = c.benchmark_group("update_mask_640x480_n1000");
    g.bench_function("total", |b| {
        b.iter(|| {
            update_mask(
                &input,
                &static_t1,
                &cfg,
                &mut buf.view(),
                black_box(&mut out),
            )
        })
    });
    // Leave the workspace filled by one full step, then time each stage on its inputs.
    let report = update_mask(&input, &static_t1, &cfg, &mut buf.view(), &mut out).expect("step");
    let n = report.frames.count;
    let origin = report.frames.space_origin;
    let mut ws = buf.view();
    g.bench_function("frames", |b| {
        b.iter(|| create_frames(&input, &cfg, ws.samples, ws.frames))
    });
    g.bench_function("twists", |b| {
        b.iter(|| compute_twists(&ws.frames[..n], &origin, &mut ws.twists[..n]))
    });
    for (l, f) in ws.frame_labels.iter_mut().zip(ws.frames.iter()).take(n) {
        *l = f.label;
    }
    g.bench_function("grouping", |b| {
        b.iter(|| {
            group_frames(
                &ws.twists[..n],
                &ws.frame_labels[..n],
                &cfg,
                &mut ws.group,
                &mut ws.frame_group[..n],
                ws.groups,
            )
        })
    });
    let groups = FrameGroups {
        frames: &ws.frames[..n],
        frame_group: &ws.frame_group[..n],
        groups: &ws.groups[..report.grouping.count],
        space_origin: origin,
    };
    g.bench_function("mask", |b| {
        b.iter(|| {
            correct_mask(
                &input,
                &static_t1,
                &groups,
                &cfg,
                &mut ws.mask,
                black_box(&mut out),
            )
        })
    });
    g.finish();
}

criterion_group!(benches, stages);
criterion_main!(benches);
