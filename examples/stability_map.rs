//! The stability map of the space-time velocity scheme on the one-degree-of-freedom oscillator
//! `m u'' + k u = 0`, from the library's own scheme (`softway::time::SpaceTimeScheme`: its
//! transfer matrix of `(u, h v)` over one step, which depends only on kappa = k h^2 / m).
//!
//! * Prints the book's table: the spectral radius and the largest energy met along the orbit
//!   over the initial energy (the worst of 100 starting phases, 3000 steps) for several alpha,
//!   beta and kappa.
//! * Draws `book/src/images/stability_map.svg` (or the file given with `--svg`): the spectral
//!   radius and the energy overshoot against kappa from 1e-2 to 1e8 (log axes) for alpha in
//!   {0.5, sqrt(2)/2, 0.75, 1} and beta in {1 - alpha, 1/2}. The overshoot is
//!   `max_n ||S T^n S^-1||^2` over n = 0..3000, T the transfer matrix and S the energy metric
//!   (`E = (k u^2 + m v^2) / 2`): the largest energy along the orbit from the worst starting
//!   state, exactly, where the table samples 100 starting phases. It is drawn where the scheme
//!   is stable (radius <= 1) only.
//! * Checks (exit status 1 with a message otherwise) what the book's time-scheme chapter says:
//!   beta = 1 - alpha conserves (determinant 1; radius 1 at every kappa for alpha >= sqrt(2)/2);
//!   alpha = 0.5, beta = 1/2 (which is also 1 - alpha) has radius 1 only up to
//!   kappa = 4 / (1 - 2 alpha^2) = 8 and tends to 5.83 beyond; beta = 1/2 is stable at every
//!   kappa only with alpha = 1 (the window `1 - alpha <= beta <= alpha^2 - alpha + 1/2`), where it
//!   damps and never overshoots; where a curve loses stability it does so at
//!   kappa = 4 / (2 (beta - (alpha^2 - alpha + 1/2))) (8, 9.657 and 10.667 for alpha = 0.5,
//!   sqrt(2)/2 and 0.75 with beta = 1/2); the overshoot of alpha = 0.75, beta = 0.25 at
//!   kappa = 100 is the table's 29.3 within its phase sampling.
//!
//! Run: `cargo run --example stability_map [-- --svg FILE.svg]` (rewrites the book's figure
//! by default). Its test: `cargo test --example stability_map`.

mod common;

use std::path::{Path, PathBuf};

use common::run::{conclude, Args, Failure};
use nalgebra::Matrix2;
use softway::time::{Beta, SpaceTimeScheme};

/// The figure's kappa range: 10^KAPPA_DECADES.0 to 10^KAPPA_DECADES.1, POINTS_PER_DECADE
/// points a decade.
const KAPPA_DECADES: (i32, i32) = (-2, 8);
const POINTS_PER_DECADE: usize = 40;
/// Steps over which the overshoot is taken (as the table's orbits).
const ORBIT_STEPS: usize = 3000;

/// What the example is asked to do.
#[derive(Debug, Clone, Default)]
struct Options {
    /// Where to draw the SVG; `None`: draw nothing.
    svg: Option<PathBuf>,
}

/// One curve of the figure: a scheme, its label, and per kappa the spectral radius and the
/// energy overshoot (`None` where unstable).
#[derive(Debug, Clone)]
struct Curve {
    alpha: f64,
    beta: f64,
    label: String,
    points: Vec<(f64, f64, Option<f64>)>,
}

/// What the run computed.
#[derive(Debug, Clone)]
struct Summary {
    curves: Vec<Curve>,
}

fn kappas() -> Vec<f64> {
    let (lo, hi) = KAPPA_DECADES;
    let n = (hi - lo) as usize * POINTS_PER_DECADE;
    (0..=n)
        .map(|i| 10f64.powf(lo as f64 + i as f64 / POINTS_PER_DECADE as f64))
        .collect()
}

/// The largest singular value of a 2x2 matrix.
fn norm2(a: &Matrix2<f64>) -> f64 {
    let f2 = a.norm_squared();
    let det = a.determinant();
    (0.5 * (f2 + (f2 * f2 - 4.0 * det * det).max(0.0).sqrt())).sqrt()
}

