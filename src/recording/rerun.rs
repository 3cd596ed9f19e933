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
//! | `obstacles/<name>` | first step (fixed obstacles) or every step (moving ones) | the obstacle's shape |
//! | `contacts/candidates` | every iteration | every contact record: slave point and a segment to its master point |
//! | `contacts/active` | every iteration | slave points in the active set |
//! | `contacts/gap` | every iteration | slave points coloured by their gap [m] (red: penetration, blue: open) |
//! | `contacts/normal_force` | every iteration | normal force arrows, labelled in N |
//! | `contacts/friction_force` | every iteration | friction force arrows |
//! | `contacts/slip` | every iteration | slip velocity times the step size [m] (the slip of the step) |
//! | `solver/residual_norm` | every iteration | residual norm before the solve [N] |
//! | `solver/relative_residual` | every iteration | the residual over the force scale (what the tolerance tests) |
//! | `solver/increment_norm` | every iteration | velocity increment norm [m/s] |
//! | `solver/active_set_size` | every iteration | number of active contacts |
//! | `solver/candidates` | every iteration | broad-phase candidate pairs |
//! | `energy/<kind>` | every step (and at t = 0) | kinetic, internal, contact, external_work, dissipated [J] |
//! | `probes/<name>` | every step (and at t = 0) | displacement [m] and velocity [m/s] components of a probe node |
//! | `log` | on events | contact status changes, step summaries, messages of the solver (step cuts) |
//!
//! Recording never changes the results: the recorder only reads the simulation. Log from the
//! thread that steps the simulation (Rerun's time cursor is per thread).

use std::collections::BTreeSet;
use std::ops::Range;
use std::path::Path;

use nalgebra::SVector;
use re_sdk::blueprint::{
    Blueprint, BlueprintActivation, ContainerLike, Horizontal, Spatial2DView, Spatial3DView, Tabs,
    TextLogView, TimePanel, TimeSeriesView, Vertical,
};
use re_sdk::{RecordingStream, RecordingStreamBuilder, RecordingStreamResult};
use re_sdk_types::archetypes::{
    Arrows2D, Arrows3D, LineStrips2D, LineStrips3D, Mesh3D, Points2D, Points3D, Scalars,
    SeriesLines, TextLog, ViewCoordinates,
};
use re_sdk_types::blueprint::components::PlayState;
use re_sdk_types::components::{Color, Radius, TextLogLevel};

use super::{ContactRecord, IterationInfo, Recorder};
use crate::assembly::von_mises;
use crate::contact::{Obstacle, ObstacleShape};
use crate::dim::{Dim, SpatialDim};
use crate::error::{Error, Result};
use crate::simulation::{BodyId, Simulation, StepReport};

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
    /// von Mises stress of the committed state (start of the step) [Pa], per cell.
    #[default]
    VonMises,
    /// Speed of the current end-of-step velocity estimate [m/s], per node.
    Speed,
}

/// Drawing data of one body, built once.
struct BodyDraw {
    name: String,
    /// Global node ids.
    nodes: Range<usize>,
    /// Global cell ids (the order of [`Simulation::cell_stresses`]).
    cells: Range<usize>,
    /// Local node ids of every cell, in the element's order (2D: around the cell).
    cell_nodes: Vec<Vec<usize>>,
    /// 3D: local ids of the boundary nodes (the vertices of the logged surface).
    surface_nodes: Vec<usize>,
    /// 3D: boundary triangles as indices into `surface_nodes`.
    triangles: Vec<[u32; 3]>,
}

/// A probe: a node whose displacement and velocity are logged every step.
struct ProbeDraw {
    name: String,
    body: BodyId,
    node: usize,
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
    probes: Vec<ProbeDraw>,
    /// von Mises stress of every cell of the committed state [Pa].
    mises: Vec<f64>,
    /// Largest colour-field value seen so far (the top of the colour scale).
    field_max: f64,
    /// Largest contact force seen so far [N] (scales the force arrows).
    force_max: f64,
    /// Size of the scene (diagonal of the reference bounding box) [m].
    scene_size: f64,
    /// Whether the previous iteration logged any contact record.
    had_contacts: bool,
    /// (slave, obstacle) pairs of the previous iteration's active set.
    active: BTreeSet<(usize, Option<usize>)>,
    errors: usize,
    first_error: Option<String>,
}

