//! The hand-eye calibration file: where the camera sits in the robot (base) frame.
//!
//! # Contract
//!
//! A JSON object with one key, `robot_from_camera`: the 4x4 homogeneous transform, row
//! major (four rows of four numbers), translation in metres, that maps a point in the colour
//! camera's optical frame (x right, y down, z forward, as the intrinsics use) to the robot
//! base frame (z up, normal to the table):
//!
//! ```json
//! {"robot_from_camera": [[1, 0, 0, 0.5], [0, -1, 0, 0.0], [0, 0, -1, 0.6], [0, 0, 0, 1]]}
//! ```
//!
//! [`HandEye::from_json`] refuses, naming the file and the problem, a matrix whose numbers
//! are not finite, whose last row is not `0 0 0 1`, whose rotation is not orthonormal with
//! determinant +1 (within [`ROTATION_TOLERANCE`]; a mirror or a scaled matrix is a wrong
//! calibration, not a rounding error), or whose camera lies farther than
//! [`MAX_CAMERA_DISTANCE_M`] from the robot base (a calibration in millimetres, usually).
//! A valid rotation is re-orthonormalised once so later maths sees an exact rotation.

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Matrix4, Rotation3, Translation3, UnitQuaternion};
use riseg_core::Pose;
use serde::Deserialize;

/// Largest `|RᵀR − I|` entry and `|det R − 1|` accepted in a calibration.
pub const ROTATION_TOLERANCE: f64 = 1e-3;
/// Farthest a camera may be from the robot base, metres; a Panda reaches 0.855 m and a
/// camera over its table is within 2 m of the base.
pub const MAX_CAMERA_DISTANCE_M: f64 = 3.0;

/// A validated hand-eye calibration (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandEye {
    /// The colour camera's pose in the robot base frame (metres).
    pub robot_from_camera: Pose,
}

/// Why a calibration file was refused; the message names the file.
#[derive(Debug, thiserror::Error)]
#[error("calibration {}: {problem}", path.display())]
pub struct CalibError {
    /// The file.
    pub path: PathBuf,
    /// What is wrong with it.
    pub problem: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CalibFile {
    robot_from_camera: [[f64; 4]; 4],
}

impl HandEye {
    /// Reads and validates the calibration file `path` (module docs).
    ///
    /// # Errors
    /// [`CalibError`] naming `path` when it cannot be read or is refused.
    pub fn read(path: &Path) -> Result<Self, CalibError> {
        let bytes = std::fs::read(path).map_err(|e| CalibError {
            path: path.to_owned(),
            problem: e.to_string(),
        })?;
        Self::from_json(&bytes, path)
    }

    /// Parses and validates calibration JSON; `path` only names it in errors.
    ///
    /// # Errors
    /// [`CalibError`] when the JSON is malformed or the transform is refused (module docs).
    pub fn from_json(bytes: &[u8], path: &Path) -> Result<Self, CalibError> {
        let refuse = |problem: String| CalibError {
            path: path.to_owned(),
            problem,
        };
        let file: CalibFile = serde_json::from_slice(bytes).map_err(|e| {
            refuse(format!(
                "{e} (expected {{\"robot_from_camera\": [[r00, r01, r02, tx_m], ..., [0, 0, 0, 1]]}})"
            ))
        })?;
        let m = Matrix4::from_fn(|r, c| file.robot_from_camera[r][c]);
        Self::from_matrix(&m).map_err(refuse)
    }

