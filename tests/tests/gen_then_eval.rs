//! A simulated dataset from `riseg gen`, scored against itself by `riseg eval`'s library
//! code: every number must be 100, on every push index.

use riseg::{
    cli::{eval, generate::write_dataset},
    sim::Layout,
};

#[test]
fn generated_dataset_against_itself_scores_100_everywhere() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut objects = Vec::new();
    write_dataset(dir.path(), 1, 7, Layout::Loose, 2, |_, scene| {
        objects.push(scene.objects);
    })
    .expect("gen");
    assert_eq!(objects.len(), 1);
    let pairs = eval::find_frame_pairs(dir.path(), dir.path()).expect("pairs");
    assert_eq!(pairs.len(), 3, "initial frame and two pushes");
    let report = eval::evaluate(&pairs, || {}).expect("eval");
    assert_eq!(report.pushes.len(), 3);
    for row in &report.pushes {
        for value in [
            row.overlap.p,
            row.overlap.r,
            row.overlap.f,
            row.boundary.p,
            row.boundary.r,
            row.boundary.f,
            row.objects_f75_pct,
        ] {
            assert!((value - 100.0).abs() < 1e-9, "push {}: {row:?}", row.push);
        }
    }
}
