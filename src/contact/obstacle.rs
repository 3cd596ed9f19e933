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

/// One piece of an obstacle's motion schedule: a constant velocity until `until`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotionSegment<const D: usize> {
    /// The end of this piece [s] (it starts where the previous one ends, the first at 0).
    pub until: f64,
    /// Linear velocity [m/s].
    pub velocity: SVector<f64, D>,
    /// Angular velocity about the pivot [rad/s]: 1 component in 2D, 3 in 3D (empty: none).
    #[serde(default)]
    pub angular_velocity: Vec<f64>,
}

/// A rigid obstacle moving at a constant velocity (changed between steps through the API) or
/// along a piecewise-constant schedule.
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
    /// A piecewise-constant motion in time order; when not empty it replaces `velocity`, and
    /// after the last piece the obstacle stops.
    #[serde(default)]
    pub motion: Vec<MotionSegment<D>>,
    /// The point rotations turn about [m] (default: the shape's point or centre).
    #[serde(default)]
    pub pivot: Option<SVector<f64, D>>,
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
            motion: Vec::new(),
            pivot: None,
        }
    }

    /// Sets a piecewise-constant motion schedule (see [`Obstacle::motion`]).
    pub fn with_motion(mut self, motion: Vec<MotionSegment<D>>) -> Self {
        self.motion = motion;
        self
    }

    /// The displacement of a scheduled obstacle between times `t0` and `t1` [m] (the integral
    /// of its piecewise-constant velocity); `None` without a schedule.
    pub fn scheduled_displacement(&self, t0: f64, t1: f64) -> Option<SVector<f64, D>> {
        if self.motion.is_empty() {
            return None;
        }
        let mut d = SVector::<f64, D>::zeros();
        let mut start = 0.0;
        for piece in &self.motion {
            let (a, b) = (t0.max(start), t1.min(piece.until));
            if b > a {
                d += piece.velocity * (b - a);
            }
            start = piece.until;
        }
        Some(d)
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
