//! The Norton-Hoff viscoplastic law of the paper's examples 2 and 3: the deviatoric stress is
//! `s = 2 K (sqrt(3) eps_dot_eq)^(m - 1) eps_dot'`, `eps_dot_eq = sqrt(2/3 eps_dot' :
//! eps_dot')`, so that a uniaxial flow at rate `eps_dot` needs `sqrt(3) K (sqrt(3)
//! eps_dot)^m`; incompressibility is a penalty on the volumetric rate, `p = -bulk_penalty
//! tr(eps_dot)`, integrated with the cell's average volumetric rate (B-bar) on Quad4 and Hex8
//! so that it does not lock. The law is a flow: it stores no energy, and its stress works are
//! dissipated; it is integrated on the current configuration (updated Lagrangian).
//!
//! At rest `eps_dot_eq -> 0` and the viscosity `K (sqrt(3) eps_dot_eq)^(m - 1)` grows without
//! bound for m < 1: the rate is regularised, `eps_dot_eq^2 + rate_regularization^2`.

use serde::{Deserialize, Serialize};

use super::{ConstitutiveLaw, PointKinematics, PointResponse};
use crate::dim::{Voigt, VoigtMatrix};
use crate::error::Result;

/// The default regularisation of the equivalent strain rate (1/s).
pub const DEFAULT_RATE_REGULARIZATION: f64 = 1e-6;

fn default_regularization() -> f64 {
    DEFAULT_RATE_REGULARIZATION
}

/// Norton-Hoff viscoplasticity.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NortonHoff {
    /// Consistency K (Pa s^m), > 0.
    pub consistency: f64,
    /// Rate sensitivity m, in (0, 1] (m = 1: a Newtonian fluid of viscosity K).
    pub exponent: f64,
    /// Mass density rho (kg/m^3), >= 0 (0: quasi-static flow).
    pub density: f64,
    /// Penalty on the volumetric rate (Pa s), > 0 (a few decades above the viscosity).
    pub bulk_penalty: f64,
    /// Regularisation of the equivalent strain rate (1/s), > 0.
    #[serde(default = "default_regularization")]
    pub rate_regularization: f64,
}

impl NortonHoff {
    /// A validated law with the default regularisation.
    pub fn new(consistency: f64, exponent: f64, density: f64, bulk_penalty: f64) -> Result<Self> {
        let m = NortonHoff {
            consistency,
            exponent,
            density,
            bulk_penalty,
            rate_regularization: DEFAULT_RATE_REGULARIZATION,
        };
        m.validate()?;
        Ok(m)
    }

    /// Checks the ranges of the parameters.
    pub fn validate(&self) -> Result<()> {
        let bad = super::out_of_range;
        let positive = |v: f64| v > 0.0 && v.is_finite();
        if !positive(self.consistency) {
            return bad(
                "consistency",
                self.consistency,
                "a finite value > 0 [Pa s^m]",
            );
        }
        if !(self.exponent > 0.0 && self.exponent <= 1.0) {
            return bad("exponent", self.exponent, "a value in (0, 1]");
        }
        if !(self.density >= 0.0 && self.density.is_finite()) {
            return bad("density", self.density, "a finite value >= 0 [kg/m^3]");
        }
        if !positive(self.bulk_penalty) {
            return bad(
                "bulk_penalty",
                self.bulk_penalty,
                "a finite value > 0 [Pa s]",
            );
        }
        if !positive(self.rate_regularization) {
            return bad(
                "rate_regularization",
                self.rate_regularization,
                "a finite value > 0 [1/s]",
            );
        }
        Ok(())
    }

    /// The uniaxial flow stress at strain rate `rate` (Pa): `sqrt(3) K (sqrt(3) rate)^m`.
    pub fn flow_stress(&self, rate: f64) -> f64 {
        3f64.sqrt() * self.consistency * (3f64.sqrt() * rate).powf(self.exponent)
    }
}

impl ConstitutiveLaw for NortonHoff {
    /// The accumulated equivalent strain per quadrature point.
    fn history_len(&self) -> usize {
        1
    }

    fn is_linear(&self) -> bool {
        false
    }

    fn updated_lagrangian(&self) -> bool {
        true
    }

    fn volumetric_average(&self) -> bool {
        true
    }

    fn dissipative(&self) -> bool {
        true
    }

