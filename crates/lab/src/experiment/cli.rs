//! `nonholo experiment`, `nonholo merge`, `nonholo plot` and `nonholo reproduce`.

use std::path::{Path, PathBuf};

use clap::Args;

use super::shard::{self, Shard};
use super::spec::Kind;
use super::{Experiment, ResultsDir, RunOptions, default_dir, run};
use crate::{CliError, fields, io, note};

#[derive(Debug, Clone, Args)]
pub struct ExperimentArgs {
    /// Experiment file (TOML), e.g. experiments/sleigh-slope-sweep.toml.
    pub file: PathBuf,
    /// Run every point again, even those whose results are stored.
    #[arg(long)]
    pub force: bool,
    /// Worker threads, 1 to 1024 (default: all cores). Results do not
    /// depend on it (a run stopped by a wall-time budget is recorded
    /// without its machine-dependent values; step budgets stop the same
    /// everywhere).
    #[arg(long, allow_hyphen_values = true)]
    pub threads: Option<usize>,
    /// Results directory (default: results/<name> beside experiments/):
    /// created if missing; an existing one must be empty or nonholo's.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
    /// Compute only shard I of N (`--shard 2/4`: the points whose index is
    /// 1 modulo 4) into its own directory (default
    /// results/<name>.shard-I-of-N); `nonholo merge` gathers the shards
    /// into the results of a single run (docs/cluster.md).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
}

#[derive(Debug, Clone, Args)]
pub struct MergeArgs {
    /// Experiment file whose shards to merge.
    pub file: PathBuf,
    /// The shard directories (each written by `nonholo experiment FILE
    /// --shard I/N`).
    #[arg(required = true)]
    pub shards: Vec<PathBuf>,
    /// Results directory (default: results/<name> beside experiments/).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Worker threads for what the merge computes itself (the `[minimise]`
    /// searches), 1 to 1024 (default: all cores).
    #[arg(long, allow_hyphen_values = true)]
    pub threads: Option<usize>,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Debug, Clone, Args)]
pub struct PlotArgs {
    /// Experiment file whose stored results to draw.
    pub file: PathBuf,
    /// Results directory (default: results/<name> beside experiments/).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

#[derive(Debug, Clone, Args)]
pub struct ReproduceArgs {
    /// Directory of experiment files.
    #[arg(long, default_value = "experiments")]
    pub experiments: PathBuf,
    /// The figures page whose table is rebuilt.
    #[arg(long, default_value = "docs/figures.md")]
    pub figures: PathBuf,
    /// Run every point again.
    #[arg(long)]
    pub force: bool,
    /// Worker threads, 1 to 1024 (default: all cores).
    #[arg(long, allow_hyphen_values = true)]
    pub threads: Option<usize>,
}

#[derive(Debug, Clone, Args)]
pub struct WorkPrecisionArgs {
    /// Work-precision experiment files (default: every experiments/*.toml of
    /// kind "work-precision").
    pub files: Vec<PathBuf>,
    /// Directory searched when no file is given.
    #[arg(long, default_value = "experiments")]
    pub experiments: PathBuf,
    /// Run every point again, even those whose results are stored.
    #[arg(long)]
    pub force: bool,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
}

/// Every `*.toml` in `dir`, sorted.
fn experiment_files(dir: &Path) -> Result<Vec<PathBuf>, CliError> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| CliError::Input(format!("--experiments {}: {e}", dir.display())))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    Ok(files)
}

/// Refuses two experiment files of one name: they would write one results
/// directory.
fn distinct_names<'a>(
    experiments: impl IntoIterator<Item = (&'a Path, &'a Experiment)>,
) -> Result<(), CliError> {
    let mut seen: Vec<(&Path, &str)> = Vec::new();
    for (f, exp) in experiments {
        if let Some((g, _)) = seen.iter().find(|(_, n)| *n == exp.name) {
            return Err(CliError::Input(format!(
                "{} and {} are both named `{}`: they would write the same results directory",
                g.display(),
                f.display(),
                exp.name
            )));
        }
        seen.push((f, &exp.name));
    }
    Ok(())
}

