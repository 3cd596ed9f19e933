//! Every bundled scene without a test of its own runs (shortened where long) with physical
//! assertions against closed-form solutions (the tilting floor: against the slope's static
//! balance and atan(mu)). The ring drop and the gripper have theirs
//! (tests/friction.rs, tests/contact.rs, tests/gripper.rs). None starts with an overlap or
//! lets a body fall through an obstacle (issue 14).
#![cfg(feature = "formats")]

use crate::common;

use softway::dim::{Dim, SpatialDim};
use softway::Simulation;

/// The scene's simulation, its end time, and the global node nearest `point`.
fn scene<const D: usize>(
    name: &str,
    overrides: &[&str],
    point: [f64; 3],
) -> (Simulation<D>, f64, usize)
where
    Dim<D>: SpatialDim<D>,
{
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    let scene = common::fixture::<D>(name, &overrides);
    let sim = scene.simulation().unwrap();
    // No overlap at t = 0, of any depth.
    assert_eq!(sim.check_overlaps().unwrap(), [], "{name}");
    let node = (0..sim.reference_positions().len())
        .min_by(|&a, &b| {
            let d = |n: usize| {
                (0..D)
                    .map(|k| (sim.reference_positions()[n][k] - point[k]).powi(2))
                    .sum::<f64>()
            };
            d(a).total_cmp(&d(b))
        })
        .unwrap();
    (sim, scene.end_time, node)
}

/// Runs to `end`, returning (time, displacement component `k` of `node`) after every step.
fn history<const D: usize>(
    sim: &mut Simulation<D>,
    end: f64,
    node: usize,
    k: usize,
) -> Vec<(f64, f64)>
where
    Dim<D>: SpatialDim<D>,
{
    let mut out = Vec::new();
    while sim.state().time < end - 1e-9 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("t = {}: {e}", sim.state().time));
        assert_eq!(sim.fell_through(), None, "t = {}", r.time);
        out.push((r.time, sim.state().displacement[node * D + k]));
    }
    out
}

#[test]
fn cantilever() {
    let (mut sim, end, tip) = scene::<2>("cantilever", &[], [2.0, 0.1, 0.0]);
    let h = history(&mut sim, end, tip, 1);
    // Euler-Bernoulli with shear, plane strain: q L^4 / (8 E' I) + q L^2 / (2 kappa G A).
    let (e, nu, rho, l, t): (f64, f64, f64, f64, f64) = (2.1e11, 0.3, 7800.0, 2.0, 0.2);
    let q = rho * 9.81 * t;
    let ep = e / (1.0 - nu * nu);
    let i = t.powi(3) / 12.0;
    let g = e / (2.0 * (1.0 + nu));
    let fixed = q * l.powi(4) / (8.0 * ep * i) + q * l * l / (2.0 * 5.0 / 6.0 * g * t);
    let mean = -h.iter().map(|p| p.1).sum::<f64>() / h.len() as f64;
    let deepest = -h.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    eprintln!(
        "cantilever: mean tip deflection {mean:.4e} m, deepest {deepest:.4e}, static {fixed:.4e}"
    );
    // Measured -4.5 % and -2.8 % (Quad4, 4 cells through the depth, fully integrated).
    common::verify::record("scene-cantilever", "mean", (mean - fixed) / fixed);
    common::verify::record(
        "scene-cantilever",
        "deepest",
        (deepest - 2.0 * fixed) / (2.0 * fixed),
    );
    assert!((mean - fixed).abs() < 0.06 * fixed);
    assert!((deepest - 2.0 * fixed).abs() < 0.05 * 2.0 * fixed);
}

#[test]
fn cantilever_3d() {
    let (mut sim, end, tip) = scene::<3>("cantilever_3d", &[], [1.0, 0.05, 0.05]);
    let h = history(&mut sim, end, tip, 2);
    // First bending mode: f = 1.875^2 / (2 pi L^2) sqrt(E I / (rho A)).
    let (e, rho, l, a): (f64, f64, f64, f64) = (2.1e11, 7800.0, 1.0, 0.1);
    let f = 1.875f64.powi(2) / (2.0 * std::f64::consts::PI * l * l)
        * (e * a.powi(4) / 12.0 / (rho * a * a)).sqrt();
    let crossings: Vec<f64> = h
        .windows(2)
        .filter(|w| w[0].1 > 0.0 && w[1].1 <= 0.0)
        .map(|w| w[0].0 + (w[1].0 - w[0].0) * w[0].1 / (w[0].1 - w[1].1))
        .collect();
    let period = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
    eprintln!(
        "cantilever_3d: period {period:.4e} s against {:.4e} s ({} crossings)",
        1.0 / f,
        crossings.len()
    );
    // Measured 6.3 % short (6.7 % with the uniform kick before): the fully integrated Hex8,
    // 2 x 2 cells across, is stiffer in bending than the beam (shear locking; issue 11 adds
    // B-bar / reduced integration).
    common::verify::record("scene-cantilever-3d", "period", period * f - 1.0);
    assert!(crossings.len() >= 2);
    assert!((period * f - 1.0).abs() < 0.08, "{}", period * f);
}

