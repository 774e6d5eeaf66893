//! The explicit (ODE) form of formulation A (`src/ode.rs`): `q⁗` from A's
//! derivative array against C's Taylor coefficients, the explicit form
//! against the implicit form and against C, convergence orders, drift of
//! the hidden constraints, the guards (singular set; resolution of `q⁗`,
//! where the explicit form stops by design), and the cost of a right-hand
//! side.
//!
//! C (`nonholo_vakonomic`) only supplies initial data and reference values;
//! A's explicit form never consults it.

mod common;

use common::*;
use std::time::Instant;

use nonholo_core::integrate::{
    ImplicitSystem, IntegrateError, Method, OdeSystem, Options, SystemError, solve,
};
use nonholo_core::{Initial, Model, Params, Run, Scene, simulate};
use nonholo_embedding::ode::ODE_RESOLUTION;
use nonholo_embedding::{Embedding, OPTIONS};
use nonholo_scenes::Sleigh;
use nonholo_vakonomic::Vakonomic;

fn pairs(items: &[(&str, &str)]) -> Vec<(String, String)> {
    items
        .iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect()
}

/// The sleigh with default parameters (a = 0.4, α = 0.3) and `potential`.
fn sleigh(potential: &str) -> Sleigh {
    let given = pairs(&[("potential", potential)]);
    Sleigh::from_params(&Params::resolve(Sleigh::INFO.params, &given, "parameter").unwrap())
        .unwrap()
}

/// A with `opts`; unless they say otherwise, with the settings these tests
/// measure: the explicit form stopping at the singular set
/// (`continuation = none`) and projected onto its hidden constraints.
fn embedding<S: Scene>(scene: S, opts: &[(&str, &str)]) -> Embedding<S> {
    let mut all: Vec<(&str, &str)> = vec![("continuation", "none"), ("stab", "projection")];
    all.retain(|(k, _)| opts.iter().all(|(o, _)| o != k));
    all.extend_from_slice(opts);
    Embedding::new(
        scene,
        Params::resolve(OPTIONS, &pairs(&all), "option").unwrap(),
    )
    .unwrap()
}

/// C's Taylor coefficients `(q̈, q⃛, q⁗)` of `(x, y)` at `(t, y)`.
fn taylor(c: &mut Vakonomic<Sleigh>, t: f64, y: &[f64]) -> [[f64; 2]; 3] {
    let (mut yd, mut ydd, mut yddd) = ([0.0; 7], [0.0; 7], [0.0; 7]);
    c.taylor(t, y, &mut yd, &mut ydd, &mut yddd).unwrap();
    [[yd[3], yd[4]], [ydd[3], ydd[4]], [yddd[3], yddd[4]]]
}

/// A's initial data matched with C at `(t, y)` (as the lab matches them:
/// C's Taylor coefficients `q̈`, `q⃛`; A completes and checks them).
fn matched(c: &mut Vakonomic<Sleigh>, t: f64, y: &[f64]) -> Initial {
    let [second, third, _] = taylor(c, t, y);
    Initial {
        t0: t,
        q: y[..3].to_vec(),
        qd: y[3..6].to_vec(),
        extra: vec![
            ("x_ddot".into(), second[0]),
            ("y_ddot".into(), second[1]),
            ("x_dddot".into(), third[0]),
            ("y_dddot".into(), third[1]),
        ],
    }
}

/// C from `y` (with its λ0) by DOP853 at 1e-12.
fn run_c(s: &Sleigh, y: &[f64; 7], t_end: f64, every: f64) -> Run {
    run_c_tol(s, y, t_end, every, 1e-12)
}

/// `max |(x, y)_a − (x, y)_b|` over common samples.
fn position_difference(a: &Run, b: &Run) -> f64 {
    assert_eq!(a.solution.t.len(), b.solution.t.len());
    common::position_difference(a, b)
}

