//! Issue 14, monitors that speak up: implicit projection's contact-set cycles are reported by
//! `RunMonitor` (see its unit tests for the warning); a calm scene reports none. Overlaps of
//! any depth at t = 0 (a floor drawn the wrong way round, a block in a box, a body in a body,
//! a body that overlaps itself), the fall-through monitor (a block through a thin floor) and
//! the tunnelling watch (a block through a thin box, a small ball, a thin closed trimesh
//! within one step).

use crate::common;

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
    let mut sim = common::resting_block::<D>(Material::LinearElastic(
        LinearElastic::new(1e6, 0.3, 1000.0).unwrap(),
    ));
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
/// under the soft way (`soft_way`) or the default contact settings.
fn dropped_on_a_facet_floor<const D: usize>(speed: f64, soft_way: bool) -> Simulation<D>
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
        .contact(if soft_way {
            ContactSettings {
                method: ContactMethod::SoftWay,
                penalty: 1e10,
                ..ContactSettings::default()
            }
        } else {
            ContactSettings::default()
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
    let mut sim = dropped_on_a_facet_floor::<D>(300.0, true);
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

/// The same block thrown at 300 m/s under the default settings: implicit projection holds its
/// boundary nodes on the floor within the first step, and its interior nodes, which contact
/// does not hold, go on through the bottom face, 0.1 to 0.15 m below the floor after one step
/// and 2 m after six. The small-strain law does not resist the fold, and no boundary node is
/// inside the floor: the run went on silently for as long as it was asked to (found
/// 2026-11-30). The monitor stops it at the first step, naming a folded cell.
fn a_block_folded_through_its_own_boundary_stops_the_run<const D: usize>()
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let mut sim = dropped_on_a_facet_floor::<D>(300.0, false);
    assert!(sim.inverted_cell().is_none());
    let mut monitor = RunMonitor::new(&sim);
    let r = sim.step().unwrap();
    let e = monitor
        .step(&sim, &r)
        .expect_err("the monitor stops the run");
    let m = e.to_string();
    assert!(
        matches!(e, Error::TurnedInsideOut { step: 1, ref body, .. } if body == "block"),
        "{m}"
    );
    assert!(
        m.starts_with("a cell turned inside out at step 1 (t = 1.000000e-3 s): cell ")
            && m.contains("of body `block` near (")
            && m.contains("use a smaller time_step"),
        "{m}"
    );
    let (_, cell, centre) = sim.inverted_cell().unwrap();
    let depth = -centre[1];
    eprintln!("D = {D}: cell {cell} turned inside out, its centre {depth:.3e} m below the floor");
}

/// The same block dropped gently onto the floor, under either method: no overlap, no
/// fall-through, no cell turned inside out.
fn a_block_landing_on_a_facet_floor_does_not_fall_through<const D: usize>()
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    for soft_way in [true, false] {
        let mut sim = dropped_on_a_facet_floor::<D>(1.0, soft_way);
        let mut monitor = RunMonitor::new(&sim);
        for _ in 0..40 {
            let r = sim.step().unwrap();
            monitor.step(&sim, &r).unwrap();
            assert!(sim.fell_through().is_none());
        }
    }
}

/// A thin axisymmetric wall (radii 20 and 22 mm, 60 mm) that bulges by 0.1 mm at mid-height
/// and so leans by a hair at both ends (tests/tube_crush.rs's tube), self-contact on: nothing
/// overlaps, and `current_penetration` (history.csv's t = 0 row, the summary's start) says 0.
/// A detector with the monitors' old wide margin paired inner-face nodes near an end with the
/// end face, their normals opposed by a hair, at a negative gap: that false pair is what
/// `current_penetration` reported (0.96 mm on the bundled tube's 1250 cells with the bulge
/// running to the ends) before it was made the deepest of `overlaps`. Detection now rejects
/// it too (a node beside its own corner: the self-contact rule of `detection.rs`).
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
    // Nor does detection with the old measure's reach (a margin of four mean facets): the
    // inner face's nodes near the end lie behind the end face beside their own corner, which
    // the self-contact rule rejects (it found them 0.96 mm deep before).
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
    assert!(deepest < 1e-9, "a false self pair {deepest} m deep");
}

