//! The time series: energies and probes every step, solver scalars every iteration, and
//! their names.

use re_sdk_types::archetypes::{Scalars, SeriesLines};

use super::{RerunRecorder, ENERGY_KINDS};
use crate::dim::{Dim, SpatialDim};
use crate::recording::IterationInfo;
use crate::simulation::{BodyId, Simulation};

/// A probe: a node whose displacement and velocity are logged every step.
pub(super) struct ProbeDraw {
    pub(super) name: String,
    pub(super) body: BodyId,
    pub(super) node: usize,
}

impl<const D: usize> RerunRecorder<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// Names the lines of every series (static).
    pub(super) fn log_series_styles(&mut self) {
        let mut styles: Vec<(String, Vec<String>)> = ENERGY_KINDS
            .iter()
            .map(|k| (format!("energy/{k}"), vec![k.to_string()]))
            .collect();
        for s in [
            "residual_norm",
            "relative_residual",
            "increment_norm",
            "active_set_size",
            "candidates",
        ] {
            styles.push((format!("solver/{s}"), vec![s.to_string()]));
        }
        let axes = ["x", "y", "z"];
        for p in &self.probes {
            let mut names: Vec<String> = axes[..D].iter().map(|a| format!("u{a}")).collect();
            names.extend(axes[..D].iter().map(|a| format!("v{a}")));
            styles.push((format!("probes/{}", p.name), names));
        }
        for (path, names) in styles {
            let r = self
                .rec
                .log_static(path, &SeriesLines::new().with_names(names));
            self.check(r);
        }
    }

    /// The energies and the probes (every step, and the initial state).
    pub(super) fn log_step_scalars(&mut self, sim: &Simulation<D>) {
        let e = sim.energies();
        let values = [
            e.kinetic,
            e.internal,
            e.contact,
            e.external_work,
            e.dissipated,
        ];
        for (kind, value) in ENERGY_KINDS.iter().zip(values) {
            let r = self
                .rec
                .log(format!("energy/{kind}"), &Scalars::single(value));
            self.check(r);
        }
        for p in 0..self.probes.len() {
            let (body, node) = (self.probes[p].body, self.probes[p].node);
            let (Ok(u), Ok(v)) = (sim.displacement(body, node), sim.velocity(body, node)) else {
                continue;
            };
            let values: Vec<f64> = u.iter().chain(v.iter()).copied().collect();
            let path = format!("probes/{}", self.probes[p].name);
            let r = self.rec.log(path, &Scalars::new(values));
            self.check(r);
        }
    }

    /// The solver's scalars of one iteration.
    pub(super) fn log_solver_scalars(&mut self, info: &IterationInfo<'_, D>) {
        let active = info.contacts.iter().filter(|c| c.active).count();
        let scalars = [
            ("solver/residual_norm", info.residual_norm),
            ("solver/relative_residual", info.relative_residual),
            ("solver/increment_norm", info.increment_norm),
            ("solver/active_set_size", active as f64),
            ("solver/candidates", info.candidates as f64),
        ];
        for (path, value) in scalars {
            let r = self.rec.log(path, &Scalars::single(value));
            self.check(r);
        }
    }
}
