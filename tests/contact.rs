//! Contact resolution against analytic solutions, in 2D and 3D: the elastic bar hitting a rigid
//! wall (Hughes et al. 1976), two bars hitting head on, blocks on an incline with Coulomb,
//! Tresca and viscoplastic friction, and the energy account.

use crate::common;

use common::verify::record;
use common::{block, vec_d};
use softway::contact::{ContactMethod, ContactSettings, FrictionLaw, Obstacle, ObstacleShape};
use softway::dim::{Dim, SpatialDim};
use softway::prelude::*;
use softway::simulation::MasterId;

const L: f64 = 1.0;
const V0: f64 = 0.01;
const GAP: f64 = 0.01;

fn bar_material() -> Material {
    // c = sqrt(E / rho) = 1 m/s, nu = 0: a one-dimensional bar.
    Material::LinearElastic(LinearElastic::new(1.0, 0.0, 1.0).unwrap())
}

/// Cross-section of the bar meshes [m^2] (per unit thickness in 2D).
fn section<const D: usize>() -> f64 {
    if D == 2 {
        0.1
    } else {
        0.01
    }
}

fn contact(method: ContactMethod) -> ContactSettings {
    ContactSettings {
        method,
        penalty: 1e5,
        gap_tolerance: 1e-12,
        ..ContactSettings::default()
    }
}

struct Impact {
    duration: f64,
    mean_force: f64,
    exit_velocity: f64,
    max_step_penetration: f64,
    energy_error: f64,
    /// Largest |E - E(0) - W + D| over the steps, relative to `energy_reference()`.
    account: f64,
    /// Largest |Q - Q(0) - W + D| over the steps (Q the scheme's energy; no external force
    /// here), relative to `energy_reference()`.
    scheme_account: f64,
    /// Dissipated energy at the end, relative to E(0).
    dissipated: f64,
}

/// The bar [0, L] moving at V0 towards a wall at L + GAP; c = 1, so contact should last 2 L / c
/// with the force rho c V0 A and the bar should leave at -V0.
fn bar_impact<const D: usize>(method: ContactMethod) -> Impact
where
    Dim<D>: SpatialDim<D>,
{
    let cells = 100;
    let mesh = block::<D>([L, 0.1, 0.1], [cells, 1, 1], false);
    let h = 2.0 * L / 300.0;
    let wall = Obstacle::new(
        "wall",
        ObstacleShape::Halfspace {
            point: vec_d::<D>([L + GAP, 0.0, 0.0]),
            normal: vec_d::<D>([-1.0, 0.0, 0.0]),
        },
    );
    let mut sim = Simulation::<D>::builder()
        .time_step(h)
        .body(Body::new("bar", mesh, bar_material()).with_velocity(vec_d::<D>([V0, 0.0, 0.0])))
        .obstacle(wall)
        .contact(contact(method))
        .build()
        .unwrap();
    let e0 = sim.energies().total();
    let q0 = sim.scheme_energy();
    let (mut first, mut last) = (None, 0);
    let mut forces = Vec::new();
    let mut max_pen: f64 = 0.0;
    let (mut account, mut scheme_account): (f64, f64) = (0.0, 0.0);
    let mut n = 0;
    while sim.state().time < GAP / V0 + 2.0 * L + 0.5 {
        let r = sim.step().unwrap();
        n += 1;
        max_pen = max_pen.max(r.max_penetration);
        let e = sim.energies();
        let reference = sim.energy_reference();
        account = account.max((e.total() - e0 - e.external_work + e.dissipated).abs() / reference);
        scheme_account = scheme_account
            .max((sim.scheme_energy() - q0 - e.external_work + e.dissipated).abs() / reference);
        if r.contact_forces[0][0].abs() > 0.0 {
            first.get_or_insert(n);
            last = n;
            forces.push(-r.contact_forces[0][0]);
        }
    }
    let first = first.expect("the bar reaches the wall");
    // Drop the partial first and last steps from the mean force.
    let inner = &forces[2..forces.len() - 2];
    let mean_force = inner.iter().sum::<f64>() / inner.len() as f64;
    let momentum: f64 = (0..sim.node_count())
        .map(|i| sim.velocity(sim.body_ids()[0], i).unwrap()[0])
        .sum::<f64>()
        / sim.node_count() as f64;
    Impact {
        duration: (last - first + 1) as f64 * h,
        mean_force,
        exit_velocity: momentum,
        max_step_penetration: max_pen,
        energy_error: (sim.energies().total() - e0).abs() / e0,
        account,
        scheme_account,
        dissipated: sim.energies().dissipated / e0,
    }
}

/// The figures of the book's table (`--nocapture` shows them).
fn print_impact<const D: usize>(name: &str, r: &Impact) {
    eprintln!(
        "{D}D {name}: duration {:.4} s, mean force {:.5e} N ({:.1e}), exit velocity {:.5e} m/s, \
         penetration {:.2e} m, energy error {:.2e}, account {:.2e}, scheme account {:.1e}, \
         dissipated {:.2e} E(0)",
        r.duration,
        r.mean_force,
        V0 * section::<D>(),
        r.exit_velocity,
        r.max_step_penetration,
        r.energy_error,
        r.account,
        r.scheme_account,
        r.dissipated
    );
}

