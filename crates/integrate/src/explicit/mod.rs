//! Explicit Runge–Kutta methods: RK4 (fixed step), DOPRI5 and DOP853
//! (adaptive, or fixed step when `Options::fixed_step` is set).
//!
//! [`crate::Solver`] is the solver state of the three methods: the shared
//! step loop ([`crate::driver`]: budgets, minimum step, landing on `t_end`
//! and output times, `after_step`, guard, samples) around the core [`Rk`],
//! which attempts trial steps with Hairer's controller and stiffness test.
//! A method ([`Scheme`]) only computes the stages of a trial step, its
//! error estimate, the derivative at the new point, the stiffness quotient
//! and the coefficients of its step polynomial. The method modules
//! ([`rk4`], [`dopri5`], [`dop853`]) document order, reference, controller
//! constants and counters; the methods take no settings beyond the shared
//! [`Options`].
//!
//! # A step
//!
//! 1. `f(t0, y0)` is evaluated once (at the first [`crate::Solver::step`]);
//!    afterwards the derivative at the end of each accepted step is the
//!    first stage of the next (FSAL). An error of `f` at an accepted state
//!    is fatal: [`IntegrateError::System`]; a non-finite `f(t0, y0)` is
//!    [`IntegrateError::InvalidInput`] (naming the component). A first step
//!    from `HINIT` that is zero or not finite (its weighted norms
//!    overflowed, e.g. `|f| ~ 1e307`) ends the run with
//!    [`IntegrateError::NonFinite`] at `t0`.
//! 2. Budgets before each trial step: `max_steps` (accepted + rejected) →
//!    `TooManySteps`; `max_wall_time_s`, checked every 8 trial steps →
//!    `TimeBudgetExceeded` (both [`StopReason::Budget`]);
//!    `|h| < h_min(t) = max(16 ε |t|, floor)` → `StepSizeTooSmall`, or
//!    `NonFinite` if the last rejection was for a non-finite stage, state or
//!    error estimate (the collapse is then driven by overflow, not by
//!    accuracy). The absolute `floor = 16 ε min(10⁻⁶ |t_end − t0|,
//!    h_first)` only matters near `t = 0`: it is positive (repeated
//!    shrinking near `t = 0` ends) and at most a `3.6e-15` fraction of the
//!    first step whatever the span. A step that would pass `t_end`
//!    (`t + 1.01 h > t_end`, as `dopri5.f`) is shortened to land on it.
//! 3. Adaptive methods reject a step whose error estimate exceeds 1 (Hairer's
//!    controller), whose error estimate or new state is not finite (`h /= 4`),
//!    or at one of whose later stages `f` failed (`h /= 4`; if that takes `h`
//!    below the minimum the run ends with `System` and the last error).
//!    With a fixed step every step is accepted, and a failing or non-finite
//!    stage ends the run (`System`, `NonFinite`; a stage beyond the system's
//!    singular set, [`SystemError::singular`], as `Stopped` at the step's start).
//! 4. After an accepted step: the step polynomial is stored (if
//!    `Options::dense`), [`OdeSystem::after_step`] may project the state
//!    (then `f` is evaluated again there), then the guard is evaluated on
//!    the projected state (always in this order), and output samples inside
//!    the step are taken from the polynomial.
//! 5. A guard that changes from `> 0` to `<= 0` across a step is located on
//!    the step polynomial (Illinois iteration to `~1e-14` relative in `t`);
//!    the run stops there ([`StopReason::Guard`];
//!    [`IntegrateError::Stopped`] from `solve`), `t_last` being the first
//!    located time at which the guard is `<= 0`.
//!
//! Error norms use the scale `atol_i + rtol·max(|y_n,i|, |y_n+1,i|)` with
//! `atol_i` from `Options::atol_components` if set, else `Options::atol`.
//!
//! Every error reports the last time reached (`error.time() ==
//! Some(partial.t_last)`), with the samples, counters and dense output up to
//! that time. Stage vectors are allocated once per run (by
//! [`crate::Solver::new`]); a step only allocates by pushing samples and step
//! polynomials.

pub(crate) mod control;
mod dop853;
mod dopri5;
mod rk4;
mod tableau;

use std::mem::swap;

use crate::driver::{Attempt, Core, Driver, Landing, Run, Trial};
use crate::record::Record;
use crate::validate::{atol_vector, validate};
use crate::{
    Failure, IntegrateError, Method, OdeSystem, Options, Stats, StiffnessEstimate, SystemError,
};
use control::{ControlParams, Controller, Rhs, StiffnessTest, Tol, all_finite, hinit};
use dop853::Dop853;
use dopri5::Dopri5;
use rk4::Rk4;

