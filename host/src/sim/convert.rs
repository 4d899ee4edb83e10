//! The one boundary between riseg's types (nalgebra, metres) and the simulator's engine
//! types (glam-based rapier3d/parry3d, centimetres); see TOOLCHAIN.md, "Math types across
//! crates". Nothing else in the crate converts by hand.
//!
//! Why centimetres: parry's GJK-based queries (ray casts on cylinders and rounded boxes,
//! distances between rounded or polyhedral shapes) use absolute tolerances tuned for
//! metre-sized shapes. With 3-7 cm objects expressed in metres they were measured off by
//! 2-13 mm (false ray hits outside cylinders, distances 3 mm wrong); the same queries in
//! centimetres are accurate to a few micrometres (p99). Rapier is told the scale through
//! `IntegrationParameters::length_unit`.

use nalgebra::{Point3, Quaternion, Translation3, UnitQuaternion, Vector3};
use parry3d::math::{Pose as GlamPose, Rotation as GlamRot, Vector as GlamVec};
use riseg_core::Pose;

/// Simulator length units (centimetres) per metre.
pub(crate) const CM_PER_M: f32 = 100.0;

/// Direction (unitless) nalgebra → glam.
pub(crate) fn dir_to_sim(v: &Vector3<f32>) -> GlamVec {
    GlamVec::new(v.x, v.y, v.z)
}

/// Direction (unitless) glam → nalgebra.
pub(crate) fn dir_from_sim(v: GlamVec) -> Vector3<f32> {
    Vector3::new(v.x, v.y, v.z)
}

/// Point in metres → simulator point in centimetres.
pub(crate) fn point_to_sim(p: &Point3<f32>) -> GlamVec {
    GlamVec::new(p.x, p.y, p.z) * CM_PER_M
}

/// Simulator point in centimetres → point in metres.
pub(crate) fn point_from_sim(v: GlamVec) -> Point3<f32> {
    Point3::new(v.x, v.y, v.z) / CM_PER_M
}

/// Pose with translation in metres → simulator pose in centimetres.
pub(crate) fn pose_to_sim(p: &Pose) -> GlamPose {
    let q = p.rotation.quaternion();
    GlamPose::from_parts(
        point_to_sim(&Point3::from(p.translation.vector)),
        GlamRot::from_xyzw(q.i, q.j, q.k, q.w),
    )
}

/// Simulator pose in centimetres → pose in metres (the quaternion is renormalised).
pub(crate) fn pose_from_sim(p: &GlamPose) -> Pose {
    let r = p.rotation;
    let t = point_from_sim(p.translation);
    Pose::from_parts(
        Translation3::new(t.x, t.y, t.z),
        UnitQuaternion::new_normalize(Quaternion::new(r.w, r.x, r.y, r.z)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_round_trip_and_act_alike() {
        let p = Pose::from_parts(
            Translation3::new(0.1, -0.2, 0.3),
            UnitQuaternion::from_euler_angles(0.3, -0.7, 1.9),
        );
        let g = pose_to_sim(&p);
        assert!((g.translation.z - 30.0).abs() < 1e-5, "centimetres inside");
        let back = pose_from_sim(&g);
        assert!((back.to_homogeneous() - p.to_homogeneous()).abs().max() < 1e-6);
        let x = Point3::new(0.5, 0.25, -1.0);
        let via_sim = point_from_sim(g * point_to_sim(&x));
        assert!((via_sim - p * x).norm() < 1e-6);
        let d = Vector3::new(0.0, 0.6, 0.8);
        assert_eq!(dir_from_sim(dir_to_sim(&d)), d);
    }
}
