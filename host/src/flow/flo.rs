//! Middlebury `.flo` files (Baker et al., "A Database and Evaluation Methodology for
//! Optical Flow"), and atomic file writes.
//!
//! ```text
//! bytes 0..4    f32  202021.25  (the ASCII bytes "PIEH")
//! bytes 4..8    i32  width  >= 1
//! bytes 8..12   i32  height >= 1
//! bytes 12..    f32  dx, dy for each pixel, row-major (width · height · 8 bytes)
//! ```
//! All values little-endian. A file whose length differs from the header's size is
//! rejected before anything is allocated, so a corrupt header cannot exhaust memory.

use super::{Flow, FlowError};
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// The float every `.flo` file starts with.
pub const FLO_MAGIC: f32 = 202_021.25;

/// What is wrong with a `.flo` byte stream or a flow that cannot be written as one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FloFormatError {
    /// Fewer than the 12 header bytes.
    #[error("{len} bytes is shorter than the 12-byte header")]
    TooShort {
        /// Bytes present.
        len: usize,
    },
    /// The first four bytes are not the magic float.
    #[error("bad magic {found} (expected 202021.25)")]
    BadMagic {
        /// The float found.
        found: f32,
    },
    /// Width or height is below 1, or too large for the format.
    #[error("bad size {width}x{height}")]
    BadSize {
        /// Width as stored (or as given).
        width: i64,
        /// Height as stored (or as given).
        height: i64,
    },
    /// The body's length does not match the header.
    #[error("body has {found} bytes, {expected} expected")]
    Length {
        /// Bytes the header requires.
        expected: u64,
        /// Bytes present.
        found: u64,
    },
}

/// Why reading or writing a `.flo` file failed; names the file.
#[derive(Debug, thiserror::Error)]
#[error("{}: {problem}", path.display())]
pub struct FloError {
    /// The file.
    pub path: PathBuf,
    /// What went wrong.
    pub problem: FloProblem,
}

