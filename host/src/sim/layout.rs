//! Seeded object sets and their placement on the table, in three scene families
//! ([`Layout`], DESIGN.md §4).
//!
//! **Loose** (the original family): 4-6 objects of similar size, drawn from a two-shape
//! family, in similar colours, placed close together so that most of them touch a
//! neighbour. Placement is geometric (parry distance queries), before any physics: each new
//! object is slid along a random horizontal ray out of a random already-placed "anchor"
//! until it is `gap` away from the anchor (bisection on the distance, which is monotone
//! along the ray for convex shapes), and kept only if it is at least that far from every
//! other object and stays near the table centre. Of several such candidates the one
//! nearest the centroid of the objects placed so far wins, so the objects form a compact
//! group rather than a chain. Most gaps are 0.5 mm (touching once the physics settles), one
//! in five is 4-12 mm (close but apart).
//!
//! **Packed**: look-alike objects flush in a grid, the regime where a static segmenter
//! merges them. One size, one height, one albedo (up to a barely visible variation) and one
//! texture pattern for the whole pack: 4-6 boxes with a 4-7 cm footprint in rows of at most
//! [`PACK_MAX_COLS`] (2x2, 1x4, 1x5, 2x3, 2x2+1, ...), or, in one scene in
//! [`CAN_SCENES_IN`], upright cylinders ("cans") of 4-7 cm diameter in square rows or
//! hex-packed. Neighbours are [`PACK_GAP_CM`] apart (sub-millimetre, as real packed boxes;
//! below a D415's depth resolution), the whole pack has a random yaw and stands near the
//! table centre.
//!
//! **Mixed**: a pack of 2-4 look-alike boxes, then 1-3 loose objects slid against it or
//! its neighbours as in `Loose` (their colours near the pack's).
//!
//! Public sizes ([`ObjectShape`]) are in metres; everything inside, like the rest of the
//! simulator's engine side, is in centimetres (see `convert`).

use core::fmt;

use parry3d::{
    math::{Pose as GlamPose, Rotation as GlamRot, Vector as GlamVec},
    query,
    shape::{Shape, SharedShape},
};
use riseg_core::rng::Pcg32;

use super::convert::CM_PER_M;

/// The scene family the simulator draws (module docs; DESIGN.md §4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Layout {
    /// 4-6 objects of mixed shapes (a two-shape family), 3-7 cm, touching or a few
    /// millimetres apart. Shapes and heights differ, so a static segmenter already finds
    /// most objects: the easy regime.
    #[default]
    Loose,
    /// 4-6 look-alike boxes (or cans) of one size, height and texture, flush in a grid with
    /// sub-millimetre gaps: nothing tells them apart before a push (the paper's regime).
    Packed,
    /// A flush pack of 2-4 look-alike boxes with 1-3 loose objects against or near it.
    Mixed,
}

impl Layout {
    /// Every family, in the order of the docs.
    pub const ALL: [Self; 3] = [Self::Loose, Self::Packed, Self::Mixed];

    /// The family's name on the command line: `loose`, `packed`, `mixed`.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::Loose => "loose",
            Self::Packed => "packed",
            Self::Mixed => "mixed",
        }
    }
}

impl fmt::Display for Layout {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

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
    /// Mixed with the scene seed into the texture seed: `label << 40` for an object with a
    /// pattern of its own, [`PACK_TEXTURE_KEY`] for every object of a pack.
    pub texture_key: u64,
}

/// What to draw and where objects may go.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LayoutSpec {
    pub layout: Layout,
    pub min_objects: usize,
    pub max_objects: usize,
    pub min_size_m: f32,
    pub max_size_m: f32,
    /// Largest distance of a loose object's centre from the table centre, centimetres.
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

