//! Where readers get files: the disk ([`DiskFiles`]), or files already in memory
//! ([`MemoryFiles`]: a browser, where there is no file system, gets a dropped scene folder
//! as a list of names and bytes).
//!
//! Contract of a [`Files`] source, which every reader in [`crate::io`] relies on so that a
//! scene read from memory is checked by the same rules, and fails with the same message,
//! as the same scene read from disk:
//! - [`Files::read`] gives a file's bytes, or [`io::ErrorKind::NotFound`] when there is
//!   no file at that path.
//! - [`Files::list`] gives the names of a folder's entries (files and sub-folders, in no
//!   particular order), or `NotFound` when there is no such folder.
//! - [`Files::is_dir`] and [`Files::is_file`] say whether a folder or a file is there.

use std::{
    borrow::Cow,
    collections::BTreeMap,
    ffi::OsString,
    fs, io,
    path::{Path, PathBuf},
};

/// A source of files (module docs).
pub trait Files {
    /// The bytes of the file at `path` (borrowed from a source that holds them).
    ///
    /// # Errors
    /// [`io::ErrorKind::NotFound`] if there is no such file; other errors as the source has.
    fn read(&self, path: &Path) -> io::Result<Cow<'_, [u8]>>;

    /// The names of the entries of the folder `dir`.
    ///
    /// # Errors
    /// [`io::ErrorKind::NotFound`] if there is no such folder; other errors as the source has.
    fn list(&self, dir: &Path) -> io::Result<Vec<OsString>>;

    /// Whether `path` is a folder.
    fn is_dir(&self, path: &Path) -> bool;

    /// Whether `path` is a file.
    fn is_file(&self, path: &Path) -> bool;
}

/// The file system.
#[derive(Debug, Clone, Copy, Default)]
pub struct DiskFiles;

impl Files for DiskFiles {
    fn read(&self, path: &Path) -> io::Result<Cow<'_, [u8]>> {
        fs::read(path).map(Cow::Owned)
    }

    fn list(&self, dir: &Path) -> io::Result<Vec<OsString>> {
        fs::read_dir(dir)?
            .map(|entry| entry.map(|e| e.file_name()))
            .collect()
    }

    fn is_dir(&self, path: &Path) -> bool {
        path.is_dir()
    }

    fn is_file(&self, path: &Path) -> bool {
        path.is_file()
    }
}

/// Files held in memory, by path. A folder exists when some file lies below it; there are
/// no empty folders.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct MemoryFiles {
    files: BTreeMap<PathBuf, Vec<u8>>,
}

impl MemoryFiles {
    /// No files.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds the file `path` with `bytes`, replacing a file of that path.
    pub fn insert(&mut self, path: impl Into<PathBuf>, bytes: Vec<u8>) {
        self.files.insert(path.into(), bytes);
    }

    /// The paths below `dir` (not `dir` itself), relative to it.
    fn below<'a>(&'a self, dir: &'a Path) -> impl Iterator<Item = &'a Path> + 'a {
        self.files
            .keys()
            .filter_map(move |p| p.strip_prefix(dir).ok())
            .filter(|rest| !rest.as_os_str().is_empty())
    }
}

impl Files for MemoryFiles {
    fn read(&self, path: &Path) -> io::Result<Cow<'_, [u8]>> {
        self.files
            .get(path)
            .map(|bytes| Cow::Borrowed(bytes.as_slice()))
            .ok_or_else(|| io::ErrorKind::NotFound.into())
    }

    fn list(&self, dir: &Path) -> io::Result<Vec<OsString>> {
        let mut names: Vec<OsString> = self
            .below(dir)
            .filter_map(|rest| rest.iter().next().map(OsString::from))
            .collect();
        if names.is_empty() {
            return Err(io::ErrorKind::NotFound.into());
        }
        names.dedup();
        Ok(names)
    }

    fn is_dir(&self, path: &Path) -> bool {
        self.below(path).next().is_some()
    }

    fn is_file(&self, path: &Path) -> bool {
        self.files.contains_key(path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memory_files_behave_like_a_folder_tree() {
        let mut files = MemoryFiles::new();
        files.insert("s/rgb/000000.png", vec![1]);
        files.insert("s/rgb/000001.png", vec![2]);
        files.insert("s/scene_camera.json", vec![3]);
        assert_eq!(*files.read(Path::new("s/rgb/000001.png")).unwrap(), [2]);
        let missing = files.read(Path::new("s/rgb/000002.png")).unwrap_err();
        assert_eq!(missing.kind(), io::ErrorKind::NotFound);
        let mut top = files.list(Path::new("s")).unwrap();
        top.sort();
        assert_eq!(top, ["rgb", "scene_camera.json"]);
        assert_eq!(files.list(Path::new("s/rgb")).unwrap().len(), 2);
        let no_dir = files.list(Path::new("s/depth")).unwrap_err();
        assert_eq!(no_dir.kind(), io::ErrorKind::NotFound);
        assert!(files.is_dir(Path::new("s")) && files.is_dir(Path::new("s/rgb")));
        assert!(!files.is_dir(Path::new("s/scene_camera.json")));
        assert!(
            !files.is_dir(Path::new("s/r")),
            "a name prefix is not a folder"
        );
        assert!(files.is_file(Path::new("s/scene_camera.json")));
        assert!(!files.is_file(Path::new("s/rgb")));
    }
}
