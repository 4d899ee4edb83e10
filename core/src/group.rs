//! GroupBFIFs: decide which frames lie on one rigid body from their twists and the mask.
//!
//! Contract, for frames with twists `V_i` and accumulated-mask labels `l_i`:
//! - Frames link only inside one segment of the mask; a segment is split, never merged
//!   here. A frame is *moving* when `|V_i|` (rotation weighted by
//!   [`Config::length_scale_m`]) reaches [`Config::static_below_m`]; pairs across segments
//!   count as data only when both frames move, so static frames (whose twists are all
//!   noise around zero) never say anything about other segments.
//! - The data of a pair is its twist distance `d_ij`. A binned Gaussian KDE of `d` over all
//!   pairs is split at its first valley into the near component (pairs on one body: `d`
//!   is twist noise) and the far component (pairs on two bodies that moved differently).
//!   These are the likelihoods `p(d | same body)` and `p(d | different bodies)`.
//! - The prior comes from the mask: `P(same body | one segment)` is the Laplace-smoothed
//!   share of near pairs among the pairs inside one segment. Pairs across segments shape
//!   the KDE (they show what "different bodies" look like) but never link.
//! - A pair links when the posterior `P(same body | d, mask)` exceeds
//!   [`Config::link_posterior`]. With no valley (nothing moved, one moving body, or bodies
//!   whose motions noise cannot tell apart) every pair is near.
//! - Groups are formed by quick shift on the link graph, joined with union-find: each frame
//!   points at its nearest linked frame with more links (density). A plain union of all
//!   links would let a few corrupted twists (a flow outlier, a triangle on two bodies)
//!   chain two bodies together; pointing up the density gradient does not.
//! - Groups with fewer than [`Config::min_group_frames`] frames become [`NO_GROUP`].
//!
//! Cost: three passes over the `n(n−1)/2` pairs; the first computes distances and stores
//! each pair's KDE bin in one byte, the other two read bins only.

use wide::{f32x4, i16x8, i32x4, i32x8, u8x16};

use crate::{
    Config, Error, Twist,
    error::{Buffer, check_len},
    math::{Real, exp, sqrt, sqrt4},
    union_find::{find, union},
};

/// Group id of a frame that belongs to no group.
pub const NO_GROUP: u16 = u16::MAX;

/// Bins of the distance KDE (the last bin takes everything beyond [`Config::kde_range_m`]).
pub const KDE_BINS: usize = 120;

/// Farthest a frame's quick-shift parent may be, in KDE bandwidths (the twist noise).
const ATTACH_BANDWIDTHS: Real = 3.0;

/// Pair-bin code: never linked (static with moving, or static across segments).
const NO_PAIR: u8 = 255;
/// Flag bit set on the bin of a moving pair across two segments.
const ACROSS: u8 = 0x80;
const _: () = assert!((KDE_BINS as u8 - 1) | ACROSS < NO_PAIR && KDE_BINS < 0x80);

/// A group of frames that move as one rigid body.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GroupInfo {
    /// Frames in the group.
    pub frames: u32,
    /// Spatial twist of the group's root frame (its smallest frame index; space frame of
    /// the step).
    pub twist: Twist,
    /// Whether the twist is above the noise floor.
    pub moving: bool,
    /// The accumulated-mask label of the group's frames (groups never span segments).
    pub label: u16,
}

/// Scratch for [`group_frames`]. Contents are garbage after the call.
#[derive(Debug)]
pub struct GroupScratch<'a> {
    /// One byte per frame pair, `n(n−1)/2` entries.
    pub pair_bin: &'a mut [u8],
    /// Union-find parents, then group ids; `n` entries.
    pub parent: &'a mut [u32],
    /// Link counts (density), then group ids by root; `n` entries.
    pub links: &'a mut [u32],
    /// Quick-shift parent of each frame, then its group root; `n` entries.
    pub attach: &'a mut [u32],
    /// The twists' six components, component by component (`w.x` of every frame, then
    /// `w.y`, …), so that pass 1 loads four frames' components at once; `6n` entries.
    /// [`crate::pipeline::update_mask`] lends it to [`crate::split::split_mixed_groups`]
    /// afterwards.
    pub twist_lanes: &'a mut [Real],
}

/// Element counts [`GroupScratch`] needs; `const` so bare-metal callers can size `static`s.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GroupScratchLen {
    /// Length of [`GroupScratch::pair_bin`].
    pub pair_bin: usize,
    /// Length of [`GroupScratch::parent`], [`GroupScratch::links`] and
    /// [`GroupScratch::attach`].
    pub per_frame: usize,
    /// Length of [`GroupScratch::twist_lanes`]: six per frame.
    pub twist_lanes: usize,
}

impl GroupScratchLen {
    /// Lengths for up to `n` frames. `n·(n−1)/2` is computed without an intermediate that
    /// could overflow (the even factor is halved first) and saturates at `usize::MAX`
    /// where the true count does not fit (`n > 65536` on 32-bit targets): no buffer of that
    /// size exists, so the length check then fails instead of wrapping to a short buffer.
    #[must_use]
    pub const fn for_frames(n: usize) -> Self {
        let m = n.saturating_sub(1);
        let pair_bin = if n.is_multiple_of(2) {
            (n / 2).saturating_mul(m)
        } else {
            n.saturating_mul(m / 2)
        };
        Self {
            pair_bin,
            per_frame: n,
            twist_lanes: n.saturating_mul(TWIST_LANES),
        }
    }

    /// Bytes the scratch takes (saturating): `pair_bin` bytes, then `parent`, `links` and
    /// `attach` of `per_frame` `u32`s each, then the `twist_lanes`.
    #[must_use]
    pub const fn bytes(&self) -> usize {
        self.pair_bin
            .saturating_mul(size_of::<u8>())
            .saturating_add(self.per_frame.saturating_mul(3 * size_of::<u32>()))
            .saturating_add(self.twist_lanes.saturating_mul(size_of::<Real>()))
    }
}

/// What [`group_frames`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grouping {
    /// Groups written to the front of the `groups` slice.
    pub count: usize,
    /// The distance at which the KDE splits near from far pairs, metres (`None`: no
    /// valley, every moving pair counted as near).
    pub split_m: Option<Real>,
    /// Groups added by splitting groups that two rigid motions explain
    /// ([`crate::split`]); `0` from [`group_frames`] alone.
    pub mixed_splits: usize,
}

/// GroupBFIFs: assigns each frame a group id (`< count`) or [`NO_GROUP`].
///
/// `labels[i]` is the accumulated-mask label of frame `i`. Writes `frame_group[..n]` and
/// `groups[..count]`.
///
/// # Errors
/// [`Error::SizeMismatch`] if `labels.len() != twists.len()`; [`Error::BufferTooSmall`] if
/// `frame_group`, `groups` or a scratch slice is shorter than [`GroupScratchLen`] says
/// (nothing is written then); [`Error::TooManyLabels`] if more than `u16::MAX - 1` groups
/// form; [`Error::BadConfig`] if `cfg` fails [`Config::check`].
pub fn group_frames(
    twists: &[Twist],
    labels: &[u16],
    cfg: &Config,
    scratch: &mut GroupScratch<'_>,
    frame_group: &mut [u16],
    groups: &mut [GroupInfo],
) -> Result<Grouping, Error> {
    cfg.check()?;
    let n = twists.len();
    if labels.len() != n {
        return Err(Error::SizeMismatch);
    }
    let need = GroupScratchLen::for_frames(n);
    check_len(Buffer::PairDist, need.pair_bin, scratch.pair_bin.len())?;
    check_len(Buffer::FrameScratch, n, scratch.parent.len())?;
    check_len(Buffer::FrameScratch, n, scratch.links.len())?;
    check_len(Buffer::FrameScratch, n, scratch.attach.len())?;
    check_len(
        Buffer::FrameScratch,
        need.twist_lanes,
        scratch.twist_lanes.len(),
    )?;
    check_len(Buffer::Frames, n, frame_group.len())?;
    check_len(Buffer::Groups, n, groups.len())?;
    let pair_bin = &mut scratch.pair_bin[..need.pair_bin];
    let parent = &mut scratch.parent[..n];
    let links = &mut scratch.links[..n];
    let attach = &mut scratch.attach[..n];

    let scale = cfg.length_scale_m;
    let floor2 = cfg.static_below_m * cfg.static_below_m;
    let moving = |t: &Twist| t.norm_squared(scale) >= floor2;

    // Pass 1: bins and histograms (index 0: inside one segment, 1: across). Until pass
    // 2, `attach` holds the labels and `links` each frame's code flags across segments
    // ([`across_flags`]).
    for (((flags, label_slot), t), &label) in links
        .iter_mut()
        .zip(attach.iter_mut())
        .zip(twists)
        .zip(labels)
    {
        *flags = across_flags(moving(t));
        *label_slot = u32::from(label);
    }
    let bin_width = cfg.kde_range_m / KDE_BINS as Real;
    let bins_per_m = 1.0 / bin_width;
    let lanes = fill_lanes(twists, &mut scratch.twist_lanes[..need.twist_lanes]);
    pass_one(&lanes, (attach, links), (scale, bins_per_m), pair_bin);
    // Histograms (index 0: inside one segment, 1: across), counted per code first.
    let per_code = count_codes(pair_bin);
    let mut hist = [[0u32; KDE_BINS]; 2];
    let [inside, across] = &mut hist;
    for (b, (inside, across)) in inside.iter_mut().zip(across.iter_mut()).enumerate() {
        *inside = per_code.get(b).copied().unwrap_or(0);
        *across = per_code.get(b | usize::from(ACROSS)).copied().unwrap_or(0);
    }

    let (posterior, split) = posterior_table(&hist, cfg);
    // Frames link inside one segment only; across pairs inform the KDE and priors. A
    // frame attaches only within a few bandwidths: a frame whose twist flow noise put
    // between two bodies' twists links to both, and the whole sparser body would chain
    // through it into the denser one if its mode could point that far. Both decisions
    // are per pair code, so they are tabled once.
    let attach_bins = (ATTACH_BANDWIDTHS * cfg.kde_bandwidth_m * bins_per_m) as u8;
    let (links_at, attaches_at) = link_tables(&posterior, cfg.link_posterior, attach_bins);

    // Pass 2: density of each frame = its number of links. The posterior usually falls
    // with the distance, so that the linking codes are the ones below a bound: then the
    // table look-up is one compare, which vectorises.
    let density = links;
    density.fill(0);
    match codes_below(&links_at) {
        Some(bound) => links_below(n, pair_bin, bound, density, SIXTEEN_PAIR_CODES),
        None => {
            for (i, row) in pair_rows(n, pair_bin) {
                let Some(later) = density.get_mut(i + 1..) else {
                    break;
                };
                let mut own = 0u32;
                for (&code, d) in row.iter().zip(later) {
                    let link = u32::from(links_at[usize::from(code)]);
                    own += link;
                    *d += link;
                }
                if let Some(d) = density.get_mut(i) {
                    *d += own;
                }
            }
        }
    }
    // Pass 3 (quick shift): each frame points at its nearest linked frame of higher
    // density; ties in distance go to the denser frame. Only a mode has no such frame.
    // `parent` is free until the union below: it holds the key of each frame's current
    // attachment.
    attach_up(n, pair_bin, density, &attaches_at, attach, parent);
    for (i, p) in parent.iter_mut().enumerate() {
        *p = i as u32;
    }
    for i in 0..n {
        if let Some(&up) = attach.get(i)
            && up != NONE
        {
            union(parent, i, up as usize);
        }
    }
    for (i, root) in attach.iter_mut().enumerate() {
        *root = find(parent, i) as u32;
    }
    let count = finish_groups(twists, labels, cfg, attach, density, frame_group, groups)?;
    let split_m = split.map(|b| b as Real * bin_width);
    // With no valley every pair is near: the groups of a segment are one motion.
    let count = merge_close_groups(
        labels,
        cfg,
        split_m.unwrap_or(Real::INFINITY),
        (parent, density),
        frame_group,
        groups.get_mut(..count).unwrap_or(&mut []),
    );
    Ok(Grouping {
        count,
        split_m,
        mixed_splits: 0,
    })
}

