//! Failures, budgets, guards and projections: every run that does not reach
//! `t_end` returns the error and the partial solution up to the error time.

mod common;

use std::f64::consts::{FRAC_PI_2, PI};

use common::{Kepler, Oscillator, dist, radau_ode_second_filterings};
use nonholo_integrate::{Failure, IntegrateError, Method, OdeSystem, Options, SystemError, solve};

/// Options for `method`: a fixed step `h` for RK4, tolerance `tol` otherwise.
fn opts_for(method: Method, h: f64, tol: f64) -> Options {
    Options {
        fixed_step: method.needs_fixed_step().then_some(h),
        rtol: tol,
        atol: tol,
        ..Options::default()
    }
}

/// Checks the invariants every failure shares and returns it.
fn failure(r: Result<nonholo_integrate::Solution, Failure>) -> Failure {
    let f = r.expect_err("the run must fail");
    let p = &f.partial;
    if let Some(t) = f.error.time() {
        assert_eq!(t, p.t_last, "error time is the last time reached: {f}");
        assert!(p.t.iter().all(|&tau| tau <= t));
    }
    assert_eq!(p.y.len(), p.t.len() * p.dim);
    assert_eq!(p.y_last.len(), p.dim);
    f
}

/// `y' = −1`, `y(0) = 1`; `f` is not defined for `y < 0` (reached at t = 1).
struct Domain;

impl OdeSystem for Domain {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        if y[0] < 0.0 {
            return Err(SystemError::new(format!("negative state {}", y[0])));
        }
        dy[0] = -1.0;
        Ok(())
    }
}

#[test]
fn rhs_failure_at_a_state_reports_its_time() {
    for method in Method::ALL {
        let mut opts = opts_for(method, 0.125, 1e-8);
        opts.output = vec![0.5, 0.9, 1.5];
        let f = failure(solve(method, &mut Domain, 0.0, &[1.0], 2.0, &opts));
        let IntegrateError::System { t, source } = &f.error else {
            panic!("{method:?}: expected a System error, got {f}");
        };
        assert!(source.message.starts_with("negative state"));
        if method == Method::Rk4 {
            // Exact steps land on t = 1 (y = 0); the next step's stage 2 fails.
            assert_eq!(*t, 1.0);
        } else {
            // Trial stages beyond y = 0 are rejected (h /= 4) until h is
            // below 16 ε t: the run ends next to the boundary.
            assert!((t - 1.0).abs() < 1e-10, "{method:?}: t = {t}");
            assert!(f.partial.stats.rejected_steps > 10);
        }
        assert_eq!(f.partial.t, [0.5, 0.9]);
        assert!((f.partial.row(1)[0] - 0.1).abs() < 1e-12);
    }
}

#[test]
fn rhs_failure_at_the_initial_state() {
    for method in Method::ALL {
        let opts = opts_for(method, 0.1, 1e-6);
        let f = failure(solve(method, &mut Domain, 0.0, &[-1.0], 1.0, &opts));
        assert!(
            matches!(f.error, IntegrateError::System { t: 0.0, .. }),
            "{f}"
        );
        assert_eq!(f.partial.stats.rhs_evals, 1);
        assert_eq!(f.partial.stats.steps, 0);
    }
}

/// The oscillator watched by `guard = y1 = cos t`.
struct Watched {
    guard_calls: usize,
}

impl OdeSystem for Watched {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        Oscillator.rhs(t, y, dy)
    }
    fn guard(&mut self, _t: f64, y: &[f64]) -> Option<f64> {
        self.guard_calls += 1;
        Some(y[0])
    }
    fn guard_reason(&mut self, t: f64, _y: &[f64]) -> String {
        format!("y1 reached zero at t = {t}")
    }
}

