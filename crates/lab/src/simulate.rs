//! `nonholo simulate`: one motion of one scene under one formulation.

use std::path::{Path, PathBuf};

use clap::Args;
use nonholo_core::integrate::{Method, Options, Radau5Options};
use nonholo_core::{Run, RunConfig, init, simulate};

use crate::formulations;
use crate::matching::{self, MatchReport};
use crate::record::RunRecord;
use crate::{CliError, fields, io};

#[derive(Debug, Clone, Args)]
#[command(allow_negative_numbers = true)]
pub struct SimulateArgs {
    /// Scene name (see `nonholo scenes`).
    #[arg(long, allow_hyphen_values = true)]
    pub scene: String,
    /// Formulation: chetaev (B), vakonomic (C), embedding (A), visc, mass, gauss, friction.
    #[arg(long, default_value = "chetaev", allow_hyphen_values = true)]
    pub formulation: String,
    /// Scene parameter, `name=value` (repeatable); angles accept a `deg` suffix.
    #[arg(long = "param", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub params: Vec<String>,
    /// Initial value, `name=value` (repeatable): a coordinate, `<coord>_dot`,
    /// a convenience value of the scene, or a formulation's own (`lambda`).
    #[arg(long = "init", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub init: Vec<String>,
    /// Formulation option, `name=value` (repeatable), e.g. `stab=projection`.
    #[arg(long = "option", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub options: Vec<String>,
    /// End of the time span (start is 0).
    #[arg(long, default_value_t = 10.0, allow_hyphen_values = true)]
    pub t_end: f64,
    /// Spacing of the output grid (default: 1/100 of the span; at most 1e6 points).
    #[arg(long, allow_hyphen_values = true)]
    pub output_every: Option<f64>,
    /// Integrator: rk4 (needs --step), dopri5, dop853, radau5 (implicit).
    #[arg(long, default_value = "dop853", allow_hyphen_values = true)]
    pub integrator: String,
    /// Relative tolerance, in [2.2e-14, 1) (default 1e-10; not with --step
    /// for the explicit methods).
    #[arg(long, allow_hyphen_values = true)]
    pub rtol: Option<f64>,
    /// Absolute tolerance, in [1e-100, 1e100] (default 1e-10; not with
    /// --step for the explicit methods).
    #[arg(long, allow_hyphen_values = true)]
    pub atol: Option<f64>,
    /// Fixed step size: required for rk4; turns step-size control off for the others.
    #[arg(long, allow_hyphen_values = true)]
    pub step: Option<f64>,
    /// Newton iteration of radau5: auto (the formulation's choice, the
    /// default), simplified, full. With --integrator radau5 only.
    #[arg(long, allow_hyphen_values = true)]
    pub radau_newton: Option<String>,
    /// Continuous extension of radau5 (output samples, guard location):
    /// auto (hermite for ODE formulations, collocation for implicit ones),
    /// collocation (RADAU5's polynomial), hermite (a quintic through the last
    /// three step points where the Jacobian's row is not stiff; ODE
    /// formulations only). Default auto; with --integrator radau5 only.
    #[arg(long, allow_hyphen_values = true)]
    pub radau_dense: Option<String>,
    /// radau5 keeps its Jacobian after a step whose Newton iteration
    /// contracted at rate ≤ this (RADAU5's THET; negative: a new Jacobian
    /// every step). Below 1; default RADAU5's 0.001 (its documentation
    /// advises 0.1 when Jacobians are costly). With --integrator radau5 only.
    #[arg(long, allow_hyphen_values = true)]
    pub radau_jacobian_reuse: Option<f64>,
    /// radau5's Newton iteration stops when its estimated remaining error,
    /// in units of the error scale, is at most this (RADAU5's FNEWT;
    /// between 0 and 1). Default: RADAU5's, max(10·uround/rtol',
    /// min(0.03, rtol'^½)) with rtol' = 0.1·rtol^⅔. Tighter costs Newton
    /// iterations and removes the iteration error that builds up over many
    /// steps (docs/integrators.md).
    #[arg(long, allow_hyphen_values = true)]
    pub radau_newton_tol: Option<f64>,
    /// Budget on integrator steps (accepted plus rejected): where the run
    /// stops on it is the same on every machine.
    #[arg(long, default_value_t = 10_000_000, allow_hyphen_values = true)]
    pub max_steps: u64,
    /// Budget on wall-clock time in seconds (default: none).
    #[arg(long, allow_hyphen_values = true)]
    pub max_wall_time: Option<f64>,
    /// Move inconsistent initial data onto the constraints (nearest in the
    /// kinetic-energy metric) instead of refusing them.
    #[arg(long)]
    pub project_init: bool,
    /// Stop an explicit run (dopri5, dop853) where Hairer's stiffness test
    /// has fired 15 times in a row: stability, not accuracy, would limit its
    /// steps from there on (default: a warning only).
    #[arg(long)]
    pub stiff_stop: bool,
    /// Write the run to FILE.json, or FILE.csv plus FILE.csv.meta.json (status,
    /// tolerances, options, diagnostics); default: a summary on stdout. The
    /// directory must exist.
    #[arg(long, allow_hyphen_values = true)]
    pub out: Option<PathBuf>,
    /// Also write the file when the run fails part-way (status "failed"; JSON only).
    #[arg(long)]
    pub keep_partial: bool,
}

