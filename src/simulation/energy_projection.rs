//! [`ProjectionEnergy::Bounded`](crate::contact::ProjectionEnergy::Bounded): implicit
//! projection's end-of-step position correction puts energy into the scheme's conserved
//! energy Q where it moves a compressed contact patch (the soft cube at h = 1/60 s: 0.94 J at
//! its second landing, 8.6 % of the input; the account books it exactly, as negative
//! dissipation). Bounded, the correction gives back at most what the run has dissipated so far
//! (the inelastic stops of the contact nodes); the excess is taken back out of each body's
//! deformation velocity, as the projection methods of geometric integration return a state to
//! an invariant's level set: the velocity minus the body's rigid motion (the lumped masses'
//! best fit, translation and rotation, so that linear and angular momentum are kept) is
//! scaled by the `s` that removes it (Q is quadratic in `s`: three evaluations fit it). Where
//! no `s` can remove it all, the one that removes most. Unbounded (a first version), the
//! bar impact's contact force fell 6 % short of the analytic one: its stop and correction
//! together are what that force needs.

use nalgebra::{Matrix3, SVector, Vector3};

use super::Simulation;
use crate::dim::{Dim, Kinematics, SpatialDim};

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// Takes the energy the projection created in the bodies (from `u_before` to `u1`, with
    /// the external forces `f_ext`'s work on that move deducted), beyond `allowance`, out of
    /// their deformation velocity in `v1`, each body in proportion to what it was given.
    /// `allowance` is what the run has dissipated so far: the correction may give back what
    /// the contact's inelastic stops took (the bar impact's stop and correction together are
    /// what its analytic contact force needs), not more. Returns Q at `(u_before, v1)` and at
    /// `(u1, v1)` as they leave, where it measured both (one body, `v1` left as it was), for
    /// the correction's booking.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn remove_projection_energy(
        &self,
        u_before: &[f64],
        u1: &[f64],
        v1: &mut [f64],
        f_ext: &[f64],
        h: f64,
        history: &[f64],
        allowance: f64,
    ) -> Option<(f64, f64)> {
        let dofs_of = |b: usize| self.nodes_of(b).start * D..self.nodes_of(b).end * D;
        let one_body = self.model.bodies.len() == 1;
        let moved: Vec<bool> = (0..self.model.bodies.len())
            .map(|b| dofs_of(b).any(|i| u1[i] != u_before[i]))
            .collect();
        if !one_body && !moved.contains(&true) {
            // Nothing to bound, and no value the booking could reuse.
            return None;
        }
        let q_before = self.scheme_energy_at(u_before, v1, h, history);
        // Q at (u1, v1) where one body holds every unknown (then `u_mixed` is `u1`).
        let mut q_after = one_body.then_some(q_before);
        let created: Vec<f64> = (0..self.model.bodies.len())
            .map(|b| {
                if !moved[b] {
                    return 0.0;
                }
                let dofs = dofs_of(b);
                // Q is a sum over bodies: body b's part of the change, the others unmoved.
                let mut u_mixed = u_before.to_vec();
                u_mixed[dofs.clone()].copy_from_slice(&u1[dofs.clone()]);
                let work: f64 = dofs.map(|i| f_ext[i] * (u1[i] - u_before[i])).sum();
                let q_mixed = self.scheme_energy_at(&u_mixed, v1, h, history);
                if let Some(q) = q_after.as_mut() {
                    *q = q_mixed;
                }
                (q_mixed - q_before - work).max(0.0)
            })
            .collect();
        let total: f64 = created.iter().sum();
        let excess = total - allowance.max(0.0);
        if !(excess > 0.0) {
            return q_after.map(|q| (q_before, q));
        }
        for (b, &given) in created.iter().enumerate() {
            let remove = given * excess / total;
            if !(remove > 0.0) {
                continue;
            }
            let dofs = dofs_of(b);
            let rigid = self.rigid_velocity(b, u1, v1);
            let with_scale = |s: f64| -> Vec<f64> {
                let mut v = v1.to_vec();
                for i in dofs.clone() {
                    v[i] = rigid[i - dofs.start] + s * (v1[i] - rigid[i - dofs.start]);
                }
                v
            };
            let q = |s: f64| self.scheme_energy_at(u1, &with_scale(s), h, history);
            let (q0, qh, q1) = (q(0.0), q(0.5), q(1.0));
            let (d1, dh) = (q1 - q0, qh - q0);
            let c = 2.0 * (d1 - 2.0 * dh);
            let bq = d1 - c;
            if !(c > 0.0) {
                continue;
            }
            // c s^2 + b s + q0 = q1 - remove.
            let disc = bq * bq - 4.0 * c * (q0 - q1 + remove);
            let s = if disc >= 0.0 {
                (-bq + disc.sqrt()) / (2.0 * c)
            } else {
                -bq / (2.0 * c)
            };
            let v = with_scale(s.clamp(0.0, 1.0));
            v1[dofs.clone()].copy_from_slice(&v[dofs]);
        }
        None
    }

    /// The rigid velocity field that best fits body `b`'s velocities `v` at displacements `u`
    /// (lumped masses: the same linear and angular momentum), per dof of the body.
    fn rigid_velocity(&self, b: usize, u: &[f64], v: &[f64]) -> Vec<f64> {
        let nodes = self.nodes_of(b);
        let x = |n: usize| self.reference[n] + Self::node_vector(u, n);
        let mass: f64 = nodes.clone().map(|n| self.nodal_mass[n]).sum();
        let mut out = vec![0.0; nodes.len() * D];
        if !(mass > 0.0) {
            return out;
        }
        let centre = nodes
            .clone()
            .map(|n| x(n) * self.nodal_mass[n])
            .sum::<SVector<f64, D>>()
            / mass;
        let mean = nodes
            .clone()
            .map(|n| Self::node_vector(v, n) * self.nodal_mass[n])
            .sum::<SVector<f64, D>>()
            / mass;
        let axisymmetric = self.model.settings.kinematics == Kinematics::Axisymmetric;
        let to3 = |a: &SVector<f64, D>| Vector3::from_fn(|i, _| if i < D { a[i] } else { 0.0 });
        // The spin (about z in 2D): I w = L. Axisymmetric: only the axial translation is rigid.
        let mut inertia = Matrix3::zeros();
        let mut momentum = Vector3::zeros();
        for n in nodes.clone() {
            let r = to3(&(x(n) - centre));
            let m = self.nodal_mass[n];
            inertia += (Matrix3::identity() * r.norm_squared() - r * r.transpose()) * m;
            momentum += r.cross(&to3(&Self::node_vector(v, n))) * m;
        }
        let spin = if axisymmetric {
            Vector3::zeros()
        } else if D == 2 {
            Vector3::new(
                0.0,
                0.0,
                momentum[2] / inertia[(2, 2)].max(f64::MIN_POSITIVE),
            )
        } else {
            inertia
                .try_inverse()
                .map_or(Vector3::zeros(), |i| i * momentum)
        };
        for (k, n) in nodes.enumerate() {
            let turn = spin.cross(&to3(&(x(n) - centre)));
            for i in 0..D {
                out[k * D + i] = if axisymmetric && i == 0 {
                    0.0
                } else {
                    mean[i] + turn[i]
                };
            }
        }
        out
    }
}
