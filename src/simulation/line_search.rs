//! Newton's line search on the step's energy. With the contact method's outer variables and
//! the friction thresholds held (one pass), the step's residual is the gradient of a potential
//! in the end velocities: the inertia and strain energies, the penalty or held-velocity
//! energy of the normal law, and the return map's Moreau envelope (convex for a fixed slip
//! limit). Along a Newton direction `d` the potential's slope at length `s` is
//! `R(v + s d) . d`, negative at 0 for a positive definite iteration matrix; the search looks
//! for the length where it turns (a bracketed secant) and accepts one where the slope is
//! small, or still descending (Crisfield's line search; Wriggers, *Nonlinear Finite Element
//! Methods*, 2008, section 5.1.2). A residual-norm test rejects the steps that cross a
//! stick/slip kink: with it, a 3D block whose contacts flip between stick and slip took
//! dozens of iterations that each backtracked to a sixteenth of the step, and stalled.
//!
//! Also the merit the plain Newton's halving compares ([`merit`]).

use std::collections::BTreeMap;

use super::contact_terms::{ContactTerms, HeldRow};
use crate::contact::ContactKey;

/// The slope, relative to the slope at 0, below which a length is accepted.
const SLOPE_RATIO: f64 = 0.5;
/// Trial lengths after the full step.
const MAX_TRIALS: usize = 6;

/// A search along one Newton direction.
pub(super) struct LineSearch {
    /// The iterate the direction starts from.
    base: Vec<f64>,
    /// The full Newton increment.
    direction: Vec<f64>,
    /// The slope at 0 (negative).
    slope0: f64,
    /// The longest length known to descend, with its slope.
    lower: (f64, f64),
    /// The shortest length known to ascend, with its slope.
    upper: Option<(f64, f64)>,
    /// The length being tried.
    length: f64,
    /// Lengths tried.
    trials: usize,
    /// The search ran out and went back to its longest descending length: accept it.
    settled: bool,
}

/// What to do with the length just tried.
#[derive(Debug, PartialEq)]
pub(super) enum Verdict {
    /// Keep the iterate at the length tried.
    Accept,
    /// Try the iterate at this length.
    Retry(f64),
}