/// Merges groups of one segment whose twists are closer than `resolution_m` (the KDE
/// valley): motions the data cannot tell apart are one motion. Such near-twins come from
/// frames whose points touch a neighbouring body's depth; left apart they would compete
/// for the same pixels. Returns the new group count; ids stay dense, in order of the
/// first old group of each merged set.
fn merge_close_groups(
    labels: &[u16],
    cfg: &Config,
    resolution_m: Real,
    (parent, new_id): (&mut [u32], &mut [u32]),
    frame_group: &mut [u16],
    groups: &mut [GroupInfo],
) -> usize {
    let count = groups.len().min(parent.len()).min(new_id.len());
    for (g, p) in parent.iter_mut().take(count).enumerate() {
        *p = g as u32;
    }
    // 1. Moving groups of one segment closer than the resolution unite: one body whose
    //    twists flow noise spread (a rolling ball) stays one group.
    let close = |a: &GroupInfo, b: &GroupInfo| {
        a.label == b.label && a.twist.distance(&b.twist, cfg.length_scale_m) <= resolution_m
    };
    for (g, a) in groups.iter().enumerate().take(count) {
        for (h, b) in groups.iter().enumerate().take(count).skip(g + 1) {
            if a.moving && b.moving && close(a, b) {
                union(parent, g, h);
            }
        }
    }
    // 2. Each set then joins its nearest larger set of the segment within the resolution,
    //    compared by the twist of its largest group (a tree, like quick shift): a union of
    //    every close pair would let a small static group next to a moving one chain a
    //    moving body into the still rest of its segment.
    let set_of = |parent: &mut [u32], g: usize| {
        let root = find(parent, g);
        let mut frames = 0u32;
        let mut largest = g;
        for (h, b) in groups.iter().enumerate().take(count) {
            if find(parent, h) == root {
                frames = frames.saturating_add(b.frames);
                if groups.get(largest).is_none_or(|l| b.frames > l.frames) {
                    largest = h;
                }
            }
        }
        (root, frames, largest)
    };
    for g in 0..count {
        let (root, frames, largest) = set_of(parent, g);
        if root != g {
            continue;
        }
        let Some(a) = groups.get(largest).copied() else {
            continue;
        };
        let mut nearest: Option<(Real, usize)> = None;
        for h in 0..count {
            let (other, other_frames, other_largest) = set_of(parent, h);
            let Some(b) = groups.get(other_largest) else {
                continue;
            };
            if other != h
                || other == root
                || (other_frames, u32::MAX - other as u32) <= (frames, u32::MAX - root as u32)
                || !close(&a, b)
            {
                continue;
            }
            let d = a.twist.distance(&b.twist, cfg.length_scale_m);
            if nearest.is_none_or(|(best, _)| d < best) {
                nearest = Some((d, other));
            }
        }
        if let Some((_, other)) = nearest {
            union(parent, root, other);
        }
    }
    let mut next = 0u32;
    for g in 0..count {
        let root = find(parent, g);
        let id = if root == g {
            next += 1;
            next - 1
        } else {
            new_id.get(root).copied().unwrap_or(NONE)
        };
        if let Some(slot) = new_id.get_mut(g) {
            *slot = id;
        }
    }
    for fg in frame_group.iter_mut().filter(|g| **g != NO_GROUP) {
        *fg = new_id
            .get(usize::from(*fg))
            .map_or(NO_GROUP, |&id| id as u16);
    }
    // Compact in place (a new id is never above the old one, and roots come before
    // their parts); each merged group keeps the twist of its largest part.
    let merged = next as usize;
    for g in 0..count {
        let id = new_id.get(g).copied().unwrap_or(NONE) as usize;
        let is_root = parent.get(g).is_some_and(|&p| p as usize == g);
        let Some(&part) = groups.get(g) else { continue };
        let Some(slot) = groups.get_mut(id) else {
            continue;
        };
        if is_root {
            *slot = part;
        } else if part.frames > slot.frames {
            set_twist(slot, part.twist, cfg);
            slot.frames = part.frames;
        }
    }
    count_members(
        labels,
        frame_group,
        groups.get_mut(..merged).unwrap_or(&mut []),
    );
    merged
}

/// Recomputes frame counts and labels of `groups` from the frames' group ids.
fn count_members(labels: &[u16], frame_group: &[u16], groups: &mut [GroupInfo]) {
    for g in groups.iter_mut() {
        g.frames = 0;
    }
    for (&fg, &label) in frame_group.iter().zip(labels) {
        if let Some(g) = groups.get_mut(usize::from(fg)) {
            g.frames += 1;
            g.label = label;
        }
    }
}

/// Sets a group's twist and whether it is above the noise floor.
fn set_twist(g: &mut GroupInfo, twist: Twist, cfg: &Config) {
    g.twist = twist;
    g.moving = twist.norm_squared(cfg.length_scale_m) >= cfg.static_below_m * cfg.static_below_m;
}

const NONE: u32 = u32::MAX;

/// Components of a twist: `w.x, w.y, w.z, v.x, v.y, v.z`.
const TWIST_LANES: usize = 6;
// The pipeline lends the lanes to `split_mixed_groups` as its `misses` scratch.
const _: () = assert!(crate::split::MISS_SCRATCH_PER_FRAME <= TWIST_LANES);

/// Writes the components of `twists` into `lanes` component by component
/// ([`GroupScratch::twist_lanes`]; `6·twists.len()` entries) and returns the six lanes.
fn fill_lanes<'a>(twists: &[Twist], lanes: &'a mut [Real]) -> [&'a [Real]; TWIST_LANES] {
    let n = twists.len();
    for (c, lane) in lanes.chunks_exact_mut(n.max(1)).enumerate() {
        for (x, t) in lane.iter_mut().zip(twists) {
            *x = if c < 3 { t.w[c % 3] } else { t.v[c % 3] };
        }
    }
    let lanes: &'a [Real] = lanes;
    core::array::from_fn(|c| lanes.get(c * n..(c + 1) * n).unwrap_or(&[]))
}

/// Whether [`pair_codes`] codes sixteen pairs at a time, and pass 2 takes rows
/// [`LINK_ROWS`] at a time ([`links_below`]): only where `wide` has vector lanes to pack
/// the codes with.
const SIXTEEN_PAIR_CODES: bool = cfg!(vector_lanes);

