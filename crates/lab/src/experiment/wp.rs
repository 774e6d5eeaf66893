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
//! disturbed by each other, and interleaved: every ladder value of every
//! line runs once (and is measured), then each further round of repeats
//! times every value once more, so a change in the machine's speed during
//! a point falls on all lines alike. Results go to the experiment's directory:
//!
//! | file | content |
//! |---|---|
//! | `points/<i>.json` | one point: references and rows (reused when the configuration is unchanged) |
//! | `work_precision.csv` | one row per (point, line, ladder value) |
//! | `references.csv`, `references/<i>-<label>.csv` | what each reference is, its estimated error, its trajectory |
//! | `summary.json` | fitted slopes per line: error against evaluations (the observed order), time, tolerance; the cost spread (no order where evaluations vary by less than 2×: a line held by stability) |
//! | `plots/wp-<i>-*.png/svg`, `index.html`, `manifest.json` | figures, page, provenance |
//!
//! This module runs the ladders; `wp/output.rs` writes the tables, fits the
//! slopes and writes the summary and the page, `wp/plots.rs` draws the
//! figures (through the pipeline both kinds share, see [`super`]).

mod output;
mod plots;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nonholo_core::RunStatus;
use nonholo_core::integrate::IntegrateError;
use serde::{Deserialize, Serialize};

pub use self::output::{MIN_COST_SPREAD, Slopes, log_slope, slopes};
pub use self::plots::{caption, draw};
use super::files::{StoredPoint, load_points, point_path, write_json};
use super::key::point_key;
use super::manifest::write_manifest;
use super::output::median;
use super::reference::{Reference, ReferenceInfo, compute, q_error};
use super::spec::{Experiment, Ladder, RefSpec, compact};
use super::sweep::{Point, resolve};
use super::{Outcome, ResultsDir, RunOptions};
use crate::CliError;
use crate::record::Counters;
use crate::simulate::{RunSpec, execute};
use crate::table::{StateRow, Table, state_header};

/// Schema of a work-precision point file.
pub const WP_SCHEMA: &str = "nonholo.wp-point/1";

/// What a point of a work-precision experiment stores: every line's
/// reference and every run of its ladder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Ladders {
    pub references: Vec<RefRecord>,
    pub rows: Vec<WpRow>,
}

/// One point of a work-precision experiment, as stored in `points/<i>.json`.
pub type WpPoint = StoredPoint<Ladders>;

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
    #[serde(flatten)]
    pub counters: Counters,
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

/// The stored result of `point`, if it is complete and for the same computation.
fn stored(dir: &Path, exp: &Experiment, point: &Point) -> Option<WpPoint> {
    let key = point_key(exp, point, WP_SCHEMA).ok()?;
    let r: WpPoint = super::files::stored(dir, point.index, WP_SCHEMA, &key)?;
    let complete = r.body.references.iter().all(|f| {
        f.file
            .as_ref()
            .is_none_or(|file| dir.join("references").join(file).exists())
    });
    complete.then_some(r)
}

/// Coordinates `(name, unit)` of the experiment's scene.
fn coordinates(exp: &Experiment) -> Result<Vec<(String, String)>, String> {
    let info = exp.scene_info()?;
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

/// A ladder value after its first run: the measured row, the spec to time
/// again and the wall times so far.
struct Timed<'a> {
    row: WpRow,
    spec: &'a RunSpec,
    walls: Vec<f64>,
    /// Timed again in the next round: its runs so far completed or stopped.
    again: bool,
}

impl Timed<'_> {
    /// One more timed run; a run that fails or stops on its wall-time
    /// budget ends the repeats (its cost measures nothing).
    fn repeat(&mut self) {
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| execute(self.spec)));
        self.again = false;
        if let Ok(Ok((run, _))) = outcome {
            self.walls.push(run.solution.stats.wall_time_s);
            self.again = run.status() != RunStatus::Failed;
        }
    }

    /// The row with the median and the least of the wall times.
    fn finish(mut self) -> WpRow {
        if !self.walls.is_empty() {
            self.row.repeats = self.walls.len();
            self.row.wall_time_min_s = self.walls.iter().copied().reduce(f64::min);
            self.row.wall_time_median_s = median(self.walls);
        }
        self.row
    }
}

/// Runs one ladder value once and measures it against `reference`; the
/// caller times the repeats ([`Timed::repeat`]).
fn measure<'a>(
    point: usize,
    label: &str,
    (tolerance, step_count, spec): &'a (Option<f64>, Option<usize>, RunSpec),
    reference: Option<&Reference>,
    coords: &[(String, String)],
) -> Timed<'a> {
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
        counters: Counters::default(),
        constraint_residual_max: None,
        energy_drift_max: None,
        reference_error: reference.and_then(|r| r.info.error_estimate),
    };
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| execute(spec)));
    let run = match outcome {
        Ok(Ok((run, _))) => run,
        Ok(Err(e)) => {
            row.error = Some(e.to_string());
            return Timed {
                row,
                spec,
                walls: Vec::new(),
                again: false,
            };
        }
        Err(_) => {
            row.error = Some("internal error (panic)".into());
            return Timed {
                row,
                spec,
                walls: Vec::new(),
                again: false,
            };
        }
    };
    let walls = vec![run.solution.stats.wall_time_s];
    // A failed run is not repeated: its cost measures nothing.
    let again = run.status() != RunStatus::Failed;
    let row = measured(row, &run, reference, coords);
    Timed {
        row,
        spec,
        walls,
        again,
    }
}

