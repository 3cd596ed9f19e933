//! Coulomb friction as a return map under the soft way, the augmented Lagrangian and implicit
//! projection (default scheme and tolerances), in 2D and 3D: a block on a 30 degree slope
//! slides at g (sin 30 - mu cos 30) for mu = 0.3; with mu = 0.7 it sticks (no creep between
//! 0.1 s and 1 s) on a 25 degree slope with a material damping of 5 % and on a 30 degree slope
//! with 20 %; with 5 % at 30 degrees it walks, the same under every method once the step
//! resolves the block; the bundled ring drop runs through its landing with Coulomb 0.3 and
//! dissipates. Tresca friction between two bodies: a block slowing on another at limit x area
//! over its mass.

use crate::common;

use common::verify::record;
use common::{block, energy_error, vec_d};
use softway::contact::{
    ContactMethod, ContactSettings, FrictionLaw, GapDisplacement, Obstacle, ObstacleShape,
};
use softway::dim::{Dim, SpatialDim};
use softway::prelude::*;
use softway::simulation::{RayleighDamping, RunMonitor};

const G: f64 = 9.81;

/// `per_method!(module, test_fn)`: `module::{d2,d3}_{soft_way, augmented_lagrangian,
/// implicit_projection}`, every method that carries friction in both dimensions.
macro_rules! per_method {
    ($module:ident, $test:ident) => {
        mod $module {
            use super::*;
            #[test]
            fn d2_soft_way() {
                $test::<2>(ContactMethod::SoftWay);
            }
            #[test]
            fn d3_soft_way() {
                $test::<3>(ContactMethod::SoftWay);
            }
            #[test]
            fn d2_augmented_lagrangian() {
                $test::<2>(ContactMethod::AugmentedLagrangian);
            }
            #[test]
            fn d3_augmented_lagrangian() {
                $test::<3>(ContactMethod::AugmentedLagrangian);
            }
            #[test]
            fn d2_implicit_projection() {
                $test::<2>(ContactMethod::ImplicitProjection);
            }
            #[test]
            fn d3_implicit_projection() {
                $test::<3>(ContactMethod::ImplicitProjection);
            }
        }
    };
}

per_method!(slide, block_on_a_slope_slides);
per_method!(stick, block_on_a_slope_sticks);

/// The persistency stop on trapezoid gaps (the augmented Lagrangian's by default, the soft
/// way's as an option) gives a closing pair an impulse after the step; on a pair that slips,
/// Coulomb's law asks `mu` times it of friction against the slip. Frictionless, the stop let
/// the block slide 8.6 % (soft way) and 10.0 % (augmented Lagrangian) faster than the law
/// (2D, measured 2026-12-03).
mod slide_with_the_stop {
    use super::*;
    fn slides<const D: usize>(method: ContactMethod, stop: Option<bool>)
    where
        Dim<D>: SpatialDim<D>,
    {
        let sim = slope_with_gaps::<D>(
            0.3,
            method,
            RayleighDamping::NONE,
            30.0,
            1e-3,
            GapDisplacement::Trapezoid,
            stop,
        );
        slides_at_the_law_s_rate(sim, &format!("{method:?} on trapezoid gaps, stop {stop:?}"));
    }
    #[test]
    fn d2_soft_way() {
        slides::<2>(ContactMethod::SoftWay, Some(true));
    }
    #[test]
    fn d3_soft_way() {
        slides::<3>(ContactMethod::SoftWay, Some(true));
    }
    #[test]
    fn d2_augmented_lagrangian() {
        slides::<2>(ContactMethod::AugmentedLagrangian, None);
    }
    #[test]
    fn d3_augmented_lagrangian() {
        slides::<3>(ContactMethod::AugmentedLagrangian, None);
    }
}

// The scene a user tries first: 30 degrees, mu = 0.7 (tan 30 / 0.7 = 0.82 of the cone), here
// with a material damping of 20 % of critical at the block's first mode: it sticks under every
// method at the default step. With 5 % it walks, and so does the converged model
// ([`walks_near_the_cone_when_lightly_damped`]).
per_method!(stick_near_the_cone, block_near_the_cone_sticks);
// Laws that read only whether a point is closed (Tresca, viscoplastic) act on the whole
// contact patch between bodies, whichever pass carries the load.
per_method!(
    tresca_between_bodies,
    a_block_slides_on_a_block_under_tresca
);
per_method!(
    viscoplastic_between_bodies,
    a_block_slides_on_a_block_under_viscoplastic_friction
);
per_method!(
    coulomb_between_bodies,
    a_block_slides_on_a_block_under_coulomb
);

fn block_near_the_cone_sticks<const D: usize>(method: ContactMethod)
where
    Dim<D>: SpatialDim<D>,
{
    sticks_on_a_slope_of::<D>(method, 30.0, material_damping(0.2));
}

