//! Panda kinematics and the joint-space check of a planned push.
//!
//! # Contract
//!
//! - [`flange_pose`] is the Panda's forward kinematics from Franka's published modified
//!   (Craig) Denavit–Hartenberg table ([`PANDA_DH`], [`FLANGE_D_M`]); [`ee_pose`] appends
//!   the robot's flange-to-end-effector transform `F_T_EE` (from the robot state, as Desk
//!   configured it), the frame of the commanded `O_T_EE` poses; [`jacobian`] is the 6x7
//!   geometric Jacobian of that end effector in the base frame.
//! - [`check`] tracks a planned 1 kHz path from the robot's measured joint positions with
//!   damped-least-squares differential IK, joint 3 (the elbow's position) held
//!   ([`HELD_JOINT`]: the driver commands no elbow, so the robot resolves the redundancy
//!   itself; holding the elbow is this check's assumption), and refuses, never clips: a
//!   start pose the kinematics do not reproduce within [`START_TOL_M`] / [`START_TOL_RAD`]
//!   (not a Panda, or another end effector), a sample the IK cannot reach within
//!   [`TRACK_TOL_M`] / [`TRACK_TOL_RAD`], and any joint position, velocity,
//!   acceleration or jerk (backward differences, at rest before and after) at or beyond
//!   the Panda's published limits. A refusal names the joint, the sample's time, the value
//!   and the limit.
//!
//! Sources: "Robot and interface specifications" of the Franka Control Interface
//! documentation (frankaemika.github.io/docs/control_parameters.html), whose tables are
//! github.com/frankaemika/docs `source/dh-parameters.csv` (commit 2a134dd: the Denavit–
//! Hartenberg parameters in Craig's convention, flange row included) and
//! `source/control-parameters-joint-panda.csv` (commit cda9283: "Limits for Panda").
//! libfranka's `include/franka/rate_limiting.h` (0.9, the release speaking this client's
//! protocol) has the same velocity, acceleration and jerk limits less its own margins.
//! These are the Panda's (Franka Emika Robot); the Franka Research 3 has other joint
//! limits and needs another protocol version.

use nalgebra::{Matrix4, Matrix6, Matrix6x1, Point3, Rotation3, SMatrix, Vector3};

use super::trajectory::DT_S;

/// A 6x7 geometric Jacobian: linear (m/s) then angular (rad/s) velocity per joint rate.
pub type Jacobian = SMatrix<f64, 6, 7>;

/// Modified DH parameters `[a_m, d_m, alpha_rad]` of joints 1 to 7 (`a` and `alpha` of
/// the previous link, Craig's convention; module docs for the source).
pub const PANDA_DH: [[f64; 3]; 7] = [
    [0.0, 0.333, 0.0],
    [0.0, 0.0, -core::f64::consts::FRAC_PI_2],
    [0.0, 0.316, core::f64::consts::FRAC_PI_2],
    [0.0825, 0.0, core::f64::consts::FRAC_PI_2],
    [-0.0825, 0.384, -core::f64::consts::FRAC_PI_2],
    [0.0, 0.0, core::f64::consts::FRAC_PI_2],
    [0.088, 0.0, core::f64::consts::FRAC_PI_2],
];
/// The flange's offset along joint 7's axis, metres (the table's "Flange" row).
pub const FLANGE_D_M: f64 = 0.107;

/// Panda joint position upper limits, rad ("Limits for Panda", `q_max`).
pub const PANDA_Q_MAX_RAD: [f64; 7] = [2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973];
/// Panda joint position lower limits, rad (`q_min`).
pub const PANDA_Q_MIN_RAD: [f64; 7] = [
    -2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973,
];
/// Panda joint velocity limits, rad/s (`q̇_max`).
pub const PANDA_DQ_MAX_RAD_PER_S: [f64; 7] =
    [2.1750, 2.1750, 2.1750, 2.1750, 2.6100, 2.6100, 2.6100];
