//! Friction: the tangential laws of section 3.2 of the paper (Coulomb, Tresca, viscoplastic)
//! and their stick/slip logic, evaluated per contact pair.
//!
//! **Penalty methods (soft way, augmented Lagrangian): a return map.** Coulomb and Tresca are
//! a tangential penalty with an elastic-slip anchor (Wriggers 2006, Laursen 2002; the notes'
//! section 3), the crate-internal `return_map`. Each contact carries its elastic slip `s_e` in the state (reset
//! when the contact opens, re-projected onto the current tangent plane). With the slip
//! increment `h w_t`, `w_t = (I - n n) w1` the relative tangential *end* velocity (not the
//! trapezoid mean: with the mean, stick would force `w_t1 = -w_t0`), the trial force is
//!
//! ```text
//! F_tr = -eps_t A (s_e + h w_t)
//! stick (|F_tr| <= limit): F_t = F_tr,              s_e <- s_e + h w_t
//! slip  (|F_tr| >  limit): F_t = limit F_tr/|F_tr|, s_e <- -F_t / (eps_t A)
//! ```
//!
//! with `limit = mu F_n` (Coulomb, the *current* normal force of the iterate: no lagged fixed
//! point) or `limit = tau_max A` (Tresca, while the contact is closed). The tangential penalty
//! is the normal one, `eps_t = zeta` (Pa/m): the elastic slip in stick is at most `mu` times the
//! penetration, and it does not drift (an anchor, not a damper). Where `zeta A h` exceeds four
//! times the slave's diagonal of the iteration matrix, the spring is that instead (the contact
//! methods' `PENALTY_TANGENT_CAP`: a stiffer spring made Newton cycle on stick-slip switches),
//! and the elastic slip at most `F_t h / (4 diagonal)`, below `F_t h^2 / (4 m)`. The consistent tangent
//! `d(-F_t)/dw1` is `eps_t A h (I - n n)` in stick and `(limit eps_t A h/|F_tr|)(I - n n - t t)`
//! in slip; the slip's rank-one coupling of the threshold to the gap, `mu t dF_n/dv1`, is not
//! symmetric: it is returned apart, kept out of the Cholesky and solved by GMRES on the
//! symmetric factor (`simulation::linear_solve`), and the tangent is checked whole.
//!
//! In slip the consistent tangent has no stiffness along the slip: Newton moves a slipping
//! point along it as far as the body's own stiffness allows. Where the point should stop, that
//! step carries it through the stick disk into slip the other way, and the next step back
//! (3D: a block squeezed by two jaws had 11 floor nodes reverse in one Newton step; each step
//! then backtracked to a tenth of its length, and Newton stalled at a relative residual of
//! 5e-2). A slip whose direction turned by more than 60 degrees since Newton's previous
//! iterate therefore takes the secant tangent `(limit eps_t A h/|F_tr|)(I - n n)` instead:
//! the quadratic that touches the law's energy from above at the iterate (the iteratively
//! reweighted step of a Huber function), which keeps the stiffness along the slip. Slips that
//! keep their direction keep the consistent tangent and Newton's quadratic convergence.
//!
//! **Implicit projection** has the same return map with Coulomb's threshold taken from the
//! previous pass's normal force (its normal force is a multiplier, exact only when the active
//! set has converged: the crate-internal `ThresholdIteration` is that fixed point) and a
//! tangential stiffness of the slave's diagonal per step (no penalty to borrow).
//! Viscoplastic friction is the smooth law `F_t = -a A (|v_t|^2 + v_reg^2)^((p-1)/2) v_t` on
//! the mean relative tangential velocity under every method ([`FrictionLaw::force`]).
//!
//! Dissipation is booked in every case as `-F_t . (h/2)(I - n n)(w0 + w1)`, the work along the
//! slip of eq 22 (the displacement of the configuration update): the energy account stays
//! closed, the elastic slip's energy included (returned when a stuck contact unloads).

use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

mod threshold;
pub(crate) use threshold::{ThresholdIteration, ThresholdSample};

/// Default regularisation velocity of the friction laws (m/s).
pub const DEFAULT_REGULARIZATION: f64 = 1e-6;

