//! Issue 14, monitors that speak up: implicit projection's contact-set cycles are reported by
//! `RunMonitor` (see its unit tests for the warning); a calm scene reports none. Overlaps of
//! any depth at t = 0 (a floor drawn the wrong way round, a block in a box, a body in a body)
//! and the fall-through monitor (a block through a thin floor).

mod common;

use common::{block, vec_d};
use softway::contact::{ContactMethod, ContactSettings, Obstacle, ObstacleShape};
use softway::prelude::*;
use softway::simulation::RunMonitor;

/// A block resting on a floor under gravity with implicit projection (the default method):
/// no point is held, no set comes back, and the monitor has nothing to say.
fn a_block_at_rest_makes_no_cycle_warning<const D: usize>()
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let mesh: Mesh<D> = block([0.2, 0.1, 0.2], [4, 2, 4], false);
    let mut g = [0.0; 3];
    g[D - 1] = -9.81;
    let mut up = [0.0; 3];
    up[D - 1] = 1.0;
    let mut sim = Simulation::<D>::builder()
        .time_step(1e-3)
        .gravity(vec_d(g))
        .body(Body::new(
            "block",
            mesh,
            Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap()),
        ))
        .obstacle(Obstacle::new(
            "floor",
            ObstacleShape::Halfspace {
                point: vec_d([0.0; 3]),
                normal: vec_d(up),
            },
        ))
        .contact(ContactSettings {
            method: ContactMethod::ImplicitProjection,
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    let mut monitor = RunMonitor::new(&sim);
    for _ in 0..50 {
        let r = sim.step().unwrap();
        assert_eq!(
            (r.held_contacts, r.contact_cycles),
            (0, 0),
            "step {}",
            r.step
        );
        let news = monitor.step(&sim, &r).unwrap().unwrap_or_default();
        assert!(
            !news.contains("contact set cycled"),
            "step {}: {news}",
            r.step
        );
    }
    let w = monitor.warnings();
    assert!(!w.iter().any(|w| w.contains("contact set cycled")), "{w:?}");
}

// ---------------------------------------------------------------------------------------------
// Overlaps of any depth at t = 0, and the fall-through monitor.

fn elastic() -> Material {
    Material::LinearElastic(LinearElastic::new(1e6, 0.3, 1000.0).unwrap())
}

/// A block [0, 1] x [0, 0.5] (x [0, 1]) moved up by `lift`, 4 x 2 (x 4) cells.
fn lifted_block<const D: usize>(lift: f64) -> Mesh<D>
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let mut mesh: Mesh<D> = block([1.0, 0.5, 1.0], [4, 2, 4], false);
    let mut up = [0.0; 3];
    up[1] = lift;
    mesh.translate(&vec_d(up));
    mesh
}

/// A floor at y = 0 of 8 m by 8 m: a polyline (2D) or two triangles (3D), solid below when
/// `right_way`, above otherwise.
fn facet_floor<const D: usize>(right_way: bool) -> ObstacleShape<D> {
    let (vertices, mut indices): (Vec<[f64; 3]>, Vec<Vec<usize>>) = if D == 2 {
        (vec![[4.0, 0.0, 0.0], [-4.0, 0.0, 0.0]], vec![vec![0, 1]])
    } else {
        // Counter-clockwise seen from above (+y): normal +y.
        (
            vec![
                [-4.0, 0.0, -4.0],
                [-4.0, 0.0, 4.0],
                [4.0, 0.0, 4.0],
                [4.0, 0.0, -4.0],
            ],
            vec![vec![0, 1, 2], vec![0, 2, 3]],
        )
    };
    if !right_way {
        for f in &mut indices {
            f.reverse();
        }
    }
    ObstacleShape::Facets {
        vertices: vertices.into_iter().map(vec_d).collect(),
        indices,
    }
}

fn boundary_nodes<const D: usize>(mesh: &Mesh<D>) -> usize
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    mesh.boundary_nodes().len()
}