    fn evaluate(
        &self,
        point: &PointKinematics,
        history: &[f64],
        new_history: &mut [f64],
    ) -> PointResponse {
        let r = point.strain_rate;
        let trace = r[0] + r[1] + r[2];
        // The deviatoric rate as tensor components (shears halved).
        let d = Voigt::new(
            r[0] - trace / 3.0,
            r[1] - trace / 3.0,
            r[2] - trace / 3.0,
            0.5 * r[3],
            0.5 * r[4],
            0.5 * r[5],
        );
        let contraction = d[0] * d[0]
            + d[1] * d[1]
            + d[2] * d[2]
            + 2.0 * (d[3] * d[3] + d[4] * d[4] + d[5] * d[5]);
        let rate_eq2 = 2.0 / 3.0 * contraction + self.rate_regularization.powi(2);
        let rate_eq = rate_eq2.sqrt();
        let m = self.exponent;
        let mu = self.consistency * (3f64.sqrt() * rate_eq).powf(m - 1.0);
        let mut stress = d * (2.0 * mu);
        for i in 0..3 {
            stress[i] += self.bulk_penalty * trace;
        }
        // d stress / d rate (engineering shears in): 2 mu P + 4/3 (m - 1) mu / eq^2 d d^T,
        // plus the penalty on the trace.
        let mut viscosity = VoigtMatrix::zeros();
        for i in 0..3 {
            for j in 0..3 {
                viscosity[(i, j)] =
                    2.0 * mu * (if i == j { 1.0 } else { 0.0 } - 1.0 / 3.0) + self.bulk_penalty;
            }
            viscosity[(i + 3, i + 3)] = mu;
        }
        if !point.secant {
            viscosity += d * d.transpose() * (4.0 / 3.0 * (m - 1.0) * mu / rate_eq2);
        }
        if let (Some(out), Some(old)) = (new_history.first_mut(), history.first()) {
            *out = old + point.time_step * (2.0 / 3.0 * contraction).sqrt();
        }
        PointResponse {
            stress,
            stiffness: VoigtMatrix::zeros(),
            viscosity,
            energy_density: 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dim::Kinematics;
    use crate::material::tests::tangent_error;
    use nalgebra::Matrix3;

    fn point(rate: Voigt) -> PointKinematics {
        PointKinematics {
            kinematics: Kinematics::Solid,
            strain: Voigt::new(1e-3, 0.0, 0.0, 0.0, 0.0, 0.0),
            strain_rate: rate,
            spin: Matrix3::zeros(),
            time_step: 1.0,
            alpha: 1.0,
            increment: Matrix3::zeros(),
            end_increment: Matrix3::zeros(),
            secant: false,
        }
    }

    /// Incompressible uniaxial flow: sigma_xx - sigma_yy = sqrt(3) K (sqrt(3) rate)^m.
    #[test]
    fn uniaxial_flow_stress() {
        for m in [0.1, 0.5, 1.0] {
            let law = NortonHoff::new(2.0, m, 0.0, 1e6).unwrap();
            let rate = 0.3;
            let r = law.evaluate(
                &point(Voigt::new(rate, -rate / 2.0, -rate / 2.0, 0.0, 0.0, 0.0)),
                &[0.0],
                &mut [0.0],
            );
            let axial = r.stress[0] - r.stress[1];
            let expected = law.flow_stress(rate);
            assert!(
                (axial / expected - 1.0).abs() < 1e-9,
                "m = {m}: {axial} vs {expected}"
            );
            assert!((r.stress[1] - r.stress[2]).abs() < 1e-12 * expected);
        }
    }

    #[test]
    fn viscosity_matches_differences_of_the_stress() {
        let law = NortonHoff::new(2.0, 0.1, 0.0, 50.0).unwrap();
        for k in [
            Kinematics::PlaneStrain,
            Kinematics::Axisymmetric,
            Kinematics::Solid,
        ] {
            let mut p = point(Voigt::new(0.2, -0.1, 0.05, 0.3, 0.1, -0.2));
            p.kinematics = k;
            let e = tangent_error(&law, &p);
            assert!(e < 1e-6, "{k:?}: {e:e}");
        }
    }

    #[test]
    fn out_of_range_parameters_are_refused() {
        assert!(NortonHoff::new(0.0, 0.1, 0.0, 1.0).is_err());
        assert!(NortonHoff::new(1.0, 0.0, 0.0, 1.0).is_err());
        assert!(NortonHoff::new(1.0, 1.5, 0.0, 1.0).is_err());
        assert!(NortonHoff::new(1.0, 0.5, -1.0, 1.0).is_err());
        assert!(NortonHoff::new(1.0, 0.5, 0.0, 0.0).is_err());
        assert!(NortonHoff::new(1.0, 0.5, 0.0, f64::NAN).is_err());
    }
}

#[cfg(test)]
mod definiteness {
    use super::*;
    use crate::dim::Kinematics;
    use nalgebra::Matrix3;

    /// The viscosity is positive semi-definite for any rate (in the engineering-strain metric).
    #[test]
    fn viscosity_is_positive_definite() {
        let law = NortonHoff::new(1e6, 0.2, 0.0, 1e9).unwrap();
        let mut seed = 12345u64;
        let mut rand = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        for _ in 0..1000 {
            let scale = 10f64.powf(4.0 * rand());
            let rate = Voigt::from_fn(|_, _| scale * rand());
            let p = PointKinematics {
                kinematics: Kinematics::Solid,
                strain: Voigt::zeros(),
                strain_rate: rate,
                spin: Matrix3::zeros(),
                time_step: 0.1,
                alpha: 0.75,
                increment: Matrix3::zeros(),
                end_increment: Matrix3::zeros(),
                secant: false,
            };
            let r = law.evaluate(&p, &[0.0], &mut [0.0]);
            let v = r.viscosity;
            let sym = (v + v.transpose()) * 0.5;
            let min = sym.symmetric_eigen().eigenvalues.min();
            assert!(
                min > -1e-9 * v.amax(),
                "rate {rate:?}: min eigenvalue {min:e}"
            );
        }
    }

    /// The tube crush's point that Rust 1.95 and 1.96 compiled wrong at opt-level 3
    /// (`rust-toolchain.toml`): the release build gave the viscosity's (zz, hoop) entry the value
    /// of the outer product's (hoop, hoop) entry, -1.72e8 instead of 2.90e7 Pa s, and an
    /// indefinite tangent. The tests run at opt-level 1; `.ci/run` runs this one again with the
    /// crate at opt-level 3, as the release build computes it.
    #[test]
    fn the_tube_crush_viscosity_is_computed_as_written() {
        let law = NortonHoff::new(8e7, 0.1, 7800.0, 1e7).unwrap();
        let rate = Voigt::new(
            -0.3245445175997803,
            -0.6737641315619131,
            -0.17008311707272433,
            0.0,
            0.0,
            -0.11870385838363173,
        );
        let p = PointKinematics {
            kinematics: Kinematics::Axisymmetric,
            strain: Voigt::zeros(),
            strain_rate: rate,
            spin: Matrix3::zeros(),
            time_step: 1e-6,
            alpha: 0.75,
            increment: Matrix3::zeros(),
            end_increment: Matrix3::zeros(),
            secant: false,
        };
        let v = law.evaluate(&p, &[0.0], &mut [0.0]).viscosity;
        // By hand: 2 mu (-1/3) + bulk + 4/3 (m - 1) mu d_zz d_hoop / eq^2, written out.
        let trace = rate[0] + rate[1] + rate[2];
        let (d_zz, d_hoop) = (rate[1] - trace / 3.0, rate[2] - trace / 3.0);
        let d_rz = 0.5 * rate[5];
        let d_rr = rate[0] - trace / 3.0;
        let eq2 = 2.0 / 3.0 * (d_rr * d_rr + d_zz * d_zz + d_hoop * d_hoop + 2.0 * d_rz * d_rz)
            + DEFAULT_RATE_REGULARIZATION.powi(2);
        let mu = 8e7 * (3.0 * eq2).sqrt().powf(0.1 - 1.0);
        let expected = -2.0 / 3.0 * mu + 1e7 + 4.0 / 3.0 * (0.1 - 1.0) * mu * d_zz * d_hoop / eq2;
        for (i, j) in [(1, 2), (2, 1)] {
            assert!(
                (v[(i, j)] / expected - 1.0).abs() < 1e-12,
                "entry ({i}, {j}): {:e} against {expected:e}",
                v[(i, j)]
            );
        }
        assert!(v.symmetric_eigen().eigenvalues.min() > 0.0);
    }
}
