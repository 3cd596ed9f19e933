//! A fixed-timestep driver for hosts with their own frame clock (a game at 60 Hz, a robot's
//! control loop): the host hands in the time its frame took, the driver runs as many whole
//! steps of the simulation's step size as that time covers, carries the remainder to the
//! next frame, and says how far the simulation lags behind the host's clock.

use super::{ContactEvent, Simulation, StepReport};
use crate::dim::{Dim, SpatialDim};
use crate::error::Result;

/// Runs whole steps to keep up with a host's clock. The accumulated time that is not yet a
/// whole step is carried over; at most `max_steps_per_frame` steps run per frame (so a slow
/// frame cannot start a spiral of ever longer frames), the rest is reported as lag.
#[derive(Debug, Clone, PartialEq)]
pub struct FixedTimestep {
    accumulated: f64,
    max_steps_per_frame: usize,
}

/// What one frame of a [`FixedTimestep`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameReport {
    /// Steps run in this frame.
    pub steps: usize,
    /// The report of the last step run (None if the frame ran none).
    pub last: Option<StepReport>,
    /// Host time not yet simulated (s): below one step when the simulation keeps up.
    pub lag: f64,
    /// The fraction of a step the host is ahead of the simulation, in [0, 1) when it keeps up:
    /// the weight to interpolate positions between the last two steps when drawing.
    pub blend: f64,
    /// Whether the frame hit `max_steps_per_frame` with a whole step or more left.
    pub behind: bool,
    /// The contact events of every step run in this frame, in order
    /// ([`Simulation::contact_events`] holds the last step's only: a landing in an earlier
    /// step of the frame is there and nowhere else).
    pub events: Vec<ContactEvent>,
}

impl Default for FixedTimestep {
    fn default() -> Self {
        FixedTimestep::new(8)
    }
}

impl FixedTimestep {
    /// A driver running at most `max_steps_per_frame` steps per frame (at least 1).
    pub fn new(max_steps_per_frame: usize) -> Self {
        FixedTimestep {
            accumulated: 0.0,
            max_steps_per_frame: max_steps_per_frame.max(1),
        }
    }

    /// Host time not yet simulated (s).
    pub fn lag(&self) -> f64 {
        self.accumulated
    }

    /// Forgets the lag (a host that pauses, or gives up catching up after a long frame).
    pub fn reset(&mut self) {
        self.accumulated = 0.0;
    }

    /// Adds the host's frame time `frame_time` (s) and runs the whole steps it covers (at most
    /// `max_steps_per_frame`). On a step's error the time of that step and the steps after it
    /// stays accumulated and the state is the last good step's.
    pub fn advance<const D: usize>(
        &mut self,
        sim: &mut Simulation<D>,
        frame_time: f64,
    ) -> Result<FrameReport>
    where
        Dim<D>: SpatialDim<D>,
    {
        self.advance_with(sim, frame_time, &mut crate::recording::NullRecorder)
    }

    /// [`FixedTimestep::advance`], every step observed by `recorder` (a Rerun recording of
    /// the host's run: `Simulation::step_with`).
    pub fn advance_with<const D: usize>(
        &mut self,
        sim: &mut Simulation<D>,
        frame_time: f64,
        recorder: &mut dyn crate::recording::Recorder<D>,
    ) -> Result<FrameReport>
    where
        Dim<D>: SpatialDim<D>,
    {
        if !(frame_time >= 0.0 && frame_time.is_finite()) {
            return Err(super::invalid(
                "frame_time",
                frame_time,
                "a finite time >= 0 (s)",
            ));
        }
        let h = sim.settings().time_step;
        self.accumulated += frame_time;
        let mut steps = 0;
        let mut last = None;
        let mut events = Vec::new();
        // A whole step is due when the accumulated time reaches it up to round-off (60 frames
        // of 1/60 s make 60 steps of 1/60 s).
        let due = |acc: f64| acc >= h * (1.0 - 1e-9);
        while due(self.accumulated) && steps < self.max_steps_per_frame {
            last = Some(sim.step_with(recorder)?);
            events.extend_from_slice(sim.contact_events());
            self.accumulated = (self.accumulated - h).max(0.0);
            steps += 1;
        }
        Ok(FrameReport {
            steps,
            last,
            lag: self.accumulated,
            blend: (self.accumulated / h).min(1.0),
            behind: due(self.accumulated),
            events,
        })
    }
}
