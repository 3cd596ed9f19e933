//! What a change of step size does to the scheme's conserved energy Q (the quantity the
//! space-time scheme keeps at a fixed step): a step cut in two halves (what `Simulation::step`
//! does when Newton fails) moves it a little; steps cut again and again pump energy into the
//! modes the step does not resolve (a known defect: the contact chapter, "A stalled Newton is
//! retried").

mod common;

use softway::contact::{GapDisplacement, PenaltyForce};
use softway::prelude::*;

/// A 1 m steel bar (100 Quad4 cells) thrown at 1 m/s against a rigid wall 0.1 mm away, at `k`
/// times the explicit stable step, with the soft way's secant pressure (Q exact at a fixed
/// step); once it has bounced off (3 l/c), it flies free for 4 l/c, vibrating, and the steps
/// `cut(n)` says (n counted from the separation) are taken as two halves. Returns Q at the end
/// over Q at the separation.
fn free_flight_after_impact(k: f64, cut: impl Fn(usize) -> bool) -> f64 {
    let (mut sim, transit) =
        common::steel_bar_at_a_wall(k, GapDisplacement::Trapezoid, PenaltyForce::Secant);
    let h = sim.model().settings.time_step;
    let separated = 3.0 * transit;
    while sim.state().time < separated {
        sim.step().unwrap();
    }
    let q = sim.scheme_energy();
    let mut n = 0;
    while sim.state().time < separated + 4.0 * transit {
        n += 1;
        if cut(n) {
            sim.advance(0.5 * h, &mut NullRecorder).unwrap();
            sim.advance(0.5 * h, &mut NullRecorder).unwrap();
        } else {
            sim.step().unwrap();
        }
    }
    sim.scheme_energy() / q
}

/// Without cuts Q stays to 3e-11; one step halved moves it by 1.8e-3, 1.3e-2 and 1.6e-2 at 2, 5
/// and 10 times the explicit step (measured 2026-11-26).
#[test]
fn one_cut_step_moves_the_conserved_energy_little() {
    for k in [2.0, 5.0, 10.0] {
        let steady = free_flight_after_impact(k, |_| false);
        assert!((steady - 1.0).abs() < 1e-9, "k = {k}: {steady}");
        let once = free_flight_after_impact(k, |n| n == 5);
        eprintln!("k = {k}: Q(end)/Q(separation) {once} after one cut step");
        common::verify::record("step-cut", "Q change", once - 1.0);
        assert!((once - 1.0).abs() < 0.025, "k = {k}: {once}");
    }
}

/// Every seventh step halved: Q grows 59-fold at twice the explicit step in four transit times
/// (3.3e5-fold at 5 times; every third step halved, the run stops as unstable). The scheme at a
/// fixed step conserves a modified energy that depends on the step; changing the step back and
/// forth excites the unresolved modes parametrically. This is what made the bar impact's paper
/// pressure look 444-fold unstable while Newton stalled at its round-off floor and its steps were
/// cut (`tests/secant_penalty.rs`).
#[test]
#[ignore = "known defect: Q grows 59-fold when every seventh step is halved (k = 2)"]
fn repeated_cut_steps_keep_the_conserved_energy() {
    let periodic = free_flight_after_impact(2.0, |n| n % 7 == 0);
    assert!((periodic - 1.0).abs() < 0.025, "{periodic}");
}
