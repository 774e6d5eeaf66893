//! Peers side by side (feature `peers`): the same right-hand sides — our
//! `OdeSystem`s, automatic-differentiation Jacobians included — solved by
//! our integrators and by two other Rust crates.
//!
//! - `diffsol` 0.18 (dense nalgebra matrices and LU): its BDF (variable
//!   order 1–5, NDF formulas as in MATLAB's ode15s / SciPy's BDF) and two
//!   SDIRK methods, ESDIRK34 (Jørgensen, Kristensen & Thomsen 2018, order 3,
//!   stiffly accurate) and TR-BDF2 (order 2). The right-hand side is
//!   our `rhs` through diffsol's closure API; the Jacobian is given as a
//!   Jacobian–vector-product closure served from our dense `jacobian`, which
//!   is evaluated once per `(t, y)` and cached (diffsol assembles its dense
//!   Jacobian from `n` products at the same point).
//! - `ode_solvers` 0.6: its DOP853 (Hairer's `dop853.f` transcribed), on
//!   our `rhs`, against our DOP853.
//!
//! A right-hand side that fails (`SystemError`) returns NaN to the peer and
//! the first message is kept; every failure is recorded, never hidden.

use std::cell::{Cell, RefCell};
use std::time::Instant;

use diffsol::{NalgebraLU, NalgebraMat, OdeBuilder, OdeSolverMethod};
use nonholo_chetaev::Chetaev;
use nonholo_core::integrate::{
    Dense, Method, OdeSystem, Options, Radau5Options, RadauDense, RadauNewton, solve,
};
use nonholo_core::{Model, Observation, Params, Scene};
use nonholo_realise::{Visc, visc};
use nonholo_scenes::Sleigh;

use crate::hand::{BodyVisc, Constants};
use crate::setup::{initial, options};
use crate::timing::median;

/// The formulation of a peer problem.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Formulation {
    /// B (Chetaev, no stabilisation), state `(q, q̇)`.
    B,
    /// `visc(k)`, state `(q, q̇)`.
    Visc { k: f64 },
    /// `visc(k)` hand-written in the adapted state `(x, y, φ, u, w, ω)`
    /// ([`BodyVisc`]); samples are mapped back to `(q, q̇)`.
    ViscBody { k: f64 },
    /// `visc(k)` with `form = adapted`: the generic AD form in `(q, c, w)`
    /// (right-hand side and Jacobian by AD); samples mapped back to `(q, q̇)`
    /// by the model.
    ViscAdapted { k: f64 },
}

/// The map of a problem's state to `(q, q̇)`.
pub enum ToCartesian {
    Identity,
    Body,
    Adapted(Box<Visc<Sleigh>>),
}

impl ToCartesian {
    /// `y` (the problem's state at `t`) as `(q, q̇)`, in place.
    pub fn apply(&mut self, t: f64, y: &mut [f64]) -> Result<(), String> {
        match self {
            ToCartesian::Identity => Ok(()),
            ToCartesian::Body => {
                BodyVisc::to_cartesian(y);
                Ok(())
            }
            ToCartesian::Adapted(v) => {
                let n = y.len() / 2;
                let mut obs = Observation::new(n, v.multiplier_names().len());
                v.observe(t, y, &mut obs).map_err(|e| e.message)?;
                y[..n].copy_from_slice(&obs.q);
                y[n..].copy_from_slice(&obs.qd);
                Ok(())
            }
        }
    }
}

/// One initial value problem on the sleigh.
#[derive(Debug, Clone)]
pub struct Problem {
    /// `visc` or `B`.
    pub name: String,
    pub scene: Sleigh,
    pub potential: &'static str,
    pub formulation: Formulation,
    pub phi: f64,
    pub u: f64,
    pub omega: f64,
    pub t_end: f64,
}

impl Problem {
    /// The system and its initial state (fresh diagnostics).
    pub fn build(&self) -> Result<(Box<dyn OdeSystem>, Vec<f64>), String> {
        let init =
            initial(&self.scene, self.phi, self.u, self.omega, None).map_err(|e| e.to_string())?;
        match self.formulation {
            Formulation::B => {
                let mut b = Chetaev::new(
                    self.scene.clone(),
                    Params::defaults(nonholo_chetaev::OPTIONS),
                )
                .map_err(|e| e.to_string())?;
                let y0 = b.initial_state(&init).map_err(|e| e.to_string())?;
                Ok((Box::new(b), y0))
            }
            Formulation::Visc { k } | Formulation::ViscAdapted { k } => {
                let mut v = self.visc(k)?;
                let y0 = v.initial_state(&init).map_err(|e| e.to_string())?;
                Ok((Box::new(v), y0))
            }
            Formulation::ViscBody { k } => {
                let mut y0: Vec<f64> = init.q.iter().chain(&init.qd).copied().collect();
                BodyVisc::from_cartesian(&mut y0);
                let sys = BodyVisc {
                    c: Constants::of(&self.scene),
                    k,
                };
                Ok((Box::new(sys), y0))
            }
        }
    }