fn check_impact<const D: usize>(method: ContactMethod)
where
    Dim<D>: SpatialDim<D>,
{
    let r = bar_impact::<D>(method);
    let force = 1.0 * 1.0 * V0 * section::<D>(); // rho c v0 A
    let name = method.name();
    print_impact::<D>(name, &r);
    record("bar-wall", "duration", (r.duration - 2.0 * L) / (2.0 * L));
    record("bar-wall", "force", (r.mean_force - force) / force);
    record("bar-wall", "exit v", (r.exit_velocity + V0) / V0);
    record("bar-wall", "energy", r.energy_error);
    assert!(
        (r.duration - 2.0 * L).abs() < 0.05 * 2.0 * L,
        "{name}: duration {}",
        r.duration
    );
    assert!(
        (r.mean_force - force).abs() < 0.05 * force,
        "{name}: force {} vs {force}",
        r.mean_force
    );
    assert!(
        (r.exit_velocity + V0).abs() < 0.05 * V0,
        "{name}: exit velocity {}",
        r.exit_velocity
    );
    assert!(
        r.energy_error < 0.05,
        "{name}: energy error {}",
        r.energy_error
    );
    if method == ContactMethod::ImplicitProjection {
        record(
            "bar-wall-projection",
            "penetration / L",
            r.max_step_penetration / L,
        );
        assert!(
            r.max_step_penetration < 1e-9 * L,
            "penetration {}",
            r.max_step_penetration
        );
    }
}

fn bar_impact_soft_way<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    check_impact::<D>(ContactMethod::SoftWay);
}

fn bar_impact_implicit_projection<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    check_impact::<D>(ContactMethod::ImplicitProjection);
}

fn bar_impact_augmented_lagrangian<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    check_impact::<D>(ContactMethod::AugmentedLagrangian);
}

/// Explicit projection, a lossy baseline, on the bar: what it achieves, measured (2D / 3D
/// alike): contact for exactly 300 steps (2.0000 s), mean force 1.00025 rho c v0 A, exit
/// velocity 0.99371 v0, no penetration left at step ends (2e-16 m), the projection's booked
/// dissipation -9.5e-4 E(0) (it put a little energy in), E - E(0) - W + D within 2.9e-3 of the
/// reference at every step (the scheme's swing of E, see `scheme_energy`), and the scheme's
/// energy account closed to 9e-13. The bounds leave a factor of about 2 to 10 over these.
fn bar_impact_explicit_projection<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let r = bar_impact::<D>(ContactMethod::ExplicitProjection);
    print_impact::<D>("explicit_projection", &r);
    let h = 2.0 * L / 300.0;
    let force = V0 * section::<D>(); // rho c v0 A
    record(
        "bar-wall-explicit",
        "duration (steps)",
        (r.duration - 2.0 * L) / h,
    );
    record("bar-wall-explicit", "force", (r.mean_force - force) / force);
    record("bar-wall-explicit", "exit v", (r.exit_velocity + V0) / V0);
    record(
        "bar-wall-explicit-losses",
        "penetration / L",
        r.max_step_penetration / L,
    );
    record("bar-wall-explicit-losses", "D / E0", r.dissipated);
    record("bar-wall-explicit-account", "E", r.account);
    record("bar-wall-explicit-account", "Q", r.scheme_account);
    assert!(
        (r.duration - 2.0 * L).abs() <= h * (1.0 + 1e-9),
        "duration {}",
        r.duration
    );
    assert!(
        (r.mean_force - force).abs() < 2e-3 * force,
        "force {} vs {force}",
        r.mean_force
    );
    assert!(
        (r.exit_velocity + V0).abs() < 1e-2 * V0,
        "exit velocity {}",
        r.exit_velocity
    );
    assert!(
        r.max_step_penetration < 1e-12 * L,
        "penetration {}",
        r.max_step_penetration
    );
    assert!(r.account < 1e-2, "energy account off by {}", r.account);
    assert!(
        r.scheme_account < 1e-9,
        "scheme energy account off by {}",
        r.scheme_account
    );
    assert!(
        r.dissipated.abs() < 1e-2,
        "dissipated {} E(0)",
        r.dissipated
    );
}

