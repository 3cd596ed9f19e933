//! A read-only view of the symmetric sparse matrices a simulation assembles (mass,
//! stiffness), so that no sparse-library type appears in the public API.

use faer::sparse::SparseColMat;

/// A view of a symmetric sparse matrix, stored as its lower triangle in compressed sparse
/// columns (row indices sorted within each column).
#[derive(Debug, Clone, Copy)]
pub struct SymmetricMatrix<'a> {
    size: usize,
    col_ptr: &'a [usize],
    row_idx: &'a [usize],
    values: &'a [f64],
}

impl<'a> SymmetricMatrix<'a> {
    pub(super) fn of(m: &'a SparseColMat<usize, f64>) -> Self {
        SymmetricMatrix {
            size: m.nrows(),
            col_ptr: m.symbolic().col_ptr(),
            row_idx: m.symbolic().row_idx(),
            values: m.val(),
        }
    }

    /// Number of rows (and columns).
    pub fn size(&self) -> usize {
        self.size
    }

    /// Start of each column in [`SymmetricMatrix::row_indices`] (`size + 1` entries).
    pub fn column_starts(&self) -> &'a [usize] {
        self.col_ptr
    }

    /// Row index of each stored entry (lower triangle: row >= column).
    pub fn row_indices(&self) -> &'a [usize] {
        self.row_idx
    }

    /// Value of each stored entry.
    pub fn values(&self) -> &'a [f64] {
        self.values
    }

    /// `A x`.
    pub fn mul(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.size];
        for j in 0..self.size {
            for k in self.col_ptr[j]..self.col_ptr[j + 1] {
                let i = self.row_idx[k];
                y[i] += self.values[k] * x[j];
                if i != j {
                    y[j] += self.values[k] * x[i];
                }
            }
        }
        y
    }

    /// `x^T A y`.
    pub fn dot(&self, x: &[f64], y: &[f64]) -> f64 {
        x.iter().zip(self.mul(y)).map(|(a, b)| a * b).sum()
    }

    /// The full dense matrix.
    pub fn to_dense(&self) -> nalgebra::DMatrix<f64> {
        let mut m = nalgebra::DMatrix::zeros(self.size, self.size);
        for j in 0..self.size {
            for k in self.col_ptr[j]..self.col_ptr[j + 1] {
                m[(self.row_idx[k], j)] = self.values[k];
                m[(j, self.row_idx[k])] = self.values[k];
            }
        }
        m
    }
}
