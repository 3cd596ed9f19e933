//! Meshes: nodes, cells, boundary extraction and quality checks.

pub mod generators;

use std::collections::HashMap;

use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

use crate::dim::{Dim, SpatialDim};
use crate::element::{ElementKind, ShapeValues};
use crate::error::{Error, Result};

/// A block of cells of one element type; connectivity is flat, `kind.nodes()` per cell.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellBlock {
    /// Element type of every cell of the block.
    pub kind: ElementKind,
    /// Node indices, `kind.nodes()` per cell.
    pub connectivity: Vec<usize>,
}

impl CellBlock {
    /// Number of cells.
    pub fn len(&self) -> usize {
        self.connectivity.len() / self.kind.nodes()
    }

    /// Whether the block has no cell.
    pub fn is_empty(&self) -> bool {
        self.connectivity.is_empty()
    }

    /// Node indices of cell `c`.
    pub fn cell(&self, c: usize) -> &[usize] {
        let n = self.kind.nodes();
        &self.connectivity[c * n..(c + 1) * n]
    }

    /// Iterates the cells' node lists.
    pub fn cells(&self) -> std::slice::ChunksExact<'_, usize> {
        self.connectivity.chunks_exact(self.kind.nodes())
    }
}

/// A face of the boundary: 2 nodes in 2D (a segment), 3 or 4 in 3D (triangle or quadrangle),
/// ordered so that its normal points out of the body.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct BoundaryFace {
    /// Node indices, outward orientation.
    pub nodes: Vec<usize>,
    /// The block and the cell it belongs to.
    pub cell: (usize, usize),
}

/// A finite element mesh in D dimensions, coordinates in metres.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Mesh<const D: usize> {
    /// Node coordinates (m).
    pub nodes: Vec<SVector<f64, D>>,
    /// Cells grouped by element type.
    pub blocks: Vec<CellBlock>,
    /// Named node sets (from Gmsh physical groups), node indices sorted.
    #[serde(default)]
    pub node_sets: HashMap<String, Vec<usize>>,
}

