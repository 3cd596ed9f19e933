//! Prints the cost of contact: a 3D box (Hex8) falls onto a rigid plane with the soft way;
//! compares the median time of contact-free steps with steps in contact, and the iterations.
//!
//! Run: `cargo run --release --example contact_perf [-- CELLS_PER_EDGE]` (default 20).

use std::time::Instant;

use nalgebra::Vector3;
use softway::contact::{ContactMethod, ContactSettings, Obstacle, ObstacleShape};
use softway::prelude::*;

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> Result<()> {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(20);
    let mesh = cuboid(
        Vector3::new(0.0, 0.0, 0.01),
        Vector3::new(1.0, 1.0, 1.01),
        [n, n, n],
        ElementKind::Hex8,
    )?;
    let cells = mesh.cell_count();
    let rubber = Material::LinearElastic(LinearElastic::new(1e7, 0.3, 1000.0)?);
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
        .body(Body::new("box", mesh, rubber).with_velocity(Vector3::new(0.0, 0.0, -1.0)))
        .obstacle(plane)
        .contact(ContactSettings {
            method: ContactMethod::SoftWay,
            penalty: 1e10,
            ..ContactSettings::default()
        })
        .build()?;
    let (mut free, mut contact, mut iterations) = (Vec::new(), Vec::new(), Vec::new());
    let t = Instant::now();
    sim.step()?; // the one-time factorisation
    let first = t.elapsed().as_secs_f64();
    for _ in 0..40 {
        let t = Instant::now();
        let r = sim.step()?;
        let dt = t.elapsed().as_secs_f64();
        if r.active_contacts > 0 {
            contact.push(dt);
            iterations.push(r.iterations as f64);
        } else {
            free.push(dt);
        }
    }
    let (f, c) = (median(free.clone()), median(contact.clone()));
    println!(
        "hex8 box {cells} cells, {} unknowns: first step {first:.3} s; contact-free steps: {} (median {f:.4} s); contact steps: {} (median {c:.4} s, {:.1} iterations); ratio {:.2}",
        sim.node_count() * 3,
        free.len(),
        contact.len(),
        median(iterations),
        c / f
    );
    Ok(())
}
