//! Contact between deformable bodies: three soft blocks (E = 1e5 Pa) dropped in a stack on a
//! floor, each offset sideways by 1 cm from the one below, in 2D and 3D. The soft way keeps
//! both passes between bodies at half the area each; it runs through the landing and the
//! settling with its energy account within 2 %. And a soft ring (E = 5e7 Pa) dropped at 2 m/s
//! onto a softer pad (E = 5e6 Pa) lying on a rigid base: it lands, bounces off, and the
//! energy account holds.

use crate::common;

use common::{block, energy_error, vec_d};
use softway::contact::{
    ContactMethod, ContactSettings, FrictionLaw, GapDisplacement, Obstacle, ObstacleShape,
};
use softway::dim::{Dim, SpatialDim};
use softway::prelude::*;

/// The largest penetration over the run and the energy error at its end.
fn stack<const D: usize>(method: ContactMethod, gaps: GapDisplacement) -> Stack
where
    Dim<D>: SpatialDim<D>,
{
    stack_with_friction::<D>(method, gaps, FrictionLaw::Frictionless)
}

/// The stack's simulation: three blocks 2 mm apart, the lowest 1 mm above the floor.
fn stack_simulation<const D: usize>(
    method: ContactMethod,
    gaps: GapDisplacement,
    friction: FrictionLaw,
) -> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    let mut gravity = [0.0; 3];
    gravity[D - 1] = -9.81;
    let mut builder = Simulation::<D>::builder()
        .time_step(1e-3)
        .gravity(vec_d(gravity));
    for k in 0..3 {
        let mut mesh: Mesh<D> = block([0.1, 0.1, 0.1], [4, 4, 4], false);
        // 1 mm above the floor, 2 mm between blocks, each 1 cm to the side of the one below.
        let mut shift = [0.01 * k as f64, 0.0, 0.0];
        shift[D - 1] = 0.102 * k as f64 + 0.001;
        for x in &mut mesh.nodes {
            *x += vec_d::<D>(shift);
        }
        builder = builder.body(Body::new(
            format!("block{k}"),
            mesh,
            Material::LinearElastic(LinearElastic::new(1e5, 0.3, 1000.0).unwrap()),
        ));
    }
    builder
        .obstacle(common::floor::<D>())
        .contact(ContactSettings {
            method,
            penalty: 1e9,
            gap_displacement: gaps,
            friction,
            ..ContactSettings::default()
        })
        .build()
        .unwrap()
}

/// [`stack`] with a friction law on every contact.
fn stack_with_friction<const D: usize>(
    method: ContactMethod,
    gaps: GapDisplacement,
    friction: FrictionLaw,
) -> Stack
where
    Dim<D>: SpatialDim<D>,
{
    let mut sim = stack_simulation::<D>(method, gaps, friction);
    let (mut penetration, mut settled, mut largest_error) = (0.0_f64, 0.0_f64, 0.0_f64);
    let (mut iterations, mut cuts) = (0, 0);
    // Each block's momentum along each horizontal axis (N s): the floor without friction
    // exerts none along them, so the three must sum to zero.
    let sideways_momenta = |sim: &Simulation<D>| -> Vec<Vec<f64>> {
        let momenta: Vec<_> = sim
            .body_ids()
            .into_iter()
            .map(|b| sim.body_momentum(b).unwrap())
            .collect();
        (0..D - 1)
            .map(|k| momenta.iter().map(|p| p[k]).collect())
            .collect()
    };
    let (mut largest_momentum, mut momentum_drift) = (0.0_f64, 0.0_f64);
    while sim.state().time < 0.5 - 1e-9 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("{method:?}, t = {}: {e}", sim.state().time));
        penetration = penetration.max(r.max_penetration);
        for p in sideways_momenta(&sim) {
            largest_momentum = p.iter().fold(largest_momentum, |m, x| m.max(x.abs()));
            momentum_drift = momentum_drift.max(p.iter().sum::<f64>().abs());
        }
        iterations += r.iterations;
        cuts += r.cuts;
        if sim.state().time > LANDED_AFTER {
            largest_error = largest_error.max(energy_error(&sim));
        }
        if sim.state().time > SETTLED_AFTER {
            settled = settled.max(r.max_penetration);
        }
    }
    let error = energy_error(&sim);
    let sideways = momentum_drift / largest_momentum.max(f64::MIN_POSITIVE);
    eprintln!(
        "{D}D {method:?} stack, {gaps:?} gaps: largest penetration {penetration:.3e} m \
         ({settled:.3e} m after {SETTLED_AFTER} s), energy error {error:.2e} (at most \
         {largest_error:.2e} after {LANDED_AFTER} s); {iterations} Newton iterations, {cuts} \
         step cuts; sideways momenta at the end {:.3e} N s (largest {largest_momentum:.3e}, \
         their sum at most {sideways:.1e} of it)",
        sideways_momenta(&sim)[0][0]
    );
    Stack {
        penetration,
        settled,
        error: error.max(largest_error),
        sideways,
    }
}

