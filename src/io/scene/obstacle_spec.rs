//! `[[obstacles]]`: names, shapes (halfspace, box, ball, polyline / trimesh), velocity or
//! motion schedule (with angular velocities about the pivot) and friction, validated for
//! dimension D.

use nalgebra::SVector;

use super::schema::{ObstacleSection, ShapeSpec};
use super::LoadedScene;
use crate::contact::{MotionSegment, Obstacle, ObstacleShape};
use crate::dim::{Dim, SpatialDim};
use crate::error::{Error, Result};

impl LoadedScene {
    /// `obstacles.{o}`: name, shape, velocity or motion, pivot, friction.
    pub(super) fn obstacle<const D: usize>(
        &self,
        o: usize,
        spec: &ObstacleSection,
    ) -> Result<Obstacle<D>>
    where
        Dim<D>: SpatialDim<D>,
    {
        let key = format!("obstacles.{o}");
        let earlier = self.file.obstacles[..o].iter().map(|x| x.name.as_str());
        self.unique_name(&key, earlier, &spec.name, "obstacle")?;
        let shape = self.shape::<D>(&format!("{key}.shape"), &spec.shape)?;
        let mut obstacle = Obstacle::new(spec.name.clone(), shape);
        if let Some(v) = &spec.velocity {
            obstacle.velocity = self.vector::<D>(&format!("{key}.velocity"), v)?;
        }
        if let Some(motion) = &spec.motion {
            if spec.velocity.is_some() {
                return Err(self.error(
                    &format!("{key}.motion"),
                    "both `velocity` and `motion`",
                    "one of them: a constant `velocity` or a `motion` schedule",
                ));
            }
            let mut previous = 0.0;
            for (i, m) in motion.iter().enumerate() {
                let mk = format!("{key}.motion.{i}");
                if !(m.until > previous && m.until.is_finite()) {
                    return Err(self.error(
                        &format!("{mk}.until"),
                        m.until,
                        format!("a finite time [s] after the previous entry's ({previous})"),
                    ));
                }
                previous = m.until;
                let velocity = self.vector::<D>(&format!("{mk}.velocity"), &m.velocity)?;
                let angular_velocity = match &m.angular_velocity {
                    Some(w) => self.angular::<D>(&format!("{mk}.angular_velocity"), w)?,
                    None => Vec::new(),
                };
                obstacle.motion.push(MotionSegment {
                    until: m.until,
                    velocity,
                    angular_velocity,
                });
            }
        }
        if let Some(p) = &spec.pivot {
            obstacle.pivot = Some(self.vector::<D>(&format!("{key}.pivot"), p)?);
        }
        if let Some(f) = &spec.friction {
            obstacle.friction = Some(self.friction(&format!("{key}.friction"), f)?);
        }
        Ok(obstacle)
    }

