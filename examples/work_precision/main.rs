//! Work-precision on the bar impact of `examples/bar_impact.rs` (issue 13, item 4): the error
//! in contact duration, mean contact force and energy against wall time, for softway at steps
//! from 1x to 50x the explicit stable step, against two baselines written here on the same
//! discretisation, run in the same process (machine drift cancels in the ratios).
//!
//! The bar: steel, L = 1 m, E = 200 GPa, rho = 8000 kg/m^3, nu = 0 (a one-dimensional rod,
//! c = sqrt(E / rho) = 5000 m/s), 100 x 1 Quad4 cells in plane strain (A = 0.1 m^2 per metre),
//! v0 = 1 m/s towards a rigid wall 0.1 mm away. Analytic: contact for 2 L / c = 0.4 ms with the
//! force rho c v0 A = 4 MN, then the bar leaves with all its energy.
//!
//! The explicit stable step: `h_crit = l_e / c` = 2 microseconds (l_e = L / 100, the
//! lumped-mass linear rod element's `2 / omega_max`). The program also prints the measured
//! `2 / omega_max` of the lumped 2D mesh (power iteration, checked within 2 % of it; measured
//! +0.01 %): the central-difference run at 0.9 h_crit is inside it.
//!
//! The runs, each from the same mesh (`softway::prelude::rectangle`) and material:
//! * softway (the library, every contact method, the soft way with zeta = 1e5 E / L as in
//!   `bar_impact`) at h = k h_crit, k in {1, 2, 5, 10, 20, 50}; alpha = 0.75, beta = 0.25 (the
//!   default scheme), consistent mass (the default).
//! * central difference (explicit), lumped mass (row sums of the library's consistent mass
//!   matrix), stiffness from the library (`Simulation::stiffness_matrix`), at 0.9 h_crit;
//!   contact as a kinematic constraint: a wall node whose predicted position goes through the
//!   wall is put back on it, its velocity corrected, and the force that does it in one step,
//!   `m_i p / h^2`, is the contact force (the forward-increment Lagrange multiplier of Carpenter,
//!   Taylor and Katona 1991, exact for a lumped mass).
//! * Newmark average acceleration (trapezoidal rule, implicit, gamma = 1/2, beta = 1/4) on the
//!   library's consistent mass and stiffness at the same k as softway; the same kinematic
//!   contact: a Lagrange multiplier per wall node holding it on the wall at the end of the step,
//!   with an active set (tensile multipliers released, penetrating nodes added), through the
//!   Schur complement of the factored `4 M / h^2 + K` (a banded Cholesky, nodes ordered along
//!   the bar). After the step the held nodes' normal velocity and acceleration are set to the
//!   wall's (zero), as implicit projection does: the trapezoidal rule under a position
//!   constraint alone flips the held node's velocity every step (`v1 = 2 (u1 - u0) / h - v0`)
//!   and pumps energy in at the release; that variant is also run ("Newmark, position only")
//!   to show it.
//!
//! Measured per run: wall time (median of `--reps` repetitions, taken in rounds over every
//! run so that a burst of load spreads over the sides; `std::time::Instant`; the
//! stepping only, with softway's first factorisation and the baselines' factorisation inside,
//! the assembly of M and K outside for every side), the contact duration (steps with a wall
//! force times h) against 2 L / c, the mean wall force over the contact steps (the first and
//! last left out: partly open; all of them below three steps) against rho c v0 A, the energy at
//! the end against the initial kinetic energy (central difference: the invariant it keeps in
//! free flight, `v_{n+1/2}^T M v_{n+1/2} / 2 + u_n^T K u_{n+1} / 2`), and the exit velocity of
//! the centre of mass against -v0.
//!
//! Printed: the table, the time ratios of softway to Newmark at the same k and at equal error
//! (Newmark's time interpolated log-log at softway's error), and to central difference.
//! Drawn: `book/src/images/work_precision.svg` (or `--svg FILE`): error against wall time,
//! log-log, duration and force.
//!
//! Run: `cargo run --release --example work_precision [-- --reps 7] [--svg FILE.svg]` (the
//! book's figures: `cargo run --release --no-default-features --features parallel --example
//! work_precision -- --reps 7`, the same program without building the unused `rerun`
//! recorder; the book's Performance chapter has them and why softway loses here).
//! Its test (a few runs, the physics checked, the figure drawn to a temporary file):
//! `cargo test --example work_precision`.

