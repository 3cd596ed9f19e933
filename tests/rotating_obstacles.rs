//! Rotating obstacles: motion schedules with an angular velocity about a pivot
//! (`MotionSegment::angular_velocity`, `Obstacle::pivot`; the scene's `angular_velocity` and
//! `pivot`), in 2D and 3D, with the default scheme and contact method (implicit projection):
//!
//! * the pose is the exact composition of the schedule's turns about the moving pivot, and a
//!   simulation rebuilt from its model and state continues bit for bit;
//! * every shape's gap, normal and closest point in a turned pose match the turned shape's
//!   (a turned box is no longer axis-aligned); the broad phase sees what a paddle sweeps
//!   within one step;
//! * a frictionless block on a floor (a half-space, or a box plate) tilting at omega stays on
//!   it and slides down as a point mass on a rotating line does: the floor's force is along
//!   the turned normal, of size `m (g cos theta + 2 omega r' - d omega^2)`, and the block
//!   reaches `r(s) = g / (2 omega^2) (sin omega s - sinh omega s)`;
//! * with Coulomb friction a block on a turntable (3D) or on top of a turning drum (2D) moves
//!   with the surface, `omega x r`;
//! * scene files: `angular_velocity` and `pivot` are read; a wrong length or NaN is refused
//!   naming the key.

use crate::common;

use common::{block, energy_error, vec_d};
use nalgebra::{Rotation2, Rotation3, SMatrix, SVector, Vector3};
use softway::contact::gap::posed_obstacle_gap;
use softway::contact::{
    ContactSurface, DetectionOptions, Detector, FrictionLaw, Master, MotionSegment,
};
use softway::dim::{Dim, SpatialDim};
use softway::prelude::*;
use softway::simulation::RayleighDamping;

const G: f64 = 9.81;

/// The rotation `exp(turn)` (`turn`: an angle in 2D, a rotation vector in 3D).
fn rotation<const D: usize>(turn: &[f64]) -> SMatrix<f64, D, D> {
    if D == 2 {
        let r = Rotation2::new(turn[0]);
        SMatrix::from_fn(|i, j| r.matrix()[(i, j)])
    } else {
        let r = Rotation3::new(Vector3::new(turn[0], turn[1], turn[2]));
        SMatrix::from_fn(|i, j| r.matrix()[(i, j)])
    }
}

/// The angular velocity that tilts the up axis (the last) towards -x at `w` [rad/s]: up turns
/// to `(-sin theta, [0,] cos theta)` and x to `(cos theta, [0,] sin theta)`.
fn tilt<const D: usize>(w: f64) -> Vec<f64> {
    if D == 2 {
        vec![w]
    } else {
        vec![0.0, -w, 0.0]
    }
}

/// The unit vector along axis `k`.
fn axis<const D: usize>(k: usize) -> SVector<f64, D> {
    let mut e = SVector::zeros();
    e[k] = 1.0;
    e
}

fn piece<const D: usize>(until: f64, v: [f64; 3], w: Vec<f64>) -> MotionSegment<D> {
    MotionSegment {
        until,
        velocity: vec_d(v),
        angular_velocity: w,
    }
}

/// The block's mass [kg], centre of mass [m] and its velocity [m/s] (from the mass matrix).
fn centre_of_mass<const D: usize>(sim: &Simulation<D>) -> (f64, SVector<f64, D>, SVector<f64, D>)
where
    Dim<D>: SpatialDim<D>,
{
    let positions: Vec<f64> = sim
        .positions()
        .iter()
        .flat_map(|x| x.iter().copied())
        .collect();
    let m = sim.mass_matrix();
    let (mx, mv) = (m.mul(&positions), m.mul(&sim.state().velocity));
    let mass = sim.body_mass(sim.body_ids()[0]).unwrap();
    let sum = |v: &[f64]| {
        SVector::<f64, D>::from_fn(|k, _| v.iter().skip(k).step_by(D).sum::<f64>() / mass)
    };
    (mass, sum(&mx), sum(&mv))
}