/// The blocks have met the floor and each other by then; before it the account's reference is
/// the little work gravity has done, against which the free fall's bounded swing of E (the
/// scheme conserves Q) is large.
const LANDED_AFTER: f64 = 0.05;

/// The last 50 ms. The stack does not rest then: without friction it comes apart (the bottom
/// block pushed out along the floor, the middle one sliding off it: 2D, by 0.5 s, 13 cm and
/// 9.6 cm down, the blocks' sideways momenta summing to zero), and with Coulomb 0.5 the
/// blocks ring (no damping) and the top one walks 4 cm; the contacts are live throughout.
const SETTLED_AFTER: f64 = 0.45;

/// What a stack's run measures.
struct Stack {
    /// The deepest gap after any step (m).
    penetration: f64,
    /// The deepest gap after `SETTLED_AFTER` (m).
    settled: f64,
    /// The energy account's largest error after `LANDED_AFTER`, relative to the reference.
    error: f64,
    /// The largest sum of the blocks' sideways momenta over the run, relative to the largest
    /// of them: zero without floor friction (Newton's third law between the blocks).
    sideways: f64,
}

fn a_stack_under_the_augmented_lagrangian<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    stack_holds::<D>(
        ContactMethod::AugmentedLagrangian,
        GapDisplacement::Configuration,
        2e-3,
    );
}

/// The stack under `method` on `gaps`: its account within 2e-2 after the landing, no sideways
/// momentum made between the blocks, and no gap deeper than `deepest` (m).
fn stack_holds<const D: usize>(method: ContactMethod, gaps: GapDisplacement, deepest: f64)
where
    Dim<D>: SpatialDim<D>,
{
    let Stack {
        penetration,
        error,
        sideways,
        ..
    } = stack::<D>(method, gaps);
    assert!(error < 2e-2, "energy error {error}");
    // Round-off: the augmented Lagrangian's persistency stop solves its metric projection
    // iteratively to 1e-12 of the right-hand side, and what that leaves adds up over 500
    // steps (1.5e-8 on the 3D stack on trapezoid gaps, 2026-12-03; 1.4e-9 in 2D).
    assert!(sideways < 5e-8, "sideways momentum created: {sideways:e}");
    assert!(penetration < deepest, "penetration {penetration}");
}

fn a_stack_under_the_soft_way<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    let Stack {
        penetration,
        error,
        sideways,
        ..
    } = stack::<D>(ContactMethod::SoftWay, GapDisplacement::Configuration);
    common::verify::record("stack", &format!("energy {D}D"), error);
    common::verify::record("stack", &format!("penetration {D}D (m)"), penetration);
    assert!(error < 2e-2, "energy error {error}");
    assert!(sideways < 1e-8, "sideways momentum created: {sideways:e}");
    // Measured 3.6e-4 m (2D) and 1.05e-3 m (3D): far above the penalty's own pressure / zeta
    // (3e-6 m at the bottom of the stack), an open defect (book, contact chapter); with one
    // pass the 2D stack went 3.6 mm deep and the 3D one did not converge at its landing.
    assert!(penetration < 2e-3, "penetration {penetration}");
}

/// Implicit projection holds the body listed first as the slave, and the other body's nodes
/// beyond the edge of its holding nodes (`held_pairs`): the middle and top blocks' corners,
/// 1 cm in from the edges below, which one pass left to sink 3.99e-3 m (2D). What remains is
/// transient, inside the contact patches: a master node between two held slaves can sink into
/// the slave facet under it while the blocks ring (2.9e-4 m in 2D; 5.2e-4 m, at 0.19 s, before
/// each step's active set started from the last one's); in 2D, in the last 50 ms, as the
/// blocks slide apart, it is out (`settled`, m); in 3D a top-block node still sinks 4.4e-4 m
/// then (the open test below asks for none), and a step of the tumbling blocks can leave a
/// node millimetres inside (`deepest`, m; see the 3D test).
fn a_stack_under_implicit_projection<const D: usize>(settled_below: f64, deepest: f64)
where
    Dim<D>: SpatialDim<D>,
{
    let Stack {
        penetration,
        settled,
        error,
        sideways,
    } = stack::<D>(
        ContactMethod::ImplicitProjection,
        GapDisplacement::Configuration,
    );
    // The energies' account, which the scheme conserves only to O(h): it swings by about 2 %
    // either way while the blocks ring. The frictionless 2D stack peaked at -1.66e-2 at
    // t = 0.133 s with one pass and +2.02e-2 at t = 0.157 s once the master nodes were moved
    // out (2026-12-02); the account on the scheme's own energy closes to 2e-9 in both
    // (`scheme_energy_drift` of the same stack as a scene file, `softway run`).
    assert!(error < 2.5e-2, "energy error {error}");
    assert!(sideways < 1e-8, "sideways momentum created: {sideways:e}");
    assert!(
        settled < settled_below,
        "penetration in the last 50 ms {settled}"
    );
    assert!(penetration < deepest, "penetration {penetration}");
}

