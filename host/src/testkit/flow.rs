//! Image pairs with exact ground-truth flow, generated procedurally (nothing downloaded):
//! used by the flow tests, the `flow_pairs` example and `bench/flow.sh`.
//!
//! A [`FlowScene`] is a static or moving textured background plus rigid textured objects
//! drawn on top of it in order. Every layer's texture is a continuous function of the
//! layer's own coordinates (value-noise octaves with a roughly 1/f spectrum plus
//! sharp-edged discs and squares), so the second image shows exactly the first image's
//! content moved rigidly: a layer with centre `c`, translation `t` and rotation `θ` maps
//! the point `p` of the first image to `c + t + R(θ)·(p − c)` in the second. The images are
//! rendered with 2x2 supersampling and rounded to 8-bit RGB; the flow is the exact motion
//! of each first-image pixel centre (of the topmost layer there).
//!
//! [`FlowPair::interior`] marks pixels whose flow an estimator can be expected to get
//! right: at least [`FlowScene::interior_margin_px`] pixels away from any layer boundary and
//! the image border in the first image, and likewise around the target position in the
//! second image, on the same layer (so not occluded).

use riseg_core::ImageView;

use crate::flow::luma;
use crate::io::image::{FlowImage, Image, RgbImage};
use crate::par::*;
use riseg_core::rng::Pcg32;

/// The outline of a layer, in the layer's own coordinates (origin at its centre, before
/// its angle is applied).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Covers the whole plane (a background).
    Everywhere,
    /// An axis-aligned ellipse.
    Ellipse {
        /// Semi-axes along local x and y, pixels.
        semi_axes_px: [f32; 2],
    },
    /// An axis-aligned rectangle with rounded corners.
    RoundedRect {
        /// Half the width and height, pixels.
        half_extents_px: [f32; 2],
        /// Corner radius, pixels (at most the smaller half extent).
        corner_px: f32,
    },
}

impl Shape {
    fn contains(&self, lx: f32, ly: f32) -> bool {
        match *self {
            Self::Everywhere => true,
            Self::Ellipse {
                semi_axes_px: [a, b],
            } => (lx / a).powi(2) + (ly / b).powi(2) <= 1.0,
            Self::RoundedRect {
                half_extents_px: [hx, hy],
                corner_px,
            } => {
                let r = corner_px.min(hx).min(hy).max(0.0);
                let qx = lx.abs() - (hx - r);
                let qy = ly.abs() - (hy - r);
                qx.max(0.0).hypot(qy.max(0.0)) + qx.max(qy).min(0.0) <= r
            }
        }
    }
}

/// One rigid textured layer and its motion between the two images.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Layer {
    /// Seed of the layer's texture.
    pub texture_seed: u64,
    /// Outline.
    pub shape: Shape,
    /// Centre in the first image, pixels (also the centre of rotation).
    pub centre_px: [f32; 2],
    /// Orientation of the shape and texture in the first image, radians.
    pub angle_rad: f32,
    /// Translation of the centre from the first to the second image, pixels.
    pub translation_px: [f32; 2],
    /// Rotation about the centre from the first to the second image, radians (positive
    /// turns +x towards +y, i.e. clockwise on screen).
    pub rotation_rad: f32,
}

impl Layer {
    /// A static layer.
    #[must_use]
    pub const fn still(texture_seed: u64, shape: Shape, centre_px: [f32; 2]) -> Self {
        Self {
            texture_seed,
            shape,
            centre_px,
            angle_rad: 0.0,
            translation_px: [0.0, 0.0],
            rotation_rad: 0.0,
        }
    }

    /// Layer coordinates of image point `(x, y)` in image `second` (false: first).
    fn local(&self, x: f32, y: f32, second: bool) -> (f32, f32) {
        let (cx, cy, a) = if second {
            (
                self.centre_px[0] + self.translation_px[0],
                self.centre_px[1] + self.translation_px[1],
                self.angle_rad + self.rotation_rad,
            )
        } else {
            (self.centre_px[0], self.centre_px[1], self.angle_rad)
        };
        let (s, c) = a.sin_cos();
        let (dx, dy) = (x - cx, y - cy);
        (c * dx + s * dy, -s * dx + c * dy)
    }