fn the_pose_is_the_exact_composition_of_the_schedule<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let w1 = tilt::<D>(1.0);
    let w2: Vec<f64> = if D == 2 {
        vec![-3.0]
    } else {
        vec![0.5, 0.0, 1.5]
    };
    let motion = vec![
        piece::<D>(0.2, [0.1, 0.0, 0.0], w1.clone()),
        piece::<D>(0.5, [0.0, 0.2, 0.0], w2.clone()),
        piece::<D>(0.6, [0.0; 3], Vec::new()),
    ];
    let centre = vec_d::<D>([10.0, 10.0, 10.0]);
    let pivot = vec_d::<D>([9.0, 10.0, 10.0]);
    let ball = Obstacle::new(
        "ball",
        ObstacleShape::Ball {
            center: centre,
            radius: 0.5,
        },
    )
    .with_motion(motion)
    .with_pivot(pivot);
    let steel = Material::LinearElastic(LinearElastic::new(2e11, 0.3, 7800.0).unwrap());
    // A step that does not divide the pieces' ends: the steps across them compose the turns.
    let mut sim = Simulation::<D>::builder()
        .time_step(0.03)
        .body(Body::new(
            "block",
            block::<D>([0.1, 0.1, 0.1], [1, 1, 1], false),
            steel,
        ))
        .obstacle(ball)
        .build()
        .unwrap();
    let scale = |w: &[f64], t: f64| -> Vec<f64> { w.iter().map(|x| x * t).collect() };
    let mut straddling = None;
    let mut rebuilt = None;
    while sim.state().time < 1.0 - 1e-12 {
        let t0 = sim.state().time;
        sim.step().unwrap();
        if t0 < 0.2 && sim.state().time > 0.2 {
            straddling = Some(
                sim.obstacle_angular_velocity(sim.obstacle_ids()[0])
                    .unwrap(),
            );
        }
        if sim.state().step == 10 {
            rebuilt =
                Some(Simulation::from_parts(sim.model().clone(), sim.state().clone()).unwrap());
        }
    }
    let expected = rotation::<D>(&scale(&w2, 0.3)) * rotation::<D>(&scale(&w1, 0.2));
    let r = sim.obstacle_rotation(sim.obstacle_ids()[0]).unwrap();
    assert!((r - expected).amax() < 1e-12, "{r} vs {expected}");
    let t = vec_d::<D>([0.1 * 0.2, 0.2 * 0.3, 0.0]);
    assert!((sim.obstacle_translation(sim.obstacle_ids()[0]).unwrap() - t).norm() < 1e-12);
    assert!((sim.obstacle_pivot(sim.obstacle_ids()[0]).unwrap() - (pivot + t)).norm() < 1e-12);
    // The step from 0.18 to 0.21 turns by exp(0.01 w2) exp(0.02 w1).
    let w = straddling.expect("a step across t = 0.2");
    let across = rotation::<D>(&scale(&w2, 0.01)) * rotation::<D>(&scale(&w1, 0.02));
    assert!((rotation::<D>(&scale(&w, 0.03)) - across).amax() < 1e-12);
    // Stopped after the last piece.
    assert!(sim
        .obstacle_angular_velocity(sim.obstacle_ids()[0])
        .unwrap()
        .iter()
        .all(|w| *w == 0.0));
    // The ball's centre where the pose puts it: pivot + T + R (c - pivot).
    let posed = &sim.posed_obstacles()[0];
    let c = pivot + t + expected * (centre - pivot);
    let diagonal = SVector::<f64, D>::repeat(1.0).normalize();
    for dir in [axis::<D>(0), axis::<D>(1), diagonal] {
        let g = posed_obstacle_gap(posed, &(c + dir * 0.6), None, 0.0).unwrap();
        assert!((g.gap - 0.1).abs() < 1e-12 && (g.normal - dir).norm() < 1e-12);
    }
    // The simulation rebuilt at step 10 from its model and state continues bit for bit.
    let mut rebuilt = rebuilt.expect("step 10");
    while rebuilt.state().time < 1.0 - 1e-12 {
        rebuilt.step().unwrap();
    }
    assert_eq!(rebuilt.state(), sim.state());
    // A scheduled obstacle's angular velocity is not the host's to set.
    assert!(sim
        .set_obstacle_angular_velocity(sim.obstacle_ids()[0], &w1)
        .is_err());
}

#[test]
fn the_2d_angle_is_the_sum_of_the_turns() {
    let motion = vec![
        piece::<2>(0.25, [0.0; 3], vec![2.0]),
        piece::<2>(0.5, [0.0; 3], vec![-0.5]),
    ];
    let plate = Obstacle::new(
        "plate",
        ObstacleShape::Halfspace {
            point: vec_d([0.0, -5.0, 0.0]),
            normal: vec_d([0.0, 1.0, 0.0]),
        },
    )
    .with_motion(motion);
    let rubber = Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap());
    let mut sim = Simulation2::builder()
        .time_step(0.007)
        .body(Body::new(
            "b",
            block::<2>([0.1, 0.1, 0.1], [1, 1, 1], false),
            rubber,
        ))
        .obstacle(plate)
        .build()
        .unwrap();
    while sim.state().time < 0.6 {
        sim.step().unwrap();
    }
    let angle = sim.obstacle_angle(sim.obstacle_ids()[0]).unwrap();
    assert!((angle - (0.5 - 0.125)).abs() < 1e-13, "{angle}");
    // A host-driven obstacle turns at the angular velocity it is given.
    let mut sim = Simulation2::builder()
        .time_step(0.01)
        .body(Body::new(
            "b",
            block::<2>([0.1, 0.1, 0.1], [1, 1, 1], false),
            Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap()),
        ))
        .obstacle(
            Obstacle::new(
                "far",
                ObstacleShape::Ball {
                    center: vec_d([5.0, 5.0, 0.0]),
                    radius: 1.0,
                },
            )
            .with_angular_velocity(&[0.3]),
        )
        .build()
        .unwrap();
    for _ in 0..10 {
        sim.step().unwrap();
    }
    sim.set_obstacle_angular_velocity(sim.obstacle_ids()[0], &[-0.1])
        .unwrap();
    for _ in 0..10 {
        sim.step().unwrap();
    }
    assert!((sim.obstacle_angle(sim.obstacle_ids()[0]).unwrap() - 0.02).abs() < 1e-14);
    assert!(sim
        .set_obstacle_angular_velocity(sim.obstacle_ids()[0], &[f64::NAN])
        .is_err());
    assert!(sim
        .set_obstacle_angular_velocity(sim.obstacle_ids()[0], &[0.1, 0.2])
        .is_err());
}

