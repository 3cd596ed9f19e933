//! Implicit projection's end-of-step correction in the step's own metric
//! ([`ProjectionMetric::Step`]): the penetrating points are moved onto their masters by a
//! rigid motion of each body first (least squares on its obstacle contacts: it strains
//! nothing), then by the smallest change of the whole configuration in the norm of the
//! iteration matrix
//! `S = M/h + alpha^2 h K / 2`, `min 1/2 du^T S du` subject to `G_c du = -g_c` for every
//! penetrating active point c (G_c: the slave's normal, minus the master facet's weights times
//! it). The paper's projection moves each point alone ([`ProjectionMetric::Node`]): a point
//! stopped in one step from v0 sits about `h |v0| / 2` deep and moving it alone strains its
//! cells by that much, `k delta^2 / 2` against the `m v0^2 / 2` the stop removed, a ratio
//! `(h omega / 2)^2` that exceeds 1 wherever the step exceeds the contact patch's period
//! (about 11 on the soft cube at h = 1/60 s). In the step's metric the stiff modes refuse the
//! correction and the patch moves with its neighbours instead.
//!
//! The held points that do not penetrate keep their place on the master (`G_c du = 0`): the
//! correction of their neighbours would otherwise press them in or lift them off.
//!
//! The constraints are imposed by a penalty of [`VELOCITY_PENALTY`] times the slave's largest
//! diagonal entry, which leaves `1/VELOCITY_PENALTY` of each gap; one Uzawa correction takes
//! that to its square.
//! These are the rows, and the penalty, of implicit projection's velocity constraint in
//! Newton, so the step's last contact factorisation preconditions the solve almost exactly:
//! with rows for the penetrating points only, its conjugate gradients took 4 to 7 iterations
//! (the soft cube of 1331 nodes; the performance chapter), with the held rows one.

use std::collections::BTreeSet;

use nalgebra::{DMatrix, DVector, SVector};

use super::Simulation;
use crate::contact::methods::implicit_projection::VELOCITY_PENALTY;
use crate::contact::methods::PairOutcome;
use crate::contact::{ContactKey, ContactPair, Master, ProjectionMetric};
use crate::dim::{Dim, SpatialDim};
use crate::error::Result;
use crate::friction::FrictionLaw;

/// One constraint: its dofs with their coefficients (G_c), its gap (m), its penalty.
type Constraint = (Vec<(usize, f64)>, f64, f64);

/// A stopped pair: the contact, the master point (m) and the impulse as a force over the
/// step on the slave (N).
pub(super) type StoppedPair<const D: usize> = (ContactKey, SVector<f64, D>, SVector<f64, D>);

/// The penalty that imposes the persistency stop, relative to the largest diagonal of its
/// rows.
const PENALTY: f64 = 1e4;

/// Depths below this fraction of `gap_tolerance` are round-off the end-of-step correction
/// leaves as they are. Not the whole tolerance: Newton leaves held points 1e-12 to 1e-9 m deep,
/// and leaving those (a whole `gap_tolerance`) stored 4.8e-10 m inside the floor on a landing
/// block and changed the drum's friction-carried block turning rate from 0.13 % to 1.3 % off
/// the drum's (2026-12-02).
const ROUND_OFF_DEPTH: f64 = 1e-3;

/// A stopped pair whose friction is at least this fraction of its Coulomb limit slips, and
/// its stop's impulse takes friction (`stop_friction`).
const SLIPPING: f64 = 0.99;

/// The most solves of the end-of-step projection's active set on its penetrating points.
const MOVED_OUT_ROUNDS: usize = 6;

/// Whether a rigid translation of each body comes first. Off: on the soft cube it took the
/// energy created after the landing from 0.98 to 0.21 of the input, but the bundled gripper
/// (a block on a floor between closing jaws) stopped converging at step 108 with it, even
/// restricted to bodies near one obstacle only (the book's contact chapter, Limits).
const RIGID_PART: bool = false;

