//! The four contact methods of the paper's Table 1 behind one interface, [`Method`]: each
//! says what its normal law adds to the residual and tangent of a Newton iteration, how it
//! updates its outer variables (multipliers, active set) between Newton solves, and what it
//! corrects at the end of the step. The step ([`crate::simulation`]) drives them all the same
//! way; friction ([`crate::friction`]) acts on top of any of them.
//!
//! * [`soft_way`]: penalty on the eq 22 gap (eq 27).
//! * [`augmented_lagrangian`]: Uzawa updates of multipliers around soft-way solves (eq 28-30).
//! * [`implicit_projection`]: an active set with zero relative normal end velocity, positions
//!   projected at the end of the step.
//! * [`explicit_projection`]: contact ignored in the step, penetrating points projected at its
//!   end (category 1 baseline).

use std::collections::{BTreeMap, BTreeSet, HashSet};

use nalgebra::SVector;

use super::{ContactKey, ContactMethod, ContactSettings};

pub(crate) mod augmented_lagrangian;
pub(crate) mod explicit_projection;
pub(crate) mod implicit_projection;
pub(crate) mod projection;
pub(crate) mod soft_way;

/// The penalty methods' tangential spring times the step, at most this many times the
/// slave's diagonal of the iteration matrix: the Newton tangent's rows at most quintuple where
/// a point sticks, and a stick-slip switch changes them by no more. The normal penalty times
/// the area, the spring's own value, is about 20 diagonals per step on the 3D stack of soft
/// blocks with Coulomb 0.5: its soft way took 16 minutes (20 to 50 iterations a step) and its
/// augmented Lagrangian 23 minutes with 414 cut steps; capped at 4, 36 s and 113 s with no cut
/// step (`two_bodies::d3`, dev build, 2026-11-30). At 1 the tilting floor's friction past the
/// cone read 1.98 % from mu (0.34 % at 4, 0.00 % uncapped) and the 3D slide's account
/// 1.17e-3 (9.7e-4 at 4). The elastic slip stays at most `F_t h / (4 diagonal)`, below
/// `F_t h^2 / (4 m)`.
pub(crate) const PENALTY_TANGENT_CAP: f64 = 4.0;

/// The variables a method updates between Newton solves within one step.
#[derive(Debug, Clone, Default)]
pub(crate) struct OuterVariables {
    /// Augmented Lagrangian: contact pressures (Pa), positive, of closed pairs only (carried
    /// from step to step, dropped when the pair opens); implicit projection: the normal
    /// forces (N) of the last solve on active points.
    pub multipliers: BTreeMap<ContactKey, f64>,
    /// Implicit projection: the active set.
    pub active: BTreeSet<ContactKey>,
    /// Implicit projection: every active set seen in this step (a repeat is a cycle).
    pub seen_sets: HashSet<Vec<ContactKey>>,
    /// Implicit projection: how often each point was released in this step; a point released
    /// [`implicit_projection::RELEASES_BEFORE_LOCK`] times stays closed until the step ends.
    pub releases: BTreeMap<ContactKey, u32>,
    /// Implicit projection: the points whose status is kept until the step ends (released
    /// too often, or flipping in a cycle).
    pub locked: BTreeSet<ContactKey>,
    /// Implicit projection: active sets that came back since the caller last took the count
    /// (the step's monitor reads and resets it after every outer update).
    pub cycles: usize,
    /// The soft way: the pairs closed when the last step ended. Newton's first direction
    /// (from the predictor `v1 = v0`, which opens a resting point moving up) keeps their
    /// penalty's closed branch, so that a contact the predictor lifts off is not dropped for
    /// an iteration; cleared after that direction.
    pub predicted: BTreeSet<ContactKey>,
    /// The projections: the edge pairs (`held_pairs::held_pairs`) held so far in this step. An
    /// active one stays held until the step ends (released by its tension like any other
    /// point), so that Newton's problem does not change from one iterate to the next as the
    /// edge criterion flips.
    pub edge_held: BTreeSet<ContactKey>,
    /// Whether [`Method::start`] ran in this step.
    pub started: bool,
    /// Augmented Lagrangian: each pair's penalty as a multiple of `zeta`, raised where an
    /// Uzawa update did not shrink the pair's violation enough (this step only).
    pub penalty_scales: BTreeMap<ContactKey, f64>,
    /// Augmented Lagrangian: each violating pair's violation (penetration, or the open gap a
    /// pressure acts across) at the previous Uzawa update (m).
    pub previous_violations: BTreeMap<ContactKey, f64>,
}

/// What the normal law of one pair needs in an iteration.
#[derive(Debug, Clone, Copy)]
pub(crate) struct NormalInput {
    /// The contact.
    pub key: ContactKey,
    /// The eq 22 gap (m).
    pub gap: f64,
    /// The same gap at the start of the step, `gap - (h/2) n . (w0 + w1)` (m).
    pub start_gap: f64,
    /// The relative normal end velocity (m/s).
    pub normal_velocity: f64,
    /// The slave's contact area (m^2).
    pub area: f64,
    /// The step (s).
    pub time_step: f64,
    /// The largest diagonal entry of the slave's rows of the iteration matrix.
    pub diagonal: f64,
}

