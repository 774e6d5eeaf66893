//! Result files of a comparison: tables, trajectories, summary and the
//! page's content (the files and page code both kinds share are in
//! [`super::files`], [`crate::table`], [`super::page`] and
//! [`super::manifest`]). Every file is written atomically.

use std::path::{Path, PathBuf};

use serde::Serialize;
use serde_json::{Value as Json, json};

use super::files::write_json;
use super::page::Page;
use super::point::{FormResult, PairResult, PointResult, Samples};
use super::spec::Experiment;
use crate::record::Counters;
use crate::table::{self, StateRow, Table, escape, plain, plain_opt, state_header};

/// `trajectories/<index>-<label>.csv`.
pub fn trajectory_path(dir: &Path, index: usize, label: &str) -> PathBuf {
    dir.join("trajectories")
        .join(format!("{index}-{label}.csv"))
}

/// Writes one formulation's samples: `t, q…, q_dot…, multipliers…,
/// residual, energy, chart…` (the scene's velocity-chart values).
pub fn write_trajectory(dir: &Path, index: usize, s: &Samples) -> Result<(), String> {
    let more = s
        .multipliers
        .iter()
        .cloned()
        .chain(["residual".into(), "energy".into()])
        .chain(s.chart_names.iter().cloned());
    let mut table = Table::new(state_header(
        s.coordinates.iter().map(|(c, _)| c.as_str()),
        more,
    ))?;
    for (i, o) in s.obs.iter().enumerate() {
        let (residual, energy) = s
            .physics
            .get(i)
            .copied()
            .ok_or_else(|| format!("{}: no residual and energy at sample {i}", s.label))?;
        table.push_state(&StateRow {
            t: s.t[i],
            q: &o.q,
            q_dot: &o.qd,
            more: &[
                &o.multipliers,
                &[residual, energy],
                s.chart.get(i).map_or(&[][..], Vec::as_slice),
            ],
        })?;
    }
    table.write(&trajectory_path(dir, index, &s.label))
}

/// A trajectory file read back: column names and rows.
pub struct Trajectory {
    pub header: Vec<String>,
    pub rows: Vec<Vec<f64>>,
}

impl Trajectory {
    /// Reads a trajectory file; a field that is not a number is an error
    /// naming the file, line and column.
    pub fn read(path: &Path) -> Result<Trajectory, String> {
        let mut r = csv::Reader::from_path(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let header: Vec<String> = r
            .headers()
            .map_err(|e| format!("{}: {e}", path.display()))?
            .iter()
            .map(String::from)
            .collect();
        let mut rows = Vec::new();
        for (i, rec) in r.records().enumerate() {
            let rec = rec.map_err(|e| format!("{}: {e}", path.display()))?;
            let row = rec
                .iter()
                .zip(&header)
                .map(|(v, h)| {
                    v.parse::<f64>().map_err(|_| {
                        format!(
                            "{}:{}: column `{h}`: `{v}` is not a number",
                            path.display(),
                            i + 2
                        )
                    })
                })
                .collect::<Result<Vec<f64>, String>>()?;
            rows.push(row);
        }
        Ok(Trajectory { header, rows })
    }

    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let i = self.header.iter().position(|h| h == name)?;
        Some(self.rows.iter().map(|r| r[i]).collect())
    }
}

/// The divergence of formulation `label` from the reference at one point.
fn vs_reference<'a>(r: &'a PointResult, label: &str, reference: &str) -> Option<&'a PairResult> {
    r.body
        .pairs
        .iter()
        .find(|p| (p.a == reference && p.b == label) || (p.b == reference && p.a == label))
}

/// The divergence measures of a pair, as `runs.csv` and `pairs.csv` give them.
#[derive(Default, Serialize)]
struct Divergence {
    #[serde(serialize_with = "plain_opt")]
    div_xy_end: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    div_xy_max: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    div_q_end: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    div_q_max: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    t_exceed: Option<f64>,
}

impl From<&PairResult> for Divergence {
    fn from(p: &PairResult) -> Self {
        Divergence {
            div_xy_end: p.div_xy_end,
            div_xy_max: p.div_xy_max,
            div_q_end: p.div_q_end,
            div_q_max: p.div_q_max,
            t_exceed: p.t_exceed,
        }
    }
}

/// A row of `runs.csv` (after the point and its swept values): one
/// formulation at one point, and its divergence from the reference
/// formulation (empty for the reference itself).
#[derive(Default, Serialize)]
struct RunRow<'a> {
    label: &'a str,
    formulation: &'a str,
    integrator: &'a str,
    #[serde(serialize_with = "plain")]
    rtol: f64,
    #[serde(serialize_with = "plain")]
    atol: f64,
    status: &'a str,
    #[serde(serialize_with = "plain_opt")]
    t_last: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    error_t: Option<f64>,
    error: Option<&'a str>,
    counters: Counters,
    #[serde(serialize_with = "plain_opt")]
    constraint_residual_max: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    energy_initial: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    energy_drift_max: Option<f64>,
    reference: Option<&'a str>,
    divergence: Divergence,
    /// Crossings of a singular set (A past its map's singular set).
    crossings: Option<usize>,
    /// Sign changes of the quantity `[measures] reversals` names.
    reversals: Option<usize>,
    /// Changes of mode (the friction realisation's stick–slip transitions).
    switches: Option<usize>,
    /// The located time of the first, and what it was (`stick→slip`).
    #[serde(serialize_with = "plain_opt")]
    first_switch_t: Option<f64>,
    first_switch: Option<&'a str>,
}