/// Probes (nodes of a tiny body) against obstacles posed at `t0` and `t1`, with a margin.
fn pairs_over_step<const D: usize>(
    t0: &[Obstacle<D>],
    t1: &[Obstacle<D>],
    probes: &[SVector<f64, D>],
    margin: f64,
) -> (Vec<(usize, Master)>, Vec<softway::contact::ContactPair<D>>)
where
    Dim<D>: SpatialDim<D>,
{
    // One facet per run of consecutive probes keeps them all slaves.
    let facets: Vec<[usize; D]> = (0..probes.len())
        .map(|i| std::array::from_fn(|k| (i + k) % probes.len()))
        .collect();
    let surface = ContactSurface::from_facets(&[facets], &[0]);
    let mut det = Detector::new(
        surface,
        DetectionOptions {
            margin,
            ..Default::default()
        },
    );
    det.update_candidates_posed(probes, probes, t0, t1);
    let candidates = det.candidates().to_vec();
    (candidates, det.pairs(probes, t1))
}

fn turned_shapes_have_the_turned_gaps<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let turn: Vec<f64> = if D == 2 {
        vec![0.7]
    } else {
        vec![0.3, -0.5, 0.4]
    };
    let r = rotation::<D>(&turn);
    let t = vec_d::<D>([0.3, -0.2, 0.1]);
    let up = axis::<D>(D - 1);
    let given = vec_d::<D>([0.5, 0.5, 0.5]);
    let half = vec_d::<D>([0.3, 0.2, 0.1]);
    let facet_vertices: Vec<SVector<f64, D>> = if D == 2 {
        // Solid below: the segment runs right to left.
        vec![vec_d([1.0, 0.0, 0.0]), vec_d([0.0, 0.0, 0.0])]
    } else {
        vec![
            vec_d([0.0; 3]),
            vec_d([1.0, 0.0, 0.0]),
            vec_d([0.0, 1.0, 0.0]),
        ]
    };
    let centroid = facet_vertices.iter().sum::<SVector<f64, D>>() / D as f64;
    // (obstacle, its pivot as the test knows it, local probes with their gap and local normal)
    type Case<const D: usize> = (
        Obstacle<D>,
        SVector<f64, D>,
        Vec<(SVector<f64, D>, f64, SVector<f64, D>)>,
    );
    let mut cases: Vec<Case<D>> = Vec::new();
    let plane = Obstacle::new(
        "plane",
        ObstacleShape::Halfspace {
            point: vec_d([0.1, 0.2, 0.3]),
            normal: up,
        },
    );
    let on_plane = vec_d::<D>([0.1, 0.2, 0.3]) + axis::<D>(0) * 0.4;
    cases.push((
        plane,
        vec_d([0.1, 0.2, 0.3]),
        vec![
            (on_plane + up * 0.05, 0.05, up),
            (on_plane - up * 0.02, -0.02, up),
        ],
    ));
    let ball = Obstacle::new(
        "ball",
        ObstacleShape::Ball {
            center: vec_d([0.2, 0.0, 0.1]),
            radius: 0.4,
        },
    )
    .with_pivot(given);
    let dir = vec_d::<D>([1.0, -2.0, 0.5]).normalize();
    cases.push((
        ball,
        given,
        vec![
            (vec_d::<D>([0.2, 0.0, 0.1]) + dir * 0.45, 0.05, dir),
            (vec_d::<D>([0.2, 0.0, 0.1]) - up * 0.3, -0.1, -up),
        ],
    ));
    let bx = Obstacle::new(
        "box",
        ObstacleShape::Box {
            center: vec_d([0.0; 3]),
            half_extents: half,
        },
    );
    let x = axis::<D>(0);
    let corner = half + SVector::<f64, D>::repeat(0.03);
    cases.push((
        bx,
        SVector::zeros(),
        vec![
            // Outside the +x face, inside just under it, beyond a corner.
            (x * 0.35 + axis::<D>(1) * 0.05, 0.05, x),
            (x * 0.28, -0.02, x),
            (
                corner,
                0.03 * (D as f64).sqrt(),
                SVector::<f64, D>::repeat(1.0).normalize(),
            ),
        ],
    ));
    let facets = Obstacle::new(
        "facets",
        ObstacleShape::Facets {
            vertices: facet_vertices,
            indices: vec![(0..D).collect()],
        },
    );
    let mut inside = vec_d::<D>([0.3, 0.2, 0.0]);
    inside[D - 1] = 0.0;
    cases.push((
        facets,
        centroid,
        vec![
            (inside + up * 0.04, 0.04, up),
            (inside - up * 0.01, -0.01, up),
        ],
    ));
    for (obstacle, pivot, probes) in cases {
        let name = obstacle.name.clone();
        let posed = Obstacle {
            translation: t,
            rotation: r,
            ..obstacle.clone()
        };
        let world = |y: &SVector<f64, D>| pivot + t + r * (y - pivot);
        let points: Vec<SVector<f64, D>> = probes.iter().map(|p| world(&p.0)).collect();
        // Swept from the shape at t = 0 to the pose: the broad phase keeps every probe.
        let (_, pairs) = pairs_over_step(
            std::slice::from_ref(&obstacle),
            std::slice::from_ref(&posed),
            &points,
            1.0,
        );
        assert_eq!(pairs.len(), probes.len(), "{name}: {pairs:?}");
        for (pair, (local, gap, normal)) in pairs.iter().zip(&probes) {
            let n = r * normal;
            assert!(
                (pair.gap - gap).abs() < 1e-12,
                "{name}: gap {} vs {gap}",
                pair.gap
            );
            assert!((pair.normal - n).norm() < 1e-12, "{name}: normal");
            // Faces: the closest point is the probe moved back along the normal.
            if (pair.point - (world(local) - n * *gap)).norm() > 1e-12 {
                assert!(
                    name == "box" && matches!(pair.feature, softway::contact::Feature::Vertex(_))
                );
                assert!((pair.point - world(&half)).norm() < 1e-12, "{name}: corner");
            }
            if name != "facets" {
                let g = posed_obstacle_gap(&posed, &world(local), None, 0.0).unwrap();
                assert!((g.gap - gap).abs() < 1e-12 && (g.normal - n).norm() < 1e-12);
            }
        }
    }
}

