//! Obstacle poses: each obstacle's translation and rotation about its pivot (the pivot moves
//! with the translation), advanced every step from its velocity and angular velocity, and the
//! surface velocity `v + omega x (x - pivot)` that contact reads. A schedule's piece turns the
//! obstacle about the moving pivot at a constant angular velocity, so the pose at the end of
//! a step is the exact composition of the turns `exp(omega_i dt_i)` of the pieces it spans.

use nalgebra::{SMatrix, SVector};

use super::state::State;
use super::ObstacleId;
use super::{invalid, Simulation};
use crate::contact::Obstacle;
use crate::dim::{Dim, SpatialDim};
use crate::error::Result;

impl<const D: usize> Simulation<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// Displacement of an obstacle (of its pivot) since t = 0 (m).
    pub fn obstacle_translation(&self, obstacle: ObstacleId) -> Result<SVector<f64, D>> {
        let k = self.obstacle_index(obstacle)?;
        Ok(self.translation_of(k))
    }

    fn translation_of(&self, k: usize) -> SVector<f64, D> {
        SVector::from_column_slice(&self.state.obstacle_translations[k * D..k * D + D])
    }

    /// Rotation of an obstacle about its pivot since t = 0.
    pub fn obstacle_rotation(&self, obstacle: ObstacleId) -> Result<SMatrix<f64, D, D>> {
        let k = self.obstacle_index(obstacle)?;
        Ok(self.rotation_of(k))
    }

    fn rotation_of(&self, k: usize) -> SMatrix<f64, D, D> {
        let r = <Dim<D>>::ROTATION;
        <Dim<D>>::rotation_matrix(&self.state.obstacle_rotations[k * r..k * r + r])
    }

    /// Velocity of an obstacle's pivot (m/s): the last step's, or the one set for the next
    /// step.
    pub fn obstacle_linear_velocity(&self, obstacle: ObstacleId) -> Result<SVector<f64, D>> {
        Ok(self.obstacle_velocity(self.obstacle_index(obstacle)?))
    }

    /// Angular velocity of an obstacle about its pivot (rad/s; 1 component in 2D, 3 in 3D):
    /// the last step's, or the one set for the next step.
    pub fn obstacle_angular_velocity(&self, obstacle: ObstacleId) -> Result<Vec<f64>> {
        let k = self.obstacle_index(obstacle)?;
        let a = <Dim<D>>::ANGULAR;
        Ok(self.state.obstacle_angular_velocities[k * a..k * a + a].to_vec())
    }

    /// Where the pivot of an obstacle is now (m): its pivot at t = 0 plus its translation.
    pub fn obstacle_pivot(&self, obstacle: ObstacleId) -> Result<SVector<f64, D>> {
        let k = self.obstacle_index(obstacle)?;
        Ok(self.model.obstacles[k].pivot_point() + self.translation_of(k))
    }

    /// The index of a kinematic obstacle the host may drive (no motion schedule).
    fn driven_index(&self, obstacle: ObstacleId, what: &str) -> Result<usize> {
        let k = self.obstacle_index(obstacle)?;
        let o = &self.model.obstacles[k];
        if !o.motion.is_empty() {
            return Err(invalid(
                &format!("obstacle `{}` {what}", o.name),
                "a motion schedule",
                &format!("an obstacle without a motion schedule (its schedule sets its {what})"),
            ));
        }
        Ok(k)
    }

    /// Sets the velocity of an obstacle's pivot (m/s) from the next step on (kinematic
    /// obstacles driven by a host).
    pub fn set_obstacle_velocity(
        &mut self,
        obstacle: ObstacleId,
        v: SVector<f64, D>,
    ) -> Result<()> {
        let k = self.driven_index(obstacle, "velocity")?;
        if v.iter().any(|x| !x.is_finite()) {
            return Err(invalid(
                &format!("obstacle `{}` velocity", self.model.obstacles[k].name),
                format!("{:?}", v.as_slice()),
                "finite components (m/s)",
            ));
        }
        self.state.obstacle_velocities[k * D..k * D + D].copy_from_slice(v.as_slice());
        self.next_poses.retain(|p| p.0 != obstacle);
        Ok(())
    }

    /// Sets the angular velocity of an obstacle about its pivot (rad/s; 1 component in 2D,
    /// 3 in 3D) from the next step on (kinematic obstacles driven by a host).
    pub fn set_obstacle_angular_velocity(
        &mut self,
        obstacle: ObstacleId,
        omega: &[f64],
    ) -> Result<()> {
        let k = self.driven_index(obstacle, "angular velocity")?;
        let a = <Dim<D>>::ANGULAR;
        if omega.len() != a || omega.iter().any(|w| !w.is_finite()) {
            return Err(invalid(
                &format!(
                    "obstacle `{}` angular velocity",
                    self.model.obstacles[k].name
                ),
                format!("{omega:?}"),
                &format!("{a} finite component(s) (rad/s)"),
            ));
        }
        self.state.obstacle_angular_velocities[k * a..k * a + a].copy_from_slice(omega);
        self.next_poses.retain(|p| p.0 != obstacle);
        Ok(())
    }

    /// Drives a kinematic obstacle to a pose at the end of the next step: its pivot displaced
    /// by `translation` (m) from t = 0 and turned by `rotation` (a rotation matrix) about
    /// it. The step moves it there at constant velocity and angular velocity (the shortest
    /// turn), so contact sees the surface velocity of that motion and the obstacle's work is
    /// booked; a step of another size ([`Simulation::advance`]) reaches the pose too. A velocity
    /// or angular velocity set afterwards replaces the pose. How a host drives a gripper's jaw
    /// or a robot's link: call it before every step.
    pub fn set_obstacle_next_pose(
        &mut self,
        obstacle: ObstacleId,
        translation: SVector<f64, D>,
        rotation: SMatrix<f64, D, D>,
    ) -> Result<()> {
        let k = self.driven_index(obstacle, "pose")?;
        let name = &self.model.obstacles[k].name;
        if translation.iter().any(|x| !x.is_finite()) {
            return Err(invalid(
                &format!("obstacle `{name}` translation"),
                format!("{:?}", translation.as_slice()),
                "finite components (m)",
            ));
        }
        let orthogonality =
            (rotation.transpose() * rotation - SMatrix::<f64, D, D>::identity()).norm();
        let det = <Dim<D>>::det(&rotation);
        if !(orthogonality < 1e-6 && (det - 1.0).abs() < 1e-6) {
            return Err(invalid(
                &format!("obstacle `{name}` rotation"),
                format!("a matrix with |R^T R - I| = {orthogonality:.1e} and det {det:.6}"),
                "a rotation matrix (orthonormal, determinant 1)",
            ));
        }
        self.drive_to_pose(k, &translation, &rotation, self.model.settings.time_step);
        self.next_poses.retain(|p| p.0 != obstacle);
        self.next_poses.push((obstacle, translation, rotation));
        Ok(())
    }

    /// Sets obstacle `k`'s velocity and angular velocity so that a step of `h` (s) ends at the
    /// pose.
    fn drive_to_pose(
        &mut self,
        k: usize,
        translation: &SVector<f64, D>,
        rotation: &SMatrix<f64, D, D>,
        h: f64,
    ) {
        let v = (translation - self.translation_of(k)) / h;
        let (a, r) = (<Dim<D>>::ANGULAR, <Dim<D>>::ROTATION);
        let turn =
            <Dim<D>>::turn_between(&self.state.obstacle_rotations[k * r..k * r + r], rotation);
        self.state.obstacle_velocities[k * D..k * D + D].copy_from_slice(v.as_slice());
        for (w, t) in self.state.obstacle_angular_velocities[k * a..k * a + a]
            .iter_mut()
            .zip(turn)
        {
            *w = t / h;
        }
    }

    /// Takes the poses asked by [`Simulation::set_obstacle_next_pose`] over a step of `h` (s),
    /// the one about to run (the host may run another size than the configured one).
    pub(crate) fn drive_to_next_poses(&mut self, h: f64) {
        for (id, translation, rotation) in self.next_poses.clone() {
            // An obstacle removed since has no pose to reach.
            if let Ok(k) = self.obstacle_index(id) {
                self.drive_to_pose(k, &translation, &rotation, h);
            }
        }
    }

    /// The obstacles in their current pose (`translation` and `rotation` set).
    pub fn posed_obstacles(&self) -> Vec<Obstacle<D>> {
        self.obstacles_at(
            &self.state.obstacle_translations,
            &self.state.obstacle_rotations,
        )
    }

    /// The obstacles where a step of `h` (s) from the current state puts them, at the
    /// velocities in the state (a schedule sets those at the start of each step, so a
    /// recorder's `step_start` hook sees the step's own).
    pub fn obstacles_after(&self, h: f64) -> Vec<Obstacle<D>> {
        let (translations, rotations) = self.obstacle_poses_after(h);
        self.obstacles_at(&translations, &rotations)
    }

    /// Sets the velocity and angular velocity of every scheduled obstacle for a step of size
    /// `h`: its displacement and its turn over the step (across schedule pieces) divided by
    /// `h`.
    pub(super) fn schedule_obstacles(&mut self, h: f64) {
        let t0 = self.state.time;
        let a = <Dim<D>>::ANGULAR;
        for (k, o) in self.model.obstacles.iter().enumerate() {
            if let Some(d) = o.scheduled_displacement(t0, t0 + h) {
                let v = d / h;
                self.state.obstacle_velocities[k * D..k * D + D].copy_from_slice(v.as_slice());
                let turn = scheduled_turn::<D>(o, t0, t0 + h);
                let omega = &mut self.state.obstacle_angular_velocities[k * a..k * a + a];
                for (w, t) in omega.iter_mut().zip(turn) {
                    *w = t / h;
                }
            }
        }
    }

    /// The obstacles' poses after a step of `h` (flat translations, stored rotations): the
    /// translation moves by `h v`, the rotation turns by `exp(h omega)`; an obstacle that does
    /// not turn keeps its stored rotation's bits.
    pub(super) fn obstacle_poses_after(&self, h: f64) -> (Vec<f64>, Vec<f64>) {
        let translations: Vec<f64> = self
            .state
            .obstacle_translations
            .iter()
            .zip(&self.state.obstacle_velocities)
            .map(|(t, v)| t + h * v)
            .collect();
        let (a, r) = (<Dim<D>>::ANGULAR, <Dim<D>>::ROTATION);
        let mut rotations = self.state.obstacle_rotations.clone();
        for k in 0..self.model.obstacles.len() {
            let omega = &self.state.obstacle_angular_velocities[k * a..k * a + a];
            if omega.iter().any(|w| *w != 0.0) {
                let turn: Vec<f64> = omega.iter().map(|w| w * h).collect();
                let next = <Dim<D>>::turned(&rotations[k * r..k * r + r], &turn);
                rotations[k * r..k * r + r].copy_from_slice(&next);
            }
        }
        (translations, rotations)
    }

    /// The obstacles at the given poses (D translations and `ROTATION` stored values each).
    pub(super) fn obstacles_at(&self, translations: &[f64], rotations: &[f64]) -> Vec<Obstacle<D>> {
        let r = <Dim<D>>::ROTATION;
        self.model
            .obstacles
            .iter()
            .enumerate()
            .map(|(k, o)| Obstacle {
                translation: SVector::from_column_slice(&translations[k * D..k * D + D]),
                rotation: <Dim<D>>::rotation_matrix(&rotations[k * r..k * r + r]),
                ..o.clone()
            })
            .collect()
    }

    /// The velocity of obstacle `k`'s pivot (m/s).
    pub(super) fn obstacle_velocity(&self, k: usize) -> SVector<f64, D> {
        SVector::from_column_slice(&self.state.obstacle_velocities[k * D..k * D + D])
    }

    /// The velocity of obstacle `k`'s surface at `x` (m/s), `posed` being the obstacle at the
    /// end of the step: `v + omega x (x - pivot)` (exactly `v` when it does not turn).
    pub(super) fn surface_velocity(
        &self,
        k: usize,
        posed: &Obstacle<D>,
        x: &SVector<f64, D>,
    ) -> SVector<f64, D> {
        let v = self.obstacle_velocity(k);
        match self.spin(k, posed, x) {
            Some(s) => v + s,
            None => v,
        }
    }

    /// `omega x (x - pivot)` of obstacle `k` at `x`, `None` when it does not turn.
    fn spin(&self, k: usize, posed: &Obstacle<D>, x: &SVector<f64, D>) -> Option<SVector<f64, D>> {
        let a = <Dim<D>>::ANGULAR;
        let omega = &self.state.obstacle_angular_velocities[k * a..k * a + a];
        if omega.iter().all(|w| *w == 0.0) {
            return None;
        }
        let pivot = posed.pivot_point() + posed.translation;
        Some(<Dim<D>>::spin_velocity(omega, &(x - pivot)))
    }

    /// Whether some obstacle turns in the step.
    pub(super) fn obstacles_turn(&self) -> bool {
        self.state
            .obstacle_angular_velocities
            .iter()
            .any(|w| *w != 0.0)
    }

    /// The work over a step of `h` of forces (obstacle, point, force) that turning obstacles
    /// apply, through their turning: `h f . (omega x r)`, summed (J). The pivot's share,
    /// `h F . v` on each obstacle's total force, is booked apart.
    pub(super) fn spin_work(
        &self,
        h: f64,
        posed: &[Obstacle<D>],
        forces: impl IntoIterator<Item = (usize, SVector<f64, D>, SVector<f64, D>)>,
    ) -> f64 {
        forces
            .into_iter()
            .filter_map(|(k, x, f)| self.spin(k, &posed[k], &x).map(|s| h * f.dot(&s)))
            .sum()
    }

    /// Checks the obstacle poses of a state against the model; a state from before rotating
    /// obstacles (no rotations, no angular velocities) gets the model's.
    pub(super) fn check_obstacle_state(&self, state: &mut State) -> Result<()> {
        let n = self.model.obstacles.len();
        let (rotations, angular) = initial_rotations(&self.model.obstacles);
        if state.obstacle_rotations.is_empty() && state.obstacle_angular_velocities.is_empty() {
            state.obstacle_rotations = rotations;
            state.obstacle_angular_velocities = angular;
        }
        let checks = [
            (
                "obstacle_rotations",
                state.obstacle_rotations.len(),
                n * <Dim<D>>::ROTATION,
            ),
            (
                "obstacle_angular_velocities",
                state.obstacle_angular_velocities.len(),
                n * <Dim<D>>::ANGULAR,
            ),
        ];
        for (name, found, expected) in checks {
            if found != expected {
                return Err(invalid(
                    &format!("state.{name}"),
                    format!("{found} values"),
                    &format!("{expected} values (the model's)"),
                ));
            }
        }
        Ok(())
    }
}

