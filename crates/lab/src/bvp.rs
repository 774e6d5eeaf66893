//! `nonholo bvp`: Hamilton's principle as a boundary-value problem — a
//! path with fixed ends made stationary by Newton's method on a grid
//! (crate `nonholo-variational`, docs/variational.md) — and the
//! stationarity residual of a given motion (`--stationarity-of`).
//!
//! The pieces here are shared with experiments of kind `bvp`
//! ([`crate::experiment::bvp`]): the variational formulation a name and its
//! options select ([`formulation`]), one solve on one grid with its
//! diagnostics ([`Job`], [`solve`]), and result files of `nonholo simulate`
//! read back as end data and starting paths ([`RunFile`]).

use std::path::PathBuf;

use clap::Args;
use nonholo_core::Scene;
use nonholo_core::monitor::Monitor;
use nonholo_variational as var;
use serde::Serialize;
use serde_json::Value as Json;

use crate::record::{
    Counters, DiagnosticsRecord, ErrorRecord, InitRecord, IntegratorRecord, RUN_SCHEMA, RunRecord,
    StatsRecord, params_json,
};
use crate::simulate::{flag, pairs};
use crate::{CliError, fields};

#[derive(Debug, Clone, Args)]
#[command(allow_negative_numbers = true)]
pub struct BvpArgs {
    /// Scene name (see `nonholo scenes`); with --ends-from or
    /// --stationarity-of it must be the file's scene (default: the file's).
    #[arg(long, allow_hyphen_values = true)]
    pub scene: Option<String>,
    /// `vakonomic` (C: every coordinate varied, constraints with
    /// multipliers) or `embedding` (A: the scene's map, or with --dependent
    /// the paper's general case, eq. 27–30).
    #[arg(long, default_value = "vakonomic", allow_hyphen_values = true)]
    pub formulation: String,
    /// Scene parameter, `name=value` (repeatable; over those of an
    /// --ends-from file).
    #[arg(long = "param", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub params: Vec<String>,
    /// A dependent coordinate of the paper's general case (repeatable, one
    /// per nonholonomic constraint): it follows the discretised eq. (28).
    #[arg(long = "dependent", value_name = "NAME", allow_hyphen_values = true)]
    pub dependent: Vec<String>,
    /// End conditions: `configuration` (default), `natural` or `full` for the
    /// map; `free` (default) or `fixed` for the dependent end values of the
    /// general case; `fixed` for vakonomic.
    #[arg(long, allow_hyphen_values = true)]
    pub ends: Option<String>,
    /// How the map is imposed at the nodes: `implicit` (default; regular
    /// where the map is singular) or `explicit` (eq. 14 as written).
    #[arg(long, allow_hyphen_values = true)]
    pub map_form: Option<String>,
    /// End of the horizon `t1` (the start is the end data's time, 0 by
    /// default); with --ends-from, one of the file's output times (default:
    /// its last).
    #[arg(long, allow_hyphen_values = true)]
    pub t_end: Option<f64>,
    /// Grid nodes, ends included (at least 3; 5 for the map).
    #[arg(long, default_value_t = 201, allow_hyphen_values = true)]
    pub nodes: usize,
    /// End data from a result file of `nonholo simulate` (or `bvp`), JSON:
    /// the state at its first time and at --t-end.
    #[arg(long, allow_hyphen_values = true)]
    pub ends_from: Option<PathBuf>,
    /// A coordinate at `t0`, `name=value` (repeatable; all of them, unless
    /// --ends-from gives them).
    #[arg(long = "q0", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub q0: Vec<String>,
    /// A coordinate at `t1` (repeatable), as --q0.
    #[arg(long = "q1", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub q1: Vec<String>,
    /// A velocity at `t0`, `<coord>_dot=value` (repeatable; `--ends full`
    /// needs every one), as --q0.
    #[arg(long = "qd0", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub qd0: Vec<String>,
    /// A velocity at `t1` (repeatable), as --qd0.
    #[arg(long = "qd1", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub qd1: Vec<String>,
    /// Starting path: `line` (straight between the ends, dependent values
    /// from the map; default) or a result file (JSON) interpolated at the
    /// nodes.
    #[arg(long, default_value = "line", allow_hyphen_values = true)]
    pub start: String,
    /// Solve on the grid halved twice as well (Richardson: measured order,
    /// error estimate, extrapolation); the finest path is written.
    #[arg(long)]
    pub refine: bool,
    /// Newton's tolerance on the scaled residual (forces in N or N m,
    /// constraints in their units).
    #[arg(long, default_value_t = 1e-10, allow_hyphen_values = true)]
    pub tol: f64,
    /// Largest number of Newton iterations.
    #[arg(long, default_value_t = 40, allow_hyphen_values = true)]
    pub max_iter: usize,
    /// Memory for the Newton matrix and its factors, in GB: larger grids
    /// are refused before anything is allocated.
    #[arg(long, default_value_t = 8.0, allow_hyphen_values = true)]
    pub max_memory: f64,
    /// Budget on wall-clock time in seconds for Newton's method (default:
    /// none).
    #[arg(long, allow_hyphen_values = true)]
    pub max_wall_time: Option<f64>,
    /// Do not solve: measure how far the motion in FILE (JSON, e.g. B's) is
    /// from a stationary path of this problem on the grid, and print it.
    #[arg(long, allow_hyphen_values = true)]
    pub stationarity_of: Option<PathBuf>,
    /// Print JSON instead of text (with --stationarity-of).
    #[arg(long)]
    pub json: bool,
    /// Write the path to FILE.json (schema `nonholo.run/1` with a `bvp`
    /// object) or FILE.csv plus FILE.csv.meta.json; default: a summary on
    /// stdout. The directory must exist.
    #[arg(long, allow_hyphen_values = true)]
    pub out: Option<PathBuf>,
}

