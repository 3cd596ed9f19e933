//! Bodies and obstacles added and removed between steps.
//!
//! The simulation is rebuilt from the edited model (validation, matrices, surfaces: the cost
//! of building it, once per edit), and the state is carried over entity by entity: the nodes,
//! material history and contact memory of the bodies that stay, the poses of the obstacles that
//! stay; new entities start from their initial state. The contact factorisations that
//! precondition the solves are dropped (the pattern changed). Handles of the entities that stay
//! are unchanged; the removed entity's handle becomes stale.

use std::ops::Range;

use super::{Body, BodyId, ObstacleId, Simulation, State};
use crate::contact::{MasterId, Obstacle};
use crate::dim::{Dim, SpatialDim};
use crate::error::{Error, Result};

/// Where each old entity went in the edited model (`None`: removed).
struct Remap {
    bodies: Vec<Option<usize>>,
    obstacles: Vec<Option<usize>>,
}

/// `count` entities that all stay where they are.
fn kept(count: usize) -> Vec<Option<usize>> {
    (0..count).map(Some).collect()
}

/// `count` entities without the one at `removed`: the later ones move down by one.
fn without(count: usize, removed: usize) -> Vec<Option<usize>> {
    (0..count)
        .map(|i| match i.cmp(&removed) {
            std::cmp::Ordering::Less => Some(i),
            std::cmp::Ordering::Equal => None,
            std::cmp::Ordering::Greater => Some(i - 1),
        })
        .collect()
}

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// Adds a body between steps; it starts from its initial velocity, undeformed. Its
    /// energy at entry is added to the energy the account starts from. Errors as
    /// [`Simulation::builder`]'s `build` for an invalid body (a duplicate name, a bad mesh or
    /// material), leaving the simulation as it was.
    pub fn add_body(&mut self, body: Body<D>) -> Result<BodyId> {
        let mut model = self.model.clone();
        model.bodies.push(body);
        let remap = Remap {
            bodies: kept(self.model.bodies.len()),
            obstacles: kept(self.model.obstacles.len()),
        };
        let position = self.model.bodies.len();
        self.rebuild(model, &remap)?;
        Ok(self.insert_body_slot(position))
    }

    /// Removes a body between steps and returns it (as it was given, undeformed). Its
    /// current kinetic and internal energy leave the account with it. The last body cannot be
    /// removed.
    pub fn remove_body(&mut self, body: BodyId) -> Result<Body<D>> {
        let b = self.body_index(body)?;
        if self.model.bodies.len() == 1 {
            return Err(Error::InvalidHandle(format!(
                "body `{}` is the simulation's only body: a simulation keeps at least one",
                self.model.bodies[b].name
            )));
        }
        let mut model = self.model.clone();
        let removed = model.bodies.remove(b);
        let remap = Remap {
            bodies: without(self.model.bodies.len(), b),
            obstacles: kept(self.model.obstacles.len()),
        };
        self.rebuild(model, &remap)?;
        self.remove_body_slot(b);
        Ok(removed)
    }

    /// Adds a rigid obstacle between steps, at its initial pose and velocity.
    pub fn add_obstacle(&mut self, obstacle: Obstacle<D>) -> Result<ObstacleId> {
        let mut model = self.model.clone();
        model.obstacles.push(obstacle);
        let remap = Remap {
            bodies: kept(self.model.bodies.len()),
            obstacles: kept(self.model.obstacles.len()),
        };
        let position = self.model.obstacles.len();
        self.rebuild(model, &remap)?;
        Ok(self.insert_obstacle_slot(position))
    }

    /// Removes an obstacle between steps and returns it (at its pose at t = 0).
    pub fn remove_obstacle(&mut self, obstacle: ObstacleId) -> Result<Obstacle<D>> {
        let k = self.obstacle_index(obstacle)?;
        let mut model = self.model.clone();
        let removed = model.obstacles.remove(k);
        let remap = Remap {
            bodies: kept(self.model.bodies.len()),
            obstacles: without(self.model.obstacles.len(), k),
        };
        self.rebuild(model, &remap)?;
        self.remove_obstacle_slot(k);
        Ok(removed)
    }

    /// Changes the factor on gravity of one body from the next step on (1: the settings'
    /// gravity; 0: weightless).
    pub fn set_gravity_scale(&mut self, body: BodyId, scale: f64) -> Result<()> {
        let b = self.body_index(body)?;
        if !scale.is_finite() {
            return Err(super::invalid(
                &format!("body `{}` gravity_scale", self.model.bodies[b].name),
                scale,
                "a finite factor",
            ));
        }
        self.model.bodies[b].gravity_scale = scale;
        self.gravity_force = super::gravity_forces(
            &self.model.settings,
            &self.model.bodies,
            &self.node_offsets,
            &self.matrices.mass,
        );
        Ok(())
    }

    /// Each body's range in the material history.
    fn history_ranges(&self) -> Vec<Range<usize>> {
        let mut ranges = vec![0..0; self.model.bodies.len()];
        let mut offset = 0;
        for seg in &self.table.segments {
            let per = self.integration[seg.body].history_per_cell(seg.kind);
            let len = seg.cells.len() * per;
            let r = &mut ranges[seg.body];
            if r.start == r.end {
                *r = offset..offset + len;
            } else {
                r.end = offset + len;
            }
            offset += len;
        }
        ranges
    }

    /// Each body's range of global facets in the contact surface (empty without detection).
    fn facet_ranges(&self) -> Vec<Range<usize>> {
        let mut ranges = vec![0..0; self.model.bodies.len()];
        if let Some(detector) = &self.caches.detector {
            for (f, &b) in detector.surface().facet_body().iter().enumerate() {
                let r = &mut ranges[b];
                if r.start == r.end {
                    *r = f..f + 1;
                } else {
                    r.end = f + 1;
                }
            }
        }
        ranges
    }

    /// Replaces the model by `model` (validated and built afresh) and carries the state over
    /// through `remap`.
    fn rebuild(&mut self, model: super::Model<D>, remap: &Remap) -> Result<()> {
        let mut fresh = Simulation::from_model(model)?;
        let old = &self.state;
        let before = self.energies();
        let mut state: State = fresh.state.clone();

        // Nodes, history and facets of the bodies that stay.
        let (old_history, new_history) = (self.history_ranges(), fresh.history_ranges());
        let (old_facets, new_facets) = (self.facet_ranges(), fresh.facet_ranges());
        let mut node_map = vec![None; self.reference.len()];
        let mut facet_map = vec![None; old_facets.iter().map(|r| r.end).max().unwrap_or(0)];
        for (b, target) in remap.bodies.iter().enumerate() {
            let Some(nb) = *target else { continue };
            let (from, to) = (self.nodes_of(b), fresh.nodes_of(nb));
            for (i, j) in from.clone().zip(to) {
                node_map[i] = Some(j);
            }
            let (from, to) = (from.start * D..from.end * D, fresh.node_offsets[nb] * D);
            for field in [
                (&old.displacement, &mut state.displacement),
                (&old.velocity, &mut state.velocity),
                (&old.gap_displacement, &mut state.gap_displacement),
                (&old.loads, &mut state.loads),
            ] {
                if field.0.len() == self.reference.len() * D {
                    field.1[to..to + from.len()].copy_from_slice(&field.0[from.clone()]);
                }
            }
            let (h0, h1) = (old_history[b].clone(), new_history[nb].clone());
            if h0.len() == h1.len() && h0.end <= old.material_history.len() {
                state.material_history[h1].copy_from_slice(&old.material_history[h0]);
            }
            for (i, j) in old_facets[b].clone().zip(new_facets[nb].clone()) {
                facet_map[i] = Some(j);
            }
        }
        // Poses of the obstacles that stay.
        let (a, r) = (<Dim<D>>::ANGULAR, <Dim<D>>::ROTATION);
        for (k, target) in remap.obstacles.iter().enumerate() {
            let Some(nk) = *target else { continue };
            for (width, from, to) in [
                (
                    D,
                    &old.obstacle_translations,
                    &mut state.obstacle_translations,
                ),
                (D, &old.obstacle_velocities, &mut state.obstacle_velocities),
                (r, &old.obstacle_rotations, &mut state.obstacle_rotations),
                (
                    a,
                    &old.obstacle_angular_velocities,
                    &mut state.obstacle_angular_velocities,
                ),
            ] {
                to[nk * width..nk * width + width]
                    .copy_from_slice(&from[k * width..k * width + width]);
            }
        }
        // Contact memory keyed by (slave node, master).
        let key = |(n, m): (usize, MasterId)| -> Option<(usize, MasterId)> {
            let n = node_map.get(n).copied().flatten()?;
            let m = match m {
                MasterId::Body(b) => MasterId::Body(remap.bodies.get(b).copied().flatten()?),
                MasterId::Obstacle(k) => {
                    MasterId::Obstacle(remap.obstacles.get(k).copied().flatten()?)
                }
            };
            Some((n, m))
        };
        state.multipliers = old
            .multipliers
            .iter()
            .filter_map(|&(n, m, l)| key((n, m)).map(|(n, m)| (n, m, l)))
            .collect();
        state.friction_normals = old
            .friction_normals
            .iter()
            .filter_map(|&(n, m, f)| key((n, m)).map(|(n, m)| (n, m, f)))
            .collect();
        state.active_contacts = old.active_contacts.iter().filter_map(|&k| key(k)).collect();
        state.friction_anchors = old
            .friction_anchors
            .iter()
            .filter_map(|(n, m, s)| key((*n, *m)).map(|(n, m)| (n, m, s.clone())))
            .collect();
        state.contact_memory.detection = old
            .contact_memory
            .detection
            .iter()
            .filter_map(|&(k, feature)| {
                let new_key = key(k)?;
                let feature = match k.1 {
                    MasterId::Body(_) => facet_map.get(feature).copied().flatten()?,
                    MasterId::Obstacle(_) => feature,
                };
                Some((new_key, feature))
            })
            .collect();
        state.contact_memory.detection.sort_unstable();
        state.contact_memory.factors.clear();
        state.contact_memory.next_factor = old.contact_memory.next_factor;
        state.contact_memory.double_precision_only = old.contact_memory.double_precision_only;

        state.step = old.step;
        state.time = old.time;
        state.external_work = old.external_work;
        state.dissipated_energy = old.dissipated_energy;
        state.contact_loss = old.contact_loss;
        state.contact_energy = old.contact_energy;
        state.body_slots = old.body_slots.clone();
        state.obstacle_slots = old.obstacle_slots.clone();
        // The account: energy that enters with a new body, or leaves with a removed one.
        state.reference_energy = old.reference_energy;
        fresh.state = state;
        let after = fresh.energies();
        fresh.state.reference_energy +=
            (after.kinetic + after.internal) - (before.kinetic + before.internal);
        fresh.warnings = self.warnings.clone();
        *self = fresh;
        Ok(())
    }
}
