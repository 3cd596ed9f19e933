//! Where 2D and 3D differ.
//!
//! Everything in softway is generic over `const D: usize` with the single bound
//! `where Dim<D>: SpatialDim<D>`. Determinants, inverses, facet normals, the embedding of a
//! D-dimensional gradient in the 3D strain of the material law, angular velocities and
//! rotations all live here, implemented for `Dim<2>` and `Dim<3>` only (the trait is sealed);
//! the point-to-facet projection and the bounding-volume tree in its supertrait `GeometryDim`
//! (`crate::geometry`). A few `D == 2` branches remain where a facet is a segment rather
//! than a triangle (the contact areas, the barycentric weights, the free ends of polylines)
//! and in the Rerun drawing.

use nalgebra::{Matrix2, Matrix3, Rotation2, Rotation3, SMatrix, SVector, Vector2, Vector3};
use serde::{Deserialize, Serialize};

/// A 6-component Voigt vector: `[xx, yy, zz, yz, xz, xy]`; strains carry engineering shears
/// (`2 eps_ij`), stresses the tensor components.
pub type Voigt = SVector<f64, 6>;
/// A 6x6 Voigt matrix (material tangent).
pub type VoigtMatrix = SMatrix<f64, 6, 6>;

/// How a 2D model stands for a 3D body.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Kinematics {
    /// 2D, `eps_zz = 0`; quantities per unit thickness.
    #[default]
    PlaneStrain,
    /// 2D, `sigma_zz = 0`; quantities per unit thickness.
    PlaneStress,
    /// 2D, x = r >= 0, y = the axis; hoop strain `u_r / r`; quantities over the whole revolution.
    Axisymmetric,
    /// 3D solid.
    Solid,
}

/// Marker type carrying the spatial dimension.
#[derive(Debug, Clone, Copy, Default)]
pub struct Dim<const D: usize>;

mod sealed {
    pub trait Sealed {}
    impl Sealed for super::Dim<2> {}
    impl Sealed for super::Dim<3> {}
}

/// Dimension-specific operations; implemented for `Dim<2>` and `Dim<3>` only.
pub trait SpatialDim<const D: usize>:
    sealed::Sealed + crate::geometry::GeometryDim<D> + Send + Sync + 'static
{
    /// Number of angular velocity components (1 in 2D, 3 in 3D).
    const ANGULAR: usize;

    /// Number of values that store a rotation (an obstacle's pose in the state): the angle
    /// (rad) in 2D, the rotation matrix's 9 entries (column-major) in 3D.
    const ROTATION: usize;

    /// Determinant of a D x D matrix.
    fn det(m: &SMatrix<f64, D, D>) -> f64;

    /// Inverse of a D x D matrix, `None` when singular.
    fn inverse(m: &SMatrix<f64, D, D>) -> Option<SMatrix<f64, D, D>>;

    /// Measure (length in 2D, area in 3D) and unit outward normal of a boundary facet
    /// (a segment in 2D, a triangle in 3D) whose nodes are ordered so that the body lies on
    /// the left of the segment (2D) or below the counter-clockwise triangle (3D).
    fn facet_measure_normal(p: &[SVector<f64, D>; D]) -> (f64, SVector<f64, D>);

    /// The velocity `omega x r` of a rigid spin; `omega` has [`SpatialDim::ANGULAR`] components.
    fn spin_velocity(omega: &[f64], r: &SVector<f64, D>) -> SVector<f64, D>;

    /// The rotation matrix of [`SpatialDim::ROTATION`] stored values.
    fn rotation_matrix(stored: &[f64]) -> SMatrix<f64, D, D>;

    /// The stored values of a rotation matrix.
    fn rotation_values(r: &SMatrix<f64, D, D>) -> Vec<f64>;

    /// The stored rotation `stored` followed by the turn `exp(turn)` (`turn`: a rotation vector,
    /// angular velocity times time, [`SpatialDim::ANGULAR`] components). 2D angles add exactly.
    fn turned(stored: &[f64], turn: &[f64]) -> Vec<f64>;

    /// The rotation vector of the turn `a` followed by the turn `b` (`log(exp(b) exp(a))`).
    fn compose_turns(a: &[f64], b: &[f64]) -> Vec<f64>;

    /// The shortest turn (a rotation vector, [`SpatialDim::ANGULAR`] components) that takes
    /// the stored rotation `stored` to the rotation matrix `target`: `log(target stored^T)`.
    fn turn_between(stored: &[f64], target: &SMatrix<f64, D, D>) -> Vec<f64>;

    /// The strain-rate operator of one node: maps the node's velocity to the Voigt strain rate,
    /// given the shape function value `n`, its spatial gradient `grad` and the radius `r`
    /// (used by axisymmetric kinematics only).
    fn strain_operator(
        kinematics: Kinematics,
        n: f64,
        grad: &SVector<f64, D>,
        r: f64,
    ) -> SMatrix<f64, 6, D>;

    /// One node's share of the 3D gradient of a field whose nodal value is `u`: the in-plane
    /// block `u grad^T`, and in axisymmetric kinematics the hoop term `n u_r / r` in the zz
    /// slot (the updated-Lagrangian kinematics and the geometric stiffness use it).
    fn gradient_3d(
        kinematics: Kinematics,
        n: f64,
        grad: &SVector<f64, D>,
        r: f64,
        u: &SVector<f64, D>,
    ) -> Matrix3<f64>;

    /// The D x D block of a 3 x 3 tensor.
    fn in_plane_block(t: &Matrix3<f64>) -> SMatrix<f64, D, D>;

    /// The measure factor of a quadrature point: 1 for plane and solid kinematics, `2 pi r`
    /// for axisymmetric ones (integrals are over the whole revolution).
    fn measure_factor(kinematics: Kinematics, position: &SVector<f64, D>) -> f64;

    /// Whether these kinematics belong to this dimension.
    fn supports(kinematics: Kinematics) -> bool;

    /// Embeds a point in 3D space (z = 0 in 2D), for output files.
    fn to_3d(v: &SVector<f64, D>) -> [f64; 3];
}

