//! Diagnosis of closed-loop simulated episodes (as `riseg bench` runs them), stage by
//! stage: per push, which objects truly moved, the flow's error on each object, the body
//! frames' twists and groups, the static segments and the accumulated mask, each against
//! the ground-truth objects; then RISeg's and the motion ceiling's objects found.
//!
//! `cargo run --release --example diag_loop -- LAYOUT [--exact] [--quiet] SIM_SEED...`
//! (`LAYOUT`: loose, packed or mixed; the sim seeds of a bench's scenes are printed by
//! `riseg bench --per-scene`). `--exact` feeds the tracker the simulator's exact flow
//! instead of the built-in one, so the core is judged apart from the flow; `--quiet`
//! prints one line per scene. `--dump DIR` (without `--quiet`) writes each push's pair as
//! `DIR/SEED_T.a.png`, `.b.png` (frames `T-1` and `T`), `.labels.png` (truth at `T-1`)
//! and `.gt.flo` (exact flow), which the `flow_objects` example reads. The built-in flow
//! gets each push's motion hint as in `riseg bench`; `DIAG_NO_HINT=1` withholds it.

use core::cell::RefCell;
use std::{collections::BTreeMap, rc::Rc};

use riseg::{
    eval::ceiling::{CeilingParams, MotionCeiling},
    eval::metrics::image_metrics,
    flow::{DisFlow, FlowError, FlowEstimator, FlowParams},
    io::image::FlowImage,
    io::image::{DepthImage, Gray16Image},
    io::scene::ObjectPose,
    rig::camera::{Camera, CameraError, CameraFrame},
    rig::episode::run_episode,
    rig::tracker::Tracker,
    segment::{ClassicalSegmenter, SegmenterParams},
    sim::{Layout, SimCamera, SimConfig, SimRig, SimScene, ground_truth_flow},
};
use riseg_core::Config;

fn histogram(a: &[u16], b: &[u16]) -> BTreeMap<u16, BTreeMap<u16, u32>> {
    let mut m: BTreeMap<u16, BTreeMap<u16, u32>> = BTreeMap::new();
    for (&p, &l) in a.iter().zip(b) {
        if p != 0 {
            *m.entry(p).or_default().entry(l).or_default() += 1;
        }
    }
    m
}

/// Frames the camera took: (truth labels, depth, poses).
type Taken = Rc<RefCell<Vec<(Gray16Image, DepthImage, Vec<ObjectPose>)>>>;

/// The simulated camera, remembering each capture's ground truth.
struct Recording {
    camera: SimCamera,
    taken: Taken,
}

impl Camera for Recording {
    fn capture(&mut self) -> Result<CameraFrame, CameraError> {
        let f = self.camera.capture()?;
        self.taken.borrow_mut().push((
            f.truth.clone().expect("truth"),
            f.depth_m.clone(),
            f.truth_poses.clone().expect("poses"),
        ));
        Ok(f)
    }
}

/// The exact flow between the last two captures, or the built-in flow.
struct MaybeExact {
    taken: Taken,
    world_from_camera: riseg_core::Pose,
    intrinsics: riseg_core::Intrinsics,
    dis: DisFlow,
    exact: bool,
}

impl FlowEstimator for MaybeExact {
    fn estimate_with_hint(
        &self,
        first: riseg_core::ImageView<'_, [u8; 3]>,
        second: riseg_core::ImageView<'_, [u8; 3]>,
        hint_px: [f32; 2],
    ) -> Result<FlowImage, FlowError> {
        if self.exact || std::env::var_os("DIAG_NO_HINT").is_some() {
            return self.estimate(first, second);
        }
        self.dis.estimate_with_hint(first, second, hint_px)
    }

