//! Prints the speed figures of the foundation: assembly of a ~100k-cell 3D box (Tet4 and
//! Hex8) with 1 and 2 threads, the one-time factorisation and one linear step of the Hex8 box,
//! and the memory the solver holds against the process's peak.
//!
//! Run: `cargo run --release --example perf_report [-- CELLS]` (default 100000).

mod common;

use common::median;
use std::time::Instant;

use nalgebra::Vector3;
use softway::assembly::{cell_values, BodyIntegration, CellTable, Pattern};
use softway::contact::{ContactSurface, DetectionOptions, Detector, Obstacle, ObstacleShape};
use softway::dim::Kinematics;
use softway::prelude::*;

fn main() -> Result<()> {
    let target: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(100_000);
    let steel = LinearElastic::new(2.1e11, 0.3, 7800.0)?;
    let integration = BodyIntegration::new(Kinematics::Solid, Material::LinearElastic(steel));
    println!(
        "machine: {} logical cores",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    for kind in [ElementKind::Tet4, ElementKind::Hex8] {
        let per_cube = if kind == ElementKind::Tet4 { 6 } else { 1 };
        let n = ((target / per_cube) as f64).cbrt().round() as usize;
        let mesh = cuboid(
            Vector3::zeros(),
            Vector3::new(1.0, 1.0, 1.0),
            [n, n, n],
            kind,
        )?;
        let mut table = CellTable::default();
        table.push_block(0, kind, &mesh.blocks[0].connectivity, 0);
        let t = Instant::now();
        let pattern = Pattern::new::<3>(&table, mesh.nodes.len())?;
        let pattern_s = t.elapsed().as_secs_f64();
        let mut medians = Vec::new();
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool");
            let times: Vec<f64> = (0..5)
                .map(|_| {
                    let t = Instant::now();
                    let v = pool.install(|| {
                        cell_values::<3>(
                            &table,
                            &pattern,
                            &mesh.nodes,
                            std::slice::from_ref(&integration),
                        )
                    });
                    std::hint::black_box(v);
                    t.elapsed().as_secs_f64()
                })
                .collect();
            medians.push(median(times));
        }
        println!(
            "{}: {} cells, {} nodes; pattern (once) {:.3} s; element assembly median of 5: 1 thread {:.3} s, 2 threads {:.3} s, speed-up {:.2}",
            kind.name(),
            mesh.cell_count(),
            mesh.nodes.len(),
            pattern_s,
            medians[0],
            medians[1],
            medians[0] / medians[1]
        );
    }

    let n = (target as f64).cbrt().round() as usize;
    let mesh = cuboid(
        Vector3::zeros(),
        Vector3::new(1.0, 1.0, 1.0),
        [n, n, n],
        ElementKind::Hex8,
    )?;
    let cells = mesh.cell_count();
    let body = Body::new("box", mesh, Material::LinearElastic(steel))
        .with_velocity(Vector3::new(0.0, 0.0, -1.0))
        .with_constraint_in_box(
            Vector3::new(-1.0, -1.0, -1e-9),
            Vector3::new(2.0, 2.0, 1e-9),
            [Some(0.0); 3],
        );
    let t = Instant::now();
    let mut sim = Simulation3::builder().time_step(1e-5).body(body).build()?;
    let build_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    sim.step()?; // includes the symbolic analysis and the numeric factorisation
    let first_s = t.elapsed().as_secs_f64();
    let steps: Vec<f64> = (0..10)
        .map(|_| {
            let t = Instant::now();
            sim.step().expect("step");
            t.elapsed().as_secs_f64()
        })
        .collect();
    let step_s = median(steps);
    // Before the detection below, whose hierarchy is not the solver's.
    let memory = common::memory_line(&sim.solver_memory());
    // Detection on the same box against a plane under it: one update of the swept candidates
    // and one narrow phase, as every Newton iteration of a contact step does.
    let surface = ContactSurface::from_bodies(&[&sim.bodies()[0].mesh], &[0]);
    let mut detector = Detector::new(
        surface,
        DetectionOptions {
            margin: 0.01,
            facing: true,
            ..Default::default()
        },
    );
    let plane = Obstacle::new(
        "ground",
        ObstacleShape::Halfspace {
            point: Vector3::new(0.0, 0.0, -0.005),
            normal: Vector3::new(0.0, 0.0, 1.0),
        },
    );
    let x0 = sim.positions();
    let x1: Vec<Vector3<f64>> = x0
        .iter()
        .map(|x| x - Vector3::new(0.0, 0.0, 0.01))
        .collect();
    let obstacles = vec![plane];
    let detection: Vec<f64> = (0..10)
        .map(|_| {
            let t = Instant::now();
            detector.update_candidates(&x0, &x1, &obstacles, &[Vector3::zeros()]);
            std::hint::black_box(detector.pairs(&x1, &obstacles));
            t.elapsed().as_secs_f64()
        })
        .collect();
    let detection_s = median(detection);
    println!(
        "hex8 linear step: {cells} cells, {} unknowns; build (assembly of K and M) {:.3} s; first step (analysis + factorisation + solve) {:.3} s; later steps median of 10: {:.4} s",
        sim.node_count() * 3,
        build_s,
        first_s,
        step_s
    );
    println!("{memory}");
    println!(
        "detection on that box (surface of {} facets) against a plane: median of 10 {:.4} s = {:.1} % of a linear step",
        detector.surface().facets().len(),
        detection_s,
        100.0 * detection_s / step_s
    );
    Ok(())
}
