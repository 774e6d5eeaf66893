//! Experiments of kind `bvp`: Hamilton's principle with fixed ends, solved
//! on grids and set beside initial-value motions (`[bvp]`,
//! [`super::spec::BvpSpec`], docs/variational.md).
//!
//! At every point of the sweep the `[[formulation]]` lines are integrated
//! from `[init]` to the longest horizon, sampled on the finest grid. For
//! every horizon `t1` and spacing `h`, each `[[bvp.line]]` is solved on
//! `[0, t1]` with the end data of line `ends_from` at `0` and `t1`, and its
//! nodes compared with every initial-value line; the motions named in
//! `stationarity` are measured for stationarity under each problem.
//!
//! | file | content |
//! |---|---|
//! | `bvp.json` | everything computed (what `nonholo plot` redraws from) |
//! | `ivp.csv` | one row per (point, initial-value line): status, reach, the sign changes of `[measures] reversals` |
//! | `solves.csv` | one row per (point, line, horizon, h): Newton's work, errors against each initial-value line, orders, the grid's own error estimate |
//! | `stationarity.csv` | one row per (point, horizon, h, problem, motion): the stationarity residual |
//! | `horizons.csv` | one row per (point, line, h, horizon): how far the solution on `[0, t1]` is, on the shortest horizon's span, from the solution on the shortest horizon |
//! | `summary.json`, `manifest.json`, `plots/`, `index.html` | as for the other kinds |
//!
//! Solves take milliseconds to a second, so nothing is stored per point and
//! a run computes everything again; a stored `bvp.json` that agrees with it
//! apart from wall times stays (see `run`).

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::files::{remove_other_figures, write_json};
use super::manifest::write_manifest;
use super::page::Page;
use super::pens::Pens;
use super::spec::{BvpSpec, Experiment};
use super::sweep::{self, Point};
use super::{Outcome, RunOptions};
use crate::CliError;
use crate::bvp::{Job, map_form_name, variant};
use crate::plot::{Dash, LinePlot, Pen, Series, line_plot};
use crate::simulate::{execute, output_grid};
use crate::table::{self, Plain, Table};

/// Schema of `bvp.json`.
pub const SCHEMA: &str = "nonholo.bvp/1";

/// Everything a bvp experiment computed.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BvpResult {
    pub schema: String,
    pub experiment: String,
    /// Swept names, in the order of each point's `values`.
    pub axes: Vec<String>,
    pub points: Vec<PointOut>,
}

/// One point of the sweep.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PointOut {
    pub index: usize,
    pub values: Vec<String>,
    pub ivp: Vec<IvpOut>,
    /// Upper bound on the error of `ends_from`'s motion at the nodes: its
    /// largest difference from the same run at 100 times its tolerances
    /// (`None` for a fixed step).
    pub reference_error: Option<f64>,
    pub solves: Vec<SolveOut>,
    pub stationarity: Vec<StationarityOut>,
    pub horizons: Vec<HorizonOut>,
    /// The drawn paths: the coarsest grid's nodes on the longest horizon.
    pub path_t: Vec<f64>,
    /// Coordinates per node.
    pub n: usize,
    /// Each line's path at `path_t`, node after node (initial-value lines
    /// first; lines that failed before the end are left out).
    pub paths: Vec<PathOut>,
}

/// An initial-value line at a point.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct IvpOut {
    pub label: String,
    pub formulation: String,
    /// `completed` or `failed`.
    pub status: String,
    pub error: Option<String>,
    /// Last time sampled.
    pub t_last: Option<f64>,
    pub wall_s: f64,
    /// Where `[measures] reversals` changes sign on the finest grid (the
    /// midpoint of the two samples), if asked for.
    #[serde(default)]
    pub reversals: Vec<f64>,
}

/// One boundary-value solve.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SolveOut {
    pub label: String,
    pub horizon: f64,
    pub h: f64,
    pub intervals: usize,
    /// `solved` or `failed`.
    pub status: String,
    pub error: Option<String>,
    pub iterations: Option<usize>,
    pub damped_steps: Option<usize>,
    /// Final scaled residual.
    pub residual: Option<f64>,
    pub unknowns: Option<usize>,
    pub nonzeros: Option<usize>,
    /// Wall time of the Newton solve (assembly, factorisations, line search).
    pub wall_s: Option<f64>,
    /// Largest difference in any coordinate at the nodes from each
    /// initial-value line, in the order of `[[formulation]]` (`None` where
    /// that line failed before `t1`).
    pub errors: Vec<Option<f64>>,
    /// Observed order of the error against `ends_from` between this `h`
    /// and the previous (coarser) one (`None` where either error is
    /// round-off, below `1e4 ε max|q|`).
    pub order: Option<f64>,
    /// Largest difference at this grid's nodes from the solution on the
    /// next finer grid.
    pub self_difference: Option<f64>,
    /// Observed order of those differences (this grid and the next finer).
    pub self_order: Option<f64>,
    /// This solution's own error estimate at the previous (coarser) grid's
    /// nodes, from Richardson's argument: `d/(r² − 1)` with `d` the coarser
    /// grid's `self_difference`, the design order 2 and the spacing ratio
    /// `r`.
    pub error_estimate: Option<f64>,
    /// Largest nonholonomic residual at the nodes (velocities by
    /// differences).
    pub constraint_max: Option<f64>,
    pub energy_drift: Option<f64>,
}

/// A stationarity residual.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StationarityOut {
    pub horizon: f64,
    pub h: f64,
    /// The problem: a `[[bvp.line]]` label.
    pub under: String,
    /// The motion: a `[[formulation]]` label.
    pub of: String,
    pub max: Option<f64>,
    pub rms: Option<f64>,
    pub t: Option<f64>,
    pub coordinate: Option<String>,
    pub constraint_max: Option<f64>,
    pub error: Option<String>,
}

/// The dependence of a line's solution on the horizon.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct HorizonOut {
    pub label: String,
    pub h: f64,
    pub horizon: f64,
    /// Largest difference (any coordinate) on `[0, shortest horizon]` from
    /// the solution on the shortest horizon (same `h`, same nodes).
    pub spread: Option<f64>,
}

