//! The `softway` command line: `run`, `check`, `resume` (see scene-format.md). SIGINT and
//! SIGTERM end a run cleanly (outputs, a checkpoint, the recording); a second one at once.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use softway::contact::{ContactMethod, FrictionLaw};
use softway::dim::Kinematics;
use softway::dim::{Dim, SpatialDim};
use softway::io::checkpoint::{self, AnyCheckpoint, Checkpoint};
use softway::io::output::{self, Progress, RunOptions};
use softway::io::scene::plain;
use softway::io::scene::{self, LoadedScene};
use softway::simulation::BodyId;
use softway::Error;

#[cfg(unix)]
use signal_hook::{
    consts::{SIGINT, SIGTERM},
    iterator::Signals,
};

#[derive(Parser)]
#[command(
    name = "softway",
    version,
    about = "Deformable bodies in dynamic contact (Bajer & Bohatier's soft way)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene and write history.csv, summary.json and VTK files.
    Run {
        /// The scene file (TOML).
        scene: PathBuf,
        /// Output folder [default: out/<scene file stem>].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Record every solver iteration to this Rerun file.
        #[arg(long, value_name = "FILE.rrd")]
        rerun: Option<PathBuf>,
        /// Override a scene key: --set simulation.time_step=2e-4 (a TOML literal).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Print nothing but errors.
        #[arg(long)]
        quiet: bool,
        /// Also write <out>/checkpoints/step_<N>.ckpt every N steps.
        #[arg(long, value_name = "N")]
        checkpoint_every: Option<usize>,
    },
    /// Validate a scene and its meshes, print a summary, run nothing.
    Check {
        /// The scene file (TOML).
        scene: PathBuf,
        /// Override a scene key (as for `run`).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
    },
    /// Continue a run from a checkpoint; its history.csv ends as the uninterrupted run's.
    Resume {
        /// The checkpoint file (<out>/checkpoints/step_<N>.ckpt).
        checkpoint: PathBuf,
        /// Output folder [default: the run's, the folder that holds checkpoints/].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Record the rest of the run to this Rerun file.
        #[arg(long, value_name = "FILE.rrd")]
        rerun: Option<PathBuf>,
        /// Print nothing but errors.
        #[arg(long)]
        quiet: bool,
        /// Write checkpoints every N steps [default: as the run that wrote the checkpoint].
        #[arg(long, value_name = "N")]
        checkpoint_every: Option<usize>,
    },
}

const INVALID: u8 = 2;
const FAILED: u8 = 3;
/// 128 + SIGPIPE: standard output was closed by its reader (`softway check SCENE | head -1`),
/// the status of a program that SIGPIPE ends.
const BROKEN_PIPE: i32 = 141;

/// `println!` that does not panic when standard output is a closed pipe: the program ends
/// quietly with [`BROKEN_PIPE`] (every line of `check` is written once the scene is valid, so
/// nothing is lost that the reader wanted). Any other write error: a message, status 3.
macro_rules! outln {
    ($($arg:tt)*) => { write_out(format_args!($($arg)*)) };
}

/// `eprintln!` that does not panic when standard error is closed: the message is lost, the exit
/// status stays the one the contract gives.
macro_rules! errln {
    ($($arg:tt)*) => { write_err(format_args!($($arg)*)) };
}

fn write_out(line: std::fmt::Arguments) {
    let mut out = std::io::stdout().lock();
    // Line buffered: the line is written (or refused) here, not at exit.
    if let Err(e) = out.write_fmt(line).and_then(|()| out.write_all(b"\n")) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(BROKEN_PIPE);
        }
        errln!("error: cannot write to standard output: {e}");
        std::process::exit(FAILED.into());
    }
}

