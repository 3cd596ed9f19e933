//! Running a scene and writing its outputs: `history.csv`, `summary.json`, VTK files,
//! checkpoints (`super::checkpoint`); resuming from a checkpoint.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use nalgebra::SVector;
use serde::Serialize;

use super::atomic::{remove_temporaries, write_atomic};
use super::checkpoint::{self, Checkpoint, RunRecord};
use super::scene::Scene;
use super::vtk::{self, VtkCellKind, VtkField, VtkPiece};
use crate::assembly::von_mises;
use crate::contact::ContactMethod;
use crate::dim::{Dim, SpatialDim};
use crate::element::ElementKind;
use crate::error::{Error, Result};
use crate::recording::Recorder;
use crate::simulation::{RunMonitor, Simulation, StepReport};

/// `summary.json`.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Summary {
    /// Steps taken.
    pub steps: usize,
    /// Time reached (s).
    pub final_time: f64,
    /// Newton plus contact iterations over the run.
    pub total_iterations: usize,
    /// Largest penetration over the run (m).
    pub max_penetration: f64,
    /// Wall-clock duration (s).
    pub wall_seconds: f64,
    /// |E(t_end) - E(0) - external_work + dissipated| / max(E(0) + |external_work|, tiny).
    pub energy_drift: f64,
    /// The same account on the energy the time scheme conserves, with the loads' work on its
    /// shadow displacement ([`RunMonitor::scheme_energy_drift`]); free of `energy_drift`'s
    /// `O(h)` offset where a body ends at another velocity under a load.
    pub scheme_energy_drift: f64,
    /// Warnings (stability window, ...).
    pub warnings: Vec<String>,
    /// "completed", "failed" or "interrupted" (SIGINT or SIGTERM, or the caller's stop flag).
    pub status: String,
    /// The error of a failed run.
    pub error: Option<String>,
    /// Energy at t = 0 (J).
    pub initial_energy: f64,
    /// Kinetic + internal + contact energy at the end (J).
    pub final_energy: f64,
    /// Cumulative external work (J).
    pub external_work: f64,
    /// Cumulative dissipation (J).
    pub dissipated_energy: f64,
    /// The last checkpoint this run wrote, relative to the output folder
    /// (`checkpoints/step_<N>.ckpt`), if any.
    pub last_checkpoint: Option<String>,
}

/// Progress of a run, for progress bars.
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    /// Current time (s).
    pub time: f64,
    /// End time (s).
    pub end_time: f64,
    /// Steps done.
    pub steps: usize,
    /// Iterations of the last step.
    pub iterations: usize,
}

/// A failed run: what was written, and why it stopped.
#[derive(Debug)]
pub struct RunFailure {
    /// The summary written to `summary.json`.
    pub summary: Box<Summary>,
    /// The error.
    pub error: Error,
}

/// `history.csv`: written whole at the start (header and the rows so far), then one row
/// appended per history step with a single write, so that a killed run leaves whole rows.
struct History {
    file: File,
    path: PathBuf,
    /// Everything written, for checkpoints (kept only when they are on).
    text: Option<String>,
}

impl History {
    fn start(path: PathBuf, text: String, keep: bool) -> Result<Self> {
        let error = |source| Error::Output {
            file: path.clone(),
            source,
        };
        write_atomic(&path, false, |w| w.write_all(text.as_bytes())).map_err(error)?;
        let file = OpenOptions::new().append(true).open(&path).map_err(error)?;
        Ok(History {
            file,
            path,
            text: keep.then_some(text),
        })
    }

    fn row(&mut self, cells: &[String]) -> Result<()> {
        let line = line(cells);
        self.file
            .write_all(line.as_bytes())
            .map_err(|source| Error::Output {
                file: self.path.clone(),
                source,
            })?;
        if let Some(text) = &mut self.text {
            text.push_str(&line);
        }
        Ok(())
    }
}

/// One CSV line.
fn line(cells: &[String]) -> String {
    cells.join(",") + "\n"
}

