//! Contact resolution against analytic solutions, in 2D and 3D: the elastic bar hitting a rigid
//! wall (Hughes et al. 1976), two bars hitting head on, blocks on an incline with Coulomb,
//! Tresca and viscoplastic friction, and the energy account.

mod common;

use common::{block, vec_d};
use softway::contact::{ContactMethod, ContactSettings, FrictionLaw, Obstacle, ObstacleShape};
use softway::dim::{Dim, SpatialDim};
use softway::prelude::*;

const L: f64 = 1.0;
const V0: f64 = 0.01;
const GAP: f64 = 0.01;

fn bar_material() -> Material {
    // c = sqrt(E / rho) = 1 m/s, nu = 0: a one-dimensional bar.
    Material::LinearElastic(LinearElastic::new(1.0, 0.0, 1.0).unwrap())
}

/// Cross-section of the bar meshes [m^2] (per unit thickness in 2D).
fn section<const D: usize>() -> f64 {
    if D == 2 {
        0.1
    } else {
        0.01
    }
}

fn contact(method: ContactMethod) -> ContactSettings {
    ContactSettings {
        method,
        penalty: 1e5,
        gap_tolerance: 1e-12,
        ..ContactSettings::default()
    }
}

struct Impact {
    duration: f64,
    mean_force: f64,
    exit_velocity: f64,
    max_step_penetration: f64,
    energy_error: f64,
}

/// The bar [0, L] moving at V0 towards a wall at L + GAP; c = 1, so contact should last 2 L / c
/// with the force rho c V0 A and the bar should leave at -V0.
fn bar_impact<const D: usize>(method: ContactMethod) -> Impact
where
    Dim<D>: SpatialDim<D>,
{
    let cells = 100;
    let mesh = block::<D>([L, 0.1, 0.1], [cells, 1, 1], false);
    let h = 2.0 * L / 300.0;
    let wall = Obstacle::new(
        "wall",
        ObstacleShape::Halfspace {
            point: vec_d::<D>([L + GAP, 0.0, 0.0]),
            normal: vec_d::<D>([-1.0, 0.0, 0.0]),
        },
    );
    let mut sim = Simulation::<D>::builder()
        .time_step(h)
        .body(Body::new("bar", mesh, bar_material()).with_velocity(vec_d::<D>([V0, 0.0, 0.0])))
        .obstacle(wall)
        .contact(contact(method))
        .build()
        .unwrap();
    let e0 = sim.energies().total();
    let mass = sim.body_mass(BodyId(0));
    let (mut first, mut last) = (None, 0);
    let mut forces = Vec::new();
    let mut max_pen: f64 = 0.0;
    let mut n = 0;
    while sim.state().time < GAP / V0 + 2.0 * L + 0.5 {
        let r = sim.step().unwrap();
        n += 1;
        max_pen = max_pen.max(r.max_penetration);
        if r.contact_forces[0][0].abs() > 0.0 {
            first.get_or_insert(n);
            last = n;
            forces.push(-r.contact_forces[0][0]);
        }
    }
    let first = first.expect("the bar reaches the wall");
    // Drop the partial first and last steps from the mean force.
    let inner = &forces[2..forces.len() - 2];
    let mean_force = inner.iter().sum::<f64>() / inner.len() as f64;
    let momentum: f64 = (0..sim.node_count())
        .map(|i| sim.velocity(BodyId(0), i).unwrap()[0])
        .sum::<f64>()
        / sim.node_count() as f64;
    let _ = mass;
    Impact {
        duration: (last - first + 1) as f64 * h,
        mean_force,
        exit_velocity: momentum,
        max_step_penetration: max_pen,
        energy_error: (sim.energies().total() - e0).abs() / e0,
    }
}

fn check_impact<const D: usize>(method: ContactMethod)
where
    Dim<D>: SpatialDim<D>,
{
    let r = bar_impact::<D>(method);
    let force = 1.0 * 1.0 * V0 * section::<D>(); // rho c v0 A
    let name = method.name();
    assert!(
        (r.duration - 2.0 * L).abs() < 0.05 * 2.0 * L,
        "{name}: duration {}",
        r.duration
    );
    assert!(
        (r.mean_force - force).abs() < 0.05 * force,
        "{name}: force {} vs {force}",
        r.mean_force
    );
    assert!(
        (r.exit_velocity + V0).abs() < 0.05 * V0,
        "{name}: exit velocity {}",
        r.exit_velocity
    );
    assert!(
        r.energy_error < 0.05,
        "{name}: energy error {}",
        r.energy_error
    );
    if method == ContactMethod::ImplicitProjection {
        assert!(
            r.max_step_penetration < 1e-9 * L,
            "penetration {}",
            r.max_step_penetration
        );
    }
}

fn bar_impact_soft_way<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    check_impact::<D>(ContactMethod::SoftWay);
}

fn bar_impact_implicit_projection<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    check_impact::<D>(ContactMethod::ImplicitProjection);
}

fn bar_impact_augmented_lagrangian<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    check_impact::<D>(ContactMethod::AugmentedLagrangian);
}

