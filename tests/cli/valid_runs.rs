//! Valid scenes: the output folder and its files, `--set`, instability.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Output;

use serde_json::Value;

use super::support::*;

// ---------------------------------------------------------------------------------------------
// Valid scenes.

/// A clamped beam and a free block (no [output] section: the defaults apply).
const TINY: &str = r#"# A clamped beam sagging under gravity and a free block flying beside it.
[simulation]
dimension = 2
time_step = 1.0e-3
end_time = 0.01
gravity = [0.0, -9.81]

[[bodies]]
name = "beam"
mesh = { generator = "rectangle", min = [0.0, 0.0], max = [1.0, 0.1], cells = [4, 1], element = "quad4" }
material = { model = "linear_elastic", youngs_modulus = 1.0e6, poissons_ratio = 0.3, density = 1000.0 }

[[bodies.constraints]]
region = { min = [-0.001, -0.001], max = [0.001, 0.101] }
velocity = [0.0, 0.0]

[[bodies]]
name = "block"
mesh = { generator = "rectangle", min = [2.0, 0.0], max = [2.2, 0.2], cells = [1, 1], element = "tri3" }
material = { model = "linear_elastic", youngs_modulus = 1.0e6, poissons_ratio = 0.3, density = 1000.0 }
initial_velocity = [1.0, 0.0]

[[probes]]
name = "tip"
body = "beam"
point = [1.0, 0.1]

[[probes]]
name = "corner"
body = "block"
point = [2.0, 0.0]
"#;

const TINY_HEADER: &str = "step,time,iterations,kinetic_energy,internal_energy,contact_energy,\
external_work,dissipated_energy,max_penetration,active_contacts,reaction.beam.x,reaction.beam.y,\
probe.tip.ux,probe.tip.uy,probe.tip.vx,probe.tip.vy,\
probe.corner.ux,probe.corner.uy,probe.corner.vx,probe.corner.vy";

/// Writes `text` as `<dir>/scenes/<stem>.toml`; returns its absolute path.
fn write_scene(dir: &Path, stem: &str, text: &str) -> PathBuf {
    let scenes = dir.join("scenes");
    fs::create_dir_all(&scenes).unwrap();
    let path = scenes.join(format!("{stem}.toml"));
    fs::write(&path, text).unwrap();
    path
}

/// history.csv: the header and the rows as numbers (all finite).
fn history(out: &Path) -> (String, Vec<Vec<f64>>) {
    let text = fs::read_to_string(out.join("history.csv")).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_string();
    let columns = header.split(',').count();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            let row: Vec<f64> = l
                .split(',')
                .map(|c| c.parse::<f64>().unwrap_or_else(|_| panic!("{c:?} in {l}")))
                .collect();
            assert_eq!(row.len(), columns, "{l}");
            assert!(row.iter().all(|x| x.is_finite()), "a non-finite value: {l}");
            row
        })
        .collect();
    (header, rows)
}

