//! The space-time velocity step as a pipeline: the start of the step (positions, obstacles,
//! loads), Newton with the contact method ([`super::newton`]), the configuration update and
//! the method's end-of-step correction, the energy account, and the commit of the new state
//! (or, on failure, the restore of the old one). A step that does not converge is cut in
//! halves.

use nalgebra::SVector;

use super::newton::{Solution, StepStart};
use super::observe::{NullRecorder, Recorder};
use super::{end_positions, invalid, Simulation, StepReport};
use crate::assembly;
use crate::contact::methods::projection::{project, Applied, ProjectionContext};
use crate::contact::methods::{self, EndProjection, Method};
use crate::contact::{GapDisplacement, Master, ProjectionMetric};
use crate::dim::{Dim, SpatialDim};
use crate::error::{Error, Result};
use crate::time::SpaceTimeScheme;

/// Deepest step cut: a step is halved at most this many times.
const MAX_CUTS: usize = 4;

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// One step of the configured size.
    pub fn step(&mut self) -> Result<StepReport> {
        let h = self.model.settings.time_step;
        self.advance(h, &mut NullRecorder)
    }

    /// One step of the configured size, observed by a recorder.
    pub fn step_with(&mut self, recorder: &mut dyn Recorder<D>) -> Result<StepReport> {
        let h = self.model.settings.time_step;
        self.advance(h, recorder)
    }

    /// One step of size `h` (s) observed by `recorder`. A step whose Newton or contact
    /// iteration does not converge (or whose contact set cycles) is cut in halves, up to four
    /// times; on error the state is left as it was at the start of the step.
    pub fn advance(&mut self, h: f64, recorder: &mut dyn Recorder<D>) -> Result<StepReport> {
        if !(h > 0.0 && h.is_finite()) {
            return Err(invalid("time_step", h, "a finite value > 0 [s]"));
        }
        let saved = self.state.clone();
        let saved_log = self.contact_log.clone();
        self.step_cycles = 0;
        self.sweeps.clear();
        match self.advance_cut(h, recorder, 0, true) {
            Ok(mut r) => {
                self.close_contact_log(&r.contact_forces);
                r.contact_cycles = self.step_cycles;
                Ok(r)
            }
            Err(e) => {
                self.state = saved;
                self.contact_log = saved_log;
                self.sweeps.clear();
                Err(e)
            }
        }
    }

    fn advance_cut(
        &mut self,
        h: f64,
        recorder: &mut dyn Recorder<D>,
        depth: usize,
        last_piece: bool,
    ) -> Result<StepReport> {
        match self.advance_once(h, recorder, last_piece) {
            Err(Error::NotConverged { .. } | Error::InvertedCell { .. }) if depth < MAX_CUTS => {
                recorder.log(
                    self,
                    &format!(
                        "step {} at t = {:.6e} s: no convergence (or a cell turned inside out) \
                         with h = {h:.3e} s, cutting it in two",
                        self.state.step + 1,
                        self.state.time
                    ),
                );
                let first = self.advance_cut(0.5 * h, recorder, depth + 1, false)?;
                let mut second = self.advance_cut(0.5 * h, recorder, depth + 1, last_piece)?;
                second.iterations += first.iterations;
                second.cuts += first.cuts + 1;
                second.held_contacts = second.held_contacts.max(first.held_contacts);
                second.time_step = h;
                for (a, b) in second.reactions.iter_mut().zip(&first.reactions) {
                    for (x, y) in a.iter_mut().zip(b) {
                        *x = 0.5 * (*x + y);
                    }
                }
                for (a, b) in second.contact_forces.iter_mut().zip(&first.contact_forces) {
                    for (x, y) in a.iter_mut().zip(b) {
                        *x = 0.5 * (*x + y);
                    }
                }
                Ok(second)
            }
            other => other,
        }
    }

    /// Whether gaps are measured on the running eq 22 displacement: chosen, and a penalty
    /// method (the projections put the configuration itself on the surface).
    fn gaps_on_trapezoid(&self) -> bool {
        self.model.contact.gap_displacement == GapDisplacement::Trapezoid
            && methods::method(self.model.contact.method).end_projection() == EndProjection::None
    }

    /// What the step starts from.
    fn step_start(&self, h: f64) -> StepStart<D> {
        let ndof = self.state.velocity.len();
        let u0 = self.state.displacement.clone();
        let v0 = self.state.velocity.clone();
        let f_ext: Vec<f64> = self
            .gravity_force
            .iter()
            .zip(&self.state.loads)
            .map(|(g, l)| g + l)
            .collect();
        let gap_u0 = if self.gaps_on_trapezoid() && self.state.gap_displacement.len() == ndof {
            self.state.gap_displacement.clone()
        } else {
            u0.clone()
        };
        let x0 = end_positions(&self.reference, &gap_u0, &v0, &vec![0.0; ndof], 0.0);
        let (translations_t1, rotations_t1) = self.obstacle_poses_after(h);
        let areas = if self.caches.detector.is_some() {
            self.tributary_areas(&x0)
        } else {
            Vec::new()
        };
        StepStart {
            step: self.state.step + 1,
            t0: self.state.time,
            h,
            obstacles_t0: self.posed_obstacles(),
            obstacles_t1: self.obstacles_at(&translations_t1, &rotations_t1),
            translations_t1,
            rotations_t1,
            u0,
            v0,
            gap_u0,
            f_ext,
            x0,
            areas,
        }
    }

    /// The energy that the time scheme conserves at the current state, for the configured
    /// step (J):
    /// `Q = 1/2 v^T M v + U(u) + h/2 (alpha - beta) u^T K v + h^2/4 (alpha^2 - 2 alpha beta) v^T K v`.
    /// A step of a linear law with `beta = 1 - alpha` keeps it exactly, up to the work
    /// `f . (du + h/2 (alpha - beta) dv)` of constant external forces f; other `beta` scale
    /// each mode's part by the transfer matrix's determinant per step (numerical damping).
    /// It is E plus terms that vanish with h, except on stiff modes (`k h^2 / m >> 1`): there
    /// E swings along the orbit while Q stays, and the difference E - Q is that swing. For a
    /// law that is not linear, U is its stored energy and K the reference stiffness: Q is then
    /// kept only approximately.
    pub fn scheme_energy(&self) -> f64 {
        let s = &self.state;
        let h = self.model.settings.time_step;
        self.scheme_energy_at(&s.displacement, &s.velocity, h, &s.material_history)
    }

    /// [`Self::scheme_energy`] at displacements `u`, velocities `v`, step `h` and material
    /// history `history` (the transfer matrix's invariant form `omega(x, T x)`, omega the
    /// symplectic form, written with M and K).
    fn scheme_energy_at(&self, u: &[f64], v: &[f64], h: f64, history: &[f64]) -> f64 {
        let SpaceTimeScheme { alpha, beta } = self.model.settings.scheme;
        0.5 * assembly::symmetric_dot(&self.matrices.mass, v, v)
            + self.internal_energy(u, history)
            + 0.5 * h * (alpha - beta) * self.stiffness_product(u, v)
            + 0.25 * (alpha * alpha - 2.0 * alpha * beta) * h * h * self.stiffness_product(v, v)
    }

    /// The energy the end-of-step projection took out of the system (negative: put in),
    /// from `before` to `after` it, both (u, v): the work it causes (external forces on its
    /// displacement, obstacles' (pivots') velocities times its impulse; the caller adds the
    /// turning obstacles' `spin_work`) minus its change of the
    /// scheme's conserved energy ([`Self::scheme_energy`], with the step's own h). Measured
    /// on E instead, it would count the strain of the stiff modes that moving a node kicks,
    /// which the next steps' swing of E gives back unbooked: on the ring drop that booked
    /// -130,900 J over a landing after which E - E(0) - W was +38 J. Booked as dissipation,
    /// it closes the scheme's account exactly, whatever its sign.
    fn projection_dissipation(
        &self,
        before: [&[f64]; 2],
        after: [&[f64]; 2],
        f_ext: &[f64],
        impulses: &[Vec<f64>],
        h: f64,
        history: &[f64],
    ) -> f64 {
        let SpaceTimeScheme { alpha, beta } = self.model.settings.scheme;
        let change = self.scheme_energy_at(after[0], after[1], h, history)
            - self.scheme_energy_at(before[0], before[1], h, history);
        // The external forces' work in Q's terms: f.du + h/2 (alpha - beta) f.dv. Prescribed
        // components do not move: their reactions do no work here.
        let mut work: f64 = (0..f_ext.len())
            .map(|i| {
                f_ext[i]
                    * (after[0][i] - before[0][i]
                        + 0.5 * h * (alpha - beta) * (after[1][i] - before[1][i]))
            })
            .sum();
        for (k, f) in impulses.iter().enumerate() {
            let v = self.obstacle_velocity(k);
            work += h * (0..D).map(|i| f[i] * v[i]).sum::<f64>();
        }
        work - change
    }

    /// One step without cutting. `count_step` is false for the first pieces of a cut step.
    fn advance_once(
        &mut self,
        h: f64,
        recorder: &mut dyn Recorder<D>,
        count_step: bool,
    ) -> Result<StepReport> {
        self.ensure_system(h)?;
        self.sync_contact_factors()?;
        if let Some(detector) = self.caches.detector.as_mut() {
            detector.set_memory(&self.state.contact_memory.detection);
        }
        self.schedule_obstacles(h);
        let start = self.step_start(h);
        recorder.step_start(self, start.step);
        let solution = self.solve_step(&start, recorder)?;
        self.finish_step(start, solution, recorder, count_step)
    }

    /// The configuration update, the end-of-step correction, works and reactions, and the
    /// commit of the new state.
    fn finish_step(
        &mut self,
        start: StepStart<D>,
        solution: Solution<D>,
        recorder: &mut dyn Recorder<D>,
        count_step: bool,
    ) -> Result<StepReport> {
        let (step, t0, h) = (start.step, start.t0, start.h);
        let (u0, v0, f_ext) = (&start.u0, &start.v0, &start.f_ext);
        let ndof = v0.len();
        let method: &dyn Method = methods::method(self.model.contact.method);
        let Solution {
            mut v1,
            ref material_history,
            ref residual,
            ref terms,
            ref vars,
            ref friction_normals,
            ref kernel_damping_forces,
            ..
        } = solution;
        // The configuration update and the end-of-step projections.
        let (b0, b1) = self.model.settings.scheme.update_weights();
        let mut u1: Vec<f64> = (0..ndof)
            .map(|i| u0[i] + h * (b0 * v0[i] + b1 * v1[i]))
            .collect();
        // The gaps' displacement: eq 22's increment (the configuration itself when the
        // paper's `GapDisplacement::Configuration` is chosen).
        let mut gap_u1: Vec<f64> = if self.gaps_on_trapezoid() {
            (0..ndof)
                .map(|i| start.gap_u0[i] + 0.5 * h * (v0[i] + v1[i]))
                .collect()
        } else {
            u1.clone()
        };
        // The damping force's work along the eq 22 displacement h (v0 + v1) / 2: with the
        // force at v_alpha, exactly the kinetic energy it removes from a rigid motion.
        let mut damping_loss = 0.0;
        if let Some(c) = &self.damping {
            let alpha = self.model.settings.scheme.alpha;
            let v_alpha: Vec<f64> = (0..ndof)
                .map(|i| (1.0 - alpha) * v0[i] + alpha * v1[i])
                .collect();
            let mut force = vec![0.0; ndof];
            assembly::symmetric_mul_add(c, &v_alpha, 1.0, &mut force);
            damping_loss = (0..ndof)
                .map(|i| force[i] * 0.5 * h * (v0[i] + v1[i]))
                .sum();
        }
        damping_loss += kernel_damping_forces
            .iter()
            .enumerate()
            .map(|(i, f)| f * 0.5 * h * (v0[i] + v1[i]))
            .sum::<f64>();
        let mut contact_forces = vec![vec![0.0; D]; self.model.obstacles.len()];
        for p in &terms.pairs {
            if let Some(k) = p.obstacle {
                let f = p.normal * p.normal_force + p.friction;
                for i in 0..D {
                    contact_forces[k][i] += f[i];
                }
            }
        }
        // Signed: negative where the projection created energy.
        let mut projection_dissipation = 0.0;
        // The projection's impulses on obstacles, where they act (for turning obstacles' work).
        let mut applied: Vec<Applied<D>> = Vec::new();
        let rule = method.end_projection();
        if rule != EndProjection::None {
            if let Some(detector) = self.caches.detector.as_mut() {
                let x_end = end_positions(&self.reference, &gap_u1, &v1, &vec![0.0; ndof], 0.0);
                detector.update_candidates_posed(
                    &start.x0,
                    &x_end,
                    &start.obstacles_t0,
                    &start.obstacles_t1,
                );
                let pairs = detector.pairs(&x_end, &start.obstacles_t1);
                let (u_before, v_before) = (u1.clone(), v1.clone());
                let mut impulses = vec![vec![0.0; D]; self.model.obstacles.len()];
                // Projected on the gaps' positions; the configuration moves with them.
                let gap_before = gap_u1.clone();
                if rule == EndProjection::Active
                    && self.model.contact.projection == ProjectionMetric::Step
                {
                    let facets = detector.surface().facets().to_vec();
                    // Twice: the first correction can bring neighbours of the contact
                    // patch into the master.
                    let mut pairs = pairs;
                    for pass in 0..2 {
                        let x_end =
                            end_positions(&self.reference, &gap_u1, &v1, &vec![0.0; ndof], 0.0);
                        if pass > 0 {
                            let detector = self.caches.detector.as_mut().expect("checked");
                            detector.update_candidates_posed(
                                &start.x0,
                                &x_end,
                                &start.obstacles_t0,
                                &start.obstacles_t1,
                            );
                            pairs = detector.pairs(&x_end, &start.obstacles_t1);
                        }
                        let du = self.weighted_projection(&pairs, &facets, &x_end, h, step)?;
                        for (g, d) in gap_u1.iter_mut().zip(&du) {
                            *g += d;
                        }
                    }
                } else {
                    let detector = self.caches.detector.as_ref().expect("checked");
                    let velocity = |k: usize, x: &SVector<f64, D>| {
                        self.surface_velocity(k, &start.obstacles_t1[k], x)
                    };
                    let context = ProjectionContext {
                        rule,
                        active: &vars.active,
                        facet_body: detector.surface().facet_body(),
                        facets: detector.surface().facets(),
                        nodal_mass: &self.nodal_mass,
                        prescribed: &self.prescribed,
                        obstacle_velocity: &velocity,
                        time_step: h,
                    };
                    project(
                        &context,
                        &pairs,
                        &mut gap_u1,
                        &mut v1,
                        &mut impulses,
                        &mut applied,
                    );
                }
                for i in 0..ndof {
                    u1[i] += gap_u1[i] - gap_before[i];
                }
                if rule != EndProjection::None {
                    projection_dissipation = self.projection_dissipation(
                        [&u_before, &v_before],
                        [&u1, &v1],
                        f_ext,
                        &impulses,
                        h,
                        material_history,
                    );
                    if self.obstacles_turn() {
                        // Turning obstacles' impulses also work through their turning.
                        projection_dissipation +=
                            self.spin_work(h, &start.obstacles_t1, applied.iter().copied());
                    }
                }
                for (total, impulse) in contact_forces.iter_mut().zip(&impulses) {
                    for (t, i) in total.iter_mut().zip(impulse) {
                        *t += i;
                    }
                }
            }
        }

        // Reactions, works and dissipation.
        let mut reactions = vec![vec![0.0; D]; self.model.bodies.len()];
        let mut work = 0.0;
        for i in 0..ndof {
            let du = u1[i] - u0[i];
            let reaction = if self.prescribed[i].is_some() {
                residual[i]
            } else {
                0.0
            };
            work += (f_ext[i] + reaction) * du;
        }
        for (k, f) in contact_forces.iter().enumerate() {
            let v = self.obstacle_velocity(k);
            work += h * (0..D).map(|i| f[i] * v[i]).sum::<f64>();
        }
        if self.obstacles_turn() {
            let at_pairs = terms.pairs.iter().filter_map(|p| {
                let f = p.normal * p.normal_force + p.friction;
                p.obstacle.map(|k| (k, p.master_point, f))
            });
            let forces = at_pairs.chain(applied.iter().copied());
            work += self.spin_work(h, &start.obstacles_t1, forces);
        }
        for (b, r) in reactions.iter_mut().enumerate() {
            for n in self.nodes_of(b) {
                for k in 0..D {
                    let dof = n * D + k;
                    if self.prescribed[dof].is_some() {
                        r[k] += residual[dof];
                    }
                }
            }
        }

        // Final gaps in the stored configuration.
        let mut max_penetration: f64 = 0.0;
        let mut contacts = Vec::new();
        let mut swept = None;
        if let Some(detector) = self.caches.detector.as_mut() {
            let x_end = end_positions(&self.reference, &gap_u1, &v1, &vec![0.0; ndof], 0.0);
            detector.update_candidates_posed(
                &start.x0,
                &x_end,
                &start.obstacles_t0,
                &start.obstacles_t1,
            );
            swept = super::overlap::through_candidates(detector, &start.obstacles_t0)
                .map(|candidates| (x_end.clone(), candidates));
            for p in detector.pairs(&x_end, &start.obstacles_t1) {
                max_penetration = max_penetration.max(-p.gap);
                let force = terms
                    .pairs
                    .iter()
                    .find(|q| {
                        q.key.0 == p.slave
                            && q.obstacle
                                == match p.master {
                                    Master::Obstacle(k) => Some(k),
                                    _ => None,
                                }
                    })
                    .map_or(0.0, |q| q.normal_force.max(0.0));
                if p.gap < 0.0 || force > 0.0 {
                    contacts.push((p.slave, p.gap, force));
                }
            }
        }
        let active_contacts = terms.pairs.iter().filter(|p| p.normal_force > 0.0).count();

        let previous = self.state.clone();
        if let Some(detector) = &self.caches.detector {
            self.state.contact_memory.detection = detector.memory();
        }
        let state = &mut self.state;
        state.step = if count_step { step } else { state.step };
        state.time = t0 + h;
        state.displacement = u1;
        state.gap_displacement = gap_u1;
        state.velocity = v1;
        state.external_work += work;
        state.dissipated_energy +=
            h * terms.dissipation_rate + projection_dissipation + damping_loss;
        state.obstacle_translations = start.translations_t1.clone();
        state.obstacle_rotations = start.rotations_t1.clone();
        state.material_history.clone_from(material_history);
        state.contact_energy = terms.energy;
        state.multipliers = vars
            .multipliers
            .iter()
            .map(|(&(s, m), &l)| (s, m, l))
            .collect();
        state.friction_normals = friction_normals
            .iter()
            .map(|(&(s, m), &f)| (s, m, f))
            .collect();
        state.friction_anchors = terms
            .pairs
            .iter()
            .filter_map(|p| p.anchor.map(|a| (p.key.0, p.key.1, a.as_slice().to_vec())))
            .collect();
        if !method.carries_multipliers() {
            state.multipliers.clear();
        }
        let energies = self.energies();
        let limit = 1e6 * self.energy_reference().max(f64::MIN_POSITIVE);
        let finite = self
            .state
            .displacement
            .iter()
            .chain(&self.state.velocity)
            .all(|x| x.is_finite());
        if !finite || !energies.total().is_finite() || energies.total() > limit {
            let detail = if !finite || !energies.total().is_finite() {
                "a displacement, velocity or energy became non-finite".to_string()
            } else {
                format!(
                    "the total energy {:.3e} J exceeds 1e6 times its reference {:.3e} J \
                     (E(0) + |external work| + dissipated), a growth by {:.2e}",
                    energies.total(),
                    self.energy_reference(),
                    energies.total() / self.energy_reference().max(f64::MIN_POSITIVE)
                )
            };
            self.state = previous;
            return Err(Error::Unstable {
                step,
                time: t0 + h,
                detail,
            });
        }
        self.log_contacts(&terms.pairs, &terms.forces);
        if let Some((x1, candidates)) = swept {
            self.sweeps.push(super::overlap::Sweep {
                x0: start.x0,
                x1,
                obstacles_t0: start.obstacles_t0,
                obstacles_t1: start.obstacles_t1,
                h,
                candidates,
            });
        }
        let report = StepReport {
            step,
            time: t0 + h,
            time_step: h,
            iterations: solution.iterations,
            residual: solution.relative,
            energies,
            max_penetration,
            active_contacts,
            reactions,
            contact_forces,
            contacts,
            cuts: 0,
            held_contacts: vars.locked.len(),
            contact_cycles: 0,
        };
        recorder.step_end(self, &report);
        Ok(report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::methods::OuterVariables;
    use crate::contact::{
        ContactMethod, ContactSettings, FrictionLaw, MasterId, Obstacle, ObstacleShape,
    };
    use crate::material::{LinearElastic, Material};
    use crate::mesh::generators::rectangle;
    use crate::simulation::contact_terms::TermsInput;
    use crate::simulation::{Body, Simulation2};
    use nalgebra::Vector2;
    use std::collections::BTreeMap;

    /// The contact forces and the assembled tangent at end velocities `v1`.
    fn forces_and_tangent(
        sim: &mut Simulation2,
        v1: &[f64],
        h: f64,
        friction_normals: &BTreeMap<(usize, MasterId), f64>,
        anchors: &BTreeMap<(usize, MasterId), Vector2<f64>>,
    ) -> (Vec<f64>, nalgebra::DMatrix<f64>, [usize; 2]) {
        sim.ensure_system(h).unwrap();
        let n = v1.len();
        let u0 = sim.state.displacement.clone();
        let v0 = sim.state.velocity.clone();
        let x0 = end_positions(&sim.reference, &u0, &v0, &vec![0.0; n], 0.0);
        let x_gap = end_positions(&sim.reference, &u0, &v0, v1, h);
        let obstacles = sim.model.obstacles.clone();
        let t1: Vec<Vector2<f64>> = obstacles.iter().map(|o| o.translation).collect();
        let areas = sim.tributary_areas(&x0);
        let det = sim.caches.detector.as_mut().unwrap();
        det.update_candidates(&x0, &x_gap, &obstacles, &t1);
        let pairs = det.pairs(&x_gap, &obstacles);
        let diagonal = vec![1.0; n];
        // Implicit projection: every detected point active (its multipliers zero).
        let mut vars = OuterVariables::default();
        if sim.model.contact.method == ContactMethod::ImplicitProjection {
            vars.active = pairs.iter().map(|p| sim.contact_key(p)).collect();
        }
        let terms = sim.contact_terms(
            &pairs,
            &TermsInput {
                method: methods::method(sim.model.contact.method),
                obstacles_t1: &obstacles,
                x_gap: &x_gap,
                v0: &v0,
                v1,
                time_step: h,
                areas: &areas,
                vars: &vars,
                friction_normals,
                friction_anchors: anchors,
                diagonal: &diagonal,
            },
        );
        let mut k = nalgebra::DMatrix::zeros(n, n);
        for &(r, c, v) in terms.entries.iter().chain(&terms.geometric) {
            k[(r, c)] += v;
            if r != c {
                k[(c, r)] += v;
            }
        }
        for (u, w) in &terms.coupling {
            for &(r, a) in u {
                for &(c, b) in w {
                    k[(r, c)] += a * b;
                }
            }
        }
        // Closed contacts, and those at the slip limit.
        let closed = terms.pairs.iter().filter(|p| p.normal_force > 0.0);
        let slipping = closed
            .clone()
            .filter(|p| p.friction.norm() >= (1.0 - 1e-9) * 0.4 * p.normal_force)
            .count();
        (terms.forces, k, [closed.count(), slipping])
    }

    /// The assembled contact tangent against central differences of the contact forces;
    /// `anchors` are the elastic slips of the friction return map at the start of the step.
    fn check(
        sim: Simulation2,
        anchors: &BTreeMap<(usize, MasterId), Vector2<f64>>,
        tolerance: f64,
    ) -> [usize; 2] {
        check_at_speed(sim, anchors, tolerance, 0.01)
    }

    /// [`check`] with end velocities of about `speed` (m/s).
    fn check_at_speed(
        mut sim: Simulation2,
        anchors: &BTreeMap<(usize, MasterId), Vector2<f64>>,
        tolerance: f64,
        speed: f64,
    ) -> [usize; 2] {
        let h = 1e-3;
        let n = sim.state.velocity.len();
        // A velocity field that keeps every contact strictly open or strictly closed.
        let v1: Vec<f64> = (0..n).map(|i| speed * ((i as f64) * 0.7).sin()).collect();
        let normals = BTreeMap::new();
        let (_, k, counts) = forces_and_tangent(&mut sim, &v1, h, &normals, anchors);
        assert!(k.amax() > 0.0, "no contact in the test configuration");
        let eps = 1e-7;
        let mut worst: f64 = 0.0;
        for j in 0..n {
            let (mut vp, mut vm) = (v1.clone(), v1.clone());
            vp[j] += eps;
            vm[j] -= eps;
            let (fp, _, _) = forces_and_tangent(&mut sim, &vp, h, &normals, anchors);
            let (fm, _, _) = forces_and_tangent(&mut sim, &vm, h, &normals, anchors);
            for i in 0..n {
                // The tangent is d(-f)/dv1.
                let fd = -(fp[i] - fm[i]) / (2.0 * eps);
                worst = worst.max((fd - k[(i, j)]).abs());
            }
        }
        assert!(
            worst <= tolerance * k.amax(),
            "tangent error {worst:e} of {:e}",
            k.amax()
        );
        counts
    }

    fn block_on(obstacle: Obstacle<2>, friction: FrictionLaw, penetration: f64) -> Simulation2 {
        let mesh = rectangle(
            Vector2::new(-0.5, 0.0),
            Vector2::new(0.5, 0.2),
            [4, 2],
            crate::element::ElementKind::Quad4,
        )
        .unwrap();
        let mut sim = Simulation2::builder()
            .body(Body::new(
                "b",
                mesh,
                Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap()),
            ))
            .obstacle(obstacle)
            .contact(ContactSettings {
                method: ContactMethod::SoftWay,
                penalty: 1e8,
                friction,
                ..ContactSettings::default()
            })
            .build()
            .unwrap();
        // Push the body into the obstacle.
        for i in 0..sim.node_count() {
            sim.state.displacement[2 * i + 1] = -penetration;
        }
        sim
    }

    #[test]
    fn soft_way_tangent_against_a_halfspace_matches_finite_differences() {
        let plane = Obstacle::new(
            "p",
            ObstacleShape::Halfspace {
                point: Vector2::zeros(),
                normal: Vector2::new(0.1, 1.0),
            },
        );
        check(
            block_on(plane, FrictionLaw::Frictionless, 1e-3),
            &BTreeMap::new(),
            1e-6,
        );
    }

    #[test]
    fn soft_way_tangent_against_a_ball_matches_finite_differences() {
        // The curvature term zeta (-g) (I - n n) / R matters here.
        let ball = Obstacle::new(
            "ball",
            ObstacleShape::Ball {
                center: Vector2::new(0.05, -0.5),
                radius: 0.5,
            },
        );
        // The curvature term is about 1.5 % of the tangent here (|g| / R); what remains is the
        // variation of the projected contact area with the normal, not in the tangent.
        check(
            block_on(ball, FrictionLaw::Frictionless, 1e-2),
            &BTreeMap::new(),
            3e-3,
        );
    }

    #[test]
    fn implicit_projection_tangent_on_a_turning_ball_matches_finite_differences() {
        // The held normal velocity against a curved master that turns: the normal's variation
        // and the surface velocity following the closest point (which cancel on a ball turning
        // about its centre, where n . v_m = 0).
        for omega in [0.0, 20.0] {
            let ball = Obstacle::new(
                "drum",
                ObstacleShape::Ball {
                    center: Vector2::new(0.05, -0.5),
                    radius: 0.5,
                },
            );
            let mut sim = block_on(ball, FrictionLaw::Frictionless, 1e-2);
            sim.model.contact.method = ContactMethod::ImplicitProjection;
            sim.state.obstacle_angular_velocities = vec![omega];
            check_at_speed(sim, &BTreeMap::new(), 1e-5, 2.0);
        }
    }

    #[test]
    fn coulomb_friction_tangent_matches_finite_differences() {
        let plane = Obstacle::new(
            "p",
            ObstacleShape::Halfspace {
                point: Vector2::zeros(),
                normal: Vector2::new(0.0, 1.0),
            },
        );
        let law = FrictionLaw::Coulomb {
            coefficient: 0.4,
            regularization: 1e-3,
        };
        // The return map on a block pressed 1 mm into a plane: every contact sticks without an
        // elastic slip at the start (increments h w_t of ~1e-5 m against mu times the 1 mm
        // penetration), and slips with one of 2 mm, either way.
        for (elastic_slip, slips) in [(0.0, false), (2e-3, true), (-2e-3, true)] {
            let sim = block_on(plane.clone(), law, 1e-3);
            let mut anchors = BTreeMap::new();
            for s in 0..sim.node_count() {
                anchors.insert((s, MasterId::Obstacle(0)), Vector2::new(elastic_slip, 0.0));
            }
            let [closed, slipping] = check(sim, &anchors, 1e-6);
            assert_eq!(closed, 5, "closed contacts");
            assert_eq!(
                slipping,
                if slips { closed } else { 0 },
                "elastic slip {elastic_slip}"
            );
        }
    }

    #[test]
    fn coulomb_friction_tangent_on_a_turning_plane_matches_finite_differences() {
        let plane = Obstacle {
            rotation: nalgebra::Rotation2::new(0.05).into_inner(),
            ..Obstacle::new(
                "p",
                ObstacleShape::Halfspace {
                    point: Vector2::new(0.3, 0.0),
                    normal: Vector2::new(0.0, 1.0),
                },
            )
        };
        let law = FrictionLaw::Coulomb {
            coefficient: 0.4,
            regularization: 1e-3,
        };
        for (elastic_slip, omega) in [(0.0, 0.0), (0.0, 2.0), (2e-3, 2.0)] {
            let mut sim = block_on(plane.clone(), law, 1e-3);
            sim.state.obstacle_angular_velocities = vec![omega];
            let mut anchors = BTreeMap::new();
            for s in 0..sim.node_count() {
                anchors.insert((s, MasterId::Obstacle(0)), Vector2::new(elastic_slip, 0.0));
            }
            eprintln!("omega {omega} slip {elastic_slip}");
            check(sim, &anchors, 1e-6);
        }
    }

    /// An upper block pressed 1 mm into a lower one, 1 cm off centre, under `method`.
    fn two_blocks(method: ContactMethod) -> Simulation2 {
        let lower = rectangle(
            Vector2::new(-0.5, -0.2),
            Vector2::new(0.5, 0.0),
            [3, 1],
            crate::element::ElementKind::Quad4,
        )
        .unwrap();
        let mut upper = rectangle(
            Vector2::new(-0.3, 0.0),
            Vector2::new(0.3, 0.2),
            [2, 1],
            crate::element::ElementKind::Quad4,
        )
        .unwrap();
        upper.translate(&Vector2::new(0.01, -1e-3));
        let mat = Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap());
        Simulation2::builder()
            .body(Body::new("upper", upper, mat))
            .body(Body::new("lower", lower, mat))
            .contact(ContactSettings {
                method,
                penalty: 1e8,
                ..ContactSettings::default()
            })
            .build()
            .unwrap()
    }

    #[test]
    fn soft_way_tangent_between_two_bodies_matches_finite_differences() {
        // The facet terms (normal and closest-point variations) of a deformable master. The
        // projected contact area follows the master's normal; that variation is not in the
        // tangent (a relative error of ~6e-4 here), everything else is.
        check(two_blocks(ContactMethod::SoftWay), &BTreeMap::new(), 1e-3);
    }

    #[test]
    fn implicit_projection_tangent_between_two_bodies_matches_finite_differences() {
        // A held normal velocity on a facet master that turns and slides under the slave:
        // the normal's and the closest point's variation (a non-symmetric rank-one term per
        // pair) and the constraint force's geometric term are in the tangent. At 2 m/s of
        // sliding the turning normal's term is about 3e-3 of the tangent.
        let sim = two_blocks(ContactMethod::ImplicitProjection);
        check_at_speed(sim, &BTreeMap::new(), 2e-5, 2.0);
    }

    /// A block dropped at 1 m/s onto a plane 0.1 mm under it, `steps` steps of 1 ms; the
    /// velocities at the end.
    fn dropped_block(
        penalty: f64,
        single_precision: bool,
        steps: usize,
    ) -> (Simulation2, Vec<f64>) {
        let mesh = rectangle(
            Vector2::new(-0.5, 1e-4),
            Vector2::new(0.5, 0.2001),
            // 25 bottom nodes: more than CG takes on without a contact factorisation.
            [24, 4],
            crate::element::ElementKind::Quad4,
        )
        .unwrap();
        let plane = Obstacle::new(
            "ground",
            ObstacleShape::Halfspace {
                point: Vector2::zeros(),
                normal: Vector2::new(0.0, 1.0),
            },
        );
        let mut sim = Simulation2::builder()
            .gravity(Vector2::new(0.0, -9.81))
            .body(
                Body::new(
                    "b",
                    mesh,
                    Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap()),
                )
                .with_velocity(Vector2::new(0.0, -1.0)),
            )
            .obstacle(plane)
            .contact(ContactSettings {
                method: ContactMethod::SoftWay,
                penalty,
                ..ContactSettings::default()
            })
            .build()
            .unwrap();
        sim.state.contact_memory.double_precision_only = !single_precision;
        for _ in 0..steps {
            sim.step().unwrap();
        }
        let v = sim.state.velocity.clone();
        (sim, v)
    }

    #[test]
    fn single_precision_contact_factors_give_the_double_precision_answer() {
        let (single, v_single) = dropped_block(1e8, true, 4);
        assert!(
            !single.state.contact_memory.double_precision_only,
            "refinement converged"
        );
        assert!(single
            .caches
            .contact_factors
            .iter()
            .all(|f| f.is_single_precision()));
        let (double, v_double) = dropped_block(1e8, false, 4);
        assert!(double
            .caches
            .contact_factors
            .iter()
            .all(|f| !f.is_single_precision()));
        assert!(
            !single.caches.contact_factors.is_empty(),
            "a contact matrix was factored"
        );
        let scale = v_double.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let diff = v_single
            .iter()
            .zip(&v_double)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        // Both are Newton solutions to the same tolerance (1e-8 of the force scale).
        assert!(diff < 1e-6 * scale, "{diff} vs {scale}");
    }

    /// The general path (internal forces and tangent from the element kernel every Newton
    /// iteration, the path of laws that are not linear) gives the linear fast path's answer.
    #[test]
    fn the_general_path_matches_the_linear_fast_path() {
        for method in [ContactMethod::SoftWay, ContactMethod::ImplicitProjection] {
            let run = |general: bool| {
                let (mut sim, _) = dropped_block(1e8, true, 0);
                sim.model.contact.method = method;
                sim.general_path = general;
                let mut reports = Vec::new();
                for _ in 0..8 {
                    reports.push(sim.step().unwrap());
                }
                (
                    sim.state.velocity.clone(),
                    sim.state.displacement.clone(),
                    reports,
                )
            };
            let (v_fast, u_fast, r_fast) = run(false);
            let (v_general, u_general, r_general) = run(true);
            assert!(
                r_fast.iter().any(|r| r.active_contacts > 0),
                "{method:?}: no contact"
            );
            let scale = v_fast.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let dv = v_fast
                .iter()
                .zip(&v_general)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            let du = u_fast
                .iter()
                .zip(&u_general)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            // Both are Newton solutions to the same tolerance (1e-8 of the force scale).
            assert!(
                dv < 1e-6 * scale,
                "{method:?}: velocities differ by {dv:e} of {scale:e}"
            );
            assert!(
                du < 1e-6 * scale * 1e-3 * 8.0,
                "{method:?}: displacements differ by {du:e}"
            );
            for (a, b) in r_fast.iter().zip(&r_general) {
                let e = a.energies.total().abs().max(1e-12);
                assert!(
                    (a.energies.total() - b.energies.total()).abs() < 1e-6 * e,
                    "{method:?}: energies {:?} vs {:?}",
                    a.energies,
                    b.energies
                );
            }
        }
    }

    /// A law with history through the general path: the state carries the history from step
    /// to step, and a failed step restores it.
    #[test]
    fn material_history_is_state() {
        use crate::material::tests::TestLaw;
        let (mut sim, _) = dropped_block(1e8, true, 0);
        let elastic = crate::material::LinearElastic::new(1e6, 0.3, 1000.0).unwrap();
        sim.integration[0].law = std::sync::Arc::new(TestLaw {
            elastic,
            cubic: 1e8,
            eta: 1e3,
            exponent: 0.5,
        });
        sim.general_path = true;
        sim.state.material_history = vec![0.0; assembly::history_len(&sim.table, &sim.integration)];
        assert_eq!(
            sim.state.material_history.len(),
            24 * 4 * 4,
            "4 points per Quad4"
        );
        let mut previous = 0.0;
        for step in 0..6 {
            let before = format!("{:?}", sim.state);
            sim.set_solver_limits(1, 1e-300).unwrap();
            assert!(sim.step().is_err());
            assert_eq!(
                before,
                format!("{:?}", sim.state),
                "step {step}: not restored"
            );
            sim.set_solver_limits(50, 1e-8).unwrap();
            sim.step().unwrap();
            // The test law accumulates h * |strain rate| (regularised): it grows every step.
            let total: f64 = sim.state.material_history.iter().sum();
            assert!(total > previous, "step {step}: {total} <= {previous}");
            previous = total;
        }
    }
}
