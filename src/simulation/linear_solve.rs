//! The linear solves of Newton: the factored contact-free iteration matrix `A0 = M/h +
//! (alpha^2 h / 2) K` (once per step size), and with contact `A0 + K_c` solved by conjugate
//! gradients preconditioned with the nearest factored matrix, or factored anew.
//!
//! The policy: CG stops at a tenth of the Newton tolerance; it is preconditioned by `A0` or by
//! one of the last [`CONTACT_FACTORS_KEPT`] contact factorisations, whichever differs from
//! `A0 + K_c` in the fewest unknowns by more than half their diagonal (points entering or
//! leaving contact: a low-rank difference CG resolves in about one iteration each). More than
//! [`PCG_LOW_RANK`] such unknowns, or CG out of iterations, and the contact matrix is factored
//! (single precision refined by CG; double precision when that fails, then for good). Which
//! factorisations exist is part of the state ([`ContactMemory`](super::ContactMemory)): they
//! change the round-off of a step, so a restored or resumed simulation uses the same ones.
//! With non-symmetric rank-one terms in the tangent (implicit projection's held normals that
//! turn), the whole operator is solved by flexible GMRES on the same preconditioners
//! ([`coupled_solve`](Simulation::coupled_solve)).

use faer::sparse::{SparseColMat, Triplet};

use super::contact_terms::RankOne;
use super::state::FactorRecord;
use super::Simulation;
use crate::assembly;
use crate::dim::{Dim, Kinematics, SpatialDim};
use crate::error::{Error, Result};
use crate::solver::krylov::{conjugate_gradients, flexible_gmres};
use crate::solver::SparseCholesky;

/// Conjugate-gradient iterations allowed on top of the number of strongly changed unknowns
/// (see [`strong_changes`]) before the contact matrix is factored anew.
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
pub(super) const CONTACT_FACTORS_KEPT: usize = 2;

/// Symbolic analyses of contact patterns kept for reuse besides the kept factorisations'
/// (the stack of two soft cubes: 149 of 338 factorisations found theirs among the last four,
/// 159 among the last eight).
const ANALYSES_KEPT: usize = 4;

/// Conjugate-gradient iterations allowed to refine a solve with a fresh single-precision
/// factorisation before it is redone in double precision.
const SINGLE_PRECISION_REFINEMENT: usize = 10;

/// The memory the linear solves hold (bytes), from [`Simulation::solver_memory`]: what a
/// host budgets for, and what the performance chapter compares with the process's peak.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SolverMemory {
    /// The values of the contact-free iteration matrix's factor (double precision), the
    /// largest single item of a 3D problem.
    pub factor: usize,
    /// The values of the kept contact factorisations (single precision where they are).
    pub contact_factors: usize,
    /// Values and indices of the stored sparse matrices: stiffness, mass, damping and the
    /// contact-free iteration matrix.
    pub matrices: usize,
}

impl SolverMemory {
    /// The sum of the three (bytes).
    pub fn total(&self) -> usize {
        self.factor + self.contact_factors + self.matrices
    }
}

/// Bytes of a compressed-column matrix: its values, row indices and column pointers.
fn matrix_bytes(matrix: &SparseColMat<usize, f64>) -> usize {
    let entries = matrix.val().len();
    entries * (std::mem::size_of::<f64>() + std::mem::size_of::<usize>())
        + (matrix.ncols() + 1) * std::mem::size_of::<usize>()
}

/// The factored contact-free iteration matrix for one step size.
pub(super) struct IterationSystem {
    pub(super) time_step: f64,
    pub(super) matrix: SparseColMat<usize, f64>,
    pub(super) diagonal: Vec<f64>,
    pub(super) cholesky: SparseCholesky,
}

/// The factorisation of a contact iteration matrix `A0 + K_c` named by a [`FactorRecord`].
pub(super) struct ContactFactor {
    id: u64,
    cholesky: SparseCholesky,
    /// The diagonal of the factored `K_c` (free unknowns), per unknown.
    diagonal: Vec<f64>,
}

impl ContactFactor {
    #[cfg(test)]
    pub(super) fn is_single_precision(&self) -> bool {
        self.cholesky.is_single_precision()
    }

