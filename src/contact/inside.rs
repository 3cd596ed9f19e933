//! Which points are inside an obstacle or a body, at any depth: what the overlap check at
//! t = 0 and the fall-through monitor ask, where contact detection only looks near surfaces.
//!
//! * Half-space, box, ball: the signed distance of the gap (`posed_obstacle_gap`), negative
//!   inside, whatever the depth.
//! * Polyline, trimesh ([`FacetSolid`]): the nearest facet (a hierarchy searched with growing
//!   boxes), and the side of its nearest point Q given by the angle-weighted pseudo-normal at
//!   Q (the facet's normal inside a facet, the sum of the two normals on a shared edge, the
//!   angle-weighted sum around a shared vertex), so that shared features do not flip the
//!   sign. A point whose nearest point is on a free end (an end of an open polyline, a free
//!   edge or its vertices of an open trimesh) is outside: the solid does not extend beyond
//!   the facets. An open floor drawn the wrong way round thus holds everything above it.
//! * A body: containment in one of its cells (inverse of the isoparametric map, cells found
//!   through a hierarchy of their boxes), and the depth is the distance to its nearest
//!   boundary facet.

use std::collections::HashMap;

use nalgebra::{SMatrix, SVector};

use crate::contact::gap::posed_obstacle_gap;
use crate::contact::obstacle::{Obstacle, ObstacleShape};
use crate::dim::{Dim, SpatialDim};
use crate::element::ElementKind;
use crate::geometry::{Aabb, BoxTree, FacetProjection, Feature, GeometryDim};

/// Where a segment crosses a surface: the fraction of the way, and the outward normal there.
type Cut<const D: usize> = (f64, SVector<f64, D>);

/// Oriented facets (segments in 2D, triangles in 3D) with a hierarchy and their adjacency.
pub(crate) struct FacetSolid<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    vertices: Vec<SVector<f64, D>>,
    facets: Vec<[usize; D]>,
    /// A label per facet (the body of a body's facet; 0 for an obstacle).
    labels: Vec<usize>,
    normals: Vec<SVector<f64, D>>,
    boxes: Vec<Aabb<D>>,
    tree: BoxTree<D>,
    bounds: Aabb<D>,
    /// Facets around each vertex.
    vertex_facets: Vec<Vec<usize>>,
    /// 3D: facets around each edge (sorted vertex pair).
    edge_facets: HashMap<(usize, usize), Vec<usize>>,
    /// Vertices on a free end (2D: one segment; 3D: on an edge of one triangle).
    free: Vec<bool>,
    /// The vertex each vertex is merged into (the first at the same place).
    canonical: Vec<usize>,
}

