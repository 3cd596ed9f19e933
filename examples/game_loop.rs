//! A game's host loop at 60 Hz driving softway through `FixedTimestep`: the frames come with
//! jitter (a frame of 1/60 s +- 30 %, one long hitch), the driver runs whole steps of 1/240 s
//! and reports the lag; soft crates are spawned while it runs, land on the floor (contact
//! events), and the oldest ones are despawned. Checks: the simulated time follows the host's
//! clock within a step (the hitch's excess aside), every landing is reported once, every live
//! crate rests on the floor at the end (its lowest point within a micrometre), and stale handles
//! are refused. The contact settings are the defaults.
//!
//! Run: `cargo run --example game_loop [-- --seconds 3] [--rerun game.rrd]` (2D, 3 s of
//! host time; `--rerun` needs the `rerun` feature, on by default, and records every step
//! through `FixedTimestep::advance_with`, the crates appearing and disappearing as they are
//! spawned and despawned; view the file with `rerun game.rrd`). Its tests:
//! `cargo test --example game_loop`.

mod common;

use std::path::Path;

use common::run::{conclude, Args, Failure, Recording};
use nalgebra::Vector2;
use softway::contact::ObstacleShape;
use softway::prelude::*;

/// What the loop saw.
#[derive(Debug)]
pub struct Played {
    /// Frames run.
    pub frames: usize,
    /// Steps run.
    pub steps: usize,
    /// The host's clock and the simulation's time at the end (s).
    pub host_time: f64,
    /// The simulation's time at the end (s).
    pub sim_time: f64,
    /// Host time dropped after the hitch (s).
    pub dropped: f64,
    /// Crates spawned, despawned, and landings reported.
    pub spawned: usize,
    /// Crates despawned.
    pub despawned: usize,
    /// `Started` events against the floor (a crate that bounces lands more than once).
    pub landings: usize,
    /// Crates that touched the floor at least once.
    pub landed: usize,
    /// The largest distance of a live crate's lowest point from the floor at the end (m).
    pub rest_error: f64,
}

fn crate_body(name: String, x: f64) -> softway::Result<Body<2>> {
    let rubber = Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0)?);
    let mesh = rectangle(
        Vector2::new(x, 0.05),
        Vector2::new(x + 0.1, 0.15),
        [2, 2],
        ElementKind::Quad4,
    )?;
    // Light stiffness damping so that crates settle, as a game would want.
    Ok(Body::new(name, mesh, rubber).with_damping(0.0, 1e-3))
}

