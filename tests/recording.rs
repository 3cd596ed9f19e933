//! The Rerun recorder (feature `rerun`): the entity paths of a recording, one logged
//! configuration per iteration of the step reports, contact records drawn when present, and
//! results identical with and without recording.
#![cfg(feature = "rerun")]

use std::collections::BTreeMap;

use nalgebra::{SVector, Vector2, Vector3};
use softway::contact::{Obstacle, ObstacleShape};
use softway::prelude::*;
use softway::recording::rerun::{EntityRows, MemoryRecording, ENERGY_KINDS};
use softway::recording::{ColorField, ContactRecord, IterationInfo, RerunRecorder};
use softway::simulation::StepReport;

fn steel() -> Material {
    Material::LinearElastic(LinearElastic::new(210e9, 0.3, 7800.0).unwrap())
}

/// A 2D cantilever sagging under gravity.
fn cantilever_2d() -> Simulation2 {
    let mesh = rectangle(
        Vector2::new(0.0, 0.0),
        Vector2::new(1.0, 0.1),
        [10, 2],
        ElementKind::Quad4,
    )
    .unwrap();
    let beam = Body::new("beam", mesh, steel()).with_constraint_in_box(
        Vector2::new(-1e-9, -1.0),
        Vector2::new(1e-9, 1.0),
        [Some(0.0), Some(0.0)],
    );
    Simulation2::builder()
        .time_step(1e-4)
        .gravity(Vector2::new(0.0, -9.81))
        .body(beam)
        .build()
        .unwrap()
}

/// A 3D cantilever of hexahedra.
fn cantilever_3d() -> Simulation3 {
    let mesh = cuboid(
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(1.0, 0.1, 0.1),
        [6, 1, 1],
        ElementKind::Hex8,
    )
    .unwrap();
    let beam = Body::new("bar", mesh, steel()).with_constraint_in_box(
        Vector3::new(-1e-9, -1.0, -1.0),
        Vector3::new(1e-9, 1.0, 1.0),
        [Some(0.0), Some(0.0), Some(0.0)],
    );
    Simulation3::builder()
        .time_step(1e-4)
        .gravity(Vector3::new(0.0, 0.0, -9.81))
        .body(beam)
        .build()
        .unwrap()
}

fn run<const D: usize>(
    sim: &mut Simulation<D>,
    steps: usize,
    recorder: &mut dyn Recorder<D>,
) -> Vec<StepReport>
where
    Dim<D>: SpatialDim<D>,
{
    (0..steps)
        .map(|_| sim.step_with(recorder).unwrap())
        .collect()
}

fn rows(memory: &MemoryRecording) -> BTreeMap<String, EntityRows> {
    memory.entity_rows().unwrap()
}

fn assert_recording<const D: usize>(mut sim: Simulation<D>, body: &str, steps: usize)
where
    Dim<D>: SpatialDim<D>,
{
    let (recorder, memory) = RerunRecorder::<D>::to_memory().unwrap();
    let mut recorder = recorder.with_probe("tip", sim.body_ids()[0], 1);
    let reports = run(&mut sim, steps, &mut recorder);
    let iterations: usize = reports.iter().map(|r| r.iterations).sum();
    assert!(iterations >= steps, "{iterations} iterations");
    assert_eq!(recorder.iterations(), iterations as u64);
    recorder.flush().unwrap();
    assert!(recorder.error().is_none(), "{:?}", recorder.error());
    let rows = rows(&memory);

    // Exactly one configuration per iteration of the step reports.
    for part in ["mesh", "nodes"] {
        let path = format!("bodies/{body}/{part}");
        let r = rows
            .get(&path)
            .unwrap_or_else(|| panic!("{path} missing: {rows:?}"));
        assert_eq!(r.temporal, iterations, "{path}");
    }
    for s in ["residual_norm", "increment_norm", "active_set_size"] {
        let path = format!("solver/{s}");
        assert_eq!(rows[&path].temporal, iterations, "{path}");
        assert_eq!(rows[&path].static_rows, 1, "{path}: the series style");
    }
    // Energies and probes: the initial state and every step.
    for kind in ENERGY_KINDS {
        assert_eq!(
            rows[&format!("energy/{kind}")].temporal,
            steps + 1,
            "{kind}"
        );
    }
    assert_eq!(rows["probes/tip"].temporal, steps + 1);
    // One summary per step in the text log.
    assert_eq!(rows["log"].temporal, steps);
    // No contact: no contact entity.
    assert!(!rows.keys().any(|k| k.starts_with("contacts/")), "{rows:?}");
}

