//! Reference elements: shape functions, their derivatives and quadrature rules.
//!
//! Node orderings follow Gmsh and VTK (they agree for these linear cells). Reference
//! coordinates are stored in 3 slots; 2D elements leave the last one at zero and only the first
//! D are read by the D-dimensional kernels.

use serde::{Deserialize, Serialize};

/// Largest number of nodes of a supported element (Hex8).
pub const MAX_NODES: usize = 8;

/// The supported element types.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ElementKind {
    /// 3-node triangle (2D), linear.
    Tri3,
    /// 4-node quadrilateral (2D), bilinear.
    Quad4,
    /// 4-node tetrahedron (3D), linear.
    Tet4,
    /// 8-node hexahedron (3D), trilinear.
    Hex8,
}

/// A quadrature point on the reference element: coordinates and weight.
#[derive(Debug, Clone, Copy)]
pub struct QuadraturePoint {
    /// Reference coordinates (unused slots are zero).
    pub xi: [f64; 3],
    /// Weight (the weights sum to the reference measure).
    pub weight: f64,
}

const G: f64 = 0.577_350_269_189_625_8; // 1/sqrt(3)

const TRI3_RULE: [QuadraturePoint; 3] = [
    QuadraturePoint {
        xi: [1.0 / 6.0, 1.0 / 6.0, 0.0],
        weight: 1.0 / 6.0,
    },
    QuadraturePoint {
        xi: [2.0 / 3.0, 1.0 / 6.0, 0.0],
        weight: 1.0 / 6.0,
    },
    QuadraturePoint {
        xi: [1.0 / 6.0, 2.0 / 3.0, 0.0],
        weight: 1.0 / 6.0,
    },
];

const QUAD4_RULE: [QuadraturePoint; 4] = [
    QuadraturePoint {
        xi: [-G, -G, 0.0],
        weight: 1.0,
    },
    QuadraturePoint {
        xi: [G, -G, 0.0],
        weight: 1.0,
    },
    QuadraturePoint {
        xi: [G, G, 0.0],
        weight: 1.0,
    },
    QuadraturePoint {
        xi: [-G, G, 0.0],
        weight: 1.0,
    },
];

// Degree-2 rule on the unit tetrahedron (exact for the consistent mass matrix).
const TA: f64 = 0.585_410_196_624_968_5;
const TB: f64 = 0.138_196_601_125_010_5;
const TET4_RULE: [QuadraturePoint; 4] = [
    QuadraturePoint {
        xi: [TB, TB, TB],
        weight: 1.0 / 24.0,
    },
    QuadraturePoint {
        xi: [TA, TB, TB],
        weight: 1.0 / 24.0,
    },
    QuadraturePoint {
        xi: [TB, TA, TB],
        weight: 1.0 / 24.0,
    },
    QuadraturePoint {
        xi: [TB, TB, TA],
        weight: 1.0 / 24.0,
    },
];

const HEX8_RULE: [QuadraturePoint; 8] = [
    QuadraturePoint {
        xi: [-G, -G, -G],
        weight: 1.0,
    },
    QuadraturePoint {
        xi: [G, -G, -G],
        weight: 1.0,
    },
    QuadraturePoint {
        xi: [G, G, -G],
        weight: 1.0,
    },
    QuadraturePoint {
        xi: [-G, G, -G],
        weight: 1.0,
    },
    QuadraturePoint {
        xi: [-G, -G, G],
        weight: 1.0,
    },
    QuadraturePoint {
        xi: [G, -G, G],
        weight: 1.0,
    },
    QuadraturePoint {
        xi: [G, G, G],
        weight: 1.0,
    },
    QuadraturePoint {
        xi: [-G, G, G],
        weight: 1.0,
    },
];

