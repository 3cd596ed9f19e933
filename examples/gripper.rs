//! A robot gripper, driven the way a robot controller drives it: every step the host sets
//! where each of two rigid jaws must be at the end of the step (`set_obstacle_next_pose`).
//! The jaws close on a soft block resting on the floor (Coulomb friction, mu = 0.8), hold,
//! then lift; the block rises with them, carried by friction alone. The example reads the
//! jaws' contact forces through the API and checks that their vertical friction carries the
//! block's weight, and that the block follows the jaws.
//!
//! Run: `cargo run --example gripper [-- [--end-time 0.5] [--rerun gripper.rrd]]` (2D, 0.5 s,
//! default scheme and contact method; `--rerun` needs the `rerun` feature, on by default, and
//! records every iteration with the jaws drawn where the host puts them; view the file with
//! `rerun gripper.rrd`). Its tests: `cargo test --example gripper`.

mod common;

use std::path::Path;

use common::run::{conclude, Args, Failure, Recording};
use nalgebra::{Matrix2, Vector2};
use softway::contact::ObstacleShape;
use softway::prelude::*;

/// Each jaw closes at this speed (m/s) until `CLOSE` (s): 5 mm of gap, then 1 mm into the block.
const CLOSE_SPEED: f64 = 0.05;
const CLOSE: f64 = 0.12;
/// Held still until `HOLD` (s), then lifted at `LIFT_SPEED` (m/s) until `LIFT` (s).
const HOLD: f64 = 0.2;
const LIFT_SPEED: f64 = 0.1;
const LIFT: f64 = 0.5;
const G: f64 = 9.81;

/// Where a jaw's centre is at time `t` relative to its start: closing, holding, lifting.
fn jaw_offset(side: f64, t: f64) -> Vector2<f64> {
    let x = side * CLOSE_SPEED * t.min(CLOSE);
    let y = LIFT_SPEED * (t.min(LIFT) - HOLD).max(0.0);
    Vector2::new(x, y)
}

/// What the run measured.
#[derive(Debug)]
pub struct Gripped {
    /// The block's mean rise during the lift (m), and the jaws' travel.
    pub lifted: f64,
    /// The jaws' rise during the lift (m).
    pub jaw_travel: f64,
    /// Mean over the second half of the lift of the jaws' upward force on the block (N/m),
    /// and the block's weight (N/m).
    pub carried: f64,
    /// The block's weight per metre of thickness (N/m).
    pub weight: f64,
    /// Mean squeeze of the left jaw over the same window (N/m).
    pub squeeze: f64,
}

