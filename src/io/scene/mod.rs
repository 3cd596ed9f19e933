//! Scene files (TOML): the schema of `scene-format.md`, `--set` overrides, validation with
//! messages that name the file, the key and its line.
//!
//! [`load`] reads a file into a [`LoadedScene`] (the raw [`SceneFile`] and the text, for error
//! locations); [`LoadedScene::build`] validates it into a [`Scene`] for dimension 2 or 3.
//! The parts: `schema` (the serde types, as written), `overrides` (`--set`),
//! `error_location` (serde errors as key, found, expected and line), `build` (settings,
//! contact, bodies, probes, output), `mesh_spec` (generators and Gmsh files),
//! `obstacle_spec` (obstacle shapes) and `limits` (steps and memory checked before anything is
//! allocated, the number format of messages).

mod build;
mod error_location;
mod limits;
mod mesh_spec;
mod obstacle_spec;
mod overrides;
mod schema;

use std::path::{Path, PathBuf};

pub use schema::{
    AngularSpec, BetaSpec, BodySection, ComponentsSpec, ConstraintSection, ContactSection,
    FrictionSpec, MaterialSpec, MeshSpec, NamedComponents, ObstacleSection, OutputSection,
    ProbeSection, RegionSpec, SceneFile, ShapeSpec, SimulationSection,
};

use crate::contact::{ContactSettings, Obstacle};
use crate::dim::{Dim, SpatialDim};
use crate::error::{Error, Result};
use crate::simulation::{Body, Settings};
pub use build::scene_size;
use error_location::{
    line_of, refine_key, scene_path, split_serde_message, untagged_expectation, value_at,
};
pub use limits::{
    cell_triplets, memory_limit, memory_lower_bound, plain, step_count, DEFAULT_MEMORY_LIMIT,
    MAX_STEPS,
};
use overrides::apply_override;

/// A parsed scene file with the text it came from (for error locations).
#[derive(Debug, Clone)]
pub struct LoadedScene {
    /// The scene file.
    pub path: PathBuf,
    /// The raw schema.
    pub file: SceneFile,
    text: String,
    overridden: Vec<String>,
}

/// Reads, overrides (`KEY=VALUE` with dotted keys; `bodies.0.` and `obstacles.NAME.` address
/// list items) and deserialises a scene file.
pub fn load(path: &Path, overrides: &[String]) -> Result<LoadedScene> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::SceneSyntax {
        file: path.to_path_buf(),
        message: format!("cannot read the scene file: {e}"),
    })?;
    parse(path, &text, overrides)
}

/// Like [`load`], from text.
pub fn parse(path: &Path, text: &str, overrides: &[String]) -> Result<LoadedScene> {
    let syntax = |message: String| Error::SceneSyntax {
        file: path.to_path_buf(),
        message,
    };
    let mut table: toml::Table =
        toml::from_str(text).map_err(|e| syntax(e.to_string().trim_end().to_string()))?;
    let mut overridden = Vec::new();
    for o in overrides {
        let key = apply_override(&mut table, o).map_err(|m| syntax(format!("--set {o}: {m}")))?;
        overridden.push(key);
    }
    let value = toml::Value::Table(table);
    let file: SceneFile = serde_path_to_error::deserialize(value.clone()).map_err(|e| {
        // `message()`, not `to_string()`: the latter appends "in `path`" on extra lines.
        let message = e.inner().message().trim_end().to_string();
        let key = refine_key(&value, &scene_path(&e.path().to_string()), &message);
        let located = LoadedScene {
            path: path.to_path_buf(),
            file: empty_scene(),
            text: text.to_string(),
            overridden: overridden.clone(),
        };
        let (found, expected) = match untagged_expectation(&key) {
            Some(expected) if message.starts_with("data did not match any variant") => {
                let found = value_at(&value, &key)
                    .map(|v| v.to_string())
                    .unwrap_or_else(|| "nothing".into());
                (found, expected.to_string())
            }
            _ => split_serde_message(&message),
        };
        Error::Scene {
            file: path.to_path_buf(),
            location: located.location(&key),
            key,
            found,
            expected,
        }
    })?;
    Ok(LoadedScene {
        path: path.to_path_buf(),
        file,
        text: text.to_string(),
        overridden,
    })
}