fn number(x: f64) -> String {
    // Shortest text that reads back as the same f64; the outputs never hold NaN or inf.
    if x.is_finite() {
        format!("{x:?}")
    } else {
        "0.0".into()
    }
}

fn history_header<const D: usize>(scene: &Scene<D>) -> Vec<String>
where
    Dim<D>: SpatialDim<D>,
{
    let axes = ["x", "y", "z"];
    let mut h: Vec<String> = [
        "step",
        "time",
        "iterations",
        "kinetic_energy",
        "internal_energy",
        "contact_energy",
        "external_work",
        "dissipated_energy",
        "max_penetration",
        "active_contacts",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    for o in &scene.obstacles {
        h.extend(
            axes[..D]
                .iter()
                .map(|a| format!("contact_force.{}.{a}", o.name)),
        );
    }
    for b in scene.bodies.iter().filter(|b| !b.constraints.is_empty()) {
        h.extend(axes[..D].iter().map(|a| format!("reaction.{}.{a}", b.name)));
    }
    for p in &scene.probes {
        h.extend(axes[..D].iter().map(|a| format!("probe.{}.u{a}", p.name)));
        h.extend(axes[..D].iter().map(|a| format!("probe.{}.v{a}", p.name)));
    }
    h
}

fn history_row<const D: usize>(
    sim: &Simulation<D>,
    scene: &Scene<D>,
    report: Option<&StepReport>,
) -> Vec<String>
where
    Dim<D>: SpatialDim<D>,
{
    let e = report.map(|r| r.energies).unwrap_or_else(|| sim.energies());
    let state = sim.state();
    let mut row = vec![
        state.step.to_string(),
        number(state.time),
        report.map_or(0, |r| r.iterations).to_string(),
        number(e.kinetic),
        number(e.internal),
        number(e.contact),
        number(e.external_work),
        number(e.dissipated),
        // At t = 0 the overlaps the scene starts with.
        number(report.map_or_else(|| sim.current_penetration(), |r| r.max_penetration)),
        report.map_or(0, |r| r.active_contacts).to_string(),
    ];
    for k in 0..scene.obstacles.len() {
        row.extend((0..D).map(|i| number(report.map_or(0.0, |r| r.contact_forces[k][i]))));
    }
    for (b, body) in scene.bodies.iter().enumerate() {
        if body.constraints.is_empty() {
            continue;
        }
        for k in 0..D {
            row.push(number(report.map_or(0.0, |r| r.reactions[b][k])));
        }
    }
    let ids = sim.body_ids();
    for p in &scene.probes {
        let u = sim
            .displacement(ids[p.body], p.node)
            .unwrap_or_else(|_| SVector::zeros());
        let v = sim
            .velocity(ids[p.body], p.node)
            .unwrap_or_else(|_| SVector::zeros());
        row.extend(u.iter().map(|x| number(*x)));
        row.extend(v.iter().map(|x| number(*x)));
    }
    row
}

fn vtk_kind(kind: ElementKind) -> VtkCellKind {
    match kind {
        ElementKind::Tri3 => VtkCellKind::Tri3,
        ElementKind::Quad4 => VtkCellKind::Quad4,
        ElementKind::Tet4 => VtkCellKind::Tet4,
        ElementKind::Hex8 => VtkCellKind::Hex8,
    }
}

/// Writes one `.vtu` per body for the current state; returns the files relative to `out`.
fn write_vtk<const D: usize>(
    sim: &Simulation<D>,
    out: &Path,
    contacts: &[(usize, f64, f64)],
) -> Result<Vec<String>>
where
    Dim<D>: SpatialDim<D>,
{
    let stresses = sim.cell_stresses();
    let strains = sim.cell_equivalent_strains();
    let mut cell_offset = 0;
    let mut files = Vec::new();
    for (b, body) in sim.bodies().iter().enumerate() {
        let range = sim.nodes_of(b);
        let points: Vec<[f64; 3]> = body.mesh.nodes.iter().map(<Dim<D>>::to_3d).collect();
        let mut displacement = Vec::with_capacity(points.len() * 3);
        let mut velocity = Vec::with_capacity(points.len() * 3);
        for g in range.clone() {
            let st = sim.state();
            let u = SVector::<f64, D>::from_column_slice(&st.displacement[g * D..g * D + D]);
            let v = SVector::<f64, D>::from_column_slice(&st.velocity[g * D..g * D + D]);
            displacement.extend_from_slice(&<Dim<D>>::to_3d(&u));
            velocity.extend_from_slice(&<Dim<D>>::to_3d(&v));
        }
        // Contact gap [m] and normal force [N] of the slave points in contact.
        let mut gap = vec![0.0; points.len()];
        let mut force = vec![0.0; points.len()];
        for &(node, g, f) in contacts {
            if range.contains(&node) {
                gap[node - range.start] = g;
                force[node - range.start] = f;
            }
        }
        let cells: Vec<(VtkCellKind, &[usize])> = body
            .mesh
            .blocks
            .iter()
            .flat_map(|blk| blk.cells().map(move |c| (vtk_kind(blk.kind), c)))
            .collect();
        let n_cells = cells.len();
        let body_stress = &stresses[cell_offset..cell_offset + n_cells];
        let body_strain = &strains[cell_offset..cell_offset + n_cells];
        cell_offset += n_cells;
        // Stress as a symmetric 3x3 tensor (ParaView's 9-component convention) and von Mises.
        let mut tensor = Vec::with_capacity(n_cells * 9);
        for s in body_stress {
            tensor.extend_from_slice(&[s[0], s[5], s[4], s[5], s[1], s[3], s[4], s[3], s[2]]);
        }
        let mises: Vec<f64> = body_stress.iter().map(von_mises).collect();
        let piece = VtkPiece {
            points: &points,
            cells: &cells,
            point_data: &[
                VtkField {
                    name: "displacement",
                    components: 3,
                    values: &displacement,
                },
                VtkField {
                    name: "velocity",
                    components: 3,
                    values: &velocity,
                },
                VtkField {
                    name: "contact_gap",
                    components: 1,
                    values: &gap,
                },
                VtkField {
                    name: "contact_force",
                    components: 1,
                    values: &force,
                },
            ],
            cell_data: &[
                VtkField {
                    name: "stress",
                    components: 9,
                    values: &tensor,
                },
                VtkField {
                    name: "von_mises",
                    components: 1,
                    values: &mises,
                },
                VtkField {
                    name: "equivalent_strain",
                    components: 1,
                    values: body_strain,
                },
            ],
        };
        let name = format!("vtk/{}_{:06}.vtu", body.name, sim.state().step);
        let path = out.join(&name);
        vtk::write_vtu(&path, &piece).map_err(|source| Error::Output { file: path, source })?;
        files.push(name);
    }
    Ok(files)
}

fn write_json(path: &Path, summary: &Summary) -> Result<()> {
    let text = serde_json::to_string_pretty(summary).unwrap_or_else(|_| "{}".into());
    write_atomic(path, false, |w| w.write_all((text + "\n").as_bytes())).map_err(|source| {
        Error::Output {
            file: path.to_path_buf(),
            source,
        }
    })
}

/// Options of a run beyond its scene.
#[derive(Debug, Clone, Copy, Default)]
pub struct RunOptions<'a> {
    /// Write `<out>/checkpoints/step_<N>.ckpt` every this many steps (0: no checkpoints).
    pub checkpoint_every: usize,
    /// Read between steps: once it is true the run stops after the step under way, writes
    /// its outputs (and a checkpoint of that step when checkpoints are on) and returns a
    /// summary with status "interrupted". A signal handler sets it.
    pub stop: Option<&'a AtomicBool>,
}

