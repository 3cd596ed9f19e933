//! A first look at the paper's example 3 (not the example: 80 cells against its 1250, the
//! law's constants guessed for a steel): an axisymmetric tube (radii 20 and 22 mm, 60 mm
//! long, bulged 0.1 mm at mid-height), Norton-Hoff with inertia (K = 8e7 Pa s^m, m = 0.1,
//! 7800 kg/m^3), its base held, crushed by a plate at 50 m/s over 30 mm (h = 1 us), with
//! self-contact, under implicit projection and the soft way (zeta = 1e13 Pa/m). A fold forms
//! under the plate and touches itself (1 or 2 points) with wall that started at least 18 mm
//! away (a fold, not a node beside a corner); the run ends and the energy account closes. `cargo test --all-features --test suite tube_crush:: -- --nocapture` prints the figures.
use crate::common;
use nalgebra::Vector2;
use softway::contact::{ContactMethod, ContactSettings, Obstacle, ObstacleShape};
use softway::material::NortonHoff;
use softway::prelude::*;

#[test]
fn tube() {
    for method in [ContactMethod::ImplicitProjection, ContactMethod::SoftWay] {
        let mut mesh = rectangle(
            Vector2::new(0.02, 0.0),
            Vector2::new(0.022, 0.06),
            [2, 40],
            ElementKind::Quad4,
        )
        .unwrap();
        // A small imperfection: the wall bulges outward by 0.1 mm at mid-height.
        for x in &mut mesh.nodes {
            x.x += 1e-4 * (std::f64::consts::PI * x.y / 0.06).sin();
        }
        let body = Body::new(
            "tube",
            mesh,
            Material::NortonHoff(NortonHoff::new(8e7, 0.1, 7800.0, 1e5).unwrap()),
        )
        .with_constraint_in_box(
            Vector2::new(-1.0, -1e-9),
            Vector2::new(1.0, 1e-9),
            [Some(0.0), Some(0.0)],
        );
        let plate = Obstacle {
            velocity: Vector2::new(0.0, -50.0),
            ..Obstacle::new(
                "plate",
                ObstacleShape::Halfspace {
                    point: Vector2::new(0.0, 0.0601),
                    normal: Vector2::new(0.0, -1.0),
                },
            )
        };
        let mut sim = Simulation::<2>::builder()
            .kinematics(Kinematics::Axisymmetric)
            .time_step(1e-6)
            .body(body)
            .obstacle(plate)
            .contact(ContactSettings {
                method,
                penalty: 1e13,
                self_contact: true,
                ..ContactSettings::default()
            })
            .build()
            .unwrap();
        let id = sim.body_id("tube").unwrap();
        let mut self_steps = 0;
        let mut most = 0;
        let mut deepest: f64 = 0.0;
        let mut lowest_self = f64::INFINITY;
        let mut closest_apart = f64::INFINITY;
        let clock = std::time::Instant::now();
        let mut outcome = String::from("ran");
        while sim.state().time < 6e-4 - 1e-12 {
            match sim.step() {
                Ok(r) => deepest = deepest.max(r.max_penetration),
                Err(e) => {
                    outcome = format!("stopped at t = {:.3e}: {e}", sim.state().time);
                    break;
                }
            }
            let own: Vec<_> = sim
                .contacts()
                .iter()
                .filter(|c| c.master == ContactMaster::Body(id) && c.normal_force > 0.0)
                .collect();
            if !own.is_empty() {
                self_steps += 1;
                most = most.max(own.len());
                let (x, x0) = (sim.positions(), sim.reference_positions());
                for c in &own {
                    lowest_self = lowest_self.min(c.point.y);
                    // The material the node touches: the node nearest the contact point, other
                    // than the node itself. A fold brings together wall that was far apart; a
                    // false pair beside a corner is a cell or two away (1.5 mm cells).
                    let touched = (0..x.len())
                        .filter(|&n| n != c.node)
                        .min_by(|&a, &b| {
                            (x[a] - c.point).norm().total_cmp(&(x[b] - c.point).norm())
                        })
                        .unwrap();
                    closest_apart = closest_apart.min((x0[touched] - x0[c.node]).norm());
                }
            }
        }
        let e = sim.energies();
        let account = common::energy_error(&sim);
        eprintln!(
            "{method:?}: {outcome}; t = {:.3e} s, crushed {:.1} mm, {self_steps} steps with self-contact (at most {most} points, lowest at y = {lowest_self:.4}; touching wall at least {closest_apart:.2e} m apart at the start), deepest penetration {deepest:.3e} m, account {:.2e}, E {:.3e} W {:.3e} D {:.3e}, {:.1} s",
            sim.state().time,
            50.0 * sim.state().time * 1e3,
            account,
            e.total(), e.external_work, e.dissipated,
            clock.elapsed().as_secs_f64()
        );
        assert_eq!(outcome, "ran", "{method:?}");
        assert!(
            self_steps >= 20,
            "{method:?}: {self_steps} steps with self-contact"
        );
        assert!(deepest < 1e-4, "{method:?}: penetration {deepest}");
        // Genuine fold contacts (measured: at least 18 and 19.5 mm apart at the start).
        assert!(
            closest_apart > 5e-3,
            "{method:?}: a self-contact between wall {closest_apart} m apart"
        );
        assert!(account < 1e-2, "{method:?}: account {account}");
    }
}
