//! Structured mesh generators: `rectangle`, `box` ([`cuboid`]), `annulus`, `polygon`, and the
//! extrusion of a 2D quadrilateral mesh into 3D.
//!
//! Every generated cell is positively oriented (checked and fixed at the cell centre).

use nalgebra::{SVector, Vector2, Vector3};

use super::Mesh;
use crate::dim::{Dim, SpatialDim};
use crate::element::ElementKind;
use crate::error::{Error, Result};

fn invalid(name: &str, found: impl std::fmt::Display, expected: &str) -> Error {
    Error::InvalidParameter {
        name: name.to_string(),
        found: found.to_string(),
        expected: expected.to_string(),
    }
}

fn check_cells<const N: usize>(cells: [usize; N]) -> Result<()> {
    if cells.contains(&0) {
        return Err(invalid(
            "cells",
            format!("{cells:?}"),
            "at least 1 cell in every direction",
        ));
    }
    Ok(())
}

/// A structured grid of quadrilaterals from a map of the unit square; `grid[j][i]` is the
/// node at `(i / nu, j / nv)`.
fn quad_grid(
    nu: usize,
    nv: usize,
    map: impl Fn(f64, f64) -> Vector2<f64>,
    kind: ElementKind,
    periodic_u: bool,
) -> Result<Mesh<2>> {
    let columns = if periodic_u { nu } else { nu + 1 };
    let mut nodes = Vec::with_capacity(columns * (nv + 1));
    for j in 0..=nv {
        for i in 0..columns {
            nodes.push(map(i as f64 / nu as f64, j as f64 / nv as f64));
        }
    }
    let id = |i: usize, j: usize| j * columns + (i % columns);
    let mut conn = Vec::new();
    for j in 0..nv {
        for i in 0..nu {
            let q = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
            match kind {
                ElementKind::Quad4 => conn.extend_from_slice(&q),
                ElementKind::Tri3 => {
                    // Alternate the diagonal so the grid has no preferred direction.
                    if (i + j) % 2 == 0 {
                        conn.extend_from_slice(&[q[0], q[1], q[2], q[0], q[2], q[3]]);
                    } else {
                        conn.extend_from_slice(&[q[0], q[1], q[3], q[1], q[2], q[3]]);
                    }
                }
                other => {
                    return Err(invalid("element", other.name(), "tri3 or quad4 in 2D"));
                }
            }
        }
    }
    let mut mesh = Mesh::new(nodes, kind, conn);
    orient_cells(&mut mesh);
    Ok(mesh)
}

/// Reverses every cell whose Jacobian is negative at its centre.
fn orient_cells<const D: usize>(mesh: &mut Mesh<D>)
where
    Dim<D>: SpatialDim<D>,
{
    for b in 0..mesh.blocks.len() {
        let kind = mesh.blocks[b].kind;
        let n = kind.nodes();
        let centre = match kind {
            ElementKind::Tri3 => [1.0 / 3.0, 1.0 / 3.0, 0.0],
            ElementKind::Tet4 => [0.25; 3],
            _ => [0.0; 3],
        };
        let flip: &[usize] = match kind {
            ElementKind::Tri3 => &[0, 2, 1],
            ElementKind::Quad4 => &[0, 3, 2, 1],
            ElementKind::Tet4 => &[0, 2, 1, 3],
            ElementKind::Hex8 => &[0, 3, 2, 1, 4, 7, 6, 5],
        };
        for c in 0..mesh.blocks[b].len() {
            let cell: Vec<usize> = mesh.blocks[b].cell(c).to_vec();
            let j = mesh.jacobian(kind, &cell, centre);
            if <Dim<D>>::det(&j) < 0.0 {
                let conn = &mut mesh.blocks[b].connectivity[c * n..(c + 1) * n];
                for (slot, &from) in flip.iter().enumerate() {
                    conn[slot] = cell[from];
                }
            }
        }
    }
}