/// Formulation names `nonholo bvp` and experiments of kind `bvp` take.
pub const FORMULATIONS: [&str; 2] = ["vakonomic", "embedding"];

/// The variational formulation of `name` on `scene`, with its end
/// conditions, map form and dependent coordinates (names); every choice
/// checked against what the scene has. An error names the choice it is
/// about: `formulation`, `dependent`, `ends` or `map_form` (the experiment
/// keys; `--formulation`, `--dependent`, `--ends`, `--map-form` on the
/// command line, [`choice_flag`]).
pub fn formulation(
    scene: &nonholo_core::SceneInfo,
    name: &str,
    dependent: &[String],
    ends: Option<&str>,
    map_form: Option<&str>,
) -> Result<var::Formulation, (&'static str, String)> {
    let choice = |what: &'static str, given: Option<&str>, valid: &[&str]| match given {
        Some(g) if !valid.contains(&g) => Err((
            what,
            format!(
                "`{g}` does not apply to formulation {name} here; valid: {}",
                valid.join(", ")
            ),
        )),
        _ => Ok(()),
    };
    match name {
        "vakonomic" => {
            if !dependent.is_empty() {
                return Err((
                    "dependent",
                    "dependent coordinates belong to the embedding's general case (formulation \
                     embedding); the vakonomic problem varies every coordinate"
                        .into(),
                ));
            }
            if map_form.is_some() {
                return Err((
                    "map_form",
                    "a map form belongs to formulation embedding".into(),
                ));
            }
            choice("ends", ends, &["fixed"])?;
            Ok(var::Formulation::Vakonomic)
        }
        "embedding" if !dependent.is_empty() => {
            if map_form.is_some() {
                return Err((
                    "map_form",
                    "a map form belongs to the embedding with the scene's map, not to the \
                     general case (dependent coordinates)"
                        .into(),
                ));
            }
            let indices = dependent
                .iter()
                .map(|d| {
                    scene.coordinate_index(d).ok_or_else(|| {
                        (
                            "dependent",
                            format!(
                                "`{d}` is not a coordinate of {} ({})",
                                scene.name,
                                scene
                                    .coordinates
                                    .iter()
                                    .map(|c| c.name)
                                    .collect::<Vec<_>>()
                                    .join(", ")
                            ),
                        )
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            if let Some(d) = crate::fields::repeated(dependent) {
                return Err(("dependent", format!("`{d}` is named twice")));
            }
            if indices.len() != scene.s() {
                return Err((
                    "dependent",
                    format!(
                        "{} dependent coordinates given ({}), but {} has {} nonholonomic \
                         constraint{}: the general case (eq. 27–30) solves each constraint for \
                         one dependent velocity",
                        indices.len(),
                        dependent.join(", "),
                        scene.name,
                        scene.s(),
                        if scene.s() == 1 { "" } else { "s" }
                    ),
                ));
            }
            choice("ends", ends, &["free", "fixed"])?;
            let end = match ends {
                Some("fixed") => var::DependentEnd::Fixed,
                _ => var::DependentEnd::Free,
            };
            Ok(var::Formulation::General {
                dependent: indices,
                end,
            })
        }
        "embedding" => {
            if scene.embedding.is_none() {
                return Err((
                    "dependent",
                    format!(
                        "{} has no embedding map (eq. 14): give its dependent coordinates \
                         (one per nonholonomic constraint) for the paper's general case \
                         (eq. 27–30)",
                        scene.name
                    ),
                ));
            }
            choice("ends", ends, &["configuration", "natural", "full"])?;
            choice("map_form", map_form, &["implicit", "explicit"])?;
            let ends = match ends {
                Some("natural") => var::MapEnds::Natural,
                Some("full") => var::MapEnds::Full,
                _ => var::MapEnds::Configuration,
            };
            let form = match map_form {
                Some("explicit") => var::MapForm::Explicit,
                _ => var::MapForm::Implicit,
            };
            Ok(var::Formulation::Map { ends, form })
        }
        other => Err((
            "formulation",
            format!(
                "`{other}` has no boundary-value form; valid: {}",
                FORMULATIONS.join(", ")
            ),
        )),
    }
}

/// The command-line flag of a choice [`formulation`] refused.
pub fn choice_flag(field: &str) -> String {
    format!("--{}", field.replace('_', "-"))
}

/// Name of a variational formulation in records: `vakonomic`,
/// `embedding-map` or `embedding-general`.
pub fn variant(f: &var::Formulation) -> &'static str {
    f.name()
}

/// The map form's name, if the formulation has one.
pub fn map_form_name(f: &var::Formulation) -> Option<&'static str> {
    match f {
        var::Formulation::Map { form, .. } => Some(form.name()),
        _ => None,
    }
}

/// One boundary-value problem to solve (and paths whose stationarity to
/// measure on its grid).
#[derive(Debug, Clone)]
pub struct Job {
    pub scene: String,
    pub params: Vec<(String, String)>,
    pub formulation: var::Formulation,
    pub t0: f64,
    pub t1: f64,
    pub intervals: usize,
    pub ends: var::Ends,
    /// Starting path at the nodes (node after node); the straight line
    /// between the ends if `None`.
    pub start: Option<Vec<f64>>,
    /// Solve on grids halved twice as well.
    pub refine: bool,
    /// Solve at all (without: only the stationarity of `check`).
    pub solve: bool,
    pub options: var::Options,
    /// Paths at the nodes whose stationarity residual is measured.
    pub check: Vec<Vec<f64>>,
}

/// The solution of a [`Job`] on its finest grid, with what the solve found.
#[derive(Debug, Clone)]
pub struct Solved {
    pub solution: var::Solution,
    /// Node velocities (central differences), node after node.
    pub qd: Vec<f64>,
    /// C's multipliers at the nodes (`λ = μ/h`), for the formulations that
    /// impose the constraints on every interval.
    pub lambda: Option<Vec<f64>>,
    pub diagnostics: nonholo_core::Diagnostics,
    /// The report of every level solved (one, or three with refinement).
    pub levels: Vec<var::Report>,
    pub refinement: Option<RefinementRecord>,
    pub multipliers: usize,
}

/// What grid refinement found ([`var::refine`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RefinementRecord {
    /// Intervals of the three grids.
    pub intervals: [usize; 3],
    /// Largest difference at the coarse nodes between levels 0–1 and 1–2.
    pub differences: [f64; 2],
    /// `log2` of their ratio (`None` where a difference is zero: no
    /// discretisation error to measure).
    pub order: Option<f64>,
    pub design_order: f64,
    /// Error estimate of the finest path, `d₂/(2^p − 1)`.
    pub error_estimate: f64,
    /// Error estimate of the Richardson extrapolation at the coarse nodes.
    pub extrapolated_error: f64,
}

