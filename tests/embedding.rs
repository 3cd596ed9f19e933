//! The embedding API a game or robotics host drives: handles that go stale without panics,
//! bodies and obstacles added and removed between steps, a kinematic obstacle posed every
//! step, contact forces per obstacle, per body pair and per node checked against the change of
//! momentum, contact events, per-body gravity, the fixed-timestep driver, `Send + Sync`.

use crate::common;

use common::{block, vec_d};
use nalgebra::{SMatrix, SVector};
use softway::contact::ObstacleShape;
use softway::dim::{Dim, SpatialDim};
use softway::prelude::*;

const G: f64 = 9.81;

fn rubber() -> Material {
    Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap())
}

/// A 0.1 m block of rubber whose lowest face is at height `bottom`, with light stiffness
/// damping (a damping ratio of about 0.15 at its first mode) so that it comes to rest.
fn cube<const D: usize>(name: &str, x: f64, bottom: f64) -> Body<D>
where
    Dim<D>: SpatialDim<D>,
{
    let mut mesh: Mesh<D> = block([0.1, 0.1, 0.1], [2, 2, 2], false);
    for p in &mut mesh.nodes {
        p[0] += x;
        p[D - 1] += bottom;
    }
    Body::new(name, mesh, rubber()).with_damping(0.0, 1e-3)
}

fn gravity<const D: usize>() -> SVector<f64, D> {
    let mut g = SVector::zeros();
    g[D - 1] = -G;
    g
}

/// A block 2 mm above the floor at a game's step, the default contact settings.
fn scene<const D: usize>() -> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    Simulation::<D>::builder()
        .time_step(1.0 / 240.0)
        .gravity(gravity())
        .body(cube("a", 0.0, 0.002))
        .obstacle(common::floor())
        .build()
        .unwrap()
}

/// The height of a body's lowest node above the floor (m).
fn lowest_point<const D: usize>(sim: &Simulation<D>, body: BodyId) -> f64
where
    Dim<D>: SpatialDim<D>,
{
    sim.body_positions(body)
        .unwrap()
        .iter()
        .map(|x| x[D - 1])
        .fold(f64::INFINITY, f64::min)
}

/// The total momentum of a body (kg m/s): `M v` summed over its nodes.
fn momentum<const D: usize>(sim: &Simulation<D>, body: BodyId) -> SVector<f64, D>
where
    Dim<D>: SpatialDim<D>,
{
    let m = sim.mass_matrix();
    let v = &sim.state().velocity;
    let mv = m.mul(v);
    let mut p = SVector::zeros();
    for n in sim.body_nodes(body).unwrap() {
        for k in 0..D {
            p[k] += mv[n * D + k];
        }
    }
    p
}

fn stale_and_forged_handles_are_errors<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let mut sim = scene::<D>();
    let a = sim.body_id("a").unwrap();
    let b = sim.add_body(cube("b", 0.3, 0.002)).unwrap();
    assert_ne!(a, b);
    assert_eq!(sim.body_ids(), vec![a, b]);
    // Per-body cell fields are the bodies' parts of the whole list, in order.
    sim.step().unwrap();
    let (sa, sb) = (
        sim.body_cell_stresses(a).unwrap(),
        sim.body_cell_stresses(b).unwrap(),
    );
    assert!(!sa.is_empty() && !sb.is_empty());
    assert_eq!([sa, sb].concat(), sim.cell_stresses());
    let strains = [
        sim.body_cell_equivalent_strains(a).unwrap(),
        sim.body_cell_equivalent_strains(b).unwrap(),
    ];
    assert_eq!(strains.concat(), sim.cell_equivalent_strains());
    sim.remove_body(a).unwrap();
    for result in [
        sim.position(a, 0).err(),
        sim.velocity(a, 0).err(),
        sim.body_nodes(a).err(),
        sim.body_mass(a).err(),
        sim.remove_body(a).err(),
        sim.set_gravity_scale(a, 0.0).err(),
        sim.body_positions(BodyId::initial(7)).err(),
        sim.body_cell_stresses(a).err(),
        sim.body_cell_equivalent_strains(BodyId::initial(7)).err(),
    ] {
        let e = result.expect("a stale or forged handle is refused");
        assert!(matches!(e, Error::InvalidHandle(_)), "{e}");
    }
    // The slot of `a` is reused with a new generation: the old handle stays stale.
    let c = sim.add_body(cube("c", 0.6, 0.002)).unwrap();
    assert!(sim.position(a, 0).is_err());
    assert!(sim.position(c, 0).is_ok());
    let floor = sim.obstacle_id("floor").unwrap();
    sim.remove_obstacle(floor).unwrap();
    assert!(sim.obstacle_translation(floor).is_err());
    assert!(sim.set_obstacle_velocity(floor, SVector::zeros()).is_err());
    assert!(sim.obstacle_contact_force(floor).is_err());
    // The last body stays.
    sim.remove_body(c).unwrap();
    assert!(matches!(sim.remove_body(b), Err(Error::InvalidHandle(_))));
}

