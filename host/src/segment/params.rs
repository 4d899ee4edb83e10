//! Tunables of the [`ClassicalSegmenter`](super::ClassicalSegmenter), with the reason for
//! each default.
//!
//! Depth noise of stereo and structured-light cameras grows with the square of depth, so
//! the depth tolerances are "floor or a multiple of the noise at that depth, whichever is
//! larger": `max(base_m, k · depth_noise_m_at_1m · z²)` (`z` in metres), see
//! [`SegmenterParams::plane_tolerance_m`], [`SegmenterParams::min_height_at_m`] and
//! [`SegmenterParams::depth_jump_at_m`].

use super::SegmentError;

/// Noise multiples in the depth tolerances: a plane inlier is within 3 σ, a surface step
/// between neighbours within 4 σ, an object at least 4 σ above the table.
const PLANE_SIGMAS: f32 = 3.0;
const JUMP_SIGMAS: f32 = 4.0;
const HEIGHT_SIGMAS: f32 = 4.0;

/// Every tunable of the classical segmenter. Start from [`SegmenterParams::default`] and
/// assign fields; [`SegmenterParams::check`] validates them.
///
/// (De)serialises field by field under these names (the `[segmenter]` section of a
/// `riseg --config` file); a missing field keeps its default, an unknown one is an error.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SegmenterParams {
    // --- Depth noise ------------------------------------------------------------------
    /// Standard deviation of depth at 1 m, metres; it scales with `z²`. 2 mm fits a
    /// RealSense D415 and a Kinect v1 at 1 m (both grow to 1-2 cm at 2-3 m).
    pub depth_noise_m_at_1m: f32,

    // --- Table plane --------------------------------------------------------------------
    /// Seed of the RANSAC sampler: the same frame and seed give the same output.
    pub seed: u64,
    /// RANSAC hypotheses per plane search. With the table on 30 % of the sampled points a
    /// random triple is all-table with probability 0.027, so 300 draws miss it with
    /// probability 3e-4.
    pub ransac_iterations: u32,
    /// Distance from the plane within which a point is a plane inlier, metres (floor of
    /// [`Self::plane_tolerance_m`]). 8 mm absorbs a slightly warped table and the depth
    /// bias of real cameras away from the image centre.
    pub plane_inlier_m: f32,
    /// Largest angle between a point's surface normal and the plane normal for an inlier,
    /// degrees. Rejects points of walls and object sides that cross the plane.
    pub plane_normal_deg: f32,
    /// Smallest share of the sampled depth points a table must hold (a higher plane
    /// parallel to the dominant one is taken as the table only if it has this much).
    /// 0.1: a table seen by a tabletop camera covers far more, the top of a large box
    /// (which must not be taken for the table) less.
    pub min_table_share: f32,
    /// A parallel plane must lie this far above the dominant plane to be a candidate
    /// table (the dominant plane may be the floor), metres.
    pub table_step_m: f32,
    /// How far inside the convex hull of the table's inliers an object's footprint must be,
    /// metres. 1 cm keeps a wall rising behind the table, whose foot is the hull's edge,
    /// out of the objects.
    pub hull_margin_m: f32,

    // --- Objects ------------------------------------------------------------------------
    /// Smallest height above the table of an object point, metres (floor of
    /// [`Self::min_height_at_m`]). 1.2 cm: above the plane's noise and warp, below the
    /// thinnest objects of interest (a book lying flat).
    pub min_height_m: f32,
    /// Largest height above the table of an object point, metres. Higher points (walls,
    /// people, shelves) are not objects on the table.
    pub max_height_m: f32,
    /// Largest depth step between neighbouring pixels of one surface, metres, measured
    /// along the surface normal (floor of [`Self::depth_jump_at_m`]). 8 mm: larger than the
    /// noise, smaller than the step where one object occludes another.
    pub depth_jump_m: f32,
    /// Largest angle between the smoothed normals of neighbouring pixels of one surface,
    /// degrees. Loose (the smoothing spreads a 90° box edge over several pixels, and convex
    /// edges belong to one object); concave creases are what separates objects.
    pub grow_normal_deg: f32,

    // --- Normals and creases ------------------------------------------------------------
    /// Half-width of the edge-aware box filter on the 3-D points before normals, pixels.
    pub smooth_radius_px: usize,
    /// Normals are the cross product of point differences `±normal_radius_px` apart.
    pub normal_radius_px: usize,
    /// Creases compare the normals `±crease_radius_px` apart along x and along y.
    pub crease_radius_px: usize,
    /// A concave bend of the surface sharper than this is a soft crease: growth goes on
    /// across it (as a learned segmenter would merge touching objects) but the heatmap
    /// marks it uncertain. Degrees; 20° is above the normal noise on flat surfaces and the
    /// bend of a bowl over the crease baseline.
    pub crease_soft_deg: f32,
    /// A concave bend sharper than this blocks region growing (two objects meeting at a
    /// clear V), degrees.
    pub crease_block_deg: f32,
    /// A soft crease also blocks growth when the colours on its two sides differ by more
    /// than this (sum of absolute RGB differences, 0-765). Colour alone never blocks, so
    /// printed textures do not split objects.
    pub crease_colour_diff: u16,
    /// Connected crease regions smaller than this are noise and dropped, square metres.
    /// 1 cm²: a 2 cm long crease a few pixels wide, as where two objects touch, is larger;
    /// specks from depth noise on curved or glossy surfaces are smaller.
    pub crease_min_area_m2: f32,

    // --- Cleanup ------------------------------------------------------------------------
    /// Segments with a smaller area are merged into the neighbour they share the longest
    /// depth-continuous border with, or dropped, square metres (6 cm²: a bottle cap seen from
    /// above is about 9 cm²).
    pub min_segment_area_m2: f32,
    /// An enclosed hole in depth at least this large is an uncertainty source in the
    /// heatmap (smaller ones are dropouts and are only filled), square metres.
    pub hole_min_area_m2: f32,

    // --- Heatmap ------------------------------------------------------------------------
    /// Half-width of the uncertain band (120-149) around creases, contacts and holes,
    /// metres; the value grows from 120 at the source to 149 at this distance.
    pub band_m: f32,
    /// Object pixels closer than this to the table are the rim: heat
    /// [`Self::rim_heat`], below `l_l`, so object outlines do not read as contacts, metres.
    pub rim_m: f32,
    /// Heat of rim pixels (below 120).
    pub rim_heat: u8,
    /// Distance over which certain pixels ramp from 150 to 255 once clear of the band and
    /// the rim, metres.
    pub certain_ramp_m: f32,
    /// Two segments closer than this in the image (measured at the pixel's depth, pixels
    /// without depth not counted) are in contact, metres. 2 mm: about two pixels at
    /// 0.6 m. Wider gaps are mostly objects that stand apart; marking them uncertain draws
    /// FindAction to pairs that do not touch (on the scenes of
    /// `tests/segment_calibration.rs`, 6 mm cost it several of the 23 merged scenes).
    pub contact_gap_m: f32,
    /// ... provided their depths there differ by less than this, metres. 3 cm: objects of
    /// a tabletop scene that touch side by side differ less in height seen from above;
    /// a larger difference is mostly one object occluding another farther back.
    pub contact_depth_m: f32,
    /// Radius of the disc that finds notches in a segment's outline (heatmap necks),
    /// metres. 1 cm: larger than the pixel noise of the outline, smaller than the objects.
    pub neck_radius_m: f32,
    /// Smallest share of a notch's disc that lies in its own segment (0.5 on a straight
    /// outline; 0.65 is a clear concave bend), in `(0.5, 1]`.
    pub neck_notch_share: f32,
    /// Longest chord across a neck, metres (the narrowest object of interest is about
    /// 3 cm wide).
    pub neck_chord_max_m: f32,
    /// A segment whose footprint's principal length exceeds this is a pack of several
    /// objects (heatmap packs), metres. 10.5 cm: objects of interest are up to about 7 cm
    /// across, and their visible sides add up to a centimetre; a row of two 6 cm boxes
    /// is longer.
    pub pack_max_len_m: f32,
    /// ... or whose footprint area (principal length times width) exceeds this, square
    /// metres: 65 cm², above a 7 cm square box with its sides (about 60), below four 4 cm
    /// boxes packed 2x2 (about 70).
    pub pack_max_area_m2: f32,
    /// Nominal size of one object of a pack: the cut grid's cell, metres.
    pub pack_cell_m: f32,
}

