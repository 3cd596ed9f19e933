//! Tests of the step: the contact tangent against central differences of the contact forces
//! (penalty and implicit projection, obstacles and bodies, friction), single-precision contact
//! factorisations against double, the general path against the linear one, material history
//! as state.

use super::*;
use crate::contact::methods::OuterVariables;
use crate::contact::{
    ContactMethod, ContactSettings, FrictionLaw, MasterId, Obstacle, ObstacleShape,
};
use crate::material::{LinearElastic, Material};
use crate::mesh::generators::rectangle;
use crate::simulation::contact_terms::{ContactTerms, TermsInput};
use crate::simulation::{Body, Simulation2};
use nalgebra::Vector2;
use std::collections::BTreeMap;

/// The contact terms at end velocities `v1`.
fn terms_at(
    sim: &mut Simulation2,
    v1: &[f64],
    h: f64,
    friction_normals: &BTreeMap<(usize, MasterId), f64>,
    anchors: &BTreeMap<(usize, MasterId), Vector2<f64>>,
) -> ContactTerms<2> {
    sim.ensure_system(h).unwrap();
    let n = v1.len();
    let u0 = sim.state.displacement.clone();
    let v0 = sim.state.velocity.clone();
    let x0 = end_positions(&sim.reference, &u0, &v0, &vec![0.0; n], 0.0);
    let x_gap = end_positions(&sim.reference, &u0, &v0, v1, h);
    let obstacles = sim.model.obstacles.clone();
    let t1: Vec<Vector2<f64>> = obstacles.iter().map(|o| o.translation).collect();
    let areas = sim.tributary_areas(&x0);
    let det = sim.caches.detector.as_mut().unwrap();
    det.update_candidates(&x0, &x_gap, &obstacles, &t1);
    let pairs = det.pairs(&x_gap, &obstacles);
    // The iteration matrix's own diagonal: the tangential springs are measured by it.
    let diagonal = sim.system_diagonal().to_vec();
    // Implicit projection: every detected point active (its multipliers zero).
    let mut vars = OuterVariables::default();
    if sim.model.contact.method == ContactMethod::ImplicitProjection {
        vars.active = pairs.iter().map(|p| sim.contact_key(p)).collect();
    }
    sim.contact_terms(
        &pairs,
        &TermsInput {
            method: methods::method(sim.model.contact.method),
            obstacles_t1: &obstacles,
            x_gap: &x_gap,
            v0: &v0,
            v1,
            time_step: h,
            areas: &areas,
            vars: &vars,
            friction_normals,
            friction_anchors: anchors,
            diagonal: &diagonal,
            slip_directions: &Default::default(),
            held_predictions: &Default::default(),
        },
    )
}

/// The contact forces and the assembled tangent at end velocities `v1`.
fn forces_and_tangent(
    sim: &mut Simulation2,
    v1: &[f64],
    h: f64,
    friction_normals: &BTreeMap<(usize, MasterId), f64>,
    anchors: &BTreeMap<(usize, MasterId), Vector2<f64>>,
) -> (Vec<f64>, nalgebra::DMatrix<f64>, [usize; 2]) {
    let n = v1.len();
    let terms = terms_at(sim, v1, h, friction_normals, anchors);
    let mut k = nalgebra::DMatrix::zeros(n, n);
    for &(r, c, v) in terms.entries.iter().chain(&terms.geometric) {
        k[(r, c)] += v;
        if r != c {
            k[(c, r)] += v;
        }
    }
    for (u, w) in &terms.coupling {
        for &(r, a) in u {
            for &(c, b) in w {
                k[(r, c)] += a * b;
            }
        }
    }
    // Closed contacts, and those at the slip limit.
    let closed = terms.pairs.iter().filter(|p| p.normal_force > 0.0);
    let slipping = closed
        .clone()
        .filter(|p| p.friction.norm() >= (1.0 - 1e-9) * 0.4 * p.normal_force)
        .count();
    (terms.forces, k, [closed.count(), slipping])
}