/// The bar [0, L] between two walls GAP away from its ends, moving at V0, with the augmented
/// Lagrangian: it bounces off the right wall (t = 1 to 3 s), then off the left one (5 to 7 s),
/// and comes back to the right one at 9 s. A pressure acts only on closed pairs: at the end of
/// every step each multiplier left in the state belongs to a wall that pushes; between
/// contacts (its end nodes detected across an open gap for a few steps after leaving and
/// before arriving) there is none, and no force; the second contact with the right wall
/// starts from no multiplier.
fn augmented_lagrangian_releases_open_pairs<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let mesh = block::<D>([L, 0.1, 0.1], [100, 1, 1], false);
    let h = 2.0 * L / 300.0;
    let wall = |name: &str, x: f64, nx: f64| {
        Obstacle::new(
            name,
            ObstacleShape::Halfspace {
                point: vec_d::<D>([x, 0.0, 0.0]),
                normal: vec_d::<D>([nx, 0.0, 0.0]),
            },
        )
    };
    let mut sim = Simulation::<D>::builder()
        .time_step(h)
        .body(Body::new("bar", mesh, bar_material()).with_velocity(vec_d::<D>([V0, 0.0, 0.0])))
        .obstacle(wall("left", -GAP, 1.0))
        .obstacle(wall("right", L + GAP, -1.0))
        .contact(contact(ContactMethod::AugmentedLagrangian))
        .build()
        .unwrap();
    // Contacts seen so far, in order: 1 = right, 0 = left.
    let mut contacts: Vec<usize> = Vec::new();
    let mut multipliers_seen = 0;
    while sim.state().time < 10.0 {
        let before = sim.state().multipliers.clone();
        let r = sim.step().unwrap();
        let pushing: Vec<usize> = (0..2).filter(|&k| r.contact_forces[k][0] != 0.0).collect();
        if let Some(&k) = pushing.first() {
            if contacts.last() != Some(&k) {
                // A new contact: no multiplier of that wall carried into its first step.
                let carried = before
                    .iter()
                    .filter(|&&(_, m, _)| m == MasterId::Obstacle(k))
                    .count();
                record("al-walls-restart", "carried multipliers", carried as f64);
                assert!(
                    before.iter().all(|&(_, m, _)| m != MasterId::Obstacle(k)),
                    "t = {}: contact with wall {k} starts from {before:?}",
                    sim.state().time
                );
                contacts.push(k);
            }
        }
        let state = &sim.state().multipliers;
        let t = sim.state().time;
        if (3.5..4.5).contains(&t) || (7.5..8.5).contains(&t) {
            let between = pushing.len() + state.len();
            record("al-walls", "forces or multipliers between", between as f64);
            assert!(
                pushing.is_empty() && state.is_empty(),
                "t = {t}: between contacts, forces on {pushing:?}, multipliers {state:?}"
            );
        }
        multipliers_seen += state.len();
        let idle = state.iter().filter(|&&(_, master, lambda)| {
            !(lambda > 0.0 && matches!(master, MasterId::Obstacle(k) if pushing.contains(&k)))
        });
        record(
            "al-walls",
            "multipliers off a pushing wall",
            idle.count() as f64,
        );
        for &(node, master, lambda) in state {
            let MasterId::Obstacle(k) = master else {
                panic!("multiplier {master:?}")
            };
            assert!(
                lambda > 0.0 && pushing.contains(&k),
                "t = {}: node {node} keeps {lambda} Pa on wall {k}, which does not push",
                sim.state().time
            );
        }
    }
    assert_eq!(contacts, [1, 0, 1], "contacts in order");
    assert!(multipliers_seen > 0, "Uzawa never ran");
}

/// Two identical bars [0, L] and [L + GAP, 2 L + GAP] meeting head on at +-V0.
fn bars_head_on<const D: usize>(method: ContactMethod)
where
    Dim<D>: SpatialDim<D>,
{
    let cells = 60;
    let left = block::<D>([L, 0.1, 0.1], [cells, 1, 1], false);
    let mut right = left.clone();
    right.translate(&vec_d::<D>([L + GAP, 0.0, 0.0]));
    let h = 2.0 * L / 200.0;
    let mut sim = Simulation::<D>::builder()
        .time_step(h)
        .body(Body::new("left", left, bar_material()).with_velocity(vec_d::<D>([V0, 0.0, 0.0])))
        .body(Body::new("right", right, bar_material()).with_velocity(vec_d::<D>([-V0, 0.0, 0.0])))
        .contact(contact(method))
        .build()
        .unwrap();
    let mean_velocity = |sim: &Simulation<D>, b: usize| -> f64 {
        let n = sim.bodies()[b].mesh.nodes.len();
        (0..n)
            .map(|i| sim.velocity(sim.body_ids()[b], i).unwrap()[0])
            .sum::<f64>()
            / n as f64
    };
    let momentum = |sim: &Simulation<D>| -> f64 {
        let ones: Vec<f64> = (0..sim.node_count() * D)
            .map(|i| if i % D == 0 { 1.0 } else { 0.0 })
            .collect();
        sim.mass_matrix().dot(&ones, &sim.state().velocity)
    };
    let p0 = momentum(&sim);
    let scale = sim.body_mass(sim.body_ids()[0]).unwrap() * V0;
    let (mut first, mut last, mut n) = (None, 0, 0);
    while sim.state().time < GAP / (2.0 * V0) + 2.0 * L + 0.5 {
        let r = sim.step().unwrap();
        n += 1;
        if r.active_contacts > 0 {
            first.get_or_insert(n);
            last = n;
        }
        record("two-bars", "momentum", (momentum(&sim) - p0).abs() / scale);
        assert!(
            (momentum(&sim) - p0).abs() < 1e-10 * scale,
            "momentum drifts"
        );
    }
    let duration = (last - first.expect("the bars meet") + 1) as f64 * h;
    record(
        "two-bars-waves",
        "duration",
        (duration - 2.0 * L) / (2.0 * L),
    );
    assert!(
        (duration - 2.0 * L).abs() < 0.05 * 2.0 * L,
        "{}: duration {duration}",
        method.name()
    );
    let (vl, vr) = (mean_velocity(&sim, 0), mean_velocity(&sim, 1));
    record("two-bars-waves", "exit v", (vl + V0) / V0);
    record("two-bars-waves", "exit v", (vr - V0) / V0);
    record("two-bars-symmetry", "v_l + v_r", (vl + vr) / V0);
    assert!(
        (vl + V0).abs() < 0.05 * V0 && (vr - V0).abs() < 0.05 * V0,
        "{}: {vl} {vr}",
        method.name()
    );
    // Symmetry: the two bars mirror each other.
    assert!(
        (vl + vr).abs() < 1e-6 * V0,
        "{}: asymmetric {vl} {vr}",
        method.name()
    );
}

