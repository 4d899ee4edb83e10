//! Frame building (`riseg_core::se3::try_frame_from_points` and
//! `riseg_core::frames::BodyFrame::twist`) from arbitrary triplets of points, any `f32`
//! coordinates (NaN, infinities, huge, tiny, coincident, collinear).
//!
//! Contract checked: no panic; a frame that is returned has its origin at `p0` exactly,
//! its x axis along `p1 − p0`, its z axis normal to `p1 − p0` and `p2 − p0`, and `p2` on
//! its positive-y side; a body frame's twist, when returned, is finite.
//!
//! Tolerance: the z axis comes from the cross product `(p1 − p0) × (p2 − p0)`, whose
//! relative rounding error is about `ε / sin α` (`α` the angle at `p0`, which the function
//! keeps above `asin(MIN_FRAME_SIN)`), so the axes agree to [`AXIS_ULPS`]` · ε / sin α`.

#![no_main]

use arbitrary::{Arbitrary, Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use nalgebra::{Point3, Vector3};
use riseg_core::{frames::BodyFrame, se3::try_frame_from_points};

/// Roundings allowed, in units of `ε / sin α`.
const AXIS_ULPS: f32 = 64.0;

#[derive(Debug, Arbitrary)]
struct Raw {
    p_t: [[f32; 3]; 3],
    p_t1: [[f32; 3]; 3],
    origin: [f32; 3],
}

fn check_frame(p: &[Point3<f32>; 3]) {
    let Some(pose) = try_frame_from_points(&p[0], &p[1], &p[2]) else {
        return;
    };
    assert!(
        pose.translation.vector == p[0].coords,
        "origin moved: {pose:?}"
    );
    // The sides as the function sees them (f32 differences), then exact in f64, where no
    // square of an f32 underflows or overflows.
    let (a, b) = ((p[1] - p[0]).cast::<f64>(), (p[2] - p[0]).cast::<f64>());
    let (ua, ub) = (a / a.norm(), b / b.norm());
    let sin = ua.cross(&ub).norm();
    let tol = f64::from(AXIS_ULPS * f32::EPSILON) / sin;
    let axis = |v: Vector3<f32>| (pose.rotation * v).cast::<f64>();
    let (x, y, z) = (axis(Vector3::x()), axis(Vector3::y()), axis(Vector3::z()));
    assert!(
        (x - ua).norm() <= tol,
        "x axis {x:?} not along {a:?} (tol {tol:e})"
    );
    assert!(
        z.dot(&ua).abs() <= tol,
        "z axis {z:?} not normal to {a:?} (tol {tol:e})"
    );
    assert!(
        z.dot(&ub).abs() <= tol,
        "z axis {z:?} not normal to {b:?} (tol {tol:e})"
    );
    assert!(y.dot(&ub) > 0.0, "p2 not on the positive-y side: {pose:?}");
}

fuzz_target!(|data: &[u8]| {
    let parsed: Result<Raw> = Unstructured::new(data).arbitrary();
    let Ok(raw) = parsed else {
        return;
    };
    let points = |p: [[f32; 3]; 3]| p.map(Point3::from);
    let (p_t, p_t1) = (points(raw.p_t), points(raw.p_t1));
    check_frame(&p_t);
    check_frame(&p_t1);
    let frame = BodyFrame {
        p_t,
        p_t1,
        ..BodyFrame::EMPTY
    };
    if let Some(twist) = frame.twist(&Point3::from(raw.origin)) {
        assert!(twist.is_finite(), "{twist:?}");
    }
});
