//! How far a body has turned: the rotation of the best fit of its current configuration to
//! its reference one. Small-strain laws see a finite rotation as strain; the run warns when a
//! body of such a law turns past a few degrees. The same fit takes the motion of a body of an
//! updated-Lagrangian law back to the reference for the stiffness terms of the scheme's
//! conserved energy ([`Simulation::stiffness_fields`]).

use nalgebra::{SMatrix, SVector};

use super::{BodyId, Simulation};
use crate::dim::{Dim, SpatialDim};
use crate::error::Result;

/// A best fit: the rotation, the reference centroid and the current one.
type BestFit<const D: usize> = (SMatrix<f64, D, D>, SVector<f64, D>, SVector<f64, D>);

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
        let Some((r, _, _)) = self.best_fit(index, &self.state.displacement) else {
            return 0.0;
        };
        // trace R = 2 cos(theta) in 2D, 1 + 2 cos(theta) in 3D.
        let cos = ((r.trace() - (D as f64 - 2.0)) / 2.0).clamp(-1.0, 1.0);
        cos.acos()
    }

    /// The rotation R that best maps the body's reference configuration onto the one at
    /// displacements `u` (the polar factor of `sum (x - c)(X - c0)^T`), with the centroids `c0`
    /// of the reference and `c` of that configuration; `None` for a body collapsed to a point.
    fn best_fit(&self, index: usize, u: &[f64]) -> Option<BestFit<D>> {
        let nodes = self.nodes_of(index);
        let x = |n: usize| self.reference[n] + Self::node_vector(u, n);
        let count = nodes.len().max(1) as f64;
        let c0 = nodes
            .clone()
            .map(|n| self.reference[n])
            .sum::<SVector<f64, D>>()
            / count;
        let c = nodes.clone().map(x).sum::<SVector<f64, D>>() / count;
        let mut a = SMatrix::<f64, D, D>::zeros();
        for n in nodes.clone() {
            a += (x(n) - c) * (self.reference[n] - c0).transpose();
        }
        // The polar factor by Newton's iteration R <- (R + R^-T) / 2 (quadratic; a handful of
        // iterations from the normalised matrix).
        let scale = a.norm();
        if !(scale > 0.0) {
            return None;
        }
        let mut r = a / scale;
        for _ in 0..50 {
            let inverse = <Dim<D>>::inverse(&r)?;
            let next = (r + inverse.transpose()) * 0.5;
            let change = (next - r).norm();
            r = next;
            if change < 1e-12 {
                break;
            }
        }
        Some((r, c0, c))
    }

    /// The fields that the stiffness terms of the scheme's conserved energy
    /// ([`Self::scheme_energy`]) take K of, at displacements `u` and velocities `v`: each
    /// body's displacement and velocity with its mean removed (K annihilates translations;
    /// removing them avoids the cancellation of large equal terms). Bodies of
    /// updated-Lagrangian laws, which may turn by any angle, are taken back by their best-fit
    /// rotation first (corotated: `R^T (x - c) - (X - c0)` and `R^T v`), since the reference
    /// K does not annihilate a finite rotation: a rigid motion then gives zero, and a small
    /// one the linear law's terms. (Left out, the terms were zero and Q was E for them, whose
    /// swing at a start from rest, 6 % of a tiny input, read as energy created.)
    pub(super) fn stiffness_fields(&self, u: &[f64], v: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (mut wu, mut wv) = (u.to_vec(), v.to_vec());
        for body in 0..self.model.bodies.len() {
            let nodes = self.nodes_of(body);
            let count = nodes.len().max(1) as f64;
            let corotated = if self.integration[body].law.updated_lagrangian() {
                self.best_fit(body, u)
            } else {
                None
            };
            if let Some((r, c0, c)) = corotated {
                let rt = r.transpose();
                for n in nodes.clone() {
                    let x = self.reference[n] + Self::node_vector(u, n);
                    let du = rt * (x - c) - (self.reference[n] - c0);
                    let dv = rt * Self::node_vector(v, n);
                    for k in 0..D {
                        wu[n * D + k] = du[k];
                        wv[n * D + k] = dv[k];
                    }
                }
            }
            for w in [&mut wu, &mut wv] {
                for k in 0..D {
                    let mean = nodes.clone().map(|n| w[n * D + k]).sum::<f64>() / count;
                    for n in nodes.clone() {
                        w[n * D + k] -= mean;
                    }
                }
            }
        }
        (wu, wv)
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
