//! The foundation: elements, assembly and the space-time velocity step against analytic
//! solutions and conserved quantities, each in 2D and 3D.

use crate::common;

use common::verify::record;
use common::{block, dense, vec_d};
use nalgebra::{DMatrix, DVector, SMatrix, SVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use softway::dim::{Dim, Kinematics, SpatialDim};
use softway::prelude::*;

fn material(e: f64, nu: f64, rho: f64) -> Material {
    Material::LinearElastic(LinearElastic::new(e, nu, rho).unwrap())
}

/// Moves interior nodes randomly (keeps the boundary, so the domain is unchanged).
fn distort<const D: usize>(mesh: &mut Mesh<D>, amount: f64, seed: u64)
where
    Dim<D>: SpatialDim<D>,
{
    let boundary = mesh.boundary_nodes();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for n in 0..mesh.nodes.len() {
        if boundary.binary_search(&n).is_err() {
            for k in 0..D {
                mesh.nodes[n][k] += amount * (rng.random::<f64>() - 0.5);
            }
        }
    }
}

fn kinematics_for<const D: usize>() -> Vec<Kinematics> {
    if D == 2 {
        vec![Kinematics::PlaneStrain, Kinematics::PlaneStress]
    } else {
        vec![Kinematics::Solid]
    }
}

/// Constant strain: a linear displacement on the boundary must be reproduced exactly inside,
/// with zero interior residual.
fn patch_test<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let grad = SMatrix::<f64, D, D>::from_fn(|_, _| rng.random::<f64>() - 0.5) * 1e-3;
    for simplex in [true, false] {
        for kin in kinematics_for::<D>() {
            let mut mesh = block::<D>([1.0, 0.8, 0.6], [4, 3, 3], simplex);
            distort(&mut mesh, 0.08, 3);
            let exact: Vec<f64> = mesh
                .nodes
                .iter()
                .flat_map(|x| (grad * x).iter().copied().collect::<Vec<_>>())
                .collect();
            patch_solve(mesh, kin, &exact);
        }
    }
}

fn patch_solve<const D: usize>(mesh: Mesh<D>, kin: Kinematics, exact: &[f64])
where
    Dim<D>: SpatialDim<D>,
{
    let boundary = mesh.boundary_nodes();
    let sim = Simulation::<D>::builder()
        .kinematics(kin)
        .body(Body::new("patch", mesh, material(2e11, 0.3, 7800.0)))
        .build()
        .unwrap();
    let k = dense(sim.stiffness_matrix());
    // K u_exact vanishes at interior dofs.
    let f = &k * DVector::from_column_slice(exact);
    let free: Vec<usize> = (0..exact.len())
        .filter(|i| boundary.binary_search(&(i / D)).is_err())
        .collect();
    let scale = k.amax() * exact.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let residual = free.iter().map(|&i| f[i].abs()).fold(0.0, f64::max);
    record("patch", "residual", residual / scale);
    for &i in &free {
        assert!(
            f[i].abs() < 1e-10 * scale,
            "{kin:?}: interior residual {}",
            f[i]
        );
    }
    // Solving with the boundary values reproduces the field.
    let fixed: Vec<usize> = (0..exact.len()).filter(|i| !free.contains(i)).collect();
    let kff = DMatrix::from_fn(free.len(), free.len(), |a, b| k[(free[a], free[b])]);
    let rhs = DVector::from_fn(free.len(), |a, _| {
        -fixed
            .iter()
            .map(|&j| k[(free[a], j)] * exact[j])
            .sum::<f64>()
    });
    let u = kff.lu().solve(&rhs).unwrap();
    let off = free
        .iter()
        .enumerate()
        .map(|(a, &i)| (u[a] - exact[i]).abs());
    record("patch", "displacement (m)", off.fold(0.0, f64::max));
    for (a, &i) in free.iter().enumerate() {
        assert!(
            (u[a] - exact[i]).abs() < 1e-9 * 1e-3,
            "{kin:?}: {} vs {}",
            u[a],
            exact[i]
        );
    }
    // Internal forces from the stresses equal K u.
    let fi = sim.internal_forces(exact);
    let off = (0..exact.len()).map(|i| (fi[i] - f[i]).abs());
    record("patch", "f_int - K u", off.fold(0.0, f64::max) / scale);
    for i in 0..exact.len() {
        assert!((fi[i] - f[i]).abs() < 1e-9 * scale);
    }
}