/// A pair's normal force and the stiffness of its law.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct NormalLaw {
    /// Compressive normal force on the slave (N).
    pub force: f64,
    /// `d force / d (n . w1)`, w1 the relative end velocity (N s/m).
    pub stiffness: f64,
    /// The normal force (N) whose direction turns with the gap's gradient, the factor of the
    /// geometric tangent `-(h/2) F Hess(g)`: the penalty's force, or an active constraint's
    /// (negative in tension); 0 where no force acts.
    pub geometric_force: f64,
    /// `d force / d (n . w1)` (N s/m) through the normal velocity itself, where the force
    /// holds `w_n = n . w1` (implicit projection's velocity branch): `w_n` also changes with
    /// the positions, through the normal and the closest point, and that variation, `(h/2)
    /// Hess(g) w1` per unit of the end positions, enters the tangent with this factor (a
    /// non-symmetric rank-one term). 0 where the force depends on the gap only.
    pub velocity_stiffness: f64,
    /// The closed branch's force (N, a tension) of a pair the law finds open but that was
    /// closed when the last step ended ([`OuterVariables::predicted`]): with `stiffness`, it
    /// sets the first Newton direction as if the pair were still closed; it is not in the
    /// residual (which keeps the law's zero). 0 elsewhere.
    pub predicted_force: f64,
    /// The constraint a held point's force enforces, where the force is a multiplier less a
    /// penalty times that constraint (implicit projection's active points); `None` elsewhere.
    pub held: Option<HeldConstraint>,
}

/// A constraint held by `force = lambda - penalty * value`: Newton keeps the force's
/// linearised prediction beside it (`newton`'s merit), so that the constraint's curvature is
/// measured in its own units rather than times the penalty.
#[derive(Debug, Clone, Copy)]
pub(crate) struct HeldConstraint {
    /// The constraint's value at the iterate (m/s).
    pub value: f64,
    /// The penalty that holds it (N s/m).
    pub penalty: f64,
}

/// One pair's forces in an iteration, as the outer updates and the records see them.
#[derive(Debug, Clone)]
pub(crate) struct PairOutcome<const D: usize> {
    /// The contact.
    pub key: ContactKey,
    /// The master's outward normal.
    pub normal: SVector<f64, D>,
    /// The eq 22 gap (m).
    pub gap: f64,
    /// Normal force on the slave (N; negative: tension, implicit projection).
    pub normal_force: f64,
    /// Friction force on the slave (N).
    pub friction: SVector<f64, D>,
    /// Mean tangential relative velocity over the step (m/s).
    pub slip: SVector<f64, D>,
    /// The master point (m).
    pub master_point: SVector<f64, D>,
    /// The obstacle, for obstacle masters.
    pub obstacle: Option<usize>,
    /// The relative normal end velocity (m/s).
    pub normal_velocity: f64,
    /// The master's velocity where the slave touches it (m/s; an obstacle's surface
    /// velocity, zero for a facet, whose nodes are in `nodes`).
    pub master_velocity: SVector<f64, D>,
    /// The slave and the master's nodes with their weights in the relative velocity (only where
    /// closed pairs are stopped after the step, `ContactSettings::stops_closed_pairs`; empty
    /// otherwise).
    pub nodes: Vec<(usize, f64)>,
    /// The elastic slip after the step (m; return-map laws on closed contacts).
    pub anchor: Option<SVector<f64, D>>,
    /// A projection's edge pair (frictionless): its master facet's nodes and the closest
    /// point's weights on them. Those of its nodes that hold the slave's body carry its normal
    /// force in their Coulomb thresholds.
    pub carried_by: Option<[(usize, f64); D]>,
}

/// The normal state of one pair after a converged Newton solve.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PairStatus {
    /// The contact.
    pub key: ContactKey,
    /// The eq 22 gap (m).
    pub gap: f64,
    /// Normal force on the slave (N; negative: tension).
    pub normal_force: f64,
    /// The relative normal end velocity (m/s).
    pub normal_velocity: f64,
}

impl<const D: usize> From<&PairOutcome<D>> for PairStatus {
    fn from(p: &PairOutcome<D>) -> Self {
        PairStatus {
            key: p.key,
            gap: p.gap,
            normal_force: p.normal_force,
            normal_velocity: p.normal_velocity,
        }
    }
}

/// The result of an outer update.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum OuterUpdate {
    /// The method's conditions hold: the step may end.
    Converged,
    /// The outer variables changed: solve again.
    Again,
    /// The active set came back to one seen before in this step.
    Cycle,
}

/// Which points the end-of-step projection moves onto their master.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum EndProjection {
    /// No projection.
    None,
    /// The points of the active set (their normal end velocity is already zero).
    Active,
    /// Every penetrating point, whose approaching normal velocity is removed too.
    PenetratingWithVelocity,
}

