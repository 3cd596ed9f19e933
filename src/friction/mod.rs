//! Friction: the tangential laws of section 3.2 of the paper (Coulomb, Tresca, viscoplastic)
//! and their stick/slip logic, evaluated per contact pair.
//!
//! Friction acts on the mean relative tangential velocity over the step,
//! `v_t = (I - n n) (v_rel(v0) + v_rel(v1)) / 2`, so that the dissipated work `-F_t . v_t h` is
//! the work along the slip of eq 22. Coulomb's threshold `mu F_n` follows the normal force by a
//! fixed point between Newton solves ([`threshold_change`]): each inner problem is a Tresca
//! problem with a symmetric tangent.

use std::collections::BTreeMap;

use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// Default regularisation velocity of the friction laws [m/s].
pub const DEFAULT_REGULARIZATION: f64 = 1e-6;

/// A tangential law.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "law", rename_all = "snake_case")]
pub enum FrictionLaw {
    /// No tangential force.
    #[default]
    Frictionless,
    /// `|F_t| <= mu F_n`: `F_t = -mu F_n v_t / sqrt(|v_t|^2 + v_reg^2)`, a stick regularised
    /// below `regularization` [m/s] of slip rate.
    Coulomb {
        /// mu [-].
        coefficient: f64,
        /// Slip-rate scale of the regularised stick [m/s].
        regularization: f64,
    },
    /// `|F_t| <= limit A` (a limit shear stress), regularised like Coulomb.
    Tresca {
        /// Limit shear stress [Pa].
        limit: f64,
        /// Slip-rate scale of the regularised stick [m/s].
        regularization: f64,
    },
    /// `F_t = -a A |v_t|^(p-1) v_t` (eq 33) with `|v_t|` replaced by
    /// `sqrt(|v_t|^2 + v_reg^2)` (eq 34).
    Viscoplastic {
        /// a [Pa (s/m)^p].
        coefficient: f64,
        /// p [-].
        exponent: f64,
        /// v_reg [m/s].
        regularization: f64,
    },
}

impl FrictionLaw {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        let bad = |name: &str, v: f64, expected: &str| {
            Err(Error::InvalidParameter {
                name: name.into(),
                found: v.to_string(),
                expected: expected.into(),
            })
        };
        let (values, reg): (&[(&str, f64)], f64) = match self {
            FrictionLaw::Frictionless => return Ok(()),
            FrictionLaw::Coulomb {
                coefficient,
                regularization,
            } => (&[("coefficient", *coefficient)], *regularization),
            FrictionLaw::Tresca {
                limit,
                regularization,
            } => (&[("limit", *limit)], *regularization),
            FrictionLaw::Viscoplastic {
                coefficient,
                exponent,
                regularization,
            } => {
                if !(*exponent >= 0.0 && exponent.is_finite()) {
                    return bad("exponent", *exponent, "a finite value >= 0");
                }
                (&[("coefficient", *coefficient)], *regularization)
            }
        };
        for (name, v) in values {
            if !(*v >= 0.0 && v.is_finite()) {
                return bad(name, *v, "a finite value >= 0");
            }
        }
        if !(reg > 0.0 && reg.is_finite()) {
            return bad("regularization", reg, "a finite value > 0 [m/s]");
        }
        Ok(())
    }

    /// The friction force on the slave for a normal force `normal_force` [N], a tributary area
    /// `area` [m^2] and a tangential relative velocity `slip` [m/s] (in the tangent plane of
    /// `normal`), with its derivative with respect to `slip` (the normal force held fixed).
    pub fn force<const D: usize>(
        &self,
        normal_force: f64,
        area: f64,
        slip: &SVector<f64, D>,
        normal: &SVector<f64, D>,
    ) -> (SVector<f64, D>, SMatrix<f64, D, D>) {
        let tangent_plane = SMatrix::<f64, D, D>::identity() - normal * normal.transpose();
        let zero = (SVector::zeros(), SMatrix::zeros());
        // F_t = -limit v_t / sqrt(|v_t|^2 + eps^2): the regularised stick of eq 34 with p = 0,
        // smooth (no kink between stick and slip), so that Newton converges.
        let regularised_limit = |limit: f64, eps: f64| {
            if limit <= 0.0 {
                return zero;
            }
            let s = (slip.norm_squared() + eps * eps).sqrt();
            let force = -slip * (limit / s);
            let d = -(tangent_plane / s - slip * slip.transpose() / (s * s * s)) * limit;
            (force, d)
        };
        match *self {
            FrictionLaw::Frictionless => zero,
            FrictionLaw::Coulomb {
                coefficient,
                regularization,
            } => regularised_limit(coefficient * normal_force.max(0.0), regularization),
            FrictionLaw::Tresca {
                limit,
                regularization,
            } => {
                if normal_force > 0.0 {
                    regularised_limit(limit * area, regularization)
                } else {
                    zero
                }
            }
            FrictionLaw::Viscoplastic {
                coefficient,
                exponent,
                regularization,
            } => {
                if normal_force <= 0.0 {
                    return zero;
                }
                let s = (slip.norm_squared() + regularization * regularization).sqrt();
                let a = coefficient * area;
                let force = -slip * (a * s.powf(exponent - 1.0));
                let d = -(tangent_plane * s.powf(exponent - 1.0)
                    + slip * slip.transpose() * ((exponent - 1.0) * s.powf(exponent - 3.0)))
                    * a;
                (force, d)
            }
        }
    }
}