#[test]
fn gmsh_plate() {
    let (mut sim, end, top) = scene::<2>("gmsh_plate", &[], [1.0, 1.0, 0.0]);
    let h = history(&mut sim, end, top, 1);
    // A column under its own weight, suddenly loaded: rho g H^2 / (2 E) static.
    let fixed = 1100.0 * 9.81 / (2.0 * 1.0e6);
    let deepest = -h.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let e = sim.energies();
    let error = (e.total() - sim.initial_energy() - e.external_work + e.dissipated).abs()
        / sim.energy_reference();
    eprintln!("gmsh_plate: deepest {deepest:.4e} m, static {fixed:.4e}, energy error {error:.2e}");
    // A suddenly loaded column overshoots to about twice its static compression (measured
    // 1.79 times here: plane stress lets it bulge sideways, nu = 0.45).
    common::verify::record("scene-gmsh-plate", "deepest / static", deepest / fixed);
    common::verify::record("scene-gmsh-plate", "energy", error);
    assert!(deepest > 1.5 * fixed && deepest < 2.1 * fixed);
    assert!(error < 5e-3);
}

#[test]
fn thick_cylinder() {
    let (mut sim, end, outer) = scene::<2>("thick_cylinder", &[], [2.0, 0.1, 0.0]);
    let h = history(&mut sim, end, outer, 0);
    // Lame, plane strain (ends held), bore displaced by u_a, outer surface free:
    // u = A r + B / r, A = (1 - 2 nu) B / b^2, u(b) / u_a = ((1 - 2 nu) / b + 1 / b) / ((1 - 2 nu) a / b^2 + 1 / a).
    let (a, b, nu) = (1.0, 2.0, 0.3);
    let u_a = 1.0e-3 * end;
    let ratio = ((1.0 - 2.0 * nu) / b + 1.0 / b) / ((1.0 - 2.0 * nu) * a / (b * b) + 1.0 / a);
    let u = h.last().unwrap().1;
    eprintln!(
        "thick_cylinder: outer {u:.6e} m against Lame {:.6e}",
        ratio * u_a
    );
    // Measured 2e-5 relative.
    common::verify::record(
        "scene-thick-cylinder",
        "u(b)",
        (u - ratio * u_a) / (ratio * u_a),
    );
    assert!((u - ratio * u_a).abs() < 1e-3 * ratio * u_a);
}

/// The rolling ring (shortened to 0.3 s): the centre accelerates at g sin(20) / (1 + k),
/// k = (R1^2 + R2^2) / (2 R2^2), within 1 % (least squares on the mean node velocity over
/// 0.1..0.3 s), and the ring turns by its travel over R within 1 %.
#[test]
fn rolling_ring() {
    let (mut sim, _, _) = scene::<2>("rolling_ring", &[], [0.0, 0.2, 0.0]);
    let mean = |sim: &Simulation<2>, values: &[f64]| {
        let n = sim.reference_positions().len();
        (0..n).map(|i| values[2 * i]).sum::<f64>() / n as f64
    };
    let (mut t, mut v) = (Vec::new(), Vec::new());
    while sim.state().time < 0.3 - 1e-9 {
        sim.step()
            .unwrap_or_else(|e| panic!("t = {}: {e}", sim.state().time));
        if sim.state().time > 0.1 - 1e-9 {
            t.push(sim.state().time);
            v.push(mean(&sim, &sim.state().velocity));
        }
    }
    let a = common::least_squares_slope(&t, &v);
    let k = (0.05f64.powi(2) + 0.1f64.powi(2)) / (2.0 * 0.01);
    let expected = 9.81 * 20f64.to_radians().sin() / (1.0 + k);
    let travel = mean(&sim, &sim.state().displacement);
    let turned = sim.body_rotation(sim.body_ids()[0]).unwrap();
    eprintln!(
        "rolling ring: a = {a:.4} against {expected:.4}, turned {turned:.4} rad, travel / R {:.4}",
        travel / 0.1
    );
    assert!(
        (a / expected - 1.0).abs() < 0.01,
        "a = {a} against {expected}"
    );
    assert!(
        (turned / (travel / 0.1) - 1.0).abs() < 0.01,
        "turned {turned} against {}",
        travel / 0.1
    );
}