fn contact_forces_balance_the_change_of_momentum<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let mut sim = scene::<D>();
    let a = sim.body_id("a").unwrap();
    let floor = sim.obstacle_id("floor").unwrap();
    let mass = sim.body_mass(a).unwrap();
    let h = sim.settings().time_step;
    let (mut started, mut stopped) = (0, 0);
    for _ in 0..120 {
        let p0 = momentum(&sim, a);
        sim.step().unwrap();
        let dp = momentum(&sim, a) - p0;
        let f = sim.obstacle_contact_force(floor).unwrap();
        // M (v1 - v0) = h (m g + F): internal forces cancel over a body.
        let expected = (gravity::<D>() * mass + f) * h;
        assert!(
            (dp - expected).norm() <= 1e-6 * (mass * G * h + f.norm() * h),
            "step {}: dp {dp:?} against h (m g + F) {expected:?}",
            sim.state().step
        );
        // The points' forces add up to the nodes' contact forces.
        let points: SVector<f64, D> = sim.contacts().iter().map(|c| c.force()).sum();
        let nodal: SVector<f64, D> = (0..sim.bodies()[0].mesh.nodes.len())
            .map(|n| sim.node_contact_force(a, n).unwrap())
            .sum();
        assert!((nodal - points).norm() <= 1e-9 * (1.0 + f.norm()));
        for e in sim.contact_events() {
            match e {
                ContactEvent::Started(t) => {
                    assert_eq!(*t, Touching::BodyObstacle(a, floor));
                    started += 1;
                }
                ContactEvent::Stopped(_) => stopped += 1,
            }
        }
    }
    // Landed (the block may bounce: events come in pairs), and touching at the end.
    assert!(
        started >= 1 && started == stopped + 1,
        "{started} starts, {stopped} stops"
    );
    assert!(sim
        .touching()
        .any(|t| *t == Touching::BodyObstacle(a, floor)));
    // Resting: the floor carries the weight.
    let f = sim.obstacle_contact_force(floor).unwrap();
    assert!(
        (f[D - 1] - mass * G).abs() < 0.05 * mass * G,
        "floor force {} N against the weight {} N",
        f[D - 1],
        mass * G
    );
}