    /// `visc(k)` in the problem's form (`cartesian` or `adapted`).
    fn visc(&self, k: f64) -> Result<Visc<Sleigh>, String> {
        let form = match self.formulation {
            Formulation::ViscAdapted { .. } => "adapted",
            _ => "cartesian",
        };
        let opts = options(visc::OPTIONS, &[("k", &k.to_string()), ("form", form)])
            .map_err(|e| e.to_string())?;
        Visc::new(self.scene.clone(), opts).map_err(|e| e.to_string())
    }

    /// The map of this problem's states to `(q, q̇)`.
    pub fn to_cartesian(&self) -> Result<ToCartesian, String> {
        Ok(match self.formulation {
            Formulation::ViscBody { .. } => ToCartesian::Body,
            Formulation::ViscAdapted { k } => ToCartesian::Adapted(Box::new(self.visc(k)?)),
            _ => ToCartesian::Identity,
        })
    }

    /// The parameter that labels the problem in tables: `k` or `a`.
    pub fn label(&self) -> String {
        match self.formulation {
            Formulation::Visc { k }
            | Formulation::ViscBody { k }
            | Formulation::ViscAdapted { k } => format!("k={k:.0e}"),
            Formulation::B => format!("a={}", self.scene.a),
        }
    }

    /// The closed form at `t` (`(q, q̇)`), where the scene has one.
    pub fn closed_form(&self, t: f64, out: &mut [f64]) -> Result<(), String> {
        let init =
            initial(&self.scene, self.phi, self.u, self.omega, None).map_err(|e| e.to_string())?;
        let (q, qd) = out.split_at_mut(init.q.len());
        self.scene.closed_form(&init.q, &init.qd, t, q, qd)
    }
}

/// Work counters of one run, as far as each solver reports them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Work {
    /// Right-hand-side evaluations (counted at our `rhs`, so the same for
    /// every solver).
    pub rhs: usize,
    /// Of which only for dense output (our DOP853; ode_solvers computes
    /// its three dense stages on every step and counts them in `rhs`).
    pub dense_rhs: usize,
    /// Dense Jacobians `∂f/∂y` evaluated (our AD `jacobian`).
    pub jac: usize,
    /// Jacobian–vector products requested (diffsol only).
    pub jvp: usize,
    pub steps: usize,
    pub rejected: usize,
    pub newton_iters: usize,
    pub newton_fails: usize,
    /// LU factorisations (Radau: a real + complex pair counts one; diffsol:
    /// linear-solver set-ups).
    pub lu: usize,
}

/// Samples of a run: times and states (row-major), its continuous
/// extension when asked for, work and wall time.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub t: Vec<f64>,
    pub y: Vec<f64>,
    /// The state at `t_end` from the last step (not from an interpolant).
    pub y_end: Vec<f64>,
    pub dim: usize,
    pub dense: Option<Dense>,
    pub work: Work,
    pub wall_s: f64,
}

impl Outcome {
    pub fn row(&self, i: usize) -> &[f64] {
        &self.y[i * self.dim..(i + 1) * self.dim]
    }

    /// Samples and final state as `(q, q̇)`.
    fn into_cartesian(mut self, problem: &Problem) -> Result<Self, String> {
        let mut map = problem.to_cartesian()?;
        for (row, &t) in self.y.chunks_mut(self.dim).zip(&self.t) {
            map.apply(t, row)?;
        }
        map.apply(problem.t_end, &mut self.y_end)?;
        // The continuous extension stays in the problem's own state.
        Ok(self)
    }
}

/// A failed run: the message and what was counted up to it.
#[derive(Debug, Clone)]
pub struct Failed {
    pub message: String,
    pub work: Work,
    pub wall_s: f64,
}

pub type Attempt = Result<Outcome, Failed>;

