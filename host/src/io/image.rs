//! The host's one owned image type and its files: 8-bit RGB PNG, 16-bit grey PNG (depth,
//! labels), 8-bit grey PNG (heatmaps) and Middlebury `.flo` optical flow.
//!
//! Contract:
//! - [`Image<T>`] is row-major with no padding: pixel `(x, y)` is `data[y·width + x]`, and
//!   `data.len() == width·height` always holds (checked on construction). Sizes are
//!   `usize`. Every image in the host is one ([`RgbImage`], [`DepthImage`], [`FlowImage`],
//!   labels and heatmaps); [`Image::view`] lends it to riseg-core, to the flow estimators
//!   and to the segmenter as an [`ImageView`] without copying.
//! - Every reader error is an [`ImageIoError`] whose message starts with the file's path and
//!   then says the problem: missing file, unreadable file, corrupt PNG, wrong colour type or
//!   bit depth, wrong size (see [`ImageIoError::expect_size`]), or a malformed `.flo`.
//!   Readers never panic on any file content.
//! - Every writer is atomic: the bytes go to a temporary file in the destination's folder,
//!   which is flushed to disk and then renamed over the destination, so a reader sees either
//!   the old file, or the complete new one, never half a file ([`super::write_atomic`]).
//!   The `_as` writers take a [`Durability`]: [`Durability::Derived`] skips the flush for
//!   outputs a command can compute again (the contract is in [`Durability`]'s docs).
//! - Encoding is deterministic: the same image gives the same bytes.
//!
//! `.flo` (Middlebury): little-endian `f32` magic `202021.25` (the bytes `PIEH`), `i32`
//! width, `i32` height, then `width·height` pairs of `f32` `(dx, dy)` in row-major order.
//! Flow is in pixels: the pixel `(x, y)` of the first image moves to `(x + dx, y + dy)`.

use std::{
    borrow::Cow,
    fs::File,
    io::{self, BufReader, Cursor, Write as _},
    path::{Path, PathBuf},
};

use riseg_core::ImageView;

use super::files::{DiskFiles, Files};
use super::{Durability, write_atomic_as};

use image::{
    DynamicImage, ExtendedColorType, ImageDecoder as _, ImageEncoder,
    codecs::png::{CompressionType, FilterType, PngDecoder, PngEncoder},
};

/// An owned, row-major image without padding.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image<T> {
    width: usize,
    height: usize,
    data: Vec<T>,
}

/// The most pixels riseg decodes from one file or accepts in a scene's camera: 16.8
/// million (4096 x 4096, a 5K frame). A PNG header declaring more is refused before any
/// pixel memory is allocated, so a corrupt or hostile 74-byte file cannot exhaust memory.
pub const MAX_IMAGE_PIXELS: usize = 1 << 24;

/// 8-bit RGB pixels.
pub type RgbImage = Image<[u8; 3]>;
/// 16-bit grey pixels: depth in the scene's depth unit, or instance labels.
pub type Gray16Image = Image<u16>;
/// Optical flow `(dx, dy)` in pixels.
pub type FlowImage = Image<[f32; 2]>;
/// Depth in metres, `0.0` where there is no reading.
pub type DepthImage = Image<f32>;
/// 8-bit grey pixels: a heatmap, a mask.
pub type Gray8Image = Image<u8>;

/// `data.len()` does not match `width·height` in [`Image::from_vec`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("image data has {len} pixels, which is not {width}x{height}")]
pub struct ImageSizeError {
    /// Requested width, pixels.
    pub width: usize,
    /// Requested height, pixels.
    pub height: usize,
    /// Pixels supplied.
    pub len: usize,
}

impl<T> Image<T> {
    /// Wraps row-major pixels.
    ///
    /// # Errors
    /// [`ImageSizeError`] if `data.len() != width·height`.
    pub fn from_vec(width: usize, height: usize, data: Vec<T>) -> Result<Self, ImageSizeError> {
        let needed = width.checked_mul(height);
        if needed == Some(data.len()) {
            Ok(Self {
                width,
                height,
                data,
            })
        } else {
            Err(ImageSizeError {
                width,
                height,
                len: data.len(),
            })
        }
    }

    /// An image whose pixel `(x, y)` is `f(x, y)`, built row by row.
    ///
    /// # Panics
    /// If `width·height` overflows `usize` (no such image fits in memory).
    pub fn from_fn(width: usize, height: usize, mut f: impl FnMut(usize, usize) -> T) -> Self {
        let pixels = width
            .checked_mul(height)
            .expect("image size overflows usize");
        let mut data = Vec::with_capacity(pixels);
        for y in 0..height {
            for x in 0..width {
                data.push(f(x, y));
            }
        }
        Self {
            width,
            height,
            data,
        }
    }

    /// Width, pixels.
    #[must_use]
    pub const fn width(&self) -> usize {
        self.width
    }

    /// Height, pixels.
    #[must_use]
    pub const fn height(&self) -> usize {
        self.height
    }

    /// `(width, height)`, pixels.
    #[must_use]
    pub const fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The pixel at `(x, y)`, or `None` outside the image.
    #[must_use]
    pub fn get(&self, x: usize, y: usize) -> Option<&T> {
        if x < self.width && y < self.height {
            self.data.get(y * self.width + x)
        } else {
            None
        }
    }

    /// The image lent as a riseg-core view (packed: the stride is the width).
    #[must_use]
    pub fn view(&self) -> ImageView<'_, T> {
        ImageView::packed(self.width, self.height, &self.data)
            .expect("an Image holds exactly width·height pixels")
    }

    /// All pixels, row-major.
    #[must_use]
    pub fn as_slice(&self) -> &[T] {
        &self.data
    }

    /// All pixels, row-major, mutable (the size cannot change).
    pub fn as_mut_slice(&mut self) -> &mut [T] {
        &mut self.data
    }

    /// The pixel vector, row-major.
    #[must_use]
    pub fn into_vec(self) -> Vec<T> {
        self.data
    }

    /// A new image of the same size with `f` applied to every pixel.
    #[must_use]
    pub fn map<U>(&self, f: impl FnMut(&T) -> U) -> Image<U> {
        Image {
            width: self.width,
            height: self.height,
            data: self.data.iter().map(f).collect(),
        }
    }
}

