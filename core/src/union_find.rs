//! Union-find over caller-owned `u32` parent slices (GroupBFIFs' groups, CorrectMask's
//! provisional labels and label merges, FindAction's runs).
//!
//! Contract: element `i` starts as its own parent (`parent[i] = i`); [`union`] always makes
//! the larger root point at the smaller, so a parent never exceeds its index and the root
//! of a set is its smallest element whatever order the unions come in. [`find`] halves
//! paths as it walks and ends on any slice contents (it stops at the first entry that does
//! not point lower); indices outside the slice are their own roots. No panics.

/// Root of `i`'s set.
pub(crate) fn find(parent: &mut [u32], mut i: usize) -> usize {
    loop {
        let Some(&p) = parent.get(i) else {
            return i;
        };
        let p = p as usize;
        if p >= i {
            return i;
        }
        let grand = parent.get(p).copied().unwrap_or(p as u32);
        if let Some(slot) = parent.get_mut(i) {
            *slot = grand;
        }
        i = p;
    }
}

/// Joins the sets of `a` and `b`; the smaller root stays the root. Returns whether they
/// were two sets.
pub(crate) fn union(parent: &mut [u32], a: usize, b: usize) -> bool {
    let (ra, rb) = (find(parent, a), find(parent, b));
    let (keep, drop) = if ra < rb { (ra, rb) } else { (rb, ra) };
    if keep == drop {
        return false;
    }
    if let Some(slot) = parent.get_mut(drop) {
        *slot = keep as u32;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roots_are_the_smallest_members_whatever_the_order() {
        let mut parent: [u32; 8] = core::array::from_fn(|i| i as u32);
        assert!(union(&mut parent, 6, 3));
        assert!(union(&mut parent, 7, 6));
        assert!(union(&mut parent, 5, 1));
        assert!(!union(&mut parent, 3, 7));
        assert!(union(&mut parent, 7, 5));
        let roots: [usize; 8] = core::array::from_fn(|i| find(&mut parent, i));
        assert_eq!(roots, [0, 1, 2, 1, 4, 1, 1, 1]);
    }

    #[test]
    fn garbage_parents_end_without_panics() {
        let mut parent = [5u32, 9, u32::MAX, 0, 3];
        for i in 0..8 {
            let r = find(&mut parent, i);
            assert!(r <= i);
        }
        union(&mut parent, 2, 40);
    }
}
