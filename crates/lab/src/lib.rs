//! The `nonholo` command line and the lab: formulations registry, runs,
//! result files.

pub mod bvp;
pub mod compare;
pub mod experiment;
pub mod fields;
pub mod formulations;
pub mod io;
pub mod linearize;
pub mod listing;
pub mod matching;
pub mod plot;
pub mod record;
pub mod simulate;
pub mod table;

use thiserror::Error;

/// Errors reported by the command line, each with its exit status
/// ([`CliError::exit_code`]; docs/cli.md lists them).
#[derive(Debug, Error)]
pub enum CliError {
    /// Refused input (a flag, a file, a name, a value): nothing ran. Exit 2.
    #[error("{0}")]
    Input(String),
    /// A scene or formulation refused its parameters or initial data. Exit 2.
    #[error(transparent)]
    Setup(#[from] nonholo_core::Error),
    /// A run failed. Exit 1.
    #[error("{0}")]
    Run(String),
    /// An experiment ran to its end and wrote its results, but some of its
    /// runs failed. Exit 3.
    #[error("{0}")]
    RunsFailed(String),
    /// A result could not be written (a file, a directory, stdout). Exit 4.
    #[error("{0}")]
    Output(String),
    /// The results directory is in use by another nonholo process. Exit 5.
    #[error("{0}")]
    Busy(String),
    /// `compare`: the two results directories hold different results (the
    /// report on stdout says where). Exit 6.
    #[error("{0}")]
    Differ(String),
}

impl CliError {
    pub fn exit_code(&self) -> i32 {
        match self {
            CliError::Input(_) | CliError::Setup(_) => 2,
            CliError::Run(_) => 1,
            CliError::RunsFailed(_) => 3,
            CliError::Output(_) => 4,
            CliError::Busy(_) => 5,
            CliError::Differ(_) => 6,
        }
    }
}

/// Writes to stdout; a closed stdout or a broken pipe is an output error.
pub fn print_stdout(text: &str) -> Result<(), CliError> {
    io::print_stdout(text).map_err(CliError::Output)
}
