//! Contact resolution against analytic solutions, in 2D and 3D: the elastic bar hitting a rigid
//! wall (Hughes et al. 1976), two bars hitting head on, blocks on an incline with Coulomb,
//! Tresca and viscoplastic friction, and the energy account.

mod common;

use common::{block, vec_d};
use nalgebra::SVector;
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

both_dims!(
    bar_impact_soft_way,
    bar_impact_implicit_projection,
    bar_impact_augmented_lagrangian
);

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
