//! RGB-D rendering by ray casting: one ray per pixel through a parry BVH over the table
//! and the objects, exact instance labels and depth, then D415-like sensor effects.
//!
//! - Rays: pixel `(u, v)` (centre of the pixel, see `riseg_core::camera`) looks along
//!   `R·((u − cx)/fx, (v − cy)/fy, 1)`, so a hit's ray parameter is its depth `z` in the
//!   camera frame (in centimetres, like all engine-side geometry; converted to metres on
//!   output).
//! - Colour: albedo × texture × (ambient + Lambert) under one fixed light in the world
//!   frame, no shadows. The texture is value noise evaluated in the surface's own frame,
//!   so it moves rigidly with the object (optical flow needs texture; brightness constancy
//!   holds up to shading). Then Gaussian noise per channel.
//! - Depth: the exact `z` plus Gaussian noise with σ growing as `z²` (σ = `depth_sigma_m`
//!   at 0.6 m), and readings missing with probability `edge_dropout` on depth edges (a
//!   4-neighbour more than `edge_step_m` nearer or farther, or no surface).
//! - Deterministic: rows run in parallel, but every row draws its noise from its own
//!   generator seeded by `(noise_seed, row)`, so the output does not depend on scheduling.

use parry3d::{
    math::{Pose as GlamPose, Vector as GlamVec},
    partitioning::{Bvh, BvhBuildStrategy},
    query::Ray,
    shape::Shape,
};
use rayon::prelude::*;
use riseg_core::{Intrinsics, rng::Pcg32};

use super::convert::CM_PER_M;
use crate::io::image::{DepthImage, Gray16Image, Image, RgbImage};

/// A surface the renderer can hit: the table or one object.
pub(crate) struct Surface<'a> {
    /// Geometry in centimetres.
    pub shape: &'a dyn Shape,
    /// Translation in centimetres.
    pub world_from_surface_cm: GlamPose,
    /// Instance label written for this surface (0 = table).
    pub label: u16,
    /// Albedo in `[0, 1]` per channel.
    pub albedo: [f32; 3],
    /// Texture seed; the pattern is fixed in the surface's frame.
    pub texture_seed: u32,
    /// Size of the texture's coarse cells, centimetres.
    pub texture_cell_cm: f32,
    /// Relative albedo variation of the texture (0.15 = ±15 %).
    pub texture_contrast: f32,
}

/// Sensor noise and camera geometry of one render.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sensor {
    pub width: usize,
    pub height: usize,
    pub intrinsics: Intrinsics,
    /// Translation in centimetres.
    pub world_from_camera_cm: GlamPose,
    /// Colour noise σ, 8-bit levels.
    pub rgb_sigma: f32,
    /// Depth noise σ at 0.6 m, metres (scales with z²).
    pub depth_sigma_m: f32,
    /// Depth step that makes a depth edge, metres.
    pub edge_step_m: f32,
    /// Probability that a depth-edge pixel has no reading.
    pub edge_dropout: f32,
}

/// A rendered frame: noisy colour and depth, exact labels and depth.
pub(crate) struct Rendered {
    pub rgb: RgbImage,
    pub depth_m: DepthImage,
    pub labels: Gray16Image,
    pub true_depth_m: DepthImage,
}

#[derive(Debug, Clone, Copy, Default)]
struct Hit {
    label: u16,
    z_m: f32,
    rgb: [u8; 3],
}

/// Light direction (towards the light), world frame, from above and slightly aside.
const LIGHT: [f32; 3] = [0.3, -0.25, 0.92];
const AMBIENT: f32 = 0.35;
/// Colour where a ray hits nothing.
const BACKGROUND: [u8; 3] = [20, 20, 24];
/// Farthest surface considered, centimetres along z.
const MAX_DEPTH_CM: f32 = 1000.0;

/// splitmix64 finaliser: a good 64-bit mixing function.
pub(crate) fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn lattice(ix: i32, iy: i32, iz: i32, seed: u32) -> f32 {
    let key = (u64::from(ix as u32) << 32 | u64::from(iy as u32))
        ^ mix64(u64::from(iz as u32) << 32 | u64::from(seed));
    (mix64(key) >> 40) as f32 * (1.0 / 16_777_216.0)
}