impl<const D: usize> Mesh<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// A mesh from nodes and one block of cells.
    pub fn new(nodes: Vec<SVector<f64, D>>, kind: ElementKind, connectivity: Vec<usize>) -> Self {
        Mesh {
            nodes,
            blocks: vec![CellBlock { kind, connectivity }],
            node_sets: HashMap::new(),
        }
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Number of cells over all blocks.
    pub fn cell_count(&self) -> usize {
        self.blocks.iter().map(CellBlock::len).sum()
    }

    /// Checks that the element types match the dimension, that connectivity is in range and that
    /// every node is used. `body` names the mesh in messages.
    pub fn validate_topology(&self, body: &str) -> Result<()> {
        let err = |message: String| {
            Err(Error::Mesh {
                body: body.to_string(),
                message,
            })
        };
        if self.nodes.is_empty() || self.cell_count() == 0 {
            return err("the mesh has no node or no cell; expected at least one cell".into());
        }
        let mut used = vec![false; self.nodes.len()];
        for block in &self.blocks {
            if block.kind.dimension() != D {
                return err(format!(
                    "found {} cells in a {D}D simulation; expected {}",
                    block.kind.name(),
                    if D == 2 {
                        "tri3 or quad4"
                    } else {
                        "tet4 or hex8"
                    }
                ));
            }
            if block.connectivity.len() % block.kind.nodes() != 0 {
                return err("connectivity length is not a multiple of the cell size".into());
            }
            for (c, cell) in block.cells().enumerate() {
                for &n in cell {
                    if n >= self.nodes.len() {
                        return err(format!(
                            "cell {c} names node {n}; expected an index below {}",
                            self.nodes.len()
                        ));
                    }
                    used[n] = true;
                }
            }
        }
        if let Some(n) = used.iter().position(|u| !u) {
            return err(format!(
                "node {n} belongs to no cell; expected every node to be used"
            ));
        }
        for (n, x) in self.nodes.iter().enumerate() {
            if x.iter().any(|c| !c.is_finite()) {
                return err(format!("node {n} has a non-finite coordinate"));
            }
        }
        Ok(())
    }

    /// Checks every cell's Jacobian at its quadrature points and corners: an inverted or
    /// degenerate cell is an error naming the cell.
    pub fn check_quality(&self, body: &str) -> Result<()> {
        let mut offset = 0;
        for block in &self.blocks {
            for (c, cell) in block.cells().enumerate() {
                // Degenerate: a determinant below 1e-12 of the cell's own size^D (the whole
                // mesh's size refused the small cells of a long mesh: a 1 km bar of 1 cm cubes).
                let size = cell_diagonal(&self.nodes, cell).max(f64::MIN_POSITIVE);
                let floor = 1e-12 * size.powi(D as i32);
                let mut min_det = f64::INFINITY;
                let points = block
                    .kind
                    .quadrature()
                    .iter()
                    .map(|q| q.xi)
                    .chain(block.kind.node_coordinates().iter().copied());
                for xi in points {
                    let j = self.jacobian(block.kind, cell, xi);
                    min_det = min_det.min(<Dim<D>>::det(&j));
                }
                if min_det.is_nan() || min_det <= floor {
                    return Err(Error::InvertedElement {
                        body: body.to_string(),
                        cell: offset + c,
                        kind: if min_det < -floor {
                            "inverted"
                        } else {
                            "degenerate"
                        },
                        jacobian: min_det,
                    });
                }
            }
            offset += block.len();
        }
        Ok(())
    }

    /// dx/dxi of one cell at reference point `xi` (column k = d x / d xi_k).
    pub fn jacobian(&self, kind: ElementKind, cell: &[usize], xi: [f64; 3]) -> SMatrix<f64, D, D> {
        jacobian_with(&kind.shape(xi), cell, &self.nodes)
    }

    /// The first cell that is turned inside out when the nodes are at `positions` (the
    /// mesh's nodes moved, in its order): a Jacobian below `-1e-12 size^D` at a quadrature
    /// point (one point for the linear simplices, whose Jacobian is constant), `size` the
    /// cell's diagonal. Its index and centre (m). Not at the corners: a quadrilateral with
    /// one reflex corner is distorted, not folded, and its quadrature points still integrate
    /// it (the bundled tube crush's fold has such cells on the floor; Newton's test of
    /// updated-Lagrangian cells reads the quadrature points too).
    pub(crate) fn inverted_cell(
        &self,
        positions: &[SVector<f64, D>],
    ) -> Option<(usize, SVector<f64, D>)> {
        let mut offset = 0;
        for block in &self.blocks {
            let points: Vec<[f64; 3]> = match block.kind {
                ElementKind::Tri3 | ElementKind::Tet4 => vec![block.kind.node_coordinates()[0]],
                _ => block.kind.quadrature().iter().map(|q| q.xi).collect(),
            };
            // The shape functions' derivatives at those points, the same for every cell.
            let shapes: Vec<_> = points.iter().map(|&xi| block.kind.shape(xi)).collect();
            for (c, cell) in block.cells().enumerate() {
                let least = shapes
                    .iter()
                    .map(|s| <Dim<D>>::det(&jacobian_with(s, cell, positions)))
                    .fold(f64::INFINITY, f64::min);
                if least >= 0.0 {
                    continue;
                }
                if least < -1e-12 * cell_diagonal(positions, cell).powi(D as i32) {
                    let centre = cell.iter().map(|&n| positions[n]).sum::<SVector<f64, D>>()
                        / cell.len() as f64;
                    return Some((offset + c, centre));
                }
            }
            offset += block.len();
        }
        None
    }

    /// The diagonal of the bounding box (m).
    pub fn characteristic_length(&self) -> f64 {
        let (lo, hi) = self.bounding_box();
        (hi - lo).norm().max(f64::MIN_POSITIVE)
    }

    /// Smallest and largest coordinates.
    pub fn bounding_box(&self) -> (SVector<f64, D>, SVector<f64, D>) {
        let mut lo = SVector::<f64, D>::repeat(f64::INFINITY);
        let mut hi = SVector::<f64, D>::repeat(f64::NEG_INFINITY);
        for x in &self.nodes {
            lo = lo.inf(x);
            hi = hi.sup(x);
        }
        (lo, hi)
    }

    /// The faces that belong to exactly one cell, outward oriented, in a deterministic order.
    pub fn boundary_faces(&self) -> Vec<BoundaryFace> {
        let mut seen: HashMap<Vec<usize>, (usize, BoundaryFace)> = HashMap::new();
        let mut order = 0usize;
        for (b, block) in self.blocks.iter().enumerate() {
            for (c, cell) in block.cells().enumerate() {
                for face in block.kind.faces() {
                    let nodes: Vec<usize> = face.iter().map(|&i| cell[i]).collect();
                    let mut key = nodes.clone();
                    key.sort_unstable();
                    if seen.remove(&key).is_none() {
                        seen.insert(
                            key,
                            (
                                order,
                                BoundaryFace {
                                    nodes,
                                    cell: (b, c),
                                },
                            ),
                        );
                        order += 1;
                    }
                }
            }
        }
        let mut faces: Vec<(usize, BoundaryFace)> = seen.into_values().collect();
        faces.sort_unstable_by_key(|(o, _)| *o);
        faces.into_iter().map(|(_, f)| f).collect()
    }

    /// The boundary as simplicial facets (segments in 2D, triangles in 3D; quadrangles are
    /// split along their first diagonal), outward oriented.
    pub fn boundary_facets(&self) -> Vec<[usize; D]> {
        let mut facets = Vec::new();
        for face in self.boundary_faces() {
            let n = &face.nodes;
            let mut push = |ids: &[usize]| {
                let mut f = [0usize; D];
                f.copy_from_slice(ids);
                facets.push(f);
            };
            if n.len() == D {
                push(n);
            } else {
                // Quadrangle in 3D.
                push(&[n[0], n[1], n[2]]);
                push(&[n[0], n[2], n[3]]);
            }
        }
        facets
    }

    /// The nodes on the boundary, sorted.
    pub fn boundary_nodes(&self) -> Vec<usize> {
        let mut nodes: Vec<usize> = self
            .boundary_faces()
            .into_iter()
            .flat_map(|f| f.nodes)
            .collect();
        nodes.sort_unstable();
        nodes.dedup();
        nodes
    }

    /// The nodes inside the axis-aligned box `[min, max]` (bounds included).
    pub fn nodes_in_box(&self, min: &SVector<f64, D>, max: &SVector<f64, D>) -> Vec<usize> {
        (0..self.nodes.len())
            .filter(|&n| {
                let x = &self.nodes[n];
                (0..D).all(|k| x[k] >= min[k] && x[k] <= max[k])
            })
            .collect()
    }

    /// The node nearest to `point` (the first one on ties).
    pub fn nearest_node(&self, point: &SVector<f64, D>) -> usize {
        let mut best = (0, f64::INFINITY);
        for (n, x) in self.nodes.iter().enumerate() {
            let d = (x - point).norm_squared();
            if d < best.1 {
                best = (n, d);
            }
        }
        best.0
    }

    /// Moves the mesh by `offset`.
    pub fn translate(&mut self, offset: &SVector<f64, D>) {
        for x in &mut self.nodes {
            *x += offset;
        }
    }
}