fn bodies_come_and_go_between_steps<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let mut sim = scene::<D>();
    let a = sim.body_id("a").unwrap();
    for _ in 0..20 {
        sim.step().unwrap();
    }
    // Spawned on top of `a` while it runs: they touch, the body pair's forces are opposite.
    let b = sim.add_body(cube("b", 0.0, 0.103)).unwrap();
    let mass_b = sim.body_mass(b).unwrap();
    let h = sim.settings().time_step;
    let mut touched = false;
    for _ in 0..120 {
        let p0 = momentum(&sim, b);
        sim.step().unwrap();
        let on_a = sim.contact_force_between(a, b).unwrap();
        let on_b = sim.contact_force_between(b, a).unwrap();
        assert!((on_a + on_b).norm() <= 1e-12 * (1.0 + on_a.norm()));
        touched |= on_a[D - 1] < 0.0;
        // b touches only a: M (v1 - v0) = h (m g + F_ab).
        let dp = momentum(&sim, b) - p0;
        let expected = (gravity::<D>() * mass_b + on_b) * h;
        assert!(
            (dp - expected).norm() <= 1e-6 * (mass_b * G + on_b.norm()) * h,
            "step {}: dp {dp:?} against h (m g + F) {expected:?}",
            sim.state().step
        );
    }
    assert!(touched, "b rests on a and pushes it down");
    // Removing `a` leaves `b` where it was, with its velocity; then `b` falls to the floor.
    let (xb, vb) = (sim.position(b, 3).unwrap(), sim.velocity(b, 3).unwrap());
    sim.remove_body(a).unwrap();
    assert_eq!(sim.position(b, 3).unwrap(), xb);
    assert_eq!(sim.velocity(b, 3).unwrap(), vb);
    assert!(sim.position(a, 0).is_err());
    for _ in 0..240 {
        sim.step().unwrap();
    }
    let lowest = lowest_point(&sim, b);
    assert!(
        lowest.abs() < 2e-3,
        "b lies on the floor: lowest point {lowest} m"
    );
    // A snapshot continues bit for bit, whatever happened to the original since.
    let mut copy = sim.try_clone().unwrap();
    let saved = sim.state().clone();
    sim.step().unwrap();
    let next = sim.state().clone();
    copy.step().unwrap();
    assert_eq!(copy.state(), &next);
    sim.set_state(saved).unwrap();
    sim.step().unwrap();
    assert_eq!(sim.state(), &next);
    // No energy created by the edits.
    let e = sim.energies();
    let created = e.total() + e.dissipated - sim.initial_energy() - e.external_work;
    assert!(
        created < 0.05 * sim.energy_reference(),
        "energy created {created} J of {} J",
        sim.energy_reference()
    );
}

fn a_kinematic_obstacle_follows_its_poses<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    // A paddle (box obstacle) that the host poses every step: it moves along x into the block
    // and pushes it over the floor while turning slowly about its centre.
    let paddle = Obstacle::new(
        "paddle",
        ObstacleShape::Box {
            center: vec_d([-0.03, 0.05, 0.05]),
            half_extents: vec_d([0.02, 0.04, 0.1]),
        },
    );
    let mut sim = scene::<D>();
    let a = sim.body_id("a").unwrap();
    let floor = sim.obstacle_id("floor").unwrap();
    let id = sim.add_obstacle(paddle).unwrap();
    let mass = sim.body_mass(a).unwrap();
    let h = sim.settings().time_step;
    let mut touched = false;
    for i in 1..=90 {
        let t = i as f64 * h;
        let translation = vec_d::<D>([0.2 * t, 0.0, 0.0]);
        let angle = 0.2 * t;
        let rotation = SMatrix::<f64, D, D>::from_fn(|r, c| match (r, c) {
            (0, 0) | (1, 1) => angle.cos(),
            (1, 0) => angle.sin(),
            (0, 1) => -angle.sin(),
            (2, 2) => 1.0,
            _ => 0.0,
        });
        sim.set_obstacle_next_pose(id, translation, rotation)
            .unwrap();
        let p0 = momentum(&sim, a);
        sim.step().unwrap();
        assert!((sim.obstacle_translation(id).unwrap() - translation).norm() < 1e-12);
        assert!((sim.obstacle_rotation(id).unwrap() - rotation).amax() < 1e-12);
        // M (v1 - v0) = h (m g + F_floor + F_paddle).
        let (f_floor, f_paddle) = (
            sim.obstacle_contact_force(floor).unwrap(),
            sim.obstacle_contact_force(id).unwrap(),
        );
        let dp = momentum(&sim, a) - p0;
        let expected = (gravity::<D>() * mass + f_floor + f_paddle) * h;
        let scale = (mass * G + f_floor.norm() + f_paddle.norm()) * h;
        assert!(
            (dp - expected).norm() <= 1e-6 * scale,
            "step {i}: {dp:?} against {expected:?}"
        );
        touched |= f_paddle[0] > 0.0;
    }
    assert!(touched, "the paddle pushed the block");
    assert!(
        sim.velocity(a, 0).unwrap()[0] > 0.1,
        "the block moves with the paddle"
    );
    // A step of another size than the configured one reaches the pose too (its velocity is
    // taken over the step actually run), and a velocity set afterwards replaces the pose.
    let rotation = sim.obstacle_rotation(id).unwrap();
    let target = sim.obstacle_translation(id).unwrap() + vec_d::<D>([1e-3, 0.0, 0.0]);
    sim.set_obstacle_next_pose(id, target, rotation).unwrap();
    sim.advance(h / 4.0, &mut NullRecorder).unwrap();
    assert!((sim.obstacle_translation(id).unwrap() - target).norm() < 1e-12);
    sim.set_obstacle_next_pose(id, target * 2.0, rotation)
        .unwrap();
    sim.set_obstacle_velocity(id, SVector::zeros()).unwrap();
    sim.step().unwrap();
    assert!((sim.obstacle_translation(id).unwrap() - target).norm() < 1e-12);
    let bad = SMatrix::<f64, D, D>::identity() * 2.0;
    assert!(sim
        .set_obstacle_next_pose(id, SVector::zeros(), bad)
        .is_err());
}

