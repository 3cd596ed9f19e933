//! Contact resolution: the laws that turn a detected pair into nodal forces and their tangent.
//!
//! A pair couples a slave node `s` with a master: a rigid obstacle moving at velocity `V`, or a
//! facet of a body with nodes `m_i` and weights `N_i` at the closest point. With the predicted
//! end positions of eq 22, `x1 = x0 + h (v0 + v1) / 2`, the gap is linear in the unknown:
//! `dg/dv1 = (h / 2) w` with the generalised normal `w = (n; -N_1 n; ...; -N_D n)`.
//!
//! * soft way: `p = zeta (-g)` for `g < 0`; the force on the nodes is `p A w` (A: the slave's
//!   tributary area), its tangent `(h/2) A (zeta w w^T - p grad^2 g)`.
//! * augmented Lagrangian: the same with `p = max(0, lambda - zeta g)` and Uzawa updates of
//!   `lambda` between solves.
//! * implicit projection: the relative normal end velocity `c = w . v1 - n . V` is held at zero
//!   by a multiplier (augmented Lagrangian on the velocity constraint, exact at convergence);
//!   positions are projected onto the master at the end of the step.
//! * explicit projection: the step is solved without contact; penetrating points are projected
//!   and their normal relative velocity removed at its end.
//!
//! Friction acts on the mean relative tangential velocity over the step,
//! `v_t = (I - n n) (v_rel(v0) + v_rel(v1)) / 2`, so that the dissipated work `-F_t . v_t h` is
//! the work along the slip of eq 22.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// How contact conditions are enforced (`[contact].method`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ContactMethod {
    /// Penalty on the normal displacement integrated from the velocity (eq 27).
    SoftWay,
    /// Active set with zero relative normal end velocity and end positions projected.
    #[default]
    ImplicitProjection,
    /// Uzawa updates of multipliers around soft-way solves (eq 28-30).
    AugmentedLagrangian,
    /// Status frozen in the step, projection at its end (category 1 baseline).
    ExplicitProjection,
}

impl ContactMethod {
    /// Every method, in the order the scene format lists them.
    pub const ALL: [ContactMethod; 4] = [
        ContactMethod::SoftWay,
        ContactMethod::ImplicitProjection,
        ContactMethod::AugmentedLagrangian,
        ContactMethod::ExplicitProjection,
    ];

    /// The scene-file name.
    pub fn name(self) -> &'static str {
        match self {
            ContactMethod::SoftWay => "soft_way",
            ContactMethod::ImplicitProjection => "implicit_projection",
            ContactMethod::AugmentedLagrangian => "augmented_lagrangian",
            ContactMethod::ExplicitProjection => "explicit_projection",
        }
    }

    /// Whether it is a penalty method (the soft way, the augmented Lagrangian): one that needs
    /// `penalty` (zeta) and may measure its gaps on [`GapDisplacement::Trapezoid`].
    pub fn is_penalty(self) -> bool {
        matches!(
            self,
            ContactMethod::SoftWay | ContactMethod::AugmentedLagrangian
        )
    }
}

/// Parses the scene-file name of a method (`[contact].method`: "soft_way",
/// "implicit_projection", "augmented_lagrangian", "explicit_projection"), as
/// [`ContactMethod::name`] writes it; anything else is [`Error::InvalidParameter`] listing the
/// valid names.
///
/// ```
/// use softway::contact::ContactMethod;
/// assert_eq!("soft_way".parse::<ContactMethod>().unwrap(), ContactMethod::SoftWay);
/// let e = "softway".parse::<ContactMethod>().unwrap_err();
/// assert!(e.to_string().contains("one of soft_way, implicit_projection"));
/// ```
impl std::str::FromStr for ContactMethod {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        ContactMethod::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| Error::InvalidParameter {
                name: "contact method".into(),
                found: format!("{s:?}"),
                expected: format!(
                    "one of {}",
                    ContactMethod::ALL.map(ContactMethod::name).join(", ")
                ),
            })
    }
}

pub use crate::friction::{FrictionLaw, DEFAULT_REGULARIZATION};

