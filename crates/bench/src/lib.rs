//! Peers and benchmarks for `nonholo` (bench-only crate, not published).
//!
//! - [`setup`]: the sleigh, its initial data and every formulation at one
//!   fixed generic state, shared by the criterion benchmark
//!   (`benches/rhs.rs`), the `rhs-report` binary and the allocation test.
//! - [`hand`]: the spec's reduced sleigh equations written by hand (B and C
//!   in `(x, y, φ, u, ω[, μ])`) and the body-frame equations of the
//!   realisations in the formulations' own state: the baselines against
//!   which the automatic-differentiation right-hand sides are timed.
//! - [`page`]: `results/peers/index.html`, the peer comparison as a result
//!   page (error against wall time per problem, and the tables).
//! - [`timing`]: a plain median timer (the report binary; criterion does the
//!   benchmark proper).
//! - `peers` (feature `peers`): `diffsol` (BDF, ESDIRK34, TR-BDF2) and
//!   `ode_solvers` (DOP853) driving our right-hand sides, compared with our
//!   Radau IIA and DOP853 on error, time and work (`peers` binary).
//!
//! The peers are optional dependencies behind the `peers` feature, so the
//! workspace build and `cargo test --workspace` never compile them.

pub mod hand;
pub mod page;
pub mod setup;
pub mod timing;

#[cfg(feature = "peers")]
pub mod peers;

/// The `main` of every report binary: run `run`, print its error on stderr
/// after the binary's name and turn the outcome into the exit code.
pub fn report_main<E: std::fmt::Display>(
    run: impl FnOnce() -> Result<(), E>,
) -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            let name = std::env::args()
                .next()
                .and_then(|a| {
                    std::path::Path::new(&a)
                        .file_name()
                        .map(|n| n.to_string_lossy().into_owned())
                })
                .unwrap_or_else(|| "error".to_string());
            eprintln!("{name}: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
