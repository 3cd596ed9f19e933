//! The augmented Lagrangian with Uzawa updates (eq 28-30): soft-way solves around multipliers
//! `lambda` (contact pressures), updated as `lambda <- max(0, lambda - zeta g)` until no gap is
//! below `-gap_tolerance` and no pressure acts across a gap above it. The multipliers of closed
//! pairs are carried from step to step; those of open pairs are dropped.

use std::collections::BTreeSet;

use super::soft_way::penalty_law;
use super::{Method, NormalInput, NormalLaw, OuterUpdate, OuterVariables, PairStatus};
use crate::contact::{ContactKey, ContactSettings};

/// The augmented Lagrangian (Uzawa).
pub(crate) struct AugmentedLagrangian;

impl Method for AugmentedLagrangian {
    fn symmetric_pairs(&self) -> bool {
        true
    }

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
        let (zeta, tolerance) = (settings.penalty, settings.gap_tolerance);
        let lambda = |vars: &OuterVariables, p: &PairStatus| {
            vars.multipliers.get(&p.key).copied().unwrap_or(0.0)
        };
        // Signorini to the tolerance: no penetration, and no pressure across an open gap.
        let penetrates = pairs.iter().any(|p| p.gap < -tolerance);
        let pushes_open = pairs
            .iter()
            .any(|p| p.gap > tolerance && lambda(vars, p) - zeta * p.gap > 0.0);
        if !penetrates && !pushes_open {
            // A pair whose update would give zero is open: its multiplier goes, as do those
            // of pairs no longer detected, so that a pair found again starts from zero
            // instead of being pushed apart by a stale pressure.
            let closed: BTreeSet<ContactKey> = pairs
                .iter()
                .filter(|p| lambda(vars, p) - zeta * p.gap > 0.0)
                .map(|p| p.key)
                .collect();
            vars.multipliers.retain(|key, _| closed.contains(key));
            return OuterUpdate::Converged;
        }
        for p in pairs {
            let next = (lambda(vars, p) - zeta * p.gap).max(0.0);
            if next > 0.0 {
                vars.multipliers.insert(p.key, next);
            } else {
                vars.multipliers.remove(&p.key);
            }
        }
        OuterUpdate::Again
    }

    fn carries_multipliers(&self) -> bool {
        true
    }
}
