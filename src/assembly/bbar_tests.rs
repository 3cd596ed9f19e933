//! The element kernel's tangent on the B-bar path (the cell-averaged volumetric strain of
//! Quad4 and Hex8 cells) against central differences of its own forces, column by column
//! (issue 11): Norton-Hoff, whose tangent carries the derivative of its viscosity, and the
//! elastic laws at nu = 0.499, in plane strain, axisymmetric and solid kinematics.

use nalgebra::{DMatrix, DVector, SVector};

use super::*;
use crate::material::{Hypoelastic, LinearElastic, NortonHoff, RotationUpdate};

/// Largest `|K - FD|` entry over the largest `|K|` entry allowed.
const TOLERANCE: f64 = 1e-6;

/// The difference step over the largest nodal value of the differentiated field (fields and
/// cells are of unit size). Central differences err by the truncation, `STEP^2` times the
/// third derivative (Norton-Hoff's power law: 2e-8 at 1e-4), plus the round-off,
/// `f64::EPSILON / STEP` times the forces over the tangent (5e-10 at 1e-6); at 1e-5 both
/// measured under 3e-10, more than three decades under `TOLERANCE`.
const STEP: f64 = 1e-5;

/// The field the forces are differentiated in.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Field {
    Displacement,
    Velocity,
}

/// One distorted cell, off the axis, and a fixed state to integrate it at.
struct Cell<const D: usize> {
    kind: ElementKind,
    x: Vec<SVector<f64, D>>,
    /// Displacement at the start of the step (the reference of updated-Lagrangian laws) (m).
    start: Vec<f64>,
    /// Displacement at t_alpha (m).
    u: Vec<f64>,
    /// Velocity at t_alpha (m/s).
    v: Vec<f64>,
}

/// Uniform numbers in [-1, 1), the same every run.
fn noise(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed;
    move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

fn distorted<const D: usize>(kind: ElementKind) -> Cell<D> {
    let mut rand = noise(kind.nodes() as u64 * 31 + D as u64);
    assert!(
        matches!(kind, ElementKind::Quad4 | ElementKind::Hex8),
        "B-bar is for Quad4 and Hex8"
    );
    let corners = super::tests::corners(kind);
    // Every node moved by up to 0.1 m more, and the cell moved off the axis (r in [0.9, 2.3]).
    let x: Vec<SVector<f64, D>> = corners
        .iter()
        .map(|c| SVector::from_fn(|i, _| c[i] + 0.1 * rand() + if i == 0 { 1.0 } else { 0.0 }))
        .collect();
    let m = kind.nodes() * D;
    let start: Vec<f64> = (0..m).map(|_| 0.05 * rand()).collect();
    let u: Vec<f64> = start.iter().map(|s| s + 0.02 * rand()).collect();
    let v: Vec<f64> = (0..m).map(|_| 0.5 * rand()).collect();
    Cell {
        kind,
        x,
        start,
        u,
        v,
    }
}

/// The cell's forces and its tangent with `weights` (on `dsigma/deps`, `dsigma/deps_dot`) at
/// displacement `u` and velocity `v`.
fn forces_and_tangent<const D: usize>(
    cell: &Cell<D>,
    body: &BodyIntegration,
    u: &[f64],
    v: &[f64],
    weights: (f64, f64),
    secant: bool,
) -> (DVector<f64>, DMatrix<f64>)
where
    Dim<D>: SpatialDim<D>,
{
    let nodes: Vec<usize> = (0..cell.kind.nodes()).collect();
    let m = nodes.len() * D;
    let history = vec![0.0; body.history_per_cell(cell.kind)];
    let mut new_history = history.clone();
    let mut values = vec![0.0; m * (m + 1) / 2];
    let mut force = vec![0.0; m];
    let fields = KernelFields {
        displacement: Some(u),
        velocity: Some(v),
        weights,
        start: Some(&cell.start),
        end: None,
        time_step: 1e-3,
        alpha: 0.75,
        secant,
    };
    let out = CellOutput {
        history: &history,
        new_history: Some(&mut new_history),
        tangent: Some(&mut values),
        force: Some(&mut force),
        ..Default::default()
    };
    cell_kernel::<D>(cell.kind, &nodes, &cell.x, body, &fields, out);
    (
        DVector::from_vec(force),
        super::tests::symmetric_from_lower::<D>(&nodes, &values),
    )
}

/// The tangent (weight 1 on the derivative in `field`), the central differences of the forces
/// in each dof of `field` (column j: dof j), and the largest entry of their difference over
/// the tangent's largest entry, with where it is.
struct Comparison {
    tangent: DMatrix<f64>,
    error: f64,
    at: (usize, usize),
}

impl std::fmt::Debug for Comparison {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:.2e} at {:?}", self.error, self.at)
    }
}