    /// Exact motion of first-image point `(x, y)`, pixels (computed in `f64`).
    fn motion(&self, x: f64, y: f64) -> [f32; 2] {
        let (cx, cy) = (f64::from(self.centre_px[0]), f64::from(self.centre_px[1]));
        let (s, c) = f64::from(self.rotation_rad).sin_cos();
        let (dx, dy) = (x - cx, y - cy);
        let nx = cx + f64::from(self.translation_px[0]) + c * dx - s * dy;
        let ny = cy + f64::from(self.translation_px[1]) + s * dx + c * dy;
        [(nx - x) as f32, (ny - y) as f32]
    }
}

/// A background and objects on top of it (later objects cover earlier ones).
#[derive(Debug, Clone, PartialEq)]
pub struct FlowScene {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// The layer behind everything; its shape should be [`Shape::Everywhere`].
    pub background: Layer,
    /// Rigid objects, drawn in order.
    pub objects: Vec<Layer>,
    /// Distance from boundaries, borders and occlusions for [`FlowPair::interior`], pixels.
    pub interior_margin_px: usize,
}

/// Two 8-bit RGB images and the exact flow from the first to the second.
#[derive(Debug, Clone, PartialEq)]
pub struct FlowPair {
    /// First image.
    pub first: RgbImage,
    /// Second image, the first's size.
    pub second: RgbImage,
    /// Exact flow at every first-image pixel centre.
    pub flow: FlowImage,
    /// Layer of every first-image pixel: 0 background, `k` the `k`-th object (1-based).
    pub labels: Vec<u16>,
    /// Pixels whose flow is well defined for an estimator (see the module docs).
    pub interior: Vec<bool>,
}

impl FlowPair {
    /// The first image as a view.
    #[must_use]
    pub fn first_view(&self) -> ImageView<'_, [u8; 3]> {
        self.first.view()
    }

    /// The second image as a view.
    #[must_use]
    pub fn second_view(&self) -> ImageView<'_, [u8; 3]> {
        self.second.view()
    }

    /// The first image's luma.
    #[must_use]
    pub fn first_gray(&self) -> Image<f32> {
        luma(self.first_view())
    }

    /// The second image's luma.
    #[must_use]
    pub fn second_gray(&self) -> Image<f32> {
        luma(self.second_view())
    }

    /// Pixels on objects (label > 0), moving or not.
    #[must_use]
    pub fn object_mask(&self) -> Vec<bool> {
        self.labels.iter().map(|&l| l > 0).collect()
    }
}

/// The whole image translated by `shift_px` (a textured plane; no objects).
#[must_use]
pub fn translated(width: usize, height: usize, seed: u64, shift_px: [f32; 2]) -> FlowPair {
    let centre = [width as f32 / 2.0, height as f32 / 2.0];
    FlowScene {
        width,
        height,
        background: Layer {
            translation_px: shift_px,
            ..Layer::still(seed, Shape::Everywhere, centre)
        },
        objects: Vec::new(),
        interior_margin_px: 8,
    }
    .render()
}

/// The whole image rotated by `angle_rad` about the image centre (no objects).
#[must_use]
pub fn rotated(width: usize, height: usize, seed: u64, angle_rad: f32) -> FlowPair {
    let centre = [(width as f32 - 1.0) / 2.0, (height as f32 - 1.0) / 2.0];
    FlowScene {
        width,
        height,
        background: Layer {
            rotation_rad: angle_rad,
            ..Layer::still(seed, Shape::Everywhere, centre)
        },
        objects: Vec::new(),
        interior_margin_px: 8,
    }
    .render()
}

