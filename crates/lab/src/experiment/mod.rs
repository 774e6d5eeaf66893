//! The experiment runner: `nonholo experiment FILE`.
//!
//! An experiment file ([`spec`]) names a scene, formulations to compare, a
//! time grid, a sweep and what to measure. [`run`] expands the sweep into
//! points ([`sweep`]), runs every point's formulations in parallel
//! ([`point`]), and writes to `results/<name>/`:
//!
//! | file | content |
//! |---|---|
//! | `points/<i>.json` | one point: swept values, every formulation's status, counters, diagnostics, every pair's divergence |
//! | `runs.csv` | one row per (point, formulation): swept values, status, counters, diagnostics, divergence from the reference formulation |
//! | `pairs.csv` | one row per (point, pair): divergence measures |
//! | `timing.csv` | wall times, and the time reached by runs a wall-time budget stopped (kept apart: the other tables are identical whatever the thread count and however the sweep was interrupted) |
//! | `trajectories/<i>-<label>.csv` | samples of the plotted point (of all points with `plots.all_trajectories`) |
//! | `summary.json`, `config.json`, `manifest.json` | aggregates; the resolved configuration; command, file hash, git revision, versions, machine, times |
//! | `plots/*.png`, `plots/*.svg`, `index.html` | the figures and a page showing them with the tables |
//!
//! Every file is written atomically, and the directory is locked while one
//! process writes it ([`dir`]). A point whose result file exists with
//! the same resume key ([`key`]: a hash of everything the point's results
//! depend on) is not run again (unless `--force`), so a sweep killed
//! half-way finishes with every point exactly once.
//!
//! Both kinds of experiment (comparisons here, work-precision in [`wp`])
//! share one results pipeline: point files and atomic writes ([`files`]),
//! the resume key ([`key`]), typed CSV records ([`crate::table`]), the page
//! ([`page`]) and the manifest ([`manifest`]). What is particular to a
//! comparison: [`point`] (running one point), [`output`] (its tables,
//! trajectories and summary), [`plots`].

pub mod bvp;
pub mod cli;
pub mod dir;
pub mod files;
pub mod key;
pub mod manifest;
pub mod minimise;
pub mod output;
pub mod page;
pub mod pens;
pub mod plots;
pub mod point;
pub mod reference;
pub mod shard;
pub mod spec;
pub mod stability;
pub mod sweep;
pub mod wp;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

pub use dir::ResultsDir;
pub use point::{Comparison, FormResult, PairResult, PointResult};
pub use spec::{Experiment, SpecError};

use crate::CliError;

/// The error of a run stopped by its wall-time budget, as result files give
/// it: where such a run stops depends on the machine and its load, so the
/// time reached and the counters are left out (docs/schema.md).
/// Whether a failed run's message is a used-up budget (`max_steps` or
/// `max_wall_time`), in the words of the integrator's error and of
/// [`wall_time_stop`].
pub fn budget_stop(error: Option<&str>) -> bool {
    error.is_some_and(|e| e.contains(" budget of ") && e.contains(" used up"))
}

pub fn wall_time_stop(seconds: f64) -> String {
    format!(
        "wall-time budget of {} s used up (a machine-dependent stop: the time reached and \
         the counters are left out of the results; a step budget, max_steps, stops at the \
         same place on every machine)",
        crate::fields::num(seconds)
    )
}

impl Experiment {
    /// Checks that `p` can be set up (called for every point at load).
    pub fn check_point(&self, p: &sweep::Point) -> Result<(), String> {
        point::check_point(self, p)
    }
}

/// The worker threads of a run (`threads`, else one per core) and their
/// pool.
pub(crate) fn worker_pool(threads: Option<usize>) -> Result<(rayon::ThreadPool, usize), CliError> {
    let threads = threads.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| CliError::Run(format!("cannot start {threads} worker threads: {e}")))?;
    Ok((pool, threads))
}

/// The stored result file `name` of an experiment of kind stability or
/// bvp, read for `nonholo plot`: refused if missing or unreadable.
pub(crate) fn read_stored<T: serde::de::DeserializeOwned>(
    dir: &Path,
    name: &str,
) -> Result<T, CliError> {
    let path = dir.join(name);
    let text = std::fs::read_to_string(&path).map_err(|e| {
        CliError::Input(format!(
            "{}: {e} (run the experiment first)",
            path.display()
        ))
    })?;
    serde_json::from_str(&text).map_err(|e| CliError::Input(format!("{}: {e}", path.display())))
}

