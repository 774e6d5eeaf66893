use thiserror::Error;

/// Errors of scene, formulation and initial-data set-up: everything a user
/// can get wrong before a run starts.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum Error {
    #[error("unknown {what} `{name}`; valid names: {}", valid.join(", "))]
    UnknownName {
        what: String,
        name: String,
        valid: Vec<String>,
    },
    #[error("{what} `{name}` given more than once")]
    Repeated { what: String, name: String },
    #[error("{what} `{name}`: cannot read `{value}` as {expected}")]
    Parse {
        what: String,
        name: String,
        value: String,
        expected: String,
    },
    #[error("{what} `{name}` = {value} is outside its range {range} ({description})")]
    OutOfRange {
        what: String,
        name: String,
        value: String,
        range: String,
        description: String,
    },
    /// Parameters that are each in range but do not fit together.
    #[error("inconsistent parameters: {0}")]
    InconsistentParams(String),
    /// Initial data that violate the constraints, or name clashes among them.
    #[error("inconsistent initial data: {0}")]
    InconsistentInit(String),
    /// The formulation needs a piece the scene does not have.
    #[error("formulation `{formulation}` is not applicable to scene `{scene}`: {reason}")]
    NotApplicable {
        formulation: String,
        scene: String,
        reason: String,
    },
    /// A name the workbench knows of but this build does not provide.
    #[error("{0}")]
    Unavailable(String),
    /// A numerical set-up step failed (projection did not converge, singular matrix).
    #[error("{0}")]
    Numerical(String),
}
