//! Validation of a parsed scene into typed values for dimension D: settings, contact, bodies
//! (their meshes in `mesh_spec`, obstacle shapes in `obstacle_spec`), probes and output.

use std::collections::BTreeMap;

use nalgebra::SVector;

use super::schema::{
    AngularSpec, BetaSpec, BodySection, ComponentsSpec, ConstraintSection, FrictionSpec,
    MaterialSpec,
};
use super::{LoadedScene, OutputOptions, Probe, Scene};
use crate::contact::resolution::DEFAULT_REGULARIZATION;
use crate::contact::{
    ContactMethod, ContactSettings, FrictionLaw, GapDisplacement, MasterNodes, PenaltyForce,
    ProjectionEnergy, ProjectionMetric, UzawaPenalty,
};
use crate::dim::{Dim, Kinematics, SpatialDim};
use crate::error::{Error, Result};
use crate::material::{Hypoelastic, LinearElastic, Material, NortonHoff, RotationUpdate};
use crate::mesh::Mesh;
use crate::simulation::{Body, Constraint, MassKind, Settings};
use crate::solver::FillOrdering;
use crate::time::{Beta, SpaceTimeScheme};

impl LoadedScene {
    /// Validates the whole scene for dimension D, reading mesh files.
    pub fn build<const D: usize>(&self) -> Result<Scene<D>>
    where
        Dim<D>: SpatialDim<D>,
    {
        let settings = self.settings::<D>()?;
        let contact = self.check_contact()?;

        if self.file.bodies.is_empty() {
            return Err(self.error("bodies", "no [[bodies]]", "at least one body"));
        }
        let mut bodies = Vec::new();
        for (b, spec) in self.file.bodies.iter().enumerate() {
            bodies.push(self.body::<D>(b, spec, settings.kinematics)?);
        }
        self.check_memory(&bodies)?;
        let mut obstacles = Vec::new();
        for (o, spec) in self.file.obstacles.iter().enumerate() {
            obstacles.push(self.obstacle::<D>(o, spec)?);
        }
        let probes = self.probes(&bodies)?;
        let output = self.output_options()?;
        Ok(Scene {
            settings,
            end_time: self.file.simulation.end_time,
            bodies,
            obstacles,
            probes,
            output,
            contact,
        })
    }

    /// The whole scene's memory lower bound against the machine's (see `limits`): every body,
    /// Gmsh meshes too, before the simulation allocates its matrices.
    fn check_memory<const D: usize>(&self, bodies: &[Body<D>]) -> Result<()>
    where
        Dim<D>: SpatialDim<D>,
    {
        let (unknowns, triplets) = scene_size(bodies);
        let needed = super::memory_lower_bound(unknowns, triplets, D);
        let limit = super::memory_limit();
        if needed <= limit {
            return Ok(());
        }
        let cells: usize = bodies.iter().map(|b| b.mesh.cell_count()).sum();
        Err(self.error(
            "bodies",
            format!(
                "{} bodies of {cells} cells in all: {unknowns:.1e} unknowns, at least {} of \
                 matrices",
                bodies.len(),
                super::limits::bytes(needed)
            ),
            format!(
                "a scene whose matrices fit in this machine's {} of memory (fewer cells)",
                super::limits::bytes(limit)
            ),
        ))
    }

    /// `[[probes]]`: unique names, the body by name, the nearest node to the point.
    fn probes<const D: usize>(&self, bodies: &[Body<D>]) -> Result<Vec<Probe>>
    where
        Dim<D>: SpatialDim<D>,
    {
        let mut probes = Vec::new();
        for (p, spec) in self.file.probes.iter().enumerate() {
            let key = format!("probes.{p}");
            let earlier = self.file.probes[..p].iter().map(|x| x.name.as_str());
            self.unique_name(&key, earlier, &spec.name, "probe")?;
            let body = bodies
                .iter()
                .position(|b| b.name == spec.body)
                .ok_or_else(|| {
                    let names: Vec<&str> = bodies.iter().map(|b| b.name.as_str()).collect();
                    self.error(
                        &format!("{key}.body"),
                        format!("\"{}\"", spec.body),
                        format!("the name of a body: {names:?}"),
                    )
                })?;
            let point = self.vector::<D>(&format!("{key}.point"), &spec.point)?;
            let node = bodies[body].mesh.nearest_node(&point);
            probes.push(Probe {
                name: spec.name.clone(),
                body,
                node,
            });
        }
        Ok(probes)
    }

