//! The element kernel: the one place where a cell is integrated.

use nalgebra::{SMatrix, SVector};

use super::{for_lower_pairs, BodyIntegration, KernelFields, MAX_DOFS};
use crate::dim::{Dim, Kinematics, SpatialDim, Voigt};
use crate::element::{ElementKind, MAX_NODES};
use crate::material::PointKinematics;

/// What the element kernel writes for one cell; each output is optional.
#[derive(Default)]
pub(super) struct CellOutput<'a> {
    /// The cell's history at the start of the step (quadrature point after point).
    pub(super) history: &'a [f64],
    /// Where the cell's new history goes.
    pub(super) new_history: Option<&'a mut [f64]>,
    /// Tangent values (lower triangle, canonical order).
    pub(super) tangent: Option<&'a mut [f64]>,
    /// Consistent mass values (lower triangle, canonical order).
    pub(super) mass: Option<&'a mut [f64]>,
    /// Internal forces on the cell's dofs (`nodes * D`).
    pub(super) force: Option<&'a mut [f64]>,
    /// The part of `force` that dissipates (stiffness damping of updated-Lagrangian bodies,
    /// the whole stress of flow laws).
    pub(super) damping_force: Option<&'a mut [f64]>,
    /// Volume-averaged stress.
    pub(super) stress: Option<&'a mut Voigt>,
    /// Stored energy (J).
    pub(super) energy: Option<&'a mut f64>,
}

