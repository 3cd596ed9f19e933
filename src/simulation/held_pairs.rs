//! Which detected pairs a contact method holds: both passes between two bodies for the
//! penalty methods; for the projections, one pass plus the other body's nodes beyond the edge
//! of the first one's holding nodes (edge pairs), and one pass within a fold.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::SVector;

use super::body_of;
use crate::contact::methods::Method;
use crate::contact::{ContactKey, ContactPair, Detector, Master, MasterId};
use crate::dim::{Dim, SpatialDim};

/// Self-contact in one pass, for the methods that hold each pair as a constraint: where a
/// fold's two sides are both slaves of each other (node s on a facet holding node m, and m on
/// a facet holding s), the two velocity constraints are (nearly) the same one, and their
/// multipliers split the force arbitrarily, one of them in tension: the active set then
/// releases and re-activates them without end. Of two such pairs only the one with the
/// smaller slave is kept; a side's corner that has no such partner stays a slave.
fn one_pass_self_contact<const D: usize>(
    pairs: &mut Vec<ContactPair<D>>,
    facets: &[[usize; D]],
    facet_body: &[usize],
    offsets: &[usize],
) {
    let body = |node: usize| body_of(offsets, node);
    // The facet each self-contact slave is paired with (one per slave and master body).
    let own: BTreeMap<usize, usize> = pairs
        .iter()
        .filter_map(|p| match p.master {
            Master::Facet(f) if facet_body[f] == body(p.slave) => Some((p.slave, f)),
            _ => None,
        })
        .collect();
    pairs.retain(|p| match p.master {
        Master::Facet(f) if facet_body[f] == body(p.slave) => !facets[f]
            .iter()
            .any(|&m| m < p.slave && own.get(&m).is_some_and(|&g| facets[g].contains(&p.slave))),
        _ => true,
    });
}

/// The gap (relative to the detection margin) up to which a slave node holds the master body's
/// surface where it projects: beyond it the node is off that surface.
const HOLDS_WITHIN_GAP: f64 = 4e-3;
/// The offset along the master's surface (relative to the detection margin) beyond which a
/// slave's closest point is not its normal projection: the node lies beyond the master's edge.
const HOLDS_WITHIN_OFFSET: f64 = 4e-2;

/// Between two bodies under the projections, which node of the body listed first holds the
/// other body's surface: it has a pair against that body whose closest point is its normal
/// projection (not an edge or corner it lies beyond), within `HOLDS_WITHIN_GAP` of it.
fn holding_slaves<const D: usize>(
    pairs: &[ContactPair<D>],
    facet_body: &[usize],
    x: &[SVector<f64, D>],
    margin: f64,
) -> std::collections::BTreeSet<(usize, usize)> {
    pairs
        .iter()
        .filter_map(|p| match p.master {
            Master::Facet(f) if p.gap <= HOLDS_WITHIN_GAP * margin => {
                let offset = x[p.slave] - p.point;
                let along = (offset.norm_squared() - p.gap * p.gap).max(0.0).sqrt();
                (along <= HOLDS_WITHIN_OFFSET * margin).then_some((p.slave, facet_body[f]))
            }
            _ => None,
        })
        .collect()
}

/// The detected pairs the method holds. Between two bodies, the penalty methods keep both
/// passes (each body's nodes against the other's facets, at half the contact area each: the
/// same total stiffness on matching faces, and no corner of either body left unchecked).
///
/// The projections hold each pair as a constraint, and two passes over the same patch hold it
/// twice: node s on a facet around m and m on a facet around s are nearly the same constraint,
/// their multipliers split the force arbitrarily, one in tension, and the active set cycles.
/// So the nodes of the body listed first are slaves, and a node of the other body is a slave
/// too only beyond the edge of the first one's holding nodes: where its closest point on the
/// facet it meets has weight on a node that does not hold the second body's surface
/// (`holding_slaves`). That is the corner of a block resting 1 cm in from the edge of the
/// block below: one pass left it unheld, and it sank 4 mm into the lower block's edge facet
/// (whose outer node holds nothing). Such an edge pair holds the normal only (no friction:
/// `ContactTerms`). Within a fold, of two pairs that hold each other's slave
/// (`one_pass_self_contact`), the one with the smaller slave. Implicit projection's
/// end-of-step projection moves the same pairs that Newton held: moving a dropped pair too (a
/// fold's corner measured against the other side's end vertex) strained the tip out of what
/// Newton solved and put energy in. Explicit projection holds nothing in Newton and projects
/// every pair.
///
/// An active edge pair stays held for the rest of the step once it has been beyond the edge
/// (`edge_held`, the step's record; `active`, the active set), released only by its tension:
/// otherwise the edge rule, read at each iterate, dropped a held pair whose constraint had
/// just pulled its node back across the edge, and took it again at the next iterate (the 3D
/// stack of three soft blocks at step 398: a top-block node in 5 kN of tension, in and out
/// for 50 iterations, in every cut of the step; the run stopped). `x`: the positions the pairs
/// were detected at; `offsets`: the first node of each body.
pub(super) fn held_pairs<const D: usize>(
    method: &dyn Method,
    pairs: &mut Vec<ContactPair<D>>,
    detector: &Detector<D>,
    x: &[SVector<f64, D>],
    offsets: &[usize],
    edge_held: &mut BTreeSet<ContactKey>,
    active: &BTreeSet<ContactKey>,
) where
    Dim<D>: SpatialDim<D>,
{
    if method.symmetric_pairs() || !method.in_newton() {
        return;
    }
    let surface = detector.surface();
    let facet_body = surface.facet_body();
    let body = |node: usize| body_of(offsets, node);
    let holding = holding_slaves(pairs, facet_body, x, detector.options().margin);
    pairs.retain(|p| match p.master {
        Master::Facet(f) => {
            let (slave_body, master_body) = (body(p.slave), facet_body[f]);
            if !edge_pair(method, slave_body, master_body) {
                return true;
            }
            // Beyond the edge: the closest point has weight on a node that holds nothing.
            let beyond = surface.facets()[f]
                .iter()
                .zip(&p.barycentric)
                .any(|(s, &w)| w > 0.0 && !holding.contains(&(*s, slave_body)));
            let key = (p.slave, MasterId::Body(master_body));
            if beyond {
                edge_held.insert(key);
            }
            beyond || (active.contains(&key) && edge_held.contains(&key))
        }
        Master::Obstacle(_) => true,
    });
    one_pass_self_contact(pairs, surface.facets(), facet_body, offsets);
}

/// Whether a pair between deformable bodies is a projection's edge pair (`held_pairs`): its
/// slave in the body listed later. Such a pair is held only beyond the edge of the first
/// body's holding nodes, and holds the normal only.
pub(super) fn edge_pair(method: &dyn Method, slave_body: usize, master_body: usize) -> bool {
    !method.symmetric_pairs() && master_body < slave_body
}
