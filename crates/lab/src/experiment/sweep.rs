//! Sweep points and their resolution into run specifications.

use nonholo_core::integrate::{Method, Options, Radau5Options};

use super::spec::{CLOSED_FORM, Experiment, FormulationSpec, SweepMode, apply};
use crate::fields;
use crate::simulate::{RunSpec, output_grid};

/// One point of a sweep: its index and the value of every axis (as text).
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    pub index: usize,
    pub values: Vec<String>,
}

/// SplitMix64: a small, fully specified generator, so that a seeded random
/// sweep draws the same points on every machine and every version.
struct SplitMix(u64);

impl SplitMix {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The points of `exp`'s sweep in a fixed order (grid: first axis slowest).
pub fn points(exp: &Experiment) -> Vec<Point> {
    match &exp.mode {
        SweepMode::Single => vec![Point {
            index: 0,
            values: Vec::new(),
        }],
        SweepMode::Zip => (0..exp.axes[0].values.len())
            .map(|i| Point {
                index: i,
                values: exp.axes.iter().map(|a| a.values[i].clone()).collect(),
            })
            .collect(),
        SweepMode::Grid => {
            let mut out: Vec<Vec<String>> = vec![Vec::new()];
            for axis in &exp.axes {
                out = out
                    .into_iter()
                    .flat_map(|prefix| {
                        axis.values.iter().map(move |v| {
                            let mut p = prefix.clone();
                            p.push(v.clone());
                            p
                        })
                    })
                    .collect();
            }
            out.into_iter()
                .enumerate()
                .map(|(index, values)| Point { index, values })
                .collect()
        }
        SweepMode::Random { samples, seed, log } => {
            let mut rng = SplitMix(*seed);
            (0..*samples)
                .map(|index| Point {
                    index,
                    values: exp
                        .axes
                        .iter()
                        .map(|a| {
                            let (lo, hi): (f64, f64) = (
                                a.values[0].parse().unwrap_or(0.0),
                                a.values[1].parse().unwrap_or(1.0),
                            );
                            let u = rng.next_f64();
                            let v = if log.contains(&a.name) {
                                (lo.ln() + u * (hi.ln() - lo.ln())).exp()
                            } else {
                                lo + u * (hi - lo)
                            };
                            format!("{v:?}")
                        })
                        .collect(),
                })
                .collect()
        }
    }
}

/// A formulation at one point: its run specification, or the closed form.
#[derive(Debug, Clone, PartialEq)]
pub struct PointRun {
    pub label: String,
    pub spec: RunSpec,
}

/// The experiment at one point: its scene parameters, initial data and
/// formulations with the point's swept values applied.
#[derive(Debug, Clone, PartialEq)]
pub struct Applied {
    pub params: Vec<(String, String)>,
    pub init: Vec<(String, String)>,
    pub forms: Vec<FormulationSpec>,
}

/// Applies the swept values of `point` to `exp`.
pub fn apply_point(exp: &Experiment, point: &Point) -> Result<Applied, String> {
    let mut params = exp.params.clone();
    let mut init = exp.init.clone();
    let mut forms: Vec<FormulationSpec> = exp.formulations.clone();
    for (axis, value) in exp.axes.iter().zip(&point.values) {
        apply(&axis.target, value, &mut params, &mut forms, &mut init)?;
    }
    Ok(Applied {
        params,
        init,
        forms,
    })
}

/// Resolves every formulation at `point` into a [`RunSpec`] (a closed-form
/// reference keeps formulation `closed-form`).
pub fn resolve(exp: &Experiment, point: &Point) -> Result<Vec<PointRun>, String> {
    let Applied {
        params,
        init,
        forms,
    } = apply_point(exp, point)?;
    let grid = output_grid(exp.t_end, exp.output_every)?;
    forms
        .iter()
        .map(|f| {
            let merge = |base: &[(String, String)], over: &[(String, String)]| {
                let mut out: Vec<(String, String)> = base
                    .iter()
                    .filter(|(k, _)| !over.iter().any(|(o, _)| o == k))
                    .cloned()
                    .collect();
                out.extend(over.iter().cloned());
                out
            };
            let s = &f.settings;
            let method = if f.formulation == CLOSED_FORM {
                Method::Dop853
            } else {
                fields::method(&s.integrator).map_err(|m| format!("{}: {m}", f.label))?
            };
            if method.needs_fixed_step() && s.step.is_none() {
                return Err(format!(
                    "{}: integrator `{}` needs `step`",
                    f.label, s.integrator
                ));
            }
            // Checked where the values were read; again for experiments
            // built in code.
            fields::rtol(s.rtol).map_err(|m| format!("{}: rtol: {m}", f.label))?;
            fields::atol(s.atol).map_err(|m| format!("{}: atol: {m}", f.label))?;
            Ok(PointRun {
                label: f.label.clone(),
                spec: RunSpec {
                    scene: exp.scene.clone(),
                    formulation: f.formulation.clone(),
                    params: merge(&params, &f.params),
                    init: merge(&init, &f.init),
                    options: f.options.clone(),
                    method,
                    integrator: Options {
                        rtol: s.rtol,
                        atol: s.atol,
                        fixed_step: s.step,
                        max_steps: s.max_steps,
                        max_wall_time_s: s.max_wall_time,
                        stiff_stop: s.stiff_stop,
                        radau5: Radau5Options {
                            newton: fields::radau_newton(&s.radau_newton)
                                .map_err(|m| format!("{}: radau_newton: {m}", f.label))?,
                            dense_output: fields::radau_dense(&s.radau_dense)
                                .map_err(|m| format!("{}: radau_dense: {m}", f.label))?,
                            jacobian_reuse: s.radau_jacobian_reuse,
                            newton_tol: s.radau_newton_tol,
                            ..Radau5Options::default()
                        },
                        output: grid.clone(),
                        dense: false,
                        ..Options::default()
                    },
                    t_end: exp.t_end,
                    project_init: s.project_init,
                },
            })
        })
        .collect()
}
