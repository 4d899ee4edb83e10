//! riseg's UOIS metrics against the independent Python implementation in
//! `bench/metrics_reference.py` (numpy + scipy's linear_sum_assignment), on 240 seeded
//! random label-map pairs: random blobs, then shifts, merges, splits, dropped and added
//! objects, boundary noise, independent maps, empty maps and whole-image objects.
//!
//! Needs `python3` with numpy and scipy (`pip install numpy scipy`). Without them the test
//! fails when the `CI` environment variable is set, and otherwise prints that it skipped.

use std::path::Path;
use std::process::Command;

use riseg::eval::metrics::{ImageMetrics, image_metrics};
use serde_json::Value;

const CASES: usize = 240;
const TOLERANCE: f64 = 1e-6;

/// Knuth's MMIX linear congruential generator; the high bits are the output.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u32 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 33) as u32
    }

    /// Uniform in `lo..=hi`.
    fn range(&mut self, lo: i64, hi: i64) -> i64 {
        lo + i64::from(self.next()) % (hi - lo + 1)
    }

    fn index(&mut self, n: usize) -> usize {
        self.next() as usize % n
    }

    fn chance(&mut self, percent: u32) -> bool {
        self.next() % 100 < percent
    }
}

#[derive(Clone)]
struct Map {
    width: usize,
    height: usize,
    labels: Vec<u16>,
}

impl Map {
    fn empty(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            labels: vec![0; width * height],
        }
    }

    fn objects(&self) -> Vec<u16> {
        let mut ids: Vec<u16> = self.labels.iter().copied().filter(|&l| l != 0).collect();
        ids.sort_unstable();
        ids.dedup();
        ids
    }

    /// A label not used in the map.
    fn fresh_label(&self, rng: &mut Lcg) -> u16 {
        let used = self.objects();
        loop {
            let label = rng.range(1, 65535) as u16;
            if !used.contains(&label) {
                return label;
            }
        }
    }

    /// Paints one random blob: an ellipse, a rectangle or a union of three discs.
    fn paint_blob(&mut self, rng: &mut Lcg, label: u16, max_radius: i64) {
        let (w, h) = (self.width as i64, self.height as i64);
        let (cx, cy) = (rng.range(0, w - 1), rng.range(0, h - 1));
        let (rx, ry) = (rng.range(1, max_radius), rng.range(1, max_radius));
        let shape = rng.index(3);
        let discs: Vec<(i64, i64, i64)> = (0..3)
            .map(|_| {
                (
                    cx + rng.range(-rx, rx),
                    cy + rng.range(-ry, ry),
                    rng.range(1, rx.max(ry)),
                )
            })
            .collect();
        for y in 0..h {
            for x in 0..w {
                let (dx, dy) = (x - cx, y - cy);
                let inside = match shape {
                    0 => dx * dx * ry * ry + dy * dy * rx * rx <= rx * rx * ry * ry,
                    1 => dx.abs() <= rx && dy.abs() <= ry,
                    _ => discs
                        .iter()
                        .any(|&(qx, qy, r)| (x - qx).pow(2) + (y - qy).pow(2) <= r * r),
                };
                if inside {
                    self.labels[(y * w + x) as usize] = label;
                }
            }
        }
    }

    fn random(rng: &mut Lcg, width: usize, height: usize, objects: usize) -> Self {
        let mut map = Self::empty(width, height);
        let max_radius = (width.min(height) / 4).max(2) as i64;
        for _ in 0..objects {
            let label = map.fresh_label(rng);
            map.paint_blob(rng, label, max_radius);
        }
        map
    }

    fn shifted(&self, dx: i64, dy: i64) -> Self {
        let mut out = Self::empty(self.width, self.height);
        let (w, h) = (self.width as i64, self.height as i64);
        for y in 0..h {
            for x in 0..w {
                let (sx, sy) = (x - dx, y - dy);
                if (0..w).contains(&sx) && (0..h).contains(&sy) {
                    out.labels[(y * w + x) as usize] = self.labels[(sy * w + sx) as usize];
                }
            }
        }
        out
    }

    fn replace(&mut self, from: u16, to: u16) {
        for l in &mut self.labels {
            if *l == from {
                *l = to;
            }
        }
    }

    /// Gives the pixels of `label` on one side of a random line a fresh label.
    fn split(&mut self, rng: &mut Lcg, label: u16) {
        let fresh = self.fresh_label(rng);
        let (nx, ny) = (rng.range(-10, 10), rng.range(-10, 10));
        let pixels: Vec<usize> = (0..self.labels.len())
            .filter(|&i| self.labels[i] == label)
            .collect();
        let (sx, sy) = pixels.iter().fold((0i64, 0i64), |(sx, sy), &i| {
            (sx + (i % self.width) as i64, sy + (i / self.width) as i64)
        });
        let n = pixels.len().max(1) as i64;
        let (cx, cy) = (sx / n, sy / n);
        for i in pixels {
            let (x, y) = ((i % self.width) as i64, (i / self.width) as i64);
            if (x - cx) * nx + (y - cy) * ny > 0 {
                self.labels[i] = fresh;
            }
        }
    }

    /// Copies a 4-neighbour's label into `percent` % of the pixels next to another label.
    fn boundary_noise(&mut self, rng: &mut Lcg, percent: u32) {
        let (w, h) = (self.width, self.height);
        let before = self.labels.clone();
        for y in 0..h {
            for x in 0..w {
                let here = before[y * w + x];
                let neighbours = [
                    (x > 0).then(|| before[y * w + x - 1]),
                    (x + 1 < w).then(|| before[y * w + x + 1]),
                    (y > 0).then(|| before[(y - 1) * w + x]),
                    (y + 1 < h).then(|| before[(y + 1) * w + x]),
                ];
                let other: Vec<u16> = neighbours
                    .into_iter()
                    .flatten()
                    .filter(|&l| l != here)
                    .collect();
                if !other.is_empty() && rng.chance(percent) {
                    self.labels[y * w + x] = other[rng.index(other.len())];
                }
            }
        }
    }

    /// Renumbers every object with distinct random labels.
    fn renumbered(&self, rng: &mut Lcg) -> Self {
        let mut out = Self::empty(self.width, self.height);
        let mut taken = Vec::new();
        for old in self.objects() {
            let new = loop {
                let candidate = if rng.chance(50) {
                    rng.range(1, 12) as u16
                } else {
                    rng.range(1, 65535) as u16
                };
                if !taken.contains(&candidate) {
                    break candidate;
                }
            };
            taken.push(new);
            for (o, &l) in out.labels.iter_mut().zip(&self.labels) {
                if l == old {
                    *o = new;
                }
            }
        }
        out
    }
}

