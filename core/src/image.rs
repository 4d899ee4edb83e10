//! Borrowed image views: width, height, row stride (in elements) and a data slice.
//!
//! The constructors check that the layout fits the slice, so once a view exists no
//! accessor panics: out-of-range coordinates give `None`.
//!
//! Pixel conventions used across the crate:
//! - depth: `f32` metres; `0`, negative, NaN, infinity and anything beyond [`MAX_DEPTH_M`] mean
//!   "no reading" and are never used;
//! - flow: `[dx, dy]` in pixels per pixel, row-major (the Middlebury `.flo` layout);
//! - labels: `u16`, `0` = background;
//! - heatmap: `u8`, 0-255, high = surely inside an object.

use crate::Error;

fn layout_ok(width: usize, height: usize, stride: usize, len: usize) -> bool {
    if stride < width {
        return false;
    }
    if height == 0 || width == 0 {
        return true;
    }
    (height - 1)
        .checked_mul(stride)
        .and_then(|n| n.checked_add(width))
        .is_some_and(|n| n <= len)
}

/// A read-only image view.
#[derive(Debug, Clone, Copy)]
pub struct ImageView<'a, T> {
    width: usize,
    height: usize,
    stride: usize,
    data: &'a [T],
}

impl<'a, T> ImageView<'a, T> {
    /// A view of `data` as `height` rows of `width` pixels, rows `stride` elements apart.
    ///
    /// # Errors
    /// [`Error::BadImageLayout`] if `stride < width` or `data.len() < (height - 1)·stride + width`.
    pub fn new(width: usize, height: usize, stride: usize, data: &'a [T]) -> Result<Self, Error> {
        if layout_ok(width, height, stride, data.len()) {
            Ok(Self {
                width,
                height,
                stride,
                data,
            })
        } else {
            Err(Error::BadImageLayout)
        }
    }

    /// A tightly packed view (`stride == width`).
    ///
    /// # Errors
    /// [`Error::BadImageLayout`] if `data` is shorter than `width·height`.
    pub fn packed(width: usize, height: usize, data: &'a [T]) -> Result<Self, Error> {
        Self::new(width, height, width, data)
    }

    /// Width in pixels.
    #[must_use]
    pub const fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    #[must_use]
    pub const fn height(&self) -> usize {
        self.height
    }

    /// `(width, height)`.
    #[must_use]
    pub const fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The pixel at column `x`, row `y`.
    #[must_use]
    pub fn get(&self, x: usize, y: usize) -> Option<&'a T> {
        if x < self.width && y < self.height {
            self.data.get(y * self.stride + x)
        } else {
            None
        }
    }

    /// Row `y`, `width` pixels long.
    #[must_use]
    pub fn row(&self, y: usize) -> Option<&'a [T]> {
        if y < self.height {
            self.data.get(y * self.stride..y * self.stride + self.width)
        } else {
            None
        }
    }

    /// Iterates over `(x, y, &pixel)` in row-major order.
    pub fn pixels(&self) -> impl Iterator<Item = (usize, usize, &'a T)> + '_ {
        (0..self.height).flat_map(move |y| {
            self.row(y)
                .unwrap_or(&[])
                .iter()
                .enumerate()
                .map(move |(x, p)| (x, y, p))
        })
    }
}

impl<T: Copy> ImageView<'_, T> {
    /// The pixel at signed coordinates, `None` outside the image (also where a
    /// coordinate does not fit a `usize`, as from 2^32 on a 32-bit target).
    #[must_use]
    pub fn at(&self, x: i64, y: i64) -> Option<T> {
        let x = usize::try_from(x).ok()?;
        let y = usize::try_from(y).ok()?;
        self.get(x, y).copied()
    }
}

/// A mutable image view.
#[derive(Debug)]
pub struct ImageViewMut<'a, T> {
    width: usize,
    height: usize,
    stride: usize,
    data: &'a mut [T],
}

impl<'a, T> ImageViewMut<'a, T> {
    /// A mutable view; same layout rule as [`ImageView::new`].
    ///
    /// # Errors
    /// [`Error::BadImageLayout`] if the layout does not fit `data`.
    pub fn new(
        width: usize,
        height: usize,
        stride: usize,
        data: &'a mut [T],
    ) -> Result<Self, Error> {
        if layout_ok(width, height, stride, data.len()) {
            Ok(Self {
                width,
                height,
                stride,
                data,
            })
        } else {
            Err(Error::BadImageLayout)
        }
    }

    /// A tightly packed mutable view.
    ///
    /// # Errors
    /// [`Error::BadImageLayout`] if `data` is shorter than `width·height`.
    pub fn packed(width: usize, height: usize, data: &'a mut [T]) -> Result<Self, Error> {
        Self::new(width, height, width, data)
    }