/// Smooth value noise in `[0, 1)`, one lattice cell per unit.
fn value_noise(p: GlamVec, seed: u32) -> f32 {
    let f = p.floor();
    let t = p - f;
    let s = t * t * (GlamVec::splat(3.0) - 2.0 * t);
    let (x0, y0, z0) = (f.x as i32, f.y as i32, f.z as i32);
    let mut acc = 0.0;
    for corner in 0..8 {
        let (dx, dy, dz) = (corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
        let w = if dx == 1 { s.x } else { 1.0 - s.x }
            * if dy == 1 { s.y } else { 1.0 - s.y }
            * if dz == 1 { s.z } else { 1.0 - s.z };
        acc += w * lattice(x0 + dx, y0 + dy, z0 + dz, seed);
    }
    acc
}

/// Two octaves of value noise at a point in the surface's frame, in `[0, 1)`.
fn texture(p_cm: GlamVec, seed: u32, cell_cm: f32) -> f32 {
    let coarse = value_noise(p_cm / cell_cm, seed);
    let fine = value_noise(p_cm / (0.4 * cell_cm), seed ^ 0x5bd1_e995);
    0.6 * coarse + 0.4 * fine
}

/// One standard normal sample (Box-Muller, cosine branch).
fn gaussian(rng: &mut Pcg32) -> f32 {
    let u1 = 1.0 - rng.unit(); // (0, 1]
    let u2 = rng.unit();
    (-2.0 * u1.ln()).sqrt() * (core::f32::consts::TAU * u2).cos()
}

fn shade(surface: &Surface<'_>, point: GlamVec, normal: GlamVec) -> [f32; 3] {
    let light = GlamVec::from_array(LIGHT).normalize();
    let lambert = normal.dot(light).max(0.0);
    let local = surface.world_from_surface_cm.inverse_transform_point(point);
    let t = texture(local, surface.texture_seed, surface.texture_cell_cm);
    let k =
        (1.0 + surface.texture_contrast * (2.0 * t - 1.0)) * (AMBIENT + (1.0 - AMBIENT) * lambert);
    surface.albedo.map(|a| a * k)
}

/// Renders the surfaces as the sensor sees them.
pub(crate) fn render(surfaces: &[Surface<'_>], sensor: &Sensor, noise_seed: u64) -> Rendered {
    let (w, h) = (sensor.width, sensor.height);
    let aabbs: Vec<_> = surfaces
        .iter()
        .map(|s| s.shape.compute_aabb(&s.world_from_surface_cm))
        .collect();
    let bvh = Bvh::from_leaves(BvhBuildStrategy::Binned, &aabbs);
    let cam = sensor.world_from_camera_cm;
    let k = sensor.intrinsics;
    let row_seed = |pass: u64, y: usize| mix64(noise_seed ^ mix64((pass << 32) | y as u64));

    let mut hits = vec![Hit::default(); w * h];
    hits.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            let mut rng = Pcg32::new(row_seed(1, y));
            for (x, hit) in row.iter_mut().enumerate() {
                let dir_cam = GlamVec::new((x as f32 - k.cx) / k.fx, (y as f32 - k.cy) / k.fy, 1.0);
                let ray = Ray::new(cam.translation, cam.rotation * dir_cam);
                let best = bvh.find_best(
                    MAX_DEPTH_CM,
                    |node, best_so_far| node.cast_ray(&ray, best_so_far),
                    |leaf, best_so_far| {
                        let s = surfaces.get(leaf as usize)?;
                        s.shape.cast_ray_and_get_normal(
                            &s.world_from_surface_cm,
                            &ray,
                            best_so_far,
                            true,
                        )
                    },
                );
                let colour =
                    match best.and_then(|(leaf, i)| Some((surfaces.get(leaf as usize)?, i))) {
                        Some((surface, inter)) => {
                            let point = ray.point_at(inter.time_of_impact);
                            hit.label = surface.label;
                            hit.z_m = inter.time_of_impact / CM_PER_M;
                            // Seen from outside, the visible side faces the camera.
                            let normal = if inter.normal.dot(ray.dir) > 0.0 {
                                -inter.normal
                            } else {
                                inter.normal
                            };
                            shade(surface, point, normal)
                        }
                        None => BACKGROUND.map(|c| f32::from(c) / 255.0),
                    };
                hit.rgb = colour.map(|c| {
                    let v = c * 255.0 + sensor.rgb_sigma * gaussian(&mut rng);
                    v.round().clamp(0.0, 255.0) as u8
                });
            }
        });

    let z_at = |x: usize, y: usize| hits[y * w + x].z_m;
    let mut depth = vec![0.0_f32; w * h];
    depth
        .par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            let mut rng = Pcg32::new(row_seed(2, y));
            for (x, d) in row.iter_mut().enumerate() {
                let z = z_at(x, y);
                // Draw both samples for every pixel so the stream does not depend on content.
                let noise = gaussian(&mut rng);
                let drop = rng.unit() < sensor.edge_dropout;
                if z <= 0.0 {
                    continue;
                }
                let neighbours = [
                    (x > 0).then(|| z_at(x - 1, y)),
                    (x + 1 < w).then(|| z_at(x + 1, y)),
                    (y > 0).then(|| z_at(x, y - 1)),
                    (y + 1 < h).then(|| z_at(x, y + 1)),
                ];
                let on_edge = neighbours
                    .iter()
                    .flatten()
                    .any(|&n| n <= 0.0 || (n - z).abs() > sensor.edge_step_m);
                if on_edge && drop {
                    continue;
                }
                let sigma = sensor.depth_sigma_m * (z / 0.6) * (z / 0.6);
                *d = (z + sigma * noise).max(0.0);
            }
        });

    // Every buffer holds width·height pixels, so these indices are in range.
    let at = |x: usize, y: usize| y * w + x;
    Rendered {
        rgb: Image::from_fn(sensor.width, sensor.height, |x, y| hits[at(x, y)].rgb),
        labels: Image::from_fn(sensor.width, sensor.height, |x, y| hits[at(x, y)].label),
        true_depth_m: Image::from_fn(sensor.width, sensor.height, |x, y| hits[at(x, y)].z_m),
        depth_m: Image::from_fn(sensor.width, sensor.height, |x, y| depth[at(x, y)]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_noise_is_continuous_and_in_range() {
        let mut prev = value_noise(GlamVec::new(0.0, 0.3, 0.7), 9);
        for i in 1..1000 {
            let p = GlamVec::new(i as f32 * 0.01, 0.3, 0.7);
            let v = value_noise(p, 9);
            assert!((0.0..1.0).contains(&v));
            assert!((v - prev).abs() < 0.1, "jump at {p:?}");
            prev = v;
        }
    }

    #[test]
    fn gaussian_has_unit_variance() {
        let mut rng = Pcg32::new(3);
        let n = 20_000;
        let samples: Vec<f32> = (0..n).map(|_| gaussian(&mut rng)).collect();
        let mean = samples.iter().sum::<f32>() / n as f32;
        let var = samples.iter().map(|s| (s - mean) * (s - mean)).sum::<f32>() / n as f32;
        assert!(
            mean.abs() < 0.03 && (var - 1.0).abs() < 0.05,
            "{mean} {var}"
        );
    }
}
