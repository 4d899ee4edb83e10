//! The simulated tabletop: riseg's built-in camera and robot, with exact ground truth.
//!
//! A table, 4-6 touching objects of similar size, shape and colour, an RGB-D camera with
//! D415-like colour intrinsics, and a pusher. Physics runs on rapier3d (the push is a
//! kinematic body moved through the simulation, then the objects settle); images are ray
//! cast against the same collider shapes with parry3d.
//!
//! The objects come in three scene families ([`Layout`], [`SimConfig::layout`]): `Loose`
//! (mixed shapes touching, the default), `Packed` (look-alike boxes or cans flush in a grid,
//! the regime where a static segmenter merges everything) and `Mixed` (a pack with loose
//! objects against it). Every family uses the same camera, renderer and sensor noise; the
//! family also picks the scripted pushes of [`SimScene::scripted_push`].
//!
//! # Frames
//! - **world** (= table = robot base): origin at the centre of the table top, z up. Pushes
//!   ([`SimScene::push`]) and object poses are in this frame.
//! - **camera**: OpenCV convention (x right, y down, z forward), at
//!   [`SimScene::world_from_camera`]: [`SimConfig::camera_height_m`] above the table, its
//!   optical axis tilted [`SimConfig::camera_tilt_rad`] from vertical towards the objects'
//!   centroid, from a seeded direction. This is the hand-eye transform; it is not the
//!   identity.
//! - **object**: each object's body frame, [`ObjectPose::world_from_object`]; its texture
//!   is fixed in this frame, so it moves with the object.
//!
//! # Ground truth
//! [`SimFrame::labels`] holds instance ids (`0` = table/background, objects `1..=n`) and
//! [`SimFrame::true_depth_m`] the exact depth, both per ray. [`ground_truth_flow`] turns
//! two pose sets into the exact forward flow.
//!
//! # Units
//! The public API is in metres (nalgebra types). The engines run in centimetres (glam
//! types) because parry's GJK tolerances suit shapes of a few units; the private module
//! `convert` is the one place that converts.
//!
//! # Determinism
//! Everything follows from the seed: the same seed and the same calls give bit-identical
//! images on one build. Physics is single-threaded; rendering is parallel over rows with
//! per-row noise generators, so thread scheduling does not matter. No clocks, no hash maps.
//! Each [`SimScene::render`] draws fresh sensor noise (a counter advances), as a real
//! camera would.

mod convert;
mod devices;
mod flow;
mod layout;
mod render;
mod seed;
mod shear;

use core::fmt;

use nalgebra::{Matrix3, Point3, Rotation3, UnitQuaternion, Vector3};
use parry3d::{math::Vector as GlamVec, query::Ray, shape::Ball};
use rapier3d::prelude::{
    Collider, ColliderBuilder, ColliderHandle, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle,
};
use riseg_core::{Intrinsics, Pose, rng::Pcg32};

/// Where one object is: its label (as in [`SimFrame::labels`]) and body frame in the world
/// frame. Defined with the scene folder format, which stores it (`poses.json`).
pub use crate::io::scene::ObjectPose;
pub use devices::{ARM_MAX_PUSH_LEN_M, ARM_MAX_TOOL_HEIGHT_M, SimCamera, SimRig, SimRobot};
pub use flow::{UNKNOWN_FLOW_PX, ground_truth_flow};
pub use layout::{Layout, ObjectShape};
pub use seed::{MAX_SCENE_ATTEMPTS, Seeded, attempt_seed, first_usable_seed, scene_seed};

use crate::{
    io::image::{DepthImage, Gray16Image, RgbImage},
    rig::robot::PushCommand,
};
use convert::{
    CM_PER_M, dir_from_sim, dir_to_sim, point_from_sim, point_to_sim, pose_from_sim, pose_to_sim,
};
use layout::{LayoutSpec, Placed, random_layout};
use render::{Sensor, Surface, mix64};

/// Half extents of the table top (x, y), metres; the top is the plane z = 0.
pub const TABLE_HALF_EXTENTS_M: [f32; 2] = [0.6, 0.6];
const TABLE_THICKNESS_M: f32 = 0.04;
/// Two objects closer than this count as touching, metres.
pub const TOUCH_GAP_M: f32 = 0.002;
/// Length of the scripted pushes of `riseg gen`: FindAction's push length (the paper's
/// `d_push`, [`riseg_core::Config::push_len_m`]), metres.
pub const DEFAULT_PUSH_LEN_M: f32 = riseg_core::Config::PAPER.push_len_m;
/// Longest travel [`SimScene::push`] moves the pusher ball, metres: a sanity bound of the
/// physics, not of the arm (the simulated arm refuses pushes longer than
/// [`ARM_MAX_PUSH_LEN_M`]).
pub const PUSHER_MAX_TRAVEL_M: f32 = 0.3;

