//! The element kernel's tangent against central differences of its own forces, for the
//! updated-Lagrangian path (material and geometric stiffness).

use nalgebra::{DMatrix, DVector, SVector};

use super::*;
use crate::material::{Hypoelastic, RotationUpdate};
use crate::verify_record::record;

/// One cell of `kind` with nodes `x` (reference), its forces and its tangent
/// `d forces / d u` (weights (1, 0)) at displacement `u` from the start displacement `u0`,
/// with the history `history` (per quadrature point).
fn forces_and_tangent<const D: usize>(
    kind: ElementKind,
    kinematics: Kinematics,
    x: &[SVector<f64, D>],
    u0: &[f64],
    u: &[f64],
    history: &[f64],
) -> (DVector<f64>, DMatrix<f64>)
where
    Dim<D>: SpatialDim<D>,
{
    let law = Hypoelastic::new(1e6, 0.3, 1000.0, RotationUpdate::HughesWinget).unwrap();
    let body = BodyIntegration::new(kinematics, Material::Hypoelastic(law));
    let cell: Vec<usize> = (0..kind.nodes()).collect();
    let m = cell.len() * D;
    let mut values = vec![0.0; m * (m + 1) / 2];
    let mut force = vec![0.0; m];
    let mut new_history = vec![0.0; history.len()];
    let fields = KernelFields {
        displacement: Some(u),
        start: Some(u0),
        weights: (1.0, 0.0),
        ..Default::default()
    };
    let out = CellOutput {
        history,
        new_history: Some(&mut new_history),
        tangent: Some(&mut values),
        force: Some(&mut force),
        ..Default::default()
    };
    cell_kernel::<D>(kind, &cell, x, &body, &fields, out);
    (
        DVector::from_vec(force),
        symmetric_from_lower::<D>(&cell, &values),
    )
}

/// The cell's symmetric tangent from the kernel's packed lower triangle (shared with
/// `bbar_tests`).
pub(super) fn symmetric_from_lower<const D: usize>(cell: &[usize], values: &[f64]) -> DMatrix<f64>
where
    Dim<D>: SpatialDim<D>,
{
    let m = cell.len() * D;
    let mut k = DMatrix::zeros(m, m);
    let mut slot = 0;
    for_lower_pairs::<D>(cell, |p, q| {
        k[(p, q)] = values[slot];
        k[(q, p)] = values[slot];
        slot += 1;
    });
    k
}

/// Central differences of the forces in direction `d`.
fn difference<const D: usize>(
    kind: ElementKind,
    kinematics: Kinematics,
    x: &[SVector<f64, D>],
    u0: &[f64],
    u: &[f64],
    history: &[f64],
    d: &DVector<f64>,
) -> DVector<f64>
where
    Dim<D>: SpatialDim<D>,
{
    let eps = 1e-7;
    let at = |s: f64| {
        let w: Vec<f64> = u
            .iter()
            .zip(d.iter())
            .map(|(a, b)| a + s * eps * b)
            .collect();
        forces_and_tangent::<D>(kind, kinematics, x, u0, &w, history).0
    };
    (at(1.0) - at(-1.0)) / (2.0 * eps)
}

/// The corners of a slightly distorted cell of `kind` (m), shared with `bbar_tests`.
pub(super) fn corners(kind: ElementKind) -> Vec<[f64; 3]> {
    match kind {
        ElementKind::Tri3 => vec![[0.0, 0.0, 0.0], [1.0, 0.1, 0.0], [0.2, 0.9, 0.0]],
        ElementKind::Quad4 => vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.1, 0.0],
            [1.1, 0.9, 0.0],
            [0.1, 1.0, 0.0],
        ],
        ElementKind::Tet4 => vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.1, 0.0],
            [0.1, 0.9, 0.1],
            [0.0, 0.1, 1.1],
        ],
        ElementKind::Hex8 => {
            let mut c = Vec::new();
            for z in [0.0, 1.0] {
                for (x, y) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
                    c.push([x + 0.05 * y * z, y + 0.1 * x * z, z + 0.05 * x]);
                }
            }
            c
        }
    }
}