impl FlowScene {
    /// A static textured background with 4-6 touching or overlapping objects (ellipses and
    /// rounded rectangles, 70-170 px across at 640x480, scaled with the width) near the
    /// centre; the first stays put, the others move up to 16 px and turn up to 6 degrees,
    /// like objects after a small push.
    #[must_use]
    pub fn random_objects(width: usize, height: usize, seed: u64) -> Self {
        let mut rng = Pcg32::new(seed);
        let mut uniform = |lo: f32, hi: f32| lo + (hi - lo) * rng.unit();
        let scale = width as f32 / 640.0;
        let (w, h) = (width as f32, height as f32);
        let mut layers = Vec::new();
        let n = 4 + (uniform(0.0, 3.0) as usize).min(2);
        for k in 0..n {
            let shape = if uniform(0.0, 1.0) < 0.5 {
                Shape::Ellipse {
                    semi_axes_px: [uniform(35.0, 85.0) * scale, uniform(35.0, 85.0) * scale],
                }
            } else {
                Shape::RoundedRect {
                    half_extents_px: [uniform(35.0, 85.0) * scale, uniform(35.0, 85.0) * scale],
                    corner_px: uniform(4.0, 20.0) * scale,
                }
            };
            let centre_px = [w * uniform(0.25, 0.75), h * uniform(0.25, 0.75)];
            let angle_rad = uniform(-3.2, 3.2);
            let (translation_px, rotation_rad) = if k == 0 {
                ([0.0, 0.0], 0.0)
            } else {
                let dir = uniform(-3.2, 3.2);
                let len = uniform(2.0, 16.0) * scale;
                (
                    [len * dir.cos(), len * dir.sin()],
                    uniform(-6.0, 6.0).to_radians(),
                )
            };
            let texture_seed = u64::from(rng_bits(&mut uniform));
            layers.push(Layer {
                texture_seed,
                shape,
                centre_px,
                angle_rad,
                translation_px,
                rotation_rad,
            });
        }
        let background_seed = u64::from(rng_bits(&mut uniform));
        Self {
            width,
            height,
            background: Layer::still(background_seed, Shape::Everywhere, [w / 2.0, h / 2.0]),
            objects: layers,
            interior_margin_px: 4,
        }
    }

    /// Topmost layer (0 background, `k` object `k - 1`) at `(x, y)` of image `second`.
    fn layer_at(&self, x: f32, y: f32, second: bool) -> usize {
        for (k, o) in self.objects.iter().enumerate().rev() {
            let (lx, ly) = o.local(x, y, second);
            if o.shape.contains(lx, ly) {
                return k + 1;
            }
        }
        0
    }

    fn layer(&self, k: usize) -> &Layer {
        if k == 0 {
            &self.background
        } else {
            &self.objects[k - 1]
        }
    }

    fn render_image(&self, textures: &[Texture], second: bool) -> RgbImage {
        let w = self.width;
        let mut out = vec![[0u8; 3]; w * self.height];
        if w > 0 {
            self.render_rows(textures, second, &mut out);
        }
        Image::from_vec(w, self.height, out).expect("one pixel per position")
    }

    fn render_rows(&self, textures: &[Texture], second: bool, out: &mut [[u8; 3]]) {
        let w = self.width;
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, px) in row.iter_mut().enumerate() {
                let mut acc = [0.0f32; 3];
                for (sx, sy) in [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)] {
                    let (fx, fy) = (x as f32 + sx, y as f32 + sy);
                    let k = self.layer_at(fx, fy, second);
                    let (lx, ly) = self.layer(k).local(fx, fy, second);
                    let c = textures[k].colour(lx, ly);
                    for (a, v) in acc.iter_mut().zip(c) {
                        *a += v;
                    }
                }
                for (p, a) in px.iter_mut().zip(acc) {
                    *p = (a * 0.25).round().clamp(0.0, 255.0) as u8;
                }
            }
        });
    }

    fn labels(&self, second: bool) -> Vec<u16> {
        let w = self.width;
        let mut out = vec![0u16; w * self.height];
        if w == 0 {
            return out;
        }
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, l) in row.iter_mut().enumerate() {
                *l = u16::try_from(self.layer_at(x as f32, y as f32, second)).unwrap_or(u16::MAX);
            }
        });
        out
    }

    /// Renders both images, the exact flow, the labels and the interior mask.
    #[must_use]
    pub fn render(&self) -> FlowPair {
        let (w, h) = (self.width, self.height);
        let textures: Vec<Texture> = core::iter::once(&self.background)
            .chain(&self.objects)
            .map(|l| Texture::new(l.texture_seed))
            .collect();
        let first = self.render_image(&textures, false);
        let second = self.render_image(&textures, true);
        let labels = self.labels(false);
        let labels1 = self.labels(true);
        let flow: Vec<[f32; 2]> = labels
            .iter()
            .enumerate()
            .map(|(i, &l)| {
                self.layer(usize::from(l))
                    .motion((i % w) as f64, (i / w) as f64)
            })
            .collect();
        let m = self.interior_margin_px;
        let near0 = NearEdge::new(&labels, w, h, m);
        let near1 = NearEdge::new(&labels1, w, h, m);
        let interior = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let [dx, dy] = flow[i];
                let (tx, ty) = ((x as f32 + dx).round(), (y as f32 + dy).round());
                let inside = |vx: f32, vy: f32| {
                    vx >= m as f32
                        && vy >= m as f32
                        && vx + (m as f32) < w as f32
                        && vy + (m as f32) < h as f32
                };
                if !inside(x as f32, y as f32) || !inside(tx, ty) {
                    return false;
                }
                let (tx, ty) = (tx as usize, ty as usize);
                !near0.at(x, y) && !near1.at(tx, ty) && labels1[ty * w + tx] == labels[i]
            })
            .collect();
        FlowPair {
            first,
            second,
            flow: Image::from_vec(w, h, flow).expect("one vector per pixel"),
            labels,
            interior,
        }
    }
}