fn two_bars_soft_way<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    bars_head_on::<D>(ContactMethod::SoftWay);
}

fn two_bars_implicit_projection<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    bars_head_on::<D>(ContactMethod::ImplicitProjection);
}

/// Implicit projection carries the points held when a step ends to the next step's start
/// (`State::active_contacts`): once a block rests on the floor, the held set stays the same
/// and no step activates a point (measured: 5 of 5 bottom nodes held in 2D, 15 of 25 in 3D,
/// the others lifted). Here the resting nodes' round-off gaps happen to read as penetrations,
/// which started them held before too; the stack of blocks with Coulomb friction
/// (`two_bodies::d2::a_coulomb_stack_under_implicit_projection`) is the scene whose points
/// started free and fell through their masters (it stopped at step 496). The held points'
/// multipliers are carried too (`State::multipliers`): at rest they are the floor's force,
/// and a step needs no multiplier pass to find it again.
fn a_resting_block_keeps_its_held_set<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    /// The contact status changes the solver reports.
    struct Changes(Vec<String>);
    impl<const D: usize> Recorder<D> for Changes
    where
        Dim<D>: SpatialDim<D>,
    {
        fn is_enabled(&self) -> bool {
            false
        }
        fn log(&mut self, _sim: &Simulation<D>, message: &str) {
            self.0.push(message.to_owned());
        }
    }
    let mut sim = common::resting_block::<D>(Material::LinearElastic(
        LinearElastic::new(1e6, 0.3, 1000.0).unwrap(),
    ));
    let bottom = if D == 2 { 5 } else { 25 };
    let mut changes = Changes(Vec::new());
    for _ in 0..100 {
        sim.step_with(&mut changes).unwrap();
    }
    let held = sim.state().active_contacts.clone();
    assert!(held.len() >= bottom / 2, "{} held of {bottom}", held.len());
    let settling = changes.0.len();
    changes.0.clear();
    let (mut most_iterations, mut total_iterations) = (0, 0);
    for _ in 0..50 {
        let r = sim.step_with(&mut changes).unwrap();
        assert_eq!(sim.state().active_contacts, held, "step {}", r.step);
        most_iterations = most_iterations.max(r.iterations);
        total_iterations += r.iterations;
        let carried: f64 = sim.state().multipliers.iter().map(|m| m.2).sum();
        let floor = r.contact_forces[0][D - 1];
        assert!(
            (carried / floor - 1.0).abs() < 1e-3,
            "step {}: multipliers {carried} N, floor {floor} N",
            r.step
        );
    }
    // Fewer than two Newton iterations a step, which is what starting each step's
    // multipliers at zero takes (measured over these 50 steps: 72 in one dimension and 92 in
    // the other, against 100 and 100).
    assert!(
        most_iterations <= 2 && total_iterations < 100,
        "{total_iterations} iterations in 50 steps at rest, at most {most_iterations}"
    );
    assert!(
        changes.0.iter().all(|m| !m.contains("activated")),
        "at rest, {} status changes: {:?} ({settling} while it settled)",
        changes.0.len(),
        changes.0.first()
    );
}

/// A soft block (E = 1e5 Pa, nu = 0.3, 1000 kg/m^3) moving down at `speed` onto a floor
/// `floor_below` under its bottom face at y (2D) or z (3D) = 0, under gravity.
fn block_onto_floor<const D: usize>(
    mesh: Mesh<D>,
    speed: f64,
    floor_below: f64,
    time_step: f64,
) -> SimulationBuilder<D>
where
    Dim<D>: SpatialDim<D>,
{
    let axis = |x: f64| {
        let mut v = [0.0; 3];
        v[D - 1] = x;
        vec_d(v)
    };
    Simulation::<D>::builder()
        .time_step(time_step)
        .gravity(axis(-9.81))
        .body(
            Body::new(
                "block",
                mesh,
                Material::LinearElastic(LinearElastic::new(1e5, 0.3, 1000.0).unwrap()),
            )
            .with_velocity(axis(-speed)),
        )
        .obstacle(Obstacle::new(
            "floor",
            ObstacleShape::Halfspace {
                point: axis(-floor_below),
                normal: axis(1.0),
            },
        ))
}

