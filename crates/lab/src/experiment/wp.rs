//! Work-precision experiments (`kind = "work-precision"`): for every line
//! (a formulation with an integrator), a ladder of tolerances — or of step
//! counts for fixed-step methods — each run timed `repeats` times, its error
//! measured against the line's reference ([`super::reference`]) on the
//! output grid.
//!
//! Errors are in the coordinates `q` (largest over the coordinates, angles
//! modulo 2π): `err_end` at the last common time of run and reference,
//! `err_max` over the common grid; relative errors divide by the largest
//! `|q_k|` of the reference over the grid, and `scd = −log10` of the relative
//! error (significant correct digits). Cost: the median and the minimum of
//! the integration wall time over the repeats, and the counters of the
//! first repeat (they do not vary).
//!
//! Runs are timed one at a time on one thread, so that the timings are not
//! disturbed by each other. Results go to the experiment's directory:
//!
//! | file | content |
//! |---|---|
//! | `points/<i>.json` | one point: references and rows (reused when the configuration is unchanged) |
//! | `work_precision.csv` | one row per (point, line, ladder value) |
//! | `references.csv`, `references/<i>-<label>.csv` | what each reference is, its estimated error, its trajectory |
//! | `summary.json` | fitted slopes per line: error against evaluations (the observed order), time, tolerance; the cost spread (no order where evaluations vary by less than 2×: a line held by stability) |
//! | `plots/wp-<i>-*.png/svg`, `index.html`, `manifest.json` | figures, page, provenance |

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nonholo_core::RunStatus;
use nonholo_core::integrate::Method;
use serde::{Deserialize, Serialize};
use serde_json::json;
use sha2::{Digest, Sha256};

use super::output::{
    escape, load_points, median, num, point_path, write, write_json, write_manifest,
};
use super::reference::{Reference, ReferenceInfo, compute, q_error};
use super::spec::{Experiment, Ladder, RefSpec, compact};
use super::sweep::{Point, PointRun, resolve};
use super::{Outcome, RunOptions};
use crate::plot::{Cell, CellStatus, LinePlot, Series, StatusGrid, line_plot, status_grid};
use crate::simulate::{RunSpec, execute};

/// Schema of a work-precision point file.
pub const WP_SCHEMA: &str = "nonholo.wp-point/1";

/// One run of a ladder.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct WpRow {
    pub point: usize,
    pub label: String,
    pub formulation: String,
    pub integrator: String,
    /// Newton iteration of radau5 as run (`simplified` or `full`).
    pub radau_newton: Option<String>,
    /// `rtol = atol` of an adaptive run.
    pub tolerance: Option<f64>,
    /// Number of equal steps of a fixed-step run, and their size.
    pub step_count: Option<usize>,
    pub step: Option<f64>,
    /// `completed`, `stopped` (at a singular set, by design) or `failed`.
    pub status: String,
    pub error: Option<String>,
    pub error_t: Option<f64>,
    /// Last time of the common grid of run and reference.
    pub t_common_end: Option<f64>,
    pub err_end: Option<f64>,
    pub err_max: Option<f64>,
    pub rel_err_end: Option<f64>,
    pub rel_err_max: Option<f64>,
    pub scd_end: Option<f64>,
    pub scd_max: Option<f64>,
    pub wall_time_median_s: Option<f64>,
    pub wall_time_min_s: Option<f64>,
    pub repeats: usize,
    pub steps: usize,
    pub rejected_steps: usize,
    pub rhs_evals: usize,
    pub jacobian_evals: usize,
    pub lu_decompositions: usize,
    pub newton_failures: usize,
    pub constraint_residual_max: Option<f64>,
    pub energy_drift_max: Option<f64>,
    /// The reference's own estimated error (see [`ReferenceInfo`]).
    pub reference_error: Option<f64>,
}

/// The reference of one line at one point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RefRecord {
    pub label: String,
    /// `references/<point>-<label>.csv`, or why there is none.
    pub file: Option<String>,
    pub failure: Option<String>,
    pub info: Option<ReferenceInfo>,
}

/// One point of a work-precision experiment, as stored in `points/<i>.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WpPoint {
    pub schema: String,
    pub index: usize,
    pub values: Vec<String>,
    pub hash: String,
    pub references: Vec<RefRecord>,
    pub rows: Vec<WpRow>,
}

/// Hash of a point's resolved runs, ladders and repeats: a stored point is
/// reused only if the experiment still asks for the same computation.
fn hash(exp: &Experiment, runs: &[PointRun]) -> String {
    let ladders: Vec<_> = exp.formulations.iter().map(|f| &f.work_precision).collect();
    let mut h = Sha256::new();
    h.update(WP_SCHEMA.as_bytes());
    h.update(env!("CARGO_PKG_VERSION").as_bytes());
    h.update(format!("{runs:?}|{ladders:?}|{}", exp.repeats).as_bytes());
    h.finalize()
        .iter()
        .take(8)
        .map(|b| format!("{b:02x}"))
        .collect()
}

