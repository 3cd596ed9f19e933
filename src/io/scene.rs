//! Scene files (TOML): the schema of `scene-format.md`, `--set` overrides, validation with
//! messages that name the file, the key and its line.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use nalgebra::SVector;
use serde::Deserialize;

use crate::contact::resolution::DEFAULT_REGULARIZATION;
use crate::contact::{ContactMethod, ContactSettings, FrictionLaw, Obstacle, ObstacleShape};
use crate::dim::{Dim, Kinematics, SpatialDim};
use crate::element::ElementKind;
use crate::error::{Error, Result};
use crate::material::{LinearElastic, Material};
use crate::mesh::{generators, Mesh};
use crate::simulation::{Body, Constraint, MassKind, Settings};
use crate::solver::FillOrdering;
use crate::time::{Beta, SpaceTimeScheme};

// ---------------------------------------------------------------------------------------------
// The raw schema, as written in the file.

/// The whole scene file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// `[simulation]`.
    pub simulation: SimulationSection,
    /// `[contact]`.
    #[serde(default)]
    pub contact: ContactSection,
    /// `[[bodies]]`.
    pub bodies: Vec<BodySection>,
    /// `[[obstacles]]`.
    #[serde(default)]
    pub obstacles: Vec<ObstacleSection>,
    /// `[[probes]]`.
    #[serde(default)]
    pub probes: Vec<ProbeSection>,
    /// `[output]`.
    #[serde(default)]
    pub output: OutputSection,
}

/// `beta = "energy" | "trapezoid" | number`.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum BetaSpec {
    /// A number in [0, 1].
    Value(f64),
    /// "energy" or "trapezoid".
    Name(String),
}

impl Default for BetaSpec {
    fn default() -> Self {
        BetaSpec::Name("energy".into())
    }
}

fn default_alpha() -> f64 {
    0.75
}
fn default_max_iterations() -> i64 {
    50
}
fn default_tolerance() -> f64 {
    1e-8
}
fn default_gap_tolerance() -> f64 {
    1e-9
}
fn default_vtk_interval() -> f64 {
    0.01
}

/// `[simulation]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulationSection {
    /// 2 or 3.
    pub dimension: i64,
    /// 2D only.
    #[serde(default)]
    pub kinematics: Option<String>,
    /// h [s].
    pub time_step: f64,
    /// [s].
    pub end_time: f64,
    /// Dirac point.
    #[serde(default = "default_alpha")]
    pub alpha: f64,
    /// Position update weight.
    #[serde(default)]
    pub beta: BetaSpec,
    /// [m/s^2].
    #[serde(default)]
    pub gravity: Option<Vec<f64>>,
    /// Newton + contact iterations per step.
    #[serde(default = "default_max_iterations")]
    pub max_iterations: i64,
    /// Relative residual.
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// "consistent" | "lumped".
    #[serde(default)]
    pub mass: Option<String>,
    /// Fill-reducing ordering of the sparse factorisation: "nested_dissection" (default) |
    /// "minimum_degree".
    #[serde(default)]
    pub ordering: Option<String>,
}

/// A friction law as written.
#[derive(Debug, Clone, Deserialize, PartialEq, Default)]
#[serde(tag = "law", rename_all = "snake_case", deny_unknown_fields)]
pub enum FrictionSpec {
    /// No friction.
    #[default]
    Frictionless,
    /// |F_t| <= mu F_n.
    Coulomb {
        /// mu.
        coefficient: f64,
        /// Stick slip-velocity scale [m/s].
        #[serde(default)]
        regularization: Option<f64>,
    },
    /// Constant limit.
    Tresca {
        /// Limit shear stress [Pa].
        limit: f64,
    },
    /// F_t = -a |v_t|^(p-1) v_t.
    Viscoplastic {
        /// a.
        coefficient: f64,
        /// p.
        exponent: f64,
        /// v_reg [m/s].
        #[serde(default)]
        regularization: Option<f64>,
    },
}

/// `[contact]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSection {
    /// Method name.
    #[serde(default = "default_method")]
    pub method: String,
    /// zeta [Pa/m].
    #[serde(default)]
    pub penalty: Option<f64>,
    /// Self-contact on.
    #[serde(default)]
    pub self_contact: bool,
    /// [m].
    #[serde(default = "default_gap_tolerance")]
    pub gap_tolerance: f64,
    /// Default friction law.
    #[serde(default)]
    pub friction: FrictionSpec,
}

fn default_method() -> String {
    "implicit_projection".into()
}

impl Default for ContactSection {
    fn default() -> Self {
        ContactSection {
            method: default_method(),
            penalty: None,
            self_contact: false,
            gap_tolerance: default_gap_tolerance(),
            friction: FrictionSpec::Frictionless,
        }
    }
}

/// `mesh = { ... }`: a generator or a file.
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// rectangle | box | annulus | polygon.
    pub generator: Option<String>,
    /// A Gmsh file, relative to the scene.
    pub file: Option<String>,
    /// rectangle / box.
    pub min: Option<Vec<f64>>,
    /// rectangle / box.
    pub max: Option<Vec<f64>>,
    /// Cells per direction.
    pub cells: Option<Vec<i64>>,
    /// tri3 | quad4 | tet4 | hex8.
    pub element: Option<String>,
    /// annulus.
    pub center: Option<Vec<f64>>,
    /// annulus [m].
    pub inner_radius: Option<f64>,
    /// annulus [m].
    pub outer_radius: Option<f64>,
    /// polygon [m].
    pub vertices: Option<Vec<Vec<f64>>>,
    /// 3D annulus and polygon: extrusion length along z [m].
    pub length: Option<f64>,
}

/// `material = { model = ..., ... }`.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case", deny_unknown_fields)]
pub enum MaterialSpec {
    /// Small-strain isotropic elasticity.
    LinearElastic {
        /// E [Pa].
        youngs_modulus: f64,
        /// nu.
        poissons_ratio: f64,
        /// rho [kg/m^3].
        density: f64,
    },
    /// Corotational hypoelasticity (large rotations).
    Hypoelastic {
        /// E [Pa].
        youngs_modulus: f64,
        /// nu.
        poissons_ratio: f64,
        /// rho [kg/m^3].
        density: f64,
        /// hughes_winget | paper_series.
        #[serde(default)]
        rotation: Option<String>,
    },
    /// Norton-Hoff viscoplasticity.
    NortonHoff {
        /// K [Pa s^m].
        consistency: f64,
        /// m.
        exponent: f64,
        /// rho [kg/m^3].
        density: f64,
        /// Volumetric penalty [Pa s].
        bulk_penalty: f64,
    },
}