impl<'a> RunRow<'a> {
    fn new(f: &'a FormResult, vs_reference: Option<(&'a str, &PairResult)>) -> Self {
        RunRow {
            label: &f.label,
            formulation: &f.formulation,
            integrator: &f.integrator,
            rtol: f.rtol,
            atol: f.atol,
            status: &f.status,
            t_last: f.t_last,
            error_t: f.error_t,
            error: f.error.as_deref(),
            counters: f.counters,
            constraint_residual_max: f.constraint_residual_max,
            energy_initial: f.energy_initial,
            energy_drift_max: f.energy_drift_max,
            reference: vs_reference.map(|(r, _)| r),
            divergence: vs_reference
                .map(|(_, p)| Divergence::from(p))
                .unwrap_or_default(),
            crossings: f.crossings,
            reversals: f.reversals,
            switches: f.switches,
            first_switch_t: f.first_switch_t,
            first_switch: f.first_switch.as_deref(),
        }
    }
}

/// A row of `pairs.csv` (after the point and its swept values).
#[derive(Default, Serialize)]
struct PairRow<'a> {
    a: &'a str,
    b: &'a str,
    #[serde(serialize_with = "plain_opt")]
    span_end: Option<f64>,
    divergence: Divergence,
}

/// A row of `timing.csv`: what depends on the machine.
#[derive(Default, Serialize)]
struct TimingRow<'a> {
    point: usize,
    label: &'a str,
    #[serde(serialize_with = "plain")]
    wall_time_s: f64,
    /// The time reached by a run its wall-time budget stopped.
    #[serde(serialize_with = "plain_opt")]
    wall_time_stop_t: Option<f64>,
}

/// `runs.csv`, `pairs.csv`, `timing.csv` and `config.json`.
pub fn write_tables(exp: &Experiment, dir: &Path, results: &[PointResult]) -> Result<(), String> {
    let axes = || exp.axes.iter().map(|a| a.name.as_str());

    let mut runs = Table::per_point::<RunRow>(axes())?;
    let mut pairs = Table::per_point::<PairRow>(axes())?;
    let mut timing = Table::new(table::columns::<TimingRow>()?)?;
    for r in results {
        for f in &r.body.formulations {
            let vs = vs_reference(r, &f.label, &exp.reference)
                .filter(|_| f.label != exp.reference)
                .map(|p| (exp.reference.as_str(), p));
            runs.at_point(r.index, &r.values, &RunRow::new(f, vs))?;
            timing.push(&TimingRow {
                point: r.index,
                label: &f.label,
                wall_time_s: f.wall_time_s,
                wall_time_stop_t: f.wall_time_stop_t,
            })?;
        }
        for p in &r.body.pairs {
            let row = PairRow {
                a: &p.a,
                b: &p.b,
                span_end: p.span_end,
                divergence: Divergence::from(p),
            };
            pairs.at_point(r.index, &r.values, &row)?;
        }
    }
    runs.write(&dir.join("runs.csv"))?;
    pairs.write(&dir.join("pairs.csv"))?;
    timing.write(&dir.join("timing.csv"))?;

    let config = json!({
        "name": exp.name,
        "title": exp.title,
        "claim": exp.claim,
        "scene": exp.scene,
        "params": exp.params,
        "init": exp.init,
        "time": {"t_end": exp.t_end, "output_every": exp.output_every},
        "formulations": exp.formulations.iter().map(|f| json!({
            "label": f.label,
            "formulation": f.formulation,
            "integrator": f.settings.integrator,
            "rtol": f.settings.rtol,
            "atol": f.settings.atol,
            "step": f.settings.step,
            "max_steps": f.settings.max_steps,
            "max_wall_time": f.settings.max_wall_time,
            "project_init": f.settings.project_init,
            "stiff_stop": f.settings.stiff_stop,
            "options": f.options,
            "init": f.init,
            "params": f.params,
        })).collect::<Vec<_>>(),
        "sweep": {
            "mode": format!("{:?}", exp.mode),
            "axes": exp.axes.iter().map(|a| json!({"name": a.name, "values": a.values})).collect::<Vec<_>>(),
        },
        "measures": {"threshold": exp.threshold, "reference": exp.reference, "reversals": exp.reversals, "repeats": exp.repeats},
        "minimise": exp.minimise.as_ref().map(|m| json!({"over": m.over, "range": m.range, "samples": m.samples, "refine": m.refine, "label": m.label})),
        "plots": {"point": exp.plot_point, "also": exp.also_points, "log_time": exp.log_time, "all_trajectories": exp.all_trajectories},
    });
    write_json(&dir.join("config.json"), &config)
}

