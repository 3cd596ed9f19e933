//! Recording every solver iteration to [Rerun](https://rerun.io) (cargo feature `rerun`).
//!
//! [`RerunRecorder`] writes an `.rrd` file ([`RerunRecorder::to_file`]), streams to a viewer
//! ([`RerunRecorder::spawn`], [`RerunRecorder::connect`]) or keeps the messages in memory
//! ([`RerunRecorder::to_memory`], for tests). The files are written by `re_sdk` 0.36.3 and are
//! read by the viewer and the `rerun` command line of the `rerun-sdk==0.36.3` Python package.
//!
//! Timelines: `step` (the step number, 1-based), `iteration` (every iteration of the run,
//! counted from 1) and `sim_time` (seconds; per-iteration data sits at the *end* of its step,
//! since it shows the predicted end-of-step configuration).
//!
//! Entity paths (stable; the book's chapter "Debugging contact with Rerun" documents them):
//!
//! | path | when | what |
//! |---|---|---|
//! | `bodies/<name>/mesh` | every iteration | deformed mesh at the predicted end positions (2D: one closed line strip per cell; 3D: boundary triangles), coloured by the [`ColorField`] |
//! | `bodies/<name>/nodes` | every iteration | the nodes, same positions |
//! | `obstacles/<name>` | first step (fixed obstacles) or every step (moving ones) | the obstacle's shape in its pose (translated and turned) |
//! | `contacts/candidates` | every iteration | every contact record: slave point and a segment to its master point |
//! | `contacts/active` | every iteration | slave points in the active set |
//! | `contacts/gap` | every iteration | slave points coloured by their gap (m; red: penetration, blue: open) |
//! | `contacts/normal_force` | every iteration | normal force arrows, labelled in N |
//! | `contacts/friction_force` | every iteration | friction force arrows |
//! | `contacts/slip` | every iteration | slip velocity times the step size (m; the slip of the step) |
//! | `solver/residual_norm` | every iteration | residual norm before the solve (N) |
//! | `solver/relative_residual` | every iteration | the residual over the force scale (what the tolerance tests) |
//! | `solver/increment_norm` | every iteration | velocity increment norm (m/s) |
//! | `solver/active_set_size` | every iteration | number of active contacts |
//! | `solver/candidates` | every iteration | broad-phase candidate pairs |
//! | `energy/<kind>` | every step (and at t = 0) | kinetic, internal, contact, external_work, dissipated (J) |
//! | `probes/<name>` | every step (and at t = 0) | displacement (m) and velocity (m/s) components of a probe node |
//! | `log` | on events | contact status changes, step summaries, messages of the solver (step cuts) |
//!
//! Recording never changes the results: the recorder only reads the simulation. Log from the
//! thread that steps the simulation (Rerun's time cursor is per thread).

mod blueprint;
mod colors;
mod contacts;
mod memory;
mod obstacle_shapes;
mod scene;
mod series;

use std::collections::BTreeSet;
use std::path::Path;

use re_sdk::blueprint::BlueprintActivation;
use re_sdk::{RecordingStream, RecordingStreamBuilder, RecordingStreamResult};
use re_sdk_types::archetypes::TextLog;
use re_sdk_types::components::TextLogLevel;

pub use memory::{EntityRows, MemoryRecording};

use super::{IterationInfo, Recorder};
use crate::assembly::von_mises;
use crate::contact::Obstacle;
use crate::dim::{Dim, SpatialDim};
use crate::error::{Error, Result};
use crate::simulation::{BodyId, Simulation, StepReport};
use blueprint::blueprint;
use scene::BodyDraw;
use series::ProbeDraw;

/// The Rerun application id of softway's recordings.
pub const APPLICATION_ID: &str = "softway";

/// The energy kinds logged under `energy/<kind>`, in the order of [`crate::simulation::Energies`].
pub const ENERGY_KINDS: [&str; 5] = [
    "kinetic",
    "internal",
    "contact",
    "external_work",
    "dissipated",
];

/// The field that colours the meshes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ColorField {
    /// von Mises stress of the committed state (start of the step) (Pa), per cell.
    #[default]
    VonMises,
    /// Speed of the current end-of-step velocity estimate (m/s), per node.
    Speed,
}

/// Records every iteration of a run to Rerun. See the [module docs](self) for the entity paths.
pub struct RerunRecorder<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    rec: RecordingStream,
    color_field: ColorField,
    /// Iterations recorded so far (the `iteration` timeline).
    iteration: i64,
    bodies: Option<Vec<BodyDraw>>,
    obstacles: Vec<Obstacle<D>>,
    /// Obstacles the host already moves (state velocity) when the recording starts: drawn
    /// every step like scheduled ones.
    host_moved: Vec<bool>,
    probes: Vec<ProbeDraw>,
    /// von Mises stress of every cell of the committed state (Pa).
    mises: Vec<f64>,
    /// Largest colour-field value seen so far (the top of the colour scale).
    field_max: f64,
    /// Largest contact force seen so far (N; scales the force arrows).
    force_max: f64,
    /// Size of the scene (diagonal of the reference bounding box) (m).
    scene_size: f64,
    /// Whether the previous iteration logged any contact record.
    had_contacts: bool,
    /// (slave, obstacle) pairs of the previous iteration's active set.
    active: BTreeSet<(usize, Option<usize>)>,
    errors: usize,
    first_error: Option<String>,
}