/// What the run loop carries from step to step besides the simulation's state (saved in
/// checkpoints as a [`RunRecord`]).
struct Carried {
    summary: Summary,
    last_history: f64,
    next_vtk: f64,
    turned: Vec<f64>,
    pvd: Vec<(f64, usize, String)>,
    /// Wall-clock seconds of earlier sessions (a resumed run's).
    wall_before: f64,
    /// Energy created since the run's start, penetration, cuts, cycles.
    monitor: RunMonitor,
}

/// Runs a validated scene to its end time, writing the outputs into `out` (created if
/// missing). The history is written row by row, so a failed run leaves everything up to its
/// last good step. `recorder` observes every step and iteration
/// ([`NullRecorder`](crate::recording::NullRecorder) for none); it never changes the results.
pub fn run<const D: usize>(
    scene: &Scene<D>,
    out: &Path,
    stem: &str,
    progress: &mut dyn FnMut(Progress),
    recorder: &mut dyn Recorder<D>,
) -> std::result::Result<Summary, Box<RunFailure>>
where
    Dim<D>: SpatialDim<D>,
{
    run_with(scene, out, stem, RunOptions::default(), progress, recorder)
}

fn fail(error: Error) -> Box<RunFailure> {
    Box::new(RunFailure {
        summary: Box::new(empty_summary()),
        error,
    })
}