/// A contact method: its normal law, its outer update and its end-of-step correction.
pub(crate) trait Method: Sync {
    /// Whether contact enters the Newton iterations (explicit projection: no).
    fn in_newton(&self) -> bool {
        true
    }

    /// Called once per step with the contacts predicted to penetrate at the first iteration
    /// (end velocity = start velocity) and those held or closed when the last step ended
    /// (`State::active_contacts`).
    fn start(&self, _vars: &mut OuterVariables, _starting: &[ContactKey]) {}

    /// Whether the points closed when a step ends are kept (`State::active_contacts`) for the
    /// next step's [`Method::start`] although the method has no active set (the soft way's
    /// first direction, [`OuterVariables::predicted`]).
    fn keeps_closed_points(&self) -> bool {
        false
    }

    /// The normal law of one pair.
    fn normal_law(
        &self,
        input: &NormalInput,
        vars: &OuterVariables,
        settings: &ContactSettings,
    ) -> NormalLaw;

    /// Whether the gap stores penalty energy `zeta g^2 / 2` per area.
    fn stores_energy(&self) -> bool {
        false
    }

    /// Updates the outer variables after Newton converged for them.
    fn outer_update(
        &self,
        _pairs: &[PairStatus],
        _vars: &mut OuterVariables,
        _settings: &ContactSettings,
        _time_step: f64,
        _log: &mut dyn FnMut(String),
    ) -> OuterUpdate {
        OuterUpdate::Converged
    }

    /// Whether a point counts as active in the records.
    fn is_active(&self, key: &ContactKey, vars: &OuterVariables) -> bool {
        vars.active.contains(key)
    }

    /// The end-of-step correction.
    fn end_projection(&self) -> EndProjection {
        EndProjection::None
    }

    /// Whether the multipliers are carried to the next step.
    fn carries_multipliers(&self) -> bool {
        false
    }

    /// Whether Coulomb and Tresca are the penalty return map (elastic-slip anchors, the
    /// current normal force, [`crate::friction::return_map`]) rather than the smooth law with
    /// the threshold's fixed point.
    fn friction_return_map(&self) -> bool {
        false
    }

    /// The return map's tangential stiffness (N/m) for a pair (default: the normal penalty
    /// times the contact area, so that the elastic slip is at most mu times the penetration,
    /// capped at [`PENALTY_TANGENT_CAP`] times the slave's diagonal per step).
    fn tangential_stiffness(&self, input: &NormalInput, settings: &ContactSettings) -> f64 {
        let spring = settings.penalty * input.area;
        if input.diagonal > 0.0 {
            spring.min(PENALTY_TANGENT_CAP * input.diagonal / input.time_step)
        } else {
            // No mass and no stiffness in the iteration matrix (a rigid-viscoplastic body
            // without density): nothing to measure a cap by.
            spring
        }
    }

    /// Whether pairs between deformable surfaces are kept in both directions (each at half
    /// the contact area) rather than one pass.
    fn symmetric_pairs(&self) -> bool {
        false
    }

    /// Whether Coulomb's threshold takes the normal force of the previous pass (a fixed point
    /// across passes) rather than the current iterate's.
    fn lagged_friction_threshold(&self) -> bool {
        false
    }

    /// Whether a pair counts as closed while it is in the active set (implicit projection,
    /// whose normal force is exact only when the active set has converged) rather than while
    /// its normal force is positive.
    fn closed_by_active_set(&self) -> bool {
        false
    }
}

/// The implementation of a method.
pub(crate) fn method(m: ContactMethod) -> &'static dyn Method {
    match m {
        ContactMethod::SoftWay => &soft_way::SoftWay,
        ContactMethod::AugmentedLagrangian => &augmented_lagrangian::AugmentedLagrangian,
        ContactMethod::ImplicitProjection => &implicit_projection::ImplicitProjection,
        ContactMethod::ExplicitProjection => &explicit_projection::ExplicitProjection,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::MasterId;

    /// The penalty methods' tangential spring is the normal penalty times the area, capped at
    /// four diagonals per step; without a diagonal (no mass, no stiffness) it is not capped.
    #[test]
    fn the_penalty_tangential_spring_is_capped_by_the_diagonal() {
        let settings = ContactSettings {
            penalty: 1e9,
            ..ContactSettings::default()
        };
        let input = |diagonal: f64| NormalInput {
            key: (0, MasterId::Obstacle(0)),
            gap: -1e-4,
            start_gap: 0.0,
            normal_velocity: -0.1,
            area: 1e-2,
            time_step: 1e-3,
            diagonal,
        };
        for m in [ContactMethod::SoftWay, ContactMethod::AugmentedLagrangian] {
            let method = method(m);
            // zeta A = 1e7 N/m against 4 x 1e3 / 1e-3 = 4e6 N/m.
            assert_eq!(method.tangential_stiffness(&input(1e3), &settings), 4e6);
            assert_eq!(method.tangential_stiffness(&input(1e6), &settings), 1e7);
            assert_eq!(method.tangential_stiffness(&input(0.0), &settings), 1e7);
        }
    }
}
