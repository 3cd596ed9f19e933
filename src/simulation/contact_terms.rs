//! What contact adds to one Newton iteration: for every detected pair, its geometry (from
//! [`crate::contact::gap`]), the method's normal law ([`crate::contact::methods`]), the friction
//! law ([`crate::friction`]), and from them the nodal forces, the tangent entries and the
//! records the observers see.

use std::collections::BTreeMap;

use nalgebra::{SMatrix, SVector};

use super::held_pairs::edge_pair;
use super::observe::ContactRecord;
use super::Simulation;
use crate::contact::gap::{facet_gap, facet_gap_hessian, obstacle_gap_hessian};
use crate::contact::methods::{
    HeldConstraint, Method, NormalInput, NormalLaw, OuterVariables, PairOutcome,
};
use crate::contact::{ContactKey, ContactPair, FrictionLaw, Master, MasterId, Obstacle};
use crate::dim::{Dim, Kinematics, SpatialDim};
use crate::friction::return_map;

/// A rank-one matrix `u v^T` with sparse `u` and `v` (index, value).
pub(super) type RankOne = (Vec<(usize, f64)>, Vec<(usize, f64)>);

/// A held constraint in an iteration: its key, value (m/s) and gradient with respect to the
/// end velocities (index, value).
pub(super) type HeldRow = (ContactKey, f64, Vec<(usize, f64)>);

/// Everything contact adds to one iteration.
#[derive(Default)]
pub(super) struct ContactTerms<const D: usize> {
    /// Contact forces on the nodes (N; flat, D per node).
    pub forces: Vec<f64>,
    /// The forces (N; flat, D per node, empty when none) that the closed branch of pairs
    /// predicted closed adds where the law found them open ([`NormalLaw::predicted_force`]):
    /// they enter the first Newton direction only, not the residual.
    pub predicted_forces: Vec<f64>,
    /// Tangent entries `d(-forces)/dv1` (lower triangle).
    pub entries: Vec<(usize, usize, f64)>,
    /// The geometric part of the tangent (variation of the normal and of the closest point):
    /// kept while the iteration matrix stays positive definite.
    pub geometric: Vec<(usize, usize, f64)>,
    /// Every pair's forces.
    pub pairs: Vec<PairOutcome<D>>,
    /// The non-symmetric part of `d(-forces)/dv1` left out of `entries`: Coulomb slip's
    /// coupling of the threshold to the gap, `-mu t dF_n/dv1`, one rank-one term `u v^T` per
    /// slipping contact (sparse `u`, `v`). Newton solves with it by GMRES preconditioned with
    /// the symmetric factorisation (or the Sherman-Morrison-Woodbury formula), so that the
    /// Cholesky never sees it.
    pub coupling: Vec<RankOne>,
    /// The floating-point noise of the contact forces (N): a gap is known to a unit in the
    /// last place of the positions it is measured between, and each normal law multiplies it
    /// by its stiffness per unit of gap (the root sum of squares over the pairs).
    pub round_off: f64,
    /// Penalty energy stored in the gaps (J).
    pub energy: f64,
    /// Friction dissipation rate, and the constraint normal forces' work rate (W).
    pub dissipation_rate: f64,
    /// The rate of work the penalty normal forces take from the relative motion (W), along
    /// the trapezoid increment `h (w0 + w1) / 2` the scheme books forces on (constraint
    /// forces' work is in `dissipation_rate`).
    pub normal_work_rate: f64,
    /// The held constraints ([`HeldConstraint`]): each one's key, value (m/s) and gradient
    /// with respect to the end velocities (index, value), from which Newton predicts the
    /// value after its increment.
    pub held: Vec<HeldRow>,
    /// Newton's merit: what the held forces' penalty adds to the residual (N; flat, empty
    /// when nothing) beyond the forces their linearised prediction gives,
    /// `-penalty (C - C_predicted)` spread like the force ...
    pub merit_excess: Vec<f64>,
    /// ... and the sum of squares of the same curvature errors in force units of the slave's
    /// diagonal, `diagonal (C - C_predicted)` (N^2).
    pub merit_constraints: f64,
}

