//! `Simulation<D>`: a model, its state, and the space-time velocity step.
//!
//! * [`model`]: what a simulation is made of (settings, bodies, obstacles, contact settings).
//! * [`state`]: everything that affects the next steps' results.
//! * `step`: the step as a pipeline (prediction, Newton with the contact method, end-of-step
//!   correction, energy account, commit or restore), with `newton` (the iteration loop),
//!   `contact_terms` (what each detected pair adds to the residual and tangent) and
//!   `linear_solve` (the factorisations and preconditioned solves).
//! * [`observe`]: the hooks a recorder receives.
//! * `monitor`: overlaps in the current configuration, the energy created beyond the input.

use faer::sparse::SparseColMat;
use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

mod builder;
mod cell_fields;
mod contact_terms;
mod contacts;
mod damping;
mod edit;
mod energy_projection;
mod fixed_timestep;
mod handles;
mod held_pairs;
mod line_search;
mod linear_solve;
pub mod model;
mod monitor;
mod newton;
pub mod observe;
mod obstacle_motion;
mod overlap;
mod rotation;
pub mod state;
mod step;
mod step_change;
mod symmetric_matrix;
mod weighted_projection;

pub use builder::SimulationBuilder;
pub use contacts::{ContactEvent, ContactMaster, ContactPoint, Touching};
pub use fixed_timestep::{FixedTimestep, FrameReport};
pub use handles::{BodyId, ObstacleId, Slots};
pub use linear_solve::SolverMemory;
pub use model::{Body, Constraint, MassKind, Model, RayleighDamping, Settings};
pub use monitor::{
    energy_created, Overlap, RunMonitor, Tunnel, ENERGY_FAILURE, ENERGY_WARNING,
    HELD_TENSION_FAILURE,
};
pub use rotation::SMALL_STRAIN_ROTATION_LIMIT;
pub use state::{ContactMemory, FactorRecord, MasterId, State};
pub use symmetric_matrix::SymmetricMatrix;

use crate::assembly::{self, BodyIntegration, CellTable, LinearMatrices, Pattern};
use crate::contact::{
    ContactMethod, ContactSettings, ContactSurface, DetectionOptions, Detector, Obstacle,
};
use crate::dim::{Dim, Kinematics, SpatialDim};
use crate::error::{Error, Result};
use crate::mesh::Mesh;
use crate::time::{Beta, SpaceTimeScheme};

/// Energies and works of the whole system (J) (per unit thickness in plane kinematics, over the
/// whole revolution in axisymmetric ones).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Energies {
    /// `1/2 v^T M v`.
    pub kinetic: f64,
    /// Stored elastic energy.
    pub internal: f64,
    /// Energy stored in soft-way penalties.
    pub contact: f64,
    /// Cumulative work of gravity, loads, moving obstacles and constraint reactions.
    pub external_work: f64,
    /// Cumulative dissipation: viscous, friction, the projections' corrections (signed), and
    /// the contacts' normal forces (a constraint's work, signed; a penalty's net loss,
    /// `State::contact_loss`).
    pub dissipated: f64,
}

impl Energies {
    /// Kinetic + internal + contact.
    pub fn total(&self) -> f64 {
        self.kinetic + self.internal + self.contact
    }
}

