//! Sparse linear solves: faer's supernodal Cholesky with the symbolic analysis (fill-reducing
//! ordering, elimination tree, supernodes) done once per sparsity pattern.
//!
//! Threads (feature `parallel-factor`, off by default): the numeric factorisation of a large
//! factor runs its dense kernels on the rayon pool's threads (`factor_parallelism`). Its
//! values have the same bits for any number of threads: faer visits the supernodes in one
//! fixed order, its dense Cholesky blocks by fixed sizes, and its matrix products share out
//! tiles of the output, each summed over the whole depth by one thread (measured:
//! `examples/thread_report.rs`, identical factors on 1, 2, 4 and 8 threads). It is off by
//! default because on the project's 2-core machine, shared with other work, two threads took
//! 1.1 to 2x the time of one at 2.4, 18 and 70 million factor entries. faer's threaded
//! triangular solve splits the depth of a matrix-vector product among the threads and adds
//! their partial sums, so its result changes with the thread count: small factors are solved by
//! faer sequentially, large ones by `tree_solve`, which shares out independent subtrees of
//! the elimination tree among the rayon pool's threads (feature `parallel`) with the same bits
//! on any thread count.

pub(crate) mod krylov;
mod ordering;
mod tree_solve;

pub use ordering::FillOrdering;

use std::sync::{Arc, Mutex};

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::Perm;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::SparseColMat;
use faer::{Conj, Par, Side};

use crate::error::{Error, Result};

/// Factors with at least this many entries are computed with threads (feature
/// `parallel-factor`); smaller ones sequentially. A round figure, not a measured break-even:
/// on the project's shared 2-core machine two threads were slower at every size measured,
/// from 2.4 million entries (1.1x the time of one thread) up.
#[doc(hidden)]
pub const PARALLEL_FACTOR_ENTRIES: usize = 1_000_000;

/// Factors with at least this many entries are solved by the tree-split solve
/// (`tree_solve`: independent subtrees on the rayon pool's threads with the feature
/// `parallel`), smaller ones by faer's sequential solve. Below it, the tasks are too small for
/// threads to pay (a round figure, like [`PARALLEL_FACTOR_ENTRIES`]).
#[doc(hidden)]
pub const PARALLEL_SOLVE_ENTRIES: usize = 1_000_000;

/// The parallelism of a numeric factorisation with `entries` factor entries: the rayon pool's
/// threads for a large factor (feature `parallel-factor`), one thread otherwise. The factor's
/// values do not depend on it (see the module's documentation).
fn factor_parallelism(entries: usize) -> Par {
    let large = entries >= PARALLEL_FACTOR_ENTRIES;
    #[cfg(feature = "parallel-factor")]
    {
        let threads = rayon::current_num_threads();
        if large && threads > 1 {
            return Par::rayon(threads);
        }
    }
    let _ = large;
    Par::Seq
}

/// Entries of a single-precision factor below this fraction of its largest entry, and of a
/// right-hand side (scaled to a largest entry of 1) below it, are set to zero. They are
/// round-off (a component that cancels, such as the transverse coupling of a bar with nu = 0),
/// far below what single precision resolves, and their products reach the subnormal range,
/// where each operation costs about a hundred cycles: the two-bar contact test's solves took
/// 700 us instead of 110 us (`tests/contact.rs` `d3::two_bars_implicit_projection`, 14.1 s
/// against 4.2 s).
const SINGLE_PRECISION_DROP: f64 = 1e-12;

/// Elementwise passes over factors (the single-precision rounding and drop) work in chunks of
/// this many values, on the rayon pool's threads with `parallel`: on the 28^3 Hex8 cube's
/// contact factors (70M values) they were 2.4 % of a two-thread run's samples, all on one
/// thread (`perf record` on `contact_perf hex 28`, 2026-11-30).
const ELEMENTWISE_CHUNK: usize = 1 << 16;

/// The largest magnitude among `values` (exact in any order: the same bits on any thread
/// count).
fn largest_magnitude(values: &[f32]) -> f32 {
    crate::parallel::map_chunks(values, ELEMENTWISE_CHUNK, |_, c| {
        c.iter().fold(0.0f32, |m, v| m.max(v.abs()))
    })
    .into_iter()
    .fold(0.0, f32::max)
}

