//! Global assembly: element kernels scattered into one sparse symmetric matrix.
//!
//! The pattern (lower triangle, column-compressed) is built once from the cell table; every
//! cell contributes a fixed number of values (`m (m + 1) / 2` for `m = nodes * D` distinct
//! dofs), so the value array is cut into disjoint per-cell chunks that rayon fills in parallel;
//! faer's argsort then sums the duplicates. The result is the same with any thread count
//! because each chunk is written by exactly one cell and the summation order is fixed.

use faer::sparse::{Argsort, Pair, SparseColMat, SymbolicSparseColMat};
use nalgebra::SVector;

use crate::dim::{Dim, Kinematics, SpatialDim, Voigt};
use crate::element::{ElementKind, MAX_NODES};
use crate::error::{Error, Result};
use crate::material::{ConstitutiveLaw, Material};
use std::sync::Arc;

mod kernel;
#[cfg(test)]
use kernel::geometric_stiffness;

#[allow(unused_imports)] // for `internals` users; the kernel itself calls it directly
pub use kernel::spatial_gradients;
use kernel::{cell_kernel, CellOutput};

/// Largest number of dofs of one cell.
pub(crate) const MAX_DOFS: usize = MAX_NODES * 3;

/// A run of cells of one kind and one body, stored contiguously.
#[derive(Debug, Clone)]
pub struct CellSegment {
    /// Element type.
    pub kind: ElementKind,
    /// Body index.
    pub body: usize,
    /// Range of cells in the table.
    pub cells: std::ops::Range<usize>,
    /// First value slot of the segment in the value arrays.
    pub first_value: usize,
}

/// All cells of all bodies, with global node numbers.
#[derive(Debug, Clone, Default)]
pub struct CellTable {
    /// Global node ids, flat; cell `c` of segment `s` starts at `node_start[c]`.
    pub nodes: Vec<usize>,
    /// Start of each cell in `nodes`.
    pub node_start: Vec<usize>,
    /// Segments of uniform kind and body.
    pub segments: Vec<CellSegment>,
}

impl CellTable {
    /// Adds a block of cells of one body; `connectivity` holds local node ids, shifted by
    /// `node_offset` to global ones.
    pub fn push_block(
        &mut self,
        body: usize,
        kind: ElementKind,
        connectivity: &[usize],
        node_offset: usize,
    ) {
        let n = kind.nodes();
        let first_cell = self.node_start.len();
        let first_value = self.value_count();
        for cell in connectivity.chunks_exact(n) {
            self.node_start.push(self.nodes.len());
            self.nodes.extend(cell.iter().map(|&i| i + node_offset));
        }
        let cells = first_cell..self.node_start.len();
        self.segments.push(CellSegment {
            kind,
            body,
            cells,
            first_value,
        });
    }

    /// Total number of values (lower-triangle triplets) of all cells for dimension `d`.
    fn value_count(&self) -> usize {
        self.segments
            .last()
            .map(|s| s.first_value + s.cells.len() * values_per_cell(s.kind, self.dimension()))
            .unwrap_or(0)
    }

    fn dimension(&self) -> usize {
        self.segments
            .first()
            .map(|s| s.kind.dimension())
            .unwrap_or(2)
    }

    /// The global nodes of cell `c`.
    pub fn cell(&self, c: usize, kind: ElementKind) -> &[usize] {
        &self.nodes[self.node_start[c]..self.node_start[c] + kind.nodes()]
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.node_start.len()
    }

    /// Whether there is no cell.
    pub fn is_empty(&self) -> bool {
        self.node_start.is_empty()
    }
}

fn values_per_cell(kind: ElementKind, d: usize) -> usize {
    let m = kind.nodes() * d;
    m * (m + 1) / 2
}

/// Calls `f(p, q)` for the lower-triangle local dof pairs of a cell, in the canonical order
/// shared by the pattern and the value fill.
#[inline]
fn for_lower_pairs<const D: usize>(cell: &[usize], mut f: impl FnMut(usize, usize)) {
    let m = cell.len() * D;
    for p in 0..m {
        let gp = cell[p / D] * D + p % D;
        for q in 0..m {
            let gq = cell[q / D] * D + q % D;
            if gp > gq || (gp == gq && p == q) {
                f(p, q);
            }
        }
    }
}

