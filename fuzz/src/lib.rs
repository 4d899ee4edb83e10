//! Input builders shared by the fuzz targets in `fuzz_targets/`.
//!
//! Each builder turns fuzzer bytes (an [`Unstructured`]) into a value of the domain the
//! target attacks. Most draws are *plausible* (a depth near a tabletop, a config near
//! [`Config::PAPER`]) so that the fuzzer reaches deep code, and a share are *anything*
//! (NaN, infinities, huge, negative, zero) so that every guard is exercised. Nothing here
//! filters out inputs a caller could pass: the targets only restrict sizes, so that one
//! execution stays fast.

use arbitrary::{Result, Unstructured};
use riseg_core::{Config, Intrinsics, MAX_CLUSTERS};

/// Largest image side the pipeline targets use: big enough for several segments and
/// frames, small enough for thousands of executions per second.
pub const MAX_SIDE_PX: usize = 24;

/// Largest [`Config::frame_samples`] drawn (the grouping scratch grows as its square).
pub const MAX_FRAME_SAMPLES: usize = 300;

/// Largest [`Config::kmeans_samples`] drawn.
pub const MAX_KMEANS_SAMPLES: usize = 600;

/// Any `f32` bit pattern: NaN, infinities, subnormals and huge values included.
///
/// # Errors
/// Only when `u` is exhausted in a way `arbitrary` reports (it usually yields zeros).
pub fn any_f32(u: &mut Unstructured<'_>) -> Result<f32> {
    Ok(f32::from_bits(u.arbitrary()?))
}

/// A positive value near `typical` (factors from 1/16 to 16, most near 1), or, one time in
/// eight, any `f32`.
///
/// # Errors
/// As [`any_f32`].
pub fn near(u: &mut Unstructured<'_>, typical: f32) -> Result<f32> {
    let sel: u8 = u.arbitrary()?;
    if sel >= 224 {
        any_f32(u)
    } else {
        Ok(typical * ((f32::from(sel) - 112.0) / 28.0).exp2())
    }
}

/// A config near [`Config::PAPER`]: every length and count is drawn around its paper value
/// (sometimes anything, so [`Config::check`] is exercised), with the counts that size the
/// workspace capped by [`MAX_FRAME_SAMPLES`] and [`MAX_KMEANS_SAMPLES`].
///
/// # Errors
/// As [`any_f32`].
pub fn config(u: &mut Unstructured<'_>) -> Result<Config> {
    let p = Config::PAPER;
    let mut c = p;
    c.frame_samples = u.int_in_range(0..=MAX_FRAME_SAMPLES)?;
    c.frame_max_side_m = near(u, 0.2)?;
    c.frame_min_side_m = if u.arbitrary()? {
        0.0
    } else {
        near(u, p.frame_min_side_m)?
    };
    c.frame_min_sin = near(u, p.frame_min_sin)?;
    c.depth_edge_m = near(u, p.depth_edge_m)?;
    c.depth_window_px = u.int_in_range(0..=9)?;
    c.depth_window_tol_m = near(u, p.depth_window_tol_m)?;
    c.frame_rigid_tol_m = near(u, 0.5)?;
    c.length_scale_m = near(u, p.length_scale_m)?;
    c.static_below_m = near(u, p.static_below_m)?;
    c.kde_range_m = near(u, p.kde_range_m)?;
    c.kde_bandwidth_m = near(u, p.kde_bandwidth_m)?;
    c.link_posterior = near(u, p.link_posterior)?;
    c.min_group_frames = u.int_in_range(0..=8)?;
    c.min_segment_px = u.int_in_range(0..=40)?;
    c.grow_tol_px = near(u, p.grow_tol_px)?;
    c.merge_twist_m = if u.arbitrary()? { 0.0 } else { near(u, 0.002)? };
    c.certain_from = u.arbitrary()?;
    c.uncertain_from = u.arbitrary()?;
    c.max_clusters = u.int_in_range(0..=MAX_CLUSTERS + 1)?;
    c.kmeans_samples = u.int_in_range(0..=MAX_KMEANS_SAMPLES)?;
    c.kmeans_iters = u.int_in_range(0..=30)?;
    c.region_min_area_m2 = near(u, p.region_min_area_m2)?;
    c.region_max_len_m = near(u, p.region_max_len_m)?;
    c.region_cell_m = near(u, p.region_cell_m)?;
    c.pair_max_m = near(u, p.pair_max_m)?;
    c.uncertain_max_m = near(u, p.uncertain_max_m)?;
    c.push_len_m = near(u, p.push_len_m)?;
    c.push_carry_frac = if u.arbitrary()? { 0.0 } else { near(u, p.push_carry_frac)? };
    c.max_pushes = u.arbitrary()?;
    c.seed = u.arbitrary()?;
    Ok(c)
}