/// The end-of-step projection under implicit projection keeps the held points that do not
/// penetrate on their masters while it moves the penetrating ones out (its rows are Newton's
/// velocity constraints): the soft cube's block (E = 1e5 Pa, Tet4, 8 cells a side) landing at
/// 1.4 m/s at a game's step, default settings, 2 s, ends every step with at most round-off
/// inside the floor. Measured 2026-11-30: 0 m in 2D and 1.5e-9 m in 3D; with rows for the
/// penetrating points only (before), 7.5e-7 m in 3D: the correction pressed held neighbours
/// in, and they waited for the next step's Newton.
fn a_soft_block_landing_under_implicit_projection_ends_every_step_outside<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let mut sim = block_onto_floor::<D>(
        block([0.2, 0.2, 0.2], [8, 8, 8], true),
        1.4,
        1e-3,
        1.0 / 60.0,
    )
    .build()
    .unwrap();
    assert_eq!(
        sim.model().contact.method,
        ContactMethod::ImplicitProjection
    );
    let (mut deepest, mut held_steps): (f64, usize) = (0.0, 0);
    for _ in 0..120 {
        let r = sim.step().unwrap();
        deepest = deepest.max(r.max_penetration);
        held_steps += usize::from(r.active_contacts > 0);
    }
    assert!(held_steps >= 40, "{D}D: {held_steps} steps in contact");
    assert!(deepest < 1e-8, "{D}D: {deepest:.3e} m inside the floor");
}

/// A block thrown on the floor at 3 m/s at a game's step (default settings, the soft cube's
/// material and Tet4 / Tri3 cells, 4 a side): in one step its bottom nodes sink 35.5 mm into
/// the floor (eq 12's displacement), the next layer of nodes, 25 mm up, 10 mm, and the
/// end-of-step projection must lift the block out, not flatten its bottom cells onto the
/// floor. Until 2026-12-01 every penetrating point was put onto its master (an equality):
/// here the conserved energy reached 1.81 (2D) and 2.23 (3D) times the input; the same throw
/// in a scene file (Coulomb 0.5, `softway run`) ended its first step with 10 J of strain from
/// 4.7 J and a cell turned inside out, and at E = 1 MPa stopped with 1000 % created. The
/// projection's penetrating rows are now inequalities (`weighted_projection.rs`). No state
/// holds more than the input (the conserved energy Q), nothing is booked as created, and every
/// step ends outside the floor. Measured: Q at most 0.96 (2D) and 0.91 (3D) of the input; the
/// block bounces.
fn a_block_thrown_on_the_floor_lands<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let mut sim = block_onto_floor::<D>(
        block([0.1, 0.1, 0.1], [4, 4, 4], true),
        3.0,
        2e-3,
        1.0 / 60.0,
    )
    .build()
    .unwrap();
    // The energy the scheme conserves (E itself swings with the modes the step does not
    // resolve: up to 1.24 times the input in flight, 2D).
    let q0 = sim.scheme_energy();
    let (mut fullest, mut booked_in, mut deepest, mut in_contact) = (0.0_f64, 0.0_f64, 0.0_f64, 0);
    for _ in 0..30 {
        let r = sim.step().unwrap();
        let e = sim.energies();
        let input = q0 + e.external_work.abs();
        fullest = fullest.max(sim.scheme_energy() / input);
        booked_in = booked_in.max(-e.dissipated / input);
        deepest = deepest.max(r.max_penetration);
        in_contact += usize::from(r.active_contacts > 0);
    }
    record("thrown-block", &format!("{D}D fullest"), fullest);
    record("thrown-block", &format!("{D}D booked in"), booked_in);
    assert!(in_contact >= 1, "{D}D: it never landed");
    assert!(
        fullest <= 1.0,
        "{D}D: a state held {fullest:.3} of the input"
    );
    assert!(
        booked_in <= 1e-9,
        "{D}D: {booked_in:.3e} of the input booked as created"
    );
    assert!(deepest < 1e-8, "{D}D: {deepest:.3e} m inside the floor");
}

