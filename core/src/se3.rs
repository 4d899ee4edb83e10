//! Rigid motions and the body frame-invariant feature (BFIF): the spatial twist.
//!
//! Names say which way a transform maps: `p_in_a = a_from_b * p_in_b`.
//!
//! A body frame sits on three points of a rigid body. Between two images the frame moves
//! from `space_from_body_t` to `space_from_body_t1`; the relative motion
//! `M = space_from_body_t1 · space_from_body_t⁻¹` maps every point of the body at `t` to
//! where it is at `t+1`, so it is the same for every frame on one body. Its logarithm in
//! se(3), expressed in a fixed space frame, is the BFIF ([`spatial_twist`]). The paper's
//! finite-difference form `(M − I)/dt` agrees to first order; the log is exact for any
//! motion, so riseg uses it.
//!
//! All transcendentals go through `libm` (see `math`), so results are bit-identical on
//! every target.

use nalgebra::{
    Isometry3, Matrix3, Point3, Quaternion, Rotation3, Translation3, UnitQuaternion, Vector3,
};

use crate::math::{Real, atan2, frexp, scalbn, sin_cos, sqrt};

/// A rigid transform `a_from_b`.
pub type Pose = Isometry3<Real>;

/// A twist in se(3): angular part `w` first (rad), then linear part `v` (m), as in sophus.
///
/// ```text
///            | [w]×  v |
///  (w, v)^ = |  0    0 |      exp: se(3) → SE(3),  log: SE(3) → se(3)
/// ```
///
/// For a spatial twist, `v` is the displacement of the (imagined, infinitely large) body
/// point that sits at the space frame's origin.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Twist {
    /// Rotation vector (axis times angle), radians.
    pub w: Vector3<Real>,
    /// Linear part, metres.
    pub v: Vector3<Real>,
}

/// Below this angle the series forms of the exp/log coefficients are used.
const SERIES_BELOW_RAD: Real = 0.3;

fn skew(w: &Vector3<Real>) -> Matrix3<Real> {
    Matrix3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0)
}

impl Twist {
    /// The zero twist (no motion).
    pub const ZERO: Self = Self {
        w: Vector3::new(0.0, 0.0, 0.0),
        v: Vector3::new(0.0, 0.0, 0.0),
    };

    /// The rigid motion `exp((w, v)^)`.
    #[must_use]
    pub fn exp(&self) -> Pose {
        let theta2 = self.w.norm_squared();
        let theta = sqrt(theta2);
        let (s_half, c_half) = sin_cos(0.5 * theta);
        // (1 - cos θ)/θ² = 2 sin²(θ/2)/θ² and (θ - sin θ)/θ³, both as series near 0.
        let (half_sin_over, b, c) = if theta < SERIES_BELOW_RAD {
            let t4 = theta2 * theta2;
            (
                0.5 - theta2 / 48.0 + t4 / 3840.0,
                0.5 - theta2 / 24.0 + t4 / 720.0,
                1.0 / 6.0 - theta2 / 120.0 + t4 / 5040.0,
            )
        } else {
            let (s, _) = sin_cos(theta);
            (
                s_half / theta,
                2.0 * s_half * s_half / theta2,
                (theta - s) / (theta2 * theta),
            )
        };
        let q = UnitQuaternion::new_normalize(Quaternion::new(
            c_half,
            self.w.x * half_sin_over,
            self.w.y * half_sin_over,
            self.w.z * half_sin_over,
        ));
        let k = skew(&self.w);
        let v_mat = Matrix3::identity() + k * b + k * k * c;
        Isometry3::from_parts(Translation3::from(v_mat * self.v), q)
    }

    /// The twist whose exponential is `pose`, with rotation angle in `[0, π]`.
    #[must_use]
    pub fn log(pose: &Pose) -> Self {
        let q = pose.rotation.quaternion();
        // q and -q are one rotation; take the one with w >= 0 so the angle is <= π.
        let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
        let (qw, qv) = (q.w * sign, q.imag() * sign);
        let s = qv.norm(); // sin(θ/2)
        let theta = 2.0 * atan2(s, qw);
        let scale = if s > 1e-7 {
            theta / s
        } else {
            2.0 / qw.max(1e-7)
        };
        let w = qv * scale;
        let theta2 = theta * theta;
        // V⁻¹ = I − ½[w]× + c [w]×², c = (1 − (θ/2)·cot(θ/2))/θ², cot(θ/2) = qw/s.
        let c = if theta < SERIES_BELOW_RAD {
            1.0 / 12.0 + theta2 / 720.0 + theta2 * theta2 / 30240.0
        } else {
            (1.0 - 0.5 * theta * qw / s) / theta2
        };
        let k = skew(&w);
        let v_inv = Matrix3::identity() - k * 0.5 + k * k * c;
        Self {
            w,
            v: v_inv * pose.translation.vector,
        }
    }

    /// The twist of the inverse motion.
    #[must_use]
    pub fn neg(&self) -> Self {
        Self {
            w: -self.w,
            v: -self.v,
        }
    }

