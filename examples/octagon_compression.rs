//! The paper's example 2 (Bajer & Bohatier 1995, Fig. 10-11): a quarter of an octagonal domain
//! compressed at v = 0.1 m/s by a rigid die, Norton-Hoff (m = 0.1, K = 1 Pa s^0.1) without
//! inertia (rho = 0: each step is a quasi-static viscous flow), h = 1 s, 30 increments,
//! viscoplastic friction `T = -0.05 |v_t|^(m - 1) v_t` on the die. The scene is the bundled
//! `fixtures/scenes/octagon_compression.toml` (its header states the sizes and units the paper
//! leaves out), loaded with `softway::io::scene::load` as the command line loads it.
//!
//! Checked at the end (exit status 1 and what failed otherwise):
//! * the flow keeps the volume: the billet's area within 2 % of its start. The bulk penalty
//!   (1e3 Pa s, 1e3 K) lets a pressure p change the volume at the rate p / 1e3 per second, and p
//!   is of the order of the flow stress (1.6 to 1.7 Pa): up to 5e-2 over the 30 s if it never
//!   relaxed (measured: -0.42 % after 10 increments, -1.45 % after 30);
//! * the die's force lies between the plane-strain flow stress `2 K (2 v / H)^m` times the
//!   contact width (the die's flat, 4.14 m at the start, and what spreads under it) and times
//!   the billet's full width (10 m): friction and the shape raise it above the first, the
//!   free sides keep it below the second;
//! * the energy account (the die's work against the dissipation of the flow and of friction)
//!   within 2 % of its reference;
//! * the equivalent strain (the paper's Fig. 11 plots it) concentrates: the largest cell value
//!   is at least twice the mean, and the mean lies below the homogeneous compression's
//!   `ln(H0 / H)` (the dead zone under the die's middle and the corner the die never reaches
//!   barely flow; the band from the die's edge to the billet's centre takes the strain, the
//!   centre most).
//!
//! Printed: Newton iterations per step against the paper's 5 to 8.
//!
//! `--figure FILE.svg` draws the end's deformed mesh, every cell filled with its equivalent
//! strain on a viridis-like colour map, the undeformed outline and the die's face (the book's
//! `book/src/images/octagon_strain.svg`, the paper's Fig. 11).
//!
//! Run: `cargo run --features formats --example octagon_compression [-- --end-time 30]
//! [--set contact.method="augmented_lagrangian"] [--rerun octagon.rrd] [--figure FILE.svg]`
//! (the whole scene, 30 increments, by default; under a second in release). The VTK frames with the equivalent
//! strain as cell data: `softway run fixtures/scenes/octagon_compression.toml --out octagon`.
//! Its test, the first 10 increments: `cargo test --features formats --example
//! octagon_compression`.

// `!(error <= bound)` is deliberate: a NaN fails the check too.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod common;

use std::path::{Path, PathBuf};

use common::run::{conclude, Args, Failure, Recording};
use softway::prelude::*;

/// The die's speed [m/s] and the billet's initial height [m] (the scene's).
const DIE_SPEED: f64 = 0.1;
const HEIGHT: f64 = 10.0;
/// Norton-Hoff's K [Pa s^m] and m (the scene's).
const CONSISTENCY: f64 = 1.0;
const EXPONENT: f64 = 0.1;

/// What the example is asked to do.
#[derive(Debug, Clone)]
struct Options {
    /// Simulated time [s] (the scene's `simulation.end_time`; one increment per second).
    end_time: f64,
    /// Scene overrides, `KEY=VALUE` as `softway run --set` takes them.
    overrides: Vec<String>,
    /// Record every solver iteration to this Rerun file.
    rerun: Option<PathBuf>,
    /// Draw the end's deformed mesh coloured by the equivalent strain into this SVG file.
    figure: Option<PathBuf>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            end_time: 30.0,
            overrides: Vec::new(),
            rerun: None,
            figure: None,
        }
    }
}

/// What the run measured.
#[derive(Debug, Clone)]
struct Summary {
    /// Newton iterations of every step.
    iterations: Vec<usize>,
    /// The billet's height at the end [m].
    height: f64,
    /// Relative change of the billet's area.
    area_change: f64,
    /// The die's force on the billet at the last step [N per metre of thickness].
    die_force: f64,
    /// The contact width at the end [m].
    contact_width: f64,
    /// The plane-strain flow stress at the end's strain rate [Pa].
    flow_stress: f64,
    /// `(E - E(0) - W + D) / reference` at the end.
    energy_account: f64,
    /// The cells' equivalent strain: smallest, mean (by cell), largest.
    strain: (f64, f64, f64),
    /// The figure drawn, if asked for.
    figure: Option<PathBuf>,
}

