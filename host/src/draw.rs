//! Drawing for pictures people look at: label colours, masks blended over colour images,
//! lines, arrows and dots. Everything clips to a rectangle of the image, so a shape that
//! leaves it is cut, never wrapped or a panic.

use crate::io::image::RgbImage;

/// A distinct, stable colour per instance label (golden-ratio hues, bright enough to read
/// on black); `0` is black.
#[must_use]
pub fn label_colour(label: u16) -> [u8; 3] {
    if label == 0 {
        return [0, 0, 0];
    }
    let h = (f32::from(label) * 0.618_034).fract() * 6.0;
    let x = 1.0 - ((h % 2.0) - 1.0).abs();
    let (r, g, b) = match h as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    [r, g, b].map(|c: f32| (40.0 + 215.0 * c) as u8)
}

/// The push's colour in pictures.
pub const PUSH_COLOUR: [u8; 3] = [255, 230, 0];

/// A body frame's colour in pictures: its twist group's (the label colour of `group + 1`)
/// when that group moved; grey when it joined no group or a static one.
#[must_use]
pub fn body_frame_colour(group: Option<u16>, moving: bool) -> [u8; 3] {
    match group {
        Some(id) if moving => label_colour(id.saturating_add(1)),
        _ => [120, 120, 120],
    }
}

/// `rgb` with each labelled pixel blended half-way to its label's colour and the label
/// boundaries (a 4-neighbour with another label) drawn in full colour; background is
/// dimmed. `labels` must hold one label per pixel; missing labels count as background.
#[must_use]
pub fn overlay_labels(rgb: &RgbImage, labels: &[u16]) -> RgbImage {
    let (w, h) = (rgb.width(), rgb.height());
    let label = |x: usize, y: usize| labels.get(y * w + x).copied().unwrap_or(0);
    RgbImage::from_fn(rgb.width(), rgb.height(), |x, y| {
        let (x, y) = (x, y);
        let c = rgb.as_slice().get(y * w + x).copied().unwrap_or_default();
        let l = label(x, y);
        if l == 0 {
            return c.map(|v| v / 2);
        }
        let edge = (x > 0 && label(x - 1, y) != l)
            || (x + 1 < w && label(x + 1, y) != l)
            || (y > 0 && label(x, y - 1) != l)
            || (y + 1 < h && label(x, y + 1) != l);
        let lc = label_colour(l);
        if edge {
            lc
        } else {
            [0, 1, 2].map(|i| ((u16::from(c[i]) + u16::from(lc[i])) / 2) as u8)
        }
    })
}

/// A rectangle of an image that drawing stays inside: `x0..x1 × y0..y1`, pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Clip {
    /// First column.
    pub x0: usize,
    /// First row.
    pub y0: usize,
    /// One past the last column.
    pub x1: usize,
    /// One past the last row.
    pub y1: usize,
}

impl Clip {
    /// The whole of `img`.
    #[must_use]
    pub fn all(img: &RgbImage) -> Self {
        Self {
            x0: 0,
            y0: 0,
            x1: img.width(),
            y1: img.height(),
        }
    }
}

/// Sets pixel `(x, y)` (rounded) to `colour` if it lies inside `clip`.
pub fn put(img: &mut RgbImage, clip: Clip, x: f32, y: f32, colour: [u8; 3]) {
    let (px, py) = (x.round(), y.round());
    let inside = px >= clip.x0 as f32
        && py >= clip.y0 as f32
        && px < clip.x1.min(img.width()) as f32
        && py < clip.y1.min(img.height()) as f32;
    if inside {
        let index = py as usize * img.width() + px as usize;
        if let Some(p) = img.as_mut_slice().get_mut(index) {
            *p = colour;
        }
    }
}

