//! Contact detection: which slave nodes touch which master surfaces, with the signed gap of
//! method.md section 2.
//!
//! * **Slaves** are the boundary nodes of every body; **masters** are the rigid obstacles and
//!   the boundary facets (segments in 2D, triangles in 3D) of every body.
//! * **Broad phase** ([`Detector::update_candidates`]): each facet's box swept over the step (its
//!   nodes at `x0` and `x1`, grown by [`DetectionOptions::margin`]) sits in a bounding-volume
//!   hierarchy built once and refitted per call; each slave's segment `x0 -> x1` is tested
//!   against it and against every obstacle's region swept between its poses at t0 and t1
//!   (translation, and rotation about its pivot). A node that travels several thicknesses of a body within one step still meets the
//!   facets it crosses; one that goes through a whole body (ends beyond its far face) is seen
//!   outside at the end of the step: step control must prevent that.
//! * **Narrow phase** ([`Detector::pairs`]): for each slave and each master body (or obstacle)
//!   among the candidates, the closest facet, its closest point Q, the feature holding Q, the
//!   barycentric weights of Q, the facet's outward normal n and the gap `g = (x_P - Q) . n`.
//! * **Deformable against deformable**: every body's nodes are slaves of every other body's
//!   facets, so both surfaces act as master (two passes, symmetric); a resolution method that
//!   wants a single pass keeps one of the two pairs.
//! * **Self-contact** (option): a node is never paired with the facets that share it nor with
//!   their immediate neighbours (facets sharing a node with those), only with facets that face
//!   it (the node's averaged outward normal and the facet's normal point against each other),
//!   and, when it penetrates, only while it is nearer the facet than a third of the path along
//!   the surface to it (a node beside its own corner lies behind the far side's facet).

use std::collections::HashMap;

use nalgebra::{SMatrix, SVector};

use crate::contact::gap::{point_gap, posed_obstacle_gap};
use crate::contact::obstacle::{Obstacle, ObstacleShape};
use crate::contact::{ContactKey, MasterId};
use crate::dim::{Dim, SpatialDim};
pub use crate::geometry::Feature;
use crate::geometry::{Aabb, BoxTree, GeometryDim};

pub use super::surface::ContactSurface;

/// Detection parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectionOptions {
    /// Detect a body's nodes against its own facets. Default false.
    pub self_contact: bool,
    /// Distance (m) added to the swept boxes of the broad phase, and the activation distance
    /// of the narrow phase: a pair is reported while its gap is below it. Default 0.
    pub margin: f64,
    /// Detect each body's nodes against the other bodies' facets. Default true.
    pub deformable_pairs: bool,
    /// Hysteresis (m): the master facet chosen at the previous call for a (slave, master) is
    /// kept while it is no farther than the closest one plus this distance, so that the normal
    /// does not flip between Newton iterations near edges and corners. Default 0 (exact ties
    /// only keep the previous choice).
    pub hysteresis: f64,
    /// Pair a node with another body's facets only when they face each other (opposed
    /// normals), as self-contact always does. At flush corners (two bars meeting head on) the
    /// closest facet is otherwise a side face that the node merely lies on the extension of.
    /// The simulation turns it on; default false (pure closest facet).
    pub facing: bool,
    /// Keep a node's master facet, within [`LOCKED_REACH`] of its size, once it changed
    /// [`FLIPS_BEFORE_LOCK`] times since the memory was set (between facets whose normals
    /// differ by more than [`FLIP_ANGLE`]), until [`Detector::release_facet_locks`]. The
    /// simulation turns it on for implicit projection, whose held normal velocity flips with
    /// the facet; default false. (The soft way's 3D stack sank twice as deep with it: 1.03e-4
    /// m against 5.3e-5, its nodes at the blocks' edges held to the top face or the side.)
    pub lock_flipping_facets: bool,
}

impl Default for DetectionOptions {
    fn default() -> Self {
        DetectionOptions {
            self_contact: false,
            margin: 0.0,
            deformable_pairs: true,
            hysteresis: 0.0,
            facing: false,
            lock_flipping_facets: false,
        }
    }
}

/// The master side of a contact candidate or pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Master {
    /// A rigid obstacle (index in the obstacle slice).
    Obstacle(usize),
    /// A facet of a body (index in [`ContactSurface::facets`]).
    Facet(usize),
}

