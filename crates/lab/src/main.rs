use clap::{Parser, Subcommand};
use nonholo_lab::bvp::{self, BvpArgs};
use nonholo_lab::compare::{self, CompareArgs};
use nonholo_lab::experiment::cli::{
    self, ExperimentArgs, MergeArgs, PlotArgs, ReproduceArgs, WorkPrecisionArgs,
};
use nonholo_lab::linearize::{self, LinearizeArgs};
use nonholo_lab::simulate::{self, SimulateArgs};
use nonholo_lab::{CliError, listing, note};

/// A workbench for nonholonomic mechanics: Hamilton-principle embedding (A),
/// D'Alembert–Lagrange with Chetaev's conditions (B), vakonomic (C).
///
/// Exit status: 0 success; 1 a run failed; 2 refused input (nothing ran);
/// 3 an experiment finished but some of its runs failed; 4 a result could
/// not be written; 5 the results directory is in use by another nonholo;
/// 6 `compare` found different results (docs/cli.md).
#[derive(Debug, Parser)]
#[command(name = "nonholo", version, about, long_about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// List the scenes: coordinates, parameters (units, defaults, ranges), formulations that apply.
    Scenes {
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Run one motion of a scene under one formulation.
    Simulate(Box<SimulateArgs>),
    /// Linearise a formulation about a steady motion: eigenvalues and eigenvectors of the essential dynamics.
    Linearize(Box<LinearizeArgs>),
    /// Hamilton's principle as it is stated: a path with fixed ends made stationary (C, or A by its map or the paper's general case), or the stationarity residual of a given motion.
    Bvp(Box<BvpArgs>),
    /// Run an experiment file: sweeps, comparisons, plots, reports in results/<name>/.
    Experiment(ExperimentArgs),
    /// Error against cost: run work-precision experiments (all of experiments/ by default).
    WorkPrecision(WorkPrecisionArgs),
    /// Gather the shards of an experiment (`experiment --shard I/N`) into the results of a single run.
    Merge(MergeArgs),
    /// Redraw an experiment's figures from its stored results.
    Plot(PlotArgs),
    /// Run every experiment marked as a figure and rebuild docs/figures.md.
    Reproduce(ReproduceArgs),
    /// Whether two results directories hold the same results: every table, cell by cell, wall times aside (exit 6 if not).
    Compare(CompareArgs),
}

fn scenes(json: bool) -> Result<(), CliError> {
    if json {
        let mut text = serde_json::to_string_pretty(&listing::json())
            .map_err(|e| CliError::Output(e.to_string()))?;
        text.push('\n');
        nonholo_lab::print_stdout(&text)
    } else {
        nonholo_lab::print_stdout(&listing::text())
    }
}

/// The command line, parsed; help and usage errors printed as clap does,
/// except that a closed stdout or stderr never stops the program with a
/// panic, and help that could not be written is an output error.
fn parse() -> Cli {
    match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let text = e.render().to_string();
            if e.use_stderr() {
                note!("{}", text.trim_end());
                std::process::exit(e.exit_code());
            }
            if let Err(out) = nonholo_lab::print_stdout(&text) {
                note!("error: {out}");
                std::process::exit(out.exit_code());
            }
            std::process::exit(0);
        }
    }
}

fn main() {
    let cli = parse();
    let result: Result<(), CliError> = match &cli.command {
        Command::Scenes { json } => scenes(*json),
        Command::Simulate(args) => simulate::command(args),
        Command::Linearize(args) => linearize::command(args),
        Command::Bvp(args) => bvp::command(args),
        Command::Experiment(args) => cli::experiment(args),
        Command::WorkPrecision(args) => cli::work_precision(args),
        Command::Merge(args) => cli::merge(args),
        Command::Plot(args) => cli::plot(args),
        Command::Reproduce(args) => cli::reproduce(args),
        Command::Compare(args) => compare::command(args),
    };
    if let Err(e) = result {
        note!("error: {e}");
        std::process::exit(e.exit_code());
    }
}