    fn shape<const D: usize>(&self, key: &str, s: &ShapeSpec) -> Result<ObstacleShape<D>>
    where
        Dim<D>: SpatialDim<D>,
    {
        Ok(match s {
            ShapeSpec::Halfspace { point, normal } => {
                let n = self.vector::<D>(&format!("{key}.normal"), normal)?;
                if n.norm() == 0.0 {
                    return Err(self.error(
                        &format!("{key}.normal"),
                        "a zero vector",
                        "a non-zero normal",
                    ));
                }
                ObstacleShape::Halfspace {
                    point: self.vector::<D>(&format!("{key}.point"), point)?,
                    normal: n.normalize(),
                }
            }
            ShapeSpec::Box {
                center,
                half_extents,
            } => {
                let h = self.vector::<D>(&format!("{key}.half_extents"), half_extents)?;
                if h.iter().any(|x| *x <= 0.0) {
                    return Err(self.error(
                        &format!("{key}.half_extents"),
                        format!("{:?}", h.as_slice()),
                        "positive half extents [m]",
                    ));
                }
                ObstacleShape::Box {
                    center: self.vector::<D>(&format!("{key}.center"), center)?,
                    half_extents: h,
                }
            }
            ShapeSpec::Ball { center, radius } => ObstacleShape::Ball {
                center: self.vector::<D>(&format!("{key}.center"), center)?,
                radius: self.positive(&format!("{key}.radius"), *radius, "m")?,
            },
            ShapeSpec::Polyline {
                vertices,
                indices,
                file,
            }
            | ShapeSpec::Trimesh {
                vertices,
                indices,
                file,
            } => {
                let is_polyline = matches!(s, ShapeSpec::Polyline { .. });
                if is_polyline != (D == 2) {
                    return Err(self.error(
                        &format!("{key}.type"),
                        if is_polyline {
                            "\"polyline\" in 3D"
                        } else {
                            "\"trimesh\" in 2D"
                        },
                        if D == 2 {
                            "\"polyline\" in 2D"
                        } else {
                            "\"trimesh\" in 3D"
                        },
                    ));
                }
                if file.is_some() {
                    return Err(Error::NotAvailable {
                        feature: format!("{}: `{key}.file`", self.path.display()),
                        detail: "give the obstacle's `vertices` and `indices` inline".into(),
                    });
                }
                let verts = vertices.as_ref().ok_or_else(|| {
                    self.error(&format!("{key}.vertices"), "nothing", "a list of vertices")
                })?;
                let idx = indices.as_ref().ok_or_else(|| {
                    self.error(
                        &format!("{key}.indices"),
                        "nothing",
                        format!("a list of facets of {D} vertex indices"),
                    )
                })?;
                let what = if D == 2 { "segment" } else { "triangle" };
                if verts.is_empty() {
                    return Err(self.error(
                        &format!("{key}.vertices"),
                        "an empty list",
                        format!("the vertices of at least one {what}"),
                    ));
                }
                if idx.is_empty() {
                    return Err(self.error(
                        &format!("{key}.indices"),
                        "an empty list",
                        format!("at least one {what} of {D} vertex indices"),
                    ));
                }
                let mut vs = Vec::new();
                for (i, v) in verts.iter().enumerate() {
                    vs.push(self.vector::<D>(&format!("{key}.vertices.{i}"), v)?);
                }
                let mut facets = Vec::new();
                for (i, f) in idx.iter().enumerate() {
                    if f.len() != D || f.iter().any(|&k| k < 0 || k as usize >= vs.len()) {
                        return Err(self.error(
                            &format!("{key}.indices.{i}"),
                            format!("{f:?}"),
                            format!("{D} indices below {}", vs.len()),
                        ));
                    }
                    let ids: Vec<usize> = f.iter().map(|&k| k as usize).collect();
                    let mut corners = [SVector::<f64, D>::zeros(); D];
                    for (c, &k) in corners.iter_mut().zip(&ids) {
                        *c = vs[k];
                    }
                    // The measure, computed as the contact search does: zero is a facet with
                    // no normal, infinite one whose coordinates overflow when squared.
                    let (measure, _) = <Dim<D>>::facet_measure_normal(&corners);
                    if !(measure > 0.0 && measure.is_finite()) {
                        let (shape, size) = if D == 2 {
                            ("segment", "length")
                        } else {
                            ("triangle", "area")
                        };
                        let found = if measure.is_finite() {
                            format!("{f:?}: a {shape} of {size} {}", super::plain(measure))
                        } else {
                            // 1e200 m is finite; its square, which the measure takes, is not.
                            format!(
                                "{f:?}: a {shape} whose {size} overflows (coordinates beyond \
                                 about 1e154 m)"
                            )
                        };
                        return Err(self.error(
                            &format!("{key}.indices.{i}"),
                            found,
                            format!("a {shape} of finite, positive {size}"),
                        ));
                    }
                    facets.push(ids);
                }
                ObstacleShape::Facets {
                    vertices: vs,
                    indices: facets,
                }
            }
        })
    }
}
