//! The soft cube of the peer figures, softway beside rapier3d-f64 0.36's soft bodies, in one
//! process: a 0.2 m cube (E = 1e5 Pa, nu = 0.3, rho = 1000 kg/m^3) of n^3 cubes split into six
//! tetrahedra each (softway's `cuboid` mesh, handed to rapier as its cells), dropped from rest
//! 0.1 m above a rigid floor, gravity 9.81 m/s^2, 2 simulated seconds.
//!
//! * softway: the soft way (zeta = 1e8 Pa/m, the paper's end-of-step pressure, and the secant
//!   option on trapezoid gaps), and implicit projection (the default method), frictionless
//!   floor, default scheme, at the step asked; undamped, and with a material damping of 5 % of
//!   critical at the cube's first mode (rapier's bodies are damped and come to rest);
//! * rapier: `SoftBodySolver::Constraints` (its default) and `SoftBodySolver::Fem` (implicit
//!   Euler FEM), corotational cells, the particle radius half a cell, sleeping off, a fixed
//!   cuboid ground (friction 0.5, rapier's default), its default 4 substeps.
//!
//! Printed per run: wall time per simulated second, the deepest a node went below the floor
//! (rapier keeps its particles a radius above it: its figure is the depth below that radius),
//! the sag at the end (0.2 m less the mean height of the top face over the bottom face) against
//! the frictionless column's rho g H^2 / (2 E) = 1.96 mm, and the kinetic energy left at 2 s.
//!
//! Run (from `benches/compare/rapier`; its own workspace, out of softway's build and CI):
//! `cargo run --release --bin soft_cube -- [CELLS_PER_EDGE [STEP]]` (default 6 and 1/60 s).

use std::time::Instant;

use nalgebra::Vector3;
use rapier3d_f64::prelude::*;
use softway::contact::{
    ContactMethod, ContactSettings, GapDisplacement, Obstacle, ObstacleShape, PenaltyForce,
};
use softway::prelude::*;

const SIZE: f64 = 0.2;
const DROP: f64 = 0.1;
const YOUNG: f64 = 1e5;
const POISSON: f64 = 0.3;
const DENSITY: f64 = 1000.0;
const GRAVITY: f64 = 9.81;
const END: f64 = 2.0;

/// What a run measured.
struct Outcome {
    label: String,
    /// Wall time per simulated second [s/s], or the error that stopped the run.
    result: Result<f64, String>,
    /// The deepest a node went below the floor (or below rapier's particle radius) [m].
    depth: f64,
    /// 0.2 m less the mean top height over the mean bottom height, at the end [m].
    sag: f64,
    /// Kinetic energy at the end [J].
    kinetic: f64,
}

/// The sag from node heights: top face nodes (highest in the reference) against bottom ones.
fn sag(reference: &[Vector3<f64>], heights: &[f64]) -> f64 {
    let mean = |pick: &dyn Fn(f64) -> bool| {
        let (sum, count) = reference
            .iter()
            .zip(heights)
            .filter(|(x, _)| pick(x.z))
            .fold((0.0, 0usize), |(s, c), (_, z)| (s + z, c + 1));
        sum / count as f64
    };
    let top = mean(&|z| z > DROP + SIZE - 1e-9);
    let bottom = mean(&|z| z < DROP + 1e-9);
    SIZE - (top - bottom)
}

fn softway_run(
    mesh: &Mesh<3>,
    dt: f64,
    label: &str,
    contact: ContactSettings,
    damping: f64,
) -> Outcome {
    let reference: Vec<Vector3<f64>> = mesh.nodes.clone();
    let body = Body::new(
        "cube",
        mesh.clone(),
        Material::LinearElastic(LinearElastic::new(YOUNG, POISSON, DENSITY).unwrap()),
    )
    .with_damping(0.0, damping);
    let mut sim = Simulation3::builder()
        .time_step(dt)
        .gravity(Vector3::new(0.0, 0.0, -GRAVITY))
        .body(body)
        .obstacle(Obstacle::new(
            "floor",
            ObstacleShape::Halfspace {
                point: Vector3::zeros(),
                normal: Vector3::z(),
            },
        ))
        .contact(contact)
        .build()
        .expect("the scene is valid");
    let id = sim.body_id("cube").expect("one body");
    let (mut depth, mut result) = (0.0f64, Ok(0.0));
    let clock = Instant::now();
    while sim.state().time < END - 1e-9 {
        if let Err(e) = sim.step() {
            result = Err(format!("stopped at t = {:.3} s: {e}", sim.state().time));
            break;
        }
        let lowest = sim
            .body_positions(id)
            .expect("the body")
            .iter()
            .map(|x| x.z)
            .fold(f64::INFINITY, f64::min);
        depth = depth.max(-lowest);
    }
    if result.is_ok() {
        result = Ok(clock.elapsed().as_secs_f64() / END);
    }
    let heights: Vec<f64> = sim
        .body_positions(id)
        .expect("the body")
        .iter()
        .map(|x| x.z)
        .collect();
    let m = sim.mass_matrix();
    let v = &sim.state().velocity;
    Outcome {
        label: label.into(),
        result,
        depth,
        sag: sag(&reference, &heights),
        kinetic: 0.5 * m.dot(v, v),
    }
}