/// Near the cone a lightly damped elastic block walks: a friction-driven stick-slip of its
/// rocking, which the work of gravity feeds and friction dissipates. It is the model's, not a
/// step's or a method's: at h = 0.1 ms (the block's first mode resolved, omega h = 0.5) and 5 %
/// damping, the three methods walk the same 4.4 mm between 0.1 s and 1 s (measured 4.420,
/// 4.413, 4.489 mm, implicit projection, soft way, augmented Lagrangian, 2026-11-30), and finer meshes walk
/// too (3.6 and 3.4 mm/s with 2x and 4x the cells, against 4.9 mm/s, soft way). 2D only: the
/// 3D runs at this step take minutes.
#[test]
fn walks_near_the_cone_when_lightly_damped() {
    let walks: Vec<(ContactMethod, f64)> = [
        ContactMethod::ImplicitProjection,
        ContactMethod::SoftWay,
        ContactMethod::AugmentedLagrangian,
    ]
    .into_iter()
    .map(|method| {
        let mut sim = slope::<2>(0.7, method, material_damping(0.05), 30.0, 1e-4);
        run_to(&mut sim, 0.1);
        let start = mean_along::<2>(&sim.state().displacement);
        run_to(&mut sim, 1.0);
        let walk = mean_along::<2>(&sim.state().displacement) - start;
        eprintln!(
            "2D {method:?}, h = 0.1 ms, 5 % damping: walk {walk:.4e} m over t = 0.1..1 s, energy \
             error {:.2e}",
            energy_error(&sim)
        );
        // Measured 2.6e-5 and 1.6e-5 for the penalty methods (2.2e-2 and 2.5e-2 before their
        // tangential spring was capped at four diagonals per step, 2026-11-30), 3e-4 for
        // implicit projection.
        assert!(
            energy_error(&sim) < 2e-3,
            "{method:?}: {}",
            energy_error(&sim)
        );
        (method, walk)
    })
    .collect();
    let mean = walks.iter().map(|w| w.1).sum::<f64>() / walks.len() as f64;
    assert!(
        mean > 3e-3,
        "the block walks {mean:e} m: it should not stick"
    );
    for (method, walk) in walks {
        assert!(
            (walk - mean).abs() < 0.03 * mean,
            "{method:?} walks {walk:e} m, the methods' mean {mean:e} m"
        );
    }
}

/// The walk of [`walks_near_the_cone_when_lightly_damped`] with the persistency stop on
/// trapezoid gaps (the soft way's option, the augmented Lagrangian's default there), against
/// implicit projection's. Measured 2026-12-03 (release build): implicit projection 4.42 mm,
/// the soft way with the stop 4.61 mm, the augmented Lagrangian 4.64 mm; 5.57 and 4.96 mm
/// while the stop's impulse carried no friction.
#[test]
#[ignore = "slow: about 4 minutes in a release build (three runs of 10 000 steps); \
            walks_near_the_cone_when_lightly_damped runs the methods on their default gaps"]
fn walks_near_the_cone_with_the_stop() {
    let walk = |gaps, method, stop| {
        let mut sim =
            slope_with_gaps::<2>(0.7, method, material_damping(0.05), 30.0, 1e-4, gaps, stop);
        run_to(&mut sim, 0.1);
        let start = mean_along::<2>(&sim.state().displacement);
        run_to(&mut sim, 1.0);
        let walk = mean_along::<2>(&sim.state().displacement) - start;
        eprintln!(
            "{method:?} on {gaps:?} gaps, stop {stop:?}: walk {walk:.4e} m, energy error {:.2e}",
            energy_error(&sim)
        );
        walk
    };
    let reference = walk(
        GapDisplacement::Configuration,
        ContactMethod::ImplicitProjection,
        None,
    );
    for (method, stop) in [
        (ContactMethod::SoftWay, Some(true)),
        (ContactMethod::AugmentedLagrangian, None),
    ] {
        let w = walk(GapDisplacement::Trapezoid, method, stop);
        assert!(
            (w - reference).abs() < 0.08 * reference,
            "{method:?} with the stop walks {w:e} m, implicit projection {reference:e} m"
        );
    }
}