/// A drawn path.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PathOut {
    pub label: String,
    pub q: Vec<f64>,
}

fn spec_of(exp: &Experiment) -> Result<&BvpSpec, CliError> {
    exp.bvp
        .as_ref()
        .ok_or_else(|| CliError::Input(format!("{}: no [bvp] table", exp.name)))
}

/// Largest absolute difference of two equally long slices.
fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| {
        if (x - y).is_nan() {
            f64::NAN
        } else {
            m.max((x - y).abs())
        }
    })
}

/// Every `step`-th node of a node-major path, the first `count + 1`.
fn nodes(path: &[f64], n: usize, step: usize, count: usize) -> Option<Vec<f64>> {
    let need = count * step + 1;
    (path.len() >= need * n).then(|| {
        (0..=count)
            .flat_map(|j| path[j * step * n..(j * step + 1) * n].iter().copied())
            .collect()
    })
}

/// The values of `name` (a velocity-chart value, a coordinate or
/// `<coord>_dot`) along samples, node after node.
struct Quantity<'a> {
    name: &'a str,
    q: &'a [f64],
    qd: &'a [f64],
}

impl nonholo_scenes::SceneVisitor for Quantity<'_> {
    type Output = Option<Vec<f64>>;
    fn visit<S: nonholo_core::Scene>(self, scene: S) -> Option<Vec<f64>> {
        let info = scene.info();
        let n = info.n();
        let states = self.q.chunks(n).zip(self.qd.chunks(n));
        if let Some(k) = info.velocity_chart.iter().position(|c| c.name == self.name) {
            let mut c = vec![0.0; info.velocity_chart.len()];
            return states
                .map(|(q, qd)| scene.chart_from(q, qd, &mut c).then_some(c[k]))
                .collect();
        }
        if let Some(k) = info.coordinate_index(self.name) {
            return Some(states.map(|(q, _)| q[k]).collect());
        }
        let k = info.coordinate_index(self.name.strip_suffix("_dot")?)?;
        Some(states.map(|(_, qd)| qd[k]).collect())
    }
}

/// An initial-value line's samples on the finest grid.
struct Ivp {
    out: IvpOut,
    q: Vec<f64>,
    qd: Vec<f64>,
}

fn run_ivps(exp: &Experiment, point: &Point, grid: &[f64], t_max: f64) -> Result<Vec<Ivp>, String> {
    let runs = sweep::resolve(exp, point)?;
    let params = sweep::apply_point(exp, point)?.params;
    Ok(runs
        .into_iter()
        .map(|mut r| {
            r.spec.integrator.output = grid.to_vec();
            r.spec.t_end = t_max;
            let started = std::time::Instant::now();
            let form = r.spec.formulation.clone();
            match execute(&r.spec) {
                Ok((run, _)) => {
                    // Samples up to the first that is not finite (a run that
                    // overflowed is cut there and counted as failed).
                    let finite = run
                        .samples
                        .iter()
                        .position(|o| o.q.iter().chain(&o.qd).any(|v| !v.is_finite()))
                        .unwrap_or(run.samples.len());
                    let samples = &run.samples[..finite];
                    let q: Vec<f64> = samples.iter().flat_map(|o| o.q.clone()).collect();
                    let qd: Vec<f64> = samples.iter().flat_map(|o| o.qd.clone()).collect();
                    let t = &run.solution.t[..finite];
                    let t_last = t.last().copied();
                    let reversals = exp
                        .reversals
                        .as_deref()
                        .and_then(|name| {
                            let scene = nonholo_scenes::build(&exp.scene, &params).ok()?;
                            let values = scene.visit(Quantity {
                                name,
                                q: &q,
                                qd: &qd,
                            })?;
                            Some(super::point::sign_change_times(t, &values))
                        })
                        .unwrap_or_default();
                    Ivp {
                        out: IvpOut {
                            label: r.label,
                            formulation: form,
                            status: if run.completed() && finite == run.samples.len() {
                                "completed"
                            } else {
                                "failed"
                            }
                            .into(),
                            error: run.failure.as_ref().map(|e| e.to_string()).or_else(|| {
                                (finite < run.samples.len()).then(|| {
                                    format!(
                                        "a value that is not finite at t = {} (the samples \
                                         end there)",
                                        run.solution.t[finite]
                                    )
                                })
                            }),
                            t_last,
                            wall_s: started.elapsed().as_secs_f64(),
                            reversals,
                        },
                        q,
                        qd,
                    }
                }
                Err(e) => Ivp {
                    out: IvpOut {
                        label: r.label,
                        formulation: form,
                        status: "failed".into(),
                        error: Some(e.to_string()),
                        t_last: None,
                        wall_s: started.elapsed().as_secs_f64(),
                        reversals: Vec::new(),
                    },
                    q: Vec::new(),
                    qd: Vec::new(),
                },
            }
        })
        .collect())
}

/// The largest difference of `ends_from`'s motion from the same run at 100
/// times its tolerances (an upper bound on its own error, if the error
/// falls with the tolerance).
fn reference_error(
    exp: &Experiment,
    point: &Point,
    spec: &BvpSpec,
    grid: &[f64],
    t_max: f64,
    reference: &Ivp,
) -> Option<f64> {
    let runs = sweep::resolve(exp, point).ok()?;
    let mut r = runs.into_iter().find(|r| r.label == spec.ends_from)?;
    if r.spec.integrator.fixed_step.is_some() {
        return None;
    }
    r.spec.integrator.output = grid.to_vec();
    r.spec.t_end = t_max;
    r.spec.integrator.rtol = (r.spec.integrator.rtol * 100.0).min(1e-2);
    r.spec.integrator.atol = (r.spec.integrator.atol * 100.0).min(1e-2);
    let (run, _) = execute(&r.spec).ok()?;
    let q: Vec<f64> = run.samples.iter().flat_map(|o| o.q.clone()).collect();
    let len = q.len().min(reference.q.len());
    Some(max_diff(&q[..len], &reference.q[..len]))
}