/// Why reading or writing an image file failed; the message names the file.
#[derive(Debug, thiserror::Error)]
#[error("{}: {problem}", path.display())]
pub struct ImageIoError {
    /// The file.
    pub path: PathBuf,
    /// What is wrong with it.
    pub problem: ImageProblem,
}

/// What is wrong with an image file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImageProblem {
    /// The file does not exist.
    #[error("file not found")]
    Missing,
    /// The operating system refused to read, write or rename the file.
    #[error("I/O error: {0}")]
    Io(#[source] io::Error),
    /// The bytes are not a PNG the decoder accepts.
    #[error("corrupt or unsupported PNG: {0}")]
    CorruptPng(#[source] image::ImageError),
    /// A valid PNG of the wrong colour type or bit depth.
    #[error("expected {expected}, found {found}")]
    WrongFormat {
        /// What the caller needs, e.g. "16-bit greyscale PNG".
        expected: &'static str,
        /// What the file holds, e.g. "8-bit greyscale".
        found: String,
    },
    /// The image is valid but not the size the caller needs.
    #[error("expected {expected_width}x{expected_height} pixels, found {width}x{height}")]
    WrongSize {
        /// Width the caller needs.
        expected_width: usize,
        /// Height the caller needs.
        expected_height: usize,
        /// Width in the file.
        width: usize,
        /// Height in the file.
        height: usize,
    },
    /// The file declares more than [`MAX_IMAGE_PIXELS`]; it was not decoded.
    #[error("declares {width}x{height} pixels, more than the {MAX_IMAGE_PIXELS} riseg reads")]
    TooManyPixels {
        /// Declared width.
        width: usize,
        /// Declared height.
        height: usize,
    },
    /// An image to write has a side beyond what a PNG can hold (`u32`).
    #[error("a {width}x{height} image is too large for a PNG")]
    TooLargeForPng {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
    },
    /// The `.flo` file is malformed.
    #[error("not a valid Middlebury .flo file: {0}")]
    CorruptFlo(#[source] FloFormatError),
}

impl ImageIoError {
    fn new(path: &Path, problem: ImageProblem) -> Self {
        Self {
            path: path.to_path_buf(),
            problem,
        }
    }

    fn io(path: &Path, e: io::Error) -> Self {
        let problem = if e.kind() == io::ErrorKind::NotFound {
            ImageProblem::Missing
        } else {
            ImageProblem::Io(e)
        };
        Self::new(path, problem)
    }

    /// Checks that `image`, read from `path`, is `width` x `height` pixels.
    ///
    /// # Errors
    /// [`ImageProblem::WrongSize`] naming `path` otherwise.
    pub fn expect_size<T>(
        path: &Path,
        image: &Image<T>,
        width: usize,
        height: usize,
    ) -> Result<(), Self> {
        if image.width == width && image.height == height {
            Ok(())
        } else {
            Err(Self::new(
                path,
                ImageProblem::WrongSize {
                    expected_width: width,
                    expected_height: height,
                    width: image.width,
                    height: image.height,
                },
            ))
        }
    }
}

/// [`write_atomic_as`] with an error naming `path`.
fn write_file(path: &Path, bytes: &[u8], durability: Durability) -> Result<(), ImageIoError> {
    write_atomic_as(path, durability, |file| file.write_all(bytes))
        .map_err(|e| ImageIoError::new(path, ImageProblem::Io(e)))
}

fn read_bytes<'a>(files: &'a impl Files, path: &Path) -> Result<Cow<'a, [u8]>, ImageIoError> {
    files.read(path).map_err(|e| ImageIoError::io(path, e))
}

/// The size the PNG header of `bytes` declares (read from the header alone).
fn png_size(path: &Path, bytes: &[u8]) -> Result<(usize, usize), ImageIoError> {
    let decoder = PngDecoder::new(Cursor::new(bytes))
        .map_err(|e| ImageIoError::new(path, ImageProblem::CorruptPng(e)))?;
    let (width, height) = decoder.dimensions();
    Ok((width as usize, height as usize))
}

/// The most bytes a PNG decoder may allocate: a [`MAX_IMAGE_PIXELS`] image of 16-bit RGBA,
/// the widest PNG pixel, plus room for the decoder's own rows.
const MAX_DECODER_BYTES: usize = 2 * MAX_IMAGE_PIXELS * 8;

/// What [`decode_png`] found: an 8-bit RGB PNG decoded straight into its pixel buffer, or
/// any other PNG decoded for conversion.
enum Decoded {
    Rgb8(RgbImage),
    Other(DynamicImage),
}

impl Decoded {
    /// The image as 8-bit RGB ([`read_png_as_rgb8`]'s conversion).
    fn into_rgb8(self, path: &Path) -> Result<RgbImage, ImageIoError> {
        match self {
            Self::Rgb8(rgb) => Ok(rgb),
            Self::Other(other) => {
                let rgb = other.into_rgb8();
                let (width, height) = rgb.dimensions();
                let data = rgb.as_raw().as_chunks::<3>().0.to_vec();
                from_decoded(path, width, height, data)
            }
        }
    }

    /// The error for a PNG that is not of the `expected` kind.
    fn wrong_format(&self, path: &Path, expected: &'static str) -> ImageIoError {
        let found = match self {
            Self::Rgb8(_) => "8-bit RGB".into(),
            Self::Other(other) => format_name(other),
        };
        ImageIoError::new(path, ImageProblem::WrongFormat { expected, found })
    }
}

/// `TooManyPixels` when a declared `width x height` exceeds [`MAX_IMAGE_PIXELS`].
fn check_pixel_count(path: &Path, width: usize, height: usize) -> Result<(), ImageIoError> {
    if width.saturating_mul(height) > MAX_IMAGE_PIXELS {
        return Err(ImageIoError::new(
            path,
            ImageProblem::TooManyPixels { width, height },
        ));
    }
    Ok(())
}

/// Decodes `path` from `files` after checking the declared size against
/// [`MAX_IMAGE_PIXELS`] (the decoder's allocation is capped to match). An 8-bit RGB PNG is
/// decoded straight into the [`RgbImage`] buffer (no second copy).
fn decode_png(files: &impl Files, path: &Path) -> Result<Decoded, ImageIoError> {
    let bytes = read_bytes(files, path)?;
    let (width, height) = png_size(path, &bytes)?;
    check_pixel_count(path, width, height)?;
    let corrupt = |e| ImageIoError::new(path, ImageProblem::CorruptPng(e));
    let mut decoder = PngDecoder::new(Cursor::new(&*bytes)).map_err(corrupt)?;
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_DECODER_BYTES as u64);
    decoder.set_limits(limits).map_err(corrupt)?;
    if decoder.color_type() == image::ColorType::Rgb8 {
        let mut data = vec![[0u8; 3]; width * height];
        decoder
            .read_image(data.as_flattened_mut())
            .map_err(corrupt)?;
        let rgb =
            Image::from_vec(width, height, data).expect("the buffer has width x height pixels");
        return Ok(Decoded::Rgb8(rgb));
    }
    DynamicImage::from_decoder(decoder)
        .map(Decoded::Other)
        .map_err(corrupt)
}