/// Creates `out` (and `vtk/`, `checkpoints/` as needed) and removes the partial `*.tmp`
/// files of the kinds a run writes that a killed run may have left there, and an earlier
/// run's `summary.json`.
fn prepare(out: &Path, vtk: bool, checkpoints: bool) -> Result<()> {
    let create = |p: &Path| {
        std::fs::create_dir_all(p).map_err(|source| Error::Output {
            file: p.to_path_buf(),
            source,
        })
    };
    create(out)?;
    remove_temporaries(out, &[".csv.tmp", ".json.tmp", ".pvd.tmp"]);
    // An earlier run's summary: summary.json is there only once this run has ended.
    let summary = out.join("summary.json");
    if summary.is_file() {
        std::fs::remove_file(&summary).map_err(|source| Error::Output {
            file: summary.clone(),
            source,
        })?;
    }
    for (on, folder, ending) in [
        (vtk, "vtk", ".vtu.tmp"),
        (checkpoints, "checkpoints", ".ckpt.tmp"),
    ] {
        if on {
            create(&out.join(folder))?;
            remove_temporaries(&out.join(folder), &[ending]);
        }
    }
    Ok(())
}

/// Like [`run`], with checkpoints and a stop flag ([`RunOptions`]).
pub fn run_with<const D: usize>(
    scene: &Scene<D>,
    out: &Path,
    stem: &str,
    options: RunOptions,
    progress: &mut dyn FnMut(Progress),
    recorder: &mut dyn Recorder<D>,
) -> std::result::Result<Summary, Box<RunFailure>>
where
    Dim<D>: SpatialDim<D>,
{
    let start = Instant::now();
    let sim = scene.simulation().map_err(fail)?;
    // Overlaps beyond the reach of contact detection are invalid input: nothing is written.
    let overlaps = sim.check_overlaps().map_err(fail)?;
    let vtk_on = scene.output.vtk_interval > 0.0;
    prepare(out, vtk_on, options.checkpoint_every > 0).map_err(fail)?;
    let mut text = line(&history_header(scene));
    text += &line(&history_row(&sim, scene, None));
    let history = History::start(out.join("history.csv"), text, options.checkpoint_every > 0)
        .map_err(fail)?;
    let mut summary = empty_summary();
    summary.warnings = sim.warnings().to_vec();
    // `Simulation::current_penetration`, from the overlaps in hand.
    summary.max_penetration = overlaps.iter().fold(0.0, |m: f64, o| m.max(o.depth));
    for overlap in overlaps {
        summary.warnings.push(overlap.to_string());
    }
    summary.initial_energy = sim.initial_energy();
    let mut carried = Carried {
        summary,
        last_history: 0.0,
        next_vtk: scene.output.vtk_interval,
        turned: vec![0.0; scene.bodies.len()],
        pvd: Vec::new(),
        wall_before: 0.0,
        monitor: RunMonitor::new(&sim),
    };
    if vtk_on {
        write_frame(&sim, out, stem, &mut carried.pvd, &[]).map_err(fail)?;
    }
    drive(
        scene, stem, sim, out, history, carried, options, progress, recorder, start,
    )
}