/// The assembled contact tangent against central differences of the contact forces;
/// `anchors` are the elastic slips of the friction return map at the start of the step.
fn check(
    sim: Simulation2,
    anchors: &BTreeMap<(usize, MasterId), Vector2<f64>>,
    tolerance: f64,
) -> [usize; 2] {
    check_at_speed(sim, anchors, tolerance, 0.01)
}

/// [`check`] with end velocities of about `speed` (m/s).
fn check_at_speed(
    mut sim: Simulation2,
    anchors: &BTreeMap<(usize, MasterId), Vector2<f64>>,
    tolerance: f64,
    speed: f64,
) -> [usize; 2] {
    let h = 1e-3;
    let n = sim.state.velocity.len();
    // A velocity field that keeps every contact strictly open or strictly closed.
    let v1: Vec<f64> = (0..n).map(|i| speed * ((i as f64) * 0.7).sin()).collect();
    let normals = BTreeMap::new();
    let (_, k, counts) = forces_and_tangent(&mut sim, &v1, h, &normals, anchors);
    assert!(k.amax() > 0.0, "no contact in the test configuration");
    let eps = 1e-7;
    let mut worst: f64 = 0.0;
    for j in 0..n {
        let (mut vp, mut vm) = (v1.clone(), v1.clone());
        vp[j] += eps;
        vm[j] -= eps;
        let (fp, _, _) = forces_and_tangent(&mut sim, &vp, h, &normals, anchors);
        let (fm, _, _) = forces_and_tangent(&mut sim, &vm, h, &normals, anchors);
        for i in 0..n {
            // The tangent is d(-f)/dv1.
            let fd = -(fp[i] - fm[i]) / (2.0 * eps);
            worst = worst.max((fd - k[(i, j)]).abs());
        }
    }
    assert!(
        worst <= tolerance * k.amax(),
        "tangent error {worst:e} of {:e}",
        k.amax()
    );
    counts
}