fn format_name(image: &DynamicImage) -> String {
    match image {
        DynamicImage::ImageLuma8(_) => "8-bit greyscale".into(),
        DynamicImage::ImageLumaA8(_) => "8-bit greyscale with alpha".into(),
        DynamicImage::ImageRgb8(_) => "8-bit RGB".into(),
        DynamicImage::ImageRgba8(_) => "8-bit RGBA".into(),
        DynamicImage::ImageLuma16(_) => "16-bit greyscale".into(),
        DynamicImage::ImageLumaA16(_) => "16-bit greyscale with alpha".into(),
        DynamicImage::ImageRgb16(_) => "16-bit RGB".into(),
        DynamicImage::ImageRgba16(_) => "16-bit RGBA".into(),
        other => format!("{:?}", other.color()),
    }
}

/// Reads `path` with `read` (one of this module's readers) and checks that the image is
/// `width` x `height` pixels. A PNG's declared size is checked before it is decoded, so a
/// file of the wrong size costs no pixel memory.
///
/// # Errors
/// `read`'s errors, or [`ImageProblem::WrongSize`] naming `path`.
pub fn read_sized<T>(
    path: &Path,
    width: usize,
    height: usize,
    read: impl FnOnce(&Path) -> Result<Image<T>, ImageIoError>,
) -> Result<Image<T>, ImageIoError> {
    read_sized_in(&DiskFiles, path, width, height, read)
}

/// [`read_sized`] with the PNG header read from `files`.
///
/// # Errors
/// As [`read_sized`].
pub fn read_sized_in<T>(
    files: &impl Files,
    path: &Path,
    width: usize,
    height: usize,
    read: impl FnOnce(&Path) -> Result<Image<T>, ImageIoError>,
) -> Result<Image<T>, ImageIoError> {
    const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];
    // A file that cannot be read, or is no PNG, is left to `read` to name.
    if let Ok(bytes) = files.read(path)
        && bytes.starts_with(&PNG_SIGNATURE)
    {
        let (declared_width, declared_height) = png_size(path, &bytes)?;
        if (declared_width, declared_height) != (width, height) {
            return Err(ImageIoError::new(
                path,
                ImageProblem::WrongSize {
                    expected_width: width,
                    expected_height: height,
                    width: declared_width,
                    height: declared_height,
                },
            ));
        }
    }
    let image = read(path)?;
    ImageIoError::expect_size(path, &image, width, height)?;
    Ok(image)
}

/// Reads an 8-bit RGB PNG. An 8-bit RGBA PNG is accepted too (alpha is dropped), since
/// other tools save colour images that way.
///
/// # Errors
/// Missing file, I/O error, corrupt PNG, or any other colour type or bit depth.
pub fn read_rgb8(path: &Path) -> Result<RgbImage, ImageIoError> {
    read_rgb8_in(&DiskFiles, path)
}

/// [`read_rgb8`] from `files`.
///
/// # Errors
/// As [`read_rgb8`].
pub fn read_rgb8_in(files: &impl Files, path: &Path) -> Result<RgbImage, ImageIoError> {
    match decode_png(files, path)? {
        Decoded::Rgb8(rgb) => Ok(rgb),
        Decoded::Other(DynamicImage::ImageRgba8(img)) => {
            let (width, height) = img.dimensions();
            let pixels = img.as_raw().as_chunks::<4>().0;
            let data = pixels.iter().map(|c| [c[0], c[1], c[2]]).collect();
            from_decoded(path, width, height, data)
        }
        other => Err(other.wrong_format(path, "8-bit RGB PNG")),
    }
}

/// Reads a PNG of any colour type and bit depth converted to 8-bit RGB: grey is repeated
/// in the three channels, alpha is dropped, 16-bit samples are scaled to 8 bits. For
/// pictures from other tools (`riseg flow`); scene frames use the strict [`read_rgb8`].
///
/// # Errors
/// Missing file, I/O error, or corrupt PNG.
pub fn read_png_as_rgb8(path: &Path) -> Result<RgbImage, ImageIoError> {
    read_png_as_rgb8_mapped(path, |&rgb| rgb)
}

/// [`read_png_as_rgb8`] with every pixel mapped through `pixel` (`riseg flow` keeps only
/// the luma), without holding the whole RGB image: a non-interlaced PNG that decodes to
/// 8-bit RGB, what cameras and `riseg gen` write, is decoded from the file one row at a
/// time, so neither the file's bytes nor its RGB pixels are ever held whole (in a
/// one-shot `riseg flow` on a 640x480 pair, about 650 fewer fresh pages to fault in). Any
/// other PNG is decoded whole and converted as [`read_png_as_rgb8`] says.
///
/// # Errors
/// As [`read_png_as_rgb8`].
pub fn read_png_as_rgb8_mapped<T>(
    path: &Path,
    mut pixel: impl FnMut(&[u8; 3]) -> T,
) -> Result<Image<T>, ImageIoError> {
    // A file cut short is corrupt; any other failure to read it is an I/O error.
    let failed = |e| match e {
        png::DecodingError::IoError(e) if e.kind() != std::io::ErrorKind::UnexpectedEof => {
            ImageIoError::io(path, e)
        }
        e => ImageIoError::new(path, ImageProblem::CorruptPng(png_error(e))),
    };
    let file = File::open(path).map_err(|e| ImageIoError::io(path, e))?;
    let mut decoder = png::Decoder::new_with_limits(
        BufReader::with_capacity(PNG_READ_BYTES, file),
        png::Limits {
            bytes: MAX_DECODER_BYTES,
        },
    );
    // The output colour types `image`'s decoder gives (`decode_png`'s path).
    decoder.set_transformations(png::Transformations::EXPAND);
    // The declared size first: `read_info` already reserves a row against the limit.
    let (png_width, png_height) = {
        let info = decoder.read_header_info().map_err(failed)?;
        (info.width, info.height)
    };
    let (width, height) = (png_width as usize, png_height as usize);
    check_pixel_count(path, width, height)?;
    let mut reader = decoder.read_info().map_err(failed)?;
    let interlaced = reader.info().interlaced;
    if interlaced || reader.output_color_type() != (png::ColorType::Rgb, png::BitDepth::Eight) {
        return Ok(decode_png(&DiskFiles, path)?.into_rgb8(path)?.map(pixel));
    }
    let mut data = Vec::with_capacity(width * height);
    // The last call also reads the rest of the image data, as a whole-image decode does.
    while let Some(row) = reader.next_row().map_err(failed)? {
        data.extend(row.data().as_chunks::<3>().0.iter().map(&mut pixel));
    }
    from_decoded(path, png_width, png_height, data)
}

