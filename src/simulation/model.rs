//! The model: what a simulation is made of (settings, bodies, obstacles, contact settings), one
//! serialisable value that does not change while the simulation runs.

use nalgebra::SVector;
use serde::{Deserialize, Serialize};

use crate::contact::{ContactSettings, Obstacle};
use crate::dim::{Dim, Kinematics, SpatialDim};
use crate::material::Material;
use crate::mesh::Mesh;
use crate::solver::FillOrdering;
use crate::time::SpaceTimeScheme;

/// Consistent or row-sum lumped mass matrix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MassKind {
    /// `int rho N_a N_b` (the default).
    #[default]
    Consistent,
    /// Row sums of the consistent matrix on the diagonal.
    Lumped,
}

/// Global parameters of a simulation. Units are SI.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Settings<const D: usize> {
    /// Time step h (s), > 0.
    pub time_step: f64,
    /// alpha and beta of the space-time scheme.
    pub scheme: SpaceTimeScheme,
    /// Gravity acceleration [m/s^2].
    pub gravity: SVector<f64, D>,
    /// 2D: plane strain, plane stress or axisymmetric; 3D: solid.
    pub kinematics: Kinematics,
    /// Largest number of Newton and contact iterations in one step.
    pub max_iterations: usize,
    /// Relative residual tolerance of Newton.
    pub tolerance: f64,
    /// Mass matrix kind.
    pub mass: MassKind,
    /// Fill-reducing ordering of the sparse Cholesky factorisation.
    #[serde(default)]
    pub ordering: FillOrdering,
}

impl<const D: usize> Default for Settings<D>
where
    Dim<D>: SpatialDim<D>,
{
    fn default() -> Self {
        Settings {
            time_step: 1e-3,
            scheme: SpaceTimeScheme::default(),
            gravity: SVector::zeros(),
            kinematics: if <Dim<D>>::supports(Kinematics::Solid) {
                Kinematics::Solid
            } else {
                Kinematics::PlaneStrain
            },
            max_iterations: 50,
            tolerance: 1e-8,
            mass: MassKind::Consistent,
            ordering: FillOrdering::NestedDissection,
        }
    }
}

/// Prescribed velocity components on a set of nodes of one body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Constraint {
    /// Node indices in the body's mesh.
    pub nodes: Vec<usize>,
    /// One entry per component; `None` leaves the component free (m/s).
    pub velocity: Vec<Option<f64>>,
}

/// Rayleigh damping of one body: `C = mass * M + stiffness * K` (K the small-strain stiffness
/// of the body's law at rest). A damped mode of circular frequency omega loses amplitude at the
/// rate `(mass + stiffness * omega^2) / 2`: mass-proportional damping acts on slow modes (and on
/// rigid motion), stiffness-proportional damping on fast ones.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct RayleighDamping {
    /// Mass-proportional coefficient (1/s).
    pub mass: f64,
    /// Stiffness-proportional coefficient (s).
    pub stiffness: f64,
}

impl RayleighDamping {
    /// No damping.
    pub const NONE: RayleighDamping = RayleighDamping {
        mass: 0.0,
        stiffness: 0.0,
    };

    /// The coefficients that give the damping ratio `ratio` at the two circular frequencies
    /// `omega_1` and `omega_2` (rad/s) (the usual way to choose them).
    pub fn from_ratio(ratio: f64, omega_1: f64, omega_2: f64) -> Self {
        let mass = 2.0 * ratio * omega_1 * omega_2 / (omega_1 + omega_2);
        RayleighDamping {
            mass,
            stiffness: 2.0 * ratio / (omega_1 + omega_2),
        }
    }

    /// Whether both coefficients are zero.
    pub fn is_none(&self) -> bool {
        self.mass == 0.0 && self.stiffness == 0.0
    }
}

/// A deformable body: mesh, law, initial motion and constraints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Body<const D: usize> {
    /// Unique name.
    pub name: String,
    /// Mesh in the reference configuration (m).
    pub mesh: Mesh<D>,
    /// Constitutive law.
    pub material: Material,
    /// Initial velocity of every node (m/s).
    pub initial_velocity: SVector<f64, D>,
    /// Initial angular velocity about the centre of mass (rad/s): 1 component in 2D, 3 in 3D.
    pub initial_angular_velocity: Vec<f64>,
    /// Prescribed velocity components.
    pub constraints: Vec<Constraint>,
    /// Rayleigh damping (none by default).
    #[serde(default)]
    pub damping: RayleighDamping,
    /// The factor on gravity for this body (1: the settings' gravity; 0: none).
    #[serde(default = "unit_scale")]
    pub gravity_scale: f64,
}

fn unit_scale() -> f64 {
    1.0
}

impl<const D: usize> Body<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// A body at rest without constraints.
    pub fn new(name: impl Into<String>, mesh: Mesh<D>, material: Material) -> Self {
        Body {
            name: name.into(),
            mesh,
            material,
            initial_velocity: SVector::zeros(),
            initial_angular_velocity: vec![0.0; <Dim<D>>::ANGULAR],
            constraints: Vec::new(),
            damping: RayleighDamping::NONE,
            gravity_scale: 1.0,
        }
    }

    /// Scales gravity on this body (1: the settings' gravity; 0: weightless).
    pub fn with_gravity_scale(mut self, scale: f64) -> Self {
        self.gravity_scale = scale;
        self
    }

    /// Sets Rayleigh damping `C = mass * M + stiffness * K` (mass (1/s), stiffness (s)).
    pub fn with_damping(mut self, mass: f64, stiffness: f64) -> Self {
        self.damping = RayleighDamping { mass, stiffness };
        self
    }

    /// Sets the initial velocity (m/s).
    pub fn with_velocity(mut self, v: SVector<f64, D>) -> Self {
        self.initial_velocity = v;
        self
    }

    /// Sets the initial angular velocity (rad/s) (1 component in 2D, 3 in 3D).
    pub fn with_angular_velocity(mut self, omega: &[f64]) -> Self {
        self.initial_angular_velocity = omega.to_vec();
        self
    }

    /// Adds a constraint on the nodes in `[min, max]`: `velocity[k] = Some(v)` prescribes
    /// component k.
    pub fn with_constraint_in_box(
        mut self,
        min: SVector<f64, D>,
        max: SVector<f64, D>,
        velocity: [Option<f64>; D],
    ) -> Self {
        let nodes = self.mesh.nodes_in_box(&min, &max);
        self.constraints.push(Constraint {
            nodes,
            velocity: velocity.to_vec(),
        });
        self
    }
}

/// Everything a simulation is built from. With a [`super::State`] it rebuilds the simulation
/// exactly ([`super::Simulation::from_parts`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(bound = "")]
pub struct Model<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    /// Global parameters.
    pub settings: Settings<D>,
    /// The deformable bodies, in order (their nodes are numbered body after body).
    pub bodies: Vec<Body<D>>,
    /// The rigid obstacles at t = 0.
    pub obstacles: Vec<Obstacle<D>>,
    /// Contact method, penalty, friction.
    pub contact: ContactSettings,
}
