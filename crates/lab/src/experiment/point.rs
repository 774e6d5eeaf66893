//! One sweep point: every formulation run on the common output grid, and the
//! measures that compare them.

use nonholo_core::consistency::check_or_project;
use nonholo_core::init;
use nonholo_core::integrate::IntegrateError;
use nonholo_core::monitor::state_measures;
use nonholo_core::{Observation, Run, Scene};
use nonholo_scenes::SceneVisitor;
use serde::{Deserialize, Serialize};

use super::files::StoredPoint;
use super::key::point_key;
use super::spec::{CLOSED_FORM, Experiment};
use super::sweep::{Point, PointRun, resolve};
use crate::record::Counters;
use crate::simulate::{ResolveInit, execute};

/// Schema of a point's result file.
pub const POINT_SCHEMA: &str = "nonholo.point/1";

/// One formulation at one point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FormResult {
    pub label: String,
    pub formulation: String,
    pub integrator: String,
    pub rtol: f64,
    pub atol: f64,
    /// `completed`; `stopped` (the run ended where the formulation stops by
    /// design, at a singular set: a result, not an error); or `failed`.
    pub status: String,
    pub error_t: Option<f64>,
    pub error: Option<String>,
    /// Last time reached.
    pub t_last: Option<f64>,
    #[serde(flatten)]
    pub counters: Counters,
    pub wall_time_s: f64,
    pub constraint_residual_max: Option<f64>,
    pub energy_initial: Option<f64>,
    pub energy_drift_max: Option<f64>,
    /// What the formulation found setting up (A: rank_w, hidden constraints…).
    pub report: Vec<(String, f64)>,
    /// The time reached by a run that its wall-time budget stopped: it
    /// depends on the machine, so it goes to `timing.csv` only, and the
    /// run's other measures are left out (see [`super::wall_time_stop`]).
    #[serde(default)]
    pub wall_time_stop_t: Option<f64>,
    /// Crossings of a singular set the run made (formulation A past its
    /// map's singular set; 0 for the others; none without a run).
    #[serde(default)]
    pub crossings: Option<usize>,
    /// Sign changes of the quantity `[measures] reversals` names on the
    /// output grid (none unless asked for).
    #[serde(default)]
    pub reversals: Option<usize>,
    /// Changes of mode the run made (the friction realisation's stick–slip
    /// transitions; 0 for formulations without modes, none without a run).
    #[serde(default)]
    pub switches: Option<usize>,
    /// The located time of the first change of mode.
    #[serde(default)]
    pub first_switch_t: Option<f64>,
    /// What the first change of mode was, `<from>→<to>` (`stick→slip`).
    #[serde(default)]
    pub first_switch: Option<String>,
}

impl FormResult {
    /// A formulation that produced no trajectory: set-up failed, or it was never run.
    pub fn failed(
        label: &str,
        formulation: &str,
        integrator: &str,
        (rtol, atol): (f64, f64),
        error_t: Option<f64>,
        error: String,
    ) -> Self {
        FormResult {
            label: label.into(),
            formulation: formulation.into(),
            integrator: integrator.into(),
            rtol,
            atol,
            status: "failed".into(),
            error_t,
            error: Some(error),
            t_last: None,
            counters: Counters::default(),
            wall_time_s: 0.0,
            constraint_residual_max: None,
            energy_initial: None,
            energy_drift_max: None,
            report: Vec::new(),
            wall_time_stop_t: None,
            crossings: None,
            reversals: None,
            switches: None,
            first_switch_t: None,
            first_switch: None,
        }
    }
}

/// Two formulations compared on their common output grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairResult {
    pub a: String,
    pub b: String,
    /// Last common grid time (None if the two share no sample).
    pub span_end: Option<f64>,
    /// `‖(x, y)_a − (x, y)_b‖` (first two coordinates) at `span_end` and its maximum.
    pub div_xy_end: Option<f64>,
    pub div_xy_max: Option<f64>,
    /// `‖q_a − q_b‖` (angles compared modulo 2π) at `span_end` and its maximum.
    pub div_q_end: Option<f64>,
    pub div_q_max: Option<f64>,
    /// First grid time at which the (x, y) divergence exceeds the threshold.
    pub t_exceed: Option<f64>,
}