/// The rubber block dropped 2 mm at a game's step (four steps a frame at 60 Hz) lands and
/// rests: the frames' events are every step's, one landing, no energy created. With a
/// second block dropped onto it, the two rest on each other. (On 2026-11-23 the default
/// method rattled this block, 16 landings in 0.5 s, and the 3D pair created 3.4 J on a
/// 0.97 J reference.)
fn a_soft_block_at_a_games_step_lands_and_rests<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    for stacked in [false, true] {
        let mut by_frames = scene::<D>();
        let mut by_steps = scene::<D>();
        if stacked {
            by_frames.add_body(cube("b", 0.0, 0.105)).unwrap();
            by_steps.add_body(cube("b", 0.0, 0.105)).unwrap();
        }
        let mut driver = FixedTimestep::default();
        let (mut frame_events, mut step_events) = (Vec::new(), Vec::new());
        let mut last_event_frame = 0;
        for f in 0..30 {
            let frame = driver.advance(&mut by_frames, 1.0 / 60.0).unwrap();
            assert_eq!(frame.steps, 4);
            if !frame.events.is_empty() {
                last_event_frame = f;
            }
            frame_events.extend(frame.events);
            for _ in 0..4 {
                by_steps.step().unwrap();
                step_events.extend_from_slice(by_steps.contact_events());
            }
        }
        assert_eq!(by_frames.state(), by_steps.state());
        assert_eq!(
            frame_events, step_events,
            "a frame reports every step's events"
        );
        let sim = by_frames;
        let a = sim.body_id("a").unwrap();
        let floor = sim.obstacle_id("floor").unwrap();
        let landings = frame_events
            .iter()
            .filter(|e| **e == ContactEvent::Started(Touching::BodyObstacle(a, floor)))
            .count();
        let e = sim.energies();
        let created = e.total() + e.dissipated - sim.initial_energy() - e.external_work;
        let lowest = lowest_point(&sim, a);
        eprintln!(
            "D = {D}, stacked {stacked}: {landings} landings, the last event in frame \
             {last_event_frame}, {created:.1e} J created, kinetic {:.1e} J, lowest {lowest:.1e} m",
            e.kinetic
        );
        // Measured 2026-11-30: 2 landings alone (one bounce), 2 (2D) and 4 (3D) under the
        // second block; the last event in frame 2 alone, 7 and 9 stacked; 1e-12 to 3e-9 J
        // created.
        let (most_landings, settled_by) = if stacked { (4, 12) } else { (2, 4) };
        assert!(
            (1..=most_landings).contains(&landings),
            "stacked {stacked}: {landings} landings"
        );
        assert!(
            last_event_frame <= settled_by,
            "stacked {stacked}: contact changes until frame {last_event_frame}"
        );
        let reference = sim.energy_reference();
        assert!(
            created.abs() <= 1e-6 * reference,
            "stacked {stacked}: {created} J created of {reference} J"
        );
        assert!(e.kinetic <= 1e-5 * reference, "still moving: {e:?}");
        // Implicit projection's end-of-step correction leaves depths of round-off, below
        // 1e-3 gap_tolerance = 1e-12 m (measured 4.1e-13 and 5.6e-13 m, 2026-12-02).
        assert!((-1e-12..1e-9).contains(&lowest), "lowest point {lowest} m");
    }
}