/// The results directory of `exp` (`--out`, or `results/<name>`), opened
/// and locked for writing.
fn open_dir(exp: &Experiment, out: Option<&Path>, create: bool) -> Result<ResultsDir, CliError> {
    let (dir, what) = match out {
        Some(d) => (d.to_path_buf(), "--out"),
        None => (default_dir(exp), "results directory"),
    };
    let dir = ResultsDir::open(&dir, what, create)?;
    dir.check_experiment(&exp.name, what)?;
    Ok(dir)
}

/// `nonholo work-precision [FILE...]`: runs work-precision experiments (the
/// given files, or every one in `experiments/`); exit 3 if runs failed.
/// Every file is read and checked, and every results directory locked,
/// before anything runs.
pub fn work_precision(args: &WorkPrecisionArgs) -> Result<(), CliError> {
    let experiments: Vec<(PathBuf, Experiment)> = if args.files.is_empty() {
        let mut wp = Vec::new();
        for f in experiment_files(&args.experiments)? {
            let exp = load(&f)?;
            if exp.kind == Kind::WorkPrecision {
                wp.push((f, exp));
            }
        }
        if wp.is_empty() {
            return Err(CliError::Input(format!(
                "no experiment of kind \"work-precision\" in {}",
                args.experiments.display()
            )));
        }
        wp
    } else {
        args.files
            .iter()
            .map(|f| Ok((f.clone(), load(f)?)))
            .collect::<Result<_, CliError>>()?
    };
    if let Some((f, _)) = experiments
        .iter()
        .find(|(_, e)| e.kind != Kind::WorkPrecision)
    {
        return Err(CliError::Input(format!(
            "{}: experiment.kind is not \"work-precision\" (run it with `nonholo experiment`)",
            f.display()
        )));
    }
    distinct_names(experiments.iter().map(|(f, e)| (f.as_path(), e)))?;
    let dirs = experiments
        .iter()
        .map(|(_, exp)| open_dir(exp, None, true))
        .collect::<Result<Vec<_>, _>>()?;
    let (mut failed, mut runs, mut failed_references) = (0, 0, 0);
    for ((_, exp), dir) in experiments.iter().zip(dirs) {
        let o = run(
            exp,
            &RunOptions {
                force: args.force,
                threads: Some(1),
                quiet: args.quiet,
                shard: None,
            },
            dir,
        )?;
        note!(
            "{}: {} points ({} reused), {} runs ({} failed); results in {}",
            exp.name,
            o.points,
            o.reused,
            o.runs,
            o.failed_runs,
            o.dir.display()
        );
        failed += o.failed_runs;
        runs += o.runs;
        failed_references += o.failed_references;
    }
    if failed > 0 {
        return Err(CliError::RunsFailed(format!(
            "{failed} of {runs} work-precision runs failed (reasons in each experiment's work_precision.csv)"
        )));
    }
    if failed_references > 0 {
        return Err(CliError::RunsFailed(references_failed(failed_references)));
    }
    Ok(())
}

fn threads(n: Option<usize>) -> Result<Option<usize>, CliError> {
    n.map(|n| crate::simulate::flag("--threads", fields::threads(n)))
        .transpose()
}

fn load(path: &Path) -> Result<Experiment, CliError> {
    Experiment::load(path).map_err(|e| CliError::Input(e.to_string()))
}

