use std::fmt;

use crate::Solution;

/// A failure reported by an [`crate::OdeSystem`].
#[derive(Debug, Clone, PartialEq)]
pub struct SystemError {
    /// What went wrong, for people.
    pub message: String,
    /// The state lies beyond the system's singular set, where its equations
    /// stop by design: a fixed-step method ends such a run as
    /// [`IntegrateError::Stopped`], not as a failure.
    pub singular: bool,
}

impl SystemError {
    /// A system error with this message.
    pub fn new(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
            singular: false,
        }
    }

    /// A state beyond the system's singular set (see [`SystemError::singular`]).
    pub fn singular(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
            singular: true,
        }
    }
}

impl fmt::Display for SystemError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for SystemError {}

/// Why an integration did not reach `t_end`.
///
/// In every variant that has one, `t` is the last time reached, equal to
/// `Failure::partial.t_last`.
#[derive(Debug, Clone, PartialEq)]
pub enum IntegrateError {
    /// Options or initial data rejected before the first step.
    InvalidInput(String),
    /// The step size fell below what the floating-point resolution of `t` allows.
    StepSizeTooSmall {
        /// Last time reached.
        t: f64,
        /// The step size that was too small.
        h: f64,
    },
    /// More than `Options::max_steps` steps (accepted plus rejected) were needed.
    TooManySteps {
        /// Last time reached.
        t: f64,
        /// The budget `Options::max_steps`.
        max_steps: usize,
        /// The step size at that time.
        h: f64,
        /// Set when an explicit method's stiffness test had fired.
        stiffness: Option<StiffnessEstimate>,
    },
    /// The wall-clock budget `Options::max_wall_time_s` was used up.
    TimeBudgetExceeded {
        /// Last time reached.
        t: f64,
        /// The budget `Options::max_wall_time_s`.
        seconds: f64,
        /// The step size at that time.
        h: f64,
        /// Set when an explicit method's stiffness test had fired.
        stiffness: Option<StiffnessEstimate>,
    },
    /// An explicit method's stiffness test fired 15 times in a row and
    /// `Options::stiff_stop` is set: stability, not accuracy, limits the
    /// step from there on.
    Stiff {
        /// Last time reached.
        t: f64,
        /// The step size at that time.
        h: f64,
        /// Where the test fired.
        stiffness: StiffnessEstimate,
    },
    /// The state or its derivative stopped being finite; also when the step
    /// size collapsed because the last trial steps were rejected for
    /// non-finite stages, states or error estimates (overflow), and when the
    /// initial step size computed by `HINIT` is zero or not finite (its
    /// weighted norms overflowed).
    NonFinite {
        /// Last time reached (the last finite state).
        t: f64,
    },
    /// The system could not evaluate `f` at an accepted state, or kept
    /// failing on trial stages down to the smallest step.
    System {
        /// Last time reached.
        t: f64,
        /// The system's last error.
        source: SystemError,
    },
    /// [`crate::OdeSystem::guard`] reached zero at `t`, or a fixed step from
    /// `t` had a stage beyond the system's singular set
    /// ([`SystemError::singular`]).
    Stopped {
        /// The located time at which the guard is zero (or just past zero);
        /// with a fixed step, the start of the step that would cross it.
        t: f64,
        /// [`crate::OdeSystem::guard_reason`] at that time.
        reason: String,
    },
}

/// Where Hairer's stiffness test of an explicit method fired: at time `t`,
/// with step size `h`, `h·ρ = h_rho` above the method's stability bound,
/// `ρ` estimating the magnitude of the dominant eigenvalue of `∂f/∂y`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StiffnessEstimate {
    /// Time of the step at which the test fired.
    pub t: f64,
    /// Its step size.
    pub h: f64,
    /// `h·ρ` there.
    pub h_rho: f64,
}

impl StiffnessEstimate {
    /// The estimate `ρ` of the dominant eigenvalue's magnitude.
    pub fn rho(&self) -> f64 {
        self.h_rho / self.h.abs()
    }
}

/// What a used-up budget says about the step size and stiffness.
fn budget_note(h: f64, stiffness: &Option<StiffnessEstimate>) -> String {
    match stiffness {
        Some(s) => format!(
            " (step size {h:.3e}); the problem is stiff for this explicit method: its stiffness \
             test fired at t = {:.6}, where h·ρ = {:.2} with ρ ≈ {:.3e} (dominant eigenvalue \
             magnitude, 1/time unit), so stability rather than accuracy holds the step near \
             {:.1e}; use an implicit method (radau5)",
            s.t,
            s.h_rho,
            s.rho(),
            s.h.abs()
        ),
        None => format!(" (step size {h:.3e})"),
    }
}

impl IntegrateError {
    /// Time at which the error happened, if it happened during the run.
    pub fn time(&self) -> Option<f64> {
        match *self {
            IntegrateError::InvalidInput(_) => None,
            IntegrateError::StepSizeTooSmall { t, .. }
            | IntegrateError::TooManySteps { t, .. }
            | IntegrateError::TimeBudgetExceeded { t, .. }
            | IntegrateError::Stiff { t, .. }
            | IntegrateError::NonFinite { t }
            | IntegrateError::System { t, .. }
            | IntegrateError::Stopped { t, .. } => Some(t),
        }
    }
}

impl fmt::Display for IntegrateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            IntegrateError::InvalidInput(m) => write!(f, "invalid integrator input: {m}"),
            IntegrateError::StepSizeTooSmall { t, h } => {
                write!(
                    f,
                    "at t = {t}: step size {h:e} too small (the problem may be stiff or singular here)"
                )
            }
            IntegrateError::TooManySteps {
                t,
                max_steps,
                h,
                stiffness,
            } => write!(
                f,
                "at t = {t}: step budget of {max_steps} steps used up{}",
                budget_note(*h, stiffness)
            ),
            IntegrateError::TimeBudgetExceeded {
                t,
                seconds,
                h,
                stiffness,
            } => write!(
                f,
                "at t = {t}: wall-time budget of {seconds} s used up{}",
                budget_note(*h, stiffness)
            ),
            IntegrateError::Stiff { t, h, stiffness } => write!(
                f,
                "at t = {t}: stopped{}",
                budget_note(*h, &Some(*stiffness))
            ),
            IntegrateError::NonFinite { t } => write!(
                f,
                "at t = {t}: the solution is not finite (overflow or NaN in the state, \
                 its derivative, the error estimate or the initial step size)"
            ),
            IntegrateError::System { t, source } => write!(f, "at t = {t}: {source}"),
            IntegrateError::Stopped { t, reason } => write!(f, "at t = {t}: {reason}"),
        }
    }
}

impl std::error::Error for IntegrateError {}

/// An integration that did not reach `t_end`: the error and everything
/// computed before it (samples up to the failure time, counters).
#[derive(Debug, Clone)]
pub struct Failure {
    /// What happened.
    pub error: IntegrateError,
    /// Samples, continuous extension and counters up to the error time.
    pub partial: Solution,
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.error.fmt(f)
    }
}

impl std::error::Error for Failure {}
