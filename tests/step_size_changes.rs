//! What a change of step size does to the scheme's conserved energy Q (the quantity the
//! space-time scheme keeps at a fixed step): a step cut in two halves (what `Simulation::step`
//! does when Newton fails) moves it a little; steps cut again and again pump energy into the
//! modes the step does not resolve (a known defect: the contact chapter, "A stalled Newton is
//! retried").

use crate::common;

use softway::contact::{GapDisplacement, PenaltyForce};
use softway::prelude::*;

/// A 1 m steel bar (100 Quad4 cells) thrown at 1 m/s against a rigid wall 0.1 mm away, at `k`
/// times the explicit stable step, with the soft way's secant pressure (Q exact at a fixed
/// step); once it has bounced off (3 l/c), it flies free for 4 l/c, vibrating, and the steps
/// `cut(n)` says (n counted from the separation) are taken as two halves. Returns Q at the end
/// over Q at the separation.
fn free_flight_after_impact(k: f64, cut: impl Fn(usize) -> bool) -> f64 {
    free_flight_with_cuts(k, cut, false)
}

/// [`free_flight_after_impact`], with the displacement shifted by `a (h - h') v` at each change
/// of step from h to h' when `shifted` (a = (alpha - beta) / 2).
fn free_flight_with_cuts(k: f64, cut: impl Fn(usize) -> bool, shifted: bool) -> f64 {
    let (mut sim, transit) =
        common::steel_bar_at_a_wall(k, GapDisplacement::Trapezoid, PenaltyForce::Secant);
    let h = sim.model().settings.time_step;
    let SpaceTimeScheme { alpha, beta } = sim.model().settings.scheme;
    let shift = if shifted {
        0.5 * (alpha - beta) * 0.5 * h
    } else {
        0.0
    };
    let separated = 3.0 * transit;
    while sim.state().time < separated {
        sim.step().unwrap();
    }
    let q = sim.scheme_energy();
    let mut n = 0;
    while sim.state().time < separated + 4.0 * transit {
        n += 1;
        if cut(n) {
            shift_displacement(&mut sim, shift);
            sim.advance(0.5 * h, &mut NullRecorder).unwrap();
            sim.advance(0.5 * h, &mut NullRecorder).unwrap();
            shift_displacement(&mut sim, -shift);
        } else {
            sim.step().unwrap();
        }
    }
    sim.scheme_energy() / q
}

/// u += `by` v (s), through the public state.
fn shift_displacement(sim: &mut Simulation<2>, by: f64) {
    if by == 0.0 {
        return;
    }
    let mut state = sim.state().clone();
    for (u, v) in state.displacement.iter_mut().zip(&sim.state().velocity) {
        *u += by * v;
    }
    sim.set_state(state).unwrap();
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

/// Why cuts pump, and a change of step that keeps Q (an experiment for issue 10, not yet what
/// `Simulation::step` does). With a = (alpha - beta) / 2 and the shadow displacement
/// u~ = u + a h v, the conserved energy is `Q_h = 1/2 v^T M v + 1/2 u~^T K u~ + g h^2 v^T K v`,
/// g = (alpha^2 - 2 alpha beta) / 4 - a^2 / 2 (1/64 at the default 0.75 and 0.25; 0 at
/// alpha = sqrt(2)/2, beta = 1 - alpha). A change of step from h to h' at a fixed u moves u~ by
/// a (h' - h) v; shifting u by a (h - h') v keeps it, and Q then moves only by g's term.
/// Measured (k = 2, twice the explicit step): every seventh step halved, Q ends at 1.0003 of
/// its value (59-fold without the shift), every third at 1.04 (unstable without), one halved
/// step 9.5e-5 (1.8e-3). At k = 5 g's term is no longer small: every seventh step halved, Q
/// grows 43-fold (3.3e5-fold without).
#[test]
fn cut_steps_that_keep_the_shadow_displacement_keep_q() {
    let once = free_flight_with_cuts(2.0, |n| n == 5, true);
    assert!((once - 1.0).abs() < 2e-4, "once: {once}");
    let periodic = free_flight_with_cuts(2.0, |n| n % 7 == 0, true);
    assert!((periodic - 1.0).abs() < 1e-3, "every seventh: {periodic}");
    let often = free_flight_with_cuts(2.0, |n| n % 3 == 0, true);
    assert!((often - 1.0).abs() < 0.05, "every third: {often}");
    // Five times the explicit step: g's term pumps (measured 43-fold; 3.3e5 without the shift).
    let stiff = free_flight_with_cuts(5.0, |n| n % 7 == 0, true);
    assert!(stiff < 100.0, "k = 5, every seventh: {stiff}");
    eprintln!(
        "shifted cuts, Q(end)/Q(separation): k = 2: {once} (one), {periodic} (every seventh), \
         {often} (every third); k = 5: {stiff} (every seventh)"
    );
}