    fn estimate(
        &self,
        first: riseg_core::ImageView<'_, [u8; 3]>,
        second: riseg_core::ImageView<'_, [u8; 3]>,
    ) -> Result<FlowImage, FlowError> {
        if !self.exact {
            return self.dis.estimate(first, second);
        }
        let taken = self.taken.borrow();
        let [.., (labels, depth, before), (_, _, after)] = taken.as_slice() else {
            panic!("two captures");
        };
        Ok(ground_truth_flow(
            &self.intrinsics,
            &self.world_from_camera,
            labels,
            depth,
            before,
            after,
        )
        .expect("exact flow")
        .with_unknown_as_nan())
    }
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let layout = match args.first().map(String::as_str) {
        Some("loose") => Layout::Loose,
        Some("mixed") => Layout::Mixed,
        _ => Layout::Packed,
    };
    let exact = args.iter().any(|a| a == "--exact");
    let quiet = args.iter().any(|a| a == "--quiet");
    let dump = args
        .iter()
        .position(|a| a == "--dump")
        .and_then(|i| args.get(i + 1))
        .map(std::path::PathBuf::from);
    let (mut total, mut found, mut reach) = (0, 0, 0);
    for seed in args.iter().skip(1).filter_map(|a| a.parse::<u64>().ok()) {
        let (n, f, c) = one(seed, layout, exact, quiet, dump.as_deref())?;
        println!("scene {seed}: riseg {f}/{n} ceiling {c}/{n}");
        total += n;
        found += f;
        reach += c;
    }
    println!("all: riseg {found}/{total} ceiling {reach}/{total}");
    Ok(())
}

