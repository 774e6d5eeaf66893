//! One run: initial data, a model, an integrator; the physical trajectory
//! on the output grid, the continuous extension, diagnostics and counters.

use std::time::Instant;

use nonholo_integrate::{
    Failure, IntegrateError, Method, Options, RadauNewton, Solution, solve, solve_implicit,
};

use crate::Error;
use crate::consistency::InitProjection;
use crate::init::Initial;
use crate::model::{CrossingRecord, Model, Observation, SwitchRecord};
use crate::monitor::Diagnostics;

/// Integrator choice and settings for a run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunConfig {
    pub method: Method,
    /// Integrator options; `output` is the sampling grid.
    pub options: Options,
    pub t_end: f64,
    /// Move inconsistent initial data onto the constraints instead of refusing them.
    pub project_init: bool,
}

/// A finished (or failed) run.
pub struct Run {
    pub model: Box<dyn Model>,
    /// Initial data after any projection.
    pub initial: Initial,
    /// What `--project-init` changed, if it was asked for.
    pub projection: Option<InitProjection>,
    pub config: RunConfig,
    pub solution: Solution,
    /// Physical reading at each time of `solution.t`.
    pub samples: Vec<Observation>,
    pub diagnostics: Diagnostics,
    /// Why the run stopped before `t_end`, if it did.
    pub failure: Option<IntegrateError>,
    /// The crossings of singular sets the run made ([`Model::crossing`]).
    pub crossings: Vec<CrossingRecord>,
    /// The changes of mode the run made ([`Model::switch`]).
    pub switches: Vec<SwitchRecord>,
}

impl std::fmt::Debug for Run {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Run")
            .field("scene", &self.model.scene_info().name)
            .field("formulation", &self.model.formulation().name)
            .field("initial", &self.initial)
            .field("samples", &self.samples.len())
            .field("failure", &self.failure)
            .finish()
    }
}

impl Run {
    /// Physical state at any time in the integrated span, from the
    /// continuous extension (requires `options.dense`). Times past the end
    /// of a run that stopped early are refused, even inside the last step.
    pub fn observe_at(&mut self, t: f64, obs: &mut Observation) -> Result<(), String> {
        let dense = self
            .solution
            .dense
            .as_ref()
            .ok_or("the run kept no continuous extension (dense output off)")?;
        if t > self.solution.t_last {
            return Err(format!(
                "t = {t} is beyond the end of the run (t = {}{})",
                self.solution.t_last,
                if self.failure.is_some() {
                    ", where it stopped"
                } else {
                    ""
                }
            ));
        }
        let mut y = vec![0.0; dense.dim()];
        if !dense.eval(t, &mut y) {
            let (a, b) = dense.span().unwrap_or((f64::NAN, f64::NAN));
            return Err(format!("t = {t} outside the integrated span [{a}, {b}]"));
        }
        self.model
            .observe(t, &y, obs)
            .map_err(|e| format!("at t = {t}: {e}"))
    }

    /// Whether the run reached `t_end`.
    pub fn completed(&self) -> bool {
        self.failure.is_none()
    }

    /// How the run ended: the one place that tells a stop by design (a
    /// singular set the formulation cannot pass) from a failure.
    pub fn status(&self) -> RunStatus {
        match &self.failure {
            None => RunStatus::Completed,
            Some(IntegrateError::Stopped { .. }) => RunStatus::Stopped,
            Some(_) => RunStatus::Failed,
        }
    }
}

/// How a run ended (see [`Run::status`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunStatus {
    /// Reached `t_end`.
    Completed,
    /// Stopped where its formulation stops by design, with time and reason.
    Stopped,
    /// Any other failure (budget, Newton, non-finite values, …).
    Failed,
}

impl RunStatus {
    /// The name used in result files: `completed`, `stopped`, `failed`.
    pub fn as_str(self) -> &'static str {
        match self {
            RunStatus::Completed => "completed",
            RunStatus::Stopped => "stopped",
            RunStatus::Failed => "failed",
        }
    }
}

