//! Recycled buffers. Allocations the size of a 640x480 plane are mapped fresh from
//! the operating system and fault in page by page on every call; at this image size that
//! costs about as much as the arithmetic, so the estimator keeps its buffers between calls.
//! Within a call (the first one above all, in a one-shot `riseg flow`), buffers made with
//! room for a full-resolution plane ([`Pool::reserve_room`]) serve every pyramid level, so
//! only the pages of the largest use of each buffer are ever faulted in.

use core::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};

/// Buffers kept at most (a 640x480 medium run uses a few dozen at its peak).
const KEEP: usize = 64;

/// A shared pool of `Vec<T>` buffers.
#[derive(Debug)]
pub(crate) struct Pool<T = f32> {
    free: Mutex<Vec<Vec<T>>>,
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

    /// A fresh buffer of `len` zeros with at least the reserved room.
    fn fresh(&self, len: usize) -> Vec<T> {
        // All zeros: the allocator hands out fresh zeroed pages without writing them.
        let mut v = vec![T::default(); len.max(self.room.load(Ordering::Relaxed))];
        v.truncate(len);
        v
    }

    /// A buffer of `len` zeros, reusing a kept buffer with room if there is one.
    pub fn zeroed(&self, len: usize) -> Vec<T> {
        match self.take(len) {
            Some(mut v) => {
                v.clear();
                v.resize(len, T::default());
                v
            }
            None => self.fresh(len),
        }
    }

    /// A buffer of `len` values of no particular content (the caller overwrites all of
    /// them), reusing a kept buffer with room if there is one ([`Pool::take`]).
    pub fn scratch(&self, len: usize) -> Vec<T> {
        match self.take(len) {
            Some(mut v) => {
                v.truncate(len);
                v.resize(len, T::default());
                v
            }
            None => self.fresh(len),
        }
    }

    /// The kept buffer with room for `len` values that [`Pool::scratch`] fills least: the
    /// shortest already holding `len` values (nothing to fill; call after call, each
    /// buffer keeps one role), else the longest. `None` if no buffer has room.
    fn take(&self, len: usize) -> Option<Vec<T>> {
        let mut free = self.free.lock().unwrap_or_else(PoisonError::into_inner);
        let best = free
            .iter()
            .enumerate()
            .filter(|(_, v)| v.capacity() >= len)
            .min_by_key(|(_, v)| {
                if v.len() >= len {
                    (false, v.len())
                } else {
                    (true, usize::MAX - v.len())
                }
            })
            .map(|(i, _)| i);
        best.map(|i| free.swap_remove(i))
    }

    /// Gives a buffer back for later calls. One without room (an empty `Vec::new()`, as a
    /// run's flow before its coarsest level) is dropped: any request it could serve needs
    /// no allocation, and one kept per call filled the [`KEEP`] places within a few dozen
    /// calls, after which every buffer given back was dropped and made anew.
    pub fn put(&self, v: Vec<T>) {
        if v.capacity() == 0 {
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
        let cap = a.capacity();
        pool.put(a);
        let b = pool.zeroed(50);
        assert_eq!(b.len(), 50);
        assert!(b.iter().all(|&v| v == 0.0));
        assert_eq!(b.capacity(), cap, "the kept buffer was reused");
        pool.put(b);
        let d = pool.scratch(80);
        assert_eq!((d.len(), d.capacity()), (80, cap));
        let c = pool.zeroed(1000);
        assert_eq!(c.len(), 1000);
    }

    #[test]
    fn buffers_without_room_are_not_kept() {
        let pool: Pool = Pool::default();
        for _ in 0..2 * KEEP {
            pool.put(Vec::new());
        }
        pool.put(pool.zeroed(10));
        let free = pool.free.lock().unwrap_or_else(PoisonError::into_inner);
        let rooms: Vec<usize> = free.iter().map(Vec::capacity).collect();
        assert_eq!(rooms, [10], "only the buffer with room is kept");
    }

    #[test]
    fn reserved_room_lets_a_small_buffer_serve_a_larger_request() {
        let pool: Pool = Pool::default();
        pool.reserve_room(1000);
        pool.reserve_room(10); // the largest room asked for holds
        let mut small = pool.scratch(10);
        assert_eq!(small.len(), 10);
        assert!(small.capacity() >= 1000, "{}", small.capacity());
        small.fill(3.0);
        let cap = small.capacity();
        pool.put(small);
        let large = pool.zeroed(1000);
        assert_eq!(large.capacity(), cap, "the small buffer was reused");
        assert!(large.len() == 1000 && large.iter().all(|&v| v == 0.0));
        let fresh = pool.zeroed(20);
        assert!(fresh.len() == 20 && fresh.iter().all(|&v| v == 0.0));
    }
}