/// What one step did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepReport {
    /// Step number (1-based).
    pub step: usize,
    /// Time at the end of the step (s).
    pub time: f64,
    /// The step size used (s).
    pub time_step: f64,
    /// Newton plus contact-set iterations (linear solves).
    pub iterations: usize,
    /// Final relative residual.
    pub residual: f64,
    /// Energies at the end of the step.
    pub energies: Energies,
    /// Largest penetration at the end of the step (m).
    pub max_penetration: f64,
    /// Active contacts at the end of the step.
    pub active_contacts: usize,
    /// Force that each body's constraints exert on it during the step (N), by body.
    pub reactions: Vec<Vec<f64>>,
    /// Force that each obstacle exerts on the bodies during the step (N), by obstacle.
    pub contact_forces: Vec<Vec<f64>>,
    /// Slave points in contact at the end of the step, with their gap (m) and normal force (N)
    /// (global node, gap, force).
    pub contacts: Vec<(usize, f64, f64)>,
    /// Times the step was cut in two (no convergence, or a cell turned inside out).
    pub cuts: usize,
    /// Of those cuts, the ones whose attempt at the larger size spent `max_iterations`
    /// (rather than cycling, running out of contact passes or turning a cell inside out).
    #[serde(default)]
    pub cuts_out_of_iterations: usize,
    /// Whether Newton's plain iteration stalled on the step (or on a piece of it) and the
    /// globalized one solved it: a line search on the step's energy, and the secant tangent
    /// for friction slips that turned (`Simulation::step` tries it before it cuts a step).
    #[serde(default)]
    pub globalized: bool,
    /// Contact points whose status implicit projection held until the step ended because its
    /// active set cycled: points released twice in the step (kept closed) and, when an active
    /// set came back, the points that kept flipping (kept as they were). 0 for the other
    /// methods; the largest count of the pieces of a cut step.
    #[serde(default)]
    pub held_contacts: usize,
    /// The tension (N) that the points held closed carry at the end of the step (they would
    /// have been released): the adhesion a cycle's compromise leaves; 0 for the other
    /// methods. For a cut step, that of the piece where it was the largest part of
    /// [`StepReport::compression`].
    #[serde(default)]
    pub held_tension: f64,
    /// The sum of the compressive normal forces (N) of the step's other contact points (the
    /// piece's of [`StepReport::held_tension`]).
    #[serde(default)]
    pub compression: f64,
    /// How far a point held open ends on the wrong side of implicit projection's law (m): the
    /// largest `-max(w_n h / 2, g)` of the points held open (`w_n` the relative normal end
    /// velocity, `g` the eq 22 gap), positive only for a point that penetrates while it still
    /// approaches, which the law would have closed; 0 when every point held open ends clear or
    /// leaving, and for the other methods. The largest of the pieces of a cut step.
    #[serde(default)]
    pub held_open_depth: f64,
    /// Times implicit projection's active set came back to a set already seen in the step
    /// (a cycle), over every attempt of the step, the cut ones included. 0 for the other
    /// methods.
    #[serde(default)]
    pub contact_cycles: usize,
    /// Numeric factorisations of an iteration matrix in the step (contact-free or with
    /// contact, over every attempt, the failed ones included): what a slow step usually spent
    /// its time on. 0 in reports from before it.
    #[serde(default)]
    pub factorisations: usize,
}

/// A simulation of deformable bodies in D dimensions: a [`Model`], a [`State`], what is
/// derived from the model once (node numbering, matrices, surfaces) and caches rebuilt on
/// demand (factorisations, hierarchies).
pub struct Simulation<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    model: Model<D>,
    state: State,
    node_offsets: Vec<usize>,
    reference: Vec<SVector<f64, D>>,
    table: CellTable,
    pattern: Pattern,
    integration: Vec<BodyIntegration>,
    matrices: LinearMatrices,
    prescribed: Vec<Option<f64>>,
    gravity_force: Vec<f64>,
    warnings: Vec<String>,
    boundary_faces: Vec<Vec<usize>>,
    nodal_mass: Vec<f64>,
    /// Rayleigh damping `C` on the pattern of M and K (`None`: no body is damped).
    damping: Option<SparseColMat<usize, f64>>,
    /// Whether internal forces and the tangent are assembled every Newton iteration (a law
    /// that is not linear; tests switch it on for linear ones to compare the two paths).
    general_path: bool,
    /// The last step's contacts, for the host's queries (an output, not state).
    contact_log: contacts::ContactLog<D>,
    /// Active sets that came back in the step under way, over all its attempts (cut ones
    /// included): an output of the step, not state.
    step_cycles: usize,
    /// Numeric factorisations since the step under way began (an output of the step, not
    /// state; atomic because `&self` solves factor too).
    step_factorisations: std::sync::atomic::AtomicUsize,
    /// The poses the host asked obstacles to reach at the end of the next step
    /// ([`Simulation::set_obstacle_next_pose`]): input for one step, not state.
    next_poses: Vec<(ObstacleId, SVector<f64, D>, SMatrix<f64, D, D>)>,
    /// Whether the attempt under way runs the globalized Newton (a line search on the step's
    /// energy, the secant tangent for slips that turned; `newton.rs`): a step whose plain
    /// Newton stalls is tried again with it before it is cut. Per attempt, not state.
    globalized_newton: bool,
    /// The step just taken as detection swept it (one per piece of a cut step), for the
    /// tunnelling watch ([`Simulation::tunnelled`]): an output of the step, not state.
    sweeps: Vec<overlap::Sweep<D>>,
    caches: Caches<D>,
}

