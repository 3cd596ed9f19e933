//! Property tests of the mesh generators (issue 14): random valid parameters (seeded ChaCha8,
//! lengths from 1e-3 to 1e3 m) for `rectangle`, `cuboid`, `annulus`, `polygon` and `extrude`,
//! every element kind each takes. For every mesh:
//!
//! * every cell has a positive Jacobian at its quadrature points and corners
//!   (`check_quality`), and the topology is valid;
//! * the total volume (`measure`) equals the analytic area or volume (a rectangle's, a box's,
//!   the inscribed polygon ring of an annulus, a convex quadrilateral's, base times height);
//! * the boundary is closed and outward: in 2D every boundary node starts one boundary segment
//!   and ends one, in 3D every directed boundary edge is matched by its reverse, and the
//!   volume the boundary encloses (divergence theorem, `sum x . n dS / D`) equals the cells'.

use nalgebra::{Vector2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use softway::dim::{Dim, SpatialDim};
use softway::element::ElementKind;
use softway::mesh::generators::{annulus, cuboid, extrude, measure, polygon, rectangle};
use softway::mesh::Mesh;
use std::collections::BTreeMap;
use std::f64::consts::PI;

const CASES: usize = 150;

/// A length between 1e-3 and 1e3 m, log-uniform.
fn length(rng: &mut ChaCha8Rng) -> f64 {
    10f64.powf(rng.random_range(-3.0..3.0))
}

fn cells(rng: &mut ChaCha8Rng, max: usize) -> usize {
    rng.random_range(1..=max)
}

/// The volume the boundary encloses, `sum_facets x . n dS / D` (outward facets), and whether
/// the boundary is closed.
fn enclosed<const D: usize>(mesh: &Mesh<D>) -> (f64, Result<(), String>)
where
    Dim<D>: SpatialDim<D>,
{
    let facets = mesh.boundary_facets();
    // About the bounding box's centre: less cancellation far from the origin.
    let (lo, hi) = mesh.bounding_box();
    let centre = (lo + hi) / 2.0;
    let x = |n: usize| mesh.nodes[n] - centre;
    let mut volume = 0.0;
    let mut closed = Ok(());
    if D == 2 {
        // Counter-clockwise boundary: the segment a -> b adds (a x b) / 2.
        let mut degree: BTreeMap<usize, (i32, i32)> = BTreeMap::new();
        for f in &facets {
            let (a, b) = (x(f[0]), x(f[1]));
            volume += 0.5 * (a[0] * b[1] - a[1] * b[0]);
            degree.entry(f[0]).or_default().0 += 1;
            degree.entry(f[1]).or_default().1 += 1;
        }
        if let Some((n, d)) = degree.iter().find(|(_, (o, i))| o != i) {
            closed = Err(format!(
                "node {n}: {} outgoing, {} incoming segments",
                d.0, d.1
            ));
        }
    } else {
        let mut edges: BTreeMap<(usize, usize), i32> = BTreeMap::new();
        for f in &facets {
            let (a, b, c) = (x(f[0]), x(f[1]), x(f[2]));
            let (a, b, c) = (
                Vector3::new(a[0], a[1], a[2]),
                Vector3::new(b[0], b[1], b[2]),
                Vector3::new(c[0], c[1], c[2]),
            );
            volume += a.dot(&b.cross(&c)) / 6.0;
            for (p, q) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
                *edges.entry((p, q)).or_default() += 1;
            }
        }
        for (&(p, q), &k) in &edges {
            if k != 1 || edges.get(&(q, p)) != Some(&1) {
                closed = Err(format!("edge {p} -> {q} is not matched by its reverse"));
                break;
            }
        }
    }
    (volume, closed)
}

/// The checks common to every generated mesh, against the analytic volume `exact`.
fn check<const D: usize>(what: &str, mesh: &Mesh<D>, exact: f64)
where
    Dim<D>: SpatialDim<D>,
{
    mesh.validate_topology("generated")
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    mesh.check_quality("generated")
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    // Round-off: the nodes carry eps |x| each, relative to the mesh's smallest extent.
    let (lo, hi) = mesh.bounding_box();
    let far = lo.abs().max().max(hi.abs().max());
    let extent = (hi - lo).min();
    let tolerance = 1e-12 + 200.0 * f64::EPSILON * far / extent;
    let volume = measure(mesh);
    assert!(
        (volume - exact).abs() <= tolerance * exact,
        "{what}: volume {volume:e}, analytic {exact:e} (tolerance {tolerance:e})"
    );
    let (bounded, closed) = enclosed(mesh);
    closed.unwrap_or_else(|e| panic!("{what}: boundary not closed: {e}"));
    assert!(
        (bounded - volume).abs() <= tolerance * volume,
        "{what}: the boundary encloses {bounded:e}, the cells {volume:e} (tolerance \
         {tolerance:e})"
    );
}

