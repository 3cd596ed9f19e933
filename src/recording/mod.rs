//! Consumers of the step's observer hooks ([`Recorder`], defined with the simulation):
//! [`NullRecorder`] and, with the `rerun` feature, the Rerun recorder.

#[cfg(feature = "rerun")]
pub mod rerun;

pub use crate::simulation::observe::{ContactRecord, IterationInfo, NullRecorder, Recorder};

#[cfg(feature = "rerun")]
pub use rerun::{ColorField, RerunRecorder};