/// What can be rebuilt from the model and the state at any time: dropping it changes no
/// result, only the time of the next step.
struct Caches<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    /// The factored contact-free iteration matrix of the last step size.
    system: Option<linear_solve::IterationSystem>,
    /// The factorisations named by [`ContactMemory::factors`], by id.
    contact_factors: Vec<linear_solve::ContactFactor>,
    /// The symbolic analyses of the last contact patterns that were not the contact-free
    /// one, unfactored, oldest first (see `Simulation::analysis_for`).
    analyses: Vec<crate::solver::SparseCholesky>,
    /// Detection (its hierarchy and candidates; its memory is synchronised with the state).
    detector: Option<Detector<D>>,
    /// The polyline and trimesh obstacles' facets with their adjacency, and every body's
    /// cells in global node ids: what the overlap check and the fall-through monitor search
    /// (built at their first use).
    solids: std::sync::OnceLock<overlap::Solids<D>>,
}

/// 2D simulation.
pub type Simulation2 = Simulation<2>;
/// 3D simulation.
pub type Simulation3 = Simulation<3>;

fn invalid(name: &str, found: impl std::fmt::Display, expected: &str) -> Error {
    Error::InvalidParameter {
        name: name.into(),
        found: found.to_string(),
        expected: expected.into(),
    }
}

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// A builder with default settings.
    pub fn builder() -> SimulationBuilder<D> {
        SimulationBuilder::default()
    }

    /// Validates a model, assembles its matrices and sets the initial state: what
    /// [`SimulationBuilder::build`] does, for a model held as a value (a deserialised one).
    /// Every pair of bodies, and every body with every obstacle, may touch.
    pub fn from_model(model: Model<D>) -> Result<Self> {
        let Model {
            settings,
            bodies,
            obstacles,
            contact,
        } = &model;
        validate_settings(settings)?;
        if bodies.is_empty() {
            return Err(invalid("bodies", "none", "at least one body"));
        }
        let mut node_offsets = Vec::with_capacity(bodies.len());
        let mut reference = Vec::new();
        let mut table = CellTable::default();
        let mut integration = Vec::new();
        // Whether contact is detected at all (the massless-flow check below needs it).
        let touches = !obstacles.is_empty() || bodies.len() > 1 || contact.self_contact;
        for (b, body) in bodies.iter().enumerate() {
            if bodies[..b].iter().any(|o| o.name == body.name) {
                return Err(invalid("name", &body.name, "a unique body name"));
            }
            body.mesh.validate_topology(&body.name)?;
            body.mesh.check_quality(&body.name)?;
            body.material.validate()?;
            damping::validate(&body.name, &body.damping)?;
            if !body.gravity_scale.is_finite() {
                return Err(invalid(
                    &format!("body `{}` gravity_scale", body.name),
                    body.gravity_scale,
                    "a finite factor",
                ));
            }
            if body.initial_angular_velocity.len() != <Dim<D>>::ANGULAR {
                return Err(invalid(
                    "initial_angular_velocity",
                    format!("{} components", body.initial_angular_velocity.len()),
                    &format!("{} component(s)", <Dim<D>>::ANGULAR),
                ));
            }
            if settings.kinematics == Kinematics::PlaneStress
                && matches!(body.material, crate::material::Material::NortonHoff(_))
            {
                return Err(invalid(
                    "kinematics",
                    "plane_stress with the norton_hoff material",
                    "plane_strain, axisymmetric or 3D (an incompressible flow in plane stress \
                     would need its thickness as an unknown)",
                ));
            }
            if touches
                && contact.method == crate::contact::ContactMethod::ImplicitProjection
                && matches!(body.material, crate::material::Material::NortonHoff(_))
                && body.material.density() == 0.0
            {
                // Its velocity penalty scales with the iteration matrix's diagonal, M / h plus
                // the small-strain stiffness, both zero for a massless flow: the contact passes
                // never settle (the octagon stopped at step 1 after 50 passes, residual 0).
                return Err(invalid(
                    "contact.method",
                    format!(
                        "implicit_projection with body `{}` a massless norton_hoff flow \
                         (density 0; the method's velocity penalty scales with the mass and the \
                         small-strain stiffness, both zero)",
                        body.name
                    ),
                    "soft_way or augmented_lagrangian for a quasi-static flow, or a density > 0",
                ));
            }
            if settings.kinematics == Kinematics::Axisymmetric {
                if let Some(n) = body.mesh.nodes.iter().position(|x| x[0] < -1e-12) {
                    return Err(Error::Mesh {
                        body: body.name.clone(),
                        message: format!(
                            "node {n} has r = x = {} < 0; expected r >= 0 in axisymmetric kinematics",
                            body.mesh.nodes[n][0]
                        ),
                    });
                }
            }
            let offset = reference.len();
            node_offsets.push(offset);
            reference.extend_from_slice(&body.mesh.nodes);
            for block in &body.mesh.blocks {
                table.push_block(b, block.kind, &block.connectivity, offset);
            }
            let mut body_integration = BodyIntegration::new(settings.kinematics, body.material);
            if body_integration.law.updated_lagrangian() {
                body_integration.stiffness_damping = body.damping.stiffness;
            }
            integration.push(body_integration);
        }
        let nodes = reference.len();
        let pattern = Pattern::new::<D>(&table, nodes)?;
        let matrices = assembly::assemble_linear::<D>(
            &table,
            &pattern,
            &reference,
            &integration,
            settings.mass == MassKind::Lumped,
        );

        let ndof = nodes * D;
        let mut prescribed = vec![None; ndof];
        for (b, body) in bodies.iter().enumerate() {
            for (c, constraint) in body.constraints.iter().enumerate() {
                if constraint.velocity.len() != D {
                    return Err(invalid(
                        &format!("bodies.{b}.constraints.{c}.velocity"),
                        format!("{} components", constraint.velocity.len()),
                        &format!("{D} components"),
                    ));
                }
                if constraint.nodes.is_empty() {
                    return Err(Error::EmptySelection {
                        what: format!("constraint {c}"),
                        body: body.name.clone(),
                        hint: "enlarge its region so that it contains nodes of the mesh".into(),
                    });
                }
                for &n in &constraint.nodes {
                    if n >= body.mesh.nodes.len() {
                        return Err(Error::InvalidHandle(format!(
                            "constraint {c} of body `{}` names node {n} of {}",
                            body.name,
                            body.mesh.nodes.len()
                        )));
                    }
                    for (k, v) in constraint.velocity.iter().enumerate() {
                        if let Some(v) = v {
                            prescribed[(node_offsets[b] + n) * D + k] = Some(*v);
                        }
                    }
                }
            }
        }

        let gravity_force = gravity_forces(settings, bodies, &node_offsets, &matrices.mass);

        let mut velocity = vec![0.0; ndof];
        for (b, body) in bodies.iter().enumerate() {
            let centre = centre_of_mass(
                &matrices.mass,
                &reference,
                node_offsets[b],
                body.mesh.nodes.len(),
            );
            for (n, x) in body.mesh.nodes.iter().enumerate() {
                let v = body.initial_velocity
                    + <Dim<D>>::spin_velocity(&body.initial_angular_velocity, &(x - centre));
                for k in 0..D {
                    velocity[(node_offsets[b] + n) * D + k] = v[k];
                }
            }
        }
        for (dof, p) in prescribed.iter().enumerate() {
            if let Some(v) = p {
                velocity[dof] = *v;
            }
        }
        let mut warnings = Vec::new();
        if let Some(w) = settings.scheme.stability_warning() {
            warnings.push(w);
        }
        let needs_contact = !obstacles.is_empty() || bodies.len() > 1 || contact.self_contact;
        if needs_contact {
            contact.validate()?;
        }
        for (k, o) in obstacles.iter().enumerate() {
            if obstacles[..k].iter().any(|p| p.name == o.name) {
                return Err(invalid("obstacle name", &o.name, "a unique obstacle name"));
            }
            if let Some(f) = &o.friction {
                f.validate()?;
            }
            obstacle_motion::validate_motion(o)?;
        }
        let mut obstacle_translations = Vec::with_capacity(obstacles.len() * D);
        let mut obstacle_velocities = Vec::with_capacity(obstacles.len() * D);
        for o in obstacles {
            obstacle_translations.extend(o.translation.iter());
            obstacle_velocities.extend(o.velocity.iter());
        }
        let (obstacle_rotations, obstacle_angular_velocities) =
            obstacle_motion::initial_rotations(obstacles);
        let mut boundary_faces = Vec::new();
        let mut detector = None;
        if needs_contact {
            let meshes: Vec<&Mesh<D>> = bodies.iter().map(|b| &b.mesh).collect();
            let surface = ContactSurface::from_bodies(&meshes, &node_offsets);
            let mut facet_size = 0.0;
            let mut facet_count = 0usize;
            for (b, body) in bodies.iter().enumerate() {
                for face in body.mesh.boundary_faces() {
                    let global: Vec<usize> =
                        face.nodes.iter().map(|&n| n + node_offsets[b]).collect();
                    facet_size += (reference[global[1]] - reference[global[0]]).norm();
                    facet_count += 1;
                    boundary_faces.push(global);
                }
            }
            let mean_size = facet_size / facet_count.max(1) as f64;
            detector = Some(Detector::new(
                surface,
                DetectionOptions {
                    self_contact: contact.self_contact,
                    margin: 0.25 * mean_size,
                    deformable_pairs: true,
                    hysteresis: 1e-3 * mean_size,
                    facing: true,
                    lock_flipping_facets: contact.method == ContactMethod::ImplicitProjection,
                },
            ));
        }
        let mut nodal_mass = vec![0.0; nodes];
        {
            let mut e = vec![0.0; ndof];
            for n in 0..nodes {
                e[n * D] = 1.0;
            }
            let mut me = vec![0.0; ndof];
            assembly::symmetric_mul_add(&matrices.mass, &e, 1.0, &mut me);
            for n in 0..nodes {
                nodal_mass[n] = me[n * D];
            }
        }
        let state = State {
            step: 0,
            time: 0.0,
            displacement: vec![0.0; ndof],
            gap_displacement: vec![0.0; ndof],
            velocity,
            scheme_time_step: 0.0,
            external_work: 0.0,
            dissipated_energy: 0.0,
            contact_loss: 0.0,
            loads: vec![0.0; ndof],
            obstacle_translations,
            obstacle_velocities,
            obstacle_rotations,
            obstacle_angular_velocities,
            contact_energy: 0.0,
            multipliers: Vec::new(),
            friction_normals: Vec::new(),
            friction_anchors: Vec::new(),
            active_contacts: Vec::new(),
            reference_energy: 0.0,
            material_history: vec![0.0; assembly::history_len(&table, &integration)],
            contact_memory: ContactMemory::default(),
            body_slots: Slots::identity(bodies.len()),
            obstacle_slots: Slots::identity(obstacles.len()),
        };
        let general_path = integration.iter().any(|b| !b.law.is_linear());
        // Updated-Lagrangian bodies take their stiffness part in the element kernel.
        let body_damping: Vec<_> = bodies
            .iter()
            .zip(&integration)
            .map(|(b, i)| RayleighDamping {
                mass: b.damping.mass,
                stiffness: if i.law.updated_lagrangian() {
                    0.0
                } else {
                    b.damping.stiffness
                },
            })
            .collect();
        let damping = damping::damping_matrix(&body_damping, &node_offsets, &matrices, D);
        let mut sim = Simulation {
            model,
            state,
            node_offsets,
            reference,
            table,
            pattern,
            integration,
            matrices,
            prescribed,
            gravity_force,
            warnings,
            boundary_faces,
            nodal_mass,
            damping,
            general_path,
            contact_log: Default::default(),
            step_cycles: 0,
            step_factorisations: Default::default(),
            next_poses: Vec::new(),
            globalized_newton: false,
            sweeps: Vec::new(),
            caches: Caches {
                system: None,
                contact_factors: Vec::new(),
                analyses: Vec::new(),
                detector,
                solids: Default::default(),
            },
        };
        sim.state.reference_energy = sim.energies().total();
        Ok(sim)
    }

    /// Rebuilds a simulation from its model and a state taken from it (or from a checkpoint):
    /// the next steps are bit for bit those the original would have taken.
    pub fn from_parts(model: Model<D>, state: State) -> Result<Self> {
        let mut sim = Self::from_model(model)?;
        sim.set_state(state)?;
        Ok(sim)
    }

    /// An independent copy that continues bit for bit like this one (a snapshot to branch
    /// from: the model and state copied, the matrices rebuilt, the caches left to refill).
    pub fn try_clone(&self) -> Result<Self> {
        let mut copy = Self::from_parts(self.model.clone(), self.state.clone())?;
        copy.warnings.clone_from(&self.warnings);
        copy.next_poses.clone_from(&self.next_poses);
        Ok(copy)
    }

    /// Replaces the state (for example one returned by [`Simulation::state`] earlier): the
    /// simulation continues from it exactly. The sizes must match the model.
    pub fn set_state(&mut self, state: State) -> Result<()> {
        let ndof = self.reference.len() * D;
        let checks = [
            ("displacement", state.displacement.len(), ndof),
            ("velocity", state.velocity.len(), ndof),
            ("loads", state.loads.len(), ndof),
            (
                "obstacle_translations",
                state.obstacle_translations.len(),
                self.model.obstacles.len() * D,
            ),
            (
                "obstacle_velocities",
                state.obstacle_velocities.len(),
                self.model.obstacles.len() * D,
            ),
        ];
        for (name, found, expected) in checks {
            if found != expected {
                return Err(invalid(
                    &format!("state.{name}"),
                    format!("{found} values"),
                    &format!("{expected} values (the model's)"),
                ));
            }
        }
        let mut state = state;
        self.check_obstacle_state(&mut state)?;
        if state.body_slots.is_empty() {
            state.body_slots = Slots::identity(self.model.bodies.len());
        }
        if state.obstacle_slots.is_empty() {
            state.obstacle_slots = Slots::identity(self.model.obstacles.len());
        }
        if !state.body_slots.holds_positions(self.model.bodies.len())
            || !state
                .obstacle_slots
                .holds_positions(self.model.obstacles.len())
        {
            return Err(invalid(
                "state.body_slots",
                format!(
                    "slots at positions {:?} (bodies) and {:?} (obstacles)",
                    state.body_slots.positions(),
                    state.obstacle_slots.positions()
                ),
                &format!(
                    "each of 0..{} (bodies) and 0..{} (obstacles) once (the model's)",
                    self.model.bodies.len(),
                    self.model.obstacles.len()
                ),
            ));
        }
        if !(state.scheme_time_step >= 0.0 && state.scheme_time_step.is_finite()) {
            return Err(invalid(
                "state.scheme_time_step",
                state.scheme_time_step,
                "a finite step size >= 0 [s] (0: any)",
            ));
        }
        if state.gap_displacement.is_empty() {
            // A state from before the gap displacement existed: the configuration's.
            state.gap_displacement = state.displacement.clone();
        } else if state.gap_displacement.len() != ndof {
            return Err(invalid(
                "state.gap_displacement",
                format!("{} values", state.gap_displacement.len()),
                &format!("{ndof} values (the model's) or none"),
            ));
        }
        self.state = state;
        self.contact_log.clear();
        self.sweeps.clear();
        Ok(())
    }

    /// Changes the Newton limits between steps: the largest number of iterations of one step
    /// and the relative residual tolerance (validated like the settings).
    pub fn set_solver_limits(&mut self, max_iterations: usize, tolerance: f64) -> Result<()> {
        let mut settings = self.model.settings.clone();
        settings.max_iterations = max_iterations;
        settings.tolerance = tolerance;
        validate_settings(&settings)?;
        self.model.settings = settings;
        Ok(())
    }

    /// The model (settings, bodies, obstacles, contact settings).
    pub fn model(&self) -> &Model<D> {
        &self.model
    }

    /// The settings.
    pub fn settings(&self) -> &Settings<D> {
        &self.model.settings
    }

    /// The bodies.
    pub fn bodies(&self) -> &[Body<D>] {
        &self.model.bodies
    }

    /// The state (time, displacements, velocities, works).
    pub fn state(&self) -> &State {
        &self.state
    }

    /// Warnings gathered while building (stability window, ...).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Total number of nodes.
    pub fn node_count(&self) -> usize {
        self.reference.len()
    }

    /// The rigid obstacles, at their pose at t = 0 (see [`Simulation::posed_obstacles`]).
    pub fn obstacles(&self) -> &[Obstacle<D>] {
        &self.model.obstacles
    }

    /// The contact settings.
    pub fn contact_settings(&self) -> &ContactSettings {
        &self.model.contact
    }

    /// The contact detector, when contact is possible (obstacles, several bodies or
    /// self-contact).
    pub fn detector(&self) -> Option<&Detector<D>> {
        self.caches.detector.as_ref()
    }

    /// The mass matrix (kg).
    pub fn mass_matrix(&self) -> SymmetricMatrix<'_> {
        SymmetricMatrix::of(&self.matrices.mass)
    }

    /// The stiffness matrix on the reference configuration (N/m).
    pub fn stiffness_matrix(&self) -> SymmetricMatrix<'_> {
        SymmetricMatrix::of(&self.matrices.stiffness)
    }

    /// Energies at the current state.
    pub fn energies(&self) -> Energies {
        let s = &self.state;
        Energies {
            kinetic: 0.5 * assembly::symmetric_dot(&self.matrices.mass, &s.velocity, &s.velocity),
            internal: self.internal_energy(&s.displacement, &s.material_history),
            contact: s.contact_energy,
            external_work: s.external_work,
            dissipated: s.dissipated(),
        }
    }

    /// The body a global node belongs to.
    pub(super) fn body_of_node(&self, node: usize) -> usize {
        body_of(&self.node_offsets, node)
    }

    /// The stored internal energy at displacements `u` with the material history `history`
    /// (J): what [`Self::energies`] reports, so that other accounts (the end-of-step
    /// projection's) use the same matrices.
    pub(super) fn internal_energy(&self, u: &[f64], history: &[f64]) -> f64 {
        if self.general_path {
            self.integrate_at(u, history).energy
        } else {
            0.5 * self.stiffness_product(u, u)
        }
    }

    /// `a^T K b`, with each body's mean removed from both first: `K` annihilates
    /// translations, and removing them avoids the cancellation of large equal terms. Bodies
    /// of updated-Lagrangian laws are left out: the reference `K` does not annihilate their
    /// rotations.
    pub(super) fn stiffness_product(&self, a: &[f64], b: &[f64]) -> f64 {
        let centred = |u: &[f64]| {
            let mut w = u.to_vec();
            for body in 0..self.model.bodies.len() {
                let range = self.nodes_of(body);
                let count = range.len().max(1) as f64;
                let updated = self.integration[body].law.updated_lagrangian();
                for k in 0..D {
                    let mean = range.clone().map(|n| u[n * D + k]).sum::<f64>() / count;
                    for n in range.clone() {
                        w[n * D + k] = if updated { 0.0 } else { w[n * D + k] - mean };
                    }
                }
            }
            w
        };
        assembly::symmetric_dot(&self.matrices.stiffness, &centred(a), &centred(b))
    }

    /// The energy that stability is measured against: E(0) + |external work| + |dissipated|
    /// (the dissipation is negative where the end-of-step projection created energy: that
    /// energy is booked, so it counts like work).
    pub fn energy_reference(&self) -> f64 {
        self.state.reference_energy
            + self.state.external_work.abs()
            + self.state.dissipated_energy.abs()
            + self.state.contact_loss.max(0.0)
    }

    /// Energy at t = 0 (J).
    pub fn initial_energy(&self) -> f64 {
        self.state.reference_energy
    }

    /// Internal forces of displacements `u` (flat, D per node) integrated from the element
    /// stresses (N).
    pub fn internal_forces(&self, u: &[f64]) -> Vec<f64> {
        self.integrate_at(u, &self.state.material_history).forces
    }

    /// The element integrals at displacements `u` (zero strain rate) with `history`.
    fn integrate_at(&self, u: &[f64], history: &[f64]) -> assembly::Integrated {
        let fields = assembly::KernelFields {
            displacement: Some(u),
            ..Default::default()
        };
        assembly::integrate::<D>(
            &self.table,
            None,
            &self.reference,
            &self.integration,
            &fields,
            history,
            u.len(),
        )
    }

    /// Whether Newton assembles the internal forces and the tangent every iteration.
    fn uses_general_path(&self) -> bool {
        self.general_path
    }

    /// Reference (undeformed) node positions, bodies in order (m).
    pub fn reference_positions(&self) -> &[SVector<f64, D>] {
        &self.reference
    }
}