// `!(error <= bound)` is deliberate: a NaN fails the check too.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod baselines;
#[path = "../common/mod.rs"]
mod common;

use std::path::{Path, PathBuf};
use std::time::Instant;

use baselines::{central_difference, newmark, Discrete};
use common::median;
use common::run::{conclude, Args, Failure};
use nalgebra::Vector2;
use softway::prelude::*;

/// Length [m], height [m] (the section per metre of thickness), Young's modulus [Pa], density
/// [kg/m^3], initial velocity [m/s] and initial gap to the wall [m]: `bar_impact`'s.
const L: f64 = 1.0;
const HEIGHT: f64 = 0.1;
const E: f64 = 200e9;
const RHO: f64 = 8000.0;
const V0: f64 = 1.0;
const GAP: f64 = 1e-4;
/// Cells along the bar.
const CELLS: usize = 100;
/// The step multiples of h_crit for softway and Newmark.
const KS: [f64; 6] = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0];
/// Central difference runs at this fraction of h_crit.
const CD_FACTOR: f64 = 0.9;
/// Errors drawn on the log axes are clamped to this (an exact 0 has no logarithm: the quantised
/// duration often lands on 2 L / c).
const ERROR_FLOOR: f64 = 1e-3;

/// The softway contact methods, the default (implicit projection) first.
const METHODS: [ContactMethod; 4] = [
    ContactMethod::ImplicitProjection,
    ContactMethod::SoftWay,
    ContactMethod::AugmentedLagrangian,
    ContactMethod::ExplicitProjection,
];

fn wave_speed() -> f64 {
    (E / RHO).sqrt()
}

/// The explicit stable step of the lumped-mass linear rod: `l_e / c`.
fn h_crit() -> f64 {
    L / CELLS as f64 / wave_speed()
}

/// Simulated time for a step h: up to the release, and as long again as the gap takes to close
/// after it (`bar_impact`'s).
fn end_time(h: f64) -> f64 {
    GAP / V0 + 2.0 * L / wave_speed() + GAP / V0 + 10.0 * h
}

fn analytic_duration() -> f64 {
    2.0 * L / wave_speed()
}

fn analytic_force() -> f64 {
    RHO * wave_speed() * V0 * HEIGHT
}

/// Which integrator a run used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scheme {
    Softway(ContactMethod),
    CentralDifference,
    Newmark,
    /// Newmark with the position constraint alone (no velocity reset of the held nodes).
    NewmarkPositionOnly,
}

impl Scheme {
    fn label(self) -> String {
        match self {
            Scheme::Softway(m) => format!("softway {}", m.name()),
            Scheme::CentralDifference => "central difference".into(),
            Scheme::Newmark => "Newmark avg. accel.".into(),
            Scheme::NewmarkPositionOnly => "Newmark, position only".into(),
        }
    }
}

/// What one run measured.
#[derive(Debug, Clone, Copy)]
struct Outcome {
    /// Contact duration [s]: steps with a wall force times h.
    duration: f64,
    /// Mean wall force over the contact steps (first and last left out when three or more) [N].
    force: f64,
    /// Energy at the end over the initial kinetic energy.
    energy_ratio: f64,
    /// Velocity of the centre of mass at the end [m/s].
    exit_velocity: f64,
    steps: usize,
    /// Newton iterations per step (softway only).
    iterations: Option<f64>,
}

