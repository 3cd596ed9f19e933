//! Contact: rigid obstacles, detection (broad and narrow phase) and resolution (the soft way,
//! implicit and explicit projection, augmented Lagrangian; Coulomb, Tresca and viscoplastic
//! friction).

pub mod detection;
pub mod obstacle;
pub mod resolution;

pub use detection::{ContactPair, ContactSurface, DetectionOptions, Detector, Feature, Master};
pub use obstacle::{Obstacle, ObstacleShape};
pub use resolution::{ContactMethod, ContactSettings, FrictionLaw};