/// The solvers of the comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Solver {
    /// Ours, `nonholo_integrate::solve` with this method (Radau IIA with
    /// RADAU5's simplified Newton iteration).
    Ours(Method),
    /// Ours, Radau IIA with the full Newton iteration (what `nonholo
    /// simulate` chooses for `visc`).
    OursFullNewton,
    /// Ours, Radau IIA with simplified Newton keeping its Jacobian while
    /// the Newton contraction θ stays at or below this threshold instead of
    /// RADAU5's default 0.001 (`radau5.jacobian_reuse`; Hairer's RADAU5
    /// suggests 0.1 where Jacobians are costly).
    OursReuse(Reuse),
    /// Ours, Radau IIA with simplified Newton and the Hermite continuous
    /// extension (`radau5.dense_output = hermite`), with RADAU5's reuse
    /// threshold (`None`) or another one.
    OursHermite(Option<Reuse>),
    /// As `OursHermite(Some(Reuse::Tenth))` with the Newton iteration's stopping
    /// test (RADAU5's `FNEWT`) [`TIGHT_NEWTON`] times tighter than RADAU5's
    /// default at the run's tolerance: a Jacobian kept over many steps
    /// leaves iteration error that builds up (`docs/integrators.md`,
    /// "Newton stopping test"). The integrator raises it to its floor
    /// `10·uround/rtol'`, which binds below tolerances of about 3e-13
    /// (the test would then be less than ten times tighter); the studies
    /// here run at 1e-4 … 1e-10.
    OursTightNewton,
    /// diffsol with this method; `max_fails` is its cap on nonlinear-solver
    /// failures over the whole run (`OdeSolverOptions::
    /// max_nonlinear_solver_failures`, default [`DIFFSOL_DEFAULT_CAP`]).
    Diffsol {
        method: DiffsolMethod,
        max_fails: usize,
    },
    /// `ode_solvers::Dop853`.
    OdeSolversDop853,
}

/// The Jacobian-reuse thresholds tried besides RADAU5's default.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reuse {
    Hundredth,
    Tenth,
}

impl Reuse {
    pub fn theta(self) -> f64 {
        match self {
            Reuse::Hundredth => 0.01,
            Reuse::Tenth => 0.1,
        }
    }
}

/// How many times tighter than RADAU5's default [`Solver::OursTightNewton`]
/// stops the Newton iteration.
pub const TIGHT_NEWTON: f64 = 10.0;

/// diffsol's default cap on nonlinear-solver failures per run.
pub const DIFFSOL_DEFAULT_CAP: usize = 50;

/// The diffsol methods compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiffsolMethod {
    Bdf,
    Esdirk34,
    TrBdf2,
}

/// Our Radau IIA with `newton` and RADAU5's Jacobian reuse (or `theta`),
/// read through RADAU5's collocation polynomial as in the stored results
/// (the default is now the Hermite extension: [`Solver::OursHermite`]).
fn radau5(newton: RadauNewton, theta: Option<f64>) -> Radau5Options {
    let default = Radau5Options::default();
    Radau5Options {
        newton,
        jacobian_reuse: theta.unwrap_or(default.jacobian_reuse),
        dense_output: RadauDense::Collocation,
        ..default
    }
}

/// Our Radau IIA with simplified Newton read through the Hermite
/// extension, with RADAU5's Jacobian reuse (or `theta`).
fn hermite(theta: Option<f64>) -> Radau5Options {
    Radau5Options {
        dense_output: RadauDense::Hermite,
        ..radau5(RadauNewton::Simplified, theta)
    }
}

