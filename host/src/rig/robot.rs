//! The robot side of the loop: a push planned by FindAction in the camera frame becomes a
//! straight, level Cartesian motion in the robot frame, checked against limits before it is
//! sent, and the [`Robot`] trait that executes it.
//!
//! Frames: `robot_from_camera` is the hand-eye calibration (the user's file for a real
//! robot; the simulator's true camera pose in simulation). The robot frame has z up, normal
//! to the table. A push is refused, never clipped, when its start or end leaves the
//! workspace box or it is longer than allowed: a robot that silently moves somewhere else
//! than planned is worse than one that stops.
//!
//! # From FindAction's push to a command
//!
//! FindAction decides the push once, in the camera frame: it starts at the pushed object's
//! edge (where the pushed segment of the mask ends), points at the pushed cluster's centre
//! and is [`riseg_core::Config::push_len_m`] long. [`plan_push`] only says the same in the
//! robot's terms:
//! 1. maps the edge and the direction to the robot frame and levels the direction (a push
//!    slides along the table);
//! 2. lowers the tool to half the edge's height over the table (objects tip less when
//!    pushed near their middle), at least [`PushGeometry::min_height_m`];
//! 3. backs the start off the edge by [`PushGeometry::approach_m`] so the tool starts
//!    clear of the object, and lengthens the motion by the same amount: the object itself
//!    moves about FindAction's push length;
//! 4. checks the command against the arm's [`PushLimits`].
use nalgebra::{Point3, Vector3};
use riseg_core::{Pose, action::Push};

/// A straight push in the robot (base) frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PushCommand {
    /// Where the pusher starts, robot frame, metres.
    pub start_robot_m: Point3<f32>,
    /// Unit direction of motion, robot frame.
    pub direction_robot: Vector3<f32>,
    /// Distance to travel, metres.
    pub length_m: f32,
}

impl PushCommand {
    /// Where the pusher stops, robot frame, metres.
    #[must_use]
    pub fn end_robot_m(&self) -> Point3<f32> {
        self.start_robot_m + self.direction_robot * self.length_m
    }
}

/// Where pushes may go, in the robot frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PushLimits {
    /// Lower corner of the allowed box (x, y, z), metres.
    pub workspace_min_m: [f32; 3],
    /// Upper corner of the allowed box (x, y, z), metres.
    pub workspace_max_m: [f32; 3],
    /// Longest allowed push, metres.
    pub max_push_len_m: f32,
}

/// Why a push was refused.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum PushRefused {
    /// The push has NaN or infinite coordinates, or a zero direction.
    #[error("push is not finite or has no direction")]
    NotFinite,
    /// The push is longer than [`PushLimits::max_push_len_m`].
    #[error("push of {length_m:.3} m is longer than the limit of {limit_m:.3} m")]
    TooLong {
        /// Requested length, metres.
        length_m: f32,
        /// The limit, metres.
        limit_m: f32,
    },
    /// The start or end of the push is outside the workspace box.
    #[error(
        "push {which} at ({:.3}, {:.3}, {:.3}) m (robot frame) is outside the workspace \
         [{:.3}, {:.3}] x [{:.3}, {:.3}] x [{:.3}, {:.3}] m",
        point[0], point[1], point[2], min[0], max[0], min[1], max[1], min[2], max[2]
    )]
    OutsideWorkspace {
        /// `"start"` or `"end"`.
        which: &'static str,
        /// The offending point, robot frame, metres.
        point: [f32; 3],
        /// Workspace lower corner.
        min: [f32; 3],
        /// Workspace upper corner.
        max: [f32; 3],
    },
}

/// How a push meets the objects, robot frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PushGeometry {
    /// Height of the table top in the robot frame, metres.
    pub table_z_m: f32,
    /// Gap between the object's edge and the tool's centre at the start, metres (more than
    /// the tool's radius).
    pub approach_m: f32,
    /// Lowest height of the tool's centre over the table, metres.
    pub min_height_m: f32,
}