/// Everything `[contact]` sets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContactSettings {
    /// The method.
    pub method: ContactMethod,
    /// zeta (Pa/m): contact pressure per unit penetration (soft way, augmented Lagrangian).
    pub penalty: f64,
    /// Whether a body's nodes are checked against its own facets.
    pub self_contact: bool,
    /// Augmented Lagrangian: Uzawa stops when every gap is within this (m); implicit
    /// projection: the relative normal velocity tolerance is this over h.
    pub gap_tolerance: f64,
    /// The default friction law.
    pub friction: FrictionLaw,
    /// Largest number of Uzawa updates (augmented Lagrangian) or active-set passes.
    pub max_passes: usize,
    /// The displacement the gaps are measured on.
    #[serde(default)]
    pub gap_displacement: GapDisplacement,
    /// Implicit projection: the metric of its end-of-step projection.
    #[serde(default)]
    pub projection: ProjectionMetric,
    /// Implicit projection: the energy its end-of-step projection may put in.
    #[serde(default)]
    pub projection_energy: ProjectionEnergy,
    /// The soft way: the pressure from the end-of-step gap (the paper) or the potential's
    /// secant over the step.
    #[serde(default)]
    pub penalty_force: PenaltyForce,
    /// The augmented Lagrangian: zeta fixed through a step's Uzawa updates (the paper) or
    /// raised per pair where an update did not shrink its violation enough.
    #[serde(default)]
    pub uzawa_penalty: UzawaPenalty,
    /// Implicit projection between deformable surfaces: what keeps the master side's nodes out
    /// of the slave side's facets.
    #[serde(default)]
    pub master_nodes: MasterNodes,
    /// Implicit projection, [`MasterNodes::Projected`]: the depth (m) a master node may end
    /// at: shallower, it is left where Newton put it (and kept from ending deeper); deeper,
    /// it is moved out.
    #[serde(default = "default_master_tolerance")]
    pub master_tolerance: f64,
    /// On trapezoid gaps ([`GapDisplacement::Trapezoid`]), whether a pair that ends its step
    /// closed (a normal force pushing it out) and still approaching has that relative normal
    /// velocity stopped after the step (`Simulation::stop_closed_pairs`: the persistency
    /// condition as a velocity update, the impulse's work booked as dissipation). `None`: the
    /// method's own choice, on for the augmented Lagrangian (whose multipliers close those
    /// gaps) and off for the soft way (the paper's penalty). On, the soft way's contact
    /// nodes no longer keep the step-to-step alternation `w1 = -w0` that trapezoid gaps do
    /// not see (the trapezoid rule on a penalty spring stiffer than the step resolves); the
    /// book's contact chapter has the measurements. Penalty methods on trapezoid gaps only.
    #[serde(default)]
    pub persistency_stop: Option<bool>,
}

fn default_master_tolerance() -> f64 {
    DEFAULT_MASTER_TOLERANCE
}

/// The default [`ContactSettings::master_tolerance`] (m). A resting stack's master nodes sit a
/// few micrometres inside at equilibrium (5 um on the bundled block stack): moved out at every
/// step, Newton put them back at the next, and the stack took 1419 Newton iterations instead
/// of 907 (1404 at a tolerance of 1e-6 m, 1038 at 5e-6 m, 887 at 1e-5 m; 2026-12-02).
pub const DEFAULT_MASTER_TOLERANCE: f64 = 1e-5;

/// What keeps implicit projection's master nodes out of the slave surface between two
/// deformable bodies. Newton holds one pass as constraints (the nodes of the body listed
/// first against the other's facets, plus the other's nodes beyond the edge of the first
/// one's): two passes over a patch would hold it twice, and the active set cycles. The other
/// body's nodes inside the patch are masters only, and sink into the slave facets between
/// held nodes while the bodies ring (a master node between two held slaves, by about
/// `l theta / 4` for a facet of length `l` and a turn `theta` of the master surface).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MasterNodes {
    /// The end-of-step projection moves those deeper than
    /// [`ContactSettings::master_tolerance`] out too, and keeps the others from ending deeper
    /// than it: their pairs are inequality rows of the
    /// same correction that puts the held points on their masters (the step metric,
    /// [`ProjectionMetric::Step`]; the paper's node projection moves active points only). Not
    /// within a fold (self-
    /// contact): moved out there, the folding strip's tip created 0.49 of the reference
    /// energy (4.5e-2 with the default tolerance).
    #[default]
    Projected,
    /// One pass and nothing else (until 2026-12-02).
    Free,
}