/// Everything the simulator can be asked to vary, with a D415-like preset.
///
/// `#[non_exhaustive]`: outside the crate, start from [`SimConfig::D415`] and assign fields.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct SimConfig {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Colour intrinsics (depth is rendered aligned to colour).
    pub intrinsics: Intrinsics,
    /// Height of the camera centre above the table, metres.
    pub camera_height_m: f32,
    /// Angle between the optical axis and the vertical, radians.
    pub camera_tilt_rad: f32,
    /// Fewest objects in a scene.
    pub min_objects: usize,
    /// Most objects in a scene.
    pub max_objects: usize,
    /// Smallest object dimension drawn, metres.
    pub min_object_size_m: f32,
    /// Largest object dimension drawn, metres.
    pub max_object_size_m: f32,
    /// Colour noise σ, 8-bit levels.
    pub rgb_noise_sigma: f32,
    /// Depth noise σ at 0.6 m, metres; it grows with the square of the depth.
    pub depth_sigma_at_0_6_m: f32,
    /// Depth step between 4-neighbours that makes a depth edge, metres.
    pub depth_edge_step_m: f32,
    /// Probability that a depth-edge pixel has no reading.
    pub depth_edge_dropout: f32,
    /// Which scene family to draw ([`Layout`]); the object counts and sizes above bound
    /// every family.
    pub layout: Layout,
    /// Radius of the spherical pusher, metres.
    pub pusher_radius_m: f32,
    /// Pusher speed along the push, metres per second.
    pub push_speed_m_per_s: f32,
    /// Physics time step, seconds.
    pub physics_dt_s: f32,
    /// Longest the objects may take to settle after a push, seconds.
    pub settle_max_s: f32,
}

impl SimConfig {
    /// RealSense D415-like colour camera at 640x480 (fx = fy = 615), 0.60 m above the
    /// table, tilted 15°; 4-6 objects of 3-7 cm in a [`Layout::Loose`] scene; a 5 mm pusher
    /// at 5 cm/s.
    pub const D415: Self = Self {
        width: 640,
        height: 480,
        intrinsics: Intrinsics {
            fx: 615.0,
            fy: 615.0,
            cx: 319.5,
            cy: 239.5,
        },
        camera_height_m: 0.60,
        camera_tilt_rad: 15.0 * core::f32::consts::PI / 180.0,
        min_objects: 4,
        max_objects: 6,
        min_object_size_m: 0.03,
        max_object_size_m: 0.07,
        rgb_noise_sigma: 2.0,
        depth_sigma_at_0_6_m: 0.001,
        depth_edge_step_m: 0.01,
        depth_edge_dropout: 0.7,
        layout: Layout::Loose,
        pusher_radius_m: 0.005,
        push_speed_m_per_s: 0.05,
        physics_dt_s: 1.0 / 240.0,
        settle_max_s: 3.0,
    };

    /// This configuration drawing scenes of `layout`.
    #[must_use]
    pub const fn with_layout(mut self, layout: Layout) -> Self {
        self.layout = layout;
        self
    }

    fn check(&self) -> Result<(), SimError> {
        let bad = |what: &str| Err(SimError::BadConfig(what.to_owned()));
        if self.width == 0 || self.height == 0 || self.width > 8192 || self.height > 8192 {
            return bad("image size must be 1..=8192 pixels per side");
        }
        if self.intrinsics.check().is_err() {
            return bad("intrinsics must be finite with positive focal lengths");
        }
        let positive = [
            self.camera_height_m,
            self.min_object_size_m,
            self.pusher_radius_m,
            self.push_speed_m_per_s,
            self.physics_dt_s,
            self.settle_max_s,
            self.depth_edge_step_m,
        ];
        if !positive.iter().all(|v| v.is_finite() && *v > 0.0) {
            return bad("lengths, speeds and times must be finite and positive");
        }
        let non_negative = [self.rgb_noise_sigma, self.depth_sigma_at_0_6_m];
        if !non_negative.iter().all(|v| v.is_finite() && *v >= 0.0) {
            return bad("noise levels must be finite and not negative");
        }
        if !(0.0..=1.0).contains(&self.depth_edge_dropout) {
            return bad("depth_edge_dropout must be in [0, 1]");
        }
        if !(0.0..1.2).contains(&self.camera_tilt_rad) {
            return bad("camera_tilt_rad must be in [0, 1.2)");
        }
        if self.min_objects == 0 || self.max_objects < self.min_objects || self.max_objects > 64 {
            return bad("need 1 <= min_objects <= max_objects <= 64");
        }
        if !(self.max_object_size_m >= self.min_object_size_m && self.max_object_size_m <= 0.2) {
            return bad("need min_object_size_m <= max_object_size_m <= 0.2");
        }
        Ok(())
    }
}

