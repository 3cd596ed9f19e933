//! Nodes inside another body, the body itself or an obstacle at any depth
//! (`contact::inside`): the overlaps at t = 0 ([`Simulation::overlaps`],
//! [`Simulation::check_overlaps`]) and the fall-through monitor ([`Simulation::fell_through`]),
//! which contact detection alone cannot see beyond its margin; and the tunnelling watch
//! ([`Simulation::tunnelled`]): nodes that passed through an obstacle within a step and ended
//! outside it, where no test of the end of the step can see them; and a body's own cells
//! turned inside out ([`Simulation::inverted_cell`]).

use std::collections::BTreeMap;

use nalgebra::SVector;

use super::monitor::{Overlap, Tunnel};
use super::Simulation;
use crate::contact::detection::{ContactSurface, Detector};
use crate::contact::inside::{obstacle_depth, passes_through, CellIndex, FacetSolid};
use crate::contact::{Master, Obstacle, ObstacleShape};
use crate::dim::{Dim, SpatialDim};
use crate::element::ElementKind;
use crate::error::{Error, Result};
use crate::geometry::Aabb;

/// What a node is inside (indices in scene order).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Inside {
    Body(usize),
    Obstacle(usize),
}

/// The geometry searched, built once: each obstacle's facets (polyline, trimesh) and every
/// cell of every body as (body, kind, global nodes).
pub(crate) struct Solids<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    obstacles: Vec<Option<FacetSolid<D>>>,
    cells: Vec<(usize, ElementKind, Vec<usize>)>,
}

/// A step (or a piece of a cut step) as detection swept it: node positions at its start and
/// end (the gaps' configuration, m), the obstacles' poses at both, its length (s), and the
/// broad phase's (node, obstacle) pairs against boxes, balls, polylines and trimeshes.
pub(crate) struct Sweep<const D: usize> {
    pub(crate) x0: Vec<SVector<f64, D>>,
    pub(crate) x1: Vec<SVector<f64, D>>,
    pub(crate) obstacles_t0: Vec<Obstacle<D>>,
    pub(crate) obstacles_t1: Vec<Obstacle<D>>,
    pub(crate) h: f64,
    pub(crate) candidates: Vec<(usize, usize)>,
}

/// The last broad phase's (node, obstacle) pairs against obstacles a node can pass through
/// (boxes, balls, polylines, trimeshes): the tunnelling watch's prefilter (the node's path
/// over the step meets the obstacle's region swept over it, grown by the margin). `None` when
/// there is no such obstacle.
pub(crate) fn through_candidates<const D: usize>(
    detector: &Detector<D>,
    obstacles: &[Obstacle<D>],
) -> Option<Vec<(usize, usize)>>
where
    Dim<D>: SpatialDim<D>,
{
    let solid = |k: usize| !matches!(obstacles[k].shape, ObstacleShape::Halfspace { .. });
    if !(0..obstacles.len()).any(solid) {
        return None;
    }
    Some(
        detector
            .candidates()
            .iter()
            .filter_map(|&(n, m)| match m {
                Master::Obstacle(k) if solid(k) => Some((n, k)),
                _ => None,
            })
            .collect(),
    )
}