    #[cfg(test)]
    pub(super) fn id(&self) -> u64 {
        self.id
    }
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

/// A solve with the symmetric part of the iteration matrix: right-hand side and residual target
/// in, solution out.
type SymmetricSolve<'a> = dyn FnMut(&[f64], f64) -> Result<Vec<f64>> + 'a;

/// Solves `(S + sum u v^T) x = b`, `S` the symmetric part of the iteration matrix (solved by
/// `solve`, to a residual target) and `u v^T` the non-symmetric rank-one terms of the tangent
/// (Coulomb slip's threshold coupled to the gap; a held normal velocity whose normal turns), by
/// the Sherman-Morrison-Woodbury formula: `x = x0 - Z (I + V^T Z)^-1 V^T x0`, `x0 = S^-1 b`,
/// `Z = S^-1 U`. The Cholesky factorisations only ever see `S`. Prescribed unknowns take no
/// part. A singular capacitance matrix leaves `x0` (Newton goes on without the coupling).
/// The fallback of the linear path's flexible GMRES (`coupled_solve`), and the general
/// path's solve (whose factorisation is exact: one triangular solve per term).
pub(super) fn woodbury(
    solve: &mut SymmetricSolve<'_>,
    coupling: &[RankOne],
    prescribed: &[Option<f64>],
    b: &[f64],
    target: f64,
) -> Result<Vec<f64>> {
    let ndof = b.len();
    let mut x = solve(b, target)?;
    let m = coupling.len();
    if m == 0 {
        return Ok(x);
    }
    let mut z = Vec::with_capacity(m);
    for (u, _) in coupling {
        let mut rhs = vec![0.0; ndof];
        for &(i, a) in u {
            if prescribed[i].is_none() {
                rhs[i] += a;
            }
        }
        let norm = rhs.iter().map(|r| r * r).sum::<f64>().sqrt();
        z.push(solve(&rhs, 1e-10 * norm)?);
    }
    let mut g = nalgebra::DMatrix::<f64>::identity(m, m);
    let mut r = nalgebra::DVector::<f64>::zeros(m);
    for (k, (_, v)) in coupling.iter().enumerate() {
        for &(i, c) in v {
            if prescribed[i].is_none() {
                r[k] += c * x[i];
                for (l, zl) in z.iter().enumerate() {
                    g[(k, l)] += c * zl[i];
                }
            }
        }
    }
    if let Some(y) = g.lu().solve(&r) {
        for (l, zl) in z.iter().enumerate() {
            for i in 0..ndof {
                x[i] -= zl[i] * y[l];
            }
        }
    }
    Ok(x)
}

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// The memory the linear solves hold now (bytes): factor values and stored matrices.
    /// Nothing is factored before the first step.
    pub fn solver_memory(&self) -> SolverMemory {
        let system = self.caches.system.as_ref();
        SolverMemory {
            factor: system.map_or(0, |s| s.cholesky.value_bytes()),
            contact_factors: self
                .caches
                .contact_factors
                .iter()
                .map(|f| f.cholesky.value_bytes())
                .sum(),
            matrices: matrix_bytes(&self.matrices.stiffness)
                + matrix_bytes(&self.matrices.mass)
                + self.damping.as_ref().map_or(0, matrix_bytes)
                + system.map_or(0, |s| matrix_bytes(&s.matrix)),
        }
    }

    /// Factors the contact-free iteration matrix for step size `h` unless it already is.
    pub(super) fn ensure_system(&mut self, h: f64) -> Result<()> {
        if self
            .caches
            .system
            .as_ref()
            .is_some_and(|s| s.time_step == h)
        {
            return Ok(());
        }
        let (_, d1) = self.model.settings.scheme.displacement_weights();
        let matrix = self.iteration_matrix(h, d1);
        let mut cholesky = match self.caches.system.take() {
            Some(s) => s.cholesky,
            None => SparseCholesky::analyse_with(&matrix, self.model.settings.ordering, D)?,
        };
        // The general path factors its own matrix every iteration and needs only this one's
        // analysis: a flow law at rest with no mass (rho = 0) has nothing to factor here.
        let factored = self.counted(|| cholesky.factor(&matrix, self.state.step + 1));
        if !self.general_path {
            factored?;
        }
        let diagonal = diagonal_of(&matrix);
        self.caches.system = Some(IterationSystem {
            time_step: h,
            matrix,
            diagonal,
            cholesky,
        });
        Ok(())
    }

