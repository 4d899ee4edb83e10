//! The one error type of `riseg-core`: `Copy`, no strings, cheap to return from hot loops.

use core::fmt;

/// Which caller buffer a [`Error::BufferTooSmall`] is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Buffer {
    /// Output frames.
    Frames,
    /// Sampled-pixel scratch.
    Samples,
    /// Pairwise twist distances.
    PairDist,
    /// Per-frame scratch of the grouping stage.
    FrameScratch,
    /// Per-group scratch (motions, counts).
    Groups,
    /// Per-pixel scratch (splat depth, source index, component ids).
    Pixels,
    /// Breadth-first-search queue.
    Queue,
    /// Per-segment scratch.
    Segments,
    /// Output labels.
    Labels,
    /// Seed scratch of CorrectMask.
    Seeds,
    /// FindAction: each sample's squared distance to its nearest centre.
    SampleDist,
    /// FindAction: each sample's nearest centre (or certain region).
    SampleNearest,
    /// FindAction: certain and uncertain pixel counts of each row.
    RowCounts,
    /// FindAction: runs of certain pixels.
    Runs,
    /// FindAction: each row's first run.
    RowRuns,
}

/// Why a `riseg-core` call failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Error {
    /// A caller buffer is shorter than the call needs; nothing was written.
    BufferTooSmall {
        /// Which buffer.
        buffer: Buffer,
        /// Elements needed.
        needed: usize,
        /// Elements given.
        got: usize,
    },
    /// `width`/`height`/`stride` do not describe the data slice.
    BadImageLayout,
    /// Two inputs that must match in size do not.
    SizeMismatch,
    /// The three points are (nearly) collinear or coincide: no frame exists.
    DegenerateFrame,
    /// An input that must be finite holds NaN or infinity.
    NonFinite,
    /// A [`Config`](crate::Config) field is out of its documented range.
    BadConfig,
    /// More segments or groups than the fixed capacity (`u16` labels) allows.
    TooManyLabels,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::BufferTooSmall {
                buffer,
                needed,
                got,
            } => write!(f, "{buffer:?} buffer too small: need {needed}, got {got}"),
            Self::BadImageLayout => f.write_str("width, height and stride do not fit the data"),
            Self::SizeMismatch => f.write_str("inputs differ in size"),
            Self::DegenerateFrame => f.write_str("points are collinear: no frame exists"),
            Self::NonFinite => f.write_str("input holds NaN or infinity"),
            Self::BadConfig => f.write_str("config field out of range"),
            Self::TooManyLabels => f.write_str("more labels than u16 ids allow"),
        }
    }
}

impl core::error::Error for Error {}

/// Returns `Err(BufferTooSmall)` when `got < needed`.
pub(crate) const fn check_len(buffer: Buffer, needed: usize, got: usize) -> Result<(), Error> {
    if got < needed {
        Err(Error::BufferTooSmall {
            buffer,
            needed,
            got,
        })
    } else {
        Ok(())
    }
}