fn stored(dir: &Path, exp: &Experiment, point: &Point) -> Option<WpPoint> {
    let text = std::fs::read_to_string(point_path(dir, point.index)).ok()?;
    let r: WpPoint = serde_json::from_str(&text).ok()?;
    let complete = r.references.iter().all(|f| {
        f.file
            .as_ref()
            .is_none_or(|file| dir.join("references").join(file).exists())
    });
    (r.schema == WP_SCHEMA && r.hash == hash(exp, &resolve(exp, point).ok()?) && complete)
        .then_some(r)
}

/// Coordinates `(name, unit)` of the experiment's scene.
fn coordinates(exp: &Experiment) -> Result<Vec<(String, String)>, String> {
    let info = nonholo_scenes::info(&exp.scene).map_err(|e| e.to_string())?;
    Ok(info
        .coordinates
        .iter()
        .map(|c| (c.name.to_string(), c.unit.to_string()))
        .collect())
}

/// The ladder of a line as run specifications.
fn ladder_runs(base: &RunSpec, ladder: &Ladder) -> Vec<(Option<f64>, Option<usize>, RunSpec)> {
    match ladder {
        Ladder::Tolerances(tols) => tols
            .iter()
            .map(|&tol| {
                let mut s = base.clone();
                s.integrator.rtol = tol;
                s.integrator.atol = tol;
                s.integrator.fixed_step = None;
                (Some(tol), None, s)
            })
            .collect(),
        Ladder::Steps(counts) => counts
            .iter()
            .map(|&n| {
                let mut s = base.clone();
                s.integrator.fixed_step = Some(base.t_end / n as f64);
                (None, Some(n), s)
            })
            .collect(),
    }
}

/// Runs one ladder value `repeats` times and measures it against `reference`.
fn measure(
    point: usize,
    label: &str,
    (tolerance, step_count, spec): &(Option<f64>, Option<usize>, RunSpec),
    repeats: usize,
    reference: Option<&Reference>,
    coords: &[(String, String)],
) -> WpRow {
    let mut row = WpRow {
        point,
        label: label.into(),
        formulation: spec.formulation.clone(),
        integrator: spec.method.name().into(),
        radau_newton: None,
        tolerance: *tolerance,
        step_count: *step_count,
        step: spec.integrator.fixed_step,
        status: "failed".into(),
        error: None,
        error_t: None,
        t_common_end: None,
        err_end: None,
        err_max: None,
        rel_err_end: None,
        rel_err_max: None,
        scd_end: None,
        scd_max: None,
        wall_time_median_s: None,
        wall_time_min_s: None,
        repeats: 0,
        steps: 0,
        rejected_steps: 0,
        rhs_evals: 0,
        jacobian_evals: 0,
        lu_decompositions: 0,
        newton_failures: 0,
        constraint_residual_max: None,
        energy_drift_max: None,
        reference_error: reference.and_then(|r| r.info.error_estimate),
    };
    let mut walls = Vec::with_capacity(repeats);
    let mut first = None;
    for _ in 0..repeats {
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| execute(spec)));
        match outcome {
            Ok(Ok((run, _))) => {
                walls.push(run.solution.stats.wall_time_s);
                // A failed run is not repeated: its cost measures nothing.
                let failed = run.status() == RunStatus::Failed;
                if first.is_none() {
                    first = Some(run);
                }
                if failed {
                    break;
                }
            }
            Ok(Err(e)) => {
                row.error = Some(e.to_string());
                return row;
            }
            Err(_) => {
                row.error = Some("internal error (panic)".into());
                return row;
            }
        }
    }
    let Some(run) = first else { return row };
    row.repeats = walls.len();
    row.wall_time_min_s = walls.iter().copied().reduce(f64::min);
    row.wall_time_median_s = median(walls);
    if run.config.method.is_implicit() {
        row.radau_newton = Some(run.config.options.radau5.newton.name().into());
    }
    let st = &run.solution.stats;
    row.steps = st.steps;
    row.rejected_steps = st.rejected_steps;
    row.rhs_evals = st.rhs_evals;
    row.jacobian_evals = st.jacobian_evals;
    row.lu_decompositions = st.lu_decompositions;
    row.newton_failures = st.newton_failures;
    let finite = |v: f64| v.is_finite().then_some(v);
    row.constraint_residual_max = finite(run.diagnostics.constraint_residual_max);
    row.energy_drift_max = finite(run.diagnostics.energy_drift_max);
    row.status = run.status().as_str().into();
    row.error = run.failure.as_ref().map(|e| e.to_string());
    row.error_t = run.failure.as_ref().and_then(|e| e.time());
    if row.status == "failed" {
        return row;
    }
    let Some(reference) = reference else {
        return row;
    };
    let t = &run.solution.t[..run.samples.len()];
    let common = super::point::common_len(t, &reference.t);
    if common == 0 {
        return row;
    }
    let errs: Vec<f64> = (0..common)
        .map(|i| q_error(&run.samples[i], &reference.obs[i], coords))
        .collect();
    let scale = reference.obs[..common]
        .iter()
        .flat_map(|o| o.q.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(f64::MIN_POSITIVE);
    let err_end = errs[common - 1];
    let err_max = errs.iter().copied().fold(0.0, f64::max);
    if !(err_end.is_finite() && err_max.is_finite()) {
        row.status = "failed".into();
        row.error = Some("the error against the reference is not finite".into());
        return row;
    }
    row.t_common_end = Some(reference.t[common - 1]);
    row.err_end = Some(err_end);
    row.err_max = Some(err_max);
    row.rel_err_end = Some(err_end / scale);
    row.rel_err_max = Some(err_max / scale);
    let scd = |e: f64| finite(-(e / scale).log10());
    row.scd_end = scd(err_end);
    row.scd_max = scd(err_max);
    row
}

