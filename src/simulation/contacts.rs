//! What the last step's contacts were, for a host: every contact point with its master, point,
//! normal, gap and forces; the force on each obstacle, between two bodies and on each node;
//! and the events (two entities started or stopped touching).
//!
//! This is an output of the step, not state: restoring a state clears it, and the next step
//! reports every touching pair as started.

use std::collections::BTreeSet;

use nalgebra::SVector;

use super::{BodyId, ObstacleId, Simulation};
use crate::contact::methods::projection::BodyImpulse;
use crate::contact::methods::PairOutcome;
use crate::contact::MasterId;
use crate::dim::{Dim, SpatialDim};
use crate::error::Result;

/// What a contact point touches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ContactMaster {
    /// A rigid obstacle.
    Obstacle(ObstacleId),
    /// A facet of a body (the slave's own body in self-contact).
    Body(BodyId),
}

/// One contact point at the end of the last step: a boundary node of a body (the slave)
/// against a master surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactPoint<const D: usize> {
    /// The body of the slave node.
    pub body: BodyId,
    /// The slave node, in its body's mesh numbering.
    pub node: usize,
    /// What it touches.
    pub master: ContactMaster,
    /// The closest point on the master (m).
    pub point: SVector<f64, D>,
    /// The master's unit outward normal there.
    pub normal: SVector<f64, D>,
    /// The gap (m; negative: penetration), on the step's predicted end positions (eq 22).
    pub gap: f64,
    /// The compressive normal force on the slave (N; per unit thickness in plane kinematics).
    pub normal_force: f64,
    /// The friction force on the slave (N).
    pub friction_force: SVector<f64, D>,
    /// The mean tangential slip velocity over the step (m/s).
    pub slip_velocity: SVector<f64, D>,
}

impl<const D: usize> ContactPoint<D> {
    /// The whole force the master exerts on the slave (N): normal plus friction.
    pub fn force(&self) -> SVector<f64, D> {
        self.normal * self.normal_force + self.friction_force
    }
}

/// Two entities in contact: a body against an obstacle, or two bodies (in handle order; the
/// same body twice for self-contact).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Touching {
    /// A body against an obstacle.
    BodyObstacle(BodyId, ObstacleId),
    /// Two bodies (the smaller handle first), or a body against itself.
    BodyBody(BodyId, BodyId),
}

/// A change of what touches what between the end of the previous step and the end of the
/// last one (a pair touches while at least one of its points carries a compressive force).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ContactEvent {
    /// The pair started touching during the last step.
    Started(Touching),
    /// The pair stopped touching during the last step.
    Stopped(Touching),
}

/// The last step's contacts (an output of the step, cleared when the state is replaced).
#[derive(Debug, Clone)]
pub(super) struct ContactLog<const D: usize> {
    points: Vec<ContactPoint<D>>,
    /// Contact force on every node (N, D per node): slave and master sides.
    nodal_forces: Vec<f64>,
    /// Force of each obstacle on the bodies over the last step (N), with the end-of-step
    /// projection's impulses over h.
    obstacle_forces: Vec<SVector<f64, D>>,
    /// Explicit projection's end-of-step impulses between bodies, over the step (N): (slave
    /// body, master body, force on the slave body).
    projection_between: Vec<(BodyId, BodyId, SVector<f64, D>)>,
    touching: BTreeSet<Touching>,
    events: Vec<ContactEvent>,
}

impl<const D: usize> Default for ContactLog<D> {
    fn default() -> Self {
        ContactLog {
            points: Vec::new(),
            nodal_forces: Vec::new(),
            obstacle_forces: Vec::new(),
            projection_between: Vec::new(),
            touching: BTreeSet::new(),
            events: Vec::new(),
        }
    }
}

impl<const D: usize> ContactLog<D> {
    /// Forgets everything (a replaced state, a changed model).
    pub(super) fn clear(&mut self) {
        *self = ContactLog::default();
    }
}