/// At the default step (1 ms, the block's first mode unresolved, omega h = 5) and 5 % damping,
/// the block should hop no more than the converged one, which touches the slope in all but 0.7
/// to 1.2 % of its steps. Open: see the ignore reasons.
mod hops_near_the_cone {
    use super::*;
    #[test]
    #[ignore = "no contact in 17.0 % of the steps (2026-12-03, Newton solving slip's coupling; 16.2 % without, 19.9 % before the tangential spring's cap): the soft way's block hops (walk 10.9 mm against 4.4)"]
    fn d2_soft_way() {
        hops_like_the_converged_block::<2>(ContactMethod::SoftWay);
    }
    #[test]
    #[ignore = "no contact in 17.4 % of the steps (2026-12-03, Newton solving slip's coupling; 16.4 % without, 18.9 % before the tangential spring's cap): the soft way's block hops (walk 14 mm)"]
    fn d3_soft_way() {
        hops_like_the_converged_block::<3>(ContactMethod::SoftWay);
    }
    #[test]
    #[ignore = "no contact in 17.4 % of the steps (2026-12-03, Newton solving slip's coupling; 18.6 % without, 18.5 % before the tangential spring's cap, 16.2 % before cut steps kept the scheme's energy). Its 1.2 % before came from cut steps and the \
                tolerance: with that Newton, a tolerance of 3e-9 gave 11.9 % and 1e-10 35.6 %"]
    fn d2_augmented_lagrangian() {
        hops_like_the_converged_block::<2>(ContactMethod::AugmentedLagrangian);
    }
    #[test]
    #[ignore = "no contact in 16.6 % of the steps (2026-12-03, Newton solving slip's coupling; 18.4 % without, 16.5 % before the tangential spring's cap), 13.1 % before cut steps kept the scheme's energy (30 % with the paper's fixed zeta, walk 38 mm)"]
    fn d3_augmented_lagrangian() {
        hops_like_the_converged_block::<3>(ContactMethod::AugmentedLagrangian);
    }
    #[test]
    #[ignore = "no contact in 10.8 % of the steps (2026-12-03; 10.9 % read earlier, 10.6 % before the end-of-step projection held points within the gap tolerance, 2026-12-02; 14.3 % with a tangential spring of 100 diagonals per step, 13.1 % before the active set was carried from step to step). Its 1.6 % before came from steps whose \
                Newton failed (12, 115, 120, 138, ...) and were cut in halves; the line search \
                now solves them at full size"]
    fn d2_implicit_projection() {
        hops_like_the_converged_block::<2>(ContactMethod::ImplicitProjection);
    }
    #[test]
    #[ignore = "no contact in 7.8 % of the steps (2026-12-03; 9.1 % read earlier, 8.4 % before the end-of-step projection held points within the gap tolerance, 2026-12-02; 11.5 % with a tangential spring of 100 diagonals per step), 12.9 % before cut steps kept the scheme's energy (it runs to the end since a stalled Newton is \
                retried with the line search; it stopped at step 295)"]
    fn d3_implicit_projection() {
        hops_like_the_converged_block::<3>(ContactMethod::ImplicitProjection);
    }
}

fn hops_like_the_converged_block<const D: usize>(method: ContactMethod)
where
    Dim<D>: SpatialDim<D>,
{
    let mut sim = slope::<D>(0.7, method, material_damping(0.05), 30.0, 1e-3);
    let (mut steps, mut airborne) = (0, 0);
    while sim.state().time < 1.0 - 1e-9 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("t = {}: {e}", sim.state().time));
        steps += 1;
        airborne += usize::from(r.active_contacts == 0);
    }
    let share = airborne as f64 / steps as f64;
    eprintln!(
        "{D}D {method:?}: no contact in {:.1} % of the steps",
        100.0 * share
    );
    assert!(
        share <= 0.03,
        "no contact in {:.1} % of the steps",
        100.0 * share
    );
}

/// A 0.2 x 0.1 (x 0.1) m block resting on the plane y = 0 (z = 0 in 3D) under gravity tilted by
/// 30 degrees (down the slope along +x), E = 1e7 Pa, zeta = 1e10 Pa/m (a penetration of about
/// 1e-7 m), Coulomb `mu`, the default scheme and tolerances.
fn slope<const D: usize>(
    mu: f64,
    method: ContactMethod,
    damping: RayleighDamping,
    degrees: f64,
    time_step: f64,
) -> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    slope_with_gaps(
        mu,
        method,
        damping,
        degrees,
        time_step,
        GapDisplacement::default(),
        None,
    )
}

/// [`slope`] with the gaps measured on `gaps` and the persistency stop `stop`
/// (`ContactSettings::persistency_stop`).
fn slope_with_gaps<const D: usize>(
    mu: f64,
    method: ContactMethod,
    damping: RayleighDamping,
    degrees: f64,
    time_step: f64,
    gaps: GapDisplacement,
    stop: Option<bool>,
) -> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    let theta = degrees.to_radians();
    let mesh = block::<D>([0.2, 0.1, 0.1], [4, 2, 2], false);
    let mut normal = [0.0; 3];
    normal[D - 1] = 1.0;
    let mut g = [0.0; 3];
    g[0] = G * theta.sin();
    g[D - 1] = -G * theta.cos();
    Simulation::<D>::builder()
        .time_step(time_step)
        .gravity(vec_d(g))
        .body(
            Body::new(
                "block",
                mesh,
                Material::LinearElastic(LinearElastic::new(1e7, 0.3, 1000.0).unwrap()),
            )
            .with_damping(damping.mass, damping.stiffness),
        )
        .obstacle(Obstacle::new(
            "slope",
            ObstacleShape::Halfspace {
                point: vec_d([0.0; 3]),
                normal: vec_d(normal),
            },
        ))
        .contact(ContactSettings {
            method,
            penalty: 1e10,
            friction: if mu > 0.0 {
                FrictionLaw::Coulomb {
                    coefficient: mu,
                    regularization: 1e-6,
                }
            } else {
                FrictionLaw::Frictionless
            },
            gap_displacement: gaps,
            persistency_stop: stop,
            ..ContactSettings::default()
        })
        .build()
        .unwrap()
}

