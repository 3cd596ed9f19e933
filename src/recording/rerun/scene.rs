//! The bodies (deformed meshes coloured by the colour field, nodes) and the rigid obstacles,
//! in Rerun's coordinates.

use std::ops::Range;

use nalgebra::SVector;
use re_sdk_types::archetypes::{Clear, LineStrips2D, Mesh3D, Points2D, Points3D, ViewCoordinates};
use re_sdk_types::components::{Color, Radius};

use super::colors::colormap;
use super::obstacle_shapes::{shape_strips, shape_triangles};
use super::{ColorField, RerunRecorder};
use crate::contact::Obstacle;
use crate::dim::{Dim, SpatialDim};
use crate::recording::IterationInfo;
use crate::simulation::Simulation;

/// Drawing data of one body, built once.
pub(super) struct BodyDraw {
    name: String,
    /// Global node ids.
    nodes: Range<usize>,
    /// Global cell ids (the order of [`Simulation::cell_stresses`]).
    cells: Range<usize>,
    /// Local node ids of every cell, in the element's order (2D: around the cell).
    cell_nodes: Vec<Vec<usize>>,
    /// 3D: local ids of the boundary nodes (the vertices of the logged surface).
    surface_nodes: Vec<usize>,
    /// 3D: boundary triangles as indices into `surface_nodes`.
    triangles: Vec<[u32; 3]>,
}