/// Intrinsics for a `width × height` image: a focal length near 40 px and the principal
/// point near the centre, or, one time in eight per value, anything (so they may fail
/// [`Intrinsics::check`]).
///
/// # Errors
/// As [`any_f32`].
pub fn intrinsics(u: &mut Unstructured<'_>, width: usize, height: usize) -> Result<Intrinsics> {
    let f = near(u, 40.0)?;
    let fy = if u.arbitrary()? { f } else { near(u, 40.0)? };
    let centre = |u: &mut Unstructured<'_>, side: usize| -> Result<f32> {
        let c = side as f32 / 2.0;
        Ok(c * near(u, 1.0)?)
    };
    Ok(Intrinsics {
        fx: f,
        fy,
        cx: centre(u, width)?,
        cy: centre(u, height)?,
    })
}

/// A depth reading in metres: mostly a tabletop distance (0.3 to 1.3 m in 4 mm steps), else
/// no reading (0), NaN, an infinity, a negative value, or any `f32`.
///
/// # Errors
/// As [`any_f32`].
pub fn depth_m(u: &mut Unstructured<'_>) -> Result<f32> {
    Ok(match u.arbitrary::<u8>()? {
        b @ 0..=249 => 0.3 + f32::from(b) * 0.004,
        250 => 0.0,
        251 => f32::NAN,
        252 => f32::INFINITY,
        253 => -0.5,
        _ => any_f32(u)?,
    })
}

/// A flow vector in pixels: mostly small (quarter-pixel steps within ±8 px), else any pair
/// of `f32`.
///
/// # Errors
/// As [`any_f32`].
pub fn flow_px(u: &mut Unstructured<'_>) -> Result<[f32; 2]> {
    let (a, b): (i8, i8) = (u.arbitrary()?, u.arbitrary()?);
    if a == i8::MIN {
        Ok([any_f32(u)?, any_f32(u)?])
    } else {
        Ok([f32::from(a) / 16.0, f32::from(b) / 16.0])
    }
}

/// A label map with values `0..=max_label` (`max_label` at most 255, so segments repeat and
/// touch), row-major, `pixels` long.
///
/// # Errors
/// As [`any_f32`].
pub fn labels(u: &mut Unstructured<'_>, pixels: usize, max_label: u8) -> Result<Vec<u16>> {
    many(u, pixels, |u| {
        Ok(u16::from(u.arbitrary::<u8>()?) % (u16::from(max_label) + 1))
    })
}

/// An image size with sides in `1..=MAX_SIDE_PX`.
///
/// # Errors
/// As [`any_f32`].
pub fn size(u: &mut Unstructured<'_>) -> Result<(usize, usize)> {
    Ok((
        u.int_in_range(1..=MAX_SIDE_PX)?,
        u.int_in_range(1..=MAX_SIDE_PX)?,
    ))
}

/// `n` values drawn with `draw`.
///
/// # Errors
/// `draw`'s errors.
pub fn many<T>(
    u: &mut Unstructured<'_>,
    n: usize,
    mut draw: impl FnMut(&mut Unstructured<'_>) -> Result<T>,
) -> Result<Vec<T>> {
    (0..n).map(|_| draw(u)).collect()
}

/// `values` made blocky in place: every pixel of a `width`-wide row-major image copies the
/// value at the top-left corner of its `block × block` cell, so regions (segments, certain
/// heatmap areas) form often; `block = 1` leaves the values as drawn.
pub fn blocky<T: Copy>(values: &mut [T], width: usize, block: usize) {
    let block = block.max(1);
    for i in 0..values.len() {
        let (x, y) = (i % width / block * block, i / width / block * block);
        if let Some(&corner) = values.get(y * width + x) {
            values[i] = corner;
        }
    }
}