/// A frame's flags for [`code_of_bin`]: what its pairs across segments with a moving
/// frame add to their bin ([`ACROSS`] if it moves, or all bits: [`NO_PAIR`]).
fn across_flags(moving: bool) -> u32 {
    u32::from(if moving { ACROSS } else { NO_PAIR })
}

/// The flags a row's frame adds to the [`across_flags`] of its partners: none if it
/// moves, all bits otherwise (a static frame's pairs across segments are never data).
fn own_flags(moving_flags: u32) -> u32 {
    if moving_flags == u32::from(ACROSS) {
        0
    } else {
        u32::from(NO_PAIR)
    }
}

/// The pair code of a pair at twist distance `d` (metres): its KDE bin, flagged
/// [`ACROSS`] for a pair across segments, or [`NO_PAIR`] ([`code_of_bin`]).
#[inline]
fn pair_code(d: Real, bins_per_m: Real, across: bool, flags: u32) -> u8 {
    // NaN fails the comparison and lands in the last bin.
    let b = d * bins_per_m;
    let b = if b < KDE_BINS as Real {
        b as u8
    } else {
        KDE_BINS as u8 - 1
    };
    code_of_bin(u32::from(b), across, flags) as u8
}

/// [`pair_code`] from the pair's bin. `flags` is the partner's [`across_flags`] or'ed
/// with the row frame's [`own_flags`]: [`ACROSS`] when both move, [`NO_PAIR`]'s bits
/// otherwise, which cover every bin. Across segments only pairs of moving frames are
/// data.
#[inline]
fn code_of_bin(bin: u32, across: bool, flags: u32) -> u32 {
    bin | if across { flags } else { 0 }
}

/// The bins [`pair_code`] takes from four `d · bins_per_m`, bit for bit: truncated below
/// [`KDE_BINS`], the last bin otherwise (NaN too).
#[inline]
fn four_bins(b: f32x4) -> i32x4 {
    let last = f32x4::splat((KDE_BINS - 1) as Real);
    // Every lane is then a whole number in `[0, KDE_BINS)` or a value in it to truncate
    // (or `-0`, which truncates to 0), so the conversion is exact and never saturates.
    // On SSE the minimum with the last bin is one instruction (`minps`, which gives its
    // second operand when the first is NaN) and truncates alike: values in
    // `[KDE_BINS − 1, KDE_BINS)` truncate to the last bin either way. Elsewhere
    // `fast_min` may keep a NaN, so the compare and select stay.
    let b = if cfg!(target_feature = "sse") {
        b.fast_min(last)
    } else {
        b.simd_lt(f32x4::splat(KDE_BINS as Real)).select(b, last)
    };
    b.fast_trunc_int()
}

/// The squared distances [`Twist::distance`] takes the root of, from one twist (`ti`,
/// its components splat) to four (`tj`, component by component): the same operations in
/// the same order, `v.norm_squared() + L·L·w.norm_squared()` with nalgebra's
/// `(x² + y²) + z²`, one lane per pair. The differences are taken `tj − ti`, which is
/// `−(ti − tj)` exactly (rounding is symmetric), so the squares are the same; it spares
/// copying the splat `ti` before each subtraction.
#[inline]
fn four_distances_squared(
    ti: &[f32x4; TWIST_LANES],
    tj: [&[Real; 4]; TWIST_LANES],
    scale2: f32x4,
) -> [Real; 4] {
    let [tw0, tw1, tw2, tv0, tv1, tv2] = *ti;
    let [w0, w1, w2, v0, v1, v2] = tj;
    let d = [
        f32x4::new(*w0) - tw0,
        f32x4::new(*w1) - tw1,
        f32x4::new(*w2) - tw2,
        f32x4::new(*v0) - tv0,
        f32x4::new(*v1) - tv1,
        f32x4::new(*v2) - tv2,
    ];
    let w2 = (d[0] * d[0] + d[1] * d[1]) + d[2] * d[2];
    let v2 = (d[3] * d[3] + d[4] * d[4]) + d[5] * d[5];
    (v2 + scale2 * w2).to_array()
}

/// Pass 1: writes the codes of all pairs into `pair_bin`, row by row ([`pair_codes`]).
/// `labels` are the frames' labels and `flags` their [`across_flags`]. A row whose pairs
/// are all inside one segment (its frame's run of equal labels reaches the last frame, as
/// every row does when the frames lie in one segment) is coded without looking at labels
/// or flags.
fn pass_one(
    lanes: &[&[Real]; TWIST_LANES],
    (labels, flags): (&[u32], &[u32]),
    scales: (Real, Real),
    pair_bin: &mut [u8],
) {
    let n = labels.len();
    let mut run_end = 0;
    for (i, row) in pair_rows_mut(n, pair_bin) {
        if run_end <= i {
            let later = labels.get(i + 1..).unwrap_or(&[]);
            let label = labels.get(i);
            run_end = i + 1 + later.iter().take_while(|&l| Some(l) == label).count();
        }
        if run_end >= n {
            pair_codes::<true>(lanes, i, (labels, flags), scales, row);
        } else {
            pair_codes::<false>(lanes, i, (labels, flags), scales, row);
        }
    }
}

/// Pass 1 for frame `i`: writes the codes of its pairs with frames `i + 1..` into `row`
/// (`n − i − 1` entries), sixteen frames at a time, then four, then one. Bit for bit what
/// [`Twist::distance`] gives pair by pair: the same operations in the same order, one
/// lane per pair. `labels` are the frames' labels and `flags` their [`across_flags`];
/// `INSIDE`: every partner has frame `i`'s label, so the codes are the bins alone.
// Where sixteen pairs are coded at a time, each kind of row is a function of its own:
// inlined side by side, the inside rows' loop reloaded the splat twist from the stack
// every sixteen pairs. Without vector lanes (Cortex-M) the inlined pair costs less.
#[cfg_attr(vector_lanes, inline(never))]
fn pair_codes<'a, const INSIDE: bool>(
    lanes: &[&[Real]; TWIST_LANES],
    i: usize,
    (labels, flags): (&'a [u32], &'a [u32]),
    (scale, bins_per_m): (Real, Real),
    row: &mut [u8],
) {
    let at = |c: usize| lanes.get(c).and_then(|l| l.get(i)).copied().unwrap_or(0.0);
    let ti: [Real; TWIST_LANES] = core::array::from_fn(at);
    let li = labels.get(i).copied().unwrap_or(0);
    let own = own_flags(flags.get(i).copied().unwrap_or(0));
    let from = i + 1;
    let scale2 = scale * scale;
    let row_frame = RowFrame {
        twist: ti.map(f32x4::splat),
        scale2: f32x4::splat(scale2),
        bins_per_m: f32x4::splat(bins_per_m),
        // Labels and flags fit `i32`: a `u16` and a byte.
        label: i32x4::splat(li as i32),
        flags: i32x4::splat(own as i32),
    };
    let tail = |l: usize| lanes.get(l).and_then(|x| x.get(from..)).unwrap_or(&[]);
    let labels = labels.get(from..).unwrap_or(&[]);
    let flags = flags.get(from..).unwrap_or(&[]);
    // Sixteen frames at a time: each lane, the labels and the flags in chunks of 16.
    // Without vector lanes (Cortex-M: `wide`'s narrowings are scalar) the four-pair path
    // costs less, so there every pair goes through it.
    let (row16, rest16) = if SIXTEEN_PAIR_CODES {
        row.as_chunks_mut::<16>()
    } else {
        (Default::default(), row)
    };
    let done16 = row16.len() * 16;
    let sixteens: [&[[Real; 16]]; TWIST_LANES] =
        core::array::from_fn(|l| tail(l).as_chunks::<16>().0);
    let [w0, w1, w2, v0, v1, v2] = sixteens;
    let tj16 = w0.iter().zip(w1).zip(w2).zip(v0).zip(v1).zip(v2);
    let meta16 = labels
        .as_chunks::<16>()
        .0
        .iter()
        .zip(flags.as_chunks::<16>().0);
    for ((out, (lj, fj)), tj) in row16.iter_mut().zip(meta16).zip(tj16) {
        let (((((w0, w1), w2), v0), v1), v2) = tj;
        let (Some(w0), Some(w1), Some(w2), Some(v0), Some(v1), Some(v2), Some(lj), Some(fj)) = (
            quarters(w0),
            quarters(w1),
            quarters(w2),
            quarters(v0),
            quarters(v1),
            quarters(v2),
            quarters(lj),
            quarters(fj),
        ) else {
            return;
        };
        let quarter = |k: usize| {
            let tj = [&w0[k], &w1[k], &w2[k], &v0[k], &v1[k], &v2[k]];
            if INSIDE {
                row_frame.four_bins(tj)
            } else {
                row_frame.four_codes(tj, &lj[k], &fj[k])
            }
        };
        // Codes are bytes, so the saturating narrowings are exact.
        let pack = |a: i32x4, b: i32x4| {
            let (a, b) = (a.to_array(), b.to_array());
            i16x8::from_i32x8_saturate(i32x8::new(core::array::from_fn(|k| {
                if k < 4 { a[k] } else { b[k - 4] }
            })))
        };
        *out = u8x16::narrow_i16x8(pack(quarter(0), quarter(1)), pack(quarter(2), quarter(3)))
            .to_array();
    }
    // Then four at a time.
    let (row4, rest) = rest16.as_chunks_mut::<4>();
    let fours: [&[[Real; 4]]; TWIST_LANES] =
        core::array::from_fn(|l| tail(l).get(done16..).unwrap_or(&[]).as_chunks::<4>().0);
    let [w0, w1, w2, v0, v1, v2] = fours;
    let tj4 = w0.iter().zip(w1).zip(w2).zip(v0).zip(v1).zip(v2);
    let after16 = |x: &'a [u32]| x.get(done16..).unwrap_or(&[]).as_chunks::<4>().0;
    let meta4 = after16(labels).iter().zip(after16(flags));
    for ((out, (lj, fj)), tj) in row4.iter_mut().zip(meta4).zip(tj4) {
        let (((((w0, w1), w2), v0), v1), v2) = tj;
        let tj = [w0, w1, w2, v0, v1, v2];
        let codes = if INSIDE {
            row_frame.four_bins(tj)
        } else {
            row_frame.four_codes(tj, lj, fj)
        };
        *out = codes.to_array().map(|c| c as u8);
    }
    let done = done16 + row4.len() * 4;
    for (k, slot) in rest.iter_mut().enumerate() {
        let j = from + done + k;
        let tj: [Real; TWIST_LANES] =
            core::array::from_fn(|l| lanes.get(l).and_then(|x| x.get(j)).copied().unwrap_or(0.0));
        let d: [Real; TWIST_LANES] = core::array::from_fn(|l| ti[l] - tj[l]);
        let w2 = (d[0] * d[0] + d[1] * d[1]) + d[2] * d[2];
        let v2 = (d[3] * d[3] + d[4] * d[4]) + d[5] * d[5];
        let (lj, fj) = (
            labels.get(done + k).copied().unwrap_or(0),
            flags.get(done + k).copied().unwrap_or(0),
        );
        let across = !INSIDE && li != lj;
        *slot = pair_code(sqrt(v2 + scale2 * w2), bins_per_m, across, fj | own);
    }
}

