//! Monitors that speak up: bodies that overlap each other or an obstacle (at t = 0, where no
//! method can be trusted to separate them gracefully), and the energy account that says when
//! a run created energy (more energy in the bodies, plus what left them, than was ever put
//! in).

use std::fmt;

use serde::{Deserialize, Serialize};

use super::{Energies, Simulation, StepReport};
use crate::contact::ContactMethod;
use crate::dim::{Dim, SpatialDim};
use crate::error::{Error, Result};
use crate::time::SpaceTimeScheme;

/// Nodes of a body inside another body or an obstacle in the current configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct Overlap {
    /// The body whose nodes are inside.
    pub body: String,
    /// What they are inside: `body `NAME`` or `obstacle `NAME``.
    pub other: String,
    /// Nodes inside.
    pub nodes: usize,
    /// The deepest of them (m): the distance to the nearest surface of the other.
    pub depth: f64,
    /// Whether the other is a polyline or trimesh obstacle (whose solid side is set by the
    /// order of each facet's vertices).
    pub facets: bool,
    /// The nodes deeper than contact detection reaches into the other (`reach`): no contact
    /// method ever finds them.
    pub beyond_reach: usize,
    /// How deep contact detection reaches into the other (m): its margin, a quarter of the
    /// mean boundary facet, for another body, a polyline or a trimesh; infinite for a
    /// half-space, a box or a ball (found at any depth).
    pub reach: f64,
}

impl fmt::Display for Overlap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "body `{}` overlaps {} at t = 0: {} node(s) inside, the deepest {:.3e} m; move the \
             bodies apart in the scene (contact methods push an overlap out in one step, with \
             an impulse that is not physical)",
            self.body, self.other, self.nodes, self.depth
        )?;
        write!(f, "{}", super::overlap::facet_hint(self.facets))
    }
}

/// Nodes of a body that passed through an obstacle within the last step and ended outside it
/// on its far side ([`Simulation::tunnelled`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Tunnel {
    /// The body whose nodes passed through.
    pub body: String,
    /// The fastest of them: its index in its body's mesh.
    pub node: usize,
    /// What they passed through: `obstacle `NAME``.
    pub other: String,
    /// Nodes that passed through.
    pub nodes: usize,
    /// The fastest node's speed relative to the obstacle over the step (m/s).
    pub speed: f64,
    /// Its path relative to the obstacle over the step (m).
    pub travel: f64,
    /// The part of that path inside the obstacle (m).
    pub inside: f64,
    /// The time it took to cross the obstacle (s): the step times `inside / travel`.
    pub crossing_time: f64,
}

/// The fraction of the input energy a run may create before a warning:
/// `E(t) + max(dissipated, 0) > (1 + ENERGY_WARNING) (E(0) + |external work|)`.
pub const ENERGY_WARNING: f64 = 0.05;
/// ... and before the run is stopped (exit status 3): ten times the input created, an
/// energy of eleven times all that went in, which no reading of the account explains (the
/// runs of issue 14 reached 35 to 200 times their input; explicit projection on the bundled
/// ring drop books about 1x its input as created and only warns).
pub const ENERGY_FAILURE: f64 = 10.0;
/// The fraction of the input that may leave the scheme's conserved energy unbooked (neither
/// stored nor dissipated) before a warning ([`RunMonitor::scheme_energy_drift`]): the
/// creation warning's threshold, for the other sign.
pub const ENERGY_LOSS_WARNING: f64 = 0.05;
/// The tension of the points implicit projection held closed through a contact-set cycle,
/// as a fraction of the compression of the step's other contact points (or, if larger, of the
/// most the run's contact points have pressed with in one step so far), above which the run
/// stops (exit status 3): half the contact answer is then adhesion. Every cycle is a warning
/// (the first one's step in the summary); in the implicit-projection runs of tests/contact.rs,
/// friction.rs, gripper.rs, rotating_obstacles.rs, monitors.rs and soft_cube.rs the held
/// points carried at most 1.5 N of tension against 234 N of compression.
pub const HELD_TENSION_FAILURE: f64 = 0.5;