/// A pair's geometry, kinematics and normal law: the normal phase of the contact terms.
struct PairNormal<const D: usize> {
    key: ContactKey,
    /// The slave and the master's nodes with their weights in the relative velocity.
    nodes: Vec<(usize, f64)>,
    normal: SVector<f64, D>,
    /// The eq 22 gap (m).
    gap: f64,
    /// An obstacle's surface velocity at the contact point (m/s).
    master_velocity: SVector<f64, D>,
    obstacle: Option<usize>,
    master_point: SVector<f64, D>,
    /// A master facet's nodes and weights.
    facet_weights: Option<[(usize, f64); D]>,
    /// The slave's contact area (m^2; half of it for each pass between deformable bodies).
    area: f64,
    /// Relative start and end velocities (m/s).
    r0: SVector<f64, D>,
    r1: SVector<f64, D>,
    law_input: NormalInput,
    law: NormalLaw,
}

/// What the contact terms of an iteration read besides the pairs.
pub(super) struct TermsInput<'a, const D: usize> {
    /// The method.
    pub method: &'a dyn Method,
    /// The obstacles at t1.
    pub obstacles_t1: &'a [Obstacle<D>],
    /// Predicted end positions (eq 22) (m).
    pub x_gap: &'a [SVector<f64, D>],
    /// Start and end velocities (m/s).
    pub v0: &'a [f64],
    /// End velocities (m/s).
    pub v1: &'a [f64],
    /// The step (s).
    pub time_step: f64,
    /// Each boundary node's face shares (area, outward normal).
    pub areas: &'a [Vec<(f64, SVector<f64, D>)>],
    /// The method's outer variables.
    pub vars: &'a OuterVariables,
    /// The Coulomb thresholds (normal forces) of the friction fixed point (N).
    pub friction_normals: &'a BTreeMap<ContactKey, f64>,
    /// The elastic slips of the return-map laws at the start of the step (m).
    pub friction_anchors: &'a BTreeMap<ContactKey, SVector<f64, D>>,
    /// The diagonal of the contact-free iteration matrix.
    pub diagonal: &'a [f64],
    /// The friction forces' directions at Newton's previous iterate (unit vectors; see
    /// `return_map`).
    pub slip_directions: &'a BTreeMap<ContactKey, SVector<f64, D>>,
    /// The held constraints' values that Newton's last increment predicted from their
    /// linearisation (m/s): their forces' geometric tangent and Newton's merit read the
    /// prediction's force (see `newton::merit`).
    pub held_predictions: &'a BTreeMap<ContactKey, f64>,
}

