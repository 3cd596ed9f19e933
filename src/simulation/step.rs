//! The space-time velocity step: Newton on the momentum balance at `t_alpha`, with the contact
//! methods inside it, step cutting, the state update and the energy account.

use std::collections::{BTreeMap, BTreeSet, HashSet};

use faer::sparse::{SparseColMat, Triplet};
use nalgebra::{SMatrix, SVector};

use super::{end_positions, invalid, BodyId, MasterId, Simulation, StepReport};
use crate::assembly;
use crate::contact::resolution::{facet_gap_hessian, plane_weights};
use crate::contact::{
    ContactMethod, ContactPair, Feature, FrictionLaw, Master, Obstacle, ObstacleShape,
};
use crate::dim::{Dim, SpatialDim};
use crate::error::{Error, Result};
use crate::recording::{ContactRecord, IterationInfo, NullRecorder, Recorder};
use crate::solver::SparseCholesky;

/// Deepest step cut: a step is halved at most this many times.
const MAX_CUTS: usize = 4;

/// Conjugate-gradient iterations allowed on top of the number of strongly changed unknowns
/// (see [`ContactFactor`]) before the contact matrix is factored anew.
const PCG_SLACK: usize = 6;

/// At most this many unknowns whose contact stiffness changed strongly since the nearest
/// factorisation are left to conjugate gradients; more, and the contact matrix is factored.
/// A factorisation costs about 20 to 25 preconditioner solves (Hex8 box, nested dissection,
/// single precision) and then serves the following iterations and steps; CG needs about one
/// iteration per changed unknown.
const PCG_LOW_RANK: usize = 12;

/// A change of the contact diagonal above this fraction of the factored diagonal counts as a
/// strong (low-rank) change: CG resolves each such unknown in about one iteration.
const STRONG_CHANGE: f64 = 0.5;

/// Contact factorisations kept as preconditioners. Two: Newton often returns to the contact
/// set of the previous iteration or step after one excursion (a node released by the predictor
/// and caught again), and each factorisation costs a dozen or more solves.
const CONTACT_FACTORS_KEPT: usize = 2;

/// Conjugate-gradient iterations allowed to refine a solve with a fresh single-precision
/// factorisation before it is redone in double precision.
const SINGLE_PRECISION_REFINEMENT: usize = 10;

/// The factorisation of a contact iteration matrix `A0 + K_c`, kept as the preconditioner of
/// the following iterations and steps (the contact set changes little between them).
pub(super) struct ContactFactor {
    time_step: f64,
    cholesky: SparseCholesky,
    /// The diagonal of the factored `K_c` (free unknowns), per unknown.
    diagonal: Vec<f64>,
}

/// Number of unknowns whose contact stiffness `now` differs from the factored `then` by more
/// than [`STRONG_CHANGE`] of the factored diagonal `base + then`.
fn strong_changes(base: &[f64], then: Option<&[f64]>, now: &[f64]) -> usize {
    (0..now.len())
        .filter(|&i| {
            let old = then.map_or(0.0, |t| t[i]);
            (now[i] - old).abs() > STRONG_CHANGE * (base[i] + old).abs()
        })
        .count()
}