/// A block thrown hard and sideways at a game's step (the one-block measurement scene,
/// `benches/scenes/one_block_3d.toml`: 0.1 m, Tet4 / Tri3 cells 4 a side, E = 1 MPa,
/// Coulomb 0.5, 0.1 % stiffness damping), at 10 m/s down and 1 m/s along the floor, default
/// method: every step ends outside the floor. With two passes of the end-of-step correction
/// (until 2026-12-02) a pass's correction brought neighbours in that nothing moved out again:
/// the scene file ended steps 14 and 25 with nodes 8.3e-6 and 1.7e-5 m inside; now passes
/// go on while one moves something (`PROJECTION_PASSES`).
fn a_block_thrown_hard_ends_every_step_outside<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let mut velocity = [1.0, 0.0, 0.0];
    velocity[D - 1] = -10.0;
    let mut up = [0.0; 3];
    up[D - 1] = 1.0;
    let mut mesh: Mesh<D> = block([0.1, 0.1, 0.1], [4, 4, 4], true);
    for x in &mut mesh.nodes {
        x[D - 1] += 0.002;
    }
    let mut sim = Simulation::<D>::builder()
        .time_step(1.0 / 60.0)
        .gravity(vec_d(up) * -9.81)
        .body(
            Body::new(
                "block",
                mesh,
                Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap()),
            )
            .with_velocity(vec_d(velocity))
            .with_damping(0.0, 1e-3),
        )
        .obstacle(Obstacle::new(
            "floor",
            ObstacleShape::Halfspace {
                point: vec_d([0.0; 3]),
                normal: vec_d(up),
            },
        ))
        .contact(ContactSettings {
            friction: FrictionLaw::Coulomb {
                coefficient: 0.5,
                regularization: softway::friction::DEFAULT_REGULARIZATION,
            },
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    let (mut deepest, mut in_contact) = (0.0_f64, 0);
    for _ in 0..60 {
        let r = sim.step().unwrap();
        deepest = deepest.max(r.max_penetration);
        in_contact += usize::from(r.active_contacts > 0);
    }
    assert!(in_contact >= 10, "{D}D: {in_contact} steps in contact");
    assert!(deepest < 1e-8, "{D}D: {deepest:.3e} m inside the floor");
}

both_dims!(
    bar_impact_soft_way,
    bar_impact_implicit_projection,
    bar_impact_augmented_lagrangian,
    bar_impact_explicit_projection,
    augmented_lagrangian_releases_open_pairs,
    two_bars_soft_way,
    two_bars_implicit_projection,
    a_resting_block_keeps_its_held_set,
    a_soft_block_landing_under_implicit_projection_ends_every_step_outside,
    a_block_thrown_on_the_floor_lands,
    a_block_thrown_hard_ends_every_step_outside,
    a_bouncing_block_converges_in_one_iteration_per_steady_contact_step,
    coulomb_incline,
    tresca_incline,
    viscoplastic_incline,
);

const G: f64 = 9.81;

/// A block resting on a plane y = 0 under gravity tilted by `theta` (it slides along +x);
/// returns its mean x velocity after `time` seconds and the simulation.
fn incline<const D: usize>(theta: f64, law: FrictionLaw, time: f64) -> (f64, Simulation<D>)
where
    Dim<D>: SpatialDim<D>,
{
    let mesh = block::<D>([0.1, 0.05, 0.05], [4, 2, 2], false);
    let ground = Obstacle::new(
        "ground",
        ObstacleShape::Halfspace {
            point: vec_d::<D>([0.0, 0.0, 0.0]),
            normal: vec_d::<D>([0.0, 1.0, 0.0]),
        },
    );
    let mut sim = Simulation::<D>::builder()
        .time_step(1e-3)
        // alpha = 1, beta = 1/2: unconditionally stable, exact under constant acceleration.
        .scheme(1.0, Beta::Trapezoid)
        .tolerance(1e-6)
        .gravity(vec_d::<D>([G * theta.sin(), -G * theta.cos(), 0.0]))
        .body(Body::new(
            "block",
            mesh,
            Material::LinearElastic(LinearElastic::new(1e7, 0.3, 1000.0).unwrap()),
        ))
        .obstacle(ground)
        .contact(ContactSettings {
            method: ContactMethod::SoftWay,
            penalty: 1e11,
            friction: law,
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    while sim.state().time < time - 1e-9 {
        sim.step().unwrap();
    }
    let n = sim.node_count();
    let vx = (0..n)
        .map(|i| sim.velocity(sim.body_ids()[0], i).unwrap()[0])
        .sum::<f64>()
        / n as f64;
    (vx, sim)
}

fn coulomb_incline<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let (theta, mu) = (30f64.to_radians(), 0.3);
    let law = FrictionLaw::Coulomb {
        coefficient: mu,
        regularization: 1e-6,
    };
    let (v, sim) = incline::<D>(theta, law, 0.3);
    let a = v / 0.3;
    let exact = G * (theta.sin() - mu * theta.cos());
    record("incline", "a", (a - exact) / exact);
    assert!(
        (a - exact).abs() < 0.02 * exact,
        "a = {a}, expected {exact}"
    );
    // Friction dissipates, and the energy account balances.
    let e = sim.energies();
    assert!(e.dissipated > 0.0);
    let balance = (e.total() - sim.initial_energy() - e.external_work + e.dissipated).abs();
    record("incline-energy", "account / W", balance / e.external_work);
    assert!(
        balance < 0.01 * e.external_work,
        "energy account off by {balance} of {}",
        e.external_work
    );
    // It sticks when tan(theta) < mu.
    let (v, _) = incline::<D>(10f64.to_radians(), law, 0.3);
    record("incline-stick", "v (m/s)", v);
    assert!(v.abs() < 1e-4, "sliding at {v} although tan(theta) < mu");
}

fn tresca_incline<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    // |F_t| = limit x contact area: a = g sin(theta) - limit A / m.
    let theta = 30f64.to_radians();
    let limit = 100.0;
    let (v, sim) = incline::<D>(
        theta,
        FrictionLaw::Tresca {
            limit,
            regularization: 1e-6,
        },
        0.3,
    );
    let area = if D == 2 { 0.1 } else { 0.1 * 0.05 };
    let mass = sim.body_mass(sim.body_ids()[0]).unwrap();
    let exact = G * theta.sin() - limit * area / mass;
    record("tresca", "a", (v / 0.3 - exact) / exact);
    assert!(
        (v / 0.3 - exact).abs() < 0.02 * exact,
        "a = {}, expected {exact}",
        v / 0.3
    );
}

fn viscoplastic_incline<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    // p = 1: F_t = -a A v, so v(t) = v_T (1 - exp(-t / tau)), tau = m / (a A).
    let theta = 30f64.to_radians();
    let coefficient = 200.0;
    let law = FrictionLaw::Viscoplastic {
        coefficient,
        exponent: 1.0,
        regularization: 1e-9,
    };
    let (v, sim) = incline::<D>(theta, law, 0.3);
    let area = if D == 2 { 0.1 } else { 0.1 * 0.05 };
    let mass = sim.body_mass(sim.body_ids()[0]).unwrap();
    let tau = mass / (coefficient * area);
    let v_terminal = G * theta.sin() * tau;
    let exact = v_terminal * (1.0 - (-0.3 / tau).exp());
    record("viscoplastic", "v", (v - exact) / exact);
    assert!(
        (v - exact).abs() < 0.02 * exact,
        "v = {v}, expected {exact}"
    );
}