/// The messages of an in-memory recording ([`RerunRecorder::to_memory`]).
pub struct MemoryRecording {
    storage: re_sdk::sink::MemorySinkStorage,
}

/// What an in-memory recording holds for one entity path.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct EntityRows {
    /// Rows logged on the `iteration` timeline (one per log call).
    pub temporal: usize,
    /// Static rows.
    pub static_rows: usize,
}

impl MemoryRecording {
    /// Takes the messages logged so far (flush the recorder first, [`RerunRecorder::flush`])
    /// and counts the rows of every entity path of the recording (the blueprint is left out).
    pub fn entity_rows(&self) -> Result<std::collections::BTreeMap<String, EntityRows>> {
        let mut rows = std::collections::BTreeMap::<String, EntityRows>::new();
        for msg in self.storage.take() {
            let re_sdk::log::LogMsg::ArrowMsg(store, arrow) = msg else {
                continue;
            };
            if store.kind() != re_sdk::StoreKind::Recording {
                continue;
            }
            let chunk = re_sdk::log::Chunk::from_arrow_msg(&arrow).map_err(rerun_error)?;
            let path = chunk.entity_path().to_string();
            let path = path.trim_start_matches('/').to_string();
            let entry = rows.entry(path).or_default();
            if chunk.is_static() {
                entry.static_rows += chunk.num_rows();
            } else if chunk.timelines().keys().any(|t| t.as_str() == "iteration") {
                entry.temporal += chunk.num_rows();
            }
        }
        Ok(rows)
    }

    /// Encodes the messages logged so far as the bytes of an `.rrd` file (taking them).
    pub fn rrd_bytes(&self) -> Result<Vec<u8>> {
        self.storage.drain_as_bytes().map_err(rerun_error)
    }
}

fn rerun_error(e: impl std::fmt::Display) -> Error {
    Error::Recording(e.to_string())
}

