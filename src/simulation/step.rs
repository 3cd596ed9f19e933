//! The space-time velocity step as a pipeline: the start of the step (positions, obstacles,
//! loads), Newton with the contact method ([`super::newton`]), the configuration update and
//! the method's end-of-step correction, the energy account, and the commit of the new state
//! (or, on failure, the restore of the old one). A step that does not converge is cut in
//! halves.

use std::collections::BTreeSet;

use nalgebra::SVector;

use super::held_pairs::held_pairs;
use super::newton::{Solution, StepStart};
use super::observe::{NullRecorder, Recorder};
use super::{body_of, end_positions, invalid, Simulation, StepReport};
use crate::assembly;
use crate::contact::methods::projection::{project, Applied, BodyImpulse, ProjectionContext};
use crate::contact::methods::{self, implicit_projection, EndProjection, Method};
use crate::contact::{
    ContactKey, ContactMethod, ContactPair, GapDisplacement, Master, MasterId, MasterNodes,
    ProjectionEnergy, ProjectionMetric,
};
use crate::dim::{Dim, SpatialDim};
use crate::error::{Error, Result};
use crate::time::SpaceTimeScheme;

/// Deepest step cut: a step is halved at most this many times.
const MAX_CUTS: usize = 4;

/// Most passes of implicit projection's end-of-step correction in the step's metric (each
/// after detecting again; a pass that moves nothing ends them).
const PROJECTION_PASSES: usize = 4;

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// What to change after an instability. Outside the scheme's unconditionally stable
    /// window, alpha and beta; inside it the scheme is not the cause, so the advice names
    /// what is: a penalty too stiff for the step, an overlap at the start, or magnitudes out
    /// of range.
    pub(super) fn instability_advice(&self, non_finite: bool) -> String {
        let scheme = self.model.settings.scheme;
        if !scheme.is_unconditionally_stable() {
            return format!(
                "{} lie outside the unconditionally stable window: {}, or a smaller time_step",
                scheme.parameters(),
                crate::time::WINDOW_ADVICE
            );
        }
        let contact = if self.caches.detector.is_none() {
            ""
        } else {
            match self.model.contact.method {
                ContactMethod::SoftWay | ContactMethod::AugmentedLagrangian => {
                    "a contact penalty too stiff for the time step (use a smaller time_step or \
                     penalty, or implicit_projection), "
                }
                ContactMethod::ExplicitProjection => {
                    "explicit_projection's end-of-step correction (use implicit_projection, or a \
                     smaller time_step), "
                }
                ContactMethod::ImplicitProjection => "",
            }
        };
        let magnitudes = "magnitudes out of range (the scene's velocities, densities, moduli, \
                          penalties and loads)";
        if non_finite {
            // A value left the floating-point range: the scene's numbers come first.
            return format!(
                "the time scheme ({}) is unconditionally stable: look first for {magnitudes}, \
                 then {contact}bodies that overlap at the start (softway check reports them)",
                scheme.parameters()
            );
        }
        format!(
            "the time scheme ({}) is unconditionally stable, so look elsewhere: {contact}bodies \
             that overlap at the start (softway check reports them), or {magnitudes}",
            scheme.parameters()
        )
    }

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
        self.drive_to_next_poses(h);
        let saved = self.state.clone();
        let saved_log = self.contact_log.clone();
        self.step_cycles = 0;
        *self.step_factorisations.get_mut() = 0;
        self.sweeps.clear();
        match self.advance_cut(h, recorder, 0, true) {
            Ok(mut r) => {
                self.next_poses.clear();
                self.close_contact_log(&r.contact_forces);
                r.contact_cycles = self.step_cycles;
                r.factorisations = *self.step_factorisations.get_mut();
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
        let mut attempt = self.advance_once(h, recorder, last_piece);
        if let Err(Error::NotConverged { .. }) = attempt {
            // Newton's plain iteration stalled: the same step with the globalized one, before
            // the step is cut (the plain iteration stays the first attempt: it is the paper's,
            // and the path the measured results were taken on).
            recorder.log(
                self,
                &format!(
                    "step {} at t = {:.6e} s: no convergence with h = {h:.3e} s, trying the \
                     line search and the secant slip tangent",
                    self.state.step + 1,
                    self.state.time
                ),
            );
            self.globalized_newton = true;
            attempt = self.advance_once(h, recorder, last_piece);
            self.globalized_newton = false;
            if let Ok(report) = &mut attempt {
                report.globalized = true;
            }
        }
        match attempt {
            // A factorisation that fails mid-step is cut too: the iteration matrix is
            // M / h + alpha^2 h K / 2, so a halved step quadruples the mass's share and restores
            // a positive definite matrix where compression (the geometric stiffness) or a
            // collapsing cell made the tangent indefinite.
            Err(
                e @ (Error::NotConverged { .. }
                | Error::InvertedCell { .. }
                | Error::Factorization { .. }),
            ) if depth < MAX_CUTS => {
                let out_of_iterations = matches!(
                    e,
                    Error::NotConverged { iterations, .. }
                        if iterations >= self.model.settings.max_iterations
                );
                recorder.log(
                    self,
                    &format!(
                        "step {} at t = {:.6e} s, h = {h:.3e} s, cutting it in two: {e}",
                        self.state.step + 1,
                        self.state.time
                    ),
                );
                let mut report = self.advance_in_halves(h, recorder, depth, last_piece)?;
                report.cuts_out_of_iterations += usize::from(out_of_iterations);
                Ok(report)
            }
            Err(Error::Factorization { step, message }) => Err(Error::Factorization {
                step,
                message: format!("{message}; still so with the step cut to {h:.3e} s"),
            }),
            other => other,
        }
    }

    /// A step of size `h` taken as two halves, each cut again if it fails (`depth` cuts
    /// so far), reported as one step: iterations and cuts summed, forces and reactions
    /// averaged.
    fn advance_in_halves(
        &mut self,
        h: f64,
        recorder: &mut dyn Recorder<D>,
        depth: usize,
        last_piece: bool,
    ) -> Result<StepReport> {
        // Each half re-expresses the state for its size as it starts (`step_change.rs`), and
        // the next whole step for its own: a change at the start of a step leaves the step's
        // own end-of-step projection to put back what it moved into a master. The obstacles
        // move with the bodies for the halves, and back to their poses when the halves end, at
        // the step's velocities (the halves may end at others).
        // None before the first step: the bodies are not re-expressed (valid for any step).
        // The gaps see the nodes move by `c (h - h / 2) v`, c the gaps' weight
        // (`reexpression_weights`); where the bodies' weights differ (laws of both kinds on
        // trapezoid gaps), the first body's.
        let lag = if self.state.scheme_time_step == h {
            0.5 * self.reexpression_weights(0).1 * h
        } else {
            0.0
        };
        let velocities = (
            self.state.obstacle_velocities.clone(),
            self.state.obstacle_angular_velocities.clone(),
        );
        self.shift_obstacles(lag, &velocities);
        let first = self.advance_cut(0.5 * h, recorder, depth + 1, false)?;
        let mut second = self.advance_cut(0.5 * h, recorder, depth + 1, last_piece)?;
        self.shift_obstacles(-lag, &velocities);
        second.iterations += first.iterations;
        second.cuts += first.cuts + 1;
        second.cuts_out_of_iterations += first.cuts_out_of_iterations;
        second.held_contacts = second.held_contacts.max(first.held_contacts);
        second.held_open_depth = second.held_open_depth.max(first.held_open_depth);
        if first.held_tension / first.compression.max(f64::MIN_POSITIVE)
            > second.held_tension / second.compression.max(f64::MIN_POSITIVE)
        {
            (second.held_tension, second.compression) = (first.held_tension, first.compression);
        }
        second.globalized |= first.globalized;
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

    /// Whether gaps are measured on the running eq 22 displacement: chosen, and a penalty
    /// method (the projections put the configuration itself on the surface).
    fn gaps_on_trapezoid(&self) -> bool {
        self.model.contact.gap_displacement == GapDisplacement::Trapezoid
            && methods::method(self.model.contact.method).end_projection() == EndProjection::None
    }

    /// How a re-expression of the state between steps (a change of step size, the augmented
    /// Lagrangian's persistency stop) moves body `body`'s configuration and gaps'
    /// displacement: `(c_u, c_gap)` per unit of the change `h v - h' v'` (`h (v - v')` for the
    /// stop). On configuration gaps both move together by `a = (alpha - beta) / 2`, which
    /// keeps the scheme's shadow displacement `w = u + a h v`. On trapezoid gaps the gaps'
    /// offset from the configuration, `h (1/2 - beta) (v - v(0))`, is kept, so that the two
    /// agree at rest: a linear law's body keeps w (`c_u = a`, the gaps
    /// `(alpha + beta - 1) / 2`, nothing at the default alpha + beta = 1, where they are w up
    /// to a constant); an updated-Lagrangian law's keeps its configuration (`c_u = 0`, the
    /// gaps `beta - 1/2`), since a shift of it would bypass its stress history (a hypoelastic
    /// block dropped under the augmented Lagrangian with halved steps ended 3.6e-2 off its
    /// account; `step_size_changes::the_configuration_rests_where_trapezoid_gaps_say_d2`).
    pub(super) fn reexpression_weights(&self, body: usize) -> (f64, f64) {
        let SpaceTimeScheme { alpha, beta } = self.model.settings.scheme;
        let a = 0.5 * (alpha - beta);
        if !self.gaps_on_trapezoid() {
            (a, a)
        } else if self
            .integration
            .get(body)
            .is_some_and(|i| i.law.updated_lagrangian())
        {
            (0.0, beta - 0.5)
        } else {
            (a, a + beta - 0.5)
        }
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

    /// The energy that the time scheme conserves at the current state (J):
    /// `Q = 1/2 v^T M v + U(u) + h/2 (alpha - beta) u^T K v + h^2/4 (alpha^2 - 2 alpha beta) v^T K v`.
    /// A step of a linear law with `beta = 1 - alpha` keeps it exactly, up to the work
    /// `f . (du + h/2 (alpha - beta) dv)` of constant external forces f; other `beta` scale
    /// each mode's part by the transfer matrix's determinant per step (numerical damping).
    /// It is E plus terms that vanish with h, except on stiff modes (`k h^2 / m >> 1`): there
    /// E swings along the orbit while Q stays, and the difference E - Q is that swing. For a
    /// law that is not linear, U is its stored energy and K the reference stiffness: Q is then
    /// kept only approximately.
    ///
    /// The step is the one the state's (u, v) belong to (`State::scheme_time_step`: the last
    /// step's), or the configured one before the first step.
    pub fn scheme_energy(&self) -> f64 {
        let s = &self.state;
        let h = if s.scheme_time_step > 0.0 {
            s.scheme_time_step
        } else {
            self.model.settings.time_step
        };
        self.scheme_energy_at(&s.displacement, &s.velocity, h, &s.material_history)
    }

    /// [`Self::scheme_energy`] at displacements `u`, velocities `v`, step `h` and material
    /// history `history` (the transfer matrix's invariant form `omega(x, T x)`, omega the
    /// symplectic form, written with M and K).
    pub(super) fn scheme_energy_at(&self, u: &[f64], v: &[f64], h: f64, history: &[f64]) -> f64 {
        let SpaceTimeScheme { alpha, beta } = self.model.settings.scheme;
        let (wu, wv) = self.stiffness_fields(u, v);
        // K wv once for both of its terms: this runs several times a contact step.
        let mut k_wv = vec![0.0; wv.len()];
        assembly::symmetric_mul_add(&self.matrices.stiffness, &wv, 1.0, &mut k_wv);
        let dot = |a: &[f64]| a.iter().zip(&k_wv).map(|(a, b)| a * b).sum::<f64>();
        0.5 * assembly::symmetric_dot(&self.matrices.mass, v, v)
            + self.internal_energy(u, history)
            + 0.5 * h * (alpha - beta) * dot(&wu)
            + 0.25 * (alpha * alpha - 2.0 * alpha * beta) * h * h * dot(&wv)
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
    /// `known` holds Q before and after where the caller has them already.
    #[allow(clippy::too_many_arguments)]
    fn projection_dissipation(
        &self,
        before: [&[f64]; 2],
        after: [&[f64]; 2],
        f_ext: &[f64],
        impulses: &[Vec<f64>],
        h: f64,
        history: &[f64],
        known: Option<(f64, f64)>,
    ) -> f64 {
        let SpaceTimeScheme { alpha, beta } = self.model.settings.scheme;
        let (q_before, q_after) = known.unwrap_or_else(|| {
            (
                self.scheme_energy_at(before[0], before[1], h, history),
                self.scheme_energy_at(after[0], after[1], h, history),
            )
        });
        let change = q_after - q_before;
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

    /// The pairs the end-of-step projection moves, at the end positions `x_end`: detected,
    /// then held as Newton held them (`held_pairs`, with the step's edge pairs `edge_held` and
    /// its active set `active`), then the master side's pairs between two bodies
    /// (`MasterNodes::Projected`), at any gap: those deeper than `master_tolerance` are moved
    /// out, the others are kept from going deeper than it. Returns the pairs and where the
    /// master side's begin.
    fn end_of_step_pairs(
        &mut self,
        start: &StepStart<D>,
        x_end: &[SVector<f64, D>],
        method: &dyn Method,
        edge_held: &mut BTreeSet<ContactKey>,
        active: &BTreeSet<ContactKey>,
    ) -> (Vec<ContactPair<D>>, usize) {
        let detector = self.caches.detector.as_mut().expect("contact detection");
        detector.update_candidates_posed(
            &start.x0,
            x_end,
            &start.obstacles_t0,
            &start.obstacles_t1,
        );
        let detected = detector.pairs(x_end, &start.obstacles_t1);
        let mut pairs = detected.clone();
        held_pairs(
            method,
            &mut pairs,
            detector,
            x_end,
            &self.node_offsets,
            edge_held,
            active,
        );
        let master_side = pairs.len();
        if self.model.contact.master_nodes == MasterNodes::Projected {
            // The pairs between two bodies that `held_pairs` dropped (it keeps the detected
            // order): the master side's nodes, never held. Within a fold the dropped side is
            // left alone: moved out, the folding strip's tip created 0.49 of the reference
            // energy, 4.5e-2 with the default tolerance (2026-12-02).
            let facet_body = detector.surface().facet_body();
            let mut held = pairs.iter().peekable();
            let unheld: Vec<ContactPair<D>> = detected
                .into_iter()
                .filter(|p| held.next_if_eq(&p).is_none())
                .filter(|p| match p.master {
                    Master::Facet(f) => facet_body[f] != body_of(&self.node_offsets, p.slave),
                    Master::Obstacle(_) => false,
                })
                .collect();
            pairs.extend(unheld);
        }
        (pairs, master_side)
    }

    /// One step without cutting. `count_step` is false for the first pieces of a cut step.
    fn advance_once(
        &mut self,
        h: f64,
        recorder: &mut dyn Recorder<D>,
        count_step: bool,
    ) -> Result<StepReport> {
        self.change_step_to(h)?;
        // The cached factorisations the state names first: rebuilding one refactors the
        // contact-free matrix for its own step size, which may not be this step's.
        self.sync_contact_factors()?;
        self.ensure_system(h)?;
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
        // Its impulses between bodies (for the body pairs' forces).
        let mut between_bodies: Vec<BodyImpulse<D>> = Vec::new();
        // Newton's locked master facets (`FLIPS_BEFORE_LOCK`) end with it: the end-of-step
        // projection and the penetration reported below take each node's closest facet.
        if let Some(detector) = self.caches.detector.as_mut() {
            detector.release_facet_locks();
        }
        let rule = method.end_projection();
        if rule != EndProjection::None && self.caches.detector.is_some() {
            let x_end = end_positions(&self.reference, &gap_u1, &v1, &vec![0.0; ndof], 0.0);
            // The edge pairs Newton held, and any the end positions put beyond an edge.
            let mut edge_held = vars.edge_held.clone();
            let (pairs, master_side) =
                self.end_of_step_pairs(&start, &x_end, method, &mut edge_held, &vars.active);
            let (u_before, v_before) = (u1.clone(), v1.clone());
            let mut impulses = vec![vec![0.0; D]; self.model.obstacles.len()];
            // Projected on the gaps' positions; the configuration moves with them.
            let gap_before = gap_u1.clone();
            if rule == EndProjection::Active
                && self.model.contact.projection == ProjectionMetric::Step
            {
                let detector = self.caches.detector.as_ref().expect("checked");
                let facets = detector.surface().facets().to_vec();
                // Again while a correction moved something: each can bring neighbours of
                // the contact patch into the master (at most `PROJECTION_PASSES`).
                let (mut pairs, mut master_side) = (pairs, master_side);
                for pass in 0..PROJECTION_PASSES {
                    let x_end = end_positions(&self.reference, &gap_u1, &v1, &vec![0.0; ndof], 0.0);
                    if pass > 0 {
                        (pairs, master_side) = self.end_of_step_pairs(
                            &start,
                            &x_end,
                            method,
                            &mut edge_held,
                            &vars.active,
                        );
                    }
                    let du = self.weighted_projection(
                        &pairs,
                        master_side,
                        &vars.active,
                        &facets,
                        &x_end,
                        h,
                        step,
                    )?;
                    if du.iter().all(|&d| d == 0.0) {
                        break;
                    }
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
                // The master side's pairs within the tolerance are for the step metric's
                // rows only.
                let depth = self.model.contact.master_tolerance;
                let pairs: Vec<ContactPair<D>> = pairs
                    .into_iter()
                    .enumerate()
                    .filter(|(i, p)| *i < master_side || p.gap < -depth)
                    .map(|(_, p)| p)
                    .collect();
                project(
                    &context,
                    &pairs,
                    &mut gap_u1,
                    &mut v1,
                    &mut impulses,
                    &mut applied,
                    &mut between_bodies,
                );
            }
            for i in 0..ndof {
                u1[i] += gap_u1[i] - gap_before[i];
            }
            // Q before and after the correction, where the bound has measured them.
            let mut known = None;
            if self.model.contact.projection_energy == ProjectionEnergy::Bounded
                && rule == EndProjection::Active
                && self.model.contact.projection == ProjectionMetric::Step
            {
                known = self.remove_projection_energy(
                    &u_before,
                    &u1,
                    &mut v1,
                    f_ext,
                    h,
                    material_history,
                    self.state.dissipated() + h * terms.dissipation_rate,
                );
            }
            projection_dissipation = self.projection_dissipation(
                [&u_before, &v_before],
                [&u1, &v1],
                f_ext,
                &impulses,
                h,
                material_history,
                known,
            );
            if self.obstacles_turn() {
                // Turning obstacles' impulses also work through their turning.
                projection_dissipation +=
                    self.spin_work(h, &start.obstacles_t1, applied.iter().copied());
            }
            for (total, impulse) in contact_forces.iter_mut().zip(&impulses) {
                for (t, i) in total.iter_mut().zip(impulse) {
                    *t += i;
                }
            }
        }

        // The persistency condition on trapezoid gaps (`ContactSettings::stops_closed_pairs`).
        if self.model.contact.stops_closed_pairs() {
            let (u_before, v_before) = (u1.clone(), v1.clone());
            let mut impulses = vec![vec![0.0; D]; self.model.obstacles.len()];
            let first_applied = applied.len();
            for (key, point, force) in self.stop_closed_pairs(&terms.pairs, &mut v1, h, step)? {
                match key.1 {
                    MasterId::Obstacle(k) => {
                        for (total, f) in impulses[k].iter_mut().zip(force.iter()) {
                            *total += f;
                        }
                        applied.push((k, point, force));
                    }
                    MasterId::Body(b) => between_bodies.push((key.0, b, force)),
                }
            }
            // Keeps the gaps' offset from the configuration eq 22's, as a change of step does
            // (`reexpression_weights`). Left as they were, the configuration drifted off its
            // gaps by `h (1/2 - beta) dv` a stop: an AL block stack rested 0.3-0.5 mm inside
            // the floor its gaps said it touched.
            for body in 0..self.model.bodies.len() {
                let (c_u, c_gap) = self.reexpression_weights(body);
                let nodes = self.nodes_of(body);
                for i in nodes.start * D..nodes.end * D {
                    let change = -h * (v1[i] - v_before[i]);
                    u1[i] += c_u * change;
                    gap_u1[i] += c_gap * change;
                }
            }
            projection_dissipation += self.projection_dissipation(
                [&u_before, &v_before],
                [&u1, &v1],
                f_ext,
                &impulses,
                h,
                material_history,
                None,
            );
            if self.obstacles_turn() {
                projection_dissipation += self.spin_work(
                    h,
                    &start.obstacles_t1,
                    applied[first_applied..].iter().copied(),
                );
            }
            for (total, impulse) in contact_forces.iter_mut().zip(&impulses) {
                for (t, i) in total.iter_mut().zip(impulse) {
                    *t += i;
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
        state.scheme_time_step = h;
        state.displacement = u1;
        state.gap_displacement = gap_u1;
        state.velocity = v1;
        state.external_work += work;
        state.dissipated_energy +=
            h * terms.dissipation_rate + projection_dissipation + damping_loss;
        // What the penalty's normal forces took from the bodies less what the gaps store
        // more: the paper's end-of-step pressure's zeta A (g1 - g0)^2 / 2 a step (backward
        // Euler on the contact spring) plus the configuration gaps' offset from the trapezoid
        // increment (the secant's: nothing on trapezoid gaps); booked while the net is a loss
        // (`State::dissipated`), since a net gain is the offset's pump, which the monitor must
        // see. Unbooked, a settling stack of soft blocks under the soft way fell 6 % short of
        // its account.
        state.contact_loss += h * terms.normal_work_rate - (terms.energy - state.contact_energy);
        state.obstacle_translations = start.translations_t1.clone();
        state.obstacle_rotations = start.rotations_t1.clone();
        state.material_history.clone_from(material_history);
        state.contact_energy = terms.energy;
        state.multipliers = if method.closed_by_active_set() {
            // The held points' forces at the step's end, not the last multiplier update's:
            // the outer iteration ends where the constraints are met to `gap_tolerance / h`,
            // which the penalty (1e4 diagonals) still turns into newtons (a resting block's
            // multipliers were 2.5 % (2D) and 23 % (3D) off the floor's force).
            terms
                .pairs
                .iter()
                .filter(|p| vars.active.contains(&p.key))
                .map(|p| (p.key.0, p.key.1, p.normal_force.max(0.0)))
                .collect()
        } else {
            vars.multipliers
                .iter()
                .map(|(&(s, m), &l)| (s, m, l))
                .collect()
        };
        state.friction_normals = friction_normals
            .iter()
            .map(|(&(s, m), &f)| (s, m, f))
            .collect();
        state.friction_anchors = terms
            .pairs
            .iter()
            .filter_map(|p| p.anchor.map(|a| (p.key.0, p.key.1, a.as_slice().to_vec())))
            .collect();
        state.active_contacts = if method.keeps_closed_points() {
            terms
                .pairs
                .iter()
                .filter(|p| p.normal_force > 0.0)
                .map(|p| p.key)
                .collect()
        } else {
            vars.active.iter().copied().collect()
        };
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
        if finite && energies.internal.is_nan() {
            // Finite fields but an updated-Lagrangian cell folded at the end of the step (the
            // end-of-step projection moved a node through its own cell): an inverted cell,
            // which a cut step may avoid, not an instability.
            self.state = previous;
            return Err(Error::InvertedCell {
                step,
                time: t0 + h,
                halvings: 0,
                place: None,
            });
        }
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
                advice: self.instability_advice(!finite || !energies.total().is_finite()),
            });
        }
        self.log_contacts(&terms.pairs, &terms.forces, &between_bodies);
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
        // What the points held closed pull with (their tension, N) against what the step's
        // contacts push with: the price of a cycle's compromise.
        let (held_tension, compression) = terms.pairs.iter().fold((0.0, 0.0), |(t, c), p| {
            if vars.locked.contains(&p.key) && p.normal_force < 0.0 {
                (t - p.normal_force, c)
            } else {
                (t, c + p.normal_force.max(0.0))
            }
        });
        // How far the points held open end on the wrong side of the law, in the gap's terms
        // (the law's constraint, h/2 per unit): a point that penetrates while it approaches
        // would have been activated.
        let held_open_depth = terms
            .pairs
            .iter()
            .filter(|p| vars.locked.contains(&p.key) && !vars.active.contains(&p.key))
            .map(|p| -0.5 * h * implicit_projection::constraint(p.normal_velocity, p.gap, h))
            .fold(0.0_f64, f64::max);
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
            cuts_out_of_iterations: 0,
            globalized: false,
            held_contacts: vars.locked.len(),
            held_tension,
            compression,
            held_open_depth,
            contact_cycles: 0,
            factorisations: 0,
        };
        recorder.step_end(self, &report);
        Ok(report)
    }
}

#[cfg(test)]
mod tests;
