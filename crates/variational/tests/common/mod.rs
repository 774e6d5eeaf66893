//! Shared helpers: scenes, initial-value references at the grid nodes.
#![allow(dead_code)]

use nonholo_core::integrate::{Method, Options};
use nonholo_core::{Initial, Model, Params, RunConfig, Scene, simulate};
use nonholo_variational::Ends;

pub fn scene<S: Scene>(params: &[(&str, &str)]) -> S {
    let p: Vec<(String, String)> = params
        .iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect();
    S::from_params(&Params::resolve(S::INFO.params, &p, "parameter").unwrap()).unwrap()
}

pub fn vakonomic<S: Scene>(s: S) -> Box<dyn Model> {
    Box::new(
        nonholo_vakonomic::Vakonomic::new(s, Params::defaults(nonholo_vakonomic::OPTIONS)).unwrap(),
    )
}

pub fn chetaev<S: Scene>(s: S) -> Box<dyn Model> {
    Box::new(nonholo_chetaev::Chetaev::new(s, Params::defaults(nonholo_chetaev::OPTIONS)).unwrap())
}

/// Positions and velocities of `model` from `(q0, q̇0, extra)` at the
/// times `t` (DOP853, tolerance 1e-13), node after node.
pub fn reference(
    model: Box<dyn Model>,
    q0: &[f64],
    qd0: &[f64],
    extra: &[f64],
    t: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let run = simulate(
        model,
        Initial {
            t0: t[0],
            q: q0.to_vec(),
            qd: qd0.to_vec(),
            extra: nonholo_core::model::multiplier_names(extra.len(), 0)
                .into_iter()
                .zip(extra.iter().copied())
                .collect(),
        },
        RunConfig {
            method: Method::Dop853,
            options: Options {
                rtol: 1e-13,
                atol: 1e-13,
                output: t.to_vec(),
                ..Options::default()
            },
            t_end: *t.last().unwrap(),
            project_init: false,
        },
    )
    .unwrap();
    assert!(run.failure.is_none(), "{:?}", run.failure);
    assert_eq!(run.samples.len(), t.len());
    let q = run.samples.iter().flat_map(|o| o.q.clone()).collect();
    let qd = run.samples.iter().flat_map(|o| o.qd.clone()).collect();
    (q, qd)
}

/// End data from a reference path with velocities.
pub fn ends_of(q: &[f64], qd: &[f64], n: usize) -> Ends {
    let last = q.len() / n - 1;
    Ends {
        q0: q[..n].to_vec(),
        q1: q[last * n..].to_vec(),
        qd0: Some(qd[..n].to_vec()),
        qd1: Some(qd[last * n..].to_vec()),
    }
}

/// Largest difference between two node-major paths.
pub fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
}

/// `0, T/N, …, T`.
pub fn grid(t1: f64, intervals: usize) -> Vec<f64> {
    (0..=intervals)
        .map(|k| {
            if k == intervals {
                t1
            } else {
                t1 * (k as f64 / intervals as f64)
            }
        })
        .collect()
}