/// What a point of a comparison stores: every formulation's result and
/// every pair's divergence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Comparison {
    pub formulations: Vec<FormResult>,
    pub pairs: Vec<PairResult>,
}

/// The result of one point, as stored in `points/<index>.json`.
pub type PointResult = StoredPoint<Comparison>;

/// A formulation's samples on the grid (for measures and trajectory files).
pub struct Samples {
    pub label: String,
    pub coordinates: Vec<(String, String)>,
    pub multipliers: Vec<String>,
    pub t: Vec<f64>,
    pub obs: Vec<Observation>,
    /// `(residual, energy)` per sample.
    pub physics: Vec<(f64, f64)>,
    /// The scene's velocity-chart names ([`Scene::chart_from`]) and their
    /// values per sample (the sleigh's `u`, `omega`).
    pub chart_names: Vec<String>,
    pub chart: Vec<Vec<f64>>,
}

/// Checks that every formulation of `point` can be set up (names, ranges,
/// applicability) without running anything.
pub fn check_point(exp: &Experiment, point: &Point) -> Result<(), String> {
    for r in resolve(exp, point)? {
        // A fixed step that cannot reach t_end within the step budget is
        // refused here, by the integrator's own test, not as a failed run.
        let o = &r.spec.integrator;
        if let Some(h) = o.fixed_step {
            nonholo_core::integrate::fixed_step_budget(0.0, r.spec.t_end, h, o.max_steps)
                .map_err(|e| format!("{}: {e}", r.label))?;
        }
        let scene = nonholo_scenes::build(&r.spec.scene, &r.spec.params)
            .map_err(|e| format!("{}: {e}", r.label))?;
        if r.spec.formulation == CLOSED_FORM {
            if scene.info().closed_form.is_none() {
                return Err(format!(
                    "{}: scene `{}` has no closed form",
                    r.label,
                    scene.info().name
                ));
            }
            scene
                .clone()
                .visit(ResolveInit {
                    given: r.spec.init.clone(),
                    extra: Vec::new(),
                })
                .map_err(|e| format!("{}: {e}", r.label))?;
            continue;
        }
        let mut model =
            crate::formulations::build_model(scene.clone(), &r.spec.formulation, &r.spec.options)
                .map_err(|e| format!("{}: {e}", r.label))?;
        crate::formulations::check_radau_dense(model.as_mut(), r.spec.method, o)
            .map_err(|e| format!("{}: {e}", r.label))?;
        scene
            .visit(ResolveInit {
                given: r.spec.init.clone(),
                extra: model.extra_init_names(),
            })
            .map_err(|e| format!("{}: {e}", r.label))?;
    }
    Ok(())
}

/// Samples the scene's closed form on the grid from the resolved initial
/// data: the samples, and where and why it stopped applying (if it did).
pub(crate) struct ClosedForm<'a> {
    pub spec: &'a crate::simulate::RunSpec,
}

impl SceneVisitor for ClosedForm<'_> {
    type Output = Result<(Vec<f64>, Vec<Observation>, Option<(f64, String)>), String>;
    fn visit<S: Scene>(self, scene: S) -> Self::Output {
        let mut initial = init::resolve(&scene, &self.spec.init, &[]).map_err(|e| e.to_string())?;
        check_or_project(&scene, &mut initial, self.spec.project_init)
            .map_err(|e| e.to_string())?;
        let n = scene.info().n();
        let (mut t, mut obs) = (Vec::new(), Vec::new());
        for &time in &self.spec.integrator.output {
            let mut o = Observation::new(n, 0);
            if let Err(why) = scene.closed_form(&initial.q, &initial.qd, time, &mut o.q, &mut o.qd)
            {
                if t.is_empty() {
                    return Err(why);
                }
                return Ok((t, obs, Some((time, why))));
            }
            t.push(time);
            obs.push(o);
        }
        Ok((t, obs, None))
    }
}

struct Physics<'a> {
    t: &'a [f64],
    obs: &'a [Observation],
}

