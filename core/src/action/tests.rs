//! FindAction on synthetic heatmaps: every step of the module docs, end to end.

extern crate std;

use std::{vec, vec::Vec};

use super::*;
use crate::camera::{MAX_CAMERA_PX, MIN_FOCAL_PX};
use crate::math::{round, sqrt};
use crate::test_workspace::ActionBuf;

const W: usize = 320;
const H: usize = 240;
const Z_M: Real = 0.6;

fn intrinsics() -> Intrinsics {
    Intrinsics::new(300.0, 300.0, 159.5, 119.5).unwrap()
}

/// A synthetic heatmap over a flat depth plane (1 px ≈ 2 mm at 0.6 m, fx = 300).
struct Scene {
    heat: Vec<u8>,
    depth: Vec<Real>,
}

impl Scene {
    fn new() -> Self {
        Self {
            heat: vec![0; W * H],
            depth: vec![Z_M; W * H],
        }
    }

    fn disc(&mut self, cx: Real, cy: Real, r: Real, v: u8) -> &mut Self {
        for y in 0..H {
            for x in 0..W {
                let (dx, dy) = (x as Real - cx, y as Real - cy);
                if dx * dx + dy * dy <= r * r {
                    self.heat[y * W + x] = v;
                }
            }
        }
        self
    }

    /// Pixels with `x0 <= x < x1`, `y0 <= y < y1`.
    fn rect(&mut self, x0: usize, y0: usize, x1: usize, y1: usize, v: u8) -> &mut Self {
        for y in y0..y1 {
            for x in x0..x1 {
                self.heat[y * W + x] = v;
            }
        }
        self
    }

    fn heat_at(&self, p: [Real; 2]) -> u8 {
        self.heat[round(p[1]) as usize * W + round(p[0]) as usize]
    }

    fn run(&self, cfg: &Config) -> Result<ActionReport, Error> {
        run(W, H, &self.heat, &self.depth, &intrinsics(), cfg)
    }
}

/// FindAction with an all-background mask: the push starts at the heatmap's rim.
fn run(
    w: usize,
    h: usize,
    heat: &[u8],
    depth: &[Real],
    k: &Intrinsics,
    cfg: &Config,
) -> Result<ActionReport, Error> {
    run_masked(w, h, heat, depth, &vec![0; w * h], k, cfg)
}

fn run_masked(
    w: usize,
    h: usize,
    heat: &[u8],
    depth: &[Real],
    mask: &[u16],
    k: &Intrinsics,
    cfg: &Config,
) -> Result<ActionReport, Error> {
    find_action(
        &ImageView::packed(w, h, heat)?,
        &ImageView::packed(w, h, depth)?,
        &ImageView::packed(w, h, mask)?,
        k,
        cfg,
        ActionBuf::new(cfg, w, h).view(),
    )
}

/// Index of the cluster whose pixel centre is within 3 px of `(x, y)`.
fn find(clusters: &[Cluster], x: Real, y: Real) -> Option<usize> {
    clusters.iter().position(|c| {
        let (dx, dy) = (c.centre_px[0] - x, c.centre_px[1] - y);
        dx * dx + dy * dy < 9.0
    })
}

const A: (Real, Real) = (110.0, 130.0);
const B: (Real, Real) = (150.0, 130.0);
const C: (Real, Real) = (110.0, 90.0);
const R_PX: Real = 15.0;

/// Three certain discs: A–B 40 px (8 cm), A–C 40 px (8 cm), B–C 11.3 cm; an uncertain
/// band only in the gap between A and B.
fn three_blobs() -> Scene {
    let mut s = Scene::new();
    s.disc(A.0, A.1, R_PX, 255)
        .disc(B.0, B.1, R_PX, 255)
        .disc(C.0, C.1, R_PX, 255)
        .rect(126, 118, 135, 143, 130);
    s
}

#[test]
fn picks_the_pair_with_the_uncertain_band_between_them() {
    let s = three_blobs();
    let report = s.run(&Config::PAPER).unwrap();
    let certain = report.certain();
    assert_eq!(certain.len(), 3, "{certain:?}");
    let a = find(certain, A.0, A.1).expect("cluster at A");
    let b = find(certain, B.0, B.1).expect("cluster at B");
    assert!(find(certain, C.0, C.1).is_some());
    let pair = report.pair().expect("a pair qualifies");
    let mut got = [pair.pushed, pair.other];
    got.sort_unstable();
    let mut want = [a, b];
    want.sort_unstable();
    assert_eq!(got, want);
    assert!((pair.pair_dist_m - 0.08).abs() < 0.005, "{pair:?}");
    assert!(pair.uncertain_dist_m <= Config::PAPER.uncertain_max_m);
    // Every uncertain centre lies in the band.
    for u in report.uncertain() {
        assert!((125.0..136.0).contains(&u.centre_px[0]), "{u:?}");
    }
    let push = report.push().expect("a push");
    assert_eq!(push.target_px, certain[pair.pushed].centre_px);
    assert!(s.heat_at(push.start_px) < Config::PAPER.certain_from);
    assert_eq!(push.length_m, 0.02);
}

/// An uncertain centre at pixel `(x, y)` (for [`ranked`]).
fn uncertain_at(x: Real, y: Real) -> Cluster {
    Cluster {
        centre_px: [x, y],
        centre_cam_m: intrinsics().back_project(x, y, Z_M),
        samples: 100,
    }
}