impl SimulateArgs {
    /// `nonholo simulate --scene SCENE --formulation FORMULATION` with every
    /// other flag at its default, as the command line parses it (for code
    /// and tests that set a few fields and keep the rest).
    pub fn new(scene: &str, formulation: &str) -> SimulateArgs {
        #[derive(clap::Parser)]
        struct Line {
            #[command(flatten)]
            args: SimulateArgs,
        }
        <Line as clap::Parser>::parse_from([
            "simulate",
            "--scene",
            scene,
            "--formulation",
            formulation,
        ])
        .args
    }
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

/// `r`, or a refusal naming `flag`.
pub fn flag<T>(flag: &str, r: Result<T, String>) -> Result<T, CliError> {
    r.map_err(|e| CliError::Input(format!("{flag}: {e}")))
}

/// Default tolerances of a run (`--rtol`, `--atol`, and an experiment's `rtol`, `atol`).
pub const DEFAULT_TOL: f64 = 1e-10;

/// Default step budget of a run (`--max-steps`, `max_steps`).
pub const DEFAULT_MAX_STEPS: usize = 10_000_000;

/// Output grid `0, Δ, 2Δ, …` up to `t_end`, which is always the last point
/// (`every` checked by [`fields::output_every`]).
pub fn output_grid(t_end: f64, every: f64) -> Result<Vec<f64>, String> {
    fields::output_every(every, t_end)?;
    let count = (t_end / every).floor() as usize;
    let mut grid: Vec<f64> = (0..=count).map(|i| i as f64 * every).collect();
    if t_end - grid[count] > 1e-12 * t_end {
        grid.push(t_end);
    } else {
        grid[count] = t_end;
    }
    Ok(grid)
}

/// Integrator method and options from command-line values, checked by
/// [`fields`] (the checks experiment files go through too).
pub fn integrator(args: &SimulateArgs) -> Result<(Method, Options), CliError> {
    let method = flag("--integrator", fields::method(&args.integrator))?;
    let step = args
        .step
        .map(|h| flag("--step", fields::step(h)))
        .transpose()?;
    if method.needs_fixed_step() && step.is_none() {
        return Err(CliError::Input(format!(
            "--integrator: `{}` has a fixed step: give --step",
            args.integrator
        )));
    }
    if step.is_some() {
        for (name, given) in [("--rtol", args.rtol), ("--atol", args.atol)] {
            if given.is_some() {
                flag(name, fields::tolerance_with_step(method, "--step"))?;
            }
        }
    }
    let max_steps = flag("--max-steps", fields::max_steps(args.max_steps))?;
    let rtol = flag("--rtol", fields::rtol(args.rtol.unwrap_or(DEFAULT_TOL)))?;
    let atol = flag("--atol", fields::atol(args.atol.unwrap_or(DEFAULT_TOL)))?;
    let max_wall_time_s = args
        .max_wall_time
        .map(|s| flag("--max-wall-time", fields::max_wall_time(s)))
        .transpose()?;
    let mut options = Options {
        rtol,
        atol,
        fixed_step: step,
        max_steps,
        max_wall_time_s,
        stiff_stop: args.stiff_stop,
        // Samples come from each step's polynomial as the run passes the
        // output times; keeping every polynomial is only needed for
        // evaluation at arbitrary times afterwards.
        dense: false,
        ..Options::default()
    };
    // Radau IIA's settings, refused with another integrator (where they
    // would be ignored without a word).
    let given = [
        ("--radau-newton", args.radau_newton.is_some()),
        ("--radau-dense", args.radau_dense.is_some()),
        (
            "--radau-jacobian-reuse",
            args.radau_jacobian_reuse.is_some(),
        ),
        ("--radau-newton-tol", args.radau_newton_tol.is_some()),
    ];
    if let Some((name, _)) = given.iter().find(|(_, g)| *g)
        && method != Method::Radau5
    {
        return Err(CliError::Input(format!(
            "{name}: a setting of --integrator radau5, not of {}",
            method.name()
        )));
    }
    let defaults = Radau5Options::default();
    if let Some(n) = &args.radau_newton {
        options.radau5.newton = flag("--radau-newton", fields::radau_newton(n))?;
    }
    options.radau5.dense_output = match &args.radau_dense {
        Some(d) => flag("--radau-dense", fields::radau_dense(d))?,
        None => defaults.dense_output,
    };
    options.radau5.jacobian_reuse = flag(
        "--radau-jacobian-reuse",
        fields::radau_jacobian_reuse(args.radau_jacobian_reuse.unwrap_or(defaults.jacobian_reuse)),
    )?;
    options.radau5.newton_tol = args
        .radau_newton_tol
        .map(|v| flag("--radau-newton-tol", fields::radau_newton_tol(v)))
        .transpose()?;
    Ok((method, options))
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
    let mut model = formulations::build_model(scene.clone(), &spec.formulation, &spec.options)?;
    formulations::check_radau_dense(model.as_mut(), spec.method, &spec.integrator)
        .map_err(|e| CliError::Input(format!("--radau-dense: {e}")))?;
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

/// `--scene` and `--formulation` checked: known names, and the formulation
/// applicable to the scene.
pub fn scene_and_formulation(scene: &str, formulation: &str) -> Result<(), CliError> {
    let scene = flag(
        "--scene",
        nonholo_scenes::info(scene).map_err(|e| e.to_string()),
    )?;
    let f = flag(
        "--formulation",
        formulations::info(formulation).map_err(|e| e.to_string()),
    )?;
    flag(
        "--formulation",
        (f.applicable)(scene).map_err(|reason| {
            format!(
                "formulation `{}` is not applicable to scene `{}`: {reason}",
                f.name, scene.name
            )
        }),
    )
}

/// The run `args` describe, every value checked (nothing runs).
pub fn spec(args: &SimulateArgs) -> Result<RunSpec, CliError> {
    scene_and_formulation(&args.scene, &args.formulation)?;
    let t_end = flag("--t-end", fields::t_end(args.t_end))?;
    let every = args.output_every.unwrap_or(t_end / 100.0);
    let (method, mut options) = integrator(args)?;
    options.output = flag("--output-every", output_grid(t_end, every))?;
    Ok(RunSpec {
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

/// Builds and runs the simulation described by `args`; for formulation A
/// also reports how its initial derivatives were matched with C.
pub fn run(args: &SimulateArgs) -> Result<(Run, Option<MatchReport>), CliError> {
    execute(&spec(args)?)
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

/// Where `--out` writes: the file, and for a CSV its `.meta.json`.
pub(crate) struct OutFiles {
    main: PathBuf,
    meta: Option<PathBuf>,
}

/// The files `--out` names, checked before anything runs: a known format,
/// an existing directory that takes files, no directory in the way.
pub(crate) fn out_files(
    out: Option<&PathBuf>,
    keep_partial: bool,
) -> Result<Option<OutFiles>, CliError> {
    let Some(path) = out else {
        return Ok(None);
    };
    let csv = match path.extension().and_then(|e| e.to_str()) {
        Some("json") => false,
        Some("csv") if keep_partial => {
            return Err(CliError::Input(
                "--keep-partial needs a .json output: a CSV cannot say that the run failed".into(),
            ));
        }
        Some("csv") => true,
        _ => {
            return Err(CliError::Input(format!(
                "--out {}: the file name must end in .json or .csv",
                path.display()
            )));
        }
    };
    let check = |p: &Path| {
        io::check_target(p)
            .map_err(|e| CliError::Input(format!("--out {}: {e}", path.display())))?;
        if let (Some(dir), Some(name)) = (p.parent(), p.file_name()) {
            let dir = if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            };
            io::clean_stale_temporaries(dir, Some(&name.to_string_lossy()));
        }
        Ok::<_, CliError>(p.to_path_buf())
    };
    let meta = csv
        .then(|| {
            let name = path
                .file_name()
                .map(|n| n.to_string_lossy())
                .unwrap_or_default();
            check(&path.with_file_name(format!("{name}.meta.json")))
        })
        .transpose()?;
    Ok(Some(OutFiles {
        main: check(path)?,
        meta,
    }))
}

fn pretty(value: &impl serde::Serialize) -> Result<Vec<u8>, CliError> {
    let mut b = serde_json::to_vec_pretty(value).map_err(|e| CliError::Run(e.to_string()))?;
    b.push(b'\n');
    Ok(b)
}

/// Writes `record` to the files `--out` named (JSON, or CSV with its
/// `.meta.json`), all or nothing.
pub(crate) fn write_record(
    out: &OutFiles,
    record: &RunRecord,
    multiplier_names: &[String],
) -> Result<(), CliError> {
    let mut files = Vec::new();
    match &out.meta {
        Some(meta) => {
            let csv = record.to_csv(multiplier_names).map_err(CliError::Run)?;
            files.push((out.main.clone(), csv));
            files.push((meta.clone(), pretty(&record.metadata())?));
        }
        None => files.push((out.main.clone(), pretty(record)?)),
    }
    let refs: Vec<(&Path, &[u8])> = files
        .iter()
        .map(|(p, b)| (p.as_path(), b.as_slice()))
        .collect();
    io::write_group(&refs).map_err(CliError::Output)
}

/// Runs `nonholo simulate`; writes the file or prints the summary. Every
/// value and the output files are checked before the run.
pub fn command(args: &SimulateArgs) -> Result<(), CliError> {
    let spec = spec(args)?;
    let out = out_files(args.out.as_ref(), args.keep_partial)?;
    let (run, matching) = execute(&spec)?;
    if let Some(p) = &run.projection {
        crate::note!(
            "--project-init moved the initial data: |Δq| = {:.3e}, |Δq̇| = {:.3e} (velocity residual {:.3e} → {:.3e})",
            p.projection.dq_norm,
            p.projection.dqd_norm,
            p.projection.velocity_residual.0,
            p.projection.velocity_residual.1
        );
    }
    let failure = run.failure.as_ref().map(|e| {
        CliError::Run(format!(
            "{e}{}",
            if args.out.is_some() && !args.keep_partial {
                " (no file written; --keep-partial writes the trajectory up to the failure)"
            } else {
                ""
            }
        ))
    });
    let record = RunRecord::from_run(&run).map(|mut r| {
        r.matching = matching;
        r
    });
    match out {
        Some(out) if run.completed() || args.keep_partial => {
            let record = record.map_err(|e| match &failure {
                Some(f) => CliError::Run(format!("{f} (no file written: {e})")),
                None => CliError::Run(e),
            })?;
            write_record(&out, &record, &run.model.multiplier_names())?;
        }
        Some(_) => {}
        None => match record {
            Ok(record) => {
                if let Err(e) = crate::print_stdout(&summary(&run, &record)) {
                    match &failure {
                        // The run's failure is what the exit status reports.
                        Some(_) => crate::note!("{e}"),
                        None => return Err(e),
                    }
                }
            }
            Err(e) if failure.is_none() => return Err(CliError::Run(e)),
            Err(_) => {}
        },
    }
    match failure {
        None => Ok(()),
        Some(f) => Err(f),
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
            .map(|h| format!(", step {}", fields::num(h)))
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
    if !r.crossings.is_empty() {
        let max = |f: fn(&nonholo_core::CrossingRecord) -> f64| {
            r.crossings.iter().map(f).fold(0.0, f64::max)
        };
        let _ = writeln!(
            s,
            "{} crossings of a singular set (first at t = {:.6}, last at t = {:.6}); \
             gap interpolation error ≤ {:.1e}, return residual ≤ {:.1e}, restart change ≤ {:.1e}",
            r.crossings.len(),
            r.crossings[0].t_singular,
            r.crossings[r.crossings.len() - 1].t_singular,
            max(|c| c.gap_error),
            max(|c| c.return_residual),
            max(|c| c.restart_change),
        );
    }
    for w in &r.switches {
        let _ = writeln!(
            s,
            "switch {}: {} {} → {} at t = {:.9} (force ratio {:.6}, by {}{})",
            w.number,
            w.part,
            w.from,
            w.to,
            w.t,
            w.force_ratio,
            w.decided_by,
            if w.velocity_jump > 0.0 {
                format!("; slip left removed, velocity jump {:.1e}", w.velocity_jump)
            } else {
                String::new()
            }
        );
    }
    s
}
