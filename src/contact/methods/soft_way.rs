//! The soft way (eq 27): a penalty on the eq 22 gap. The contact pressure is
//! `p = zeta (-g)` for `g < 0`; a node's force is `p` times its contact area, and its tangent
//! `zeta A (h/2) n n^T` spread over the master's nodes (plus the geometric terms of the gap's
//! Hessian, added by the step).

use super::{Method, NormalInput, NormalLaw, OuterVariables};
use crate::contact::ContactSettings;

/// The soft way.
pub(crate) struct SoftWay;

/// The penalty law around a multiplier `lambda` (Pa): `p = max(0, lambda - zeta g)`.
pub(crate) fn penalty_law(lambda: f64, input: &NormalInput, zeta: f64) -> NormalLaw {
    let p = lambda - zeta * input.gap;
    if p > 0.0 {
        NormalLaw {
            force: p * input.area,
            stiffness: 0.5 * input.time_step * zeta * input.area,
            pressure: p,
        }
    } else {
        NormalLaw::default()
    }
}

impl Method for SoftWay {
    fn symmetric_pairs(&self) -> bool {
        true
    }

    fn normal_law(
        &self,
        input: &NormalInput,
        _vars: &OuterVariables,
        settings: &ContactSettings,
    ) -> NormalLaw {
        penalty_law(0.0, input, settings.penalty)
    }

    fn stores_energy(&self) -> bool {
        true
    }

    fn friction_return_map(&self) -> bool {
        true
    }
}