#[test]
fn axisymmetric_bar_impact() {
    // A solid cylinder (r <= 0.1 m, axis y) falling along its axis onto a rigid plane: with
    // nu = 0 the wave is one-dimensional; the force is rho c v0 pi R^2 over the whole revolution.
    let radius = 0.1;
    let mesh = block::<2>([radius, L, 0.0], [2, 100, 1], false);
    let mut mesh = mesh;
    mesh.translate(&vec_d::<2>([0.0, GAP, 0.0]));
    let floor = Obstacle::new(
        "floor",
        ObstacleShape::Halfspace {
            point: vec_d::<2>([0.0, 0.0, 0.0]),
            normal: vec_d::<2>([0.0, 1.0, 0.0]),
        },
    );
    let h = 2.0 * L / 300.0;
    let mut sim = Simulation2::builder()
        .kinematics(softway::dim::Kinematics::Axisymmetric)
        .time_step(h)
        .body(Body::new("rod", mesh, bar_material()).with_velocity(vec_d::<2>([0.0, -V0, 0.0])))
        .obstacle(floor)
        .contact(contact(ContactMethod::SoftWay))
        .build()
        .unwrap();
    let mut forces = Vec::new();
    let (mut first, mut last, mut n) = (None, 0, 0);
    while sim.state().time < GAP / V0 + 2.0 * L + 0.5 {
        let r = sim.step().unwrap();
        n += 1;
        if r.contact_forces[0][1] > 0.0 {
            first.get_or_insert(n);
            last = n;
            forces.push(r.contact_forces[0][1]);
        }
    }
    let duration = (last - first.unwrap() + 1) as f64 * h;
    let inner = &forces[2..forces.len() - 2];
    let mean = inner.iter().sum::<f64>() / inner.len() as f64;
    let exact = V0 * std::f64::consts::PI * radius * radius;
    assert!(
        (duration - 2.0 * L).abs() < 0.05 * 2.0 * L,
        "duration {duration}"
    );
    assert!(
        (mean - exact).abs() < 0.05 * exact,
        "force {mean} vs {exact}"
    );
}

