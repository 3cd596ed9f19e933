//! The bundled scenes as a newcomer runs them: `softway run fixtures/scenes/<scene>.toml`, no
//! option, to the end. Each must end with exit status 0 and exactly the warnings the book's
//! command-line chapter lists for it (Limits and monitors): a change that adds a warning to a
//! bundled scene, or cures one, fails here until the book and this list say so. The tube
//! crush is left out for its 2 minutes (dev build, 2 cores; CI's budget): at its defaults it ends
//! with one warning, penetration 9.3e-5 m against 2.4e-5 m, which the book lists too
//! (`examples/tube_crush.rs` runs it whole, ignored for time).

use std::fs;

use serde_json::Value;

use super::support::*;

/// Each bundled scene with the start of each warning its run at the defaults gives.
const EXPECTED: &[(&str, &[&str])] = &[
    // Three blocks landing on each other at a game's step under implicit projection: its
    // landing was cut in halves until Newton's merit for held constraints, and one step's
    // contact set cycled until the held multipliers were carried (both 2026-12-01; at 1/240 s
    // one cycling step remains, issue 10).
    ("block_stack", &[]),
    ("cantilever", &[]),
    ("cantilever_3d", &[]),
    ("folding_strip", &[]),
    ("gmsh_plate", &[]),
    ("gripper", &[]),
    // On the paper's configuration gaps the stored configuration's offset created 25 % at step
    // 2; on trapezoid gaps none.
    ("octagon_compression", &[]),
    ("resting_block", &[]),
    // At zeta = 1e10 Pa/m the paper's configuration gaps put energy in at each bounce (5.7 %
    // at step 582 of 600); at 3e9 none.
    ("ring_drop", &[]),
    ("rolling_ring", &[]),
    // Its scheme (alpha = 0.8, beta = 0.3) damps the massless tube's modes by design: 48.8 %
    // of the bore's work is that damping, which `scheme_energy_drift` shows (2026-12-01).
    (
        "thick_cylinder",
        &["the energy account does not close: 48.8% of the input"],
    ),
    ("tilting_floor", &[]),
];

/// Scenes left out of [`EXPECTED`], with the reason.
const LEFT_OUT: &[&str] = &["tube_crush"];

#[test]
fn every_bundled_scene_runs_with_the_warnings_the_book_lists() {
    let scenes = repo().join("fixtures/scenes");
    let mut bundled: Vec<String> = fs::read_dir(&scenes)
        .unwrap()
        .filter_map(|e| {
            let path = e.unwrap().path();
            (path.extension()? == "toml").then(|| path.file_stem()?.to_str().map(String::from))?
        })
        .filter(|name| !LEFT_OUT.contains(&name.as_str()))
        .collect();
    bundled.sort();
    let listed: Vec<&str> = EXPECTED.iter().map(|e| e.0).collect();
    assert_eq!(
        bundled, listed,
        "a bundled scene without its expected warnings here"
    );

    let dir = tempdir();
    let mut wrong = Vec::new();
    for (name, expected) in EXPECTED {
        let out = dir.path().join(name);
        let file = scenes.join(format!("{name}.toml"));
        let o = run_scene(dir.path(), &file, &out, &[]);
        assert_eq!(o.status.code(), Some(0), "{name}: {}", stderr(&o));
        let summary: Value =
            serde_json::from_str(&fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        assert_eq!(summary["status"], "completed", "{name}");
        let warnings = warnings(&out);
        let matches = warnings.len() == expected.len()
            && warnings
                .iter()
                .zip(*expected)
                .all(|(w, e)| w.starts_with(e));
        eprintln!("{name}: {warnings:?}");
        if !matches {
            wrong.push(format!("{name}: expected {expected:?}, got {warnings:?}"));
        }
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
}
