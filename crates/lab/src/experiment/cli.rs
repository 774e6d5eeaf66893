//! `nonholo experiment`, `nonholo plot` and `nonholo reproduce`.

use std::path::{Path, PathBuf};

use clap::Args;

use super::spec::Kind;
use super::{Experiment, RunOptions, default_dir, run};
use crate::CliError;

#[derive(Debug, Clone, Args)]
pub struct ExperimentArgs {
    /// Experiment file (TOML), e.g. experiments/sleigh-slope-sweep.toml.
    pub file: PathBuf,
    /// Run every point again, even those whose results are stored.
    #[arg(long)]
    pub force: bool,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Results directory (default: results/<name> beside experiments/).
    #[arg(long)]
    pub out: Option<PathBuf>,
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
    /// Worker threads (default: all cores).
    #[arg(long)]
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

/// `nonholo work-precision [FILE...]`: runs work-precision experiments (the
/// given files, or every one in `experiments/`); exit 3 if runs failed.
pub fn work_precision(args: &WorkPrecisionArgs) -> Result<(), CliError> {
    // Each file is loaded (and its points checked) once.
    let experiments: Vec<(PathBuf, Experiment)> = if args.files.is_empty() {
        let mut files: Vec<PathBuf> = std::fs::read_dir(&args.experiments)
            .map_err(|e| CliError::Input(format!("{}: {e}", args.experiments.display())))?
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        let mut wp = Vec::new();
        for f in files {
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
    let mut failed = 0;
    let mut runs = 0;
    for (f, exp) in &experiments {
        if exp.kind != Kind::WorkPrecision {
            return Err(CliError::Input(format!(
                "{}: experiment.kind is not \"work-precision\" (run it with `nonholo experiment`)",
                f.display()
            )));
        }
        let o = run(
            exp,
            &RunOptions {
                out_dir: default_dir(exp),
                force: args.force,
                threads: Some(1),
                quiet: args.quiet,
            },
        )
        .map_err(CliError::Run)?;
        eprintln!(
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
    }
    if failed > 0 {
        return Err(CliError::RunsFailed(format!(
            "{failed} of {runs} work-precision runs failed (reasons in each experiment's work_precision.csv)"
        )));
    }
    Ok(())
}

fn threads(n: Option<usize>) -> Result<Option<usize>, CliError> {
    match n {
        Some(0) => Err(CliError::Input("--threads: must be at least 1".into())),
        other => Ok(other),
    }
}

fn load(path: &Path) -> Result<Experiment, CliError> {
    Experiment::load(path).map_err(|e| CliError::Input(e.to_string()))
}

/// `nonholo experiment FILE`: exit 0 if every run completed or stopped where
/// its formulation stops by design, 3 if some failed.
pub fn experiment(args: &ExperimentArgs) -> Result<(), CliError> {
    let exp = load(&args.file)?;
    let out = args.out.clone().unwrap_or_else(|| default_dir(&exp));
    let o = run(
        &exp,
        &RunOptions {
            out_dir: out,
            force: args.force,
            threads: threads(args.threads)?,
            quiet: args.quiet,
        },
    )
    .map_err(CliError::Run)?;
    eprintln!(
        "{}: {} points ({} reused), {} runs: {} completed, {} stopped at a singular set, {} failed; results in {}",
        exp.name,
        o.points,
        o.reused,
        o.runs,
        o.runs - o.failed_runs - o.stopped_runs,
        o.stopped_runs,
        o.failed_runs,
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
                    _ => "runs.csv",
                })
                .display()
        )));
    }
    Ok(())
}

/// `nonholo plot FILE`: redraws the figures and the page from stored results.
pub fn plot(args: &PlotArgs) -> Result<(), CliError> {
    let exp = load(&args.file)?;
    let dir = args.out.clone().unwrap_or_else(|| default_dir(&exp));
    if exp.kind == Kind::WorkPrecision {
        let plots = super::wp::redraw(&exp, &dir).map_err(CliError::Run)?;
        eprintln!(
            "{} plots redrawn in {}",
            plots.len(),
            dir.join("plots").display()
        );
        return Ok(());
    }
    let results = super::files::load_points(&exp, &dir).map_err(CliError::Run)?;
    let plots = super::plots::draw(&exp, &dir, &results).map_err(CliError::Run)?;
    super::output::write_html(&exp, &dir, &results, &plots).map_err(CliError::Run)?;
    eprintln!(
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
pub fn reproduce(args: &ReproduceArgs) -> Result<(), CliError> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(&args.experiments)
        .map_err(|e| CliError::Input(format!("{}: {e}", args.experiments.display())))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    let mut rows = Vec::new();
    let mut broken = Vec::new();
    for f in &files {
        let exp = load(f)?;
        if !exp.figure {
            continue;
        }
        let dir = default_dir(&exp);
        eprintln!("== {} ({})", exp.name, f.display());
        let status = match run(
            &exp,
            &RunOptions {
                out_dir: dir.clone(),
                force: args.force,
                threads: threads(args.threads)?,
                quiet: false,
            },
        ) {
            Ok(o) => {
                let plural =
                    |n: usize, what: &str| format!("{n} {what}{}", if n == 1 { "" } else { "s" });
                let mut s = format!("{}, {}", plural(o.points, "point"), plural(o.runs, "run"));
                if o.stopped_runs > 0 {
                    s.push_str(&format!(", {} stopped at a singular set", o.stopped_runs));
                }
                if o.failed_runs > 0 {
                    s.push_str(&format!(", **{} failed**", o.failed_runs));
                }
                s
            }
            Err(e) => {
                broken.push(exp.name.clone());
                format!("**not run**: {e}")
            }
        };
        let figures_dir = args.figures.parent().unwrap_or(Path::new("."));
        let rel = |p: &Path| relative(figures_dir, p);
        let main_plot = main_plot(&exp, &dir);
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
    let page = std::fs::read_to_string(&args.figures).unwrap_or_default();
    let new = match (page.find(BEGIN), page.find(END)) {
        (Some(a), Some(b)) if a < b => format!("{}{}{}", &page[..a], table, &page[b + END.len()..]),
        _ => format!("# Figures\n\n{table}\n\n{page}"),
    };
    crate::record::write_atomic(&args.figures, new.as_bytes())
        .map_err(|e| CliError::Run(format!("cannot write {}: {e}", args.figures.display())))?;
    eprintln!(
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
fn main_plot(exp: &Experiment, dir: &Path) -> Option<PathBuf> {
    let plots = dir.join("plots");
    let mut candidates: Vec<String> = exp.main_plot.iter().cloned().collect();
    if exp.kind == Kind::WorkPrecision {
        candidates.push(format!("wp-{}-max-time", exp.plot_point));
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

/// `p` relative to directory `from` (both relative to the working directory).
fn relative(from: &Path, p: &Path) -> String {
    let depth = from
        .components()
        .filter(|c| !matches!(c, std::path::Component::CurDir))
        .count();
    let mut s = "../".repeat(depth);
    s.push_str(&p.display().to_string());
    s
}