/// The paper's first example with the hypoelastic law (shortened to the first bounce,
/// 0.35 s): the ring lands and leaves the base again, its energy account closes within 2 %,
/// and it stays a ring (no node's distance from the centroid changes by more than 5 %).
#[test]
fn ring_drop_hypoelastic() {
    let (mut sim, _, _) = scene::<2>(
        "ring_drop",
        &["bodies.0.material = { model = \"hypoelastic\", youngs_modulus = 5.0e7, poissons_ratio = 0.3, density = 1000.0 }"],
        [0.0, 0.2, 0.0],
    );
    let mut touched = false;
    let mut left = false;
    while sim.state().time < 0.35 - 1e-9 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("t = {}: {e}", sim.state().time));
        if r.active_contacts > 0 {
            touched = true;
        } else if touched {
            left = true;
        }
    }
    let error = common::energy_error(&sim);
    eprintln!("hypoelastic ring drop: touched {touched}, left {left}, energy error {error:.3e}");
    assert!(touched && left);
    assert!(error < 0.02, "{error}");
    let (x0, x) = (sim.reference_positions(), sim.positions());
    let centre = |p: &[nalgebra::SVector<f64, 2>]| {
        p.iter().sum::<nalgebra::SVector<f64, 2>>() / p.len() as f64
    };
    let (c0, c) = (centre(x0), centre(&x));
    for (p0, p) in x0.iter().zip(&x) {
        let (r0, r) = ((p0 - c0).norm(), (p - c).norm());
        assert!((r / r0 - 1.0).abs() < 0.05, "radius {r0} -> {r}");
    }
}

/// The stack of three rubber blocks at a game's step, run to 1 s: it lands and stands, held by
/// friction on its offsets. The floor carries the three blocks' weight (within 1 % over the
/// last 0.2 s: they still rock), the top block sits 8 mm (the three 2-3 mm gaps) plus the
/// stack's compression lower and within 2 mm of where it started sideways (frictionless,
/// the blocks slide apart by centimetres and topple), no node is more than 20 um inside
/// another body (9.3e-6 m since the end-of-step projection moves the master side's nodes out
/// too, 2026-12-02; 2.6e-5 m before), and the energy account closes within 2 % (5.2e-5
/// measured).
/// Every step converges at full size: the landing's step 6 was cut in halves until Newton's
/// merit measured a held constraint's curvature in its own units (2026-12-01).
#[test]
fn block_stack() {
    let (mut sim, _, _) = scene::<3>("block_stack", &["simulation.end_time=1.0"], [0.0; 3]);
    let top = sim.body_nodes(sim.body_id("top").unwrap()).unwrap();
    let centre = |sim: &Simulation<3>| {
        let x = sim.positions();
        top.clone().map(|n| x[n]).sum::<nalgebra::Vector3<f64>>() / top.len() as f64
    };
    let start = centre(&sim);
    let weight = 3.0 * 1000.0 * 1e-3 * 9.81;
    let (mut deepest, mut floor_force, mut samples, mut cuts) = (0.0f64, 0.0, 0, 0);
    let mut most_iterations = (0, 0);
    let mut factorisations = 0;
    while sim.state().time < 1.0 - 1e-9 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("t = {}: {e}", sim.state().time));
        assert_eq!(sim.fell_through(), None, "t = {}", r.time);
        deepest = deepest.max(r.max_penetration);
        cuts += r.cuts;
        factorisations += r.factorisations;
        most_iterations = most_iterations.max((r.iterations, r.step));
        if r.time > 0.8 {
            floor_force += r.contact_forces[0][2];
            samples += 1;
        }
    }
    let moved = centre(&sim) - start;
    let floor_force = floor_force / samples as f64;
    let error = common::energy_error(&sim);
    eprintln!(
        "block stack: top block moved {moved:?} m, floor force {floor_force:.3} N of \
         {weight:.3}, deepest {deepest:.2e} m, account {error:.2e}, {cuts} cut(s), \
         {factorisations} factorisations"
    );
    // 427 in the 60 steps; 527 while the end-of-step projection moved its round-off depths
    // out (2026-12-01; the performance chapter); 449 since it moves master nodes too, 437
    // since it watches the points it could press in (2026-12-02).
    assert!(factorisations <= 470, "{factorisations} factorisations");
    assert_eq!(cuts, 0, "steps cut");
    assert!((floor_force / weight - 1.0).abs() < 1e-2, "{floor_force} N");
    assert!(
        (-9.5e-3..-8e-3).contains(&moved.z),
        "top block sank {} m",
        -moved.z
    );
    assert!(
        moved.xy().norm() < 2e-3,
        "top block slid {} m",
        moved.xy().norm()
    );
    assert!(deepest < 2e-5, "penetration {deepest} m");
    assert!(error < 2e-2, "account {error}");
    // Room below `max_iterations` (50), where a step is retried and then cut: the landing's
    // step 7 took all 50 until the secant slip tangent and the inexact threshold passes
    // (2026-12-01: 39).
    assert!(
        most_iterations.0 <= 42,
        "step {} took {} Newton iterations",
        most_iterations.1,
        most_iterations.0
    );
}