/// Whether the rigid part includes small rotations (else translations only: with rotations
/// a contact patch of a few nearly collinear points gave large turns, and a block on a slope
/// stopped converging).
const ROTATIONS: bool = false;

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// The correction of the configuration that moves the penetrating points of `pairs`
    /// (found at `positions`) onto their masters and keeps the other `active` ones there:
    /// rigid first, then in the step's metric (zero where nothing penetrates). The pairs from
    /// `master_side` on are the master side's nodes between two bodies: those deeper than
    /// `master_tolerance` are moved out, the others kept from ending deeper than it.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn weighted_projection(
        &mut self,
        pairs: &[ContactPair<D>],
        master_side: usize,
        active: &BTreeSet<ContactKey>,
        facets: &[[usize; D]],
        positions: &[SVector<f64, D>],
        h: f64,
        step: usize,
    ) -> Result<Vec<f64>> {
        debug_assert_eq!(self.model.contact.projection, ProjectionMetric::Step);
        let ndof = self.nodal_mass.len() * D;
        // Each constraint: its dofs with coefficients, its gap, its penalty.
        let mut rows: Vec<Constraint> = Vec::new();
        // The obstacle pairs, for the rigid part: (slave, normal, gap).
        let mut obstacle_rows: Vec<(usize, SVector<f64, D>, f64)> = Vec::new();
        let diagonal = self.system_diagonal().to_vec();
        // The obstacles each node is near (any gap): a body near two takes no rigid part.
        let near: Vec<(usize, usize)> = pairs
            .iter()
            .filter_map(|p| match p.master {
                Master::Obstacle(k) => Some((p.slave, k)),
                Master::Facet(_) => None,
            })
            .collect();
        // Whether a row holds a point that does not penetrate (gap 0).
        let mut holds: Vec<bool> = Vec::new();
        // Whether a row only watches its point: an inequality, imposed only if the correction
        // would break it.
        let mut watches: Vec<bool> = Vec::new();
        let gap_tolerance = self.model.contact.gap_tolerance;
        let master_tolerance = self.model.contact.master_tolerance;
        for (index, p) in pairs.iter().enumerate() {
            // A point nothing holds and that does not penetrate is watched: kept from ending
            // inside; a master-side node within its tolerance, from ending deeper than the
            // tolerance. Without these rows the correction that moved one point out pressed a
            // neighbour in, and the next pass the other way round: the 3D stack of soft blocks
            // ended its landing steps' four passes with master-side nodes 2.5e-5 to 3.8e-5 m
            // deep, and its top block's bottom nodes 1.8e-3 m deep in a cut step once those
            // had rows (2026-12-02).
            let master_watched = index >= master_side && p.gap >= -master_tolerance;
            let watched = master_watched
                || (index < master_side && p.gap >= 0.0 && !active.contains(&self.contact_key(p)));
            // Every penetrating point is moved out, active or free (a free one is leaving its
            // master: it penetrates while it separates). An active point that does not
            // penetrate stays where it is along the normal. So does, after being put onto
            // its master, one within the gap tolerance: the first pass's correction leaves
            // its points 1e-14 to 1e-12 m deep, and as inequalities their rows' multipliers
            // were round-off of either sign; dropping the rows they pulled took the second
            // pass up to six solves and a factorisation of its own (65 of them in 120 steps
            // of the soft cube).
            let held = !watched && p.gap >= -gap_tolerance;
            let mut g: Vec<(usize, f64)> = (0..D).map(|k| (p.slave * D + k, p.normal[k])).collect();
            if let Master::Facet(f) = p.master {
                for (i, &n) in facets[f].iter().enumerate() {
                    let w = p.barycentric[i];
                    g.extend((0..D).map(|k| (n * D + k, -w * p.normal[k])));
                }
            }
            g.retain(|&(i, c)| c != 0.0 && self.prescribed[i].is_none());
            if g.is_empty() {
                continue;
            }
            // Newton's velocity constraint's penalty.
            let rho = VELOCITY_PENALTY
                * (0..D)
                    .map(|k| diagonal[p.slave * D + k])
                    .fold(0.0, f64::max);
            if matches!(p.master, Master::Obstacle(_)) && !held {
                obstacle_rows.push((p.slave, p.normal, p.gap));
            }
            // A watched row's "gap" is its distance from the depth it may reach.
            let gap = if master_watched {
                p.gap + master_tolerance
            } else if watched {
                p.gap
            } else {
                p.gap.min(0.0)
            };
            rows.push((g, gap, rho));
            holds.push(held);
            watches.push(watched);
        }
        // Nothing deeper than round-off: no correction. A correction leaves its points 1e-13
        // to 1e-21 m deep, which the next pass corrected again, two solves and often a
        // factorisation for nothing (257 of the bundled block stack's 430 corrections).
        if rows
            .iter()
            .all(|row| row.1 >= -ROUND_OFF_DEPTH * gap_tolerance)
        {
            return Ok(vec![0.0; ndof]);
        }
        // The rigid part first: it strains nothing.
        let rigid = if RIGID_PART {
            self.rigid_projection(&obstacle_rows, &near, positions)
        } else {
            vec![0.0; ndof]
        };
        for row in &mut rows {
            row.1 += row.0.iter().map(|&(i, a)| a * rigid[i]).sum::<f64>();
        }
        let mut du = rigid.clone();
        // A penetrating point's row is an inequality (moved out of its master), a held one's
        // an equality (kept on it), a watched one an inequality not yet imposed.
        let (rows, moved_out): (Vec<Constraint>, Vec<bool>) = rows
            .into_iter()
            .zip(holds.into_iter().zip(watches))
            .filter(|(row, (held, watched))| *held || *watched || row.1 < 0.0)
            .map(|(row, (held, _))| (row, !held))
            .unzip();
        if rows.iter().all(|row| row.1 >= 0.0) {
            return Ok(du);
        }
        let elastic = self.projection_moving_out(&rows, &moved_out, h, step)?;
        for (d, e) in du.iter_mut().zip(&elastic) {
            *d += e;
        }
        Ok(du)
    }

    /// [`Self::metric_projection`] with the rows of penetrating points (`moved_out`) as
    /// inequalities, `G_c du >= -gap_c`: a point is moved out of its master, not necessarily
    /// onto it. A row whose multiplier pulls (its point would end clear of the master without
    /// it) is dropped, and taken back if its point then ends inside (a primal active set, at
    /// most [`MOVED_OUT_ROUNDS`] solves); an inequality row that starts satisfied (gap >= 0)
    /// starts dropped. With every row an equality, a block that landed
    /// at 3 m/s at h = 1/60 s (its bottom nodes 35.5 mm deep, the next layer, 25 mm up, 10 mm)
    /// had both layers put on the floor: its bottom cells flattened, 10 J of strain from the
    /// 4.7 J of the throw and the fall (E = 1e5 Pa; a cell turned inside out), or 94.7 J
    /// (E = 1 MPa): `contact::*::a_block_thrown_on_the_floor_lands`.
    fn projection_moving_out(
        &mut self,
        rows: &[Constraint],
        moved_out: &[bool],
        h: f64,
        step: usize,
    ) -> Result<Vec<f64>> {
        let tolerance = self.model.contact.gap_tolerance;
        let mut used: Vec<bool> = rows
            .iter()
            .zip(moved_out)
            .map(|(row, &inequality)| !inequality || row.1 < 0.0)
            .collect();
        // Where the rounds do not settle, the round that leaves the least depth: near-duplicate
        // rows of the two sides of a patch (a held slave, a master-side node beside it) can
        // trade places round after round, and the last round left a point 6.1e-5 m inside
        // (the 2D stack of soft blocks, 2026-12-02). Keeping a row taken back for good instead
        // left the 3D stack 2.34e-5 m deep against 1.52e-5 m this way.
        let mut best: Option<(f64, Vec<f64>)> = None;
        let mut elastic = Vec::new();
        for _ in 0..MOVED_OUT_ROUNDS {
            let chosen: Vec<Constraint> = rows
                .iter()
                .zip(&used)
                .filter(|(_, &u)| u)
                .map(|(row, _)| row.clone())
                .collect();
            let multipliers;
            (elastic, multipliers) = self.metric_projection(&chosen, h, step)?;
            let mut multipliers = multipliers.into_iter();
            let mut changed = false;
            for (c, (g, gap, _)) in rows.iter().enumerate() {
                if used[c] {
                    let m = multipliers.next().expect("one per used row");
                    if moved_out[c] && m < 0.0 {
                        used[c] = false;
                        changed = true;
                    }
                } else {
                    let moved: f64 = g.iter().map(|&(i, a)| a * elastic[i]).sum();
                    if gap + moved < -tolerance {
                        used[c] = true;
                        changed = true;
                    }
                }
            }
            if !changed {
                return Ok(elastic);
            }
            let depth = rows
                .iter()
                .map(|(g, gap, _)| -(gap + g.iter().map(|&(i, a)| a * elastic[i]).sum::<f64>()))
                .fold(0.0, f64::max);
            if best.as_ref().is_none_or(|(least, _)| depth < *least) {
                best = Some((depth, elastic.clone()));
            }
        }
        Ok(best.map_or(elastic, |(_, e)| e))
    }

    /// The smallest change `du` in the step's metric `S` with `G_c du = -gap_c` for every row
    /// c (imposed by each row's penalty and one Uzawa correction), prescribed components
    /// unmoved, and each row's multiplier: `S du = sum_c G_c^T m_c`, so that `m_c` is the
    /// impulse (N s) the row's constraint applies along `G_c` when `du` is a velocity change
    /// times h.
    pub(super) fn metric_projection(
        &mut self,
        rows: &[Constraint],
        h: f64,
        step: usize,
    ) -> Result<(Vec<f64>, Vec<f64>)> {
        let ndof = self.nodal_mass.len() * D;
        let entries = penalty_entries(rows);
        // Uzawa on the penalty: the multipliers (in units of the right-hand side) start at 0.
        let mut multipliers = vec![0.0; rows.len()];
        let mut elastic = vec![0.0; ndof];
        for _ in 0..2 {
            let mut rhs = vec![0.0; ndof];
            for ((g, gap, rho), m) in rows.iter().zip(&multipliers) {
                for &(i, a) in g {
                    rhs[i] += a * (m - rho * gap);
                }
            }
            elastic = self.penalised_solve(&entries, &rhs, h, step)?;
            for ((g, gap, rho), m) in rows.iter().zip(multipliers.iter_mut()) {
                let moved: f64 = g.iter().map(|&(i, a)| a * elastic[i]).sum();
                // The constraint's force after this solve: rho (-gap - moved) + m.
                *m -= rho * (gap + moved);
            }
        }
        Ok((self.without_prescribed(elastic), multipliers))
    }

    /// Solves `(S + entries) du = rhs` to 1e-12 of the right-hand side (the nearest kept
    /// factorisation with conjugate gradients, or a new one).
    fn penalised_solve(
        &mut self,
        entries: &[(usize, usize, f64)],
        rhs: &[f64],
        h: f64,
        step: usize,
    ) -> Result<Vec<f64>> {
        let norm = rhs.iter().map(|r| r * r).sum::<f64>().sqrt();
        let target = 1e-12 * norm;
        Ok(match self.preconditioned_solve(entries, &[], rhs, target) {
            Some(x) => x,
            None => self.factor_contact(entries, &[], rhs, target, h, step)?.0,
        })
    }

    /// Zeroes the prescribed components of a correction.
    fn without_prescribed(&self, mut du: Vec<f64>) -> Vec<f64> {
        for (i, d) in du.iter_mut().enumerate() {
            if self.prescribed[i].is_some() {
                *d = 0.0;
            }
        }
        du
    }

    /// The augmented Lagrangian's persistency stop on trapezoid gaps: every pair of `pairs`
    /// that ends the step closed (a normal force pushing it out) and still approaching has
    /// that relative normal velocity removed from `v1` by the smallest change in the step's
    /// metric (the one implicit projection's end-of-step correction takes), so that the
    /// consistent mass and the stiffness share it as the step itself would; pairs with a
    /// massless side are left alone. On trapezoid gaps, which the multipliers hold closed,
    /// such a pair otherwise alternates `w1 = -w0` from step to step, which the scheme does
    /// not damp. Returns each stopped pair with its impulse as a force over the step on the
    /// slave (N).
    pub(super) fn stop_closed_pairs(
        &mut self,
        pairs: &[PairOutcome<D>],
        v1: &mut [f64],
        h: f64,
        step: usize,
    ) -> Result<Vec<StoppedPair<D>>> {
        let diagonal = self.system_diagonal().to_vec();
        let mut rows: Vec<Constraint> = Vec::new();
        let mut stopped = Vec::new();
        for p in pairs {
            if p.normal_force <= 0.0 || p.normal_velocity >= 0.0 {
                continue;
            }
            if p.nodes
                .iter()
                .any(|&(node, _)| self.nodal_mass[node] <= 0.0)
            {
                // A massless side (a quasi-static flow): no velocity of its own to stop, and
                // the metric has no mass to share the change by.
                continue;
            }
            let mut g: Vec<(usize, f64)> = p
                .nodes
                .iter()
                .flat_map(|&(node, c)| (0..D).map(move |k| (node * D + k, c)))
                .map(|(i, c)| (i, c * p.normal[i % D]))
                .collect();
            g.retain(|&(i, c)| c != 0.0 && self.prescribed[i].is_none());
            if g.is_empty() {
                continue;
            }
            let rho = PENALTY * g.iter().map(|&(i, _)| diagonal[i]).fold(0.0, f64::max);
            // In displacement units: the step's travel at that velocity.
            rows.push((g, h * p.normal_velocity, rho));
            stopped.push(p);
        }
        if rows.is_empty() {
            return Ok(Vec::new());
        }
        let (du, multipliers) = self.metric_projection(&rows, h, step)?;
        for (v, d) in v1.iter_mut().zip(&du) {
            *v += d / h;
        }
        let friction = self.stop_friction(&stopped, &rows, &multipliers, v1, h, step)?;
        Ok(stopped
            .iter()
            .zip(&multipliers)
            .zip(&friction)
            .map(|((p, m), f)| (p.key, p.master_point, p.normal * (m / h) + f / h))
            .collect())
    }

    /// Coulomb's share of the persistency stop: the stop's normal impulse `m` on a pair that
    /// slips comes with `mu m` of friction against the slip, as the law asks of any impulse
    /// (the cone holds impulses as it holds forces). Applied in the same metric with the stop's
    /// rows held (their penalty in the matrix), so the stopped normal velocities stay stopped;
    /// shortened per pair where it would reverse the slip (one more solve). Sticking pairs
    /// (inside the cone) and the other laws, whose limit does not grow with the normal force,
    /// take none. Changes `v1`; returns each pair's added impulse (N s): its friction, and
    /// the normal reaction of its held row to the others' friction.
    fn stop_friction(
        &mut self,
        stopped: &[&PairOutcome<D>],
        rows: &[Constraint],
        multipliers: &[f64],
        v1: &mut [f64],
        h: f64,
        step: usize,
    ) -> Result<Vec<SVector<f64, D>>> {
        let mut impulses = vec![SVector::<f64, D>::zeros(); stopped.len()];
        let mut slipping: Vec<Slipping> = Vec::new();
        for (k, (p, m)) in stopped.iter().zip(multipliers).enumerate() {
            let FrictionLaw::Coulomb { coefficient, .. } = self.friction_law(p.obstacle) else {
                continue;
            };
            let limit = coefficient * p.normal_force;
            let magnitude = p.friction.norm();
            if *m <= 0.0 || limit <= 0.0 || magnitude < SLIPPING * limit {
                continue;
            }
            let along = p.friction / magnitude;
            let mut g: Vec<(usize, f64)> = p
                .nodes
                .iter()
                .flat_map(|&(node, c)| (0..D).map(move |j| (node * D + j, c * along[j])))
                .collect();
            g.retain(|&(i, c)| c != 0.0 && self.prescribed[i].is_none());
            // The end slip relative to the master (an obstacle's surface moves) runs against
            // the friction.
            let speed =
                along.dot(&p.master_velocity) - g.iter().map(|&(i, c)| c * v1[i]).sum::<f64>();
            if speed > 0.0 {
                slipping.push(Slipping {
                    pair: k,
                    along: g,
                    speed,
                    impulse: coefficient * m,
                });
            }
        }
        if slipping.is_empty() {
            return Ok(impulses);
        }
        let entries = penalty_entries(rows);
        let ndof = v1.len();
        let rhs_of = |slipping: &[Slipping]| {
            let mut rhs = vec![0.0; ndof];
            for s in slipping {
                for &(i, c) in &s.along {
                    rhs[i] += c * s.impulse;
                }
            }
            rhs
        };
        let mut du = self.penalised_solve(&entries, &rhs_of(&slipping), h, step)?;
        let mut shortened = false;
        for s in &mut slipping {
            let slowed: f64 = s.along.iter().map(|&(i, c)| c * du[i]).sum::<f64>() / h;
            if slowed > s.speed {
                s.impulse *= s.speed / slowed;
                shortened = true;
            }
        }
        if shortened {
            du = self.penalised_solve(&entries, &rhs_of(&slipping), h, step)?;
        }
        // The held rows' reactions to the friction: more normal impulse on the stopped pairs
        // (the penalty's force on what the solve left of each row). On a moving obstacle it
        // works through the obstacle's motion, and left out of the impulses that work went
        // unbooked: the tilting floor's start created 7.0-7.6 % of its input.
        for (k, (g, _, rho)) in rows.iter().enumerate() {
            let moved: f64 = g.iter().map(|&(i, a)| a * du[i]).sum();
            impulses[k] = stopped[k].normal * (-rho * moved);
        }
        for (v, d) in v1.iter_mut().zip(&self.without_prescribed(du)) {
            *v += d / h;
        }
        for s in slipping {
            let p = stopped[s.pair];
            impulses[s.pair] += p.friction * (s.impulse / p.friction.norm());
        }
        Ok(impulses)
    }

    /// The rigid motion of each body (translation, and small rotation about the mean contact
    /// point if [`ROTATIONS`]) that best removes its penetrations into obstacles, in the
    /// least-squares sense (minimum norm where the contacts leave it free: along a flat floor),
    /// shortened so that no point passes its master, and only where it moves every point out.
    /// Bodies with prescribed components take none.
    fn rigid_projection(
        &self,
        obstacle_rows: &[(usize, SVector<f64, D>, f64)],
        near: &[(usize, usize)],
        positions: &[SVector<f64, D>],
    ) -> Vec<f64> {
        let ndof = self.nodal_mass.len() * D;
        let mut du = vec![0.0; ndof];
        let unknowns = D + if ROTATIONS { Dim::<D>::ANGULAR } else { 0 };
        for b in 0..self.model.bodies.len() {
            let nodes = self.nodes_of(b);
            if (nodes.start * D..nodes.end * D).any(|i| self.prescribed[i].is_some()) {
                continue;
            }
            let rows: Vec<_> = obstacle_rows
                .iter()
                .filter(|r| nodes.contains(&r.0))
                .collect();
            let mut obstacles = near.iter().filter(|(n, _)| nodes.contains(n)).map(|p| p.1);
            let first = obstacles.next();
            if rows.is_empty() || obstacles.any(|k| Some(k) != first) {
                continue;
            }
            let centre = rows
                .iter()
                .fold(SVector::<f64, D>::zeros(), |c, r| c + positions[r.0])
                / rows.len() as f64;
            // Rotations scaled by the contact patch's size, so that both kinds of unknown
            // weigh alike in the minimum norm.
            let size = rows
                .iter()
                .map(|r| (positions[r.0] - centre).norm())
                .fold(0.0, f64::max)
                .max(1e-12);
            let mut a = DMatrix::<f64>::zeros(rows.len(), unknowns);
            let mut rhs = DVector::<f64>::zeros(rows.len());
            for (k, (slave, normal, gap)) in rows.iter().enumerate() {
                let r = (positions[*slave] - centre) / size;
                for j in 0..D {
                    a[(k, j)] = normal[j];
                }
                for j in 0..unknowns - D {
                    let mut omega = vec![0.0; Dim::<D>::ANGULAR];
                    omega[j] = 1.0;
                    a[(k, D + j)] = normal.dot(&Dim::<D>::spin_velocity(&omega, &r));
                }
                rhs[k] = -gap;
            }
            let svd = a.clone().svd(true, true);
            let largest = svd.singular_values.max();
            let Ok(q) = svd.solve(&rhs, 1e-6 * largest) else {
                continue;
            };
            // No point is moved past its master: the least-squares motion is shortened until
            // the least penetrating point just reaches it (the rest is the elastic part's).
            let moved = &a * &q;
            // Only where it moves every point outwards (a body landing on one surface), not
            // between surfaces that face each other (a block between jaws): there it would
            // push the other side deeper in.
            let largest_move = moved.amax();
            if moved.iter().any(|m| *m < -1e-9 * largest_move) {
                continue;
            }
            let scale = rows
                .iter()
                .zip(moved.iter())
                .filter(|(_, m)| **m > 0.0)
                .map(|(r, m)| -r.2 / m)
                .fold(1.0f64, f64::min)
                .max(0.0);
            let q = q * scale;
            let omega: Vec<f64> = (0..Dim::<D>::ANGULAR)
                .map(|j| if D + j < unknowns { q[D + j] } else { 0.0 })
                .collect();
            for n in nodes {
                let r = (positions[n] - centre) / size;
                let d = Dim::<D>::spin_velocity(&omega, &r);
                for k in 0..D {
                    du[n * D + k] = q[k] + d[k];
                }
            }
        }
        du
    }
}

/// A stopped pair that slips, in `stop_friction`.
struct Slipping {
    /// Its index among the stopped pairs.
    pair: usize,
    /// Its rows along the friction force (G_t).
    along: Vec<(usize, f64)>,
    /// Its slip speed (m/s), against the friction.
    speed: f64,
    /// Its friction impulse (N s).
    impulse: f64,
}

/// The lower triangle of the rows' penalty matrix `sum_c rho_c G_c^T G_c`.
fn penalty_entries(rows: &[Constraint]) -> Vec<(usize, usize, f64)> {
    let mut entries = Vec::new();
    for (g, _, rho) in rows {
        for &(i, a) in g {
            for &(j, b) in g {
                if i >= j {
                    entries.push((i, j, rho * a * b));
                }
            }
        }
    }
    entries
}