/// `max_n ||S T^n S^-1||^2`, n = 0..ORBIT_STEPS: the largest energy along the orbit over the
/// initial energy, from the worst initial state. With m = h = 1 and k = kappa, T acts on
/// `(u, v)` and the energy is `(kappa u^2 + v^2) / 2`, so S = diag(sqrt(kappa), 1).
fn energy_overshoot(scheme: &SpaceTimeScheme, kappa: f64) -> f64 {
    let s = Matrix2::new(kappa.sqrt(), 0.0, 0.0, 1.0);
    let s_inv = Matrix2::new(1.0 / kappa.sqrt(), 0.0, 0.0, 1.0);
    let t = s * scheme.transfer_matrix(kappa) * s_inv;
    let mut power = Matrix2::identity();
    let mut worst: f64 = 1.0;
    for _ in 0..ORBIT_STEPS {
        power = t * power;
        worst = worst.max(norm2(&power).powi(2));
    }
    worst
}

/// The table's measure: the largest energy met along the orbit over the initial energy, for
/// the worst of 100 initial phases (the start point on the orbit matters: from pure
/// displacement the swing at alpha = 0.75 is only 3x, from the worst phase it is thousands at
/// large kappa), stepped with `step_oscillator`.
fn energy_swing(s: &SpaceTimeScheme, kappa: f64) -> f64 {
    let (m, k, h) = (1.0, kappa, 1.0);
    let mut worst: f64 = 1.0;
    for phase in 0..100 {
        let theta = std::f64::consts::PI * phase as f64 / 100.0;
        let (mut u, mut v) = (theta.cos() * (2.0 / k).sqrt(), theta.sin() * 2f64.sqrt());
        let e0 = 0.5 * k * u * u + 0.5 * m * v * v;
        for _ in 0..ORBIT_STEPS {
            (u, v) = s.step_oscillator(m, k, h, u, v);
            worst = worst.max((0.5 * k * u * u + 0.5 * m * v * v) / e0);
        }
    }
    worst
}

/// Prints the book's table (the time-scheme chapter).
fn print_table() {
    let kappas = [1e-2, 1.0, 1e2, 1e4, 1e8];
    print!("| alpha | beta |");
    for k in kappas {
        print!(" rho(kappa={k:.0e}) / max E/E0 |");
    }
    println!();
    println!("|---|---|{}", "---|".repeat(kappas.len()));
    let cases = [
        (0.5, Beta::Energy),
        (0.7, Beta::Energy),
        (std::f64::consts::FRAC_1_SQRT_2, Beta::Energy),
        (0.75, Beta::Energy),
        (0.75, Beta::Value(0.281)),
        (0.8, Beta::Value(0.3)),
        (0.75, Beta::Trapezoid),
        (1.0, Beta::Trapezoid),
    ];
    for (alpha, beta) in cases {
        let s = SpaceTimeScheme::new(alpha, beta).expect("valid");
        print!("| {:.4} | {:.4} |", s.alpha, s.beta);
        for k in kappas {
            let r = s.spectral_radius(k);
            if r > 1.0 + 1e-9 {
                print!(" {r:.3} / unstable |");
            } else {
                print!(" {r:.3} / {:.3} |", energy_swing(&s, k));
            }
        }
        println!();
    }
}

/// The figure's schemes: alpha in {0.5, sqrt(2)/2, 0.75, 1}, beta in {1 - alpha, 1/2}
/// (alpha = 0.5 gives the same scheme twice: drawn once).
fn schemes() -> Vec<(SpaceTimeScheme, String)> {
    let alphas = [
        (0.5, "0.5"),
        (std::f64::consts::FRAC_1_SQRT_2, "√2/2"),
        (0.75, "0.75"),
        (1.0, "1"),
    ];
    let mut out = Vec::new();
    for (alpha, name) in alphas {
        for beta in [Beta::Energy, Beta::Trapezoid] {
            let s = SpaceTimeScheme::new(alpha, beta).expect("valid");
            if out.iter().any(|(o, _): &(SpaceTimeScheme, String)| *o == s) {
                continue;
            }
            let beta_name = match (beta, alpha == 0.5) {
                (Beta::Energy, true) => "β = 1 - α = 1/2".to_string(),
                (Beta::Energy, false) => {
                    let b = format!("{:.3}", s.beta);
                    format!(
                        "β = 1 - α = {}",
                        b.trim_end_matches('0').trim_end_matches('.')
                    )
                }
                _ => "β = 1/2".to_string(),
            };
            out.push((s, format!("α = {name}, {beta_name}")));
        }
    }
    out
}