/// A slightly distorted cell of `kind` away from the axis, a start displacement that turns
/// and stretches it, and a pre-stress of `stress` Pa in every component.
fn setup<const D: usize>(
    kind: ElementKind,
    stress: f64,
) -> (Vec<SVector<f64, D>>, Vec<f64>, Vec<f64>) {
    let corners = corners(kind);
    // Off the axis (axisymmetric kinematics need r > 0).
    let x: Vec<SVector<f64, D>> = corners
        .iter()
        .map(|c| SVector::from_fn(|i, _| c[i] + if i == 0 { 1.0 } else { 0.0 }))
        .collect();
    let u0: Vec<f64> = x
        .iter()
        .flat_map(|p| {
            // A rotation of 0.4 rad about z plus a 2 % stretch along x.
            let (c, s) = (0.4f64.cos(), 0.4f64.sin());
            let mut q = *p;
            q[0] = c * p[0] - s * p[1];
            q[1] = s * p[0] + c * p[1];
            q[0] *= 1.02;
            (0..D).map(move |i| q[i] - p[i]).collect::<Vec<_>>()
        })
        .collect();
    let points = kind.quadrature().len();
    let history: Vec<f64> = (0..points)
        .flat_map(|_| {
            let mut s = [stress, 0.5 * stress, 0.3 * stress, 0.0, 0.0, 0.2 * stress];
            if D == 3 {
                s[3] = 0.1 * stress;
                s[4] = -0.15 * stress;
            }
            s
        })
        .collect();
    (x, u0, history)
}

fn relative(a: &DVector<f64>, b: &DVector<f64>) -> f64 {
    (a - b).amax() / b.amax().max(1e-300)
}

fn check<const D: usize>(kind: ElementKind, kinematics: Kinematics)
where
    Dim<D>: SpatialDim<D>,
{
    let m = kind.nodes() * D;
    let direction = DVector::from_fn(m, |i, _| ((i * 7 + 3) % 11) as f64 / 11.0 - 0.4);
    // No pre-stress: the tangent is exact at the start of the step, and to first order
    // in the increment after it.
    let (x, u0, history) = setup::<D>(kind, 0.0);
    let (_, k) = forces_and_tangent::<D>(kind, kinematics, &x, &u0, &u0, &history);
    let fd = difference::<D>(kind, kinematics, &x, &u0, &u0, &history, &direction);
    let e = relative(&(&k * &direction), &fd);
    record("hypoelastic-tangent", "unstressed", e);
    assert!(e < 1e-6, "{kind:?} {kinematics:?} unstressed: {e:e}");
    // Pre-stressed (1 % of E): in the direction of a rigid rotation of the current
    // configuration (in-plane) the geometric stiffness is the whole, exact answer.
    let stress = 1e4;
    let (x, u0, history) = setup::<D>(kind, stress);
    let current: Vec<SVector<f64, D>> = x
        .iter()
        .enumerate()
        .map(|(a, p)| p + SVector::from_column_slice(&u0[a * D..a * D + D]))
        .collect();
    let spin = DVector::from_fn(m, |i, _| {
        let p = current[i / D];
        match i % D {
            0 => -p[1],
            1 => p[0],
            _ => 0.0,
        }
    });
    let (f0, k) = forces_and_tangent::<D>(kind, kinematics, &x, &u0, &u0, &history);
    let fd = difference::<D>(kind, kinematics, &x, &u0, &u0, &history, &spin);
    let e = relative(&(&k * &spin), &fd);
    eprintln!("{kind:?} {kinematics:?}: rotation {e:.2e}");
    if kinematics != Kinematics::Axisymmetric {
        record("hypoelastic-tangent", "rotation", e);
        assert!(e < 1e-6, "{kind:?} {kinematics:?} rotation: {e:e}");
        // The forces turn with the body: d f = spin x f.
        let turned = DVector::from_fn(m, |i, _| match i % D {
            0 => -f0[i + 1],
            1 => f0[i - 1],
            _ => 0.0,
        });
        assert!(relative(&fd, &turned) < 1e-6, "{kind:?} {kinematics:?}");
    } else {
        // An in-plane rotation of an axisymmetric section is not rigid (it changes radii).
        record("hypoelastic-tangent", "rotation axisymmetric", e);
        assert!(
            e < 3.0 * stress / 1e6,
            "{kind:?} axisymmetric rotation: {e:e}"
        );
    }
    // In any direction the tangent leaves out only the Jaumann and volume terms, of the
    // order of stress / E.
    let fd = difference::<D>(kind, kinematics, &x, &u0, &u0, &history, &direction);
    let e = relative(&(&k * &direction), &fd);
    eprintln!("{kind:?} {kinematics:?}: pre-stressed {e:.2e}");
    record("hypoelastic-tangent", "general", e);
    assert!(
        e < 3.0 * stress / 1e6,
        "{kind:?} {kinematics:?} pre-stressed: {e:e}"
    );
}

