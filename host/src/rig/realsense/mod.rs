//! Intel RealSense D415 (any librealsense2 depth camera with an RGB colour stream) as a
//! [`Camera`] (feature `realsense`).
//!
//! # Contract
//!
//! - librealsense2 is loaded at run time: the file `RISEG_REALSENSE_LIB` names, else the
//!   first of [`LIBRARY_NAMES`] the system's loader finds. No library and no device are
//!   two distinct errors ([`RealSenseError::LibraryMissing`], [`RealSenseError::NoDevice`]).
//! - Colour (RGB8) and depth (Z16) stream at [`RealSenseConfig`]'s size and rate; depth is
//!   filtered (spatial and temporal on, hole filling off by default: filled holes are
//!   invented geometry at exactly the seams RISeg looks at), then aligned to colour by
//!   librealsense's `align` block, and converted to metres with the device's depth unit.
//! - The intrinsics are the colour stream's, from the device (librealsense's `ppx`, `ppy`
//!   put pixel `(x, y)`'s centre at `(x, y)`, as riseg's `cx`, `cy` do). librealsense reports a
//!   distortion model; the loop uses a pinhole, so non-zero distortion coefficients are
//!   logged once as a warning (a D415's colour stream reports zeros).
//! - [`RealSenseConfig::warmup_frames`] framesets are dropped at start (auto-exposure
//!   settles); each [`Camera::capture`] first drops [`RealSenseConfig::settle_frames`]
//!   framesets, so the frame returned was taken after the robot stopped, not buffered
//!   before.
//! - Any librealsense error while streaming (the camera unplugged, no frame within
//!   [`RealSenseConfig::timeout_ms`]) is a [`CameraError`] naming the device and the call;
//!   the loop stops on it.
//!
//! The FFI is confined to the private `ffi` module (the one place in riseg with `unsafe`).

#[allow(unsafe_code)]
mod ffi;

use std::path::PathBuf;

use riseg_core::Intrinsics;

use crate::{
    io::image::{DepthImage, RgbImage},
    rig::camera::{Camera, CameraError, CameraFrame},
};

/// Environment variable naming the librealsense2 shared library to load.
pub const LIBRARY_ENV: &str = "RISEG_REALSENSE_LIB";

/// Names tried, in order, when [`LIBRARY_ENV`] is not set: the development symlink, the
/// sonames of Intel's packages and source builds (2.50 to 2.59), the same under
/// `/usr/local/lib` (a source build's default prefix), and the macOS and Windows names.
pub const LIBRARY_NAMES: &[&str] = &[
    "librealsense2.so",
    "librealsense2.so.2.59",
    "librealsense2.so.2.58",
    "librealsense2.so.2.57",
    "librealsense2.so.2.56",
    "librealsense2.so.2.55",
    "librealsense2.so.2.54",
    "librealsense2.so.2.53",
    "librealsense2.so.2.52",
    "librealsense2.so.2.51",
    "librealsense2.so.2.50",
    "/usr/local/lib/librealsense2.so",
    "librealsense2.dylib",
    "realsense2.dll",
];

/// Stream settings of a [`RealSense`] camera.
#[derive(Debug, Clone, PartialEq)]
pub struct RealSenseConfig {
    /// The librealsense2 library file; `None`: [`LIBRARY_ENV`], then [`LIBRARY_NAMES`].
    pub library: Option<PathBuf>,
    /// Colour (and aligned depth) width, pixels. A D415 streams both at 640x480, 848x480,
    /// 1280x720.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Frames per second of both streams (6, 15, 30 or 60 on a D415, by size).
    pub fps: u32,
    /// Framesets dropped after the start (auto-exposure settles).
    pub warmup_frames: u32,
    /// Framesets dropped before each capture (the newest after the robot stopped).
    pub settle_frames: u32,
    /// Longest wait for one frameset, milliseconds.
    pub timeout_ms: u32,
    /// librealsense's edge-preserving spatial filter.
    pub spatial_filter: bool,
    /// librealsense's temporal filter (averages the settle frames on a still scene).
    pub temporal_filter: bool,
    /// librealsense's hole filling (invents depth; off by default).
    pub hole_filling: bool,
}

impl Default for RealSenseConfig {
    fn default() -> Self {
        Self {
            library: None,
            width: 640,
            height: 480,
            fps: 30,
            warmup_frames: 30,
            settle_frames: 5,
            timeout_ms: 5000,
            spatial_filter: true,
            temporal_filter: true,
            hole_filling: false,
        }
    }
}

