//! Newton's method on the momentum balance at `t_alpha`,
//! `R(v1) = M (v1 - v0)/h + f_int(u_alpha) - f_ext - f_c(v1) = 0`, with the contact method's
//! outer loop around it (multiplier or active-set updates, the friction threshold's fixed
//! point). Prescribed components are set in the initial guess and kept; the tangent is the
//! contact-free iteration matrix plus the contact entries, solved by
//! [`linear_solve`](super::linear_solve). A step whose residual grows is backtracked (contact
//! and friction are not smooth).

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::SVector;

use super::contact_terms::{ContactTerms, RankOne, TermsInput};
use super::held_pairs::held_pairs;
use super::line_search::{free_dot, merit, HeldPredictions, LineSearch, Verdict};
use super::linear_solve::woodbury;
use super::observe::{IterationInfo, Recorder};
use super::{end_positions, Simulation};
use crate::assembly::{self, KernelFields};
use crate::contact::methods::{self, Method, OuterUpdate, OuterVariables, PairOutcome, PairStatus};
use crate::contact::{ContactKey, FrictionLaw, MasterId, Obstacle};
use crate::dim::{Dim, Kinematics, SpatialDim};
use crate::error::{Error, Result};
use crate::friction::{ThresholdIteration, ThresholdSample};

/// A residual no larger than this multiple of the contact forces' floating-point noise
/// (`ContactTerms::round_off`), where an iteration stopped halving it, is converged: Newton
/// cannot reduce it further. (The implicit projection's velocity penalty, 1e4 times the
/// diagonal, puts that floor near a relative residual of 5e-8 on a block carried by a drum of
/// 1 m radius: Newton went on at 5.8e-8 and 9.95e-8 in turn until it ran out of iterations.
/// Laws with a tangent add `Simulation::tangent_round_off`: in the tube crush under implicit
/// projection, Norton-Hoff at m = 0.1 in the part riding on the plate at 50 m/s put that noise
/// at 2.9 N, and Newton wandered between 0.66 and 1.06 N at step 764 until it gave up.)
const ROUND_OFF_FACTOR: f64 = 4.0;
/// Iterations in a row that must stall at that floor (the bound is an estimate: a stiff
/// soft-way bar impact still halves its residual below it now and then).
const FLOOR_STALLS: usize = 3;
/// Halvings of a Newton increment while the residual grows.
const MAX_BACKTRACKS: usize = 4;
/// A pass that solves with thresholds that have not settled (Coulomb's lagged threshold,
/// `ThresholdIteration`) stops at this fraction of their last relative change (not below the
/// tolerance): the next thresholds are then within 1 % of the exact map's, and the passes
/// spend no iterations on digits the next update discards (an inexact fixed point). The last
/// pass, whose thresholds settle, goes on to the tolerance. Measured (release, 2026-12-01): the
/// bundled block stack 1012 -> 928 Newton iterations, its worst step 45 -> 39; the 3D
/// two-block stack 578 -> 528; 1e-1 saves less (960), as its passes end further from the
/// next thresholds.
const UNSETTLED_PASS_FRACTION: f64 = 1e-2;
/// Takes back half of the last Newton increment (backtracking).
fn halve_last_increment(v1: &mut [f64], last_increment: &mut [f64]) {
    for (v, d) in v1.iter_mut().zip(last_increment.iter_mut()) {
        *d *= 0.5;
        *v -= *d;
    }
}

/// The relative residual below which the laws' consistent tangents replace their secant ones
/// (on the octagon of the paper's example 2: 10 iterations per step on average at 1e-1,
/// `cargo run --features formats --example octagon_compression`).
const SECANT_UNTIL: f64 = 1e-1;
/// Halvings of a Newton increment that turned a cell inside out (1e-6 of it at most).
const MAX_INVERSION_BACKTRACKS: usize = 20;

/// Most rank-one terms (slipping Coulomb contacts, held normal velocities on a turning
/// normal) that enter a Newton solve (about two GMRES iterations each, or one extra symmetric
/// solve each where GMRES falls back to [`woodbury`]); beyond, Newton goes on without them
/// (quasi-Newton).
const MAX_COUPLED: usize = 64;

/// Why a step's Newton iteration stopped short of its tolerance (for the message).
#[derive(Clone, Copy)]
enum Stall {
    /// `max_iterations` spent.
    Iterations,
    /// Implicit projection's active set came back with no point left to hold.
    ContactCycle,
    /// `max_passes` contact passes (multiplier or active-set updates) without settling.
    ContactPasses,
}

