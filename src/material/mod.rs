//! Constitutive laws.
//!
//! Laws work on 3D Voigt quantities ([`crate::dim::Voigt`]); 2D kinematics embed their strain
//! in 3D ([`crate::dim::SpatialDim::strain_operator`]) and plane stress condenses the tangent.
//! The enum is the serialisable description of a body's law; rate-dependent laws with history
//! (hypoelastic, Norton-Hoff) join it as variants whose state lives per quadrature point.

use serde::{Deserialize, Serialize};

use crate::dim::{Kinematics, VoigtMatrix};
use crate::error::{Error, Result};

/// Isotropic linear elasticity (small strain).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LinearElastic {
    /// Young's modulus E [Pa], > 0.
    pub youngs_modulus: f64,
    /// Poisson's ratio nu, in (-1, 0.5).
    pub poissons_ratio: f64,
    /// Mass density rho [kg/m^3], >= 0.
    pub density: f64,
}

impl LinearElastic {
    /// A validated law.
    pub fn new(youngs_modulus: f64, poissons_ratio: f64, density: f64) -> Result<Self> {
        let m = LinearElastic {
            youngs_modulus,
            poissons_ratio,
            density,
        };
        m.validate()?;
        Ok(m)
    }

    /// Checks the ranges of the parameters.
    pub fn validate(&self) -> Result<()> {
        let bad = |name: &str, found: f64, expected: &str| {
            Err(Error::InvalidParameter {
                name: name.into(),
                found: found.to_string(),
                expected: expected.into(),
            })
        };
        if !(self.youngs_modulus > 0.0 && self.youngs_modulus.is_finite()) {
            return bad(
                "youngs_modulus",
                self.youngs_modulus,
                "a finite value > 0 [Pa]",
            );
        }
        if !(self.poissons_ratio > -1.0 && self.poissons_ratio < 0.5) {
            return bad(
                "poissons_ratio",
                self.poissons_ratio,
                "a value in (-1, 0.5)",
            );
        }
        if !(self.density >= 0.0 && self.density.is_finite()) {
            return bad("density", self.density, "a finite value >= 0 [kg/m^3]");
        }
        Ok(())
    }

    /// Lame's first parameter lambda [Pa].
    pub fn lambda(&self) -> f64 {
        let (e, nu) = (self.youngs_modulus, self.poissons_ratio);
        e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    }

    /// Shear modulus mu [Pa].
    pub fn shear_modulus(&self) -> f64 {
        self.youngs_modulus / (2.0 * (1.0 + self.poissons_ratio))
    }

    /// The 3D Voigt elasticity matrix.
    pub fn elasticity(&self) -> VoigtMatrix {
        let (l, mu) = (self.lambda(), self.shear_modulus());
        let mut c = VoigtMatrix::zeros();
        for i in 0..3 {
            for j in 0..3 {
                c[(i, j)] = l;
            }
            c[(i, i)] = l + 2.0 * mu;
            c[(i + 3, i + 3)] = mu;
        }
        c
    }

    /// Speed of the longitudinal (pressure) wave [m/s] in these kinematics.
    pub fn wave_speed(&self, kinematics: Kinematics) -> f64 {
        if self.density <= 0.0 {
            return f64::INFINITY;
        }
        let c = condense(self.elasticity(), kinematics);
        (c[(0, 0)] / self.density).sqrt()
    }
}

/// A body's constitutive law.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case")]
#[non_exhaustive]
pub enum Material {
    /// Isotropic linear elasticity.
    LinearElastic(LinearElastic),
}

impl Material {
    /// Mass density [kg/m^3].
    pub fn density(&self) -> f64 {
        match self {
            Material::LinearElastic(m) => m.density,
        }
    }

    /// The constant Voigt tangent of a linear law, condensed for the kinematics; `None` for
    /// a nonlinear law (assembled every Newton iteration instead).
    pub fn linear_tangent(&self, kinematics: Kinematics) -> Option<VoigtMatrix> {
        match self {
            Material::LinearElastic(m) => Some(condense(m.elasticity(), kinematics)),
        }
    }

    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        match self {
            Material::LinearElastic(m) => m.validate(),
        }
    }

    /// Longitudinal wave speed [m/s], for step-size estimates.
    pub fn wave_speed(&self, kinematics: Kinematics) -> f64 {
        match self {
            Material::LinearElastic(m) => m.wave_speed(kinematics),
        }
    }
}

/// Plane stress: eliminates the zz component so that `sigma_zz = 0` (static condensation);
/// other kinematics keep the 3D tangent.
pub fn condense(c: VoigtMatrix, kinematics: Kinematics) -> VoigtMatrix {
    if kinematics != Kinematics::PlaneStress {
        return c;
    }
    let mut out = c;
    for i in 0..6 {
        for j in 0..6 {
            out[(i, j)] = c[(i, j)] - c[(i, 2)] * c[(2, j)] / c[(2, 2)];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_stress_tangent_is_the_textbook_one() {
        let m = LinearElastic::new(210e9, 0.3, 7800.0).unwrap();
        let c = condense(m.elasticity(), Kinematics::PlaneStress);
        let f = 210e9 / (1.0 - 0.09);
        assert!((c[(0, 0)] - f).abs() < 1e-6 * f);
        assert!((c[(0, 1)] - 0.3 * f).abs() < 1e-6 * f);
        assert!((c[(5, 5)] - f * 0.35).abs() < 1e-6 * f);
        assert!(c.row(2).iter().all(|v| v.abs() < 1e-3));
    }

    #[test]
    fn out_of_range_parameters_are_rejected() {
        assert!(LinearElastic::new(0.0, 0.3, 1.0).is_err());
        assert!(LinearElastic::new(1.0, 0.5, 1.0).is_err());
        assert!(LinearElastic::new(1.0, -1.0, 1.0).is_err());
        assert!(LinearElastic::new(1.0, 0.2, -1.0).is_err());
    }

    #[test]
    fn bar_wave_speed_with_zero_poisson_ratio() {
        let m = LinearElastic::new(4.0, 0.0, 1.0).unwrap();
        for k in [
            Kinematics::PlaneStrain,
            Kinematics::PlaneStress,
            Kinematics::Solid,
        ] {
            assert!((m.wave_speed(k) - 2.0).abs() < 1e-14);
        }
    }
}
