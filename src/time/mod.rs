//! The space-time velocity scheme of Bajer & Bohatier (method.md section 1).
//!
//! Over a step `[t0, t0 + h]` the velocity is linear, the unknown is the end velocity `v1`, and
//! the virtual velocity is a Dirac at `tau = alpha`: the momentum balance holds at
//! `t_alpha = t0 + alpha h` with
//!
//! * `u_alpha = u0 + h (alpha - alpha^2 / 2) v0 + h (alpha^2 / 2) v1` (the exact integral of the
//!   linear velocity up to `alpha`),
//! * `v_alpha = (1 - alpha) v0 + alpha v1`,
//!
//! and the configuration is updated with `u1 = u0 + h ((1 - beta) v0 + beta v1)`.

use nalgebra::Matrix2;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// How beta is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Beta {
    /// `beta = 1 - alpha`: no numerical damping (transfer determinant 1).
    Energy,
    /// `beta = 1/2`: the exact integral of the linear velocity.
    Trapezoid,
    /// A given value in `[0, 1]`.
    Value(f64),
}

/// The two parameters of the scheme.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SpaceTimeScheme {
    /// Dirac point of the virtual velocity, in `[0, 1]`.
    pub alpha: f64,
    /// Weight of `v1` in the position update, in `[0, 1]`.
    pub beta: f64,
}

impl Default for SpaceTimeScheme {
    fn default() -> Self {
        SpaceTimeScheme {
            alpha: 0.75,
            beta: 0.25,
        }
    }
}

/// What to choose instead of parameters outside the unconditionally stable window.
pub const WINDOW_ADVICE: &str =
    "use alpha >= sqrt(2)/2 ~ 0.7071 with beta in [1 - alpha, alpha^2 - alpha + 1/2]";

impl SpaceTimeScheme {
    /// A scheme with validated parameters.
    pub fn new(alpha: f64, beta: Beta) -> Result<Self> {
        let bad = |name: &str, v: f64| Error::InvalidParameter {
            name: name.into(),
            found: v.to_string(),
            expected: "a number in [0, 1]".into(),
        };
        if !(0.0..=1.0).contains(&alpha) {
            return Err(bad("alpha", alpha));
        }
        let beta = match beta {
            Beta::Energy => 1.0 - alpha,
            Beta::Trapezoid => 0.5,
            Beta::Value(b) if (0.0..=1.0).contains(&b) => b,
            Beta::Value(b) => return Err(bad("beta", b)),
        };
        Ok(SpaceTimeScheme { alpha, beta })
    }

    /// `(c0, c1)` with `u_alpha = u0 + h (c0 v0 + c1 v1)`.
    pub fn displacement_weights(&self) -> (f64, f64) {
        let a = self.alpha;
        (a - 0.5 * a * a, 0.5 * a * a)
    }

    /// `(c0, c1)` with `v_alpha = c0 v0 + c1 v1`.
    pub fn velocity_weights(&self) -> (f64, f64) {
        (1.0 - self.alpha, self.alpha)
    }

    /// `(c0, c1)` with `u1 = u0 + h (c0 v0 + c1 v1)`.
    pub fn update_weights(&self) -> (f64, f64) {
        (1.0 - self.beta, self.beta)
    }

    /// Whether `(alpha, beta)` lies in the unconditional stability window
    /// `1 - alpha <= beta <= alpha^2 - alpha + 1/2` (which needs `alpha >= sqrt(2)/2`).
    pub fn is_unconditionally_stable(&self) -> bool {
        let (a, b) = (self.alpha, self.beta);
        let tol = 1e-12;
        b >= 1.0 - a - tol && b <= a * a - a + 0.5 + tol
    }

    /// `alpha = A, beta = B` for messages, each to 12 significant digits (beta = 1 - alpha
    /// reads 0.297, not 0.29700000000000004).
    pub fn parameters(&self) -> String {
        let short = |x: f64| {
            let s = format!("{:.12}", x);
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        };
        format!("alpha = {}, beta = {}", short(self.alpha), short(self.beta))
    }

    /// A warning for parameters outside the window, `None` inside it.
    pub fn stability_warning(&self) -> Option<String> {
        if self.is_unconditionally_stable() {
            return None;
        }
        let limit = if self.alpha < std::f64::consts::FRAC_1_SQRT_2 && self.beta == 1.0 - self.alpha
        {
            format!(
                "; stable only while k h^2 / m <= {:.4}",
                4.0 / (1.0 - 2.0 * self.alpha * self.alpha)
            )
        } else {
            String::new()
        };
        Some(format!(
            "{} is outside the unconditional stability window \
             1 - alpha <= beta <= alpha^2 - alpha + 1/2 (alpha >= sqrt(2)/2){limit}",
            self.parameters()
        ))
    }

    /// One step of the undamped oscillator `m u'' + k u = 0`, through the same weights the
    /// finite element step uses.
    pub fn step_oscillator(&self, m: f64, k: f64, h: f64, u0: f64, v0: f64) -> (f64, f64) {
        let (d0, d1) = self.displacement_weights();
        // m (v1 - v0) / h + k (u0 + h d0 v0 + h d1 v1) = 0
        let v1 = (m / h * v0 - k * (u0 + h * d0 * v0)) / (m / h + k * h * d1);
        let (b0, b1) = self.update_weights();
        (u0 + h * (b0 * v0 + b1 * v1), v1)
    }

