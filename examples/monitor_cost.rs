//! Prints what the run monitors' geometric checks cost against a step: the soft cube of the
//! peer comparisons (0.2 m, E = 1e5 Pa, 5 % stiffness damping) dropped on a floor at
//! h = 1/60 s with the default contact settings, Tet4 or Hex8, `n` cells per edge; after
//! 60 steps (1 s, the cube resting) the median time of a step and of each check:
//! `Simulation::inverted_cell` (a cell turned inside out), `fell_through` and `tunnelled`
//! (the last two cost nothing here: the floor is a half-space).
//!
//! Run: `RAYON_NUM_THREADS=1 cargo run --release --example monitor_cost [-- CELLS...]`
//! (default 6 10 16).

mod common;

use std::time::Instant;

use common::median;
use nalgebra::Vector3;
use softway::contact::ObstacleShape;
use softway::prelude::*;

/// The median wall time of `f` over `runs` calls (s).
fn timed(runs: usize, mut f: impl FnMut()) -> f64 {
    median(
        (0..runs)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64()
            })
            .collect(),
    )
}

fn main() -> Result<()> {
    let sizes: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let sizes = if sizes.is_empty() {
        vec![6, 10, 16]
    } else {
        sizes
    };
    for kind in [ElementKind::Tet4, ElementKind::Hex8] {
        for &n in &sizes {
            let mesh = cuboid(
                Vector3::new(0.0, 0.0, 0.1),
                Vector3::new(0.2, 0.2, 0.3),
                [n, n, n],
                kind,
            )?;
            let rubber = Material::LinearElastic(LinearElastic::new(1e5, 0.3, 1000.0)?);
            let floor = ObstacleShape::Halfspace {
                point: Vector3::zeros(),
                normal: Vector3::z(),
            };
            let mut sim = Simulation3::builder()
                .time_step(1.0 / 60.0)
                .gravity(Vector3::new(0.0, 0.0, -9.81))
                .body(Body::new("cube", mesh, rubber).with_damping(0.0, 1.27e-3))
                .obstacle(Obstacle::new("floor", floor))
                .build()?;
            for _ in 0..60 {
                sim.step()?;
            }
            let mut failed = None;
            let step = timed(10, || {
                if let Err(e) = sim.step() {
                    failed = Some(e);
                }
            });
            if let Some(e) = failed {
                return Err(e);
            }
            let inverted = timed(50, || assert!(sim.inverted_cell().is_none()));
            let fell = timed(50, || assert!(sim.fell_through().is_none()));
            let tunnelled = timed(50, || assert!(sim.tunnelled().is_none()));
            println!(
                "{kind:?} {n}^3 ({} nodes): step {:.3} ms; inverted_cell {:.4} ms ({:.2} %), \
                 fell_through {:.4} ms, tunnelled {:.4} ms",
                (n + 1).pow(3),
                step * 1e3,
                inverted * 1e3,
                100.0 * inverted / step,
                fell * 1e3,
                tunnelled * 1e3
            );
        }
    }
    Ok(())
}