/// The energy created so far, as a fraction of the input: `(E(t) + max(D, 0) - E(0) - |W|) /
/// (E(0) + |W|)`, with E = kinetic + internal + contact energy, D the dissipated energy and W
/// the external work. A run that keeps its account has `E(t) + D = E(0) + W <= E(0) + |W|`,
/// so a positive value is energy that nothing put in (an unstable step, a projection that
/// pushes, a penalty too stiff for the step). Zero when there is no input to compare with.
pub fn energy_created(e0: f64, e: &Energies) -> f64 {
    let input = e0 + e.external_work.abs();
    if !(input > 0.0) {
        return 0.0;
    }
    (e.total() + e.dissipated.max(0.0) - input) / input
}

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// The largest penetration in the current configuration (m; 0 when none): the deepest of
    /// [`Simulation::overlaps`], what history.csv's `max_penetration` reports at t = 0 and
    /// `check` warns about. (It was the deepest negative gap a detector with a wide margin
    /// found, which at the end of a tube's wall that leans by a hair paired the inner face's
    /// nodes with the end face: 0.96 mm of self-overlap that is not there.)
    pub fn current_penetration(&self) -> f64 {
        self.overlaps().iter().fold(0.0, |m: f64, o| m.max(o.depth))
    }
}

/// A cell of any body turned inside out at the end of the step: [`Error::TurnedInsideOut`].
fn inverted_cell_check<const D: usize>(sim: &Simulation<D>, report: &StepReport) -> Result<()>
where
    Dim<D>: SpatialDim<D>,
{
    match sim.inverted_cell() {
        Some((body, cell, centre)) => Err(Error::TurnedInsideOut {
            step: report.step,
            time: report.time,
            body,
            cell,
            centre: centre.as_slice().to_vec(),
        }),
        None => Ok(()),
    }
}

/// Whether a step's contact-set cycle left an answer other than the law's: a point held
/// closed that ends in tension, or a point held open that ends penetrating while it
/// approaches (deeper than `gap_tolerance`, m), or a cycle with no point held (a cut
/// attempt's). Held points that all end on the law's side (closed ones pressing, open ones
/// clear or leaving) make the set the law's own, whatever the iteration went through: the
/// bundled block stack's two cycled steps end so (2026-11-30: seven and nine points held
/// open 1e-6 to 2.6e-5 m clear, one held closed pressing with 0.016 and 0.010 N).
fn cycle_left_the_law(report: &StepReport, gap_tolerance: f64) -> bool {
    if report.held_contacts == 0 {
        return report.contact_cycles > 0;
    }
    report.held_tension > 0.0 || report.held_open_depth > gap_tolerance
}

/// An [`Error::ContactCycling`] when the points held closed through a contact-set cycle pull
/// with more than [`HELD_TENSION_FAILURE`] of the compression of the step's other points, or
/// of `run_compression` (N), the most the run's contact points pressed with in one step, if
/// that is larger: a light touch whose held points pull a little while nothing else presses
/// (a fold's first contact: 0.24 N/m in one step, against 0.6 to 7.6 N/m carried in the steps
/// around it) is not a contact answer made of adhesion.
fn held_tension_check(report: &StepReport, run_compression: f64) -> Result<()> {
    let reference = report.compression.max(run_compression);
    if report.held_tension > HELD_TENSION_FAILURE * reference {
        return Err(Error::ContactCycling {
            step: report.step,
            time: report.time,
            held: report.held_contacts,
            tension: report.held_tension,
            compression: report.compression,
            run_compression,
            limit: 100.0 * HELD_TENSION_FAILURE,
        });
    }
    Ok(())
}