impl Stall {
    /// The cause and the advice; the error reaches the user after the step was retried with
    /// the line search and cut in halves.
    fn cause(self, max_iterations: usize, max_passes: usize) -> String {
        let retried = "the step was retried with a line search and cut in halves without success";
        match self {
            Stall::Iterations => format!(
                "max_iterations = {max_iterations} spent; {retried}: try a smaller time_step, \
                 or a larger max_iterations only if the residual was still falling (the Rerun \
                 recording shows it, `--rerun FILE.rrd`)"
            ),
            Stall::ContactCycle => format!(
                "implicit projection's contact set cycles (an active set came back with no \
                 point left to hold), not a residual above the tolerance; {retried}: try a \
                 smaller time_step, or contact.method = \"soft_way\""
            ),
            Stall::ContactPasses => format!(
                "the contact passes did not settle in {max_passes} passes; {retried}: try a \
                 smaller time_step (library: a larger ContactSettings::max_passes)"
            ),
        }
    }
}

/// What a step starts from.
pub(super) struct StepStart<const D: usize> {
    /// Step number (1-based).
    pub step: usize,
    /// Time at the start (s).
    pub t0: f64,
    /// Step size (s).
    pub h: f64,
    /// Displacements and velocities at t0.
    pub u0: Vec<f64>,
    /// Velocities at t0 (m/s).
    pub v0: Vec<f64>,
    /// The displacement gaps are measured on at t0 (m; see `GapDisplacement`).
    pub gap_u0: Vec<f64>,
    /// External forces at t_alpha (N).
    pub f_ext: Vec<f64>,
    /// Positions at t0 that gaps are measured on (m).
    pub x0: Vec<SVector<f64, D>>,
    /// The obstacles at t0 and t1.
    pub obstacles_t0: Vec<Obstacle<D>>,
    /// The obstacles at t1.
    pub obstacles_t1: Vec<Obstacle<D>>,
    /// Obstacle translations at t1 (flat) (m).
    pub translations_t1: Vec<f64>,
    /// Obstacle rotations at t1 (stored values, see `State::obstacle_rotations`).
    pub rotations_t1: Vec<f64>,
    /// Face shares of the boundary nodes at t0.
    pub areas: Vec<Vec<(f64, SVector<f64, D>)>>,
}

