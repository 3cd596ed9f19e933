//! Contact: rigid obstacles, detection (broad and narrow phase), the gap, and the methods that
//! enforce the contact conditions (the soft way, implicit and explicit projection, augmented
//! Lagrangian), one file each behind one internal interface (the crate-private module
//! `contact::methods`), chosen by [`ContactMethod`]. Friction laws live in [`crate::friction`].

pub mod detection;
pub mod gap;
pub(crate) mod inside;
pub(crate) mod methods;
pub mod obstacle;
pub mod resolution;
mod surface;

use serde::{Deserialize, Serialize};

pub use detection::{ContactPair, ContactSurface, DetectionOptions, Detector, Feature, Master};
pub use obstacle::{MotionSegment, Obstacle, ObstacleShape};
pub use resolution::{
    ContactMethod, ContactSettings, FrictionLaw, GapDisplacement, MasterNodes, PenaltyForce,
    ProjectionEnergy, ProjectionMetric, UzawaPenalty, DEFAULT_MASTER_TOLERANCE,
};

/// The master side of a contact, as remembered between iterations and steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum MasterId {
    /// A rigid obstacle (index).
    Obstacle(usize),
    /// A body's surface (body index).
    Body(usize),
}

/// One contact: (global slave node, master).
pub type ContactKey = (usize, MasterId);