/// A slave node inside something, with its depth (m).
struct NodeInside {
    body: usize,
    other: Inside,
    depth: f64,
}

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    fn solids(&self) -> &Solids<D> {
        self.caches.solids.get_or_init(|| Solids {
            obstacles: self
                .model
                .obstacles
                .iter()
                .map(|o| FacetSolid::of_obstacle(&o.shape))
                .collect(),
            cells: self
                .model
                .bodies
                .iter()
                .enumerate()
                .flat_map(|(b, body)| {
                    let offset = self.node_offsets[b];
                    body.mesh.blocks.iter().flat_map(move |block| {
                        block
                            .cells()
                            .map(move |c| (b, block.kind, c.iter().map(|&n| n + offset).collect()))
                    })
                })
                .collect(),
        })
    }

    /// The reach of contact detection (m): its margin, a quarter of the mean boundary facet.
    /// A node farther than that from every facet of a polyline, a trimesh or another body is
    /// not found (half-spaces, boxes and balls are found at any depth); 0 without contact.
    pub fn detection_reach(&self) -> f64 {
        self.caches
            .detector
            .as_ref()
            .map_or(0.0, |d| d.options().margin)
    }

    /// Every boundary node inside another body or an obstacle in the current configuration,
    /// at any depth; `analytic` includes half-spaces, boxes and balls; `itself` includes
    /// nodes inside their own body's cells (not the cells that hold them); `skip(node,
    /// other)` leaves a pair out before its depth is computed.
    fn nodes_inside(
        &self,
        analytic: bool,
        itself: bool,
        skip: impl Fn(usize, Inside) -> bool,
    ) -> Vec<NodeInside> {
        // Without contact detection (one body, no obstacle, no self-contact) only the body's
        // own cells are searched, on its boundary built here.
        let built;
        let surface = match self.caches.detector.as_ref() {
            Some(detector) => detector.surface(),
            None if itself => {
                let meshes: Vec<&crate::mesh::Mesh<D>> =
                    self.model.bodies.iter().map(|b| &b.mesh).collect();
                built = ContactSurface::from_bodies(&meshes, &self.node_offsets);
                &built
            }
            None => return Vec::new(),
        };
        let x = self.positions();
        let obstacles = self.posed_obstacles();
        let solids = self.solids();
        let mut found = Vec::new();
        for (k, o) in obstacles.iter().enumerate() {
            let facets = matches!(o.shape, ObstacleShape::Facets { .. });
            if !facets && !analytic {
                continue;
            }
            for (&node, &body) in surface.slaves().iter().zip(surface.slave_body()) {
                if skip(node, Inside::Obstacle(k)) {
                    continue;
                }
                if let Some(depth) = obstacle_depth(o, solids.obstacles[k].as_ref(), &x[node]) {
                    found.push(NodeInside {
                        body,
                        other: Inside::Obstacle(k),
                        depth,
                    });
                }
            }
        }
        // The cells' hierarchy and the bodies' surfaces, built when first needed.
        let mut cells: Option<CellIndex<D>> = None;
        let mut surfaces: Option<FacetSolid<D>> = None;
        let bodies_surface = || {
            FacetSolid::new(
                x.clone(),
                surface
                    .facets()
                    .iter()
                    .copied()
                    .zip(surface.facet_body().iter().copied()),
            )
        };
        let mut hits = Vec::new();
        if self.model.bodies.len() > 1 {
            // Only nodes in another body's box, not already paired with it, are tested
            // against its cells: in a run, nodes near another body are its candidates, so
            // the cells' hierarchy is seldom built.
            let boxes: Vec<Aabb<D>> = (0..self.model.bodies.len())
                .map(|b| {
                    let end = self.node_offsets.get(b + 1).copied().unwrap_or(x.len());
                    Aabb::from_points(&x[self.node_offsets[b]..end])
                })
                .collect();
            let pending: Vec<(usize, usize, usize)> = surface
                .slaves()
                .iter()
                .zip(surface.slave_body())
                .flat_map(|(&node, &body)| {
                    let p = Aabb {
                        min: x[node],
                        max: x[node],
                    };
                    boxes
                        .iter()
                        .enumerate()
                        .filter(move |&(b, bb)| b != body && bb.intersects(&p))
                        .map(move |(b, _)| (node, body, b))
                })
                .filter(|&(node, _, b)| !skip(node, Inside::Body(b)))
                .collect();
            for (node, body, b) in pending {
                let index = cells.get_or_insert_with(|| CellIndex::new(&solids.cells, &x));
                if !index.holds(&x[node], b, &solids.cells, &x, &mut hits) {
                    continue;
                }
                let s = surfaces.get_or_insert_with(bodies_surface);
                let depth = s.distance(&x[node], b).unwrap_or(0.0);
                found.push(NodeInside {
                    body,
                    other: Inside::Body(b),
                    depth,
                });
            }
        }
        if itself {
            // A node in a cell of its own body that does not hold it: the mesh folds onto
            // itself. Its depth is the distance to the body's surface without the facets
            // around the node and their neighbours (those hold it or are next to it), so that
            // a node that only touches such a cell (duplicated at the same place, or hanging
            // on a face) is at depth 0, or a millionth of those facets.
            let index = cells.get_or_insert_with(|| CellIndex::new(&solids.cells, &x));
            let mut ring = Vec::new();
            for (&node, &body) in surface.slaves().iter().zip(surface.slave_body()) {
                if skip(node, Inside::Body(body))
                    || !index.holds_apart(&x[node], node, body, &solids.cells, &x, &mut hits)
                {
                    continue;
                }
                ring.clear();
                for &f in surface.facets_of_node(node) {
                    ring.extend_from_slice(&surface.facets()[f]);
                }
                let s = surfaces.get_or_insert_with(bodies_surface);
                let depth = s.distance_apart(&x[node], body, &ring).unwrap_or(0.0);
                // Round-off, relative to the facets around the node.
                let size = ring
                    .iter()
                    .map(|&r| (x[r] - x[node]).norm())
                    .fold(0.0, f64::max);
                if depth > 1e-6 * size {
                    found.push(NodeInside {
                        body,
                        other: Inside::Body(body),
                        depth,
                    });
                }
            }
        }
        found
    }

    /// Groups nodes inside by (body, other): (nodes, deepest, nodes deeper than the reach
    /// where it applies); nodes no deeper than `tolerance` are left out.
    fn group(
        &self,
        found: &[NodeInside],
        tolerance: f64,
    ) -> BTreeMap<(usize, Inside), (usize, f64, usize)> {
        let reach = self.detection_reach();
        let mut groups: BTreeMap<(usize, Inside), (usize, f64, usize)> = BTreeMap::new();
        for n in found {
            if n.depth <= tolerance {
                continue;
            }
            let key = (n.body, n.other);
            let unreached = n.depth > reach && self.needs_reach(n.other);
            let e = groups.entry(key).or_insert((0, 0.0, 0));
            e.0 += 1;
            e.1 = f64::max(e.1, n.depth);
            e.2 += usize::from(unreached);
        }
        groups
    }

    /// Whether detection reaches only `reach` into `other` (another body, a polyline or a
    /// trimesh), not all of it (half-space, box, ball).
    fn needs_reach(&self, other: Inside) -> bool {
        match other {
            Inside::Body(_) => true,
            Inside::Obstacle(k) => {
                matches!(self.model.obstacles[k].shape, ObstacleShape::Facets { .. })
            }
        }
    }

    fn overlap(
        &self,
        (body, other): (usize, Inside),
        (nodes, depth, beyond): (usize, f64, usize),
    ) -> Overlap {
        Overlap {
            body: self.model.bodies[body].name.clone(),
            other: match other {
                Inside::Body(b) if b == body => "itself".into(),
                Inside::Body(b) => format!("body `{}`", self.model.bodies[b].name),
                Inside::Obstacle(k) => format!("obstacle `{}`", self.model.obstacles[k].name),
            },
            nodes,
            depth,
            facets: matches!(other, Inside::Obstacle(k)
                if matches!(self.model.obstacles[k].shape, ObstacleShape::Facets { .. })),
            beyond_reach: beyond,
            reach: if self.needs_reach(other) {
                self.detection_reach()
            } else {
                f64::INFINITY
            },
        }
    }

    /// Overlaps in the current configuration, of any depth: boundary nodes of a body inside
    /// another body (in one of its cells), itself (in one of its cells that does not hold the
    /// node: a mesh folded onto itself; [`Overlap::other`] is `itself`) or an obstacle (on its
    /// solid side: see
    /// `contact::inside`), deeper than a millionth of the mean boundary facet (round-off of
    /// bodies placed exactly in touch is not one), one per body and what its nodes are inside
    /// (two bodies that overlap each other: one for each), in scene order. The depth is the distance to the nearest
    /// surface; [`Overlap::beyond_reach`] counts the nodes that contact detection does not
    /// find ([`Simulation::detection_reach`]).
    pub fn overlaps(&self) -> Vec<Overlap> {
        // The reach is a quarter of the mean facet: a millionth of the facet.
        let tolerance = 4e-6 * self.detection_reach();
        let found = self.nodes_inside(true, true, |_, _| false);
        self.group(&found, tolerance)
            .into_iter()
            .map(|(k, v)| self.overlap(k, v))
            .collect()
    }

    /// The overlaps (see [`Simulation::overlaps`]), or [`Error::Overlap`] for the first whose
    /// nodes lie deeper than contact detection reaches: no contact method ever pushes those
    /// out, so the run could only let the body fall through or stay stuck. What `softway
    /// check` and `run` refuse at t = 0 (exit status 2); shallower ones are warnings.
    pub fn check_overlaps(&self) -> Result<Vec<Overlap>> {
        let overlaps = self.overlaps();
        if let Some(o) = overlaps.iter().find(|o| o.beyond_reach > 0) {
            return Err(Error::Overlap {
                body: o.body.clone(),
                other: o.other.clone(),
                nodes: o.nodes,
                beyond: o.beyond_reach,
                depth: o.depth,
                reach: o.reach,
                hint: if o.other == "itself" {
                    SELF_OVERLAP_HINT.into()
                } else {
                    facet_hint(o.facets)
                },
            });
        }
        Ok(overlaps)
    }

    /// The fall-through monitor: boundary nodes that end up inside another body, a polyline or
    /// a trimesh deeper than contact detection reaches and that the last detection did not
    /// pair with it (they crossed its surface within a step without being caught, or were
    /// inside all along). The group with the most such nodes, as an [`Overlap`] (all its
    /// nodes beyond reach); `None` when there is none.
    pub fn fell_through(&self) -> Option<Overlap> {
        let detector = self.caches.detector.as_ref()?;
        // Half-spaces, boxes and balls are found at any depth: nothing to watch without a
        // polyline, a trimesh or a second body.
        let facets = self
            .model
            .obstacles
            .iter()
            .any(|o| matches!(o.shape, ObstacleShape::Facets { .. }));
        if !facets && self.model.bodies.len() < 2 {
            return None;
        }
        let facet_body = detector.surface().facet_body();
        let mut reached: Vec<(usize, Inside)> = detector
            .candidates()
            .iter()
            .map(|&(n, m)| match m {
                Master::Obstacle(k) => (n, Inside::Obstacle(k)),
                Master::Facet(f) => (n, Inside::Body(facet_body[f])),
            })
            .collect();
        reached.sort_unstable();
        reached.dedup();
        let reach = self.detection_reach();
        let found: Vec<NodeInside> = self
            .nodes_inside(false, false, |n, o| reached.binary_search(&(n, o)).is_ok())
            .into_iter()
            .filter(|n| n.depth > reach)
            .collect();
        self.group(&found, reach)
            .into_iter()
            .max_by(|a, b| a.1 .0.cmp(&b.1 .0).then(b.0.cmp(&a.0)))
            .map(|(k, v)| self.overlap(k, v))
    }
}

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// The first cell of any body turned inside out in the current configuration (a
    /// negative Jacobian at a quadrature point): its body's name, its index in that
    /// body's mesh and its centre (m). A small-strain law does not resist such a fold: the
    /// nodes pass through one another with finite stresses, and contact, which holds only
    /// boundary nodes, does not see interior nodes leaving through the boundary (a block
    /// thrown hard at a floor under implicit projection: its boundary held on the floor, its
    /// interior going on below it).
    pub fn inverted_cell(&self) -> Option<(String, usize, SVector<f64, D>)> {
        self.model.bodies.iter().enumerate().find_map(|(b, body)| {
            let start = self.node_offsets[b];
            let positions: Vec<SVector<f64, D>> = (start..start + body.mesh.nodes.len())
                .map(|g| self.reference[g] + Self::node_vector(&self.state.displacement, g))
                .collect();
            body.mesh
                .inverted_cell(&positions)
                .map(|(cell, centre)| (body.name.clone(), cell, centre))
        })
    }

    /// The tunnelling watch: boundary nodes whose straight path over the last step (each piece
    /// of a cut step), relative to an obstacle, passed through it and ended outside on its far
    /// side (see `contact::inside::passes_through`): a fast body that crossed a thin box, a
    /// small ball or a closed trimesh within one step, which no test of the end of the step
    /// sees. Only the pairs the broad phase found (the node's path meets the obstacle's
    /// region swept over the step) are tested. The (body, obstacle) with the most such nodes,
    /// named by its fastest node; `None` when there is none. Half-spaces and open polylines
    /// or trimeshes have no far side ([`Simulation::fell_through`] watches those); bodies
    /// passing through each other within a step are not watched.
    pub fn tunnelled(&self) -> Option<Tunnel> {
        if self.sweeps.is_empty() {
            return None;
        }
        let reach = self.detection_reach();
        let solids = self.solids();
        let n = self.reference.len();
        // (body, obstacle) -> (nodes, fastest: (speed, node, travel, inside, h)).
        type Fastest = (f64, usize, f64, f64, f64);
        let mut groups: BTreeMap<(usize, usize), (usize, Fastest)> = BTreeMap::new();
        for sweep in &self.sweeps {
            if sweep.x0.len() != n || sweep.x1.len() != n {
                continue;
            }
            for &(node, k) in &sweep.candidates {
                let Some(c) = passes_through(
                    &sweep.obstacles_t0[k],
                    &sweep.obstacles_t1[k],
                    solids.obstacles[k].as_ref(),
                    &sweep.x0[node],
                    &sweep.x1[node],
                    reach,
                ) else {
                    continue;
                };
                let body = self.body_of_node(node);
                let speed = c.travel / sweep.h;
                let e = groups
                    .entry((body, k))
                    .or_insert((0, (f64::NEG_INFINITY, 0, 0.0, 0.0, 0.0)));
                e.0 += 1;
                if speed > e.1 .0 {
                    e.1 = (speed, node, c.travel, c.inside, sweep.h);
                }
            }
        }
        groups
            .into_iter()
            .max_by(|a, b| a.1 .0.cmp(&b.1 .0).then(b.0.cmp(&a.0)))
            .map(
                |((body, k), (nodes, (speed, node, travel, inside, h)))| Tunnel {
                    body: self.model.bodies[body].name.clone(),
                    node: node - self.node_offsets[body],
                    other: format!("obstacle `{}`", self.model.obstacles[k].name),
                    nodes,
                    speed,
                    travel,
                    inside,
                    crossing_time: h * inside / travel,
                },
            )
    }
}

/// Appended to the messages about a body that overlaps itself.
pub(crate) const SELF_OVERLAP_HINT: &str =
    "; or rather, since it overlaps itself, fix its mesh: cells of one part of it lie over \
     cells of another (a mesh folded onto itself, arms that cross)";

/// The orientation of polyline and trimesh facets, appended to messages about them.
pub(crate) fn facet_hint(facets: bool) -> String {
    if facets {
        "; a polyline is solid on the left of each segment (from its first vertex to its \
         second), a trimesh behind each triangle (counter-clockwise seen from outside): if the \
         body should be on the other side, reverse each facet's vertex order"
            .into()
    } else {
        String::new()
    }
}