impl Solver {
    pub fn crate_name(self) -> &'static str {
        match self {
            Solver::Ours(_)
            | Solver::OursFullNewton
            | Solver::OursReuse(_)
            | Solver::OursHermite(_)
            | Solver::OursTightNewton => "nonholo",
            Solver::OdeSolversDop853 => "ode_solvers",
            _ => "diffsol",
        }
    }

    pub fn method_name(self) -> &'static str {
        match self {
            Solver::Ours(Method::Radau5) => "Radau IIA (radau5)",
            Solver::OursFullNewton => "Radau IIA (radau5), full Newton",
            Solver::OursReuse(Reuse::Hundredth) => "Radau IIA (radau5), reuse θ ≤ 0.01",
            Solver::OursReuse(Reuse::Tenth) => "Radau IIA (radau5), reuse θ ≤ 0.1",
            Solver::OursHermite(None) => "Radau IIA (radau5), Hermite dense output",
            Solver::OursHermite(Some(Reuse::Hundredth)) => {
                "Radau IIA (radau5), reuse θ ≤ 0.01, Hermite dense output"
            }
            Solver::OursHermite(Some(Reuse::Tenth)) => {
                "Radau IIA (radau5), reuse θ ≤ 0.1, Hermite dense output"
            }
            Solver::OursTightNewton => {
                "Radau IIA (radau5), reuse θ ≤ 0.1, Newton test ÷ 10, Hermite dense output"
            }
            Solver::Ours(Method::Dop853) => "DOP853",
            Solver::Ours(Method::Dopri5) => "DOPRI5",
            Solver::Ours(Method::Rk4) => "RK4",
            Solver::Diffsol { method, max_fails } => match (method, max_fails) {
                (DiffsolMethod::Bdf, DIFFSOL_DEFAULT_CAP) => "BDF (NDF, order 1-5)",
                (DiffsolMethod::Esdirk34, DIFFSOL_DEFAULT_CAP) => "ESDIRK34",
                (DiffsolMethod::TrBdf2, DIFFSOL_DEFAULT_CAP) => "TR-BDF2",
                (DiffsolMethod::Bdf, _) => "BDF, no failure cap",
                (DiffsolMethod::Esdirk34, _) => "ESDIRK34, no failure cap",
                (DiffsolMethod::TrBdf2, _) => "TR-BDF2, no failure cap",
            },
            Solver::OdeSolversDop853 => "DOP853",
        }
    }

    /// The same solver without diffsol's cap on nonlinear failures.
    pub fn uncapped(self) -> Self {
        match self {
            Solver::Diffsol { method, .. } => Solver::Diffsol {
                method,
                max_fails: usize::MAX / 2,
            },
            other => other,
        }
    }

    /// Runs `problem` at `rtol = atol = tol`, sampled on `grid`.
    /// `dense` keeps our continuous extension (for references).
    pub fn run(self, problem: &Problem, tol: f64, grid: &[f64], dense: bool) -> Attempt {
        let attempt = match self {
            Solver::Ours(method) => {
                let radau = radau5(RadauNewton::Simplified, None);
                run_ours(problem, method, radau, tol, grid, dense)
            }
            Solver::OursFullNewton => {
                let radau = radau5(RadauNewton::Full, None);
                run_ours(problem, Method::Radau5, radau, tol, grid, dense)
            }
            Solver::OursReuse(reuse) => {
                let radau = radau5(RadauNewton::Simplified, Some(reuse.theta()));
                run_ours(problem, Method::Radau5, radau, tol, grid, dense)
            }
            Solver::OursHermite(reuse) => {
                let radau = hermite(reuse.map(Reuse::theta));
                run_ours(problem, Method::Radau5, radau, tol, grid, dense)
            }
            Solver::OursTightNewton => {
                let radau = Radau5Options {
                    newton_tol: Some(Radau5Options::default().newton_tol_at(tol) / TIGHT_NEWTON),
                    ..hermite(Some(Reuse::Tenth.theta()))
                };
                run_ours(problem, Method::Radau5, radau, tol, grid, dense)
            }
            Solver::OdeSolversDop853 => run_ode_solvers(problem, tol, grid),
            Solver::Diffsol { method, max_fails } => {
                run_diffsol(problem, method, max_fails, tol, grid)
            }
        };
        let outcome = attempt?;
        let (work, wall_s) = (outcome.work.clone(), outcome.wall_s);
        outcome.into_cartesian(problem).map_err(|message| Failed {
            message: format!("mapping the samples to (q, q̇) failed: {message}"),
            work,
            wall_s,
        })
    }
}

fn run_ours(
    problem: &Problem,
    method: Method,
    radau5: Radau5Options,
    tol: f64,
    grid: &[f64],
    dense: bool,
) -> Attempt {
    let fail = |message: String| Failed {
        message,
        work: Work::default(),
        wall_s: 0.0,
    };
    let (mut sys, y0) = problem.build().map_err(fail)?;
    let opts = Options {
        rtol: tol,
        atol: tol,
        output: grid.to_vec(),
        dense,
        radau5,
        ..Options::default()
    };
    let start = Instant::now();
    let result = solve(method, &mut *sys, 0.0, &y0, problem.t_end, &opts);
    let wall_s = start.elapsed().as_secs_f64();
    let work_of = |s: &nonholo_core::integrate::Stats| Work {
        rhs: s.rhs_evals,
        dense_rhs: s.dense_rhs_evals,
        jac: s.jacobian_evals,
        jvp: 0,
        steps: s.steps,
        rejected: s.rejected_steps,
        newton_iters: s.newton_iterations,
        newton_fails: s.newton_failures,
        lu: s.lu_decompositions,
    };
    match result {
        Ok(sol) => Ok(Outcome {
            dim: sol.dim,
            y_end: sol.y_last,
            work: work_of(&sol.stats),
            t: sol.t,
            y: sol.y,
            dense: sol.dense,
            wall_s,
        }),
        Err(f) => Err(Failed {
            message: format!("{} (t reached {})", f.error, f.partial.t_last),
            work: work_of(&f.partial.stats),
            wall_s,
        }),
    }
}

/// Our system behind diffsol's closures: `rhs`, and `J v` from the cached
/// dense AD Jacobian.
struct DiffsolAdapter {
    sys: Box<dyn OdeSystem>,
    n: usize,
    jac: Vec<f64>,
    jac_t: f64,
    jac_y: Vec<f64>,
    jac_valid: bool,
    work: Work,
    error: Option<String>,
}

