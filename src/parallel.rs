//! The crate's data-parallel loops, in one place: on the rayon pool with the feature
//! `parallel`, in order on the calling thread without it. The work items are independent and
//! their results are put together in order, so either way gives the same bits.

/// Runs `pass` on each `chunk`-long piece of `values` with the piece's index.
pub(crate) fn for_each_chunk_mut<T: Send>(
    values: &mut [T],
    chunk: usize,
    pass: impl Fn(usize, &mut [T]) + Sync + Send,
) {
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        values
            .par_chunks_mut(chunk)
            .enumerate()
            .for_each(|(i, c)| pass(i, c));
    }
    #[cfg(not(feature = "parallel"))]
    values
        .chunks_mut(chunk)
        .enumerate()
        .for_each(|(i, c)| pass(i, c));
}

/// `f` of each `chunk`-long piece of `items` with the index of its first item, in order.
pub(crate) fn map_chunks<T: Sync, R: Send>(
    items: &[T],
    chunk: usize,
    f: impl Fn(usize, &[T]) -> R + Sync + Send,
) -> Vec<R> {
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        items
            .par_chunks(chunk)
            .enumerate()
            .map(|(i, c)| f(i * chunk, c))
            .collect()
    }
    #[cfg(not(feature = "parallel"))]
    items
        .chunks(chunk)
        .enumerate()
        .map(|(i, c)| f(i * chunk, c))
        .collect()
}

/// `f` of each of `items`, in order.
pub(crate) fn map_each<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync + Send) -> Vec<R> {
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        items.par_iter().map(f).collect()
    }
    #[cfg(not(feature = "parallel"))]
    items.iter().map(f).collect()
}

/// `f(i)` for `i` in `0..n`, in order.
pub(crate) fn map_indices<R: Send>(n: usize, f: impl Fn(usize) -> R + Sync + Send) -> Vec<R> {
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        (0..n).into_par_iter().map(f).collect()
    }
    #[cfg(not(feature = "parallel"))]
    (0..n).map(f).collect()
}

/// Runs `run` on each job.
pub(crate) fn for_each_job<J: Send>(jobs: Vec<J>, run: impl Fn(J) + Send + Sync) {
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        jobs.into_par_iter().for_each(run);
    }
    #[cfg(not(feature = "parallel"))]
    jobs.into_iter().for_each(run);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_helpers_keep_the_order_of_their_items() {
        let items: Vec<u32> = (0..1000).collect();
        let sums = map_chunks(&items, 64, |first, c| (first, c.iter().sum::<u32>()));
        assert_eq!(sums.len(), 16);
        assert_eq!(sums[1], (64, (64..128).sum()));
        assert_eq!(map_indices(5, |i| i * i), vec![0, 1, 4, 9, 16]);
        assert_eq!(map_each(&[1.5f64, 2.5], |&v| v as f32), vec![1.5f32, 2.5]);
        let mut values = vec![0usize; 100];
        for_each_chunk_mut(&mut values, 30, |i, c| c.iter_mut().for_each(|v| *v = i));
        assert_eq!((values[29], values[30], values[99]), (0, 1, 3));
        let seen = std::sync::Mutex::new(Vec::new());
        for_each_job(vec![3, 1, 2], |j| seen.lock().unwrap().push(j));
        let mut seen = seen.into_inner().unwrap();
        seen.sort();
        assert_eq!(seen, vec![1, 2, 3]);
    }
}