/// One active contact: a slave node against a master, at the narrow-phase configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactPair<const D: usize> {
    /// The slave node (global id).
    pub slave: usize,
    /// The master: the obstacle, or the chosen facet of the master body.
    pub master: Master,
    /// Signed gap `(x_P - Q) . n` (m); negative is penetration.
    pub gap: f64,
    /// Unit outward normal of the master at Q (the facet's normal for a facet).
    pub normal: SVector<f64, D>,
    /// The closest point Q on the master (m).
    pub point: SVector<f64, D>,
    /// Weights of the master facet's nodes at Q (`[1, 0, ..]` for an obstacle).
    pub barycentric: [f64; D],
    /// The feature of the master holding Q.
    pub feature: Feature,
}

/// A facet obstacle's geometry in its frame at zero translation, with its hierarchy.
struct ObstacleFacets<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    sizes: (usize, usize),
    vertices: Vec<SVector<f64, D>>,
    facets: Vec<[usize; D]>,
    boxes: Vec<Aabb<D>>,
    tree: BoxTree<D>,
    bounds: Aabb<D>,
}

impl<const D: usize> ObstacleFacets<D>
where
    Dim<D>: SpatialDim<D>,
{
    fn new(vertices: &[SVector<f64, D>], indices: &[Vec<usize>]) -> Self {
        // Malformed facets (wrong arity, index out of range) are skipped, not fatal.
        let facets: Vec<[usize; D]> = indices
            .iter()
            .filter(|f| f.len() == D && f.iter().all(|&i| i < vertices.len()))
            .map(|f| std::array::from_fn(|k| f[k]))
            .collect();
        let boxes: Vec<Aabb<D>> = facets
            .iter()
            .map(|f| Aabb::from_points(f.iter().map(|&i| &vertices[i])))
            .collect();
        let bounds = boxes.iter().fold(Aabb::from_points([]), |a, b| a.merged(b));
        ObstacleFacets {
            sizes: (vertices.len(), indices.len()),
            vertices: vertices.to_vec(),
            facets,
            tree: BoxTree::new(&boxes),
            boxes,
            bounds,
        }
    }

    fn verts(&self, f: usize) -> [SVector<f64, D>; D] {
        self.facets[f].map(|i| self.vertices[i])
    }
}

/// `x > 0`, false for NaN.
fn positive(x: f64) -> bool {
    x > 0.0
}

/// The closest facet chosen for one point.
#[derive(Debug, Clone, Copy)]
struct Choice<const D: usize> {
    facet: usize,
    point: SVector<f64, D>,
    barycentric: [f64; D],
    feature: Feature,
    normal: SVector<f64, D>,
    gap: f64,
}

/// Chooses the master facet for point `p` among `candidates`: the closest one; among facets
/// at the same distance (a shared edge or vertex), the one whose normal best follows `p - Q`
/// (largest gap), then the lowest index; the previous choice is kept while it is within
/// `hysteresis` (m) of the closest. Degenerate facets and those `accept` rejects are skipped.
fn choose<const D: usize>(
    p: &SVector<f64, D>,
    candidates: impl Iterator<Item = usize>,
    verts: impl Fn(usize) -> [SVector<f64, D>; D],
    accept: impl Fn(&SVector<f64, D>) -> bool,
    keep: impl Fn(usize, f64, f64) -> bool,
    previous: Option<usize>,
    hysteresis: f64,
) -> Option<Choice<D>>
where
    Dim<D>: SpatialDim<D>,
{
    let mut best: Option<(f64, f64, Choice<D>)> = None;
    let mut kept: Option<(f64, Choice<D>)> = None;
    for f in candidates {
        let v = verts(f);
        let (measure, normal) = <Dim<D>>::facet_measure_normal(&v);
        if !positive(measure) || !accept(&normal) {
            continue;
        }
        let Some(proj) = <Dim<D>>::project_on_facet(p, &v) else {
            continue;
        };
        let d = (p - proj.point).norm();
        let gap = point_gap(p, &proj.point, &normal);
        if !keep(f, gap, d) {
            continue;
        }
        let c = Choice {
            facet: f,
            point: proj.point,
            barycentric: proj.barycentric,
            feature: proj.feature,
            normal,
            gap,
        };
        // Ties are relative to the facet size: exact ties at shared features differ by
        // rounding only.
        let tol = 1e-9 * (v[1] - v[0]).norm().max(d);
        if Some(f) == previous {
            kept = Some((d, c));
        }
        best = match best {
            None => Some((d, tol, c)),
            Some((bd, btol, bc)) => {
                let t = tol.max(btol);
                if d < bd - t || (d <= bd + t && gap > bc.gap) {
                    Some((d.min(bd), t, c))
                } else {
                    Some((bd.min(d), t, bc))
                }
            }
        };
    }
    let (bd, tol, bc) = best?;
    match kept {
        Some((d, c)) if d <= bd + hysteresis + tol => Some(c),
        _ => Some(bc),
    }
}