fn the_broad_phase_sees_what_a_paddle_sweeps<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    // A paddle along x from its pivot at the origin, turning by 0.6 rad about the last axis
    // (z in 3D) within one step.
    let turn: Vec<f64> = if D == 2 {
        vec![0.6]
    } else {
        vec![0.0, 0.0, 0.6]
    };
    let paddle = Obstacle::new(
        "paddle",
        ObstacleShape::Box {
            center: vec_d([0.5, 0.0, 0.0]),
            half_extents: vec_d([0.5, 0.05, 0.05]),
        },
    )
    .with_pivot(SVector::zeros());
    let turned = Obstacle {
        rotation: rotation::<D>(&turn),
        ..paddle.clone()
    };
    // Halfway through the turn, 0.8 m out: 0.19 m clear of the paddle at both ends of the
    // step, inside it in the middle; 2.2 m out is beyond its reach.
    let at = |radius: f64| vec_d::<D>([radius * 0.3f64.cos(), radius * 0.3f64.sin(), 0.0]);
    let (candidates, pairs) = pairs_over_step(
        std::slice::from_ref(&paddle),
        std::slice::from_ref(&turned),
        &[at(0.8), at(2.2)],
        0.01,
    );
    assert!(
        candidates.contains(&(0, Master::Obstacle(0))),
        "{candidates:?}"
    );
    assert!(
        !candidates.contains(&(1, Master::Obstacle(0))),
        "{candidates:?}"
    );
    // Neither is near the paddle at the end of the step.
    assert!(pairs.is_empty());
}

/// Stiffness-proportional damping of 5 % of critical at the block's first axial mode (as in
/// tests/friction.rs): a material's own damping, so that the block's ringing does not hide
/// the forces measured.
fn material_damping() -> RayleighDamping {
    let omega = std::f64::consts::PI * (1e7f64 / 1000.0).sqrt() / (2.0 * 0.1);
    RayleighDamping {
        mass: 0.0,
        stiffness: 2.0 * 0.05 / omega,
    }
}