fn scene_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/octagon_compression.toml")
}

fn area(sim: &Simulation2) -> f64 {
    let mut mesh = sim.model().bodies[0].mesh.clone();
    mesh.nodes = sim.positions();
    softway::mesh::generators::measure(&mesh)
}

fn run(options: &Options) -> Result<Summary, Failure> {
    let mut overrides = vec![format!("simulation.end_time={}", options.end_time)];
    overrides.extend(options.overrides.iter().cloned());
    let scene = softway::io::scene::load(&scene_path(), &overrides)?.build::<2>()?;
    let mut sim = scene.simulation()?;
    let mut recording = Recording::new(options.rerun.as_deref(), &scene.obstacles)?;
    for probe in &scene.probes {
        recording = recording.with_probe(&probe.name, BodyId::initial(probe.body), probe.node);
    }
    let area0 = area(&sim);
    let mut iterations = Vec::new();
    let mut die_force = 0.0;
    while sim.state().time < scene.end_time - 1e-9 {
        let report = sim.step_with(recording.recorder())?;
        iterations.push(report.iterations);
        die_force = -report.contact_forces[0][1]; // obstacle 0 (the die), pushing down
    }
    recording.finish()?;

    let height = HEIGHT - DIE_SPEED * sim.state().time;
    // The contact width: the nodes on the die's plane (the top's flat and what spread).
    let contact_width = sim
        .positions()
        .iter()
        .filter(|p| p.y > height - 1e-3)
        .map(|p| p.x)
        .fold(0.0, f64::max);
    let strains = sim.cell_equivalent_strains();
    let mean = strains.iter().sum::<f64>() / strains.len() as f64;
    let low = strains.iter().copied().fold(f64::INFINITY, f64::min);
    let high = strains.iter().copied().fold(0.0, f64::max);
    if let Some(path) = &options.figure {
        draw(&sim, &strains, height, path)?;
    }
    let e = sim.energies();
    Ok(Summary {
        iterations,
        height,
        area_change: area(&sim) / area0 - 1.0,
        die_force,
        contact_width,
        flow_stress: 2.0 * CONSISTENCY * (2.0 * DIE_SPEED / height).powf(EXPONENT),
        energy_account: (e.total() - sim.initial_energy() - e.external_work + e.dissipated)
            / sim.energy_reference(),
        strain: (low, mean, high),
        figure: options.figure.clone(),
    })
}

/// Viridis at 0, 1/8, .., 1 (matplotlib's, as R's `viridis(9)` lists it): perceptually
/// uniform and readable in grey, without plotters' `colormaps` feature.
const VIRIDIS: [(u8, u8, u8); 9] = [
    (0x44, 0x01, 0x54),
    (0x47, 0x2d, 0x7b),
    (0x3b, 0x52, 0x8b),
    (0x2c, 0x72, 0x8e),
    (0x21, 0x90, 0x8c),
    (0x27, 0xad, 0x81),
    (0x5d, 0xc8, 0x63),
    (0xaa, 0xdc, 0x32),
    (0xfd, 0xe7, 0x25),
];