/// The augmented Lagrangian on trapezoid gaps holds the damped block on the 25 degree slope
/// (mu = 0.7) as on the configuration's, in about one Newton iteration a step once settled:
/// its multipliers close these gaps, and a pair that ends a step closed and still approaching
/// has that velocity stopped (`GapDisplacement::Trapezoid`). Without the stop a closed pair
/// alternated `w1 = -w0` from step to step: 10 iterations a step in 2D (19 on average before
/// the tangential spring's cap), and the account 2.0e-3 (measured 2026-11-30).
fn sticks_on_trapezoid_gaps<const D: usize>(method: ContactMethod, stop: Option<bool>)
where
    Dim<D>: SpatialDim<D>,
{
    let mut sim = slope_with_gaps::<D>(
        0.7,
        method,
        material_damping(0.05),
        25.0,
        1e-3,
        GapDisplacement::Trapezoid,
        stop,
    );
    run_to(&mut sim, 0.1);
    let (_, range, most) = range_from_settled::<D>(&mut sim);
    eprintln!(
        "{D}D {method:?} on trapezoid gaps (stop {stop:?}), stick: range {range:.3e} m over t = \
         0.1..1 s, iterations per step <= {most} (after settling), energy error {:.2e}",
        energy_error(&sim)
    );
    assert!(range < 1e-6, "the block moved by {range:e} m");
    assert!(
        most <= 2,
        "{most} Newton iterations in a step of resting contact"
    );
    assert!(energy_error(&sim) < 1e-3, "{}", energy_error(&sim));
}

#[test]
fn sticks_on_trapezoid_gaps_d2() {
    sticks_on_trapezoid_gaps::<2>(ContactMethod::AugmentedLagrangian, None);
}

#[test]
fn sticks_on_trapezoid_gaps_d3() {
    sticks_on_trapezoid_gaps::<3>(ContactMethod::AugmentedLagrangian, None);
}

/// The soft way with the persistency stop (`ContactSettings::persistency_stop`) holds the same
/// block on trapezoid gaps, settled, in one Newton iteration a step, its account to 9e-12 /
/// 2.2e-10 (2D / 3D). Without the stop its contact springs alternate undamped: at most 6 / 5
/// iterations a step once settled, the account 1.9e-9 / 2.0e-9 (measured 2026-12-03).
#[test]
fn the_soft_way_with_the_stop_sticks_on_trapezoid_gaps_d2() {
    sticks_on_trapezoid_gaps::<2>(ContactMethod::SoftWay, Some(true));
}

#[test]
fn the_soft_way_with_the_stop_sticks_on_trapezoid_gaps_d3() {
    sticks_on_trapezoid_gaps::<3>(ContactMethod::SoftWay, Some(true));
}

/// Stiffness-proportional damping of `ratio` of critical at the block's first axial mode (the
/// quarter wave through its 0.1 m height, omega = pi c / (2 H), c = sqrt(E / rho)), more on
/// faster modes: a material's own damping, which brings the block to rest.
fn material_damping(ratio: f64) -> RayleighDamping {
    let omega = std::f64::consts::PI * (1e7f64 / 1000.0).sqrt() / (2.0 * 0.1);
    RayleighDamping {
        mass: 0.0,
        stiffness: 2.0 * ratio / omega,
    }
}

/// Runs a settled block on the slope to t = 1 s, a millisecond at a time: its mean displacement
/// along the slope at the start, that displacement's range over the run, and the most Newton
/// iterations in a step.
fn range_from_settled<const D: usize>(sim: &mut Simulation<D>) -> (f64, f64, usize)
where
    Dim<D>: SpatialDim<D>,
{
    let start = mean_along::<D>(&sim.state().displacement);
    let (mut low, mut high, mut most) = (start, start, 0);
    while sim.state().time < 1.0 - 1e-9 {
        let next = sim.state().time + 1e-3;
        most = most.max(run_to(sim, next));
        let u = mean_along::<D>(&sim.state().displacement);
        low = low.min(u);
        high = high.max(u);
    }
    (start, high - low, most)
}

/// The mean of the nodes' displacements (or velocities) along the slope.
fn mean_along<const D: usize>(values: &[f64]) -> f64
where
    Dim<D>: SpatialDim<D>,
{
    let n = values.len() / D;
    (0..n).map(|i| values[i * D]).sum::<f64>() / n as f64
}

/// Steps to `time`, returning the largest Newton iteration count of a step.
fn run_to<const D: usize>(sim: &mut Simulation<D>, time: f64) -> usize
where
    Dim<D>: SpatialDim<D>,
{
    run_to_watching(sim, time, &mut |_, _| {})
}

