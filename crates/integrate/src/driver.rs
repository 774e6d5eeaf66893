//! Pieces of the step loop shared by the explicit driver (`explicit::run`)
//! and the Radau IIA driver (`radau`): the record of samples, step
//! polynomials and counters, input validation, the budgets checked before
//! every trial step, the fixed-step count and the location of guard
//! crossings on a step polynomial.

use std::time::Instant;

use crate::dense::eval_nested;
use crate::explicit::control::all_finite;
use crate::{Dense, Failure, IntegrateError, Method, Options, Solution, Stats, StiffnessEstimate};

/// Samples, step polynomials and counters collected during a run.
pub(crate) struct Record {
    pub(crate) method: Method,
    pub(crate) dim: usize,
    pub(crate) ncoef: usize,
    /// Requested output times, `t_end` appended if missing.
    pub(crate) grid: Vec<f64>,
    /// Index of the next grid time to sample.
    pub(crate) next: usize,
    pub(crate) t: Vec<f64>,
    pub(crate) y: Vec<f64>,
    pub(crate) dense: Option<Dense>,
    pub(crate) stats: Stats,
    pub(crate) start: Instant,
}

impl Record {
    pub(crate) fn next_time(&self) -> Option<f64> {
        self.grid.get(self.next).copied()
    }

    /// Samples every pending grid time `<= t_lim`: `y_lim` at `t_lim` itself,
    /// the step polynomial `(coef, t_n, h_n)` before it.
    pub(crate) fn emit(
        &mut self,
        t_lim: f64,
        y_lim: &[f64],
        poly: Option<(&[f64], f64, f64)>,
        buf: &mut [f64],
    ) {
        while let Some(tau) = self.next_time() {
            if tau > t_lim {
                break;
            }
            match poly {
                Some((coef, tn, h)) if tau < t_lim => {
                    eval_nested(coef, self.dim, self.ncoef, (tau - tn) / h, buf);
                    self.y.extend_from_slice(buf);
                }
                _ => {
                    // Only `tau == t_lim` can get here: the driver computes
                    // the polynomial whenever a grid time lies inside a step.
                    debug_assert!(tau == t_lim);
                    self.y.extend_from_slice(y_lim);
                }
            }
            self.t.push(tau);
            self.next += 1;
        }
    }

    /// The budget error before the next trial step from `(t, h)`, if any:
    /// `max_steps` trial steps (accepted + rejected) done →
    /// [`IntegrateError::TooManySteps`]; `max_wall_time_s` elapsed, checked
    /// every 8 trial steps → [`IntegrateError::TimeBudgetExceeded`].
    pub(crate) fn budget_exceeded(
        &self,
        opts: &Options,
        t: f64,
        h: f64,
        stiffness: Option<StiffnessEstimate>,
    ) -> Option<IntegrateError> {
        let trials = self.stats.steps + self.stats.rejected_steps;
        if trials >= opts.max_steps {
            return Some(IntegrateError::TooManySteps {
                t,
                max_steps: opts.max_steps,
                h,
                stiffness,
            });
        }
        let limit = opts.max_wall_time_s?;
        (trials % 8 == 0 && self.start.elapsed().as_secs_f64() > limit).then_some(
            IntegrateError::TimeBudgetExceeded {
                t,
                seconds: limit,
                h,
                stiffness,
            },
        )
    }

    pub(crate) fn finish(mut self, t_last: f64, y_last: &[f64], rhs_evals: usize) -> Solution {
        self.stats.rhs_evals = rhs_evals;
        self.stats.wall_time_s = self.start.elapsed().as_secs_f64();
        Solution {
            method: self.method,
            dim: self.dim,
            t: self.t,
            y: self.y,
            dense: self.dense,
            t_last,
            y_last: y_last.to_vec(),
            stats: self.stats,
        }
    }

    pub(crate) fn fail(
        self,
        error: IntegrateError,
        t_last: f64,
        y_last: &[f64],
        rhs_evals: usize,
    ) -> Failure {
        Failure {
            error,
            partial: self.finish(t_last, y_last, rhs_evals),
        }
    }
}