/// First zero of C's forward speed `u = ẋ cos φ + ẏ sin φ` on its samples.
fn c_reversal(c: &Run) -> f64 {
    let u: Vec<f64> = c
        .samples
        .iter()
        .map(|o| o.qd[0] * o.q[2].cos() + o.qd[1] * o.q[2].sin())
        .collect();
    let t = &c.solution.t;
    let i = (1..u.len())
        .find(|&i| u[i - 1] * u[i] <= 0.0)
        .expect("C reverses");
    t[i - 1] + (t[i] - t[i - 1]) * u[i - 1] / (u[i - 1] - u[i])
}

/// (a) Along C's motions (both potentials, λ0 ∈ {0, 0.5, −1}, up to 0.1 s
/// before C's reversal), A's `w(z) = q⁗` — at C's own `z` and at A's
/// completion of C's `(q, q̇, q̈)` — equals C's Taylor coefficient `q⁗`, and
/// equals the `q⁗` of the consistent completion A uses for the implicit
/// form's initial slope.
#[test]
fn fourth_derivative_equals_vakonomic_along_its_motion() {
    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    let mut count = 0;
    for potential in ["paper", "com"] {
        let s = sleigh(potential);
        for lambda0 in [0.0, 0.5, -1.0] {
            let y0 = c_state(0.2, 2.0, 0.7, lambda0);
            let c_run = run_c(&s, &y0, 1.5, 0.05);
            let t_rev = c_reversal(&c_run);
            let mut c = vakonomic(&s);
            let mut a = embedding(s.clone(), &[]);
            for (i, &t) in c_run.solution.t.iter().enumerate() {
                if t > t_rev - 0.1 {
                    break;
                }
                let y = c_run.solution.row(i);
                let [second, third, fourth] = taylor(&mut c, t, y);
                let scale = fourth[0].abs().max(fourth[1].abs());
                let rel =
                    |w: &[f64], v: &[f64; 2]| (w[0] - v[0]).abs().max((w[1] - v[1]).abs()) / scale;
                // At C's own z.
                let zc = [
                    y[0], y[1], y[3], y[4], second[0], second[1], third[0], third[1],
                ];
                let init = matched(&mut c, t, y);
                let z = a.initial_state(&init).unwrap();
                let yp0 = a.initial_slope().unwrap();
                let at_c = rel(
                    a.explicit_form().fourth_derivative(t, &zc).unwrap(),
                    &fourth,
                );
                // At A's completion (z moved onto A's hidden constraints).
                let w = a.explicit_form().fourth_derivative(t, &z).unwrap().to_vec();
                let at_a = rel(&w, &fourth);
                let vs_slope = rel(&w, &[yp0[6], yp0[7]]);
                assert!(
                    at_c < 1e-8 && at_a < 1e-8 && vs_slope < 1e-10,
                    "{potential}, λ0 = {lambda0}, t = {t}: w(z_C) {at_c:e}, w(z_A) {at_a:e} from \
                     C's q⁗ {fourth:?}; {vs_slope:e} from the completion's q⁗"
                );
                worst = (worst.0.max(at_c), worst.1.max(at_a), worst.2.max(vs_slope));
                count += 1;
            }
        }
    }
    eprintln!(
        "w(z) vs C's q⁗ over {count} states of C's motions: worst relative {:.1e} at C's z, \
         {:.1e} at A's completion; vs the completion's q⁗ {:.1e}",
        worst.0, worst.1, worst.2
    );
}