fn block_on(obstacle: Obstacle<2>, friction: FrictionLaw, penetration: f64) -> Simulation2 {
    let mesh = rectangle(
        Vector2::new(-0.5, 0.0),
        Vector2::new(0.5, 0.2),
        [4, 2],
        crate::element::ElementKind::Quad4,
    )
    .unwrap();
    let mut sim = Simulation2::builder()
        .body(Body::new(
            "b",
            mesh,
            Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap()),
        ))
        .obstacle(obstacle)
        .contact(ContactSettings {
            method: ContactMethod::SoftWay,
            penalty: 1e8,
            friction,
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    // Push the body into the obstacle.
    for i in 0..sim.node_count() {
        sim.state.displacement[2 * i + 1] = -penetration;
    }
    sim
}

#[test]
fn soft_way_tangent_against_a_halfspace_matches_finite_differences() {
    let plane = Obstacle::new(
        "p",
        ObstacleShape::Halfspace {
            point: Vector2::zeros(),
            normal: Vector2::new(0.1, 1.0),
        },
    );
    check(
        block_on(plane, FrictionLaw::Frictionless, 1e-3),
        &BTreeMap::new(),
        1e-6,
    );
}

#[test]
fn soft_way_tangent_against_a_ball_matches_finite_differences() {
    // The curvature term zeta (-g) (I - n n) / R matters here.
    let ball = Obstacle::new(
        "ball",
        ObstacleShape::Ball {
            center: Vector2::new(0.05, -0.5),
            radius: 0.5,
        },
    );
    // The curvature term is about 1.5 % of the tangent here (|g| / R); what remains is the
    // variation of the projected contact area with the normal, not in the tangent.
    check(
        block_on(ball, FrictionLaw::Frictionless, 1e-2),
        &BTreeMap::new(),
        3e-3,
    );
}

#[test]
fn implicit_projection_tangent_on_a_turning_ball_matches_finite_differences() {
    // The held normal velocity against a curved master that turns: the normal's variation
    // and the surface velocity following the closest point (which cancel on a ball turning
    // about its centre, where n . v_m = 0).
    for omega in [0.0, 20.0] {
        check_at_speed(block_in_drum(omega), &BTreeMap::new(), 1e-5, 2.0);
    }
}

/// The block pressed 1 cm into a drum of 0.5 m radius turning at `omega` (rad/s), under
/// implicit projection.
fn block_in_drum(omega: f64) -> Simulation2 {
    let ball = Obstacle::new(
        "drum",
        ObstacleShape::Ball {
            center: Vector2::new(0.05, -0.5),
            radius: 0.5,
        },
    );
    let mut sim = block_on(ball, FrictionLaw::Frictionless, 1e-2);
    sim.model.contact.method = ContactMethod::ImplicitProjection;
    sim.state.obstacle_angular_velocities = vec![omega];
    sim
}

#[test]
fn coulomb_friction_tangent_matches_finite_differences() {
    let plane = Obstacle::new(
        "p",
        ObstacleShape::Halfspace {
            point: Vector2::zeros(),
            normal: Vector2::new(0.0, 1.0),
        },
    );
    let law = FrictionLaw::Coulomb {
        coefficient: 0.4,
        regularization: 1e-3,
    };
    // The return map on a block pressed 1 mm into a plane: every contact sticks without an
    // elastic slip at the start (increments h w_t of ~1e-5 m against mu times the 1 mm
    // penetration), and slips with one of 2 mm, either way.
    for (elastic_slip, slips) in [(0.0, false), (2e-3, true), (-2e-3, true)] {
        let sim = block_on(plane.clone(), law, 1e-3);
        let mut anchors = BTreeMap::new();
        for s in 0..sim.node_count() {
            anchors.insert((s, MasterId::Obstacle(0)), Vector2::new(elastic_slip, 0.0));
        }
        let [closed, slipping] = check(sim, &anchors, 1e-6);
        assert_eq!(closed, 5, "closed contacts");
        assert_eq!(
            slipping,
            if slips { closed } else { 0 },
            "elastic slip {elastic_slip}"
        );
    }
}

#[test]
fn coulomb_friction_tangent_on_a_turning_plane_matches_finite_differences() {
    let plane = Obstacle {
        rotation: nalgebra::Rotation2::new(0.05).into_inner(),
        ..Obstacle::new(
            "p",
            ObstacleShape::Halfspace {
                point: Vector2::new(0.3, 0.0),
                normal: Vector2::new(0.0, 1.0),
            },
        )
    };
    let law = FrictionLaw::Coulomb {
        coefficient: 0.4,
        regularization: 1e-3,
    };
    for (elastic_slip, omega) in [(0.0, 0.0), (0.0, 2.0), (2e-3, 2.0)] {
        let mut sim = block_on(plane.clone(), law, 1e-3);
        sim.state.obstacle_angular_velocities = vec![omega];
        let mut anchors = BTreeMap::new();
        for s in 0..sim.node_count() {
            anchors.insert((s, MasterId::Obstacle(0)), Vector2::new(elastic_slip, 0.0));
        }
        eprintln!("omega {omega} slip {elastic_slip}");
        check(sim, &anchors, 1e-6);
    }
}

/// An upper block pressed 1 mm into a lower one, 1 cm off centre, under `method`.
fn two_blocks(method: ContactMethod) -> Simulation2 {
    let lower = rectangle(
        Vector2::new(-0.5, -0.2),
        Vector2::new(0.5, 0.0),
        [3, 1],
        crate::element::ElementKind::Quad4,
    )
    .unwrap();
    let mut upper = rectangle(
        Vector2::new(-0.3, 0.0),
        Vector2::new(0.3, 0.2),
        [2, 1],
        crate::element::ElementKind::Quad4,
    )
    .unwrap();
    upper.translate(&Vector2::new(0.01, -1e-3));
    let mat = Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap());
    Simulation2::builder()
        .body(Body::new("upper", upper, mat))
        .body(Body::new("lower", lower, mat))
        .contact(ContactSettings {
            method,
            penalty: 1e8,
            ..ContactSettings::default()
        })
        .build()
        .unwrap()
}

