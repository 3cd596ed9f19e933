//! Sparse linear solves: faer's supernodal Cholesky with the symbolic analysis done once.

use faer::linalg::solvers::Solve;
use faer::prelude::Reborrow;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::SparseColMat;
use faer::Side;

use crate::error::{Error, Result};

/// A Cholesky factorisation whose symbolic analysis (ordering, elimination tree, supernodes)
/// is computed once per sparsity pattern and reused by every numeric factorisation.
pub struct SparseCholesky {
    symbolic: SymbolicLlt<usize>,
    factor: Option<Llt<usize, f64>>,
    /// The pattern the symbolic analysis was made for (column pointers, row indices).
    pattern: (Vec<usize>, Vec<usize>),
}

impl std::fmt::Debug for SparseCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseCholesky")
            .field("factored", &self.factor.is_some())
            .finish()
    }
}

impl SparseCholesky {
    /// Symbolic analysis of a matrix stored as its lower triangle.
    pub fn analyse(matrix: &SparseColMat<usize, f64>) -> Result<Self> {
        let symbolic = SymbolicLlt::try_new(matrix.symbolic().rb(), Side::Lower).map_err(|e| {
            Error::Factorization {
                step: 0,
                message: format!("{e:?}"),
            }
        })?;
        let pattern = (
            matrix.symbolic().col_ptr().to_vec(),
            matrix.symbolic().row_idx().to_vec(),
        );
        Ok(SparseCholesky {
            symbolic,
            factor: None,
            pattern,
        })
    }

    /// Like [`SparseCholesky::factor`], re-analysing first when `matrix` has another pattern
    /// than the analysed one (contact between bodies adds couplings).
    pub fn factor_any(&mut self, matrix: &SparseColMat<usize, f64>, step: usize) -> Result<()> {
        let same = self.pattern.0 == matrix.symbolic().col_ptr()
            && self.pattern.1 == matrix.symbolic().row_idx();
        if !same {
            *self = SparseCholesky::analyse(matrix)?;
        }
        self.factor(matrix, step)
    }

    /// Numeric factorisation of a matrix with the analysed pattern; `step` names the step in
    /// the error.
    pub fn factor(&mut self, matrix: &SparseColMat<usize, f64>, step: usize) -> Result<()> {
        let llt = Llt::try_new_with_symbolic(self.symbolic.clone(), matrix.rb(), Side::Lower)
            .map_err(|e| Error::Factorization {
                step,
                message: format!(
                    "{e:?}: the iteration matrix is not positive definite (a body with \
                     no mass and no support, or a non-physical material)"
                ),
            })?;
        self.factor = Some(llt);
        Ok(())
    }

    /// Solves `A x = b` in place.
    pub fn solve_in_place(&self, rhs: &mut [f64]) {
        if let Some(llt) = &self.factor {
            llt.solve_in_place(faer::ColMut::from_slice_mut(rhs));
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
}
