//! Recycled buffers. Allocations the size of a 640x480 plane are mapped fresh from
//! the operating system and fault in page by page on every call; at this image size that
//! costs about as much as the arithmetic, so the estimator keeps its buffers between calls.
//! Within a call (the first one above all, in a one-shot `riseg flow`), buffers made with
//! room for a full-resolution plane ([`Pool::reserve_room`]) serve every pyramid level, so
//! only the pages of the largest use of each buffer are ever faulted in.
//!
//! A buffer is lent as a [`Lent`]: the values in use at the front of a buffer that keeps
//! its whole length, so that lending it again for more values writes nothing (a `Vec`
//! shortened for a small loan has to write every value it grows by again). A fresh buffer
//! is the allocator's zeros over its whole room, written by no one.

use core::ops::{Deref, DerefMut};
use core::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};

/// Buffers kept at most (a 640x480 medium run uses a few dozen at its peak).
const KEEP: usize = 64;

/// A buffer lent by a [`Pool`] (or made by [`Lent::default`], empty): its first `len`
/// values, as a slice. Give it back with [`Pool::put`].
#[derive(Debug, Clone)]
pub(crate) struct Lent<T> {
    /// The whole buffer; at least `len` values.
    buf: Vec<T>,
    /// Values lent.
    len: usize,
    /// Values at the front that any loan may have written (and so faulted in).
    written: usize,
}

impl<T> Default for Lent<T> {
    fn default() -> Self {
        Self {
            buf: Vec::new(),
            len: 0,
            written: 0,
        }
    }
}

impl<T> Lent<T> {
    /// This buffer lent again for `len` values (at most its length).
    fn lend(mut self, len: usize) -> Self {
        self.len = len;
        self.written = self.written.max(len);
        self
    }

    /// The values lent, as an owned `Vec` (which leaves the pool).
    pub fn into_vec(mut self) -> Vec<T> {
        self.buf.truncate(self.len);
        self.buf
    }
}

impl<T> Deref for Lent<T> {
    type Target = [T];

    #[inline]
    fn deref(&self) -> &[T] {
        self.buf.get(..self.len).unwrap_or_default()
    }
}

impl<T> DerefMut for Lent<T> {
    #[inline]
    fn deref_mut(&mut self) -> &mut [T] {
        self.buf.get_mut(..self.len).unwrap_or_default()
    }
}

/// A shared pool of buffers of `T`.
#[derive(Debug)]
pub(crate) struct Pool<T = f32> {
    free: Mutex<Vec<Lent<T>>>,
    /// Values a fresh buffer has room for at least ([`Pool::reserve_room`]).
    room: AtomicUsize,
}

impl<T> Default for Pool<T> {
    fn default() -> Self {
        Self {
            free: Mutex::new(Vec::new()),
            room: AtomicUsize::new(0),
        }
    }
}

impl<T: Copy + Default> Pool<T> {
    /// From now on, buffers made fresh have room for at least `len` values (the largest
    /// `len` asked for so far holds). A run asks for its small buffers first (the coarse
    /// pyramid levels) and its large ones last; with room for the large ones, the
    /// buffers of the coarse levels serve the fine levels again instead of fresh ones.
    /// Room costs no memory until it is used: fresh pages are mapped when first touched.
    pub fn reserve_room(&self, len: usize) {
        self.room.fetch_max(len, Ordering::Relaxed);
    }

    /// A buffer of `len` zeros. A kept buffer is cleared over all `len` values, also those
    /// no loan has written yet: a page that is first read as the allocator's zeros and
    /// then written faults in twice (one-shot `riseg flow`: 370 page faults more when only
    /// the written values were cleared).
    pub fn zeroed(&self, len: usize) -> Lent<T> {
        match self.take(len) {
            Some(v) => {
                let mut v = v.lend(len);
                v.fill(T::default());
                v
            }
            None => self.fresh(len),
        }
    }

    /// A buffer of `len` values of no particular content (the caller overwrites all of
    /// them): nothing is written.
    pub fn scratch(&self, len: usize) -> Lent<T> {
        match self.take(len) {
            Some(v) => v.lend(len),
            None => self.fresh(len),
        }
    }

