//! `mesh = { ... }`: a body's mesh from a generator (rectangle, box, annulus, polygon, with
//! the 3D extrusion) or a Gmsh file, with the keys each one accepts.

use std::collections::BTreeMap;

use nalgebra::SVector;

use super::plain;
use super::schema::MeshSpec;
use super::LoadedScene;
use crate::dim::{Dim, SpatialDim};
use crate::element::ElementKind;
use crate::error::{Error, Result};
use crate::mesh::{generators, Mesh};

impl LoadedScene {
    fn cells<const N: usize>(&self, key: &str, cells: &Option<Vec<i64>>) -> Result<[usize; N]> {
        let c = cells
            .as_ref()
            .ok_or_else(|| self.error(key, "nothing", format!("{N} positive integers")))?;
        if c.len() != N || c.iter().any(|&n| n < 1) {
            return Err(self.error(key, format!("{c:?}"), format!("{N} positive integers")));
        }
        // The generators multiply these; a huge request must be an input error, not an
        // arithmetic overflow (a panic) or an allocation failure.
        const MAX_CELLS: i64 = 100_000_000;
        let total = c.iter().try_fold(1i64, |acc, &n| acc.checked_mul(n));
        if total.is_none_or(|t| t > MAX_CELLS) {
            return Err(self.error(
                key,
                format!("{c:?}"),
                format!("at most {MAX_CELLS} cells in all"),
            ));
        }
        // Before the generator allocates: the grid's nodes times N unknowns each, and the
        // least memory their matrices take (see `limits`).
        let nodes: f64 = c.iter().map(|&n| n as f64 + 1.0).product();
        let unknowns = nodes * N as f64;
        let triplets = total.unwrap_or(0) as f64 * super::limits::grid_cell_triplets(N);
        let needed = super::memory_lower_bound(unknowns, triplets, N);
        let limit = super::memory_limit();
        if needed > limit {
            return Err(self.error(
                key,
                format!(
                    "{c:?}: {nodes:.1e} nodes, {unknowns:.1e} unknowns, at least {} of matrices",
                    super::limits::bytes(needed)
                ),
                format!(
                    "a mesh whose matrices fit in this machine's {} of memory (fewer cells)",
                    super::limits::bytes(limit)
                ),
            ));
        }
        let mut out = [0usize; N];
        for (o, &n) in out.iter_mut().zip(c) {
            *o = n as usize;
        }
        Ok(out)
    }

    fn element(&self, key: &str, e: &Option<String>, default: ElementKind) -> Result<ElementKind> {
        let kind = match e.as_deref() {
            None => default,
            Some("tri3") => ElementKind::Tri3,
            Some("quad4") => ElementKind::Quad4,
            Some("tet4") => ElementKind::Tet4,
            Some("hex8") => ElementKind::Hex8,
            Some(other) => {
                return Err(self.error(
                    key,
                    format!("\"{other}\""),
                    "\"tri3\", \"quad4\", \"tet4\" or \"hex8\"",
                ))
            }
        };
        if kind.dimension() != default.dimension() {
            return Err(self.error(
                key,
                format!("\"{}\"", kind.name()),
                if default.dimension() == 2 {
                    "\"tri3\" or \"quad4\" in 2D"
                } else {
                    "\"tet4\" or \"hex8\" in 3D"
                },
            ));
        }
        Ok(kind)
    }

