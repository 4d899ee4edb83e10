//! Seeded object sets and their placement: 4-6 objects of similar size, drawn from a
//! two-shape family, in similar colours, placed close together on the table so that most
//! of them touch a neighbour.
//!
//! Placement is geometric (parry distance queries), before any physics: each new object is
//! slid along a random horizontal ray out of a random already-placed "anchor" until it
//! is `gap` away from the anchor (bisection on the distance, which is monotone along the
//! ray for convex shapes), and kept only if it is at least that far from every other
//! object and stays near the table centre. Of several such candidates the one nearest the
//! centroid of the objects placed so far wins, so the objects form a compact group rather
//! than a chain. Most gaps are 0.5 mm (touching once the physics settles), one in five is
//! 4-12 mm (close but apart).
//!
//! Public sizes ([`ObjectShape`]) are in metres; everything inside, like the rest of the
//! simulator's engine side, is in centimetres (see `convert`).

use parry3d::{
    math::{Pose as GlamPose, Rotation as GlamRot, Vector as GlamVec},
    query,
    shape::{Shape, SharedShape},
};
use riseg_core::rng::Pcg32;

use super::convert::CM_PER_M;

/// One object's geometry, in its body frame (z up when resting).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ObjectShape {
    /// A box with the given half extents (x, y, z), resting on a face.
    Box {
        /// Half extents, metres.
        half_extents_m: [f32; 3],
    },
    /// An upright cylinder.
    Cylinder {
        /// Radius, metres.
        radius_m: f32,
        /// Half height, metres.
        half_height_m: f32,
    },
    /// A capsule lying on its side (axis horizontal).
    Capsule {
        /// Radius, metres.
        radius_m: f32,
        /// Half length of the axis segment (without the caps), metres.
        half_segment_m: f32,
    },
    /// A sphere.
    Sphere {
        /// Radius, metres.
        radius_m: f32,
    },
    /// A box with rounded edges, resting on a face.
    RoundedBox {
        /// Half extents including the rounding, metres.
        half_extents_m: [f32; 3],
        /// Edge radius, metres.
        border_radius_m: f32,
    },
}

impl ObjectShape {
    /// The parry shape in centimetres, in the orientation parry defines it (cylinders and
    /// capsules along their local y axis; [`ObjectShape::rest_rotation`] turns them to rest).
    pub(crate) fn to_sim_shape(self) -> SharedShape {
        let cm = |m: f32| m * CM_PER_M;
        match self {
            Self::Box { half_extents_m: h } => SharedShape::cuboid(cm(h[0]), cm(h[1]), cm(h[2])),
            Self::Cylinder {
                radius_m,
                half_height_m,
            } => SharedShape::cylinder(cm(half_height_m), cm(radius_m)),
            Self::Capsule {
                radius_m,
                half_segment_m,
            } => SharedShape::capsule_y(cm(half_segment_m), cm(radius_m)),
            Self::Sphere { radius_m } => SharedShape::ball(cm(radius_m)),
            Self::RoundedBox {
                half_extents_m: h,
                border_radius_m: r,
            } => SharedShape::round_cuboid(cm(h[0] - r), cm(h[1] - r), cm(h[2] - r), cm(r)),
        }
    }

    /// Rotation from the parry shape's frame to a resting pose with heading `yaw_rad`.
    fn rest_rotation(self, yaw_rad: f32) -> GlamRot {
        let yaw = GlamRot::from_rotation_z(yaw_rad);
        match self {
            // parry's cylinder axis is y; stand it on the table (y → z).
            Self::Cylinder { .. } => yaw * GlamRot::from_rotation_x(core::f32::consts::FRAC_PI_2),
            // The capsule axis (y) is already horizontal: it lies on its side.
            _ => yaw,
        }
    }
}

/// The five kinds of the shape family.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Box,
    Cylinder,
    Capsule,
    Sphere,
    RoundedBox,
}

const KINDS: [Kind; 5] = [
    Kind::Box,
    Kind::Cylinder,
    Kind::Capsule,
    Kind::Sphere,
    Kind::RoundedBox,
];

fn uniform(rng: &mut Pcg32, lo: f32, hi: f32) -> f32 {
    lo + (hi - lo) * rng.unit()
}