impl<const D: usize> FacetSolid<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// The facets `facets` (indices into `vertices`, outward oriented), labelled; degenerate
    /// or malformed facets are skipped.
    pub(crate) fn new(
        vertices: Vec<SVector<f64, D>>,
        facets: impl IntoIterator<Item = ([usize; D], usize)>,
    ) -> Self {
        // Vertices at the same place are one (a triangle soup shares its edges too).
        let mut first: HashMap<[u64; D], usize> = HashMap::new();
        let canonical: Vec<usize> = vertices
            .iter()
            .enumerate()
            .map(|(i, v)| {
                *first
                    .entry(std::array::from_fn(|k| v[k].to_bits()))
                    .or_insert(i)
            })
            .collect();
        let mut kept = Vec::new();
        let mut labels = Vec::new();
        let mut normals = Vec::new();
        for (f, label) in facets {
            if f.iter().any(|&i| i >= vertices.len()) {
                continue;
            }
            let f = f.map(|i| canonical[i]);
            let (measure, n) = <Dim<D>>::facet_measure_normal(&f.map(|i| vertices[i]));
            if !(measure > 0.0 && measure.is_finite()) {
                continue;
            }
            kept.push(f);
            labels.push(label);
            normals.push(n);
        }
        let boxes: Vec<Aabb<D>> = kept
            .iter()
            .map(|f| Aabb::from_points(f.iter().map(|&i| &vertices[i])))
            .collect();
        let bounds = boxes.iter().fold(Aabb::from_points([]), |a, b| a.merged(b));
        let mut vertex_facets = vec![Vec::new(); vertices.len()];
        let mut edge_facets: HashMap<(usize, usize), Vec<usize>> = HashMap::new();
        for (k, f) in kept.iter().enumerate() {
            for &v in f {
                vertex_facets[v].push(k);
            }
            if D == 3 {
                for e in 0..3 {
                    let (a, b) = (f[e], f[(e + 1) % 3]);
                    edge_facets.entry((a.min(b), a.max(b))).or_default().push(k);
                }
            }
        }
        let mut free = vec![false; vertices.len()];
        if D == 2 {
            for (v, fs) in vertex_facets.iter().enumerate() {
                free[v] = fs.len() == 1;
            }
        } else {
            for (&(a, b), fs) in &edge_facets {
                if fs.len() == 1 {
                    free[a] = true;
                    free[b] = true;
                }
            }
        }
        FacetSolid {
            tree: BoxTree::new(&boxes),
            vertices,
            facets: kept,
            labels,
            normals,
            boxes,
            bounds,
            vertex_facets,
            edge_facets,
            free,
            canonical,
        }
    }

    /// A polyline or trimesh obstacle's facets in the frame of its shape at t = 0; `None` for
    /// another shape.
    pub(crate) fn of_obstacle(shape: &ObstacleShape<D>) -> Option<Self> {
        let ObstacleShape::Facets { vertices, indices } = shape else {
            return None;
        };
        let facets = indices
            .iter()
            .filter(|f| f.len() == D)
            .map(|f| (std::array::from_fn(|k| f[k]), 0));
        Some(Self::new(vertices.clone(), facets))
    }

    /// The nearest facet that `accept(label, facet)` accepts to `p`: (distance, facet,
    /// projection).
    fn nearest(
        &self,
        p: &SVector<f64, D>,
        accept: impl Fn(usize, usize) -> bool,
    ) -> Option<(f64, usize, FacetProjection<D>)> {
        if self.facets.is_empty() || !p.iter().all(|c| c.is_finite()) {
            return None;
        }
        let point = Aabb { min: *p, max: *p };
        let diag = (self.bounds.max - self.bounds.min).norm();
        let outside = self.bounds.distance(&point);
        // No facet is nearer than the facets' bounds.
        let mut r = (1e-3 * diag).max(outside).max(1e-300);
        let reach = 4.0 * (diag + outside);
        let mut hits = Vec::new();
        // Grow a box until it holds an accepted facet at most its half-width away: it then
        // holds every facet as close as the closest one.
        for _ in 0..64 {
            hits.clear();
            self.tree.query(&point.loosened(r), &mut hits);
            hits.sort_unstable();
            let mut best: Option<(f64, usize, FacetProjection<D>)> = None;
            for &f in &hits {
                if !accept(self.labels[f], f) || self.boxes[f].distance(&point) > r {
                    continue;
                }
                let v = self.facets[f].map(|i| self.vertices[i]);
                let Some(q) = <Dim<D>>::project_on_facet(p, &v) else {
                    continue;
                };
                let d = (p - q.point).norm();
                if best.is_none_or(|b| d < b.0) {
                    best = Some((d, f, q));
                }
            }
            if let Some(b) = best {
                if b.0 <= r {
                    return Some(b);
                }
            }
            if r > reach || !r.is_finite() {
                break;
            }
            r *= 4.0;
        }
        None
    }

    /// The distance from `p` to the nearest facet labelled `label` (m).
    pub(crate) fn distance(&self, p: &SVector<f64, D>, label: usize) -> Option<f64> {
        self.nearest(p, |l, _| l == label).map(|b| b.0)
    }

    /// The distance from `p` to the nearest facet labelled `label` none of whose vertices is
    /// in `apart` (indices into the vertices given at construction) (m).
    pub(crate) fn distance_apart(
        &self,
        p: &SVector<f64, D>,
        label: usize,
        apart: &[usize],
    ) -> Option<f64> {
        let apart: Vec<usize> = apart
            .iter()
            .filter_map(|&v| self.canonical.get(v).copied())
            .collect();
        self.nearest(p, |l, f| {
            l == label && !self.facets[f].iter().any(|v| apart.contains(v))
        })
        .map(|b| b.0)
    }

    /// `Some(depth)` when `p` is on the solid side (behind the pseudo-normal of its nearest
    /// point, not on a free end), the depth being the distance to that point (m).
    pub(crate) fn inside(&self, p: &SVector<f64, D>) -> Option<f64> {
        let (d, f, q) = self.nearest(p, |_, _| true)?;
        let facet = self.facets[f];
        let n = match q.feature {
            Feature::Face => self.normals[f],
            Feature::Edge(e) => {
                let (a, b) = (facet[e], facet[(e + 1) % D]);
                let around = self.edge_facets.get(&(a.min(b), a.max(b)))?;
                if around.len() < 2 {
                    return None;
                }
                around.iter().map(|&g| self.normals[g]).sum()
            }
            Feature::Vertex(i) => {
                let v = facet[i];
                if self.free[v] {
                    return None;
                }
                self.vertex_facets[v]
                    .iter()
                    .map(|&g| self.normals[g] * self.angle_at(g, v))
                    .sum()
            }
        };
        ((p - q.point).dot(&n) < 0.0).then_some(d)
    }

    /// Where the segment from `y0` to `y1` (m) enters the facets first and leaves them last:
    /// ((fraction of the way from `y0`, facet normal), (fraction of the way back from `y1`,
    /// facet normal)), an entry crossing a facet against its outward normal and an exit along
    /// it; `None` without both, or when the exit comes before the entry.
    fn entry_and_exit(
        &self,
        y0: &SVector<f64, D>,
        y1: &SVector<f64, D>,
    ) -> Option<(Cut<D>, Cut<D>)> {
        let d = y1 - y0;
        let mut hits = Vec::new();
        self.tree.query(&Aabb::from_points([y0, y1]), &mut hits);
        let mut entry: Option<(f64, usize)> = None;
        let mut exit: Option<(f64, usize)> = None;
        for &f in &hits {
            let s = d.dot(&self.normals[f]);
            // Along the facet's plane: neither in nor out.
            if !(s.abs() > 1e-12 * d.norm()) {
                continue;
            }
            let v = self.facets[f].map(|i| self.vertices[i]);
            let Some(t) = <Dim<D>>::segment_crosses_facet(y0, y1, &v) else {
                continue;
            };
            if s < 0.0 && entry.is_none_or(|e| (t, f) < e) {
                entry = Some((t, f));
            } else if s > 0.0 && exit.is_none_or(|e| (t, f) > e) {
                exit = Some((t, f));
            }
        }
        let ((t_in, f_in), (t_out, f_out)) = (entry?, exit?);
        (t_in < t_out).then(|| {
            (
                (t_in, self.normals[f_in]),
                (1.0 - t_out, self.normals[f_out]),
            )
        })
    }

    /// The angle of facet `g` at its vertex `v` (rad; 1 for a segment).
    fn angle_at(&self, g: usize, v: usize) -> f64 {
        if D == 2 {
            return 1.0;
        }
        let f = self.facets[g];
        let Some(i) = f.iter().position(|&w| w == v) else {
            return 0.0;
        };
        let o = self.vertices[v];
        let (a, b) = (
            self.vertices[f[(i + 1) % 3]] - o,
            self.vertices[f[(i + 2) % 3]] - o,
        );
        (a.dot(&b) / (a.norm() * b.norm())).clamp(-1.0, 1.0).acos()
    }
}