#[test]
fn guard_crossing_is_located_on_the_continuous_extension() {
    // cos t = 0 at π/2. The located time is accurate to the interpolation
    // error over |y1'| = 1: ~1e-12 at these settings, asserted to 1e-10.
    // RADAU5's continuous extension is its collocation polynomial of degree
    // 3 (order 3 inside the step, against 4 and 7 for DOPRI5 and DOP853): at
    // tol 1e-12 its error on the oscillator is up to 4.6e-10 between step
    // points (2.6e-12 at them), so states taken from it are asserted to 2e-9.
    for method in Method::ALL {
        let bound = if method == Method::Radau5 {
            2e-9
        } else {
            1e-10
        };
        for dense in [true, false] {
            // RK4's global error at π/2 is ~t h⁴/120 = 8e-12 for h = 0.005.
            let mut opts = opts_for(method, 0.005, 1e-12);
            opts.dense = dense;
            opts.output = vec![0.5, 1.0, 1.5, 2.0, 2.5];
            let mut sys = Watched { guard_calls: 0 };
            let f = failure(solve(method, &mut sys, 0.0, &[1.0, 0.0], 3.0, &opts));
            let IntegrateError::Stopped { t, reason } = &f.error else {
                panic!("{method:?}: expected Stopped, got {f}");
            };
            eprintln!(
                "{method:?} dense={dense}: root {t}, error {:.1e}",
                t - FRAC_PI_2
            );
            assert!((t - FRAC_PI_2).abs() < bound, "{method:?}: t = {t}");
            assert!(reason.starts_with("y1 reached zero"));
            let p = &f.partial;
            assert!(p.y_last[0] <= 0.0 && p.y_last[0].abs() < bound);
            assert!(
                (p.y_last[1] + 1.0).abs() < bound,
                "{method:?}: {:?}",
                p.y_last
            );
            // Samples up to the root only.
            assert_eq!(p.t, [0.5, 1.0, 1.5]);
            assert!(dist(p.row(2), &Oscillator::exact(1.5)) < 10.0 * bound);
            assert_eq!(p.dense.is_some(), dense);
            if let Some(d) = &p.dense {
                let (_, b) = d.span().unwrap();
                assert!(b >= *t, "the step containing the root is kept");
            }
        }
    }
}

#[test]
fn guard_nonpositive_at_t0_stops_at_once() {
    for method in Method::ALL {
        let mut opts = opts_for(method, 0.01, 1e-6);
        opts.output = vec![0.0, 1.0];
        let mut sys = Watched { guard_calls: 0 };
        let f = failure(solve(method, &mut sys, 0.0, &[0.0, 1.0], 3.0, &opts));
        assert!(
            matches!(f.error, IntegrateError::Stopped { t: 0.0, .. }),
            "{f}"
        );
        assert_eq!(f.partial.t, [0.0]);
        assert_eq!((f.partial.stats.steps, f.partial.stats.rhs_evals), (0, 0));
        assert_eq!(sys.guard_calls, 1);
    }
}

/// `y' = y²`, `y(0) = 1`: `y = 1/(1 − t)` blows up at t = 1.
struct BlowUp;

impl OdeSystem for BlowUp {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        dy[0] = y[0] * y[0];
        Ok(())
    }
}

#[test]
fn blow_up_ends_with_a_small_step_or_a_non_finite_state() {
    for method in [Method::Dopri5, Method::Dop853] {
        let opts = opts_for(method, 0.0, 1e-8);
        let f = failure(solve(method, &mut BlowUp, 0.0, &[1.0], 2.0, &opts));
        assert!(
            matches!(
                f.error,
                IntegrateError::StepSizeTooSmall { .. } | IntegrateError::NonFinite { .. }
            ),
            "{method:?}: {f}"
        );
        let t = f.error.time().unwrap();
        eprintln!("{method:?}: {f}");
        assert!((t - 1.0).abs() < 1e-3, "{method:?}: t = {t}");
    }
    // With a fixed step the numerical solution outlives the singularity a
    // little and then overflows.
    let opts = opts_for(Method::Rk4, 1e-3, 1e-6);
    let f = failure(solve(Method::Rk4, &mut BlowUp, 0.0, &[1.0], 2.0, &opts));
    eprintln!("Rk4: {f}");
    assert!(matches!(f.error, IntegrateError::NonFinite { .. }), "{f}");
    let t = f.error.time().unwrap();
    assert!(t > 0.99 && t < 1.1, "t = {t}");
}

