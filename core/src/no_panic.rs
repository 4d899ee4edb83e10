//! riseg-core promises no panics on any input a caller can pass. These properties throw
//! arbitrary images (NaN and negative depth, huge or non-finite flow, random labels and
//! heatmaps, tiny and odd sizes) at the public entry points and require an `Ok` or an
//! `Err`, never a panic. (The fuzz targets of a later issue go further; this runs in
//! every `cargo test`.)

use std::{vec, vec::Vec};

use nalgebra::Point3;
use proptest::prelude::*;

use crate::{
    Config, ImageView, Intrinsics,
    action::find_action,
    frames::MotionInput,
    pipeline::update_mask,
    test_workspace::{ActionBuf, WorkspaceBuf},
};

#[path = "../tests/common/uniform.rs"]
mod uniform;

use uniform::uniform;

fn depth_value() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => uniform(0.3, 1.2),
        1 => Just(0.0f32),
        1 => Just(f32::NAN),
        1 => Just(-0.5f32),
        1 => Just(f32::INFINITY),
    ]
}

fn flow_value() -> impl Strategy<Value = [f32; 2]> {
    prop_oneof![
        6 => (uniform(-4.0, 4.0), uniform(-4.0, 4.0)).prop_map(|(x, y)| [x, y]),
        1 => Just([f32::NAN, 0.0]),
        1 => Just([1e30, -1e30]),
        1 => (uniform(-400.0, 400.0), uniform(-400.0, 400.0)).prop_map(|(x, y)| [x, y]),
    ]
}

/// A scene of `w × h` with blocky labels (so segments and frames exist) and noisy values.
#[derive(Debug, Clone)]
struct Scene {
    width: usize,
    height: usize,
    labels_t: Vec<u16>,
    static_t1: Vec<u16>,
    depth_t: Vec<f32>,
    depth_t1: Vec<f32>,
    flow: Vec<[f32; 2]>,
    heatmap: Vec<u8>,
}

fn scene() -> impl Strategy<Value = Scene> {
    (1usize..48, 1usize..40).prop_flat_map(|(width, height)| {
        let n = width * height;
        (
            proptest::collection::vec(0u16..4, n),
            proptest::collection::vec(0u16..4, n),
            proptest::collection::vec(depth_value(), n),
            proptest::collection::vec(depth_value(), n),
            proptest::collection::vec(flow_value(), n),
            proptest::collection::vec(any::<u8>(), n),
            1usize..8,
        )
            .prop_map(move |(lt, ls, dt, dt1, flow, heatmap, block)| {
                // Blocky labels: every pixel copies the label of its block's corner.
                let blocky = |l: &Vec<u16>| {
                    (0..n)
                        .map(|i| {
                            let (x, y) = (i % width / block * block, i / width / block * block);
                            l[y * width + x]
                        })
                        .collect::<Vec<u16>>()
                };
                Scene {
                    width,
                    height,
                    labels_t: blocky(&lt),
                    static_t1: blocky(&ls),
                    depth_t: dt,
                    depth_t1: dt1,
                    flow,
                    heatmap,
                }
            })
    })
}

fn small_config() -> Config {
    let mut cfg = Config::PAPER;
    cfg.frame_samples = 64;
    cfg.frame_max_side_m = 0.2;
    cfg.frame_min_side_m = 0.0;
    cfg.frame_rigid_tol_m = 0.5;
    cfg.min_segment_px = 3;
    cfg.kmeans_samples = 64;
    cfg.min_group_frames = 1;
    cfg
}

proptest! {
    #[test]
    fn update_mask_never_panics(s in scene(), seed in any::<u64>()) {
        let mut cfg = small_config();
        cfg.seed = seed;
        let (w, h) = (s.width, s.height);
        let k = Intrinsics::new(40.0, 40.0, w as f32 / 2.0, h as f32 / 2.0).unwrap();
        let input = MotionInput::new(
            ImageView::packed(w, h, &s.labels_t).unwrap(),
            ImageView::packed(w, h, &s.depth_t).unwrap(),
            ImageView::packed(w, h, &s.depth_t1).unwrap(),
            ImageView::packed(w, h, &s.flow).unwrap(),
            k,
        ).unwrap();
        let mut buf = WorkspaceBuf::new(&cfg, w, h);
        let px = buf.len().mask.pixels;
        let mut out = vec![0u16; px];
        let static_t1 = ImageView::packed(w, h, &s.static_t1).unwrap();
        if let Ok(report) = update_mask(&input, &static_t1, &cfg, &mut buf.view(), &mut out) {
            // Post-condition: background stays background, and no label exceeds the report.
            for (&o, &st) in out.iter().zip(&s.static_t1) {
                prop_assert!(st != 0 || o == 0);
                prop_assert!(o <= report.mask.max_label);
            }
            prop_assert!(report.frames.count <= cfg.frame_samples);
            prop_assert!(Point3::from(report.frames.space_origin.coords).coords.iter().all(|c| c.is_finite()));
        }
    }

    #[test]
    fn find_action_never_panics(s in scene(), seed in any::<u64>()) {
        let mut cfg = small_config();
        cfg.seed = seed;
        let (w, h) = (s.width, s.height);
        let k = Intrinsics::new(40.0, 40.0, w as f32 / 2.0, h as f32 / 2.0).unwrap();
        let mut buf = ActionBuf::new(&cfg, w, h);
        let heat = ImageView::packed(w, h, &s.heatmap).unwrap();
        let depth = ImageView::packed(w, h, &s.depth_t).unwrap();
        if let Ok(report) = find_action(&heat, &depth, &ImageView::packed(w, h, &s.static_t1).unwrap(), &k, &cfg, buf.view())
            && let Some(push) = report.push()
        {
            prop_assert!(push.direction_cam.iter().all(|c| c.is_finite()));
            prop_assert!((push.direction_cam.norm() - 1.0).abs() < 1e-3);
        }
    }
}
