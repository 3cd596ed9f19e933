//! The hypoelastic law of the paper's section 4 (eqs 45-55): the Jaumann (corotational) rate
//! of the Cauchy stress is `E D`, integrated over a step on the configuration at its start
//! (updated Lagrangian). Over an increment with displacement gradient `G = d(du)/dx0` the
//! midpoint gradient `L = G (I + G/2)^-1` gives the strain increment `sym L` and the spin
//! increment `W = skew L`; the stress at the end of the increment is `Q sigma0 Q^T + E sym L`
//! with `Q` the incremental rotation.
//!
//! `Q` is exactly orthogonal by default (Hughes-Winget: `(I - W/2)^-1 (I + W/2)`, the Cayley
//! transform, for which a rigid rotation gives `sym L = 0` exactly), or the paper's two-term
//! series of `exp(W)` (eq 52), which is not orthogonal: a rigid spin then scales the stress by
//! `1 + O(|W|^4)` per step.

use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

use super::{condense, ConstitutiveLaw, LinearElastic, PointKinematics, PointResponse};
use crate::dim::{Voigt, VoigtMatrix};
use crate::error::Result;

/// How the incremental rotation of the stress is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RotationUpdate {
    /// Hughes-Winget: `(I - W/2)^-1 (I + W/2)`, exactly orthogonal.
    #[default]
    HughesWinget,
    /// The paper's eq 52: `I + W + W^2/2`, the exponential's series to second order.
    PaperSeries,
}

/// Corotational hypoelasticity: large rotations, small elastic strains.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Hypoelastic {
    /// Young's modulus E (Pa), > 0.
    pub youngs_modulus: f64,
    /// Poisson's ratio nu, in (-1, 0.5).
    pub poissons_ratio: f64,
    /// Mass density rho (kg/m^3), >= 0.
    pub density: f64,
    /// The incremental rotation.
    #[serde(default)]
    pub rotation: RotationUpdate,
}

impl Hypoelastic {
    /// A validated law.
    pub fn new(
        youngs_modulus: f64,
        poissons_ratio: f64,
        density: f64,
        rotation: RotationUpdate,
    ) -> Result<Self> {
        let m = Hypoelastic {
            youngs_modulus,
            poissons_ratio,
            density,
            rotation,
        };
        m.validate()?;
        Ok(m)
    }

    /// The elastic constants as the small-strain law.
    pub fn elastic(&self) -> LinearElastic {
        LinearElastic {
            youngs_modulus: self.youngs_modulus,
            poissons_ratio: self.poissons_ratio,
            density: self.density,
        }
    }

    /// Checks the ranges of the parameters.
    pub fn validate(&self) -> Result<()> {
        self.elastic().validate()
    }

    /// The incremental rotation of a spin increment `w` (skew).
    pub fn incremental_rotation(&self, w: &Matrix3<f64>) -> Matrix3<f64> {
        let i = Matrix3::identity();
        match self.rotation {
            RotationUpdate::HughesWinget => {
                // I - W/2 is invertible for every skew W (its eigenvalues are 1 - i theta/2).
                let a = (i - w * 0.5).try_inverse().unwrap_or(i);
                a * (i + w * 0.5)
            }
            RotationUpdate::PaperSeries => i + w + w * w * 0.5,
        }
    }

    /// The stress after an increment of displacement gradient `g` (w.r.t. the configuration
    /// at its start) from `sigma0`, with the (condensed) elasticity `c`.
    fn advance(&self, c: &VoigtMatrix, sigma0: &Voigt, g: &Matrix3<f64>) -> Voigt {
        let (strain, spin) = increment(g);
        let q = self.incremental_rotation(&spin);
        to_voigt(&(q * from_voigt(sigma0) * q.transpose())) + c * strain
    }
}

/// Strain increment (Voigt, engineering shears) and spin increment of an increment whose
/// displacement gradient with respect to its start configuration is `g`: the symmetric and
/// skew parts of the gradient with respect to the midpoint configuration.
pub fn increment(g: &Matrix3<f64>) -> (Voigt, Matrix3<f64>) {
    let half = Matrix3::identity() + g * 0.5;
    let l = g * half.try_inverse().unwrap_or_else(Matrix3::identity);
    let d = (l + l.transpose()) * 0.5;
    let w = (l - l.transpose()) * 0.5;
    (
        Voigt::new(
            d[(0, 0)],
            d[(1, 1)],
            d[(2, 2)],
            2.0 * d[(1, 2)],
            2.0 * d[(0, 2)],
            2.0 * d[(0, 1)],
        ),
        w,
    )
}

/// A symmetric tensor from its Voigt stress components.
pub fn from_voigt(s: &Voigt) -> Matrix3<f64> {
    Matrix3::new(s[0], s[5], s[4], s[5], s[1], s[3], s[4], s[3], s[2])
}

/// The Voigt stress components of a (symmetrised) tensor.
pub fn to_voigt(t: &Matrix3<f64>) -> Voigt {
    let s = (t + t.transpose()) * 0.5;
    Voigt::new(
        s[(0, 0)],
        s[(1, 1)],
        s[(2, 2)],
        s[(1, 2)],
        s[(0, 2)],
        s[(0, 1)],
    )
}

impl ConstitutiveLaw for Hypoelastic {
    /// The Cauchy stress at the start of the step (Voigt) per quadrature point.
    fn history_len(&self) -> usize {
        6
    }

    fn is_linear(&self) -> bool {
        false
    }

