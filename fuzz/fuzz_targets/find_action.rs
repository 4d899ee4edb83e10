//! `riseg_core::action::find_action` on small arbitrary heatmaps, depth, masks, intrinsics
//! and configs near the paper's.
//!
//! Contract checked: no panic for any input; on `Ok`, at most `max_clusters` clusters of
//! each class, a pair's indices point at clusters and respect `d_a` (`pair_max_m`) and
//! `d_b` (`uncertain_max_m`), and a push has a finite start, a unit direction and the
//! configured length.

#![no_main]

use arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use riseg::rig::workspace::ActionBuf;
use riseg_core::{ImageView, action::find_action};
use riseg_fuzz::{blocky, config, depth_m, intrinsics, labels, many, size};

fn run(u: &mut Unstructured<'_>) -> Result<()> {
    let cfg = config(u)?;
    let (w, h) = size(u)?;
    let k = intrinsics(u, w, h)?;
    let n = w * h;
    let block = u.int_in_range(1..=6)?;
    let mut heat: Vec<u8> = many(u, n, |u| u.arbitrary())?;
    blocky(&mut heat, w, block);
    let max_label = u.int_in_range(0..=6)?;
    let mut mask = labels(u, n, max_label)?;
    blocky(&mut mask, w, block);
    let depth = many(u, n, depth_m)?;
    let mut buf = ActionBuf::new(&cfg, w, h);
    let report = find_action(
        &ImageView::packed(w, h, &heat).expect("packed heatmap"),
        &ImageView::packed(w, h, &depth).expect("packed depth"),
        &ImageView::packed(w, h, &mask).expect("packed mask"),
        &k,
        &cfg,
        buf.view(),
    );
    let Ok(report) = report else {
        return Ok(());
    };
    assert!(report.certain().len() <= cfg.max_clusters);
    assert!(report.uncertain().len() <= cfg.max_clusters);
    if let Some(pair) = report.pair() {
        assert!(pair.pushed < report.certain().len() && pair.other < report.certain().len());
        assert!(pair.pushed != pair.other);
        assert!(pair.uncertain.is_none_or(|u| u < report.uncertain().len()));
        assert!(pair.pair_dist_m <= cfg.pair_max_m, "{pair:?}");
        // Beyond d_b only a seam pair, which is reported only with its push (a split).
        assert!(
            pair.uncertain_dist_m <= cfg.uncertain_max_m
                || (cfg.push_carry_frac > 0.0 && report.push().is_some()),
            "{pair:?}"
        );
    }
    if let Some(push) = report.push() {
        assert!(report.pair().is_some());
        assert!(
            push.start_cam_m.coords.iter().all(|c| c.is_finite()),
            "{push:?}"
        );
        assert!(push.direction_cam.iter().all(|c| c.is_finite()), "{push:?}");
        assert!((push.direction_cam.norm() - 1.0).abs() < 1e-3, "{push:?}");
        assert!(push.length_m == cfg.push_len_m);
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let _ = run(&mut Unstructured::new(data));
});