/// Runs the gripper for `end` seconds (at most `LIFT`), recording to the Rerun file `rerun`
/// when given.
pub fn run(end: f64, rerun: Option<&Path>) -> Result<Gripped, Failure> {
    let rubber = Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0)?);
    let block = rectangle(
        Vector2::zeros(),
        Vector2::new(0.1, 0.1),
        [6, 6],
        ElementKind::Quad4,
    )?;
    let jaw = |name: &str, x: f64| {
        Obstacle::new(
            name,
            ObstacleShape::Box {
                center: Vector2::new(x, 0.05),
                half_extents: Vector2::new(0.02, 0.04),
            },
        )
    };
    let floor = Obstacle::new(
        "floor",
        ObstacleShape::Halfspace {
            point: Vector2::zeros(),
            normal: Vector2::new(0.0, 1.0),
        },
    );
    let mut sim = Simulation2::builder()
        .time_step(1e-3)
        .gravity(Vector2::new(0.0, -G))
        .body(Body::new("block", block, rubber))
        .obstacle(floor)
        .obstacle(jaw("left", -0.025))
        .obstacle(jaw("right", 0.125))
        .contact(ContactSettings {
            penalty: 1e9,
            friction: FrictionLaw::Coulomb {
                coefficient: 0.8,
                regularization: 1e-6,
            },
            ..ContactSettings::default()
        })
        .build()?;
    let mut recording = Recording::new(rerun, sim.obstacles())?;
    let block = sim.body_id("block").expect("built with it");
    let jaws = [
        (sim.obstacle_id("left").expect("built"), 1.0),
        (sim.obstacle_id("right").expect("built"), -1.0),
    ];
    let weight = sim.body_mass(block)? * G;
    let h = sim.settings().time_step;
    let mean_height = |sim: &Simulation2| -> softway::Result<f64> {
        let x = sim.body_positions(block)?;
        Ok(x.iter().map(|p| p.y).sum::<f64>() / x.len() as f64)
    };
    let (mut at_hold, mut carried, mut squeeze, mut samples) = (None, 0.0, 0.0, 0);
    let end = end.min(LIFT);
    let steps = (end / h).round() as usize;
    for i in 1..=steps {
        let t = i as f64 * h;
        for (jaw, side) in jaws {
            sim.set_obstacle_next_pose(jaw, jaw_offset(side, t), Matrix2::identity())?;
        }
        sim.step_with(recording.recorder())?;
        if at_hold.is_none() && t >= HOLD - 1e-9 {
            at_hold = Some(mean_height(&sim)?);
        }
        if t > 0.5 * (HOLD + end) {
            let left = sim.obstacle_contact_force(jaws[0].0)?;
            let right = sim.obstacle_contact_force(jaws[1].0)?;
            carried += left.y + right.y;
            squeeze += left.x;
            samples += 1;
        }
    }
    recording.finish()?;
    let rise = mean_height(&sim)? - at_hold.unwrap_or(0.0);
    Ok(Gripped {
        lifted: rise,
        jaw_travel: LIFT_SPEED * (end - HOLD).max(0.0),
        carried: carried / samples.max(1) as f64,
        weight,
        squeeze: squeeze / samples.max(1) as f64,
    })
}

/// The checks: the block follows the jaws within 5 % of their travel, and their upward force
/// carries its weight within 5 % once it rises at their speed.
fn check(g: &Gripped) -> Result<(), String> {
    let slip = g.jaw_travel - g.lifted;
    if slip.abs() > 0.05 * g.jaw_travel {
        return Err(format!(
            "the block rose {:.4} m against the jaws' {:.4} m",
            g.lifted, g.jaw_travel
        ));
    }
    if (g.carried - g.weight).abs() > 0.05 * g.weight {
        return Err(format!(
            "the jaws carry {:.2} N/m against the weight {:.2} N/m",
            g.carried, g.weight
        ));
    }
    Ok(())
}

fn print(g: &Gripped) {
    println!(
        "block lifted {:.4} m with the jaws' {:.4} m; jaws carry {:.2} N/m of its {:.2} N/m \
         weight, squeezing with {:.1} N/m",
        g.lifted, g.jaw_travel, g.carried, g.weight, g.squeeze
    );
}

fn main() -> std::process::ExitCode {
    let usage = "usage: gripper [--end-time SECONDS] [--rerun FILE.rrd]";
    let outcome = Args::parse(&["--end-time"], usage).and_then(|args| {
        let end = args.get("--end-time")?.unwrap_or(LIFT);
        run(end, args.rerun()?.as_deref())
    });
    conclude("gripper", outcome, print, check)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default run, checked as `main` checks it.
    #[test]
    fn the_jaws_lift_the_block() {
        let gripped = run(LIFT, None).unwrap();
        check(&gripped).unwrap();
    }

    /// `--rerun FILE` writes a recording (the jaws closing, 0.05 s), into a folder created
    /// for it.
    #[cfg(feature = "rerun")]
    #[test]
    fn records_to_rerun() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("new/gripper.rrd");
        run(0.05, Some(&path)).unwrap();
        let size = std::fs::metadata(&path).unwrap().len();
        assert!(size > 10_000, "{size} bytes recorded");
    }
}
