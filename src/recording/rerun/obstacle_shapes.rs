//! The outlines (2D) and surfaces (3D) drawn for the rigid obstacles.

use nalgebra::SVector;

use crate::contact::ObstacleShape;

/// 2D outline of an obstacle shape as line strips (m); a half-space is drawn as a segment
/// `4 size` long around the point of its boundary nearest the origin of its `point`.
pub(super) fn shape_strips<const D: usize>(
    shape: &ObstacleShape<D>,
    size: f64,
) -> Vec<Vec<SVector<f64, D>>> {
    let v = |x: f64, y: f64| SVector::<f64, D>::from_fn(|k, _| if k == 0 { x } else { y });
    match shape {
        ObstacleShape::Halfspace { point, normal } => {
            let n = normal.normalize();
            let t = v(-n[1], n[0]);
            vec![vec![point - t * (2.0 * size), point + t * (2.0 * size)]]
        }
        ObstacleShape::Box {
            center,
            half_extents: e,
        } => {
            let corners = [
                (-1.0, -1.0),
                (1.0, -1.0),
                (1.0, 1.0),
                (-1.0, 1.0),
                (-1.0, -1.0),
            ];
            vec![corners
                .iter()
                .map(|(a, b)| center + v(a * e[0], b * e[1]))
                .collect()]
        }
        ObstacleShape::Ball { center, radius } => {
            let n = 64;
            vec![(0..=n)
                .map(|i| {
                    let a = std::f64::consts::TAU * i as f64 / n as f64;
                    center + v(radius * a.cos(), radius * a.sin())
                })
                .collect()]
        }
        ObstacleShape::Facets { vertices, indices } => indices
            .iter()
            .map(|f| f.iter().filter_map(|&i| vertices.get(i).copied()).collect())
            .collect(),
    }
}

/// 3D surface of an obstacle shape: vertices (m) and triangles; a half-space is drawn as a
/// square of side `4 size` centred on its `point`.
pub(super) fn shape_triangles<const D: usize>(
    shape: &ObstacleShape<D>,
    size: f64,
) -> (Vec<SVector<f64, D>>, Vec<[u32; 3]>) {
    let v = |x: f64, y: f64, z: f64| {
        SVector::<f64, D>::from_fn(|k, _| match k {
            0 => x,
            1 => y,
            _ => z,
        })
    };
    match shape {
        ObstacleShape::Halfspace { point, normal } => {
            let n = normal.normalize();
            // Any vector not parallel to n, then two tangents.
            let a = if n[0].abs() < 0.9 {
                v(1.0, 0.0, 0.0)
            } else {
                v(0.0, 1.0, 0.0)
            };
            let t1 = cross(&n, &a).normalize() * (2.0 * size);
            let t2 = cross(&n, &t1);
            let verts = vec![
                point - t1 - t2,
                point + t1 - t2,
                point + t1 + t2,
                point - t1 + t2,
            ];
            (verts, vec![[0, 1, 2], [0, 2, 3]])
        }
        ObstacleShape::Box {
            center,
            half_extents: e,
        } => {
            let mut verts = Vec::with_capacity(8);
            for k in 0..8 {
                let s = |bit: usize| if k & (1 << bit) != 0 { 1.0 } else { -1.0 };
                verts.push(center + v(s(0) * e[0], s(1) * e[1], s(2) * e[2]));
            }
            let quads = [
                [0, 2, 3, 1],
                [4, 5, 7, 6],
                [0, 1, 5, 4],
                [2, 6, 7, 3],
                [0, 4, 6, 2],
                [1, 3, 7, 5],
            ];
            let tris = quads
                .iter()
                .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
                .collect();
            (verts, tris)
        }
        ObstacleShape::Ball { center, radius } => {
            let (rings, sectors) = (12usize, 24usize);
            let mut verts = Vec::new();
            for i in 0..=rings {
                let theta = std::f64::consts::PI * i as f64 / rings as f64;
                for j in 0..sectors {
                    let phi = std::f64::consts::TAU * j as f64 / sectors as f64;
                    verts.push(
                        center
                            + v(
                                radius * theta.sin() * phi.cos(),
                                radius * theta.sin() * phi.sin(),
                                radius * theta.cos(),
                            ),
                    );
                }
            }
            let mut tris = Vec::new();
            for i in 0..rings {
                for j in 0..sectors {
                    let a = (i * sectors + j) as u32;
                    let b = (i * sectors + (j + 1) % sectors) as u32;
                    let c = a + sectors as u32;
                    let d = b + sectors as u32;
                    tris.push([a, c, b]);
                    tris.push([b, c, d]);
                }
            }
            (verts, tris)
        }
        ObstacleShape::Facets { vertices, indices } => {
            let tris = indices
                .iter()
                .filter(|f| f.len() >= 3 && f.iter().all(|&i| i < vertices.len()))
                .map(|f| [f[0] as u32, f[1] as u32, f[2] as u32])
                .collect();
            (vertices.clone(), tris)
        }
    }
}

fn cross<const D: usize>(a: &SVector<f64, D>, b: &SVector<f64, D>) -> SVector<f64, D> {
    let c = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    SVector::<f64, D>::from_fn(|k, _| c[k])
}