/// The sparsity pattern of the global matrices (lower triangle), built once.
#[derive(Clone)]
pub struct Pattern {
    /// Number of unknowns.
    pub size: usize,
    symbolic: SymbolicSparseColMat<usize>,
    argsort: Argsort<usize>,
    /// Number of triplet values (cell contributions before summation).
    pub triplets: usize,
}

impl std::fmt::Debug for Pattern {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pattern")
            .field("size", &self.size)
            .field("triplets", &self.triplets)
            .finish()
    }
}

impl Pattern {
    /// The pattern of a cell table over `nodes` nodes.
    pub fn new<const D: usize>(table: &CellTable, nodes: usize) -> Result<Self> {
        let size = nodes * D;
        let mut pairs = Vec::with_capacity(table.value_count());
        for seg in &table.segments {
            for c in seg.cells.clone() {
                let cell = table.cell(c, seg.kind);
                for_lower_pairs::<D>(cell, |p, q| {
                    let gp = cell[p / D] * D + p % D;
                    let gq = cell[q / D] * D + q % D;
                    pairs.push(Pair::new(gp, gq));
                });
            }
        }
        let triplets = pairs.len();
        let (symbolic, argsort) = SymbolicSparseColMat::try_new_from_indices(size, size, &pairs)
            .map_err(|e| Error::Factorization {
                step: 0,
                message: format!("pattern: {e:?}"),
            })?;
        Ok(Pattern {
            size,
            symbolic,
            argsort,
            triplets,
        })
    }

    /// Sums per-cell triplet values into a matrix of this pattern.
    pub fn matrix(&self, values: &[f64]) -> SparseColMat<usize, f64> {
        SparseColMat::new_from_argsort(self.symbolic.clone(), &self.argsort, values)
            .expect("values match the pattern by construction")
    }
}

/// What one body needs for its element integrals.
#[derive(Clone)]
pub struct BodyIntegration {
    /// Kinematics of the body.
    pub kinematics: Kinematics,
    /// Constitutive law, evaluated per quadrature point.
    pub law: Arc<dyn ConstitutiveLaw>,
    /// Mass density (kg/m^3).
    pub density: f64,
    /// Updated-Lagrangian laws: the stiffness-proportional Rayleigh coefficient b (s), as the
    /// viscous stress `b E D` on the current configuration (a constant `b K` on the reference
    /// configuration would damp rigid rotations).
    pub stiffness_damping: f64,
}

impl BodyIntegration {
    /// A body of `material` in `kinematics`.
    pub fn new(kinematics: Kinematics, material: Material) -> Self {
        BodyIntegration {
            kinematics,
            law: Arc::new(material),
            density: material.density(),
            stiffness_damping: 0.0,
        }
    }

    /// History values of one cell of `kind`.
    pub(crate) fn history_per_cell(&self, kind: ElementKind) -> usize {
        kind.quadrature().len() * self.law.history_len()
    }
}

/// Total history values of every cell of a table (the length of the state's material history).
pub fn history_len(table: &CellTable, bodies: &[BodyIntegration]) -> usize {
    table
        .segments
        .iter()
        .map(|seg| seg.cells.len() * bodies[seg.body].history_per_cell(seg.kind))
        .sum()
}

/// The fields the element kernel evaluates the law with.
#[derive(Debug, Clone, Copy, Default)]
pub struct KernelFields<'a> {
    /// Displacements at `t_alpha` (flat, D per node) (m); `None`: zero strain.
    pub displacement: Option<&'a [f64]>,
    /// Velocities at `t_alpha` (m/s); `None`: zero strain rate.
    pub velocity: Option<&'a [f64]>,
    /// Weights of `dsigma/deps` and `dsigma/deps_dot` in the tangent.
    pub weights: (f64, f64),
    /// Displacements at the start of the step (flat) (m): the reference configuration of
    /// updated-Lagrangian laws; `None`: `displacement` (no increment).
    pub start: Option<&'a [f64]>,
    /// Displacements at the end of the step (m), for the history of updated-Lagrangian laws;
    /// `None`: `displacement`.
    pub end: Option<&'a [f64]>,
    /// The step (s) and alpha, passed to the law.
    pub time_step: f64,
    /// alpha.
    pub alpha: f64,
    /// Ask the laws for their secant tangent (see [`crate::material::PointKinematics::secant`]).
    pub secant: bool,
}