impl Default for SegmenterParams {
    fn default() -> Self {
        Self {
            depth_noise_m_at_1m: 0.002,
            seed: 1,
            ransac_iterations: 300,
            plane_inlier_m: 0.008,
            plane_normal_deg: 25.0,
            min_table_share: 0.1,
            table_step_m: 0.05,
            hull_margin_m: 0.01,
            min_height_m: 0.012,
            max_height_m: 0.5,
            depth_jump_m: 0.008,
            grow_normal_deg: 25.0,
            smooth_radius_px: 3,
            normal_radius_px: 3,
            crease_radius_px: 4,
            crease_soft_deg: 30.0,
            crease_block_deg: 45.0,
            crease_colour_diff: 90,
            crease_min_area_m2: 1e-4,
            min_segment_area_m2: 6e-4,
            hole_min_area_m2: 1e-4,
            band_m: 0.01,
            rim_m: 0.004,
            rim_heat: 100,
            certain_ramp_m: 0.02,
            contact_gap_m: 0.002,
            contact_depth_m: 0.03,
            neck_radius_m: 0.01,
            neck_notch_share: 0.65,
            neck_chord_max_m: 0.03,
            pack_max_len_m: 0.105,
            pack_max_area_m2: 0.0065,
            pack_cell_m: 0.06,
        }
    }
}