fn block_entries<const D: usize>(
    entries: &mut Vec<(usize, usize, f64)>,
    a: usize,
    b: usize,
    block: &SMatrix<f64, D, D>,
) {
    for i in 0..D {
        for j in 0..D {
            let (r, c) = (a * D + i, b * D + j);
            if r >= c && block[(i, j)] != 0.0 {
                entries.push((r, c, block[(i, j)]));
            }
        }
    }
}

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// The friction law of a contact (the obstacle's own, or the default).
    pub(super) fn friction_law(&self, obstacle: Option<usize>) -> FrictionLaw {
        obstacle
            .and_then(|k| self.model.obstacles[k].friction)
            .unwrap_or(self.model.contact.friction)
    }

    /// Each boundary node's shares of the surface (m^2) at positions `x`, with the outward
    /// normal of the face each share comes from (length x unit thickness in plane kinematics,
    /// `2 pi r` x length in axisymmetric ones).
    pub(super) fn tributary_areas(
        &self,
        x: &[SVector<f64, D>],
    ) -> Vec<Vec<(f64, SVector<f64, D>)>> {
        let mut shares: Vec<Vec<(f64, SVector<f64, D>)>> = vec![Vec::new(); x.len()];
        let axisymmetric = self.model.settings.kinematics == Kinematics::Axisymmetric;
        for face in &self.boundary_faces {
            let first: [SVector<f64, D>; D] = std::array::from_fn(|i| x[face[i]]);
            let (_, normal) = <Dim<D>>::facet_measure_normal(&first);
            if D == 2 {
                let (a, b) = (face[0], face[1]);
                let length = (x[b] - x[a]).norm();
                if axisymmetric {
                    let (ra, rb) = (x[a][0].max(0.0), x[b][0].max(0.0));
                    let tau = 2.0 * std::f64::consts::PI * length / 6.0;
                    shares[a].push((tau * (2.0 * ra + rb), normal));
                    shares[b].push((tau * (ra + 2.0 * rb), normal));
                } else {
                    shares[a].push((0.5 * length, normal));
                    shares[b].push((0.5 * length, normal));
                }
            } else {
                let tri = |p: usize, q: usize, r: usize| {
                    let v = [x[p], x[q], x[r]].map(|v| nalgebra::Vector3::new(v[0], v[1], v[2]));
                    0.5 * (v[1] - v[0]).cross(&(v[2] - v[0])).norm()
                };
                let total = if face.len() == 4 {
                    tri(face[0], face[1], face[2]) + tri(face[0], face[2], face[3])
                } else {
                    tri(face[0], face[1], face[2])
                };
                for &n in face {
                    shares[n].push((total / face.len() as f64, normal));
                }
            }
        }
        shares
    }

    /// The contact area of a slave node against a master of normal `n`: its face shares
    /// projected on the contact plane (faces turned away from the master do not count, so a
    /// corner node of a flat face carries its half of that face only).
    fn contact_area(shares: &[(f64, SVector<f64, D>)], n: &SVector<f64, D>) -> f64 {
        shares.iter().map(|(a, nf)| a * (-nf.dot(n)).max(0.0)).sum()
    }

    /// The key of a detected pair.
    pub(super) fn contact_key(&self, pair: &ContactPair<D>) -> ContactKey {
        match pair.master {
            Master::Obstacle(k) => (pair.slave, MasterId::Obstacle(k)),
            Master::Facet(f) => {
                let surface = self.caches.detector.as_ref().expect("contact").surface();
                (pair.slave, MasterId::Body(surface.facet_body()[f]))
            }
        }
    }

    /// The geometry, kinematics and normal law of a detected pair (the normal phase of
    /// [`Self::contact_terms`]); `None` for a degenerate master facet.
    fn pair_normal(
        &self,
        pair: &ContactPair<D>,
        input: &TermsInput<'_, D>,
    ) -> Option<PairNormal<D>> {
        let h = input.time_step;
        let x_gap = input.x_gap;
        let s = pair.slave;
        let surface = self.caches.detector.as_ref()?.surface();
        // Master nodes with their weights, the normal and the gap.
        let mut facet_weights = None;
        let (key, nodes, normal, gap, master_velocity, obstacle, master_point) = match pair.master {
            Master::Obstacle(k) => (
                (s, MasterId::Obstacle(k)),
                vec![(s, 1.0)],
                pair.normal,
                pair.gap,
                // The surface's velocity where the point touches it.
                self.surface_velocity(k, &input.obstacles_t1[k], &pair.point),
                Some(k),
                pair.point,
            ),
            Master::Facet(f) => {
                let facet = surface.facets()[f];
                let y: [SVector<f64, D>; D] = std::array::from_fn(|i| x_gap[facet[i]]);
                let g = facet_gap::<D>(&x_gap[s], &y)?;
                let mut nodes = vec![(s, 1.0)];
                for i in 0..D {
                    nodes.push((facet[i], -g.weights[i]));
                }
                facet_weights = Some(std::array::from_fn(|i| (facet[i], g.weights[i])));
                (
                    (s, MasterId::Body(surface.facet_body()[f])),
                    nodes,
                    g.normal,
                    g.gap,
                    SVector::zeros(),
                    None,
                    g.point,
                )
            }
        };
        let relative = |v: &[f64]| -> SVector<f64, D> {
            let mut r = -master_velocity;
            for &(n, c) in &nodes {
                r += SVector::<f64, D>::from_column_slice(&v[n * D..n * D + D]) * c;
            }
            r
        };
        let mut area = Self::contact_area(&input.areas[s], &normal);
        if obstacle.is_none() && input.method.symmetric_pairs() {
            // Both passes act on a pair of deformable surfaces: half each.
            area *= 0.5;
        }
        let (r0, r1) = (relative(input.v0), relative(input.v1));
        let normal_velocity = normal.dot(&r1);
        let law_input = NormalInput {
            key,
            gap,
            start_gap: gap - 0.5 * h * normal.dot(&(r0 + r1)),
            normal_velocity,
            area,
            time_step: h,
            diagonal: (0..D)
                .map(|k| input.diagonal[s * D + k])
                .fold(0.0, f64::max),
        };
        let law = input
            .method
            .normal_law(&law_input, input.vars, &self.model.contact);
        Some(PairNormal {
            key,
            nodes,
            normal,
            gap,
            master_velocity,
            obstacle,
            master_point,
            facet_weights,
            area,
            r0,
            r1,
            law_input,
            law,
        })
    }

    /// The slaves that an area law's friction (Tresca, viscoplastic) counts as inside the
    /// contact patch although their own pair carries no load: the nodes of the master facets
    /// of loaded pairs between deformable surfaces (active ones under implicit projection).
    /// One pass often carries the load over a patch (the penalty methods' two passes at half
    /// the area each: the multipliers or the penalty put it on one; implicit projection's
    /// frictionless edge pairs at a perimeter), and a law that reads only whether a point is
    /// closed would then act on part of the area. Empty for the other laws.
    fn area_law_patch<'p>(
        &self,
        normals: impl Iterator<Item = &'p PairNormal<D>>,
        input: &TermsInput<'_, D>,
    ) -> Vec<bool> {
        let area_law =
            |law: FrictionLaw| law != FrictionLaw::Frictionless && !law.follows_normal_force();
        if !area_law(self.friction_law(None)) {
            return Vec::new();
        }
        // Under implicit projection a point is held while it is active (see `closed` below).
        let loaded = |p: &PairNormal<D>| {
            if input.method.closed_by_active_set() {
                p.law.stiffness > 0.0
            } else {
                p.law.force > 0.0
            }
        };
        let mut patch = vec![false; input.x_gap.len()];
        for p in normals.filter(|p| loaded(p)) {
            for &(node, _) in p.facet_weights.iter().flatten() {
                patch[node] = true;
            }
        }
        patch
    }

    /// Forces, tangent entries and outcomes of every detected pair: the normal phase first
    /// ([`Self::pair_normal`]), then friction and assembly, which read the whole contact
    /// patch ([`Self::area_law_patch`]).
    pub(super) fn contact_terms(
        &self,
        pairs: &[ContactPair<D>],
        input: &TermsInput<'_, D>,
    ) -> ContactTerms<D> {
        let h = input.time_step;
        let x_gap = input.x_gap;
        let ndof = input.v1.len();
        let mut terms = ContactTerms {
            forces: vec![0.0; ndof],
            ..Default::default()
        };
        let node_v =
            |v: &[f64], n: usize| SVector::<f64, D>::from_column_slice(&v[n * D..n * D + D]);
        let Some(detector) = &self.caches.detector else {
            return terms;
        };
        let surface = detector.surface();
        let normals: Vec<(&ContactPair<D>, PairNormal<D>)> = pairs
            .iter()
            .filter_map(|pair| Some((pair, self.pair_normal(pair, input)?)))
            .collect();
        let patch = self.area_law_patch(normals.iter().map(|(_, p)| p), input);
        // Only the persistency stop after the step reads a pair's nodes.
        let keep_nodes = self.model.contact.stops_closed_pairs();
        for (pair, p) in &normals {
            let s = pair.slave;
            let PairNormal {
                key,
                ref nodes,
                normal,
                gap,
                master_velocity,
                obstacle,
                master_point,
                facet_weights,
                area,
                r0,
                r1,
                law_input,
                law: normal_law,
            } = *p;
            let projector = SMatrix::<f64, D, D>::identity() - normal * normal.transpose();
            let slip = projector * (r0 + r1) * 0.5;
            let normal_velocity = law_input.normal_velocity;
            let (normal_force, normal_stiffness) = (normal_law.force, normal_law.stiffness);
            // The gap moves by h/2 per unit of normal velocity.
            let reach = x_gap[s].norm().max(master_point.norm());
            let noise = normal_stiffness
                * f64::EPSILON
                * (2.0 * reach / h + normal_velocity.abs() + master_velocity.norm());
            terms.round_off = terms.round_off.hypot(noise);
            // A projection's edge pair (the second body's node beyond the first one's holding
            // nodes, `held_pairs`) holds the normal only: the patch's friction is the first
            // body's, and two sticking pairs on the same edge over-constrain the slip.
            let is_edge_pair = match pair.master {
                Master::Facet(f) => {
                    edge_pair(input.method, self.body_of_node(s), surface.facet_body()[f])
                }
                Master::Obstacle(_) => false,
            };
            let law = if is_edge_pair {
                FrictionLaw::Frictionless
            } else {
                self.friction_law(obstacle)
            };
            // d(-friction)/dw1 (w1 the relative end velocity), the elastic slip after the
            // step, and d friction/d F_n (the non-symmetric coupling).
            let mut anchor = None;
            let mut d_normal_force = SVector::<f64, D>::zeros();
            // Under implicit projection a pair is closed while it is in the active set (the
            // outer loop releases the ones in tension): within Newton an active pair's force is
            // exact only at convergence, and a law that does not follow the force (Tresca,
            // viscoplastic) switched on by its sign turns its whole friction on and off with
            // the noise of a force near zero (the 3D blocks sliding over each other at first
            // touch: no convergence after four step cuts).
            let by_active_set = input.method.closed_by_active_set();
            let lagged = input.method.lagged_friction_threshold();
            // A point of the contact patch that the other pass holds (`area_law_patch`) is
            // closed for a law that reads only the status.
            let in_patch = obstacle.is_none() && patch.get(s).copied().unwrap_or(false);
            let closed = if by_active_set {
                normal_stiffness > 0.0
            } else {
                normal_force > 0.0
            } || (in_patch && !law.follows_normal_force());
            // The force a threshold reads: Coulomb's follows the normal force (the previous
            // pass's under implicit projection), the other laws' only the status.
            let threshold_force = if !law.follows_normal_force() {
                if closed {
                    1.0
                } else {
                    0.0
                }
            } else if lagged {
                input.friction_normals.get(&key).copied().unwrap_or(0.0)
            } else {
                normal_force
            };
            let (friction, friction_tangent) = if law == FrictionLaw::Frictionless {
                (SVector::zeros(), SMatrix::zeros())
            } else if input.method.friction_return_map() && law.has_return_map() {
                // The return map: the elastic slip is reset when the contact opens.
                let limit = law.slip_limit(threshold_force, area);
                if closed && threshold_force > 0.0 {
                    let previous = input
                        .friction_anchors
                        .get(&key)
                        .copied()
                        .unwrap_or_else(SVector::zeros);
                    let stiffness = input
                        .method
                        .tangential_stiffness(&law_input, &self.model.contact);
                    let map = return_map(
                        limit,
                        stiffness,
                        &previous,
                        &r1,
                        &normal,
                        h,
                        input.slip_directions.get(&key),
                    );
                    anchor = Some(map.anchor);
                    if !lagged && law.follows_normal_force() {
                        d_normal_force = map.d_limit * law.slip_limit(1.0, area);
                    }
                    (map.force, map.tangent)
                } else {
                    (SVector::zeros(), SMatrix::zeros())
                }
            } else {
                // The smooth law on the mean tangential velocity with the normal force of the
                // previous pass (a fixed point on the threshold: a sequence of Tresca problems,
                // each with a symmetric tangent). Only Coulomb's threshold depends on the
                // force; the other laws need the status.
                let threshold = if law.follows_normal_force() {
                    input.friction_normals.get(&key).copied().unwrap_or(0.0)
                } else {
                    threshold_force
                };
                if threshold > 0.0 {
                    let (f, d) = law.force(threshold, area, &slip, &normal);
                    // d slip/d w1 = (I - n n)/2.
                    (f, -d * 0.5)
                } else {
                    (SVector::zeros(), SMatrix::zeros())
                }
            };
            let force = normal * normal_force + friction;
            for &(n, c) in nodes {
                for k in 0..D {
                    terms.forces[n * D + k] += c * force[k];
                }
            }
            if normal_law.predicted_force != 0.0 {
                terms.predicted_forces.resize(ndof, 0.0);
                for &(n, c) in nodes {
                    for k in 0..D {
                        terms.predicted_forces[n * D + k] +=
                            c * normal[k] * normal_law.predicted_force;
                    }
                }
            }
            // A held constraint's force as its linearised prediction gives it (the solve's
            // residual keeps the penalty's, `newton::merit`), and the constraint's gradient:
            // `n` on the involved nodes, plus the turning below.
            let mut geometric_force = normal_law.geometric_force;
            let mut held_gradient: Option<Vec<(usize, f64)>> = None;
            if let Some(HeldConstraint { value, penalty }) = normal_law.held {
                if let Some(&predicted) = input.held_predictions.get(&key) {
                    let curvature = value - predicted;
                    let excess = -penalty * curvature;
                    geometric_force -= excess;
                    if excess != 0.0 {
                        terms.merit_excess.resize(ndof, 0.0);
                        for &(n, c) in nodes {
                            for k in 0..D {
                                terms.merit_excess[n * D + k] += c * normal[k] * excess;
                            }
                        }
                    }
                    terms.merit_constraints += (law_input.diagonal * curvature).powi(2);
                }
                held_gradient = Some(
                    nodes
                        .iter()
                        .flat_map(|&(n, c)| (0..D).map(move |i| (n * D + i, c * normal[i])))
                        .collect(),
                );
            }
            // Tangent: d(-force)/dv1 on every pair of involved nodes.
            if normal_stiffness > 0.0 || law != FrictionLaw::Frictionless {
                let nn = normal * normal.transpose();
                let turning = geometric_force != 0.0 || normal_law.velocity_stiffness > 0.0;
                let hessian: Option<Vec<Vec<f64>>> = if turning {
                    match pair.master {
                        Master::Facet(f) => {
                            let facet = surface.facets()[f];
                            let y: [SVector<f64, D>; D] = std::array::from_fn(|i| x_gap[facet[i]]);
                            Some(facet_gap_hessian::<D>(&x_gap[s], &y))
                        }
                        Master::Obstacle(k) => {
                            let hs = obstacle_gap_hessian(&input.obstacles_t1[k], pair, &x_gap[s]);
                            Some(
                                (0..D)
                                    .map(|i| (0..D).map(|j| hs[(i, j)]).collect())
                                    .collect(),
                            )
                        }
                    }
                } else {
                    None
                };
                if let (Some(hess), true) = (&hessian, normal_law.velocity_stiffness > 0.0) {
                    // The force holds w_n = grad(g) . V (V the involved nodes' end velocities
                    // relative to the master): d w_n / d x = Hess(g) V, and the end positions
                    // move by h/2 per unit of v1. d(-force)/dv1 gains grad(g) k (h/2) (Hess V)^T.
                    let mut stacked = vec![0.0; nodes.len() * D];
                    for (a, &(n, _)) in nodes.iter().enumerate() {
                        let v = node_v(input.v1, n);
                        for i in 0..D {
                            stacked[a * D + i] = v[i];
                        }
                    }
                    if obstacle.is_some() {
                        for i in 0..D {
                            stacked[i] -= master_velocity[i];
                        }
                    }
                    // A turning obstacle's surface velocity follows the closest point Q:
                    // n . v_m also varies by (dQ/dx)^T W^T n, W = d v_m / dQ (its spin) and
                    // dQ/dx = I - n n^T - g Hess(g). (On a ball turning about its centre
                    // n . v_m stays 0, and this cancels the Hess(g) v_m above.)
                    let mut spin_term = SVector::<f64, D>::zeros();
                    if let Some(k) = obstacle {
                        let posed = &input.obstacles_t1[k];
                        let at = |q: &SVector<f64, D>| self.surface_velocity(k, posed, q);
                        let base = at(&master_point);
                        let wn = SVector::<f64, D>::from_fn(|j, _| {
                            let mut shifted = master_point;
                            shifted[j] += 1.0;
                            normal.dot(&(at(&shifted) - base))
                        });
                        if wn != SVector::<f64, D>::zeros() {
                            let hs = SMatrix::<f64, D, D>::from_fn(|i, j| hess[i][j]);
                            let closest = SMatrix::<f64, D, D>::identity()
                                - normal * normal.transpose()
                                - hs * gap;
                            spin_term = closest.transpose() * wn;
                        }
                    }
                    let factor = 0.5 * h * normal_law.velocity_stiffness;
                    let row: Vec<(usize, f64)> = nodes
                        .iter()
                        .enumerate()
                        .flat_map(|(a, &(n, _))| (0..D).map(move |i| (a, n, i)))
                        .map(|(a, n, i)| {
                            let q: f64 = (0..stacked.len())
                                .map(|j| hess[a * D + i][j] * stacked[j])
                                .sum::<f64>()
                                - if a == 0 { spin_term[i] } else { 0.0 };
                            (n * D + i, factor * q)
                        })
                        .filter(|&(_, x)| x != 0.0)
                        .collect();
                    let column: Vec<(usize, f64)> = nodes
                        .iter()
                        .flat_map(|&(n, c)| (0..D).map(move |i| (n * D + i, c * normal[i])))
                        .filter(|&(_, x)| x != 0.0)
                        .collect();
                    if let Some(gradient) = &mut held_gradient {
                        gradient.extend(
                            row.iter()
                                .map(|&(i, x)| (i, x / normal_law.velocity_stiffness)),
                        );
                    }
                    if !row.is_empty() {
                        terms.coupling.push((column, row));
                    }
                }
                if d_normal_force != SVector::<f64, D>::zeros() {
                    // d(-F_t)/dv1 through F_n, which falls by `normal_stiffness` per unit of
                    // n . w1: u v^T with u = B^T mu t, v = B^T n normal_stiffness.
                    let spread = |x: SVector<f64, D>| -> Vec<(usize, f64)> {
                        nodes
                            .iter()
                            .flat_map(|&(n, c)| (0..D).map(move |i| (n * D + i, c * x[i])))
                            .filter(|&(_, x)| x != 0.0)
                            .collect()
                    };
                    terms
                        .coupling
                        .push((spread(d_normal_force), spread(normal * normal_stiffness)));
                }
                for (a, &(na, ca)) in nodes.iter().enumerate() {
                    for (b, &(nb, cb)) in nodes.iter().enumerate() {
                        let block = (nn * normal_stiffness + friction_tangent) * (ca * cb);
                        block_entries(&mut terms.entries, na, nb, &block);
                        if let (Some(hess), true) = (&hessian, geometric_force != 0.0) {
                            let g = SMatrix::<f64, D, D>::from_fn(|i, j| {
                                -0.5 * h * geometric_force * hess[a * D + i][b * D + j]
                            });
                            block_entries(&mut terms.geometric, na, nb, &g);
                        }
                    }
                }
            }
            if let (Some(gradient), Some(held)) = (held_gradient, normal_law.held) {
                terms.held.push((key, held.value, gradient));
            }
            if input.method.stores_energy() && gap < 0.0 {
                terms.energy += 0.5 * self.model.contact.penalty * area * gap * gap;
            }
            terms.dissipation_rate += -friction.dot(&slip);
            // A constraint stores nothing: its normal force's work is dissipated, signed, like
            // its end-of-step projection's. A penalty's is booked against what it stores
            // (`State::contact_loss`).
            let normal_work_rate = -normal_force * normal.dot(&(r0 + r1)) * 0.5;
            if input.method.stores_energy() {
                terms.normal_work_rate += normal_work_rate;
            } else {
                terms.dissipation_rate += normal_work_rate;
            }
            terms.pairs.push(PairOutcome {
                key,
                normal,
                gap,
                normal_force,
                friction,
                slip,
                master_point,
                obstacle,
                normal_velocity,
                master_velocity,
                // No copy on the Newton iterations where nothing stops pairs.
                nodes: if keep_nodes {
                    nodes.clone()
                } else {
                    Vec::new()
                },
                anchor,
                carried_by: if is_edge_pair { facet_weights } else { None },
            });
        }
        terms
    }

    /// The observers' view of an iteration's pairs.
    pub(super) fn records(
        &self,
        terms: &ContactTerms<D>,
        x_gap: &[SVector<f64, D>],
        method: &dyn Method,
        vars: &OuterVariables,
    ) -> Vec<ContactRecord<D>> {
        terms
            .pairs
            .iter()
            .map(|p| ContactRecord {
                slave: p.key.0,
                obstacle: p.obstacle,
                position: x_gap[p.key.0],
                master_point: p.master_point,
                normal: p.normal,
                gap: p.gap,
                normal_force: p.normal_force,
                friction_force: p.friction,
                slip_velocity: p.slip,
                active: p.normal_force > 0.0 || method.is_active(&p.key, vars),
            })
            .collect()
    }
}