/// The same stack with the penalty's gaps measured on the running eq 22 displacement
/// (`GapDisplacement::Trapezoid`): the configuration no longer stores a step's travel inside
/// the other body. Measured 3.1e-5 m (2D) and 5.3e-5 m (3D), ten to twenty times less than
/// with the paper's configuration gaps, still ten times the static pressure / zeta (the
/// landing's dynamic pressure). The end-of-step penalty's dissipation, which left the account
/// 2.3e-2 / 1.7e-2 short, is booked (`State::contact_loss`): 2D, at most 1.5e-2 after the
/// landing, 2.6e-3 at the end.
fn trapezoid_gaps_keep_the_stack_apart<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    stack_holds::<D>(ContactMethod::SoftWay, GapDisplacement::Trapezoid, 1e-4);
}

/// The same stack under the augmented Lagrangian on trapezoid gaps (its persistency stop on):
/// Uzawa closes the gaps it measures, so the blocks stay apart to its gap tolerance. Measured
/// (2026-12-03, since the stop keeps the configuration's offset from the gaps) 4.6e-9 m (2D)
/// and 7.2e-9 m (3D), against 2.9e-4 m on the paper's configuration gaps; the account at most
/// 1.5e-2 / 1.3e-2 after the landing, 2.3e-3 / 9.0e-3 at the end; 4488 / 7129 Newton
/// iterations, 0 / 4 cut steps (the soft way's 1689 / 2198).
fn trapezoid_gaps_keep_the_augmented_lagrangian_stack_apart<const D: usize>()
where
    Dim<D>: SpatialDim<D>,
{
    stack_holds::<D>(
        ContactMethod::AugmentedLagrangian,
        GapDisplacement::Trapezoid,
        1e-7,
    );
}

/// The ring drop's ring (radii 0.8 and 1 m, 64 x 4 Quad4, E = 5e7 Pa, 1000 kg/m^3, plane
/// strain) 5 cm above a 3 m x 0.3 m pad (30 x 4 Quad4, E = 5e6 Pa) lying on a rigid base,
/// falling at 2 m/s under gravity; run to 0.2 s, through the landing and the rebound. Returns
/// the largest penetration, the largest energy error over the run, and the ring's kinetic
/// energy and vertical momentum at the end.
struct RingOnPad {
    penetration: f64,
    error: f64,
    kinetic: f64,
    momentum: f64,
}

impl RingOnPad {
    /// The ring's rebound at 0.2 s: the soft way at the default step measured 1213 J and
    /// 1517 kg m/s (per metre), implicit projection at half the step 1179 J and 1500 kg m/s.
    fn rebounds_as_both_methods_do(&self) {
        assert!(
            (self.kinetic - 1195.0).abs() < 50.0,
            "kinetic energy {}",
            self.kinetic
        );
        assert!(
            (self.momentum - 1510.0).abs() < 40.0,
            "momentum {}",
            self.momentum
        );
    }
}

fn ring_on_pad(settings: ContactSettings, time_step: f64) -> RingOnPad {
    use nalgebra::Vector2;
    let elastic = |e: f64| Material::LinearElastic(LinearElastic::new(e, 0.3, 1000.0).unwrap());
    let ring = annulus(
        Vector2::new(0.0, 1.35),
        0.8,
        1.0,
        [64, 4],
        ElementKind::Quad4,
    )
    .unwrap();
    let pad = rectangle(
        Vector2::new(-1.5, 0.0),
        Vector2::new(1.5, 0.3),
        [30, 4],
        ElementKind::Quad4,
    )
    .unwrap();
    let method = settings.method;
    let mut sim = Simulation::<2>::builder()
        .time_step(time_step)
        .gravity(Vector2::new(0.0, -9.81))
        .body(Body::new("ring", ring, elastic(5e7)).with_velocity(Vector2::new(0.0, -2.0)))
        .body(Body::new("pad", pad, elastic(5e6)))
        .obstacle(Obstacle::new(
            "base",
            ObstacleShape::Halfspace {
                point: Vector2::zeros(),
                normal: Vector2::new(0.0, 1.0),
            },
        ))
        .contact(settings)
        .build()
        .unwrap();
    let ring = sim.body_id("ring").unwrap();
    let (mut penetration, mut error) = (0.0_f64, 0.0_f64);
    while sim.state().time < 0.2 - 1e-9 {
        let r = sim
            .step()
            .unwrap_or_else(|e| panic!("{method:?}, t = {}: {e}", sim.state().time));
        penetration = penetration.max(r.max_penetration);
        error = error.max(energy_error(&sim));
    }
    let momentum = sim.body_momentum(ring).unwrap();
    let v = &sim.state().velocity;
    let mv = sim.mass_matrix().mul(v);
    let kinetic: f64 = sim
        .body_nodes(ring)
        .unwrap()
        .flat_map(|n| [2 * n, 2 * n + 1])
        .map(|i| 0.5 * v[i] * mv[i])
        .sum();
    eprintln!(
        "ring on pad, {method:?}, h = {time_step:e} s: penetration {penetration:.3e} m, \
         largest energy error {error:.2e}, ring's kinetic energy {kinetic:.1} J, momentum {:.1} \
         kg m/s",
        momentum[1]
    );
    RingOnPad {
        penetration,
        error,
        kinetic,
        momentum: momentum[1],
    }
}

