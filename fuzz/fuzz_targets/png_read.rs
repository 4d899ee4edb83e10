//! The PNG readers of `riseg::io::image` (`read_rgb8`, `read_png_as_rgb8`, `read_gray16`,
//! `read_gray8`, `read_gray_widened`) on arbitrary bytes, written to a file on tmpfs
//! (`/dev/shm`) because the readers take paths.
//!
//! Contract checked: no panic, no abort and no allocation beyond the reader's limit (a
//! header declaring a huge size must be an error, not an out-of-memory); an image that
//! reads has a non-empty size; a 16-bit grey or 8-bit RGB image of at most
//! [`ROUND_TRIP_MAX_PX`] pixels writes and reads back unchanged.

#![no_main]

use std::{path::PathBuf, sync::OnceLock};

use libfuzzer_sys::fuzz_target;
use riseg::io::image::{
    read_gray_widened, read_gray8, read_gray16, read_png_as_rgb8, read_rgb8, write_gray16,
    write_rgb8,
};

/// Largest image that is also written and read back (writing costs a compression).
const ROUND_TRIP_MAX_PX: usize = 1 << 16;

fn scratch_dir() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let base = if std::path::Path::new("/dev/shm").is_dir() {
            PathBuf::from("/dev/shm")
        } else {
            std::env::temp_dir()
        };
        let dir = base.join(format!("riseg-fuzz-png-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("scratch folder");
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    let dir = scratch_dir();
    let input = dir.join("input.png");
    std::fs::write(&input, data).expect("write to tmpfs");
    let _ = read_png_as_rgb8(&input);
    let _ = read_gray8(&input);
    let _ = read_gray_widened(&input);
    if let Ok(image) = read_gray16(&input) {
        assert!(image.width() > 0 && image.height() > 0);
        if image.as_slice().len() <= ROUND_TRIP_MAX_PX {
            let out = dir.join("gray16.png");
            write_gray16(&out, &image).expect("write a decoded 16-bit image");
            assert!(
                read_gray16(&out).expect("read back") == image,
                "16-bit round trip"
            );
        }
    }
    if let Ok(image) = read_rgb8(&input) {
        assert!(image.width() > 0 && image.height() > 0);
        if image.as_slice().len() <= ROUND_TRIP_MAX_PX {
            let out = dir.join("rgb8.png");
            write_rgb8(&out, &image).expect("write a decoded RGB image");
            assert!(
                read_rgb8(&out).expect("read back") == image,
                "RGB round trip"
            );
        }
    }
});