#[test]
fn step_budget() {
    let k = Kepler { e: 0.5 };
    for method in Method::ALL {
        let mut opts = opts_for(method, 0.01, 1e-10);
        opts.max_steps = 10;
        if opts.fixed_step.is_some() {
            // 629 fixed steps cannot fit in 10: refused before the first step.
            let f = failure(solve(
                method,
                &mut Kepler { e: 0.5 },
                0.0,
                &k.y0(),
                2.0 * PI,
                &opts,
            ));
            assert!(
                matches!(&f.error, IntegrateError::InvalidInput(m) if m.contains("max_steps = 10")),
                "{f}"
            );
            assert_eq!(f.partial.stats.steps, 0);
            continue;
        }
        let f = failure(solve(
            method,
            &mut Kepler { e: 0.5 },
            0.0,
            &k.y0(),
            2.0 * PI,
            &opts,
        ));
        assert!(
            matches!(f.error, IntegrateError::TooManySteps { max_steps: 10, .. }),
            "{f}"
        );
        let st = &f.partial.stats;
        assert_eq!(st.steps + st.rejected_steps, 10);
        assert_eq!(f.partial.dense.as_ref().unwrap().len(), st.steps);
        assert!(dist(&f.partial.y_last, &k.exact(f.partial.t_last)) < 1e-6);
    }
}

#[test]
fn wall_time_budget() {
    for method in Method::ALL {
        let mut opts = opts_for(method, 0.01, 1e-6);
        opts.max_wall_time_s = Some(0.0);
        let f = failure(solve(method, &mut Oscillator, 0.0, &[1.0, 0.0], 1.0, &opts));
        assert!(
            matches!(f.error, IntegrateError::TimeBudgetExceeded { t: 0.0, seconds, .. } if seconds == 0.0),
            "{f}"
        );
        assert!(f.partial.stats.wall_time_s > 0.0);
    }
}

/// Rotation on the unit circle, projected back onto it after every step.
struct Circle {
    project: bool,
    calls: usize,
}

impl OdeSystem for Circle {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        dy[0] = -y[1];
        dy[1] = y[0];
        Ok(())
    }
    fn after_step(&mut self, _t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        self.calls += 1;
        if !self.project {
            return Ok(false);
        }
        let r = y[0].hypot(y[1]);
        y[0] /= r;
        y[1] /= r;
        Ok(true)
    }
}

#[test]
fn after_step_projection_is_applied_and_counted() {
    for method in Method::ALL {
        let opts = opts_for(method, 0.1, 1e-5);
        let run = |project| {
            let mut sys = Circle { project, calls: 0 };
            let s = solve(method, &mut sys, 0.0, &[1.0, 0.0], 50.0, &opts).unwrap();
            assert_eq!(sys.calls, s.stats.steps);
            s
        };
        let (free, projected) = (run(false), run(true));
        let radius = |y: &[f64]| y[0].hypot(y[1]);
        assert!(
            (radius(&free.y_last) - 1.0).abs() > 1e-9,
            "{method:?}: drift expected"
        );
        assert!((radius(&projected.y_last) - 1.0).abs() < 4.0 * f64::EPSILON);
        // One extra evaluation of f per projected step (the FSAL value is stale).
        let st = &projected.stats;
        let st_free = &free.stats;
        if method == Method::Rk4 {
            assert_eq!(st.rhs_evals, st_free.rhs_evals + st.steps);
        } else if method == Method::Radau5 {
            // RADAU5 evaluates f at every accepted state anyway (for its
            // error estimate), after the projection: the projection costs
            // nothing. Both runs meet the documented count, which has no
            // term for a projection (n = 2 f per finite-difference
            // Jacobian); an extra f per projected step would exceed its
            // slack of 1 + rejected steps for the second filterings
            // (measured: 153 steps, none rejected, no second filtering, in
            // both runs).
            let (sp, sf) = (
                radau_ode_second_filterings(st, 2),
                radau_ode_second_filterings(st_free, 2),
            );
            eprintln!(
                "Radau5 circle: {} steps, {} rejected, {sp} second filterings \
                 (free run: {} steps, {} rejected, {sf})",
                st.steps, st.rejected_steps, st_free.steps, st_free.rejected_steps
            );
        } else {
            let per_trial = if method == Method::Dopri5 { 6 } else { 11 };
            let per_accept = if method == Method::Dopri5 { 1 } else { 5 };
            let trials = st.steps + st.rejected_steps;
            assert_eq!(st.rhs_evals, 2 + per_trial * trials + per_accept * st.steps);
        }
    }
}

/// `after_step` that refuses a state.
struct Refuses;

