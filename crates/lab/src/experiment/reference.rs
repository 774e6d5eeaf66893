//! References for work-precision lines: what a run's error is measured against.
//!
//! A line's reference is the scene's closed form when the scene has one for
//! the line's formulation and it applies to the initial data; otherwise a
//! run of the same formulation, options and initial data at a much tighter
//! tolerance, whose own error is estimated by a second run with another
//! method (or, where only one method applies, another tolerance): the
//! largest difference of the two on the output grid bounds the error of the
//! better one from above, as long as the check is no more accurate than
//! the primary reference. A reference may run other formulation options
//! than the line (`reference.options`): another form of the same equations.

use nonholo_core::integrate::{IntegrateError, Method};
use nonholo_core::{Observation, Run};
use serde::{Deserialize, Serialize};

use super::point::ClosedForm;
use super::spec::RefSpec;
use crate::simulate::{RunSpec, execute};

/// A reference trajectory on the output grid.
#[derive(Debug, Clone)]
pub struct Reference {
    pub info: ReferenceInfo,
    pub t: Vec<f64>,
    pub obs: Vec<Observation>,
}

/// What a reference is and how good it is (stored beside it as JSON and in
/// `references.csv`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReferenceInfo {
    /// `closed-form` or `computed`.
    pub kind: String,
    pub integrator: Option<String>,
    pub rtol: Option<f64>,
    pub check_integrator: Option<String>,
    pub check_rtol: Option<f64>,
    /// Largest difference in `q` (max over coordinates, angles modulo 2π) of
    /// the two computed references over their common grid: an estimate (from
    /// above) of the reference's own error. `0` for a closed form (exact to
    /// round-off); absent when the check run failed.
    pub error_estimate: Option<f64>,
    /// The same difference at the last common time.
    pub error_estimate_end: Option<f64>,
    /// Why the check run failed, if it did.
    pub check_failure: Option<String>,
    /// Last time of the reference (before `t_end` if the motion stops at a
    /// singular set, or the closed form stops applying).
    pub t_last: f64,
    /// Why it ends early, if it does.
    pub stop: Option<String>,
    pub wall_time_s: f64,
}

/// `max_k |q_a,k − q_b,k|` with angles compared modulo 2π.
pub fn q_error(a: &Observation, b: &Observation, coordinates: &[(String, String)]) -> f64 {
    (0..a.q.len())
        .map(|k| super::point::coord_diff(a.q[k] - b.q[k], coordinates[k].1 == "rad").abs())
        .fold(0.0, f64::max)
}

/// The run behind a computed reference: `spec` with `method` at `rtol =
/// atol`, within the reference's budgets.
fn tight(spec: &RunSpec, method: &str, rtol: f64, r: &RefSpec) -> Result<Run, String> {
    let mut s = spec.clone();
    s.method = Method::from_name(method).ok_or_else(|| format!("unknown integrator `{method}`"))?;
    s.integrator.rtol = rtol;
    s.integrator.atol = rtol;
    s.integrator.fixed_step = None;
    s.integrator.max_wall_time_s = r.max_wall_time;
    s.integrator.max_steps = r.max_steps;
    s.options = super::spec::override_with(&s.options, &r.options);
    // Samples at step end points, not interpolated: Radau IIA's collocation
    // polynomial (degree 3; implicit forms, and stiff rows under the Hermite
    // extension) would add ~1e-10 at tolerance 1e-13.
    s.integrator.hit_output = true;
    let (run, _) = execute(&s).map_err(|e| e.to_string())?;
    Ok(run)
}

/// A run is usable as a reference if it completed or stopped by design. A
/// stop on the wall-time budget is reported without the time reached,
/// which depends on the machine.
fn usable(run: &Run) -> Result<Option<String>, String> {
    match &run.failure {
        None => Ok(None),
        Some(IntegrateError::Stopped { t, reason }) => Ok(Some(format!("at t = {t}: {reason}"))),
        Some(IntegrateError::TimeBudgetExceeded { seconds, .. }) => {
            Err(super::wall_time_stop(*seconds))
        }
        Some(e) => Err(e.to_string()),
    }
}

