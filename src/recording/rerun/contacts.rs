//! The contact records of an iteration (slave points, master points, gaps, forces, slip) and
//! the changes of the active set, as text.

use std::collections::BTreeSet;

use re_sdk_types::archetypes::{
    Arrows2D, Arrows3D, LineStrips2D, LineStrips3D, Points2D, Points3D,
};
use re_sdk_types::components::{Color, Radius, TextLogLevel};

use super::colors::gap_color;
use super::scene::{xy, xyz};
use super::RerunRecorder;
use crate::contact::Obstacle;
use crate::dim::{Dim, SpatialDim};
use crate::recording::{ContactRecord, IterationInfo};

impl<const D: usize> RerunRecorder<D>
where
    Dim<D>: SpatialDim<D>,
{
    pub(super) fn log_contacts(&mut self, info: &IterationInfo<'_, D>) {
        let contacts = info.contacts;
        if contacts.is_empty() && !self.had_contacts {
            return;
        }
        self.had_contacts = !contacts.is_empty();
        let force_top = contacts.iter().fold(0.0f64, |m, c| {
            m.max(c.normal_force.abs()).max(c.friction_force.norm())
        });
        if force_top.is_finite() {
            self.force_max = self.force_max.max(force_top);
        }
        // Arrow length [m] per newton: the largest force so far is 10% of the scene.
        let per_newton = if self.force_max > 0.0 {
            0.1 * self.scene_size / self.force_max
        } else {
            0.0
        };
        let gap_top = contacts.iter().fold(0.0f64, |m, c| m.max(c.gap.abs()));
        let active: Vec<&ContactRecord<D>> = contacts.iter().filter(|c| c.active).collect();
        let loaded: Vec<&ContactRecord<D>> =
            contacts.iter().filter(|c| c.normal_force != 0.0).collect();
        let rubbing: Vec<&ContactRecord<D>> = contacts
            .iter()
            .filter(|c| c.friction_force.norm() > 0.0)
            .collect();
        let slipping: Vec<&ContactRecord<D>> = contacts
            .iter()
            .filter(|c| c.slip_velocity.norm() > 0.0)
            .collect();

        let grey = Color::from_rgb(150, 150, 150);
        let red = Color::from_rgb(220, 30, 30);
        let orange = Color::from_rgb(240, 140, 0);
        let purple = Color::from_rgb(150, 60, 200);
        let green = Color::from_rgb(20, 160, 60);
        let gap_colors: Vec<Color> = contacts.iter().map(|c| gap_color(c.gap, gap_top)).collect();
        let gap_labels: Vec<String> = contacts
            .iter()
            .map(|c| format!("{:.3e} m", c.gap))
            .collect();
        let force_labels: Vec<String> = loaded
            .iter()
            .map(|c| format!("{:.3e} N", c.normal_force))
            .collect();
        let pt = Radius::new_ui_points(3.0);
        let h = info.time_step;

        let results = if D == 2 {
            let pos = |c: &ContactRecord<D>| xy(&c.position);
            let segments: Vec<Vec<[f32; 2]>> = contacts
                .iter()
                .map(|c| vec![xy(&c.position), xy(&c.master_point)])
                .collect();
            [
                self.rec.log(
                    "contacts/candidates",
                    &LineStrips2D::new(segments).with_colors([grey]),
                ),
                self.rec.log(
                    "contacts/active",
                    &Points2D::new(active.iter().map(|c| pos(c)))
                        .with_colors([red])
                        .with_radii([Radius::new_ui_points(4.0)]),
                ),
                self.rec.log(
                    "contacts/gap",
                    &Points2D::new(contacts.iter().map(pos))
                        .with_colors(gap_colors)
                        .with_labels(gap_labels)
                        .with_radii([pt]),
                ),
                self.rec.log(
                    "contacts/normal_force",
                    &Arrows2D::from_vectors(
                        loaded
                            .iter()
                            .map(|c| xy(&(c.normal * (c.normal_force * per_newton)))),
                    )
                    .with_origins(loaded.iter().map(|c| pos(c)))
                    .with_labels(force_labels)
                    .with_colors([orange]),
                ),
                self.rec.log(
                    "contacts/friction_force",
                    &Arrows2D::from_vectors(
                        rubbing.iter().map(|c| xy(&(c.friction_force * per_newton))),
                    )
                    .with_origins(rubbing.iter().map(|c| pos(c)))
                    .with_colors([purple]),
                ),
                self.rec.log(
                    "contacts/slip",
                    &Arrows2D::from_vectors(slipping.iter().map(|c| xy(&(c.slip_velocity * h))))
                        .with_origins(slipping.iter().map(|c| pos(c)))
                        .with_colors([green]),
                ),
            ]
        } else {
            let pos = |c: &ContactRecord<D>| xyz(&c.position);
            let segments: Vec<Vec<[f32; 3]>> = contacts
                .iter()
                .map(|c| vec![xyz(&c.position), xyz(&c.master_point)])
                .collect();
            [
                self.rec.log(
                    "contacts/candidates",
                    &LineStrips3D::new(segments).with_colors([grey]),
                ),
                self.rec.log(
                    "contacts/active",
                    &Points3D::new(active.iter().map(|c| pos(c)))
                        .with_colors([red])
                        .with_radii([Radius::new_ui_points(4.0)]),
                ),
                self.rec.log(
                    "contacts/gap",
                    &Points3D::new(contacts.iter().map(pos))
                        .with_colors(gap_colors)
                        .with_labels(gap_labels)
                        .with_radii([pt]),
                ),
                self.rec.log(
                    "contacts/normal_force",
                    &Arrows3D::from_vectors(
                        loaded
                            .iter()
                            .map(|c| xyz(&(c.normal * (c.normal_force * per_newton)))),
                    )
                    .with_origins(loaded.iter().map(|c| pos(c)))
                    .with_labels(force_labels)
                    .with_colors([orange]),
                ),
                self.rec.log(
                    "contacts/friction_force",
                    &Arrows3D::from_vectors(
                        rubbing
                            .iter()
                            .map(|c| xyz(&(c.friction_force * per_newton))),
                    )
                    .with_origins(rubbing.iter().map(|c| pos(c)))
                    .with_colors([purple]),
                ),
                self.rec.log(
                    "contacts/slip",
                    &Arrows3D::from_vectors(slipping.iter().map(|c| xyz(&(c.slip_velocity * h))))
                        .with_origins(slipping.iter().map(|c| pos(c)))
                        .with_colors([green]),
                ),
            ]
        };
        for r in results {
            self.check(r);
        }
    }

    /// Logs the changes of the active set as text.
    pub(super) fn log_status_changes(&mut self, info: &IterationInfo<'_, D>) {
        let now: BTreeSet<(usize, Option<usize>)> = info
            .contacts
            .iter()
            .filter(|c| c.active)
            .map(|c| (c.slave, c.obstacle))
            .collect();
        if now == self.active {
            return;
        }
        let name = |o: Option<usize>, obstacles: &[Obstacle<D>]| match o {
            Some(o) => match obstacles.get(o) {
                Some(ob) => format!("obstacle `{}`", ob.name),
                None => format!("obstacle {o}"),
            },
            None => "a body facet".to_string(),
        };
        let closed: Vec<_> = now.difference(&self.active).copied().collect();
        let opened: Vec<_> = self.active.difference(&now).copied().collect();
        const DETAIL: usize = 10;
        let mut lines = vec![format!(
            "step {} iteration {}: {} contact(s) closed, {} opened; active set {}",
            info.step,
            info.iteration,
            closed.len(),
            opened.len(),
            now.len()
        )];
        for &(slave, o) in closed.iter().take(DETAIL) {
            let rec = info
                .contacts
                .iter()
                .find(|c| c.slave == slave && c.obstacle == o);
            let (gap, force) = rec.map_or((0.0, 0.0), |c| (c.gap, c.normal_force));
            lines.push(format!(
                "  node {slave} closed on {} (gap {gap:.3e} m, normal force {force:.3e} N)",
                name(o, &self.obstacles)
            ));
        }
        for &(slave, o) in opened.iter().take(DETAIL) {
            lines.push(format!(
                "  node {slave} released from {}",
                name(o, &self.obstacles)
            ));
        }
        if closed.len() > DETAIL || opened.len() > DETAIL {
            lines.push("  ...".into());
        }
        self.active = now;
        self.log_text(TextLogLevel::INFO, lines.join("\n"));
    }
}