/// `nonholo experiment FILE`: exit 0 if every run completed or stopped where
/// its formulation stops by design, 3 if some failed.
pub fn experiment(args: &ExperimentArgs) -> Result<(), CliError> {
    let threads = threads(args.threads)?;
    let exp = load(&args.file)?;
    let shard = args.shard.as_deref().map(Shard::parse).transpose()?;
    if shard.is_some() && exp.kind == Kind::WorkPrecision {
        return Err(CliError::Input(format!(
            "--shard: {} is a work-precision experiment, which times its runs one at a time \
             on one machine; --shard splits compare experiments only",
            exp.name
        )));
    }
    if shard.is_some() && exp.kind == Kind::Bvp {
        return Err(CliError::Input(format!(
            "--shard: {} is a bvp experiment, which takes seconds to a minute on one machine; \
             --shard splits compare experiments only",
            exp.name
        )));
    }
    if shard.is_some() && exp.kind == Kind::Stability {
        return Err(CliError::Input(format!(
            "--shard: {} is a stability experiment, which takes seconds on one machine; \
             --shard splits compare experiments only",
            exp.name
        )));
    }
    let out = match (shard, &args.out) {
        (Some(s), None) => {
            let dir = ResultsDir::open(&s.default_dir(&exp), "shard directory", true)?;
            dir.check_experiment(&exp.name, "shard directory")?;
            dir
        }
        _ => open_dir(&exp, args.out.as_deref(), true)?,
    };
    let is_shard_dir = shard::shard_of(out.path()).is_some();
    let holds_full_results = ["summary.json", "runs.csv"]
        .iter()
        .any(|f| out.path().join(f).exists());
    if shard.is_some() && !is_shard_dir && holds_full_results {
        return Err(CliError::Input(format!(
            "--out: {} holds the full results of a run (summary.json, runs.csv); a shard \
             writes into a directory of its own (the default results/<name>.shard-I-of-N, \
             or an empty --out), and `nonholo merge` gathers the shards",
            out.path().display()
        )));
    }
    if shard.is_none() && is_shard_dir {
        return Err(CliError::Input(format!(
            "--out: {} is a shard directory (it holds shard.json); merge the shards with \
             `nonholo merge` instead of writing full results into one",
            out.path().display()
        )));
    }
    let o = run(
        &exp,
        &RunOptions {
            force: args.force,
            threads,
            quiet: args.quiet,
            shard,
        },
        out,
    )?;
    note!(
        "{}: {} points ({} reused), {} runs: {} completed, {} stopped at a singular set, {} failed{}; results in {}",
        exp.name,
        o.points,
        o.reused,
        o.runs,
        o.runs - o.failed_runs - o.stopped_runs,
        o.stopped_runs,
        o.failed_runs,
        if o.budget_runs > 0 {
            format!(" ({} of them on their budget)", o.budget_runs)
        } else {
            String::new()
        },
        o.dir.display()
    );
    if o.failed_runs > 0 {
        return Err(CliError::RunsFailed(format!(
            "{} of {} runs failed (reasons in {})",
            o.failed_runs,
            o.runs,
            o.dir
                .join(match exp.kind {
                    Kind::WorkPrecision => "work_precision.csv",
                    Kind::Stability => "samples.csv",
                    Kind::Bvp => "solves.csv",
                    Kind::Compare => "runs.csv",
                })
                .display()
        )));
    }
    if o.failed_references > 0 {
        return Err(CliError::RunsFailed(references_failed(o.failed_references)));
    }
    Ok(())
}

/// The exit-3 message of work-precision references that failed.
fn references_failed(n: usize) -> String {
    format!(
        "{n} work-precision reference{} could not be computed, so {} lines have no errors \
         (reasons in references.csv, column `failure`)",
        if n == 1 { "" } else { "s" },
        if n == 1 { "its" } else { "their" }
    )
}

