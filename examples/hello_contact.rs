//! The smallest contact scene: an elastic block dropped on a rigid floor, the contact resolved
//! by the soft way, with the default time scheme (h = 1 ms, alpha = 0.75, beta = 1 - alpha).
//! The scene is built by the README's library lines; a little stiffness-proportional damping
//! (`C = 1e-3 s K`) lets the block settle instead of ringing for ever.
//!
//! Checked at the end (the program exits with status 1 and says what failed otherwise):
//! * the block comes to rest on the floor: its kinetic energy is below 1e-3 of the energy the
//!   fall released (m g times the 5 cm drop), and the floor carries its weight m g within 1 %;
//! * the penetration stays bounded: below 1 % of the block's height at every step;
//! * energy is not created: at the end `E - E(0) - W + D <= 0` (E kinetic + elastic + contact
//!   energy, W the work of gravity, D what damping dissipated): the block holds no more than
//!   gravity gave it less what damping took (measured -1.9 % of the fall's energy: the impact
//!   loses a little more than damping books). Step by step the account swings: +0.5 % during
//!   the free fall (the update with beta != 1/2 lags the exact displacement by O(h)) and up to
//!   +9.3 % in the impact's few steps (the stiff modes' swing of E that beta = 1 - alpha keeps,
//!   see the book's time-scheme chapter); the check bounds that swing at 20 %.
//!
//! Run: `cargo run --example hello_contact [-- --end-time 1.0] [--rerun hello.rrd]`
//! (`--rerun` needs the `rerun` feature, on by default; view the file with `rerun hello.rrd`).
//! Its tests: `cargo test --example hello_contact`.

mod common;

use common::run::{conclude, Args, Failure, Recording};
use nalgebra::Vector2;
use softway::prelude::*;

/// What the example is asked to do.
#[derive(Debug, Clone)]
struct Options {
    /// Simulated time [s].
    end_time: f64,
    /// Record every solver iteration to this Rerun file.
    rerun: Option<std::path::PathBuf>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            end_time: 1.0,
            rerun: None,
        }
    }
}

/// What the run measured.
#[derive(Debug, Clone)]
struct Summary {
    /// Steps taken.
    steps: usize,
    /// The block's mass [kg] (per metre of thickness).
    mass: f64,
    /// Energy the fall released, m g times the drop height [J].
    fall_energy: f64,
    /// Kinetic energy at the end [J].
    kinetic: f64,
    /// Vertical force of the floor on the block at the end [N].
    floor_force: f64,
    /// Largest penetration at the end of a step [m].
    max_penetration: f64,
    /// Largest `E - E(0) - W + D` over the steps, over the fall's energy.
    swing: f64,
    /// `E - E(0) - W + D` at the end, over the fall's energy (negative: energy lost).
    account: f64,
    /// Energy damping dissipated [J].
    dissipated: f64,
}

const G: f64 = 9.81;
const HEIGHT: f64 = 0.1;
const DROP: f64 = 0.05;

fn run(options: &Options) -> Result<Summary, Failure> {
    // The README's library lines, from here to `.build()?`.
    // A 0.2 m x 0.1 m rubber block, its base 5 cm above a rigid floor.
    let (corner, opposite) = (Vector2::new(-0.1, 0.05), Vector2::new(0.1, 0.15)); // [m]
    let mesh = rectangle(corner, opposite, [8, 4], ElementKind::Quad4)?;
    let rubber = Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0)?); // E [Pa], nu, rho
    let block = Body::new("block", mesh, rubber).with_damping(0.0, 1e-3); // C = 1e-3 s K
    let floor = ObstacleShape::Halfspace {
        point: Vector2::zeros(),
        normal: Vector2::y(),
    };
    let mut sim = Simulation2::builder()
        .gravity(Vector2::new(0.0, -9.81)) // [m/s^2]; h = 1 ms, alpha = 0.75: the defaults
        .body(block)
        .obstacle(Obstacle::new("floor", floor))
        .contact(ContactSettings {
            method: ContactMethod::SoftWay,
            penalty: 1e9, // zeta [Pa/m]
            ..Default::default()
        })
        .build()?;

    // Step to the end time, recording when asked, and keep what the checks need.
    let mut recording = Recording::new(options.rerun.as_deref(), sim.obstacles())?;
    let mass = sim.body_mass(sim.body_id("block").expect("named above"))?;
    let fall_energy = mass * G * DROP;
    let e0 = sim.initial_energy();
    let (mut max_penetration, mut swing): (f64, f64) = (0.0, 0.0);
    let (mut floor_force, mut steps) = (0.0, 0);
    while sim.state().time < options.end_time - 1e-9 {
        let report = sim.step_with(recording.recorder())?;
        steps += 1;
        max_penetration = max_penetration.max(report.max_penetration);
        floor_force = report.contact_forces[0][1]; // obstacle 0, the y component [N]
        let e = report.energies;
        swing = swing.max((e.total() - e0 - e.external_work + e.dissipated) / fall_energy);
    }
    recording.finish()?;
    let e = sim.energies();
    Ok(Summary {
        steps,
        mass,
        fall_energy,
        kinetic: e.kinetic,
        floor_force,
        max_penetration,
        swing,
        account: (e.total() - e0 - e.external_work + e.dissipated) / fall_energy,
        dissipated: e.dissipated,
    })
}