/// Continues a run from a checkpoint ([`checkpoint::read`]),
/// writing into `out`: `history.csv` is rewritten with the checkpoint's rows, then every
/// step appends to it exactly as the uninterrupted run would have; the `.pvd` collection
/// keeps the checkpoint's frames whose files are in `out` (all of them when `out` is the
/// original run's folder).
pub fn resume<const D: usize>(
    checkpoint: Checkpoint<D>,
    out: &Path,
    options: RunOptions,
    progress: &mut dyn FnMut(Progress),
    recorder: &mut dyn Recorder<D>,
) -> std::result::Result<Summary, Box<RunFailure>>
where
    Dim<D>: SpatialDim<D>,
{
    let start = Instant::now();
    let scene = checkpoint.scene();
    let Checkpoint {
        softway_version,
        stem,
        model,
        state,
        run,
        ..
    } = checkpoint;
    if run.turned.len() != scene.bodies.len() {
        return Err(fail(Error::Output {
            file: out.to_path_buf(),
            source: std::io::Error::other("the checkpoint's run record does not fit its model"),
        }));
    }
    let sim = Simulation::from_parts(model, state).map_err(fail)?;
    let vtk_on = scene.output.vtk_interval > 0.0;
    prepare(out, vtk_on, options.checkpoint_every > 0).map_err(fail)?;
    let history = History::start(
        out.join("history.csv"),
        run.history,
        options.checkpoint_every > 0,
    )
    .map_err(fail)?;
    let mut summary = empty_summary();
    summary.steps = sim.state().step;
    summary.total_iterations = run.total_iterations;
    summary.max_penetration = run.max_penetration;
    summary.warnings = run.warnings;
    summary.initial_energy = sim.initial_energy();
    if softway_version != env!("CARGO_PKG_VERSION") {
        summary.warnings.push(format!(
            "resumed from a checkpoint written by softway {softway_version} (this is {}): \
             the results may differ in round-off from the uninterrupted run's",
            env!("CARGO_PKG_VERSION")
        ));
    }
    let pvd: Vec<(f64, usize, String)> = run
        .pvd
        .into_iter()
        .filter(|(_, _, f)| out.join(f).is_file())
        .collect();
    if vtk_on {
        let path = out.join(format!("{stem}.pvd"));
        vtk::write_pvd_parts(&path, &pvd)
            .map_err(|source| fail(Error::Output { file: path, source }))?;
    }
    let carried = Carried {
        summary,
        last_history: run.last_history,
        next_vtk: run.next_vtk,
        turned: run.turned,
        pvd,
        wall_before: run.wall_seconds,
        monitor: run.monitor.unwrap_or_else(|| RunMonitor::new(&sim)),
    };
    drive(
        &scene, &stem, sim, out, history, carried, options, progress, recorder, start,
    )
}

/// Writes the VTK files of the current state and the `.pvd` collection with them.
fn write_frame<const D: usize>(
    sim: &Simulation<D>,
    out: &Path,
    stem: &str,
    pvd: &mut Vec<(f64, usize, String)>,
    contacts: &[(usize, f64, f64)],
) -> Result<()>
where
    Dim<D>: SpatialDim<D>,
{
    for (part, f) in write_vtk(sim, out, contacts)?.into_iter().enumerate() {
        pvd.push((sim.state().time, part, f));
    }
    let pvd_path = out.join(format!("{stem}.pvd"));
    vtk::write_pvd_parts(&pvd_path, pvd).map_err(|source| Error::Output {
        file: pvd_path.clone(),
        source,
    })
}

