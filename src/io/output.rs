//! Running a scene and writing its outputs: `history.csv`, `summary.json`, VTK files.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use std::time::Instant;

use nalgebra::SVector;
use serde::Serialize;

use super::scene::Scene;
use super::vtk::{self, VtkCellKind, VtkField, VtkPiece};
use crate::assembly::von_mises;
use crate::dim::{Dim, SpatialDim};
use crate::element::ElementKind;
use crate::error::{Error, Result};
use crate::recording::Recorder;
use crate::simulation::{BodyId, RunMonitor, Simulation, StepReport};

/// `summary.json`.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Summary {
    /// Steps taken.
    pub steps: usize,
    /// Time reached [s].
    pub final_time: f64,
    /// Newton plus contact iterations over the run.
    pub total_iterations: usize,
    /// Largest penetration over the run [m].
    pub max_penetration: f64,
    /// Wall-clock duration [s].
    pub wall_seconds: f64,
    /// |E(t_end) - E(0) - external_work + dissipated| / max(E(0) + |external_work|, tiny).
    pub energy_drift: f64,
    /// Warnings (stability window, ...).
    pub warnings: Vec<String>,
    /// "completed" or "failed".
    pub status: String,
    /// The error of a failed run.
    pub error: Option<String>,
    /// Energy at t = 0 [J].
    pub initial_energy: f64,
    /// Kinetic + internal + contact energy at the end [J].
    pub final_energy: f64,
    /// Cumulative external work [J].
    pub external_work: f64,
    /// Cumulative dissipation [J].
    pub dissipated_energy: f64,
}

/// Progress of a run, for progress bars.
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    /// Current time [s].
    pub time: f64,
    /// End time [s].
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

struct History {
    file: BufWriter<File>,
    path: PathBuf,
}

impl History {
    fn create(path: PathBuf, header: &[String]) -> Result<Self> {
        let file = File::create(&path).map_err(|source| Error::Output {
            file: path.clone(),
            source,
        })?;
        let mut h = History {
            file: BufWriter::new(file),
            path,
        };
        h.row(header.iter().map(String::as_str))?;
        Ok(h)
    }

