//! The surfaces that can touch: every body's boundary facets (the masters) and boundary nodes
//! (the slaves), with the adjacency the narrow phase's self-contact rules read.

use nalgebra::SVector;

use crate::dim::{Dim, SpatialDim};
use crate::mesh::Mesh;

/// The surfaces that can touch: every body's boundary facets and boundary nodes, in global node
/// ids (a body's local node `i` is global node `node_offsets[body] + i`).
#[derive(Debug, Clone)]
pub struct ContactSurface<const D: usize> {
    pub(super) facets: Vec<[usize; D]>,
    pub(super) facet_body: Vec<usize>,
    pub(super) slaves: Vec<usize>,
    pub(super) slave_body: Vec<usize>,
    /// Whether the facets belong to more than one body.
    several_bodies: bool,
    /// CSR: the facets around each global node.
    node_facet_offsets: Vec<usize>,
    node_facets: Vec<usize>,
}

impl<const D: usize> ContactSurface<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// The boundary facets (outward, quadrangles split) and boundary nodes of the bodies.
    pub fn from_bodies(meshes: &[&Mesh<D>], node_offsets: &[usize]) -> Self {
        let facets: Vec<Vec<[usize; D]>> = meshes.iter().map(|m| m.boundary_facets()).collect();
        Self::from_facets(&facets, node_offsets)
    }

    /// A surface from each body's facets in local node ids, outward oriented (2D: the body on
    /// the left of each segment; 3D: counter-clockwise seen from outside). The slaves are the
    /// nodes of the facets.
    ///
    /// # Panics
    /// If `bodies` and `node_offsets` differ in length.
    pub fn from_facets(bodies: &[Vec<[usize; D]>], node_offsets: &[usize]) -> Self {
        assert_eq!(bodies.len(), node_offsets.len(), "one node offset per body");
        let mut facets = Vec::new();
        let mut facet_body = Vec::new();
        for (b, (fs, &off)) in bodies.iter().zip(node_offsets).enumerate() {
            for f in fs {
                facets.push(f.map(|i| i + off));
                facet_body.push(b);
            }
        }
        let node_count = facets.iter().flatten().map(|&i| i + 1).max().unwrap_or(0);
        let mut node_facet_offsets = vec![0usize; node_count + 1];
        for f in &facets {
            for &v in f {
                node_facet_offsets[v + 1] += 1;
            }
        }
        for i in 0..node_count {
            node_facet_offsets[i + 1] += node_facet_offsets[i];
        }
        let mut fill = node_facet_offsets.clone();
        let mut node_facets = vec![0usize; node_facet_offsets[node_count]];
        for (fi, f) in facets.iter().enumerate() {
            for &v in f {
                node_facets[fill[v]] = fi;
                fill[v] += 1;
            }
        }
        let mut slaves = Vec::new();
        let mut slave_body = Vec::new();
        for n in 0..node_count {
            let (a, b) = (node_facet_offsets[n], node_facet_offsets[n + 1]);
            if a < b {
                slaves.push(n);
                slave_body.push(facet_body[node_facets[a]]);
            }
        }
        ContactSurface {
            several_bodies: facet_body.windows(2).any(|w| w[0] != w[1]),
            facets,
            facet_body,
            slaves,
            slave_body,
            node_facet_offsets,
            node_facets,
        }
    }

    /// The master facets, global node ids.
    pub fn facets(&self) -> &[[usize; D]] {
        &self.facets
    }

    /// The body of each facet.
    pub fn facet_body(&self) -> &[usize] {
        &self.facet_body
    }

    /// Whether the surface's facets belong to more than one body.
    pub fn has_several_bodies(&self) -> bool {
        self.several_bodies
    }

    /// The slave nodes (global ids, sorted).
    pub fn slaves(&self) -> &[usize] {
        &self.slaves
    }

    /// The body of each slave (same order as [`ContactSurface::slaves`]).
    pub fn slave_body(&self) -> &[usize] {
        &self.slave_body
    }

    /// The facets around a global node (empty for a node off the surface).
    pub fn facets_of_node(&self, node: usize) -> &[usize] {
        if node + 1 >= self.node_facet_offsets.len() {
            return &[];
        }
        &self.node_facets[self.node_facet_offsets[node]..self.node_facet_offsets[node + 1]]
    }

    /// Whether self-contact excludes `facet` for the slave `node`: the facet shares the node,
    /// or shares a node with a facet that does.
    pub fn is_excluded(&self, node: usize, facet: usize) -> bool {
        let f = &self.facets[facet];
        if f.contains(&node) {
            return true;
        }
        self.facets_of_node(node)
            .iter()
            .any(|&g| self.facets[g].iter().any(|v| f.contains(v)))
    }

    /// The `count` surface nodes nearest to `node` along the surface's edges at positions `x`,
    /// with their path lengths (m), nearest first (`node` itself first, at 0): Dijkstra over
    /// the few nodes around it.
    pub fn nearest_along_surface(
        &self,
        node: usize,
        x: &[SVector<f64, D>],
        count: usize,
    ) -> Vec<(usize, f64)> {
        let mut settled: Vec<(usize, f64)> = Vec::new();
        let mut frontier: Vec<(f64, usize)> = vec![(0.0, node)];
        // Linear scans: `count` is a few dozen.
        while let Some(k) =
            (0..frontier.len()).min_by(|&a, &b| frontier[a].0.total_cmp(&frontier[b].0))
        {
            let (d, u) = frontier.swap_remove(k);
            if settled.iter().any(|s| s.0 == u) {
                continue;
            }
            settled.push((u, d));
            if settled.len() >= count {
                break;
            }
            for &f in self.facets_of_node(u) {
                for &v in &self.facets[f] {
                    if v != u && !settled.iter().any(|s| s.0 == v) {
                        frontier.push((d + (x[v] - x[u]).norm(), v));
                    }
                }
            }
        }
        settled
    }

    /// The area-weighted outward normal of a surface node at positions `x` (m) (not
    /// normalised; zero off the surface).
    pub fn node_normal(&self, node: usize, x: &[SVector<f64, D>]) -> SVector<f64, D> {
        let mut n = SVector::zeros();
        for &f in self.facets_of_node(node) {
            let (m, normal) = <Dim<D>>::facet_measure_normal(&self.facets[f].map(|v| x[v]));
            n += normal * m;
        }
        n
    }

    /// One past the largest node id used.
    pub fn node_count(&self) -> usize {
        self.node_facet_offsets.len().saturating_sub(1)
    }
}
