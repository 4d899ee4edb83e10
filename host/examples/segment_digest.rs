//! Digests and timing of the classical static segmenter, to check that a change to it
//! keeps its output bit-identical and to measure it with a profiler.
//!
//! - `cargo run --release --example segment_digest` prints one FNV-1a digest of the
//!   labels, heatmap and table plane per frame (synthetic tabletops at two sizes, the
//!   first frame of simulated scenes of every layout, the real frames of the shared data
//!   folder when present) and one over all of them. One segmenter serves every frame in
//!   turn (so scratch reuse across sizes is covered) and a fresh one checks each.
//! - `... --example segment_digest -- time N` segments the first real frame (or the
//!   synthetic tabletop without the shared data) `N` times and prints the least and the
//!   median wall time:
//!   run it under `valgrind --tool=callgrind` for an instruction count (with
//!   `RAYON_NUM_THREADS=1` every stage runs on the timing thread, so the inclusive costs
//!   of the stage functions add up).
//! - `... --example segment_digest -- time N SCENE_DIR` times frame 1 of a scene folder
//!   (`riseg gen`'s output, as `bench/speed.sh` does) instead.

use std::{
    path::{Path, PathBuf},
    time::Instant,
};

use riseg::{
    io::scene::Scene,
    segment::{ClassicalSegmenter, RgbdFrame, SegmenterParams},
    sim::{Layout, SimConfig, SimScene, first_usable_seed, scene_seed},
    testkit::segment::SyntheticTabletop,
};
use riseg_core::Intrinsics;

/// An owned frame to segment.
struct Input {
    name: String,
    width: usize,
    height: usize,
    rgb: Vec<[u8; 3]>,
    depth_m: Vec<f32>,
    k: Intrinsics,
}

fn fnv(hash: &mut u64, bytes: &[u8]) {
    for &b in bytes {
        *hash ^= u64::from(b);
        *hash = hash.wrapping_mul(0x0100_0000_01b3);
    }
}

fn shared_data() -> PathBuf {
    std::env::var_os("RISEG_SHARED_DATA").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data")),
        PathBuf::from,
    )
}

fn real_frame(name: String, color: PathBuf, depth: PathBuf, k: Intrinsics) -> Option<Input> {
    let rgb = riseg::io::image::read_rgb8(&color).ok()?;
    let depth = riseg::io::image::read_gray16(&depth).ok()?;
    let (width, height) = depth.size();
    Some(Input {
        name,
        width,
        height,
        rgb: rgb.as_slice().to_vec(),
        depth_m: depth
            .as_slice()
            .iter()
            .map(|&d| f32::from(d) * 1e-3)
            .collect(),
        k,
    })
}

fn real_frames() -> Vec<Input> {
    let root = shared_data();
    let mut out = Vec::new();
    let ucn = Intrinsics::new(612.937, 613.173, 322.549, 248.158).expect("intrinsics");
    let demo = root.join("ucn-demo/data/demo");
    for i in 0..9 {
        out.extend(real_frame(
            format!("ucn_{i:06}"),
            demo.join(format!("{i:06}-color.png")),
            demo.join(format!("{i:06}-depth.png")),
            ucn,
        ));
    }
    let kinect = Intrinsics::new(525.0, 525.0, 319.5, 239.5).expect("intrinsics");
    let osd = root.join("osd-samples/sample_data");
    for name in ["learn6", "test42", "test50", "test63", "test64"] {
        out.extend(real_frame(
            format!("osd_{name}"),
            osd.join(format!("image_color/{name}.png")),
            osd.join(format!("disparity/{name}.png")),
            kinect,
        ));
    }
    out
}

fn synthetic(width: usize, height: usize, seed: u64) -> Input {
    let t = SyntheticTabletop::boxes(width, height, seed).expect("scene");
    Input {
        name: format!("synthetic_{width}x{height}_{seed}"),
        width,
        height,
        rgb: t.rgb,
        depth_m: t.depth_m,
        k: t.intrinsics,
    }
}

fn simulated(layout: Layout, scene: usize) -> Option<Input> {
    let config = SimConfig::D415.with_layout(layout);
    let mut found = first_usable_seed(scene_seed(1, scene), |s| {
        Ok::<_, ()>(SimScene::with_config(s, config))
    })
    .ok()?
    .ok()?;
    let f = found.value.render();
    let (width, height) = f.depth_m.size();
    Some(Input {
        name: format!("sim_{layout}_{scene}"),
        width,
        height,
        rgb: f.rgb.as_slice().to_vec(),
        depth_m: f.depth_m.as_slice().to_vec(),
        k: f.intrinsics,
    })
}