impl DiffsolAdapter {
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) {
        self.work.rhs += 1;
        if let Err(e) = self.sys.rhs(t, y, dy) {
            self.error
                .get_or_insert(format!("rhs at t = {t}: {}", e.message));
            dy.fill(f64::NAN);
        }
    }

    fn jvp(&mut self, t: f64, y: &[f64], v: &[f64], out: &mut [f64]) {
        self.work.jvp += 1;
        let n = self.n;
        if !(self.jac_valid && self.jac_t == t && self.jac_y == y) {
            self.work.jac += 1;
            self.jac_t = t;
            self.jac_y.copy_from_slice(y);
            self.jac_valid = match self.sys.jacobian(t, y, &mut self.jac) {
                Ok(true) => true,
                // No Jacobian: forward differences, as our Radau does.
                Ok(false) => self.forward_differences(t, y),
                Err(e) => {
                    self.error
                        .get_or_insert(format!("jacobian at t = {t}: {}", e.message));
                    false
                }
            };
            if !self.jac_valid {
                out.fill(f64::NAN);
                return;
            }
        }
        for i in 0..n {
            out[i] = (0..n).map(|j| self.jac[i * n + j] * v[j]).sum();
        }
    }

    /// Forward-difference Jacobian into `self.jac` (RADAU5's increments).
    fn forward_differences(&mut self, t: f64, y: &[f64]) -> bool {
        let n = self.n;
        let (mut f0, mut f1, mut yh) = (vec![0.0; n], vec![0.0; n], y.to_vec());
        self.work.rhs += 1;
        if let Err(e) = self.sys.rhs(t, y, &mut f0) {
            self.error
                .get_or_insert(format!("rhs at t = {t}: {}", e.message));
            return false;
        }
        for j in 0..n {
            let h = (f64::EPSILON * 1e-5f64.max(y[j].abs())).sqrt();
            yh[j] = y[j] + h;
            self.work.rhs += 1;
            if let Err(e) = self.sys.rhs(t, &yh, &mut f1) {
                self.error
                    .get_or_insert(format!("rhs at t = {t}: {}", e.message));
                return false;
            }
            for i in 0..n {
                self.jac[i * n + j] = (f1[i] - f0[i]) / h;
            }
            yh[j] = y[j];
        }
        true
    }
}

/// Drives a diffsol solver to the end of `grid`; the solution matrix and
/// the solver's statistics.
macro_rules! drive {
    ($solver:expr, $grid:expr) => {{
        match $solver {
            Ok(mut s) => match s.solve_dense($grid) {
                Ok((ys, _stop)) => Ok((ys, s.get_statistics().clone())),
                Err(e) => Err((e.to_string(), Some(s.get_statistics().clone()))),
            },
            Err(e) => Err((e.to_string(), None)),
        }
    }};
}

fn run_diffsol(
    problem: &Problem,
    which: DiffsolMethod,
    max_fails: usize,
    tol: f64,
    grid: &[f64],
) -> Attempt {
    let (sys, y0) = problem.build().map_err(|message| Failed {
        message,
        work: Work::default(),
        wall_s: 0.0,
    })?;
    let n = y0.len();
    let adapter = RefCell::new(DiffsolAdapter {
        sys,
        n,
        jac: vec![0.0; n * n],
        jac_t: f64::NAN,
        jac_y: vec![0.0; n],
        jac_valid: false,
        work: Work::default(),
        error: None,
    });
    let start = Instant::now();
    let built = OdeBuilder::<NalgebraMat<f64>>::new()
        .t0(0.0)
        .rtol(tol)
        .atol([tol])
        .rhs_implicit(
            |x: &[f64], _p: &[f64], t: f64, y: &mut [f64]| adapter.borrow_mut().rhs(t, x, y),
            |x: &[f64], _p: &[f64], t: f64, v: &[f64], y: &mut [f64]| {
                adapter.borrow_mut().jvp(t, x, v, y)
            },
        )
        .init(
            |_p: &[f64], _t: f64, y: &mut [f64]| y.copy_from_slice(&y0),
            n,
        )
        .build();
    let mut problem_d = match built {
        Ok(p) => p,
        Err(e) => {
            return Err(Failed {
                message: format!("diffsol could not build the problem: {e}"),
                work: adapter.borrow().work.clone(),
                wall_s: start.elapsed().as_secs_f64(),
            });
        }
    };
    problem_d.ode_options.max_nonlinear_solver_failures = max_fails;
    let result = match which {
        DiffsolMethod::Bdf => drive!(problem_d.bdf::<NalgebraLU<f64>>(), grid),
        DiffsolMethod::Esdirk34 => drive!(problem_d.esdirk34::<NalgebraLU<f64>>(), grid),
        DiffsolMethod::TrBdf2 => drive!(problem_d.tr_bdf2::<NalgebraLU<f64>>(), grid),
    };
    let wall_s = start.elapsed().as_secs_f64();
    let mut adapter = adapter.into_inner();
    let mut fill = |stats: &diffsol::ode_solver::OdeSolverStatistics| {
        adapter.work.steps = stats.number_of_steps;
        adapter.work.rejected =
            stats.number_of_error_test_failures + stats.number_of_nonlinear_solver_fails;
        adapter.work.newton_iters = stats.number_of_nonlinear_solver_iterations;
        adapter.work.newton_fails = stats.number_of_nonlinear_solver_fails;
        adapter.work.lu = stats.number_of_linear_solver_setups;
    };
    match result {
        Ok((ys, stats)) => {
            fill(&stats);
            let mut y = Vec::with_capacity(n * grid.len());
            for col in 0..grid.len() {
                for i in 0..n {
                    y.push(ys[(i, col)]);
                }
            }
            if let Some(e) = adapter.error.take() {
                // The solver finished although a call failed somewhere
                // (a rejected trial): keep the run, say so in the log.
                eprintln!("  note: diffsol {which:?} recovered from: {e}");
            }
            // The last column is at the stop time, where the solver lands.
            let y_end = y[(grid.len() - 1) * n..].to_vec();
            Ok(Outcome {
                t: grid.to_vec(),
                y_end,
                y,
                dim: n,
                dense: None,
                work: adapter.work,
                wall_s,
            })
        }
        Err((message, stats)) => {
            if let Some(stats) = stats {
                fill(&stats);
            }
            let message = match adapter.error.take() {
                Some(e) => format!("{message}; first system error: {e}"),
                None => message,
            };
            Err(Failed {
                message,
                work: adapter.work,
                wall_s,
            })
        }
    }
}

