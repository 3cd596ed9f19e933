//! The geometry bridge: point-to-facet projection and the bounding-volume hierarchy.
//!
//! This module is the only place in softway that names parry or glam (parry 0.31 works on glam
//! vectors; softway works on nalgebra's `SVector`). A parry upgrade touches this file only.
//! Everything dimension-specific sits in the sealed trait [`GeometryDim`], implemented for
//! `Dim<2>` (parry2d-f64) and `Dim<3>` (parry3d-f64); it is a supertrait of
//! [`SpatialDim`](crate::dim::SpatialDim), so generic code keeps the single bound
//! `where Dim<D>: SpatialDim<D>`.

use nalgebra::SVector;

use crate::dim::Dim;

mod sealed {
    pub trait Sealed {}
    impl Sealed for crate::dim::Dim<2> {}
    impl Sealed for crate::dim::Dim<3> {}
}

/// An axis-aligned box `[min, max]` (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb<const D: usize> {
    /// Smallest coordinates (m).
    pub min: SVector<f64, D>,
    /// Largest coordinates (m).
    pub max: SVector<f64, D>,
}

impl<const D: usize> Aabb<D> {
    /// The box of a set of points; an empty set gives an inverted (empty) box.
    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a SVector<f64, D>>) -> Self {
        let mut b = Aabb::<D> {
            min: SVector::repeat(f64::INFINITY),
            max: SVector::repeat(f64::NEG_INFINITY),
        };
        for p in points {
            b.min = b.min.inf(p);
            b.max = b.max.sup(p);
        }
        b
    }

    /// The box grown by `margin` (m) on every side.
    pub fn loosened(&self, margin: f64) -> Self {
        Aabb {
            min: self.min.add_scalar(-margin),
            max: self.max.add_scalar(margin),
        }
    }

    /// The smallest box holding both.
    pub fn merged(&self, other: &Self) -> Self {
        Aabb {
            min: self.min.inf(&other.min),
            max: self.max.sup(&other.max),
        }
    }

    /// Whether the two closed boxes share a point.
    pub fn intersects(&self, other: &Self) -> bool {
        (0..D).all(|k| self.min[k] <= other.max[k] && other.min[k] <= self.max[k])
    }

    /// Euclidean distance between the two boxes (m; 0 when they overlap).
    pub fn distance(&self, other: &Self) -> f64 {
        let mut d2 = 0.0;
        for k in 0..D {
            let gap = (other.min[k] - self.max[k])
                .max(self.min[k] - other.max[k])
                .max(0.0);
            d2 += gap * gap;
        }
        d2.sqrt()
    }
}

/// Which feature of a master facet (or obstacle) holds the closest point.
///
/// Local numbering: `Vertex(i)` is the facet's i-th node; in 3D `Edge(e)` joins nodes `e` and
/// `(e + 1) % 3`. A 2D segment has no `Edge`: its interior is its `Face`. For a box obstacle
/// `Vertex(bits)` is the corner whose coordinate k is at `+half_extent` when bit k is set and
/// `Edge(k)` an edge parallel to axis k (3D).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Feature {
    /// A vertex (local index).
    Vertex(usize),
    /// An edge (local index), 3D only.
    Edge(usize),
    /// The interior of the facet, or the surface of an analytic obstacle.
    Face,
}

/// The closest point of a facet to a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FacetProjection<const D: usize> {
    /// The closest point Q (m).
    pub point: SVector<f64, D>,
    /// Weights of the facet's nodes at Q (they sum to 1).
    pub barycentric: [f64; D],
    /// The feature holding Q.
    pub feature: Feature,
}

/// A bounding-volume hierarchy over boxes keyed by their index (parry's `Bvh`); build once,
/// [`refit`](BoxTree::refit) when the boxes move.
pub struct BoxTree<const D: usize>
where
    Dim<D>: GeometryDim<D>,
{
    inner: <Dim<D> as GeometryDim<D>>::Tree,
    len: usize,
}

