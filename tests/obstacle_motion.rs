//! Obstacles that follow a piecewise-constant motion schedule (`Obstacle::motion`, the scene's
//! `motion`): the displacement is the exact integral of the schedule whatever the step, the
//! obstacle stops after the last piece, and a plate driven down then held compresses a block
//! by what it travelled. A floor rising at a constant velocity lifts a block resting on it.

use crate::common;

use common::{block, vec_d};
use softway::contact::{MotionSegment, ObstacleShape};
use softway::dim::{Dim, SpatialDim};
use softway::prelude::*;

fn piece<const D: usize>(until: f64, v: [f64; 3]) -> MotionSegment<D> {
    MotionSegment {
        until,
        velocity: vec_d(v),
        angular_velocity: Vec::new(),
    }
}

/// A free steel block and `obstacle`.
fn block_and<const D: usize>(obstacle: Obstacle<D>, h: f64) -> softway::Result<Simulation<D>>
where
    Dim<D>: SpatialDim<D>,
{
    let mesh: Mesh<D> = block([0.1, 0.1, 0.1], [1, 1, 1], false);
    let steel = Material::LinearElastic(LinearElastic::new(2e11, 0.3, 7800.0).unwrap());
    Simulation::<D>::builder()
        .time_step(h)
        .body(Body::new("block", mesh, steel))
        .obstacle(obstacle)
        .contact(ContactSettings {
            method: ContactMethod::SoftWay,
            penalty: 1e9,
            ..Default::default()
        })
        .build()
}

/// A free block and a ball far from it; the ball follows `motion`.
fn ball_on_a_schedule<const D: usize>(motion: Vec<MotionSegment<D>>, h: f64) -> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    let ball = ObstacleShape::Ball {
        center: vec_d([10.0, 10.0, 10.0]),
        radius: 0.5,
    };
    block_and(Obstacle::new("ball", ball).with_motion(motion), h).unwrap()
}

fn the_displacement_is_the_integral_of_the_schedule<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let motion = vec![
        piece::<D>(0.2, [0.05, 0.0, 0.0]),
        piece::<D>(0.6, [0.0, 0.1, 0.0]),
    ];
    // A step that does not divide the pieces' ends: the steps across them are averaged.
    let mut sim = ball_on_a_schedule::<D>(motion, 0.03);
    let mut straddling = None;
    while sim.state().time < 1.0 - 1e-12 {
        let t0 = sim.state().time;
        sim.step().unwrap();
        if t0 < 0.2 && sim.state().time > 0.2 {
            straddling = Some(sim.state().obstacle_velocities.clone());
        }
    }
    let t = sim.obstacle_translation(sim.obstacle_ids()[0]).unwrap();
    let expected = vec_d::<D>([0.05 * 0.2, 0.1 * 0.4, 0.0]);
    assert!((t - expected).norm() < 1e-12, "{t:?} vs {expected:?}");
    // The step from 0.18 to 0.21: 0.02 s at (0.05, 0) and 0.01 s at (0, 0.1).
    let v = straddling.expect("a step across t = 0.2");
    assert!((v[0] - 0.05 * 0.02 / 0.03).abs() < 1e-12, "{v:?}");
    assert!((v[1] - 0.1 * 0.01 / 0.03).abs() < 1e-12, "{v:?}");
    // Stopped after the last piece.
    assert!(sim.state().obstacle_velocities.iter().all(|v| *v == 0.0));
    // A scheduled obstacle's velocity is not the host's to set.
    assert!(sim
        .set_obstacle_velocity(sim.obstacle_ids()[0], vec_d([1.0, 0.0, 0.0]))
        .is_err());
}

fn bad_schedules_are_refused<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let build = |motion: Vec<MotionSegment<D>>| {
        let plane = ObstacleShape::Halfspace {
            point: vec_d([0.0, -1.0, -1.0]),
            normal: vec_d([0.0, 1.0, 1.0]),
        };
        block_and(Obstacle::new("plane", plane).with_motion(motion), 1e-3)
    };
    let not_increasing = vec![piece::<D>(0.5, [0.0; 3]), piece::<D>(0.5, [0.0; 3])];
    let err = build(not_increasing).err().expect("refused").to_string();
    assert!(err.contains("motion.1.until"), "{err}");
    let infinite = vec![piece::<D>(f64::INFINITY, [0.0; 3])];
    assert!(build(infinite).is_err());
    // Angular velocities need 1 (2D) or 3 (3D) finite components.
    for omega in [
        vec![0.5; <Dim<D>>::ANGULAR + 1],
        vec![f64::NAN; <Dim<D>>::ANGULAR],
    ] {
        let mut turning = piece::<D>(0.5, [0.0; 3]);
        turning.angular_velocity = omega;
        let err = build(vec![turning]).err().expect("refused").to_string();
        assert!(err.contains("motion.0.angular_velocity"), "{err}");
    }
}

