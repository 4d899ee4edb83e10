//! `riseg gen` end to end: determinism, the benchmark contract of every scene, and the
//! exactness of the ground-truth flow. The dataset (3 loose scenes, seed 1, 3 pushes) is
//! made once per test binary and shared; the other scene families are checked on a scene
//! each.

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
    cli::generate::{GeneratedScene, generate_scene, scene_dir_name, write_dataset},
    io::image::{FlowImage, Gray16Image, RgbImage},
    io::scene::{ObjectPose, Scene, list_scenes},
    sim::{Layout, TABLE_HALF_EXTENTS_M, scene_seed},
};

const SCENES: usize = 3;
const SEED: u64 = 1;
const PUSHES: usize = 3;

struct Dataset {
    dir: PathBuf,
    generated: Vec<GeneratedScene>,
}

/// An empty-to-be folder under Cargo's scratch space for integration tests (kept after the
/// run so a failure can be inspected; replaced by the next run).
fn fresh_dir(tag: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("gen-dataset-{tag}"));
    let _ = fs::remove_dir_all(&dir);
    dir
}

fn dataset() -> &'static Dataset {
    static DATASET: OnceLock<Dataset> = OnceLock::new();
    DATASET.get_or_init(|| {
        let dir = fresh_dir("a");
        let mut generated = Vec::new();
        write_dataset(&dir, SCENES, SEED, Layout::Loose, PUSHES, |_, g| {
            generated.push(g.clone());
        })
        .unwrap();
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
    write_dataset(&again, SCENES, SEED, Layout::Loose, PUSHES, |_, _| {}).unwrap();
    let second = all_files(&again);
    // 3 scenes x (camera + actions + poses + 4 rgb + 4 depth + 4 label + 3 flow) + 3
    // previews.
    assert_eq!(first.len(), SCENES * 18 + SCENES, "{:?}", first.keys());
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
    let other = generate_scene(scene_seed(SEED + 1, 0), Layout::Loose, 0).unwrap();
    let own = Scene::read(&dataset().dir.join(scene_dir_name(0))).unwrap();
    assert_ne!(other.scene.rgb[0], own.rgb[0]);
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
        for (t, poses) in scene.poses.as_ref().unwrap().iter().enumerate() {
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

/// Largest horizontal displacement of each object between two pose lists, metres.
fn moved_m(before: &[ObjectPose], after: &[ObjectPose]) -> Vec<f32> {
    before
        .iter()
        .zip(after)
        .map(|(a, b)| {
            assert_eq!(a.label, b.label);
            let d = b.world_from_object.translation.vector - a.world_from_object.translation.vector;
            d.xy().norm()
        })
        .collect()
}

#[test]
fn packed_and_mixed_scenes_are_deterministic_and_their_pushes_shear() {
    let seed = scene_seed(SEED, 0);
    for layout in [Layout::Packed, Layout::Mixed] {
        let g = generate_scene(seed, layout, 2).unwrap();
        let again = generate_scene(seed, layout, 2).unwrap();
        assert_eq!(g.scene, again.scene, "{layout}: same seed, same scene");
        assert_ne!(
            g.scene.rgb[0],
            generate_scene(seed, Layout::Loose, 0).unwrap().scene.rgb[0],
            "{layout}: the family matters"
        );
        let dir = fresh_dir(layout.name());
        g.scene.write(&dir).unwrap();
        assert_eq!(Scene::read(&dir).unwrap(), g.scene, "{layout}: read back");

        let labels = g.scene.labels.as_ref().unwrap();
        assert!((4..=6).contains(&ids(&labels[0]).len()), "{layout}");
        // Every push moves part of the objects by most of its 2 cm and leaves some where
        // they were.
        let poses = g.scene.poses.as_ref().unwrap();
        assert_eq!(poses.len(), 3);
        for t in 0..2 {
            let moved = moved_m(&poses[t], &poses[t + 1]);
            println!("{layout} push {}: moved {moved:?} m", t + 1);
            assert!(moved.iter().any(|&m| m > 0.01), "{layout} push {}", t + 1);
            assert!(moved.iter().any(|&m| m < 0.002), "{layout} push {}", t + 1);
        }
    }
}

fn bilinear(img: &RgbImage, x: f32, y: f32) -> Option<[f32; 3]> {
    let (x0, y0) = (x.floor(), y.floor());
    if x0 < 0.0 || y0 < 0.0 {
        return None;
    }
    let (ix, iy) = (x0 as usize, y0 as usize);
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

/// Mean per-channel error sums of warping frame t+1 back to frame t.
#[derive(Default)]
struct WarpErrors {
    gt: f64,
    zero: f64,
    n: u64,
}

impl WarpErrors {
    fn add(&mut self, gt: f32, zero: f32) {
        self.gt += f64::from(gt);
        self.zero += f64::from(zero);
        self.n += 1;
    }

    fn means(&self) -> (f64, f64) {
        let n = self.n.max(1) as f64;
        (self.gt / n, self.zero / n)
    }
}

#[test]
fn warping_back_by_ground_truth_flow_reproduces_the_previous_frame() {
    let ds = dataset();
    // All object pixels; those that move more than half a pixel; and the moving pixels of
    // objects that turned less than 10 degrees, where brightness constancy holds (a rolling
    // ball turns 50-70 degrees in a push and its shading changes under the fixed light).
    let (mut all, mut moving, mut steady) = (
        WarpErrors::default(),
        WarpErrors::default(),
        WarpErrors::default(),
    );
    for g in &ds.generated {
        let s = &g.scene;
        let (labels, flow) = (s.labels.as_ref().unwrap(), s.flow.as_ref().unwrap());
        for t in 0..s.frames() - 1 {
            let turned_deg = |label: u16| {
                let pose = |poses: &[ObjectPose]| {
                    poses
                        .iter()
                        .find(|p| p.label == label)
                        .unwrap()
                        .world_from_object
                };
                let poses = s.poses.as_ref().unwrap();
                let (a, b) = (pose(&poses[t]), pose(&poses[t + 1]));
                (b.rotation * a.rotation.inverse()).angle().to_degrees()
            };
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
                        .get(tx.round() as usize, ty.round() as usize)
                        .is_some_and(|&l| l == label);
                    let Some(warped) = bilinear(next, tx, ty).filter(|_| visible) else {
                        continue;
                    };
                    let here = now.get(x, y).unwrap().map(f32::from);
                    let still = next.get(x, y).unwrap().map(f32::from);
                    let (e_gt, e_zero) = (abs_diff(here, warped), abs_diff(here, still));
                    all.add(e_gt, e_zero);
                    if dx.hypot(dy) > 0.5 {
                        moving.add(e_gt, e_zero);
                        if turned_deg(label) < 10.0 {
                            steady.add(e_gt, e_zero);
                        }
                    }
                }
            }
        }
    }
    println!("mean |I_t - warp(I_t+1, flow)| per channel, 8-bit levels (GT flow vs zero flow):");
    for (name, e) in [
        ("object pixels", &all),
        ("moving", &moving),
        ("moving, turned < 10 deg", &steady),
    ] {
        let (gt, zero) = e.means();
        println!(
            "  {name:<24} {:>7} px: GT flow {gt:5.2}, zero flow {zero:5.2}",
            e.n
        );
    }
    let ((gt_all, zero_all), (gt_m, zero_m), (gt_s, zero_s)) =
        (all.means(), moving.means(), steady.means());
    assert!(
        moving.n > 5000 && steady.n > 1000,
        "pushes should move many object pixels"
    );
    assert!(gt_all < 0.5 * zero_all && gt_m < 0.4 * zero_m);
    // Where brightness constancy holds, what remains is sensor noise (sigma 2 per image)
    // and bilinear interpolation of the texture.
    assert!(
        gt_s < 0.2 * zero_s,
        "GT flow {gt_s:.2} vs zero flow {zero_s:.2}"
    );
    assert!(
        gt_s < 5.0,
        "GT flow error {gt_s:.2} levels where nothing turned"
    );
}