#[test]
fn soft_way_tangent_between_two_bodies_matches_finite_differences() {
    // The facet terms (normal and closest-point variations) of a deformable master. The
    // projected contact area follows the master's normal; that variation is not in the
    // tangent (a relative error of ~6e-4 here), everything else is.
    check(two_blocks(ContactMethod::SoftWay), &BTreeMap::new(), 1e-3);
}

#[test]
fn implicit_projection_tangent_between_two_bodies_matches_finite_differences() {
    // A held normal velocity on a facet master that turns and slides under the slave:
    // the normal's and the closest point's variation (a non-symmetric rank-one term per
    // pair) and the constraint force's geometric term are in the tangent. At 2 m/s of
    // sliding the turning normal's term is about 3e-3 of the tangent.
    let sim = two_blocks(ContactMethod::ImplicitProjection);
    check_at_speed(sim, &BTreeMap::new(), 2e-5, 2.0);
}

/// The held constraints' gradients (`ContactTerms::held`, from which Newton predicts their
/// values after an increment: its merit) against central differences of their values, at
/// end velocities of about `speed` (m/s); returns how many were checked.
fn check_held_gradients(mut sim: Simulation2, speed: f64, tolerance: f64) -> usize {
    let h = 1e-3;
    let n = sim.state.velocity.len();
    let v1: Vec<f64> = (0..n).map(|i| speed * ((i as f64) * 0.7).sin()).collect();
    let none = BTreeMap::new();
    let held = terms_at(&mut sim, &v1, h, &none, &BTreeMap::new()).held;
    let value_at = |sim: &mut Simulation2, v: &[f64], key| {
        let terms = terms_at(sim, v, h, &none, &BTreeMap::new());
        terms
            .held
            .iter()
            .find(|row| row.0 == key)
            .expect("still held")
            .1
    };
    let eps = 1e-7;
    for (key, _, gradient) in &held {
        let scale = gradient.iter().fold(0.0f64, |m, g| m.max(g.1.abs()));
        for j in 0..n {
            let (mut vp, mut vm) = (v1.clone(), v1.clone());
            vp[j] += eps;
            vm[j] -= eps;
            let fd = (value_at(&mut sim, &vp, *key) - value_at(&mut sim, &vm, *key)) / (2.0 * eps);
            let exact: f64 = gradient.iter().filter(|g| g.0 == j).map(|g| g.1).sum();
            assert!(
                (fd - exact).abs() <= tolerance * scale,
                "{key:?}, unknown {j}: gradient {exact:e}, differences {fd:e}"
            );
        }
    }
    held.len()
}

#[test]
fn held_constraint_gradients_match_finite_differences() {
    // Between bodies, sliding at 2 m/s under a facet that turns (the curvature the merit
    // measures), and on a drum turning at 20 rad/s.
    let sim = two_blocks(ContactMethod::ImplicitProjection);
    assert!(check_held_gradients(sim, 2.0, 1e-6) > 0);
    // As the tangent on the turning drum (above): 1.2e-6 measured.
    assert!(check_held_gradients(block_in_drum(20.0), 2.0, 1e-5) > 0);
}