fn random_shape(rng: &mut Pcg32, kind: Kind, min_m: f32, max_m: f32) -> ObjectShape {
    let mut size = |lo: f32, hi: f32| 0.5 * uniform(rng, lo, hi);
    match kind {
        Kind::Box => ObjectShape::Box {
            half_extents_m: [size(min_m, max_m), size(min_m, max_m), size(min_m, max_m)],
        },
        Kind::Cylinder => ObjectShape::Cylinder {
            radius_m: size(min_m, 0.85 * max_m),
            half_height_m: size(min_m, max_m),
        },
        Kind::Capsule => {
            let radius_m = size(min_m, 0.6 * max_m);
            let length_m = 2.0
                * size(
                    (2.0 * radius_m + 0.01).max(min_m),
                    max_m.max(2.0 * radius_m + 0.01),
                );
            ObjectShape::Capsule {
                radius_m,
                half_segment_m: 0.5 * length_m - radius_m,
            }
        }
        Kind::Sphere => ObjectShape::Sphere {
            radius_m: size(min_m, 0.85 * max_m),
        },
        Kind::RoundedBox => {
            let h = [size(min_m, max_m), size(min_m, max_m), size(min_m, max_m)];
            let border_radius_m = (0.4 * h[0].min(h[1]).min(h[2])).min(0.006);
            ObjectShape::RoundedBox {
                half_extents_m: h,
                border_radius_m,
            }
        }
    }
}

/// An object placed at rest on the table, before physics.
#[derive(Debug, Clone)]
pub(crate) struct Placed {
    pub shape: ObjectShape,
    /// The shape in centimetres.
    pub collider: SharedShape,
    /// Translation in centimetres.
    pub world_from_object_cm: GlamPose,
    /// Linear sRGB-ish albedo in `[0, 1]`.
    pub albedo: [f32; 3],
}

/// What to draw and where objects may go.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LayoutSpec {
    pub min_objects: usize,
    pub max_objects: usize,
    pub min_size_m: f32,
    pub max_size_m: f32,
    /// Largest distance of an object's centre from the table centre, centimetres.
    pub max_radius_cm: f32,
}

fn shape_distance(a: &SharedShape, pa: &GlamPose, b: &SharedShape, pb: &GlamPose) -> f32 {
    // Every shape of the family is convex and supported; treat "unsupported" as touching
    // so such a placement is never accepted.
    query::distance(pa, a.as_ref(), pb, b.as_ref()).map_or(0.0, |d| d.distance)
}

/// Height of the body origin above the table when the shape rests on it with `rotation`,
/// centimetres.
fn rest_height(shape: &dyn Shape, rotation: GlamRot) -> f32 {
    -shape
        .compute_aabb(&GlamPose::from_rotation(rotation))
        .mins
        .z
}

fn hsv_to_rgb(h: f32, s: f32, v: f32) -> [f32; 3] {
    let h6 = (h.rem_euclid(1.0)) * 6.0;
    let c = v * s;
    let x = c * (1.0 - ((h6 % 2.0) - 1.0).abs());
    let (r, g, b) = match h6 as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [r + m, g + m, b + m]
}

/// Draws and places a set of objects; `None` if the placement failed (the caller retries
/// with a different seed).
pub(crate) fn random_layout(rng: &mut Pcg32, spec: &LayoutSpec) -> Option<Vec<Placed>> {
    let span = (spec.max_objects - spec.min_objects + 1) as u32;
    let count = spec.min_objects + rng.below(span) as usize;
    // A two-kind family per scene, e.g. boxes and rounded boxes.
    let first = KINDS[rng.below(5) as usize];
    let second = KINDS[(first as usize + 1 + rng.below(4) as usize) % 5];
    let base_hue = rng.unit();

    let mut placed: Vec<Placed> = Vec::with_capacity(count);
    for k in 0..count {
        let kind = if rng.below(2) == 0 { first } else { second };
        let shape = random_shape(rng, kind, spec.min_size_m, spec.max_size_m);
        let collider = shape.to_sim_shape();
        let rotation = shape.rest_rotation(uniform(rng, 0.0, core::f32::consts::TAU));
        // 0.5 mm above the table: the physics lets it settle.
        let z_cm = rest_height(collider.as_ref(), rotation) + 0.05;
        let albedo = hsv_to_rgb(
            base_hue + uniform(rng, -0.03, 0.03),
            uniform(rng, 0.45, 0.65),
            uniform(rng, 0.6, 0.8),
        );
        let pose = if k == 0 {
            let offset = GlamVec::new(uniform(rng, -1.0, 1.0), uniform(rng, -1.0, 1.0), z_cm);
            Some(GlamPose::from_parts(offset, rotation))
        } else {
            let centroid = placed.iter().fold(GlamVec::ZERO, |acc, p| {
                acc + p.world_from_object_cm.translation
            }) / placed.len() as f32;
            let mut best: Option<(f32, GlamPose)> = None;
            let mut found = 0;
            for _ in 0..64 {
                let Some(pose) = slide_next_to(rng, &placed, &collider, rotation, z_cm, spec)
                else {
                    continue;
                };
                let d = (pose.translation - centroid).truncate().length();
                if best.is_none_or(|(bd, _)| d < bd) {
                    best = Some((d, pose));
                }
                found += 1;
                if found == 6 {
                    break;
                }
            }
            best.map(|(_, pose)| pose)
        };
        placed.push(Placed {
            shape,
            collider,
            world_from_object_cm: pose?,
            albedo,
        });
    }
    Some(placed)
}

