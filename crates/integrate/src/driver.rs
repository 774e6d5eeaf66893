//! The step loop shared by every method: a [`Driver`] holds the state of a
//! run (time, state, step size, samples, counters, guard) and advances it
//! one accepted step per [`Driver::step`]; the method itself is a [`Core`]
//! that attempts trial steps.
//!
//! One call of [`Driver::step`] reads, in order:
//!
//! 1. **Start** (first call only): the sample at `t0`, the guard at `t0`
//!    (`<= 0` stops at once), `t_end == t0`, then [`Core::start`] (e.g.
//!    `f(t0, y0)`) and the first step size (`fixed_step`, else
//!    `min(h_init, h_max)`, else the method's [`Core::initial_step`]).
//! 2. **Trial steps** until one is accepted, each preceded by the loop head
//!    ([`Driver::trial_steps`]): budgets (`max_steps` trial steps, the wall
//!    clock every 8 trial steps), the minimum step size `h_min(t)` (see
//!    [`StepFloor`]), and landing: the fixed-step grid `t0 + k h`, or for
//!    adaptive methods `t_end` (when `t + stretch·h` reaches it, Hairer's
//!    [`Landing`]) and, with `Options::hit_output`, the next output time.
//!    [`Core::attempt`] then accepts, rejects (the step is retried from the
//!    same state with the size it proposes), repeats or fails.
//! 3. **The accepted step** ([`Driver::accepted`]): counters,
//!    [`Core::accept`] (the new state), the step polynomial stored, then
//!    `after_step` of the system and [`Core::new_state`] (what the method
//!    needs at the possibly projected state), the guard watch on that
//!    state, samples of the output grid inside the step, `t_end`, and the
//!    next step size ([`Core::proposal`] bounded by `h_max` and, after a
//!    rejection, by `h`; [`Core::settle`]).
//!
//! Every terminal [`StopReason`] leaves the driver at the last time
//! reached, so that [`Driver::into_solution`] is the partial solution of a
//! [`Failure`].

use std::mem::swap;

use crate::guard::guard_crossing;
use crate::record::Record;
use crate::{IntegrateError, Options, Solution, Stats, StiffnessEstimate, StopReason, SystemError};

/// What the step loop asks of the system (through the method's wrapper of
/// it): its hooks and its count of evaluations of `f` (or `F`).
pub(crate) trait Hooks {
    /// Evaluations of `f` (or `F`) so far.
    fn evals(&self) -> usize;
    /// [`crate::OdeSystem::after_step`].
    fn after_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError>;
    /// [`crate::OdeSystem::guard`].
    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64>;
    /// [`crate::OdeSystem::guard_reason`].
    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String;
}

/// A trial step `[t, t_new]` of size `h` as the loop head set it up.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Trial {
    /// Start of the step (the current time).
    pub t: f64,
    /// Step size, `t_new − t` up to rounding (exactly that when landing).
    pub h: f64,
    /// End of the step.
    pub t_new: f64,
    /// `h_min(t)`: a rejection that would take `h` below it ends the run.
    pub h_min: f64,
    /// No step has been accepted yet.
    pub first: bool,
    /// The previous trial step was rejected.
    pub after_reject: bool,
    /// The step polynomial will be needed (`Options::dense`, a guard, or
    /// an output time inside the step): methods for which it costs
    /// evaluations compute it only then.
    pub need_poly: bool,
}

/// How a trial step ended.
pub(crate) enum Attempt {
    /// Accepted: the method holds the new state, its polynomial and its
    /// proposal for the next step size.
    Accepted,
    /// Rejected: retry from the same state with step size `h` (`nonfinite`:
    /// because of a non-finite stage or estimate, which turns a later
    /// step-size collapse into [`IntegrateError::NonFinite`]).
    Rejected { h: f64, nonfinite: bool },
    /// Try the same step again without counting a rejection (Radau5 with a
    /// fixed step: once more with a fresh Jacobian).
    Repeat,
    /// The run cannot go on.
    Failed(IntegrateError),
}

/// When an adaptive step is stretched to land on `t_end` (or on the next
/// output time, `Options::hit_output`): `t + stretch·h` reaches it
/// (`inclusive`: `>=`, else `>`), as in Hairer's codes (`dopri5.f`,
/// `dop853.f`: `1.01`, `>`; `radau5.f`: `1.0001`, `>=`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Landing {
    pub stretch: f64,
    pub inclusive: bool,
}

impl Landing {
    /// Whether a step of size `h` from `t` is to end at `target`.
    fn reaches(self, t: f64, h: f64, target: f64) -> bool {
        let overshoot = t + self.stretch * h - target;
        if self.inclusive {
            overshoot >= 0.0
        } else {
            overshoot > 0.0
        }
    }
}

