//! Coulomb's lagged threshold as a fixed point across the outer passes (implicit projection's
//! return map, and the smooth law under every method): each pass solves with the normal
//! forces of the last as thresholds, `F = T(F)`, until no threshold changes by more than
//! `1e-6` of the largest normal force.
//!
//! The plain iteration converges linearly, as fast as a slipping contact's friction feeds back
//! into the normal forces. [`ThresholdIteration`] mixes each update with the previous ones
//! (Anderson acceleration with up to [`MEMORY`] previous passes, a multisecant method on the
//! fixed point; Walker and Ni, SIAM J. Numer. Anal. 49, 2011). The stopping test is unchanged:
//! it is always on the plain map's own change `|T(F) - F|`.

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};

use super::FrictionLaw;

/// The previous updates the mixing uses.
const MEMORY: usize = 3;

/// One contact's normal force after a converged inner solve, for the threshold fixed point.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ThresholdSample<K> {
    /// The contact (slave, master).
    pub key: K,
    /// The law acting on it.
    pub law: FrictionLaw,
    /// Its normal force (N).
    pub normal_force: f64,
}

/// One update: Coulomb's thresholds in and the normal forces they gave (N).
type Update<K> = (BTreeMap<K, f64>, BTreeMap<K, f64>);

/// The thresholds' fixed point within one step: [`ThresholdIteration::next`] after each
/// converged pass, [`ThresholdIteration::forget`] when the pass changed anything else (the
/// active set, the multipliers: the map itself changed).
#[derive(Debug)]
pub(crate) struct ThresholdIteration<K> {
    /// The last updates, oldest first.
    history: Vec<Update<K>>,
    /// The plain map's change at the last update, relative to the largest normal force (0
    /// when it settled).
    last_change: f64,
}

impl<K> Default for ThresholdIteration<K> {
    fn default() -> Self {
        Self {
            history: Vec::new(),
            last_change: 0.0,
        }
    }
}

impl<K: Ord + Copy> ThresholdIteration<K> {
    /// Drops the previous updates: the next one is plain.
    pub(crate) fn forget(&mut self) {
        self.history.clear();
    }

    /// How far the thresholds were from settling at the last [`next`](Self::next): the plain
    /// map's change relative to the largest normal force (0 once they settled). The inner
    /// solve that follows needs to be no more accurate than a fraction of it.
    pub(crate) fn last_change(&self) -> f64 {
        self.last_change
    }

    /// The next thresholds (normal forces by contact) after a converged inner solve with
    /// `current`, or `None` when they changed by at most `1e-6` of the largest normal force
    /// (the fixed point has settled). Only Coulomb follows the force and is mixed; the other
    /// laws need the contact status only.
    pub(crate) fn next(
        &mut self,
        samples: &[ThresholdSample<K>],
        current: &BTreeMap<K, f64>,
    ) -> Option<BTreeMap<K, f64>> {
        let scale = samples
            .iter()
            .map(|p| p.normal_force.abs())
            .fold(0.0, f64::max);
        let mut change: f64 = 0.0;
        let mut next = BTreeMap::new();
        let mut thresholds = BTreeMap::new();
        let mut forces = BTreeMap::new();
        for p in samples {
            let f = p.normal_force.max(0.0);
            let old = current.get(&p.key).copied().unwrap_or(0.0);
            if matches!(p.law, FrictionLaw::Coulomb { .. }) {
                change = change.max((f - old).abs());
                thresholds.insert(p.key, old);
                forces.insert(p.key, f);
            }
            if f > 0.0 {
                next.insert(p.key, f);
            }
        }
        change = change.max(
            current
                .iter()
                .filter(|(k, _)| !next.contains_key(k))
                .map(|(_, f)| f.abs())
                .fold(0.0, f64::max),
        );
        let scale = scale.max(f64::MIN_POSITIVE);
        if change <= 1e-6 * scale {
            self.history.clear();
            self.last_change = 0.0;
            return None;
        }
        self.last_change = change / scale;
        self.history.push((thresholds, forces));
        if self.history.len() > MEMORY + 1 {
            self.history.remove(0);
        }
        for (key, value) in mixed(&mut self.history).unwrap_or_default() {
            if value > 0.0 {
                next.insert(key, value);
            } else {
                next.remove(&key);
            }
        }
        Some(next)
    }
}