/// Sixteen values as four fours (never `None`).
#[inline]
fn quarters<T>(x: &[T; 16]) -> Option<&[[T; 4]; 4]> {
    x.as_chunks::<4>().0.first_chunk::<4>()
}

/// The frame of a pass-1 row, splat for [`RowFrame::four_codes`].
struct RowFrame {
    twist: [f32x4; TWIST_LANES],
    scale2: f32x4,
    bins_per_m: f32x4,
    label: i32x4,
    /// Its [`own_flags`].
    flags: i32x4,
}

impl RowFrame {
    /// The codes of its pairs with four frames (twists component by component, labels,
    /// [`across_flags`]): [`code_of_bin`] of [`four_bins`], one lane per pair.
    #[inline]
    fn four_codes(
        &self,
        tj: [&[Real; 4]; TWIST_LANES],
        labels: &[u32; 4],
        flags: &[u32; 4],
    ) -> i32x4 {
        let lanes_of = |x: &[u32; 4]| i32x4::new(x.map(|x| x as i32));
        let inside = lanes_of(labels).simd_eq(self.label);
        self.four_bins(tj) | (!inside & (lanes_of(flags) | self.flags))
    }

    /// The bins of its pairs with four frames ([`four_bins`]): their codes when the
    /// frames have its label.
    #[inline]
    fn four_bins(&self, tj: [&[Real; 4]; TWIST_LANES]) -> i32x4 {
        let norm2 = four_distances_squared(&self.twist, tj, self.scale2);
        four_bins(sqrt4(f32x4::new(norm2)) * self.bins_per_m)
    }
}

/// How many times each code occurs in `codes`. Four tables, one for each byte of a
/// group of four, so that runs of one code (common: most pairs of a body share a bin)
/// do not wait on their own last count; the sums are the same. Eight codes a round
/// spare half the loop's own instructions.
fn count_codes(codes: &[u8]) -> [u32; 256] {
    let mut tables = [[0u32; 256]; 4];
    let (eights, rest) = codes.as_chunks::<8>();
    for eight in eights {
        for four in eight.as_chunks::<4>().0 {
            for (table, &code) in tables.iter_mut().zip(four) {
                table[usize::from(code)] += 1;
            }
        }
    }
    for &code in rest {
        tables[0][usize::from(code)] += 1;
    }
    let [a, b, c, d] = &tables;
    core::array::from_fn(|k| a[k] + b[k] + c[k] + d[k])
}

fn bump(counts: &mut [u32], i: usize) {
    if let Some(c) = counts.get_mut(i) {
        *c = c.saturating_add(1);
    }
}

/// The stored codes of the pairs `(i, j > i)` for each frame `i`, in pass 1's order.
fn pair_rows(n: usize, pair_bin: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    (0..n).scan(0, move |start, i| {
        let len = n - i - 1;
        let row = pair_bin.get(*start..*start + len)?;
        *start += len;
        Some((i, row))
    })
}

/// [`pair_rows`], writable.
fn pair_rows_mut(n: usize, pair_bin: &mut [u8]) -> impl Iterator<Item = (usize, &mut [u8])> {
    let mut rest = pair_bin;
    (0..n).map_while(move |i| {
        let len = n - i - 1;
        let (row, tail) = core::mem::take(&mut rest).split_at_mut_checked(len)?;
        rest = tail;
        Some((i, row))
    })
}

/// Which pair codes link (inside one segment, posterior above `link_posterior`) and
/// which of those attach (bin at most `attach_bins`), tabled by code. The codes past
/// the last bin and below [`ACROSS`] never occur and never link, so that the linking
/// codes of a posterior falling with the distance are the ones below a bound
/// ([`codes_below`]), which passes 2 and 3 test with one compare.
fn link_tables(
    posterior: &[Real; KDE_BINS],
    link_posterior: Real,
    attach_bins: u8,
) -> ([bool; 256], [bool; 256]) {
    let mut links_at = [false; 256];
    let mut attaches_at = [false; 256];
    for (code, (link, attach)) in links_at.iter_mut().zip(attaches_at.iter_mut()).enumerate() {
        // Codes with ACROSS set (and NO_PAIR) are past the bins too.
        *link = posterior.get(code).is_some_and(|&p| p > link_posterior);
        *attach = *link && code <= usize::from(attach_bins);
    }
    (links_at, attaches_at)
}

/// `bound` if `table` holds exactly for the codes below it, `None` if it is not of
/// that form.
fn codes_below(table: &[bool; 256]) -> Option<u8> {
    let bound = table.iter().take_while(|&&t| t).count();
    let rest = table.get(bound..).unwrap_or(&[]);
    (rest.iter().all(|&t| !t)).then_some(u8::try_from(bound).ok()?)
}

/// Rows that [`links_below`] takes at a time where there are vector lanes.
const LINK_ROWS: usize = 8;

/// Pass 2 when the linking codes are those below `bound`: adds each frame's number of
/// links to its entry of `density` (`n` entries). With `blocks` (where there are vector
/// lanes) rows go [`LINK_ROWS`] at a time ([`link_rows_below`]); the last rows, and every
/// row without, one at a time ([`add_links_below`]).
fn links_below(n: usize, pair_bin: &[u8], bound: u8, density: &mut [u32], blocks: bool) {
    // Fused: a block is pulled whole, also past the last row, which must stay `None`.
    let mut rows = pair_rows(n, pair_bin).fuse();
    loop {
        let block: [Option<(usize, &[u8])>; LINK_ROWS] = core::array::from_fn(|_| rows.next());
        let full = matches!(block, [.., Some(_)]);
        if blocks && let [Some((first, _)), .., Some(_)] = block {
            link_rows_below(
                first,
                block.map(|r| r.map_or(&[][..], |r| r.1)),
                bound,
                density,
            );
            continue;
        }
        for &(i, row) in block.iter().flatten() {
            let Some(later) = density.get_mut(i + 1..) else {
                break;
            };
            let own = add_links_below(row, later, bound);
            if let Some(d) = density.get_mut(i) {
                *d += own;
            }
        }
        if !full {
            return;
        }
    }
}