impl Outcome {
    /// From the wall force of every step [N] (0: no contact).
    fn from_forces(forces: &[f64], h: f64, energy_ratio: f64, exit_velocity: f64) -> Outcome {
        let touching: Vec<usize> = (0..forces.len()).filter(|&i| forces[i] != 0.0).collect();
        let (duration, force) = match (touching.first(), touching.last()) {
            (Some(&first), Some(&last)) => {
                let inner = if last - first + 1 >= 3 {
                    &forces[first + 1..last]
                } else {
                    &forces[first..=last]
                };
                let contact: Vec<f64> = inner.iter().copied().filter(|&f| f != 0.0).collect();
                let mean = contact.iter().sum::<f64>() / contact.len().max(1) as f64;
                ((last - first + 1) as f64 * h, mean)
            }
            _ => (0.0, 0.0),
        };
        Outcome {
            duration,
            force,
            energy_ratio,
            exit_velocity,
            steps: forces.len(),
            iterations: None,
        }
    }

    fn duration_error(&self) -> f64 {
        self.duration / analytic_duration() - 1.0
    }
    fn force_error(&self) -> f64 {
        self.force / analytic_force() - 1.0
    }
    fn energy_error(&self) -> f64 {
        self.energy_ratio - 1.0
    }
    fn exit_error(&self) -> f64 {
        self.exit_velocity / -V0 - 1.0
    }
    /// The larger of the duration and force errors (what "equal error" compares).
    fn error(&self) -> f64 {
        self.duration_error().abs().max(self.force_error().abs())
    }
}

/// One run: its integrator, step and what it measured, or why it failed.
#[derive(Debug, Clone)]
struct Run {
    scheme: Scheme,
    /// h / h_crit.
    k: f64,
    h: f64,
    /// Median wall time of the stepping [s].
    seconds: f64,
    outcome: Result<Outcome, String>,
}

/// The bar and the wall, as `bar_impact` builds them.
fn bar(method: ContactMethod, h: f64) -> Result<Simulation2> {
    let mesh = rectangle(
        Vector2::zeros(),
        Vector2::new(L, HEIGHT),
        [CELLS, 1],
        ElementKind::Quad4,
    )?;
    let steel = Material::LinearElastic(LinearElastic::new(E, 0.0, RHO)?);
    let body = Body::new("bar", mesh, steel).with_velocity(Vector2::new(V0, 0.0));
    let wall = Obstacle::new(
        "wall",
        ObstacleShape::Halfspace {
            point: Vector2::new(L + GAP, 0.0),
            normal: Vector2::new(-1.0, 0.0),
        },
    );
    Simulation2::builder()
        .time_step(h)
        .body(body)
        .obstacle(wall)
        .contact(ContactSettings {
            method,
            penalty: 1e5 * E / L, // zeta [Pa/m]
            gap_tolerance: 1e-12,
            ..Default::default()
        })
        .build()
}

/// One softway run; the stepping timed.
fn softway_once(method: ContactMethod, h: f64) -> Result<(Outcome, f64), Failure> {
    let mut sim = bar(method, h)?;
    let e0 = sim.energies().total();
    let ones: Vec<f64> = (0..sim.node_count() * 2)
        .map(|i| ((i + 1) % 2) as f64)
        .collect();
    let mass = sim.mass_matrix().dot(&ones, &ones);
    let end = end_time(h);
    let mut forces = Vec::new();
    let mut iterations = 0;
    let start = Instant::now();
    while sim.state().time < end {
        let report = sim.step()?;
        forces.push(-report.contact_forces[0][0]);
        iterations += report.iterations;
    }
    let seconds = start.elapsed().as_secs_f64();
    let exit = sim.mass_matrix().dot(&ones, &sim.state().velocity) / mass;
    let mut outcome = Outcome::from_forces(&forces, h, sim.energies().total() / e0, exit);
    outcome.iterations = Some(iterations as f64 / forces.len() as f64);
    Ok((outcome, seconds))
}

/// What the program is asked to do.
#[derive(Debug, Clone)]
struct Options {
    /// Repetitions per run (the median time is kept).
    reps: usize,
    /// The step multiples of softway and Newmark.
    ks: Vec<f64>,
    /// The softway methods.
    methods: Vec<ContactMethod>,
    /// Where to draw the SVG; `None`: nothing drawn.
    svg: Option<PathBuf>,
}

/// Everything measured.
#[derive(Debug, Clone)]
struct Summary {
    runs: Vec<Run>,
    /// `2 / omega_max` of the lumped 2D mesh [s].
    lumped_stable_step: f64,
}

