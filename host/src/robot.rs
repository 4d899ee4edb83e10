//! The robot side of the loop: a push planned by FindAction in the camera frame becomes a
//! straight Cartesian motion in the robot frame, checked against limits before it is sent.
//!
//! Frames: `robot_from_camera` is the hand-eye calibration (the user's file for a real
//! robot; the simulator's true camera pose in simulation). A push is refused, never
//! clipped, when its start or end leaves the workspace box or it is longer than allowed:
//! a robot that silently moves somewhere else than planned is worse than one that stops.

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

/// Turns a FindAction push (camera frame) into a robot command, or refuses it.
///
/// # Errors
/// [`PushRefused`] when the push is not finite, too long, or starts or ends outside the
/// workspace.
pub fn plan_push(
    push: &Push,
    robot_from_camera: &Pose,
    limits: &PushLimits,
) -> Result<PushCommand, PushRefused> {
    let start = robot_from_camera * push.start_cam_m;
    let direction = (robot_from_camera.rotation * push.direction_cam)
        .try_normalize(1e-6)
        .ok_or(PushRefused::NotFinite)?;
    let finite = start
        .coords
        .iter()
        .chain(direction.iter())
        .all(|v| v.is_finite());
    if !finite || !push.length_m.is_finite() || push.length_m < 0.0 {
        return Err(PushRefused::NotFinite);
    }
    if push.length_m > limits.max_push_len_m {
        return Err(PushRefused::TooLong {
            length_m: push.length_m,
            limit_m: limits.max_push_len_m,
        });
    }
    let cmd = PushCommand {
        start_robot_m: start,
        direction_robot: direction,
        length_m: push.length_m,
    };
    for (which, p) in [("start", cmd.start_robot_m), ("end", cmd.end_robot_m())] {
        let inside =
            (0..3).all(|i| p[i] >= limits.workspace_min_m[i] && p[i] <= limits.workspace_max_m[i]);
        if !inside {
            return Err(PushRefused::OutsideWorkspace {
                which,
                point: [p.x, p.y, p.z],
                min: limits.workspace_min_m,
                max: limits.workspace_max_m,
            });
        }
    }
    Ok(cmd)
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion};

    use super::*;

    /// A camera 0.6 m above the table origin, looking down and tilted 15° (camera z = view).
    fn robot_from_camera() -> Pose {
        let down = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), core::f32::consts::PI);
        let tilt = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 15f32.to_radians());
        Pose::from_parts(Translation3::new(0.5, 0.0, 0.6), tilt * down)
    }

    fn limits() -> PushLimits {
        PushLimits {
            workspace_min_m: [0.2, -0.3, -0.01],
            workspace_max_m: [0.8, 0.3, 0.3],
            max_push_len_m: 0.05,
        }
    }

    fn push_at(start_cam_m: Point3<f32>, direction_cam: Vector3<f32>, length_m: f32) -> Push {
        Push {
            start_px: [0.0, 0.0],
            target_px: [0.0, 0.0],
            start_cam_m,
            direction_cam,
            length_m,
        }
    }

    #[test]
    fn a_push_in_the_camera_frame_lands_where_the_hand_eye_transform_says() {
        let t = robot_from_camera();
        let p = push_at(
            Point3::new(0.02, -0.01, 0.58),
            Vector3::new(1.0, 0.0, 0.0),
            0.02,
        );
        let cmd = plan_push(&p, &t, &limits()).unwrap();
        let expected_start = t * p.start_cam_m;
        assert!((cmd.start_robot_m - expected_start).norm() < 1e-6);
        // The camera's x axis is the robot's x axis (rotations are about x only).
        assert!((cmd.direction_robot - Vector3::x()).norm() < 1e-6);
        assert!((cmd.end_robot_m() - (expected_start + Vector3::x() * 0.02)).norm() < 1e-6);
        // Not the identity: the start moved from camera to robot coordinates.
        assert!((cmd.start_robot_m.coords - p.start_cam_m.coords).norm() > 0.1);
    }

    #[test]
    fn pushes_outside_limits_are_refused_with_a_clear_message() {
        let t = robot_from_camera();
        let far = push_at(
            Point3::new(0.0, 0.0, 2.0),
            Vector3::new(1.0, 0.0, 0.0),
            0.02,
        );
        let err = plan_push(&far, &t, &limits()).unwrap_err();
        assert!(matches!(
            err,
            PushRefused::OutsideWorkspace { which: "start", .. }
        ));
        assert!(err.to_string().contains("outside the workspace"), "{err}");
        let long = push_at(
            Point3::new(0.0, 0.0, 0.58),
            Vector3::new(1.0, 0.0, 0.0),
            0.2,
        );
        assert_eq!(
            plan_push(&long, &t, &limits()),
            Err(PushRefused::TooLong {
                length_m: 0.2,
                limit_m: 0.05
            })
        );
        let nan = push_at(
            Point3::new(f32::NAN, 0.0, 0.58),
            Vector3::new(1.0, 0.0, 0.0),
            0.02,
        );
        assert_eq!(plan_push(&nan, &t, &limits()), Err(PushRefused::NotFinite));
        // Ends outside: start near the +x edge, pushing further out.
        let start_cam = t.inverse() * Point3::new(0.79, 0.0, 0.05);
        let out = push_at(start_cam, t.inverse().rotation * Vector3::x(), 0.02);
        assert!(matches!(
            plan_push(&out, &t, &limits()),
            Err(PushRefused::OutsideWorkspace { which: "end", .. })
        ));
    }
}
