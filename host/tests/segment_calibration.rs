//! Calibration of the classical segmenter's heatmap to FindAction's thresholds (paper
//! `l_u = 150`, `l_l = 120`), on the initial frames of simulated scenes (issue 7).
//!
//! Ground truth comes from the simulator: its label image and the pairs of objects whose
//! colliders are at most [`TOUCH_GAP_M`] apart ([`SimScene::touching_pairs`]).
//!
//! - **Band coverage.** A *merged contact pixel* is a pixel of object `a` with an
//!   8-neighbour of object `b` (`a ≠ b`, both non-zero, `(a, b)` a touching pair) where the
//!   segmenter gave both pixels one segment. Pooled over the scenes, at least half of these
//!   pixels must have heat in `120..=149`.
//! - **FindAction.** In every scene where the segmenter merged a touching pair (the segment
//!   covering most of `a` also covers most of `b`), FindAction on the initial heatmap and
//!   depth ([`Config::PAPER`]) must choose two certain clusters whose pixel centres lie on
//!   two different objects that touch, in at least 80 % of those scenes.
//!
//! Both print per-scene numbers (`cargo test --test segment_calibration -- --nocapture`).
//!
//! What the numbers say (seeds 0..40, the default window, which the heatmap's contact,
//! neck, step and pack rules and FindAction's region and pair rules were tuned on): 95.9 %
//! band coverage, FindAction right in 23 of 23 merged scenes. On seeds 40..80
//! (`RISEG_CALIB_FIRST_SEED=40`, not tuned on but looked at during development) coverage is
//! 96.6 % and FindAction is right
//! in 21 of 22. Before FindAction clustered certain pixels by connected regions and
//! required pairs to touch, it was right in 17 of 23 and 15 of 22, and would fail the
//! 80 % bar. Given a heatmap drawn from the ground truth itself (certain inside objects,
//! uncertain within 6 px of a touching neighbour), FindAction is right in 22 of 23 and 22
//! of 22.

use std::collections::HashSet;

use riseg::rig::workspace::ActionBuf;
use riseg::segment::{
    ClassicalSegmenter, HEAT_CERTAIN, HEAT_UNCERTAIN, RgbdFrame, SegmenterParams,
};
use riseg::sim::{SimScene, TOUCH_GAP_M};
use riseg_core::{Config, ImageView, action::find_action};

/// Scene seeds `FIRST_SEED..FIRST_SEED + SCENES`; `RISEG_CALIB_FIRST_SEED` moves the window
/// (to look at other scenes; the assertions are calibrated on the default window).
const SCENES: u64 = 40;
const FIRST_SEED: u64 = 0;