/// Watches a run step by step ([`RunMonitor::step`]): the energy created beyond the input
/// ([`energy_created`]: a warning above [`ENERGY_WARNING`], an error above
/// [`ENERGY_FAILURE`]), penetrations deeper than a tenth of the mean boundary facet, steps
/// that had to be cut, and steps in which implicit projection's contact set cycled
/// ([`StepReport::held_contacts`], [`StepReport::contact_cycles`]). [`RunMonitor::warnings`]
/// says what it saw, for the summary. A checkpoint stores it, so that a resumed run measures
/// from the run's start and stops where the uninterrupted one stops.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
// The unit tests build one field by field; a monitor of zeros means nothing to a caller.
#[cfg_attr(test, derive(Default))]
pub struct RunMonitor {
    v0: Vec<f64>,
    e0: f64,
    method: Option<ContactMethod>,
    penetration_tolerance: f64,
    /// (step, time, fraction) where the warning threshold was first crossed, and the peak.
    created: Option<(usize, f64, f64)>,
    created_peak: f64,
    /// (step, time) of the first penetration beyond the tolerance, and the deepest.
    penetrated: Option<(usize, f64)>,
    deepest: f64,
    /// Steps that were cut, cuts in all, the first such step and its time.
    cut_steps: usize,
    cuts: usize,
    first_cut: Option<(usize, f64)>,
    /// Cut steps with a cut made because an attempt spent `max_iterations`, and that limit
    /// (defaults: a checkpoint written before 2026-11-30 still loads).
    #[serde(default)]
    cut_steps_out_of_iterations: usize,
    #[serde(default)]
    max_iterations: usize,
    /// Steps in which implicit projection's active set cycled and the points it held end
    /// against its law ([`cycle_left_the_law`]), the first such step and its time, and the
    /// most points held in one step.
    cycled_steps: usize,
    first_cycle: Option<(usize, f64)>,
    most_held: usize,
    /// The most the contact points pressed with in one step so far (N), the scale the held
    /// points' tension is measured against when a step's other points press less. Absent
    /// in checkpoints written before it was kept: it starts again at the checkpoint.
    #[serde(default)]
    compression_peak: f64,
    /// Implicit projection's activation tolerance on a gap (m, `contact.gap_tolerance`): a
    /// point held open within it of the law's side is not a compromise. (0 in checkpoints
    /// written before it was kept: every point held open in a wrong state then counts.)
    #[serde(default)]
    gap_tolerance: f64,
    /// Whether the penalty methods measure gaps on the stored configuration (the paper's
    /// `gap_displacement`), whose offset at impacts is what creates energy on a bouncing body.
    #[serde(default)]
    configuration_gaps: bool,
    /// Whether implicit projection's end-of-step correction may put in any energy
    /// (`projection_energy = "booked"`, the paper's), which is what creates energy on a soft
    /// body at a game's step.
    #[serde(default)]
    projection_energy_booked: bool,
    /// The stability warning of a scheme outside the unconditionally stable window, whose
    /// conserved quantity Q is no norm (g < 0): modes stiffer than its limit grow while Q
    /// stays, so the mechanical energy E is watched too, from `e0_mechanical`.
    #[serde(default)]
    outside_window: Option<String>,
    /// E(0), for that watch.
    #[serde(default)]
    e0_mechanical: f64,
    /// Whether the warning threshold was crossed by E rather than Q.
    #[serde(default)]
    created_mechanical: bool,
    /// The account on the scheme's conserved energy at the last step of the configured size
    /// ([`RunMonitor::scheme_energy_drift`]), signed: negative where energy left unbooked.
    #[serde(default)]
    scheme_account: f64,
    /// The time scheme's (alpha, beta), which damps where alpha + beta != 1 (unknown in
    /// checkpoints written before it was kept).
    #[serde(default)]
    scheme: Option<(f64, f64)>,
    /// Whether a body's law is the hypoelastic one, whose stored energy is not the integral
    /// of its stress power over large strain increments.
    #[serde(default)]
    hypoelastic: bool,
}

/// What [`RunMonitor`] measured the energy created on.
fn measure_name(mechanical: bool) -> &'static str {
    if mechanical {
        "the mechanical energy (kinetic + internal + contact, which the time scheme does not \
         bound outside its stability window)"
    } else {
        "the energy the time scheme conserves (kinetic + internal + contact)"
    }
}

impl RunMonitor {
    /// A monitor of `sim` from its current state (E(0) is the simulation's reference energy).
    pub fn new<const D: usize>(sim: &Simulation<D>) -> Self
    where
        Dim<D>: SpatialDim<D>,
    {
        let detector = sim.caches.detector.as_ref();
        RunMonitor {
            v0: sim.state.velocity.clone(),
            e0: sim.scheme_energy() + sim.state().contact_energy,
            e0_mechanical: sim.energies().total(),
            created_mechanical: false,
            outside_window: sim.model.settings.scheme.stability_warning(),
            method: detector.map(|_| sim.model.contact.method),
            projection_energy_booked: sim.model.contact.projection_energy
                == crate::contact::ProjectionEnergy::Booked,
            configuration_gaps: sim.model.contact.gap_displacement
                == crate::contact::GapDisplacement::Configuration,
            // A tenth of the mean boundary facet (the margin is a quarter of it).
            penetration_tolerance: detector.map_or(f64::INFINITY, |d| 0.4 * d.options().margin),
            created: None,
            created_peak: 0.0,
            penetrated: None,
            deepest: 0.0,
            cut_steps: 0,
            cuts: 0,
            first_cut: None,
            cut_steps_out_of_iterations: 0,
            max_iterations: sim.model.settings.max_iterations,
            cycled_steps: 0,
            first_cycle: None,
            most_held: 0,
            compression_peak: 0.0,
            gap_tolerance: sim.model.contact.gap_tolerance,
            scheme_account: 0.0,
            scheme: Some((
                sim.model.settings.scheme.alpha,
                sim.model.settings.scheme.beta,
            )),
            hypoelastic: sim
                .model
                .bodies
                .iter()
                .any(|b| matches!(b.material, crate::material::Material::Hypoelastic(_))),
        }
    }