/// Our system as an `ode_solvers::System` (which takes `&self`).
struct OdeSolversAdapter<'a> {
    sys: &'a RefCell<Box<dyn OdeSystem>>,
    evals: &'a Cell<usize>,
    error: &'a RefCell<Option<String>>,
}

type State6 = ode_solvers::SVector<f64, 6>;

impl ode_solvers::System<f64, State6> for OdeSolversAdapter<'_> {
    fn system(&self, t: f64, y: &State6, dy: &mut State6) {
        self.evals.set(self.evals.get() + 1);
        if let Err(e) = self
            .sys
            .borrow_mut()
            .rhs(t, y.as_slice(), dy.as_mut_slice())
        {
            self.error
                .borrow_mut()
                .get_or_insert(format!("rhs at t = {t}: {}", e.message));
            dy.fill(f64::NAN);
        }
    }
}

fn run_ode_solvers(problem: &Problem, tol: f64, grid: &[f64]) -> Attempt {
    let (sys, y0) = problem.build().map_err(|message| Failed {
        message,
        work: Work::default(),
        wall_s: 0.0,
    })?;
    if y0.len() != 6 {
        return Err(Failed {
            message: format!("the ode_solvers adapter has dimension 6, not {}", y0.len()),
            work: Work::default(),
            wall_s: 0.0,
        });
    }
    // Its dense output walks an evenly spaced grid from t0 by dx.
    let dx = if grid.len() > 1 {
        grid[1] - grid[0]
    } else {
        problem.t_end
    };
    let sys = RefCell::new(sys);
    let evals = Cell::new(0);
    let error = RefCell::new(None);
    let adapter = OdeSolversAdapter {
        sys: &sys,
        evals: &evals,
        error: &error,
    };
    let start = Instant::now();
    let mut stepper = ode_solvers::Dop853::new(
        adapter,
        0.0,
        problem.t_end,
        dx,
        State6::from_column_slice(&y0),
        tol,
        tol,
    );
    let result = stepper.integrate();
    let wall_s = start.elapsed().as_secs_f64();
    let mut work = Work {
        rhs: evals.get(),
        ..Work::default()
    };
    let failure = error.borrow_mut().take();
    match result {
        Ok(stats) => {
            work.steps = stats.accepted_steps as usize;
            work.rejected = stats.rejected_steps as usize;
            if let Some(e) = failure {
                return Err(Failed {
                    message: format!("ode_solvers finished on NaN: {e}"),
                    work,
                    wall_s,
                });
            }
            let t = stepper.x_out().clone();
            let y = stepper
                .y_out()
                .iter()
                .flat_map(|v| v.iter().copied())
                .collect();
            // The state of the last step, from a second (untimed) run with
            // sparse output: the same steps, no interpolation.
            let (sys, y0) = problem.build().map_err(|message| Failed {
                message,
                work: work.clone(),
                wall_s,
            })?;
            let sys = RefCell::new(sys);
            let evals2 = Cell::new(0);
            let error2 = RefCell::new(None);
            let mut sparse = ode_solvers::Dop853::new(
                OdeSolversAdapter {
                    sys: &sys,
                    evals: &evals2,
                    error: &error2,
                },
                0.0,
                problem.t_end,
                dx,
                State6::from_column_slice(&y0),
                tol,
                tol,
            );
            sparse.set_output(ode_solvers::OutputType::Sparse);
            let y_end = match (
                sparse.integrate(),
                sparse.x_out().last(),
                sparse.y_out().last(),
            ) {
                (Ok(_), Some(&t_last), Some(v)) if t_last == problem.t_end => v.as_slice().to_vec(),
                _ => {
                    return Err(Failed {
                        message: "ode_solvers' sparse rerun did not end at t_end".into(),
                        work,
                        wall_s,
                    });
                }
            };
            Ok(Outcome {
                t,
                y,
                y_end,
                dim: 6,
                dense: None,
                work,
                wall_s,
            })
        }
        Err(e) => Err(Failed {
            message: match failure {
                Some(f) => format!("{e}; first system error: {f}"),
                None => e.to_string(),
            },
            work,
            wall_s,
        }),
    }
}