/// Writes a reference's trajectory: `t`, then `q`, then `q̇` columns.
fn write_reference(path: &Path, r: &Reference, coords: &[(String, String)]) -> Result<(), String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["t".to_string()];
    header.extend(coords.iter().map(|c| c.0.clone()));
    header.extend(coords.iter().map(|c| format!("{}_dot", c.0)));
    w.write_record(&header).map_err(|e| e.to_string())?;
    for (t, o) in r.t.iter().zip(&r.obs) {
        let mut rec = vec![t.to_string()];
        rec.extend(o.q.iter().chain(&o.qd).map(|v| v.to_string()));
        w.write_record(&rec).map_err(|e| e.to_string())?;
    }
    let bytes = w.into_inner().map_err(|e| e.to_string())?;
    write(path, &bytes)
}

/// Runs one point: references (shared by lines of the same physics), then
/// every line's ladder.
fn run_point(exp: &Experiment, point: &Point, dir: &Path, quiet: bool) -> Result<WpPoint, String> {
    let coords = coordinates(exp)?;
    let runs = resolve(exp, point)?;
    let at = compact(&exp.axes, &point.values);
    let at = if at.is_empty() { at } else { format!("{at}: ") };
    let mut cache: HashMap<String, Result<Reference, String>> = HashMap::new();
    let mut references = Vec::new();
    let mut rows = Vec::new();
    for (r, f) in runs.iter().zip(&exp.formulations) {
        let (ladder, refspec) = f
            .work_precision
            .as_ref()
            .ok_or_else(|| format!("{}: no work-precision ladder", r.label))?;
        let key = physics_key(&r.spec, refspec);
        let reference = cache
            .entry(key)
            .or_insert_with(|| compute(&r.spec, refspec, &coords))
            .clone();
        let record = match &reference {
            Ok(rf) => {
                let file = format!("{}-{}.csv", point.index, r.label);
                write_reference(&dir.join("references").join(&file), rf, &coords)?;
                RefRecord {
                    label: r.label.clone(),
                    file: Some(file),
                    failure: None,
                    info: Some(rf.info.clone()),
                }
            }
            Err(e) => RefRecord {
                label: r.label.clone(),
                file: None,
                failure: Some(e.clone()),
                info: None,
            },
        };
        references.push(record);
        for value in ladder_runs(&r.spec, ladder) {
            let row = measure(
                point.index,
                &r.label,
                &value,
                exp.repeats,
                reference.as_ref().ok(),
                &coords,
            );
            if !quiet {
                eprintln!(
                    "  {at}{} {}: {} {}, err_max {}, {} rhs, {:.3e} s",
                    r.label,
                    value
                        .0
                        .map(|t| format!("tol {t:e}"))
                        .or(value.1.map(|n| format!("{n} steps")))
                        .unwrap_or_default(),
                    row.status,
                    row.error
                        .as_deref()
                        .map(|e| format!("({e})"))
                        .unwrap_or_default(),
                    row.err_max
                        .map(|e| format!("{e:.3e}"))
                        .unwrap_or("—".into()),
                    row.rhs_evals,
                    row.wall_time_median_s.unwrap_or(f64::NAN)
                );
            }
            rows.push(row);
        }
    }
    Ok(WpPoint {
        schema: WP_SCHEMA.into(),
        index: point.index,
        values: point.values.clone(),
        hash: hash(exp, &runs),
        references,
        rows,
    })
}

/// Lines with the same formulation, scene, options, initial data and
/// reference settings share one reference.
fn physics_key(spec: &RunSpec, r: &RefSpec) -> String {
    format!(
        "{}|{}|{:?}|{:?}|{:?}|{}|{:?}|{:?}",
        spec.scene,
        spec.formulation,
        spec.params,
        spec.init,
        spec.options,
        spec.t_end,
        spec.integrator.output,
        r
    )
}