/// A block [0, 1] x [0.1, 0.6] (x [0, 1]) moving down at `speed` (m/s) with steps of `h` (s)
/// towards `plate` (implicit projection, the default method).
fn thrown_at<const D: usize>(plate: ObstacleShape<D>, speed: f64, h: f64) -> Simulation<D>
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let mut v = [0.0; 3];
    v[1] = -speed;
    let mut body = Body::new("block", lifted_block::<D>(0.1), elastic());
    body.initial_velocity = vec_d(v);
    Simulation::<D>::builder()
        .time_step(h)
        .body(body)
        .obstacle(Obstacle::new("plate", plate))
        .build()
        .unwrap()
}

/// A plate 4 cm thick (8 m wide) with its top at y = 0.02.
fn thin_box<const D: usize>() -> ObstacleShape<D> {
    ObstacleShape::Box {
        center: vec_d([0.5, 0.0, 0.5]),
        half_extents: vec_d([4.0, 0.02, 4.0]),
    }
}

/// The steps of `sim` until the monitor stops it (at most `steps`): (step, error).
fn run_monitored<const D: usize>(sim: &mut Simulation<D>, steps: usize) -> Option<(usize, Error)>
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let mut monitor = RunMonitor::new(sim);
    for _ in 0..steps {
        let r = sim.step().unwrap();
        if let Err(e) = monitor.step(sim, &r) {
            return Some((r.step, e));
        }
    }
    None
}

/// The bottom of a block thrown at 5 m/s with steps of 0.1 s goes from 8 cm above a plate 4
/// cm thick to 42 cm under it in the first step: no node ends inside the plate, nothing is
/// detected, and the block would fly on under it; the tunnelling watch stops the run at that
/// step, naming the body, the plate, the speed and the cause. With steps of 1 ms the block
/// lands on the plate and nothing is said.
fn a_block_through_a_thin_box_stops_the_run<const D: usize>()
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let mut sim = thrown_at::<D>(thin_box(), 5.0, 0.1);
    assert!(sim.check_overlaps().unwrap().is_empty());
    let (step, e) = run_monitored(&mut sim, 3).expect("the watch stops the run");
    assert_eq!(step, 1, "{e}");
    let Error::Tunnelled {
        ref body,
        ref other,
        nodes,
        speed,
        travel,
        inside,
        crossing_time,
        ..
    } = e
    else {
        panic!("{e}");
    };
    // The boundary nodes below y = 0.48 (the bottom and the middle layer): 5 + 2 in 2D,
    // 25 + 16 in 3D.
    let bottom = if D == 2 { 7 } else { 41 };
    assert_eq!(
        (body.as_str(), other.as_str(), nodes),
        ("block", "obstacle `plate`", bottom)
    );
    assert!(
        (speed - 5.0).abs() < 1e-6 && (travel - 0.5).abs() < 1e-7,
        "{e}"
    );
    assert!((inside - 0.04).abs() < 1e-9, "{e}");
    assert!((crossing_time - 8e-3).abs() < 1e-9, "{e}");
    let m = e.to_string();
    assert!(
        m.starts_with(&format!(
            "tunnelling at step 1 (t = 1.000000e-1 s): {bottom} node(s) of body `block` passed \
             through obstacle `plate` within the step and ended outside it on the far side, \
             where contact detection does not see them (node "
        )) && m.contains(" at 5.000e0 m/s relative to it: 5.000e-1 m in the step, 4.000e-2 m of it inside); the step is too long for the speed: the body crossed the obstacle in one step; use a smaller time_step (well below the 8.000e-3 s the crossing took) or a thicker obstacle"),
        "{m}"
    );
    let mut sim = thrown_at::<D>(thin_box(), 5.0, 1e-3);
    assert!(run_monitored(&mut sim, 40).is_none());
    // It landed: its bottom is on the plate, not under it.
    let lowest = sim
        .positions()
        .iter()
        .map(|x| x[1])
        .fold(f64::INFINITY, f64::min);
    assert!(lowest > 0.0, "{lowest}");
}