/// Stiffness and mass matrices of linear bodies, assembled on the reference configuration.
pub struct LinearMatrices {
    /// Stiffness K (N/m; lower triangle).
    pub stiffness: SparseColMat<usize, f64>,
    /// Mass M (kg; lower triangle), consistent or lumped.
    pub mass: SparseColMat<usize, f64>,
}

/// Assembles the stiffness and mass of every cell (in parallel with the `parallel` feature).
pub fn assemble_linear<const D: usize>(
    table: &CellTable,
    pattern: &Pattern,
    x: &[SVector<f64, D>],
    bodies: &[BodyIntegration],
    lumped: bool,
) -> LinearMatrices
where
    Dim<D>: SpatialDim<D>,
{
    let (k_vals, m_vals) = cell_values::<D>(table, pattern, x, bodies);
    let stiffness = pattern.matrix(&k_vals);
    let mut mass = pattern.matrix(&m_vals);
    if lumped {
        lump(&mut mass);
    }
    LinearMatrices { stiffness, mass }
}

/// Per-cell triplet values of the stiffness (the tangent at zero strain and rate) and the
/// consistent mass.
pub fn cell_values<const D: usize>(
    table: &CellTable,
    pattern: &Pattern,
    x: &[SVector<f64, D>],
    bodies: &[BodyIntegration],
) -> (Vec<f64>, Vec<f64>)
where
    Dim<D>: SpatialDim<D>,
{
    let mut k_vals = vec![0.0; pattern.triplets];
    let mut m_vals = vec![0.0; pattern.triplets];
    for seg in &table.segments {
        let per = values_per_cell(seg.kind, D);
        let range = seg.first_value..seg.first_value + per * seg.cells.len();
        let body = &bodies[seg.body];
        let fields = KernelFields {
            weights: (1.0, 0.0),
            ..Default::default()
        };
        let work = |(c, (k, m)): (usize, (&mut [f64], &mut [f64]))| {
            let cell = table.cell(seg.cells.start + c, seg.kind);
            let out = CellOutput {
                tangent: Some(k),
                mass: Some(m),
                ..Default::default()
            };
            cell_kernel::<D>(seg.kind, cell, x, body, &fields, out);
        };
        let (k_seg, m_seg) = (&mut k_vals[range.clone()], &mut m_vals[range]);
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            k_seg
                .par_chunks_mut(per)
                .zip(m_seg.par_chunks_mut(per))
                .enumerate()
                .for_each(work);
        }
        #[cfg(not(feature = "parallel"))]
        k_seg
            .chunks_mut(per)
            .zip(m_seg.chunks_mut(per))
            .enumerate()
            .for_each(work);
    }
    (k_vals, m_vals)
}

/// Replaces a consistent mass matrix by its row-sum lumped diagonal (same pattern).
pub fn lump(mass: &mut SparseColMat<usize, f64>) {
    let n = mass.nrows();
    let ones = vec![1.0; n];
    let mut row_sums = vec![0.0; n];
    symmetric_mul_add(mass, &ones, 1.0, &mut row_sums);
    let col_ptr = mass.symbolic().col_ptr().to_vec();
    let row_idx = mass.symbolic().row_idx().to_vec();
    let vals = mass.val_mut();
    for j in 0..n {
        for k in col_ptr[j]..col_ptr[j + 1] {
            vals[k] = if row_idx[k] == j { row_sums[j] } else { 0.0 };
        }
    }
}

/// Stored entries from which `symmetric_mul_add` is computed in `PRODUCT_CHUNKS` column
/// chunks, on the rayon pool's threads with the feature `parallel` (the same chunks and sums
/// on one thread: the same bits on any thread count). Below it, the product is one sequential
/// pass (a round figure, like the solver's thresholds).
#[doc(hidden)]
pub const PARALLEL_PRODUCT_ENTRIES: usize = 1_000_000;

/// The column chunks of a large product, of about equal stored entries.
const PRODUCT_CHUNKS: usize = 8;

/// `y += s A x` for a symmetric matrix stored as its lower triangle.
pub fn symmetric_mul_add(a: &SparseColMat<usize, f64>, x: &[f64], s: f64, y: &mut [f64]) {
    if a.val().len() < PARALLEL_PRODUCT_ENTRIES {
        lower_columns_mul_add(a, x, s, 0..a.ncols(), y, 0);
    } else {
        chunked_mul_add(a, x, s, y);
    }
}