/// The accepted state a step starts from: `t`, `y` and `f(t, y)`.
#[derive(Clone, Copy)]
struct Start<'a> {
    t: f64,
    y: &'a [f64],
    f: &'a [f64],
}

/// A computed step `[t, t + h]`, as the continuous extension needs it.
#[derive(Clone, Copy)]
struct StepData<'a> {
    t: f64,
    h: f64,
    y: &'a [f64],
    f0: &'a [f64],
    y_new: &'a [f64],
    f_new: &'a [f64],
}

/// One explicit Runge–Kutta method: stages, error estimate, dense output.
trait Scheme {
    /// Number of coefficient vectors of the step polynomial.
    const NCOEF: usize;
    /// Step-size control; `None` for a method that needs a fixed step.
    const CONTROL: Option<ControlParams>;

    /// Allocates the stage vectors for dimension `dim`.
    fn new(dim: usize) -> Self;

    /// Computes a trial step of size `h` from `from` (ending at `t_new`) into
    /// `y_new`; returns the scaled error estimate if `tol` is given, else 0.
    fn step<S: OdeSystem + ?Sized>(
        &mut self,
        rhs: &mut Rhs<'_, S>,
        from: Start<'_>,
        h: f64,
        t_new: f64,
        y_new: &mut [f64],
        tol: Option<Tol<'_>>,
    ) -> Result<f64, SystemError>;

    /// Writes `f(t_new, y_new)` of the last trial step into `f_new`.
    fn f_new<S: OdeSystem + ?Sized>(
        &mut self,
        rhs: &mut Rhs<'_, S>,
        t_new: f64,
        y_new: &[f64],
        f_new: &mut [f64],
    ) -> Result<(), SystemError>;

    /// Estimate `|h|·ρ` of the dominant eigenvalue times the step, if the method has one.
    fn stiffness(&self, h: f64, y_new: &[f64], f_new: &[f64]) -> Option<f64>;

    /// Writes the `NCOEF × dim` coefficients of the step polynomial.
    fn dense<S: OdeSystem + ?Sized>(
        &mut self,
        rhs: &mut Rhs<'_, S>,
        step: StepData<'_>,
        coef: &mut [f64],
    ) -> Result<(), SystemError>;
}

/// Writes the cubic Hermite part (coefficients 1–4 of the nested form):
/// `y_n`, `y_{n+1} − y_n`, `h f_n − c2`, `c2 − h f_{n+1} − c3`.
fn hermite(coef: &mut [f64], s: StepData<'_>) {
    let dim = s.y.len();
    for i in 0..dim {
        let ydiff = s.y_new[i] - s.y[i];
        let bspl = s.h * s.f0[i] - ydiff;
        coef[i] = s.y[i];
        coef[dim + i] = ydiff;
        coef[2 * dim + i] = bspl;
        coef[3 * dim + i] = ydiff - s.h * s.f_new[i] - bspl;
    }
}

/// A run of `method` (RK4, DOPRI5 or DOP853) on `sys` from `(t0, y0)` to
/// `t_end`, with the settings and checks of [`crate::solve`] (invalid input
/// comes back as a [`Failure`] at once; nothing of `sys` is evaluated
/// before the first step).
pub(crate) fn run<'a, S: OdeSystem + ?Sized + 'a>(
    method: Method,
    sys: &'a mut S,
    t0: f64,
    y0: &[f64],
    t_end: f64,
    opts: &Options,
) -> Result<Box<dyn Run + 'a>, Failure> {
    Ok(match method {
        Method::Rk4 => Box::new(driver::<Rk4, S>(method, sys, t0, y0, t_end, opts)?),
        Method::Dopri5 => Box::new(driver::<Dopri5, S>(method, sys, t0, y0, t_end, opts)?),
        Method::Dop853 => Box::new(driver::<Dop853, S>(method, sys, t0, y0, t_end, opts)?),
        Method::Radau5 => unreachable!("Radau IIA is set up by crate::radau"),
    })
}

/// Validates the input and sets up the driver of scheme `M`.
fn driver<'a, M: Scheme, S: OdeSystem + ?Sized>(
    method: Method,
    sys: &'a mut S,
    t0: f64,
    y0: &[f64],
    t_end: f64,
    opts: &Options,
) -> Result<Driver<Rhs<'a, S>, Rk<M>>, Failure> {
    let dim = sys.dim();
    let rec = Record::new(method, dim, M::NCOEF, opts, t_end);
    // The scheme has no step-size control exactly when the method needs a fixed step.
    debug_assert_eq!(M::CONTROL.is_none(), method.needs_fixed_step());
    if let Err(msg) = validate(method.needs_fixed_step(), dim, t0, y0, t_end, opts) {
        return Err(rec.fail(IntegrateError::InvalidInput(msg), t0, y0, 0));
    }
    let core = Rk::<M>::new(dim, opts);
    Ok(Driver::new(
        Rhs { sys, evals: 0 },
        core,
        rec,
        t0,
        y0,
        t_end,
        opts,
    ))
}

