//! What the runnable examples share: their command line (`--end-time T`, `--rerun FILE`, and
//! a few flags of their own) and the optional Rerun recording.

use std::path::PathBuf;

use softway::dim::{Dim, SpatialDim};
use softway::prelude::*;

/// The error of an example: a message for the terminal.
pub type Failure = Box<dyn std::error::Error>;

/// The command line of an example, read with `std::env::args` (no parser crate).
#[derive(Debug, Default)]
pub struct Args {
    /// `(flag, value)` in the order given, each flag taking one value.
    pairs: Vec<(String, String)>,
}

impl Args {
    /// Reads `--flag value` pairs; `known` lists the flags this example takes (besides
    /// `--rerun`), `usage` is printed for `--help` and for anything unknown.
    pub fn parse(known: &[&str], usage: &str) -> Result<Self, Failure> {
        let mut pairs = Vec::new();
        let mut args = std::env::args().skip(1);
        while let Some(flag) = args.next() {
            if flag == "--help" || flag == "-h" {
                println!("{usage}");
                std::process::exit(0);
            }
            if flag != "--rerun" && !known.contains(&flag.as_str()) {
                return Err(format!("unknown argument `{flag}`\n{usage}").into());
            }
            let value = args
                .next()
                .ok_or_else(|| format!("`{flag}` needs a value\n{usage}"))?;
            pairs.push((flag, value));
        }
        Ok(Args { pairs })
    }

    /// The last value given for `flag`, parsed.
    pub fn get<T: std::str::FromStr>(&self, flag: &str) -> Result<Option<T>, Failure> {
        match self.pairs.iter().rev().find(|(f, _)| f == flag) {
            None => Ok(None),
            Some((_, v)) => v
                .parse()
                .map(Some)
                .map_err(|_| format!("`{flag} {v}`: not a valid value").into()),
        }
    }

    /// Every value given for `flag`, in order (a flag that may repeat, like `--set`).
    pub fn all(&self, flag: &str) -> Vec<String> {
        self.pairs
            .iter()
            .filter(|(f, _)| f == flag)
            .map(|(_, v)| v.clone())
            .collect()
    }

    /// `--rerun FILE`: refused with a clear message when the example was built without the
    /// `rerun` feature.
    pub fn rerun(&self) -> Result<Option<PathBuf>, Failure> {
        let path = self.get::<PathBuf>("--rerun")?;
        if path.is_some() && !cfg!(feature = "rerun") {
            return Err(
                "`--rerun` needs the `rerun` cargo feature (on by default); \
                        rebuild without `--no-default-features`"
                    .into(),
            );
        }
        Ok(path)
    }
}

/// Where the steps are recorded: nowhere, or a Rerun `.rrd` file (feature `rerun`).
pub enum Recording<const D: usize>
where
    Dim<D>: SpatialDim<D>,
{
    /// Nothing recorded.
    Off(NullRecorder),
    /// Every solver iteration recorded to a file.
    #[cfg(feature = "rerun")]
    Rerun(Box<softway::recording::RerunRecorder<D>>),
}

impl<const D: usize> Recording<D>
where
    Dim<D>: SpatialDim<D>,
{
    /// Records into `path` when given (the obstacles drawn as they move), else nothing.
    pub fn new(path: Option<&std::path::Path>, obstacles: &[Obstacle<D>]) -> Result<Self> {
        match path {
            None => Ok(Recording::Off(NullRecorder)),
            #[cfg(feature = "rerun")]
            Some(path) => Ok(Recording::Rerun(Box::new(
                softway::recording::RerunRecorder::to_file(path)?.with_obstacles(obstacles),
            ))),
            #[cfg(not(feature = "rerun"))]
            Some(_) => {
                let _ = obstacles;
                Err(Error::Recording(
                    "built without the `rerun` cargo feature".into(),
                ))
            }
        }
    }

    /// Also logs node `node` of `body` under `probes/<name>` (a no-op without a recording).
    pub fn with_probe(self, name: &str, body: BodyId, node: usize) -> Self {
        match self {
            #[cfg(feature = "rerun")]
            Recording::Rerun(rerun) => {
                Recording::Rerun(Box::new(rerun.with_probe(name, body, node)))
            }
            other => {
                let _ = (name, body, node);
                other
            }
        }
    }

    /// The recorder to hand to `Simulation::step_with`.
    pub fn recorder(&mut self) -> &mut dyn Recorder<D> {
        match self {
            Recording::Off(null) => null,
            #[cfg(feature = "rerun")]
            Recording::Rerun(rerun) => rerun.as_mut(),
        }
    }

    /// Completes the file (its footer); nothing without a recording.
    pub fn finish(self) -> Result<()> {
        match self {
            Recording::Off(_) => Ok(()),
            #[cfg(feature = "rerun")]
            Recording::Rerun(rerun) => rerun.finish(),
        }
    }
}

/// How an example ends: the run's error (exit 2), or its summary printed and checked (exit 0,
/// or 1 with what failed).
pub fn conclude<S>(
    name: &str,
    outcome: Result<S, Failure>,
    print: impl Fn(&S),
    check: impl Fn(&S) -> Result<(), String>,
) -> std::process::ExitCode {
    match outcome {
        Err(e) => {
            eprintln!("{name}: {e}");
            std::process::ExitCode::from(2)
        }
        Ok(s) => {
            print(&s);
            match check(&s) {
                Ok(()) => std::process::ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("{name} FAILED:\n{e}");
                    std::process::ExitCode::FAILURE
                }
            }
        }
    }
}