/// Runs `pass` on each chunk of `values` (`ELEMENTWISE_CHUNK` of them), in parallel with
/// `parallel`.
fn for_each_chunk(values: &mut [f32], pass: impl Fn(&mut [f32]) + Sync + Send) {
    crate::parallel::for_each_chunk_mut(values, ELEMENTWISE_CHUNK, |_, c| pass(c));
}

/// The numeric factor in the precision it was computed in.
enum Values {
    None,
    Double(Vec<f64>),
    Single(Vec<f32>),
}

/// A Cholesky factorisation whose symbolic analysis is computed once per sparsity pattern and
/// reused by every numeric factorisation.
pub struct SparseCholesky {
    symbolic: Arc<SymbolicCholesky<usize>>,
    /// The split of a large supernodal factor's tree for the solves (`None`: faer's solve).
    split: Option<Arc<tree_solve::TreeSplit>>,
    /// The numeric factor.
    values: Values,
    /// The pattern the symbolic analysis was made for (column pointers, row indices).
    pattern: (Vec<usize>, Vec<usize>),
    ordering: FillOrdering,
    block: usize,
    /// The solve workspace, allocated once: a fresh one per solve costs page faults (about a
    /// third of a solve on 28k unknowns).
    workspace: Mutex<MemBuffer>,
}

impl std::fmt::Debug for SparseCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseCholesky")
            .field("ordering", &self.ordering)
            .field("factor_entries", &self.symbolic.len_val())
            .field(
                "factored",
                &match self.values {
                    Values::None => "no",
                    Values::Double(_) => "double precision",
                    Values::Single(_) => "single precision",
                },
            )
            .finish()
    }
}

impl SparseCholesky {
    /// Symbolic analysis of a matrix stored as its lower triangle, with the default ordering
    /// (nested dissection) on the graph of its unknowns.
    pub fn analyse(matrix: &SparseColMat<usize, f64>) -> Result<Self> {
        Self::analyse_with(matrix, FillOrdering::default(), 1)
    }