/// Computes one point (never panics: a failure is recorded where it
/// happened).
fn compute_point(exp: &Experiment, spec: &BvpSpec, point: &Point) -> Result<PointOut, String> {
    let t_max = exp.t_end;
    let h_min = spec.h[spec.h.len() - 1];
    let grid = output_grid(t_max, h_min)?;
    let params = sweep::apply_point(exp, point)?.params;
    let n = nonholo_scenes::describe(&exp.scene, &params)
        .map_err(|e| e.to_string())?
        .n();
    let ivps = run_ivps(exp, point, &grid, t_max)?;
    let reference = ivps
        .iter()
        .position(|i| i.out.label == spec.ends_from)
        .ok_or("ends_from names no line")?;
    let reference_error = reference_error(exp, point, spec, &grid, t_max, &ivps[reference]);
    let steps: Vec<usize> = spec
        .h
        .iter()
        .map(|h| (h / h_min).round() as usize)
        .collect();
    // Differences below this are round-off, whose ratios are no orders.
    let q_scale = ivps[reference].q.iter().fold(1.0f64, |m, v| m.max(v.abs()));
    let round_off = 1e4 * f64::EPSILON * q_scale;
    let measurable = |a: f64, b: f64| a > round_off && b > round_off;
    let mut solves = Vec::new();
    let mut stationarity = Vec::new();
    // Solutions kept for the horizon and self-convergence measures:
    // (line, horizon index, h index) → node path.
    let mut kept: Vec<(usize, usize, usize, Vec<f64>)> = Vec::new();
    for (ih, &t1) in spec.horizons.iter().enumerate() {
        for (jh, &h) in spec.h.iter().enumerate() {
            let count = (t1 / h).round() as usize;
            let step = steps[jh];
            let at = |i: &Ivp| nodes(&i.q, n, step, count);
            let ref_q = at(&ivps[reference]);
            let ref_qd = nodes(&ivps[reference].qd, n, step, count);
            let checks: Vec<(String, Option<Vec<f64>>)> = spec
                .stationarity
                .iter()
                .map(|l| {
                    let i = ivps
                        .iter()
                        .find(|i| i.out.label == *l)
                        .expect("checked at load");
                    (l.clone(), at(i))
                })
                .collect();
            for (il, line) in spec.lines.iter().enumerate() {
                let failed = |e: String| SolveOut {
                    label: line.label.clone(),
                    horizon: t1,
                    h,
                    intervals: count,
                    status: "failed".into(),
                    error: Some(e),
                    iterations: None,
                    damped_steps: None,
                    residual: None,
                    unknowns: None,
                    nonzeros: None,
                    wall_s: None,
                    errors: vec![None; ivps.len()],
                    order: None,
                    self_difference: None,
                    self_order: None,
                    error_estimate: None,
                    constraint_max: None,
                    energy_drift: None,
                };
                let (Some(rq), Some(rqd)) = (&ref_q, &ref_qd) else {
                    solves.push(failed(format!(
                        "{} did not reach t1 = {}: no end data ({})",
                        spec.ends_from,
                        crate::fields::num(t1),
                        ivps[reference].out.error.clone().unwrap_or_default()
                    )));
                    continue;
                };
                let last = count * n;
                let job = Job {
                    scene: exp.scene.clone(),
                    params: params.clone(),
                    formulation: line.resolved.clone(),
                    t0: 0.0,
                    t1,
                    intervals: count,
                    ends: nonholo_variational::Ends {
                        q0: rq[..n].to_vec(),
                        q1: rq[last..last + n].to_vec(),
                        qd0: Some(rqd[..n].to_vec()),
                        qd1: Some(rqd[last..last + n].to_vec()),
                    },
                    start: spec.start_from_reference.then(|| rq.clone()),
                    refine: false,
                    solve: true,
                    options: nonholo_variational::Options {
                        max_iter: spec.max_iter,
                        tol: spec.tol,
                        ..nonholo_variational::Options::default()
                    },
                    check: if spec.stationarity_under.contains(&line.label) {
                        checks.iter().filter_map(|(_, p)| p.clone()).collect()
                    } else {
                        Vec::new()
                    },
                };
                let outcome = match crate::bvp::solve(&job) {
                    Ok(o) => o,
                    Err(e) => {
                        solves.push(failed(e.to_string()));
                        continue;
                    }
                };
                let mut results = outcome.stationarity.iter();
                let measured = spec.stationarity_under.contains(&line.label);
                for (of, path) in checks.iter().filter(|_| measured) {
                    let mut row = StationarityOut {
                        horizon: t1,
                        h,
                        under: line.label.clone(),
                        of: of.clone(),
                        max: None,
                        rms: None,
                        t: None,
                        coordinate: None,
                        constraint_max: None,
                        error: None,
                    };
                    match (path, path.as_ref().and_then(|_| results.next())) {
                        (Some(_), Some(Ok(st))) => {
                            row.max = Some(st.max);
                            row.rms = Some(st.rms);
                            row.t = Some(st.t);
                            row.coordinate = Some(st.coordinate.clone());
                            row.constraint_max = Some(st.constraint_max);
                        }
                        (Some(_), Some(Err(e))) => row.error = Some(e.to_string()),
                        _ => row.error = Some(format!("{of} did not reach t1")),
                    }
                    stationarity.push(row);
                }
                match outcome.solved {
                    Some(Ok(s)) => {
                        let report = &s.levels[0];
                        let errors = ivps
                            .iter()
                            .map(|i| at(i).map(|p| max_diff(&s.solution.q, &p)))
                            .collect();
                        solves.push(SolveOut {
                            status: "solved".into(),
                            error: None,
                            iterations: Some(report.iterations),
                            damped_steps: Some(report.damped_steps),
                            residual: report.residual_history.last().copied(),
                            unknowns: Some(report.unknowns),
                            nonzeros: Some(report.nonzeros),
                            wall_s: Some(report.wall_seconds),
                            errors,
                            constraint_max: Some(s.diagnostics.nonholonomic_residual_max),
                            energy_drift: Some(s.diagnostics.energy_drift_max),
                            ..failed(String::new())
                        });
                        kept.push((il, ih, jh, s.solution.q));
                    }
                    Some(Err(e)) => solves.push(failed(e.to_string())),
                    None => solves.push(failed("not solved".into())),
                }
            }
        }
    }
    // Orders against the reference and between grids.
    let find = |il: usize, ih: usize, jh: usize| {
        kept.iter()
            .find(|(a, b, c, _)| (*a, *b, *c) == (il, ih, jh))
            .map(|k| &k.3)
    };
    let row_of = |il: usize, ih: usize, jh: usize| (ih * spec.h.len() + jh) * spec.lines.len() + il;
    for (il, _) in spec.lines.iter().enumerate() {
        for ih in 0..spec.horizons.len() {
            for jh in 0..spec.h.len() {
                let r = row_of(il, ih, jh);
                if jh > 0 {
                    let (e0, e1) = (
                        solves[row_of(il, ih, jh - 1)].errors[reference],
                        solves[r].errors[reference],
                    );
                    if let (Some(a), Some(b)) = (e0, e1)
                        && measurable(a, b)
                    {
                        solves[r].order = Some((a / b).ln() / (spec.h[jh - 1] / spec.h[jh]).ln());
                    }
                }
                if jh + 1 < spec.h.len()
                    && let (Some(c), Some(f)) = (find(il, ih, jh), find(il, ih, jh + 1))
                {
                    let ratio = steps[jh] / steps[jh + 1];
                    let count = c.len() / n - 1;
                    if let Some(fine) = nodes(f, n, ratio, count) {
                        let d = max_diff(c, &fine);
                        solves[r].self_difference = Some(d);
                        // Richardson: the finer solution's error is about
                        // d/(r^p − 1) at the coarse nodes.
                        let rr = (ratio * ratio) as f64;
                        solves[row_of(il, ih, jh + 1)].error_estimate = Some(d / (rr - 1.0));
                    }
                }
            }
            for jh in 0..spec.h.len().saturating_sub(2) {
                let r = row_of(il, ih, jh);
                let next = solves[row_of(il, ih, jh + 1)].self_difference;
                if let (Some(a), Some(b)) = (solves[r].self_difference, next)
                    && measurable(a, b)
                {
                    solves[r].self_order = Some((a / b).ln() / (spec.h[jh] / spec.h[jh + 1]).ln());
                }
            }
        }
    }
    // The dependence on the horizon.
    let mut horizons = Vec::new();
    for (il, line) in spec.lines.iter().enumerate() {
        for (jh, &h) in spec.h.iter().enumerate() {
            let base = find(il, 0, jh);
            for (ih, &t1) in spec.horizons.iter().enumerate().skip(1) {
                let spread = match (base, find(il, ih, jh)) {
                    (Some(b), Some(o)) => Some(max_diff(b, &o[..b.len()])),
                    _ => None,
                };
                horizons.push(HorizonOut {
                    label: line.label.clone(),
                    h,
                    horizon: t1,
                    spread,
                });
            }
        }
    }
    // The paths drawn: the coarsest grid of the longest horizon.
    let ih = spec.horizons.len() - 1;
    let t1 = spec.horizons[ih];
    let count = (t1 / spec.h[0]).round() as usize;
    let path_t: Vec<f64> = (0..=count).map(|j| t1 * j as f64 / count as f64).collect();
    let mut paths: Vec<PathOut> = ivps
        .iter()
        .filter_map(|i| {
            nodes(&i.q, n, steps[0], count).map(|q| PathOut {
                label: i.out.label.clone(),
                q,
            })
        })
        .collect();
    for (il, line) in spec.lines.iter().enumerate() {
        if let Some(q) = find(il, ih, 0) {
            paths.push(PathOut {
                label: line.label.clone(),
                q: q.clone(),
            });
        }
    }
    Ok(PointOut {
        index: point.index,
        values: point.values.clone(),
        ivp: ivps.into_iter().map(|i| i.out).collect(),
        reference_error,
        solves,
        stationarity,
        horizons,
        path_t,
        n,
        paths,
    })
}

