//! The raw schema of a scene file, as written (`scene-format.md`): serde types with the
//! documented defaults; unknown keys are refused. Validation and units come later (`build`).

use serde::Deserialize;

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
// Not `Beta`: a bare number or name here, an externally tagged enum there.
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
// Names stay strings (not `Kinematics`, `MassKind`, ...) so messages list the accepted spellings.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulationSection {
    /// 2 or 3.
    pub dimension: i64,
    /// 2D only.
    #[serde(default)]
    pub kinematics: Option<String>,
    /// h (s).
    pub time_step: f64,
    /// (s).
    pub end_time: f64,
    /// Dirac point.
    #[serde(default = "default_alpha")]
    pub alpha: f64,
    /// Position update weight.
    #[serde(default)]
    pub beta: BetaSpec,
    /// (m/s^2).
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
// Not `FrictionLaw`: that requires `regularization` (tresca too); here it is optional or absent.
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
        /// Stick slip-velocity scale (m/s).
        #[serde(default)]
        regularization: Option<f64>,
    },
    /// Constant limit.
    Tresca {
        /// Limit shear stress (Pa).
        limit: f64,
    },
    /// F_t = -a |v_t|^(p-1) v_t.
    Viscoplastic {
        /// a.
        coefficient: f64,
        /// p.
        exponent: f64,
        /// v_reg (m/s).
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
    /// zeta (Pa/m).
    #[serde(default)]
    pub penalty: Option<f64>,
    /// Self-contact on.
    #[serde(default)]
    pub self_contact: bool,
    /// (m).
    #[serde(default = "default_gap_tolerance")]
    pub gap_tolerance: f64,
    /// Default friction law.
    #[serde(default)]
    pub friction: FrictionSpec,
    /// "configuration" | "trapezoid".
    #[serde(default)]
    pub gap_displacement: Option<String>,
    /// Implicit projection's end-of-step projection: "step" | "node".
    #[serde(default)]
    pub projection: Option<String>,
    /// The energy that projection may put in: "booked" | "bounded".
    #[serde(default)]
    pub projection_energy: Option<String>,
    /// The soft way's pressure: "end_of_step" | "secant".
    #[serde(default)]
    pub penalty_force: Option<String>,
    /// The augmented Lagrangian's penalty through Uzawa: "growing" | "fixed".
    #[serde(default)]
    pub uzawa_penalty: Option<String>,
    /// Implicit projection's master side between deformable surfaces: "projected" | "free".
    #[serde(default)]
    pub master_nodes: Option<String>,
    /// The depth (m) from which "projected" moves a master node out.
    #[serde(default = "default_master_tolerance")]
    pub master_tolerance: f64,
    /// On trapezoid gaps, stop closed pairs' approach after each step (default: the
    /// method's; on for the augmented Lagrangian, off for the soft way).
    #[serde(default)]
    pub persistency_stop: Option<bool>,
}

fn default_master_tolerance() -> f64 {
    crate::contact::DEFAULT_MASTER_TOLERANCE
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
            gap_displacement: None,
            projection: None,
            projection_energy: None,
            penalty_force: None,
            uzawa_penalty: None,
            master_nodes: None,
            master_tolerance: default_master_tolerance(),
            persistency_stop: None,
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
    /// annulus (m).
    pub inner_radius: Option<f64>,
    /// annulus (m).
    pub outer_radius: Option<f64>,
    /// polygon (m).
    pub vertices: Option<Vec<Vec<f64>>>,
    /// 3D annulus and polygon: extrusion length along z (m).
    pub length: Option<f64>,
}

/// `material = { model = ..., ... }`.
// Not `Material`: as written (optional keys, strings), validated into `Material` by the builder.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case", deny_unknown_fields)]
pub enum MaterialSpec {
    /// Small-strain isotropic elasticity.
    LinearElastic {
        /// E (Pa).
        youngs_modulus: f64,
        /// nu.
        poissons_ratio: f64,
        /// rho (kg/m^3).
        density: f64,
    },
    /// Corotational hypoelasticity (large rotations).
    Hypoelastic {
        /// E (Pa).
        youngs_modulus: f64,
        /// nu.
        poissons_ratio: f64,
        /// rho (kg/m^3).
        density: f64,
        /// hughes_winget | paper_series.
        #[serde(default)]
        rotation: Option<String>,
    },
    /// Norton-Hoff viscoplasticity.
    NortonHoff {
        /// K (Pa s^m).
        consistency: f64,
        /// m.
        exponent: f64,
        /// rho (kg/m^3).
        density: f64,
        /// Volumetric penalty (Pa s).
        bulk_penalty: f64,
        /// Regularisation of the equivalent strain rate (1/s).
        #[serde(default)]
        rate_regularization: Option<f64>,
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
    /// Box corner (m).
    pub min: Option<Vec<f64>>,
    /// Box corner (m).
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
    /// Prescribed components (m/s).
    pub velocity: ComponentsSpec,
}

/// `initial_angular_velocity`: a number in 2D, a vector in 3D.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum AngularSpec {
    /// 2D (rad/s).
    Scalar(f64),
    /// 3D (rad/s).
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
    /// (m/s).
    #[serde(default)]
    pub initial_velocity: Option<Vec<f64>>,
    /// (rad/s).
    #[serde(default)]
    pub initial_angular_velocity: Option<AngularSpec>,
    /// Prescribed velocities.
    #[serde(default)]
    pub constraints: Vec<ConstraintSection>,
    /// Rayleigh damping.
    #[serde(default)]
    pub damping: Option<DampingSpec>,
    /// Factor on gravity for this body (dimensionless, default 1).
    #[serde(default)]
    pub gravity_scale: Option<f64>,
}

/// `damping = { mass, stiffness }`: Rayleigh damping `C = mass M + stiffness K`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DampingSpec {
    /// (1/s).
    #[serde(default)]
    pub mass: f64,
    /// (s).
    #[serde(default)]
    pub stiffness: f64,
}

/// `shape = { type = ..., ... }`.
// Not `ObstacleShape`: the scene spells polyline/trimesh (and a file) where it has `Facets`.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSpec {
    /// Half-space.
    Halfspace {
        /// (m).
        point: Vec<f64>,
        /// Outward normal.
        normal: Vec<f64>,
    },
    /// Axis-aligned box.
    Box {
        /// (m).
        center: Vec<f64>,
        /// (m).
        half_extents: Vec<f64>,
    },
    /// Ball / disc.
    Ball {
        /// (m).
        center: Vec<f64>,
        /// (m).
        radius: f64,
    },
    /// 2D polyline.
    Polyline {
        /// (m).
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
        /// (m).
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
    /// (m/s).
    #[serde(default)]
    pub velocity: Option<Vec<f64>>,
    /// A piecewise-constant motion instead of `velocity`.
    #[serde(default)]
    pub motion: Option<Vec<MotionSpec>>,
    /// The point rotations turn about (m).
    #[serde(default)]
    pub pivot: Option<Vec<f64>>,
    /// Overrides `[contact].friction`.
    #[serde(default)]
    pub friction: Option<FrictionSpec>,
}

/// One entry of an obstacle's `motion`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionSpec {
    /// End of the piece (s).
    pub until: f64,
    /// (m/s).
    pub velocity: Vec<f64>,
    /// (rad/s) about the pivot.
    #[serde(default)]
    pub angular_velocity: Option<AngularSpec>,
}

/// `[[probes]]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeSection {
    /// Unique name.
    pub name: String,
    /// Body name.
    pub body: String,
    /// (m); the nearest node of the undeformed mesh is recorded.
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
