//! Checkpoints: everything a run needs to continue bit for bit, in one file.
//!
//! `softway run SCENE --checkpoint-every N` writes `<out>/checkpoints/step_<N>.ckpt`;
//! `softway resume CHECKPOINT` continues from it ([`super::output::resume`]). A checkpoint
//! holds the [`Model`] (settings, meshes, materials, obstacles, contact), the [`State`] (the
//! simulation continues from them exactly: [`Simulation::from_parts`]), what the run adds
//! (end time, probes, output intervals) and what its outputs need to continue: the text of
//! `history.csv` so far, the VTK frames of the `.pvd` collection, the counters of the summary
//! and the times of the next history row and VTK frame.
//!
//! The file is one header line, then JSON:
//!
//! ```text
//! softway-checkpoint format=1 dimension=2 softway=0.1.0 bytes=123456 crc32=1a2b3c4d
//! {"softway_version":"0.1.0", ...}
//! ```
//!
//! `bytes` is the length of the JSON and `crc32` its checksum, so that a truncated or corrupted
//! file is refused with a message that says so. Every `f64` is written as the shortest text
//! that reads back to the same bits (serde_json with `float_roundtrip`), and the writer reads
//! each checkpoint back before keeping it.
//!
//! [`Simulation::from_parts`]: crate::simulation::Simulation::from_parts

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::atomic::write_atomic;
use super::scene::{OutputOptions, Probe, Scene};
use crate::dim::{Dim, SpatialDim};
use crate::error::{Error, Result};
use crate::simulation::{Model, RunMonitor, State};

/// The format version this softway writes and reads.
pub const FORMAT: u32 = 1;

const MAGIC: &str = "softway-checkpoint";

/// A checkpoint of a run of dimension D.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(bound = "")]
pub struct Checkpoint<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    /// The softway version that wrote it (bit-for-bit continuation holds for the same build).
    pub softway_version: String,
    /// The scene file's stem (names the `.pvd` collection).
    pub stem: String,
    /// End time of the run (s).
    pub end_time: f64,
    /// `[output]` history_interval (s; 0 = every step).
    pub history_interval: f64,
    /// `[output]` vtk_interval (s; 0 = no VTK files).
    pub vtk_interval: f64,
    /// The probes: (name, body index, node of the body's mesh).
    pub probes: Vec<(String, usize, usize)>,
    /// Everything the simulation is built from.
    pub model: Model<D>,
    /// The state after step `state.step`.
    pub state: State,
    /// What the run loop and its outputs carry.
    pub run: RunRecord,
}

/// What the run loop carries from step to step besides the simulation's state.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RunRecord {
    /// The checkpoint interval of the run (steps; 0: none).
    pub checkpoint_every: usize,
    /// Newton plus contact iterations so far.
    pub total_iterations: usize,
    /// Largest penetration so far (m).
    pub max_penetration: f64,
    /// Wall-clock seconds spent so far, over every resumption.
    pub wall_seconds: f64,
    /// Warnings of the summary so far (the simulation's, from its model).
    pub warnings: Vec<String>,
    /// Time of the last history row (s).
    pub last_history: f64,
    /// Time of the next VTK frame (s).
    pub next_vtk: f64,
    /// Largest rotation of each body seen so far (small-strain laws warn about it) (rad).
    pub turned: Vec<f64>,
    /// The text of `history.csv` so far, header included.
    pub history: String,
    /// The `.pvd` entries so far: (time, part, file relative to the output folder).
    pub pvd: Vec<(f64, usize, String)>,
    /// The run's monitor (energy created since the run's start, penetration, cuts, cycles).
    /// Absent in checkpoints written before it was stored: the resumed run's monitor then
    /// starts at the checkpoint.
    #[serde(default)]
    pub monitor: Option<RunMonitor>,
}

/// A checkpoint of either dimension, as read from a file.
#[derive(Debug, Clone)]
pub enum AnyCheckpoint {
    /// A 2D run.
    Two(Box<Checkpoint<2>>),
    /// A 3D run.
    Three(Box<Checkpoint<3>>),
}

