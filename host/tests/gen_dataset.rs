//! `riseg gen` end to end: determinism, the benchmark contract of every scene, and the
//! exactness of the ground-truth flow. The dataset (3 scenes, seed 1, 3 pushes) is made once
//! per test binary and shared.

#![allow(
    clippy::unwrap_used,
    reason = "test helpers: a panic is the failure report"
)]

use std::{
    collections::BTreeMap,
    fs,
    path::{Path, PathBuf},
    sync::OnceLock,
};

use riseg::{
    r#gen::{GeneratedScene, generate_scene, scene_dir_name, scene_seed, write_dataset},
    imageio::{FlowImage, Gray16Image, RgbImage},
    scene::{Scene, list_scenes},
    sim::TABLE_HALF_EXTENTS_M,
};

const SCENES: usize = 3;
const SEED: u64 = 1;
const PUSHES: usize = 3;

struct Dataset {
    dir: PathBuf,
    generated: Vec<GeneratedScene>,
}

fn fresh_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("riseg-gen-{tag}-{}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    dir
}

fn dataset() -> &'static Dataset {
    static DATASET: OnceLock<Dataset> = OnceLock::new();
    DATASET.get_or_init(|| {
        let dir = fresh_dir("a");
        let mut generated = Vec::new();
        write_dataset(&dir, SCENES, SEED, PUSHES, |_, g| generated.push(g.clone())).unwrap();
        Dataset { dir, generated }
    })
}

/// Every file under `root`, by relative path, with its bytes.
fn all_files(root: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let rel = path.strip_prefix(root).unwrap().to_path_buf();
                out.insert(rel, fs::read(&path).unwrap());
            }
        }
    }
    out
}

#[test]
fn same_seed_gives_identical_files() {
    let first = all_files(&dataset().dir);
    let again = fresh_dir("b");
    write_dataset(&again, SCENES, SEED, PUSHES, |_, _| {}).unwrap();
    let second = all_files(&again);
    // 3 scenes x (camera + actions + 4 rgb + 4 depth + 4 label + 3 flow) + 3 previews.
    assert_eq!(first.len(), SCENES * 17 + SCENES, "{:?}", first.keys());
    assert_eq!(
        first.keys().collect::<Vec<_>>(),
        second.keys().collect::<Vec<_>>()
    );
    for (path, bytes) in &first {
        assert!(
            second[path] == *bytes,
            "{} differs between runs",
            path.display()
        );
    }
    // And the seed matters: another seed gives another initial image.
    let other = generate_scene(scene_seed(SEED + 1, 0), 0).unwrap();
    let own = Scene::read(&dataset().dir.join(scene_dir_name(0))).unwrap();
    assert_ne!(other.scene.rgb[0], own.rgb[0]);
    fs::remove_dir_all(&again).unwrap();
}

/// Labels of the 4-adjacent pixel pairs with two different object ids (not the table).
fn touching_label_pairs(labels: &Gray16Image) -> Vec<(u16, u16)> {
    let (w, h) = (labels.width(), labels.height());
    let mut pairs = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let a = *labels.get(x, y).unwrap();
            for (nx, ny) in [(x + 1, y), (x, y + 1)] {
                let Some(&b) = labels.get(nx, ny) else {
                    continue;
                };
                if a != 0 && b != 0 && a != b {
                    let pair = (a.min(b), a.max(b));
                    if !pairs.contains(&pair) {
                        pairs.push(pair);
                    }
                }
            }
        }
    }
    pairs
}

fn ids(labels: &Gray16Image) -> Vec<u16> {
    let mut ids: Vec<u16> = labels
        .as_slice()
        .iter()
        .copied()
        .filter(|&l| l > 0)
        .collect();
    ids.sort_unstable();
    ids.dedup();
    ids
}

fn max_object_flow(flow: &FlowImage, labels: &Gray16Image) -> f32 {
    flow.as_slice()
        .iter()
        .zip(labels.as_slice())
        .filter(|(_, l)| **l > 0)
        .map(|([dx, dy], _)| (dx * dx + dy * dy).sqrt())
        .fold(0.0, f32::max)
}