    /// `[output]`: the history and VTK intervals.
    fn output_options(&self) -> Result<OutputOptions> {
        let out = &self.file.output;
        if !(out.history_interval >= 0.0 && out.history_interval.is_finite()) {
            return Err(self.error(
                "output.history_interval",
                out.history_interval,
                "a finite value >= 0 [s]",
            ));
        }
        if !(out.vtk_interval >= 0.0 && out.vtk_interval.is_finite()) {
            return Err(self.error(
                "output.vtk_interval",
                out.vtk_interval,
                "a finite value >= 0 [s]",
            ));
        }
        Ok(OutputOptions {
            history_interval: out.history_interval,
            vtk_interval: out.vtk_interval,
        })
    }

    /// `[simulation]`: the time step, the scheme, gravity, kinematics and solver options.
    fn settings<const D: usize>(&self) -> Result<Settings<D>>
    where
        Dim<D>: SpatialDim<D>,
    {
        let s = &self.file.simulation;
        let kinematics = match (D, s.kinematics.as_deref()) {
            (3, None) | (3, Some("solid")) => Kinematics::Solid,
            (3, Some(k)) => {
                return Err(self.error(
                    "simulation.kinematics",
                    format!("\"{k}\""),
                    "no kinematics key in 3D (or \"solid\")",
                ))
            }
            (_, None) | (_, Some("plane_strain")) => Kinematics::PlaneStrain,
            (_, Some("plane_stress")) => Kinematics::PlaneStress,
            (_, Some("axisymmetric")) => Kinematics::Axisymmetric,
            (_, Some(k)) => {
                return Err(self.error(
                    "simulation.kinematics",
                    format!("\"{k}\""),
                    "\"plane_strain\", \"plane_stress\" or \"axisymmetric\"",
                ))
            }
        };
        let time_step = self.positive("simulation.time_step", s.time_step, "s")?;
        if !(s.end_time >= 0.0 && s.end_time.is_finite()) {
            return Err(self.error("simulation.end_time", s.end_time, "a finite value >= 0 [s]"));
        }
        let steps = super::step_count(s.end_time, time_step);
        if steps > super::MAX_STEPS {
            return Err(self.error(
                "simulation.time_step",
                format!(
                    "{} s with end_time = {} s: {steps:.1e} steps",
                    super::plain(time_step),
                    super::plain(s.end_time)
                ),
                format!(
                    "at most {:e} steps (a larger time_step or a shorter end_time)",
                    super::MAX_STEPS
                ),
            ));
        }
        if !(0.0..=1.0).contains(&s.alpha) {
            return Err(self.error("simulation.alpha", s.alpha, "a number in [0, 1]"));
        }
        let beta = match &s.beta {
            BetaSpec::Name(n) if n == "energy" => Beta::Energy,
            BetaSpec::Name(n) if n == "trapezoid" => Beta::Trapezoid,
            BetaSpec::Value(b) if (0.0..=1.0).contains(b) => Beta::Value(*b),
            BetaSpec::Value(b) => {
                return Err(self.error(
                    "simulation.beta",
                    b,
                    "\"energy\", \"trapezoid\" or a number in [0, 1]",
                ))
            }
            BetaSpec::Name(n) => {
                return Err(self.error(
                    "simulation.beta",
                    format!("\"{n}\""),
                    "\"energy\", \"trapezoid\" or a number in [0, 1]",
                ))
            }
        };
        let scheme = SpaceTimeScheme::new(s.alpha, beta)?;
        let gravity = match &s.gravity {
            Some(g) => self.vector::<D>("simulation.gravity", g)?,
            None => SVector::zeros(),
        };
        if s.max_iterations < 1 {
            return Err(self.error(
                "simulation.max_iterations",
                s.max_iterations,
                "an integer >= 1",
            ));
        }
        if !(s.tolerance > 0.0 && s.tolerance < 1.0) {
            return Err(self.error("simulation.tolerance", s.tolerance, "a number in (0, 1)"));
        }
        let mass = self.keyword(
            "simulation.mass",
            s.mass.as_deref(),
            &[
                ("consistent", MassKind::Consistent),
                ("lumped", MassKind::Lumped),
            ],
        )?;
        let ordering = self.keyword(
            "simulation.ordering",
            s.ordering.as_deref(),
            &[
                ("nested_dissection", FillOrdering::NestedDissection),
                ("minimum_degree", FillOrdering::MinimumDegree),
            ],
        )?;
        Ok(Settings {
            time_step,
            scheme,
            gravity,
            kinematics,
            max_iterations: s.max_iterations as usize,
            tolerance: s.tolerance,
            mass,
            ordering,
        })
    }