/// What a [`Job`] produced: the solution (or why there is none) and the
/// stationarity of each checked path.
#[derive(Debug, Clone)]
pub struct JobOutcome {
    pub solved: Option<Result<Solved, var::Error>>,
    pub stationarity: Vec<Result<var::Stationarity, var::Error>>,
    pub wall_seconds: f64,
}

/// Solves `job` (and measures its checks). Refused input (a scene, its
/// parameters) is an `Err`; a solve that fails is in the outcome.
pub fn solve(job: &Job) -> Result<JobOutcome, CliError> {
    let scene = nonholo_scenes::build(&job.scene, &job.params)?;
    Ok(scene.visit(Visit(job)))
}

struct Visit<'a>(&'a Job);

impl nonholo_scenes::SceneVisitor for Visit<'_> {
    type Output = JobOutcome;
    fn visit<S: Scene>(self, scene: S) -> JobOutcome {
        let job = self.0;
        let wall = std::time::Instant::now();
        let problem = var::Problem::with_limit(
            &scene,
            job.formulation.clone(),
            job.t0,
            job.t1,
            job.intervals,
            job.ends.clone(),
            job.options.max_bytes,
        );
        let problem = match problem {
            Ok(p) => p,
            Err(e) => {
                return JobOutcome {
                    solved: job.solve.then(|| Err(e.clone())),
                    stationarity: job.check.iter().map(|_| Err(e.clone())).collect(),
                    wall_seconds: wall.elapsed().as_secs_f64(),
                };
            }
        };
        let stationarity = job
            .check
            .iter()
            .map(|path| var::Solver::new(&problem, &job.options)?.stationarity(path))
            .collect();
        let solved = job.solve.then(|| solve_on(&scene, &problem, job));
        JobOutcome {
            solved,
            stationarity,
            wall_seconds: wall.elapsed().as_secs_f64(),
        }
    }
}

fn solve_on<S: Scene>(
    scene: &S,
    problem: &var::Problem<'_, S>,
    job: &Job,
) -> Result<Solved, var::Error> {
    let start = match &job.start {
        Some(s) => s.clone(),
        None => problem.start_line(),
    };
    let (solution, levels, refinement, finest) = if job.refine {
        let r = var::refine(
            scene,
            &job.formulation,
            (job.t0, job.t1),
            job.intervals,
            &job.ends,
            Some(&start),
            &job.options,
        )?;
        let record = RefinementRecord {
            intervals: [job.intervals, 2 * job.intervals, 4 * job.intervals],
            differences: r.differences,
            order: r.order.is_finite().then_some(r.order),
            design_order: var::DESIGN_ORDER,
            error_estimate: r.error_estimate,
            extrapolated_error: r.extrapolated_error,
        };
        let levels = r.solutions.iter().map(|s| s.report.clone()).collect();
        let finest = var::Problem::with_limit(
            scene,
            job.formulation.clone(),
            job.t0,
            job.t1,
            4 * job.intervals,
            job.ends.clone(),
            job.options.max_bytes,
        )?;
        let solution = r.solutions.into_iter().last().expect("three levels");
        (solution, levels, Some(record), Some(finest))
    } else {
        let solution = var::Solver::new(problem, &job.options)?.solve(&start, &job.options)?;
        let levels = vec![solution.report.clone()];
        (solution, levels, None, None)
    };
    let on = finest.as_ref().unwrap_or(problem);
    let lambda = on.node_multipliers(&solution.multipliers);
    let qd = solution.velocities();
    let n = solution.n;
    let mut monitor = Monitor::new(scene);
    for (k, t) in solution.t.iter().enumerate() {
        monitor.record(
            scene,
            *t,
            &solution.q[k * n..(k + 1) * n],
            &qd[k * n..(k + 1) * n],
        );
    }
    Ok(Solved {
        qd,
        lambda,
        diagnostics: monitor.diagnostics().clone(),
        levels,
        refinement,
        multipliers: on.multipliers(),
        solution,
    })
}

/// The `bvp` object of a result file (docs/schema.md).
#[derive(Debug, Clone, Serialize)]
pub struct BvpRecord {
    /// `vakonomic`, `embedding-map` or `embedding-general`.
    pub variant: String,
    /// `fixed` (vakonomic), `configuration`/`natural`/`full` (map),
    /// `free`/`fixed` (general case: the dependent end values at `t1`).
    pub ends: String,
    /// `implicit` or `explicit` (the map only).
    pub map_form: Option<String>,
    /// Dependent coordinates (the map's, or the general case's).
    pub dependent: Vec<String>,
    pub t0: f64,
    pub t1: f64,
    /// Of the written (finest) grid.
    pub nodes: usize,
    pub intervals: usize,
    pub unknowns: usize,
    pub multipliers: usize,
    /// Stored entries of the Newton matrix.
    pub nonzeros: usize,
    pub newton_tol: f64,
    pub max_iter: usize,
    /// Per level solved (one; three with refinement, coarse to fine).
    pub levels: Vec<LevelRecord>,
    pub refinement: Option<RefinementRecord>,
    /// `line` or the starting file's path.
    pub start: String,
    /// The file the end data came from, if any.
    pub ends_from: Option<String>,
}

