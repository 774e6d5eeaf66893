//! `nonholo linearize`: the eigenvalues of a formulation's motion about a
//! steady motion of a scene (crate `nonholo-stability`, docs/stability.md).

use clap::Args;
use nonholo_core::{Initial, SceneInfo};
use nonholo_stability::{Linearisation, Options, linearize};
use serde::Serialize;

use crate::formulations;
use crate::simulate::{ResolveInit, flag, pairs, scene_and_formulation};
use crate::{CliError, fields};

#[derive(Debug, Clone, Args)]
#[command(allow_negative_numbers = true)]
pub struct LinearizeArgs {
    /// Scene name (see `nonholo scenes`).
    #[arg(long, allow_hyphen_values = true)]
    pub scene: String,
    /// Formulation: chetaev (B), vakonomic (C), gauss, or a realisation
    /// (visc, mass: linearised without reduction).
    #[arg(long, default_value = "chetaev", allow_hyphen_values = true)]
    pub formulation: String,
    /// Scene parameter, `name=value` (repeatable).
    #[arg(long = "param", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub params: Vec<String>,
    /// A value of the steady motion, `name=value` (repeatable), named as for
    /// `simulate --init`. Velocities (and velocity-chart values) not given
    /// are zero, not the scene's defaults: a steady motion is stated in full.
    #[arg(long = "steady", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub steady: Vec<String>,
    /// Formulation option, `name=value` (repeatable).
    #[arg(long = "option", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub options: Vec<String>,
    /// A state component to keep independent where the constraints leave a
    /// choice (repeatable), e.g. `phi_dot`.
    #[arg(long = "independent", value_name = "NAME")]
    pub independent: Vec<String>,
    /// Largest rate of an essential component at a steady motion (units
    /// of the component per second).
    #[arg(long, default_value_t = 1e-8, allow_hyphen_values = true)]
    pub steady_tol: f64,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// The resolved steady state for `steady` pairs: the pairs, plus every
/// velocity (or velocity-chart value, if the scene has a chart and no
/// `<coord>_dot` is given) not given, at zero.
pub fn steady_pairs(info: &SceneInfo, given: &[(String, String)]) -> Vec<(String, String)> {
    let has = |n: &str| given.iter().any(|(k, _)| k == n);
    let dots_given = given.iter().any(|(k, _)| k.ends_with("_dot"));
    let mut out = given.to_vec();
    if !info.velocity_chart.is_empty() && !dots_given {
        for c in info.velocity_chart {
            if !has(c.name) {
                out.push((c.name.into(), "0".into()));
            }
        }
    } else {
        // Velocities stated component by component: the others are zero
        // (not the scene's default chart values).
        for c in info.coordinates {
            let name = format!("{}_dot", c.name);
            if !has(&name) {
                out.push((name, "0".into()));
            }
        }
    }
    out
}

/// Builds the model and linearises it about the steady motion `steady`.
pub fn linearise_at(
    scene: &str,
    params: &[(String, String)],
    formulation: &str,
    options: &[(String, String)],
    steady: &[(String, String)],
    opts: &Options,
) -> Result<Linearisation, CliError> {
    let built = nonholo_scenes::build(scene, params)?;
    let mut model = formulations::build_model(built.clone(), formulation, options)?;
    let given = steady_pairs(built.info(), steady);
    // A steady motion off the constraints is the caller's to correct:
    // linearize does not project (simulate's --project-init does).
    let off = |e: nonholo_core::Error| match e {
        nonholo_core::Error::OffConstraints {
            level, residuals, ..
        } => CliError::Input(format!(
            "--steady: the steady motion's {} violate the {} ({}): give a steady motion on \
             the constraints (linearize does not project it)",
            level.quantity(),
            level.constraints(),
            residuals
                .iter()
                .map(|(c, r)| format!("{c}: residual {r:.3e}"))
                .collect::<Vec<_>>()
                .join("; ")
        )),
        e => e.into(),
    };
    let initial: Initial = built
        .visit(ResolveInit {
            given,
            extra: model.extra_init_names(),
        })
        .map_err(off)?;
    linearize(model.as_mut(), &initial, opts).map_err(off)
}

#[derive(Serialize)]
struct ModeJson {
    re: f64,
    im: f64,
    vector: Vec<[f64; 2]>,
}

#[derive(Serialize)]
struct LinearisationJson<'a> {
    schema: &'static str,
    scene: &'a str,
    formulation: &'a str,
    essential: &'a [String],
    cyclic: Vec<(&'a str, f64)>,
    dependent: &'a [String],
    residual: f64,
    matrix: Vec<Vec<f64>>,
    modes: Vec<ModeJson>,
}

/// Schema name of the JSON `nonholo linearize --json` prints.
pub const SCHEMA: &str = "nonholo.linearisation/1";

fn json(args: &LinearizeArgs, lin: &Linearisation) -> Result<String, CliError> {
    let m = lin.matrix.nrows();
    let doc = LinearisationJson {
        schema: SCHEMA,
        scene: &args.scene,
        formulation: &args.formulation,
        essential: &lin.names,
        cyclic: lin.cyclic.iter().map(|(n, r)| (n.as_str(), *r)).collect(),
        dependent: &lin.dependent,
        residual: lin.residual,
        matrix: (0..m)
            .map(|i| (0..m).map(|j| lin.matrix[(i, j)]).collect())
            .collect(),
        modes: lin
            .modes
            .iter()
            .map(|md| ModeJson {
                re: md.value.re,
                im: md.value.im,
                vector: md.vector.iter().map(|z| [z.re, z.im]).collect(),
            })
            .collect(),
    };
    let mut text =
        serde_json::to_string_pretty(&doc).map_err(|e| CliError::Output(e.to_string()))?;
    text.push('\n');
    Ok(text)
}

fn text(args: &LinearizeArgs, lin: &Linearisation) -> String {
    let mut s = format!(
        "scene {}, formulation {}: linearisation about the steady motion at t = {}\n",
        args.scene, args.formulation, lin.t
    );
    if lin.cyclic.is_empty() {
        s.push_str(
            "no coordinate is cyclic here: this is the linearisation about an equilibrium\n",
        );
    } else {
        s.push_str("cyclic (quotiented out), with their rates:\n");
        for (n, r) in &lin.cyclic {
            s.push_str(&format!("  {n:>12} moves at {r:.6e} per s\n"));
        }
    }
    if !lin.dependent.is_empty() {
        s.push_str(&format!(
            "eliminated by the constraints: {}\n",
            lin.dependent.join(", ")
        ));
    }
    s.push_str(&format!(
        "essential components: {} (largest rate at the state {:.1e})\n",
        lin.names.join(", "),
        lin.residual
    ));
    s.push_str("eigenvalues (1/s), by decreasing real part, with their eigenvectors:\n");
    // Real parts within 1e-9 of the largest modulus are zero to the
    // precision of the linearisation (as in experiments of kind stability).
    let level = 1e-9 * lin.modes.iter().map(|m| m.value.norm()).fold(1.0, f64::max);
    for md in &lin.modes {
        let v = md.value;
        let kind = if v.re > level {
            "unstable"
        } else if v.re < -level {
            "decays"
        } else {
            "neutral"
        };
        s.push_str(&format!(
            "  {:>22.14e} {:>+22.14e} i   {kind}\n",
            v.re, v.im
        ));
        let parts: Vec<String> = lin
            .names
            .iter()
            .zip(&md.vector)
            .map(|(n, z)| {
                if z.im == 0.0 {
                    format!("{n} {:.4}", z.re)
                } else {
                    format!("{n} {:.4}{:+.4}i", z.re, z.im)
                }
            })
            .collect();
        s.push_str(&format!("      {}\n", parts.join(", ")));
    }
    s
}

/// `nonholo linearize`.
pub fn command(args: &LinearizeArgs) -> Result<(), CliError> {
    scene_and_formulation(&args.scene, &args.formulation)?;
    let steady_tol = flag("--steady-tol", fields::positive_finite(args.steady_tol))?;
    if let Some(name) = fields::repeated(&args.independent) {
        return Err(CliError::Input(format!(
            "--independent: `{name}` is given twice"
        )));
    }
    let opts = Options {
        independent: args.independent.clone(),
        steady_tol,
        ..Options::default()
    };
    let lin = linearise_at(
        &args.scene,
        &pairs("--param", &args.params)?,
        &args.formulation,
        &pairs("--option", &args.options)?,
        &pairs("--steady", &args.steady)?,
        &opts,
    )?;
    let out = if args.json {
        json(args, &lin)?
    } else {
        text(args, &lin)
    };
    crate::print_stdout(&out)
}