    /// `bodies.{b}`: name, mesh, material, initial velocities, constraints, mesh checks.
    fn body<const D: usize>(
        &self,
        b: usize,
        spec: &BodySection,
        kinematics: Kinematics,
    ) -> Result<Body<D>>
    where
        Dim<D>: SpatialDim<D>,
    {
        let key = format!("bodies.{b}");
        let earlier = self.file.bodies[..b].iter().map(|x| x.name.as_str());
        self.unique_name(&key, earlier, &spec.name, "body")?;
        let (mesh, groups) = self.mesh::<D>(&format!("{key}.mesh"), &spec.mesh, &spec.name)?;
        let material = self.material(&format!("{key}.material"), &spec.material)?;
        let mut body = Body::new(spec.name.clone(), mesh, material);
        if let Some(v) = &spec.initial_velocity {
            body.initial_velocity = self.vector::<D>(&format!("{key}.initial_velocity"), v)?;
        }
        if let Some(w) = &spec.initial_angular_velocity {
            let k = format!("{key}.initial_angular_velocity");
            body.initial_angular_velocity = self.angular::<D>(&k, w)?;
        }
        if let Some(d) = &spec.damping {
            body.damping.mass = self.non_negative(&format!("{key}.damping.mass"), d.mass, "1/s")?;
            body.damping.stiffness =
                self.non_negative(&format!("{key}.damping.stiffness"), d.stiffness, "s")?;
        }
        if let Some(s) = spec.gravity_scale {
            if !s.is_finite() {
                return Err(self.error(
                    &format!("{key}.gravity_scale"),
                    s,
                    "a finite factor (dimensionless)",
                ));
            }
            body.gravity_scale = s;
        }
        for (c, cs) in spec.constraints.iter().enumerate() {
            let ck = format!("{key}.constraints.{c}");
            body.constraints
                .push(self.constraint::<D>(&ck, cs, &body.mesh, &groups, &spec.name)?);
        }
        if kinematics == Kinematics::Axisymmetric {
            if let Some(n) = body.mesh.nodes.iter().position(|x| x[0] < 0.0) {
                return Err(self.error(
                    &format!("{key}.mesh"),
                    format!("node {n} at r = x = {}", body.mesh.nodes[n][0]),
                    "r = x >= 0 for every node in axisymmetric kinematics",
                ));
            }
        }
        if let Err(e) = body.mesh.check_quality(&spec.name) {
            return Err(match e {
                Error::InvertedElement {
                    cell,
                    kind,
                    jacobian,
                    ..
                } => self.error(
                    &format!("{key}.mesh"),
                    format!("cell {cell} {kind} (Jacobian determinant {jacobian:.3e})"),
                    "cells with a positive Jacobian everywhere (check node ordering and geometry)",
                ),
                other => other,
            });
        }
        Ok(body)
    }

