//! Integrators for initial value problems `y' = f(t, y)`, `y(t0) = y0`, and
//! for implicit systems `F(t, y, y') = 0` (differential-algebraic equations
//! of index up to 3).
//!
//! This crate knows no mechanics. A problem is anything implementing
//! [`OdeSystem`] (or [`ImplicitSystem`] for [`solve_implicit`]); a run
//! returns a [`Solution`] (samples on a requested output grid, optional
//! continuous extension, work counters) or a [`Failure`] carrying the error,
//! the time at which it happened and the partial solution up to that time.
//!
//! | method | order | error estimate | dense output order | reference |
//! |---|---|---|---|---|
//! | [`Method::Rk4`] | 4 | none (fixed step) | 3 (cubic Hermite) | Kutta 1901 |
//! | [`Method::Dopri5`] | 5 | embedded 4 | 4 | Dormand & Prince 1980; Hairer, Nørsett & Wanner, *Solving ODE I*, §II.4–6 (DOPRI5) |
//! | [`Method::Dop853`] | 8 | embedded 5 and 3 | 7 | Prince & Dormand 1981; Hairer, Nørsett & Wanner, §II.10 (DOP853) |
//! | [`Method::Radau5`] | 5 (stage order 3, L-stable, implicit) | embedded 3, filtered | 5 on non-stiff rows of ODEs (Hermite, default), else 3 (collocation polynomial) | Hairer & Wanner, *Solving ODE II*, §IV.8 (RADAU5) |
//!
//! Step-size control, initial step selection and stiffness detection follow
//! Hairer's DOPRI5/DOP853 codes; Radau IIA follows his RADAU5 (simplified
//! Newton iteration with Jacobian reuse, Gustafsson's predictive controller;
//! optionally a full Newton iteration, [`RadauNewton::Full`], for fully
//! implicit index-3 systems outside Hessenberg form; see the documentation
//! of `src/radau/mod.rs` for its options, counters and failures).
//!
//! # Solving, or stepping
//!
//! [`solve`] and [`solve_implicit`] run to `t_end`. They are loops over a
//! solver state, which can also be driven by hand: a [`Solver`] is built
//! from `(method, system, t0, y0, t_end, options)` ([`Solver::new`]) or
//! `(system, t0, y0, y'0, t_end, options)` ([`Solver::implicit`]; invalid
//! input is refused there) and advanced by
//! `step()`, which returns after every accepted step with a [`StopReason`]:
//! `Accepted { t }` (the run goes on), or a terminal `End { t }`,
//! `Guard { t, reason }`, `Budget(error)` or `Failed(error)`. `t()`, `y()`
//! and `stats()` show the current state; `into_solution()` hands over the
//! samples, continuous extension and counters up to it, and `solve()` is
//! `while let Accepted = step() {}` turned into `Ok` or a [`Failure`].
//! Workspaces are allocated by the constructors; a step allocates only to
//! store samples and step polynomials.
//!
//! All methods share one step loop (budgets, minimum step size, landing on
//! `t_end` and output times, `after_step` before the guard, the guard
//! watch, samples, the bounds on the next step size); a method only
//! attempts trial steps (`src/driver.rs`).
//!
//! # Settings
//!
//! [`Options`] holds what every method reads (tolerances, per-component
//! `atol`, fixed step, `h_init`, `h_max`, budgets, output grid, `dense`,
//! `hit_output`) and [`Radau5Options`] the settings of Radau5 alone (its
//! Newton iteration and the reuse of Jacobians and step sizes); the
//! explicit methods have no settings of their own (their controller
//! constants are those of `dopri5.f` and `dop853.f`). Both structs derive
//! `serde`'s `Serialize` and `Deserialize` (missing fields take their
//! defaults, unknown fields are refused), so that the settings can be
//! written beside every result; their item docs list the defaults.

// A `Failure` carries its partial `Solution` by design, and `Ok` carries a
// `Solution` of the same size: boxing the error would save nothing.
#![allow(clippy::result_large_err)]
#![warn(missing_docs)]

mod dense;
mod driver;
mod error;
mod explicit;
mod guard;
mod options;
mod radau;
mod record;
mod solution;
mod solver;
mod stop;
mod system;
mod validate;
pub use validate::fixed_step_budget;