fn write_err(line: std::fmt::Arguments) {
    let mut err = std::io::stderr().lock();
    let _ = err.write_fmt(line).and_then(|()| err.write_all(b"\n"));
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Run {
            scene,
            out,
            rerun,
            set,
            quiet,
            checkpoint_every,
        } => {
            if let Some(code) = refused_flags(rerun.as_deref(), checkpoint_every) {
                return code;
            }
            let loaded = match scene::load(&scene, &set) {
                Ok(l) => l,
                Err(e) => return invalid(&e),
            };
            let stem = scene
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("scene")
                .to_string();
            let out = out.unwrap_or_else(|| Path::new("out").join(&stem));
            if let Some(code) = not_a_folder(&out) {
                return code;
            }
            let job = Job {
                input: scene.clone(),
                out,
                quiet,
                rerun,
                checkpoint_every: checkpoint_every.unwrap_or(0),
            };
            match loaded.dimension() {
                Ok(2) => run::<2>(&loaded, &stem, &job),
                Ok(_) => run::<3>(&loaded, &stem, &job),
                Err(e) => invalid(&e),
            }
        }
        Command::Check { scene, set } => {
            let loaded = match scene::load(&scene, &set) {
                Ok(l) => l,
                Err(e) => return invalid(&e),
            };
            match loaded.dimension() {
                Ok(2) => check::<2>(&loaded),
                Ok(_) => check::<3>(&loaded),
                Err(e) => invalid(&e),
            }
        }
        Command::Resume {
            checkpoint: file,
            out,
            rerun,
            quiet,
            checkpoint_every,
        } => {
            if let Some(code) = refused_flags(rerun.as_deref(), checkpoint_every) {
                return code;
            }
            let ckpt = match checkpoint::read(&file) {
                Ok(c) => c,
                Err(e) => return invalid(&e),
            };
            let out = out.unwrap_or_else(|| checkpoint::default_out(&file));
            if let Some(code) = not_a_folder(&out) {
                return code;
            }
            let mut job = Job {
                input: file,
                out,
                quiet,
                rerun,
                checkpoint_every: 0,
            };
            match ckpt {
                AnyCheckpoint::Two(c) => {
                    job.checkpoint_every = checkpoint_every.unwrap_or(c.run.checkpoint_every);
                    resume::<2>(*c, &job)
                }
                AnyCheckpoint::Three(c) => {
                    job.checkpoint_every = checkpoint_every.unwrap_or(c.run.checkpoint_every);
                    resume::<3>(*c, &job)
                }
            }
        }
    }
}

fn zero_checkpoints() -> Error {
    Error::InvalidParameter {
        name: "--checkpoint-every".into(),
        found: "0".into(),
        expected: "a number of steps, at least 1".into(),
    }
}

fn invalid(e: &Error) -> ExitCode {
    errln!("error: {e}");
    ExitCode::from(INVALID)
}

/// Like [`invalid`], for an error found while building or starting a scene: the message names
/// the scene file even when the error comes from the library (a mesh, the simulation setup).
fn invalid_in(scene: &Path, e: &Error) -> ExitCode {
    let message = e.to_string();
    let file = scene.display().to_string();
    if matches!(e, Error::Scene { .. } | Error::SceneSyntax { .. }) || message.contains(&file) {
        errln!("error: {message}");
    } else {
        errln!("error: {file}: {message}");
    }
    ExitCode::from(INVALID)
}

