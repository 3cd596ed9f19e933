//! What the step shows its observers: hooks at the start of a step, after every iteration and
//! at the end of a step, and the data they receive. The simulation owns these types; the
//! `recording` module only consumes them (the step never depends on what a recorder does).

use nalgebra::SVector;

use super::{Simulation, StepReport};
use crate::dim::{Dim, SpatialDim};

/// One slave point's contact state in an iteration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactRecord<const D: usize> {
    /// Global node id of the slave point.
    pub slave: usize,
    /// Index of the obstacle, or `None` for a facet of a body.
    pub obstacle: Option<usize>,
    /// Predicted end position of the slave point (eq 22) (m).
    pub position: SVector<f64, D>,
    /// Closest point on the master (m).
    pub master_point: SVector<f64, D>,
    /// Unit outward normal of the master.
    pub normal: SVector<f64, D>,
    /// Signed gap (m) (negative: penetration).
    pub gap: f64,
    /// Compressive normal force on the slave (N).
    pub normal_force: f64,
    /// Friction force on the slave (N).
    pub friction_force: SVector<f64, D>,
    /// Tangential relative velocity (slip rate) (m/s).
    pub slip_velocity: SVector<f64, D>,
    /// Whether the point carries force (in the active set).
    pub active: bool,
}

/// What one iteration of a step looked like.
#[derive(Debug, Clone, Copy)]
pub struct IterationInfo<'a, const D: usize> {
    /// Step number (1-based).
    pub step: usize,
    /// Iteration within the step (1-based).
    pub iteration: usize,
    /// Time at the start of the step (s).
    pub time: f64,
    /// Step size (s).
    pub time_step: f64,
    /// Norm of the residual before this iteration's solve (N).
    pub residual_norm: f64,
    /// Relative residual (residual over the largest force term).
    pub relative_residual: f64,
    /// Norm of the velocity increment of this iteration (m/s).
    pub increment_norm: f64,
    /// The current estimate of the end-of-step velocities (flat, D per node) (m/s).
    pub end_velocity: &'a [f64],
    /// The predicted end-of-step node positions (eq 22: `x0 + h (v0 + v1) / 2`) (m).
    pub end_positions: &'a [SVector<f64, D>],
    /// Number of broad-phase candidate pairs.
    pub candidates: usize,
    /// The contact pairs of this iteration (near or active).
    pub contacts: &'a [ContactRecord<D>],
}

/// An observer of the solver. Every hook has an empty default.
pub trait Recorder<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    /// Whether the recorder wants the per-iteration hooks; the solver skips building their
    /// data (positions, contact records) when it does not.
    fn is_enabled(&self) -> bool {
        true
    }
    /// Before the first iteration of a step.
    fn step_start(&mut self, _sim: &Simulation<D>, _step: usize) {}
    /// After every Newton / contact iteration.
    fn iteration(&mut self, _sim: &Simulation<D>, _info: &IterationInfo<'_, D>) {}
    /// After a step is committed.
    fn step_end(&mut self, _sim: &Simulation<D>, _report: &StepReport) {}
    /// A notable event (contact status changes, step cuts), as text.
    fn log(&mut self, _sim: &Simulation<D>, _message: &str) {}
}

/// A recorder that does nothing (and costs nothing).
#[derive(Debug, Clone, Copy, Default)]
pub struct NullRecorder;

impl<const D: usize> Recorder<D> for NullRecorder
where
    Dim<D>: SpatialDim<D>,
{
    fn is_enabled(&self) -> bool {
        false
    }
}