/// One Newton solve.
#[derive(Debug, Clone, Serialize)]
pub struct LevelRecord {
    pub intervals: usize,
    pub unknowns: usize,
    pub nonzeros: usize,
    pub iterations: usize,
    /// Scaled residual before each iteration and at the end.
    pub residual_history: Vec<f64>,
    /// Largest coordinate change of each step.
    pub step_history: Vec<f64>,
    pub damped_steps: usize,
    pub assembly_seconds: f64,
    pub factor_seconds: f64,
    pub wall_seconds: f64,
}

impl From<&var::Report> for LevelRecord {
    fn from(r: &var::Report) -> Self {
        LevelRecord {
            intervals: r.nodes - 1,
            unknowns: r.unknowns,
            nonzeros: r.nonzeros,
            iterations: r.iterations,
            residual_history: r.residual_history.clone(),
            step_history: r.step_history.clone(),
            damped_steps: r.damped_steps,
            assembly_seconds: r.assembly_seconds,
            factor_seconds: r.factor_seconds,
            wall_seconds: r.wall_seconds,
        }
    }
}

/// Method name of a boundary-value solve in `integrator.method`.
pub const METHOD: &str = "bvp-midpoint";

/// The result record of a solved job: `nonholo.run/1` with the `bvp`
/// object. Refuses (with the column and time) a value that is not finite.
pub fn record(
    job: &Job,
    solved: &Solved,
    outcome: &JobOutcome,
    start: &str,
    ends_from: Option<&str>,
) -> Result<RunRecord, String> {
    let scene = nonholo_scenes::build(&job.scene, &job.params).map_err(|e| e.to_string())?;
    let info = scene.info();
    let sol = &solved.solution;
    let n = sol.n;
    let rows =
        |v: &[f64], w: usize| -> Vec<Vec<f64>> { v.chunks(w).map(<[f64]>::to_vec).collect() };
    let q = rows(&sol.q, n);
    let q_dot = rows(&solved.qd, n);
    let lambda = solved.lambda.as_ref().map(|l| rows(l, info.s()));
    for (what, table) in [
        ("q", Some(&q)),
        ("q_dot", Some(&q_dot)),
        ("lambda", lambda.as_ref()),
    ] {
        for (k, r) in table.into_iter().flatten().enumerate() {
            if let Some(j) = r.iter().position(|v| !v.is_finite()) {
                return Err(format!(
                    "refusing to write a non-finite value: {what}[{j}] = {} at t = {}",
                    r[j], sol.t[k]
                ));
            }
        }
    }
    let d = DiagnosticsRecord::from(&solved.diagnostics);
    let mut scalars: Vec<(String, f64)> = vec![
        (
            "diagnostics.constraint_residual_max".into(),
            d.constraint_residual_max,
        ),
        ("diagnostics.energy_initial".into(), d.energy_initial),
        ("diagnostics.energy_final".into(), d.energy_final),
        ("diagnostics.energy_drift_max".into(), d.energy_drift_max),
    ];
    for inv in &d.invariants {
        scalars.push((format!("diagnostics.invariants.{}", inv.name), inv.initial));
        scalars.push((
            format!("diagnostics.invariants.{}", inv.name),
            inv.drift_max,
        ));
    }
    for (i, l) in solved.levels.iter().enumerate() {
        for v in l.residual_history.iter().chain(&l.step_history) {
            scalars.push((format!("bvp.levels[{i}]"), *v));
        }
    }
    if let Some(f) = &solved.refinement {
        for v in f
            .differences
            .iter()
            .chain([&f.error_estimate, &f.extrapolated_error])
        {
            scalars.push(("bvp.refinement".into(), *v));
        }
    }
    if let Some((name, v)) = scalars.iter().find(|(_, v)| !v.is_finite()) {
        return Err(format!(
            "refusing to write a non-finite value: {name} = {v}"
        ));
    }
    let dependent = match &job.formulation {
        var::Formulation::General { dependent, .. } => dependent.clone(),
        var::Formulation::Map { .. } => info
            .embedding
            .map(|e| e.dependent.to_vec())
            .unwrap_or_default(),
        var::Formulation::Vakonomic => Vec::new(),
    };
    let iterations: usize = solved.levels.iter().map(|l| l.iterations).sum();
    let finest = solved.levels.last().cloned().unwrap_or_default();
    let mut options = serde_json::Map::new();
    options.insert("ends".into(), Json::from(job.formulation.ends_name()));
    if let Some(f) = map_form_name(&job.formulation) {
        options.insert("map_form".into(), Json::from(f));
    }
    if !dependent.is_empty() {
        options.insert(
            "dependent".into(),
            Json::from(
                dependent
                    .iter()
                    .map(|&i| info.coordinates[i].name)
                    .collect::<Vec<_>>(),
            ),
        );
    }
    Ok(RunRecord {
        schema: RUN_SCHEMA,
        scene: info.name.to_string(),
        formulation: match job.formulation {
            var::Formulation::Vakonomic => "vakonomic",
            _ => "embedding",
        }
        .to_string(),
        integrator: IntegratorRecord {
            method: METHOD.into(),
            rtol: job.options.tol,
            atol: job.options.tol,
            fixed_step: Some((job.t1 - job.t0) / (sol.t.len() - 1) as f64),
            max_steps: job.options.max_iter,
            max_wall_time_s: None,
            radau_newton: None,
            atol_components: None,
            h_init: None,
            h_max: None,
            output: sol.t.clone(),
            dense: false,
            hit_output: true,
            radau5: None,
            stiff_stop: false,
        },
        params: params_json(scene.params()),
        options,
        init: InitRecord {
            t0: job.t0,
            q: job.ends.q0.clone(),
            q_dot: qd_row(&solved.qd, n, 0),
            extra: serde_json::Map::new(),
            projection: None,
            report: serde_json::Map::new(),
        },
        coordinates: info
            .coordinates
            .iter()
            .map(|c| c.name.to_string())
            .collect(),
        t: sol.t.clone(),
        q,
        q_dot,
        multiplier_convention: lambda
            .is_some()
            .then_some("C: multipliers of the action, L + λᵀg (λ = μ/h of the discrete constraints, at the nodes)"),
        lambda,
        nu: None,
        diagnostics: d,
        stats: StatsRecord {
            counters: Counters {
                steps: sol.t.len() - 1,
                rejected_steps: 0,
                rhs_evals: 0,
                jacobian_evals: iterations,
                lu_decompositions: iterations,
                newton_failures: 0,
            },
            wall_time_s: outcome.wall_seconds,
            stiffness_detected: None,
        },
        crossings: Vec::new(),
        switches: Vec::new(),
        status: "completed",
        error: None::<ErrorRecord>,
        matching: None,
        bvp: Some(BvpRecord {
            variant: variant(&job.formulation).into(),
            ends: job.formulation.ends_name().into(),
            map_form: map_form_name(&job.formulation).map(String::from),
            dependent: dependent
                .iter()
                .map(|&i| info.coordinates[i].name.to_string())
                .collect(),
            t0: job.t0,
            t1: job.t1,
            nodes: sol.t.len(),
            intervals: sol.t.len() - 1,
            unknowns: finest.unknowns,
            multipliers: solved.multipliers,
            nonzeros: finest.nonzeros,
            newton_tol: job.options.tol,
            max_iter: job.options.max_iter,
            levels: solved.levels.iter().map(LevelRecord::from).collect(),
            refinement: solved.refinement.clone(),
            start: start.into(),
            ends_from: ends_from.map(String::from),
        }),
    })
}