/// The soft way at the default step: the ring lands (2 m/s), bounces off and rises at 0.2 s.
/// Measured: penetration 7.8e-4 m, largest energy error 1.17e-2 (the penalty's unbooked loss),
/// the ring's kinetic energy 1213 J and momentum 1517 kg m/s (per metre). (The report
/// of a ring on a pad was a 35-fold gain, exit 0.)
#[test]
fn a_soft_ring_dropped_on_a_soft_pad_soft_way() {
    let r = ring_on_pad(
        ContactSettings {
            method: ContactMethod::SoftWay,
            penalty: 1e9,
            ..ContactSettings::default()
        },
        1e-3,
    );
    assert!(r.error < 1.5e-2, "energy error {}", r.error);
    // A hundredth of the ring's outer facet (0.098 m).
    assert!(r.penetration < 1e-3, "penetration {}", r.penetration);
    assert!(
        r.momentum > 0.0,
        "the ring bounced: momentum {}",
        r.momentum
    );
    r.rebounds_as_both_methods_do();
}

/// Implicit projection, the default method, at the default step: it lands and bounces as the
/// soft way does, and the account closes. Measured (2026-11-27): one step of 200 cut,
/// penetration 8.0e-6 m, largest energy error 8.7e-3, in 9 s. Before, the ring's bottom node
/// crossed the pad's vertex under it at every Newton iteration (the dent its push makes is a
/// concave V, its facets 2.4 degrees apart), no full step converged from the first contact on,
/// 82 of 200 steps were cut and the account drifted 112 %: a facet that changes twice in a
/// step is now kept until Newton ends (`FLIPS_BEFORE_LOCK`). 2026-12-01: the end-of-step
/// projection moves penetrating points out of their masters instead of onto them, and the
/// largest energy error went from 9.51e-3 to 1.02e-2 (penetration 6.1e-6 m, 6.2e-6 m): the
/// bound is the soft way's, 1.5e-2, within the 2 %.
#[test]
fn a_soft_ring_dropped_on_a_soft_pad_implicit_projection() {
    let r = ring_on_pad(ContactSettings::default(), 1e-3);
    assert!(r.error < 1.5e-2, "energy error {}", r.error);
    assert!(r.penetration < 2e-5, "penetration {}", r.penetration);
    r.rebounds_as_both_methods_do();
}

/// Implicit projection at half the default step: it lands and bounces as the soft way does,
/// with no penetration. Measured: penetration 4.4e-6 m, largest energy error 5.3e-3.
#[test]
fn a_soft_ring_dropped_on_a_soft_pad_implicit_projection_half_step() {
    let r = ring_on_pad(ContactSettings::default(), 5e-4);
    assert!(r.error < 1e-2, "energy error {}", r.error);
    assert!(r.penetration < 1e-5, "penetration {}", r.penetration);
    r.rebounds_as_both_methods_do();
}

/// Coulomb 0.5 on every contact of the stack.
const COULOMB: FrictionLaw = FrictionLaw::Coulomb {
    coefficient: 0.5,
    regularization: 1e-4,
};

/// The targets for the stack with Coulomb 0.5 on every contact: the account within
/// 2 % throughout, no node deeper than `deepest`. Measured 2026-11-29 (2D, `cargo test
/// --all-features --test suite coulomb_stack -- --nocapture`): the soft way's account at most
/// 1.44e-2 after the landing (8.1e-4 at the end), the augmented Lagrangian's 1.59e-2 (1.1e-3),
/// deepest gaps 2.9e-4 and 2.7e-4 m; implicit projection's 1.4e-2 (2.3e-4), 3.4e-4 m. Before
/// the penalty's own loss was booked (`State::contact_loss`) the first two ended at 6.4e-2 and
/// 5.9e-2, and peaked at 0.17.
fn coulomb_stack<const D: usize>(method: ContactMethod, deepest: f64)
where
    Dim<D>: SpatialDim<D>,
{
    coulomb_stack_on::<D>(method, GapDisplacement::Configuration, deepest);
}

