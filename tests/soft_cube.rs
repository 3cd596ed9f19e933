//! The soft cube of the peer comparison (0.2 m, E = 1e5 Pa, nu = 0.3, rho = 1000 kg/m^3, Tet4,
//! 8 cells a side) dropped from 0.1 m onto a plane at a game's step, h = 1/60 s, for 2 s.
//! Explicit projection, the soft way and the augmented Lagrangian (zeta = 1e8 Pa/m) run to the
//! end; with the paper's configuration gaps the penalty methods leave the cube 15 to 19 mm
//! deep (one step's travel at impact), with `GapDisplacement::Trapezoid` the soft way keeps it
//! within 0.25 mm.

use crate::common;

use common::{block, vec_d};
use softway::contact::{ContactMethod, ContactSettings, GapDisplacement, Obstacle, ObstacleShape};
use softway::prelude::*;
use softway::simulation::energy_created;

/// The largest penetration over the run.
fn drop_cube(method: ContactMethod, gaps: GapDisplacement) -> f64 {
    drop_cube_measured(method, gaps).0
}

/// The largest penetration (m) and the largest energy created (the run monitor's measure,
/// a fraction of the input) over the run.
fn drop_cube_measured(method: ContactMethod, gaps: GapDisplacement) -> (f64, f64) {
    let mut mesh: Mesh<3> = block([0.2, 0.2, 0.2], [8, 8, 8], true);
    for x in &mut mesh.nodes {
        x[2] += 0.1;
    }
    let mut sim = Simulation::<3>::builder()
        .time_step(1.0 / 60.0)
        .gravity(vec_d([0.0, 0.0, -9.81]))
        .body(Body::new(
            "cube",
            mesh,
            Material::LinearElastic(LinearElastic::new(1e5, 0.3, 1000.0).unwrap()),
        ))
        .obstacle(Obstacle::new(
            "floor",
            ObstacleShape::Halfspace {
                point: vec_d([0.0; 3]),
                normal: vec_d([0.0, 0.0, 1.0]),
            },
        ))
        .contact(ContactSettings {
            method,
            penalty: 1e8,
            gap_displacement: gaps,
            projection: if std::env::var("CUBE_NODE").is_ok() {
                softway::contact::ProjectionMetric::Node
            } else {
                softway::contact::ProjectionMetric::Step
            },
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    let mut penetration: f64 = 0.0;
    let mut created: f64 = 0.0;
    let e0 = sim.initial_energy();
    while sim.state().time < 2.0 - 1e-9 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("{method:?}, t = {}: {e}", sim.state().time));
        penetration = penetration.max(r.max_penetration);
        // After the fall's first steps, where the work done is still tiny against the
        // kinetic energy of the scheme's start-up (the measure is 1.0 at step 1 for every
        // method).
        if sim.state().time > 0.14 {
            created = created.max(energy_created(e0, &sim.energies()));
        }
        if std::env::var("CUBE_DEBUG").is_ok() {
            let e = sim.energies();
            eprintln!(
                "t {:.4} it {} active {} pen {:.3e} K {:.3} U {:.3} W {:.3} D {:.3} created {:.3}",
                r.time,
                r.iterations,
                r.active_contacts,
                r.max_penetration,
                e.kinetic,
                e.internal,
                e.external_work,
                e.dissipated,
                energy_created(e0, &e)
            );
        }
    }
    eprintln!(
        "{method:?}, {gaps:?}: largest penetration {penetration:.3e} m, \
         largest energy created {created:.3e} of the input"
    );
    (penetration, created)
}

#[test]
fn the_soft_cube_lands_at_a_game_step() {
    // Measured: 2.0e-2 m (configuration) against 2.4e-4 m (trapezoid); the static pressure
    // over zeta is 2e-5 m, the cube still bounces at 2 s.
    let configuration = drop_cube(ContactMethod::SoftWay, GapDisplacement::Configuration);
    let trapezoid = drop_cube(ContactMethod::SoftWay, GapDisplacement::Trapezoid);
    assert!(trapezoid < 5e-4, "{trapezoid}");
    assert!(configuration > 10.0 * trapezoid);
    // Measured 1.9e-2 m: the same stored penetration.
    assert!(
        drop_cube(
            ContactMethod::AugmentedLagrangian,
            GapDisplacement::Configuration
        ) < 3e-2
    );
    // Projected onto the plane at every step end.
    assert!(
        drop_cube(
            ContactMethod::ExplicitProjection,
            GapDisplacement::Configuration
        ) < 1e-12
    );
}

#[test]
fn implicit_projection_soft_cube() {
    // The default method and scheme run the 2 s (the active set cycled at 0.53 s before its
    // activation test and constraint were made to agree), and the end-of-step projection
    // leaves nothing inside the plane (measured 7.2e-8 m). Open (the book's contact chapter,
    // Limits): the projection still puts energy in, measured at most 0.98 of the input after
    // the landing (the soft way with configuration gaps 2.09, the augmented Lagrangian 2.96,
    // explicit projection 24.2; the paper's node-by-node projection went to 1852 times the
    // input).
    let (penetration, created) = drop_cube_measured(
        ContactMethod::ImplicitProjection,
        GapDisplacement::Configuration,
    );
    assert!(penetration < 1e-6, "{penetration}");
    assert!(created < 1.2, "{created}");
}
