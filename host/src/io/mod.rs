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

/// How a file written by [`write_atomic_as`] survives a crash of the *machine* (power loss,
/// kernel panic). Both are atomic for every reader and against a crash of riseg itself: a
/// hidden temporary file in the destination's folder is renamed over the destination once
/// it is complete, so a reader sees the old file or the whole new one, never half a file.
///
/// The contract, by what the file is:
/// - [`Durability::Durable`] (what [`write_atomic`] and the image writers use): recordings
///   and datasets, which cannot be made again: scene folders (`riseg gen`, the frames of
///   `riseg run --live`), reports and masks of the long commands. The data is flushed to
///   disk (`fsync`) before the rename, so once the call returns the new file survives a
///   power loss.
/// - [`Durability::Derived`]: outputs a one-shot command computes from its inputs and can
///   compute again (`riseg flow`'s `.flo` field and picture, `riseg segment`'s labels,
///   heatmap and picture). Renamed without the flush: the flush is a large share of such a
///   call (milliseconds on an idle SSD, far more on a busy or network disk) and buys
///   nothing a rerun does not. After a power loss within the kernel's writeback delay
///   (seconds) the file may be the old one, missing or empty; run the command again.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Durability {
    /// Flushed to disk before the rename: survives a power loss once written.
    #[default]
    Durable,
    /// Renamed without a flush: a derived output a rerun writes again.
    Derived,
}

/// Writes `bytes` to `path` atomically: a hidden temporary file in the same folder
/// (`.{name}.tmp-{pid}-{n}`), flushed to disk, then renamed over `path`, so a reader sees the old
/// file or the whole new one, never half a file. On error the temporary file is removed.
/// Every file riseg writes goes through here ([`Durability::Durable`]; [`write_atomic_as`]
/// for derived outputs).
///
/// What is at `path` is respected: a symbolic link is followed and its target written
/// (the link stays a link); a device, pipe or socket is written directly, not replaced
/// (so `-o /dev/stdout` works and `-o /dev/full` is a "no space" error); only a regular
/// file, or nothing, is replaced by the rename. A folder is an error.
///
/// # Errors
/// The I/O error of the step that failed (the folder is missing or not writable, the
/// disk is full, the path is a folder, ...). Callers add the path to the message.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomic_as(path, Durability::Durable, |file| file.write_all(bytes))
}

/// [`write_atomic`] with the bytes written by `fill`, so that a large file need not be held
/// whole in memory first. `fill` writes straight to the file (unbuffered: write in large
/// pieces); everything else, the temporary file, the flush to disk, the rename, what is at
/// `path` and the errors, is as for [`write_atomic`].
///
/// # Errors
/// As [`write_atomic`], and any error `fill` returns.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut fs::File) -> io::Result<()>,
) -> io::Result<()> {
    write_atomic_as(path, Durability::Durable, fill)
}

/// [`write_atomic_with`] with the [`Durability`] the file needs: as [`write_atomic`] for
/// [`Durability::Durable`]; for [`Durability::Derived`] the temporary file is renamed
/// without being flushed to disk first (see [`Durability`] for when that is right).
///
/// # Errors
/// As [`write_atomic_with`].
pub fn write_atomic_as(
    path: &Path,
    durability: Durability,
    fill: impl FnOnce(&mut fs::File) -> io::Result<()>,
) -> io::Result<()> {
    let target = follow_links(path)?;
    if let Some(kind) = special_file(&target)? {
        let mut file = match kind {
            Special::Folder => return Err(is_a_folder()),
            Special::Device => fs::OpenOptions::new().write(true).open(&target)?,
        };
        fill(&mut file)?;
        return file.flush();
    }
    let tmp = temp_beside(&target, "tmp");
    let result = (|| {
        let mut file = fs::File::create(&tmp)?;
        fill(&mut file)?;
        if durability == Durability::Durable {
            file.sync_all()?;
        }
        fs::rename(&tmp, &target)
    })();
    if result.is_err() {
        // Best effort: the temporary file may not exist if creating it failed.
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// Checks, before long work, that [`write_atomic`] could write `path` now: its folder
/// exists and takes a new file (a probe file is created and removed), or `path` is a
/// device or pipe. Nothing at `path` changes.
///
/// # Errors
/// The I/O error that writing would meet (missing or read-only folder, `path` a folder).
pub fn check_writable(path: &Path) -> io::Result<()> {
    let target = follow_links(path)?;
    match special_file(&target)? {
        Some(Special::Folder) => Err(is_a_folder()),
        Some(Special::Device) => Ok(()),
        None => {
            let probe = temp_beside(&target, "probe");
            fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&probe)?;
            fs::remove_file(&probe)
        }
    }
}

/// What is at a path that is not a regular file.
enum Special {
    Folder,
    /// A device, pipe or socket: written in place.
    Device,
}

/// `None` for a regular file or nothing at `path`.
fn special_file(path: &Path) -> io::Result<Option<Special>> {
    match fs::metadata(path) {
        Ok(m) if m.is_dir() => Ok(Some(Special::Folder)),
        Ok(m) if m.is_file() => Ok(None),
        Ok(_) => Ok(Some(Special::Device)),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e),
    }
}