/// [`symmetric_mul_add`] in [`PRODUCT_CHUNKS`] column chunks.
fn chunked_mul_add(a: &SparseColMat<usize, f64>, x: &[f64], s: f64, y: &mut [f64]) {
    let col_ptr = a.symbolic().col_ptr();
    let entries = a.val().len();
    // Each chunk of columns adds into its own buffer, over the rows from its first column on
    // (the lower triangle's); the buffers are then added row by row in the chunks' order.
    let mut bounds = vec![0];
    for c in 1..PRODUCT_CHUNKS {
        let target = c * entries / PRODUCT_CHUNKS;
        let j = col_ptr.partition_point(|&p| p < target).min(a.ncols());
        bounds.push(j.max(*bounds.last().expect("one bound")));
    }
    bounds.push(a.ncols());
    let chunk = |c: usize| {
        let (first, end) = (bounds[c], bounds[c + 1]);
        let mut buffer = vec![0.0; a.nrows() - first];
        lower_columns_mul_add(a, x, s, first..end, &mut buffer, first);
        buffer
    };
    let buffers: Vec<Vec<f64>> = crate::parallel::map_indices(PRODUCT_CHUNKS, chunk);
    let add_rows = |block: usize, rows: &mut [f64]| {
        let start = block * ROW_BLOCK;
        for (c, buffer) in buffers.iter().enumerate() {
            let first = bounds[c];
            for (k, yi) in rows.iter_mut().enumerate() {
                if start + k >= first {
                    *yi += buffer[start + k - first];
                }
            }
        }
    };
    const ROW_BLOCK: usize = 1 << 14;
    crate::parallel::for_each_chunk_mut(y, ROW_BLOCK, add_rows);
}

/// `y[i - first] += s (A x)_i` restricted to the stored entries of `columns` (lower triangle,
/// each off-diagonal entry standing for two), for rows `i >= first`.
fn lower_columns_mul_add(
    a: &SparseColMat<usize, f64>,
    x: &[f64],
    s: f64,
    columns: std::ops::Range<usize>,
    y: &mut [f64],
    first: usize,
) {
    let col_ptr = a.symbolic().col_ptr();
    let row_idx = a.symbolic().row_idx();
    let vals = a.val();
    for j in columns {
        let xj = s * x[j];
        let mut acc = 0.0;
        for k in col_ptr[j]..col_ptr[j + 1] {
            let i = row_idx[k];
            let v = vals[k];
            y[i - first] += v * xj;
            if i != j {
                acc += v * x[i];
            }
        }
        y[j - first] += s * acc;
    }
}

/// `x^T A y` for a symmetric matrix stored as its lower triangle.
pub fn symmetric_dot(a: &SparseColMat<usize, f64>, x: &[f64], y: &[f64]) -> f64 {
    let mut ay = vec![0.0; y.len()];
    symmetric_mul_add(a, y, 1.0, &mut ay);
    x.iter().zip(&ay).map(|(a, b)| a * b).sum()
}

/// The average Voigt stress of every cell for displacements `u` (flat, D per node) and the
/// material history `history` (the state's), bodies in order.
pub fn cell_stresses<const D: usize>(
    table: &CellTable,
    x: &[SVector<f64, D>],
    bodies: &[BodyIntegration],
    u: &[f64],
    history: &[f64],
) -> Vec<Voigt>
where
    Dim<D>: SpatialDim<D>,
{
    let fields = KernelFields {
        displacement: Some(u),
        ..Default::default()
    };
    let mut out = vec![Voigt::zeros(); table.len()];
    let mut offset = 0;
    for seg in &table.segments {
        let body = &bodies[seg.body];
        let per = body.history_per_cell(seg.kind);
        for c in seg.cells.clone() {
            let cell = table.cell(c, seg.kind);
            let output = CellOutput {
                history: history.get(offset..offset + per).unwrap_or(&[]),
                stress: Some(&mut out[c]),
                ..Default::default()
            };
            offset += per;
            cell_kernel::<D>(seg.kind, cell, x, body, &fields, output);
        }
    }
    out
}

