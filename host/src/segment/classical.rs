//! The built-in classical segmenter: no model weights, RGB-D geometry only (colour helps
//! at ambiguous creases).
//!
//! Pipeline, each stage documented in its module:
//! 1. back-project depth (row by row as the smoothing reads it), smooth the points
//!    edge-aware, normals from cross products
//!    ([`geometry`](super::geometry));
//! 2. fit the table plane by seeded RANSAC and least squares, and the hull of its inliers
//!    ([`plane`](super::plane));
//! 3. object pixels: height above the table in `[h_min(z), max_height_m]`, footprint at
//!    least `hull_margin_m` inside the hull;
//! 4. concave creases (dropping specks smaller than `crease_min_area_m2`), region growing, small-segment cleanup, hole filling
//!    ([`grow`](super::grow));
//! 5. the heatmap ([`heat`](super::heat)).
//!
//! Like the learned segmenters RISeg corrects, it merges touching objects whose contact
//! shows no depth step, concave crease or crease with a colour change (two boxes of equal
//! height pushed flush together are one segment); the heatmap marks the creases and
//! contacts it does see as uncertain.
//!
//! All frame-sized buffers live in the segmenter and are reused, so segmenting a stream of
//! frames of one size allocates only the output and line buffers (a few kilobytes per
//! parallel task). With the `threads` feature the per-pixel stages run rows in parallel;
//! every pixel's arithmetic is the same whatever the thread count, so the output is
//! bit-identical on 1 or more threads and without the feature.

use riseg_core::Intrinsics;

use super::{
    RgbdFrame, SegmentError, Segmentation, SegmenterParams, StaticSegmenter,
    geometry::{self, P3},
    grow::{GrowInput, GrowScratch, grow_segments},
    heat::{HeatInput, HeatScratch, heatmap},
    plane::{PlaneScratch, TableFit, TablePlane, fit_table, is_grid_row},
};
use crate::{io::image::Image, par::*};

/// Heat of background points just under the object threshold (see [`heat`](super::heat)).
const TABLE_HEAT_MAX: f32 = 100.0;

/// The result of [`ClassicalSegmenter::segment_detailed`]: the segmentation and the table
/// it found.
#[derive(Debug, Clone, PartialEq)]
pub struct ClassicalOutput {
    /// Labels and heatmap.
    pub segmentation: Segmentation,
    /// The fitted table plane, camera frame.
    pub plane: TablePlane,
}

#[derive(Debug, Default)]
struct Scratch {
    smooth: geometry::SmoothScratch,
    pts: Vec<P3>,
    nrm: Vec<P3>,
    crease: Vec<u8>,
    object: Vec<bool>,
    px_area_m2: Vec<f32>,
    hole: Vec<u8>,
    step: Vec<u8>,
    queue: Vec<u32>,
    seen: Vec<bool>,
    plane: PlaneScratch,
    grow: GrowScratch,
    heat: HeatScratch,
}

/// Table-plane fit + region growing over depth and normal continuity (module docs).
#[derive(Debug)]
pub struct ClassicalSegmenter {
    params: SegmenterParams,
    scratch: Scratch,
}

/// One row of the height test, branch-free so that the compiler vectorises it: `heat` is
/// `⌊100 · max(0, h / h_min)⌋` for points below the object threshold, 0 elsewhere, and
/// `object` marks points from the threshold up to `max_height_m` (the candidates of the
/// hull test).
fn classify_row(
    [px, py, pz]: [&[f32]; 3],
    table: &TableFit,
    p: &SegmenterParams,
    object: &mut [bool],
    heat: &mut [u8],
) {
    let w = object.len();
    let (px, py, pz, heat) = (&px[..w], &py[..w], &pz[..w], &mut heat[..w]);
    for x in 0..w {
        let q = [px[x], py[x], pz[x]];
        let height = table.height_of(q);
        let h_min = p.min_height_at_m(q[2]);
        let below = height < h_min;
        let value = (TABLE_HEAT_MAX * (height / h_min).max(0.0)) as u8;
        heat[x] = if (q[2] > 0.0) & below { value } else { 0 };
        object[x] = (q[2] > 0.0) & !below & (height <= p.max_height_m);
    }
}

impl ClassicalSegmenter {
    /// A segmenter with checked `params`.
    ///
    /// # Errors
    /// [`SegmentError::BadParams`] if a field is out of range.
    pub fn new(params: SegmenterParams) -> Result<Self, SegmentError> {
        params.check()?;
        Ok(Self {
            params,
            scratch: Scratch::default(),
        })
    }