fn rerun_error(e: impl std::fmt::Display) -> Error {
    Error::Recording(e.to_string())
}

impl<const D: usize> RerunRecorder<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// Records into the `.rrd` file at `path` (created or truncated, its missing parent folders
    /// created, as the output folder of a run is). Call [`RerunRecorder::finish`] at the end to
    /// write the file's footer.
    pub fn to_file(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(|source| Error::Output {
                file: parent.to_path_buf(),
                source,
            })?;
        }
        let rec = builder().save(path).map_err(|e| Error::Output {
            file: path.to_path_buf(),
            source: std::io::Error::other(e.to_string()),
        })?;
        Ok(Self::from_stream(rec))
    }

    /// Records into memory, for tests: the returned [`MemoryRecording`] reads the messages.
    pub fn to_memory() -> Result<(Self, MemoryRecording)> {
        let (rec, storage) = builder().memory().map_err(rerun_error)?;
        Ok((Self::from_stream(rec), MemoryRecording { storage }))
    }

    /// Spawns a Rerun viewer (the `rerun` executable on `PATH`, listening on the loopback
    /// interface only) and streams to it over gRPC.
    pub fn spawn() -> Result<Self> {
        let opts = re_sdk::SpawnOptions {
            extra_args: vec!["--bind".into(), "127.0.0.1".into()],
            ..Default::default()
        };
        Ok(Self::from_stream(
            builder().spawn_opts(&opts).map_err(rerun_error)?,
        ))
    }

    /// Streams to a running viewer over gRPC, e.g. `rerun+http://127.0.0.1:9876/proxy`
    /// (`None`: that default address).
    pub fn connect(url: Option<&str>) -> Result<Self> {
        let url = url.unwrap_or(re_sdk::DEFAULT_CONNECT_URL);
        let rec = builder()
            .connect_grpc_opts(url.to_string())
            .map_err(rerun_error)?;
        Ok(Self::from_stream(rec))
    }

    /// Records into an existing stream (any sink). A disabled stream makes a recorder that
    /// logs nothing and costs nothing but a branch per hook.
    pub fn from_stream(rec: RecordingStream) -> Self {
        let mut recorder = RerunRecorder {
            rec,
            color_field: ColorField::default(),
            iteration: 0,
            bodies: None,
            host_moved: Vec::new(),
            obstacles: Vec::new(),
            probes: Vec::new(),
            mises: Vec::new(),
            field_max: 0.0,
            force_max: 0.0,
            scene_size: 1.0,
            had_contacts: false,
            active: BTreeSet::new(),
            errors: 0,
            first_error: None,
        };
        if recorder.rec.is_enabled() {
            recorder.rec.set_log_time_enabled(false);
            recorder.rec.set_log_tick_enabled(false);
            let sent = blueprint::<D>().send(&recorder.rec, BlueprintActivation::default());
            recorder.check(sent);
        }
        recorder
    }

    /// Chooses the field that colours the meshes.
    pub fn with_color_field(mut self, field: ColorField) -> Self {
        self.color_field = field;
        self
    }

    /// The rigid obstacles to draw under `obstacles/<name>` (names contact records). Those
    /// that move (a velocity, an angular velocity or a motion schedule) are drawn every step in
    /// the simulation's pose of the obstacle with the same index at the end of the step.
    pub fn with_obstacles(mut self, obstacles: &[Obstacle<D>]) -> Self {
        self.obstacles = obstacles.to_vec();
        self
    }

    /// Adds a probe logged under `probes/<name>`: node `node` of body `body`.
    pub fn with_probe(mut self, name: impl Into<String>, body: BodyId, node: usize) -> Self {
        self.probes.push(ProbeDraw {
            name: name.into(),
            body,
            node,
        });
        self
    }

    /// Whether anything is recorded (false for a disabled stream, e.g. with `RERUN=0`).
    pub fn is_enabled(&self) -> bool {
        self.rec.is_enabled()
    }

    /// Iterations recorded so far.
    pub fn iterations(&self) -> u64 {
        self.iteration as u64
    }

    /// The first logging error, if any (logging errors never stop a run), and how many there
    /// were.
    pub fn error(&self) -> Option<(&str, usize)> {
        self.first_error.as_deref().map(|e| (e, self.errors))
    }

    /// Blocks until everything logged so far has reached the sink.
    pub fn flush(&self) -> Result<()> {
        if !self.rec.is_enabled() {
            return Ok(());
        }
        self.rec.flush_blocking().map_err(rerun_error)
    }

    /// Flushes, completes the file (its footer) and closes the stream; returns the first
    /// logging error, if any.
    pub fn finish(self) -> Result<()> {
        if self.rec.is_enabled() {
            self.rec.flush_blocking().map_err(rerun_error)?;
            self.rec.finalize_deferred_sinks();
        }
        match self.first_error {
            Some(e) => Err(rerun_error(format!(
                "{} logging error(s), the first: {e}",
                self.errors
            ))),
            None => Ok(()),
        }
    }

    fn check<T>(&mut self, r: RecordingStreamResult<T>) {
        if let Err(e) = r {
            self.errors += 1;
            if self.first_error.is_none() {
                self.first_error = Some(e.to_string());
            }
        }
    }

    fn set_time(&self, step: usize, iteration: i64, time: f64) {
        self.rec.set_time_sequence("step", step as i64);
        self.rec.set_time_sequence("iteration", iteration);
        self.rec.set_duration_secs("sim_time", time);
    }

    fn log_text(&mut self, level: &'static str, text: String) {
        let r = self.rec.log(
            "log",
            &TextLog::new(text).with_level(TextLogLevel::from(level)),
        );
        self.check(r);
    }

    /// Builds the drawing data and logs what never changes, once.
    fn setup(&mut self, sim: &Simulation<D>) {
        if self.bodies.is_some() {
            return;
        }
        let bodies = self.setup_scene(sim);
        self.log_series_styles();
        self.host_moved = host_moved(sim);
        self.log_fixed_obstacles();
        self.bodies = Some(bodies);
        // The initial state, at step 0 / iteration 0.
        self.set_time(0, 0, sim.state().time);
        self.log_step_scalars(sim);
    }
}

