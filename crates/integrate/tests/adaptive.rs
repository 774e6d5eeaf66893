//! Adaptive runs of DOPRI5 and DOP853: accuracy against tolerance, output
//! grid, work counters, stiffness detection.

mod common;

use std::f64::consts::PI;

use common::{Kepler, Oscillator, adaptive, dist, slope};
use nonholo_integrate::{Method, OdeSystem, Options, SystemError, solve};

const ADAPTIVE: [Method; 2] = [Method::Dopri5, Method::Dop853];

/// Largest error against the closed form over `n + 1` equidistant samples.
fn kepler_max_error(method: Method, tol: f64, periods: f64, n: usize) -> (f64, f64) {
    let k = Kepler { e: 0.5 };
    let t_end = periods * 2.0 * PI;
    let opts = Options {
        rtol: tol,
        atol: tol,
        output: (0..=n).map(|i| t_end * i as f64 / n as f64).collect(),
        ..Options::default()
    };
    let s = solve(method, &mut Kepler { e: 0.5 }, 0.0, &k.y0(), t_end, &opts).unwrap();
    assert_eq!(s.t.len(), n + 1);
    let err = (0..s.t.len())
        .map(|i| dist(s.row(i), &k.exact(s.t[i])))
        .fold(0.0, f64::max);
    let energy = (Kepler::energy(&s.y_last) + 0.5).abs();
    (err, energy)
}

#[test]
fn kepler_at_tolerance_1e_10() {
    // The controller keeps each local error near tol (DOPRI5's estimate is
    // that of the embedded 4th-order solution, so the 5th-order local error
    // is smaller still), but global errors add up over the ~180 (DOPRI5) or
    // ~35 (DOP853) steps per period, and on Kepler an error in the energy
    // becomes an error in the period, so the phase error grows linearly with
    // time. Measured: one period 1.5e-8 (DOPRI5), 6.9e-9 (DOP853); three
    // periods 7.3e-8, 4.9e-8, i.e. 100–750 × tol — the same as scipy's RK45
    // (1.1e-7) and DOP853 (5.1e-8) on this problem. The bounds below leave
    // a factor 2–3 of margin; the energy, free of the phase drift, stays at
    // a few tol.
    for method in ADAPTIVE {
        let (err1, _) = kepler_max_error(method, 1e-10, 1.0, 200);
        let (err3, energy) = kepler_max_error(method, 1e-10, 3.0, 600);
        eprintln!("{method:?}: 1 period {err1:.2e}, 3 periods {err3:.2e}, energy {energy:.2e}");
        assert!(err1 < 4e-8, "{method:?}: one period, error {err1:e}");
        assert!(err3 < 2e-7, "{method:?}: three periods, error {err3:e}");
        assert!(energy < 2e-9, "{method:?}: energy error {energy:e}");
    }
}

#[test]
fn error_is_proportional_to_tolerance() {
    // Hairer's control of the error per step with local extrapolation gives
    // global errors ∝ tol (DOPRI5: h ∝ tol^(1/5), local error ∝ h^6, number of
    // steps ∝ tol^(-1/5)). Measured slopes 1.04 (DOPRI5), 1.07 (DOP853).
    for method in ADAPTIVE {
        let tols = [1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12];
        let errs: Vec<f64> = tols
            .iter()
            .map(|&tol| kepler_max_error(method, tol, 3.0, 200).0)
            .collect();
        let p = slope(&tols, &errs);
        eprintln!("{method:?}: error ∝ tol^{p:.3}");
        assert!(
            (0.8..=1.25).contains(&p),
            "{method:?}: slope {p}, errors {errs:?}"
        );
    }
}