/// A small ball (radius 5 cm) and a thin closed trimesh plate (3D; a closed polyline in 2D),
/// crossed within one step: the same stop.
fn a_block_through_a_small_ball_or_a_closed_plate_stops_the_run<const D: usize>()
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let ball = ObstacleShape::Ball {
        center: vec_d([0.5, -0.05, 0.5]),
        radius: 0.05,
    };
    // A box 4 cm thick as facets: its 2D outline counter-clockwise, its 3D faces
    // counter-clockwise seen from outside.
    let (lo, hi) = (
        vec_d::<D>([-4.0, -0.02, -4.0]),
        vec_d::<D>([4.0, 0.02, 4.0]),
    );
    let closed = if D == 2 {
        ObstacleShape::Facets {
            vertices: vec![
                vec_d([lo[0], lo[1], 0.0]),
                vec_d([hi[0], lo[1], 0.0]),
                vec_d([hi[0], hi[1], 0.0]),
                vec_d([lo[0], hi[1], 0.0]),
            ],
            indices: vec![vec![0, 1], vec![1, 2], vec![2, 3], vec![3, 0]],
        }
    } else {
        let mut mesh: Mesh<3> = block([1.0, 1.0, 1.0], [1, 1, 1], true);
        for x in &mut mesh.nodes {
            for k in 0..3 {
                x[k] = lo[k] + x[k] * (hi[k] - lo[k]);
            }
        }
        let faces: Vec<Vec<usize>> = mesh.boundary_faces().into_iter().map(|f| f.nodes).collect();
        ObstacleShape::Facets {
            vertices: mesh
                .nodes
                .iter()
                .map(|x| vec_d([x[0], x[1], x[2]]))
                .collect(),
            indices: faces,
        }
    };
    for (shape, expected) in [(ball, 1), (closed, if D == 2 { 7 } else { 41 })] {
        let mut sim = thrown_at::<D>(shape, 5.0, 0.1);
        assert!(sim.check_overlaps().unwrap().is_empty());
        let (step, e) = run_monitored(&mut sim, 3).expect("the watch stops the run");
        assert_eq!(step, 1, "{e}");
        let Error::Tunnelled { nodes, .. } = e else {
            panic!("{e}");
        };
        assert!(nodes >= expected, "{e}");
    }
}

/// A block that slides along a thin plate, rests on it, and one that rides a box turning
/// and moving under it: nothing passes through, nothing is said.
fn sliding_and_riding_are_not_tunnelling<const D: usize>()
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    // Sliding at 2 m/s along the plate's top, under gravity, steps of 10 ms.
    let mut v = [0.0; 3];
    v[0] = 2.0;
    let mut g = [0.0; 3];
    g[1] = -9.81;
    let mut body = Body::new("block", lifted_block::<D>(0.02), elastic());
    body.initial_velocity = vec_d(v);
    let mut sim = Simulation::<D>::builder()
        .time_step(1e-2)
        .gravity(vec_d(g))
        .body(body)
        .obstacle(Obstacle::new("plate", thin_box()))
        .build()
        .unwrap();
    assert!(run_monitored(&mut sim, 60)
        .map(|(_, e)| e.to_string())
        .is_none());
    // On a ball (radius 0.3 m) turning at 20 rad/s and moving sideways at 1 m/s.
    let mut body = Body::new("block", lifted_block::<D>(0.3), elastic());
    body.initial_velocity = vec_d([1.0, 0.0, 0.0]);
    let mut omega = vec![20.0];
    if D == 3 {
        omega = vec![0.0, 0.0, 20.0];
    }
    let mut sim = Simulation::<D>::builder()
        .time_step(1e-2)
        .gravity(vec_d(g))
        .body(body)
        .obstacle(
            Obstacle::new(
                "drum",
                ObstacleShape::Ball {
                    center: vec_d([0.5, 0.0, 0.5]),
                    radius: 0.3,
                },
            )
            .with_velocity(vec_d([1.0, 0.0, 0.0]))
            .with_angular_velocity(&omega),
        )
        .build()
        .unwrap();
    assert!(run_monitored(&mut sim, 60)
        .map(|(_, e)| e.to_string())
        .is_none());
}

/// Bends a strip lying along x (its thickness along y, from 0) about the centre (xc, r0) at
/// x = xc: the part beyond turns by `turn` (rad) at the rate 1 / r0 along x, then goes on
/// straight along the tangent; every cell keeps its orientation while y < r0.
fn bend<const D: usize>(mesh: &mut Mesh<D>, xc: f64, r0: f64, turn: f64)
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    for x in &mut mesh.nodes {
        let s = x[0] - xc;
        if s <= 0.0 {
            continue;
        }
        let r = r0 - x[1];
        let theta = (s / r0).min(turn);
        let along = (s - r0 * turn).max(0.0);
        x[0] = xc + r * theta.sin() + along * theta.cos();
        x[1] = r0 - r * theta.cos() + along * theta.sin();
    }
}