/// `Some(depth)` (m) when the point `p` is inside obstacle `o` in its pose, `None` when
/// outside; `solid` is the obstacle's [`FacetSolid`] for a polyline or trimesh.
pub(crate) fn obstacle_depth<const D: usize>(
    o: &Obstacle<D>,
    solid: Option<&FacetSolid<D>>,
    p: &SVector<f64, D>,
) -> Option<f64>
where
    Dim<D>: SpatialDim<D>,
{
    match &o.shape {
        ObstacleShape::Facets { .. } => solid?.inside(&o.to_local(p)),
        _ => {
            let g = posed_obstacle_gap(o, p, None, 0.0)?.gap;
            (g < 0.0).then_some(-g)
        }
    }
}

/// A node's straight path over a step through an obstacle (see [`passes_through`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Crossing {
    /// The length of the path relative to the obstacle (m).
    pub(crate) travel: f64,
    /// The length of it inside the obstacle, from where it entered to where it left (m).
    pub(crate) inside: f64,
}

/// Whether a node going from `x0` (obstacle `o` in its pose `o0` at the start of the step) to
/// `x1` (pose `o1` at its end) passed through the obstacle: its straight path in the frame of
/// the obstacle's shape at t = 0 (`to_local` at either pose, so that a moving or turning
/// obstacle is followed) starts and ends outside, crosses the surface inwards and then
/// outwards, its middle between the two crossings is inside, and it left on the far side (the
/// outward normals where it entered and where it left oppose each other) or went deeper than
/// `reach` (m). A node that slides along the surface, rests on it or rounds a convex corner
/// by a short chord does neither. Half-spaces have no far side: `None`. `solid` is the
/// obstacle's [`FacetSolid`] for a polyline or trimesh (an open one has no far side either).
pub(crate) fn passes_through<const D: usize>(
    o0: &Obstacle<D>,
    o1: &Obstacle<D>,
    solid: Option<&FacetSolid<D>>,
    x0: &SVector<f64, D>,
    x1: &SVector<f64, D>,
    reach: f64,
) -> Option<Crossing>
where
    Dim<D>: SpatialDim<D>,
{
    let (y0, y1) = (o0.to_local(x0), o1.to_local(x1));
    let travel = (y1 - y0).norm();
    if !(travel > 0.0 && travel.is_finite()) {
        return None;
    }
    // (fraction in, normal in), (fraction back from y1 out, normal out), depth of the middle.
    let (entry, exit, depth) = match &o0.shape {
        ObstacleShape::Halfspace { .. } => return None,
        ObstacleShape::Box {
            center,
            half_extents,
        } => {
            let (a, b) = (y0 - center, y1 - center);
            let entry = <Dim<D>>::segment_hits_box(&a, &b, half_extents)?;
            let exit = <Dim<D>>::segment_hits_box(&b, &a, half_extents)?;
            let mid = a + (b - a) * (0.5 * (entry.0 + 1.0 - exit.0));
            let depth = (0..D)
                .map(|k| half_extents[k] - mid[k].abs())
                .fold(f64::INFINITY, f64::min);
            (entry, exit, depth)
        }
        ObstacleShape::Ball { center, radius } => {
            let (a, b) = (y0 - center, y1 - center);
            let entry = <Dim<D>>::segment_hits_ball(&a, &b, *radius)?;
            let exit = <Dim<D>>::segment_hits_ball(&b, &a, *radius)?;
            let mid = a + (b - a) * (0.5 * (entry.0 + 1.0 - exit.0));
            (entry, exit, radius - mid.norm())
        }
        ObstacleShape::Facets { .. } => {
            let s = solid?;
            let (entry, exit) = s.entry_and_exit(&y0, &y1)?;
            if s.inside(&y0).is_some() || s.inside(&y1).is_some() {
                return None;
            }
            let mid = y0 + (y1 - y0) * (0.5 * (entry.0 + 1.0 - exit.0));
            (entry, exit, s.inside(&mid)?)
        }
    };
    // A cast that starts inside (or on the surface) stops at once: both ends are outside.
    let inside = (1.0 - entry.0 - exit.0) * travel;
    if !(entry.0 > 0.0 && exit.0 > 0.0 && inside > 0.0 && depth > 1e-9 * travel) {
        return None;
    }
    (entry.1.dot(&exit.1) < 0.0 || depth > reach).then_some(Crossing { travel, inside })
}

