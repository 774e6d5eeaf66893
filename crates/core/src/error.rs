use thiserror::Error;

/// Errors of scene, formulation and initial-data set-up: everything a user
/// can get wrong before a run starts.
///
/// Each variant carries the values it is about; the message is rendered
/// from them, so code (and tests) match on variants and fields, not prose.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum Error {
    /// A name that is not one of `valid` (parameter, option, initial value,
    /// scene, formulation).
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
    /// Parameters that are each in range but do not fit together: the
    /// relation `requirement` between `values` fails; `why` says where it
    /// comes from.
    #[error(
        "inconsistent parameters: {} violate {requirement}: {why}",
        values.iter().map(|(n, v)| format!("{n} = {}", num(*v))).collect::<Vec<_>>().join(", ")
    )]
    InconsistentParams {
        requirement: String,
        values: Vec<(String, f64)>,
        why: String,
    },
    /// Velocities given both as `<coord>_dot` and through the scene's
    /// convenience values.
    #[error(
        "inconsistent initial data: give the velocities either as {} or through the scene's \
         convenience values {}, not both (got {} and {})",
        coordinates.join(", "), chart.join(", "), raw_given.join(", "), chart_given.join(", ")
    )]
    VelocitiesTwice {
        /// `<coord>_dot` names of the scene.
        coordinates: Vec<String>,
        /// The scene's convenience values.
        chart: Vec<String>,
        raw_given: Vec<String>,
        chart_given: Vec<String>,
    },
    /// Initial data off the constraints at `level`: each constraint with its
    /// residual, the largest distance and the tolerance.
    #[error(
        "inconsistent initial data: the initial {} violate the {} ({}; distance {distance:.3e}, \
         tolerance {tolerance:.1e}); give consistent {} or pass --project-init to move {}",
        level.quantity(), level.constraints(),
        residuals.iter().map(|(c, r)| format!("{c}: residual {r:.3e}")).collect::<Vec<_>>().join("; "),
        level.quantity(), level.projection()
    )]
    OffConstraints {
        level: Level,
        residuals: Vec<(String, f64)>,
        distance: f64,
        tolerance: f64,
    },
    /// A formulation needs initial values that were not given.
    #[error("inconsistent initial data: formulation {formulation} needs {needs}: give {}{}",
        names.join(", "), hint.as_deref().map(|h| format!(" ({h})")).unwrap_or_default())]
    MissingInit {
        formulation: &'static str,
        /// What is missing, in words (`q̈_I(0)`).
        needs: String,
        names: Vec<String>,
        hint: Option<String>,
    },
    /// Initial data that a formulation cannot start from: they contradict
    /// its own equations (A: the embedding map, the hidden constraints).
    #[error("inconsistent initial data: {reason}")]
    InconsistentInit {
        formulation: &'static str,
        reason: String,
    },
    /// The formulation needs a piece the scene does not have.
    #[error("formulation `{formulation}` is not applicable to scene `{scene}`: {reason}")]
    NotApplicable {
        formulation: String,
        scene: String,
        reason: String,
    },
    /// The formulation has no form the chosen integrator can integrate.
    #[error(
        "formulation `{formulation}` is an implicit (differential-algebraic) system and \
         `{method}` integrates explicit ones only: use --integrator radau5"
    )]
    NoExplicitForm {
        formulation: &'static str,
        method: &'static str,
    },
    /// A numerical set-up step failed (`stage`: what was being computed;
    /// `detail`: the solver's own account).
    #[error("{stage} failed: {detail}")]
    Numerical { stage: String, detail: String },
}

/// The level at which initial data violate the constraints.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    /// Positions against the holonomic constraints `f = 0`.
    Positions,
    /// Velocities against `g = 0` and `ḟ = 0`.
    Velocities,
}

impl Level {
    /// `positions` or `velocities`.
    pub fn quantity(self) -> &'static str {
        match self {
            Level::Positions => "positions",
            Level::Velocities => "velocities",
        }
    }

    /// The constraints checked at this level.
    pub fn constraints(self) -> &'static str {
        match self {
            Level::Positions => "holonomic constraints",
            Level::Velocities => "constraints",
        }
    }

    fn projection(self) -> &'static str {
        match self {
            Level::Positions => "them onto the constraints",
            Level::Velocities => "q̇0 to the nearest consistent velocity",
        }
    }
}

impl Error {
    /// A failed numerical set-up step.
    pub fn numerical(stage: impl Into<String>, detail: impl std::fmt::Display) -> Self {
        Error::Numerical {
            stage: stage.into(),
            detail: detail.to_string(),
        }
    }
}

/// A number as messages print it: plain between 1e-5 and 1e16 (`0.5`,
/// `300`), in exponent form outside (`1e300`, `2.5e-7`), never hundreds of
/// digits.
pub fn num(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || !v.is_finite() || (1e-5..1e16).contains(&a) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}