/// One integration method inside the shared step loop: its workspaces and
/// its state between steps (derivative at the current state, step-size
/// controller, Jacobian, …). `P` is the system as the method sees it.
pub(crate) trait Core<P: Hooks> {
    /// Coefficient vectors of the step polynomial (nested form of
    /// [`crate::Dense`]); fixed for the run.
    fn ncoef(&self) -> usize;
    /// How an adaptive step lands on `t_end` and output times.
    const LANDING: Landing;

    /// At the initial state, before the first step: what the method needs
    /// there (e.g. `f(t0, y0)`).
    fn start(&mut self, p: &mut P, t0: f64, y0: &[f64]) -> Result<(), IntegrateError>;

    /// The first step size when neither `fixed_step` nor `h_init` is given
    /// (Hairer's `HINIT` or its first guess), at most `h_max`; after
    /// [`Core::start`].
    fn initial_step(&mut self, p: &mut P, t0: f64, y0: &[f64], h_max: f64) -> f64;

    /// Where an explicit method's stiffness test fired (for budget errors).
    fn stiffness(&self) -> Option<StiffnessEstimate> {
        None
    }

    /// Attempts the trial step `trial` from the current state `y`.
    fn attempt(&mut self, p: &mut P, trial: Trial, y: &[f64], stats: &mut Stats) -> Attempt;

    /// The trial step was accepted (`stats.steps` counts it already): writes
    /// `y_{n+1}` into `y`; returns whether [`Core::coef`] holds the step's
    /// polynomial.
    fn accept(&mut self, trial: Trial, y: &mut Vec<f64>, stats: &mut Stats) -> bool;

    /// After `after_step` at the new state `(t, y)` (`projected`: it moved
    /// `y`; `last`: the run ends here): what the method needs at that state
    /// (e.g. `f(t, y)`); an error ends the run.
    fn new_state(
        &mut self,
        p: &mut P,
        t: f64,
        y: &[f64],
        projected: bool,
        last: bool,
    ) -> Result<(), IntegrateError>;

    /// The polynomial of the last accepted step (when [`Core::accept`] said so).
    fn coef(&self) -> &[f64];

    /// The next step size the method proposes after an accepted step;
    /// `None` with a fixed step.
    fn proposal(&self) -> Option<f64>;

    /// The next step from `t` after an accepted step of size `h`, given the
    /// proposal `h_new` bounded by `h_max` (and by `h` after a rejection):
    /// the step size and whether it lands on `t_end`.
    fn settle(&mut self, _t: f64, _h: f64, h_new: f64, _t_end: f64) -> (f64, bool) {
        (h_new, false)
    }
}

/// Where the driver is in its run.
enum Phase {
    /// [`Driver::step`] has not been called yet.
    Start,
    Running,
    /// A terminal reason was returned; every later call returns it again.
    Done(StopReason),
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

/// A run in progress, whatever its method and system: what
/// [`crate::Solver`] asks of a [`Driver`].
pub(crate) trait Run {
    /// Advances the run by one accepted step, or says why it cannot.
    fn step(&mut self) -> StopReason;
    /// Current time.
    fn t(&self) -> f64;
    /// Current state.
    fn y(&self) -> &[f64];
    /// Counters so far (`rhs_evals` and `wall_time_s` included).
    fn stats(&self) -> Stats;
    /// Samples, continuous extension and counters up to the current time.
    fn into_solution(self: Box<Self>) -> Solution;
}

impl<P: Hooks, C: Core<P>> Run for Driver<P, C> {
    fn step(&mut self) -> StopReason {
        self.advance()
    }

    fn t(&self) -> f64 {
        self.t
    }

    fn y(&self) -> &[f64] {
        &self.y
    }

    fn stats(&self) -> Stats {
        let mut stats = self.rec.stats.clone();
        stats.rhs_evals = self.problem.evals();
        stats.wall_time_s = self.rec.start.elapsed().as_secs_f64();
        stats
    }