#[test]
fn records_one_configuration_per_iteration_2d() {
    assert_recording(cantilever_2d(), "beam", 12);
}

#[test]
fn records_one_configuration_per_iteration_3d() {
    let mut sim = cantilever_3d();
    let (recorder, memory) = RerunRecorder::<3>::to_memory().unwrap();
    let mut recorder = recorder.with_color_field(ColorField::Speed);
    let reports = run(&mut sim, 4, &mut recorder);
    recorder.flush().unwrap();
    let rows = rows(&memory);
    let iterations: usize = reports.iter().map(|r| r.iterations).sum();
    assert_eq!(rows["bodies/bar/mesh"].temporal, iterations);
    // The triangles are logged once, statically.
    assert_eq!(rows["bodies/bar/mesh"].static_rows, 1);
    assert_recording(cantilever_3d(), "bar", 5);
}

#[test]
fn recording_does_not_change_results() {
    let mut plain = cantilever_2d();
    let mut recorded = cantilever_2d();
    let (mut recorder, _memory) = RerunRecorder::<2>::to_memory().unwrap();
    let a = run(&mut plain, 20, &mut NullRecorder);
    let b = run(&mut recorded, 20, &mut recorder);
    assert_eq!(a, b);
    assert_eq!(plain.state(), recorded.state());
}

#[test]
fn an_rrd_file_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.rrd");
    let mut sim = cantilever_2d();
    let mut recorder = RerunRecorder::<2>::to_file(&path).unwrap();
    run(&mut sim, 3, &mut recorder);
    recorder.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert!(bytes.len() > 1000, "{} bytes", bytes.len());
    assert_eq!(&bytes[..4], b"RRF2", "the .rrd magic");
}

#[test]
fn unwritable_file_is_an_output_error() {
    let dir = tempfile::tempdir().unwrap();
    // Missing folders are created.
    let path = dir.path().join("missing/folder/run.rrd");
    RerunRecorder::<2>::to_file(&path)
        .unwrap()
        .finish()
        .unwrap();
    assert!(path.is_file());
    // A file in the way of the folder.
    let blocker = dir.path().join("a_file");
    std::fs::write(&blocker, "").unwrap();
    let path = blocker.join("run.rrd");
    match RerunRecorder::<2>::to_file(&path) {
        Err(Error::Output { file, .. }) => assert_eq!(file, blocker),
        Err(e) => panic!("unexpected error {e}"),
        Ok(_) => panic!("created {}", path.display()),
    }
}

/// Contact records made by hand, fed to the recorder directly: every contact entity is
/// logged, status changes reach the text log, and an iteration without contact clears them.
fn contacts_by_hand<const D: usize>(sim: Simulation<D>, obstacle: Obstacle<D>)
where
    Dim<D>: SpatialDim<D>,
{
    let (recorder, memory) = RerunRecorder::<D>::to_memory().unwrap();
    let mut recorder = recorder.with_obstacles(&[obstacle]);
    let positions = sim.positions();
    let velocity = sim.state().velocity.clone();
    let mut e = SVector::<f64, D>::zeros();
    e[0] = 1.0;
    let mut up = SVector::<f64, D>::zeros();
    up[1] = 1.0;
    let record = |slave: usize, gap: f64, force: f64, active: bool| ContactRecord::<D> {
        slave,
        obstacle: Some(0),
        position: positions[slave],
        master_point: positions[slave] - up * gap,
        normal: up,
        gap,
        normal_force: force,
        friction_force: e * (0.3 * force),
        slip_velocity: e * 1e-3,
        active,
    };
    let sets: [Vec<ContactRecord<D>>; 3] = [
        vec![record(0, 1e-4, 0.0, false), record(1, -2e-5, 50.0, true)],
        vec![record(0, -1e-5, 10.0, true), record(1, -1e-5, 40.0, true)],
        vec![],
    ];
    recorder.step_start(&sim, 1);
    for (k, contacts) in sets.iter().enumerate() {
        recorder.iteration(
            &sim,
            &IterationInfo {
                step: 1,
                iteration: k + 1,
                time: 0.0,
                time_step: 1e-4,
                residual_norm: 1.0 / (k + 1) as f64,
                relative_residual: 1e-3 / (k + 1) as f64,
                increment_norm: 0.1,
                end_velocity: &velocity,
                end_positions: &positions,
                candidates: 7,
                contacts,
            },
        );
    }
    recorder.log(&sim, "step 1 cut to h = 5e-5 s");
    recorder.flush().unwrap();
    assert!(recorder.error().is_none(), "{:?}", recorder.error());
    let rows = rows(&memory);
    for path in [
        "contacts/candidates",
        "contacts/active",
        "contacts/gap",
        "contacts/normal_force",
        "contacts/friction_force",
        "contacts/slip",
    ] {
        // Two iterations with contacts, and one that clears them.
        assert_eq!(
            rows.get(path).map(|r| r.temporal),
            Some(3),
            "{path}: {rows:?}"
        );
    }
    assert_eq!(rows["solver/active_set_size"].temporal, 3);
    assert_eq!(rows["solver/candidates"].temporal, 3);
    assert_eq!(rows["obstacles/floor"].static_rows, 1);
    // Status changes: node 1 closes, node 0 closes, both open; plus the cut message.
    assert_eq!(rows["log"].temporal, 4);
    let bytes = memory.rrd_bytes().unwrap();
    assert!(!bytes.is_empty());
}