impl<const D: usize> Checkpoint<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// The scene the run loop works from (the model's parts, end time, probes, outputs).
    pub fn scene(&self) -> Scene<D> {
        Scene {
            settings: self.model.settings.clone(),
            end_time: self.end_time,
            bodies: self.model.bodies.clone(),
            obstacles: self.model.obstacles.clone(),
            probes: self
                .probes
                .iter()
                .map(|(name, body, node)| Probe {
                    name: name.clone(),
                    body: *body,
                    node: *node,
                })
                .collect(),
            output: OutputOptions {
                history_interval: self.history_interval,
                vtk_interval: self.vtk_interval,
            },
            contact: self.model.contact.clone(),
        }
    }

    /// The scene-level parts of a checkpoint of `scene` (the model, state and run record are
    /// filled in by the caller).
    pub(crate) fn of_scene(
        scene: &Scene<D>,
        stem: &str,
        model: Model<D>,
        state: State,
        run: RunRecord,
    ) -> Self {
        Checkpoint {
            softway_version: env!("CARGO_PKG_VERSION").to_string(),
            stem: stem.to_string(),
            end_time: scene.end_time,
            history_interval: scene.output.history_interval,
            vtk_interval: scene.output.vtk_interval,
            probes: scene
                .probes
                .iter()
                .map(|p| (p.name.clone(), p.body, p.node))
                .collect(),
            model,
            state,
            run,
        }
    }

    /// Writes the checkpoint to `path`, whole or not at all (synced to disk before the
    /// rename). It is read back first: a value JSON cannot carry (a non-finite number) is an
    /// error here rather than a checkpoint that cannot be resumed.
    pub fn write(&self, path: &Path) -> Result<()> {
        let output_error = |message: String| Error::Output {
            file: path.to_path_buf(),
            source: std::io::Error::other(message),
        };
        let json = serde_json::to_string(self).map_err(|e| output_error(e.to_string()))?;
        let back: Checkpoint<D> = serde_json::from_str(&json)
            .map_err(|e| output_error(format!("the checkpoint would not read back: {e}")))?;
        let again = serde_json::to_string(&back).map_err(|e| output_error(e.to_string()))?;
        if again != json {
            return Err(output_error(
                "the checkpoint would not read back to the same values".into(),
            ));
        }
        let header = format!(
            "{MAGIC} format={FORMAT} dimension={D} softway={} bytes={} crc32={:08x}\n",
            env!("CARGO_PKG_VERSION"),
            json.len(),
            crc32fast::hash(json.as_bytes())
        );
        write_atomic(path, true, |w| {
            w.write_all(header.as_bytes())?;
            w.write_all(json.as_bytes())
        })
        .map_err(|source| Error::Output {
            file: path.to_path_buf(),
            source,
        })
    }
}

/// `<out>/checkpoints/step_<step>.ckpt`.
pub fn path_for(out: &Path, step: usize) -> PathBuf {
    out.join("checkpoints").join(format!("step_{step}.ckpt"))
}

/// The output folder `softway resume` writes into by default: the folder that holds the
/// checkpoint's `checkpoints/` folder (the run's own), else the checkpoint's folder.
pub fn default_out(checkpoint: &Path) -> PathBuf {
    let folder = checkpoint.parent().unwrap_or(Path::new(""));
    match folder.file_name() {
        Some(name) if name == "checkpoints" => folder.parent().unwrap_or(Path::new("")),
        _ => folder,
    }
    .to_path_buf()
}

/// Reads and checks a checkpoint: its header (format, dimension, length, checksum), then its
/// content. Every problem is an [`Error::Checkpoint`] that names the file and says what is
/// wrong.
pub fn read(path: &Path) -> Result<AnyCheckpoint> {
    let problem = |problem: String| Error::Checkpoint {
        file: path.to_path_buf(),
        problem,
    };
    let bytes = std::fs::read(path).map_err(|e| problem(format!("cannot read it: {e}")))?;
    let not_one = || {
        problem(format!(
            "not a softway checkpoint (it does not start with `{MAGIC}`)"
        ))
    };
    let newline = bytes.iter().position(|&b| b == b'\n').ok_or_else(not_one)?;
    let header = std::str::from_utf8(&bytes[..newline]).map_err(|_| not_one())?;
    let mut words = header.split(' ');
    if words.next() != Some(MAGIC) {
        return Err(not_one());
    }
    let fields: Vec<(&str, &str)> = words.filter_map(|w| w.split_once('=')).collect();
    let field = |key: &str| {
        fields
            .iter()
            .find(|(k, _)| *k == key)
            .map(|(_, v)| *v)
            .ok_or_else(|| problem(format!("corrupted: its header has no `{key}`")))
    };
    let format: u32 = field("format")?
        .parse()
        .map_err(|_| problem("corrupted: its header's `format` is not a number".into()))?;
    if format != FORMAT {
        return Err(problem(format!(
            "checkpoint format {format} (written by softway {}), this softway ({}) reads \
             format {FORMAT}: resume it with the softway that wrote it",
            field("softway").unwrap_or("?"),
            env!("CARGO_PKG_VERSION")
        )));
    }
    let expected: usize = field("bytes")?
        .parse()
        .map_err(|_| problem("corrupted: its header's `bytes` is not a number".into()))?;
    let body = &bytes[newline + 1..];
    if body.len() < expected {
        return Err(problem(format!(
            "truncated: {} of its {expected} bytes are there; resume from an earlier \
             checkpoint",
            body.len()
        )));
    }
    if body.len() > expected {
        return Err(problem(format!(
            "corrupted: {} bytes where its header says {expected}; resume from an earlier \
             checkpoint",
            body.len()
        )));
    }
    let crc = field("crc32")?;
    let actual = format!("{:08x}", crc32fast::hash(body));
    if crc != actual {
        return Err(problem(format!(
            "corrupted: its checksum is crc32 {actual}, its header says {crc}; resume from an \
             earlier checkpoint"
        )));
    }
    let content = |e: serde_json::Error| {
        problem(format!(
            "its content does not describe a run this softway can continue: {e}"
        ))
    };
    match field("dimension")? {
        "2" => Ok(AnyCheckpoint::Two(Box::new(
            serde_json::from_slice(body).map_err(content)?,
        ))),
        "3" => Ok(AnyCheckpoint::Three(Box::new(
            serde_json::from_slice(body).map_err(content)?,
        ))),
        d => Err(problem(format!(
            "corrupted: its header's dimension is {d}, expected 2 or 3"
        ))),
    }
}
