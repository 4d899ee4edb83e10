//! Recycled buffers. Allocations the size of a 640x480 plane are mapped fresh from
//! the operating system and fault in page by page on every call; at this image size that
//! costs about as much as the arithmetic, so the estimator keeps its buffers between calls.

use std::sync::{Mutex, PoisonError};

/// Buffers kept at most (a 640x480 medium run uses a few dozen at its peak).
const KEEP: usize = 64;

/// A shared pool of `Vec<T>` buffers.
#[derive(Debug)]
pub(crate) struct Pool<T = f32>(Mutex<Vec<Vec<T>>>);

impl<T> Default for Pool<T> {
    fn default() -> Self {
        Self(Mutex::new(Vec::new()))
    }
}

impl<T: Copy + Default> Pool<T> {
    /// A buffer of `len` zeros, reusing the smallest kept buffer that is large enough.
    pub fn zeroed(&self, len: usize) -> Vec<T> {
        match self.take(len) {
            Some(mut v) => {
                v.clear();
                v.resize(len, T::default());
                v
            }
            None => vec![T::default(); len],
        }
    }

    /// A buffer of `len` values of no particular content (the caller overwrites all of
    /// them), reusing the smallest kept buffer that is large enough.
    pub fn scratch(&self, len: usize) -> Vec<T> {
        match self.take(len) {
            Some(mut v) => {
                v.truncate(len);
                v.resize(len, T::default());
                v
            }
            None => vec![T::default(); len],
        }
    }

    /// The smallest kept buffer with room for `len` values, if any.
    fn take(&self, len: usize) -> Option<Vec<T>> {
        let mut free = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        let best = free
            .iter()
            .enumerate()
            .filter(|(_, v)| v.capacity() >= len)
            .min_by_key(|(_, v)| v.capacity())
            .map(|(i, _)| i);
        best.map(|i| free.swap_remove(i))
    }

    /// Gives a buffer back for later calls.
    pub fn put(&self, v: Vec<T>) {
        let mut free = self.0.lock().unwrap_or_else(PoisonError::into_inner);
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
}
