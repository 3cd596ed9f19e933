//! Handles of bodies and obstacles, and the queries that take them.
//!
//! A handle is a slot and a generation: removing a body frees its slot and bumps the
//! generation, so a handle kept by a host after the removal (or forged) is refused with
//! [`Error::InvalidHandle`], never mistaken for the body that reuses the slot. Bodies keep the
//! order in which they were added (the model's order, the node numbering's); a handle does not
//! change when another body is removed. The slot tables live in the [`State`](super::State),
//! so that a snapshot restored, or a checkpoint resumed, gives back the handles it had.

use nalgebra::SVector;
use serde::{Deserialize, Serialize};

use super::Simulation;
use crate::dim::{Dim, SpatialDim};
use crate::error::{Error, Result};

/// Handle of a body in a simulation: returned by [`Simulation::add_body`],
/// [`Simulation::body_id`] and [`Simulation::body_ids`]. Stays valid until the body is
/// removed; a stale handle gives [`Error::InvalidHandle`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct BodyId {
    slot: u32,
    generation: u32,
}

/// Handle of a rigid obstacle: returned by [`Simulation::add_obstacle`],
/// [`Simulation::obstacle_id`] and [`Simulation::obstacle_ids`]. Stays valid until the
/// obstacle is removed; a stale handle gives [`Error::InvalidHandle`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct ObstacleId {
    slot: u32,
    generation: u32,
}

/// One slot: its generation and, while occupied, the entity's position in the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
struct Slot {
    generation: u32,
    position: Option<usize>,
}

/// A generational slot table: handle (slot, generation) to position in the model's list.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Slots {
    slots: Vec<Slot>,
}

impl Slots {
    /// `count` entities at positions `0..count`, slot i holding position i.
    pub(crate) fn identity(count: usize) -> Self {
        Slots {
            slots: (0..count)
                .map(|i| Slot {
                    generation: 0,
                    position: Some(i),
                })
                .collect(),
        }
    }

    /// Whether the table holds no slot (a state from before handles: see `ensure`).
    pub(crate) fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// Number of occupied slots.
    pub(crate) fn len(&self) -> usize {
        self.slots.iter().filter(|s| s.position.is_some()).count()
    }

    /// The positions the occupied slots hold, in slot order.
    pub(crate) fn positions(&self) -> Vec<usize> {
        self.slots.iter().filter_map(|s| s.position).collect()
    }

    /// Whether the occupied slots hold the positions `0..count`, each once (a table built
    /// by hand, or deserialised, may not: lookups would then index out of range).
    pub(crate) fn holds_positions(&self, count: usize) -> bool {
        let mut seen = vec![false; count];
        for p in self.slots.iter().filter_map(|s| s.position) {
            match seen.get_mut(p) {
                Some(s) if !*s => *s = true,
                _ => return false,
            }
        }
        seen.iter().all(|&s| s)
    }

    fn resolve(&self, slot: u32, generation: u32) -> Option<usize> {
        self.slots
            .get(slot as usize)
            .filter(|s| s.generation == generation)
            .and_then(|s| s.position)
    }

    /// The (slot, generation) of the entity at `position`.
    fn handle_at(&self, position: usize) -> Option<(u32, u32)> {
        self.slots
            .iter()
            .position(|s| s.position == Some(position))
            .map(|i| (i as u32, self.slots[i].generation))
    }

    /// The (slot, generation) of every entity, in position order.
    fn in_order(&self) -> Vec<(u32, u32)> {
        let mut out = vec![(0, 0); self.len()];
        for (i, s) in self.slots.iter().enumerate() {
            if let Some(p) = s.position {
                out[p] = (i as u32, s.generation);
            }
        }
        out
    }

    /// Occupies a free slot (or a new one) for an entity appended at `position`.
    fn insert(&mut self, position: usize) -> (u32, u32) {
        if let Some(i) = self.slots.iter().position(|s| s.position.is_none()) {
            self.slots[i].position = Some(position);
            (i as u32, self.slots[i].generation)
        } else {
            self.slots.push(Slot {
                generation: 0,
                position: Some(position),
            });
            ((self.slots.len() - 1) as u32, 0)
        }
    }