/// Why a RealSense camera could not start.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RealSenseError {
    /// librealsense2 is not installed where it was looked for.
    #[error(
        "RealSense: librealsense2 not found (tried {tried}); install librealsense2 (Intel's \
         packages or a source build) or set {LIBRARY_ENV}=/path/to/librealsense2.so"
    )]
    LibraryMissing {
        /// Each file tried and the loader's message.
        tried: String,
    },
    /// The library lacks a function the driver needs.
    #[error("RealSense: {path} has no {symbol}: not librealsense2 2.50 or later")]
    NotLibrealsense {
        /// The library file.
        path: String,
        /// The missing function.
        symbol: String,
    },
    /// The library works and sees no camera.
    #[error(
        "RealSense: no device connected (librealsense2 {library} found none); plug the D415 \
         into a USB 3 port and check it with rs-enumerate-devices"
    )]
    NoDevice {
        /// The library file.
        library: String,
    },
    /// librealsense refused to start the streams.
    #[error("RealSense (librealsense2 {library}): {message}")]
    Device {
        /// The library file.
        library: String,
        /// librealsense's function and message.
        message: String,
    },
    /// A setting is out of range.
    #[error("RealSense: {0}")]
    Config(String),
}

/// A RealSense camera streaming aligned colour and depth (module docs).
#[derive(Debug)]
pub struct RealSense {
    session: ffi::Session,
    config: RealSenseConfig,
    library: String,
    warned_distortion: bool,
}

impl RealSense {
    /// Loads librealsense2, opens the first device and starts streaming (module docs).
    ///
    /// # Errors
    /// [`RealSenseError`]: which of library, device or stream start failed, and why.
    pub fn open(config: RealSenseConfig) -> Result<Self, RealSenseError> {
        let int = |v: u32, what: &str| {
            i32::try_from(v)
                .ok()
                .filter(|&v| v > 0)
                .ok_or_else(|| RealSenseError::Config(format!("{what} {v} is not a positive size")))
        };
        let req = ffi::StreamRequest {
            width: int(config.width, "width")?,
            height: int(config.height, "height")?,
            fps: int(config.fps, "frame rate")?,
            spatial: config.spatial_filter,
            temporal: config.temporal_filter,
            hole_filling: config.hole_filling,
        };
        let library = config
            .library
            .clone()
            .or_else(|| std::env::var_os(LIBRARY_ENV).map(PathBuf::from));
        let (mut session, library) =
            ffi::Session::start(library.as_deref(), &req).map_err(|e| match e {
                ffi::StartError::Load(ffi::LoadError::NotFound(tried)) => {
                    RealSenseError::LibraryMissing {
                        tried: tried
                            .iter()
                            .map(|(name, why)| format!("{name}: {why}"))
                            .collect::<Vec<_>>()
                            .join("; "),
                    }
                }
                ffi::StartError::Load(ffi::LoadError::MissingSymbol { path, symbol }) => {
                    RealSenseError::NotLibrealsense { path, symbol }
                }
                ffi::StartError::NoDevice(library) => RealSenseError::NoDevice { library },
                ffi::StartError::Device(library, message) => {
                    RealSenseError::Device { library, message }
                }
            })?;
        for i in 0..config.warmup_frames {
            session
                .skip(config.timeout_ms)
                .map_err(|message| RealSenseError::Device {
                    library: library.clone(),
                    message: format!("warm-up frame {i}: {message}"),
                })?;
        }
        log::info!(
            "RealSense: streaming {}x{} at {} fps through {library}",
            config.width,
            config.height,
            config.fps
        );
        Ok(Self {
            session,
            config,
            library,
            warned_distortion: false,
        })
    }

    fn lost(&self, message: &str) -> CameraError {
        CameraError(format!(
            "RealSense (librealsense2 {}): {message}; camera unplugged or stalled?",
            self.library
        ))
    }
}

impl Camera for RealSense {
    fn capture(&mut self) -> Result<CameraFrame, CameraError> {
        let timeout_ms = self.config.timeout_ms;
        for _ in 0..self.config.settle_frames {
            self.session.skip(timeout_ms).map_err(|e| self.lost(&e))?;
        }
        let c = self
            .session
            .capture(timeout_ms)
            .map_err(|e| self.lost(&e))?;
        let i = c.intrinsics;
        if (i.width, i.height) != (c.width as i32, c.height as i32) {
            return Err(self.lost(&format!(
                "colour intrinsics are for {}x{}, the frame is {}x{}",
                i.width, i.height, c.width, c.height
            )));
        }
        if !self.warned_distortion && i.coeffs.iter().any(|&k| k != 0.0) {
            self.warned_distortion = true;
            log::warn!(
                "RealSense: the colour stream reports {} distortion {:?}; riseg uses a pinhole \
                 model and ignores it",
                i.model_name(),
                i.coeffs
            );
        }
        let unit = c.depth_unit_m;
        let depth: Vec<f32> = c.depth_raw.iter().map(|&d| f32::from(d) * unit).collect();
        let size_err = |e: crate::io::image::ImageSizeError| self.lost(&e.to_string());
        Ok(CameraFrame {
            rgb: RgbImage::from_vec(
                c.width,
                c.height,
                c.rgb.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect(),
            )
            .map_err(size_err)?,
            depth_m: DepthImage::from_vec(c.width, c.height, depth).map_err(size_err)?,
            intrinsics: Intrinsics {
                fx: i.fx,
                fy: i.fy,
                cx: i.ppx,
                cy: i.ppy,
            },
            truth: None,
            truth_poses: None,
        })
    }
}
