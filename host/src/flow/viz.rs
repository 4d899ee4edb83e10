//! Flow as a colour image with the Middlebury colour wheel (Baker et al. 2011): hue is the
//! direction, saturation the magnitude relative to a maximum.
//!
//! Directions (image axes, `dy` down): right is red, down is yellow-orange, left is cyan,
//! up is blue-violet; zero flow is white. Vectors longer than the maximum are drawn at
//! 75 % brightness; non-finite vectors (unknown flow) are black.

use crate::io::image::{FlowImage, RgbImage};

/// Colour-wheel segment lengths: red-yellow, yellow-green, green-cyan, cyan-blue,
/// blue-magenta, magenta-red.
const SEGMENTS: [usize; 6] = [15, 6, 4, 11, 13, 6];
const NCOLS: usize = 55;

/// The 55 wheel colours, 0-255.
fn wheel() -> [[f32; 3]; NCOLS] {
    let mut out = [[0.0f32; 3]; NCOLS];
    let mut k = 0;
    for (seg, &n) in SEGMENTS.iter().enumerate() {
        for i in 0..n {
            let up = (255 * i / n) as f32;
            let down = 255.0 - up;
            out[k] = match seg {
                0 => [255.0, up, 0.0],
                1 => [down, 255.0, 0.0],
                2 => [0.0, 255.0, up],
                3 => [0.0, down, 255.0],
                4 => [up, 0.0, 255.0],
                _ => [255.0, 0.0, down],
            };
            k += 1;
        }
    }
    out
}

/// The largest finite vector length in `flow`, pixels (0 for an all-zero flow).
#[must_use]
pub fn max_magnitude(flow: &FlowImage) -> f32 {
    flow.as_slice()
        .iter()
        .map(|v| libm::hypotf(v[0], v[1]))
        .filter(|m| m.is_finite())
        .fold(0.0, f32::max)
}

/// `flow` drawn as an 8-bit RGB image of its size, saturation scaled so that
/// `max_magnitude_px` (default: the flow's largest vector) is fully saturated.
#[must_use]
pub fn flow_to_rgb(flow: &FlowImage, max_magnitude_px: Option<f32>) -> RgbImage {
    let wheel = wheel();
    let max = max_magnitude_px.unwrap_or_else(|| max_magnitude(flow));
    let inv = if max > 0.0 && max.is_finite() {
        1.0 / max
    } else {
        0.0
    };
    flow.map(|v| {
        if !(v[0].is_finite() && v[1].is_finite()) {
            return [0; 3];
        }
        let rad = libm::hypotf(v[0], v[1]) * inv;
        let a = libm::atan2f(-v[1], -v[0]) / core::f32::consts::PI;
        let fk = (a + 1.0) / 2.0 * (NCOLS - 1) as f32;
        let k0 = (fk.floor() as usize).min(NCOLS - 1);
        let k1 = (k0 + 1) % NCOLS;
        let f = fk - k0 as f32;
        let mut rgb = [0u8; 3];
        for ((out, c0), c1) in rgb.iter_mut().zip(&wheel[k0]).zip(&wheel[k1]) {
            let col = ((1.0 - f) * c0 + f * c1) / 255.0;
            let col = if rad <= 1.0 {
                1.0 - rad * (1.0 - col)
            } else {
                col * 0.75
            };
            *out = (255.0 * col).clamp(0.0, 255.0) as u8;
        }
        rgb
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn colour(dx: f32, dy: f32, max: f32) -> [u8; 3] {
        let f = FlowImage::from_vec(1, 1, vec![[dx, dy]]).unwrap();
        flow_to_rgb(&f, Some(max)).as_slice()[0]
    }

    #[test]
    fn known_directions() {
        assert_eq!(colour(1.0, 0.0, 1.0), [255, 0, 0], "right is red");
        let left = colour(-1.0, 0.0, 1.0);
        assert!(
            left[0] < 10 && left[1] > 180 && left[2] == 255,
            "left {left:?}"
        );
        let down = colour(0.0, 1.0, 1.0);
        assert!(
            down[0] == 255 && down[1] > 200 && down[2] == 0,
            "down {down:?}"
        );
        let up = colour(0.0, -1.0, 1.0);
        assert!(up[2] == 255 && up[0] < 110 && up[1] == 0, "up {up:?}");
        assert_eq!(colour(0.0, 0.0, 1.0), [255, 255, 255], "zero is white");
    }

    #[test]
    fn magnitude_sets_saturation() {
        let half = colour(0.5, 0.0, 1.0);
        assert_eq!(half, [255, 127, 127]);
        let over = colour(2.0, 0.0, 1.0);
        assert_eq!(over, [191, 0, 0]);
        let f = FlowImage::from_vec(2, 1, vec![[0.0, 3.0], [f32::NAN, 0.0]]).unwrap();
        assert_eq!(max_magnitude(&f), 3.0);
        let c = flow_to_rgb(&f, None);
        assert_eq!(c.as_slice()[1], [0, 0, 0], "unknown is black");
        assert_eq!(wheel().len(), SEGMENTS.iter().sum::<usize>());
    }
}