/// Runs a work-precision experiment (see the module documentation).
pub fn run(exp: &Experiment, opts: &RunOptions) -> Result<Outcome, String> {
    let started = std::time::SystemTime::now();
    let dir = &opts.out_dir;
    super::prepare_dir(dir, &["points", "references", "plots"])?;
    let mut points = Vec::new();
    let mut reused = 0;
    let all = exp.points();
    for p in &all {
        if !opts.force
            && let Some(r) = stored(dir, exp, p)
        {
            reused += 1;
            points.push(r);
            continue;
        }
        if !opts.quiet {
            eprintln!("{}: point {} of {}", exp.name, p.index + 1, all.len());
        }
        let r = run_point(exp, p, dir, opts.quiet)?;
        write_json(&point_path(dir, p.index), &r)?;
        points.push(r);
    }
    write_tables(exp, dir, &points)?;
    let plots = draw(exp, dir, &points)?;
    write_summary(exp, dir, &points)?;
    write_html(exp, dir, &points, &plots)?;
    write_manifest(exp, dir, started, 1)?;
    let rows = points.iter().flat_map(|p| &p.rows);
    let count = |s: &str| rows.clone().filter(|r| r.status == s).count();
    Ok(Outcome {
        dir: dir.clone(),
        points: points.len(),
        reused,
        failed_runs: count("failed"),
        stopped_runs: count("stopped"),
        runs: rows.clone().count(),
        plots,
    })
}

/// The stored points of `exp` in `dir` (for `nonholo plot`).
pub fn load(exp: &Experiment, dir: &Path) -> Result<Vec<WpPoint>, String> {
    load_points(exp, dir)
}

/// `work_precision.csv` and `references.csv`.
fn write_tables(exp: &Experiment, dir: &Path, points: &[WpPoint]) -> Result<(), String> {
    let axes: Vec<String> = exp.axes.iter().map(|a| a.name.clone()).collect();
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["point".to_string()];
    header.extend(axes.iter().cloned());
    header.extend(
        [
            "label",
            "formulation",
            "integrator",
            "radau_newton",
            "tolerance",
            "step_count",
            "step",
            "status",
            "t_common_end",
            "err_end",
            "err_max",
            "rel_err_end",
            "rel_err_max",
            "scd_end",
            "scd_max",
            "wall_time_median_s",
            "wall_time_min_s",
            "repeats",
            "steps",
            "rejected_steps",
            "rhs_evals",
            "jacobian_evals",
            "lu_decompositions",
            "newton_failures",
            "constraint_residual_max",
            "energy_drift_max",
            "reference_error",
            "error_t",
            "error",
        ]
        .map(String::from),
    );
    w.write_record(&header).map_err(|e| e.to_string())?;
    for p in points {
        for r in &p.rows {
            let mut rec = vec![p.index.to_string()];
            rec.extend(p.values.iter().cloned());
            rec.extend([
                r.label.clone(),
                r.formulation.clone(),
                r.integrator.clone(),
                r.radau_newton.clone().unwrap_or_default(),
                num(r.tolerance),
                r.step_count.map(|n| n.to_string()).unwrap_or_default(),
                num(r.step),
                r.status.clone(),
                num(r.t_common_end),
                num(r.err_end),
                num(r.err_max),
                num(r.rel_err_end),
                num(r.rel_err_max),
                num(r.scd_end),
                num(r.scd_max),
                num(r.wall_time_median_s),
                num(r.wall_time_min_s),
                r.repeats.to_string(),
                r.steps.to_string(),
                r.rejected_steps.to_string(),
                r.rhs_evals.to_string(),
                r.jacobian_evals.to_string(),
                r.lu_decompositions.to_string(),
                r.newton_failures.to_string(),
                num(r.constraint_residual_max),
                num(r.energy_drift_max),
                num(r.reference_error),
                num(r.error_t),
                r.error.clone().unwrap_or_default(),
            ]);
            w.write_record(&rec).map_err(|e| e.to_string())?;
        }
    }
    write(
        &dir.join("work_precision.csv"),
        &w.into_inner().map_err(|e| e.to_string())?,
    )?;

    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["point".to_string()];
    header.extend(axes.iter().cloned());
    header.extend(
        [
            "label",
            "kind",
            "integrator",
            "rtol",
            "check_integrator",
            "check_rtol",
            "error_estimate",
            "error_estimate_end",
            "t_last",
            "stop",
            "check_failure",
            "wall_time_s",
            "file",
            "failure",
        ]
        .map(String::from),
    );
    w.write_record(&header).map_err(|e| e.to_string())?;
    for p in points {
        for r in &p.references {
            let mut rec = vec![p.index.to_string()];
            rec.extend(p.values.iter().cloned());
            let i = r.info.as_ref();
            rec.extend([
                r.label.clone(),
                i.map(|i| i.kind.clone()).unwrap_or_default(),
                i.and_then(|i| i.integrator.clone()).unwrap_or_default(),
                num(i.and_then(|i| i.rtol)),
                i.and_then(|i| i.check_integrator.clone())
                    .unwrap_or_default(),
                num(i.and_then(|i| i.check_rtol)),
                num(i.and_then(|i| i.error_estimate)),
                num(i.and_then(|i| i.error_estimate_end)),
                num(i.map(|i| i.t_last)),
                i.and_then(|i| i.stop.clone()).unwrap_or_default(),
                i.and_then(|i| i.check_failure.clone()).unwrap_or_default(),
                num(i.map(|i| i.wall_time_s)),
                r.file.clone().unwrap_or_default(),
                r.failure.clone().unwrap_or_default(),
            ]);
            w.write_record(&rec).map_err(|e| e.to_string())?;
        }
    }
    write(
        &dir.join("references.csv"),
        &w.into_inner().map_err(|e| e.to_string())?,
    )
}