/// [`run_to`], handing every step's report to `watch`.
fn run_to_watching<const D: usize>(
    sim: &mut Simulation<D>,
    time: f64,
    watch: &mut dyn FnMut(&Simulation<D>, &StepReport),
) -> usize
where
    Dim<D>: SpatialDim<D>,
{
    let mut most = 0;
    while sim.state().time < time - 1e-9 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("t = {}: {e}", sim.state().time));
        watch(sim, &r);
        most = most.max(r.iterations);
    }
    most
}

/// The block with mu = 0.7 > tan 30 and a material damping of 5 %, default scheme: between
/// 0.1 s and 1 s its mean displacement along the slope stays within 1e-6 m (no creep).
/// Undamped, it must creep: see [`undamped_floor_reaction_keeps_swinging`].
fn block_on_a_slope_sticks<const D: usize>(method: ContactMethod)
where
    Dim<D>: SpatialDim<D>,
{
    sticks_on_a_slope_of::<D>(method, 25.0, material_damping(0.05));
}

fn sticks_on_a_slope_of<const D: usize>(
    method: ContactMethod,
    degrees: f64,
    damping: RayleighDamping,
) where
    Dim<D>: SpatialDim<D>,
{
    let mut sim = slope::<D>(0.7, method, damping, degrees, 1e-3);
    let settle = run_to(&mut sim, 0.1);
    let (start, range, most) = range_from_settled::<D>(&mut sim);
    let drift = mean_along::<D>(&sim.state().displacement) - start;
    eprintln!(
        "{D}D {method:?} stick: drift {drift:.3e} m, range {range:.3e} m over t = 0.1..1 s, u(0.1) = {start:.3e} \
         m, iterations per step <= {settle} (settling), <= {most} (after), energy error {:.2e}",
        energy_error(&sim)
    );
    if degrees == 25.0 {
        record("friction-stick", "motion (m)", range);
    }
    assert!(
        range < 1e-6,
        "the block moved by {range:e} m along the slope between 0.1 s and 1 s"
    );
    // Measured 1e-10 to 7e-5 of the reference since the penalty methods' tangential spring
    // was capped at four diagonals per step (2026-11-30; 1.6e-3 to 1.3e-2 before, booked
    // while the block settled, its edge nodes slipping, sticking and slipping again).
    assert!(energy_error(&sim) < 1e-3, "{}", energy_error(&sim));
}

fn block_on_a_slope_slides<const D: usize>(method: ContactMethod)
where
    Dim<D>: SpatialDim<D>,
{
    let sim = slope::<D>(0.3, method, RayleighDamping::NONE, 30.0, 1e-3);
    slides_at_the_law_s_rate(sim, &format!("{method:?}"));
}

/// Runs a block on a 30 degree slope with Coulomb 0.3 from rest to 0.5 s and checks its
/// acceleration g (sin 30 - 0.3 cos 30) within 1 %, the dissipation and the account.
fn slides_at_the_law_s_rate<const D: usize>(mut sim: Simulation<D>, method: &str)
where
    Dim<D>: SpatialDim<D>,
{
    let (theta, mu) = (30f64.to_radians(), 0.3);
    let mut monitor = RunMonitor::new(&sim);
    let mut watch = |sim: &Simulation<D>, r: &StepReport| {
        monitor.step(sim, r).unwrap();
    };
    let mut run_to = |sim: &mut Simulation<D>, time: f64| run_to_watching(sim, time, &mut watch);
    run_to(&mut sim, 0.1);
    // The acceleration: a least-squares line through the mean velocity of every step from
    // 0.1 s to 0.5 s (the block's elastic vibration averages out).
    let mut most = 0;
    let mut samples = Vec::new();
    while sim.state().time < 0.5 - 1e-9 {
        let next = sim.state().time + 1e-3;
        most = most.max(run_to(&mut sim, next));
        samples.push((sim.state().time, mean_along::<D>(&sim.state().velocity)));
    }
    let n = samples.len() as f64;
    let (st, sv) = samples
        .iter()
        .fold((0.0, 0.0), |(a, b), &(t, v)| (a + t, b + v));
    let (mt, mv) = (st / n, sv / n);
    let (num, den) = samples.iter().fold((0.0, 0.0), |(a, b), &(t, v)| {
        (a + (t - mt) * (v - mv), b + (t - mt) * (t - mt))
    });
    let a = num / den;
    let exact = G * (theta.sin() - mu * theta.cos());
    let error = (a - exact) / exact;
    eprintln!(
        "{D}D {method} slide: a = {a:.5} m/s^2, expected {exact:.5} ({:.3} %), iterations per step <= \
         {most}, dissipated {:.4e} J, energy error {:.2e}, scheme's account {:.2e}",
        100.0 * error,
        sim.energies().dissipated,
        energy_error(&sim),
        monitor.scheme_energy_drift()
    );
    record("friction-slide", "a", error);
    assert!(error.abs() < 0.01, "a = {a}, expected {exact}");
    assert!(sim.energies().dissipated > 0.0);
    // The energy the scheme conserves closes to Newton's tolerance: measured at the end
    // 1.8e-8 / 1.6e-8 under implicit projection (2D / 3D) and at most 1.6e-9 under the
    // penalty methods (2026-12-03).
    assert!(
        monitor.scheme_energy_drift() < 1e-7,
        "{}",
        monitor.scheme_energy_drift()
    );
    // The mechanical energy differs from it by O(h) terms of the block's vibration, which
    // swing with its phase: the 2D augmented Lagrangian's account read 4.2e-4, then 2.0e-3
    // in its last two steps of free flight, and up to 2.5e-3 from step 100 on (1.9e-3 before
    // Newton solved slip's coupling, when it ended at 8.2e-4 by its phase).
    assert!(energy_error(&sim) < 4e-3, "{}", energy_error(&sim));
}

