//! A ray-cast tabletop RGB-D frame with known instance labels, for tests and benchmarks of
//! segmenters: boxes on a table seen by a camera 60 cm above it, tilted 15° from straight
//! down (the simulator's viewpoint), with D415-like depth noise quantised to millimetres.
//!
//! Layout (table frame: z up, metres; the camera looks at the origin from `-y`). Every box
//! is at most 7 cm across, the size of one object the heatmap's pack rule allows:
//!
//! | label | box | x range | y range | height | note |
//! |---|---|---|---|---|---|
//! | 1 | A | -0.21..-0.14 | -0.035..0.035 | 0.08 | alone |
//! | 2 | B | -0.06..0.005 | -0.04..0.04 | 0.06 | touches C |
//! | 3 | C | 0.005..0.075 | -0.05..0.05 | 0.09 | touches B |
//! | 4 | D | 0.15..0.21 | 0.02..0.09 | 0.05 | alone |
//! | 5 | E | -0.11..-0.04 | 0.11..0.17 | 0.05 | flush with F, same height |
//! | 6 | F | -0.04..0.03 | 0.11..0.17 | 0.05 | flush with E, same height |

use riseg_core::{Intrinsics, rng::Pcg32};

#[cfg(test)]
use crate::segment::SegmenterParams;

/// Boxes of [`SyntheticTabletop::boxes`]: `[x0, x1, y0, y1, height]` (metres) and colour.
const BOXES: [([f32; 5], [u8; 3]); 6] = [
    ([-0.21, -0.14, -0.035, 0.035, 0.08], [200, 40, 40]),
    ([-0.06, 0.005, -0.04, 0.04, 0.06], [40, 170, 60]),
    ([0.005, 0.075, -0.05, 0.05, 0.09], [50, 70, 200]),
    ([0.15, 0.21, 0.02, 0.09, 0.05], [220, 200, 40]),
    ([-0.11, -0.04, 0.11, 0.17, 0.05], [150, 90, 170]),
    ([-0.04, 0.03, 0.11, 0.17, 0.05], [160, 100, 150]),
];
const TABLE_COLOUR: [u8; 3] = [170, 135, 95];
const CAMERA_HEIGHT_M: f32 = 0.6;
const TILT_DEG: f32 = 15.0;
const NOISE_M: f32 = 0.0008;

/// An owned synthetic RGB-D frame with its ground truth.
#[derive(Debug, Clone)]
pub struct SyntheticTabletop {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Intrinsics (D415-like, 615 px focal length at 640 px width).
    pub intrinsics: Intrinsics,
    /// Colour, row-major.
    pub rgb: Vec<[u8; 3]>,
    /// Depth in metres (quantised to millimetres), row-major; every pixel has a reading.
    pub depth_m: Vec<f32>,
    /// True instance labels (module docs), `0` = table.
    pub truth: Vec<u16>,
}

impl SyntheticTabletop {
    /// Renders the scene of the module docs at `width × height`; `seed` fixes the noise.
    ///
    /// # Errors
    /// [`riseg_core::Error::BadConfig`] for a zero size.
    pub fn boxes(width: usize, height: usize, seed: u64) -> Result<Self, riseg_core::Error> {
        if width == 0 || height == 0 {
            return Err(riseg_core::Error::BadConfig);
        }
        let intrinsics = riseg_core::synth::d415_like_camera(width, height)?;
        // Camera axes in the table frame: x right, y down the image, z forward.
        let tilt = TILT_DEG.to_radians();
        let centre = [0.0, -CAMERA_HEIGHT_M * tilt.tan(), CAMERA_HEIGHT_M];
        let z_axis = [0.0, tilt.sin(), -tilt.cos()];
        let x_axis = [1.0, 0.0, 0.0];
        let y_axis = [0.0, -tilt.cos(), -tilt.sin()];
        let mut rng = Pcg32::new(seed);
        let n = width * height;
        let (mut rgb, mut depth_m, mut truth) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        for v in 0..height {
            for u in 0..width {
                let (a, b) = (
                    (u as f32 - intrinsics.cx) / intrinsics.fx,
                    (v as f32 - intrinsics.cy) / intrinsics.fy,
                );
                let dir: [f32; 3] =
                    core::array::from_fn(|k| a * x_axis[k] + b * y_axis[k] + z_axis[k]);
                // Table plane z = 0.
                let mut hit = (-centre[2] / dir[2], 0u16, 2usize);
                for (k, (b, _)) in BOXES.iter().enumerate() {
                    if let Some((t, axis)) = ray_box(centre, dir, b)
                        && t < hit.0
                    {
                        hit = (t, k as u16 + 1, axis);
                    }
                }
                let (t, label, axis) = hit;
                let base = if label == 0 {
                    TABLE_COLOUR
                } else {
                    BOXES[usize::from(label) - 1].1
                };
                // Tops lit fully, sides facing x or y a little darker.
                let shade = [0.8, 0.7, 1.0][axis];
                let jitter = rng.unit() * 10.0 - 5.0;
                rgb.push(base.map(|c| (f32::from(c) * shade + jitter).clamp(0.0, 255.0) as u8));
                let noise = (rng.unit() + rng.unit() + rng.unit() - 1.5) * 2.0 * NOISE_M;
                depth_m.push(((t + noise) * 1000.0).round() / 1000.0);
                truth.push(label);
            }
        }
        Ok(Self {
            width,
            height,
            intrinsics,
            rgb,
            depth_m,
            truth,
        })
    }
}

