//! A change of step size that keeps the energy the scheme conserves.
//!
//! At a fixed step h the scheme keeps (linear law, `beta = 1 - alpha`)
//! `Q_h = 1/2 v^T M v + 1/2 w^T K w + g h^2 v^T K v` with the shadow displacement
//! `w = u + a h v`, `a = (alpha - beta) / 2` and `g = (alpha^2 - 2 alpha beta) / 4 - a^2 / 2`
//! (1/64 at the default 0.75 and 0.25; [`Simulation::scheme_energy`]). The same (u, v) taken on
//! with another step h' has another Q: a stiff mode, whose part of Q is mostly `g h^2 k v^2`,
//! gains or loses energy at each change, and steps that change back and forth (a cut step's
//! halves) pump it: every seventh step halved, a bar's Q grew 59-fold at twice the explicit
//! step and 3.3e5-fold at five times (`tests/step_size_changes.rs`).
//!
//! So the state is re-expressed for the new step: w is kept (`u' = u + a (h v - h' v')`), and
//! the velocity is mapped by `v' = (M + 2 g h'^2 K)^-1 (M + 2 g h h' K) v`, which leaves rigid
//! motions (K annihilates them) and resolved modes (`g h^2 k << m`) as they are. Per mode Q
//! never grows, since `(m + 2 g h h' k)^2 <= (m + 2 g h^2 k) (m + 2 g h'^2 k)`
//! (Cauchy-Schwarz); a mode loses about `g (h - h')^2 k / m` of its kinetic part per change
//! (the exact map, `sqrt((m + 2 g h^2 k) / (m + 2 g h'^2 k))` per mode, is a matrix square
//! root), booked as dissipation. A map whose change back is its inverse
//! (`c = g h (h + h')`, `c' = g h' (h + h')`) was tried for cut steps: it is not exact either
//! once the halves have moved the mode's phase (a beam set vibrating in every mode, every
//! third step cut, kept 0.90 of Q), and it can put energy in.
//!
//! The velocity map needs the linear law's K (the reference stiffness is the law's) and
//! `g > 0` (Q positive definite): otherwise only w is kept.
//!
//! Contact sees the shift: a node riding a plate at 50 m/s moves `a (h - h') v` (6e-6 m at the
//! tube crush's step) while the plate follows the clock, which is also the pose a host drives it
//! to. So a change is made at the start of a step (a cut step's halves each re-express the
//! state for their size as they start, and the next whole step for its own), where the step
//! itself resolves what moved, and for a cut step's halves the obstacles move with the bodies
//! (by their velocity times the same lag) and back to their poses when the halves end
//! ([`Simulation::shift_obstacles`]): the nodes on a moving plate then end the cut step a lag's
//! travel ahead of it, and the next step's change puts them back on it. The gaps'
//! displacement moves with the configuration on configuration gaps; on trapezoid gaps (eq 22's
//! running increment) it keeps its offset `h (1/2 - beta) (v - v(0))` from the configuration:
//! it does not move at all at the default alpha + beta = 1, where it is w up to a constant,
//! and bodies of updated-Lagrangian laws keep their configuration instead, whose shift their
//! stress history would not see (`Simulation::reexpression_weights`; the obstacles' lag for a
//! cut step's halves follows the gaps).