/// The colour of `t` in 0..1 (clamped), linear between the anchors.
fn viridis(t: f64) -> plotters::style::RGBColor {
    let s = t.clamp(0.0, 1.0) * (VIRIDIS.len() - 1) as f64;
    let i = (s.floor() as usize).min(VIRIDIS.len() - 2);
    let f = s - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |x: u8, y: u8| (x as f64 + f * (y as f64 - x as f64)).round() as u8;
    plotters::style::RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// Draws the billet's cells at their current positions, filled by `strains` (one per cell,
/// the mesh's order), over the undeformed outline, with the die's face at `die` [m] and a
/// colour bar.
fn draw(sim: &Simulation2, strains: &[f64], die: f64, path: &Path) -> Result<(), Failure> {
    use plotters::prelude::*;

    let mesh = &sim.model().bodies[0].mesh;
    let (x0, x) = (&mesh.nodes, sim.positions());
    let finite = || strains.iter().copied().filter(|e| e.is_finite());
    let low = finite().fold(f64::INFINITY, f64::min);
    let low = if low.is_finite() { low } else { 0.0 };
    // A uniform field (the first step) still needs a range to map.
    let high = finite().fold(low, f64::max).max(low + 1e-9);
    let colour = |e: f64| {
        if e.is_finite() {
            viridis((e - low) / (high - low))
        } else {
            RGBColor(0x99, 0x99, 0x99) // an inverted cell
        }
    };

    let all = || x0.iter().chain(x.iter());
    let x_hi = all().fold(0.0f64, |m, p| m.max(p.x)) * 1.04;
    let y_hi = all().fold(die, |m, p| m.max(p.y)) * 1.04;
    // Equal scales: the plot area's width follows the ranges at a fixed height (the margins
    // are 15 px a side; the colour bar takes what the title's exact height leaves over).
    let (plot_h, label_w, label_h, bar_w) = (640.0, 50.0, 45.0, 130.0);
    let width = (plot_h * x_hi / y_hi + label_w + 30.0 + bar_w).ceil() as u32;
    let height = (plot_h + label_h + 30.0).ceil() as u32 + 40;
    let root = SVGBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(
        &format!(
            "Equivalent strain at t = {:.0} s ({:.0} % reduction): {low:.3} to {high:.3}",
            sim.state().time,
            100.0 * (1.0 - die / HEIGHT)
        ),
        ("sans-serif", 18),
    )?;
    let plot_h = root.dim_in_pixel().1 as f64 - label_h - 30.0;
    let plot_w = plot_h * x_hi / y_hi;
    let (left, right) = root.split_horizontally((plot_w + label_w + 30.0).round() as u32);

    let mut chart = ChartBuilder::on(&left)
        .margin(15)
        .x_label_area_size(label_h as u32)
        .y_label_area_size(label_w as u32)
        .build_cartesian_2d(0.0..x_hi, 0.0..y_hi)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x [m]")
        .y_desc("y [m]")
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 16))
        .draw()?;
    let point = |p: &nalgebra::Vector2<f64>| (p.x, p.y);
    let edge = BLACK.mix(0.6).stroke_width(1);
    let mut c = 0;
    for block in &mesh.blocks {
        for cell in block.cells() {
            // Quad4 and Tri3: the corners in order.
            let corners: Vec<(f64, f64)> = cell.iter().map(|&n| point(&x[n])).collect();
            chart.draw_series(std::iter::once(Polygon::new(
                corners.clone(),
                colour(strains[c]).filled(),
            )))?;
            let mut closed = corners;
            closed.push(closed[0]);
            chart.draw_series(std::iter::once(PathElement::new(closed, edge)))?;
            c += 1;
        }
    }
    // The undeformed outline: the edges of one cell only.
    let mut edges: std::collections::BTreeMap<(usize, usize), usize> = Default::default();
    for cell in mesh.blocks.iter().flat_map(|b| b.cells()) {
        for e in 0..cell.len() {
            let (a, b) = (cell[e], cell[(e + 1) % cell.len()]);
            *edges.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let grey = RGBColor(0x88, 0x88, 0x88).stroke_width(1);
    for (&(a, b), _) in edges.iter().filter(|(_, &n)| n == 1) {
        chart.draw_series(DashedLineSeries::new(
            [point(&x0[a]), point(&x0[b])],
            4,
            3,
            grey,
        ))?;
    }
    // The die's face.
    chart.draw_series(LineSeries::new(
        [(0.0, die), (x_hi, die)],
        BLACK.stroke_width(3),
    ))?;

    // The colour bar: thin bands from low to high, labelled on its right.
    let mut bar = ChartBuilder::on(&right)
        .margin(15)
        .margin_left(10)
        .x_label_area_size(label_h as u32)
        .right_y_label_area_size(60)
        .build_cartesian_2d(0.0..1.0, low..high)?;
    bar.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_labels(8)
        .y_label_formatter(&|e| format!("{e:.2}"))
        .y_desc("equivalent strain")
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 16))
        .draw()?;
    let bands = 200;
    bar.draw_series((0..bands).map(|k| {
        let (a, b) = (k as f64 / bands as f64, (k + 1) as f64 / bands as f64);
        let (e0, e1) = (low + a * (high - low), low + b * (high - low));
        Rectangle::new([(0.0, e0), (1.0, e1)], viridis((a + b) / 2.0).filled())
    }))?;
    root.present()?;
    Ok(())
}

