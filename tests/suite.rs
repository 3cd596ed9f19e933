//! The integration tests, one module per file of `tests/`, linked into one test binary.
//!
//! One binary rather than one per file: each binary links softway and its dependencies again
//! (29 links per feature set), and the test harness spreads one binary's tests over every core,
//! where per-file binaries run one after the other with their longest test last. Run one file's
//! tests with its module path as the filter: `cargo test --all-features --test suite two_bodies::`.

// Declared first: its macros (`both_dims!`) are in textual scope for the modules below.
#[macro_use]
mod common;

mod bundled_scenes;
#[cfg(feature = "formats")]
mod checkpoint;
#[cfg(feature = "cli")]
mod cli;
mod contact;
mod damping;
mod detection;
mod determinism;
mod embedding;
mod foundation;
mod friction;
#[cfg(feature = "formats")]
mod fuzz_inputs;
mod generator_properties;
#[cfg(feature = "formats")]
mod gmsh_reader;
mod gripper;
mod large_rotations;
mod locking;
mod monitors;
mod norton_hoff;
mod obstacle_motion;
mod persistency_stop;
mod pipeline;
mod recording;
mod rolling;
mod rotating_obstacles;
mod secant_penalty;
mod self_contact;
mod soft_cube;
mod step_size_changes;
mod tube_crush;
mod two_bodies;
#[cfg(feature = "formats")]
mod vtk_writer;