/// Runs a bvp experiment and writes its results.
pub fn run(
    exp: &Experiment,
    opts: &RunOptions,
    out: super::ResultsDir,
) -> Result<Outcome, CliError> {
    let spec = spec_of(exp)?;
    let started = std::time::SystemTime::now();
    let dir = out.path().to_path_buf();
    out.prepare(&["plots"])?;
    let (pool, threads) = super::worker_pool(opts.threads)?;
    let points = exp.points();
    if !opts.quiet {
        crate::note!(
            "{}: {} boundary-value line(s) × {} horizon(s) × {} grid(s) at {} point(s)",
            exp.name,
            spec.lines.len(),
            spec.horizons.len(),
            spec.h.len(),
            points.len()
        );
    }
    let computed: Vec<Result<PointOut, String>> = pool.install(|| {
        points
            .par_iter()
            .map(|p| {
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    compute_point(exp, spec, p)
                }))
                .unwrap_or_else(|_| Err("internal error (panic)".into()))
                .map_err(|e| format!("point {}: {e}", p.index))
            })
            .collect()
    });
    let result = BvpResult {
        schema: SCHEMA.into(),
        experiment: exp.name.clone(),
        axes: exp.axes.iter().map(|a| a.name.clone()).collect(),
        points: computed
            .into_iter()
            .collect::<Result<_, _>>()
            .map_err(CliError::Run)?,
    };
    // A run computes everything again, and everything but its wall times
    // is deterministic: where the stored result agrees with this one apart
    // from them, it stays (tables, figures and page are written from it, as
    // they were), so that `nonholo reproduce` on a fresh clone does not
    // rewrite the committed timings for nothing. `--force` takes the new.
    let stored = match opts.force {
        false => super::read_stored::<BvpResult>(&dir, "bvp.json").ok(),
        true => None,
    };
    let (result, kept) = match stored {
        Some(old) if super::same_apart_from(&old, &result, "wall_s") => (old, true),
        _ => (result, false),
    };
    // The figures first: a failure there leaves the tables of the last run
    // beside its figures.
    let written = (|| {
        let plots = draw(exp, spec, &dir, &result)?;
        write_json(&dir.join("bvp.json"), &result)?;
        write_tables(exp, &dir, &result)?;
        write_summary(exp, spec, &dir, &result, &plots)?;
        write_html(exp, spec, &dir, &result, &plots)?;
        write_manifest(exp, &dir, started, threads)?;
        Ok::<_, String>(plots)
    })();
    let plots = written.map_err(CliError::Output)?;
    out.finish();
    let all = result.points.iter().flat_map(|p| &p.solves);
    let failed = all.clone().filter(|s| s.status == "failed").count()
        + result
            .points
            .iter()
            .flat_map(|p| &p.ivp)
            .filter(|i| i.status == "failed")
            .count();
    Ok(Outcome {
        dir,
        points: result.points.len(),
        reused: if kept { result.points.len() } else { 0 },
        failed_runs: failed,
        stopped_runs: 0,
        budget_runs: 0,
        runs: all.count() + result.points.iter().map(|p| p.ivp.len()).sum::<usize>(),
        failed_references: 0,
        plots,
    })
}