    /// A fresh buffer of `len` zeros with at least the reserved room.
    fn fresh(&self, len: usize) -> Lent<T> {
        Lent {
            // All zeros: the allocator hands out fresh zeroed pages without writing them.
            buf: vec![T::default(); len.max(self.room.load(Ordering::Relaxed))],
            len,
            written: len,
        }
    }

    /// The kept buffer with room for `len` values whose loan touches the fewest new
    /// pages: the one with the fewest written values that has at least `len` (no page
    /// faulted in; call after call, each buffer keeps one role), else the one with the
    /// most. `None` if no buffer has room.
    fn take(&self, len: usize) -> Option<Lent<T>> {
        let mut free = self.free.lock().unwrap_or_else(PoisonError::into_inner);
        let best = free
            .iter()
            .enumerate()
            .filter(|(_, v)| v.buf.len() >= len)
            .min_by_key(|(_, v)| {
                if v.written >= len {
                    (false, v.written)
                } else {
                    (true, usize::MAX - v.written)
                }
            })
            .map(|(i, _)| i);
        best.map(|i| free.swap_remove(i))
    }

    /// Gives a buffer back for later calls. One without room (an empty
    /// [`Lent::default`], as a run's flow before its coarsest level) is dropped: any
    /// request it could serve needs no allocation, and one kept per call filled the
    /// [`KEEP`] places within a few dozen calls, after which every buffer given back was
    /// dropped and made anew.
    pub fn put(&self, v: Lent<T>) {
        if v.buf.is_empty() {
            return;
        }
        let mut free = self.free.lock().unwrap_or_else(PoisonError::into_inner);
        if free.len() < KEEP {
            free.push(v);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reuses_and_zeroes() {
        let pool: Pool = Pool::default();
        let mut a = pool.zeroed(100);
        a.fill(3.0);
        let at = a.as_ptr();
        pool.put(a);
        let b = pool.zeroed(50);
        assert_eq!(b.len(), 50);
        assert!(b.iter().all(|&v| v == 0.0));
        assert_eq!(b.as_ptr(), at, "the kept buffer was reused");
        pool.put(b);
        let d = pool.scratch(80);
        assert_eq!((d.len(), d.as_ptr()), (80, at));
        // Zeroed where the loan of 100 wrote, not only where that of 50 cleared.
        pool.put(d);
        let e = pool.zeroed(100);
        assert!(e.len() == 100 && e.iter().all(|&v| v == 0.0));
        let c = pool.zeroed(1000);
        assert_eq!(c.len(), 1000);
        assert_eq!(c.into_vec(), vec![0.0; 1000]);
    }

    #[test]
    fn a_longer_loan_after_a_shorter_one_writes_nothing() {
        let pool: Pool = Pool::default();
        let mut a = pool.scratch(100);
        a.fill(3.0);
        pool.put(a);
        let mut b = pool.scratch(10);
        b.fill(4.0);
        pool.put(b);
        // A shortened `Vec` would have refilled values 10..100 (with zeros).
        let c = pool.scratch(100);
        assert_eq!(&c[..10], &[4.0; 10]);
        assert_eq!(&c[10..], &[3.0; 90]);
    }

    #[test]
    fn buffers_without_room_are_not_kept() {
        let pool: Pool = Pool::default();
        for _ in 0..2 * KEEP {
            pool.put(Lent::default());
        }
        pool.put(pool.zeroed(10));
        let free = pool.free.lock().unwrap_or_else(PoisonError::into_inner);
        let rooms: Vec<usize> = free.iter().map(|v| v.buf.len()).collect();
        assert_eq!(rooms, [10], "only the buffer with room is kept");
    }

    #[test]
    fn reserved_room_lets_a_small_buffer_serve_a_larger_request() {
        let pool: Pool = Pool::default();
        pool.reserve_room(1000);
        pool.reserve_room(10); // the largest room asked for holds
        let mut small = pool.scratch(10);
        assert_eq!(small.len(), 10);
        small.fill(3.0);
        let at = small.as_ptr();
        pool.put(small);
        let large = pool.zeroed(1000);
        assert_eq!(large.as_ptr(), at, "the small buffer was reused");
        assert!(large.len() == 1000 && large.iter().all(|&v| v == 0.0));
        let fresh = pool.zeroed(20);
        assert!(fresh.len() == 20 && fresh.iter().all(|&v| v == 0.0));
    }
}
