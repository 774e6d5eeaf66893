//! The result files of a work-precision experiment: `work_precision.csv`,
//! `references.csv`, the fitted slopes in `summary.json`, the page.

use std::path::{Path, PathBuf};

use nonholo_core::integrate::Method;
use serde::Serialize;
use serde_json::json;

use super::plots::line_name;
use super::{RefRecord, WpPoint, WpRow, caption};
use crate::experiment::files::write_json;
use crate::experiment::page::Page;
use crate::experiment::spec::Experiment;
use crate::record::Counters;
use crate::table::{self, Table, plain_opt};

/// A row of `work_precision.csv` (after the point and its swept values).
#[derive(Default, Serialize)]
struct RunRow<'a> {
    label: &'a str,
    formulation: &'a str,
    integrator: &'a str,
    radau_newton: Option<&'a str>,
    #[serde(serialize_with = "plain_opt")]
    tolerance: Option<f64>,
    step_count: Option<usize>,
    #[serde(serialize_with = "plain_opt")]
    step: Option<f64>,
    status: &'a str,
    #[serde(serialize_with = "plain_opt")]
    t_common_end: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    err_end: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    err_max: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    rel_err_end: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    rel_err_max: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    scd_end: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    scd_max: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    wall_time_median_s: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    wall_time_min_s: Option<f64>,
    repeats: usize,
    counters: Counters,
    #[serde(serialize_with = "plain_opt")]
    constraint_residual_max: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    energy_drift_max: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    reference_error: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    error_t: Option<f64>,
    error: Option<&'a str>,
}

impl<'a> From<&'a WpRow> for RunRow<'a> {
    fn from(r: &'a WpRow) -> Self {
        RunRow {
            label: &r.label,
            formulation: &r.formulation,
            integrator: &r.integrator,
            radau_newton: r.radau_newton.as_deref(),
            tolerance: r.tolerance,
            step_count: r.step_count,
            step: r.step,
            status: &r.status,
            t_common_end: r.t_common_end,
            err_end: r.err_end,
            err_max: r.err_max,
            rel_err_end: r.rel_err_end,
            rel_err_max: r.rel_err_max,
            scd_end: r.scd_end,
            scd_max: r.scd_max,
            wall_time_median_s: r.wall_time_median_s,
            wall_time_min_s: r.wall_time_min_s,
            repeats: r.repeats,
            counters: r.counters,
            constraint_residual_max: r.constraint_residual_max,
            energy_drift_max: r.energy_drift_max,
            reference_error: r.reference_error,
            error_t: r.error_t,
            error: r.error.as_deref(),
        }
    }
}

/// A row of `references.csv` (after the point and its swept values): a
/// line's reference, or why it has none.
#[derive(Default, Serialize)]
struct ReferenceRow<'a> {
    label: &'a str,
    kind: Option<&'a str>,
    integrator: Option<&'a str>,
    #[serde(serialize_with = "plain_opt")]
    rtol: Option<f64>,
    check_integrator: Option<&'a str>,
    #[serde(serialize_with = "plain_opt")]
    check_rtol: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    error_estimate: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    error_estimate_end: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    t_last: Option<f64>,
    stop: Option<&'a str>,
    check_failure: Option<&'a str>,
    #[serde(serialize_with = "plain_opt")]
    wall_time_s: Option<f64>,
    file: Option<&'a str>,
    failure: Option<&'a str>,
}

impl<'a> From<&'a RefRecord> for ReferenceRow<'a> {
    fn from(r: &'a RefRecord) -> Self {
        let i = r.info.as_ref();
        ReferenceRow {
            label: &r.label,
            kind: i.map(|i| i.kind.as_str()),
            integrator: i.and_then(|i| i.integrator.as_deref()),
            rtol: i.and_then(|i| i.rtol),
            check_integrator: i.and_then(|i| i.check_integrator.as_deref()),
            check_rtol: i.and_then(|i| i.check_rtol),
            error_estimate: i.and_then(|i| i.error_estimate),
            error_estimate_end: i.and_then(|i| i.error_estimate_end),
            t_last: i.map(|i| i.t_last),
            stop: i.and_then(|i| i.stop.as_deref()),
            check_failure: i.and_then(|i| i.check_failure.as_deref()),
            wall_time_s: i.map(|i| i.wall_time_s),
            file: r.file.as_deref(),
            failure: r.failure.as_deref(),
        }
    }
}