/// Redraws the figures and the page from `bvp.json` (`nonholo plot`).
pub fn redraw(exp: &Experiment, out: super::ResultsDir) -> Result<Vec<PathBuf>, CliError> {
    let spec = spec_of(exp)?;
    let dir = out.path().to_path_buf();
    let path = dir.join("bvp.json");
    let result: BvpResult = super::read_stored(&dir, "bvp.json")?;
    let per_point = spec.lines.len() * spec.horizons.len() * spec.h.len();
    let current = result.schema == SCHEMA
        && result.points.len() == exp.points().len()
        && result.points.iter().zip(exp.points()).all(|(r, p)| {
            r.values == p.values
                && r.solves.len() == per_point
                && r.ivp
                    .iter()
                    .map(|i| &i.label)
                    .eq(exp.formulations.iter().map(|f| &f.label))
        });
    if !current {
        return Err(CliError::Input(format!(
            "{}: computed for another version of the experiment (run it again)",
            path.display()
        )));
    }
    let plots = (|| {
        let plots = draw(exp, spec, &dir, &result)?;
        write_html(exp, spec, &dir, &result, &plots)?;
        Ok::<_, String>(plots)
    })()
    .map_err(CliError::Output)?;
    out.finish();
    Ok(plots)
}

fn write_tables(exp: &Experiment, dir: &Path, r: &BvpResult) -> Result<(), String> {
    let axes = || r.axes.iter().map(String::as_str);
    let spec = exp.bvp.as_ref().ok_or("no [bvp]")?;
    let mut header: Vec<String> = ["point"]
        .into_iter()
        .chain(axes())
        .map(String::from)
        .collect();
    header.extend(
        [
            "label",
            "formulation",
            "variant",
            "ends",
            "map_form",
            "horizon",
            "h",
            "intervals",
            "status",
            "iterations",
            "damped_steps",
            "residual",
            "unknowns",
            "nonzeros",
            "wall_s",
        ]
        .map(String::from),
    );
    header.extend(exp.formulations.iter().map(|f| format!("err_{}", f.label)));
    header.extend(
        [
            "order",
            "self_difference",
            "self_order",
            "error_estimate",
            "constraint_max",
            "energy_drift",
            "reference_error",
            "error",
        ]
        .map(String::from),
    );
    let mut solves = Table::new(header)?;
    let mut st = Table::new(
        ["point"]
            .into_iter()
            .chain(axes())
            .chain([
                "horizon",
                "h",
                "under",
                "of",
                "max",
                "rms",
                "t",
                "coordinate",
                "constraint_max",
                "error",
            ])
            .map(String::from)
            .collect::<Vec<_>>(),
    )?;
    let mut hz = Table::new(
        ["point"]
            .into_iter()
            .chain(axes())
            .chain(["label", "h", "horizon", "spread"])
            .map(String::from)
            .collect::<Vec<_>>(),
    )?;
    let mut ivp = Table::new(
        ["point"]
            .into_iter()
            .chain(axes())
            .chain([
                "label",
                "formulation",
                "status",
                "t_last",
                "reversals",
                "first_reversal",
                "wall_s",
                "error",
            ])
            .map(String::from)
            .collect::<Vec<_>>(),
    )?;
    let opt = |v: Option<f64>| v.map(Plain);
    for p in &r.points {
        for i in &p.ivp {
            ivp.push(&(
                p.index,
                &p.values,
                (
                    &i.label,
                    &i.formulation,
                    &i.status,
                    opt(i.t_last),
                    exp.reversals.as_ref().map(|_| i.reversals.len()),
                    opt(i.reversals.first().copied()),
                    Plain(i.wall_s),
                    i.error.as_deref().unwrap_or(""),
                ),
            ))?;
        }
        for s in &p.solves {
            let line = spec
                .lines
                .iter()
                .find(|l| l.label == s.label)
                .ok_or("unknown line")?;
            let head = (
                p.index,
                &p.values,
                (
                    &s.label,
                    &line.formulation,
                    variant(&line.resolved),
                    line.resolved.ends_name(),
                    map_form_name(&line.resolved).unwrap_or(""),
                    Plain(s.horizon),
                    Plain(s.h),
                    s.intervals,
                    &s.status,
                    s.iterations,
                    s.damped_steps,
                    opt(s.residual),
                ),
            );
            let tail = (
                s.unknowns,
                s.nonzeros,
                opt(s.wall_s),
                s.errors.iter().map(|e| opt(*e)).collect::<Vec<_>>(),
                (
                    opt(s.order),
                    opt(s.self_difference),
                    opt(s.self_order),
                    opt(s.error_estimate),
                    opt(s.constraint_max),
                    opt(s.energy_drift),
                    opt(p.reference_error),
                    s.error.as_deref().unwrap_or(""),
                ),
            );
            solves.push(&(head, tail))?;
        }
        for s in &p.stationarity {
            st.push(&(
                p.index,
                &p.values,
                (
                    Plain(s.horizon),
                    Plain(s.h),
                    &s.under,
                    &s.of,
                    opt(s.max),
                    opt(s.rms),
                    opt(s.t),
                    s.coordinate.as_deref().unwrap_or(""),
                    opt(s.constraint_max),
                    s.error.as_deref().unwrap_or(""),
                ),
            ))?;
        }
        for h in &p.horizons {
            hz.push(&(
                p.index,
                &p.values,
                (&h.label, Plain(h.h), Plain(h.horizon), opt(h.spread)),
            ))?;
        }
    }
    ivp.write(&dir.join("ivp.csv"))?;
    solves.write(&dir.join("solves.csv"))?;
    st.write(&dir.join("stationarity.csv"))?;
    hz.write(&dir.join("horizons.csv"))
}