/// The read buffer of [`read_png_as_rgb8_mapped`], bytes: a 450 KB frame is read in 8
/// system calls instead of the 56 of `BufReader`'s default 8 KiB (about 15 us less per
/// file).
const PNG_READ_BYTES: usize = 64 << 10;

/// A `png` crate error as the `image` crate reports it (its own conversion is private), so
/// that both decoding paths describe a corrupt file alike.
fn png_error(e: png::DecodingError) -> image::ImageError {
    use image::error::{
        DecodingError, ImageFormatHint, LimitError, LimitErrorKind, ParameterError,
        ParameterErrorKind,
    };
    match e {
        png::DecodingError::IoError(e) => image::ImageError::IoError(e),
        e @ png::DecodingError::Format(_) => image::ImageError::Decoding(DecodingError::new(
            ImageFormatHint::Exact(image::ImageFormat::Png),
            e,
        )),
        e @ png::DecodingError::Parameter(_) => image::ImageError::Parameter(
            ParameterError::from_kind(ParameterErrorKind::Generic(e.to_string())),
        ),
        png::DecodingError::LimitsExceeded => {
            image::ImageError::Limits(LimitError::from_kind(LimitErrorKind::InsufficientMemory))
        }
    }
}

/// Reads a 16-bit greyscale PNG (depth, labels). Any other bit depth is an error, so an
/// 8-bit depth image, whose values cannot hold millimetres, is refused.
///
/// # Errors
/// Missing file, I/O error, corrupt PNG, or not 16-bit greyscale.
pub fn read_gray16(path: &Path) -> Result<Gray16Image, ImageIoError> {
    read_gray16_in(&DiskFiles, path)
}

/// [`read_gray16`] from `files`.
///
/// # Errors
/// As [`read_gray16`].
pub fn read_gray16_in(files: &impl Files, path: &Path) -> Result<Gray16Image, ImageIoError> {
    match decode_png(files, path)? {
        Decoded::Other(DynamicImage::ImageLuma16(img)) => {
            let (width, height) = img.dimensions();
            from_decoded(path, width, height, img.into_raw())
        }
        other => Err(other.wrong_format(path, "16-bit greyscale PNG")),
    }
}

/// Reads an 8-bit greyscale PNG (a heatmap). Any other bit depth is an error, so a 16-bit
/// image, whose values are not on the 0-255 scale, is refused rather than truncated.
///
/// # Errors
/// Missing file, I/O error, corrupt PNG, or not 8-bit greyscale.
pub fn read_gray8(path: &Path) -> Result<Gray8Image, ImageIoError> {
    match decode_png(&DiskFiles, path)? {
        Decoded::Other(DynamicImage::ImageLuma8(img)) => {
            let (width, height) = img.dimensions();
            from_decoded(path, width, height, img.into_raw())
        }
        other => Err(other.wrong_format(path, "8-bit greyscale PNG")),
    }
}

/// Reads a 16-bit or 8-bit greyscale PNG as 16-bit values (8-bit values are widened
/// unchanged, not rescaled). For label images, where other tools often save 8 bits.
///
/// # Errors
/// Missing file, I/O error, corrupt PNG, or not greyscale.
pub fn read_gray_widened(path: &Path) -> Result<Gray16Image, ImageIoError> {
    read_gray_widened_in(&DiskFiles, path)
}

/// [`read_gray_widened`] from `files`.
///
/// # Errors
/// As [`read_gray_widened`].
pub fn read_gray_widened_in(files: &impl Files, path: &Path) -> Result<Gray16Image, ImageIoError> {
    match decode_png(files, path)? {
        Decoded::Other(DynamicImage::ImageLuma16(img)) => {
            let (width, height) = img.dimensions();
            from_decoded(path, width, height, img.into_raw())
        }
        Decoded::Other(DynamicImage::ImageLuma8(img)) => {
            let (width, height) = img.dimensions();
            let data = img.into_raw().into_iter().map(u16::from).collect();
            from_decoded(path, width, height, data)
        }
        other => Err(other.wrong_format(path, "8- or 16-bit greyscale PNG")),
    }
}

fn from_decoded<T>(
    path: &Path,
    width: u32,
    height: u32,
    data: Vec<T>,
) -> Result<Image<T>, ImageIoError> {
    Image::from_vec(width as usize, height as usize, data).map_err(|e| {
        ImageIoError::new(
            path,
            ImageProblem::CorruptPng(image::ImageError::IoError(io::Error::other(e))),
        )
    })
}

fn encode_png(
    path: &Path,
    bytes: &[u8],
    (width, height): (usize, usize),
    color: ExtendedColorType,
) -> Result<Vec<u8>, ImageIoError> {
    let too_large = || ImageIoError::new(path, ImageProblem::TooLargeForPng { width, height });
    let png_width = u32::try_from(width).map_err(|_| too_large())?;
    let png_height = u32::try_from(height).map_err(|_| too_large())?;
    let mut out = Vec::new();
    PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Adaptive)
        .write_image(bytes, png_width, png_height, color)
        .map_err(|e| ImageIoError::new(path, ImageProblem::CorruptPng(e)))?;
    Ok(out)
}

/// Writes an 8-bit RGB PNG atomically.
///
/// # Errors
/// I/O errors, or an image the PNG encoder refuses (e.g. zero width), naming `path`.
pub fn write_rgb8(path: &Path, image: &RgbImage) -> Result<(), ImageIoError> {
    write_rgb8_as(path, image, Durability::Durable)
}