/// Broad and narrow phase over a [`ContactSurface`]; see the module documentation.
pub struct Detector<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    surface: ContactSurface<D>,
    options: DetectionOptions,
    facet_boxes: Vec<Aabb<D>>,
    tree: Option<BoxTree<D>>,
    candidates: Vec<(usize, Master)>,
    obstacle_facets: Vec<Option<ObstacleFacets<D>>>,
    /// The master feature chosen last for each (slave, master): the narrow phase keeps it
    /// while it stays within the hysteresis (see [`Detector::memory`]).
    previous: HashMap<ContactKey, usize>,
    /// How many times each (slave, body) changed its master facet since the memory was last
    /// set (a step's start): from [`FLIPS_BEFORE_LOCK`] on, the facet it has is kept.
    flips: HashMap<ContactKey, u32>,
}

/// Changes of master facet within a step after which a node keeps its facet until the step
/// ends (while it stays a candidate). A node in the concave V that its own push dents under a
/// vertex of the other body (the soft ring on the soft pad, `tests/two_bodies.rs`: facets
/// 2.4 degrees apart) crossed the vertex by 0.1 mm at each Newton iteration, beyond the
/// hysteresis: the normal flipped, the velocity constraint pushed it back, and no full step
/// converged from the first contact on (82 of 200 steps cut, the account off by 112 %).
/// Locked after two changes, one step of 200 is cut and the account closes to 8.7e-3.
/// The same rule as implicit projection's node locking for the active set.
pub const FLIPS_BEFORE_LOCK: u32 = 2;

/// A change of master facet counts towards the lock when the normals differ by more than this
/// (rad): the two triangles of a flat quadrangle, or facets that strain tilts by a fraction of
/// a degree, are left to the hysteresis (a 3D stack's nodes slide across such diagonals,
/// and a facet kept far beyond its edge spreads the force with negative weights).
pub const FLIP_ANGLE: f64 = 1e-2;

/// How far a locked facet is kept, over its size: beyond, the closest facet is taken again.
pub const LOCKED_REACH: f64 = 0.05;

/// A facet's longest edge (m).
fn facet_size<const D: usize>(v: &[SVector<f64, D>; D]) -> f64 {
    (0..D)
        .map(|i| (v[(i + 1) % D] - v[i]).norm())
        .fold(0.0, f64::max)
}

/// Self-contact keeps a penetrating pair only while the distance to its closest point is
/// below this fraction of the path along the surface from the slave to the facet's nearest
/// node. A node beside a convex corner of interior angle theta lies below the far side's
/// facet at a depth of `path tan(theta / 2)`, inside its own body and touching nothing: a
/// third rejects every corner of more than 37 degrees (the facing test rejects those of more
/// than 90), and beside a split quadrangle's diagonal, where the closest point lies on an edge
/// off to the side, the distance counts and not the depth. A fold's two sides meet far along
/// the surface and keep their pairs. (The tube crush's curl: a node 0.15 mm below the top
/// end's inner corner was paired with the end face 0.146 mm deep, and pushed out of its own
/// corner with 1.5 kN.)
const SELF_CONTACT_DISTANCE_OVER_PATH: f64 = 1.0 / 3.0;

/// The nodes nearest along the surface that the self-contact rule looks at: a facet beyond
/// them keeps its pair.
const PATH_SEARCH_NODES: usize = 32;

/// Slaves per traversal of the hierarchy in the broad phase.
const GROUP: usize = 8;

/// Candidate pairs of the slaves `slaves[start..start + chunk.len()]`.
type Chunk = Vec<(usize, Master)>;

/// `f` over `items` in chunks of 512 (each given its first item's index), the results
/// flattened in order.
fn map_chunks<T: Sync, R: Send>(
    items: &[T],
    f: impl Fn(usize, &[T]) -> Vec<R> + Sync + Send,
) -> Vec<R> {
    crate::parallel::map_chunks(items, 512, f)
        .into_iter()
        .flatten()
        .collect()
}