impl<const D: usize> BoxTree<D>
where
    Dim<D>: GeometryDim<D>,
{
    /// Builds the hierarchy; leaf `i` is `boxes[i]`.
    pub fn new(boxes: &[Aabb<D>]) -> Self {
        BoxTree {
            inner: <Dim<D>>::tree_build(boxes),
            len: boxes.len(),
        }
    }

    /// Number of leaves.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the hierarchy has no leaf.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Moves every leaf to its new box (same count and order as at construction) and refits
    /// the internal nodes: O(n), the topology is kept.
    pub fn refit(&mut self, boxes: &[Aabb<D>]) {
        assert_eq!(
            boxes.len(),
            self.len,
            "refit with a different number of boxes"
        );
        <Dim<D>>::tree_refit(&mut self.inner, boxes);
    }

    /// Appends to `out` the leaves whose boxes intersect `query` (tree order, unsorted).
    pub fn query(&self, query: &Aabb<D>, out: &mut Vec<usize>) {
        <Dim<D>>::tree_query(&self.inner, query, out);
    }
}

/// Dimension-specific geometry: the parry types behind the BVH and the projection of a point
/// on a facet (segment in 2D, triangle in 3D). Sealed; implemented for `Dim<2>` and `Dim<3>`.
pub trait GeometryDim<const D: usize>: sealed::Sealed {
    /// The hierarchy and its workspace (opaque).
    #[doc(hidden)]
    type Tree: Send + Sync;

    #[doc(hidden)]
    fn tree_build(boxes: &[Aabb<D>]) -> Self::Tree;
    #[doc(hidden)]
    fn tree_refit(tree: &mut Self::Tree, boxes: &[Aabb<D>]);
    #[doc(hidden)]
    fn tree_query(tree: &Self::Tree, query: &Aabb<D>, out: &mut Vec<usize>);

    /// The closest point to `p` (m) on the facet with vertices `v` (m), with its barycentric
    /// weights and feature. `None` for a degenerate facet (zero length or zero area).
    fn project_on_facet(
        p: &SVector<f64, D>,
        v: &[SVector<f64, D>; D],
    ) -> Option<FacetProjection<D>>;

    /// Where the segment from `p0` to `p1` (m) meets the solid box `[-half, half]` (m) first:
    /// the fraction of the way (0 when `p0` is inside or on it) and the box's outward normal
    /// there; `None` when it misses (parry's solid ray cast).
    fn segment_hits_box(
        p0: &SVector<f64, D>,
        p1: &SVector<f64, D>,
        half: &SVector<f64, D>,
    ) -> Option<(f64, SVector<f64, D>)>;

    /// Where the segment from `p0` to `p1` (m) meets the solid ball of radius `radius` (m)
    /// about the origin first: the fraction of the way (0 when `p0` is inside or on it) and the
    /// outward normal there; `None` when it misses (parry's solid ray cast).
    fn segment_hits_ball(
        p0: &SVector<f64, D>,
        p1: &SVector<f64, D>,
        radius: f64,
    ) -> Option<(f64, SVector<f64, D>)>;

    /// The fraction of the way from `p0` to `p1` (m) at which the segment crosses the facet
    /// with vertices `v` (m) (segment in 2D, triangle in 3D; either side); `None` when it
    /// misses (parry's ray cast).
    fn segment_crosses_facet(
        p0: &SVector<f64, D>,
        p1: &SVector<f64, D>,
        v: &[SVector<f64, D>; D],
    ) -> Option<f64>;

    /// The same projection computed by parry (`PointQueryWithLocation`): the test oracle for
    /// [`GeometryDim::project_on_facet`]. Returns the point and the barycentric weights.
    #[doc(hidden)]
    fn parry_project_on_facet(
        p: &SVector<f64, D>,
        v: &[SVector<f64, D>; D],
    ) -> (SVector<f64, D>, [f64; D]);
}

macro_rules! impl_tree {
    ($D:literal, $parry:ident, $to:expr) => {
        type Tree = (
            $parry::partitioning::Bvh,
            $parry::partitioning::BvhWorkspace,
        );

        fn tree_build(boxes: &[Aabb<$D>]) -> Self::Tree {
            let leaves: Vec<$parry::bounding_volume::Aabb> = boxes
                .iter()
                .map(|b| $parry::bounding_volume::Aabb::new($to(&b.min), $to(&b.max)))
                .collect();
            let bvh = $parry::partitioning::Bvh::from_leaves(
                $parry::partitioning::BvhBuildStrategy::Binned,
                &leaves,
            );
            (bvh, Default::default())
        }

        #[cfg(not(feature = "parallel"))]
        fn tree_refit(tree: &mut Self::Tree, boxes: &[Aabb<$D>]) {
            for (i, b) in boxes.iter().enumerate() {
                let aabb = $parry::bounding_volume::Aabb::new($to(&b.min), $to(&b.max));
                // Margin 0: the stored leaf is exactly the new box (no fattening), so queries
                // are exact box tests.
                tree.0.insert_or_update_partially(aabb, i as u32, 0.0);
            }
            tree.0.refit(&mut tree.1);
        }

        #[cfg(feature = "parallel")]
        fn tree_refit(tree: &mut Self::Tree, boxes: &[Aabb<$D>]) {
            let updates: Vec<($parry::bounding_volume::Aabb, u32, f64)> = boxes
                .iter()
                .enumerate()
                .map(|(i, b)| {
                    (
                        $parry::bounding_volume::Aabb::new($to(&b.min), $to(&b.max)),
                        i as u32,
                        0.0,
                    )
                })
                .collect();
            let mut statuses = Vec::new();
            tree.0
                .insert_or_update_batch_partially_parallel(&updates, &mut statuses);
            tree.0.refit_parallel(&mut tree.1);
        }

        fn tree_query(tree: &Self::Tree, query: &Aabb<$D>, out: &mut Vec<usize>) {
            let q = $parry::bounding_volume::Aabb::new($to(&query.min), $to(&query.max));
            out.extend(tree.0.intersect_aabb(&q).map(|i| i as usize));
        }
    };
}