/// A reference solution: values at any time in `[0, t_end]`.
pub enum Reference {
    /// Our continuous extension of a tight run, of the problem's own state,
    /// mapped to `(q, q̇)` by `map`.
    Dense {
        dense: Dense,
        map: RefCell<ToCartesian>,
    },
    /// The scene's closed form.
    Closed(Problem),
}

impl Reference {
    pub fn eval(&self, t: f64, out: &mut [f64]) -> Result<(), String> {
        match self {
            Reference::Dense { dense, map } => {
                if dense.eval(t, out) {
                    map.borrow_mut().apply(t, out)
                } else {
                    Err(format!("t = {t} outside the reference's span"))
                }
            }
            Reference::Closed(p) => p.closed_form(t, out),
        }
    }
}

/// Errors of a run against a reference, `‖y − y_ref‖∞` over the whole
/// state: `(at t_end, max over the samples before t_end and the final
/// state, note)`. The final state is the last step's, not an interpolated
/// sample; where a solver's sample at `t_end` differs from it, the note
/// says by how much.
pub fn errors(
    run: &Outcome,
    reference: &Reference,
    t_end: f64,
) -> Result<(f64, f64, String), String> {
    let dist = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0f64, |m, d| if d.is_nan() { f64::NAN } else { m.max(d) })
    };
    let mut r = vec![0.0; run.dim];
    reference.eval(t_end, &mut r)?;
    let at_end = dist(&run.y_end, &r);
    let mut max = at_end;
    let mut note = String::new();
    let slack = 1e-9 * t_end.abs().max(1.0);
    for (i, &t) in run.t.iter().enumerate() {
        if (t - t_end).abs() <= slack {
            let d = dist(run.row(i), &run.y_end);
            if d > 1e-12 * (1.0 + run.y_end.iter().fold(0.0f64, |m, v| m.max(v.abs()))) {
                note = format!(
                    "its dense-output sample at t_end differs from its final step's state by {d:.2e} \
                     (error {:.2e}); the table uses the final state",
                    dist(run.row(i), &r)
                );
            }
            continue;
        }
        reference.eval(t, &mut r)?;
        let e = dist(run.row(i), &r);
        max = if e.is_nan() || max.is_nan() {
            f64::NAN
        } else {
            max.max(e)
        };
    }
    Ok((at_end, max, note))
}

/// One row of the comparison.
#[derive(Debug, Clone)]
pub struct Row {
    pub problem: String,
    pub potential: &'static str,
    pub param: String,
    pub t_end: f64,
    pub crate_name: &'static str,
    pub method: &'static str,
    pub tol: f64,
    /// `ok` or `failed`.
    pub status: &'static str,
    pub message: String,
    pub err_end: f64,
    pub err_max: f64,
    /// The reference's own error estimate (difference of two references).
    pub ref_err: f64,
    pub reference: String,
    pub wall_median_s: f64,
    pub wall_min_s: f64,
    pub repeats: usize,
    pub work: Work,
}

impl Row {
    pub const HEADER: &'static str = "problem,potential,param,t_end,crate,method,tol,status,\
        err_end,err_max,ref_err,reference,wall_median_s,wall_min_s,repeats,rhs_evals,\
        dense_rhs_evals,jac_evals,jvp_evals,steps,rejected,newton_iters,newton_fails,lu,message";

    pub fn csv(&self) -> String {
        let w = &self.work;
        format!(
            "{},{},{},{},{},{},{:e},{},{:e},{:e},{:e},{},{:e},{:e},{},{},{},{},{},{},{},{},{},{},{}",
            self.problem,
            self.potential,
            self.param,
            self.t_end,
            self.crate_name,
            quote(self.method),
            self.tol,
            self.status,
            self.err_end,
            self.err_max,
            self.ref_err,
            quote(&self.reference),
            self.wall_median_s,
            self.wall_min_s,
            self.repeats,
            w.rhs,
            w.dense_rhs,
            w.jac,
            w.jvp,
            w.steps,
            w.rejected,
            w.newton_iters,
            w.newton_fails,
            w.lu,
            quote(&self.message)
        )
    }
}