    /// The parameters in use.
    #[must_use]
    pub fn params(&self) -> &SegmenterParams {
        &self.params
    }

    /// Segments `frame` and also returns the table plane.
    ///
    /// # Errors
    /// [`SegmentError::Intrinsics`] for bad intrinsics, [`SegmentError::NoTablePlane`] when
    /// no plane holds `min_table_share` of the depth samples (no table in view, or almost
    /// no depth), [`SegmentError::TooManySegments`] beyond 65 535 segments.
    pub fn segment_detailed(
        &mut self,
        frame: &RgbdFrame<'_>,
        intrinsics: &Intrinsics,
    ) -> Result<ClassicalOutput, SegmentError> {
        intrinsics.check()?;
        let (w, h) = (frame.width(), frame.height());
        let n = w * h;
        let p = &self.params;
        let s = &mut self.scratch;
        s.pts.resize(n, [0.0; 3]);
        s.nrm.resize(n, [0.0; 3]);
        s.crease.resize(n, 0);
        s.object.resize(n, false);
        s.px_area_m2.resize(n, 0.0);
        s.hole.resize(n, 0);
        s.step.resize(n, 0);

        geometry::smooth_points(frame, intrinsics, p, &mut s.smooth, &mut s.pts);
        // Normals where they are read: the table fit's grid rows now, the rows around the
        // objects (for creases and growing) once the objects are known.
        let grid_row = |y| is_grid_row(w, h, y);
        geometry::normals(w, h, &s.smooth.planes, p, grid_row, &mut s.nrm);
        let table = fit_table(w, h, &s.pts, &s.nrm, p, &mut s.plane)?;
        let px_per_m2 = 1.0 / (intrinsics.fx * intrinsics.fy);
        for (a, q) in s.px_area_m2.iter_mut().zip(&s.pts) {
            *a = q[2] * q[2] * px_per_m2;
        }
        let mut heat = vec![0u8; n];
        let planes = &s.smooth.planes;
        s.object
            .par_chunks_mut(w)
            .zip(heat.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, (object, heat))| {
                let [px, py, pz] = planes.row_xyz(y);
                classify_row([px, py, pz], &table, p, object, heat);
                table
                    .hull
                    .keep_inside([px, py, pz], p.hull_margin_m, object);
            });

        let object_rows = geometry::object_rows(w, &s.object);
        // Creases read normals `crease_radius_px` rows above and below an object pixel;
        // growing reads them at object pixels only.
        let near = object_rows.start.saturating_sub(p.crease_radius_px)
            ..(object_rows.end + p.crease_radius_px).min(h);
        if !object_rows.is_empty() {
            geometry::normals(
                w,
                h,
                &s.smooth.planes,
                p,
                |y| near.contains(&y) && !grid_row(y),
                &mut s.nrm,
            );
        }
        let crease_input = geometry::CreaseInput {
            w,
            h,
            rgb: frame.rgb(),
            pts: &s.pts,
            nrm: &s.nrm,
            object: &s.object,
            object_rows: object_rows.clone(),
        };
        geometry::creases(&crease_input, p, &mut s.crease);
        geometry::drop_small_regions(
            w,
            h,
            &s.px_area_m2,
            p.crease_min_area_m2,
            &mut s.crease,
            &mut s.queue,
            &mut s.seen,
        );

        let mut labels = vec![0u16; n];
        let segments = grow_segments(
            &GrowInput {
                w,
                h,
                pts: &s.pts,
                nrm: &s.nrm,
                crease: &s.crease,
                object: &s.object,
                object_rows,
                px_area_m2: &s.px_area_m2,
            },
            p,
            &mut s.grow,
            &mut labels,
            &mut s.hole,
            &mut s.step,
        )?;
        geometry::drop_small_regions(
            w,
            h,
            &s.px_area_m2,
            p.crease_min_area_m2,
            &mut s.step,
            &mut s.queue,
            &mut s.seen,
        );
        heatmap(
            &HeatInput {
                w,
                h,
                pts: &s.pts,
                crease: &s.crease,
                hole: &s.hole,
                step: &s.step,
                labels: &labels,
                segments,
                inv_focal: 1.0 / (intrinsics.fx * intrinsics.fy).sqrt(),
                table_normal: table.plane.normal.into(),
            },
            p,
            &mut s.heat,
            &mut heat,
        );
        Ok(ClassicalOutput {
            segmentation: Segmentation {
                labels: Image::from_vec(w, h, labels).expect("one label per pixel"),
                heatmap: Image::from_vec(w, h, heat).expect("one heat value per pixel"),
            },
            plane: table.plane,
        })
    }
}

