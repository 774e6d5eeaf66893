//! Helpers shared by the embedding's integration tests: C (the vakonomic
//! motion A is matched with) as a reference, run configurations, distances.
#![allow(dead_code)]

use nonholo_core::integrate::{Method, Options};
use nonholo_core::{Initial, Params, Run, RunConfig, simulate};
use nonholo_scenes::Sleigh;
use nonholo_vakonomic::Vakonomic;

pub fn vakonomic(s: &Sleigh) -> Vakonomic<Sleigh> {
    Vakonomic::new(s.clone(), Params::defaults(nonholo_vakonomic::OPTIONS)).unwrap()
}

/// C's state `(x, y, φ, ẋ, ẏ, φ̇, λ)` at the origin for forward speed `u`.
pub fn c_state(phi: f64, u: f64, omega: f64, lambda: f64) -> [f64; 7] {
    [0.0, 0.0, phi, u * phi.cos(), u * phi.sin(), omega, lambda]
}

/// `rtol = atol`, output every `every` up to `t_end`.
pub fn config(method: Method, rtol: f64, t_end: f64, every: f64) -> RunConfig {
    let n = (t_end / every).round() as usize;
    RunConfig {
        method,
        options: Options {
            rtol,
            atol: rtol,
            output: (0..=n).map(|i| (i as f64 * every).min(t_end)).collect(),
            ..Options::default()
        },
        t_end,
        project_init: false,
    }
}

/// C from `y` (with its λ0) by DOP853 at `rtol`.
pub fn run_c_tol(s: &Sleigh, y: &[f64; 7], t_end: f64, every: f64, rtol: f64) -> Run {
    let init = Initial {
        t0: 0.0,
        q: y[..3].to_vec(),
        qd: y[3..6].to_vec(),
        extra: vec![("lambda".into(), y[6])],
    };
    simulate(
        Box::new(vakonomic(s)),
        init,
        config(Method::Dop853, rtol, t_end, every),
    )
    .unwrap()
}

/// `max |(x, y)_a − (x, y)_b|` over the samples both have.
pub fn position_difference(a: &Run, b: &Run) -> f64 {
    a.samples
        .iter()
        .zip(&b.samples)
        .map(|(p, q)| (p.q[0] - q.q[0]).abs().max((p.q[1] - q.q[1]).abs()))
        .fold(0.0, f64::max)
}

/// C's Taylor coefficients `(q̈, q⃛)` of `(x, y)` at `y`, t = 0.
pub fn taylor(s: &Sleigh, y: &[f64; 7]) -> ([f64; 2], [f64; 2]) {
    let (mut yd, mut ydd, mut yddd) = ([0.0; 7], [0.0; 7], [0.0; 7]);
    vakonomic(s)
        .taylor(0.0, y, &mut yd, &mut ydd, &mut yddd)
        .unwrap();
    ([yd[3], yd[4]], [ydd[3], ydd[4]])
}

/// A's initial data as the lab matches them (C's `q̈`, and `q⃛` if `third`).
pub fn matched(s: &Sleigh, y: &[f64; 7], third: bool) -> Initial {
    let (second, dddot) = taylor(s, y);
    let mut extra = vec![
        ("x_ddot".to_string(), second[0]),
        ("y_ddot".to_string(), second[1]),
    ];
    if third {
        extra.push(("x_dddot".into(), dddot[0]));
        extra.push(("y_dddot".into(), dddot[1]));
    }
    Initial {
        t0: 0.0,
        q: y[..3].to_vec(),
        qd: y[3..6].to_vec(),
        extra,
    }
}
