//! Formats: owned images and PNG ([`image`]), the Middlebury `.flo` flow format
//! ([`image::read_flo`] and friends), atomic writes ([`write_atomic`]), and the scene
//! folder ([`scene`]), and where readers get files: the disk or memory ([`files`]). Pure:
//! nothing here names the CLI, the simulator or the loop.

pub mod files;
pub mod image;
pub mod scene;

use core::sync::atomic::{AtomicU64, Ordering};
use std::{
    fs,
    io::{self, Write as _},
    path::{Path, PathBuf},
};

/// A hidden name beside `name` for a temporary file or folder, unique within this machine's
/// processes and this process's threads: `.{name}.{kind}-{pid}-{n}`.
pub(crate) fn temp_name(name: &str, kind: &str) -> String {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    format!(".{name}.{kind}-{}-{n}", std::process::id())
}

/// Writes `bytes` to `path` atomically: a hidden temporary file in the same folder
/// (`.{name}.tmp-{pid}-{n}`), flushed to disk, then renamed over `path`, so a reader sees the old
/// file or the whole new one, never half a file. On error the temporary file is removed.
/// Every file riseg writes goes through here.
///
/// # Errors
/// The I/O error of the step that failed (the folder is missing or not writable, the
/// disk is full, ...). Callers add the path to the message.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .map_or_else(|| "unnamed".into(), |n| n.to_string_lossy().into_owned());
    let tmp = dir.join(temp_name(&name, "tmp"));
    let result = (|| {
        let mut file = fs::File::create(&tmp)?;
        file.write_all(bytes)?;
        file.sync_all()?;
        fs::rename(&tmp, path)
    })();
    if result.is_err() {
        // Best effort: the temporary file may not exist if creating it failed.
        let _ = fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn write_atomic_replaces_whole_and_leaves_no_temporary() {
        let dir = std::env::temp_dir().join(format!("riseg-io-atomic-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.json");
        write_atomic(&path, b"first, longer").unwrap();
        write_atomic(&path, b"second").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"second");
        let names: Vec<_> = fs::read_dir(&dir).unwrap().collect();
        assert_eq!(names.len(), 1);
        // A missing folder is an error and leaves nothing behind.
        let missing = dir.join("no-such-folder").join("b.json");
        assert!(write_atomic(&missing, b"x").is_err());
        fs::remove_dir_all(&dir).unwrap();
    }
}