/// The equivalent logarithmic strain of every cell for displacements `u` (flat, D per node)
/// from the reference positions `x`, bodies in order: `sqrt(2/3 e : e)` with `e` the
/// deviatoric part of the Hencky strain `ln(F^T F) / 2`, averaged over the cell's quadrature
/// points by volume. On a proportional path it is the accumulated equivalent strain that
/// forming codes plot (the paper's example 2); plane kinematics take no out-of-plane stretch
/// (plane stress's thickness change is not in `u`), axisymmetric ones the hoop stretch.
pub fn cell_equivalent_strains<const D: usize>(
    table: &CellTable,
    x: &[SVector<f64, D>],
    bodies: &[BodyIntegration],
    u: &[f64],
) -> Vec<f64>
where
    Dim<D>: SpatialDim<D>,
{
    let mut out = vec![0.0; table.len()];
    for seg in &table.segments {
        let kinematics = bodies[seg.body].kinematics;
        for c in seg.cells.clone() {
            let cell = table.cell(c, seg.kind);
            let (mut sum, mut volume) = (0.0, 0.0);
            for q in seg.kind.quadrature() {
                let (n, grads, position, det) = spatial_gradients::<D>(seg.kind, cell, x, q.xi);
                let r = position[0];
                let mut f = nalgebra::Matrix3::<f64>::identity();
                for (a, &node) in cell.iter().enumerate() {
                    let ua = SVector::<f64, D>::from_column_slice(&u[node * D..node * D + D]);
                    f += <Dim<D>>::gradient_3d(kinematics, n[a], &grads[a], r, &ua);
                }
                let w = q.weight * det.abs() * <Dim<D>>::measure_factor(kinematics, &position);
                sum += w * equivalent_log_strain(&f);
                volume += w;
            }
            out[c] = if volume > 0.0 { sum / volume } else { 0.0 };
        }
    }
    out
}

/// `sqrt(2/3 e : e)`, `e` the deviatoric Hencky strain of the deformation gradient `f`; NaN
/// for an inverted `f`.
pub fn equivalent_log_strain(f: &nalgebra::Matrix3<f64>) -> f64 {
    if f.determinant() <= 0.0 {
        return f64::NAN;
    }
    let stretches = (f.transpose() * f).symmetric_eigenvalues();
    let e = stretches.map(|l| 0.5 * l.ln());
    let mean = e.sum() / 3.0;
    (2.0 / 3.0 * e.map(|v| (v - mean).powi(2)).sum()).sqrt()
}

/// Von Mises equivalent stress of a Voigt stress.
pub fn von_mises(s: &Voigt) -> f64 {
    let (xx, yy, zz, yz, xz, xy) = (s[0], s[1], s[2], s[3], s[4], s[5]);
    (0.5 * ((xx - yy).powi(2) + (yy - zz).powi(2) + (zz - xx).powi(2))
        + 3.0 * (yz * yz + xz * xz + xy * xy))
        .sqrt()
}

/// What [`integrate`] returns.
pub struct Integrated {
    /// Internal forces `int B^T sigma` (N; flat, D per node).
    pub forces: Vec<f64>,
    /// Tangent values in the pattern's triplet order, when a pattern was given.
    pub tangent: Option<Vec<f64>>,
    /// Stored energy (J); NaN when a cell of an updated-Lagrangian law is inverted at
    /// `t_alpha` (its Jacobian is not positive).
    pub energy: f64,
    /// The material history at the end of the step, for these fields.
    pub history: Vec<f64>,
    /// The part of `forces` that dissipates (N): the stiffness-proportional damping of
    /// updated-Lagrangian bodies and the whole stress of flow laws (empty without either).
    pub damping_forces: Vec<f64>,
    /// The first inverted cell (the one `energy` is NaN for), in the table's order: its body
    /// and its nodes, for the error that names where it is.
    pub inverted: Option<(usize, Vec<usize>)>,
}