/// [`write_rgb8`] with the [`Durability`] the file needs.
///
/// # Errors
/// As [`write_rgb8`].
pub fn write_rgb8_as(
    path: &Path,
    image: &RgbImage,
    durability: Durability,
) -> Result<(), ImageIoError> {
    let bytes: Vec<u8> = image.data.iter().flatten().copied().collect();
    let png = encode_png(path, &bytes, image.size(), ExtendedColorType::Rgb8)?;
    write_file(path, &png, durability)
}

/// Writes a 16-bit greyscale PNG atomically.
///
/// # Errors
/// As [`write_rgb8`].
pub fn write_gray16(path: &Path, image: &Gray16Image) -> Result<(), ImageIoError> {
    write_gray16_as(path, image, Durability::Durable)
}

/// [`write_gray16`] with the [`Durability`] the file needs.
///
/// # Errors
/// As [`write_rgb8`].
pub fn write_gray16_as(
    path: &Path,
    image: &Gray16Image,
    durability: Durability,
) -> Result<(), ImageIoError> {
    // The encoder takes native-endian samples and writes PNG's big-endian ones.
    let bytes: Vec<u8> = image.data.iter().flat_map(|v| v.to_ne_bytes()).collect();
    let png = encode_png(path, &bytes, image.size(), ExtendedColorType::L16)?;
    write_file(path, &png, durability)
}

/// Writes an 8-bit greyscale PNG atomically.
///
/// # Errors
/// As [`write_rgb8`].
pub fn write_gray8(path: &Path, image: &Gray8Image) -> Result<(), ImageIoError> {
    write_gray8_as(path, image, Durability::Durable)
}

/// [`write_gray8`] with the [`Durability`] the file needs.
///
/// # Errors
/// As [`write_rgb8`].
pub fn write_gray8_as(
    path: &Path,
    image: &Gray8Image,
    durability: Durability,
) -> Result<(), ImageIoError> {
    let png = encode_png(path, &image.data, image.size(), ExtendedColorType::L8)?;
    write_file(path, &png, durability)
}

/// The `.flo` magic number (the bytes `PIEH` read as a little-endian `f32`).
pub const FLO_MAGIC: f32 = 202_021.25;
/// Largest width or height accepted from a `.flo` header (bounds memory on corrupt files).
pub const FLO_MAX_SIDE_PX: u32 = 1 << 15;
const FLO_HEADER_BYTES: usize = 12;

/// What is wrong with `.flo` bytes, or with a flow that cannot be written as a `.flo` file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FloFormatError {
    /// Fewer than the 12 header bytes.
    #[error("{len} bytes, shorter than the 12-byte header")]
    TooShort {
        /// Bytes present.
        len: usize,
    },
    /// The first four bytes are not [`FLO_MAGIC`].
    #[error("magic is {found}, expected {FLO_MAGIC}")]
    BadMagic {
        /// The float found.
        found: f32,
    },
    /// A side in the header is below 1 or above [`FLO_MAX_SIDE_PX`].
    #[error("header says {width}x{height} pixels; each side must be 1..={FLO_MAX_SIDE_PX}")]
    BadSize {
        /// Width as stored.
        width: i32,
        /// Height as stored.
        height: i32,
    },
    /// The file's length does not match its header.
    #[error("{found} bytes, a {width}x{height} flow needs {expected}")]
    Length {
        /// Width from the header.
        width: usize,
        /// Height from the header.
        height: usize,
        /// Bytes the header requires, header included.
        expected: usize,
        /// Bytes present.
        found: usize,
    },
    /// A vector component is NaN or infinite (unknown flow is written as `1e10`, finite).
    #[error("the vector of pixel ({x}, {y}) is not finite; unknown flow is written as 1e10")]
    NonFinite {
        /// Column of the first such pixel.
        x: usize,
        /// Row of the first such pixel.
        y: usize,
    },
    /// A flow to encode has a side of zero or above [`FLO_MAX_SIDE_PX`].
    #[error("cannot write a {width}x{height} flow; each side must be 1..={FLO_MAX_SIDE_PX}")]
    Unwritable {
        /// Width of the flow.
        width: usize,
        /// Height of the flow.
        height: usize,
    },
}

/// The `.flo` header of `flow`: magic, width, height.
fn flo_header(flow: &FlowImage) -> Result<[u8; FLO_HEADER_BYTES], FloFormatError> {
    let side_ok = |s: usize| s > 0 && s <= FLO_MAX_SIDE_PX as usize;
    if !side_ok(flow.width) || !side_ok(flow.height) {
        return Err(FloFormatError::Unwritable {
            width: flow.width,
            height: flow.height,
        });
    }
    let mut header = [0u8; FLO_HEADER_BYTES];
    header[..4].copy_from_slice(&FLO_MAGIC.to_le_bytes());
    // Both sides are at most FLO_MAX_SIDE_PX, so they fit in i32.
    header[4..8].copy_from_slice(&(flow.width as i32).to_le_bytes());
    header[8..12].copy_from_slice(&(flow.height as i32).to_le_bytes());
    Ok(header)
}

/// The `.flo` body bytes of `vectors` into `out` (8 bytes per vector).
fn encode_flo_body(vectors: &[[f32; 2]], out: &mut [u8]) {
    for (o, [dx, dy]) in out.as_chunks_mut::<8>().0.iter_mut().zip(vectors) {
        let (x, y) = o.split_at_mut(4);
        x.copy_from_slice(&dx.to_le_bytes());
        y.copy_from_slice(&dy.to_le_bytes());
    }
}

/// The `.flo` bytes of `flow`.
///
/// # Errors
/// [`FloFormatError::Unwritable`] if a side is zero or above [`FLO_MAX_SIDE_PX`].
pub fn encode_flo(flow: &FlowImage) -> Result<Vec<u8>, FloFormatError> {
    let header = flo_header(flow)?;
    let mut bytes = vec![0u8; FLO_HEADER_BYTES + flow.data.len() * 8];
    let (head, body) = bytes.split_at_mut(FLO_HEADER_BYTES);
    head.copy_from_slice(&header);
    encode_flo_body(&flow.data, body);
    Ok(bytes)
}