/// The cause inside a [`FloError`].
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FloProblem {
    /// The file could not be read or written.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// The bytes are not a valid `.flo` file.
    #[error("not a valid .flo file: {0}")]
    Format(#[from] FloFormatError),
}

/// The `.flo` bytes of `flow`.
///
/// # Errors
/// [`FloFormatError::BadSize`] if the flow is empty or a side exceeds `i32::MAX`.
pub fn encode_flo(flow: &Flow) -> Result<Vec<u8>, FloFormatError> {
    let (w, h) = (flow.width(), flow.height());
    let bad = || FloFormatError::BadSize {
        width: i64::try_from(w).unwrap_or(i64::MAX),
        height: i64::try_from(h).unwrap_or(i64::MAX),
    };
    let wi = i32::try_from(w).map_err(|_| bad())?;
    let hi = i32::try_from(h).map_err(|_| bad())?;
    if wi < 1 || hi < 1 {
        return Err(bad());
    }
    let mut out = Vec::with_capacity(12 + 8 * flow.as_slice().len());
    out.extend_from_slice(&FLO_MAGIC.to_le_bytes());
    out.extend_from_slice(&wi.to_le_bytes());
    out.extend_from_slice(&hi.to_le_bytes());
    for v in flow.as_slice() {
        out.extend_from_slice(&v[0].to_le_bytes());
        out.extend_from_slice(&v[1].to_le_bytes());
    }
    Ok(out)
}

/// Parses `.flo` bytes.
///
/// # Errors
/// A [`FloFormatError`] naming the first problem found.
pub fn decode_flo(bytes: &[u8]) -> Result<Flow, FloFormatError> {
    let (header, body) = bytes
        .split_first_chunk::<12>()
        .ok_or(FloFormatError::TooShort { len: bytes.len() })?;
    let word = |i: usize| [header[i], header[i + 1], header[i + 2], header[i + 3]];
    let magic = f32::from_le_bytes(word(0));
    if magic != FLO_MAGIC {
        return Err(FloFormatError::BadMagic { found: magic });
    }
    let (wi, hi) = (i32::from_le_bytes(word(4)), i32::from_le_bytes(word(8)));
    if wi < 1 || hi < 1 {
        return Err(FloFormatError::BadSize {
            width: wi.into(),
            height: hi.into(),
        });
    }
    // Saturates only above any possible body length.
    let expected = (u64::from(wi.unsigned_abs()) * u64::from(hi.unsigned_abs())).saturating_mul(8);
    if expected != body.len() as u64 {
        return Err(FloFormatError::Length {
            expected,
            found: body.len() as u64,
        });
    }
    let data = body
        .chunks_exact(8)
        .map(|c| {
            [
                f32::from_le_bytes([c[0], c[1], c[2], c[3]]),
                f32::from_le_bytes([c[4], c[5], c[6], c[7]]),
            ]
        })
        .collect();
    // The sides are positive i32s and the body length matched, so this cannot fail.
    Flow::new(wi.unsigned_abs() as usize, hi.unsigned_abs() as usize, data).map_err(
        |_: FlowError| FloFormatError::Length {
            expected,
            found: body.len() as u64,
        },
    )
}

/// Reads a `.flo` file.
///
/// # Errors
/// A [`FloError`] naming `path` if it cannot be read or is not a valid `.flo` file.
pub fn read_flo(path: &Path) -> Result<Flow, FloError> {
    let err = |problem: FloProblem| FloError {
        path: path.to_path_buf(),
        problem,
    };
    let bytes = std::fs::read(path).map_err(|e| err(e.into()))?;
    decode_flo(&bytes).map_err(|e| err(e.into()))
}

/// Writes `flow` to `path` atomically ([`write_atomic`]).
///
/// # Errors
/// A [`FloError`] naming `path` if the flow cannot be encoded or the file written.
pub fn write_flo(path: &Path, flow: &Flow) -> Result<(), FloError> {
    let err = |problem: FloProblem| FloError {
        path: path.to_path_buf(),
        problem,
    };
    let bytes = encode_flo(flow).map_err(|e| err(e.into()))?;
    write_atomic(path, &bytes).map_err(|e| err(e.into()))
}

/// Writes `bytes` to a temporary file beside `path`, flushes it to disk and renames it
/// over `path`: readers see the old file or the whole new one, never a partial one. The
/// temporary file is removed if anything fails.
///
/// # Errors
/// The I/O error of the step that failed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let name = path.file_name().ok_or_else(|| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "the path has no file name",
        )
    })?;
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp{}", std::process::id()));
    let tmp = path.with_file_name(tmp_name);
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        // Best effort: the temporary file may not exist.
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Flow {
        let data = (0..12)
            .map(|i| [i as f32 * 0.5 - 2.0, -(i as f32) * 1.25])
            .collect();
        Flow::new(4, 3, data).unwrap()
    }

    #[test]
    fn bytes_round_trip_and_header_layout() {
        let f = sample();
        let b = encode_flo(&f).unwrap();
        assert_eq!(&b[..4], b"PIEH");
        assert_eq!(b.len(), 12 + 12 * 8);
        assert_eq!(i32::from_le_bytes([b[4], b[5], b[6], b[7]]), 4);
        assert_eq!(decode_flo(&b).unwrap(), f);
    }

    #[test]
    fn file_round_trip_leaves_no_temporary() {
        let dir = std::env::temp_dir().join(format!("riseg-flo-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.flo");
        write_flo(&path, &sample()).unwrap();
        assert_eq!(read_flo(&path).unwrap(), sample());
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert_eq!(names.len(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn corrupt_bytes_are_errors() {
        let b = encode_flo(&sample()).unwrap();
        assert!(matches!(
            decode_flo(&b[..5]),
            Err(FloFormatError::TooShort { len: 5 })
        ));
        assert!(matches!(
            decode_flo(&b[..b.len() - 1]),
            Err(FloFormatError::Length { .. })
        ));
        let mut bad = b.clone();
        bad[0] ^= 1;
        assert!(matches!(
            decode_flo(&bad),
            Err(FloFormatError::BadMagic { .. })
        ));
        let mut huge = b[..12].to_vec();
        huge[4..8].copy_from_slice(&i32::MAX.to_le_bytes());
        huge[8..12].copy_from_slice(&i32::MAX.to_le_bytes());
        assert!(matches!(
            decode_flo(&huge),
            Err(FloFormatError::Length { .. })
        ));
        let mut neg = b.clone();
        neg[8..12].copy_from_slice(&(-3i32).to_le_bytes());
        assert!(matches!(
            decode_flo(&neg),
            Err(FloFormatError::BadSize { .. })
        ));
        let empty = Flow::new(0, 0, Vec::new()).unwrap();
        assert!(encode_flo(&empty).is_err());
    }

    #[test]
    fn missing_file_error_names_it() {
        let e = read_flo(Path::new("/nonexistent/riseg/x.flo")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/riseg/x.flo"), "{e}");
    }
}