/// A 0.2 x 0.1 (x 0.1) m block (E = 1e7 Pa, 1000 kg/m^3, damped 5 %) resting on `plate`
/// under gravity, default scheme and contact method, `friction` against the plate.
fn block_on<const D: usize>(
    plate: Obstacle<D>,
    friction: FrictionLaw,
    at: [f64; 3],
    method: ContactMethod,
) -> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    let mut mesh = block::<D>([0.2, 0.1, 0.1], [4, 2, 2], false);
    mesh.translate(&vec_d(at));
    let damping = material_damping();
    Simulation::<D>::builder()
        .gravity(-axis::<D>(D - 1) * G)
        .body(
            Body::new(
                "block",
                mesh,
                Material::LinearElastic(LinearElastic::new(1e7, 0.3, 1000.0).unwrap()),
            )
            .with_damping(damping.mass, damping.stiffness),
        )
        .obstacle(plate.with_friction(friction))
        .contact(ContactSettings {
            method,
            // zeta for the penalty methods: a penetration of about 1e-7 m under the block.
            penalty: 1e10,
            ..ContactSettings::default()
        })
        .build()
        .unwrap()
}

/// A frictionless block on a plate that rests 0.2 s, then tilts at omega = 0.25 rad/s about
/// the point under the block's centre until 1 s (0.2 rad).
fn frictionless_block_on_a_tilting_plate<const D: usize>(boxed: bool)
where
    Dim<D>: SpatialDim<D>,
{
    let w = 0.25;
    let up = axis::<D>(D - 1);
    let mut pivot = vec_d::<D>([0.1, 0.05, 0.05]);
    pivot[D - 1] = 0.0;
    let shape = if boxed {
        let mut half = vec_d::<D>([1.0, 0.5, 0.5]);
        half[D - 1] = 0.05;
        ObstacleShape::Box {
            center: pivot - up * 0.05,
            half_extents: half,
        }
    } else {
        ObstacleShape::Halfspace {
            point: pivot,
            normal: up,
        }
    };
    let plate = Obstacle::new("plate", shape)
        .with_pivot(pivot)
        .with_motion(vec![
            piece::<D>(0.2, [0.0; 3], Vec::new()),
            piece::<D>(1.0, [0.0; 3], tilt::<D>(w)),
        ]);
    let mut sim = block_on::<D>(
        plate,
        FrictionLaw::Frictionless,
        [0.0; 3],
        ContactMethod::default(),
    );
    let frame = |theta: f64| {
        let r = rotation::<D>(&tilt::<D>(theta));
        (r * axis::<D>(0), r * up)
    };
    // Per step: time, |F|, m (g cos theta + 2 w r' - d w^2), m g cos theta.
    let mut rows = Vec::new();
    let mut worst_angle: f64 = 0.0;
    let mut heights = Vec::new();
    let (mut r0, mut v0, mut d0) = (0.0, 0.0, 0.0);
    let mut most = 0;
    while sim.state().time < 1.0 - 1e-9 {
        let report = sim.step().unwrap();
        most = most.max(report.iterations);
        let time = sim.state().time;
        let theta = w * (time - 0.2).max(0.0);
        let (tangent, normal) = frame(theta);
        let f = SVector::<f64, D>::from_column_slice(&report.contact_forces[0]);
        let (m, x, v) = centre_of_mass(&sim);
        if f.norm() > 0.5 * m * G {
            let along = f.dot(&normal);
            worst_angle = worst_angle.max((f - normal * along).norm().atan2(along));
        }
        // x = pivot + r t + d n, t and n turning at w: r' = v . t + w d, and the normal
        // balance N = m (g cos theta + 2 w r' - d w^2) = m (g cos theta + 2 w v . t + d w^2).
        let d = (x - pivot).dot(&normal);
        let along = v.dot(&tangent);
        if (time - 0.2).abs() < 5e-4 {
            // The block at rest as the plate starts turning under it: r' = w d.
            (r0, v0, d0) = ((x - pivot).dot(&tangent), along + w * d, d);
        }
        if time > 0.2 {
            heights.push(d - d0 * (1.0 + 0.5 * theta * theta));
            rows.push((
                time,
                f.norm(),
                m * (G * theta.cos() + 2.0 * w * along + d * w * w),
                m * G * theta.cos(),
            ));
        }
    }
    let name = if boxed { "box" } else { "half-space" };
    // The force is along the turned normal (frictionless).
    assert!(
        worst_angle < 1e-9,
        "{D}D {name}: force {worst_angle:e} rad off the normal"
    );
    // Window means of the force against the rotating line's N, and against m g cos theta.
    let mut worst_error: f64 = 0.0;
    let mut coriolis: f64 = 0.0;
    for k in 0..4 {
        let (a, b) = (0.2 + 0.2 * k as f64, 0.4 + 0.2 * k as f64);
        let window: Vec<_> = rows.iter().filter(|r| r.0 > a && r.0 <= b).collect();
        let n = window.len() as f64;
        let mean = |f: fn(&&(f64, f64, f64, f64)) -> f64| window.iter().map(f).sum::<f64>() / n;
        let (force, expected, plain) = (mean(|r| r.1), mean(|r| r.2), mean(|r| r.3));
        eprintln!(
            "{D}D {name}: t in ({a:.1}, {b:.1}]: |F| {force:.4} N, m (g cos + 2 w r' - d w^2) {expected:.4} N \
             ({:+.3} %), m g cos {plain:.4} N ({:+.3} %)",
            100.0 * (force / expected - 1.0),
            100.0 * (force / plain - 1.0)
        );
        worst_error = worst_error.max((force / expected - 1.0).abs());
        coriolis = coriolis.max((expected / plain - 1.0).abs());
    }
    // The slide along the plate: r'' = w^2 r - g sin(w s) from (r0, v0) at s = 0.
    let (_, x, _) = centre_of_mass(&sim);
    let (tangent, _) = frame(0.2);
    let r = (x - pivot).dot(&tangent);
    let s = 0.8;
    let a = G / (2.0 * w * w);
    let exact = a * (w * s).sin() + r0 * (w * s).cosh() + (v0 / w - a) * (w * s).sinh();
    // The height over the plate: the linear (small-strain) law dilates a body turned by
    // theta by theta^2 / 2 (the strain of (R - I) X), so the centre rises by d0 theta^2 / 2
    // (1 mm at 0.2 rad); what is left is the block's ringing.
    let lift = heights.iter().fold(0.0f64, |m, d| m.max(d.abs()));
    eprintln!(
        "{D}D {name}: slid r = {r:.5} m against {exact:.5} m ({:+.3} %), height over the plate off d0 (1 + theta^2 / 2) by {lift:.2e} m at most, \
         force off the normal {worst_angle:.1e} rad, iterations per step <= {most}, energy error {:.2e}",
        100.0 * (r / exact - 1.0),
        energy_error(&sim)
    );
    assert!(
        worst_error < 0.005,
        "{D}D {name}: normal force off by {worst_error}"
    );
    assert!(
        coriolis > 0.02,
        "the Coriolis term is resolved ({coriolis})"
    );
    assert!(
        (r / exact - 1.0).abs() < 0.005,
        "{D}D {name}: slid {r} m, expected {exact} m"
    );
    assert!(
        energy_error(&sim) < 1e-2,
        "{D}D {name}: energy error {}",
        energy_error(&sim)
    );
    assert!(
        lift < 1e-4,
        "{D}D {name}: the block left the plate by {lift} m"
    );
}