fn qd_row(qd: &[f64], n: usize, k: usize) -> Vec<f64> {
    qd[k * n..(k + 1) * n].to_vec()
}

/// A result file of `nonholo simulate` or `nonholo bvp` (schema
/// `nonholo.run/1`), read for its samples.
#[derive(Debug, Clone)]
pub struct RunFile {
    pub path: PathBuf,
    pub scene: String,
    /// Its scene parameters as `name=value` pairs.
    pub params: Vec<(String, String)>,
    pub t: Vec<f64>,
    /// Samples, node after node.
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    pub n: usize,
}

impl RunFile {
    /// Reads `path`, refusing anything that is not a run of schema
    /// `nonholo.run/1` with at least two samples of finite numbers at
    /// increasing times.
    pub fn read(path: &std::path::Path) -> Result<RunFile, String> {
        let at = |m: String| format!("{}: {m}", path.display());
        let text = std::fs::read_to_string(path).map_err(|e| at(e.to_string()))?;
        let j: Json = serde_json::from_str(&text).map_err(|e| at(format!("not JSON: {e}")))?;
        if j.get("schema").and_then(Json::as_str) != Some(RUN_SCHEMA) {
            return Err(at(format!(
                "not a run file (schema {RUN_SCHEMA}: `nonholo simulate --out FILE.json`)"
            )));
        }
        let scene = j["scene"].as_str().unwrap_or_default().to_string();
        let params = j["params"]
            .as_object()
            .map(|o| {
                o.iter()
                    .map(|(k, v)| {
                        let text = match v {
                            Json::String(s) => s.clone(),
                            other => other.to_string(),
                        };
                        (k.clone(), text)
                    })
                    .collect()
            })
            .unwrap_or_default();
        let numbers = |key: &str| -> Result<Vec<f64>, String> {
            j[key]
                .as_array()
                .ok_or_else(|| at(format!("no `{key}` array")))?
                .iter()
                .map(|v| {
                    v.as_f64()
                        .ok_or_else(|| at(format!("`{key}` holds a non-number")))
                })
                .collect()
        };
        let matrix = |key: &str| -> Result<(Vec<f64>, usize), String> {
            let rows = j[key]
                .as_array()
                .ok_or_else(|| at(format!("no `{key}` array")))?;
            let mut out = Vec::new();
            let mut width = None;
            for r in rows {
                let r = r
                    .as_array()
                    .ok_or_else(|| at(format!("`{key}` is not a table")))?;
                if *width.get_or_insert(r.len()) != r.len() {
                    return Err(at(format!("`{key}` has rows of different lengths")));
                }
                for v in r {
                    out.push(
                        v.as_f64()
                            .ok_or_else(|| at(format!("`{key}` holds a non-number")))?,
                    );
                }
            }
            Ok((out, width.unwrap_or(0)))
        };
        let t = numbers("t")?;
        let (q, n) = matrix("q")?;
        let (qd, nd) = matrix("q_dot")?;
        if t.len() < 2 || q.len() != t.len() * n || qd.len() != q.len() || nd != n {
            return Err(at(format!(
                "{} samples of t with {} of q and {} of q_dot: a run needs at least two \
                 samples of each",
                t.len(),
                q.len() / n.max(1),
                qd.len() / nd.max(1)
            )));
        }
        if t.windows(2)
            .any(|w| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater))
        {
            return Err(at("its times do not increase".into()));
        }
        Ok(RunFile {
            path: path.to_path_buf(),
            scene,
            params,
            t,
            q,
            qd,
            n,
        })
    }

    /// The sample at `t` (one of the output times, to 1e-9 relative), as
    /// `(q, q̇)`.
    pub fn state_at(&self, t: f64) -> Result<(Vec<f64>, Vec<f64>), String> {
        let tol = 1e-9 * (1.0 + t.abs());
        let k = self
            .t
            .iter()
            .position(|&s| (s - t).abs() <= tol)
            .ok_or_else(|| {
                format!(
                    "{}: t = {} is not one of its output times ({} … {}): end data are taken at \
                     samples, not interpolated",
                    self.path.display(),
                    fields::num(t),
                    fields::num(self.t[0]),
                    fields::num(self.t[self.t.len() - 1])
                )
            })?;
        let n = self.n;
        Ok((
            self.q[k * n..(k + 1) * n].to_vec(),
            self.qd[k * n..(k + 1) * n].to_vec(),
        ))
    }

    /// The path at `times` (inside the file's span), node after node: cubic
    /// Hermite interpolation on the samples and their velocities (exact at
    /// samples; fourth order between them).
    pub fn sample(&self, times: &[f64]) -> Result<Vec<f64>, String> {
        let (first, last) = (self.t[0], self.t[self.t.len() - 1]);
        let n = self.n;
        let mut out = Vec::with_capacity(times.len() * n);
        for &t in times {
            let slack = 1e-9 * (1.0 + t.abs());
            if t < first - slack || t > last + slack {
                return Err(format!(
                    "{}: t = {} is outside its samples ({} … {})",
                    self.path.display(),
                    fields::num(t),
                    fields::num(first),
                    fields::num(last)
                ));
            }
            let j = self
                .t
                .partition_point(|&s| s <= t)
                .clamp(1, self.t.len() - 1);
            let (ta, tb) = (self.t[j - 1], self.t[j]);
            let h = tb - ta;
            let s = ((t - ta) / h).clamp(0.0, 1.0);
            let (h00, h10, h01, h11) = (
                (1.0 + 2.0 * s) * (1.0 - s) * (1.0 - s),
                s * (1.0 - s) * (1.0 - s),
                s * s * (3.0 - 2.0 * s),
                s * s * (s - 1.0),
            );
            for i in 0..n {
                let (qa, qb) = (self.q[(j - 1) * n + i], self.q[j * n + i]);
                let (va, vb) = (self.qd[(j - 1) * n + i], self.qd[j * n + i]);
                out.push(h00 * qa + h10 * h * va + h01 * qb + h11 * h * vb);
            }
        }
        Ok(out)
    }
}