impl SceneVisitor for Physics<'_> {
    /// `(residual, energy)` and the chart values per sample.
    type Output = (Vec<(f64, f64)>, Vec<Vec<f64>>);
    fn visit<S: Scene>(self, scene: S) -> Self::Output {
        let measures = self
            .t
            .iter()
            .zip(self.obs)
            .map(|(t, o)| state_measures(&scene, *t, &o.q, &o.qd))
            .collect();
        let width = scene.info().velocity_chart.len();
        let mut chart = Vec::with_capacity(self.obs.len());
        for o in self.obs {
            let mut c = vec![0.0; width];
            if !scene.chart_from(&o.q, &o.qd, &mut c) {
                // No chart reading: no chart columns.
                return (measures, Vec::new());
            }
            chart.push(c);
        }
        (measures, chart)
    }
}

/// The velocity-chart names of a scene whose chart was read (none if
/// `chart` is empty: no reading, or no samples).
fn chart_names(info: &nonholo_core::SceneInfo, chart: &[Vec<f64>]) -> Vec<String> {
    if chart.is_empty() {
        return Vec::new();
    }
    info.velocity_chart
        .iter()
        .map(|c| c.name.to_string())
        .collect()
}

fn failed(r: &PointRun, error_t: Option<f64>, error: String) -> FormResult {
    let s = &r.spec;
    let integrator = if s.formulation == CLOSED_FORM {
        "—"
    } else {
        s.method.name()
    };
    FormResult::failed(
        &r.label,
        &s.formulation,
        integrator,
        (s.integrator.rtol, s.integrator.atol),
        error_t,
        error,
    )
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

fn from_run(r: &PointRun, run: &Run) -> FormResult {
    let d = &run.diagnostics;
    FormResult {
        label: r.label.clone(),
        formulation: r.spec.formulation.clone(),
        integrator: r.spec.method.name().into(),
        rtol: r.spec.integrator.rtol,
        atol: r.spec.integrator.atol,
        status: run.status().as_str().into(),
        error_t: run.failure.as_ref().and_then(|e| e.time()),
        error: run.failure.as_ref().map(|e| e.to_string()),
        t_last: finite(run.solution.t_last),
        counters: Counters::from(&run.solution.stats),
        wall_time_s: run.solution.stats.wall_time_s,
        constraint_residual_max: finite(d.constraint_residual_max),
        energy_initial: finite(d.energy_initial),
        energy_drift_max: finite(d.energy_drift_max),
        report: run
            .model
            .init_report()
            .into_iter()
            .filter(|(_, v)| v.is_finite())
            .map(|(k, v)| (k.to_string(), v))
            .collect(),
        wall_time_stop_t: None,
        crossings: Some(run.crossings.len()),
        reversals: None,
        switches: Some(run.switches.len()),
        first_switch_t: run.switches.first().map(|s| s.t),
        first_switch: run.switches.first().map(|s| format!("{}→{}", s.from, s.to)),
    }
}

/// A run its wall-time budget stopped: failed, with no time, counter or
/// measure, since they depend on the machine (the time reached is kept
/// for `timing.csv`).
fn wall_time_stopped(r: &PointRun, run: &Run, seconds: f64) -> FormResult {
    let mut res = failed(r, None, super::wall_time_stop(seconds));
    res.wall_time_s = run.solution.stats.wall_time_s;
    res.wall_time_stop_t = Some(run.solution.t_last);
    res
}

/// The first sample at which a value that would be written is not finite:
/// its index, the column and the value.
fn first_non_finite(s: &Samples) -> Option<(usize, String, f64)> {
    for (i, o) in s.obs.iter().enumerate() {
        let named = s
            .coordinates
            .iter()
            .map(|(c, _)| c.clone())
            .zip(&o.q)
            .chain(
                s.coordinates
                    .iter()
                    .map(|(c, _)| format!("{c}_dot"))
                    .zip(&o.qd),
            )
            .chain(s.multipliers.iter().cloned().zip(&o.multipliers));
        for (name, v) in named {
            if !v.is_finite() {
                return Some((i, name, *v));
            }
        }
        if let Some((residual, energy)) = s.physics.get(i) {
            for (name, v) in [("residual", residual), ("energy", energy)] {
                if !v.is_finite() {
                    return Some((i, name.to_string(), *v));
                }
            }
        }
        if let Some(chart) = s.chart.get(i) {
            for (name, v) in s.chart_names.iter().zip(chart) {
                if !v.is_finite() {
                    return Some((i, name.clone(), *v));
                }
            }
        }
    }
    None
}

/// Cuts `samples` before the first value that is not finite, so that no
/// result file holds one; a run that had not failed by then fails there,
/// with the time and the column.
fn cut_at_non_finite(res: &mut FormResult, samples: &mut Samples) {
    let Some((i, column, v)) = first_non_finite(samples) else {
        return;
    };
    let t = samples.t[i];
    samples.t.truncate(i);
    samples.obs.truncate(i);
    samples.physics.truncate(i);
    samples.chart.truncate(i);
    if res.status != "failed" {
        res.status = "failed".into();
        res.error_t = Some(t);
        res.error = Some(format!(
            "at t = {t}: `{column}` is not finite ({v}): the state overflowed or left the domain \
             of the scene's functions; the samples from there on are left out"
        ));
    }
    res.t_last = samples.t.last().copied();
}

/// Sign changes of the column `name` (a velocity-chart value, a coordinate
/// or a velocity `<coord>_dot`) over the samples: a sample that is exactly
/// zero counts with the next non-zero one.
fn sign_changes(s: &Samples, name: &str) -> Option<usize> {
    let values: Vec<f64> = if let Some(k) = s.chart_names.iter().position(|c| c == name) {
        s.chart.iter().map(|c| c[k]).collect()
    } else if let Some(k) = s.coordinates.iter().position(|(c, _)| c == name) {
        s.obs.iter().map(|o| o.q[k]).collect()
    } else {
        let k = s
            .coordinates
            .iter()
            .position(|(c, _)| name.strip_suffix("_dot") == Some(c.as_str()))?;
        s.obs.iter().map(|o| o.qd[k]).collect()
    };
    Some(sign_change_times(&s.t, &values).len())
}

/// Times where `values` (sampled at `t`) change sign: the midpoint of the
/// two samples; a sample exactly zero counts with the next non-zero one.
pub(crate) fn sign_change_times(t: &[f64], values: &[f64]) -> Vec<f64> {
    let mut out = Vec::new();
    let mut last: Option<(f64, f64)> = None;
    for (&ti, &v) in t.iter().zip(values).filter(|(_, v)| **v != 0.0) {
        if let Some((tl, vl)) = last
            && (v > 0.0) != (vl > 0.0)
        {
            out.push(0.5 * (tl + ti));
        }
        last = Some((ti, v));
    }
    out
}

/// Runs every formulation of `point`; a failure of one is recorded and the
/// others go on. Never panics (a panic inside a run is caught and recorded).
pub fn run_point(exp: &Experiment, point: &Point) -> (PointResult, Vec<Samples>) {
    let runs = match resolve(exp, point) {
        Ok(r) => r,
        Err(e) => {
            // Every point is checked when the experiment is loaded; this is
            // for experiments built in code.
            let formulations = exp
                .formulations
                .iter()
                .map(|f| {
                    FormResult::failed(
                        &f.label,
                        &f.formulation,
                        &f.settings.integrator,
                        (f.settings.rtol, f.settings.atol),
                        None,
                        e.clone(),
                    )
                })
                .collect();
            return (
                PointResult {
                    schema: POINT_SCHEMA.into(),
                    index: point.index,
                    values: point.values.clone(),
                    hash: String::new(),
                    body: Comparison {
                        formulations,
                        pairs: Vec::new(),
                    },
                },
                Vec::new(),
            );
        }
    };
    let hash = point_key(exp, point, POINT_SCHEMA).unwrap_or_default();
    let mut results = Vec::new();
    let mut samples = Vec::new();
    // Wall times of every run, and whether it is timed again (an
    // integration that ran and did not fail).
    let mut walls: Vec<(Vec<f64>, bool)> = Vec::new();
    for r in &runs {
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| one(r)));
        let (res, smp) = match outcome {
            Ok(x) => x,
            Err(p) => {
                let msg = p
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| p.downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                (
                    failed(r, None, format!("internal error (panic): {msg}")),
                    None,
                )
            }
        };
        let mut res = res;
        if let (Some(name), Some(s)) = (&exp.reversals, &smp) {
            res.reversals = sign_changes(s, name);
        }
        let timed = r.spec.formulation != CLOSED_FORM && res.status != "failed";
        walls.push((vec![res.wall_time_s], timed));
        results.push(res);
        if let Some(s) = smp {
            samples.push(s);
        }
    }
    // Repeats in rounds, each timing every formulation once, so that a
    // change in the machine's speed falls on all of them alike.
    for _ in 1..exp.repeats {
        for (r, (times, again)) in runs.iter().zip(&mut walls) {
            *again = *again && time_again(r, times);
        }
    }
    for (res, (times, _)) in results.iter_mut().zip(walls) {
        if let Some(median) = super::output::median(times) {
            res.wall_time_s = median;
        }
    }
    let pairs = pair_measures(exp, &runs, &samples);
    (
        PointResult {
            schema: POINT_SCHEMA.into(),
            index: point.index,
            values: point.values.clone(),
            hash,
            body: Comparison {
                formulations: results,
                pairs,
            },
        },
        samples,
    )
}