/// `work_precision.csv` and `references.csv`.
pub(super) fn write_tables(exp: &Experiment, dir: &Path, points: &[WpPoint]) -> Result<(), String> {
    let axes = || exp.axes.iter().map(|a| a.name.as_str());
    let mut runs = Table::per_point::<RunRow>(axes())?;
    let mut references = Table::per_point::<ReferenceRow>(axes())?;
    for p in points {
        for r in &p.body.rows {
            runs.at_point(p.index, &p.values, &RunRow::from(r))?;
        }
        for r in &p.body.references {
            references.at_point(p.index, &p.values, &ReferenceRow::from(r))?;
        }
    }
    runs.write(&dir.join("work_precision.csv"))?;
    references.write(&dir.join("references.csv"))
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
    p.body
        .rows
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
    let evals = col(&|r| Some(r.counters.rhs_evals as f64));
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

pub(super) fn write_summary(
    exp: &Experiment,
    dir: &Path,
    points: &[WpPoint],
) -> Result<(), String> {
    let lines: Vec<_> = points
        .iter()
        .flat_map(|p| {
            exp.formulations.iter().map(move |f| {
                let s = slopes(p, &f.label);
                let rows: Vec<&WpRow> = p.body.rows.iter().filter(|r| r.label == f.label).collect();
                let reference = p.body.references.iter().find(|r| r.label == f.label);
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

/// `index.html`: the observed orders, every plot with its caption, then the
/// tables of references and runs.
pub(super) fn write_html(
    exp: &Experiment,
    dir: &Path,
    points: &[WpPoint],
    plots: &[PathBuf],
) -> Result<(), String> {
    let fmt = |v: Option<f64>| v.map(|x| format!("{x:.2}")).unwrap_or("—".into());
    let mut orders = vec![
        [
            "point",
            "line",
            "method order",
            "observed order",
            "error vs tolerance slope",
            "cost spread (max/min evaluations)",
            "points fitted",
        ]
        .map(String::from)
        .to_vec(),
    ];
    for p in points {
        for f in &exp.formulations {
            let s = slopes(p, &f.label);
            orders.push(vec![
                p.index.to_string(),
                line_name(f),
                Method::from_name(&f.settings.integrator)
                    .map(|m| m.order().to_string())
                    .unwrap_or_default(),
                fmt(s.order),
                fmt(s.tolerance),
                fmt(s.cost_spread),
                s.fitted.to_string(),
            ]);
        }
    }
    Page {
        exp,
        overview: String::new(),
        files: &[
            "work_precision.csv",
            "references.csv",
            "summary.json",
            "manifest.json",
        ],
        before: vec![("Observed orders".into(), table::html(orders))],
        plots,
        caption: &|stem| caption(exp, stem),
        after: vec![
            (
                "References".into(),
                table::html_from_csv(&dir.join("references.csv")),
            ),
            (
                "Runs".into(),
                table::html_from_csv(&dir.join("work_precision.csv")),
            ),
        ],
    }
    .write(dir)
}

#[cfg(test)]
mod tests {
    use super::super::{Ladders, WP_SCHEMA};
    use super::*;

    fn point(rows: &[(f64, usize, f64)]) -> WpPoint {
        WpPoint {
            schema: WP_SCHEMA.into(),
            index: 0,
            values: vec![],
            hash: String::new(),
            body: Ladders {
                references: vec![],
                rows: rows
                    .iter()
                    .map(|&(tol, evals, err)| WpRow {
                        label: "l".into(),
                        status: "completed".into(),
                        tolerance: Some(tol),
                        counters: Counters {
                            rhs_evals: evals,
                            ..Counters::default()
                        },
                        err_max: Some(err),
                        rel_err_max: Some(err),
                        wall_time_median_s: Some(evals as f64 * 1e-6),
                        ..WpRow::default()
                    })
                    .collect(),
            },
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