/// Values `name=value` for every coordinate (`suffix` `""`) or velocity
/// (`"_dot"`) of `scene`, refusing unknown, repeated or missing names.
fn vector(
    flag_name: &str,
    scene: &nonholo_core::SceneInfo,
    given: &[(String, String)],
    suffix: &str,
) -> Result<Vec<f64>, CliError> {
    let n = scene.n();
    let mut out = vec![f64::NAN; n];
    for (k, v) in given {
        let i = scene
            .coordinates
            .iter()
            .position(|c| format!("{}{suffix}", c.name) == *k)
            .ok_or_else(|| {
                CliError::Input(format!(
                    "{flag_name}: `{k}` is not one of {}",
                    scene
                        .coordinates
                        .iter()
                        .map(|c| format!("{}{suffix}", c.name))
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
            })?;
        if !out[i].is_nan() {
            return Err(CliError::Input(format!("{flag_name}: `{k}` given twice")));
        }
        let x: f64 = v
            .parse()
            .ok()
            .filter(|x: &f64| x.is_finite())
            .ok_or_else(|| {
                CliError::Input(format!("{flag_name}: `{k}={v}` is not a finite number"))
            })?;
        out[i] = x;
    }
    if let Some(i) = out.iter().position(|x| x.is_nan()) {
        return Err(CliError::Input(format!(
            "{flag_name}: no value for `{}{suffix}` (give every one, or take them from \
             --ends-from)",
            scene.coordinates[i].name
        )));
    }
    Ok(out)
}

/// [`var::Problem::check_size`] on a built scene.
struct SizeCheck<'a> {
    formulation: &'a var::Formulation,
    span: (f64, f64),
    intervals: usize,
    ends: &'a var::Ends,
    max_bytes: f64,
}

impl nonholo_scenes::SceneVisitor for SizeCheck<'_> {
    type Output = Result<(), var::Error>;
    fn visit<S: Scene>(self, scene: S) -> Self::Output {
        var::Problem::check_size(
            &scene,
            self.formulation.clone(),
            self.span.0,
            self.span.1,
            self.intervals,
            self.ends.clone(),
            self.max_bytes,
        )
    }
}