/// [`coulomb_stack`] with the gaps measured on `gaps`.
fn coulomb_stack_on<const D: usize>(method: ContactMethod, gaps: GapDisplacement, deepest: f64)
where
    Dim<D>: SpatialDim<D>,
{
    let Stack {
        penetration, error, ..
    } = stack_with_friction::<D>(method, gaps, COULOMB);
    common::verify::record("stack", &format!("energy {D}D Coulomb"), error);
    assert!(error < 2e-2, "energy error {error}");
    assert!(penetration < deepest, "penetration {penetration}");
}

/// The stack with Tresca friction (300 Pa, about a third of a block's weight per area) on every
/// contact: a law that reads only whether a point is closed, over patches between bodies
/// whichever pass carries their load (`area_law_patch`).
fn tresca_stack<const D: usize>(method: ContactMethod, deepest: f64)
where
    Dim<D>: SpatialDim<D>,
{
    let Stack {
        penetration, error, ..
    } = stack_with_friction::<D>(
        method,
        GapDisplacement::Configuration,
        FrictionLaw::Tresca {
            limit: 300.0,
            regularization: 1e-4,
        },
    );
    common::verify::record("stack", &format!("energy {D}D Tresca"), error);
    assert!(error < 2e-2, "energy error {error}");
    assert!(penetration < deepest, "penetration {penetration}");
}

/// A stack rebuilt from its model and state while its blocks press on each other goes on
/// with the same bits as the run that was not: the contact patterns between bodies change
/// the factorisations' symbolic analyses, which the rebuilt simulation makes anew (its kept
/// analyses are a cache: each depends on its pattern alone).
fn rebuilt_stack_continues_bit_for_bit<const D: usize>(method: ContactMethod)
where
    Dim<D>: SpatialDim<D>,
{
    let stack = || {
        stack_simulation::<D>(
            method,
            GapDisplacement::Configuration,
            FrictionLaw::Frictionless,
        )
    };
    let (mut whole, mut first) = (stack(), stack());
    for _ in 0..30 {
        whole.step().unwrap();
        first.step().unwrap();
    }
    let mut rebuilt =
        Simulation::<D>::from_parts(first.model().clone(), first.state().clone()).unwrap();
    let lowest = whole.body_ids()[0];
    let in_lowest = whole.body_positions(lowest).unwrap().len();
    let mut between_bodies = 0;
    for step in 0..30 {
        let a = whole.step().unwrap();
        rebuilt.step().unwrap();
        assert_eq!(
            format!("{:?}", whole.state()),
            format!("{:?}", rebuilt.state()),
            "{method:?} step {step} after the rebuild"
        );
        between_bodies += a.contacts.iter().filter(|c| c.0 >= in_lowest).count();
    }
    assert!(between_bodies > 0, "{method:?}: the blocks never touched");
}

mod d2 {
    use softway::contact::{ContactMethod, GapDisplacement};

    #[test]
    fn a_rebuilt_stack_continues_bit_for_bit() {
        super::rebuilt_stack_continues_bit_for_bit::<2>(ContactMethod::ImplicitProjection);
        super::rebuilt_stack_continues_bit_for_bit::<2>(ContactMethod::SoftWay);
    }

    #[test]
    fn a_tresca_stack_under_the_soft_way() {
        super::tresca_stack::<2>(ContactMethod::SoftWay, 2e-3);
    }
    #[test]
    fn a_tresca_stack_under_the_augmented_lagrangian() {
        super::tresca_stack::<2>(ContactMethod::AugmentedLagrangian, 2e-3);
    }
    #[test]
    fn a_tresca_stack_under_implicit_projection() {
        // 1.78e-5 m since the master side's nodes are moved out too (2026-12-02).
        super::tresca_stack::<2>(ContactMethod::ImplicitProjection, 2e-4);
    }

