//! Prints what the fill-reducing ordering does to the sparse Cholesky factorisation of the
//! iteration matrix `M/h + (alpha^2 h/2) K` of a Hex8 cube: factor entries, symbolic analysis,
//! numeric factorisation (double and single precision) and one solve, per ordering.
//!
//! Run: `cargo run --release --example ordering_report [-- CELLS_PER_EDGE]` (default 20).

mod common;

use common::median;
use std::time::Instant;

use softway::prelude::*;
use softway::solver::SparseCholesky;

fn main() -> Result<()> {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(20);
    let a = common::cube_iteration_matrix(n)?;
    println!("hex8 cube {n}^3 cells, {} unknowns", a.nrows());
    let b: Vec<f64> = (0..a.nrows()).map(|i| (i as f64 * 0.1).sin()).collect();
    let median_solve = |chol: &SparseCholesky| {
        median(
            (0..5)
                .map(|_| {
                    let mut x = b.clone();
                    let t = Instant::now();
                    chol.solve_in_place(&mut x);
                    t.elapsed().as_secs_f64()
                })
                .collect(),
        )
    };
    for ordering in [FillOrdering::NestedDissection, FillOrdering::MinimumDegree] {
        let t = Instant::now();
        let mut chol = SparseCholesky::analyse_with(&a, ordering, 3)?;
        let analysis = t.elapsed().as_secs_f64();
        let t = Instant::now();
        chol.factor(&a, 0)?;
        let double = t.elapsed().as_secs_f64();
        let solve = median_solve(&chol);
        let t = Instant::now();
        chol.factor_single(&a, 0)?;
        let single = t.elapsed().as_secs_f64();
        let solve_single = median_solve(&chol);
        println!(
            "{:>18}: factor entries {:>10} ({:.0} MiB); analysis {analysis:.3} s; numeric factorisation {double:.3} s (single precision {single:.3} s); solve {solve:.4} s (single {solve_single:.4} s)",
            ordering.name(),
            chol.factor_entries(),
            chol.factor_entries() as f64 * 8.0 / 1048576.0,
        );
    }
    Ok(())
}
