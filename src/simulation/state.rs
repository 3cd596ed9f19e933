//! The state: everything that affects the results of the next steps, one serialisable value.
//! What is not here is a cache, rebuilt from the model and the state (matrices, factorisations,
//! hierarchies): a failed step restores the state and nothing else, and a simulation rebuilt
//! from a model and a state continues bit for bit.

use serde::{Deserialize, Serialize};

use super::handles::Slots;
use crate::contact::ContactKey;
pub use crate::contact::MasterId;

/// The evolving state: one serialisable value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct State {
    /// Steps taken.
    pub step: usize,
    /// Current time (s).
    pub time: f64,
    /// Nodal displacements from the reference configuration (m), D per node, bodies in order.
    pub displacement: Vec<f64>,
    /// Nodal velocities (m/s).
    pub velocity: Vec<f64>,
    /// The displacement contact gaps are measured on (m) (with
    /// [`crate::contact::GapDisplacement::Trapezoid`]): the running sum of eq 22,
    /// `h (v0 + v1) / 2` per step, moved with the configuration by end-of-step projections.
    /// It differs from `displacement` by the scheme's `h (1/2 - beta) (v - v(0))` per node,
    /// which changes of step and the augmented Lagrangian's persistency stop keep
    /// (`simulation/step_change.rs`), so the two agree at rest.
    #[serde(default)]
    pub gap_displacement: Vec<f64>,
    /// The step size (s) the displacement and velocity are the scheme's variables for: the
    /// last step's (a cut step's last piece's). A step of another size first re-expresses them
    /// for its own so that the energy the scheme conserves does not grow
    /// (`simulation/step_change.rs`). 0 (the initial state, and states from before this field):
    /// valid for any step.
    #[serde(default)]
    pub scheme_time_step: f64,
    /// Cumulative external work (J).
    pub external_work: f64,
    /// Cumulative dissipation (J), but for the penalty contacts' (`contact_loss`).
    pub dissipated_energy: f64,
    /// Cumulative work the penalty's normal forces took from the bodies, less the growth of the
    /// energy the gaps store (J), signed: counted as dissipated while positive
    /// ([`State::dissipated`]); a net gain is energy the contacts created, which the energy
    /// monitor reports.
    #[serde(default)]
    pub contact_loss: f64,
    /// Constant external nodal forces set through the API (N).
    pub loads: Vec<f64>,
    /// Displacement of each obstacle since t = 0 (m), D per obstacle.
    pub obstacle_translations: Vec<f64>,
    /// Velocity of each obstacle (of its pivot) (m/s), D per obstacle (changed between steps
    /// through the API; a schedule's mean over the step).
    pub obstacle_velocities: Vec<f64>,
    /// Rotation of each obstacle about its pivot since t = 0: the angle (rad) in 2D, the
    /// rotation matrix's 9 entries (column-major) in 3D, per obstacle (empty in states from
    /// before rotating obstacles: none turned).
    #[serde(default)]
    pub obstacle_rotations: Vec<f64>,
    /// Angular velocity of each obstacle about its pivot (rad/s), 1 (2D) or 3 (3D) per
    /// obstacle (a schedule's turn over the step divided by the step; empty: none).
    #[serde(default)]
    pub obstacle_angular_velocities: Vec<f64>,
    /// Energy stored in soft-way penalties at the end of the last step (J).
    pub contact_energy: f64,
    /// Multipliers carried from step to step: (slave node, master, value). The augmented
    /// Lagrangian's contact pressures (Pa), for the pairs closed at the end of the last step
    /// only; implicit projection's multiplier forces (N) of the points it held then.
    pub multipliers: Vec<(usize, MasterId, f64)>,
    /// The normal forces that set the friction thresholds (slave node, master, force (N)),
    /// carried from step to step as the start of the fixed point on the threshold.
    pub friction_normals: Vec<(usize, MasterId, f64)>,
    /// The elastic slips of the friction return map (slave node, master, D components (m)):
    /// one per closed contact under a penalty method with Coulomb or Tresca friction, dropped
    /// when the contact opens.
    pub friction_anchors: Vec<(usize, MasterId, Vec<f64>)>,
    /// Implicit projection: the points held at the end of the last step (slave node, master),
    /// the start of the next step's active set; the soft way: the points closed (loaded) at
    /// the end of the last step, whose penalty the next step's first Newton direction keeps.
    /// Empty in states from before it (the active set is then found from the predicted
    /// penetrations alone).
    #[serde(default)]
    pub active_contacts: Vec<(usize, MasterId)>,
    /// The energy stability is measured against at t = 0 (J) (E(0)).
    pub reference_energy: f64,
    /// Per-quadrature-point history of the materials that carry one, cell by cell.
    pub material_history: Vec<f64>,
    /// Contact memory that changes results: the narrow phase's chosen facets and the contact
    /// factorisations that precondition the linear solves.
    pub contact_memory: ContactMemory,
    /// The handles of the bodies (slot and generation to position in the model); empty in
    /// states from before handles (then the model's order).
    #[serde(default)]
    pub body_slots: Slots,
    /// The handles of the obstacles; empty in states from before handles.
    #[serde(default)]
    pub obstacle_slots: Slots,
}

impl State {
    /// Cumulative dissipation (J): the bodies', friction's, the projections' and the
    /// constraints' plus the penalty contacts' net loss while it is one. A net gain there is
    /// not booked: the account shows it as energy created.
    pub fn dissipated(&self) -> f64 {
        self.dissipated_energy + self.contact_loss.max(0.0)
    }
}

/// The parts of contact resolution that carry over from step to step.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ContactMemory {
    /// The narrow phase's hysteresis: the master facet (or obstacle feature) chosen last for
    /// each (slave, master).
    pub detection: Vec<(ContactKey, usize)>,
    /// The contact iteration matrices factored as preconditioners, newest first. A solve
    /// preconditioned by one of them gives other round-off than by another, so which ones
    /// exist is state; the factors themselves are a cache rebuilt from these entries.
    pub factors: Vec<FactorRecord>,
    /// Whether new contact matrices are factored in single precision (switched off for good
    /// the first time a single-precision factor fails to converge).
    pub double_precision_only: bool,
    /// The id of the next factorisation.
    pub next_factor: u64,
}

/// A factored contact iteration matrix: the contact-free matrix of `time_step` plus `entries`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FactorRecord {
    /// Its id (the cache key).
    pub id: u64,
    /// The step size of the contact-free part (s).
    pub time_step: f64,
    /// The contact entries on free unknowns (row, column, value; lower triangle).
    pub entries: Vec<(usize, usize, f64)>,
    /// Whether it was factored in single precision.
    pub single_precision: bool,
}
