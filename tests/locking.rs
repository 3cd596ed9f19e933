//! Volumetric locking of the elastic laws: a clamped cantilever under a tip load, solved
//! statically with the assembled stiffness (K u = f), against Timoshenko's tip deflection, at
//! nu = 0.3 and nearly incompressible nu = 0.499, with Quad4 (plane strain) and Hex8.

use crate::common;

use common::block;
use common::verify::record;
use nalgebra::{DMatrix, DVector};
use softway::dim::{Dim, SpatialDim};
use softway::prelude::*;

const LENGTH: f64 = 1.0;
const DEPTH: f64 = 0.1;
const E: f64 = 1e7;
const LOAD: f64 = 10.0;

/// The tip deflection of the FE cantilever over Timoshenko's, `P L^3 / (3 E' I) + P L / (k G A)`
/// (plane strain: E' = E / (1 - nu^2); 3D: E), for a total tip load P spread over the tip face.
fn deflection_ratio<const D: usize>(nu: f64, cells: [usize; 3]) -> f64
where
    Dim<D>: SpatialDim<D>,
{
    let mesh: Mesh<D> = block([LENGTH, DEPTH, DEPTH], cells, false);
    let nodes = mesh.nodes.clone();
    let sim = Simulation::<D>::builder()
        .time_step(1e-3)
        .body(Body::new(
            "beam",
            mesh,
            Material::LinearElastic(LinearElastic::new(E, nu, 1000.0).unwrap()),
        ))
        .build()
        .unwrap();
    let k = sim.stiffness_matrix().to_dense();
    let free: Vec<usize> = (0..nodes.len() * D)
        .filter(|i| nodes[i / D][0] > 1e-12)
        .collect();
    let tip: Vec<usize> = (0..nodes.len())
        .filter(|&n| (nodes[n][0] - LENGTH).abs() < 1e-12)
        .collect();
    // Consistent nodal forces of a uniform shear on the tip face: the tributary share of each
    // tip node (a node on an edge of the face takes half of an interior one's per direction).
    let weight = |n: usize| -> f64 {
        (1..D)
            .map(|k| {
                let on_edge = nodes[n][k].abs() < 1e-12 || (nodes[n][k] - DEPTH).abs() < 1e-12;
                if on_edge {
                    0.5
                } else {
                    1.0
                }
            })
            .product()
    };
    let total: f64 = tip.iter().map(|&n| weight(n)).sum();
    let mut f = DVector::zeros(nodes.len() * D);
    for &n in &tip {
        f[n * D + 1] = -LOAD * weight(n) / total;
    }
    let kf = DMatrix::from_fn(free.len(), free.len(), |i, j| k[(free[i], free[j])]);
    let ff = DVector::from_fn(free.len(), |i, _| f[free[i]]);
    let u = kf.cholesky().expect("positive definite").solve(&ff);
    let position = |dof: usize| free.iter().position(|&d| d == dof).unwrap();
    let tip_deflection =
        -tip.iter().map(|&n| u[position(n * D + 1)]).sum::<f64>() / tip.len() as f64;
    let width = if D == 2 { 1.0 } else { DEPTH };
    let area = DEPTH * width;
    let inertia = width * DEPTH.powi(3) / 12.0;
    let bending_modulus = if D == 2 { E / (1.0 - nu * nu) } else { E };
    let shear_modulus = E / (2.0 * (1.0 + nu));
    let exact = LOAD * LENGTH.powi(3) / (3.0 * bending_modulus * inertia)
        + LOAD * LENGTH / (5.0 / 6.0 * shear_modulus * area);
    let ratio = tip_deflection / exact;
    eprintln!("{D}D nu = {nu}, cells {cells:?}: tip deflection {tip_deflection:.5e} m, Timoshenko {exact:.5e} m, ratio {ratio:.4}");
    ratio
}

/// Measured (`cargo test --release --all-features --test suite locking:: -- --nocapture`): 0.960 at
/// nu = 0.3 (full integration), 1.003 at nu = 0.499 (B-bar; 0.114 with full integration).
#[test]
fn quad4_cantilever_does_not_lock() {
    let compressible = deflection_ratio::<2>(0.3, [40, 4, 1]);
    let nearly_incompressible = deflection_ratio::<2>(0.499, [40, 4, 1]);
    record("locking", "Quad4 nu 0.3", compressible - 1.0);
    record("locking", "Quad4 nu 0.499", nearly_incompressible - 1.0);
    assert!((compressible - 1.0).abs() < 0.05, "{compressible}");
    assert!(
        (nearly_incompressible - 1.0).abs() < 0.02,
        "{nearly_incompressible}"
    );
}

/// Two Hex8 through the depth shear-lock in bending whatever nu: measured 0.869 at nu = 0.3,
/// 0.944 at nu = 0.499 (B-bar; 0.422 with full integration).
#[test]
fn hex8_cantilever_does_not_lock() {
    let compressible = deflection_ratio::<3>(0.3, [20, 2, 2]);
    let nearly_incompressible = deflection_ratio::<3>(0.499, [20, 2, 2]);
    record("locking", "Hex8 nu 0.3", compressible - 1.0);
    record("locking", "Hex8 nu 0.499", nearly_incompressible - 1.0);
    assert!((compressible - 1.0).abs() < 0.15, "{compressible}");
    assert!(
        (nearly_incompressible - 1.0).abs() < 0.07,
        "{nearly_incompressible}"
    );
}