/// One run of one job: what it measured and the seconds it took.
type Job<'a> = Box<dyn Fn() -> Result<(Outcome, f64), Failure> + 'a>;

/// A baseline's run, timed as a whole.
fn baseline<'a>(f: impl Fn() -> Outcome + 'a) -> Job<'a> {
    Box::new(move || {
        let start = Instant::now();
        let o = f();
        Ok((o, start.elapsed().as_secs_f64()))
    })
}

fn run(options: &Options) -> Result<Summary, Failure> {
    let d = Discrete::new()?;
    let hc = h_crit();
    // Every run, then `reps` rounds over all of them: a burst of the machine's load lands on
    // one repetition of several runs, not on every repetition of one (the median drops it).
    let mut jobs: Vec<(Scheme, f64, f64, Job)> = Vec::new();
    let h = CD_FACTOR * hc;
    let d = &d;
    let cd = baseline(move || central_difference(d, h));
    jobs.push((Scheme::CentralDifference, CD_FACTOR, h, cd));
    for &k in &options.ks {
        let h = k * hc;
        for (scheme, reset) in [
            (Scheme::Newmark, true),
            (Scheme::NewmarkPositionOnly, false),
        ] {
            jobs.push((scheme, k, h, baseline(move || newmark(d, h, reset))));
        }
        for &method in &options.methods {
            jobs.push((
                Scheme::Softway(method),
                k,
                h,
                Box::new(move || softway_once(method, h)),
            ));
        }
    }
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); jobs.len()];
    let mut outcomes: Vec<Result<Outcome, String>> = vec![Err("not run".into()); jobs.len()];
    for _ in 0..options.reps.max(1) {
        for (i, (_, _, _, job)) in jobs.iter().enumerate() {
            if outcomes[i].is_err() && !times[i].is_empty() {
                continue;
            }
            match job() {
                Ok((o, seconds)) => {
                    times[i].push(seconds);
                    outcomes[i] = Ok(o);
                }
                Err(e) => {
                    times[i].push(f64::NAN);
                    outcomes[i] = Err(e.to_string());
                }
            }
        }
    }
    let runs = jobs
        .iter()
        .zip(times)
        .zip(outcomes)
        .map(|(((scheme, k, h, _), times), outcome)| Run {
            scheme: *scheme,
            k: *k,
            h: *h,
            seconds: if outcome.is_ok() {
                median(times)
            } else {
                f64::NAN
            },
            outcome,
        })
        .collect();
    let summary = Summary {
        runs,
        lumped_stable_step: d.lumped_stable_step(),
    };
    if let Some(path) = &options.svg {
        draw(&summary, path)?;
    }
    Ok(summary)
}

impl Summary {
    fn find(&self, scheme: Scheme, k: f64) -> Option<(&Run, Outcome)> {
        self.runs
            .iter()
            .find(|r| r.scheme == scheme && r.k == k)
            .and_then(|r| r.outcome.clone().ok().map(|o| (r, o)))
    }

    /// The schemes present, in order of first appearance.
    fn schemes(&self) -> Vec<Scheme> {
        let mut out: Vec<Scheme> = Vec::new();
        for r in &self.runs {
            if !out.contains(&r.scheme) {
                out.push(r.scheme);
            }
        }
        out
    }

    /// Newmark's wall time at error `e`, interpolated log-log between its runs (`None` outside
    /// their range).
    fn newmark_time_at(&self, e: f64) -> Option<f64> {
        let mut points: Vec<(f64, f64)> = self
            .runs
            .iter()
            .filter(|r| r.scheme == Scheme::Newmark)
            .filter_map(|r| Some((r.outcome.as_ref().ok()?.error(), r.seconds)))
            .filter(|(e, _)| *e > 0.0)
            .collect();
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        points.windows(2).find_map(|w| {
            let ((e0, t0), (e1, t1)) = (w[0], w[1]);
            (e0 <= e && e <= e1 && e1 > e0).then(|| {
                let s = (e / e0).ln() / (e1 / e0).ln();
                (t0.ln() + s * (t1 / t0).ln()).exp()
            })
        })
    }
}