/// A hierarchy of the boxes of bodies' cells in their current configuration; the cells are
/// (body, kind, global nodes), kept by the caller.
pub(crate) struct CellIndex<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    tree: BoxTree<D>,
}

impl<const D: usize> CellIndex<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// The hierarchy of `cells` at positions `x` (m).
    pub(crate) fn new(cells: &[(usize, ElementKind, Vec<usize>)], x: &[SVector<f64, D>]) -> Self {
        let boxes: Vec<Aabb<D>> = cells
            .iter()
            .map(|(_, _, nodes)| Aabb::from_points(nodes.iter().map(|&n| &x[n])))
            .collect();
        CellIndex {
            tree: BoxTree::new(&boxes),
        }
    }

    /// Whether a cell of body `body` holds `p` (the same `cells` and `x` as at construction).
    pub(crate) fn holds(
        &self,
        p: &SVector<f64, D>,
        body: usize,
        cells: &[(usize, ElementKind, Vec<usize>)],
        x: &[SVector<f64, D>],
        hits: &mut Vec<usize>,
    ) -> bool {
        self.held_by(p, body, None, cells, x, hits)
    }

    /// Whether a cell of body `body` other than those of node `apart` holds `p`.
    fn held_by(
        &self,
        p: &SVector<f64, D>,
        body: usize,
        apart: Option<usize>,
        cells: &[(usize, ElementKind, Vec<usize>)],
        x: &[SVector<f64, D>],
        hits: &mut Vec<usize>,
    ) -> bool {
        hits.clear();
        self.tree.query(&Aabb { min: *p, max: *p }, hits);
        hits.iter().any(|&c| {
            let (b, kind, nodes) = &cells[c];
            if *b != body || apart.is_some_and(|n| nodes.contains(&n)) {
                return false;
            }
            let corners: Vec<SVector<f64, D>> = nodes.iter().map(|&n| x[n]).collect();
            in_cell(*kind, &corners, p)
        })
    }
}