    fn check_contact(&self) -> Result<ContactSettings> {
        let c = &self.file.contact;
        let Ok(method) = c.method.parse::<ContactMethod>() else {
            let names = ContactMethod::ALL.map(ContactMethod::name);
            return Err(self.error(
                "contact.method",
                format!("\"{}\"", c.method),
                format!("one of {names:?}"),
            ));
        };
        if let Some(p) = c.penalty {
            self.positive("contact.penalty", p, "Pa/m")?;
        } else if method.is_penalty() {
            return Err(self.error(
                "contact.penalty",
                "nothing",
                format!(
                    "a penalty zeta > 0 [Pa/m] for method \"{}\" (it has no default: the \
                     penetration is the contact pressure / zeta, and zeta l_e / E of 10 to 1000 \
                     suits elements of size l_e and Young's modulus E; or method = \
                     \"implicit_projection\", which needs none)",
                    c.method
                ),
            ));
        }
        self.positive("contact.gap_tolerance", c.gap_tolerance, "m")?;
        self.non_negative("contact.master_tolerance", c.master_tolerance, "m")?;
        let friction = self.friction("contact.friction", &c.friction)?;
        let any_friction = friction != FrictionLaw::Frictionless
            || self.file.obstacles.iter().any(|o| {
                o.friction
                    .as_ref()
                    .is_some_and(|f| *f != FrictionSpec::Frictionless)
            });
        if method == ContactMethod::ExplicitProjection && any_friction {
            return Err(self.error(
                "contact.method",
                "\"explicit_projection\" with a friction law",
                "a method with a normal force inside the step to carry friction (soft_way, \
                 implicit_projection or augmented_lagrangian), or law = \"frictionless\"",
            ));
        }
        let gap_displacement = self.keyword(
            "contact.gap_displacement",
            c.gap_displacement.as_deref(),
            &[
                ("configuration", GapDisplacement::Configuration),
                ("trapezoid", GapDisplacement::Trapezoid),
            ],
        )?;
        let projection = self.keyword(
            "contact.projection",
            c.projection.as_deref(),
            &[
                ("step", ProjectionMetric::Step),
                ("node", ProjectionMetric::Node),
            ],
        )?;
        let projection_energy = self.keyword(
            "contact.projection_energy",
            c.projection_energy.as_deref(),
            &[
                ("bounded", ProjectionEnergy::Bounded),
                ("booked", ProjectionEnergy::Booked),
            ],
        )?;
        let penalty_force = self.keyword(
            "contact.penalty_force",
            c.penalty_force.as_deref(),
            &[
                ("end_of_step", PenaltyForce::EndOfStep),
                ("secant", PenaltyForce::Secant),
            ],
        )?;
        let uzawa_penalty = self.keyword(
            "contact.uzawa_penalty",
            c.uzawa_penalty.as_deref(),
            &[
                ("growing", UzawaPenalty::Growing),
                ("fixed", UzawaPenalty::Fixed),
            ],
        )?;
        let master_nodes = self.keyword(
            "contact.master_nodes",
            c.master_nodes.as_deref(),
            &[
                ("projected", MasterNodes::Projected),
                ("free", MasterNodes::Free),
            ],
        )?;
        if penalty_force == PenaltyForce::Secant
            && (method != ContactMethod::SoftWay || gap_displacement != GapDisplacement::Trapezoid)
        {
            return Err(self.error(
                "contact.penalty_force",
                format!(
                    "\"secant\" with method \"{}\" and gap_displacement \"{}\"",
                    method.name(),
                    c.gap_displacement.as_deref().unwrap_or("configuration")
                ),
                "method \"soft_way\" with gap_displacement \"trapezoid\" (the secant is the soft \
                 way's pressure, and needs each step's start gap to be the last step's end gap)",
            ));
        }
        if let Some(stop) = c.persistency_stop {
            if !method.is_penalty() || gap_displacement != GapDisplacement::Trapezoid {
                return Err(self.error(
                    "contact.persistency_stop",
                    format!(
                        "{stop} with method \"{}\" and gap_displacement \"{}\"",
                        method.name(),
                        c.gap_displacement.as_deref().unwrap_or("configuration")
                    ),
                    "method \"soft_way\" or \"augmented_lagrangian\" with gap_displacement \
                     \"trapezoid\" (the stop keeps trapezoid gaps' closed pairs closed), or no \
                     persistency_stop",
                ));
            }
        }
        Ok(ContactSettings {
            method,
            penalty: c.penalty.unwrap_or(0.0),
            self_contact: c.self_contact,
            gap_tolerance: c.gap_tolerance,
            friction,
            gap_displacement,
            projection,
            projection_energy,
            penalty_force,
            uzawa_penalty,
            master_nodes,
            master_tolerance: c.master_tolerance,
            persistency_stop: c.persistency_stop,
            ..ContactSettings::default()
        })
    }

