//! A push as a Cartesian path sampled at the FCI's 1 kHz, and its checks.
//!
//! # Contract
//!
//! [`plan`] turns a [`PushCommand`] into the tool-centre positions commanded every
//! millisecond (orientation held): from where the tool is (`home`), straight to
//! [`MotionLimits::hover_m`] above the push start, descend to the start, push to the end,
//! lift to the hover height, and return straight to `home` (out of the camera's view).
//! Each segment is a straight line with a quintic time scaling (zero velocity and
//! acceleration at both ends), as short in time as [`MotionLimits`] allows.
//!
//! Before anything moves, [`check`] refuses, never clips:
//! - a descend, push or lift sample outside the workspace box ([`PushLimits`]);
//! - a sample whose finite-difference velocity, acceleration or jerk exceeds Franka's
//!   published Cartesian limits ([`FRANKA_MAX_VEL_M_PER_S`], [`FRANKA_MAX_ACC_M_PER_S2`],
//!   [`FRANKA_MAX_JERK_M_PER_S3`]) or the tighter [`MotionLimits`].
//!
//! The transit segments (home to hover, hover to home) are not boxed: the arm starts at a
//! pose the user chose, usually above the workspace; they pass at or above the hover
//! height over the push.

use nalgebra::{Point3, Vector3};

use crate::rig::robot::{PushCommand, PushLimits};

/// Franka's control period, seconds (1 kHz).
pub const DT_S: f64 = 1e-3;
/// Franka Emika Panda, Cartesian translational velocity limit, m/s ("Robot and interface
/// specifications", Franka Control Interface documentation, frankaemika.github.io/docs:
/// `ṗ_max = 1.7 m/s`).
pub const FRANKA_MAX_VEL_M_PER_S: f64 = 1.7;
/// The same page: `p̈_max = 13.0 m/s²`.
pub const FRANKA_MAX_ACC_M_PER_S2: f64 = 13.0;
/// The same page: `p⃛_max = 6500.0 m/s³`.
pub const FRANKA_MAX_JERK_M_PER_S3: f64 = 6500.0;

/// Peak of `s'`, `s''`, `s'''` of the quintic `10τ³ − 15τ⁴ + 6τ⁵` on `[0, 1]`.
const QUINTIC_PEAK_VEL: f64 = 1.875;
const QUINTIC_PEAK_ACC: f64 = 5.773_502_7;
const QUINTIC_PEAK_JERK: f64 = 60.0;

/// How fast a push may be, and how high the tool travels over the objects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionLimits {
    /// Fastest tool speed, m/s.
    pub max_vel_m_per_s: f64,
    /// Largest acceleration, m/s².
    pub max_acc_m_per_s2: f64,
    /// Largest jerk, m/s³.
    pub max_jerk_m_per_s3: f64,
    /// Height of the approach and lift above the push line, metres.
    pub hover_m: f64,
}

impl Default for MotionLimits {
    /// Gentle: 5 cm/s, 0.5 m/s², 50 m/s³, approach from 10 cm above.
    fn default() -> Self {
        Self {
            max_vel_m_per_s: 0.05,
            max_acc_m_per_s2: 0.5,
            max_jerk_m_per_s3: 50.0,
            hover_m: 0.10,
        }
    }
}

/// A planned push: positions at 1 kHz and which samples are the push itself.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Tool-centre positions, robot frame, metres, one per millisecond.
    pub positions_m: Vec<Point3<f64>>,
    /// Index range of the descend, push and lift segments (boxed by the workspace).
    pub boxed: core::ops::Range<usize>,
}

/// Why a trajectory was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MotionRefused {
    /// A [`MotionLimits`] value is not positive and finite or exceeds Franka's limit.
    #[error("{0}")]
    Limits(String),
    /// A sample leaves the workspace.
    #[error(
        "sample {index} at ({:.3}, {:.3}, {:.3}) m is outside the workspace", point[0], point[1], point[2]
    )]
    OutsideWorkspace {
        /// The sample.
        index: usize,
        /// Where, robot frame, metres.
        point: [f64; 3],
    },
    /// A finite difference exceeds a limit.
    #[error("sample {index}: {what} {value:.4} exceeds the limit {limit:.4}")]
    Exceeds {
        /// The sample.
        index: usize,
        /// `"velocity (m/s)"`, `"acceleration (m/s²)"` or `"jerk (m/s³)"`.
        what: &'static str,
        /// The value.
        value: f64,
        /// The limit.
        limit: f64,
    },
}