/// Runs `r` once (its repeats are timed by [`run_point`]).
fn one(r: &PointRun) -> (FormResult, Option<Samples>) {
    let scene = match nonholo_scenes::build(&r.spec.scene, &r.spec.params) {
        Ok(s) => s,
        Err(e) => return (failed(r, None, e.to_string()), None),
    };
    let info = scene.info();
    let coordinates: Vec<(String, String)> = info
        .coordinates
        .iter()
        .map(|c| (c.name.to_string(), c.unit.to_string()))
        .collect();
    if r.spec.formulation == CLOSED_FORM {
        let started = std::time::Instant::now();
        return match scene.clone().visit(ClosedForm { spec: &r.spec }) {
            Err(e) => (failed(r, Some(0.0), e), None),
            Ok((t, obs, stop)) => {
                let (physics, chart) = scene.clone().visit(Physics { t: &t, obs: &obs });
                let mut res = failed(r, None, String::new());
                res.error = None;
                res.status = "completed".into();
                res.t_last = t.last().copied();
                res.wall_time_s = started.elapsed().as_secs_f64();
                if let Some((te, why)) = stop {
                    res.status = "failed".into();
                    res.error_t = Some(te);
                    res.error = Some(why);
                }
                res.energy_initial = physics.first().map(|p| p.1);
                res.energy_drift_max = physics.first().map(|p0| {
                    physics
                        .iter()
                        .fold(0.0, |m: f64, p| m.max((p.1 - p0.1).abs()))
                });
                res.constraint_residual_max =
                    Some(physics.iter().fold(0.0, |m: f64, p| m.max(p.0)));
                let mut samples = Samples {
                    label: r.label.clone(),
                    coordinates,
                    multipliers: Vec::new(),
                    t,
                    obs,
                    physics,
                    chart_names: chart_names(info, &chart),
                    chart,
                };
                cut_at_non_finite(&mut res, &mut samples);
                res.energy_initial = res.energy_initial.and_then(finite);
                res.energy_drift_max = res.energy_drift_max.and_then(finite);
                res.constraint_residual_max = res.constraint_residual_max.and_then(finite);
                with_samples(res, samples)
            }
        };
    }
    match execute(&r.spec) {
        Err(e) => (failed(r, None, e.to_string()), None),
        Ok((run, _matching)) => {
            if let Some(IntegrateError::TimeBudgetExceeded { seconds, .. }) = &run.failure {
                return (wall_time_stopped(r, &run, *seconds), None);
            }
            let mut res = from_run(r, &run);
            let t = run.solution.t[..run.samples.len()].to_vec();
            let (physics, chart) = scene.clone().visit(Physics {
                t: &t,
                obs: &run.samples,
            });
            let mut samples = Samples {
                label: r.label.clone(),
                coordinates,
                multipliers: run.model.multiplier_names(),
                t,
                obs: run.samples,
                physics,
                chart_names: chart_names(info, &chart),
                chart,
            };
            cut_at_non_finite(&mut res, &mut samples);
            with_samples(res, samples)
        }
    }
}