    /// Checks a committed step: `Ok(Some(message))` when a warning threshold is crossed for
    /// the first time (to log now), an [`Error::FellThrough`] when nodes ended the step inside
    /// another body or a polyline or trimesh beyond the reach of contact detection
    /// ([`Simulation::fell_through`]), an [`Error::Tunnelled`] when nodes passed through an
    /// obstacle within the step and ended outside it on its far side
    /// ([`Simulation::tunnelled`]), an [`Error::ContactCycling`] when the points held closed
    /// through a contact-set cycle pull with more than [`HELD_TENSION_FAILURE`] of the other
    /// points' compression (or of the most the run's points pressed with in a step), an
    /// [`Error::EnergyCreated`] when the energy created
    /// exceeds [`ENERGY_FAILURE`] times the input.
    pub fn step<const D: usize>(
        &mut self,
        sim: &Simulation<D>,
        report: &StepReport,
    ) -> Result<Option<String>>
    where
        Dim<D>: SpatialDim<D>,
    {
        if let Some(o) = sim.fell_through() {
            return Err(Error::FellThrough {
                step: report.step,
                time: report.time,
                body: o.body,
                other: o.other,
                nodes: o.nodes,
                depth: o.depth,
                reach: o.reach,
                advice: format!(
                    "{}{}",
                    match self.method {
                        Some(ContactMethod::SoftWay | ContactMethod::AugmentedLagrangian) => {
                            "the body crossed the surface within a step without being caught, or \
                             sank through it: use a smaller time_step (a node should move less \
                             than a quarter of the mean boundary facet per step) or a larger \
                             penalty"
                        }
                        _ => {
                            "the body crossed the surface within a step without being caught: \
                             use a smaller time_step (a node should move less than a quarter of \
                             the mean boundary facet per step)"
                        }
                    },
                    if o.facets {
                        format!(
                            "; or it was on the solid side all along{}",
                            super::overlap::facet_hint(true)
                        )
                    } else {
                        String::new()
                    }
                ),
            });
        }
        if let Some(t) = sim.tunnelled() {
            return Err(Error::Tunnelled {
                step: report.step,
                time: report.time,
                body: t.body,
                node: t.node,
                other: t.other,
                nodes: t.nodes,
                speed: t.speed,
                travel: t.travel,
                inside: t.inside,
                crossing_time: t.crossing_time,
            });
        }
        held_tension_check(report, self.compression_peak)?;
        self.compression_peak = self.compression_peak.max(report.compression);
        let mut news = Vec::new();
        // Q is the invariant of steps of the configured size: a shortened last step leaves a
        // state off that orbit, which says nothing about energy created.
        let h = sim.model.settings.time_step;
        if (report.time_step - h).abs() > 1e-9 * h {
            inverted_cell_check(sim, report)?;
            self.note_contacts(report, &mut news);
            return Ok((!news.is_empty()).then(|| news.join("; ")));
        }
        // Measured on the energy the scheme conserves, Q (E swings on stiff modes while Q
        // stays), with the external work in Q's terms: f . du + h/2 (alpha - beta) f . dv.
        let mut energies = report.energies;
        energies.kinetic = sim.scheme_energy();
        energies.internal = 0.0;
        let SpaceTimeScheme { alpha, beta } = sim.model.settings.scheme;
        let f_dv: f64 = (0..self.v0.len())
            .map(|i| {
                (sim.gravity_force[i] + sim.state.loads.get(i).copied().unwrap_or(0.0))
                    * (sim.state.velocity[i] - self.v0[i])
            })
            .sum();
        energies.external_work += 0.5 * h * (alpha - beta) * f_dv;
        let input = self.e0 + energies.external_work.abs();
        if input > 0.0 {
            self.scheme_account =
                (energies.total() + energies.dissipated - self.e0 - energies.external_work) / input;
        }
        let mut measured = (energy_created(self.e0, &energies), self.e0, energies, false);
        if self.outside_window.is_some() {
            // Q holds still while a mode the scheme amplifies grows: E shows it (the ring drop
            // at alpha = 0.703, beta = 1 - alpha: E(t) + D reaches 11x the input at step 430,
            // where Q never crossed the 5 % warning).
            let created = energy_created(self.e0_mechanical, &report.energies);
            if created > measured.0 {
                measured = (created, self.e0_mechanical, report.energies, true);
            }
        }
        let (created, e0, energies, mechanical) = measured;
        self.created_peak = self.created_peak.max(created);
        if created > ENERGY_FAILURE {
            return Err(Error::EnergyCreated {
                step: report.step,
                time: report.time,
                measure: measure_name(mechanical).into(),
                energy: energies.total() + energies.dissipated.max(0.0),
                input: e0 + energies.external_work.abs(),
                percent: 100.0 * created,
                advice: self.advice(),
            });
        }
        // After the gross energy check: a run that created that much names its cause there.
        inverted_cell_check(sim, report)?;
        if created > ENERGY_WARNING && self.created.is_none() {
            self.created = Some((report.step, report.time, created));
            self.created_mechanical = mechanical;
            news.push(format!(
                "energy created: from step {} (t = {:.6e} s)",
                report.step, report.time
            ));
        }
        self.note_contacts(report, &mut news);
        Ok((!news.is_empty()).then(|| news.join("; ")))
    }