/// The same stack under the augmented Lagrangian (zeta = 1e9 Pa/m, the scene's Coulomb 0.5),
/// to 0.5 s: the landing and the first ringing. Returns the top block's move (m), the
/// deepest point (m), the energy account, the scheme's account and the cut steps.
fn stack_under_the_augmented_lagrangian() -> (nalgebra::Vector3<f64>, f64, f64, f64, usize) {
    let (mut sim, _, _) = scene::<3>(
        "block_stack",
        &[
            "simulation.end_time=0.5",
            "contact.method=\"augmented_lagrangian\"",
            "contact.penalty=1e9",
        ],
        [0.0; 3],
    );
    let top = sim.body_nodes(sim.body_id("top").unwrap()).unwrap();
    let centre = |sim: &Simulation<3>| {
        let x = sim.positions();
        top.clone().map(|n| x[n]).sum::<nalgebra::Vector3<f64>>() / top.len() as f64
    };
    let start = centre(&sim);
    let mut monitor = softway::simulation::RunMonitor::new(&sim);
    let (mut deepest, mut cuts, mut iterations) = (0.0f64, 0, 0);
    while sim.state().time < 0.5 - 1e-9 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("t = {}: {e}", sim.state().time));
        monitor
            .step(&sim, &r)
            .unwrap_or_else(|e| panic!("the run monitor stopped the run: {e}"));
        assert_eq!(sim.fell_through(), None, "t = {}", r.time);
        deepest = deepest.max(r.max_penetration);
        cuts += r.cuts;
        iterations += r.iterations;
    }
    let moved = centre(&sim) - start;
    let (error, scheme) = (common::energy_error(&sim), monitor.scheme_energy_drift());
    eprintln!(
        "block stack, augmented Lagrangian: top block moved {moved:?} m, deepest \
         {deepest:.2e} m, account {error:.2e}, scheme's {scheme:.2e}, {iterations} iterations, \
         {cuts} cut(s)"
    );
    (moved, deepest, error, scheme, cuts)
}

/// The stack under the augmented Lagrangian with its default configuration gaps: it stopped at
/// step 4 (no convergence in 50 iterations) until Newton solved slip's coupling (2026-12-03).
/// It lands and rings without a cut step, sinks like the default method's stack, and closes
/// its accounts; the configuration gaps' offset stores about one step's travel at the landing,
/// 3.0e-3 m, which the run's summary warns about (measured 3.01e-3 m, account 1.4e-3).
#[test]
fn block_stack_under_the_augmented_lagrangian() {
    let (moved, deepest, error, scheme, cuts) = stack_under_the_augmented_lagrangian();
    assert_eq!(cuts, 0, "steps cut");
    assert!(
        (-9.5e-3..-8e-3).contains(&moved.z),
        "top block sank {} m",
        -moved.z
    );
    assert!(deepest < 3.1e-3, "penetration {deepest} m");
    assert!(error < 2e-2, "account {error}");
    assert!(scheme < 1e-8, "scheme's account {scheme}");
}

/// Open: on configuration gaps the penalty methods' top block slides about 1 cm at the landing
/// and then holds, where implicit projection's stays within 1 mm.
#[test]
#[ignore = "the top block slides 11.2 mm sideways at the landing (2026-12-03; the soft way's probe 11.6 mm, with slip's coupling solved or not): the configuration gaps' stored offset, 3.0e-3 m deep; on trapezoid gaps 0.34 mm at 1.5 s, resting 8.5 mm down as under implicit projection since the persistency stop keeps the configuration on its gaps (the soft way 3.3 mm)"]
fn block_stack_under_the_augmented_lagrangian_holds_its_offsets() {
    let (moved, ..) = stack_under_the_augmented_lagrangian();
    assert!(
        moved.xy().norm() < 2e-3,
        "top block slid {} m",
        moved.xy().norm()
    );
}

