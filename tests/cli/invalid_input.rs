//! Bad scenes: exit status 2, one clear message, nothing written.

use std::fs;

use super::support::*;

#[test]
fn malformed_toml() {
    let file = bad("malformed_toml");
    let dir = tempdir();
    let out = dir.path().join("out");
    let err = assert_invalid(
        dir.path(),
        &[
            "run",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
    );
    assert!(err.contains(file.to_str().unwrap()), "{err}");
    let line = line_of(&file, "end_time = 0.01 seconds");
    assert!(err.contains(&format!("line {line}")), "{err}");
    assert!(
        err.contains("seconds"),
        "the message shows what was found:\n{err}"
    );
    assert!(err.contains("expected"), "{err}");
}

#[test]
fn unknown_keys() {
    assert_bad_scene(
        "unknown_key_top",
        Expect {
            key: "simulation.steps",
            marker: Some("steps = 100"),
            found: "unknown field `steps`",
            expected: "`time_step`",
        },
    );
    assert_bad_scene(
        "unknown_table",
        Expect {
            key: "solver",
            marker: Some("[solver]"),
            found: "unknown field `solver`",
            expected: "`simulation`",
        },
    );
    assert_bad_scene(
        "unknown_key_nested",
        Expect {
            key: "bodies.0.material.colour",
            marker: Some("colour"),
            found: "unknown field `colour`",
            expected: "`youngs_modulus`",
        },
    );
    assert_bad_scene(
        "unknown_key_region",
        Expect {
            key: "bodies.0.constraints.0.region.radius",
            marker: Some("radius"),
            found: "unknown field `radius`",
            expected: "`min`",
        },
    );
}

#[test]
fn wrong_types_and_missing_keys() {
    assert_bad_scene(
        "wrong_type",
        Expect {
            key: "bodies.0.material.youngs_modulus",
            marker: Some("youngs_modulus = \"stiff\""),
            found: "\"stiff\"",
            expected: "a number",
        },
    );
    assert_bad_scene(
        "wrong_type_top",
        Expect {
            key: "simulation.end_time",
            marker: Some("end_time = \"soon\""),
            found: "\"soon\"",
            expected: "a number",
        },
    );
    assert_bad_scene(
        "beta_wrong_type",
        Expect {
            key: "simulation.beta",
            marker: Some("beta = true"),
            found: "true",
            expected: "\"energy\", \"trapezoid\" or a number in [0, 1]",
        },
    );
    // The key is not in the file: the message points at the table that lacks it.
    assert_bad_scene(
        "missing_key",
        Expect {
            key: "simulation.end_time",
            marker: Some("[simulation]"),
            found: "nothing",
            expected: "`end_time`",
        },
    );
}

#[test]
fn out_of_range_numbers() {
    let cases = [
        (
            "youngs_modulus_zero",
            "bodies.0.material.youngs_modulus",
            "youngs_modulus = 0.0",
            "0",
            "> 0",
        ),
        (
            "youngs_modulus_negative",
            "bodies.0.material.youngs_modulus",
            "youngs_modulus = -2.0e11",
            "-2e11",
            "> 0",
        ),
        (
            "poissons_ratio_half",
            "bodies.0.material.poissons_ratio",
            "poissons_ratio = 0.5",
            "0.5",
            "(-1, 0.5)",
        ),
        (
            "poissons_ratio_minus_one",
            "bodies.0.material.poissons_ratio",
            "poissons_ratio = -1.0",
            "-1",
            "(-1, 0.5)",
        ),
        (
            "alpha_above_one",
            "simulation.alpha",
            "alpha = 1.2",
            "1.2",
            "[0, 1]",
        ),
        (
            "alpha_negative",
            "simulation.alpha",
            "alpha = -0.1",
            "-0.1",
            "[0, 1]",
        ),
        (
            "beta_above_one",
            "simulation.beta",
            "beta = 1.5",
            "1.5",
            "a number in [0, 1]",
        ),
        (
            "beta_unknown",
            "simulation.beta",
            "beta = \"midpoint\"",
            "\"midpoint\"",
            "\"energy\"",
        ),
        (
            "time_step_zero",
            "simulation.time_step",
            "time_step = 0.0",
            "0",
            "> 0 [s]",
        ),
        (
            "time_step_negative",
            "simulation.time_step",
            "time_step = -1.0e-3",
            "-0.001",
            "> 0 [s]",
        ),
        (
            "end_time_negative",
            "simulation.end_time",
            "end_time = -0.01",
            "-0.01",
            ">= 0 [s]",
        ),
        (
            "dimension_four",
            "simulation.dimension",
            "dimension = 4",
            "4",
            "2 or 3",
        ),
        (
            "ordering_unknown",
            "simulation.ordering",
            "ordering = ",
            "\"metis\"",
            "\"nested_dissection\"",
        ),
        (
            "kinematics_unknown",
            "simulation.kinematics",
            "kinematics = ",
            "\"plane_strian\"",
            "\"plane_strain\"",
        ),
        (
            "contact_method_unknown",
            "contact.method",
            "method = \"magic\"",
            "\"magic\"",
            "soft_way",
        ),
        (
            "penalty_force_secant_configuration",
            "contact.penalty_force",
            "penalty_force = \"secant\"",
            "\"secant\" with method \"soft_way\" and gap_displacement \"configuration\"",
            "gap_displacement \"trapezoid\"",
        ),
        (
            "persistency_stop_implicit_projection",
            "contact.persistency_stop",
            "persistency_stop = true",
            "true with method \"implicit_projection\" and gap_displacement \"configuration\"",
            "gap_displacement \"trapezoid\"",
        ),
        (
            "projection_unknown",
            "contact.projection",
            "projection = \"midpoint\"",
            "\"midpoint\"",
            "\"step\" or \"node\"",
        ),
        (
            "projection_energy_unknown",
            "contact.projection_energy",
            "projection_energy = \"free\"",
            "\"free\"",
            "\"bounded\" or \"booked\"",
        ),
        (
            "uzawa_penalty_unknown",
            "contact.uzawa_penalty",
            "uzawa_penalty = \"doubling\"",
            "\"doubling\"",
            "\"growing\" or \"fixed\"",
        ),
        (
            "master_nodes_unknown",
            "contact.master_nodes",
            "master_nodes = \"held\"",
            "\"held\"",
            "\"projected\" or \"free\"",
        ),
        (
            "master_tolerance_negative",
            "contact.master_tolerance",
            "master_tolerance = -1.0e-5",
            "-0.00001",
            ">= 0 [m]",
        ),
        (
            "contact_penalty_negative",
            "contact.penalty",
            "penalty = -1.0e9",
            "-1000000000",
            "> 0 [Pa/m]",
        ),
    ];
    assert_bad_scenes(&cases);
    // A penalty has no default: soft_way without one points at [contact].
    assert_bad_scene(
        "soft_way_without_penalty",
        Expect {
            key: "contact.penalty",
            marker: Some("[contact]"),
            found: "nothing",
            expected: "penalty zeta > 0 [Pa/m] for method \"soft_way\"",
        },
    );
}

/// Issue 11: the Norton-Hoff parameters and the hypoelastic rotation update.
#[test]
fn material_laws() {
    let cases = [
        (
            "exponent_zero",
            "bodies.0.material.exponent",
            "exponent = 0.0",
            "0",
            "a value in (0, 1]",
        ),
        (
            "exponent_above_one",
            "bodies.0.material.exponent",
            "exponent = 1.5",
            "1.5",
            "a value in (0, 1]",
        ),
        (
            "consistency_zero",
            "bodies.0.material.consistency",
            "consistency = 0.0",
            "0",
            "a finite value > 0 [Pa s^m]",
        ),
        (
            "consistency_negative",
            "bodies.0.material.consistency",
            "consistency = -1.0",
            "-1",
            "a finite value > 0 [Pa s^m]",
        ),
        (
            "rotation_unknown",
            "bodies.0.material.rotation",
            "rotation = \"bogus\"",
            "\"bogus\"",
            "\"hughes_winget\" (exactly orthogonal, the default) or \"paper_series\"",
        ),
    ];
    assert_bad_scenes(&cases);
}

/// The accepted side of the same checks: the closed end m = 1, both rotation updates by name
/// and the default (no `rotation` key), each one the scene's only change from a bad fixture.
#[test]
fn material_laws_accepted() {
    use softway::material::{Material, RotationUpdate};
    let accepted = |name: &str, set: &str| {
        let file = bad(name);
        let dir = tempdir();
        let o = run_in(dir.path(), &["check", file.to_str().unwrap(), "--set", set]);
        assert_eq!(o.status.code(), Some(0), "{set}: {}", stderr(&o));
        let scene = softway::io::scene::load(&file, &[set.to_string()])
            .and_then(|s| s.build::<2>())
            .unwrap();
        scene.bodies[0].material
    };
    let m = accepted("exponent_above_one", "bodies.0.material.exponent = 1.0");
    assert!(
        matches!(m, Material::NortonHoff(l) if l.exponent == 1.0),
        "{m:?}"
    );
    let m = accepted("consistency_zero", "bodies.0.material.consistency = 1.0e6");
    assert!(
        matches!(m, Material::NortonHoff(l) if l.consistency == 1e6),
        "{m:?}"
    );
    for (set, rotation) in [
        (
            "bodies.0.material.rotation = \"paper_series\"",
            RotationUpdate::PaperSeries,
        ),
        (
            "bodies.0.material.rotation = \"hughes_winget\"",
            RotationUpdate::HughesWinget,
        ),
        (
            "bodies.0.material = { model = \"hypoelastic\", youngs_modulus = 1.0e6, \
             poissons_ratio = 0.3, density = 1000.0 }",
            RotationUpdate::HughesWinget,
        ),
    ] {
        let m = accepted("rotation_unknown", set);
        assert!(
            matches!(m, Material::Hypoelastic(l) if l.rotation == rotation),
            "{set}: {m:?}"
        );
    }
}

#[test]
fn bad_meshes() {
    let mesh_line = Some("mesh = ");
    assert_bad_scene(
        "element_wrong_dimension",
        Expect {
            key: "bodies.0.mesh.element",
            marker: mesh_line,
            found: "\"hex8\"",
            expected: "\"tri3\" or \"quad4\" in 2D",
        },
    );
    assert_bad_scene(
        "generator_unknown",
        Expect {
            key: "bodies.0.mesh.generator",
            marker: mesh_line,
            found: "\"disc\"",
            expected: "\"rectangle\"",
        },
    );
    assert_bad_scene(
        "cells_overflow",
        Expect {
            key: "bodies.0.mesh.cells",
            marker: mesh_line,
            found: "[100000000000, 100000000000]",
            expected: "at most",
        },
    );
    assert_bad_scene(
        "mesh_missing",
        Expect {
            key: "bodies.0.mesh.file",
            marker: mesh_line,
            found: "no_such_mesh.msh",
            expected: "a readable Gmsh MSH 2.2 or 4.1 file",
        },
    );
    // The truncated copy of square_tri3_v22_ascii.msh ends inside node 54, on its line 64.
    assert_bad_scene(
        "mesh_truncated",
        Expect {
            key: "bodies.0.mesh.file",
            marker: mesh_line,
            found: "truncated.msh (line 64: ",
            expected: "Gmsh",
        },
    );
    assert_bad_scene(
        "mesh_wrong_dimension",
        Expect {
            key: "bodies.0.mesh.file",
            marker: mesh_line,
            found: "box_tet4_v41_ascii.msh (found 3D elements as the highest dimension; \
                    expected 2D cells)",
            expected: "a readable Gmsh MSH 2.2 or 4.1 file",
        },
    );
    assert_bad_scene(
        "mesh_file_with_cells",
        Expect {
            key: "bodies.0.mesh.cells",
            marker: mesh_line,
            found: "`cells` with a mesh file",
            expected: "only `file`",
        },
    );
    // inverted.msh: two triangles of a square, the second one numbered clockwise.
    assert_bad_scene(
        "mesh_inverted",
        Expect {
            key: "bodies.0.mesh",
            marker: mesh_line,
            found: "Gmsh element 3 (cell 1 of the body) inverted",
            expected: "positive Jacobian",
        },
    );
}

#[test]
fn obstacle_motion_schedules() {
    assert_bad_scene(
        "motion_and_velocity",
        Expect {
            key: "obstacles.0.motion",
            marker: Some("motion = ["),
            found: "both `velocity` and `motion`",
            expected: "a constant `velocity` or a `motion` schedule",
        },
    );
    assert_bad_scene(
        "motion_until_not_increasing",
        Expect {
            key: "obstacles.0.motion.1.until",
            marker: Some("until = 0.004"),
            found: "0.004",
            expected: "after the previous entry's (0.005)",
        },
    );
    assert_bad_scene(
        "motion_angular_velocity_vector",
        Expect {
            key: "obstacles.0.motion.0.angular_velocity",
            marker: Some("angular_velocity = [0.0, 0.0, 0.5]"),
            found: "3 components [0.0, 0.0, 0.5]",
            expected: "a number [rad/s] in 2D",
        },
    );
    assert_bad_scene(
        "motion_angular_velocity_nan",
        Expect {
            key: "obstacles.0.motion.0.angular_velocity",
            marker: Some("angular_velocity = nan"),
            found: "the number NaN",
            expected: "finite numbers [rad/s]",
        },
    );
    assert_bad_scene(
        "pivot_length",
        Expect {
            key: "obstacles.0.pivot",
            marker: Some("pivot = [0.0, 0.2, 0.0]"),
            found: "3 components",
            expected: "2 components (dimension = 2)",
        },
    );
}

/// A body that starts deeper inside an obstacle than contact detection reaches (here a floor
/// polyline drawn the wrong way round: solid above) cannot be run.
#[test]
fn bodies_inside_obstacles() {
    assert_bad_scene(
        "polyline_reversed",
        Expect {
            key: "floor",
            marker: None,
            found: "12 boundary node(s) inside at t = 0",
            expected: "none that deep",
        },
    );
}

/// A mesh that overlaps itself (a Gmsh file whose two squares share no node and overlap by
/// half their side) cannot be run: its nodes are deeper inside it than contact detection
/// reaches.
#[test]
fn meshes_that_overlap_themselves() {
    assert_bad_scene(
        "mesh_overlaps_itself",
        Expect {
            key: "sheet",
            marker: None,
            found: "2 boundary node(s) inside at t = 0",
            expected: "none that deep",
        },
    );
    let file = bad("mesh_overlaps_itself");
    let dir = tempdir();
    let err = assert_invalid(dir.path(), &["check", file.to_str().unwrap()]);
    assert!(
        err.contains("body `sheet` starts inside itself")
            && err.trim_end().ends_with(
                "; or rather, since it overlaps itself, fix its mesh: cells of one part of it \
                 lie over cells of another (a mesh folded onto itself, arms that cross)"
            ),
        "{err}"
    );
}

#[test]
fn selections_and_names() {
    assert_bad_scene(
        "region_empty",
        Expect {
            key: "bodies.0.constraints.0.region",
            marker: Some("region = "),
            found: "selects no node of body `beam`",
            expected: "contains nodes",
        },
    );
    assert_bad_scene(
        "region_group_unknown",
        Expect {
            key: "bodies.0.constraints.0.region.group",
            marker: Some("region = "),
            found: "\"top\"",
            expected: "[\"bottom\", \"solid\"]",
        },
    );
    assert_bad_scene(
        "probe_unknown_body",
        Expect {
            key: "probes.0.body",
            marker: Some("body = \"bean\""),
            found: "\"bean\"",
            expected: "[\"beam\"]",
        },
    );
    assert_bad_scene(
        "probe_point_length",
        Expect {
            key: "probes.0.point",
            marker: Some("point = "),
            found: "3 components",
            expected: "2 components",
        },
    );
    assert_bad_scene(
        "body_name_slash",
        Expect {
            key: "bodies.0.name",
            marker: Some("name = \"left/beam\""),
            found: "\"left/beam\"",
            expected: "letters, digits",
        },
    );
}

/// Every bad fixture is refused, so none can slip into the suite unchecked.
#[test]
fn every_bad_fixture_is_refused() {
    let dir = tempdir();
    let mut n = 0;
    for e in fs::read_dir(repo().join("fixtures/scenes/bad")).unwrap() {
        let path = e.unwrap().path();
        if path.extension().is_some_and(|x| x == "toml") {
            assert_invalid(dir.path(), &["check", path.to_str().unwrap()]);
            n += 1;
        }
    }
    assert!(n >= 30, "{n} bad scenes");
}
