//! The end-of-step projection shared by implicit and explicit projection: a point is moved
//! onto its master, the correction shared between the two sides as the paper says ("related to
//! the dynamic conditions of the solids S1 and S2"): the common point on the segment P1 Q1 is
//! the mass-weighted one, and both sides move to it; a rigid master takes none of it.

use std::collections::BTreeSet;

use nalgebra::SVector;

use super::EndProjection;
use crate::contact::{ContactKey, ContactPair, Master, MasterId};

/// What the projection reads.
pub(crate) struct ProjectionContext<'a, const D: usize> {
    /// Which points move.
    pub rule: EndProjection,
    /// The active set (implicit projection).
    pub active: &'a BTreeSet<ContactKey>,
    /// The body of every surface facet.
    pub facet_body: &'a [usize],
    /// The nodes of every surface facet.
    pub facets: &'a [[usize; D]],
    /// Lumped nodal masses (kg).
    pub nodal_mass: &'a [f64],
    /// Prescribed velocity components (they do not move).
    pub prescribed: &'a [Option<f64>],
    /// The velocity of obstacle k's surface at a point (m/s).
    pub obstacle_velocity: &'a dyn Fn(usize, &SVector<f64, D>) -> SVector<f64, D>,
    /// The step (s).
    pub time_step: f64,
}

/// An impulse on an obstacle as a force over the step: (obstacle, master point (m), force (N)).
pub(crate) type Applied<const D: usize> = (usize, SVector<f64, D>, SVector<f64, D>);

/// An impulse between two bodies as a force over the step: (slave node, master body, force on
/// the slave (N)); the master's facet nodes receive the opposite.
pub(crate) type BodyImpulse<const D: usize> = (usize, usize, SVector<f64, D>);

/// Projects the points of `pairs` (found in the stored end configuration) that the rule names:
/// moves `u1` (and for [`EndProjection::PenetratingWithVelocity`] removes the approaching
/// normal relative velocity from `v1`, adding the impulse to `contact_forces` as a force, and
/// to `applied` with the point it acts at, or to `between_bodies` for a facet master).
pub(crate) fn project<const D: usize>(
    ctx: &ProjectionContext<'_, D>,
    pairs: &[ContactPair<D>],
    u1: &mut [f64],
    v1: &mut [f64],
    contact_forces: &mut [Vec<f64>],
    applied: &mut Vec<Applied<D>>,
    between_bodies: &mut Vec<BodyImpulse<D>>,
) {
    let h = ctx.time_step;
    for p in pairs {
        let key = match p.master {
            Master::Obstacle(k) => (p.slave, MasterId::Obstacle(k)),
            Master::Facet(f) => (p.slave, MasterId::Body(ctx.facet_body[f])),
        };
        let project = match ctx.rule {
            EndProjection::None => false,
            // Out of the master only: an active point that ends above it stays there.
            EndProjection::Active => ctx.active.contains(&key) && p.gap < 0.0,
            EndProjection::PenetratingWithVelocity => p.gap < 0.0,
        };
        if !project {
            continue;
        }
        let s = p.slave;
        // Master nodes (weights) and the master's velocity.
        let (masters, master_velocity): (Vec<(usize, f64)>, SVector<f64, D>) = match p.master {
            Master::Obstacle(k) => (Vec::new(), (ctx.obstacle_velocity)(k, &p.point)),
            Master::Facet(f) => {
                let w = p.barycentric;
                let list: Vec<(usize, f64)> = (0..D).map(|i| (ctx.facets[f][i], w[i])).collect();
                let mut v = SVector::<f64, D>::zeros();
                for &(n, c) in &list {
                    v += SVector::<f64, D>::from_column_slice(&v1[n * D..n * D + D]) * c;
                }
                (list, v)
            }
        };
        let ms = ctx.nodal_mass[s];
        let mm: f64 = masters.iter().map(|&(n, c)| c * ctx.nodal_mass[n]).sum();
        // The slave takes the part mm / (ms + mm) of the correction, the master the rest.
        let slave_share = if masters.is_empty() || ms + mm <= 0.0 {
            1.0
        } else {
            mm / (ms + mm)
        };
        let correction = -p.normal * p.gap;
        let sum_w2: f64 = masters.iter().map(|&(_, c)| c * c).sum::<f64>().max(1e-300);
        // Moves the slave by its share of `delta` and the master point by the rest, spread
        // over the facet nodes by their weights; prescribed dofs stay.
        let prescribed = ctx.prescribed;
        let share = |values: &mut [f64], delta: &SVector<f64, D>| {
            for k in 0..D {
                if prescribed[s * D + k].is_none() {
                    values[s * D + k] += slave_share * delta[k];
                }
                for &(n, c) in &masters {
                    if prescribed[n * D + k].is_none() {
                        values[n * D + k] -= (1.0 - slave_share) * delta[k] * c / sum_w2;
                    }
                }
            }
        };
        share(u1, &correction);
        if ctx.rule == EndProjection::PenetratingWithVelocity {
            let vs = SVector::<f64, D>::from_column_slice(&v1[s * D..s * D + D]);
            let vn = p.normal.dot(&(vs - master_velocity));
            if vn < 0.0 {
                // One normal impulse J, +J on the slave and -c_i J on the facet's nodes: the
                // relative normal velocity becomes zero and the momentum of the two bodies is
                // kept (J = -vn / (1/ms + sum c_i^2 / m_i); a rigid master: J = -ms vn).
                let inverse_mass = 1.0 / ms
                    + masters
                        .iter()
                        .map(|&(n, c)| c * c / ctx.nodal_mass[n])
                        .sum::<f64>();
                let impulse = -vn / inverse_mass;
                let kicks = ms > 0.0
                    && masters.iter().all(|&(n, _)| ctx.nodal_mass[n] > 0.0)
                    && impulse.is_finite();
                if !kicks {
                    // A massless side (a quasi-static flow): the kinematic share above.
                    share(v1, &(-p.normal * vn));
                    continue;
                }
                let j = p.normal * impulse;
                for k in 0..D {
                    if prescribed[s * D + k].is_none() {
                        v1[s * D + k] += j[k] / ms;
                    }
                    for &(n, c) in &masters {
                        if prescribed[n * D + k].is_none() {
                            v1[n * D + k] -= c * j[k] / ctx.nodal_mass[n];
                        }
                    }
                }
                // The impulse over the step, as a force on the slave.
                let f = j / h;
                match p.master {
                    Master::Obstacle(k) => {
                        for i in 0..D {
                            contact_forces[k][i] += f[i];
                        }
                        applied.push((k, p.point, f));
                    }
                    Master::Facet(facet) => between_bodies.push((s, ctx.facet_body[facet], f)),
                }
            }
        }
    }
}