/// Parses `.flo` bytes. The header is checked against [`FLO_MAX_SIDE_PX`] and the length
/// before anything is allocated, so a corrupt header cannot exhaust memory.
///
/// # Errors
/// A [`FloFormatError`] naming the first problem found.
pub fn decode_flo(bytes: &[u8]) -> Result<FlowImage, FloFormatError> {
    let word = |i: usize| -> Option<[u8; 4]> { bytes.get(i..i + 4)?.try_into().ok() };
    let (Some(m), Some(w), Some(h)) = (word(0), word(4), word(8)) else {
        return Err(FloFormatError::TooShort { len: bytes.len() });
    };
    let magic = f32::from_le_bytes(m);
    if magic.to_bits() != FLO_MAGIC.to_bits() {
        return Err(FloFormatError::BadMagic { found: magic });
    }
    let (w, h) = (i32::from_le_bytes(w), i32::from_le_bytes(h));
    let side_ok = |s: i32| s > 0 && s as u32 <= FLO_MAX_SIDE_PX;
    if !side_ok(w) || !side_ok(h) {
        return Err(FloFormatError::BadSize {
            width: w,
            height: h,
        });
    }
    // Both sides are in 1..=FLO_MAX_SIDE_PX, so they fit in usize and their product does too.
    let (width, height) = (w as usize, h as usize);
    let pixels = width * height;
    let expected = FLO_HEADER_BYTES + pixels * 8;
    if bytes.len() != expected {
        return Err(FloFormatError::Length {
            width,
            height,
            expected,
            found: bytes.len(),
        });
    }
    let data: Vec<[f32; 2]> = bytes[FLO_HEADER_BYTES..]
        .chunks_exact(8)
        .map(|c| {
            [
                f32::from_le_bytes([c[0], c[1], c[2], c[3]]),
                f32::from_le_bytes([c[4], c[5], c[6], c[7]]),
            ]
        })
        .collect();
    if let Some(i) = data
        .iter()
        .position(|v| !(v[0].is_finite() && v[1].is_finite()))
    {
        return Err(FloFormatError::NonFinite {
            x: i % width,
            y: i / width,
        });
    }
    // The sides are checked and the length matched, so this cannot fail.
    Image::from_vec(width, height, data).map_err(|_| FloFormatError::Length {
        width,
        height,
        expected,
        found: bytes.len(),
    })
}

/// Reads a Middlebury `.flo` file.
///
/// # Errors
/// Missing file, I/O error, or [`ImageProblem::CorruptFlo`] (wrong magic, non-positive or
/// oversized dimensions, or a file length that does not match its header), naming `path`.
pub fn read_flo(path: &Path) -> Result<FlowImage, ImageIoError> {
    read_flo_in(&DiskFiles, path)
}

/// [`read_flo`] from `files`.
///
/// # Errors
/// As [`read_flo`].
pub fn read_flo_in(files: &impl Files, path: &Path) -> Result<FlowImage, ImageIoError> {
    let bytes = read_bytes(files, path)?;
    decode_flo(&bytes).map_err(|e| ImageIoError::new(path, ImageProblem::CorruptFlo(e)))
}

/// Writes a Middlebury `.flo` file atomically.
///
/// # Errors
/// An image side above [`FLO_MAX_SIDE_PX`] (or zero), or I/O errors, naming `path`.
pub fn write_flo(path: &Path, flow: &FlowImage) -> Result<(), ImageIoError> {
    write_flo_as(path, flow, Durability::Durable)
}

/// [`write_flo`] with the [`Durability`] the file needs.
///
/// # Errors
/// As [`write_flo`].
pub fn write_flo_as(
    path: &Path,
    flow: &FlowImage,
    durability: Durability,
) -> Result<(), ImageIoError> {
    let header =
        flo_header(flow).map_err(|e| ImageIoError::new(path, ImageProblem::CorruptFlo(e)))?;
    write_atomic_as(path, durability, |file| {
        file.write_all(&header)?;
        // The body is the vectors' little-endian f32 bytes. On a little-endian machine
        // those are the vectors' bytes in memory: one write, no copy and no fresh buffer
        // (a copy of a 640x480 field is 2.4 MB of pages to fault in; `riseg flow` one-shot,
        // measured). Elsewhere they are encoded a piece at a time.
        #[cfg(target_endian = "little")]
        file.write_all(bytemuck::cast_slice(&flow.data))?;
        #[cfg(target_endian = "big")]
        {
            const PIECE_VECTORS: usize = 8192;
            let mut piece = vec![0u8; PIECE_VECTORS * 8];
            for vectors in flow.data.chunks(PIECE_VECTORS) {
                let bytes = &mut piece[..vectors.len() * 8];
                encode_flo_body(vectors, bytes);
                file.write_all(bytes)?;
            }
        }
        Ok(())
    })
    .map_err(|e| ImageIoError::new(path, ImageProblem::Io(e)))
}

#[cfg(test)]
mod tests {
    use std::fs;

    use super::*;