/// A velocity given as an array or as `{ x = .., y = .. }`.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum ComponentsSpec {
    /// All components.
    Array(Vec<f64>),
    /// Some components.
    Named(NamedComponents),
}

/// `{ x = .., y = .., z = .. }`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NamedComponents {
    /// x component.
    pub x: Option<f64>,
    /// y component.
    pub y: Option<f64>,
    /// z component.
    pub z: Option<f64>,
}

/// `region = { min, max }` or `region = { group = "name" }`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    /// Box corner [m].
    pub min: Option<Vec<f64>>,
    /// Box corner [m].
    pub max: Option<Vec<f64>>,
    /// A Gmsh physical group name.
    pub group: Option<String>,
}

/// `[[bodies.constraints]]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConstraintSection {
    /// Which nodes.
    pub region: RegionSpec,
    /// Prescribed components [m/s].
    pub velocity: ComponentsSpec,
}

/// `initial_angular_velocity`: a number in 2D, a vector in 3D.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum AngularSpec {
    /// 2D [rad/s].
    Scalar(f64),
    /// 3D [rad/s].
    Vector(Vec<f64>),
}

/// `[[bodies]]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodySection {
    /// Unique name.
    pub name: String,
    /// Mesh.
    pub mesh: MeshSpec,
    /// Law.
    pub material: MaterialSpec,
    /// [m/s].
    #[serde(default)]
    pub initial_velocity: Option<Vec<f64>>,
    /// [rad/s].
    #[serde(default)]
    pub initial_angular_velocity: Option<AngularSpec>,
    /// Prescribed velocities.
    #[serde(default)]
    pub constraints: Vec<ConstraintSection>,
}

/// `shape = { type = ..., ... }`.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSpec {
    /// Half-space.
    Halfspace {
        /// [m].
        point: Vec<f64>,
        /// Outward normal.
        normal: Vec<f64>,
    },
    /// Axis-aligned box.
    Box {
        /// [m].
        center: Vec<f64>,
        /// [m].
        half_extents: Vec<f64>,
    },
    /// Ball / disc.
    Ball {
        /// [m].
        center: Vec<f64>,
        /// [m].
        radius: f64,
    },
    /// 2D polyline.
    Polyline {
        /// [m].
        #[serde(default)]
        vertices: Option<Vec<Vec<f64>>>,
        /// Segments.
        #[serde(default)]
        indices: Option<Vec<Vec<i64>>>,
        /// A file.
        #[serde(default)]
        file: Option<String>,
    },
    /// 3D triangle mesh.
    Trimesh {
        /// [m].
        #[serde(default)]
        vertices: Option<Vec<Vec<f64>>>,
        /// Triangles.
        #[serde(default)]
        indices: Option<Vec<Vec<i64>>>,
        /// A file.
        #[serde(default)]
        file: Option<String>,
    },
}

/// `[[obstacles]]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleSection {
    /// Unique name.
    pub name: String,
    /// Shape.
    pub shape: ShapeSpec,
    /// [m/s].
    #[serde(default)]
    pub velocity: Option<Vec<f64>>,
    /// Overrides `[contact].friction`.
    #[serde(default)]
    pub friction: Option<FrictionSpec>,
}

/// `[[probes]]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeSection {
    /// Unique name.
    pub name: String,
    /// Body name.
    pub body: String,
    /// [m]; the nearest node of the undeformed mesh is recorded.
    pub point: Vec<f64>,
}

/// `[output]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSection {
    /// Simulated seconds between history rows; 0 = every step.
    #[serde(default)]
    pub history_interval: f64,
    /// Simulated seconds between VTK files; 0 = none.
    #[serde(default = "default_vtk_interval")]
    pub vtk_interval: f64,
}

impl Default for OutputSection {
    fn default() -> Self {
        OutputSection {
            history_interval: 0.0,
            vtk_interval: default_vtk_interval(),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Loading, overrides and error locations.

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

/// serde_path_to_error writes `bodies[0].material`; scene keys are `bodies.0.material`.
fn scene_path(p: &str) -> String {
    let p = p.replace('[', ".").replace(']', "");
    if p == "." {
        String::new()
    } else {
        p
    }
}

/// The value at a dotted key path (`bodies.0.material`), if present.
fn value_at<'a>(root: &'a toml::Value, key: &str) -> Option<&'a toml::Value> {
    let mut v = root;
    for part in key.split('.').filter(|p| !p.is_empty()) {
        v = match v {
            toml::Value::Table(t) => t.get(part)?,
            toml::Value::Array(a) => a.get(part.parse::<usize>().ok()?)?,
            _ => return None,
        };
    }
    Some(v)
}

/// serde's description of a value (`serde::de::Unexpected`), as it appears in its messages.
fn unexpected(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => format!("string {s:?}"),
        toml::Value::Integer(i) => format!("integer `{i}`"),
        toml::Value::Float(f) => format!("floating point `{}`", serde_float(*f)),
        toml::Value::Boolean(b) => format!("boolean `{b}`"),
        toml::Value::Array(_) => "sequence".into(),
        toml::Value::Table(_) => "map".into(),
        toml::Value::Datetime(d) => format!("{d}"),
    }
}

fn serde_float(f: f64) -> String {
    // serde prints floats with a trailing ".0" when integral (its `WithDecimalPoint`).
    let s = f.to_string();
    if f.is_finite() && !s.contains(['.', 'e', 'E']) {
        format!("{s}.0")
    } else {
        s
    }
}

/// serde_path_to_error stops at the table of an internally tagged enum (`material`, `shape`,
/// `friction`) and at the table holding a missing field; this finds the key inside it that
/// the message is about, so the error names e.g. `bodies.0.material.youngs_modulus`.
fn refine_key(root: &toml::Value, key: &str, message: &str) -> String {
    let join = |field: &str| {
        if key.is_empty() {
            field.to_string()
        } else {
            format!("{key}.{field}")
        }
    };
    let quoted = |prefix: &str| {
        message
            .strip_prefix(prefix)
            .and_then(|rest| rest.split('`').next())
            .map(str::to_string)
    };
    let Some(toml::Value::Table(table)) = value_at(root, key) else {
        return key.to_string();
    };
    let names_field = |field: &str| key == field || key.ends_with(&format!(".{field}"));
    if let Some(field) = quoted("missing field `") {
        if !table.contains_key(&field) {
            return join(&field);
        }
    }
    if let Some(field) = quoted("unknown field `") {
        if table.contains_key(&field) && !names_field(&field) {
            return join(&field);
        }
    }
    if let Some(variant) = quoted("unknown variant `") {
        let hits: Vec<&String> = table
            .iter()
            .filter(|(_, v)| v.as_str() == Some(variant.as_str()))
            .map(|(k, _)| k)
            .collect();
        if let [one] = hits[..] {
            return join(one);
        }
    }
    for prefix in ["invalid type: ", "invalid value: "] {
        if let Some(rest) = message.strip_prefix(prefix) {
            let found = rest.split(", expected ").next().unwrap_or("");
            let hits: Vec<&String> = table
                .iter()
                .filter(|(_, v)| unexpected(v) == found)
                .map(|(k, _)| k)
                .collect();
            if let [one] = hits[..] {
                return join(one);
            }
        }
    }
    key.to_string()
}

