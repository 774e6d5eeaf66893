//! The record of a run: samples on the output grid, step polynomials,
//! counters, and the budgets checked before every trial step.

use std::time::Instant;

use crate::dense::eval_nested;
use crate::{Dense, Failure, IntegrateError, Method, Options, Solution, Stats, StiffnessEstimate};

/// Samples, step polynomials and counters collected during a run, and its budgets.
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
    /// `Options::max_steps`.
    max_steps: usize,
    /// `Options::max_wall_time_s`.
    max_wall_time_s: Option<f64>,
    /// `Options::stiff_stop`.
    stiff_stop: bool,
}

impl Record {
    /// An empty record of a run of `method` to `t_end` (the clock starts
    /// now), for states of dimension `dim` and step polynomials of `ncoef`
    /// coefficients; the grid is `opts.output` with `t_end` appended if
    /// missing.
    pub(crate) fn new(
        method: Method,
        dim: usize,
        ncoef: usize,
        opts: &Options,
        t_end: f64,
    ) -> Self {
        let mut grid = opts.output.clone();
        if grid.last() != Some(&t_end) {
            grid.push(t_end);
        }
        Record {
            method,
            dim,
            ncoef,
            grid,
            next: 0,
            t: Vec::new(),
            y: Vec::new(),
            dense: opts.dense.then(|| Dense::new(dim, ncoef)),
            stats: Stats::default(),
            start: Instant::now(),
            max_steps: opts.max_steps,
            max_wall_time_s: opts.max_wall_time_s,
            stiff_stop: opts.stiff_stop,
        }
    }

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
    /// every 8 trial steps → [`IntegrateError::TimeBudgetExceeded`]; with
    /// `stiff_stop`, an explicit method's stiffness test fired 15 times in
    /// a row → [`IntegrateError::Stiff`].
    pub(crate) fn budget_exceeded(
        &self,
        t: f64,
        h: f64,
        stiffness: Option<StiffnessEstimate>,
    ) -> Option<IntegrateError> {
        if let Some(s) = stiffness.filter(|_| self.stiff_stop) {
            return Some(IntegrateError::Stiff { t, h, stiffness: s });
        }
        let trials = self.stats.steps + self.stats.rejected_steps;
        if trials >= self.max_steps {
            return Some(IntegrateError::TooManySteps {
                t,
                max_steps: self.max_steps,
                h,
                stiffness,
            });
        }
        let limit = self.max_wall_time_s?;
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