fn one(
    seed: u64,
    layout: Layout,
    exact: bool,
    quiet: bool,
    dump: Option<&std::path::Path>,
) -> anyhow::Result<(usize, usize, usize)> {
    let mut ceiling = MotionCeiling::new(CeilingParams::DEFAULT);
    let mut last = (0, 0, 0);
    let sim = SimScene::with_config(seed, SimConfig::D415.with_layout(layout))?;
    let intrinsics = sim.intrinsics();
    let rig = SimRig::new(sim);
    let taken: Taken = Rc::default();
    let mut camera = Recording {
        camera: rig.camera,
        taken: Rc::clone(&taken),
    };
    let mut robot = rig.robot;
    let cfg = Config::PAPER;
    let mut tracker = Tracker::new(
        ClassicalSegmenter::new(SegmenterParams::default())?,
        MaybeExact {
            taken,
            world_from_camera: rig.setup.robot_from_camera,
            intrinsics,
            dis: DisFlow::new(FlowParams::MEDIUM)?.with_threads(1)?,
            exact,
        },
        cfg,
    )?;
    let world_from_camera = rig.setup.robot_from_camera;
    let mut prev: Option<(Vec<u16>, Vec<ObjectPose>)> = None;
    let mut prev_frame: Option<CameraFrame> = None;
    run_episode(&mut camera, &mut robot, &mut tracker, &rig.setup, |f| {
        let truth = f.frame.truth.as_ref().ok_or("truth")?.as_slice().to_vec();
        let poses = f.frame.truth_poses.clone().ok_or("poses")?;
        let (w, h) = f.frame.size();
        let cf = f
            .frame
            .ceiling_frame(f.observation.static_seg.labels.as_slice())
            .ok_or("ceil")?;
        let cmask = ceiling.next_frame(&cf).map_err(|e| e.to_string())?;
        let cm = image_metrics(&truth, &cmask, w, h).map_err(|e| e.to_string())?;
        let rm = image_metrics(&truth, &f.observation.mask, w, h).map_err(|e| e.to_string())?;
        last = (rm.objects_gt, rm.objects_detected, cm.objects_detected);
        if quiet {
            return Ok(());
        }
        println!("== frame {} decision {:?}", f.t, f.decision);
        if let Some((prev_truth, prev_poses)) = &prev {
            for (a, b) in prev_poses.iter().zip(&poses) {
                let d = a.world_from_object.inverse() * b.world_from_object;
                println!(
                    "   object {} moved {:.1} mm {:.2} deg",
                    a.label,
                    1e3 * (b.world_from_object.translation.vector
                        - a.world_from_object.translation.vector)
                        .norm(),
                    d.rotation.angle().to_degrees()
                );
            }
            if let (Some(step), Some(pf)) = (&f.observation.step, &prev_frame) {
                let exact = ground_truth_flow(
                    &pf.intrinsics,
                    &world_from_camera,
                    pf.truth.as_ref().ok_or("truth")?,
                    &pf.depth_m,
                    prev_poses,
                    &poses,
                )
                .map_err(|e| e.to_string())?;
                let exact = exact.with_unknown_as_nan();
                if let Some(dir) = dump {
                    let stem = dir.join(format!("{seed}_{}", f.t));
                    std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
                    let name = |s: &str| stem.with_extension(s);
                    riseg::io::image::write_rgb8(&name("a.png"), &pf.rgb)
                        .map_err(|e| e.to_string())?;
                    riseg::io::image::write_rgb8(&name("b.png"), &f.frame.rgb)
                        .map_err(|e| e.to_string())?;
                    riseg::io::image::write_gray16(
                        &name("labels.png"),
                        pf.truth.as_ref().ok_or("truth")?,
                    )
                    .map_err(|e| e.to_string())?;
                    riseg::io::image::write_flo(&name("gt.flo"), &exact)
                        .map_err(|e| e.to_string())?;
                }
                let mut err: BTreeMap<u16, (f64, u32, u32, [f32; 4])> = BTreeMap::new();
                for (i, &l) in prev_truth.iter().enumerate() {
                    if l == 0 || pf.depth_m.as_slice()[i] <= 0.0 {
                        continue;
                    }
                    let (a, b) = (step.flow.as_slice()[i], exact.as_slice()[i]);
                    let e = f64::from(((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt());
                    let s = err.entry(l).or_default();
                    s.0 += e;
                    s.1 += 1;
                    s.2 += u32::from(e > 3.0);
                    s.3[0] += a[0];
                    s.3[1] += a[1];
                    s.3[2] += b[0];
                    s.3[3] += b[1];
                }
                for (l, (sum, n, bad, m)) in err {
                    let k = n as f32;
                    println!(
                        "   object {l}: flow EPE {:.2} px, {:.1} % over 3 px; mean flow ({:.1}, {:.1}) exact ({:.1}, {:.1})",
                        sum / f64::from(n),
                        100.0 * f64::from(bad) / f64::from(n),
                        m[0] / k,
                        m[1] / k,
                        m[2] / k,
                        m[3] / k
                    );
                }
                println!("   {:?}", step.report.grouping);
                let mut hist: BTreeMap<Option<u16>, (bool, BTreeMap<u16, u32>)> = BTreeMap::new();
                for g in &step.frames {
                    let [u, v] = g.frame.px_t[0];
                    let l = prev_truth[v as usize * w + u as usize];
                    let e = hist.entry(g.group).or_default();
                    e.0 = g.moving;
                    *e.1.entry(l).or_default() += 1;
                }
                let origin = step.report.frames.space_origin;
                let mut norms: BTreeMap<u16, Vec<f32>> = BTreeMap::new();
                for g in &step.frames {
                    let [u, v] = g.frame.px_t[0];
                    let l = prev_truth[v as usize * w + u as usize];
                    let tw = g.frame.twist(&origin).unwrap_or(riseg_core::Twist::ZERO);
                    norms
                        .entry(l)
                        .or_default()
                        .push(tw.norm_squared(cfg.length_scale_m).sqrt());
                }
                let mut comps: BTreeMap<u16, Vec<[f32; 6]>> = BTreeMap::new();
                for g in &step.frames {
                    let [u, v] = g.frame.px_t[0];
                    let l = prev_truth[v as usize * w + u as usize];
                    let tw = g.frame.twist(&origin).unwrap_or(riseg_core::Twist::ZERO);
                    let s = cfg.length_scale_m;
                    comps.entry(l).or_default().push([
                        tw.w[0] * s,
                        tw.w[1] * s,
                        tw.w[2] * s,
                        tw.v[0],
                        tw.v[1],
                        tw.v[2],
                    ]);
                }
                for (l, v) in &comps {
                    let med: Vec<f32> = (0..6)
                        .map(|k| {
                            let mut c: Vec<f32> = v.iter().map(|x| x[k]).collect();
                            c.sort_by(f32::total_cmp);
                            1e3 * c[c.len() / 2]
                        })
                        .collect();
                    let mut d: Vec<f32> = v
                        .iter()
                        .map(|x| {
                            (0..6)
                                .map(|k| (1e3 * x[k] - med[k]).powi(2))
                                .sum::<f32>()
                                .sqrt()
                        })
                        .collect();
                    d.sort_by(f32::total_cmp);
                    println!(
                        "   object {l}: median twist mm {med:.2?}, distance to it q25 {:.2} q50 {:.2} q75 {:.2} q90 {:.2}",
                        d[d.len() / 4],
                        d[d.len() / 2],
                        d[d.len() * 3 / 4],
                        d[d.len() * 9 / 10]
                    );
                }
                for (l, mut v) in norms {
                    v.sort_by(f32::total_cmp);
                    let q = |p: f32| v[((v.len() - 1) as f32 * p) as usize];
                    println!(
                        "   object {l}: twist norm q10 {:.4} q50 {:.4} q90 {:.4} (n {})",
                        q(0.1),
                        q(0.5),
                        q(0.9),
                        v.len()
                    );
                }
                // Would the truth partition of each two-object group pass split.rs?
                for (g, (_, h)) in &hist {
                    let objs: Vec<u16> = h
                        .iter()
                        .filter(|(_, n)| **n >= 15)
                        .map(|(l, _)| *l)
                        .collect();
                    if g.is_none() || objs.len() != 2 {
                        continue;
                    }
                    let member = |gf: &riseg::rig::tracker::GroupedFrame, l: Option<u16>| {
                        let [u, v] = gf.frame.px_t[0];
                        gf.group == *g
                            && l.is_none_or(|l| prev_truth[v as usize * w + u as usize] == l)
                    };
                    let pts = |l: Option<u16>| {
                        step.frames
                            .iter()
                            .filter(move |gf| member(gf, l))
                            .flat_map(|gf| gf.frame.p_t.iter().zip(gf.frame.p_t1.iter()))
                    };
                    let fit = |l| {
                        riseg_core::se3::fit_rigid_motion(pts(l)).expect("a group of 15+ frames")
                    };
                    let one = fit(None);
                    let parts = [fit(Some(objs[0])), fit(Some(objs[1]))];
                    let mean_miss = |m: &riseg_core::Pose, l: Option<u16>| {
                        let (mut s, mut n) = (0.0, 0.0);
                        for (a, b) in pts(l) {
                            s += (m * a - b).norm();
                            n += 1.0;
                        }
                        (s, n)
                    };
                    let (s1, n1) = mean_miss(&one, None);
                    let (sa, na) = mean_miss(&parts[0], Some(objs[0]));
                    let (sb, nb) = mean_miss(&parts[1], Some(objs[1]));
                    let cen = |l| {
                        let (mut c, mut n) = (nalgebra::Vector3::zeros(), 0.0);
                        for (a, _) in pts(Some(l)) {
                            c += a.coords;
                            n += 1.0;
                        }
                        nalgebra::Point3::from(c / n)
                    };
                    let gap = [cen(objs[0]), cen(objs[1])]
                        .iter()
                        .map(|c| (parts[0] * c - parts[1] * c).norm())
                        .fold(0.0f32, f32::max);
                    println!(
                        "   group {g:?} truth split {objs:?}: miss one {:.2} mm, split {:.2} mm (ratio {:.2}), gap {:.2} mm",
                        1e3 * s1 / n1,
                        1e3 * (sa + sb) / (na + nb),
                        (sa + sb) / (na + nb) / (s1 / n1),
                        1e3 * gap
                    );
                }
                for (g, (moving, h)) in &hist {
                    println!("   group {g:?} moving {moving}: frames per object {h:?}");
                }
            }
        }
        for (s, h) in histogram(f.observation.static_seg.labels.as_slice(), &truth) {
            println!("   static {s}: {h:?}");
        }
        for (s, h) in histogram(&f.observation.mask, &truth) {
            println!("   mask {s}: {h:?}");
        }
        prev = Some((truth, poses));
        prev_frame = Some(f.frame.clone());
        Ok(())
    })?;
    Ok(last)
}