    pub(super) fn friction(&self, key: &str, f: &FrictionSpec) -> Result<FrictionLaw> {
        let non_negative =
            |k: &str, v: f64, unit: &str| self.non_negative(&format!("{key}.{k}"), v, unit);
        let regularization = |r: &Option<f64>| -> Result<f64> {
            match r {
                Some(r) => self.positive(&format!("{key}.regularization"), *r, "m/s"),
                None => Ok(DEFAULT_REGULARIZATION),
            }
        };
        Ok(match f {
            FrictionSpec::Frictionless => FrictionLaw::Frictionless,
            FrictionSpec::Coulomb {
                coefficient,
                regularization: r,
            } => {
                non_negative("coefficient", *coefficient, "-")?;
                FrictionLaw::Coulomb {
                    coefficient: *coefficient,
                    regularization: regularization(r)?,
                }
            }
            FrictionSpec::Tresca { limit } => {
                non_negative("limit", *limit, "Pa")?;
                FrictionLaw::Tresca {
                    limit: *limit,
                    regularization: DEFAULT_REGULARIZATION,
                }
            }
            FrictionSpec::Viscoplastic {
                coefficient,
                exponent,
                regularization: r,
            } => {
                non_negative("coefficient", *coefficient, "Pa (s/m)^p")?;
                non_negative("exponent", *exponent, "-")?;
                FrictionLaw::Viscoplastic {
                    coefficient: *coefficient,
                    exponent: *exponent,
                    regularization: regularization(r)?,
                }
            }
        })
    }

    fn material(&self, key: &str, m: &MaterialSpec) -> Result<Material> {
        let elastic =
            |youngs_modulus: f64, poissons_ratio: f64, density: f64| -> Result<LinearElastic> {
                self.positive(&format!("{key}.youngs_modulus"), youngs_modulus, "Pa")?;
                if !(poissons_ratio > -1.0 && poissons_ratio < 0.5) {
                    return Err(self.error(
                        &format!("{key}.poissons_ratio"),
                        poissons_ratio,
                        "a value in (-1, 0.5)",
                    ));
                }
                self.non_negative(&format!("{key}.density"), density, "kg/m^3")?;
                LinearElastic::new(youngs_modulus, poissons_ratio, density)
            };
        match m {
            MaterialSpec::LinearElastic {
                youngs_modulus,
                poissons_ratio,
                density,
            } => Ok(Material::LinearElastic(elastic(
                *youngs_modulus,
                *poissons_ratio,
                *density,
            )?)),
            MaterialSpec::Hypoelastic {
                youngs_modulus,
                poissons_ratio,
                density,
                rotation,
            } => {
                let e = elastic(*youngs_modulus, *poissons_ratio, *density)?;
                let rotation = match rotation.as_deref() {
                    None | Some("hughes_winget") => RotationUpdate::HughesWinget,
                    Some("paper_series") => RotationUpdate::PaperSeries,
                    Some(other) => {
                        return Err(self.error(
                            &format!("{key}.rotation"),
                            format!("\"{other}\""),
                            "\"hughes_winget\" (exactly orthogonal, the default) or \"paper_series\" (eq 52)",
                        ))
                    }
                };
                Ok(Material::Hypoelastic(Hypoelastic::new(
                    e.youngs_modulus,
                    e.poissons_ratio,
                    e.density,
                    rotation,
                )?))
            }
            MaterialSpec::NortonHoff {
                consistency,
                exponent,
                density,
                bulk_penalty,
                rate_regularization,
            } => {
                self.positive(&format!("{key}.consistency"), *consistency, "Pa s^m")?;
                if !(*exponent > 0.0 && *exponent <= 1.0) {
                    return Err(self.error(
                        &format!("{key}.exponent"),
                        exponent,
                        "a value in (0, 1]",
                    ));
                }
                self.non_negative(&format!("{key}.density"), *density, "kg/m^3")?;
                self.positive(&format!("{key}.bulk_penalty"), *bulk_penalty, "Pa s")?;
                let mut law = NortonHoff::new(*consistency, *exponent, *density, *bulk_penalty)?;
                if let Some(r) = rate_regularization {
                    self.positive(&format!("{key}.rate_regularization"), *r, "1/s")?;
                    law.rate_regularization = *r;
                }
                Ok(Material::NortonHoff(law))
            }
        }
    }