impl OdeSystem for Refuses {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        Oscillator.rhs(t, y, dy)
    }
    fn after_step(&mut self, t: f64, _y: &mut [f64]) -> Result<bool, SystemError> {
        if t > 1.0 {
            Err(SystemError::new("constraint violated"))
        } else {
            Ok(false)
        }
    }
}

#[test]
fn after_step_error_ends_the_run() {
    for method in Method::ALL {
        let mut opts = opts_for(method, 0.3, 1e-6);
        opts.output = vec![0.5, 1.0, 1.05, 3.0];
        let f = failure(solve(method, &mut Refuses, 0.0, &[1.0, 0.0], 3.0, &opts));
        let IntegrateError::System { t, source } = &f.error else {
            panic!("{f}");
        };
        assert!(*t > 1.0 && source.message == "constraint violated");
        assert_eq!(f.partial.dense.as_ref().unwrap().span().unwrap().1, *t);
        // Samples up to the failure time, from the step polynomial.
        let n = f.partial.t.len();
        assert!(n >= 2 && f.partial.t[..2] == [0.5, 1.0]);
        assert!(f.partial.t.iter().all(|&tau| tau <= *t));
    }
}

/// `f` turns NaN for t > 0.5.
struct GoesNan;

impl OdeSystem for GoesNan {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, t: f64, _y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        dy[0] = if t > 0.5 { f64::NAN } else { 1.0 };
        Ok(())
    }
}

#[test]
fn non_finite_values() {
    // Fixed step: fatal at once.
    for method in Method::ALL {
        let opts = Options {
            fixed_step: Some(0.125),
            ..Options::default()
        };
        let f = failure(solve(method, &mut GoesNan, 0.0, &[0.0], 1.0, &opts));
        assert!(
            matches!(f.error, IntegrateError::NonFinite { t: 0.5 }),
            "{method:?}: {f}"
        );
        assert!((f.partial.y_last[0] - 0.5).abs() < 1e-15);
    }
    // Adaptive: non-finite trial steps are rejected until h is too small;
    // the collapse is driven by NaN, so it is reported as NonFinite.
    for method in [Method::Dopri5, Method::Dop853, Method::Radau5] {
        let opts = opts_for(method, 0.0, 1e-8);
        let f = failure(solve(method, &mut GoesNan, 0.0, &[0.0], 1.0, &opts));
        eprintln!("{method:?}: {f}");
        assert!(
            matches!(f.error, IntegrateError::NonFinite { t } if (t - 0.5).abs() < 1e-12),
            "{method:?}: {f}"
        );
    }
}

#[test]
fn invalid_input_is_rejected_before_any_evaluation() {
    let ok = Options::default();
    let y0 = [1.0, 0.0];
    let bad: Vec<(Method, Options, &[f64], f64)> = vec![
        (Method::Rk4, ok.clone(), &y0, 1.0), // RK4 without fixed step
        (
            Method::Dopri5,
            Options {
                fixed_step: Some(-0.1),
                ..ok.clone()
            },
            &y0,
            1.0,
        ),
        (
            Method::Dopri5,
            Options {
                rtol: 0.0,
                ..ok.clone()
            },
            &y0,
            1.0,
        ),
        (
            Method::Dopri5,
            Options {
                atol: f64::NAN,
                ..ok.clone()
            },
            &y0,
            1.0,
        ),
        (
            Method::Dopri5,
            Options {
                h_init: Some(0.0),
                ..ok.clone()
            },
            &y0,
            1.0,
        ),
        (
            Method::Dop853,
            Options {
                h_max: Some(f64::INFINITY),
                ..ok.clone()
            },
            &y0,
            1.0,
        ),
        (
            Method::Dop853,
            Options {
                output: vec![0.5, 0.2],
                ..ok.clone()
            },
            &y0,
            1.0,
        ),
        (
            Method::Dop853,
            Options {
                output: vec![0.5, 0.5],
                ..ok.clone()
            },
            &y0,
            1.0,
        ),
        (
            Method::Dop853,
            Options {
                output: vec![1.5],
                ..ok.clone()
            },
            &y0,
            1.0,
        ),
        (
            Method::Dop853,
            Options {
                output: vec![-0.1],
                ..ok.clone()
            },
            &y0,
            1.0,
        ),
        (
            Method::Dopri5,
            Options {
                max_wall_time_s: Some(-1.0),
                ..ok.clone()
            },
            &y0,
            1.0,
        ),
        (Method::Dopri5, ok.clone(), &[1.0], 1.0), // wrong length
        (Method::Dopri5, ok.clone(), &[f64::INFINITY, 0.0], 1.0), // not finite
        (Method::Dopri5, ok.clone(), &y0, -1.0),   // backward
        (Method::Dopri5, ok.clone(), &y0, f64::NAN),
    ];
    for (method, opts, y0, t_end) in bad {
        let f = solve(method, &mut Oscillator, 0.0, y0, t_end, &opts).unwrap_err();
        assert!(matches!(f.error, IntegrateError::InvalidInput(_)), "{f}");
        assert_eq!(f.error.time(), None);
        assert_eq!(f.partial.stats.rhs_evals, 0);
        assert!(f.partial.t.is_empty());
    }
}