/// `nonholo merge FILE SHARD...`: gathers the shards' stored points into
/// one results directory and writes the tables, figures and pages from
/// them (nothing is run again; a `[minimise]` search is made here). Exit 2
/// if a point is in none of the shards, 3 if some runs failed.
pub fn merge(args: &MergeArgs) -> Result<(), CliError> {
    let threads = threads(args.threads)?;
    let exp = load(&args.file)?;
    if exp.kind != Kind::Compare {
        return Err(CliError::Input(format!(
            "{}: only compare experiments are sharded, so there is nothing to merge",
            exp.name
        )));
    }
    // The same directory twice (however spelled) would meet its own lock.
    let out_path = args.out.clone().unwrap_or_else(|| default_dir(&exp));
    let canonical = |p: &Path| p.canonicalize().unwrap_or_else(|_| p.to_path_buf());
    let mut seen = vec![canonical(&out_path)];
    for d in &args.shards {
        let c = canonical(d);
        if seen.contains(&c) {
            return Err(CliError::Input(format!(
                "merge: {} is given twice (as a shard and as the output, or as two shards)",
                d.display()
            )));
        }
        seen.push(c);
    }
    let shards = args
        .shards
        .iter()
        .map(|d| ResultsDir::open(d, "shard directory", false))
        .collect::<Result<Vec<_>, _>>()?;
    // A refused merge leaves no trace: an output directory made here is
    // removed again (with its lock) if the shards do not make the results.
    let existed = out_path.exists();
    let out = open_dir(&exp, args.out.as_deref(), true)?;
    if shard::shard_of(out.path()).is_some() {
        return Err(CliError::Input(format!(
            "merge: the output {} is a shard directory",
            out.path().display()
        )));
    }
    let points = match shard::gather(&exp, &shards, out.path()) {
        Ok(points) => points,
        Err(e) => {
            drop(out);
            if !existed {
                let _ = std::fs::remove_dir_all(&out_path);
            }
            return Err(e);
        }
    };
    for s in shards {
        s.finish();
    }
    let o = run(
        &exp,
        &RunOptions {
            force: false,
            threads,
            quiet: args.quiet,
            shard: None,
        },
        out,
    )?;
    note!(
        "{}: {} points merged from {} shards ({} reused), {} runs; results in {}",
        exp.name,
        points,
        args.shards.len(),
        o.reused,
        o.runs,
        o.dir.display()
    );
    if o.reused != o.points {
        // Cannot happen: every point was checked by the same test the run
        // reuses it by. Reported as a failed run (status 1) if it does.
        return Err(CliError::Run(format!(
            "merge: {} points were computed again instead of reused",
            o.points - o.reused
        )));
    }
    if o.failed_runs > 0 {
        return Err(CliError::RunsFailed(format!(
            "{} of {} runs failed (reasons in {})",
            o.failed_runs,
            o.runs,
            o.dir.join("runs.csv").display()
        )));
    }
    Ok(())
}

/// `nonholo plot FILE`: redraws the figures and the page from stored
/// results. Results that are missing, unreadable or stale (computed for
/// another version of the experiment file) are refused before anything is
/// drawn.
pub fn plot(args: &PlotArgs) -> Result<(), CliError> {
    let exp = load(&args.file)?;
    let out = open_dir(&exp, args.out.as_deref(), false)?;
    out.prepare(&["plots"])?;
    let dir = out.path().to_path_buf();
    let plots = if exp.kind == Kind::WorkPrecision {
        super::wp::redraw(&exp, out)?
    } else if exp.kind == Kind::Stability {
        super::stability::redraw(&exp, out)?
    } else if exp.kind == Kind::Bvp {
        super::bvp::redraw(&exp, out)?
    } else {
        let results: Vec<super::PointResult> =
            super::files::load_points(&exp, &dir, super::point::POINT_SCHEMA)
                .map_err(CliError::Input)?;
        for point in std::iter::once(exp.plot_point).chain(exp.also_points.iter().copied()) {
            super::plots::trajectories(&exp, &dir, &results, point).map_err(CliError::Input)?;
        }
        let plots = super::plots::draw(&exp, &dir, &results).map_err(CliError::Output)?;
        super::output::write_html(&exp, &dir, &results, &plots).map_err(CliError::Output)?;
        out.finish();
        plots
    };
    note!(
        "{} plots redrawn in {}",
        plots.len(),
        dir.join("plots").display()
    );
    Ok(())
}