/// A CSV field, quoted when it needs to be.
fn quote(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// What runs are measured against: the grid their samples are read on, the
/// reference, its name (for the CSV) and its own estimated error.
#[derive(Clone, Copy)]
pub struct Against<'a> {
    pub grid: &'a [f64],
    pub reference: &'a Reference,
    pub name: &'a str,
    pub ref_err: f64,
}

/// Runs `solver` `repeats` times; one row.
pub fn measure(
    problem: &Problem,
    solver: Solver,
    tol: f64,
    against: Against<'_>,
    repeats: usize,
) -> Row {
    let mut rows = measure_all(problem, &[solver], tol, against, repeats);
    rows.remove(0)
}

/// Runs every solver of `solvers` once (errors against `against`, work
/// counters), then times `repeats − 1` more rounds, each running every
/// solver that has not failed once, starting one solver further on each
/// round, so that a change in the machine's speed falls on all of them
/// alike; one row per solver, in order, with
/// the median and the least of its wall times.
pub fn measure_all(
    problem: &Problem,
    solvers: &[Solver],
    tol: f64,
    against: Against<'_>,
    repeats: usize,
) -> Vec<Row> {
    measure_all_retrying(problem, solvers, |_, _| None, tol, against, repeats)
}

/// [`measure_all`], where a solver whose first run `retry` answers with
/// another solver (diffsol without its failure cap after a capped-out run,
/// say) has that one run right after it and timed in the same rounds; its
/// row follows the first one's.
pub fn measure_all_retrying(
    problem: &Problem,
    solvers: &[Solver],
    retry: impl Fn(Solver, &Row) -> Option<Solver>,
    tol: f64,
    against: Against<'_>,
    repeats: usize,
) -> Vec<Row> {
    // (solver, its row, its wall times) after the first run.
    let first = |solver: Solver| -> (Solver, Row, Vec<f64>) {
        let mut row = Row {
            problem: problem.name.clone(),
            potential: problem.potential,
            param: problem.label(),
            t_end: problem.t_end,
            crate_name: solver.crate_name(),
            method: solver.method_name(),
            tol,
            status: "ok",
            message: String::new(),
            err_end: f64::NAN,
            err_max: f64::NAN,
            ref_err: against.ref_err,
            reference: against.name.to_string(),
            wall_median_s: f64::NAN,
            wall_min_s: f64::NAN,
            repeats: 0,
            work: Work::default(),
        };
        let wall = match solver.run(problem, tol, against.grid, false) {
            Err(f) => {
                row.status = "failed";
                row.message = f.message;
                row.work = f.work;
                f.wall_s
            }
            Ok(out) => {
                match errors(&out, against.reference, problem.t_end) {
                    Ok((e_end, e_max, note)) => {
                        row.err_end = e_end;
                        row.err_max = e_max;
                        row.message = note;
                    }
                    Err(e) => row.message = format!("error not measured: {e}"),
                }
                row.work = out.work;
                out.wall_s
            }
        };
        (solver, row, vec![wall])
    };
    let mut runs = Vec::with_capacity(solvers.len());
    for &solver in solvers {
        let run = first(solver);
        let again = retry(solver, &run.1);
        runs.push(run);
        runs.extend(again.map(first));
    }
    let n = runs.len();
    for round in 1..repeats {
        // Each round starts one solver further on, so that no solver holds
        // the same place in the order (first after the previous case's
        // last run, say) in every round.
        for i in (0..n).map(|j| (j + round) % n) {
            let (solver, row, walls) = &mut runs[i];
            if row.status != "ok" {
                continue;
            }
            match solver.run(problem, tol, against.grid, false) {
                Ok(o) => walls.push(o.wall_s),
                Err(f) => {
                    row.message = format!("a repeat failed: {}", f.message);
                    row.status = "failed";
                }
            }
        }
    }
    runs.into_iter()
        .map(|(_, mut row, mut walls)| {
            row.repeats = walls.len();
            row.wall_min_s = walls.iter().copied().fold(f64::INFINITY, f64::min);
            row.wall_median_s = median(&mut walls);
            row
        })
        .collect()
}

/// Largest difference `‖a − b‖∞` of two references over `grid`.
pub fn reference_distance(a: &Reference, b: &Reference, grid: &[f64], dim: usize) -> f64 {
    let (mut ya, mut yb) = (vec![0.0; dim], vec![0.0; dim]);
    let mut max = 0.0f64;
    for &t in grid {
        if a.eval(t, &mut ya).is_err() || b.eval(t, &mut yb).is_err() {
            return f64::NAN;
        }
        let d = ya
            .iter()
            .zip(&yb)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0f64, f64::max);
        max = max.max(d);
    }
    max
}