/// [`links_below`] for the rows of frames `first..first + LINK_ROWS` (`rows`, each
/// running to the last frame). Their pairs with each sixteen later frames are compared at
/// once, row by row, and the pairs that do not link counted in bytes: the later frames'
/// counts (at most [`LINK_ROWS`]) are widened once per sixteen, and each row's own are
/// kept sixteen lanes wide and emptied every 255 rounds, before a byte could carry. The
/// pairs among the block's frames and the rows' last few pairs go one at a time
/// ([`add_links_below`]).
fn link_rows_below(first: usize, rows: [&[u8]; LINK_ROWS], bound: u8, density: &mut [u32]) {
    // Pairs among the block's frames: the first `LINK_ROWS - 1 - r` of row `r`.
    let mut own = [0u32; LINK_ROWS];
    for (r, (row, own)) in rows.iter().zip(own.iter_mut()).enumerate() {
        let codes = row.get(..LINK_ROWS - 1 - r).unwrap_or(row);
        *own += add_links_below(
            codes,
            density.get_mut(first + r + 1..).unwrap_or(&mut []),
            bound,
        );
    }
    // Pairs with the frames from `first + LINK_ROWS` on, sixteen at a time.
    let bodies: [&[u8]; LINK_ROWS] = core::array::from_fn(|r| {
        rows.get(r)
            .and_then(|row| row.get(LINK_ROWS - 1 - r..))
            .unwrap_or(&[])
    });
    let chunks = bodies.iter().map(|b| b.len() / 16).min().unwrap_or(0);
    let later = density.get_mut(first + LINK_ROWS..).unwrap_or(&mut []);
    let (later16, rest) = later.split_at_mut((chunks * 16).min(later.len()));
    let [b0, b1, b2, b3, b4, b5, b6, b7] = bodies.map(|b| b.as_chunks::<16>().0);
    let sixteens = (b0.iter().zip(b1).zip(b2).zip(b3)).zip(b4.iter().zip(b5).zip(b6).zip(b7));
    let bound16 = u8x16::splat(bound);
    // The pairs that do not link are counted (a compare gives all ones for them, so
    // subtracting it adds one), which spares inverting each compare: the links are the
    // pairs less those. `own16` holds each row's since it was last emptied, `rounds` ago.
    let mut own16 = [u8x16::ZERO; LINK_ROWS];
    let empty = |own16: &mut [u8x16; LINK_ROWS], own: &mut [u32; LINK_ROWS], rounds: u32| {
        for (o, bytes) in own.iter_mut().zip(own16.iter_mut()) {
            let unlinked: u32 = bytes.to_array().iter().map(|&b| u32::from(b)).sum();
            *o += 16 * rounds - unlinked;
            *bytes = u8x16::ZERO;
        }
    };
    let mut rounds = 0;
    let block_rows = u8x16::splat(LINK_ROWS as u8);
    for (d, ((((r0, r1), r2), r3), (((r4, r5), r6), r7))) in
        later16.as_chunks_mut::<16>().0.iter_mut().zip(sixteens)
    {
        let mut unlinked = u8x16::ZERO;
        for (codes, own16) in [r0, r1, r2, r3, r4, r5, r6, r7]
            .iter()
            .zip(own16.iter_mut())
        {
            let codes = u8x16::new(**codes);
            let unlink = codes.max(bound16).simd_eq(codes);
            unlinked -= unlink;
            *own16 -= unlink;
        }
        for (d, &links) in d.iter_mut().zip(&(block_rows - unlinked).to_array()) {
            *d += u32::from(links);
        }
        rounds += 1;
        if rounds == 255 {
            empty(&mut own16, &mut own, rounds);
            rounds = 0;
        }
    }
    empty(&mut own16, &mut own, rounds);
    for (body, own) in bodies.iter().zip(own.iter_mut()) {
        *own += add_links_below(body.get(chunks * 16..).unwrap_or(&[]), &mut *rest, bound);
    }
    for (d, o) in density.iter_mut().skip(first).zip(own) {
        *d += o;
    }
}

/// Pass 2 for one row when the linking codes are those below `bound`: adds each pair's
/// link to the later frame's density (`later`, as long as `row`) and returns the row's
/// own link count. With vector lanes sixteen codes are compared at once (a compare per
/// four codes costs more than the widening of the links).
fn add_links_below(row: &[u8], later: &mut [u32], bound: u8) -> u32 {
    let (row16, rest) = if SIXTEEN_PAIR_CODES {
        row.as_chunks::<16>()
    } else {
        (Default::default(), row)
    };
    let (later16, later) = later.split_at_mut(later.len().min(row16.len() * 16));
    let (bound16, one) = (u8x16::splat(bound), u8x16::splat(1));
    let mut own = 0u32;
    for (codes, d) in row16.iter().zip(later16.as_chunks_mut::<16>().0) {
        let links = (u8x16::new(*codes).simd_lt(bound16) & one).to_array();
        // The two halves' bytes added (each at most 2), then all eight summed into the
        // top byte by one multiplication: at most sixteen, so no byte carries.
        let halves = links.as_chunks::<8>().0.iter();
        let pairs = halves.fold(0u64, |sum, half| sum + u64::from_le_bytes(*half));
        own += (pairs.wrapping_mul(0x0101_0101_0101_0101) >> 56) as u32;
        for (d, &link) in d.iter_mut().zip(&links) {
            *d += u32::from(link);
        }
    }
    for (&code, d) in rest.iter().zip(later) {
        let link = u32::from(code < bound);
        own += link;
        *d += link;
    }
    own
}

/// Densities at or above this share one attachment key in [`attach_up`] (ties between
/// them then go to the lower index). Reaching it takes `2^24` frames, whose pair codes
/// alone would take `2^47` bytes.
const KEY_DENSITY_MAX: u32 = (1 << 24) - 1;

/// Pass 3 (quick shift): writes into `attach[i]` the frame that frame `i` points at, or
/// [`NONE`] for a mode. Among the pairs whose code `attaches_at`, a frame points at the
/// partner of higher rank `(density, −index)` that is nearest (the code, a bin: codes with
/// [`ACROSS`] never attach, as [`link_tables`] makes them), ties going to the higher rank.
/// `keys` (`n` entries) is scratch, and `density` is overwritten.
///
/// Ranks are unique, so the result does not depend on the order the pairs are visited
/// in. They are visited row by row, each row in order: then the frame already chosen
/// (the incumbent) always has a lower index than the newcomer, and the newcomer ranks
/// higher exactly when it is denser. So one `u32` key decides, the nearness in the top
/// byte above the inverted density (up to [`KEY_DENSITY_MAX`]): smaller is better. The
/// densities are inverted once, in place; each frame's key is kept next to its choice,
/// and frame `i`'s own along its row in registers.
fn attach_up(
    n: usize,
    pair_bin: &[u8],
    density: &mut [u32],
    attaches_at: &[bool; 256],
    attach: &mut [u32],
    keys: &mut [u32],
) {
    // Sparseness: the density inverted, so that the denser frame has the smaller key.
    for d in density.iter_mut() {
        *d = KEY_DENSITY_MAX - (*d).min(KEY_DENSITY_MAX);
    }
    let sparseness = &*density;
    // Codes that attach are below `ACROSS`, so every key is below `u32::MAX`: "no
    // attachment yet".
    let key = |code: u8, sparse: u32| (u32::from(code) << 24) | sparse;
    attach.fill(NONE);
    keys.fill(u32::MAX);
    let bound = codes_below(attaches_at);
    for (i, row) in pair_rows(n, pair_bin) {
        let (Some(&own_sparse), Some(later_sparse)) = (sparseness.get(i), sparseness.get(i + 1..))
        else {
            break;
        };
        let (Some((own_up, later_up)), Some((own_key, later_keys))) = (
            attach.get_mut(i..).and_then(|s| s.split_first_mut()),
            keys.get_mut(i..).and_then(|s| s.split_first_mut()),
        ) else {
            break;
        };
        let mut best = (*own_up, *own_key);
        // The pair of frame `i` with frame `i + 1 + k`, which has sparseness `later` and
        // the choice `(up, up_key)`.
        let mut offer = |k: usize, code: u8, later: u32, up: &mut u32, up_key: &mut u32| {
            if own_sparse > later {
                // Frame `i` ranks lower: the later frame is a candidate for it.
                let new = key(code, later);
                if new < best.1 {
                    best = ((i + 1 + k) as u32, new);
                }
            } else {
                let new = key(code, own_sparse);
                if new < *up_key {
                    *up = i as u32;
                    *up_key = new;
                }
            }
        };
        // With a bound, sixteen codes are compared at once and only the ones below it are
        // visited (a branch per code would be a coin flip); the rest of the row, or all
        // of it without a bound, code by code.
        let chunked = if bound.is_some() {
            row.len() / 16 * 16
        } else {
            0
        };
        let (
            Some((codes, codes_rest)),
            Some((dens, dens_rest)),
            Some((ups, ups_rest)),
            Some((ks, ks_rest)),
        ) = (
            row.split_at_checked(chunked),
            later_sparse.split_at_checked(chunked),
            later_up.split_at_mut_checked(chunked),
            later_keys.split_at_mut_checked(chunked),
        )
        else {
            break;
        };
        let bound16 = u8x16::splat(bound.unwrap_or(0));
        let sixteens = (codes
            .as_chunks::<16>()
            .0
            .iter()
            .zip(dens.as_chunks::<16>().0))
        .zip(ups.as_chunks_mut::<16>().0.iter_mut())
        .zip(ks.as_chunks_mut::<16>().0.iter_mut());
        for (c, (((codes, dens), ups), ks)) in sixteens.enumerate() {
            let mut below = u8x16::new(*codes).simd_lt(bound16).to_bitmask();
            while below != 0 {
                // Below 16: the mask has sixteen bits.
                let k = below.trailing_zeros() as usize & 15;
                below &= below - 1;
                offer(c * 16 + k, codes[k], dens[k], &mut ups[k], &mut ks[k]);
            }
        }
        let rest = codes_rest.iter().zip(dens_rest).zip(ups_rest).zip(ks_rest);
        for (k, (((&code, &later), up), up_key)) in rest.enumerate() {
            if attaches_at[usize::from(code)] {
                offer(chunked + k, code, later, up, up_key);
            }
        }
        (*own_up, *own_key) = best;
    }
}

