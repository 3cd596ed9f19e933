//! rapier's broad phase (`BroadPhaseBvh`, rapier3d-f64 0.36) against softway's contact
//! detection (`Detector::update_candidates`, a parry BVH) on the surfaces of
//! `benches/detection.rs`: closed cube-spheres of 12 n^2 triangles, every vertex moved by up to
//! 0.17 mean edge lengths over the step, self-contact on, margin 0.
//!
//! Both sides get the same swept boxes (a node's segment from x0 to x1, a facet's six
//! points) and alternate between two motions, so that every box moves at every update. rapier
//! has one collider per slave node and one per facet, with the boxes given by `set_aabb`
//! (its own boxes would come from each collider's shape and pose), collision groups that keep
//! node-node and facet-facet pairs out (its tree still finds them, its filter drops them), and
//! reports the pairs as add/delete events, which a host keeps in a set. It knows no adjacency:
//! a node's own facets are pairs too, and its fat boxes (a skin of 4 % of `length_unit`, set
//! to the mean edge) find pairs early. softway's detector finds node-facet candidates only,
//! without a node's own facets and their neighbours.
//!
//! Run (from `benches/compare/rapier`; its own workspace, out of softway's build and CI):
//! `cargo run --release --bin broad_phase -- [SUBDIVISIONS...]` (default 29 91: 10,092 and 99,372 facets).
//! Prints the median of 15 updates per side and the ratio.

use std::collections::HashSet;
use std::time::Instant;

use nalgebra::Vector3;
use rapier3d_f64::prelude::*;
use softway::contact::detection::{ContactSurface, DetectionOptions, Detector};

#[path = "../../../../common/sphere.rs"]
mod sphere;
use sphere::{cube_sphere, mean_edge, motion};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn aabb(points: impl Iterator<Item = Vector3<f64>>) -> Aabb {
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(f64::NEG_INFINITY),
    );
    for p in points {
        lo = lo.inf(&p);
        hi = hi.sup(&p);
    }
    Aabb::new(Vector::new(lo.x, lo.y, lo.z), Vector::new(hi.x, hi.y, hi.z))
}

const UPDATES: usize = 15;

