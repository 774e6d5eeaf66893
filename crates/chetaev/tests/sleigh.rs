//! Formulation B on the sleigh: closed form (a = 0), the spec's reduced
//! equations (a ≠ 0, both potentials), convergence orders, invariants.

mod common;

use common::*;
use nonholo_core::integrate::{Method, Options};
use nonholo_core::{RunConfig, Scene, init, simulate};
use nonholo_scenes::Sleigh;
use rand::{Rng, SeedableRng};

const INIT: &[(&str, &str)] = &[
    ("x", "0"),
    ("y", "0"),
    ("phi", "0.2"),
    ("u", "2"),
    ("omega", "0.7"),
];

fn max_error_against_closed_form(potential: &str, method: Method, tol: f64) -> f64 {
    let s: Sleigh = scene(&[("a", "0"), ("alpha", "0.3"), ("potential", potential)]);
    let run = run_b(&s, &[], INIT, method, tol, 20.0, grid(20.0, 0.05));
    assert!(run.completed(), "{:?}", run.failure);
    let (q0, qd0) = (&run.initial.q, &run.initial.qd);
    let (mut q, mut qd) = ([0.0; 3], [0.0; 3]);
    let mut err = 0.0f64;
    for (t, obs) in run.solution.t.iter().zip(&run.samples) {
        s.closed_form(q0, qd0, *t, &mut q, &mut qd).unwrap();
        for i in 0..3 {
            err = err
                .max((obs.q[i] - q[i]).abs())
                .max((obs.qd[i] - qd[i]).abs());
        }
    }
    err
}

/// Spec: with a = 0 the trajectory is known in closed form; DOP853 at
/// tolerance 1e-12 must match it to 1e-9 over [0, 20] (positions reach
/// ~40 m, so this is ~1e-11 relative: what a 1e-12 local tolerance allows
/// after ~300 steps).
#[test]
fn a_zero_matches_closed_form_both_potentials() {
    for potential in ["paper", "com"] {
        let err = max_error_against_closed_form(potential, Method::Dop853, 1e-12);
        assert!(err < 1e-9, "potential {potential}: max error {err:e}");
    }
}

/// The closed form's physics: x stays bounded, y drifts at g sin α/(2ω0).
#[test]
fn a_zero_drifts_across_the_slope() {
    let s: Sleigh = scene(&[("a", "0"), ("alpha", "0.3")]);
    let t_end = 200.0;
    let run = run_b(
        &s,
        &[],
        INIT,
        Method::Dop853,
        1e-12,
        t_end,
        grid(t_end, 0.1),
    );
    let xs: Vec<f64> = run.samples.iter().map(|o| o.q[0]).collect();
    let x_range =
        xs.iter().cloned().fold(f64::MIN, f64::max) - xs.iter().cloned().fold(f64::MAX, f64::min);
    // |x − x0| ≤ (|C| · 2 + K)/ω0 from the closed form: bounded independent of t.
    let k = 9.81 * 0.3f64.sin() / 0.7;
    let c = 2.0 - k * 0.2f64.sin();
    assert!(
        x_range <= (2.0 * c.abs() + k) / 0.7 + 1e-9,
        "x range {x_range}"
    );
    // Mean drift of y over whole periods 2π/ω0.
    let period = 2.0 * std::f64::consts::PI / 0.7;
    let periods = (t_end / period).floor();
    let t1 = periods * period;
    let mut obs = nonholo_core::Observation::new(3, 1);
    let mut run = run;
    run.observe_at(t1, &mut obs).unwrap();
    let drift = (obs.q[1] - 0.0) / t1;
    let expect = 9.81 * 0.3f64.sin() / (2.0 * 0.7);
    // Over whole periods the oscillating terms of y(t) cancel except the
    // initial offset −C(cos φ − cos φ0)/ω0 − K(sin 2φ − sin 2φ0)/(4ω0), which is 0.
    assert!(
        (drift - expect).abs() < 1e-9,
        "drift {drift} expected {expect}"
    );
}