impl Default for SimConfig {
    fn default() -> Self {
        Self::D415
    }
}

/// Why the simulator refused a request.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// A [`SimConfig`] field is out of range.
    #[error("bad simulator configuration: {0}")]
    BadConfig(String),
    /// No valid object placement was found for the seed.
    #[error("could not place the objects for seed {seed} in {attempts} attempts")]
    Placement {
        /// The scene seed.
        seed: u64,
        /// Placements tried.
        attempts: u32,
    },
    /// A push request is malformed.
    #[error("bad push: {0}")]
    BadPush(String),
    /// Label and depth images of different sizes.
    #[error("labels are {}x{} but depth is {}x{}", labels.0, labels.1, depth.0, depth.1)]
    SizeMismatch {
        /// Label image size.
        labels: (usize, usize),
        /// Depth image size.
        depth: (usize, usize),
    },
    /// A label in the image has no object pose.
    #[error("label {0} has no object pose")]
    UnknownLabel(u16),
}

/// What one object is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectInfo {
    /// Instance label, from 1.
    pub label: u16,
    /// Geometry.
    pub shape: ObjectShape,
    /// Albedo (before texture and shading), each channel in `[0, 1]`.
    pub albedo: [f32; 3],
}

/// World-frame axis-aligned bounds of one object.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectBounds {
    /// Instance label.
    pub label: u16,
    /// Lower corner, metres.
    pub min_m: Point3<f32>,
    /// Upper corner, metres.
    pub max_m: Point3<f32>,
}

/// A scripted push of `riseg gen` ([`SimScene::scripted_push`]): the command, in the world
/// frame (the simulated robot's frame), and the object it aims at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScriptedPush {
    /// The pusher's straight motion, world frame.
    pub command: PushCommand,
    /// Label of the object the push aims at.
    pub target: u16,
}

/// One RGB-D frame with its ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct SimFrame {
    /// Colour, with sensor noise.
    pub rgb: RgbImage,
    /// Depth in metres with sensor noise; `0.0` = no reading (depth edges, nothing hit).
    pub depth_m: DepthImage,
    /// Instance labels: `0` = table/background, objects from 1.
    pub labels: Gray16Image,
    /// Exact depth (z in the camera frame) of the surface each pixel sees; `0.0` if none.
    pub true_depth_m: DepthImage,
    /// Colour (and depth) intrinsics.
    pub intrinsics: Intrinsics,
    /// The camera's pose in the world (table) frame.
    pub world_from_camera: Pose,
    /// Every object's pose when the frame was taken.
    pub object_poses: Vec<ObjectPose>,
}

struct SimObject {
    info: ObjectInfo,
    /// Mixed with the scene seed into the texture seed (look-alike objects share it).
    texture_key: u64,
    body: RigidBodyHandle,
    collider: ColliderHandle,
}

/// A simulated tabletop scene.
pub struct SimScene {
    config: SimConfig,
    seed: u64,
    world: PhysicsWorld,
    table: ColliderHandle,
    objects: Vec<SimObject>,
    world_from_camera: Pose,
    rng: Pcg32,
    frames_rendered: u64,
}

impl fmt::Debug for SimScene {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SimScene")
            .field("seed", &self.seed)
            .field("objects", &self.objects())
            .field("world_from_camera", &self.world_from_camera)
            .field("frames_rendered", &self.frames_rendered)
            .finish_non_exhaustive()
    }
}

/// Placements tried before [`SimError::Placement`].
const PLACEMENT_ATTEMPTS: u32 = 16;

impl SimScene {
    /// A scene drawn from `seed` with the [`SimConfig::D415`] camera, settled.
    ///
    /// # Errors
    /// [`SimError::Placement`] in the rare case no placement is found.
    pub fn new(seed: u64) -> Result<Self, SimError> {
        Self::with_config(seed, SimConfig::D415)
    }

