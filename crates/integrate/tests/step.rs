//! The step API: the solver states driven by hand, the reasons `step()`
//! returns (accepted step, end, guard stop with its time, budgets,
//! failures), `solve` as the loop over `step()`, the contract of
//! `guard_reason`, and steps that allocate nothing.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use common::Oscillator;
use nonholo_integrate::{
    Failure, ImplicitSystem, IntegrateError, Method, OdeSystem, Options, Solution, Solver, Stats,
    StopReason, SystemError, solve, solve_implicit,
};

/// The oscillator `y1' = y2, y2' = −y1` as `F(t, y, y') = y' − f(y) = 0`.
struct ImplicitOscillator;

impl ImplicitSystem for ImplicitOscillator {
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
}

/// One call the integrator made to [`Watched`].
#[derive(Debug, Clone, PartialEq)]
enum Call {
    Rhs,
    AfterStep,
    Guard { t: f64, y: Vec<f64>, g: f64 },
}

/// The oscillator with the guard `y1 − level` (`cos t = level`; its cube
/// root with `cbrt`), or `t_stop − t`, logging every call; its
/// `guard_reason` checks the contract of [`OdeSystem::guard_reason`]
/// against the log.
struct Watched {
    level: f64,
    cbrt: bool,
    t_stop: Option<f64>,
    log: Vec<Call>,
    reasons: usize,
    /// Positive guard evaluations between the stopping one and `guard_reason`.
    positive_after: usize,
}

impl Watched {
    fn new(level: f64) -> Self {
        Watched {
            level,
            cbrt: false,
            t_stop: None,
            log: Vec::new(),
            reasons: 0,
            positive_after: 0,
        }
    }

    fn guard_value(&mut self, t: f64, y: &[f64]) -> f64 {
        let g = match self.t_stop {
            Some(ts) => ts - t,
            None if self.cbrt => (y[0] - self.level).cbrt(),
            None => y[0] - self.level,
        };
        self.log.push(Call::Guard {
            t,
            y: y.to_vec(),
            g,
        });
        g
    }

    /// Bitwise the state of the last guard evaluation that was not
    /// positive, and only positive guard evaluations since.
    fn check_contract(&mut self, t: f64, y: &[f64]) -> String {
        self.reasons += 1;
        let k = self
            .log
            .iter()
            .rposition(|c| matches!(c, Call::Guard { g, .. } if g.is_nan() || *g <= 0.0))
            .expect("a non-positive guard evaluation before guard_reason");
        let Call::Guard { t: tg, y: yg, .. } = &self.log[k] else {
            unreachable!()
        };
        assert_eq!(tg.to_bits(), t.to_bits(), "guard_reason at another time");
        assert!(
            yg.iter().zip(y).all(|(a, b)| a.to_bits() == b.to_bits()),
            "guard_reason at another state: {yg:?} vs {y:?}"
        );
        self.positive_after = self.log.len() - k - 1;
        for c in &self.log[k + 1..] {
            assert!(
                matches!(c, Call::Guard { g, .. } if *g > 0.0),
                "{c:?} between the stopping guard evaluation and guard_reason"
            );
        }
        format!("y1 reached {} at t = {t}", self.level)
    }
}

impl OdeSystem for Watched {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        self.log.push(Call::Rhs);
        Oscillator.rhs(t, y, dy)
    }
    fn after_step(&mut self, _t: f64, _y: &mut [f64]) -> Result<bool, SystemError> {
        self.log.push(Call::AfterStep);
        Ok(false)
    }
    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        Some(self.guard_value(t, y))
    }
    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        self.check_contract(t, y)
    }
}

