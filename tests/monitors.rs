//! Issue 14, monitors that speak up: implicit projection's contact-set cycles are reported by
//! `RunMonitor` (see its unit tests for the warning); a calm scene reports none.

mod common;

use common::{block, vec_d};
use softway::contact::{ContactMethod, ContactSettings, Obstacle, ObstacleShape};
use softway::prelude::*;
use softway::simulation::RunMonitor;

/// A block resting on a floor under gravity with implicit projection (the default method):
/// no point is held, no set comes back, and the monitor has nothing to say.
fn a_block_at_rest_makes_no_cycle_warning<const D: usize>()
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let mesh: Mesh<D> = block([0.2, 0.1, 0.2], [4, 2, 4], false);
    let mut g = [0.0; 3];
    g[D - 1] = -9.81;
    let mut up = [0.0; 3];
    up[D - 1] = 1.0;
    let mut sim = Simulation::<D>::builder()
        .time_step(1e-3)
        .gravity(vec_d(g))
        .body(Body::new(
            "block",
            mesh,
            Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap()),
        ))
        .obstacle(Obstacle::new(
            "floor",
            ObstacleShape::Halfspace {
                point: vec_d([0.0; 3]),
                normal: vec_d(up),
            },
        ))
        .contact(ContactSettings {
            method: ContactMethod::ImplicitProjection,
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    let mut monitor = RunMonitor::new(&sim);
    for _ in 0..50 {
        let r = sim.step().unwrap();
        assert_eq!(
            (r.held_contacts, r.contact_cycles),
            (0, 0),
            "step {}",
            r.step
        );
        let news = monitor.step(&sim, &r).unwrap().unwrap_or_default();
        assert!(
            !news.contains("contact set cycled"),
            "step {}: {news}",
            r.step
        );
    }
    let w = monitor.warnings();
    assert!(!w.iter().any(|w| w.contains("contact set cycled")), "{w:?}");
}

both_dims!(a_block_at_rest_makes_no_cycle_warning);
