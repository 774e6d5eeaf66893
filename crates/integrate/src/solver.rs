//! A run in progress, advanced one accepted step at a time.

use crate::driver::Run;
use crate::{
    Failure, ImplicitSystem, IntegrateError, Method, OdeSystem, Options, Solution, Stats,
    StopReason,
};

/// A run of any method on any system, advanced one accepted step at a time
/// ([`Solver::step`] says why it returned: [`StopReason`]).
///
/// Built like [`crate::solve`] ([`Solver::new`]) or [`crate::solve_implicit`]
/// ([`Solver::implicit`]), which are `Solver::…(..)?.solve()`. Samples on
/// `opts.output`, the continuous extension and the counters accumulate as in
/// those functions, and [`Solver::into_solution`] hands them over at any
/// point. Workspaces are allocated by the constructor; a step allocates only
/// to store samples and step polynomials.
///
/// ```
/// use nonholo_integrate::{Method, OdeSystem, Options, Solver, StopReason, SystemError};
///
/// struct Decay;
/// impl OdeSystem for Decay {
///     fn dim(&self) -> usize { 1 }
///     fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
///         dy[0] = -y[0];
///         Ok(())
///     }
/// }
///
/// let mut sys = Decay;
/// let opts = Options { rtol: 1e-8, atol: 1e-8, ..Options::default() };
/// let mut run = Solver::new(Method::Dopri5, &mut sys, 0.0, &[1.0], 1.0, &opts).unwrap();
/// while let StopReason::Accepted { t } = run.step() {
///     assert!(t > 0.0 && t < 1.0);
/// }
/// assert_eq!(run.t(), 1.0);
/// assert!((run.y()[0] - (-1.0f64).exp()).abs() < 1e-7);
/// ```
pub struct Solver<'a> {
    run: Box<dyn Run + 'a>,
}

impl<'a> Solver<'a> {
    /// A run of `method` on the explicit system `y' = f(t, y)` of `sys` from
    /// `(t0, y0)` to `t_end`, with the settings and checks of
    /// [`crate::solve`]: invalid input comes back as a [`Failure`] at once.
    /// Nothing of `sys` is evaluated before the first [`Solver::step`].
    pub fn new<S: OdeSystem + ?Sized + 'a>(
        method: Method,
        sys: &'a mut S,
        t0: f64,
        y0: &[f64],
        t_end: f64,
        opts: &Options,
    ) -> Result<Self, Failure> {
        let run = match method {
            Method::Radau5 => crate::radau::run_ode(sys, t0, y0, t_end, opts)?,
            _ => crate::explicit::run(method, sys, t0, y0, t_end, opts)?,
        };
        Ok(Solver { run })
    }

    /// A Radau IIA run on the implicit system `F(t, y, y') = 0` of `sys`
    /// from consistent `(t0, y0, y'0)` to `t_end`, with the settings and
    /// checks of [`crate::solve_implicit`]: invalid input, inconsistent
    /// initial values included (one evaluation of `F`), comes back as a
    /// [`Failure`] at once.
    pub fn implicit<S: ImplicitSystem + ?Sized + 'a>(
        sys: &'a mut S,
        t0: f64,
        y0: &[f64],
        yp0: &[f64],
        t_end: f64,
        opts: &Options,
    ) -> Result<Self, Failure> {
        let run = crate::radau::run_implicit(sys, t0, y0, yp0, t_end, opts)?;
        Ok(Solver { run })
    }

    /// Advances the run by one accepted step, or says why it cannot
    /// ([`StopReason`]). The first call also evaluates the guard (and, for
    /// explicit methods and ODEs, `f`) at `t0` and chooses the first step
    /// size.
    pub fn step(&mut self) -> StopReason {
        self.run.step()
    }

    /// Current time: `t0` before the first step, the end of the last
    /// accepted step, or the time a terminal [`StopReason`] reports.
    pub fn t(&self) -> f64 {
        self.run.t()
    }

    /// State at [`Solver::t`] (after `after_step`).
    pub fn y(&self) -> &[f64] {
        self.run.y()
    }

    /// Work counters so far.
    pub fn stats(&self) -> Stats {
        self.run.stats()
    }

    /// Samples, continuous extension and counters up to [`Solver::t`].
    pub fn into_solution(self) -> Solution {
        self.run.into_solution()
    }

    /// Steps to the end: `Ok` at `t_end`, else the [`Failure`] with the
    /// partial solution (a guard stop as [`IntegrateError::Stopped`]).
    pub fn solve(mut self) -> Result<Solution, Failure> {
        let error = loop {
            match self.step() {
                StopReason::Accepted { .. } => {}
                StopReason::End { .. } => return Ok(self.into_solution()),
                StopReason::Guard { t, reason } => break IntegrateError::Stopped { t, reason },
                StopReason::Budget(error) | StopReason::Failed(error) => break error,
            }
        };
        Err(Failure {
            error,
            partial: self.into_solution(),
        })
    }
}