/// Panda joint acceleration limits, rad/s² (`q̈_max`).
pub const PANDA_DDQ_MAX_RAD_PER_S2: [f64; 7] = [15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0];
/// Panda joint jerk limits, rad/s³ (`q⃛_max`).
pub const PANDA_DDDQ_MAX_RAD_PER_S3: [f64; 7] =
    [7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0];

/// The joint (0-based: joint 3) the check holds: FCI's elbow is joint 3's position and
/// the sign of joint 4 (libfranka `RobotState::elbow`); with it fixed the other six joints
/// follow from the pose.
pub const HELD_JOINT: usize = 2;
/// Largest position error of a tracked sample, metres.
pub const TRACK_TOL_M: f64 = 1e-4;
/// Largest orientation error of a tracked sample, rad.
pub const TRACK_TOL_RAD: f64 = 1e-3;
/// Largest distance between the kinematics' and the robot's reported start position, metres.
pub const START_TOL_M: f64 = 1e-3;
/// Largest angle between the kinematics' and the robot's reported start orientation, rad.
pub const START_TOL_RAD: f64 = 1e-2;
/// Damping of the least-squares step (metres and radians mixed, as usual).
const DAMPING: f64 = 1e-3;
/// Position residual at which a sample's Newton steps stop, metres: at 1 kHz, a position
/// noise of 1e-10 m is a jerk noise under 1 m/s³.
const CONVERGED_M: f64 = 1e-10;
/// Orientation residual at which a sample's Newton steps stop, rad.
const CONVERGED_RAD: f64 = 1e-9;
/// Newton steps per sample at most.
const MAX_STEPS: usize = 20;

/// Why the joints refuse a path.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JointRefused {
    /// The Panda kinematics at the measured joints do not give the robot's reported pose.
    #[error(
        "the Panda kinematics at the measured joint positions put the end effector \
         {position_m:.4} m and {rotation_rad:.4} rad from the robot's reported pose \
         (not a Panda, or an end effector other than the robot's F_T_EE?)"
    )]
    StartMismatch {
        /// Position disagreement, metres.
        position_m: f64,
        /// Orientation disagreement, rad.
        rotation_rad: f64,
    },
    /// Differential IK could not follow the path.
    #[error(
        "the path is not reachable: at t = {time_s:.3} s the arm stays {position_m:.5} m \
         and {rotation_rad:.5} rad from the commanded pose"
    )]
    Unreachable {
        /// The sample's time from the start of the push, seconds.
        time_s: f64,
        /// Position error, metres.
        position_m: f64,
        /// Orientation error, rad.
        rotation_rad: f64,
    },
    /// A joint breaks one of its limits.
    #[error(
        "joint {joint} {what} {value:.4} at t = {time_s:.3} s is beyond the Panda's limit \
         {limit:.4}"
    )]
    Limit {
        /// The joint, 1 to 7.
        joint: usize,
        /// `"position (rad)"`, `"velocity (rad/s)"`, `"acceleration (rad/s²)"` or
        /// `"jerk (rad/s³)"`.
        what: &'static str,
        /// The sample's time from the start of the push, seconds.
        time_s: f64,
        /// The value.
        value: f64,
        /// The limit it reaches or passes (a rate limit with the value's sign).
        limit: f64,
    },
}

/// One modified-DH link transform: `RotX(alpha) · TransX(a) · RotZ(theta) · TransZ(d)`.
fn link(a_m: f64, d_m: f64, alpha_rad: f64, theta_rad: f64) -> Matrix4<f64> {
    let (sa, ca) = alpha_rad.sin_cos();
    let (st, ct) = theta_rad.sin_cos();
    Matrix4::new(
        ct,
        -st,
        0.0,
        a_m,
        st * ca,
        ct * ca,
        -sa,
        -sa * d_m,
        st * sa,
        ct * sa,
        ca,
        ca * d_m,
        0.0,
        0.0,
        0.0,
        1.0,
    )
}

