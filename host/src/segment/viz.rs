//! A picture for people: colour | labels | heatmap, side by side, to check a segmentation
//! by eye.
//!
//! Labels: background black, each segment a distinct colour ([`label_colour`]). Heatmap: below 120 grey (brightness `v`/2, the
//! table is dark), 120-149 orange to yellow (uncertain), 150-255 green getting lighter
//! (certain).

use super::{HEAT_CERTAIN, HEAT_UNCERTAIN, Segmentation};

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

/// `rgb | labels | heatmap` as one `3·width × height` RGB image (row-major). `rgb` must
/// hold `width·height` pixels; missing pixels are drawn black.
#[must_use]
pub fn side_by_side(rgb: &[[u8; 3]], seg: &Segmentation) -> Vec<[u8; 3]> {
    let w = seg.width;
    let mut out = Vec::with_capacity(3 * w * seg.height);
    for y in 0..seg.height {
        let row = y * w..(y + 1) * w;
        let colour = rgb.get(row.clone());
        out.extend((0..w).map(|x| colour.map_or([0; 3], |c| c[x])));
        let labels = seg.labels.get(row.clone()).unwrap_or(&[]);
        out.extend((0..w).map(|x| label_colour(labels.get(x).copied().unwrap_or(0))));
        let heat = seg.heatmap.get(row).unwrap_or(&[]);
        out.extend((0..w).map(|x| heat_colour(heat.get(x).copied().unwrap_or(0))));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn picture_is_three_panels_and_bands_have_their_colours() {
        let seg = Segmentation {
            width: 2,
            height: 1,
            labels: vec![0, 1],
            heatmap: vec![10, 200],
        };
        let out = side_by_side(&[[9, 9, 9], [8, 8, 8]], &seg);
        assert_eq!(out.len(), 6);
        assert_eq!(out[2], [0, 0, 0]);
        assert_ne!(out[3], [0, 0, 0]);
        assert_eq!(heat_colour(130)[0], 255);
        assert!(heat_colour(255)[1] > 200 && heat_colour(0) == [0, 0, 0]);
        assert_ne!(label_colour(1), label_colour(2));
    }
}