/// The physical checks; `Err` says which failed.
fn check(s: &Summary) -> Result<(), String> {
    let mut failed = Vec::new();
    if !(s.area_change.abs() < 2e-2) {
        failed.push(format!(
            "the area changed by {:+.3} % (more than 2 %)",
            100.0 * s.area_change
        ));
    }
    let (below, above) = (s.flow_stress * s.contact_width, s.flow_stress * HEIGHT);
    if !(s.die_force > below && s.die_force < above) {
        failed.push(format!(
            "the die's force {:.4} N is outside {below:.4} .. {above:.4} N",
            s.die_force
        ));
    }
    if !(s.energy_account.abs() < 2e-2) {
        failed.push(format!(
            "energy account off by {:.3e} of the reference (more than 2e-2)",
            s.energy_account
        ));
    }
    let homogeneous = (HEIGHT / s.height).ln();
    let (_, mean, high) = s.strain;
    if !(high >= 2.0 * mean && mean < homogeneous && mean > 0.0) {
        failed.push(format!(
            "equivalent strain: mean {mean:.3}, largest {high:.3} (homogeneous {homogeneous:.3})"
        ));
    }
    if failed.is_empty() {
        Ok(())
    } else {
        Err(failed.join("\n"))
    }
}

fn print(s: &Summary) {
    let mut sorted = s.iterations.clone();
    sorted.sort_unstable();
    let total: usize = sorted.iter().sum();
    println!(
        "octagon_compression: {} increments, height {:.2} m ({:.0} % reduction)",
        s.iterations.len(),
        s.height,
        100.0 * (1.0 - s.height / HEIGHT)
    );
    println!(
        "  Newton:      {total} iterations, {} to {} per step (median {}; the paper: 5 to 8)",
        sorted.first().unwrap_or(&0),
        sorted.last().unwrap_or(&0),
        sorted.get(sorted.len() / 2).unwrap_or(&0)
    );
    println!(
        "  volume:      area {:+.3} % of the start",
        100.0 * s.area_change
    );
    println!(
        "  die:         {:.4} N per metre, between {:.4} (flow stress x contact width {:.3} m) and \
         {:.4} (x full width)",
        s.die_force,
        s.flow_stress * s.contact_width,
        s.contact_width,
        s.flow_stress * HEIGHT
    );
    println!(
        "  strain:      equivalent {:.3} to {:.3}, mean {:.3} (homogeneous ln(H0/H) = {:.3})",
        s.strain.0,
        s.strain.2,
        s.strain.1,
        (HEIGHT / s.height).ln()
    );
    println!(
        "  energy:      E - E(0) - W + D = {:+.3e} of the reference",
        s.energy_account
    );
    if let Some(figure) = &s.figure {
        println!("  figure:      drew {}", figure.display());
    }
}

fn main() -> std::process::ExitCode {
    let usage = "usage: octagon_compression [--end-time SECONDS] [--set KEY=VALUE]... \
                 [--rerun FILE.rrd] [--figure FILE.svg]";
    let options = Args::parse(&["--end-time", "--set", "--figure"], usage).and_then(|args| {
        Ok(Options {
            end_time: args
                .get("--end-time")?
                .unwrap_or(Options::default().end_time),
            overrides: args.all("--set"),
            rerun: args.rerun()?,
            figure: args.get("--figure")?,
        })
    });
    conclude(
        "octagon_compression",
        options.and_then(|o| run(&o)),
        print,
        check,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first 10 increments (a 10 % reduction), checked as `main` checks the whole run.
    #[test]
    fn first_ten_increments() {
        let s = run(&Options {
            end_time: 10.0,
            ..Options::default()
        })
        .unwrap();
        print(&s);
        check(&s).unwrap();
    }

    /// `--figure FILE` draws the deformed mesh (two increments): one filled polygon per cell.
    #[test]
    fn draws_the_strain_figure() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("octagon_strain.svg");
        let s = run(&Options {
            end_time: 2.0,
            figure: Some(path.clone()),
            ..Options::default()
        })
        .unwrap();
        assert_eq!(s.iterations.len(), 2);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("<svg"), "{}", &text[..80.min(text.len())]);
        // 8 x 8 quads; the colour bar's bands are `<rect`s, the edges `<polyline`s.
        assert_eq!(text.matches("<polygon").count(), 64);
        assert!(text.contains("equivalent strain"));
    }

    /// `--rerun FILE` records the flow (two increments).
    #[cfg(feature = "rerun")]
    #[test]
    fn records_to_rerun() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("octagon.rrd");
        run(&Options {
            end_time: 2.0,
            rerun: Some(path.clone()),
            ..Options::default()
        })
        .unwrap();
        let size = std::fs::metadata(&path).unwrap().len();
        assert!(size > 10_000, "{size} bytes recorded");
    }
}
