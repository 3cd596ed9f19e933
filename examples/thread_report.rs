//! Whether faer's threads change the bits of the sparse Cholesky, and what they save: the
//! iteration matrix `M/h + (alpha^2 h/2) K` of a Hex8 cube, factored (double and single
//! precision) and solved with `Par::Seq` and with `Par::rayon(n)` inside rayon pools of 1, 2,
//! 4 and 8 threads. Prints, per pool, whether the factor values and the solutions have the
//! bits of the sequential ones, and the median times.
//!
//! Run: `cargo run --release --no-default-features --features parallel-factor,internals
//! --example thread_report [-- CELLS_PER_EDGE [REPETITIONS [library|stress]]]` (defaults 20
//! and 3). `library`: only the library's `SparseCholesky`, not faer on its own; its pools take
//! turns, so that a burst of load on a shared machine falls on one repetition of each.
//! `stress`: the threaded factorisation repeated beside a sequential one in another thread,
//! against the sequential factor's solution.

mod common;

use common::median;
use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{SparseColMat, SparseColMatRef};
use faer::{Conj, Par, Side};
use softway::prelude::*;
use softway::solver::SparseCholesky;

fn factor<T: faer::traits::RealField + Copy + Default>(
    symbolic: &SymbolicCholesky<usize>,
    a: SparseColMatRef<'_, usize, T>,
    par: Par,
) -> Vec<T> {
    let mut values = vec![T::default(); symbolic.len_val()];
    let mut scratch =
        MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<T>(par, Default::default()));
    symbolic
        .factorize_numeric_llt::<T>(
            &mut values,
            a,
            Side::Lower,
            Default::default(),
            par,
            MemStack::new(&mut scratch),
            Default::default(),
        )
        .expect("positive definite");
    values
}

fn solve<T: faer::traits::RealField + Copy>(
    symbolic: &SymbolicCholesky<usize>,
    values: &[T],
    rhs: &mut [T],
    par: Par,
) {
    let mut scratch = MemBuffer::new(symbolic.solve_in_place_scratch::<T>(1, par));
    LltRef::new(symbolic, values).solve_in_place_with_conj(
        Conj::No,
        faer::ColMut::from_slice_mut(rhs).as_mat_mut(),
        par,
        MemStack::new(&mut scratch),
    );
}