/// Least-squares slope of `ln y` against `ln x` over positive finite pairs
/// (`None` with fewer than three).
pub fn log_slope(x: &[f64], y: &[f64]) -> Option<f64> {
    let pts: Vec<(f64, f64)> = x
        .iter()
        .zip(y)
        .filter(|(a, b)| a.is_finite() && b.is_finite() && **a > 0.0 && **b > 0.0)
        .map(|(a, b)| (a.ln(), b.ln()))
        .collect();
    if pts.len() < 3 {
        return None;
    }
    let n = pts.len() as f64;
    let (mx, my) = pts
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let sxy: f64 = pts.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = pts.iter().map(|(x, _)| (x - mx).powi(2)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// The rows of a line that enter the fits: finished runs whose error stands
/// clear of the reference's own error (ten times above it) and of round-off.
fn fit_rows<'a>(p: &'a WpPoint, label: &str) -> Vec<&'a WpRow> {
    p.rows
        .iter()
        .filter(|r| r.label == label && r.status != "failed")
        .filter(|r| {
            r.err_max.is_some_and(|e| {
                e > 10.0 * r.reference_error.unwrap_or(0.0) && r.rel_err_max.unwrap_or(0.0) > 1e-14
            })
        })
        .collect()
}

/// Fitted slopes of one line at one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Slopes {
    /// `−d ln err_max / d ln rhs_evals`: the observed order (`None` when the
    /// cost hardly moves over the ladder, see [`MIN_COST_SPREAD`]).
    pub order: Option<f64>,
    /// `d ln err_max / d ln wall time` (same condition).
    pub time: Option<f64>,
    /// `d ln err_max / d ln tolerance` (1 = tolerance proportionality).
    pub tolerance: Option<f64>,
    /// Largest over smallest right-hand-side evaluations among the fitted
    /// runs: near 1 when stability, not accuracy, sets the step size.
    pub cost_spread: Option<f64>,
    pub fitted: usize,
}

/// An order is fitted only where the evaluations over the fitted runs span
/// at least this factor. An explicit method held by stability takes the
/// same steps at every tolerance while its error falls, and the fitted
/// "order" of such a line is a meaningless large number.
pub const MIN_COST_SPREAD: f64 = 2.0;

pub fn slopes(p: &WpPoint, label: &str) -> Slopes {
    let rows = fit_rows(p, label);
    let err: Vec<f64> = rows.iter().map(|r| r.err_max.unwrap_or(f64::NAN)).collect();
    let col = |f: &dyn Fn(&WpRow) -> Option<f64>| -> Vec<f64> {
        rows.iter().map(|r| f(r).unwrap_or(f64::NAN)).collect()
    };
    let evals = col(&|r| Some(r.rhs_evals as f64));
    let spread = |x: &[f64]| {
        let pos = x.iter().filter(|v| v.is_finite() && **v > 0.0);
        let (lo, hi) = pos.fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(*v), hi.max(*v))
        });
        (hi > 0.0).then(|| hi / lo)
    };
    let cost_spread = spread(&evals);
    let moves = cost_spread.is_some_and(|s| s >= MIN_COST_SPREAD);
    Slopes {
        order: log_slope(&evals, &err).map(|s| -s).filter(|_| moves),
        time: log_slope(&col(&|r| r.wall_time_median_s), &err).filter(|_| moves),
        tolerance: log_slope(&col(&|r| r.tolerance), &err),
        cost_spread,
        fitted: rows.len(),
    }
}