#[test]
fn axisymmetric_patch_test() {
    // u_r = a r, u_z = c z: constant strain (a, a, c) and sigma_rr = sigma_tt, in equilibrium.
    let mesh = block::<2>([1.0, 0.8, 0.0], [4, 3, 1], false);
    let mut mesh = mesh;
    mesh.translate(&nalgebra::Vector2::new(0.5, 0.0));
    let (a, c) = (1e-3, -2e-3);
    let exact: Vec<f64> = mesh.nodes.iter().flat_map(|x| [a * x.x, c * x.y]).collect();
    patch_solve(mesh, Kinematics::Axisymmetric, &exact);
}

/// K equals the derivative of the internal forces (central finite differences).
fn stiffness_matches_finite_differences<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    for simplex in [true, false] {
        let mut mesh = block::<D>([1.0, 0.5, 0.5], [3, 2, 2], simplex);
        distort(&mut mesh, 0.05, 11);
        let sim = Simulation::<D>::builder()
            .body(Body::new("b", mesh, material(1e7, 0.25, 1.0)))
            .build()
            .unwrap();
        let n = sim.node_count() * D;
        let k = dense(sim.stiffness_matrix());
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let u: Vec<f64> = (0..n).map(|_| rng.random::<f64>() * 1e-3).collect();
        let eps = 1e-6;
        for j in (0..n).step_by(5) {
            let (mut up, mut um) = (u.clone(), u.clone());
            up[j] += eps;
            um[j] -= eps;
            let (fp, fm) = (sim.internal_forces(&up), sim.internal_forces(&um));
            let off = (0..n).map(|i| ((fp[i] - fm[i]) / (2.0 * eps) - k[(i, j)]).abs());
            record("stiffness", "K", off.fold(0.0, f64::max) / k.amax());
            for i in 0..n {
                let fd = (fp[i] - fm[i]) / (2.0 * eps);
                assert!(
                    (fd - k[(i, j)]).abs() <= 1e-6 * k.amax(),
                    "K[{i},{j}] {} vs fd {fd}",
                    k[(i, j)]
                );
            }
        }
    }
}

/// e_k^T M e_k is the body's mass for every direction k, consistent and lumped.
fn mass_matrix_sums_to_body_mass<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    for simplex in [true, false] {
        for lumped in [false, true] {
            let mut mesh = block::<D>([2.0, 0.5, 0.25], [4, 2, 2], simplex);
            distort(&mut mesh, 0.05, 1);
            let volume = if D == 2 { 1.0 } else { 0.25 };
            let rho = 2500.0;
            let sim = Simulation::<D>::builder()
                .mass(if lumped {
                    MassKind::Lumped
                } else {
                    MassKind::Consistent
                })
                .body(Body::new("b", mesh, material(1e9, 0.3, rho)))
                .build()
                .unwrap();
            let m = dense(sim.mass_matrix());
            let n = sim.node_count();
            for k in 0..D {
                let e = DVector::from_fn(n * D, |i, _| if i % D == k { 1.0 } else { 0.0 });
                let total = e.dot(&(&m * &e));
                record("mass", "mass", (total - rho * volume) / (rho * volume));
                assert!(
                    (total - rho * volume).abs() < 1e-10 * rho * volume,
                    "{total}"
                );
            }
            if lumped {
                assert_eq!(m.iter().filter(|v| **v != 0.0).count(), n * D);
            }
        }
    }
}

#[test]
fn axisymmetric_mass_is_the_ring_mass() {
    // An annular cross-section r in [1, 3], z in [0, 2]: mass = rho 2 pi r_mean A.
    let mut mesh = block::<2>([2.0, 2.0, 0.0], [4, 3, 1], false);
    mesh.translate(&nalgebra::Vector2::new(1.0, 0.0));
    let sim = Simulation2::builder()
        .kinematics(Kinematics::Axisymmetric)
        .body(Body::new("ring", mesh, material(1e9, 0.3, 10.0)))
        .build()
        .unwrap();
    let expected = 10.0 * 2.0 * std::f64::consts::PI * 2.0 * 4.0;
    let got = sim.body_mass(sim.body_ids()[0]).unwrap();
    record("mass", "axisymmetric", (got - expected) / expected);
    assert!(
        (got - expected).abs() < 1e-10 * expected,
        "{got} vs {expected}"
    );
}

