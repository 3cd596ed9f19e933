//! Running the binary and checking its messages.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

pub(crate) fn softway() -> Command {
    Command::new(env!("CARGO_BIN_EXE_softway"))
}

pub(crate) fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub(crate) fn bad(name: &str) -> PathBuf {
    repo()
        .join("fixtures/scenes/bad")
        .join(format!("{name}.toml"))
}

pub(crate) fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

pub(crate) fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

pub(crate) fn tempdir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temporary folder")
}

/// Runs `softway ARGS` in `dir`.
pub(crate) fn run_in(dir: &Path, args: &[&str]) -> Output {
    softway()
        .current_dir(dir)
        .args(args)
        .output()
        .expect("the softway binary runs")
}

/// The 1-based number of the first line of `file` (not a comment) that contains `marker`.
pub(crate) fn line_of(file: &Path, marker: &str) -> usize {
    let text = fs::read_to_string(file).unwrap();
    text.lines()
        .position(|l| !l.starts_with('#') && l.contains(marker))
        .unwrap_or_else(|| panic!("{marker:?} is not in {}", file.display()))
        + 1
}

pub(crate) fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Exit status 2, one error message and no panic, nothing written: `dir` stays empty (no
/// `--out` folder, no default `out/`). Returns the message.
pub(crate) fn assert_invalid(dir: &Path, args: &[&str]) -> String {
    let o = run_in(dir, args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: stderr:\n{err}");
    assert!(!err.contains("panicked"), "{args:?} panicked:\n{err}");
    assert!(err.starts_with("error: "), "{args:?}: {err}");
    let messages = err.lines().filter(|l| l.starts_with("error")).count();
    assert_eq!(messages, 1, "{args:?}: one error message expected:\n{err}");
    assert!(!err.contains("warning"), "{args:?}: {err}");
    assert!(stdout(&o).is_empty(), "{args:?}: stdout {:?}", stdout(&o));
    assert!(
        entries(dir).is_empty(),
        "{args:?} created {:?} although the input is invalid",
        entries(dir)
    );
    err
}

/// What a message about a key must say.
pub(crate) struct Expect<'a> {
    /// The dotted key path.
    pub(crate) key: &'a str,
    /// A text on the line the message must point to; `None` when the key has no line (it is
    /// missing from the file, or was set with `--set`).
    pub(crate) marker: Option<&'a str>,
    /// Part of what was found.
    pub(crate) found: &'a str,
    /// Part of what was expected.
    pub(crate) expected: &'a str,
}

pub(crate) fn check_message(err: &str, file: &Path, e: &Expect) {
    let shown = file.display().to_string();
    assert!(
        err.contains(&shown),
        "the message names the file {shown}:\n{err}"
    );
    assert!(
        err.contains(&format!("`{}`", e.key)),
        "the message names `{}`:\n{err}",
        e.key
    );
    if let Some(marker) = e.marker {
        let line = line_of(file, marker);
        assert!(
            err.contains(&format!("line {line}: ")),
            "line {line} expected:\n{err}"
        );
    }
    let found = err.find("found ").expect("found ...");
    let expected = err.rfind("expected ").expect("expected ...");
    assert!(found < expected, "{err}");
    assert!(
        err[found..].contains(e.found),
        "found {:?}:\n{err}",
        e.found
    );
    assert!(
        err[expected..].contains(e.expected),
        "expected {:?}:\n{err}",
        e.expected
    );
}

/// A bad fixture: `run` and `check` both refuse it with the same message.
pub(crate) fn assert_bad_scene(name: &str, e: Expect) {
    let file = bad(name);
    let dir = tempdir();
    let path = file.to_str().unwrap();
    let out = dir.path().join("out");
    let err = assert_invalid(dir.path(), &["run", path, "--out", out.to_str().unwrap()]);
    check_message(&err, &file, &e);
    let err2 = assert_invalid(dir.path(), &["run", path]);
    assert_eq!(
        err, err2,
        "{name}: the same message with the default output folder"
    );
    let err3 = assert_invalid(dir.path(), &["check", path]);
    assert_eq!(err, err3, "{name}: `check` gives the same message as `run`");
}

/// `assert_bad_scene` for each (file, key, line marker, found, expected).
pub(crate) fn assert_bad_scenes(cases: &[(&str, &str, &str, &str, &str)]) {
    for &(name, key, marker, found, expected) in cases {
        assert_bad_scene(
            name,
            Expect {
                key,
                marker: Some(marker),
                found,
                expected,
            },
        );
    }
}

/// `softway run FILE --out OUT` with `sets` (further arguments, `--set` pairs), in `dir`.
pub(crate) fn run_scene(dir: &Path, file: &Path, out: &Path, sets: &[&str]) -> Output {
    let mut args = vec![
        "run",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(sets);
    run_in(dir, &args)
}

/// The first line of stderr that starts with `error`.
pub(crate) fn error_line(o: &Output) -> String {
    stderr(o)
        .lines()
        .find(|l| l.starts_with("error"))
        .unwrap_or_default()
        .to_string()
}

/// The warnings of `OUT/summary.json`.
pub(crate) fn warnings(out: &Path) -> Vec<String> {
    let s: Value = serde_json::from_str(&fs::read_to_string(out.join("summary.json")).unwrap())
        .expect("summary.json");
    s["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap().to_string())
        .collect()
}