#[test]
fn rectangles_and_boxes() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for case in 0..CASES {
        let min = Vector2::new(rng.random_range(-1e3..1e3), rng.random_range(-1e3..1e3));
        let size = Vector2::new(length(&mut rng), length(&mut rng));
        let n = [cells(&mut rng, 12), cells(&mut rng, 12)];
        for kind in [ElementKind::Tri3, ElementKind::Quad4] {
            let m = rectangle(min, min + size, n, kind).unwrap();
            check(
                &format!("case {case}: rectangle {min:?} + {size:?}, {n:?} {kind:?}"),
                &m,
                size.x * size.y,
            );
        }
        let min3 = Vector3::new(min.x, min.y, rng.random_range(-1e3..1e3));
        let size3 = Vector3::new(size.x, size.y, length(&mut rng));
        let n3 = [cells(&mut rng, 5), cells(&mut rng, 5), cells(&mut rng, 5)];
        for kind in [ElementKind::Tet4, ElementKind::Hex8] {
            let m = cuboid(min3, min3 + size3, n3, kind).unwrap();
            check(
                &format!("case {case}: box {min3:?} + {size3:?}, {n3:?} {kind:?}"),
                &m,
                size3.x * size3.y * size3.z,
            );
        }
    }
}

#[test]
fn annuli() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for case in 0..CASES {
        let center = Vector2::new(rng.random_range(-1e3..1e3), rng.random_range(-1e3..1e3));
        let inner = length(&mut rng);
        let outer = inner * (1.0 + 10f64.powf(rng.random_range(-2.0..1.0)));
        let n = [rng.random_range(3..=48), cells(&mut rng, 6)];
        // Straight-sided cells: the ring between two inscribed regular polygons.
        let exact =
            0.5 * n[0] as f64 * (2.0 * PI / n[0] as f64).sin() * (outer * outer - inner * inner);
        for kind in [ElementKind::Tri3, ElementKind::Quad4] {
            let m = annulus(center, inner, outer, n, kind).unwrap();
            check(
                &format!("case {case}: annulus {center:?}, {inner:e} to {outer:e}, {n:?} {kind:?}"),
                &m,
                exact,
            );
        }
    }
}

/// Convex polygons with their vertices on a circle; a quadrilateral's area is meshed exactly,
/// more vertices than the four corners of the mapping are cut by chords (area at most the
/// polygon's).
#[test]
fn convex_polygons() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for case in 0..CASES {
        let center = Vector2::new(rng.random_range(-1e3..1e3), rng.random_range(-1e3..1e3));
        let radius = length(&mut rng);
        let count = if case % 2 == 0 {
            4
        } else {
            rng.random_range(4..=12)
        };
        // Angles at least 0.2 rad apart, counter-clockwise or clockwise.
        let mut angles: Vec<f64> = Vec::new();
        while angles.len() < count {
            let a = rng.random_range(0.0..2.0 * PI);
            let gap = |b: &f64| {
                let d = (a - b).abs();
                d.min(2.0 * PI - d)
            };
            if angles.iter().all(|b| gap(b) > 0.2) {
                angles.push(a);
            }
        }
        angles.sort_by(f64::total_cmp);
        if rng.random_bool(0.5) {
            angles.reverse();
        }
        let vertices: Vec<Vector2<f64>> = angles
            .iter()
            .map(|a| center + radius * Vector2::new(a.cos(), a.sin()))
            .collect();
        // About the centre: the absolute coordinates (up to 1e3 m) cancel.
        let shoelace = (0..count)
            .map(|i| (vertices[i] - center).perp(&(vertices[(i + 1) % count] - center)))
            .sum::<f64>()
            .abs()
            / 2.0;
        let n = [cells(&mut rng, 10), cells(&mut rng, 10)];
        for kind in [ElementKind::Tri3, ElementKind::Quad4] {
            let what = format!("case {case}: polygon {vertices:?}, {n:?} {kind:?}");
            let m = polygon(&vertices, n, kind).unwrap();
            let volume = measure(&m);
            if count == 4 {
                check(&what, &m, shoelace);
            } else {
                assert!(
                    volume <= shoelace * (1.0 + 1e-10),
                    "{what}: {volume:e} > {shoelace:e}"
                );
                check(&what, &m, volume);
            }
        }
    }
}

#[test]
fn extrusions() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for case in 0..CASES {
        let inner = length(&mut rng);
        let outer = inner * (1.0 + 10f64.powf(rng.random_range(-2.0..1.0)));
        let n = [rng.random_range(3..=16), cells(&mut rng, 3)];
        let base = annulus(Vector2::zeros(), inner, outer, n, ElementKind::Quad4).unwrap();
        let z0 = rng.random_range(-1e3..1e3);
        let height = length(&mut rng);
        let layers = cells(&mut rng, 4);
        let exact = measure(&base) * height;
        for kind in [ElementKind::Tet4, ElementKind::Hex8] {
            let m = extrude(&base, z0, z0 + height, layers, kind).unwrap();
            check(
                &format!("case {case}: annulus {inner:e}..{outer:e} {n:?} extruded {z0:e} + {height:e} in {layers} {kind:?}"),
                &m,
                exact,
            );
        }
    }
}

/// Found by `extrusions` (case 61: a thin annulus extruded 138 m): `check_quality` called
/// cells degenerate against the whole mesh's size; a long mesh of good cells is valid.
#[test]
fn long_meshes_of_small_cells_are_not_degenerate() {
    let bar = cuboid(
        Vector3::zeros(),
        Vector3::new(1000.0, 0.01, 0.01),
        [1000, 1, 1],
        ElementKind::Hex8,
    )
    .unwrap();
    check("1 km bar of 1 m x 1 cm x 1 cm cells", &bar, 0.1);
    let strip = rectangle(
        Vector2::zeros(),
        Vector2::new(1e4, 1e-3),
        [2000, 1],
        ElementKind::Quad4,
    )
    .unwrap();
    check("10 km strip of 5 m x 1 mm cells", &strip, 10.0);
}
