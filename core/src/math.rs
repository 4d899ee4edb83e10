//! All float transcendentals of the crate, through `libm`, so that every target (bare
//! metal, wasm32, x86_64 with or without `std`) computes bit-identical results.
//!
//! `sqrt` is correctly rounded by IEEE 754 everywhere, so nalgebra's `norm` is safe to use.

use wide::f32x4;

/// The scalar type of the crate.
pub type Real = f32;

#[inline]
pub(crate) fn sqrt(x: Real) -> Real {
    libm::sqrtf(x)
}

/// Square roots of four lanes, correctly rounded as [`sqrt`] is: one instruction where
/// the target has vector lanes (`cfg(vector_lanes)`: SSE2, WebAssembly SIMD, NEON on
/// aarch64; IEEE 754 square roots are exact), lane by lane otherwise.
#[inline]
pub(crate) fn sqrt4(x: f32x4) -> f32x4 {
    #[cfg(vector_lanes)]
    let root = x.sqrt();
    #[cfg(not(vector_lanes))]
    let root = f32x4::new(x.to_array().map(sqrt));
    root
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

/// Nearest integer, ties away from zero: bit-identical to `libm::roundf` for every input
/// (the tests check), but branch-light and inlined, for per-pixel use.
#[inline]
pub(crate) fn round(x: Real) -> Real {
    // 2^23: from here on every f32 is an integer; NaN fails the comparison too.
    if x.is_nan() || x.abs() >= 8_388_608.0 {
        return x;
    }
    // Exact: |x| < 2^23 fits i32, and x minus its truncation is representable.
    let t = libm::copysignf(x as i32 as Real, x);
    let rest = x - t;
    if rest >= 0.5 {
        t + 1.0
    } else if rest <= -0.5 {
        t - 1.0
    } else {
        t
    }
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

#[cfg(test)]
mod tests {
    use super::round;

    fn same(x: f32) -> bool {
        round(x).to_bits() == libm::roundf(x).to_bits() || (x.is_nan() && round(x).is_nan())
    }

    #[test]
    fn round_matches_libm_at_the_edges() {
        let edges = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            -1.5,
            2.5,
            0.499_999_97,
            -0.499_999_97,
            0.3,
            -0.3,
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            16_777_217.0,
            1e30,
            -1e30,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MIN_POSITIVE,
            1e-45,
        ];
        for x in edges {
            assert!(
                same(x),
                "round({x}) = {} but libm gives {}",
                round(x),
                libm::roundf(x)
            );
        }
    }

    proptest::proptest! {
        #[test]
        fn round_matches_libm_on_any_bits(bits: u32) {
            let x = f32::from_bits(bits);
            proptest::prop_assert!(same(x), "round({}) = {}, libm {}", x, round(x), libm::roundf(x));
        }

        #[test]
        fn round_matches_libm_on_pixel_coordinates(x in -2000.0f32..2000.0) {
            proptest::prop_assert!(same(x));
        }
    }
}