fn a_plate_driven_down_then_held_compresses_a_block<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    // A 0.1 m block on a floor; a plate 1 mm above it comes down at 0.02 m/s for 0.1 s
    // (2 mm: 1 mm to touch, 1 mm into the block), then holds.
    let mesh: Mesh<D> = block([0.1, 0.1, 0.1], [4, 4, 4], false);
    let rubber = Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap());
    let (mut up, mut top) = ([0.0; 3], [0.0; 3]);
    up[D - 1] = 1.0;
    top[D - 1] = 0.101;
    let mut down = [0.0; 3];
    down[D - 1] = -0.02;
    let mut sim = Simulation::<D>::builder()
        .time_step(2e-3)
        .body(Body::new("block", mesh, rubber))
        .obstacle(Obstacle::new(
            "floor",
            ObstacleShape::Halfspace {
                point: vec_d([0.0; 3]),
                normal: vec_d(up),
            },
        ))
        .obstacle(
            Obstacle::new(
                "plate",
                ObstacleShape::Halfspace {
                    point: vec_d(top),
                    normal: -vec_d::<D>(up),
                },
            )
            .with_motion(vec![piece::<D>(0.1, down)]),
        )
        .build()
        .unwrap();
    let mut last = None;
    while sim.state().time < 0.3 - 1e-12 {
        last = Some(sim.step().unwrap());
    }
    let report = last.unwrap();
    assert!(
        (sim.obstacle_translation(sim.obstacle_ids()[1]).unwrap()[D - 1] + 0.002).abs() < 1e-12
    );
    // The block is squeezed between floor and plate by 1 mm of 0.1 m, frictionless: forces
    // along the axis of E A (1 mm / 0.1 m), plane strain stiffening it by 1/(1 - nu^2). The
    // plate's stop leaves the block ringing, a strain of about v/c = 0.02 / 31.6 = 6e-4 on
    // the 1e-2: within 10 %. (Default contact settings: implicit projection, no penetration
    // taken off the squeeze. Measured 2026-11-30: the plate's force 1.5 % (2D) and 0.8 % (3D)
    // above it, the floor's 2.0 % and 0.4 % below.)
    let (floor, plate) = (
        report.contact_forces[0][D - 1],
        report.contact_forces[1][D - 1],
    );
    eprintln!("D = {D}: floor {floor} N, plate {plate} N");
    assert!(floor > 0.0 && plate < 0.0, "{floor} {plate}");
    let (area, stiffening) = if D == 2 {
        (0.1, 1.0 / (1.0 - 0.3 * 0.3))
    } else {
        (0.01, 1.0)
    };
    let expected = 1e6 * stiffening * area * 0.01;
    for force in [floor, -plate] {
        assert!(
            (force / expected - 1.0).abs() < 0.1,
            "force {force} N against E A strain {expected} N"
        );
    }
}

both_dims!(
    the_displacement_is_the_integral_of_the_schedule,
    bad_schedules_are_refused,
    a_plate_driven_down_then_held_compresses_a_block,
);

/// A floor rising at 0.3 m/s from t = 0 lifts a block resting on it (1/60 s, the default
/// method): the block rides it, and the energy account ends off by exactly the offset the book
/// describes (time scheme, energy accounting): a constant load's work measured on u rather
/// than on the shadow displacement w = u + a h v misses `a h f . (v - v(0))`, here
/// `0.25 h m g 0.3` (0.1226 J per metre of depth in 2D, 1.226e-2 J in 3D: the account reads
/// it as energy lost, to six digits). An open defect of issue 10 (the
/// account should close): this test pins the cause, and changes when the account is measured
/// on w.
fn a_rising_floor_lifts_a_block<const D: usize>()
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    use softway::material::{LinearElastic, Material};
    use softway::simulation::Body;
    let mesh = common::block::<D>([0.1, 0.1, 0.1], [2, 2, 2], D == 3);
    let material = Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap());
    let h = 1.0 / 60.0;
    let mut gravity = common::vec_d::<D>([0.0; 3]);
    gravity[D - 1] = -9.81;
    let mut rising = common::vec_d::<D>([0.0; 3]);
    rising[D - 1] = 0.3;
    let mut sim = Simulation::<D>::builder()
        .time_step(h)
        .gravity(gravity)
        .body(Body::new("block", mesh, material).with_damping(0.0, 1e-3))
        .obstacle(common::floor::<D>().with_velocity(rising))
        .build()
        .unwrap();
    for _ in 0..90 {
        sim.step().unwrap();
    }
    let n = sim.state().velocity.len() / D;
    let mean = |field: &[f64]| field.iter().skip(D - 1).step_by(D).sum::<f64>() / n as f64;
    let (lifted, speed) = (mean(&sim.state().displacement), mean(&sim.state().velocity));
    let e = sim.energies();
    let account = e.total() - sim.initial_energy() - e.external_work + e.dissipated;
    let mass = 1000.0 * 0.1_f64.powi(D as i32);
    let offset = 0.25 * h * mass * 9.81 * 0.3;
    eprintln!(
        "{D}D: lifted {lifted:.5} m at {speed:.6} m/s; account {account:.5e} J against the \
         offset {offset:.5e} J"
    );
    assert!((lifted - 0.45).abs() < 1e-3, "{D}D: lifted {lifted} m");
    assert!((speed - 0.3).abs() < 1e-4, "{D}D: {speed} m/s");
    assert!(
        (account + offset).abs() < 1e-3 * offset,
        "{D}D: account {account} J, offset {offset} J"
    );
}

#[test]
fn a_rising_floor_lifts_a_block_d2() {
    a_rising_floor_lifts_a_block::<2>();
}

#[test]
fn a_rising_floor_lifts_a_block_d3() {
    a_rising_floor_lifts_a_block::<3>();
}
