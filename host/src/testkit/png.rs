//! Hostile PNG files for the readers' tests: a real PNG whose header lies about its size.

use image::{ExtendedColorType, ImageEncoder as _, codecs::png::PngEncoder};

/// A real 1x1 16-bit grey PNG whose header is patched to declare `width x height` (the
/// IHDR checksum redone, so a decoder accepts the header and only the pixel data is
/// short): a few dozen bytes that a reader trusting the header would allocate
/// `width·height` pixels for.
///
/// # Panics
/// Never for any size (the 1x1 encode cannot fail).
#[must_use]
pub fn png_declaring(width: u32, height: u32) -> Vec<u8> {
    let mut png = Vec::new();
    PngEncoder::new(&mut png)
        .write_image(&[0, 0], 1, 1, ExtendedColorType::L16)
        .expect("a 1x1 PNG encodes");
    // IHDR: length at 8, type at 12, width and height at 16 and 20, checksum at 29.
    png[16..20].copy_from_slice(&width.to_be_bytes());
    png[20..24].copy_from_slice(&height.to_be_bytes());
    let crc = crc32(&png[12..29]);
    png[29..33].copy_from_slice(&crc.to_be_bytes());
    png
}

/// PNG's CRC-32 (ISO 3309, reflected polynomial `0xEDB88320`), bit by bit.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_of_a_known_chunk_and_the_patched_header_decodes_to_the_declared_size() {
        // The IEND chunk's checksum, fixed by the PNG specification.
        assert_eq!(crc32(b"IEND"), 0xAE42_6082);
        let png = png_declaring(640, 480);
        let decoder = image::codecs::png::PngDecoder::new(std::io::Cursor::new(&png)).unwrap();
        assert_eq!(image::ImageDecoder::dimensions(&decoder), (640, 480));
    }
}
