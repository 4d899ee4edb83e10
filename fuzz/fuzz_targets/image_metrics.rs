//! `riseg::eval::metrics::image_metrics` (the UOIS metrics) on arbitrary label maps: small
//! blocky maps with a few labels (so objects overlap and touch), and sometimes any
//! `width`/`height` against the slices' length.
//!
//! Contract checked (module docs): no panic; on `Ok`, every fraction is in `[0, 1]` and not
//! NaN, at most `min(#G, #P)` objects are detected, and a map scored against itself is
//! perfect (every F is 1, every object detected).

#![no_main]

use arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use riseg::eval::metrics::{ImageMetrics, image_metrics};
use riseg_fuzz::{blocky, labels, size};

fn check_ranges(m: &ImageMetrics) {
    for p in [m.overlap, m.boundary] {
        for v in [p.precision, p.recall, p.f_measure] {
            assert!((0.0..=1.0).contains(&v), "{m:?}");
        }
    }
    assert!((0.0..=1.0).contains(&m.objects_detected_share), "{m:?}");
    assert!(
        m.objects_detected <= m.objects_gt.min(m.objects_pred),
        "{m:?}"
    );
}

fn run(u: &mut Unstructured<'_>) -> Result<()> {
    let (w, h) = size(u)?;
    let n = w * h;
    let block = u.int_in_range(1..=6)?;
    let (gt_max, pred_max) = (u.arbitrary()?, u.arbitrary()?);
    let mut gt = labels(u, n, gt_max)?;
    blocky(&mut gt, w, block);
    let mut pred = labels(u, n, pred_max)?;
    blocky(&mut pred, w, block);
    // One time in sixteen, any size claimed for the same slices.
    let (w, h) = if u.int_in_range(0..=15)? == 0 {
        (u.arbitrary()?, u.arbitrary()?)
    } else {
        (w, h)
    };
    if let Ok(m) = image_metrics(&gt, &pred, w, h) {
        check_ranges(&m);
        let own = image_metrics(&gt, &gt, w, h).expect("gt against itself");
        assert!(
            own.overlap.f_measure == 1.0 && own.boundary.f_measure == 1.0,
            "{own:?}"
        );
        assert!(own.objects_detected == own.objects_gt, "{own:?}");
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let _ = run(&mut Unstructured::new(data));
});
