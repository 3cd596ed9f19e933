//! Fields per cell for outputs and hosts: the mean stress and the equivalent strain.

use super::Simulation;
use crate::assembly;
use crate::dim::{Dim, SpatialDim};

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// The equivalent logarithmic strain of every cell, bodies in order (dimensionless):
    /// `sqrt(2/3 e : e)`, `e` the deviatoric part of the Hencky strain `ln(F^T F) / 2`,
    /// averaged over the cell by volume (0 at rest; 1 for a bar stretched incompressibly to
    /// e = 2.718 times its length). On a proportional path it is the accumulated equivalent
    /// strain that forming codes plot. Plane kinematics take no out-of-plane stretch,
    /// axisymmetric ones the hoop stretch; an inverted cell gives NaN.
    pub fn cell_equivalent_strains(&self) -> Vec<f64> {
        assembly::cell_equivalent_strains::<D>(
            &self.table,
            &self.reference,
            &self.integration,
            &self.state.displacement,
        )
    }

    /// Average Voigt stress of every cell, bodies in order (Pa).
    pub fn cell_stresses(&self) -> Vec<crate::dim::Voigt> {
        assembly::cell_stresses::<D>(
            &self.table,
            &self.reference,
            &self.integration,
            &self.state.displacement,
            &self.state.material_history,
        )
    }
}
