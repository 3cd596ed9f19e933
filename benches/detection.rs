//! Contact detection per update on closed sphere surfaces of ~10k, ~100k and ~1M triangles,
//! every vertex moved by up to 0.17 mean edge lengths over the step (the motion of
//! `benches/compare/ipctk_candidates.py`), self-contact on, margin 0.
//!
//! `cargo bench --bench detection` runs criterion. `SOFTWAY_EXPORT_DIR=dir cargo bench --bench
//! detection` also writes `sphere_<n>_x0.obj` / `sphere_<n>_x1.obj` there for the ipctk script.
//! `SOFTWAY_BENCH_SIZES=29,91` restricts the sizes (cube-sphere subdivisions; 12 n^2 facets).

use std::hint::black_box;
use std::io::Write;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use nalgebra::Vector3;
use softway::contact::detection::{ContactSurface, DetectionOptions, Detector};
use softway::geometry::Aabb;

#[path = "common/sphere.rs"]
mod sphere;
use sphere::{cube_sphere, motion};

fn write_obj(path: &std::path::Path, x: &[Vector3<f64>], tris: &[[usize; 3]]) {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).expect("create obj"));
    for p in x {
        writeln!(f, "v {:.17e} {:.17e} {:.17e}", p.x, p.y, p.z).unwrap();
    }
    for t in tris {
        writeln!(f, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
    }
}

/// All-pairs node/facet box tests (facet boxes grown by `margin`), self-contact exclusion as
/// in the detector.
fn brute_force(
    surface: &ContactSurface<3>,
    x0: &[Vector3<f64>],
    x1: &[Vector3<f64>],
    margin: f64,
) -> usize {
    let boxes: Vec<Aabb<3>> = surface
        .facets()
        .iter()
        .map(|f| Aabb::from_points(f.iter().flat_map(|&v| [&x0[v], &x1[v]])).loosened(margin))
        .collect();
    let mut count = 0;
    for &n in surface.slaves() {
        let seg = Aabb {
            min: x0[n].inf(&x1[n]),
            max: x0[n].sup(&x1[n]),
        };
        for (f, b) in boxes.iter().enumerate() {
            if b.intersects(&seg) && !surface.is_excluded(n, f) {
                count += 1;
            }
        }
    }
    count
}

fn sizes() -> Vec<usize> {
    std::env::var("SOFTWAY_BENCH_SIZES")
        .ok()
        .map(|s| s.split(',').filter_map(|t| t.trim().parse().ok()).collect())
        .unwrap_or_else(|| vec![29, 91, 289])
}

fn bench(c: &mut Criterion) {
    let export = std::env::var_os("SOFTWAY_EXPORT_DIR").map(std::path::PathBuf::from);
    let mut group = c.benchmark_group("detection");
    group.sample_size(10);
    for n in sizes() {
        let (x0, tris) = cube_sphere(n);
        let x1 = motion(&x0, &tris, 0);
        let facets = tris.len();
        if let Some(dir) = &export {
            std::fs::create_dir_all(dir).unwrap();
            write_obj(&dir.join(format!("sphere_{facets}_x0.obj")), &x0, &tris);
            write_obj(&dir.join(format!("sphere_{facets}_x1.obj")), &x1, &tris);
        }
        let surface = ContactSurface::from_facets(std::slice::from_ref(&tris), &[0]);
        let options = DetectionOptions {
            self_contact: true,
            margin: 0.0,
            ..Default::default()
        };
        let mut det = Detector::new(surface.clone(), options);
        let t = Instant::now();
        det.update_candidates(&x0, &x1, &[], &[]);
        let first = t.elapsed();
        let candidates = det.candidates().len();
        let t = Instant::now();
        let pairs = det.pairs(&x1, &[]).len();
        let narrow = t.elapsed();
        println!(
            "sphere {facets} facets, {} nodes: first update (build) {:.1} ms, {candidates} candidates, \
             narrow phase {:.1} ms, {pairs} active pairs",
            x0.len(),
            first.as_secs_f64() * 1e3,
            narrow.as_secs_f64() * 1e3
        );
        group.bench_with_input(
            BenchmarkId::new("update_candidates", facets),
            &facets,
            |b, _| {
                b.iter(|| {
                    det.update_candidates(black_box(&x0), black_box(&x1), &[], &[]);
                    black_box(det.candidates().len())
                })
            },
        );
        // The narrow phase needs candidates: a margin of about 1.3 mean edge lengths gives some
        // 30 per node, a pessimistic contact zone covering the whole surface.
        let margin = 2.0 / n as f64;
        let mut wide = Detector::new(surface.clone(), DetectionOptions { margin, ..options });
        wide.update_candidates(&x0, &x1, &[], &[]);
        let wide_pairs = wide.pairs(&x1, &[]).len();
        println!(
            "  margin {margin:.4}: {} candidates, {wide_pairs} active pairs",
            wide.candidates().len()
        );
        group.bench_with_input(BenchmarkId::new("pairs_margin", facets), &facets, |b, _| {
            b.iter(|| black_box(wide.pairs(black_box(&x1), &[]).len()))
        });
        drop(wide);
        if facets <= 20_000 {
            // With margin 0 the two-ring exclusion leaves no candidate under this motion; a
            // margin of two mean edge lengths gives thousands to compare.
            let margin = 4.0 / n as f64;
            let mut wide = Detector::new(surface.clone(), DetectionOptions { margin, ..options });
            wide.update_candidates(&x0, &x1, &[], &[]);
            let count = brute_force(&surface, &x0, &x1, margin);
            assert_eq!(
                count,
                wide.candidates().len(),
                "the hierarchy misses no candidate"
            );
            println!("brute-force check with margin {margin:.3}: {count} candidates, equal");
            group.bench_with_input(BenchmarkId::new("brute_force", facets), &facets, |b, _| {
                b.iter(|| black_box(brute_force(&surface, &x0, &x1, 0.0)))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