impl MotionLimits {
    /// Checks the limits are positive, finite and within Franka's.
    ///
    /// # Errors
    /// [`MotionRefused::Limits`] naming the value.
    pub fn validate(&self) -> Result<(), MotionRefused> {
        for (name, v, franka) in [
            (
                "max_vel_m_per_s",
                self.max_vel_m_per_s,
                FRANKA_MAX_VEL_M_PER_S,
            ),
            (
                "max_acc_m_per_s2",
                self.max_acc_m_per_s2,
                FRANKA_MAX_ACC_M_PER_S2,
            ),
            (
                "max_jerk_m_per_s3",
                self.max_jerk_m_per_s3,
                FRANKA_MAX_JERK_M_PER_S3,
            ),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= franka) {
                return Err(MotionRefused::Limits(format!(
                    "{name} = {v} must be positive and at most Franka's published {franka}"
                )));
            }
        }
        if !(self.hover_m.is_finite() && self.hover_m > 0.0) {
            return Err(MotionRefused::Limits(format!(
                "hover_m = {} must be positive",
                self.hover_m
            )));
        }
        Ok(())
    }
}

/// Appends a straight segment from the last sample to `to` (module docs).
fn segment(out: &mut Vec<Point3<f64>>, to: Point3<f64>, m: &MotionLimits) {
    let Some(&from) = out.last() else {
        out.push(to);
        return;
    };
    let len = (to - from).norm();
    if len == 0.0 {
        return;
    }
    let t_s = (QUINTIC_PEAK_VEL * len / m.max_vel_m_per_s)
        .max((QUINTIC_PEAK_ACC * len / m.max_acc_m_per_s2).sqrt())
        .max((QUINTIC_PEAK_JERK * len / m.max_jerk_m_per_s3).cbrt());
    let steps = (t_s / DT_S).ceil().max(1.0) as usize;
    for k in 1..=steps {
        let tau = k as f64 / steps as f64;
        let s = tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau);
        out.push(from + (to - from) * s);
    }
}

/// Plans the push `cmd` from the tool position `home` (module docs).
///
/// # Errors
/// [`MotionRefused::Limits`] for invalid [`MotionLimits`].
pub fn plan(
    home: Point3<f64>,
    cmd: &PushCommand,
    m: &MotionLimits,
) -> Result<Trajectory, MotionRefused> {
    m.validate()?;
    let start = cmd.start_robot_m.cast::<f64>();
    let end = cmd.end_robot_m().cast::<f64>();
    let up = Vector3::z() * m.hover_m;
    let mut p = vec![home];
    segment(&mut p, start + up, m);
    let boxed_from = p.len();
    for to in [start, end, end + up] {
        segment(&mut p, to, m);
    }
    let boxed = boxed_from..p.len();
    segment(&mut p, home, m);
    Ok(Trajectory {
        positions_m: p,
        boxed,
    })
}

