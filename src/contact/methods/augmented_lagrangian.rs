//! The augmented Lagrangian with Uzawa updates (eq 28-30): soft-way solves around multipliers
//! `lambda` (contact pressures), updated as `lambda <- max(0, lambda - zeta g)` until no gap is
//! below `-gap_tolerance` and no pressure acts across a gap above it. The multipliers of closed
//! pairs are carried from step to step; those of open pairs are dropped. By default
//! ([`UzawaPenalty::Growing`]) a pair whose violation an update shrank by less than 4x gets a
//! tenfold penalty for the rest of the step (at most 100 zeta); `Fixed` is the paper's.

use std::collections::BTreeSet;

use super::soft_way::penalty_law;
use super::{Method, NormalInput, NormalLaw, OuterUpdate, OuterVariables, PairStatus};
use crate::contact::{ContactKey, ContactSettings, UzawaPenalty};

/// The augmented Lagrangian (Uzawa).
pub(crate) struct AugmentedLagrangian;

/// A pair whose violation an Uzawa update left above this fraction of the previous one gets a
/// stiffer penalty for the rest of the step.
const PENALTY_GROWTH_BELOW: f64 = 0.25;

/// Largest multiple of `zeta` a pair's penalty reaches within a step.
const MAX_PENALTY_SCALE: f64 = 100.0;

/// A violation an update left above this fraction of the previous one did not move.
const STALLED_ABOVE: f64 = 0.99;

/// Where Uzawa stalls, violations up to this multiple of `gap_tolerance` end the step.
const STALLED_GAP_FACTOR: f64 = 10.0;

