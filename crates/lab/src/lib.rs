//! The `nonholo` command line and the lab: formulations registry, runs,
//! result files.

pub mod experiment;
pub mod formulations;
pub mod listing;
pub mod matching;
pub mod plot;
pub mod record;
pub mod simulate;
pub mod table;

use thiserror::Error;

/// Errors reported by the command line. Exit status 2 for bad input, 1 for a
/// run that failed, 3 for an experiment some of whose runs failed.
#[derive(Debug, Error)]
pub enum CliError {
    #[error("{0}")]
    Input(String),
    #[error(transparent)]
    Setup(#[from] nonholo_core::Error),
    #[error("{0}")]
    Run(String),
    /// An experiment ran to its end, but some of its runs failed.
    #[error("{0}")]
    RunsFailed(String),
}

impl CliError {
    pub fn exit_code(&self) -> i32 {
        match self {
            CliError::Input(_) | CliError::Setup(_) => 2,
            CliError::Run(_) => 1,
            CliError::RunsFailed(_) => 3,
        }
    }
}

/// Writes to stdout; a closed pipe (`nonholo scenes | head`) ends quietly
/// instead of panicking.
pub fn print_stdout(text: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("error: cannot write to stdout: {e}");
        std::process::exit(1);
    }
}
