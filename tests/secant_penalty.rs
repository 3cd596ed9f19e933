//! The soft way's secant pressure (`PenaltyForce::Secant`, a discrete gradient of the penalty
//! potential) on trapezoid gaps: a free elastic block thrown against a rigid floor (no gravity)
//! bounces off with the energy it came with, where the paper's end-of-step pressure loses some.

use crate::common;

use common::{block, vec_d};
use softway::contact::{ContactMethod, ContactSettings, GapDisplacement, PenaltyForce};
use softway::dim::{Dim, SpatialDim};
use softway::prelude::*;

/// Throws the block down at 1 m/s from 1 mm above the floor and runs until it has left;
/// returns the energy account on E and on the scheme's conserved energy Q relative to the
/// initial kinetic energy, and the largest penetration.
fn bounce<const D: usize>(force: PenaltyForce) -> (f64, f64, f64)
where
    Dim<D>: SpatialDim<D>,
{
    let mut down = [0.0; 3];
    down[D - 1] = -1.0;
    let mut mesh: Mesh<D> = block([0.1, 0.1, 0.1], [4, 4, 4], false);
    let mut lift = [0.0; 3];
    lift[D - 1] = 1e-3;
    for x in &mut mesh.nodes {
        *x += vec_d::<D>(lift);
    }
    let body = Body::new(
        "block",
        mesh,
        Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap()),
    )
    .with_velocity(vec_d(down));
    let mut sim = Simulation::<D>::builder()
        .time_step(1e-3)
        .body(body)
        .obstacle(common::floor::<D>())
        .contact(ContactSettings {
            method: ContactMethod::SoftWay,
            penalty: 1e9,
            gap_displacement: GapDisplacement::Trapezoid,
            penalty_force: force,
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    let start = sim.energies().total();
    let mut penetration: f64 = 0.0;
    let mut touched = false;
    while sim.state().time < 0.1 - 1e-9 {
        let r = sim.step().unwrap();
        penetration = penetration.max(r.max_penetration);
        touched |= r.active_contacts > 0;
    }
    assert!(touched, "the block never reached the floor");
    let e = sim.energies();
    assert_eq!(e.contact, 0.0, "the block is still on the floor at 0.1 s");
    let account_e = (e.total() - start) / start;
    let account_q = (sim.scheme_energy() - start) / start;
    eprintln!(
        "{D}D {force:?}: E account {account_e:+.3e}, Q account {account_q:+.3e}, largest \
         penetration {penetration:.3e} m"
    );
    (account_e, account_q, penetration)
}

fn secant_pressure_keeps_the_bounce_elastic<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let (_, q_paper, _) = bounce::<D>(PenaltyForce::EndOfStep);
    let (_, q_secant, penetration) = bounce::<D>(PenaltyForce::Secant);
    // Measured: Q account -6.17e-2 (2D) / -6.18e-2 (3D) with the paper's pressure, +3.8e-4 /
    // +1.7e-4 with the secant (the same with a Newton tolerance of 1e-12: the rest is not the
    // solver's; not found yet).
    assert!(q_secant.abs() < 1e-3, "Q account {q_secant}");
    assert!(
        q_paper.abs() > 50.0 * q_secant.abs(),
        "{q_paper} against {q_secant}"
    );
    // p / zeta for the impact pressure rho c v0 (c = sqrt(E / rho) = 31.6 m/s) is 3.2e-5 m;
    // measured 1.06e-4 (2D) / 1.03e-4 m (3D), against 4.9e-5 / 4.7e-5 m with the paper's
    // pressure: the secant averages the step's start and end gaps, so it lags the end one.
    assert!(penetration < 1.3e-4, "penetration {penetration}");
}

both_dims!(secant_pressure_keeps_the_bounce_elastic);

/// The bar impact of `examples/bar_impact.rs` (steel, L = 1 m, c = 5000 m/s, 100 cells,
/// zeta = 1e5 E / L) at k times the explicit stable step l_e / c: the scheme's conserved energy
/// at the end over the initial energy, or `None` when a step did not converge.
fn bar_impact(k: f64, gaps: GapDisplacement, force: PenaltyForce) -> Option<f64> {
    let (mut sim, transit) = common::steel_bar_at_a_wall(k, gaps, force);
    let h = sim.model().settings.time_step;
    let q0 = sim.scheme_energy();
    // The bar reaches the wall 0.1 mm away at 1 m/s, then stays in contact for 2 l / c.
    let end = 2e-4 + 2.0 * transit + 10.0 * h;
    while sim.state().time < end {
        sim.step().ok()?;
    }
    Some(sim.scheme_energy() / q0)
}

/// At steps above the explicit limit the paper's pressure puts energy into the bouncing bar
/// (its stiff contact springs close and open within a few steps), more the larger the step;
/// the secant does not. Measured Q(end) / Q(0), k = 2, 5, 10: configuration gaps with the
/// paper's pressure 1.018, 1.052, 1.105; secant 1 within 2e-10. (Before Newton accepted a
/// residual at its floating-point floor, the paper's pressure stalled at relative residuals of
/// 1.05e-8 to 1.7e-8 on many steps, and the cut steps made those figures 1.30, 444 and 249.)
#[test]
fn secant_pressure_keeps_the_bar_impact_at_large_steps() {
    let mut growth = 1.0;
    for k in [2.0, 5.0, 10.0] {
        let paper = bar_impact(k, GapDisplacement::Configuration, PenaltyForce::EndOfStep);
        let secant = bar_impact(k, GapDisplacement::Trapezoid, PenaltyForce::Secant);
        eprintln!("k = {k}: Q(end)/Q(0) {paper:?} (paper's pressure), {secant:?} (secant)");
        let secant = secant.expect("the secant runs");
        assert!((secant - 1.0).abs() < 1e-6, "k = {k}: secant {secant}");
        let paper = paper.expect("the paper's pressure runs");
        assert!(paper > 1.01 && paper > growth, "k = {k}: paper's {paper}");
        growth = paper;
    }
}
