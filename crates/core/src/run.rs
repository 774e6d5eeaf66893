//! One run: initial data, a model, an integrator; the physical trajectory
//! on the output grid, the continuous extension, diagnostics and counters.

use nonholo_integrate::{
    IntegrateError, Method, Options, RadauNewton, Solution, solve, solve_implicit,
};

use crate::Error;
use crate::consistency::InitProjection;
use crate::init::Initial;
use crate::model::{Model, Observation};
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
    let result = if config.method.is_implicit() && model.implicit().is_some() {
        let yp0 = model.initial_slope()?;
        let sys = model.implicit().expect("checked above");
        solve_implicit(sys, initial.t0, &y0, &yp0, config.t_end, &config.options)
    } else if let Some(sys) = model.ode() {
        solve(
            config.method,
            sys,
            initial.t0,
            &y0,
            config.t_end,
            &config.options,
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
    })
}
