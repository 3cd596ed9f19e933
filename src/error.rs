//! The crate's one error type.

use std::path::PathBuf;

/// Everything that can go wrong in softway. Each variant carries enough context to act on.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A scene file (or a `--set` override) holds a value that cannot be used.
    #[error("{file}: {location}`{key}`: found {found}, expected {expected}")]
    Scene {
        /// The scene file.
        file: PathBuf,
        /// `line N: ` when known, else empty.
        location: String,
        /// Dotted key path, e.g. `bodies.0.material.youngs_modulus`.
        key: String,
        /// What was found.
        found: String,
        /// What is expected.
        expected: String,
    },
    /// The scene file is not valid TOML or does not match the schema.
    #[error("{file}: {message}")]
    SceneSyntax {
        /// The scene file.
        file: PathBuf,
        /// The parser's message, with line and column.
        message: String,
    },
    /// A parameter passed through the library API is out of range.
    #[error("invalid parameter `{name}`: found {found}, expected {expected}")]
    InvalidParameter {
        /// Parameter name.
        name: String,
        /// What was found.
        found: String,
        /// What is expected.
        expected: String,
    },
    /// A mesh file could not be read.
    #[error("mesh file {file}: {message}")]
    MeshFile {
        /// The mesh file.
        file: PathBuf,
        /// What went wrong, with the line or byte offset where known.
        message: String,
    },
    /// A mesh is not usable (wrong element type, empty, bad connectivity).
    #[error("mesh of body `{body}`: {message}")]
    Mesh {
        /// Body name.
        body: String,
        /// What is wrong.
        message: String,
    },
    /// An element has a non-positive Jacobian (inverted or degenerate).
    #[error(
        "body `{body}`: cell {cell} is {kind} (Jacobian determinant {jacobian:.3e}); \
         expected a positive determinant (check the node ordering and the geometry)"
    )]
    InvertedElement {
        /// Body name.
        body: String,
        /// Cell index in the body's mesh.
        cell: usize,
        /// "inverted" or "degenerate".
        kind: &'static str,
        /// The smallest Jacobian determinant found.
        jacobian: f64,
    },
    /// A node selection (constraint region, probe) selects no node.
    #[error("{what} selects no node of body `{body}`; {hint}")]
    EmptySelection {
        /// What selected nothing, e.g. `constraint 0`.
        what: String,
        /// Body name.
        body: String,
        /// What to change.
        hint: String,
    },
    /// A feature the scene asks for is not implemented in this version.
    #[error("{feature} is not available in this version of softway: {detail}")]
    NotAvailable {
        /// The feature.
        feature: String,
        /// What works instead.
        detail: String,
    },
    /// Newton (with the contact iterations) did not converge, even after cutting the step.
    #[error(
        "no convergence at step {step} (t = {time:.6e} s) after {iterations} iterations: \
         relative residual {residual:.3e} (tolerance {tolerance:.1e}); {site}; {cause}"
    )]
    NotConverged {
        /// Step number (1-based).
        step: usize,
        /// Time at the start of the step (s).
        time: f64,
        /// Iterations spent.
        iterations: usize,
        /// Last relative residual.
        residual: f64,
        /// The tolerance asked for.
        tolerance: f64,
        /// Where it is stuck: the node with the largest residual and the contact there, or
        /// the points a cycling contact set kept switching; and the step's contact pairs.
        site: String,
        /// Why it stopped and what to try: iterations spent, a contact set that cycles, or
        /// contact passes that did not settle.
        cause: String,
    },
    /// The energy grew without bound or a value became non-finite.
    #[error("numerical instability at step {step} (t = {time:.6e} s): {detail}; {advice}")]
    Unstable {
        /// Step number (1-based).
        step: usize,
        /// Time at the end of the failed step (s).
        time: f64,
        /// The energy growth or the non-finite quantity.
        detail: String,
        /// What to change: the scheme's alpha and beta when they are outside the
        /// unconditionally stable window, otherwise the step, the penalty or the scene's
        /// magnitudes.
        advice: String,
    },
    /// Implicit projection's contact set cycled and the points it held closed to end the step
    /// pull with more than [`HELD_TENSION_FAILURE`](crate::simulation::HELD_TENSION_FAILURE)
    /// of what the step's other contact points push with (or, if more, the run's contact
    /// points in one step so far): the contact answer is mostly adhesion that is not there.
    #[error(
        "contact set cycling at step {step} (t = {time:.6e} s): {held} point(s) held closed \
         until the step's end pull with {tension:.3e} N against {compression:.3e} N of \
         compression at the other contact points (at most {run_compression:.3e} N in a step of \
         the run so far; the run stops above {limit}% of the larger); use a smaller \
         time_step, or the soft way (contact.method = \"soft_way\"), whose contact set does \
         not cycle"
    )]
    ContactCycling {
        /// Step number (1-based).
        step: usize,
        /// Time at the end of the step (s).
        time: f64,
        /// Points held until the step's end.
        held: usize,
        /// Their tension (N).
        tension: f64,
        /// The other points' compressive normal forces (N).
        compression: f64,
        /// The most the run's contact points pressed with in one step before (N).
        run_compression: f64,
        /// The limit, in percent of the compression.
        limit: f64,
    },
    /// The run created energy: kinetic + internal + contact energy plus the dissipated energy
    /// exceeded the input (E(0) + |external work|) by more than
    /// [`ENERGY_FAILURE`](crate::simulation::ENERGY_FAILURE) of it.
    #[error(
        "energy created at step {step} (t = {time:.6e} s): {measure} plus the dissipated \
         energy is {energy:.3e} J, \
         {percent:.1}% above the input E(0) + |external work| = {input:.3e} J (the run stops \
         above 1000%); {advice}"
    )]
    EnergyCreated {
        /// Step number (1-based).
        step: usize,
        /// Time at the end of the step (s).
        time: f64,
        /// What was measured: the scheme's conserved energy Q, or (outside the stability
        /// window, where Q bounds nothing) the mechanical energy E.
        measure: String,
        /// Q(t) (or E(t)) + max(dissipated, 0) (J).
        energy: f64,
        /// E(0) + |external work| (J).
        input: f64,
        /// The excess, in percent of the input.
        percent: f64,
        /// What to change.
        advice: String,
    },
    /// A body starts inside an obstacle or another body deeper than contact detection
    /// reaches (see [`Simulation::check_overlaps`](crate::simulation::Simulation::check_overlaps)):
    /// invalid input.
    #[error(
        "body `{body}` starts inside {other}: found {nodes} boundary node(s) inside at t = 0, \
         {beyond} of them deeper than contact detection reaches ({reach:.3e} m, a quarter of \
         the mean boundary facet), the deepest {depth:.3e} m, expected none that deep: no \
         contact method would push them out, and the body would fall through or stay stuck; \
         move the bodies apart in the scene{hint}"
    )]
    Overlap {
        /// The body whose nodes are inside.
        body: String,
        /// `body `NAME`` or `obstacle `NAME``.
        other: String,
        /// Its boundary nodes inside.
        nodes: usize,
        /// Those deeper than `reach`.
        beyond: usize,
        /// The deepest (m), distance to the nearest surface of the other.
        depth: f64,
        /// The reach of contact detection (m).
        reach: f64,
        /// Empty, or the orientation of polyline and trimesh facets.
        hint: String,
    },
    /// Boundary nodes ended a step inside another body, a polyline or a trimesh deeper than
    /// contact detection reaches, unpaired (see
    /// [`Simulation::fell_through`](crate::simulation::Simulation::fell_through)).
    #[error(
        "fall-through at step {step} (t = {time:.6e} s): {nodes} node(s) of body `{body}` \
         ended the step inside {other}, the deepest {depth:.3e} m, beyond the reach of contact \
         detection ({reach:.3e} m), so nothing pushes them out: {advice}"
    )]
    FellThrough {
        /// Step number (1-based).
        step: usize,
        /// Time at the end of the step (s).
        time: f64,
        /// The body whose nodes are inside.
        body: String,
        /// `body `NAME`` or `obstacle `NAME``.
        other: String,
        /// Its boundary nodes inside beyond reach.
        nodes: usize,
        /// The deepest (m), distance to the nearest surface of the other.
        depth: f64,
        /// The reach of contact detection (m).
        reach: f64,
        /// What happened and what to change (for a polyline or trimesh, also how its facets
        /// set its solid side: the body may have been inside all along).
        advice: String,
    },
    /// Boundary nodes passed through an obstacle within a step and ended outside it on its far
    /// side, unseen by contact detection (see
    /// [`Simulation::tunnelled`](crate::simulation::Simulation::tunnelled)).
    #[error(
        "tunnelling at step {step} (t = {time:.6e} s): {nodes} node(s) of body `{body}` passed \
         through {other} within the step and ended outside it on the far side, where contact \
         detection does not see them (node {node} at {speed:.3e} m/s relative to it: \
         {travel:.3e} m in the step, {inside:.3e} m of it inside); the step is too long for the \
         speed: the body crossed the obstacle in one step; use a smaller time_step (well below \
         the {crossing_time:.3e} s the crossing took) or a thicker obstacle"
    )]
    Tunnelled {
        /// Step number (1-based).
        step: usize,
        /// Time at the end of the step (s).
        time: f64,
        /// The body whose nodes passed through.
        body: String,
        /// The fastest of them (index in its body's mesh).
        node: usize,
        /// `obstacle `NAME``.
        other: String,
        /// Nodes that passed through.
        nodes: usize,
        /// The fastest node's speed relative to the obstacle (m/s).
        speed: f64,
        /// Its path relative to the obstacle over the step (m).
        travel: f64,
        /// The part of it inside the obstacle (m).
        inside: f64,
        /// The time the crossing took (s).
        crossing_time: f64,
    },
    /// A cell of an updated-Lagrangian body turned inside out (at t_alpha or at the end of
    /// the step, at a quadrature point) in every Newton iterate tried (after halving the
    /// increment) or after the end-of-step projection, at the step's finest cut.
    #[error(
        "a cell turned inside out at step {step} (t = {time:.6e} s){}: its Jacobian at t_alpha \
         or at the step's end is not positive {}, down to the step's finest cut; use a smaller \
         time_step, a finer mesh where the body deforms most, or a softer contact penalty",
        inversion_place(place),
        inversion_tries(*halvings)
    )]
    InvertedCell {
        /// Step number (1-based).
        step: usize,
        /// Time at the end of the failed step (s).
        time: f64,
        /// Halvings of the increment tried.
        halvings: usize,
        /// The body and the centre of the cell (its nodes' mean at the start of the step, m),
        /// when Newton's iterate found it (not for a fold by the end-of-step correction).
        place: Option<(String, Vec<f64>)>,
    },
    /// A cell of a body ended a step turned inside out (see
    /// [`Simulation::inverted_cell`](crate::simulation::Simulation::inverted_cell)): its
    /// nodes passed through one another.
    #[error(
        "a cell turned inside out at step {step} (t = {time:.6e} s): cell {cell} of body \
         `{body}` near ({}) m has a negative Jacobian at the end of the step, its nodes passed \
         through one another; strains of that order are beyond a small-strain law, which does \
         not resist them, and contact holds only boundary nodes: use a smaller time_step, a \
         slower impact or load, or a finer mesh where the body deforms most",
        centre.iter().map(|c| format!("{c:.4e}")).collect::<Vec<_>>().join(", ")
    )]
    TurnedInsideOut {
        /// Step number (1-based).
        step: usize,
        /// Time at the end of the step (s).
        time: f64,
        /// The body.
        body: String,
        /// The cell's index in the body's mesh.
        cell: usize,
        /// The cell's centre at the end of the step (m).
        centre: Vec<f64>,
    },
    /// The sparse factorisation failed (matrix not positive definite).
    #[error("factorisation failed at step {step}: {message}")]
    Factorization {
        /// Step number.
        step: usize,
        /// Solver message.
        message: String,
    },
    /// Writing an output file failed.
    #[error("cannot write {file}: {source}")]
    Output {
        /// The file or folder.
        file: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A handle does not name an existing body, obstacle or node.
    #[error("{0}")]
    InvalidHandle(String),
    /// The Rerun recording could not be created, written or flushed (feature `rerun`).
    #[error("Rerun recording: {0}")]
    Recording(String),
    /// A checkpoint cannot be read: not a checkpoint, another format version, truncated,
    /// corrupted (its checksum differs), or it does not fit the simulation it describes.
    #[error("{file}: {problem}")]
    Checkpoint {
        /// The checkpoint file.
        file: PathBuf,
        /// What is wrong and what to do.
        problem: String,
    },
}

/// `Result` with softway's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Where [`Error::InvertedCell`]'s cell is, when known: ", in body `b` near (x, y) m".
fn inversion_place(place: &Option<(String, Vec<f64>)>) -> String {
    match place {
        Some((body, centre)) => {
            let coordinates: Vec<String> = centre.iter().map(|c| format!("{c:.4e}")).collect();
            format!(", in body `{body}` near ({}) m", coordinates.join(", "))
        }
        None => String::new(),
    }
}

/// What was tried before [`Error::InvertedCell`]: Newton's increment halved, or (none) the
/// first iterate or the end-of-step correction folded the cell.
fn inversion_tries(halvings: usize) -> String {
    if halvings == 0 {
        "at the first Newton iterate or after the end-of-step correction".to_string()
    } else {
        format!("even after halving the Newton increment {halvings} times")
    }
}