    fn temp_dir(tag: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("riseg-imageio-{tag}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn files_in(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_header_declaring_a_huge_or_wrong_size_is_refused_before_decoding() {
        let dir = temp_dir("huge");
        let huge = dir.join("huge.png");
        fs::write(&huge, crate::testkit::png::png_declaring(100_000, 100_000)).unwrap();
        let e = read_gray16(&huge).unwrap_err();
        assert!(
            matches!(
                e.problem,
                ImageProblem::TooManyPixels { width: 100_000, .. }
            ),
            "{e}"
        );
        assert!(
            e.to_string().starts_with(&huge.display().to_string()),
            "{e}"
        );
        // Within the cap but not the camera's size: refused from the header alone (the
        // file holds one pixel of data, so decoding would fail differently).
        let wrong = dir.join("wrong.png");
        fs::write(&wrong, crate::testkit::png::png_declaring(640, 480)).unwrap();
        let e = read_sized(&wrong, 320, 240, read_gray16).unwrap_err();
        assert!(
            matches!(e.problem, ImageProblem::WrongSize { width: 640, .. }),
            "{e}"
        );
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn sizes_are_checked_and_views_lend_the_pixels() {
        assert!(Gray8Image::from_vec(3, 2, vec![0; 5]).is_err());
        assert!(Gray8Image::from_vec(usize::MAX, 2, Vec::new()).is_err());
        let img = Gray16Image::from_fn(3, 2, |x, y| (10 * y + x) as u16);
        let view = img.view();
        assert_eq!(view.size(), (3, 2));
        assert_eq!(view.get(2, 1), Some(&12));
        assert_eq!(view.get(3, 0), None);
        assert_eq!(img.get(1, 1), Some(&11));
        assert!(core::ptr::eq(view.row(0).unwrap(), &img.as_slice()[..3]));
    }

    #[test]
    fn round_trips_are_exact_and_leave_no_temp_files() {
        let dir = temp_dir("roundtrip");
        let rgb = RgbImage::from_fn(7, 5, |x, y| [x as u8 * 30, y as u8 * 40, 255 - x as u8]);
        let gray = Gray16Image::from_fn(7, 5, |x, y| (x * 9000 + y) as u16);
        let flow = FlowImage::from_fn(7, 5, |x, y| [x as f32 * 0.5 - 1.0, -(y as f32) * 0.25]);
        write_rgb8(&dir.join("c.png"), &rgb).unwrap();
        write_gray16(&dir.join("d.png"), &gray).unwrap();
        write_flo(&dir.join("f.flo"), &flow).unwrap();
        let heat = Gray8Image::from_fn(7, 5, |x, y| (x * 30 + y) as u8);
        write_gray8(&dir.join("h.png"), &heat).unwrap();
        assert_eq!(read_gray8(&dir.join("h.png")).unwrap(), heat);
        assert_eq!(
            read_gray_widened(&dir.join("h.png")).unwrap(),
            heat.map(|&v| u16::from(v))
        );
        assert_eq!(read_rgb8(&dir.join("c.png")).unwrap(), rgb);
        assert_eq!(read_gray16(&dir.join("d.png")).unwrap(), gray);
        assert_eq!(read_gray_widened(&dir.join("d.png")).unwrap(), gray);
        assert_eq!(read_flo(&dir.join("f.flo")).unwrap(), flow);
        assert_eq!(files_in(&dir), ["c.png", "d.png", "f.flo", "h.png"]);
        // Overwriting replaces the file whole.
        write_gray16(&dir.join("d.png"), &Gray16Image::from_fn(2, 2, |_, _| 7)).unwrap();
        assert_eq!(read_gray16(&dir.join("d.png")).unwrap().as_slice(), [7; 4]);
        fs::remove_dir_all(&dir).unwrap();
    }

    /// Found by the `png_read` fuzz target (and issue 15, defect 2): a 68-byte PNG whose
    /// header declares 100000x100000 pixels made every reader allocate the declared size
    /// first (an out-of-memory abort). Now it is an error naming the file, for each reader.
    #[test]
    fn flo_layout_is_middlebury() {
        let dir = temp_dir("flo-layout");
        let path = dir.join("f.flo");
        let flow = FlowImage::from_vec(2, 1, vec![[1.0, 2.0], [3.0, 4.0]]).unwrap();
        write_flo(&path, &flow).unwrap();
        let bytes = fs::read(&path).unwrap();
        assert_eq!(&bytes[0..4], b"PIEH");
        assert_eq!(i32::from_le_bytes(bytes[4..8].try_into().unwrap()), 2);
        assert_eq!(i32::from_le_bytes(bytes[8..12].try_into().unwrap()), 1);
        let floats: Vec<f32> = bytes[12..]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert_eq!(floats, [1.0, 2.0, 3.0, 4.0]);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bad_files_are_errors_that_name_the_file() {
        let dir = temp_dir("bad");
        let message = |e: ImageIoError| e.to_string();

        let missing = dir.join("missing.png");
        let e = read_rgb8(&missing).unwrap_err();
        assert!(matches!(e.problem, ImageProblem::Missing));
        assert!(message(e).contains("missing.png"));

        let garbage = dir.join("garbage.png");
        fs::write(&garbage, b"\x89PNG\r\n\x1a\nnot really").unwrap();
        let e = read_gray16(&garbage).unwrap_err();
        assert!(matches!(e.problem, ImageProblem::CorruptPng(_)), "{e}");
        assert!(message(e).contains("garbage.png"));

        let rgb = dir.join("rgb.png");
        write_rgb8(&rgb, &RgbImage::from_fn(3, 2, |_, _| [1, 2, 3])).unwrap();
        let e = read_gray16(&rgb).unwrap_err();
        assert!(message(e).contains("expected 16-bit greyscale PNG, found 8-bit RGB"));
        let gray = dir.join("gray.png");
        write_gray16(&gray, &Gray16Image::from_fn(3, 2, |_, _| 1)).unwrap();
        let e = read_rgb8(&gray).unwrap_err();
        assert!(message(e).contains("found 16-bit greyscale"));

        let e = read_gray8(&gray).unwrap_err();
        assert!(message(e).contains("expected 8-bit greyscale PNG, found 16-bit greyscale"));

        let img = read_gray16(&gray).unwrap();
        let e = ImageIoError::expect_size(&gray, &img, 4, 2).unwrap_err();
        assert!(message(e).contains("gray.png: expected 4x2 pixels, found 3x2"));

        let flo = dir.join("bad.flo");
        for (bytes, needle) in [
            (b"PIE".to_vec(), "shorter than the 12-byte header"),
            ([b"XXXX".as_slice(), &[0; 8]].concat(), "magic"),
            (
                [
                    b"PIEH".as_slice(),
                    &(-1i32).to_le_bytes(),
                    &1i32.to_le_bytes(),
                ]
                .concat(),
                "header says -1x1",
            ),
            (
                [
                    b"PIEH".as_slice(),
                    &1i32.to_le_bytes(),
                    &1i32.to_le_bytes(),
                    &[0; 4],
                ]
                .concat(),
                "16 bytes, a 1x1 flow needs 20",
            ),
        ] {
            fs::write(&flo, bytes).unwrap();
            let m = message(read_flo(&flo).unwrap_err());
            assert!(m.contains("bad.flo") && m.contains(needle), "{m}");
        }
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn any_png_reads_as_rgb8() {
        let dir = temp_dir("as-rgb8");
        let rgb = RgbImage::from_fn(3, 2, |x, y| [x as u8, y as u8, 7]);
        write_rgb8(&dir.join("c.png"), &rgb).unwrap();
        assert_eq!(read_png_as_rgb8(&dir.join("c.png")).unwrap(), rgb);
        let grey = Gray8Image::from_fn(3, 2, |x, y| (10 * x + y) as u8);
        write_gray8(&dir.join("g.png"), &grey).unwrap();
        assert_eq!(
            read_png_as_rgb8(&dir.join("g.png")).unwrap(),
            grey.map(|&v| [v; 3])
        );
        let deep = Gray16Image::from_fn(1, 1, |_, _| 0xff00);
        write_gray16(&dir.join("d.png"), &deep).unwrap();
        assert_eq!(
            read_png_as_rgb8(&dir.join("d.png")).unwrap().as_slice(),
            [[0xfe; 3]]
        );
        let e = read_png_as_rgb8(&dir.join("missing.png")).unwrap_err();
        assert!(matches!(e.problem, ImageProblem::Missing));
        fs::remove_dir_all(&dir).unwrap();
    }

    /// The row-by-row path of `read_png_as_rgb8_mapped` (8-bit RGB) gives what decoding
    /// the whole image gives, and reports a damaged or cut file as corrupt, naming it.
    #[test]
    fn mapped_reads_match_whole_decodes_and_report_damage() {
        let dir = temp_dir("mapped");
        let rgb = RgbImage::from_fn(37, 23, |x, y| {
            [(x * 7) as u8, (y * 11) as u8, (x * y) as u8]
        });
        let path = dir.join("c.png");
        write_rgb8(&path, &rgb).unwrap();
        let weigh =
            |p: &[u8; 3]| u32::from(p[0]) + 300 * u32::from(p[1]) + 90_000 * u32::from(p[2]);
        assert_eq!(
            read_png_as_rgb8_mapped(&path, weigh).unwrap(),
            rgb.map(weigh)
        );
        let grey = Gray8Image::from_fn(5, 4, |x, y| (40 * x + y) as u8);
        write_gray8(&dir.join("g.png"), &grey).unwrap();
        assert_eq!(
            read_png_as_rgb8_mapped(&dir.join("g.png"), weigh).unwrap(),
            grey.map(|&v| weigh(&[v; 3]))
        );
        let bytes = fs::read(&path).unwrap();
        let mut flipped = bytes.clone();
        flipped[bytes.len() / 2] ^= 0x5a;
        let cut = &bytes[..bytes.len() / 2];
        for (name, damaged) in [("flipped.png", &flipped[..]), ("cut.png", cut)] {
            let bad = dir.join(name);
            fs::write(&bad, damaged).unwrap();
            let e = read_png_as_rgb8_mapped(&bad, weigh).unwrap_err();
            assert!(
                matches!(e.problem, ImageProblem::CorruptPng(_)),
                "{name}: {e}"
            );
            assert!(e.to_string().contains(name), "{e}");
        }
        // A folder opens but cannot be read: an I/O error, not a corrupt file.
        let folder = dir.join("folder.png");
        fs::create_dir(&folder).unwrap();
        let e = read_png_as_rgb8_mapped(&folder, weigh).unwrap_err();
        assert!(matches!(e.problem, ImageProblem::Io(_)), "{e}");
        assert!(e.to_string().contains("folder.png"), "{e}");
        // A header declaring more pixels than any frame (one row wider than the decoder's
        // memory limit, too): named as too large before any row is reserved.
        for (w, h) in [(100_000, 100_000), (200_000_000, 1)] {
            let huge = dir.join("huge.png");
            fs::write(&huge, crate::testkit::png::png_declaring(w, h)).unwrap();
            let e = read_png_as_rgb8_mapped(&huge, weigh).unwrap_err();
            assert!(
                matches!(e.problem, ImageProblem::TooManyPixels { .. }),
                "{w}x{h}: {e}"
            );
        }
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn image_size_is_checked() {
        assert!(Image::from_vec(2, 2, vec![0u8; 3]).is_err());
        let img = Image::from_vec(2, 2, vec![1u8, 2, 3, 4]).unwrap();
        assert_eq!(img.get(1, 1), Some(&4));
        assert_eq!(img.get(2, 0), None);
    }

    fn sample_flow() -> FlowImage {
        let data = (0..12)
            .map(|i| [i as f32 * 0.5 - 2.0, -(i as f32) * 1.25])
            .collect();
        FlowImage::from_vec(4, 3, data).unwrap()
    }

    #[test]
    fn flo_bytes_round_trip_and_header_layout() {
        let f = sample_flow();
        let b = encode_flo(&f).unwrap();
        assert_eq!(&b[..4], b"PIEH");
        assert_eq!(b.len(), 12 + 12 * 8);
        assert_eq!(i32::from_le_bytes([b[4], b[5], b[6], b[7]]), 4);
        assert_eq!(decode_flo(&b).unwrap(), f);
    }

    #[test]
    fn flo_file_round_trip_leaves_no_temporary() {
        let dir = temp_dir("flo-file");
        let path = dir.join("a.flo");
        write_flo(&path, &sample_flow()).unwrap();
        assert_eq!(read_flo(&path).unwrap(), sample_flow());
        // The file is written from the vectors' memory, not through `encode_flo`.
        assert_eq!(
            fs::read(&path).unwrap(),
            encode_flo(&sample_flow()).unwrap()
        );
        assert_eq!(files_in(&dir), ["a.flo"]);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn corrupt_flo_bytes_are_errors() {
        let b = encode_flo(&sample_flow()).unwrap();
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
        // A huge header is refused before anything is allocated.
        let mut huge = b[..12].to_vec();
        huge[4..8].copy_from_slice(&i32::MAX.to_le_bytes());
        huge[8..12].copy_from_slice(&i32::MAX.to_le_bytes());
        assert!(matches!(
            decode_flo(&huge),
            Err(FloFormatError::BadSize { .. })
        ));
        // NaN in pixel (1, 2) of the 4-wide flow: vector 9, its dy at byte 12 + 9 * 8 + 4.
        let mut nan = b.clone();
        nan[12 + 9 * 8 + 4..][..4].copy_from_slice(&f32::NAN.to_le_bytes());
        assert_eq!(
            decode_flo(&nan),
            Err(FloFormatError::NonFinite { x: 1, y: 2 })
        );
        let mut neg = b.clone();
        neg[8..12].copy_from_slice(&(-3i32).to_le_bytes());
        assert!(matches!(
            decode_flo(&neg),
            Err(FloFormatError::BadSize { .. })
        ));
        let empty = FlowImage::from_vec(0, 0, Vec::new()).unwrap();
        assert!(matches!(
            encode_flo(&empty),
            Err(FloFormatError::Unwritable { .. })
        ));
    }

    #[test]
    fn missing_flo_file_error_names_it() {
        let e = read_flo(Path::new("/nonexistent/riseg/x.flo")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/riseg/x.flo"), "{e}");
    }
}