/// Draws and places a set of objects of `spec.layout`; `None` if the placement failed (the
/// caller retries with a different seed).
pub(crate) fn random_layout(rng: &mut Pcg32, spec: &LayoutSpec) -> Option<Vec<Placed>> {
    let span = (spec.max_objects - spec.min_objects + 1) as u32;
    let count = spec.min_objects + rng.below(span) as usize;
    match spec.layout {
        Layout::Loose => {
            let family = LooseFamily::draw(rng);
            let mut placed: Vec<Placed> = Vec::with_capacity(count);
            for _ in 0..count {
                add_loose(rng, &mut placed, &family, spec)?;
            }
            Some(placed)
        }
        Layout::Packed => {
            let cans = rng.below(CAN_SCENES_IN) == 0;
            Some(pack(rng, count, cans, spec).0)
        }
        Layout::Mixed => {
            // 2-4 packed and 1-3 loose when the count allows it.
            let lo = count.saturating_sub(3).max(2).min(count);
            let hi = count.saturating_sub(1).min(4).max(lo);
            let packed = lo + rng.below((hi - lo + 1) as u32) as usize;
            let (mut placed, pack_hue) = pack(rng, packed, false, spec);
            let mut family = LooseFamily::draw(rng);
            family.base_hue = pack_hue;
            for _ in packed..count {
                add_loose(rng, &mut placed, &family, spec)?;
            }
            // parry's box-box distance is occasionally wrong in one argument order, so the
            // clearance test of a slide can pass two boxes that overlap; refuse those
            // (`Loose` keeps its historic placement, this check would change it).
            (!any_overlap(&placed)).then_some(placed)
        }
    }
}

/// True if two of the objects intersect.
fn any_overlap(placed: &[Placed]) -> bool {
    placed.iter().enumerate().any(|(i, a)| {
        placed[i + 1..].iter().any(|b| {
            query::intersection_test(
                &a.world_from_object_cm,
                a.collider.as_ref(),
                &b.world_from_object_cm,
                b.collider.as_ref(),
            )
            .is_ok_and(|r| r.intersecting)
        })
    })
}

/// The shapes and colour of one scene's loose objects: a two-kind family (e.g. boxes and
/// rounded boxes) around one hue.
struct LooseFamily {
    first: Kind,
    second: Kind,
    base_hue: f32,
}

impl LooseFamily {
    fn draw(rng: &mut Pcg32) -> Self {
        let first = KINDS[rng.below(5) as usize];
        let second = KINDS[(first as usize + 1 + rng.below(4) as usize) % 5];
        Self {
            first,
            second,
            base_hue: rng.unit(),
        }
    }
}