/// The tilting floor (Coulomb mu = 0.4, the plate turning at 0.5 rad/s from 0.1 s), run to
/// 1 s (25.8 degrees). Per 10-step window, the plate's force along it over its force across
/// it: while the block holds it follows tan(theta) (the static balance on the slope); it
/// reaches mu (the block slides) near atan(mu) = 21.8 degrees, and stays there.
/// The resting block (the soft way on trapezoid gaps with the persistency stop): it lands and
/// rests on its penalty, its bottom face's centre still (at most 2.4e-8 m/s over the last 10
/// steps, 2026-12-03) and within twice the pressure over zeta (1.04e-6 m below the floor
/// against 9.81e-7 m), its account closed (3.4e-11). With `contact.persistency_stop=false`
/// (the paper's soft way) the same node alternates at 3.5e-2 m/s from step to step.
#[test]
fn resting_block() {
    let run = |overrides: &[&str]| {
        let (mut sim, end, bottom) = scene::<3>("resting_block", overrides, [0.05, 0.05, 0.02]);
        let mut fastest = 0.0f64;
        while sim.state().time < end - 1e-9 {
            let r = sim
                .step()
                .unwrap_or_else(|e| panic!("t = {}: {e}", sim.state().time));
            assert_eq!(sim.fell_through(), None, "t = {}", r.time);
            if sim.state().time > end - 10.5 / 60.0 {
                fastest = fastest.max(sim.state().velocity[bottom * 3 + 2].abs());
            }
        }
        let depth = -0.02 - sim.state().displacement[bottom * 3 + 2];
        (fastest, depth, common::energy_error(&sim))
    };
    let (fastest, depth, account) = run(&[]);
    let pressure_depth = 1000.0 * 9.81 * 0.1 / 1e9;
    eprintln!(
        "resting block: bottom centre at most {fastest:.2e} m/s over the last 10 steps, \
         {depth:.3e} m below the floor (pressure / zeta {pressure_depth:.3e} m), account \
         {account:.2e}"
    );
    assert!(fastest < 1e-6, "{fastest} m/s");
    assert!(
        depth > 0.0 && depth < 2.0 * pressure_depth,
        "{depth} m below the floor"
    );
    assert!(account < 1e-6, "account {account}");
    let (alternating, ..) = run(&["contact.persistency_stop=false"]);
    eprintln!("without the stop: {alternating:.2e} m/s");
    assert!(alternating > 5e-3, "{alternating} m/s");
}

#[test]
fn tilting_floor() {
    let (mut sim, _, centre) = scene::<2>(
        "tilting_floor",
        &["simulation.end_time=1.0"],
        [0.1, 0.05, 0.0],
    );
    let (w, mu) = (0.5f64, 0.4f64);
    let theta = |t: f64| w * (t - 0.1).max(0.0);
    let (mut sums, mut windows) = ([0.0; 3], Vec::new());
    let mut slid_at_15 = None;
    while sim.state().time < 1.0 - 1e-9 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("t = {}: {e}", sim.state().time));
        let th = theta(r.time);
        let (t, n) = (
            nalgebra::Vector2::new(th.cos(), th.sin()),
            nalgebra::Vector2::new(-th.sin(), th.cos()),
        );
        let f = nalgebra::Vector2::new(r.contact_forces[0][0], r.contact_forces[0][1]);
        sums = [sums[0] + f.dot(&t), sums[1] + f.dot(&n), sums[2] + th];
        if r.step % 10 == 0 {
            windows.push((sums[2] / 10.0, sums[0] / sums[1]));
            sums = [0.0; 3];
        }
        if slid_at_15.is_none() && th >= 15f64.to_radians() {
            slid_at_15 = Some(block_slide(&sim, centre, th));
        }
    }
    let onset = windows
        .iter()
        .find(|(th, ratio)| *th > 0.0 && *ratio >= 0.99 * mu)
        .map(|w| w.0.to_degrees())
        .expect("the block slides");
    let holding = windows
        .iter()
        .filter(|(th, _)| (5f64.to_radians()..18f64.to_radians()).contains(th))
        .map(|(th, ratio)| (ratio / th.tan() - 1.0).abs())
        .fold(0.0, f64::max);
    let beyond = windows
        .iter()
        .filter(|(th, _)| *th > (mu.atan() + 1.5f64.to_radians()))
        .map(|(_, ratio)| (ratio / mu - 1.0).abs())
        .fold(0.0, f64::max);
    let (slid_15, slid_end) = (
        slid_at_15.unwrap(),
        block_slide(&sim, centre, theta(sim.state().time)),
    );
    eprintln!(
        "tilting_floor: friction / normal reaches mu at {onset:.2} degrees (atan mu = {:.2}); \
         before 18 degrees it is within {:.1} % of tan(theta), past {:.1} degrees within {:.2} % \
         of mu; the block slid {:.2} mm by 15 degrees, {:.2} mm by 25.8",
        mu.atan().to_degrees(),
        100.0 * holding,
        mu.atan().to_degrees() + 1.5,
        100.0 * beyond,
        1e3 * slid_15,
        1e3 * slid_end
    );
    // Measured 21.64 degrees; 0.1 % from tan(theta) at worst; 0.34 %; -0.11 mm, 2.36 mm
    // (2026-11-30; 0.5 %, 0.00 % and -0.10 mm before the penalty methods' tangential spring
    // was capped at four diagonals per step).
    // With the small-strain law the block crept (10.9 % below tan(theta), 1.41 mm by 15
    // degrees, 11.7 mm by the end, onset at 22.8): it read its own turn as strain.
    assert!((onset - mu.atan().to_degrees()).abs() < 1.0, "{onset}");
    assert!(holding < 0.02 && beyond < 0.01, "{holding} {beyond}");
    assert!(
        slid_15.abs() < 5e-4 && slid_end > 1e-3,
        "{slid_15} {slid_end}"
    );
}

