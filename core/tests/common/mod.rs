//! Proptest strategies shared by the property tests.

use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use riseg_core::Pose;

mod uniform;
pub use uniform::uniform;

/// A point in a 30 cm cube around the camera's working distance.
pub fn point() -> impl Strategy<Value = Point3<f32>> {
    (
        uniform(-0.15, 0.15),
        uniform(-0.15, 0.15),
        uniform(0.45, 0.75),
    )
        .prop_map(|(x, y, z)| Point3::new(x, y, z))
}

/// A rigid motion: rotation up to 3 rad about a random axis, translation up to 10 cm.
pub fn motion() -> impl Strategy<Value = Pose> {
    (
        uniform(-1.0, 1.0),
        uniform(-1.0, 1.0),
        uniform(-1.0, 1.0),
        uniform(0.0, 3.0),
        uniform(-0.1, 0.1),
        uniform(-0.1, 0.1),
        uniform(-0.1, 0.1),
    )
        .prop_filter_map("axis too short", |(ax, ay, az, angle, tx, ty, tz)| {
            let axis = Vector3::new(ax, ay, az).try_normalize(1e-3)?;
            Some(Pose::from_parts(
                Translation3::new(tx, ty, tz),
                UnitQuaternion::from_scaled_axis(axis * angle),
            ))
        })
}

/// Three points that are clearly not collinear (sine of the angle at the first above 0.2,
/// sides at least 5 mm).
pub fn triplet() -> impl Strategy<Value = [Point3<f32>; 3]> {
    (point(), point(), point()).prop_filter_map("degenerate triangle", |(a, b, c)| {
        let (u, v) = (b - a, c - a);
        let ok =
            u.norm() > 0.005 && v.norm() > 0.005 && u.cross(&v).norm() > 0.2 * u.norm() * v.norm();
        ok.then_some([a, b, c])
    })
}