#[test]
fn empty_span_returns_the_initial_state() {
    for method in Method::ALL {
        let mut opts = opts_for(method, 0.1, 1e-6);
        opts.output = vec![2.0];
        let s = solve(method, &mut Oscillator, 2.0, &[1.0, 0.0], 2.0, &opts).unwrap();
        assert_eq!(
            (s.t.as_slice(), s.y_last.as_slice()),
            (&[2.0][..], &[1.0, 0.0][..])
        );
        assert_eq!(s.stats.rhs_evals, 0);
    }
}

// ---------------------------------------------------------------------------
// Step-size floor, overflow, tolerances, the order of after_step and guard.

/// `y' = 1/(1 + t)²`, `y(0) = 0`: `y = t/(1 + t) → 1`.
struct Saturating;

impl OdeSystem for Saturating {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, t: f64, _y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        dy[0] = 1.0 / ((1.0 + t) * (1.0 + t));
        Ok(())
    }
}

/// `f` is defined at `t0 = 0` only: every trial step fails.
struct OnlyAtStart;

impl OdeSystem for OnlyAtStart {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, t: f64, _y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        if t > 0.0 {
            return Err(SystemError::new("undefined for t > 0"));
        }
        dy[0] = 1.0;
        Ok(())
    }
}

#[test]
fn step_floor_is_sane_for_any_span() {
    // With the old floor 16ε·max(|t|, 1e-6·span), t_end = 1e300 put the
    // floor at 3.6e279 and every run failed at t = 0. Now the absolute
    // floor is 16ε·min(1e-6·span, h_first): the runs reach 1e300 (the step
    // grows by the controller's largest factor once the solution has
    // settled). Measured: DOPRI5 368 steps, DOP853 380, Radau5 391.
    let adaptive = [Method::Dopri5, Method::Dop853, Method::Radau5];
    for method in adaptive {
        let opts = Options {
            rtol: 1e-8,
            atol: 1e-8,
            dense: false,
            ..Options::default()
        };
        let s = solve(method, &mut Saturating, 0.0, &[0.0], 1e300, &opts)
            .unwrap_or_else(|f| panic!("{method:?}: {f}"));
        eprintln!(
            "{method:?} to t = 1e300: {} steps, y = {}",
            s.stats.steps, s.y_last[0]
        );
        assert_eq!(s.t_last, 1e300);
        assert!(
            (s.y_last[0] - 1.0).abs() < 1e-6,
            "{method:?}: {}",
            s.y_last[0]
        );
        assert!(s.stats.steps < 2000);
    }
    // Shrinking near t = 0 ends: every trial step fails, each failure
    // divides h by 4 (explicit) or 2 (Radau5) until it is below the floor,
    // at most 16ε ≈ 3.6e-15 of the first step: ~24 and ~48 rejections,
    // whatever the span.
    for method in adaptive {
        for t_end in [1.0, 1e300] {
            let opts = opts_for(method, 0.0, 1e-6);
            let f = failure(solve(method, &mut OnlyAtStart, 0.0, &[0.0], t_end, &opts));
            let st = &f.partial.stats;
            eprintln!(
                "{method:?}, t_end = {t_end:e}: {f} after {} rejections",
                st.rejected_steps
            );
            assert!(
                matches!(f.error, IntegrateError::System { t: 0.0, .. }),
                "{method:?}: {f}"
            );
            assert!(st.rejected_steps >= 20 && st.rejected_steps <= 60, "{st:?}");
        }
    }
}