/// A block 1.2 m above a floor drawn the wrong way round (solid above) starts inside it, far
/// beyond the reach of contact detection: every boundary node is reported, the deepest 1.7 m
/// away, and `check_overlaps` refuses the scene with the orientation hint. Drawn the right
/// way, nothing is reported.
fn a_reversed_floor_is_found_at_any_depth<const D: usize>()
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    for right_way in [false, true] {
        let mesh = lifted_block::<D>(1.2);
        let nodes = boundary_nodes(&mesh);
        let sim = Simulation::<D>::builder()
            .time_step(1e-3)
            .body(Body::new("block", mesh, elastic()))
            .obstacle(Obstacle::new("floor", facet_floor::<D>(right_way)))
            .contact(ContactSettings {
                method: ContactMethod::SoftWay,
                penalty: 1e10,
                ..ContactSettings::default()
            })
            .build()
            .unwrap();
        let overlaps = sim.overlaps();
        if right_way {
            assert!(overlaps.is_empty(), "{overlaps:?}");
            assert!(sim.check_overlaps().unwrap().is_empty());
            continue;
        }
        assert_eq!(overlaps.len(), 1, "{overlaps:?}");
        let o = &overlaps[0];
        assert_eq!(
            (
                o.body.as_str(),
                o.other.as_str(),
                o.nodes,
                o.beyond_reach,
                o.facets
            ),
            ("block", "obstacle `floor`", nodes, nodes, true)
        );
        assert!((o.depth - 1.7).abs() < 1e-9, "{o:?}");
        assert!((o.reach - sim.detection_reach()).abs() == 0.0 && o.reach < 0.1);
        let e = sim.check_overlaps().unwrap_err();
        assert!(matches!(e, Error::Overlap { .. }), "{e}");
        let m = e.to_string();
        assert!(
            m.starts_with(&format!(
                "body `block` starts inside obstacle `floor`: found {nodes} boundary node(s) \
                 inside at t = 0, {nodes} of them deeper than contact detection reaches"
            )) && m.contains("the deepest 1.700e0 m")
                && m.ends_with("reverse each facet's vertex order"),
            "{m}"
        );
    }
}

/// A block inside a box obstacle, its boundary nodes 0.75 m from the box's faces at most:
/// reported with that depth; a box is found by contact detection at any depth, so it stays a
/// warning.
fn a_block_inside_a_box_is_reported_with_its_depth<const D: usize>()
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let mesh = lifted_block::<D>(0.0);
    let nodes = boundary_nodes(&mesh);
    let sim = Simulation::<D>::builder()
        .time_step(1e-3)
        .body(Body::new("block", mesh, elastic()))
        .obstacle(Obstacle::new(
            "box",
            ObstacleShape::Box {
                center: vec_d([0.5, 0.25, 0.5]),
                half_extents: vec_d([1.0, 1.0, 1.0]),
            },
        ))
        .build()
        .unwrap();
    let overlaps = sim.check_overlaps().unwrap();
    assert_eq!(overlaps.len(), 1, "{overlaps:?}");
    let o = &overlaps[0];
    assert_eq!(
        (o.other.as_str(), o.nodes, o.beyond_reach, o.facets),
        ("obstacle `box`", nodes, 0, false)
    );
    assert!((o.depth - 0.75).abs() < 1e-12, "{o:?}");
    assert!(o.reach.is_infinite());
    assert!(
        o.to_string().starts_with(&format!(
            "body `block` overlaps obstacle `box` at t = 0: {nodes} node(s) inside, the \
                 deepest 7.500e-1 m"
        )),
        "{o}"
    );
}

/// A small block in the middle of a large one, its boundary nodes 0.75 m from the large one's
/// surface: reported with that depth (in the large body's cells, whatever their number), and
/// refused, since contact detection does not reach that deep into a body.
fn a_body_inside_another_is_reported_with_its_depth<const D: usize>()
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let large: Mesh<D> = block([2.0, 2.0, 2.0], [3, 3, 3], false);
    let mut small: Mesh<D> = block([0.5, 0.5, 0.5], [2, 2, 2], true);
    small.translate(&vec_d([0.75, 0.75, 0.75]));
    let nodes = boundary_nodes(&small);
    let sim = Simulation::<D>::builder()
        .time_step(1e-3)
        .body(Body::new("large", large, elastic()))
        .body(Body::new("small", small, elastic()))
        .build()
        .unwrap();
    let overlaps = sim.overlaps();
    assert_eq!(overlaps.len(), 1, "{overlaps:?}");
    let o = &overlaps[0];
    assert_eq!(
        (o.body.as_str(), o.other.as_str(), o.nodes, o.beyond_reach),
        ("small", "body `large`", nodes, nodes)
    );
    assert!((o.depth - 0.75).abs() < 1e-12, "{o:?}");
    let m = sim.check_overlaps().unwrap_err().to_string();
    assert!(
        m.starts_with("body `small` starts inside body `large`:")
            && m.contains("the deepest 7.500e-1 m")
            && !m.contains("polyline"),
        "{m}"
    );
}

/// The lifted block moving down at `speed` (m/s) towards a facet floor drawn the right way,
/// under the soft way.
fn dropped_on_a_facet_floor<const D: usize>(speed: f64) -> Simulation<D>
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let mesh = lifted_block::<D>(0.01);
    let mut v = [0.0; 3];
    v[1] = -speed;
    let mut body = Body::new("block", mesh, elastic());
    body.initial_velocity = vec_d(v);
    Simulation::<D>::builder()
        .time_step(1e-3)
        .body(body)
        .obstacle(Obstacle::new("floor", facet_floor::<D>(true)))
        .contact(ContactSettings {
            method: ContactMethod::SoftWay,
            penalty: 1e10,
            ..ContactSettings::default()
        })
        .build()
        .unwrap()
}

