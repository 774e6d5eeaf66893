//! Shared helpers for the tests of formulation B.
#![allow(dead_code)]

use nonholo_chetaev::{Chetaev, OPTIONS};
use nonholo_core::integrate::{Method, OdeSystem, Options, SystemError};
use nonholo_core::{Model, Observation, Params, Run, RunConfig, Scene, init, simulate};

pub fn pairs(items: &[(&str, &str)]) -> Vec<(String, String)> {
    items
        .iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect()
}

/// Formulation B on `scene` with options `opts`.
pub fn chetaev<S: Scene>(scene: S, opts: &[(&str, &str)]) -> Chetaev<S> {
    Chetaev::new(
        scene,
        Params::resolve(OPTIONS, &pairs(opts), "option").unwrap(),
    )
    .unwrap()
}

pub fn scene<S: Scene>(params: &[(&str, &str)]) -> S {
    S::from_params(&Params::resolve(S::INFO.params, &pairs(params), "parameter").unwrap()).unwrap()
}

/// Runs B on `scene` from named initial values with an adaptive method.
pub fn run_b<S: Scene + Clone>(
    scene: &S,
    opts: &[(&str, &str)],
    init_values: &[(&str, &str)],
    method: Method,
    tol: f64,
    t_end: f64,
    output: Vec<f64>,
) -> Run {
    let model = chetaev(scene.clone(), opts);
    let initial = init::resolve(scene, &pairs(init_values), &[]).unwrap();
    simulate(
        Box::new(model),
        initial,
        RunConfig {
            method,
            options: Options {
                rtol: tol,
                atol: tol,
                output,
                ..Options::default()
            },
            t_end,
            project_init: false,
        },
    )
    .unwrap()
}

/// `0, dt, ..., t_end`.
pub fn grid(t_end: f64, dt: f64) -> Vec<f64> {
    let n = (t_end / dt).round() as usize;
    (0..=n).map(|i| t_end * i as f64 / n as f64).collect()
}

/// Least-squares slope of log(err) against log(h).
pub fn fitted_order(h: &[f64], err: &[f64]) -> f64 {
    let x: Vec<f64> = h.iter().map(|v| v.ln()).collect();
    let y: Vec<f64> = err.iter().map(|v| v.ln()).collect();
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(&y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    sxy / sxx
}

/// `q̈` into `qdd` and `λ` then `ν` into `multipliers` (as many as given) of
/// B at `(t, q, q̇)`: the right-hand side and the observation of the model.
pub fn accelerations<S: Scene>(
    b: &mut Chetaev<S>,
    t: f64,
    q: &[f64],
    qd: &[f64],
    qdd: &mut [f64],
    multipliers: &mut [f64],
) -> Result<(), SystemError> {
    let n = q.len();
    let y: Vec<f64> = q.iter().chain(qd).copied().collect();
    let mut dy = vec![0.0; 2 * n];
    b.rhs(t, &y, &mut dy)?;
    qdd.copy_from_slice(&dy[n..]);
    let mut obs = Observation::new(n, b.multiplier_names().len());
    b.observe(t, &y, &mut obs)?;
    for (m, v) in multipliers.iter_mut().zip(&obs.multipliers) {
        *m = *v;
    }
    Ok(())
}