    /// Symbolic analysis with a chosen ordering; `block` consecutive unknowns (the `D`
    /// components of a node) are ordered together.
    pub fn analyse_with(
        matrix: &SparseColMat<usize, f64>,
        ordering: FillOrdering,
        block: usize,
    ) -> Result<Self> {
        let col_ptr = matrix.symbolic().col_ptr().to_vec();
        let row_idx = matrix.symbolic().row_idx().to_vec();
        let dissection = match ordering {
            FillOrdering::NestedDissection => {
                ordering::nested_dissection(&col_ptr, &row_idx, block)
            }
            FillOrdering::MinimumDegree => None,
        };
        let analysis_error = |e: faer::sparse::FaerError| Error::Factorization {
            step: 0,
            message: format!("symbolic analysis: {e:?}"),
        };
        let symbolic = match dissection {
            Some((forward, inverse)) => {
                let n = forward.len();
                let perm = Perm::new_checked(forward.into(), inverse.into(), n);
                factorize_symbolic_cholesky(
                    matrix.symbolic(),
                    Side::Lower,
                    SymmetricOrdering::Custom(perm.as_ref()),
                    CholeskySymbolicParams::default(),
                )
            }
            None => factorize_symbolic_cholesky(
                matrix.symbolic(),
                Side::Lower,
                SymmetricOrdering::Amd,
                CholeskySymbolicParams::default(),
            ),
        }
        .map_err(analysis_error)?;
        let workspace = Mutex::new(MemBuffer::new(
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
        ));
        let split = match symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(supernodal)
                if symbolic.len_val() >= PARALLEL_SOLVE_ENTRIES =>
            {
                tree_solve::TreeSplit::new(supernodal).map(Arc::new)
            }
            _ => None,
        };
        Ok(SparseCholesky {
            workspace,
            split,
            symbolic: Arc::new(symbolic),
            values: Values::None,
            pattern: (col_ptr, row_idx),
            ordering,
            block,
        })
    }

    /// A factorisation object with the same symbolic analysis (shared, not recomputed) and
    /// no numeric factor yet.
    pub fn unfactored_copy(&self) -> Self {
        SparseCholesky {
            workspace: Mutex::new(MemBuffer::new(
                self.symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
            )),
            symbolic: Arc::clone(&self.symbolic),
            split: self.split.clone(),
            values: Values::None,
            pattern: self.pattern.clone(),
            ordering: self.ordering,
            block: self.block,
        }
    }

    /// Whether this is the analysis `analyse_with(matrix, ordering, block)` would make: the
    /// same pattern, ordering and block (the analysis is a function of these alone).
    pub fn is_analysis_of(
        &self,
        matrix: &SparseColMat<usize, f64>,
        ordering: FillOrdering,
        block: usize,
    ) -> bool {
        self.ordering == ordering
            && self.block == block
            && self.pattern.0 == matrix.symbolic().col_ptr()
            && self.pattern.1 == matrix.symbolic().row_idx()
    }

    /// Takes over the value storage of `donor`, a factorisation no longer needed, where this
    /// one has no factor yet: the next numeric factorisation in the donor's precision writes
    /// over that storage instead of allocating a new one, zeroing it and faulting its pages in
    /// (every value is written: the same bits).
    pub fn reuse_storage_of(&mut self, donor: SparseCholesky) {
        if matches!(self.values, Values::None) {
            self.values = donor.values;
        }
    }

    /// The same analysis solved by the tree-split solve whatever its size (tests of small
    /// factors); `None` when the tree has nothing to split.
    #[cfg(test)]
    fn with_tree_split(mut self) -> Option<Self> {
        let SymbolicCholeskyRaw::Supernodal(supernodal) = self.symbolic.raw() else {
            return None;
        };
        self.split = Some(Arc::new(tree_solve::TreeSplit::new(supernodal)?));
        Some(self)
    }

    /// Number of stored entries of the factor L (its memory is 8 bytes per entry).
    pub fn factor_entries(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Re-analyses (same ordering) when `matrix` has another pattern than the analysed one.
    pub fn reanalyse_if_new_pattern(&mut self, matrix: &SparseColMat<usize, f64>) -> Result<()> {
        if !self.is_analysis_of(matrix, self.ordering, self.block) {
            *self = SparseCholesky::analyse_with(matrix, self.ordering, self.block)?;
        }
        Ok(())
    }

    /// Like [`SparseCholesky::factor`], re-analysing first (same ordering) when `matrix` has
    /// another pattern than the analysed one (contact between bodies adds couplings).
    pub fn factor_any(&mut self, matrix: &SparseColMat<usize, f64>, step: usize) -> Result<()> {
        self.reanalyse_if_new_pattern(matrix)?;
        self.factor(matrix, step)
    }

    /// Like [`SparseCholesky::factor_single`], re-analysing first when the pattern differs.
    pub fn factor_any_single(
        &mut self,
        matrix: &SparseColMat<usize, f64>,
        step: usize,
    ) -> Result<()> {
        self.reanalyse_if_new_pattern(matrix)?;
        self.factor_single(matrix, step)
    }

    /// Numeric factorisation of a matrix with the analysed pattern; `step` names the step in
    /// the error. On error the previous factor is gone (solves leave the right-hand side as is).
    pub fn factor(&mut self, matrix: &SparseColMat<usize, f64>, step: usize) -> Result<()> {
        let values = match std::mem::replace(&mut self.values, Values::None) {
            Values::Double(v) => v,
            _ => Vec::new(),
        };
        let values = self.factor_values(matrix.as_ref(), values, step)?;
        self.values = Values::Double(values);
        Ok(())
    }

    /// Numeric factorisation in single precision: half the memory and the memory traffic of
    /// [`SparseCholesky::factor`], and about half its time. Its solves are accurate to roughly
    /// `1e-7` times the condition number: use it as a preconditioner (mixed-precision
    /// iterative refinement), not as a solver. Fails where rounding to single precision
    /// leaves the matrix indefinite.
    pub fn factor_single(&mut self, matrix: &SparseColMat<usize, f64>, step: usize) -> Result<()> {
        let values = match std::mem::replace(&mut self.values, Values::None) {
            Values::Single(v) => v,
            _ => Vec::new(),
        };
        let rounded: Vec<f32> = crate::parallel::map_each(matrix.val(), |&v| v as f32);
        let single = faer::sparse::SparseColMatRef::new(matrix.symbolic(), &rounded);
        let mut values = self.factor_values(single, values, step)?;
        // An exact maximum and an elementwise rule: the same bits in any chunking.
        let largest = largest_magnitude(&values);
        let floor = (SINGLE_PRECISION_DROP * f64::from(largest)) as f32;
        for_each_chunk(&mut values, |v| {
            for v in v {
                if v.abs() < floor {
                    *v = 0.0;
                }
            }
        });
        self.values = Values::Single(values);
        Ok(())
    }

    fn factor_values<T: faer::traits::RealField + Copy + Default>(
        &self,
        matrix: faer::sparse::SparseColMatRef<'_, usize, T>,
        mut values: Vec<T>,
        step: usize,
    ) -> Result<Vec<T>> {
        let failure = |message: String| Error::Factorization { step, message };
        values.resize(self.symbolic.len_val(), T::default());
        let par = factor_parallelism(self.symbolic.len_val());
        let mut scratch = MemBuffer::try_new(
            self.symbolic
                .factorize_numeric_llt_scratch::<T>(par, Default::default()),
        )
        .map_err(|_| failure("not enough memory for the factorisation workspace".into()))?;
        self.symbolic
            .factorize_numeric_llt::<T>(
                &mut values,
                matrix,
                Side::Lower,
                Default::default(),
                par,
                MemStack::new(&mut scratch),
                Default::default(),
            )
            .map_err(|e| {
                // In words, not faer's type names.
                let faer::linalg::solvers::LltError::NonPositivePivot { index } = e;
                let what = format!("pivot {index} of the factorisation is not positive");
                failure(format!(
                    "{what}: the iteration matrix is not positive definite (a body with \
                     no mass and no support, a non-physical material, or once the run is under \
                     way a body compressed past its buckling load or a collapsing cell)"
                ))
            })?;
        Ok(values)
    }

    /// Bytes of the stored factor's values: 8 per entry in double precision, 4 in single, 0
    /// before the first numeric factorisation. (The symbolic structure, shared by every
    /// factorisation of the pattern, is not counted.)
    pub fn value_bytes(&self) -> usize {
        match &self.values {
            Values::None => 0,
            Values::Double(v) => v.len() * std::mem::size_of::<f64>(),
            Values::Single(v) => v.len() * std::mem::size_of::<f32>(),
        }
    }

    /// Whether the stored factor is in single precision.
    pub fn is_single_precision(&self) -> bool {
        matches!(self.values, Values::Single(_))
    }

    /// Solves with the factor `values` in their precision: the tree-split solve for a large
    /// factor, faer's sequential one otherwise (its threaded solve sums partial products per
    /// thread, see the module's documentation, which would make the result depend on the
    /// thread count).
    fn solve_values<T: tree_solve::Real>(
        &self,
        values: &[T],
        x: &mut [T],
        scratch: &mut MemBuffer,
    ) {
        let (Some(split), SymbolicCholeskyRaw::Supernodal(supernodal)) =
            (&self.split, self.symbolic.raw())
        else {
            LltRef::new(&self.symbolic, values).solve_in_place_with_conj(
                Conj::No,
                faer::ColMut::from_slice_mut(x).as_mat_mut(),
                Par::Seq,
                MemStack::new(scratch),
            );
            return;
        };
        match self.symbolic.perm() {
            Some(perm) => {
                let (forward, inverse) = perm.arrays();
                let mut permuted: Vec<T> = forward.iter().map(|&f| x[f]).collect();
                split.solve(supernodal, values, &mut permuted);
                for (xi, &i) in x.iter_mut().zip(inverse) {
                    *xi = permuted[i];
                }
            }
            None => split.solve(supernodal, values, x),
        }
    }

    /// Solves `A x = b` in place (leaves `rhs` as is when nothing is factored). With a
    /// single-precision factor the result is rounded accordingly.
    pub fn solve_in_place(&self, rhs: &mut [f64]) {
        if rhs.is_empty() {
            return;
        }
        // A poisoned lock only means another solve panicked; the buffer is plain scratch.
        let mut scratch = self
            .workspace
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        match &self.values {
            Values::None => {}
            Values::Double(values) => self.solve_values(values, rhs, &mut scratch),
            Values::Single(values) => {
                // Scaled to a largest entry of 1: single precision's range is narrow (a
                // residual near 1e-40 would be subnormal, slow, and lose its digits).
                let largest = rhs.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let scale = if largest > 0.0 && largest.is_finite() {
                    largest
                } else {
                    1.0
                };
                let mut single: Vec<f32> = rhs
                    .iter()
                    .map(|&v| {
                        let v = v / scale;
                        if v.abs() < SINGLE_PRECISION_DROP {
                            0.0
                        } else {
                            v as f32
                        }
                    })
                    .collect();
                self.solve_values(values, &mut single, &mut scratch);
                for (r, s) in rhs.iter_mut().zip(&single) {
                    *r = f64::from(*s) * scale;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::sparse::Triplet;

    #[test]
    fn solves_a_laplacian_with_reused_symbolic_analysis() {
        let n = 50;
        let build = |shift: f64| {
            let mut t = Vec::new();
            for i in 0..n {
                t.push(Triplet::new(i, i, 2.0 + shift));
                if i + 1 < n {
                    t.push(Triplet::new(i + 1, i, -1.0));
                }
            }
            SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &t).unwrap()
        };
        let a = build(0.1);
        let mut chol = SparseCholesky::analyse(&a).unwrap();
        for shift in [0.1, 1.0] {
            let a = build(shift);
            chol.factor(&a, 0).unwrap();
            let x_true: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
            let mut b = vec![0.0; n];
            crate::assembly::symmetric_mul_add(&a, &x_true, 1.0, &mut b);
            chol.solve_in_place(&mut b);
            let err: f64 = b
                .iter()
                .zip(&x_true)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(err < 1e-12, "{err}");
        }
    }

    /// The 7-point Laplacian (plus `shift` on the diagonal) of an `m^3` grid with `block`
    /// unknowns per grid point (uncoupled copies), lower triangle.
    fn grid_laplacian(m: usize, block: usize, shift: f64) -> SparseColMat<usize, f64> {
        let id = |i: usize, j: usize, k: usize| (i * m + j) * m + k;
        let mut t = Vec::new();
        for i in 0..m {
            for j in 0..m {
                for k in 0..m {
                    let p = id(i, j, k);
                    for c in 0..block {
                        t.push(Triplet::new(p * block + c, p * block + c, 6.0 + shift));
                        for q in [
                            (i + 1 < m).then(|| id(i + 1, j, k)),
                            (j + 1 < m).then(|| id(i, j + 1, k)),
                            (k + 1 < m).then(|| id(i, j, k + 1)),
                        ]
                        .into_iter()
                        .flatten()
                        {
                            t.push(Triplet::new(q * block + c, p * block + c, -1.0));
                        }
                    }
                }
            }
        }
        let n = m * m * m * block;
        SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &t).unwrap()
    }

    fn residual_of(a: &SparseColMat<usize, f64>, x: &[f64], b: &[f64]) -> f64 {
        let mut ax = vec![0.0; b.len()];
        crate::assembly::symmetric_mul_add(a, x, 1.0, &mut ax);
        ax.iter()
            .zip(b)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max)
    }

    /// The tree-split solve agrees with faer's sequential solve to round-off, in double and
    /// single precision, and has the same bits on 1, 2 and 4 threads.
    #[test]
    fn the_tree_split_solve_agrees_with_faer_and_with_itself_on_any_thread_count() {
        let a = grid_laplacian(14, 3, 0.01);
        let b: Vec<f64> = (0..a.nrows()).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut faer_solve =
            SparseCholesky::analyse_with(&a, FillOrdering::NestedDissection, 3).unwrap();
        assert!(faer_solve.split.is_none(), "small: faer's solve");
        let mut tree = faer_solve
            .unfactored_copy()
            .with_tree_split()
            .expect("a nested dissection tree splits");
        for single in [false, true] {
            if single {
                faer_solve.factor_single(&a, 0).unwrap();
                tree.factor_single(&a, 0).unwrap();
            } else {
                faer_solve.factor(&a, 0).unwrap();
                tree.factor(&a, 0).unwrap();
            }
            let mut expected = b.clone();
            faer_solve.solve_in_place(&mut expected);
            let mut solutions = Vec::new();
            for threads in [1, 2, 4] {
                let mut x = b.clone();
                crate::on_threads(threads, || tree.solve_in_place(&mut x));
                solutions.push(x);
            }
            let tolerance = if single { 1e-5 } else { 1e-12 };
            let largest = expected.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let difference = solutions[0]
                .iter()
                .zip(&expected)
                .map(|(p, q)| (p - q).abs())
                .fold(0.0, f64::max);
            assert!(
                difference <= tolerance * largest,
                "{difference} of {largest}"
            );
            if !single {
                assert!(residual_of(&a, &solutions[0], &b) < 1e-12);
            }
            for x in &solutions[1..] {
                let same = x
                    .iter()
                    .zip(&solutions[0])
                    .all(|(p, q)| p.to_bits() == q.to_bits());
                assert!(same, "the bits follow the thread count (single: {single})");
            }
        }
    }

    #[test]
    fn nested_dissection_solves_exactly_with_less_fill_than_minimum_degree() {
        let a = grid_laplacian(12, 3, 0.01);
        let b: Vec<f64> = (0..a.nrows()).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut entries = Vec::new();
        for ordering in [FillOrdering::NestedDissection, FillOrdering::MinimumDegree] {
            let mut chol = SparseCholesky::analyse_with(&a, ordering, 3).unwrap();
            chol.factor(&a, 0).unwrap();
            let mut x = b.clone();
            chol.solve_in_place(&mut x);
            assert!(residual_of(&a, &x, &b) < 1e-11, "{ordering:?}");
            entries.push(chol.factor_entries());
        }
        // A 3D grid: the separators of nested dissection beat minimum degree's fill.
        assert!(entries[0] < entries[1], "{entries:?}");
    }

    #[test]
    fn nested_dissection_is_a_permutation_of_whole_blocks() {
        let a = grid_laplacian(5, 2, 0.0);
        let (forward, inverse) =
            ordering::nested_dissection(a.symbolic().col_ptr(), a.symbolic().row_idx(), 2)
                .expect("125 vertices are ordered by METIS");
        let mut seen = vec![false; a.nrows()];
        for (new, &old) in forward.iter().enumerate() {
            assert!(!seen[old]);
            seen[old] = true;
            assert_eq!(inverse[old], new);
        }
        // The two unknowns of a grid point stay adjacent, in order.
        for pair in forward.chunks(2) {
            assert_eq!(pair[0] % 2, 0);
            assert_eq!(pair[1], pair[0] + 1);
        }
        // Tiny or block-incompatible graphs fall back to minimum degree.
        let small = grid_laplacian(2, 1, 0.0);
        assert!(ordering::nested_dissection(
            small.symbolic().col_ptr(),
            small.symbolic().row_idx(),
            1
        )
        .is_none());
        assert!(
            ordering::nested_dissection(a.symbolic().col_ptr(), a.symbolic().row_idx(), 4)
                .is_none()
        );
    }

    #[test]
    fn single_precision_factor_solves_to_single_precision() {
        let a = grid_laplacian(8, 1, 0.5);
        let b: Vec<f64> = (0..a.nrows()).map(|i| 1.0 + (i as f64).cos()).collect();
        let mut chol = SparseCholesky::analyse(&a).unwrap();
        chol.factor_single(&a, 0).unwrap();
        assert!(chol.is_single_precision());
        let mut x = b.clone();
        chol.solve_in_place(&mut x);
        let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let r = residual_of(&a, &x, &b) / scale;
        // Rounded to f32, not to f64: good enough to precondition, not to solve.
        assert!(r < 1e-5 && r > 1e-12, "{r}");
        chol.factor(&a, 0).unwrap();
        assert!(!chol.is_single_precision());
    }

    #[test]
    fn single_precision_solves_keep_their_digits_at_any_scale() {
        // A right-hand side near 1e-40 (subnormal in f32) or 1e37 (near its overflow) solves
        // to the same relative accuracy as one near 1: the solve scales it.
        let a = grid_laplacian(8, 1, 0.5);
        let mut chol = SparseCholesky::analyse(&a).unwrap();
        chol.factor_single(&a, 0).unwrap();
        for scale in [1e-40, 1.0, 1e37] {
            let b: Vec<f64> = (0..a.nrows())
                .map(|i| scale * (1.0 + (i as f64).cos()))
                .collect();
            let mut x = b.clone();
            chol.solve_in_place(&mut x);
            let r = residual_of(&a, &x, &b) / (2.0 * scale);
            assert!(
                r < 1e-5 && x.iter().all(|v| v.is_finite()),
                "{scale:e}: {r}"
            );
        }
    }

    #[test]
    fn an_indefinite_matrix_is_a_factorisation_error_naming_the_step() {
        let mut a = grid_laplacian(3, 1, 0.0);
        for v in a.val_mut() {
            *v = -*v;
        }
        let mut chol = SparseCholesky::analyse(&a).unwrap();
        match chol.factor(&a, 7) {
            Err(Error::Factorization { step: 7, .. }) => {}
            other => panic!("{other:?}"),
        }
        // Nothing factored: a solve leaves the right-hand side as it is.
        let mut x = vec![1.0; a.nrows()];
        chol.solve_in_place(&mut x);
        assert!(x.iter().all(|&v| v == 1.0));
    }
}