impl<const D: usize> CellIndex<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// Whether a cell of body `body` that does not hold node `node` holds `p`: a node in its
    /// own body elsewhere than in its own cells (or on a cell it only touches: a node
    /// duplicated at the same place, a hanging node; the caller's depth tells those apart).
    pub(crate) fn holds_apart(
        &self,
        p: &SVector<f64, D>,
        node: usize,
        body: usize,
        cells: &[(usize, ElementKind, Vec<usize>)],
        x: &[SVector<f64, D>],
        hits: &mut Vec<usize>,
    ) -> bool {
        self.held_by(p, body, Some(node), cells, x, hits)
    }
}

/// Whether `p` lies in the cell of type `kind` with nodes at `x` (m): the reference
/// coordinates of `p` by Newton on the isoparametric map (exact in one iteration for
/// simplices), within the reference element.
pub(crate) fn in_cell<const D: usize>(
    kind: ElementKind,
    x: &[SVector<f64, D>],
    p: &SVector<f64, D>,
) -> bool {
    let simplex = matches!(kind, ElementKind::Tri3 | ElementKind::Tet4);
    let mut xi = [0.0; 3];
    if simplex {
        xi[..D].fill(1.0 / (D as f64 + 1.0));
    }
    let size = x.iter().map(|v| (v - x[0]).norm()).fold(0.0, f64::max);
    for _ in 0..20 {
        let s = kind.shape(xi);
        let mut r = -p;
        let mut j = SMatrix::<f64, D, D>::zeros();
        for (a, v) in x.iter().enumerate() {
            r += v * s.n[a];
            for k in 0..D {
                j.column_mut(k).axpy(s.dn[a][k], v, 1.0);
            }
        }
        let Some(inv) = j.try_inverse() else {
            return false;
        };
        let dxi = inv * r;
        for k in 0..D {
            xi[k] -= dxi[k];
        }
        if r.norm() <= 1e-12 * size {
            break;
        }
        if xi.iter().any(|c| !c.is_finite() || c.abs() > 1e6) {
            return false;
        }
    }
    // The residual at the final coordinates decides: a map that did not converge is outside.
    let s = kind.shape(xi);
    let mut r = -p;
    for (a, v) in x.iter().enumerate() {
        r += v * s.n[a];
    }
    if !(r.norm() <= 1e-9 * size) {
        return false;
    }
    let tol = 1e-12;
    if simplex {
        xi[..D].iter().all(|&c| c >= -tol) && xi[..D].iter().sum::<f64>() <= 1.0 + tol
    } else {
        xi[..D].iter().all(|&c| c.abs() <= 1.0 + tol)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Vector2, Vector3};

    #[test]
    fn polyline_sides_and_ends() {
        // A floor drawn right to left (solid below), then a V whose two segments share a
        // vertex.
        let s = FacetSolid::<2>::new(
            vec![Vector2::new(1.0, 0.0), Vector2::new(-1.0, 0.0)],
            [([0, 1], 0)],
        );
        assert_eq!(s.inside(&Vector2::new(0.2, -0.5)), Some(0.5));
        assert_eq!(s.inside(&Vector2::new(0.2, 0.5)), None);
        // Beyond a free end: outside, whatever the side.
        assert_eq!(s.inside(&Vector2::new(3.0, -0.5)), None);
        let v = FacetSolid::<2>::new(
            vec![
                Vector2::new(1.0, 1.0),
                Vector2::new(0.0, 0.0),
                Vector2::new(-1.0, 1.0),
            ],
            [([0, 1], 0), ([1, 2], 0)],
        );
        // Below the V's apex (nearest point: the shared vertex): inside; above, in the V: out.
        assert!(v.inside(&Vector2::new(0.0, -0.3)).is_some());
        assert_eq!(v.inside(&Vector2::new(0.0, 0.3)), None);
    }

    #[test]
    fn a_triangle_soup_shares_its_edges() {
        // A floor of two triangles with their own copies of the diagonal's vertices, drawn
        // counter-clockwise seen from above (solid below): a point under the diagonal, whose
        // nearest point is on that edge, is inside; one above is not.
        let v = |x: f64, z: f64| Vector3::new(x, 0.0, z);
        let s = FacetSolid::<3>::new(
            vec![
                v(-1.0, -1.0),
                v(1.0, 1.0),
                v(1.0, -1.0),
                v(-1.0, -1.0),
                v(-1.0, 1.0),
                v(1.0, 1.0),
            ],
            [([0, 1, 2], 0), ([3, 4, 5], 0)],
        );
        assert_eq!(s.inside(&Vector3::new(0.0, -0.5, 0.0)), Some(0.5));
        assert_eq!(s.inside(&Vector3::new(0.0, 0.5, 0.0)), None);
    }

    #[test]
    fn closed_trimesh_tetrahedron() {
        // A tetrahedron, counter-clockwise seen from outside.
        let x = vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
            Vector3::new(0.0, 0.0, 1.0),
        ];
        let s = FacetSolid::<3>::new(
            x,
            [
                ([0, 2, 1], 0),
                ([0, 1, 3], 0),
                ([0, 3, 2], 0),
                ([1, 2, 3], 0),
            ],
        );
        let d = s.inside(&Vector3::new(0.1, 0.1, 0.1)).unwrap();
        assert!((d - 0.1).abs() < 1e-12);
        // Outside near a vertex, an edge and a face.
        assert_eq!(s.inside(&Vector3::new(-0.1, -0.1, -0.1)), None);
        assert_eq!(s.inside(&Vector3::new(0.5, -0.1, -0.1)), None);
        assert_eq!(s.inside(&Vector3::new(0.4, 0.4, 0.4)), None);
    }

    /// A path through a thin box, one that slides along it, one that rounds its corner, and
    /// the same box turned by a quarter turn over the step (the path followed in its frame).
    #[test]
    fn paths_through_obstacles() {
        let plate = Obstacle::new(
            "plate",
            ObstacleShape::Box {
                center: Vector2::new(0.0, 0.0),
                half_extents: Vector2::new(1.0, 0.02),
            },
        );
        let through = |o0: &Obstacle<2>, o1: &Obstacle<2>, a: [f64; 2], b: [f64; 2]| {
            passes_through(
                o0,
                o1,
                None,
                &Vector2::new(a[0], a[1]),
                &Vector2::new(b[0], b[1]),
                0.01,
            )
        };
        let c = through(&plate, &plate, [0.0, 0.1], [0.0, -0.4]).unwrap();
        assert!((c.travel - 0.5).abs() < 1e-12 && (c.inside - 0.04).abs() < 1e-12);
        // Ends inside, starts inside, slides along the top, rounds the corner.
        assert!(through(&plate, &plate, [0.0, 0.1], [0.0, 0.0]).is_none());
        assert!(through(&plate, &plate, [0.0, 0.0], [0.0, -0.4]).is_none());
        assert!(through(&plate, &plate, [-0.5, 0.02], [0.5, 0.02]).is_none());
        assert!(through(&plate, &plate, [0.95, 0.025], [1.01, 0.0]).is_none());
        // A ball cut by a shallow chord (deeper than the reach) and a grazing one.
        let ball = Obstacle::new(
            "ball",
            ObstacleShape::Ball {
                center: Vector2::new(0.0, 0.0),
                radius: 1.0,
            },
        );
        assert!(through(&ball, &ball, [-2.0, 0.95], [2.0, 0.95]).is_some());
        assert!(through(&ball, &ball, [-0.2, 1.0], [0.2, 0.995]).is_none());
        // The plate turned by a quarter turn about its centre over the step (it stands along
        // y at the end): a node at rest beside its end at x = 1.1 is passed through by it in
        // its frame; one at rest far away is not.
        let mut turned = plate.clone();
        turned.rotation = nalgebra::Matrix2::new(0.0, -1.0, 1.0, 0.0);
        assert!(through(&plate, &turned, [0.1, 0.5], [0.1, 0.5]).is_some());
        assert!(through(&plate, &turned, [3.0, 3.0], [3.0, 3.0]).is_none());
    }

    #[test]
    fn points_in_cells() {
        let quad = [
            Vector2::new(0.0, 0.0),
            Vector2::new(2.0, 0.0),
            Vector2::new(2.5, 1.0),
            Vector2::new(0.0, 1.0),
        ];
        assert!(in_cell(ElementKind::Quad4, &quad, &Vector2::new(2.2, 0.9)));
        assert!(!in_cell(ElementKind::Quad4, &quad, &Vector2::new(2.2, 0.1)));
        let tri = [
            Vector2::new(0.0, 0.0),
            Vector2::new(1.0, 0.0),
            Vector2::new(0.0, 1.0),
        ];
        assert!(in_cell(ElementKind::Tri3, &tri, &Vector2::new(0.2, 0.2)));
        assert!(!in_cell(ElementKind::Tri3, &tri, &Vector2::new(0.6, 0.6)));
        let hex: Vec<Vector3<f64>> = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ]
        .iter()
        .map(|c| Vector3::new(c[0], c[1], c[2]))
        .collect();
        assert!(in_cell(
            ElementKind::Hex8,
            &hex,
            &Vector3::new(0.9, 0.5, 0.1)
        ));
        assert!(!in_cell(
            ElementKind::Hex8,
            &hex,
            &Vector3::new(1.1, 0.5, 0.1)
        ));
    }
}