/// What an untagged value (one of several shapes) accepts, by key.
fn untagged_expectation(key: &str) -> Option<&'static str> {
    let last = key.rsplit('.').next().unwrap_or("");
    match last {
        "beta" => Some("\"energy\", \"trapezoid\" or a number in [0, 1]"),
        "velocity" if key.contains(".constraints.") => {
            Some("an array of numbers [m/s] or a table of some components, e.g. { y = 0.0 }")
        }
        "initial_angular_velocity" => Some("a number [rad/s] in 2D, [wx, wy, wz] [rad/s] in 3D"),
        _ => None,
    }
}

/// Turns serde's "invalid type: string \"a\", expected f64" into (found, expected).
fn split_serde_message(msg: &str) -> (String, String) {
    if let Some(i) = msg.find(", expected ") {
        let found = msg[..i]
            .trim_start_matches("invalid type: ")
            .trim_start_matches("invalid value: ");
        let expected = match &msg[i + ", expected ".len()..] {
            "f64" => "a number",
            "i64" => "an integer",
            "a boolean" | "bool" => "true or false",
            other => other,
        };
        return (found.to_string(), expected.to_string());
    }
    if let Some(rest) = msg.strip_prefix("missing field ") {
        return ("nothing".into(), format!("the required key {rest}"));
    }
    (
        msg.to_string(),
        "a value of the documented type (see scene-format.md)".into(),
    )
}

fn apply_override(
    table: &mut toml::Table,
    assignment: &str,
) -> std::result::Result<String, String> {
    let (key, value) = assignment
        .split_once('=')
        .ok_or_else(|| "expected KEY=VALUE, e.g. simulation.time_step=2e-4".to_string())?;
    let key = key.trim();
    let literal: toml::Table = toml::from_str(&format!("v = {}", value.trim()))
        .map_err(|e| format!("the value is not a TOML literal ({})", e.message()))?;
    let value = literal.get("v").cloned().ok_or("empty value")?;
    let parts: Vec<&str> = key.split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(format!("`{key}` is not a dotted key path"));
    }
    let mut current = table;
    let mut path = Vec::new();
    let mut i = 0;
    while i + 1 < parts.len() {
        let part = parts[i];
        path.push(part.to_string());
        let entry = current
            .entry(part.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        current = match entry {
            toml::Value::Table(t) => t,
            toml::Value::Array(items) => {
                i += 1;
                let selector = parts[i];
                let index = match selector.parse::<usize>() {
                    Ok(n) => n,
                    Err(_) => items
                        .iter()
                        .position(|it| it.get("name").and_then(|n| n.as_str()) == Some(selector))
                        .ok_or_else(|| format!("no item of `{part}` is named `{selector}`"))?,
                };
                path.push(index.to_string());
                let len = items.len();
                match items.get_mut(index) {
                    Some(toml::Value::Table(t)) => t,
                    _ => {
                        return Err(format!(
                            "`{part}` has {len} items; index {index} is out of range"
                        ))
                    }
                }
            }
            _ => return Err(format!("`{}` is not a table", path.join("."))),
        };
        i += 1;
    }
    if i >= parts.len() {
        return Err(format!("`{key}` names a list item, not a key"));
    }
    path.push(parts[i].to_string());
    current.insert(parts[i].to_string(), value);
    Ok(path.join("."))
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
        match line_of(&self.text, key) {
            Some(line) => format!("line {line}: "),
            None => String::new(),
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
            found: found.to_string(),
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
}

/// The 1-based line where a dotted key (or its deepest existing parent) is defined.
fn line_of(text: &str, key: &str) -> Option<usize> {
    use toml::de::{DeTable, DeValue};
    let doc = DeTable::parse(text).ok()?;
    let mut span = None;
    let mut table: Option<&DeTable> = Some(doc.get_ref());
    let mut array: Option<&[toml::Spanned<DeValue>]> = None;
    for part in key.split('.') {
        // A part that is not in the file (a missing key): stop at its deepest existing parent.
        let value = if let Some(items) = array.take() {
            match part.parse::<usize>().ok().and_then(|i| items.get(i)) {
                Some(v) => v,
                None => break,
            }
        } else {
            let Some(t) = table.take() else { break };
            let Some((k, v)) = t.iter().find(|(k, _)| k.get_ref().as_ref() == part) else {
                break;
            };
            span = Some(k.span());
            v
        };
        if span.is_none() || matches!(value.get_ref(), DeValue::Table(_)) {
            span = Some(value.span());
        }
        match value.get_ref() {
            DeValue::Table(t) => table = Some(t),
            DeValue::Array(a) => array = Some(a.as_ref()),
            _ => {}
        }
    }
    let start = span?.start;
    Some(text[..start.min(text.len())].matches('\n').count() + 1)
}

// ---------------------------------------------------------------------------------------------
// Validation into typed values.

/// Output options.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutputOptions {
    /// [s]; 0 = every step.
    pub history_interval: f64,
    /// [s]; 0 = none.
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
    /// End time [s].
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
        crate::simulation::Simulation::with_contact(
            self.settings.clone(),
            self.bodies.clone(),
            self.obstacles.clone(),
            self.contact.clone(),
        )
    }
}

impl LoadedScene {
    /// The dimension the scene declares (2 or 3).
    pub fn dimension(&self) -> Result<usize> {
        match self.file.simulation.dimension {
            2 => Ok(2),
            3 => Ok(3),
            d => Err(self.error("simulation.dimension", d, "2 or 3")),
        }
    }