#[test]
fn print_bar_impact_figures() {
    for method in [
        ContactMethod::SoftWay,
        ContactMethod::ImplicitProjection,
        ContactMethod::AugmentedLagrangian,
        ContactMethod::ExplicitProjection,
    ] {
        let r = bar_impact::<2>(method);
        println!(
            "{}: duration {:.4} (2.0), force {:.5e} ({:.5e}), exit {:.5e} ({:.1e}), penetration {:.2e}, energy error {:.3e}",
            method.name(), r.duration, r.mean_force, V0 * 0.1, r.exit_velocity, -V0, r.max_step_penetration, r.energy_error
        );
    }
}

/// Two identical bars [0, L] and [L + GAP, 2 L + GAP] meeting head on at +-V0.
fn bars_head_on<const D: usize>(method: ContactMethod)
where
    Dim<D>: SpatialDim<D>,
{
    let cells = 60;
    let left = block::<D>([L, 0.1, 0.1], [cells, 1, 1], false);
    let mut right = left.clone();
    right.translate(&vec_d::<D>([L + GAP, 0.0, 0.0]));
    let h = 2.0 * L / 200.0;
    let mut sim = Simulation::<D>::builder()
        .time_step(h)
        .body(Body::new("left", left, bar_material()).with_velocity(vec_d::<D>([V0, 0.0, 0.0])))
        .body(Body::new("right", right, bar_material()).with_velocity(vec_d::<D>([-V0, 0.0, 0.0])))
        .contact(contact(method))
        .build()
        .unwrap();
    let mean_velocity = |sim: &Simulation<D>, b: usize| -> f64 {
        let n = sim.bodies()[b].mesh.nodes.len();
        (0..n)
            .map(|i| sim.velocity(BodyId(b), i).unwrap()[0])
            .sum::<f64>()
            / n as f64
    };
    let momentum = |sim: &Simulation<D>| -> f64 {
        let ones: Vec<f64> = (0..sim.node_count() * D)
            .map(|i| if i % D == 0 { 1.0 } else { 0.0 })
            .collect();
        sim.mass_matrix().dot(&ones, &sim.state().velocity)
    };
    let p0 = momentum(&sim);
    let scale = sim.body_mass(BodyId(0)) * V0;
    let (mut first, mut last, mut n) = (None, 0, 0);
    while sim.state().time < GAP / (2.0 * V0) + 2.0 * L + 0.5 {
        let r = sim.step().unwrap();
        n += 1;
        if r.active_contacts > 0 {
            first.get_or_insert(n);
            last = n;
        }
        assert!(
            (momentum(&sim) - p0).abs() < 1e-10 * scale,
            "momentum drifts"
        );
    }
    let duration = (last - first.expect("the bars meet") + 1) as f64 * h;
    assert!(
        (duration - 2.0 * L).abs() < 0.05 * 2.0 * L,
        "{}: duration {duration}",
        method.name()
    );
    let (vl, vr) = (mean_velocity(&sim, 0), mean_velocity(&sim, 1));
    assert!(
        (vl + V0).abs() < 0.05 * V0 && (vr - V0).abs() < 0.05 * V0,
        "{}: {vl} {vr}",
        method.name()
    );
    // Symmetry: the two bars mirror each other.
    assert!(
        (vl + vr).abs() < 1e-6 * V0,
        "{}: asymmetric {vl} {vr}",
        method.name()
    );
}

fn two_bars_soft_way<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    bars_head_on::<D>(ContactMethod::SoftWay);
}

fn two_bars_implicit_projection<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    bars_head_on::<D>(ContactMethod::ImplicitProjection);
}

both_dims!(
    bar_impact_soft_way,
    bar_impact_implicit_projection,
    bar_impact_augmented_lagrangian,
    two_bars_soft_way,
    two_bars_implicit_projection,
    coulomb_incline,
    tresca_incline,
    viscoplastic_incline,
);

const G: f64 = 9.81;

