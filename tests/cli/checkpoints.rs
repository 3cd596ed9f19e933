//! Checkpoints, `resume`, interrupts and atomic outputs: the real binary is stopped mid-way
//! (SIGINT, SIGTERM, SIGKILL), every output it leaves is complete or absent (parsed), and
//! resuming from a checkpoint ends with the uninterrupted run's history.csv byte for byte.
//!
//! The scene is `ring_drop.toml` cut short (the ring lands at t = 0.166 s, so the contact
//! memory is in the checkpoints after that).

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use serde_json::Value;

use super::support::*;

/// Long enough to stop it mid-way (about 0.6 s of run), short enough for the suite.
const END_TIME: &str = "simulation.end_time=0.4";
/// The steps of that run.
const STEPS: usize = 400;
/// Fewer VTK frames than the bundled scene, but some on each side of the checkpoints.
const VTK: &str = "output.vtk_interval=0.05";

fn ring_drop() -> PathBuf {
    repo().join("fixtures/scenes/ring_drop.toml")
}

fn run_args(out: &Path, extra: &[&str]) -> Vec<String> {
    let mut args: Vec<String> = [
        "run",
        ring_drop().to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--set",
        END_TIME,
        "--set",
        VTK,
        "--quiet",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    args.extend(extra.iter().map(|s| s.to_string()));
    args
}

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("cli_checkpoints")
        .join(name);
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

/// The uninterrupted run with a checkpoint every 25 steps, once per test binary: its folder.
fn reference() -> &'static Path {
    static REFERENCE: OnceLock<PathBuf> = OnceLock::new();
    REFERENCE.get_or_init(|| {
        let out = scratch("reference").join("out");
        let o = softway()
            .args(run_args(&out, &["--checkpoint-every", "25"]))
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        out
    })
}

fn history_text(out: &Path) -> String {
    fs::read_to_string(out.join("history.csv")).unwrap()
}

