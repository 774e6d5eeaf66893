//! `nonholo simulate`: one motion of one scene under one formulation.

use std::path::PathBuf;

use clap::Args;
use nonholo_core::integrate::{Method, Options, RadauNewton};
use nonholo_core::{Run, RunConfig, init, simulate};

use crate::CliError;
use crate::formulations;
use crate::matching::{self, MatchReport};
use crate::record::{RunRecord, write_atomic};

#[derive(Debug, Clone, Args)]
#[command(allow_negative_numbers = true)]
pub struct SimulateArgs {
    /// Scene name (see `nonholo scenes`).
    #[arg(long)]
    pub scene: String,
    /// Formulation: chetaev (B), ...
    #[arg(long, default_value = "chetaev")]
    pub formulation: String,
    /// Scene parameter, `name=value` (repeatable); angles accept a `deg` suffix.
    #[arg(long = "param", value_name = "NAME=VALUE")]
    pub params: Vec<String>,
    /// Initial value, `name=value` (repeatable): a coordinate, `<coord>_dot`,
    /// a convenience value of the scene, or a formulation's own (`lambda`).
    #[arg(long = "init", value_name = "NAME=VALUE")]
    pub init: Vec<String>,
    /// Formulation option, `name=value` (repeatable), e.g. `stab=projection`.
    #[arg(long = "option", value_name = "NAME=VALUE")]
    pub options: Vec<String>,
    /// End of the time span (start is 0).
    #[arg(long, default_value_t = 10.0)]
    pub t_end: f64,
    /// Spacing of the output grid (default: 1/100 of the span).
    #[arg(long)]
    pub output_every: Option<f64>,
    /// Integrator: rk4, dopri5, dop853.
    #[arg(long, default_value = "dop853")]
    pub integrator: String,
    /// Relative tolerance (adaptive methods).
    #[arg(long, default_value_t = 1e-10)]
    pub rtol: f64,
    /// Absolute tolerance (adaptive methods).
    #[arg(long, default_value_t = 1e-10)]
    pub atol: f64,
    /// Fixed step size: required for rk4; turns step-size control off for the others.
    #[arg(long)]
    pub step: Option<f64>,
    /// Newton iteration of radau5: auto (the formulation's choice), simplified, full.
    #[arg(long, default_value = "auto")]
    pub radau_newton: String,
    /// Budget on integrator steps (accepted plus rejected).
    #[arg(long, default_value_t = 10_000_000)]
    pub max_steps: usize,
    /// Budget on wall-clock time in seconds (default: none).
    #[arg(long)]
    pub max_wall_time: Option<f64>,
    /// Move inconsistent initial data onto the constraints (nearest in the
    /// kinetic-energy metric) instead of refusing them.
    #[arg(long)]
    pub project_init: bool,
    /// Write the run to FILE.json, or FILE.csv plus FILE.csv.meta.json (status,
    /// tolerances, options, diagnostics); default: a summary on stdout.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Also write the file when the run fails part-way (status "failed"; JSON only).
    #[arg(long)]
    pub keep_partial: bool,
}

/// Splits `name=value` pairs given to `flag`.
pub fn pairs(flag: &str, items: &[String]) -> Result<Vec<(String, String)>, CliError> {
    items
        .iter()
        .map(|s| {
            s.split_once('=')
                .map(|(a, b)| (a.trim().to_string(), b.trim().to_string()))
                .filter(|(a, _)| !a.is_empty())
                .ok_or_else(|| CliError::Input(format!("{flag} expects NAME=VALUE, got `{s}`")))
        })
        .collect()
}

pub fn positive(flag: &str, v: f64) -> Result<f64, CliError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(CliError::Input(format!(
            "{flag}: must be a positive finite number (got {v})"
        )))
    }
}

/// Most output points a run may ask for (each is a row of the result).
pub const MAX_OUTPUT_POINTS: f64 = 1e6;

/// Output grid `0, Δ, 2Δ, …` up to `t_end`, which is always the last point.
pub fn output_grid(t_end: f64, every: f64) -> Result<Vec<f64>, CliError> {
    let count = (t_end / every).floor();
    if count.is_nan() || count > MAX_OUTPUT_POINTS {
        return Err(CliError::Input(format!(
            "--output-every {every:e} over [0, {t_end:e}] gives {count:.3e} output points \
             (limit {MAX_OUTPUT_POINTS:e})"
        )));
    }
    let count = count as usize;
    let mut grid: Vec<f64> = (0..=count).map(|i| i as f64 * every).collect();
    if t_end - grid[count] > 1e-12 * t_end {
        grid.push(t_end);
    } else {
        grid[count] = t_end;
    }
    Ok(grid)
}

/// Smallest relative tolerance accepted: below ~100 ε double precision
/// cannot deliver what is asked, and a result file would claim it did.
pub const MIN_RTOL: f64 = 100.0 * f64::EPSILON;