/// (b) From the same consistent initial data (matched with C at λ0 = 0,
/// completed by `initial_state`), A's explicit form by DOP853 at 1e-10
/// (projection on) reproduces A's implicit form by Radau at 1e-10 and C
/// (DOP853, 1e-12) in position to 1e-7, sampled every 1e-3 s, up to t = 0.9
/// (C reverses at 0.923; the explicit form's resolution guard would stop it
/// at 0.906451, see (g)). The heading passes π/2 at t ≈ 0.884, where the
/// map's derivatives need the quadrant-switching arctangent of
/// `nonholo_core::scene::atan2` (num-dual's `atan2`, differentiated through
/// `ẏ/ẋ`, stopped the explicit form there).
#[test]
fn explicit_form_reproduces_implicit_form_and_vakonomic() {
    let s = sleigh("paper");
    let y0 = c_state(0.2, 2.0, 0.7, 0.0);
    let init = matched(&mut vakonomic(&s), 0.0, &y0);
    let t_end = 0.9;
    let c = run_c(&s, &y0, t_end, 1e-3);
    // Default options: stab = projection (ignored by the implicit form).
    let start = Instant::now();
    let ode = simulate(
        Box::new(embedding(s.clone(), &[])),
        init.clone(),
        config(Method::Dop853, 1e-10, t_end, 1e-3),
    )
    .unwrap();
    let ode_ms = start.elapsed().as_secs_f64() * 1e3;
    let start = Instant::now();
    let dae = simulate(
        Box::new(embedding(s.clone(), &[])),
        init.clone(),
        config(Method::Radau5, 1e-10, t_end, 1e-3),
    )
    .unwrap();
    let dae_ms = start.elapsed().as_secs_f64() * 1e3;
    assert!(ode.completed(), "{:?}", ode.failure);
    assert!(dae.completed(), "{:?}", dae.failure);
    let (vs_dae, vs_c, dae_c) = (
        position_difference(&ode, &dae),
        position_difference(&ode, &c),
        position_difference(&dae, &c),
    );
    let st = &ode.solution.stats;
    eprintln!(
        "to t = {t_end}: explicit vs implicit {vs_dae:.1e}, explicit vs C {vs_c:.1e}, \
         implicit vs C {dae_c:.1e}; explicit {} steps ({} rejected, {} rhs) {ode_ms:.0} ms, \
         implicit {} steps {dae_ms:.0} ms",
        st.steps, st.rejected_steps, st.rhs_evals, dae.solution.stats.steps
    );
    assert!(vs_dae < 1e-7 && vs_c < 1e-7, "{vs_dae:e} {vs_c:e}");
}

/// The derivative array traced into programs (the default) and evaluated
/// by dual passes over the jets give the same motion: DOP853 at 1e-10 to
/// t = 0.8 (projection on), with the same steps and positions within 1e-12
/// m (the two `q⁗` differ by round-off, ~1e-15 relative; measured 2e-15 m
/// at the outputs, where a wrong derivative would move them by the runs'
/// own error, ~1e-10); the sleigh is traced (no branch of its functions
/// depends on values).
#[test]
fn traced_and_dual_pass_derivative_arrays_give_one_motion() {
    let s = sleigh("paper");
    let y0 = c_state(0.2, 2.0, 0.7, 0.0);
    let init = matched(&mut vakonomic(&s), 0.0, &y0);
    let run = |traced: bool| {
        let mut a = embedding(s.clone(), &[]);
        a.explicit_form().set_traced(traced);
        let run = simulate(
            Box::new(a),
            init.clone(),
            config(Method::Dop853, 1e-10, 0.8, 1e-2),
        )
        .unwrap();
        assert!(run.completed(), "{:?}", run.failure);
        run
    };
    let (traced, dual) = (run(true), run(false));
    let diff = position_difference(&traced, &dual);
    let (a, b) = (&traced.solution.stats, &dual.solution.stats);
    eprintln!(
        "traced vs dual passes: positions {diff:.1e}; steps {} and {}, rhs {} and {}, {:.1} and \
         {:.1} ms",
        a.steps,
        b.steps,
        a.rhs_evals,
        b.rhs_evals,
        a.wall_time_s * 1e3,
        b.wall_time_s * 1e3
    );
    assert!(diff < 1e-12, "{diff:e}");
    assert_eq!(a.steps, b.steps);
    let mut probe = embedding(s, &[]);
    probe.explicit_form().set_traced(true);
    let z = probe.initial_state(&init).unwrap();
    probe.explicit_form().fourth_derivative(0.0, &z).unwrap();
    assert_eq!(probe.explicit_form().trace_refused(), None);
}

/// Final state at t = 0.5 of A's explicit form from the default matched
/// data (projection on).
fn final_state(method: Method, opts: Options) -> Vec<f64> {
    let s = sleigh("paper");
    let init = matched(&mut vakonomic(&s), 0.0, &c_state(0.2, 2.0, 0.7, 0.0));
    let mut a = embedding(s, &[]);
    let z0 = a.initial_state(&init).unwrap();
    let opts = Options {
        dense: false,
        ..opts
    };
    solve(method, a.explicit_form(), 0.0, &z0, 0.5, &opts)
        .unwrap()
        .y_last
}

