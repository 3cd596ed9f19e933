//! Implicit projection: an active-set iteration inside the step. For an active point the
//! relative normal end velocity is held at zero (the paper: "the normal velocity at the end of
//! the time step is settled equal to zero and the tangential velocity is free to change") by a
//! multiplier updated between solves (an augmented Lagrangian on the velocity constraint, exact
//! at convergence); its end position is projected onto the master ([`super::projection`]).
//!
//! The constraint of an active point is `C = max(w_n, 2 g / h) = 0` (w_n the relative normal
//! end velocity, g the eq 22 gap, which moves by `h/2` per unit of w_n: both branches have
//! slope 1). A point already on the master, or one that cannot stop before it, is held at
//! `w_n = 0` (the paper's rule); a point that would stop short of the master closes the gap
//! exactly instead of being held in the air. A free point is activated only when it violates
//! the same constraint (penetrating and still approaching): the activation test and the
//! constraint agree, so a point that penetrates while it separates is not re-activated (the
//! cycle the position test made on soft bodies). Points in tension are released; a point
//! released twice in a step stays closed until the step ends (node locking), and when a set
//! comes back every point released in the step keeps its status until the step ends: each
//! point changes status a bounded number of times, so the iteration ends.

use super::{
    EndProjection, HeldConstraint, Method, NormalInput, NormalLaw, OuterUpdate, OuterVariables,
    PairStatus,
};
use crate::contact::{ContactKey, ContactSettings};

/// Implicit projection.
pub(crate) struct ImplicitProjection;

/// The velocity penalty that holds an active point, relative to its largest diagonal entry
/// (the end-of-step projection's rows take the same, so that Newton's last factorisation
/// preconditions them).
pub(crate) const VELOCITY_PENALTY: f64 = 1e4;

/// The return map's tangential stiffness times the step, relative to the slave's diagonal.
/// At 100 (until 2026-11-29) the 3D stack of blocks with Coulomb 0.5 stopped at step 191:
/// about ten slipping points reversed their friction at every Newton iterate, a slip rate of
/// a few micrometres per second making a trial force past the limit the other way.
const TANGENTIAL_PENALTY: f64 = 1.0;

/// Releases of one point in a step after which it stays closed until the step ends.
pub(crate) const RELEASES_BEFORE_LOCK: u32 = 2;

/// The constraint of an active point, `max(w_n, 2 g / h)` (m/s): zero when it is held on the
/// master (`w_n = 0`, `g <= 0`) or closes the gap exactly while approaching (`g = 0`).
pub(crate) fn constraint(normal_velocity: f64, gap: f64, time_step: f64) -> f64 {
    normal_velocity.max(2.0 * gap / time_step)
}

impl Method for ImplicitProjection {
    fn start(&self, vars: &mut OuterVariables, starting: &[ContactKey]) {
        // Points predicted to penetrate with v1 = v0 start active (this also catches points
        // already touching that the master moves into), and so do the points held when the
        // last step ended: those about to separate are released by their tension.
        vars.active.extend(starting.iter().copied());
    }

    fn normal_law(
        &self,
        input: &NormalInput,
        vars: &OuterVariables,
        _settings: &ContactSettings,
    ) -> NormalLaw {
        if !vars.active.contains(&input.key) {
            return NormalLaw::default();
        }
        let rho = VELOCITY_PENALTY * input.diagonal;
        let lambda = vars.multipliers.get(&input.key).copied().unwrap_or(0.0);
        let value = constraint(input.normal_velocity, input.gap, input.time_step);
        let force = lambda - rho * value;
        let holds_velocity = input.normal_velocity >= 2.0 * input.gap / input.time_step;
        NormalLaw {
            force,
            stiffness: rho,
            geometric_force: force,
            velocity_stiffness: if holds_velocity { rho } else { 0.0 },
            predicted_force: 0.0,
            held: Some(HeldConstraint {
                value,
                penalty: rho,
            }),
        }
    }