/// Internal forces `f_int = int B^T sigma` integrated cell by cell from the law's stresses at
/// the displacements and velocities of `fields` and the material `history` at the start of
/// the step, the tangent values of `fields.weights` (when `pattern` is given), the stored
/// energy and the new history. The path of laws that are not linear; for linear laws the
/// forces equal `K u` (tested). Cells run in parallel; sums are in a fixed order.
pub fn integrate<const D: usize>(
    table: &CellTable,
    pattern: Option<&Pattern>,
    x: &[SVector<f64, D>],
    bodies: &[BodyIntegration],
    fields: &KernelFields<'_>,
    history: &[f64],
    ndof: usize,
) -> Integrated
where
    Dim<D>: SpatialDim<D>,
{
    let mut f = vec![0.0; ndof];
    let mut tangent = pattern.map(|p| vec![0.0; p.triplets]);
    let mut energy = 0.0;
    let mut new_history = vec![0.0; history_len(table, bodies)];
    let mut damping_forces = Vec::new();
    let mut inverted = None;
    let mut offset = 0;
    for seg in &table.segments {
        let per = values_per_cell(seg.kind, D);
        let m = seg.kind.nodes() * D;
        let body = &bodies[seg.body];
        // Damped updated-Lagrangian bodies keep their damping forces apart too, in the
        // second half of each cell's chunk.
        let damped = (body.stiffness_damping > 0.0 && body.law.updated_lagrangian())
            || body.law.dissipative();
        let chunk = if damped { 2 * m } else { m };
        if damped && damping_forces.is_empty() {
            damping_forces = vec![0.0; ndof];
        }
        let count = seg.cells.len();
        let hp = body.history_per_cell(seg.kind);
        let seg_history = history.get(offset..offset + count * hp).unwrap_or(&[]);
        // Per-cell forces, energies and histories, summed or copied in a fixed order.
        let mut local = vec![0.0; count * chunk];
        let mut energies = vec![0.0; count];
        let mut histories = vec![0.0; count * hp.max(1)];
        let k_seg: Option<&mut [f64]> = tangent
            .as_mut()
            .map(|t| &mut t[seg.first_value..seg.first_value + per * count]);
        let work =
            |c: usize, fl: &mut [f64], e: &mut f64, hl: &mut [f64], k: Option<&mut [f64]>| {
                let cell = table.cell(seg.cells.start + c, seg.kind);
                let (fl, fd) = fl.split_at_mut(m);
                let out = CellOutput {
                    history: seg_history.get(c * hp..(c + 1) * hp).unwrap_or(&[]),
                    new_history: (hp > 0).then_some(hl),
                    tangent: k,
                    force: Some(fl),
                    damping_force: damped.then_some(fd),
                    energy: Some(e),
                    ..Default::default()
                };
                cell_kernel::<D>(seg.kind, cell, x, body, fields, out);
            };
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            let cells = local
                .par_chunks_mut(chunk)
                .zip(energies.par_iter_mut())
                .zip(histories.par_chunks_mut(hp.max(1)));
            match k_seg {
                Some(k) => cells
                    .zip(k.par_chunks_mut(per))
                    .enumerate()
                    .for_each(|(c, (((fl, e), hl), k))| work(c, fl, e, hl, Some(k))),
                None => cells
                    .enumerate()
                    .for_each(|(c, ((fl, e), hl))| work(c, fl, e, hl, None)),
            }
        }
        #[cfg(not(feature = "parallel"))]
        {
            let mut k_chunks = k_seg.map(|k| k.chunks_mut(per));
            let cells = local
                .chunks_mut(chunk)
                .zip(energies.iter_mut())
                .zip(histories.chunks_mut(hp.max(1)));
            for (c, ((fl, e), hl)) in cells.enumerate() {
                work(c, fl, e, hl, k_chunks.as_mut().and_then(|it| it.next()));
            }
        }
        for (c, fl) in local.chunks(chunk).enumerate() {
            let cell = table.cell(seg.cells.start + c, seg.kind);
            for (a, &node) in cell.iter().enumerate() {
                for k in 0..D {
                    f[node * D + k] += fl[a * D + k];
                    if damped {
                        damping_forces[node * D + k] += fl[m + a * D + k];
                    }
                }
            }
        }
        let segment_energy = energies.iter().sum::<f64>();
        energy += segment_energy;
        // Searched only when this segment holds an inverted cell (its energy sum is NaN).
        if inverted.is_none() && segment_energy.is_nan() {
            inverted = energies.iter().position(|e| e.is_nan()).map(|c| {
                let nodes = table.cell(seg.cells.start + c, seg.kind);
                (seg.body, nodes.to_vec())
            });
        }
        if hp > 0 {
            new_history[offset..offset + count * hp].copy_from_slice(&histories);
        }
        offset += count * hp;
    }
    Integrated {
        forces: f,
        tangent,
        energy,
        history: new_history,
        damping_forces,
        inverted,
    }
}

#[cfg(test)]
mod bbar_tests;
#[cfg(test)]
mod tests;