/// The bundled ring drop (soft way, zeta = 3e9 Pa/m) to its end (0.6 s: the landing, the
/// bounce and the second landing) with `friction`: steps in contact, Newton iterations per
/// contact step, the most in a step, the dissipated energy and the energy-account error
/// relative to the energy reference.
#[cfg(feature = "formats")]
fn ring_drop(method: &str, friction: &str, extra: &[&str]) -> (usize, f64, usize, f64, f64) {
    let mut overrides = vec![
        format!("contact.friction={friction}"),
        format!("contact.method=\"{method}\""),
    ];
    overrides.extend(extra.iter().map(|s| s.to_string()));
    let scene = common::fixture::<2>("ring_drop", &overrides);
    let mut sim = scene.simulation().unwrap();
    let (mut iterations, mut most, mut contact_steps) = (0, 0, 0);
    while sim.state().time < scene.end_time - 1e-9 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("{method}, {friction}, t = {}: {e}", sim.state().time));
        if r.active_contacts > 0 {
            contact_steps += 1;
            iterations += r.iterations;
            most = most.max(r.iterations);
        }
    }
    let per_step = iterations as f64 / contact_steps.max(1) as f64;
    (
        contact_steps,
        per_step,
        most,
        sim.energies().dissipated,
        energy_error(&sim),
    )
}

/// The bundled ring drop with Coulomb 0.3 runs to its end with each method that takes
/// friction, dissipates, and friction keeps the energy account: its error is within 1e-3 of the
/// frictionless run's (the method's own drift with this penalty and step) and below the
/// issue's 1 % (the augmented Lagrangian: 4 %, not met).
// The bundled scene is read through the scene format.
#[cfg(feature = "formats")]
fn ring_drop_with_coulomb_friction(method: &str) {
    ring_drop_with_coulomb_friction_on(method, &[]);
}

/// [`ring_drop_with_coulomb_friction`] with `extra` scene overrides.
#[cfg(feature = "formats")]
fn ring_drop_with_coulomb_friction_on(method: &str, extra: &[&str]) {
    let (steps, per_step, most, dissipated, error) =
        ring_drop(method, "{law=\"coulomb\",coefficient=0.3}", extra);
    let (_, per_step_0, most_0, dissipated_0, error_0) =
        ring_drop(method, "{law=\"frictionless\"}", extra);
    eprintln!(
        "ring drop, {method} {extra:?}, Coulomb 0.3: {steps} steps in contact, {per_step:.2} iterations \
         per step (at most {most}), dissipated {dissipated:.4e} J, energy error {error:.3e}; \
         frictionless: {per_step_0:.2} (at most {most_0}), energy error {error_0:.3e}"
    );
    assert!(steps > 10, "the ring never landed");
    if !extra.is_empty() {
        // The augmented Lagrangian on trapezoid gaps: its persistency stops, in the step's
        // metric, take energy out (measured 56 J of the 1.2 kJ input with Coulomb; stops
        // sized on the lumped mass put energy in: -3.55 J booked by 0.4 s, frictionless).
        assert!(
            dissipated_0 > 0.0,
            "the frictionless run booked {dissipated_0} J dissipated"
        );
    }
    // Implicit projection books its end-of-step projection in the dissipated energy too
    // (negative where it puts energy in), so friction's share cannot be read from the total
    // there; its account is checked below.
    // So do the augmented Lagrangian's persistency stops on trapezoid gaps.
    if method != "implicit_projection" && extra.is_empty() {
        assert!(
            dissipated - dissipated_0 > 0.0,
            "no friction dissipation: {dissipated} J against {dissipated_0} J frictionless"
        );
    }
    // The account's error at the end is each method's own (frictionless: soft way 4.58e-3,
    // augmented Lagrangian 3.82e-2, implicit projection 2.005e-3 of the reference; with
    // Coulomb 4.27e-3, 3.72e-2 and 2.005e-3, measured 2026-11-30 at zeta = 3e9 Pa/m;
    // through the landing, 0.4 s, the soft way's was 1.38e-2 at 1e10). The augmented Lagrangian's
    // multipliers close the gaps on the stored configuration, whose offset puts energy in at
    // each bounce: it misses the 1 %.
    // On trapezoid gaps (`gap_displacement = "trapezoid"`) its account closes to 3.7e-3 with
    // Coulomb and without (measured 2026-11-30).
    let (added, bound) = match method {
        "augmented_lagrangian" if extra.is_empty() => (2e-3, 4e-2),
        _ => (1e-3, 1e-2),
    };
    assert!(
        (error - error_0).abs() < added,
        "{error} vs frictionless {error_0}"
    );
    assert!(error < bound, "{error}");
}