/// A tangential law.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "law", rename_all = "snake_case")]
pub enum FrictionLaw {
    /// No tangential force.
    #[default]
    Frictionless,
    /// `|F_t| <= mu F_n`: the return map under every method that carries friction (module
    /// docs). [`FrictionLaw::force`] is its smooth form `F_t = -mu F_n v_t / sqrt(|v_t|^2 +
    /// v_reg^2)`, which no method uses any more.
    Coulomb {
        /// mu (dimensionless).
        coefficient: f64,
        /// Slip-rate scale of the smooth form (m/s; accepted, unused by the methods).
        regularization: f64,
    },
    /// `|F_t| <= limit A` (a limit shear stress) on closed contacts: the return map, like
    /// Coulomb.
    Tresca {
        /// Limit shear stress (Pa).
        limit: f64,
        /// Slip-rate scale of the smooth form (m/s; accepted, unused by the methods).
        regularization: f64,
    },
    /// `F_t = -a A |v_t|^(p-1) v_t` (eq 33) with `|v_t|` replaced by
    /// `sqrt(|v_t|^2 + v_reg^2)` (eq 34).
    Viscoplastic {
        /// a (Pa (s/m)^p).
        coefficient: f64,
        /// p (dimensionless).
        exponent: f64,
        /// v_reg (m/s).
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

    /// The friction force on the slave for a normal force `normal_force` (N), a tributary area
    /// `area` (m^2) and a tangential relative velocity `slip` (m/s) (in the tangent plane of
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

/// The outcome of the return map of one contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ReturnMap<const D: usize> {
    /// Friction force on the slave (N; in the tangent plane).
    pub force: SVector<f64, D>,
    /// The elastic slip after the step (m) (`-force / (eps_t A)`).
    pub anchor: SVector<f64, D>,
    /// Whether the contact slips.
    pub slipping: bool,
    /// `d(-force)/dw1`, w1 the relative end velocity, the limit held fixed (N s/m; symmetric).
    pub tangent: SMatrix<f64, D, D>,
    /// `d force / d limit` (the slip direction in slip, zero in stick) (dimensionless).
    pub d_limit: SVector<f64, D>,
}

impl FrictionLaw {
    /// Whether the law is a return map under penalty methods (Coulomb, Tresca).
    pub fn has_return_map(&self) -> bool {
        matches!(
            self,
            FrictionLaw::Coulomb { .. } | FrictionLaw::Tresca { .. }
        )
    }

    /// Whether the law's slip limit follows the normal force (Coulomb); the others need only
    /// whether the contact is closed.
    pub fn follows_normal_force(&self) -> bool {
        matches!(self, FrictionLaw::Coulomb { .. })
    }