/// Computes the reference of a line whose runs are `spec` (any tolerance).
pub fn compute(
    spec: &RunSpec,
    r: &RefSpec,
    coordinates: &[(String, String)],
) -> Result<Reference, String> {
    let started = std::time::Instant::now();
    if r.closed_form
        && let Some(cf) = closed_form(spec)?
    {
        let (t, obs, stop) = cf;
        let t_last = t.last().copied().unwrap_or(0.0);
        return Ok(Reference {
            info: ReferenceInfo {
                kind: "closed-form".into(),
                integrator: None,
                rtol: None,
                check_integrator: None,
                check_rtol: None,
                error_estimate: Some(0.0),
                error_estimate_end: Some(0.0),
                check_failure: None,
                t_last,
                stop,
                wall_time_s: started.elapsed().as_secs_f64(),
            },
            t,
            obs,
        });
    }
    let primary = tight(spec, &r.integrator, r.rtol, r).map_err(|e| {
        format!(
            "reference run ({} at {:e}) could not start: {e}",
            r.integrator, r.rtol
        )
    })?;
    let stop = usable(&primary).map_err(|e| {
        format!(
            "reference run ({} at {:e}) failed: {e}",
            r.integrator, r.rtol
        )
    })?;
    let n = primary.samples.len();
    let t = primary.solution.t[..n].to_vec();
    if let Some((i, _)) = primary
        .samples
        .iter()
        .enumerate()
        .find(|(_, o)| !o.q.iter().chain(&o.qd).all(|v| v.is_finite()))
    {
        return Err(format!(
            "reference run ({} at {:e}) failed: at t = {}: its state is not finite",
            r.integrator, r.rtol, t[i]
        ));
    }
    let mut info = ReferenceInfo {
        kind: "computed".into(),
        integrator: Some(r.integrator.clone()),
        rtol: Some(r.rtol),
        check_integrator: Some(r.check_integrator.clone()),
        check_rtol: Some(r.check_rtol),
        error_estimate: None,
        error_estimate_end: None,
        check_failure: None,
        t_last: primary.solution.t_last,
        stop,
        wall_time_s: 0.0,
    };
    match tight(spec, &r.check_integrator, r.check_rtol, r).and_then(|c| usable(&c).map(|_| c)) {
        Ok(check) => {
            let common = super::point::common_len(&t, &check.solution.t).min(check.samples.len());
            let errs: Vec<f64> = (0..common)
                .map(|i| q_error(&primary.samples[i], &check.samples[i], coordinates))
                .collect();
            info.error_estimate = errs.iter().copied().reduce(f64::max);
            info.error_estimate_end = errs.last().copied();
        }
        Err(e) => info.check_failure = Some(e),
    }
    info.wall_time_s = started.elapsed().as_secs_f64();
    Ok(Reference {
        info,
        t,
        obs: primary.samples,
    })
}

type Sampled = (Vec<f64>, Vec<Observation>, Option<String>);

/// The closed form on the grid, if the scene has one for this formulation
/// and it applies to these parameters and initial data.
fn closed_form(spec: &RunSpec) -> Result<Option<Sampled>, String> {
    let scene = nonholo_scenes::build(&spec.scene, &spec.params).map_err(|e| e.to_string())?;
    let Some(cf) = scene.info().closed_form else {
        return Ok(None);
    };
    if cf.formulation != spec.formulation {
        return Ok(None);
    }
    match scene.visit(ClosedForm { spec }) {
        // Does not apply here (e.g. the sleigh's closed form needs a = 0).
        Err(_) => Ok(None),
        Ok((t, obs, stop)) => Ok(Some((
            t,
            obs,
            stop.map(|(te, why)| format!("closed form stops applying at t = {te}: {why}")),
        ))),
    }
}