/// Plays `seconds` of host time, recording to the Rerun file `rerun` when given.
pub fn play(seconds: f64, rerun: Option<&Path>) -> Result<Played, Failure> {
    let floor = Obstacle::new(
        "floor",
        ObstacleShape::Halfspace {
            point: Vector2::zeros(),
            normal: Vector2::new(0.0, 1.0),
        },
    );
    let mut sim = Simulation2::builder()
        .time_step(1.0 / 240.0)
        .gravity(Vector2::new(0.0, -9.81))
        .body(crate_body("crate 0".into(), 0.0)?)
        .obstacle(floor)
        .build()?;
    let mut recording = Recording::new(rerun, sim.obstacles())?;
    let floor = sim.obstacle_id("floor").expect("built with it");
    let mut alive = vec![sim.body_id("crate 0").expect("built with it")];
    let mut despawned_ids = Vec::new();
    let mut clock = FixedTimestep::new(8);
    let mut played = Played {
        frames: 0,
        steps: 0,
        host_time: 0.0,
        sim_time: 0.0,
        dropped: 0.0,
        spawned: 1,
        despawned: 0,
        landings: 0,
        landed: 0,
        rest_error: 0.0,
    };
    let mut frame = 0usize;
    let mut landed = std::collections::BTreeSet::new();
    while played.host_time < seconds - 1e-9 {
        // 1/60 s with a deterministic +-30 % jitter, and one hitch of 0.25 s at frame 90.
        let jitter = 1.0 + 0.3 * ((frame as f64) * 2.3).sin();
        let dt = if frame == 90 { 0.25 } else { jitter / 60.0 };
        played.host_time += dt;
        let report = clock.advance_with(&mut sim, dt, recording.recorder())?;
        played.steps += report.steps;
        if report.behind {
            // The game gives up catching up rather than stalling its frames.
            played.dropped += clock.lag();
            clock.reset();
        }
        // The events of every step of the frame (`sim.contact_events()` has the last step's).
        for event in &report.events {
            if let ContactEvent::Started(Touching::BodyObstacle(body, o)) = event {
                if *o == floor {
                    played.landings += 1;
                    landed.insert(*body);
                }
            }
        }
        // A crate every 30 frames, side by side, until the last second; beyond three, the
        // oldest goes.
        if frame % 30 == 29 && played.host_time < seconds - 1.0 {
            let x = 0.25 * played.spawned as f64;
            let id = sim.add_body(crate_body(format!("crate {}", played.spawned), x)?)?;
            alive.push(id);
            played.spawned += 1;
            if alive.len() > 3 {
                let old = alive.remove(0);
                sim.remove_body(old)?;
                despawned_ids.push(old);
                played.despawned += 1;
            }
        }
        frame += 1;
    }
    recording.finish()?;
    for old in &despawned_ids {
        if sim.position(*old, 0).is_ok() {
            return Err("a despawned crate's handle still answers".into());
        }
    }
    played.frames = frame;
    played.landed = landed.len();
    played.sim_time = sim.state().time;
    for id in &alive {
        let lowest = sim
            .body_positions(*id)?
            .iter()
            .map(|p| p.y)
            .fold(f64::INFINITY, f64::min);
        played.rest_error = played.rest_error.max(lowest.abs());
    }
    Ok(played)
}

fn check(p: &Played) -> Result<(), String> {
    let h = 1.0 / 240.0;
    let behind = p.host_time - p.dropped - p.sim_time;
    if !(behind > -1e-9 && behind < h) {
        return Err(format!(
            "the simulation is {behind} s behind the host's clock (minus the dropped time)"
        ));
    }
    if p.landed != p.spawned || p.landings < p.landed {
        return Err(format!(
            "{} crates of {} reported landing ({} landings)",
            p.landed, p.spawned, p.landings
        ));
    }
    if p.rest_error > 1e-6 {
        return Err(format!(
            "a crate does not rest on the floor: a lowest point {} m from it",
            p.rest_error
        ));
    }
    if p.despawned == 0 {
        return Err("no crate was despawned".into());
    }
    Ok(())
}

fn print(p: &Played) {
    println!(
        "{} frames, {} steps, host {:.3} s, simulated {:.3} s, dropped {:.3} s; {} crates \
         spawned, {} despawned, {} landed ({} landings with the bounces); the crates rest within {:.1e} m of the floor",
        p.frames,
        p.steps,
        p.host_time,
        p.sim_time,
        p.dropped,
        p.spawned,
        p.despawned,
        p.landed,
        p.landings,
        p.rest_error
    );
}

fn main() -> std::process::ExitCode {
    let usage = "usage: game_loop [--seconds SECONDS] [--rerun FILE.rrd]";
    let outcome = Args::parse(&["--seconds"], usage).and_then(|args| {
        let seconds = args.get("--seconds")?.unwrap_or(3.0);
        play(seconds, args.rerun()?.as_deref())
    });
    conclude("game_loop", outcome, print, check)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default run, checked as `main` checks it.
    #[test]
    fn the_loop_keeps_up_and_the_crates_land() {
        let played = play(3.0, None).unwrap();
        check(&played).unwrap();
    }

    /// `--rerun FILE` records the loop as `main` plays it, crates spawned and despawned (the
    /// recorder follows the changing set of bodies).
    #[cfg(feature = "rerun")]
    #[test]
    fn records_to_rerun() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("game.rrd");
        let played = play(3.0, Some(&path)).unwrap();
        check(&played).unwrap();
        assert!(played.despawned > 0, "{played:?}");
        let size = std::fs::metadata(&path).unwrap().len();
        assert!(size > 10_000, "{size} bytes recorded");
    }
}
