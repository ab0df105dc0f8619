//! The one switch between serial and parallel work in the facade: with the `parallel`
//! feature these run on rayon's pool, without it on the calling thread, with the same
//! results either way.

use voxoct_core::{Octree, Triangle};

/// Applies `f` to every item with its index, keeping the order; the first error wins.
pub(crate) fn map_indexed<I: Send, O: Send, E: Send>(
    items: Vec<I>,
    f: impl Fn(usize, I) -> Result<O, E> + Sync + Send,
) -> Result<Vec<O>, E> {
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        items
            .into_par_iter()
            .enumerate()
            .map(|(i, x)| f(i, x))
            .collect()
    }
    #[cfg(not(feature = "parallel"))]
    {
        items
            .into_iter()
            .enumerate()
            .map(|(i, x)| f(i, x))
            .collect()
    }
}

/// Inserts every triangle into `tree` ([`Octree::par_insert`] or [`Octree::insert_all`]:
/// the same leaves and hits).
pub(crate) fn insert(tree: &mut Octree, triangles: &[Triangle]) {
    #[cfg(feature = "parallel")]
    tree.par_insert(triangles);
    #[cfg(not(feature = "parallel"))]
    tree.insert_all(triangles);
}

/// `(a(), b())`, the two at once with the `parallel` feature (`b` on another thread when
/// one is free), one after the other without it.
pub(crate) fn join<A: Send, B: Send>(
    a: impl FnOnce() -> A + Send,
    b: impl FnOnce() -> B + Send,
) -> (A, B) {
    #[cfg(feature = "parallel")]
    {
        rayon::join(a, b)
    }
    #[cfg(not(feature = "parallel"))]
    {
        (a(), b())
    }
}

/// How many threads the work runs on: rayon's pool with the `parallel` feature, else 1.
#[must_use]
pub fn threads() -> usize {
    #[cfg(feature = "parallel")]
    {
        rayon::current_num_threads()
    }
    #[cfg(not(feature = "parallel"))]
    {
        1
    }
}
