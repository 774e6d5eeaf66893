//! The `nonholo` command line and the lab: formulations registry, runs,
//! result files.

pub mod formulations;
pub mod listing;
pub mod matching;
pub mod record;
pub mod simulate;

use thiserror::Error;

/// Errors reported by the command line. Exit status 2 for bad input, 1 for a
/// run that failed.
#[derive(Debug, Error)]
pub enum CliError {
    #[error("{0}")]
    Input(String),
    #[error(transparent)]
    Setup(#[from] nonholo_core::Error),
    #[error("{0}")]
    Run(String),
}

impl CliError {
    pub fn exit_code(&self) -> i32 {
        match self {
            CliError::Input(_) | CliError::Setup(_) => 2,
            CliError::Run(_) => 1,
        }
    }
}