/// The element kernel, the one place where a cell is integrated: at every quadrature point the
/// law is evaluated on the strain and strain rate of `fields`, and the tangent
/// `int B^T (w_0 dsigma/deps + w_1 dsigma/deps_dot) B`, the mass `int rho N N`, the internal
/// forces `int B^T sigma`, the mean stress and the stored energy are accumulated as requested.
#[allow(non_snake_case)]
pub(super) fn cell_kernel<const D: usize>(
    kind: ElementKind,
    cell: &[usize],
    x: &[SVector<f64, D>],
    body: &BodyIntegration,
    fields: &KernelFields<'_>,
    out: CellOutput<'_>,
) where
    Dim<D>: SpatialDim<D>,
{
    let n = kind.nodes();
    let m = n * D;
    let density = body.density;
    let per_point = body.law.history_len();
    let mut out = out;
    let mut new_history = out.new_history.take();
    let mut scratch = vec![0.0; if new_history.is_none() { per_point } else { 0 }];
    let want_tangent = out.tangent.is_some();
    let want_mass = out.mass.is_some();
    let mut K = [[0.0f64; MAX_DOFS]; MAX_DOFS];
    let mut M = [[0.0f64; MAX_NODES]; MAX_NODES];
    let mut force = [0.0f64; MAX_DOFS];
    let mut stress_sum = Voigt::zeros();
    let mut stress_weight = 0.0;
    let mut energy = 0.0;
    let node_value = |values: &[f64], node: usize| {
        SVector::<f64, D>::from_column_slice(&values[node * D..node * D + D])
    };
    // Updated-Lagrangian laws integrate on the configuration at t_alpha, reached from the
    // one at t0 (their reference) by the increment u_alpha - u0.
    let updated = body.law.updated_lagrangian();
    let zero = SVector::<f64, D>::zeros();
    let field = |values: Option<&[f64]>, node: usize| values.map_or(zero, |u| node_value(u, node));
    let start = fields.start.or(fields.displacement);
    let end = fields.end.or(fields.displacement);
    let mut x_local = [zero; MAX_NODES];
    let mut du_alpha = [zero; MAX_NODES];
    let mut du_end = [zero; MAX_NODES];
    for (a, &node) in cell.iter().enumerate() {
        x_local[a] = x[node];
        if updated {
            let u0 = field(start, node);
            x_local[a] += u0;
            du_alpha[a] = field(fields.displacement, node) - u0;
            du_end[a] = field(end, node) - u0;
        }
    }
    let mut inverted = false;
    // Pass 1: every quadrature point's geometry and strain operators.
    let rule = kind.quadrature();
    let mut points = [PointGeometry::<D>::default(); MAX_POINTS];
    for (iq, q) in rule.iter().enumerate() {
        let (shape, mut grads, mut position, det) = local_gradients::<D>(kind, &x_local[..n], q.xi);
        let mut dv = q.weight * det * <Dim<D>>::measure_factor(body.kinematics, &position);
        let mut increment = nalgebra::Matrix3::<f64>::zeros();
        let mut end_increment = nalgebra::Matrix3::<f64>::zeros();
        if updated {
            for a in 0..n {
                let (na, ga, r) = (shape[a], &grads[a], position[0]);
                increment += <Dim<D>>::gradient_3d(body.kinematics, na, ga, r, &du_alpha[a]);
                end_increment += <Dim<D>>::gradient_3d(body.kinematics, na, ga, r, &du_end[a]);
            }
            // To t_alpha: gradients F^-T grad0, volume det F dV0 (the hoop stretch r/r0
            // included), position moved.
            let f = SMatrix::<f64, D, D>::identity() + <Dim<D>>::in_plane_block(&increment);
            let f_inv = <Dim<D>>::inverse(&f).unwrap_or_else(SMatrix::zeros);
            let jacobian = (nalgebra::Matrix3::identity() + increment).determinant();
            // The end of the step too: the next step starts there, and a cell folded at a
            // quadrature point integrates with a negative volume, which makes the iteration
            // matrix indefinite (the tube crush under implicit projection once failed its
            // factorisation so, a step after ending with such a cell).
            let end_jacobian = (nalgebra::Matrix3::identity() + end_increment).determinant();
            if !(jacobian > 0.0 && end_jacobian > 0.0 && det > 0.0) {
                // An inverted cell: the energy says so (NaN), and Newton backs off.
                inverted = true;
            }
            dv *= jacobian;
            for a in 0..n {
                grads[a] = f_inv.transpose() * grads[a];
                position += du_alpha[a] * shape[a];
            }
        }
        let point = &mut points[iq];
        for a in 0..n {
            point.b[a] =
                <Dim<D>>::strain_operator(body.kinematics, shape[a], &grads[a], position[0]);
        }
        point.shape = shape;
        point.grads = grads;
        point.position = position;
        point.dv = dv;
        point.plane_weight = q.weight * det;
        point.increment = increment;
        point.end_increment = end_increment;
    }
    // B-bar: the volumetric part of every strain operator replaced by its cell average, for
    // laws that need it on the elements whose full integration locks (Quad4, Hex8). Not in
    // plane stress, where the thickness strain is free and nothing locks.
    if body.law.volumetric_average()
        && body.kinematics != Kinematics::PlaneStress
        && matches!(kind, ElementKind::Quad4 | ElementKind::Hex8)
    {
        average_volumetric::<D>(&mut points[..rule.len()], n);
    }
    // Pass 2: the law and the integrals.
    for (iq, point) in points[..rule.len()].iter().enumerate() {
        let PointGeometry {
            shape,
            grads,
            position,
            dv,
            plane_weight,
            increment,
            end_increment,
            ..
        } = *point;
        let b = &point.b;
        let points = iq * per_point..(iq + 1) * per_point;
        let history = out.history.get(points.clone()).unwrap_or(&[]);
        let new_point_history = match new_history.as_deref_mut() {
            Some(h) => &mut h[points],
            None => &mut scratch[..],
        };
        let mut strain = Voigt::zeros();
        let mut strain_rate = Voigt::zeros();
        let mut spin = nalgebra::Matrix3::<f64>::zeros();
        for (a, &node) in cell.iter().enumerate() {
            if let (Some(u), false) = (fields.displacement, updated) {
                strain += b[a] * node_value(u, node);
            }
            if let Some(v) = fields.velocity {
                let va = node_value(v, node);
                strain_rate += b[a] * va;
                // The skew part of grad v (in-plane in 2D; the hoop direction has no spin).
                for i in 0..D {
                    for j in 0..D {
                        spin[(i, j)] += 0.5 * (va[i] * grads[a][j] - va[j] * grads[a][i]);
                    }
                }
            }
        }
        let response = body.law.evaluate(
            &PointKinematics {
                kinematics: body.kinematics,
                strain,
                strain_rate,
                spin,
                time_step: fields.time_step,
                alpha: fields.alpha,
                secant: fields.secant,
                increment,
                end_increment,
            },
            history,
            new_point_history,
        );
        // Stiffness-proportional damping of updated-Lagrangian bodies: b E D.
        let damping = body.stiffness_damping;
        let dissipative = body.law.dissipative();
        let damping_stress = if updated && damping > 0.0 {
            response.stiffness * strain_rate * damping
        } else {
            Voigt::zeros()
        };
        if want_tangent {
            let (w0, w1) = fields.weights;
            let viscosity = if updated && damping > 0.0 {
                response.viscosity + response.stiffness * damping
            } else {
                response.viscosity
            };
            let tangent = if w1 == 0.0 {
                response.stiffness * w0
            } else {
                response.stiffness * w0 + viscosity * w1
            };
            // K is symmetric for symmetric laws: compute the blocks (bb, a) with bb >= a and
            // mirror them after.
            for a in 0..n {
                let cb = tangent * b[a] * dv;
                for bb in a..n {
                    let kab = b[bb].transpose() * cb; // (D x 6)(6 x D): block (bb, a)
                    for i in 0..D {
                        for j in 0..D {
                            K[bb * D + i][a * D + j] += kab[(i, j)];
                        }
                    }
                }
            }
            // Flow laws leave it out: their stress over the step's viscous stiffness is
            // large where the flow is fast, and the geometric part, negative in compression,
            // would make the iteration matrix indefinite (the residual stays exact).
            if updated && !dissipative {
                geometric_stiffness::<D>(
                    body.kinematics,
                    &shape[..n],
                    &grads[..n],
                    position[0],
                    &response.stress,
                    fields.weights.0 * dv,
                    &mut K,
                );
            }
        }
        if want_mass {
            for a in 0..n {
                for bb in a..n {
                    M[a][bb] += density * shape[a] * shape[bb] * dv;
                }
            }
        }
        if out.force.is_some() {
            let total = response.stress + damping_stress;
            for a in 0..n {
                let fa = b[a].transpose() * total * dv;
                for k in 0..D {
                    force[a * D + k] += fa[k];
                }
            }
        }
        if let Some(fd) = out.damping_force.as_deref_mut() {
            // A flow law's whole stress dissipates.
            let dissipating = if dissipative {
                response.stress + damping_stress
            } else {
                damping_stress
            };
            for a in 0..n {
                let fa = b[a].transpose() * dissipating * dv;
                for k in 0..D {
                    fd[a * D + k] += fa[k];
                }
            }
        }
        // The mean stress is weighted by the plane measure (without the axisymmetric 2 pi r).
        let w = plane_weight;
        stress_sum += response.stress * w;
        stress_weight += w;
        energy += response.energy_density * dv;
    }
    if let Some(k_out) = out.tangent {
        for a in 0..n {
            for bb in a + 1..n {
                for i in 0..D {
                    for j in 0..D {
                        K[a * D + j][bb * D + i] = K[bb * D + i][a * D + j];
                    }
                }
            }
        }
        let mut slot = 0;
        for_lower_pairs::<D>(cell, |p, q| {
            k_out[slot] = K[p][q];
            slot += 1;
        });
        debug_assert_eq!(slot, m * (m + 1) / 2);
    }
    if let Some(m_out) = out.mass {
        for a in 0..n {
            for bb in a + 1..n {
                M[bb][a] = M[a][bb];
            }
        }
        let mut slot = 0;
        for_lower_pairs::<D>(cell, |p, q| {
            m_out[slot] = if p % D == q % D { M[p / D][q / D] } else { 0.0 };
            slot += 1;
        });
    }
    if let Some(f) = out.force {
        f[..m].copy_from_slice(&force[..m]);
    }
    if let Some(s) = out.stress {
        *s = if stress_weight > 0.0 {
            stress_sum / stress_weight
        } else {
            stress_sum
        };
    }
    if let Some(e) = out.energy {
        *e = if inverted { f64::NAN } else { energy };
    }
}