#[test]
fn updated_lagrangian_tangent_matches_differences_of_the_forces() {
    for kinematics in [
        Kinematics::PlaneStrain,
        Kinematics::PlaneStress,
        Kinematics::Axisymmetric,
    ] {
        check::<2>(ElementKind::Tri3, kinematics);
        check::<2>(ElementKind::Quad4, kinematics);
    }
    check::<3>(ElementKind::Tet4, Kinematics::Solid);
    check::<3>(ElementKind::Hex8, Kinematics::Solid);
}

/// Without the geometric stiffness a pre-stressed body's rotation would meet no stiffness:
/// the material part alone annihilates it.
#[test]
fn the_material_part_alone_does_not_see_a_rotation() {
    let kind = ElementKind::Quad4;
    let (x, u0, history) = setup::<2>(kind, 0.0);
    let (_, k) = forces_and_tangent::<2>(kind, Kinematics::PlaneStrain, &x, &u0, &u0, &history);
    let spin = DVector::from_fn(8, |i, _| {
        let p = x[i / 2] + SVector::<f64, 2>::from_column_slice(&u0[i / 2 * 2..i / 2 * 2 + 2]);
        if i % 2 == 0 {
            -p[1]
        } else {
            p[0]
        }
    });
    assert!((&k * &spin).amax() < 1e-9 * k.amax());
}

/// A cell turned inside out by the increment, at t_alpha or at the end of the step, reports it:
/// the energy is NaN (Newton backs off on it, then the step is cut, then
/// `Error::InvertedCell`).
#[test]
fn an_inverted_cell_makes_the_energy_nan() {
    let kind = ElementKind::Quad4;
    let (x, u0, history) = setup::<2>(kind, 0.0);
    let law = Hypoelastic::new(1e6, 0.3, 1000.0, RotationUpdate::HughesWinget).unwrap();
    let body = BodyIntegration::new(Kinematics::PlaneStrain, Material::Hypoelastic(law));
    let cell: Vec<usize> = (0..4).collect();
    let energy_between = |start: &[f64], u: &[f64], end: Option<&[f64]>| {
        let mut e = 0.0;
        let mut force = vec![0.0; 8];
        let mut new_history = vec![0.0; history.len()];
        let fields = KernelFields {
            displacement: Some(u),
            start: Some(start),
            end,
            ..Default::default()
        };
        let out = CellOutput {
            history: &history,
            new_history: Some(&mut new_history),
            force: Some(&mut force),
            energy: Some(&mut e),
            ..Default::default()
        };
        cell_kernel::<2>(kind, &cell, &x, &body, &fields, out);
        e
    };
    let energy = |u: &[f64]| energy_between(&u0, u, None);
    assert!(energy(&u0).is_finite());
    // Mirror the cell through its first node: every Jacobian turns negative.
    let mirrored: Vec<f64> = (0..8)
        .map(|i| {
            let (node, k) = (i / 2, i % 2);
            let p = x[node][k] + u0[i];
            let origin = x[0][k] + u0[k];
            if k == 0 {
                u0[i] - 2.0 * (p - origin)
            } else {
                u0[i]
            }
        })
        .collect();
    assert!(energy(&mirrored).is_nan());
    // Folded at the end of the step only (fine at t_alpha): the next step would start from a
    // negative volume, so this iterate is refused too.
    assert!(energy_between(&u0, &u0, Some(&mirrored)).is_nan());
    // Already folded at the start (a state that reached it some other way).
    assert!(energy_between(&mirrored, &mirrored, None).is_nan());
}

/// The equivalent logarithmic strain of an incompressible uniaxial stretch is ln of the
/// stretch, whatever the axis; a rigid rotation strains nothing.
#[test]
fn equivalent_strain_of_a_stretch_and_a_rotation() {
    use nalgebra::{Matrix3, Rotation3, Vector3};
    for stretch in [1.1_f64, 2.0, 0.5] {
        let f = Matrix3::from_diagonal(&Vector3::new(
            1.0 / stretch.sqrt(),
            stretch,
            1.0 / stretch.sqrt(),
        ));
        let turned = Rotation3::from_euler_angles(0.3, -0.7, 1.1).into_inner() * f;
        for g in [f, turned] {
            let e = super::equivalent_log_strain(&g);
            assert!(
                (e - stretch.ln().abs()).abs() < 1e-12,
                "{e} vs {}",
                stretch.ln()
            );
        }
    }
    let rotation = Rotation3::from_euler_angles(0.2, 0.4, -0.9).into_inner();
    assert!(super::equivalent_log_strain(&rotation) < 1e-12);
    assert!(super::equivalent_log_strain(&-Matrix3::identity()).is_nan());
}

