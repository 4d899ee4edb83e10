//! Finding and loading the ONNX Runtime shared library, once per process.
//!
//! Where the library comes from, in order: the `ORT_DYLIB_PATH` environment variable (a
//! path to `libonnxruntime.so`, `.dylib` or `onnxruntime.dll`), else the `capi/` folder of
//! the `onnxruntime` Python wheel that `python3` imports. Anything else (no library, a file
//! that is not one, a version older than `ort` supports) is one [`OnnxError::Runtime`]
//! saying what to install; nothing here panics on a missing or wrong library.

use std::{
    path::{Path, PathBuf},
    process::Command,
    sync::OnceLock,
};

use ort::environment::Environment;

use super::OnnxError;

/// What to install, appended to every runtime error.
const INSTALL_HINT: &str = "install the ONNX Runtime Python wheel (`python3 -m pip install \
     onnxruntime==1.32.0`) or set ORT_DYLIB_PATH to an onnxruntime shared library, version \
     1.17 or newer";

/// The process's one ONNX Runtime environment (loaded on first use).
///
/// # Errors
/// [`OnnxError::Runtime`] if the library cannot be found or loaded; the same error on
/// every later call.
pub(super) fn environment() -> Result<&'static Environment, OnnxError> {
    static ENVIRONMENT: OnceLock<Result<Environment, OnnxError>> = OnceLock::new();
    ENVIRONMENT
        .get_or_init(|| {
            let path = library_path()?;
            load(&path).map_err(|problem| {
                OnnxError::Runtime(format!(
                    "cannot load ONNX Runtime from {}: {problem}; {INSTALL_HINT}",
                    path.display()
                ))
            })
        })
        .as_ref()
        .map_err(Clone::clone)
}

/// Loads the library at `path` and builds the environment; `ort` may panic on a library
/// it cannot use, which becomes an error here.
fn load(path: &Path) -> Result<Environment, String> {
    let path = path.to_owned();
    std::panic::catch_unwind(move || {
        ort::init_from(&path)
            .map_err(|e| e.to_string())?
            .with_name("riseg")
            .build()
            .map_err(|e| e.to_string())
    })
    .unwrap_or_else(|_| Err("ONNX Runtime failed to initialise".to_owned()))
}

/// The shared library to load: `ORT_DYLIB_PATH`, else the wheel's `capi/` folder.
fn library_path() -> Result<PathBuf, OnnxError> {
    if let Some(path) = std::env::var_os("ORT_DYLIB_PATH").filter(|p| !p.is_empty()) {
        let path = PathBuf::from(path);
        if !path.is_file() {
            return Err(OnnxError::Runtime(format!(
                "ORT_DYLIB_PATH={} is not a file; {INSTALL_HINT}",
                path.display()
            )));
        }
        return Ok(path);
    }
    let output = Command::new("python3")
        .args([
            "-c",
            "import onnxruntime, os; print(os.path.dirname(onnxruntime.__file__))",
        ])
        .output();
    let package = match output {
        Ok(out) if out.status.success() => {
            PathBuf::from(String::from_utf8_lossy(&out.stdout).trim())
        }
        Ok(_) => {
            return Err(OnnxError::Runtime(format!(
                "ORT_DYLIB_PATH is not set and python3 cannot import onnxruntime; \
                 {INSTALL_HINT}"
            )));
        }
        Err(e) => {
            return Err(OnnxError::Runtime(format!(
                "ORT_DYLIB_PATH is not set and python3 cannot be run ({e}); {INSTALL_HINT}"
            )));
        }
    };
    let capi = package.join("capi");
    wheel_library(&capi).ok_or_else(|| {
        OnnxError::Runtime(format!(
            "no onnxruntime shared library in {}; {INSTALL_HINT}",
            capi.display()
        ))
    })
}

/// The main library in a wheel's `capi/` folder (`libonnxruntime.so.1.32.0`, not
/// `libonnxruntime_providers_shared.so`).
fn wheel_library(capi: &Path) -> Option<PathBuf> {
    let (prefix, suffix) = (std::env::consts::DLL_PREFIX, std::env::consts::DLL_SUFFIX);
    let stem = format!("{prefix}onnxruntime");
    let mut found: Vec<PathBuf> = std::fs::read_dir(capi)
        .ok()?
        .filter_map(Result::ok)
        .map(|entry| entry.path())
        .filter(|path| {
            path.file_name()
                .and_then(|name| name.to_str())
                .and_then(|name| name.strip_prefix(stem.as_str()))
                // `.so`, `.so.1.32.0`, `.1.32.0.dylib`, `.dll`; not `_providers_shared.so`.
                .is_some_and(|rest| {
                    rest.starts_with('.') && rest.contains(suffix.trim_start_matches('.'))
                })
        })
        .collect();
    found.sort();
    found.into_iter().next()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wheel_library_skips_the_providers_library() {
        let dir = tempfile::tempdir().unwrap();
        for name in [
            "libonnxruntime_providers_shared.so",
            "libonnxruntime.so.1.32.0",
            "__init__.py",
        ] {
            std::fs::write(dir.path().join(name), b"").unwrap();
        }
        assert_eq!(
            wheel_library(dir.path()),
            Some(dir.path().join("libonnxruntime.so.1.32.0"))
        );
        assert_eq!(wheel_library(&dir.path().join("absent")), None);
    }
}