/// Entry of the ray `o + t·d` into the box `[x0, x1, y0, y1, height]` standing on z = 0:
/// `(t, axis of the face hit)`, or `None` if it misses.
fn ray_box(o: [f32; 3], d: [f32; 3], b: &[f32; 5]) -> Option<(f32, usize)> {
    let lo = [b[0], b[2], 0.0];
    let hi = [b[1], b[3], b[4]];
    let (mut t_in, mut t_out, mut axis) = (f32::NEG_INFINITY, f32::INFINITY, 0);
    for k in 0..3 {
        if d[k].abs() < 1e-12 {
            if o[k] < lo[k] || o[k] > hi[k] {
                return None;
            }
            continue;
        }
        let (t0, t1) = ((lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]);
        let (near, far) = (t0.min(t1), t0.max(t1));
        if near > t_in {
            (t_in, axis) = (near, k);
        }
        t_out = t_out.min(far);
    }
    (t_in <= t_out && t_in > 0.0).then_some((t_in, axis))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::segment::{ClassicalSegmenter, HEAT_CERTAIN, HEAT_UNCERTAIN, RgbdFrame};

    /// Pixels of label `l` at least `r` pixels (Chebyshev) from any pixel of another label.
    fn interior(t: &SyntheticTabletop, l: u16, r: usize) -> Vec<usize> {
        let (w, h) = (t.width, t.height);
        (0..w * h)
            .filter(|&i| {
                let (x, y) = (i % w, i / w);
                t.truth[i] == l
                    && x >= r
                    && y >= r
                    && x + r < w
                    && y + r < h
                    && (y - r..=y + r).all(|yy| (x - r..=x + r).all(|xx| t.truth[yy * w + xx] == l))
            })
            .collect()
    }

    /// The most common output label on the pixels of true label `l`.
    fn majority(t: &SyntheticTabletop, labels: &[u16], l: u16) -> u16 {
        let mut count = std::collections::BTreeMap::new();
        for (i, _) in t.truth.iter().enumerate().filter(|&(_, &v)| v == l) {
            *count.entry(labels[i]).or_insert(0usize) += 1;
        }
        count
            .into_iter()
            .max_by_key(|&(_, c)| c)
            .map_or(0, |(k, _)| k)
    }

    #[test]
    fn boxes_on_a_table_segment_and_heat_as_documented() {
        let t = SyntheticTabletop::boxes(640, 480, 7).unwrap();
        let (w, h) = (t.width, t.height);
        let frame = RgbdFrame::new(w, h, &t.rgb, &t.depth_m).unwrap();
        let mut seg = ClassicalSegmenter::new(SegmenterParams::default()).unwrap();
        let out = seg.segment_detailed(&frame, &t.intrinsics).unwrap();
        let (labels, heat) = (
            out.segmentation.labels.as_slice(),
            out.segmentation.heatmap.as_slice(),
        );

        // The table is background and below l_l.
        let table: Vec<usize> = interior(&t, 0, 3);
        let table_labelled = table.iter().filter(|&&i| labels[i] != 0).count();
        assert!(
            table_labelled * 200 < table.len(),
            "{table_labelled} table pixels labelled"
        );
        assert!(table.iter().all(|&i| heat[i] < HEAT_UNCERTAIN));
        // The fitted plane is z = 0 of the table frame: 60 cm below the camera.
        assert!((out.plane.offset_m - 0.6).abs() < 0.005, "{:?}", out.plane);

        // Every box is found; the separate boxes A, D have labels of their own.
        let major: Vec<u16> = (1..=6).map(|l| majority(&t, labels, l)).collect();
        assert!(major.iter().all(|&l| l != 0), "{major:?}");
        let (a, b, c, d) = (major[0], major[1], major[2], major[3]);
        assert!(
            a != d && ![b, c].contains(&a) && ![b, c].contains(&d),
            "{major:?}"
        );

        // Box interiors (2 cm from every edge) are certain.
        for l in 1..=6 {
            let core = interior(&t, l, 14);
            let certain = core.iter().filter(|&&i| heat[i] >= HEAT_CERTAIN).count();
            assert!(
                certain * 100 >= core.len() * 95,
                "box {l}: {certain} of {} interior pixels certain",
                core.len()
            );
        }

        // Where B and C touch, the heat is in the uncertain band.
        let contact: Vec<usize> = (0..w * h)
            .filter(|&i| {
                let (x, y) = (i % w, i / w);
                matches!(t.truth[i], 2 | 3)
                    && x >= 2
                    && x + 2 < w
                    && y >= 2
                    && y + 2 < h
                    && (y - 2..=y + 2).any(|yy| {
                        (x - 2..=x + 2).any(|xx| {
                            let o = t.truth[yy * w + xx];
                            matches!(o, 2 | 3) && o != t.truth[i]
                        })
                    })
            })
            .collect();
        assert!(contact.len() > 100);
        let band = contact
            .iter()
            .filter(|&&i| (HEAT_UNCERTAIN..HEAT_CERTAIN).contains(&heat[i]))
            .count();
        assert!(
            band * 100 >= contact.len() * 90,
            "{band} of {} contact pixels in 120..150",
            contact.len()
        );
        println!(
            "B/C: labels {b}/{c}; E/F (flush, equal height): labels {}/{}",
            major[4], major[5]
        );
    }

    #[test]
    fn zero_size_is_an_error() {
        assert!(SyntheticTabletop::boxes(0, 480, 1).is_err());
    }
}