    /// A scene drawn from `seed` with `config`, settled.
    ///
    /// # Errors
    /// [`SimError::BadConfig`] for an out-of-range field; [`SimError::Placement`] if no
    /// placement is found.
    pub fn with_config(seed: u64, config: SimConfig) -> Result<Self, SimError> {
        config.check()?;
        let spec = LayoutSpec {
            layout: config.layout,
            min_objects: config.min_objects,
            max_objects: config.max_objects,
            min_size_m: config.min_object_size_m,
            max_size_m: config.max_object_size_m,
            max_radius_cm: 12.0,
        };
        for attempt in 0..PLACEMENT_ATTEMPTS {
            let mut rng = Pcg32::new(mix64(seed ^ mix64(u64::from(attempt))));
            if let Some(placed) = random_layout(&mut rng, &spec) {
                return Ok(Self::build(seed, config, rng, &placed));
            }
        }
        Err(SimError::Placement {
            seed,
            attempts: PLACEMENT_ATTEMPTS,
        })
    }

    fn build(seed: u64, config: SimConfig, mut rng: Pcg32, placed: &[Placed]) -> Self {
        let mut world = PhysicsWorld::new();
        world.gravity = GlamVec::new(0.0, 0.0, -9.81 * CM_PER_M);
        let params = &mut world.integration_parameters;
        params.dt = config.physics_dt_s;
        // The world is in centimetres: rapier scales its tolerances by this.
        params.length_unit = CM_PER_M;
        params.num_solver_iterations = 8;
        // Rapier reuses a contact (frozen normal and anchors) until the pair's relative pose
        // drifts by its recycle distance, 5 cm here. A box sliding past the corner of its
        // diagonal neighbour in a pack (0.3-1.1 mm away) then meets a frozen corner-to-corner
        // normal and drags the neighbour along; packs need contacts recomputed every step.
        // Loose scenes keep recycling so that they stay the scenes they were.
        params.contact_recycling = config.layout == Layout::Loose;

        let half_thickness_cm = 0.5 * TABLE_THICKNESS_M * CM_PER_M;
        let (_, table) = world.insert(
            RigidBodyBuilder::fixed().translation(GlamVec::new(0.0, 0.0, -half_thickness_cm)),
            ColliderBuilder::cuboid(
                TABLE_HALF_EXTENTS_M[0] * CM_PER_M,
                TABLE_HALF_EXTENTS_M[1] * CM_PER_M,
                half_thickness_cm,
            )
            .friction(0.5),
        );
        let objects = placed
            .iter()
            .zip(1u16..)
            .map(|(p, label)| {
                let (body, collider) = world.insert(
                    RigidBodyBuilder::dynamic()
                        .pose(p.world_from_object_cm)
                        // Stand-ins for the rolling resistance of soft toys: without them
                        // a pushed ball rolls on for ever; with them it travels about as
                        // far as it is pushed.
                        .linear_damping(2.0)
                        .angular_damping(30.0),
                    ColliderBuilder::new(p.collider.clone())
                        // 400 kg/m³ (hollow plastic toys), in kg/cm³.
                        .density(400.0 / (CM_PER_M * CM_PER_M * CM_PER_M))
                        .friction(0.6)
                        .restitution(0.0),
                );
                SimObject {
                    info: ObjectInfo {
                        label,
                        shape: p.shape,
                        albedo: p.albedo,
                    },
                    texture_key: p.texture_key,
                    body,
                    collider,
                }
            })
            .collect();
        let mut scene = Self {
            config,
            seed,
            world,
            table,
            objects,
            world_from_camera: Pose::identity(),
            rng: Pcg32::new(0),
            frames_rendered: 0,
        };
        scene.settle();
        let azimuth_rad = rng.unit() * core::f32::consts::TAU;
        scene.world_from_camera = scene.aim_camera(azimuth_rad);
        scene.rng = rng;
        scene
    }

    /// The camera pose looking at the objects' centroid from `azimuth_rad`.
    fn aim_camera(&self, azimuth_rad: f32) -> Pose {
        let n = self.objects.len().max(1) as f32;
        let centroid = self.object_poses().iter().fold(Vector3::zeros(), |acc, p| {
            acc + p.world_from_object.translation.vector
        }) / n;
        let target = Point3::new(centroid.x, centroid.y, 0.0);
        let h = self.config.camera_height_m;
        let back = Vector3::new(azimuth_rad.cos(), azimuth_rad.sin(), 0.0);
        let eye = target - back * (h * self.config.camera_tilt_rad.tan()) + Vector3::z() * h;
        let z = (target - eye).normalize();
        // Image x is horizontal; image y (down) then points back towards the camera.
        let x = z.cross(&Vector3::z()).normalize();
        let y = z.cross(&x);
        let rotation = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
        Pose::from_parts(eye.into(), UnitQuaternion::from_rotation_matrix(&rotation))
    }