fn frictionless_block_on_a_tilting_floor<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    frictionless_block_on_a_tilting_plate::<D>(false);
}

fn frictionless_block_on_a_tilting_box<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    frictionless_block_on_a_tilting_plate::<D>(true);
}

/// Steps `sim` to `end` and returns the turning rate of the block's centre of mass about
/// `pivot` (its polar angle in the first two axes) over `settle..end`, relative to `omega`
/// (the mean over whole periods of the block's rocking and ringing, which the instantaneous
/// velocity shows: a few percent of omega x r).
fn carried<const D: usize>(
    sim: &mut Simulation<D>,
    omega: f64,
    pivot: SVector<f64, D>,
    settle: f64,
    end: f64,
) -> f64
where
    Dim<D>: SpatialDim<D>,
{
    let polar = |sim: &Simulation<D>| {
        let (_, x, _) = centre_of_mass(sim);
        let r = x - pivot;
        r[1].atan2(r[0])
    };
    let advance = |sim: &mut Simulation<D>, to: f64| {
        while sim.state().time < to - 1e-9 {
            sim.step()
                .unwrap_or_else(|e| panic!("t = {}: {e}", sim.state().time));
        }
    };
    advance(sim, settle);
    let start = polar(sim);
    advance(sim, end);
    (polar(sim) - start) / (omega * (end - settle)) - 1.0
}

