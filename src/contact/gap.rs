//! The contact gap, computed in one place: the signed distance of a slave point to its
//! master at the predicted end of the step (eq 22), the master nodes' weights, and its
//! derivatives (gradient and Hessian) that the contact tangents need.
//!
//! Detection picks the master (the closest facet or the obstacle feature, with hysteresis);
//! the methods take their gap from here.

use nalgebra::{SMatrix, SVector};

use crate::contact::detection::{ContactPair, Feature};
use crate::contact::obstacle::{Obstacle, ObstacleShape};
use crate::dim::{Dim, SpatialDim};

/// The gap of a point to the plane of a facet.
#[derive(Debug, Clone, Copy)]
pub struct FacetGap<const D: usize> {
    /// Signed gap `(x - y_0) . n` (m); negative is penetration.
    pub gap: f64,
    /// The facet's outward unit normal.
    pub normal: SVector<f64, D>,
    /// Barycentric weights (unclamped) of the projection of the point on the facet's plane.
    pub weights: [f64; D],
    /// The projection of the point on the facet's plane (m).
    pub point: SVector<f64, D>,
}

/// The gap of `x` to the plane of the facet with vertices `y`; `None` for a degenerate facet.
pub fn facet_gap<const D: usize>(
    x: &SVector<f64, D>,
    y: &[SVector<f64, D>; D],
) -> Option<FacetGap<D>>
where
    Dim<D>: SpatialDim<D>,
{
    let (measure, n) = <Dim<D>>::facet_measure_normal(y);
    if measure <= 0.0 {
        return None;
    }
    let weights = plane_weights::<D>(x, y, &n);
    let mut point = SVector::<f64, D>::zeros();
    for i in 0..D {
        point += y[i] * weights[i];
    }
    Some(FacetGap {
        gap: (x - y[0]).dot(&n),
        normal: n,
        weights,
        point,
    })
}

/// The Hessian of the signed distance to a facet's plane (slave and facet nodes, `D + 1`
/// nodes), by central differences of its analytic gradient; the gradient is `n` for the slave
/// and `-N_i n` for the facet nodes (the envelope theorem on the closest point).
pub fn facet_gap_hessian<const D: usize>(
    slave: &SVector<f64, D>,
    facet: &[SVector<f64, D>; D],
) -> Vec<Vec<f64>>
where
    Dim<D>: SpatialDim<D>,
{
    let m = (D + 1) * D;
    let mut coords: Vec<f64> = slave.iter().copied().collect();
    for v in facet {
        coords.extend(v.iter().copied());
    }
    let size = facet
        .iter()
        .map(|v| (v - facet[0]).norm())
        .fold(0.0, f64::max)
        .max(1e-300);
    let eps = 1e-6 * size;
    let mut hessian = vec![vec![0.0; m]; m];
    for j in 0..m {
        let mut plus = coords.clone();
        let mut minus = coords.clone();
        plus[j] += eps;
        minus[j] -= eps;
        let (gp, gm) = (
            facet_gap_gradient::<D>(&plus),
            facet_gap_gradient::<D>(&minus),
        );
        if let (Some(gp), Some(gm)) = (gp, gm) {
            for i in 0..m {
                hessian[i][j] = (gp.1[i] - gm.1[i]) / (2.0 * eps);
            }
        }
    }
    // Symmetrise the finite-difference noise away.
    for i in 0..m {
        for j in 0..i {
            let s = 0.5 * (hessian[i][j] + hessian[j][i]);
            hessian[i][j] = s;
            hessian[j][i] = s;
        }
    }
    hessian
}

/// Gap to a facet's plane and its gradient for flat coordinates `(x_s, y_1, .., y_D)`.
pub fn facet_gap_gradient<const D: usize>(coords: &[f64]) -> Option<(f64, Vec<f64>)>
where
    Dim<D>: SpatialDim<D>,
{
    let x = SVector::<f64, D>::from_column_slice(&coords[..D]);
    let y: [SVector<f64, D>; D] = std::array::from_fn(|i| {
        SVector::<f64, D>::from_column_slice(&coords[(i + 1) * D..(i + 2) * D])
    });
    let f = facet_gap::<D>(&x, &y)?;
    let mut grad = Vec::with_capacity((D + 1) * D);
    grad.extend(f.normal.iter().copied());
    for w in f.weights {
        grad.extend((f.normal * -w).iter().copied());
    }
    Some((f.gap, grad))
}

/// Barycentric weights (unclamped) of the projection of `x` on the plane of facet `y`.
pub fn plane_weights<const D: usize>(
    x: &SVector<f64, D>,
    y: &[SVector<f64, D>; D],
    n: &SVector<f64, D>,
) -> [f64; D] {
    let r = x - y[0] - n * (x - y[0]).dot(n);
    let mut w = [0.0; D];
    if D == 2 {
        let t = y[1] - y[0];
        let s = r.dot(&t) / t.norm_squared();
        w[0] = 1.0 - s;
        w[1] = s;
    } else {
        let (e1, e2) = (y[1] - y[0], y[2] - y[0]);
        let (a, b, c) = (e1.dot(&e1), e1.dot(&e2), e2.dot(&e2));
        let (r1, r2) = (r.dot(&e1), r.dot(&e2));
        let det = a * c - b * b;
        let s = (c * r1 - b * r2) / det;
        let t = (a * r2 - b * r1) / det;
        w[0] = 1.0 - s - t;
        w[1] = s;
        w[2] = t;
    }
    w
}

