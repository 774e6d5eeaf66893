use clap::{Parser, Subcommand};
use nonholo_lab::experiment::cli::{
    self, ExperimentArgs, PlotArgs, ReproduceArgs, WorkPrecisionArgs,
};
use nonholo_lab::simulate::{self, SimulateArgs};
use nonholo_lab::{CliError, listing};

/// A workbench for nonholonomic mechanics: Hamilton-principle embedding (A),
/// D'Alembert–Lagrange with Chetaev's conditions (B), vakonomic (C).
#[derive(Debug, Parser)]
#[command(name = "nonholo", version, about)]
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
    /// Run an experiment file: sweeps, comparisons, plots, reports in results/<name>/.
    Experiment(ExperimentArgs),
    /// Error against cost: run work-precision experiments (all of experiments/ by default).
    WorkPrecision(WorkPrecisionArgs),
    /// Redraw an experiment's figures from its stored results.
    Plot(PlotArgs),
    /// Run every experiment marked as a figure and rebuild docs/figures.md.
    Reproduce(ReproduceArgs),
}

fn main() {
    let cli = Cli::parse();
    let result: Result<(), CliError> = match &cli.command {
        Command::Scenes { json } => {
            if *json {
                let mut text = serde_json::to_string_pretty(&listing::json()).unwrap_or_default();
                text.push('\n');
                nonholo_lab::print_stdout(&text);
            } else {
                nonholo_lab::print_stdout(&listing::text());
            }
            Ok(())
        }
        Command::Simulate(args) => simulate::command(args),
        Command::Experiment(args) => cli::experiment(args),
        Command::WorkPrecision(args) => cli::work_precision(args),
        Command::Plot(args) => cli::plot(args),
        Command::Reproduce(args) => cli::reproduce(args),
    };
    if let Err(e) = result {
        eprintln!("error: {e}");
        std::process::exit(e.exit_code());
    }
}