    fn constraint<const D: usize>(
        &self,
        key: &str,
        c: &ConstraintSection,
        mesh: &Mesh<D>,
        groups: &BTreeMap<String, Vec<usize>>,
        body: &str,
    ) -> Result<Constraint>
    where
        Dim<D>: SpatialDim<D>,
    {
        let nodes = match (&c.region.group, &c.region.min, &c.region.max) {
            (Some(g), None, None) => groups.get(g).cloned().ok_or_else(|| {
                let names: Vec<&String> = groups.keys().collect();
                self.error(
                    &format!("{key}.region.group"),
                    format!("\"{g}\""),
                    format!("a physical group of the mesh file: {names:?}"),
                )
            })?,
            (None, Some(min), Some(max)) => {
                let min = self.vector::<D>(&format!("{key}.region.min"), min)?;
                let max = self.vector::<D>(&format!("{key}.region.max"), max)?;
                mesh.nodes_in_box(&min, &max)
            }
            _ => {
                return Err(self.error(
                    &format!("{key}.region"),
                    "an incomplete region",
                    "{ min = [..], max = [..] } or { group = \"name\" }",
                ))
            }
        };
        if nodes.is_empty() {
            let (lo, hi) = mesh.bounding_box();
            return Err(self.error(
                &format!("{key}.region"),
                format!("a region that selects no node of body `{body}`"),
                format!(
                    "a region that contains nodes (the mesh spans {:?} to {:?})",
                    lo.as_slice(),
                    hi.as_slice()
                ),
            ));
        }
        let velocity = match &c.velocity {
            ComponentsSpec::Array(v) => self
                .vector::<D>(&format!("{key}.velocity"), v)?
                .iter()
                .map(|x| Some(*x))
                .collect(),
            ComponentsSpec::Named(n) => {
                if D == 2 && n.z.is_some() {
                    return Err(self.error(
                        &format!("{key}.velocity.z"),
                        "a z component in 2D",
                        "x and y only",
                    ));
                }
                let v: Vec<Option<f64>> = [n.x, n.y, n.z][..D].to_vec();
                if v.iter().all(Option::is_none) {
                    return Err(self.error(
                        &format!("{key}.velocity"),
                        "no component",
                        "at least one of x, y, z",
                    ));
                }
                if v.iter().flatten().any(|x| !x.is_finite()) {
                    return Err(self.error(
                        &format!("{key}.velocity"),
                        "a non-finite component",
                        "finite numbers [m/s]",
                    ));
                }
                v
            }
        };
        Ok(Constraint { nodes, velocity })
    }

    /// An angular velocity: a number in 2D, a vector `[wx, wy, wz]` in 3D, finite (rad/s).
    pub(super) fn angular<const D: usize>(&self, key: &str, w: &AngularSpec) -> Result<Vec<f64>>
    where
        Dim<D>: SpatialDim<D>,
    {
        let found = match w {
            AngularSpec::Scalar(x) => format!("the number {x}"),
            AngularSpec::Vector(v) => format!("{} components {v:?}", v.len()),
        };
        let values = match (w, <Dim<D>>::ANGULAR) {
            (AngularSpec::Scalar(x), 1) => vec![*x],
            (AngularSpec::Vector(v), 3) if v.len() == 3 => v.clone(),
            _ => {
                return Err(self.error(
                    key,
                    found,
                    if D == 2 {
                        "a number [rad/s] in 2D"
                    } else {
                        "a vector [wx, wy, wz] [rad/s] in 3D"
                    },
                ))
            }
        };
        if values.iter().any(|x| !x.is_finite()) {
            return Err(self.error(key, found, "finite numbers [rad/s]"));
        }
        Ok(values)
    }

