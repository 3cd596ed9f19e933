//! Contact: rigid obstacles, detection (broad and narrow phase) and, later, resolution.

pub mod obstacle;

pub use obstacle::{Obstacle, ObstacleShape};