#[test]
fn contact_records_are_logged_2d() {
    let floor = Obstacle::new(
        "floor",
        ObstacleShape::Halfspace {
            point: Vector2::new(0.0, -0.1),
            normal: Vector2::new(0.0, 1.0),
        },
    );
    contacts_by_hand(cantilever_2d(), floor);
}

#[test]
fn contact_records_are_logged_3d() {
    let ball = Obstacle::new(
        "floor",
        ObstacleShape::Ball {
            center: Vector3::new(0.5, 0.0, -1.0),
            radius: 0.9,
        },
    );
    contacts_by_hand(cantilever_3d(), ball);
}

#[test]
fn a_disabled_stream_records_nothing() {
    let mut recorder = RerunRecorder::<2>::from_stream(re_sdk::RecordingStream::disabled());
    assert!(!recorder.is_enabled());
    let mut sim = cantilever_2d();
    run(&mut sim, 3, &mut recorder);
    assert_eq!(recorder.iterations(), 0);
    recorder.finish().unwrap();
}

/// Obstacles that move (a velocity, a motion schedule, turning or not) are drawn every step in
/// the simulation's pose; a fixed one once, static.
#[test]
fn moving_and_turning_obstacles_are_drawn_every_step() {
    use softway::contact::MotionSegment;
    let plane = |name: &str, y: f64| {
        Obstacle::new(
            name,
            ObstacleShape::Halfspace {
                point: Vector2::new(0.5, y),
                normal: Vector2::new(0.0, 1.0),
            },
        )
    };
    let obstacles = vec![
        plane("fixed", -1.0),
        plane("tilting", -2.0).with_motion(vec![MotionSegment {
            until: 1.0,
            velocity: Vector2::zeros(),
            angular_velocity: vec![0.5],
        }]),
        plane("lifted", -3.0).with_motion(vec![MotionSegment {
            until: 1.0,
            velocity: Vector2::new(0.0, 0.1),
            angular_velocity: Vec::new(),
        }]),
    ];
    let mut builder = Simulation2::builder().time_step(1e-4).body(Body::new(
        "beam",
        rectangle(
            Vector2::new(0.0, 0.0),
            Vector2::new(1.0, 0.1),
            [4, 1],
            ElementKind::Quad4,
        )
        .unwrap(),
        steel(),
    ));
    for o in &obstacles {
        builder = builder.obstacle(o.clone());
    }
    let mut sim = builder.build().unwrap();
    let (recorder, memory) = RerunRecorder::<2>::to_memory().unwrap();
    let mut recorder = recorder.with_obstacles(&obstacles);
    run(&mut sim, 3, &mut recorder);
    recorder.flush().unwrap();
    assert!(recorder.error().is_none(), "{:?}", recorder.error());
    let rows = rows(&memory);
    assert_eq!(rows["obstacles/fixed"].static_rows, 1);
    assert_eq!(rows["obstacles/fixed"].temporal, 0);
    for moving in ["obstacles/tilting", "obstacles/lifted"] {
        assert_eq!(rows[moving].temporal, 3, "{moving}: {rows:?}");
        assert_eq!(rows[moving].static_rows, 0, "{moving}");
    }
}