/// Anderson's mixed update from the history `(x_i, g_i)` (thresholds and the forces they
/// gave, changes `f_i = g_i - x_i`, the last one the newest): `g - dG gamma`, with `gamma`
/// minimising the linearised change `|f - dF gamma|` over the differences of consecutive
/// updates. `None` where the newest change is not smaller than the one before (the map does
/// not contract there: the history restarts from the newest update, which is taken plain) or
/// the least-squares problem is singular.
fn mixed<K: Ord + Copy>(history: &mut Vec<Update<K>>) -> Option<Vec<(K, f64)>> {
    let n = history.len();
    if n < 2 {
        return None;
    }
    let at = |m: &BTreeMap<K, f64>, k: &K| m.get(k).copied().unwrap_or(0.0);
    let mut keys: Vec<K> = history
        .iter()
        .flat_map(|(x, _)| x.keys().copied())
        .collect();
    keys.sort();
    keys.dedup();
    let change = |(x, g): &Update<K>| {
        DVector::from_iterator(keys.len(), keys.iter().map(|k| at(g, k) - at(x, k)))
    };
    let forces =
        |(_, g): &Update<K>| DVector::from_iterator(keys.len(), keys.iter().map(|k| at(g, k)));
    let f = change(&history[n - 1]);
    if f.norm() >= change(&history[n - 2]).norm() {
        history.drain(..n - 1);
        return None;
    }
    let mut d_f = DMatrix::zeros(keys.len(), n - 1);
    let mut d_g = DMatrix::zeros(keys.len(), n - 1);
    for j in 0..n - 1 {
        d_f.set_column(j, &(change(&history[j + 1]) - change(&history[j])));
        d_g.set_column(j, &(forces(&history[j + 1]) - forces(&history[j])));
    }
    let gamma = d_f.svd(true, true).solve(&f, 1e-12 * f.norm()).ok()?;
    if !gamma.iter().all(|g| g.is_finite()) {
        return None;
    }
    let x = forces(&history[n - 1]) - d_g * gamma;
    Some(keys.into_iter().zip(x.iter().copied()).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    const COULOMB: FrictionLaw = FrictionLaw::Coulomb {
        coefficient: 0.5,
        regularization: 1e-6,
    };

    /// Passes until the fixed point settles, with the map `T(F) = A F + b` (N) standing for the
    /// inner solve, and where it settled.
    fn passes(
        a: [[f64; 3]; 3],
        b: [f64; 3],
        law: FrictionLaw,
        accelerated: bool,
    ) -> (usize, BTreeMap<usize, f64>) {
        let mut iteration = ThresholdIteration::default();
        let mut current = BTreeMap::new();
        for pass in 1..200 {
            let x: Vec<f64> = (0..3)
                .map(|k| current.get(&k).copied().unwrap_or(0.0))
                .collect();
            let samples: Vec<ThresholdSample<usize>> = (0..3)
                .map(|k| ThresholdSample {
                    key: k,
                    law,
                    normal_force: b[k] + (0..3).map(|j| a[k][j] * x[j]).sum::<f64>(),
                })
                .collect();
            if !accelerated {
                iteration.forget();
            }
            match iteration.next(&samples, &current) {
                Some(next) => current = next,
                None => return (pass, current),
            }
        }
        panic!("the fixed point did not settle");
    }

    /// The exact fixed point of `F = A F + b`, from `(I - A) F = b`.
    fn fixed_point(a: [[f64; 3]; 3], b: [f64; 3]) -> [f64; 3] {
        let m = nalgebra::Matrix3::from_fn(|i, j| f64::from(u8::from(i == j)) - a[i][j]);
        let f = m.lu().solve(&nalgebra::Vector3::from(b)).expect("regular");
        [f[0], f[1], f[2]]
    }

    /// Friction feeding back into the normal forces, halving the change per pass as on a block
    /// sliding onto the floor: the mixed updates settle in fewer passes, on the same fixed
    /// point to the stopping test's tolerance.
    #[test]
    fn mixing_settles_a_contracting_threshold_map_in_fewer_passes() {
        let a = [[0.45, 0.05, 0.0], [0.05, -0.3, 0.04], [0.0, 0.08, 0.2]];
        let b = [10.0, 6.0, 3.0];
        let exact = fixed_point(a, b);
        let (plain, at_plain) = passes(a, b, COULOMB, false);
        let (mixed, at_mixed) = passes(a, b, COULOMB, true);
        assert!(2 * mixed < plain, "{mixed} passes against {plain}");
        for (k, f) in exact.iter().enumerate() {
            for settled in [&at_plain, &at_mixed] {
                assert!(
                    (settled[&k] - f).abs() <= 4e-5,
                    "{k}: {settled:?} {exact:?}"
                );
            }
        }
    }

    /// A map that does not contract (a threshold swinging with a growing change) gets no
    /// mixing: every update is the plain one.
    #[test]
    fn a_growing_change_takes_the_plain_update() {
        let mut iteration = ThresholdIteration::default();
        let sample = |f: f64| {
            [ThresholdSample {
                key: 0usize,
                law: COULOMB,
                normal_force: f,
            }]
        };
        let first = iteration
            .next(&sample(1.0), &BTreeMap::new())
            .expect("changed");
        assert_eq!(first[&0], 1.0);
        assert_eq!(iteration.last_change(), 1.0);
        // From 1 N to 3 N: the change grew from 1 N to 2 N, two thirds of the largest force.
        let second = iteration.next(&sample(3.0), &first).expect("changed");
        assert_eq!(second[&0], 3.0);
        assert!((iteration.last_change() - 2.0 / 3.0).abs() < 1e-15);
        // Settled: nothing left to tell the inner solve.
        assert!(iteration.next(&sample(3.0), &second).is_none());
        assert_eq!(iteration.last_change(), 0.0);
    }

    /// Tresca's threshold needs only the status: its forces do not keep the fixed point
    /// going.
    #[test]
    fn only_coulomb_thresholds_keep_the_fixed_point_going() {
        let tresca = FrictionLaw::Tresca {
            limit: 100.0,
            regularization: 1e-6,
        };
        let (passes_tresca, _) = passes([[0.2; 3]; 3], [1.0, 2.0, 3.0], tresca, true);
        assert_eq!(passes_tresca, 1);
    }
}