#[test]
fn output_grid_is_sampled_exactly_and_t_end_appended() {
    for method in ADAPTIVE {
        let grid = vec![0.0, 0.25, 1.0, 2.5, 2.75];
        let opts = Options {
            rtol: 1e-11,
            atol: 1e-11,
            output: grid.clone(),
            dense: false,
            ..Options::default()
        };
        let y0 = [1.0, 0.0];
        let s = solve(method, &mut Oscillator, 0.0, &y0, 3.0, &opts).unwrap();
        assert_eq!(s.t, [0.0, 0.25, 1.0, 2.5, 2.75, 3.0]);
        assert_eq!(s.y.len(), 6 * 2);
        assert_eq!(s.row(0), y0, "the sample at t0 is y0 itself");
        for (i, &t) in s.t.iter().enumerate() {
            assert!(
                dist(s.row(i), &Oscillator::exact(t)) < 1e-9,
                "{method:?} t = {t}"
            );
        }
        assert_eq!(s.row(5), &s.y_last[..]);
        assert_eq!(s.t_last, 3.0);
        assert!(s.dense.is_none());

        // t_end already in the grid: not repeated; empty grid: just t_end.
        let opts = Options {
            output: vec![1.5, 3.0],
            ..Options::default()
        };
        let s = solve(method, &mut Oscillator, 0.0, &y0, 3.0, &opts).unwrap();
        assert_eq!(s.t, [1.5, 3.0]);
        let s = solve(method, &mut Oscillator, 0.0, &y0, 3.0, &Options::default()).unwrap();
        assert_eq!(s.t, [3.0]);
    }
}

#[test]
fn rk4_output_grid_between_steps() {
    let opts = Options {
        fixed_step: Some(0.01),
        output: (0..=30).map(|i| i as f64 * 0.1).collect(),
        ..Options::default()
    };
    let s = solve(Method::Rk4, &mut Oscillator, 0.0, &[1.0, 0.0], 3.0, &opts).unwrap();
    assert_eq!(s.t.len(), 31);
    for (i, &t) in s.t.iter().enumerate() {
        // Hermite interpolation error ~h⁴/384·|y''''| plus global error ~3e-9.
        assert!(dist(s.row(i), &Oscillator::exact(t)) < 1e-8, "t = {t}");
    }
}

#[test]
fn work_counters_add_up() {
    // rhs_evals = 1 (t0) + 1 (HINIT) + per trial step: DOPRI5 6;
    // DOP853 11, + 1 per accepted step (f at the new point), + 3 per step
    // with dense output.
    let k = Kepler { e: 0.5 };
    for (method, dense) in [
        (Method::Dopri5, true),
        (Method::Dop853, true),
        (Method::Dop853, false),
    ] {
        let opts = Options {
            rtol: 1e-8,
            atol: 1e-8,
            dense,
            ..Options::default()
        };
        let s = solve(
            method,
            &mut Kepler { e: 0.5 },
            0.0,
            &k.y0(),
            2.0 * PI,
            &opts,
        )
        .unwrap();
        let st = &s.stats;
        let trials = st.steps + st.rejected_steps;
        let expect = match method {
            Method::Dopri5 => 2 + 6 * trials,
            _ => 2 + 11 * trials + st.steps + if dense { 3 * st.steps } else { 0 },
        };
        assert_eq!(st.rhs_evals, expect, "{method:?} dense={dense}: {st:?}");
        let dense_evals = if method == Method::Dop853 && dense {
            3 * st.steps
        } else {
            0
        };
        assert_eq!(st.dense_rhs_evals, dense_evals, "{method:?} dense={dense}");
        assert_eq!(st.newton_iterations, 0);
        assert_eq!(s.dense.as_ref().map(|d| d.len()), dense.then_some(st.steps));
        assert_eq!(
            (st.jacobian_evals, st.lu_decompositions, st.newton_failures),
            (0, 0, 0)
        );
        assert!(st.wall_time_s > 0.0);
        assert!(st.stiffness_detected.is_none());
    }
}

