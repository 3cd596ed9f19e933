//! How far a body has turned: the rotation of the best fit of its current configuration to
//! its reference one. Small-strain laws see a finite rotation as strain; the run warns when a
//! body of such a law turns past a few degrees.

use nalgebra::SMatrix;

use super::{BodyId, Simulation};
use crate::dim::{Dim, SpatialDim};
use crate::error::Result;

/// The rotation past which a body of a small-strain law is reported (rad) (5 degrees: the
/// strain a rigid rotation theta fakes is about theta^2 / 2 = 0.4 %).
pub const SMALL_STRAIN_ROTATION_LIMIT: f64 = 5.0 * std::f64::consts::PI / 180.0;

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// The angle (rad) of the rotation that best maps the body's reference configuration onto
    /// its current one (the polar factor of `sum (x - x_mean)(X - X_mean)^T`).
    pub fn body_rotation(&self, body: BodyId) -> Result<f64> {
        Ok(self.rotation_of_body(self.body_index(body)?))
    }

    /// [`Self::body_rotation`] of the body at position `index` of the model.
    pub(crate) fn rotation_of_body(&self, index: usize) -> f64 {
        let nodes = self.nodes_of(index);
        let x = self.positions();
        let count = nodes.len().max(1) as f64;
        let mean = |p: &dyn Fn(usize) -> nalgebra::SVector<f64, D>| {
            nodes.clone().map(p).sum::<nalgebra::SVector<f64, D>>() / count
        };
        let (c0, c) = (mean(&|n| self.reference[n]), mean(&|n| x[n]));
        let mut a = SMatrix::<f64, D, D>::zeros();
        for n in nodes.clone() {
            a += (x[n] - c) * (self.reference[n] - c0).transpose();
        }
        // The polar factor by Newton's iteration R <- (R + R^-T) / 2 (quadratic; a handful of
        // iterations from the normalised matrix).
        let scale = a.norm();
        if !(scale > 0.0) {
            return 0.0;
        }
        let mut r = a / scale;
        for _ in 0..50 {
            let Some(inverse) = <Dim<D>>::inverse(&r) else {
                return 0.0;
            };
            let next = (r + inverse.transpose()) * 0.5;
            let change = (next - r).norm();
            r = next;
            if change < 1e-12 {
                break;
            }
        }
        // trace R = 2 cos(theta) in 2D, 1 + 2 cos(theta) in 3D.
        let cos = ((r.trace() - (D as f64 - 2.0)) / 2.0).clamp(-1.0, 1.0);
        cos.acos()
    }

    /// The bodies of small-strain laws that have turned past
    /// [`SMALL_STRAIN_ROTATION_LIMIT`], with their rotation (rad).
    pub fn small_strain_rotations(&self) -> Vec<(BodyId, f64)> {
        (0..self.model.bodies.len())
            .filter(|&b| !self.integration[b].law.updated_lagrangian())
            .map(|b| (self.body_at(b), self.rotation_of_body(b)))
            .filter(|&(_, angle)| angle > SMALL_STRAIN_ROTATION_LIMIT)
            .collect()
    }
}