/// How to run an experiment (where: the [`ResultsDir`] given to [`run`]).
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Run every point again even if its result is stored.
    pub force: bool,
    /// Worker threads (default: all cores).
    pub threads: Option<usize>,
    /// No progress output.
    pub quiet: bool,
    /// Compute only this slice of the points, and write only the points
    /// (no tables, figures or pages: `nonholo merge` writes those).
    pub shard: Option<shard::Shard>,
}

/// What a run of an experiment did.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    pub dir: PathBuf,
    pub points: usize,
    /// Points taken from stored results.
    pub reused: usize,
    /// (point, formulation) runs that failed (not counting designed stops).
    pub failed_runs: usize,
    /// Runs that stopped at a singular set.
    pub stopped_runs: usize,
    /// Of the failed runs, those that used up their step or wall-time
    /// budget ([`budget_stop`]): the designed end of an explicit method on
    /// a stiff problem, told apart in tables and figures.
    pub budget_runs: usize,
    pub runs: usize,
    /// Work-precision references that could not be computed: the runs of
    /// their lines have no error, and the experiment exits as if runs failed.
    pub failed_references: usize,
    pub plots: Vec<PathBuf>,
}

/// The default results directory of `exp`: `results/<name>` next to the
/// `experiments/` directory holding the file, else in the current directory.
pub fn default_dir(exp: &Experiment) -> PathBuf {
    let root = exp
        .path
        .parent()
        .filter(|p| p.file_name().is_some_and(|n| n == "experiments"))
        .and_then(|p| p.parent())
        .map(Path::to_path_buf)
        .unwrap_or_default();
    root.join("results").join(&exp.name)
}

/// Progress reporting: a bar on a terminal, a few plain lines otherwise.
struct Progress {
    total: usize,
    done: AtomicUsize,
    failed: AtomicUsize,
    bar: Option<indicatif::ProgressBar>,
    quiet: bool,
    lines: Mutex<usize>,
}

impl Progress {
    fn new(total: usize, quiet: bool, name: &str) -> Self {
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let b = indicatif::ProgressBar::new(total as u64);
            b.set_style(
                indicatif::ProgressStyle::with_template(
                    "{prefix} [{bar:30}] {pos}/{len} points, {msg} failed runs, {elapsed} elapsed, {eta} left",
                )
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
                .progress_chars("=> "),
            );
            b.set_prefix(name.to_string());
            b.set_message("0");
            b
        });
        Progress {
            total,
            done: AtomicUsize::new(0),
            failed: AtomicUsize::new(0),
            bar,
            quiet,
            lines: Mutex::new(0),
        }
    }

    fn point_done(&self, failed_runs: usize, reused: bool) {
        let done = self.done.fetch_add(1, Ordering::SeqCst) + 1;
        let failed = self.failed.fetch_add(failed_runs, Ordering::SeqCst) + failed_runs;
        if let Some(b) = &self.bar {
            b.set_message(failed.to_string());
            b.inc(1);
        } else if !self.quiet {
            // About twenty lines over the whole sweep.
            let every = self.total.div_ceil(20).max(1);
            let mut lines = self.lines.lock().unwrap_or_else(|e| e.into_inner());
            if done == self.total || done / every > *lines {
                *lines = done / every;
                crate::note!(
                    "{done}/{} points done ({failed} failed runs){}",
                    self.total,
                    if reused {
                        ", some reused from stored results"
                    } else {
                        ""
                    }
                );
            }
        }
    }

    fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish();
        }
    }
}

/// Whether the trajectory file at `path` has a column for each quantity
/// drawn against time (files written before the chart columns existed have
/// none: the point is computed again). Reads the header only.
fn has_series_columns(path: &Path, series: &[String]) -> bool {
    if series.is_empty() {
        return true;
    }
    let Ok(mut reader) = csv::Reader::from_path(path) else {
        return false;
    };
    let Ok(header) = reader.headers() else {
        return false;
    };
    series.iter().all(|s| header.iter().any(|h| h == s))
}