/// A falling body `x' = v`, `v' = −g` with an enormous `g`.
struct Falling {
    g: f64,
}

impl OdeSystem for Falling {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        dy[0] = y[1];
        dy[1] = -self.g;
        Ok(())
    }
}

/// `y' = 1/y`: not finite at `y = 0`.
struct Reciprocal;

impl OdeSystem for Reciprocal {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        dy[0] = 1.0 / y[0];
        Ok(())
    }
}

#[test]
fn overflow_is_reported_as_non_finite() {
    // f(t0, y0) not finite: invalid initial data, named as such.
    for method in Method::ALL {
        let opts = opts_for(method, 0.1, 1e-6);
        let f = solve(method, &mut Reciprocal, 0.0, &[0.0], 1.0, &opts).unwrap_err();
        let IntegrateError::InvalidInput(msg) = &f.error else {
            panic!("{method:?}: {f}");
        };
        assert!(msg.contains("f(t0, y0) is not finite"), "{msg}");
        assert_eq!(f.partial.stats.rhs_evals, 1);
    }
    // g = 1e307 from x0 = 1: f(t0, y0) is finite, but HINIT's weighted
    // norm |f/sk| overflows and its first step comes out as 0 (formerly
    // "step size 0e0 too small"): NonFinite at t0.
    for method in [Method::Dopri5, Method::Dop853, Method::Radau5] {
        let opts = opts_for(method, 0.0, 1e-6);
        let mut sys = Falling { g: 1e307 };
        let f = failure(solve(method, &mut sys, 0.0, &[1.0, 0.0], 10.0, &opts));
        eprintln!("{method:?}, g = 1e307, HINIT: {f}");
        assert!(
            matches!(f.error, IntegrateError::NonFinite { t: 0.0 }),
            "{method:?}: {f}"
        );
        assert_eq!(f.partial.stats.steps + f.partial.stats.rejected_steps, 0);
    }
    // With a given first step the run goes on until the squared, weighted
    // error norms or the state x = −g t²/2 overflow: from then on every
    // trial step is rejected for a non-finite error estimate or state
    // until h is below the floor, and the run ends with NonFinite, not with
    // StepSizeTooSmall. Measured: DOPRI5 at t = 3.33 (5 steps, 25
    // rejected), DOP853 at t = 0 (its error norm overflows at once: the
    // rounding of Σ er_j k_j with |k_j| = 1e307, divided by sk = 1e-6 and
    // squared; 28 rejections), Radau5 at t = 0 (its Newton norm overflows;
    // 55 rejections, h halved each time).
    for method in [Method::Dopri5, Method::Dop853, Method::Radau5] {
        let opts = Options {
            h_init: Some(1e-3),
            ..opts_for(method, 0.0, 1e-6)
        };
        let mut sys = Falling { g: 1e307 };
        let f = failure(solve(method, &mut sys, 0.0, &[1.0, 0.0], 10.0, &opts));
        eprintln!(
            "{method:?}, g = 1e307, h_init = 1e-3: {f} ({} steps, {} rejected)",
            f.partial.stats.steps, f.partial.stats.rejected_steps
        );
        let IntegrateError::NonFinite { t } = f.error else {
            panic!("{method:?}: {f}");
        };
        assert!(t < 10.0, "{method:?}: t = {t}");
        assert!(f.partial.y_last.iter().all(|v| v.is_finite()));
    }
}

#[test]
fn tolerances_are_validated() {
    let y0 = [1.0, 0.0];
    let base = Options::default();
    let bad = [
        Options {
            rtol: 1e-14,
            atol: 1e-14,
            ..base.clone()
        },
        Options {
            atol: 0.0,
            ..base.clone()
        },
        Options {
            atol: f64::INFINITY,
            ..base.clone()
        },
        Options {
            atol_components: Some(vec![1e-6]),
            ..base.clone()
        },
        Options {
            atol_components: Some(vec![1e-6, 0.0]),
            ..base.clone()
        },
        Options {
            atol_components: Some(vec![f64::NAN, 1e-6]),
            ..base.clone()
        },
    ];
    for method in Method::ALL {
        for opts in &bad {
            let opts = Options {
                fixed_step: method.needs_fixed_step().then_some(0.1),
                ..opts.clone()
            };
            let f = solve(method, &mut Oscillator, 0.0, &y0, 1.0, &opts).unwrap_err();
            let IntegrateError::InvalidInput(msg) = &f.error else {
                panic!("{method:?}: {f}");
            };
            if opts.rtol < 1e-13 {
                assert!(msg.contains("double precision"), "{msg}");
            }
            assert_eq!(f.partial.stats.rhs_evals, 0);
        }
        // 100ε itself is accepted.
        let opts = Options {
            rtol: 100.0 * f64::EPSILON,
            atol: 1e-14,
            fixed_step: method.needs_fixed_step().then_some(0.01),
            ..base.clone()
        };
        let s = solve(method, &mut Oscillator, 0.0, &y0, 0.5, &opts).unwrap();
        assert!(dist(&s.y_last, &Oscillator::exact(0.5)) < 1e-8);
    }
}

