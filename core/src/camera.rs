//! Pinhole camera: back-projection of a pixel with depth, and projection of a 3-D point.
//!
//! Camera frame: x right, y down, z forward (OpenCV). A pixel `(u, v)` is measured from the
//! centre of the top-left pixel, so `cx = (width - 1) / 2` is the optical axis of an ideal
//! sensor. Depth `z` is the distance along the optical axis, not along the ray.

use nalgebra::{Point3, Vector2};

use crate::{Error, math::Real};

/// Smallest focal length accepted, pixels. A numerical bound, not a physical one: with
/// pixel offsets up to [`MAX_CAMERA_PX`] and depth up to
/// [`MAX_DEPTH_M`](crate::image::MAX_DEPTH_M), every back-projected coordinate stays below
/// about 1e10 m, so sums over a whole image stay finite in `f32`.
pub const MIN_FOCAL_PX: Real = 0.01;
/// Largest focal length or principal-point offset accepted, pixels.
pub const MAX_CAMERA_PX: Real = 1.0e6;

/// Pinhole intrinsics in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Focal length along x, pixels.
    pub fx: Real,
    /// Focal length along y, pixels.
    pub fy: Real,
    /// Principal point x, pixels.
    pub cx: Real,
    /// Principal point y, pixels.
    pub cy: Real,
}

impl Intrinsics {
    /// Checked intrinsics.
    ///
    /// # Errors
    /// [`Error::NonFinite`] if a value is not finite; [`Error::BadConfig`] if a focal
    /// length is outside [[`MIN_FOCAL_PX`], [`MAX_CAMERA_PX`]] or the principal point is
    /// further than [`MAX_CAMERA_PX`] from the origin.
    pub fn new(fx: Real, fy: Real, cx: Real, cy: Real) -> Result<Self, Error> {
        let k = Self { fx, fy, cx, cy };
        k.check()?;
        Ok(k)
    }

    /// Validates fields that a caller may have set directly.
    ///
    /// # Errors
    /// As [`Intrinsics::new`].
    pub fn check(&self) -> Result<(), Error> {
        if ![self.fx, self.fy, self.cx, self.cy]
            .iter()
            .all(|v| v.is_finite())
        {
            return Err(Error::NonFinite);
        }
        let focal_ok = |f: Real| (MIN_FOCAL_PX..=MAX_CAMERA_PX).contains(&f);
        let centre_ok = |c: Real| c.abs() <= MAX_CAMERA_PX;
        if !(focal_ok(self.fx) && focal_ok(self.fy) && centre_ok(self.cx) && centre_ok(self.cy)) {
            return Err(Error::BadConfig);
        }
        Ok(())
    }

    /// The 3-D point in the camera frame seen at pixel `(u, v)` with depth `z_m`.
    #[must_use]
    pub fn back_project(&self, u: Real, v: Real, z_m: Real) -> Point3<Real> {
        Point3::new(
            (u - self.cx) * z_m / self.fx,
            (v - self.cy) * z_m / self.fy,
            z_m,
        )
    }

    /// The pixel where `p` (camera frame) appears; `None` if `p` is not in front of the camera.
    #[must_use]
    pub fn project(&self, p: &Point3<Real>) -> Option<Vector2<Real>> {
        if p.z > 1e-6 && p.x.is_finite() && p.y.is_finite() {
            Some(Vector2::new(
                self.fx * p.x / p.z + self.cx,
                self.fy * p.y / p.z + self.cy,
            ))
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn project_inverts_back_project() {
        let k = Intrinsics::new(615.0, 615.0, 319.5, 239.5).unwrap();
        let p = k.back_project(100.25, 400.5, 0.63);
        let px = k.project(&p).unwrap();
        assert!((px.x - 100.25).abs() < 1e-3 && (px.y - 400.5).abs() < 1e-3);
        assert!(k.project(&Point3::new(0.0, 0.0, -1.0)).is_none());
    }

    #[test]
    fn bad_intrinsics_are_errors() {
        assert_eq!(Intrinsics::new(0.0, 1.0, 0.0, 0.0), Err(Error::BadConfig));
        // A focal length of 1e-37 px would send back-projected points past f32's range.
        assert_eq!(
            Intrinsics::new(1e-37, 1e-37, 0.0, 0.0),
            Err(Error::BadConfig)
        );
        assert_eq!(Intrinsics::new(1.0, 2e6, 0.0, 0.0), Err(Error::BadConfig));
        assert_eq!(
            Intrinsics::new(615.0, 615.0, -2e6, 0.0),
            Err(Error::BadConfig)
        );
        assert!(Intrinsics::new(MIN_FOCAL_PX, MAX_CAMERA_PX, -MAX_CAMERA_PX, 0.0).is_ok());
        assert_eq!(
            Intrinsics::new(f32::NAN, 1.0, 0.0, 0.0),
            Err(Error::NonFinite)
        );
    }
}