/// The base-frame poses of joint frames 1 to 7 (each rotating about its own z).
fn joint_frames(q_rad: &[f64; 7]) -> [Matrix4<f64>; 7] {
    let mut t = Matrix4::identity();
    core::array::from_fn(|i| {
        let [a, d, alpha] = PANDA_DH[i];
        t *= link(a, d, alpha, q_rad[i]);
        t
    })
}

/// The flange pose `O_T_F` at joint positions `q_rad`, base frame, metres.
#[must_use]
pub fn flange_pose(q_rad: &[f64; 7]) -> Matrix4<f64> {
    joint_frames(q_rad)[6] * link(0.0, FLANGE_D_M, 0.0, 0.0)
}

/// The end-effector pose `O_T_EE = O_T_F · F_T_EE`.
#[must_use]
pub fn ee_pose(q_rad: &[f64; 7], f_t_ee: &Matrix4<f64>) -> Matrix4<f64> {
    flange_pose(q_rad) * f_t_ee
}

/// The geometric Jacobian of the end effector, base frame: rows linear velocity (m/s) then
/// angular velocity (rad/s), one column per joint.
#[must_use]
pub fn jacobian(q_rad: &[f64; 7], f_t_ee: &Matrix4<f64>) -> Jacobian {
    let frames = joint_frames(q_rad);
    let ee = frames[6] * link(0.0, FLANGE_D_M, 0.0, 0.0) * f_t_ee;
    let p_ee = translation(&ee);
    let mut j = Jacobian::zeros();
    for (i, f) in frames.iter().enumerate() {
        let z = f.fixed_view::<3, 1>(0, 2).into_owned();
        let linear = z.cross(&(p_ee - translation(f)));
        j.fixed_view_mut::<3, 1>(0, i).copy_from(&linear);
        j.fixed_view_mut::<3, 1>(3, i).copy_from(&z);
    }
    j
}

/// `error <= tol`, false for NaN.
fn within(error: f64, tol: f64) -> bool {
    error <= tol
}

fn translation(m: &Matrix4<f64>) -> Vector3<f64> {
    m.fixed_view::<3, 1>(0, 3).into_owned()
}

fn rotation(m: &Matrix4<f64>) -> Rotation3<f64> {
    Rotation3::from_matrix_unchecked(m.fixed_view::<3, 3>(0, 0).into_owned())
}

/// The rotation vector (axis times angle, rad) of `r`, accurate for small angles (where
/// an angle from the trace alone loses half the digits).
fn rotation_vector(r: &Rotation3<f64>) -> Vector3<f64> {
    let m = r.matrix();
    let sin_axis = Vector3::new(
        m[(2, 1)] - m[(1, 2)],
        m[(0, 2)] - m[(2, 0)],
        m[(1, 0)] - m[(0, 1)],
    ) * 0.5;
    let sin = sin_axis.norm();
    let cos = (m.trace() - 1.0) * 0.5;
    if sin > 1e-9 {
        sin_axis * (sin.atan2(cos) / sin)
    } else if cos > 0.0 {
        sin_axis
    } else {
        // Half a turn: the axis from the trace is well conditioned there.
        r.scaled_axis()
    }
}

/// The pose error taking `from` to `to`: translation (m) and rotation vector (rad), base frame.
fn pose_error(from: &Matrix4<f64>, to: &Matrix4<f64>) -> Matrix6x1<f64> {
    let dp = translation(to) - translation(from);
    let dr = rotation_vector(&(rotation(to) * rotation(from).inverse()));
    Matrix6x1::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}