/// The rectangle `[min, max]` divided into `cells = [nx, ny]` quadrilaterals (or twice as many
/// triangles).
pub fn rectangle(
    min: Vector2<f64>,
    max: Vector2<f64>,
    cells: [usize; 2],
    kind: ElementKind,
) -> Result<Mesh<2>> {
    check_cells(cells)?;
    if (0..2).any(|k| max[k] <= min[k]) {
        return Err(invalid(
            "max",
            format!("{max:?} with min {min:?}"),
            "max > min componentwise",
        ));
    }
    let d = max - min;
    quad_grid(
        cells[0],
        cells[1],
        |u, v| min + Vector2::new(u * d.x, v * d.y),
        kind,
        false,
    )
}

/// The box `[min, max]` divided into `cells = [nx, ny, nz]` hexahedra (or six tetrahedra each).
pub fn cuboid(
    min: Vector3<f64>,
    max: Vector3<f64>,
    cells: [usize; 3],
    kind: ElementKind,
) -> Result<Mesh<3>> {
    check_cells(cells)?;
    if (0..3).any(|k| max[k] <= min[k]) {
        return Err(invalid(
            "max",
            format!("{max:?} with min {min:?}"),
            "max > min componentwise",
        ));
    }
    let base = rectangle(
        Vector2::new(min.x, min.y),
        Vector2::new(max.x, max.y),
        [cells[0], cells[1]],
        ElementKind::Quad4,
    )?;
    extrude(&base, min.z, max.z, cells[2], kind)
}

/// Extrudes a 2D quadrilateral mesh along z from `z0` to `z1` in `layers` layers of hexahedra
/// (or six tetrahedra per hexahedron, a conforming Kuhn split).
pub fn extrude(
    base: &Mesh<2>,
    z0: f64,
    z1: f64,
    layers: usize,
    kind: ElementKind,
) -> Result<Mesh<3>> {
    check_cells([layers])?;
    if z1 <= z0 {
        return Err(invalid("length", z1 - z0, "a positive extrusion length"));
    }
    if base.blocks.iter().any(|b| b.kind != ElementKind::Quad4) {
        return Err(invalid(
            "element",
            "tri3 base",
            "a quad4 base mesh to extrude",
        ));
    }
    let nb = base.nodes.len();
    let mut nodes = Vec::with_capacity(nb * (layers + 1));
    for l in 0..=layers {
        let z = z0 + (z1 - z0) * l as f64 / layers as f64;
        nodes.extend(base.nodes.iter().map(|p| Vector3::new(p.x, p.y, z)));
    }
    // Kuhn paths from corner 0 to corner 6 of the hexahedron.
    const KUHN: [[usize; 4]; 6] = [
        [0, 1, 2, 6],
        [0, 1, 5, 6],
        [0, 3, 2, 6],
        [0, 3, 7, 6],
        [0, 4, 5, 6],
        [0, 4, 7, 6],
    ];
    let mut conn = Vec::new();
    for l in 0..layers {
        for q in base.blocks.iter().flat_map(|b| b.cells()) {
            let mut hex = [0usize; 8];
            for a in 0..4 {
                hex[a] = q[a] + l * nb;
                hex[a + 4] = q[a] + (l + 1) * nb;
            }
            match kind {
                ElementKind::Hex8 => conn.extend_from_slice(&hex),
                ElementKind::Tet4 => {
                    for path in KUHN {
                        conn.extend(path.iter().map(|&a| hex[a]));
                    }
                }
                other => return Err(invalid("element", other.name(), "tet4 or hex8 in 3D")),
            }
        }
    }
    let mut mesh = Mesh::new(nodes, kind, conn);
    orient_cells(&mut mesh);
    Ok(mesh)
}