/// Outcome of the stages of a trial step.
enum Stages {
    /// Stages computed; the error estimate (0 with a fixed step). If it is
    /// at most 1, `y_new`, `f_new` and (if asked for) the polynomial are set.
    Done(f64),
    /// `f` failed on a stage.
    Rhs(SystemError),
    /// A stage, the error estimate or the new state is not finite.
    NonFinite,
}

/// An explicit Runge–Kutta method in the step loop: the scheme's stage
/// vectors, `f` at the current state, the step-size controller and the
/// stiffness test. Allocated once per run.
struct Rk<M> {
    scheme: M,
    /// `f(t, y)` at the current state (the first stage of the next step).
    f: Vec<f64>,
    y_new: Vec<f64>,
    f_new: Vec<f64>,
    /// Coefficients of the polynomial of the last trial step.
    coef: Vec<f64>,
    /// Evaluations of `f` spent on dense output only (`Stats::dense_rhs_evals`).
    dense_evals: usize,
    rtol: f64,
    /// Absolute tolerance of every component.
    atol: Vec<f64>,
    /// Hairer's controller; `None` with a fixed step.
    ctrl: Option<Controller>,
    stiff: Option<StiffnessTest>,
    /// Where the stiffness test fired first.
    stiffness: Option<StiffnessEstimate>,
    /// The controller's next step size after the last accepted step.
    h_next: f64,
    /// The last trial step computed its polynomial.
    need_dense: bool,
}

impl<M: Scheme> Rk<M> {
    fn new(dim: usize, opts: &Options) -> Self {
        Rk {
            scheme: M::new(dim),
            f: vec![0.0; dim],
            y_new: vec![0.0; dim],
            f_new: vec![0.0; dim],
            coef: vec![0.0; M::NCOEF * dim],
            dense_evals: 0,
            rtol: opts.rtol,
            atol: atol_vector(opts, dim),
            ctrl: match (opts.fixed_step, M::CONTROL) {
                (None, Some(p)) => Some(Controller::new(p)),
                _ => None,
            },
            stiff: M::CONTROL.map(|p| StiffnessTest::new(p.stiff_bound)),
            stiffness: None,
            h_next: f64::NAN,
            need_dense: false,
        }
    }

    /// The stages of the trial step `[from.t, t_new]` of size `h`, `f` at
    /// its end and (if `need_dense`) its polynomial.
    fn stages<S: OdeSystem + ?Sized>(
        &mut self,
        rhs: &mut Rhs<'_, S>,
        y: &[f64],
        trial: Trial,
    ) -> Stages {
        let Trial {
            t,
            h,
            t_new,
            need_poly: need_dense,
            ..
        } = trial;
        let from = Start { t, y, f: &self.f };
        let tol = self.ctrl.is_some().then_some(Tol {
            rtol: self.rtol,
            atol: &self.atol,
        });
        let err = match self.scheme.step(rhs, from, h, t_new, &mut self.y_new, tol) {
            Ok(err) => err,
            Err(e) => return Stages::Rhs(e),
        };
        if !err.is_finite() {
            return Stages::NonFinite;
        }
        if err > 1.0 {
            return Stages::Done(err);
        }
        if !all_finite(&self.y_new) {
            return Stages::NonFinite;
        }
        if let Err(e) = self.scheme.f_new(rhs, t_new, &self.y_new, &mut self.f_new) {
            return Stages::Rhs(e);
        }
        if !all_finite(&self.f_new) {
            return Stages::NonFinite;
        }
        if need_dense {
            let step = StepData {
                t,
                h,
                y,
                f0: &self.f,
                y_new: &self.y_new,
                f_new: &self.f_new,
            };
            let before = rhs.evals;
            let res = self.scheme.dense(rhs, step, &mut self.coef);
            self.dense_evals += rhs.evals - before;
            if let Err(e) = res {
                return Stages::Rhs(e);
            }
            if !all_finite(&self.coef) {
                return Stages::NonFinite;
            }
        }
        Stages::Done(err)
    }
}