/// Dense group ids in root order, small groups dropped, then counts and each group's
/// root twist.
fn finish_groups(
    twists: &[Twist],
    labels: &[u16],
    cfg: &Config,
    root_of: &[u32],
    scratch: &mut [u32],
    frame_group: &mut [u16],
    groups: &mut [GroupInfo],
) -> Result<usize, Error> {
    scratch.fill(0);
    for &r in root_of {
        if r != NONE {
            bump(scratch, r as usize);
        }
    }
    let mut count = 0usize;
    for slot in scratch.iter_mut() {
        if *slot >= cfg.min_group_frames.max(1) {
            if count >= usize::from(NO_GROUP) {
                return Err(Error::TooManyLabels);
            }
            *slot = count as u32;
            count += 1;
        } else {
            *slot = NONE;
        }
    }
    // A group's twist is its root's: one member's twist, which a few corrupted members
    // cannot pull away as they would pull a mean. The root is the union-find root, the
    // member with the smallest frame index (not the quick-shift mode: on exact twists the
    // two agree, under noise they can differ by a few millimetres).
    for (i, (&r, fg)) in root_of.iter().zip(frame_group.iter_mut()).enumerate() {
        let gid = if r == NONE {
            NONE
        } else {
            scratch.get(r as usize).copied().unwrap_or(NONE)
        };
        *fg = if gid == NONE { NO_GROUP } else { gid as u16 };
        if r as usize == i
            && let (Some(g), Some(&t)) = (groups.get_mut(gid as usize), twists.get(i))
        {
            set_twist(g, t, cfg);
        }
    }
    count_members(
        labels,
        frame_group,
        groups.get_mut(..count).unwrap_or(&mut []),
    );
    Ok(count)
}

/// Posterior `P(same body | bin)` for pairs inside one segment (the only pairs that link),
/// and the valley bin that splits near from far (`None`: no valley). The KDE is over all
/// data pairs, inside and across segments.
fn posterior_table(hist: &[[u32; KDE_BINS]; 2], cfg: &Config) -> ([Real; KDE_BINS], Option<usize>) {
    let sigma_bins = cfg.kde_bandwidth_m / (cfg.kde_range_m / KDE_BINS as Real);
    let mut all = [0.0 as Real; KDE_BINS];
    for (a, (h0, h1)) in all.iter_mut().zip(hist[0].iter().zip(&hist[1])) {
        *a = (*h0 + *h1) as Real;
    }
    let density = smooth(&all, sigma_bins, 0, KDE_BINS);
    let split = first_valley(&density);
    let cut = split.unwrap_or(KDE_BINS);
    // Likelihoods: the KDE of the near pairs and of the far pairs, each normalised; the far
    // one gets a small uniform floor so that a distance no pair showed is "different".
    let near = normalised(smooth(&all, sigma_bins, 0, cut), 0.0);
    let far = normalised(smooth(&all, sigma_bins, cut, KDE_BINS), 1e-3);
    // Prior from the mask: the share of near pairs among the pairs inside one segment.
    let inside = &hist[0];
    let total: u64 = inside.iter().map(|&c| u64::from(c)).sum();
    let near_count: u64 = inside.iter().take(cut).map(|&c| u64::from(c)).sum();
    let prior = (near_count as Real + 1.0) / (total as Real + 2.0);
    let mut table = [0.0; KDE_BINS];
    for (p, (g, f)) in table.iter_mut().zip(near.iter().zip(&far)) {
        let a = prior * g;
        let b = (1.0 - prior) * f;
        *p = if a + b > 0.0 { a / (a + b) } else { 0.0 };
    }
    (table, split)
}

/// Gaussian KDE on bins `[from, to)` of a histogram (other bins count zero).
fn smooth(hist: &[Real; KDE_BINS], sigma_bins: Real, from: usize, to: usize) -> [Real; KDE_BINS] {
    let sigma = sigma_bins.max(0.5);
    // `as` saturates (an infinite sigma gives usize::MAX), so the `+ 1` must too.
    let reach = ((3.0 * sigma) as usize).saturating_add(1);
    let mut kernel = [0.0 as Real; KDE_BINS];
    for (d, k) in kernel.iter_mut().enumerate().take(reach.min(KDE_BINS)) {
        let x = d as Real / sigma;
        *k = exp(-0.5 * x * x);
    }
    // Only the bins within reach: farther ones would add `count · 0`, which leaves a
    // non-negative sum as it is.
    let mut out = [0.0; KDE_BINS];
    for (b, &count) in hist.iter().enumerate().take(to).skip(from) {
        if count == 0.0 {
            continue;
        }
        let (near, far) = (b.saturating_sub(reach - 1), b.saturating_add(reach));
        for (o, slot) in out.iter_mut().enumerate().take(far).skip(near) {
            let d = b.abs_diff(o);
            if let Some(k) = kernel.get(d) {
                *slot += count * k;
            }
        }
    }
    out
}

fn normalised(mut density: [Real; KDE_BINS], uniform_share: Real) -> [Real; KDE_BINS] {
    let total: Real = density.iter().sum();
    let u = 1.0 / KDE_BINS as Real;
    for d in &mut density {
        let p = if total > 0.0 { *d / total } else { u };
        *d = (1.0 - uniform_share) * p + uniform_share * u;
    }
    density
}