fn write_summary(exp: &Experiment, dir: &Path, points: &[WpPoint]) -> Result<(), String> {
    let lines: Vec<_> = points
        .iter()
        .flat_map(|p| {
            exp.formulations.iter().map(move |f| {
                let s = slopes(p, &f.label);
                let rows: Vec<&WpRow> = p.rows.iter().filter(|r| r.label == f.label).collect();
                let reference = p.references.iter().find(|r| r.label == f.label);
                json!({
                    "point": p.index,
                    "values": p.values,
                    "label": f.label,
                    "formulation": f.formulation,
                    "integrator": f.settings.integrator,
                    "method_order": Method::from_name(&f.settings.integrator).map(|m| m.order()),
                    "observed_order": s.order,
                    "slope_error_vs_time": s.time,
                    "slope_error_vs_tolerance": s.tolerance,
                    "points_fitted": s.fitted,
                    "cost_spread": s.cost_spread,
                    "runs": rows.len(),
                    "failed": rows.iter().filter(|r| r.status == "failed").count(),
                    "best_scd_max": rows.iter().filter_map(|r| r.scd_max).reduce(f64::max),
                    "reference": reference.and_then(|r| r.info.as_ref()).map(|i| json!({
                        "kind": i.kind,
                        "error_estimate": i.error_estimate,
                    })),
                    "reference_failure": reference.and_then(|r| r.failure.clone()),
                })
            })
        })
        .collect();
    write_json(
        &dir.join("summary.json"),
        &json!({
            "schema": "nonholo.wp-summary/1",
            "experiment": exp.name,
            "title": exp.title,
            "claim": exp.claim,
            "kind": "work-precision",
            "repeats": exp.repeats,
            "axes": exp.axes.iter().map(|a| a.name.clone()).collect::<Vec<_>>(),
            "lines": lines,
        }),
    )
}

/// `(stem, what, x label, x, y, legend shows the observed order)`.
type PlotSpec<'a> = (
    &'a str,
    &'a str,
    &'a str,
    &'a dyn Fn(&WpRow) -> Option<f64>,
    &'a dyn Fn(&WpRow) -> Option<f64>,
    bool,
);

/// The plots of every point: error (max over the grid, at the end) against
/// median wall time and against right-hand-side evaluations, and error
/// against tolerance.
pub fn draw(exp: &Experiment, dir: &Path, points: &[WpPoint]) -> Result<Vec<PathBuf>, String> {
    let mut files = Vec::new();
    for p in points {
        let at = compact(&exp.axes, &p.values);
        let series = |x: &dyn Fn(&WpRow) -> Option<f64>,
                      y: &dyn Fn(&WpRow) -> Option<f64>,
                      with_order: bool| {
            exp.formulations
                .iter()
                .map(|f| {
                    let rows: Vec<&WpRow> = p
                        .rows
                        .iter()
                        .filter(|r| r.label == f.label && r.status != "failed")
                        .collect();
                    let mut pts: Vec<(f64, f64)> = rows
                        .iter()
                        .map(|r| (x(r).unwrap_or(f64::NAN), y(r).unwrap_or(f64::NAN)))
                        .collect();
                    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                    let s = slopes(p, &f.label);
                    let mut label = line_name(f);
                    if with_order {
                        match (s.order, s.cost_spread) {
                            (Some(o), _) => label.push_str(&format!(" (order {o:.1})")),
                            (None, Some(c)) if s.fitted >= 3 && c < MIN_COST_SPREAD => {
                                label.push_str(" (cost flat over the ladder)")
                            }
                            _ => {}
                        }
                    }
                    Series {
                        label,
                        x: pts.iter().map(|q| q.0).collect(),
                        y: pts.iter().map(|q| q.1).collect(),
                    }
                })
                .collect::<Vec<_>>()
        };
        let title = |what: &str| {
            if at.is_empty() {
                format!("{}: {what}", exp.title)
            } else {
                format!("{what}, {at}")
            }
        };
        let plots: [PlotSpec; 5] = [
            (
                "max-time",
                "max error over the grid vs time",
                "median wall time [s]",
                &|r| r.wall_time_median_s,
                &|r| r.err_max,
                false,
            ),
            (
                "end-time",
                "error at the end vs time",
                "median wall time [s]",
                &|r| r.wall_time_median_s,
                &|r| r.err_end,
                false,
            ),
            (
                "max-evals",
                "max error over the grid vs evaluations",
                "right-hand-side evaluations",
                &|r| Some(r.rhs_evals as f64),
                &|r| r.err_max,
                true,
            ),
            (
                "end-evals",
                "error at the end vs evaluations",
                "right-hand-side evaluations",
                &|r| Some(r.rhs_evals as f64),
                &|r| r.err_end,
                true,
            ),
            (
                "tolerance",
                "max error over the grid vs tolerance",
                "tolerance rtol = atol",
                &|r| r.tolerance,
                &|r| r.err_max,
                false,
            ),
        ];
        for (stem, what, x_label, x, y, with_order) in plots {
            if stem == "tolerance" && p.rows.iter().all(|r| r.tolerance.is_none()) {
                continue;
            }
            let plot = LinePlot {
                title: title(what),
                x_label: x_label.into(),
                y_label: "error in q (max over coordinates)".into(),
                log_x: true,
                log_y: true,
                equal_aspect: false,
                series: series(x, y, with_order),
            };
            files.extend(line_plot(
                &plot,
                &dir.join("plots").join(format!("wp-{}-{stem}", p.index)),
            )?);
        }
    }
    if points.len() >= 2 {
        files.extend(stability_map(exp, dir, points)?);
    }
    Ok(files)
}