#[cfg(feature = "formats")]
mod ring_drop {
    #[test]
    fn soft_way() {
        super::ring_drop_with_coulomb_friction("soft_way");
    }
    #[test]
    fn augmented_lagrangian() {
        super::ring_drop_with_coulomb_friction("augmented_lagrangian");
    }
    #[test]
    fn implicit_projection() {
        super::ring_drop_with_coulomb_friction("implicit_projection");
    }
    #[test]
    fn augmented_lagrangian_on_trapezoid_gaps() {
        super::ring_drop_with_coulomb_friction_on(
            "augmented_lagrangian",
            &["contact.gap_displacement=\"trapezoid\""],
        );
    }
}

/// Why the stick test damps its block: gravity switched on at t = 0 on an elastic block resting
/// on a frictionless floor (flat, soft way, default scheme). Undamped, the floor's reaction
/// keeps swinging (the bar under a suddenly applied load; measured 0.64 to 1.35 m g in 2D, 0.59
/// to 1.39 m g in 3D between 0.1 s and 0.2 s), so Coulomb's threshold mu F_n dips below
/// what holds a block on a slope (tan(theta) / mu of the mean: 0.67 at 25 degrees and
/// mu = 0.7, 0.82 at 30) once a period, and the block must creep; with the 5 % material
/// damping the reaction settles to m g.
fn undamped_floor_reaction_keeps_swinging<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let mass = 1000.0 * 0.2 * 0.1 * if D == 3 { 0.1 } else { 1.0 };
    let weight = mass * G;
    for (damping, label) in [
        (RayleighDamping::NONE, "undamped"),
        (material_damping(0.05), "damped"),
    ] {
        let mut sim = slope::<D>(0.0, ContactMethod::SoftWay, damping, 0.0, 1e-3);
        let (mut low, mut high) = (f64::INFINITY, 0.0f64);
        while sim.state().time < 0.2 - 1e-9 {
            let r = sim.step().unwrap();
            if r.time > 0.1 {
                let f = r.contact_forces[0][D - 1];
                low = low.min(f);
                high = high.max(f);
            }
        }
        eprintln!(
            "{D}D {label}: floor reaction between {:.3} and {:.3} m g over 0.1..0.2 s",
            low / weight,
            high / weight
        );
        if damping.is_none() {
            record("floor-reaction", "undamped low / mg", low / weight);
            record("floor-reaction", "undamped high / mg", high / weight);
            assert!(low < 0.7 * weight && high > 1.3 * weight, "{low} {high}");
        } else {
            let off = (low - weight).abs().max((high - weight).abs());
            record("floor-reaction", "damped F / mg - 1", off / weight);
            assert!(
                (low - weight).abs() < 2e-2 * weight && (high - weight).abs() < 2e-2 * weight,
                "{low} {high}"
            );
        }
    }
}

both_dims!(undamped_floor_reaction_keeps_swinging);

/// A 5 cm block (E = 1 MPa, 20 % of critical damping at its first mode) set down on a 0.2 m
/// block resting on the floor, Tresca friction (100 Pa) everywhere, the default scheme and
/// tolerances, h = 1 ms. Once both have settled (50 ms), the upper block is launched at
/// 0.3 m/s: over the next 40 ms its momentum falls by limit x A per second (A its bottom face:
/// 2 m/s^2), the lower one stays, held by the floor (whose limit over its 8x larger face the
/// drag does not reach), and the energy account closes over the slide. The lower block's top
/// nodes are 2.5 cm apart and the upper block starts half a spacing off them and slides
/// 1.04 cm, so the lower nodes under it carry exactly A throughout. (Launched at the first
/// touch, the block's landing opens and closes the contact, and Tresca acts only while it is
/// closed.) Under implicit projection the 3D blocks of `determinism.rs` stopped at the first
/// touch while the friction of a law that does not follow the normal force was switched by
/// the sign of that force within Newton.
fn a_block_slides_on_a_block_under_tresca<const D: usize>(method: ContactMethod)
where
    Dim<D>: SpatialDim<D>,
{
    let limit = 100.0;
    block_slides_on_a_block::<D>(
        method,
        FrictionLaw::Tresca {
            limit,
            regularization: 1e-4,
        },
        area_law_slowing::<D>(limit),
    );
}