/// The job `args` describe, every value checked, and the files it read.
fn job(args: &BvpArgs) -> Result<(Job, String, Option<String>), CliError> {
    let read = |name: &str, p: &PathBuf| flag(name, RunFile::read(p));
    let data = match (&args.stationarity_of, &args.ends_from) {
        (Some(p), _) => Some(read("--stationarity-of", p)?),
        (None, Some(p)) => Some(read("--ends-from", p)?),
        (None, None) => None,
    };
    let ends_file = match (&args.ends_from, &args.stationarity_of) {
        (Some(e), Some(_)) => Some(read("--ends-from", e)?),
        _ => data.clone(),
    };
    let scene_name = match (&args.scene, &data) {
        (Some(s), Some(d)) if *s != d.scene => {
            return Err(CliError::Input(format!(
                "--scene {s}: {} is a run of scene {}",
                d.path.display(),
                d.scene
            )));
        }
        (Some(s), _) => s.clone(),
        (None, Some(d)) => d.scene.clone(),
        (None, None) => {
            return Err(CliError::Input(
                "--scene: give the scene (or --ends-from a run of it)".into(),
            ));
        }
    };
    flag(
        "--scene",
        nonholo_scenes::info(&scene_name).map_err(|e| e.to_string()),
    )?;
    let mut params = data.as_ref().map(|d| d.params.clone()).unwrap_or_default();
    params = crate::experiment::spec::override_with(&params, &pairs("--param", &args.params)?);
    // The parameters resolve (ranges, names) before anything else is asked;
    // the built scene's description has its own size (`sleigh-train`).
    let info = nonholo_scenes::build(&scene_name, &params)?.info();
    let formulation = formulation(
        info,
        &args.formulation,
        &args.dependent,
        args.ends.as_deref(),
        args.map_form.as_deref(),
    )
    .map_err(|(field, m)| CliError::Input(format!("{}: {m}", choice_flag(field))))?;
    if args.nodes < 3 || args.nodes > 100_000_000 {
        return Err(CliError::Input(format!(
            "--nodes: {} (at least 3, at most 1e8)",
            args.nodes
        )));
    }
    let tol = flag("--tol", fields::rtol(args.tol))?;
    if args.max_iter == 0 || args.max_iter > 10_000 {
        return Err(CliError::Input(format!(
            "--max-iter: {} (1 to 10000)",
            args.max_iter
        )));
    }
    if !(args.max_memory.is_finite() && args.max_memory > 0.0) {
        return Err(CliError::Input(format!(
            "--max-memory: {} is not a positive number of GB",
            args.max_memory
        )));
    }
    for f in [&data, &ends_file].into_iter().flatten() {
        if f.scene != scene_name || f.n != info.n() {
            return Err(CliError::Input(format!(
                "{}: a run of scene {} with {} coordinates; the problem is on {} ({} \
                 coordinates)",
                f.path.display(),
                f.scene,
                f.n,
                info.name,
                info.n()
            )));
        }
    }
    let (t0, t1, ends) = match &ends_file {
        Some(f) => {
            let t0 = f.t[0];
            let t1 = args.t_end.unwrap_or(f.t[f.t.len() - 1]);
            let (q0, qd0) = f.state_at(t0).map_err(CliError::Input)?;
            let (q1, qd1) = flag("--t-end", f.state_at(t1))?;
            for (name, given) in [
                ("--q0", &args.q0),
                ("--q1", &args.q1),
                ("--qd0", &args.qd0),
                ("--qd1", &args.qd1),
            ] {
                if !given.is_empty() {
                    return Err(CliError::Input(format!(
                        "{name}: the end data come from {}",
                        f.path.display()
                    )));
                }
            }
            (
                t0,
                t1,
                var::Ends {
                    q0,
                    q1,
                    qd0: Some(qd0),
                    qd1: Some(qd1),
                },
            )
        }
        None => {
            let t1 = args
                .t_end
                .ok_or_else(|| CliError::Input("--t-end: give the end of the horizon".into()))?;
            let q0 = vector("--q0", info, &pairs("--q0", &args.q0)?, "")?;
            let q1 = vector("--q1", info, &pairs("--q1", &args.q1)?, "")?;
            let velocities = |name: &str, given: &[String]| {
                if given.is_empty() {
                    Ok(None)
                } else {
                    vector(name, info, &pairs(name, given)?, "_dot").map(Some)
                }
            };
            (
                0.0,
                t1,
                var::Ends {
                    q0,
                    q1,
                    qd0: velocities("--qd0", &args.qd0)?,
                    qd1: velocities("--qd1", &args.qd1)?,
                },
            )
        }
    };
    flag("--t-end", fields::t_end(t1 - t0).map(|_| ()))?;
    let intervals = args.nodes - 1;
    let max_bytes = args.max_memory * 1e9;
    // A grid too large for memory is refused before any path of its size
    // is made.
    nonholo_scenes::build(&scene_name, &params)?
        .visit(SizeCheck {
            formulation: &formulation,
            span: (t0, t1),
            intervals,
            ends: &ends,
            max_bytes,
        })
        .map_err(|e| cli_error(&e))?;
    // Node times, for paths read from files.
    let times = || -> Vec<f64> {
        (0..=intervals)
            .map(|k| var::node_time(t0, t1, intervals, k))
            .collect()
    };
    let (start, start_name) = match args.start.as_str() {
        "line" => (None, "line".to_string()),
        file => {
            let f = flag("--start", RunFile::read(std::path::Path::new(file)))?;
            (
                Some(flag("--start", f.sample(&times()))?),
                f.path.display().to_string(),
            )
        }
    };
    let check = match &args.stationarity_of {
        Some(_) => {
            let d = data.as_ref().expect("read above");
            vec![flag("--stationarity-of", d.sample(&times()))?]
        }
        None => Vec::new(),
    };
    if args.stationarity_of.is_some() && (args.out.is_some() || args.refine) {
        return Err(CliError::Input(
            "--stationarity-of measures a given path and solves nothing: --out and --refine \
             do not apply"
                .into(),
        ));
    }
    if args.json && args.stationarity_of.is_none() {
        return Err(CliError::Input(
            "--json prints the stationarity of --stationarity-of; a solution is written with \
             --out FILE.json"
                .into(),
        ));
    }
    Ok((
        Job {
            scene: scene_name,
            params,
            formulation,
            t0,
            t1,
            intervals,
            ends,
            start,
            refine: args.refine,
            solve: args.stationarity_of.is_none(),
            options: var::Options {
                max_iter: args.max_iter,
                tol,
                max_bytes,
                max_wall_time: args
                    .max_wall_time
                    .map(|s| flag("--max-wall-time", fields::max_wall_time(s)))
                    .transpose()?,
            },
            check,
        },
        start_name,
        args.ends_from.as_ref().map(|p| p.display().to_string()),
    ))
}

#[derive(Serialize)]
struct StationarityJson<'a> {
    schema: &'static str,
    scene: &'a str,
    file: String,
    variant: &'static str,
    ends: &'static str,
    t0: f64,
    t1: f64,
    nodes: usize,
    /// Largest component of the residual (N, or N m for an angle).
    max: f64,
    rms: f64,
    t: f64,
    coordinate: &'a str,
    constraint_max: f64,
}

