//! The soft cube of the peer comparison (0.2 m, E = 1e5 Pa, nu = 0.3, rho = 1000 kg/m^3, Tet4,
//! 8 cells a side) dropped from 0.1 m onto a plane at a game's step, h = 1/60 s, for 2 s.
//! The soft way and the augmented Lagrangian (zeta = 1e8 Pa/m) run to the end; with the
//! paper's configuration gaps they leave the cube 15 to 19 mm deep (one step's travel at
//! impact) and create energy, with `GapDisplacement::Trapezoid` the soft way keeps it within
//! 0.25 mm and creates none. Energy is read as the run monitor reads it (the summary's
//! warning); the monitor stops explicit projection at the landing.

use crate::common;

use common::{block, vec_d};
use softway::contact::{
    ContactMethod, ContactSettings, GapDisplacement, Obstacle, ObstacleShape, ProjectionEnergy,
};
use softway::prelude::*;
use softway::simulation::{energy_created, RunMonitor, ENERGY_WARNING};

/// What a drop measured.
struct Drop {
    /// The largest penetration over the run (m).
    penetration: f64,
    /// The largest depth any contact point's pressure stands for over the run (m): its eq 22
    /// gap, which the soft way's pressure is zeta times.
    pressure_depth: f64,
    /// The largest energy created, a fraction of the input, on the run monitor's measure (the
    /// scheme's conserved energy: the one the summary's warning reads).
    created: f64,
    /// The monitor's error where it stopped the run (as `softway run` stops with exit 3).
    stopped: Option<String>,
    /// Numeric factorisations over the run (contact-free and contact matrices).
    factorisations: usize,
}

/// The largest penetration over the run.
fn drop_cube(method: ContactMethod, gaps: GapDisplacement) -> f64 {
    drop_cube_measured(method, gaps).penetration
}

/// The cube dropped for 2 s with `method` on `gaps`, watched by the run monitor.
fn drop_cube_measured(method: ContactMethod, gaps: GapDisplacement) -> Drop {
    drop_cube_with(method, gaps, ProjectionEnergy::Booked)
}

/// The cube dropped for 2 s with `method` on `gaps` and implicit projection's `energy`
/// bound, watched by the run monitor.
fn drop_cube_with(method: ContactMethod, gaps: GapDisplacement, energy: ProjectionEnergy) -> Drop {
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
            projection_energy: energy,
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
    let mut pressure_depth: f64 = 0.0;
    let mut factorisations = 0;
    // What the summary's energy warning reads (the scheme's conserved energy).
    let mut monitor = RunMonitor::new(&sim);
    let e0 = sim.initial_energy();
    while sim.state().time < 2.0 - 1e-9 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("{method:?}, t = {}: {e}", sim.state().time));
        penetration = penetration.max(r.max_penetration);
        pressure_depth = sim
            .contacts()
            .iter()
            .map(|c| -c.gap)
            .fold(pressure_depth, f64::max);
        factorisations += r.factorisations;
        if let Err(e) = monitor.step(&sim, &r) {
            eprintln!("{method:?}, {gaps:?}: stopped: {e}");
            return Drop {
                penetration,
                pressure_depth,
                created: monitor.energy_created_peak(),
                stopped: Some(e.to_string()),
                factorisations,
            };
        }
        if std::env::var("CUBE_DEBUG").is_ok() {
            let e = sim.energies();
            eprintln!(
                "t {:.4} it {} active {} pen {:.3e} K {:.3} U {:.3} W {:.3} D {:.3} created (E) {:.3} \
                 Q {:.4} created (Q, peak so far) {:.3} pz {:.4}",
                r.time,
                r.iterations,
                r.active_contacts,
                r.max_penetration,
                e.kinetic,
                e.internal,
                e.external_work,
                e.dissipated,
                energy_created(e0, &e),
                sim.scheme_energy(),
                monitor.energy_created_peak(),
                sim.body_momentum(sim.body_ids()[0]).unwrap()[2]
            );
        }
    }
    let created = monitor.energy_created_peak();
    eprintln!(
        "{method:?}, {gaps:?}: largest penetration {penetration:.3e} m (pressure over zeta \
         {pressure_depth:.3e} m), largest energy created {created:.3e} of the input, {factorisations} factorisations"
    );
    Drop {
        penetration,
        pressure_depth,
        created,
        stopped: None,
        factorisations,
    }
}