fn summary(out: &Path) -> Value {
    let text = fs::read_to_string(out.join("summary.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn assert_success(o: &Output) {
    assert_eq!(o.status.code(), Some(0), "stderr:\n{}", stderr(o));
}

#[test]
fn defaults_out_folder_history_summary_and_vtk() {
    let dir = tempdir();
    let scene = write_scene(dir.path(), "tiny", TINY);
    let work = dir.path().join("work");
    fs::create_dir(&work).unwrap();
    // No --out: the outputs go to out/<scene stem> under the current directory.
    let o = run_in(&work, &["run", scene.to_str().unwrap()]);
    assert_success(&o);
    // Standard error is not a terminal here: nothing but errors.
    assert_eq!(stderr(&o), "", "nothing on a non-terminal stderr");
    assert_eq!(entries(&work), ["out"]);
    let out = work.join("out/tiny");
    assert_eq!(
        entries(&out),
        ["history.csv", "summary.json", "tiny.pvd", "vtk"]
    );

    let (header, rows) = history(&out);
    assert_eq!(
        header, TINY_HEADER,
        "columns in the order of scene-format.md"
    );
    // history_interval = 0 by default: the t = 0 row and one row per step.
    assert_eq!(rows.len(), 11);
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r[0], i as f64, "step column");
        assert!(
            (r[1] - i as f64 * 1e-3).abs() < 1e-12,
            "time column {}",
            r[1]
        );
    }
    // At t = 0: no iteration, the block's kinetic energy 1/2 (1000 * 0.04) 1^2 = 20 J.
    assert_eq!(rows[0][2], 0.0);
    assert!((rows[0][3] - 20.0).abs() < 1e-9, "{}", rows[0][3]);
    // The free block keeps its initial velocity: its probe moves at 1 m/s in x.
    let last = rows.last().unwrap();
    let corner_ux = header
        .split(',')
        .position(|c| c == "probe.corner.ux")
        .unwrap();
    assert!((last[corner_ux] - 0.01).abs() < 1e-9, "{}", last[corner_ux]);
    // Gravity pulls the beam tip down.
    let tip_uy = header.split(',').position(|c| c == "probe.tip.uy").unwrap();
    assert!(last[tip_uy] < 0.0);

    let s = summary(&out);
    for key in [
        "steps",
        "final_time",
        "total_iterations",
        "max_penetration",
        "wall_seconds",
        "energy_drift",
        "scheme_energy_drift",
        "warnings",
    ] {
        assert!(s.get(key).is_some(), "summary.json lacks {key}: {s}");
    }
    assert_eq!(s["steps"], 10);
    assert!((s["final_time"].as_f64().unwrap() - 0.01).abs() < 1e-12);
    let iterations: f64 = rows.iter().map(|r| r[2]).sum();
    assert_eq!(s["total_iterations"].as_f64().unwrap(), iterations);
    assert_eq!(s["max_penetration"], 0.0);
    assert!(s["warnings"].is_array());
    assert_eq!(s["status"], "completed");

    // vtk_interval = 0.01 by default: frames at t = 0 and t = 0.01, one file per body.
    assert_eq!(
        entries(&out.join("vtk")),
        [
            "beam_000000.vtu",
            "beam_000010.vtu",
            "block_000000.vtu",
            "block_000010.vtu"
        ]
    );
    let pvd = fs::read_to_string(out.join("tiny.pvd")).unwrap();
    for f in entries(&out.join("vtk")) {
        assert!(pvd.contains(&format!("file=\"vtk/{f}\"")), "{pvd}");
    }
}

#[test]
fn set_time_step_changes_the_rows() {
    let dir = tempdir();
    let scene = write_scene(dir.path(), "tiny", TINY);
    let out = dir.path().join("o");
    let o = run_in(
        dir.path(),
        &[
            "run",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--set",
            "simulation.time_step=5e-4",
            "--set",
            "output.vtk_interval=0.0",
        ],
    );
    assert_success(&o);
    let (_, rows) = history(&out);
    assert_eq!(rows.len(), 21);
    assert_eq!(summary(&out)["steps"], 20);
    // vtk_interval = 0: no VTK file at all.
    assert_eq!(entries(&out), ["history.csv", "summary.json"]);
}