/// 3D: a block 0.5 m from the axis of a turntable (a half-space turning about its normal at
/// 1 rad/s from t = 0.1 s), with Coulomb friction mu = 0.8, rides with it once friction has
/// brought it up to speed (mu g = 7.8 m/s^2 against 0.5 m/s: about 65 ms of slip, in which
/// it falls 0.033 rad behind and drifts 4 mm outwards): from 0.4 s to 1.1 s it turns at the
/// table's rate. The relative error of that rate.
fn turntable(method: ContactMethod) -> f64 {
    let table = Obstacle::new(
        "table",
        ObstacleShape::Halfspace {
            point: vec_d([0.0; 3]),
            normal: vec_d([0.0, 0.0, 1.0]),
        },
    )
    .with_motion(vec![
        piece::<3>(0.1, [0.0; 3], Vec::new()),
        piece::<3>(1.1, [0.0; 3], vec![0.0, 0.0, 1.0]),
    ]);
    let coulomb = FrictionLaw::Coulomb {
        coefficient: 0.8,
        regularization: 1e-6,
    };
    let mut sim = block_on::<3>(table, coulomb, [0.4, -0.05, 0.0], method);
    let error = carried(&mut sim, 1.0, SVector::zeros(), 0.4, 1.1);
    let (_, x, _) = centre_of_mass(&sim);
    let radius = (x.x * x.x + x.y * x.y).sqrt();
    eprintln!(
        "turntable, {method:?}: turning rate of the block {:+.3} % off the table's over 0.4..1.1 s, \
         radius {radius:.5} m at 1.1 s (0.5 m at rest)",
        100.0 * error
    );
    assert!((radius - 0.5).abs() < 1e-2, "{radius}");
    error
}

/// 2D: a block on top of a drum of radius 1 m turning at 0.2 rad/s clockwise from t = 0.1 s,
/// with Coulomb friction mu = 0.8, is carried over it at omega x r (0.2 m/s), tilting with it
/// (0.2 rad by 1.1 s: g sin 0.2 = 1.9 m/s^2 against mu g cos 0.2 = 7.7 m/s^2) and rocking on
/// it (about 6 Hz). The relative error of its turning rate about the drum's centre over
/// 0.4..1.1 s.
fn drum(method: ContactMethod) -> f64 {
    let centre = vec_d::<2>([0.1, -1.0, 0.0]);
    let drum = Obstacle::new(
        "drum",
        ObstacleShape::Ball {
            center: centre,
            radius: 1.0,
        },
    )
    .with_motion(vec![
        piece::<2>(0.1, [0.0; 3], Vec::new()),
        piece::<2>(1.1, [0.0; 3], vec![-0.2]),
    ]);
    let coulomb = FrictionLaw::Coulomb {
        coefficient: 0.8,
        regularization: 1e-6,
    };
    let mut sim = block_on::<2>(drum, coulomb, [0.0; 3], method);
    let error = carried(&mut sim, -0.2, centre, 0.4, 1.1);
    eprintln!(
        "drum, {method:?}: turning rate of the block {:+.3} % off the drum's over 0.4..1.1 s",
        100.0 * error
    );
    error
}

/// Friction carries the block under the soft way (zeta = 1e10 Pa/m) and under the default
/// method, implicit projection, which got through the block's coming up to speed only once a
/// stalled Newton was retried with the line search (the turntable's is ignored for its time).
mod carried_by_friction {
    use super::*;

    #[test]
    #[cfg_attr(
        not(feature = "parallel"),
        ignore = "slow without threads (20-50 s): runs with the default features; nothing it reaches depends on a feature but the threaded assembly, which determinism.rs checks"
    )]
    fn turntable_soft_way() {
        assert!(turntable(ContactMethod::SoftWay).abs() < 0.01);
    }

    #[test]
    fn drum_soft_way() {
        // Measured -0.67 %: the rocking is not averaged over whole periods exactly.
        assert!(drum(ContactMethod::SoftWay).abs() < 0.02);
    }

    /// Measured -0.010 %. It stopped at t = 0.187 s (nodes on either side of the spin axis
    /// flipping between stick and slip) until a stalled Newton was retried with the line search
    /// and the secant slip tangent.
    #[test]
    #[ignore = "slow (21 s, CI's budget): the soft way and the drum under implicit projection run"]
    fn turntable_implicit_projection() {
        assert!(turntable(ContactMethod::ImplicitProjection).abs() < 0.01);
    }

    /// Measured +0.134 %. It stopped at t = 0.102 s, Newton going on at relative residuals of
    /// 5.8e-8 and 9.95e-8 in turn (the floating-point floor of the velocity penalty at 1 m from
    /// the origin) until a residual at that floor counted as converged.
    #[test]
    fn drum_implicit_projection() {
        assert!(drum(ContactMethod::ImplicitProjection).abs() < 0.01);
    }
}

both_dims!(
    the_pose_is_the_exact_composition_of_the_schedule,
    turned_shapes_have_the_turned_gaps,
    the_broad_phase_sees_what_a_paddle_sweeps,
    frictionless_block_on_a_tilting_floor,
    frictionless_block_on_a_tilting_box,
);

/// Scene files: `angular_velocity` (a number in 2D, [wx, wy, wz] in 3D) and `pivot` are read;
/// a wrong length or a NaN is refused naming the key.
#[cfg(feature = "formats")]
mod scene_files {
    use super::*;