/// Predicted end-of-step positions with the exact integral of the velocity (eq 22).
fn end_positions<const D: usize>(
    x: &[SVector<f64, D>],
    u0: &[f64],
    v0: &[f64],
    v1: &[f64],
    h: f64,
) -> Vec<SVector<f64, D>> {
    (0..x.len())
        .map(|n| {
            x[n] + SVector::<f64, D>::from_fn(|k, _| {
                let i = n * D + k;
                u0[i] + 0.5 * h * (v0[i] + v1[i])
            })
        })
        .collect()
}

fn validate_settings<const D: usize>(s: &Settings<D>) -> Result<()>
where
    Dim<D>: SpatialDim<D>,
{
    if !(s.time_step > 0.0 && s.time_step.is_finite()) {
        return Err(invalid("time_step", s.time_step, "a finite value > 0 [s]"));
    }
    SpaceTimeScheme::new(s.scheme.alpha, Beta::Value(s.scheme.beta))?;
    if !<Dim<D>>::supports(s.kinematics) {
        return Err(invalid(
            "kinematics",
            format!("{:?}", s.kinematics),
            if D == 2 {
                "plane_strain, plane_stress or axisymmetric"
            } else {
                "solid"
            },
        ));
    }
    if s.max_iterations == 0 {
        return Err(invalid("max_iterations", 0, "at least 1"));
    }
    if !(s.tolerance > 0.0 && s.tolerance < 1.0) {
        return Err(invalid("tolerance", s.tolerance, "a value in (0, 1)"));
    }
    if s.gravity.iter().any(|g| !g.is_finite()) {
        return Err(invalid(
            "gravity",
            format!("{:?}", s.gravity.as_slice()),
            "finite components",
        ));
    }
    Ok(())
}