/// A block thrown at 300 m/s onto a thin floor (drawn the right way) crosses it within a
/// step: the soft way's penalty meets it once, then its nodes are beyond the reach of
/// detection, under the floor; the monitor stops the run there (it ran on silently before).
fn a_block_through_a_thin_floor_stops_the_run<const D: usize>()
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let mut sim = dropped_on_a_facet_floor::<D>(300.0);
    assert!(sim.check_overlaps().unwrap().is_empty());
    let mut monitor = RunMonitor::new(&sim);
    let mut stopped = None;
    for _ in 0..10 {
        let r = sim.step().unwrap();
        if let Err(e) = monitor.step(&sim, &r) {
            stopped = Some((r.step, e));
            break;
        }
    }
    let (step, e) = stopped.expect("the monitor stops the run");
    assert!(step <= 3, "step {step}: {e}");
    assert!(matches!(e, Error::FellThrough { .. }), "{e}");
    let m = e.to_string();
    assert!(
        m.starts_with(&format!("fall-through at step {step} (t = "))
            && m.contains("of body `block` ended the step inside obstacle `floor`")
            && m.contains("use a smaller time_step")
            && m.ends_with("reverse each facet's vertex order"),
        "{m}"
    );
}

/// The same block dropped gently onto the floor: no overlap, no fall-through.
fn a_block_landing_on_a_facet_floor_does_not_fall_through<const D: usize>()
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let mut sim = dropped_on_a_facet_floor::<D>(1.0);
    let mut monitor = RunMonitor::new(&sim);
    for _ in 0..40 {
        let r = sim.step().unwrap();
        monitor.step(&sim, &r).unwrap();
        assert!(sim.fell_through().is_none());
    }
}

/// A thin axisymmetric wall (radii 20 and 22 mm, 60 mm) that bulges by 0.1 mm at mid-height
/// and so leans by a hair at both ends (tests/tube_crush.rs's tube), self-contact on: nothing
/// overlaps, and `current_penetration` (history.csv's t = 0 row, the summary's start) says 0.
/// A detector with the monitors' wide margin does pair inner-face nodes near an end with the
/// end face, their normals opposed by a hair, at a negative gap: that false pair is what
/// `current_penetration` reported (0.96 mm on the bundled tube's 1250 cells with the bulge
/// running to the ends) before it was made the deepest of `overlaps`.
#[test]
fn a_wall_leaning_at_its_end_does_not_overlap_itself() {
    use nalgebra::Vector2;
    use softway::contact::detection::{DetectionOptions, Detector};
    let mut mesh = softway::mesh::generators::rectangle(
        Vector2::new(0.02, 0.0),
        Vector2::new(0.022, 0.06),
        [5, 250],
        ElementKind::Quad4,
    )
    .unwrap();
    for x in &mut mesh.nodes {
        x.x += 1e-4 * (std::f64::consts::PI * x.y / 0.06).sin();
    }
    let sim = Simulation::<2>::builder()
        .kinematics(Kinematics::Axisymmetric)
        .time_step(1e-6)
        .body(Body::new("tube", mesh, elastic()))
        .contact(ContactSettings {
            method: ContactMethod::SoftWay,
            penalty: 1e13,
            self_contact: true,
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    assert!(sim.overlaps().is_empty(), "{:?}", sim.overlaps());
    assert_eq!(sim.current_penetration(), 0.0);
    // The false pair, found as the old measure found it (a margin of four mean facets).
    let template = sim.detector().unwrap();
    let options = DetectionOptions {
        margin: 16.0 * template.options().margin,
        ..*template.options()
    };
    let mut wide = Detector::new(template.surface().clone(), options);
    let x = sim.positions();
    wide.update_candidates(&x, &x, &[], &[]);
    let deepest = wide
        .pairs(&x, &[])
        .iter()
        .fold(0.0f64, |m, p| m.max(-p.gap));
    assert!(deepest > 1e-4, "no false self pair: {deepest}");
}

both_dims!(
    a_block_at_rest_makes_no_cycle_warning,
    a_reversed_floor_is_found_at_any_depth,
    a_block_inside_a_box_is_reported_with_its_depth,
    a_body_inside_another_is_reported_with_its_depth,
    a_block_through_a_thin_floor_stops_the_run,
    a_block_landing_on_a_facet_floor_does_not_fall_through,
);
