//! Where RISeg beats the motion ceiling: runs `riseg bench`'s episode on simulated scenes
//! (same tracker, settings and one-thread flow as the bench) and, at each frame, lists the
//! object pairs the ceiling joined (condition 1 in every frame so far, condition 2 on
//! every push so far, touching now: `riseg::eval::ceiling`) that RISeg's mask separated
//! (the objects' plurality labels in the mask differ), with the facts behind each:
//! per push, the pair's true relative motion (the larger disagreement of the two motions
//! at either centre, mm, and the rotation between them, degrees) against the floors, each
//! object's own motion, its static plurality label per frame, and the UpdateMask group
//! that most of the body frames on each object fell in (so a RISeg split can be told
//! apart: by motion grouping, or without it). It also prints the ceiling's objects found
//! under looser floors.
//!
//! `cargo run --release --example diag_ceiling -- LAYOUT SIM_SEED...` (`LAYOUT`: loose,
//! packed or mixed; the sim seeds are those `riseg bench --per-scene` prints).

use std::collections::{BTreeMap, BTreeSet};

use riseg::{
    eval::ceiling::{
        CeilingFrame, CeilingParams, MotionCeiling, motion_gaps, same_motion, static_segments,
        touching_pairs,
    },
    eval::metrics::image_metrics,
    io::scene::ObjectPose,
    sim::Layout,
};
use riseg_core::Pose;

#[path = "support/sim_episode.rs"]
mod sim_episode;
use sim_episode::{FrameTruth, frame_truth, run_sim_episode};

/// One captured frame, as far as the diagnosis needs it.
struct Frame {
    truth: Vec<u16>,
    static_labels: Vec<u16>,
    mask: Vec<u16>,
    poses: BTreeMap<u16, Pose>,
    pose_list: Vec<ObjectPose>,
    /// Per object: how many of the body frames whose first pixel is on it fell in each
    /// UpdateMask group (`None`: in no group; `true`: the group moved).
    groups: BTreeMap<u16, BTreeMap<(Option<u16>, bool), usize>>,
}

/// The plurality label of `labels` on each object of `truth` (ties to the smaller), and
/// its share of the object's pixels.
fn plurality(truth: &[u16], labels: &[u16]) -> BTreeMap<u16, (u16, f32)> {
    let mut counts: BTreeMap<u16, BTreeMap<u16, usize>> = BTreeMap::new();
    for (&t, &l) in truth.iter().zip(labels) {
        if t != 0 {
            *counts.entry(t).or_default().entry(l).or_default() += 1;
        }
    }
    counts
        .into_iter()
        .map(|(t, c)| {
            let total: usize = c.values().sum();
            let (l, n) = c.iter().fold(
                (0, 0),
                |best, (&l, &n)| if n > best.1 { (l, n) } else { best },
            );
            (t, (l, n as f32 / total as f32))
        })
        .collect()
}

/// Per object, the best overlap F of any predicted segment (F > 0.75 is "found").
fn best_f(truth: &[u16], pred: &[u16]) -> BTreeMap<u16, f32> {
    let mut tp: BTreeMap<(u16, u16), usize> = BTreeMap::new();
    let mut gsize: BTreeMap<u16, usize> = BTreeMap::new();
    let mut psize: BTreeMap<u16, usize> = BTreeMap::new();
    for (&t, &p) in truth.iter().zip(pred) {
        if t != 0 {
            *gsize.entry(t).or_default() += 1;
        }
        if p != 0 {
            *psize.entry(p).or_default() += 1;
        }
        if t != 0 && p != 0 {
            *tp.entry((t, p)).or_default() += 1;
        }
    }
    let mut best: BTreeMap<u16, f32> = gsize.keys().map(|&t| (t, 0.0)).collect();
    for (&(t, p), &n) in &tp {
        let f = 2.0 * n as f32 / (gsize[&t] + psize[&p]) as f32;
        let b = best.entry(t).or_default();
        *b = b.max(f);
    }
    best
}

/// The pair's motion disagreement on one push: (the larger distance between the two
/// motions' images of either centre, mm; the rotation between the motions, degrees).
fn disagreement(a: [&Pose; 2], b: [&Pose; 2]) -> (f32, f32) {
    let (angle_rad, apart_m) = motion_gaps(a, b);
    (1e3 * apart_m, angle_rad.to_degrees())
}