#[test]
fn step_size_options_are_respected() {
    let y0 = [1.0, 0.0];
    let opts = Options {
        h_max: Some(0.05),
        ..Options::default()
    };
    for method in ADAPTIVE {
        let s = solve(method, &mut Oscillator, 0.0, &y0, 1.0, &opts).unwrap();
        assert!(s.stats.steps >= 20, "{method:?}: {} steps", s.stats.steps);
        let d = s.dense.unwrap();
        let mut out = [0.0; 2];
        assert!(d.eval(1.0, &mut out) && dist(&out, &s.y_last) < 1e-15);
    }
    // Fixed step for the embedded methods: no rejection, no controller.
    let opts = Options {
        fixed_step: Some(0.1),
        rtol: 1e-13,
        atol: 1e-13,
        ..Options::default()
    };
    for method in ADAPTIVE {
        let s = solve(method, &mut Oscillator, 0.0, &y0, 1.0, &opts).unwrap();
        assert_eq!((s.stats.steps, s.stats.rejected_steps), (10, 0));
    }
}

/// `y' = −λ (y − cos t)`: stiff for large λ; the explicit methods are
/// driven to the edge of their stability regions.
struct StiffRelaxation {
    lambda: f64,
}

impl OdeSystem for StiffRelaxation {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        dy[0] = -self.lambda * (y[0] - t.cos());
        Ok(())
    }
}

#[test]
fn stiffness_is_detected_and_the_run_goes_on() {
    // With λ = 1e6 and loose tolerance the step settles at |hλ| near the
    // stability boundary (3.3 for DOPRI5, 6.8 for DOP853): the test, first
    // tried at accepted step 1000, fires 15 times with h·ρ above 3.25 / 6.1.
    for (method, bound) in [(Method::Dopri5, 3.25), (Method::Dop853, 6.1)] {
        let opts = Options {
            rtol: 1e-3,
            atol: 1e-3,
            dense: false,
            ..Options::default()
        };
        let mut sys = StiffRelaxation { lambda: 1e6 };
        let s = solve(method, &mut sys, 0.0, &[0.0], 0.01, &opts).unwrap();
        let (t, h_rho) = s.stats.stiffness_detected.expect("stiffness detected");
        eprintln!(
            "{method:?}: stiff at t = {t:.3e}, h·ρ = {h_rho:.3} after {} steps",
            s.stats.steps
        );
        assert!(s.stats.steps > 1000);
        assert!(h_rho > bound && h_rho < 2.0 * bound, "h·ρ = {h_rho}");
        assert!(t > 0.0 && t < 0.01);
        assert_eq!(s.t_last, 0.01);
        assert!((s.y_last[0] - 0.01f64.cos()).abs() < 1e-3);
    }
}

#[test]
fn nonstiff_problem_is_not_flagged() {
    for method in ADAPTIVE {
        let k = Kepler { e: 0.5 };
        let s = adaptive(
            method,
            &mut Kepler { e: 0.5 },
            &k.y0(),
            20.0 * 2.0 * PI,
            1e-12,
        );
        assert!(s.stats.steps > 1000, "the test must have been tried");
        assert!(s.stats.stiffness_detected.is_none(), "{method:?}");
    }
}