/// Records the calls of `after_step` and `guard`.
#[derive(Default)]
struct CallLog {
    calls: Vec<(&'static str, f64)>,
}

impl CallLog {
    /// Checks `guard(t0)`, then per accepted step `after_step(t)`, `guard(t)`.
    fn check(&self, t0: f64, steps: usize, what: &str) {
        assert_eq!(self.calls.first(), Some(&("guard", t0)), "{what}");
        let rest = &self.calls[1..];
        assert_eq!(rest.len(), 2 * steps, "{what}: {:?}", self.calls);
        let mut t_prev = t0;
        for pair in rest.chunks(2) {
            let [(a, ta), (g, tg)] = [pair[0], pair[1]];
            assert_eq!((a, g), ("after_step", "guard"), "{what}: {:?}", self.calls);
            assert!(ta == tg && ta > t_prev, "{what}: {pair:?}");
            t_prev = ta;
        }
    }
}

impl OdeSystem for CallLog {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        Oscillator.rhs(t, y, dy)
    }
    fn after_step(&mut self, t: f64, _y: &mut [f64]) -> Result<bool, SystemError> {
        self.calls.push(("after_step", t));
        Ok(false)
    }
    fn guard(&mut self, t: f64, _y: &[f64]) -> Option<f64> {
        self.calls.push(("guard", t));
        Some(1.0)
    }
}

impl nonholo_integrate::ImplicitSystem for CallLog {
    fn dim(&self) -> usize {
        2
    }
    fn residual(
        &mut self,
        _t: f64,
        y: &[f64],
        yp: &[f64],
        res: &mut [f64],
    ) -> Result<(), SystemError> {
        res[0] = yp[0] - y[1];
        res[1] = yp[1] + y[0];
        Ok(())
    }
    fn jacobians(
        &mut self,
        _t: f64,
        _y: &[f64],
        _yp: &[f64],
        jy: &mut [f64],
        jyp: &mut [f64],
    ) -> Result<(), SystemError> {
        jy.copy_from_slice(&[0.0, -1.0, 1.0, 0.0]);
        jyp.copy_from_slice(&[1.0, 0.0, 0.0, 1.0]);
        Ok(())
    }
    fn after_step(&mut self, t: f64, _y: &mut [f64]) -> Result<bool, SystemError> {
        self.calls.push(("after_step", t));
        Ok(false)
    }
    fn guard(&mut self, t: f64, _y: &[f64]) -> Option<f64> {
        self.calls.push(("guard", t));
        Some(1.0)
    }
}

#[test]
fn after_step_comes_before_guard_in_every_step() {
    // The documented contract (OdeSystem::after_step, ::guard and their
    // ImplicitSystem counterparts): guard(t0); then, per accepted step,
    // after_step(t) and then guard(t) at the same t; nothing for rejected
    // steps.
    for method in Method::ALL {
        let opts = opts_for(method, 0.1, 1e-6);
        let mut log = CallLog::default();
        let s = solve(method, &mut log, 0.0, &[1.0, 0.0], 2.0, &opts).unwrap();
        log.check(0.0, s.stats.steps, &format!("{method:?}"));
    }
    let mut log = CallLog::default();
    let opts = Options {
        rtol: 1e-6,
        atol: 1e-6,
        ..Options::default()
    };
    let s = nonholo_integrate::solve_implicit(&mut log, 0.0, &[1.0, 0.0], &[0.0, -1.0], 2.0, &opts)
        .unwrap();
    log.check(0.0, s.stats.steps, "implicit Radau5");
}