/// The row name of a point: its `case` value if the sweep has one, else the
/// swept values.
fn case_name(exp: &Experiment, p: &WpPoint) -> String {
    exp.axes
        .iter()
        .position(|a| a.name == "case")
        .and_then(|i| p.values.get(i).cloned())
        .unwrap_or_else(|| compact(&exp.axes, &p.values))
}

/// The stability map: points (cases) × lines, each cell the run at the
/// line's finest rung — completed (with its correct digits), stopped at a
/// singular set, or failed (with the time reached).
fn stability_map(exp: &Experiment, dir: &Path, points: &[WpPoint]) -> Result<Vec<PathBuf>, String> {
    let cells = points
        .iter()
        .map(|p| {
            exp.formulations
                .iter()
                .map(|f| {
                    let Some(r) = p.rows.iter().rev().find(|r| r.label == f.label) else {
                        return Cell {
                            status: CellStatus::Missing,
                            text: String::new(),
                        };
                    };
                    let at = |t: Option<f64>| t.map(|t| format!(" t={t:.3}")).unwrap_or_default();
                    match r.status.as_str() {
                        "completed" => Cell {
                            status: CellStatus::Completed,
                            text: r.scd_max.map(|d| format!("{d:.1}")).unwrap_or("—".into()),
                        },
                        "stopped" => Cell {
                            status: CellStatus::Stopped,
                            text: format!(
                                "{}{}",
                                r.scd_max.map(|d| format!("{d:.1},")).unwrap_or_default(),
                                at(r.error_t)
                            ),
                        },
                        _ => Cell {
                            status: CellStatus::Failed,
                            text: format!("fail{}", at(r.error_t)),
                        },
                    }
                })
                .collect()
        })
        .collect();
    status_grid(
        &StatusGrid {
            title: format!("{}: stability map", exp.title),
            rows: points.iter().map(|p| case_name(exp, p)).collect(),
            columns: exp.formulations.iter().map(|f| f.label.clone()).collect(),
            cells,
            note:
                "numbers: correct digits −log10(max |Δq| / max |q|) against the line's reference, \
                   finest rung; t: where a run stopped or failed (reasons in work_precision.csv); \
                   lines: see index.html or work_precision.csv for formulation, integrator, options"
                    .into(),
        },
        &dir.join("plots").join("stability-map"),
    )
}

/// `label: formulation · integrator` (with the Newton iteration if chosen).
fn line_name(f: &super::spec::FormulationSpec) -> String {
    let mut s = format!("{}: {} · {}", f.label, f.formulation, f.settings.integrator);
    if f.settings.integrator == "radau5" && f.settings.radau_newton != "auto" {
        s.push_str(&format!(" ({} Newton)", f.settings.radau_newton));
    }
    s
}

/// Caption of a work-precision plot from its stem.
pub fn caption(exp: &Experiment, stem: &str) -> String {
    if stem == "stability-map" {
        return "Stability map: every point (case) against every line at its finest rung — green: \
                completed, with its correct digits; amber: stopped at a singular set (by design), \
                with the time; red: failed, with the time (the message is in work_precision.csv); \
                grey: not run."
            .into();
    }
    let mut parts = stem.splitn(3, '-');
    let (_, point, what) = (parts.next(), parts.next(), parts.next().unwrap_or(""));
    let point = point.unwrap_or("0");
    let common = format!(
        "Point {point}; error = largest |q_k − q_ref,k| over the coordinates (angles modulo 2π) against the line's reference (references.csv gives each reference and its own estimated error); one dot per ladder value; failed runs left out; {} timed repeats, median.",
        exp.repeats
    );
    match what {
        "max-time" => {
            format!("Largest error over the output grid against median wall time. {common}")
        }
        "end-time" => format!("Error at the last common time against median wall time. {common}"),
        "max-evals" => format!(
            "Largest error over the output grid against right-hand-side evaluations (Radau IIA: stage evaluations; Jacobians not counted); legend: observed order, the fitted slope. {common}"
        ),
        "end-evals" => format!(
            "Error at the last common time against right-hand-side evaluations; legend: observed order. {common}"
        ),
        "tolerance" => format!(
            "Largest error against the requested tolerance (slope 1: tolerance proportionality). {common}"
        ),
        other => other.to_string(),
    }
}

