//! Formats: owned images and PNG ([`image`]), the Middlebury `.flo` flow format
//! ([`image::read_flo`] and friends), atomic writes, and the scene folder ([`scene`]).
//! Pure: nothing here names the CLI, the simulator or the loop.

pub mod image;
pub mod scene;