impl SpatialDim<2> for Dim<2> {
    const ANGULAR: usize = 1;
    const ROTATION: usize = 1;

    fn det(m: &Matrix2<f64>) -> f64 {
        m.determinant()
    }

    fn inverse(m: &Matrix2<f64>) -> Option<Matrix2<f64>> {
        m.try_inverse()
    }

    fn facet_measure_normal(p: &[Vector2<f64>; 2]) -> (f64, Vector2<f64>) {
        let t = p[1] - p[0];
        let length = t.norm();
        if length == 0.0 {
            return (0.0, Vector2::zeros());
        }
        // Body on the left of p0 -> p1: the outward normal is the tangent turned clockwise.
        (length, Vector2::new(t.y, -t.x) / length)
    }

    fn spin_velocity(omega: &[f64], r: &Vector2<f64>) -> Vector2<f64> {
        omega[0] * Vector2::new(-r.y, r.x)
    }

    fn rotation_matrix(stored: &[f64]) -> Matrix2<f64> {
        Rotation2::new(stored[0]).into_inner()
    }

    fn rotation_values(r: &Matrix2<f64>) -> Vec<f64> {
        vec![r[(1, 0)].atan2(r[(0, 0)])]
    }

    fn turned(stored: &[f64], turn: &[f64]) -> Vec<f64> {
        vec![stored[0] + turn[0]]
    }

    fn compose_turns(a: &[f64], b: &[f64]) -> Vec<f64> {
        vec![a[0] + b[0]]
    }

    fn turn_between(stored: &[f64], target: &Matrix2<f64>) -> Vec<f64> {
        let difference = target[(1, 0)].atan2(target[(0, 0)]) - stored[0];
        // Wrapped to (-pi, pi]: the shortest turn.
        let two_pi = 2.0 * std::f64::consts::PI;
        vec![difference - two_pi * (difference / two_pi).round()]
    }

    fn strain_operator(
        kinematics: Kinematics,
        n: f64,
        grad: &Vector2<f64>,
        r: f64,
    ) -> SMatrix<f64, 6, 2> {
        let mut b = SMatrix::<f64, 6, 2>::zeros();
        b[(0, 0)] = grad.x;
        b[(1, 1)] = grad.y;
        b[(5, 0)] = grad.y;
        b[(5, 1)] = grad.x;
        if kinematics == Kinematics::Axisymmetric {
            // Hoop strain u_r / r sits in the out-of-plane slot.
            b[(2, 0)] = if r > 0.0 { n / r } else { 0.0 };
        }
        b
    }

    fn gradient_3d(
        kinematics: Kinematics,
        n: f64,
        grad: &Vector2<f64>,
        r: f64,
        u: &Vector2<f64>,
    ) -> Matrix3<f64> {
        let mut g = Matrix3::zeros();
        g.fixed_view_mut::<2, 2>(0, 0)
            .copy_from(&(u * grad.transpose()));
        if kinematics == Kinematics::Axisymmetric && r > 0.0 {
            g[(2, 2)] = n * u.x / r;
        }
        g
    }