fn digest(seg: &mut ClassicalSegmenter, f: &Input) -> u64 {
    let frame = RgbdFrame::new(f.width, f.height, &f.rgb, &f.depth_m).expect("frame");
    let mut hash = 0xcbf2_9ce4_8422_2325;
    match seg.segment_detailed(&frame, &f.k) {
        Ok(out) => {
            let s = &out.segmentation;
            for &l in s.labels.as_slice() {
                fnv(&mut hash, &l.to_le_bytes());
            }
            fnv(&mut hash, s.heatmap.as_slice());
            for v in [
                out.plane.normal.x,
                out.plane.normal.y,
                out.plane.normal.z,
                out.plane.offset_m,
            ] {
                fnv(&mut hash, &v.to_le_bytes());
            }
        }
        Err(e) => fnv(&mut hash, e.to_string().as_bytes()),
    }
    hash
}

/// The first real frame of the shared data, or a synthetic tabletop without it.
fn first_real_frame() -> Input {
    let demo = shared_data().join("ucn-demo/data/demo");
    let ucn = Intrinsics::new(612.937, 613.173, 322.549, 248.158).expect("intrinsics");
    real_frame(
        "ucn_000000".into(),
        demo.join("000000-color.png"),
        demo.join("000000-depth.png"),
        ucn,
    )
    .unwrap_or_else(|| synthetic(640, 480, 1))
}

/// Frame 1 of a scene folder (the frame `bench/speed.sh` times).
fn scene_frame(dir: &Path) -> Input {
    let scene = Scene::read(dir).expect("a scene folder");
    let t = 1.min(scene.rgb.len() - 1);
    let (width, height) = scene.rgb[t].size();
    Input {
        name: format!("{} frame {t}", dir.display()),
        width,
        height,
        rgb: scene.rgb[t].as_slice().to_vec(),
        depth_m: scene.depth[t]
            .as_slice()
            .iter()
            .map(|&r| scene.camera.depth_m(r))
            .collect(),
        k: scene.camera.intrinsics(),
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let params = SegmenterParams::default();
    if args.first().map(String::as_str) == Some("time") {
        let n: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(20);
        let f = match args.get(2) {
            Some(dir) => scene_frame(Path::new(dir)),
            None => first_real_frame(),
        };
        let mut seg = ClassicalSegmenter::new(params).expect("params");
        let frame = RgbdFrame::new(f.width, f.height, &f.rgb, &f.depth_m).expect("frame");
        // Inside a pool (`RAYON_NUM_THREADS` threads) so that, on one thread, every stage
        // runs on the calling thread and a profiler's inclusive costs add up per stage.
        let pool = rayon::ThreadPoolBuilder::new()
            .build()
            .expect("a thread pool");
        let mut ms: Vec<f64> = pool.install(|| {
            (0..n)
                .map(|_| {
                    let start = Instant::now();
                    core::hint::black_box(seg.segment_detailed(&frame, &f.k).expect("segments"));
                    start.elapsed().as_secs_f64() * 1e3
                })
                .collect()
        });
        ms.sort_by(f64::total_cmp);
        if let (Some(min), Some(median)) = (ms.first(), ms.get(n / 2)) {
            println!(
                "{}: {n} runs, min {min:.2} ms, median {median:.2} ms",
                f.name
            );
        }
        return;
    }
    let mut inputs = vec![
        synthetic(640, 480, 1),
        synthetic(640, 480, 2),
        synthetic(320, 240, 3),
    ];
    for layout in [Layout::Loose, Layout::Packed, Layout::Mixed] {
        for scene in 0..4 {
            inputs.extend(simulated(layout, scene));
        }
    }
    inputs.extend(real_frames());
    inputs.push(synthetic(333, 211, 4));
    let mut shared = ClassicalSegmenter::new(params).expect("params");
    let mut all = 0xcbf2_9ce4_8422_2325;
    for f in &inputs {
        let d = digest(&mut shared, f);
        let fresh = digest(&mut ClassicalSegmenter::new(params).expect("params"), f);
        assert_eq!(d, fresh, "{}: reused and fresh segmenters differ", f.name);
        println!("{:<28} {d:016x}", f.name);
        fnv(&mut all, &d.to_le_bytes());
    }
    println!("{} frames, all {all:016x}", inputs.len());
}