/// A prediction made from `gt` by one to three random edits, renumbered.
fn perturbed(rng: &mut Lcg, gt: &Map) -> Map {
    let mut pred = gt.clone();
    for _ in 0..rng.range(1, 3) {
        let objects = pred.objects();
        match rng.index(8) {
            0 => pred = pred.shifted(rng.range(-4, 4), rng.range(-4, 4)),
            1 if objects.len() >= 2 => {
                let a = objects[rng.index(objects.len())];
                let b = objects[rng.index(objects.len())];
                pred.replace(b, a);
            }
            2 if !objects.is_empty() => {
                let a = objects[rng.index(objects.len())];
                pred.split(rng, a);
            }
            3 if !objects.is_empty() => pred.replace(objects[rng.index(objects.len())], 0),
            4 => {
                let label = pred.fresh_label(rng);
                let max_radius = (pred.width.min(pred.height) / 5).max(2) as i64;
                pred.paint_blob(rng, label, max_radius);
            }
            5 => pred.boundary_noise(rng, 30),
            6 => {
                let objects = rng.index(8);
                pred = Map::random(rng, gt.width, gt.height, objects);
            }
            _ => {} // keep: the unedited copy
        }
    }
    pred.renumbered(rng)
}

/// The 240 cases: the edge cases first, four full-size 640×480 images, the rest random.
fn cases() -> Vec<(Map, Map)> {
    let mut rng = Lcg(0x5eed_2024);
    let mut out = Vec::new();
    for i in 0..CASES {
        let (w, h) = if i % 60 == 5 {
            (640, 480)
        } else {
            (rng.range(16, 96) as usize, rng.range(12, 72) as usize)
        };
        let objects = rng.index(8);
        let gt = Map::random(&mut rng, w, h, if i % 60 == 5 { 5 } else { objects });
        let whole = |label| Map {
            width: w,
            height: h,
            labels: vec![label; w * h],
        };
        let pair = match i {
            0 => (Map::empty(w, h), Map::empty(w, h)),
            1 => (Map::random(&mut rng, w, h, 3), Map::empty(w, h)),
            2 => (Map::empty(w, h), Map::random(&mut rng, w, h, 3)),
            3 => (Map::random(&mut rng, w, h, 3), whole(9)),
            4 => (whole(2), Map::random(&mut rng, w, h, 3)),
            5 => {
                let shifted = gt.shifted(2, -1);
                (gt, shifted.renumbered(&mut rng))
            }
            _ => {
                let pred = perturbed(&mut rng, &gt);
                (gt, pred)
            }
        };
        out.push(pair);
    }
    out
}

