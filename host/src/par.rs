//! Data parallelism for the pure parts: rayon with the `threads` feature; without it
//! (wasm32 without threads) the same `par_*` calls run as plain iterators on the calling
//! thread. The results are bit-identical either way: every task writes its own output and
//! no sum crosses tasks.

#[cfg(feature = "threads")]
pub(crate) use rayon::{
    prelude::*,
    slice::{Chunks, ChunksMut},
};
#[cfg(not(feature = "threads"))]
pub(crate) use serial::{Chunks, ChunksMut, ForEachInit, ParSlice, ParSliceMut};

#[cfg(not(feature = "threads"))]
mod serial {
    pub(crate) use core::slice::{Chunks, ChunksMut};
    use core::slice::{Iter, IterMut};

    /// rayon's `par_*` names for shared slices, run serially.
    pub(crate) trait ParSlice<T> {
        fn par_iter(&self) -> Iter<'_, T>;
        fn par_chunks(&self, n: usize) -> Chunks<'_, T>;
    }

    /// rayon's `par_chunks_mut` and `par_iter_mut`, run serially.
    pub(crate) trait ParSliceMut<T> {
        fn par_chunks_mut(&mut self, n: usize) -> ChunksMut<'_, T>;
        fn par_iter_mut(&mut self) -> IterMut<'_, T>;
    }

    impl<T> ParSlice<T> for [T] {
        fn par_iter(&self) -> Iter<'_, T> {
            self.iter()
        }
        fn par_chunks(&self, n: usize) -> Chunks<'_, T> {
            self.chunks(n)
        }
    }

    impl<T> ParSliceMut<T> for [T] {
        fn par_chunks_mut(&mut self, n: usize) -> ChunksMut<'_, T> {
            self.chunks_mut(n)
        }
        fn par_iter_mut(&mut self) -> IterMut<'_, T> {
            self.iter_mut()
        }
    }

    /// rayon's `for_each_init`, run serially: one state for the whole iteration.
    pub(crate) trait ForEachInit: Iterator + Sized {
        fn for_each_init<T>(self, init: impl Fn() -> T, op: impl Fn(&mut T, Self::Item)) {
            let mut state = init();
            self.for_each(|item| op(&mut state, item));
        }
    }

    impl<I: Iterator> ForEachInit for I {}
}