impl<const D: usize> RerunRecorder<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// Builds the drawing data of the bodies and logs what never changes about them: the
    /// scene size, the 3D view's axes, the triangles of the 3D meshes.
    pub(super) fn setup_scene(&mut self, sim: &Simulation<D>) -> Vec<BodyDraw> {
        let mut bodies = Vec::new();
        let mut cell_offset = 0;
        for (b, body) in sim.bodies().iter().enumerate() {
            let cell_nodes: Vec<Vec<usize>> = body
                .mesh
                .blocks
                .iter()
                .flat_map(|blk| blk.cells().map(|c| c.to_vec()))
                .collect();
            let n_cells = cell_nodes.len();
            let (surface_nodes, triangles) = if D == 3 {
                surface(&body.mesh.boundary_facets(), body.mesh.node_count())
            } else {
                (Vec::new(), Vec::new())
            };
            bodies.push(BodyDraw {
                name: body.name.clone(),
                nodes: sim.nodes_of(b),
                cells: cell_offset..cell_offset + n_cells,
                cell_nodes,
                surface_nodes,
                triangles,
            });
            cell_offset += n_cells;
        }
        let reference = sim.reference_positions();
        if let Some(first) = reference.first() {
            let (lo, hi) = reference
                .iter()
                .fold((*first, *first), |(lo, hi), x| (lo.inf(x), hi.sup(x)));
            let size = (hi - lo).norm();
            if size > 0.0 && size.is_finite() {
                self.scene_size = size;
            }
        }
        if D == 3 {
            // The 3D view's up axis: against gravity (z when there is none).
            let g = sim.settings().gravity;
            let y_up = g.iter().any(|c| *c != 0.0) && g[1].abs() > g[2].abs() && g[1] < 0.0;
            let coordinates = if y_up {
                ViewCoordinates::RIGHT_HAND_Y_UP()
            } else {
                ViewCoordinates::RIGHT_HAND_Z_UP()
            };
            let r = self.rec.log_static("/", &coordinates);
            self.check(r);
        }
        for body in &bodies {
            if D == 3 {
                let r = self.rec.log_static(
                    format!("bodies/{}/mesh", body.name),
                    &Mesh3D::update_fields().with_triangle_indices(body.triangles.clone()),
                );
                self.check(r);
            }
        }
        bodies
    }

    /// Bodies added or removed between steps (a host's spawn and despawn): the drawing data
    /// is rebuilt and the removed bodies' entities are cleared.
    pub(super) fn follow_bodies(&mut self, sim: &Simulation<D>) {
        let Some(drawn) = &self.bodies else {
            return;
        };
        let bodies = sim.bodies();
        let same = drawn.len() == bodies.len()
            && drawn
                .iter()
                .enumerate()
                .all(|(b, d)| d.name == bodies[b].name && d.nodes == sim.nodes_of(b));
        if same {
            return;
        }
        let gone: Vec<String> = drawn
            .iter()
            .filter(|d| !bodies.iter().any(|b| b.name == d.name))
            .map(|d| d.name.clone())
            .collect();
        for name in gone {
            let r = self.rec.log(format!("bodies/{name}"), &Clear::recursive());
            self.check(r);
        }
        let redrawn = self.setup_scene(sim);
        self.bodies = Some(redrawn);
    }

    /// Whether obstacle `o` moves (a velocity, an angular velocity or a motion schedule, or
    /// a host that poses it from the first step).
    pub(super) fn obstacle_moves(&self, o: usize) -> bool {
        let obstacle = &self.obstacles[o];
        self.host_moved.get(o).copied().unwrap_or(false)
            || !obstacle.motion.is_empty()
            || obstacle.velocity.iter().any(|v| *v != 0.0)
            || obstacle.angular_velocity.iter().any(|w| *w != 0.0)
    }

    /// Logs the obstacles that do not move, once (static), in their pose.
    pub(super) fn log_fixed_obstacles(&mut self) {
        for o in 0..self.obstacles.len() {
            if !self.obstacle_moves(o) {
                let posed = self.obstacles[o].clone();
                self.log_obstacle(&posed, true);
            }
        }
    }

    /// Logs an obstacle's shape in its pose (translation and rotation about its pivot).
    pub(super) fn log_obstacle(&mut self, obstacle: &Obstacle<D>, is_static: bool) {
        let place = |p: &SVector<f64, D>| obstacle.to_world(p);
        let path = format!("obstacles/{}", obstacle.name);
        let color = Color::from_rgb(120, 120, 130);
        let r = if D == 2 {
            let strips: Vec<Vec<[f32; 2]>> = shape_strips(&obstacle.shape, self.scene_size)
                .into_iter()
                .map(|s| s.iter().map(|p| xy(&place(p))).collect())
                .collect();
            let arch = LineStrips2D::new(strips)
                .with_colors([color])
                .with_radii([Radius::new_ui_points(2.0)]);
            if is_static {
                self.rec.log_static(path, &arch)
            } else {
                self.rec.log(path, &arch)
            }
        } else {
            let (vertices, triangles) = shape_triangles(&obstacle.shape, self.scene_size);
            let vertices: Vec<[f32; 3]> = vertices.iter().map(|p| xyz(&place(p))).collect();
            let arch = Mesh3D::new(vertices)
                .with_triangle_indices(triangles)
                .with_albedo_factor(0x78788280u32);
            if is_static {
                self.rec.log_static(path, &arch)
            } else {
                self.rec.log(path, &arch)
            }
        };
        self.check(r);
    }

    pub(super) fn log_bodies(&mut self, info: &IterationInfo<'_, D>) {
        let Some(bodies) = self.bodies.take() else {
            return;
        };
        // The colour field: per cell (2D strips) and per node (3D vertex colours).
        let speed = |g: usize| -> f64 {
            let v = info.end_velocity.get(g * D..g * D + D).unwrap_or(&[]);
            v.iter().map(|x| x * x).sum::<f64>().sqrt()
        };
        for body in &bodies {
            let Some(positions) = info.end_positions.get(body.nodes.clone()) else {
                continue; // not this simulation's bodies (cannot happen after follow_bodies)
            };
            let cell_value: Vec<f64> = match self.color_field {
                ColorField::VonMises => body
                    .cells
                    .clone()
                    .map(|c| self.mises.get(c).copied().unwrap_or(0.0))
                    .collect(),
                ColorField::Speed => body
                    .cell_nodes
                    .iter()
                    .map(|c| {
                        c.iter().map(|&n| speed(body.nodes.start + n)).sum::<f64>()
                            / c.len().max(1) as f64
                    })
                    .collect(),
            };
            let top = cell_value.iter().fold(0.0f64, |m, v| m.max(*v));
            if top.is_finite() {
                self.field_max = self.field_max.max(top);
            }
            let scale = self.field_max;
            let mesh_path = format!("bodies/{}/mesh", body.name);
            let nodes_path = format!("bodies/{}/nodes", body.name);
            let node_color = Color::from_rgb(210, 210, 210);
            let node_radius = Radius::new_ui_points(1.5);
            let (r1, r2) = if D == 2 {
                let p2: Vec<[f32; 2]> = positions.iter().map(xy).collect();
                let strips: Vec<Vec<[f32; 2]>> = body
                    .cell_nodes
                    .iter()
                    .map(|c| c.iter().chain(c.first()).map(|&n| p2[n]).collect())
                    .collect();
                let colors: Vec<Color> = cell_value.iter().map(|v| colormap(*v, scale)).collect();
                let r1 = self.rec.log(
                    mesh_path,
                    &LineStrips2D::new(strips)
                        .with_colors(colors)
                        .with_radii([Radius::new_ui_points(1.0)]),
                );
                let r2 = self.rec.log(
                    nodes_path,
                    &Points2D::new(p2)
                        .with_colors([node_color])
                        .with_radii([node_radius]),
                );
                (r1, r2)
            } else {
                let mut node_value = vec![0.0; positions.len()];
                match self.color_field {
                    ColorField::Speed => {
                        for (n, v) in node_value.iter_mut().enumerate() {
                            *v = speed(body.nodes.start + n);
                        }
                    }
                    ColorField::VonMises => {
                        let mut count = vec![0usize; positions.len()];
                        for (c, cell) in body.cell_nodes.iter().enumerate() {
                            for &n in cell {
                                node_value[n] += cell_value[c];
                                count[n] += 1;
                            }
                        }
                        for (v, k) in node_value.iter_mut().zip(count) {
                            *v /= k.max(1) as f64;
                        }
                    }
                }
                let vertices: Vec<[f32; 3]> = body
                    .surface_nodes
                    .iter()
                    .map(|&n| xyz(&positions[n]))
                    .collect();
                let colors: Vec<Color> = body
                    .surface_nodes
                    .iter()
                    .map(|&n| colormap(node_value[n], scale))
                    .collect();
                let r1 = self
                    .rec
                    .log(mesh_path, &Mesh3D::new(vertices).with_vertex_colors(colors));
                let p3: Vec<[f32; 3]> = positions.iter().map(xyz).collect();
                let r2 = self.rec.log(
                    nodes_path,
                    &Points3D::new(p3)
                        .with_colors([node_color])
                        .with_radii([node_radius]),
                );
                (r1, r2)
            };
            self.check(r1);
            self.check(r2);
        }
        self.bodies = Some(bodies);
    }
}

