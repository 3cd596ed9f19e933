//! [`SimulationBuilder`]: a simulation set up in code.

use nalgebra::SVector;

use super::{Body, MassKind, Model, Settings, Simulation};
use crate::contact::{ContactSettings, Obstacle};
use crate::dim::{Dim, Kinematics, SpatialDim};
use crate::error::Result;
use crate::solver::FillOrdering;
use crate::time::{Beta, SpaceTimeScheme};

/// Builds a [`Simulation`]: made by [`Simulation::builder`] (default settings, no body), the
/// one way to build a simulation in code ([`Simulation::from_model`] takes a model held as a
/// value, [`Simulation::from_parts`] restores a saved state).
#[derive(Debug, Clone)]
pub struct SimulationBuilder<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    settings: Settings<D>,
    bodies: Vec<Body<D>>,
    obstacles: Vec<Obstacle<D>>,
    contact: ContactSettings,
}

impl<const D: usize> Default for SimulationBuilder<D>
where
    Dim<D>: SpatialDim<D>,
{
    fn default() -> Self {
        SimulationBuilder {
            settings: Settings::default(),
            bodies: Vec::new(),
            obstacles: Vec::new(),
            contact: ContactSettings::default(),
        }
    }
}

impl<const D: usize> SimulationBuilder<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// Replaces all settings.
    pub fn settings(mut self, settings: Settings<D>) -> Self {
        self.settings = settings;
        self
    }

    /// Time step h (s).
    pub fn time_step(mut self, h: f64) -> Self {
        self.settings.time_step = h;
        self
    }

    /// alpha and beta of the scheme (validated by [`SimulationBuilder::build`]).
    pub fn scheme(mut self, alpha: f64, beta: Beta) -> Self {
        let b = match beta {
            Beta::Energy => 1.0 - alpha,
            Beta::Trapezoid => 0.5,
            Beta::Value(b) => b,
        };
        self.settings.scheme = SpaceTimeScheme { alpha, beta: b };
        self
    }

    /// Gravity [m/s^2].
    pub fn gravity(mut self, g: SVector<f64, D>) -> Self {
        self.settings.gravity = g;
        self
    }

    /// Kinematics (2D: plane strain, plane stress, axisymmetric).
    pub fn kinematics(mut self, k: Kinematics) -> Self {
        self.settings.kinematics = k;
        self
    }

    /// Relative residual tolerance of Newton.
    pub fn tolerance(mut self, tolerance: f64) -> Self {
        self.settings.tolerance = tolerance;
        self
    }

    /// Largest number of Newton and contact iterations in one step.
    pub fn max_iterations(mut self, n: usize) -> Self {
        self.settings.max_iterations = n;
        self
    }

    /// Mass matrix kind.
    pub fn mass(mut self, m: MassKind) -> Self {
        self.settings.mass = m;
        self
    }

    /// Fill-reducing ordering of the sparse Cholesky factorisation.
    pub fn ordering(mut self, ordering: FillOrdering) -> Self {
        self.settings.ordering = ordering;
        self
    }

    /// Adds a body.
    pub fn body(mut self, body: Body<D>) -> Self {
        self.bodies.push(body);
        self
    }

    /// Adds a rigid obstacle.
    pub fn obstacle(mut self, obstacle: Obstacle<D>) -> Self {
        self.obstacles.push(obstacle);
        self
    }

    /// Contact method, penalty, friction.
    pub fn contact(mut self, contact: ContactSettings) -> Self {
        self.contact = contact;
        self
    }

    /// Validates everything and assembles the matrices.
    pub fn build(self) -> Result<Simulation<D>> {
        Simulation::from_model(Model {
            settings: self.settings,
            bodies: self.bodies,
            obstacles: self.obstacles,
            contact: self.contact,
        })
    }
}
