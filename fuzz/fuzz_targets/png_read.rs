//! The PNG readers of `riseg::io::image` (`read_rgb8`, `read_png_as_rgb8`, `read_gray16`,
//! `read_gray8`, `read_gray_widened`) on arbitrary bytes, written to a file on tmpfs
//! (`/dev/shm`) because the readers take paths.
//!
//! Contract checked: no panic, no abort and no allocation beyond the reader's limit (a
//! header declaring a huge size must be an error, not an out-of-memory); an image that
//! reads has a non-empty size; a 16-bit grey or 8-bit RGB image of at most
//! [`ROUND_TRIP_MAX_PX`] pixels writes and reads back unchanged.

#![no_main]

use std::{
    path::{Path, PathBuf},
    sync::OnceLock,
};

use libfuzzer_sys::fuzz_target;
use riseg::io::image::{
    read_gray_widened, read_gray8, read_gray16, read_png_as_rgb8, read_rgb8, write_gray16,
    write_rgb8,
};

/// Largest image that is also written and read back (writing costs a compression).
const ROUND_TRIP_MAX_PX: usize = 1 << 16;

/// A file of this process on tmpfs (`/dev/shm`, else the temporary folder); the target
/// removes its files at the end of every run, so nothing is left behind.
fn scratch(name: &str) -> PathBuf {
    static BASE: OnceLock<PathBuf> = OnceLock::new();
    let base = BASE.get_or_init(|| {
        let shm = PathBuf::from("/dev/shm");
        let dir = if shm.is_dir() {
            shm
        } else {
            std::env::temp_dir()
        };
        dir.join(format!("riseg-fuzz-png-{}", std::process::id()))
    });
    let mut path = base.clone().into_os_string();
    path.push(format!("-{name}"));
    path.into()
}

fn check(input: &Path) {
    let _ = read_png_as_rgb8(input);
    let _ = read_gray8(input);
    let _ = read_gray_widened(input);
    if let Ok(image) = read_gray16(input) {
        assert!(image.width() > 0 && image.height() > 0);
        if image.as_slice().len() <= ROUND_TRIP_MAX_PX {
            let out = scratch("gray16.png");
            write_gray16(&out, &image).expect("write a decoded 16-bit image");
            assert!(
                read_gray16(&out).expect("read back") == image,
                "16-bit round trip"
            );
        }
    }
    if let Ok(image) = read_rgb8(input) {
        assert!(image.width() > 0 && image.height() > 0);
        if image.as_slice().len() <= ROUND_TRIP_MAX_PX {
            let out = scratch("rgb8.png");
            write_rgb8(&out, &image).expect("write a decoded RGB image");
            assert!(
                read_rgb8(&out).expect("read back") == image,
                "RGB round trip"
            );
        }
    }
}

fuzz_target!(|data: &[u8]| {
    let input = scratch("input.png");
    std::fs::write(&input, data).expect("write to tmpfs");
    check(&input);
    for name in ["input.png", "gray16.png", "rgb8.png"] {
        let _ = std::fs::remove_file(scratch(name));
    }
});