/// The slowing (m/s^2) of the upper block under an area law's limit (Pa): limit x A / m, A its
/// bottom face (length x unit thickness in 2D), m its mass (5 cm high, 1000 kg/m^3).
fn area_law_slowing<const D: usize>(limit: f64) -> f64 {
    let area = if D == 2 { 0.05 } else { 0.05 * 0.05 };
    limit * area / (1000.0 * area * 0.05)
}

/// Viscoplastic friction `-a A |v|^(p-1) v` at exponent p = 0: a regularised Tresca law
/// through the smooth branch (no return map), the same slowing `a A / m`.
fn a_block_slides_on_a_block_under_viscoplastic_friction<const D: usize>(method: ContactMethod)
where
    Dim<D>: SpatialDim<D>,
{
    let coefficient = 100.0;
    block_slides_on_a_block::<D>(
        method,
        FrictionLaw::Viscoplastic {
            coefficient,
            exponent: 0.0,
            regularization: 1e-4,
        },
        area_law_slowing::<D>(coefficient),
    );
}

fn a_block_slides_on_a_block_under_coulomb<const D: usize>(method: ContactMethod)
where
    Dim<D>: SpatialDim<D>,
{
    let mu = 0.3;
    block_slides_on_a_block::<D>(
        method,
        FrictionLaw::Coulomb {
            coefficient: mu,
            regularization: 1e-4,
        },
        mu * G,
    );
}

fn block_slides_on_a_block<const D: usize>(
    method: ContactMethod,
    friction: FrictionLaw,
    deceleration: f64,
) where
    Dim<D>: SpatialDim<D>,
{
    let (v0, settle, slide) = (0.3, 0.05, 0.04);
    let (lower_size, lower_cells, shift) = if D == 2 {
        ([0.2, 0.05, 0.0], [8, 2, 1], [0.0625, 0.05, 0.0])
    } else {
        ([0.2, 0.1, 0.05], [8, 4, 2], [0.0625, 0.0375, 0.05])
    };
    let lower: Mesh<D> = block(lower_size, lower_cells, false);
    let mut upper: Mesh<D> = block([0.05, 0.05, 0.05], [2, 2, 2], false);
    upper.translate(&vec_d(shift));
    let (young, density) = (1e6, 1000.0);
    let rubber = Material::LinearElastic(LinearElastic::new(young, 0.3, density).unwrap());
    // 20 % of critical at the quarter wave through the 5 cm height.
    let omega = std::f64::consts::PI * (young / density).sqrt() / (2.0 * 0.05);
    let damping = 2.0 * 0.2 / omega;
    let mut g = [0.0; 3];
    g[D - 1] = -G;
    let mut sim = Simulation::<D>::builder()
        .time_step(1e-3)
        .gravity(vec_d(g))
        .body(Body::new("lower", lower, rubber).with_damping(0.0, damping))
        .body(Body::new("upper", upper, rubber).with_damping(0.0, damping))
        .obstacle(common::floor::<D>())
        .contact(ContactSettings {
            method,
            penalty: 1e9,
            friction,
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    run_to(&mut sim, settle);
    let ids = sim.body_ids();
    for node in 0..sim.body_nodes(ids[1]).unwrap().len() {
        let v = sim.velocity(ids[1], node).unwrap() + vec_d::<D>([v0, 0.0, 0.0]);
        sim.set_velocity(ids[1], node, v).unwrap();
    }
    let ledger = |sim: &Simulation<D>| {
        let e = sim.energies();
        e.total() + e.dissipated - e.external_work
    };
    let (before, kinetic) = (ledger(&sim), sim.energies().kinetic);
    let mean_velocity = |sim: &Simulation<D>, b: BodyId| {
        sim.body_momentum(b).unwrap()[0] / sim.body_mass(b).unwrap()
    };
    let start = mean_velocity(&sim, ids[1]);
    run_to(&mut sim, settle + slide);
    let exact = -deceleration * slide;
    let change = mean_velocity(&sim, ids[1]) - start;
    let lower_velocity = mean_velocity(&sim, ids[0]);
    let error = (ledger(&sim) - before).abs() / kinetic;
    eprintln!(
        "{D}D {method:?} {friction:?}: velocity change {change:.5} m/s against {exact:.5} \
         ({:.3}x), lower block {lower_velocity:.2e} m/s, energy error {error:.2e}",
        change / exact
    );
    record(
        "friction-between-bodies",
        match friction {
            FrictionLaw::Coulomb { .. } => "coulomb dv",
            FrictionLaw::Tresca { .. } => "tresca dv",
            _ => "viscoplastic dv",
        },
        (change - exact) / exact,
    );
    assert!(
        (change - exact).abs() < 0.02 * exact.abs(),
        "{D}D {method:?}: velocity change {change} m/s, expected {exact}"
    );
    assert!(
        lower_velocity.abs() < 1e-3,
        "{D}D {method:?}: the lower block moves at {lower_velocity} m/s"
    );
    assert!(
        error < 1e-2,
        "{D}D {method:?}: energy error {error} of the launch's"
    );
}