impl Simulation<2> {
    /// The angle an obstacle has turned about its pivot since t = 0 (rad, counter-clockwise).
    pub fn obstacle_angle(&self, obstacle: ObstacleId) -> Result<f64> {
        Ok(self.state.obstacle_rotations[self.obstacle_index(obstacle)?])
    }
}

/// The initial stored rotations and angular velocities of `obstacles` (their `rotation` and
/// `angular_velocity`; none: zero).
pub(super) fn initial_rotations<const D: usize>(obstacles: &[Obstacle<D>]) -> (Vec<f64>, Vec<f64>)
where
    Dim<D>: SpatialDim<D>,
{
    let mut rotations = Vec::with_capacity(obstacles.len() * <Dim<D>>::ROTATION);
    let mut angular = Vec::with_capacity(obstacles.len() * <Dim<D>>::ANGULAR);
    for o in obstacles {
        rotations.extend(<Dim<D>>::rotation_values(&o.rotation));
        if o.angular_velocity.is_empty() {
            angular.extend(std::iter::repeat_n(0.0, <Dim<D>>::ANGULAR));
        } else {
            angular.extend(&o.angular_velocity);
        }
    }
    (rotations, angular)
}

/// The turn (rotation vector) of a scheduled obstacle between `t0` and `t1`: the pieces' turns
/// `omega_i dt_i` composed in time order.
fn scheduled_turn<const D: usize>(o: &Obstacle<D>, t0: f64, t1: f64) -> Vec<f64>
where
    Dim<D>: SpatialDim<D>,
{
    let mut turn = vec![0.0; <Dim<D>>::ANGULAR];
    let mut start = 0.0;
    for piece in &o.motion {
        let (a, b) = (t0.max(start), t1.min(piece.until));
        if b > a && piece.angular_velocity.iter().any(|w| *w != 0.0) {
            let step: Vec<f64> = piece.angular_velocity.iter().map(|w| w * (b - a)).collect();
            turn = <Dim<D>>::compose_turns(&turn, &step);
        }
        start = piece.until;
    }
    turn
}