/// Runs `r` once more and adds its wall time to `times`; false (nothing
/// added) for a run that fails differently, e.g. on a wall-time budget,
/// whose repeats then end with the times measured.
fn time_again(r: &PointRun, times: &mut Vec<f64>) -> bool {
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| execute(&r.spec)));
    match outcome {
        Ok(Ok((run, _)))
            if !matches!(run.failure, Some(IntegrateError::TimeBudgetExceeded { .. })) =>
        {
            times.push(run.solution.stats.wall_time_s);
            true
        }
        _ => false,
    }
}

/// A result and its samples, if it has any: a trajectory file is written
/// for (and expected of) exactly the results with a `t_last`.
fn with_samples(mut res: FormResult, samples: Samples) -> (FormResult, Option<Samples>) {
    if samples.t.is_empty() {
        res.t_last = None;
        (res, None)
    } else {
        (res, Some(samples))
    }
}

/// Divergence measures for every pair of formulations with samples.
fn pair_measures(exp: &Experiment, runs: &[PointRun], samples: &[Samples]) -> Vec<PairResult> {
    let mut pairs = Vec::new();
    for (i, ra) in runs.iter().enumerate() {
        for rb in &runs[i + 1..] {
            let sa = samples.iter().find(|s| s.label == ra.label);
            let sb = samples.iter().find(|s| s.label == rb.label);
            pairs.push(compare(exp, &ra.label, &rb.label, sa, sb));
        }
    }
    pairs
}