/// Gravity as consistent nodal forces: `M g`, g scaled per body.
fn gravity_forces<const D: usize>(
    settings: &Settings<D>,
    bodies: &[Body<D>],
    node_offsets: &[usize],
    mass: &SparseColMat<usize, f64>,
) -> Vec<f64>
where
    Dim<D>: SpatialDim<D>,
{
    let ndof = mass.ncols();
    let mut g_field = vec![0.0; ndof];
    for (body, &offset) in bodies.iter().zip(node_offsets) {
        for n in offset..offset + body.mesh.nodes.len() {
            for k in 0..D {
                g_field[n * D + k] = body.gravity_scale * settings.gravity[k];
            }
        }
    }
    let mut force = vec![0.0; ndof];
    assembly::symmetric_mul_add(mass, &g_field, 1.0, &mut force);
    force
}

/// Mass-weighted centre of the nodes `offset..offset + count`.
fn centre_of_mass<const D: usize>(
    mass: &SparseColMat<usize, f64>,
    x: &[SVector<f64, D>],
    offset: usize,
    count: usize,
) -> SVector<f64, D> {
    let n = x.len();
    let mut total = 0.0;
    let mut moment = SVector::<f64, D>::zeros();
    let mut e = vec![0.0; n * D];
    for node in offset..offset + count {
        e[node * D] = 1.0;
    }
    let mut me = vec![0.0; n * D];
    assembly::symmetric_mul_add(mass, &e, 1.0, &mut me);
    for node in offset..offset + count {
        let m = me[node * D];
        total += m;
        moment += x[node] * m;
    }
    if total > 0.0 {
        moment / total
    } else {
        x[offset..offset + count].iter().sum::<SVector<f64, D>>() / count.max(1) as f64
    }
}

/// The body a global node belongs to, `offsets` holding each body's first node.
pub(super) fn body_of(offsets: &[usize], node: usize) -> usize {
    offsets.partition_point(|&o| o <= node) - 1
}