    /// The configuration the scene was made with.
    #[must_use]
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// Colour (and aligned depth) intrinsics.
    #[must_use]
    pub fn intrinsics(&self) -> Intrinsics {
        self.config.intrinsics
    }

    /// The camera's pose in the world (table, robot base) frame: the hand-eye transform.
    #[must_use]
    pub fn world_from_camera(&self) -> Pose {
        self.world_from_camera
    }

    /// What the objects are, in label order.
    #[must_use]
    pub fn objects(&self) -> Vec<ObjectInfo> {
        self.objects.iter().map(|o| o.info).collect()
    }

    /// Where the objects are now, in label order.
    #[must_use]
    pub fn object_poses(&self) -> Vec<ObjectPose> {
        self.objects
            .iter()
            .filter_map(|o| {
                let body = self.world.bodies.get(o.body)?;
                Some(ObjectPose {
                    label: o.info.label,
                    world_from_object: pose_from_sim(body.position()),
                })
            })
            .collect()
    }

    /// World-frame bounds of every object now, in label order.
    #[must_use]
    pub fn object_bounds(&self) -> Vec<ObjectBounds> {
        self.objects
            .iter()
            .filter_map(|o| {
                let c = self.world.colliders.get(o.collider)?;
                let aabb = c.shape().compute_aabb(c.position());
                Some(ObjectBounds {
                    label: o.info.label,
                    min_m: point_from_sim(aabb.mins),
                    max_m: point_from_sim(aabb.maxs),
                })
            })
            .collect()
    }

    /// Labels of the object pairs closer than `max_gap_m` (`a < b`, sorted).
    #[must_use]
    pub fn touching_pairs(&self, max_gap_m: f32) -> Vec<(u16, u16)> {
        let colliders: Vec<_> = self
            .objects
            .iter()
            .filter_map(|o| Some((o.info.label, self.world.colliders.get(o.collider)?)))
            .collect();
        let mut pairs = Vec::new();
        for (i, (la, a)) in colliders.iter().enumerate() {
            for (lb, b) in &colliders[i + 1..] {
                let d_cm =
                    parry3d::query::distance(a.position(), a.shape(), b.position(), b.shape())
                        .map_or(0.0, |d| d.distance);
                if d_cm <= max_gap_m * CM_PER_M {
                    pairs.push((*la, *lb));
                }
            }
        }
        pairs
    }

    /// Renders the scene as the camera sees it now, with fresh sensor noise.
    pub fn render(&mut self) -> SimFrame {
        let table = self.world.colliders.get(self.table);
        let mut surfaces: Vec<Surface<'_>> = Vec::with_capacity(self.objects.len() + 1);
        if let Some(t) = table {
            surfaces.push(Surface {
                shape: t.shape(),
                world_from_surface_cm: *t.position(),
                label: 0,
                albedo: [0.62, 0.6, 0.56],
                texture_seed: mix64(self.seed ^ 0x7AB1E) as u32,
                texture_cell_cm: 1.2,
                texture_contrast: 0.12,
            });
        }
        for o in &self.objects {
            if let Some(c) = self.world.colliders.get(o.collider) {
                surfaces.push(Surface {
                    shape: c.shape(),
                    world_from_surface_cm: *c.position(),
                    label: o.info.label,
                    albedo: o.info.albedo,
                    texture_seed: mix64(self.seed ^ o.texture_key) as u32,
                    texture_cell_cm: 0.6,
                    texture_contrast: 0.18,
                });
            }
        }
        let sensor = Sensor {
            width: self.config.width,
            height: self.config.height,
            intrinsics: self.config.intrinsics,
            world_from_camera_cm: pose_to_sim(&self.world_from_camera),
            rgb_sigma: self.config.rgb_noise_sigma,
            depth_sigma_m: self.config.depth_sigma_at_0_6_m,
            edge_step_m: self.config.depth_edge_step_m,
            edge_dropout: self.config.depth_edge_dropout,
        };
        let noise_seed = mix64(self.seed ^ mix64(0xF8A3E ^ self.frames_rendered));
        self.frames_rendered += 1;
        let r = render::render(&surfaces, &sensor, noise_seed);
        SimFrame {
            rgb: r.rgb,
            depth_m: r.depth_m,
            labels: r.labels,
            true_depth_m: r.true_depth_m,
            intrinsics: self.config.intrinsics,
            world_from_camera: self.world_from_camera,
            object_poses: self.object_poses(),
        }
    }

