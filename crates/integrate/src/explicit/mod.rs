//! Explicit Runge–Kutta methods: RK4 (fixed step), DOPRI5 and DOP853
//! (adaptive, or fixed step when `Options::fixed_step` is set).
//!
//! One driver ([`run`]) serves the three methods; a method ([`Scheme`])
//! only computes the stages of a trial step, its error estimate, the
//! derivative at the new point, the stiffness quotient and the coefficients
//! of its step polynomial. The method modules ([`rk4`], [`dopri5`],
//! [`dop853`]) document order, reference, defaults and counters.
//!
//! # The step loop
//!
//! 1. `f(t0, y0)` is evaluated once; afterwards the derivative at the end of
//!    each accepted step is the first stage of the next (FSAL). An error of
//!    `f` at an accepted state is fatal: [`IntegrateError::System`]; a
//!    non-finite `f(t0, y0)` is [`IntegrateError::InvalidInput`] (naming
//!    the component). A first step from `HINIT` that is zero or not finite
//!    (its weighted norms overflowed, e.g. `|f| ~ 1e307`) ends the run
//!    with [`IntegrateError::NonFinite`] at `t0`.
//! 2. Budgets before each trial step: `max_steps` (accepted + rejected) →
//!    `TooManySteps`; `max_wall_time_s`, checked every 8 trial steps →
//!    `TimeBudgetExceeded`; `|h| < h_min(t) = max(16 ε |t|, floor)` →
//!    `StepSizeTooSmall`, or `NonFinite` if the last rejection was for a
//!    non-finite stage, state or error estimate (the collapse is then
//!    driven by overflow, not by accuracy). The absolute `floor =
//!    16 ε min(10⁻⁶ |t_end − t0|, h_first)` only matters near `t = 0`: it is
//!    positive (repeated shrinking near `t = 0` ends) and at most a
//!    `3.6e-15` fraction of the first step whatever the span.
//! 3. Adaptive methods reject a step whose error estimate exceeds 1 (Hairer's
//!    controller), whose error estimate or new state is not finite (`h /= 4`),
//!    or at one of whose later stages `f` failed (`h /= 4`; if that takes `h`
//!    below the minimum the run ends with `System` and the last error).
//!    With a fixed step every step is accepted, and a failing or non-finite
//!    stage ends the run (`System`, `NonFinite`).
//! 4. After an accepted step: the step polynomial is stored (if
//!    `Options::dense`), [`OdeSystem::after_step`] may project the state
//!    (then `f` is evaluated again there), then the guard is evaluated on
//!    the projected state (always in this order), and output samples inside
//!    the step are taken from the polynomial.
//!
//! Error norms use the scale `atol_i + rtol·max(|y_n,i|, |y_n+1,i|)` with
//! `atol_i` from `Options::atol_components` if set, else `Options::atol`.
//! 5. A guard that changes from `> 0` to `<= 0` across a step is located on
//!    the step polynomial (Illinois iteration to `~1e-14` relative in `t`);
//!    the run stops there with [`IntegrateError::Stopped`], `t_last` being
//!    the first located time at which the guard is `<= 0`.
//!
//! Every error reports the last time reached (`error.time() ==
//! Some(partial.t_last)`), with the samples, counters and dense output up to
//! that time. Stage vectors are allocated once per run; the step loop only
//! allocates by pushing samples and step polynomials.

pub(crate) mod control;
mod dop853;
mod dopri5;
mod rk4;
mod tableau;

use std::mem::swap;
use std::time::Instant;

use crate::driver::{Record, StepFloor, atol_vector, fixed_step_count, guard_crossing, validate};
use crate::{
    Dense, Failure, IntegrateError, Method, OdeSystem, Options, Solution, Stats, StiffnessEstimate,
    SystemError,
};
use control::{ControlParams, Controller, Rhs, StiffnessTest, Tol, all_finite, hinit};

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