/// The AD-derived accelerations of B equal the spec's reduced equations
/// (u̇ = aω² + g sin α cos φ, ω̇ = −(a u ω + [com] g a sin α sin φ)/J) at
/// random states and parameters, and the multiplier equals the independent
/// derivation λ = m(uω + aω̇) + m g sin α sin φ (lateral momentum balance).
#[test]
fn accelerations_match_reduced_equations() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(20261121);
    for potential in ["paper", "com"] {
        for _ in 0..300 {
            let a: f64 = rng.random_range(-1.0..1.0);
            let j = a * a + rng.random_range(0.1..2.0);
            let m: f64 = rng.random_range(0.5..3.0);
            let alpha: f64 = rng.random_range(0.0..1.4);
            let g = 9.81;
            let s: Sleigh = scene(&[
                ("a", &a.to_string()),
                ("J", &j.to_string()),
                ("m", &m.to_string()),
                ("alpha", &alpha.to_string()),
                ("potential", potential),
            ]);
            let mut b = chetaev(s, &[]);
            let (x, y): (f64, f64) = (rng.random_range(-10.0..10.0), rng.random_range(-10.0..10.0));
            let phi: f64 = rng.random_range(-4.0..4.0);
            let (u, w): (f64, f64) = (rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0));
            let q = [x, y, phi];
            let qd = [u * phi.cos(), u * phi.sin(), w];
            let (mut qdd, mut lam) = ([0.0; 3], [0.0; 1]);
            accelerations(&mut b, 0.0, &q, &qd, &mut qdd, &mut lam).unwrap();

            let com = if potential == "com" { 1.0 } else { 0.0 };
            let ud = a * w * w + g * alpha.sin() * phi.cos();
            let wd = -(a * u * w + com * g * a * alpha.sin() * phi.sin()) / j;
            let expect = [
                ud * phi.cos() - u * w * phi.sin(),
                ud * phi.sin() + u * w * phi.cos(),
                wd,
            ];
            let lambda = m * (u * w + a * wd) + m * g * alpha.sin() * phi.sin();
            for i in 0..3 {
                let tol = 1e-12 * (1.0 + expect[i].abs());
                assert!(
                    (qdd[i] - expect[i]).abs() < tol,
                    "{potential}: q̈[{i}] {} vs {}",
                    qdd[i],
                    expect[i]
                );
            }
            assert!(
                (lam[0] - lambda).abs() < 1e-12 * (1.0 + lambda.abs()),
                "λ {} vs {lambda}",
                lam[0]
            );
        }
    }
}

