//! The files `riseg segment` reads and writes: PNG images and the scene camera JSON.
//!
//! Contract:
//! - Every error is a [`FileError`] whose message starts with the file's path and then
//!   says the problem (missing, unreadable, corrupt PNG, wrong colour type or bit depth,
//!   wrong size, malformed JSON, a camera value out of range). Nothing panics on any file
//!   content.
//! - PNG decoding happens in one function, [`read_png`]; the typed readers only check the
//!   colour type.
//! - Writers are atomic: the encoded bytes go to a temporary file next to the destination,
//!   which is flushed to disk and renamed over it, so a reader sees the old file or the
//!   complete new one, never half a file.
//!
//! Scene camera file (`scene_camera.json`, the scene folder's format):
//! `{"width": 640, "height": 480, "fx": 615.0, "fy": 615.0, "cx": 319.5, "cy": 239.5,
//! "depth_unit_m": 0.001}`; a depth PNG holds depth in `depth_unit_m` units, 0 = no reading.

use std::{
    fs,
    io::{self, BufReader, Write as _},
    path::{Path, PathBuf},
};

use image::{DynamicImage, ExtendedColorType, ImageEncoder, Limits, codecs::png};
use riseg_core::Intrinsics;

/// Why reading or writing a file failed; the message names the file.
#[derive(Debug, thiserror::Error)]
#[error("{}: {problem}", path.display())]
pub struct FileError {
    /// The file.
    pub path: PathBuf,
    /// What is wrong with it.
    pub problem: FileProblem,
}