impl ImplicitSystem for Watched {
    fn dim(&self) -> usize {
        2
    }
    fn residual(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        res: &mut [f64],
    ) -> Result<(), SystemError> {
        self.log.push(Call::Rhs);
        ImplicitOscillator.residual(t, y, yp, res)
    }
    fn jacobians(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        jy: &mut [f64],
        jyp: &mut [f64],
    ) -> Result<(), SystemError> {
        ImplicitOscillator.jacobians(t, y, yp, jy, jyp)
    }
    fn after_step(&mut self, _t: f64, _y: &mut [f64]) -> Result<bool, SystemError> {
        self.log.push(Call::AfterStep);
        Ok(false)
    }
    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        Some(self.guard_value(t, y))
    }
    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        self.check_contract(t, y)
    }
}

/// What a hand-driven run saw: every reason `step()` returned (the last
/// one terminal) and the result `solve` would give.
struct Driven {
    reasons: Vec<StopReason>,
    result: Result<Solution, Failure>,
}

/// Drives `s` by hand to a terminal reason, checking on the way that the
/// accepted times increase, that `t()` follows them and that `stats()`
/// counts the steps; then checks that the terminal reason repeats.
fn drive(mut s: Solver<'_>) -> Driven {
    let mut reasons = Vec::new();
    let mut t_prev = s.t();
    loop {
        let reason = s.step();
        reasons.push(reason.clone());
        if let StopReason::Accepted { t } = reason {
            assert!(t > t_prev, "accepted times increase: {t_prev} then {t}");
            assert_eq!(s.t(), t);
            assert_eq!(s.stats().steps, reasons.len());
            t_prev = t;
            continue;
        }
        // Terminal: it stays so, and the solver stays where it stopped.
        let (t, y) = (s.t(), s.y().to_vec());
        assert_eq!(s.step(), reason);
        assert_eq!((s.t(), s.y()), (t, &y[..]));
        let error = match reason {
            StopReason::Accepted { .. } => unreachable!(),
            StopReason::End { t: te } => {
                assert_eq!(te, t);
                None
            }
            StopReason::Guard { t: tg, reason } => {
                assert_eq!(tg, t);
                Some(IntegrateError::Stopped { t: tg, reason })
            }
            StopReason::Budget(e) | StopReason::Failed(e) => Some(e),
        };
        let partial = s.into_solution();
        assert_eq!(partial.t_last, t);
        let result = match error {
            None => Ok(partial),
            Some(error) => Err(Failure { error, partial }),
        };
        return Driven { reasons, result };
    }
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Bitwise the same samples, continuous extension, last state and counters
/// (wall time aside), and the same error.
fn assert_same(a: &Result<Solution, Failure>, b: &Result<Solution, Failure>) {
    let (sa, sb) = match (a, b) {
        (Ok(sa), Ok(sb)) => (sa, sb),
        (Err(fa), Err(fb)) => {
            assert_eq!(fa.error, fb.error);
            (&fa.partial, &fb.partial)
        }
        _ => panic!("one run failed, the other did not: {a:?} vs {b:?}"),
    };
    assert_eq!(bits(&sa.t), bits(&sb.t));
    assert_eq!(bits(&sa.y), bits(&sb.y));
    assert_eq!(sa.t_last.to_bits(), sb.t_last.to_bits());
    assert_eq!(bits(&sa.y_last), bits(&sb.y_last));
    assert_eq!(sa.dense, sb.dense);
    let (mut ta, mut tb) = (sa.stats.clone(), sb.stats.clone());
    (ta.wall_time_s, tb.wall_time_s) = (0.0, 0.0);
    assert_eq!(ta, tb);
}

/// `opts` with the step RK4 needs.
fn for_method(method: Method, opts: &Options) -> Options {
    Options {
        fixed_step: method.needs_fixed_step().then_some(0.01),
        ..opts.clone()
    }
}

/// `solve` and the loop over `step()` on the oscillator, by method.
fn ode_both(method: Method, t_end: f64, opts: &Options) -> (Result<Solution, Failure>, Driven) {
    let opts = for_method(method, opts);
    let y0 = [1.0, 0.0];
    let solved = solve(method, &mut Oscillator, 0.0, &y0, t_end, &opts);
    let mut sys = Oscillator;
    // Input refused by the constructor: no step, the same failure.
    let driven = match Solver::new(method, &mut sys, 0.0, &y0, t_end, &opts) {
        Ok(s) => drive(s),
        Err(f) => Driven {
            reasons: Vec::new(),
            result: Err(f),
        },
    };
    (solved, driven)
}

#[test]
fn step_returns_accepted_steps_then_end() {
    let opts = Options {
        output: vec![0.5, 1.0, 2.5],
        ..Options::default()
    };
    for method in Method::ALL {
        let (_, d) = ode_both(method, 3.0, &opts);
        let (last, accepted) = d.reasons.split_last().unwrap();
        assert!(accepted.len() > 1, "{method:?}");
        assert!(
            accepted
                .iter()
                .all(|r| matches!(r, StopReason::Accepted { t } if *t < 3.0)),
            "{method:?}: {accepted:?}"
        );
        assert_eq!(*last, StopReason::End { t: 3.0 }, "{method:?}");
        let s = d.result.unwrap();
        assert_eq!(s.t, [0.5, 1.0, 2.5, 3.0]);
        assert_eq!(s.stats.steps, accepted.len() + 1);
    }
    // t_end = t0 ends at once.
    let mut sys = Oscillator;
    let refused = Solver::new(Method::Dopri5, &mut sys, 1.0, &[1.0, 0.0], 1.0, &opts).is_err();
    assert!(refused, "output times outside [t0, t_end] are refused");
    let o = Options::default();
    let mut s = Solver::new(Method::Dopri5, &mut sys, 1.0, &[1.0, 0.0], 1.0, &o).unwrap();
    assert_eq!(s.step(), StopReason::End { t: 1.0 });
    assert_eq!(s.stats().rhs_evals, 0);
    drop(s);
    // Before the first step: the initial state, nothing counted.
    let s = Solver::new(Method::Dop853, &mut sys, 0.0, &[1.0, 0.0], 1.0, &o).unwrap();
    assert_eq!((s.t(), s.y()), (0.0, &[1.0, 0.0][..]));
    let st = s.stats();
    assert_eq!(
        st,
        Stats {
            wall_time_s: st.wall_time_s,
            ..Stats::default()
        }
    );
}

#[test]
fn solve_is_the_loop_over_step() {
    let plain = Options {
        rtol: 1e-8,
        atol: 1e-8,
        output: vec![0.25, 1.0, 4.0],
        ..Options::default()
    };
    let hit = Options {
        hit_output: true,
        dense: false,
        ..plain.clone()
    };
    let budget = Options {
        max_steps: 7,
        ..plain.clone()
    };
    for opts in [&plain, &hit, &budget] {
        for method in Method::ALL {
            let (solved, driven) = ode_both(method, 5.0, opts);
            assert_same(&solved, &driven.result);
        }
        let y0 = [1.0, 0.0];
        let yp0 = [0.0, -1.0];
        let solved = solve_implicit(&mut ImplicitOscillator, 0.0, &y0, &yp0, 5.0, opts);
        let mut sys = ImplicitOscillator;
        let s = Solver::implicit(&mut sys, 0.0, &y0, &yp0, 5.0, opts).unwrap();
        assert_same(&solved, &drive(s).result);
    }
    // With a guard stop, too.
    for method in Method::ALL {
        let opts = for_method(method, &plain);
        let y0 = [1.0, 0.0];
        let solved = solve(method, &mut Watched::new(0.3), 0.0, &y0, 5.0, &opts);
        let mut sys = Watched::new(0.3);
        let driven = drive(Solver::new(method, &mut sys, 0.0, &y0, 5.0, &opts).unwrap());
        assert!(matches!(
            solved,
            Err(Failure {
                error: IntegrateError::Stopped { .. },
                ..
            })
        ));
        assert_same(&solved, &driven.result);
    }
}

#[test]
fn guard_stop_is_a_reason_with_the_located_time() {
    // y1 = cos t reaches 0.3 at t = acos(0.3).
    let t_star = 0.3f64.acos();
    let y0 = [1.0, 0.0];
    for method in Method::ALL {
        let opts = for_method(
            method,
            &Options {
                rtol: 1e-10,
                atol: 1e-10,
                ..Options::default()
            },
        );
        let mut sys = Watched::new(0.3);
        let d = drive(Solver::new(method, &mut sys, 0.0, &y0, 5.0, &opts).unwrap());
        let Some(StopReason::Guard { t, reason }) = d.reasons.last() else {
            panic!("{method:?}: {:?}", d.reasons.last());
        };
        assert!((t - t_star).abs() < 1e-8, "{method:?}: {t} vs {t_star}");
        assert_eq!(*reason, format!("y1 reached 0.3 at t = {t}"));
        assert_eq!(sys.reasons, 1);
        let f = d.result.unwrap_err();
        assert!((f.partial.y_last[0] - 0.3).abs() < 1e-7, "{method:?}");
    }
    // A guard <= 0 at t0 stops the first step() at t0, before any evaluation of f.
    let mut sys = Watched::new(1.0);
    let mut s = Solver::new(Method::Dopri5, &mut sys, 0.0, &y0, 5.0, &Options::default()).unwrap();
    assert_eq!(
        s.step(),
        StopReason::Guard {
            t: 0.0,
            reason: "y1 reached 1 at t = 0".into()
        }
    );
    assert_eq!(s.stats().rhs_evals, 0);
}

#[test]
fn guard_reason_is_asked_at_the_stopping_guard_evaluation() {
    let y0 = [1.0, 0.0];
    let yp0 = [0.0, -1.0];
    // Crossings inside a step, located by the Illinois iteration (with the
    // cube root of the guard its last evaluations may lie on the positive
    // side), and a guard zero at t0 (level 1 = y1(0)).
    let mut positive_after = 0;
    for cbrt in [false, true] {
        for level in [0.3, 0.0, -0.7, 0.999, 1.0] {
            let watched = || Watched {
                cbrt,
                ..Watched::new(level)
            };
            for method in Method::ALL {
                let opts = for_method(method, &Options::default());
                let mut sys = watched();
                let f = solve(method, &mut sys, 0.0, &y0, 5.0, &opts).unwrap_err();
                assert!(matches!(f.error, IntegrateError::Stopped { .. }), "{f}");
                assert_eq!(sys.reasons, 1, "{method:?}, level {level}");
                positive_after += sys.positive_after;
            }
            let mut sys = watched();
            let opts = Options::default();
            let f = solve_implicit(&mut sys, 0.0, &y0, &yp0, 5.0, &opts).unwrap_err();
            assert!(matches!(f.error, IntegrateError::Stopped { .. }), "{f}");
            assert_eq!(sys.reasons, 1, "implicit, level {level}");
            positive_after += sys.positive_after;
        }
    }
    assert!(positive_after > 0, "no location ended on the positive side");
    // A guard exactly zero at the end of a fixed step (the grid time
    // t0 + 5 h): the stop is the step end itself.
    let h = 0.01;
    for method in Method::ALL {
        let opts = Options {
            fixed_step: Some(h),
            ..Options::default()
        };
        let mut sys = Watched::new(0.0);
        sys.t_stop = Some(0.0 + 5.0 * h);
        let f = solve(method, &mut sys, 0.0, &y0, 1.0, &opts).unwrap_err();
        assert_eq!(f.error.time(), Some(0.0 + 5.0 * h), "{method:?}");
        assert_eq!(f.partial.stats.steps, 5);
        assert_eq!(sys.reasons, 1);
    }
}

/// `y' = −y` whose `f` fails for `t > 0.5`.
struct FailsLate;

impl OdeSystem for FailsLate {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        if t > 0.5 {
            return Err(SystemError::new("no f beyond t = 0.5"));
        }
        dy[0] = -y[0];
        Ok(())
    }
}