fn compare(n: usize) {
    let (x0, tris) = cube_sphere(n);
    let edge = mean_edge(&x0, &tris);
    let motions = [motion(&x0, &tris, 1), motion(&x0, &tris, 2)];
    let nodes = x0.len();

    // softway: node-facet candidates, self-contact on, margin 0 and one mean edge.
    let surface = ContactSurface::from_facets(std::slice::from_ref(&tris), &[0]);
    let softway = |margin: f64| {
        let options = DetectionOptions {
            self_contact: true,
            margin,
            ..Default::default()
        };
        let mut detector = Detector::new(surface.clone(), options);
        let t = Instant::now();
        detector.update_candidates(&x0, &motions[0], &[], &[]);
        let first = t.elapsed().as_secs_f64();
        let mut times = Vec::new();
        for k in 0..UPDATES {
            let t = Instant::now();
            detector.update_candidates(&x0, &motions[(k + 1) % 2], &[], &[]);
            times.push(t.elapsed().as_secs_f64());
        }
        (median(times), first, detector.candidates().len())
    };
    let (softway_time, softway_first, softway_candidates) = softway(0.0);
    let (wide_time, _, wide_candidates) = softway(edge);

    // rapier: one collider per node (handles 0..nodes) and per facet, boxes set by hand.
    // The fat-box skin is 4 % of the length unit: a mesh edge here, not a metre.
    let params = IntegrationParameters {
        length_unit: edge,
        ..Default::default()
    };
    let bodies = RigidBodySet::new();
    let mut colliders = ColliderSet::new();
    // Colliders without a body are fixed: every pair type on, and groups that keep node-node
    // and facet-facet pairs out (rapier's filter, applied after its tree finds them).
    let nodes_meet_facets =
        InteractionGroups::new(Group::GROUP_1, Group::GROUP_2, InteractionTestMode::And);
    let facets_meet_nodes =
        InteractionGroups::new(Group::GROUP_2, Group::GROUP_1, InteractionTestMode::And);
    let mut handles: Vec<ColliderHandle> = Vec::with_capacity(nodes + tris.len());
    for p in &x0 {
        handles.push(
            colliders.insert(
                ColliderBuilder::ball(1e-9)
                    .translation(Vector::new(p.x, p.y, p.z))
                    .active_collision_types(ActiveCollisionTypes::all())
                    .collision_groups(nodes_meet_facets),
            ),
        );
    }
    for t in &tris {
        let v = |i: usize| Vector::new(x0[t[i]].x, x0[t[i]].y, x0[t[i]].z);
        handles.push(
            colliders.insert(
                ColliderBuilder::triangle(v(0), v(1), v(2))
                    .active_collision_types(ActiveCollisionTypes::all())
                    .collision_groups(facets_meet_nodes),
            ),
        );
    }
    let mut broad_phase = BroadPhaseBvh::new();
    let mut events = Vec::new();
    let mut pairs: HashSet<(ColliderHandle, ColliderHandle)> = HashSet::new();
    let mut rapier_update =
        |x1: &[Vector3<f64>],
         broad_phase: &mut BroadPhaseBvh,
         pairs: &mut HashSet<(ColliderHandle, ColliderHandle)>| {
            for (i, h) in handles.iter().enumerate() {
                let b = if i < nodes {
                    aabb([x0[i], x1[i]].into_iter())
                } else {
                    let t = tris[i - nodes];
                    aabb(t.iter().flat_map(|&v| [x0[v], x1[v]]))
                };
                broad_phase.set_aabb(&params, *h, b);
            }
            events.clear();
            broad_phase.update(&params, &colliders, &bodies, &[], &[], &mut events);
            for e in &events {
                match e {
                    BroadPhasePairEvent::AddPair(p) => {
                        pairs.insert((p.collider1, p.collider2));
                    }
                    BroadPhasePairEvent::DeletePair(p) => {
                        pairs.remove(&(p.collider1, p.collider2));
                        pairs.remove(&(p.collider2, p.collider1));
                    }
                }
            }
        };
    let t = Instant::now();
    rapier_update(&motions[0], &mut broad_phase, &mut pairs);
    let rapier_first = t.elapsed().as_secs_f64();
    let mut rapier_times = Vec::new();
    for k in 0..UPDATES {
        let t = Instant::now();
        rapier_update(&motions[(k + 1) % 2], &mut broad_phase, &mut pairs);
        rapier_times.push(t.elapsed().as_secs_f64());
    }
    let is_node = |h: &ColliderHandle| (h.into_raw_parts().0 as usize) < nodes;
    let node_facet = pairs
        .iter()
        .filter(|(a, b)| is_node(a) != is_node(b))
        .count();

    let (s, r) = (softway_time, median(rapier_times));
    println!(
        "{} facets, {nodes} nodes: softway {:.2} ms per update (first {:.1} ms), {softway_candidates} \
         node-facet candidates; rapier {:.2} ms (first {:.1} ms), {} pairs of which {node_facet} \
         node-facet; rapier / softway = {:.2}; softway with a margin of one edge {:.2} ms, \
         {wide_candidates} candidates",
        tris.len(),
        s * 1e3,
        softway_first * 1e3,
        r * 1e3,
        rapier_first * 1e3,
        pairs.len(),
        r / s,
        wide_time * 1e3
    );
}

fn main() {
    let sizes: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let sizes = if sizes.is_empty() {
        vec![29, 91]
    } else {
        sizes
    };
    println!(
        "one thread each (RAYON_NUM_THREADS=1 for softway's parallel detection if the feature is on); \
         median of {UPDATES} updates"
    );
    for n in sizes {
        compare(n);
    }
}