/// Writes `<out>/checkpoints/step_<N>.ckpt` of the current step; returns its path relative
/// to `out`.
#[allow(clippy::too_many_arguments)]
fn write_checkpoint<const D: usize>(
    scene: &Scene<D>,
    stem: &str,
    sim: &Simulation<D>,
    out: &Path,
    history: &History,
    carried: &Carried,
    every: usize,
    start: Instant,
) -> Result<String>
where
    Dim<D>: SpatialDim<D>,
{
    let run = RunRecord {
        checkpoint_every: every,
        total_iterations: carried.summary.total_iterations,
        max_penetration: carried.summary.max_penetration,
        wall_seconds: carried.wall_before + start.elapsed().as_secs_f64(),
        warnings: carried.summary.warnings.clone(),
        last_history: carried.last_history,
        next_vtk: carried.next_vtk,
        turned: carried.turned.clone(),
        history: history.text.clone().unwrap_or_default(),
        pvd: carried.pvd.clone(),
        monitor: Some(carried.monitor.clone()),
    };
    let ckpt = Checkpoint::of_scene(scene, stem, sim.model().clone(), sim.state().clone(), run);
    let step = sim.state().step;
    ckpt.write(&checkpoint::path_for(out, step))?;
    Ok(format!("checkpoints/step_{step}.ckpt"))
}