/// Preconditioned conjugate gradients on `apply(x) = b` until the residual norm is at most
/// `target` (never below 1e-10 |b|): the solution and its residual
/// `b - apply(x)`; `None` if that takes more than `max` iterations.
fn conjugate_gradients(
    apply: &dyn Fn(&[f64]) -> Vec<f64>,
    precondition: &dyn Fn(&mut [f64]),
    b: &[f64],
    target: f64,
    max: usize,
) -> Option<(Vec<f64>, Vec<f64>)> {
    let n = b.len();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let b_norm = dot(b, b).sqrt();
    if b_norm == 0.0 {
        return Some((vec![0.0; n], vec![0.0; n]));
    }
    let target = target.max(1e-10 * b_norm);
    let mut x = b.to_vec();
    precondition(&mut x);
    let ax = apply(&x);
    let mut r: Vec<f64> = b.iter().zip(&ax).map(|(b, a)| b - a).collect();
    let mut z = r.clone();
    precondition(&mut z);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    for _ in 0..max {
        if dot(&r, &r).sqrt() <= target {
            return Some((x, r));
        }
        let ap = apply(&p);
        let alpha = rz / dot(&p, &ap);
        if !alpha.is_finite() || alpha <= 0.0 {
            return None;
        }
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        z.copy_from_slice(&r);
        precondition(&mut z);
        let rz_next = dot(&r, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
    }
    (dot(&r, &r).sqrt() <= target).then_some((x, r))
}

/// The factored contact-free iteration matrix for one step size.
pub(super) struct IterationSystem {
    time_step: f64,
    matrix: SparseColMat<usize, f64>,
    diagonal: Vec<f64>,
    cholesky: SparseCholesky,
}

/// One slave point's contribution in an iteration.
struct PairTerms<const D: usize> {
    key: (usize, MasterId),
    normal: SVector<f64, D>,
    gap: f64,
    normal_force: f64,
    friction: SVector<f64, D>,
    slip: SVector<f64, D>,
    master_point: SVector<f64, D>,
    obstacle: Option<usize>,
    /// Implicit projection: the relative normal end velocity [m/s].
    normal_velocity: f64,
}

/// Everything contact adds to one iteration.
#[derive(Default)]
struct ContactTerms<const D: usize> {
    forces: Vec<f64>,
    entries: Vec<(usize, usize, f64)>,
    /// The geometric part of the tangent (variation of the normal and of the closest point):
    /// kept while the iteration matrix stays positive definite.
    geometric: Vec<(usize, usize, f64)>,
    pairs: Vec<PairTerms<D>>,
    energy: f64,
    dissipation_rate: f64,
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
    /// One step of the configured size.
    pub fn step(&mut self) -> Result<StepReport> {
        let h = self.settings.time_step;
        self.advance(h, &mut NullRecorder)
    }

    /// One step of the configured size, observed by a recorder.
    pub fn step_with(&mut self, recorder: &mut dyn Recorder<D>) -> Result<StepReport> {
        let h = self.settings.time_step;
        self.advance(h, recorder)
    }

    /// One step of size `h` [s] observed by `recorder`. A step whose Newton or contact
    /// iteration does not converge (or whose contact set cycles) is cut in halves, up to four
    /// times; on error the state is left as it was at the start of the step.
    pub fn advance(&mut self, h: f64, recorder: &mut dyn Recorder<D>) -> Result<StepReport> {
        if !(h > 0.0 && h.is_finite()) {
            return Err(invalid("time_step", h, "a finite value > 0 [s]"));
        }
        let saved = self.state.clone();
        match self.advance_cut(h, recorder, 0, true) {
            Ok(r) => Ok(r),
            Err(e) => {
                self.state = saved;
                Err(e)
            }
        }
    }

    fn advance_cut(
        &mut self,
        h: f64,
        recorder: &mut dyn Recorder<D>,
        depth: usize,
        last_piece: bool,
    ) -> Result<StepReport> {
        match self.advance_once(h, recorder, last_piece) {
            Err(Error::NotConverged { .. }) if depth < MAX_CUTS => {
                recorder.log(
                    self,
                    &format!(
                        "step {} at t = {:.6e} s: no convergence with h = {h:.3e} s, cutting it in two",
                        self.state.step + 1,
                        self.state.time
                    ),
                );
                let first = self.advance_cut(0.5 * h, recorder, depth + 1, false)?;
                let mut second = self.advance_cut(0.5 * h, recorder, depth + 1, last_piece)?;
                second.iterations += first.iterations;
                second.time_step = h;
                for (a, b) in second.reactions.iter_mut().zip(&first.reactions) {
                    for (x, y) in a.iter_mut().zip(b) {
                        *x = 0.5 * (*x + y);
                    }
                }
                for (a, b) in second.contact_forces.iter_mut().zip(&first.contact_forces) {
                    for (x, y) in a.iter_mut().zip(b) {
                        *x = 0.5 * (*x + y);
                    }
                }
                Ok(second)
            }
            other => other,
        }
    }

    fn ensure_system(&mut self, h: f64) -> Result<()> {
        if self.system.as_ref().is_some_and(|s| s.time_step == h) {
            return Ok(());
        }
        let (_, d1) = self.settings.scheme.displacement_weights();
        let matrix = self.iteration_matrix(h, d1);
        let mut cholesky = match self.system.take() {
            Some(s) => s.cholesky,
            None => SparseCholesky::analyse_with(&matrix, self.settings.ordering, D)?,
        };
        cholesky.factor(&matrix, self.state.step + 1)?;
        let mut diagonal = vec![0.0; matrix.nrows()];
        let (cp, ri, v) = (
            matrix.symbolic().col_ptr(),
            matrix.symbolic().row_idx(),
            matrix.val(),
        );
        for j in 0..matrix.ncols() {
            for k in cp[j]..cp[j + 1] {
                if ri[k] == j {
                    diagonal[j] = v[k];
                }
            }
        }
        self.system = Some(IterationSystem {
            time_step: h,
            matrix,
            diagonal,
            cholesky,
        });
        Ok(())
    }

    /// `M/h + (alpha^2 h / 2) K` with prescribed rows and columns replaced by the identity
    /// (scaled to the mean diagonal, for conditioning).
    fn iteration_matrix(&self, h: f64, d1: f64) -> SparseColMat<usize, f64> {
        let mut a = self.matrices.mass.clone();
        let (m_vals, k_vals) = (self.matrices.mass.val(), self.matrices.stiffness.val());
        let col_ptr = a.symbolic().col_ptr().to_vec();
        let row_idx = a.symbolic().row_idx().to_vec();
        let vals = a.val_mut();
        for i in 0..vals.len() {
            vals[i] = m_vals[i] / h + d1 * h * k_vals[i];
        }
        let mut diag_sum = 0.0;
        for j in 0..col_ptr.len() - 1 {
            for k in col_ptr[j]..col_ptr[j + 1] {
                if row_idx[k] == j {
                    diag_sum += vals[k];
                }
            }
        }
        let scale = diag_sum / (col_ptr.len() - 1).max(1) as f64;
        for j in 0..col_ptr.len() - 1 {
            for k in col_ptr[j]..col_ptr[j + 1] {
                let i = row_idx[k];
                if self.prescribed[i].is_some() || self.prescribed[j].is_some() {
                    vals[k] = if i == j { scale } else { 0.0 };
                }
            }
        }
        a
    }

    /// The obstacles at the given translations (D per obstacle).
    fn obstacles_at(&self, translations: &[f64]) -> Vec<Obstacle<D>> {
        self.obstacles
            .iter()
            .enumerate()
            .map(|(k, o)| Obstacle {
                translation: SVector::from_column_slice(&translations[k * D..k * D + D]),
                ..o.clone()
            })
            .collect()
    }

    fn obstacle_velocity(&self, k: usize) -> SVector<f64, D> {
        SVector::from_column_slice(&self.state.obstacle_velocities[k * D..k * D + D])
    }

    /// Each boundary node's shares of the surface [m^2] at positions `x`, with the outward
    /// normal of the face each share comes from (length x unit thickness in plane kinematics,
    /// `2 pi r` x length in axisymmetric ones).
    fn tributary_areas(&self, x: &[SVector<f64, D>]) -> Vec<Vec<(f64, SVector<f64, D>)>> {
        let mut shares: Vec<Vec<(f64, SVector<f64, D>)>> = vec![Vec::new(); x.len()];
        let axisymmetric = self.settings.kinematics == crate::dim::Kinematics::Axisymmetric;
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

    /// Hessian of the distance to an analytic obstacle at a slave point (zero on faces).
    fn obstacle_gap_hessian(
        &self,
        obstacle: &Obstacle<D>,
        pair: &ContactPair<D>,
        x: &SVector<f64, D>,
    ) -> SMatrix<f64, D, D> {
        let n = pair.normal;
        let projector = SMatrix::<f64, D, D>::identity() - n * n.transpose();
        let distance = (x - pair.point).norm();
        match (&obstacle.shape, pair.feature) {
            (ObstacleShape::Ball { center, .. }, _) => {
                let d = (x - center - obstacle.translation).norm();
                if d > 0.0 {
                    projector / d
                } else {
                    SMatrix::zeros()
                }
            }
            (ObstacleShape::Box { .. }, Feature::Vertex(_)) if distance > 0.0 => {
                projector / distance
            }
            (ObstacleShape::Box { .. }, Feature::Edge(k)) if distance > 0.0 && D == 3 => {
                let mut e = SVector::<f64, D>::zeros();
                e[k] = 1.0;
                (projector - e * e.transpose()) / distance
            }
            (ObstacleShape::Facets { .. }, Feature::Vertex(_)) if distance > 0.0 => {
                projector / distance
            }
            // Faces are flat; the edges of a triangle-mesh obstacle are not curved in their own
            // direction and their small transverse term is dropped (named in the book).
            _ => SMatrix::zeros(),
        }
    }

    /// Forces, tangent entries and records of every detected pair.
    #[allow(clippy::too_many_arguments)]
    fn contact_terms(
        &self,
        pairs: &[ContactPair<D>],
        obstacles_t1: &[Obstacle<D>],
        x_gap: &[SVector<f64, D>],
        v0: &[f64],
        v1: &[f64],
        h: f64,
        areas: &[Vec<(f64, SVector<f64, D>)>],
        multipliers: &BTreeMap<(usize, MasterId), f64>,
        friction_normals: &BTreeMap<(usize, MasterId), f64>,
        active: &BTreeSet<(usize, MasterId)>,
        diagonal: &[f64],
    ) -> ContactTerms<D> {
        let method = self.contact.method;
        let zeta = self.contact.penalty;
        let ndof = v1.len();
        let mut terms = ContactTerms {
            forces: vec![0.0; ndof],
            ..Default::default()
        };
        let node_v =
            |v: &[f64], n: usize| SVector::<f64, D>::from_column_slice(&v[n * D..n * D + D]);
        let detector = match &self.detector {
            Some(d) => d,
            None => return terms,
        };
        let surface = detector.surface();
        for pair in pairs {
            let s = pair.slave;

            // Master nodes with their weights, the normal and the gap.
            let (key, nodes, normal, gap, master_velocity, obstacle, master_point) =
                match pair.master {
                    Master::Obstacle(k) => (
                        (s, MasterId::Obstacle(k)),
                        vec![(s, 1.0)],
                        pair.normal,
                        pair.gap,
                        self.obstacle_velocity(k),
                        Some(k),
                        pair.point,
                    ),
                    Master::Facet(f) => {
                        let facet = surface.facets()[f];
                        let y: [SVector<f64, D>; D] = std::array::from_fn(|i| x_gap[facet[i]]);
                        let (measure, n) = <Dim<D>>::facet_measure_normal(&y);
                        if measure <= 0.0 {
                            continue;
                        }
                        let w = plane_weights::<D>(&x_gap[s], &y, &n);
                        let g = (x_gap[s] - y[0]).dot(&n);
                        let mut nodes = vec![(s, 1.0)];
                        let mut q = SVector::<f64, D>::zeros();
                        for i in 0..D {
                            nodes.push((facet[i], -w[i]));
                            q += y[i] * w[i];
                        }
                        (
                            (s, MasterId::Body(surface.facet_body()[f])),
                            nodes,
                            n,
                            g,
                            SVector::zeros(),
                            None,
                            q,
                        )
                    }
                };
            let relative = |v: &[f64]| -> SVector<f64, D> {
                let mut r = -master_velocity;
                for &(n, c) in &nodes {
                    r += node_v(v, n) * c;
                }
                r
            };
            let area = Self::contact_area(&areas[s], &normal);
            let (r0, r1) = (relative(v0), relative(v1));
            let projector = SMatrix::<f64, D, D>::identity() - normal * normal.transpose();
            let slip = projector * (r0 + r1) * 0.5;
            let normal_velocity = normal.dot(&r1);

            // Normal force and the stiffness of its law.
            let (normal_force, normal_stiffness, pressure) = match method {
                ContactMethod::SoftWay | ContactMethod::AugmentedLagrangian => {
                    let lambda = if method == ContactMethod::AugmentedLagrangian {
                        multipliers.get(&key).copied().unwrap_or(0.0)
                    } else {
                        0.0
                    };
                    let p = lambda - zeta * gap;
                    if p > 0.0 {
                        (p * area, 0.5 * h * zeta * area, p)
                    } else {
                        (0.0, 0.0, 0.0)
                    }
                }
                ContactMethod::ImplicitProjection => {
                    if active.contains(&key) {
                        let rho = 1e4 * (0..D).map(|k| diagonal[s * D + k]).fold(0.0, f64::max);
                        let lambda = multipliers.get(&key).copied().unwrap_or(0.0);
                        (lambda - rho * normal_velocity, rho, 0.0)
                    } else {
                        (0.0, 0.0, 0.0)
                    }
                }
                ContactMethod::ExplicitProjection => (0.0, 0.0, 0.0),
            };
            // Friction takes the normal force of the previous pass (a fixed point on the
            // friction threshold: a sequence of Tresca problems, each with a symmetric tangent).
            let law = obstacle
                .and_then(|k| self.obstacles[k].friction)
                .unwrap_or(self.contact.friction);
            // Only Coulomb's threshold depends on the force; the other laws need the status.
            let threshold = match law {
                FrictionLaw::Coulomb { .. } => friction_normals.get(&key).copied().unwrap_or(0.0),
                _ => normal_force,
            };
            let (friction, friction_tangent) =
                if threshold > 0.0 && law != FrictionLaw::Frictionless {
                    law.force(threshold, area, &slip, &normal)
                } else {
                    (SVector::zeros(), SMatrix::zeros())
                };
            let force = normal * normal_force + friction;
            for &(n, c) in &nodes {
                for k in 0..D {
                    terms.forces[n * D + k] += c * force[k];
                }
            }
            // Tangent: d(-force)/dv1 on every pair of involved nodes.
            if normal_stiffness > 0.0 || law != FrictionLaw::Frictionless {
                let nn = normal * normal.transpose();
                let geometric: Option<Vec<Vec<f64>>> = if pressure > 0.0 {
                    match pair.master {
                        Master::Facet(f) => {
                            let facet = surface.facets()[f];
                            let y: [SVector<f64, D>; D] = std::array::from_fn(|i| x_gap[facet[i]]);
                            Some(facet_gap_hessian::<D>(&x_gap[s], &y))
                        }
                        Master::Obstacle(k) => {
                            let hs = self.obstacle_gap_hessian(&obstacles_t1[k], pair, &x_gap[s]);
                            let mut m = vec![vec![0.0; D]; D];
                            for i in 0..D {
                                for j in 0..D {
                                    m[i][j] = hs[(i, j)];
                                }
                            }
                            Some(m)
                        }
                    }
                } else {
                    None
                };
                for (a, &(na, ca)) in nodes.iter().enumerate() {
                    for (b, &(nb, cb)) in nodes.iter().enumerate() {
                        let block =
                            nn * (normal_stiffness * ca * cb) - friction_tangent * (0.5 * ca * cb);
                        block_entries(&mut terms.entries, na, nb, &block);
                        if let Some(hess) = &geometric {
                            let g = SMatrix::<f64, D, D>::from_fn(|i, j| {
                                -0.5 * h * pressure * area * hess[a * D + i][b * D + j]
                            });
                            block_entries(&mut terms.geometric, na, nb, &g);
                        }
                    }
                }
            }
            if matches!(
                method,
                ContactMethod::SoftWay | ContactMethod::AugmentedLagrangian
            ) && gap < 0.0
            {
                terms.energy += 0.5 * zeta * area * gap * gap;
            }
            terms.dissipation_rate += -friction.dot(&slip);
            terms.pairs.push(PairTerms {
                key,
                normal,
                gap,
                normal_force,
                friction,
                slip,
                master_point,
                obstacle,
                normal_velocity,
            });
        }
        terms
    }

    /// The iteration matrix with the contact entries added; re-analysed when the contact adds
    /// couplings that are not in the contact-free pattern.
    fn contact_matrix(&self, entries: &[(usize, usize, f64)]) -> Result<SparseColMat<usize, f64>> {
        let system = self.system.as_ref().expect("ensure_system ran");
        let base = &system.matrix;
        let mut matrix = base.clone();
        let (cp, ri) = (
            base.symbolic().col_ptr().to_vec(),
            base.symbolic().row_idx().to_vec(),
        );
        let vals = matrix.val_mut();
        let mut missing = Vec::new();
        for &(r, c, v) in entries {
            if self.prescribed[r].is_some() || self.prescribed[c].is_some() {
                continue;
            }
            match ri[cp[c]..cp[c + 1]].binary_search(&r) {
                Ok(k) => vals[cp[c] + k] += v,
                Err(_) => missing.push(Triplet::new(r, c, v)),
            }
        }
        if missing.is_empty() {
            return Ok(matrix);
        }
        let mut triplets = missing;
        for j in 0..matrix.ncols() {
            for k in cp[j]..cp[j + 1] {
                triplets.push(Triplet::new(ri[k], j, matrix.val()[k]));
            }
        }
        SparseColMat::try_new_from_triplets(matrix.nrows(), matrix.ncols(), &triplets).map_err(
            |e| Error::Factorization {
                step: self.state.step + 1,
                message: format!("{e:?}"),
            },
        )
    }

    /// One step without cutting. `count_step` is false for the first pieces of a cut step.
    fn advance_once(
        &mut self,
        h: f64,
        recorder: &mut dyn Recorder<D>,
        count_step: bool,
    ) -> Result<StepReport> {
        let step = self.state.step + 1;
        let t0 = self.state.time;
        self.ensure_system(h)?;
        recorder.step_start(self, step);

        let scheme = self.settings.scheme;
        let (d0, d1) = scheme.displacement_weights();
        let ndof = self.state.velocity.len();
        let v0 = self.state.velocity.clone();
        let u0 = self.state.displacement.clone();
        let f_ext: Vec<f64> = self
            .gravity_force
            .iter()
            .zip(&self.state.loads)
            .map(|(g, l)| g + l)
            .collect();
        let method = self.contact.method;
        let contact_in_newton =
            self.detector.is_some() && method != ContactMethod::ExplicitProjection;
        let x0 = end_positions(&self.reference, &u0, &v0, &vec![0.0; ndof], 0.0);
        let translations_t0 = self.state.obstacle_translations.clone();
        let translations_t1: Vec<f64> = translations_t0
            .iter()
            .zip(&self.state.obstacle_velocities)
            .map(|(t, v)| t + h * v)
            .collect();
        let obstacles_t0 = self.obstacles_at(&translations_t0);
        let obstacles_t1 = self.obstacles_at(&translations_t1);
        let t1_vectors: Vec<SVector<f64, D>> = obstacles_t1.iter().map(|o| o.translation).collect();
        let areas = if self.detector.is_some() {
            self.tributary_areas(&x0)
        } else {
            Vec::new()
        };
        let diagonal = self
            .system
            .as_ref()
            .map(|s| s.diagonal.clone())
            .unwrap_or_default();

        let frictional = self.contact.friction != FrictionLaw::Frictionless
            || self
                .obstacles
                .iter()
                .any(|o| o.friction.is_some_and(|f| f != FrictionLaw::Frictionless));
        let mut friction_normals: BTreeMap<(usize, MasterId), f64> = self
            .state
            .friction_normals
            .iter()
            .map(|&(s, m, f)| ((s, m), f))
            .collect();
        let mut multipliers: BTreeMap<(usize, MasterId), f64> =
            if method == ContactMethod::AugmentedLagrangian {
                self.state
                    .multipliers
                    .iter()
                    .map(|&(s, m, l)| ((s, m), l))
                    .collect()
            } else {
                BTreeMap::new()
            };
        let mut active: BTreeSet<(usize, MasterId)> = BTreeSet::new();
        let mut active_initialised = false;
        let mut seen_sets: HashSet<Vec<(usize, MasterId)>> = HashSet::new();
        let mut passes = 0;

        let mut v1 = v0.clone();
        for (dof, p) in self.prescribed.iter().enumerate() {
            if let Some(v) = p {
                v1[dof] = *v;
            }
        }
        let mut u_alpha = vec![0.0; ndof];
        let mut residual = vec![0.0; ndof];
        let mut iterations = 0;
        let relative;
        let mut terms = ContactTerms::<D>::default();
        let mut candidates = 0;
        let tolerance = self.settings.tolerance;
        let not_converged = |iterations: usize, residual: f64| Error::NotConverged {
            step,
            time: t0,
            iterations,
            residual,
            tolerance,
        };
        let mut previous_norm = f64::INFINITY;
        let mut last_increment: Vec<f64> = Vec::new();
        // -M v0 / h: the same in every iteration.
        let mut momentum0 = vec![0.0; ndof];
        assembly::symmetric_mul_add(&self.matrices.mass, &v0, -1.0 / h, &mut momentum0);
        let mut backtracks = 0;
        loop {
            let x_gap = end_positions(&self.reference, &u0, &v0, &v1, h);
            if contact_in_newton {
                let detector = self.detector.as_mut().expect("contact_in_newton");
                detector.update_candidates(&x0, &x_gap, &obstacles_t0, &t1_vectors);
                candidates = detector.candidates().len();
                let mut pairs = detector.pairs(&x_gap, &obstacles_t1);
                // One pass between two bodies: the nodes of the body listed first are slaves
                // against the facets of the other (no duplicated constraints). Self-contact
                // keeps both sides of a fold.
                let facet_body = detector.surface().facet_body();
                let offsets = &self.node_offsets;
                pairs.retain(|p| match p.master {
                    Master::Facet(f) => {
                        let slave_body = offsets.partition_point(|&o| o <= p.slave) - 1;
                        facet_body[f] >= slave_body
                    }
                    Master::Obstacle(_) => true,
                });
                if method == ContactMethod::ImplicitProjection && !active_initialised {
                    // Points predicted to penetrate with v1 = v0 start active: this also
                    // catches points already touching that the master moves into.
                    for p in &pairs {
                        if p.gap < 0.0 {
                            let key = match p.master {
                                Master::Obstacle(k) => (p.slave, MasterId::Obstacle(k)),
                                Master::Facet(f) => (
                                    p.slave,
                                    MasterId::Body(
                                        self.detector.as_ref().expect("set").surface().facet_body()
                                            [f],
                                    ),
                                ),
                            };
                            active.insert(key);
                        }
                    }
                    active_initialised = true;
                }
                terms = self.contact_terms(
                    &pairs,
                    &obstacles_t1,
                    &x_gap,
                    &v0,
                    &v1,
                    h,
                    &areas,
                    &multipliers,
                    &friction_normals,
                    &active,
                    &diagonal,
                );
            }
            for i in 0..ndof {
                u_alpha[i] = u0[i] + h * (d0 * v0[i] + d1 * v1[i]);
            }
            let mut inertia = momentum0.clone();
            let mut momentum1 = vec![0.0; ndof];
            let mut internal = vec![0.0; ndof];
            assembly::symmetric_mul_add(&self.matrices.mass, &v1, 1.0 / h, &mut momentum1);
            assembly::symmetric_mul_add(&self.matrices.stiffness, &u_alpha, 1.0, &mut internal);
            let mut free_norm2 = 0.0;
            let mut scale2 = [0.0f64; 5];
            for i in 0..ndof {
                let contact = terms.forces.get(i).copied().unwrap_or(0.0);
                let old = inertia[i];
                inertia[i] += momentum1[i];
                residual[i] = inertia[i] + internal[i] - f_ext[i] - contact;
                if self.prescribed[i].is_none() {
                    free_norm2 += residual[i] * residual[i];
                }
                // The scale includes prescribed dofs: at equilibrium the free-dof forces
                // cancel, while the reactions carry the load level.
                scale2[0] += old * old;
                scale2[1] += momentum1[i] * momentum1[i];
                scale2[2] += internal[i] * internal[i];
                scale2[3] += f_ext[i] * f_ext[i];
                scale2[4] += contact * contact;
            }
            let scale = scale2.iter().fold(0.0f64, |m, s| m.max(s.sqrt()));
            let norm = free_norm2.sqrt();
            let rel = if scale > 0.0 { norm / scale } else { 0.0 };
            if !rel.is_finite() {
                return Err(Error::Unstable {
                    step,
                    time: t0 + h,
                    detail: "the residual became non-finite".into(),
                });
            }
            // Backtracking: contact and friction are not smooth, and a full Newton step can
            // overshoot (first touch with a stiff penalty); halve it while the residual grows.
            if contact_in_newton
                && !last_increment.is_empty()
                && norm > previous_norm
                && backtracks < 4
            {
                for i in 0..ndof {
                    last_increment[i] *= 0.5;
                    v1[i] -= last_increment[i];
                }
                backtracks += 1;
                continue;
            }
            backtracks = 0;
            previous_norm = norm;
            if rel <= self.settings.tolerance {
                // Newton converged for the current multipliers and active set.
                let mut done = true;
                match method {
                    ContactMethod::AugmentedLagrangian => {
                        let worst = terms.pairs.iter().map(|p| -p.gap).fold(0.0, f64::max);
                        if worst > self.contact.gap_tolerance {
                            done = false;
                            for p in &terms.pairs {
                                let lambda = multipliers.entry(p.key).or_insert(0.0);
                                *lambda = (*lambda - self.contact.penalty * p.gap).max(0.0);
                            }
                        }
                    }
                    ContactMethod::ImplicitProjection => {
                        let mut changed = false;
                        for p in &terms.pairs {
                            if active.contains(&p.key) && p.normal_force < 0.0 {
                                active.remove(&p.key);
                                multipliers.remove(&p.key);
                                changed = true;
                                recorder.log(
                                    self,
                                    &format!(
                                        "step {step}: node {} released (tension {:.3e} N)",
                                        p.key.0, p.normal_force
                                    ),
                                );
                            } else if !active.contains(&p.key)
                                && p.gap < -self.contact.gap_tolerance
                            {
                                active.insert(p.key);
                                changed = true;
                                recorder.log(
                                    self,
                                    &format!(
                                        "step {step}: node {} activated (gap {:.3e} m)",
                                        p.key.0, p.gap
                                    ),
                                );
                            }
                        }
                        if changed {
                            let set: Vec<(usize, MasterId)> = active.iter().copied().collect();
                            if !seen_sets.insert(set) {
                                recorder.log(self, &format!("step {step}: the contact set cycles"));
                                return Err(not_converged(iterations, rel));
                            }
                            done = false;
                        } else {
                            let tolerance = self.contact.gap_tolerance / h;
                            let worst = terms
                                .pairs
                                .iter()
                                .filter(|p| active.contains(&p.key))
                                .map(|p| p.normal_velocity.abs())
                                .fold(0.0, f64::max);
                            if worst > tolerance {
                                done = false;
                                for p in &terms.pairs {
                                    if active.contains(&p.key) {
                                        multipliers.insert(p.key, p.normal_force);
                                    }
                                }
                            }
                        }
                    }
                    _ => {}
                }
                if done && frictional {
                    // The friction threshold follows the normal force until it settles.
                    let scale = terms
                        .pairs
                        .iter()
                        .map(|p| p.normal_force.abs())
                        .fold(0.0, f64::max);
                    let mut change: f64 = 0.0;
                    let mut next = BTreeMap::new();
                    for p in &terms.pairs {
                        let f = p.normal_force.max(0.0);
                        let old = friction_normals.get(&p.key).copied().unwrap_or(0.0);
                        let law = p
                            .obstacle
                            .and_then(|k| self.obstacles[k].friction)
                            .unwrap_or(self.contact.friction);
                        // Coulomb follows the force; the other laws only need the contact status.
                        if matches!(law, FrictionLaw::Coulomb { .. }) {
                            change = change.max((f - old).abs());
                        }
                        if f > 0.0 {
                            next.insert(p.key, f);
                        }
                    }
                    change = change.max(
                        friction_normals
                            .iter()
                            .filter(|(k, _)| !next.contains_key(k))
                            .map(|(_, f)| f.abs())
                            .fold(0.0, f64::max),
                    );
                    if change > 1e-6 * scale.max(f64::MIN_POSITIVE) {
                        done = false;
                        friction_normals = next;
                    }
                }
                if done {
                    relative = rel;
                    break;
                }
                passes += 1;
                previous_norm = f64::INFINITY;
                last_increment.clear();
                if passes > self.contact.max_passes {
                    return Err(not_converged(iterations, rel));
                }
                continue;
            }
            if iterations >= self.settings.max_iterations {
                return Err(not_converged(iterations, rel));
            }
            let mut increment: Vec<f64> = residual
                .iter()
                .zip(&self.prescribed)
                .map(|(r, p)| if p.is_some() { 0.0 } else { -r })
                .collect();
            // Linear solves go only as far as Newton needs: a tenth of its tolerance.
            let target = 0.1 * tolerance * scale;
            if terms.entries.is_empty() {
                if let Some(system) = &self.system {
                    system.cholesky.solve_in_place(&mut increment);
                }
            } else if let Some(x) = self.preconditioned_solve(&terms, &increment, target) {
                // The nearest factorisation (the last contact one or the contact-free one)
                // preconditions conjugate gradients, solved only as far as Newton needs.
                increment = x;
            } else {
                increment = self.factor_contact(&terms, &increment, target, h, step)?;
            }
            let mut inc2 = 0.0;
            for i in 0..ndof {
                if self.prescribed[i].is_none() {
                    v1[i] += increment[i];
                    inc2 += increment[i] * increment[i];
                }
            }
            last_increment = increment;
            iterations += 1;
            if !recorder.is_enabled() {
                continue;
            }
            let records = self.records(&terms, &x_gap, &active);
            recorder.iteration(
                self,
                &IterationInfo {
                    step,
                    iteration: iterations,
                    time: t0,
                    time_step: h,
                    residual_norm: norm,
                    relative_residual: rel,
                    increment_norm: inc2.sqrt(),
                    end_velocity: &v1,
                    end_positions: &end_positions(&self.reference, &u0, &v0, &v1, h),
                    candidates,
                    contacts: &records,
                },
            );
        }

        // The configuration update and the end-of-step projections.
        let (b0, b1) = scheme.update_weights();
        let mut u1: Vec<f64> = (0..ndof)
            .map(|i| u0[i] + h * (b0 * v0[i] + b1 * v1[i]))
            .collect();
        let mut contact_forces = vec![vec![0.0; D]; self.obstacles.len()];
        for p in &terms.pairs {
            if let Some(k) = p.obstacle {
                let f = p.normal * p.normal_force + p.friction;
                for i in 0..D {
                    contact_forces[k][i] += f[i];
                }
            }
        }
        let mut projection_loss = 0.0;
        let projecting = matches!(
            method,
            ContactMethod::ImplicitProjection | ContactMethod::ExplicitProjection
        );
        let end_pairs = match self.detector.as_mut() {
            Some(detector) if projecting => {
                let x_end = end_positions(&self.reference, &u1, &v1, &vec![0.0; ndof], 0.0);
                detector.update_candidates(&x0, &x_end, &obstacles_t0, &t1_vectors);
                let pairs = detector.pairs(&x_end, &obstacles_t1);
                let surface_bodies: Vec<usize> = detector.surface().facet_body().to_vec();
                let facets: Vec<[usize; D]> = detector.surface().facets().to_vec();
                Some((pairs, surface_bodies, facets))
            }
            _ => None,
        };
        if let Some((pairs, surface_bodies, facets)) = end_pairs {
            let kinetic_before = 0.5 * assembly::symmetric_dot(&self.matrices.mass, &v1, &v1);
            for p in &pairs {
                let key = match p.master {
                    Master::Obstacle(k) => (p.slave, MasterId::Obstacle(k)),
                    Master::Facet(f) => (p.slave, MasterId::Body(surface_bodies[f])),
                };
                let project = match method {
                    ContactMethod::ImplicitProjection => active.contains(&key),
                    _ => p.gap < 0.0,
                };
                if !project {
                    continue;
                }
                let s = p.slave;
                // Master nodes (weights) and the master's velocity.
                let (masters, master_velocity): (Vec<(usize, f64)>, SVector<f64, D>) = match p
                    .master
                {
                    Master::Obstacle(k) => (Vec::new(), self.obstacle_velocity(k)),
                    Master::Facet(f) => {
                        let w = p.barycentric;
                        let list: Vec<(usize, f64)> =
                            (0..D).map(|i| (facets[f][i], w[i])).collect();
                        let mut v = SVector::<f64, D>::zeros();
                        for &(n, c) in &list {
                            v += SVector::<f64, D>::from_column_slice(&v1[n * D..n * D + D]) * c;
                        }
                        (list, v)
                    }
                };
                let ms = self.nodal_mass[s];
                let mm: f64 = masters.iter().map(|&(n, c)| c * self.nodal_mass[n]).sum();
                // The shared (mass-weighted) point: the slave takes the part mm / (ms + mm) of
                // the correction, the master the rest; a rigid master takes none.
                let slave_share = if masters.is_empty() || ms + mm <= 0.0 {
                    1.0
                } else {
                    mm / (ms + mm)
                };
                let correction = -p.normal * p.gap;
                let sum_w2: f64 = masters.iter().map(|&(_, c)| c * c).sum::<f64>().max(1e-300);
                // Moves the slave by its share of `delta` and the master point by the rest,
                // spread over the facet nodes by their weights; prescribed dofs stay.
                let prescribed = &self.prescribed;
                let share = |values: &mut [f64], delta: &SVector<f64, D>| {
                    for k in 0..D {
                        if prescribed[s * D + k].is_none() {
                            values[s * D + k] += slave_share * delta[k];
                        }
                        for &(n, c) in &masters {
                            if prescribed[n * D + k].is_none() {
                                values[n * D + k] -= (1.0 - slave_share) * delta[k] * c / sum_w2;
                            }
                        }
                    }
                };
                share(&mut u1, &correction);
                if method == ContactMethod::ExplicitProjection {
                    // Remove the approaching normal relative velocity, shared the same way.
                    let vs = SVector::<f64, D>::from_column_slice(&v1[s * D..s * D + D]);
                    let vn = p.normal.dot(&(vs - master_velocity));
                    if vn < 0.0 {
                        let dv = -p.normal * vn;
                        share(&mut v1, &dv);
                        if let Master::Obstacle(k) = p.master {
                            // The impulse over the step, as a force.
                            let f = dv * (ms * slave_share / h);
                            for i in 0..D {
                                contact_forces[k][i] += f[i];
                            }
                        }
                    }
                }
            }
            if method == ContactMethod::ExplicitProjection {
                let kinetic_after = 0.5 * assembly::symmetric_dot(&self.matrices.mass, &v1, &v1);
                projection_loss = (kinetic_before - kinetic_after).max(0.0);
            }
        }

        // Reactions, works and dissipation.
        let mut reactions = vec![vec![0.0; D]; self.bodies.len()];
        let mut work = 0.0;
        for i in 0..ndof {
            let du = u1[i] - u0[i];
            let reaction = if self.prescribed[i].is_some() {
                residual[i]
            } else {
                0.0
            };
            work += (f_ext[i] + reaction) * du;
        }
        for (k, f) in contact_forces.iter().enumerate() {
            let v = self.obstacle_velocity(k);
            work += h * (0..D).map(|i| f[i] * v[i]).sum::<f64>();
        }
        for (b, r) in reactions.iter_mut().enumerate() {
            for n in self.body_nodes(BodyId(b)) {
                for k in 0..D {
                    let dof = n * D + k;
                    if self.prescribed[dof].is_some() {
                        r[k] += residual[dof];
                    }
                }
            }
        }

        // Final gaps in the stored configuration.
        let mut max_penetration: f64 = 0.0;
        let mut contacts = Vec::new();
        if let Some(detector) = self.detector.as_mut() {
            let x_end = end_positions(&self.reference, &u1, &v1, &vec![0.0; ndof], 0.0);
            detector.update_candidates(&x0, &x_end, &obstacles_t0, &t1_vectors);
            for p in detector.pairs(&x_end, &obstacles_t1) {
                max_penetration = max_penetration.max(-p.gap);
                let force = terms
                    .pairs
                    .iter()
                    .find(|q| {
                        q.key.0 == p.slave
                            && q.obstacle
                                == match p.master {
                                    Master::Obstacle(k) => Some(k),
                                    _ => None,
                                }
                    })
                    .map_or(0.0, |q| q.normal_force.max(0.0));
                if p.gap < 0.0 || force > 0.0 {
                    contacts.push((p.slave, p.gap, force));
                }
            }
        }
        let active_contacts = terms.pairs.iter().filter(|p| p.normal_force > 0.0).count();

        let previous = self.state.clone();
        let state = &mut self.state;
        state.step = if count_step { step } else { state.step };
        state.time = t0 + h;
        state.displacement = u1;
        state.velocity = v1;
        state.external_work += work;
        state.dissipated_energy += h * terms.dissipation_rate + projection_loss;
        state.obstacle_translations = translations_t1;
        state.contact_energy = terms.energy;
        state.multipliers = multipliers.iter().map(|(&(s, m), &l)| (s, m, l)).collect();
        state.friction_normals = friction_normals
            .iter()
            .map(|(&(s, m), &f)| (s, m, f))
            .collect();
        if method != ContactMethod::AugmentedLagrangian {
            state.multipliers.clear();
        }
        let energies = self.energies();
        let limit = 1e6 * self.energy_reference().max(f64::MIN_POSITIVE);
        let finite = self
            .state
            .displacement
            .iter()
            .chain(&self.state.velocity)
            .all(|x| x.is_finite());
        if !finite || !energies.total().is_finite() || energies.total() > limit {
            let detail = if !finite || !energies.total().is_finite() {
                "a displacement, velocity or energy became non-finite".to_string()
            } else {
                format!(
                    "the total energy {:.3e} J exceeds 1e6 times its reference {:.3e} J \
                     (E(0) + |external work| + dissipated), a growth by {:.2e}",
                    energies.total(),
                    self.energy_reference(),
                    energies.total() / self.energy_reference().max(f64::MIN_POSITIVE)
                )
            };
            self.state = previous;
            return Err(Error::Unstable {
                step,
                time: t0 + h,
                detail,
            });
        }
        let report = StepReport {
            step,
            time: t0 + h,
            time_step: h,
            iterations,
            residual: relative,
            energies,
            max_penetration,
            active_contacts,
            reactions,
            contact_forces,
            contacts,
        };
        recorder.step_end(self, &report);
        Ok(report)
    }

    /// The diagonal of contact stiffness entries on free unknowns.
    fn free_contact_diagonal(&self, entries: &[(usize, usize, f64)]) -> Vec<f64> {
        let mut d = vec![0.0; self.prescribed.len()];
        for &(r, c, v) in entries {
            if r == c && self.prescribed[r].is_none() {
                d[r] += v;
            }
        }
        d
    }

    /// Makes an inexact increment conserve momentum exactly. Between free bodies (no
    /// obstacle, no prescribed component in a direction) the momentum balance is linear in the
    /// velocities, and the internal and contact forces (equal and opposite) drop out of it:
    /// a uniform correction `c` in each direction, `c = h * sum(linear residual) / mass`,
    /// removes the part of the linear solve's residual that would change the total momentum.
    /// Conjugate gradients stop at a fraction of the Newton tolerance; this keeps the head-on
    /// impact of two bodies momentum-conserving to round-off all the same.
    fn conserve_momentum(&self, x: &mut [f64], residual: &[f64], h: f64) {
        if !self.obstacles.is_empty() {
            return;
        }
        let mass: f64 = self.nodal_mass.iter().sum();
        if !(mass > 0.0) {
            return;
        }
        for d in 0..D {
            // Axisymmetric: a radial translation is no rigid motion (it strains the hoop).
            let axisymmetric_radius =
                d == 0 && self.settings.kinematics == crate::dim::Kinematics::Axisymmetric;
            if axisymmetric_radius
                || (d..x.len())
                    .step_by(D)
                    .any(|i| self.prescribed[i].is_some())
            {
                continue;
            }
            let imbalance: f64 = (d..x.len()).step_by(D).map(|i| residual[i]).sum();
            let c = h * imbalance / mass;
            for i in (d..x.len()).step_by(D) {
                x[i] += c;
            }
        }
    }

    /// `x -> (A0 + K) x` for contact stiffness entries `entries` (lower triangle, free
    /// unknowns only).
    fn contact_operator<'a>(
        &'a self,
        entries: &'a [(usize, usize, f64)],
    ) -> impl Fn(&[f64]) -> Vec<f64> + 'a {
        let system = self.system.as_ref().expect("ensure_system ran");
        move |x: &[f64]| -> Vec<f64> {
            let mut y = vec![0.0; x.len()];
            assembly::symmetric_mul_add(&system.matrix, x, 1.0, &mut y);
            for &(r, c, v) in entries {
                y[r] += v * x[c];
                if r != c {
                    y[c] += v * x[r];
                }
            }
            y
        }
    }

    /// The contact entries on free unknowns.
    fn free_entries(&self, entries: &[(usize, usize, f64)]) -> Vec<(usize, usize, f64)> {
        entries
            .iter()
            .copied()
            .filter(|&(r, c, _)| self.prescribed[r].is_none() && self.prescribed[c].is_none())
            .collect()
    }

    /// Keeps a new contact factorisation (of `A0 + entries`) as the newest preconditioner.
    fn keep_contact_factor(
        &mut self,
        cholesky: SparseCholesky,
        entries: &[(usize, usize, f64)],
        h: f64,
    ) {
        let diagonal = self.free_contact_diagonal(entries);
        self.contact_solvers.insert(
            0,
            ContactFactor {
                time_step: h,
                cholesky,
                diagonal,
            },
        );
    }

    /// Factors `A0 + K_c` (kept as the preconditioner of the following iterations) and solves
    /// with it. The consistent tangent first; where its geometric part makes the matrix
    /// indefinite (large pressure on a soft body), Newton goes on without it. Each matrix is
    /// factored in single precision first and the solve refined by conjugate gradients in
    /// double precision (a few iterations); where that does not converge (an ill-conditioned
    /// matrix), in double precision, solved directly.
    fn factor_contact(
        &mut self,
        terms: &ContactTerms<D>,
        b: &[f64],
        target: f64,
        h: f64,
        step: usize,
    ) -> Result<Vec<f64>> {
        let mut candidates = Vec::new();
        if !terms.geometric.is_empty() {
            let mut with_geometry = terms.entries.clone();
            with_geometry.extend_from_slice(&terms.geometric);
            candidates.push(self.free_entries(&with_geometry));
        }
        candidates.push(self.free_entries(&terms.entries));
        // The new factorisation takes the place (and the symbolic analysis) of the oldest.
        let recycled = if self.contact_solvers.len() >= CONTACT_FACTORS_KEPT {
            self.contact_solvers.pop()
        } else {
            None
        };
        let mut cholesky = match recycled {
            Some(f) => f.cholesky,
            None => SparseCholesky::analyse_with(
                &self.contact_matrix(&candidates[0])?,
                self.settings.ordering,
                D,
            )?,
        };
        let mut failure = None;
        for entries in &candidates {
            let matrix = self.contact_matrix(entries)?;
            if self.single_precision_contact && cholesky.factor_any_single(&matrix, step).is_ok() {
                let refined = conjugate_gradients(
                    &self.contact_operator(entries),
                    &|r| cholesky.solve_in_place(r),
                    b,
                    target,
                    SINGLE_PRECISION_REFINEMENT,
                );
                if let Some((mut x, residual)) = refined {
                    self.conserve_momentum(&mut x, &residual, h);
                    self.keep_contact_factor(cholesky, entries, h);
                    return Ok(x);
                }
                // Too ill-conditioned for single precision: stay in double from now on.
                self.single_precision_contact = false;
            }
            match cholesky.factor_any(&matrix, step) {
                Ok(()) => {
                    let mut x = b.to_vec();
                    cholesky.solve_in_place(&mut x);
                    self.keep_contact_factor(cholesky, entries, h);
                    return Ok(x);
                }
                Err(e) => failure = Some(e),
            }
        }
        Err(failure.expect("at least one candidate matrix"))
    }

    /// Solves `(A0 + K_c) x = b` to a residual norm of `target` by conjugate gradients
    /// preconditioned with the nearest factored matrix: one of the last contact factorisations
    /// or the contact-free `A0`, whichever differs from `A0 + K_c` in fewer unknowns by more
    /// than half their diagonal. Such a difference is of low rank, and CG resolves it in about one
    /// iteration per unknown; the small drift of the other entries (contact areas) costs one
    /// or two more. `None` when the tangent has a geometric part, the difference is not of low
    /// rank, or CG does not converge in time: the caller then factors `A0 + K_c`.
    fn preconditioned_solve(
        &self,
        terms: &ContactTerms<D>,
        b: &[f64],
        target: f64,
    ) -> Option<Vec<f64>> {
        let system = self.system.as_ref()?;
        if !terms.geometric.is_empty() {
            return None;
        }
        let entries = self.free_entries(&terms.entries);
        let now = self.free_contact_diagonal(&entries);
        // The nearest factorisation; ties go to the most recent contact one.
        let mut nearest: Option<&ContactFactor> = None;
        let mut changes = strong_changes(&system.diagonal, None, &now);
        for f in self.contact_solvers.iter().rev() {
            if f.time_step != system.time_step {
                continue;
            }
            let c = strong_changes(&system.diagonal, Some(&f.diagonal), &now);
            if c <= changes {
                changes = c;
                nearest = Some(f);
            }
        }
        if changes > PCG_LOW_RANK {
            return None;
        }
        let apply = self.contact_operator(&entries);
        let preconditioner = nearest.map_or(&system.cholesky, |f| &f.cholesky);
        let (mut x, residual) = conjugate_gradients(
            &apply,
            &|r| preconditioner.solve_in_place(r),
            b,
            target,
            changes + PCG_SLACK,
        )?;
        self.conserve_momentum(&mut x, &residual, system.time_step);
        Some(x)
    }

    fn records(
        &self,
        terms: &ContactTerms<D>,
        x_gap: &[SVector<f64, D>],
        active: &BTreeSet<(usize, MasterId)>,
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
                active: p.normal_force > 0.0 || active.contains(&p.key),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::{ContactSettings, ObstacleShape};
    use crate::material::{LinearElastic, Material};
    use crate::mesh::generators::rectangle;
    use crate::simulation::{Body, Simulation2};
    use nalgebra::Vector2;

    /// The contact forces and the assembled tangent at end velocities `v1`.
    fn forces_and_tangent(
        sim: &mut Simulation2,
        v1: &[f64],
        h: f64,
        friction_normals: &BTreeMap<(usize, MasterId), f64>,
    ) -> (Vec<f64>, nalgebra::DMatrix<f64>) {
        sim.ensure_system(h).unwrap();
        let n = v1.len();
        let u0 = sim.state.displacement.clone();
        let v0 = sim.state.velocity.clone();
        let x0 = end_positions(&sim.reference, &u0, &v0, &vec![0.0; n], 0.0);
        let x_gap = end_positions(&sim.reference, &u0, &v0, v1, h);
        let obstacles = sim.obstacles.clone();
        let t1: Vec<Vector2<f64>> = obstacles.iter().map(|o| o.translation).collect();
        let areas = sim.tributary_areas(&x0);
        let det = sim.detector.as_mut().unwrap();
        det.update_candidates(&x0, &x_gap, &obstacles, &t1);
        let pairs = det.pairs(&x_gap, &obstacles);
        let diagonal = vec![1.0; n];
        let terms = sim.contact_terms(
            &pairs,
            &obstacles,
            &x_gap,
            &v0,
            v1,
            h,
            &areas,
            &BTreeMap::new(),
            friction_normals,
            &BTreeSet::new(),
            &diagonal,
        );
        let mut k = nalgebra::DMatrix::zeros(n, n);
        for &(r, c, v) in terms.entries.iter().chain(&terms.geometric) {
            k[(r, c)] += v;
            if r != c {
                k[(c, r)] += v;
            }
        }
        (terms.forces, k)
    }

    fn check(mut sim: Simulation2, friction: bool, tolerance: f64) {
        let h = 1e-3;
        let n = sim.state.velocity.len();
        // A velocity field that keeps every contact strictly open or strictly closed.
        let v1: Vec<f64> = (0..n).map(|i| 0.01 * ((i as f64) * 0.7).sin()).collect();
        let mut normals = BTreeMap::new();
        if friction {
            // Freeze the thresholds at the current normal forces (the fixed point's inner problem).
            let (_, _) = forces_and_tangent(&mut sim, &v1, h, &normals);
            let det = sim.detector.as_ref().unwrap();
            let _ = det;
            for s in 0..sim.node_count() {
                normals.insert((s, MasterId::Obstacle(0)), 10.0);
            }
        }
        let (_, k) = forces_and_tangent(&mut sim, &v1, h, &normals);
        assert!(k.amax() > 0.0, "no contact in the test configuration");
        let eps = 1e-7;
        let mut worst: f64 = 0.0;
        for j in 0..n {
            let (mut vp, mut vm) = (v1.clone(), v1.clone());
            vp[j] += eps;
            vm[j] -= eps;
            let (fp, _) = forces_and_tangent(&mut sim, &vp, h, &normals);
            let (fm, _) = forces_and_tangent(&mut sim, &vm, h, &normals);
            for i in 0..n {
                // The tangent is d(-f)/dv1.
                let fd = -(fp[i] - fm[i]) / (2.0 * eps);
                worst = worst.max((fd - k[(i, j)]).abs());
            }
        }
        assert!(
            worst <= tolerance * k.amax(),
            "tangent error {worst:e} of {:e}",
            k.amax()
        );
    }

    fn block_on(obstacle: Obstacle<2>, friction: FrictionLaw, penetration: f64) -> Simulation2 {
        let mesh = rectangle(
            Vector2::new(-0.5, 0.0),
            Vector2::new(0.5, 0.2),
            [4, 2],
            crate::element::ElementKind::Quad4,
        )
        .unwrap();
        let mut sim = Simulation2::builder()
            .body(Body::new(
                "b",
                mesh,
                Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap()),
            ))
            .obstacle(obstacle)
            .contact(ContactSettings {
                method: ContactMethod::SoftWay,
                penalty: 1e8,
                friction,
                ..ContactSettings::default()
            })
            .build()
            .unwrap();
        // Push the body into the obstacle.
        for i in 0..sim.node_count() {
            sim.state.displacement[2 * i + 1] = -penetration;
        }
        sim
    }

    #[test]
    fn soft_way_tangent_against_a_halfspace_matches_finite_differences() {
        let plane = Obstacle::new(
            "p",
            ObstacleShape::Halfspace {
                point: Vector2::zeros(),
                normal: Vector2::new(0.1, 1.0),
            },
        );
        check(
            block_on(plane, FrictionLaw::Frictionless, 1e-3),
            false,
            1e-6,
        );
    }

    #[test]
    fn soft_way_tangent_against_a_ball_matches_finite_differences() {
        // The curvature term zeta (-g) (I - n n) / R matters here.
        let ball = Obstacle::new(
            "ball",
            ObstacleShape::Ball {
                center: Vector2::new(0.05, -0.5),
                radius: 0.5,
            },
        );
        // The curvature term is about 1.5 % of the tangent here (|g| / R); what remains is the
        // variation of the projected contact area with the normal, not in the tangent.
        check(block_on(ball, FrictionLaw::Frictionless, 1e-2), false, 3e-3);
    }

    #[test]
    fn coulomb_friction_tangent_matches_finite_differences() {
        let plane = Obstacle::new(
            "p",
            ObstacleShape::Halfspace {
                point: Vector2::zeros(),
                normal: Vector2::new(0.0, 1.0),
            },
        );
        let law = FrictionLaw::Coulomb {
            coefficient: 0.4,
            regularization: 1e-3,
        };
        check(block_on(plane, law, 1e-3), true, 1e-6);
    }

    #[test]
    fn soft_way_tangent_between_two_bodies_matches_finite_differences() {
        // The facet terms (normal and closest-point variations) of a deformable master.
        let lower = rectangle(
            Vector2::new(-0.5, -0.2),
            Vector2::new(0.5, 0.0),
            [3, 1],
            crate::element::ElementKind::Quad4,
        )
        .unwrap();
        let mut upper = rectangle(
            Vector2::new(-0.3, 0.0),
            Vector2::new(0.3, 0.2),
            [2, 1],
            crate::element::ElementKind::Quad4,
        )
        .unwrap();
        upper.translate(&Vector2::new(0.01, -1e-3));
        let mat = Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap());
        let sim = Simulation2::builder()
            .body(Body::new("upper", upper, mat))
            .body(Body::new("lower", lower, mat))
            .contact(ContactSettings {
                method: ContactMethod::SoftWay,
                penalty: 1e8,
                ..ContactSettings::default()
            })
            .build()
            .unwrap();
        // The projected contact area follows the master's normal; that variation is not in
        // the tangent (a relative error of ~6e-4 here), everything else is.
        check(sim, false, 1e-3);
    }

    /// A block dropped at 1 m/s onto a plane 0.1 mm under it, `steps` steps of 1 ms; the
    /// velocities at the end.
    fn dropped_block(
        penalty: f64,
        single_precision: bool,
        steps: usize,
    ) -> (Simulation2, Vec<f64>) {
        let mesh = rectangle(
            Vector2::new(-0.5, 1e-4),
            Vector2::new(0.5, 0.2001),
            // 25 bottom nodes: more than CG takes on without a contact factorisation.
            [24, 4],
            crate::element::ElementKind::Quad4,
        )
        .unwrap();
        let plane = Obstacle::new(
            "ground",
            ObstacleShape::Halfspace {
                point: Vector2::zeros(),
                normal: Vector2::new(0.0, 1.0),
            },
        );
        let mut sim = Simulation2::builder()
            .gravity(Vector2::new(0.0, -9.81))
            .body(
                Body::new(
                    "b",
                    mesh,
                    Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap()),
                )
                .with_velocity(Vector2::new(0.0, -1.0)),
            )
            .obstacle(plane)
            .contact(ContactSettings {
                method: ContactMethod::SoftWay,
                penalty,
                ..ContactSettings::default()
            })
            .build()
            .unwrap();
        sim.single_precision_contact = single_precision;
        for _ in 0..steps {
            sim.step().unwrap();
        }
        let v = sim.state.velocity.clone();
        (sim, v)
    }

    #[test]
    fn single_precision_contact_factors_give_the_double_precision_answer() {
        let (single, v_single) = dropped_block(1e8, true, 4);
        assert!(single.single_precision_contact, "refinement converged");
        assert!(single
            .contact_solvers
            .iter()
            .all(|f| f.cholesky.is_single_precision()));
        let (double, v_double) = dropped_block(1e8, false, 4);
        assert!(double
            .contact_solvers
            .iter()
            .all(|f| !f.cholesky.is_single_precision()));
        assert!(
            !single.contact_solvers.is_empty(),
            "a contact matrix was factored"
        );
        let scale = v_double.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let diff = v_single
            .iter()
            .zip(&v_double)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        // Both are Newton solutions to the same tolerance (1e-8 of the force scale).
        assert!(diff < 1e-6 * scale, "{diff} vs {scale}");
    }
}