impl<M: Scheme, S: OdeSystem + ?Sized> Core<Rhs<'_, S>> for Rk<M> {
    fn ncoef(&self) -> usize {
        M::NCOEF
    }
    const LANDING: Landing = Landing {
        stretch: 1.01,
        inclusive: false,
    };

    /// `f(t0, y0)`, which must be finite.
    fn start(&mut self, rhs: &mut Rhs<'_, S>, t0: f64, y0: &[f64]) -> Result<(), IntegrateError> {
        if let Err(source) = rhs.eval(t0, y0, &mut self.f) {
            return Err(IntegrateError::System { t: t0, source });
        }
        if let Some(i) = self.f.iter().position(|v| !v.is_finite()) {
            let msg = format!(
                "f(t0, y0) is not finite: component {i} is {} at t0 = {t0}",
                self.f[i]
            );
            return Err(IntegrateError::InvalidInput(msg));
        }
        Ok(())
    }

    /// Hairer's `HINIT` with the method's order (adaptive methods only).
    fn initial_step(&mut self, rhs: &mut Rhs<'_, S>, t0: f64, y0: &[f64], h_max: f64) -> f64 {
        let p = M::CONTROL.expect("validated: a method without control has a fixed step");
        let tol = Tol {
            rtol: self.rtol,
            atol: &self.atol,
        };
        hinit(
            rhs,
            t0,
            y0,
            &self.f,
            p.hinit_order,
            h_max,
            tol,
            &mut self.y_new,
            &mut self.f_new,
        )
    }

    fn stiffness(&self) -> Option<StiffnessEstimate> {
        self.stiffness
    }

    /// Stages and error test. Adaptive methods reject a step whose error
    /// exceeds 1 (Hairer's controller proposes the retry), and one with a
    /// failing (`h/4`; below `h_min` the run ends) or non-finite stage
    /// (`h/4`); with a fixed step those end the run.
    fn attempt(
        &mut self,
        rhs: &mut Rhs<'_, S>,
        trial: Trial,
        y: &[f64],
        stats: &mut Stats,
    ) -> Attempt {
        let (t, h) = (trial.t, trial.h);
        self.need_dense = trial.need_poly;
        let stages = self.stages(rhs, y, trial);
        stats.dense_rhs_evals = self.dense_evals;
        let err = match stages {
            Stages::Done(err) => err,
            Stages::Rhs(source) if self.ctrl.is_none() && source.singular => {
                return Attempt::Failed(IntegrateError::Stopped {
                    t,
                    reason: format!(
                        "{} (a stage of the fixed step h = {h:.3e} from this time)",
                        source.message
                    ),
                });
            }
            Stages::Rhs(source) => {
                if self.ctrl.is_none() || h.abs() / 4.0 < trial.h_min {
                    return Attempt::Failed(IntegrateError::System { t, source });
                }
                return Attempt::Rejected {
                    h: h / 4.0,
                    nonfinite: false,
                };
            }
            Stages::NonFinite => {
                if self.ctrl.is_none() {
                    return Attempt::Failed(IntegrateError::NonFinite { t });
                }
                return Attempt::Rejected {
                    h: h / 4.0,
                    nonfinite: true,
                };
            }
        };
        if let Some(c) = self.ctrl.as_mut() {
            if err > 1.0 {
                return Attempt::Rejected {
                    h: c.rejected(h, err),
                    nonfinite: false,
                };
            }
            self.h_next = c.accepted(h, err);
        }
        Attempt::Accepted
    }

    /// The stiffness test (when due), then `y_{n+1}` and `f_{n+1}` become current.
    fn accept(&mut self, trial: Trial, y: &mut Vec<f64>, stats: &mut Stats) -> bool {
        let (t, h) = (trial.t, trial.h);
        if let Some(st) = self.stiff.as_mut() {
            if st.due(stats.steps) {
                let ratio = self.scheme.stiffness(h, &self.y_new, &self.f_new);
                if let Some(h_rho) = st.update(ratio) {
                    stats.stiffness_detected.get_or_insert((t, h_rho));
                    self.stiffness
                        .get_or_insert(StiffnessEstimate { t, h, h_rho });
                }
            }
        }
        swap(y, &mut self.y_new);
        swap(&mut self.f, &mut self.f_new);
        self.need_dense
    }

    /// `f` again at a projected state.
    fn new_state(
        &mut self,
        rhs: &mut Rhs<'_, S>,
        t: f64,
        y: &[f64],
        projected: bool,
        _last: bool,
    ) -> Result<(), IntegrateError> {
        if !projected {
            return Ok(());
        }
        match rhs.eval(t, y, &mut self.f) {
            Err(source) => Err(IntegrateError::System { t, source }),
            Ok(()) if !all_finite(y) || !all_finite(&self.f) => {
                Err(IntegrateError::NonFinite { t })
            }
            Ok(()) => Ok(()),
        }
    }

    fn coef(&self) -> &[f64] {
        &self.coef
    }

    fn proposal(&self) -> Option<f64> {
        self.ctrl.is_some().then_some(self.h_next)
    }
}