/// How far the block's centre node has slid down the plate turned by `theta` [m].
fn block_slide(sim: &Simulation<2>, node: usize, theta: f64) -> f64 {
    let x = sim.positions()[node];
    // The pivot is the plate's point (0.1, 0) under the block's centre, (0.1, 0.05) at rest.
    -((x.x - 0.1) * theta.cos() + x.y * theta.sin())
}

/// The paper's second example (`octagon_compression.toml`), shortened to 10 of its 30
/// increments: Norton-Hoff, no inertia, viscoplastic friction on the die. The billet's area
/// is kept within 0.5 % (the volumetric penalty), the die's work is dissipated by the flow and
/// the friction (energy account within 2 %), and the die's force lies between the plane-strain
/// flow stress 2 K (2 v / H)^m over the contact width and over the billet's full width (10 m).
#[test]
fn octagon_compression() {
    let (mut sim, _, _) = scene::<2>("octagon_compression", &[], [0.0, 0.0, 0.0]);
    let area = |sim: &Simulation<2>| {
        let mut mesh = sim.model().bodies[0].mesh.clone();
        mesh.nodes = sim.positions();
        softway::mesh::generators::measure(&mesh)
    };
    let area0 = area(&sim);
    let mut iterations = Vec::new();
    let mut force = 0.0;
    for _ in 0..10 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("t = {}: {e}", sim.state().time));
        iterations.push(r.iterations);
        force = r.contact_forces[0][1];
    }
    let change = area(&sim) / area0 - 1.0;
    let error = common::energy_error(&sim);
    // The contact width: the top's flat (the octagon's top side, 4.14 m, and what has spread).
    let top: f64 = sim
        .positions()
        .iter()
        .filter(|p| p.y > 10.0 - 0.1 * sim.state().time - 1e-3)
        .map(|p| p.x)
        .fold(0.0, f64::max);
    let height = 10.0 - 0.1 * sim.state().time;
    let flow = 2.0 * (2.0 * 0.1 / height).powf(0.1);
    let estimate = flow * top;
    eprintln!(
        "octagon: area {:+.3} %, energy account {error:.2e}, die force {:.4} N against {estimate:.4} \
         (contact width {top:.3} m), iterations per step {iterations:?}",
        100.0 * change,
        -force
    );
    assert!(change.abs() < 0.005, "{change}");
    assert!(error < 0.02, "{error}");
    assert!(
        -force > estimate && -force < flow * 10.0,
        "{force}: {estimate} .. {}",
        flow * 10.0
    );
}

#[test]
fn folding_strip() {
    // Under the soft way (zeta = 1e9 Pa/m, tests/self_contact.rs's).
    folding_strip_with(&["contact.method=\"soft_way\"", "contact.penalty=1e9"]);
}

/// With Tresca friction (1000 Pa) on the fold, under the soft way: an area law over a
/// self-contact patch, which one pass often carries alone. Before a slave counted as closed
/// where the other pass held the patch, this run stopped at step 568 (no convergence, the
/// plate's corner), and the augmented Lagrangian's too.
#[test]
fn folding_strip_with_tresca_friction() {
    folding_strip_with(&[
        "contact.method=\"soft_way\"",
        "contact.penalty=1e9",
        "contact.friction={law=\"tresca\",limit=1000.0}",
    ]);
}

/// With Tresca friction (1000 Pa) under the scene's implicit projection. The run monitor
/// stopped it at step 305 (exit status 3): where the upper arm first touched the lower one,
/// two points held through a contact-set cycle pulled 0.24 N/m while nothing else pressed in
/// that step, though the fold carried 0.6 to 7.6 N/m in the steps around it; the held
/// tension is now also measured against the most the run's contacts carried in a step.
/// Measured 2026-11-29: 72 cut steps, contact-set cycles in 22, deepest gap 1.19e-5 m.
#[test]
fn folding_strip_with_tresca_friction_under_implicit_projection() {
    folding_strip_with(&["contact.friction={law=\"tresca\",limit=1000.0}"]);
}

/// The scene as written: implicit projection. Measured: the free end's faces at most 1.77e-5 m
/// across each other (a corner of one arm against the end of the other, which one pass does
/// not hold), 1.17e-5 m deep by `Simulation::overlaps`, 1.2e-2 of the reference dissipated.
/// It created 1.34 of the reference while the end-of-step projection also moved the pairs
/// Newton had dropped (the contact chapter, Self-contact).
#[test]
fn folding_strip_default_method() {
    folding_strip_with(&[]);
}