impl<const D: usize> Detector<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// A detector over `surface`; the hierarchy is built at the first
    /// [`Detector::update_candidates`].
    pub fn new(surface: ContactSurface<D>, options: DetectionOptions) -> Self {
        Detector {
            surface,
            options,
            facet_boxes: Vec::new(),
            tree: None,
            candidates: Vec::new(),
            obstacle_facets: Vec::new(),
            previous: HashMap::new(),
            flips: HashMap::new(),
        }
    }

    /// The surface.
    pub fn surface(&self) -> &ContactSurface<D> {
        &self.surface
    }

    /// The options.
    pub fn options(&self) -> &DetectionOptions {
        &self.options
    }

    /// Changes the options (takes effect at the next call).
    pub fn set_options(&mut self, options: DetectionOptions) {
        self.options = options;
    }

    /// The candidates of the last [`Detector::update_candidates`]: (slave node, master),
    /// sorted by slave, then obstacles before facets, then index.
    pub fn candidates(&self) -> &[(usize, Master)] {
        &self.candidates
    }

    /// Drops the hierarchy so that the next [`Detector::update_candidates`] builds it anew.
    /// Refitting keeps the topology of the first build; after large deformations (the tree
    /// then still answers exactly, only slower) a rebuild restores its quality.
    pub fn rebuild_hierarchy(&mut self) {
        self.tree = None;
    }

    /// The narrow phase's memory: the master facet (or obstacle feature) chosen last for each
    /// (slave, master), sorted. It changes which facet a node is paired with, so it is part of
    /// the simulation's state (restored when a step fails, stored in checkpoints).
    pub fn memory(&self) -> Vec<(ContactKey, usize)> {
        let mut m: Vec<(ContactKey, usize)> = self.previous.iter().map(|(k, v)| (*k, *v)).collect();
        m.sort_unstable();
        m
    }

    /// Replaces the narrow phase's memory (see [`Detector::memory`]).
    /// The count of facet changes that locks a node's facet ([`FLIPS_BEFORE_LOCK`]) starts
    /// again from zero: the simulation sets the memory at the start of every step.
    pub fn set_memory(&mut self, memory: &[(ContactKey, usize)]) {
        self.previous = memory.iter().copied().collect();
        self.flips.clear();
    }

    /// Ends the locks of master facets that changed too often ([`FLIPS_BEFORE_LOCK`]): the
    /// next calls choose the closest facet again (with the hysteresis).
    pub fn release_facet_locks(&mut self) {
        self.flips.clear();
    }

    /// The swept box of every facet at the last update (m; the broad phase's leaves): empty
    /// when no facet can be a master (one body, no self-contact).
    pub fn facet_boxes(&self) -> &[Aabb<D>] {
        &self.facet_boxes
    }

    /// (Re)builds the hierarchies of the facet obstacles whose sizes changed. Obstacle shapes
    /// are rigid: only their pose may change between calls.
    fn sync_obstacles(&mut self, obstacles: &[Obstacle<D>]) {
        self.obstacle_facets.resize_with(obstacles.len(), || None);
        for (k, o) in obstacles.iter().enumerate() {
            match &o.shape {
                ObstacleShape::Facets { vertices, indices } => {
                    let sizes = (vertices.len(), indices.len());
                    if self.obstacle_facets[k].as_ref().map(|c| c.sizes) != Some(sizes) {
                        self.obstacle_facets[k] = Some(ObstacleFacets::new(vertices, indices));
                    }
                }
                _ => self.obstacle_facets[k] = None,
            }
        }
    }

    /// Broad phase over a step: each slave's segment from `x0` to `x1` against each facet's
    /// box swept from `x0` to `x1` (grown by the margin), and against each obstacle's region
    /// swept from its `translation` (t0) to `obstacle_translation_t1` (t1), grown by the
    /// margin. `x0`, `x1` are global node positions (m). Deterministic order.
    ///
    /// # Panics
    /// If `x0` or `x1` is shorter than [`ContactSurface::node_count`], or the translations do
    /// not match the obstacles.
    pub fn update_candidates(
        &mut self,
        x0: &[SVector<f64, D>],
        x1: &[SVector<f64, D>],
        obstacles: &[Obstacle<D>],
        obstacle_translation_t1: &[SVector<f64, D>],
    ) {
        assert_eq!(
            obstacles.len(),
            obstacle_translation_t1.len(),
            "one t1 translation per obstacle"
        );
        let poses: Vec<_> = obstacles
            .iter()
            .zip(obstacle_translation_t1)
            .map(|(o, t)| (*t, o.rotation))
            .collect();
        self.candidates_over_step(x0, x1, obstacles, &poses);
    }

    /// [`Detector::update_candidates`] with the obstacles in their poses at t0 and t1
    /// (translation and rotation about the pivot): a turning obstacle's region swept over the
    /// step is bounded in the frame of its shape (see `obstacle_overlaps`).
    ///
    /// # Panics
    /// As [`Detector::update_candidates`], or if the two obstacle slices differ in length.
    pub fn update_candidates_posed(
        &mut self,
        x0: &[SVector<f64, D>],
        x1: &[SVector<f64, D>],
        obstacles_t0: &[Obstacle<D>],
        obstacles_t1: &[Obstacle<D>],
    ) {
        assert_eq!(
            obstacles_t0.len(),
            obstacles_t1.len(),
            "one t1 pose per obstacle"
        );
        let poses: Vec<_> = obstacles_t1
            .iter()
            .map(|o| (o.translation, o.rotation))
            .collect();
        self.candidates_over_step(x0, x1, obstacles_t0, &poses);
    }

    /// The broad phase with each obstacle's (translation, rotation) at t1.
    fn candidates_over_step(
        &mut self,
        x0: &[SVector<f64, D>],
        x1: &[SVector<f64, D>],
        obstacles: &[Obstacle<D>],
        poses_t1: &[(SVector<f64, D>, SMatrix<f64, D, D>)],
    ) {
        let n = self.surface.node_count();
        assert!(
            x0.len() >= n && x1.len() >= n,
            "positions shorter than the surface's nodes"
        );
        let margin = self.options.margin.max(0.0);
        // Facets are masters only of self-contact and of other bodies' nodes: a lone body
        // against obstacles needs no hierarchy (a third of a small cube's step went to it).
        let facet_masters = self.options.self_contact
            || (self.options.deformable_pairs && self.surface.has_several_bodies());
        self.facet_boxes = if facet_masters {
            map_chunks(&self.surface.facets, |_, fs| {
                fs.iter()
                    .map(|f| {
                        Aabb::from_points(
                            f.iter().map(|&i| &x0[i]).chain(f.iter().map(|&i| &x1[i])),
                        )
                        .loosened(margin)
                    })
                    .collect()
            })
        } else {
            Vec::new()
        };
        match &mut self.tree {
            _ if !facet_masters => self.tree = None,
            Some(t) if t.len() == self.facet_boxes.len() => t.refit(&self.facet_boxes),
            _ => self.tree = Some(BoxTree::new(&self.facet_boxes)),
        }
        self.sync_obstacles(obstacles);
        let tree = self.tree.as_ref();
        let (surface, options, cache, facet_boxes) = (
            &self.surface,
            &self.options,
            &self.obstacle_facets,
            &self.facet_boxes,
        );
        self.candidates = map_chunks(&surface.slaves, |start, slaves| -> Chunk {
            let mut out = Vec::new();
            let mut hits = Vec::new();
            let mut ring = Vec::new();
            // A few neighbouring slaves share one traversal of the hierarchy: their boxes are
            // tiny and close, so one query with their union costs about as much as one of
            // theirs, and the hits are then re-tested per slave.
            for (g, group) in slaves.chunks(GROUP).enumerate() {
                let segs: Vec<Aabb<D>> = group
                    .iter()
                    .map(|&n| Aabb::from_points([&x0[n], &x1[n]]))
                    .collect();
                let union = segs.iter().skip(1).fold(segs[0], |u, b| u.merged(b));
                hits.clear();
                if let Some(tree) = tree {
                    tree.query(&union, &mut hits);
                    hits.sort_unstable();
                }
                for (i, (&node, seg)) in group.iter().zip(&segs).enumerate() {
                    let body = surface.slave_body[start + g * GROUP + i];
                    for (k, o) in obstacles.iter().enumerate() {
                        if obstacle_overlaps(o, &poses_t1[k], seg, margin, cache[k].as_ref()) {
                            out.push((node, Master::Obstacle(k)));
                        }
                    }
                    // The nodes of the facets around the slave: a facet holding one of them
                    // is excluded from self-contact.
                    ring.clear();
                    if options.self_contact {
                        for &f in surface.facets_of_node(node) {
                            ring.extend_from_slice(&surface.facets[f]);
                        }
                    }
                    for &f in &hits {
                        if !facet_boxes[f].intersects(seg) {
                            continue;
                        }
                        let allowed = if surface.facet_body[f] == body {
                            options.self_contact
                                && !surface.facets[f].iter().any(|v| ring.contains(v))
                        } else {
                            options.deformable_pairs
                        };
                        if allowed {
                            out.push((node, Master::Facet(f)));
                        }
                    }
                }
            }
            out
        });
    }

    /// Narrow phase at the configuration `x` (global node positions (m), usually the predicted
    /// end of the step) with the obstacles in their pose: one pair per (slave,
    /// obstacle) and per (slave, master body) among the candidates whose gap is below the
    /// margin. Sorted by slave, then master.
    ///
    /// # Panics
    /// If `x` is shorter than [`ContactSurface::node_count`].
    pub fn pairs(
        &mut self,
        x: &[SVector<f64, D>],
        obstacles: &[Obstacle<D>],
    ) -> Vec<ContactPair<D>> {
        assert!(
            x.len() >= self.surface.node_count(),
            "positions shorter than the surface's nodes"
        );
        self.sync_obstacles(obstacles);
        // Groups of candidates with one slave.
        let mut groups = Vec::new();
        let mut a = 0;
        while a < self.candidates.len() {
            let mut b = a + 1;
            while b < self.candidates.len() && self.candidates[b].0 == self.candidates[a].0 {
                b += 1;
            }
            groups.push((a, b));
            a = b;
        }
        let (surface, options, cache, previous, flips, cands) = (
            &self.surface,
            &self.options,
            &self.obstacle_facets,
            &self.previous,
            &self.flips,
            &self.candidates,
        );
        let activation = options.margin;
        let results: Vec<(ContactPair<D>, MasterId, usize, bool)> = map_chunks(&groups, |_, gs| {
            let mut out = Vec::new();
            for &(a, b) in gs {
                let node = cands[a].0;
                let p = x[node];
                let mut i = a;
                while i < b {
                    match cands[i].1 {
                        Master::Obstacle(k) => {
                            i += 1;
                            let Some(o) = obstacles.get(k) else { continue };
                            let key = MasterId::Obstacle(k);
                            let prev = previous.get(&(node, key)).copied();
                            if let Some((pair, choice)) =
                                obstacle_pair(o, cache[k].as_ref(), &p, prev, options.hysteresis)
                            {
                                let pair = ContactPair {
                                    slave: node,
                                    master: Master::Obstacle(k),
                                    ..pair
                                };
                                out.push((pair, key, choice, pair.gap < activation));
                            }
                        }
                        Master::Facet(f0) => {
                            let body = surface.facet_body[f0];
                            let mut j = i;
                            while j < b
                                && matches!(cands[j].1, Master::Facet(f) if surface.facet_body[f] == body)
                            {
                                j += 1;
                            }
                            let key = MasterId::Body(body);
                            let prev = previous.get(&(node, key)).copied();
                            // Only facets facing the node (opposed normals): always for
                            // self-contact, between bodies with `facing`.
                            let own_body =
                                body == surface.facet_body[surface.facets_of_node(node)[0]];
                            let own =
                                (options.facing || own_body).then(|| surface.node_normal(node, x));
                            let paths = std::cell::OnceCell::new();
                            let choice = choose(
                                &p,
                                cands[i..j].iter().map(|c| match c.1 {
                                    Master::Facet(f) => f,
                                    Master::Obstacle(_) => unreachable!("facets only"),
                                }),
                                |f| surface.facets[f].map(|v| x[v]),
                                |n| own.is_none_or(|nn| nn.dot(n) < 0.0),
                                |f, gap, distance| {
                                    if !own_body || gap >= 0.0 {
                                        return true;
                                    }
                                    // Computed once per slave, for its penetrating candidates.
                                    let near = paths.get_or_init(|| {
                                        surface.nearest_along_surface(node, x, PATH_SEARCH_NODES)
                                    });
                                    let reach = distance / SELF_CONTACT_DISTANCE_OVER_PATH;
                                    let beside_own_corner = near.iter().any(|&(v, path)| {
                                        path <= reach && surface.facets[f].contains(&v)
                                    });
                                    !beside_own_corner
                                },
                                prev,
                                // A memory carried over an edit of the bodies may name a
                                // facet that is gone: no lock then.
                                match prev.and_then(|f| surface.facets.get(f)) {
                                    Some(facet)
                                        if flips.get(&(node, key)).copied().unwrap_or(0)
                                            >= FLIPS_BEFORE_LOCK
                                            && options.lock_flipping_facets =>
                                    {
                                        LOCKED_REACH * facet_size(&facet.map(|v| x[v]))
                                    }
                                    _ => options.hysteresis,
                                },
                            );
                            if let Some(c) = choice {
                                let pair = ContactPair {
                                    slave: node,
                                    master: Master::Facet(c.facet),
                                    gap: c.gap,
                                    normal: c.normal,
                                    point: c.point,
                                    barycentric: c.barycentric,
                                    feature: c.feature,
                                };
                                out.push((pair, key, c.facet, c.gap < activation));
                            }
                            i = j;
                        }
                    }
                }
            }
            out
        });
        // Flips are counted only where they can lock: the other methods keep the closest facet.
        if self.options.lock_flipping_facets {
            for (p, key, choice, _) in &results {
                let key = (p.slave, *key);
                let Some(&prev) = self.previous.get(&key) else {
                    continue;
                };
                // A change between facets that turn the normal (not two halves of a flat quad).
                if !matches!(p.master, Master::Facet(_)) || prev == *choice {
                    continue;
                }
                let Some(facet) = self.surface.facets.get(prev) else {
                    continue;
                };
                let (_, n) = <Dim<D>>::facet_measure_normal(&facet.map(|v| x[v]));
                if n.dot(&p.normal) < (1.0 - 0.5 * FLIP_ANGLE * FLIP_ANGLE) {
                    *self.flips.entry(key).or_insert(0) += 1;
                }
            }
        }
        self.previous = results
            .iter()
            .map(|(p, key, choice, _)| ((p.slave, *key), *choice))
            .collect();
        results.into_iter().filter(|r| r.3).map(|r| r.0).collect()
    }
}

