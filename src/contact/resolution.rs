//! Contact resolution: the laws that turn a detected pair into nodal forces and their tangent.
//!
//! A pair couples a slave node `s` with a master: a rigid obstacle moving at velocity `V`, or a
//! facet of a body with nodes `m_i` and weights `N_i` at the closest point. With the predicted
//! end positions of eq 22, `x1 = x0 + h (v0 + v1) / 2`, the gap is linear in the unknown:
//! `dg/dv1 = (h / 2) w` with the generalised normal `w = (n; -N_1 n; ...; -N_D n)`.
//!
//! * soft way: `p = zeta (-g)` for `g < 0`; the force on the nodes is `p A w` (A: the slave's
//!   tributary area), its tangent `(h/2) A (zeta w w^T - p grad^2 g)`.
//! * augmented Lagrangian: the same with `p = max(0, lambda - zeta g)` and Uzawa updates of
//!   `lambda` between solves.
//! * implicit projection: the relative normal end velocity `c = w . v1 - n . V` is held at zero
//!   by a multiplier (augmented Lagrangian on the velocity constraint, exact at convergence);
//!   positions are projected onto the master at the end of the step.
//! * explicit projection: the step is solved without contact; penetrating points are projected
//!   and their normal relative velocity removed at its end.
//!
//! Friction acts on the mean relative tangential velocity over the step,
//! `v_t = (I - n n) (v_rel(v0) + v_rel(v1)) / 2`, so that the dissipated work `-F_t . v_t h` is
//! the work along the slip of eq 22.

use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

use crate::dim::{Dim, SpatialDim};
use crate::error::{Error, Result};

/// How contact conditions are enforced (`[contact].method`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ContactMethod {
    /// Penalty on the normal displacement integrated from the velocity (eq 27).
    SoftWay,
    /// Active set with zero relative normal end velocity and end positions projected.
    #[default]
    ImplicitProjection,
    /// Uzawa updates of multipliers around soft-way solves (eq 28-30).
    AugmentedLagrangian,
    /// Status frozen in the step, projection at its end (category 1 baseline).
    ExplicitProjection,
}

impl ContactMethod {
    /// The scene-file name.
    pub fn name(self) -> &'static str {
        match self {
            ContactMethod::SoftWay => "soft_way",
            ContactMethod::ImplicitProjection => "implicit_projection",
            ContactMethod::AugmentedLagrangian => "augmented_lagrangian",
            ContactMethod::ExplicitProjection => "explicit_projection",
        }
    }
}

/// Default regularisation velocity of the friction laws [m/s].
pub const DEFAULT_REGULARIZATION: f64 = 1e-6;

/// A tangential law.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "law", rename_all = "snake_case")]
pub enum FrictionLaw {
    /// No tangential force.
    #[default]
    Frictionless,
    /// `|F_t| <= mu F_n`; stick regularised below `regularization` [m/s] of slip rate.
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
        let regularised_limit = |limit: f64, eps: f64| {
            if limit <= 0.0 {
                return zero;
            }
            let speed = slip.norm();
            if speed <= eps {
                (-slip * (limit / eps), -tangent_plane * (limit / eps))
            } else {
                let t = slip / speed;
                (
                    -t * limit,
                    -(tangent_plane - t * t.transpose()) * (limit / speed),
                )
            }
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

/// Everything `[contact]` sets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContactSettings {
    /// The method.
    pub method: ContactMethod,
    /// zeta [Pa/m]: contact pressure per unit penetration (soft way, augmented Lagrangian).
    pub penalty: f64,
    /// Whether a body's nodes are checked against its own facets.
    pub self_contact: bool,
    /// Augmented Lagrangian: Uzawa stops when every gap is within this [m]; implicit
    /// projection: the relative normal velocity tolerance is this over h.
    pub gap_tolerance: f64,
    /// The default friction law.
    pub friction: FrictionLaw,
    /// Largest number of Uzawa updates (augmented Lagrangian) or active-set passes.
    pub max_passes: usize,
}

impl Default for ContactSettings {
    fn default() -> Self {
        ContactSettings {
            method: ContactMethod::ImplicitProjection,
            penalty: 0.0,
            self_contact: false,
            gap_tolerance: 1e-9,
            friction: FrictionLaw::Frictionless,
            max_passes: 50,
        }
    }
}

impl ContactSettings {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        let needs_penalty = matches!(
            self.method,
            ContactMethod::SoftWay | ContactMethod::AugmentedLagrangian
        );
        if needs_penalty && !(self.penalty > 0.0 && self.penalty.is_finite()) {
            return Err(Error::InvalidParameter {
                name: "penalty".into(),
                found: self.penalty.to_string(),
                expected: format!("zeta > 0 [Pa/m] for method {}", self.method.name()),
            });
        }
        if !(self.gap_tolerance > 0.0 && self.gap_tolerance.is_finite()) {
            return Err(Error::InvalidParameter {
                name: "gap_tolerance".into(),
                found: self.gap_tolerance.to_string(),
                expected: "a finite value > 0 [m]".into(),
            });
        }
        self.friction.validate()
    }
}