/// Follows `targets` (end-effector poses, one per millisecond) from `q0_rad` by damped
/// least squares with [`HELD_JOINT`] fixed; the joint positions of every sample.
///
/// # Errors
/// [`JointRefused::Unreachable`] at the first sample left farther than the tolerances.
fn track(
    q0_rad: &[f64; 7],
    f_t_ee: &Matrix4<f64>,
    targets: impl Iterator<Item = Matrix4<f64>>,
) -> Result<Vec<[f64; 7]>, JointRefused> {
    let moving: [usize; 6] = core::array::from_fn(|k| if k < HELD_JOINT { k } else { k + 1 });
    let mut q = *q0_rad;
    let mut out = Vec::new();
    for (index, target) in targets.enumerate() {
        let mut e = pose_error(&ee_pose(&q, f_t_ee), &target);
        for _ in 0..MAX_STEPS {
            // Far below the tolerances: the residual is noise in the finite differences.
            if e.fixed_rows::<3>(0).norm() < CONVERGED_M
                && e.fixed_rows::<3>(3).norm() < CONVERGED_RAD
            {
                break;
            }
            let full = jacobian(&q, f_t_ee);
            let j = Matrix6::from_fn(|r, c| full[(r, moving[c])]);
            let jjt = j * j.transpose() + Matrix6::identity() * (DAMPING * DAMPING);
            let Some(step) = jjt.cholesky().map(|c| j.transpose() * c.solve(&e)) else {
                break;
            };
            for (k, &i) in moving.iter().enumerate() {
                q[i] += step[k];
            }
            e = pose_error(&ee_pose(&q, f_t_ee), &target);
        }
        let (position_m, rotation_rad) = (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm());
        if !within(position_m, TRACK_TOL_M) || !within(rotation_rad, TRACK_TOL_RAD) {
            return Err(JointRefused::Unreachable {
                time_s: index as f64 * DT_S,
                position_m,
                rotation_rad,
            });
        }
        out.push(q);
    }
    Ok(out)
}

/// Checks joint positions sampled at 1 kHz against the Panda's limits (module docs).
///
/// # Errors
/// [`JointRefused::Limit`] for the first sample and joint that breaks one.
pub fn check_limits(q0_rad: &[f64; 7], path_rad: &[[f64; 7]]) -> Result<(), JointRefused> {
    // The arm is at rest at q0 before the path and at its last sample after it.
    let last = path_rad.last().unwrap_or(q0_rad);
    let at = |i: isize| -> &[f64; 7] {
        if i < 0 {
            q0_rad
        } else {
            path_rad.get(i as usize).unwrap_or(last)
        }
    };
    for i in 0..(path_rad.len() + 3) as isize {
        let x: [&[f64; 7]; 4] = core::array::from_fn(|k| at(i - k as isize));
        let time_s = i as f64 * DT_S;
        for joint in 0..7 {
            let [q, q1, q2, q3] = x.map(|s| s[joint]);
            let refuse = |what, value, limit| JointRefused::Limit {
                joint: joint + 1,
                what,
                time_s,
                value,
                limit,
            };
            if q.is_nan() || q >= PANDA_Q_MAX_RAD[joint] {
                return Err(refuse("position (rad)", q, PANDA_Q_MAX_RAD[joint]));
            }
            if q <= PANDA_Q_MIN_RAD[joint] {
                return Err(refuse("position (rad)", q, PANDA_Q_MIN_RAD[joint]));
            }
            for (what, value, limit) in [
                (
                    "velocity (rad/s)",
                    (q - q1) / DT_S,
                    PANDA_DQ_MAX_RAD_PER_S[joint],
                ),
                (
                    "acceleration (rad/s²)",
                    (q - 2.0 * q1 + q2) / (DT_S * DT_S),
                    PANDA_DDQ_MAX_RAD_PER_S2[joint],
                ),
                (
                    "jerk (rad/s³)",
                    (q - 3.0 * q1 + 3.0 * q2 - q3) / (DT_S * DT_S * DT_S),
                    PANDA_DDDQ_MAX_RAD_PER_S3[joint],
                ),
            ] {
                if value.is_nan() || value.abs() >= limit {
                    // Signed like the value: "-12.66 beyond the limit -12.5".
                    return Err(refuse(what, value, limit.copysign(value)));
                }
            }
        }
    }
    Ok(())
}

