//! Contact detection: broad and narrow phase against brute force, self-contact of a folded
//! strip, a fast thin body, and hand-computed gaps, normals and barycentrics.
//! Each generic check runs in 2D and 3D through `dims!`.

use nalgebra::{SVector, Vector2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use softway::contact::detection::{
    ContactPair, ContactSurface, DetectionOptions, Detector, Feature, Master,
};
use softway::contact::{Obstacle, ObstacleShape};
use softway::dim::{Dim, SpatialDim};
use softway::element::ElementKind;
use softway::geometry::{Aabb, GeometryDim};
use softway::mesh::generators::{annulus, cuboid, rectangle};
use softway::mesh::Mesh;

/// Dimension-specific meshes for the generic checks.
trait TestDim<const D: usize> {
    /// The box `[min, max]`, `cells` per side, simplices or not.
    fn block(min: [f64; D], max: [f64; D], cells: [usize; D], simplex: bool) -> Mesh<D>;
    /// A curved body (2D: an annulus; 3D: a tet block).
    fn curved(center: [f64; D]) -> Mesh<D>;
}

impl TestDim<2> for Dim<2> {
    fn block(min: [f64; 2], max: [f64; 2], cells: [usize; 2], simplex: bool) -> Mesh<2> {
        let kind = if simplex {
            ElementKind::Tri3
        } else {
            ElementKind::Quad4
        };
        rectangle(Vector2::from(min), Vector2::from(max), cells, kind).unwrap()
    }
    fn curved(c: [f64; 2]) -> Mesh<2> {
        annulus(Vector2::from(c), 0.2, 0.4, [16, 2], ElementKind::Quad4).unwrap()
    }
}

impl TestDim<3> for Dim<3> {
    fn block(min: [f64; 3], max: [f64; 3], cells: [usize; 3], simplex: bool) -> Mesh<3> {
        let kind = if simplex {
            ElementKind::Tet4
        } else {
            ElementKind::Hex8
        };
        cuboid(Vector3::from(min), Vector3::from(max), cells, kind).unwrap()
    }
    fn curved(c: [f64; 3]) -> Mesh<3> {
        let min = c.map(|v| v - 0.3);
        let max = c.map(|v| v + 0.3);
        Self::block(min, max, [2, 2, 2], true)
    }
}

/// Runs a generic check in 2D and 3D.
macro_rules! dims {
    ($($name:ident => $f:ident;)*) => {
        mod d2 { use super::*; $(#[test] fn $name() { $f::<2>(); })* }
        mod d3 { use super::*; $(#[test] fn $name() { $f::<3>(); })* }
    };
}

dims! {
    random_deformed_meshes_match_brute_force => random_matches_brute_force;
    folding_strip_finds_self_contact => folding_strip;
    thin_body_fast_is_caught => thin_body_fast;
    a_node_beside_its_own_corner_touches_nothing => node_beside_own_corner;
    a_lone_body_without_self_contact_queries_no_facets => lone_body;
}

/// One body without self-contact: no facet can be a master, so the broad phase builds no
/// facet hierarchy (a third of a small cube's run went to it), and the candidates are the
/// obstacle candidates that the full search finds.
fn lone_body<const D: usize>()
where
    Dim<D>: SpatialDim<D> + TestDim<D>,
{
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mesh = <Dim<D>>::block([0.0; D], [1.0; D], [4; D], true);
    let x0 = mesh.nodes.clone();
    let x1: Vec<SVector<f64, D>> = x0
        .iter()
        .map(|x| x + SVector::<f64, D>::from_fn(|_, _| rng.random_range(-0.2..0.05)))
        .collect();
    let obstacles = vec![Obstacle::new(
        "floor",
        ObstacleShape::Halfspace {
            point: e::<D>(D - 1) * 0.1,
            normal: e::<D>(D - 1),
        },
    )];
    let poses = vec![SVector::<f64, D>::zeros()];
    let options = |self_contact| DetectionOptions {
        self_contact,
        margin: 0.3,
        deformable_pairs: true,
        hysteresis: 0.0,
        facing: false,
        lock_flipping_facets: false,
    };
    let surface = ContactSurface::from_bodies(&[&mesh], &[0]);
    let mut lone = Detector::new(surface.clone(), options(false));
    lone.update_candidates(&x0, &x1, &obstacles, &poses);
    let mut full = Detector::new(surface, options(true));
    full.update_candidates(&x0, &x1, &obstacles, &poses);
    assert!(lone.facet_boxes().is_empty());
    assert!(!full.facet_boxes().is_empty());
    let obstacle_candidates: Vec<_> = full
        .candidates()
        .iter()
        .filter(|(_, m)| matches!(m, Master::Obstacle(_)))
        .copied()
        .collect();
    assert!(!obstacle_candidates.is_empty());
    assert!(full.candidates().len() > obstacle_candidates.len());
    assert_eq!(lone.candidates(), &obstacle_candidates[..]);
}

fn e<const D: usize>(k: usize) -> SVector<f64, D> {
    let mut v = SVector::zeros();
    v[k] = 1.0;
    v
}

/// Concatenates the bodies' nodes; returns positions and node offsets.
fn stack<const D: usize>(meshes: &[&Mesh<D>]) -> (Vec<SVector<f64, D>>, Vec<usize>) {
    let mut x = Vec::new();
    let mut offsets = Vec::new();
    for m in meshes {
        offsets.push(x.len());
        x.extend_from_slice(&m.nodes);
    }
    (x, offsets)
}

fn seg_box<const D: usize>(a: &SVector<f64, D>, b: &SVector<f64, D>) -> Aabb<D> {
    Aabb {
        min: a.inf(b),
        max: a.sup(b),
    }
}

/// Independent exclusion rule: the facet shares a node with a facet that holds the node.
fn excluded<const D: usize>(facets: &[[usize; D]], node: usize, f: usize) -> bool {
    facets
        .iter()
        .filter(|g| g.contains(&node))
        .any(|g| g.iter().any(|v| facets[f].contains(v)))
}

/// Brute force: the obstacle predicates of the broad phase, written out.
fn brute_obstacle_overlap<const D: usize>(
    o: &Obstacle<D>,
    t1: &SVector<f64, D>,
    seg: &Aabb<D>,
    margin: f64,
) -> bool {
    let (lo, hi) = (o.translation.inf(t1), o.translation.sup(t1));
    match &o.shape {
        ObstacleShape::Halfspace { point, normal } => {
            let n = normal.normalize();
            // Lowest corner of the box along n.
            let corner =
                SVector::<f64, D>::from_fn(|k, _| if n[k] > 0.0 { seg.min[k] } else { seg.max[k] });
            [o.translation, *t1]
                .iter()
                .any(|t| (corner - point - t).dot(&n) < margin)
        }
        ObstacleShape::Box {
            center,
            half_extents,
        } => Aabb {
            min: center + lo - half_extents,
            max: center + hi + half_extents,
        }
        .loosened(margin)
        .intersects(seg),
        ObstacleShape::Ball { center, radius } => {
            Aabb {
                min: center + lo,
                max: center + hi,
            }
            .distance(seg)
                <= radius + margin
        }
        ObstacleShape::Facets { vertices, indices } => indices.iter().any(|f| {
            let b = Aabb::from_points(f.iter().map(|&i| &vertices[i]));
            Aabb {
                min: b.min + lo,
                max: b.max + hi,
            }
            .loosened(margin)
            .intersects(seg)
        }),
    }
}

/// Brute force closest facet: minimum distance, ties broken by the largest gap, then the
/// lowest index.
fn brute_choose<const D: usize>(
    p: &SVector<f64, D>,
    facets: impl Iterator<Item = (usize, [SVector<f64, D>; D])>,
    accept: impl Fn(&SVector<f64, D>) -> bool,
    keep: impl Fn(usize, f64, f64) -> bool,
) -> Option<(usize, f64, SVector<f64, D>, Feature)>
where
    Dim<D>: SpatialDim<D>,
{
    let mut all = Vec::new();
    for (f, v) in facets {
        let (m, n) = <Dim<D>>::facet_measure_normal(&v);
        if m <= 0.0 || !accept(&n) {
            continue;
        }
        let pr = <Dim<D> as GeometryDim<D>>::project_on_facet(p, &v).unwrap();
        if !keep(f, (p - pr.point).dot(&n), (p - pr.point).norm()) {
            continue;
        }
        all.push((
            f,
            (p - pr.point).norm(),
            (p - pr.point).dot(&n),
            n,
            pr.feature,
            (v[1] - v[0]).norm(),
        ));
    }
    let dmin = all.iter().map(|a| a.1).fold(f64::INFINITY, f64::min);
    let tied = all
        .iter()
        .filter(|a| a.1 <= dmin + 1e-9 * a.5.max(a.1) * 2.0);
    // First of the largest gap among the tied facets (they come in index order).
    let mut best = None;
    for a in tied {
        if best.is_none_or(|b: (usize, f64, SVector<f64, D>, Feature)| a.2 > b.1) {
            best = Some((a.0, a.2, a.3, a.4));
        }
    }
    best
}

/// Shortest paths (m) along the facets' edges from `node` to every node (Dijkstra, by
/// linear scans).
fn surface_distances<const D: usize>(
    facets: &[[usize; D]],
    x: &[SVector<f64, D>],
    node: usize,
) -> Vec<f64> {
    let mut dist = vec![f64::INFINITY; x.len()];
    let mut done = vec![false; x.len()];
    dist[node] = 0.0;
    while let Some(u) = (0..x.len())
        .filter(|&v| !done[v] && dist[v].is_finite())
        .min_by(|&a, &b| dist[a].total_cmp(&dist[b]))
    {
        done[u] = true;
        for f in facets.iter().filter(|f| f.contains(&u)) {
            for &v in f {
                dist[v] = dist[v].min(dist[u] + (x[v] - x[u]).norm());
            }
        }
    }
    dist
}

fn brute_obstacle_gap<const D: usize>(o: &Obstacle<D>, p: &SVector<f64, D>) -> f64
where
    Dim<D>: SpatialDim<D>,
{
    let q = p - o.translation;
    match &o.shape {
        ObstacleShape::Halfspace { point, normal } => (q - point).dot(&normal.normalize()),
        ObstacleShape::Ball { center, radius } => (q - center).norm() - radius,
        ObstacleShape::Box {
            center,
            half_extents,
        } => {
            let y = q - center;
            let out = SVector::<f64, D>::from_fn(|k, _| (y[k].abs() - half_extents[k]).max(0.0));
            if out.norm() > 0.0 {
                out.norm()
            } else {
                -(0..D)
                    .map(|k| half_extents[k] - y[k].abs())
                    .fold(f64::INFINITY, f64::min)
            }
        }
        ObstacleShape::Facets { vertices, indices } => {
            let fs = indices
                .iter()
                .enumerate()
                .map(|(i, f)| (i, std::array::from_fn(|k| vertices[f[k]])));
            brute_choose(&q, fs, |_| true, |_, _, _| true).unwrap().1
        }
    }
}

fn random_matches_brute_force<const D: usize>()
where
    Dim<D>: SpatialDim<D> + TestDim<D>,
{
    for seed in 0..3u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let a = <Dim<D>>::block([0.0; D], [1.0; D], [4; D], false);
        let mut bmin = [0.0; D];
        bmin[0] = 0.8;
        let mut bmax = [1.0; D];
        bmax[0] = 1.8;
        let b = <Dim<D>>::block(bmin, bmax, [3; D], true);
        let mut cc = [0.5; D];
        cc[D - 1] = 1.3;
        let c = <Dim<D>>::curved(cc);
        let (mut x0, offsets) = stack(&[&a, &b, &c]);
        for x in x0.iter_mut() {
            *x += SVector::<f64, D>::from_fn(|_, _| rng.random_range(-0.03..0.03));
        }
        let x1: Vec<SVector<f64, D>> = x0
            .iter()
            .map(|x| x + SVector::<f64, D>::from_fn(|_, _| rng.random_range(-0.1..0.1)))
            .collect();
        let tool = <Dim<D>>::block([0.3; D], [0.6; D], [2; D], true);
        let tool_facets = tool.boundary_facets();
        let mut tool_shift = SVector::<f64, D>::zeros();
        tool_shift[D - 1] = -0.5;
        let obstacles = vec![
            Obstacle::new(
                "floor",
                ObstacleShape::Halfspace {
                    point: e::<D>(D - 1) * 0.05,
                    normal: e::<D>(D - 1) * 2.0,
                },
            ),
            Obstacle::new(
                "ball",
                ObstacleShape::Ball {
                    center: e::<D>(0) * 1.9 + e::<D>(D - 1) * 0.5,
                    radius: 0.3,
                },
            ),
            Obstacle::new(
                "box",
                ObstacleShape::Box {
                    center: e::<D>(0) * -0.1 + e::<D>(D - 1) * 0.5,
                    half_extents: SVector::repeat(0.15),
                },
            ),
            Obstacle::new(
                "tool",
                ObstacleShape::Facets {
                    vertices: tool.nodes.iter().map(|v| v + tool_shift).collect(),
                    indices: tool_facets.iter().map(|f| f.to_vec()).collect(),
                },
            ),
        ];
        let t1: Vec<SVector<f64, D>> = obstacles
            .iter()
            .map(|_| SVector::from_fn(|_, _| rng.random_range(-0.05..0.05)))
            .collect();
        let margin = 0.05;
        let options = DetectionOptions {
            self_contact: true,
            margin,
            deformable_pairs: true,
            hysteresis: 0.0,
            facing: false,
            lock_flipping_facets: false,
        };
        let surface = ContactSurface::from_bodies(&[&a, &b, &c], &offsets);
        let facets = surface.facets().to_vec();
        let fbody = surface.facet_body().to_vec();
        let mut det = Detector::new(surface.clone(), options);
        det.update_candidates(&x0, &x1, &obstacles, &t1);

        // Brute force candidates.
        let mut brute = Vec::new();
        for (s, &node) in surface.slaves().iter().enumerate() {
            let seg = seg_box(&x0[node], &x1[node]);
            for (k, o) in obstacles.iter().enumerate() {
                if brute_obstacle_overlap(o, &t1[k], &seg, margin) {
                    brute.push((node, Master::Obstacle(k)));
                }
            }
            for (f, fc) in facets.iter().enumerate() {
                let same = fbody[f] == surface.slave_body()[s];
                if same && excluded(&facets, node, f) {
                    continue;
                }
                let fb =
                    Aabb::from_points(fc.iter().flat_map(|&v| [&x0[v], &x1[v]])).loosened(margin);
                if fb.intersects(&seg) {
                    brute.push((node, Master::Facet(f)));
                }
            }
        }
        assert_eq!(det.candidates(), &brute[..], "seed {seed}");
        assert!(
            brute.len() > 50,
            "a meaningful number of candidates: {}",
            brute.len()
        );

        // Brute force pairs at x1, obstacles at t1.
        let moved: Vec<Obstacle<D>> = obstacles
            .iter()
            .zip(&t1)
            .map(|(o, t)| Obstacle {
                translation: *t,
                ..o.clone()
            })
            .collect();
        let pairs = det.pairs(&x1, &moved);
        let mut normals = vec![SVector::<f64, D>::zeros(); x1.len()];
        for f in &facets {
            let (m, n) = <Dim<D>>::facet_measure_normal(&f.map(|v| x1[v]));
            for &v in f {
                normals[v] += n * m;
            }
        }
        let mut expected: Vec<(usize, Master, f64, Option<Feature>)> = Vec::new();
        let mut i = 0;
        while i < brute.len() {
            let (node, m) = brute[i];
            match m {
                Master::Obstacle(k) => {
                    let g = brute_obstacle_gap(&moved[k], &x1[node]);
                    if g < margin {
                        expected.push((node, m, g, None));
                    }
                    i += 1;
                }
                Master::Facet(f0) => {
                    let body = fbody[f0];
                    let mut group = Vec::new();
                    while i < brute.len()
                        && brute[i].0 == node
                        && matches!(brute[i].1, Master::Facet(f) if fbody[f] == body)
                    {
                        if let Master::Facet(f) = brute[i].1 {
                            group.push(f);
                        }
                        i += 1;
                    }
                    let own = facets
                        .iter()
                        .zip(&fbody)
                        .find(|(fc, _)| fc.contains(&node))
                        .unwrap()
                        .1;
                    let accept = |n: &SVector<f64, D>| body != *own || normals[node].dot(n) < 0.0;
                    // Self-contact penetrating: not nearer than a third of the path along the
                    // surface.
                    let path = surface_distances(&facets, &x1, node);
                    let keep = |f: usize, g: f64, d: f64| {
                        body != *own || g >= 0.0 || facets[f].iter().all(|&v| path[v] > 3.0 * d)
                    };
                    let fs = group.iter().map(|&f| (f, facets[f].map(|v| x1[v])));
                    if let Some((f, g, _, feat)) = brute_choose(&x1[node], fs, accept, keep) {
                        if g < margin {
                            expected.push((node, Master::Facet(f), g, Some(feat)));
                        }
                    }
                }
            }
        }
        assert_eq!(pairs.len(), expected.len(), "seed {seed}");
        for (p, (node, m, g, feat)) in pairs.iter().zip(&expected) {
            assert_eq!((p.slave, p.master), (*node, *m), "seed {seed}");
            assert!((p.gap - g).abs() < 1e-12, "{} vs {g}", p.gap);
            if let Some(feat) = feat {
                assert_eq!(p.feature, *feat);
            }
            assert!((p.normal.norm() - 1.0).abs() < 1e-12);
        }
        let kinds = |f: fn(&ContactPair<D>) -> bool| pairs.iter().filter(|p| f(p)).count();
        assert!(kinds(|p| matches!(p.master, Master::Obstacle(_))) > 0);
        assert!(kinds(|p| matches!(p.master, Master::Facet(_))) > 0);
        assert!(kinds(|p| p.gap < 0.0) > 0, "some penetration");
    }
}

/// Bends a strip (length along axis 0, thickness `h` along the last axis) around a
/// semicircle of centre-line radius `r` starting at `a`: the folded arm comes back over the
/// straight one with its faces `2 r - h` apart (negative: overlapping).
fn fold<const D: usize>(x: &SVector<f64, D>, a: f64, r: f64, h: f64) -> SVector<f64, D> {
    let (s, w) = (x[0], x[D - 1] - h / 2.0);
    let mut y = *x;
    let arc = std::f64::consts::PI * r;
    let (px, pz) = if s <= a {
        (s, w)
    } else if s <= a + arc {
        let t = (s - a) / r;
        (a + (r - w) * t.sin(), r - (r - w) * t.cos())
    } else {
        (a - (s - a - arc), 2.0 * r - w)
    };
    y[0] = px;
    y[D - 1] = pz + h / 2.0;
    y
}

fn folding_strip<const D: usize>()
where
    Dim<D>: SpatialDim<D> + TestDim<D>,
{
    let h = 0.05;
    let mut max = [0.2; D];
    max[0] = 2.0;
    max[D - 1] = h;
    let mut cells = [2; D];
    cells[0] = 40;
    cells[D - 1] = 1;
    let strip = <Dim<D>>::block([0.0; D], max, cells, false);
    let (x0, offsets) = stack(&[&strip]);
    let (a, r) = (0.6, 0.45 * h);
    let x1: Vec<SVector<f64, D>> = x0.iter().map(|x| fold(x, a, r, h)).collect();
    let margin = 0.2 * h;
    let surface = ContactSurface::from_bodies(&[&strip], &offsets);
    let facets = surface.facets().to_vec();
    let mut det = Detector::new(
        surface,
        DetectionOptions {
            self_contact: true,
            margin,
            ..Default::default()
        },
    );
    det.update_candidates(&x0, &x1, &[], &[]);
    let pairs = det.pairs(&x1, &[]);
    for p in &pairs {
        let Master::Facet(f) = p.master else {
            panic!("no obstacle here")
        };
        assert!(
            !excluded(&facets, p.slave, f),
            "node {} paired with its neighbour facet {f}",
            p.slave
        );
    }
    // Nodes of the former top face, well past the fold, lie 2r - h = -0.1 h below the
    // straight arm's top face.
    let arc_end = a + std::f64::consts::PI * r;
    let folded_top: Vec<usize> = (0..x0.len())
        .filter(|&n| {
            (x0[n][D - 1] - h).abs() < 1e-12 && x0[n][0] > arc_end + 0.1 && x1[n][0] > 0.05
        })
        .collect();
    assert!(!folded_top.is_empty());
    for n in folded_top {
        let p = pairs
            .iter()
            .find(|p| p.slave == n)
            .unwrap_or_else(|| panic!("node {n} found no contact"));
        assert!(
            (p.gap - (2.0 * r - h)).abs() < 1e-9,
            "gap {} for node {n}",
            p.gap
        );
        assert!((p.normal - e::<D>(D - 1)).norm() < 1e-9);
    }
}

/// The tube crush's curl in miniature: the cells along a unit block's left face squashed
/// against its top-left corner, whose top face leans down by 0.08 per metre (an acute corner,
/// 85 degrees). The node that came from half height sits 0.06 m below the corner, right under
/// the top face's first facet, which is two facets away along the surface (beyond the
/// neighbours self-contact excludes) and faces it (normals at 95 degrees): it lies 0.06 m
/// inside its own body, 0.06 m from that facet along the surface, and touches nothing.
fn node_beside_own_corner<const D: usize>()
where
    Dim<D>: SpatialDim<D> + TestDim<D>,
{
    let block = <Dim<D>>::block([0.0; D], [1.0; D], [4; D], false);
    let (x0, offsets) = stack(&[&block]);
    let top = |x: &SVector<f64, D>| (x[D - 1] - 1.0).abs() < 1e-12;
    let x1: Vec<SVector<f64, D>> = x0
        .iter()
        .map(|x| {
            let mut y = *x;
            if x[0] == 0.0 {
                for (from, to) in [(0.75, 0.97), (0.5, 0.94)] {
                    if (x[D - 1] - from).abs() < 1e-12 {
                        y[D - 1] = to;
                    }
                }
            }
            if top(x) {
                y[D - 1] = 1.0 - 0.08 * x[0];
            }
            y
        })
        .collect();
    let surface = ContactSurface::from_bodies(&[&block], &offsets);
    let mut det = Detector::new(
        surface,
        DetectionOptions {
            self_contact: true,
            margin: 0.05,
            ..Default::default()
        },
    );
    det.update_candidates(&x1, &x1, &[], &[]);
    let beside: Vec<usize> = (0..x1.len())
        .filter(|&n| x1[n][0] == 0.0 && (x1[n][D - 1] - 0.94).abs() < 1e-12)
        .collect();
    assert!(!beside.is_empty());
    // The pair the topology alone lets through: the corner's facet, found by the broad phase.
    assert!(det
        .candidates()
        .iter()
        .any(|&(n, m)| beside.contains(&n) && matches!(m, Master::Facet(_))));
    let pairs = det.pairs(&x1, &[]);
    let deepest = pairs.iter().map(|p| p.gap).fold(f64::INFINITY, f64::min);
    assert!(
        pairs.iter().all(|p| !beside.contains(&p.slave)),
        "{:?}",
        pairs.iter().find(|p| beside.contains(&p.slave))
    );
    assert!(deepest > -1e-9, "a pair {deepest} m deep");
}

fn thin_body_fast<const D: usize>()
where
    Dim<D>: SpatialDim<D> + TestDim<D>,
{
    // A plate 0.01 thick, 0.02 above a thick block, moving down 0.05 (5 thicknesses) per step.
    let t = 0.01;
    let mut pmin = [0.1; D];
    pmin[D - 1] = 1.02;
    let mut pmax = [0.9; D];
    pmax[D - 1] = 1.02 + t;
    let mut cells = [4; D];
    cells[D - 1] = 1;
    let plate = <Dim<D>>::block(pmin, pmax, cells, false);
    let block = <Dim<D>>::block([0.0; D], [1.0; D], [3; D], true);
    let (x0, offsets) = stack(&[&plate, &block]);
    let nplate = plate.nodes.len();
    let x1: Vec<SVector<f64, D>> = x0
        .iter()
        .enumerate()
        .map(|(i, x)| {
            if i < nplate {
                x - e::<D>(D - 1) * 0.05
            } else {
                *x
            }
        })
        .collect();
    let margin = 1e-3;
    let surface = ContactSurface::from_bodies(&[&plate, &block], &offsets);
    let mut det = Detector::new(
        surface,
        DetectionOptions {
            margin,
            ..Default::default()
        },
    );
    // Boxes at x0 alone miss the block.
    det.update_candidates(&x0, &x0, &[], &[]);
    assert!(det.candidates().is_empty());
    det.update_candidates(&x0, &x1, &[], &[]);
    let pairs = det.pairs(&x1, &[]);
    let bottom: Vec<usize> = (0..nplate)
        .filter(|&n| (x0[n][D - 1] - 1.02).abs() < 1e-12)
        .collect();
    for n in &bottom {
        let p = pairs
            .iter()
            .find(|p| p.slave == *n)
            .expect("bottom node of the plate caught");
        assert!((p.gap + 0.03).abs() < 1e-12, "gap {}", p.gap);
        assert!((p.normal - e::<D>(D - 1)).norm() < 1e-12);
    }

    // The same plate at rest, a box obstacle crossing 0.3 per step into it (30 thicknesses).
    let plate_only = ContactSurface::from_bodies(&[&plate], &[0]);
    let mut det = Detector::new(
        plate_only,
        DetectionOptions {
            margin,
            ..Default::default()
        },
    );
    let x: Vec<SVector<f64, D>> = plate.nodes.clone();
    let tool = Obstacle::new(
        "tool",
        ObstacleShape::Box {
            center: e::<D>(0) * 0.5 + e::<D>(D - 1) * 0.6,
            half_extents: SVector::repeat(0.25),
        },
    );
    let t1 = vec![e::<D>(D - 1) * 0.3];
    det.update_candidates(&x, &x, std::slice::from_ref(&tool), &t1);
    assert!(!det.candidates().is_empty());
    let moved = Obstacle {
        translation: t1[0],
        ..tool
    };
    let pairs = det.pairs(&x, &[moved]);
    assert!(!pairs.is_empty());
    for p in &pairs {
        assert!(p.gap < 0.0 && p.gap > -0.25, "gap {}", p.gap);
    }
}

// ---- hand-computed values -------------------------------------------------------------

/// A square body (facets CCW) as master and a second body whose three nodes are the probes.
fn square_and_probes(probes: [Vector2<f64>; 3]) -> Vec<ContactPair<2>> {
    let square = vec![[0, 1], [1, 2], [2, 3], [3, 0]];
    let probe = vec![[0, 1], [1, 2]];
    let x = vec![
        Vector2::new(0.0, 0.0),
        Vector2::new(1.0, 0.0),
        Vector2::new(1.0, 1.0),
        Vector2::new(0.0, 1.0),
        probes[0],
        probes[1],
        probes[2],
    ];
    let surface = ContactSurface::from_facets(&[square, probe], &[0, 4]);
    let mut det = Detector::new(
        surface,
        DetectionOptions {
            margin: 0.5,
            ..Default::default()
        },
    );
    det.update_candidates(&x, &x, &[], &[]);
    det.pairs(&x, &[])
        .into_iter()
        .filter(|p| p.slave >= 4)
        .collect()
}

#[test]
fn hand_values_2d_face_vertex_penetration() {
    let pairs = square_and_probes([
        Vector2::new(0.3, 1.1),
        Vector2::new(1.1, 1.2),
        Vector2::new(0.5, 0.9),
    ]);
    assert_eq!(pairs.len(), 3);
    // Face of the top facet (1,1) -> (0,1).
    let p = &pairs[0];
    assert_eq!(p.master, Master::Facet(2));
    assert!((p.gap - 0.1).abs() < 1e-12);
    assert!((p.normal - Vector2::new(0.0, 1.0)).norm() < 1e-12);
    assert!((p.point - Vector2::new(0.3, 1.0)).norm() < 1e-12);
    assert!((p.barycentric[0] - 0.3).abs() < 1e-12 && (p.barycentric[1] - 0.7).abs() < 1e-12);
    assert_eq!(p.feature, Feature::Face);
    // Corner (1,1): both facets reach it; the top one gives the larger gap (0.2 vs 0.1).
    let p = &pairs[1];
    assert_eq!(p.master, Master::Facet(2));
    assert!((p.gap - 0.2).abs() < 1e-12);
    assert_eq!(p.feature, Feature::Vertex(0));
    assert_eq!(p.barycentric, [1.0, 0.0]);
    assert!((p.point - Vector2::new(1.0, 1.0)).norm() < 1e-12);
    // Inside, 0.1 below the top.
    let p = &pairs[2];
    assert_eq!(p.master, Master::Facet(2));
    assert!((p.gap + 0.1).abs() < 1e-12);
    assert_eq!(p.feature, Feature::Face);
}

#[test]
fn hand_values_3d_face_edge_vertex() {
    let tri = vec![[0, 1, 2]];
    let probe = vec![[0, 1, 2]];
    let x = vec![
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(0.0, 1.0, 0.0),
        Vector3::new(0.2, 0.2, 0.5),
        Vector3::new(0.5, -0.3, 0.4),
        Vector3::new(-0.2, -0.1, -0.3),
    ];
    let surface = ContactSurface::from_facets(&[tri, probe], &[0, 3]);
    let mut det = Detector::new(
        surface,
        DetectionOptions {
            margin: 1.0,
            ..Default::default()
        },
    );
    det.update_candidates(&x, &x, &[], &[]);
    let pairs: Vec<_> = det
        .pairs(&x, &[])
        .into_iter()
        .filter(|p| p.slave >= 3)
        .collect();
    assert_eq!(pairs.len(), 3);
    let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-12);
    let p = &pairs[0];
    assert_eq!((p.master, p.feature), (Master::Facet(0), Feature::Face));
    assert!((p.gap - 0.5).abs() < 1e-12);
    assert!(close(&p.barycentric, &[0.6, 0.2, 0.2]));
    assert!(close(p.normal.as_slice(), &[0.0, 0.0, 1.0]));
    let p = &pairs[1];
    assert_eq!(p.feature, Feature::Edge(0));
    assert!((p.gap - 0.4).abs() < 1e-12);
    assert!(close(&p.barycentric, &[0.5, 0.5, 0.0]));
    assert!(close(p.point.as_slice(), &[0.5, 0.0, 0.0]));
    let p = &pairs[2];
    assert_eq!(p.feature, Feature::Vertex(0));
    assert!((p.gap + 0.3).abs() < 1e-12);
    assert!(close(&p.barycentric, &[1.0, 0.0, 0.0]));
}

/// Probes (nodes of a tiny body) against one obstacle each.
fn obstacle_pairs<const D: usize>(
    o: Obstacle<D>,
    probes: Vec<SVector<f64, D>>,
) -> Vec<ContactPair<D>>
where
    Dim<D>: SpatialDim<D>,
{
    // One facet per pair of consecutive probes keeps them all slaves.
    let facets: Vec<[usize; D]> = (0..probes.len())
        .map(|i| std::array::from_fn(|k| (i + k) % probes.len()))
        .collect();
    let surface = ContactSurface::from_facets(&[facets], &[0]);
    let mut det = Detector::new(
        surface,
        DetectionOptions {
            margin: 10.0,
            ..Default::default()
        },
    );
    let obstacles = [o];
    det.update_candidates(&probes, &probes, &obstacles, &[SVector::zeros()]);
    det.pairs(&probes, &obstacles)
}

#[test]
fn hand_values_obstacles_2d() {
    let v = Vector2::new;
    let half = Obstacle::new(
        "h",
        ObstacleShape::Halfspace {
            point: v(0.0, 0.0),
            normal: v(0.0, 2.0),
        },
    );
    let p = obstacle_pairs(half, vec![v(0.3, -0.1), v(1.0, 0.5)]);
    assert!((p[0].gap + 0.1).abs() < 1e-12 && (p[0].point - v(0.3, 0.0)).norm() < 1e-12);
    assert!((p[0].normal - v(0.0, 1.0)).norm() < 1e-12 && (p[1].gap - 0.5).abs() < 1e-12);

    let ball = Obstacle::new(
        "b",
        ObstacleShape::Ball {
            center: v(0.0, 0.0),
            radius: 1.0,
        },
    )
    .with_velocity(v(1.0, 0.0));
    let ball = Obstacle {
        translation: v(1.0, 0.0),
        ..ball
    };
    let p = obstacle_pairs(ball, vec![v(1.0, 2.0), v(1.5, 0.0)]);
    assert!((p[0].gap - 1.0).abs() < 1e-12 && (p[0].point - v(1.0, 1.0)).norm() < 1e-12);
    assert!((p[1].gap + 0.5).abs() < 1e-12 && (p[1].normal - v(1.0, 0.0)).norm() < 1e-12);

    let bx = Obstacle::new(
        "x",
        ObstacleShape::Box {
            center: v(0.0, 0.0),
            half_extents: v(1.0, 1.0),
        },
    );
    let p = obstacle_pairs(bx, vec![v(2.0, 2.0), v(0.5, 0.8), v(0.5, 1.5)]);
    assert!((p[0].gap - 2f64.sqrt()).abs() < 1e-12 && p[0].feature == Feature::Vertex(3));
    assert!((p[0].normal - v(1.0, 1.0) / 2f64.sqrt()).norm() < 1e-12);
    assert!((p[1].gap + 0.2).abs() < 1e-12 && (p[1].normal - v(0.0, 1.0)).norm() < 1e-12);
    assert!((p[1].point - v(0.5, 1.0)).norm() < 1e-12);
    assert!((p[2].gap - 0.5).abs() < 1e-12 && p[2].feature == Feature::Face);

    // A polyline V, solid below it (on the left of each segment, which runs right to left).
    let poly = Obstacle::new(
        "v",
        ObstacleShape::Facets {
            vertices: vec![v(-1.0, 1.0), v(0.0, 0.0), v(1.0, 1.0)],
            indices: vec![vec![1, 0], vec![2, 1]],
        },
    );
    let p = obstacle_pairs(poly, vec![v(0.0, -0.5), v(0.5, 0.0)]);
    // Below the apex, inside: both segments reach the vertex at the same gap -0.5/sqrt 2.
    assert!((p[0].gap + 0.5 / 2f64.sqrt()).abs() < 1e-12);
    assert!((p[0].point - v(0.0, 0.0)).norm() < 1e-12);
    assert!(matches!(p[0].feature, Feature::Vertex(_)));
    // Under the right segment, inside.
    assert!((p[1].gap + 0.5 / 2f64.sqrt()).abs() < 1e-12 && p[1].feature == Feature::Face);
}

#[test]
fn hand_values_obstacles_3d() {
    let v = Vector3::new;
    let bx = Obstacle::new(
        "x",
        ObstacleShape::Box {
            center: v(0.0, 0.0, 0.0),
            half_extents: v(1.0, 1.0, 1.0),
        },
    );
    let p = obstacle_pairs(
        bx,
        vec![v(2.0, 2.0, 0.0), v(0.0, 0.0, 0.9), v(2.0, 2.0, 2.0)],
    );
    assert!((p[0].gap - 2f64.sqrt()).abs() < 1e-12 && p[0].feature == Feature::Edge(2));
    assert!((p[1].gap + 0.1).abs() < 1e-12 && (p[1].normal - v(0.0, 0.0, 1.0)).norm() < 1e-12);
    assert!((p[2].gap - 3f64.sqrt()).abs() < 1e-12 && p[2].feature == Feature::Vertex(7));
    let ball = Obstacle::new(
        "b",
        ObstacleShape::Ball {
            center: v(0.0, 0.0, 0.0),
            radius: 0.5,
        },
    );
    let p = obstacle_pairs(
        ball,
        vec![v(0.0, 0.0, 0.2), v(0.0, 3.0, 0.0), v(1.0, 0.0, 0.0)],
    );
    assert!((p[0].gap + 0.3).abs() < 1e-12 && (p[0].normal - v(0.0, 0.0, 1.0)).norm() < 1e-12);
    assert!((p[1].gap - 2.5).abs() < 1e-12);
    let mesh = Obstacle::new(
        "t",
        ObstacleShape::Facets {
            vertices: vec![v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)],
            indices: vec![vec![0, 1, 2]],
        },
    );
    let p = obstacle_pairs(
        mesh,
        vec![v(0.2, 0.2, -0.5), v(0.5, -0.3, 0.4), v(3.0, 3.0, 3.0)],
    );
    assert!((p[0].gap + 0.5).abs() < 1e-12 && p[0].feature == Feature::Face);
    assert!((p[1].gap - 0.4).abs() < 1e-12 && p[1].feature == Feature::Edge(0));
    assert!((p[2].gap - 3.0).abs() < 1e-12 && p[2].feature == Feature::Edge(1));
}

/// Near a corner the chosen facet is stable: a point moving across the bisector keeps its
/// master within the hysteresis.
#[test]
fn hysteresis_keeps_the_master_near_a_corner() {
    let square = vec![[0, 1], [1, 2], [2, 3], [3, 0]];
    let probe = vec![[0, 1]];
    let mut x = vec![
        Vector2::new(0.0, 0.0),
        Vector2::new(1.0, 0.0),
        Vector2::new(1.0, 1.0),
        Vector2::new(0.0, 1.0),
        Vector2::new(0.95, 0.9), // inside, nearer the right facet (0.05 vs 0.1)
        Vector2::new(5.0, 5.0),
    ];
    let surface = ContactSurface::from_facets(&[square, probe], &[0, 4]);
    let options = DetectionOptions {
        margin: 0.1,
        hysteresis: 0.02,
        ..Default::default()
    };
    let mut det = Detector::new(surface, options);
    det.update_candidates(&x, &x, &[], &[]);
    let probe =
        |pairs: Vec<ContactPair<2>>| pairs.into_iter().find(|p| p.slave == 4).unwrap().master;
    assert_eq!(probe(det.pairs(&x, &[])), Master::Facet(1));
    // Just across the bisector: the top facet is now 0.01 closer, within the hysteresis.
    x[4] = Vector2::new(0.915, 0.925);
    assert_eq!(probe(det.pairs(&x, &[])), Master::Facet(1));
    // Far across: the top facet wins.
    x[4] = Vector2::new(0.9, 0.97);
    assert_eq!(probe(det.pairs(&x, &[])), Master::Facet(2));
    // Without hysteresis the switch is immediate (a new step: the count of changes that
    // locks a facet starts again).
    det.set_options(DetectionOptions {
        hysteresis: 0.0,
        ..options
    });
    det.set_memory(&det.memory());
    x[4] = Vector2::new(0.95, 0.9);
    det.pairs(&x, &[]);
    x[4] = Vector2::new(0.915, 0.925);
    assert_eq!(probe(det.pairs(&x, &[])), Master::Facet(2));
}

/// A node that swings across the bisector at every call changes its master twice, then keeps
/// the facet it has until the locks are released (the end of Newton's iterations) or the
/// memory is set (a step's start).
#[test]
fn a_facet_that_changes_twice_is_kept() {
    let square = vec![[0, 1], [1, 2], [2, 3], [3, 0]];
    let probe = vec![[0, 1]];
    let right = Vector2::new(0.95, 0.9);
    let top = Vector2::new(0.9, 0.95);
    let mut x = vec![
        Vector2::new(0.0, 0.0),
        Vector2::new(1.0, 0.0),
        Vector2::new(1.0, 1.0),
        Vector2::new(0.0, 1.0),
        right,
        Vector2::new(5.0, 5.0),
    ];
    let surface = ContactSurface::from_facets(&[square, probe], &[0, 4]);
    let mut det = Detector::new(
        surface,
        DetectionOptions {
            margin: 0.1,
            lock_flipping_facets: true,
            ..Default::default()
        },
    );
    det.update_candidates(&x, &x, &[], &[]);
    let mut master = |det: &mut Detector<2>, at: Vector2<f64>| {
        x[4] = at;
        let pairs = det.pairs(&x, &[]);
        pairs.into_iter().find(|p| p.slave == 4).unwrap().master
    };
    assert_eq!(softway::contact::detection::FLIPS_BEFORE_LOCK, 2);
    assert_eq!(master(&mut det, right), Master::Facet(1));
    assert_eq!(master(&mut det, top), Master::Facet(2));
    assert_eq!(master(&mut det, right), Master::Facet(1));
    // Locked: the top facet is nearer, the right one is kept.
    assert_eq!(master(&mut det, top), Master::Facet(1));
    assert_eq!(master(&mut det, top), Master::Facet(1));
    det.release_facet_locks();
    assert_eq!(master(&mut det, top), Master::Facet(2));
    // Two more changes lock it again; a new step's memory unlocks it.
    assert_eq!(master(&mut det, right), Master::Facet(1));
    assert_eq!(master(&mut det, top), Master::Facet(1));
    det.set_memory(&det.memory());
    assert_eq!(master(&mut det, top), Master::Facet(2));
}

#[test]
fn degenerate_facets_do_not_panic() {
    // A zero-length segment and a zero-area triangle among the masters.
    let x2 = vec![
        Vector2::new(0.0, 0.0),
        Vector2::new(0.0, 0.0),
        Vector2::new(0.0, 0.1),
        Vector2::new(0.1, 0.1),
    ];
    let s = ContactSurface::from_facets(&[vec![[0, 1]], vec![[2, 3]]], &[0, 0]);
    let mut det = Detector::new(
        s,
        DetectionOptions {
            margin: 1.0,
            ..Default::default()
        },
    );
    det.update_candidates(&x2, &x2, &[], &[]);
    assert!(det
        .pairs(&x2, &[])
        .iter()
        .all(|p| p.master != Master::Facet(0)));
    let x3 = vec![
        Vector3::zeros(),
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(2.0, 0.0, 0.0),
        Vector3::new(0.5, 0.1, 0.1),
    ];
    let s = ContactSurface::from_facets(&[vec![[0, 1, 2]], vec![[3, 3, 3]]], &[0, 0]);
    let mut det = Detector::new(
        s,
        DetectionOptions {
            margin: 1.0,
            ..Default::default()
        },
    );
    det.update_candidates(&x3, &x3, &[], &[]);
    assert!(det.pairs(&x3, &[]).is_empty());
}