    /// The penetration, the step cuts and the contact-set cycles of a step.
    fn note_contacts(&mut self, report: &StepReport, news: &mut Vec<String>) {
        self.deepest = self.deepest.max(report.max_penetration);
        if report.max_penetration > self.penetration_tolerance && self.penetrated.is_none() {
            self.penetrated = Some((report.step, report.time));
            news.push(format!(
                "penetration {:.3e} m at step {} (t = {:.6e} s)",
                report.max_penetration, report.step, report.time
            ));
        }
        if report.cuts > 0 {
            self.cut_steps += 1;
            self.cuts += report.cuts;
            self.first_cut.get_or_insert((report.step, report.time));
            if report.cuts_out_of_iterations > 0 {
                self.cut_steps_out_of_iterations += 1;
            }
        }
        if cycle_left_the_law(report, self.gap_tolerance) {
            self.cycled_steps += 1;
            self.most_held = self.most_held.max(report.held_contacts);
            if self.first_cycle.is_none() {
                self.first_cycle = Some((report.step, report.time));
                news.push(format!(
                    "contact set cycled at step {} (t = {:.6e} s)",
                    report.step, report.time
                ));
            }
        }
    }

    /// The largest energy created so far, as a fraction of the input, on the measure the
    /// warnings use (the scheme's conserved energy; outside the stability window, the larger
    /// of it and the mechanical energy): 0 when none was created.
    pub fn energy_created_peak(&self) -> f64 {
        self.created_peak
    }

    /// The energy account on the scheme's own terms at the last step of the configured size:
    /// `|Q(t) + C(t) + D - Q(0) - C(0) - W_w| / (Q(0) + C(0) + |W_w|)`, Q the energy the
    /// time scheme conserves, C the contact energy, D the dissipated energy and W_w the loads'
    /// work on the shadow displacement `w = u + (alpha - beta) h v / 2`. `energy_drift` is the
    /// same account on the mechanical energy E and the work on u, which differ from these by
    /// `O(h)` where a body's velocity changed under a load (the book's time-scheme chapter);
    /// this one closes wherever the scheme's energy is booked whole.
    pub fn scheme_energy_drift(&self) -> f64 {
        self.scheme_account.abs()
    }