/// Checks the initial data and options; the message says what is wrong.
pub(crate) fn validate(
    needs_fixed_step: bool,
    dim: usize,
    t0: f64,
    y0: &[f64],
    t_end: f64,
    opts: &Options,
) -> Result<(), String> {
    let positive = |x: f64| x > 0.0 && x.is_finite();
    if dim == 0 {
        return Err("the system has dimension 0".into());
    }
    if y0.len() != dim {
        return Err(format!(
            "y0 has length {} but the system has dimension {dim}",
            y0.len()
        ));
    }
    if !t0.is_finite() || !t_end.is_finite() {
        return Err(format!("t0 = {t0} and t_end = {t_end} must be finite"));
    }
    if t_end < t0 {
        return Err(format!(
            "t_end = {t_end} < t0 = {t0}: backward integration is not supported"
        ));
    }
    if !all_finite(y0) {
        return Err("y0 is not finite".into());
    }
    if !positive(opts.rtol) || !positive(opts.atol) {
        return Err(format!(
            "rtol = {} and atol = {} must be positive and finite",
            opts.rtol, opts.atol
        ));
    }
    if opts.rtol < RTOL_MIN {
        return Err(format!(
            "rtol = {:e} is below 100·ε = {RTOL_MIN:.2e}: double precision (ε = {:.2e}) \
             cannot deliver a relative accuracy finer than about that (rounding in the \
             stages and in t alone is of order ε per step); use rtol >= {RTOL_MIN:.2e}",
            opts.rtol,
            f64::EPSILON
        ));
    }
    if let Some(a) = &opts.atol_components {
        if a.len() != dim {
            return Err(format!(
                "atol_components has length {} but the system has dimension {dim}",
                a.len()
            ));
        }
        if let Some((i, v)) = a.iter().enumerate().find(|(_, v)| !positive(**v)) {
            return Err(format!(
                "atol_components[{i}] = {v} must be positive and finite"
            ));
        }
    }
    match opts.fixed_step {
        None if needs_fixed_step => return Err("this method needs Options::fixed_step".into()),
        Some(h) if !positive(h) => {
            return Err(format!("fixed_step = {h} must be positive and finite"));
        }
        _ => {}
    }
    for (name, v) in [("h_init", opts.h_init), ("h_max", opts.h_max)] {
        if let Some(h) = v {
            if !positive(h) {
                return Err(format!("{name} = {h} must be positive and finite"));
            }
        }
    }
    if let Some(s) = opts.max_wall_time_s {
        if s.is_nan() || s < 0.0 {
            return Err(format!("max_wall_time_s = {s} must be >= 0"));
        }
    }
    let mut prev = f64::NEG_INFINITY;
    for &tau in &opts.output {
        if !(tau >= t0 && tau <= t_end) {
            return Err(format!("output time {tau} lies outside [{t0}, {t_end}]"));
        }
        if tau <= prev {
            return Err(format!("output times must increase ({prev} then {tau})"));
        }
        prev = tau;
    }
    Ok(())
}

/// The smallest relative tolerance accepted: `100·ε ≈ 2.2e-14`.
pub(crate) const RTOL_MIN: f64 = 100.0 * f64::EPSILON;

/// The absolute tolerance of every component: `Options::atol_components`,
/// else `Options::atol` repeated (validated before).
pub(crate) fn atol_vector(opts: &Options, dim: usize) -> Vec<f64> {
    match &opts.atol_components {
        Some(a) => a.clone(),
        None => vec![opts.atol; dim],
    }
}

/// The smallest step size of the adaptive step loops:
/// `h_min(t) = max(16 ε |t|, floor)`.
///
/// The relative part keeps `t + h` distinguishable from `t` (16 ulps). The
/// absolute floor only matters near `t = 0`, where `16 ε |t|` vanishes: it
/// is `16 ε min(10⁻⁶ |t_end − t0|, h_first)` (at least the smallest normal
/// number), so it is positive — a step shrunk again and again near
/// `t = 0` falls below it after finitely many reductions — yet never more
/// than `16 ε ≈ 3.6e-15` times the first step, whatever the span (a span of
/// `1e300` no longer puts the floor above the first step).
#[derive(Debug, Clone, Copy)]
pub(crate) struct StepFloor {
    floor: f64,
}