#[test]
fn generated_scenes_meet_the_contract() {
    let ds = dataset();
    let scenes = list_scenes(&ds.dir).unwrap();
    assert_eq!(scenes.len(), SCENES);
    for (dir, generated) in scenes.iter().zip(&ds.generated) {
        let scene = Scene::read(dir).unwrap();
        assert_eq!(
            scene,
            generated.scene,
            "{}: read back differs",
            dir.display()
        );
        assert_eq!(scene.frames(), PUSHES + 1);
        assert_eq!(scene.actions.len(), PUSHES);
        let labels = scene.labels.as_ref().unwrap();
        let flow = scene.flow.as_ref().unwrap();

        let objects = ids(&labels[0]);
        assert!(
            (4..=6).contains(&objects.len()),
            "{}: {objects:?}",
            dir.display()
        );
        let pairs = touching_label_pairs(&labels[0]);
        assert!(
            !pairs.is_empty(),
            "{}: no touching pair in the labels",
            dir.display()
        );
        println!(
            "{}: {} objects, touching pairs {pairs:?}, {} attempt(s)",
            dir.display(),
            objects.len(),
            generated.attempts
        );

        for t in 0..PUSHES {
            let moved = max_object_flow(&flow[t], &labels[t]);
            println!("  push {}: largest object flow {moved:.1} px", t + 1);
            assert!(
                moved > 1.0,
                "{}: push {} moved nothing",
                dir.display(),
                t + 1
            );
            // Every object is still in view after the push.
            assert_eq!(
                ids(&labels[t + 1]),
                objects,
                "{}: push {}",
                dir.display(),
                t + 1
            );
        }
        // No object leaves the table: centres over the table top, resting on it.
        for (t, poses) in generated.object_poses.iter().enumerate() {
            assert_eq!(poses.len(), objects.len());
            for p in poses {
                let c = p.world_from_object.translation.vector;
                assert!(
                    c.x.abs() < TABLE_HALF_EXTENTS_M[0] - 0.05
                        && c.y.abs() < TABLE_HALF_EXTENTS_M[1] - 0.05
                        && c.z > 0.0
                        && c.z < 0.08,
                    "{}: frame {t}, object {} at {c:?}",
                    dir.display(),
                    p.label
                );
            }
        }
    }
}

fn bilinear(img: &RgbImage, x: f32, y: f32) -> Option<[f32; 3]> {
    let (x0, y0) = (x.floor(), y.floor());
    if x0 < 0.0 || y0 < 0.0 {
        return None;
    }
    let (ix, iy) = (x0 as u32, y0 as u32);
    let (fx, fy) = (x - x0, y - y0);
    let p = |dx, dy| img.get(ix + dx, iy + dy).map(|c| c.map(f32::from));
    let (a, b, c, d) = (p(0, 0)?, p(1, 0)?, p(0, 1)?, p(1, 1)?);
    Some(core::array::from_fn(|k| {
        (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy
    }))
}

fn abs_diff(a: [f32; 3], b: [f32; 3]) -> f32 {
    (0..3).map(|k| (a[k] - b[k]).abs()).sum::<f32>() / 3.0
}

#[test]
fn warping_back_by_ground_truth_flow_reproduces_the_previous_frame() {
    let ds = dataset();
    let (mut gt_moving, mut zero_moving, mut n_moving) = (0.0_f64, 0.0_f64, 0_u64);
    let (mut gt_all, mut zero_all, mut n_all) = (0.0_f64, 0.0_f64, 0_u64);
    for g in &ds.generated {
        let s = &g.scene;
        let (labels, flow) = (s.labels.as_ref().unwrap(), s.flow.as_ref().unwrap());
        for t in 0..s.frames() - 1 {
            let (now, next) = (&s.rgb[t], &s.rgb[t + 1]);
            for y in 0..now.height() {
                for x in 0..now.width() {
                    let label = *labels[t].get(x, y).unwrap();
                    if label == 0 {
                        continue;
                    }
                    let [dx, dy] = *flow[t].get(x, y).unwrap();
                    let (tx, ty) = (x as f32 + dx, y as f32 + dy);
                    // Same pixel set for both errors: the point is still visible at t+1.
                    let visible = labels[t + 1]
                        .get(tx.round() as u32, ty.round() as u32)
                        .is_some_and(|&l| l == label);
                    let Some(warped) = bilinear(next, tx, ty).filter(|_| visible) else {
                        continue;
                    };
                    let here = now.get(x, y).unwrap().map(f32::from);
                    let still = next.get(x, y).unwrap().map(f32::from);
                    let (e_gt, e_zero) = (abs_diff(here, warped), abs_diff(here, still));
                    gt_all += f64::from(e_gt);
                    zero_all += f64::from(e_zero);
                    n_all += 1;
                    if dx.hypot(dy) > 0.5 {
                        gt_moving += f64::from(e_gt);
                        zero_moving += f64::from(e_zero);
                        n_moving += 1;
                    }
                }
            }
        }
    }
    let mean = |sum: f64, n: u64| sum / n.max(1) as f64;
    let (gt_m, zero_m) = (mean(gt_moving, n_moving), mean(zero_moving, n_moving));
    let (gt_a, zero_a) = (mean(gt_all, n_all), mean(zero_all, n_all));
    println!(
        "mean |I_t - warp(I_t+1)| per channel, 8-bit levels: moving object pixels ({n_moving}): \
         GT flow {gt_m:.2}, zero flow {zero_m:.2}; all object pixels ({n_all}): GT flow \
         {gt_a:.2}, zero flow {zero_a:.2}"
    );
    assert!(n_moving > 1000, "pushes should move many object pixels");
    assert!(
        gt_m < 0.4 * zero_m,
        "GT flow {gt_m:.2} vs zero flow {zero_m:.2}"
    );
    // What remains is sensor noise (sigma 2 per image) and shading changes under rotation.
    assert!(gt_m < 6.0, "GT flow error {gt_m:.2} levels is too large");
    assert!(gt_a < zero_a);
}