    fn into_solution(self: Box<Self>) -> Solution {
        let evals = self.problem.evals();
        self.rec.finish(self.t, &self.y, evals)
    }
}

/// The state of a run and the step loop shared by every method (see the
/// module documentation). `P` is the system, `C` the method.
pub(crate) struct Driver<P, C> {
    problem: P,
    core: C,
    rec: Record,
    t0: f64,
    t_end: f64,
    /// Current time and state (after a guard stop: the located ones).
    t: f64,
    y: Vec<f64>,
    /// Size of the next trial step.
    h: f64,
    h_max: f64,
    h_init: Option<f64>,
    /// Fixed step: `(h, number of steps)`.
    fixed: Option<(f64, usize)>,
    hit_output: bool,
    /// Set by [`Driver::begin`] from the first step size.
    floor: StepFloor,
    /// The current trial step ends at `t_end`.
    last: bool,
    /// The previous trial step was rejected.
    after_reject: bool,
    /// The last rejection was caused by a non-finite stage, state or error
    /// estimate: a step-size collapse then is reported as `NonFinite`.
    nonfinite_reject: bool,
    /// The guard at the last accepted state (`None`: no guard).
    g_prev: Option<f64>,
    /// The guard is watched (it returned a value at `t0`).
    guard_active: bool,
    /// The state at a located guard zero.
    y_root: Vec<f64>,
    buf: Vec<f64>,
    phase: Phase,
}

impl<P: Hooks, C: Core<P>> Driver<P, C> {
    /// A run of `core` on `problem` from `(t0, y0)` to `t_end`, with the
    /// record `rec` of [`Record::new`]; `opts` validated.
    pub(crate) fn new(
        problem: P,
        core: C,
        rec: Record,
        t0: f64,
        y0: &[f64],
        t_end: f64,
        opts: &Options,
    ) -> Self {
        let dim = y0.len();
        let span = t_end - t0;
        Driver {
            problem,
            core,
            rec,
            t0,
            t_end,
            t: t0,
            y: y0.to_vec(),
            h: f64::NAN,
            h_max: opts.h_max.unwrap_or(span),
            h_init: opts.h_init,
            fixed: opts.fixed_step.map(|h| (h, fixed_step_count(span, h))),
            hit_output: opts.hit_output,
            floor: StepFloor::new(span, 1.0),
            last: false,
            after_reject: false,
            nonfinite_reject: false,
            g_prev: None,
            guard_active: false,
            y_root: vec![0.0; dim],
            buf: vec![0.0; dim],
            phase: Phase::Start,
        }
    }

    /// Advances the run by one accepted step (see the module documentation).
    fn advance(&mut self) -> StopReason {
        match &self.phase {
            Phase::Done(stop) => return stop.clone(),
            Phase::Start => {
                self.phase = Phase::Running;
                if let Some(stop) = self.begin() {
                    return self.done(stop);
                }
            }
            Phase::Running => {}
        }
        let trial = match self.trial_steps() {
            Ok(trial) => trial,
            Err(stop) => return self.done(stop),
        };
        match self.accepted(trial) {
            stop @ StopReason::Accepted { .. } => stop,
            stop => self.done(stop),
        }
    }

    /// Records a terminal reason.
    fn done(&mut self, stop: StopReason) -> StopReason {
        self.phase = Phase::Done(stop.clone());
        stop
    }

    /// Before the first step: sample and guard at `t0`, the method's start,
    /// the first step size. `Some` ends the run.
    fn begin(&mut self) -> Option<StopReason> {
        let (t0, t_end) = (self.t0, self.t_end);
        self.rec.emit(t0, &self.y, None, &mut self.buf);
        self.g_prev = self.problem.guard(t0, &self.y);
        self.guard_active = self.g_prev.is_some();
        if self.g_prev.is_some_and(|g| g <= 0.0 || g.is_nan()) {
            let reason = self.problem.guard_reason(t0, &self.y);
            return Some(StopReason::Guard { t: t0, reason });
        }
        if t_end == t0 {
            return Some(StopReason::End { t: t0 });
        }
        if let Err(e) = self.core.start(&mut self.problem, t0, &self.y) {
            return Some(StopReason::Failed(e));
        }
        let h = match (self.fixed, self.h_init) {
            (Some((h, _)), _) => h,
            (None, Some(h)) => h.min(self.h_max),
            (None, None) => self
                .core
                .initial_step(&mut self.problem, t0, &self.y, self.h_max),
        };
        if !(h > 0.0 && h.is_finite()) {
            // Only the initial-step choice can get here (the other steps are
            // validated): its weighted norms overflowed although the
            // derivative at t0 is finite.
            return Some(StopReason::Failed(IntegrateError::NonFinite { t: t0 }));
        }
        self.h = h;
        self.floor = StepFloor::new(t_end - t0, h);
        None
    }