const BEGIN: &str = "<!-- figures:begin (generated by `nonholo reproduce`) -->";
const END: &str = "<!-- figures:end -->";

/// `nonholo reproduce`: runs every experiment marked `figure = true` and
/// rebuilds the table of `docs/figures.md` (figure, claim, command, status).
/// Every experiment file is read and checked, the figures page's directory
/// and every results directory are checked and locked, before anything
/// runs.
pub fn reproduce(args: &ReproduceArgs) -> Result<(), CliError> {
    let threads = threads(args.threads)?;
    let figures = io::check_target(&args.figures)
        .map_err(|e| CliError::Input(format!("--figures {}: {e}", args.figures.display())))?;
    let files = experiment_files(&args.experiments)?;
    let mut experiments = Vec::new();
    for f in &files {
        let exp = load(f)?;
        if exp.figure {
            experiments.push((f, exp));
        }
    }
    if experiments.is_empty() {
        return Err(CliError::Input(format!(
            "--experiments {}: no experiment file there is marked as a figure \
             (`figure = true` in [experiment]); nothing to reproduce, {} left as it is",
            args.experiments.display(),
            args.figures.display()
        )));
    }
    distinct_names(experiments.iter().map(|(f, e)| (f.as_path(), e)))?;
    let dirs = experiments
        .iter()
        .map(|(_, exp)| open_dir(exp, None, true))
        .collect::<Result<Vec<_>, _>>()?;
    let figures_dir = figures
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .to_path_buf();
    if let Some(name) = figures.file_name() {
        io::clean_stale_temporaries(&figures_dir, Some(&name.to_string_lossy()));
    }
    let mut rows = Vec::new();
    let mut broken = Vec::new();
    for ((f, exp), out) in experiments.iter().zip(dirs) {
        let dir = out.path().to_path_buf();
        note!("== {} ({})", exp.name, f.display());
        let status = match run(
            exp,
            &RunOptions {
                force: args.force,
                threads,
                quiet: false,
                shard: None,
            },
            out,
        ) {
            Ok(o) => {
                let plural =
                    |n: usize, what: &str| format!("{n} {what}{}", if n == 1 { "" } else { "s" });
                let mut s = format!("{}, {}", plural(o.points, "point"), plural(o.runs, "run"));
                if o.stopped_runs > 0 {
                    s.push_str(&format!(", {} stopped at a singular set", o.stopped_runs));
                }
                if o.budget_runs > 0 {
                    s.push_str(&format!(", {} on their step budget", o.budget_runs));
                }
                if o.failed_runs > o.budget_runs {
                    s.push_str(&format!(", **{} failed**", o.failed_runs - o.budget_runs));
                }
                s
            }
            Err(e) => {
                note!("error: {e}");
                broken.push(exp.name.clone());
                format!("**not run**: {e}")
            }
        };
        let rel = |p: &Path| relative(&figures_dir, p);
        let main_plot = main_plot(exp, &dir);
        let figure = match &main_plot {
            Some(p) => format!(
                "[![{}]({})]({})",
                exp.name,
                rel(p),
                rel(&dir.join("index.html"))
            ),
            None => format!("[{}]({})", exp.name, rel(&dir.join("index.html"))),
        };
        rows.push(format!(
            "| {figure} | {} | `nonholo experiment {}` | {status} |",
            exp.claim.replace('|', "\\|"),
            f.display()
        ));
    }
    let table = format!(
        "{BEGIN}\n\n| figure | claim | command | status |\n|---|---|---|---|\n{}\n\n{END}",
        rows.join("\n")
    );
    let page = match std::fs::read_to_string(&figures) {
        Ok(p) => p,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => String::new(),
        Err(e) => {
            return Err(CliError::Output(format!(
                "--figures {}: {e}",
                args.figures.display()
            )));
        }
    };
    let new = match (page.find(BEGIN), page.find(END)) {
        (Some(a), Some(b)) if a < b => format!("{}{}{}", &page[..a], table, &page[b + END.len()..]),
        _ => format!("# Figures\n\n{table}\n\n{page}"),
    };
    io::write_atomic(&args.figures, new.as_bytes())
        .map_err(|e| CliError::Output(format!("cannot write {}: {e}", args.figures.display())))?;
    note!(
        "{} figure experiments; table rebuilt in {}",
        rows.len(),
        args.figures.display()
    );
    if broken.is_empty() {
        Ok(())
    } else {
        Err(CliError::Run(format!(
            "experiments not run: {}",
            broken.join(", ")
        )))
    }
}

