//! The triangular solve pair `L L^T x = b` of a supernodal factor, with independent subtrees
//! of the elimination tree solved on the rayon pool's threads (feature `parallel`).
//!
//! faer's threaded solve splits each matrix-vector product's depth among the threads and adds
//! their partial sums, so its last bits follow the thread count (the module above). Here the
//! work is split by the tree instead, the same way for any thread count: the factor's
//! supernodes are cut into tasks, disjoint subtrees of about equal work, and the rest (the
//! separators above them, the top). Each task works on its own copy of its unknowns. Going
//! down (`L y = b`), a task updates its own unknowns and adds what it sends up into a buffer of
//! its own; the buffers are then added to the top's unknowns in the tasks' order, and the top's
//! supernodes are solved in sequence. Going up (`L^T x = y`), the top first, then each task
//! reads the top's values and writes only its own. Each task's arithmetic is the same whichever
//! thread runs it, and so is the order of every sum: one thread or eight give the same bits.

use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;
use faer::{Accum, MatMut, MatRef, Par};

use crate::parallel::for_each_job;

/// The factor's precisions (f64, f32).
pub(super) trait Real:
    faer::traits::RealField
    + Copy
    + Send
    + Sync
    + std::ops::AddAssign
    + std::ops::SubAssign
    + std::ops::Neg<Output = Self>
{
    const ZERO: Self;
    const ONE: Self;
}

impl Real for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
}

impl Real for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
}

/// Tasks (disjoint subtrees) to cut the tree into: a few per thread of a small machine, so
/// that uneven subtrees still share out evenly.
const TASKS: usize = 8;

/// The split of a supernodal elimination tree into independent subtrees.
#[derive(Debug)]
pub(super) struct TreeSplit {
    /// Each task's supernodes, ascending (children before parents).
    tasks: Vec<Vec<usize>>,
    /// Each task's columns, ascending: what it gathers from `x` and scatters back.
    task_columns: Vec<Vec<usize>>,
    /// The supernodes above every task, ascending.
    top: Vec<usize>,
    /// The columns of the top supernodes, ascending.
    top_columns: Vec<usize>,
    /// Per column of a task: its place in the task's columns.
    slot: Vec<usize>,
    /// Per supernode of a task, its rows below as places in the task's work vector: its own
    /// columns first, then the top's (`task_columns[t].len() + place in top_columns`).
    mapped_rows: Vec<Vec<u32>>,
}

/// One supernode's dense block: `(first column, columns, rows below, values offset)`.
fn block(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    s: usize,
) -> (usize, usize, &[usize], usize) {
    let begin = symbolic.supernode_begin()[s];
    let end = symbolic.supernode_end()[s];
    let rows = &symbolic.row_idx()
        [symbolic.col_ptr_for_row_idx()[s]..symbolic.col_ptr_for_row_idx()[s + 1]];
    (begin, end - begin, rows, symbolic.col_ptr_for_val()[s])
}

