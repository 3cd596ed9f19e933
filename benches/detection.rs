//! Contact detection per update on closed sphere surfaces of ~10k, ~100k and ~1M triangles,
//! every vertex moved by up to 0.17 mean edge lengths over the step (the motion of
//! `benches/compare/ipctk_candidates.py`), self-contact on, margin 0.
//!
//! `cargo bench --bench detection` runs criterion. `SOFTWAY_EXPORT_DIR=dir cargo bench --bench
//! detection` also writes `sphere_<n>_x0.obj` / `sphere_<n>_x1.obj` there for the ipctk script.
//! `SOFTWAY_BENCH_SIZES=29,91` restricts the sizes (cube-sphere subdivisions; 12 n^2 facets).

use std::collections::HashMap;
use std::hint::black_box;
use std::io::Write;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use nalgebra::Vector3;
use softway::contact::detection::{ContactSurface, DetectionOptions, Detector};
use softway::geometry::Aabb;

/// A cube subdivided `n x n` per face, projected on the unit sphere: 12 n^2 outward triangles.
fn cube_sphere(n: usize) -> (Vec<Vector3<f64>>, Vec<[usize; 3]>) {
    let mut index: HashMap<[usize; 3], usize> = HashMap::new();
    let mut nodes = Vec::new();
    let mut id = |p: [usize; 3], nodes: &mut Vec<Vector3<f64>>| {
        *index.entry(p).or_insert_with(|| {
            let v = Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64) * (2.0 / n as f64)
                - Vector3::repeat(1.0);
            nodes.push(v.normalize());
            nodes.len() - 1
        })
    };
    let mut tris = Vec::new();
    for axis in 0..3 {
        for side in [0, n] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for i in 0..n {
                for j in 0..n {
                    let corner = |a: usize, b: usize| {
                        let mut p = [0; 3];
                        p[axis] = side;
                        p[u] = a;
                        p[v] = b;
                        p
                    };
                    let q = [
                        id(corner(i, j), &mut nodes),
                        id(corner(i + 1, j), &mut nodes),
                        id(corner(i + 1, j + 1), &mut nodes),
                        id(corner(i, j + 1), &mut nodes),
                    ];
                    for t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
                        let (a, b, c) = (nodes[t[0]], nodes[t[1]], nodes[t[2]]);
                        let outward = (b - a).cross(&(c - a)).dot(&(a + b + c)) > 0.0;
                        tris.push(if outward { t } else { [t[0], t[2], t[1]] });
                    }
                }
            }
        }
    }
    (nodes, tris)
}

/// A deterministic pseudo-random number in [-1, 1) from an integer (splitmix64).
fn hash_unit(mut z: u64) -> f64 {
    z = z.wrapping_add(0x9E3779B97F4A7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// Every vertex moved by up to 0.17 mean edge lengths in a pseudo-random direction.
fn motion(x0: &[Vector3<f64>], tris: &[[usize; 3]]) -> Vec<Vector3<f64>> {
    let mean_edge = tris
        .iter()
        .map(|t| {
            (0..3)
                .map(|k| (x0[t[k]] - x0[t[(k + 1) % 3]]).norm())
                .sum::<f64>()
        })
        .sum::<f64>()
        / (3 * tris.len()) as f64;
    x0.iter()
        .enumerate()
        .map(|(i, x)| {
            let d = Vector3::from_fn(|k, _| hash_unit((3 * i + k) as u64));
            // d lies in the unit cube: scale so that |d| <= 1 holds.
            x + d * (0.17 * mean_edge / 3f64.sqrt())
        })
        .collect()
}

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
        let x1 = motion(&x0, &tris);
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