/// The bundled ring drop (`fixtures/scenes/ring_drop.toml`) with explicit projection through
/// its landing (0.4 s): the projection's energy is booked as dissipation, measured on the
/// scheme's conserved energy Q (`Simulation::scheme_energy`), so that the scheme's account
/// `Q - Q(0) - W_Q + D` closes at every step (measured 2.1e-12 of the reference), `W_Q` the
/// work of gravity in Q's terms, `W + h/2 (alpha - beta) g . (p - p(0))` (p the momentum).
/// The account on E, `E - E(0) - W + D`, is off by E - Q, the swing of the stiff modes that
/// each projection kicks (beta = 1 - alpha does not damp them): measured 7.4e-2 of the
/// reference at its worst (step 127, in contact) and 3.2e-2 at 0.4 s. Before, the projection
/// booked only the kinetic energy it removed: 21,473 J dissipated at 0.4 s against 565 J
/// initially, an account off by 18 times its reference.
#[cfg(feature = "formats")]
#[test]
fn ring_drop_explicit_projection_energy_account() {
    let overrides = [
        "contact.method=\"explicit_projection\"".to_string(),
        "simulation.end_time=0.4".to_string(),
    ];
    let scene = common::fixture::<2>("ring_drop", &overrides);
    let mut sim = scene.simulation().unwrap();
    let h = sim.model().settings.time_step;
    let scheme = sim.model().settings.scheme;
    let g = sim.model().settings.gravity;
    // The momentum along each axis: 1_k^T M v.
    let momentum = |sim: &Simulation2| -> [f64; 2] {
        let v = &sim.state().velocity;
        [0, 1].map(|k| {
            let e: Vec<f64> = (0..v.len())
                .map(|i| if i % 2 == k { 1.0 } else { 0.0 })
                .collect();
            sim.mass_matrix().dot(&e, v)
        })
    };
    let (e0, q0, p0) = (sim.energies().total(), sim.scheme_energy(), momentum(&sim));
    let (mut worst_e, mut worst_q, mut landed): (f64, f64, bool) = (0.0, 0.0, false);
    while sim.state().time < scene.end_time - 1e-9 {
        let r = sim.step().unwrap();
        landed |= r.contact_forces[0][1] > 0.0;
        assert!(
            r.max_penetration < 1e-12,
            "penetration {}",
            r.max_penetration
        );
        let e = sim.energies();
        let reference = sim.energy_reference();
        let p = momentum(&sim);
        let gravity_q: f64 = (0..2).map(|k| g[k] * (p[k] - p0[k])).sum();
        let work_q = e.external_work + 0.5 * h * (scheme.alpha - scheme.beta) * gravity_q;
        worst_q = worst_q.max((sim.scheme_energy() - q0 - work_q + e.dissipated).abs() / reference);
        worst_e = worst_e.max((e.total() - e0 - e.external_work + e.dissipated).abs() / reference);
    }
    let e = sim.energies();
    let end = (e.total() - e0 - e.external_work + e.dissipated).abs() / sim.energy_reference();
    eprintln!(
        "ring drop, explicit projection, 0.4 s: account on E {worst_e:.2e} at worst, {end:.2e} \
         at the end; on Q {worst_q:.1e}; dissipated {:.4} J, reference {:.4} J",
        e.dissipated,
        sim.energy_reference()
    );
    record("ring-drop-explicit", "Q", worst_q);
    record("ring-drop-explicit", "E worst", worst_e);
    record("ring-drop-explicit", "E at 0.4 s", end);
    assert!(landed, "the ring never landed");
    assert!(worst_q < 1e-9, "scheme energy account off by {worst_q}");
    assert!(worst_e < 0.1, "energy account off by {worst_e}");
    assert!(end < 0.05, "energy account off by {end} at the end");
    // Net, the projection put energy in (25 J of the reference's 1,190 J): booked, negative.
    assert!(
        e.dissipated < 0.0 && -e.dissipated < 0.05 * sim.energy_reference(),
        "dissipated {}",
        e.dissipated
    );
}

/// The soft way's first Newton direction keeps the penalty of the points closed when the last
/// step ended (`OuterVariables::predicted` in the code): a block bouncing on its contact
/// face, whose bottom moves up in some steps, used to be predicted open there (`v1 = v0`), its
/// first direction fell through the floor, and Newton backtracked and came back in 2 to 5
/// iterations (and a factorisation where the predictor released part of the face). Every step
/// whose contact set is the previous step's now converges in one iteration.
fn a_bouncing_block_converges_in_one_iteration_per_steady_contact_step<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let mut sim = block_onto_floor::<D>(block([0.2, 0.1, 0.2], [4, 2, 4], false), 1.0, 2e-3, 1e-3)
        .contact(ContactSettings {
            method: ContactMethod::SoftWay,
            penalty: 1e8,
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    // (step, iterations) of the steps whose contact count is the previous step's.
    let (mut previous, mut steady) = (0, Vec::new());
    for _ in 0..60 {
        let r = sim.step().unwrap();
        if r.active_contacts > 0 && r.active_contacts == previous {
            steady.push((r.step, r.iterations, r.factorisations));
        }
        previous = r.active_contacts;
    }
    // Measured: 14 such steps in 2D and 37 in 3D; before, 1 and 3 of them took 2 or 3
    // iterations. None factors: the kept factorisation has the same contact set.
    assert!(
        steady.len() >= 10,
        "{D}D: {} steady contact steps",
        steady.len()
    );
    let slow: Vec<_> = steady.iter().filter(|(_, i, f)| *i > 1 || *f > 0).collect();
    assert!(
        slow.is_empty(),
        "{D}D: steady contact steps (step, iterations, factorisations) with more than one \
         iteration or a factorisation: {slow:?}"
    );
}