/// The segment casts of [`GeometryDim`] through parry's `RayCast`, the same in 2D and 3D.
macro_rules! impl_casts {
    ($D:literal, $parry:ident, $to:expr, $from:expr) => {
        fn segment_hits_box(
            p0: &SVector<f64, $D>,
            p1: &SVector<f64, $D>,
            half: &SVector<f64, $D>,
        ) -> Option<(f64, SVector<f64, $D>)> {
            use $parry::query::RayCast;
            let ray = $parry::query::Ray::new($to(p0), $to(&(p1 - p0)));
            $parry::shape::Cuboid::new($to(half))
                .cast_local_ray_and_get_normal(&ray, 1.0, true)
                .map(|hit| (hit.time_of_impact, $from(hit.normal)))
        }

        fn segment_hits_ball(
            p0: &SVector<f64, $D>,
            p1: &SVector<f64, $D>,
            radius: f64,
        ) -> Option<(f64, SVector<f64, $D>)> {
            use $parry::query::RayCast;
            let ray = $parry::query::Ray::new($to(p0), $to(&(p1 - p0)));
            $parry::shape::Ball::new(radius)
                .cast_local_ray_and_get_normal(&ray, 1.0, true)
                .map(|hit| (hit.time_of_impact, $from(hit.normal)))
        }
    };
}

impl GeometryDim<2> for Dim<2> {
    impl_tree!(2, parry2d_f64, |v: &SVector<f64, 2>| {
        parry2d_f64::math::Vector::new(v[0], v[1])
    });
    impl_casts!(
        2,
        parry2d_f64,
        |v: &SVector<f64, 2>| parry2d_f64::math::Vector::new(v[0], v[1]),
        |v: parry2d_f64::math::Vector| SVector::<f64, 2>::new(v.x, v.y)
    );

    fn segment_crosses_facet(
        p0: &SVector<f64, 2>,
        p1: &SVector<f64, 2>,
        v: &[SVector<f64, 2>; 2],
    ) -> Option<f64> {
        use parry2d_f64::math::Vector;
        use parry2d_f64::query::RayCast;
        let g = |x: &SVector<f64, 2>| Vector::new(x.x, x.y);
        let ray = parry2d_f64::query::Ray::new(g(p0), g(&(p1 - p0)));
        parry2d_f64::shape::Segment::new(g(&v[0]), g(&v[1])).cast_local_ray(&ray, 1.0, false)
    }

    fn project_on_facet(
        p: &SVector<f64, 2>,
        v: &[SVector<f64, 2>; 2],
    ) -> Option<FacetProjection<2>> {
        let ab = v[1] - v[0];
        let l2 = ab.norm_squared();
        if !(l2.is_finite() && l2 > 0.0) {
            return None;
        }
        let t = (p - v[0]).dot(&ab) / l2;
        let (t, feature) = if t <= 0.0 {
            (0.0, Feature::Vertex(0))
        } else if t >= 1.0 {
            (1.0, Feature::Vertex(1))
        } else {
            (t, Feature::Face)
        };
        Some(FacetProjection {
            point: v[0] + ab * t,
            barycentric: [1.0 - t, t],
            feature,
        })
    }

