//! Rayleigh damping `C = a M + b K` per body, in 2D and 3D: a free body's velocity decays as
//! exp(-a t); an oscillator's amplitude decays at (a + b omega^2)/2 with the damped period; the
//! energy account books what the damping removes.

use crate::common;

use common::verify::record;
use common::{block, energy_error, vec_d};
use softway::dim::{Dim, SpatialDim};
use softway::prelude::*;

both_dims!(
    mass_damping_decays_a_free_body_exponentially,
    an_oscillator_decays_at_the_rayleigh_rate
);

/// A free block moving at 1 m/s with mass-proportional damping a = 5 /s: every node's
/// velocity follows the scheme's factor (1 - a h (1 - alpha)) / (1 + a h alpha) per step
/// exactly, within 0.2 % of exp(-a t) at t = 0.2 s; the lost kinetic energy is booked.
fn mass_damping_decays_a_free_body_exponentially<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let (a, h, alpha) = (5.0, 1e-3, 0.75);
    let mut sim = Simulation::<D>::builder()
        .time_step(h)
        .body(
            Body::new(
                "block",
                block::<D>([0.2, 0.1, 0.1], [2, 1, 1], false),
                Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap()),
            )
            .with_velocity(vec_d([1.0, 0.0, 0.0]))
            .with_damping(a, 0.0),
        )
        .build()
        .unwrap();
    for _ in 0..200 {
        sim.step().unwrap();
    }
    let factor: f64 = (1.0 - a * h * (1.0 - alpha)) / (1.0 + a * h * alpha);
    let discrete = factor.powi(200);
    let exact = (-a * 0.2f64).exp();
    let off = sim
        .state()
        .velocity
        .chunks(D)
        .map(|v| (v[0] - discrete).abs());
    record("damping-mass", "factor (m/s)", off.fold(0.0, f64::max));
    for (n, v) in sim.state().velocity.chunks(D).enumerate() {
        assert!(
            (v[0] - discrete).abs() < 1e-12,
            "node {n}: {} against {discrete}",
            v[0]
        );
        assert!(v[1..].iter().all(|c| c.abs() < 1e-12));
    }
    record("damping-mass", "exp(-at)", (discrete - exact) / exact);
    assert!(
        (discrete - exact).abs() < 2e-3 * exact,
        "{discrete} vs {exact}"
    );
    let e = sim.energies();
    record("damping-mass", "energy", energy_error(&sim));
    assert!(e.dissipated > 0.0);
    assert!(energy_error(&sim) < 1e-9, "{}", energy_error(&sim));
}

/// A unit square (cube) of one element, clamped on x = 0, its x = 1 face free along x only,
/// given 0.1 m/s along x: one mode. Its undamped period T gives omega; with damping (a, b) the
/// peaks of the free face's displacement decay at (a + b omega^2) / 2 and come every
/// T / sqrt(1 - zeta^2), zeta = (a / omega + b omega) / 2.
fn an_oscillator_decays_at_the_rayleigh_rate<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let undamped = oscillate::<D>(0.0, 0.0);
    let (t_undamped, _) = period_and_decay(&undamped);
    let omega = 2.0 * std::f64::consts::PI / t_undamped;
    for (a, b) in [(2.0, 0.0), (0.0, 2e-3), (1.0, 1e-3)] {
        let history = oscillate::<D>(a, b);
        let (period, rate) = period_and_decay(&history);
        let expected = 0.5 * (a + b * omega * omega);
        let zeta = 0.5 * (a / omega + b * omega);
        let expected_period = t_undamped / (1.0 - zeta * zeta).sqrt();
        eprintln!(
            "{D}D a = {a}, b = {b}: decay {rate:.5} /s against {expected:.5}, period {period:.6} \
             s against {expected_period:.6} (zeta {zeta:.4}, omega {omega:.3} rad/s)"
        );
        record("damping-oscillator", "decay", (rate - expected) / expected);
        record(
            "damping-oscillator",
            "period",
            (period - expected_period) / expected_period,
        );
        assert!(
            (rate - expected).abs() < 5e-3 * expected,
            "{rate} vs {expected}"
        );
        assert!((period - expected_period).abs() < 1e-3 * expected_period);
    }
}

/// The free face's displacement along x every step (with the step's time).
fn oscillate<const D: usize>(a: f64, b: f64) -> Vec<(f64, f64)>
where
    Dim<D>: SpatialDim<D>,
{
    let free = [None, Some(0.0), Some(0.0)];
    let mut sim = Simulation::<D>::builder()
        .time_step(2e-4)
        .body(
            Body::new(
                "cell",
                block::<D>([1.0, 1.0, 1.0], [1, 1, 1], false),
                Material::LinearElastic(LinearElastic::new(1e3, 0.0, 1.0).unwrap()),
            )
            .with_velocity(vec_d([0.1, 0.0, 0.0]))
            .with_constraint_in_box(
                vec_d([-0.1, -0.1, -0.1]),
                vec_d([0.1, 1.1, 1.1]),
                [Some(0.0); D],
            )
            .with_constraint_in_box(
                vec_d([0.9, -0.1, -0.1]),
                vec_d([1.1, 1.1, 1.1]),
                std::array::from_fn(|k| free[k]),
            )
            .with_damping(a, b),
        )
        .build()
        .unwrap();
    let node = sim
        .reference_positions()
        .iter()
        .position(|x| x[0] > 0.5)
        .unwrap();
    let mut out = Vec::new();
    while sim.state().time < 1.0 {
        sim.step().unwrap();
        out.push((sim.state().time, sim.state().displacement[node * D]));
    }
    out
}

/// The mean time between successive maxima and the decay rate of the first to the last
/// maximum (parabola through each peak's three samples).
fn period_and_decay(history: &[(f64, f64)]) -> (f64, f64) {
    let mut peaks = Vec::new();
    for w in history.windows(3) {
        let ((t0, y0), (t1, y1), (_, y2)) = (w[0], w[1], w[2]);
        if y1 > y0 && y1 >= y2 && y1 > 0.0 {
            let dt = t1 - t0;
            let curvature = y0 - 2.0 * y1 + y2;
            let shift = 0.5 * (y0 - y2) / curvature;
            let peak = y1 - 0.25 * (y0 - y2) * shift;
            peaks.push((t1 + shift * dt, peak));
        }
    }
    assert!(peaks.len() >= 3, "{} peaks", peaks.len());
    let (first, last) = (peaks[0], peaks[peaks.len() - 1]);
    let period = (last.0 - first.0) / (peaks.len() - 1) as f64;
    let rate = (first.1 / last.1).ln() / (last.0 - first.0);
    (period, rate)
}