/// The signed gap of a point `x` to a master point `q` of outward normal `n`:
/// `(x - q) . n`, negative in penetration.
pub fn point_gap<const D: usize>(
    x: &SVector<f64, D>,
    q: &SVector<f64, D>,
    n: &SVector<f64, D>,
) -> f64 {
    (x - q).dot(n)
}

/// A point's gap to an analytic obstacle.
#[derive(Debug, Clone, Copy)]
pub struct ObstacleGap<const D: usize> {
    /// Signed gap (m); negative is penetration.
    pub gap: f64,
    /// The obstacle's outward unit normal at the closest point.
    pub normal: SVector<f64, D>,
    /// The closest point on the obstacle's surface (m).
    pub point: SVector<f64, D>,
    /// The feature holding it.
    pub feature: Feature,
    /// The face to remember (inside a box: the face pushed out through, kept within the
    /// hysteresis), else 0.
    pub choice: usize,
}

/// The gap of point `p` to an analytic obstacle (half-space, ball, box) at `translation`;
/// `previous` and `hysteresis` (m) keep a box's exit face stable near its diagonals. `None`
/// for a degenerate shape or a facet obstacle (searched by the detector).
pub fn analytic_obstacle_gap<const D: usize>(
    shape: &ObstacleShape<D>,
    translation: &SVector<f64, D>,
    p: &SVector<f64, D>,
    previous: Option<usize>,
    hysteresis: f64,
) -> Option<ObstacleGap<D>> {
    let found = |gap: f64,
                 normal: SVector<f64, D>,
                 point: SVector<f64, D>,
                 feature: Feature,
                 choice: usize| ObstacleGap {
        gap,
        normal,
        point,
        feature,
        choice,
    };
    let t = *translation;
    match shape {
        ObstacleShape::Halfspace { point, normal } => {
            let norm = normal.norm();
            if !(norm > 0.0 && norm.is_finite()) {
                return None;
            }
            let n = normal / norm;
            let g = point_gap(p, &(point + t), &n);
            Some(found(g, n, p - n * g, Feature::Face, 0))
        }
        ObstacleShape::Ball { center, radius } => {
            let c = center + t;
            let r = p - c;
            let d = r.norm();
            // At the centre every direction is a normal: take the last axis (up) for
            // determinism.
            let n = if d > 0.0 {
                r / d
            } else {
                let mut up = SVector::<f64, D>::zeros();
                up[D - 1] = 1.0;
                up
            };
            Some(found(d - radius, n, c + n * *radius, Feature::Face, 0))
        }
        ObstacleShape::Box {
            center,
            half_extents,
        } => {
            let c = center + t;
            let y = p - c;
            let h = half_extents.abs();
            let q = SVector::<f64, D>::from_fn(|k, _| y[k].clamp(-h[k], h[k]));
            let outside = y - q;
            let d = outside.norm();
            if d > 0.0 {
                let clamped: Vec<usize> = (0..D).filter(|&k| y[k].abs() > h[k]).collect();
                let bits = (0..D).filter(|&k| y[k] > 0.0).fold(0, |b, k| b | (1 << k));
                let feature = match clamped.len() {
                    1 => Feature::Face,
                    l if l == D => Feature::Vertex(bits),
                    _ => Feature::Edge((0..D).find(|k| !clamped.contains(k)).unwrap_or(0)),
                };
                return Some(found(d, outside / d, c + q, feature, 0));
            }
            // Inside: the nearest face, face id 2 k + (side > 0); the previous face is kept
            // within the hysteresis.
            let depth = |face: usize| {
                h[face / 2]
                    - if face % 2 == 1 {
                        y[face / 2]
                    } else {
                        -y[face / 2]
                    }
            };
            let mut best = 0;
            for face in 1..2 * D {
                if depth(face) < depth(best) {
                    best = face;
                }
            }
            if let Some(pf) = previous.filter(|&f| f < 2 * D) {
                if depth(pf) <= depth(best) + hysteresis {
                    best = pf;
                }
            }
            let k = best / 2;
            let s = if best % 2 == 1 { 1.0 } else { -1.0 };
            let mut n = SVector::<f64, D>::zeros();
            n[k] = s;
            let mut qp = *p;
            qp[k] = c[k] + s * h[k];
            Some(found(-depth(best), n, qp, Feature::Face, best))
        }
        ObstacleShape::Facets { .. } => None,
    }
}