/// `row` filled from its first run `run`: counters, diagnostics and the
/// error against `reference` on the common output grid.
fn measured(
    mut row: WpRow,
    run: &nonholo_core::Run,
    reference: Option<&Reference>,
    coords: &[(String, String)],
) -> WpRow {
    if let Some(IntegrateError::TimeBudgetExceeded { seconds, .. }) = &run.failure {
        // Where it stopped depends on the machine: no time, no counter.
        row.error = Some(super::wall_time_stop(*seconds));
        return row;
    }
    if run.config.method.is_implicit() {
        row.radau_newton = Some(run.config.options.radau5.newton.name().into());
    }
    let st = &run.solution.stats;
    row.counters = Counters::from(st);
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
    row.rel_err_end = finite(err_end / scale);
    row.rel_err_max = finite(err_max / scale);
    let scd = |e: f64| finite(-(e / scale).log10());
    row.scd_end = scd(err_end);
    row.scd_max = scd(err_max);
    row
}

/// Writes a reference's trajectory: `t`, then `q`, then `q̇` columns.
fn write_reference(path: &Path, r: &Reference, coords: &[(String, String)]) -> Result<(), String> {
    let mut table = Table::new(state_header(coords.iter().map(|c| c.0.as_str()), []))?;
    for (t, o) in r.t.iter().zip(&r.obs) {
        table.push_state(&StateRow {
            t: *t,
            q: &o.q,
            q_dot: &o.qd,
            more: &[],
        })?;
    }
    table.write(path)
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
    let mut lines = Vec::new();
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
        lines.push((&r.label, ladder_runs(&r.spec, ladder), reference));
    }
    // Every ladder value is run and measured once, line after line; then
    // the repeats are timed in rounds, each round timing every value once,
    // so that a change in the machine's speed during the point falls on
    // every line alike.
    let mut timed: Vec<Timed> = Vec::new();
    for (label, values, reference) in &lines {
        for value in values {
            let t = measure(point.index, label, value, reference.as_ref().ok(), &coords);
            if !quiet {
                let row = &t.row;
                crate::note!(
                    "  {at}{} {}: {} {}, err_max {}, {} rhs, {:.3e} s",
                    label,
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
                    row.counters.rhs_evals,
                    t.walls.first().copied().unwrap_or(f64::NAN)
                );
            }
            timed.push(t);
        }
    }
    for _ in 1..exp.repeats {
        for t in timed.iter_mut().filter(|t| t.again) {
            t.repeat();
        }
    }
    let rows = timed.into_iter().map(Timed::finish).collect();
    Ok(WpPoint {
        schema: WP_SCHEMA.into(),
        index: point.index,
        values: point.values.clone(),
        hash: point_key(exp, point, WP_SCHEMA)?,
        body: Ladders { references, rows },
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
pub fn run(exp: &Experiment, opts: &RunOptions, out: ResultsDir) -> Result<Outcome, CliError> {
    let started = std::time::SystemTime::now();
    let dir = &out.path().to_path_buf();
    out.prepare(&["points", "references", "plots"])?;
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
            crate::note!("{}: point {} of {}", exp.name, p.index + 1, all.len());
        }
        let r = run_point(exp, p, dir, opts.quiet).map_err(CliError::Output)?;
        write_json(&point_path(dir, p.index), &r).map_err(CliError::Output)?;
        points.push(r);
    }
    let written = (|| {
        output::write_tables(exp, dir, &points)?;
        let plots = draw(exp, dir, &points)?;
        output::write_summary(exp, dir, &points)?;
        output::write_html(exp, dir, &points, &plots)?;
        write_manifest(exp, dir, started, 1)?;
        Ok::<_, String>(plots)
    })();
    let plots = written.map_err(CliError::Output)?;
    out.finish();
    let rows = points.iter().flat_map(|p| &p.body.rows);
    let count = |s: &str| rows.clone().filter(|r| r.status == s).count();
    Ok(Outcome {
        dir: dir.clone(),
        points: points.len(),
        reused,
        failed_runs: count("failed"),
        stopped_runs: count("stopped"),
        budget_runs: rows
            .clone()
            .filter(|r| r.status == "failed" && super::budget_stop(r.error.as_deref()))
            .count(),
        runs: rows.clone().count(),
        failed_references: points
            .iter()
            .flat_map(|p| &p.body.references)
            .filter(|r| r.failure.is_some())
            .count(),
        plots,
    })
}

/// The stored points of `exp` in `dir` (for `nonholo plot`).
pub fn load(exp: &Experiment, dir: &Path) -> Result<Vec<WpPoint>, String> {
    load_points(exp, dir, WP_SCHEMA)
}

/// Redraws the figures and the page from stored points (`nonholo plot`):
/// stale or missing results are refused (exit 2) before anything is drawn.
pub fn redraw(exp: &Experiment, out: ResultsDir) -> Result<Vec<PathBuf>, CliError> {
    let dir = &out.path().to_path_buf();
    let points = load(exp, dir).map_err(CliError::Input)?;
    let written = (|| {
        let plots = draw(exp, dir, &points)?;
        output::write_html(exp, dir, &points, &plots)?;
        Ok::<_, String>(plots)
    })();
    let plots = written.map_err(CliError::Output)?;
    out.finish();
    Ok(plots)
}