    /// Squared twist norm with rotation weighted by `length_scale_m` (units: m²).
    #[must_use]
    pub fn norm_squared(&self, length_scale_m: Real) -> Real {
        self.v.norm_squared() + length_scale_m * length_scale_m * self.w.norm_squared()
    }

    /// Distance between two twists, `sqrt(|Δv|² + (L·|Δw|)²)` in metres, with rotation
    /// weighted by the length scale `L = length_scale_m` (about an object's size) so that a
    /// rotation of `θ` counts like the displacement `L·θ` it causes at that distance.
    #[must_use]
    pub fn distance(&self, other: &Self, length_scale_m: Real) -> Real {
        let d = Self {
            w: self.w - other.w,
            v: self.v - other.v,
        };
        sqrt(d.norm_squared(length_scale_m))
    }

    /// True when every component is finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.w.iter().chain(self.v.iter()).all(|x| x.is_finite())
    }
}

/// The relative motion `M = space_from_body_t1 · space_from_body_t⁻¹` (maps the body at
/// `t` onto the body at `t+1`, in the space frame).
#[must_use]
pub fn relative_motion(space_from_body_t: &Pose, space_from_body_t1: &Pose) -> Pose {
    space_from_body_t1 * space_from_body_t.inverse()
}

/// The spatial twist (BFIF) `log(M)` of a body frame that moved from `space_from_body_t`
/// to `space_from_body_t1`: identical for every frame on one rigid body.
#[must_use]
pub fn spatial_twist(space_from_body_t: &Pose, space_from_body_t1: &Pose) -> Twist {
    Twist::log(&relative_motion(space_from_body_t, space_from_body_t1))
}

/// Smallest `sin` of the angle at the origin of a frame's triangle that counts as
/// non-collinear in [`try_frame_from_points`].
pub const MIN_FRAME_SIN: Real = 1e-3;

/// The least-squares rigid motion carrying each point `a` to its `b` (Kabsch: the SVD of
/// the points' cross-covariance, with the reflection removed); `None` with fewer than six
/// pairs or a fit that is not finite.
pub fn fit_rigid_motion<'p>(
    pairs: impl Iterator<Item = (&'p Point3<Real>, &'p Point3<Real>)> + Clone,
) -> Option<Pose> {
    let (mut n, mut sum_t, mut sum_t1) = (0.0, Vector3::zeros(), Vector3::zeros());
    for (a, b) in pairs.clone() {
        n += 1.0;
        sum_t += a.coords;
        sum_t1 += b.coords;
    }
    if n < 6.0 {
        return None;
    }
    let (c_t, c_t1) = (sum_t / n, sum_t1 / n);
    let mut cross = Matrix3::zeros();
    for (a, b) in pairs {
        cross += (a.coords - c_t) * (b.coords - c_t1).transpose();
    }
    let svd = cross.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut v = v_t.transpose();
    if (v * u.transpose()).determinant() < 0.0 {
        v.column_mut(2).neg_mut();
    }
    let rotation = Rotation3::from_matrix_unchecked(v * u.transpose());
    let rotation = UnitQuaternion::from_rotation_matrix(&rotation);
    let translation = c_t1 - rotation * c_t;
    let pose = Pose::from_parts(Translation3::from(translation), rotation);
    let finite = pose.translation.vector.iter().all(|x| x.is_finite())
        && pose.rotation.coords.iter().all(|x| x.is_finite());
    finite.then_some(pose)
}

/// The body frame on three points: origin `p0`, x towards `p1`, z normal to the plane of
/// the three points, `y = z × x`. Returns `frame_from_body` in the frame the points are in,
/// or `None` if the points coincide or are collinear (`sin` of the angle at `p0` below
/// [`MIN_FRAME_SIN`]) or not finite.
#[must_use]
pub fn try_frame_from_points(
    p0: &Point3<Real>,
    p1: &Point3<Real>,
    p2: &Point3<Real>,
) -> Option<Pose> {
    // Each side is scaled by a power of two (exact) so its squares neither underflow nor
    // overflow: the axes are those of the unscaled sides, for sides of any finite length.
    let a = scaled_to_unit_range(&(p1 - p0))?;
    let b = scaled_to_unit_range(&(p2 - p0))?;
    let (na, nb) = (a.norm(), b.norm());
    let n = a.cross(&b);
    let nn = n.norm();
    // Finite: both sides are, with components below 1 in magnitude.
    if nn <= MIN_FRAME_SIN * na * nb {
        return None;
    }
    let x = a / na;
    let z = n / nn;
    let y = z.cross(&x);
    let rot = nalgebra::Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    Some(Isometry3::from_parts(
        Translation3::from(p0.coords),
        UnitQuaternion::from_rotation_matrix(&rot),
    ))
}