/// dx/dxi of one cell with its nodes at `nodes`, from its shape functions' derivatives `s` at
/// a reference point (column k = d x / d xi_k).
fn jacobian_with<const D: usize>(
    s: &ShapeValues,
    cell: &[usize],
    nodes: &[SVector<f64, D>],
) -> SMatrix<f64, D, D> {
    let mut j = SMatrix::<f64, D, D>::zeros();
    for (a, &n) in cell.iter().enumerate() {
        for k in 0..D {
            j.column_mut(k).axpy(s.dn[a][k], &nodes[n], 1.0);
        }
    }
    j
}

/// The diagonal of a cell's bounding box with its nodes at `nodes` (m).
fn cell_diagonal<const D: usize>(nodes: &[SVector<f64, D>], cell: &[usize]) -> f64 {
    let (mut lo, mut hi) = (nodes[cell[0]], nodes[cell[0]]);
    for &n in cell {
        lo = lo.inf(&nodes[n]);
        hi = hi.sup(&nodes[n]);
    }
    (hi - lo).norm()
}

#[cfg(test)]
mod tests {
    use super::generators::*;
    use super::*;
    use nalgebra::{Vector2, Vector3};

    #[test]
    fn boundary_of_a_rectangle_is_closed_and_outward() {
        for kind in [ElementKind::Tri3, ElementKind::Quad4] {
            let m =
                rectangle(Vector2::new(0.0, 0.0), Vector2::new(2.0, 1.0), [4, 3], kind).unwrap();
            let facets = m.boundary_facets();
            assert_eq!(facets.len(), 2 * (4 + 3));
            let mut perimeter = 0.0;
            let mut flux = Vector2::zeros();
            for f in &facets {
                let (len, n) = <Dim<2>>::facet_measure_normal(&[m.nodes[f[0]], m.nodes[f[1]]]);
                perimeter += len;
                flux += n * len;
                let mid = (m.nodes[f[0]] + m.nodes[f[1]]) / 2.0;
                // Outward: moving along n leaves the rectangle.
                let out = mid + n * 1e-3;
                assert!(out.x < 0.0 || out.x > 2.0 || out.y < 0.0 || out.y > 1.0);
            }
            assert!((perimeter - 6.0).abs() < 1e-12);
            assert!(flux.norm() < 1e-12);
        }
    }