impl SegmenterParams {
    /// Checks every field against its range.
    ///
    /// # Errors
    /// [`SegmentError::BadParams`] naming the first bad field.
    pub fn check(&self) -> Result<(), SegmentError> {
        let bad = |name, reason| Err(SegmentError::BadParams { name, reason });
        let positive = [
            ("depth_noise_m_at_1m", self.depth_noise_m_at_1m),
            ("plane_inlier_m", self.plane_inlier_m),
            ("table_step_m", self.table_step_m),
            ("min_height_m", self.min_height_m),
            ("max_height_m", self.max_height_m),
            ("depth_jump_m", self.depth_jump_m),
            ("min_segment_area_m2", self.min_segment_area_m2),
            ("crease_min_area_m2", self.crease_min_area_m2),
            ("hole_min_area_m2", self.hole_min_area_m2),
            ("band_m", self.band_m),
            ("certain_ramp_m", self.certain_ramp_m),
            ("contact_depth_m", self.contact_depth_m),
            ("neck_radius_m", self.neck_radius_m),
            ("neck_chord_max_m", self.neck_chord_max_m),
            ("pack_max_len_m", self.pack_max_len_m),
            ("pack_max_area_m2", self.pack_max_area_m2),
            ("pack_cell_m", self.pack_cell_m),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return bad(name, "must be finite and > 0");
            }
        }
        let non_negative = [
            ("hull_margin_m", self.hull_margin_m),
            ("rim_m", self.rim_m),
            ("contact_gap_m", self.contact_gap_m),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, "must be finite and >= 0");
            }
        }
        let angles = [
            ("plane_normal_deg", self.plane_normal_deg),
            ("grow_normal_deg", self.grow_normal_deg),
            ("crease_soft_deg", self.crease_soft_deg),
            ("crease_block_deg", self.crease_block_deg),
        ];
        for (name, v) in angles {
            if !(v > 0.0 && v <= 180.0) {
                return bad(name, "must be in (0, 180] degrees");
            }
        }
        if self.crease_block_deg < self.crease_soft_deg {
            return bad("crease_block_deg", "must be >= crease_soft_deg");
        }
        if self.max_height_m <= self.min_height_m {
            return bad("max_height_m", "must be > min_height_m");
        }
        if !(self.min_table_share > 0.0 && self.min_table_share <= 1.0) {
            return bad("min_table_share", "must be in (0, 1]");
        }
        if !(self.neck_notch_share > 0.5 && self.neck_notch_share <= 1.0) {
            return bad("neck_notch_share", "must be in (0.5, 1]");
        }
        if self.ransac_iterations == 0 {
            return bad("ransac_iterations", "must be > 0");
        }
        if self.rim_heat >= super::HEAT_UNCERTAIN {
            return bad("rim_heat", "must be < 120 (the paper's l_l)");
        }
        for (name, v) in [
            ("smooth_radius_px", self.smooth_radius_px),
            ("normal_radius_px", self.normal_radius_px),
            ("crease_radius_px", self.crease_radius_px),
        ] {
            if !(1..=16).contains(&v) {
                return bad(name, "must be in 1..=16 pixels");
            }
        }
        Ok(())
    }

    /// Depth noise (one σ) at depth `z_m`, metres.
    #[must_use]
    pub fn noise_at_m(&self, z_m: f32) -> f32 {
        self.depth_noise_m_at_1m * z_m * z_m
    }

    /// Largest distance from the table plane of a plane inlier at depth `z_m`, metres:
    /// `max(plane_inlier_m, 3 σ(z))`.
    #[must_use]
    pub fn plane_tolerance_m(&self, z_m: f32) -> f32 {
        self.plane_inlier_m.max(PLANE_SIGMAS * self.noise_at_m(z_m))
    }

    /// Smallest height above the table of an object point at depth `z_m`, metres:
    /// `max(min_height_m, 4 σ(z))`.
    #[must_use]
    pub fn min_height_at_m(&self, z_m: f32) -> f32 {
        self.min_height_m.max(HEIGHT_SIGMAS * self.noise_at_m(z_m))
    }

    /// Largest step along the normal between neighbouring pixels of one surface at depth
    /// `z_m`, metres: `max(depth_jump_m, 4 σ(z))`.
    #[must_use]
    pub fn depth_jump_at_m(&self, z_m: f32) -> f32 {
        self.depth_jump_m.max(JUMP_SIGMAS * self.noise_at_m(z_m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_bad_fields_are_named() {
        assert_eq!(SegmenterParams::default().check(), Ok(()));
        let p = SegmenterParams {
            band_m: f32::NAN,
            ..SegmenterParams::default()
        };
        assert!(matches!(
            p.check(),
            Err(SegmentError::BadParams { name: "band_m", .. })
        ));
        let p = SegmenterParams {
            rim_heat: 130,
            ..SegmenterParams::default()
        };
        assert!(matches!(
            p.check(),
            Err(SegmentError::BadParams {
                name: "rim_heat",
                ..
            })
        ));
    }

    #[test]
    fn tolerances_grow_with_depth_squared_above_their_floor() {
        let p = SegmenterParams::default();
        assert_eq!(p.plane_tolerance_m(0.6), p.plane_inlier_m);
        assert!((p.plane_tolerance_m(3.0) - 3.0 * 0.002 * 9.0).abs() < 1e-6);
        assert!(p.depth_jump_at_m(2.0) > p.depth_jump_at_m(1.0));
    }
}