fn check<const D: usize>(loaded: &LoadedScene) -> ExitCode
where
    Dim<D>: SpatialDim<D>,
{
    let scene = match loaded.build::<D>() {
        Ok(s) => s,
        Err(e) => return invalid_in(&loaded.path, &e),
    };
    let sim = match scene.simulation() {
        Ok(s) => s,
        Err(e) => return invalid_in(&loaded.path, &e),
    };
    let overlaps = match sim.check_overlaps() {
        Ok(o) => o,
        Err(e) => return invalid_in(&loaded.path, &e),
    };
    let s = &scene.settings;
    let kinematics = match s.kinematics {
        Kinematics::PlaneStrain => "plane_strain",
        Kinematics::PlaneStress => "plane_stress",
        Kinematics::Axisymmetric => "axisymmetric",
        Kinematics::Solid => "solid",
    };
    // Plane kinematics: per metre of thickness; axisymmetric: the whole revolution.
    let per_thickness = matches!(
        s.kinematics,
        Kinematics::PlaneStrain | Kinematics::PlaneStress
    );
    outln!("{}: valid", loaded.path.display());
    outln!(
        "  {D}D {kinematics}, h = {} s, end_time = {} s ({} steps), alpha = {}, beta = {}",
        plain(s.time_step),
        plain(scene.end_time),
        // As `run` counts them (at most MAX_STEPS: checked at load).
        plain(scene::step_count(scene.end_time, s.time_step)),
        plain(s.scheme.alpha),
        plain(s.scheme.beta)
    );
    let (unknowns, triplets) = scene::scene_size(&scene.bodies);
    for (b, body) in scene.bodies.iter().enumerate() {
        outln!(
            "  body `{}`: {} nodes, {} cells, mass {:.6e} {}, {} constraint(s)",
            body.name,
            body.mesh.node_count(),
            body.mesh.cell_count(),
            sim.body_mass(BodyId::initial(b)).unwrap_or(f64::NAN),
            if per_thickness {
                "kg/m (per metre of thickness)"
            } else {
                "kg"
            },
            body.constraints.len()
        );
        if !body.damping.is_none() {
            outln!(
                "    Rayleigh damping: mass {:e} 1/s, stiffness {:e} s",
                body.damping.mass,
                body.damping.stiffness
            );
        }
    }
    outln!(
        "  estimate: {unknowns:.0} unknowns, at least {:.1e} bytes of matrices (this machine: \
         {:.1e} bytes)",
        scene::memory_lower_bound(unknowns, triplets, D),
        scene::memory_limit()
    );
    for o in &scene.obstacles {
        outln!("  obstacle `{}`", o.name);
    }
    if sim.detector().is_some() {
        let method = scene.contact.method;
        let penalty = if matches!(
            method,
            ContactMethod::SoftWay | ContactMethod::AugmentedLagrangian
        ) {
            format!(", penalty {:e} Pa/m", scene.contact.penalty)
        } else {
            String::new()
        };
        outln!(
            "  contact: {}{penalty}, friction {}",
            method.name(),
            friction_text(&scene.contact.friction)
        );
    }
    for overlap in overlaps {
        outln!("  warning: {overlap}");
    }
    for p in &scene.probes {
        outln!(
            "  probe `{}`: body {}, node {}",
            p.name,
            scene.bodies[p.body].name,
            p.node
        );
    }
    for w in sim.warnings() {
        outln!("  warning: {w}");
    }
    ExitCode::SUCCESS
}

/// A friction law as the scene file names it, with its parameters.
fn friction_text(law: &FrictionLaw) -> String {
    match law {
        FrictionLaw::Frictionless => "frictionless".into(),
        FrictionLaw::Coulomb {
            coefficient,
            regularization,
        } => format!(
            "coulomb (coefficient {}, regularization {:e} m/s)",
            plain(*coefficient),
            regularization
        ),
        FrictionLaw::Tresca {
            limit,
            regularization,
        } => format!(
            "tresca (limit {:e} Pa, regularization {:e} m/s)",
            limit, regularization
        ),
        FrictionLaw::Viscoplastic {
            coefficient,
            exponent,
            regularization,
        } => format!(
            "viscoplastic (coefficient {}, exponent {}, regularization {:e} m/s)",
            plain(*coefficient),
            plain(*exponent),
            regularization
        ),
    }
}

/// Flags this build or the contract refuses: `--rerun` without the `rerun` feature,
/// `--checkpoint-every 0`.
fn refused_flags(rerun: Option<&Path>, checkpoint_every: Option<usize>) -> Option<ExitCode> {
    #[cfg(not(feature = "rerun"))]
    if rerun.is_some() {
        return Some(invalid(&Error::NotAvailable {
            feature: "--rerun".into(),
            detail: "this softway was built without the `rerun` cargo feature; rebuild with \
                     `--features rerun` or run without it"
                .into(),
        }));
    }
    #[cfg(feature = "rerun")]
    let _ = rerun;
    (checkpoint_every == Some(0)).then(|| invalid(&zero_checkpoints()))
}

/// Up front: a file where the output folder should be is invalid input, not a failed run.
fn not_a_folder(out: &Path) -> Option<ExitCode> {
    (out.exists() && !out.is_dir()).then(|| {
        invalid(&Error::SceneSyntax {
            file: out.to_path_buf(),
            message: "--out names a file; expected a folder (created if missing)".into(),
        })
    })
}

/// What `run` and `resume` share: where the outputs go and how.
struct Job {
    /// The scene or checkpoint file (named by messages about it).
    input: PathBuf,
    out: PathBuf,
    quiet: bool,
    rerun: Option<PathBuf>,
    /// 0: no checkpoints.
    checkpoint_every: usize,
}

fn run<const D: usize>(loaded: &LoadedScene, stem: &str, job: &Job) -> ExitCode
where
    Dim<D>: SpatialDim<D>,
{
    let scene = match loaded.build::<D>() {
        Ok(s) => s,
        Err(e) => return invalid_in(&loaded.path, &e),
    };
    execute(&scene, job, |options, progress, recorder| {
        output::run_with::<D>(&scene, &job.out, stem, options, progress, recorder)
    })
}