    fn row<'a>(&mut self, cells: impl Iterator<Item = &'a str>) -> Result<()> {
        let line: Vec<&str> = cells.collect();
        writeln!(self.file, "{}", line.join(","))
            .and_then(|_| self.file.flush())
            .map_err(|source| Error::Output {
                file: self.path.clone(),
                source,
            })
    }
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
    for p in &scene.probes {
        let u = sim
            .displacement(BodyId(p.body), p.node)
            .unwrap_or_else(|_| SVector::zeros());
        let v = sim
            .velocity(BodyId(p.body), p.node)
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
    let mut cell_offset = 0;
    let mut files = Vec::new();
    for (b, body) in sim.bodies().iter().enumerate() {
        let id = BodyId(b);
        let range = sim.body_nodes(id);
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
    let tmp = path.with_extension("json.tmp");
    std::fs::write(&tmp, text + "\n")
        .and_then(|_| std::fs::rename(&tmp, path))
        .map_err(|source| Error::Output {
            file: path.to_path_buf(),
            source,
        })
}

/// Runs a validated scene to its end time, writing the outputs into `out` (created if
/// missing). The history is flushed row by row, so a failed run leaves everything up to its
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
    let start = Instant::now();
    let fail = |error: Error| {
        Box::new(RunFailure {
            summary: Box::new(empty_summary()),
            error,
        })
    };
    let mut sim = scene.simulation().map_err(fail)?;
    let warnings: Vec<String> = sim.warnings().to_vec();
    let create = |p: &Path| {
        std::fs::create_dir_all(p).map_err(|source| Error::Output {
            file: p.to_path_buf(),
            source,
        })
    };
    create(out).map_err(fail)?;
    let vtk_on = scene.output.vtk_interval > 0.0;
    if vtk_on {
        create(&out.join("vtk")).map_err(fail)?;
    }
    let header = history_header(scene);
    let mut history = History::create(out.join("history.csv"), &header).map_err(fail)?;
    history
        .row(history_row(&sim, scene, None).iter().map(String::as_str))
        .map_err(fail)?;

    let pvd_path = out.join(format!("{stem}.pvd"));
    let mut pvd: Vec<(f64, usize, String)> = Vec::new();
    let write_frame = |sim: &Simulation<D>,
                       pvd: &mut Vec<(f64, usize, String)>,
                       contacts: &[(usize, f64, f64)]|
     -> Result<()> {
        for (part, f) in write_vtk(sim, out, contacts)?.into_iter().enumerate() {
            pvd.push((sim.state().time, part, f));
        }
        vtk::write_pvd_parts(&pvd_path, pvd).map_err(|source| Error::Output {
            file: pvd_path.clone(),
            source,
        })
    };
    if vtk_on {
        write_frame(&sim, &mut pvd, &[]).map_err(fail)?;
    }

    let mut summary = empty_summary();
    summary.warnings = warnings;
    for overlap in sim.overlaps() {
        summary.warnings.push(overlap.to_string());
    }
    summary.initial_energy = sim.initial_energy();
    summary.max_penetration = sim.current_penetration();
    let mut monitor = RunMonitor::new(&sim);
    let h = scene.settings.time_step;
    let end = scene.end_time;
    let mut last_history = 0.0;
    let mut next_vtk = scene.output.vtk_interval;
    let mut error = None;
    // The largest rotation of each small-strain body, checked at every history row.
    let mut turned: Vec<f64> = vec![0.0; scene.bodies.len()];
    // Bounded by construction: the scene's step count (at most MAX_STEPS, checked at load)
    // and one more, whatever the round-off of the times.
    let budget = super::scene::step_count(end, h).min(super::scene::MAX_STEPS) as usize + 1;
    for _ in 0..budget {
        if sim.state().time >= end - 1e-9 * h {
            break;
        }
        let t = sim.state().time;
        // The last step is shortened to end exactly at end_time.
        let step = if end - t < h * (1.0 + 1e-9) {
            end - t
        } else {
            h
        };
        match sim.advance(step, recorder) {
            Ok(report) => {
                match monitor.step(&sim, &report) {
                    Ok(Some(news)) => recorder.log(&sim, &format!("warning: {news}")),
                    Ok(None) => {}
                    Err(e) => {
                        // The step is committed: its row shows the energy that stopped the run.
                        summary.steps = report.step;
                        summary.total_iterations += report.iterations;
                        summary.max_penetration =
                            summary.max_penetration.max(report.max_penetration);
                        let row = history_row(&sim, scene, Some(&report));
                        error = Some(
                            history
                                .row(row.iter().map(String::as_str))
                                .err()
                                .unwrap_or(e),
                        );
                        break;
                    }
                }
                summary.steps = report.step;
                summary.total_iterations += report.iterations;
                summary.max_penetration = summary.max_penetration.max(report.max_penetration);
                let now = report.time;
                let last = now >= end - 1e-9 * h;
                let interval = scene.output.history_interval;
                if interval == 0.0 || now - last_history >= interval * (1.0 - 1e-9) || last {
                    last_history = now;
                    for (body, angle) in sim.small_strain_rotations() {
                        turned[body.0] = turned[body.0].max(angle);
                    }
                    if let Err(e) = history.row(
                        history_row(&sim, scene, Some(&report))
                            .iter()
                            .map(String::as_str),
                    ) {
                        error = Some(e);
                        break;
                    }
                }
                if vtk_on && (now >= next_vtk * (1.0 - 1e-9) || last) {
                    next_vtk = next_after(next_vtk, now, scene.output.vtk_interval);
                    if let Err(e) = write_frame(&sim, &mut pvd, &report.contacts) {
                        error = Some(e);
                        break;
                    }
                }
                progress(Progress {
                    time: now,
                    end_time: end,
                    steps: report.step,
                    iterations: report.iterations,
                });
            }
            Err(e) => {
                error = Some(e);
                break;
            }
        }
    }
    let e = sim.energies();
    summary.final_time = sim.state().time;
    summary.wall_seconds = start.elapsed().as_secs_f64();
    summary.final_energy = e.total();
    summary.external_work = e.external_work;
    summary.dissipated_energy = e.dissipated;
    let reference = (summary.initial_energy + e.external_work.abs()).max(f64::MIN_POSITIVE);
    summary.energy_drift =
        ((e.total() - summary.initial_energy - e.external_work + e.dissipated).abs() / reference)
            .min(f64::MAX);
    for (b, &angle) in turned.iter().enumerate() {
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
    summary.warnings.extend(monitor.warnings());
    // Booked energy growth closes the account, so energy_drift cannot show it: say it here.
    if e.dissipated < -1e-9 * reference {
        summary.warnings.push(format!(
            "the run created {:.4} J: dissipated_energy is negative, and energy_drift does not \
             count what the account books (explicit_projection's end-of-step correction can put \
             energy in)",
            -e.dissipated
        ));
    }
    if let Some(err) = &error {
        summary.status = "failed".into();
        summary.error = Some(err.to_string());
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
        warnings: Vec::new(),
        status: "completed".into(),
        error: None,
        initial_energy: 0.0,
        final_energy: 0.0,
        external_work: 0.0,
        dissipated_energy: 0.0,
    }
}