    /// The transfer matrix of `(u, h v)` over one step for `kappa = k h^2 / m`.
    pub fn transfer_matrix(&self, kappa: f64) -> Matrix2<f64> {
        // Scale m = 1, h = 1, k = kappa: then (u, h v) = (u, v).
        let (u_a, w_a) = self.step_oscillator(1.0, kappa, 1.0, 1.0, 0.0);
        let (u_b, w_b) = self.step_oscillator(1.0, kappa, 1.0, 0.0, 1.0);
        Matrix2::new(u_a, u_b, w_a, w_b)
    }

    /// Spectral radius of the transfer matrix at `kappa`.
    pub fn spectral_radius(&self, kappa: f64) -> f64 {
        let t = self.transfer_matrix(kappa);
        let (tr, det) = (t.trace(), t.determinant());
        let disc = tr * tr / 4.0 - det;
        if disc >= 0.0 {
            let s = disc.sqrt();
            (tr / 2.0 + s).abs().max((tr / 2.0 - s).abs())
        } else {
            det.abs().sqrt()
        }
    }

    /// The spectral radius as `kappa -> infinity` for `beta = 1 - alpha` (method.md section 1):
    /// 1 for `alpha >= sqrt(2)/2`, else `(1 - alpha^2 + sqrt(1 - 2 alpha^2)) / alpha^2`.
    pub fn stiff_limit_radius(alpha: f64) -> f64 {
        let a2 = alpha * alpha;
        if 2.0 * a2 >= 1.0 {
            1.0
        } else {
            (1.0 - a2 + (1.0 - 2.0 * a2).sqrt()) / a2
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::verify_record::record;

    fn kappas() -> impl Iterator<Item = f64> {
        (-3..=8).map(|e| 10f64.powi(e))
    }

    #[test]
    fn energy_beta_gives_unit_determinant() {
        for alpha in [0.5, 0.6, std::f64::consts::FRAC_1_SQRT_2, 0.75, 0.9, 1.0] {
            let s = SpaceTimeScheme::new(alpha, Beta::Energy).unwrap();
            for kappa in kappas() {
                let det = s.transfer_matrix(kappa).determinant();
                record("transfer-det", "det - 1", (det - 1.0).abs());
                assert!(
                    (det - 1.0).abs() < 1e-9,
                    "alpha {alpha} kappa {kappa}: {det}"
                );
            }
        }
    }

    #[test]
    fn unconditionally_stable_above_sqrt2_over_2() {
        for alpha in [std::f64::consts::FRAC_1_SQRT_2, 0.75, 0.85, 1.0] {
            let s = SpaceTimeScheme::new(alpha, Beta::Energy).unwrap();
            assert!(s.is_unconditionally_stable());
            for kappa in kappas() {
                let r = s.spectral_radius(kappa);
                record("transfer-stable", "rho - 1", r - 1.0);
                assert!(r <= 1.0 + 1e-7, "alpha {alpha} kappa {kappa}: {r}");
            }
        }
    }

    #[test]
    fn below_sqrt2_over_2_the_stiff_limit_matches_method_md() {
        for alpha in [0.5, 0.6, 0.7] {
            let s = SpaceTimeScheme::new(alpha, Beta::Energy).unwrap();
            assert!(!s.is_unconditionally_stable());
            let limit = SpaceTimeScheme::stiff_limit_radius(alpha);
            assert!(limit > 1.0);
            let r = s.spectral_radius(1e12);
            record("transfer-stiff-limit", "limit", (r - limit).abs() / limit);
            assert!(
                (r - limit).abs() < 1e-4 * limit,
                "alpha {alpha}: {r} vs {limit}"
            );
            // Stable up to kappa = 4 / (1 - 2 alpha^2), unstable beyond.
            let edge = 4.0 / (1.0 - 2.0 * alpha * alpha);
            let (below, above) = (
                s.spectral_radius(0.99 * edge),
                s.spectral_radius(1.01 * edge),
            );
            record("transfer-stiff-limit", "rho - 1 below", below - 1.0);
            record("transfer-stiff-limit", "rho - 1 above", above - 1.0);
            assert!(s.spectral_radius(0.99 * edge) <= 1.0 + 1e-9);
            assert!(s.spectral_radius(1.01 * edge) > 1.0);
        }
    }

    #[test]
    fn window_interior_damps_stiff_modes() {
        let s = SpaceTimeScheme {
            alpha: 0.75,
            beta: 0.281,
        };
        assert!(s.is_unconditionally_stable());
        let r = s.spectral_radius(1e10);
        assert!((r - 0.943).abs() < 2e-3, "{r}");
    }

    #[test]
    fn out_of_range_parameters_are_rejected() {
        assert!(SpaceTimeScheme::new(1.1, Beta::Energy).is_err());
        assert!(SpaceTimeScheme::new(0.7, Beta::Value(-0.1)).is_err());
    }
}
