//! Rayleigh damping per body, `C = a M + b K` (`RayleighDamping`): a constant matrix on the
//! pattern that M and K share, entering the momentum equation as `C v_alpha` (the velocity at
//! the scheme's collocation instant, where the internal forces are taken) and the iteration
//! matrix as `alpha C`.

use super::{RayleighDamping, Simulation};
use crate::assembly::LinearMatrices;
use crate::dim::{Dim, SpatialDim};
use crate::error::{Error, Result};

/// The values of C on the pattern of M and K, or `None` when no body is damped. Bodies do not
/// share matrix entries, so each entry takes the coefficients of its column's body.
pub(super) fn damping_values(
    damping: &[RayleighDamping],
    node_offsets: &[usize],
    matrices: &LinearMatrices,
    dim: usize,
) -> Option<Vec<f64>> {
    if damping.iter().all(RayleighDamping::is_none) {
        return None;
    }
    let mass = &matrices.mass;
    let col_ptr = mass.symbolic().col_ptr();
    let (m, k) = (mass.val(), matrices.stiffness.val());
    let mut values = vec![0.0; m.len()];
    for j in 0..col_ptr.len() - 1 {
        let node = j / dim;
        let body = node_offsets.partition_point(|&o| o <= node) - 1;
        let RayleighDamping {
            mass: a,
            stiffness: b,
        } = damping[body];
        for e in col_ptr[j]..col_ptr[j + 1] {
            values[e] = a * m[e] + b * k[e];
        }
    }
    Some(values)
}

/// Refuses negative or non-finite coefficients.
pub(super) fn validate(body: &str, damping: &RayleighDamping) -> Result<()> {
    for (key, value, unit) in [
        ("damping.mass", damping.mass, "1/s"),
        ("damping.stiffness", damping.stiffness, "s"),
    ] {
        if !(value.is_finite() && value >= 0.0) {
            return Err(Error::InvalidParameter {
                name: format!("bodies.{body}.{key}"),
                found: format!("{value:e}"),
                expected: format!("a finite number >= 0 [{unit}]"),
            });
        }
    }
    Ok(())
}

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// Adds `scale * C x` to `out` (nothing without damping).
    pub(super) fn add_damping_force(&self, x: &[f64], scale: f64, out: &mut [f64]) {
        let Some(values) = &self.damping else {
            return;
        };
        let mass = &self.matrices.mass;
        let (col_ptr, row_idx) = (mass.symbolic().col_ptr(), mass.symbolic().row_idx());
        // Lower triangle stored: mirror the off-diagonal entries.
        for j in 0..col_ptr.len() - 1 {
            for e in col_ptr[j]..col_ptr[j + 1] {
                let i = row_idx[e];
                let c = scale * values[e];
                out[i] += c * x[j];
                if i != j {
                    out[j] += c * x[i];
                }
            }
        }
    }
}