fn gravity_scale_and_the_fixed_timestep<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let mut sim = Simulation::<D>::builder()
        .time_step(1.0 / 240.0)
        .gravity(gravity())
        .body(cube("floating", 0.0, 1.0).with_gravity_scale(0.0))
        .body(cube("falling", 0.5, 1.0))
        .build()
        .unwrap();
    let (floating, falling) = (
        sim.body_id("floating").unwrap(),
        sim.body_id("falling").unwrap(),
    );
    let mut driver = FixedTimestep::default();
    let mut steps = 0;
    for _ in 0..60 {
        let frame = driver.advance(&mut sim, 1.0 / 60.0).unwrap();
        steps += frame.steps;
        assert!(frame.lag < 1.0 / 240.0 && !frame.behind);
    }
    assert_eq!(steps, 240, "one second of host time at 240 Hz");
    assert!((sim.state().time - 1.0).abs() < 1e-9);
    // Free fall for 1 s: v = -g t; the weightless body does not move.
    assert!((sim.velocity(falling, 0).unwrap()[D - 1] + G).abs() < 1e-6);
    assert!(sim.velocity(floating, 0).unwrap().norm() < 1e-12);
    sim.set_gravity_scale(floating, 1.0).unwrap();
    sim.step().unwrap();
    assert!(sim.velocity(floating, 0).unwrap()[D - 1] < 0.0);
    // A frame far too long: at most 8 steps run, the rest is lag.
    let frame = driver.advance(&mut sim, 1.0).unwrap();
    assert_eq!(frame.steps, 8);
    assert!(frame.behind && (frame.lag - (1.0 - 8.0 / 240.0)).abs() < 1e-9);
    assert!(driver.advance(&mut sim, f64::NAN).is_err());
}

/// `body_momentum` of a body in free fall (no obstacle) is `m g t` to round-off, is the sum
/// of `M v` over its nodes, and belongs to that body only (a second one at rest beside it),
/// with consistent and lumped mass.
fn momentum_of_a_free_fall<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    for mass in [MassKind::Consistent, MassKind::Lumped] {
        let h = 1.0 / 240.0;
        let mut sim = Simulation::<D>::builder()
            .time_step(h)
            .gravity(gravity())
            .mass(mass)
            .body(Body::new(
                "falling",
                block([0.1, 0.1, 0.1], [2, 2, 2], false),
                rubber(),
            ))
            .body(cube("still", 1.0, 0.0).with_gravity_scale(0.0))
            .build()
            .unwrap();
        let (falling, still) = (
            sim.body_id("falling").unwrap(),
            sim.body_id("still").unwrap(),
        );
        let m = sim.body_mass(falling).unwrap();
        assert_eq!(
            sim.body_momentum(falling).unwrap(),
            SVector::<f64, D>::zeros()
        );
        for _ in 0..24 {
            sim.step().unwrap();
        }
        let t = sim.state().time;
        let p = sim.body_momentum(falling).unwrap();
        let expected = gravity::<D>() * (m * t);
        assert!(
            (p - expected).norm() <= 1e-12 * expected.norm(),
            "{mass:?}: {p:?} against m g t = {expected:?}"
        );
        // The sum of M v over the body's degrees of freedom, from the public mass matrix.
        let mv = sim.mass_matrix().mul(&sim.state().velocity);
        let mut sum = SVector::<f64, D>::zeros();
        for n in sim.body_nodes(falling).unwrap() {
            for d in 0..D {
                sum[d] += mv[n * D + d];
            }
        }
        assert!(
            (p - sum).norm() <= 1e-14 * sum.norm(),
            "{p:?} against {sum:?}"
        );
        assert_eq!(
            sim.body_momentum(still).unwrap(),
            SVector::<f64, D>::zeros()
        );
        sim.remove_body(still).unwrap();
        assert!(sim.body_momentum(still).is_err(), "a stale handle");
    }
}