/// A block resting on a plane y = 0 under gravity tilted by `theta` (it slides along +x);
/// returns its mean x velocity after `time` seconds and the simulation.
fn incline<const D: usize>(theta: f64, law: FrictionLaw, time: f64) -> (f64, Simulation<D>)
where
    Dim<D>: SpatialDim<D>,
{
    let mesh = block::<D>([0.1, 0.05, 0.05], [4, 2, 2], false);
    let ground = Obstacle::new(
        "ground",
        ObstacleShape::Halfspace {
            point: vec_d::<D>([0.0, 0.0, 0.0]),
            normal: vec_d::<D>([0.0, 1.0, 0.0]),
        },
    );
    let mut sim = Simulation::<D>::builder()
        .time_step(1e-3)
        // alpha = 1, beta = 1/2: unconditionally stable, exact under constant acceleration.
        .scheme(1.0, Beta::Trapezoid)
        .tolerance(1e-6)
        .gravity(vec_d::<D>([G * theta.sin(), -G * theta.cos(), 0.0]))
        .body(Body::new(
            "block",
            mesh,
            Material::LinearElastic(LinearElastic::new(1e7, 0.3, 1000.0).unwrap()),
        ))
        .obstacle(ground)
        .contact(ContactSettings {
            method: ContactMethod::SoftWay,
            penalty: 1e11,
            friction: law,
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    while sim.state().time < time - 1e-9 {
        sim.step().unwrap();
    }
    let n = sim.node_count();
    let vx = (0..n)
        .map(|i| sim.velocity(BodyId(0), i).unwrap()[0])
        .sum::<f64>()
        / n as f64;
    (vx, sim)
}

fn coulomb_incline<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let (theta, mu) = (30f64.to_radians(), 0.3);
    let law = FrictionLaw::Coulomb {
        coefficient: mu,
        regularization: 1e-6,
    };
    let (v, sim) = incline::<D>(theta, law, 0.3);
    let a = v / 0.3;
    let exact = G * (theta.sin() - mu * theta.cos());
    assert!(
        (a - exact).abs() < 0.02 * exact,
        "a = {a}, expected {exact}"
    );
    // Friction dissipates, and the energy account balances.
    let e = sim.energies();
    assert!(e.dissipated > 0.0);
    let balance = (e.total() - sim.initial_energy() - e.external_work + e.dissipated).abs();
    assert!(
        balance < 0.01 * e.external_work,
        "energy account off by {balance} of {}",
        e.external_work
    );
    // It sticks when tan(theta) < mu.
    let (v, _) = incline::<D>(10f64.to_radians(), law, 0.3);
    assert!(v.abs() < 1e-4, "sliding at {v} although tan(theta) < mu");
}

fn tresca_incline<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    // |F_t| = limit x contact area: a = g sin(theta) - limit A / m.
    let theta = 30f64.to_radians();
    let limit = 100.0;
    let (v, sim) = incline::<D>(
        theta,
        FrictionLaw::Tresca {
            limit,
            regularization: 1e-6,
        },
        0.3,
    );
    let area = if D == 2 { 0.1 } else { 0.1 * 0.05 };
    let mass = sim.body_mass(BodyId(0));
    let exact = G * theta.sin() - limit * area / mass;
    assert!(
        (v / 0.3 - exact).abs() < 0.02 * exact,
        "a = {}, expected {exact}",
        v / 0.3
    );
}

fn viscoplastic_incline<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    // p = 1: F_t = -a A v, so v(t) = v_T (1 - exp(-t / tau)), tau = m / (a A).
    let theta = 30f64.to_radians();
    let coefficient = 200.0;
    let law = FrictionLaw::Viscoplastic {
        coefficient,
        exponent: 1.0,
        regularization: 1e-9,
    };
    let (v, sim) = incline::<D>(theta, law, 0.3);
    let area = if D == 2 { 0.1 } else { 0.1 * 0.05 };
    let mass = sim.body_mass(BodyId(0));
    let tau = mass / (coefficient * area);
    let v_terminal = G * theta.sin() * tau;
    let exact = v_terminal * (1.0 - (-0.3 / tau).exp());
    assert!(
        (v - exact).abs() < 0.02 * exact,
        "v = {v}, expected {exact}"
    );
}

#[test]
fn axisymmetric_bar_impact() {
    // A solid cylinder (r <= 0.1 m, axis y) falling along its axis onto a rigid plane: with
    // nu = 0 the wave is one-dimensional; the force is rho c v0 pi R^2 over the whole revolution.
    let radius = 0.1;
    let mesh = block::<2>([radius, L, 0.0], [2, 100, 1], false);
    let mut mesh = mesh;
    mesh.translate(&vec_d::<2>([0.0, GAP, 0.0]));
    let floor = Obstacle::new(
        "floor",
        ObstacleShape::Halfspace {
            point: vec_d::<2>([0.0, 0.0, 0.0]),
            normal: vec_d::<2>([0.0, 1.0, 0.0]),
        },
    );
    let h = 2.0 * L / 300.0;
    let mut sim = Simulation2::builder()
        .kinematics(softway::dim::Kinematics::Axisymmetric)
        .time_step(h)
        .body(Body::new("rod", mesh, bar_material()).with_velocity(vec_d::<2>([0.0, -V0, 0.0])))
        .obstacle(floor)
        .contact(contact(ContactMethod::SoftWay))
        .build()
        .unwrap();
    let mut forces = Vec::new();
    let (mut first, mut last, mut n) = (None, 0, 0);
    while sim.state().time < GAP / V0 + 2.0 * L + 0.5 {
        let r = sim.step().unwrap();
        n += 1;
        if r.contact_forces[0][1] > 0.0 {
            first.get_or_insert(n);
            last = n;
            forces.push(r.contact_forces[0][1]);
        }
    }
    let duration = (last - first.unwrap() + 1) as f64 * h;
    let inner = &forces[2..forces.len() - 2];
    let mean = inner.iter().sum::<f64>() / inner.len() as f64;
    let exact = V0 * std::f64::consts::PI * radius * radius;
    assert!(
        (duration - 2.0 * L).abs() < 0.05 * 2.0 * L,
        "duration {duration}"
    );
    assert!(
        (mean - exact).abs() < 0.05 * exact,
        "force {mean} vs {exact}"
    );
}