/// The boundary triangles of a 3D mesh with compact vertex numbering.
fn surface<const D: usize>(facets: &[[usize; D]], nodes: usize) -> (Vec<usize>, Vec<[u32; 3]>) {
    let mut index = vec![u32::MAX; nodes];
    let mut surface_nodes = Vec::new();
    let mut triangles = Vec::with_capacity(facets.len());
    for f in facets {
        let mut t = [0u32; 3];
        for (k, &n) in f.iter().take(3).enumerate() {
            if index[n] == u32::MAX {
                index[n] = surface_nodes.len() as u32;
                surface_nodes.push(n);
            }
            t[k] = index[n];
        }
        triangles.push(t);
    }
    (surface_nodes, triangles)
}

/// 2D positions and vectors as Rerun logs them. Rerun's 2D views draw y downwards (image
/// convention), so y is negated: the scene appears upright, and tools reading `bodies/*`,
/// `contacts/*` or `obstacles/*` of a 2D recording must negate y back.
pub(super) fn xy<const D: usize>(p: &SVector<f64, D>) -> [f32; 2] {
    [p[0] as f32, -(p[1] as f32)]
}

pub(super) fn xyz<const D: usize>(p: &SVector<f64, D>) -> [f32; 3] {
    let z = if D > 2 { p[2] } else { 0.0 };
    [p[0] as f32, p[1] as f32, z as f32]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn surface_is_compact() {
        let (nodes, tris) = surface::<3>(&[[5, 7, 9], [7, 9, 11]], 12);
        assert_eq!(nodes, vec![5, 7, 9, 11]);
        assert_eq!(tris, vec![[0, 1, 2], [1, 2, 3]]);
    }
}