fn is_a_folder() -> io::Error {
    io::Error::new(io::ErrorKind::IsADirectory, "is a folder, not a file")
}

/// `path` with every symbolic link at its end followed (a link to a link, ...): where a
/// write must go. Links inside the folder part are left to the operating system.
fn follow_links(path: &Path) -> io::Result<PathBuf> {
    // The kernel's own limit on a chain of links.
    const MAX_LINKS: usize = 40;
    let mut current = path.to_path_buf();
    for _ in 0..MAX_LINKS {
        match fs::symlink_metadata(&current) {
            Ok(m) if m.file_type().is_symlink() => {
                let link = fs::read_link(&current)?;
                current = match current.parent() {
                    Some(dir) if link.is_relative() => dir.join(link),
                    _ => link,
                };
            }
            _ => return Ok(current),
        }
    }
    Err(io::Error::other(format!(
        "more than {MAX_LINKS} symbolic links in a chain"
    )))
}

/// A hidden file name in `path`'s folder for a temporary of `kind`.
fn temp_beside(path: &Path, kind: &str) -> PathBuf {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .map_or_else(|| "unnamed".into(), |n| n.to_string_lossy().into_owned());
    dir.join(temp_name(&name, kind))
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
        // A derived output (no flush) is replaced whole just the same.
        write_atomic_as(&path, Durability::Derived, |f| {
            f.write_all(b"third, longer")
        })
        .unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"third, longer");
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 1);
        let failed = write_atomic_as(&path, Durability::Derived, |f| {
            f.write_all(b"half")?;
            Err(io::Error::other("the fill failed"))
        });
        assert!(failed.is_err());
        assert_eq!(fs::read(&path).unwrap(), b"third, longer");
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 1, "no temporary left");
        // A missing folder is an error and leaves nothing behind.
        let missing = dir.join("no-such-folder").join("b.json");
        assert!(write_atomic(&missing, b"x").is_err());
        assert!(check_writable(&missing).is_err());
        assert!(
            check_writable(&dir).is_err(),
            "a folder is not writable as a file"
        );
        assert!(write_atomic(&dir, b"x").is_err());
        check_writable(&path).unwrap();
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 1, "the probe is gone");
        fs::remove_dir_all(&dir).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn write_atomic_writes_through_links_and_into_devices() {
        let dir = std::env::temp_dir().join(format!("riseg-io-links-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(dir.join("sub")).unwrap();
        // link -> sub/link2 -> target.json (relative links, resolved from their folders)
        std::os::unix::fs::symlink("sub/link2", dir.join("link")).unwrap();
        std::os::unix::fs::symlink("../target.json", dir.join("sub/link2")).unwrap();
        write_atomic(&dir.join("link"), b"through").unwrap();
        assert_eq!(fs::read(dir.join("target.json")).unwrap(), b"through");
        let meta = fs::symlink_metadata(dir.join("link")).unwrap();
        assert!(meta.file_type().is_symlink(), "the link stays a link");
        // A device is written, not replaced.
        write_atomic(Path::new("/dev/null"), b"gone").unwrap();
        assert!(!fs::metadata("/dev/null").unwrap().is_file());
        if Path::new("/dev/full").exists() {
            let e = write_atomic(Path::new("/dev/full"), b"x").unwrap_err();
            assert_eq!(e.raw_os_error(), Some(28), "ENOSPC: {e}");
            assert!(!fs::metadata("/dev/full").unwrap().is_file());
        }
        // A link loop is an error, not a hang.
        std::os::unix::fs::symlink("loop", dir.join("loop")).unwrap();
        assert!(write_atomic(&dir.join("loop"), b"x").is_err());
        fs::remove_dir_all(&dir).unwrap();
    }
}
