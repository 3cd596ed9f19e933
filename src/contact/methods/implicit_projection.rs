//! Implicit projection: an active-set iteration inside the step. For an active point the
//! relative normal end velocity is held at zero (the paper: "the normal velocity at the end of
//! the time step is settled equal to zero and the tangential velocity is free to change") by a
//! multiplier updated between solves (an augmented Lagrangian on the velocity constraint, exact
//! at convergence); its end position is projected onto the master ([`super::projection`]).
//! Points in tension are released, newly penetrating points added, until the set no longer
//! changes; a set seen before in the step is a cycle.

use super::{
    EndProjection, Method, NormalInput, NormalLaw, OuterUpdate, OuterVariables, PairStatus,
};
use crate::contact::{ContactKey, ContactSettings};

/// Implicit projection.
pub(crate) struct ImplicitProjection;

/// The velocity penalty that holds an active point, relative to its largest diagonal entry.
const VELOCITY_PENALTY: f64 = 1e4;

/// The return map's tangential stiffness times the step, relative to the largest diagonal.
const TANGENTIAL_PENALTY: f64 = 1e2;

impl Method for ImplicitProjection {
    fn start(&self, vars: &mut OuterVariables, penetrating: &[ContactKey]) {
        // Points predicted to penetrate with v1 = v0 start active: this also catches points
        // already touching that the master moves into.
        vars.active.extend(penetrating.iter().copied());
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
        NormalLaw {
            force: lambda - rho * input.normal_velocity,
            stiffness: rho,
            pressure: 0.0,
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
        let mut changed = false;
        for p in pairs {
            if vars.active.contains(&p.key) && p.normal_force < 0.0 {
                vars.active.remove(&p.key);
                vars.multipliers.remove(&p.key);
                changed = true;
                log(format!(
                    "node {} released (tension {:.3e} N)",
                    p.key.0, p.normal_force
                ));
            } else if !vars.active.contains(&p.key) && p.gap < -settings.gap_tolerance {
                vars.active.insert(p.key);
                changed = true;
                log(format!("node {} activated (gap {:.3e} m)", p.key.0, p.gap));
            }
        }
        if changed {
            let set: Vec<ContactKey> = vars.active.iter().copied().collect();
            if !vars.seen_sets.insert(set) {
                log("the contact set cycles".into());
                return OuterUpdate::Cycle;
            }
            return OuterUpdate::Again;
        }
        let tolerance = settings.gap_tolerance / time_step;
        let worst = pairs
            .iter()
            .filter(|p| vars.active.contains(&p.key))
            .map(|p| p.normal_velocity.abs())
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

    // Coulomb and Tresca as the return map: the normal force of an active point is a
    // multiplier of a velocity constraint, exact only at convergence, so Coulomb's threshold
    // takes the previous pass's (the fixed point that the smooth law used).
    fn friction_return_map(&self) -> bool {
        true
    }

    fn lagged_friction_threshold(&self) -> bool {
        true
    }

    /// No penalty here: a stiffness of `TANGENTIAL_PENALTY` times the slave's diagonal per
    /// step, so that a sticking point's elastic slip is `F_t h / (100 diagonal)`, about
    /// `F_t h^2 / (100 m)`, and the iteration matrix's rows grow a hundredfold at most.
    fn tangential_stiffness(&self, input: &NormalInput, _settings: &ContactSettings) -> f64 {
        TANGENTIAL_PENALTY * input.diagonal / input.time_step
    }

    fn end_projection(&self) -> EndProjection {
        EndProjection::Active
    }
}