impl<const D: usize> RerunRecorder<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// Records into the `.rrd` file at `path` (created or truncated). Call
    /// [`RerunRecorder::finish`] at the end to write the file's footer.
    pub fn to_file(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
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

    /// The rigid obstacles to draw under `obstacles/<name>` (names contact records). Their
    /// position at time t is `translation + velocity * t`.
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
        let mut bodies = Vec::new();
        let mut cell_offset = 0;
        for (b, body) in sim.bodies().iter().enumerate() {
            let cell_nodes: Vec<Vec<usize>> = body
                .mesh
                .blocks
                .iter()
                .flat_map(|blk| blk.cells().map(|c| c.to_vec()))
                .collect();
            let n_cells = cell_nodes.len();
            let (surface_nodes, triangles) = if D == 3 {
                surface(&body.mesh.boundary_facets(), body.mesh.node_count())
            } else {
                (Vec::new(), Vec::new())
            };
            bodies.push(BodyDraw {
                name: body.name.clone(),
                nodes: sim.body_nodes(BodyId(b)),
                cells: cell_offset..cell_offset + n_cells,
                cell_nodes,
                surface_nodes,
                triangles,
            });
            cell_offset += n_cells;
        }
        let reference = sim.reference_positions();
        if let Some(first) = reference.first() {
            let (lo, hi) = reference
                .iter()
                .fold((*first, *first), |(lo, hi), x| (lo.inf(x), hi.sup(x)));
            let size = (hi - lo).norm();
            if size > 0.0 && size.is_finite() {
                self.scene_size = size;
            }
        }
        if D == 3 {
            // The 3D view's up axis: against gravity (z when there is none).
            let g = sim.settings().gravity;
            let y_up = g.iter().any(|c| *c != 0.0) && g[1].abs() > g[2].abs() && g[1] < 0.0;
            let coordinates = if y_up {
                ViewCoordinates::RIGHT_HAND_Y_UP()
            } else {
                ViewCoordinates::RIGHT_HAND_Z_UP()
            };
            let r = self.rec.log_static("/", &coordinates);
            self.check(r);
        }
        for body in &bodies {
            if D == 3 {
                let r = self.rec.log_static(
                    format!("bodies/{}/mesh", body.name),
                    &Mesh3D::update_fields().with_triangle_indices(body.triangles.clone()),
                );
                self.check(r);
            }
        }
        let mut styles: Vec<(String, Vec<String>)> = ENERGY_KINDS
            .iter()
            .map(|k| (format!("energy/{k}"), vec![k.to_string()]))
            .collect();
        for s in [
            "residual_norm",
            "relative_residual",
            "increment_norm",
            "active_set_size",
            "candidates",
        ] {
            styles.push((format!("solver/{s}"), vec![s.to_string()]));
        }
        let axes = ["x", "y", "z"];
        for p in &self.probes {
            let mut names: Vec<String> = axes[..D].iter().map(|a| format!("u{a}")).collect();
            names.extend(axes[..D].iter().map(|a| format!("v{a}")));
            styles.push((format!("probes/{}", p.name), names));
        }
        for (path, names) in styles {
            let r = self
                .rec
                .log_static(path, &SeriesLines::new().with_names(names));
            self.check(r);
        }
        let fixed: Vec<usize> = (0..self.obstacles.len())
            .filter(|&o| self.obstacles[o].velocity.iter().all(|v| *v == 0.0))
            .collect();
        for o in fixed {
            self.log_obstacle(o, 0.0, true);
        }
        self.bodies = Some(bodies);
        // The initial state, at step 0 / iteration 0.
        self.set_time(0, 0, sim.state().time);
        self.log_step_scalars(sim);
    }

    fn log_obstacle(&mut self, o: usize, time: f64, is_static: bool) {
        let obstacle = &self.obstacles[o];
        let shift = obstacle.translation + obstacle.velocity * time;
        let path = format!("obstacles/{}", obstacle.name);
        let color = Color::from_rgb(120, 120, 130);
        let r = if D == 2 {
            let strips: Vec<Vec<[f32; 2]>> = shape_strips(&obstacle.shape, self.scene_size)
                .into_iter()
                .map(|s| s.iter().map(|p| xy(&(p + shift))).collect())
                .collect();
            let arch = LineStrips2D::new(strips)
                .with_colors([color])
                .with_radii([Radius::new_ui_points(2.0)]);
            if is_static {
                self.rec.log_static(path, &arch)
            } else {
                self.rec.log(path, &arch)
            }
        } else {
            let (vertices, triangles) = shape_triangles(&obstacle.shape, self.scene_size);
            let vertices: Vec<[f32; 3]> = vertices.iter().map(|p| xyz(&(p + shift))).collect();
            let arch = Mesh3D::new(vertices)
                .with_triangle_indices(triangles)
                .with_albedo_factor(0x78788280u32);
            if is_static {
                self.rec.log_static(path, &arch)
            } else {
                self.rec.log(path, &arch)
            }
        };
        self.check(r);
    }

    fn log_step_scalars(&mut self, sim: &Simulation<D>) {
        let e = sim.energies();
        let values = [
            e.kinetic,
            e.internal,
            e.contact,
            e.external_work,
            e.dissipated,
        ];
        for (kind, value) in ENERGY_KINDS.iter().zip(values) {
            let r = self
                .rec
                .log(format!("energy/{kind}"), &Scalars::single(value));
            self.check(r);
        }
        for p in 0..self.probes.len() {
            let (body, node) = (self.probes[p].body, self.probes[p].node);
            let (Ok(u), Ok(v)) = (sim.displacement(body, node), sim.velocity(body, node)) else {
                continue;
            };
            let values: Vec<f64> = u.iter().chain(v.iter()).copied().collect();
            let path = format!("probes/{}", self.probes[p].name);
            let r = self.rec.log(path, &Scalars::new(values));
            self.check(r);
        }
    }

    fn log_bodies(&mut self, info: &IterationInfo<'_, D>) {
        let Some(bodies) = self.bodies.take() else {
            return;
        };
        // The colour field: per cell (2D strips) and per node (3D vertex colours).
        let speed = |g: usize| -> f64 {
            let v = info.end_velocity.get(g * D..g * D + D).unwrap_or(&[]);
            v.iter().map(|x| x * x).sum::<f64>().sqrt()
        };
        for body in &bodies {
            let positions = &info.end_positions[body.nodes.clone()];
            let cell_value: Vec<f64> = match self.color_field {
                ColorField::VonMises => body
                    .cells
                    .clone()
                    .map(|c| self.mises.get(c).copied().unwrap_or(0.0))
                    .collect(),
                ColorField::Speed => body
                    .cell_nodes
                    .iter()
                    .map(|c| {
                        c.iter().map(|&n| speed(body.nodes.start + n)).sum::<f64>()
                            / c.len().max(1) as f64
                    })
                    .collect(),
            };
            let top = cell_value.iter().fold(0.0f64, |m, v| m.max(*v));
            if top.is_finite() {
                self.field_max = self.field_max.max(top);
            }
            let scale = self.field_max;
            let mesh_path = format!("bodies/{}/mesh", body.name);
            let nodes_path = format!("bodies/{}/nodes", body.name);
            let node_color = Color::from_rgb(210, 210, 210);
            let node_radius = Radius::new_ui_points(1.5);
            let (r1, r2) = if D == 2 {
                let p2: Vec<[f32; 2]> = positions.iter().map(xy).collect();
                let strips: Vec<Vec<[f32; 2]>> = body
                    .cell_nodes
                    .iter()
                    .map(|c| c.iter().chain(c.first()).map(|&n| p2[n]).collect())
                    .collect();
                let colors: Vec<Color> = cell_value.iter().map(|v| colormap(*v, scale)).collect();
                let r1 = self.rec.log(
                    mesh_path,
                    &LineStrips2D::new(strips)
                        .with_colors(colors)
                        .with_radii([Radius::new_ui_points(1.0)]),
                );
                let r2 = self.rec.log(
                    nodes_path,
                    &Points2D::new(p2)
                        .with_colors([node_color])
                        .with_radii([node_radius]),
                );
                (r1, r2)
            } else {
                let mut node_value = vec![0.0; positions.len()];
                match self.color_field {
                    ColorField::Speed => {
                        for (n, v) in node_value.iter_mut().enumerate() {
                            *v = speed(body.nodes.start + n);
                        }
                    }
                    ColorField::VonMises => {
                        let mut count = vec![0usize; positions.len()];
                        for (c, cell) in body.cell_nodes.iter().enumerate() {
                            for &n in cell {
                                node_value[n] += cell_value[c];
                                count[n] += 1;
                            }
                        }
                        for (v, k) in node_value.iter_mut().zip(count) {
                            *v /= k.max(1) as f64;
                        }
                    }
                }
                let vertices: Vec<[f32; 3]> = body
                    .surface_nodes
                    .iter()
                    .map(|&n| xyz(&positions[n]))
                    .collect();
                let colors: Vec<Color> = body
                    .surface_nodes
                    .iter()
                    .map(|&n| colormap(node_value[n], scale))
                    .collect();
                let r1 = self
                    .rec
                    .log(mesh_path, &Mesh3D::new(vertices).with_vertex_colors(colors));
                let p3: Vec<[f32; 3]> = positions.iter().map(xyz).collect();
                let r2 = self.rec.log(
                    nodes_path,
                    &Points3D::new(p3)
                        .with_colors([node_color])
                        .with_radii([node_radius]),
                );
                (r1, r2)
            };
            self.check(r1);
            self.check(r2);
        }
        self.bodies = Some(bodies);
    }

    fn log_contacts(&mut self, info: &IterationInfo<'_, D>) {
        let contacts = info.contacts;
        if contacts.is_empty() && !self.had_contacts {
            return;
        }
        self.had_contacts = !contacts.is_empty();
        let force_top = contacts.iter().fold(0.0f64, |m, c| {
            m.max(c.normal_force.abs()).max(c.friction_force.norm())
        });
        if force_top.is_finite() {
            self.force_max = self.force_max.max(force_top);
        }
        // Arrow length [m] per newton: the largest force so far is 10% of the scene.
        let per_newton = if self.force_max > 0.0 {
            0.1 * self.scene_size / self.force_max
        } else {
            0.0
        };
        let gap_top = contacts.iter().fold(0.0f64, |m, c| m.max(c.gap.abs()));
        let active: Vec<&ContactRecord<D>> = contacts.iter().filter(|c| c.active).collect();
        let loaded: Vec<&ContactRecord<D>> =
            contacts.iter().filter(|c| c.normal_force != 0.0).collect();
        let rubbing: Vec<&ContactRecord<D>> = contacts
            .iter()
            .filter(|c| c.friction_force.norm() > 0.0)
            .collect();
        let slipping: Vec<&ContactRecord<D>> = contacts
            .iter()
            .filter(|c| c.slip_velocity.norm() > 0.0)
            .collect();

        let grey = Color::from_rgb(150, 150, 150);
        let red = Color::from_rgb(220, 30, 30);
        let orange = Color::from_rgb(240, 140, 0);
        let purple = Color::from_rgb(150, 60, 200);
        let green = Color::from_rgb(20, 160, 60);
        let gap_colors: Vec<Color> = contacts.iter().map(|c| gap_color(c.gap, gap_top)).collect();
        let gap_labels: Vec<String> = contacts
            .iter()
            .map(|c| format!("{:.3e} m", c.gap))
            .collect();
        let force_labels: Vec<String> = loaded
            .iter()
            .map(|c| format!("{:.3e} N", c.normal_force))
            .collect();
        let pt = Radius::new_ui_points(3.0);
        let h = info.time_step;

        let results = if D == 2 {
            let pos = |c: &ContactRecord<D>| xy(&c.position);
            let segments: Vec<Vec<[f32; 2]>> = contacts
                .iter()
                .map(|c| vec![xy(&c.position), xy(&c.master_point)])
                .collect();
            [
                self.rec.log(
                    "contacts/candidates",
                    &LineStrips2D::new(segments).with_colors([grey]),
                ),
                self.rec.log(
                    "contacts/active",
                    &Points2D::new(active.iter().map(|c| pos(c)))
                        .with_colors([red])
                        .with_radii([Radius::new_ui_points(4.0)]),
                ),
                self.rec.log(
                    "contacts/gap",
                    &Points2D::new(contacts.iter().map(pos))
                        .with_colors(gap_colors)
                        .with_labels(gap_labels)
                        .with_radii([pt]),
                ),
                self.rec.log(
                    "contacts/normal_force",
                    &Arrows2D::from_vectors(
                        loaded
                            .iter()
                            .map(|c| xy(&(c.normal * (c.normal_force * per_newton)))),
                    )
                    .with_origins(loaded.iter().map(|c| pos(c)))
                    .with_labels(force_labels)
                    .with_colors([orange]),
                ),
                self.rec.log(
                    "contacts/friction_force",
                    &Arrows2D::from_vectors(
                        rubbing.iter().map(|c| xy(&(c.friction_force * per_newton))),
                    )
                    .with_origins(rubbing.iter().map(|c| pos(c)))
                    .with_colors([purple]),
                ),
                self.rec.log(
                    "contacts/slip",
                    &Arrows2D::from_vectors(slipping.iter().map(|c| xy(&(c.slip_velocity * h))))
                        .with_origins(slipping.iter().map(|c| pos(c)))
                        .with_colors([green]),
                ),
            ]
        } else {
            let pos = |c: &ContactRecord<D>| xyz(&c.position);
            let segments: Vec<Vec<[f32; 3]>> = contacts
                .iter()
                .map(|c| vec![xyz(&c.position), xyz(&c.master_point)])
                .collect();
            [
                self.rec.log(
                    "contacts/candidates",
                    &LineStrips3D::new(segments).with_colors([grey]),
                ),
                self.rec.log(
                    "contacts/active",
                    &Points3D::new(active.iter().map(|c| pos(c)))
                        .with_colors([red])
                        .with_radii([Radius::new_ui_points(4.0)]),
                ),
                self.rec.log(
                    "contacts/gap",
                    &Points3D::new(contacts.iter().map(pos))
                        .with_colors(gap_colors)
                        .with_labels(gap_labels)
                        .with_radii([pt]),
                ),
                self.rec.log(
                    "contacts/normal_force",
                    &Arrows3D::from_vectors(
                        loaded
                            .iter()
                            .map(|c| xyz(&(c.normal * (c.normal_force * per_newton)))),
                    )
                    .with_origins(loaded.iter().map(|c| pos(c)))
                    .with_labels(force_labels)
                    .with_colors([orange]),
                ),
                self.rec.log(
                    "contacts/friction_force",
                    &Arrows3D::from_vectors(
                        rubbing
                            .iter()
                            .map(|c| xyz(&(c.friction_force * per_newton))),
                    )
                    .with_origins(rubbing.iter().map(|c| pos(c)))
                    .with_colors([purple]),
                ),
                self.rec.log(
                    "contacts/slip",
                    &Arrows3D::from_vectors(slipping.iter().map(|c| xyz(&(c.slip_velocity * h))))
                        .with_origins(slipping.iter().map(|c| pos(c)))
                        .with_colors([green]),
                ),
            ]
        };
        for r in results {
            self.check(r);
        }
    }

    /// Logs the changes of the active set as text.
    fn log_status_changes(&mut self, info: &IterationInfo<'_, D>) {
        let now: BTreeSet<(usize, Option<usize>)> = info
            .contacts
            .iter()
            .filter(|c| c.active)
            .map(|c| (c.slave, c.obstacle))
            .collect();
        if now == self.active {
            return;
        }
        let name = |o: Option<usize>, obstacles: &[Obstacle<D>]| match o {
            Some(o) => match obstacles.get(o) {
                Some(ob) => format!("obstacle `{}`", ob.name),
                None => format!("obstacle {o}"),
            },
            None => "a body facet".to_string(),
        };
        let closed: Vec<_> = now.difference(&self.active).copied().collect();
        let opened: Vec<_> = self.active.difference(&now).copied().collect();
        const DETAIL: usize = 10;
        let mut lines = vec![format!(
            "step {} iteration {}: {} contact(s) closed, {} opened; active set {}",
            info.step,
            info.iteration,
            closed.len(),
            opened.len(),
            now.len()
        )];
        for &(slave, o) in closed.iter().take(DETAIL) {
            let rec = info
                .contacts
                .iter()
                .find(|c| c.slave == slave && c.obstacle == o);
            let (gap, force) = rec.map_or((0.0, 0.0), |c| (c.gap, c.normal_force));
            lines.push(format!(
                "  node {slave} closed on {} (gap {gap:.3e} m, normal force {force:.3e} N)",
                name(o, &self.obstacles)
            ));
        }
        for &(slave, o) in opened.iter().take(DETAIL) {
            lines.push(format!(
                "  node {slave} released from {}",
                name(o, &self.obstacles)
            ));
        }
        if closed.len() > DETAIL || opened.len() > DETAIL {
            lines.push("  ...".into());
        }
        self.active = now;
        self.log_text(TextLogLevel::INFO, lines.join("\n"));
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
        // The committed state does not change during the step.
        if self.color_field == ColorField::VonMises {
            self.mises = sim.cell_stresses().iter().map(von_mises).collect();
        }
        let t_end = sim.state().time + sim.settings().time_step;
        self.set_time(step, self.iteration + 1, t_end);
        for o in 0..self.obstacles.len() {
            if self.obstacles[o].velocity.iter().any(|v| *v != 0.0) {
                self.log_obstacle(o, t_end, false);
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
        let active = info.contacts.iter().filter(|c| c.active).count();
        let scalars = [
            ("solver/residual_norm", info.residual_norm),
            ("solver/relative_residual", info.relative_residual),
            ("solver/increment_norm", info.increment_norm),
            ("solver/active_set_size", active as f64),
            ("solver/candidates", info.candidates as f64),
        ];
        for (path, value) in scalars {
            let r = self.rec.log(path, &Scalars::single(value));
            self.check(r);
        }
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

fn builder() -> RecordingStreamBuilder {
    RecordingStreamBuilder::new(APPLICATION_ID)
}

/// The layout the recording opens on: the bodies and contacts on the left; the solver
/// residuals, the energies and the text log on the right; the `iteration` timeline selected.
fn blueprint<const D: usize>() -> Blueprint {
    let contents = ["bodies/**", "obstacles/**", "contacts/**"];
    let scene: ContainerLike = if D == 2 {
        Spatial2DView::new("Bodies and contacts")
            .with_contents(contents)
            .into()
    } else {
        Spatial3DView::new("Bodies and contacts")
            .with_contents(contents)
            .into()
    };
    let residuals = Tabs::new([
        TimeSeriesView::new("Residual norm [N]")
            .with_contents(["solver/residual_norm"])
            .into(),
        TimeSeriesView::new("Relative residual")
            .with_contents(["solver/relative_residual"])
            .into(),
        TimeSeriesView::new("Increment norm [m/s]")
            .with_contents(["solver/increment_norm"])
            .into(),
    ]);
    let plots = Vertical::new([
        residuals.into(),
        TimeSeriesView::new("Active set")
            .with_contents(["solver/active_set_size", "solver/candidates"])
            .into(),
        TimeSeriesView::new("Energy [J]")
            .with_origin("energy")
            .into(),
        TextLogView::new("Log").with_origin("log").into(),
    ]);
    // Following: the viewer opens on the last iteration recorded (live: the newest).
    let time = TimePanel::new()
        .with_timeline("iteration")
        .with_play_state(PlayState::Following);
    Blueprint::new(Horizontal::new([scene, plots.into()]).with_column_shares(vec![2.0, 1.0]))
        .with_time_panel(time)
}

/// The boundary triangles of a 3D mesh with compact vertex numbering.
fn surface<const D: usize>(facets: &[[usize; D]], nodes: usize) -> (Vec<usize>, Vec<[u32; 3]>) {
    let mut index = vec![u32::MAX; nodes];
    let mut surface_nodes = Vec::new();
    let mut triangles = Vec::with_capacity(facets.len());
    for f in facets {
        let mut t = [0u32; 3];
        for (k, &n) in f.iter().take(3).enumerate() {
            if index[n] == u32::MAX {
                index[n] = surface_nodes.len() as u32;
                surface_nodes.push(n);
            }
            t[k] = index[n];
        }
        triangles.push(t);
    }
    (surface_nodes, triangles)
}

/// 2D positions and vectors as Rerun logs them. Rerun's 2D views draw y downwards (image
/// convention), so y is negated: the scene appears upright, and tools reading `bodies/*`,
/// `contacts/*` or `obstacles/*` of a 2D recording must negate y back.
fn xy<const D: usize>(p: &SVector<f64, D>) -> [f32; 2] {
    [p[0] as f32, -(p[1] as f32)]
}

fn xyz<const D: usize>(p: &SVector<f64, D>) -> [f32; 3] {
    let z = if D > 2 { p[2] } else { 0.0 };
    [p[0] as f32, p[1] as f32, z as f32]
}

/// Rainbow colour of `value / top` (blue at 0, cyan, green, yellow, red at 1), bright enough
/// on the viewer's dark background.
fn colormap(value: f64, top: f64) -> Color {
    const STOPS: [[f64; 3]; 5] = [
        [40.0, 90.0, 255.0],
        [0.0, 200.0, 255.0],
        [40.0, 220.0, 80.0],
        [255.0, 220.0, 0.0],
        [230.0, 30.0, 30.0],
    ];
    let s = if top > 0.0 && value.is_finite() {
        (value / top).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = s * (STOPS.len() - 1) as f64;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - i as f64;
    let c = |k: usize| (STOPS[i][k] + f * (STOPS[i + 1][k] - STOPS[i][k])).round() as u8;
    Color::from_rgb(c(0), c(1), c(2))
}

/// Red for penetration, blue for an open gap, stronger with |gap| / top.
fn gap_color(gap: f64, top: f64) -> Color {
    let s = if top > 0.0 && gap.is_finite() {
        (gap.abs() / top).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let fade = (200.0 * (1.0 - s)) as u8;
    if gap < 0.0 {
        Color::from_rgb(230, fade, fade)
    } else {
        Color::from_rgb(fade, fade, 230)
    }
}

/// 2D outline of an obstacle shape as line strips [m]; a half-space is drawn as a segment
/// `4 size` long around the point of its boundary nearest the origin of its `point`.
fn shape_strips<const D: usize>(shape: &ObstacleShape<D>, size: f64) -> Vec<Vec<SVector<f64, D>>> {
    let v = |x: f64, y: f64| SVector::<f64, D>::from_fn(|k, _| if k == 0 { x } else { y });
    match shape {
        ObstacleShape::Halfspace { point, normal } => {
            let n = normal.normalize();
            let t = v(-n[1], n[0]);
            vec![vec![point - t * (2.0 * size), point + t * (2.0 * size)]]
        }
        ObstacleShape::Box {
            center,
            half_extents: e,
        } => {
            let corners = [
                (-1.0, -1.0),
                (1.0, -1.0),
                (1.0, 1.0),
                (-1.0, 1.0),
                (-1.0, -1.0),
            ];
            vec![corners
                .iter()
                .map(|(a, b)| center + v(a * e[0], b * e[1]))
                .collect()]
        }
        ObstacleShape::Ball { center, radius } => {
            let n = 64;
            vec![(0..=n)
                .map(|i| {
                    let a = std::f64::consts::TAU * i as f64 / n as f64;
                    center + v(radius * a.cos(), radius * a.sin())
                })
                .collect()]
        }
        ObstacleShape::Facets { vertices, indices } => indices
            .iter()
            .map(|f| f.iter().filter_map(|&i| vertices.get(i).copied()).collect())
            .collect(),
    }
}

/// 3D surface of an obstacle shape: vertices [m] and triangles; a half-space is drawn as a
/// square of side `4 size` centred on its `point`.
fn shape_triangles<const D: usize>(
    shape: &ObstacleShape<D>,
    size: f64,
) -> (Vec<SVector<f64, D>>, Vec<[u32; 3]>) {
    let v = |x: f64, y: f64, z: f64| {
        SVector::<f64, D>::from_fn(|k, _| match k {
            0 => x,
            1 => y,
            _ => z,
        })
    };
    match shape {
        ObstacleShape::Halfspace { point, normal } => {
            let n = normal.normalize();
            // Any vector not parallel to n, then two tangents.
            let a = if n[0].abs() < 0.9 {
                v(1.0, 0.0, 0.0)
            } else {
                v(0.0, 1.0, 0.0)
            };
            let t1 = cross(&n, &a).normalize() * (2.0 * size);
            let t2 = cross(&n, &t1);
            let verts = vec![
                point - t1 - t2,
                point + t1 - t2,
                point + t1 + t2,
                point - t1 + t2,
            ];
            (verts, vec![[0, 1, 2], [0, 2, 3]])
        }
        ObstacleShape::Box {
            center,
            half_extents: e,
        } => {
            let mut verts = Vec::with_capacity(8);
            for k in 0..8 {
                let s = |bit: usize| if k & (1 << bit) != 0 { 1.0 } else { -1.0 };
                verts.push(center + v(s(0) * e[0], s(1) * e[1], s(2) * e[2]));
            }
            let quads = [
                [0, 2, 3, 1],
                [4, 5, 7, 6],
                [0, 1, 5, 4],
                [2, 6, 7, 3],
                [0, 4, 6, 2],
                [1, 3, 7, 5],
            ];
            let tris = quads
                .iter()
                .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
                .collect();
            (verts, tris)
        }
        ObstacleShape::Ball { center, radius } => {
            let (rings, sectors) = (12usize, 24usize);
            let mut verts = Vec::new();
            for i in 0..=rings {
                let theta = std::f64::consts::PI * i as f64 / rings as f64;
                for j in 0..sectors {
                    let phi = std::f64::consts::TAU * j as f64 / sectors as f64;
                    verts.push(
                        center
                            + v(
                                radius * theta.sin() * phi.cos(),
                                radius * theta.sin() * phi.sin(),
                                radius * theta.cos(),
                            ),
                    );
                }
            }
            let mut tris = Vec::new();
            for i in 0..rings {
                for j in 0..sectors {
                    let a = (i * sectors + j) as u32;
                    let b = (i * sectors + (j + 1) % sectors) as u32;
                    let c = a + sectors as u32;
                    let d = b + sectors as u32;
                    tris.push([a, c, b]);
                    tris.push([b, c, d]);
                }
            }
            (verts, tris)
        }
        ObstacleShape::Facets { vertices, indices } => {
            let tris = indices
                .iter()
                .filter(|f| f.len() >= 3 && f.iter().all(|&i| i < vertices.len()))
                .map(|f| [f[0] as u32, f[1] as u32, f[2] as u32])
                .collect();
            (vertices.clone(), tris)
        }
    }
}

fn cross<const D: usize>(a: &SVector<f64, D>, b: &SVector<f64, D>) -> SVector<f64, D> {
    let c = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    SVector::<f64, D>::from_fn(|k, _| c[k])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colormap_ends() {
        let blue = Color::from_rgb(40, 90, 255);
        assert_eq!(colormap(0.0, 1.0), blue);
        assert_eq!(colormap(2.0, 1.0), Color::from_rgb(230, 30, 30));
        assert_eq!(colormap(0.5, 1.0), Color::from_rgb(40, 220, 80));
        assert_eq!(colormap(f64::NAN, 1.0), blue);
        assert_eq!(colormap(1.0, 0.0), blue);
    }

    #[test]
    fn surface_is_compact() {
        let (nodes, tris) = surface::<3>(&[[5, 7, 9], [7, 9, 11]], 12);
        assert_eq!(nodes, vec![5, 7, 9, 11]);
        assert_eq!(tris, vec![[0, 1, 2], [1, 2, 3]]);
    }
}