/// Shape values, spatial gradients, position and Jacobian determinant at a reference point.
pub type PointShape<const D: usize> = (
    [f64; MAX_NODES],
    [SVector<f64, D>; MAX_NODES],
    SVector<f64, D>,
    f64,
);

/// Shape values, spatial gradients, position and Jacobian determinant at a reference point.
pub fn spatial_gradients<const D: usize>(
    kind: ElementKind,
    cell: &[usize],
    x: &[SVector<f64, D>],
    xi: [f64; 3],
) -> PointShape<D>
where
    Dim<D>: SpatialDim<D>,
{
    let mut local = [SVector::<f64, D>::zeros(); MAX_NODES];
    for (a, &node) in cell.iter().enumerate() {
        local[a] = x[node];
    }
    local_gradients::<D>(kind, &local[..cell.len()], xi)
}

/// [`spatial_gradients`] on the cell's own node positions `x` (in cell order).
fn local_gradients<const D: usize>(
    kind: ElementKind,
    x: &[SVector<f64, D>],
    xi: [f64; 3],
) -> PointShape<D>
where
    Dim<D>: SpatialDim<D>,
{
    let s = kind.shape(xi);
    let mut jac = SMatrix::<f64, D, D>::zeros();
    let mut position = SVector::<f64, D>::zeros();
    for (a, xa) in x.iter().enumerate() {
        position += xa * s.n[a];
        for k in 0..D {
            jac.column_mut(k).axpy(s.dn[a][k], xa, 1.0);
        }
    }
    let det = <Dim<D>>::det(&jac);
    let inv = <Dim<D>>::inverse(&jac).unwrap_or_else(SMatrix::zeros);
    let mut grads = [SVector::<f64, D>::zeros(); MAX_NODES];
    for a in 0..x.len() {
        let mut dxi = SVector::<f64, D>::zeros();
        for k in 0..D {
            dxi[k] = s.dn[a][k];
        }
        // dN/dx = J^-T dN/dxi, with J_ik = dx_i/dxi_k.
        grads[a] = inv.transpose() * dxi;
    }
    (s.n, grads, position, det)
}