impl<const D: usize> Recorder<D> for RerunRecorder<D>
where
    Dim<D>: SpatialDim<D>,
{
    fn step_start(&mut self, sim: &Simulation<D>, step: usize) {
        if !self.rec.is_enabled() {
            return;
        }
        self.setup(sim);
        self.follow_bodies(sim);
        // The committed state does not change during the step.
        if self.color_field == ColorField::VonMises {
            self.mises = sim.cell_stresses().iter().map(von_mises).collect();
        }
        let h = sim.settings().time_step;
        let t_end = sim.state().time + h;
        self.set_time(step, self.iteration + 1, t_end);
        // Moving obstacles in the simulation's pose at the end of the step (the drawn ones
        // matched to the simulation's by index).
        let posed = sim.obstacles_after(h);
        for o in 0..self.obstacles.len() {
            if self.obstacle_moves(o) {
                let obstacle = match posed.get(o) {
                    Some(p) => Obstacle {
                        name: self.obstacles[o].name.clone(),
                        ..p.clone()
                    },
                    None => self.obstacles[o].clone(),
                };
                self.log_obstacle(&obstacle, false);
            }
        }
    }

    fn iteration(&mut self, sim: &Simulation<D>, info: &IterationInfo<'_, D>) {
        if !self.rec.is_enabled() {
            return;
        }
        if self.bodies.is_none() {
            self.setup(sim);
            if self.color_field == ColorField::VonMises {
                self.mises = sim.cell_stresses().iter().map(von_mises).collect();
            }
        }
        self.iteration += 1;
        self.set_time(info.step, self.iteration, info.time + info.time_step);
        self.log_bodies(info);
        self.log_contacts(info);
        self.log_solver_scalars(info);
        self.log_status_changes(info);
    }

    fn step_end(&mut self, sim: &Simulation<D>, report: &StepReport) {
        if !self.rec.is_enabled() {
            return;
        }
        self.setup(sim);
        self.set_time(report.step, self.iteration, report.time);
        self.log_step_scalars(sim);
        self.log_text(
            TextLogLevel::DEBUG,
            format!(
                "step {} done: t = {:.6e} s, h = {:.3e} s, {} iteration(s), relative residual {:.3e}, \
                 {} active contact(s), max penetration {:.3e} m",
                report.step,
                report.time,
                report.time_step,
                report.iterations,
                report.residual,
                report.active_contacts,
                report.max_penetration
            ),
        );
    }

    fn log(&mut self, _sim: &Simulation<D>, message: &str) {
        if !self.rec.is_enabled() {
            return;
        }
        self.log_text(TextLogLevel::WARN, message.to_string());
    }
}

/// Per obstacle: whether the state gives it a velocity or an angular velocity (a host that
/// poses it with `set_obstacle_next_pose`).
fn host_moved<const D: usize>(sim: &Simulation<D>) -> Vec<bool>
where
    Dim<D>: SpatialDim<D>,
{
    let state = sim.state();
    let a = <Dim<D>>::ANGULAR;
    (0..sim.obstacles().len())
        .map(|k| {
            let v = state.obstacle_velocities.get(k * D..k * D + D);
            let w = state.obstacle_angular_velocities.get(k * a..k * a + a);
            v.into_iter().chain(w).flatten().any(|x| *x != 0.0)
        })
        .collect()
}

fn builder() -> RecordingStreamBuilder {
    RecordingStreamBuilder::new(APPLICATION_ID)
}