/// A ring between `inner_radius` and `outer_radius` around `center`, `cells = [around,
/// through]`.
pub fn annulus(
    center: Vector2<f64>,
    inner_radius: f64,
    outer_radius: f64,
    cells: [usize; 2],
    kind: ElementKind,
) -> Result<Mesh<2>> {
    check_cells(cells)?;
    if !(inner_radius > 0.0 && outer_radius > inner_radius) {
        return Err(invalid(
            "outer_radius",
            format!("inner {inner_radius}, outer {outer_radius}"),
            "0 < inner_radius < outer_radius",
        ));
    }
    if cells[0] < 3 {
        return Err(invalid(
            "cells",
            format!("{cells:?}"),
            "at least 3 cells around",
        ));
    }
    let map = |u: f64, v: f64| {
        let theta = 2.0 * std::f64::consts::PI * u;
        let r = inner_radius + (outer_radius - inner_radius) * v;
        center + r * Vector2::new(theta.cos(), theta.sin())
    };
    quad_grid(cells[0], cells[1], map, kind, true)
}

/// A convex polygon (at least 4 vertices) meshed by a transfinite (Coons) map of the unit square: the boundary is
/// split into four sides at the vertices nearest to a quarter of the vertex count each;
/// `cells = [n1, n2]` along the first and second sides.
pub fn polygon(vertices: &[Vector2<f64>], cells: [usize; 2], kind: ElementKind) -> Result<Mesh<2>> {
    check_cells(cells)?;
    let mut v: Vec<Vector2<f64>> = vertices.to_vec();
    // A quadrilateral map of a triangle needs a straight corner, which is degenerate.
    if v.len() < 4 {
        return Err(invalid(
            "vertices",
            format!("{} vertices", v.len()),
            "at least 4 vertices",
        ));
    }
    let signed_area: f64 = (0..v.len())
        .map(|i| v[i].perp(&v[(i + 1) % v.len()]))
        .sum::<f64>()
        / 2.0;
    if signed_area.abs() < 1e-300 {
        return Err(invalid(
            "vertices",
            "a degenerate polygon",
            "a convex polygon of positive area",
        ));
    }
    if signed_area < 0.0 {
        v.reverse();
    }
    for i in 0..v.len() {
        let (a, b, c) = (v[i], v[(i + 1) % v.len()], v[(i + 2) % v.len()]);
        if (b - a).perp(&(c - b)) < -1e-12 * (b - a).norm() * (c - b).norm() {
            return Err(invalid(
                "vertices",
                "a non-convex polygon",
                "a convex polygon",
            ));
        }
    }
    let n = v.len();
    let corners = [
        0,
        (n as f64 / 4.0).round() as usize,
        n / 2,
        (3.0 * n as f64 / 4.0).round() as usize,
    ];
    // Side k runs from corner k to corner k+1 along the boundary.
    let sides: Vec<Vec<Vector2<f64>>> = (0..4)
        .map(|k| {
            let (a, b) = (corners[k], if k == 3 { n } else { corners[k + 1] });
            (a..=b).map(|i| v[i % n]).collect()
        })
        .collect();
    let along = |side: &[Vector2<f64>], s: f64| -> Vector2<f64> {
        let lengths: Vec<f64> = side.windows(2).map(|w| (w[1] - w[0]).norm()).collect();
        let total: f64 = lengths.iter().sum();
        let mut target = s.clamp(0.0, 1.0) * total;
        for (k, l) in lengths.iter().enumerate() {
            if target <= *l || k == lengths.len() - 1 {
                let t = if *l > 0.0 { (target / l).min(1.0) } else { 0.0 };
                return side[k] + (side[k + 1] - side[k]) * t;
            }
            target -= l;
        }
        side[side.len() - 1]
    };
    let (p00, p10, p11, p01) = (v[corners[0]], v[corners[1]], v[corners[2]], v[corners[3]]);
    let map = |u: f64, w: f64| {
        let bottom = along(&sides[0], u);
        let right = along(&sides[1], w);
        let top = along(&sides[2], 1.0 - u);
        let left = along(&sides[3], 1.0 - w);
        (1.0 - w) * bottom + w * top + (1.0 - u) * left + u * right
            - ((1.0 - u) * (1.0 - w) * p00
                + u * (1.0 - w) * p10
                + u * w * p11
                + (1.0 - u) * w * p01)
    };
    quad_grid(cells[0], cells[1], map, kind, false)
}