/// The physical checks; `Err` says which failed.
fn check(s: &Summary) -> Result<(), String> {
    let mut failed = Vec::new();
    if s.kinetic > 1e-3 * s.fall_energy {
        failed.push(format!(
            "not at rest: kinetic energy {:.3e} J > 1e-3 of the fall's {:.3e} J",
            s.kinetic, s.fall_energy
        ));
    }
    let weight = s.mass * G;
    if (s.floor_force - weight).abs() > 0.01 * weight {
        failed.push(format!(
            "the floor carries {:.4} N, not the weight {:.4} N (1 %)",
            s.floor_force, weight
        ));
    }
    if s.max_penetration > 0.01 * HEIGHT {
        failed.push(format!(
            "penetration {:.3e} m > 1 % of the block's height",
            s.max_penetration
        ));
    }
    if s.account > 1e-9 {
        failed.push(format!(
            "energy created: E - E(0) - W + D = {:.3e} of the fall's energy at the end",
            s.account
        ));
    }
    if s.swing > 0.2 {
        failed.push(format!(
            "E - E(0) - W + D reached {:.3e} of the fall's energy (more than 0.2)",
            s.swing
        ));
    }
    if failed.is_empty() {
        Ok(())
    } else {
        Err(failed.join("\n"))
    }
}

fn print(s: &Summary) {
    println!("hello_contact: {} steps", s.steps);
    println!(
        "  at rest:     kinetic energy {:.3e} J ({:.2e} of the fall's {:.4} J)",
        s.kinetic,
        s.kinetic / s.fall_energy,
        s.fall_energy
    );
    println!(
        "  floor force: {:.4} N against the weight m g = {:.4} N ({:+.2e})",
        s.floor_force,
        s.mass * G,
        s.floor_force / (s.mass * G) - 1.0
    );
    println!("  penetration: {:.3e} m at most", s.max_penetration);
    println!(
        "  energy:      E - E(0) - W + D = {:+.3e} of the fall's energy at the end, \
         {:+.3e} at most; damping dissipated {:.4} J",
        s.account, s.swing, s.dissipated
    );
}

fn main() -> std::process::ExitCode {
    let usage = "usage: hello_contact [--end-time SECONDS] [--rerun FILE.rrd]";
    let options = Args::parse(&["--end-time"], usage).and_then(|args| {
        Ok(Options {
            end_time: args
                .get("--end-time")?
                .unwrap_or(Options::default().end_time),
            rerun: args.rerun()?,
        })
    });
    conclude("hello_contact", options.and_then(|o| run(&o)), print, check)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default run, checked as `main` checks it.
    #[test]
    fn block_comes_to_rest_on_the_floor() {
        let s = run(&Options::default()).unwrap();
        print(&s);
        check(&s).unwrap();
    }

    /// The README's library snippet builds the scene with this file's lines.
    #[test]
    fn readme_shows_these_lines() {
        let scene = |text: &'static str| -> &'static str {
            let start = text
                .find("    // A 0.2 m x 0.1 m rubber block")
                .expect("the scene's first line");
            let end = start + text[start..].find(".build()?;").expect("its last line");
            &text[start..end]
        };
        let here = scene(include_str!("hello_contact.rs"));
        let readme = scene(include_str!("../README.md"));
        assert_eq!(
            here, readme,
            "README.md and examples/hello_contact.rs differ"
        );
    }

    /// `--rerun FILE` writes a recording (the fall and the landing, 0.2 s).
    #[cfg(feature = "rerun")]
    #[test]
    fn records_to_rerun() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("hello.rrd");
        let options = Options {
            end_time: 0.2,
            rerun: Some(path.clone()),
        };
        let s = run(&options).unwrap();
        assert!(s.max_penetration > 0.0, "the block has not landed");
        let size = std::fs::metadata(&path).unwrap().len();
        assert!(size > 10_000, "{size} bytes recorded");
    }
}