fn bits64(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn bits32(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn timed<R>(reps: usize, mut f: impl FnMut() -> R) -> (R, f64) {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..reps {
        let t = Instant::now();
        last = Some(f());
        times.push(t.elapsed().as_secs_f64());
    }
    (last.expect("one repetition"), median(times))
}

fn main() -> Result<()> {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(20);
    let a = common::cube_iteration_matrix(n)?;
    let single: Vec<f32> = a.val().iter().map(|&v| v as f32).collect();
    let a32 = SparseColMatRef::new(a.symbolic(), &single);
    let b: Vec<f64> = (0..a.nrows()).map(|i| (i as f64 * 0.1).sin()).collect();
    let b32: Vec<f32> = b.iter().map(|&v| v as f32).collect();
    println!("hex8 cube {n}^3 cells, {} unknowns", a.nrows());

    let reps: usize = std::env::args()
        .nth(2)
        .and_then(|a| a.parse().ok())
        .unwrap_or(3);
    if std::env::args().nth(3).is_some_and(|a| a == "stress") {
        return stress(&a, &b, reps);
    }
    if std::env::args().nth(3).is_none_or(|a| a != "library") {
        faer_direct(&a, a32, &b, &b32, reps);
    }

    // The library's factorisation (nested dissection), in each pool.
    let pools: Vec<_> = [1, 2, 4, 8]
        .into_iter()
        .map(|threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool")
        })
        .collect();
    let mut chol = SparseCholesky::analyse_with(&a, FillOrdering::NestedDissection, 3)?;
    let mut times = vec![[Vec::new(), Vec::new(), Vec::new(), Vec::new()]; pools.len()];
    let mut solutions: Vec<Vec<u64>> = vec![Vec::new(); pools.len()];
    for _ in 0..reps {
        for (p, pool) in pools.iter().enumerate() {
            pool.install(|| -> Result<()> {
                let t = Instant::now();
                chol.factor(&a, 0)?;
                times[p][0].push(t.elapsed().as_secs_f64());
                let mut x = b.clone();
                let t = Instant::now();
                chol.solve_in_place(&mut x);
                times[p][1].push(t.elapsed().as_secs_f64());
                let t = Instant::now();
                chol.factor_single(&a, 0)?;
                times[p][2].push(t.elapsed().as_secs_f64());
                let mut x32 = b.clone();
                let t = Instant::now();
                chol.solve_in_place(&mut x32);
                times[p][3].push(t.elapsed().as_secs_f64());
                let mut bits = bits64(&x);
                bits.extend(bits64(&x32));
                solutions[p] = bits;
                Ok(())
            })?;
        }
    }
    for (p, pool) in pools.iter().enumerate() {
        let [t, s, t32, s32] = times[p].clone().map(median);
        println!(
            "SparseCholesky (nested dissection, {} entries), {} threads: factor {t:.3} s (f32 {t32:.3} s), \
             solve {s:.4} s (f32 {s32:.4} s); solutions equal to 1 thread's: {}",
            chol.factor_entries(),
            pool.current_num_threads(),
            solutions[p] == solutions[0]
        );
    }
    Ok(())
}

/// faer on its own (AMD ordering): its factor values, and its threaded solve, against
/// `Par::Seq`'s.
fn faer_direct(
    a: &SparseColMat<usize, f64>,
    a32: SparseColMatRef<'_, usize, f32>,
    b: &[f64],
    b32: &[f32],
    reps: usize,
) {
    let symbolic = factorize_symbolic_cholesky(
        a.symbolic(),
        Side::Lower,
        SymmetricOrdering::Amd,
        Default::default(),
    )
    .expect("symbolic analysis");
    let (l_seq, t_seq) = timed(reps, || factor::<f64>(&symbolic, a.as_ref(), Par::Seq));
    let (l32_seq, t32_seq) = timed(reps, || factor::<f32>(&symbolic, a32, Par::Seq));
    let (x_seq, s_seq) = timed(reps, || {
        let mut x = b.to_vec();
        solve(&symbolic, &l_seq, &mut x, Par::Seq);
        x
    });
    let (x32_seq, s32_seq) = timed(reps, || {
        let mut x = b32.to_vec();
        solve(&symbolic, &l32_seq, &mut x, Par::Seq);
        x
    });
    println!(
        "faer, AMD, {} factor entries; Par::Seq: factor {t_seq:.3} s (f32 {t32_seq:.3} s), solve {s_seq:.4} s (f32 {s32_seq:.4} s)",
        symbolic.len_val()
    );
    for threads in [1, 2, 4, 8] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool");
        pool.install(|| {
            let par = Par::rayon(0);
            let (l, t) = timed(reps, || factor::<f64>(&symbolic, a.as_ref(), par));
            let (l32, t32) = timed(reps, || factor::<f32>(&symbolic, a32, par));
            // The sequential factor solved with threads, to separate the two.
            let (x, s) = timed(reps, || {
                let mut x = b.to_vec();
                solve(&symbolic, &l_seq, &mut x, par);
                x
            });
            let (x32, s32) = timed(reps, || {
                let mut x = b32.to_vec();
                solve(&symbolic, &l32_seq, &mut x, par);
                x
            });
            let mut x_seq_solve = b.to_vec();
            solve(&symbolic, &l, &mut x_seq_solve, Par::Seq);
            let differing = |p: &[u64], q: &[u64]| p.iter().zip(q).filter(|(a, b)| a != b).count();
            println!(
                "{threads} threads, Par::rayon: factor {t:.3} s (f32 {t32:.3} s), solve {s:.4} s (f32 {s32:.4} s); \
                 factor bits equal: f64 {} ({} entries differ), f32 {}; Par::Seq solve on it equal: {}; \
                 threaded solve bits equal: f64 {} ({} entries differ), f32 {}",
                bits64(&l) == bits64(&l_seq),
                differing(&bits64(&l), &bits64(&l_seq)),
                bits32(&l32) == bits32(&l32_seq),
                bits64(&x_seq_solve) == bits64(&x_seq),
                bits64(&x) == bits64(&x_seq),
                differing(&bits64(&x), &bits64(&x_seq)),
                bits32(&x32) == bits32(&x32_seq),
            );
        });
    }
}

/// The threaded factorisation repeated in a pool of 2 threads while another thread factors
/// sequentially: whether every repetition gives the bits of the first.
fn stress(a: &SparseColMat<usize, f64>, b: &[f64], reps: usize) -> Result<()> {
    let solution = |chol: &SparseCholesky| {
        let mut x = b.to_vec();
        chol.solve_in_place(&mut x);
        bits64(&x)
    };
    let mut reference = SparseCholesky::analyse_with(a, FillOrdering::NestedDissection, 3)?;
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a thread pool")
        .install(|| reference.factor(a, 0))?;
    let expected = solution(&reference);
    let stop = std::sync::atomic::AtomicBool::new(false);
    std::thread::scope(|scope| -> Result<()> {
        scope.spawn(|| {
            let mut other = reference.unfactored_copy();
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(1)
                    .build()
                    .expect("a thread pool")
                    .install(|| other.factor(a, 0))
                    .expect("factored");
            }
        });
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .expect("a thread pool");
        let mut chol = reference.unfactored_copy();
        let mut differ = 0;
        for _ in 0..reps {
            pool.install(|| chol.factor(a, 0))?;
            differ += usize::from(solution(&chol) != expected);
        }
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        println!(
            "stress: {differ} of {reps} threaded factorisations differ from the sequential one"
        );
        Ok(())
    })
}