impl PushLimits {
    /// Checks `cmd` against the limits.
    ///
    /// # Errors
    /// [`PushRefused`] when the command is not finite, too long, or starts or ends outside
    /// the workspace.
    pub fn check(&self, cmd: &PushCommand) -> Result<(), PushRefused> {
        let finite = cmd
            .start_robot_m
            .coords
            .iter()
            .chain(cmd.direction_robot.iter())
            .all(|v| v.is_finite());
        if !finite || !cmd.length_m.is_finite() || cmd.length_m < 0.0 {
            return Err(PushRefused::NotFinite);
        }
        if cmd.length_m > self.max_push_len_m {
            return Err(PushRefused::TooLong {
                length_m: cmd.length_m,
                limit_m: self.max_push_len_m,
            });
        }
        for (which, p) in [("start", cmd.start_robot_m), ("end", cmd.end_robot_m())] {
            let inside =
                (0..3).all(|i| p[i] >= self.workspace_min_m[i] && p[i] <= self.workspace_max_m[i]);
            if !inside {
                return Err(PushRefused::OutsideWorkspace {
                    which,
                    point: [p.x, p.y, p.z],
                    min: self.workspace_min_m,
                    max: self.workspace_max_m,
                });
            }
        }
        Ok(())
    }
}

/// Turns a FindAction push (camera frame; it starts at the pushed object's edge) into a
/// level robot command (module docs), or refuses it.
///
/// # Errors
/// [`PushRefused::NotFinite`] when a value is not finite or the push is vertical in the
/// robot frame; the errors of [`PushLimits::check`].
pub fn plan_push(
    push: &Push,
    robot_from_camera: &Pose,
    geometry: &PushGeometry,
    limits: &PushLimits,
) -> Result<PushCommand, PushRefused> {
    let edge = robot_from_camera * push.start_cam_m;
    let mut direction = robot_from_camera.rotation * push.direction_cam;
    direction.z = 0.0;
    let direction = direction
        .try_normalize(1e-6)
        .ok_or(PushRefused::NotFinite)?;
    let over_table_m = (0.5 * (edge.z - geometry.table_z_m)).max(geometry.min_height_m);
    let contact = Point3::new(edge.x, edge.y, geometry.table_z_m + over_table_m);
    let cmd = PushCommand {
        start_robot_m: contact - direction * geometry.approach_m,
        direction_robot: direction,
        length_m: push.length_m + geometry.approach_m,
    };
    limits.check(&cmd)?;
    Ok(cmd)
}

/// The calibration the loop needs to turn pixels into robot motions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotSetup {
    /// Hand-eye calibration: the camera's pose in the robot frame.
    pub robot_from_camera: Pose,
    /// How the tool meets the objects.
    pub geometry: PushGeometry,
}

/// Why the robot could not execute a push.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct RobotError(pub String);

/// Something that executes pushes: the simulator, or a real arm.
pub trait Robot {
    /// Where pushes may go; the loop checks every command against these before sending.
    fn limits(&self) -> PushLimits;