/// A found value that is a number, in [`plain`] notation (never 309 digits).
fn plain_found(found: String) -> String {
    match found.parse::<f64>() {
        Ok(x) => plain(x),
        Err(_) => found,
    }
}

fn empty_scene() -> SceneFile {
    SceneFile {
        simulation: SimulationSection {
            dimension: 2,
            kinematics: None,
            time_step: 1.0,
            end_time: 0.0,
            alpha: 0.75,
            beta: BetaSpec::default(),
            gravity: None,
            max_iterations: 1,
            tolerance: 1e-8,
            mass: None,
            ordering: None,
        },
        contact: ContactSection::default(),
        bodies: Vec::new(),
        obstacles: Vec::new(),
        probes: Vec::new(),
        output: OutputSection::default(),
    }
}

impl LoadedScene {
    /// `line N: ` for a dotted key path, or `--set: ` when the key was overridden.
    pub fn location(&self, key: &str) -> String {
        if self
            .overridden
            .iter()
            .any(|o| key == o || key.starts_with(&format!("{o}.")))
        {
            return "--set: ".into();
        }
        // A value of the file judged with a sibling from --set (the indices of a polyline
        // whose vertices were overridden): the line, and the override it was judged with.
        let sibling = self.overridden.iter().find(|o| {
            o.rsplit_once('.').is_some_and(|(parent, _)| {
                parent.contains('.') && key.starts_with(&format!("{parent}."))
            })
        });
        match (line_of(&self.text, key), sibling) {
            (Some(line), Some(o)) => format!("line {line} (with --set {o}): "),
            (Some(line), None) => format!("line {line}: "),
            (None, _) => String::new(),
        }
    }

    /// An error about `key`.
    pub fn error(
        &self,
        key: &str,
        found: impl std::fmt::Display,
        expected: impl Into<String>,
    ) -> Error {
        Error::Scene {
            file: self.path.clone(),
            location: self.location(key),
            key: key.to_string(),
            found: plain_found(found.to_string()),
            expected: expected.into(),
        }
    }

    /// The folder paths in the scene are relative to.
    pub fn base_dir(&self) -> PathBuf {
        self.path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default()
    }

    /// The dimension the scene declares (2 or 3).
    pub fn dimension(&self) -> Result<usize> {
        match self.file.simulation.dimension {
            2 => Ok(2),
            3 => Ok(3),
            d => Err(self.error("simulation.dimension", d, "2 or 3")),
        }
    }
}

/// Output options.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutputOptions {
    /// (s); 0 = every step.
    pub history_interval: f64,
    /// (s); 0 = none.
    pub vtk_interval: f64,
}

/// A probe: the nearest node of a body.
#[derive(Debug, Clone, PartialEq)]
pub struct Probe {
    /// Name.
    pub name: String,
    /// Body index.
    pub body: usize,
    /// Node in the body's mesh.
    pub node: usize,
}

/// A scene validated for dimension D.
#[derive(Debug, Clone)]
pub struct Scene<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    /// Global settings.
    pub settings: Settings<D>,
    /// End time (s).
    pub end_time: f64,
    /// Bodies.
    pub bodies: Vec<Body<D>>,
    /// Obstacles.
    pub obstacles: Vec<Obstacle<D>>,
    /// Probes.
    pub probes: Vec<Probe>,
    /// Output options.
    pub output: OutputOptions,
    /// Contact method, penalty and default friction.
    pub contact: ContactSettings,
}

impl<const D: usize> Scene<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// The simulation this scene describes.
    pub fn simulation(&self) -> Result<crate::simulation::Simulation<D>> {
        crate::simulation::Simulation::from_model(crate::simulation::Model {
            settings: self.settings.clone(),
            bodies: self.bodies.clone(),
            obstacles: self.obstacles.clone(),
            contact: self.contact.clone(),
        })
    }
}