impl StaticSegmenter for ClassicalSegmenter {
    /// See [`ClassicalSegmenter::segment_detailed`] for the errors.
    fn segment(
        &mut self,
        frame: &RgbdFrame<'_>,
        intrinsics: &Intrinsics,
    ) -> Result<Segmentation, SegmentError> {
        self.segment_detailed(frame, intrinsics)
            .map(|o| o.segmentation)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testkit::segment::SyntheticTabletop;

    #[test]
    fn same_frame_and_seed_give_the_same_output() {
        let t = SyntheticTabletop::boxes(320, 240, 5).unwrap();
        let frame = RgbdFrame::new(320, 240, &t.rgb, &t.depth_m).unwrap();
        let mut a = ClassicalSegmenter::new(SegmenterParams::default()).unwrap();
        let first = a.segment(&frame, &t.intrinsics).unwrap();
        let again = a.segment(&frame, &t.intrinsics).unwrap();
        let mut b = ClassicalSegmenter::new(SegmenterParams::default()).unwrap();
        assert_eq!(first, again);
        assert_eq!(first, b.segment(&frame, &t.intrinsics).unwrap());
        assert!(first.segment_count() >= 3);
    }

    #[test]
    fn every_marker_of_a_missing_reading_gives_the_same_output() {
        let (w, h) = (320, 240);
        let t = SyntheticTabletop::boxes(w, h, 5).unwrap();
        // Holes scattered over table and objects, plus a block and a full row.
        let mut rng = riseg_core::rng::Pcg32::new(11);
        let holes: Vec<bool> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                rng.below(9) == 0 || (100..130).contains(&x) && (90..110).contains(&y) || y == 60
            })
            .collect();
        let mut seg = ClassicalSegmenter::new(SegmenterParams::default()).unwrap();
        let outputs: Vec<_> = [0.0, -0.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY]
            .into_iter()
            .map(|marker| {
                let depth: Vec<f32> = t
                    .depth_m
                    .iter()
                    .zip(&holes)
                    .map(|(&z, &hole)| if hole { marker } else { z })
                    .collect();
                let frame = RgbdFrame::new(w, h, &t.rgb, &depth).unwrap();
                seg.segment(&frame, &t.intrinsics).unwrap()
            })
            .collect();
        assert!(outputs[0].segment_count() >= 2);
        for out in &outputs[1..] {
            assert_eq!(out, &outputs[0]);
        }
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        let t = SyntheticTabletop::boxes(64, 48, 5).unwrap();
        assert!(matches!(
            RgbdFrame::new(64, 48, &t.rgb[1..], &t.depth_m),
            Err(SegmentError::SizeMismatch { what: "rgb", .. })
        ));
        assert!(matches!(
            RgbdFrame::new(0, 48, &[], &[]),
            Err(SegmentError::Empty { .. })
        ));
        assert!(matches!(
            RgbdFrame::new(1 << 16, 1 << 16, &[], &[]),
            Err(SegmentError::TooLarge { .. })
        ));
        let mut seg = ClassicalSegmenter::new(SegmenterParams::default()).unwrap();
        let frame = RgbdFrame::new(64, 48, &t.rgb, &t.depth_m).unwrap();
        let mut k = t.intrinsics;
        k.fx = f32::NAN;
        assert!(matches!(
            seg.segment(&frame, &k),
            Err(SegmentError::Intrinsics(_))
        ));
        // No depth at all, or depth that is all NaN / negative: no table.
        for fill in [0.0, f32::NAN, -1.0, f32::INFINITY] {
            let depth = vec![fill; 64 * 48];
            let frame = RgbdFrame::new(64, 48, &t.rgb, &depth).unwrap();
            assert!(matches!(
                seg.segment(&frame, &t.intrinsics),
                Err(SegmentError::NoTablePlane { .. })
            ));
        }
        // Tiny frames segment without panicking.
        for (w, h) in [(1, 1), (3, 2), (1, 40), (17, 1), (40, 1), (1, 200_000)] {
            let t = SyntheticTabletop::boxes(w, h, 5).unwrap();
            let frame = RgbdFrame::new(w, h, &t.rgb, &t.depth_m).unwrap();
            let _ = seg.segment(&frame, &t.intrinsics);
        }
        assert!(matches!(
            ClassicalSegmenter::new(SegmenterParams {
                min_height_m: 1.0,
                ..SegmenterParams::default()
            }),
            Err(SegmentError::BadParams { .. })
        ));
    }
}