/// The whole scene: the upper arm's free end comes down with the plate onto the lower arm,
/// which it does not cross.
fn folding_strip_with(overrides: &[&str]) {
    let (mut sim, end, _) = scene::<2>("folding_strip", overrides, [0.0, 0.0, 0.0]);
    let id = sim.body_id("strip").unwrap();
    // The fold's two faces at the free end: the upper arm's underside, the lower arm's top.
    let nearest = |p: [f64; 2]| {
        (0..sim.reference_positions().len())
            .min_by(|&a, &b| {
                let d = |n: usize| {
                    let x = sim.reference_positions()[n];
                    (x.x - p[0]).powi(2) + (x.y - p[1]).powi(2)
                };
                d(a).total_cmp(&d(b))
            })
            .unwrap()
    };
    let (upper, lower) = (nearest([0.0, 0.02]), nearest([0.0, 0.01]));
    let mut self_steps = 0;
    let mut closest: f64 = f64::INFINITY;
    let mut deepest_self: f64 = 0.0;
    // The command line's monitor too: a run it stops exits with status 3.
    let mut monitor = softway::simulation::RunMonitor::new(&sim);
    while sim.state().time < end - 1e-9 {
        let report = sim
            .step()
            .unwrap_or_else(|e| panic!("t = {}: {e}", sim.state().time));
        monitor
            .step(&sim, &report)
            .unwrap_or_else(|e| panic!("the run monitor stopped the run: {e}"));
        let own = softway::simulation::ContactMaster::Body(id);
        if sim
            .contacts()
            .iter()
            .any(|c| c.master == own && c.normal_force > 0.0)
        {
            self_steps += 1;
        }
        let x = sim.positions();
        closest = closest.min(x[upper].y - x[lower].y);
        for o in sim.overlaps() {
            if o.other.contains("itself") || o.other.contains("strip") {
                deepest_self = deepest_self.max(o.depth);
            }
        }
    }
    eprintln!("deepest self-overlap {deepest_self:e}");
    let e = sim.energies();
    let created = (e.total() - sim.initial_energy() - e.external_work) / sim.energy_reference();
    eprintln!(
        "folding strip: {self_steps} steps with self-contact, the free end's faces at least \
         {closest:.3e} m apart (1 cm at the start), energy created {created:.2e}"
    );
    assert!(self_steps >= 20, "{self_steps} steps with self-contact");
    // The faces met and did not cross beyond the penalty's 2 p / zeta (7e-5 m in
    // tests/self_contact.rs; measured 1.24e-5 m).
    assert!(
        closest > -7e-5,
        "the upper arm went {closest} m through the lower one"
    );
    assert!(closest < 1e-6, "the arms stayed {closest} m apart");
    assert!(created < 2e-2, "energy created {created}");
    // No node ends a step deeper in the strip's own cells than the faces' bound.
    assert!(
        deepest_self < 7e-5,
        "a node {deepest_self} m inside the strip"
    );
    // Implicit projection's velocity penalty (1e4 times the largest diagonal) leaves the
    // contact matrices within reach of single precision: no factor failed its refinement.
    assert!(
        !sim.state().contact_memory.double_precision_only,
        "a single-precision contact factor failed its refinement"
    );
}

/// The tube crush under the default method, implicit projection, over its first 30 mm (the
/// scene goes on to 45 mm): it used to stop at step 284 with a cell turned inside out, where
/// the end-of-step projection pushed the curl's tip out of its own end face (a false
/// self-contact pair, found 0.118 mm deep: a node beside its own corner, which detection now
/// rejects). Measured: 600 steps, 32 cut, no penetration (3e-11 m), the account closed to
/// 2e-12, no step with self-contact (the base fold closes at 35.9 mm). The whole scene runs
/// too (900 steps, 210 cut, penetration 7.0e-6 m, `energy_drift` 3.2e-12: `softway run
/// fixtures/scenes/tube_crush.toml --set contact.method="implicit_projection"`, 45 minutes);
/// it stopped at step 764 (38.2 mm) until Newton's floating-point floor counted the
/// Norton-Hoff forces' noise (the book's materials chapter).
#[test]
#[ignore = "slow (5 to 8 min on 2 cores; 19 iterations per step at the median)"]
fn tube_crush_default_method() {
    let (mut sim, end, _) = scene::<2>(
        "tube_crush",
        &[
            "contact.method=\"implicit_projection\"",
            "simulation.end_time=6e-4",
        ],
        [0.0, 0.0, 0.0],
    );
    let own = softway::simulation::ContactMaster::Body(sim.body_id("tube").unwrap());
    let mut self_steps = 0;
    let mut deepest: f64 = 0.0;
    while sim.state().time < end - 1e-9 {
        sim.step()
            .unwrap_or_else(|e| panic!("t = {}: {e}", sim.state().time));
        if sim
            .contacts()
            .iter()
            .any(|c| c.master == own && c.normal_force > 0.0)
        {
            self_steps += 1;
        }
        deepest = deepest.max(sim.current_penetration());
    }
    let error = common::energy_error(&sim);
    assert_eq!(
        self_steps, 0,
        "steps with self-contact before the base fold closes"
    );
    assert!(deepest < 1e-9, "penetration {deepest} m");
    assert!(error < 1e-6, "{error}");
}