    fn in_plane_block(t: &Matrix3<f64>) -> Matrix2<f64> {
        t.fixed_view::<2, 2>(0, 0).into_owned()
    }

    fn measure_factor(kinematics: Kinematics, position: &Vector2<f64>) -> f64 {
        match kinematics {
            Kinematics::Axisymmetric => 2.0 * std::f64::consts::PI * position.x,
            _ => 1.0,
        }
    }

    fn supports(kinematics: Kinematics) -> bool {
        kinematics != Kinematics::Solid
    }

    fn to_3d(v: &Vector2<f64>) -> [f64; 3] {
        [v.x, v.y, 0.0]
    }
}

impl SpatialDim<3> for Dim<3> {
    const ANGULAR: usize = 3;
    const ROTATION: usize = 9;

    fn det(m: &Matrix3<f64>) -> f64 {
        m.determinant()
    }

    fn inverse(m: &Matrix3<f64>) -> Option<Matrix3<f64>> {
        m.try_inverse()
    }

    fn facet_measure_normal(p: &[Vector3<f64>; 3]) -> (f64, Vector3<f64>) {
        let c = (p[1] - p[0]).cross(&(p[2] - p[0]));
        let twice_area = c.norm();
        if twice_area == 0.0 {
            return (0.0, Vector3::zeros());
        }
        (0.5 * twice_area, c / twice_area)
    }

    fn spin_velocity(omega: &[f64], r: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(omega[0], omega[1], omega[2]).cross(r)
    }

    fn rotation_matrix(stored: &[f64]) -> Matrix3<f64> {
        Matrix3::from_column_slice(stored)
    }

    fn rotation_values(r: &Matrix3<f64>) -> Vec<f64> {
        r.as_slice().to_vec()
    }

    fn turned(stored: &[f64], turn: &[f64]) -> Vec<f64> {
        let r =
            Rotation3::new(Vector3::from_column_slice(turn)) * Matrix3::from_column_slice(stored);
        r.as_slice().to_vec()
    }

    fn compose_turns(a: &[f64], b: &[f64]) -> Vec<f64> {
        // No round-off through exp and log when one of them does not turn.
        if a.iter().all(|x| *x == 0.0) {
            return b.to_vec();
        }
        if b.iter().all(|x| *x == 0.0) {
            return a.to_vec();
        }
        let (a, b) = (Vector3::from_column_slice(a), Vector3::from_column_slice(b));
        let r = Rotation3::new(b) * Rotation3::new(a);
        r.scaled_axis().as_slice().to_vec()
    }

    fn turn_between(stored: &[f64], target: &Matrix3<f64>) -> Vec<f64> {
        let relative = target * Matrix3::from_column_slice(stored).transpose();
        Rotation3::from_matrix(&relative)
            .scaled_axis()
            .as_slice()
            .to_vec()
    }

    fn strain_operator(
        _kinematics: Kinematics,
        _n: f64,
        grad: &Vector3<f64>,
        _r: f64,
    ) -> SMatrix<f64, 6, 3> {
        let mut b = SMatrix::<f64, 6, 3>::zeros();
        b[(0, 0)] = grad.x;
        b[(1, 1)] = grad.y;
        b[(2, 2)] = grad.z;
        b[(3, 1)] = grad.z;
        b[(3, 2)] = grad.y;
        b[(4, 0)] = grad.z;
        b[(4, 2)] = grad.x;
        b[(5, 0)] = grad.y;
        b[(5, 1)] = grad.x;
        b
    }

    fn gradient_3d(
        _kinematics: Kinematics,
        _n: f64,
        grad: &Vector3<f64>,
        _r: f64,
        u: &Vector3<f64>,
    ) -> Matrix3<f64> {
        u * grad.transpose()
    }

    fn in_plane_block(t: &Matrix3<f64>) -> Matrix3<f64> {
        *t
    }

    fn measure_factor(_kinematics: Kinematics, _position: &Vector3<f64>) -> f64 {
        1.0
    }

    fn supports(kinematics: Kinematics) -> bool {
        kinematics == Kinematics::Solid
    }

    fn to_3d(v: &Vector3<f64>) -> [f64; 3] {
        [v.x, v.y, v.z]
    }
}
