//! The soft cube of the peer comparison (0.2 m, E = 1e5 Pa, nu = 0.3, rho = 1000 kg/m^3, Tet4,
//! 8 cells a side) dropped from 0.1 m onto a plane at a game's step, h = 1/60 s, for 2 s.
//! Explicit projection, the soft way and the augmented Lagrangian (zeta = 1e8 Pa/m) run to the
//! end; with the paper's configuration gaps the penalty methods leave the cube 15 to 19 mm
//! deep (one step's travel at impact), with `GapDisplacement::Trapezoid` the soft way keeps it
//! within 0.25 mm.

mod common;

use common::{block, vec_d};
use softway::contact::{ContactMethod, ContactSettings, GapDisplacement, Obstacle, ObstacleShape};
use softway::prelude::*;

/// The largest penetration over the run.
fn drop_cube(method: ContactMethod, gaps: GapDisplacement) -> f64 {
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
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    let mut penetration: f64 = 0.0;
    while sim.state().time < 2.0 - 1e-9 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("{method:?}, t = {}: {e}", sim.state().time));
        penetration = penetration.max(r.max_penetration);
    }
    eprintln!("{method:?}, {gaps:?}: largest penetration {penetration:.3e} m");
    penetration
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
#[ignore = "the active set cycles at t = 0.53 s (reported as no convergence)"]
fn implicit_projection_soft_cube() {
    assert!(
        drop_cube(
            ContactMethod::ImplicitProjection,
            GapDisplacement::Configuration
        ) < 1e-12
    );
}
