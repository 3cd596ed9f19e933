//! Contact: rigid obstacles, detection (broad and narrow phase) and, later, resolution.

pub mod detection;
pub mod obstacle;

pub use detection::{ContactPair, ContactSurface, DetectionOptions, Detector, Feature, Master};
pub use obstacle::{Obstacle, ObstacleShape};