impl TreeSplit {
    /// The split of `symbolic`'s tree, or `None` when it has too little to share (fewer than
    /// two subtrees).
    pub(super) fn new(symbolic: &SymbolicSupernodalCholesky<usize>) -> Option<Self> {
        let n = symbolic.n_supernodes();
        let columns = symbolic.nrows();
        let mut supernode_of = vec![0usize; columns];
        for s in 0..n {
            let (begin, width, _, _) = block(symbolic, s);
            supernode_of[begin..begin + width].fill(s);
        }
        // The parent is the supernode of the first row below the block (a later one).
        let mut parent = vec![None; n];
        let mut children = vec![Vec::new(); n];
        let mut work = vec![0usize; n];
        for s in 0..n {
            let (_, width, rows, _) = block(symbolic, s);
            work[s] += width * (width + rows.len());
            if let Some(&r) = rows.first() {
                let p = supernode_of[r];
                if p <= s {
                    return None;
                }
                parent[s] = Some(p);
                children[p].push(s);
                let w = work[s];
                work[p] += w;
            }
        }
        let total: usize = (0..n)
            .filter(|&s| parent[s].is_none())
            .map(|s| work[s])
            .sum();
        // Open the heaviest subtree into its children until each is at most a TASKS-th of
        // the whole (or a leaf).
        let mut roots: Vec<usize> = (0..n).filter(|&s| parent[s].is_none()).collect();
        let mut top = Vec::new();
        loop {
            let (k, &heaviest) = roots
                .iter()
                .enumerate()
                .max_by_key(|&(_, &s)| (work[s], std::cmp::Reverse(s)))?;
            if work[heaviest] * TASKS <= total || children[heaviest].is_empty() {
                break;
            }
            roots.swap_remove(k);
            top.push(heaviest);
            roots.extend(&children[heaviest]);
        }
        if roots.len() < 2 {
            return None;
        }
        roots.sort_unstable();
        top.sort_unstable();
        let mut owner = vec![usize::MAX; columns];
        let mut slot = vec![0usize; columns];
        let mut tasks = Vec::with_capacity(roots.len());
        let mut task_columns = Vec::with_capacity(roots.len());
        for (t, &root) in roots.iter().enumerate() {
            let mut members = vec![root];
            let mut k = 0;
            while k < members.len() {
                members.extend(&children[members[k]]);
                k += 1;
            }
            members.sort_unstable();
            let mut own = Vec::new();
            for &s in &members {
                let (begin, width, _, _) = block(symbolic, s);
                own.extend(begin..begin + width);
            }
            own.sort_unstable();
            for (k, &c) in own.iter().enumerate() {
                owner[c] = t;
                slot[c] = k;
            }
            tasks.push(members);
            task_columns.push(own);
        }
        let mut top_columns = Vec::new();
        for &s in &top {
            let (begin, width, _, _) = block(symbolic, s);
            top_columns.extend(begin..begin + width);
        }
        top_columns.sort_unstable();
        let mut top_slot = vec![0usize; columns];
        for (k, &c) in top_columns.iter().enumerate() {
            top_slot[c] = k;
        }
        let mut mapped_rows = vec![Vec::new(); n];
        for (t, members) in tasks.iter().enumerate() {
            let own = task_columns[t].len();
            for &s in members {
                let (_, _, rows, _) = block(symbolic, s);
                let mapped = rows
                    .iter()
                    .map(|&r| {
                        if owner[r] == t {
                            slot[r]
                        } else {
                            own + top_slot[r]
                        }
                    })
                    .map(|k| u32::try_from(k).ok())
                    .collect::<Option<Vec<u32>>>()?;
                mapped_rows[s] = mapped;
            }
        }
        Some(TreeSplit {
            tasks,
            task_columns,
            top,
            top_columns,
            slot,
            mapped_rows,
        })
    }