    /// True when no object moves faster than 1 mm/s or 0.02 rad/s.
    fn all_still(&self) -> bool {
        self.objects.iter().all(|o| {
            self.world.bodies.get(o.body).is_none_or(|b| {
                // Linear velocity in cm/s.
                b.is_sleeping() || (b.linvel().length() < 0.1 && b.angvel().length() < 0.02)
            })
        })
    }

    /// Steps until every object has been still for 0.1 s, or `settle_max_s` passed.
    fn settle(&mut self) {
        let dt = self.config.physics_dt_s;
        let max_steps = (self.config.settle_max_s / dt).ceil() as usize;
        let quiet_steps = (0.1 / dt).ceil() as usize;
        let mut quiet = 0;
        for _ in 0..max_steps {
            self.world.step();
            quiet = if self.all_still() { quiet + 1 } else { 0 };
            if quiet >= quiet_steps {
                break;
            }
        }
    }

    /// Pushes: a small ball (radius [`SimConfig::pusher_radius_m`]) appears with its centre
    /// at the command's start (world frame), moves its length along its direction at
    /// [`SimConfig::push_speed_m_per_s`] through the physics, lifts off and disappears;
    /// then the objects settle.
    ///
    /// # Errors
    /// [`SimError::BadPush`] (nothing moves) if a value is not finite, the direction is
    /// zero, the length is not in `(0, PUSHER_MAX_TRAVEL_M]`, or the start is below the table
    /// top by more than the pusher radius allows.
    pub fn push(&mut self, cmd: &PushCommand) -> Result<(), SimError> {
        let (start_world_m, direction_world, length_m) =
            (cmd.start_robot_m, cmd.direction_robot, cmd.length_m);
        let finite = start_world_m
            .iter()
            .chain(direction_world.iter())
            .all(|v| v.is_finite());
        if !finite || !length_m.is_finite() {
            return Err(SimError::BadPush("a value is not finite".into()));
        }
        let Some(dir) = direction_world.try_normalize(1e-6) else {
            return Err(SimError::BadPush("the direction is zero".into()));
        };
        if !(length_m > 0.0 && length_m <= PUSHER_MAX_TRAVEL_M) {
            return Err(SimError::BadPush(format!(
                "length {length_m} m is not in (0, {PUSHER_MAX_TRAVEL_M}]"
            )));
        }
        let r_m = self.config.pusher_radius_m;
        if start_world_m.z < r_m - 1e-4 || start_world_m.z + dir.z * length_m < r_m - 1e-4 {
            return Err(SimError::BadPush(format!(
                "the pusher (radius {r_m} m) would go into the table"
            )));
        }
        let dt = self.config.physics_dt_s;
        let start = point_to_sim(&start_world_m);
        let dir = dir_to_sim(&dir);
        // Sleeping bodies would ignore the pusher's first contact.
        self.world.wake_up_all(true);
        let (pusher, _) = self.world.insert(
            RigidBodyBuilder::kinematic_position_based().translation(start),
            ColliderBuilder::ball(r_m * CM_PER_M).friction(0.3),
        );
        let drive = |world: &mut PhysicsWorld, from: GlamVec, delta: GlamVec, secs: f32| {
            let steps = (secs / dt).ceil().max(1.0) as usize;
            for i in 1..=steps {
                if let Some(b) = world.bodies.get_mut(pusher) {
                    b.set_next_kinematic_translation(from + delta * (i as f32 / steps as f32));
                }
                world.step();
            }
        };
        let end = start + dir * (length_m * CM_PER_M);
        drive(
            &mut self.world,
            start,
            end - start,
            length_m / self.config.push_speed_m_per_s,
        );
        // Lift off 5 cm in 0.1 s, then remove the pusher.
        drive(&mut self.world, end, GlamVec::new(0.0, 0.0, 5.0), 0.1);
        self.world.remove_body_with_colliders(pusher, true);
        self.settle();
        Ok(())
    }

