//! The `softway` command line against its contract (`scene-format.md`): exit statuses, error
//! messages, the output folder and the columns of its files. Drives the real binary.
//!
//! Bad scenes live in `fixtures/scenes/bad/` (one defect each); valid scenes are written into
//! temporary folders. Every case is a tiny mesh and a handful of steps.
//!
//! `support.rs`: running the binary and checking messages; `invalid_input.rs`: bad scenes
//! (exit status 2); `valid_runs.rs`: runs, their outputs, `--set`, instability (exit status 3);
//! `checkpoints.rs`: checkpoints, `resume`, interrupts and atomic outputs;
//! `reliability.rs`: issue 14 (runs that end, limits, overlaps, messages, monitors);
//! `messages.rs`: issue 14's messages (no type names, advice that fits the case, the memory
//! estimate); `bundled_defaults.rs`: every bundled scene at its defaults, to the end, with the
//! warnings the book lists.

mod bundled_defaults;
mod checkpoints;
mod invalid_input;
mod messages;
mod reliability;
mod support;
mod valid_runs;