/// A block dropped at 1 m/s onto a plane 0.1 mm under it, `steps` steps of 1 ms; the
/// velocities at the end.
fn dropped_block(penalty: f64, single_precision: bool, steps: usize) -> (Simulation2, Vec<f64>) {
    let mesh = rectangle(
        Vector2::new(-0.5, 1e-4),
        Vector2::new(0.5, 0.2001),
        // 25 bottom nodes: more than CG takes on without a contact factorisation.
        [24, 4],
        crate::element::ElementKind::Quad4,
    )
    .unwrap();
    let plane = Obstacle::new(
        "ground",
        ObstacleShape::Halfspace {
            point: Vector2::zeros(),
            normal: Vector2::new(0.0, 1.0),
        },
    );
    let mut sim = Simulation2::builder()
        .gravity(Vector2::new(0.0, -9.81))
        .body(
            Body::new(
                "b",
                mesh,
                Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap()),
            )
            .with_velocity(Vector2::new(0.0, -1.0)),
        )
        .obstacle(plane)
        .contact(ContactSettings {
            method: ContactMethod::SoftWay,
            penalty,
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    sim.state.contact_memory.double_precision_only = !single_precision;
    for _ in 0..steps {
        sim.step().unwrap();
    }
    let v = sim.state.velocity.clone();
    (sim, v)
}

#[test]
fn single_precision_contact_factors_give_the_double_precision_answer() {
    let (single, v_single) = dropped_block(1e8, true, 4);
    assert!(
        !single.state.contact_memory.double_precision_only,
        "refinement converged"
    );
    assert!(single
        .caches
        .contact_factors
        .iter()
        .all(|f| f.is_single_precision()));
    let (double, v_double) = dropped_block(1e8, false, 4);
    assert!(double
        .caches
        .contact_factors
        .iter()
        .all(|f| !f.is_single_precision()));
    assert!(
        !single.caches.contact_factors.is_empty(),
        "a contact matrix was factored"
    );
    let scale = v_double.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let diff = v_single
        .iter()
        .zip(&v_double)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    // Both are Newton solutions to the same tolerance (1e-8 of the force scale).
    assert!(diff < 1e-6 * scale, "{diff} vs {scale}");
}

/// `solver_memory` counts what is factored: nothing before the first step, the contact-free
/// factor in double precision after it, and each kept contact factor on the same pattern at
/// half those bytes in single precision, the full bytes in double.
#[test]
fn solver_memory_counts_the_factors_held() {
    let (fresh, _) = dropped_block(1e8, true, 0);
    let before = fresh.solver_memory();
    assert_eq!((before.factor, before.contact_factors), (0, 0));
    assert!(before.matrices > 0);
    for single in [true, false] {
        let (sim, _) = dropped_block(1e8, single, 4);
        let memory = sim.solver_memory();
        let entries = sim
            .caches
            .system
            .as_ref()
            .unwrap()
            .cholesky
            .factor_entries();
        assert_eq!(memory.factor, 8 * entries);
        let kept = sim.caches.contact_factors.len();
        assert!(kept > 0, "a contact matrix was factored");
        // The plane adds only diagonal blocks: the contact factors share A0's pattern.
        let per_factor = if single { 4 * entries } else { 8 * entries };
        assert_eq!(memory.contact_factors, kept * per_factor);
        assert_eq!(
            memory.total(),
            memory.factor + memory.contact_factors + memory.matrices
        );
    }
}

/// The cache drops a contact factorisation as soon as the state forgets it (it held the
/// forgotten ones until the next step began: a step that factored twice held four).
#[test]
fn the_cache_holds_only_the_contact_factors_the_state_names() {
    let (mut sim, _) = dropped_block(1e8, true, 4);
    let h = sim.model.settings.time_step;
    let b = vec![1.0; sim.prescribed.len()];
    let before = sim.state.contact_memory.next_factor;
    for _ in 0..3 {
        sim.factor_contact(&[], &[], &b, 1e-9, h, sim.state.step + 1)
            .unwrap();
    }
    assert_eq!(sim.state.contact_memory.next_factor, before + 3);
    let named = &sim.state.contact_memory.factors;
    assert_eq!(
        sim.caches.contact_factors.len(),
        super::super::linear_solve::CONTACT_FACTORS_KEPT
    );
    assert!(sim
        .caches
        .contact_factors
        .iter()
        .all(|f| named.iter().any(|r| r.id == f.id())));
}

/// The general path (internal forces and tangent from the element kernel every Newton
/// iteration, the path of laws that are not linear) gives the linear fast path's answer.
#[test]
fn the_general_path_matches_the_linear_fast_path() {
    for method in [ContactMethod::SoftWay, ContactMethod::ImplicitProjection] {
        let run = |general: bool| {
            let (mut sim, _) = dropped_block(1e8, true, 0);
            sim.model.contact.method = method;
            sim.general_path = general;
            let mut reports = Vec::new();
            for _ in 0..8 {
                reports.push(sim.step().unwrap());
            }
            (
                sim.state.velocity.clone(),
                sim.state.displacement.clone(),
                reports,
            )
        };
        let (v_fast, u_fast, r_fast) = run(false);
        let (v_general, u_general, r_general) = run(true);
        assert!(
            r_fast.iter().any(|r| r.active_contacts > 0),
            "{method:?}: no contact"
        );
        let scale = v_fast.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let dv = v_fast
            .iter()
            .zip(&v_general)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        let du = u_fast
            .iter()
            .zip(&u_general)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        // Both are Newton solutions to the same tolerance (1e-8 of the force scale).
        assert!(
            dv < 1e-6 * scale,
            "{method:?}: velocities differ by {dv:e} of {scale:e}"
        );
        assert!(
            du < 1e-6 * scale * 1e-3 * 8.0,
            "{method:?}: displacements differ by {du:e}"
        );
        for (a, b) in r_fast.iter().zip(&r_general) {
            let e = a.energies.total().abs().max(1e-12);
            assert!(
                (a.energies.total() - b.energies.total()).abs() < 1e-6 * e,
                "{method:?}: energies {:?} vs {:?}",
                a.energies,
                b.energies
            );
        }
    }
}

/// A law with history through the general path: the state carries the history from step
/// to step, and a failed step restores it.
#[test]
fn material_history_is_state() {
    use crate::material::tests::TestLaw;
    let (mut sim, _) = dropped_block(1e8, true, 0);
    let elastic = crate::material::LinearElastic::new(1e6, 0.3, 1000.0).unwrap();
    sim.integration[0].law = std::sync::Arc::new(TestLaw {
        elastic,
        cubic: 1e8,
        eta: 1e3,
        exponent: 0.5,
    });
    sim.general_path = true;
    sim.state.material_history = vec![0.0; assembly::history_len(&sim.table, &sim.integration)];
    assert_eq!(
        sim.state.material_history.len(),
        24 * 4 * 4,
        "4 points per Quad4"
    );
    let mut previous = 0.0;
    for step in 0..6 {
        let before = format!("{:?}", sim.state);
        sim.set_solver_limits(1, 1e-300).unwrap();
        assert!(sim.step().is_err());
        assert_eq!(
            before,
            format!("{:?}", sim.state),
            "step {step}: not restored"
        );
        sim.set_solver_limits(50, 1e-8).unwrap();
        sim.step().unwrap();
        // The test law accumulates h * |strain rate| (regularised): it grows every step.
        let total: f64 = sim.state.material_history.iter().sum();
        assert!(total > previous, "step {step}: {total} <= {previous}");
        previous = total;
    }
}

/// A step after a half step whose contact factorisations the cache lacks (a failed attempt's
/// cuts evicted them; restored, the state still names them): rebuilding them refactors the
/// contact-free matrix for the half step, and the step must still solve with its own. It once
/// kept the half step's matrix, converged elsewhere, and a retried step differed from the
/// uninterrupted one.
#[test]
fn rebuilt_factorisations_leave_the_step_its_own_matrix() {
    let (mut reference, _) = dropped_block(1e8, true, 4);
    let (mut rebuilt, _) = dropped_block(1e8, true, 4);
    let h = reference.model.settings.time_step;
    for sim in [&mut reference, &mut rebuilt] {
        sim.advance(0.5 * h, &mut NullRecorder).unwrap();
    }
    let half = rebuilt
        .state
        .contact_memory
        .factors
        .iter()
        .find(|f| f.time_step == 0.5 * h)
        .expect("the half step factored a contact matrix")
        .id;
    rebuilt.caches.contact_factors.retain(|f| f.id() != half);
    let a = reference.step().unwrap();
    let b = rebuilt.step().unwrap();
    assert_eq!(rebuilt.caches.system.as_ref().unwrap().time_step, h);
    // The rebuilt one factors the evicted matrix again (and the step's own after it).
    assert!(
        b.factorisations > a.factorisations,
        "factorisations {} against {}",
        b.factorisations,
        a.factorisations
    );
    let same_count = StepReport {
        factorisations: a.factorisations,
        ..b
    };
    assert_eq!(format!("{a:?}"), format!("{same_count:?}"));
    assert_eq!(
        format!("{:?}", reference.state),
        format!("{:?}", rebuilt.state)
    );
}

/// A cut step's halves (`advance_in_halves`) re-express the state for half the step and back:
/// a clamped beam set vibrating in every mode (most of them unresolved at three times the
/// explicit step), every third step cut, ends with the same state as with the halves taken as
/// steps of half the size, and the scheme's energy never grows over a cut.
#[test]
fn cut_steps_never_grow_the_conserved_energy() {
    let (e, rho) = (1e6, 1000.0);
    let h = 3.0 * 0.1 / f64::sqrt(e / rho);
    let mesh = rectangle(
        Vector2::zeros(),
        Vector2::new(1.0, 0.2),
        [10, 2],
        crate::element::ElementKind::Quad4,
    )
    .unwrap();
    let material = Material::LinearElastic(LinearElastic::new(e, 0.3, rho).unwrap());
    let beam = Body::new("beam", mesh, material).with_constraint_in_box(
        Vector2::new(-1e-9, -1.0),
        Vector2::new(1e-9, 1.0),
        [Some(0.0); 2],
    );
    let run = |cut: bool| {
        let mut sim = Simulation2::builder()
            .time_step(h)
            .body(beam.clone())
            .build()
            .unwrap();
        for i in 0..sim.state.velocity.len() {
            if sim.prescribed[i].is_none() {
                sim.state.velocity[i] = 0.1 * (1.7 * i as f64).sin();
            }
        }
        sim.state.reference_energy = sim.energies().total();
        let q0 = sim.scheme_energy();
        let mut q = q0;
        for n in 1..=30 {
            if n % 3 == 0 {
                if cut {
                    sim.advance_in_halves(h, &mut NullRecorder, 0, true)
                        .unwrap();
                } else {
                    sim.advance(0.5 * h, &mut NullRecorder).unwrap();
                    sim.advance(0.5 * h, &mut NullRecorder).unwrap();
                }
            } else {
                sim.step().unwrap();
            }
            let now = sim.scheme_energy();
            assert!(now <= q * (1.0 + 1e-9), "step {n}: Q {now} after {q}");
            q = now;
        }
        // The plain halves leave the state for half the step: a whole step takes it back.
        sim.step().unwrap();
        let account = (sim.scheme_energy() - q0 + sim.energies().dissipated).abs() / q0;
        assert!(account < 1e-9, "account of Q {account}");
        sim.state
    };
    let (cut, halves) = (run(true), run(false));
    for (a, b) in cut.velocity.iter().zip(&halves.velocity) {
        assert!((a - b).abs() < 1e-12, "velocity {a} against {b}");
    }
    for (a, b) in cut.displacement.iter().zip(&halves.displacement) {
        assert!((a - b).abs() < 1e-12, "displacement {a} against {b}");
    }
}

/// A plate pushing a soft block at 2 m/s (implicit projection, 0.2 m block, E = 1e5 Pa, no
/// gravity), steps of 2 ms with one in three cut (`advance_in_halves`): no node is inside the
/// plate after any step. (Re-expressing the state when the cut step ended, as a first version
/// did, left the held nodes 5e-4 m inside it, a quarter of the half step's travel, and 8e-6 m
/// with the plate moved by the same lag: the velocity map changes the held nodes' normal
/// velocity. Each change now comes at the start of a step, whose end-of-step projection puts
/// them back.)
fn cut_steps_keep_a_pushed_block_on_the_plate<const D: usize>(mesh: crate::mesh::Mesh<D>)
where
    Dim<D>: SpatialDim<D>,
{
    let material = Material::LinearElastic(LinearElastic::new(1e5, 0.3, 1000.0).unwrap());
    let mut along = SVector::<f64, D>::zeros();
    along[0] = 1.0;
    let plate = Obstacle::new(
        "plate",
        ObstacleShape::Halfspace {
            point: SVector::zeros(),
            normal: along,
        },
    )
    .with_velocity(2.0 * along);
    let h = 2e-3;
    let mut sim = Simulation::<D>::builder()
        .time_step(h)
        .body(Body::new("block", mesh, material))
        .obstacle(plate)
        .build()
        .unwrap();
    for n in 1..=30 {
        if n % 3 == 0 {
            sim.advance_in_halves(h, &mut NullRecorder, 0, true)
                .unwrap();
        } else {
            sim.step().unwrap();
        }
        let deepest = sim.current_penetration();
        assert!(
            deepest < 1e-9,
            "{D}D step {n}: {deepest} m inside the plate"
        );
    }
}

#[test]
fn cut_steps_keep_a_pushed_block_on_the_plate_d2() {
    let mesh = rectangle(
        Vector2::zeros(),
        Vector2::new(0.2, 0.2),
        [4, 4],
        crate::element::ElementKind::Quad4,
    )
    .unwrap();
    cut_steps_keep_a_pushed_block_on_the_plate::<2>(mesh);
}

#[test]
fn cut_steps_keep_a_pushed_block_on_the_plate_d3() {
    let mesh = crate::mesh::generators::cuboid(
        nalgebra::Vector3::zeros(),
        nalgebra::Vector3::new(0.2, 0.2, 0.2),
        [4, 4, 4],
        crate::element::ElementKind::Hex8,
    )
    .unwrap();
    cut_steps_keep_a_pushed_block_on_the_plate::<3>(mesh);
}

/// Coulomb friction between two bodies under implicit projection (its return map on a lagged
/// threshold, here 100 N on every pair), sticking and slipping: the tangential rows and columns
/// of the assembled tangent against central differences of the contact forces. (The normal
/// ones carry the velocity penalty, 1e4 diagonals, and are checked above.)
#[test]
fn implicit_projection_friction_tangent_between_two_bodies_matches_finite_differences() {
    for (elastic_slip, speed) in [(0.0, 0.01), (0.0, 2.0), (2e-3, 0.01), (2e-3, 2.0)] {
        let mut sim = two_blocks(ContactMethod::ImplicitProjection);
        sim.model.contact.friction = FrictionLaw::Coulomb {
            coefficient: 0.5,
            regularization: 1e-3,
        };
        let h = 1e-3;
        let n = sim.state.velocity.len();
        let v1: Vec<f64> = (0..n).map(|i| speed * ((i as f64) * 0.7).sin()).collect();
        let pairs = terms_at(&mut sim, &v1, h, &BTreeMap::new(), &BTreeMap::new()).pairs;
        let normals: BTreeMap<_, _> = pairs.iter().map(|p| (p.key, 100.0)).collect();
        let anchors: BTreeMap<_, _> = pairs
            .iter()
            .map(|p| (p.key, Vector2::new(elastic_slip, 0.0)))
            .collect();
        let terms = terms_at(&mut sim, &v1, h, &normals, &anchors);
        let frictional = terms.pairs.iter().filter(|p| p.friction.norm() > 0.0);
        let slipping = frictional
            .clone()
            .filter(|p| p.friction.norm() >= (1.0 - 1e-9) * 50.0)
            .count();
        assert!(frictional.count() > 0, "no friction in the configuration");
        let (_, k, _) = forces_and_tangent(&mut sim, &v1, h, &normals, &anchors);
        let diagonal = sim.system_diagonal().iter().copied().fold(0.0, f64::max);
        let eps = 1e-7;
        let mut worst: f64 = 0.0;
        for j in (0..n).step_by(2) {
            let (mut vp, mut vm) = (v1.clone(), v1.clone());
            vp[j] += eps;
            vm[j] -= eps;
            let (fp, _, _) = forces_and_tangent(&mut sim, &vp, h, &normals, &anchors);
            let (fm, _, _) = forces_and_tangent(&mut sim, &vm, h, &normals, &anchors);
            for i in (0..n).step_by(2) {
                let fd = -(fp[i] - fm[i]) / (2.0 * eps);
                worst = worst.max((fd - k[(i, j)]).abs());
            }
        }
        eprintln!(
            "elastic slip {elastic_slip}, speed {speed}: {slipping} slipping, tangential error \
             {worst:.2e} against the largest diagonal {diagonal:.2e}"
        );
        assert!(worst <= 1e-4 * diagonal, "tangent error {worst:e}");
    }
}