/// Schema of `nonholo bvp --stationarity-of FILE --json`.
pub const STATIONARITY_SCHEMA: &str = "nonholo.stationarity/1";

/// Runs `nonholo bvp`.
pub fn command(args: &BvpArgs) -> Result<(), CliError> {
    let (job, start_name, ends_from) = job(args)?;
    let out = crate::simulate::out_files(args.out.as_ref(), false)?;
    let outcome = solve(&job)?;
    if let Some(path) = &args.stationarity_of {
        let st = match &outcome.stationarity[0] {
            Ok(s) => s,
            Err(e) => return Err(cli_error(e)),
        };
        if args.json {
            let doc = StationarityJson {
                schema: STATIONARITY_SCHEMA,
                scene: &job.scene,
                file: path.display().to_string(),
                variant: variant(&job.formulation),
                ends: job.formulation.ends_name(),
                t0: job.t0,
                t1: job.t1,
                nodes: job.intervals + 1,
                max: st.max,
                rms: st.rms,
                t: st.t,
                coordinate: &st.coordinate,
                constraint_max: st.constraint_max,
            };
            let mut text =
                serde_json::to_string_pretty(&doc).map_err(|e| CliError::Output(e.to_string()))?;
            text.push('\n');
            return crate::print_stdout(&text);
        }
        return crate::print_stdout(&format!(
            "stationarity of {} under {} ({} ends) on {} nodes over [{}, {}]:\n  largest {:.3e} \
             (N or N m) at t = {} ({}), rms {:.3e}; largest discrete constraint {:.3e}\n",
            path.display(),
            variant(&job.formulation),
            job.formulation.ends_name(),
            job.intervals + 1,
            fields::num(job.t0),
            fields::num(job.t1),
            st.max,
            fields::num(st.t),
            st.coordinate,
            st.rms,
            st.constraint_max
        ));
    }
    let solved = match outcome.solved.as_ref().expect("solve requested") {
        Ok(s) => s,
        Err(e) => return Err(cli_error(e)),
    };
    let record =
        record(&job, solved, &outcome, &start_name, ends_from.as_deref()).map_err(CliError::Run)?;
    match out {
        Some(out) => crate::simulate::write_record(&out, &record, &multiplier_names(&record)),
        None => crate::print_stdout(&summary(&record)),
    }
}

/// Refused input (exit 2: nothing was solved) or a solve that failed (1).
fn cli_error(e: &var::Error) -> CliError {
    match e {
        var::Error::TooLarge { .. } => CliError::Input(format!("--nodes, --max-memory: {e}")),
        // The solver's fields are the flags' names.
        var::Error::Input { field, reason }
            if [
                "t-end",
                "q0",
                "q1",
                "qd0",
                "qd1",
                "dependent",
                "nodes",
                "ends",
                "start",
            ]
            .contains(&field.as_str()) =>
        {
            CliError::Input(format!("--{field}: {reason}"))
        }
        var::Error::Input { .. }
        | var::Error::NotApplicable { .. }
        | var::Error::InconsistentEnds { .. } => CliError::Input(e.to_string()),
        var::Error::Singular { .. }
        | var::Error::NotFinite { .. }
        | var::Error::NotConverged { .. }
        | var::Error::TimeBudget { .. } => CliError::Run(e.to_string()),
    }
}

fn multiplier_names(r: &RunRecord) -> Vec<String> {
    let s = r
        .lambda
        .as_ref()
        .and_then(|l| l.first())
        .map_or(0, Vec::len);
    nonholo_core::model::multiplier_names(s, 0)
}

/// A short account of a solve.
pub fn summary(r: &RunRecord) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let Some(b) = &r.bvp else {
        return s;
    };
    let _ = writeln!(
        s,
        "scene {}, {} ({} ends{}), {} nodes on [{}, {}]",
        r.scene,
        b.variant,
        b.ends,
        b.map_form
            .as_ref()
            .map(|f| format!(", {f} map"))
            .unwrap_or_default(),
        b.nodes,
        fields::num(b.t0),
        fields::num(b.t1)
    );
    for l in &b.levels {
        let _ = writeln!(
            s,
            "  {} intervals: {} unknowns, {} stored entries, {} Newton iterations ({} damped), \
             residual {:.2e} → {:.2e}, {:.4} s",
            l.intervals,
            l.unknowns,
            l.nonzeros,
            l.iterations,
            l.damped_steps,
            l.residual_history.first().copied().unwrap_or(f64::NAN),
            l.residual_history.last().copied().unwrap_or(f64::NAN),
            l.wall_seconds
        );
    }
    if let Some(f) = &b.refinement {
        let _ = writeln!(
            s,
            "refinement: differences {:.3e}, {:.3e}; order {} (design {}); error of the \
             finest path ≈ {:.2e}, of the extrapolation ≈ {:.2e}",
            f.differences[0],
            f.differences[1],
            f.order
                .map_or("not measurable (a difference is zero)".into(), |o| format!(
                    "{o:.3}"
                )),
            f.design_order,
            f.error_estimate,
            f.extrapolated_error
        );
    }
    if let (Some(t), Some(q), Some(qd)) = (r.t.last(), r.q.last(), r.q_dot.last()) {
        let _ = writeln!(s, "state at t = {t} (velocities by differences):");
        for (i, c) in r.coordinates.iter().enumerate() {
            let _ = writeln!(
                s,
                "  {c:>8} = {:>22.15e}   {c}_dot = {:>22.15e}",
                q[i], qd[i]
            );
        }
    }
    let d = &r.diagnostics;
    let _ = writeln!(
        s,
        "constraint residual at the nodes max {:.3e}; energy {:.12e}, drift max {:.3e}",
        d.constraint_residual_max, d.energy_initial, d.energy_drift_max
    );
    s
}