fn compare<const D: usize>(
    cell: &Cell<D>,
    body: &BodyIntegration,
    field: Field,
    secant: bool,
) -> Comparison
where
    Dim<D>: SpatialDim<D>,
{
    let weights = match field {
        Field::Displacement => (1.0, 0.0),
        Field::Velocity => (0.0, 1.0),
    };
    let (_, k) = forces_and_tangent(cell, body, &cell.u, &cell.v, weights, secant);
    let base = match field {
        Field::Displacement => &cell.u,
        Field::Velocity => &cell.v,
    };
    let h = STEP * base.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    let m = base.len();
    let mut fd = DMatrix::zeros(m, m);
    for j in 0..m {
        let at = |sign: f64| {
            let mut w = base.clone();
            w[j] += sign * h;
            let (u, v) = match field {
                Field::Displacement => (&w, &cell.v),
                Field::Velocity => (&cell.u, &w),
            };
            forces_and_tangent(cell, body, u, v, weights, false).0
        };
        fd.set_column(j, &((at(1.0) - at(-1.0)) / (2.0 * h)));
    }
    let difference = &k - &fd;
    let at = difference.iamax_full();
    Comparison {
        error: difference[at] / k.amax(),
        at,
        tangent: k,
    }
}

/// The tangent's largest eigenvalue over its second: one volumetric constraint per cell
/// (B-bar) makes a single eigenvalue of the order of the bulk modulus (or penalty), full
/// integration one per quadrature point (with B-bar switched off in the kernel, 4.8 instead of
/// 500 for the Quad4 in plane strain at nu = 0.499).
fn volumetric_separation(k: &DMatrix<f64>) -> f64 {
    let sym = (k + k.transpose()) * 0.5;
    let mut e: Vec<f64> = sym.symmetric_eigen().eigenvalues.iter().copied().collect();
    e.sort_by(|a, b| b.total_cmp(a));
    e[0] / e[1]
}

/// The three B-bar cases: Quad4 in plane strain and axisymmetric, Hex8 in 3D.
fn for_each_case(mut f: impl FnMut(&dyn Fn(Material, Field, bool) -> (Comparison, String))) {
    fn run<const D: usize>(
        kind: ElementKind,
        kinematics: Kinematics,
    ) -> impl Fn(Material, Field, bool) -> (Comparison, String)
    where
        Dim<D>: SpatialDim<D>,
    {
        move |material, field, secant| {
            let body = BodyIntegration::new(kinematics, material);
            // The path under test: the kernel averages the volumetric strain of these.
            assert!(body.law.volumetric_average(), "{material:?}");
            let mut cell = distorted::<D>(kind);
            if matches!(material, Material::Hypoelastic(_)) {
                // At the start of the step: unstressed, where its tangent is exact.
                cell.u = cell.start.clone();
            }
            let c = compare(&cell, &body, field, secant);
            (c, format!("{kind:?} {kinematics:?} {field:?}"))
        }
    }
    f(&run::<2>(ElementKind::Quad4, Kinematics::PlaneStrain));
    f(&run::<2>(ElementKind::Quad4, Kinematics::Axisymmetric));
    f(&run::<3>(ElementKind::Hex8, Kinematics::Solid));
}

/// Norton-Hoff: the forces' derivative in the velocity at a fixed configuration is the whole
/// viscous tangent, the derivative of the rate-dependent viscosity included (the derivative
/// through the configuration is left out on purpose for flow laws: see the kernel).
#[test]
fn norton_hoff_tangent_on_the_bbar_path_matches_differences() {
    // Rates of about 0.5 1/s give a viscosity near 1e6 Pa s: penalties 10 times that (the
    // deviatoric, non-linear part is a tenth of the tangent) and 1e4 times (as in the scenes).
    for penalty in [1e7, 1e10] {
        let law = Material::NortonHoff(NortonHoff::new(1e6, 0.2, 7800.0, penalty).unwrap());
        for_each_case(|run| {
            let (c, case) = run(law, Field::Velocity, false);
            eprintln!("Norton-Hoff, penalty {penalty:e}, {case}: {c:?}");
            assert!(
                c.error.abs() < TOLERANCE,
                "penalty {penalty:e}, {case}: {c:?}"
            );
            if penalty > 1e9 {
                let s = volumetric_separation(&c.tangent);
                assert!(s > 50.0, "{case}: {s}");
            } else {
                // The secant tangent (without the viscosity's derivative) fails the check by
                // 0.15: the check sees that term.
                let (secant, _) = run(law, Field::Velocity, true);
                assert!(secant.error.abs() > 1e3 * TOLERANCE, "{case}: {secant:?}");
            }
        });
    }
}

/// The elastic laws at nu = 0.499 (B-bar from nu = 0.4): the small-strain law at a displaced
/// state, the hypoelastic one at the start of a step from a displaced configuration (no
/// stress yet: its tangent is exact there; see `tests.rs` for the pre-stressed case).
#[test]
fn nearly_incompressible_elastic_tangent_on_the_bbar_path_matches_differences() {
    let elastic = LinearElastic::new(1e6, 0.499, 1000.0).unwrap();
    let hypoelastic = Hypoelastic::new(1e6, 0.499, 1000.0, RotationUpdate::HughesWinget).unwrap();
    for (name, law) in [
        ("linear elastic", Material::LinearElastic(elastic)),
        ("hypoelastic", Material::Hypoelastic(hypoelastic)),
    ] {
        for_each_case(|run| {
            let (c, case) = run(law, Field::Displacement, false);
            eprintln!("{name}, {case}: {c:?}");
            assert!(c.error.abs() < TOLERANCE, "{name}, {case}: {c:?}");
            let s = volumetric_separation(&c.tangent);
            assert!(s > 50.0, "{name}, {case}: {s}");
        });
    }
}
