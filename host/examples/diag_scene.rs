//! Diagnosis of one recorded scene, stage by stage: for every push, the body frames'
//! groups against the ground-truth objects, and what CorrectMask made of them.
//!
//! `cargo run --release --example diag_scene -- SCENE_DIR [--exact]` (`--exact`: the
//! scene's own `flow/` instead of the built-in flow).

use std::{collections::BTreeMap, path::PathBuf};

use riseg::{
    flow::{DisFlow, FlowParams},
    io::scene::Scene,
    rig::camera::SceneReplay,
    rig::tracker::{GivenInputs, Tracker},
    segment::{ClassicalSegmenter, SegmenterParams},
};
use riseg_core::Config;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(args.next().ok_or_else(|| anyhow::anyhow!("SCENE_DIR"))?);
    let exact = args.next().as_deref() == Some("--exact");
    let scene = Scene::read(&dir)?;
    let mut tracker = Tracker::new(
        ClassicalSegmenter::new(SegmenterParams::default())?,
        DisFlow::new(FlowParams::MEDIUM)?,
        Config::PAPER,
    )?;
    for t in 0..scene.frames() {
        let frame = SceneReplay::frame(&scene, t).ok_or_else(|| anyhow::anyhow!("frame {t}"))?;
        let truth = frame.truth.clone().expect("labels");
        let (w, _) = frame.size();
        let flow = match (&scene.flow, t) {
            (Some(flows), 1..) if exact => Some(flows[t - 1].clone().with_unknown_as_nan()),
            _ => None,
        };
        let prev_truth = tracker.last_frame().and_then(|f| f.truth.clone());
        let obs = tracker.observe_given(
            frame,
            GivenInputs {
                static_seg: None,
                flow,
            },
        )?;
        let distinct = |m: &[u16]| {
            let mut v: Vec<u16> = m.iter().copied().filter(|&l| l != 0).collect();
            v.sort_unstable();
            v.dedup();
            v.len()
        };
        println!(
            "== frame {t}: static segments {}, mask segments {}",
            distinct(obs.static_seg.labels.as_slice()),
            distinct(&obs.mask)
        );
        let Some(step) = &obs.step else { continue };
        println!("   {:?}", step.report);
        let prev_truth = prev_truth.expect("previous");
        // group -> (moving, truth label histogram of the frames' origins at t)
        let mut hist: BTreeMap<Option<u16>, (bool, BTreeMap<u16, u32>)> = BTreeMap::new();
        for g in &step.frames {
            let [u, v] = g.frame.px_t[0];
            let l = prev_truth.as_slice()[v as usize * w + u as usize];
            let e = hist.entry(g.group).or_default();
            e.0 = g.moving;
            *e.1.entry(l).or_default() += 1;
        }
        for (g, (moving, h)) in &hist {
            println!("   group {g:?} moving {moving}: {h:?}");
        }
        // twist norms per truth label
        let origin = step.report.frames.space_origin;
        let mut norms: BTreeMap<u16, Vec<f32>> = BTreeMap::new();
        for g in &step.frames {
            let [u, v] = g.frame.px_t[0];
            let l = prev_truth.as_slice()[v as usize * w + u as usize];
            let tw = g.frame.twist(&origin).unwrap_or(riseg_core::Twist::ZERO);
            norms
                .entry(l)
                .or_default()
                .push(tw.norm_squared(0.05).sqrt());
        }
        for (l, mut v) in norms {
            v.sort_by(f32::total_cmp);
            let q = |p: f32| v[((v.len() - 1) as f32 * p) as usize];
            println!(
                "   truth {l}: twist norm q10 {:.4} q50 {:.4} q90 {:.4} (n {})",
                q(0.1),
                q(0.5),
                q(0.9),
                v.len()
            );
        }
        // mask label -> truth histogram at t+1
        let mut m: BTreeMap<u16, BTreeMap<u16, u32>> = BTreeMap::new();
        for (&p, &l) in obs.mask.iter().zip(truth.as_slice()) {
            if p != 0 || l != 0 {
                *m.entry(p).or_default().entry(l).or_default() += 1;
            }
        }
        for (p, h) in &m {
            println!("   mask {p}: {h:?}");
        }
    }
    Ok(())
}