    /// Solves `L L^T x = b` in place (`x` in the factor's permuted order), `values` the
    /// factor's values in any precision.
    pub(super) fn solve<T: Real>(
        &self,
        symbolic: &SymbolicSupernodalCholesky<usize>,
        values: &[T],
        x: &mut [T],
    ) {
        // Each task's work vector: its own unknowns, then the top's (a buffer of what it
        // sends up going down; the top's values going up).
        let tops = self.top_columns.len();
        let mut works: Vec<Vec<T>> = self
            .task_columns
            .iter()
            .map(|own| {
                let mut work: Vec<T> = own.iter().map(|&c| x[c]).collect();
                work.resize(own.len() + tops, T::ZERO);
                work
            })
            .collect();
        for_each_job(works.iter_mut().enumerate().collect(), |(t, work)| {
            let mut product = Vec::new();
            for &s in &self.tasks[t] {
                let (begin, width, _, _) = block(symbolic, s);
                let at = self.slot[begin];
                solve_diagonal(symbolic, values, s, &mut work[at..at + width]);
                below_times(symbolic, values, s, &work[at..at + width], &mut product);
                for (&k, &p) in self.mapped_rows[s].iter().zip(&product) {
                    work[k as usize] -= p;
                }
            }
        });
        // The top's buffers hold minus what each task sent: added in the tasks' order.
        for (work, own) in works.iter().zip(&self.task_columns) {
            for (&c, &v) in self.top_columns.iter().zip(&work[own.len()..]) {
                x[c] += v;
            }
        }
        let mut product = Vec::new();
        for &s in &self.top {
            let (begin, width, rows, _) = block(symbolic, s);
            solve_diagonal(symbolic, values, s, &mut x[begin..begin + width]);
            below_times(symbolic, values, s, &x[begin..begin + width], &mut product);
            for (&r, &p) in rows.iter().zip(&product) {
                x[r] -= p;
            }
        }
        // Up: the top, then the tasks reading the top's values.
        let mut gathered = Vec::new();
        for &s in self.top.iter().rev() {
            let (begin, width, rows, _) = block(symbolic, s);
            gathered.clear();
            gathered.extend(rows.iter().map(|&r| x[r]));
            up(symbolic, values, s, &gathered, &mut x[begin..begin + width]);
        }
        for_each_job(works.iter_mut().enumerate().collect(), |(t, work)| {
            let own = self.task_columns[t].len();
            for (w, &c) in work[own..].iter_mut().zip(&self.top_columns) {
                *w = x[c];
            }
            let mut gathered = Vec::new();
            for &s in self.tasks[t].iter().rev() {
                let (begin, width, _, _) = block(symbolic, s);
                gathered.clear();
                gathered.extend(self.mapped_rows[s].iter().map(|&k| work[k as usize]));
                let at = self.slot[begin];
                up(symbolic, values, s, &gathered, &mut work[at..at + width]);
            }
        });
        for (own, work) in self.task_columns.iter().zip(&works) {
            for (&c, &v) in own.iter().zip(work) {
                x[c] = v;
            }
        }
    }
}

/// Supernode `s`'s block of the factor: its diagonal part and its rows below.
fn parts<'v, T: Real>(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &'v [T],
    s: usize,
) -> (MatRef<'v, T>, MatRef<'v, T>) {
    let (_, width, rows, at) = block(symbolic, s);
    let l = MatRef::from_column_major_slice(
        &values[at..at + width * (width + rows.len())],
        width + rows.len(),
        width,
    );
    l.split_at_row(width)
}

/// `x_s <- L_ss^-1 x_s`.
fn solve_diagonal<T: Real>(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &[T],
    s: usize,
    mine: &mut [T],
) {
    let (diagonal, _) = parts(symbolic, values, s);
    let width = mine.len();
    solve_lower_triangular_in_place(
        diagonal,
        MatMut::from_column_major_slice_mut(mine, width, 1),
        Par::Seq,
    );
}

/// `product <- L_below x_s`, one value per row below supernode `s`.
fn below_times<T: Real>(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &[T],
    s: usize,
    mine: &[T],
    product: &mut Vec<T>,
) {
    let (_, below) = parts(symbolic, values, s);
    product.clear();
    product.resize(below.nrows(), T::ZERO);
    if !product.is_empty() {
        matmul(
            MatMut::from_column_major_slice_mut(product, below.nrows(), 1),
            Accum::Replace,
            below,
            MatRef::from_column_major_slice(mine, mine.len(), 1),
            T::ONE,
            Par::Seq,
        );
    }
}

/// Supernode `s` going up: its rows below (`gathered`) subtracted through `L^T`, then its
/// diagonal block solved, on its own unknowns `mine`.
fn up<T: Real>(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &[T],
    s: usize,
    gathered: &[T],
    mine: &mut [T],
) {
    let (diagonal, below) = parts(symbolic, values, s);
    let width = mine.len();
    let mut mine = MatMut::from_column_major_slice_mut(mine, width, 1);
    if !gathered.is_empty() {
        matmul(
            mine.as_mut(),
            Accum::Add,
            below.transpose(),
            MatRef::from_column_major_slice(gathered, gathered.len(), 1),
            -T::ONE,
            Par::Seq,
        );
    }
    solve_upper_triangular_in_place(diagonal.transpose(), mine, Par::Seq);
}