    /// Builds a body's mesh; returns it with the named node sets of a mesh file.
    pub(super) fn mesh<const D: usize>(
        &self,
        key: &str,
        spec: &MeshSpec,
        body: &str,
    ) -> Result<(Mesh<D>, BTreeMap<String, Vec<usize>>)>
    where
        Dim<D>: SpatialDim<D>,
    {
        let default_kind = if D == 2 {
            ElementKind::Quad4
        } else {
            ElementKind::Hex8
        };
        let wrap = |e: Error| match e {
            Error::InvalidParameter {
                name,
                found,
                expected,
            } => self.error(&format!("{key}.{name}"), found, expected),
            other => other,
        };
        let present = [
            ("min", spec.min.is_some()),
            ("max", spec.max.is_some()),
            ("cells", spec.cells.is_some()),
            ("element", spec.element.is_some()),
            ("center", spec.center.is_some()),
            ("inner_radius", spec.inner_radius.is_some()),
            ("outer_radius", spec.outer_radius.is_some()),
            ("vertices", spec.vertices.is_some()),
            ("length", spec.length.is_some()),
        ];
        match (&spec.generator, &spec.file) {
            (Some(_), Some(_)) => {
                Err(self.error(key, "both `generator` and `file`", "one of them"))
            }
            (None, None) => Err(self.error(
                key,
                "neither `generator` nor `file`",
                "a generator (rectangle, box, annulus, polygon) or a Gmsh file",
            )),
            (None, Some(file)) => {
                // A mesh file brings its own cells: generator keys would be silently ignored.
                if let Some((name, _)) = present.iter().find(|(_, is)| *is) {
                    return Err(self.error(
                        &format!("{key}.{name}"),
                        format!("`{name}` with a mesh file"),
                        "only `file` (the generator keys do not apply to a Gmsh file)",
                    ));
                }
                let path = self.base_dir().join(file);
                let unreadable = |message: String| {
                    self.error(
                        &format!("{key}.file"),
                        format!("{} ({message})", path.display()),
                        "a readable Gmsh MSH 2.2 or 4.1 file",
                    )
                };
                let gmsh =
                    crate::io::gmsh::read_gmsh(&path).map_err(|e| unreadable(e.to_string()))?;
                let mesh = crate::io::gmsh::from_gmsh::<D>(&gmsh).map_err(unreadable)?;
                let groups = mesh.node_sets.clone().into_iter().collect();
                mesh.validate_topology(body).map_err(|e| match e {
                    Error::Mesh { message, .. } => self.error(
                        &format!("{key}.file"),
                        format!("{} ({message})", path.display()),
                        "a mesh whose cells use every node, with finite coordinates",
                    ),
                    other => other,
                })?;
                // Cells named by their Gmsh element tag, the number a user sees in Gmsh.
                if let Err(Error::InvertedElement {
                    cell,
                    kind,
                    jacobian,
                    ..
                }) = mesh.check_quality(body)
                {
                    let tag = crate::io::gmsh::cell_tags::<D>(&gmsh).get(cell).copied();
                    return Err(self.error(
                        key,
                        format!(
                            "Gmsh element {} (cell {cell} of the body) {kind} (Jacobian \
                             determinant {jacobian:.3e})",
                            tag.map_or("?".to_string(), |t| t.to_string())
                        ),
                        "cells with a positive Jacobian everywhere (check node ordering and \
                         geometry)",
                    ));
                }
                Ok((mesh, groups))
            }
            (Some(g), None) => {
                let allowed: &[&str] = match g.as_str() {
                    "rectangle" | "box" => &["min", "max", "cells", "element"],
                    "annulus" => &[
                        "center",
                        "inner_radius",
                        "outer_radius",
                        "cells",
                        "element",
                        "length",
                    ],
                    "polygon" => &["vertices", "cells", "element", "length"],
                    other => {
                        return Err(self.error(
                            &format!("{key}.generator"),
                            format!("\"{other}\""),
                            "\"rectangle\", \"box\", \"annulus\" or \"polygon\"",
                        ))
                    }
                };
                for (name, is) in present {
                    if is && !allowed.contains(&name) {
                        return Err(self.error(
                            &format!("{key}.{name}"),
                            format!("`{name}` with generator \"{g}\""),
                            format!("only {allowed:?}"),
                        ));
                    }
                }
                let need = |name: &str, v: &Option<Vec<f64>>| -> Result<Vec<f64>> {
                    v.clone().ok_or_else(|| {
                        self.error(
                            &format!("{key}.{name}"),
                            "nothing",
                            format!("`{name}` for generator \"{g}\""),
                        )
                    })
                };
                let kind = self.element(&format!("{key}.element"), &spec.element, default_kind)?;
                let mesh3 = |m: Mesh<3>| -> Mesh<D> { convert_mesh::<3, D>(m) };
                let mesh2 = |m: Mesh<2>| -> Mesh<D> { convert_mesh::<2, D>(m) };
                let mesh: Mesh<D> = match (g.as_str(), D) {
                    ("rectangle", 2) => {
                        let min =
                            self.vector::<2>(&format!("{key}.min"), &need("min", &spec.min)?)?;
                        let max =
                            self.vector::<2>(&format!("{key}.max"), &need("max", &spec.max)?)?;
                        let cells = self.cells::<2>(&format!("{key}.cells"), &spec.cells)?;
                        mesh2(generators::rectangle(min, max, cells, kind).map_err(wrap)?)
                    }
                    ("box", 3) => {
                        let min =
                            self.vector::<3>(&format!("{key}.min"), &need("min", &spec.min)?)?;
                        let max =
                            self.vector::<3>(&format!("{key}.max"), &need("max", &spec.max)?)?;
                        let cells = self.cells::<3>(&format!("{key}.cells"), &spec.cells)?;
                        mesh3(generators::cuboid(min, max, cells, kind).map_err(wrap)?)
                    }
                    ("rectangle", _) | ("box", _) => {
                        return Err(self.error(
                            &format!("{key}.generator"),
                            format!("\"{g}\" in {D}D"),
                            if D == 2 {
                                "\"rectangle\" in 2D (\"box\" is 3D)"
                            } else {
                                "\"box\" in 3D (\"rectangle\" is 2D)"
                            },
                        ))
                    }
                    ("annulus", _) | ("polygon", _) => {
                        let base_kind = if D == 3 { ElementKind::Quad4 } else { kind };
                        let base = if g == "annulus" {
                            let c = need("center", &spec.center)?;
                            let center = self.vector::<D>(&format!("{key}.center"), &c)?;
                            let ri = spec.inner_radius.ok_or_else(|| {
                                self.error(
                                    &format!("{key}.inner_radius"),
                                    "nothing",
                                    "a radius > 0 [m]",
                                )
                            })?;
                            let ro = spec.outer_radius.ok_or_else(|| {
                                self.error(
                                    &format!("{key}.outer_radius"),
                                    "nothing",
                                    "a radius > inner_radius [m]",
                                )
                            })?;
                            // Each radius blamed by its own key (the generator's message
                            // would name outer_radius for a NaN inner one).
                            let ri = self.positive(&format!("{key}.inner_radius"), ri, "m")?;
                            if !(ro > ri && ro.is_finite()) {
                                return Err(self.error(
                                    &format!("{key}.outer_radius"),
                                    ro,
                                    format!("a finite radius > inner_radius = {} [m]", plain(ri)),
                                ));
                            }
                            let cells = if D == 2 {
                                self.cells::<2>(&format!("{key}.cells"), &spec.cells)?
                            } else {
                                let c3 = self.cells::<3>(&format!("{key}.cells"), &spec.cells)?;
                                [c3[0], c3[1]]
                            };
                            generators::annulus(
                                nalgebra::Vector2::new(center[0], center[1]),
                                ri,
                                ro,
                                cells,
                                base_kind,
                            )
                            .map_err(wrap)?
                        } else {
                            let verts = spec.vertices.as_ref().ok_or_else(|| {
                                self.error(
                                    &format!("{key}.vertices"),
                                    "nothing",
                                    "a list of [x, y] vertices",
                                )
                            })?;
                            let mut v2 = Vec::new();
                            for (i, v) in verts.iter().enumerate() {
                                v2.push(self.vector::<2>(&format!("{key}.vertices.{i}"), v)?);
                            }
                            let cells = if D == 2 {
                                self.cells::<2>(&format!("{key}.cells"), &spec.cells)?
                            } else {
                                let c3 = self.cells::<3>(&format!("{key}.cells"), &spec.cells)?;
                                [c3[0], c3[1]]
                            };
                            generators::polygon(&v2, cells, base_kind).map_err(wrap)?
                        };
                        if D == 2 {
                            if spec.length.is_some() {
                                return Err(self.error(
                                    &format!("{key}.length"),
                                    "a length in 2D",
                                    "no `length` in 2D (it is the 3D extrusion)",
                                ));
                            }
                            mesh2(base)
                        } else {
                            let length = spec.length.ok_or_else(|| {
                                self.error(
                                    &format!("{key}.length"),
                                    "nothing",
                                    "the extrusion length along z [m] in 3D",
                                )
                            })?;
                            self.positive(&format!("{key}.length"), length, "m")?;
                            let layers = self.cells::<3>(&format!("{key}.cells"), &spec.cells)?[2];
                            let z0 = if g == "annulus" {
                                self.vector::<D>(
                                    &format!("{key}.center"),
                                    spec.center.as_deref().unwrap_or(&[]),
                                )?[D - 1]
                                    - length / 2.0
                            } else {
                                0.0
                            };
                            mesh3(
                                generators::extrude(&base, z0, z0 + length, layers, kind)
                                    .map_err(wrap)?,
                            )
                        }
                    }
                    _ => unreachable!("generator names are checked above"),
                };
                Ok((mesh, BTreeMap::new()))
            }
        }
    }
}

/// Re-types a mesh whose dimension is known to equal D at run time.
fn convert_mesh<const A: usize, const D: usize>(m: Mesh<A>) -> Mesh<D> {
    assert_eq!(A, D, "dimension checked by the caller");
    Mesh {
        nodes: m
            .nodes
            .iter()
            .map(|x| SVector::<f64, D>::from_column_slice(x.as_slice()))
            .collect(),
        blocks: m.blocks,
        node_sets: m.node_sets,
    }
}