/// A body whose mesh overlaps itself: a strip 3 m x 0.25 m (x 0.25 m) of 24 x 2 (x 2) cells
/// bent up and back about x = 1 by half a turn and 0.6 rad more, so that its end comes down
/// through its first metre (in 3D, two cells across z: nodes on the faces z = 0 and 0.25 lie
/// on the other arm's faces, not inside it). Reported as overlapping itself, and refused since nodes are
/// deeper than detection reaches; bent by half a turn only (its arms 9 cm apart), nothing is
/// reported.
fn a_body_overlapping_itself_is_refused<const D: usize>()
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    for folded in [false, true] {
        let mut mesh: Mesh<D> = block([3.0, 0.25, 0.25], [24, 2, 2], false);
        let pi = std::f64::consts::PI;
        bend(&mut mesh, 1.0, 0.3, if folded { pi + 0.6 } else { pi });
        let sim = Simulation::<D>::builder()
            .time_step(1e-3)
            .body(Body::new("strip", mesh, elastic()))
            .obstacle(Obstacle::new(
                "floor",
                ObstacleShape::Halfspace {
                    point: vec_d([0.0, -1.0, 0.0]),
                    normal: vec_d([0.0, 1.0, 0.0]),
                },
            ))
            .build()
            .unwrap();
        let overlaps = sim.overlaps();
        if !folded {
            assert!(overlaps.is_empty(), "{overlaps:?}");
            continue;
        }
        assert_eq!(overlaps.len(), 1, "{overlaps:?}");
        let o = &overlaps[0];
        assert_eq!((o.body.as_str(), o.other.as_str()), ("strip", "itself"));
        assert!(o.beyond_reach > 0 && o.depth > o.reach, "{o:?}");
        let e = sim.check_overlaps().unwrap_err();
        assert!(matches!(e, Error::Overlap { .. }), "{e}");
        let m = e.to_string();
        assert!(
            m.starts_with("body `strip` starts inside itself: found ")
                && m.ends_with(
                    "move the bodies apart in the scene; or rather, since it overlaps itself, \
                     fix its mesh: cells of one part of it lie over cells of another (a mesh \
                     folded onto itself, arms that cross)"
                ),
            "{m}"
        );
    }
}

/// Meshes in tight contact with themselves but not overlapping: a thin ring (an annulus of
/// 64 x 2 cells, whose first and last columns share their nodes) and a strip 1 m x 1 cm of
/// 100 x 2 cells bent into a hairpin whose arms are 1 mm apart (inner radius 0.5 mm); nothing
/// is reported.
#[test]
fn tight_folds_do_not_overlap_themselves() {
    use nalgebra::Vector2;
    let ring = softway::mesh::generators::annulus(
        Vector2::zeros(),
        0.1,
        0.102,
        [64, 2],
        ElementKind::Quad4,
    )
    .unwrap();
    let mut hairpin = softway::mesh::generators::rectangle(
        Vector2::new(0.0, 0.0),
        Vector2::new(1.0, 0.01),
        [100, 2],
        ElementKind::Quad4,
    )
    .unwrap();
    bend(&mut hairpin, 0.5, 0.0105, std::f64::consts::PI);
    for (name, mesh) in [("ring", ring), ("hairpin", hairpin)] {
        let sim = Simulation::<2>::builder()
            .time_step(1e-4)
            .body(Body::new(name, mesh, elastic()))
            .contact(ContactSettings {
                self_contact: true,
                ..ContactSettings::default()
            })
            .build()
            .unwrap();
        assert!(sim.overlaps().is_empty(), "{name}: {:?}", sim.overlaps());
    }
}

both_dims!(
    a_block_through_a_thin_box_stops_the_run,
    a_block_through_a_small_ball_or_a_closed_plate_stops_the_run,
    sliding_and_riding_are_not_tunnelling,
    a_body_overlapping_itself_is_refused,
    a_block_at_rest_makes_no_cycle_warning,
    a_reversed_floor_is_found_at_any_depth,
    a_block_inside_a_box_is_reported_with_its_depth,
    a_body_inside_another_is_reported_with_its_depth,
    a_block_through_a_thin_floor_stops_the_run,
    a_block_folded_through_its_own_boundary_stops_the_run,
    a_block_landing_on_a_facet_floor_does_not_fall_through,
);
