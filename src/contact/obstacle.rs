//! Rigid kinematic obstacles.

use nalgebra::SVector;
use serde::{Deserialize, Serialize};

/// The shape of a rigid obstacle, in its position at t = 0 [m].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ObstacleShape<const D: usize> {
    /// The half-space `(x - point) . normal <= 0` is solid; `normal` points out of it.
    Halfspace {
        /// A point of the boundary plane [m].
        point: SVector<f64, D>,
        /// Outward normal (normalised when used).
        normal: SVector<f64, D>,
    },
    /// An axis-aligned solid box.
    Box {
        /// Centre [m].
        center: SVector<f64, D>,
        /// Half extents [m], > 0.
        half_extents: SVector<f64, D>,
    },
    /// A solid ball (disc in 2D).
    Ball {
        /// Centre [m].
        center: SVector<f64, D>,
        /// Radius [m], > 0.
        radius: f64,
    },
    /// 2D: a polyline of segments; 3D: a triangle mesh. Facets are oriented like boundary
    /// facets of a body (2D: solid on the left of each segment; 3D: counter-clockwise seen from
    /// outside).
    Facets {
        /// Vertices [m].
        vertices: Vec<SVector<f64, D>>,
        /// D vertex indices per facet.
        indices: Vec<Vec<usize>>,
    },
}

/// A rigid obstacle moving at a constant velocity (changed between steps through the API).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Obstacle<const D: usize> {
    /// Unique name (history columns use it).
    pub name: String,
    /// Shape at t = 0.
    pub shape: ObstacleShape<D>,
    /// Velocity [m/s].
    pub velocity: SVector<f64, D>,
    /// Displacement of the obstacle since t = 0 [m] (advanced every step).
    pub translation: SVector<f64, D>,
    /// Friction law against this obstacle; `None` uses the contact settings' law.
    #[serde(default)]
    pub friction: Option<crate::contact::FrictionLaw>,
}

impl<const D: usize> Obstacle<D> {
    /// A fixed obstacle.
    pub fn new(name: impl Into<String>, shape: ObstacleShape<D>) -> Self {
        Obstacle {
            name: name.into(),
            shape,
            velocity: SVector::zeros(),
            translation: SVector::zeros(),
            friction: None,
        }
    }

    /// Sets the friction law against this obstacle.
    pub fn with_friction(mut self, law: crate::contact::FrictionLaw) -> Self {
        self.friction = Some(law);
        self
    }

    /// Sets the velocity [m/s].
    pub fn with_velocity(mut self, v: SVector<f64, D>) -> Self {
        self.velocity = v;
        self
    }
}