    fn vector<const D: usize>(&self, key: &str, v: &[f64]) -> Result<SVector<f64, D>> {
        if v.len() != D {
            return Err(self.error(
                key,
                format!("{} components", v.len()),
                format!("{D} components (dimension = {D})"),
            ));
        }
        if v.iter().any(|x| !x.is_finite()) {
            return Err(self.error(key, format!("{v:?}"), "finite numbers"));
        }
        Ok(SVector::from_column_slice(v))
    }

    /// `{key}.name` must differ from the `earlier` names of its list and be a valid name.
    fn unique_name<'a>(
        &self,
        key: &str,
        mut earlier: impl Iterator<Item = &'a str>,
        name: &str,
        what: &str,
    ) -> Result<()> {
        let key = format!("{key}.name");
        if earlier.any(|e| e == name) {
            return Err(self.error(
                &key,
                format!("\"{name}\" again"),
                format!("a unique {what} name"),
            ));
        }
        self.name(&key, name)
    }

    /// Names become history.csv columns (`probe.<name>.ux`), VTK file names
    /// (`vtk/<body>_<step>.vtu`) and `--set obstacles.NAME.` paths: no commas, quotes, dots,
    /// slashes or spaces.
    fn name(&self, key: &str, name: &str) -> Result<()> {
        let ok = |c: char| c.is_alphanumeric() || c == '_' || c == '-';
        if name.is_empty() || !name.chars().all(ok) {
            return Err(self.error(
                key,
                format!("{name:?}"),
                "a non-empty name of letters, digits, '_' and '-'",
            ));
        }
        Ok(())
    }

    fn positive(&self, key: &str, v: f64, unit: &str) -> Result<f64> {
        if v > 0.0 && v.is_finite() {
            Ok(v)
        } else {
            Err(self.error(key, v, format!("a finite value > 0 [{unit}]")))
        }
    }

    /// Validates the whole scene for dimension D, reading mesh files.
    pub fn build<const D: usize>(&self) -> Result<Scene<D>>
    where
        Dim<D>: SpatialDim<D>,
    {
        let s = &self.file.simulation;
        let kinematics = match (D, s.kinematics.as_deref()) {
            (3, None) | (3, Some("solid")) => Kinematics::Solid,
            (3, Some(k)) => {
                return Err(self.error(
                    "simulation.kinematics",
                    format!("\"{k}\""),
                    "no kinematics key in 3D (or \"solid\")",
                ))
            }
            (_, None) | (_, Some("plane_strain")) => Kinematics::PlaneStrain,
            (_, Some("plane_stress")) => Kinematics::PlaneStress,
            (_, Some("axisymmetric")) => Kinematics::Axisymmetric,
            (_, Some(k)) => {
                return Err(self.error(
                    "simulation.kinematics",
                    format!("\"{k}\""),
                    "\"plane_strain\", \"plane_stress\" or \"axisymmetric\"",
                ))
            }
        };
        let time_step = self.positive("simulation.time_step", s.time_step, "s")?;
        if !(s.end_time >= 0.0 && s.end_time.is_finite()) {
            return Err(self.error("simulation.end_time", s.end_time, "a finite value >= 0 [s]"));
        }
        if !(0.0..=1.0).contains(&s.alpha) {
            return Err(self.error("simulation.alpha", s.alpha, "a number in [0, 1]"));
        }
        let beta = match &s.beta {
            BetaSpec::Name(n) if n == "energy" => Beta::Energy,
            BetaSpec::Name(n) if n == "trapezoid" => Beta::Trapezoid,
            BetaSpec::Value(b) if (0.0..=1.0).contains(b) => Beta::Value(*b),
            BetaSpec::Value(b) => {
                return Err(self.error(
                    "simulation.beta",
                    b,
                    "\"energy\", \"trapezoid\" or a number in [0, 1]",
                ))
            }
            BetaSpec::Name(n) => {
                return Err(self.error(
                    "simulation.beta",
                    format!("\"{n}\""),
                    "\"energy\", \"trapezoid\" or a number in [0, 1]",
                ))
            }
        };
        let scheme = SpaceTimeScheme::new(s.alpha, beta)?;
        let gravity = match &s.gravity {
            Some(g) => self.vector::<D>("simulation.gravity", g)?,
            None => SVector::zeros(),
        };
        if s.max_iterations < 1 {
            return Err(self.error(
                "simulation.max_iterations",
                s.max_iterations,
                "an integer >= 1",
            ));
        }
        if !(s.tolerance > 0.0 && s.tolerance < 1.0) {
            return Err(self.error("simulation.tolerance", s.tolerance, "a number in (0, 1)"));
        }
        let mass = match s.mass.as_deref() {
            None | Some("consistent") => MassKind::Consistent,
            Some("lumped") => MassKind::Lumped,
            Some(m) => {
                return Err(self.error(
                    "simulation.mass",
                    format!("\"{m}\""),
                    "\"consistent\" or \"lumped\"",
                ))
            }
        };
        let ordering = match s.ordering.as_deref() {
            None | Some("nested_dissection") => FillOrdering::NestedDissection,
            Some("minimum_degree") => FillOrdering::MinimumDegree,
            Some(o) => {
                return Err(self.error(
                    "simulation.ordering",
                    format!("\"{o}\""),
                    "\"nested_dissection\" or \"minimum_degree\"",
                ))
            }
        };
        let settings = Settings {
            time_step,
            scheme,
            gravity,
            kinematics,
            max_iterations: s.max_iterations as usize,
            tolerance: s.tolerance,
            mass,
            ordering,
        };

        let contact = self.check_contact()?;

        if self.file.bodies.is_empty() {
            return Err(self.error("bodies", "no [[bodies]]", "at least one body"));
        }
        let mut bodies = Vec::new();
        for (b, spec) in self.file.bodies.iter().enumerate() {
            let key = format!("bodies.{b}");
            let earlier = self.file.bodies[..b].iter().map(|x| x.name.as_str());
            self.unique_name(&key, earlier, &spec.name, "body")?;
            let (mesh, groups) = self.mesh::<D>(&format!("{key}.mesh"), &spec.mesh, &spec.name)?;
            let material = self.material(&format!("{key}.material"), &spec.material)?;
            let mut body = Body::new(spec.name.clone(), mesh, material);
            if let Some(v) = &spec.initial_velocity {
                body.initial_velocity = self.vector::<D>(&format!("{key}.initial_velocity"), v)?;
            }
            if let Some(w) = &spec.initial_angular_velocity {
                let k = format!("{key}.initial_angular_velocity");
                body.initial_angular_velocity = match (w, <Dim<D>>::ANGULAR) {
                    (AngularSpec::Scalar(x), 1) => vec![*x],
                    (AngularSpec::Vector(v), 3) if v.len() == 3 => v.clone(),
                    _ => {
                        return Err(self.error(
                            &k,
                            format!("{w:?}"),
                            if D == 2 {
                                "a number [rad/s] in 2D"
                            } else {
                                "a vector [wx, wy, wz] [rad/s] in 3D"
                            },
                        ))
                    }
                };
                if body.initial_angular_velocity.iter().any(|x| !x.is_finite()) {
                    return Err(self.error(&k, format!("{w:?}"), "finite numbers"));
                }
            }
            for (c, cs) in spec.constraints.iter().enumerate() {
                let ck = format!("{key}.constraints.{c}");
                body.constraints
                    .push(self.constraint::<D>(&ck, cs, &body.mesh, &groups, &spec.name)?);
            }
            if kinematics == Kinematics::Axisymmetric {
                if let Some(n) = body.mesh.nodes.iter().position(|x| x[0] < 0.0) {
                    return Err(self.error(
                        &format!("{key}.mesh"),
                        format!("node {n} at r = x = {}", body.mesh.nodes[n][0]),
                        "r = x >= 0 for every node in axisymmetric kinematics",
                    ));
                }
            }
            if let Err(e) = body.mesh.check_quality(&spec.name) {
                return Err(match e {
                    Error::InvertedElement { cell, kind, jacobian, .. } => self.error(
                        &format!("{key}.mesh"),
                        format!("cell {cell} {kind} (Jacobian determinant {jacobian:.3e})"),
                        "cells with a positive Jacobian everywhere (check node ordering and geometry)",
                    ),
                    other => other,
                });
            }
            bodies.push(body);
        }

        let mut obstacles = Vec::new();
        for (o, spec) in self.file.obstacles.iter().enumerate() {
            let key = format!("obstacles.{o}");
            let earlier = self.file.obstacles[..o].iter().map(|x| x.name.as_str());
            self.unique_name(&key, earlier, &spec.name, "obstacle")?;
            let shape = self.shape::<D>(&format!("{key}.shape"), &spec.shape)?;
            let mut obstacle = Obstacle::new(spec.name.clone(), shape);
            if let Some(v) = &spec.velocity {
                obstacle.velocity = self.vector::<D>(&format!("{key}.velocity"), v)?;
            }
            if let Some(f) = &spec.friction {
                obstacle.friction = Some(self.friction(&format!("{key}.friction"), f)?);
            }
            obstacles.push(obstacle);
        }

        let mut probes = Vec::new();
        for (p, spec) in self.file.probes.iter().enumerate() {
            let key = format!("probes.{p}");
            let earlier = self.file.probes[..p].iter().map(|x| x.name.as_str());
            self.unique_name(&key, earlier, &spec.name, "probe")?;
            let body = bodies
                .iter()
                .position(|b| b.name == spec.body)
                .ok_or_else(|| {
                    let names: Vec<&str> = bodies.iter().map(|b| b.name.as_str()).collect();
                    self.error(
                        &format!("{key}.body"),
                        format!("\"{}\"", spec.body),
                        format!("the name of a body: {names:?}"),
                    )
                })?;
            let point = self.vector::<D>(&format!("{key}.point"), &spec.point)?;
            let node = bodies[body].mesh.nearest_node(&point);
            probes.push(Probe {
                name: spec.name.clone(),
                body,
                node,
            });
        }

        let out = &self.file.output;
        if !(out.history_interval >= 0.0 && out.history_interval.is_finite()) {
            return Err(self.error(
                "output.history_interval",
                out.history_interval,
                "a finite value >= 0 [s]",
            ));
        }
        if !(out.vtk_interval >= 0.0 && out.vtk_interval.is_finite()) {
            return Err(self.error(
                "output.vtk_interval",
                out.vtk_interval,
                "a finite value >= 0 [s]",
            ));
        }
        Ok(Scene {
            settings,
            end_time: s.end_time,
            bodies,
            obstacles,
            probes,
            output: OutputOptions {
                history_interval: out.history_interval,
                vtk_interval: out.vtk_interval,
            },
            contact,
        })
    }

    fn check_contact(&self) -> Result<ContactSettings> {
        let c = &self.file.contact;
        const METHODS: [&str; 4] = [
            "soft_way",
            "implicit_projection",
            "augmented_lagrangian",
            "explicit_projection",
        ];
        if !METHODS.contains(&c.method.as_str()) {
            return Err(self.error(
                "contact.method",
                format!("\"{}\"", c.method),
                format!("one of {METHODS:?}"),
            ));
        }
        if let Some(p) = c.penalty {
            self.positive("contact.penalty", p, "Pa/m")?;
        } else if matches!(c.method.as_str(), "soft_way" | "augmented_lagrangian") {
            return Err(self.error(
                "contact.penalty",
                "nothing",
                format!("a penalty zeta > 0 [Pa/m] for method \"{}\"", c.method),
            ));
        }
        self.positive("contact.gap_tolerance", c.gap_tolerance, "m")?;
        let method = match c.method.as_str() {
            "soft_way" => ContactMethod::SoftWay,
            "augmented_lagrangian" => ContactMethod::AugmentedLagrangian,
            "explicit_projection" => ContactMethod::ExplicitProjection,
            _ => ContactMethod::ImplicitProjection,
        };
        let friction = self.friction("contact.friction", &c.friction)?;
        let any_friction = friction != FrictionLaw::Frictionless
            || self.file.obstacles.iter().any(|o| {
                o.friction
                    .as_ref()
                    .is_some_and(|f| *f != FrictionSpec::Frictionless)
            });
        if method == ContactMethod::ExplicitProjection && any_friction {
            return Err(self.error(
                "contact.method",
                "\"explicit_projection\" with a friction law",
                "a method with a normal force inside the step to carry friction (soft_way, \
                 implicit_projection or augmented_lagrangian), or law = \"frictionless\"",
            ));
        }
        Ok(ContactSettings {
            method,
            penalty: c.penalty.unwrap_or(0.0),
            self_contact: c.self_contact,
            gap_tolerance: c.gap_tolerance,
            friction,
            ..ContactSettings::default()
        })
    }

    fn friction(&self, key: &str, f: &FrictionSpec) -> Result<FrictionLaw> {
        let non_negative = |k: &str, v: f64| {
            if v >= 0.0 && v.is_finite() {
                Ok(())
            } else {
                Err(self.error(&format!("{key}.{k}"), v, "a finite value >= 0"))
            }
        };
        let regularization = |r: &Option<f64>| -> Result<f64> {
            match r {
                Some(r) => self.positive(&format!("{key}.regularization"), *r, "m/s"),
                None => Ok(DEFAULT_REGULARIZATION),
            }
        };
        Ok(match f {
            FrictionSpec::Frictionless => FrictionLaw::Frictionless,
            FrictionSpec::Coulomb {
                coefficient,
                regularization: r,
            } => {
                non_negative("coefficient", *coefficient)?;
                FrictionLaw::Coulomb {
                    coefficient: *coefficient,
                    regularization: regularization(r)?,
                }
            }
            FrictionSpec::Tresca { limit } => {
                non_negative("limit", *limit)?;
                FrictionLaw::Tresca {
                    limit: *limit,
                    regularization: DEFAULT_REGULARIZATION,
                }
            }
            FrictionSpec::Viscoplastic {
                coefficient,
                exponent,
                regularization: r,
            } => {
                non_negative("coefficient", *coefficient)?;
                non_negative("exponent", *exponent)?;
                FrictionLaw::Viscoplastic {
                    coefficient: *coefficient,
                    exponent: *exponent,
                    regularization: regularization(r)?,
                }
            }
        })
    }

    fn material(&self, key: &str, m: &MaterialSpec) -> Result<Material> {
        match m {
            MaterialSpec::LinearElastic { youngs_modulus, poissons_ratio, density } => {
                self.positive(&format!("{key}.youngs_modulus"), *youngs_modulus, "Pa")?;
                if !(*poissons_ratio > -1.0 && *poissons_ratio < 0.5) {
                    return Err(self.error(&format!("{key}.poissons_ratio"), poissons_ratio, "a value in (-1, 0.5)"));
                }
                if !(*density >= 0.0 && density.is_finite()) {
                    return Err(self.error(&format!("{key}.density"), density, "a finite value >= 0 [kg/m^3]"));
                }
                Ok(Material::LinearElastic(LinearElastic::new(*youngs_modulus, *poissons_ratio, *density)?))
            }
            MaterialSpec::Hypoelastic { .. } | MaterialSpec::NortonHoff { .. } => Err(Error::NotAvailable {
                feature: format!("{}: the {} material", self.path.display(), if matches!(m, MaterialSpec::Hypoelastic { .. }) { "hypoelastic" } else { "norton_hoff" }),
                detail: format!("`{key}.model` is accepted by the parser, but only \"linear_elastic\" runs in this version"),
            }),
        }
    }

    fn cells<const N: usize>(&self, key: &str, cells: &Option<Vec<i64>>) -> Result<[usize; N]> {
        let c = cells
            .as_ref()
            .ok_or_else(|| self.error(key, "nothing", format!("{N} positive integers")))?;
        if c.len() != N || c.iter().any(|&n| n < 1) {
            return Err(self.error(key, format!("{c:?}"), format!("{N} positive integers")));
        }
        // The generators multiply these; a huge request must be an input error, not an
        // arithmetic overflow (a panic) or an allocation failure.
        const MAX_CELLS: i64 = 100_000_000;
        let total = c.iter().try_fold(1i64, |acc, &n| acc.checked_mul(n));
        if total.is_none_or(|t| t > MAX_CELLS) {
            return Err(self.error(
                key,
                format!("{c:?}"),
                format!("at most {MAX_CELLS} cells in all"),
            ));
        }
        let mut out = [0usize; N];
        for (o, &n) in out.iter_mut().zip(c) {
            *o = n as usize;
        }
        Ok(out)
    }

    fn element(&self, key: &str, e: &Option<String>, default: ElementKind) -> Result<ElementKind> {
        let kind = match e.as_deref() {
            None => default,
            Some("tri3") => ElementKind::Tri3,
            Some("quad4") => ElementKind::Quad4,
            Some("tet4") => ElementKind::Tet4,
            Some("hex8") => ElementKind::Hex8,
            Some(other) => {
                return Err(self.error(
                    key,
                    format!("\"{other}\""),
                    "\"tri3\", \"quad4\", \"tet4\" or \"hex8\"",
                ))
            }
        };
        if kind.dimension() != default.dimension() {
            return Err(self.error(
                key,
                format!("\"{}\"", kind.name()),
                if default.dimension() == 2 {
                    "\"tri3\" or \"quad4\" in 2D"
                } else {
                    "\"tet4\" or \"hex8\" in 3D"
                },
            ));
        }
        Ok(kind)
    }

    /// Builds a body's mesh; returns it with the named node sets of a mesh file.
    fn mesh<const D: usize>(
        &self,
        key: &str,
        spec: &MeshSpec,
        body: &str,
    ) -> Result<(Mesh<D>, BTreeMap<String, Vec<usize>>)>
    where
        Dim<D>: SpatialDim<D>,
    {
        let default_kind = if D == 2 {
            ElementKind::Quad4
        } else {
            ElementKind::Hex8
        };
        let wrap = |e: Error| match e {
            Error::InvalidParameter {
                name,
                found,
                expected,
            } => self.error(&format!("{key}.{name}"), found, expected),
            other => other,
        };
        let present = [
            ("min", spec.min.is_some()),
            ("max", spec.max.is_some()),
            ("cells", spec.cells.is_some()),
            ("element", spec.element.is_some()),
            ("center", spec.center.is_some()),
            ("inner_radius", spec.inner_radius.is_some()),
            ("outer_radius", spec.outer_radius.is_some()),
            ("vertices", spec.vertices.is_some()),
            ("length", spec.length.is_some()),
        ];
        match (&spec.generator, &spec.file) {
            (Some(_), Some(_)) => {
                Err(self.error(key, "both `generator` and `file`", "one of them"))
            }
            (None, None) => Err(self.error(
                key,
                "neither `generator` nor `file`",
                "a generator (rectangle, box, annulus, polygon) or a Gmsh file",
            )),
            (None, Some(file)) => {
                // A mesh file brings its own cells: generator keys would be silently ignored.
                if let Some((name, _)) = present.iter().find(|(_, is)| *is) {
                    return Err(self.error(
                        &format!("{key}.{name}"),
                        format!("`{name}` with a mesh file"),
                        "only `file` (the generator keys do not apply to a Gmsh file)",
                    ));
                }
                let path = self.base_dir().join(file);
                let mesh = crate::mesh::from_gmsh_file::<D>(&path).map_err(|e| match e {
                    Error::MeshFile { file, message } => self.error(
                        &format!("{key}.file"),
                        format!("{} ({message})", file.display()),
                        "a readable Gmsh MSH 2.2 or 4.1 file",
                    ),
                    other => other,
                })?;
                let groups = mesh.node_sets.clone().into_iter().collect();
                mesh.validate_topology(body).map_err(|e| match e {
                    Error::Mesh { message, .. } => self.error(
                        &format!("{key}.file"),
                        format!("{} ({message})", path.display()),
                        "a mesh whose cells use every node, with finite coordinates",
                    ),
                    other => other,
                })?;
                Ok((mesh, groups))
            }
            (Some(g), None) => {
                let allowed: &[&str] = match g.as_str() {
                    "rectangle" | "box" => &["min", "max", "cells", "element"],
                    "annulus" => &[
                        "center",
                        "inner_radius",
                        "outer_radius",
                        "cells",
                        "element",
                        "length",
                    ],
                    "polygon" => &["vertices", "cells", "element", "length"],
                    other => {
                        return Err(self.error(
                            &format!("{key}.generator"),
                            format!("\"{other}\""),
                            "\"rectangle\", \"box\", \"annulus\" or \"polygon\"",
                        ))
                    }
                };
                for (name, is) in present {
                    if is && !allowed.contains(&name) {
                        return Err(self.error(
                            &format!("{key}.{name}"),
                            format!("`{name}` with generator \"{g}\""),
                            format!("only {allowed:?}"),
                        ));
                    }
                }
                let need = |name: &str, v: &Option<Vec<f64>>| -> Result<Vec<f64>> {
                    v.clone().ok_or_else(|| {
                        self.error(
                            &format!("{key}.{name}"),
                            "nothing",
                            format!("`{name}` for generator \"{g}\""),
                        )
                    })
                };
                let kind = self.element(&format!("{key}.element"), &spec.element, default_kind)?;
                let mesh3 = |m: Mesh<3>| -> Mesh<D> { convert_mesh::<3, D>(m) };
                let mesh2 = |m: Mesh<2>| -> Mesh<D> { convert_mesh::<2, D>(m) };
                let mesh: Mesh<D> = match (g.as_str(), D) {
                    ("rectangle", 2) => {
                        let min =
                            self.vector::<2>(&format!("{key}.min"), &need("min", &spec.min)?)?;
                        let max =
                            self.vector::<2>(&format!("{key}.max"), &need("max", &spec.max)?)?;
                        let cells = self.cells::<2>(&format!("{key}.cells"), &spec.cells)?;
                        mesh2(generators::rectangle(min, max, cells, kind).map_err(wrap)?)
                    }
                    ("box", 3) => {
                        let min =
                            self.vector::<3>(&format!("{key}.min"), &need("min", &spec.min)?)?;
                        let max =
                            self.vector::<3>(&format!("{key}.max"), &need("max", &spec.max)?)?;
                        let cells = self.cells::<3>(&format!("{key}.cells"), &spec.cells)?;
                        mesh3(generators::cuboid(min, max, cells, kind).map_err(wrap)?)
                    }
                    ("rectangle", _) | ("box", _) => {
                        return Err(self.error(
                            &format!("{key}.generator"),
                            format!("\"{g}\" in {D}D"),
                            if D == 2 {
                                "\"rectangle\" in 2D (\"box\" is 3D)"
                            } else {
                                "\"box\" in 3D (\"rectangle\" is 2D)"
                            },
                        ))
                    }
                    ("annulus", _) | ("polygon", _) => {
                        let base_kind = if D == 3 { ElementKind::Quad4 } else { kind };
                        let base = if g == "annulus" {
                            let c = need("center", &spec.center)?;
                            let center = self.vector::<D>(&format!("{key}.center"), &c)?;
                            let ri = spec.inner_radius.ok_or_else(|| {
                                self.error(
                                    &format!("{key}.inner_radius"),
                                    "nothing",
                                    "a radius > 0 [m]",
                                )
                            })?;
                            let ro = spec.outer_radius.ok_or_else(|| {
                                self.error(
                                    &format!("{key}.outer_radius"),
                                    "nothing",
                                    "a radius > inner_radius [m]",
                                )
                            })?;
                            let cells = if D == 2 {
                                self.cells::<2>(&format!("{key}.cells"), &spec.cells)?
                            } else {
                                let c3 = self.cells::<3>(&format!("{key}.cells"), &spec.cells)?;
                                [c3[0], c3[1]]
                            };
                            generators::annulus(
                                nalgebra::Vector2::new(center[0], center[1]),
                                ri,
                                ro,
                                cells,
                                base_kind,
                            )
                            .map_err(wrap)?
                        } else {
                            let verts = spec.vertices.as_ref().ok_or_else(|| {
                                self.error(
                                    &format!("{key}.vertices"),
                                    "nothing",
                                    "a list of [x, y] vertices",
                                )
                            })?;
                            let mut v2 = Vec::new();
                            for (i, v) in verts.iter().enumerate() {
                                v2.push(self.vector::<2>(&format!("{key}.vertices.{i}"), v)?);
                            }
                            let cells = if D == 2 {
                                self.cells::<2>(&format!("{key}.cells"), &spec.cells)?
                            } else {
                                let c3 = self.cells::<3>(&format!("{key}.cells"), &spec.cells)?;
                                [c3[0], c3[1]]
                            };
                            generators::polygon(&v2, cells, base_kind).map_err(wrap)?
                        };
                        if D == 2 {
                            if spec.length.is_some() {
                                return Err(self.error(
                                    &format!("{key}.length"),
                                    "a length in 2D",
                                    "no `length` in 2D (it is the 3D extrusion)",
                                ));
                            }
                            mesh2(base)
                        } else {
                            let length = spec.length.ok_or_else(|| {
                                self.error(
                                    &format!("{key}.length"),
                                    "nothing",
                                    "the extrusion length along z [m] in 3D",
                                )
                            })?;
                            self.positive(&format!("{key}.length"), length, "m")?;
                            let layers = self.cells::<3>(&format!("{key}.cells"), &spec.cells)?[2];
                            let z0 = if g == "annulus" {
                                self.vector::<D>(
                                    &format!("{key}.center"),
                                    spec.center.as_deref().unwrap_or(&[]),
                                )?[D - 1]
                                    - length / 2.0
                            } else {
                                0.0
                            };
                            mesh3(
                                generators::extrude(&base, z0, z0 + length, layers, kind)
                                    .map_err(wrap)?,
                            )
                        }
                    }
                    _ => unreachable!("generator names are checked above"),
                };
                Ok((mesh, BTreeMap::new()))
            }
        }
    }

    fn constraint<const D: usize>(
        &self,
        key: &str,
        c: &ConstraintSection,
        mesh: &Mesh<D>,
        groups: &BTreeMap<String, Vec<usize>>,
        body: &str,
    ) -> Result<Constraint>
    where
        Dim<D>: SpatialDim<D>,
    {
        let nodes = match (&c.region.group, &c.region.min, &c.region.max) {
            (Some(g), None, None) => groups.get(g).cloned().ok_or_else(|| {
                let names: Vec<&String> = groups.keys().collect();
                self.error(
                    &format!("{key}.region.group"),
                    format!("\"{g}\""),
                    format!("a physical group of the mesh file: {names:?}"),
                )
            })?,
            (None, Some(min), Some(max)) => {
                let min = self.vector::<D>(&format!("{key}.region.min"), min)?;
                let max = self.vector::<D>(&format!("{key}.region.max"), max)?;
                mesh.nodes_in_box(&min, &max)
            }
            _ => {
                return Err(self.error(
                    &format!("{key}.region"),
                    "an incomplete region",
                    "{ min = [..], max = [..] } or { group = \"name\" }",
                ))
            }
        };
        if nodes.is_empty() {
            let (lo, hi) = mesh.bounding_box();
            return Err(self.error(
                &format!("{key}.region"),
                format!("a region that selects no node of body `{body}`"),
                format!(
                    "a region that contains nodes (the mesh spans {:?} to {:?})",
                    lo.as_slice(),
                    hi.as_slice()
                ),
            ));
        }
        let velocity = match &c.velocity {
            ComponentsSpec::Array(v) => self
                .vector::<D>(&format!("{key}.velocity"), v)?
                .iter()
                .map(|x| Some(*x))
                .collect(),
            ComponentsSpec::Named(n) => {
                if D == 2 && n.z.is_some() {
                    return Err(self.error(
                        &format!("{key}.velocity.z"),
                        "a z component in 2D",
                        "x and y only",
                    ));
                }
                let v: Vec<Option<f64>> = [n.x, n.y, n.z][..D].to_vec();
                if v.iter().all(Option::is_none) {
                    return Err(self.error(
                        &format!("{key}.velocity"),
                        "no component",
                        "at least one of x, y, z",
                    ));
                }
                if v.iter().flatten().any(|x| !x.is_finite()) {
                    return Err(self.error(
                        &format!("{key}.velocity"),
                        "a non-finite component",
                        "finite numbers [m/s]",
                    ));
                }
                v
            }
        };
        Ok(Constraint { nodes, velocity })
    }

    fn shape<const D: usize>(&self, key: &str, s: &ShapeSpec) -> Result<ObstacleShape<D>>
    where
        Dim<D>: SpatialDim<D>,
    {
        Ok(match s {
            ShapeSpec::Halfspace { point, normal } => {
                let n = self.vector::<D>(&format!("{key}.normal"), normal)?;
                if n.norm() == 0.0 {
                    return Err(self.error(
                        &format!("{key}.normal"),
                        "a zero vector",
                        "a non-zero normal",
                    ));
                }
                ObstacleShape::Halfspace {
                    point: self.vector::<D>(&format!("{key}.point"), point)?,
                    normal: n.normalize(),
                }
            }
            ShapeSpec::Box {
                center,
                half_extents,
            } => {
                let h = self.vector::<D>(&format!("{key}.half_extents"), half_extents)?;
                if h.iter().any(|x| *x <= 0.0) {
                    return Err(self.error(
                        &format!("{key}.half_extents"),
                        format!("{:?}", h.as_slice()),
                        "positive half extents [m]",
                    ));
                }
                ObstacleShape::Box {
                    center: self.vector::<D>(&format!("{key}.center"), center)?,
                    half_extents: h,
                }
            }
            ShapeSpec::Ball { center, radius } => ObstacleShape::Ball {
                center: self.vector::<D>(&format!("{key}.center"), center)?,
                radius: self.positive(&format!("{key}.radius"), *radius, "m")?,
            },
            ShapeSpec::Polyline {
                vertices,
                indices,
                file,
            }
            | ShapeSpec::Trimesh {
                vertices,
                indices,
                file,
            } => {
                let is_polyline = matches!(s, ShapeSpec::Polyline { .. });
                if is_polyline != (D == 2) {
                    return Err(self.error(
                        &format!("{key}.type"),
                        if is_polyline {
                            "\"polyline\" in 3D"
                        } else {
                            "\"trimesh\" in 2D"
                        },
                        if D == 2 {
                            "\"polyline\" in 2D"
                        } else {
                            "\"trimesh\" in 3D"
                        },
                    ));
                }
                if file.is_some() {
                    return Err(Error::NotAvailable {
                        feature: format!("{}: `{key}.file`", self.path.display()),
                        detail: "give the obstacle's `vertices` and `indices` inline".into(),
                    });
                }
                let verts = vertices.as_ref().ok_or_else(|| {
                    self.error(&format!("{key}.vertices"), "nothing", "a list of vertices")
                })?;
                let idx = indices.as_ref().ok_or_else(|| {
                    self.error(
                        &format!("{key}.indices"),
                        "nothing",
                        format!("a list of facets of {D} vertex indices"),
                    )
                })?;
                let mut vs = Vec::new();
                for (i, v) in verts.iter().enumerate() {
                    vs.push(self.vector::<D>(&format!("{key}.vertices.{i}"), v)?);
                }
                let mut facets = Vec::new();
                for (i, f) in idx.iter().enumerate() {
                    if f.len() != D || f.iter().any(|&k| k < 0 || k as usize >= vs.len()) {
                        return Err(self.error(
                            &format!("{key}.indices.{i}"),
                            format!("{f:?}"),
                            format!("{D} indices below {}", vs.len()),
                        ));
                    }
                    facets.push(f.iter().map(|&k| k as usize).collect());
                }
                ObstacleShape::Facets {
                    vertices: vs,
                    indices: facets,
                }
            }
        })
    }
}

/// Re-types a mesh whose dimension is known to equal D at run time.
fn convert_mesh<const A: usize, const D: usize>(m: Mesh<A>) -> Mesh<D> {
    assert_eq!(A, D, "dimension checked by the caller");
    Mesh {
        nodes: m
            .nodes
            .iter()
            .map(|x| SVector::<f64, D>::from_column_slice(x.as_slice()))
            .collect(),
        blocks: m.blocks,
        node_sets: m.node_sets,
    }
}
