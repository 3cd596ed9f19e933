//! Helpers shared by the integration tests.
#![allow(dead_code)]

/// The verification chapter's measured figures: `verify::record(row, quantity, value)`.
#[path = "../../src/verify_record.rs"]
pub mod verify;

use nalgebra::{DMatrix, SVector, Vector2, Vector3};
use softway::element::ElementKind;
use softway::mesh::generators::{cuboid, rectangle};
use softway::mesh::Mesh;

/// Runs a generic test function in 2D and 3D: `both_dims!(f, g)` makes `d2::f`, `d3::f`, ...
#[macro_export]
macro_rules! both_dims {
    ($($(#[$attr:meta])* $name:ident),* $(,)?) => {
        mod d2 { $( $(#[$attr])* #[test] fn $name() { super::$name::<2>(); } )* }
        mod d3 { $( $(#[$attr])* #[test] fn $name() { super::$name::<3>(); } )* }
    };
}

/// Copies a mesh whose dimension equals D at run time.
pub fn retype<const A: usize, const D: usize>(m: Mesh<A>) -> Mesh<D> {
    assert_eq!(A, D);
    Mesh {
        nodes: m
            .nodes
            .iter()
            .map(|x| SVector::<f64, D>::from_fn(|i, _| x[i]))
            .collect(),
        blocks: m.blocks,
        node_sets: m.node_sets,
    }
}

/// The box [0, size] with `cells` divisions (first D entries used); simplices or not.
pub fn block<const D: usize>(size: [f64; 3], cells: [usize; 3], simplex: bool) -> Mesh<D> {
    if D == 2 {
        let kind = if simplex {
            ElementKind::Tri3
        } else {
            ElementKind::Quad4
        };
        retype(
            rectangle(
                Vector2::zeros(),
                Vector2::new(size[0], size[1]),
                [cells[0], cells[1]],
                kind,
            )
            .unwrap(),
        )
    } else {
        let kind = if simplex {
            ElementKind::Tet4
        } else {
            ElementKind::Hex8
        };
        retype(
            cuboid(
                Vector3::zeros(),
                Vector3::new(size[0], size[1], size[2]),
                cells,
                kind,
            )
            .unwrap(),
        )
    }
}

/// The energy account's error `|E - E(0) - W + D|` relative to the energy reference.
pub fn energy_error<const D: usize>(sim: &softway::Simulation<D>) -> f64
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let e = sim.energies();
    (e.total() - sim.initial_energy() - e.external_work + e.dissipated).abs()
        / sim.energy_reference()
}

/// A rigid floor named "floor": the half-space below the plane through the origin normal to
/// the last axis.
pub fn floor<const D: usize>() -> softway::contact::Obstacle<D> {
    let mut normal = SVector::zeros();
    normal[D - 1] = 1.0;
    softway::contact::Obstacle::new(
        "floor",
        softway::contact::ObstacleShape::Halfspace {
            point: SVector::zeros(),
            normal,
        },
    )
}

/// A 0.2 x 0.1 (x 0.2) m block of `material` resting on a floor under gravity from rest (4 x 2
/// (x 4) cells, h = 1 ms), with implicit projection (the default method).
pub fn resting_block<const D: usize>(
    material: softway::material::Material,
) -> softway::Simulation<D>
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    use softway::contact::{ContactMethod, ContactSettings};
    use softway::simulation::Body;
    let mut g = [0.0; 3];
    g[D - 1] = -9.81;
    softway::Simulation::<D>::builder()
        .time_step(1e-3)
        .gravity(vec_d(g))
        .body(Body::new(
            "block",
            block([0.2, 0.1, 0.2], [4, 2, 4], false),
            material,
        ))
        .obstacle(floor::<D>())
        .contact(ContactSettings {
            method: ContactMethod::ImplicitProjection,
            ..ContactSettings::default()
        })
        .build()
        .unwrap()
}

/// The least-squares slope of `y` against `x` (an acceleration from sampled velocities).
pub fn least_squares_slope(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (xm, ym) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    x.iter()
        .zip(y)
        .map(|(a, b)| (a - xm) * (b - ym))
        .sum::<f64>()
        / x.iter().map(|a| (a - xm).powi(2)).sum::<f64>()
}

/// A vector with the first D entries of `v`.
pub fn vec_d<const D: usize>(v: [f64; 3]) -> SVector<f64, D> {
    SVector::from_fn(|i, _| v[i])
}

/// The full dense matrix of a symmetric sparse matrix stored as its lower triangle.
pub fn dense(a: softway::simulation::SymmetricMatrix<'_>) -> DMatrix<f64> {
    a.to_dense()
}

/// The bundled scene `fixtures/scenes/{name}.toml` with `overrides` (`key=value`, as `--set`).
#[cfg(feature = "formats")]
pub fn fixture<const D: usize>(name: &str, overrides: &[String]) -> softway::io::scene::Scene<D>
where
    softway::dim::Dim<D>: softway::dim::SpatialDim<D>,
{
    let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/scenes")
        .join(format!("{name}.toml"));
    softway::io::scene::load(&path, overrides)
        .and_then(|s| s.build::<D>())
        .unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// `f` run inside a rayon pool of `threads` threads (what the thread-independence tests compare).
pub fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// The bar impact of the paper's example 1 at `k` times the explicit stable step: a 1 m steel
/// bar (100 Quad4 cells, E = 200 GPa, nu = 0, rho = 8000 kg/m^3) thrown at 1 m/s against a
/// rigid wall 0.1 mm away, the soft way with zeta = 1e5 E / l and the given gaps and pressure.
/// Returns the simulation and the bar's transit time l / c (s).
pub fn steel_bar_at_a_wall(
    k: f64,
    gaps: softway::contact::GapDisplacement,
    force: softway::contact::PenaltyForce,
) -> (softway::Simulation2, f64) {
    use softway::contact::{ContactMethod, ContactSettings, Obstacle, ObstacleShape};
    use softway::material::{LinearElastic, Material};
    use softway::simulation::Body;
    let (l, e, rho) = (1.0, 200e9, 8000.0);
    let c = f64::sqrt(e / rho);
    let mesh = rectangle(
        Vector2::zeros(),
        Vector2::new(l, 0.1),
        [100, 1],
        ElementKind::Quad4,
    )
    .unwrap();
    let steel = Material::LinearElastic(LinearElastic::new(e, 0.0, rho).unwrap());
    let bar = Body::new("bar", mesh, steel).with_velocity(Vector2::new(1.0, 0.0));
    let wall = Obstacle::new(
        "wall",
        ObstacleShape::Halfspace {
            point: Vector2::new(l + 1e-4, 0.0),
            normal: Vector2::new(-1.0, 0.0),
        },
    );
    let sim = softway::Simulation2::builder()
        .time_step(k * (l / 100.0) / c)
        .body(bar)
        .obstacle(wall)
        .contact(ContactSettings {
            method: ContactMethod::SoftWay,
            penalty: 1e5 * e / l,
            gap_displacement: gaps,
            penalty_force: force,
            ..ContactSettings::default()
        })
        .build()
        .unwrap();
    (sim, l / c)
}
