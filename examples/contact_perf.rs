//! Prints the cost of contact: a 3D box falls onto a rigid plane with the soft way; compares
//! the time of contact-free steps with steps in contact (median and mean), and the iterations.
//!
//! Run: `cargo run --release --example contact_perf [-- SCENE [CELLS_PER_EDGE] [--steps]]`
//! (`--steps`: a line per step, with its Newton iterations and factorisations) with SCENE
//! * `hex` (default): a 1 m Hex8 cube (20 cells per edge), E = 1e7 Pa, hitting at 1 m/s,
//!   zeta = 1e10 Pa/m, h = 1e-3 s;
//! * `peer`: the peer-figures cube (0.2 m, E = 1e5 Pa, nu = 0.3, rho = 1000 kg/m^3, 16 cubes
//!   per edge split into tetrahedra), arriving at 1.4 m/s (a 0.1 m drop), zeta = 1e8 Pa/m,
//!   h = 1e-3 s, 100 steps (the box leaves the plane after about 45).
//!
//! Then the memory the linear solver holds against the process's peak (Linux), and last the
//! wall time of the whole run (the first step included) per simulated second,
//! on the rayon pool's threads (`RAYON_NUM_THREADS=1` for one).

mod common;

use common::{mean, median};
use std::time::Instant;

use nalgebra::Vector3;
use softway::contact::{ContactMethod, ContactSettings, Obstacle, ObstacleShape};
use softway::prelude::*;

fn main() -> Result<()> {
    let scene = std::env::args().nth(1).unwrap_or_else(|| "hex".into());
    let cells_arg: Option<usize> = std::env::args().nth(2).and_then(|a| a.parse().ok());
    let (size, cells, kind, young, speed, penalty, steps) = match scene.as_str() {
        "peer" => (
            0.2,
            cells_arg.unwrap_or(16),
            ElementKind::Tet4,
            1e5,
            1.4,
            1e8,
            100,
        ),
        _ => (
            1.0,
            cells_arg.unwrap_or(20),
            ElementKind::Hex8,
            1e7,
            1.0,
            1e10,
            40,
        ),
    };
    let gap = 0.01 * size;
    let mesh = cuboid(
        Vector3::new(0.0, 0.0, gap),
        Vector3::new(size, size, size + gap),
        [cells; 3],
        kind,
    )?;
    let cell_count = mesh.cell_count();
    let material = Material::LinearElastic(LinearElastic::new(young, 0.3, 1000.0)?);
    let plane = Obstacle::new(
        "ground",
        ObstacleShape::Halfspace {
            point: Vector3::zeros(),
            normal: Vector3::new(0.0, 0.0, 1.0),
        },
    );
    let mut sim = Simulation3::builder()
        .time_step(1e-3)
        .gravity(Vector3::new(0.0, 0.0, -9.81))
        .body(Body::new("box", mesh, material).with_velocity(Vector3::new(0.0, 0.0, -speed)))
        .obstacle(plane)
        .contact(ContactSettings {
            method: ContactMethod::SoftWay,
            penalty,
            ..ContactSettings::default()
        })
        .build()?;
    let (mut free, mut contact, mut iterations) = (Vec::new(), Vec::new(), Vec::new());
    // Factorisations in contact-free and in contact steps.
    let mut factorisations = [0, 0];
    let per_step = std::env::args().any(|a| a == "--steps");
    let run = Instant::now();
    let t = Instant::now();
    sim.step()?; // the one-time analysis and factorisation
    let first = t.elapsed().as_secs_f64();
    let peak_after_first = common::peak_resident_bytes();
    for _ in 0..steps {
        let t = Instant::now();
        let r = sim.step()?;
        let dt = t.elapsed().as_secs_f64();
        if per_step {
            println!(
                "step {}: {dt:.3} s, {} Newton iterations, {} active contacts, {} factorisations",
                r.step, r.iterations, r.active_contacts, r.factorisations
            );
        }
        factorisations[usize::from(r.active_contacts > 0)] += r.factorisations;
        if r.active_contacts > 0 {
            contact.push(dt);
            iterations.push(r.iterations as f64);
        } else {
            free.push(dt);
        }
    }
    let wall = run.elapsed().as_secs_f64();
    let (f, c) = (median(free.clone()), median(contact.clone()));
    println!(
        "{scene}: {cell_count} {kind:?} cells, {} unknowns; first step {first:.3} s",
        sim.node_count() * 3,
    );
    println!(
        "contact-free steps: {} (median {f:.4} s, mean {:.4} s; {} factorisations)",
        free.len(),
        mean(&free),
        factorisations[0]
    );
    println!(
        "contact steps: {} (median {c:.4} s, mean {:.4} s; Newton iterations median {:.1}, mean {:.2}; {} factorisations)",
        contact.len(),
        mean(&contact),
        median(iterations.clone()),
        mean(&iterations),
        factorisations[1]
    );
    println!(
        "ratio contact / contact-free: median {:.2}, mean {:.2}",
        c / f,
        mean(&contact) / mean(&free)
    );
    println!("{}", common::memory_line(&sim.solver_memory()));
    if let Some(peak) = peak_after_first {
        println!(
            "peak resident after the first step (contact-free factor only): {:.1} MiB",
            peak as f64 / (1024.0 * 1024.0)
        );
    }
    let simulated = sim.state().time;
    println!(
        "wall {wall:.2} s for {simulated:.3} s simulated ({} steps, {} rayon threads): {:.1} wall s per simulated s",
        steps + 1,
        rayon::current_num_threads(),
        wall / simulated
    );
    Ok(())
}