/// An obstacle's motion: a schedule's times increasing and finite, its velocities and angular
/// velocities finite with 1 (2D) or 3 (3D) components; the constant angular velocity likewise;
/// the pivot finite; the rotation a finite proper rotation.
pub(super) fn validate_motion<const D: usize>(o: &Obstacle<D>) -> Result<()>
where
    Dim<D>: SpatialDim<D>,
{
    let a = <Dim<D>>::ANGULAR;
    let angular = |key: &str, w: &[f64]| -> Result<()> {
        if !w.is_empty() && (w.len() != a || w.iter().any(|x| !x.is_finite())) {
            return Err(invalid(
                key,
                format!("{w:?}"),
                &format!("{a} finite component(s) [rad/s]"),
            ));
        }
        Ok(())
    };
    let mut previous = 0.0;
    for (i, piece) in o.motion.iter().enumerate() {
        let key = |what: &str| format!("obstacles.{}.motion.{i}.{what}", o.name);
        if !(piece.until > previous && piece.until.is_finite()) {
            return Err(invalid(
                &key("until"),
                piece.until,
                &format!("a finite time [s] after the previous piece's end ({previous})"),
            ));
        }
        previous = piece.until;
        if piece.velocity.iter().any(|v| !v.is_finite()) {
            return Err(invalid(
                &key("velocity"),
                format!("{:?}", piece.velocity.as_slice()),
                "finite components [m/s]",
            ));
        }
        angular(&key("angular_velocity"), &piece.angular_velocity)?;
    }
    let key = |what: &str| format!("obstacles.{}.{what}", o.name);
    angular(&key("angular_velocity"), &o.angular_velocity)?;
    if let Some(p) = o.pivot {
        if p.iter().any(|x| !x.is_finite()) {
            return Err(invalid(
                &key("pivot"),
                format!("{:?}", p.as_slice()),
                "finite components [m]",
            ));
        }
    }
    let r = &o.rotation;
    let orthogonal = (r.transpose() * r - SMatrix::<f64, D, D>::identity()).amax() < 1e-9;
    if !(orthogonal && <Dim<D>>::det(r) > 0.0) {
        return Err(invalid(
            &key("rotation"),
            format!("{:?}", r.as_slice()),
            "a rotation matrix (orthonormal, determinant 1)",
        ));
    }
    Ok(())
}