fn resume<const D: usize>(checkpoint: Checkpoint<D>, job: &Job) -> ExitCode
where
    Dim<D>: SpatialDim<D>,
{
    let scene = checkpoint.scene();
    execute(&scene, job, move |options, progress, recorder| {
        output::resume::<D>(checkpoint, &job.out, options, progress, recorder)
    })
}

/// SIGINT and SIGTERM: the first sets `stop` (the run finishes its step, writes its outputs and
/// a checkpoint, and exits with 128 + the signal's number); a second one exits at once. A
/// second one within 100 ms is the same interrupt delivered twice (`timeout` signals the
/// process and then its group) and is ignored.
struct Interrupts {
    stop: Arc<AtomicBool>,
    signal: Arc<AtomicUsize>,
}

impl Interrupts {
    fn install() -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let signal = Arc::new(AtomicUsize::new(0));
        #[cfg(unix)]
        match Signals::new([SIGINT, SIGTERM]) {
            Ok(mut signals) => {
                let (stop, signal) = (Arc::clone(&stop), Arc::clone(&signal));
                std::thread::spawn(move || {
                    let mut first: Option<std::time::Instant> = None;
                    for sig in signals.forever() {
                        match first {
                            None => {
                                first = Some(std::time::Instant::now());
                                signal.store(sig as usize, Ordering::SeqCst);
                                stop.store(true, Ordering::SeqCst);
                            }
                            Some(t) if t.elapsed() >= std::time::Duration::from_millis(100) => {
                                std::process::exit(128 + sig)
                            }
                            Some(_) => {}
                        }
                    }
                });
            }
            Err(e) => {
                errln!("warning: cannot handle SIGINT and SIGTERM ({e}): they end the run at once")
            }
        }
        Interrupts { stop, signal }
    }

    /// The exit status of an interrupted run: 128 + the signal's number (130 for SIGINT).
    fn status(&self) -> u8 {
        match self.signal.load(Ordering::SeqCst) {
            0 => 130,
            sig => (128 + sig).min(255) as u8,
        }
    }
}