    pub(super) fn vector<const D: usize>(&self, key: &str, v: &[f64]) -> Result<SVector<f64, D>> {
        if v.len() != D {
            return Err(self.error(
                key,
                format!("{} components", v.len()),
                format!("{D} components (dimension = {D})"),
            ));
        }
        if v.iter().any(|x| !x.is_finite()) {
            return Err(self.error(key, format!("{v:?}"), "finite numbers"));
        }
        Ok(SVector::from_column_slice(v))
    }

    /// `{key}.name` must differ from the `earlier` names of its list and be a valid name.
    pub(super) fn unique_name<'a>(
        &self,
        key: &str,
        mut earlier: impl Iterator<Item = &'a str>,
        name: &str,
        what: &str,
    ) -> Result<()> {
        let key = format!("{key}.name");
        if earlier.any(|e| e == name) {
            return Err(self.error(
                &key,
                format!("\"{name}\" again"),
                format!("a unique {what} name"),
            ));
        }
        self.name(&key, name)
    }

    /// Names become history.csv columns (`probe.<name>.ux`), VTK file names
    /// (`vtk/<body>_<step>.vtu`) and `--set obstacles.NAME.` paths: no commas, quotes, dots,
    /// slashes or spaces.
    pub(super) fn name(&self, key: &str, name: &str) -> Result<()> {
        let ok = |c: char| c.is_alphanumeric() || c == '_' || c == '-';
        if name.is_empty() || !name.chars().all(ok) {
            return Err(self.error(
                key,
                format!("{name:?}"),
                "a non-empty name of letters, digits, '_' and '-'",
            ));
        }
        Ok(())
    }

    /// The variant a keyword names among `choices` (the first is the default when the key is
    /// absent), or an error listing the names.
    pub(super) fn keyword<T: Copy>(
        &self,
        key: &str,
        value: Option<&str>,
        choices: &[(&str, T)],
    ) -> Result<T> {
        let Some(value) = value else {
            return Ok(choices[0].1);
        };
        choices
            .iter()
            .find(|(name, _)| *name == value)
            .map(|&(_, choice)| choice)
            .ok_or_else(|| {
                let names: Vec<String> = choices.iter().map(|(n, _)| format!("\"{n}\"")).collect();
                self.error(key, format!("\"{value}\""), names.join(" or "))
            })
    }

    pub(super) fn non_negative(&self, key: &str, v: f64, unit: &str) -> Result<f64> {
        if v >= 0.0 && v.is_finite() {
            Ok(v)
        } else {
            Err(self.error(key, v, format!("a finite value >= 0 [{unit}]")))
        }
    }

    pub(super) fn positive(&self, key: &str, v: f64, unit: &str) -> Result<f64> {
        if v > 0.0 && v.is_finite() {
            Ok(v)
        } else {
            Err(self.error(key, v, format!("a finite value > 0 [{unit}]")))
        }
    }
}

/// The unknowns of `bodies` and the entries of their cell matrices' lower triangles (the
/// sizes [`super::memory_lower_bound`] takes).
pub fn scene_size<const D: usize>(bodies: &[Body<D>]) -> (f64, f64)
where
    Dim<D>: SpatialDim<D>,
{
    let unknowns = bodies
        .iter()
        .map(|b| (b.mesh.node_count() * D) as f64)
        .sum();
    let triplets = bodies
        .iter()
        .flat_map(|b| &b.mesh.blocks)
        .map(|block| {
            let nodes = block.kind.nodes();
            (block.connectivity.len() / nodes) as f64 * super::cell_triplets(nodes, D)
        })
        .sum();
    (unknowns, triplets)
}