/// The volume [m^3] of the revolution of a 2D body's cells (axisymmetric: each cell's corners
/// split into triangles, Pappus: 2 pi times the area times the centroid's radius).
fn revolved_volume(mesh: &softway::mesh::Mesh<2>, x: &[nalgebra::Vector2<f64>]) -> f64 {
    let mut v = 0.0;
    for block in &mesh.blocks {
        let n = block.kind.nodes();
        for cell in block.connectivity.chunks(n) {
            for k in 1..n.min(4) - 1 {
                let (a, b, c) = (x[cell[0]], x[cell[k]], x[cell[k + 1]]);
                let area = 0.5 * (b - a).perp(&(c - a));
                v += 2.0 * std::f64::consts::PI * area * (a.x + b.x + c.x) / 3.0;
            }
        }
    }
    v
}

/// The paper's third example (`tube_crush.toml`: 1250 cells, Norton-Hoff with inertia, the
/// plate at 50 m/s, the soft way), shortened to its first 100 steps (5 mm of the 45 mm crush:
/// the top end flares; the example `tube_crush` runs 15 mm: `cargo test --all-features
/// --example tube_crush`). Every step
/// converges; the axial momentum balance holds (the plate's and the base's impulses against the
/// tube's momentum); the wall's volume is kept by the bulk penalty; the energy account closes;
/// the penetration stays below a twentieth of the wall; the plate's force lies around the force
/// that makes the whole section flow at the crush rate (sqrt(3) K (sqrt(3) v / L)^m times the
/// section's area; measured: 1.28 times it on average over steps 3 to 100, momentum 2e-14,
/// volume -0.107 %, account 3.7e-4, penetration 7.7e-5 m at the plate's impact).
#[test]
fn tube_crush() {
    let (mut sim, _, _) = scene::<2>("tube_crush", &[], [0.0, 0.0, 0.0]);
    let mesh = sim.model().bodies[0].mesh.clone();
    let x0 = sim.reference_positions().to_vec();
    let v0 = revolved_volume(&mesh, &x0);
    let axial = |sim: &Simulation<2>| {
        let v = &sim.state().velocity;
        let y: Vec<f64> = (0..v.len()).map(|i| (i % 2) as f64).collect();
        sim.mass_matrix().dot(&y, v)
    };
    let (mut impulse, mut deepest, mut least, mut mean) = (0.0, 0.0f64, f64::INFINITY, 0.0);
    let mut iterations = Vec::new();
    let steps = 100;
    for k in 0..steps {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("t = {}: {e}", sim.state().time));
        // The plate's and the floor's forces (the floor's is zero until the base fold lands,
        // past these steps) and the held base's reaction.
        let obstacles: f64 = r.contact_forces.iter().map(|f| f[1]).sum();
        impulse += (obstacles + r.reactions[0][1]) * r.time_step;
        deepest = deepest.max(r.max_penetration);
        iterations.push(r.iterations);
        // From the third step the plate is on the tube (0.1 mm of clearance at 50 m/s).
        if k >= 2 {
            least = least.min(-r.contact_forces[0][1]);
            mean += -r.contact_forces[0][1] / (steps - 2) as f64;
        }
    }
    let p = axial(&sim);
    let momentum = (impulse - p).abs() / (sim.body_mass(sim.body_ids()[0]).unwrap() * 50.0);
    let volume = revolved_volume(&mesh, &sim.positions()) / v0 - 1.0;
    let error = common::energy_error(&sim);
    // The section's flow force at the mean axial rate v / L.
    let area = std::f64::consts::PI * (0.022f64.powi(2) - 0.02f64.powi(2));
    let flow = 3f64.sqrt() * 8e7 * (3f64.sqrt() * 50.0 / 0.06).powf(0.1) * area;
    iterations.sort_unstable();
    eprintln!(
        "tube crush: {steps} steps, iterations {} / {} / {} (min / median / max), momentum \
         balance {momentum:.2e}, volume {:+.3} %, energy account {error:.2e}, penetration \
         {deepest:.3e} m, plate force {least:.4e} N at least, {mean:.4e} N on average (the \
         section's flow force {flow:.4e} N)",
        iterations[0],
        iterations[steps / 2],
        iterations[steps - 1],
        100.0 * volume
    );
    assert!(momentum < 1e-6, "{momentum}");
    assert!(volume.abs() < 0.005, "{volume}");
    assert!(error < 1e-2, "{error}");
    assert!(deepest < 1e-4, "{deepest}");
    assert!(least > 0.0, "{least}");
    assert!(
        mean > 0.5 * flow && mean < 2.0 * flow,
        "{mean} against {flow}"
    );
}