    fn parry_project_on_facet(
        p: &SVector<f64, 2>,
        v: &[SVector<f64, 2>; 2],
    ) -> (SVector<f64, 2>, [f64; 2]) {
        use parry2d_f64::math::Vector;
        use parry2d_f64::query::PointQueryWithLocation;
        let seg = parry2d_f64::shape::Segment::new(
            Vector::new(v[0].x, v[0].y),
            Vector::new(v[1].x, v[1].y),
        );
        let (proj, loc) = seg.project_local_point_and_get_location(Vector::new(p.x, p.y), false);
        (
            SVector::<f64, 2>::new(proj.point.x, proj.point.y),
            loc.barycentric_coordinates(),
        )
    }
}

impl GeometryDim<3> for Dim<3> {
    impl_tree!(3, parry3d_f64, |v: &SVector<f64, 3>| {
        parry3d_f64::math::Vector::new(v[0], v[1], v[2])
    });
    impl_casts!(
        3,
        parry3d_f64,
        |v: &SVector<f64, 3>| parry3d_f64::math::Vector::new(v[0], v[1], v[2]),
        |v: parry3d_f64::math::Vector| SVector::<f64, 3>::new(v.x, v.y, v.z)
    );

    fn segment_crosses_facet(
        p0: &SVector<f64, 3>,
        p1: &SVector<f64, 3>,
        v: &[SVector<f64, 3>; 3],
    ) -> Option<f64> {
        use parry3d_f64::math::Vector;
        use parry3d_f64::query::RayCast;
        let g = |x: &SVector<f64, 3>| Vector::new(x.x, x.y, x.z);
        let ray = parry3d_f64::query::Ray::new(g(p0), g(&(p1 - p0)));
        parry3d_f64::shape::Triangle::new(g(&v[0]), g(&v[1]), g(&v[2]))
            .cast_local_ray(&ray, 1.0, false)
    }