/// Whether two results agree in everything but their wall times (the
/// fields named `wall_key` at any depth, which no two runs share).
pub(crate) fn same_apart_from<T: serde::Serialize>(a: &T, b: &T, wall_key: &str) -> bool {
    fn strip(v: &mut serde_json::Value, key: &str) {
        match v {
            serde_json::Value::Object(m) => {
                m.remove(key);
                m.values_mut().for_each(|v| strip(v, key));
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(|v| strip(v, key)),
            _ => {}
        }
    }
    match (serde_json::to_value(a), serde_json::to_value(b)) {
        (Ok(mut a), Ok(mut b)) => {
            strip(&mut a, wall_key);
            strip(&mut b, wall_key);
            a == b
        }
        _ => false,
    }
}

/// The stored result of `p`, if it is for the same computation and holds a
/// run of every formulation, in the experiment's order (a point file cut
/// short or edited by hand is computed again, not reused).
fn stored(dir: &Path, exp: &Experiment, p: &sweep::Point) -> Option<PointResult> {
    let key = key::point_key(exp, p, point::POINT_SCHEMA).ok()?;
    let r: PointResult = files::stored(dir, p.index, point::POINT_SCHEMA, &key)?;
    let labels = r.body.formulations.iter().map(|f| f.label.as_str());
    labels
        .eq(exp.formulations.iter().map(|f| f.label.as_str()))
        .then_some(r)
}

/// How many runs of `r` failed.
fn failed_runs(r: &PointResult) -> usize {
    r.body
        .formulations
        .iter()
        .filter(|f| f.status == "failed")
        .count()
}

/// Whether `p` keeps its trajectories (for a figure, or all of them).
fn needs_trajectories(exp: &Experiment, p: &sweep::Point) -> bool {
    exp.all_trajectories || p.index == exp.plot_point || exp.also_points.contains(&p.index)
}

/// The stored result of `p` with its trajectories where it needs them.
fn complete(dir: &Path, exp: &Experiment, p: &sweep::Point) -> Option<PointResult> {
    stored(dir, exp, p).filter(|r| !needs_trajectories(exp, p) || has_trajectories(dir, exp, p, r))
}

/// Whether the trajectories of every run of `r` that has any are stored,
/// with every series the experiment asks for.
fn has_trajectories(dir: &Path, exp: &Experiment, p: &sweep::Point, r: &PointResult) -> bool {
    r.body
        .formulations
        .iter()
        .filter(|f| f.t_last.is_some())
        .all(|f| {
            let path = output::trajectory_path(dir, p.index, &f.label);
            path.exists() && has_series_columns(&path, &exp.series)
        })
}

/// Runs `exp` and writes its results (see the module documentation; a
/// work-precision experiment: [`wp`]).
pub fn run(exp: &Experiment, opts: &RunOptions, out: ResultsDir) -> Result<Outcome, CliError> {
    if exp.kind == spec::Kind::WorkPrecision {
        if opts.shard.is_some() {
            return Err(CliError::Input(format!(
                "{}: a work-precision experiment times its runs one at a time on one machine; \
                 --shard splits compare experiments only",
                exp.name
            )));
        }
        return wp::run(exp, opts, out);
    }
    if exp.kind == spec::Kind::Bvp {
        if opts.shard.is_some() {
            return Err(CliError::Input(format!(
                "{}: a bvp experiment takes seconds to a minute on one machine; --shard splits \
                 compare experiments only",
                exp.name
            )));
        }
        return bvp::run(exp, opts, out);
    }
    if exp.kind == spec::Kind::Stability {
        if opts.shard.is_some() {
            return Err(CliError::Input(format!(
                "{}: a stability experiment takes seconds on one machine; --shard splits \
                 compare experiments only",
                exp.name
            )));
        }
        return stability::run(exp, opts, out);
    }
    let started = std::time::SystemTime::now();
    let dir = &out.path().to_path_buf();
    if opts.shard.is_some() {
        out.prepare(&["points", "trajectories"])?;
    } else {
        out.prepare(&["points", "trajectories", "plots", minimise::CURVES])?;
    }
    let points = shard::slice(exp.points(), opts.shard);
    let (pool, threads) = worker_pool(opts.threads)?;
    let progress = Progress::new(points.len(), opts.quiet, &exp.name);
    let reused = AtomicUsize::new(0);

    let results: Vec<Result<PointResult, String>> = pool.install(|| {
        points
            .par_iter()
            .map(|p| {
                let needs_traj = needs_trajectories(exp, p);
                let mut old = if opts.force {
                    None
                } else {
                    stored(dir, exp, p)
                };
                if let Some(r) = old.take_if(|r| !needs_traj || has_trajectories(dir, exp, p, r)) {
                    reused.fetch_add(1, Ordering::SeqCst);
                    progress.point_done(failed_runs(&r), true);
                    return Ok(r);
                }
                let (r, samples) = point::run_point(exp, p);
                if needs_traj {
                    for s in &samples {
                        output::write_trajectory(dir, p.index, s)?;
                    }
                }
                // A stored result that lacked only its trajectories (they
                // are not committed) was computed again for them; where the
                // run agrees with it apart from wall times, the stored one
                // stays, so that drawing a plot on a fresh clone does not
                // rewrite the committed timings.
                let r = match old {
                    Some(old) if same_apart_from(&old, &r, "wall_time_s") => old,
                    _ => {
                        files::write_json(&files::point_path(dir, p.index), &r)?;
                        r
                    }
                };
                progress.point_done(failed_runs(&r), false);
                Ok(r)
            })
            .collect()
    });
    progress.finish();
    let results: Vec<PointResult> = results
        .into_iter()
        .collect::<Result<_, _>>()
        .map_err(CliError::Output)?;

    if let Some(s) = opts.shard {
        let indices: Vec<usize> = points.iter().map(|p| p.index).collect();
        shard::write_record(exp, dir, s, &indices).map_err(CliError::Output)?;
        manifest::write_manifest(exp, dir, started, threads).map_err(CliError::Output)?;
        out.finish();
        return Ok(outcome(
            dir,
            &results,
            reused.load(Ordering::SeqCst),
            Vec::new(),
        ));
    }

    if let Some(m) = &exp.minimise {
        if !opts.quiet {
            crate::note!(
                "{}: minimising the distance of {} from {} over {} at {} points",
                exp.name,
                m.label,
                exp.reference,
                m.over,
                points.len()
            );
        }
        pool.install(|| minimise::run(exp, m, dir, &points))
            .map_err(CliError::Output)?;
    }
    output::write_tables(exp, dir, &results).map_err(CliError::Output)?;
    let plots = plots::draw(exp, dir, &results).map_err(CliError::Output)?;
    output::write_summary(exp, dir, &results, &plots).map_err(CliError::Output)?;
    output::write_html(exp, dir, &results, &plots).map_err(CliError::Output)?;
    manifest::write_manifest(exp, dir, started, threads).map_err(CliError::Output)?;
    out.finish();
    Ok(outcome(dir, &results, reused.load(Ordering::SeqCst), plots))
}

/// The counts of a finished run.
fn outcome(dir: &Path, results: &[PointResult], reused: usize, plots: Vec<PathBuf>) -> Outcome {
    let runs = results.iter().map(|r| r.body.formulations.len()).sum();
    let count = |status: &str| {
        results
            .iter()
            .flat_map(|r| &r.body.formulations)
            .filter(|f| f.status == status)
            .count()
    };
    Outcome {
        dir: dir.to_path_buf(),
        points: results.len(),
        reused,
        failed_runs: count("failed"),
        stopped_runs: count("stopped"),
        budget_runs: results
            .iter()
            .flat_map(|r| &r.body.formulations)
            .filter(|f| f.status == "failed" && budget_stop(f.error.as_deref()))
            .count(),
        runs,
        failed_references: 0,
        plots,
    }
}

#[cfg(test)]
mod tests {
    use super::{budget_stop, wall_time_stop};
    use nonholo_core::integrate::IntegrateError;

    /// The budget test reads the integrator's own messages: a change of
    /// their wording must fail here, not silently count budgets as failures.
    #[test]
    fn budget_stops_are_told_from_failures() {
        let steps = IntegrateError::TooManySteps {
            t: 0.27,
            max_steps: 50_000,
            h: 1e-6,
            stiffness: None,
        };
        let wall = IntegrateError::TimeBudgetExceeded {
            t: 0.27,
            seconds: 10.0,
            h: 1e-6,
            stiffness: None,
        };
        assert!(budget_stop(Some(&steps.to_string())));
        assert!(budget_stop(Some(&wall.to_string())));
        assert!(budget_stop(Some(&wall_time_stop(10.0))));
        let other = IntegrateError::NonFinite { t: 0.1 };
        assert!(!budget_stop(Some(&other.to_string())));
        assert!(!budget_stop(None));
    }
}