fn fixed(n: usize) -> Options {
    Options {
        fixed_step: Some(0.5 / n as f64),
        ..Options::default()
    }
}

/// Largest component of `|a − b| / (1 + |b|)`.
fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / (1.0 + y.abs()))
        .fold(0.0, f64::max)
}

/// (c) Fixed-step orders on [0, 0.5]: RK4 4, DOPRI5 5 (±0.3). Reference:
/// DOP853 with 50 fixed steps; its error, estimated from a second
/// reference with 25 steps (order 8: error(50) ≈ |z₂₅ − z₅₀| / 255), is far
/// below the errors measured.
#[test]
fn fixed_step_orders_of_the_explicit_form() {
    let reference = final_state(Method::Dop853, fixed(50));
    let second = final_state(Method::Dop853, fixed(25));
    let ref_error = distance(&second, &reference) / 255.0;
    eprintln!(
        "reference (DOP853, 50 steps): estimated error {ref_error:.1e} (|z₂₅ − z₅₀| = {:.1e})",
        distance(&second, &reference)
    );
    for (method, steps, order) in [
        (Method::Rk4, [25, 50, 100], 4.0),
        (Method::Dopri5, [20, 40, 80], 5.0),
    ] {
        let errors: Vec<f64> = steps
            .iter()
            .map(|&n| distance(&final_state(method, fixed(n)), &reference))
            .collect();
        let orders: Vec<f64> = errors.windows(2).map(|e| (e[0] / e[1]).log2()).collect();
        let shown: Vec<String> = errors.iter().map(|e| format!("{e:.2e}")).collect();
        eprintln!("{method:?}: steps {steps:?}, errors {shown:?}, orders {orders:.2?}");
        assert!(errors[2] > 100.0 * ref_error, "{errors:?} vs {ref_error:e}");
        let last = orders[orders.len() - 1];
        assert!((last - order).abs() <= 0.3, "{method:?}: {orders:?}");
    }
}

/// (d) Without projection the hidden-constraint residual grows along a
/// DOP853 run (1e-8) from round-off to the level of the local errors (and
/// stays there over the run: the manifold is not repelling); with
/// projection every accepted state is put back on A's hidden constraints to
/// round-off. The residual is the derivative array's, relative to the terms
/// that cancel in each row ([`Embedding::hidden_residual`]).
#[test]
fn hidden_constraints_drift_without_projection() {
    let s = sleigh("paper");
    let init = matched(&mut vakonomic(&s), 0.0, &c_state(0.2, 2.0, 0.7, 0.0));
    let mut logs = Vec::new();
    for stab in ["none", "projection"] {
        let mut a = embedding(s.clone(), &[("stab", stab)]);
        let z0 = a.initial_state(&init).unwrap();
        a.explicit_form().record_hidden(true);
        let opts = Options {
            rtol: 1e-8,
            atol: 1e-8,
            ..Options::default()
        };
        let sol = solve(Method::Dop853, a.explicit_form(), 0.0, &z0, 0.8, &opts).unwrap();
        let log = a.explicit_form().hidden_log().to_vec();
        assert_eq!(log.len(), sol.stats.steps);
        let at = |t: f64| {
            log.iter()
                .find(|r| r[0] >= t)
                .map(|r| (r[1], r[2]))
                .unwrap()
        };
        let before = log.iter().fold(0.0f64, |m, r| m.max(r[1]));
        let after = log.iter().fold(0.0f64, |m, r| m.max(r[2]));
        let stats = a.explicit_form().reduction_stats();
        eprintln!(
            "stab = {stab}: hidden residual before/after each step at t ≈ 0.2 {:.1e}/{:.1e}, \
             0.4 {:.1e}/{:.1e}, 0.6 {:.1e}/{:.1e}, 0.8 {:.1e}/{:.1e}; max {before:.1e}/{after:.1e}; \
             {} steps, largest projection |Δq⃛|/|q⃛| {:.1e}",
            at(0.2).0,
            at(0.2).1,
            at(0.4).0,
            at(0.4).1,
            at(0.6).0,
            at(0.6).1,
            at(0.8).0,
            at(0.8).1,
            sol.stats.steps,
            stats.max_third_change
        );
        logs.push(log);
    }
    let (none, projected) = (&logs[0], &logs[1]);
    let grown = none.last().unwrap()[2];
    let kept = projected.iter().fold(0.0f64, |m, r| m.max(r[2]));
    assert!(kept < 1e-13, "with projection: {kept:e}");
    assert!(
        grown > 100.0 * kept && grown > 1e3 * none[0][2],
        "without projection the residual should grow: {grown:e} at the end, {:e} after the \
         first step, {kept:e} with projection",
        none[0][2]
    );
}