const QUAD_CORNERS: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
const HEX_CORNERS: [[f64; 3]; 8] = [
    [-1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0],
    [1.0, 1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
];

/// Shape function values and reference gradients at one point.
#[derive(Debug, Clone, Copy)]
pub struct ShapeValues {
    /// `N_a`, for `a < nodes`.
    pub n: [f64; MAX_NODES],
    /// `dN_a / dxi_k`.
    pub dn: [[f64; 3]; MAX_NODES],
}

impl ElementKind {
    /// Number of nodes.
    pub const fn nodes(self) -> usize {
        match self {
            ElementKind::Tri3 => 3,
            ElementKind::Quad4 | ElementKind::Tet4 => 4,
            ElementKind::Hex8 => 8,
        }
    }

    /// Spatial dimension of the element.
    pub const fn dimension(self) -> usize {
        match self {
            ElementKind::Tri3 | ElementKind::Quad4 => 2,
            ElementKind::Tet4 | ElementKind::Hex8 => 3,
        }
    }

    /// The quadrature rule used for stiffness, internal forces and consistent mass.
    pub fn quadrature(self) -> &'static [QuadraturePoint] {
        match self {
            ElementKind::Tri3 => &TRI3_RULE,
            ElementKind::Quad4 => &QUAD4_RULE,
            ElementKind::Tet4 => &TET4_RULE,
            ElementKind::Hex8 => &HEX8_RULE,
        }
    }

    /// Shape functions and their reference gradients at `xi`.
    pub fn shape(self, xi: [f64; 3]) -> ShapeValues {
        let mut s = ShapeValues {
            n: [0.0; MAX_NODES],
            dn: [[0.0; 3]; MAX_NODES],
        };
        let [x, y, z] = xi;
        match self {
            ElementKind::Tri3 => {
                s.n[..3].copy_from_slice(&[1.0 - x - y, x, y]);
                s.dn[0] = [-1.0, -1.0, 0.0];
                s.dn[1] = [1.0, 0.0, 0.0];
                s.dn[2] = [0.0, 1.0, 0.0];
            }
            ElementKind::Tet4 => {
                s.n[..4].copy_from_slice(&[1.0 - x - y - z, x, y, z]);
                s.dn[0] = [-1.0, -1.0, -1.0];
                s.dn[1] = [1.0, 0.0, 0.0];
                s.dn[2] = [0.0, 1.0, 0.0];
                s.dn[3] = [0.0, 0.0, 1.0];
            }
            ElementKind::Quad4 => {
                for (a, c) in QUAD_CORNERS.iter().enumerate() {
                    s.n[a] = 0.25 * (1.0 + c[0] * x) * (1.0 + c[1] * y);
                    s.dn[a] = [
                        0.25 * c[0] * (1.0 + c[1] * y),
                        0.25 * c[1] * (1.0 + c[0] * x),
                        0.0,
                    ];
                }
            }
            ElementKind::Hex8 => {
                for (a, c) in HEX_CORNERS.iter().enumerate() {
                    let (fx, fy, fz) = (1.0 + c[0] * x, 1.0 + c[1] * y, 1.0 + c[2] * z);
                    s.n[a] = 0.125 * fx * fy * fz;
                    s.dn[a] = [
                        0.125 * c[0] * fy * fz,
                        0.125 * c[1] * fx * fz,
                        0.125 * c[2] * fx * fy,
                    ];
                }
            }
        }
        s
    }

    /// Reference coordinates of the nodes (used to check Jacobians at the corners).
    pub fn node_coordinates(self) -> &'static [[f64; 3]] {
        const TRI: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        const QUAD: [[f64; 3]; 4] = [
            [-1.0, -1.0, 0.0],
            [1.0, -1.0, 0.0],
            [1.0, 1.0, 0.0],
            [-1.0, 1.0, 0.0],
        ];
        const TET: [[f64; 3]; 4] = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        match self {
            ElementKind::Tri3 => &TRI,
            ElementKind::Quad4 => &QUAD,
            ElementKind::Tet4 => &TET,
            ElementKind::Hex8 => &HEX_CORNERS,
        }
    }

    /// The faces of the cell (edges in 2D), each ordered so that its facet normal
    /// (see [`crate::dim::SpatialDim::facet_measure_normal`]) points out of the cell.
    pub fn faces(self) -> &'static [&'static [usize]] {
        match self {
            ElementKind::Tri3 => &[&[0, 1], &[1, 2], &[2, 0]],
            ElementKind::Quad4 => &[&[0, 1], &[1, 2], &[2, 3], &[3, 0]],
            ElementKind::Tet4 => &[&[0, 2, 1], &[0, 1, 3], &[0, 3, 2], &[1, 2, 3]],
            ElementKind::Hex8 => &[
                &[0, 3, 2, 1],
                &[4, 5, 6, 7],
                &[0, 1, 5, 4],
                &[1, 2, 6, 5],
                &[2, 3, 7, 6],
                &[3, 0, 4, 7],
            ],
        }
    }

    /// Name as used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            ElementKind::Tri3 => "tri3",
            ElementKind::Quad4 => "quad4",
            ElementKind::Tet4 => "tet4",
            ElementKind::Hex8 => "hex8",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [ElementKind; 4] = [
        ElementKind::Tri3,
        ElementKind::Quad4,
        ElementKind::Tet4,
        ElementKind::Hex8,
    ];

    #[test]
    fn partition_of_unity_and_gradients_sum_to_zero() {
        for kind in ALL {
            for q in kind.quadrature() {
                let s = kind.shape(q.xi);
                let sum: f64 = s.n[..kind.nodes()].iter().sum();
                assert!((sum - 1.0).abs() < 1e-14, "{kind:?}");
                for k in 0..3 {
                    let g: f64 = s.dn[..kind.nodes()].iter().map(|d| d[k]).sum();
                    assert!(g.abs() < 1e-14, "{kind:?}");
                }
            }
        }
    }

    #[test]
    fn shape_functions_are_nodal() {
        for kind in ALL {
            for (a, xi) in kind.node_coordinates().iter().enumerate() {
                let s = kind.shape(*xi);
                for b in 0..kind.nodes() {
                    let expected = if a == b { 1.0 } else { 0.0 };
                    assert!(
                        (s.n[b] - expected).abs() < 1e-14,
                        "{kind:?} node {a} fn {b}"
                    );
                }
            }
        }
    }

    #[test]
    fn gradients_match_finite_differences() {
        let xi = [0.21, 0.17, 0.13];
        let eps = 1e-6;
        for kind in ALL {
            let s = kind.shape(xi);
            for k in 0..kind.dimension() {
                let mut p = xi;
                let mut m = xi;
                p[k] += eps;
                m[k] -= eps;
                let (sp, sm) = (kind.shape(p), kind.shape(m));
                for a in 0..kind.nodes() {
                    let fd = (sp.n[a] - sm.n[a]) / (2.0 * eps);
                    assert!((fd - s.dn[a][k]).abs() < 1e-8, "{kind:?} a={a} k={k}");
                }
            }
        }
    }

    #[test]
    fn quadrature_weights_sum_to_reference_measure() {
        let measure = |k: ElementKind| -> f64 { k.quadrature().iter().map(|q| q.weight).sum() };
        assert!((measure(ElementKind::Tri3) - 0.5).abs() < 1e-15);
        assert!((measure(ElementKind::Quad4) - 4.0).abs() < 1e-15);
        assert!((measure(ElementKind::Tet4) - 1.0 / 6.0).abs() < 1e-15);
        assert!((measure(ElementKind::Hex8) - 8.0).abs() < 1e-15);
    }

    #[test]
    fn tet_rule_integrates_quadratics_exactly() {
        // int_T x^2 = 1/60, int_T x y = 1/120 on the unit tetrahedron.
        let q = ElementKind::Tet4.quadrature();
        let xx: f64 = q.iter().map(|p| p.weight * p.xi[0] * p.xi[0]).sum();
        let xy: f64 = q.iter().map(|p| p.weight * p.xi[0] * p.xi[1]).sum();
        assert!((xx - 1.0 / 60.0).abs() < 1e-15);
        assert!((xy - 1.0 / 120.0).abs() < 1e-15);
    }
}