#[test]
fn the_soft_cube_lands_at_a_game_step() {
    // Measured: 2.0e-2 m (configuration) against 2.4e-4 m (trapezoid); the static pressure
    // over zeta is 2e-5 m, the cube still bounces at 2 s.
    let configuration = drop_cube_measured(ContactMethod::SoftWay, GapDisplacement::Configuration);
    let trapezoid = drop_cube_measured(ContactMethod::SoftWay, GapDisplacement::Trapezoid);
    assert!(trapezoid.penetration < 5e-4, "{}", trapezoid.penetration);
    // The bound: on trapezoid gaps the stored penetration is what the penalty says,
    // its pressure over zeta (measured equal, 2.39e-4 m; on configuration gaps 2.0e-2 m is
    // stored where the pressures stand for 4.4e-4 m at most, 2026-12-03).
    assert!(
        trapezoid.penetration <= 2.0 * trapezoid.pressure_depth,
        "{} m stored against {} m of pressure over zeta",
        trapezoid.penetration,
        trapezoid.pressure_depth
    );
    assert!(configuration.penetration > 10.0 * trapezoid.penetration);
    // On the trapezoid displacement the penalty's work is booked in the conserved energy's
    // own terms: nothing is created (measured 3.8e-13 of the input). The stored
    // configuration's offset pumps: 1.07 of the input (the summary warns).
    assert!(trapezoid.created < 1e-9, "{}", trapezoid.created);
    assert!(
        configuration.created > ENERGY_WARNING,
        "{}",
        configuration.created
    );
    assert!(trapezoid.stopped.is_none() && configuration.stopped.is_none());
    // Measured 1.9e-2 m: the same stored penetration (and 1.91 of the input created).
    assert!(
        drop_cube(
            ContactMethod::AugmentedLagrangian,
            GapDisplacement::Configuration
        ) < 3e-2
    );
    // Projected onto the plane at every step end: the landing step's projection moves the
    // bottom nodes up by up to a step's travel, 2.3 cm against cells of 2.5 cm, and folds the
    // lowest cells, where the monitor stops the run, as `softway run` stops with exit 3. (Until
    // the monitor watched folds, 2026-11-30, the projection's energy stopped it at the next
    // step, 18 times the input.)
    let explicit = drop_cube_measured(
        ContactMethod::ExplicitProjection,
        GapDisplacement::Configuration,
    );
    assert!(explicit.penetration < 1e-12, "{}", explicit.penetration);
    let stopped = explicit.stopped.expect("the monitor stops the run");
    assert!(
        stopped.starts_with("a cell turned inside out at step 10 ")
            && stopped.contains("of body `cube`"),
        "{stopped}"
    );
}

#[test]
fn implicit_projection_soft_cube() {
    // The default method and scheme run the 2 s (the active set cycled at 0.53 s before its
    // activation test and constraint were made to agree), and the end-of-step projection
    // leaves nothing inside the plane (measured 7.2e-8 m until the projection kept the held
    // points on the plane, 2026-11-30; 0 since). With the paper's booked
    // correction (no longer the default, below) the projection puts energy in, at most 0.42
    // of the input on the monitor's measure (the summary warns from the second landing,
    // step 26, at 8.6 %; the book's contact chapter, Limits).
    let cube = drop_cube_measured(
        ContactMethod::ImplicitProjection,
        GapDisplacement::Configuration,
    );
    assert!(cube.penetration < 1e-9, "{}", cube.penetration);
    assert!(cube.created < 0.5, "{}", cube.created);
    // 106 (155 while the second correction moved its round-off depths out, 2026-12-01).
    assert!(cube.factorisations <= 120, "{}", cube.factorisations);
    assert!(cube.stopped.is_none());
}

#[test]
fn a_bounded_projection_energy_lands_the_soft_cube_without_creating_energy() {
    // The default: the correction may give back what the landings' stops took, not more: on
    // the monitor's measure 3.3e-2 of the input at most (0.42 booked, above), below the 5 %
    // warning; still nothing left inside the plane (measured 2.6e-7 m until the projection
    // kept the held points on the plane, 2026-11-30; 5.3e-13 m since).
    let defaults = ContactSettings::default().projection_energy;
    assert_eq!(defaults, ProjectionEnergy::Bounded);
    let cube = drop_cube_with(
        ContactMethod::ImplicitProjection,
        GapDisplacement::Configuration,
        defaults,
    );
    assert!(cube.penetration < 1e-9, "{}", cube.penetration);
    assert!(cube.created < ENERGY_WARNING, "{}", cube.created);
    // 107 factorisations in the 120 steps; 173 while the second correction moved its
    // round-off depths out (2026-12-01; the performance chapter).
    assert!(cube.factorisations <= 120, "{}", cube.factorisations);
    assert!(cube.stopped.is_none());
}

/// The augmented Lagrangian on trapezoid gaps (its persistency stop on): Uzawa closes the gaps
/// it measures, and the closed pairs' approach is stopped after each step. Measured
/// (2026-11-30) 9.8e-10 m deep at worst and 1.8e-11 of the input created, against 1.9e-2 m and
/// 1.91 on the paper's configuration gaps (above).
#[test]
fn augmented_lagrangian_on_trapezoid_gaps_soft_cube() {
    let cube = drop_cube_measured(
        ContactMethod::AugmentedLagrangian,
        GapDisplacement::Trapezoid,
    );
    assert!(cube.penetration < 1e-6, "{}", cube.penetration);
    assert!(cube.created < ENERGY_WARNING, "{}", cube.created);
    assert!(cube.stopped.is_none());
}