#[test]
fn budgets_and_failures_are_reasons() {
    let y0 = [1.0, 0.0];
    // The step budget: exactly `max_steps` trial steps.
    for method in Method::ALL {
        let opts = for_method(
            method,
            &Options {
                max_steps: 5,
                ..Options::default()
            },
        );
        let (_, d) = ode_both(method, 100.0, &opts);
        if method.needs_fixed_step() {
            // A fixed step knows its step count: refused before the first step.
            let e = &d.result.as_ref().unwrap_err().error;
            assert!(
                matches!(e, IntegrateError::InvalidInput(m) if m.contains("max_steps = 5")),
                "{e}"
            );
            continue;
        }
        let Some(StopReason::Budget(IntegrateError::TooManySteps { max_steps, t, .. })) =
            d.reasons.last()
        else {
            panic!("{method:?}: {:?}", d.reasons.last());
        };
        assert_eq!(*max_steps, 5);
        let s = &d.result.as_ref().unwrap_err().partial;
        assert_eq!(s.stats.steps + s.stats.rejected_steps, 5);
        assert_eq!(s.t_last, *t);
    }
    // The wall-clock budget, checked before the first trial step.
    let opts = Options {
        max_wall_time_s: Some(0.0),
        ..Options::default()
    };
    let mut sys = Oscillator;
    let mut s = Solver::new(Method::Radau5, &mut sys, 0.0, &y0, 1.0, &opts).unwrap();
    assert!(matches!(
        s.step(),
        StopReason::Budget(IntegrateError::TimeBudgetExceeded { t: 0.0, .. })
    ));
    // f failing at an accepted state (fixed step: at any stage) ends the run.
    let opts = Options {
        fixed_step: Some(0.1),
        ..Options::default()
    };
    let mut sys = FailsLate;
    let d = drive(Solver::new(Method::Rk4, &mut sys, 0.0, &[1.0], 1.0, &opts).unwrap());
    let Some(StopReason::Failed(IntegrateError::System { t, source })) = d.reasons.last() else {
        panic!("{:?}", d.reasons.last());
    };
    assert!((t - 0.5).abs() < 1e-12 && source.message.contains("beyond"));
    // Invalid input is refused by `new`, with the failure `solve` reports.
    let bad = Options {
        rtol: 0.0,
        ..Options::default()
    };
    let mut sys = Oscillator;
    for method in Method::ALL {
        let e = Solver::new(method, &mut sys, 0.0, &y0, 1.0, &bad).err();
        let f = e.expect("invalid rtol refused");
        assert!(matches!(f.error, IntegrateError::InvalidInput(_)));
        assert_same(
            &Err(f),
            &solve(method, &mut Oscillator, 0.0, &y0, 1.0, &bad),
        );
    }
}