/// Error ‖(q, q̇)(T) − closed form‖₂ at T = 4 for fixed steps h = T/N.
fn fixed_step_errors(method: Method, divisions: &[u32]) -> (Vec<f64>, Vec<f64>) {
    const T: f64 = 4.0;
    let s: Sleigh = scene(&[("a", "0"), ("alpha", "0.3")]);
    let initial = init::resolve(&s, &pairs(INIT), &[]).unwrap();
    let (mut q, mut qd) = ([0.0; 3], [0.0; 3]);
    s.closed_form(&initial.q, &initial.qd, T, &mut q, &mut qd)
        .unwrap();
    let steps: Vec<f64> = divisions.iter().map(|&n| T / n as f64).collect();
    let errs = steps
        .iter()
        .map(|&h| {
            let run = simulate(
                Box::new(chetaev(s.clone(), &[])),
                initial.clone(),
                RunConfig {
                    method,
                    options: Options {
                        fixed_step: Some(h),
                        output: vec![T],
                        ..Options::default()
                    },
                    t_end: T,
                    project_init: false,
                },
            )
            .unwrap();
            let o = run.samples.last().unwrap();
            (0..3)
                .map(|i| (o.q[i] - q[i]).powi(2) + (o.qd[i] - qd[i]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .collect();
    (steps, errs)
}

/// Measured orders of RK4, DOPRI5 and DOP853 on the sleigh are 4, 5 and 8:
/// least-squares slope of log(error) against log(h) within ±0.3.
///
/// Each ladder covers the method's asymptotic range with errors between
/// ~1e-5 and ~1e-12, above round-off (~1e-13 here). DOPRI5's fifth-order
/// error constants are small by design, so sixth-order terms steepen its
/// local slope from 5.7 (h = 0.3) to 5.15 (h = 0.025); its ladder is the
/// last stretch before round-off, where the fit gives ~5.25.
#[test]
fn convergence_orders_on_the_sleigh() {
    let cases: [(Method, &[u32], f64); 3] = [
        (Method::Rk4, &[40, 56, 80, 112, 160, 224], 4.0),
        (Method::Dopri5, &[56, 80, 112, 160], 5.0),
        (Method::Dop853, &[10, 14, 20, 28], 8.0),
    ];
    for (method, divisions, order) in cases {
        let (steps, errs) = fixed_step_errors(method, divisions);
        let p = fitted_order(&steps, &errs);
        eprintln!(
            "{}: h {steps:.4?}, errors {errs:?}, fitted order {p:.3}",
            method.name()
        );
        assert!(
            errs.iter().all(|e| *e > 1e-12),
            "{}: ladder reaches round-off: {errs:?}",
            method.name()
        );
        assert!(
            (p - order).abs() <= 0.3,
            "{}: fitted order {p}",
            method.name()
        );
    }
}

/// At tight tolerance B keeps the constraint and the energy at round-off
/// level relative to the energies involved (the sleigh with a ≠ 0 speeds up
/// to ~60 m/s, kinetic and potential energy ~2e3 J).
#[test]
fn energy_and_constraint_at_round_off() {
    for potential in ["paper", "com"] {
        let s: Sleigh = scene(&[("a", "0.4"), ("alpha", "0.3"), ("potential", potential)]);
        let run = run_b(&s, &[], INIT, Method::Dop853, 1e-13, 20.0, grid(20.0, 1.0));
        let d = &run.diagnostics;
        let speed_max = run
            .samples
            .iter()
            .map(|o| o.qd[0].hypot(o.qd[1]))
            .fold(0.0, f64::max);
        let energy_scale = 0.5 * speed_max * speed_max;
        eprintln!(
            "{potential}: residual {:e}, energy drift {:e} (scale {energy_scale:e})",
            d.constraint_residual_max, d.energy_drift_max
        );
        assert!(d.states_checked > 20, "{} states checked", d.states_checked);
        assert!(
            d.constraint_residual_max < 1e-11,
            "{potential}: residual {:e}",
            d.constraint_residual_max
        );
        assert!(
            d.energy_drift_max < 1e-12 * energy_scale.max(1.0),
            "{potential}: drift {:e}",
            d.energy_drift_max
        );
    }
}

/// The right-hand-side Jacobian (AD through the KKT solve) against central
/// differences of the right-hand side, for both stabilisations that change f.
#[test]
fn jacobian_matches_finite_differences() {
    use nonholo_core::integrate::OdeSystem;
    for opts in [&[][..], &[("stab", "baumgarte")][..]] {
        let s: Sleigh = scene(&[("a", "0.4"), ("potential", "com")]);
        let mut b = chetaev(s, opts);
        let y = [0.3, -0.2, 0.7, 1.1, 0.4, -0.6];
        let mut jac = [0.0; 36];
        assert!(b.jacobian(0.5, &y, &mut jac).unwrap());
        let h = 1e-6;
        for j in 0..6 {
            let (mut yp, mut ym) = (y, y);
            yp[j] += h;
            ym[j] -= h;
            let (mut fp, mut fm) = ([0.0; 6], [0.0; 6]);
            b.rhs(0.5, &yp, &mut fp).unwrap();
            b.rhs(0.5, &ym, &mut fm).unwrap();
            for i in 0..6 {
                let fd = (fp[i] - fm[i]) / (2.0 * h);
                // Central differences: error ~h² f''' + ε/h ≈ 1e-9.
                assert!(
                    (jac[i * 6 + j] - fd).abs() < 1e-7 * (1.0 + fd.abs()),
                    "{opts:?} J[{i},{j}] {} vs {fd}",
                    jac[i * 6 + j]
                );
            }
        }
    }
}

/// The horizontal sleigh with `a ≠ 0` (docs/stability.md): B follows
/// `u = V tanh(a V t/J + c)`, `ω = ω0 cosh c / cosh(a V t/J + c)`,
/// `V² = u0² + J ω0²`, to 1e-10 over 20 s at tolerance 1e-13 — forwards
/// and backwards, turning either way, the centre of mass ahead of the blade
/// or behind it, both potentials (which agree on a level plane); the
/// positions, from the closed-form heading and a quadrature of the
/// velocity, to 1e-9.
#[test]
fn horizontal_sleigh_matches_the_tanh_closed_form() {
    for (a, j, potential) in [
        ("0.4", "1", "paper"),
        ("-0.3", "0.5", "com"),
        ("1.2", "2", "paper"),
    ] {
        let s: Sleigh = scene(&[("a", a), ("J", j), ("alpha", "0"), ("potential", potential)]);
        for (u, omega) in [("2", "0.7"), ("-1.5", "0.4"), ("0.3", "-2.0")] {
            let init = [
                ("phi", "0.2"),
                ("u", u),
                ("omega", omega),
                ("x", "0"),
                ("y", "0"),
            ];
            let run = run_b(
                &s,
                &[],
                &init,
                Method::Dop853,
                1e-13,
                20.0,
                grid(20.0, 0.05),
            );
            assert!(run.completed(), "{:?}", run.failure);
            let (q0, qd0) = (&run.initial.q, &run.initial.qd);
            let (mut q, mut qd) = ([0.0; 3], [0.0; 3]);
            let (mut vel, mut pos) = (0.0f64, 0.0f64);
            for (t, obs) in run.solution.t.iter().zip(&run.samples) {
                s.closed_form(q0, qd0, *t, &mut q, &mut qd).unwrap();
                for i in 0..3 {
                    vel = vel.max((obs.qd[i] - qd[i]).abs());
                    pos = pos.max((obs.q[i] - q[i]).abs());
                }
            }
            println!("a {a}, u0 {u}, ω0 {omega}: velocities {vel:.1e}, positions {pos:.1e}");
            assert!(
                vel < 1e-10 && pos < 1e-9,
                "a {a} u0 {u} ω0 {omega}: {vel:e} {pos:e}"
            );
        }
    }
}

/// Far along (`a V t/J` well past the quadrature's range), the horizontal
/// closed form is straight motion at speed `V` along its limiting heading,
/// and with `ω0 = 0` it is straight from the start (any `a`, `a = 0` too).
#[test]
fn horizontal_closed_form_far_out_and_without_turning() {
    let s: Sleigh = scene(&[("a", "0.4"), ("alpha", "0")]);
    let (q0, qd0) = (
        [0.0, 0.0, 0.2],
        [2.0 * 0.2f64.cos(), 2.0 * 0.2f64.sin(), 0.7],
    );
    let v = (4.0f64 + 0.49).sqrt();
    let (mut q1, mut qd1, mut q2, mut qd2) = ([0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3]);
    s.closed_form(&q0, &qd0, 1000.0, &mut q1, &mut qd1).unwrap();
    s.closed_form(&q0, &qd0, 1010.0, &mut q2, &mut qd2).unwrap();
    assert!((q2[2] - q1[2]).abs() < 1e-14 && qd2[2].abs() < 1e-14);
    let moved = (q2[0] - q1[0]).hypot(q2[1] - q1[1]);
    assert!((moved - 10.0 * v).abs() < 1e-9, "{moved} vs {}", 10.0 * v);
    assert!(((q2[1] - q1[1]).atan2(q2[0] - q1[0]) - q1[2]).abs() < 1e-12);
    for a in ["0", "0.4"] {
        let s: Sleigh = scene(&[("a", a), ("alpha", "0")]);
        let (mut q, mut qd) = ([0.0; 3], [0.0; 3]);
        s.closed_form(
            &[1.0, 2.0, 0.3],
            &[0.3f64.cos(), 0.3f64.sin(), 0.0],
            5.0,
            &mut q,
            &mut qd,
        )
        .unwrap();
        assert!((q[0] - 1.0 - 5.0 * 0.3f64.cos()).abs() < 1e-14 && (q[2] - 0.3).abs() == 0.0);
    }
}