/// Total measure (area in 2D, volume in 3D; plane measure, no axisymmetric factor) of a mesh.
pub fn measure<const D: usize>(mesh: &Mesh<D>) -> f64
where
    Dim<D>: SpatialDim<D>,
{
    let mut total = 0.0;
    for block in &mesh.blocks {
        for cell in block.cells() {
            for q in block.kind.quadrature() {
                total += q.weight * <Dim<D>>::det(&mesh.jacobian(block.kind, cell, q.xi));
            }
        }
    }
    total
}

/// The centroid of the nodes (unweighted); handy for placing probes.
pub fn node_centroid<const D: usize>(mesh: &Mesh<D>) -> SVector<f64, D> {
    let mut c = SVector::<f64, D>::zeros();
    for x in &mesh.nodes {
        c += x;
    }
    c / mesh.nodes.len().max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_measures_are_exact() {
        for kind in [ElementKind::Tri3, ElementKind::Quad4] {
            let m =
                rectangle(Vector2::new(1.0, 2.0), Vector2::new(4.0, 3.0), [5, 2], kind).unwrap();
            m.check_quality("r").unwrap();
            assert!((measure(&m) - 3.0).abs() < 1e-12);
        }
        for kind in [ElementKind::Tet4, ElementKind::Hex8] {
            let m = cuboid(
                Vector3::zeros(),
                Vector3::new(1.0, 2.0, 0.5),
                [3, 2, 2],
                kind,
            )
            .unwrap();
            m.check_quality("b").unwrap();
            assert!((measure(&m) - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn annulus_area_converges_to_the_ring_area() {
        let m = annulus(
            Vector2::new(0.0, 1.0),
            0.8,
            1.0,
            [256, 2],
            ElementKind::Quad4,
        )
        .unwrap();
        m.check_quality("ring").unwrap();
        // The nodes lie on the circles: the mesh is the ring between two inscribed 256-gons.
        let n = 256.0;
        let exact = n / 2.0 * (2.0 * std::f64::consts::PI / n).sin() * (1.0 - 0.64);
        assert!((measure(&m) - exact).abs() / exact < 1e-12);
        assert_eq!(m.boundary_faces().len(), 512);
    }

    #[test]
    fn polygon_meshes_exactly_its_area() {
        // A quarter of a regular octagon, as in the paper's second example.
        let a = 1.0;
        let b = a * (std::f64::consts::PI / 8.0).tan();
        let verts = [
            Vector2::new(0.0, 0.0),
            Vector2::new(a, 0.0),
            Vector2::new(a, b),
            Vector2::new(b, a),
            Vector2::new(0.0, a),
        ];
        let area = a * a - (a - b) * (a - b) / 2.0;
        for kind in [ElementKind::Quad4, ElementKind::Tri3] {
            let m = polygon(&verts, [6, 6], kind).unwrap();
            m.check_quality("octagon").unwrap();
            assert!((measure(&m) - area).abs() < 1e-12, "{}", measure(&m));
        }
        let tri = [
            Vector2::zeros(),
            Vector2::new(1.0, 0.0),
            Vector2::new(0.0, 1.0),
        ];
        assert!(polygon(&tri, [3, 3], ElementKind::Quad4).is_err());
        assert!(polygon(
            &[
                Vector2::zeros(),
                Vector2::new(1.0, 0.0),
                Vector2::new(0.2, 0.2),
                Vector2::new(0.0, 1.0)
            ],
            [2, 2],
            ElementKind::Quad4
        )
        .is_err());
    }
}