fn print(s: &Summary) {
    let hc = h_crit();
    println!(
        "work_precision: bar impact, {CELLS} x 1 Quad4, h_crit = l_e / c = {hc:.4e} s; measured \
         2 / omega_max of the lumped mesh {:.4e} s ({:+.2} %)",
        s.lumped_stable_step,
        100.0 * (s.lumped_stable_step / hc - 1.0)
    );
    println!(
        "analytic: duration 2 L / c = {:.4e} s, force rho c v0 A = {:.4e} N",
        analytic_duration(),
        analytic_force()
    );
    println!();
    println!(
        "| scheme | k = h / h_crit | steps | wall time [ms] | duration error | force error | energy error | exit velocity error | Newton iterations / step |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for r in &s.runs {
        match &r.outcome {
            Ok(o) => println!(
                "| {} | {} | {} | {:.3} | {:+.3} % | {:+.3} % | {:+.3} % | {:+.3} % | {} |",
                r.scheme.label(),
                r.k,
                o.steps,
                1e3 * r.seconds,
                100.0 * o.duration_error(),
                100.0 * o.force_error(),
                100.0 * o.energy_error(),
                100.0 * o.exit_error(),
                o.iterations.map_or("-".into(), |i| format!("{i:.2}"))
            ),
            Err(e) => println!(
                "| {} | {} | - | - | failed: {} | | | | |",
                r.scheme.label(),
                r.k,
                e.replace('\n', " ")
            ),
        }
    }
    println!();
    println!(
        "error = max(|duration error|, |force error|); ratios are softway's time over the baseline's"
    );
    println!(
        "| softway method | k | error | time / Newmark same k (its error) | time / Newmark at equal error | time / central difference (its error) |"
    );
    println!("|---|---|---|---|---|---|");
    let cd = s.find(Scheme::CentralDifference, CD_FACTOR);
    for scheme in s.schemes() {
        let Scheme::Softway(method) = scheme else {
            continue;
        };
        for r in s.runs.iter().filter(|r| r.scheme == scheme) {
            let Ok(o) = &r.outcome else { continue };
            let same = s
                .find(Scheme::Newmark, r.k)
                .map(|(n, no)| {
                    format!("{:.2} ({:.3} %)", r.seconds / n.seconds, 100.0 * no.error())
                })
                .unwrap_or_else(|| "-".into());
            let equal = s
                .newmark_time_at(o.error())
                .map(|t| format!("{:.2}", r.seconds / t))
                .unwrap_or_else(|| "outside Newmark's range".into());
            let vs_cd = cd
                .map(|(c, co)| {
                    format!("{:.2} ({:.3} %)", r.seconds / c.seconds, 100.0 * co.error())
                })
                .unwrap_or_else(|| "-".into());
            println!(
                "| {} | {} | {:.3} % | {} | {} | {} |",
                method.name(),
                r.k,
                100.0 * o.error(),
                same,
                equal,
                vs_cd
            );
        }
    }
}

