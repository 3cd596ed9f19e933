//! Contact between deformable bodies: three soft blocks (E = 1e5 Pa) dropped in a stack on a
//! floor, each offset sideways by 1 cm from the one below, in 2D and 3D. The soft way keeps
//! both passes between bodies at half the area each; it runs through the landing and the
//! settling with its energy account within 2 %.

mod common;

use common::{block, energy_error, vec_d};
use softway::contact::{ContactMethod, ContactSettings, GapDisplacement, Obstacle, ObstacleShape};
use softway::dim::{Dim, SpatialDim};
use softway::prelude::*;

/// The largest penetration over the run and the energy error at its end.
fn stack<const D: usize>(method: ContactMethod, gaps: GapDisplacement) -> (f64, f64)
where
    Dim<D>: SpatialDim<D>,
{
    let mut up = [0.0; 3];
    up[D - 1] = 1.0;
    let mut gravity = [0.0; 3];
    gravity[D - 1] = -9.81;
    let mut builder = Simulation::<D>::builder()
        .time_step(1e-3)
        .gravity(vec_d(gravity));
    for k in 0..3 {
        let mut mesh: Mesh<D> = block([0.1, 0.1, 0.1], [4, 4, 4], false);
        // 1 mm above the floor, 2 mm between blocks, each 1 cm to the side of the one below.
        let mut shift = [0.01 * k as f64, 0.0, 0.0];
        shift[D - 1] = 0.102 * k as f64 + 0.001;
        for x in &mut mesh.nodes {
            *x += vec_d::<D>(shift);
        }
        builder = builder.body(Body::new(
            format!("block{k}"),
            mesh,
            Material::LinearElastic(LinearElastic::new(1e5, 0.3, 1000.0).unwrap()),
        ));
    }
    let mut sim = builder
        .obstacle(Obstacle::new(
            "floor",
            ObstacleShape::Halfspace {
                point: vec_d([0.0; 3]),
                normal: vec_d(up),
            },
        ))
        .contact(ContactSettings {
            method,
            penalty: 1e9,
            gap_displacement: gaps,
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    let mut penetration: f64 = 0.0;
    while sim.state().time < 0.5 - 1e-9 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("{method:?}, t = {}: {e}", sim.state().time));
        penetration = penetration.max(r.max_penetration);
    }
    let error = energy_error(&sim);
    eprintln!(
        "{D}D {method:?} stack, {gaps:?} gaps: largest penetration {penetration:.3e} m, energy error {error:.2e}"
    );
    (penetration, error)
}

fn a_stack_under_the_augmented_lagrangian<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let (penetration, error) = stack::<D>(
        ContactMethod::AugmentedLagrangian,
        GapDisplacement::Configuration,
    );
    assert!(error < 2e-2, "energy error {error}");
    assert!(penetration < 2e-3, "penetration {penetration}");
}

fn a_stack_of_soft_blocks_lands_and_settles<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let (penetration, error) = stack::<D>(ContactMethod::SoftWay, GapDisplacement::Configuration);
    common::verify::record("stack", &format!("energy {D}D"), error);
    common::verify::record("stack", &format!("penetration {D}D (m)"), penetration);
    assert!(error < 2e-2, "energy error {error}");
    // Measured 3.6e-4 m (2D) and 1.05e-3 m (3D): far above the penalty's own pressure / zeta
    // (3e-6 m at the bottom of the stack), an open defect (book, contact chapter); with one
    // pass the 2D stack went 3.6 mm deep and the 3D one did not converge at its landing.
    assert!(penetration < 2e-3, "penetration {penetration}");
}

/// The same stack with the penalty's gaps measured on the running eq 22 displacement
/// (`GapDisplacement::Trapezoid`): the configuration no longer stores a step's travel inside
/// the other body. Measured 3.1e-5 m (2D) and 5.3e-5 m (3D), ten to twenty times less than
/// with the paper's configuration gaps, still ten times the static pressure / zeta (the
/// landing's dynamic pressure); the account loses 2.3e-2 / 1.7e-2 of the reference (the
/// end-of-step penalty's dissipation, book, contact chapter).
fn trapezoid_gaps_keep_the_stack_apart<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let (penetration, error) = stack::<D>(ContactMethod::SoftWay, GapDisplacement::Trapezoid);
    assert!(penetration < 1e-4, "penetration {penetration}");
    assert!(error < 3e-2, "energy error {error}");
}

mod d2 {
    #[test]
    fn a_stack_of_soft_blocks_lands_and_settles() {
        super::a_stack_of_soft_blocks_lands_and_settles::<2>();
    }
    #[test]
    fn trapezoid_gaps_keep_the_stack_apart() {
        super::trapezoid_gaps_keep_the_stack_apart::<2>();
    }
    /// Uzawa with a fixed zeta (the paper's) needed over 50 iterations at the second landing
    /// (t = 0.104 s); with the default growing penalty it runs to the end.
    #[test]
    fn a_stack_under_the_augmented_lagrangian() {
        // Measured: energy error 6.1e-4, largest penetration 3.1e-4 m, the same open defect
        // as the soft way's stack (the depth between the blocks after a step, far above what
        // Uzawa's gaps say).
        super::a_stack_under_the_augmented_lagrangian::<2>();
    }
}

mod d3 {
    #[test]
    #[cfg_attr(
        not(feature = "parallel"),
        ignore = "slow without threads (20-50 s): runs with the default features; nothing it reaches depends on a feature but the threaded assembly, which determinism.rs checks"
    )]
    fn a_stack_of_soft_blocks_lands_and_settles() {
        super::a_stack_of_soft_blocks_lands_and_settles::<3>();
    }
    #[test]
    #[cfg_attr(
        not(feature = "parallel"),
        ignore = "slow without threads (20-50 s): runs with the default features; nothing it reaches depends on a feature but the threaded assembly, which determinism.rs checks"
    )]
    fn trapezoid_gaps_keep_the_stack_apart() {
        super::trapezoid_gaps_keep_the_stack_apart::<3>();
    }
    /// Measured: largest penetration 1.04e-3 m, energy error 3.7e-3.
    #[test]
    #[ignore = "slow (about 40 s); the 2D one runs"]
    fn a_stack_under_the_augmented_lagrangian() {
        super::a_stack_under_the_augmented_lagrangian::<3>();
    }
}

mod open {
    use softway::contact::{ContactMethod, GapDisplacement};
    #[test]
    #[ignore = "runs to the end and its account closes to 1.08e-2, but the upper block's \
                edge sinks 3.44e-3 m into the lower one: one pass holds only the lower \
                block's nodes (1.05e-3 m and 7.9e-2 while the end-of-step projection also \
                pushed the unheld pairs out; book, contact chapter, Limits)"]
    fn implicit_projection_3d() {
        // The targets: the account within 2 %, no block inside another.
        let (penetration, error) = super::stack::<3>(
            ContactMethod::ImplicitProjection,
            GapDisplacement::Configuration,
        );
        assert!(error < 2e-2, "energy error {error}");
        assert!(penetration < 1e-6, "penetration {penetration}");
    }
}