/// The median (the mean of the two middle values for an even count).
pub fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

/// `summary.json`: counts and, for every pair, the spread of the end divergence.
pub fn write_summary(
    exp: &Experiment,
    dir: &Path,
    results: &[PointResult],
    plots: &[PathBuf],
) -> Result<(), String> {
    let labels: Vec<&str> = exp.formulations.iter().map(|f| f.label.as_str()).collect();
    let per_label: Vec<Json> = labels
        .iter()
        .map(|l| {
            let rows: Vec<_> = results
                .iter()
                .flat_map(|r| &r.body.formulations)
                .filter(|f| f.label == *l)
                .collect();
            json!({
                "label": l,
                "completed": rows.iter().filter(|f| f.status == "completed").count(),
                "stopped": rows.iter().filter(|f| f.status == "stopped").count(),
                "failed": rows.iter().filter(|f| f.status == "failed").count(),
            })
        })
        .collect();
    let mut pairs = Vec::new();
    for (i, a) in labels.iter().enumerate() {
        for b in &labels[i + 1..] {
            let ends: Vec<f64> = results
                .iter()
                .flat_map(|r| &r.body.pairs)
                .filter(|p| p.a == *a && p.b == *b)
                .filter_map(|p| p.div_xy_end)
                .collect();
            pairs.push(json!({
                "a": a,
                "b": b,
                "points": ends.len(),
                "div_xy_end_min": ends.iter().copied().reduce(f64::min),
                "div_xy_end_median": median(ends.clone()),
                "div_xy_end_max": ends.iter().copied().reduce(f64::max),
            }));
        }
    }
    let runs: usize = results.iter().map(|r| r.body.formulations.len()).sum();
    let failed = results
        .iter()
        .flat_map(|r| &r.body.formulations)
        .filter(|f| f.status == "failed")
        .count();
    let stopped = results
        .iter()
        .flat_map(|r| &r.body.formulations)
        .filter(|f| f.status == "stopped")
        .count();
    let budget = results
        .iter()
        .flat_map(|r| &r.body.formulations)
        .filter(|f| f.status == "failed" && super::budget_stop(f.error.as_deref()))
        .count();
    write_json(
        &dir.join("summary.json"),
        &json!({
            "schema": "nonholo.experiment-summary/1",
            "name": exp.name,
            "title": exp.title,
            "claim": exp.claim,
            "points": results.len(),
            "runs": runs,
            "failed_runs": failed,
            "stopped_runs": stopped,
            "budget_runs": budget,
            "minima": super::minimise::summary(exp, dir),
            "formulations": per_label,
            "pairs": pairs,
            "plots": plots.iter().map(|p| p.strip_prefix(dir).unwrap_or(p).display().to_string()).collect::<Vec<_>>(),
        }),
    )
}

/// `index.html`: every plot with its caption, then the table of runs.
pub fn write_html(
    exp: &Experiment,
    dir: &Path,
    results: &[PointResult],
    plots: &[PathBuf],
) -> Result<(), String> {
    let formulations: Vec<String> = exp
        .formulations
        .iter()
        .map(|f| {
            format!(
                "{} = {} ({})",
                escape(&f.label),
                escape(&f.formulation),
                escape(&f.settings.integrator)
            )
        })
        .collect();
    Page {
        exp,
        overview: format!(
            "Scene <code>{}</code>; {} point(s); formulations: {}.",
            escape(&exp.scene),
            results.len(),
            formulations.join(", ")
        ),
        files: if exp.minimise.is_some() {
            &[
                "runs.csv",
                "pairs.csv",
                super::minimise::MINIMA,
                "summary.json",
                "config.json",
                "manifest.json",
            ]
        } else {
            &[
                "runs.csv",
                "pairs.csv",
                "summary.json",
                "config.json",
                "manifest.json",
            ]
        },
        before: Vec::new(),
        plots,
        caption: &|stem| super::plots::caption(exp, stem),
        after: exp
            .minimise
            .iter()
            .map(|m| {
                (
                    format!("Minimisation over {}", m.over),
                    table::html_from_csv(&dir.join(super::minimise::MINIMA)),
                )
            })
            .chain([("Runs".into(), table::html_from_csv(&dir.join("runs.csv")))])
            .collect(),
    }
    .write(dir)
}

#[cfg(test)]
mod tests {
    use super::median;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(vec![]), None);
        assert_eq!(median(vec![3.0, 1.0, 2.0]), Some(2.0));
        // Even count: the mean of the middle two, not the upper one.
        assert_eq!(median(vec![4.0, 1.0, 3.0, 2.0]), Some(2.5));
    }
}