/// The Newton iteration of Radau IIA called `name`.
pub fn radau_newton(name: &str) -> Result<RadauNewton, CliError> {
    RadauNewton::from_name(name).ok_or_else(|| {
        CliError::Input(format!(
            "unknown Radau Newton iteration `{name}`; valid: auto, simplified, full"
        ))
    })
}

/// Integrator method and options from command-line values.
pub fn integrator(
    name: &str,
    rtol: f64,
    atol: f64,
    step: Option<f64>,
    max_steps: usize,
) -> Result<(Method, Options), CliError> {
    let method = Method::from_name(name).ok_or_else(|| {
        CliError::Input(format!(
            "unknown integrator `{name}`; valid names: {}",
            Method::ALL.map(|m| m.name()).join(", ")
        ))
    })?;
    let step = step.map(|h| positive("--step", h)).transpose()?;
    if method.needs_fixed_step() && step.is_none() {
        return Err(CliError::Input(format!(
            "integrator `{name}` has a fixed step: give --step"
        )));
    }
    if max_steps == 0 {
        return Err(CliError::Input("--max-steps: must be at least 1".into()));
    }
    let rtol = positive("--rtol", rtol)?;
    if rtol < MIN_RTOL {
        return Err(CliError::Input(format!(
            "--rtol {rtol:e} is below what double precision can deliver (at least {MIN_RTOL:.1e})"
        )));
    }
    Ok((
        method,
        Options {
            rtol,
            atol: positive("--atol", atol)?,
            fixed_step: step,
            max_steps,
            // Samples come from each step's polynomial as the run passes the
            // output times; keeping every polynomial is only needed for
            // evaluation at arbitrary times afterwards.
            dense: false,
            ..Options::default()
        },
    ))
}

/// Everything one run needs, resolved to names and values: what `nonholo
/// simulate` and each formulation of an experiment point describe.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSpec {
    pub scene: String,
    pub formulation: String,
    pub params: Vec<(String, String)>,
    pub init: Vec<(String, String)>,
    pub options: Vec<(String, String)>,
    pub method: Method,
    pub integrator: Options,
    pub t_end: f64,
    pub project_init: bool,
}

/// Builds the model, resolves the initial data (matching A with C when
/// needed) and runs it.
pub fn execute(spec: &RunSpec) -> Result<(Run, Option<MatchReport>), CliError> {
    let scene = nonholo_scenes::build(&spec.scene, &spec.params)?;
    let model = formulations::build_model(scene.clone(), &spec.formulation, &spec.options)?;
    let mut initial = scene.clone().visit(ResolveInit {
        given: spec.init.clone(),
        extra: model.extra_init_names(),
    })?;
    let matching = if model.formulation().name == nonholo_embedding::INFO.name {
        Some(matching::prepare_embedding(&scene, &mut initial)?)
    } else {
        None
    };
    let run = simulate(
        model,
        initial,
        RunConfig {
            method: spec.method,
            options: spec.integrator.clone(),
            t_end: spec.t_end,
            project_init: spec.project_init,
        },
    )?;
    Ok((run, matching))
}

/// Builds and runs the simulation described by `args`; for formulation A
/// also reports how its initial derivatives were matched with C.
pub fn run(args: &SimulateArgs) -> Result<(Run, Option<MatchReport>), CliError> {
    let t_end = positive("--t-end", args.t_end)?;
    let every = positive("--output-every", args.output_every.unwrap_or(t_end / 100.0))?;
    let (method, mut options) = integrator(
        &args.integrator,
        args.rtol,
        args.atol,
        args.step,
        args.max_steps,
    )?;
    options.output = output_grid(t_end, every)?;
    options.radau5.newton = radau_newton(&args.radau_newton)?;
    options.max_wall_time_s = args
        .max_wall_time
        .map(|s| positive("--max-wall-time", s))
        .transpose()?;
    execute(&RunSpec {
        scene: args.scene.clone(),
        formulation: args.formulation.clone(),
        params: pairs("--param", &args.params)?,
        init: pairs("--init", &args.init)?,
        options: pairs("--option", &args.options)?,
        method,
        integrator: options,
        t_end,
        project_init: args.project_init,
    })
}

/// Resolves `--init`-style values against a scene (coordinates, velocities,
/// convenience values, the formulation's extra initial data).
pub(crate) struct ResolveInit {
    pub given: Vec<(String, String)>,
    pub extra: Vec<nonholo_core::init::ExtraName>,
}

impl nonholo_scenes::SceneVisitor for ResolveInit {
    type Output = Result<nonholo_core::Initial, nonholo_core::Error>;
    fn visit<S: nonholo_core::Scene>(self, scene: S) -> Self::Output {
        init::resolve(&scene, &self.given, &self.extra)
    }
}