fn summary(out: &Path) -> Value {
    serde_json::from_str(&fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

fn resume(checkpoint: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec!["resume", checkpoint.to_str().unwrap(), "--quiet"];
    args.extend_from_slice(extra);
    softway().args(&args).output().unwrap()
}

/// Spawns `softway ARGS` and waits until `file` exists (the run is that far).
fn spawn_until(args: &[String], cwd: &Path, file: &Path) -> Child {
    let mut child = softway()
        .args(args)
        .current_dir(cwd)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let started = Instant::now();
    while !file.exists() {
        if let Some(status) = child.try_wait().unwrap() {
            let mut err = String::new();
            use std::io::Read;
            child
                .stderr
                .take()
                .unwrap()
                .read_to_string(&mut err)
                .unwrap();
            panic!("the run ended ({status}) before {}:\n{err}", file.display());
        }
        assert!(
            started.elapsed() < Duration::from_secs(300),
            "{} never appeared",
            file.display()
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    child
}

fn signal(child: &Child, name: &str) {
    let ok = Command::new("kill")
        .args([&format!("-{name}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
}

/// Checks a well-formed XML file that closes its root element.
fn assert_xml(path: &Path) {
    let text = fs::read_to_string(path).unwrap();
    assert!(
        text.trim_end().ends_with("</VTKFile>"),
        "{} is cut short",
        path.display()
    );
    let mut reader = quick_xml::Reader::from_str(&text);
    loop {
        match reader.read_event() {
            Ok(quick_xml::events::Event::Eof) => break,
            Ok(_) => {}
            Err(e) => panic!("{}: {e}", path.display()),
        }
    }
}

/// Every output in `out` is complete (parsed) or absent; `*.tmp` files are the partial
/// temporaries a killed run may leave beside them, outputs by contract they are not.
/// Returns the checkpoints, by step.
fn assert_complete_or_absent(out: &Path) -> Vec<(usize, PathBuf)> {
    let history = out.join("history.csv");
    if history.exists() {
        let text = fs::read_to_string(&history).unwrap();
        assert!(text.ends_with('\n'), "a partial row:\n{text}");
        let mut lines = text.lines();
        let columns = lines.next().unwrap().split(',').count();
        for l in lines {
            let cells: Vec<f64> = l.split(',').map(|c| c.parse().unwrap()).collect();
            assert_eq!(cells.len(), columns, "{l}");
        }
    }
    if out.join("summary.json").exists() {
        summary(out);
    }
    let pvd = out.join("ring_drop.pvd");
    if pvd.exists() {
        assert_xml(&pvd);
        let text = fs::read_to_string(&pvd).unwrap();
        for part in text.split("file=\"").skip(1) {
            let file = &part[..part.find('"').unwrap()];
            assert!(out.join(file).is_file(), "the .pvd lists a missing {file}");
        }
    }
    if out.join("vtk").exists() {
        for entry in fs::read_dir(out.join("vtk")).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "vtu") {
                assert_xml(&path);
            }
        }
    }
    let mut checkpoints = Vec::new();
    if out.join("checkpoints").exists() {
        for entry in fs::read_dir(out.join("checkpoints")).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_str().unwrap().to_string();
            if name.ends_with(".tmp") {
                continue;
            }
            let step: usize = name
                .strip_prefix("step_")
                .and_then(|n| n.strip_suffix(".ckpt"))
                .unwrap_or_else(|| panic!("{name}"))
                .parse()
                .unwrap();
            let bytes = fs::read(&path).unwrap();
            let newline = bytes.iter().position(|&b| b == b'\n').unwrap();
            let header = std::str::from_utf8(&bytes[..newline]).unwrap();
            let length: usize = header
                .split(' ')
                .find_map(|w| w.strip_prefix("bytes="))
                .unwrap()
                .parse()
                .unwrap();
            assert_eq!(bytes.len() - newline - 1, length, "{name} is cut short");
            let _: Value = serde_json::from_slice(&bytes[newline + 1..]).unwrap();
            checkpoints.push((step, path));
        }
    }
    checkpoints.sort();
    checkpoints
}

fn verify_recording(file: &Path) {
    let Ok(o) = Command::new("rerun")
        .args(["rrd", "verify", file.to_str().unwrap()])
        .output()
    else {
        eprintln!("no `rerun` on PATH: the recording is not verified");
        return;
    };
    assert!(
        o.status.success(),
        "rerun rrd verify {}:\n{}{}",
        file.display(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn checkpoints_change_nothing_and_resume_bit_for_bit() {
    let reference = reference();
    let expected = history_text(reference);
    assert_eq!(
        summary(reference)["last_checkpoint"],
        format!("checkpoints/step_{STEPS}.ckpt").as_str()
    );
    let checkpoints = assert_complete_or_absent(reference);
    let steps: Vec<usize> = checkpoints.iter().map(|c| c.0).collect();
    assert_eq!(steps, (1..=STEPS / 25).map(|k| 25 * k).collect::<Vec<_>>());

    // The same run without checkpoints writes the same history.
    let dir = scratch("plain");
    let o = softway()
        .args(run_args(&dir.join("out"), &[]))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(history_text(&dir.join("out")), expected);
    assert!(!dir.join("out/checkpoints").exists());

    // Resumed into another folder (after the ring landed): the same history; the .pvd there
    // lists the frames of that folder only.
    let elsewhere = dir.join("elsewhere");
    let ckpt = reference.join("checkpoints/step_200.ckpt");
    let o = resume(&ckpt, &["--out", elsewhere.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(history_text(&elsewhere), expected);
    let s = summary(&elsewhere);
    assert_eq!(s["status"], "completed");
    assert_eq!(s["steps"], STEPS);
    assert_eq!(
        s["total_iterations"],
        summary(reference)["total_iterations"]
    );
    // Resume keeps the run's checkpoint interval.
    let again = assert_complete_or_absent(&elsewhere);
    assert_eq!(
        again.iter().map(|c| c.0).collect::<Vec<_>>(),
        (9..=STEPS / 25).map(|k| 25 * k).collect::<Vec<_>>()
    );
    // The resumed run's last state is the uninterrupted run's, bit for bit.
    let state = |out: &Path| {
        let bytes = fs::read(out.join(format!("checkpoints/step_{STEPS}.ckpt"))).unwrap();
        let newline = bytes.iter().position(|&b| b == b'\n').unwrap();
        let v: Value = serde_json::from_slice(&bytes[newline + 1..]).unwrap();
        v["state"].clone()
    };
    assert_eq!(state(&elsewhere), state(reference));

    // Resumed into its own folder (the default --out) from before the landing.
    let copy = dir.join("copy");
    copy_dir(reference, &copy);
    fs::write(copy.join("history.csv"), "damaged").unwrap();
    let o = resume(&copy.join("checkpoints/step_75.ckpt"), &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(history_text(&copy), expected);
    assert_eq!(
        fs::read_to_string(copy.join("ring_drop.pvd")).unwrap(),
        fs::read_to_string(reference.join("ring_drop.pvd")).unwrap()
    );
}

/// The run's monitor is in the checkpoint: a resumed run measures the energy created from the
/// run's start, so it stops where the uninterrupted run stops, with the same history and
/// warnings. (It measured from the checkpoint before: the audit's explicit-projection stack
/// stopped at step 89, resumed from step 80 it ran to step 170.) The ring drop under explicit
/// projection at twice its step creates energy: a warning at step 63, exit 3 at step 105. (With
/// zeta = 1e16, which this test used, the energy came from its 63 cuts pumping the
/// unresolved modes; cut steps keep the scheme's energy now, and that run fails to converge
/// instead.)
#[test]
fn a_resumed_run_stops_where_the_uninterrupted_run_stops() {
    let dir = scratch("monitor");
    let stiff = [
        "--set",
        "contact.method=\"explicit_projection\"",
        "--set",
        "simulation.time_step=2e-3",
        "--checkpoint-every",
        "10",
    ];
    let out = dir.join("out");
    let o = softway().args(run_args(&out, &stiff)).output().unwrap();
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    let s = summary(&out);
    assert_eq!(s["status"], "failed");
    let stopped = s["steps"].as_u64().unwrap() as usize;
    assert!(stopped > 20 && stopped < STEPS, "stopped at step {stopped}");
    let warned: Vec<Value> = s["warnings"].as_array().unwrap().clone();
    assert!(
        warned
            .iter()
            .any(|w| w.as_str().unwrap().contains("created energy")),
        "{warned:?}"
    );
    // From the last checkpoint before the stop and from one well before it.
    let last = stopped - 1 - (stopped - 1) % 10;
    for from in [last, last - 20] {
        let again = dir.join(format!("from_{from}"));
        let o = resume(
            &out.join(format!("checkpoints/step_{from}.ckpt")),
            &["--out", again.to_str().unwrap()],
        );
        assert_eq!(o.status.code(), Some(3), "from step {from}: {}", stderr(&o));
        assert_eq!(history_text(&again), history_text(&out), "from step {from}");
        let r = summary(&again);
        assert_eq!(r["steps"], s["steps"], "from step {from}");
        assert_eq!(r["error"], s["error"], "from step {from}");
        assert_eq!(
            r["warnings"].as_array().unwrap(),
            &warned,
            "from step {from}"
        );
    }
}

fn copy_dir(from: &Path, to: &Path) {
    fs::create_dir_all(to).unwrap();
    for entry in fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            fs::copy(entry.path(), target).unwrap();
        }
    }
}

#[test]
fn sigint_finishes_the_step_writes_the_outputs_and_resumes_bit_for_bit() {
    let expected = history_text(reference());
    let dir = scratch("sigint");
    let out = dir.join("out");
    let args = run_args(&out, &["--checkpoint-every", "10", "--rerun", "run.rrd"]);
    let child = spawn_until(&args, &dir, &out.join("checkpoints/step_20.ckpt"));
    signal(&child, "INT");
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    assert_complete_or_absent(&out);

    let s = summary(&out);
    assert_eq!(s["status"], "interrupted");
    let steps = s["steps"].as_u64().unwrap() as usize;
    assert!((20..STEPS).contains(&steps), "stopped at step {steps}");
    // A checkpoint of the step it stopped at, and every row up to it.
    assert_eq!(
        s["last_checkpoint"],
        format!("checkpoints/step_{steps}.ckpt").as_str()
    );
    let written = history_text(&out);
    assert_eq!(written.lines().count(), steps + 2);
    assert!(expected.starts_with(&written));
    // The recording is complete.
    assert!(!dir.join("run.rrd.tmp").exists());
    verify_recording(&dir.join("run.rrd"));

    let o = resume(&out.join(format!("checkpoints/step_{steps}.ckpt")), &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(history_text(&out), expected);
    assert_eq!(summary(&out)["status"], "completed");
}

#[test]
fn sigterm_is_an_interrupt_too() {
    let dir = scratch("sigterm");
    let out = dir.join("out");
    let args = run_args(&out, &["--checkpoint-every", "10"]);
    let child = spawn_until(&args, &dir, &out.join("checkpoints/step_10.ckpt"));
    signal(&child, "TERM");
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(143), "{}", stderr(&o));
    assert_eq!(summary(&out)["status"], "interrupted");
    assert_complete_or_absent(&out);
}

/// A second SIGINT exits at once (status 130) instead of finishing the step and writing the
/// summary: whether the first one had time to write it depends on the race, but every file the
/// run leaves is complete or absent, and it ends within seconds.
#[test]
fn a_second_sigint_exits_at_once() {
    let dir = scratch("sigint_twice");
    let out = dir.join("out");
    let args = run_args(&out, &["--checkpoint-every", "10", "--rerun", "run.rrd"]);
    let child = spawn_until(&args, &dir, &out.join("checkpoints/step_20.ckpt"));
    let sent = Instant::now();
    signal(&child, "INT");
    signal(&child, "INT");
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    assert!(
        sent.elapsed() < Duration::from_secs(10),
        "{:?}",
        sent.elapsed()
    );
    assert_complete_or_absent(&out);
    if out.join("summary.json").exists() {
        assert_eq!(summary(&out)["status"], "interrupted");
    }
}

#[test]
fn sigkill_leaves_every_file_complete_or_absent_and_the_last_checkpoint_resumes() {
    let expected = history_text(reference());
    let dir = scratch("sigkill");
    let out = dir.join("out");
    let args = run_args(&out, &["--checkpoint-every", "10", "--rerun", "run.rrd"]);
    // After the landing: the contact memory is in the state.
    let mut child = spawn_until(&args, &dir, &out.join("checkpoints/step_180.ckpt"));
    child.kill().unwrap();
    child.wait().unwrap();
    let checkpoints = assert_complete_or_absent(&out);
    assert!(
        !out.join("summary.json").exists(),
        "killed before the end: no summary"
    );
    // The recording is written beside its name until it is complete.
    assert!(!dir.join("run.rrd").exists());
    let written = history_text(&out);
    assert!(expected.starts_with(&written));

    let (last, ckpt) = checkpoints.last().unwrap();
    assert!((180..STEPS).contains(last), "killed at {last}");
    let o = resume(ckpt, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(history_text(&out), expected);
    assert_complete_or_absent(&out);
}

#[test]
fn damaged_checkpoints_are_refused_with_exit_2() {
    let good = fs::read(reference().join("checkpoints/step_25.ckpt")).unwrap();
    let dir = tempdir();
    let files = dir.path().join("files");
    fs::create_dir(&files).unwrap();
    let work = dir.path().join("work");
    fs::create_dir(&work).unwrap();
    let newline = good.iter().position(|&b| b == b'\n').unwrap();

    let mut cases: Vec<(&str, Vec<u8>, String)> = Vec::new();
    cases.push((
        "truncated",
        good[..good.len() - 1000].to_vec(),
        format!(
            "truncated: {} of its {} bytes are there; resume from an earlier checkpoint",
            good.len() - newline - 1 - 1000,
            good.len() - newline - 1
        ),
    ));
    let mut flipped = good.clone();
    let middle = newline + (good.len() - newline) / 2;
    flipped[middle] ^= 0x01;
    cases.push((
        "flipped",
        flipped,
        "corrupted: its checksum is crc32 ".into(),
    ));
    let header = std::str::from_utf8(&good[..newline]).unwrap();
    let mut future = header.replace("format=1", "format=99").into_bytes();
    future.extend_from_slice(&good[newline..]);
    cases.push((
        "future",
        future,
        "checkpoint format 99 (written by softway 0.1.0), this softway (0.1.0) reads format 1: \
         resume it with the softway that wrote it"
            .into(),
    ));
    cases.push((
        "scene",
        fs::read(ring_drop()).unwrap(),
        "not a softway checkpoint (it does not start with `softway-checkpoint`)".into(),
    ));
    cases.push(("empty", Vec::new(), "not a softway checkpoint".into()));
    for (name, bytes, message) in cases {
        let file = files.join(format!("{name}.ckpt"));
        fs::write(&file, bytes).unwrap();
        let err = assert_invalid(&work, &["resume", file.to_str().unwrap(), "--out", "out"]);
        assert!(err.contains(&file.display().to_string()), "{err}");
        assert!(
            err.contains(&message),
            "{name}: {message:?} expected:\n{err}"
        );
    }
    let err = assert_invalid(&work, &["resume", "no/such.ckpt"]);
    assert!(err.contains("no/such.ckpt: cannot read it: "), "{err}");
    let err = assert_invalid(
        &work,
        &[
            "resume",
            reference()
                .join("checkpoints/step_25.ckpt")
                .to_str()
                .unwrap(),
            "--out",
            "out",
            "--checkpoint-every",
            "0",
        ],
    );
    assert!(err.contains("found 0"), "{err}");
}