fn python_with_scipy() -> bool {
    Command::new("python3")
        .args(["-c", "import numpy, scipy"])
        .status()
        .is_ok_and(|s| s.success())
}

fn write_cases(dir: &Path, cases: &[(Map, Map)]) {
    let mut index = Vec::new();
    for (n, (gt, pred)) in cases.iter().enumerate() {
        let name = format!("case_{n:03}");
        for (suffix, map) in [("gt", gt), ("pred", pred)] {
            let bytes: Vec<u8> = map.labels.iter().flat_map(|l| l.to_le_bytes()).collect();
            std::fs::write(dir.join(format!("{name}_{suffix}.u16")), bytes)
                .expect("writing a label map into the temporary folder");
        }
        index.push(serde_json::json!({
            "name": name,
            "width": gt.width,
            "height": gt.height,
            "gt": format!("{name}_gt.u16"),
            "pred": format!("{name}_pred.u16"),
        }));
    }
    let index = serde_json::json!({ "cases": index });
    std::fs::write(dir.join("index.json"), index.to_string()).expect("writing index.json");
}

/// Every way `ours` differs from the Python result `theirs`.
fn differences(ours: &ImageMetrics, theirs: &Value) -> Vec<String> {
    let mut out = Vec::new();
    let floats = [
        ("overlap P", ours.overlap.precision, &theirs["overlap"][0]),
        ("overlap R", ours.overlap.recall, &theirs["overlap"][1]),
        ("overlap F", ours.overlap.f_measure, &theirs["overlap"][2]),
        (
            "boundary P",
            ours.boundary.precision,
            &theirs["boundary"][0],
        ),
        ("boundary R", ours.boundary.recall, &theirs["boundary"][1]),
        (
            "boundary F",
            ours.boundary.f_measure,
            &theirs["boundary"][2],
        ),
        (
            "detected share",
            ours.objects_detected_share,
            &theirs["objects_detected_share"],
        ),
    ];
    for (what, a, b) in floats {
        let b = b.as_f64().expect("a number from Python");
        if (a - b).abs() > TOLERANCE {
            out.push(format!("{what}: riseg {a}, python {b}"));
        }
    }
    let counts = [
        ("objects_gt", ours.objects_gt),
        ("objects_pred", ours.objects_pred),
        ("objects_detected", ours.objects_detected),
    ];
    for (what, a) in counts {
        let b = theirs[what].as_u64().expect("a count from Python");
        if a as u64 != b {
            out.push(format!("{what}: riseg {a}, python {b}"));
        }
    }
    out
}

#[test]
fn metrics_agree_with_the_independent_python_reference() {
    if !python_with_scipy() {
        let why = "python3 with numpy and scipy is not available (pip install numpy scipy)";
        if std::env::var_os("CI").is_some() {
            panic!("{why}; CI is set, so this comparison must run");
        }
        eprintln!("SKIPPED metrics_agree_with_the_independent_python_reference: {why}");
        return;
    }
    let cases = cases();
    assert!(cases.len() >= 200);
    let dir = tempfile::tempdir().unwrap();
    write_cases(dir.path(), &cases);

    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../bench/metrics_reference.py");
    let output = Command::new("python3")
        .arg(&script)
        .arg(dir.path().join("index.json"))
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{} failed:\n{}",
        script.display(),
        String::from_utf8_lossy(&output.stderr)
    );
    let reference: Value = serde_json::from_slice(&output.stdout).unwrap();
    let results = reference["results"].as_array().unwrap();
    assert_eq!(results.len(), cases.len());

    let mut failures = Vec::new();
    let (mut with_objects, mut partial) = (0, 0);
    for (n, ((gt, pred), theirs)) in cases.iter().zip(results).enumerate() {
        let ours = image_metrics(&gt.labels, &pred.labels, gt.width, gt.height).unwrap();
        if ours.objects_gt > 0 && ours.objects_pred > 0 {
            with_objects += 1;
            if ours.overlap.f_measure < 1.0 {
                partial += 1;
            }
        }
        let diffs = differences(&ours, theirs);
        if !diffs.is_empty() {
            failures.push(format!(
                "case_{n:03} ({}x{}): {}",
                gt.width,
                gt.height,
                diffs.join("; ")
            ));
        }
    }
    // The data must exercise the matching, not only perfect or empty predictions.
    assert!(
        with_objects >= 150 && partial >= 100,
        "{with_objects} / {partial}"
    );
    assert!(
        failures.is_empty(),
        "{} of {} cases disagree:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}