/// Whether an obstacle's region swept from its pose `o` (t0) to `pose_t1` (translation,
/// rotation), grown by `margin`, may touch the box `seg` (conservative).
///
/// An obstacle that turns is tested in the frame of its shape at t = 0, where it stands still
/// and the box moves: the box's centre c goes from xi0 to xi1 there, along
/// `xi(t) = p + R(t)^T (c - p - T(t))` (p the pivot, T linear, R turning at a constant rate by
/// the angle phi of the step), which stays within `phi (|a0| + |a1|) / 4` of the chord
/// (a = c - p - T at either end: each of `(1 - s) (E(t) - I) a0` and `s (E(t) - E(h)) a1`
/// is at most `s (1 - s) phi |a|`), and never further than `2 max |a|`. The box of the chord
/// grown by that bound and the half diagonal of `seg` is tested against the shape at rest.
fn obstacle_overlaps<const D: usize>(
    o: &Obstacle<D>,
    pose_t1: &(SVector<f64, D>, SMatrix<f64, D, D>),
    seg: &Aabb<D>,
    margin: f64,
    facets: Option<&ObstacleFacets<D>>,
) -> bool
where
    Dim<D>: SpatialDim<D>,
{
    let identity = SMatrix::<f64, D, D>::identity();
    if o.rotation == identity && pose_t1.1 == identity {
        return shape_overlaps(&o.shape, (o.translation, pose_t1.0), seg, margin, facets);
    }
    let p = o.pivot_point();
    let c = (seg.min + seg.max) * 0.5;
    let radius = 0.5 * (seg.max - seg.min).norm();
    let (a0, a1) = (c - p - o.translation, c - p - pose_t1.0);
    let (xi0, xi1) = (
        p + o.rotation.transpose() * a0,
        p + pose_t1.1.transpose() * a1,
    );
    // The angle of the step's turn R1 R0^T: its trace is (D - 2) + 2 cos(phi).
    let cos = 0.5 * ((pose_t1.1 * o.rotation.transpose()).trace() - (D as f64 - 2.0));
    let phi = cos.clamp(-1.0, 1.0).acos();
    let bow = (0.25 * phi * (a0.norm() + a1.norm())).min(2.0 * a0.norm().max(a1.norm()));
    let local = Aabb::from_points([&xi0, &xi1]).loosened(radius + bow);
    let zero = SVector::<f64, D>::zeros();
    shape_overlaps(&o.shape, (zero, zero), &local, margin, facets)
}

