//! # softway
//!
//! Deformable bodies in dynamic contact with the space-time velocity formulation and the
//! "soft way" contact method of Bajer & Bohatier (1995).
//!
//! All quantities are SI: metres, seconds, kilograms, newtons, pascals, joules. In plane
//! kinematics forces and energies are per unit thickness (1 m); in axisymmetric kinematics they
//! are totals over the whole revolution.
//!
//! ```
//! use softway::prelude::*;
//! use nalgebra::Vector2;
//!
//! // A 1 m x 0.1 m steel strip, clamped at x = 0, sagging under gravity.
//! let mesh = rectangle(Vector2::new(0.0, 0.0), Vector2::new(1.0, 0.1), [20, 2], ElementKind::Quad4)?;
//! let steel = Material::LinearElastic(LinearElastic::new(210e9, 0.3, 7800.0)?);
//! let beam = Body::new("beam", mesh, steel)
//!     .with_constraint_in_box(Vector2::new(-1e-9, -1.0), Vector2::new(1e-9, 1.0), [Some(0.0), Some(0.0)]);
//! let mut sim = Simulation2::builder()
//!     .time_step(1e-4)
//!     .gravity(Vector2::new(0.0, -9.81))
//!     .body(beam)
//!     .build()?;
//! for _ in 0..10 {
//!     let report = sim.step()?;
//!     assert_eq!(report.iterations, 1); // linear: one solve per step
//! }
//! let tip = sim.displacement(sim.body_id("beam").unwrap(), 20)?;
//! assert!(tip.y < 0.0);
//! # Ok::<(), softway::Error>(())
//! ```

#![warn(missing_docs)]
// Numerical kernels index several arrays by the same node or dof index.
#![allow(clippy::needless_range_loop)]
// `!(x > 0.0)` is deliberate: it rejects NaN along with non-positive values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

// Internal machinery: public only with the `internals` feature (benches and figure examples
// measure it); embedders see none of it, and none of faer's types.
#[cfg(feature = "internals")]
pub mod assembly;
#[cfg(not(feature = "internals"))]
#[allow(dead_code, unreachable_pub)]
pub(crate) mod assembly;
pub mod contact;
pub mod dim;
pub mod element;
pub mod error;
pub mod friction;
pub mod geometry;
#[doc(hidden)]
pub mod instantiations;
#[cfg(feature = "formats")]
pub mod io;
pub mod material;
pub mod mesh;
mod parallel;
pub mod recording;
pub mod simulation;
#[cfg(feature = "internals")]
pub mod solver;
#[cfg(not(feature = "internals"))]
#[allow(dead_code, unreachable_pub)]
pub(crate) mod solver;
pub mod time;
// The verification chapter's measured figures (`book/verification.py`).
#[cfg(test)]
mod verify_record;

/// Runs `f` on a rayon pool of `threads` threads (feature `parallel`; without it, here):
/// the unit tests of results that must not depend on the thread count.
#[cfg(test)]
pub(crate) fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    #[cfg(feature = "parallel")]
    {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool")
            .install(f)
    }
    #[cfg(not(feature = "parallel"))]
    {
        let _ = threads;
        f()
    }
}

pub use error::{Error, Result};
pub use simulation::{Simulation, Simulation2, Simulation3};
pub use solver::FillOrdering;

/// The types most programs need.
pub mod prelude {
    pub use crate::contact::{ContactMethod, ContactSettings, Obstacle, ObstacleShape};
    pub use crate::dim::{Dim, Kinematics, SpatialDim};
    pub use crate::element::ElementKind;
    pub use crate::error::{Error, Result};
    pub use crate::friction::FrictionLaw;
    pub use crate::material::{LinearElastic, Material};
    pub use crate::mesh::generators::{annulus, cuboid, extrude, polygon, rectangle};
    pub use crate::mesh::Mesh;
    pub use crate::simulation::observe::{NullRecorder, Recorder};
    pub use crate::simulation::{
        Body, BodyId, ContactEvent, ContactMaster, ContactPoint, Energies, FixedTimestep,
        FrameReport, MassKind, Model, ObstacleId, Settings, Simulation, Simulation2, Simulation3,
        SimulationBuilder, State, StepReport, Touching,
    };
    pub use crate::time::{Beta, SpaceTimeScheme};
    pub use crate::FillOrdering;
}

// The README's and the book's Rust examples run as doc tests (mdBook cannot link crates).
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;

#[cfg(doctest)]
#[doc = include_str!("../book/src/library.md")]
pub struct BookLibraryDoctests;

#[cfg(doctest)]
#[doc = include_str!("../book/src/embedding.md")]
pub struct BookEmbeddingDoctests;

#[cfg(doctest)]
#[doc = include_str!("../book/src/contact-detection.md")]
pub struct BookContactDetectionDoctests;