fn execute<const D: usize>(
    scene: &softway::io::scene::Scene<D>,
    job: &Job,
    start: impl FnOnce(
        RunOptions,
        &mut dyn FnMut(Progress),
        &mut dyn softway::recording::Recorder<D>,
    ) -> Result<output::Summary, Box<output::RunFailure>>,
) -> ExitCode
where
    Dim<D>: SpatialDim<D>,
{
    let out = job.out.as_path();
    // The recording is written beside its name and renamed once complete.
    let recording = job.rerun.as_deref().map(|f| (tmp_path(f), f));
    let mut recorder = match CliRecorder::new(scene, recording.as_ref().map(|r| r.0.as_path())) {
        Ok(r) => r,
        Err(e) => return invalid(&e),
    };
    let interrupts = Interrupts::install();
    // scene-format.md: nothing but errors with --quiet or when stderr is not a terminal.
    let show = !job.quiet && std::io::stderr().is_terminal();
    let bar = if show {
        let bar = ProgressBar::new(1000);
        bar.set_style(
            ProgressStyle::with_template("{bar:40} t = {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        Some(bar)
    } else {
        None
    };
    let started = std::time::Instant::now();
    let mut first_step = None;
    let mut on_progress = |p: Progress| {
        // A resumed run starts at its checkpoint's step.
        let first = *first_step.get_or_insert(p.steps.saturating_sub(1));
        if let Some(bar) = &bar {
            let frac = if p.end_time > 0.0 {
                p.time / p.end_time
            } else {
                1.0
            };
            bar.set_position((frac * 1000.0) as u64);
            let rate = (p.steps - first) as f64 / started.elapsed().as_secs_f64().max(1e-9);
            bar.set_message(format!(
                "{:.4e} / {:.4e} s, {:.1} steps/s, {} iterations in the last step",
                p.time, p.end_time, rate, p.iterations
            ));
        }
    };
    let options = RunOptions {
        checkpoint_every: job.checkpoint_every,
        stop: Some(&*interrupts.stop),
    };
    let result = start(options, &mut on_progress, recorder.as_dyn());
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    // Completes the .rrd file (whatever the outcome of the run: a failed run is worth replaying).
    let recorded = recorder.finish().and_then(|()| match &recording {
        Some((tmp, file)) => std::fs::rename(tmp, file).map_err(|source| Error::Output {
            file: file.to_path_buf(),
            source,
        }),
        None => Ok(()),
    });
    let warnings = match &result {
        Ok(summary) => &summary.warnings,
        Err(failure) => &failure.summary.warnings,
    };
    if show {
        for w in warnings {
            errln!("warning: {w} (also in summary.json)");
        }
    }
    if let Err(e) = &recorded {
        errln!("error: {e}");
    }
    match result {
        Ok(_) if recorded.is_err() => ExitCode::from(FAILED),
        Ok(summary) if summary.status == "interrupted" => {
            if show {
                let resume = match &summary.last_checkpoint {
                    Some(c) => format!("resume with `softway resume {}`", out.join(c).display()),
                    None => "run with --checkpoint-every N to be able to resume".into(),
                };
                errln!(
                    "interrupted at step {} (t = {:.6e} s); outputs in {}; {resume}",
                    summary.steps,
                    summary.final_time,
                    out.display()
                );
            }
            ExitCode::from(interrupts.status())
        }
        Ok(summary) => {
            if show {
                errln!(
                    "done: {} steps to t = {} s, {} iterations, energy drift {:.3e}, {:.2} s; outputs in {}",
                    summary.steps,
                    summary.final_time,
                    summary.total_iterations,
                    summary.energy_drift,
                    summary.wall_seconds,
                    out.display()
                );
            }
            ExitCode::SUCCESS
        }
        Err(failure) => {
            let code = match failure.error {
                Error::NotConverged { .. }
                | Error::Unstable { .. }
                | Error::EnergyCreated { .. }
                | Error::ContactCycling { .. }
                | Error::FellThrough { .. }
                | Error::Tunnelled { .. }
                | Error::InvertedCell { .. }
                | Error::TurnedInsideOut { .. }
                | Error::Factorization { .. }
                | Error::Output { .. } => FAILED,
                _ => {
                    // Invalid input: nothing is run, so nothing stays written.
                    if let Some((tmp, _)) = &recording {
                        let _ = std::fs::remove_file(tmp);
                    }
                    return invalid_in(&job.input, &failure.error);
                }
            };
            errln!("error: {}", failure.error);
            if code == FAILED {
                errln!(
                    "history up to step {} written to {}",
                    failure.summary.steps,
                    out.display()
                );
            }
            ExitCode::from(code)
        }
    }
}

/// `<path>.tmp`: where a file is written before it is renamed to `path`.
fn tmp_path(path: &Path) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(".tmp");
    PathBuf::from(s)
}

/// The recorder of `run`: a [`RerunRecorder`](softway::recording::RerunRecorder) writing the
/// `--rerun` file when given, else nothing.
struct CliRecorder<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    null: softway::recording::NullRecorder,
    #[cfg(feature = "rerun")]
    rerun: Option<softway::recording::RerunRecorder<D>>,
}

impl<const D: usize> CliRecorder<D>
where
    Dim<D>: SpatialDim<D>,
{
    #[cfg(feature = "rerun")]
    fn new(scene: &softway::io::scene::Scene<D>, path: Option<&Path>) -> Result<Self, Error> {
        use softway::recording::RerunRecorder;
        let rerun = match path {
            None => None,
            Some(path) => {
                let mut r = RerunRecorder::<D>::to_file(path)?.with_obstacles(&scene.obstacles);
                for p in &scene.probes {
                    r = r.with_probe(p.name.clone(), BodyId::initial(p.body), p.node);
                }
                Some(r)
            }
        };
        Ok(CliRecorder {
            null: softway::recording::NullRecorder,
            rerun,
        })
    }

    #[cfg(not(feature = "rerun"))]
    fn new(_scene: &softway::io::scene::Scene<D>, _path: Option<&Path>) -> Result<Self, Error> {
        Ok(CliRecorder {
            null: softway::recording::NullRecorder,
        })
    }

    fn as_dyn(&mut self) -> &mut dyn softway::recording::Recorder<D> {
        #[cfg(feature = "rerun")]
        if let Some(r) = &mut self.rerun {
            return r;
        }
        &mut self.null
    }

    /// Flushes and completes the recording (the .rrd footer).
    fn finish(self) -> Result<(), Error> {
        #[cfg(feature = "rerun")]
        if let Some(r) = self.rerun {
            return r.finish();
        }
        Ok(())
    }
}