    /// Validates a 4x4 transform (module docs); the error is the problem alone.
    ///
    /// # Errors
    /// A description of the first rule `m` breaks.
    pub fn from_matrix(m: &Matrix4<f64>) -> Result<Self, String> {
        if m.iter().any(|v| !v.is_finite()) {
            return Err("robot_from_camera has a number that is not finite".into());
        }
        let last = [m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)]];
        if last != [0.0, 0.0, 0.0, 1.0] {
            return Err(format!(
                "the last row of robot_from_camera is {last:?}, not [0, 0, 0, 1]"
            ));
        }
        let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
        let ortho_err = (r.transpose() * r - Matrix3::identity()).abs().max();
        let det = r.determinant();
        if ortho_err > ROTATION_TOLERANCE || (det - 1.0).abs() > ROTATION_TOLERANCE {
            return Err(format!(
                "the rotation of robot_from_camera is not orthonormal with determinant +1 \
                 (largest |RᵀR − I| entry {ortho_err:.2e}, det {det:.4}; tolerance \
                 {ROTATION_TOLERANCE:.0e}): a mirrored, scaled or transposed matrix?"
            ));
        }
        let t = m.fixed_view::<3, 1>(0, 3).into_owned();
        if t.norm() > MAX_CAMERA_DISTANCE_M {
            return Err(format!(
                "the camera is {:.3} m from the robot base (more than {MAX_CAMERA_DISTANCE_M} m): \
                 is the translation in millimetres? It must be in metres",
                t.norm()
            ));
        }
        let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&r));
        Ok(Self {
            robot_from_camera: Pose::from_parts(
                Translation3::new(t.x as f32, t.y as f32, t.z as f32),
                rotation.cast::<f32>(),
            ),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(json: &str) -> Result<HandEye, CalibError> {
        HandEye::from_json(json.as_bytes(), Path::new("hand_eye.json"))
    }

    const DOWN: &str = r#"{"robot_from_camera": [[1, 0, 0, 0.5], [0, -1, 0, 0.1], [0, 0, -1, 0.6], [0, 0, 0, 1]]}"#;

    #[test]
    fn a_camera_looking_down_maps_its_optical_axis_to_minus_z() {
        let cal = parse(DOWN).unwrap();
        let p = cal.robot_from_camera * nalgebra::Point3::new(0.0, 0.0, 0.6);
        assert!(
            (p.coords - nalgebra::Vector3::new(0.5, 0.1, 0.0)).norm() < 1e-6,
            "{p}"
        );
    }

    #[test]
    fn bad_calibrations_are_refused_naming_the_file_and_the_problem() {
        let cases = [
            (DOWN.replace("0.6]", "600]"), "millimetres"),
            (
                DOWN.replace("[1, 0, 0, 0.5]", "[2, 0, 0, 0.5]"),
                "not orthonormal",
            ),
            // A mirror: orthonormal, determinant -1.
            (
                DOWN.replace("[0, 0, -1, 0.6]", "[0, 0, 1, 0.6]"),
                "determinant +1",
            ),
            (DOWN.replace("[0, 0, 0, 1]", "[0, 0, 1, 1]"), "last row"),
            (DOWN.replace("0.5]", "1e999]"), "hand_eye.json"),
            (
                r#"{"robot_from_camera": [[1, 0, 0]]}"#.to_owned(),
                "expected",
            ),
            (r#"{"camera_from_robot": []}"#.to_owned(), "unknown field"),
        ];
        for (json, needle) in cases {
            let err = parse(&json).unwrap_err().to_string();
            assert!(err.starts_with("calibration hand_eye.json: "), "{err}");
            assert!(err.contains(needle), "{json}: {err}");
        }
        let missing = HandEye::read(Path::new("/nonexistent/cal.json")).unwrap_err();
        assert!(
            missing.to_string().contains("/nonexistent/cal.json"),
            "{missing}"
        );
    }

    #[test]
    fn a_slightly_noisy_rotation_is_accepted_and_made_exact() {
        let cal = parse(&DOWN.replace("[1, 0, 0, 0.5]", "[1.0004, 0, 0, 0.5]")).unwrap();
        let r = cal.robot_from_camera.rotation.to_rotation_matrix();
        let err = (r.matrix().transpose() * r.matrix() - Matrix3::identity())
            .abs()
            .max();
        assert!(err < 1e-6, "{err}");
    }
}
