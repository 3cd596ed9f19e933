//! Prints the stability map of the space-time velocity scheme on the one-degree-of-freedom
//! oscillator: spectral radius of the transfer matrix and the largest energy met along the
//! orbit (relative to the initial energy) for several alpha, beta and kappa = k h^2 / m.
//!
//! Run: `cargo run --example stability_map`.

use softway::time::{Beta, SpaceTimeScheme};

/// The largest energy met along the orbit over the initial energy, for the worst of 100
/// initial phases (the start point on the orbit matters: from pure displacement the swing at
/// alpha = 0.75 is only 3x, from the worst phase it is thousands at large kappa).
fn energy_swing(s: &SpaceTimeScheme, kappa: f64) -> f64 {
    let (m, k, h) = (1.0, kappa, 1.0);
    let mut worst: f64 = 1.0;
    for phase in 0..100 {
        let theta = std::f64::consts::PI * phase as f64 / 100.0;
        let (mut u, mut v) = (theta.cos() * (2.0 / k).sqrt(), theta.sin() * 2f64.sqrt());
        let e0 = 0.5 * k * u * u + 0.5 * m * v * v;
        for _ in 0..3000 {
            (u, v) = s.step_oscillator(m, k, h, u, v);
            worst = worst.max((0.5 * k * u * u + 0.5 * m * v * v) / e0);
        }
    }
    worst
}

fn main() {
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