/// Draws error against wall time, log-log: contact duration (top) and mean force (bottom).
fn draw(s: &Summary, path: &Path) -> Result<(), Failure> {
    use plotters::prelude::*;

    let colors = [
        RGBColor(0x1f, 0x77, 0xb4),
        RGBColor(0xd6, 0x27, 0x28),
        RGBColor(0x2c, 0xa0, 0x2c),
        RGBColor(0x94, 0x67, 0xbd),
        RGBColor(0xff, 0x7f, 0x0e),
        RGBColor(0x00, 0x00, 0x00),
        RGBColor(0x8c, 0x8c, 0x8c),
    ];
    let schemes = s.schemes();
    let ok: Vec<(&Run, Outcome)> = s
        .runs
        .iter()
        .filter_map(|r| Some((r, r.outcome.clone().ok()?)))
        .filter(|(r, _)| r.seconds > 0.0)
        .collect();
    if ok.is_empty() {
        return Err("no run to draw".into());
    }
    let t_lo = ok
        .iter()
        .map(|(r, _)| r.seconds)
        .fold(f64::INFINITY, f64::min)
        / 1.5;
    // Room on the right for the legend.
    let t_hi = ok.iter().map(|(r, _)| r.seconds).fold(0.0, f64::max) * 60.0;
    let root = SVGBackend::new(path, (900, 1000)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(500);
    type Measure = fn(&Outcome) -> f64;
    let panels: [(&_, &str, Measure); 2] = [
        (&top, "contact duration error vs 2L/c", |o| {
            o.duration_error()
        }),
        (&bottom, "mean contact force error vs ρ c v0 A", |o| {
            o.force_error()
        }),
    ];
    for (area, title, measure) in panels {
        let value = |o: &Outcome| measure(o).abs().max(ERROR_FLOOR);
        let e_hi = ok.iter().map(|(_, o)| value(o)).fold(ERROR_FLOOR, f64::max) * 3.0;
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!("Bar impact: |{title}| against wall time (k = h / h_crit marked)"),
                ("sans-serif", 20),
            )
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(65)
            .build_cartesian_2d(
                (t_lo..t_hi).log_scale(),
                (ERROR_FLOOR / 2.0..e_hi).log_scale(),
            )?;
        chart
            .configure_mesh()
            .x_desc("wall time of the run [s] (median)")
            .y_desc(format!("relative error (floor {ERROR_FLOOR:.0e})"))
            .x_label_formatter(&|t| format!("{t:.0e}"))
            .y_label_formatter(&|e| format!("{e:.0e}"))
            .draw()?;
        for (i, scheme) in schemes.iter().enumerate() {
            let color = colors[i % colors.len()];
            let mut points: Vec<(f64, f64, f64)> = ok
                .iter()
                .filter(|(r, _)| r.scheme == *scheme)
                .map(|(r, o)| (r.seconds, value(o), r.k))
                .collect();
            points.sort_by(|a, b| a.2.total_cmp(&b.2));
            let style = color.stroke_width(2);
            chart
                .draw_series(LineSeries::new(points.iter().map(|p| (p.0, p.1)), style))?
                .label(scheme.label())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], style));
            chart.draw_series(
                points
                    .iter()
                    .map(|p| Circle::new((p.0, p.1), 4, color.filled())),
            )?;
            // k next to the points of the baselines, the default method and the soft way.
            if matches!(
                scheme,
                Scheme::Softway(ContactMethod::SoftWay | ContactMethod::ImplicitProjection)
                    | Scheme::Newmark
                    | Scheme::CentralDifference
            ) {
                chart.draw_series(points.iter().map(|p| {
                    Text::new(
                        format!("{}", p.2),
                        (p.0, p.1),
                        ("sans-serif", 13).into_font().color(&color),
                    )
                }))?;
            }
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .draw()?;
    }
    root.present()?;
    Ok(())
}