pub(crate) fn solve<S: OdeSystem + ?Sized>(
    method: Method,
    sys: &mut S,
    t0: f64,
    y0: &[f64],
    t_end: f64,
    opts: &Options,
) -> Result<Solution, Failure> {
    match method {
        Method::Rk4 => run::<rk4::Rk4, S>(method, sys, t0, y0, t_end, opts),
        Method::Dopri5 => run::<dopri5::Dopri5, S>(method, sys, t0, y0, t_end, opts),
        Method::Dop853 => run::<dop853::Dop853, S>(method, sys, t0, y0, t_end, opts),
        Method::Radau5 => unreachable!("implicit methods are dispatched in lib.rs"),
    }
}

/// Outcome of a trial step.
enum Attempt {
    /// Stages computed; the error estimate (0 with a fixed step). If it is
    /// at most 1, `y_new`, `f_new` and (if asked for) the polynomial are set.
    Done(f64),
    /// `f` failed on a stage.
    Rhs(SystemError),
    /// A stage, the error estimate or the new state is not finite.
    NonFinite,
}

/// Buffers of the step loop, allocated once per run.
struct Work<M> {
    scheme: M,
    y_new: Vec<f64>,
    f_new: Vec<f64>,
    /// Coefficients of the current step polynomial.
    coef: Vec<f64>,
    /// Evaluations of `f` spent on dense output only (`Stats::dense_rhs_evals`).
    dense_evals: usize,
}

impl<M: Scheme> Work<M> {
    #[allow(clippy::too_many_arguments)]
    fn attempt<S: OdeSystem + ?Sized>(
        &mut self,
        rhs: &mut Rhs<'_, S>,
        from: Start<'_>,
        h: f64,
        t_new: f64,
        tol: Option<Tol<'_>>,
        need_dense: bool,
    ) -> Attempt {
        let err = match self.scheme.step(rhs, from, h, t_new, &mut self.y_new, tol) {
            Ok(err) => err,
            Err(e) => return Attempt::Rhs(e),
        };
        if !err.is_finite() {
            return Attempt::NonFinite;
        }
        if err > 1.0 {
            return Attempt::Done(err);
        }
        if !all_finite(&self.y_new) {
            return Attempt::NonFinite;
        }
        if let Err(e) = self.scheme.f_new(rhs, t_new, &self.y_new, &mut self.f_new) {
            return Attempt::Rhs(e);
        }
        if !all_finite(&self.f_new) {
            return Attempt::NonFinite;
        }
        if need_dense {
            let step = StepData {
                t: from.t,
                h,
                y: from.y,
                f0: from.f,
                y_new: &self.y_new,
                f_new: &self.f_new,
            };
            let before = rhs.evals;
            let res = self.scheme.dense(rhs, step, &mut self.coef);
            self.dense_evals += rhs.evals - before;
            if let Err(e) = res {
                return Attempt::Rhs(e);
            }
            if !all_finite(&self.coef) {
                return Attempt::NonFinite;
            }
        }
        Attempt::Done(err)
    }
}