/// A free body moving at a uniform velocity: exact displacement, no strain energy, momentum
/// kept to round-off.
fn rigid_translation_is_exact<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let mut mesh = block::<D>([1.0, 0.4, 0.3], [5, 2, 2], false);
    distort(&mut mesh, 0.03, 9);
    let v = vec_d::<D>([3.0, -2.0, 1.0]);
    let h = 1e-3;
    let mut sim = Simulation::<D>::builder()
        .time_step(h)
        .body(Body::new("b", mesh, material(1e8, 0.3, 1000.0)).with_velocity(v))
        .build()
        .unwrap();
    let m = dense(sim.mass_matrix());
    let momentum = |s: &Simulation<D>| {
        let p = &m * DVector::from_column_slice(&s.state().velocity);
        SVector::<f64, D>::from_fn(|k, _| (0..s.node_count()).map(|n| p[n * D + k]).sum())
    };
    let p0 = momentum(&sim);
    let e0 = sim.energies().kinetic;
    for _ in 0..50 {
        sim.step().unwrap();
    }
    let t = sim.state().time;
    let off = (0..sim.node_count())
        .map(|n| (sim.displacement(sim.body_ids()[0], n).unwrap() - v * t).norm());
    record("rigid", "u", off.fold(0.0, f64::max) / (v.norm() * t));
    for n in 0..sim.node_count() {
        let u = sim.displacement(sim.body_ids()[0], n).unwrap();
        assert!((u - v * t).norm() < 1e-12 * v.norm() * t);
    }
    let e = sim.energies();
    record("rigid", "strain energy", e.internal / e0);
    record("rigid", "kinetic", (e.kinetic - e0).abs() / e0);
    record(
        "rigid",
        "momentum",
        (momentum(&sim) - p0).norm() / p0.norm(),
    );
    assert!(e.internal < 1e-20 * e0, "strain energy {}", e.internal);
    assert!((e.kinetic - e0).abs() < 1e-12 * e0);
    assert!((momentum(&sim) - p0).norm() < 1e-12 * p0.norm());
}

/// Free fall: the velocity is exact; the displacement has the O(h) offset of method.md:
/// u_n = g h^2 (n^2/2 + (beta - 1/2) n).
fn free_fall_matches_the_scheme<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    for beta in [Beta::Energy, Beta::Trapezoid] {
        let g = vec_d::<D>([0.0, -9.81, 0.0]);
        let h = 0.01;
        let mut sim = Simulation::<D>::builder()
            .time_step(h)
            .scheme(0.75, beta)
            .gravity(g)
            .body(Body::new(
                "b",
                block::<D>([1.0, 1.0, 1.0], [2, 2, 2], true),
                material(1e6, 0.3, 1.0),
            ))
            .build()
            .unwrap();
        let b = sim.settings().scheme.beta;
        for n in 1..=20 {
            sim.step().unwrap();
            let nf = n as f64;
            let u = sim.displacement(sim.body_ids()[0], 0).unwrap();
            let v = sim.velocity(sim.body_ids()[0], 0).unwrap();
            // Exact up to the Newton tolerance (1e-8 relative) accumulated over the steps.
            record(
                "free-fall",
                "v",
                (v - g * h * nf).norm() / (g.norm() * h * nf),
            );
            assert!(
                (v - g * h * nf).norm() < 1e-7 * g.norm() * h * nf,
                "{v:?} vs {:?}",
                g * h * nf
            );
            let expected = g * h * h * (nf * nf / 2.0 + (b - 0.5) * nf);
            record("free-fall", "u", (u - expected).norm() / expected.norm());
            assert!(
                (u - expected).norm() < 1e-7 * expected.norm(),
                "{u:?} vs {expected:?}"
            );
        }
        let e = sim.energies();
        if beta == Beta::Trapezoid {
            // Exact integration: the work of gravity equals the kinetic energy.
            assert!((e.kinetic - e.external_work).abs() < 1e-9 * e.kinetic);
        }
    }
}

