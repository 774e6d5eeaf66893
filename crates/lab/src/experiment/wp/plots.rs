//! The figures of a work-precision experiment: error against cost per
//! point, and the stability map over the points.

use std::path::{Path, PathBuf};

use nonholo_core::integrate::{Method, Radau5Options, RadauDense, RadauNewton};

use super::{MIN_COST_SPREAD, WpPoint, WpRow, slopes};
use crate::experiment::spec::{Experiment, FormulationSpec, compact};
use crate::plot::{Cell, CellStatus, LinePlot, Series, StatusGrid, line_plot, status_grid};

/// `(stem, what, x label, x, y, legend shows the observed order)`.
type PlotSpec<'a> = (
    &'a str,
    &'a str,
    &'a str,
    &'a dyn Fn(&WpRow) -> Option<f64>,
    &'a dyn Fn(&WpRow) -> Option<f64>,
    bool,
);

/// The plots of every point with a ladder of at least two rungs: error (max
/// over the grid, at the end) against median wall time and against
/// right-hand-side evaluations, and error against tolerance; and the
/// stability map over the points.
pub fn draw(exp: &Experiment, dir: &Path, points: &[WpPoint]) -> Result<Vec<PathBuf>, String> {
    let mut files = Vec::new();
    let pens = crate::experiment::pens::of_experiment(exp);
    for p in points {
        // A line with one rung is a single point, not a work-precision
        // curve: a point where no line has two draws no per-point plot (its
        // runs are in the stability map and the tables).
        let longest = exp
            .formulations
            .iter()
            .map(|f| p.body.rows.iter().filter(|r| r.label == f.label).count())
            .max()
            .unwrap_or(0);
        if longest < 2 {
            continue;
        }
        let at = compact(&exp.axes, &p.values);
        let series = |x: &dyn Fn(&WpRow) -> Option<f64>,
                      y: &dyn Fn(&WpRow) -> Option<f64>,
                      with_order: bool| {
            exp.formulations
                .iter()
                .map(|f| {
                    let rows: Vec<&WpRow> = p
                        .body
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
                    let failed: Vec<_> = p
                        .body
                        .rows
                        .iter()
                        .filter(|r| r.label == f.label && r.status == "failed")
                        .collect();
                    if rows.is_empty() && !failed.is_empty() {
                        let n = failed.len();
                        let budget = failed
                            .iter()
                            .all(|r| super::super::budget_stop(r.error.as_deref()));
                        label.push_str(&if budget {
                            format!(" (all {n} runs used up their budget: work_precision.csv)")
                        } else {
                            format!(" (all {n} runs failed: reasons in work_precision.csv)")
                        });
                    }
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
                        pen: crate::experiment::pens::find(&pens, &f.label),
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
                "right-hand-side evaluations [count]",
                &|r| Some(r.counters.rhs_evals as f64),
                &|r| r.err_max,
                true,
            ),
            (
                "end-evals",
                "error at the end vs evaluations",
                "right-hand-side evaluations [count]",
                &|r| Some(r.counters.rhs_evals as f64),
                &|r| r.err_end,
                true,
            ),
            (
                "tolerance",
                "max error over the grid vs tolerance",
                "tolerance rtol = atol [–]",
                &|r| r.tolerance,
                &|r| r.err_max,
                false,
            ),
        ];
        for (stem, what, x_label, x, y, with_order) in plots {
            if stem == "tolerance" && p.body.rows.iter().all(|r| r.tolerance.is_none()) {
                continue;
            }
            let plot = LinePlot {
                verticals: Vec::new(),
                title: title(what),
                x_label: x_label.into(),
                y_label: "largest error in q [m, rad]".into(),
                log_x: true,
                log_y: true,
                equal_aspect: false,
                series: series(x, y, with_order),
                y_range: None,
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
    crate::experiment::files::remove_other_figures(&dir.join("plots"), &files)?;
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
                    let Some(r) = p.body.rows.iter().rev().find(|r| r.label == f.label) else {
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
                        _ if super::super::budget_stop(r.error.as_deref()) => Cell {
                            status: CellStatus::Budget,
                            text: format!("budget{}", at(r.error_t)),
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
                   finest rung; t: the time [s] where a run stopped or failed (reasons in work_precision.csv); \
                   lines: see index.html or work_precision.csv for formulation, integrator, options"
                    .into(),
        },
        &dir.join("plots").join("stability-map"),
    )
}

/// `label: formulation · integrator` (with radau5's Newton iteration,
/// continuous extension, Jacobian reuse and Newton tolerance where not the
/// default, in one parenthesis).
pub(super) fn line_name(f: &FormulationSpec) -> String {
    let s = format!("{}: {} · {}", f.label, f.formulation, f.settings.integrator);
    if f.settings.integrator != Method::Radau5.name() {
        return s;
    }
    let mut extras = Vec::new();
    if f.settings.radau_newton != RadauNewton::Auto.name() {
        extras.push(format!("{} Newton", f.settings.radau_newton));
    }
    if f.settings.radau_dense != RadauDense::default().name() {
        extras.push(format!("{} dense output", f.settings.radau_dense));
    }
    let reuse = f.settings.radau_jacobian_reuse;
    if reuse != Radau5Options::default().jacobian_reuse {
        extras.push(format!("Jacobian kept at θ ≤ {reuse}"));
    }
    if let Some(tol) = f.settings.radau_newton_tol {
        extras.push(format!("Newton to {tol:e}"));
    }
    if extras.is_empty() {
        s
    } else {
        format!("{s} ({})", extras.join("; "))
    }
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