    fn outer_update(
        &self,
        pairs: &[PairStatus],
        vars: &mut OuterVariables,
        settings: &ContactSettings,
        time_step: f64,
        log: &mut dyn FnMut(String),
    ) -> OuterUpdate {
        let tolerance = settings.gap_tolerance / time_step;
        let mut changed = false;
        for p in pairs {
            if vars.locked.contains(&p.key) {
                continue;
            }
            let c = constraint(p.normal_velocity, p.gap, time_step);
            if vars.active.contains(&p.key) && p.normal_force < 0.0 {
                let released = vars.releases.get(&p.key).copied().unwrap_or(0);
                if released >= RELEASES_BEFORE_LOCK {
                    vars.locked.insert(p.key);
                    log(format!(
                        "node {} kept closed (released {released} times; tension {:.3e} N)",
                        p.key.0, p.normal_force
                    ));
                    continue;
                }
                vars.releases.insert(p.key, released + 1);
                vars.active.remove(&p.key);
                vars.multipliers.remove(&p.key);
                changed = true;
                log(format!(
                    "node {} released (tension {:.3e} N)",
                    p.key.0, p.normal_force
                ));
            } else if !vars.active.contains(&p.key) && c < -tolerance {
                vars.active.insert(p.key);
                changed = true;
                log(format!(
                    "node {} activated (gap {:.3e} m, normal velocity {:.3e} m/s)",
                    p.key.0, p.gap, p.normal_velocity
                ));
            }
        }
        if changed {
            let set: Vec<ContactKey> = vars.active.iter().copied().collect();
            if !vars.seen_sets.insert(set) {
                vars.cycles += 1;
                // A cycle: every point released in this step keeps the status it has now
                // until the step ends (closed ones may pull, open ones are moved out by the
                // end-of-step projection); the rest go on.
                let flipping: Vec<ContactKey> = vars
                    .releases
                    .keys()
                    .filter(|k| !vars.locked.contains(k))
                    .copied()
                    .collect();
                if flipping.is_empty() {
                    log("the contact set cycles".into());
                    return OuterUpdate::Cycle;
                }
                log(format!(
                    "the contact set cycles: {} flipping node(s) keep their status",
                    flipping.len()
                ));
                vars.locked.extend(flipping);
            }
            return OuterUpdate::Again;
        }
        let worst = pairs
            .iter()
            .filter(|p| vars.active.contains(&p.key))
            .map(|p| constraint(p.normal_velocity, p.gap, time_step).abs())
            .fold(0.0, f64::max);
        if worst <= tolerance {
            return OuterUpdate::Converged;
        }
        for p in pairs {
            if vars.active.contains(&p.key) {
                vars.multipliers.insert(p.key, p.normal_force);
            }
        }
        OuterUpdate::Again
    }

    /// The held points' forces start the next step's multipliers: a point that stays held
    /// needs no pass to find its force again.
    fn carries_multipliers(&self) -> bool {
        true
    }

    // Coulomb and Tresca as the return map: the normal force of an active point is a
    // multiplier of a velocity constraint, exact only at convergence, so Coulomb's threshold
    // takes the previous pass's (the fixed point that the smooth law used).
    fn friction_return_map(&self) -> bool {
        true
    }

    fn lagged_friction_threshold(&self) -> bool {
        true
    }

    fn closed_by_active_set(&self) -> bool {
        true
    }

    /// No penalty here: a stiffness of `TANGENTIAL_PENALTY` times the slave's diagonal per
    /// step, so that a sticking point's elastic slip is `F_t h / diagonal`, at most
    /// `F_t h^2 / m`: the distance the friction force would move the node's mass in one step
    /// from rest, a second-order quantity like the scheme's own error; the iteration matrix's
    /// rows at most double.
    fn tangential_stiffness(&self, input: &NormalInput, _settings: &ContactSettings) -> f64 {
        TANGENTIAL_PENALTY * input.diagonal / input.time_step
    }

    fn end_projection(&self) -> EndProjection {
        EndProjection::Active
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::MasterId;

    /// A point that is released, activated again and released again brings the empty set
    /// back: a cycle, counted, and the flipping point held until the step ends.
    #[test]
    fn a_set_that_comes_back_is_counted_and_its_point_held() {
        let key: ContactKey = (7, MasterId::Obstacle(0));
        let settings = ContactSettings::default();
        let h = 1e-3;
        let mut vars = OuterVariables::default();
        ImplicitProjection.start(&mut vars, &[key]);
        let tension = PairStatus {
            key,
            gap: 0.0,
            normal_force: -1.0,
            normal_velocity: 0.0,
        };
        let approaching = PairStatus {
            key,
            gap: -1e-3,
            normal_force: 0.0,
            normal_velocity: -1.0,
        };
        let update = |p: PairStatus, vars: &mut OuterVariables| {
            ImplicitProjection.outer_update(&[p], vars, &settings, h, &mut |_| {})
        };
        assert_eq!(update(tension, &mut vars), OuterUpdate::Again);
        assert_eq!(update(approaching, &mut vars), OuterUpdate::Again);
        assert_eq!((vars.cycles, vars.locked.len()), (0, 0));
        assert_eq!(update(tension, &mut vars), OuterUpdate::Again);
        assert_eq!(vars.cycles, 1);
        assert!(vars.locked.contains(&key));
    }
}
