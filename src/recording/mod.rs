//! Observers of the solver: hooks at the start of a step, after every iteration and at the end
//! of a step. The solver never depends on what a recorder does.

use crate::dim::{Dim, SpatialDim};
use crate::simulation::{Simulation, StepReport};

/// What one iteration of a step looked like.
#[derive(Debug, Clone, Copy)]
pub struct IterationInfo<'a> {
    /// Step number (1-based).
    pub step: usize,
    /// Iteration within the step (1-based).
    pub iteration: usize,
    /// Norm of the residual before this iteration's solve [N].
    pub residual_norm: f64,
    /// Relative residual (residual over the largest force term).
    pub relative_residual: f64,
    /// Norm of the velocity increment of this iteration [m/s].
    pub increment_norm: f64,
    /// The current estimate of the end-of-step velocities (flat, D per node).
    pub end_velocity: &'a [f64],
}

/// An observer of the solver. Every hook has an empty default.
pub trait Recorder<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    /// Before the first iteration of a step.
    fn step_start(&mut self, _sim: &Simulation<D>, _step: usize) {}
    /// After every Newton / contact iteration.
    fn iteration(&mut self, _sim: &Simulation<D>, _info: &IterationInfo<'_>) {}
    /// After a step is committed.
    fn step_end(&mut self, _sim: &Simulation<D>, _report: &StepReport) {}
}

/// A recorder that does nothing (and costs nothing).
#[derive(Debug, Clone, Copy, Default)]
pub struct NullRecorder;

impl<const D: usize> Recorder<D> for NullRecorder where Dim<D>: SpatialDim<D> {}