/// The first clear valley after the first peak: a bin whose density is at most 2/3 of a
/// later bin's and of the peak's. `None` when the density only falls after its first peak.
fn first_valley(density: &[Real; KDE_BINS]) -> Option<usize> {
    let peak_level = density.iter().copied().fold(0.0, Real::max);
    if peak_level <= 0.0 {
        return None;
    }
    let mut b = 0;
    while b + 1 < KDE_BINS && density.get(b + 1) >= density.get(b) {
        b += 1;
    }
    let first_peak = density.get(b).copied().unwrap_or(0.0);
    let (mut low_bin, mut low) = (b, first_peak);
    for (i, &d) in density.iter().enumerate().skip(b + 1) {
        if d < low {
            (low_bin, low) = (i, d);
        } else if d > 1.5 * low && d > 0.02 * peak_level && low < first_peak / 1.5 {
            return Some(low_bin);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use std::{vec, vec::Vec};

    use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3};

    use super::*;
    use crate::{Pose, frames::BodyFrame, rng::Pcg32};

    /// Found by the `update_mask` fuzz target: a valid config whose bandwidth is many
    /// orders above the bin width (`kde_range_m` tiny) made `reach` overflow (a panic in
    /// debug builds; in release a wrapped reach of 0 zeroed the whole density). A kernel
    /// far wider than the histogram spreads every count evenly.
    #[test]
    fn smoothing_with_a_huge_bandwidth_spreads_counts_evenly() {
        let mut hist = [0.0; KDE_BINS];
        hist[3] = 2.0;
        for sigma_bins in [1e30, Real::MAX, Real::INFINITY] {
            let out = smooth(&hist, sigma_bins, 0, KDE_BINS);
            assert!(out.iter().all(|&v| v == 2.0), "sigma {sigma_bins}: {out:?}");
        }
    }

    proptest::proptest! {
        /// The smoothing visits only the bins within the kernel's reach, and gives what
        /// adding every bin's kernel to every bin gives, bit for bit.
        #[test]
        fn smoothing_within_reach_equals_smoothing_everywhere(
            counts in proptest::collection::vec(
                proptest::prop_oneof![3 => proptest::strategy::Just(0u32), 1 => 0u32..5000],
                KDE_BINS,
            ),
            sigma_bins in proptest::prop_oneof![0.0 as Real..8.0, 8.0 as Real..200.0],
            (from, to) in (0..KDE_BINS, 0..=KDE_BINS),
        ) {
            let hist: [Real; KDE_BINS] = core::array::from_fn(|b| counts[b] as Real);
            let sigma = sigma_bins.max(0.5);
            let reach = ((3.0 * sigma) as usize).saturating_add(1);
            let mut kernel = [0.0 as Real; KDE_BINS];
            for (d, k) in kernel.iter_mut().enumerate().take(reach.min(KDE_BINS)) {
                let x = d as Real / sigma;
                *k = exp(-0.5 * x * x);
            }
            let mut everywhere = [0.0 as Real; KDE_BINS];
            for (b, &count) in hist.iter().enumerate().take(to).skip(from) {
                for (o, slot) in everywhere.iter_mut().enumerate() {
                    *slot += count * kernel[b.abs_diff(o)];
                }
            }
            let got = smooth(&hist, sigma_bins, from, to);
            proptest::prop_assert_eq!(got.map(Real::to_bits), everywhere.map(Real::to_bits));
        }
    }

    #[test]
    fn scratch_len_is_exact_or_saturates_never_wraps() {
        for n in 0..200usize {
            assert_eq!(
                GroupScratchLen::for_frames(n).pair_bin,
                n * n.saturating_sub(1) / 2
            );
        }
        // n·(n−1) alone overflows u32 here; the count itself fits a 64-bit `usize` and
        // saturates a 32-bit one.
        assert_eq!(
            GroupScratchLen::for_frames(100_000).pair_bin,
            usize::try_from(4_999_950_000_u64).unwrap_or(usize::MAX)
        );
        for n in [usize::MAX, usize::MAX - 1] {
            let len = GroupScratchLen::for_frames(n);
            assert_eq!(len.pair_bin, usize::MAX);
            assert_eq!(len.bytes(), usize::MAX);
        }
    }

    /// Roughly normal noise (Irwin-Hall with 12 uniforms), standard deviation `sigma`.
    fn noise(rng: &mut Pcg32, sigma: Real) -> Vector3<Real> {
        let mut n = || (0..12).map(|_| rng.unit()).sum::<Real>() - 6.0;
        Vector3::new(n(), n(), n()) * sigma
    }

    /// `count` frames on a body centred at `centre`, moved by `motion`, with point noise.
    fn frames_on(
        rng: &mut Pcg32,
        centre: Point3<Real>,
        motion: &Pose,
        count: usize,
        sigma_m: Real,
    ) -> Vec<BodyFrame> {
        (0..count)
            .map(|_| {
                let o = centre + Vector3::new(rng.unit() - 0.5, rng.unit() - 0.5, 0.0) * 0.05;
                let p_t = [
                    o,
                    o + Vector3::new(0.025, 0.004, 0.0),
                    o + Vector3::new(0.006, 0.022, 0.002),
                ];
                let p_t1 = p_t.map(|p| motion * p + noise(rng, sigma_m));
                let p_t = p_t.map(|p| p + noise(rng, sigma_m));
                BodyFrame {
                    p_t,
                    p_t1,
                    ..BodyFrame::EMPTY
                }
            })
            .collect()
    }

    struct Run {
        frame_group: Vec<u16>,
        groups: Vec<GroupInfo>,
    }

    fn run(frames: &[BodyFrame], labels: &[u16], origin: &Point3<Real>) -> Run {
        let n = frames.len();
        let twists: Vec<Twist> = frames.iter().map(|f| f.twist(origin).unwrap()).collect();
        let len = GroupScratchLen::for_frames(n);
        let (mut pair_bin, mut parent, mut links, mut attach) =
            (vec![0u8; len.pair_bin], vec![0; n], vec![0; n], vec![0; n]);
        let mut frame_group = vec![0; n];
        let mut groups = vec![GroupInfo::default(); n];
        let mut scratch = GroupScratch {
            pair_bin: &mut pair_bin,
            parent: &mut parent,
            links: &mut links,
            attach: &mut attach,
            twist_lanes: &mut vec![0.0; len.twist_lanes],
        };
        let g = group_frames(
            &twists,
            labels,
            &Config::PAPER,
            &mut scratch,
            &mut frame_group,
            &mut groups,
        )
        .unwrap();
        groups.truncate(g.count);
        Run {
            frame_group,
            groups,
        }
    }

    /// Share of frames whose group's majority body is their own body.
    fn share_correct(frame_group: &[u16], body: &[usize], bodies: usize) -> Real {
        let mut votes = std::collections::BTreeMap::<u16, Vec<usize>>::new();
        for (&g, &b) in frame_group.iter().zip(body) {
            votes.entry(g).or_insert_with(|| vec![0; bodies])[b] += 1;
        }
        let correct: usize = votes
            .iter()
            .filter(|(g, _)| **g != NO_GROUP)
            .map(|(_, v)| *v.iter().max().unwrap())
            .sum();
        correct as Real / body.len() as Real
    }

    fn spin(centre: Point3<Real>, axis: Vector3<Real>, angle_rad: Real) -> Pose {
        let r = UnitQuaternion::from_scaled_axis(axis.normalize() * angle_rad);
        Pose::from_parts(Translation3::from(centre.coords - r * centre.coords), r)
    }

    #[test]
    fn two_moving_bodies_in_one_segment_are_split() {
        let mut rng = Pcg32::new(3);
        let (ca, cb) = (Point3::new(-0.04, 0.0, 0.6), Point3::new(0.04, 0.0, 0.6));
        let slide: Pose = Translation3::new(0.01, 0.0, 0.0).into();
        let turn = spin(cb, Vector3::new(0.0, 0.2, -1.0), 5f32.to_radians());
        let mut frames = frames_on(&mut rng, ca, &slide, 300, 3e-4);
        frames.extend(frames_on(&mut rng, cb, &turn, 200, 3e-4));
        let body: Vec<usize> = (0..500).map(|i| usize::from(i >= 300)).collect();
        let labels = vec![1; 500];
        let r = run(&frames, &labels, &Point3::new(0.0, 0.0, 0.6));
        assert!(r.groups.len() >= 2, "{:?}", r.groups);
        let share = share_correct(&r.frame_group, &body, 2);
        assert!(share >= 0.95, "{share}");
        assert!(
            r.groups.iter().filter(|g| g.frames >= 50).count() >= 2,
            "{:?}",
            r.groups
        );
    }

    #[test]
    fn one_rotating_body_is_never_split() {
        for seed in 0..5 {
            let mut rng = Pcg32::new(seed);
            let c = Point3::new(0.02, -0.01, 0.62);
            let turn = spin(c, Vector3::new(0.1, 0.0, 1.0), 8f32.to_radians());
            let frames = frames_on(&mut rng, c, &turn, 400, 3e-4);
            let r = run(&frames, &vec![7; 400], &Point3::new(0.0, 0.0, 0.6));
            assert_eq!(r.groups.len(), 1, "seed {seed}: {:?}", r.groups);
            let grouped = r.frame_group.iter().filter(|&&g| g == 0).count();
            assert!(grouped >= 390, "seed {seed}: {grouped}");
        }
    }

    #[test]
    fn static_frames_never_join_across_segments() {
        let mut rng = Pcg32::new(11);
        let still = Pose::identity();
        let nudge: Pose = Translation3::new(0.0005, 0.0, 0.0).into();
        let mut frames = frames_on(&mut rng, Point3::new(-0.05, 0.0, 0.6), &still, 150, 3e-4);
        frames.extend(frames_on(
            &mut rng,
            Point3::new(0.05, 0.0, 0.6),
            &nudge,
            150,
            3e-4,
        ));
        let labels: Vec<u16> = (0..300).map(|i| if i < 150 { 1 } else { 2 }).collect();
        let r = run(&frames, &labels, &Point3::new(0.0, 0.0, 0.6));
        for (g, info) in r.groups.iter().enumerate() {
            assert!(!info.moving);
            let members: Vec<u16> = (0..300)
                .filter(|&i| usize::from(r.frame_group[i]) == g)
                .map(|i| labels[i])
                .collect();
            assert!(
                members.windows(2).all(|w| w[0] == w[1]),
                "group {g} spans segments"
            );
        }
        assert!(r.groups.len() >= 2);
    }

    /// Calls `f(i, j, code)` for every pair `i < j` in the order pass 1 stored them.
    fn for_each_pair(n: usize, pair_bin: &[u8], mut f: impl FnMut(usize, usize, u8)) {
        for (i, row) in pair_rows(n, pair_bin) {
            for (k, &code) in row.iter().enumerate() {
                f(i, i + 1 + k, code);
            }
        }
    }

    /// Pass 3 pair by pair, as it was written first: each frame's attachment compared
    /// by `(nearness, rank)` with ranks `(density, −index)`.
    fn attach_up_pair_by_pair(
        n: usize,
        pair_bin: &[u8],
        density: &[u32],
        attaches_at: &[bool; 256],
    ) -> Vec<u32> {
        let rank = |i: usize| (density[i], u32::MAX - i as u32);
        let mut attach = vec![NONE; n];
        let mut near = vec![0u32; n];
        for_each_pair(n, pair_bin, |i, j, code| {
            if !attaches_at[usize::from(code)] {
                return;
            }
            let (low, high) = if rank(i) < rank(j) { (i, j) } else { (j, i) };
            let d_new = u32::from(code & !ACROSS);
            let current = attach[low];
            if current == NONE
                || d_new < near[low]
                || (d_new == near[low] && rank(high) > rank(current as usize))
            {
                attach[low] = high as u32;
                near[low] = d_new;
            }
        });
        attach
    }

    #[test]
    fn pairs_are_visited_with_the_codes_pass_one_wrote_for_them() {
        let n = 7;
        let mut bins = vec![0u8; n * (n - 1) / 2];
        let mut k = 0;
        for i in 0..n {
            for j in i + 1..n {
                bins[k] = (10 * i + j) as u8;
                k += 1;
            }
        }
        let mut seen = vec![];
        for_each_pair(n, &bins, |i, j, code| seen.push((i, j, code)));
        assert_eq!(seen.len(), bins.len());
        assert!(
            seen.iter()
                .all(|&(i, j, code)| i < j && usize::from(code) == 10 * i + j)
        );
        assert!(seen.windows(2).all(|w| (w[0].0, w[0].1) < (w[1].0, w[1].1)));
    }

    /// A posterior that falls with the distance tables its linking and attaching codes
    /// as the ones below a bound, so that passes 2 and 3 take their one-compare paths.
    /// (Tabling the posterior by `code % KDE_BINS` also linked the codes just past the
    /// last bin, which never occur, and sent every step to the table look-ups.)
    #[test]
    fn a_falling_posterior_links_the_codes_below_a_bound() {
        let mut posterior = [0.0; KDE_BINS];
        posterior[..6].fill(0.99);
        posterior[6] = 0.2;
        let (links_at, attaches_at) = link_tables(&posterior, 0.5, 4);
        assert_eq!(codes_below(&links_at), Some(6));
        assert_eq!(codes_below(&attaches_at), Some(5));
        assert!(!links_at[usize::from(ACROSS)] && !links_at[usize::from(NO_PAIR)]);
    }

    proptest::proptest! {
        /// [`codes_below`] finds the bound exactly when a table is of that form; pass 2's
        /// compare gives the table's link counts.
        #[test]
        fn bounded_passes_equal_the_table_passes(
            n in 1usize..80,
            codes in proptest::collection::vec(
                proptest::prop_oneof![0u8..130, proptest::strategy::Just(NO_PAIR)],
                0..3200,
            ),
            bound in 0u8..130,
            flip in proptest::option::of(0u8..=255),
        ) {
            let mut table = [false; 256];
            for (c, t) in table.iter_mut().enumerate() {
                *t = c < usize::from(bound);
            }
            if let Some(f) = flip {
                table[usize::from(f)] ^= true;
            }
            let expected = (0..=256usize)
                .find(|&b| table.iter().enumerate().all(|(c, &t)| t == (c < b)))
                .and_then(|b| u8::try_from(b).ok());
            proptest::prop_assert_eq!(codes_below(&table), expected);

            let len = GroupScratchLen::for_frames(n).pair_bin;
            let bins: Vec<u8> = (0..len).map(|k| codes.get(k % codes.len().max(1)).copied().unwrap_or(0)).collect();
            let mut plain = vec![0u32; n];
            let mut fast = vec![0u32; n];
            for (i, row) in pair_rows(n, &bins) {
                let own = add_links_below(row, &mut fast[i + 1..], bound);
                fast[i] += own;
                for (k, &code) in row.iter().enumerate() {
                    let link = u32::from(code < bound);
                    plain[i] += link;
                    plain[i + 1 + k] += link;
                }
            }
            proptest::prop_assert_eq!(&plain, &fast);
            // The whole pass, rows in blocks and one by one.
            for blocks in [true, false] {
                let mut whole = vec![0u32; n];
                links_below(n, &bins, bound, &mut whole, blocks);
                proptest::prop_assert_eq!(&plain, &whole, "blocks {}", blocks);
            }
        }

        /// [`attach_up`] chooses what pass 3 pair by pair chooses, with densities that tie
        /// often, with and without a bound on the attaching codes.
        #[test]
        fn attach_up_equals_the_pair_by_pair_pass(
            n in 1usize..70,
            codes in proptest::collection::vec(
                proptest::prop_oneof![0u8..12, 0u8..130, proptest::strategy::Just(NO_PAIR)],
                1..2500,
            ),
            densities in proptest::collection::vec(0u32..6, 70),
            bound in 0u8..14,
            flip in proptest::option::of(0u8..14),
        ) {
            let mut attaches_at = [false; 256];
            for (c, t) in attaches_at.iter_mut().enumerate() {
                *t = c < usize::from(bound);
            }
            if let Some(f) = flip {
                attaches_at[usize::from(f)] ^= true;
            }
            let len = GroupScratchLen::for_frames(n).pair_bin;
            let bins: Vec<u8> = (0..len).map(|k| codes[k % codes.len()]).collect();
            let density = &densities[..n];
            let (mut attach, mut near) = (vec![7u32; n], vec![3u32; n]);
            attach_up(n, &bins, &mut density.to_vec(), &attaches_at, &mut attach, &mut near);
            proptest::prop_assert_eq!(attach, attach_up_pair_by_pair(n, &bins, density, &attaches_at));
        }
    }

    /// Pass 2 in blocks of rows counts the pairs that do not link in bytes, emptied every
    /// 255 sixteens: rows of nearly only such pairs, just under, at and past that length,
    /// must not carry a byte.
    #[test]
    fn blocked_link_counts_survive_long_rows_without_links() {
        for n in [16 * 255 + 8, 16 * 256 + 8, 16 * 258 + 40] {
            let len = GroupScratchLen::for_frames(n).pair_bin;
            let bins: Vec<u8> = (0..len).map(|k| if k % 997 == 0 { 2 } else { 9 }).collect();
            let mut plain = vec![0u32; n];
            for (i, row) in pair_rows(n, &bins) {
                for (k, &code) in row.iter().enumerate() {
                    let link = u32::from(code < 3);
                    plain[i] += link;
                    plain[i + 1 + k] += link;
                }
            }
            let mut blocked = vec![0u32; n];
            links_below(n, &bins, 3, &mut blocked, true);
            assert_eq!(plain, blocked, "{n} frames");
        }
    }

    /// A twist component: ordinary, zero, huge or not a number.
    fn component() -> impl proptest::strategy::Strategy<Value = Real> {
        use proptest::prelude::*;
        prop_oneof![
            6 => -0.05f32..0.05,
            1 => Just(0.0),
            1 => Just(1e20),
            1 => Just(Real::NAN),
            1 => (0u8..4).prop_map(|k| Real::from(k) * 1e-3),
        ]
    }

    proptest::proptest! {
        /// Pass 1's four-at-a-time codes equal the codes of the plain pair-by-pair
        /// computation ([`Twist::distance`]), bit for bit, for every row length (the
        /// remainder of each row is done one pair at a time).
        #[test]
        fn pass_one_codes_equal_the_pair_by_pair_codes(
            frames in proptest::collection::vec(
                (proptest::array::uniform6(component()), 0u16..3),
                1..60,
            ),
            scale in proptest::sample::select(vec![0.05f32, 1.0]),
            (spread, sorted) in (1u16..4, proptest::bool::ANY),
        ) {
            // Labels in long runs too (one label, or sorted), as the frames of a scene come.
            let mut frames = frames;
            for f in &mut frames {
                f.1 %= spread;
            }
            if sorted {
                let mut labels: Vec<u16> = frames.iter().map(|f| f.1).collect();
                labels.sort_unstable();
                for (f, l) in frames.iter_mut().zip(labels) {
                    f.1 = l;
                }
            }
            let n = frames.len();
            let twists: Vec<Twist> = frames
                .iter()
                .map(|(c, _)| Twist {
                    w: Vector3::new(c[0], c[1], c[2]),
                    v: Vector3::new(c[3], c[4], c[5]),
                })
                .collect();
            let labels: Vec<u16> = frames.iter().map(|f| f.1).collect();
            let floor2 = Config::PAPER.static_below_m * Config::PAPER.static_below_m;
            let moving: Vec<bool> = twists
                .iter()
                .map(|t| t.norm_squared(scale) >= floor2)
                .collect();
            let flags: Vec<u32> = moving.iter().map(|&m| across_flags(m)).collect();
            let labels32: Vec<u32> = labels.iter().map(|&l| u32::from(l)).collect();
            let bins_per_m = KDE_BINS as Real / Config::PAPER.kde_range_m;
            let mut lanes_buf = vec![0.0; TWIST_LANES * n];
            let lanes = fill_lanes(&twists, &mut lanes_buf);
            let mut pair_bin = vec![0u8; GroupScratchLen::for_frames(n).pair_bin];
            pass_one(&lanes, (&labels32, &flags), (scale, bins_per_m), &mut pair_bin);
            // Every row through the path that looks at labels, too.
            let mut labelled = vec![0u8; pair_bin.len()];
            for (i, row) in pair_rows_mut(n, &mut labelled) {
                pair_codes::<false>(&lanes, i, (&labels32, &flags), (scale, bins_per_m), row);
            }
            proptest::prop_assert_eq!(&labelled, &pair_bin);
            let mut expected = Vec::new();
            for i in 0..n {
                for j in i + 1..n {
                    let across = labels[i] != labels[j];
                    expected.push(if across && !(moving[i] && moving[j]) {
                        NO_PAIR
                    } else {
                        let b = twists[i].distance(&twists[j], scale) * bins_per_m;
                        let b = if b < KDE_BINS as Real { b as u8 } else { KDE_BINS as u8 - 1 };
                        b | if across { ACROSS } else { 0 }
                    });
                }
            }
            proptest::prop_assert_eq!(pair_bin, expected);
            // And the distances themselves, bit for bit, four frames at a time.
            for i in 0..n {
                for j0 in (0..n.saturating_sub(3)).step_by(4) {
                    let tj: [[Real; 4]; TWIST_LANES] =
                        core::array::from_fn(|l| core::array::from_fn(|k| lanes[l][j0 + k]));
                    let ti: [f32x4; TWIST_LANES] =
                        core::array::from_fn(|l| f32x4::splat(lanes[l][i]));
                    let d2 = four_distances_squared(
                        &ti,
                        core::array::from_fn(|l| &tj[l]),
                        f32x4::splat(scale * scale),
                    );
                    for k in 0..4 {
                        let got = sqrt(d2[k]);
                        let want = twists[i].distance(&twists[j0 + k], scale);
                        proptest::prop_assert!(
                            got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                            "{} {}: {} vs {}", i, j0 + k, got, want
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn short_scratch_is_an_error() {
        let twists = [Twist::ZERO; 4];
        let mut small = [0u8; 2];
        let (mut a, mut b, mut c) = ([0; 4], [0; 4], [0; 4]);
        let mut scratch = GroupScratch {
            pair_bin: &mut small,
            parent: &mut a,
            links: &mut b,
            attach: &mut c,
            twist_lanes: &mut [0.0; 24],
        };
        let r = group_frames(
            &twists,
            &[1; 4],
            &Config::PAPER,
            &mut scratch,
            &mut [0; 4],
            &mut [GroupInfo::default(); 4],
        );
        assert!(matches!(
            r,
            Err(Error::BufferTooSmall {
                buffer: Buffer::PairDist,
                needed: 6,
                got: 2
            })
        ));
    }
}