/// (e) The explicit form stops at the embedding map's singular set as the
/// implicit form does (same guard, located on the step polynomial) when that
/// guard fires first (`singular_tol = 0.4`); with the default `singular_tol`
/// its resolution guard stops it earlier, by design (see (f), (g)). Its
/// guard is the smaller of the two. A stage beyond the set is refused by
/// both forms with the same error.
#[test]
fn guard_and_stage_check_as_in_the_implicit_form() {
    let s = sleigh("paper");
    let y0 = c_state(0.2, 2.0, 0.7, -1.0);
    let init = matched(&mut vakonomic(&s), 0.0, &y0);
    // At 0.4 m/s q⁗ is still resolved to ~1e-9: the singular-set guard
    // fires first in both forms.
    let tol = [("singular_tol", "0.4")];
    let mut stops = Vec::new();
    for method in [Method::Dop853, Method::Radau5] {
        let run = simulate(
            Box::new(embedding(s.clone(), &tol)),
            init.clone(),
            config(method, 1e-10, 2.0, 0.01),
        )
        .unwrap();
        match run.failure {
            Some(IntegrateError::Stopped { t, reason }) => {
                assert!(
                    reason.contains("zero speed") && reason.contains("extrapolated zero"),
                    "{reason}"
                );
                stops.push(t);
            }
            other => panic!("{method:?} should stop at the singular set, got {other:?}"),
        }
    }
    eprintln!(
        "singular_tol = 0.4: explicit form stops at {:.9}, implicit at {:.9}",
        stops[0], stops[1]
    );
    assert!((stops[0] - stops[1]).abs() < 1e-6, "{stops:?}");

    // With the default guard the explicit form stops at its resolution
    // limit, before the implicit form's stop and before C's reversal.
    let c = run_c(&s, &y0, 1.0, 1e-3);
    let t_rev = c_reversal(&c);
    let run = simulate(
        Box::new(embedding(s.clone(), &[])),
        init.clone(),
        config(Method::Dop853, 1e-10, 2.0, 0.01),
    )
    .unwrap();
    match &run.failure {
        Some(IntegrateError::Stopped { t, reason }) => {
            assert!(reason.contains("resolution limit"), "{reason}");
            assert!(
                *t > t_rev - 0.03 && *t < t_rev - 0.005,
                "{t} vs C's reversal {t_rev}"
            );
            eprintln!(
                "default singular_tol: explicit form stops at {t:.6} (C reverses at {t_rev:.6})"
            );
        }
        other => {
            panic!("expected the explicit form to stop at its resolution limit, got {other:?}")
        }
    }

    // The explicit form's guard is the smaller of the singular-set guard
    // and singular_tol · ln(ODE_RESOLUTION / ρ).
    let mut a = embedding(s.clone(), &[]);
    let z0 = a.initial_state(&init).unwrap();
    let yp0 = a.initial_slope().unwrap();
    let singular = ImplicitSystem::guard(a.implicit_form(), 0.0, &z0).unwrap();
    let rho = a.explicit_form().resolution(0.0, &z0).unwrap();
    assert!(rho.rho < 1e-12 && rho.observed.is_none(), "{rho:?}");
    let margin = 1e-3 * (ODE_RESOLUTION / rho.rho).ln();
    assert_eq!(
        OdeSystem::guard(a.explicit_form(), 0.0, &z0),
        Some(singular.min(margin))
    );

    // A stage beyond the set (velocity reversed against the direction at
    // the start) is refused by both forms with the same error.
    let mut back = z0.clone();
    back[2] = -z0[2];
    back[3] = -z0[3];
    let mut dy = vec![0.0; 8];
    let ode_err: SystemError = OdeSystem::rhs(a.explicit_form(), 0.0, &back, &mut dy).unwrap_err();
    let dae_err = a
        .implicit_form()
        .residual(0.0, &back, &yp0, &mut dy)
        .unwrap_err();
    assert!(
        ode_err.message.contains("crossed the singular set"),
        "{ode_err}"
    );
    assert_eq!(ode_err, dae_err);
}