/// The Hessian of the signed distance to a facet's plane (slave and facet nodes, `D + 1`
/// nodes), by central differences of its analytic gradient; the gradient is `n` for the slave
/// and `-N_i n` for the facet nodes (the envelope theorem on the closest point).
pub fn facet_gap_hessian<const D: usize>(
    slave: &SVector<f64, D>,
    facet: &[SVector<f64, D>; D],
) -> Vec<Vec<f64>>
where
    Dim<D>: SpatialDim<D>,
{
    let m = (D + 1) * D;
    let mut coords: Vec<f64> = slave.iter().copied().collect();
    for v in facet {
        coords.extend(v.iter().copied());
    }
    let size = facet
        .iter()
        .map(|v| (v - facet[0]).norm())
        .fold(0.0, f64::max)
        .max(1e-300);
    let eps = 1e-6 * size;
    let mut hessian = vec![vec![0.0; m]; m];
    for j in 0..m {
        let mut plus = coords.clone();
        let mut minus = coords.clone();
        plus[j] += eps;
        minus[j] -= eps;
        let (gp, gm) = (
            facet_gap_gradient::<D>(&plus),
            facet_gap_gradient::<D>(&minus),
        );
        if let (Some(gp), Some(gm)) = (gp, gm) {
            for i in 0..m {
                hessian[i][j] = (gp.1[i] - gm.1[i]) / (2.0 * eps);
            }
        }
    }
    // Symmetrise the finite-difference noise away.
    for i in 0..m {
        for j in 0..i {
            let s = 0.5 * (hessian[i][j] + hessian[j][i]);
            hessian[i][j] = s;
            hessian[j][i] = s;
        }
    }
    hessian
}

/// Gap to a facet's plane and its gradient for flat coordinates `(x_s, y_1, .., y_D)`.
pub fn facet_gap_gradient<const D: usize>(coords: &[f64]) -> Option<(f64, Vec<f64>)>
where
    Dim<D>: SpatialDim<D>,
{
    let x = SVector::<f64, D>::from_column_slice(&coords[..D]);
    let y: [SVector<f64, D>; D] = std::array::from_fn(|i| {
        SVector::<f64, D>::from_column_slice(&coords[(i + 1) * D..(i + 2) * D])
    });
    let (measure, n) = <Dim<D>>::facet_measure_normal(&y);
    if measure <= 0.0 {
        return None;
    }
    let weights = plane_weights::<D>(&x, &y, &n);
    let g = (x - y[0]).dot(&n);
    let mut grad = Vec::with_capacity((D + 1) * D);
    grad.extend(n.iter().copied());
    for w in weights {
        grad.extend((n * -w).iter().copied());
    }
    Some((g, grad))
}

/// Barycentric weights (unclamped) of the projection of `x` on the plane of facet `y`.
pub fn plane_weights<const D: usize>(
    x: &SVector<f64, D>,
    y: &[SVector<f64, D>; D],
    n: &SVector<f64, D>,
) -> [f64; D] {
    let r = x - y[0] - n * (x - y[0]).dot(n);
    let mut w = [0.0; D];
    if D == 2 {
        let t = y[1] - y[0];
        let s = r.dot(&t) / t.norm_squared();
        w[0] = 1.0 - s;
        w[1] = s;
    } else {
        let (e1, e2) = (y[1] - y[0], y[2] - y[0]);
        let (a, b, c) = (e1.dot(&e1), e1.dot(&e2), e2.dot(&e2));
        let (r1, r2) = (r.dot(&e1), r.dot(&e2));
        let det = a * c - b * b;
        let s = (c * r1 - b * r2) / det;
        let t = (a * r2 - b * r1) / det;
        w[0] = 1.0 - s - t;
        w[1] = s;
        w[2] = t;
    }
    w
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
        assert!((f - Vector2::new(-50.0, 0.0)).norm() < 1e-12);
        let (f, _) = law.force(100.0, 1.0, &Vector2::new(5e-7, 0.0), &n);
        assert!((f.x + 25.0).abs() < 1e-9, "regularised stick: {f:?}");
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

    #[test]
    fn facet_gap_gradient_and_hessian() {
        // A 2D segment from (0,0) to (2,0): gap = y, weights linear in x.
        let coords = [0.5, -0.1, 0.0, 0.0, 2.0, 0.0];
        let (g, grad) = facet_gap_gradient::<2>(&coords).unwrap();
        // The body is on the left of (0,0) -> (2,0), so n = (0, -1) and the point is outside.
        assert!((g - 0.1).abs() < 1e-15);
        // dg/dx_s = n; dg/dy_1 = -0.75 n; dg/dy_2 = -0.25 n.
        let (_, n) =
            <Dim<2>>::facet_measure_normal(&[Vector2::new(0.0, 0.0), Vector2::new(2.0, 0.0)]);
        assert!((grad[1] - n.y).abs() < 1e-15);
        assert!((grad[3] + 0.75 * n.y).abs() < 1e-12);
        assert!((grad[5] + 0.25 * n.y).abs() < 1e-12);
        // The gradient itself against central differences of the gap.
        let eps = 1e-7;
        for j in 0..6 {
            let (mut p, mut m) = (coords, coords);
            p[j] += eps;
            m[j] -= eps;
            let fd = (facet_gap_gradient::<2>(&p).unwrap().0
                - facet_gap_gradient::<2>(&m).unwrap().0)
                / (2.0 * eps);
            assert!((fd - grad[j]).abs() < 1e-7, "{j}: {fd} vs {}", grad[j]);
        }
        let h = facet_gap_hessian::<2>(
            &Vector2::new(0.5, -0.1),
            &[Vector2::new(0.0, 0.0), Vector2::new(2.0, 0.0)],
        );
        assert!(h.iter().flatten().all(|v| v.is_finite()));
        // Moving the slave along the segment does not change dg/dx_s: that row block is zero.
        assert!(h[0][0].abs() < 1e-6 && h[1][1].abs() < 1e-6);
    }
}
