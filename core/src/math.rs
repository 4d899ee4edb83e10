//! All float transcendentals of the crate, through `libm`, so that every target (bare
//! metal, wasm32, x86_64 with or without `std`) computes bit-identical results.
//!
//! `sqrt` is correctly rounded by IEEE 754 everywhere, so nalgebra's `norm` is safe to use.

/// The scalar type of the crate.
pub type Real = f32;

#[inline]
pub(crate) fn sqrt(x: Real) -> Real {
    libm::sqrtf(x)
}

#[inline]
pub(crate) fn sin_cos(x: Real) -> (Real, Real) {
    libm::sincosf(x)
}

#[inline]
pub(crate) fn atan2(y: Real, x: Real) -> Real {
    libm::atan2f(y, x)
}

#[inline]
pub(crate) fn exp(x: Real) -> Real {
    libm::expf(x)
}

#[inline]
pub(crate) fn round(x: Real) -> Real {
    libm::roundf(x)
}

#[inline]
pub(crate) fn floor(x: Real) -> Real {
    libm::floorf(x)
}

#[inline]
pub(crate) fn ln(x: Real) -> Real {
    libm::logf(x)
}

/// `x = m · 2^e` with `|m|` in `[0.5, 1)` (`(x, 0)` for zero, infinities and NaN).
#[inline]
pub(crate) fn frexp(x: Real) -> (Real, i32) {
    libm::frexpf(x)
}

/// `x · 2^n`, exact unless the result underflows or overflows.
#[inline]
pub(crate) fn scalbn(x: Real, n: i32) -> Real {
    libm::scalbnf(x, n)
}