    fn scene(dimension: usize, obstacle: &str) -> String {
        let (body, shape) = if dimension == 2 {
            (
                r#"mesh = { generator = "rectangle", min = [0.0, 0.0], max = [0.2, 0.1], cells = [2, 1], element = "quad4" }"#,
                r#"shape = { type = "halfspace", point = [0.1, 0.0], normal = [0.0, 1.0] }"#,
            )
        } else {
            (
                r#"mesh = { generator = "box", min = [0.0, 0.0, 0.0], max = [0.2, 0.1, 0.1], cells = [2, 1, 1], element = "hex8" }"#,
                r#"shape = { type = "halfspace", point = [0.1, 0.05, 0.0], normal = [0.0, 0.0, 1.0] }"#,
            )
        };
        format!(
            "[simulation]\ndimension = {dimension}\ntime_step = 1.0e-3\nend_time = 0.01\n\n\
             [[bodies]]\nname = \"block\"\n{body}\n\
             material = {{ model = \"linear_elastic\", youngs_modulus = 1.0e6, poissons_ratio = 0.3, density = 1000.0 }}\n\n\
             [[obstacles]]\nname = \"plate\"\n{shape}\n{obstacle}\n"
        )
    }

    fn build<const D: usize>(obstacle: &str) -> softway::Result<softway::io::scene::Scene<D>>
    where
        Dim<D>: SpatialDim<D>,
    {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scene.toml");
        std::fs::write(&path, scene(D, obstacle)).unwrap();
        softway::io::scene::load(&path, &[]).and_then(|s| s.build::<D>())
    }

    fn refused<const D: usize>(obstacle: &str) -> String
    where
        Dim<D>: SpatialDim<D>,
    {
        match build::<D>(obstacle) {
            Ok(_) => panic!("accepted: {obstacle}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn angular_velocity_and_pivot_are_read() {
        let s = build::<2>(
            "motion = [{ until = 0.5, velocity = [0.0, 0.0], angular_velocity = 0.25 }]",
        )
        .unwrap();
        let o = &s.obstacles[0];
        assert_eq!(o.motion[0].angular_velocity, vec![0.25]);
        // Default pivot: the half-space's point.
        assert_eq!(o.pivot, None);
        assert_eq!(o.pivot_point(), vec_d::<2>([0.1, 0.0, 0.0]));
        let s = build::<3>(
            "motion = [{ until = 0.5, velocity = [0.0, 0.0, 0.0], angular_velocity = [0.0, -0.25, 0.0] }]\n\
             pivot = [0.0, 0.05, 0.0]",
        )
        .unwrap();
        let o = &s.obstacles[0];
        assert_eq!(o.motion[0].angular_velocity, vec![0.0, -0.25, 0.0]);
        assert_eq!(o.pivot_point(), vec_d::<3>([0.0, 0.05, 0.0]));
        let mut sim = s.simulation().unwrap();
        for _ in 0..10 {
            sim.step().unwrap();
        }
        let expected = rotation::<3>(&[0.0, -0.25 * 0.01, 0.0]);
        assert!((sim.obstacle_rotation(sim.obstacle_ids()[0]).unwrap() - expected).amax() < 1e-15);
    }

    #[test]
    fn bad_angular_velocities_and_pivots_are_refused() {
        let key = "obstacles.0.motion.0.angular_velocity";
        let cases2 = [
            (
                "angular_velocity = [0.0, 0.0, 0.5]",
                key,
                "a number [rad/s] in 2D",
            ),
            ("angular_velocity = nan", key, "finite numbers [rad/s]"),
            ("angular_velocity = \"fast\"", key, "a number [rad/s] in 2D"),
        ];
        for (value, key, expected) in cases2 {
            let text = format!("motion = [{{ until = 0.5, velocity = [0.0, 0.0], {value} }}]");
            let err = refused::<2>(&text);
            assert!(
                err.contains(key) && err.contains(expected),
                "{value}: {err}"
            );
        }
        let cases3 = [
            (
                "angular_velocity = 0.5",
                "a vector [wx, wy, wz] [rad/s] in 3D",
            ),
            (
                "angular_velocity = [0.0, 0.5]",
                "a vector [wx, wy, wz] [rad/s] in 3D",
            ),
            (
                "angular_velocity = [0.0, inf, 0.5]",
                "finite numbers [rad/s]",
            ),
        ];
        for (value, expected) in cases3 {
            let text = format!("motion = [{{ until = 0.5, velocity = [0.0, 0.0, 0.0], {value} }}]");
            let err = refused::<3>(&text);
            assert!(
                err.contains(key) && err.contains(expected),
                "{value}: {err}"
            );
        }
        let err = refused::<3>("pivot = [0.0, 0.1]");
        assert!(
            err.contains("obstacles.0.pivot") && err.contains("3 components"),
            "{err}"
        );
        let err = refused::<2>("pivot = [0.0, nan]");
        assert!(
            err.contains("obstacles.0.pivot") && err.contains("finite"),
            "{err}"
        );
    }
}
