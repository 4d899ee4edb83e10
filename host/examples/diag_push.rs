//! What each of FindAction's pushes did in `riseg bench`'s closed loop: per push, the
//! certain clusters FindAction saw (the true object and mask label under each pixel
//! centre), the pushed cluster and its pair, the objects the push's line crosses ahead of
//! its start (the ones it is likely to carry), the objects that truly moved (1 mm or 1.5
//! degrees), and the motion ceiling's merged groups before and after the push.
//!
//! `cargo run --release --example diag_push -- LAYOUT SIM_SEED...` (`LAYOUT`: loose,
//! packed or mixed; the sim seeds are those `riseg bench --per-scene` prints).

use std::collections::{BTreeMap, BTreeSet};

use riseg::{
    eval::ceiling::{CeilingFrame, CeilingParams, MotionCeiling, moved},
    io::scene::ObjectPose,
    rig::episode::Decision,
    sim::Layout,
};
use riseg_core::Pose;

#[path = "support/sim_episode.rs"]
mod sim_episode;
use sim_episode::{FrameTruth, frame_truth, run_sim_episode};

struct Frame {
    truth: Vec<u16>,
    static_labels: Vec<u16>,
    poses: BTreeMap<u16, Pose>,
    pose_list: Vec<ObjectPose>,
    /// Certain clusters: (true object, mask label, samples) at each pixel centre.
    clusters: Vec<(u16, u16, u32)>,
    /// Pushed and other cluster, push start and target pixels.
    push: Option<(usize, usize, [f32; 2], [f32; 2])>,
    heat: Vec<u8>,
    centres: Vec<[f32; 2]>,
}

fn at(img: &[u16], w: usize, h: usize, p: [f32; 2]) -> u16 {
    let (x, y) = (p[0].round(), p[1].round());
    if x < 0.0 || y < 0.0 || x as usize >= w || y as usize >= h {
        return 0;
    }
    img[y as usize * w + x as usize]
}

/// The objects the line from `start` through `target` crosses, in order, up to the first
/// stretch of more than `gap` pixels of background after an object.
fn line_objects(truth: &[u16], w: usize, h: usize, start: [f32; 2], target: [f32; 2]) -> Vec<u16> {
    let (dx, dy) = (target[0] - start[0], target[1] - start[1]);
    let len = (dx * dx + dy * dy).sqrt().max(1e-3);
    let d = [dx / len, dy / len];
    let mut out: Vec<u16> = Vec::new();
    let mut last_obj = 0.0f32;
    let mut t = 0.0f32;
    while t < 1000.0 {
        let l = at(truth, w, h, [start[0] + t * d[0], start[1] + t * d[1]]);
        if l != 0 {
            if out.last() != Some(&l) {
                out.push(l);
            }
            last_obj = t;
        } else if !out.is_empty() && t - last_obj > 4.0 {
            break;
        }
        t += 0.5;
    }
    out
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let layout = Layout::ALL
        .into_iter()
        .find(|l| args.first().is_some_and(|a| a == l.name()))
        .unwrap_or(Layout::Packed);
    let dump = std::env::var("DIAG_DUMP").ok();
    for seed in args.iter().skip(1).filter_map(|a| a.parse::<u64>().ok()) {
        scene(seed, layout, dump.as_deref())?;
    }
    Ok(())
}

fn groups_of(mask: &[u16], truth: &[u16]) -> Vec<BTreeSet<u16>> {
    let mut counts: BTreeMap<u16, BTreeMap<u16, usize>> = BTreeMap::new();
    for (&t, &l) in truth.iter().zip(mask) {
        if t != 0 {
            *counts.entry(t).or_default().entry(l).or_default() += 1;
        }
    }
    let mut g: BTreeMap<u16, BTreeSet<u16>> = BTreeMap::new();
    for (t, c) in counts {
        let l = c
            .iter()
            .max_by_key(|(l, n)| (**n, u16::MAX - **l))
            .map_or(0, |x| *x.0);
        g.entry(l).or_default().insert(t);
    }
    g.into_values().filter(|s| s.len() > 1).collect()
}

