//! Rigid kinematic obstacles: a shape at t = 0 and a pose (a translation, and a rotation about
//! the pivot, which moves with the translation): a point `y` of the shape at t = 0 is at
//! `pivot + translation + rotation (y - pivot)`.

use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

/// The shape of a rigid obstacle, in its position at t = 0 (m).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ObstacleShape<const D: usize> {
    /// The half-space `(x - point) . normal <= 0` is solid; `normal` points out of it.
    Halfspace {
        /// A point of the boundary plane (m).
        point: SVector<f64, D>,
        /// Outward normal (normalised when used).
        normal: SVector<f64, D>,
    },
    /// A solid box, axis-aligned at t = 0 (it turns with its obstacle).
    Box {
        /// Centre (m).
        center: SVector<f64, D>,
        /// Half extents (m), > 0.
        half_extents: SVector<f64, D>,
    },
    /// A solid ball (disc in 2D).
    Ball {
        /// Centre (m).
        center: SVector<f64, D>,
        /// Radius (m), > 0.
        radius: f64,
    },
    /// 2D: a polyline of segments; 3D: a triangle mesh. Facets are oriented like boundary
    /// facets of a body (2D: solid on the left of each segment; 3D: counter-clockwise seen from
    /// outside).
    Facets {
        /// Vertices (m).
        vertices: Vec<SVector<f64, D>>,
        /// D vertex indices per facet.
        indices: Vec<Vec<usize>>,
    },
}

/// One piece of an obstacle's motion schedule: a constant velocity until `until`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotionSegment<const D: usize> {
    /// The end of this piece (s) (it starts where the previous one ends, the first at 0).
    pub until: f64,
    /// Linear velocity (m/s).
    pub velocity: SVector<f64, D>,
    /// Angular velocity about the pivot (rad/s): 1 component in 2D, 3 in 3D (empty: none).
    #[serde(default)]
    pub angular_velocity: Vec<f64>,
}

/// A rigid obstacle moving at a constant velocity and angular velocity (changed between steps
/// through the API) or along a piecewise-constant schedule.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Obstacle<const D: usize> {
    /// Unique name (history columns use it).
    pub name: String,
    /// Shape at t = 0.
    pub shape: ObstacleShape<D>,
    /// Velocity (m/s).
    pub velocity: SVector<f64, D>,
    /// Displacement of the obstacle (of its pivot) since t = 0 (m) (advanced every step).
    pub translation: SVector<f64, D>,
    /// Angular velocity about the pivot (rad/s): 1 component in 2D, 3 in 3D (empty: none).
    #[serde(default)]
    pub angular_velocity: Vec<f64>,
    /// Rotation about the pivot since t = 0 (advanced every step; the identity: not turned).
    #[serde(default = "identity::<D>")]
    pub rotation: SMatrix<f64, D, D>,
    /// Friction law against this obstacle; `None` uses the contact settings' law.
    #[serde(default)]
    pub friction: Option<crate::contact::FrictionLaw>,
    /// A piecewise-constant motion in time order; when not empty it replaces `velocity` and
    /// `angular_velocity`, and after the last piece the obstacle stops.
    #[serde(default)]
    pub motion: Vec<MotionSegment<D>>,
    /// The point rotations turn about, at t = 0 (m) (default: the shape's point or centre, the
    /// vertices' centroid for facets); it moves with the translation.
    #[serde(default)]
    pub pivot: Option<SVector<f64, D>>,
}

fn identity<const D: usize>() -> SMatrix<f64, D, D> {
    SMatrix::identity()
}

impl<const D: usize> Obstacle<D> {
    /// A fixed obstacle.
    pub fn new(name: impl Into<String>, shape: ObstacleShape<D>) -> Self {
        Obstacle {
            name: name.into(),
            shape,
            velocity: SVector::zeros(),
            translation: SVector::zeros(),
            angular_velocity: Vec::new(),
            rotation: SMatrix::identity(),
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

    /// The displacement of a scheduled obstacle between times `t0` and `t1` (m) (the integral
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

    /// Sets the velocity (m/s).
    pub fn with_velocity(mut self, v: SVector<f64, D>) -> Self {
        self.velocity = v;
        self
    }

    /// Sets the angular velocity about the pivot (rad/s) (1 component in 2D, 3 in 3D).
    pub fn with_angular_velocity(mut self, omega: &[f64]) -> Self {
        self.angular_velocity = omega.to_vec();
        self
    }

    /// Sets the point rotations turn about, at t = 0 (m).
    pub fn with_pivot(mut self, pivot: SVector<f64, D>) -> Self {
        self.pivot = Some(pivot);
        self
    }

    /// The pivot at t = 0 (m): [`Obstacle::pivot`], else the half-space's point, the box's or
    /// ball's centre, the facets' vertex centroid.
    pub fn pivot_point(&self) -> SVector<f64, D> {
        if let Some(p) = self.pivot {
            return p;
        }
        match &self.shape {
            ObstacleShape::Halfspace { point, .. } => *point,
            ObstacleShape::Box { center, .. } | ObstacleShape::Ball { center, .. } => *center,
            ObstacleShape::Facets { vertices, .. } => {
                vertices.iter().sum::<SVector<f64, D>>() / vertices.len().max(1) as f64
            }
        }
    }

    /// Whether the obstacle is turned from its shape at t = 0 (its rotation is not the
    /// identity). Obstacles that are not go through the translation-only arithmetic, bit for
    /// bit as before rotations existed.
    pub fn is_turned(&self) -> bool {
        self.rotation != SMatrix::<f64, D, D>::identity()
    }

    /// A world point `x` in the frame of the shape at t = 0 (m).
    pub fn to_local(&self, x: &SVector<f64, D>) -> SVector<f64, D> {
        if !self.is_turned() {
            return x - self.translation;
        }
        let p = self.pivot_point();
        p + self.rotation.transpose() * (x - p - self.translation)
    }

    /// A point `y` of the shape at t = 0 where the pose puts it (m).
    pub fn to_world(&self, y: &SVector<f64, D>) -> SVector<f64, D> {
        if !self.is_turned() {
            return y + self.translation;
        }
        let p = self.pivot_point();
        p + self.translation + self.rotation * (y - p)
    }

    /// A direction of the shape at t = 0 (a normal, an edge) turned with the obstacle.
    pub fn turn(&self, n: &SVector<f64, D>) -> SVector<f64, D> {
        if self.is_turned() {
            self.rotation * n
        } else {
            *n
        }
    }
}
