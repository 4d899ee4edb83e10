//! A picture of a scene for people: colour | depth | labels, initial frame above the last
//! frame, at half resolution, with the pushes drawn as arrows on the initial colour image.
//!
//! Depth is grey (near = bright) scaled to the scene's depth range, missing readings dark
//! red. Labels: 0 (table/background) black, each instance its own colour; a scene without
//! labels shows a black tile there.

use crate::{
    draw::{Clip, arrow, label_colour},
    io::image::{Image, RgbImage},
    io::scene::Scene,
};

const MISSING_DEPTH: [u8; 3] = [110, 0, 0];
const ARROW: [u8; 3] = [255, 235, 0];

/// The preview image of `scene` (see the module docs). Its size is `3·w/s × 2·h/s` with
/// `s = 2` (or 1 for images narrower or lower than 2 pixels).
#[must_use]
pub fn preview(scene: &Scene) -> RgbImage {
    let (w, h) = (scene.camera.width, scene.camera.height);
    let s = if w >= 2 && h >= 2 { 2 } else { 1 };
    let (tw, th) = (w / s, h / s);
    let last = scene.frames().saturating_sub(1);
    let frames = [0, last];

    // One depth range for both rows so they compare.
    let valid = frames
        .iter()
        .filter_map(|&t| scene.depth.get(t))
        .flat_map(|d| d.as_slice().iter().copied().filter(|&v| v > 0));
    let (lo, hi) = valid.fold((u16::MAX, 0), |(lo, hi), v| (lo.min(v), hi.max(v)));
    let span = f32::from(hi.saturating_sub(lo).max(1));

    let tile = |x: usize, y: usize| -> [u8; 3] {
        let (col, row) = (x / tw, y / th);
        let t = frames[row.min(1)];
        // Top-left source pixel of this preview pixel's s×s block.
        let (sx, sy) = ((x % tw) * s, (y % th) * s);
        match col {
            0 => scene.rgb.get(t).map_or([0; 3], |img| {
                let mut sum = [0u32; 3];
                for dy in 0..s {
                    for dx in 0..s {
                        let p = img.get(sx + dx, sy + dy).copied().unwrap_or_default();
                        for (acc, v) in sum.iter_mut().zip(p) {
                            *acc += u32::from(v);
                        }
                    }
                }
                sum.map(|v| (v / (s * s) as u32) as u8)
            }),
            1 => match scene.depth.get(t).and_then(|d| d.get(sx, sy)) {
                Some(&v) if v > 0 => {
                    let near = 1.0 - f32::from(v.saturating_sub(lo)) / span;
                    [(40.0 + 215.0 * near) as u8; 3]
                }
                _ => MISSING_DEPTH,
            },
            _ => scene
                .labels
                .as_ref()
                .and_then(|l| l.get(t)?.get(sx, sy))
                .map_or([0; 3], |&l| label_colour(l)),
        }
    };
    let mut out = Image::from_fn(3 * tw, 2 * th, tile);

    for a in &scene.actions {
        let k = scene.camera.intrinsics();
        let [x, y, z] = a.start_cam_m;
        let [dx, dy, dz] = a.direction_cam;
        let end = nalgebra::Point3::new(
            x + dx * a.length_m,
            y + dy * a.length_m,
            z + dz * a.length_m,
        );
        let Some(end_px) = k.project(&end) else {
            continue;
        };
        let scale = 1.0 / s as f32;
        let from = [a.start_px[0] * scale, a.start_px[1] * scale];
        let to = [end_px.x * scale, end_px.y * scale];
        let tile = Clip {
            x0: 0,
            y0: 0,
            x1: tw,
            y1: th,
        };
        arrow(&mut out, tile, from, to, ARROW, 1);
    }
    out
}