    /// The return map's slip limit (N) for a normal force `normal_force` (N) and a contact area
    /// `area` (m^2; zero for an open contact or a law without a return map).
    pub fn slip_limit(&self, normal_force: f64, area: f64) -> f64 {
        if normal_force <= 0.0 {
            return 0.0;
        }
        match *self {
            FrictionLaw::Coulomb { coefficient, .. } => coefficient * normal_force,
            FrictionLaw::Tresca { limit, .. } => limit * area,
            _ => 0.0,
        }
    }
}

/// The cosine below which a slipping contact's friction force counts as turned since Newton's
/// previous iterate (60 degrees): its tangent is then the secant one (module docs).
const TURNED_SLIP_COS: f64 = 0.5;

/// The return map of one closed contact (module docs): slip limit `limit` (N), tangential
/// stiffness `stiffness = eps_t A` (N/m), the previous elastic slip `anchor` (m) (re-projected
/// here onto the tangent plane of `normal`), the relative end velocity `w1` (m/s) and the step
/// `h` (s). `|F_tr| <= limit` (F_tr = 0 included) is stick. `previous_direction` is the
/// direction of the contact's friction force at Newton's previous iterate, if it had one: a
/// slip that turned by more than 60 degrees from it takes the secant tangent.
pub(crate) fn return_map<const D: usize>(
    limit: f64,
    stiffness: f64,
    anchor: &SVector<f64, D>,
    w1: &SVector<f64, D>,
    normal: &SVector<f64, D>,
    h: f64,
    previous_direction: Option<&SVector<f64, D>>,
) -> ReturnMap<D> {
    let plane = SMatrix::<f64, D, D>::identity() - normal * normal.transpose();
    let trial_slip = plane * (anchor + w1 * h);
    let trial = -trial_slip * stiffness;
    let size = trial.norm();
    if size <= limit || stiffness <= 0.0 {
        return ReturnMap {
            force: trial,
            anchor: trial_slip,
            slipping: false,
            tangent: plane * (stiffness * h),
            d_limit: SVector::zeros(),
        };
    }
    let t = trial / size;
    let force = t * limit;
    let turned = previous_direction.is_some_and(|d| d.dot(&t) < TURNED_SLIP_COS);
    // The secant `F = -limit x/|x|` (x the trial slip) keeps the stiffness along the slip.
    let secant = plane * (limit * stiffness * h / size);
    ReturnMap {
        force,
        anchor: -force / stiffness,
        slipping: true,
        tangent: if turned {
            secant
        } else {
            secant - t * t.transpose() * (limit * stiffness * h / size)
        },
        d_limit: t,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::verify_record::record;
    use nalgebra::{Matrix3, Vector2, Vector3};

    /// Central differences of a force function of the slip.
    fn check_friction<const D: usize>(law: FrictionLaw, slip: SVector<f64, D>, n: SVector<f64, D>) {
        let (f, d) = law.force(10.0, 0.5, &slip, &n);
        // Dissipation: F_t . v_t <= 0 and the force stays in the tangent plane.
        record("friction-tangent", "F.v", f.dot(&slip));
        record("friction-tangent", "F.n", f.dot(&n).abs());
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
                let error = (tangential - fd_t).norm() / (1.0 + fd_t.norm());
                record("friction-tangent", "tangent", error);
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
        record(
            "friction-closed-forms",
            "slip",
            (f - Vector2::new(-50.0, 0.0)).norm(),
        );
        assert!((f - Vector2::new(-50.0, 0.0)).norm() < 1e-9);
        let (f, _) = law.force(100.0, 1.0, &Vector2::new(1e-6, 0.0), &n);
        record(
            "friction-closed-forms",
            "stick",
            (f.x + 50.0 / 2f64.sqrt()).abs(),
        );
        assert!(
            (f.x + 50.0 / 2f64.sqrt()).abs() < 1e-9,
            "regularised stick: {f:?}"
        );
        let (f, _) = law.force(-1.0, 1.0, &Vector2::new(2.0, 0.0), &n);
        record("friction-closed-forms", "tension", f.norm());
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
        record(
            "friction-closed-forms",
            "viscoplastic",
            (f.x - expected).abs(),
        );
        assert!((f.x - expected).abs() < 1e-12);
    }
    /// The return map's tangent against central differences, in stick and in slip.
    fn check_return_map<const D: usize>(anchor: SVector<f64, D>, w1: SVector<f64, D>, slips: bool) {
        let mut n = SVector::<f64, D>::zeros();
        n[D - 1] = 0.8;
        n[0] = 0.6;
        let (limit, k, h) = (3.0, 1e4, 1e-3);
        let r = return_map(limit, k, &anchor, &w1, &n, h, None);
        assert_eq!(r.slipping, slips, "{anchor:?} {w1:?}");
        assert!(r.force.norm() <= limit * (1.0 + 1e-12));
        assert!(r.force.dot(&n).abs() < 1e-12);
        assert!((r.anchor * -k - r.force).norm() < 1e-12);
        let eps = 1e-6;
        for j in 0..D {
            let mut e = SVector::<f64, D>::zeros();
            e[j] = eps;
            let fp = return_map(limit, k, &anchor, &(w1 + e), &n, h, None).force;
            let fm = return_map(limit, k, &anchor, &(w1 - e), &n, h, None).force;
            let fd = -(fp - fm) / (2.0 * eps);
            assert!(
                (r.tangent.column(j) - fd).norm() <= 1e-6 * k * h,
                "column {j}: {:?} vs {fd:?}",
                r.tangent.column(j)
            );
        }
        assert!((r.tangent - r.tangent.transpose()).amax() < 1e-12 * k * h);
        // The derivative with respect to the limit.
        let dl = 1e-6;
        let fp = return_map(limit + dl, k, &anchor, &w1, &n, h, None).force;
        let fm = return_map(limit - dl, k, &anchor, &w1, &n, h, None).force;
        assert!(((fp - fm) / (2.0 * dl) - r.d_limit).norm() < 1e-6);
    }

    #[test]
    fn return_map_tangent_matches_finite_differences() {
        use nalgebra::Vector3;
        // Stick: a small elastic slip; slip: an anchor beyond the cone.
        check_return_map::<2>(Vector2::new(1e-4, 0.0), Vector2::new(0.05, 0.1), false);
        check_return_map::<2>(Vector2::new(1e-3, 0.0), Vector2::new(0.05, 0.1), true);
        check_return_map::<2>(Vector2::new(0.0, 0.0), Vector2::new(-2.0, 0.1), true);
        let a = Vector3::new(-8e-5, 1e-4, 0.0);
        check_return_map::<3>(a, Vector3::new(0.05, -0.1, 0.1), false);
        check_return_map::<3>(a * 10.0, Vector3::new(0.05, -0.1, 0.1), true);
        // F_tr = 0 is stick.
        let r = return_map(
            0.0,
            1.0,
            &Vector2::zeros(),
            &Vector2::zeros(),
            &Vector2::y(),
            1.0,
            None,
        );
        assert!(!r.slipping && r.force == Vector2::zeros());
    }

    /// A slip that turned since Newton's previous iterate takes the secant tangent, which maps
    /// the trial slip to the force; one that kept its direction keeps the consistent tangent.
    #[test]
    fn a_turned_slip_takes_the_secant_tangent() {
        let n = Vector3::new(0.0, 0.0, 1.0);
        let (limit, k, h) = (3.0, 1e4, 1e-3);
        let (anchor, w1) = (Vector3::new(1e-3, 0.0, 0.0), Vector3::new(0.5, -0.2, 0.3));
        let consistent = return_map(limit, k, &anchor, &w1, &n, h, None);
        assert!(consistent.slipping);
        let t = consistent.force.normalize();
        let kept = return_map(limit, k, &anchor, &w1, &n, h, Some(&t));
        assert_eq!(kept.tangent, consistent.tangent);
        let turned = return_map(limit, k, &anchor, &w1, &n, h, Some(&-t));
        assert_eq!(turned.force, consistent.force);
        let slip = (Matrix3::identity() - n * n.transpose()) * (anchor / h + w1);
        assert!((turned.tangent * slip + turned.force).norm() < 1e-12 * limit);
        assert!((turned.tangent - turned.tangent.transpose()).amax() == 0.0);
    }
}