#[test]
fn history_interval_thins_the_rows() {
    let dir = tempdir();
    let scene = write_scene(dir.path(), "tiny", TINY);
    let out = dir.path().join("o");
    let o = run_in(
        dir.path(),
        &[
            "run",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--set",
            "output.history_interval=2e-3",
            "--set",
            "output.vtk_interval=0.0",
        ],
    );
    assert_success(&o);
    let (_, rows) = history(&out);
    let steps: Vec<f64> = rows.iter().map(|r| r[0]).collect();
    assert_eq!(steps, [0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
}

#[test]
fn last_step_is_shortened_to_end_time() {
    let dir = tempdir();
    let scene = write_scene(dir.path(), "tiny", TINY);
    let out = dir.path().join("o");
    let o = run_in(
        dir.path(),
        &[
            "run",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--set",
            "simulation.end_time=0.0045",
            "--quiet",
        ],
    );
    assert_success(&o);
    assert_eq!(
        stderr(&o),
        "",
        "--quiet prints nothing for a successful run"
    );
    let (_, rows) = history(&out);
    assert_eq!(rows.len(), 6, "5 steps: 4 of 1 ms and one of 0.5 ms");
    let last = rows.last().unwrap();
    assert_eq!(last[0], 5.0);
    assert!((last[1] - 0.0045).abs() < 1e-15, "ends at {}", last[1]);
    assert!((rows[4][1] - 0.004).abs() < 1e-15);
    let s = summary(&out);
    assert!((s["final_time"].as_f64().unwrap() - 0.0045).abs() < 1e-15);
    // The last VTK frame is the end state.
    assert!(entries(&out.join("vtk")).contains(&"beam_000005.vtu".to_string()));
}

#[test]
fn alpha_outside_the_window_is_a_warning_in_the_summary() {
    let dir = tempdir();
    let scene = write_scene(dir.path(), "tiny", TINY);
    let out = dir.path().join("o");
    let o = run_in(
        dir.path(),
        &[
            "run",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--set",
            "simulation.alpha=0.6",
            "--quiet",
        ],
    );
    assert_success(&o);
    assert_eq!(stderr(&o), "", "--quiet: the warning is not printed");
    let s = summary(&out);
    let warnings: Vec<&str> = s["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("alpha = 0.6") && w.contains("stability")),
        "{warnings:?}"
    );
    // `check` shows it too.
    let o = run_in(
        dir.path(),
        &[
            "check",
            scene.to_str().unwrap(),
            "--set",
            "simulation.alpha=0.6",
        ],
    );
    assert_success(&o);
    assert!(
        stdout(&o).contains("warning: alpha = 0.6"),
        "{}",
        stdout(&o)
    );
}

#[test]
fn check_prints_a_summary_and_creates_nothing() {
    let dir = tempdir();
    let scene = write_scene(dir.path(), "tiny", TINY);
    let work = dir.path().join("work");
    fs::create_dir(&work).unwrap();
    let o = run_in(&work, &["check", scene.to_str().unwrap()]);
    assert_success(&o);
    let text = stdout(&o);
    assert!(text.contains("valid"), "{text}");
    assert!(text.contains("(10 steps)"), "{text}");
    assert!(text.contains("body `beam`: 10 nodes, 4 cells"), "{text}");
    assert!(text.contains("body `block`: 4 nodes, 2 cells"), "{text}");
    assert!(text.contains("probe `tip`"), "{text}");
    assert_eq!(stderr(&o), "");
    assert!(
        entries(&work).is_empty(),
        "check wrote {:?}",
        entries(&work)
    );
    assert_eq!(entries(&dir.path().join("scenes")), ["tiny.toml"]);
}

#[test]
fn three_dimensional_run() {
    let scene_text = r#"
[simulation]
dimension = 3
time_step = 1.0e-3
end_time = 0.003
gravity = [0.0, 0.0, -9.81]

[[bodies]]
name = "block"
mesh = { generator = "box", min = [0.0, 0.0, 0.0], max = [1.0, 0.2, 0.2], cells = [3, 1, 1], element = "tet4" }
material = { model = "linear_elastic", youngs_modulus = 1.0e6, poissons_ratio = 0.3, density = 1000.0 }

[[bodies.constraints]]
region = { min = [-0.001, -1.0, -1.0], max = [0.001, 1.0, 1.0] }
velocity = { z = 0.0 }

[[probes]]
name = "tip"
body = "block"
point = [1.0, 0.2, 0.2]

[output]
vtk_interval = 0.0
"#;
    let dir = tempdir();
    let scene = write_scene(dir.path(), "block", scene_text);
    let out = dir.path().join("o");
    let o = run_in(
        dir.path(),
        &[
            "run",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
    );
    assert_success(&o);
    let (header, rows) = history(&out);
    assert!(
        header.ends_with(
            "active_contacts,reaction.block.x,reaction.block.y,reaction.block.z,\
         probe.tip.ux,probe.tip.uy,probe.tip.uz,probe.tip.vx,probe.tip.vy,probe.tip.vz"
        ),
        "{header}"
    );
    assert_eq!(rows.len(), 4);
    // Only z is held: the reaction is vertical and carries the weight.
    let last = rows.last().unwrap();
    assert!(last[12] > 0.0, "reaction.block.z {}", last[12]);
}

// ---------------------------------------------------------------------------------------------
// --set.

#[test]
fn bad_set_overrides() {
    let dir = tempdir();
    let scene = write_scene(dir.path(), "tiny", TINY);
    let path = scene.to_str().unwrap();
    let empty = tempdir();
    let set = |arg: &str| {
        let out = empty.path().join("out");
        assert_invalid(
            empty.path(),
            &["run", path, "--out", out.to_str().unwrap(), "--set", arg],
        )
    };
    let err = set("simulation.time_step");
    assert!(
        err.contains(path) && err.contains("--set simulation.time_step"),
        "{err}"
    );
    assert!(err.contains("expected KEY=VALUE"), "{err}");
    let err = set("simulation.time_step=fast");
    assert!(err.contains("not a TOML literal"), "{err}");
    let err = set("simulation..time_step=1.0");
    assert!(err.contains("not a dotted key path"), "{err}");
    // A list item that does not exist.
    let err = set("bodies.5.name=\"x\"");
    assert!(
        err.contains("`bodies` has 2 items; index 5 is out of range"),
        "{err}"
    );
    let err = set("probes.nozzle.point=[0.0, 0.0]");
    assert!(
        err.contains("no item of `probes` is named `nozzle`"),
        "{err}"
    );
    // A value from --set is reported as such, not at the line of the file.
    let err = set("bodies.0.material.youngs_modulus=-1.0");
    check_message(
        &err,
        &scene,
        &Expect {
            key: "bodies.0.material.youngs_modulus",
            marker: None,
            found: "-1",
            expected: "> 0 [Pa]",
        },
    );
    assert!(
        err.contains("--set: `bodies.0.material.youngs_modulus`"),
        "{err}"
    );
    assert!(!err.contains("line "), "{err}");
    // A misspelt key is an unknown key, not a silently added one.
    let err = set("simulation.time_stp=1e-4");
    assert!(
        err.contains("`simulation.time_stp`") && err.contains("unknown field"),
        "{err}"
    );
    let err = set("simulation.beta=\"midpoint\"");
    assert!(
        err.contains("`simulation.beta`: found \"midpoint\""),
        "{err}"
    );
}

#[test]
fn set_addresses_obstacles_by_name() {
    let text = format!(
        "{TINY}\n[[obstacles]]\nname = \"floor\"\n\
         shape = {{ type = \"halfspace\", point = [0.0, -1.0], normal = [0.0, 1.0] }}\n"
    );
    let dir = tempdir();
    let scene = write_scene(dir.path(), "tiny", &text);
    let path = scene.to_str().unwrap();
    let work = dir.path().join("work");
    fs::create_dir(&work).unwrap();
    let o = run_in(
        &work,
        &[
            "check",
            path,
            "--set",
            "obstacles.floor.velocity=[0.0, 1.0]",
        ],
    );
    assert_success(&o);
    assert!(stdout(&o).contains("obstacle `floor`"), "{}", stdout(&o));
    let err = assert_invalid(
        &work,
        &["check", path, "--set", "obstacles.floor.velocity=[1.0]"],
    );
    assert!(
        err.contains("`obstacles.0.velocity`: found 1 components"),
        "{err}"
    );
    let err = assert_invalid(
        &work,
        &["check", path, "--set", "obstacles.wall.velocity=[1.0, 0.0]"],
    );
    assert!(
        err.contains("no item of `obstacles` is named `wall`"),
        "{err}"
    );
    // Obstacles run, with their contact force columns in history.csv.
    let o = run_in(&work, &["run", path, "--quiet"]);
    assert_success(&o);
    let history = fs::read_to_string(work.join("out/tiny/history.csv")).unwrap();
    assert!(history
        .lines()
        .next()
        .unwrap()
        .contains("contact_force.floor.x,contact_force.floor.y"));
}

// ---------------------------------------------------------------------------------------------
// Options this build lacks or values they refuse: refused cleanly, nothing written.

#[test]
fn unavailable_or_invalid_options_are_refused_cleanly() {
    let dir = tempdir();
    let scene = write_scene(dir.path(), "tiny", TINY);
    let path = scene.to_str().unwrap();
    let work = dir.path().join("work");
    fs::create_dir(&work).unwrap();
    #[cfg(not(feature = "rerun"))]
    {
        let err = assert_invalid(&work, &["run", path, "--rerun", "run.rrd"]);
        assert!(err.contains("--rerun is not available"), "{err}");
    }
    let err = assert_invalid(&work, &["run", path, "--checkpoint-every", "0"]);
    assert!(
        err.contains("`--checkpoint-every`: found 0, expected a number of steps, at least 1"),
        "{err}"
    );
}

// ---------------------------------------------------------------------------------------------
// Instability: exit status 3, the history up to the last good step.

/// A steel cantilever 1 m x 0.1 m (10 x 2 quad4, element size 0.1 m), tip moving down.
fn cantilever(alpha: f64, time_step: f64) -> String {
    format!(
        r#"[simulation]
dimension = 2
time_step = {time_step:e}
end_time = 0.1
alpha = {alpha}
beta = "energy"

[[bodies]]
name = "beam"
mesh = {{ generator = "rectangle", min = [0.0, 0.0], max = [1.0, 0.1], cells = [10, 2], element = "quad4" }}
material = {{ model = "linear_elastic", youngs_modulus = 2.1e11, poissons_ratio = 0.3, density = 7800.0 }}
initial_velocity = [0.0, -0.1]

[[bodies.constraints]]
region = {{ min = [-0.001, -0.001], max = [0.001, 0.101] }}
velocity = [0.0, 0.0]

[[probes]]
name = "tip"
body = "beam"
point = [1.0, 0.05]

[output]
vtk_interval = 0.02
"#
    )
}

/// 20 times the explicit stable step: element size / plane-strain P-wave speed.
fn large_step() -> f64 {
    let (e, nu, rho) = (2.1e11_f64, 0.3_f64, 7800.0_f64);
    let c = (e * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu) * rho)).sqrt();
    20.0 * 0.1 / c
}

/// alpha = 1/2 at 20 times the explicit step: the unresolved modes grow. The run monitor sees
/// the mechanical energy pass eleven times the input after two steps (the library's own check,
/// a growth by 1e6, came at step 10 before the monitor watched E outside the window) and stops
/// with exit status 3, naming the scheme, with the history of the steps taken.
#[test]
fn instability_exits_3_with_the_history_written() {
    let h = large_step();
    let dir = tempdir();
    let scene = write_scene(dir.path(), "cantilever", &cantilever(0.5, h));
    let out = dir.path().join("o");
    let o = run_in(
        dir.path(),
        &[
            "run",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(
        err.lines().filter(|l| l.starts_with("error")).count(),
        1,
        "{err}"
    );

    let s = summary(&out);
    assert_eq!(s["status"], "failed");
    // The monitor stops after the step that crossed the limit: it is in the history.
    let good = s["steps"].as_u64().unwrap();
    assert!((1..300).contains(&good), "stopped after {good} good steps");
    assert!(
        err.contains(&format!("energy created at step {good} "))
            && err.contains("the mechanical energy"),
        "{err}"
    );
    assert!(
        err.contains("the time scheme is the likely cause: alpha = 0.5, beta = 0.5")
            && err.contains("alpha >= sqrt(2)/2")
            && err.contains("smaller time_step"),
        "{err}"
    );
    assert!(
        err.contains(&format!("history up to step {good} written")),
        "{err}"
    );
    assert!(
        s["error"].as_str().unwrap().contains("energy created"),
        "{s}"
    );

    // Every row up to the last good step, nothing after, nothing non-finite anywhere.
    let (_, rows) = history(&out);
    assert_eq!(rows.len() as u64, good + 1);
    assert_eq!(rows.last().unwrap()[0], good as f64);
    for file in ["history.csv", "summary.json", "cantilever.pvd"] {
        let text = fs::read_to_string(out.join(file)).unwrap().to_lowercase();
        assert!(!text.contains("nan") && !text.contains("inf"), "{file}");
    }
    for f in entries(&out.join("vtk")) {
        let text = fs::read_to_string(out.join("vtk").join(f))
            .unwrap()
            .to_lowercase();
        assert!(!text.contains("nan") && !text.contains("inf"));
    }
}

#[test]
fn the_same_step_is_stable_with_alpha_in_the_window() {
    let h = large_step();
    let dir = tempdir();
    let scene = write_scene(dir.path(), "cantilever", &cantilever(0.75, h));
    let out = dir.path().join("o");
    let o = run_in(
        dir.path(),
        &[
            "run",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
    );
    assert_success(&o);
    let (_, rows) = history(&out);
    assert_eq!(
        rows.len(),
        303,
        "301 steps, a shortened last one and the t = 0 row"
    );
    // kinetic + internal energy: it oscillates (a 20x step is far from resolving the stiff
    // modes) but does not grow: no external work is done on the clamped beam.
    let energy: Vec<f64> = rows.iter().map(|r| r[3] + r[4]).collect();
    let (first, second) = energy.split_at(energy.len() / 2);
    let max = |e: &[f64]| e.iter().cloned().fold(0.0, f64::max);
    assert!(
        max(&energy) < 10.0 * energy[0],
        "{} vs E(0) = {}",
        max(&energy),
        energy[0]
    );
    assert!(
        max(second) <= max(first),
        "{} > {}",
        max(second),
        max(first)
    );
}

// ---------------------------------------------------------------------------------------------
// The bundled scenes.

#[test]
fn every_bundled_scene_passes_check() {
    let dir = tempdir();
    let mut n = 0;
    // The bundled scenes, and the measurement scenes the book's figures name.
    let files = ["fixtures/scenes", "benches/scenes"]
        .iter()
        .flat_map(|d| fs::read_dir(repo().join(d)).unwrap());
    for e in files {
        let path = e.unwrap().path();
        if path.extension().is_some_and(|x| x == "toml") {
            let o = run_in(dir.path(), &["check", path.to_str().unwrap()]);
            assert_eq!(
                o.status.code(),
                Some(0),
                "{}: {}",
                path.display(),
                stderr(&o)
            );
            assert!(stdout(&o).contains("valid"));
            // No overlap at t = 0, of any depth.
            assert!(
                !stdout(&o).contains("overlaps"),
                "{}: {}",
                path.display(),
                stdout(&o)
            );
            n += 1;
        }
    }
    assert!(n >= 1);
    assert!(
        entries(dir.path()).is_empty(),
        "check wrote {:?}",
        entries(dir.path())
    );
}

/// Energy that the account books as created (negative dissipation, explicit projection on the
/// bundled ring drop) closes the account, so energy_drift stays small: the summary says so in
/// a warning.
#[test]
fn booked_energy_growth_is_a_warning_in_the_summary() {
    let dir = tempdir();
    let out = dir.path().join("out");
    let scene = repo().join("fixtures/scenes/ring_drop.toml");
    let o = run_in(
        dir.path(),
        &[
            "run",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--set",
            "contact.method=\"explicit_projection\"",
            "--set",
            "simulation.end_time=0.4",
            "--set",
            "output.vtk_interval=0",
            "--quiet",
        ],
    );
    assert_success(&o);
    let s = summary(&out);
    let dissipated = s["dissipated_energy"].as_f64().unwrap();
    assert!(dissipated < 0.0, "dissipated {dissipated}");
    assert!(s["energy_drift"].as_f64().unwrap() < 0.05, "{s}");
    let warnings: Vec<&str> = s["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    assert!(
        warnings.iter().any(|w| w.contains("the run created")),
        "{warnings:?}"
    );
}

// ---------------------------------------------------------------------------------------------
// --rerun (feature `rerun`): the recording is written next to the outputs, its missing parent
// folders created (as --out is); a file that cannot be created is invalid input (nothing run).

#[cfg(feature = "rerun")]
#[test]
fn rerun_recording_is_written() {
    let dir = tempdir();
    let scene = write_scene(dir.path(), "tiny", TINY);
    let path = scene.to_str().unwrap();
    let work = dir.path().join("work");
    fs::create_dir(&work).unwrap();
    let o = run_in(&work, &["run", path, "--rerun", "run.rrd", "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let bytes = fs::read(work.join("run.rrd")).unwrap();
    assert_eq!(&bytes[..4], b"RRF2");
    assert!(work.join("out/tiny/history.csv").is_file());

    // The folders of the recording are created as --out's are.
    let o = run_in(
        &work,
        &["run", path, "--rerun", "new/sub/run.rrd", "--quiet"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let bytes = fs::read(work.join("new/sub/run.rrd")).unwrap();
    assert_eq!(&bytes[..4], b"RRF2");
    assert_eq!(entries(&work.join("new/sub")), ["run.rrd"]);

    // A folder that cannot be created (a file is in the way).
    let empty = dir.path().join("empty");
    fs::create_dir(&empty).unwrap();
    let blocked = scene.join("run.rrd");
    let err = assert_invalid(&empty, &["run", path, "--rerun", blocked.to_str().unwrap()]);
    assert!(
        err.starts_with(&format!("error: cannot write {path}: ")),
        "{err}"
    );
}

// ---------------------------------------------------------------------------------------------
// Large rotations: a small-strain body that turns is reported; the hypoelastic one is not.

const SPINNING: &str = r#"# A free plate spinning at 5 rad/s for 0.1 s (29 degrees).
[simulation]
dimension = 2
time_step = 2.0e-3
end_time = 0.1

[[bodies]]
name = "plate"
mesh = { generator = "rectangle", min = [-0.5, -0.5], max = [0.5, 0.5], cells = [2, 2], element = "quad4" }
material = { model = "linear_elastic", youngs_modulus = 1.0e8, poissons_ratio = 0.3, density = 1000.0 }
initial_angular_velocity = 5.0
"#;

#[test]
fn a_small_strain_body_that_turns_is_reported() {
    let dir = tempdir();
    let scene = write_scene(dir.path(), "spinning", SPINNING);
    let path = scene.to_str().unwrap();
    let out = dir.path().join("small");
    let o = run_in(dir.path(), &["run", path, "--out", out.to_str().unwrap()]);
    assert_success(&o);
    let warnings = summary(&out)["warnings"].to_string();
    assert!(
        warnings.contains("body `plate` turned") && warnings.contains("hypoelastic"),
        "{warnings}"
    );
    let out = dir.path().join("large");
    let o = run_in(
        dir.path(),
        &[
            "run",
            path,
            "--out",
            out.to_str().unwrap(),
            "--set",
            "bodies.0.material.model = \"hypoelastic\"",
        ],
    );
    assert_success(&o);
    let warnings = summary(&out)["warnings"].to_string();
    assert!(!warnings.contains("turned"), "{warnings}");
}

/// The time scheme chapter's rising floor (a block on a floor rising at 0.3 m/s under gravity,
/// h = 1/60 s): `energy_drift` carries the O(h) offset of the gravity's work measured on u
/// (a h f dv = 0.1226 J of 0.9 J), `scheme_energy_drift`, the account on the scheme's
/// conserved energy with the work on its shadow displacement, closes; no warning.
#[test]
fn the_scheme_account_has_no_load_offset() {
    let dir = tempdir();
    let scene = write_scene(
        dir.path(),
        "rising_floor",
        r#"
[simulation]
dimension = 2
time_step = 0.016666666666666666
end_time = 1.5
gravity = [0.0, -9.81]

[[bodies]]
name = "block"
mesh = { generator = "rectangle", min = [0.0, 0.0], max = [0.1, 0.1], cells = [2, 2], element = "quad4" }
material = { model = "linear_elastic", youngs_modulus = 1.0e6, poissons_ratio = 0.3, density = 1.0e3 }
damping = { mass = 0.0, stiffness = 1.0e-3 }

[[obstacles]]
name = "floor"
shape = { type = "halfspace", point = [0.0, 0.0], normal = [0.0, 1.0] }
velocity = [0.0, 0.3]

[output]
vtk_interval = 0.0
"#,
    );
    let out = dir.path().join("out");
    let o = run_scene(dir.path(), &scene, &out, &[]);
    assert_success(&o);
    let s = summary(&out);
    let (drift, scheme) = (
        s["energy_drift"].as_f64().unwrap(),
        s["scheme_energy_drift"].as_f64().unwrap(),
    );
    eprintln!("energy_drift {drift:.4e}, scheme_energy_drift {scheme:.3e}");
    assert!((0.1..0.2).contains(&drift), "energy_drift {drift}");
    assert!(scheme < 1e-6, "scheme_energy_drift {scheme}");
    assert!(warnings(&out).is_empty(), "{:?}", warnings(&out));
}
