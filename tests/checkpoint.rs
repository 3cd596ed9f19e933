//! Checkpoints through the library (`io::output::{run_with, resume}`): a run resumed from a
//! checkpoint ends with the uninterrupted run's history.csv byte for byte, for every kind of
//! state a checkpoint must carry: contact memory and contact factorisations (soft way),
//! friction anchors (Coulomb), Augmented Lagrangian multipliers, moving obstacles, material
//! history (hypoelastic, Norton-Hoff), damping, in 2D and 3D. The command line's side
//! (signals, killed runs) is in `tests/cli/checkpoints.rs`.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use softway::dim::{Dim, SpatialDim};
use softway::io::checkpoint::{self, AnyCheckpoint, Checkpoint};
use softway::io::output::{self, RunOptions, Summary};
use softway::io::scene::{self, Scene};
use softway::recording::NullRecorder;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/scenes")
        .join(name)
}

fn run<const D: usize>(
    scene: &Scene<D>,
    out: &Path,
    every: usize,
    stop: Option<&AtomicBool>,
) -> Summary
where
    Dim<D>: SpatialDim<D>,
{
    let options = RunOptions {
        checkpoint_every: every,
        stop,
    };
    output::run_with::<D>(scene, out, "scene", options, &mut |_| {}, &mut NullRecorder)
        .unwrap_or_else(|f| panic!("{}", f.error))
}

fn resume<const D: usize>(checkpoint: Checkpoint<D>, out: &Path) -> Summary
where
    Dim<D>: SpatialDim<D>,
{
    output::resume::<D>(
        checkpoint,
        out,
        RunOptions::default(),
        &mut |_| {},
        &mut NullRecorder,
    )
    .unwrap_or_else(|f| panic!("{}", f.error))
}

fn history(out: &Path) -> String {
    std::fs::read_to_string(out.join("history.csv")).unwrap()
}

/// Runs `path` with `overrides` and a checkpoint every `every` steps, resumes from the
/// checkpoint of step `at` into another folder, and compares the histories.
fn resumes_bit_for_bit(path: &Path, overrides: &[&str], every: usize, at: usize) {
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    let loaded = scene::load(path, &overrides).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let ckpt = checkpoint::path_for(&a, at);
    let (whole, resumed) = match loaded.dimension().unwrap() {
        2 => {
            let scene = loaded.build::<2>().unwrap();
            let whole = run::<2>(&scene, &a, every, None);
            let AnyCheckpoint::Two(c) = checkpoint::read(&ckpt).unwrap() else {
                panic!("a 2D checkpoint expected")
            };
            (whole, resume::<2>(*c, &b))
        }
        _ => {
            let scene = loaded.build::<3>().unwrap();
            let whole = run::<3>(&scene, &a, every, None);
            let AnyCheckpoint::Three(c) = checkpoint::read(&ckpt).unwrap() else {
                panic!("a 3D checkpoint expected")
            };
            (whole, resume::<3>(*c, &b))
        }
    };
    assert!(
        whole.steps > at,
        "{}: {} steps",
        path.display(),
        whole.steps
    );
    assert_eq!(history(&b), history(&a), "{}", path.display());
    assert_eq!(resumed.steps, whole.steps);
    assert_eq!(resumed.total_iterations, whole.total_iterations);
    assert_eq!(
        resumed.max_penetration.to_bits(),
        whole.max_penetration.to_bits()
    );
    assert_eq!(resumed.final_energy.to_bits(), whole.final_energy.to_bits());
}

#[test]
fn soft_way_ring_drop_after_the_landing() {
    resumes_bit_for_bit(
        &fixture("ring_drop.toml"),
        &["simulation.end_time=0.25", "output.vtk_interval=0.0"],
        20,
        180,
    );
}

#[test]
fn hypoelastic_ring_rolling_with_coulomb_friction_and_damping() {
    resumes_bit_for_bit(
        &fixture("rolling_ring.toml"),
        &["simulation.end_time=0.06", "output.vtk_interval=0.0"],
        10,
        30,
    );
}

#[test]
fn gripper_implicit_projection_with_moving_jaws() {
    resumes_bit_for_bit(
        &fixture("gripper.toml"),
        &["simulation.end_time=0.06", "output.vtk_interval=0.0"],
        10,
        30,
    );
}

#[test]
fn norton_hoff_octagon_under_a_die() {
    resumes_bit_for_bit(
        &fixture("octagon_compression.toml"),
        &["simulation.end_time=6.0", "output.vtk_interval=0.0"],
        2,
        4,
    );
}

const CUBE: &str = r#"# A cube sliding onto a floor: augmented Lagrangian with Coulomb friction, in 3D.
[simulation]
dimension = 3
time_step = 1.0e-3
end_time = 0.03
gravity = [0.0, 0.0, -9.81]

[contact]
method = "augmented_lagrangian"
penalty = 1.0e9
friction = { law = "coulomb", coefficient = 0.3 }

[[bodies]]
name = "cube"
mesh = { generator = "box", min = [0.0, 0.0, 0.001], max = [0.1, 0.1, 0.101], cells = [2, 2, 2], element = "hex8" }
material = { model = "linear_elastic", youngs_modulus = 1.0e6, poissons_ratio = 0.3, density = 1000.0 }
initial_velocity = [0.2, 0.0, -0.5]

[[obstacles]]
name = "floor"
shape = { type = "halfspace", point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }

[[probes]]
name = "corner"
body = "cube"
point = [0.0, 0.0, 0.001]

[output]
vtk_interval = 0.01
"#;

#[test]
fn augmented_lagrangian_cube_with_friction_in_3d() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cube.toml");
    std::fs::write(&path, CUBE).unwrap();
    resumes_bit_for_bit(&path, &[], 5, 10);
}

#[test]
fn a_stop_flag_interrupts_before_the_next_step_and_checkpoints_it() {
    let loaded = scene::load(
        &fixture("ring_drop.toml"),
        &["simulation.end_time=0.02".to_string()],
    )
    .unwrap();
    let scene = loaded.build::<2>().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let stop = AtomicBool::new(true);
    let s = run::<2>(&scene, &a, 100, Some(&stop));
    assert_eq!(s.status, "interrupted");
    assert_eq!(s.steps, 0);
    assert_eq!(
        s.last_checkpoint.as_deref(),
        Some("checkpoints/step_0.ckpt")
    );
    assert_eq!(history(&a).lines().count(), 2);
    let AnyCheckpoint::Two(c) = checkpoint::read(&checkpoint::path_for(&a, 0)).unwrap() else {
        panic!("a 2D checkpoint expected")
    };
    // Written and read back, a checkpoint is the same value.
    let again = dir.path().join("again.ckpt");
    c.write(&again).unwrap();
    let AnyCheckpoint::Two(back) = checkpoint::read(&again).unwrap() else {
        panic!("a 2D checkpoint expected")
    };
    assert_eq!(back, c);
    let resumed = resume::<2>(*c, &b);
    assert_eq!(resumed.status, "completed");
    let whole = dir.path().join("whole");
    run::<2>(&scene, &whole, 0, None);
    assert_eq!(history(&b), history(&whole));
}