/// The physics the figures rest on; `Err` says what failed.
fn check(s: &Summary) -> Result<(), String> {
    let mut failed = Vec::new();
    let mut expect = |ok: bool, what: String| {
        if !ok {
            failed.push(what);
        }
    };
    for r in &s.runs {
        let Ok(o) = &r.outcome else {
            expect(
                !matches!(r.scheme, Scheme::Softway(_)) || r.k > 1.0,
                format!("{} at k = {} failed", r.scheme.label(), r.k),
            );
            continue;
        };
        let label = format!("{} at k = {}", r.scheme.label(), r.k);
        let within =
            |bound: f64| o.duration_error().abs() <= bound && o.force_error().abs() <= bound;
        match r.scheme {
            // softway and Newmark at the explicit stable step: within 1 % (two steps of the
            // duration; round-off allowed).
            Scheme::Softway(_) | Scheme::Newmark if r.k == 1.0 => expect(
                within(0.01 + 1e-9),
                format!(
                    "{label}: duration {:+.3} %, force {:+.3} % (1 % expected)",
                    100.0 * o.duration_error(),
                    100.0 * o.force_error()
                ),
            ),
            // Central difference: two steps of the duration (0.9 %) and 1 % on the force.
            Scheme::CentralDifference => expect(
                o.duration_error().abs() <= 2.01 * r.h / analytic_duration()
                    && o.force_error().abs() <= 0.01,
                format!(
                    "{label}: duration {:+.3} %, force {:+.3} %",
                    100.0 * o.duration_error(),
                    100.0 * o.force_error()
                ),
            ),
            _ => {}
        }
    }
    // The errors grow with k: the largest k is worse than k = 1 for the soft way and Newmark.
    let largest = s.runs.iter().map(|r| r.k).fold(0.0, f64::max);
    for scheme in [Scheme::Softway(ContactMethod::SoftWay), Scheme::Newmark] {
        if let (Some((_, small)), Some((_, big))) = (s.find(scheme, 1.0), s.find(scheme, largest)) {
            expect(
                largest == 1.0 || big.error() > small.error(),
                format!(
                    "{}: error {:.3e} at k = {largest}, not above {:.3e} at k = 1",
                    scheme.label(),
                    big.error(),
                    small.error()
                ),
            );
        }
    }
    expect(
        (s.lumped_stable_step / h_crit() - 1.0).abs() < 0.02
            && CD_FACTOR * h_crit() < s.lumped_stable_step,
        format!(
            "lumped stable step {:.4e} s against l_e / c = {:.4e} s",
            s.lumped_stable_step,
            h_crit()
        ),
    );
    if failed.is_empty() {
        Ok(())
    } else {
        Err(failed.join("\n"))
    }
}

fn main() -> std::process::ExitCode {
    let usage = "usage: work_precision [--reps N (default 5)] [--svg FILE.svg] (default: the \
                 book's book/src/images/work_precision.svg)";
    let default_svg =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("book/src/images/work_precision.svg");
    let options = Args::parse(&["--reps", "--svg"], usage).and_then(|args| {
        if args.get::<String>("--rerun")?.is_some() {
            return Err("work_precision records nothing: `--rerun` is not an option here".into());
        }
        Ok(Options {
            reps: args.get("--reps")?.unwrap_or(5),
            ks: KS.to_vec(),
            methods: METHODS.to_vec(),
            svg: Some(args.get("--svg")?.unwrap_or(default_svg)),
        })
    });
    let outcome = options.and_then(|o| run(&o).map(|s| (o, s)));
    let print_and_name = |(o, s): &(Options, Summary)| {
        print(s);
        if let Some(svg) = &o.svg {
            println!("drew {}", svg.display());
        }
    };
    conclude("work_precision", outcome, print_and_name, |(_, s)| check(s))
}

#[cfg(test)]
mod tests {
    use super::*;
    use baselines::Band;

    /// A short version: the soft way and the default method at k = 1, 5 and 50, the baselines,
    /// once each; the physics checked and the figure drawn to a temporary file.
    #[test]
    fn work_precision_physics_and_figure() {
        let dir = tempfile::tempdir().unwrap();
        let svg = dir.path().join("work_precision.svg");
        let s = run(&Options {
            reps: 1,
            ks: vec![1.0, 5.0, 50.0],
            methods: vec![ContactMethod::ImplicitProjection, ContactMethod::SoftWay],
            svg: Some(svg.clone()),
        })
        .unwrap();
        print(&s);
        check(&s).unwrap();
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.starts_with("<svg"));
        assert!(text.contains("central difference"));
    }

    /// The banded Cholesky against the dense solve of the same matrix.
    #[test]
    fn band_solve_matches_dense() {
        let d = Discrete::new().unwrap();
        let a = 1e12;
        let band = Band::factor(&d, a);
        let n = d.mass.n;
        let dense = d.mass.clone();
        let b: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
        let mut x = vec![0.0; n];
        let mut work = vec![0.0; n];
        band.solve(&b, &mut x, &mut work);
        let mut mx = vec![0.0; n];
        let mut kx = vec![0.0; n];
        dense.mul_into(&x, &mut mx);
        d.stiffness.mul_into(&x, &mut kx);
        let residual = (0..n)
            .map(|i| (a * mx[i] + kx[i] - b[i]).abs())
            .fold(0.0, f64::max);
        assert!(residual < 1e-9, "residual {residual}");
    }
}