/// Draws one loose object of `family` and places it: near the table centre if it is the
/// first object, else slid against a random placed one (module docs). `None` if no
/// placement was found.
fn add_loose(
    rng: &mut Pcg32,
    placed: &mut Vec<Placed>,
    family: &LooseFamily,
    spec: &LayoutSpec,
) -> Option<()> {
    let kind = if rng.below(2) == 0 {
        family.first
    } else {
        family.second
    };
    let shape = random_shape(rng, kind, spec.min_size_m, spec.max_size_m);
    let collider = shape.to_sim_shape();
    let rotation = shape.rest_rotation(uniform(rng, 0.0, core::f32::consts::TAU));
    // 0.5 mm above the table: the physics lets it settle.
    let z_cm = rest_height(collider.as_ref(), rotation) + 0.05;
    let albedo = hsv_to_rgb(
        family.base_hue + uniform(rng, -0.03, 0.03),
        uniform(rng, 0.45, 0.65),
        uniform(rng, 0.6, 0.8),
    );
    let pose = if placed.is_empty() {
        let offset = GlamVec::new(uniform(rng, -1.0, 1.0), uniform(rng, -1.0, 1.0), z_cm);
        GlamPose::from_parts(offset, rotation)
    } else {
        let centroid = placed.iter().fold(GlamVec::ZERO, |acc, p| {
            acc + p.world_from_object_cm.translation
        }) / placed.len() as f32;
        let mut best: Option<(f32, GlamPose)> = None;
        let mut found = 0;
        for _ in 0..64 {
            let Some(pose) = slide_next_to(rng, placed, &collider, rotation, z_cm, spec) else {
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
        best?.1
    };
    placed.push(Placed {
        shape,
        collider,
        world_from_object_cm: pose,
        albedo,
        texture_key: (placed.len() as u64 + 1) << 40,
    });
    Some(())
}

/// Gap between neighbours of a pack, centimetres (0.2-0.8 mm).
const PACK_GAP_CM: (f32, f32) = (0.02, 0.08);
/// Footprint side of a packed box and diameter of a packed can, metres (clamped to the
/// configured object sizes).
const PACK_SIDE_M: (f32, f32) = (0.04, 0.07);
/// Most objects in one row of a pack.
const PACK_MAX_COLS: usize = 5;
/// One packed scene in this many is of cans rather than boxes.
const CAN_SCENES_IN: u32 = 4;
/// Texture key shared by every object of a pack; above every `label << 40`.
const PACK_TEXTURE_KEY: u64 = 1 << 60;

/// Rows and columns of a pack of `n`: drawn among the grids with rows <= columns <=
/// [`PACK_MAX_COLS`] whose last row is not empty (for 4: 1x4, 2x2; 5: 1x5, 2x3 less one;
/// 6: 2x3); the squarest grid if none fits.
fn pack_grid(rng: &mut Pcg32, n: usize) -> (usize, usize) {
    let fits = |rows: usize| {
        let cols = n.div_ceil(rows);
        rows <= cols && cols <= PACK_MAX_COLS && (rows - 1) * cols < n
    };
    let options: Vec<usize> = (1..=n).filter(|&rows| fits(rows)).collect();
    let rows = match u32::try_from(options.len()) {
        Ok(len) if len > 0 => options[rng.below(len) as usize],
        _ => n.isqrt().max(1),
    };
    (rows, n.div_ceil(rows))
}

/// Places `n` look-alike objects flush in a grid (module docs): boxes, or cans if `cans`.
/// Returns them and the pack's hue.
fn pack(rng: &mut Pcg32, n: usize, cans: bool, spec: &LayoutSpec) -> (Vec<Placed>, f32) {
    let side = |rng: &mut Pcg32| {
        let clamp = |m: f32| m.clamp(spec.min_size_m, spec.max_size_m);
        uniform(rng, clamp(PACK_SIDE_M.0), clamp(PACK_SIDE_M.1))
    };
    let (size_x_m, size_y_m) = if cans {
        let d = side(rng);
        (d, d)
    } else {
        (side(rng), side(rng))
    };
    let height_m = uniform(rng, spec.min_size_m, spec.max_size_m);
    let shape = if cans {
        ObjectShape::Cylinder {
            radius_m: 0.5 * size_x_m,
            half_height_m: 0.5 * height_m,
        }
    } else {
        ObjectShape::Box {
            half_extents_m: [0.5 * size_x_m, 0.5 * size_y_m, 0.5 * height_m],
        }
    };
    let (rows, cols) = pack_grid(rng, n);
    let last_row = n - (rows - 1) * cols;
    let last_row_start = rng.below((cols - last_row + 1) as u32) as usize;
    let (sx_cm, sy_cm) = (size_x_m * CM_PER_M, size_y_m * CM_PER_M);
    let gap = |rng: &mut Pcg32| uniform(rng, PACK_GAP_CM.0, PACK_GAP_CM.1);
    // Centres in the pack's frame, centimetres, row by row.
    let centres: Vec<(f32, f32)> = if cans {
        // One pitch for the whole pack; odd rows shifted half a pitch when hex-packed, so
        // every neighbour is one pitch away either way.
        let pitch = sx_cm + gap(rng);
        let hex = rng.below(2) == 0;
        let row_pitch = if hex { pitch * 0.75_f32.sqrt() } else { pitch };
        (0..rows)
            .flat_map(|r| (0..cols).map(move |c| (r, c)))
            .map(|(r, c)| {
                let shift = if hex && r % 2 == 1 { 0.5 * pitch } else { 0.0 };
                (c as f32 * pitch + shift, r as f32 * row_pitch)
            })
            .collect()
    } else {
        // A gap of its own between every two columns and every two rows.
        let edges = |count: usize, size_cm: f32, rng: &mut Pcg32| {
            let mut at = vec![0.0_f32; count];
            for k in 1..count {
                at[k] = at[k - 1] + size_cm + gap(rng);
            }
            at
        };
        let xs = edges(cols, sx_cm, rng);
        let ys = edges(rows, sy_cm, rng);
        ys.iter()
            .flat_map(|&y| xs.iter().map(move |&x| (x, y)))
            .collect()
    };
    // Every row full but the last, which holds `last_row` cells from `last_row_start`.
    let cells: Vec<(f32, f32)> = centres
        .iter()
        .enumerate()
        .filter(|(i, _)| {
            let in_last_row = i / cols + 1 == rows;
            !in_last_row || (last_row_start..last_row_start + last_row).contains(&(i % cols))
        })
        .map(|(_, &c)| c)
        .collect();
    let (lo, hi) = cells.iter().fold(
        (
            (f32::INFINITY, f32::INFINITY),
            (f32::NEG_INFINITY, f32::NEG_INFINITY),
        ),
        |(lo, hi), &(x, y)| ((lo.0.min(x), lo.1.min(y)), (hi.0.max(x), hi.1.max(y))),
    );
    let middle = GlamVec::new(0.5 * (lo.0 + hi.0), 0.5 * (lo.1 + hi.1), 0.0);

    let offset = GlamVec::new(uniform(rng, -1.0, 1.0), uniform(rng, -1.0, 1.0), 0.0);
    let yaw_rad = uniform(rng, 0.0, core::f32::consts::TAU);
    let yaw = GlamRot::from_rotation_z(yaw_rad);
    let rotation = shape.rest_rotation(yaw_rad);
    let collider = shape.to_sim_shape();
    // 0.5 mm above the table: the physics lets it settle.
    let z_cm = rest_height(collider.as_ref(), rotation) + 0.05;
    let (hue, saturation, value) = (rng.unit(), uniform(rng, 0.45, 0.65), uniform(rng, 0.6, 0.8));
    let placed = cells
        .iter()
        .map(|&(x, y)| {
            let centre = offset + yaw * (GlamVec::new(x, y, 0.0) - middle);
            // Printed boxes of one product differ by a barely visible amount.
            let albedo = hsv_to_rgb(
                hue + uniform(rng, -0.003, 0.003),
                saturation + uniform(rng, -0.01, 0.01),
                value + uniform(rng, -0.01, 0.01),
            );
            Placed {
                shape,
                collider: collider.clone(),
                world_from_object_cm: GlamPose::from_parts(
                    GlamVec::new(centre.x, centre.y, z_cm),
                    rotation,
                ),
                albedo,
                texture_key: PACK_TEXTURE_KEY,
            }
        })
        .collect();
    (placed, hue)
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
            layout: Layout::Loose,
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

    fn spec(layout: Layout) -> LayoutSpec {
        LayoutSpec {
            layout,
            min_objects: 4,
            max_objects: 6,
            min_size_m: 0.03,
            max_size_m: 0.07,
            max_radius_cm: 12.0,
        }
    }

    fn distance(a: &Placed, b: &Placed) -> f32 {
        shape_distance(
            &a.collider,
            &a.world_from_object_cm,
            &b.collider,
            &b.world_from_object_cm,
        )
    }

    fn nearest(objects: &[Placed], i: usize) -> f32 {
        objects
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .map(|(_, b)| distance(&objects[i], b))
            .fold(f32::INFINITY, f32::min)
    }

    #[test]
    fn loose_layouts_are_the_ones_drawn_before_the_families() {
        // Kinds and centres (centimetres) of the first loose layouts, as drawn before the
        // scene families existed: `Loose` scenes must stay what they were.
        let golden = [
            "Box 0.778 0.476 2.128; Box 5.312 0.455 2.857; Box 3.784 5.568 1.975; \
             Box 10.350 0.168 3.278; Box 4.764 -4.369 2.108; Box 8.397 7.853 2.793; ",
            "Cap 0.360 0.302 1.910; Sph -0.511 3.692 1.647; Cap -1.520 -4.271 1.843; \
             Cap 3.766 -4.111 1.913; ",
            "Box 0.376 0.877 2.865; Cap 0.473 -4.945 1.867; Box 6.349 -1.387 2.676; \
             Cap 5.513 -6.993 1.747; Box 4.083 -10.834 3.493; Cap -2.341 -10.387 1.969; ",
            "Cap 0.634 -0.283 2.036; Cap -0.556 -3.899 1.635; Cap -3.952 -6.538 2.028; \
             Sph 4.068 -5.777 2.124; Sph 0.402 -10.772 2.512; Sph -5.108 -0.625 2.890; ",
        ];
        for (seed, expected) in (0..).zip(golden) {
            let objects = random_layout(&mut Pcg32::new(seed), &spec(Layout::Loose));
            let drawn: String = objects
                .iter()
                .flatten()
                .map(|p| {
                    let t = p.world_from_object_cm.translation;
                    let kind = format!("{:?}", p.shape);
                    format!("{} {:.3} {:.3} {:.3}; ", &kind[..3], t.x, t.y, t.z)
                })
                .collect();
            assert_eq!(drawn, expected, "seed {seed}");
        }
    }

    #[test]
    fn packed_layouts_are_look_alike_grids_with_sub_millimetre_gaps() {
        let (mut boxes, mut cans) = (0, 0);
        for seed in 0..60 {
            let objects = random_layout(&mut Pcg32::new(seed), &spec(Layout::Packed))
                .expect("a pack is always placed");
            assert!((4..=6).contains(&objects.len()), "seed {seed}");
            assert!(!any_overlap(&objects), "seed {seed}: objects overlap");
            let first = &objects[0];
            match first.shape {
                ObjectShape::Box { .. } => boxes += 1,
                ObjectShape::Cylinder { .. } => cans += 1,
                other => panic!("seed {seed}: {other:?} in a pack"),
            }
            let top = |p: &Placed| p.collider.compute_aabb(&p.world_from_object_cm).maxs.z;
            for (i, p) in objects.iter().enumerate() {
                assert_eq!(p.shape, first.shape, "seed {seed}: one size");
                assert!(
                    (top(p) - top(first)).abs() < 1e-4,
                    "seed {seed}: one height"
                );
                assert_eq!(p.texture_key, PACK_TEXTURE_KEY, "seed {seed}: one texture");
                let colour_diff = (0..3)
                    .map(|k| (p.albedo[k] - first.albedo[k]).abs())
                    .fold(0.0, f32::max);
                assert!(
                    colour_diff < 0.03,
                    "seed {seed}: albedo differs by {colour_diff}"
                );
                let aabb = p.collider.compute_aabb(&p.world_from_object_cm);
                assert!(aabb.mins.z > 0.0 && aabb.mins.z < 0.1, "rests on the table");
                let footprint = p.shape.to_sim_shape().compute_local_aabb().extents();
                let side_cm = footprint.x.min(footprint.y).min(footprint.z);
                assert!(
                    (3.0..=7.0 + 1e-4).contains(&side_cm),
                    "seed {seed}: size {footprint:?}"
                );
                let gap_cm = nearest(&objects, i);
                assert!(
                    gap_cm <= PACK_GAP_CM.1 + 1e-3,
                    "seed {seed}: object {i} is {gap_cm} cm from its nearest neighbour"
                );
            }
            let n = objects.len() as f32;
            let centroid = objects
                .iter()
                .fold(GlamVec::ZERO, |a, p| a + p.world_from_object_cm.translation)
                / n;
            assert!(
                centroid.truncate().length() < 8.0,
                "seed {seed}: the pack is near the table centre: {centroid:?}"
            );
        }
        assert!(
            boxes > 30 && cans > 5,
            "{boxes} box packs, {cans} can packs"
        );
    }

    #[test]
    fn pack_grids_are_the_documented_ones() {
        let mut rng = Pcg32::new(1);
        let mut seen = Vec::new();
        for n in 1..=6 {
            for _ in 0..40 {
                let (rows, cols) = pack_grid(&mut rng, n);
                assert!(rows <= cols && cols <= PACK_MAX_COLS, "{n}: {rows}x{cols}");
                assert!(
                    (rows - 1) * cols < n && n <= rows * cols,
                    "{n}: {rows}x{cols}"
                );
                if !seen.contains(&(n, rows, cols)) {
                    seen.push((n, rows, cols));
                }
            }
        }
        seen.sort_unstable();
        let expected = [
            (1, 1, 1),
            (2, 1, 2),
            (3, 1, 3),
            (3, 2, 2),
            (4, 1, 4),
            (4, 2, 2),
            (5, 1, 5),
            (5, 2, 3),
            (6, 2, 3),
        ];
        assert_eq!(seen, expected);
        // Past what fits in rows of PACK_MAX_COLS: the squarest grid.
        assert_eq!(pack_grid(&mut rng, 40), (6, 7));
    }

    #[test]
    fn mixed_layouts_are_a_pack_with_loose_objects_against_it() {
        let mut placed = 0;
        for seed in 0..40 {
            let Some(objects) = random_layout(&mut Pcg32::new(seed), &spec(Layout::Mixed)) else {
                continue;
            };
            placed += 1;
            assert!((4..=6).contains(&objects.len()), "seed {seed}");
            let packed = objects
                .iter()
                .take_while(|p| p.texture_key == PACK_TEXTURE_KEY)
                .count();
            assert!((2..=4).contains(&packed), "seed {seed}: pack of {packed}");
            assert!(
                objects[packed..]
                    .iter()
                    .all(|p| p.texture_key != PACK_TEXTURE_KEY),
                "seed {seed}: the pack comes first"
            );
            assert!(
                (1..=3).contains(&(objects.len() - packed)),
                "seed {seed}: loose objects"
            );
            assert!(!any_overlap(&objects), "seed {seed}: objects overlap");
            for i in 0..objects.len() {
                // Packed neighbours are flush; loose ones within the loose gaps (<= 12 mm).
                let limit_cm = if i < packed { PACK_GAP_CM.1 } else { 1.2 };
                assert!(nearest(&objects, i) <= limit_cm + 1e-3, "seed {seed}: {i}");
            }
        }
        assert!(placed >= 30, "only {placed} of 40 mixed layouts placed");
    }
}