/// `(2m + 1)²` windows that contain a label boundary, answered from a summed-area table.
struct NearEdge {
    w: usize,
    h: usize,
    m: usize,
    /// `(w + 1) x (h + 1)` summed-area table of boundary pixels.
    sat: Vec<u32>,
}

impl NearEdge {
    fn new(labels: &[u16], w: usize, h: usize, m: usize) -> Self {
        let mut sat = vec![0u32; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut run = 0u32;
            for x in 0..w {
                let l = labels[y * w + x];
                let edge = (x + 1 < w && labels[y * w + x + 1] != l)
                    || (x > 0 && labels[y * w + x - 1] != l)
                    || (y + 1 < h && labels[(y + 1) * w + x] != l)
                    || (y > 0 && labels[(y - 1) * w + x] != l);
                run += u32::from(edge);
                sat[(y + 1) * (w + 1) + x + 1] = sat[y * (w + 1) + x + 1] + run;
            }
        }
        Self { w, h, m, sat }
    }

    /// Whether the window around `(x, y)` holds a boundary pixel.
    fn at(&self, x: usize, y: usize) -> bool {
        let (x0, y0) = (x.saturating_sub(self.m), y.saturating_sub(self.m));
        let (x1, y1) = ((x + self.m + 1).min(self.w), (y + self.m + 1).min(self.h));
        let s = |xx: usize, yy: usize| self.sat[yy * (self.w + 1) + xx];
        s(x1, y1) + s(x0, y0) - s(x0, y1) - s(x1, y0) > 0
    }
}

fn rng_bits(uniform: &mut impl FnMut(f32, f32) -> f32) -> u32 {
    (uniform(0.0, 1.0) * 16_777_216.0) as u32
}

/// SplitMix64 finaliser: a well-mixed hash of one word.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn hash3(a: i64, b: i64, c: u64) -> u64 {
    mix(a as u64 ^ mix(b as u64 ^ mix(c)))
}

/// A hash as a float in `[0, 1)`.
fn unit(h: u64) -> f32 {
    (h >> 40) as f32 * (1.0 / 16_777_216.0)
}

/// Value-noise octaves (period in pixels, weight), roughly a 1/f spectrum.
const OCTAVES: [(f32, f32); 6] = [
    (96.0, 0.30),
    (48.0, 0.24),
    (24.0, 0.18),
    (12.0, 0.13),
    (6.0, 0.09),
    (3.0, 0.06),
];
/// Side of the cells that may hold one sharp-edged disc or square, pixels.
const CELL_PX: f32 = 24.0;

/// A layer's continuous texture.
#[derive(Debug, Clone)]
struct Texture {
    seed: u64,
    tint: [f32; 3],
}

impl Texture {
    fn new(seed: u64) -> Self {
        let t = |k: u64| 0.45 + 0.55 * unit(hash3(0, 0, seed ^ mix(k)));
        Self {
            seed,
            tint: [t(1), t(2), t(3)],
        }
    }

    /// Smoothly interpolated lattice noise in `[0, 1)`.
    fn noise(&self, x: f32, y: f32, octave: u64) -> f32 {
        let (fx, fy) = (x.floor(), y.floor());
        let (tx, ty) = (x - fx, y - fy);
        let (sx, sy) = (tx * tx * (3.0 - 2.0 * tx), ty * ty * (3.0 - 2.0 * ty));
        let (ix, iy) = (fx as i64, fy as i64);
        let s = self.seed ^ mix(octave + 17);
        let v = |a: i64, b: i64| unit(hash3(a, b, s));
        let top = v(ix, iy) + sx * (v(ix + 1, iy) - v(ix, iy));
        let bottom = v(ix, iy + 1) + sx * (v(ix + 1, iy + 1) - v(ix, iy + 1));
        top + sy * (bottom - top)
    }