/// The step loop shared by all methods (see the module documentation).
fn run<M: Scheme, S: OdeSystem + ?Sized>(
    method: Method,
    sys: &mut S,
    t0: f64,
    y0: &[f64],
    t_end: f64,
    opts: &Options,
) -> Result<Solution, Failure> {
    let start = Instant::now();
    let dim = sys.dim();
    let mut rec = Record {
        method,
        dim,
        ncoef: M::NCOEF,
        grid: Vec::new(),
        next: 0,
        t: Vec::new(),
        y: Vec::new(),
        dense: opts.dense.then(|| Dense::new(dim, M::NCOEF)),
        stats: Stats::default(),
        start,
    };
    // The scheme has no step-size control exactly when the method needs a fixed step.
    debug_assert_eq!(M::CONTROL.is_none(), method.needs_fixed_step());
    if let Err(msg) = validate(method.needs_fixed_step(), dim, t0, y0, t_end, opts) {
        return Err(rec.fail(IntegrateError::InvalidInput(msg), t0, y0, 0));
    }
    rec.grid.extend_from_slice(&opts.output);
    if rec.grid.last() != Some(&t_end) {
        rec.grid.push(t_end);
    }

    let mut rhs = Rhs { sys, evals: 0 };
    let mut t = t0;
    let mut y = y0.to_vec();
    let mut f = vec![0.0; dim];
    let mut buf = vec![0.0; dim];
    let mut w = Work {
        scheme: M::new(dim),
        y_new: vec![0.0; dim],
        f_new: vec![0.0; dim],
        coef: vec![0.0; M::NCOEF * dim],
        dense_evals: 0,
    };

    rec.emit(t0, &y, None, &mut buf);
    let mut g_prev = rhs.sys.guard(t0, &y);
    let guard_active = g_prev.is_some();
    if g_prev.is_some_and(|g| g <= 0.0) {
        let reason = rhs.sys.guard_reason(t0, &y);
        return Err(rec.fail(IntegrateError::Stopped { t: t0, reason }, t0, &y, 0));
    }
    if t_end == t0 {
        return Ok(rec.finish(t, &y, 0));
    }
    if let Err(source) = rhs.eval(t, &y, &mut f) {
        let ev = rhs.evals;
        return Err(rec.fail(IntegrateError::System { t, source }, t, &y, ev));
    }
    if let Some(i) = f.iter().position(|v| !v.is_finite()) {
        let msg = format!(
            "f(t0, y0) is not finite: component {i} is {} at t0 = {t0}",
            f[i]
        );
        let ev = rhs.evals;
        return Err(rec.fail(IntegrateError::InvalidInput(msg), t, &y, ev));
    }

    let span = t_end - t0;
    let hmax = opts.h_max.unwrap_or(span);
    let atol = atol_vector(opts, dim);
    let tol = Tol {
        rtol: opts.rtol,
        atol: &atol,
    };
    // Fixed step: (h, number of steps); adaptive: controller and stiffness test.
    let fixed = opts.fixed_step.map(|h| (h, fixed_step_count(span, h)));
    let mut ctrl = None;
    let mut stiff = M::CONTROL.map(|p| StiffnessTest::new(p.stiff_bound));
    let mut stiffness: Option<StiffnessEstimate> = None;
    let mut h = match (fixed, M::CONTROL) {
        (Some((h, _)), _) => h,
        (None, Some(p)) => {
            ctrl = Some(Controller::new(p));
            match opts.h_init {
                Some(h) => h.min(hmax),
                None => hinit(
                    &mut rhs,
                    t,
                    &y,
                    &f,
                    p.hinit_order,
                    hmax,
                    tol,
                    &mut w.y_new,
                    &mut w.f_new,
                ),
            }
        }
        (None, None) => unreachable!("validated: this method needs a fixed step"),
    };
    if !(h > 0.0 && h.is_finite()) {
        // Only HINIT can get here (the other steps are validated): its
        // weighted norms of f overflowed although f(t0, y0) is finite.
        let ev = rhs.evals;
        return Err(rec.fail(IntegrateError::NonFinite { t }, t, &y, ev));
    }
    let floor = StepFloor::new(span, h);
    let h_min = |t: f64| floor.at(t);
    let mut reject = false;
    // The last rejection was caused by a non-finite stage, state or error
    // estimate: a step-size collapse then is reported as `NonFinite`.
    let mut nonfinite_reject = false;
    let mut last = false;

    loop {
        if let Some(e) = rec.budget_exceeded(opts, t, h, stiffness) {
            let ev = rhs.evals;
            return Err(rec.fail(e, t, &y, ev));
        }
        let t_new = match fixed {
            Some((hf, n)) => {
                let k = rec.stats.steps + 1;
                last = k >= n;
                let t_new = if last { t_end } else { t0 + k as f64 * hf };
                h = t_new - t;
                t_new
            }
            None => {
                if h.abs() < h_min(t) {
                    let e = if nonfinite_reject {
                        IntegrateError::NonFinite { t }
                    } else {
                        IntegrateError::StepSizeTooSmall { t, h }
                    };
                    let ev = rhs.evals;
                    return Err(rec.fail(e, t, &y, ev));
                }
                if t + 1.01 * h - t_end > 0.0 {
                    h = t_end - t;
                    last = true;
                }
                match rec.next_time() {
                    // Land on the next output time (`Options::hit_output`).
                    Some(tau) if opts.hit_output && !last && tau > t && t + 1.01 * h >= tau => {
                        h = tau - t;
                        tau
                    }
                    _ if last => t_end,
                    _ => t + h,
                }
            }
        };

        let need_dense =
            opts.dense || guard_active || rec.next_time().is_some_and(|tau| tau < t_new);
        let from = Start { t, y: &y, f: &f };
        let trial_tol = ctrl.is_some().then_some(tol);
        let attempt = w.attempt(&mut rhs, from, h, t_new, trial_tol, need_dense);
        rec.stats.dense_rhs_evals = w.dense_evals;
        let err = match attempt {
            Attempt::Done(err) => err,
            Attempt::Rhs(source) => {
                if ctrl.is_none() || h.abs() / 4.0 < h_min(t) {
                    let ev = rhs.evals;
                    return Err(rec.fail(IntegrateError::System { t, source }, t, &y, ev));
                }
                rec.stats.rejected_steps += 1;
                (h, reject, last) = (h / 4.0, true, false);
                nonfinite_reject = false;
                continue;
            }
            Attempt::NonFinite => {
                if ctrl.is_none() {
                    let ev = rhs.evals;
                    return Err(rec.fail(IntegrateError::NonFinite { t }, t, &y, ev));
                }
                rec.stats.rejected_steps += 1;
                (h, reject, last) = (h / 4.0, true, false);
                nonfinite_reject = true;
                continue;
            }
        };
        let mut h_next = h;
        if let Some(c) = ctrl.as_mut() {
            if err > 1.0 {
                rec.stats.rejected_steps += 1;
                (h, reject, last) = (c.rejected(h, err), true, false);
                nonfinite_reject = false;
                continue;
            }
            h_next = c.accepted(h, err);
        }
        nonfinite_reject = false;

        // The step is accepted.
        rec.stats.steps += 1;
        if let Some(st) = stiff.as_mut() {
            if st.due(rec.stats.steps) {
                let ratio = w.scheme.stiffness(h, &w.y_new, &w.f_new);
                if let Some(h_rho) = st.update(ratio) {
                    rec.stats.stiffness_detected.get_or_insert((t, h_rho));
                    stiffness.get_or_insert(StiffnessEstimate { t, h, h_rho });
                }
            }
        }
        if need_dense {
            if let Some(d) = rec.dense.as_mut() {
                d.push(t, h, &w.coef);
            }
        }
        let t_old = t;
        t = t_new;
        swap(&mut y, &mut w.y_new);
        swap(&mut f, &mut w.f_new);
        let poly = need_dense.then_some((&w.coef[..], t_old, h));

        match rhs.sys.after_step(t, &mut y) {
            Ok(false) => {}
            Ok(true) => {
                let res = rhs.eval(t, &y, &mut f);
                let error = match res {
                    Err(source) => Some(IntegrateError::System { t, source }),
                    Ok(()) if !all_finite(&y) || !all_finite(&f) => {
                        Some(IntegrateError::NonFinite { t })
                    }
                    Ok(()) => None,
                };
                if let Some(e) = error {
                    rec.emit(t, &y, poly, &mut buf);
                    let ev = rhs.evals;
                    return Err(rec.fail(e, t, &y, ev));
                }
            }
            Err(source) => {
                rec.emit(t, &y, poly, &mut buf);
                let ev = rhs.evals;
                return Err(rec.fail(IntegrateError::System { t, source }, t, &y, ev));
            }
        }

        // `w.y_new` (the previous state, already in `coef`) is free.
        let sys = &mut *rhs.sys;
        let crossing = guard_crossing(
            |tg, yg| sys.guard(tg, yg),
            &mut g_prev,
            &w.coef,
            M::NCOEF,
            t_old,
            t,
            h,
            &y,
            &mut w.y_new,
            &mut buf,
        );
        if let Some(t_root) = crossing {
            let y_root = &w.y_new;
            let reason = rhs.sys.guard_reason(t_root, y_root);
            rec.emit(t_root, y_root, poly, &mut buf);
            let e = IntegrateError::Stopped { t: t_root, reason };
            let ev = rhs.evals;
            return Err(rec.fail(e, t_root, y_root, ev));
        }

        rec.emit(t, &y, poly, &mut buf);
        if last {
            let ev = rhs.evals;
            return Ok(rec.finish(t, &y, ev));
        }
        if ctrl.is_some() {
            h_next = h_next.min(hmax);
            if reject {
                h_next = h_next.min(h);
            }
            reject = false;
            h = h_next;
        }
    }
}
