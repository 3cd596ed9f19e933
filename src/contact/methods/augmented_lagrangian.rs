//! The augmented Lagrangian with Uzawa updates (eq 28-30): soft-way solves around multipliers
//! `lambda` (contact pressures), updated as `lambda <- max(0, lambda - zeta g)` until every gap
//! is within `gap_tolerance`. The multipliers are carried from step to step.

use super::soft_way::penalty_law;
use super::{Method, NormalInput, NormalLaw, OuterUpdate, OuterVariables, PairStatus};
use crate::contact::ContactSettings;

/// The augmented Lagrangian (Uzawa).
pub(crate) struct AugmentedLagrangian;

impl Method for AugmentedLagrangian {
    fn normal_law(
        &self,
        input: &NormalInput,
        vars: &OuterVariables,
        settings: &ContactSettings,
    ) -> NormalLaw {
        let lambda = vars.multipliers.get(&input.key).copied().unwrap_or(0.0);
        penalty_law(lambda, input, settings.penalty)
    }

    fn stores_energy(&self) -> bool {
        true
    }

    fn friction_return_map(&self) -> bool {
        true
    }

    fn outer_update(
        &self,
        pairs: &[PairStatus],
        vars: &mut OuterVariables,
        settings: &ContactSettings,
        _time_step: f64,
        _log: &mut dyn FnMut(String),
    ) -> OuterUpdate {
        let worst = pairs.iter().map(|p| -p.gap).fold(0.0, f64::max);
        if worst <= settings.gap_tolerance {
            return OuterUpdate::Converged;
        }
        for p in pairs {
            let lambda = vars.multipliers.entry(p.key).or_insert(0.0);
            *lambda = (*lambda - settings.penalty * p.gap).max(0.0);
        }
        OuterUpdate::Again
    }

    fn carries_multipliers(&self) -> bool {
        true
    }
}
