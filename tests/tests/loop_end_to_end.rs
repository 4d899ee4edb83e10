//! Algorithm 1 end to end on the simulator: the loop improves on the static segmenter,
//! `run` on recorded frames equals the in-memory replay, and a push outside the robot's
//! limits is refused before anything moves.

use riseg::{
    cli::bench::{BenchConfig, run_bench, run_scene as bench_scene},
    cli::eval,
    cli::generate::generate_scene,
    cli::run::{InputDirs, replay_scene, run_scene},
    flow::{DisFlow, FlowParams},
    rig::camera::Camera as _,
    rig::episode::{Stop, run_episode},
    rig::robot::{PushLimits, PushRefused, Robot as _},
    rig::tracker::Tracker,
    segment::{ClassicalSegmenter, SegmenterParams},
    sim::{Layout, SimRig, SimScene},
};
use riseg_core::Config;

fn tracker() -> Tracker<ClassicalSegmenter, DisFlow> {
    Tracker::new(
        ClassicalSegmenter::new(SegmenterParams::default()).expect("segmenter"),
        DisFlow::new(FlowParams::MEDIUM).expect("flow"),
        Config::PAPER,
    )
    .expect("tracker")
}

/// On packs of look-alike boxes (the regime RISeg is for: the static segmenter finds almost
/// none of them), RISeg's pushes find objects the static segmenter cannot, and reach most of
/// what motion could reveal (the motion ceiling).
#[test]
fn a_three_scene_bench_improves_on_the_static_segmenter_and_repeats_exactly() {
    let cfg = BenchConfig {
        layout: Layout::Packed,
        ..BenchConfig::new(3, 1)
    };
    let (report, results) = run_bench(&cfg, |_| {}).expect("bench");
    assert_eq!(results.len(), 3);
    let last = report.riseg_rows.len() - 1;
    assert!(last >= 1, "no scene made a push: {report:?}");
    let (s, r) = (&report.static_rows[last], &report.riseg_rows[last]);
    assert_eq!(s.push, r.push);
    assert!(
        r.objects_f75_pct > s.objects_f75_pct && r.overlap.f > s.overlap.f,
        "push {}: static {s:?}, RISeg {r:?}",
        s.push
    );
    let c = &report.ceiling_rows[last];
    assert!(
        r.objects_f75_pct >= 0.75 * c.objects_f75_pct,
        "push {}: RISeg {r:?}, ceiling {c:?}",
        c.push
    );
    // Push 0 is the static segmentation itself.
    assert_eq!(report.static_rows[0], report.riseg_rows[0]);
    // Same seed, same scores.
    let again = bench_scene(&cfg, 0).expect("scene 0 again");
    assert_eq!(again.riseg_metrics, results[0].riseg_metrics);
    assert_eq!(again.static_metrics, results[0].static_metrics);
    assert_eq!(again.ceiling_metrics, results[0].ceiling_metrics);
}

#[test]
fn run_on_a_recorded_scene_equals_the_in_memory_replay_of_its_frames() {
    let generated = generate_scene(11, Layout::Loose, 2).expect("scene");
    let scene = &generated.scene;
    let dir = tempfile::tempdir().expect("temp dir");
    let scene_dir = dir.path().join("data").join("scene_000");
    scene.write(&scene_dir).expect("write scene");
    let pred = dir.path().join("pred");

    let written = run_scene(
        &mut tracker(),
        &scene_dir,
        &InputDirs::default(),
        &pred,
        |_| {},
    )
    .expect("run");
    assert_eq!(written, scene.frames());
    // The frames in memory are the PNG-rounded ones (u8 colour, millimetre depth).
    let in_memory = replay_scene(&mut tracker(), scene, Vec::new(), |_| {}).expect("replay");
    for (t, mask) in in_memory.iter().enumerate() {
        let path = pred.join("scene_000/label").join(format!("{t:06}.png"));
        let on_disk = riseg::io::image::read_gray16(&path).expect("mask png");
        assert_eq!(on_disk.as_slice(), mask.as_slice(), "frame {t}");
    }
    // And `riseg eval` reads what `run` wrote.
    let pairs = eval::find_frame_pairs(&dir.path().join("data"), &pred).expect("pairs");
    assert_eq!(pairs.len(), scene.frames());
    let report = eval::evaluate(&pairs, || {}).expect("eval");
    assert!(
        report.pushes.iter().all(|p| p.overlap.f > 50.0),
        "{report:?}"
    );
}

#[test]
fn a_push_longer_than_the_robot_allows_is_refused_and_nothing_moves() {
    let sim = SimScene::new(3).expect("scene");
    let mut rig = SimRig::new(sim);
    let limits = PushLimits {
        max_push_len_m: 0.01,
        ..rig.robot.limits()
    };
    let mut robot = rig.robot.with_limits(limits);
    let mut decisions = Vec::new();
    let summary = run_episode(
        &mut rig.camera,
        &mut robot,
        &mut tracker(),
        &rig.setup,
        |f| {
            decisions.push(f.decision);
            Ok(())
        },
    )
    .expect("episode");
    assert_eq!(summary.frames, 1);
    assert!(summary.pushes.is_empty() && robot.pushes().is_empty());
    let Stop::Refused(why) = summary.stop else {
        panic!("expected a refused push, got {:?}", summary.stop);
    };
    assert!(
        matches!(why, PushRefused::TooLong { limit_m, .. } if limit_m == 0.01),
        "{why}"
    );
    assert!(why.to_string().contains("longer than the limit"), "{why}");
    // The objects did not move: the next picture has the same ground truth.
    let before = decisions.len();
    let again = rig.camera.capture().expect("capture");
    assert_eq!(before, 1);
    let first = SimScene::new(3).expect("scene").render().labels;
    assert_eq!(again.truth.as_ref(), Some(&first));
}