    #[test]
    fn a_stack_under_implicit_projection() {
        // 9.96e-6 m since the master side's nodes are moved out too (2.9e-4 m before);
        // 1.00e-5 m, the master tolerance, since the correction watches the master side's
        // nodes within it and the points nothing holds (2026-12-02).
        super::a_stack_under_implicit_projection::<2>(1e-6, 1.5e-5);
    }
    #[test]
    fn a_stack_under_the_soft_way() {
        super::a_stack_under_the_soft_way::<2>();
    }
    #[test]
    fn trapezoid_gaps_keep_the_stack_apart() {
        super::trapezoid_gaps_keep_the_stack_apart::<2>();
    }
    #[test]
    fn trapezoid_gaps_keep_the_augmented_lagrangian_stack_apart() {
        super::trapezoid_gaps_keep_the_augmented_lagrangian_stack_apart::<2>();
    }
    #[test]
    fn a_coulomb_stack_under_the_augmented_lagrangian_on_trapezoid_gaps() {
        super::coulomb_stack_on::<2>(
            ContactMethod::AugmentedLagrangian,
            GapDisplacement::Trapezoid,
            1e-7,
        );
    }
    /// Uzawa with a fixed zeta (the paper's) needed over 50 iterations at the second landing
    /// (t = 0.104 s); with the default growing penalty it runs to the end.
    #[test]
    fn a_stack_under_the_augmented_lagrangian() {
        // Measured (2026-11-29): energy error at most 1.7e-2 after the landing, 2.1e-3 at
        // the end; largest penetration 2.9e-4 m, the same open defect
        // as the soft way's stack (the depth between the blocks after a step, far above what
        // Uzawa's gaps say).
        super::a_stack_under_the_augmented_lagrangian::<2>();
    }
    #[test]
    fn a_coulomb_stack_under_the_soft_way() {
        super::coulomb_stack::<2>(ContactMethod::SoftWay, 2e-3);
    }
    #[test]
    fn a_coulomb_stack_under_the_augmented_lagrangian() {
        super::coulomb_stack::<2>(ContactMethod::AugmentedLagrangian, 2e-3);
    }
    /// It stopped at step 496 of 500 (Newton out of iterations between the middle and top
    /// blocks) while each step's active set started from the predicted penetrations alone:
    /// the points resting on a block started free and fell 0.75 mm through it for a pass.
    /// Started from the points held when the last step ended (`State::active_contacts`), it
    /// runs: deepest gap 3.4e-4 m (the same bound as the frictionless stack's; 1.4e-4 m at
    /// rest, where the frictionless stack's is below a micrometre: friction holds the sag of
    /// the master nodes inside the patches, book, contact chapter, Limits). Since the
    /// end-of-step projection keeps held points on their masters (2026-11-30): 3.3e-4 m, 2.9e-4
    /// m in the last 50 ms.
    #[test]
    fn a_coulomb_stack_under_implicit_projection() {
        // 3.77e-5 m since the master side's nodes are moved out too (3.4e-4 m before).
        super::coulomb_stack::<2>(ContactMethod::ImplicitProjection, 2e-4);
    }
}

mod d3 {
    use softway::contact::{ContactMethod, GapDisplacement};

    #[test]
    fn a_rebuilt_stack_continues_bit_for_bit() {
        super::rebuilt_stack_continues_bit_for_bit::<3>(ContactMethod::ImplicitProjection);
        super::rebuilt_stack_continues_bit_for_bit::<3>(ContactMethod::SoftWay);
    }