/// The gap of point `p` to an analytic obstacle (half-space, ball, box) in its pose: computed
/// in the frame of the shape at t = 0, the normal and the closest point turned back (a turned
/// box is no longer axis-aligned). `None` as [`analytic_obstacle_gap`].
pub fn posed_obstacle_gap<const D: usize>(
    obstacle: &Obstacle<D>,
    p: &SVector<f64, D>,
    previous: Option<usize>,
    hysteresis: f64,
) -> Option<ObstacleGap<D>> {
    if !obstacle.is_turned() {
        return analytic_obstacle_gap(
            &obstacle.shape,
            &obstacle.translation,
            p,
            previous,
            hysteresis,
        );
    }
    let local = obstacle.to_local(p);
    let g = analytic_obstacle_gap(
        &obstacle.shape,
        &SVector::zeros(),
        &local,
        previous,
        hysteresis,
    )?;
    Some(ObstacleGap {
        normal: obstacle.turn(&g.normal),
        point: obstacle.to_world(&g.point),
        ..g
    })
}

/// Hessian of the distance to an analytic obstacle in its pose at a slave point `x` paired as
/// `pair` (zero on flat faces). The terms below are built from the world normal, point and
/// (turned) edge direction, so they are the frame's `R H R^T`.
pub fn obstacle_gap_hessian<const D: usize>(
    obstacle: &Obstacle<D>,
    pair: &ContactPair<D>,
    x: &SVector<f64, D>,
) -> SMatrix<f64, D, D> {
    let n = pair.normal;
    let projector = SMatrix::<f64, D, D>::identity() - n * n.transpose();
    let distance = (x - pair.point).norm();
    match (&obstacle.shape, pair.feature) {
        (ObstacleShape::Ball { center, .. }, _) => {
            let d = if obstacle.is_turned() {
                (x - obstacle.to_world(center)).norm()
            } else {
                (x - center - obstacle.translation).norm()
            };
            if d > 0.0 {
                projector / d
            } else {
                SMatrix::zeros()
            }
        }
        (ObstacleShape::Box { .. }, Feature::Vertex(_)) if distance > 0.0 => projector / distance,
        (ObstacleShape::Box { .. }, Feature::Edge(k)) if distance > 0.0 && D == 3 => {
            let mut e = SVector::<f64, D>::zeros();
            e[k] = 1.0;
            let e = obstacle.turn(&e);
            (projector - e * e.transpose()) / distance
        }
        (ObstacleShape::Facets { .. }, Feature::Vertex(_)) if distance > 0.0 => {
            projector / distance
        }
        // Faces are flat; the edges of a triangle-mesh obstacle are not curved in their own
        // direction and their small transverse term is dropped (named in the book).
        _ => SMatrix::zeros(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::verify_record::record;
    use nalgebra::Vector2;

    #[test]
    fn facet_gap_gradient_and_hessian() {
        // A 2D segment from (0,0) to (2,0): gap = y, weights linear in x.
        let coords = [0.5, -0.1, 0.0, 0.0, 2.0, 0.0];
        let (g, grad) = facet_gap_gradient::<2>(&coords).unwrap();
        // The body is on the left of (0,0) -> (2,0), so n = (0, -1) and the point is outside.
        record("gap-facet", "gap", (g - 0.1).abs());
        assert!((g - 0.1).abs() < 1e-15);
        // dg/dx_s = n; dg/dy_1 = -0.75 n; dg/dy_2 = -0.25 n.
        let (_, n) =
            <Dim<2>>::facet_measure_normal(&[Vector2::new(0.0, 0.0), Vector2::new(2.0, 0.0)]);
        let by_hand = [
            (grad[1] - n.y).abs(),
            (grad[3] + 0.75 * n.y).abs(),
            (grad[5] + 0.25 * n.y).abs(),
        ];
        record(
            "gap-facet",
            "by hand",
            by_hand.iter().copied().fold(0.0, f64::max),
        );
        assert!((grad[1] - n.y).abs() < 1e-15);
        assert!((grad[3] + 0.75 * n.y).abs() < 1e-12);
        assert!((grad[5] + 0.25 * n.y).abs() < 1e-12);
        // The gradient itself against central differences of the gap.
        let eps = 1e-7;
        for j in 0..6 {
            let (mut p, mut m) = (coords, coords);
            p[j] += eps;
            m[j] -= eps;
            let fd = (facet_gap_gradient::<2>(&p).unwrap().0
                - facet_gap_gradient::<2>(&m).unwrap().0)
                / (2.0 * eps);
            record("gap-facet", "central differences", (fd - grad[j]).abs());
            assert!((fd - grad[j]).abs() < 1e-7, "{j}: {fd} vs {}", grad[j]);
        }
        let h = facet_gap_hessian::<2>(
            &Vector2::new(0.5, -0.1),
            &[Vector2::new(0.0, 0.0), Vector2::new(2.0, 0.0)],
        );
        assert!(h.iter().flatten().all(|v| v.is_finite()));
        // Moving the slave along the segment does not change dg/dx_s: that row block is zero.
        assert!(h[0][0].abs() < 1e-6 && h[1][1].abs() < 1e-6);
    }
}
