//! Element assembly of a 3D box of ~100k cells (Tet4 and Hex8) with 1 and 2 threads, and one
//! linear step of a smaller box after its one-time factorisation.
//!
//! Run: `cargo bench --bench assembly`. Figures for the 100k-cell step and factorisation:
//! `cargo run --release --example perf_report`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use nalgebra::Vector3;
use softway::assembly::{cell_values, BodyIntegration, CellTable, Pattern};
use softway::dim::Kinematics;
use softway::prelude::*;

fn box_mesh(kind: ElementKind, target_cells: usize) -> Mesh<3> {
    let per_cube = if kind == ElementKind::Tet4 { 6 } else { 1 };
    let n = ((target_cells / per_cube) as f64).cbrt().round() as usize;
    cuboid(
        Vector3::zeros(),
        Vector3::new(1.0, 1.0, 1.0),
        [n, n, n],
        kind,
    )
    .expect("valid box")
}

fn assembly(c: &mut Criterion) {
    let mut group = c.benchmark_group("assembly_100k");
    group.sample_size(10);
    let steel = LinearElastic::new(2.1e11, 0.3, 7800.0).expect("valid");
    let body = BodyIntegration::new(Kinematics::Solid, Material::LinearElastic(steel));
    for kind in [ElementKind::Tet4, ElementKind::Hex8] {
        let mesh = box_mesh(kind, 100_000);
        let mut table = CellTable::default();
        table.push_block(0, kind, &mesh.blocks[0].connectivity, 0);
        let pattern = Pattern::new::<3>(&table, mesh.nodes.len()).expect("pattern");
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool");
            group.bench_with_input(
                BenchmarkId::new(
                    format!("{}_{}_cells", kind.name(), mesh.cell_count()),
                    threads,
                ),
                &threads,
                |b, _| {
                    b.iter(|| {
                        pool.install(|| {
                            cell_values::<3>(
                                &table,
                                &pattern,
                                &mesh.nodes,
                                std::slice::from_ref(&body),
                            )
                        })
                    })
                },
            );
        }
    }
    group.finish();
}

fn linear_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("linear_step");
    group.sample_size(20);
    let mesh = box_mesh(ElementKind::Hex8, 8_000);
    let cells = mesh.cell_count();
    let steel = Material::LinearElastic(LinearElastic::new(2.1e11, 0.3, 7800.0).expect("valid"));
    let body = Body::new("box", mesh, steel)
        .with_velocity(Vector3::new(0.0, 0.0, -1.0))
        .with_constraint_in_box(
            Vector3::new(-1.0, -1.0, -1e-9),
            Vector3::new(2.0, 2.0, 1e-9),
            [Some(0.0); 3],
        );
    let mut sim = Simulation3::builder()
        .time_step(1e-5)
        .body(body)
        .build()
        .expect("valid");
    sim.step().expect("first step factorises");
    group.bench_function(format!("hex8_{cells}_cells"), |b| {
        b.iter(|| sim.step().expect("step"))
    });
    group.finish();
}

criterion_group!(benches, assembly, linear_step);
criterion_main!(benches);