    /// Measured 2026-11-30: the account at most 1.47e-2 after the landing (1.2e-4 at the
    /// end), deepest gap 4.0e-4 m, 4938 Newton iterations and no cut step in 36 s (dev build,
    /// two threads). It took 16 minutes at 20 to 50 iterations a step until the return map's
    /// tangential spring was capped at four diagonals per step (`PENALTY_TANGENT_CAP`).
    #[test]
    #[cfg_attr(
        not(feature = "parallel"),
        ignore = "slow without threads: runs with the default features; nothing it reaches depends on a feature but the threaded assembly, which determinism.rs checks"
    )]
    fn a_coulomb_stack_under_the_soft_way() {
        super::coulomb_stack::<3>(ContactMethod::SoftWay, 2e-3);
    }
    #[test]
    #[ignore = "slow: 113 s in a dev build with two threads, alone (2026-11-30; 23 minutes and \
                414 cut steps before the tangential spring's cap); passes: the account at most \
                1.54e-2 after the landing, deepest gap 3.5e-4 m, 13 636 Newton iterations, no \
                cut step; the 2D one and the soft way's 3D one run"]
    fn a_coulomb_stack_under_the_augmented_lagrangian() {
        super::coulomb_stack::<3>(ContactMethod::AugmentedLagrangian, 2e-3);
    }
    #[test]
    #[cfg_attr(
        not(feature = "parallel"),
        ignore = "slow without threads (20-50 s): runs with the default features; nothing it reaches depends on a feature but the threaded assembly, which determinism.rs checks"
    )]
    fn a_stack_under_the_soft_way() {
        super::a_stack_under_the_soft_way::<3>();
    }
    #[test]
    #[cfg_attr(
        not(feature = "parallel"),
        ignore = "slow without threads (20-50 s): runs with the default features; nothing it reaches depends on a feature but the threaded assembly, which determinism.rs checks"
    )]
    fn trapezoid_gaps_keep_the_stack_apart() {
        super::trapezoid_gaps_keep_the_stack_apart::<3>();
    }
    #[test]
    #[cfg_attr(
        not(feature = "parallel"),
        ignore = "slow without threads: runs with the default features"
    )]
    fn trapezoid_gaps_keep_the_augmented_lagrangian_stack_apart() {
        super::trapezoid_gaps_keep_the_augmented_lagrangian_stack_apart::<3>();
    }
    #[test]
    #[ignore = "slow: about 115 s in a dev build with two threads, beside a CI build (2026-11-30); passes: deepest gap 1.0e-9 m, the account at most 1.36e-2 after the landing and 2.7e-4 at the end, 14 435 Newton iterations, 1 cut step; the 2D one runs"]
    fn a_coulomb_stack_under_the_augmented_lagrangian_on_trapezoid_gaps() {
        super::coulomb_stack_on::<3>(
            ContactMethod::AugmentedLagrangian,
            GapDisplacement::Trapezoid,
            1e-7,
        );
    }
    /// The stack with Coulomb 0.5 under implicit projection. It stopped at step 142, then (with
    /// active edge pairs held through their step) at 191: about ten slipping points reversed
    /// their friction at every Newton iterate under a tangential spring of 100 diagonals per
    /// step; with one (`TANGENTIAL_PENALTY`) it runs.
    #[test]
    #[cfg_attr(
        not(feature = "parallel"),
        ignore = "slow without threads: runs with the default features; nothing it reaches depends on a feature but the threaded assembly, which determinism.rs checks"
    )]
    fn a_coulomb_stack_under_implicit_projection() {
        // 5.02e-5 m (7.1e-6 m after 0.45 s) since the master side's nodes are moved out too,
        // 7663 Newton iterations, 3 cut steps (2026-12-02; 3.45e-4 m, 6926 and 2 before).
        super::coulomb_stack::<3>(ContactMethod::ImplicitProjection, 2e-4);
    }
    /// It stopped at step 398 until an active edge pair stayed held for the rest of its step
    /// (`held_pairs`). Measured 2026-11-29: the account at most 1.77e-2 after the landing,
    /// deepest gap 5.9e-4 m (4.4e-4 m in the last 50 ms: a master node's sag), 5705 Newton
    /// iterations, 2 cut steps; 2026-11-30, with the projection's held rows: 1.71e-2, 6.9e-4 m
    /// (1.8e-4 m), 5670 iterations, 5 cut steps.
    #[test]
    #[cfg_attr(
        not(feature = "parallel"),
        ignore = "slow without threads (about 40 s): runs with the default features; nothing it reaches depends on a feature but the threaded assembly, which determinism.rs checks"
    )]
    fn a_stack_under_implicit_projection() {
        // Measured 2026-12-01: 5.7e-4 m (3.6e-4 m in the last 50 ms), 4403 Newton iterations,
        // 2 cut steps. With Newton's merit but not the carried multipliers the same day, one
        // step (492 of 500) left a node 2.28e-3 m inside (6.9e-4 m before): middle-block nodes
        // released from the top block's tumbling corner (the blocks turn 28 and 36 degrees),
        // clear on Newton's eq 22 positions, ended 1.5 mm inside in the stored configuration,
        // and the end-of-step projection that moved them out pushed a top-block facet 2 mm into
        // an unheld neighbour (scratch prints). Chaotic: before the merit the same scene at
        // h = 1.05 ms showed 2.16e-3 m, after it 6.7e-4 m (`softway run` of the scene, both
        // builds). The open test asks for none. Since the end-of-step projection moves the
        // master side's nodes deeper than `master_tolerance` out too (2026-12-02): 2.49e-5 m
        // (4.9e-6 m in the last 50 ms), the account at most 1.54e-2, 4831 iterations, 2 cuts.
        // Since the correction also watches the master side's nodes within the tolerance and
        // the points nothing holds (the same day): 1.00e-5 m, the tolerance (6.7e-6 m in the
        // last 50 ms), the account at most 1.43e-2, 4880 iterations, 4 cuts.
        super::a_stack_under_implicit_projection::<3>(2e-5, 1.5e-5);
    }
    /// Measured: largest penetration 1.04e-3 m, energy error 3.7e-3 at the end (before the
    /// penalty's loss was booked and the account checked throughout).
    #[test]
    #[ignore = "slow (about 40 s); the 2D one runs"]
    fn a_stack_under_the_augmented_lagrangian() {
        super::a_stack_under_the_augmented_lagrangian::<3>();
    }
    /// It stopped at step 47 until 2026-11-30: Coulomb's lagged threshold cycled with period
    /// two, an edge pair's load passed to a node of the lower block's top face or not as that
    /// node's own force read +0.011 N or -0.006 N (`threshold_samples` now reads its status).
    #[test]
    fn a_rubber_stack_with_friction_at_240_hz() {
        super::rubber_stack_at(1.0 / 240.0, 1.0);
    }
    /// Its account was 3.2e-2 off until 2026-11-30: a step cut in halves while the upper
    /// block bounced shifted the configuration without booking the loads' work on the shift
    /// (`step_change.rs`). Its blocks settle to their rest offset until about 1 s (the upper
    /// block's mean moved 1.1e-5 m between the last two quarter seconds of the first second
    /// since Newton's merit of 2026-12-01, then less than 1e-6 m a quarter second), so it runs
    /// half a second longer.
    #[test]
    fn a_rubber_stack_with_friction_at_60_hz() {
        super::rubber_stack_at(1.0 / 60.0, 1.5);
    }
}