fn run(options: &Options) -> Result<Summary, Failure> {
    let curves: Vec<Curve> = schemes()
        .into_iter()
        .map(|(s, label)| Curve {
            alpha: s.alpha,
            beta: s.beta,
            label,
            points: kappas()
                .into_iter()
                .map(|k| {
                    let r = s.spectral_radius(k);
                    let overshoot = (r <= 1.0 + 1e-9).then(|| energy_overshoot(&s, k));
                    (k, r, overshoot)
                })
                .collect(),
        })
        .collect();
    let summary = Summary { curves };
    if let Some(path) = &options.svg {
        draw(&summary, path)?;
    }
    Ok(summary)
}

/// Draws the two panels into an SVG file.
fn draw(s: &Summary, path: &Path) -> Result<(), Failure> {
    use plotters::prelude::*;

    let colors = [
        RGBColor(0x1f, 0x77, 0xb4),
        RGBColor(0xd6, 0x27, 0x28),
        RGBColor(0x2c, 0xa0, 0x2c),
        RGBColor(0x94, 0x67, 0xbd),
    ];
    let alphas = [0.5, std::f64::consts::FRAC_1_SQRT_2, 0.75, 1.0];
    let style = |c: &Curve| -> (ShapeStyle, bool) {
        let k = alphas
            .iter()
            .position(|&a| a == c.alpha)
            .expect("one of the four");
        // Solid: beta = 1 - alpha; dashed: beta = 1/2 (alpha = 0.5 is both: solid).
        let dashed = (c.beta - (1.0 - c.alpha)).abs() > 1e-12;
        (colors[k].stroke_width(2), dashed)
    };
    let (lo, hi) = (10f64.powi(KAPPA_DECADES.0), 10f64.powi(KAPPA_DECADES.1));
    // The axes hold every value (plotters does not clip a line at the plot's edge).
    let values = || s.curves.iter().flat_map(|c| c.points.iter());
    let radius_low = values().map(|p| p.1).fold(1.0f64, f64::min) / 1.2;
    let radius_high = values().map(|p| p.1).fold(1.0f64, f64::max) * 1.2;
    let energy_high = values().filter_map(|p| p.2).fold(1.0f64, f64::max) * 10.0;
    let root = SVGBackend::new(path, (900, 1000)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(500);

    let mut radius = ChartBuilder::on(&top)
        .caption(
            "Spectral radius of the transfer matrix (1-DOF oscillator)",
            ("sans-serif", 22),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        // Base 2: ticks at 0.5, 1, 2, 4 and between (base 10 would start at 1).
        .build_cartesian_2d(
            (lo..hi).log_scale(),
            (radius_low..radius_high).log_scale().base(2.0),
        )?;
    radius
        .configure_mesh()
        .x_desc("κ = k h² / m")
        .y_desc("spectral radius ρ")
        .y_labels(15)
        .x_label_formatter(&|k| format!("{k:.0e}"))
        .y_label_formatter(&|r| format!("{r:.2}"))
        .draw()?;
    for c in &s.curves {
        let (st, dashed) = style(c);
        let points = c.points.iter().map(|p| (p.0, p.1));
        let legend = move |(x, y): (i32, i32)| PathElement::new(vec![(x, y), (x + 24, y)], st);
        if dashed {
            radius
                .draw_series(DashedLineSeries::new(points, 8, 5, st))?
                .label(c.label.as_str())
                .legend(legend);
        } else {
            radius
                .draw_series(LineSeries::new(points, st))?
                .label(c.label.as_str())
                .legend(legend);
        }
    }
    radius
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .draw()?;

    let mut energy = ChartBuilder::on(&bottom)
        .caption(
            "Largest energy along the orbit / initial energy (worst start; stable part only)",
            ("sans-serif", 22),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d((lo..hi).log_scale(), (0.5f64..energy_high).log_scale())?;
    energy
        .configure_mesh()
        .x_desc("κ = k h² / m")
        .y_desc("max E / E(0)")
        .x_label_formatter(&|k| format!("{k:.0e}"))
        .y_label_formatter(&|e| format!("{e:.0e}"))
        .draw()?;
    for c in &s.curves {
        let (st, dashed) = style(c);
        // One line per stable stretch of kappa.
        for stretch in c.points.split(|p| p.2.is_none()) {
            let points: Vec<(f64, f64)> =
                stretch.iter().filter_map(|p| Some((p.0, p.2?))).collect();
            if points.len() < 2 {
                continue;
            }
            if dashed {
                energy.draw_series(DashedLineSeries::new(points, 8, 5, st))?;
            } else {
                energy.draw_series(LineSeries::new(points, st))?;
            }
        }
    }
    root.present()?;
    Ok(())
}

/// The radius and overshoot of the curve of (alpha, beta) at the grid's kappa nearest `kappa`.
fn at(s: &Summary, alpha: f64, beta: f64, kappa: f64) -> (f64, Option<f64>) {
    let c = s
        .curves
        .iter()
        .find(|c| (c.alpha - alpha).abs() < 1e-12 && (c.beta - beta).abs() < 1e-12)
        .expect("a curve of the figure");
    let p = c
        .points
        .iter()
        .min_by(|a, b| {
            (a.0 / kappa)
                .ln()
                .abs()
                .total_cmp(&(b.0 / kappa).ln().abs())
        })
        .expect("points");
    (p.1, p.2)
}

/// The known facts (the book's time-scheme chapter); `Err` says which failed.
fn check(s: &Summary) -> Result<(), String> {
    let mut failed = Vec::new();
    let mut expect = |ok: bool, what: String| {
        if !ok {
            failed.push(what);
        }
    };
    let sqrt_half = std::f64::consts::FRAC_1_SQRT_2;
    for c in &s.curves {
        let on_edge = (c.beta - (1.0 - c.alpha)).abs() < 1e-12;
        for &(kappa, radius, overshoot) in &c.points {
            let t = SpaceTimeScheme {
                alpha: c.alpha,
                beta: c.beta,
            }
            .transfer_matrix(kappa);
            // beta = 1 - alpha: determinant 1 (no numerical damping).
            if on_edge {
                let det = t.determinant();
                expect(
                    (det - 1.0).abs() < 1e-9,
                    format!("{}: determinant {det} at kappa {kappa:.3e}", c.label),
                );
            }
            // Radius 1 at every kappa on the edge for alpha >= sqrt(2)/2.
            if on_edge && c.alpha >= sqrt_half - 1e-12 {
                expect(
                    (radius - 1.0).abs() < 1e-7,
                    format!("{}: radius {radius} at kappa {kappa:.3e}", c.label),
                );
            }
            // alpha = 1, beta = 1/2: stable, damped, never above the initial energy.
            if c.alpha == 1.0 && c.beta == 0.5 {
                expect(
                    radius <= 1.0 + 1e-12 && overshoot.is_some_and(|e| e <= 1.0 + 1e-9),
                    format!(
                        "{}: radius {radius}, overshoot {overshoot:?} at kappa {kappa:.3e}",
                        c.label
                    ),
                );
            }
        }
    }
    // alpha = 0.5, beta = 1/2: radius 1 up to kappa = 4 / (1 - 2 alpha^2) = 8, unstable beyond,
    // 5.83 in the stiff limit.
    let half = SpaceTimeScheme::new(0.5, Beta::Trapezoid).expect("valid");
    for kappa in [1e-2, 1.0, 7.9] {
        let r = half.spectral_radius(kappa);
        expect(
            (r - 1.0).abs() < 1e-9,
            format!("alpha = beta = 1/2: radius {r} at kappa {kappa} (1 expected)"),
        );
    }
    let r = half.spectral_radius(8.1);
    expect(
        r > 1.0,
        format!("alpha = beta = 1/2: radius {r} at kappa 8.1 (> 1 expected)"),
    );
    let (r, _) = at(s, 0.5, 0.5, 1e8);
    let limit = SpaceTimeScheme::stiff_limit_radius(0.5);
    expect(
        (r - limit).abs() < 1e-3 && (limit - 5.83).abs() < 5e-3,
        format!("alpha = beta = 1/2: radius {r} at kappa 1e8, stiff limit {limit} (5.83)"),
    );
    // beta = 1/2 outside the window (alpha < 1): stable for resolved modes, unstable for stiff.
    for alpha in [sqrt_half, 0.75] {
        let (small, _) = at(s, alpha, 0.5, 1e-2);
        let (stiff, _) = at(s, alpha, 0.5, 1e4);
        expect(
            small <= 1.0 && stiff > 1.0,
            format!("alpha = {alpha}, beta = 1/2: radius {small} at kappa 1e-2, {stiff} at 1e4"),
        );
    }
    // Every curve that loses stability (alpha = 0.5; beta = 1/2 with alpha < 1) does so at
    // kappa = 4 / (2 (beta - (alpha^2 - alpha + 1/2))): past the window's upper edge.
    for c in &s.curves {
        let excess = c.beta - (c.alpha * c.alpha - c.alpha + 0.5);
        match stable_up_to(c) {
            Some(edge) => {
                let formula = 4.0 / (2.0 * excess);
                expect(
                    excess > 0.0 && (edge / formula - 1.0).abs() < 1e-6,
                    format!(
                        "{}: stable up to kappa = {edge}, formula {formula}",
                        c.label
                    ),
                );
            }
            None => expect(
                excess <= 1e-12,
                format!("{}: stable at every kappa above the window", c.label),
            ),
        }
    }
    // The overshoot at alpha = 0.75, beta = 0.25, kappa = 100 is the table's (29.3, sampled
    // over 100 phases, a lower bound of the exact worst).
    let exact = energy_overshoot(&SpaceTimeScheme::new(0.75, Beta::Energy).unwrap(), 100.0);
    let sampled = energy_swing(&SpaceTimeScheme::new(0.75, Beta::Energy).unwrap(), 100.0);
    expect(
        exact >= sampled - 1e-9 && exact < 1.02 * sampled && (sampled - 29.3).abs() < 0.05,
        format!("alpha = 0.75, beta = 0.25, kappa = 100: overshoot {exact}, sampled {sampled}"),
    );
    if failed.is_empty() {
        Ok(())
    } else {
        Err(failed.join("\n"))
    }
}

/// The largest kappa up to which the scheme is stable (radius <= 1), by bisection on the
/// library's spectral radius from the first unstable point of the grid; `None`: stable over
/// the whole grid.
fn stable_up_to(c: &Curve) -> Option<f64> {
    let s = SpaceTimeScheme {
        alpha: c.alpha,
        beta: c.beta,
    };
    let i = c.points.iter().position(|p| p.1 > 1.0 + 1e-9)?;
    let (mut lo, mut hi) = (c.points[i.saturating_sub(1)].0, c.points[i].0);
    for _ in 0..60 {
        let mid = (lo * hi).sqrt();
        if s.spectral_radius(mid) > 1.0 + 1e-9 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(lo)
}

fn print(s: &Summary) {
    println!();
    println!(
        "figure: spectral radius / energy overshoot at kappa = 1, 1e2, 1e4, 1e8; stable up to"
    );
    for c in &s.curves {
        print!("  {:<28}", c.label);
        for kappa in [1.0, 1e2, 1e4, 1e8] {
            let (r, e) = at(s, c.alpha, c.beta, kappa);
            match e {
                Some(e) => print!(" {r:>6.3} / {e:<9.3e}"),
                None => print!(" {r:>6.3} / unstable "),
            }
        }
        match stable_up_to(c) {
            Some(k) => println!("  kappa = {k:.4}"),
            None => println!("  every kappa"),
        }
    }
}

fn main() -> std::process::ExitCode {
    let usage = "usage: stability_map [--svg FILE.svg] (default: the book's \
                 book/src/images/stability_map.svg)";
    let default_svg =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("book/src/images/stability_map.svg");
    let options = Args::parse(&["--svg"], usage).and_then(|args| {
        Ok(Options {
            svg: Some(args.get("--svg")?.unwrap_or(default_svg)),
        })
    });
    print_table();
    let outcome = options.and_then(|o| run(&o).map(|s| (o, s)));
    let print_and_name = |(o, s): &(Options, Summary)| {
        print(s);
        if let Some(svg) = &o.svg {
            println!("drew {}", svg.display());
        }
    };
    conclude("stability_map", outcome, print_and_name, |(_, s)| check(s))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The figure's data pass the checks, and the SVG is drawn (into a temporary file: the
    /// book's is regenerated by `cargo run --example stability_map`).
    #[test]
    fn stability_map_facts_and_figure() {
        let dir = tempfile::tempdir().unwrap();
        let svg = dir.path().join("stability_map.svg");
        let s = run(&Options {
            svg: Some(svg.clone()),
        })
        .unwrap();
        print(&s);
        check(&s).unwrap();
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.starts_with("<svg"), "{}", &text[..80.min(text.len())]);
        for c in &s.curves {
            assert!(text.contains(&c.label), "no legend for {}", c.label);
        }
    }
}