    fn updated_lagrangian(&self) -> bool {
        true
    }

    fn evaluate(
        &self,
        point: &PointKinematics,
        history: &[f64],
        new_history: &mut [f64],
    ) -> PointResponse {
        let c = condense(self.elastic().elasticity(), point.kinematics);
        let sigma0 = if history.len() >= 6 {
            Voigt::from_column_slice(&history[..6])
        } else {
            Voigt::zeros()
        };
        let stress = self.advance(&c, &sigma0, &point.increment);
        if new_history.len() >= 6 {
            let end = self.advance(&c, &sigma0, &point.end_increment);
            new_history[..6].copy_from_slice(end.as_slice());
        }
        // The stored energy of the elastic strain, 1/2 sigma : E^-1 sigma (the full 3D
        // compliance: plane stress has sigma_zz = 0, plane strain eps_zz = 0 through E).
        let compliance = self
            .elastic()
            .elasticity()
            .try_inverse()
            .unwrap_or_else(VoigtMatrix::zeros);
        PointResponse {
            stress,
            stiffness: c,
            viscosity: VoigtMatrix::zeros(),
            energy_density: 0.5 * stress.dot(&(compliance * stress)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dim::Kinematics;
    use crate::verify_record::record;
    use nalgebra::Rotation3;

    fn law(rotation: RotationUpdate) -> Hypoelastic {
        Hypoelastic::new(1e9, 0.3, 1000.0, rotation).unwrap()
    }

    fn point(g: Matrix3<f64>) -> PointKinematics {
        PointKinematics {
            kinematics: Kinematics::Solid,
            strain: Voigt::zeros(),
            strain_rate: Voigt::zeros(),
            spin: Matrix3::zeros(),
            time_step: 1e-3,
            alpha: 0.75,
            increment: g,
            end_increment: g,
            secant: false,
        }
    }

    fn invariants(s: &Voigt) -> [f64; 3] {
        let t = from_voigt(s);
        [
            t.trace(),
            0.5 * (t.trace().powi(2) - (t * t).trace()),
            t.determinant(),
        ]
    }

    /// A rigid rotation increment, whatever its size, strains nothing under Hughes-Winget.
    #[test]
    fn a_rigid_increment_does_not_strain() {
        let r = Rotation3::new(nalgebra::Vector3::new(0.3, -0.2, 0.5)).into_inner();
        let (strain, spin) = increment(&(r - Matrix3::identity()));
        assert!(strain.amax() < 1e-15, "strain {strain:?}");
        // The Cayley transform of the spin is the rotation itself.
        let q = law(RotationUpdate::HughesWinget).incremental_rotation(&spin);
        assert!((q - r).amax() < 1e-14);
    }

    /// A pre-stressed point turned through a full turn in small rigid increments keeps its
    /// stress invariants (Hughes-Winget exactly; the paper's series drifts) and, having come
    /// back, its stress.
    #[test]
    fn a_full_turn_keeps_the_stress_invariants() {
        let sigma0 = Voigt::new(3e6, -1e6, 2e6, 5e5, -4e5, 7e5);
        let steps = 200;
        let axis = nalgebra::Vector3::new(1.0, 2.0, 2.0).normalize();
        let r = Rotation3::new(axis * (2.0 * std::f64::consts::PI / steps as f64)).into_inner();
        let mut errors = Vec::new();
        for rotation in [RotationUpdate::HughesWinget, RotationUpdate::PaperSeries] {
            let m = law(rotation);
            let mut s = sigma0;
            let mut out = [0.0; 6];
            for _ in 0..steps {
                m.evaluate(&point(r - Matrix3::identity()), s.as_slice(), &mut out);
                s = Voigt::from_column_slice(&out);
            }
            let (i0, i1) = (invariants(&sigma0), invariants(&s));
            let invariant_error = (i1[0] - i0[0]).abs() / i0[0].abs();
            let back = (s - sigma0).amax() / sigma0.amax();
            errors.push((invariant_error, back));
        }
        let (hw, series) = (errors[0], errors[1]);
        eprintln!(
            "first invariant, stress after the turn: Hughes-Winget {hw:?}, series {series:?}"
        );
        record("hypoelastic-turn", "Hughes-Winget invariant", hw.0);
        record("hypoelastic-turn", "Hughes-Winget stress", hw.1);
        record("hypoelastic-turn", "series invariant", series.0);
        record("hypoelastic-turn", "series stress", series.1);
        // Round-off only: E times the strain increment round-off (1e-16) per step.
        assert!(hw.0 < 1e-10 && hw.1 < 1e-10, "Hughes-Winget {hw:?}");
        // The series is not orthogonal: Q^T Q = I + W^4/4 drifts, but stays small.
        assert!(
            series.0 > hw.0 && series.0 < 1e-3,
            "paper series {series:?}"
        );
    }

    /// The tangent is the elasticity: d sigma / d strain at a point without rotation.
    #[test]
    fn the_tangent_is_the_elasticity_for_small_increments() {
        let m = law(RotationUpdate::HughesWinget);
        let g = Matrix3::new(1e-7, 2e-8, 0.0, 0.0, -3e-8, 0.0, 0.0, 0.0, 5e-8);
        let r = m.evaluate(&point(g), &[0.0; 6], &mut [0.0; 6]);
        let (strain, _) = increment(&g);
        let expected = m.elastic().elasticity() * strain;
        assert!((r.stress - expected).amax() < 1e-9 * expected.amax());
    }
}