    /// A scripted push for `riseg gen`, drawn with the scene's generator among the
    /// candidates of the scene's [`Layout`]; `None` if no candidate qualifies. Every
    /// candidate's pusher starts 2 mm before the pushed object's surface on a line through
    /// its centre, at its centre's height (at most 3 cm), clear of every object, and
    /// travels `length_m`.
    /// - [`Layout::Loose`]: one object of a touching pair is pushed across the line joining
    ///   the pair's centres (all touching pairs, both objects of each, both directions).
    /// - [`Layout::Packed`], [`Layout::Mixed`]: the push shears the pack. A box is pushed
    ///   along one of its face normals from a free face, any other shape across the line to
    ///   a touching neighbour; kept are the pushes whose carried objects (the pushed one and,
    ///   transitively, every object a carried one would run into by more than 1 mm if it
    ///   moved rigidly along the push) are not all of them and touch one that stays. Part of
    ///   the objects slides along a face it shares with the rest, which stays.
    pub fn scripted_push(&mut self, length_m: f32) -> Option<ScriptedPush> {
        let candidates = match self.config.layout {
            Layout::Loose => self.across_pushes(length_m),
            Layout::Packed | Layout::Mixed => self.shear_pushes(length_m),
        };
        let n = u32::try_from(candidates.len()).ok().filter(|&n| n > 0)?;
        candidates.get(self.rng.below(n) as usize).copied()
    }

    /// The loose family's candidates: see [`SimScene::scripted_push`].
    fn across_pushes(&self, length_m: f32) -> Vec<ScriptedPush> {
        let mut candidates = Vec::new();
        for (a, b) in self.touching_pairs(TOUCH_GAP_M) {
            for (pushed, other) in [(a, b), (b, a)] {
                for sign in [1.0, -1.0] {
                    candidates.extend(self.push_across(pushed, other, sign, length_m));
                }
            }
        }
        candidates
    }

    fn collider_of(&self, label: u16) -> Option<&Collider> {
        let o = self.objects.iter().find(|o| o.info.label == label)?;
        self.world.colliders.get(o.collider)
    }

    fn push_across(
        &self,
        pushed: u16,
        other: u16,
        sign: f32,
        length_m: f32,
    ) -> Option<ScriptedPush> {
        let (c_pushed, c_other) = (self.collider_of(pushed)?, self.collider_of(other)?);
        let dir = across(c_pushed, c_other)? * sign;
        let start = self.push_start(c_pushed, dir)?;
        Some(ScriptedPush {
            command: PushCommand {
                start_robot_m: point_from_sim(start),
                direction_robot: dir_from_sim(dir),
                length_m,
            },
            target: pushed,
        })
    }

    /// Where the pusher's centre starts to push `pushed` along `dir` (engine frame, unit,
    /// horizontal): 2 mm before the surface on the line through the centre, at the centre's
    /// height (at most 3 cm). `None` if the pusher there is not clear of every object (by
    /// 1 mm), e.g. because a neighbour covers that face.
    fn push_start(&self, pushed: &Collider, dir: GlamVec) -> Option<GlamVec> {
        let p = pushed.position().translation;
        // Engine side: centimetres.
        let r_cm = self.config.pusher_radius_m * CM_PER_M;
        let height_cm = p.z.clamp(r_cm + 0.2, 3.0);
        // Where the line through the centre (at push height) enters the object.
        let aim = GlamVec::new(p.x, p.y, height_cm);
        let ray = Ray::new(aim - dir * 30.0, dir);
        let toi_cm = pushed
            .shape()
            .cast_ray(pushed.position(), &ray, 30.0, true)?;
        let start = ray.point_at(toi_cm) - dir * (r_cm + 0.2);
        let pusher = Ball::new(r_cm);
        let pusher_pose = parry3d::math::Pose::from_translation(start);
        let clear = self.objects.iter().all(|o| {
            self.world.colliders.get(o.collider).is_some_and(|c| {
                parry3d::query::distance(&pusher_pose, &pusher, c.position(), c.shape())
                    .is_ok_and(|d| d.distance > 0.1)
            })
        });
        clear.then_some(start)
    }
}