    /// RGB 0-255 at layer coordinates `(x, y)`.
    fn colour(&self, x: f32, y: f32) -> [f32; 3] {
        let mut lum = 0.0;
        for (o, &(period, weight)) in OCTAVES.iter().enumerate() {
            lum += weight * self.noise(x / period, y / period, o as u64);
        }
        // Spread the (roughly 0.5 +- 0.2) sum to a wider contrast.
        let lum = (0.5 + 2.0 * (lum - 0.5)).clamp(0.0, 1.0);
        let mut rgb = [0.0; 3];
        for (c, t) in rgb.iter_mut().zip(self.tint) {
            *c = 255.0 * t * (0.15 + 0.85 * lum);
        }
        let (cx, cy) = ((x / CELL_PX).floor() as i64, (y / CELL_PX).floor() as i64);
        let s = self.seed ^ mix(99);
        for j in cy - 1..=cy + 1 {
            for i in cx - 1..=cx + 1 {
                let hsh = hash3(i, j, s);
                if unit(hsh) >= 0.5 {
                    continue;
                }
                let (h1, h2, h3) = (mix(hsh), mix(hsh ^ 1), mix(hsh ^ 2));
                let ox = (i as f32 + 0.2 + 0.6 * unit(h1)) * CELL_PX;
                let oy = (j as f32 + 0.2 + 0.6 * unit(h2)) * CELL_PX;
                let r = 3.0 + 9.0 * unit(h3);
                let (dx, dy) = (x - ox, y - oy);
                let inside = if h3 & 1 == 0 {
                    dx * dx + dy * dy <= r * r
                } else {
                    dx.abs().max(dy.abs()) <= r
                };
                if inside {
                    for (k, c) in rgb.iter_mut().enumerate() {
                        *c = 255.0 * unit(mix(hsh ^ (k as u64 + 7)));
                    }
                }
            }
        }
        rgb
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_contain_their_centre_and_not_far_points() {
        let e = Shape::Ellipse {
            semi_axes_px: [10.0, 5.0],
        };
        assert!(e.contains(0.0, 0.0) && e.contains(9.9, 0.0) && !e.contains(0.0, 5.1));
        let r = Shape::RoundedRect {
            half_extents_px: [10.0, 5.0],
            corner_px: 2.0,
        };
        assert!(r.contains(9.9, 0.0) && r.contains(0.0, 4.9) && !r.contains(9.9, 4.9));
        assert!(!r.contains(10.1, 0.0));
    }

    #[test]
    fn translation_moves_content_by_the_flow() {
        // A pure integer shift: the second image is the first one moved by (3, -2).
        let p = translated(64, 48, 3, [3.0, -2.0]);
        assert!(p.flow.as_slice().iter().all(|v| *v == [3.0, -2.0]));
        let (w, mut same, mut n) = (64, 0, 0);
        for y in 2..46 {
            for x in 0..61 {
                let a = p.first.as_slice()[y * w + x];
                let b = p.second.as_slice()[(y - 2) * w + x + 3];
                same += usize::from(a == b);
                n += 1;
            }
        }
        assert_eq!(same, n);
        assert!(p.first != p.second);
    }

    #[test]
    fn rigid_objects_have_consistent_flow_and_masks() {
        let scene = FlowScene::random_objects(160, 120, 5);
        assert!((4..=6).contains(&scene.objects.len()));
        let p = scene.render();
        assert_eq!(p.labels.len(), 160 * 120);
        let objects = p.object_mask();
        assert!(objects.iter().filter(|&&o| o).count() > 160 * 120 / 10);
        // Background pixels do not move; the first object does not move either.
        for (i, &l) in p.labels.iter().enumerate() {
            if l <= 1 {
                assert_eq!(p.flow.as_slice()[i], [0.0, 0.0]);
            }
        }
        // Interior pixels are a strict, non-empty subset, away from the border.
        let n_int = p.interior.iter().filter(|&&v| v).count();
        assert!(n_int > 0 && n_int < p.interior.len());
        assert!(!p.interior[0]);
        // Same seed, same pair; different seed, different pair.
        assert_eq!(FlowScene::random_objects(160, 120, 5).render(), p);
        assert_ne!(FlowScene::random_objects(160, 120, 6), scene);
    }
}
