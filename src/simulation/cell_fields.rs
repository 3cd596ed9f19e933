//! Fields per cell for outputs and hosts: the mean stress and the equivalent strain.

use super::{BodyId, Simulation};
use crate::assembly;
use crate::dim::{Dim, SpatialDim, Voigt};
use crate::error::Result;

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
    pub fn cell_stresses(&self) -> Vec<Voigt> {
        assembly::cell_stresses::<D>(
            &self.table,
            &self.reference,
            &self.integration,
            &self.state.displacement,
            &self.state.material_history,
        )
    }

    /// The cells of `body` in [`Simulation::cell_stresses`]'s order (their indices there,
    /// the body's cells in its mesh's order); an error for a stale or forged handle.
    fn body_cells(&self, body: BodyId) -> Result<std::ops::Range<usize>> {
        let b = self.body_index(body)?;
        let start = self.model.bodies[..b]
            .iter()
            .map(|x| x.mesh.cell_count())
            .sum();
        Ok(start..start + self.model.bodies[b].mesh.cell_count())
    }

    /// Average Voigt stress (Pa) of each cell of one body, in its mesh's cell order.
    pub fn body_cell_stresses(&self, body: BodyId) -> Result<Vec<Voigt>> {
        let cells = self.body_cells(body)?;
        Ok(self.cell_stresses()[cells].to_vec())
    }

    /// The equivalent logarithmic strain (see [`Simulation::cell_equivalent_strains`]) of
    /// each cell of one body, in its mesh's cell order.
    pub fn body_cell_equivalent_strains(&self, body: BodyId) -> Result<Vec<f64>> {
        let cells = self.body_cells(body)?;
        Ok(self.cell_equivalent_strains()[cells].to_vec())
    }
}