/// Whether a shape swept between translations `t.0` and `t.1` (not turned), grown by
/// `margin`, may touch the box `seg` (conservative).
fn shape_overlaps<const D: usize>(
    shape: &ObstacleShape<D>,
    t: (SVector<f64, D>, SVector<f64, D>),
    seg: &Aabb<D>,
    margin: f64,
    facets: Option<&ObstacleFacets<D>>,
) -> bool
where
    Dim<D>: SpatialDim<D>,
{
    let (tlo, thi) = (t.0.inf(&t.1), t.0.sup(&t.1));
    match shape {
        ObstacleShape::Halfspace { point, normal } => {
            let norm = normal.norm();
            if !positive(norm) {
                return false;
            }
            let n = normal / norm;
            // Smallest signed distance over the box, at either end translation: the relative
            // motion is linear, so its extremes are at the ends.
            let low: f64 = (0..D)
                .map(|k| (seg.min[k] * n[k]).min(seg.max[k] * n[k]))
                .sum();
            let far = (point + t.0).dot(&n).max((point + t.1).dot(&n));
            low - far < margin
        }
        ObstacleShape::Box {
            center,
            half_extents,
        } => {
            let b = Aabb {
                min: center + tlo - half_extents,
                max: center + thi + half_extents,
            };
            b.loosened(margin).intersects(seg)
        }
        ObstacleShape::Ball { center, radius } => {
            let c = Aabb {
                min: center + tlo,
                max: center + thi,
            };
            c.distance(seg) <= radius + margin
        }
        ObstacleShape::Facets { .. } => {
            let Some(of) = facets else { return false };
            // In the obstacle's frame the box moves by -t: the query is its Minkowski sum.
            let q = Aabb {
                min: seg.min - thi,
                max: seg.max - tlo,
            }
            .loosened(margin);
            if !of.bounds.intersects(&q) {
                return false;
            }
            let mut hits = Vec::new();
            of.tree.query(&q, &mut hits);
            !hits.is_empty()
        }
    }
}

