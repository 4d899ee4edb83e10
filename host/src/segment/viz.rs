//! A picture for people: colour | labels | heatmap, side by side, to check a segmentation
//! by eye.
//!
//! Labels: background black, each segment a distinct colour ([`label_colour`]). Heatmap: below 120 grey (brightness `v`/2, the
//! table is dark), 120-149 orange to yellow (uncertain), 150-255 green getting lighter
//! (certain).

use super::{HEAT_CERTAIN, HEAT_UNCERTAIN, Segmentation};
use crate::io::image::{Image, RgbImage};

pub use crate::draw::label_colour;

/// A colour for heat value `v` (module docs).
#[must_use]
pub fn heat_colour(v: u8) -> [u8; 3] {
    if v < HEAT_UNCERTAIN {
        [v / 2; 3]
    } else if v < HEAT_CERTAIN {
        [255, 110 + (v - HEAT_UNCERTAIN) * 4, 0]
    } else {
        let t = v - HEAT_CERTAIN;
        [t, 120 + t.min(135), t]
    }
}

/// `rgb | labels | heatmap` as one `3·width × height` image. Pixels `rgb` (or a
/// mis-sized heatmap) lacks are drawn black.
#[must_use]
pub fn side_by_side(rgb: &RgbImage, seg: &Segmentation) -> RgbImage {
    let (w, h) = seg.size();
    Image::from_fn(3 * w, h, |x, y| {
        let (panel, x) = (x / w, x % w);
        match panel {
            0 => rgb.get(x, y).copied().unwrap_or([0; 3]),
            1 => label_colour(seg.labels.get(x, y).copied().unwrap_or(0)),
            _ => heat_colour(seg.heatmap.get(x, y).copied().unwrap_or(0)),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn picture_is_three_panels_and_bands_have_their_colours() {
        let seg = Segmentation {
            labels: Image::from_vec(2, 1, vec![0, 1]).unwrap(),
            heatmap: Image::from_vec(2, 1, vec![10, 200]).unwrap(),
        };
        let rgb = Image::from_vec(2, 1, vec![[9, 9, 9], [8, 8, 8]]).unwrap();
        let out = side_by_side(&rgb, &seg);
        assert_eq!(out.size(), (6, 1));
        let out = out.as_slice();
        assert_eq!(out[0], [9, 9, 9]);
        assert_eq!(out[2], [0, 0, 0]);
        assert_ne!(out[3], [0, 0, 0]);
        assert_eq!(heat_colour(130)[0], 255);
        assert!(heat_colour(255)[1] > 200 && heat_colour(0) == [0, 0, 0]);
        assert_ne!(label_colour(1), label_colour(2));
    }
}