fn touching_of<const D: usize>(p: &ContactPoint<D>) -> Touching {
    match p.master {
        ContactMaster::Obstacle(o) => Touching::BodyObstacle(p.body, o),
        ContactMaster::Body(b) => Touching::BodyBody(p.body.min(b), p.body.max(b)),
    }
}

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// Records one converged step piece's pairs, nodal contact forces and end-of-step
    /// impulses between bodies.
    pub(super) fn log_contacts(
        &mut self,
        pairs: &[PairOutcome<D>],
        nodal_forces: &[f64],
        between_bodies: &[BodyImpulse<D>],
    ) {
        let bodies = self.body_ids();
        let obstacles = self.obstacle_ids();
        let points = pairs
            .iter()
            .filter(|p| p.normal_force != 0.0 || p.friction.iter().any(|f| *f != 0.0))
            .map(|p| {
                let (b, node) = self.owner_of(p.key.0);
                ContactPoint {
                    body: bodies[b],
                    node,
                    master: match p.key.1 {
                        MasterId::Obstacle(k) => ContactMaster::Obstacle(obstacles[k]),
                        MasterId::Body(m) => ContactMaster::Body(bodies[m]),
                    },
                    point: p.master_point,
                    normal: p.normal,
                    gap: p.gap,
                    normal_force: p.normal_force,
                    friction_force: p.friction,
                    slip_velocity: p.slip,
                }
            })
            .collect();
        let projection_between = between_bodies
            .iter()
            .map(|&(slave, master, f)| (bodies[self.owner_of(slave).0], bodies[master], f))
            .collect();
        self.contact_log.points = points;
        self.contact_log.nodal_forces = nodal_forces.to_vec();
        self.contact_log.projection_between = projection_between;
    }

    /// Closes the log of a whole step: the obstacles' forces and the events.
    pub(super) fn close_contact_log(&mut self, obstacle_forces: &[Vec<f64>]) {
        let log = &mut self.contact_log;
        log.obstacle_forces = obstacle_forces
            .iter()
            .map(|f| SVector::from_column_slice(f))
            .collect();
        let now: BTreeSet<Touching> = log
            .points
            .iter()
            .filter(|p| p.normal_force > 0.0)
            .map(touching_of)
            .collect();
        log.events = now
            .difference(&log.touching)
            .map(|t| ContactEvent::Started(*t))
            .chain(
                log.touching
                    .difference(&now)
                    .map(|t| ContactEvent::Stopped(*t)),
            )
            .collect();
        log.touching = now;
    }

    /// The contact points at the end of the last step (those carrying a force).
    pub fn contacts(&self) -> &[ContactPoint<D>] {
        &self.contact_log.points
    }

    /// What started and stopped touching during the last step.
    pub fn contact_events(&self) -> &[ContactEvent] {
        &self.contact_log.events
    }

    /// The pairs touching at the end of the last step.
    pub fn touching(&self) -> impl Iterator<Item = &Touching> {
        self.contact_log.touching.iter()
    }

    /// The force an obstacle exerted on the bodies over the last step (N; per unit thickness
    /// in plane kinematics): the sum of its contact points' forces, and the end-of-step
    /// projection's impulses divided by the step for the projection methods. The obstacle
    /// receives the opposite.
    pub fn obstacle_contact_force(&self, obstacle: ObstacleId) -> Result<SVector<f64, D>> {
        let k = self.obstacle_index(obstacle)?;
        Ok(self
            .contact_log
            .obstacle_forces
            .get(k)
            .copied()
            .unwrap_or_else(SVector::zeros))
    }

    /// The force body `other` exerted on body `body` at the end of the last step (N): the
    /// sum over the points of `body` against `other` minus the points of `other` against
    /// `body` (each point's force acts on its slave and, opposite, on the master's facet).
    /// Zero for a body with itself. Explicit projection's end-of-step impulses between the
    /// two bodies are included, divided by the step.
    pub fn contact_force_between(&self, body: BodyId, other: BodyId) -> Result<SVector<f64, D>> {
        self.body_index(body)?;
        self.body_index(other)?;
        let mut f = SVector::zeros();
        if body == other {
            return Ok(f);
        }
        for p in &self.contact_log.points {
            if p.body == body && p.master == ContactMaster::Body(other) {
                f += p.force();
            }
            if p.body == other && p.master == ContactMaster::Body(body) {
                f -= p.force();
            }
        }
        for &(slave, master, force) in &self.contact_log.projection_between {
            if slave == body && master == other {
                f += force;
            }
            if slave == other && master == body {
                f -= force;
            }
        }
        Ok(f)
    }

    /// The contact force on a node at the end of the last step (N): as a slave and as a
    /// vertex of master facets, friction included.
    pub fn node_contact_force(&self, body: BodyId, node: usize) -> Result<SVector<f64, D>> {
        let g = self.global_node(body, node)?;
        Ok(match self.contact_log.nodal_forces.get(g * D..g * D + D) {
            Some(f) => SVector::from_column_slice(f),
            None => SVector::zeros(),
        })
    }
}