fn write_html(
    exp: &Experiment,
    dir: &Path,
    points: &[WpPoint],
    plots: &[PathBuf],
) -> Result<(), String> {
    let mut h = String::new();
    let _ = write!(
        h,
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\n\
         <style>body{{font-family:sans-serif;max-width:1200px;margin:auto;padding:1em}}\
         table{{border-collapse:collapse;font-size:0.8em}}td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}\
         figure{{margin:1.5em 0}}img{{max-width:100%}}figcaption{{color:#333}}</style></head><body>\n",
        escape(&exp.title)
    );
    let _ = writeln!(
        h,
        "<h1>{}</h1>\n<p><b>Claim tested:</b> {}</p>\n<p>{}</p>\n<p>Files: \
         <a href=\"work_precision.csv\">work_precision.csv</a>, \
         <a href=\"references.csv\">references.csv</a>, <a href=\"summary.json\">summary.json</a>, \
         <a href=\"manifest.json\">manifest.json</a>.</p>",
        escape(&exp.title),
        escape(&exp.claim),
        escape(&exp.description)
    );
    let _ = writeln!(
        h,
        "<h2>Observed orders</h2>\n<table><tr><th>point</th><th>line</th><th>method order</th><th>observed order</th><th>error vs tolerance slope</th><th>cost spread (max/min evaluations)</th><th>points fitted</th></tr>"
    );
    for p in points {
        for f in &exp.formulations {
            let s = slopes(p, &f.label);
            let fmt = |v: Option<f64>| v.map(|x| format!("{x:.2}")).unwrap_or("—".into());
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                p.index,
                escape(&line_name(f)),
                Method::from_name(&f.settings.integrator)
                    .map(|m| m.order().to_string())
                    .unwrap_or_default(),
                fmt(s.order),
                fmt(s.tolerance),
                fmt(s.cost_spread),
                s.fitted
            );
        }
    }
    let _ = writeln!(h, "</table>");
    for p in plots
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
    {
        let rel = p.strip_prefix(dir).unwrap_or(p).display().to_string();
        let stem = p
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default();
        let _ = writeln!(
            h,
            "<figure><img src=\"{rel}\" alt=\"{stem}\"><figcaption>{}</figcaption></figure>",
            escape(&caption(exp, &stem))
        );
    }
    for (title, file) in [
        ("References", "references.csv"),
        ("Runs", "work_precision.csv"),
    ] {
        let _ = writeln!(h, "<h2>{title}</h2>\n<table>");
        if let Ok(text) = std::fs::read_to_string(dir.join(file)) {
            for (i, line) in csv::ReaderBuilder::new()
                .has_headers(false)
                .from_reader(text.as_bytes())
                .records()
                .flatten()
                .enumerate()
            {
                let tag = if i == 0 { "th" } else { "td" };
                let cells: String = line
                    .iter()
                    .map(|c| format!("<{tag}>{}</{tag}>", escape(c)))
                    .collect();
                let _ = writeln!(h, "<tr>{cells}</tr>");
            }
        }
        let _ = writeln!(h, "</table>");
    }
    let _ = writeln!(h, "</body></html>");
    write(&dir.join("index.html"), h.as_bytes())
}

/// Redraws the figures and the page from stored points (`nonholo plot`).
pub fn redraw(exp: &Experiment, dir: &Path) -> Result<Vec<PathBuf>, String> {
    let points = load(exp, dir)?;
    let plots = draw(exp, dir, &points)?;
    write_html(exp, dir, &points, &plots)?;
    Ok(plots)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(rows: &[(f64, usize, f64)]) -> WpPoint {
        WpPoint {
            schema: WP_SCHEMA.into(),
            index: 0,
            values: vec![],
            hash: String::new(),
            references: vec![],
            rows: rows
                .iter()
                .map(|&(tol, evals, err)| WpRow {
                    label: "l".into(),
                    status: "completed".into(),
                    tolerance: Some(tol),
                    rhs_evals: evals,
                    err_max: Some(err),
                    rel_err_max: Some(err),
                    wall_time_median_s: Some(evals as f64 * 1e-6),
                    ..WpRow::default()
                })
                .collect(),
        }
    }

    /// err = C·evals^−5 gives order 5 and time slope −5; err = tol gives a
    /// tolerance slope of 1.
    #[test]
    fn slopes_of_an_exact_power_law() {
        let rows: Vec<_> = (0..6)
            .map(|i| {
                let evals = 100usize << i;
                let err = 1e10 * (evals as f64).powi(-5);
                (err, evals, err)
            })
            .collect();
        let s = slopes(&point(&rows), "l");
        assert!((s.order.unwrap() - 5.0).abs() < 1e-9);
        assert!((s.time.unwrap() + 5.0).abs() < 1e-9);
        assert!((s.tolerance.unwrap() - 1.0).abs() < 1e-9);
        assert_eq!(s.cost_spread, Some(32.0));
        assert_eq!(s.fitted, 6);
    }

    /// A line held by stability (same evaluations at every tolerance, error
    /// falling) has no order, but keeps its tolerance slope and spread.
    #[test]
    fn no_order_where_the_cost_does_not_move() {
        let rows: Vec<_> = (0..6)
            .map(|i| {
                let tol = 10f64.powi(-4 - i);
                (tol, 9000 + 10 * i as usize, tol)
            })
            .collect();
        let s = slopes(&point(&rows), "l");
        assert_eq!(s.order, None);
        assert_eq!(s.time, None);
        assert!((s.tolerance.unwrap() - 1.0).abs() < 1e-9);
        assert!(s.cost_spread.unwrap() < MIN_COST_SPREAD);
    }
}