/// `ρ` as reported in a resolution stop's reason ("… only to 1.00e-8 relative …").
fn reported_rho(reason: &str) -> f64 {
    let rest = reason
        .split("only to ")
        .nth(1)
        .unwrap_or_else(|| panic!("no ρ in {reason}"));
    rest.split_whitespace().next().unwrap().parse().unwrap()
}

/// Largest `|(x, y)_a − (x, y)_b|` over the output times both runs reached
/// (a stopped run ends with a sample at its stop, off the grid).
fn position_difference_common(a: &Run, b: &Run) -> f64 {
    let n = a
        .solution
        .t
        .iter()
        .zip(&b.solution.t)
        .take_while(|(x, y)| x == y)
        .count();
    assert!(n > 100, "{n} common samples");
    a.samples[..n]
        .iter()
        .zip(&b.samples[..n])
        .map(|(p, q)| (p.q[0] - q.q[0]).abs().max((p.q[1] - q.q[1]).abs()))
        .fold(0.0, f64::max)
}

/// Whether every sample of a run is finite.
fn finite(run: &Run) -> bool {
    run.samples
        .iter()
        .all(|o| o.q.iter().chain(&o.qd).all(|v| v.is_finite()))
}

/// Speed `|v|` of the last sample (at the stop of a stopped run).
fn last_speed(run: &Run) -> f64 {
    let o = run.samples.last().unwrap();
    o.qd[0].hypot(o.qd[1])
}

