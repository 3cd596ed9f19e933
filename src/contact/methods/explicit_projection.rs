//! Explicit projection (category 1, the baseline of Table 1): the step is solved without
//! contact; at its end every point that went through its master is projected onto it and its
//! approaching normal relative velocity removed (see [`super::projection`]).

use super::{EndProjection, Method, NormalInput, NormalLaw, OuterVariables};
use crate::contact::ContactSettings;

/// Explicit projection.
pub(crate) struct ExplicitProjection;

impl Method for ExplicitProjection {
    fn in_newton(&self) -> bool {
        false
    }

    fn normal_law(
        &self,
        _input: &NormalInput,
        _vars: &OuterVariables,
        _settings: &ContactSettings,
    ) -> NormalLaw {
        NormalLaw::default()
    }

    fn end_projection(&self) -> EndProjection {
        EndProjection::PenetratingWithVelocity
    }
}