    fn project_on_facet(
        p: &SVector<f64, 3>,
        v: &[SVector<f64, 3>; 3],
    ) -> Option<FacetProjection<3>> {
        let (a, b, c) = (v[0], v[1], v[2]);
        let ab = b - a;
        let ac = c - a;
        let cross2 = ab.cross(&ac).norm_squared();
        // Zero (or numerically zero) area: no normal, no meaningful projection.
        let floor = 1e-28 * ab.norm_squared() * ac.norm_squared();
        if !cross2.is_finite() || cross2.is_nan() || cross2 <= floor {
            return None;
        }
        let done = |point: SVector<f64, 3>, barycentric: [f64; 3], feature| {
            Some(FacetProjection {
                point,
                barycentric,
                feature,
            })
        };
        // Voronoi regions of the triangle, tested vertex, edge, then face.
        let ap = p - a;
        let d1 = ab.dot(&ap);
        let d2 = ac.dot(&ap);
        if d1 <= 0.0 && d2 <= 0.0 {
            return done(a, [1.0, 0.0, 0.0], Feature::Vertex(0));
        }
        let bp = p - b;
        let d3 = ab.dot(&bp);
        let d4 = ac.dot(&bp);
        if d3 >= 0.0 && d4 <= d3 {
            return done(b, [0.0, 1.0, 0.0], Feature::Vertex(1));
        }
        let vc = d1 * d4 - d3 * d2;
        if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            let t = d1 / (d1 - d3);
            return done(a + ab * t, [1.0 - t, t, 0.0], Feature::Edge(0));
        }
        let cp = p - c;
        let d5 = ab.dot(&cp);
        let d6 = ac.dot(&cp);
        if d6 >= 0.0 && d5 <= d6 {
            return done(c, [0.0, 0.0, 1.0], Feature::Vertex(2));
        }
        let vb = d5 * d2 - d1 * d6;
        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            let t = d2 / (d2 - d6);
            return done(a + ac * t, [1.0 - t, 0.0, t], Feature::Edge(2));
        }
        let va = d3 * d6 - d5 * d4;
        if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
            let t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            return done(b + (c - b) * t, [0.0, 1.0 - t, t], Feature::Edge(1));
        }
        let denom = 1.0 / (va + vb + vc);
        let (wb, wc) = (vb * denom, vc * denom);
        done(
            a + ab * wb + ac * wc,
            [1.0 - wb - wc, wb, wc],
            Feature::Face,
        )
    }

    fn parry_project_on_facet(
        p: &SVector<f64, 3>,
        v: &[SVector<f64, 3>; 3],
    ) -> (SVector<f64, 3>, [f64; 3]) {
        use parry3d_f64::math::Vector;
        use parry3d_f64::query::PointQueryWithLocation;
        let g = |x: &SVector<f64, 3>| Vector::new(x.x, x.y, x.z);
        let tri = parry3d_f64::shape::Triangle::new(g(&v[0]), g(&v[1]), g(&v[2]));
        let (proj, loc) = tri.project_local_point_and_get_location(g(p), false);
        let bary = loc.barycentric_coordinates().unwrap_or([f64::NAN; 3]);
        (
            SVector::<f64, 3>::new(proj.point.x, proj.point.y, proj.point.z),
            bary,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn check<const D: usize>(seed: u64)
    where
        Dim<D>: GeometryDim<D>,
    {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        for _ in 0..2000 {
            let mut v = [SVector::<f64, D>::zeros(); D];
            for x in v.iter_mut() {
                *x = SVector::from_fn(|_, _| rng.random_range(-1.0..1.0));
            }
            let p = SVector::<f64, D>::from_fn(|_, _| rng.random_range(-2.0..2.0));
            let Some(mine) = <Dim<D>>::project_on_facet(&p, &v) else {
                continue;
            };
            let (q, bary) = <Dim<D>>::parry_project_on_facet(&p, &v);
            assert!(
                (mine.point - q).norm() < 1e-9,
                "{:?} vs {:?}",
                mine.point,
                q
            );
            let mut rebuilt = SVector::<f64, D>::zeros();
            for k in 0..D {
                rebuilt += v[k] * mine.barycentric[k];
                assert!((mine.barycentric[k] - bary[k]).abs() < 1e-7);
            }
            assert!((rebuilt - mine.point).norm() < 1e-12);
        }
    }

    #[test]
    fn projection_matches_parry_2d() {
        check::<2>(1);
    }

    #[test]
    fn projection_matches_parry_3d() {
        check::<3>(2);
    }

    /// Segments against a box, a ball and facets: the fraction of the way, the outward
    /// normal, misses.
    #[test]
    fn segment_casts() {
        use nalgebra::{Vector2, Vector3};
        let half = Vector3::new(1.0, 0.1, 1.0);
        let (t, n) = <Dim<3>>::segment_hits_box(
            &Vector3::new(0.0, 1.0, 0.0),
            &Vector3::new(0.0, -1.0, 0.0),
            &half,
        )
        .unwrap();
        assert!((t - 0.45).abs() < 1e-12 && (n - Vector3::y()).norm() < 1e-12);
        assert!(<Dim<3>>::segment_hits_box(
            &Vector3::new(0.0, 1.0, 0.0),
            &Vector3::new(0.0, 0.2, 0.0),
            &half
        )
        .is_none());
        let (t, n) =
            <Dim<2>>::segment_hits_ball(&Vector2::new(-2.0, 0.0), &Vector2::new(2.0, 0.0), 1.0)
                .unwrap();
        assert!((t - 0.25).abs() < 1e-12 && (n + Vector2::x()).norm() < 1e-12);
        let tri = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 0.0, 1.0),
        ];
        let up = Vector3::new(0.2, 1.0, 0.2);
        let down = Vector3::new(0.2, -3.0, 0.2);
        let t = <Dim<3>>::segment_crosses_facet(&up, &down, &tri).unwrap();
        assert!((t - 0.25).abs() < 1e-12);
        assert_eq!(
            <Dim<3>>::segment_crosses_facet(&down, &up, &tri),
            Some(0.75)
        );
        assert!(<Dim<3>>::segment_crosses_facet(&up, &(up * 2.0), &tri).is_none());
        let seg = [Vector2::new(-1.0, 0.0), Vector2::new(1.0, 0.0)];
        let t = <Dim<2>>::segment_crosses_facet(
            &Vector2::new(0.5, 1.0),
            &Vector2::new(0.5, -1.0),
            &seg,
        )
        .unwrap();
        assert!((t - 0.5).abs() < 1e-12);
        assert!(<Dim<2>>::segment_crosses_facet(
            &Vector2::new(1.5, 1.0),
            &Vector2::new(1.5, -1.0),
            &seg
        )
        .is_none());
    }

    #[test]
    fn degenerate_facets_are_none() {
        let z = SVector::<f64, 3>::zeros();
        let x = SVector::<f64, 3>::new(1.0, 0.0, 0.0);
        assert!(<Dim<3>>::project_on_facet(&z, &[z, x, 2.0 * x]).is_none());
        let z2 = SVector::<f64, 2>::zeros();
        assert!(<Dim<2>>::project_on_facet(&z2, &[z2, z2]).is_none());
    }
}