/// FindAction's certain clusters of `s` and what `then` makes of their region map (with
/// the PRNG where the pair ranking leaves it).
fn with_region_map<R>(
    s: &Scene,
    cfg: &Config,
    then: impl FnOnce(&RegionMap<'_>, &mut Pcg32) -> R,
) -> (Vec<Cluster>, R) {
    let k = intrinsics();
    let heat = ImageView::packed(W, H, &s.heat).unwrap();
    let depth = ImageView::packed(W, H, &s.depth).unwrap();
    let len = ActionScratchLen::for_config(cfg, W, H);
    let (mut cbuf, mut ubuf) = (vec![0.0; len.certain], vec![0.0; len.uncertain]);
    let mut rows = vec![0u32; len.row_counts];
    let mut runs_buf = vec![0u32; len.runs];
    let mut row_runs = vec![0u32; len.row_runs];
    let mut nearest = vec![0u32; len.nearest];
    let mut cp = Planes::split(&mut cbuf, len.samples).unwrap();
    let mut up = Planes::split(&mut ubuf, len.samples).unwrap();
    let mut rng = Pcg32::new(cfg.seed);
    let (nc, _) = sample_classes(&heat, &depth, cfg, &mut rng, &mut cp, &mut up, &mut rows);
    let mut runs = RunPlanes::split(&mut runs_buf, len.max_runs).unwrap();
    let n_runs = label_runs(&heat, cfg.certain_from, &mut runs, &mut row_runs);
    let found = certain_clusters(
        &mut runs,
        n_runs,
        &row_runs,
        &cp.prefix(nc),
        &mut nearest,
        &k,
        cfg,
    );
    let map = RegionMap {
        heatmap: &heat,
        runs: runs.view(n_runs),
        row_runs: &row_runs,
        clusters: &found.clusters,
        region_of: &found.region_of,
        cfg,
    };
    let made = then(&map, &mut rng);
    (found.clusters.to_vec(), made)
}

/// FindAction's certain clusters of `s`, and its qualifying pairs, best first, against
/// the given uncertain centres (instead of k-means ones).
fn ranked(s: &Scene, cfg: &Config, uncertain: &[Cluster]) -> (Vec<Cluster>, Vec<Pair>) {
    with_region_map(s, cfg, |map, _| rank_pairs(map, uncertain, cfg).to_vec())
}

/// The push FindAction makes on `s` with `mask`, against the given uncertain centres
/// (instead of k-means ones), and the certain clusters.
fn chosen(
    s: &Scene,
    mask: &[u16],
    cfg: &Config,
    uncertain: &[Cluster],
) -> (Vec<Cluster>, Option<(Pair, Push)>) {
    let mask = ImageView::packed(W, H, mask).unwrap();
    with_region_map(s, cfg, |map, rng| {
        let pairs = rank_pairs(map, uncertain, cfg);
        choose_push(map, &mask, &pairs, &intrinsics(), cfg, rng)
    })
}

/// Sorted cluster indices of a pair.
fn members(p: &Pair) -> [usize; 2] {
    [p.pushed.min(p.other), p.pushed.max(p.other)]
}

/// A, B and C with uncertain bands across the A–B and the A–C gaps.
fn three_blobs_two_bands() -> Scene {
    let mut s = three_blobs();
    s.rect(100, 106, 121, 115, 130);
    s
}

#[test]
fn the_pair_nearest_an_uncertain_centre_wins_over_another_qualifying_pair() {
    let s = three_blobs_two_bands();
    let cfg = Config::PAPER;
    // One centre on the A–B segment, one 1 cm beside the A–C segment.
    let (certain, pairs) = ranked(
        &s,
        &cfg,
        &[uncertain_at(130.0, 130.0), uncertain_at(115.0, 110.0)],
    );
    let a = find(&certain, A.0, A.1).expect("A");
    let b = find(&certain, B.0, B.1).expect("B");
    let c = find(&certain, C.0, C.1).expect("C");
    let want = |i: usize, j: usize| [i.min(j), i.max(j)];
    assert_eq!(
        pairs.iter().map(members).collect::<Vec<_>>(),
        [want(a, b), want(a, c)]
    );
    assert!((pairs[1].uncertain_dist_m - 0.01).abs() < 1e-3, "{pairs:?}");
    // Swapped: the centre on the A–C segment wins.
    let (_, pairs) = ranked(
        &s,
        &cfg,
        &[uncertain_at(130.0, 136.0), uncertain_at(110.0, 110.0)],
    );
    assert_eq!(
        pairs.iter().map(members).collect::<Vec<_>>(),
        [want(a, c), want(a, b)]
    );
    // End to end with k-means centres: a pair across one of the two bands.
    let report = s.run(&cfg).unwrap();
    let pair = report.pair().expect("pair");
    let got = members(&pair);
    assert!(got == want(a, b) || got == want(a, c), "{pair:?}");
}

#[test]
fn no_pair_without_an_uncertain_centre_within_d_b() {
    let s = three_blobs();
    let cfg = Config::PAPER;
    // 3.4 cm beside the A–B segment: farther than d_b = 3 cm. The A–B line crosses the
    // band, so the pair is a seam pair (pushed only to split a segment); the paper's
    // choice has no pair.
    let (_, pairs) = ranked(&s, &cfg, &[uncertain_at(130.0, 147.0)]);
    assert!(pairs.iter().all(|p| is_seam(p, &cfg)), "{pairs:?}");
    let paper = Config {
        push_carry_frac: 0.0,
        ..cfg
    };
    let (_, pairs) = ranked(&s, &paper, &[uncertain_at(130.0, 147.0)]);
    assert!(pairs.is_empty(), "{pairs:?}");
    // 2.6 cm beside it: within d_b.
    let (_, pairs) = ranked(&s, &cfg, &[uncertain_at(130.0, 143.0)]);
    assert_eq!(pairs.len(), 1, "{pairs:?}");
    assert!((pairs[0].uncertain_dist_m - 0.026).abs() < 1e-3);
    // And without any uncertain pixel there is nothing to do.
    let mut s = Scene::new();
    s.disc(140.0, 120.0, R_PX, 255)
        .disc(172.0, 120.0, R_PX, 255);
    let report = s.run(&cfg).unwrap();
    assert!(report.uncertain().is_empty() && report.push().is_none());
}

#[test]
fn none_when_the_only_pair_is_farther_than_d_a() {
    // 80 px = 16 cm apart, uncertain band between them.
    let mut s = Scene::new();
    s.disc(100.0, 120.0, R_PX, 255)
        .disc(180.0, 120.0, R_PX, 255)
        .rect(116, 110, 165, 131, 130);
    let report = s.run(&Config::PAPER).unwrap();
    assert_eq!(report.certain().len(), 2);
    assert!(!report.uncertain().is_empty());
    assert_eq!(report.pair(), None);
    assert_eq!(report.push(), None);
    // Control: the same scene qualifies once d_a admits the pair.
    let mut cfg = Config::PAPER;
    cfg.pair_max_m = 0.2;
    let report = s.run(&cfg).unwrap();
    assert!(report.push().is_some());
}

/// A 2×2 pack as the heatmap draws it: a 12 cm square (60 px) with a 4 mm rim and
/// uncertain bands 1 cm either side of the two cut lines through its middle, so four
/// certain cells of about 4.6 cm.
const PACK: (usize, usize, usize) = (130, 90, 60);

fn pack_2x2() -> Scene {
    let (x0, y0, side) = PACK;
    let mut s = Scene::new();
    s.rect(x0, y0, x0 + side, y0 + side, 100) // rim (below l_l)
        .rect(x0 + 2, y0 + 2, x0 + side - 2, y0 + side - 2, 255)
        .rect(
            x0 + side / 2 - 5,
            y0 + 2,
            x0 + side / 2 + 6,
            y0 + side - 2,
            130,
        )
        .rect(
            x0 + 2,
            y0 + side / 2 - 5,
            x0 + side - 2,
            y0 + side / 2 + 6,
            130,
        );
    s
}

#[test]
fn a_2x2_pack_is_sheared_across_a_cut_from_outside_the_pack() {
    let s = pack_2x2();
    let (x0, y0, side) = PACK;
    let inner = |p: [Real; 2]| {
        let (x, y) = (round(p[0]) as usize, round(p[1]) as usize);
        (x0 + 2..x0 + side - 2).contains(&x) && (y0 + 2..y0 + side - 2).contains(&y)
    };
    let mut vertical_push = [false; 2];
    for seed in 0..16 {
        let mut cfg = Config::PAPER;
        cfg.seed = seed;
        let report = s.run(&cfg).unwrap();
        let certain = report.certain();
        assert_eq!(certain.len(), 4, "seed {seed}: one cluster per cell");
        let pair = report.pair().expect("a pair across a cut");
        let (ci, cj) = (certain[pair.pushed], certain[pair.other]);
        // Adjacent cells (34 px apart), not diagonal ones (48 px).
        let (dx, dy) = (
            cj.centre_px[0] - ci.centre_px[0],
            cj.centre_px[1] - ci.centre_px[1],
        );
        assert!(
            (dx.abs() < 2.0 && (dy.abs() - 34.0).abs() < 2.0)
                || (dy.abs() < 2.0 && (dx.abs() - 34.0).abs() < 2.0),
            "seed {seed}: {pair:?} {certain:?}"
        );
        let push = report.push().expect("push");
        assert_eq!(push.target_px, ci.centre_px);
        // Starts off the object and outside the pack's interior (never in a cut).
        assert!(s.heat_at(push.start_px) < cfg.uncertain_from, "seed {seed}");
        assert!(!inner(push.start_px), "seed {seed}: {push:?}");
        // A shear: perpendicular to the pair, into the pack.
        let pair_dir = (cj.centre_cam_m - ci.centre_cam_m).normalize();
        assert!(
            pair_dir.dot(&push.direction_cam).abs() < 0.05,
            "seed {seed}"
        );
        let inward = (ci.centre_cam_m - push.start_cam_m).normalize();
        assert!(inward.dot(&push.direction_cam) > 0.99);
        vertical_push[usize::from(push.direction_cam.y.abs() > 0.9)] = true;
    }
    assert!(
        vertical_push[0] && vertical_push[1],
        "both cut lines are used"
    );
}

#[test]
fn the_other_cluster_is_pushed_when_the_pushed_one_is_enclosed() {
    // M (small) touches R (larger) across a band; above and below M, object pixels
    // lead to T and D (more than d_a from M): no walk from M reaches the table.
    let mut s = Scene::new();
    s.rect(140, 40, 161, 201, 130) // object column through M
        .disc(150.0, 60.0, 10.0, 255) // T
        .disc(150.0, 180.0, 10.0, 255) // D
        .disc(150.0, 120.0, 8.0, 255) // M
        .rect(158, 112, 171, 129, 130) // M–R band
        .disc(180.0, 120.0, 12.0, 255); // R
    let mut cfg = Config::PAPER;
    cfg.uncertain_max_m = 0.2; // any uncertain centre qualifies the pair
    for seed in 0..8 {
        cfg.seed = seed;
        let report = s.run(&cfg).unwrap();
        let certain = report.certain();
        let m = find(certain, 150.0, 120.0).expect("M");
        let r = find(certain, 180.0, 120.0).expect("R");
        let pair = report.pair().expect("pair");
        assert_eq!((pair.pushed, pair.other), (r, m), "seed {seed}");
        let push = report.push().expect("push");
        assert_eq!(push.target_px, certain[r].centre_px);
        assert!(s.heat_at(push.start_px) < cfg.uncertain_from);
        assert!(push.direction_cam.y.abs() > 0.99, "{push:?}");
    }
}

#[test]
fn one_object_is_one_cluster_and_a_region_much_longer_than_an_object_is_split() {
    let cfg = Config::PAPER;
    // A 5 cm square: one cluster at its centre.
    let mut s = Scene::new();
    s.rect(100, 100, 125, 125, 255);
    let report = s.run(&cfg).unwrap();
    assert_eq!(report.certain().len(), 1, "{:?}", report.certain());
    let c = report.certain()[0];
    assert!((c.centre_px[0] - 112.0).abs() < 0.5 && (c.centre_px[1] - 112.0).abs() < 0.5);
    // A 15 cm × 5 cm bar (longer than region_max_len_m): round(15 / 5) = 3 pieces
    // along it, 5 cm apart.
    let mut s = Scene::new();
    s.rect(100, 100, 175, 125, 255);
    let report = s.run(&cfg).unwrap();
    let mut xs: Vec<Real> = report.certain().iter().map(|c| c.centre_px[0]).collect();
    xs.sort_by(Real::total_cmp);
    assert_eq!(xs.len(), 3, "{:?}", report.certain());
    for (x, want) in xs.iter().zip([112.0, 137.0, 162.0]) {
        assert!((x - want).abs() < 3.0, "{xs:?}");
    }
    for c in report.certain() {
        assert!((c.centre_px[1] - 112.0).abs() < 1.0);
    }
}

#[test]
fn a_2x3_pack_with_no_cut_is_split_into_six_pieces() {
    // Six 5 cm boxes, three along x and two along y, whose cuts the heatmap missed: one
    // certain region of 15 cm × 10 cm, split 3 × 2 (one piece per box), not 3 × 1.
    let mut s = Scene::new();
    s.rect(100, 100, 175, 150, 255);
    let report = s.run(&Config::PAPER).unwrap();
    let certain = report.certain();
    assert_eq!(certain.len(), 6, "{certain:?}");
    for (x, y) in [112.0, 137.0, 162.0]
        .into_iter()
        .flat_map(|x| [112.0, 137.0].map(|y| (x, y)))
    {
        assert!(
            certain
                .iter()
                .any(|c| { (c.centre_px[0] - x).abs() < 3.0 && (c.centre_px[1] - y).abs() < 3.0 }),
            "no piece near ({x}, {y}): {certain:?}"
        );
    }
}

#[test]
fn fragments_below_the_minimum_area_are_not_clusters() {
    // A disc, and a 3×3 certain speck (0.36 cm²) across an uncertain band from it.
    let mut s = Scene::new();
    s.disc(120.0, 120.0, R_PX, 255)
        .rect(136, 110, 146, 131, 130)
        .rect(140, 119, 143, 122, 255);
    let cfg = Config::PAPER;
    let report = s.run(&cfg).unwrap();
    assert_eq!(report.certain().len(), 1, "{:?}", report.certain());
    assert_eq!(report.pair(), None);
    // Control: a lower minimum keeps the speck, and the two form a pair.
    let mut cfg = cfg;
    cfg.region_min_area_m2 = 0.2e-4;
    let report = s.run(&cfg).unwrap();
    assert_eq!(report.certain().len(), 2, "{:?}", report.certain());
    assert!(report.pair().is_some());
}

#[test]
fn no_pair_across_the_table() {
    // Two discs 8 cm apart; an uncertain patch in the middle of the gap, with 8 px
    // (1.6 cm) of table between it and the discs.
    let mut s = Scene::new();
    s.disc(110.0, 120.0, 12.0, 255)
        .disc(150.0, 120.0, 12.0, 255)
        .rect(127, 112, 134, 129, 130);
    let cfg = Config::PAPER;
    let on_segment = [uncertain_at(130.0, 120.0)];
    let (certain, pairs) = ranked(&s, &cfg, &on_segment);
    assert_eq!(certain.len(), 2);
    assert!(pairs.is_empty(), "{pairs:?}");
    assert_eq!(s.run(&cfg).unwrap().pair(), None);
    // Control: with the gap filled, the pair qualifies.
    s.rect(122, 112, 139, 129, 130);
    let (_, pairs) = ranked(&s, &cfg, &on_segment);
    assert_eq!(pairs.len(), 1);
    assert!(s.run(&cfg).unwrap().push().is_some());
}

#[test]
fn no_pair_through_a_third_object() {
    // A, M, B in a row, 4.8 cm apart, with bands between neighbours: A–B (9.6 cm,
    // within d_a) crosses M, so only A–M and M–B are pairs.
    let mut s = Scene::new();
    s.disc(100.0, 120.0, 9.0, 255)
        .disc(124.0, 120.0, 9.0, 255)
        .disc(148.0, 120.0, 9.0, 255)
        .rect(108, 112, 117, 129, 130)
        .rect(132, 112, 141, 129, 130);
    let cfg = Config::PAPER;
    let (certain, pairs) = ranked(&s, &cfg, &[uncertain_at(124.0, 120.0)]);
    let a = find(&certain, 100.0, 120.0).unwrap();
    let m = find(&certain, 124.0, 120.0).unwrap();
    let b = find(&certain, 148.0, 120.0).unwrap();
    let mut got: Vec<[usize; 2]> = pairs.iter().map(members).collect();
    got.sort_unstable();
    let mut want = vec![[a.min(m), a.max(m)], [m.min(b), m.max(b)]];
    want.sort_unstable();
    assert_eq!(got, want, "{pairs:?}");
}

#[test]
fn a_one_pixel_diagonal_cut_separates_two_regions() {
    // A 6 cm square cut along its anti-diagonal by a one-pixel uncertain line; the
    // two halves touch diagonally across it (8-connected) but are two regions.
    let mut s = Scene::new();
    s.rect(100, 100, 130, 130, 255);
    for i in 0..30 {
        s.heat[(100 + i) * W + 129 - i] = 130;
    }
    let report = s.run(&Config::PAPER).unwrap();
    let certain = report.certain();
    assert_eq!(certain.len(), 2, "{certain:?}");
    let sides: Vec<bool> = certain
        .iter()
        .map(|c| c.centre_px[0] + c.centre_px[1] < 229.0)
        .collect();
    assert!(sides[0] != sides[1], "{certain:?}");
    let pair = report.pair().expect("the halves touch across the cut");
    assert!(report.push().is_some(), "{pair:?}");
}

#[test]
fn runs_label_the_4_connected_certain_regions() {
    let mut rng = Pcg32::new(17);
    for trial in 0..40 {
        let (w, h) = (1 + rng.below(40) as usize, 1 + rng.below(30) as usize);
        let density = rng.below(100);
        let heat: Vec<u8> = (0..w * h)
            .map(|_| if rng.below(100) < density { 200 } else { 130 })
            .collect();
        let view = ImageView::packed(w, h, &heat).unwrap();
        let len = ActionScratchLen::for_config(&Config::PAPER, w, h);
        let mut buf = vec![0u32; len.runs];
        let mut row_runs = vec![0u32; len.row_runs];
        let mut runs = RunPlanes::split(&mut buf, len.max_runs).unwrap();
        let n = label_runs(&view, 150, &mut runs, &mut row_runs);
        assert!(n <= len.max_runs);
        let view_runs = Runs {
            x0: &runs.x0[..n],
            x1: &runs.x1[..n],
            aux: &runs.aux[..n],
        };
        // Reference: flood fill over 4-neighbours.
        let certain = |x: usize, y: usize| heat[y * w + x] >= 150;
        let mut comp = vec![usize::MAX; w * h];
        let mut next = 0;
        for start in 0..w * h {
            if !certain(start % w, start / w) || comp[start] != usize::MAX {
                continue;
            }
            let mut stack = vec![start];
            comp[start] = next;
            while let Some(i) = stack.pop() {
                let (x, y) = (i % w, i / w);
                let around = [
                    (x > 0).then(|| i - 1),
                    (x + 1 < w).then(|| i + 1),
                    (y > 0).then(|| i - w),
                    (y + 1 < h).then(|| i + w),
                ];
                for j in around.into_iter().flatten() {
                    if certain(j % w, j / w) && comp[j] == usize::MAX {
                        comp[j] = next;
                        stack.push(j);
                    }
                }
            }
            next += 1;
        }
        // Same partition: the root run of each certain pixel maps one-to-one to the
        // reference component.
        let mut root_of_comp = vec![usize::MAX; next];
        let mut comp_of_root = std::collections::BTreeMap::new();
        for y in 0..h {
            for x in 0..w {
                let run = view_runs.at(&row_runs, x, y);
                assert_eq!(run.is_some(), certain(x, y), "trial {trial} ({x}, {y})");
                let Some(r) = run else { continue };
                let root = crate::union_find::find(runs.parent, r);
                let c = comp[y * w + x];
                if root_of_comp[c] == usize::MAX {
                    root_of_comp[c] = root;
                }
                assert_eq!(root_of_comp[c], root, "trial {trial}");
                assert_eq!(*comp_of_root.entry(root).or_insert(c), c, "trial {trial}");
            }
        }
    }
}

#[test]
fn push_starts_outside_the_cluster_perpendicular_and_points_at_its_centre() {
    let s = three_blobs();
    let k = intrinsics();
    let mut sides = [false; 2];
    for seed in 0..12 {
        let mut cfg = Config::PAPER;
        cfg.seed = seed;
        let report = s.run(&cfg).unwrap();
        let pair = report.pair().expect("pair");
        let push = report.push().expect("push");
        let certain = report.certain();
        let ci = certain[pair.pushed];
        let cj = certain[pair.other];
        // Off the object (table), just outside the pushed disc.
        assert!(
            s.heat_at(push.start_px) < cfg.uncertain_from,
            "seed {seed}: {push:?}"
        );
        let (sx, sy) = (
            push.start_px[0] - ci.centre_px[0],
            push.start_px[1] - ci.centre_px[1],
        );
        let r = sqrt(sx * sx + sy * sy);
        assert!(
            (r - R_PX).abs() < 2.0,
            "seed {seed}: start {r} px from centre"
        );
        sides[usize::from(sy > 0.0)] = true;
        // Perpendicular to the pair (pixels and metres) within 10 degrees.
        let pair_px = Vector3::new(
            cj.centre_px[0] - ci.centre_px[0],
            cj.centre_px[1] - ci.centre_px[1],
            0.0,
        )
        .normalize();
        let to_centre_px = Vector3::new(-sx, -sy, 0.0).normalize();
        let sin10 = 0.1737;
        assert!(pair_px.dot(&to_centre_px).abs() < sin10, "seed {seed}");
        let pair_m = (cj.centre_cam_m - ci.centre_cam_m).normalize();
        assert!(pair_m.dot(&push.direction_cam).abs() < sin10, "seed {seed}");
        // Points at the centre; unit length; starts at the object's depth.
        let to_centre_m = (ci.centre_cam_m - push.start_cam_m).normalize();
        assert!(to_centre_m.dot(&push.direction_cam) > 0.99);
        assert!((push.direction_cam.norm() - 1.0).abs() < 1e-5);
        assert_eq!(push.start_cam_m.z, ci.centre_cam_m.z);
        let back = k.project(&push.start_cam_m).unwrap();
        assert!((back.x - push.start_px[0]).abs() < 1e-3);
        assert!((back.y - push.start_px[1]).abs() < 1e-3);
    }
    assert!(sides[0] && sides[1], "both sides are drawn over 12 seeds");
}

#[test]
fn push_tries_the_other_side_when_one_side_never_leaves_the_region() {
    // A (pushed, smaller) touches the top border; its partner B sits right of it.
    let mut s = Scene::new();
    s.rect(100, 0, 121, 20, 255) // A: x 100..121, y 0..20, reaches the top border
        .rect(140, 0, 171, 30, 255) // B: larger
        .rect(122, 0, 139, 20, 130);
    for seed in 0..6 {
        let mut cfg = Config::PAPER;
        cfg.seed = seed;
        let report = s.run(&cfg).unwrap();
        let pair = report.pair().expect("pair");
        let ci = report.certain()[pair.pushed];
        assert!((ci.centre_px[0] - 110.0).abs() < 1.0, "{ci:?}");
        let push = report.push().expect("push");
        // Up leaves the image inside A, so the push always starts below it.
        assert!(push.start_px[1] > 19.0, "seed {seed}: {push:?}");
        assert!(push.direction_cam.y < -0.98, "seed {seed}: {push:?}");
    }
}

#[test]
fn the_push_starts_at_the_height_of_the_object_on_a_tilted_table() {
    // Depth grows with y, as for a camera tilted towards the table.
    let mut s = three_blobs();
    for y in 0..H {
        for x in 0..W {
            s.depth[y * W + x] = 0.5 + 0.001 * y as Real;
        }
    }
    let report = s.run(&Config::PAPER).unwrap();
    let pair = report.pair().expect("pair");
    let push = report.push().expect("push");
    let ci = report.certain()[pair.pushed];
    assert_eq!(push.start_cam_m.z, ci.centre_cam_m.z);
    let to_centre = (ci.centre_cam_m - push.start_cam_m).normalize();
    assert!(to_centre.dot(&push.direction_cam) > 0.9999);
}

#[test]
fn same_input_and_seed_give_identical_reports() {
    let s = three_blobs();
    let mut cfg = Config::PAPER;
    cfg.seed = 42;
    let first = s.run(&cfg).unwrap();
    let second = s.run(&cfg).unwrap();
    assert_eq!(first, second);
    assert!(first.push().is_some());
    // Bit-identical, not just equal up to float comparison quirks.
    let (p, q) = (first.push().unwrap(), second.push().unwrap());
    assert_eq!(p.start_px.map(Real::to_bits), q.start_px.map(Real::to_bits));
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    let cfg = Config::PAPER;
    let k = intrinsics();
    let heat = vec![200u8; W * H];
    let depth = vec![Z_M; W * H];
    let len = ActionScratchLen::for_config(&cfg, W, H);
    let mut c = vec![0.0; len.certain];
    let mut u = vec![0.0; len.uncertain];
    let mut d = vec![0.0; len.dist2];
    let mut n = vec![0u32; len.nearest];
    let mut r = vec![0u32; len.row_counts];
    let mut runs = vec![0u32; len.runs];
    let mut row_runs = vec![0u32; len.row_runs];
    let hv = ImageView::packed(W, H, &heat).unwrap();
    let mask = vec![0u16; W * H];
    let mv = ImageView::packed(W, H, &mask).unwrap();
    let short_depth = ImageView::packed(W, H - 1, &depth).unwrap();
    let scratch = ActionScratch {
        certain: &mut c,
        uncertain: &mut u,
        dist2: &mut d,
        nearest: &mut n,
        row_counts: &mut r,
        runs: &mut runs,
        row_runs: &mut row_runs,
    };
    assert_eq!(
        find_action(&hv, &short_depth, &mv, &k, &cfg, scratch).err(),
        Some(Error::SizeMismatch)
    );

    let dv = ImageView::packed(W, H, &depth).unwrap();
    let mut short = vec![0u32; len.nearest - 1];
    let scratch = ActionScratch {
        certain: &mut c,
        uncertain: &mut u,
        dist2: &mut d,
        nearest: &mut short,
        row_counts: &mut r,
        runs: &mut runs,
        row_runs: &mut row_runs,
    };
    assert_eq!(
        find_action(&hv, &dv, &mv, &k, &cfg, scratch).err(),
        Some(Error::BufferTooSmall {
            buffer: Buffer::SampleNearest,
            needed: len.nearest,
            got: len.nearest - 1
        })
    );
    // Room for x and y planes but not depth.
    let mut short = vec![0.0; 2 * len.samples];
    let scratch = ActionScratch {
        certain: &mut c,
        uncertain: &mut short,
        dist2: &mut d,
        nearest: &mut n,
        row_counts: &mut r,
        runs: &mut runs,
        row_runs: &mut row_runs,
    };
    assert_eq!(
        find_action(&hv, &dv, &mv, &k, &cfg, scratch).err(),
        Some(Error::BufferTooSmall {
            buffer: Buffer::Samples,
            needed: 3 * len.samples,
            got: 2 * len.samples
        })
    );

    let mut bad_cfg = cfg;
    bad_cfg.max_clusters = 0;
    assert_eq!(
        run(W, H, &heat, &depth, &k, &bad_cfg).err(),
        Some(Error::BadConfig)
    );
    let mut bad_k = k;
    bad_k.fx = Real::NAN;
    assert_eq!(
        run(W, H, &heat, &depth, &bad_k, &cfg).err(),
        Some(Error::NonFinite)
    );

    // No depth anywhere: nothing to cluster, no push.
    let s = three_blobs();
    let nan = vec![Real::NAN; W * H];
    let report = run(W, H, &s.heat, &nan, &k, &cfg).unwrap();
    assert!(report.certain().is_empty() && report.uncertain().is_empty());
    assert_eq!(report.push(), None);
    // Empty image.
    let report = run(0, 0, &[], &[], &k, &cfg).unwrap();
    assert!(report.certain().is_empty() && report.push().is_none());
}

#[test]
fn random_inputs_never_panic_and_respect_the_capacity() {
    let mut rng = Pcg32::new(99);
    let specials = [0.0, -1.0, Real::NAN, Real::INFINITY, 1e30, 1e-30, 0.6, 0.61];
    for trial in 0..200u32 {
        let w = rng.below(24) as usize;
        let h = rng.below(24) as usize;
        let mut cfg = Config::PAPER;
        cfg.max_clusters = 2 + rng.below(MAX_CLUSTERS as u32 - 1) as usize;
        cfg.kmeans_samples = cfg.max_clusters + rng.below(80) as usize;
        cfg.kmeans_iters = 1 + rng.below(5);
        cfg.pair_max_m = 0.05 + rng.unit();
        cfg.uncertain_max_m = 0.01 + rng.unit();
        cfg.seed = u64::from(trial);
        let heat: Vec<u8> = (0..w * h)
            .map(|_| [0, 125, 200, rng.below(256) as u8][rng.below(4) as usize])
            .collect();
        let depth: Vec<Real> = (0..w * h)
            .map(|_| specials[rng.below(specials.len() as u32) as usize])
            .collect();
        // Fields set directly, past the checked range too: those are refused, not a panic.
        let fx = [1e-6, MIN_FOCAL_PX, 1.0, 300.0, MAX_CAMERA_PX, 1e9][rng.below(6) as usize];
        let k = Intrinsics {
            fx,
            fy: fx,
            cx: w as Real / 2.0,
            cy: h as Real / 2.0,
        };
        let result = run(w, h, &heat, &depth, &k, &cfg);
        if k.check().is_err() {
            assert_eq!(result.err(), Some(Error::BadConfig));
            continue;
        }
        let report = result.unwrap();
        assert!(report.certain().len() <= cfg.max_clusters);
        assert!(report.uncertain().len() <= cfg.max_clusters);
        if let Some(push) = report.push() {
            assert!((push.direction_cam.norm() - 1.0).abs() < 1e-3);
        }
    }
}

#[test]
fn scratch_len_is_capped_by_the_image() {
    let cfg = Config::PAPER;
    let len = ActionScratchLen::for_config(&cfg, 640, 480);
    assert_eq!(len.samples, cfg.kmeans_samples);
    assert_eq!(len.certain, 3 * cfg.kmeans_samples);
    assert_eq!(len.row_counts, 960);
    assert_eq!(len.max_runs, 480 * 320);
    assert_eq!(len.runs, 4 * 480 * 320);
    assert_eq!(len.row_runs, 481);
    assert_eq!(
        len.bytes(),
        cfg.kmeans_samples * (12 + 12 + 4 + 4) + (960 + 4 * 480 * 320 + 481) * 4
    );
    assert_eq!(ActionScratchLen::for_config(&cfg, 7, 3).max_runs, 12);
    assert_eq!(ActionScratchLen::for_config(&cfg, 10, 10).samples, 100);
    let huge = ActionScratchLen::for_config(
        &Config {
            kmeans_samples: usize::MAX,
            ..cfg
        },
        usize::MAX,
        2,
    );
    assert_eq!(huge.bytes(), usize::MAX);
}

#[test]
fn a_short_scratch_slice_is_named_in_the_error() {
    let cfg = Config::PAPER;
    let s = three_blobs();
    let len = ActionScratchLen::for_config(&cfg, W, H);
    let cases = [
        (Buffer::Samples, len.certain),
        (Buffer::Samples, len.uncertain),
        (Buffer::SampleDist, len.dist2),
        (Buffer::SampleNearest, len.nearest),
        (Buffer::RowCounts, len.row_counts),
        (Buffer::Runs, len.runs),
        (Buffer::RowRuns, len.row_runs),
    ];
    for (slot, (buffer, needed)) in cases.into_iter().enumerate() {
        let mut buf = ActionBuf::new(&cfg, W, H);
        let mut v = buf.view();
        match slot {
            0 => v.certain = &mut core::mem::take(&mut v.certain)[1..],
            1 => v.uncertain = &mut core::mem::take(&mut v.uncertain)[1..],
            2 => v.dist2 = &mut core::mem::take(&mut v.dist2)[1..],
            3 => v.nearest = &mut core::mem::take(&mut v.nearest)[1..],
            4 => v.row_counts = &mut core::mem::take(&mut v.row_counts)[1..],
            5 => v.runs = &mut core::mem::take(&mut v.runs)[1..],
            _ => v.row_runs = &mut core::mem::take(&mut v.row_runs)[1..],
        }
        let got = find_action(
            &ImageView::packed(W, H, &s.heat).unwrap(),
            &ImageView::packed(W, H, &s.depth).unwrap(),
            &ImageView::packed(W, H, &vec![0; W * H]).unwrap(),
            &intrinsics(),
            &cfg,
            v,
        );
        assert_eq!(
            got.err(),
            Some(Error::BufferTooSmall {
                buffer,
                needed,
                got: needed - 1
            }),
            "slot {slot}"
        );
    }
}

#[test]
fn the_push_starts_where_the_pushed_segment_of_the_mask_ends() {
    let s = three_blobs();
    let k = intrinsics();
    // Each object's segment reaches 4 px beyond its certain disc.
    let mut mask = vec![0u16; W * H];
    for (label, (cx, cy)) in [(1u16, A), (2, B), (3, C)] {
        for y in 0..H {
            for x in 0..W {
                let (dx, dy) = (x as Real - cx, y as Real - cy);
                if dx * dx + dy * dy <= (R_PX + 4.0) * (R_PX + 4.0) {
                    mask[y * W + x] = label;
                }
            }
        }
    }
    for seed in 0..6 {
        let mut cfg = Config::PAPER;
        cfg.seed = seed;
        let rim = s.run(&cfg).unwrap().push().expect("push");
        let report = run_masked(W, H, &s.heat, &s.depth, &mask, &k, &cfg).unwrap();
        let push = report.push().expect("push");
        // Same pair, same line, same direction: only the start moved, outwards.
        assert_eq!(push.target_px, rim.target_px, "seed {seed}");
        assert_eq!(push.direction_cam, rim.direction_cam, "seed {seed}");
        let from = |p: [Real; 2]| [p[0] - push.target_px[0], p[1] - push.target_px[1]];
        let (e, r) = (from(push.start_px), from(rim.start_px));
        let (len_e, len_r) = (
            sqrt(e[0] * e[0] + e[1] * e[1]),
            sqrt(r[0] * r[0] + r[1] * r[1]),
        );
        assert!(
            (e[0] * r[1] - e[1] * r[0]).abs() < 1e-3 * len_e * len_r,
            "seed {seed}"
        );
        assert!(
            (len_e - (R_PX + 4.0)).abs() <= 1.0,
            "seed {seed}: start {len_e} px from the centre, rim {len_r}"
        );
        // The 3-D start is the start pixel at the pushed cluster's depth.
        let back = k.back_project(push.start_px[0], push.start_px[1], push.start_cam_m.z);
        assert_eq!(back, push.start_cam_m);
        assert_eq!(push.start_cam_m.z, rim.start_cam_m.z);
    }
    // A mask of another size is refused.
    assert_eq!(
        run_masked(W, H, &s.heat, &s.depth, &mask[1..], &k, &Config::PAPER).err(),
        Some(Error::BadImageLayout)
    );
}

/// Labels of a mask that covers `pack_2x2`'s square: `label(right, bottom)` per quadrant.
fn pack_2x2_mask(label: impl Fn(bool, bool) -> u16) -> Vec<u16> {
    let (x0, y0, side) = PACK;
    let mut mask = vec![0u16; W * H];
    for y in y0..y0 + side {
        for x in x0..x0 + side {
            mask[y * W + x] = label(x >= x0 + side / 2, y >= y0 + side / 2);
        }
    }
    mask
}

/// Whether each of 16 seeds pushes along x (`[false, ..]`: along y) with this mask.
fn push_axes(s: &Scene, mask: &[u16], cfg: &Config) -> Vec<bool> {
    (0..16)
        .map(|seed| {
            let cfg = Config { seed, ..*cfg };
            let report = run_masked(W, H, &s.heat, &s.depth, mask, &intrinsics(), &cfg).unwrap();
            let push = report.push().expect("push");
            // Outside the pack, at an outer cell, and along an axis of the grid.
            let (x0, y0, side) = PACK;
            let (x, y) = (
                round(push.start_px[0]) as usize,
                round(push.start_px[1]) as usize,
            );
            assert!(
                !((x0 + 2..x0 + side - 2).contains(&x) && (y0 + 2..y0 + side - 2).contains(&y)),
                "seed {seed}: {push:?}"
            );
            let d = push.direction_cam;
            assert!(d.x.abs() > 0.99 || d.y.abs() > 0.99, "seed {seed}: {d:?}");
            d.x.abs() > 0.99
        })
        .collect()
}

#[test]
fn a_2x2_pack_split_into_columns_is_pushed_along_the_columns_shared_face() {
    // The accumulated mask already holds the two columns apart. A push along a column
    // (y) moves one whole column: nothing new. A push along x from outside the pack moves
    // one cell of each column (the pushed one and the one it carries): both columns split.
    let s = pack_2x2();
    let columns = pack_2x2_mask(|right, _| 1 + u16::from(right));
    let rows = pack_2x2_mask(|_, bottom| 1 + u16::from(bottom));
    assert!(push_axes(&s, &columns, &Config::PAPER).iter().all(|&x| x));
    assert!(push_axes(&s, &rows, &Config::PAPER).iter().all(|&x| !x));
    // The paper's choice ignores the mask and uses both axes.
    let paper = Config {
        push_carry_frac: 0.0,
        ..Config::PAPER
    };
    let axes = push_axes(&s, &columns, &paper);
    assert!(axes.contains(&true) && axes.contains(&false), "{axes:?}");
}

/// A 1×3 row of boxes along x (the left one narrower), with a rim and uncertain bands
/// at the two cuts; the mask gives the left box label 1 and the other two label 2.
fn row_1x3() -> (Scene, Vec<u16>, [Real; 3]) {
    let (x0, y0, h) = (60usize, 100usize, 40usize);
    let cuts = [x0 + 30, x0 + 70];
    let x1 = x0 + 110;
    let mut s = Scene::new();
    s.rect(x0, y0, x1, y0 + h, 100)
        .rect(x0 + 2, y0 + 2, x1 - 2, y0 + h - 2, 255);
    for c in cuts {
        s.rect(c - 5, y0 + 2, c + 6, y0 + h - 2, 130);
    }
    let mut mask = vec![0u16; W * H];
    for y in y0..y0 + h {
        for x in x0..x1 {
            mask[y * W + x] = if x < cuts[0] { 1 } else { 2 };
        }
    }
    let centres = [
        (x0 + cuts[0]) as Real / 2.0,
        (cuts[0] + cuts[1]) as Real / 2.0,
        (cuts[1] + x1) as Real / 2.0,
    ];
    (s, mask, centres)
}

#[test]
fn an_object_already_split_off_is_not_pushed_again() {
    let (s, mask, centres) = row_1x3();
    let pushed_x = |cfg: &Config| -> Vec<Real> {
        (0..16)
            .map(|seed| {
                let cfg = Config { seed, ..*cfg };
                let report =
                    run_masked(W, H, &s.heat, &s.depth, &mask, &intrinsics(), &cfg).unwrap();
                assert_eq!(report.certain().len(), 3, "seed {seed}");
                let push = report.push().expect("push");
                // Sideways: across the row, so only the pushed box moves.
                assert!(push.direction_cam.y.abs() > 0.99, "seed {seed}: {push:?}");
                push.target_px[0]
            })
            .collect()
    };
    let near = |x: Real, c: Real| (x - c).abs() < 5.0;
    // The left box has its own label: pushing it again splits nothing.
    for x in pushed_x(&Config::PAPER) {
        assert!(
            near(x, centres[1]) || near(x, centres[2]),
            "{x} {centres:?}"
        );
    }
    // The paper's choice pushes the smaller cluster of the best pair: the left box.
    let paper = Config {
        push_carry_frac: 0.0,
        ..Config::PAPER
    };
    assert!(pushed_x(&paper).iter().any(|&x| near(x, centres[0])));
}

#[test]
fn splits_count_pairs_of_one_label_that_one_push_separates() {
    // Labels 1 1 2 2 0 0 (0: background, never a pair); clusters 0, 2 and 4 move.
    let labels = [1, 1, 2, 2, 0, 0];
    assert_eq!(push::splits(&labels, &[], 0b01_0101), 2);
    // Moving all of a label, or nothing, splits none of it.
    assert_eq!(push::splits(&labels, &[], 0b00_0011), 0);
    assert_eq!(push::splits(&labels, &[], 0), 0);
    assert_eq!(push::splits(&[7, 7, 7], &[], 0b010), 2);
    // The size prior: label 1's segment holds three objects by area, label 2's one.
    let objects = [3, 3, 1, 1, 0, 0];
    // One of label 1's two clusters moves: 1 · (3 − 1) pairs; label 2's as before.
    assert_eq!(push::splits(&labels, &objects, 0b01_0101), 3);
    // Both of label 1's clusters move, its third object stays: 2 · (3 − 2).
    assert_eq!(push::splits(&labels, &objects, 0b00_0011), 2);
    // A lone cluster of a segment of two objects.
    assert_eq!(push::splits(&[4, 5], &[2, 1], 0b01), 1);
    assert_eq!(push::splits(&[4, 5], &[2, 1], 0b10), 0);
}

/// Two columns of three boxes (34 × 30 px, about 6.8 × 6 cm) along y, already sheared
/// apart by an earlier push: a wide uncertain band (2 cm) between the columns, one-pixel
/// uncertain cuts between the boxes of a column, a rim; the mask gives each column one
/// label. Returns the scene, the mask and the box centres (column, row).
fn columns_2x3() -> (Scene, Vec<u16>, [[[Real; 2]; 3]; 2]) {
    let (x0, y0) = (100usize, 60usize);
    let (box_w, box_h, band) = (34usize, 30usize, 10usize);
    let x1 = x0 + 2 * box_w + band;
    let y1 = y0 + 3 * box_h;
    let mut s = Scene::new();
    s.rect(x0 - 2, y0 - 2, x1 + 2, y1 + 2, 100)
        .rect(x0, y0, x1, y1, 255)
        .rect(x0 + box_w, y0, x0 + box_w + band, y1, 130);
    for r in 1..3 {
        s.rect(x0, y0 + r * box_h, x1, y0 + r * box_h + 1, 130);
    }
    let mut mask = vec![0u16; W * H];
    for y in y0 - 2..y1 + 2 {
        for x in x0 - 2..x1 + 2 {
            mask[y * W + x] = if x < x0 + box_w + band / 2 { 1 } else { 2 };
        }
    }
    let mut centres = [[[0.0; 2]; 3]; 2];
    for (c, col) in centres.iter_mut().enumerate() {
        for (r, centre) in col.iter_mut().enumerate() {
            let x = x0 + c * (box_w + band);
            let y = y0 + r * box_h;
            *centre = [
                x as Real + (box_w as Real - 1.0) / 2.0,
                y as Real + (box_h as Real - 1.0) / 2.0,
            ];
        }
    }
    (s, mask, centres)
}

#[test]
fn a_column_with_no_uncertain_centre_beside_it_is_still_split_across_its_cuts() {
    // The heatmap's uncertain centres lie in the wide band between the columns (as
    // k-means puts them when the band holds most uncertain pixels): more than d_b from
    // the segment between two boxes of one column. The only pairs within d_b are across
    // the band, and their pushes (along a column) move a whole column: they split
    // nothing. Each column's boxes are seam pairs: the line between them crosses a cut.
    // A push across the columns from outside splits both.
    let (s, mask, centres) = columns_2x3();
    let band_x = 100.0 + 34.0 + 4.5;
    let uncertain = [
        uncertain_at(band_x, 75.0),
        uncertain_at(band_x, 105.0),
        uncertain_at(band_x, 135.0),
    ];
    let cfg = Config::PAPER;
    for seed in 0..16 {
        let cfg = Config { seed, ..cfg };
        let (certain, push) = chosen(&s, &mask, &cfg, &uncertain);
        assert_eq!(certain.len(), 6, "seed {seed}: one cluster per box");
        for col in &centres {
            for c in col {
                assert!(find(&certain, c[0], c[1]).is_some(), "seed {seed}: {c:?}");
            }
        }
        let (pair, push) = push.expect("a push");
        assert!(is_seam(&pair, &cfg), "seed {seed}: {pair:?}");
        // Across the columns (along x), from outside the pack.
        assert!(push.direction_cam.x.abs() > 0.99, "seed {seed}: {push:?}");
        assert!(s.heat_at(push.start_px) < 255, "seed {seed}: {push:?}");
    }
    // The paper's choice has no seam pairs: it pushes along a column.
    let paper = Config {
        push_carry_frac: 0.0,
        ..cfg
    };
    let (_, push) = chosen(&s, &mask, &paper, &uncertain);
    let (pair, push) = push.expect("a push");
    assert!(!is_seam(&pair, &paper));
    assert!(push.direction_cam.y.abs() > 0.99, "{push:?}");
}

/// A 1×3 row of 4 × 4 cm boxes (20 px) along x, with a rim: the heatmap cuts only between
/// the second and the third box, so the first two share one certain region (7 cm, one
/// cluster). The mask, like the heatmap, gives the first two boxes label 1 and the third
/// label 2. Returns the scene, the mask and the x where the two segments meet.
fn row_two_boxes_one_region() -> (Scene, Vec<u16>, Real) {
    let (x0, y0, side) = (60usize, 100usize, 20usize);
    let cut = x0 + 2 * side;
    let x1 = x0 + 3 * side;
    let mut s = Scene::new();
    s.rect(x0, y0, x1, y0 + side, 100)
        .rect(x0 + 2, y0 + 2, x1 - 2, y0 + side - 2, 255)
        .rect(cut - 3, y0 + 2, cut + 4, y0 + side - 2, 130);
    let mut mask = vec![0u16; W * H];
    for y in y0..y0 + side {
        for x in x0..x1 {
            mask[y * W + x] = if x < cut { 1 } else { 2 };
        }
    }
    (s, mask, cut as Real)
}

#[test]
fn the_segment_twice_the_area_of_another_is_pushed_though_it_has_one_cluster() {
    // Two clusters, one per label: no push splits a pair of clusters of one label. By
    // area, label 1's segment holds two objects (twice label 2's): a push across the row
    // at its cluster splits it; one at the lone box splits nothing.
    let (s, mask, cut) = row_two_boxes_one_region();
    let targets = |cfg: &Config| -> Vec<Real> {
        (0..16)
            .map(|seed| {
                let cfg = Config { seed, ..*cfg };
                let report =
                    run_masked(W, H, &s.heat, &s.depth, &mask, &intrinsics(), &cfg).unwrap();
                assert_eq!(report.certain().len(), 2, "seed {seed}");
                let push = report.push().expect("push");
                // Across the row: only the pushed cluster moves.
                assert!(push.direction_cam.y.abs() > 0.99, "seed {seed}: {push:?}");
                push.target_px[0]
            })
            .collect()
    };
    for x in targets(&Config::PAPER) {
        assert!(x < cut, "{x} {cut}");
    }
    // The paper's choice pushes the smaller cluster of the pair: the lone box.
    let paper = Config {
        push_carry_frac: 0.0,
        ..Config::PAPER
    };
    assert!(targets(&paper).iter().all(|&x| x > cut));
}

#[test]
fn a_pack_the_heatmap_shows_no_seam_in_is_pushed_between_its_size_split_pieces() {
    // Two 5 × 5 cm boxes (25 px) flush in a row, one certain region with no cut (9 cm
    // long: split into two pieces by its size), one segment in the mask; the only
    // uncertain centre lies 8 cm below the row, far from the line between the pieces,
    // or there is none.
    let (x0, y0, side) = (80usize, 100usize, 25usize);
    let x1 = x0 + 2 * side;
    let mut s = Scene::new();
    s.rect(x0, y0, x1, y0 + side, 100)
        .rect(x0 + 2, y0 + 2, x1 - 2, y0 + side - 2, 255);
    let mut mask = vec![0u16; W * H];
    for y in y0..y0 + side {
        mask[y * W + x0..y * W + x1].fill(1);
    }
    let below = [uncertain_at((x0 + side) as Real, (y0 + side + 40) as Real)];
    for (uncertain, centre) in [(&below[..], Some(0)), (&[][..], None)] {
        for seed in 0..8 {
            let cfg = Config {
                seed,
                ..Config::PAPER
            };
            let (certain, push) = chosen(&s, &mask, &cfg, uncertain);
            assert_eq!(certain.len(), 2, "seed {seed}: two pieces");
            let (pair, push) = push.expect("a push between the pieces");
            assert!(is_seam(&pair, &cfg), "seed {seed}: {pair:?}");
            assert_eq!(pair.uncertain, centre, "seed {seed}");
            // Across the row: a push along it would carry the other piece and split nothing.
            assert!(push.direction_cam.y.abs() > 0.99, "seed {seed}: {push:?}");
        }
    }
    // Two regions that no size split made stay without a pair when no uncertain centre
    // exists.
    let mut apart = Scene::new();
    apart
        .disc(140.0, 120.0, R_PX, 255)
        .disc(172.0, 120.0, R_PX, 255);
    let (_, pairs) = ranked(&apart, &Config::PAPER, &[]);
    assert!(pairs.is_empty(), "{pairs:?}");
}