/// A coordinate difference, wrapped into `[−π, π]` for an angle.
pub fn coord_diff(d: f64, angle: bool) -> f64 {
    if angle {
        let tau = std::f64::consts::TAU;
        d - (d / tau).round() * tau
    } else {
        d
    }
}

/// Length of the common grid of two runs: the leading samples at identical
/// times (a stopped run's extra sample at its stop time is not on the grid).
pub fn common_len(a: &[f64], b: &[f64]) -> usize {
    a.iter().zip(b).take_while(|(x, y)| x == y).count()
}

/// Distance between two samples: `(‖Δ(x, y)‖, ‖Δq‖)`, angles modulo 2π.
pub fn distance(a: &Observation, b: &Observation, units: &[(String, String)]) -> (f64, f64) {
    let diff = |k: usize| coord_diff(a.q[k] - b.q[k], units[k].1 == "rad");
    let xy = if a.q.len() >= 2 {
        diff(0).hypot(diff(1))
    } else {
        diff(0).abs()
    };
    let q = (0..a.q.len()).map(|k| diff(k).powi(2)).sum::<f64>().sqrt();
    (xy, q)
}

fn compare(
    exp: &Experiment,
    a: &str,
    b: &str,
    sa: Option<&Samples>,
    sb: Option<&Samples>,
) -> PairResult {
    let mut out = PairResult {
        a: a.into(),
        b: b.into(),
        span_end: None,
        div_xy_end: None,
        div_xy_max: None,
        div_q_end: None,
        div_q_max: None,
        t_exceed: None,
    };
    let (Some(sa), Some(sb)) = (sa, sb) else {
        return out;
    };
    // The common grid: samples at identical times (a stopped run's extra
    // sample at its stop time is not on the grid).
    for i in 0..common_len(&sa.t, &sb.t) {
        let (xy, q) = distance(&sa.obs[i], &sb.obs[i], &sa.coordinates);
        if !(xy.is_finite() && q.is_finite()) {
            break;
        }
        out.span_end = Some(sa.t[i]);
        out.div_xy_end = Some(xy);
        out.div_q_end = Some(q);
        out.div_xy_max = Some(out.div_xy_max.unwrap_or(0.0).max(xy));
        out.div_q_max = Some(out.div_q_max.unwrap_or(0.0).max(q));
        if out.t_exceed.is_none() && xy > exp.threshold {
            out.t_exceed = Some(sa.t[i]);
        }
    }
    out
}
