//! Data-parallel helpers: rayon with the `parallel` feature, plain loops without it. Every
//! helper gives the same result either way.

#[cfg(feature = "parallel")]
use rayon::prelude::*;

/// The number of threads that the parallel helpers use (1 without the feature).
pub(crate) fn threads() -> usize {
    #[cfg(feature = "parallel")]
    {
        rayon::current_num_threads()
    }
    #[cfg(not(feature = "parallel"))]
    {
        1
    }
}

/// Index of the first item for which `f` holds.
pub(crate) fn position_first<T: Sync>(items: &[T], f: impl Fn(&T) -> bool + Sync) -> Option<usize> {
    #[cfg(feature = "parallel")]
    {
        items.par_iter().position_first(&f)
    }
    #[cfg(not(feature = "parallel"))]
    {
        items.iter().position(f)
    }
}

/// Whether `f(i)` holds for every `i` in `0..n`.
pub(crate) fn all(n: usize, f: impl Fn(usize) -> bool + Sync) -> bool {
    #[cfg(feature = "parallel")]
    {
        (0..n).into_par_iter().with_min_len(1024).all(&f)
    }
    #[cfg(not(feature = "parallel"))]
    {
        (0..n).all(&f)
    }
}

/// Sorts (unstable; the items must be totally ordered with no equal distinct items).
pub(crate) fn sort<T: Ord + Send>(items: &mut [T]) {
    #[cfg(feature = "parallel")]
    items.par_sort_unstable();
    #[cfg(not(feature = "parallel"))]
    items.sort_unstable();
}

/// Items per chunk of [`sum`]: fixed, so that the rounding does not depend on threads.
const CHUNK: usize = 1 << 14;

/// `Σ f(item)`, summed in fixed chunks (in order), then the chunk sums in order.
pub(crate) fn sum<T: Sync>(items: &[T], f: impl Fn(&T) -> f64 + Sync) -> f64 {
    let chunk = |c: &[T]| c.iter().map(&f).sum::<f64>();
    #[cfg(feature = "parallel")]
    let parts: Vec<f64> = items.par_chunks(CHUNK).map(chunk).collect();
    #[cfg(not(feature = "parallel"))]
    let parts: Vec<f64> = items.chunks(CHUNK).map(chunk).collect();
    parts.iter().sum()
}

/// `dst[i] = f(i)` for every `i`.
pub(crate) fn fill<T: Send>(dst: &mut [T], f: impl Fn(usize) -> T + Sync) {
    #[cfg(feature = "parallel")]
    dst.par_iter_mut()
        .with_min_len(1024)
        .enumerate()
        .for_each(|(i, d)| *d = f(i));
    #[cfg(not(feature = "parallel"))]
    for (i, d) in dst.iter_mut().enumerate() {
        *d = f(i);
    }
}

/// `f(k, chunk)` for the consecutive chunks of `dst`, `len` items each (the last may be
/// shorter), `k` counting from 0.
pub(crate) fn for_each_chunk_mut<T: Send>(
    dst: &mut [T],
    len: usize,
    f: impl Fn(usize, &mut [T]) + Sync,
) {
    let len = len.max(1);
    #[cfg(feature = "parallel")]
    dst.par_chunks_mut(len)
        .enumerate()
        .for_each(|(k, c)| f(k, c));
    #[cfg(not(feature = "parallel"))]
    for (k, c) in dst.chunks_mut(len).enumerate() {
        f(k, c);
    }
}

/// `f(i, a_i, b_i)` for the pairs of two sequences of the same length, `i` counting from 0.
pub(crate) fn for_each_zip<A, B>(
    a: impl IntoIterator<Item = A>,
    b: impl IntoIterator<Item = B>,
    f: impl Fn(usize, A, B) + Sync,
) where
    A: Send,
    B: Send,
{
    let items: Vec<(A, B)> = a.into_iter().zip(b).collect();
    #[cfg(feature = "parallel")]
    items
        .into_par_iter()
        .enumerate()
        .for_each(|(i, (a, b))| f(i, a, b));
    #[cfg(not(feature = "parallel"))]
    for (i, (a, b)) in items.into_iter().enumerate() {
        f(i, a, b);
    }
}

/// `dst` becomes `[f(0), f(1), …, f(n - 1)]` (its buffer reused).
pub(crate) fn map_into<T: Send>(dst: &mut Vec<T>, n: usize, f: impl Fn(usize) -> T + Sync) {
    #[cfg(feature = "parallel")]
    (0..n).into_par_iter().map(&f).collect_into_vec(dst);
    #[cfg(not(feature = "parallel"))]
    {
        dst.clear();
        dst.extend((0..n).map(f));
    }
}

/// `f(i)` for every `i` in `0..n`, in no particular order.
pub(crate) fn for_each(n: usize, f: impl Fn(usize) + Sync) {
    #[cfg(feature = "parallel")]
    (0..n).into_par_iter().for_each(&f);
    #[cfg(not(feature = "parallel"))]
    (0..n).for_each(f);
}

/// `[f(&items[0]), f(&items[1]), …]`.
pub(crate) fn map<T: Sync, U: Send>(items: &[T], f: impl Fn(&T) -> U + Sync) -> Vec<U> {
    let mut out = Vec::new();
    map_into(&mut out, items.len(), |i| f(&items[i]));
    out
}