/// What is wrong with a file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FileProblem {
    /// The file does not exist.
    #[error("file not found")]
    Missing,
    /// The operating system refused to read, write or rename it.
    #[error("I/O error: {0}")]
    Io(#[source] io::Error),
    /// Not a PNG the decoder accepts (or too large to decode).
    #[error("corrupt or unsupported PNG: {0}")]
    CorruptPng(#[source] image::ImageError),
    /// A valid PNG of the wrong colour type or bit depth.
    #[error("expected {expected}, found {found}")]
    WrongFormat {
        /// What the caller needs.
        expected: &'static str,
        /// What the file holds.
        found: String,
    },
    /// Not the size the other inputs have.
    #[error("expected {expected_width}x{expected_height} pixels, found {width}x{height}")]
    WrongSize {
        /// Width needed.
        expected_width: u32,
        /// Height needed.
        expected_height: u32,
        /// Width found.
        width: u32,
        /// Height found.
        height: u32,
    },
    /// Malformed JSON or missing fields.
    #[error("malformed camera JSON: {0}")]
    Json(#[source] serde_json::Error),
    /// A camera value out of range.
    #[error("invalid camera: {0}")]
    BadCamera(&'static str),
}

impl FileError {
    fn new(path: &Path, problem: FileProblem) -> Self {
        Self {
            path: path.to_path_buf(),
            problem,
        }
    }

    fn io(path: &Path, e: io::Error) -> Self {
        let problem = if e.kind() == io::ErrorKind::NotFound {
            FileProblem::Missing
        } else {
            FileProblem::Io(e)
        };
        Self::new(path, problem)
    }

    /// A [`FileProblem::WrongSize`] error for `path`.
    #[must_use]
    pub fn wrong_size(path: &Path, expected: (u32, u32), found: (u32, u32)) -> Self {
        Self::new(
            path,
            FileProblem::WrongSize {
                expected_width: expected.0,
                expected_height: expected.1,
                width: found.0,
                height: found.1,
            },
        )
    }
}

/// An owned row-major image: pixel `(x, y)` is `pixels[y·width + x]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Picture<T> {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// `width·height` pixels.
    pub pixels: Vec<T>,
}

impl<T> Picture<T> {
    /// `(width, height)`.
    #[must_use]
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
}

/// Decodes the PNG at `path` (the one place PNG decoding happens).
///
/// # Errors
/// [`FileProblem::Missing`], [`FileProblem::Io`] or [`FileProblem::CorruptPng`].
pub fn read_png(path: &Path) -> Result<DynamicImage, FileError> {
    let file = fs::File::open(path).map_err(|e| FileError::io(path, e))?;
    png::PngDecoder::with_limits(BufReader::new(file), Limits::default())
        .and_then(DynamicImage::from_decoder)
        .map_err(|e| match e {
            image::ImageError::IoError(io) => FileError::io(path, io),
            other => FileError::new(path, FileProblem::CorruptPng(other)),
        })
}

/// "8-bit RGB", "16-bit greyscale", ... for error messages.
fn describe(img: &DynamicImage) -> String {
    use image::ColorType as C;
    let c = img.color();
    let kind = match c {
        C::L8 | C::L16 => "greyscale",
        C::La8 | C::La16 => "greyscale with alpha",
        C::Rgb8 | C::Rgb16 | C::Rgb32F => "RGB",
        C::Rgba8 | C::Rgba16 | C::Rgba32F => "RGBA",
        _ => return format!("{c:?}"),
    };
    format!(
        "{}-bit {kind}",
        c.bits_per_pixel() / u16::from(c.channel_count())
    )
}

/// Reads an 8-bit RGB PNG (an alpha channel, if any, is ignored).
///
/// # Errors
/// As [`read_png`], or [`FileProblem::WrongFormat`] for other colour types and bit depths.
pub fn read_rgb8(path: &Path) -> Result<Picture<[u8; 3]>, FileError> {
    let img = read_png(path)?;
    let (width, height) = (img.width(), img.height());
    let pixels = match img {
        DynamicImage::ImageRgb8(b) => b.pixels().map(|p| p.0).collect(),
        DynamicImage::ImageRgba8(b) => b.pixels().map(|p| [p.0[0], p.0[1], p.0[2]]).collect(),
        other => {
            return Err(FileError::new(
                path,
                FileProblem::WrongFormat {
                    expected: "8-bit RGB PNG",
                    found: describe(&other),
                },
            ));
        }
    };
    Ok(Picture {
        width,
        height,
        pixels,
    })
}

/// Reads a 16-bit greyscale PNG (depth or labels).
///
/// # Errors
/// As [`read_png`], or [`FileProblem::WrongFormat`] for other colour types and bit depths.
pub fn read_gray16(path: &Path) -> Result<Picture<u16>, FileError> {
    let img = read_png(path)?;
    let (width, height) = (img.width(), img.height());
    match img {
        DynamicImage::ImageLuma16(b) => Ok(Picture {
            width,
            height,
            pixels: b.into_raw(),
        }),
        other => Err(FileError::new(
            path,
            FileProblem::WrongFormat {
                expected: "16-bit greyscale PNG",
                found: describe(&other),
            },
        )),
    }
}

fn encode(
    path: &Path,
    width: u32,
    height: u32,
    bytes: &[u8],
    color: ExtendedColorType,
) -> Result<(), FileError> {
    let mut png_bytes = Vec::new();
    png::PngEncoder::new(&mut png_bytes)
        .write_image(bytes, width, height, color)
        .map_err(|e| FileError::new(path, FileProblem::CorruptPng(e)))?;
    write_atomic(path, &png_bytes)
}

/// Writes a 16-bit greyscale PNG atomically.
///
/// # Errors
/// [`FileProblem::Io`] if the file cannot be written; [`FileProblem::WrongSize`] if
/// `pixels` does not hold `width·height` values.
pub fn write_gray16(path: &Path, width: u32, height: u32, pixels: &[u16]) -> Result<(), FileError> {
    check_len(path, width, height, pixels.len())?;
    let bytes: Vec<u8> = pixels.iter().flat_map(|v| v.to_ne_bytes()).collect();
    encode(path, width, height, &bytes, ExtendedColorType::L16)
}

/// Writes an 8-bit greyscale PNG atomically.
///
/// # Errors
/// As [`write_gray16`].
pub fn write_gray8(path: &Path, width: u32, height: u32, pixels: &[u8]) -> Result<(), FileError> {
    check_len(path, width, height, pixels.len())?;
    encode(path, width, height, pixels, ExtendedColorType::L8)
}

/// Writes an 8-bit RGB PNG atomically.
///
/// # Errors
/// As [`write_gray16`].
pub fn write_rgb8(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[[u8; 3]],
) -> Result<(), FileError> {
    check_len(path, width, height, pixels.len())?;
    encode(
        path,
        width,
        height,
        pixels.as_flattened(),
        ExtendedColorType::Rgb8,
    )
}

fn check_len(path: &Path, width: u32, height: u32, len: usize) -> Result<(), FileError> {
    if (width as usize).checked_mul(height as usize) == Some(len) {
        Ok(())
    } else {
        let found_height = if width == 0 { 0 } else { len / width as usize };
        Err(FileError::wrong_size(
            path,
            (width, height),
            (width, u32::try_from(found_height).unwrap_or(u32::MAX)),
        ))
    }
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename.
///
/// # Errors
/// [`FileProblem::Io`] (the temporary file is removed).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
    let name = path
        .file_name()
        .ok_or_else(|| FileError::new(path, FileProblem::Io(io::ErrorKind::InvalidInput.into())))?;
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp{}", std::process::id()));
    let tmp = path.with_file_name(tmp_name);
    let result = (|| {
        let mut f = fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = fs::remove_file(&tmp);
        FileError::new(path, FileProblem::Io(e))
    })
}

/// The scene camera: image size, pinhole intrinsics and the depth image's unit.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize, serde::Serialize)]
pub struct SceneCamera {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Focal length along x, pixels.
    pub fx: f32,
    /// Focal length along y, pixels.
    pub fy: f32,
    /// Principal point x, pixels.
    pub cx: f32,
    /// Principal point y, pixels.
    pub cy: f32,
    /// Metres per depth-image unit (0.001 for millimetres).
    pub depth_unit_m: f32,
}

impl SceneCamera {
    /// The pinhole intrinsics.
    ///
    /// # Errors
    /// As [`Intrinsics::new`].
    pub fn intrinsics(&self) -> Result<Intrinsics, riseg_core::Error> {
        Intrinsics::new(self.fx, self.fy, self.cx, self.cy)
    }
}

/// Reads and checks a scene camera file.
///
/// # Errors
/// [`FileProblem::Missing`], [`FileProblem::Io`], [`FileProblem::Json`], or
/// [`FileProblem::BadCamera`] for a zero size, bad intrinsics or a non-positive depth unit.
pub fn read_scene_camera(path: &Path) -> Result<SceneCamera, FileError> {
    let text = fs::read(path).map_err(|e| FileError::io(path, e))?;
    let cam: SceneCamera =
        serde_json::from_slice(&text).map_err(|e| FileError::new(path, FileProblem::Json(e)))?;
    let bad = |why| Err(FileError::new(path, FileProblem::BadCamera(why)));
    if cam.width == 0 || cam.height == 0 {
        return bad("width and height must be positive");
    }
    if cam.intrinsics().is_err() {
        return bad("fx, fy, cx, cy must be finite and fx, fy positive");
    }
    if !(cam.depth_unit_m.is_finite() && cam.depth_unit_m > 0.0) {
        return bad("depth_unit_m must be finite and positive");
    }
    Ok(cam)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("riseg-files-{name}-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn png_round_trips_and_errors_name_the_file() {
        let dir = tmp_dir("png");
        let p16 = dir.join("labels.png");
        write_gray16(&p16, 3, 2, &[0, 1, 2, 300, 65535, 7]).unwrap();
        let back = read_gray16(&p16).unwrap();
        assert_eq!(back.size(), (3, 2));
        assert_eq!(back.pixels, vec![0, 1, 2, 300, 65535, 7]);
        let e = read_rgb8(&p16).unwrap_err();
        assert!(matches!(e.problem, FileProblem::WrongFormat { .. }));
        assert!(e.to_string().contains("labels.png"));

        let p8 = dir.join("heat.png");
        write_gray8(&p8, 2, 1, &[5, 250]).unwrap();
        assert!(matches!(
            read_gray16(&p8).unwrap_err().problem,
            FileProblem::WrongFormat { .. }
        ));
        let rgb = dir.join("rgb.png");
        write_rgb8(&rgb, 1, 2, &[[1, 2, 3], [4, 5, 6]]).unwrap();
        assert_eq!(read_rgb8(&rgb).unwrap().pixels, vec![[1, 2, 3], [4, 5, 6]]);

        let corrupt = dir.join("corrupt.png");
        fs::write(&corrupt, b"\x89PNG\r\n\x1a\nnot really").unwrap();
        assert!(matches!(
            read_rgb8(&corrupt).unwrap_err().problem,
            FileProblem::CorruptPng(_)
        ));
        let missing = dir.join("missing.png");
        let e = read_gray16(&missing).unwrap_err();
        assert!(matches!(e.problem, FileProblem::Missing));
        assert!(e.to_string().contains("missing.png"));
        assert!(write_gray8(&p8, 2, 2, &[1]).is_err());
        // No temporary files are left behind.
        let names: Vec<_> = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert!(names.iter().all(|n| !n.to_string_lossy().contains(".tmp")));
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn camera_file_is_checked() {
        let dir = tmp_dir("camera");
        let path = dir.join("scene_camera.json");
        fs::write(
            &path,
            br#"{"width": 640, "height": 480, "fx": 615, "fy": 615, "cx": 319.5, "cy": 239.5,
                "depth_unit_m": 0.001}"#,
        )
        .unwrap();
        let cam = read_scene_camera(&path).unwrap();
        assert_eq!((cam.width, cam.depth_unit_m), (640, 0.001));
        fs::write(&path, br#"{"width": 640}"#).unwrap();
        assert!(matches!(
            read_scene_camera(&path).unwrap_err().problem,
            FileProblem::Json(_)
        ));
        fs::write(
            &path,
            br#"{"width": 640, "height": 480, "fx": 0, "fy": 615, "cx": 319.5, "cy": 239.5,
                "depth_unit_m": 0.001}"#,
        )
        .unwrap();
        assert!(matches!(
            read_scene_camera(&path).unwrap_err().problem,
            FileProblem::BadCamera(_)
        ));
        fs::remove_dir_all(&dir).unwrap();
    }
}