/// One pen per line: the initial-value lines as in every experiment, then
/// the boundary-value lines in their formulation's colour with the next
/// free dash (C's solve dashed beside C's motion, say).
fn pens(exp: &Experiment, spec: &BvpSpec) -> Vec<(String, Pen)> {
    let mut pens = Pens::default();
    let mut out: Vec<(String, Pen)> = exp
        .formulations
        .iter()
        .map(|f| {
            (
                f.label.clone(),
                pens.take(&f.formulation, &f.settings.integrator),
            )
        })
        .collect();
    for l in &spec.lines {
        out.push((l.label.clone(), pens.take(&l.formulation, "bvp")));
    }
    out
}

/// The unit of the coordinates, for axes (`m`, `m or rad`).
fn coordinate_unit(scene: &str) -> String {
    let Ok(info) = nonholo_scenes::info(scene) else {
        return "–".into();
    };
    let mut units: Vec<&str> = Vec::new();
    for c in info.coordinates {
        let u = if c.unit.is_empty() { "–" } else { c.unit };
        if !units.contains(&u) {
            units.push(u);
        }
    }
    units.join(" or ")
}

/// The two coordinates the paths figure draws: `[plots] phase`, or the
/// first two.
fn path_axes(exp: &Experiment) -> Option<[usize; 2]> {
    let info = exp.scene_info().ok()?;
    match &exp.phase {
        Some([a, b]) => Some([info.coordinate_index(a)?, info.coordinate_index(b)?]),
        None if info.n() >= 2 => Some([0, 1]),
        None => None,
    }
}

/// Checks what the runner relies on beyond the spec (called at load).
pub fn check(exp: &Experiment) -> Result<(), String> {
    if exp.bvp.is_none() {
        return Ok(());
    }
    if exp.phase.is_some() && path_axes(exp).is_none() {
        return Err(
            "`plots.phase`: a bvp experiment draws coordinates of its scene against each other"
                .into(),
        );
    }
    Ok(())
}