/// One placement attempt: slide out of a random anchor until `gap` away from it.
fn slide_next_to(
    rng: &mut Pcg32,
    placed: &[Placed],
    collider: &SharedShape,
    rotation: GlamRot,
    z_cm: f32,
    spec: &LayoutSpec,
) -> Option<GlamPose> {
    let anchor = placed.get(rng.below(placed.len() as u32) as usize)?;
    let angle = uniform(rng, 0.0, core::f32::consts::TAU);
    let gap_cm = if rng.below(5) == 0 {
        uniform(rng, 0.4, 1.2)
    } else {
        0.05
    };
    let dir = GlamVec::new(angle.cos(), angle.sin(), 0.0);
    let a = anchor.world_from_object_cm.translation;
    let origin = GlamVec::new(a.x, a.y, z_cm);
    let pose_at = |s_cm: f32| GlamPose::from_parts(origin + dir * s_cm, rotation);
    let dist_at = |s_cm: f32| {
        shape_distance(
            collider,
            &pose_at(s_cm),
            &anchor.collider,
            &anchor.world_from_object_cm,
        )
    };
    let (mut lo, mut hi) = (0.0_f32, 25.0_f32);
    if dist_at(hi) < gap_cm {
        return None;
    }
    for _ in 0..30 {
        let mid = 0.5 * (lo + hi);
        if dist_at(mid) < gap_cm {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let pose = pose_at(hi);
    let clear = placed.iter().all(|p| {
        shape_distance(collider, &pose, &p.collider, &p.world_from_object_cm)
            >= 0.9 * gap_cm.min(0.4)
    });
    (clear && pose.translation.truncate().length() <= spec.max_radius_cm).then_some(pose)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_have_the_requested_count_and_no_overlaps() {
        let spec = LayoutSpec {
            min_objects: 4,
            max_objects: 6,
            min_size_m: 0.03,
            max_size_m: 0.07,
            max_radius_cm: 12.0,
        };
        for seed in 0..20 {
            let mut rng = Pcg32::new(seed);
            let Some(objects) = random_layout(&mut rng, &spec) else {
                continue;
            };
            assert!((4..=6).contains(&objects.len()));
            let mut touching = 0;
            for (i, a) in objects.iter().enumerate() {
                let aabb = a.collider.compute_aabb(&a.world_from_object_cm);
                assert!(aabb.mins.z > 0.0 && aabb.mins.z < 0.1, "rests on the table");
                let ext = aabb.maxs - aabb.mins;
                assert!(
                    ext.x.max(ext.y).max(ext.z) <= 7.0 * 1.75,
                    "similar size: {ext:?}"
                );
                let nearest = objects
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| *j != i)
                    .map(|(_, b)| {
                        shape_distance(
                            &a.collider,
                            &a.world_from_object_cm,
                            &b.collider,
                            &b.world_from_object_cm,
                        )
                    })
                    .fold(f32::INFINITY, f32::min);
                assert!(nearest > 0.0, "seed {seed}: objects overlap");
                if nearest < 0.1 {
                    touching += 1;
                }
            }
            assert!(touching >= 2, "seed {seed}: at least one touching pair");
        }
    }
}
