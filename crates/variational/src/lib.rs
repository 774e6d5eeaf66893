//! Hamilton's principle as it is stated: paths with fixed end points.
//!
//! A direct transcription of stationary-action problems on a uniform time
//! grid. The unknowns are the coordinates at the nodes (and one multiplier
//! per constraint row); the action is the midpoint rule, second order; the
//! stationarity conditions with respect to the admissible variations are
//! solved by Newton's method, with the sparse KKT matrix assembled from
//! automatic derivatives of the scene's own functions and factored by
//! faer's sparse LU. One engine solves:
//!
//! * **C**, the vakonomic problem: every coordinate varied with fixed ends,
//!   the constraints imposed on every interval ([`Formulation::Vakonomic`]);
//! * **A with the embedding map** `q_D = φ(q_I, q̇_I, t)` (eq. 14), with the
//!   end conditions of [`MapEnds`] ([`Formulation::Map`]);
//! * **A in the paper's general case** (eq. 27–30): the dependent
//!   coordinates follow the discretised (28) from their initial values, the
//!   independent ones are varied, the dependent end values at `t1` free or
//!   fixed ([`Formulation::General`]);
//!
//! and measures how far a given path (B's motion, say) is from stationary
//! ([`Solver::stationarity`]). [`refine`] repeats a solve on grids halved
//! twice and estimates the order and the error (Richardson). The
//! derivations and findings are in `docs/variational.md`.

mod newton;
mod problem;
mod reduced;
mod refine;

pub use newton::{Options, Report, Solution, Solver, Stationarity};
pub use problem::{
    DEFAULT_MAX_BYTES, DependentEnd, END_TOL, Ends, Formulation, MapEnds, MapForm, PROBE_INTERVALS,
    Problem, node_time, node_velocities,
};
pub use reduced::reduced_gradient;
pub use refine::{DESIGN_ORDER, Refinement, refine, sample};

use thiserror::Error;

/// Errors of a boundary-value solve, each naming where and why.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum Error {
    #[error("{field}: {reason}")]
    Input { field: String, reason: String },
    #[error("{formulation} is not applicable to {scene}: {reason}")]
    NotApplicable {
        formulation: &'static str,
        scene: &'static str,
        reason: String,
    },
    #[error("inconsistent end conditions at t = {t}: {what} has residual {residual:e}")]
    InconsistentEnds { t: f64, what: String, residual: f64 },
    #[error(
        "{nodes} nodes need {unknowns} unknowns and about {:.3e} GB for the Newton matrix and \
         its factors, more than the limit of {:.3e} GB",
        bytes / 1e9,
        limit / 1e9
    )]
    TooLarge {
        nodes: usize,
        unknowns: usize,
        bytes: f64,
        limit: f64,
    },
    #[error(
        "wall-time budget of {seconds} s used up after {iterations} Newton iterations (scaled \
         residual {residual:.2e})"
    )]
    TimeBudget {
        seconds: f64,
        iterations: usize,
        residual: f64,
    },
    #[error("singular Newton matrix at node {node} (t = {t}): {what}")]
    Singular { node: usize, t: f64, what: String },
    #[error("a non-finite stationarity condition at node {node} (t = {t}): {what}")]
    NotFinite { node: usize, t: f64, what: String },
    #[error(
        "Newton's method did not converge in {iterations} iterations; scaled residuals {}; \
         largest at {}",
        history.iter().map(|r| format!("{r:.2e}")).collect::<Vec<_>>().join(", "),
        worst.iter().map(|(k, t, w, r)| format!("node {k} (t = {t:.4}) {w}: {r:.2e}")).collect::<Vec<_>>().join("; ")
    )]
    NotConverged {
        iterations: usize,
        history: Vec<f64>,
        /// (node, time, what, scaled residual), largest first.
        worst: Vec<(usize, f64, String, f64)>,
    },
}