/// Period of a fixed-free bar (nu = 0) driven in its first mode: 4 L / c.
fn bar_period<const D: usize>(elements: usize, steps_per_period: usize) -> f64
where
    Dim<D>: SpatialDim<D>,
{
    let (length, e, rho): (f64, f64, f64) = (1.0, 1.0, 1.0);
    let period = 4.0 * length / (e / rho).sqrt();
    let h = period / steps_per_period as f64;
    let mesh = block::<D>([length, 0.05, 0.05], [elements, 1, 1], false);
    let body = Body::new("bar", mesh, material(e, 0.0, rho)).with_constraint_in_box(
        vec_d::<D>([-1e-9, -1.0, -1.0]),
        vec_d::<D>([1e-9, 1.0, 1.0]),
        std::array::from_fn(|k| if k == 0 { Some(0.0) } else { None }),
    );
    let mut sim = Simulation::<D>::builder()
        .time_step(h)
        .body(body)
        .build()
        .unwrap();
    let id = sim.body_ids()[0];
    let x: Vec<SVector<f64, D>> = sim.bodies()[0].mesh.nodes.clone();
    for (n, p) in x.iter().enumerate() {
        let v = vec_d::<D>([
            1e-3 * (std::f64::consts::FRAC_PI_2 * p[0] / length).sin(),
            0.0,
            0.0,
        ]);
        sim.set_velocity(id, n, v).unwrap();
    }
    let tip = (0..x.len())
        .find(|&n| (x[n][0] - length).abs() < 1e-12)
        .unwrap();
    let mut crossings = Vec::new();
    let mut previous: (f64, f64) = (0.0, 0.0);
    while crossings.len() < 3 {
        sim.step().unwrap();
        let now = (sim.state().time, sim.displacement(id, tip).unwrap()[0]);
        if previous.1 != 0.0 && previous.1.signum() != now.1.signum() {
            crossings.push(previous.0 + (now.0 - previous.0) * previous.1 / (previous.1 - now.1));
        }
        previous = now;
        assert!(sim.state().time < 3.0 * period, "no oscillation found");
    }
    let measured = crossings[2] - crossings[0];
    (measured - period).abs() / period
}

fn bar_period_converges_to_4l_over_c<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let coarse = bar_period::<D>(8, 24);
    let fine = bar_period::<D>(64, 400);
    record("bar-period", "64 cells", fine);
    record("bar-period", "8 cells", coarse);
    assert!(fine < 0.01, "fine error {fine}");
    assert!(fine < coarse / 4.0, "coarse {coarse}, fine {fine}");
}

/// A clamped cantilever kicked sideways, stepped at 20x the explicit stable step.
fn cantilever<const D: usize>(alpha: f64) -> (Simulation<D>, f64)
where
    Dim<D>: SpatialDim<D>,
{
    let mesh = block::<D>([1.0, 0.1, 0.1], [10, 2, 2], false);
    let mat = LinearElastic::new(1e6, 0.3, 1000.0).unwrap();
    let c = mat.wave_speed(if D == 2 {
        Kinematics::PlaneStrain
    } else {
        Kinematics::Solid
    });
    let h_explicit = 0.05 / c; // smallest element edge / wave speed
    let body = Body::new("beam", mesh, Material::LinearElastic(mat))
        .with_velocity(vec_d::<D>([0.0, 0.1, 0.0]))
        .with_constraint_in_box(
            vec_d::<D>([-1e-9, -1.0, -1.0]),
            vec_d::<D>([1e-9, 1.0, 1.0]),
            [Some(0.0); D],
        );
    let sim = Simulation::<D>::builder()
        .time_step(20.0 * h_explicit)
        .scheme(alpha, Beta::Energy)
        .body(body)
        .build()
        .unwrap();
    (sim, h_explicit)
}

fn energy_stays_bounded_with_large_steps<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let (mut sim, _) = cantilever::<D>(0.75);
    let e0 = sim.energies().total();
    let mut first_half: f64 = 0.0;
    let mut second_half: f64 = 0.0;
    for s in 0..1000 {
        let e = sim.step().unwrap().energies.total();
        if s < 500 {
            first_half = first_half.max(e);
        } else {
            second_half = second_half.max(e);
        }
    }
    record(
        "large-steps",
        "max E second/first half",
        second_half / first_half,
    );
    assert!(
        second_half <= 1.05 * first_half,
        "energy grows: {first_half} then {second_half} (E0 {e0})"
    );
    assert!(sim.warnings().is_empty());
}

fn energy_blows_up_below_the_stability_limit<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let (mut sim, _) = cantilever::<D>(0.5);
    assert!(!sim.warnings().is_empty(), "alpha = 0.5 must warn");
    for _ in 0..1000 {
        match sim.step() {
            Ok(r) => assert!(r.energies.total().is_finite()),
            Err(Error::Unstable { step, detail, .. }) => {
                record("unstable", "stopped at step", step as f64);
                assert!(step > 1 && detail.contains("exceeds 1e6"), "{detail}");
                // The state is the last good one.
                assert!(sim.state().velocity.iter().all(|v| v.is_finite()));
                assert_eq!(sim.state().step, step - 1);
                return;
            }
            Err(e) => panic!("{e}"),
        }
    }
    panic!("alpha = 0.5 at 20x the explicit step did not blow up");
}