/// Writes `DIR/SEED_T.png`: the heatmap's classes (certain light, uncertain mid, table
/// dark), true object borders red, cluster centres green (pushed: yellow).
fn dump_frame(
    dir: &str,
    seed: u64,
    t: usize,
    fr: &Frame,
    w: usize,
    h: usize,
) -> anyhow::Result<()> {
    let cfg = riseg_core::Config::PAPER;
    let mut img = image::RgbImage::new(w as u32, h as u32);
    for y in 0..h {
        for x in 0..w {
            let v = fr.heat[y * w + x];
            let g = if v >= cfg.certain_from {
                200
            } else if v >= cfg.uncertain_from {
                110
            } else {
                30
            };
            let l = fr.truth[y * w + x];
            let border = (x + 1 < w && fr.truth[y * w + x + 1] != l)
                || (y + 1 < h && fr.truth[(y + 1) * w + x] != l);
            let px = if border && l != 0 {
                [255, 0, 0]
            } else {
                [g, g, g]
            };
            img.put_pixel(x as u32, y as u32, image::Rgb(px));
        }
    }
    for (k, c) in fr.centres.iter().enumerate() {
        let col = if fr.push.is_some_and(|p| p.0 == k) {
            [255, 255, 0]
        } else {
            [0, 255, 0]
        };
        for dy in -2i32..=2 {
            for dx in -2i32..=2 {
                let (x, y) = (c[0].round() as i32 + dx, c[1].round() as i32 + dy);
                if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
                    img.put_pixel(x as u32, y as u32, image::Rgb(col));
                }
            }
        }
    }
    if let Some((_, _, s, tg)) = fr.push {
        for i in 0..=40 {
            let a = i as f32 / 40.0;
            let (x, y) = (s[0] + a * (tg[0] - s[0]), s[1] + a * (tg[1] - s[1]));
            if x >= 0.0 && y >= 0.0 && (x as usize) < w && (y as usize) < h {
                img.put_pixel(x as u32, y as u32, image::Rgb([0, 128, 255]));
            }
        }
    }
    img.save(format!("{dir}/{seed}_{t}.png"))?;
    Ok(())
}

fn scene(seed: u64, layout: Layout, dump: Option<&str>) -> anyhow::Result<()> {
    let mut frames: Vec<Frame> = Vec::new();
    let (mut width, mut height) = (0, 0);
    run_sim_episode(seed, layout, |f| {
        (width, height) = f.frame.size();
        let (w, h) = (width, height);
        let FrameTruth {
            truth,
            pose_list,
            poses,
        } = frame_truth(f)?;
        let clusters = f
            .action
            .certain()
            .iter()
            .map(|c| {
                (
                    at(&truth, w, h, c.centre_px),
                    at(&f.observation.mask, w, h, c.centre_px),
                    c.samples,
                )
            })
            .collect();
        let push = match (f.decision, f.action.pair()) {
            (Decision::Push { push, .. }, Some(pair)) => {
                Some((pair.pushed, pair.other, push.start_px, push.target_px))
            }
            _ => None,
        };
        let heat = f.observation.static_seg.heatmap.as_slice().to_vec();
        let centres = f.action.certain().iter().map(|c| c.centre_px).collect();
        frames.push(Frame {
            heat,
            centres,
            truth,
            static_labels: f.observation.static_seg.labels.as_slice().to_vec(),
            poses,
            pose_list,
            clusters,
            push,
        });
        Ok(())
    })?;
    let params = CeilingParams::DEFAULT;
    let mut ceiling = MotionCeiling::new(params);
    let mut ceil_groups = Vec::new();
    for fr in &frames {
        let m = ceiling.next_frame(&CeilingFrame {
            width,
            height,
            truth: &fr.truth,
            static_labels: &fr.static_labels,
            poses: &fr.pose_list,
        })?;
        ceil_groups.push(groups_of(&m, &fr.truth));
    }
    if let Some(dir) = dump {
        for (t, fr) in frames.iter().enumerate() {
            dump_frame(dir, seed, t, fr, width, height)?;
        }
    }
    let n_obj = frames[0].poses.len();
    println!("######## {seed} ({layout}) objects {n_obj}");
    for t in 0..frames.len().saturating_sub(1) {
        let fr = &frames[t];
        let next = &frames[t + 1];
        let cl: Vec<String> = fr
            .clusters
            .iter()
            .enumerate()
            .map(|(k, (o, l, n))| format!("c{k}=o{o}/m{l}/{n}"))
            .collect();
        println!("  push {}: clusters {}", t + 1, cl.join(" "));
        let moved_objs: BTreeSet<u16> = fr
            .poses
            .keys()
            .filter(|o| moved([&fr.poses[o], &next.poses[o]], &params))
            .copied()
            .collect();
        if let Some((i, j, s, tg)) = fr.push {
            let oi = fr.clusters.get(i).map_or(0, |c| c.0);
            let oj = fr.clusters.get(j).map_or(0, |c| c.0);
            let line = line_objects(&fr.truth, width, height, s, tg);
            println!(
                "    pushed c{i} (o{oi}) pair c{j} (o{oj}); line {line:?}; moved {moved_objs:?}"
            );
        }
        println!(
            "    ceiling groups before {:?} after {:?}",
            ceil_groups[t],
            ceil_groups[t + 1]
        );
    }
    Ok(())
}