    /// Moves the tool along `cmd` and back out of the scene; returns once the scene is
    /// still again.
    ///
    /// # Errors
    /// [`RobotError`] when the motion could not be made.
    fn execute(&mut self, cmd: &PushCommand) -> Result<(), RobotError>;
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion};

    use super::*;

    /// A camera 0.6 m above the table (z = 0), 0.5 m along x from the robot base, looking
    /// down and tilted 15° about x (camera z = view).
    fn robot_from_camera() -> Pose {
        let down = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), core::f32::consts::PI);
        let tilt = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 15f32.to_radians());
        Pose::from_parts(Translation3::new(0.5, 0.0, 0.6), tilt * down)
    }

    fn limits() -> PushLimits {
        PushLimits {
            workspace_min_m: [0.2, -0.3, 0.0],
            workspace_max_m: [0.8, 0.3, 0.3],
            max_push_len_m: 0.05,
        }
    }

    const GEOMETRY: PushGeometry = PushGeometry {
        table_z_m: 0.0,
        approach_m: 0.01,
        min_height_m: 0.007,
    };

    /// Plans a push of `length_m` whose object edge and direction are given in the robot
    /// frame (the test converts them to the camera frame, as FindAction reports them).
    fn plan(
        edge_robot: Point3<f32>,
        dir_robot: Vector3<f32>,
        length_m: f32,
    ) -> Result<PushCommand, PushRefused> {
        let t = robot_from_camera();
        let push = Push {
            start_px: [0.0, 0.0],
            target_px: [0.0, 0.0],
            start_cam_m: t.inverse() * edge_robot,
            direction_cam: t.inverse().rotation * dir_robot,
            length_m,
        };
        plan_push(&push, &t, &GEOMETRY, &limits())
    }

    #[test]
    fn the_edge_maps_through_the_hand_eye_transform_and_the_push_is_level_at_half_height() {
        // An object edge 4 cm over the table at (0.55, 0.02); the direction along robot +y
        // but tilted down, as seen from the camera.
        let edge_robot = Point3::new(0.55, 0.02, 0.04);
        let cmd = plan(edge_robot, Vector3::new(0.0, 1.0, -0.3).normalize(), 0.02).unwrap();
        assert!(
            (cmd.direction_robot - Vector3::y()).norm() < 1e-5,
            "{cmd:?}"
        );
        let expected_start = Point3::new(0.55, 0.02 - 0.01, 0.02);
        assert!(
            (cmd.start_robot_m - expected_start).norm() < 1e-5,
            "{cmd:?}"
        );
        assert!((cmd.length_m - 0.03).abs() < 1e-6);
        assert!((cmd.end_robot_m() - Point3::new(0.55, 0.04, 0.02)).norm() < 1e-5);
        // Not the identity: the camera-frame edge is far from its robot-frame coordinates.
        let edge_cam = robot_from_camera().inverse() * edge_robot;
        assert!((edge_cam.coords - edge_robot.coords).norm() > 0.1);
    }

    #[test]
    fn a_low_object_is_pushed_at_the_minimum_height() {
        let cmd = plan(Point3::new(0.5, 0.0, 0.008), Vector3::x(), 0.02).unwrap();
        assert!((cmd.start_robot_m.z - 0.007).abs() < 1e-5, "{cmd:?}");
    }

    #[test]
    fn pushes_outside_limits_are_refused_with_a_clear_message() {
        let err = plan(Point3::new(0.5, 0.9, 0.04), Vector3::x(), 0.02).unwrap_err();
        assert!(matches!(
            err,
            PushRefused::OutsideWorkspace { which: "start", .. }
        ));
        assert!(err.to_string().contains("outside the workspace"), "{err}");
        let too_long = plan(Point3::new(0.5, 0.0, 0.04), Vector3::x(), 0.2);
        assert!(
            matches!(too_long, Err(PushRefused::TooLong { length_m, limit_m: 0.05 })
                if (length_m - 0.21).abs() < 1e-6),
            "{too_long:?}"
        );
        let nan = plan(Point3::new(f32::NAN, 0.0, 0.04), Vector3::x(), 0.02);
        assert_eq!(nan, Err(PushRefused::NotFinite));
        let vertical = plan(Point3::new(0.5, 0.0, 0.04), Vector3::z(), 0.02);
        assert_eq!(vertical, Err(PushRefused::NotFinite));
        // Ends outside: starts near the +x edge of the box, pushing further out.
        assert!(matches!(
            plan(Point3::new(0.79, 0.0, 0.04), Vector3::x(), 0.02),
            Err(PushRefused::OutsideWorkspace { which: "end", .. })
        ));
    }
}