/// Explicit projection between two bodies: its end-of-step impulses keep the pair's momentum
/// (one impulse, opposite on the two sides; to 1e-9: the internal forces of the squeezed
/// blocks sum to zero to round-off), and `contact_force_between` includes them.
fn projection_impulses_between_bodies<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let h = 1.0 / 240.0;
    let mut v = SVector::<f64, D>::zeros();
    v[0] = -2.0;
    let mut sim = Simulation::<D>::builder()
        .time_step(h)
        .body(cube("a", 0.0, 0.0))
        .body(cube("b", 0.101, 0.0).with_velocity(v))
        .contact(ContactSettings {
            method: ContactMethod::ExplicitProjection,
            ..Default::default()
        })
        .build()
        .unwrap();
    let (a, b) = (sim.body_id("a").unwrap(), sim.body_id("b").unwrap());
    let total = |sim: &Simulation<D>| sim.body_momentum(a).unwrap() + sim.body_momentum(b).unwrap();
    let p_start = total(&sim);
    let mut pushed = 0;
    for _ in 0..60 {
        let p0 = sim.body_momentum(b).unwrap();
        sim.step().unwrap();
        let on_b = sim.contact_force_between(b, a).unwrap();
        let dp = sim.body_momentum(b).unwrap() - p0;
        assert!(
            (dp - on_b * h).norm() <= 1e-9 * p_start.norm(),
            "step {}: dp {dp:?} against h F {:?}",
            sim.state().step,
            on_b * h
        );
        assert!(
            (total(&sim) - p_start).norm() <= 1e-9 * p_start.norm(),
            "step {}: momentum {:?} against {p_start:?}",
            sim.state().step,
            total(&sim)
        );
        if on_b[0] > 0.0 {
            pushed += 1;
        }
    }
    assert!(pushed > 0, "b hit a");
    // The impact passed momentum on: a moves the way b came.
    assert!(sim.body_momentum(a).unwrap()[0] < 0.3 * p_start[0]);
}

/// `ContactMethod` parses the scene file's names and lists them when it cannot.
#[test]
fn contact_method_from_its_scene_name() {
    for method in ContactMethod::ALL {
        assert_eq!(method.name().parse::<ContactMethod>().unwrap(), method);
    }
    let e = "softway".parse::<ContactMethod>().unwrap_err();
    assert_eq!(
        e.to_string(),
        "invalid parameter `contact method`: found \"softway\", expected one of soft_way, \
         implicit_projection, augmented_lagrangian, explicit_projection"
    );
}

both_dims!(
    momentum_of_a_free_fall,
    stale_and_forged_handles_are_errors,
    contact_forces_balance_the_change_of_momentum,
    bodies_come_and_go_between_steps,
    a_kinematic_obstacle_follows_its_poses,
    gravity_scale_and_the_fixed_timestep,
    a_soft_block_at_a_games_step_lands_and_rests,
    projection_impulses_between_bodies,
);

#[test]
fn simulations_are_send_and_sync() {
    fn send_sync<T: Send + Sync>() {}
    send_sync::<Simulation<2>>();
    send_sync::<Simulation<3>>();
    send_sync::<State>();
    send_sync::<FixedTimestep>();
}
