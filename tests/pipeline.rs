//! The step as a pipeline: the state holds everything that affects results. A failed step
//! leaves the simulation bit for bit as it was, a retry continues exactly as an uninterrupted
//! run, and a simulation rebuilt from its model and a state continues bit for bit.

use crate::common;

use common::{block, vec_d};
use softway::contact::{ContactMethod, ContactSettings, FrictionLaw, Obstacle, ObstacleShape};
use softway::dim::{Dim, SpatialDim};
use softway::prelude::*;
use softway::simulation::State;

/// Every bit of a state (Debug prints each f64 with its shortest round-trip form, and -0.0
/// apart from 0.0).
fn bits(state: &State) -> String {
    format!("{state:?}")
}

/// A soft block 3 mm above a plane, falling at 1 m/s and sliding at 0.3 m/s, with `method`.
fn falling_block<const D: usize>(method: ContactMethod, friction: FrictionLaw) -> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    let mut mesh: Mesh<D> = block([0.4, 0.1, 0.1], [8, 2, 2], false);
    let mut offset = [-0.2, -0.05, 0.0];
    offset[D - 1] = 3e-3;
    mesh.translate(&vec_d(offset));
    let rubber = Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap());
    let mut down = [0.0; 3];
    down[D - 1] = -1.0;
    let mut g = [0.0; 3];
    g[D - 1] = -9.81;
    let mut normal = [0.0; 3];
    normal[D - 1] = 1.0;
    let mut sideways = [0.0; 3];
    sideways[0] = 0.3;
    Simulation::<D>::builder()
        .time_step(1e-3)
        .gravity(vec_d(g))
        .body(Body::new("block", mesh, rubber).with_velocity(vec_d(down) + vec_d(sideways)))
        .obstacle(Obstacle::new(
            "floor",
            ObstacleShape::Halfspace {
                point: vec_d([0.0; 3]),
                normal: vec_d(normal),
            },
        ))
        .contact(ContactSettings {
            method,
            penalty: 1e9,
            friction,
            ..ContactSettings::default()
        })
        .build()
        .unwrap()
}

const METHODS: [ContactMethod; 4] = [
    ContactMethod::SoftWay,
    ContactMethod::ImplicitProjection,
    ContactMethod::AugmentedLagrangian,
    ContactMethod::ExplicitProjection,
];

fn failed_step_restores_the_state_and_a_retry_continues_exactly<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let coulomb = FrictionLaw::Coulomb {
        coefficient: 0.3,
        regularization: 1e-3,
    };
    for method in METHODS {
        let friction = if method == ContactMethod::SoftWay {
            coulomb
        } else {
            FrictionLaw::Frictionless
        };
        let mut reference = falling_block::<D>(method, friction);
        let mut interrupted = falling_block::<D>(method, friction);
        let mut touched = false;
        for step in 0..12 {
            // From the third step on (in contact), each step of `interrupted` first fails.
            if step >= 2 {
                let before = bits(interrupted.state());
                interrupted.set_solver_limits(1, 1e-300).unwrap();
                let failure = interrupted.step();
                assert!(
                    failure.is_err(),
                    "{method:?} step {step}: the step should fail"
                );
                assert_eq!(
                    before,
                    bits(interrupted.state()),
                    "{method:?} step {step}: a failed step changed the state"
                );
                interrupted.set_solver_limits(50, 1e-8).unwrap();
            }
            let a = reference
                .step()
                .unwrap_or_else(|e| panic!("{method:?} step {step}: {e}"));
            let b = interrupted.step().unwrap();
            touched |= a.contact_forces[0].iter().any(|f| *f != 0.0);
            assert_eq!(
                bits(reference.state()),
                bits(interrupted.state()),
                "{method:?} step {step}: the retried step differs"
            );
            assert_eq!(without_factorisations(&a), without_factorisations(&b));
        }
        assert!(touched, "{method:?}: the block never touched the floor");
    }
}

/// A step report without its factorisation count: a rebuilt or retried simulation factors
/// again the cached matrices its state names (with the same bits), which the count shows.
fn without_factorisations(report: &StepReport) -> String {
    format!(
        "{:?}",
        StepReport {
            factorisations: 0,
            ..report.clone()
        }
    )
}

fn rebuilt_from_model_and_state_continues_bit_for_bit<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    for method in METHODS {
        let mut whole = falling_block::<D>(method, FrictionLaw::Frictionless);
        let mut first = falling_block::<D>(method, FrictionLaw::Frictionless);
        for step in 0..6 {
            whole
                .step()
                .unwrap_or_else(|e| panic!("{method:?} step {step}: {e}"));
            first.step().unwrap();
        }
        if D == 3 && method != ContactMethod::ExplicitProjection {
            // The rebuild must refactor the contact matrices the state names.
            assert!(
                !first.state().contact_memory.factors.is_empty(),
                "{method:?}: no contact factorisation to rebuild"
            );
        }
        let mut rebuilt =
            Simulation::<D>::from_parts(first.model().clone(), first.state().clone()).unwrap();
        for step in 0..6 {
            let a = whole.step().unwrap();
            let b = rebuilt.step().unwrap();
            assert_eq!(
                bits(whole.state()),
                bits(rebuilt.state()),
                "{method:?} step {step} after the rebuild"
            );
            assert_eq!(without_factorisations(&a), without_factorisations(&b));
        }
    }
}

fn a_state_of_the_wrong_size_is_refused<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let mut sim = falling_block::<D>(ContactMethod::SoftWay, FrictionLaw::Frictionless);
    let mut state = sim.state().clone();
    state.velocity.pop();
    let err = sim.set_state(state).unwrap_err().to_string();
    assert!(err.contains("state.velocity"), "{err}");
}

both_dims!(
    failed_step_restores_the_state_and_a_retry_continues_exactly,
    rebuilt_from_model_and_state_continues_bit_for_bit,
    a_state_of_the_wrong_size_is_refused,
);