    /// Trial steps from the current state until one is accepted; each
    /// after the loop head (budgets, minimum step, landing).
    fn trial_steps(&mut self) -> Result<Trial, StopReason> {
        loop {
            let stiffness = self.core.stiffness();
            if let Some(e) = self.rec.budget_exceeded(self.t, self.h, stiffness) {
                return Err(StopReason::Budget(e));
            }
            let t_new = self.next_time().map_err(StopReason::Failed)?;
            let trial = Trial {
                t: self.t,
                h: self.h,
                t_new,
                h_min: self.floor.at(self.t),
                first: self.rec.stats.steps == 0,
                after_reject: self.after_reject,
                need_poly: self.rec.dense.is_some()
                    || self.guard_active
                    || self.rec.next_time().is_some_and(|tau| tau < t_new),
            };
            let stats = &mut self.rec.stats;
            match self.core.attempt(&mut self.problem, trial, &self.y, stats) {
                Attempt::Accepted => return Ok(trial),
                Attempt::Rejected { h, nonfinite } => {
                    self.rec.stats.rejected_steps += 1;
                    (self.h, self.after_reject, self.last) = (h, true, false);
                    self.nonfinite_reject = nonfinite;
                }
                Attempt::Repeat => {}
                Attempt::Failed(e) => return Err(StopReason::Failed(e)),
            }
        }
    }

    /// The end of the next trial step: on the fixed-step grid, or `t + h`
    /// for adaptive methods after the minimum-step check, landing on
    /// `t_end` and (`hit_output`) on the next output time.
    fn next_time(&mut self) -> Result<f64, IntegrateError> {
        let (t, t_end) = (self.t, self.t_end);
        if let Some((hf, n)) = self.fixed {
            let k = self.rec.stats.steps + 1;
            self.last = k >= n;
            let t_new = if self.last {
                t_end
            } else {
                self.t0 + k as f64 * hf
            };
            self.h = t_new - t;
            return Ok(t_new);
        }
        if self.h.abs() < self.floor.at(t) {
            return Err(if self.nonfinite_reject {
                IntegrateError::NonFinite { t }
            } else {
                IntegrateError::StepSizeTooSmall { t, h: self.h }
            });
        }
        let landing = C::LANDING;
        if landing.reaches(t, self.h, t_end) {
            self.h = t_end - t;
            self.last = true;
        }
        Ok(match self.rec.next_time() {
            // Land on the next output time (`Options::hit_output`).
            Some(tau)
                if self.hit_output
                    && !self.last
                    && tau > t
                    && t + landing.stretch * self.h >= tau =>
            {
                self.h = tau - t;
                tau
            }
            _ if self.last => t_end,
            _ => t + self.h,
        })
    }

    /// Completes an accepted trial step: new state, step polynomial,
    /// `after_step` and the method's evaluation there, guard, samples, the
    /// next step size.
    fn accepted(&mut self, trial: Trial) -> StopReason {
        let Trial {
            t: t_old, h, t_new, ..
        } = trial;
        self.rec.stats.steps += 1;
        self.nonfinite_reject = false;
        let has_poly = self.core.accept(trial, &mut self.y, &mut self.rec.stats);
        if has_poly {
            if let Some(d) = self.rec.dense.as_mut() {
                d.push(t_old, h, self.core.coef());
            }
        }
        let t = t_new;
        self.t = t;

        // `after_step` first, then what the method needs at the state it left.
        let error = match self.problem.after_step(t, &mut self.y) {
            Err(source) => Some(IntegrateError::System { t, source }),
            Ok(projected) => {
                let res = self
                    .core
                    .new_state(&mut self.problem, t, &self.y, projected, self.last);
                res.err()
            }
        };
        if let Some(e) = error {
            let poly = has_poly.then_some((self.core.coef(), t_old, h));
            self.rec.emit(t, &self.y, poly, &mut self.buf);
            return StopReason::Failed(e);
        }

        // The guard, on the state `after_step` left.
        let ncoef = self.core.ncoef();
        let problem = &mut self.problem;
        let crossing = guard_crossing(
            |tg, yg| problem.guard(tg, yg),
            &mut self.g_prev,
            self.core.coef(),
            ncoef,
            t_old,
            t,
            h,
            &self.y,
            &mut self.y_root,
            &mut self.buf,
        );
        let poly = has_poly.then_some((self.core.coef(), t_old, h));
        if let Some(t_root) = crossing {
            let reason = self.problem.guard_reason(t_root, &self.y_root);
            self.rec.emit(t_root, &self.y_root, poly, &mut self.buf);
            swap(&mut self.y, &mut self.y_root);
            self.t = t_root;
            return StopReason::Guard { t: t_root, reason };
        }

        self.rec.emit(t, &self.y, poly, &mut self.buf);
        if self.last {
            return StopReason::End { t };
        }
        if let Some(h_new) = self.core.proposal() {
            let mut h_new = h_new.min(self.h_max);
            if self.after_reject {
                h_new = h_new.min(h);
            }
            self.after_reject = false;
            (self.h, self.last) = self.core.settle(t, h, h_new, self.t_end);
        }
        StopReason::Accepted { t }
    }
}