fn draw(
    exp: &Experiment,
    spec: &BvpSpec,
    dir: &Path,
    r: &BvpResult,
) -> Result<Vec<PathBuf>, String> {
    let pens = pens(exp, spec);
    let pen = |l: &str| super::pens::find(&pens, l);
    let unit = coordinate_unit(&exp.scene);
    let reference = exp
        .formulations
        .iter()
        .position(|f| f.label == spec.ends_from)
        .ok_or("no ends_from line")?;
    let t1 = spec.horizons[spec.horizons.len() - 1];
    let mut written = Vec::new();
    let plots = dir.join("plots");
    for p in &r.points {
        let at_t1 = |s: &&SolveOut| s.horizon == t1;
        let where_ = describe(&r.axes, &p.values);
        // Error against h, and against the Newton solve's wall time.
        let mut conv = Vec::new();
        let mut cost = Vec::new();
        for l in &spec.lines {
            let rows: Vec<&SolveOut> = p
                .solves
                .iter()
                .filter(at_t1)
                .filter(|s| s.label == l.label && s.errors[reference].is_some_and(|e| e > 0.0))
                .collect();
            let label = format!("{} ({})", l.label, line_name(l));
            conv.push(Series {
                label: label.clone(),
                x: rows.iter().map(|s| s.h).collect(),
                y: rows
                    .iter()
                    .map(|s| s.errors[reference].unwrap_or(f64::NAN))
                    .collect(),
                pen: pen(&l.label),
            });
            cost.push(Series {
                label,
                x: rows.iter().map(|s| s.wall_s.unwrap_or(f64::NAN)).collect(),
                y: rows
                    .iter()
                    .map(|s| s.errors[reference].unwrap_or(f64::NAN))
                    .collect(),
                pen: pen(&l.label),
            });
        }
        // An order-2 guide, a third below the smallest coarsest error (so
        // that it hides no line), where some line converges at about that
        // order (not where every error is round-off).
        let second_order = p
            .solves
            .iter()
            .filter(at_t1)
            .any(|s| s.order.is_some_and(|o| (o - 2.0).abs() < 0.5));
        let lowest = conv
            .iter()
            .filter(|s| !s.x.is_empty() && second_order)
            .min_by(|a, b| a.y[0].total_cmp(&b.y[0]));
        if let Some(first) = lowest {
            let (h0, e0) = (first.x[0], first.y[0] / 3.0);
            let x: Vec<f64> = spec.h.clone();
            conv.push(Series {
                label: "slope 2 (h²)".into(),
                y: x.iter().map(|h| e0 * (h / h0).powi(2)).collect(),
                x,
                pen: Some(Pen {
                    colour: 6,
                    dash: Dash::Dotted,
                }),
            });
        }
        let y_err = format!(
            "largest error at the nodes, against {} [{unit}]",
            spec.ends_from
        );
        written.extend(line_plot(
            &LinePlot {
                title: format!(
                    "Error against {}'s motion, t1 = {} s{where_}",
                    spec.ends_from,
                    crate::fields::num(t1)
                ),
                x_label: "grid spacing h [s]".into(),
                y_label: y_err.clone(),
                log_x: true,
                log_y: true,
                series: conv,
                ..LinePlot::default()
            },
            &plots.join(format!("convergence-p{}", p.index)),
        )?);
        written.extend(line_plot(
            &LinePlot {
                title: format!("Error against the cost of the solve{where_}"),
                x_label: "wall time of the solve [s]".into(),
                y_label: y_err,
                log_x: true,
                log_y: true,
                series: cost,
                ..LinePlot::default()
            },
            &plots.join(format!("cost-p{}", p.index)),
        )?);
        // Newton's iterations against h, a failure drawn at the limit.
        let mut newton = Vec::new();
        for l in &spec.lines {
            let rows: Vec<&SolveOut> = p
                .solves
                .iter()
                .filter(at_t1)
                .filter(|s| s.label == l.label)
                .collect();
            let failed = rows.iter().filter(|s| s.status == "failed").count();
            newton.push(Series {
                label: if failed == 0 {
                    l.label.clone()
                } else {
                    format!("{} (failed at {failed} of {})", l.label, rows.len())
                },
                x: rows.iter().map(|s| s.h).collect(),
                y: rows
                    .iter()
                    .map(|s| s.iterations.unwrap_or(spec.max_iter) as f64)
                    .collect(),
                pen: pen(&l.label),
            });
        }
        written.extend(line_plot(
            &LinePlot {
                title: format!("Newton's method, t1 = {} s{where_}", crate::fields::num(t1)),
                x_label: "grid spacing h [s]".into(),
                y_label: format!(
                    "Newton iterations (a failure at the limit, {}) [count]",
                    spec.max_iter
                ),
                log_x: true,
                series: newton,
                ..LinePlot::default()
            },
            &plots.join(format!("newton-p{}", p.index)),
        )?);
        if !spec.stationarity.is_empty() {
            let mut series = Vec::new();
            let mut st_pens = Pens::default();
            for of in &spec.stationarity {
                let f = exp
                    .formulations
                    .iter()
                    .find(|f| f.label == *of)
                    .ok_or("unknown line")?;
                for l in spec
                    .lines
                    .iter()
                    .filter(|l| spec.stationarity_under.contains(&l.label))
                {
                    let rows: Vec<&StationarityOut> = p
                        .stationarity
                        .iter()
                        .filter(|s| s.horizon == t1 && s.of == *of && s.under == l.label)
                        .filter(|s| s.max.is_some_and(|m| m > 0.0))
                        .collect();
                    series.push(Series {
                        label: format!("{of}'s motion under {}", l.label),
                        x: rows.iter().map(|s| s.h).collect(),
                        y: rows.iter().map(|s| s.max.unwrap_or(f64::NAN)).collect(),
                        pen: Some(st_pens.take(&f.formulation, "dop853")),
                    });
                }
            }
            written.extend(line_plot(
                &LinePlot {
                    title: format!(
                        "Stationarity of the motions, t1 = {} s{where_}",
                        crate::fields::num(t1)
                    ),
                    x_label: "grid spacing h [s]".into(),
                    y_label: "largest stationarity residual [N or N m]".into(),
                    log_x: true,
                    log_y: true,
                    series,
                    ..LinePlot::default()
                },
                &plots.join(format!("stationarity-p{}", p.index)),
            )?);
        }
        if spec.horizons.len() > 1 {
            let mut series = Vec::new();
            let mut hz_pens = Pens::default();
            for l in &spec.lines {
                for &t in &spec.horizons[1..] {
                    let rows: Vec<&HorizonOut> = p
                        .horizons
                        .iter()
                        .filter(|x| x.label == l.label && x.horizon == t)
                        .filter(|x| x.spread.is_some_and(|s| s > 0.0))
                        .collect();
                    series.push(Series {
                        label: format!("{}, t1 = {} s", l.label, crate::fields::num(t)),
                        x: rows.iter().map(|x| x.h).collect(),
                        y: rows.iter().map(|x| x.spread.unwrap_or(f64::NAN)).collect(),
                        pen: Some(hz_pens.take(&l.formulation, "bvp")),
                    });
                }
            }
            written.extend(line_plot(
                &LinePlot {
                    title: format!(
                        "Dependence on the horizon t1 on [0, {} s]{where_}",
                        crate::fields::num(spec.horizons[0])
                    ),
                    x_label: "grid spacing h [s]".into(),
                    y_label: format!(
                        "largest difference from the solution with t1 = {} s [{unit}]",
                        crate::fields::num(spec.horizons[0])
                    ),
                    log_x: true,
                    log_y: true,
                    series,
                    ..LinePlot::default()
                },
                &plots.join(format!("horizons-p{}", p.index)),
            )?);
        }
        if let Some([a, b]) = path_axes(exp) {
            let info = exp.scene_info()?;
            let series = p
                .paths
                .iter()
                .map(|path| Series {
                    label: path.label.clone(),
                    x: path.q.chunks(p.n).map(|q| q[a]).collect(),
                    y: path.q.chunks(p.n).map(|q| q[b]).collect(),
                    pen: pen(&path.label),
                })
                .collect();
            written.extend(line_plot(
                &LinePlot {
                    title: format!("The motions on [0, {} s]{where_}", crate::fields::num(t1)),
                    x_label: super::plots::quantity_label_in(Some(info), info.coordinates[a].name),
                    y_label: super::plots::quantity_label_in(Some(info), info.coordinates[b].name),
                    equal_aspect: info.coordinates[a].unit == info.coordinates[b].unit,
                    series,
                    ..LinePlot::default()
                },
                &plots.join(format!("paths-p{}", p.index)),
            )?);
        }
    }
    remove_other_figures(&plots, &written)?;
    Ok(written)
}

/// ` (name = value, …)` of a point, or nothing for a single point.
fn describe(axes: &[String], values: &[String]) -> String {
    if axes.is_empty() {
        return String::new();
    }
    let parts: Vec<String> = axes
        .iter()
        .zip(values)
        .map(|(a, v)| format!("{} = {v}", a.rsplit('.').next().unwrap_or(a)))
        .collect();
    format!(" ({})", parts.join(", "))
}

