use crate::IntegrateError;

/// Why [`crate::Solver::step`] returned.
///
/// `Accepted` means the run goes on; the other reasons are terminal: the
/// solver stays at the time they report (for `Guard`, the located time and
/// state), every later `step()` returns the same reason again, and
/// `into_solution()` gives the samples, continuous extension and counters
/// up to that time. `solve()` is the loop `while let Accepted = step()`:
/// it returns `Ok` on `End` and a [`crate::Failure`] carrying the error
/// otherwise (`Guard` as [`IntegrateError::Stopped`]).
#[derive(Debug, Clone, PartialEq)]
pub enum StopReason {
    /// One step was accepted and the solver now stands at `t < t_end`;
    /// `after_step` and the guard have seen the new state and every output
    /// time `<= t` is sampled.
    Accepted {
        /// End of the accepted step.
        t: f64,
    },
    /// The run reached `t_end` (the last step landed on it, or `t0 ==
    /// t_end`): it is complete.
    End {
        /// `t_end`.
        t: f64,
    },
    /// The guard changed from `> 0` to `<= 0` (or was `<= 0` at `t0`): the
    /// run stops at the located time.
    Guard {
        /// The located time: the first point found at which the guard is
        /// `<= 0` (to `~1e-14` relative).
        t: f64,
        /// The system's `guard_reason` at that time and state.
        reason: String,
    },
    /// A budget was used up before the next trial step:
    /// [`IntegrateError::TooManySteps`] or
    /// [`IntegrateError::TimeBudgetExceeded`]; or an explicit method found
    /// the problem stiff ([`IntegrateError::Stiff`], with
    /// `Options::stiff_stop`).
    Budget(IntegrateError),
    /// The run cannot go on: any other [`IntegrateError`] (the step size
    /// collapsed, a non-finite state, the system failed at an accepted
    /// state, …); see the methods' documentation.
    Failed(IntegrateError),
}