fn seeds() -> core::ops::Range<u64> {
    let first = std::env::var("RISEG_CALIB_FIRST_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(FIRST_SEED);
    first..first + SCENES
}

/// One scene's numbers.
struct SceneResult {
    seed: u64,
    /// Merged contact pixels (module docs).
    merged_contact_px: usize,
    /// Of those, pixels with heat in the uncertain band.
    in_band_px: usize,
    /// Touching pairs the segmenter merged.
    merged_pairs: Vec<(u16, u16)>,
    /// FindAction's pair: the ground-truth labels under the two certain centres.
    chosen: Option<(u16, u16)>,
    touching: HashSet<(u16, u16)>,
}

impl SceneResult {
    fn chose_touching_pair(&self) -> bool {
        self.chosen.is_some_and(|(a, b)| {
            a != 0 && b != 0 && a != b && self.touching.contains(&(a.min(b), a.max(b)))
        })
    }
}

fn run_scene(seed: u64) -> SceneResult {
    let mut sim = SimScene::new(seed).expect("simulated scene");
    let touching: HashSet<(u16, u16)> = sim.touching_pairs(TOUCH_GAP_M).into_iter().collect();
    let frame = sim.render();
    let (w, h) = (frame.rgb.width(), frame.rgb.height());
    let gt = frame.labels.as_slice();
    let depth_m = frame.depth_m.as_slice();
    let rgbd = RgbdFrame::new(w, h, frame.rgb.as_slice(), depth_m).expect("frame");
    let mut segmenter = ClassicalSegmenter::new(SegmenterParams::default()).expect("params");
    let seg = segmenter
        .segment_detailed(&rgbd, &frame.intrinsics)
        .unwrap_or_else(|e| panic!("seed {seed}: {e}"))
        .segmentation;
    let (pred, heat) = (seg.labels.as_slice(), seg.heatmap.as_slice());

    // Merged contact pixels and their heat.
    let (mut merged_contact_px, mut in_band_px) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let (a, p) = (gt[i], pred[i]);
            if a == 0 || p == 0 {
                continue;
            }
            let merged_contact = (-1isize..=1).any(|dy| {
                (-1isize..=1).any(|dx| {
                    let (qx, qy) = (x as isize + dx, y as isize + dy);
                    if qx < 0 || qy < 0 || qx >= w as isize || qy >= h as isize {
                        return false;
                    }
                    let q = qy as usize * w + qx as usize;
                    let b = gt[q];
                    b != 0 && b != a && touching.contains(&(a.min(b), a.max(b))) && pred[q] == p
                })
            });
            if merged_contact {
                merged_contact_px += 1;
                in_band_px += usize::from((HEAT_UNCERTAIN..HEAT_CERTAIN).contains(&heat[i]));
            }
        }
    }

    // Merged pairs: the segment covering most of one object covers most of the other.
    let objects = usize::from(gt.iter().copied().max().unwrap_or(0));
    let segments = seg.segment_count();
    let mut overlap = vec![vec![0usize; segments + 1]; objects + 1];
    for (&a, &p) in gt.iter().zip(pred) {
        overlap[usize::from(a)][usize::from(p)] += 1;
    }
    let main_segment = |a: u16| -> Option<usize> {
        let row = &overlap[usize::from(a)];
        let area: usize = row.iter().sum();
        let (p, &n) = row.iter().enumerate().skip(1).max_by_key(|&(_, n)| *n)?;
        (2 * n > area).then_some(p)
    };
    let mut merged_pairs: Vec<(u16, u16)> = touching
        .iter()
        .copied()
        .filter(|&(a, b)| {
            usize::from(a.max(b)) <= objects
                && main_segment(a).is_some_and(|p| main_segment(b) == Some(p))
        })
        .collect();
    merged_pairs.sort_unstable();

    // FindAction on the initial heatmap and depth.
    let cfg = Config::PAPER;
    let mut scratch = ActionBuf::new(&cfg, w, h);
    let report = find_action(
        &ImageView::packed(w, h, heat).expect("heatmap view"),
        &ImageView::packed(w, h, depth_m).expect("depth view"),
        &ImageView::packed(w, h, pred).expect("mask view"),
        &frame.intrinsics,
        &cfg,
        scratch.view(),
    )
    .expect("find_action");
    let label_at = |centre: [f32; 2]| -> u16 {
        let (x, y) = (centre[0].round(), centre[1].round());
        if x < 0.0 || y < 0.0 || x >= w as f32 || y >= h as f32 {
            return 0;
        }
        gt[y as usize * w + x as usize]
    };
    let chosen = report.pair().map(|pair| {
        let certain = report.certain();
        (
            label_at(certain[pair.pushed].centre_px),
            label_at(certain[pair.other].centre_px),
        )
    });
    SceneResult {
        seed,
        merged_contact_px,
        in_band_px,
        merged_pairs,
        chosen,
        touching,
    }
}

fn results() -> &'static [SceneResult] {
    static RESULTS: std::sync::OnceLock<Vec<SceneResult>> = std::sync::OnceLock::new();
    RESULTS.get_or_init(|| seeds().map(run_scene).collect())
}

#[test]
fn uncertain_band_covers_merged_contacts() {
    let (mut px, mut band) = (0, 0);
    for r in results() {
        println!(
            "seed {:2}: {:4} merged contact px, {:4} in 120..=149 ({:5.1} %)",
            r.seed,
            r.merged_contact_px,
            r.in_band_px,
            100.0 * r.in_band_px as f64 / r.merged_contact_px.max(1) as f64
        );
        px += r.merged_contact_px;
        band += r.in_band_px;
    }
    let share = band as f64 / px.max(1) as f64;
    println!(
        "pooled: {band} of {px} merged contact px in the band ({:.1} %)",
        100.0 * share
    );
    assert!(
        px > 0,
        "no scene has a merged contact: the test checks nothing"
    );
    assert!(share >= 0.5, "band covers {:.1} % < 50 %", 100.0 * share);
}

#[test]
fn find_action_picks_touching_objects_where_merged() {
    let (mut scenes, mut hits) = (0, 0);
    for r in results() {
        let hit = r.chose_touching_pair();
        println!(
            "seed {:2}: touching {:?}, merged {:?}, chosen {:?}{}",
            r.seed,
            {
                let mut t: Vec<_> = r.touching.iter().copied().collect();
                t.sort_unstable();
                t
            },
            r.merged_pairs,
            r.chosen,
            if r.merged_pairs.is_empty() {
                ""
            } else if hit {
                "  ok"
            } else {
                "  MISS"
            }
        );
        if !r.merged_pairs.is_empty() {
            scenes += 1;
            hits += usize::from(hit);
        }
    }
    println!("FindAction chose a touching pair in {hits} of {scenes} scenes with a merge");
    assert!(scenes > 0, "no scene has a merge: the test checks nothing");
    assert!(10 * hits >= 8 * scenes, "{hits} of {scenes} scenes < 80 %");
}