/// Adds the geometric (initial-stress) stiffness `weight int grad(dv_a) : (grad(dv_b) sigma)`
/// of one quadrature point to the blocks (b, a), b >= a, of `k`: the variation of the forces
/// `int B^T sigma dV` through the configuration, at fixed stress (the stress's own variation
/// is the material part; the Jaumann and volume terms, of the order of the stress, are left
/// out, which keeps the tangent symmetric).
pub(super) fn geometric_stiffness<const D: usize>(
    kinematics: crate::dim::Kinematics,
    shape: &[f64],
    grads: &[SVector<f64, D>],
    r: f64,
    stress: &Voigt,
    weight: f64,
    k: &mut [[f64; MAX_DOFS]; MAX_DOFS],
) where
    Dim<D>: SpatialDim<D>,
{
    let sigma = crate::material::stress_tensor(stress);
    // With h(a, i) the 3 x 3 gradient of a unit displacement e_i of node a, the entry is
    // h(b, i) : (h(a, j) sigma). h(a, i) is e_i (x) grad_a, plus, for i = x in axisymmetry,
    // the hoop term N_a / r at (z, z); so the entry is delta_ij grad_b . sigma grad_a, plus
    // N_a N_b sigma_zz / r^2 at i = j = x. (Written out: the 3 x 3 products took a third of a
    // hypoelastic body's assembly.)
    let n = shape.len();
    let in_plane = <Dim<D>>::in_plane_block(&sigma);
    let mut radial = SVector::<f64, D>::zeros();
    radial[0] = 1.0;
    let zero = SVector::<f64, D>::zeros();
    let mut hoop = [0.0; MAX_NODES];
    for a in 0..n {
        hoop[a] = <Dim<D>>::gradient_3d(kinematics, shape[a], &zero, r, &radial)[(2, 2)];
    }
    for a in 0..n {
        let sigma_ga = in_plane * grads[a];
        for bb in a..n {
            let s = weight * grads[bb].dot(&sigma_ga);
            for i in 0..D {
                k[bb * D + i][a * D + i] += s;
            }
            k[bb * D][a * D] += weight * hoop[a] * hoop[bb] * sigma[(2, 2)];
        }
    }
}

/// Largest number of quadrature points of a cell.
const MAX_POINTS: usize = 8;

/// One quadrature point's geometry (on the configuration the cell is integrated on).
#[derive(Clone, Copy)]
struct PointGeometry<const D: usize> {
    shape: [f64; MAX_NODES],
    grads: [SVector<f64, D>; MAX_NODES],
    position: SVector<f64, D>,
    /// The integration weight with the Jacobian and the axisymmetric measure (m^3 or m^2).
    dv: f64,
    /// The weight in the plane measure (no `2 pi r`), for the mean stress.
    plane_weight: f64,
    /// The strain operator of each node.
    b: [SMatrix<f64, 6, D>; MAX_NODES],
    increment: nalgebra::Matrix3<f64>,
    end_increment: nalgebra::Matrix3<f64>,
}

impl<const D: usize> Default for PointGeometry<D> {
    fn default() -> Self {
        PointGeometry {
            shape: [0.0; MAX_NODES],
            grads: [SVector::zeros(); MAX_NODES],
            position: SVector::zeros(),
            dv: 0.0,
            plane_weight: 0.0,
            b: [SMatrix::zeros(); MAX_NODES],
            increment: nalgebra::Matrix3::zeros(),
            end_increment: nalgebra::Matrix3::zeros(),
        }
    }
}

/// Hughes' B-bar: at every point, the volumetric strain `(eps_xx + eps_yy + eps_zz)` that each
/// node's operator produces is replaced by its volume average over the cell, one third on each
/// normal component, so that a near-incompressible law constrains one volume per cell instead
/// of one per point (the selective reduced integration of the volumetric term, for any law).
fn average_volumetric<const D: usize>(points: &mut [PointGeometry<D>], nodes: usize) {
    let volume: f64 = points.iter().map(|p| p.dv).sum();
    if !(volume > 0.0) {
        return;
    }
    let divergence = |b: &SMatrix<f64, 6, D>| b.row(0) + b.row(1) + b.row(2);
    for a in 0..nodes {
        let mean = points
            .iter()
            .map(|p| divergence(&p.b[a]) * p.dv)
            .fold(nalgebra::RowSVector::<f64, D>::zeros(), |s, r| s + r)
            / volume;
        for p in points.iter_mut() {
            let change = (mean - divergence(&p.b[a])) / 3.0;
            for row in 0..3 {
                let updated = p.b[a].row(row) + change;
                p.b[a].set_row(row, &updated);
            }
        }
    }
}