    /// What the monitor saw, as summary warnings.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if let Some((step, time, fraction)) = self.created {
            w.push(format!(
                "the run created energy: {} plus the dissipated energy exceeded the input E(0) \
                 + |external work| by {:.1}% at step {step} (t = \
                 {time:.6e} s), {:.1}% at most (warning above {:.0}%, the run stops above \
                 {:.0}%); {}",
                measure_name(self.created_mechanical),
                100.0 * fraction,
                100.0 * self.created_peak,
                100.0 * ENERGY_WARNING,
                100.0 * ENERGY_FAILURE,
                self.advice()
            ));
        }
        if let Some((step, time)) = self.penetrated {
            w.push(format!(
                "penetration beyond {:.3e} m (a tenth of the mean boundary facet) from step \
                 {step} (t = {time:.6e} s), {:.3e} m at most; {}",
                self.penetration_tolerance,
                self.deepest,
                match self.method {
                    Some(ContactMethod::SoftWay | ContactMethod::AugmentedLagrangian) => {
                        "a larger penalty or a smaller time_step keeps the bodies apart"
                    }
                    _ => "a smaller time_step keeps the bodies apart",
                }
            ));
        }
        if -self.scheme_account > ENERGY_LOSS_WARNING {
            let cause = if let Some((alpha, beta)) =
                self.scheme.filter(|(a, b)| (a + b - 1.0).abs() > 1e-12)
            {
                format!(
                    "the time scheme damps numerically (alpha = {alpha}, beta = {beta}: it \
                     conserves its energy only where beta = 1 - alpha)"
                )
            } else if self.hypoelastic {
                "the hypoelastic law is the likely cause: its stored energy (1/2 sigma : C^-1 \
                 sigma) is not the integral of its stress power over large strain increments \
                 (one block thrown at 3 m/s on a floor leaves 2.5 to 14.5 % unbooked at steps \
                 from 1e-3 to 1/60 s, without a trend; the linear-elastic block 1e-12)"
                    .to_string()
            } else {
                "a term whose energy is not booked (the cut steps' re-expression, a contact \
                 correction or a material update): a smaller time_step shows whether it \
                 converges away"
                    .to_string()
            };
            w.push(format!(
                "the energy account does not close: {:.1}% of the input E(0) + |external work| \
                 left the energy the time scheme conserves without being booked as dissipated \
                 (scheme_energy_drift; warning above {:.0}%); {cause}",
                -100.0 * self.scheme_account,
                100.0 * ENERGY_LOSS_WARNING
            ));
        }
        if let Some((step, time)) = self.first_cut {
            // A step whose attempt ran out of iterations may only need more of them: the
            // bundled block stack's cut step converges at full size in 112 iterations, and a
            // smaller time_step does not spare it its cuts (2026-11-30).
            let advice = match self.cut_steps_out_of_iterations {
                0 => "a smaller time_step avoids the cuts".to_string(),
                n => format!(
                    "{n} of them spent max_iterations = {} at full size: a larger \
                     simulation.max_iterations, or a smaller time_step, avoids those cuts",
                    self.max_iterations
                ),
            };
            w.push(format!(
                "{} step(s) did not converge at full size and were cut ({} cut(s) in all), the \
                 first at step {step} (t = {time:.6e} s); {advice}",
                self.cut_steps, self.cuts
            ));
        }
        if let Some((step, time)) = self.first_cycle {
            w.push(format!(
                "implicit_projection's contact set cycled in {} step(s), the first at step \
                 {step} (t = {time:.6e} s), with {} point(s) held at most in one step: points \
                 that kept switching between open and closed were held as they were until the \
                 step ended and some ended against the law (a point released twice stays \
                 closed, pulling on its body if need be; one held open may end inside), or the \
                 step was cut when none could be held, so the contact forces of those steps are \
                 approximate; a smaller time_step resolves the contact, and the \
                 soft_way and augmented_lagrangian methods have no active set",
                self.cycled_steps, self.most_held
            ));
        }
        w
    }

    fn advice(&self) -> String {
        if let Some(window) = &self.outside_window {
            return format!(
                "the time scheme is the likely cause: {window}; {} (the defaults, alpha = 3/4 \
                 and beta = 1/4, are inside), or a smaller time_step",
                crate::time::WINDOW_ADVICE
            );
        }
        let advice = match self.method {
            Some(ContactMethod::ExplicitProjection) => {
                "explicit_projection's end-of-step correction puts energy in: use \
                 implicit_projection, or a smaller time_step"
            }
            Some(ContactMethod::SoftWay | ContactMethod::AugmentedLagrangian)
                if self.configuration_gaps =>
            {
                "a penalty too stiff for the time step, or the stored configuration's offset \
                 from the gaps at each impact: use contact.gap_displacement = \"trapezoid\" \
                 (gaps on the displacement the energy is booked on), a smaller time_step or \
                 penalty, or implicit_projection"
            }
            Some(ContactMethod::SoftWay | ContactMethod::AugmentedLagrangian) => {
                "the penalty is too stiff for the time step: use a smaller time_step or a \
                 smaller penalty, or implicit_projection"
            }
            Some(ContactMethod::ImplicitProjection) if self.projection_energy_booked => {
                "implicit_projection's end-of-step correction can put energy in where it moves \
                 a compressed contact patch: use contact.projection_energy = \"bounded\" (it \
                 then gives back at most what the contacts dissipated), or a smaller time_step"
            }
            _ => "use a smaller time_step",
        };
        advice.into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn energies(kinetic: f64, external_work: f64, dissipated: f64) -> Energies {
        Energies {
            kinetic,
            internal: 0.0,
            contact: 0.0,
            external_work,
            dissipated,
        }
    }

    fn report(step: usize, held_contacts: usize, contact_cycles: usize) -> StepReport {
        StepReport {
            step,
            time: 1e-3 * step as f64,
            time_step: 1e-3,
            iterations: 1,
            residual: 0.0,
            energies: energies(0.0, 0.0, 0.0),
            max_penetration: 0.0,
            active_contacts: 0,
            reactions: Vec::new(),
            contact_forces: Vec::new(),
            contacts: Vec::new(),
            cuts: 0,
            cuts_out_of_iterations: 0,
            globalized: false,
            held_contacts,
            held_tension: 0.0,
            compression: 0.0,
            held_open_depth: 0.0,
            contact_cycles,
            factorisations: 0,
        }
    }

    /// A cycle's held points that pull with more than half the compression stop the run, with
    /// the step, the forces and what to change; less is a warning only.
    #[test]
    fn held_points_pulling_harder_than_half_the_compression_stop_the_run() {
        let mut r = report(7, 2, 1);
        (r.held_tension, r.compression) = (1.5, 234.0);
        held_tension_check(&r, 0.0).unwrap();
        (r.held_tension, r.compression) = (120.0, 200.0);
        assert_eq!(
            held_tension_check(&r, 150.0).unwrap_err().to_string(),
            "contact set cycling at step 7 (t = 7.000000e-3 s): 2 point(s) held closed until \
             the step's end pull with 1.200e2 N against 2.000e2 N of compression at the other \
             contact points (at most 1.500e2 N in a step of the run so far; the run stops above \
             50% of the larger); use a smaller time_step, or the soft way (contact.method = \
             \"soft_way\"), whose contact set does not cycle"
        );
        // Nothing held, nothing pressed: no contact answer to doubt.
        held_tension_check(&report(8, 0, 0), 0.0).unwrap();
    }

    /// A light touch whose held points pull a little while nothing else presses (the folding
    /// strip's first fold contact under Tresca friction) is measured against what the run's
    /// contacts carried before; the monitor keeps that scale from step to step.
    #[test]
    fn held_points_of_a_light_touch_are_measured_against_the_run() {
        let mut r = report(305, 2, 1);
        (r.held_tension, r.compression) = (0.24, 0.0);
        held_tension_check(&r, 7.6).unwrap();
        assert!(held_tension_check(&r, 0.0).is_err());
        assert!(held_tension_check(&r, 0.4).is_err());
    }

    /// Steps whose contact set cycled make one warning, with the first step, the count and
    /// the most points held; the news is given once.
    #[test]
    fn contact_set_cycles_make_one_warning() {
        let mut monitor = RunMonitor {
            e0: 1.0,
            method: Some(ContactMethod::ImplicitProjection),
            penetration_tolerance: 1.0,
            ..RunMonitor::default()
        };
        let mut news = Vec::new();
        monitor.note_contacts(&report(1, 0, 0), &mut news);
        assert!(monitor.warnings().is_empty() && news.is_empty());
        let pulling = StepReport {
            held_tension: 0.5,
            ..report(2, 3, 1)
        };
        monitor.note_contacts(&pulling, &mut news);
        monitor.note_contacts(&report(3, 0, 0), &mut news);
        let inside = StepReport {
            held_open_depth: 1e-6,
            ..report(4, 5, 2)
        };
        monitor.note_contacts(&inside, &mut news);
        monitor.note_contacts(&report(5, 0, 1), &mut news);
        assert_eq!(news, ["contact set cycled at step 2 (t = 2.000000e-3 s)"]);
        assert_eq!(
            monitor.warnings(),
            [
                "implicit_projection's contact set cycled in 3 step(s), the first at step 2 (t = \
                 2.000000e-3 s), with 5 point(s) held at most in one step: points that kept \
                 switching between open and closed were held as they were until the step ended \
                 and some ended against the law (a point released twice stays closed, pulling \
                 on its body if need be; one held open may end inside), or the step was cut \
                 when none could be held, so the contact forces of those steps are \
                 approximate; a smaller time_step resolves the contact, and the soft_way and \
                 augmented_lagrangian methods have no active set"
            ]
        );
    }

    /// A cycle whose held points all end on the law's side (closed ones pressing, open ones
    /// clear, or inside by no more than the gap tolerance) left the law's answer: no warning,
    /// no news. One against it (a held point in tension, one held open deeper) is counted.
    #[test]
    fn cycles_that_end_on_the_law_make_no_warning() {
        let mut monitor = RunMonitor {
            e0: 1.0,
            method: Some(ContactMethod::ImplicitProjection),
            penetration_tolerance: 1.0,
            gap_tolerance: 1e-9,
            ..RunMonitor::default()
        };
        let mut news = Vec::new();
        monitor.note_contacts(&report(10, 8, 1), &mut news);
        let within = StepReport {
            held_open_depth: 5e-10,
            ..report(40, 10, 1)
        };
        monitor.note_contacts(&within, &mut news);
        assert!(monitor.warnings().is_empty() && news.is_empty());
        assert!(cycle_left_the_law(
            &StepReport {
                held_tension: 1e-3,
                ..report(41, 1, 1)
            },
            1e-9
        ));
        assert!(cycle_left_the_law(
            &StepReport {
                held_open_depth: 2e-9,
                ..report(42, 1, 1)
            },
            1e-9
        ));
        // A cycle with nothing held: the attempt was cut, its answer is not the law's.
        assert!(cycle_left_the_law(&report(43, 0, 1), 1e-9));
    }

    #[test]
    fn energy_created_against_the_input() {
        // A closed account: E + D = E(0) + W.
        assert_eq!(energy_created(10.0, &energies(8.0, 0.0, 2.0)), 0.0);
        assert_eq!(energy_created(10.0, &energies(15.0, 5.0, 0.0)), 0.0);
        // 10 % more than went in.
        assert!((energy_created(10.0, &energies(11.0, 0.0, 0.0)) - 0.1).abs() < 1e-12);
        // Energy booked as negative dissipation is not subtracted: it was created.
        assert!((energy_created(10.0, &energies(30.0, 0.0, -20.0)) - 2.0).abs() < 1e-12);
        // Nothing to compare with.
        assert_eq!(energy_created(0.0, &energies(1e-30, 0.0, 0.0)), 0.0);
    }

    /// Energy that left the scheme's account unbooked warns beyond 5 % of the input, naming
    /// the scheme's damping where alpha + beta != 1; a loss below that, or energy created
    /// (the energy-created warning's), does not.
    #[test]
    fn an_unbooked_loss_warns_with_its_cause() {
        let monitor = |account: f64, scheme: (f64, f64)| RunMonitor {
            scheme_account: account,
            scheme: Some(scheme),
            ..RunMonitor::default()
        };
        for quiet in [-0.04, 0.2] {
            assert!(
                monitor(quiet, (0.75, 0.25)).warnings().is_empty(),
                "{quiet}"
            );
            assert!((monitor(quiet, (0.75, 0.25)).scheme_energy_drift() - quiet.abs()) < 1e-15);
        }
        let conserving = monitor(-0.097, (0.75, 0.25)).warnings();
        assert_eq!(conserving.len(), 1);
        assert!(
            conserving[0].starts_with("the energy account does not close: 9.7% of the input")
                && conserving[0].contains("a term whose energy is not booked"),
            "{conserving:?}"
        );
        let hypoelastic = RunMonitor {
            hypoelastic: true,
            ..monitor(-0.097, (0.75, 0.25))
        }
        .warnings();
        assert!(
            hypoelastic[0].contains("the hypoelastic law is the likely cause"),
            "{hypoelastic:?}"
        );
        let damped = monitor(-0.488, (0.8, 0.3)).warnings();
        assert!(
            damped[0].contains("48.8%")
                && damped[0].contains("the time scheme damps numerically (alpha = 0.8, beta = 0.3"),
            "{damped:?}"
        );
    }
}
