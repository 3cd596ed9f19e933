//! The swept surfaces of the detection benches (`benches/detection.rs` and
//! `benches/compare/rapier`'s `broad_phase`, which includes this file by path): closed
//! cube-spheres and a pseudo-random motion of their vertices.

use std::collections::HashMap;

use nalgebra::Vector3;

/// A cube subdivided `n x n` per face, projected on the unit sphere: 12 n^2 outward triangles.
pub fn cube_sphere(n: usize) -> (Vec<Vector3<f64>>, Vec<[usize; 3]>) {
    let mut index: HashMap<[usize; 3], usize> = HashMap::new();
    let mut nodes = Vec::new();
    let mut id = |p: [usize; 3], nodes: &mut Vec<Vector3<f64>>| {
        *index.entry(p).or_insert_with(|| {
            let v = Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64) * (2.0 / n as f64)
                - Vector3::repeat(1.0);
            nodes.push(v.normalize());
            nodes.len() - 1
        })
    };
    let mut tris = Vec::new();
    for axis in 0..3 {
        for side in [0, n] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for i in 0..n {
                for j in 0..n {
                    let corner = |a: usize, b: usize| {
                        let mut p = [0; 3];
                        p[axis] = side;
                        p[u] = a;
                        p[v] = b;
                        p
                    };
                    let q = [
                        id(corner(i, j), &mut nodes),
                        id(corner(i + 1, j), &mut nodes),
                        id(corner(i + 1, j + 1), &mut nodes),
                        id(corner(i, j + 1), &mut nodes),
                    ];
                    for t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
                        let (a, b, c) = (nodes[t[0]], nodes[t[1]], nodes[t[2]]);
                        let outward = (b - a).cross(&(c - a)).dot(&(a + b + c)) > 0.0;
                        tris.push(if outward { t } else { [t[0], t[2], t[1]] });
                    }
                }
            }
        }
    }
    (nodes, tris)
}

/// A deterministic pseudo-random number in [-1, 1) from an integer (splitmix64).
pub fn hash_unit(mut z: u64) -> f64 {
    z = z.wrapping_add(0x9E3779B97F4A7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// The mean edge length of a triangle surface.
pub fn mean_edge(x0: &[Vector3<f64>], tris: &[[usize; 3]]) -> f64 {
    tris.iter()
        .map(|t| {
            (0..3)
                .map(|k| (x0[t[k]] - x0[t[(k + 1) % 3]]).norm())
                .sum::<f64>()
        })
        .sum::<f64>()
        / (3 * tris.len()) as f64
}

/// Every vertex moved by up to 0.17 mean edge lengths in a pseudo-random direction; `seed`
/// picks the directions (seed 0 is the motion of `benches/compare/ipctk_candidates.py`'s
/// exported surfaces).
pub fn motion(x0: &[Vector3<f64>], tris: &[[usize; 3]], seed: u64) -> Vec<Vector3<f64>> {
    let edge = mean_edge(x0, tris);
    x0.iter()
        .enumerate()
        .map(|(i, x)| {
            let d = Vector3::from_fn(|k, _| hash_unit(seed * 0x1000_0000 + (3 * i + k) as u64));
            // d lies in the unit cube: scale so that |d| <= 1 holds.
            x + d * (0.17 * edge / 3f64.sqrt())
        })
        .collect()
}