use super::Simulation;
use crate::assembly;
use crate::dim::{Dim, SpatialDim};
use crate::error::Result;
use crate::time::SpaceTimeScheme;

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// Re-expresses the state for steps of `h` (s) when it holds the scheme's variables for
    /// another step size (the module documentation); the state then holds them for `h`. A
    /// state valid for any step (`scheme_time_step` 0: before the first step) is left as it
    /// is; the step that commits sets its own size.
    pub(super) fn change_step_to(&mut self, h: f64) -> Result<()> {
        let from = self.state.scheme_time_step;
        if from > 0.0 && from != h {
            self.change_step(from, h)?;
            self.state.scheme_time_step = h;
        }
        Ok(())
    }

    fn change_step(&mut self, from: f64, to: f64) -> Result<()> {
        let SpaceTimeScheme { alpha, beta } = self.model.settings.scheme;
        let a = 0.5 * (alpha - beta);
        let g = 0.25 * (alpha * alpha - 2.0 * alpha * beta) - 0.5 * a * a;
        let u = self.state.displacement.clone();
        let v = self.state.velocity.clone();
        let ndof = v.len();
        let is_free: Vec<bool> = self.prescribed.iter().map(Option::is_none).collect();
        let free = |i: usize| is_free[i];
        let v_new = if g > 0.0 && !self.general_path {
            // (M + 2 g to^2 K) v' = (M + 2 g from to K) v on the free unknowns, the
            // prescribed ones' coupling moved to the right-hand side.
            let (k_from, k_to) = (2.0 * g * from * to, 2.0 * g * to * to);
            let mut rhs = vec![0.0; ndof];
            assembly::symmetric_mul_add(&self.matrices.mass, &v, 1.0, &mut rhs);
            assembly::symmetric_mul_add(&self.matrices.stiffness, &v, k_from, &mut rhs);
            let held: Vec<f64> = (0..ndof)
                .map(|i| if free(i) { 0.0 } else { v[i] })
                .collect();
            assembly::symmetric_mul_add(&self.matrices.mass, &held, -1.0, &mut rhs);
            assembly::symmetric_mul_add(&self.matrices.stiffness, &held, -k_to, &mut rhs);
            for (i, r) in rhs.iter_mut().enumerate() {
                if !free(i) {
                    *r = 0.0;
                }
            }
            self.solve_mass_plus_stiffness(k_to, &mut rhs)?;
            (0..ndof)
                .map(|i| if free(i) { rhs[i] } else { v[i] })
                .collect()
        } else {
            v.clone()
        };
        // Every node, prescribed ones too (their velocity is prescribed, not their position),
        // and the gaps' displacement with them as `reexpression_weights` says: contact sees
        // the same relative positions on configuration gaps, and on trapezoid gaps their
        // offset from the configuration stays eq 22's, which vanishes at rest (shifted with
        // the configuration there, a cut step left it off for good).
        let mut shift = vec![0.0; ndof];
        // What w moves by: nothing where the configuration takes `a` (a linear law's body).
        let mut w_moved = vec![0.0; ndof];
        let has_gaps = self.state.gap_displacement.len() == ndof;
        for body in 0..self.model.bodies.len() {
            let (c_u, c_gap) = self.reexpression_weights(body);
            let nodes = self.nodes_of(body);
            for i in nodes.start * D..nodes.end * D {
                let change = from * v[i] - to * v_new[i];
                shift[i] = c_u * change;
                w_moved[i] = (c_u - a) * change;
                if has_gaps {
                    self.state.gap_displacement[i] += c_gap * change;
                }
            }
        }
        let u_new: Vec<f64> = (0..ndof).map(|i| u[i] + shift[i]).collect();
        // Where the shadow displacement does not move, external forces do no work in Q's
        // terms and what Q loses is dissipated; where it does (the bodies that keep their
        // configuration), the loads' work on it, `f . dw`, is Q's too.
        let history = &self.state.material_history;
        let before = self.scheme_energy_at(&u, &v, from, history);
        let after = self.scheme_energy_at(&u_new, &v_new, to, history);
        let w_work: f64 = self
            .gravity_force
            .iter()
            .zip(&self.state.loads)
            .zip(&w_moved)
            .map(|((g, l), d)| (g + l) * d)
            .sum();
        self.state.dissipated_energy += before - after + w_work;
        // The loads' work on the shift is the account's: E - W + D measures W on u, and the
        // monitor's Q-terms work, f . (w1 - w0) with w held here, is W + a h f . (v1 - v0)
        // only when W counts the shifts. Left out, two rubber blocks stacked with Coulomb
        // friction at 1/60 s, one step cut in halves while the upper one bounced, ended 3.2e-2
        // of the account's reference off (`tests/two_bodies.rs`; booked, 1.9e-6), and the
        // monitor missed the energy that a cut step's net shift puts into a body it lifts
        // (the tilting floor's cut steps at its impact, `tests/cli/reliability.rs`).
        // Prescribed unknowns shift too; their reactions are not known between steps.
        self.state.external_work += self
            .gravity_force
            .iter()
            .zip(&self.state.loads)
            .zip(&shift)
            .map(|((g, l), d)| (g + l) * d)
            .sum::<f64>();
        self.state.displacement = u_new;
        self.state.velocity = v_new;
        Ok(())
    }

    /// Moves every obstacle by `velocities` (its linear and angular velocities, as in the
    /// state) times `lag` (s) (a negative lag moves it back). A cut step's halves take the
    /// bodies re-expressed for half the step, whose nodes that ride a moving obstacle have
    /// moved by `lag` times their velocity: the obstacles move with them for the halves, and
    /// back when the cut step ends, so that they are at their clock's (or their host's) pose
    /// after the step.
    pub(super) fn shift_obstacles(&mut self, lag: f64, velocities: &ObstacleVelocities) {
        let (linear, angular) = velocities;
        for (t, v) in self.state.obstacle_translations.iter_mut().zip(linear) {
            *t += lag * v;
        }
        let (a, r) = (<Dim<D>>::ANGULAR, <Dim<D>>::ROTATION);
        for k in 0..self.model.obstacles.len() {
            let Some(omega) = angular.get(k * a..k * a + a) else {
                continue;
            };
            if omega.iter().any(|w| *w != 0.0) {
                let turn: Vec<f64> = omega.iter().map(|w| w * lag).collect();
                let rotation = &mut self.state.obstacle_rotations[k * r..k * r + r];
                let next = <Dim<D>>::turned(rotation, &turn);
                rotation.copy_from_slice(&next);
            }
        }
    }
}

/// The obstacles' linear and angular velocities, laid out as in the state.
pub(super) type ObstacleVelocities = (Vec<f64>, Vec<f64>);
