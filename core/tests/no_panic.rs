//! riseg-core promises no panics on any input a caller can pass. These properties throw
//! arbitrary images (NaN and negative depth, huge or non-finite flow, random labels and
//! heatmaps, tiny and odd sizes) at the public entry points and require an `Ok` or an
//! `Err`, never a panic. (The fuzz targets of a later issue go further; this runs in
//! every `cargo test`.)

use nalgebra::Point3;
use proptest::prelude::*;
use riseg_core::{
    Config, ImageView, Intrinsics, Pose, Twist,
    action::{ActionScratch, ActionScratchLen, find_action},
    frames::{BodyFrame, FrameSample, MotionInput},
    group::{GroupInfo, GroupScratch},
    mask::MaskScratch,
    pipeline::{Workspace, WorkspaceLen, update_mask},
};

#[path = "common/uniform.rs"]
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
        let len = WorkspaceLen::for_config(&cfg, w, h);
        let (n, px, seg) = (len.frames, len.mask.pixels, len.mask.segments);
        let mut samples = vec![FrameSample::EMPTY; n];
        let mut frames = vec![BodyFrame::EMPTY; n];
        let mut twists = vec![Twist::ZERO; n];
        let (mut fl, mut fg) = (vec![0u16; n], vec![0u16; n]);
        let mut groups = vec![GroupInfo::default(); n];
        let mut pair_bin = vec![0u8; len.group.pair_bin];
        let (mut parent, mut links, mut attach) = (vec![0; n], vec![0; n], vec![0; n]);
        let (mut key, mut source, mut segment, mut queue) = (vec![0; px], vec![0; px], vec![0; px], vec![0; px]);
        let mut claim = vec![0u16; px];
        let (mut ss, mut st, mut sk) = (vec![0; seg], vec![0; seg], vec![0; seg]);
        let mut seeds = vec![[0u32; 3]; len.mask.seeds];
        let mut motions = vec![Pose::identity(); len.mask.motions];
        let mut ws = Workspace {
            samples: &mut samples, frames: &mut frames, twists: &mut twists,
            frame_labels: &mut fl, frame_group: &mut fg, groups: &mut groups,
            group: GroupScratch { pair_bin: &mut pair_bin, parent: &mut parent, links: &mut links, attach: &mut attach },
            mask: MaskScratch {
                key: &mut key, source: &mut source, segment: &mut segment, queue: &mut queue,
                claim: &mut claim, segment_size: &mut ss, segment_target: &mut st, segment_key: &mut sk,
                seeds: &mut seeds, motions: &mut motions,
            },
        };
        let mut out = vec![0u16; px];
        let static_t1 = ImageView::packed(w, h, &s.static_t1).unwrap();
        if let Ok(report) = update_mask(&input, &static_t1, &cfg, &mut ws, &mut out) {
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
        let len = ActionScratchLen::for_config(&cfg, w, h);
        let mut certain = vec![0.0; len.certain];
        let mut uncertain = vec![0.0; len.uncertain];
        let mut dist2 = vec![0.0; len.dist2];
        let mut nearest = vec![0; len.nearest];
        let mut row_counts = vec![0; len.row_counts];
        let mut runs = vec![0; len.runs];
        let mut row_runs = vec![0; len.row_runs];
        let scratch = ActionScratch {
            certain: &mut certain, uncertain: &mut uncertain, dist2: &mut dist2,
            nearest: &mut nearest, row_counts: &mut row_counts, runs: &mut runs,
            row_runs: &mut row_runs,
        };
        let heat = ImageView::packed(w, h, &s.heatmap).unwrap();
        let depth = ImageView::packed(w, h, &s.depth_t).unwrap();
        if let Ok(report) = find_action(&heat, &depth, &k, &cfg, scratch)
            && let Some(push) = report.push()
        {
            prop_assert!(push.direction_cam.iter().all(|c| c.is_finite()));
            prop_assert!((push.direction_cam.norm() - 1.0).abs() < 1e-3);
        }
    }
}