/// Runs `model` from `initial` to `config.t_end`.
///
/// Set-up errors (inconsistent initial data, a formulation that cannot start
/// from them) are `Err`; a failure during integration is a [`Run`] with
/// [`Run::failure`] set and the trajectory up to that time.
pub fn simulate(
    mut model: Box<dyn Model>,
    mut initial: Initial,
    config: RunConfig,
) -> Result<Run, Error> {
    let projection = model.make_consistent(&mut initial, config.project_init)?;
    let y0 = model.initial_state(&initial)?;
    let formulation = model.formulation().name;
    // The Newton iteration of Radau IIA: the caller's choice, else the model's.
    let mut config = config;
    if config.options.radau5.newton == RadauNewton::Auto {
        config.options.radau5.newton = model.radau_newton();
    }
    model.accepts(config.method)?;
    // Full Newton forms dense stage Jacobians: refused at once for an
    // implicit form with sparse Jacobians (Radau IIA would refuse it at t0).
    let full = config.method.is_implicit() && config.options.radau5.newton == RadauNewton::Full;
    if full && model.implicit().is_some_and(|sys| sys.sparsity().is_some()) {
        return Err(Error::NotApplicable {
            formulation: formulation.into(),
            scene: model.scene_info().name.into(),
            reason: "radau_newton = full forms dense stage Jacobians, and this form gives its \
                     Jacobians sparse: use the simplified Newton iteration"
                .into(),
        });
    }
    let mut crossings = Vec::new();
    let mut switches = Vec::new();
    let result = if config.method.is_implicit() && model.implicit().is_some() {
        let yp0 = model.initial_slope()?;
        let sys = model.implicit().expect("checked above");
        solve_implicit(sys, initial.t0, &y0, &yp0, config.t_end, &config.options)
    } else if model.ode().is_some() {
        solve_across(
            model.as_mut(),
            config.method,
            initial.t0,
            &y0,
            config.t_end,
            &config.options,
            &mut crossings,
            &mut switches,
        )
    } else {
        return Err(Error::NoExplicitForm {
            formulation,
            method: config.method.name(),
        });
    };
    let (mut solution, mut failure) = match result {
        Ok(s) => (s, None),
        Err(f) => (f.partial, Some(f.error)),
    };
    // A run cut short ends its samples at the time it stopped, so that the
    // approach to a singularity is part of the record.
    if failure.is_some() && solution.t.last().is_some_and(|&t| solution.t_last > t) {
        solution.t.push(solution.t_last);
        solution.y.extend_from_slice(&solution.y_last);
    }
    let info = model.scene_info();
    let m = model.multiplier_names().len();
    let mut samples = Vec::with_capacity(solution.t.len());
    for (i, &t) in solution.t.iter().enumerate() {
        let mut obs = Observation::new(info.n(), m);
        match model.observe(t, solution.row(i), &mut obs) {
            Ok(()) => samples.push(obs),
            Err(e) => {
                // The sample cannot be read (e.g. a singular KKT system at a
                // sampled point): stop the trajectory there.
                failure.get_or_insert(IntegrateError::System { t, source: e });
                break;
            }
        }
    }
    let diagnostics = model.diagnostics();
    Ok(Run {
        model,
        initial,
        projection,
        config,
        solution,
        samples,
        diagnostics,
        failure,
        crossings,
        switches,
    })
}

/// Pieces of the continuous extension per crossing gap.
const GAP_PIECES: usize = 4;