/// What a line solves, for legends: `C, fixed ends`, `A, implicit map`.
fn line_name(l: &super::spec::BvpLine) -> String {
    match &l.resolved {
        nonholo_variational::Formulation::Vakonomic => "C, fixed ends".into(),
        nonholo_variational::Formulation::Map { ends, form } => {
            format!("A, {} map, {} ends", form.name(), ends.name())
        }
        nonholo_variational::Formulation::General { end, .. } => {
            format!("A general, dependent end {}", end.name())
        }
    }
}

#[derive(Serialize)]
struct SummaryLine<'a> {
    label: &'a str,
    formulation: &'a str,
    variant: &'static str,
    ends: &'static str,
    map_form: Option<&'static str>,
    failed: usize,
}

#[derive(Serialize)]
struct Summary<'a> {
    schema: &'static str,
    name: &'a str,
    kind: &'static str,
    ends_from: &'a str,
    h: &'a [f64],
    horizons: &'a [f64],
    lines: Vec<SummaryLine<'a>>,
    plots: Vec<String>,
}

fn write_summary(
    exp: &Experiment,
    spec: &BvpSpec,
    dir: &Path,
    r: &BvpResult,
    plots: &[PathBuf],
) -> Result<(), String> {
    let summary = Summary {
        schema: "nonholo.bvp-summary/1",
        name: &exp.name,
        kind: "bvp",
        ends_from: &spec.ends_from,
        h: &spec.h,
        horizons: &spec.horizons,
        lines: spec
            .lines
            .iter()
            .map(|l| SummaryLine {
                label: &l.label,
                formulation: &l.formulation,
                variant: variant(&l.resolved),
                ends: l.resolved.ends_name(),
                map_form: map_form_name(&l.resolved),
                failed: r
                    .points
                    .iter()
                    .flat_map(|p| &p.solves)
                    .filter(|s| s.label == l.label && s.status == "failed")
                    .count(),
            })
            .collect(),
        plots: plots
            .iter()
            .filter(|p| p.extension().is_some_and(|e| e == "png"))
            .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
            .collect(),
    };
    write_json(&dir.join("summary.json"), &summary)
}

fn write_html(
    exp: &Experiment,
    spec: &BvpSpec,
    dir: &Path,
    r: &BvpResult,
    plots: &[PathBuf],
) -> Result<(), String> {
    let t1 = spec.horizons[spec.horizons.len() - 1];
    let h_min = spec.h[spec.h.len() - 1];
    let mut rows = vec![
        [
            "point",
            "line",
            "what",
            "intervals (finest)",
            "iterations",
            "error against ends_from",
            "order",
            "own estimate",
            "wall [s]",
            "status",
        ]
        .map(String::from)
        .to_vec(),
    ];
    let reference = exp
        .formulations
        .iter()
        .position(|f| f.label == spec.ends_from)
        .unwrap_or(0);
    for p in &r.points {
        for l in &spec.lines {
            let finest = p
                .solves
                .iter()
                .rfind(|s| s.label == l.label && s.horizon == t1 && s.h == h_min);
            let estimate = p
                .solves
                .iter()
                .filter(|s| s.label == l.label && s.horizon == t1)
                .filter_map(|s| s.error_estimate)
                .next_back();
            let Some(s) = finest else { continue };
            let num = |v: Option<f64>| v.map(table::Plain::text).unwrap_or_default();
            rows.push(vec![
                format!("{}{}", p.index, describe(&r.axes, &p.values)),
                l.label.clone(),
                line_name(l),
                s.intervals.to_string(),
                s.iterations.map(|i| i.to_string()).unwrap_or_default(),
                num(s.errors[reference]),
                num(s.order),
                num(estimate),
                num(s.wall_s),
                s.error.clone().unwrap_or_else(|| s.status.clone()),
            ]);
        }
    }
    let caption = |stem: &str| -> String {
        let kind = stem.rsplit_once("-p").map_or(stem, |(k, _)| k);
        match kind {
            "convergence" => format!(
                "Largest difference at the nodes (any coordinate) of each boundary-value \
                 solution from {}'s motion, against the grid spacing, on [0, {} s]; dotted: \
                 slope 2, the design order. Lines that solve the same discrete equations in \
                 another form (the map explicit or implicit) lie on each other where both \
                 converge; the Newton figure tells them apart.",
                spec.ends_from,
                crate::fields::num(t1)
            ),
            "cost" => "The same errors against the wall time of Newton's method (assembly, sparse \
                       LU factorisations, line search) on this machine."
                .into(),
            "newton" => format!(
                "Newton iterations to the tolerance {} from the starting path; a solve that did \
                 not converge is drawn at the limit of {} iterations (its residuals and worst \
                 nodes are in solves.csv). Lines that solve the same discrete equations lie on \
                 each other.",
                crate::fields::num(spec.tol),
                spec.max_iter
            ),
            "stationarity" => "Largest component of the gradient of the discrete action along \
                               each motion, its component along the constraints' normals \
                               removed (N, or N m for an angle), against h: zero up to the \
                               discretisation on a stationary path."
                .into(),
            "horizons" => format!(
                "How far each line's solution on [0, t1] is, on [0, {} s], from its solution \
                 with t1 = {} s, at the same nodes: falling like h² where the motion does not \
                 depend on the horizon. Lines that solve the same discrete equations lie on \
                 each other.",
                crate::fields::num(spec.horizons[0]),
                crate::fields::num(spec.horizons[0])
            ),
            _ => "The paths of the initial-value motions and of the boundary-value solutions (at \
                  the coarsest grid)."
                .into(),
        }
    };
    Page {
        exp,
        overview: String::new(),
        files: &[
            "solves.csv",
            "ivp.csv",
            "stationarity.csv",
            "horizons.csv",
            "bvp.json",
            "summary.json",
            "manifest.json",
        ],
        before: vec![(
            format!("On the finest grid, t1 = {} s", crate::fields::num(t1)),
            table::html(rows),
        )],
        plots,
        caption: &caption,
        after: Vec::new(),
    }
    .write(dir)
}