#[test]
fn thick_cylinder_matches_lame() {
    // Axisymmetric thick-walled cylinder, bore pushed out at velocity V, ends held (u_z = 0),
    // quasi-static (negligible inertia). Lame with sigma_rr(b) = 0:
    // u(r) = A r + B / r, A = mu B / ((lambda + mu) b^2), u(a) = u_a.
    let (a, b, height) = (1.0, 2.0, 0.2);
    let mut mesh = block::<2>([b - a, height, 0.0], [40, 2, 1], false);
    mesh.translate(&nalgebra::Vector2::new(a, 0.0));
    let mat = LinearElastic::new(1e3, 0.3, 1e-9).unwrap();
    let (v, steps, h) = (1e-3, 100, 0.01);
    let body = Body::new("tube", mesh, Material::LinearElastic(mat))
        .with_constraint_in_box(
            vec_d::<2>([a - 1e-9, -1.0, 0.0]),
            vec_d::<2>([a + 1e-9, 1.0, 0.0]),
            [Some(v), None],
        )
        .with_constraint_in_box(
            vec_d::<2>([0.0, -1e-9, 0.0]),
            vec_d::<2>([9.0, 1e-9, 0.0]),
            [None, Some(0.0)],
        )
        .with_constraint_in_box(
            vec_d::<2>([0.0, height - 1e-9, 0.0]),
            vec_d::<2>([9.0, height + 1e-9, 0.0]),
            [None, Some(0.0)],
        );
    // Inside the stability window, where stiff (here: inertia-free) modes are damped.
    let mut sim = Simulation2::builder()
        .kinematics(Kinematics::Axisymmetric)
        .time_step(h)
        .scheme(0.8, Beta::Value(0.3))
        .body(body)
        .build()
        .unwrap();
    for _ in 0..steps {
        sim.step().unwrap();
    }
    let u_a = v * h * steps as f64;
    let (lambda, mu) = (mat.lambda(), mat.shear_modulus());
    let bb = u_a / (mu * a / ((lambda + mu) * b * b) + 1.0 / a);
    let aa = mu * bb / ((lambda + mu) * b * b);
    for n in 0..sim.node_count() {
        let x = sim.reference_positions()[n];
        let u = sim.displacement(sim.body_ids()[0], n).unwrap();
        let exact = aa * x.x + bb / x.x;
        record("lame", "u_r", (u.x - exact).abs() / u_a);
        assert!(
            (u.x - exact).abs() < 0.01 * u_a,
            "r = {}: {} vs {exact}",
            x.x,
            u.x
        );
        assert!(u.y.abs() < 1e-6 * u_a);
    }
}

#[cfg(feature = "parallel")]
#[test]
fn assembly_is_identical_with_one_and_two_threads() {
    let build = || {
        Simulation3::builder()
            .body(Body::new(
                "b",
                block::<3>([1.0, 1.0, 1.0], [6, 6, 6], true),
                material(1e9, 0.3, 1.0),
            ))
            .build()
            .unwrap()
    };
    let run = |threads: usize| {
        common::on_threads(threads, || {
            let s = build();
            (
                s.stiffness_matrix().values().to_vec(),
                s.mass_matrix().values().to_vec(),
            )
        })
    };
    let (k1, m1) = run(1);
    let (k2, m2) = run(2);
    let differ = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .filter(|(x, y)| x.to_bits() != y.to_bits())
            .count()
    };
    record(
        "assembly-threads",
        "differing values",
        (differ(&k1, &k2) + differ(&m1, &m2)) as f64,
    );
    assert!(k1.iter().zip(&k2).all(|(a, b)| a.to_bits() == b.to_bits()));
    assert!(m1.iter().zip(&m2).all(|(a, b)| a.to_bits() == b.to_bits()));
}

both_dims!(
    patch_test,
    stiffness_matches_finite_differences,
    mass_matrix_sums_to_body_mass,
    rigid_translation_is_exact,
    free_fall_matches_the_scheme,
    bar_period_converges_to_4l_over_c,
    energy_stays_bounded_with_large_steps,
    energy_blows_up_below_the_stability_limit,
);