/// How the augmented Lagrangian's penalty evolves through a step's Uzawa updates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UzawaPenalty {
    /// The method of multipliers' penalty update (Bertsekas 1982; Nocedal and Wright,
    /// Algorithm 17.4), per pair: where an update left the pair's violation (its penetration,
    /// or the open gap a pressure acts across) above a quarter of the previous one, its
    /// penalty grows tenfold, up to 100 zeta, for the rest of the step. Each update shrinks a
    /// penetration by about `k / (k + zeta A)` (k the body's stiffness there), so with a
    /// fixed zeta that is soft for the body Uzawa crawls: the 3D gripper's first touch needed
    /// about 120 iterations, over the default 50 (the book's contact chapter).
    #[default]
    Growing,
    /// The paper's eq 28-30: zeta fixed.
    Fixed,
}

/// How the soft way turns the step's gaps into a pressure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PenaltyForce {
    /// The paper's eq 27: `p = zeta max(-g1, 0)` on the end-of-step gap `g1`. Over a step it
    /// does the work `-p A (g1 - g0)`, which differs from the change of the penalty's potential
    /// `zeta A min(g, 0)^2 / 2` by `zeta A (g1 - g0)^2 / 2`: lost while the pair stays closed,
    /// and gained or lost when it opens or closes within the step.
    #[default]
    EndOfStep,
    /// The potential's secant over the step (a discrete gradient: Laursen and Chawla 1997,
    /// Armero and Petocz 1998): `p = (phi(g0) - phi(g1)) / (g1 - g0)` with
    /// `phi(g) = zeta min(g, 0)^2 / 2`, `g0` the start-of-step gap, so that the force's work over
    /// the step is exactly the potential's change; `zeta (-(g0 + g1) / 2)` while closed, half
    /// the paper's stiffness in the iteration. With `GapDisplacement::Trapezoid` and
    /// `beta = 1 - alpha` the scheme's conserved energy plus the potential is then conserved by
    /// frictionless contact. Penalty pressure only: the soft way.
    Secant,
}

/// How implicit projection moves its penetrating active points onto their masters at the end
/// of a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProjectionMetric {
    /// The smallest change of the whole configuration in the step's iteration matrix
    /// `M/h + alpha^2 h K / 2`: the contact patch moves with its neighbours, and a body
    /// stopped in one step is not strained by the correction (the book's contact chapter has
    /// the measurements).
    #[default]
    Step,
    /// The paper's projection: each point alone (shared with a deformable master by mass).
    /// Where the step exceeds the contact patch's period the correction strains the cells
    /// around each point by up to `h |v0| / 2` and puts energy in.
    Node,
}

/// How much energy implicit projection's end-of-step correction ([`ProjectionMetric`]) may put
/// into the bodies' conserved energy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProjectionEnergy {
    /// Whatever the correction does, booked as (negative) dissipation: the paper's. On the
    /// soft cube at h = 1/60 s it puts 0.94 J in at the second landing and the run warns
    /// (the book's contact chapter, Limits).
    Booked,
    /// At most what the run has dissipated so far (what the contact's inelastic stops took):
    /// the excess is taken back out of each body's deformation velocity (its velocity minus
    /// its rigid motion, scaled), so that linear and angular momentum are kept. The default:
    /// it changes nothing where the paper's correction creates no energy (every bundled
    /// scene), and lands the soft cube without creating any.
    #[default]
    Bounded,
}

/// The displacement that contact gaps are measured on, at the start of a step (over the step
/// every choice adds eq 22's `h (v0 + v1) / 2`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GapDisplacement {
    /// The configuration of the scheme's update (eq 12), as the paper takes the start of each
    /// step. For `beta != 1/2` a node that changes velocity is stored `h (1/2 - beta)` times
    /// the change deeper than its gap said, and the next step's penalty pushes it back out:
    /// energy enters at impacts (the book's contact chapter has the measurements).
    #[default]
    Configuration,
    /// The running sum of eq 22 over every step, the exact integral of the piecewise-linear
    /// velocity (kept in [`crate::simulation::State::gap_displacement`]). With
    /// `beta = 1 - alpha` it is the displacement in which the scheme's conserved energy
    /// books a force's work: a penalty on it no longer creates energy at impacts and the
    /// stored penetration is the penalty's, but the contact springs lose the damping the
    /// configuration's offset gave them. Penalty methods only (soft way, augmented
    /// Lagrangian); the projections always use the configuration. Under the augmented
    /// Lagrangian, whose multipliers close these gaps, a pair that ends a step closed and
    /// still approaching has that normal velocity stopped after the step, by the smallest
    /// change of the velocities in the step's metric (the persistency condition as a velocity
    /// update, after Laursen and Love 2002; booked as dissipation); without it a closed pair
    /// alternates `w1 = -w0` from step to step, which the scheme does not damp. The soft way
    /// takes the same stop as an option ([`ContactSettings::persistency_stop`]).
    Trapezoid,
}

