//! numpy arrays at the boundary: every input is checked for dtype and shape before riseg
//! sees it, and every output moves a Rust `Vec` into numpy.
//!
//! # Contract
//!
//! - An input of the wrong type, dtype or number of dimensions, or an image whose size
//!   differs from the others of one call, is a `ValueError` whose message starts with the
//!   argument's name and says what was expected and what was given.
//! - A C-contiguous input is read in place (no copy); any other layout (a slice with steps,
//!   a transposed or Fortran-ordered array) is copied once into C order.
//! - Outputs take ownership of the `Vec` riseg filled (no copy) and are writable arrays.

use numpy::{
    Element, IntoPyArray, PyArray2, PyArray3, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn,
    PyUntypedArrayMethods,
    ndarray::{Array2, Array3},
};
use pyo3::{exceptions::PyValueError, prelude::*};

/// A row-major image read from a numpy array of shape `(H, W)` or `(H, W, N)`: numpy's
/// own buffer when it is C-contiguous, else a C-order copy.
#[derive(Debug)]
pub(crate) struct Pixels<'py, T: Element> {
    pub(crate) width: usize,
    pub(crate) height: usize,
    data: Data<'py, T>,
}

#[derive(Debug)]
enum Data<'py, T: Element> {
    /// numpy's buffer, borrowed for as long as the guard lives.
    Lent(PyReadonlyArrayDyn<'py, T>),
    /// A C-order copy of a strided array.
    Copied(Vec<T>),
}

impl<T: Element + Copy> Pixels<'_, T> {
    /// Every value, row-major (channels innermost).
    pub(crate) fn values(&self) -> &[T] {
        match &self.data {
            // `image` only lends C-contiguous arrays, whose slice always exists.
            Data::Lent(array) => array.as_slice().unwrap_or(&[]),
            Data::Copied(values) => values,
        }
    }

    /// Every pixel of `N` channels, row-major.
    pub(crate) fn pixels<const N: usize>(&self) -> &[[T; N]] {
        self.values().as_chunks::<N>().0
    }
}

/// `array`'s dtype and shape as Python prints them, for an error message.
fn describe(array: &Bound<'_, PyAny>) -> String {
    let attr = |key: &str| {
        array
            .getattr(key)
            .and_then(|v| v.str().map(|s| s.to_string()))
            .ok()
    };
    match (attr("dtype"), attr("shape")) {
        (Some(dtype), Some(shape)) => format!("dtype {dtype} and shape {shape}"),
        _ => format!(
            "an object of type {}",
            array
                .get_type()
                .name()
                .map_or_else(|_| "?".into(), |n| n.to_string())
        ),
    }
}

/// `array` as an image of `T` (`dtype` names `T` in messages) with `channels` values per
/// pixel: shape `(H, W)` when `channels` is `None`, `(H, W, channels)` otherwise.
///
/// # Errors
/// `ValueError` naming `name` for another type, dtype or shape.
pub(crate) fn image<'py, T: Element + Copy>(
    name: &str,
    dtype: &str,
    channels: Option<usize>,
    array: &Bound<'py, PyAny>,
) -> PyResult<Pixels<'py, T>> {
    let shape = channels.map_or_else(|| "(H, W)".to_owned(), |n| format!("(H, W, {n})"));
    let wrong = || {
        PyValueError::new_err(format!(
            "{name}: expected a numpy array of dtype {dtype} and shape {shape}, got {}",
            describe(array)
        ))
    };
    let typed = array.cast::<PyArrayDyn<T>>().map_err(|_| wrong())?;
    let (height, width) = match (typed.shape(), channels) {
        (&[h, w], None) => (h, w),
        (&[h, w, n], Some(c)) if n == c => (h, w),
        _ => return Err(wrong()),
    };
    let readonly = typed
        .try_readonly()
        .map_err(|e| PyValueError::new_err(format!("{name}: cannot be read: {e}")))?;
    let data = if readonly.is_c_contiguous() {
        Data::Lent(readonly)
    } else {
        Data::Copied(readonly.as_array().iter().copied().collect())
    };
    Ok(Pixels {
        width,
        height,
        data,
    })
}

/// `ValueError` unless every `(name, width, height)` has the size of the first.
pub(crate) fn same_size(images: &[(&str, usize, usize)]) -> PyResult<()> {
    let Some(&(first, w, h)) = images.first() else {
        return Ok(());
    };
    for &(name, width, height) in images {
        if (width, height) != (w, h) {
            return Err(PyValueError::new_err(format!(
                "{name}: shape ({height}, {width}) differs from {first}'s ({h}, {w})"
            )));
        }
    }
    Ok(())
}

/// A `(height, width)` array owning `data` (row-major, `width · height` values).
pub(crate) fn to_numpy<T: Element>(
    py: Python<'_>,
    width: usize,
    height: usize,
    data: Vec<T>,
) -> PyResult<Bound<'_, PyArray2<T>>> {
    Array2::from_shape_vec((height, width), data)
        .map(|a| a.into_pyarray(py))
        .map_err(|e| PyValueError::new_err(format!("output of {width}x{height} pixels: {e}")))
}

/// A `(height, width, N)` array owning `data` (row-major pixels of `N` values).
pub(crate) fn to_numpy_n<T: Element + Copy, const N: usize>(
    py: Python<'_>,
    width: usize,
    height: usize,
    data: Vec<[T; N]>,
) -> PyResult<Bound<'_, PyArray3<T>>> {
    Array3::from_shape_vec((height, width, N), data.into_flattened())
        .map(|a| a.into_pyarray(py))
        .map_err(|e| PyValueError::new_err(format!("output of {width}x{height} pixels: {e}")))
}