// ---- Steps allocate nothing: a counting global allocator, armed per thread.

struct Counting;

thread_local! {
    static ARMED: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ARMED.try_with(|a| {
            if a.get() {
                let _ = COUNT.try_with(|c| c.set(c.get() + 1));
            }
        });
        unsafe { System.alloc(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ARMED.try_with(|a| {
            if a.get() {
                let _ = COUNT.try_with(|c| c.set(c.get() + 1));
            }
        });
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations made by 50 accepted steps of `s` after two warm-up steps
/// (no dense output, no output time before `t_end`, no guard).
fn allocations_of_steps(mut s: Solver<'_>) -> usize {
    for _ in 0..2 {
        assert!(matches!(s.step(), StopReason::Accepted { .. }));
    }
    COUNT.with(|c| c.set(0));
    ARMED.with(|a| a.set(true));
    for _ in 0..50 {
        let r = s.step();
        assert!(matches!(r, StopReason::Accepted { .. }), "{r:?}");
    }
    ARMED.with(|a| a.set(false));
    COUNT.with(Cell::get)
}

#[test]
fn steps_allocate_nothing() {
    let opts = Options {
        dense: false,
        ..Options::default()
    };
    let y0 = [1.0, 0.0];
    for method in Method::ALL {
        let opts = for_method(method, &opts);
        let mut sys = Oscillator;
        let n = allocations_of_steps(Solver::new(method, &mut sys, 0.0, &y0, 1e4, &opts).unwrap());
        assert_eq!(n, 0, "{method:?}");
    }
    let mut sys = ImplicitOscillator;
    let s = Solver::implicit(&mut sys, 0.0, &y0, &[0.0, -1.0], 1e4, &opts).unwrap();
    assert_eq!(allocations_of_steps(s), 0, "implicit");
}

/// `y' = 1` with a guard that is 1 before `t = 0.5` and NaN after: NaN
/// counts as not positive, so the run stops at the located `t = 0.5`
/// instead of switching the guard off.
struct NanGuard;

impl OdeSystem for NanGuard {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, _t: f64, _y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        dy[0] = 1.0;
        Ok(())
    }
    fn guard(&mut self, _t: f64, y: &[f64]) -> Option<f64> {
        Some(if y[0] < 0.5 { 1.0 } else { f64::NAN })
    }
}

#[test]
fn a_nan_guard_stops_the_run() {
    for method in Method::ALL {
        let opts = for_method(method, &Options::default());
        let r = solve(method, &mut NanGuard, 0.0, &[0.0], 3.0, &opts);
        match r.map(|s| s.t_last) {
            Err(Failure {
                error: IntegrateError::Stopped { t, .. },
                ..
            }) => assert!((t - 0.5).abs() < 1e-12, "{method:?}: {t}"),
            other => panic!("{method:?}: {other:?}"),
        }
    }
    // NaN at t0 stops at once.
    let r = solve(
        Method::Dopri5,
        &mut NanGuard,
        0.0,
        &[1.0],
        3.0,
        &Options::default(),
    );
    assert!(matches!(
        r,
        Err(Failure {
            error: IntegrateError::Stopped { t: 0.0, .. },
            ..
        })
    ));
}

/// `y' = −10⁶ (y − cos t)`: stiff for every explicit method.
struct StiffDecay;

impl OdeSystem for StiffDecay {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        dy[0] = -1e6 * (y[0] - t.cos());
        Ok(())
    }
}

/// With `stiff_stop`, DOPRI5 and DOP853 stop where their stiffness test has
/// fired 15 times in a row, as a budget, naming the estimate; without it
/// they run on (here into the step budget). Deterministic: the same stop
/// twice.
#[test]
fn stiff_stop_ends_explicit_runs_on_stiff_problems() {
    for method in [Method::Dopri5, Method::Dop853] {
        let opts = Options {
            stiff_stop: true,
            ..Options::default()
        };
        let mut sys = StiffDecay;
        let mut run = Solver::new(method, &mut sys, 0.0, &[1.0], 10.0, &opts).unwrap();
        let stop = loop {
            match run.step() {
                StopReason::Accepted { .. } => {}
                other => break other,
            }
        };
        let StopReason::Budget(IntegrateError::Stiff { t, stiffness, .. }) = stop else {
            panic!("{method:?}: {stop:?}");
        };
        // ρ = 10⁶ exactly for this problem.
        assert!(
            (stiffness.rho() / 1e6 - 1.0).abs() < 0.05,
            "{method:?}: ρ ≈ {}",
            stiffness.rho()
        );
        assert!(t < 1e-2, "{method:?}: stopped at t = {t}");
        let steps = run.stats().steps;
        assert!(steps < 2000, "{method:?}: {steps} steps");
        let again = solve(method, &mut StiffDecay, 0.0, &[1.0], 10.0, &opts).unwrap_err();
        assert_eq!(again.error.time(), Some(t));
        let off = Options {
            max_steps: 5000,
            ..Options::default()
        };
        let e = solve(method, &mut StiffDecay, 0.0, &[1.0], 10.0, &off).unwrap_err();
        assert!(
            matches!(e.error, IntegrateError::TooManySteps { .. }),
            "{method:?}"
        );
    }
}