impl Default for ContactSettings {
    fn default() -> Self {
        ContactSettings {
            method: ContactMethod::ImplicitProjection,
            penalty: 0.0,
            self_contact: false,
            gap_tolerance: 1e-9,
            friction: FrictionLaw::Frictionless,
            max_passes: 50,
            gap_displacement: GapDisplacement::Configuration,
            projection: ProjectionMetric::Step,
            projection_energy: ProjectionEnergy::Bounded,
            penalty_force: PenaltyForce::EndOfStep,
            uzawa_penalty: UzawaPenalty::Growing,
            master_nodes: MasterNodes::Projected,
            master_tolerance: DEFAULT_MASTER_TOLERANCE,
            persistency_stop: None,
        }
    }
}

impl ContactSettings {
    /// Whether closed, approaching pairs are stopped after each step
    /// ([`ContactSettings::persistency_stop`], or the method's own choice).
    pub fn stops_closed_pairs(&self) -> bool {
        self.method.is_penalty()
            && self.gap_displacement == GapDisplacement::Trapezoid
            && self
                .persistency_stop
                .unwrap_or(self.method == ContactMethod::AugmentedLagrangian)
    }

    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        if self.method.is_penalty() && !(self.penalty > 0.0 && self.penalty.is_finite()) {
            return Err(Error::InvalidParameter {
                name: "penalty".into(),
                found: self.penalty.to_string(),
                expected: format!("zeta > 0 [Pa/m] for method {}", self.method.name()),
            });
        }
        if !(self.gap_tolerance > 0.0 && self.gap_tolerance.is_finite()) {
            return Err(Error::InvalidParameter {
                name: "gap_tolerance".into(),
                found: self.gap_tolerance.to_string(),
                expected: "a finite value > 0 [m]".into(),
            });
        }
        if !(self.master_tolerance >= 0.0 && self.master_tolerance.is_finite()) {
            return Err(Error::InvalidParameter {
                name: "master_tolerance".into(),
                found: self.master_tolerance.to_string(),
                expected: "a finite value >= 0 [m]".into(),
            });
        }
        if let Some(stop) = self.persistency_stop {
            if !self.method.is_penalty() || self.gap_displacement != GapDisplacement::Trapezoid {
                return Err(Error::InvalidParameter {
                    name: "persistency_stop".into(),
                    found: format!(
                        "{stop} with method {} on {:?} gaps",
                        self.method.name(),
                        self.gap_displacement
                    ),
                    expected: "method soft_way or augmented_lagrangian with gap_displacement \
                               \"trapezoid\" (the stop keeps trapezoid gaps' closed pairs \
                               closed), or no persistency_stop"
                        .into(),
                });
            }
        }
        if self.penalty_force == PenaltyForce::Secant {
            if self.method != ContactMethod::SoftWay {
                return Err(Error::InvalidParameter {
                    name: "penalty_force".into(),
                    found: format!("\"secant\" with method {}", self.method.name()),
                    expected: "method soft_way (the secant is the soft way's pressure), or \
                               penalty_force \"end_of_step\""
                        .into(),
                });
            }
            // On the configuration's gaps the start of a step is offset from the end of the
            // last by h (1/2 - beta) dv: the secant then pumps energy in (the ring drop
            // diverged at its landing, 2.5e6 times its reference by step 143).
            if self.gap_displacement != GapDisplacement::Trapezoid {
                return Err(Error::InvalidParameter {
                    name: "penalty_force".into(),
                    found: "\"secant\" with gap_displacement \"configuration\"".into(),
                    expected: "gap_displacement \"trapezoid\" (the secant needs the start of each \
                               step's gap to be the end of the last's)"
                        .into(),
                });
            }
        }
        self.friction.validate()
    }
}