    #[test]
    fn boundary_of_a_box_encloses_its_volume() {
        for kind in [ElementKind::Tet4, ElementKind::Hex8] {
            let m = cuboid(
                Vector3::zeros(),
                Vector3::new(1.0, 2.0, 3.0),
                [2, 3, 2],
                kind,
            )
            .unwrap();
            // Divergence theorem: volume = 1/3 sum (x . n) area.
            let mut volume = 0.0;
            let mut area = 0.0;
            for f in m.boundary_facets() {
                let p = [m.nodes[f[0]], m.nodes[f[1]], m.nodes[f[2]]];
                let (a, n) = <Dim<3>>::facet_measure_normal(&p);
                volume += a * n.dot(&((p[0] + p[1] + p[2]) / 3.0)) / 3.0;
                area += a;
            }
            assert!((volume - 6.0).abs() < 1e-12, "{kind:?} {volume}");
            assert!((area - 2.0 * (2.0 + 3.0 + 6.0)).abs() < 1e-12);
        }
    }

    #[test]
    fn inverted_cell_is_reported() {
        let mut m = rectangle(
            Vector2::zeros(),
            Vector2::new(1.0, 1.0),
            [2, 2],
            ElementKind::Quad4,
        )
        .unwrap();
        m.check_quality("b").unwrap();
        m.blocks[0].connectivity.swap(1, 3); // reverse cell 0
        match m.check_quality("b") {
            Err(Error::InvertedElement {
                cell: 0,
                kind: "inverted",
                ..
            }) => {}
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn degenerate_cell_is_reported() {
        let nodes = vec![
            Vector2::new(0.0, 0.0),
            Vector2::new(1.0, 0.0),
            Vector2::new(2.0, 0.0),
        ];
        let m = Mesh::new(nodes, ElementKind::Tri3, vec![0, 1, 2]);
        assert!(matches!(
            m.check_quality("b"),
            Err(Error::InvertedElement {
                kind: "degenerate",
                ..
            })
        ));
    }
}