/// The horizontal unit direction across the line from `a`'s centre to `b`'s (turned +90°
/// about z), engine frame; `None` if the centres are on one vertical.
fn across(a: &Collider, b: &Collider) -> Option<GlamVec> {
    let (p, q) = (a.position().translation, b.position().translation);
    let line = GlamVec::new(q.x - p.x, q.y - p.y, 0.0);
    GlamVec::new(-line.y, line.x, 0.0).try_normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_is_0_6_m_up_tilted_15_degrees_and_looks_at_the_objects() {
        let sim = SimScene::new(11).unwrap();
        let cam = sim.world_from_camera();
        assert!((cam.translation.z - 0.60).abs() < 1e-5);
        let axis = cam.rotation * Vector3::z();
        let tilt_deg = axis.angle(&-Vector3::z()).to_degrees();
        assert!((tilt_deg - 15.0).abs() < 0.01, "{tilt_deg}");
        // The objects' centroid on the table projects to the image centre.
        let poses = sim.object_poses();
        let c = poses.iter().fold(Vector3::zeros(), |a, p| {
            a + p.world_from_object.translation.vector
        }) / poses.len() as f32;
        let px = sim
            .intrinsics()
            .project(&(cam.inverse() * Point3::new(c.x, c.y, 0.0)))
            .unwrap();
        assert!(
            (px.x - 319.5).abs() < 0.5 && (px.y - 239.5).abs() < 0.5,
            "{px:?}"
        );
    }

    #[test]
    fn renders_are_seeded_and_the_sensor_is_noisy_like_a_d415() {
        let mut a = SimScene::new(5).unwrap();
        let mut b = SimScene::new(5).unwrap();
        let (fa, fb) = (a.render(), b.render());
        assert_eq!(fa, fb, "same seed, same frame");
        let again = a.render();
        assert_eq!(again.labels, fa.labels);
        assert_eq!(again.true_depth_m, fa.true_depth_m);
        assert_ne!(again.rgb, fa.rgb, "each render draws fresh sensor noise");

        // Depth noise: about 1 mm at 0.6 m; readings missing only on depth edges.
        let (mut sum2, mut n, mut missing) = (0.0_f64, 0_u32, 0_u32);
        let (w, h) = (fa.depth_m.width(), fa.depth_m.height());
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let z = *fa.true_depth_m.get(x, y).unwrap();
                let d = *fa.depth_m.get(x, y).unwrap();
                if d == 0.0 {
                    missing += 1;
                    let step = [(x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)]
                        .iter()
                        .map(|&(nx, ny)| (fa.true_depth_m.get(nx, ny).unwrap() - z).abs())
                        .fold(0.0, f32::max);
                    assert!(step > 0.01, "missing reading off an edge at ({x}, {y})");
                } else if (0.59..0.61).contains(&z) {
                    sum2 += f64::from((d - z) * (d - z));
                    n += 1;
                }
            }
        }
        let sigma_mm = (sum2 / f64::from(n)).sqrt() * 1000.0;
        assert!(
            (0.8..1.2).contains(&sigma_mm),
            "depth noise {sigma_mm} mm at 0.6 m"
        );
        assert!(missing > 100, "depth edges should lose readings");
    }

    #[test]
    fn a_planned_push_moves_its_target_about_the_push_length() {
        let mut sim = SimScene::new(3).unwrap();
        let before = sim.object_poses();
        let push = sim.scripted_push(DEFAULT_PUSH_LEN_M).unwrap();
        assert!((push.command.direction_robot.norm() - 1.0).abs() < 1e-5);
        assert!(
            push.command.direction_robot.z.abs() < 1e-6,
            "pushes are horizontal"
        );
        sim.push(&push.command).unwrap();
        let after = sim.object_poses();
        let moved = |label: u16| {
            let p = |poses: &[ObjectPose]| {
                poses
                    .iter()
                    .find(|p| p.label == label)
                    .unwrap()
                    .world_from_object
                    .translation
                    .vector
            };
            (p(&after) - p(&before)).dot(&push.command.direction_robot)
        };
        let target_m = moved(push.target);
        // The pusher starts 2 mm from the surface; the object may slide a little further.
        assert!(
            (0.012..0.03).contains(&target_m),
            "target moved {target_m} m"
        );
    }

    #[test]
    fn bad_pushes_are_refused_and_move_nothing() {
        let mut sim = SimScene::new(4).unwrap();
        let before = sim.object_poses();
        let start = Point3::new(0.3, 0.3, 0.02);
        let x = Vector3::x();
        for (s, d, len) in [
            (Point3::new(f32::NAN, 0.0, 0.02), x, 0.02),
            (start, Vector3::zeros(), 0.02),
            (start, x, 0.0),
            (start, x, 1.0),
            (Point3::new(0.3, 0.3, 0.0), x, 0.02),
            (start, -Vector3::z(), 0.02),
        ] {
            let e = sim
                .push(&PushCommand {
                    start_robot_m: s,
                    direction_robot: d,
                    length_m: len,
                })
                .unwrap_err();
            assert!(matches!(e, SimError::BadPush(_)), "{e}");
        }
        assert_eq!(sim.object_poses(), before);
        let mut cfg = SimConfig::D415;
        cfg.max_objects = 2;
        assert!(matches!(
            SimScene::with_config(0, cfg),
            Err(SimError::BadConfig(_))
        ));
    }
}