pub use dense::Dense;
pub use error::{Failure, IntegrateError, StiffnessEstimate, SystemError};
pub use options::{Method, Options, Radau5Options, RadauDense, RadauNewton};
pub use solution::{Solution, Stats};
pub use solver::Solver;
pub use stop::StopReason;
pub use system::{ImplicitSystem, OdeSystem, Sparsity, jacobian_mismatch};

/// Integrates `sys` from `(t0, y0)` to `t_end` with `method` and `opts`.
///
/// Samples are taken at `opts.output` (times in `[t0, t_end]`, increasing),
/// always from the continuous extension, never by shortening steps; a
/// sample at `t0` is `y0` itself and `t_end` is appended if not listed.
/// Integration is forward only (`t_end >= t0`).
///
/// - [`Method::Rk4`] needs `opts.fixed_step`; [`Method::Dopri5`] and
///   [`Method::Dop853`] control the step size with `opts.rtol`/`opts.atol`
///   as Hairer's codes do, or take `opts.fixed_step` if it is set (every
///   step accepted; this is how convergence orders are measured). The last
///   step is shortened to land on `t_end` exactly.
/// - After each accepted step [`OdeSystem::after_step`] may project the
///   state, and then [`OdeSystem::guard`] is watched (always in this order,
///   on the projected state): a sign change from `> 0` to `<= 0` is located
///   on the step polynomial and ends the run with
///   [`IntegrateError::Stopped`] there.
/// - Tolerances: `rtol >= 100 ε ≈ 2.2e-14`, `atol` (or
///   `Options::atol_components`, per component) positive and finite, else
///   [`IntegrateError::InvalidInput`]; so is a non-finite `f(t0, y0)`.
/// - `f` failing at a trial stage of an adaptive method rejects the step
///   (`h /= 4`); failing at an accepted state, or at any stage with a fixed
///   step, ends the run with [`IntegrateError::System`].
///
/// Every error comes as a [`Failure`] whose `partial` solution holds the
/// samples, continuous extension and counters up to the error time, which
/// is also `partial.t_last`. See the documentation of the methods in
/// `src/explicit/` and `src/radau/` for orders, defaults and counters.
///
/// [`Method::Radau5`] solves the stiff ODE with Radau IIA as RADAU5 does:
/// the Jacobian comes from [`OdeSystem::jacobian`] or from forward
/// differences; a stage that cannot be evaluated, a Newton iteration that
/// fails and a singular iteration matrix reject the step (`h /= 2`).
///
/// This is the loop over the solver state's `step()`:
/// `Solver::new(method, ..)?.solve()` (see [`StopReason`]).
pub fn solve<S: OdeSystem + ?Sized>(
    method: Method,
    sys: &mut S,
    t0: f64,
    y0: &[f64],
    t_end: f64,
    opts: &Options,
) -> Result<Solution, Failure> {
    match method {
        Method::Radau5 | Method::Rk4 | Method::Dopri5 | Method::Dop853 => {
            Solver::new(method, sys, t0, y0, t_end, opts)?.solve()
        }
    }
}

/// Integrates the implicit system `F(t, y, y') = 0` from consistent initial
/// values `(t0, y0, y'0)` to `t_end` with Radau IIA (order 5).
///
/// The initial values must satisfy `F(t0, y0, y'0) = 0` and every hidden
/// constraint of the system; they are checked (`F` only: every
/// `|F_i(t0, y0, y'0)| <= atol + rtol·|y0_i|`, else
/// [`IntegrateError::InvalidInput`] naming the largest residual component)
/// and not modified.
///
/// `∂F/∂y` and `∂F/∂y'` come from [`ImplicitSystem::jacobians`]; the index
/// classes of [`ImplicitSystem::variable_index`] scale the error estimate of
/// index-2 and index-3 components by `h` and `h²`. Output grid, continuous
/// extension, projection, guard, budgets and failures are as for [`solve`];
/// `rhs_evals` counts evaluations of `F`. Method, error estimate and
/// counters: see `src/radau/mod.rs`. This is
/// `Solver::implicit(..)?.solve()`, the loop over its `step()`.
pub fn solve_implicit<S: ImplicitSystem + ?Sized>(
    sys: &mut S,
    t0: f64,
    y0: &[f64],
    yp0: &[f64],
    t_end: f64,
    opts: &Options,
) -> Result<Solution, Failure> {
    Solver::implicit(sys, t0, y0, yp0, t_end, opts)?.solve()
}