#[test]
fn dense_output_evaluations_are_counted_apart() {
    // DOP853 with a fixed step of 0.1 on [0, 1]: 10 steps, f at t0, then per
    // step 11 stages + f at the new point; dense output adds the three
    // extra stages of every step whose polynomial is needed.
    let run = |dense: bool, output: Vec<f64>| {
        let opts = Options {
            fixed_step: Some(0.1),
            dense,
            output,
            ..Options::default()
        };
        solve(
            Method::Dop853,
            &mut Oscillator,
            0.0,
            &[1.0, 0.0],
            1.0,
            &opts,
        )
        .unwrap()
    };
    let s = run(true, vec![]);
    assert_eq!(s.stats.steps, 10);
    assert_eq!(s.stats.dense_rhs_evals, 30);
    assert_eq!(s.stats.rhs_evals, 1 + 12 * 10 + 30);
    let s = run(false, vec![]);
    assert_eq!(
        (s.stats.dense_rhs_evals, s.stats.rhs_evals),
        (0, 1 + 12 * 10)
    );
    // Without Options::dense only the steps holding an output time inside
    // them pay: 0.25 and 0.55 lie inside steps 3 and 6, 0.5 is a step point.
    let s = run(false, vec![0.25, 0.5, 0.55]);
    assert_eq!(
        (s.stats.dense_rhs_evals, s.stats.rhs_evals),
        (6, 1 + 12 * 10 + 6)
    );
    // The other methods' continuous extensions are free.
    for method in [Method::Rk4, Method::Dopri5, Method::Radau5] {
        let opts = Options {
            fixed_step: Some(0.1),
            ..Options::default()
        };
        let s = solve(method, &mut Oscillator, 0.0, &[1.0, 0.0], 1.0, &opts).unwrap();
        assert_eq!(s.stats.dense_rhs_evals, 0, "{method:?}");
    }
}

/// `y1' = −y1 + sin t` (smooth) and `y2' = cos(ω t)·ω·amp` (a fast
/// oscillation of amplitude `amp` if `fast`, else a copy of `y1'`), decoupled.
struct SmoothAndFast {
    fast: bool,
}

impl OdeSystem for SmoothAndFast {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        dy[0] = -y[0] + t.sin();
        dy[1] = if self.fast {
            0.01 * 200.0 * (200.0 * t).cos()
        } else {
            -y[1] + t.sin()
        };
        Ok(())
    }
}

#[test]
fn a_component_with_a_large_atol_is_ignored_by_step_control() {
    // Component 2 oscillates fast (ω = 200); with atol_2 = 1e10 it no longer
    // counts: the run takes the steps that a run with a smooth copy in its
    // place and the same tolerances takes (both ignore component 2), far
    // fewer than with a scalar atol, and component 1 is as accurate.
    // Measured (steps with atol_2 = 1e10 / smooth copy / scalar atol):
    // DOPRI5 41 / 41 / 1433, DOP853 10 / 10 / 637, Radau5 44 / 44 / 2741,
    // i.e. 35, 64 and 62 times fewer steps (bound 30); error of component 1
    // at t = 5: 2.5e-9, 2.3e-10, 2.7e-9 (bound: the tolerance 1e-8, 3.7
    // times the largest, as the global error of these runs is about tol).
    for method in [Method::Dopri5, Method::Dop853, Method::Radau5] {
        let opts = |atol_components| Options {
            rtol: 1e-8,
            atol: 1e-8,
            atol_components,
            dense: false,
            ..Options::default()
        };
        let ignore = Some(vec![1e-8, 1e10]);
        let y0 = [1.0, 1.0];
        let run = |fast, o: &Options| {
            solve(method, &mut SmoothAndFast { fast }, 0.0, &y0, 5.0, o).unwrap()
        };
        let ignored = run(true, &opts(ignore.clone()));
        let copy = run(false, &opts(ignore));
        let scalar = run(true, &opts(None));
        eprintln!(
            "{method:?}: steps {} (atol_2 = 1e10), {} (smooth copy), {} (scalar atol)",
            ignored.stats.steps, copy.stats.steps, scalar.stats.steps
        );
        assert_eq!(ignored.stats.steps, copy.stats.steps, "{method:?}");
        assert_eq!(ignored.stats.rejected_steps, copy.stats.rejected_steps);
        assert!(scalar.stats.steps > 30 * ignored.stats.steps, "{method:?}");
        assert!((ignored.y_last[0] - copy.y_last[0]).abs() < 1e-14);
        let exact = 0.5 * (5.0f64.sin() - 5.0f64.cos()) + 1.5 * (-5.0f64).exp();
        let err = (ignored.y_last[0] - exact).abs();
        eprintln!("{method:?}: error of component 1 {err:.2e}");
        assert!(err < 1e-8, "{method:?}: {err:e}");
    }
}