impl StepFloor {
    /// The floor for a run over `span = t_end − t0 > 0` whose first trial
    /// step is `h_first > 0`.
    pub(crate) fn new(span: f64, h_first: f64) -> Self {
        let floor = 16.0 * f64::EPSILON * (1e-6 * span).min(h_first.abs());
        StepFloor {
            floor: floor.max(f64::MIN_POSITIVE),
        }
    }

    /// `h_min(t)`.
    pub(crate) fn at(&self, t: f64) -> f64 {
        (16.0 * f64::EPSILON * t.abs()).max(self.floor)
    }
}

/// Number of steps of length `h` (the last one possibly shorter) covering `span`.
pub(crate) fn fixed_step_count(span: f64, h: f64) -> usize {
    // The factor absorbs the rounding of span/h when h divides the span.
    ((span / h) * (1.0 - 1e-12)).ceil().max(1.0) as usize
}

/// Watches the guard across an accepted step `[t_old, t]` of size `h =
/// t − t_old` whose polynomial (nested form of [`Dense`], `ncoef` vectors of
/// length `y.len()`) is `coef`, `(t, y)` being the state after
/// `after_step`. `g_prev` holds the guard at the step start (`None`: no
/// guard, nothing is evaluated).
///
/// If the guard changed from `> 0` to `<= 0`, the crossing is located on
/// the polynomial (Illinois iteration to `~1e-14` relative in `t`): its
/// time is returned and the state there written into `y_root` (`y` itself
/// when it is the step end). Otherwise `g_prev` takes the new value (kept
/// if the guard returned `None`). `buf` is a workspace.
#[allow(clippy::too_many_arguments)]
pub(crate) fn guard_crossing(
    mut guard: impl FnMut(f64, &[f64]) -> Option<f64>,
    g_prev: &mut Option<f64>,
    coef: &[f64],
    ncoef: usize,
    t_old: f64,
    t: f64,
    h: f64,
    y: &[f64],
    y_root: &mut [f64],
    buf: &mut [f64],
) -> Option<f64> {
    let gp = (*g_prev)?;
    let gn = guard(t, y)?;
    if !(gp > 0.0 && gn <= 0.0) {
        *g_prev = Some(gn);
        return None;
    }
    let dim = y.len();
    let g = |s: f64| {
        eval_nested(coef, dim, ncoef, s, buf);
        guard(t_old + s * h, buf).unwrap_or(f64::NAN)
    };
    let tol_t = (1e-14 * t_old.abs().max(t.abs())).max(4.0 * f64::EPSILON * h);
    let s = locate_root(g, gp, gn, tol_t / h);
    Some(if s >= 1.0 {
        y_root.copy_from_slice(y);
        t
    } else {
        eval_nested(coef, dim, ncoef, s, y_root);
        t_old + s * h
    })
}

/// Illinois iteration for a zero of `g(s)` on `[0, 1]` with `g(0) = ga > 0 >= g(1) = gb`.
/// Returns `s` with `g(s) <= 0` (or NaN) within `tol` of the last `s` with `g > 0`.
pub(crate) fn locate_root(
    mut g: impl FnMut(f64) -> f64,
    mut ga: f64,
    mut gb: f64,
    tol: f64,
) -> f64 {
    let (mut a, mut b) = (0.0_f64, 1.0_f64);
    // Which end moved last: +1 for a, -1 for b.
    let mut side = 0;
    for _ in 0..200 {
        if b - a <= tol || gb == 0.0 {
            break;
        }
        let mut s = b - gb * (b - a) / (gb - ga);
        if !(s > a && s < b) {
            s = 0.5 * (a + b);
        }
        let gs = g(s);
        if gs > 0.0 {
            a = s;
            ga = gs;
            if side == 1 {
                gb *= 0.5;
            }
            side = 1;
        } else {
            b = s;
            gb = gs;
            if side == -1 {
                ga *= 0.5;
            }
            side = -1;
        }
    }
    b
}