/// Checks `traj` against the workspace, `m` and Franka's limits (module docs).
///
/// # Errors
/// [`MotionRefused`] for the first sample that breaks a rule.
pub fn check(
    traj: &Trajectory,
    limits: &PushLimits,
    m: &MotionLimits,
) -> Result<(), MotionRefused> {
    let p = &traj.positions_m;
    for i in traj.boxed.clone() {
        let q = p[i];
        let inside = (0..3).all(|a| {
            q[a] >= f64::from(limits.workspace_min_m[a])
                && q[a] <= f64::from(limits.workspace_max_m[a])
        });
        if !inside || !q.coords.iter().all(|v| v.is_finite()) {
            return Err(MotionRefused::OutsideWorkspace {
                index: i,
                point: [q.x, q.y, q.z],
            });
        }
    }
    // Velocity, acceleration and jerk by backward differences; the arm is at rest before
    // the first sample and after the last.
    let at = |i: isize| -> Point3<f64> {
        let last = p.len() as isize - 1;
        p[i.clamp(0, last) as usize]
    };
    let bounds = [
        (
            "velocity (m/s)",
            m.max_vel_m_per_s.min(FRANKA_MAX_VEL_M_PER_S),
        ),
        (
            "acceleration (m/s²)",
            m.max_acc_m_per_s2.min(FRANKA_MAX_ACC_M_PER_S2),
        ),
        (
            "jerk (m/s³)",
            m.max_jerk_m_per_s3.min(FRANKA_MAX_JERK_M_PER_S3),
        ),
    ];
    for i in 0..(p.len() + 3) as isize {
        let x: [Point3<f64>; 4] = core::array::from_fn(|k| at(i - k as isize));
        let v = (x[0] - x[1]).norm() / DT_S;
        let a = (x[0] - 2.0 * x[1].coords + x[2].coords).coords.norm() / (DT_S * DT_S);
        let j = (x[0].coords - 3.0 * x[1].coords + 3.0 * x[2].coords - x[3].coords).norm()
            / (DT_S * DT_S * DT_S);
        for ((what, limit), value) in bounds.iter().zip([v, a, j]) {
            // 1 % over the continuous bound: finite differences of a sampled quintic.
            if value > limit * 1.01 {
                return Err(MotionRefused::Exceeds {
                    index: i as usize,
                    what,
                    value,
                    limit: *limit,
                });
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> PushLimits {
        PushLimits {
            workspace_min_m: [0.3, -0.2, 0.0],
            workspace_max_m: [0.7, 0.2, 0.25],
            max_push_len_m: 0.06,
        }
    }

    fn push(x: f32) -> PushCommand {
        PushCommand {
            start_robot_m: Point3::new(x, 0.0, 0.02),
            direction_robot: Vector3::y(),
            length_m: 0.03,
        }
    }

    #[test]
    fn the_path_hovers_descends_pushes_lifts_and_returns_within_every_limit() {
        let m = MotionLimits::default();
        let home = Point3::new(0.45, 0.0, 0.4);
        let t = plan(home, &push(0.5), &m).unwrap();
        check(&t, &limits(), &m).unwrap();
        let p = &t.positions_m;
        assert_eq!(p[0], home);
        assert!((p[p.len() - 1] - home).norm() < 1e-12);
        let start = p[t.boxed.start - 1];
        assert!(
            (start - Point3::new(0.5, 0.0, 0.12)).norm() < 1e-6,
            "{start}"
        );
        // The push line itself is level at z = 0.02 and 3 cm long in +y.
        let low: Vec<_> = p[t.boxed.clone()]
            .iter()
            .filter(|q| (q.z - 0.02).abs() < 1e-6)
            .collect();
        let y = low.iter().map(|q| q.y).fold(f64::NEG_INFINITY, f64::max);
        assert!((y - 0.03).abs() < 1e-6, "{y}");
        // Gentle: the push takes about 1.875 · 3 cm / 5 cm/s = 1.1 s.
        assert!(low.len() > 1000, "{}", low.len());
    }

    #[test]
    fn out_of_box_pushes_and_fast_paths_are_refused_not_clipped() {
        let m = MotionLimits::default();
        let t = plan(Point3::new(0.45, 0.0, 0.4), &push(0.69), &m).unwrap();
        // Start inside, hover 10 cm up at z 0.12 inside, but the box ends at x 0.7 and the
        // push is in y: make the box lower than the hover instead.
        let low_box = PushLimits {
            workspace_max_m: [0.7, 0.2, 0.1],
            ..limits()
        };
        assert!(matches!(
            check(&t, &low_box, &m),
            Err(MotionRefused::OutsideWorkspace { .. })
        ));
        let too_fast = MotionLimits {
            max_vel_m_per_s: 2.0,
            ..m
        };
        assert!(too_fast.validate().unwrap_err().to_string().contains("1.7"));
        // A jump of 1 cm in one millisecond: 10 m/s.
        let jumpy = Trajectory {
            positions_m: vec![Point3::new(0.5, 0.0, 0.1), Point3::new(0.51, 0.0, 0.1)],
            boxed: 0..2,
        };
        let err = check(&jumpy, &limits(), &m).unwrap_err();
        assert!(
            matches!(
                err,
                MotionRefused::Exceeds {
                    what: "velocity (m/s)",
                    ..
                }
            ),
            "{err}"
        );
    }
}
