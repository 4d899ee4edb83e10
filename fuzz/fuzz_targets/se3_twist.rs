//! Twist math of `riseg_core::se3` on arbitrary finite poses and twists: the laws below
//! must hold to `f32` precision, and a law that fails is a crash (`assert!`).
//!
//! Domain (the documented one, DESIGN §3): translations of at most [`MAX_TRANSLATION_M`]
//! per axis (a robot's workspace with room to spare), any unit quaternion (from four
//! finite floats of non-negligible norm), and for twists a rotation angle below
//! `π − ANGLE_MARGIN_RAD`: [`Twist::log`] returns angles in `[0, π]`, so at `π` the axis
//! sign, and the twist with it, legitimately jumps.
//!
//! Laws:
//! 1. `log(exp(ξ)) = ξ`;
//! 2. `exp(log(P)) = P` for every pose;
//! 3. `log(P⁻¹) = −log(P)` (angle below the margin);
//! 4. frame invariance (the paper's BFIF): with `M = exp(ξ)`, a frame `A` and the frame
//!    `A·X` on the same body, moved to `M·A` and `M·A·X`, have the same spatial twist, `ξ`;
//! 5. [`Twist::distance`] is symmetric, non-negative and zero on equal twists.
//!
//! Tolerances follow from `f32` rounding: each operation errs by a few ulp relative to the
//! magnitudes it combines, and every map here is well conditioned on the domain (the
//! left Jacobian `V` of SE(3) has singular values in `[2/π, 1]` for angles up to `π`).
//! So rotations agree to [`ROT_TOL_RAD`] absolutely (angles are at most `π`), and
//! translations to [`REL_TOL`] times the sum of the translation magnitudes involved
//! (cancellation between large translations is the dominant error), plus an absolute
//! floor of [`ABS_TOL_M`] for all-zero inputs.

#![no_main]

use arbitrary::{Arbitrary, Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use nalgebra::{Quaternion, Translation3, UnitQuaternion, Vector3};
use riseg_core::{
    Pose, Twist,
    se3::{relative_motion, spatial_twist},
};

/// Largest translation component, metres.
const MAX_TRANSLATION_M: f32 = 1e3;
/// Twist angles stay this far below `π`.
const ANGLE_MARGIN_RAD: f32 = 1e-2;
/// 64 ulp of 1: a few dozen roundings, each of a few ulp.
const ROT_TOL_RAD: f32 = 64.0 * f32::EPSILON;
/// Relative translation tolerance.
const REL_TOL: f32 = 64.0 * f32::EPSILON;
/// Absolute floor, metres (a nanometre: far below any sensor).
const ABS_TOL_M: f32 = 1e-9;

#[derive(Debug, Arbitrary)]
struct Raw {
    w: [f32; 3],
    v: [f32; 3],
    a_rot: [f32; 4],
    a_t: [f32; 3],
    x_rot: [f32; 4],
    x_t: [f32; 3],
}

fn translation(t: [f32; 3]) -> Option<Vector3<f32>> {
    t.iter()
        .all(|c| c.is_finite() && c.abs() <= MAX_TRANSLATION_M)
        .then(|| Vector3::from(t))
}

fn pose(q: [f32; 4], t: [f32; 3]) -> Option<Pose> {
    let q = Quaternion::new(q[0], q[1], q[2], q[3]);
    let norm = q.norm();
    if !(norm.is_finite() && norm > 1e-3) || q.coords.iter().any(|c| !c.is_finite()) {
        return None;
    }
    Some(Pose::from_parts(
        Translation3::from(translation(t)?),
        UnitQuaternion::from_quaternion(q),
    ))
}

/// Angle of the rotation between `a` and `b` (twice the sine of the half angle: exact to
/// rounding near zero, unlike `acos`).
fn rotation_gap(a: &UnitQuaternion<f32>, b: &UnitQuaternion<f32>) -> f32 {
    2.0 * (a.inverse() * b).imag().norm()
}

fn assert_twist_close(got: &Twist, want: &Twist, t_scale: f32, what: &str) {
    let dw = (got.w - want.w).norm();
    let dv = (got.v - want.v).norm();
    let v_tol = REL_TOL * t_scale + ABS_TOL_M;
    assert!(
        dw <= ROT_TOL_RAD && dv <= v_tol,
        "{what}: got {got:?}, want {want:?} (|dw| {dw:e} > {ROT_TOL_RAD:e} or |dv| {dv:e} > {v_tol:e})"
    );
}

fn assert_pose_close(got: &Pose, want: &Pose, t_scale: f32, what: &str) {
    let dr = rotation_gap(&got.rotation, &want.rotation);
    let dt = (got.translation.vector - want.translation.vector).norm();
    let t_tol = REL_TOL * t_scale + ABS_TOL_M;
    assert!(
        dr <= ROT_TOL_RAD && dt <= t_tol,
        "{what}: got {got:?}, want {want:?} (rotation {dr:e} > {ROT_TOL_RAD:e} or translation {dt:e} > {t_tol:e})"
    );
}

fn angle(p: &Pose) -> f32 {
    p.rotation.angle()
}

fn run(raw: &Raw) -> Option<()> {
    let xi = Twist {
        w: Vector3::from(raw.w),
        v: translation(raw.v)?,
    };
    let theta = xi.w.norm();
    let in_domain = theta.is_finite() && theta < core::f32::consts::PI - ANGLE_MARGIN_RAD;
    let a = pose(raw.a_rot, raw.a_t)?;
    let x = pose(raw.x_rot, raw.x_t)?;

    // 2. exp(log(P)) = P, for any pose.
    let ta = a.translation.vector.norm();
    assert_pose_close(&Twist::log(&a).exp(), &a, ta, "exp(log(A))");

    // 3. log(P⁻¹) = −log(P).
    if angle(&a) < core::f32::consts::PI - ANGLE_MARGIN_RAD {
        assert_twist_close(
            &Twist::log(&a.inverse()),
            &Twist::log(&a).neg(),
            ta,
            "log(A⁻¹)",
        );
    }

    if !in_domain {
        return None;
    }
    // 5. distance.
    let la = Twist::log(&a);
    let d = xi.distance(&la, 0.05);
    assert!(d >= 0.0, "distance {d}");
    assert!(
        d.to_bits() == la.distance(&xi, 0.05).to_bits(),
        "distance not symmetric"
    );
    assert!(la.distance(&la, 0.05) == 0.0);

    // 1. log(exp(ξ)) = ξ.
    let m = xi.exp();
    let tm = m.translation.vector.norm();
    assert_twist_close(&Twist::log(&m), &xi, xi.v.norm() + tm, "log(exp(ξ))");

    // 4. Frame invariance: frames A and A·X on one body, moved by M.
    let b = m * a;
    let ax = a * x;
    let bx = m * ax;
    let scale = |p: &Pose| p.translation.vector.norm();
    let t_scale = tm + scale(&a) + scale(&b) + scale(&ax) + scale(&bx);
    let s1 = spatial_twist(&a, &b);
    let s2 = spatial_twist(&ax, &bx);
    assert_twist_close(&s1, &xi, t_scale, "spatial twist of A");
    assert_twist_close(&s2, &s1, t_scale, "spatial twist of A·X");
    assert_pose_close(
        &relative_motion(&ax, &bx),
        &m,
        t_scale,
        "relative motion of A·X",
    );
    Some(())
}

fuzz_target!(|data: &[u8]| {
    let parsed: Result<Raw> = Unstructured::new(data).arbitrary();
    if let Ok(raw) = parsed {
        let _ = run(&raw);
    }
});