/// The figure standing for `exp`: `plots.main` if given; else the heat map
/// of a two-variable grid, the end-divergence curve of a sweep of three or
/// more points, or the divergence against time.
pub(crate) fn main_plot(exp: &Experiment, dir: &Path) -> Option<PathBuf> {
    let plots = dir.join("plots");
    let mut candidates: Vec<String> = exp.main_plot.iter().cloned().collect();
    if exp.kind == Kind::WorkPrecision {
        candidates.push(format!("wp-{}-max-time", exp.plot_point));
    }
    if exp.kind == Kind::Stability {
        candidates.push("eigenvalues-re".into());
    }
    if exp.kind == Kind::Bvp {
        candidates.push(format!("convergence-p{}", exp.plot_point));
    }
    if exp.axes.len() == 2 {
        candidates.extend(
            exp.formulations
                .iter()
                .map(|f| format!("sweep-{}", f.label)),
        );
    }
    if exp.points().len() >= 3 {
        candidates.push("sweep-end".into());
    }
    candidates.extend(["divergence".into(), "trajectories".into()]);
    candidates
        .into_iter()
        .map(|c| plots.join(format!("{c}.png")))
        .find(|p| p.exists())
}

/// `p` as a link from a page in directory `from`: a relative path through
/// the nearest common directory of the two (both made absolute, symbolic
/// links resolved where they exist), `/`-separated.
pub fn relative(from: &Path, p: &Path) -> String {
    let absolute = |q: &Path| {
        std::fs::canonicalize(q)
            .or_else(|_| std::path::absolute(q))
            .unwrap_or_else(|_| q.to_path_buf())
    };
    let (from, to) = (absolute(from), absolute(p));
    let a: Vec<_> = from.components().collect();
    let b: Vec<_> = to.components().collect();
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut parts: Vec<String> = vec!["..".to_string(); a.len() - common];
    parts.extend(
        b[common..]
            .iter()
            .map(|c| c.as_os_str().to_string_lossy().into_owned()),
    );
    parts.join("/")
}

#[cfg(test)]
mod tests {
    use super::relative;
    use std::path::Path;

    #[test]
    fn links_are_relative_whatever_the_paths() {
        let root = std::env::temp_dir().join(format!("nonholo-rel-{}", std::process::id()));
        let docs = root.join("docs");
        let plot = root.join("results/x/plots/a.png");
        std::fs::create_dir_all(&docs).unwrap();
        std::fs::create_dir_all(plot.parent().unwrap()).unwrap();
        std::fs::write(&plot, b"").unwrap();
        assert_eq!(relative(&docs, &plot), "../results/x/plots/a.png");
        let dotted = docs.join("../results/x/plots/a.png");
        assert_eq!(relative(&docs, &dotted), "../results/x/plots/a.png");
        assert_eq!(relative(&root, &plot), "results/x/plots/a.png");
        assert_eq!(relative(Path::new("/"), Path::new("/a/b")), "a/b");
    }
}
