//! The energy account of the bundled ring drop (through its landing, 0.4 s) for each contact
//! method, with and without Coulomb friction 0.3, and for the penalty methods with each
//! `contact.gap_displacement`: the account on E (kinetic + elastic + contact energy, as
//! summary.json's `energy_drift`) and on the scheme's conserved energy Q
//! (`Simulation::scheme_energy`), both relative to the energy reference, the largest
//! penetration and the Newton iterations per contact step. The book's contact chapter quotes
//! these figures.
//!
//! Run: `cargo run --release --features formats --example energy_account`

use softway::contact::{GapDisplacement, PenaltyForce};
use softway::Simulation;

fn main() {
    let path =
        std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/ring_drop.toml");
    println!("method, gap displacement, penalty force, friction: E account (worst), Q account (worst), dissipated, max penetration, iterations per contact step");
    for method in [
        "soft_way",
        "augmented_lagrangian",
        "implicit_projection",
        "explicit_projection",
    ] {
        let variants: &[(GapDisplacement, PenaltyForce)] = match method {
            "soft_way" => &[
                (GapDisplacement::Configuration, PenaltyForce::EndOfStep),
                (GapDisplacement::Trapezoid, PenaltyForce::EndOfStep),
                (GapDisplacement::Trapezoid, PenaltyForce::Secant),
            ],
            "augmented_lagrangian" => &[
                (GapDisplacement::Configuration, PenaltyForce::EndOfStep),
                (GapDisplacement::Trapezoid, PenaltyForce::EndOfStep),
            ],
            _ => &[(GapDisplacement::Configuration, PenaltyForce::EndOfStep)],
        };
        for &(gap, force) in variants {
            for friction in [
                "{law=\"frictionless\"}",
                "{law=\"coulomb\",coefficient=0.3}",
            ] {
                if method == "explicit_projection" && friction.contains("coulomb") {
                    continue;
                }
                let overrides = [
                    format!("contact.method=\"{method}\""),
                    format!("contact.friction={friction}"),
                    "simulation.end_time=0.4".to_string(),
                ];
                let scene = softway::io::scene::load(&path, &overrides)
                    .and_then(|s| s.build::<2>())
                    .expect("the bundled scene");
                let mut model = scene.simulation().expect("builds").model().clone();
                model.contact.gap_displacement = gap;
                model.contact.penalty_force = force;
                let mut sim = Simulation::<2>::from_model(model).expect("builds");
                let (mut worst_e, mut worst_q, mut penetration) = (0.0f64, 0.0f64, 0.0f64);
                let (mut iterations, mut contact_steps) = (0, 0);
                let mut accounts = (0.0, 0.0);
                while sim.state().time < scene.end_time - 1e-9 {
                    let r = sim.step().expect("the step converges");
                    if r.active_contacts > 0 {
                        iterations += r.iterations;
                        contact_steps += 1;
                    }
                    penetration = penetration.max(r.max_penetration);
                    let e = sim.energies();
                    let reference = sim.energy_reference();
                    let booked = sim.initial_energy() + e.external_work - e.dissipated;
                    accounts = (
                        (e.total() - booked) / reference,
                        (sim.scheme_energy() - booked) / reference,
                    );
                    worst_e = worst_e.max(accounts.0.abs());
                    worst_q = worst_q.max(accounts.1.abs());
                }
                println!(
                    "{method}, {gap:?}, {force:?}, {friction}: {:+.3e} ({worst_e:.2e}), {:+.3e} \
                     ({worst_q:.2e}), {:.3e} J, {penetration:.2e} m, {:.2}",
                    accounts.0,
                    accounts.1,
                    sim.energies().dissipated,
                    iterations as f64 / contact_steps.max(1) as f64
                );
            }
        }
    }
}