/// Checks a planned push in joint space (module docs): from the measured joints `q0_rad`,
/// the robot's `F_T_EE` and its measured pose `o_t_ee`, the end-effector positions
/// `positions_m` commanded with the start orientation held: sample `k` is tracked as the
/// start pose moved by `positions_m[k] - positions_m[0]`. Returns the joint positions of
/// every sample.
///
/// # Errors
/// [`JointRefused`] naming the first problem.
pub fn check(
    q0_rad: &[f64; 7],
    f_t_ee: &Matrix4<f64>,
    o_t_ee: &Matrix4<f64>,
    positions_m: &[Point3<f64>],
) -> Result<Vec<[f64; 7]>, JointRefused> {
    let start = ee_pose(q0_rad, f_t_ee);
    let e = pose_error(&start, o_t_ee);
    let (position_m, rotation_rad) = (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm());
    if !within(position_m, START_TOL_M) || !within(rotation_rad, START_TOL_RAD) {
        return Err(JointRefused::StartMismatch {
            position_m,
            rotation_rad,
        });
    }
    let Some(&first) = positions_m.first() else {
        return Ok(Vec::new());
    };
    let targets = positions_m.iter().map(|p| {
        let mut t = start;
        let at = translation(&start) + (p - first);
        t.fixed_view_mut::<3, 1>(0, 3).copy_from(&at);
        t
    });
    let path = track(q0_rad, f_t_ee, targets)?;
    check_limits(q0_rad, &path)?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use core::f64::consts::{FRAC_1_SQRT_2, FRAC_PI_2, FRAC_PI_4};

    use super::*;

    /// Franka's ready pose.
    const READY_RAD: [f64; 7] = [
        0.0,
        -FRAC_PI_4,
        0.0,
        -3.0 * FRAC_PI_4,
        0.0,
        FRAC_PI_2,
        FRAC_PI_4,
    ];

    /// The Franka Hand's `F_T_EE`: 10.34 cm along the flange's z, turned -45° about it.
    fn hand() -> Matrix4<f64> {
        let mut t = Rotation3::from_axis_angle(&Vector3::z_axis(), -FRAC_PI_4).to_homogeneous();
        t[(2, 3)] = 0.1034;
        t
    }

    fn assert_close(a: &Matrix4<f64>, b: &Matrix4<f64>, tol: f64) {
        assert!((a - b).abs().max() < tol, "{a} vs {b}");
    }

    /// A straight move of the end effector by `by_m` from its pose at `q0`, quintic in time
    /// over `duration_s`: 1 kHz positions.
    fn straight(q0: &[f64; 7], by_m: Vector3<f64>, duration_s: f64) -> Vec<Point3<f64>> {
        let from = Point3::from(translation(&ee_pose(q0, &hand())));
        let steps = (duration_s / DT_S).round() as usize;
        (0..=steps)
            .map(|k| {
                let tau = k as f64 / steps as f64;
                from + by_m * (tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau))
            })
            .collect()
    }

    /// A matrix from its rows.
    fn rows(r: [[f64; 4]; 4]) -> Matrix4<f64> {
        Matrix4::from_fn(|i, j| r[i][j])
    }

    #[test]
    fn forward_kinematics_match_the_urdf_chain() {
        // Reference values from an independent chain: the joint origins (xyz, rpy) of
        // franka_description's panda_arm URDF, each joint turning about its own z, the
        // flange 0.107 m along joint 7's z (numpy, not this module's DH table).
        let h = FRAC_1_SQRT_2;
        let ready = rows([
            [h, -h, 0.0, 0.306_890_566_6],
            [-h, -h, 0.0, 0.0],
            [0.0, 0.0, -1.0, 0.590_282_052_3],
            [0.0, 0.0, 0.0, 1.0],
        ]);
        assert_close(&flange_pose(&READY_RAD), &ready, 1e-9);
        let q = [0.3, -0.5, 0.4, -2.0, 0.6, 1.8, -0.7];
        let other = rows([
            [0.2549226532, 0.9663209147, -0.0351899221, 0.2684956427],
            [0.8589856709, -0.2095955139, 0.4671331049, 0.3478365036],
            [0.4440248394, -0.1493104494, -0.8834864638, 0.6685770374],
            [0.0, 0.0, 0.0, 1.0],
        ]);
        assert_close(&flange_pose(&q), &other, 1e-9);
        // With the hand: the tool points straight down at (0.3069, 0, 0.4869).
        let ee = rows([
            [1.0, 0.0, 0.0, 0.306_890_566_6],
            [0.0, -1.0, 0.0, 0.0],
            [0.0, 0.0, -1.0, 0.486_882_052_3],
            [0.0, 0.0, 0.0, 1.0],
        ]);
        assert_close(&ee_pose(&READY_RAD, &hand()), &ee, 1e-9);
    }

    #[test]
    fn the_jacobian_is_the_derivative_of_the_pose() {
        let q = [0.3, -0.5, 0.4, -2.0, 0.6, 1.8, -0.7];
        let j = jacobian(&q, &hand());
        let h = 1e-6;
        for i in 0..7 {
            let mut plus = q;
            plus[i] += h;
            let mut minus = q;
            minus[i] -= h;
            let d = pose_error(&ee_pose(&minus, &hand()), &ee_pose(&plus, &hand())) / (2.0 * h);
            assert!(
                (d - j.column(i)).norm() < 1e-6,
                "column {i}: {d} vs {}",
                j.column(i)
            );
        }
    }

    #[test]
    fn a_short_straight_push_from_ready_is_tracked_within_the_limits() {
        let f_t_ee = hand();
        let start = ee_pose(&READY_RAD, &f_t_ee);
        let positions = straight(&READY_RAD, Vector3::new(0.0, 0.05, -0.03), 0.5);
        let path = check(&READY_RAD, &f_t_ee, &start, &positions).unwrap();
        assert_eq!(path.len(), positions.len());
        for (q, p) in path.iter().zip(&positions) {
            let at = ee_pose(q, &f_t_ee);
            assert!((translation(&at) - p.coords).norm() <= TRACK_TOL_M);
            let turned = rotation_vector(&(rotation(&at) * rotation(&start).inverse())).norm();
            assert!(turned <= TRACK_TOL_RAD, "{turned}");
            assert!((q[HELD_JOINT] - READY_RAD[HELD_JOINT]).abs() < 1e-15);
        }
        // The arm moved: joint 1 turned towards +y.
        let last = path.last().unwrap();
        assert!(last[0] > 0.05, "{last:?}");
    }

    #[test]
    fn a_push_that_turns_joint_1_past_its_limit_is_refused() {
        // Ready, but turned 2.8 rad about the base; 5 cm along the tool's circle about the
        // base turns joint 1 by about 0.16 rad, past q_max = 2.8973.
        let mut q0 = READY_RAD;
        q0[0] = 2.8;
        let tangent = Vector3::new(-q0[0].sin(), q0[0].cos(), 0.0);
        let positions = straight(&q0, tangent * 0.05, 2.0);
        let start = ee_pose(&q0, &hand());
        let err = check(&q0, &hand(), &start, &positions).unwrap_err();
        let JointRefused::Limit {
            joint,
            what,
            value,
            limit,
            time_s,
        } = err.clone()
        else {
            panic!("{err}");
        };
        assert_eq!((joint, what, limit), (1, "position (rad)", 2.8973), "{err}");
        assert!(
            value >= limit && value < limit + 1e-3 && time_s > 0.5,
            "{err}"
        );
        let text = err.to_string();
        assert!(
            text.contains("joint 1 position") && text.contains("2.8973"),
            "{text}"
        );
        // The same push the other way turns joint 1 away from its limit.
        let back = straight(&q0, -tangent * 0.05, 2.0);
        check(&q0, &hand(), &start, &back).unwrap();
    }

    #[test]
    fn an_unreachable_pose_is_refused() {
        let start = ee_pose(&READY_RAD, &hand());
        let positions = straight(&READY_RAD, Vector3::new(0.8, 0.0, 0.0), 5.0);
        let err = check(&READY_RAD, &hand(), &start, &positions).unwrap_err();
        assert!(
            matches!(err, JointRefused::Unreachable { time_s, .. } if time_s > 0.5),
            "{err}"
        );
        assert!(err.to_string().contains("not reachable"), "{err}");
    }

    #[test]
    fn a_reported_pose_the_kinematics_do_not_give_is_refused() {
        let mut reported = ee_pose(&READY_RAD, &hand());
        reported[(2, 3)] += 0.01;
        let positions = straight(&READY_RAD, Vector3::new(0.0, 0.01, 0.0), 0.2);
        let err = check(&READY_RAD, &hand(), &reported, &positions).unwrap_err();
        assert!(matches!(err, JointRefused::StartMismatch { .. }), "{err}");
    }

    #[test]
    fn joint_velocity_acceleration_and_jerk_limits_are_checked_at_1_khz() {
        let q0 = READY_RAD;
        let ramp = |per_sample: [f64; 7], n: usize| -> Vec<[f64; 7]> {
            (1..=n)
                .map(|k| core::array::from_fn(|j| q0[j] + per_sample[j] * k as f64))
                .collect()
        };
        // Joint 5 at 3 rad/s from the first sample: velocity past 2.61 rad/s.
        let mut step = [0.0; 7];
        step[4] = 3e-3;
        let err = check_limits(&q0, &ramp(step, 10)).unwrap_err();
        let JointRefused::Limit {
            joint: 5,
            what: "velocity (rad/s)",
            value,
            ..
        } = err
        else {
            panic!("{err}");
        };
        assert!((value - 3.0).abs() < 1e-9, "{err}");
        assert_eq!(
            err.to_string(),
            "joint 5 velocity (rad/s) 3.0000 at t = 0.000 s is beyond the Panda's limit 2.6100"
        );
        // Joint 2 at 2 rad/s (under its velocity limit), reached in one millisecond: the
        // acceleration (2000 rad/s²) breaks 7.5 rad/s².
        let mut step = [0.0; 7];
        step[1] = 2e-3;
        let err = check_limits(&q0, &ramp(step, 10)).unwrap_err();
        assert!(
            matches!(
                err,
                JointRefused::Limit {
                    joint: 2,
                    what: "acceleration (rad/s²)",
                    ..
                }
            ),
            "{err}"
        );
        // Joint 2 jumping from rest into 7.6 rad/s² within a millisecond: a jerk of
        // 3800 rad/s³, past 3750, while the acceleration is still 3.8 rad/s² at that sample.
        let path: Vec<[f64; 7]> = (1..=100)
            .map(|k| {
                let t_s = k as f64 * DT_S;
                core::array::from_fn(|j| q0[j] + if j == 1 { 3.8 * t_s * t_s } else { 0.0 })
            })
            .collect();
        let err = check_limits(&q0, &path).unwrap_err();
        assert!(
            matches!(
                err,
                JointRefused::Limit {
                    joint: 2,
                    what: "jerk (rad/s³)",
                    ..
                }
            ),
            "{err}"
        );
        // The same gently: a quintic 0.1 rad over 2 s on every joint passes.
        let path: Vec<[f64; 7]> = (1..=2000)
            .map(|k| {
                let tau = k as f64 / 2000.0;
                let s = tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau);
                core::array::from_fn(|j| q0[j] + 0.1 * s)
            })
            .collect();
        check_limits(&q0, &path).unwrap();
    }
}