/// A line from `a` to `b` (pixels), `thick` pixels wide (1 or more).
pub fn line(img: &mut RgbImage, clip: Clip, a: [f32; 2], b: [f32; 2], colour: [u8; 3], thick: u32) {
    let span = (b[0] - a[0]).abs().max((b[1] - a[1]).abs());
    if !span.is_finite() {
        return;
    }
    let n = (span.ceil() as usize).clamp(1, 1 << 16);
    let r = thick.saturating_sub(1) as f32 / 2.0;
    for i in 0..=n {
        let t = i as f32 / n as f32;
        let (x, y) = (a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t);
        let mut oy = -r;
        while oy <= r {
            let mut ox = -r;
            while ox <= r {
                put(img, clip, x + ox, y + oy, colour);
                ox += 1.0;
            }
            oy += 1.0;
        }
    }
}

/// An arrow from `from` to `to` (pixels): a shaft and two barbs at ±150° from the
/// direction, `thick` pixels wide. Nothing is drawn for a zero or non-finite arrow.
pub fn arrow(
    img: &mut RgbImage,
    clip: Clip,
    from: [f32; 2],
    to: [f32; 2],
    colour: [u8; 3],
    thick: u32,
) {
    let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
    let len = (dx * dx + dy * dy).sqrt();
    if !len.is_finite() || len < 1e-3 {
        return;
    }
    let (ux, uy) = (dx / len, dy / len);
    let head = (0.35 * len).clamp(3.0, 12.0);
    let (c, s) = (0.866_f32, 0.5_f32);
    line(img, clip, from, to, colour, thick);
    for sign in [1.0, -1.0] {
        let barb = [
            to[0] - head * (c * ux - sign * s * uy),
            to[1] - head * (sign * s * ux + c * uy),
        ];
        line(img, clip, to, barb, colour, thick);
    }
}

/// A filled square dot of side `2·radius + 1` centred on `at`.
pub fn dot(img: &mut RgbImage, clip: Clip, at: [f32; 2], colour: [u8; 3], radius: u32) {
    let r = radius as f32;
    let mut oy = -r;
    while oy <= r {
        let mut ox = -r;
        while ox <= r {
            put(img, clip, at[0] + ox, at[1] + oy, colour);
            ox += 1.0;
        }
        oy += 1.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arrows_clip_to_their_rectangle_and_reach_their_tip() {
        let mut img = RgbImage::from_fn(20, 10, |_, _| [0; 3]);
        let clip = Clip {
            x0: 0,
            y0: 0,
            x1: 10,
            y1: 10,
        };
        arrow(&mut img, clip, [2.0, 5.0], [30.0, 5.0], [255, 0, 0], 1);
        assert_eq!(img.get(5, 5), Some(&[255, 0, 0]));
        // Clipped at x = 10: nothing drawn to the right.
        assert!((10..20).all(|x| img.get(x, 5) == Some(&[0; 3])));
        let mut img = RgbImage::from_fn(20, 10, |_, _| [0; 3]);
        let all = Clip::all(&img);
        arrow(&mut img, all, [2.0, 5.0], [15.0, 5.0], [9; 3], 1);
        assert_eq!(img.get(15, 5), Some(&[9; 3]));
        // Barbs go back from the tip, above and below the shaft.
        assert!(img.get(12, 4) == Some(&[9; 3]) || img.get(12, 3) == Some(&[9; 3]));
        arrow(&mut img, all, [f32::NAN, 0.0], [1.0, 1.0], [1; 3], 3);
    }

    #[test]
    fn overlays_mark_boundaries_in_the_label_colour_and_dim_the_background() {
        let rgb = RgbImage::from_fn(4, 3, |_, _| [100; 3]);
        let labels = [0, 0, 0, 0, 0, 7, 7, 0, 0, 7, 7, 0];
        let out = overlay_labels(&rgb, &labels);
        assert_eq!(out.get(0, 0), Some(&[50; 3]));
        assert_eq!(out.get(1, 1), Some(&label_colour(7)));
        assert_ne!(label_colour(7), label_colour(8));
    }
}