/// Integrates the explicit form from `(t0, y0)` to `t_end`, past every stop
/// of its guard at which the model changes mode ([`Model::switch`]; the run
/// goes on from the same state) and every one it can cross
/// ([`Model::crossing`]): the
/// segments' samples, continuous extensions and counters are joined into
/// one solution, the gaps filled from each crossing's states; budgets are
/// for the whole run.
#[allow(clippy::result_large_err)]
fn solve_across(
    model: &mut dyn Model,
    method: Method,
    t0: f64,
    y0: &[f64],
    t_end: f64,
    opts: &Options,
    crossings: &mut Vec<CrossingRecord>,
    switches: &mut Vec<SwitchRecord>,
) -> Result<Solution, Failure> {
    let start = Instant::now();
    let mut seg = opts.clone();
    let mut total: Option<Solution> = None;
    let (mut t, mut y) = (t0, y0.to_vec());
    loop {
        let sys = model.ode().expect("checked by the caller");
        let result = solve(method, sys, t, &y, t_end, &seg);
        let (part, error) = match result {
            Ok(s) => (s, None),
            Err(f) => (f.partial, Some(f.error)),
        };
        let total = join(&mut total, part);
        let stop = |error, total: &Solution| {
            Err(Failure {
                error,
                partial: total.clone(),
            })
        };
        let (t_stop, error) = match error {
            None => return Ok(total.clone()),
            Some(IntegrateError::Stopped { t, .. })
                if model.switch().is_some() || model.crossing().is_some() =>
            {
                (t, error.expect("matched"))
            }
            Some(error) => return stop(error, total),
        };
        if let Some(switch) = model.switch() {
            let mut y_new = total.y_last.clone();
            match switch.switch(t_stop, &mut y_new) {
                Ok(Some(record)) => {
                    switches.push(record);
                    if y_new != total.y_last {
                        // The state jumps at t_stop: the samples and the
                        // continuous extension from here on start from it.
                        if total.t.last() == Some(&t_stop) {
                            let dim = total.dim;
                            let at = total.y.len() - dim;
                            total.y[at..].copy_from_slice(&y_new);
                        }
                        total.y_last.clone_from(&y_new);
                    }
                    if t_stop >= t_end {
                        return Ok(total.clone());
                    }
                    (t, y) = (t_stop, y_new);
                    seg = segment(opts.clone(), opts, t, total, start);
                    continue;
                }
                Ok(None) if model.crossing().is_some() => {}
                Ok(None) => return stop(error, total),
                Err(source) => {
                    return stop(IntegrateError::System { t: t_stop, source }, total);
                }
            }
        }
        let mut left = opts.clone();
        let used = total.stats.steps + total.stats.rejected_steps;
        left.max_steps = opts.max_steps.saturating_sub(used);
        left.max_wall_time_s = opts
            .max_wall_time_s
            .map(|s| (s - start.elapsed().as_secs_f64()).max(0.0));
        let y_stop = total.y_last.clone();
        let crossing = model.crossing().expect("checked above");
        let crossed = match crossing.cross(t_stop, &y_stop, method, &left) {
            Ok(c) => c,
            Err(source) => {
                return Err(Failure {
                    error: IntegrateError::System { t: t_stop, source },
                    partial: total.clone(),
                });
            }
        };
        // The gap (t_stop, t_resume]: samples and step polynomials from the
        // crossing's states; a gap that reaches t_end ends the run there.
        let t_gap = crossed.t.min(t_end);
        let dim = total.dim;
        let mut buf = vec![0.0; dim];
        for &tau in opts
            .output
            .iter()
            .filter(|&&tau| tau > t_stop && tau <= t_gap)
        {
            (crossed.gap)(tau, &mut buf);
            total.t.push(tau);
            total.y.extend_from_slice(&buf);
        }
        if let Some(dense) = total.dense.as_mut() {
            let h = (t_gap - t_stop) / GAP_PIECES as f64;
            for k in 0..GAP_PIECES {
                dense.push_fitted(t_stop + k as f64 * h, h, |tau, out| (crossed.gap)(tau, out));
            }
        }
        total.stats.add(&crossed.stats);
        crossings.push(crossed.record);
        if crossed.t >= t_end {
            total.t_last = t_end;
            (crossed.gap)(t_end, &mut buf);
            total.y_last.clone_from(&buf);
            if total.t.last() != Some(&t_end) {
                total.t.push(t_end);
                total.y.extend_from_slice(&buf);
            }
            return Ok(total.clone());
        }
        total.t_last = crossed.t;
        total.y_last.clone_from(&crossed.y);
        (t, y) = (crossed.t, crossed.y);
        seg = segment(left, opts, t, total, start);
    }
}

/// The options of the segment that starts at `t`: the output times after
/// it, and what is left of the run's step and wall-time budgets.
fn segment(mut seg: Options, opts: &Options, t: f64, total: &Solution, start: Instant) -> Options {
    seg.output = opts.output.iter().copied().filter(|&tau| tau > t).collect();
    seg.max_steps = opts
        .max_steps
        .saturating_sub(total.stats.steps + total.stats.rejected_steps);
    seg.max_wall_time_s = opts
        .max_wall_time_s
        .map(|s| (s - start.elapsed().as_secs_f64()).max(0.0));
    seg
}

/// Appends the segment `part` to the run's solution so far.
fn join(total: &mut Option<Solution>, part: Solution) -> &mut Solution {
    match total {
        None => total.insert(part),
        Some(sol) => {
            sol.t.extend_from_slice(&part.t);
            sol.y.extend_from_slice(&part.y);
            if let (Some(d), Some(p)) = (sol.dense.as_mut(), part.dense.as_ref()) {
                d.append(p);
            }
            sol.stats.add(&part.stats);
            sol.t_last = part.t_last;
            sol.y_last = part.y_last;
            sol
        }
    }
}