/// How many items `f` accepts.
pub(crate) fn count<T: Sync>(items: &[T], f: impl Fn(&T) -> bool + Sync) -> usize {
    #[cfg(feature = "parallel")]
    {
        items.par_iter().with_min_len(1024).filter(|x| f(x)).count()
    }
    #[cfg(not(feature = "parallel"))]
    {
        items.iter().filter(|x| f(x)).count()
    }
}

/// Appends `f(x)` for every `x` of `src`, last to first (in parallel, each written in its
/// place in `dst`).
pub(crate) fn extend_map_rev<T: Sync, U: Send>(
    dst: &mut Vec<U>,
    src: &[T],
    f: impl Fn(&T) -> U + Sync + Send,
) {
    #[cfg(feature = "parallel")]
    dst.par_extend(src.par_iter().with_min_len(1024).rev().map(f));
    #[cfg(not(feature = "parallel"))]
    dst.extend(src.iter().rev().map(f));
}

/// `(a(), b())`, the two at once with the `parallel` feature.
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

/// Appends to `dst` what `f(i, buffer)` appends for every `i` in `0..n`, in order of `i`
/// (in parallel: `per_task` consecutive `i` per task, joined in order, a batch of tasks at
/// a time so that the parts held at once are a batch's, not the whole output's).
pub(crate) fn extend_in_order<T: Send>(
    dst: &mut Vec<T>,
    n: usize,
    per_task: usize,
    f: impl Fn(usize, &mut Vec<T>) + Sync,
) {
    #[cfg(feature = "parallel")]
    {
        let per_task = per_task.max(1);
        let tasks = n.div_ceil(per_task);
        if tasks <= 1 {
            // One task: no thread pool, no part to copy.
            for i in 0..n {
                f(i, dst);
            }
            return;
        }
        let batch = 16 * rayon::current_num_threads().max(1);
        let mut parts: Vec<Vec<T>> = Vec::new();
        for first in (0..tasks).step_by(batch) {
            (first..(first + batch).min(tasks))
                .into_par_iter()
                .map(|t| {
                    let mut part = Vec::new();
                    for i in t * per_task..((t + 1) * per_task).min(n) {
                        f(i, &mut part);
                    }
                    part
                })
                .collect_into_vec(&mut parts);
            for mut part in parts.drain(..) {
                dst.append(&mut part);
            }
        }
    }
    #[cfg(not(feature = "parallel"))]
    {
        let _ = per_task;
        for i in 0..n {
            f(i, dst);
        }
    }
}

/// For every triangle, the smallest vertex index of its edge-connected piece (`n`
/// vertices). In parallel, a lock-free union-find that always links the larger root under
/// the smaller: every piece ends with its smallest vertex as root, whatever the schedule.
pub(crate) fn triangle_roots(n: usize, triangles: &[[u32; 3]]) -> Vec<u32> {
    #[cfg(feature = "parallel")]
    {
        use std::sync::atomic::{AtomicU32, Ordering};
        let parent: Vec<AtomicU32> = (0..n as u32).map(AtomicU32::new).collect();
        // Every pointer goes to a smaller index, and a root's only ever changes once (when
        // it is linked), so any pointer stored is to an ancestor: no cycle can form.
        let find = |mut x: u32| loop {
            let p = parent[x as usize].load(Ordering::Acquire);
            if p == x {
                return x;
            }
            let g = parent[p as usize].load(Ordering::Acquire);
            if g != p {
                parent[x as usize].store(g, Ordering::Release);
            }
            x = g;
        };
        let union = |a: u32, b: u32| {
            let (mut a, mut b) = (a, b);
            loop {
                a = find(a);
                b = find(b);
                if a == b {
                    return;
                }
                let (hi, lo) = (a.max(b), a.min(b));
                if parent[hi as usize]
                    .compare_exchange(hi, lo, Ordering::AcqRel, Ordering::Acquire)
                    .is_ok()
                {
                    return;
                }
            }
        };
        triangles.par_chunks(1 << 12).for_each(|c| {
            for t in c {
                union(t[0], t[1]);
                union(t[0], t[2]);
            }
        });
        triangles
            .par_iter()
            .with_min_len(1 << 12)
            .map(|t| find(t[0]))
            .collect()
    }
    #[cfg(not(feature = "parallel"))]
    {
        let mut dsu = crate::mesh::Dsu::new(n);
        for t in triangles {
            dsu.union(t[0], t[1]);
            dsu.union(t[0], t[2]);
        }
        triangles.iter().map(|t| dsu.find(t[0])).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Dsu;
    use proptest::prelude::*;

    proptest! {
        /// The roots are those of a plain union-find, whatever the thread schedule.
        #[test]
        fn triangle_roots_are_the_smallest_vertex_of_each_piece(
            tris in proptest::collection::vec([0u32..3000, 0u32..3000, 0u32..3000], 0..12000)
        ) {
            let mut dsu = Dsu::new(3000);
            for t in &tris {
                dsu.union(t[0], t[1]);
                dsu.union(t[0], t[2]);
            }
            let want: Vec<u32> = tris.iter().map(|t| dsu.find(t[0])).collect();
            prop_assert_eq!(triangle_roots(3000, &tris), want);
        }
    }
}