/// A pair's penalty as a multiple of `zeta` (1 until raised in this step).
fn penalty_scale(vars: &OuterVariables, key: &ContactKey) -> f64 {
    vars.penalty_scales.get(key).copied().unwrap_or(1.0)
}

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
        penalty_law(
            lambda,
            input,
            settings.penalty * penalty_scale(vars, &input.key),
        )
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
        let tolerance = settings.gap_tolerance;
        let zeta =
            |vars: &OuterVariables, p: &PairStatus| settings.penalty * penalty_scale(vars, &p.key);
        let lambda = |vars: &OuterVariables, p: &PairStatus| {
            vars.multipliers.get(&p.key).copied().unwrap_or(0.0)
        };
        // The pair's violation of Signorini to the tolerance: its penetration, or the gap a
        // pressure acts across (0: none).
        let violation = |vars: &OuterVariables, p: &PairStatus| {
            let trial = lambda(vars, p) - zeta(vars, p) * p.gap;
            if p.gap < -tolerance {
                -p.gap
            } else if p.gap > tolerance && trial > 0.0 {
                p.gap
            } else {
                0.0
            }
        };
        let violated = pairs.iter().any(|p| violation(vars, p) > 0.0);
        let growing = settings.uzawa_penalty == UzawaPenalty::Growing;
        // Uzawa stalls where the pressures cannot move the gaps: every violating pair at its
        // largest penalty, its violation unmoved by the last update (< 1 %), and within ten
        // times the gap tolerance (a deeper one goes on, to a cut step). Between two bodies both
        // passes hold each other's nodes, and where the meshes do not match some of those
        // constraints cannot all close: their multipliers then trade pressure (one pair's up,
        // another's down) without end. The 3D stack of soft blocks at step 227 had three
        // such pairs, violations of 1.4e-9 to 6.0e-9 m (pressures / zeta up to 9e-6 m) that
        // spent the step's 50 iterations moving less than 0.1 % per update.
        let stalled = growing
            && violated
            && pairs.iter().all(|p| {
                let violation = violation(vars, p);
                violation == 0.0
                    || penalty_scale(vars, &p.key) >= MAX_PENALTY_SCALE
                        && vars
                            .previous_violations
                            .get(&p.key)
                            .is_some_and(|&before| violation > STALLED_ABOVE * before)
                        && violation <= STALLED_GAP_FACTOR * tolerance
            });
        if !violated || stalled {
            // A pair whose update would give zero is open: its multiplier goes, as do those
            // of pairs no longer detected, so that a pair found again starts from zero
            // instead of being pushed apart by a stale pressure.
            let closed: BTreeSet<ContactKey> = pairs
                .iter()
                .filter(|p| lambda(vars, p) - zeta(vars, p) * p.gap > 0.0)
                .map(|p| p.key)
                .collect();
            vars.multipliers.retain(|key, _| closed.contains(key));
            return OuterUpdate::Converged;
        }
        for p in pairs {
            let trial = lambda(vars, p) - zeta(vars, p) * p.gap;
            let violation = violation(vars, p);
            let next = trial.max(0.0);
            if next > 0.0 {
                vars.multipliers.insert(p.key, next);
            } else {
                vars.multipliers.remove(&p.key);
            }
            // Uzawa shrinks a penetration by about k / (k + zeta A) per update (k the body's
            // stiffness there), and takes an open gap's pressure away by zeta g per update:
            // where the violation shrank by less than PENALTY_GROWTH_BELOW, the pair's penalty
            // grows tenfold (the method of multipliers' penalty update).
            let scale = penalty_scale(vars, &p.key);
            if let (Some(&before), true) = (vars.previous_violations.get(&p.key), growing) {
                if violation > PENALTY_GROWTH_BELOW * before && scale < MAX_PENALTY_SCALE {
                    vars.penalty_scales
                        .insert(p.key, (scale * 10.0).min(MAX_PENALTY_SCALE));
                }
            }
            if violation > 0.0 {
                vars.previous_violations.insert(p.key, violation);
            } else {
                vars.previous_violations.remove(&p.key);
            }
        }
        OuterUpdate::Again
    }

    fn carries_multipliers(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::MasterId;

    fn pair(gap: f64) -> PairStatus {
        PairStatus {
            key: (0, MasterId::Obstacle(0)),
            gap,
            normal_force: 0.0,
            normal_velocity: 0.0,
        }
    }

    /// Two updates on a penetration that shrank only 2x: the growing penalty goes tenfold,
    /// the paper's stays; one that shrank 10x keeps its penalty either way.
    #[test]
    fn the_penalty_grows_where_uzawa_crawls() {
        for (update, shrink, expected) in [
            (UzawaPenalty::Growing, 0.5, 10.0),
            (UzawaPenalty::Fixed, 0.5, 1.0),
            (UzawaPenalty::Growing, 0.1, 1.0),
        ] {
            let settings = ContactSettings {
                method: crate::contact::ContactMethod::AugmentedLagrangian,
                penalty: 1e9,
                uzawa_penalty: update,
                ..ContactSettings::default()
            };
            let mut vars = OuterVariables::default();
            let log = &mut |_: String| {};
            let first =
                AugmentedLagrangian.outer_update(&[pair(-1e-6)], &mut vars, &settings, 1e-3, log);
            assert_eq!(first, OuterUpdate::Again);
            AugmentedLagrangian.outer_update(
                &[pair(-1e-6 * shrink)],
                &mut vars,
                &settings,
                1e-3,
                log,
            );
            let key = (0, MasterId::Obstacle(0));
            assert_eq!(
                penalty_scale(&vars, &key),
                expected,
                "{update:?}, shrink {shrink}"
            );
            // The multiplier took zeta g with the scale of the update.
            let lambda = vars.multipliers[&key];
            assert!(
                (lambda - 1e9 * (1e-6 + 1e-6 * shrink)).abs() < 1e-6 * lambda,
                "{lambda}"
            );
        }
    }

    /// A penetration that updates at the largest penalty no longer move (locked by other
    /// constraints) ends the step within ten times the gap tolerance; a deeper one, or one
    /// that still moves, does not.
    #[test]
    fn uzawa_stops_where_the_pressure_no_longer_moves_the_gap() {
        let settings = ContactSettings {
            method: crate::contact::ContactMethod::AugmentedLagrangian,
            penalty: 1e9,
            ..ContactSettings::default()
        };
        let key = (0, MasterId::Obstacle(0));
        let log = &mut |_: String| {};
        for (gap, next, pressure, expected) in [
            (-5e-9, -4.999e-9, 5e3, OuterUpdate::Converged),
            (-5e-9, -4e-9, 5e3, OuterUpdate::Again),
            (-5e-3, -4.999e-3, 5e3, OuterUpdate::Again),
        ] {
            let mut vars = OuterVariables::default();
            vars.penalty_scales.insert(key, MAX_PENALTY_SCALE);
            vars.multipliers.insert(key, pressure);
            let first =
                AugmentedLagrangian.outer_update(&[pair(gap)], &mut vars, &settings, 1e-3, log);
            assert_eq!(first, OuterUpdate::Again);
            let second =
                AugmentedLagrangian.outer_update(&[pair(next)], &mut vars, &settings, 1e-3, log);
            assert_eq!(second, expected, "{gap} -> {next}");
        }
    }
}