/// One object's own motion on one push: (centre displacement, mm; rotation, degrees).
fn own(p: [&Pose; 2]) -> (f32, f32) {
    let d = p[0].inverse() * p[1];
    (
        1e3 * (p[1].translation.vector - p[0].translation.vector).norm(),
        d.rotation.angle().to_degrees(),
    )
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let layout = Layout::ALL
        .into_iter()
        .find(|l| args.first().is_some_and(|a| a == l.name()))
        .unwrap_or(Layout::Packed);
    for seed in args.iter().skip(1).filter_map(|a| a.parse::<u64>().ok()) {
        scene(seed, layout)?;
    }
    Ok(())
}

fn scene(seed: u64, layout: Layout) -> anyhow::Result<()> {
    println!("######## sim seed {seed} ({layout})");
    let mut frames: Vec<Frame> = Vec::new();
    let (mut width, mut height) = (0, 0);
    run_sim_episode(seed, layout, |f| {
        (width, height) = f.frame.size();
        let FrameTruth {
            truth,
            pose_list,
            poses,
        } = frame_truth(f)?;
        let mut groups: BTreeMap<u16, BTreeMap<(Option<u16>, bool), usize>> = BTreeMap::new();
        if let (Some(step), Some(prev)) = (&f.observation.step, frames.last()) {
            for g in &step.frames {
                let [u, v] = g.frame.px_t[0];
                let l = prev.truth[v as usize * width + u as usize];
                if l != 0 {
                    *groups
                        .entry(l)
                        .or_default()
                        .entry((g.group, g.moving))
                        .or_default() += 1;
                }
            }
        }
        frames.push(Frame {
            truth,
            static_labels: f.observation.static_seg.labels.as_slice().to_vec(),
            mask: f.observation.mask.clone(),
            poses,
            pose_list,
            groups,
        });
        Ok(())
    })?;

    let floors = [
        ("1mm/1.5deg", 0.001, 1.5_f32),
        ("1mm/1.0deg", 0.001, 1.0),
        ("1mm/0.5deg", 0.001, 0.5),
        ("0.5mm/0.5deg", 0.0005, 0.5),
    ];
    let mut ceilings: Vec<MotionCeiling> = floors
        .iter()
        .map(|&(_, mm, deg)| {
            MotionCeiling::new(CeilingParams {
                trans_floor_m: mm,
                rot_floor_rad: deg.to_radians(),
                ..CeilingParams::DEFAULT
            })
        })
        .collect();
    let params = CeilingParams::DEFAULT;
    for (t, fr) in frames.iter().enumerate() {
        let frame = CeilingFrame {
            width,
            height,
            truth: &fr.truth,
            static_labels: &fr.static_labels,
            poses: &fr.pose_list,
        };
        let masks: Vec<Vec<u16>> = ceilings
            .iter_mut()
            .map(|c| c.next_frame(&frame))
            .collect::<Result<_, _>>()?;
        let riseg = image_metrics(&fr.truth, &fr.mask, width, height)?;
        let found: Vec<String> = floors
            .iter()
            .zip(&masks)
            .map(|((name, ..), m)| {
                image_metrics(&fr.truth, m, width, height)
                    .map(|c| format!("{name} {}", c.objects_detected))
            })
            .collect::<Result<_, _>>()?;
        println!(
            "== frame {t}: riseg {}/{}; ceiling {}",
            riseg.objects_detected,
            riseg.objects_gt,
            found.join(", ")
        );
        let ceil = &masks[0];
        let rf = best_f(&fr.truth, &fr.mask);
        let cf = best_f(&fr.truth, ceil);
        let rl = plurality(&fr.truth, &fr.mask);
        let cl = plurality(&fr.truth, ceil);
        for (o, f) in &rf {
            println!(
                "   object {o}: riseg F {:.2} (label {} covers {:.0} %), ceiling F {:.2} (group {}); static {}",
                f,
                rl[o].0,
                100.0 * rl[o].1,
                cf[o],
                cl[o].0,
                frames[..=t]
                    .iter()
                    .map(|q| plurality(&q.truth, &q.static_labels)
                        .get(o)
                        .map_or("-".to_owned(), |(s, sh)| format!("{s}({:.0}%)", 100.0 * sh)))
                    .collect::<Vec<_>>()
                    .join(" ")
            );
        }
        // Pairs joined by the ceiling (same group, touching now) that RISeg separated.
        let touching = touching_pairs(&fr.truth, width, height, params.touch_gap_px);
        for &(a, b) in &touching {
            if cl[&a].0 != cl[&b].0 || rl[&a].0 == rl[&b].0 {
                continue;
            }
            println!(
                "   pair ({a}, {b}): ceiling joined, riseg separated (riseg F {:.2} / {:.2})",
                rf[&a], rf[&b]
            );
            for s in 0..=t {
                let q = &frames[s];
                let seg = static_segments(&q.truth, &q.static_labels);
                let touch =
                    touching_pairs(&q.truth, width, height, params.touch_gap_px).contains(&(a, b));
                let mut line = format!(
                    "      frame {s}: static {:?}/{:?} touching {touch}",
                    seg.get(&a),
                    seg.get(&b)
                );
                if s > 0 {
                    let p = &frames[s - 1];
                    let pa = [&p.poses[&a], &q.poses[&a]];
                    let pb = [&p.poses[&b], &q.poses[&b]];
                    let (mm, deg) = disagreement(pa, pb);
                    let (am, ad) = own(pa);
                    let (bm, bd) = own(pb);
                    let ga = q.groups.get(&a);
                    let gb = q.groups.get(&b);
                    line += &format!(
                        "; push {s}: relative {mm:.3} mm {deg:.3} deg (same {}); own a {am:.2} mm {ad:.2} deg, b {bm:.2} mm {bd:.2} deg; frames per (group, moving) a {:?} b {:?}",
                        same_motion(pa, pb, &params),
                        ga,
                        gb
                    );
                }
                println!("{line}");
            }
        }
        if t + 1 == frames.len() {
            // Every touching pair the static segmentation merged in every frame: its worst
            // relative motion over the pushes and whether RISeg's last mask separated it.
            for &(a, b) in &touching {
                let always_merged = frames.iter().all(|q| {
                    let seg = static_segments(&q.truth, &q.static_labels);
                    matches!((seg.get(&a), seg.get(&b)), (Some(x), Some(y)) if x == y && *x != 0)
                });
                if !always_merged {
                    continue;
                }
                let (mm, deg) = (1..=t).fold((0.0f32, 0.0f32), |(m, d), s| {
                    let (p, q) = (&frames[s - 1], &frames[s]);
                    let (x, y) =
                        disagreement([&p.poses[&a], &q.poses[&a]], [&p.poses[&b], &q.poses[&b]]);
                    (m.max(x), d.max(y))
                });
                println!(
                    "PAIR {seed} {a} {b} {mm:.3} {deg:.3} {}",
                    u8::from(rl[&a].0 != rl[&b].0)
                );
            }
        }
        let mut groups: BTreeMap<u16, BTreeSet<u16>> = BTreeMap::new();
        for (o, (g, _)) in &cl {
            groups.entry(*g).or_default().insert(*o);
        }
        let merged: Vec<_> = groups.values().filter(|g| g.len() > 1).collect();
        println!("   ceiling groups {merged:?}");
        // Every pair inside a ceiling group: were they alike on every push (the group can
        // also hold pairs that only a chain of alike neighbours joins)?
        for g in &merged {
            let objects: Vec<u16> = g.iter().copied().collect();
            for (i, &a) in objects.iter().enumerate() {
                for &b in &objects[i + 1..] {
                    let pushes: Vec<String> = (1..=t)
                        .map(|s| {
                            let (p, q) = (&frames[s - 1], &frames[s]);
                            let pa = [&p.poses[&a], &q.poses[&a]];
                            let pb = [&p.poses[&b], &q.poses[&b]];
                            let (mm, deg) = disagreement(pa, pb);
                            format!(
                                "{mm:.2}mm/{deg:.2}deg{}",
                                if same_motion(pa, pb, &params) {
                                    ""
                                } else {
                                    " DIFFERENT"
                                }
                            )
                        })
                        .collect();
                    println!(
                        "      in group ({a}, {b}): touching {}, riseg {}; pushes {}",
                        touching.contains(&(a, b)),
                        if rl[&a].0 == rl[&b].0 {
                            "joined"
                        } else {
                            "separated"
                        },
                        pushes.join(", ")
                    );
                }
            }
        }
    }
    Ok(())
}