/// Two rubber blocks (0.1 m, E = 1 MPa, 4^3 cubes of six Tet4, 5 % stiffness damping), the
/// upper 1 cm to the side, dropped 2 mm on a floor with Coulomb 0.5 everywhere, the
/// default method, a game's step: they come to rest, the upper one held by friction on the
/// offset, with the account within 2 %; the creep is measured between the last two quarter
/// seconds before `end_time` (s).
fn rubber_stack_at(time_step: f64, end_time: f64) {
    let mut builder = Simulation::<3>::builder()
        .time_step(time_step)
        .gravity(vec_d([0.0, 0.0, -9.81]));
    for k in 0..2 {
        let mut mesh: Mesh<3> = block([0.1, 0.1, 0.1], [4, 4, 4], true);
        let shift = vec_d::<3>([0.01 * k as f64, 0.0, 0.002 + 0.103 * k as f64]);
        for x in &mut mesh.nodes {
            *x += shift;
        }
        let rubber = Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap());
        builder =
            builder.body(Body::new(format!("block{k}"), mesh, rubber).with_damping(0.0, 1e-3));
    }
    let mut sim = builder
        .obstacle(common::floor::<3>())
        .contact(ContactSettings {
            friction: FrictionLaw::Coulomb {
                coefficient: 0.5,
                regularization: 1e-6,
            },
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    let upper = sim.body_nodes(sim.body_id("block1").unwrap()).unwrap();
    // The upper block's mean horizontal position (m).
    let centre = |sim: &Simulation<3>| {
        let x = sim.positions();
        upper
            .clone()
            .map(|n| x[n].xy())
            .sum::<nalgebra::Vector2<f64>>()
            / upper.len() as f64
    };
    // The upper block's mean position over the last two quarter seconds: the blocks still
    // rock (the centre swings by 3e-5 m at 1 s), a creep would move the mean.
    let (mut penetration, mut windows) = (0.0f64, [(nalgebra::Vector2::zeros(), 0); 2]);
    while sim.state().time < end_time - 1e-9 {
        let report = sim
            .step()
            .unwrap_or_else(|e| panic!("h = {time_step}, t = {}: {e}", sim.state().time));
        penetration = penetration.max(report.max_penetration);
        let t = sim.state().time;
        if t >= end_time - 0.5 - 1e-9 {
            let w = &mut windows[usize::from(t >= end_time - 0.25 - 1e-9)];
            w.0 += centre(&sim);
            w.1 += 1;
        }
    }
    let [early, late] = windows.map(|(sum, n)| sum / n as f64);
    let error = energy_error(&sim);
    let kinetic = sim.energies().kinetic;
    let creep = (late - early).norm();
    eprintln!(
        "h = {time_step}: energy error {error:.2e}, kinetic {kinetic:.2e} J, \
         deepest {penetration:.2e} m, upper block's mean moved {creep:.2e} m"
    );
    assert!(error < 2e-2, "energy error {error}");
    // At rest, held by friction on the offset; the deepest point is a master node's sag
    // (one pass: book, Contact resolution: limits).
    assert!(kinetic < 1e-4, "kinetic energy {kinetic} J");
    assert!(creep < 1e-5, "the upper block crept {creep} m");
    assert!(penetration < 5e-5, "penetration {penetration} m");
}

mod open {
    use super::Stack;
    use softway::contact::{ContactMethod, GapDisplacement};

    #[test]
    #[ignore = "penetration: 1.00e-5 m at worst, master_tolerance, 6.7e-6 m after 0.45 s since the \
                end-of-step projection keeps the master side's nodes from ending deeper than \
                master_tolerance = 1e-5 m (2026-12-02; 2.49e-5 m when it only moved those deeper \
                out, 5.3e-4 m with one pass, 2.28e-3 m on 12-01): a master \
                node between two held slaves sinks into the slave facet under it while the blocks \
                ring, and Newton does not hold it (book, contact chapter, Limits); it runs to the \
                end and the account holds (d3::a_stack_under_implicit_projection). Until an active edge pair stayed \
                held for the rest of its step it stopped at step 398: a top-block node in 5 kN \
                of tension dropped by the edge rule and taken again at the next iterate, for \
                50 iterations"]
    fn implicit_projection_3d() {
        // The targets: the account within 2 %, no block inside another.
        let Stack {
            penetration, error, ..
        } = super::stack::<3>(
            ContactMethod::ImplicitProjection,
            GapDisplacement::Configuration,
        );
        assert!(error < 2e-2, "energy error {error}");
        assert!(penetration < 1e-6, "penetration {penetration}");
    }
}