/// The geometric stiffness written out against its definition, entry by entry:
/// `h(b, i) : (h(a, j) sigma)` with `h(a, i)` the 3 x 3 gradient of a unit displacement `e_i`
/// of node `a` (the hoop term included). The differences above cannot see the axisymmetric
/// hoop term (it is of the order stress / E, inside their tolerance); this can.
#[test]
fn the_geometric_stiffness_is_its_definition() {
    fn compare<const D: usize>(kinematics: Kinematics)
    where
        Dim<D>: SpatialDim<D>,
    {
        let n = 4;
        let shape: Vec<f64> = (0..n).map(|a| 0.1 + 0.2 * a as f64).collect();
        let grads: Vec<SVector<f64, D>> = (0..n)
            .map(|a| SVector::from_fn(|i, _| ((a * 5 + i * 3) % 7) as f64 - 3.1))
            .collect();
        let stress =
            Voigt::from_fn(|i, _| 1e4 * (1.0 + i as f64) * if i % 2 == 0 { 1.0 } else { -0.7 });
        let (r, weight) = (0.37, 0.8);
        let mut k = [[0.0f64; MAX_DOFS]; MAX_DOFS];
        geometric_stiffness::<D>(kinematics, &shape, &grads, r, &stress, weight, &mut k);
        let sigma = crate::material::stress_tensor(&stress);
        let unit = |a: usize, i: usize| {
            let mut e = SVector::<f64, D>::zeros();
            e[i] = 1.0;
            <Dim<D>>::gradient_3d(kinematics, shape[a], &grads[a], r, &e)
        };
        let mut hoop_seen = 0.0f64;
        for a in 0..n {
            for j in 0..D {
                for b in a..n {
                    for i in 0..D {
                        let exact = weight * unit(b, i).component_mul(&(unit(a, j) * sigma)).sum();
                        let got = k[b * D + i][a * D + j];
                        assert!(
                            (got - exact).abs() <= 1e-12 * exact.abs().max(1e3),
                            "{kinematics:?} ({b},{i}) ({a},{j}): {got} against {exact}"
                        );
                        if i == 0 && j == 0 {
                            hoop_seen =
                                hoop_seen.max((unit(b, 0)[(2, 2)] * unit(a, 0)[(2, 2)]).abs());
                        }
                    }
                }
            }
        }
        assert_eq!(hoop_seen > 0.0, kinematics == Kinematics::Axisymmetric);
    }
    compare::<2>(Kinematics::PlaneStrain);
    compare::<2>(Kinematics::PlaneStress);
    compare::<2>(Kinematics::Axisymmetric);
    compare::<3>(Kinematics::Solid);
}

/// The chunked symmetric product (large matrices) agrees with the one-pass product to
/// round-off and has the same bits on 1, 2 and 4 threads.
#[test]
fn the_chunked_symmetric_product_agrees_and_ignores_the_thread_count() {
    use faer::sparse::Triplet;
    let n = 3000;
    let mut triplets = Vec::new();
    for j in 0..n {
        triplets.push(Triplet::new(j, j, 4.0 + (j % 7) as f64));
        for d in [1, 5, 37, 400] {
            if j + d < n {
                triplets.push(Triplet::new(j + d, j, -0.3 - 1e-3 * (d as f64)));
            }
        }
    }
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets).unwrap();
    let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
    let start: Vec<f64> = (0..n).map(|i| (i as f64 * 0.11).cos()).collect();
    let mut expected = start.clone();
    lower_columns_mul_add(&a, &x, -0.7, 0..n, &mut expected, 0);
    let mut results = Vec::new();
    for threads in [1, 2, 4] {
        let mut y = start.clone();
        crate::on_threads(threads, || chunked_mul_add(&a, &x, -0.7, &mut y));
        results.push(y);
    }
    let difference = results[0]
        .iter()
        .zip(&expected)
        .map(|(p, q)| (p - q).abs())
        .fold(0.0, f64::max);
    assert!(difference < 1e-13, "{difference}");
    for y in &results[1..] {
        assert!(y
            .iter()
            .zip(&results[0])
            .all(|(p, q)| p.to_bits() == q.to_bits()));
    }
}
