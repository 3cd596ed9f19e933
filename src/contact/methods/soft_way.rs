//! The soft way (eq 27): a penalty on the eq 22 gap. The contact pressure is
//! `p = zeta (-g)` for `g < 0`; a node's force is `p` times its contact area, and its tangent
//! `zeta A (h/2) n n^T` spread over the master's nodes (plus the geometric terms of the gap's
//! Hessian, added by the step).

use super::{Method, NormalInput, NormalLaw, OuterVariables};
use crate::contact::{ContactKey, ContactSettings, PenaltyForce};

/// The soft way.
pub(crate) struct SoftWay;

/// The penalty law around a multiplier `lambda` (Pa): `p = max(0, lambda - zeta g)`.
pub(crate) fn penalty_law(lambda: f64, input: &NormalInput, zeta: f64) -> NormalLaw {
    let p = lambda - zeta * input.gap;
    if p > 0.0 {
        NormalLaw {
            force: p * input.area,
            stiffness: 0.5 * input.time_step * zeta * input.area,
            geometric_force: p * input.area,
            velocity_stiffness: 0.0,
            predicted_force: 0.0,
            held: None,
        }
    } else {
        NormalLaw::default()
    }
}

/// The end-of-step penalty's closed branch where the gap is open: its stiffness, and its
/// (tensile) force for the first Newton direction only ([`NormalLaw::predicted_force`]).
fn predicted_penalty_law(input: &NormalInput, zeta: f64) -> NormalLaw {
    NormalLaw {
        stiffness: 0.5 * input.time_step * zeta * input.area,
        predicted_force: -zeta * input.gap * input.area,
        ..NormalLaw::default()
    }
}

/// The penalty potential's secant over the step (`PenaltyForce::Secant`): the pressure whose
/// work over the step, `-p (g1 - g0)`, is `phi(g0) - phi(g1)` with `phi(g) = zeta min(g, 0)^2 / 2`.
pub(crate) fn secant_penalty_law(input: &NormalInput, zeta: f64) -> NormalLaw {
    let (g0, g1) = (input.start_gap, input.gap);
    let phi = |g: f64| 0.5 * zeta * g.min(0.0).powi(2);
    let dg = g1 - g0;
    // Below this the secant is the tangent to round-off (|dg| relative to the gaps).
    if dg.abs() <= 1e-12 * (g0.abs() + g1.abs()) {
        return penalty_law(0.0, input, zeta);
    }
    let p = (phi(g0) - phi(g1)) / dg;
    if p <= 0.0 {
        return NormalLaw::default();
    }
    // dp/dg1 = -(phi'(g1) + p) / dg; the law's stiffness is -A dp/dg1 dg1/dw1, dg1/dw1 = h/2.
    let dp_dg1 = -(zeta * g1.min(0.0) + p) / dg;
    NormalLaw {
        force: p * input.area,
        stiffness: (-dp_dg1).max(0.0) * 0.5 * input.time_step * input.area,
        geometric_force: p * input.area,
        velocity_stiffness: 0.0,
        predicted_force: 0.0,
        held: None,
    }
}

impl Method for SoftWay {
    fn symmetric_pairs(&self) -> bool {
        true
    }

    fn start(&self, vars: &mut OuterVariables, starting: &[ContactKey]) {
        vars.predicted = starting.iter().copied().collect();
    }

    fn keeps_closed_points(&self) -> bool {
        true
    }

    fn normal_law(
        &self,
        input: &NormalInput,
        vars: &OuterVariables,
        settings: &ContactSettings,
    ) -> NormalLaw {
        let law = match settings.penalty_force {
            PenaltyForce::EndOfStep => penalty_law(0.0, input, settings.penalty),
            PenaltyForce::Secant => secant_penalty_law(input, settings.penalty),
        };
        if law.stiffness > 0.0 || !vars.predicted.contains(&input.key) {
            return law;
        }
        // Closed at the end of the last step, opened by the predictor: the first direction
        // keeps the closed branch (a resting face moving up is not dropped for an iteration
        // and caught again, with the factorisations and backtracking that costs).
        predicted_penalty_law(input, settings.penalty)
    }

    fn stores_energy(&self) -> bool {
        true
    }

    fn friction_return_map(&self) -> bool {
        true
    }
}