fn rapier_run(mesh: &Mesh<3>, dt: f64, cell: f64, solver: SoftBodySolver) -> Outcome {
    let reference: Vec<Vector3<f64>> = mesh.nodes.clone();
    let tets: Vec<[u32; 4]> = mesh.blocks[0]
        .cells()
        .map(|c| [c[0] as u32, c[1] as u32, c[2] as u32, c[3] as u32])
        .collect();
    // Lumped masses: a quarter of each tetrahedron's mass at each of its nodes.
    let mut masses = vec![0.0; reference.len()];
    for t in &tets {
        let x = |i: usize| reference[t[i] as usize];
        let volume = ((x(1) - x(0)).cross(&(x(2) - x(0))))
            .dot(&(x(3) - x(0)))
            .abs()
            / 6.0;
        for &n in t {
            masses[n as usize] += DENSITY * volume / 4.0;
        }
    }
    let radius = 0.5 * cell;
    let mut world = PhysicsWorld::new();
    world.gravity = Vector::new(0.0, 0.0, -GRAVITY);
    world.integration_parameters.dt = dt;
    world.insert(
        RigidBodyBuilder::fixed().translation(Vector::new(0.0, 0.0, -0.5)),
        ColliderBuilder::cuboid(5.0, 5.0, 0.5),
    );
    let positions: Vec<Vector> = reference
        .iter()
        .map(|x| Vector::new(x.x, x.y, x.z + radius))
        .collect();
    let builder = SoftBodyBuilder::new(positions)
        .cells(tets)
        .masses(masses.clone())
        .material(SoftBodyMaterial {
            young_modulus: YOUNG,
            poisson_ratio: POISSON,
            ..Default::default()
        })
        .cell_model(SoftBodyCellModel::Corotational)
        .particle_radius(radius)
        .can_sleep(false)
        .solver(solver);
    let handle = world.insert_soft_body(builder);
    let mut depth = 0.0f64;
    let clock = Instant::now();
    let steps = (END / dt).round() as usize;
    for _ in 0..steps {
        world.step();
        let lowest = world.soft_bodies[handle]
            .particles()
            .iter()
            .map(|p| p.position().z)
            .fold(f64::INFINITY, f64::min);
        depth = depth.max(radius - lowest);
    }
    let wall = clock.elapsed().as_secs_f64() / END;
    let particles = world.soft_bodies[handle].particles();
    let heights: Vec<f64> = particles.iter().map(|p| p.position().z - radius).collect();
    let kinetic = particles
        .iter()
        .zip(&masses)
        .map(|(p, m)| 0.5 * m * p.velocity().length_squared())
        .sum();
    Outcome {
        label: format!("rapier {solver:?}"),
        result: Ok(wall),
        depth,
        sag: sag(&reference, &heights),
        kinetic,
    }
}

fn main() {
    let mut args = std::env::args().skip(1);
    let cells: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(6);
    let dt: f64 = args
        .next()
        .and_then(|a| a.parse().ok())
        .unwrap_or(1.0 / 60.0);
    let cell = SIZE / cells as f64;
    let mesh = softway::mesh::generators::cuboid(
        Vector3::new(0.0, 0.0, DROP),
        Vector3::new(SIZE, SIZE, DROP + SIZE),
        [cells; 3],
        ElementKind::Tet4,
    )
    .expect("a valid box");
    let tets = mesh.blocks[0].cells().len();
    println!(
        "soft cube: {} nodes, {tets} tetrahedra ({cells}^3 cubes), dt = {dt:.5} s, {END} s \
         simulated, one thread; reference sag rho g H^2 / (2 E) = {:.2} mm",
        mesh.nodes.len(),
        1e3 * DENSITY * GRAVITY * SIZE * SIZE / (2.0 * YOUNG)
    );
    let soft_way = ContactSettings {
        method: ContactMethod::SoftWay,
        penalty: 1e8,
        ..ContactSettings::default()
    };
    // Stiffness-proportional damping of 5 % of critical at the cube's first axial mode (the
    // quarter wave through its height, omega = pi c / (2 H)): rapier's bodies come to rest,
    // softway's undamped elastic cube keeps ringing.
    let omega = std::f64::consts::PI * (YOUNG / DENSITY).sqrt() / (2.0 * SIZE);
    let damped = 2.0 * 0.05 / omega;
    let outcomes = [
        softway_run(&mesh, dt, "softway soft way", soft_way.clone(), 0.0),
        softway_run(
            &mesh,
            dt,
            "softway soft way, secant",
            ContactSettings {
                penalty_force: PenaltyForce::Secant,
                gap_displacement: GapDisplacement::Trapezoid,
                ..soft_way.clone()
            },
            0.0,
        ),
        softway_run(
            &mesh,
            dt,
            "softway implicit projection",
            ContactSettings::default(),
            0.0,
        ),
        softway_run(&mesh, dt, "softway soft way, damped", soft_way, damped),
        softway_run(
            &mesh,
            dt,
            "softway implicit proj., damped",
            ContactSettings::default(),
            damped,
        ),
        rapier_run(&mesh, dt, cell, SoftBodySolver::Constraints),
        rapier_run(&mesh, dt, cell, SoftBodySolver::Fem),
    ];
    let base = outcomes[5].result.clone().ok();
    for o in &outcomes {
        let time = match &o.result {
            Ok(w) => match base {
                Some(b) => format!("{w:.3} s/s ({:.2}x rapier constraints)", w / b),
                None => format!("{w:.3} s/s"),
            },
            Err(e) => e.clone(),
        };
        println!(
            "  {:<30} {time}; deepest {:.2} mm; sag {:.2} mm; kinetic energy left {:.2e} J",
            o.label,
            1e3 * o.depth,
            1e3 * o.sag,
            o.kinetic
        );
    }
}