/// The dot product over the unknowns that are not prescribed.
pub(super) fn free_dot(a: &[f64], b: &[f64], prescribed: &[Option<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .zip(prescribed)
        .filter(|(_, p)| p.is_none())
        .map(|((x, y), _)| x * y)
        .sum()
}

/// Newton's merit, the residual norm its backtracking compares (N): the free residual with
/// each held constraint's force taken at its linearised prediction, together with the
/// prediction's misses in force units of the slave's diagonal. This is the residual of
/// Newton on the pair (velocities, forces), whose direction is the penalised system's
/// (eliminate the force change and the two coincide): the penalised residual alone counts a
/// held constraint's curvature `penalty` times (implicit projection's 1e4 diagonals), so a
/// step along a turning master facet raised it 500-fold where its pair predicted well (the
/// bundled block stack's cut step), and Newton backtracked to a sixteenth. Equal to `norm`
/// where every held constraint is linear in the velocities (flat, resting obstacles).
pub(super) fn merit<const D: usize>(
    norm: f64,
    residual: &[f64],
    terms: &ContactTerms<D>,
    prescribed: &[Option<f64>],
) -> f64 {
    if terms.merit_excess.is_empty() && terms.merit_constraints == 0.0 {
        return norm;
    }
    let excess = |i: usize| terms.merit_excess.get(i).copied().unwrap_or(0.0);
    let free2: f64 = residual
        .iter()
        .enumerate()
        .filter(|&(i, _)| prescribed[i].is_none())
        .map(|(i, r)| (r + excess(i)).powi(2))
        .sum();
    (free2 + terms.merit_constraints).sqrt()
}

/// The held constraints' predictions that [`merit`] measures against: each one's value at the
/// last iterate (its own prediction, or its value where it had none) and after the whole of
/// the last increment (Newton's linearisation there). Between the two the prediction is
/// linear in the share of the increment taken, as Newton's forces are.
#[derive(Default)]
pub(super) struct HeldPredictions {
    linear: BTreeMap<ContactKey, (f64, f64)>,
    current: BTreeMap<ContactKey, f64>,
    length: f64,
}

impl HeldPredictions {
    /// The predictions at the share of the last increment being tried, for the terms.
    pub(super) fn update(&mut self) -> &BTreeMap<ContactKey, f64> {
        let length = self.length;
        self.current = self
            .linear
            .iter()
            .map(|(&key, &(from, to))| (key, from + length * (to - from)))
            .collect();
        &self.current
    }

    /// The share of the last increment taken (a line search's length).
    pub(super) fn set_length(&mut self, length: f64) {
        self.length = length;
    }

    /// The last increment was halved.
    pub(super) fn halve(&mut self) {
        self.length *= 0.5;
    }

    /// A new pass: no increment to predict along.
    pub(super) fn clear(&mut self) {
        self.linear.clear();
    }

    /// Newton takes `increment` from the iterate whose held constraints are `held`.
    pub(super) fn take(&mut self, held: &[HeldRow], increment: &[f64], prescribed: &[Option<f64>]) {
        self.linear = held
            .iter()
            .map(|(key, value, gradient)| {
                let change = gradient
                    .iter()
                    .filter(|&&(i, _)| prescribed[i].is_none())
                    .map(|&(i, g)| g * increment[i])
                    .sum::<f64>();
                let from = self.current.get(key).copied().unwrap_or(*value);
                (*key, (from, value + change))
            })
            .collect();
        self.length = 1.0;
    }
}

impl LineSearch {
    /// A search from `base` along `direction`, whose slope at 0 is `slope0`; `None` when the
    /// direction does not descend (a non-symmetric or indefinite tangent: the caller's
    /// residual-norm backtracking takes over).
    pub(super) fn new(base: Vec<f64>, direction: Vec<f64>, slope0: f64) -> Option<Self> {
        (slope0 < 0.0 && slope0.is_finite()).then_some(Self {
            base,
            direction,
            slope0,
            lower: (0.0, slope0),
            upper: None,
            length: 1.0,
            trials: 0,
            settled: false,
        })
    }

    /// The full direction.
    pub(super) fn direction(&self) -> &[f64] {
        &self.direction
    }

    /// The length being tried.
    pub(super) fn length(&self) -> f64 {
        self.length
    }

    /// The iterate at `length` (prescribed unknowns are untouched: the direction is zero there).
    pub(super) fn iterate(&self, length: f64) -> Vec<f64> {
        self.base
            .iter()
            .zip(&self.direction)
            .map(|(b, d)| b + length * d)
            .collect()
    }

    /// The length tried turned a cell inside out: it ascends as far as the search is concerned.
    pub(super) fn halved(&mut self) {
        self.upper = Some((self.length, f64::INFINITY));
        self.length = 0.5 * (self.lower.0 + self.length);
    }

    /// Judges the slope `R(v + s d) . d` at the length being tried.
    pub(super) fn judge(&mut self, slope: f64) -> Verdict {
        if self.settled {
            return Verdict::Accept;
        }
        self.trials += 1;
        let slope = if slope.is_nan() { f64::INFINITY } else { slope };
        if slope.abs() <= SLOPE_RATIO * self.slope0.abs() || (slope < 0.0 && self.upper.is_none()) {
            return Verdict::Accept;
        }
        if slope < 0.0 {
            self.lower = (self.length, slope);
        } else {
            self.upper = Some((self.length, slope));
        }
        if self.trials >= MAX_TRIALS {
            if self.lower.0 == 0.0 {
                // Nothing known to descend: the shortest length tried, as plain backtracking.
                return Verdict::Accept;
            }
            self.settled = true;
            self.length = self.lower.0;
            return Verdict::Retry(self.length);
        }
        let ((s0, g0), (s1, g1)) = (self.lower, self.upper.expect("an ascending length"));
        // Where the slope's secant between the bracket's ends crosses zero, kept inside it.
        let width = s1 - s0;
        let root = if g1.is_finite() {
            s0 - g0 * width / (g1 - g0)
        } else {
            s0 + 0.5 * width
        };
        self.length = root.clamp(s0 + 0.1 * width, s0 + 0.9 * width);
        Verdict::Retry(self.length)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs the search on a 1-D slope function; returns the accepted length and the trials.
    fn search(slope: impl Fn(f64) -> f64) -> (f64, usize) {
        let mut ls = LineSearch::new(vec![0.0], vec![1.0], slope(0.0)).unwrap();
        let mut evaluations = 1;
        loop {
            let s = ls.length();
            match ls.judge(slope(s)) {
                Verdict::Accept => return (s, evaluations),
                Verdict::Retry(_) => evaluations += 1,
            }
        }
    }

    /// A quadratic energy's slope is linear: one secant step lands on its minimum.
    #[test]
    fn a_quadratic_is_minimised_in_one_secant_step() {
        let (s, n) = search(|s| 4.0 * (s - 0.3));
        assert!((s - 0.3).abs() < 1e-12 && n == 2, "{s} after {n}");
        // A full step that still descends is accepted as it is.
        assert_eq!(search(|s| s - 2.0), (1.0, 1));
    }

    /// A kinked slope (stick to slip: a stiff branch past s = 0.2) is bracketed and the
    /// accepted length has a small slope.
    #[test]
    fn a_kinked_slope_is_bracketed() {
        let slope = |s: f64| if s < 0.2 { s - 0.2 } else { 1e4 * (s - 0.2) };
        let (s, _) = search(slope);
        assert!(
            slope(s).abs() <= 0.5 * 0.2,
            "length {s}, slope {}",
            slope(s)
        );
    }

    /// Without held constraints the merit is the residual norm; with them, the penalty's
    /// share of the residual beyond the prediction is taken out and the miss added in the
    /// diagonal's units; prescribed unknowns count in neither.
    #[test]
    fn the_merit_measures_held_constraints_in_their_own_units() {
        let residual = [3.0, 400.0, 7.0];
        let prescribed = [None, None, Some(0.0)];
        let mut terms = ContactTerms::<2>::default();
        assert_eq!(merit(5.0, &residual, &terms, &prescribed), 5.0);
        // A held force 396 N above its prediction on the second unknown, a miss of 4e-4 m/s
        // at a diagonal of 1e4 N s/m (4 N).
        terms.merit_excess = vec![0.0, -396.0, 0.0];
        terms.merit_constraints = 16.0;
        let m = merit(400.0, &residual, &terms, &prescribed);
        assert!((m - (9.0f64 + 16.0 + 16.0).sqrt()).abs() < 1e-12, "{m}");
    }

    /// Directions that do not descend are left to the caller.
    #[test]
    fn ascending_directions_are_refused() {
        assert!(LineSearch::new(vec![0.0], vec![1.0], 1.0).is_none());
        assert!(LineSearch::new(vec![0.0], vec![1.0], f64::NAN).is_none());
    }
}