/// What Newton and the outer loop converged to.
pub(super) struct Solution<const D: usize> {
    /// End velocities (m/s).
    pub v1: Vec<f64>,
    /// The residual at the solution (its prescribed rows are the reactions) (N).
    pub residual: Vec<f64>,
    /// The contact terms at the solution.
    pub terms: ContactTerms<D>,
    /// The method's outer variables at the solution.
    pub vars: OuterVariables,
    /// The friction thresholds at the solution.
    pub friction_normals: BTreeMap<ContactKey, f64>,
    /// Linear solves.
    pub iterations: usize,
    /// Final relative residual.
    pub relative: f64,
    /// The material history at the end of the step (the law's at the solution).
    pub material_history: Vec<f64>,
    /// The damping forces the element kernel added at the solution (damped
    /// updated-Lagrangian bodies; empty otherwise) (N).
    pub kernel_damping_forces: Vec<f64>,
}

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// Whether any friction law is active.
    fn frictional(&self) -> bool {
        self.model.contact.friction != FrictionLaw::Frictionless
            || self
                .model
                .obstacles
                .iter()
                .any(|o| o.friction.is_some_and(|f| f != FrictionLaw::Frictionless))
    }

    /// Where a step that does not converge is stuck, for its message: the free unknown with
    /// the largest residual (its node, body and position at the step's start, `u0`), whether
    /// that node is a contact point (its master, gap and normal force), and how many pairs
    /// the step has.
    fn residual_site(&self, residual: &[f64], pairs: &[PairOutcome<D>], u0: &[f64]) -> String {
        let worst = (0..residual.len())
            .filter(|&i| self.prescribed[i].is_none() && residual[i].is_finite())
            .max_by(|&a, &b| residual[a].abs().total_cmp(&residual[b].abs()));
        let Some(i) = worst else {
            return "no free unknown".into();
        };
        let node = i / D;
        let x = self.reference[node] + Self::node_vector(u0, node);
        let position: Vec<String> = x.iter().map(|c| format!("{c:.4e}")).collect();
        // Plane kinematics carry forces per metre of depth.
        let unit = match self.model.settings.kinematics {
            Kinematics::PlaneStrain | Kinematics::PlaneStress => "N/m",
            Kinematics::Axisymmetric | Kinematics::Solid => "N",
        };
        let mut site = format!(
            "the largest residual, {:.3e} {unit}, is at {} (x = ({}) m)",
            residual[i].abs(),
            self.node_name(node),
            position.join(", ")
        );
        let touching: Vec<String> = pairs
            .iter()
            .filter(|p| p.key.0 == node)
            .map(|p| {
                format!(
                    "{} (gap {:.3e} m, normal force {:.3e} {unit})",
                    self.master_name(p.key.1),
                    p.gap,
                    p.normal_force
                )
            })
            .collect();
        if pairs.is_empty() {
            site.push_str(", no contact in the step");
            return site;
        }
        if touching.is_empty() {
            site.push_str(", not a contact point");
        } else {
            site.push_str(&format!(", a contact point on {}", touching.join(" and ")));
        }
        let pressing = pairs.iter().filter(|p| p.normal_force != 0.0).count();
        site.push_str(&format!(
            "; {} contact pair(s) in the step, {pressing} with a normal force",
            pairs.len()
        ));
        site
    }

    /// The points implicit projection's cycling contact set kept switching, for its message.
    fn cycle_site(&self, vars: &OuterVariables) -> String {
        const LISTED: usize = 4;
        let switching: Vec<String> = vars
            .releases
            .keys()
            .take(LISTED)
            .map(|&(node, master)| {
                format!("{} on {}", self.node_name(node), self.master_name(master))
            })
            .collect();
        let more = vars.releases.len().saturating_sub(LISTED);
        format!(
            "{} point(s) active when the set came back, {} released in the step{}{}",
            vars.active.len(),
            vars.releases.len(),
            if switching.is_empty() {
                String::new()
            } else {
                format!(": {}", switching.join(", "))
            },
            if more > 0 {
                format!(" and {more} more")
            } else {
                String::new()
            }
        )
    }

    /// `node N of body `NAME`` (N counted within the body, from 0).
    fn node_name(&self, global: usize) -> String {
        let (b, local) = self.owner_of(global);
        format!("node {local} of body `{}`", self.model.bodies[b].name)
    }

    /// Each pair's normal force for the Coulomb thresholds. A projection's edge pair is
    /// frictionless (two sticking pairs on one edge over-constrain the slip), so its normal
    /// force goes to the thresholds of the nodes of its master facet that hold its body, by
    /// the closest point's weights: the patch's friction limit stays mu times all the load it
    /// carries. (Frictionless and not passed on, a 5 cm block sliding on a coarser one under
    /// Coulomb 0.3 slowed at 0.67 (2D) and 0.31 (3D) of mu g: its perimeter nodes were edge
    /// pairs and carried most of its weight.) A node holds while its pair is closed (`closed`:
    /// the method's status, not the sign of its own force): a holding node whose own force
    /// hovers about zero would otherwise take and drop the load of its neighbours' edge pairs
    /// from one pass to the next (the 240 Hz rubber stack cycled on that, a node's threshold
    /// 0.65 N and 0 in turn while its own force read +0.011 N and -0.006 N).
    fn threshold_samples(
        &self,
        pairs: &[PairOutcome<D>],
        x: &[SVector<f64, D>],
        closed: &dyn Fn(&PairOutcome<D>) -> bool,
    ) -> Vec<ThresholdSample<ContactKey>> {
        let mut forces: BTreeMap<ContactKey, f64> = pairs
            .iter()
            .filter(|p| p.carried_by.is_none())
            .map(|p| (p.key, p.normal_force.max(0.0)))
            .collect();
        let holds: BTreeSet<ContactKey> = pairs
            .iter()
            .filter(|p| p.carried_by.is_none() && closed(p))
            .map(|p| p.key)
            .collect();
        for p in pairs {
            let Some(facet) = p.carried_by else {
                continue;
            };
            if p.normal_force <= 0.0 {
                continue;
            }
            let body = MasterId::Body(self.body_of_node(p.key.0));
            let mut holding: Vec<(ContactKey, f64)> = facet
                .iter()
                .filter(|&&(n, w)| w > 0.0 && holds.contains(&(n, body)))
                .map(|&(n, w)| ((n, body), w))
                .collect();
            if holding.is_empty() {
                // None of the facet's nodes holds (released while the edge pairs took the
                // load): the nearest node that does.
                let nearest = holds
                    .iter()
                    .filter(|&&(n, m)| m == body && n != p.key.0)
                    .min_by(|a, b| {
                        let d = |k: &ContactKey| (x[k.0] - x[p.key.0]).norm_squared();
                        d(a).total_cmp(&d(b))
                    });
                holding.extend(nearest.map(|&key| (key, 1.0)));
            }
            let total: f64 = holding.iter().map(|(_, w)| w).sum();
            for (key, w) in holding {
                *forces.get_mut(&key).expect("held") += p.normal_force * w / total;
            }
        }
        pairs
            .iter()
            .filter(|p| p.carried_by.is_none())
            .map(|p| ThresholdSample {
                key: p.key,
                law: self.friction_law(p.obstacle),
                normal_force: forces[&p.key],
            })
            .collect()
    }

    /// `obstacle `NAME`` or `body `NAME``.
    fn master_name(&self, master: MasterId) -> String {
        match master {
            MasterId::Obstacle(k) => format!("obstacle `{}`", self.model.obstacles[k].name),
            MasterId::Body(b) => format!("body `{}`", self.model.bodies[b].name),
        }
    }

    /// Newton with the contact method's outer loop: the end velocities of the step.
    pub(super) fn solve_step(
        &mut self,
        start: &StepStart<D>,
        recorder: &mut dyn Recorder<D>,
    ) -> Result<Solution<D>> {
        let (step, t0, h) = (start.step, start.t0, start.h);
        let (u0, v0, f_ext) = (&start.u0, &start.v0, &start.f_ext);
        let (d0, d1) = self.model.settings.scheme.displacement_weights();
        let ndof = v0.len();
        let method: &dyn Method = methods::method(self.model.contact.method);
        let contact_in_newton = self.caches.detector.is_some() && method.in_newton();
        let diagonal = self.system_diagonal().to_vec();
        let frictional = self.frictional();
        let tolerance = self.model.settings.tolerance;
        let max_iterations = self.model.settings.max_iterations;
        let max_passes = self.model.contact.max_passes;
        let not_converged =
            |iterations: usize, residual: f64, site: String, why: Stall| Error::NotConverged {
                step,
                time: t0,
                iterations,
                residual,
                tolerance,
                site,
                cause: why.cause(max_iterations, max_passes),
            };

        let mut friction_normals: BTreeMap<ContactKey, f64> = self
            .state
            .friction_normals
            .iter()
            .map(|&(s, m, f)| ((s, m), f))
            .collect();
        let mut thresholds = ThresholdIteration::default();
        // How far the thresholds the pass solves with are from settling (0: settled, or no
        // Coulomb threshold in flux).
        let mut thresholds_unsettled = 0.0;
        // The elastic slips of the return-map laws (world components).
        let friction_anchors: BTreeMap<ContactKey, SVector<f64, D>> = self
            .state
            .friction_anchors
            .iter()
            .map(|(s, m, a)| ((*s, *m), SVector::from_column_slice(a)))
            .collect();
        let mut vars = OuterVariables::default();
        if method.carries_multipliers() {
            vars.multipliers = self
                .state
                .multipliers
                .iter()
                .map(|&(s, m, l)| ((s, m), l))
                .collect();
        }
        let mut passes = 0;

        let mut v1 = v0.clone();
        for (dof, p) in self.prescribed.iter().enumerate() {
            if let Some(v) = p {
                v1[dof] = *v;
            }
        }
        let mut u_alpha = vec![0.0; ndof];
        let mut residual = vec![0.0; ndof];
        let mut iterations = 0;
        let mut terms = ContactTerms::<D>::default();
        let mut candidates = 0;
        let mut previous_norm = f64::INFINITY;
        let mut previous_merit = f64::INFINITY;
        let mut last_increment: Vec<f64> = Vec::new();
        let mut predictions = HeldPredictions::default();
        // -M v0 / h: the same in every iteration.
        let mut momentum0 = vec![0.0; ndof];
        assembly::symmetric_mul_add(&self.matrices.mass, v0, -1.0 / h, &mut momentum0);
        let mut backtracks = 0;
        let mut line: Option<LineSearch> = None;
        // The globalized Newton (`Simulation::globalized_newton`): a line search on the step's
        // energy, and the secant tangent for slips that turned (`friction::return_map`), which
        // implicit projection's Newton always takes (its return map on a lagged threshold;
        // with the penalty methods' stiffer spring the plain Newton cut more steps with it:
        // the book, contact resolution). The friction forces' directions at the last accepted
        // iterate (unit vectors) tell which turned.
        let globalized = self.globalized_newton;
        let mut floor_stalls = 0;
        let mut slip_directions: BTreeMap<ContactKey, SVector<f64, D>> = BTreeMap::new();
        let general = self.uses_general_path();
        let mut tangent_values: Vec<f64> = Vec::new();
        let mut material_history = self.state.material_history.clone();
        let mut kernel_damping_forces = Vec::new();
        let mut secant = true;
        loop {
            let x_gap = end_positions(&self.reference, &start.gap_u0, v0, &v1, h);
            if contact_in_newton {
                let detector = self.caches.detector.as_mut().expect("contact_in_newton");
                detector.update_candidates_posed(
                    &start.x0,
                    &x_gap,
                    &start.obstacles_t0,
                    &start.obstacles_t1,
                );
                candidates = detector.candidates().len();
                let mut pairs = detector.pairs(&x_gap, &start.obstacles_t1);
                held_pairs(
                    method,
                    &mut pairs,
                    detector,
                    &x_gap,
                    &self.node_offsets,
                    &mut vars.edge_held,
                    &vars.active,
                );
                if !vars.started {
                    // Predicted to penetrate, or held when the last step ended: a point
                    // resting on a master starts held, instead of falling through it for a
                    // pass (on a stack of soft blocks, 0.75 mm at 1.5 m/s, from which the
                    // next pass's Newton with Coulomb friction did not come back).
                    let held: BTreeSet<ContactKey> =
                        self.state.active_contacts.iter().copied().collect();
                    let starting: Vec<ContactKey> = pairs
                        .iter()
                        .map(|p| (p.gap, self.contact_key(p)))
                        .filter(|(gap, key)| *gap < 0.0 || held.contains(key))
                        .map(|(_, key)| key)
                        .collect();
                    method.start(&mut vars, &starting);
                    vars.started = true;
                }
                let held_predictions = predictions.update();
                terms = self.contact_terms(
                    &pairs,
                    &TermsInput {
                        method,
                        obstacles_t1: &start.obstacles_t1,
                        x_gap: &x_gap,
                        v0,
                        v1: &v1,
                        time_step: h,
                        areas: &start.areas,
                        vars: &vars,
                        friction_normals: &friction_normals,
                        friction_anchors: &friction_anchors,
                        diagonal: &diagonal,
                        slip_directions: &slip_directions,
                        held_predictions,
                    },
                );
            }
            for i in 0..ndof {
                u_alpha[i] = u0[i] + h * (d0 * v0[i] + d1 * v1[i]);
            }
            let mut inertia = momentum0.clone();
            let mut momentum1 = vec![0.0; ndof];
            assembly::symmetric_mul_add(&self.matrices.mass, &v1, 1.0 / h, &mut momentum1);
            // Linear laws: K u_alpha with the K assembled once; other laws: the element
            // kernel's forces and tangent at this iterate.
            // The velocity at the collocation instant: rate-dependent laws and damping read it.
            let alpha = self.model.settings.scheme.alpha;
            let v_alpha: Vec<f64> = if general || self.damping.is_some() {
                (0..ndof)
                    .map(|i| (1.0 - alpha) * v0[i] + alpha * v1[i])
                    .collect()
            } else {
                Vec::new()
            };
            let mut internal = if general {
                // The configuration update u1, for the history of updated-Lagrangian laws.
                let (c0, c1) = self.model.settings.scheme.update_weights();
                let u1: Vec<f64> = (0..ndof)
                    .map(|i| u0[i] + h * (c0 * v0[i] + c1 * v1[i]))
                    .collect();
                let integrated = assembly::integrate(
                    &self.table,
                    Some(&self.pattern),
                    &self.reference,
                    &self.integration,
                    &KernelFields {
                        displacement: Some(&u_alpha),
                        velocity: Some(&v_alpha),
                        start: Some(u0),
                        end: Some(&u1),
                        weights: (d1 * h, alpha),
                        secant,
                        time_step: h,
                        alpha,
                    },
                    &self.state.material_history,
                    ndof,
                );
                if integrated.energy.is_nan() {
                    // A cell turned inside out at this iterate: back off along the last
                    // increment, or give up on the step (the step is cut).
                    if backtracks < MAX_INVERSION_BACKTRACKS {
                        if let Some(search) = &mut line {
                            search.halved();
                            predictions.set_length(search.length());
                            v1 = search.iterate(search.length());
                            backtracks += 1;
                            continue;
                        }
                        if !last_increment.is_empty() {
                            halve_last_increment(&mut v1, &mut last_increment);
                            predictions.halve();
                            backtracks += 1;
                            continue;
                        }
                    }
                    let place = integrated.inverted.map(|(body, nodes)| {
                        // Where the cell is at the start of the step: reference plus u0.
                        let centre: SVector<f64, D> = nodes
                            .iter()
                            .map(|&n| {
                                self.reference[n] + SVector::<f64, D>::from_fn(|k, _| u0[n * D + k])
                            })
                            .sum::<SVector<f64, D>>()
                            / nodes.len() as f64;
                        (
                            self.model.bodies[body].name.clone(),
                            centre.as_slice().to_vec(),
                        )
                    });
                    return Err(Error::InvertedCell {
                        step,
                        time: t0 + h,
                        halvings: backtracks,
                        place,
                    });
                }
                tangent_values = integrated.tangent.unwrap_or_default();
                material_history = integrated.history;
                kernel_damping_forces = integrated.damping_forces;
                integrated.forces
            } else {
                let mut internal = vec![0.0; ndof];
                assembly::symmetric_mul_add(&self.matrices.stiffness, &u_alpha, 1.0, &mut internal);
                internal
            };
            if let Some(c) = &self.damping {
                // Rayleigh damping at the collocation instant, with the internal forces.
                assembly::symmetric_mul_add(c, &v_alpha, 1.0, &mut internal);
            }
            let mut free_norm2 = 0.0;
            let mut scale2 = [0.0f64; 5];
            for i in 0..ndof {
                let contact = terms.forces.get(i).copied().unwrap_or(0.0);
                let old = inertia[i];
                inertia[i] += momentum1[i];
                residual[i] = inertia[i] + internal[i] - f_ext[i] - contact;
                if self.prescribed[i].is_none() {
                    free_norm2 += residual[i] * residual[i];
                }
                // The scale includes prescribed dofs: at equilibrium the free-dof forces
                // cancel, while the reactions carry the load level.
                scale2[0] += old * old;
                scale2[1] += momentum1[i] * momentum1[i];
                scale2[2] += internal[i] * internal[i];
                scale2[3] += f_ext[i] * f_ext[i];
                scale2[4] += contact * contact;
            }
            let scale = scale2.iter().fold(0.0f64, |m, s| m.max(s.sqrt()));
            let norm = free_norm2.sqrt();
            let rel = if scale > 0.0 { norm / scale } else { 0.0 };
            let merit = merit(norm, &residual, &terms, &self.prescribed);
            // Kacanov's secant iteration until the residual is small, then Newton.
            secant = rel > SECANT_UNTIL;
            if !rel.is_finite() {
                return Err(Error::Unstable {
                    step,
                    time: t0 + h,
                    detail: "the residual became non-finite".into(),
                    advice: self.instability_advice(true),
                });
            }
            // Backtracking: contact and friction are not smooth, and a full Newton step can
            // overshoot (first touch with a stiff penalty); halve it while the merit grows. An
            // iterate that converged is kept: the merit of the one before can be smaller than
            // its residual (a held constraint's curvature): the bundled folding strip's step
            // 342 took back converged iterates 28 times.
            if let Some(search) = &mut line {
                // The line search on the step's energy (`line_search`).
                match search.judge(free_dot(&residual, search.direction(), &self.prescribed)) {
                    Verdict::Retry(length) => {
                        v1 = search.iterate(length);
                        predictions.set_length(length);
                        backtracks += 1;
                        continue;
                    }
                    Verdict::Accept => line = None,
                }
            } else if contact_in_newton
                && !last_increment.is_empty()
                && merit > previous_merit
                && rel > tolerance
                && backtracks < MAX_BACKTRACKS
            {
                halve_last_increment(&mut v1, &mut last_increment);
                predictions.halve();
                backtracks += 1;
                continue;
            }
            backtracks = 0;
            let stalled_from = previous_norm;
            previous_norm = norm;
            previous_merit = merit;
            if frictional && (globalized || method.lagged_friction_threshold()) {
                slip_directions = terms
                    .pairs
                    .iter()
                    .filter(|p| p.friction != SVector::<f64, D>::zeros())
                    .map(|p| (p.key, p.friction.normalize()))
                    .collect();
            }
            // A residual within the floating-point noise of the contact forces (and, for laws
            // with a tangent of their own, of the internal and inertial forces) that Newton
            // stopped halving is converged too: it cannot be reduced further.
            let stalled = norm > 0.5 * stalled_from;
            let round_off = if stalled && rel > tolerance && general {
                terms
                    .round_off
                    .hypot(self.tangent_round_off(&tangent_values, &v1, h))
            } else {
                terms.round_off
            };
            if norm <= ROUND_OFF_FACTOR * round_off && stalled {
                floor_stalls += 1;
            } else {
                floor_stalls = 0;
            }
            // Loosened while Coulomb's thresholds are still moving (`UNSETTLED_PASS_FRACTION`).
            let pass_tolerance = tolerance.max(UNSETTLED_PASS_FRACTION * thresholds_unsettled);
            if rel <= pass_tolerance || floor_stalls >= FLOOR_STALLS {
                // Newton converged for the current outer variables.
                let statuses: Vec<PairStatus> = terms.pairs.iter().map(PairStatus::from).collect();
                let mut messages = Vec::new();
                // Only friction's thresholds read it.
                let active_before = frictional.then(|| vars.active.clone());
                let outcome =
                    method.outer_update(&statuses, &mut vars, &self.model.contact, h, &mut |m| {
                        messages.push(m)
                    });
                for m in messages {
                    recorder.log(self, &format!("step {step}: {m}"));
                }
                self.step_cycles += std::mem::take(&mut vars.cycles);
                if method.lagged_friction_threshold() {
                    // A released point carries no threshold into its next activation.
                    friction_normals.retain(|k, _| vars.active.contains(k));
                }
                if active_before.is_some_and(|before| before != vars.active) {
                    // Another problem for the thresholds: no mixing across it (a multiplier
                    // update is the same problem, solved closer).
                    thresholds.forget();
                }
                let mut done = match outcome {
                    OuterUpdate::Converged => true,
                    OuterUpdate::Again => false,
                    OuterUpdate::Cycle => {
                        let site = self.cycle_site(&vars);
                        return Err(not_converged(iterations, rel, site, Stall::ContactCycle));
                    }
                };
                // A pass after another change (active set, multipliers) is solved to the
                // tolerance: its outer update reads the solution's signs.
                thresholds_unsettled = 0.0;
                if done
                    && frictional
                    && (!method.friction_return_map() || method.lagged_friction_threshold())
                {
                    // A lagged threshold (implicit projection's return map, or the smooth law)
                    // follows the normal force until it settles; the penalty methods' return
                    // map reads the current normal force instead.
                    let closed = |p: &PairOutcome<D>| {
                        if method.closed_by_active_set() {
                            vars.active.contains(&p.key)
                        } else {
                            p.normal_force > 0.0
                        }
                    };
                    let samples = self.threshold_samples(&terms.pairs, &x_gap, &closed);
                    if let Some(next) = thresholds.next(&samples, &friction_normals) {
                        thresholds_unsettled = thresholds.last_change();
                        done = false;
                        friction_normals = next;
                        // A new threshold is a new problem: an active set seen under the old
                        // one is not a cycle.
                        vars.seen_sets.clear();
                    }
                }
                // Settled on an inexact pass: Newton goes on to the tolerance in this pass.
                let to_tolerance = done && rel > tolerance && floor_stalls < FLOOR_STALLS;
                if done && !to_tolerance {
                    return Ok(Solution {
                        v1,
                        residual,
                        terms,
                        vars,
                        friction_normals,
                        iterations,
                        relative: rel,
                        material_history,
                        kernel_damping_forces,
                    });
                }
                if !to_tolerance {
                    passes += 1;
                    previous_norm = f64::INFINITY;
                    previous_merit = f64::INFINITY;
                    predictions.clear();
                    floor_stalls = 0;
                    last_increment.clear();
                    line = None;
                    if passes > self.model.contact.max_passes {
                        let site = self.residual_site(&residual, &terms.pairs, u0);
                        return Err(not_converged(iterations, rel, site, Stall::ContactPasses));
                    }
                    continue;
                }
            }
            if iterations >= self.model.settings.max_iterations {
                let site = self.residual_site(&residual, &terms.pairs, u0);
                return Err(not_converged(iterations, rel, site, Stall::Iterations));
            }
            let mut increment: Vec<f64> = residual
                .iter()
                .zip(&self.prescribed)
                .map(|(r, p)| if p.is_some() { 0.0 } else { -r })
                .collect();
            // The closed branch of the pairs predicted closed, in the first direction only.
            for (i, f) in terms.predicted_forces.iter().enumerate() {
                if self.prescribed[i].is_none() {
                    increment[i] += f;
                }
            }
            vars.predicted.clear();
            // Linear solves go only as far as Newton needs: a tenth of its tolerance.
            let target = 0.1 * tolerance * scale;
            // The tangent's non-symmetric rank-one terms: implicit projection's held normal
            // velocity on a turning normal (without it Newton converges linearly where a fold
            // slides along itself, about 2.5x per iteration on the hairpin strip), and Coulomb
            // slip's threshold-to-gap coupling (without it each penalty method's Newton
            // converges linearly in slip: 4 to 5 times the iterations on the 2D slide, and the
            // bundled block stack under the augmented Lagrangian ran out of its 50 at step 4).
            let coupling: &[RankOne] = if terms.coupling.len() <= MAX_COUPLED {
                &terms.coupling
            } else {
                &[]
            };
            if general {
                let mut entries = terms.entries.clone();
                entries.extend_from_slice(&terms.geometric);
                // As in the linear path: where the contact's geometric part makes the matrix
                // indefinite, Newton goes on without it.
                let factor = match self.factor_with_tangent(&tangent_values, &entries, h, step) {
                    Err(_) if !terms.geometric.is_empty() => {
                        self.factor_with_tangent(&tangent_values, &terms.entries, h, step)?
                    }
                    factor => factor?,
                };
                let prescribed = &self.prescribed;
                increment = woodbury(
                    &mut |r, _| {
                        let mut x = r.to_vec();
                        factor.solve_in_place(&mut x);
                        Ok(x)
                    },
                    coupling,
                    prescribed,
                    &increment,
                    target,
                )?;
            } else if terms.entries.is_empty() {
                self.solve_contact_free(&mut increment);
            } else {
                let prescribed = self.prescribed.clone();
                let mut geometric: &[(usize, usize, f64)] = &terms.geometric;
                let coupled = if coupling.is_empty() {
                    None
                } else {
                    self.coupled_solve(
                        &terms.entries,
                        &mut geometric,
                        coupling,
                        &increment,
                        target,
                        step,
                    )?
                };
                increment = match coupled {
                    Some(x) => x,
                    None => woodbury(
                        &mut |r, target| {
                            self.symmetric_solve(&terms.entries, &mut geometric, r, target, h, step)
                        },
                        coupling,
                        &prescribed,
                        &increment,
                        target,
                    )?,
                };
            }
            if contact_in_newton && globalized && coupling.is_empty() {
                for (d, p) in increment.iter_mut().zip(&self.prescribed) {
                    if p.is_some() {
                        *d = 0.0;
                    }
                }
                let slope = free_dot(&residual, &increment, &self.prescribed);
                line = LineSearch::new(v1.clone(), increment.clone(), slope);
            }

            predictions.take(&terms.held, &increment, &self.prescribed);
            let mut inc2 = 0.0;
            for i in 0..ndof {
                if self.prescribed[i].is_none() {
                    v1[i] += increment[i];
                    inc2 += increment[i] * increment[i];
                }
            }
            last_increment = increment;
            iterations += 1;
            if !recorder.is_enabled() {
                continue;
            }
            let records = self.records(&terms, &x_gap, method, &vars);
            recorder.iteration(
                self,
                &IterationInfo {
                    step,
                    iteration: iterations,
                    time: t0,
                    time_step: h,
                    residual_norm: norm,
                    relative_residual: rel,
                    increment_norm: inc2.sqrt(),
                    end_velocity: &v1,
                    end_positions: &end_positions(&self.reference, &start.gap_u0, v0, &v1, h),
                    candidates,
                    contacts: &records,
                },
            );
        }
    }
}
