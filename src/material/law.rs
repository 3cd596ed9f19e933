//! The constitutive-law interface, evaluated per quadrature point.
//!
//! A law receives the point's kinematics over the step at `t_alpha` (the small strain of
//! `u_alpha`, the rate of deformation and the spin of `v_alpha`, the step and alpha) and its
//! history at the start of the step, and returns the stress, its consistent derivatives with
//! respect to the strain and to the strain rate, and the new history. The element kernel turns
//! them into internal forces and the Newton tangent
//! `int B^T (d1 h dsigma/deps + alpha dsigma/deps_dot) B` (d1 = alpha^2 / 2, the weight of
//! `v1` in `u_alpha`). A linear law (constant tangent, no history) is assembled once and
//! factored once per step size; any other law is evaluated every Newton iteration.
//!
//! Small-strain laws read `strain` (of the displacement from the reference configuration);
//! updated-Lagrangian laws ([`ConstitutiveLaw::updated_lagrangian`]) read the increment's
//! gradient from the start of the step, keep their stress as history and are integrated on
//! the configuration at `t_alpha`.

use nalgebra::Matrix3;

use crate::dim::{Kinematics, Voigt, VoigtMatrix};

/// The kinematics of one quadrature point over a step, at `t_alpha`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointKinematics {
    /// The body's kinematics (plane strain, plane stress, axisymmetric, solid).
    pub kinematics: Kinematics,
    /// Small strain of the displacement at `t_alpha` (dimensionless; Voigt, engineering shears).
    pub strain: Voigt,
    /// Rate of deformation at `t_alpha` (1/s; Voigt, engineering shears).
    pub strain_rate: Voigt,
    /// Spin (skew part of the velocity gradient) at `t_alpha` (1/s).
    pub spin: Matrix3<f64>,
    /// The step h (s).
    pub time_step: f64,
    /// The scheme's alpha (dimensionless).
    pub alpha: f64,
    /// Updated-Lagrangian laws: the gradient of the displacement increment from `t0` to
    /// `t_alpha` with respect to the configuration at `t0` (3 x 3: in-plane block, and the
    /// hoop term `du_r / r` in the zz slot of axisymmetric kinematics) (dimensionless).
    pub increment: Matrix3<f64>,
    /// The same from `t0` to `t1` (the configuration update), for the history at the end of
    /// the step (dimensionless).
    pub end_increment: Matrix3<f64>,
    /// Whether Newton asks for the secant rather than the consistent tangent (laws whose
    /// consistent tangent overshoots far from the solution, power-law flows: Kacanov's
    /// iteration); laws that do not care ignore it.
    pub secant: bool,
}

/// What a law returns at one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointResponse {
    /// Cauchy stress (Pa; Voigt).
    pub stress: Voigt,
    /// `d stress / d strain` at fixed strain rate (Pa).
    pub stiffness: VoigtMatrix,
    /// `d stress / d strain_rate` at fixed strain (Pa s).
    pub viscosity: VoigtMatrix,
    /// Stored (recoverable) energy per unit volume (J/m^3).
    pub energy_density: f64,
}

/// A constitutive law evaluated per quadrature point.
pub trait ConstitutiveLaw: Send + Sync {
    /// Number of history values per quadrature point (0 for laws without history).
    fn history_len(&self) -> usize {
        0
    }

    /// Whether the stress is a constant linear function of the strain (no rate, no history):
    /// such a body is assembled once.
    fn is_linear(&self) -> bool;

    /// Whether the law works on the configuration at the start of the step (updated
    /// Lagrangian: large rotations). The kernel then integrates on the current configuration,
    /// fills [`PointKinematics::increment`] and adds the geometric (initial-stress)
    /// stiffness; otherwise everything is on the reference configuration (small strain).
    fn updated_lagrangian(&self) -> bool {
        false
    }

    /// Whether the cell's volumetric strain is averaged over Quad4 and Hex8 cells (B-bar):
    /// laws that are nearly incompressible lock without it.
    fn volumetric_average(&self) -> bool {
        false
    }

    /// Whether the law stores nothing: the work of its stress is dissipated (a flow law).
    fn dissipative(&self) -> bool {
        false
    }

    /// The response at one point; writes the history at the end of the step into
    /// `new_history` (`history_len` values) from the one at its start, `history`.
    fn evaluate(
        &self,
        point: &PointKinematics,
        history: &[f64],
        new_history: &mut [f64],
    ) -> PointResponse;
}