/// The contact of point `p` with an obstacle in its current pose: the pair (slave and
/// master left to fill) and the choice to remember (face or facet index).
fn obstacle_pair<const D: usize>(
    o: &Obstacle<D>,
    facets: Option<&ObstacleFacets<D>>,
    p: &SVector<f64, D>,
    previous: Option<usize>,
    hysteresis: f64,
) -> Option<(ContactPair<D>, usize)>
where
    Dim<D>: SpatialDim<D>,
{
    let mut e0 = [0.0; D];
    e0[0] = 1.0;
    let pair =
        |gap: f64, normal: SVector<f64, D>, point: SVector<f64, D>, feature: Feature| ContactPair {
            slave: 0,
            master: Master::Obstacle(0),
            gap,
            normal,
            point,
            barycentric: e0,
            feature,
        };
    match &o.shape {
        ObstacleShape::Halfspace { .. }
        | ObstacleShape::Ball { .. }
        | ObstacleShape::Box { .. } => {
            let g = posed_obstacle_gap(o, p, previous, hysteresis)?;
            Some((pair(g.gap, g.normal, g.point, g.feature), g.choice))
        }
        ObstacleShape::Facets { .. } => {
            let of = facets?;
            if of.facets.is_empty() {
                return None;
            }
            // Searched in the frame of the shape at t = 0; the point and normal turned back.
            let pl = o.to_local(p);
            let found =
                |c: Choice<D>| pair(c.gap, o.turn(&c.normal), o.to_world(&c.point), c.feature);
            // Grow a search box until it holds a facet at most its half-width away: then it
            // holds every facet as close as the closest one. Bounded by construction: at most
            // MAX_GROWTHS boxes (4^64 ~ 3e38 times the first), then every facet is tried, so
            // that no number (huge, infinite or NaN coordinates) can keep it searching.
            const MAX_GROWTHS: usize = 64;
            let diag = (of.bounds.max - of.bounds.min).norm();
            let mut r = (1e-3 * diag).max(f64::MIN_POSITIVE);
            let reach = 4.0 * (diag + of.bounds.distance(&Aabb { min: pl, max: pl }));
            let mut hits = Vec::new();
            for _ in 0..MAX_GROWTHS {
                hits.clear();
                of.tree
                    .query(&Aabb { min: pl, max: pl }.loosened(r), &mut hits);
                hits.sort_unstable();
                let near = hits
                    .iter()
                    .any(|&f| of.boxes[f].distance(&Aabb { min: pl, max: pl }) <= r);
                if near {
                    let c = choose(
                        &pl,
                        hits.iter().copied(),
                        |f| of.verts(f),
                        |_| true,
                        |_, _, _| true,
                        previous,
                        hysteresis,
                    );
                    if let Some(c) = c {
                        if (pl - c.point).norm() <= r {
                            return Some((found(c), c.facet));
                        }
                    }
                }
                // Past reach only degenerate facets are left; a radius or reach that is not a
                // finite number cannot grow into an answer.
                if !(r <= reach && r.is_finite()) {
                    break;
                }
                r *= 4.0;
            }
            let c = choose(
                &pl,
                0..of.facets.len(),
                |f| of.verts(f),
                |_| true,
                |_, _, _| true,
                previous,
                hysteresis,
            )?;
            Some((found(c), c.facet))
        }
    }
}