/// `v · 2^k` for the `k` that brings its largest component into `[0.5, 1)` in magnitude;
/// `None` if `v` is zero or not finite. The scale is exact (barring components below that
/// one by more than 2¹²⁶), so directions computed from the result are those of `v`.
fn scaled_to_unit_range(v: &Vector3<Real>) -> Option<Vector3<Real>> {
    let largest = v.amax();
    if !(largest > 0.0 && v.iter().all(|c| c.is_finite())) {
        return None;
    }
    let (_, e) = frexp(largest);
    Some(v.map(|c| scalbn(c, -e)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Curated motions: zero, tiny, near-π, pure translation, and generic.
    pub(crate) fn twist_examples() -> [Twist; 6] {
        [
            Twist::ZERO,
            Twist {
                w: Vector3::new(1e-4, 0.0, 0.0),
                v: Vector3::new(0.0, 0.0, 0.0),
            },
            Twist {
                w: Vector3::new(0.0, 0.0, core::f32::consts::PI - 1e-3),
                v: Vector3::new(0.01, 0.02, 0.0),
            },
            Twist {
                w: Vector3::zeros(),
                v: Vector3::new(0.02, -0.01, 0.005),
            },
            Twist {
                w: Vector3::new(0.1, -0.2, 0.05),
                v: Vector3::new(0.01, 0.0, -0.02),
            },
            Twist {
                w: Vector3::new(0.0, 0.0, 0.3),
                v: Vector3::new(0.0, 0.0, 0.0),
            },
        ]
    }

    fn pose_close(a: &Pose, b: &Pose, tol: Real) -> bool {
        (a.to_homogeneous() - b.to_homogeneous()).abs().max() < tol
    }

    #[test]
    fn law_suite_on_examples() {
        let examples = twist_examples();
        assert!(examples.len() >= 3);
        for t in examples {
            let m = t.exp();
            let back = Twist::log(&m);
            assert!(back.distance(&t, 1.0) < 2e-5, "log(exp({t:?})) = {back:?}");
            assert!(pose_close(&back.exp(), &m, 1e-5));
            let inv = Twist::log(&m.inverse());
            assert!(inv.distance(&t.neg(), 1.0) < 2e-5, "{inv:?} vs {t:?}");
        }
    }

    #[test]
    fn small_angle_is_not_rounded_away() {
        let t = Twist {
            w: Vector3::new(0.0, 1e-4, 0.0),
            v: Vector3::zeros(),
        };
        let back = Twist::log(&t.exp());
        assert!((back.w.y - 1e-4).abs() < 1e-8, "{back:?}");
    }

    #[test]
    fn frame_axes_follow_the_points() {
        let f = try_frame_from_points(
            &Point3::new(1.0, 1.0, 1.0),
            &Point3::new(2.0, 1.0, 1.0),
            &Point3::new(1.0, 3.0, 1.0),
        )
        .unwrap();
        let x = f.rotation * Vector3::x();
        let z = f.rotation * Vector3::z();
        assert!((x - Vector3::x()).norm() < 1e-6 && (z - Vector3::z()).norm() < 1e-6);
        assert!((f.translation.vector - Vector3::new(1.0, 1.0, 1.0)).norm() < 1e-6);
        let p = Point3::new(0.0, 0.0, 0.0);
        assert!(
            try_frame_from_points(&p, &Point3::new(1.0, 0.0, 0.0), &Point3::new(2.0, 0.0, 0.0))
                .is_none()
        );
        assert!(try_frame_from_points(&p, &p, &Point3::new(2.0, 1.0, 0.0)).is_none());
        assert!(
            try_frame_from_points(
                &p,
                &Point3::new(f32::NAN, 0.0, 0.0),
                &Point3::new(0.0, 1.0, 0.0)
            )
            .is_none()
        );
    }

    /// Found by the `frame_from_points` fuzz target: sides of 1e-10 m gave a rotation whose
    /// x axis missed `p1 − p0` (the cross product's squared norm underflowed), and sides
    /// beyond 1e19 m gave no frame (the squares overflowed).
    #[test]
    fn frame_of_tiny_or_huge_triangles_is_the_frame_of_the_same_shape() {
        let (p0, p1, p2) = (
            Point3::new(1.0f32, 1.0, 1.0),
            Point3::new(2.0, 1.5, 1.0),
            Point3::new(1.2, 3.0, 1.7),
        );
        let unit = try_frame_from_points(&p0, &p1, &p2).unwrap();
        // Scaling by a power of two is exact, so the frame's rotation must be bit-identical.
        for k in [-60, -40, 70, 100] {
            let s = libm::scalbnf(1.0, k);
            let scaled = |p: Point3<Real>| Point3::from(p.coords * s);
            let f = try_frame_from_points(&scaled(p0), &scaled(p1), &scaled(p2))
                .unwrap_or_else(|| panic!("no frame at scale 2^{k}"));
            assert_eq!(f.rotation, unit.rotation, "scale 2^{k}");
            assert_eq!(f.translation.vector, p0.coords * s);
        }
    }

    #[test]
    fn distance_weighs_rotation_by_length_scale() {
        let a = Twist {
            w: Vector3::new(0.1, 0.0, 0.0),
            v: Vector3::zeros(),
        };
        assert!((a.distance(&Twist::ZERO, 0.05) - 0.005).abs() < 1e-7);
    }
}