/// (f) The sleigh launched up the slope (φ0 = 3, u0 = 2, ω0 = 0.3, gravity
/// at the centre of mass; matched with C at λ0 = 0) decelerates slowly
/// through zero speed. The explicit form (DOP853 at 1e-10 and 1e-12, RK4
/// with h = 1e-3) stops by design where `q⁗` is resolved only to
/// `ODE_RESOLUTION` (at |v| ≈ 0.075 m/s) — not with a failing solve, as it
/// did at t ≈ 0.674 —, 25 ms before the implicit form stops at its
/// singular-set guard (this sleigh decelerates at only ~3 m/s²); every
/// sample is finite and follows C.
#[test]
fn explicit_form_stops_at_its_resolution_limit_up_the_slope() {
    let s = sleigh("com");
    let y0 = c_state(3.0, 2.0, 0.3, 0.0);
    let init = matched(&mut vakonomic(&s), 0.0, &y0);
    let c = run_c(&s, &y0, 1.0, 1e-3);
    let t_rev = c_reversal(&c);
    let dae = simulate(
        Box::new(embedding(s.clone(), &[])),
        init.clone(),
        config(Method::Radau5, 1e-10, 3.0, 1e-3),
    )
    .unwrap();
    let t_dae = match &dae.failure {
        Some(IntegrateError::Stopped { t, reason }) if reason.contains("zero speed") => *t,
        other => panic!("the implicit form should stop at the singular set, got {other:?}"),
    };
    let mut stops = Vec::new();
    for (method, rtol, h) in [
        (Method::Dop853, 1e-10, None),
        (Method::Dop853, 1e-12, None),
        (Method::Rk4, 1e-10, Some(1e-3)),
    ] {
        let mut cfg = config(method, rtol, 3.0, 1e-3);
        cfg.options.fixed_step = h;
        let start = Instant::now();
        let run = simulate(Box::new(embedding(s.clone(), &[])), init.clone(), cfg).unwrap();
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let (t, reason) = match &run.failure {
            Some(IntegrateError::Stopped { t, reason }) => (*t, reason.clone()),
            other => panic!("{method:?} {rtol:e}: should stop by design, got {other:?}"),
        };
        // The resolution limit comes first here (the singular-set guard
        // would be named if it fired first).
        assert!(reason.contains("resolution limit"), "{reason}");
        let rho = reported_rho(&reason);
        let (speed, vs_c) = (last_speed(&run), position_difference_common(&run, &c));
        let st = &run.solution.stats;
        eprintln!(
            "up the slope, {method:?} rtol {rtol:e} h {h:?}: stops at {t:.6} ({:.1} ms before \
             the implicit form's stop {t_dae:.6}; C reverses at {t_rev:.6}), |v| = {speed:.3} m/s \
             at the last sample, ρ = {rho:.2e}; positions vs C {vs_c:.1e}; {} steps, {ms:.0} ms",
            (t_dae - t) * 1e3,
            st.steps
        );
        assert!(finite(&run), "{method:?}: non-finite samples");
        assert!((ODE_RESOLUTION..5e-8).contains(&rho), "{rho:e}");
        assert!(t_dae - t > 0.02 && t_dae - t < 0.03, "{t} vs {t_dae}");
        assert!(speed > 0.06 && speed < 0.09, "{speed}");
        assert!(vs_c < 1e-10, "{vs_c:e}");
        stops.push(t);
    }
    let spread =
        stops.iter().fold(0.0f64, |a, &t| a.max(t)) - stops.iter().fold(1.0f64, |a, &t| a.min(t));
    assert!(spread < 2e-3, "{stops:?}");
}

/// (g) The default sleigh (a = 0.4, α = 0.3, φ0 = 0.2, u0 = 2, ω0 = 0.7;
/// matched with C at λ0 = 0; both potentials) integrated to t = 3 by DOP853
/// at 1e-13 — a reference run — stops at its resolution limit shortly
/// before C's reversal, its positions agreeing with C (DOP853, 1e-13) up
/// to the stop.
#[test]
fn default_sleigh_at_tight_tolerance_stops_before_the_reversal() {
    for potential in ["paper", "com"] {
        let s = sleigh(potential);
        let y0 = c_state(0.2, 2.0, 0.7, 0.0);
        let init = matched(&mut vakonomic(&s), 0.0, &y0);
        let c = run_c_tol(&s, &y0, 1.5, 1e-3, 1e-13);
        let t_rev = c_reversal(&c);
        let start = Instant::now();
        let run = simulate(
            Box::new(embedding(s.clone(), &[])),
            init.clone(),
            config(Method::Dop853, 1e-13, 3.0, 1e-3),
        )
        .unwrap();
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let (t, reason) = match &run.failure {
            Some(IntegrateError::Stopped { t, reason }) => (*t, reason.clone()),
            other => panic!("{potential}: should stop by design, got {other:?}"),
        };
        assert!(reason.contains("resolution limit"), "{reason}");
        let rho = reported_rho(&reason);
        let vs_c = position_difference_common(&run, &c);
        let st = &run.solution.stats;
        eprintln!(
            "{potential}: DOP853 1e-13 stops at {t:.6} (C reverses at {t_rev:.6}, {:.1} ms \
             later), |v| = {:.3} m/s at the last sample, ρ = {rho:.2e}; positions vs C \
             {vs_c:.1e} over {} samples; {} steps ({} rejected), {ms:.0} ms",
            (t_rev - t) * 1e3,
            last_speed(&run),
            run.samples.len(),
            st.steps,
            st.rejected_steps
        );
        assert!(finite(&run));
        assert!((ODE_RESOLUTION..5e-8).contains(&rho), "{rho:e}");
        assert!(t_rev - t > 0.01 && t_rev - t < 0.022, "{t} vs {t_rev}");
        assert!(vs_c < 1e-10, "{vs_c:e}");
    }
}