    /// `(width, height)`.
    #[must_use]
    pub const fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The pixel at column `x`, row `y`.
    #[must_use]
    pub fn get_mut(&mut self, x: usize, y: usize) -> Option<&mut T> {
        if x < self.width && y < self.height {
            self.data.get_mut(y * self.stride + x)
        } else {
            None
        }
    }

    /// Row `y`, mutable.
    #[must_use]
    pub fn row_mut(&mut self, y: usize) -> Option<&mut [T]> {
        if y < self.height {
            self.data
                .get_mut(y * self.stride..y * self.stride + self.width)
        } else {
            None
        }
    }

    /// A read-only view of the same pixels.
    #[must_use]
    pub fn as_view(&self) -> ImageView<'_, T> {
        ImageView {
            width: self.width,
            height: self.height,
            stride: self.stride,
            data: self.data,
        }
    }
}

/// The farthest depth that counts as a reading, metres. No RGB-D camera measures beyond
/// it; a larger value is a decoding or unit error, and letting it in would let one pixel
/// (say `1e38`) overflow the sums of a step (the space frame's origin is a mean).
pub const MAX_DEPTH_M: f32 = 100.0;

/// Depth in metres; a reading counts only when finite, positive and at most
/// [`MAX_DEPTH_M`].
#[must_use]
#[inline]
pub fn valid_depth(z: f32) -> Option<f32> {
    // The two comparisons reject NaN (both fail) and infinities (one fails): no separate
    // finiteness test (a test checks).
    if z > 0.0 && z <= MAX_DEPTH_M {
        Some(z)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rule as the docs state it.
    fn valid_depth_reference(z: f32) -> Option<f32> {
        (z.is_finite() && z > 0.0 && z <= MAX_DEPTH_M).then_some(z)
    }

    #[test]
    fn valid_depth_is_finite_positive_and_at_most_the_limit() {
        for z in [
            f32::NAN,
            -f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            0.0,
            -0.0,
            f32::MIN_POSITIVE,
            f32::from_bits(1),
            0.6,
            -0.6,
            MAX_DEPTH_M,
            f32::from_bits(MAX_DEPTH_M.to_bits() + 1),
            f32::MAX,
        ] {
            assert_eq!(
                valid_depth(z).map(f32::to_bits),
                valid_depth_reference(z).map(f32::to_bits),
                "{z}"
            );
        }
    }

    proptest::proptest! {
        #[test]
        fn valid_depth_matches_the_stated_rule_on_any_bits(bits in proptest::prelude::any::<u32>()) {
            let z = f32::from_bits(bits);
            proptest::prop_assert_eq!(
                valid_depth(z).map(f32::to_bits),
                valid_depth_reference(z).map(f32::to_bits)
            );
        }
    }

    #[test]
    fn layout_is_checked_and_accessors_never_panic() {
        let data = [1u8, 2, 3, 4, 5, 6, 7];
        assert!(ImageView::new(3, 2, 4, &data).is_ok());
        assert_eq!(
            ImageView::new(3, 3, 4, &data).err(),
            Some(Error::BadImageLayout)
        );
        assert_eq!(
            ImageView::new(5, 1, 4, &data).err(),
            Some(Error::BadImageLayout)
        );
        assert_eq!(
            ImageView::new(usize::MAX, 2, usize::MAX, &data).err(),
            Some(Error::BadImageLayout)
        );
        let v = ImageView::new(3, 2, 4, &data).unwrap();
        assert_eq!(v.get(2, 1), Some(&7));
        assert_eq!(v.get(3, 0), None);
        assert_eq!(v.at(-1, 0), None);
        assert_eq!(v.at(2, 1), Some(7));
        // A wrap to `usize` would read (0, 0) and (1, 0) on a 32-bit target.
        assert_eq!(v.at(1 << 32, 0), None);
        assert_eq!(v.at(1, 1 << 32), None);
        assert_eq!(v.at(i64::MIN, i64::MAX), None);
        assert_eq!(v.row(1), Some(&data[4..7]));
        assert_eq!(v.row(2), None);
        assert_eq!(v.pixels().count(), 6);
    }

    #[test]
    fn depth_validity() {
        assert_eq!(valid_depth(0.5), Some(0.5));
        assert_eq!(valid_depth(MAX_DEPTH_M), Some(MAX_DEPTH_M));
        for z in [0.0, -1.0, f32::NAN, f32::INFINITY, 1e38, MAX_DEPTH_M * 1.01] {
            assert_eq!(valid_depth(z), None);
        }
    }
}