    /// `M/h + alpha C + (alpha^2 h / 2) K` with prescribed rows and columns replaced by the
    /// identity (scaled to the mean diagonal, for conditioning).
    fn iteration_matrix(&self, h: f64, d1: f64) -> SparseColMat<usize, f64> {
        let alpha = self.model.settings.scheme.alpha;
        self.combined_matrix(1.0 / h, alpha, d1 * h)
    }

    /// `m M + c C + k K` with prescribed rows and columns replaced by the identity (scaled to
    /// the mean diagonal, for conditioning).
    fn combined_matrix(&self, m: f64, c: f64, k: f64) -> SparseColMat<usize, f64> {
        let mut a = self.matrices.mass.clone();
        let (m_vals, k_vals) = (self.matrices.mass.val(), self.matrices.stiffness.val());
        let col_ptr = a.symbolic().col_ptr().to_vec();
        let row_idx = a.symbolic().row_idx().to_vec();
        let vals = a.val_mut();
        for i in 0..vals.len() {
            vals[i] = m * m_vals[i] + k * k_vals[i];
            if let Some(damping) = &self.damping {
                vals[i] += c * damping.val()[i];
            }
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

    /// Runs a numeric factorisation, counted for the step's report
    /// ([`StepReport::factorisations`](super::StepReport::factorisations)).
    fn counted<T>(&self, factor: impl FnOnce() -> T) -> T {
        self.step_factorisations
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        factor()
    }

    fn system(&self) -> &IterationSystem {
        self.caches.system.as_ref().expect("ensure_system ran")
    }

    /// The diagonal of the contact-free iteration matrix.
    pub(super) fn system_diagonal(&self) -> &[f64] {
        &self.system().diagonal
    }

    /// Solves with the contact-free iteration matrix in place.
    pub(super) fn solve_contact_free(&self, x: &mut [f64]) {
        self.system().cholesky.solve_in_place(x);
    }

    /// Solves `(M + k K) x = rhs` in place on the free unknowns (prescribed ones keep their
    /// right-hand side divided by the identity's scale: pass them zero). It factors with the
    /// cached system's symbolic analysis (the same pattern), and drops that system's numeric
    /// factor: the next [`Self::ensure_system`] refactors.
    pub(super) fn solve_mass_plus_stiffness(&mut self, k: f64, rhs: &mut [f64]) -> Result<()> {
        let matrix = self.combined_matrix(1.0, 0.0, k);
        let mut cholesky = match self.caches.system.take() {
            Some(s) => s.cholesky,
            None => SparseCholesky::analyse_with(&matrix, self.model.settings.ordering, D)?,
        };
        let factored = self.counted(|| cholesky.factor(&matrix, self.state.step + 1));
        if factored.is_ok() {
            cholesky.solve_in_place(rhs);
        }
        // Kept for its analysis only: a step size no step takes, so that the next
        // `ensure_system` refactors.
        self.caches.system = Some(IterationSystem {
            time_step: f64::NAN,
            diagonal: diagonal_of(&matrix),
            matrix,
            cholesky,
        });
        factored
    }

    /// The iteration matrix with the contact entries added; re-analysed when the contact adds
    /// couplings that are not in the contact-free pattern.
    fn contact_matrix(
        &self,
        base: &SparseColMat<usize, f64>,
        entries: &[(usize, usize, f64)],
    ) -> Result<SparseColMat<usize, f64>> {
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
        if !self.model.obstacles.is_empty() {
            return;
        }
        let mass: f64 = self.nodal_mass.iter().sum();
        if !(mass > 0.0) {
            return;
        }
        for d in 0..D {
            // Axisymmetric: a radial translation is no rigid motion (it strains the hoop).
            let axisymmetric_radius =
                d == 0 && self.model.settings.kinematics == Kinematics::Axisymmetric;
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
        let system = self.system();
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

    /// Factors `M/h + alpha C + K_t + K_c`, `K_t` the element kernel's tangent values (the path
    /// of laws that are not linear: the matrix changes every iteration, so it is factored every
    /// iteration, with the symbolic analysis of the contact-free matrix).
    pub(super) fn factor_with_tangent(
        &self,
        tangent_values: &[f64],
        entries: &[(usize, usize, f64)],
        h: f64,
        step: usize,
    ) -> Result<SparseCholesky> {
        let mut base = self.pattern.matrix(tangent_values);
        let (col_ptr, row_idx) = (
            base.symbolic().col_ptr().to_vec(),
            base.symbolic().row_idx().to_vec(),
        );
        let mass = self.matrices.mass.val();
        let alpha = self.model.settings.scheme.alpha;
        let vals = base.val_mut();
        for j in 0..col_ptr.len() - 1 {
            for k in col_ptr[j]..col_ptr[j + 1] {
                vals[k] += mass[k] / h;
                if let Some(c) = &self.damping {
                    vals[k] += alpha * c.val()[k];
                }
            }
        }
        // Prescribed rows and columns: the identity scaled to this matrix's mean diagonal.
        let (mut sum, mut count) = (0.0, 0usize);
        for j in 0..col_ptr.len() - 1 {
            for k in col_ptr[j]..col_ptr[j + 1] {
                if row_idx[k] == j && self.prescribed[j].is_none() {
                    sum += vals[k];
                    count += 1;
                }
            }
        }
        let scale = if count > 0 && sum > 0.0 {
            sum / count as f64
        } else {
            1.0
        };
        for j in 0..col_ptr.len() - 1 {
            for k in col_ptr[j]..col_ptr[j + 1] {
                let i = row_idx[k];
                if self.prescribed[i].is_some() || self.prescribed[j].is_some() {
                    vals[k] = if i == j { scale } else { 0.0 };
                }
            }
        }
        let matrix = self.contact_matrix(&base, &self.free_entries(entries))?;
        let mut cholesky = self.system().cholesky.unfactored_copy();
        self.counted(|| cholesky.factor_any(&matrix, step))?;
        Ok(cholesky)
    }

    /// The floating-point noise of the residual's internal and inertial forces (N): the end
    /// velocity is only known to a unit in its last place, so its forces are not known
    /// better than `eps |M/h + K_t| |v1|` (2-norm over free unknowns). Newton cannot go below
    /// it. It matters for a stiff tangent on a fast body: Norton-Hoff at small m is very
    /// viscous where the strain rate nears its regularisation, in a part that moves rigidly.
    pub(super) fn tangent_round_off(&self, tangent_values: &[f64], v1: &[f64], h: f64) -> f64 {
        if tangent_values.len() != self.pattern.triplets {
            return 0.0;
        }
        let matrix = self.pattern.matrix(tangent_values);
        let (col_ptr, row_idx, vals) = (
            matrix.symbolic().col_ptr(),
            matrix.symbolic().row_idx(),
            matrix.val(),
        );
        let mass = self.matrices.mass.val();
        let mut noise = vec![0.0; v1.len()];
        for j in 0..col_ptr.len() - 1 {
            for k in col_ptr[j]..col_ptr[j + 1] {
                // The lower triangle: each off-diagonal entry stands for two.
                let i = row_idx[k];
                let a = (vals[k] + mass[k] / h).abs();
                noise[i] += a * v1[j].abs();
                if i != j {
                    noise[j] += a * v1[i].abs();
                }
            }
        }
        let free2: f64 = noise
            .iter()
            .zip(&self.prescribed)
            .filter(|(_, p)| p.is_none())
            .map(|(n, _)| n * n)
            .sum();
        f64::EPSILON * free2.sqrt()
    }

    /// A symbolic analysis to factor `matrix` with: shared with a kept factorisation or one
    /// of the last [`ANALYSES_KEPT`] analyses when the pattern is the same, made anew
    /// otherwise. Contact between bodies adds couplings that come and go with the pairs; the
    /// same patterns recur (a stack of two soft cubes: 338 contact factorisations, 281
    /// analyses when only the newest factorisation's pattern was tried, METIS a fifth of the
    /// run). An analysis depends on the pattern alone: the same bits either way.
    fn analysis_for(&mut self, matrix: &SparseColMat<usize, f64>) -> Result<SparseCholesky> {
        let (ordering, block) = (self.model.settings.ordering, D);
        let known = |c: &&SparseCholesky| c.is_analysis_of(matrix, ordering, block);
        if let Some(c) = self
            .caches
            .contact_factors
            .iter()
            .map(|f| &f.cholesky)
            .chain(self.caches.system.as_ref().map(|s| &s.cholesky))
            .find(known)
        {
            return Ok(c.unfactored_copy());
        }
        let analyses = &mut self.caches.analyses;
        if let Some(at) = analyses.iter().position(|c| known(&c)) {
            let recent = analyses.remove(at);
            let copy = recent.unfactored_copy();
            analyses.push(recent);
            return Ok(copy);
        }
        let cholesky = SparseCholesky::analyse_with(matrix, ordering, block)?;
        if analyses.len() >= ANALYSES_KEPT {
            analyses.remove(0);
        }
        analyses.push(cholesky.unfactored_copy());
        Ok(cholesky)
    }

    /// Rebuilds the cached factorisations that the state names and the cache lacks (after a
    /// restore or a rebuild from a model and a state), and drops those it no longer names.
    pub(super) fn sync_contact_factors(&mut self) -> Result<()> {
        let records = self.state.contact_memory.factors.clone();
        self.caches
            .contact_factors
            .retain(|f| records.iter().any(|r| r.id == f.id));
        for record in &records {
            if self
                .caches
                .contact_factors
                .iter()
                .any(|f| f.id == record.id)
            {
                continue;
            }
            self.ensure_system(record.time_step)?;
            let matrix = self.contact_matrix(&self.system().matrix, &record.entries)?;
            let mut cholesky = self.analysis_for(&matrix)?;
            let step = self.state.step + 1;
            if record.single_precision {
                self.counted(|| cholesky.factor_single(&matrix, step))?;
            } else {
                self.counted(|| cholesky.factor(&matrix, step))?;
            }
            let diagonal = self.free_contact_diagonal(&record.entries);
            self.caches.contact_factors.push(ContactFactor {
                id: record.id,
                cholesky,
                diagonal,
            });
        }
        Ok(())
    }

    /// Keeps a new contact factorisation (of `A0 + entries`) as the newest preconditioner; the
    /// oldest beyond [`CONTACT_FACTORS_KEPT`] is forgotten by the state, and by the cache at
    /// once. (The cache kept them until the next step: a step that factored twice held four,
    /// 1070 MiB of a 2076 MiB peak on a 73k-unknown cube; the performance chapter, Memory.) A
    /// failed step restores a state that may name a dropped one: the next attempt's
    /// [`Self::sync_contact_factors`] factors it again, the same bits.
    fn keep_contact_factor(
        &mut self,
        cholesky: SparseCholesky,
        entries: &[(usize, usize, f64)],
        h: f64,
    ) {
        let memory = &mut self.state.contact_memory;
        let id = memory.next_factor;
        memory.next_factor += 1;
        let single_precision = cholesky.is_single_precision();
        memory.factors.insert(
            0,
            FactorRecord {
                id,
                time_step: h,
                entries: entries.to_vec(),
                single_precision,
            },
        );
        memory.factors.truncate(CONTACT_FACTORS_KEPT);
        let diagonal = self.free_contact_diagonal(entries);
        let named = &self.state.contact_memory.factors;
        self.caches
            .contact_factors
            .retain(|f| named.iter().any(|r| r.id == f.id));
        self.caches.contact_factors.insert(
            0,
            ContactFactor {
                id,
                cholesky,
                diagonal,
            },
        );
    }

    /// Factors `A0 + K_c` (kept as the preconditioner of the following iterations) and solves
    /// with it. The consistent tangent first (`entries` plus `geometric`); where its geometric
    /// part makes the matrix indefinite (large pressure on a soft body), Newton goes on without
    /// it. Each matrix is factored in single precision first and the solve refined by
    /// conjugate gradients in double precision (a few iterations); where that does not
    /// converge (an ill-conditioned matrix), in double precision, solved directly. The solution,
    /// and whether the geometric part was kept (false when it was left out).
    pub(super) fn factor_contact(
        &mut self,
        entries: &[(usize, usize, f64)],
        geometric: &[(usize, usize, f64)],
        b: &[f64],
        target: f64,
        h: f64,
        step: usize,
    ) -> Result<(Vec<f64>, bool)> {
        // The oldest kept factorisation, which the new one replaces, goes before the new one
        // is made rather than after: one contact factor fewer at the peak (267 of 1797 MiB on
        // a 73k-unknown cube; the performance chapter, Memory). The state names it until the
        // new one is kept; should no factorisation succeed, the next attempt's
        // `sync_contact_factors` makes it again, the same bits.
        // Its storage is the new one's (no new allocation to zero and fault in).
        let mut spare = None;
        if self.state.contact_memory.factors.len() >= CONTACT_FACTORS_KEPT {
            if let Some(oldest) = self.state.contact_memory.factors.last().map(|r| r.id) {
                let factors = &mut self.caches.contact_factors;
                if let Some(at) = factors.iter().position(|f| f.id == oldest) {
                    spare = Some(factors.remove(at).cholesky);
                }
            }
        }
        let mut candidates = Vec::new();
        if !geometric.is_empty() {
            let mut with_geometry = entries.to_vec();
            with_geometry.extend_from_slice(geometric);
            candidates.push(self.free_entries(&with_geometry));
        }
        candidates.push(self.free_entries(entries));
        let mut failure = None;
        for (index, entries) in candidates.iter().enumerate() {
            // The first candidate has the geometric part, if there is one.
            let kept = index == 0;
            let matrix = self.contact_matrix(&self.system().matrix, entries)?;
            let mut cholesky = self.analysis_for(&matrix)?;
            if let Some(donor) = spare.take() {
                cholesky.reuse_storage_of(donor);
            }
            if !self.state.contact_memory.double_precision_only
                && self
                    .counted(|| cholesky.factor_single(&matrix, step))
                    .is_ok()
            {
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
                    return Ok((x, kept));
                }
                // Too ill-conditioned for single precision: stay in double from now on.
                self.state.contact_memory.double_precision_only = true;
            }
            match self.counted(|| cholesky.factor(&matrix, step)) {
                Ok(()) => {
                    let mut x = b.to_vec();
                    cholesky.solve_in_place(&mut x);
                    self.keep_contact_factor(cholesky, entries, h);
                    return Ok((x, kept));
                }
                Err(e) => failure = Some(e),
            }
        }
        Err(failure.expect("at least one candidate matrix"))
    }

    /// The factorisation nearest to `A0 + K_c`, `K_c` the contact `entries` on free unknowns
    /// (`A0`'s or a kept contact one; ties go to the most recent contact one), and the number
    /// of unknowns whose contact stiffness differs strongly from it. `None` before the
    /// contact-free matrix is factored.
    fn nearest_factor(&self, entries: &[(usize, usize, f64)]) -> Option<(&SparseCholesky, usize)> {
        let system = self.caches.system.as_ref()?;
        let now = self.free_contact_diagonal(entries);
        let mut nearest: Option<&ContactFactor> = None;
        let mut changes = strong_changes(&system.diagonal, None, &now);
        for record in self.state.contact_memory.factors.iter().rev() {
            if record.time_step != system.time_step {
                continue;
            }
            let Some(f) = self
                .caches
                .contact_factors
                .iter()
                .find(|f| f.id == record.id)
            else {
                continue;
            };
            let c = strong_changes(&system.diagonal, Some(&f.diagonal), &now);
            if c <= changes {
                changes = c;
                nearest = Some(f);
            }
        }
        Some((nearest.map_or(&system.cholesky, |f| &f.cholesky), changes))
    }

    /// A solve with the symmetric contact iteration matrix `A0 + entries + geometric`: the
    /// nearest factorisation with conjugate gradients, or a new factorisation. Where the
    /// geometric part makes the matrix indefinite, the solve is without it and `geometric`
    /// is emptied, so that the iteration's other solves (the coupled terms' columns, one each)
    /// use the same matrix instead of each failing a factorisation with it first.
    pub(super) fn symmetric_solve(
        &mut self,
        entries: &[(usize, usize, f64)],
        geometric: &mut &[(usize, usize, f64)],
        b: &[f64],
        target: f64,
        h: f64,
        step: usize,
    ) -> Result<Vec<f64>> {
        if let Some(x) = self.preconditioned_solve(entries, geometric, b, target) {
            return Ok(x);
        }
        let (x, kept) = self.factor_contact(entries, geometric, b, target, h, step)?;
        if !kept {
            *geometric = &[];
        }
        Ok(x)
    }

    /// Solves `(A0 + K_c + sum u v^T) x = b`, the iteration matrix with the non-symmetric
    /// rank-one terms `coupling` (prescribed unknowns take no part), to a residual norm of
    /// `target` by flexible GMRES preconditioned with the nearest factorisation, factored
    /// first when more than [`PCG_LOW_RANK`] unknowns changed (as
    /// [`factor_contact`](Self::factor_contact), which may leave `geometric` out: then it is
    /// emptied). One Krylov iteration per changed unknown and per rank-one term, where the
    /// Sherman-Morrison-Woodbury formula takes a whole preconditioned solve per term (the 3D
    /// stack of blocks under implicit projection: 30 terms, about 200 preconditioner
    /// solves an iteration). `None` when GMRES does not converge in time.
    pub(super) fn coupled_solve(
        &mut self,
        entries: &[(usize, usize, f64)],
        geometric: &mut &[(usize, usize, f64)],
        coupling: &[RankOne],
        b: &[f64],
        target: f64,
        step: usize,
    ) -> Result<Option<Vec<f64>>> {
        let Some(h) = self.caches.system.as_ref().map(|s| s.time_step) else {
            return Ok(None);
        };
        // The solve with the symmetric part first, as the start: it factors where the
        // nearest factorisation is too far, and decides on the geometric part as a solve
        // without the coupling would.
        let start = self.symmetric_solve(entries, geometric, b, target, h, step)?;
        let mut all = self.free_entries(entries);
        all.extend(self.free_entries(geometric));
        let Some((preconditioner, changes)) = self.nearest_factor(&all) else {
            return Ok(None);
        };
        let free = |i: &usize| self.prescribed[*i].is_none();
        let coupling: Vec<RankOne> = coupling
            .iter()
            .map(|(u, v)| {
                let keep =
                    |t: &Vec<(usize, f64)>| t.iter().filter(|(i, _)| free(i)).copied().collect();
                (keep(u), keep(v))
            })
            .collect();
        let symmetric = self.contact_operator(&all);
        let apply = |x: &[f64]| {
            let mut y = symmetric(x);
            for (u, v) in &coupling {
                let vx: f64 = v.iter().map(|&(i, c)| c * x[i]).sum();
                for &(i, a) in u {
                    y[i] += a * vx;
                }
            }
            y
        };
        let solved = flexible_gmres(
            &apply,
            &|r| preconditioner.solve_in_place(r),
            b,
            start,
            target,
            changes + 2 * coupling.len() + PCG_SLACK,
        );
        Ok(solved.map(|(mut x, residual)| {
            self.conserve_momentum(&mut x, &residual, h);
            x
        }))
    }

    /// Solves `(A0 + K_c) x = b` to a residual norm of `target` by conjugate gradients
    /// preconditioned with the nearest factored matrix (see the module documentation).
    /// `None` when the difference is not of low rank, or CG meets a direction of non-positive
    /// curvature or does not converge in time: the caller then factors `A0 + K_c`.
    pub(super) fn preconditioned_solve(
        &self,
        entries: &[(usize, usize, f64)],
        geometric: &[(usize, usize, f64)],
        b: &[f64],
        target: f64,
    ) -> Option<Vec<f64>> {
        let system = self.caches.system.as_ref()?;
        // The geometric part enters the operator (CG stops on a direction of non-positive
        // curvature, and the caller factors instead).
        let mut entries = self.free_entries(entries);
        entries.extend(self.free_entries(geometric));
        let (preconditioner, changes) = self.nearest_factor(&entries)?;
        if changes > PCG_LOW_RANK {
            return None;
        }
        let apply = self.contact_operator(&entries);
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
}

/// The diagonal of a lower-triangle CSC matrix.
fn diagonal_of(matrix: &SparseColMat<usize, f64>) -> Vec<f64> {
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
    diagonal
}