/// Runs `nonholo simulate`; writes the file or prints the summary.
pub fn command(args: &SimulateArgs) -> Result<(), CliError> {
    if let Some(path) = &args.out {
        match path.extension().and_then(|e| e.to_str()) {
            Some("json") => {}
            Some("csv") if args.keep_partial => {
                return Err(CliError::Input(
                    "--keep-partial needs a .json output: a CSV cannot say that the run failed"
                        .into(),
                ));
            }
            Some("csv") => {}
            _ => {
                return Err(CliError::Input(format!(
                    "--out {}: the file name must end in .json or .csv",
                    path.display()
                )));
            }
        }
    }
    let (run, matching) = run(args)?;
    let mut record = RunRecord::from_run(&run).map_err(CliError::Run)?;
    record.matching = matching;
    if let Some(p) = &run.projection {
        eprintln!(
            "--project-init moved the initial data: |Δq| = {:.3e}, |Δq̇| = {:.3e} (velocity residual {:.3e} → {:.3e})",
            p.projection.dq_norm,
            p.projection.dqd_norm,
            p.projection.velocity_residual.0,
            p.projection.velocity_residual.1
        );
    }
    let write = run.completed() || args.keep_partial;
    match (&args.out, write) {
        (Some(path), true) => {
            let bytes = if path.extension().and_then(|e| e.to_str()) == Some("csv") {
                record
                    .to_csv(&run.model.multiplier_names())
                    .map_err(CliError::Run)?
            } else {
                let mut b =
                    serde_json::to_vec_pretty(&record).map_err(|e| CliError::Run(e.to_string()))?;
                b.push(b'\n');
                b
            };
            write_atomic(path, &bytes)
                .map_err(|e| CliError::Run(format!("cannot write {}: {e}", path.display())))?;
            if path.extension().and_then(|e| e.to_str()) == Some("csv") {
                let meta = path.with_file_name(format!(
                    "{}.meta.json",
                    path.file_name()
                        .map(|n| n.to_string_lossy())
                        .unwrap_or_default()
                ));
                let mut b = serde_json::to_vec_pretty(&record.metadata())
                    .map_err(|e| CliError::Run(e.to_string()))?;
                b.push(b'\n');
                write_atomic(&meta, &b)
                    .map_err(|e| CliError::Run(format!("cannot write {}: {e}", meta.display())))?;
            }
        }
        (None, _) => crate::print_stdout(&summary(&run, &record)),
        (Some(_), false) => {}
    }
    match &run.failure {
        None => Ok(()),
        Some(e) => Err(CliError::Run(format!(
            "{}{}",
            e,
            if args.out.is_some() && !args.keep_partial {
                " (no file written; --keep-partial writes the trajectory up to the failure)"
            } else {
                ""
            }
        ))),
    }
}

/// A short human-readable account of a run.
pub fn summary(run: &Run, r: &RunRecord) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let f = run.model.formulation();
    let _ = writeln!(
        s,
        "scene {}, formulation {} ({}), integrator {} (rtol {:e}, atol {:e}{})",
        r.scene,
        f.name,
        f.letter,
        r.integrator.method,
        r.integrator.rtol,
        r.integrator.atol,
        r.integrator
            .fixed_step
            .map(|h| format!(", step {h}"))
            .unwrap_or_default()
    );
    let _ = writeln!(
        s,
        "status: {}{}",
        r.status,
        r.error
            .as_ref()
            .map(|e| format!(" — {}", e.message))
            .unwrap_or_default()
    );
    if let (Some(t), Some(q), Some(qd)) = (r.t.last(), r.q.last(), r.q_dot.last()) {
        let _ = writeln!(s, "state at t = {t}:");
        for (i, c) in r.coordinates.iter().enumerate() {
            let _ = writeln!(
                s,
                "  {c:>8} = {:>22.15e}   {c}_dot = {:>22.15e}",
                q[i], qd[i]
            );
        }
        let names = run.model.multiplier_names();
        if let Some(last) = run.samples.last() {
            for (n, v) in names.iter().zip(&last.multipliers) {
                let _ = writeln!(s, "  {n:>8} = {v:>22.15e}");
            }
        }
    }
    let d = &r.diagnostics;
    let _ = writeln!(
        s,
        "constraint residual max {:.3e}; energy {:.12e}, drift max {:.3e}",
        d.constraint_residual_max, d.energy_initial, d.energy_drift_max
    );
    for i in &d.invariants {
        let _ = writeln!(
            s,
            "invariant {} = {:.12e}, drift max {:.3e}",
            i.name, i.initial, i.drift_max
        );
    }
    let st = &r.stats;
    let _ = writeln!(
        s,
        "{} steps ({} rejected), {} right-hand sides, {:.4} s",
        st.counters.steps, st.counters.rejected_steps, st.counters.rhs_evals, st.wall_time_s
    );
    if let Some([t, hl]) = st.stiffness_detected {
        let _ = writeln!(
            s,
            "stiffness detected at t = {t} (h·|λ| ≈ {hl:.2}): consider an implicit method"
        );
    }
    s
}
