//! Rayleigh damping per body, `C = a M + b K` (`RayleighDamping`): a constant matrix on the
//! pattern that M and K share, entering the momentum equation as `C v_alpha` (the velocity at
//! the scheme's collocation instant, where the internal forces are taken) and the iteration
//! matrix as `alpha C`.

use faer::sparse::SparseColMat;

use super::RayleighDamping;
use crate::assembly::LinearMatrices;
use crate::error::{Error, Result};

/// C on the pattern of M and K (lower triangle, as they are), or `None` when no body is damped.
/// Bodies do not share matrix entries, so each entry takes the coefficients of its column's body.
pub(super) fn damping_matrix(
    damping: &[RayleighDamping],
    node_offsets: &[usize],
    matrices: &LinearMatrices,
    dim: usize,
) -> Option<SparseColMat<usize, f64>> {
    if damping.iter().all(RayleighDamping::is_none) {
        return None;
    }
    let mut c = matrices.mass.clone();
    let col_ptr = c.symbolic().col_ptr().to_vec();
    let (m, k) = (matrices.mass.val(), matrices.stiffness.val());
    let values = c.val_mut();
    for j in 0..col_ptr.len() - 1 {
        let node = j / dim;
        let body = super::body_of(node_offsets, node);
        let RayleighDamping {
            mass: a,
            stiffness: b,
        } = damping[body];
        for e in col_ptr[j]..col_ptr[j + 1] {
            values[e] = a * m[e] + b * k[e];
        }
    }
    Some(c)
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