/// One contact's normal force after a converged inner solve, for the threshold fixed point.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ThresholdSample<K> {
    /// The contact (slave, master).
    pub key: K,
    /// The law acting on it.
    pub law: FrictionLaw,
    /// Its normal force [N].
    pub normal_force: f64,
}

/// The next Coulomb thresholds (normal forces by contact) after a converged inner solve, or
/// `None` when they changed by at most `1e-6` of the largest normal force (the fixed point has
/// settled). Only Coulomb follows the force; the other laws need the contact status only.
pub(crate) fn threshold_change<K: Ord + Copy>(
    samples: &[ThresholdSample<K>],
    current: &BTreeMap<K, f64>,
) -> Option<BTreeMap<K, f64>> {
    let scale = samples
        .iter()
        .map(|p| p.normal_force.abs())
        .fold(0.0, f64::max);
    let mut change: f64 = 0.0;
    let mut next = BTreeMap::new();
    for p in samples {
        let f = p.normal_force.max(0.0);
        let old = current.get(&p.key).copied().unwrap_or(0.0);
        if matches!(p.law, FrictionLaw::Coulomb { .. }) {
            change = change.max((f - old).abs());
        }
        if f > 0.0 {
            next.insert(p.key, f);
        }
    }
    change = change.max(
        current
            .iter()
            .filter(|(k, _)| !next.contains_key(k))
            .map(|(_, f)| f.abs())
            .fold(0.0, f64::max),
    );
    (change > 1e-6 * scale.max(f64::MIN_POSITIVE)).then_some(next)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Vector2, Vector3};

    /// Central differences of a force function of the slip.
    fn check_friction<const D: usize>(law: FrictionLaw, slip: SVector<f64, D>, n: SVector<f64, D>) {
        let (f, d) = law.force(10.0, 0.5, &slip, &n);
        // Dissipation: F_t . v_t <= 0 and the force stays in the tangent plane.
        assert!(f.dot(&slip) <= 1e-15, "{law:?}");
        assert!(f.dot(&n).abs() < 1e-12);
        let eps = 1e-7 * slip.norm().max(1e-9);
        for j in 0..D {
            let mut e = SVector::<f64, D>::zeros();
            e[j] = eps;
            let (fp, _) = law.force(10.0, 0.5, &(slip + e), &n);
            let (fm, _) = law.force(10.0, 0.5, &(slip - e), &n);
            let fd = (fp - fm) / (2.0 * eps);
            // Only the tangential part of a variation matters (slips stay tangent).
            let tangential = d.column(j) - n * n.dot(&d.column(j));
            let fd_t = fd - n * n.dot(&fd);
            let ej_t = {
                let mut e = SVector::<f64, D>::zeros();
                e[j] = 1.0;
                e - n * n[j]
            };
            if ej_t.norm() > 0.5 {
                assert!(
                    (tangential - fd_t).norm() <= 1e-5 * (1.0 + fd_t.norm()),
                    "{law:?} column {j}: {tangential:?} vs {fd_t:?}"
                );
            }
        }
    }

    #[test]
    fn friction_tangents_match_finite_differences() {
        let laws = [
            FrictionLaw::Coulomb {
                coefficient: 0.3,
                regularization: 1e-3,
            },
            FrictionLaw::Tresca {
                limit: 2.0,
                regularization: 1e-3,
            },
            FrictionLaw::Viscoplastic {
                coefficient: 0.05,
                exponent: 0.1,
                regularization: 1e-3,
            },
            FrictionLaw::Viscoplastic {
                coefficient: 0.05,
                exponent: 1.0,
                regularization: 1e-3,
            },
        ];
        for law in laws {
            for speed in [1e-4, 0.5] {
                check_friction::<2>(law, Vector2::new(speed, 0.0), Vector2::new(0.0, 1.0));
                let n3 = Vector3::new(0.0, 0.0, 1.0);
                check_friction::<3>(law, Vector3::new(speed, -0.7 * speed, 0.0), n3);
            }
        }
    }

    #[test]
    fn coulomb_limits_and_sticks() {
        let law = FrictionLaw::Coulomb {
            coefficient: 0.5,
            regularization: 1e-6,
        };
        let n = Vector2::new(0.0, 1.0);
        let (f, _) = law.force(100.0, 1.0, &Vector2::new(2.0, 0.0), &n);
        assert!((f - Vector2::new(-50.0, 0.0)).norm() < 1e-9);
        let (f, _) = law.force(100.0, 1.0, &Vector2::new(1e-6, 0.0), &n);
        assert!(
            (f.x + 50.0 / 2f64.sqrt()).abs() < 1e-9,
            "regularised stick: {f:?}"
        );
        let (f, _) = law.force(-1.0, 1.0, &Vector2::new(2.0, 0.0), &n);
        assert_eq!(f, Vector2::zeros());
    }

    #[test]
    fn viscoplastic_closed_form() {
        // F = -a A |v|^(p-1) v, regularisation negligible.
        let law = FrictionLaw::Viscoplastic {
            coefficient: 0.05,
            exponent: 0.1,
            regularization: 1e-12,
        };
        let n = Vector2::new(0.0, 1.0);
        let (f, _) = law.force(1.0, 2.0, &Vector2::new(0.3, 0.0), &n);
        let expected = -0.05 * 2.0 * 0.3f64.powf(0.1);
        assert!((f.x - expected).abs() < 1e-12);
    }
}