/// The run loop, from a fresh start or a checkpoint.
#[allow(clippy::too_many_arguments)]
fn drive<const D: usize>(
    scene: &Scene<D>,
    stem: &str,
    mut sim: Simulation<D>,
    out: &Path,
    mut history: History,
    mut carried: Carried,
    options: RunOptions,
    progress: &mut dyn FnMut(Progress),
    recorder: &mut dyn Recorder<D>,
    start: Instant,
) -> std::result::Result<Summary, Box<RunFailure>>
where
    Dim<D>: SpatialDim<D>,
{
    let vtk_on = scene.output.vtk_interval > 0.0;
    let every = options.checkpoint_every;
    let h = scene.settings.time_step;
    let end = scene.end_time;
    let mut error = None;
    let mut interrupted = false;
    let mut checkpointed = None;
    // Bounded by construction: the scene's step count (at most MAX_STEPS, checked at load)
    // and one more, whatever the round-off of the times.
    let budget = super::scene::step_count(end, h).min(super::scene::MAX_STEPS) as usize + 1;
    for _ in 0..budget {
        if sim.state().time >= end - 1e-9 * h {
            break;
        }
        if options.stop.is_some_and(|s| s.load(Ordering::SeqCst)) {
            interrupted = true;
            break;
        }
        let t = sim.state().time;
        // The last step is shortened to end exactly at end_time.
        let step = if end - t < h * (1.0 + 1e-9) {
            end - t
        } else {
            h
        };
        let report = match sim.advance(step, recorder) {
            Ok(report) => report,
            Err(e) => {
                error = Some(e);
                break;
            }
        };
        let summary = &mut carried.summary;
        match carried.monitor.step(&sim, &report) {
            Ok(Some(news)) => recorder.log(&sim, &format!("warning: {news}")),
            Ok(None) => {}
            Err(e) => {
                // The step is committed: its row shows the energy that stopped the run.
                summary.steps = report.step;
                summary.total_iterations += report.iterations;
                summary.max_penetration = summary.max_penetration.max(report.max_penetration);
                let row = history_row(&sim, scene, Some(&report));
                error = Some(history.row(&row).err().unwrap_or(e));
                break;
            }
        }
        summary.steps = report.step;
        summary.total_iterations += report.iterations;
        summary.max_penetration = summary.max_penetration.max(report.max_penetration);
        let now = report.time;
        let last = now >= end - 1e-9 * h;
        let interval = scene.output.history_interval;
        if interval == 0.0 || now - carried.last_history >= interval * (1.0 - 1e-9) || last {
            carried.last_history = now;
            for (body, angle) in sim.small_strain_rotations() {
                if let Ok(b) = sim.body_index(body) {
                    carried.turned[b] = carried.turned[b].max(angle);
                }
            }
            if let Err(e) = history.row(&history_row(&sim, scene, Some(&report))) {
                error = Some(e);
                break;
            }
        }
        if vtk_on && (now >= carried.next_vtk * (1.0 - 1e-9) || last) {
            carried.next_vtk = next_after(carried.next_vtk, now, scene.output.vtk_interval);
            if let Err(e) = write_frame(&sim, out, stem, &mut carried.pvd, &report.contacts) {
                error = Some(e);
                break;
            }
        }
        if every > 0 && report.step % every == 0 {
            match write_checkpoint(scene, stem, &sim, out, &history, &carried, every, start) {
                Ok(file) => checkpointed = Some((report.step, file)),
                Err(e) => {
                    error = Some(e);
                    break;
                }
            }
        }
        progress(Progress {
            time: now,
            end_time: end,
            steps: report.step,
            iterations: report.iterations,
        });
    }
    let mut summary = carried.summary.clone();
    if interrupted && every > 0 && checkpointed.as_ref().map(|c| c.0) != Some(sim.state().step) {
        // The step the run stopped at, so that nothing done is lost.
        match write_checkpoint(scene, stem, &sim, out, &history, &carried, every, start) {
            Ok(file) => checkpointed = Some((sim.state().step, file)),
            Err(e) => error = Some(e),
        }
    }
    summary.last_checkpoint = checkpointed.map(|c| c.1);
    let e = sim.energies();
    summary.final_time = sim.state().time;
    summary.wall_seconds = carried.wall_before + start.elapsed().as_secs_f64();
    summary.final_energy = e.total();
    summary.external_work = e.external_work;
    summary.dissipated_energy = e.dissipated;
    let reference = (summary.initial_energy + e.external_work.abs()).max(f64::MIN_POSITIVE);
    summary.energy_drift =
        ((e.total() - summary.initial_energy - e.external_work + e.dissipated).abs() / reference)
            .min(f64::MAX);
    summary.scheme_energy_drift = carried.monitor.scheme_energy_drift().min(f64::MAX);
    for (b, &angle) in carried.turned.iter().enumerate() {
        if angle > 0.0 {
            summary.warnings.push(format!(
                "body `{}` turned {:.0} degrees with a small-strain law (linear_elastic): a \
                 finite rotation shows as strain there (wrong stresses, bodies that grow); use \
                 material model = \"hypoelastic\" for large rotations",
                scene.bodies[b].name,
                angle.to_degrees()
            ));
        }
    }
    summary.warnings.extend(carried.monitor.warnings());
    // Booked energy growth closes the account, so energy_drift cannot show it: say it here.
    if e.dissipated < -1e-9 * reference {
        let method = scene.contact.method;
        let cause = match method {
            ContactMethod::ExplicitProjection | ContactMethod::ImplicitProjection => format!(
                "{}'s end-of-step projection moves nodes onto their masters and can put energy \
                 in",
                method.name()
            ),
            _ => format!(
                "{}: a contact or material term booked energy in",
                method.name()
            ),
        };
        summary.warnings.push(format!(
            "the run created {:.4} J ({:.2e} of the input E(0) + |external work|): \
             dissipated_energy is negative, and energy_drift does not count what the account \
             books ({cause})",
            -e.dissipated,
            -e.dissipated / reference
        ));
    }
    if let Some(err) = &error {
        summary.status = "failed".into();
        summary.error = Some(err.to_string());
    } else if interrupted {
        summary.status = "interrupted".into();
    }
    let written = write_json(&out.join("summary.json"), &summary);
    match (error, written) {
        (Some(error), _) | (None, Err(error)) => Err(Box::new(RunFailure {
            summary: Box::new(summary),
            error,
        })),
        (None, Ok(())) => Ok(summary),
    }
}

/// The first multiple of `interval` after `now` (from `next` on): a few additions as the runs
/// always did, then a product, so that no interval, however small, keeps it counting.
fn next_after(mut next: f64, now: f64, interval: f64) -> f64 {
    for _ in 0..64 {
        if next > now * (1.0 + 1e-9) {
            return next;
        }
        next += interval;
    }
    ((now * (1.0 + 1e-9) / interval).floor() + 1.0) * interval
}

fn empty_summary() -> Summary {
    Summary {
        steps: 0,
        final_time: 0.0,
        total_iterations: 0,
        max_penetration: 0.0,
        wall_seconds: 0.0,
        energy_drift: 0.0,
        scheme_energy_drift: 0.0,
        warnings: Vec::new(),
        status: "completed".into(),
        error: None,
        initial_energy: 0.0,
        final_energy: 0.0,
        external_work: 0.0,
        dissipated_energy: 0.0,
        last_checkpoint: None,
    }
}