    /// Frees the slot of the entity at `position`; later entities move down by one.
    fn remove(&mut self, position: usize) {
        for s in &mut self.slots {
            match s.position {
                Some(p) if p == position => {
                    s.position = None;
                    s.generation = s.generation.wrapping_add(1);
                }
                Some(p) if p > position => s.position = Some(p - 1),
                _ => {}
            }
        }
    }
}

impl BodyId {
    /// The handle that the `index`-th body given to the builder (or the `index`-th body of a
    /// scene) receives when the simulation is built. Handles of bodies added later come from
    /// [`Simulation::add_body`].
    pub fn initial(index: usize) -> Self {
        BodyId {
            slot: index as u32,
            generation: 0,
        }
    }

    fn describe(&self) -> String {
        format!(
            "body handle (slot {}, generation {})",
            self.slot, self.generation
        )
    }
}

impl ObstacleId {
    /// The handle that the `index`-th obstacle given to the builder (or of a scene) receives
    /// when the simulation is built.
    pub fn initial(index: usize) -> Self {
        ObstacleId {
            slot: index as u32,
            generation: 0,
        }
    }

    fn describe(&self) -> String {
        format!(
            "obstacle handle (slot {}, generation {})",
            self.slot, self.generation
        )
    }
}

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// The position of a body in the model (and in [`Simulation::bodies`]).
    pub fn body_index(&self, body: BodyId) -> Result<usize> {
        self.state
            .body_slots
            .resolve(body.slot, body.generation)
            .ok_or_else(|| {
                Error::InvalidHandle(format!(
                    "{} names no body of this simulation (removed, or from another one)",
                    body.describe()
                ))
            })
    }

    /// The position of an obstacle in the model (and in [`Simulation::obstacles`]).
    pub fn obstacle_index(&self, obstacle: ObstacleId) -> Result<usize> {
        self.state
            .obstacle_slots
            .resolve(obstacle.slot, obstacle.generation)
            .ok_or_else(|| {
                Error::InvalidHandle(format!(
                    "{} names no obstacle of this simulation (removed, or from another one)",
                    obstacle.describe()
                ))
            })
    }

    /// The handle of the body at position `index` of the model.
    pub(crate) fn body_at(&self, index: usize) -> BodyId {
        let (slot, generation) = self
            .state
            .body_slots
            .handle_at(index)
            .expect("every body has a slot");
        BodyId { slot, generation }
    }

    /// The handle of the obstacle at position `index` of the model.
    pub(crate) fn obstacle_at(&self, index: usize) -> ObstacleId {
        let (slot, generation) = self
            .state
            .obstacle_slots
            .handle_at(index)
            .expect("every obstacle has a slot");
        ObstacleId { slot, generation }
    }

    /// A new slot for the body appended at `position`.
    pub(super) fn insert_body_slot(&mut self, position: usize) -> BodyId {
        let (slot, generation) = self.state.body_slots.insert(position);
        BodyId { slot, generation }
    }

    /// A new slot for the obstacle appended at `position`.
    pub(super) fn insert_obstacle_slot(&mut self, position: usize) -> ObstacleId {
        let (slot, generation) = self.state.obstacle_slots.insert(position);
        ObstacleId { slot, generation }
    }

    /// Frees the slot of the body at `position`.
    pub(super) fn remove_body_slot(&mut self, position: usize) {
        self.state.body_slots.remove(position);
    }

    /// Frees the slot of the obstacle at `position`.
    pub(super) fn remove_obstacle_slot(&mut self, position: usize) {
        self.state.obstacle_slots.remove(position);
    }

    /// The bodies' handles, in the model's order.
    pub fn body_ids(&self) -> Vec<BodyId> {
        let slots = self.state.body_slots.in_order();
        slots
            .into_iter()
            .map(|(slot, generation)| BodyId { slot, generation })
            .collect()
    }

    /// The obstacles' handles, in the model's order.
    pub fn obstacle_ids(&self) -> Vec<ObstacleId> {
        let slots = self.state.obstacle_slots.in_order();
        slots
            .into_iter()
            .map(|(slot, generation)| ObstacleId { slot, generation })
            .collect()
    }

    /// The handle of the body called `name`.
    pub fn body_id(&self, name: &str) -> Option<BodyId> {
        self.model
            .bodies
            .iter()
            .position(|b| b.name == name)
            .map(|b| self.body_at(b))
    }

    /// The handle of the obstacle called `name`.
    pub fn obstacle_id(&self, name: &str) -> Option<ObstacleId> {
        self.model
            .obstacles
            .iter()
            .position(|o| o.name == name)
            .map(|k| self.obstacle_at(k))
    }

    /// The global index of a body's node (bodies' nodes numbered in the model's order).
    pub fn global_node(&self, body: BodyId, node: usize) -> Result<usize> {
        let index = self.body_index(body)?;
        let b = &self.model.bodies[index];
        if node >= b.mesh.nodes.len() {
            return Err(Error::InvalidHandle(format!(
                "node {node} of body `{}` ({} nodes)",
                b.name,
                b.mesh.nodes.len()
            )));
        }
        Ok(self.node_offsets[index] + node)
    }

    /// Range of global nodes of a body.
    pub fn body_nodes(&self, body: BodyId) -> Result<std::ops::Range<usize>> {
        Ok(self.nodes_of(self.body_index(body)?))
    }

    /// Range of global nodes of the body at position `index` of the model.
    pub(crate) fn nodes_of(&self, index: usize) -> std::ops::Range<usize> {
        let start = self.node_offsets[index];
        start..start + self.model.bodies[index].mesh.nodes.len()
    }

    /// The body and local node of a global node.
    pub(crate) fn owner_of(&self, global: usize) -> (usize, usize) {
        let b = self.body_of_node(global);
        (b, global - self.node_offsets[b])
    }

    pub(super) fn node_vector(values: &[f64], node: usize) -> SVector<f64, D> {
        SVector::from_column_slice(&values[node * D..node * D + D])
    }

    /// Displacement of a node (m).
    pub fn displacement(&self, body: BodyId, node: usize) -> Result<SVector<f64, D>> {
        Ok(Self::node_vector(
            &self.state.displacement,
            self.global_node(body, node)?,
        ))
    }

    /// Velocity of a node (m/s).
    pub fn velocity(&self, body: BodyId, node: usize) -> Result<SVector<f64, D>> {
        Ok(Self::node_vector(
            &self.state.velocity,
            self.global_node(body, node)?,
        ))
    }

    /// Current position of a node (m).
    pub fn position(&self, body: BodyId, node: usize) -> Result<SVector<f64, D>> {
        let g = self.global_node(body, node)?;
        Ok(self.reference[g] + Self::node_vector(&self.state.displacement, g))
    }

    /// Current positions of a body's nodes (m), in its mesh's order.
    pub fn body_positions(&self, body: BodyId) -> Result<Vec<SVector<f64, D>>> {
        Ok(self
            .body_nodes(body)?
            .map(|g| self.reference[g] + Self::node_vector(&self.state.displacement, g))
            .collect())
    }

    /// Current velocities of a body's nodes (m/s), in its mesh's order.
    pub fn body_velocities(&self, body: BodyId) -> Result<Vec<SVector<f64, D>>> {
        Ok(self
            .body_nodes(body)?
            .map(|g| Self::node_vector(&self.state.velocity, g))
            .collect())
    }

    /// Current positions of all nodes (m), bodies in the model's order.
    pub fn positions(&self) -> Vec<SVector<f64, D>> {
        (0..self.reference.len())
            .map(|g| self.reference[g] + Self::node_vector(&self.state.displacement, g))
            .collect()
    }

    /// Sets a node's velocity (m/s); prescribed components keep their prescribed value.
    pub fn set_velocity(&mut self, body: BodyId, node: usize, v: SVector<f64, D>) -> Result<()> {
        let g = self.global_node(body, node)?;
        if v.iter().any(|x| !x.is_finite()) {
            return Err(super::invalid(
                "velocity",
                format!("{:?}", v.as_slice()),
                "finite components (m/s)",
            ));
        }
        for k in 0..D {
            let dof = g * D + k;
            self.state.velocity[dof] = self.prescribed[dof].unwrap_or(v[k]);
        }
        if self.state.step == 0 {
            self.state.reference_energy = self.energies().total();
        }
        Ok(())
    }

    /// Sets a constant external force on a node (N; per unit thickness in plane kinematics,
    /// the total over the revolution in axisymmetric ones); it stays until changed.
    pub fn set_nodal_force(&mut self, body: BodyId, node: usize, f: SVector<f64, D>) -> Result<()> {
        let g = self.global_node(body, node)?;
        if f.iter().any(|x| !x.is_finite()) {
            return Err(super::invalid(
                "nodal force",
                format!("{:?}", f.as_slice()),
                "finite components (N)",
            ));
        }
        self.state.loads[g * D..g * D + D].copy_from_slice(f.as_slice());
        Ok(())
    }

    /// Total mass of a body (kg; per unit thickness in plane kinematics).
    pub fn body_mass(&self, body: BodyId) -> Result<f64> {
        Ok(self.mass_of(self.body_index(body)?))
    }

    /// Linear momentum of a body (kg m/s): the sum over its degrees of freedom of `M v`, in
    /// the measure of [`Simulation::body_mass`] (per unit thickness in plane kinematics; the
    /// whole revolution in axisymmetric ones, where only the axial component y is a physical
    /// momentum: the radial sum of `M v` is not the vector sum of a ring's momenta, which is
    /// zero). With consistent or lumped mass alike it changes over a step by the impulse of
    /// the forces on the body.
    pub fn body_momentum(&self, body: BodyId) -> Result<SVector<f64, D>> {
        let nodes = self.nodes_of(self.body_index(body)?);
        let mut p = SVector::<f64, D>::zeros();
        let mut e = vec![0.0; self.reference.len() * D];
        for (d, component) in p.iter_mut().enumerate() {
            e.fill(0.0);
            for n in nodes.clone() {
                e[n * D + d] = 1.0;
            }
            *component =
                crate::assembly::symmetric_dot(&self.matrices.mass, &e, &self.state.velocity);
        }
        Ok(p)
    }

    /// Total mass of the body at position `index` of the model (kg).
    pub(crate) fn mass_of(&self, index: usize) -> f64 {
        let mut e = vec![0.0; self.reference.len() * D];
        for n in self.nodes_of(index) {
            e[n * D] = 1.0;
        }
        crate::assembly::symmetric_dot(&self.matrices.mass, &e, &e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::ElementKind;
    use crate::material::{LinearElastic, Material};
    use crate::mesh::generators::rectangle;
    use crate::simulation::{Body, Simulation2};
    use nalgebra::Vector2;

    /// A slot table read from a file that points at a position the model does not have (or
    /// twice at one) is refused by `set_state`, not a panic at the next lookup.
    #[test]
    fn a_state_with_forged_slots_is_refused() {
        let table = |positions: &[Option<usize>]| Slots {
            slots: positions
                .iter()
                .map(|&position| Slot {
                    generation: 0,
                    position,
                })
                .collect(),
        };
        assert!(table(&[Some(1), None, Some(0)]).holds_positions(2));
        assert!(!table(&[Some(0), Some(5)]).holds_positions(2));
        assert!(!table(&[Some(0), Some(0)]).holds_positions(2));
        assert!(!table(&[Some(0)]).holds_positions(2));

        let material = Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap());
        let mesh = rectangle(
            Vector2::new(0.0, 0.0),
            Vector2::new(1.0, 1.0),
            [2, 2],
            ElementKind::Quad4,
        )
        .unwrap();
        let mut sim = Simulation2::builder()
            .body(Body::new("a", mesh, material))
            .build()
            .unwrap();
        let mut state = sim.state().clone();
        state.body_slots = table(&[Some(3)]);
        let e = sim.set_state(state).unwrap_err();
        assert!(
            e.to_string()
                .contains("found slots at positions [3] (bodies) and [] (obstacles)"),
            "{e}"
        );
        assert!(sim.step().is_ok());
    }
}
