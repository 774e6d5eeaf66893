//! RADAU5 — the implicit Runge–Kutta method Radau IIA of order 5 with
//! step-size control and continuous output, for stiff ODEs `y' = f(t, y)`
//! ([`crate::solve`] with [`Method::Radau5`]) and fully implicit systems
//! `F(t, y, y') = 0`, including differential-algebraic equations of index
//! up to 3 ([`crate::solve_implicit`]).
//!
//! **Reference.** E. Hairer & G. Wanner, *Solving Ordinary Differential
//! Equations II. Stiff and Differential-Algebraic Problems*, 2nd ed.,
//! Springer 1996: §IV.5 (the method), §IV.8 (this implementation), §VI.15
//! (order reduction), §VII.4 and §VII.8 (DAEs); and their code `radau5.f`
//! (version of July 9, 1996, latest correction January 18, 2002;
//! subroutines `RADAU5`, `RADCOR`, `ESTRAD`, `CONTR5`), whose structure,
//! constants and defaults are followed here. The code is written anew; the
//! constants are checked by the unit tests of `tableau.rs`.
//!
//! # Method
//!
//! Three stages, nodes `c = ((4 − √6)/10, (4 + √6)/10, 1)`, the Radau IIA
//! matrix `A` (collocation at the `c_i`), weights `b` = last row of `A`
//! (stiffly accurate). Order 5, stage order 3, L-stable. With `Z_i = Y_i − y_n`
//! the stage increments, the collocation polynomial `u` of degree 3 through
//! `(t_n, y_n)` and `(t_n + c_i h, Y_i)` has derivatives
//! `Y'_i = u'(t_n + c_i h) = h⁻¹ Σ_j (A⁻¹)_ij Z_j` at the nodes (since
//! `Z = h (A ⊗ I) Y'`). The stage equations of `F(t, y, y') = 0` are
//!
//! ```text
//! G_i(Z) = F(t_n + c_i h, y_n + Z_i, h⁻¹ Σ_j (A⁻¹)_ij Z_j) = 0,   i = 1, 2, 3,
//! y_{n+1} = y_n + Z_3,   y'_{n+1} = Y'_3.
//! ```
//!
//! For an ODE, `F = y' − f(t, y)`, they are the usual `Z = h (A ⊗ I) f(Y)`;
//! RADAU5's `M y' = f(t, y)` is `F = M y' − f`.
//!
//! **Simplified Newton iteration.** `J = ∂F/∂y` and `J' = ∂F/∂y'` are taken
//! at `(t_n, y_n, y'_n)` and frozen for the step (and beyond, see below):
//! `(I ⊗ J + h⁻¹ A⁻¹ ⊗ J') ΔZ = −G(Z)`. `A⁻¹` has one real eigenvalue
//! `γ = 3.6378…` and a complex pair `α ± iβ = 2.6811… ± 3.0504…i`; with
//! RADAU5's `T` (`T⁻¹ A⁻¹ T = Λ = [[γ, 0, 0], [0, α, −β], [0, β, α]]`) and
//! `W = (T⁻¹ ⊗ I) Z` the iteration reads
//! `(I ⊗ J + h⁻¹ Λ ⊗ J') ΔW = −(T⁻¹ ⊗ I) G(Z) =: −R`, which decouples into
//! one real and one complex linear system of size `n`:
//!
//! ```text
//! (γ/h J' + J) ΔW_1 = −R_1,      ((α + iβ)/h J' + J) (ΔW_2 + iΔW_3) = −(R_2 + iR_3).
//! ```
//!
//! `W` is the iterated quantity; `Z = (T ⊗ I) W` and
//! `Y'_i = h⁻¹ ((T Λ ⊗ I) W)_i`. Both matrices are factored by dense LU
//! with partial pivoting (`linalg.rs`) whenever `J` or `h` changes.
//!
//! - Starting values: zero at the first step; afterwards the collocation
//!   polynomial of the last accepted step, extrapolated to the new nodes.
//! - Convergence (RADAU5's `θ`, `η`): with `‖·‖` the RMS norm of `ΔW/sc`
//!   over the `3n` components (scale `sc` below), `θ_k = ‖ΔW^k‖/‖ΔW^{k−1}‖`
//!   (from the third iteration the geometric mean of the last two
//!   quotients) and `η = θ/(1 − θ)` (`FACCON`; the first iteration of a step
//!   uses `max(η_old, uround)^0.8`). The iteration stops when
//!   `η ‖ΔW^k‖ <= newton_tol`. It fails when `θ >= 0.99` (divergence) or
//!   after `newton_max_iter` iterations (the step is retried with `h/2`),
//!   and it gives up early when the predicted final correction
//!   `η ‖ΔW^k‖ θ^(NIT−1−k) / newton_tol >= 1`: the step is retried with `h`
//!   times `0.8·q^(−1/(4+NIT−1−k))`, `q` that prediction clamped to
//!   `[1e-4, 20]`.
//! - Jacobian reuse (RADAU5's `THET` logic): after an accepted step a new
//!   Jacobian is computed only if the last iteration converged with
//!   `θ > jacobian_reuse`; otherwise `J` is kept and only the matrices are
//!   refactored if `h` changes — and `h` is not changed at all when the
//!   proposed ratio `h_new/h` lies in `keep_step = [lo, hi]`. After a
//!   rejection `J` is recomputed only if it was not taken at the current
//!   state.
//!
//! **Full Newton iteration** (`Options::radau_newton =`
//! [`RadauNewton::Full`]). The same stage equations, unknowns `Z`, same
//! starting values; each iteration evaluates `J_k`, `J'_k` at the three
//! stage points `(t_n + c_k h, y_n + Z_k, Y'_k)`, `Y'_k = h⁻¹ Σ_j (A⁻¹)_kj Z_j`
//! (`A⁻¹ = T Λ T⁻¹`), forms the `3n × 3n` matrix
//!
//! ```text
//! ∂G_k/∂Z_j = δ_kj J_k + h⁻¹ (A⁻¹)_kj J'_k        (J'_k = I for an ODE)
//! ```
//!
//! and solves `(∂G/∂Z) ΔZ = −G(Z)` by real LU with partial pivoting (its
//! workspace allocated once per run). With a fixed step there is no error
//! estimate, hence no step-start Jacobian nor `n × n` factorisation. For an ODE without
//! [`OdeSystem::jacobian`] the stage Jacobians come from forward
//! differences around `f(Y_k) = Y'_k − G_k`. The monitor above is applied
//! unchanged to `ΔW = (T⁻¹ ⊗ I) ΔZ` in the same norm, so `θ`, `η`,
//! `newton_tol` and `newton_max_iter` mean the same; convergence is
//! quadratic near the solution. A singular `3n × 3n` matrix is handled as
//! a singular iteration matrix (`h/2`, at most 5 in a row). Jacobian reuse
//! and `keep_step` do not apply: after every accepted step `J`, `J'` are
//! evaluated anew at the step start and `γ/h J' + J` is factored for the
//! error estimate below (the complex matrix is not needed).
//!
//! Why: for fully implicit index-3 systems outside Hessenberg form (λ or
//! accelerations in the position-level equations, state-dependent
//! singular `∂F/∂y'`), the change of the Jacobian across the step, `O(h)`,
//! is amplified by the inverse of the iteration matrix so that the
//! simplified iteration's contraction factor does not decrease with `h`
//! and can reach 1 (measured in `tests/radau.rs` on a pendulum whose
//! equations are mixed by a state-dependent matrix: the simplified
//! iteration fails at every step size, the full one converges in 1–2
//! iterations).
//!
//! # Error estimate
//!
//! RADAU5 (`ESTRAD`; Hairer & Wanner (IV.8.19)–(IV.8.20)) estimates for
//! `M y' = f`
//!
//! ```text
//! err = (γ/h M − ∂f/∂y)⁻¹ (f(t_n, y_n) + M h⁻¹ Σ_i dd_i Z_i),
//! dd = (−(13 + 7√6)/3, (−13 + 7√6)/3, −1/3),
//! ```
//!
//! (the `γ0`-term of the embedded formula `f(t_n, y_n)`, filtered by
//! `(γ/h M − ∂f/∂y)⁻¹ = (h/γ)(M − (h/γ) ∂f/∂y)⁻¹`; `y'_n + h⁻¹ Σ dd_i Z_i`
//! vanishes for cubic solutions, so `err = O(h⁴)`). For `F(t, y, y') = 0`
//! the matrix becomes `γ/h J' + J`, and for `F = M y' − f` every `y'`
//! satisfies `f(t_n, y_n) = J' y' − F(t_n, y_n, y')`. So the implicit form
//! uses
//!
//! ```text
//! err = (γ/h J' + J)⁻¹ (J' (y'_n + h⁻¹ Σ_i dd_i Z_i) − F(t_n, y_n, y'_n)),
//! ```
//!
//! which is RADAU5's estimate exactly when `F = M y' − f`, whatever `y'_n`.
//! `y'_n` is: for an ODE `f(t_n, y_n)` (one `f` per step, as in RADAU5, and
//! the residual term vanishes); for an implicit system the given consistent
//! `y'0` at `t0`, afterwards `Y'_3` of the previous step, the derivative of
//! its collocation polynomial at its end (a consistent derivative cannot be
//! computed when `J'` is singular), with `F(t_n, y_n, y'_n)` evaluated once
//! per step: it is the Newton residual of the last stage, or the
//! inconsistency a projection introduced. At the first step and after a
//! rejection an estimate `>= 1` is filtered once more, with
//! `F(t_n, y_n + err, y'_n)` in place of `F(t_n, y_n, y'_n)` (RADAU5:
//! `f(t_n, y_n + err)`).
//!
//! The step is accepted when `‖err‖ = max(sqrt(Σ (err_i/sc_i)²/n), 1e-10)
//! < 1`, with `sc_i = atol' + rtol'·|y_n,i|` for index-1 variables,
//! `sc_i/h` for index-2 and `sc_i/h²` for index-3 variables
//! ([`crate::ImplicitSystem::variable_index`]; `radau5.f` divides its
//! `SCAL` by `h` and `h²`, i.e. "the index 2 variables are multiplied by h,
//! the index 3 variables by h**2" in estimating the error; the same scale
//! serves the Newton norm). RADAU5's tolerance transformation is applied:
//! `rtol' = 0.1·rtol^(2/3)`, `atol' = rtol'·atol/rtol`, so that the global
//! error comes out near `rtol`.
//!
//! **Index-3 caveat (measured, see `tests/radau.rs`).** In that h-scaled norm
//! the Newton iteration may leave errors of size `newton_tol·sc/h` in the
//! index-2 variables, which accumulate into the positions: on the
//! Cartesian pendulum at tol 1e-8 the positions are off by 7.6e-6 with the
//! default `newton_tol`, by 2.5e-9 at tol 1e-10 with `newton_tol = 1e-6`.
//! Tighten `newton_tol` when positions must meet the tolerance. (The full
//! Newton iteration, converging quadratically, overshoots its stopping
//! test: 1.1e-7 at tol 1e-8 with the default `newton_tol`.)
//!
//! # Step-size control
//!
//! As RADAU5: `fac = min(safe, cfac/(newt + 2·NIT))` with `safe = 0.9`,
//! `cfac = safe·(1 + 2·NIT)` (`newt` Newton iterations of the step),
//! `quot = clamp(‖err‖^(1/4)/fac, 1/8, 5)`, `h_new = h/quot` (so
//! `0.2 <= h_new/h <= 8`). From the second accepted step on, Gustafsson's
//! predictive controller: `quot = max(quot, clamp((h_acc/h)·(‖err‖²/err_acc)^(1/4)/safe, 1/8, 5))`
//! with the previous accepted `h_acc`, `err_acc = max(‖err‖, 1e-2)`. A
//! rejected step is retried with `h_new` (`h/10` at the first step); the
//! step after a rejection may not grow; `h <= h_max`; a step that would
//! reach beyond `t_end` (`t + h_new >= t_end`, or `t + 1.0001 h >= t_end`
//! at the start) lands on `t_end`.
//!
//! **Initial step**: `Options::h_init`, else for ODEs Hairer's `HINIT`
//! with the exponent 4 of the error estimate (one `f`), for implicit
//! systems `HINIT`'s first guess `0.01‖y0‖/‖y'0‖` (weighted norms; `1e-6`
//! if either is tiny).
//!
//! **Fixed step** (`Options::fixed_step`, used to measure orders): every
//! step is accepted, no error estimate; the Newton iteration runs to
//! `newton_tol` without the early give-up; a failure is retried once with a
//! fresh Jacobian and then ends the run.
//!
//! # Continuous output
//!
//! The collocation polynomial (order 3 inside the step, `CONTR5`), stored in
//! the nested form of [`Dense`] (`y_n + s(b + (1 − s)(c + s d))`, converted
//! from the values at the nodes) for `Options::dense`, output samples,
//! guard location and the Newton starting values.
//!
//! # Options (all of [`Options`])
//!
//! | option | meaning here | default |
//! |---|---|---|
//! | `rtol`, `atol` | tolerances, transformed as above | `1e-6`, `1e-6` |
//! | `fixed_step` | fixed step mode | `None` |
//! | `h_init` | first step | `HINIT` / first guess |
//! | `h_max` | largest step | `t_end − t0` |
//! | `max_steps` | budget on trial steps (accepted + rejected) | `10⁷` |
//! | `max_wall_time_s` | budget, checked every 8 trial steps | `None` |
//! | `output`, `dense` | samples and continuous extension, as for the explicit methods | `[]`, `true` |
//! | `newton_max_iter` | `NIT` | 7 |
//! | `newton_tol` | `FNEWT` | `max(10·uround/rtol', min(0.03, sqrt(rtol')))`, uround = 1e-16 |
//! | `jacobian_reuse` | `THET` (negative: new Jacobian every step) | `0.001` |
//! | `keep_step` | `(QUOT1, QUOT2)` | `(1.0, 1.2)` |
//! | `radau_newton` | simplified (RADAU5) or full Newton iteration | `Simplified` |
//! | `atol_components` | per-component `atol` (transformed like `atol`) | `None` |
//!
//! # Counters ([`Stats`])
//!
//! - `steps`: accepted steps.
//! - `rejected_steps`: every trial step not accepted — error test failed,
//!   Newton failure, `f`/`F` failed or not finite at a stage, singular
//!   iteration matrix (RADAU5's `NREJCT` counts only the first kind, after
//!   the first accepted step); `steps + rejected_steps` is RADAU5's `NSTEP`.
//! - `rhs_evals`: evaluations of `f` (ODE) or `F` (implicit): 3 per Newton
//!   iteration; 1 at each accepted state except the final one (`t0`
//!   included: for implicit systems that is the consistency check); 1 for
//!   `HINIT` (ODE, no `h_init`); `n` per finite-difference Jacobian; 1 per
//!   second filtering of the error estimate.
//! - `jacobian_evals`: evaluations of `J` (and `J'`), analytic or by finite
//!   differences. ODEs without [`OdeSystem::jacobian`] use forward
//!   differences with RADAU5's increment `sqrt(uround·max(1e-5, |y_j|))`.
//!   Full Newton: 3 per iteration (stage points) plus 1 per accepted step
//!   (step start, for the error estimate; none with a fixed step).
//! - `lu_decompositions`: factorisations of the pair — the real and the
//!   complex matrix together count once (RADAU5's `NDEC`). Full Newton: 1
//!   per iteration (the `3n × 3n` matrix) plus 1 per step size and
//!   step-start Jacobian (`γ/h J' + J`, error estimate; none with a fixed
//!   step).
//! - `newton_iterations`: all Newton iterations, converged or not.
//! - `dense_rhs_evals`: 0 (the collocation polynomial costs nothing).
//! - `newton_failures`: trial steps given up by the Newton iteration
//!   (divergence, no convergence in `newton_max_iter` iterations, or
//!   predicted too slow); each is also a rejected step, except in fixed-step
//!   mode, where the single retry with a fresh Jacobian is not.
//! - `stiffness_detected`: always `None`; `wall_time_s`: as usual.
//!
//! # The step loop and its failures
//!
//! Every failure is a [`Failure`] whose partial solution holds the samples,
//! step polynomials and counters up to `error.time()`.
//!
//! - [`IntegrateError::InvalidInput`] (before any step): the checks of the
//!   explicit methods, `newton_max_iter = 0`, `newton_tol` not positive,
//!   `jacobian_reuse >= 1`, `keep_step` not around 1, `y'0` of the wrong
//!   length or not finite, a `variable_index` outside 1–3, and — after one
//!   evaluation of `F` — inconsistent initial values: some
//!   `|F_i(t0, y0, y'0)| > atol_i + rtol·|y0_i|` (equation `i` paired with
//!   variable `i`, as in semi-explicit systems); the message names the
//!   component with the largest ratio. For an ODE, a non-finite `f(t0, y0)`.
//! - [`IntegrateError::Stopped`]: the guard changed from `> 0` to `<= 0`
//!   across a step; located on the collocation polynomial as for the
//!   explicit methods.
//! - [`IntegrateError::StepSizeTooSmall`]: `h < max(16 ε |t|, floor)`,
//!   `floor = 16 ε min(1e-6 (t_end − t0), h_first)` (as for the explicit
//!   methods) after rejections (e.g. at a singularity of the solution).
//! - [`IntegrateError::TooManySteps`], [`IntegrateError::TimeBudgetExceeded`].
//! - [`IntegrateError::NonFinite`]: the new state, `f` there, or a Jacobian
//!   is not finite; with a fixed step also a stage. (With step control a
//!   non-finite stage or estimate only rejects the step, `h/2`; if the step
//!   size then falls below the floor right after such a rejection, the run
//!   ends with `NonFinite` rather than `StepSizeTooSmall`.) Also a zero or
//!   non-finite initial step from `HINIT` (its weighted norms overflowed).
//! - [`IntegrateError::System`]: `f`/`F` or the Jacobian fails at an
//!   accepted state, `after_step` fails, a stage keeps failing down to the
//!   smallest step (each failure halves `h`) or fails with a fixed step; the
//!   iteration matrix is singular 5 times in a row (once with a fixed step;
//!   otherwise each time `h/2`), or the Newton iteration does not converge
//!   with a fixed step even with a fresh Jacobian (full Newton: at once,
//!   a fresh Jacobian would change nothing).
//!
//! **Projection** ([`OdeSystem::after_step`], [`ImplicitSystem::after_step`]):
//! for ODEs `f` is evaluated at the projected state anyway (it is the next
//! `y'_n`): no extra cost. For implicit systems `y'` stays the derivative of
//! the collocation polynomial (it cannot be recomputed when `J'` is
//! singular; it is the derivative of the polynomial translated onto the
//! projected point), and `F(t, y_projected, y')`, evaluated as at every
//! accepted state, carries the inconsistency into the next error estimate.
//!
//! **Order of calls** after an accepted step: `after_step` first, then the
//! guard on the state it left (the contract stated on the traits).
//!
//! Workspaces (Jacobians, both factorisations, the full-Newton matrix, stage
//! vectors) are allocated once per run; the step loop allocates only when it stores samples and
//! step polynomials.

mod linalg;
mod problem;
mod tableau;

use std::time::Instant;

use crate::driver::{Record, StepFloor, atol_vector, fixed_step_count, guard_crossing, validate};
use crate::explicit::control::{Tol, all_finite};
use crate::{
    Dense, Failure, ImplicitSystem, IntegrateError, Method, OdeSystem, Options, RadauNewton,
    Solution, Stats, SystemError,
};
use linalg::{ComplexLu, RealLu};
use problem::{Dae, Ode, Problem, UROUND};
use tableau::Tableau;

pub(crate) fn solve_ode<S: OdeSystem + ?Sized>(
    sys: &mut S,
    t0: f64,
    y0: &[f64],
    t_end: f64,
    opts: &Options,
) -> Result<Solution, Failure> {
    let mut p = Ode::new(sys);
    run(&mut p, t0, y0, None, t_end, opts)
}

pub(crate) fn solve_implicit<S: ImplicitSystem + ?Sized>(
    sys: &mut S,
    t0: f64,
    y0: &[f64],
    yp0: &[f64],
    t_end: f64,
    opts: &Options,
) -> Result<Solution, Failure> {
    let mut p = Dae { sys, evals: 0 };
    run(&mut p, t0, y0, Some(yp0), t_end, opts)
}

/// Number of coefficient vectors of the collocation polynomial in the
/// nested form of [`Dense`].
const NCOEF: usize = 4;

/// Settings of the Newton iteration.
#[derive(Debug, Clone, Copy)]
struct NewtonParams {
    /// `NIT`.
    nit: usize,
    /// `FNEWT`.
    fnewt: f64,
    /// `THET`.
    thet: f64,
    /// Fixed step: no step-size reduction is possible, so the prediction
    /// "will not converge in time" (`DYTH >= 1`) does not stop the iteration.
    fixed: bool,
}

/// Outcome of the Newton iteration of a trial step.
enum Newton {
    /// Converged after this many iterations.
    Converged(usize),
    /// Converging, but predicted not to reach `FNEWT` within `NIT`
    /// iterations: RADAU5 retries with `h` times this factor.
    Slow(f64),
    /// Diverged (`θ >= 0.99`) or not converged after `NIT` iterations.
    Failed,
    /// `F` could not be evaluated at a stage.
    Stage(SystemError),
    /// A residual or a Newton correction is not finite (full Newton: also
    /// a stage Jacobian).
    NonFinite,
    /// Full Newton: the `3n × 3n` matrix is singular.
    Singular,
}

/// Workspaces of the full Newton iteration (`RadauNewton::Full`).
struct FullNewton {
    /// `∂G/∂Z`, `3n × 3n`, row block `k` = stage equation `k`, column
    /// block `j` = `Z_j`; factored in place.
    lu: RealLu,
    /// `J_k`, `J'_k` at the current stage point (`J'_k` empty for explicit
    /// ODEs, where `J' = I`).
    jy: Vec<f64>,
    jyp: Vec<f64>,
    /// `−G(Z)`, then the correction `ΔZ` (stage-major, length `3n`).
    rhs: Vec<f64>,
}

/// RADAU5's convergence monitor of one Newton iteration.
struct Monitor {
    /// Corrections computed so far.
    newt: usize,
    /// Norm of the previous correction.
    dynold: f64,
    /// Previous quotient of successive norms.
    thqold: f64,
}

/// Workspaces and the per-run state of the core, allocated once per run.
struct Work {
    n: usize,
    tab: Tableau,
    /// `J = ∂F/∂y`, row-major.
    jy: Vec<f64>,
    /// `J' = ∂F/∂y'` (empty for explicit ODEs, where `J' = I`).
    jyp: Vec<f64>,
    /// `γ/h J' + J`, factored.
    e1: RealLu,
    /// `(α + iβ)/h J' + J`, factored.
    e2: ComplexLu,
    /// Transformed stage increments `W = (T⁻¹ ⊗ I) Z`.
    w: [Vec<f64>; 3],
    /// Stage increments `Z_i = Y_i − y_n`.
    z: [Vec<f64>; 3],
    /// Stage residuals, then the Newton corrections `ΔW`.
    dw: [Vec<f64>; 3],
    /// Stage state and derivative.
    ys: Vec<f64>,
    yps: Vec<f64>,
    /// The three stage derivatives `Y'_k` of a simplified Newton iteration.
    yp_stage: [Vec<f64>; 3],
    /// Error scale of the current step (index-2/3 components divided by `h`, `h²`).
    scal: Vec<f64>,
    /// Error estimate and its right-hand side.
    err: Vec<f64>,
    err_rhs: Vec<f64>,
    /// Collocation polynomial of the last converged step (nested form).
    coef: Vec<f64>,
    /// `y'` at the end of the last converged step: `h⁻¹ (A⁻¹ Z)_3`.
    yp_new: Vec<f64>,
    /// `FACCON`: `θ/(1 − θ)` of the last iteration (kept across steps).
    faccon: f64,
    /// `θ`, the contraction rate of the last Newton iteration.
    theta: f64,
    /// Full Newton workspaces (`None` in simplified mode).
    full: Option<FullNewton>,
}

impl Work {
    fn new(n: usize, identity_jp: bool, full: bool) -> Self {
        let v = || vec![0.0; n];
        Work {
            n,
            tab: Tableau::new(),
            jy: vec![0.0; n * n],
            jyp: if identity_jp {
                Vec::new()
            } else {
                vec![0.0; n * n]
            },
            e1: RealLu::new(n),
            e2: ComplexLu::new(n),
            w: [v(), v(), v()],
            z: [v(), v(), v()],
            dw: [v(), v(), v()],
            ys: v(),
            yps: v(),
            yp_stage: [v(), v(), v()],
            scal: v(),
            err: v(),
            err_rhs: v(),
            coef: vec![0.0; NCOEF * n],
            yp_new: v(),
            faccon: 1.0,
            theta: 0.0,
            full: full.then(|| FullNewton {
                lu: RealLu::new(3 * n),
                jy: vec![0.0; n * n],
                jyp: if identity_jp {
                    Vec::new()
                } else {
                    vec![0.0; n * n]
                },
                rhs: vec![0.0; 3 * n],
            }),
        }
    }

    /// Forms `γ/h J' + J` and `(α + iβ)/h J' + J` and factors them; in full
    /// Newton mode only the first, which the error estimate needs.
    fn factor(&mut self, h: f64) -> Result<(), usize> {
        let n = self.n;
        // `J' = I` (an explicit ODE) exactly when no `J'` is stored.
        let identity_jp = self.jyp.is_empty();
        let (g, a, b) = (self.tab.gamma / h, self.tab.alpha / h, self.tab.beta / h);
        let complex = self.full.is_none();
        self.e1.a.copy_from_slice(&self.jy);
        if identity_jp {
            for i in 0..n {
                self.e1.a[i * n + i] += g;
            }
        } else {
            for (k, &m) in self.jyp.iter().enumerate() {
                self.e1.a[k] += g * m;
            }
        }
        self.e1.factor()?;
        if !complex {
            return Ok(());
        }
        self.e2.re.copy_from_slice(&self.jy);
        if identity_jp {
            self.e2.im.fill(0.0);
            for i in 0..n {
                self.e2.re[i * n + i] += a;
                self.e2.im[i * n + i] = b;
            }
        } else {
            for (k, &m) in self.jyp.iter().enumerate() {
                self.e2.re[k] += a * m;
                self.e2.im[k] = b * m;
            }
        }
        self.e2.factor()
    }

    /// Error scale of a step of size `h` from the base scale `sk`.
    fn set_scale(&mut self, sk: &[f64], index: &[u8], h: f64) {
        for ((s, &k), &ix) in self.scal.iter_mut().zip(sk).zip(index) {
            *s = match ix {
                1 => k,
                2 => k / h,
                _ => k / (h * h),
            };
        }
    }

    /// Starting values of the Newton iteration: zero, or the collocation
    /// polynomial of the previous step (of size `hold`) extrapolated.
    fn start(&mut self, h: f64, hold: Option<f64>) {
        let n = self.n;
        let Some(hold) = hold else {
            for k in 0..3 {
                self.w[k].fill(0.0);
                self.z[k].fill(0.0);
            }
            return;
        };
        let ti = self.tab.ti;
        let s = self.tab.c.map(|c| 1.0 + c * h / hold);
        for i in 0..n {
            let (b, c, d) = (self.coef[n + i], self.coef[2 * n + i], self.coef[3 * n + i]);
            // p(s) − p(1) = (s − 1)(b − s(c + s d)) in the nested form.
            let z: [f64; 3] = s.map(|s| (s - 1.0) * (b - s * (c + s * d)));
            for k in 0..3 {
                self.z[k][i] = z[k];
                self.w[k][i] = ti[k][0] * z[0] + ti[k][1] * z[1] + ti[k][2] * z[2];
            }
        }
    }

    /// Starts a Newton iteration: RADAU5's `FACCON` for the first
    /// correction, `θ` reset.
    fn begin_newton(&mut self, np: NewtonParams) -> Monitor {
        self.faccon = self.faccon.max(UROUND).powf(0.8);
        self.theta = np.thet.abs();
        Monitor {
            newt: 0,
            dynold: 1.0,
            thqold: 1.0,
        }
    }

    /// The scaled RMS norm of the correction `ΔW` in `dw` over the `3n`
    /// components (RADAU5's `DYNO`).
    fn correction_norm(&self) -> f64 {
        let n = self.n;
        let [d0, d1, d2] = &self.dw;
        let mut dyno = 0.0;
        for i in 0..n {
            let s = self.scal[i];
            dyno += (d0[i] / s).powi(2) + (d1[i] / s).powi(2) + (d2[i] / s).powi(2);
        }
        (dyno / (3 * n) as f64).sqrt()
    }

    /// RADAU5's monitor after correction number `m.newt` of norm `dyno`:
    /// updates `θ` and `η = FACCON`; `Some` ends the iteration (divergence,
    /// predicted too slow, not finite) before the correction is applied.
    fn monitor(&mut self, m: &mut Monitor, dyno: f64, np: NewtonParams) -> Option<Newton> {
        if !dyno.is_finite() {
            return Some(Newton::NonFinite);
        }
        let newt = m.newt;
        if newt > 1 && newt < np.nit {
            let thq = dyno / m.dynold;
            self.theta = if newt == 2 {
                thq
            } else {
                (thq * m.thqold).sqrt()
            };
            m.thqold = thq;
            if self.theta < 0.99 {
                self.faccon = self.theta / (1.0 - self.theta);
                let left = (np.nit - 1 - newt) as i32;
                let dyth = self.faccon * dyno * self.theta.powi(left) / np.fnewt;
                if dyth >= 1.0 && !np.fixed {
                    let qnewt = dyth.clamp(1e-4, 20.0);
                    return Some(Newton::Slow(
                        0.8 * qnewt.powf(-1.0 / (4.0 + f64::from(left))),
                    ));
                }
            } else {
                return Some(Newton::Failed);
            }
        }
        m.dynold = dyno.max(UROUND);
        None
    }

    /// The simplified Newton iteration for the stage equations of the step
    /// `[t, t_new]` of size `h` from `y` (starting values set by [`Work::start`]).
    fn newton<P: Problem>(
        &mut self,
        p: &mut P,
        t: f64,
        y: &[f64],
        h: f64,
        t_new: f64,
        np: NewtonParams,
        stats: &mut Stats,
    ) -> Newton {
        let n = self.n;
        let Tableau {
            c,
            gamma,
            alpha,
            beta,
            t: tm,
            ti,
            ..
        } = self.tab;
        let mut m = self.begin_newton(np);
        loop {
            if m.newt >= np.nit {
                return Newton::Failed;
            }
            // Stage derivatives Y'_k = h⁻¹ (T Λ W)_k, with Λ W formed once per
            // component for the three stages.
            for i in 0..n {
                let (w1, w2, w3) = (self.w[0][i], self.w[1][i], self.w[2][i]);
                let v = [gamma * w1, alpha * w2 - beta * w3, beta * w2 + alpha * w3];
                for k in 0..3 {
                    self.yp_stage[k][i] = (tm[k][0] * v[0] + tm[k][1] * v[1] + tm[k][2] * v[2]) / h;
                }
            }
            // Residuals G_k = F(t + c_k h, y + Z_k, Y'_k).
            for k in 0..3 {
                let tk = if k == 2 { t_new } else { t + c[k] * h };
                for i in 0..n {
                    self.ys[i] = y[i] + self.z[k][i];
                }
                if let Err(e) = p.residual(tk, &self.ys, &self.yp_stage[k], &mut self.dw[k]) {
                    return Newton::Stage(e);
                }
            }
            // Right-hand sides −(T⁻¹ ⊗ I) G, then the two linear systems.
            let [d0, d1, d2] = &mut self.dw;
            for i in 0..n {
                let (g1, g2, g3) = (d0[i], d1[i], d2[i]);
                d0[i] = -(ti[0][0] * g1 + ti[0][1] * g2 + ti[0][2] * g3);
                d1[i] = -(ti[1][0] * g1 + ti[1][1] * g2 + ti[1][2] * g3);
                d2[i] = -(ti[2][0] * g1 + ti[2][1] * g2 + ti[2][2] * g3);
            }
            self.e1.solve(d0);
            self.e2.solve(d1, d2);
            m.newt += 1;
            stats.newton_iterations += 1;
            let dyno = self.correction_norm();
            if let Some(out) = self.monitor(&mut m, dyno, np) {
                return out;
            }
            for i in 0..n {
                let w1 = self.w[0][i] + self.dw[0][i];
                let w2 = self.w[1][i] + self.dw[1][i];
                let w3 = self.w[2][i] + self.dw[2][i];
                self.w[0][i] = w1;
                self.w[1][i] = w2;
                self.w[2][i] = w3;
                for k in 0..3 {
                    self.z[k][i] = tm[k][0] * w1 + tm[k][1] * w2 + tm[k][2] * w3;
                }
            }
            if self.faccon * dyno <= np.fnewt {
                // y' at the end of the step, h⁻¹ (A⁻¹ Z)_3 = h⁻¹ (T Λ W)_3.
                for i in 0..n {
                    let (w1, w2, w3) = (self.w[0][i], self.w[1][i], self.w[2][i]);
                    let v = [gamma * w1, alpha * w2 - beta * w3, beta * w2 + alpha * w3];
                    self.yp_new[i] = (tm[2][0] * v[0] + tm[2][1] * v[1] + tm[2][2] * v[2]) / h;
                }
                return Newton::Converged(m.newt);
            }
        }
    }

    /// The full Newton iteration for the stage equations of the step
    /// `[t, t_new]` of size `h` from `y` (starting values set by
    /// [`Work::start`]): each iteration evaluates `J_k`, `J'_k` at the three
    /// stage points `(t + c_k h, y + Z_k, h⁻¹ (A⁻¹ Z)_k)`, forms
    /// `∂G_k/∂Z_j = δ_kj J_k + h⁻¹ (A⁻¹)_kj J'_k`, factors it and solves
    /// for `ΔZ`. The monitor sees `ΔW = (T⁻¹ ⊗ I) ΔZ` in the same norm as
    /// the simplified iteration, so `newton_tol` means the same in both.
    fn newton_full<P: Problem>(
        &mut self,
        p: &mut P,
        t: f64,
        y: &[f64],
        h: f64,
        t_new: f64,
        np: NewtonParams,
        stats: &mut Stats,
    ) -> Newton {
        let n = self.n;
        let nn = 3 * n;
        let Tableau { c, ti, ainv, .. } = self.tab;
        let mut m = self.begin_newton(np);
        loop {
            if m.newt >= np.nit {
                return Newton::Failed;
            }
            let full = self.full.as_mut().expect("full Newton workspace");
            for k in 0..3 {
                let tk = if k == 2 { t_new } else { t + c[k] * h };
                for i in 0..n {
                    let s = ainv[k][0] * self.z[0][i]
                        + ainv[k][1] * self.z[1][i]
                        + ainv[k][2] * self.z[2][i];
                    self.yps[i] = s / h;
                    self.ys[i] = y[i] + self.z[k][i];
                }
                let gk = &mut self.dw[k];
                if let Err(e) = p.residual(tk, &self.ys, &self.yps, gk) {
                    return Newton::Stage(e);
                }
                if !all_finite(gk) {
                    return Newton::NonFinite;
                }
                stats.jacobian_evals += 1;
                let res = p.jacobians(tk, &self.ys, &self.yps, gk, &mut full.jy, &mut full.jyp);
                if let Err(e) = res {
                    return Newton::Stage(e);
                }
                if !all_finite(&full.jy) || (!P::IDENTITY_JP && !all_finite(&full.jyp)) {
                    return Newton::NonFinite;
                }
                // Row block k: [h⁻¹ (A⁻¹)_k1 J'_k, h⁻¹ (A⁻¹)_k2 J'_k, h⁻¹ (A⁻¹)_k3 J'_k] + J_k
                // in column block k.
                for i in 0..n {
                    let r = k * n + i;
                    let row = &mut full.lu.a[r * nn..(r + 1) * nn];
                    for (j, blk) in row.chunks_exact_mut(n).enumerate() {
                        let a = ainv[k][j] / h;
                        if P::IDENTITY_JP {
                            blk.fill(0.0);
                            blk[i] = a;
                        } else {
                            for (b, &jp) in blk.iter_mut().zip(&full.jyp[i * n..(i + 1) * n]) {
                                *b = a * jp;
                            }
                        }
                        if j == k {
                            for (b, &jv) in blk.iter_mut().zip(&full.jy[i * n..(i + 1) * n]) {
                                *b += jv;
                            }
                        }
                    }
                    full.rhs[r] = -gk[i];
                }
            }
            stats.lu_decompositions += 1;
            if full.lu.factor().is_err() {
                return Newton::Singular;
            }
            full.lu.solve(&mut full.rhs);
            // ΔW = (T⁻¹ ⊗ I) ΔZ for the monitor.
            let dz = &full.rhs;
            for i in 0..n {
                let (a, b, cc) = (dz[i], dz[n + i], dz[2 * n + i]);
                for k in 0..3 {
                    self.dw[k][i] = ti[k][0] * a + ti[k][1] * b + ti[k][2] * cc;
                }
            }
            m.newt += 1;
            stats.newton_iterations += 1;
            let dyno = self.correction_norm();
            if let Some(out) = self.monitor(&mut m, dyno, np) {
                return out;
            }
            let dz = &self.full.as_ref().expect("full Newton workspace").rhs;
            for k in 0..3 {
                for i in 0..n {
                    self.z[k][i] += dz[k * n + i];
                    self.w[k][i] += self.dw[k][i];
                }
            }
            if self.faccon * dyno <= np.fnewt {
                // y' at the end of the step, h⁻¹ (A⁻¹ Z)_3.
                for i in 0..n {
                    let s = ainv[2][0] * self.z[0][i]
                        + ainv[2][1] * self.z[1][i]
                        + ainv[2][2] * self.z[2][i];
                    self.yp_new[i] = s / h;
                }
                return Newton::Converged(m.newt);
            }
        }
    }

    /// Scaled RMS norm of `v`.
    fn norm(&self, v: &[f64]) -> f64 {
        let s: f64 = v
            .iter()
            .zip(&self.scal)
            .map(|(x, s)| (x / s) * (x / s))
            .sum();
        (s / self.n as f64).sqrt()
    }

    /// The error estimate of the converged step (see the module documentation):
    /// `err = (γ/h J' + J)⁻¹ (J' (y'_n + h⁻¹ Σ dd_i Z_i) − F(t_n, y_n, y'_n))`,
    /// with `res = F(t_n, y_n, y'_n)`; when `second` and the first estimate
    /// is `>= 1`, once more with `F(t_n, y_n + err, y'_n)` in place of `res`.
    fn estimate<P: Problem>(
        &mut self,
        p: &mut P,
        t: f64,
        y: &[f64],
        yp: &[f64],
        res: &[f64],
        h: f64,
        second: bool,
    ) -> f64 {
        let n = self.n;
        let dd = self.tab.dd;
        // err_rhs = J'(y'_n + h⁻¹ Σ dd_i Z_i), err = err_rhs − F(t_n, y_n, y'_n).
        for i in 0..n {
            let s = dd[0] * self.z[0][i] + dd[1] * self.z[1][i] + dd[2] * self.z[2][i];
            self.err[i] = yp[i] + s / h;
        }
        if P::IDENTITY_JP {
            self.err_rhs.copy_from_slice(&self.err);
        } else {
            for i in 0..n {
                let row = &self.jyp[i * n..(i + 1) * n];
                self.err_rhs[i] = row.iter().zip(&self.err).map(|(a, b)| a * b).sum();
            }
        }
        for i in 0..n {
            self.err[i] = self.err_rhs[i] - res[i];
        }
        self.e1.solve(&mut self.err);
        let e = self.norm(&self.err).max(1e-10);
        if !(e >= 1.0 && second) {
            return e;
        }
        for i in 0..n {
            self.ys[i] = y[i] + self.err[i];
        }
        if p.residual(t, &self.ys, yp, &mut self.err).is_err() {
            return e;
        }
        for i in 0..n {
            self.err[i] = self.err_rhs[i] - self.err[i];
        }
        self.e1.solve(&mut self.err);
        let e2 = self.norm(&self.err).max(1e-10);
        if e2.is_finite() { e2 } else { e }
    }

    /// The collocation polynomial through `y`, `y + Z_1`, `y + Z_2`, `y + Z_3`
    /// in the nested form `a + s(b + (1 − s)(c + s d))` of [`Dense`].
    fn polynomial(&mut self, y: &[f64]) {
        let n = self.n;
        let [c1, c2, _] = self.tab.c;
        let (w1, w2) = (c1 * (1.0 - c1), c2 * (1.0 - c2));
        for i in 0..n {
            let (z1, z2, z3) = (self.z[0][i], self.z[1][i], self.z[2][i]);
            let q1 = (z1 - c1 * z3) / w1;
            let q2 = (z2 - c2 * z3) / w2;
            let d = (q2 - q1) / (c2 - c1);
            self.coef[i] = y[i];
            self.coef[n + i] = z3;
            self.coef[2 * n + i] = q1 - c1 * d;
            self.coef[3 * n + i] = d;
        }
    }
}

/// Checks the Radau-specific options and the implicit initial data.
fn validate_radau(opts: &Options, yp0: Option<&[f64]>, index: &[u8]) -> Result<(), String> {
    let n = index.len();
    if opts.radau5.newton_max_iter == 0 {
        return Err("newton_max_iter must be at least 1".into());
    }
    if let Some(f) = opts.radau5.newton_tol {
        if !(f > 0.0 && f.is_finite()) {
            return Err(format!("newton_tol = {f} must be positive and finite"));
        }
    }
    if opts.radau5.jacobian_reuse.is_nan() || opts.radau5.jacobian_reuse >= 1.0 {
        return Err(format!(
            "jacobian_reuse = {} must be < 1",
            opts.radau5.jacobian_reuse
        ));
    }
    let (lo, hi) = opts.radau5.keep_step;
    if !(lo > 0.0 && lo <= 1.0 && hi >= 1.0 && hi.is_finite()) {
        return Err(format!(
            "keep_step = ({lo}, {hi}) must satisfy 0 < lo <= 1 <= hi < ∞"
        ));
    }
    if let Some(yp0) = yp0 {
        if yp0.len() != n {
            return Err(format!(
                "yp0 has length {} but the system has dimension {n}",
                yp0.len()
            ));
        }
        if !all_finite(yp0) {
            return Err("yp0 is not finite".into());
        }
    }
    if let Some((i, &ix)) = index
        .iter()
        .enumerate()
        .find(|(_, ix)| !(1..=3).contains(*ix))
    {
        return Err(format!(
            "variable_index[{i}] = {ix}: index classes are 1, 2 or 3"
        ));
    }
    Ok(())
}

/// `Some(message)` if `F(t0, y0, y'0) = res` is not zero within the
/// tolerances: `|F_i| <= atol + rtol·|y0_i|` for every `i`.
fn inconsistency(res: &[f64], y0: &[f64], atol: &[f64], rtol: f64) -> Option<String> {
    let mut worst: Option<(usize, f64)> = None;
    for (i, (&r, &y)) in res.iter().zip(y0).enumerate() {
        let q = r.abs() / (atol[i] + rtol * y.abs());
        if !q.is_finite() {
            return Some(format!(
                "inconsistent initial values: F[{i}](t0, y0, y'0) = {r} is not finite"
            ));
        }
        if worst.is_none_or(|(_, w)| q > w) {
            worst = Some((i, q));
        }
    }
    let (i, q) = worst?;
    (q > 1.0).then(|| {
        format!(
            "inconsistent initial values: |F[{i}](t0, y0, y'0)| = {:e} exceeds atol + rtol·|y0[{i}]| = {:e} \
             (the largest residual component relative to its tolerance)",
            res[i].abs(),
            atol[i] + rtol * y0[i].abs()
        )
    })
}

/// The step loop (see the module documentation).
fn run<P: Problem>(
    p: &mut P,
    t0: f64,
    y0: &[f64],
    yp0: Option<&[f64]>,
    t_end: f64,
    opts: &Options,
) -> Result<Solution, Failure> {
    let start = Instant::now();
    let n = p.dim();
    let mut rec = Record {
        method: Method::Radau5,
        dim: n,
        ncoef: NCOEF,
        grid: Vec::new(),
        next: 0,
        t: Vec::new(),
        y: Vec::new(),
        dense: opts.dense.then(|| Dense::new(n, NCOEF)),
        stats: Stats::default(),
        start,
    };
    let mut index = vec![1u8; n];
    p.variable_index(&mut index);
    if let Err(msg) = validate(Method::Radau5.needs_fixed_step(), n, t0, y0, t_end, opts)
        .and_then(|()| validate_radau(opts, yp0, &index))
    {
        return Err(rec.fail(IntegrateError::InvalidInput(msg), t0, y0, 0));
    }
    let mut y = y0.to_vec();
    let mut yp = vec![0.0; n];
    // F(t_n, y_n, y'_n) at the current state (zero for explicit ODEs).
    let mut res = vec![0.0; n];
    let mut buf = vec![0.0; n];
    let atol_user = atol_vector(opts, n);
    if let Some(yp0) = yp0 {
        yp.copy_from_slice(yp0);
        if let Err(source) = p.residual(t0, y0, yp0, &mut res) {
            let e = IntegrateError::System { t: t0, source };
            return Err(rec.fail(e, t0, y0, p.evals()));
        }
        if let Some(msg) = inconsistency(&res, y0, &atol_user, opts.rtol) {
            return Err(rec.fail(IntegrateError::InvalidInput(msg), t0, y0, p.evals()));
        }
    }
    rec.grid.extend_from_slice(&opts.output);
    if rec.grid.last() != Some(&t_end) {
        rec.grid.push(t_end);
    }

    rec.emit(t0, &y, None, &mut buf);
    let mut g_prev = p.guard(t0, &y);
    if g_prev.is_some_and(|g| g <= 0.0) {
        let reason = p.guard_reason(t0, &y);
        let ev = p.evals();
        return Err(rec.fail(IntegrateError::Stopped { t: t0, reason }, t0, &y, ev));
    }
    if t_end == t0 {
        let ev = p.evals();
        return Ok(rec.finish(t0, &y, ev));
    }
    let mut t = t0;
    if yp0.is_none() {
        let error = match p.accepted_state(t, &y, &mut yp, &mut res) {
            Err(source) => Some(IntegrateError::System { t, source }),
            Ok(()) => yp.iter().position(|v| !v.is_finite()).map(|i| {
                IntegrateError::InvalidInput(format!(
                    "f(t0, y0) is not finite: component {i} is {} at t0 = {t0}",
                    yp[i]
                ))
            }),
        };
        if let Some(e) = error {
            let ev = p.evals();
            return Err(rec.fail(e, t, &y, ev));
        }
    }

    // RADAU5's internal tolerances: rtol' = 0.1 rtol^(2/3), atol' = rtol'·atol/rtol
    // (component by component).
    let rtol = 0.1 * opts.rtol.powf(2.0 / 3.0);
    let atol: Vec<f64> = atol_user.iter().map(|a| rtol * a / opts.rtol).collect();
    let tol = Tol { rtol, atol: &atol };
    let np = NewtonParams {
        nit: opts.radau5.newton_max_iter,
        fnewt: opts
            .radau5
            .newton_tol
            .unwrap_or_else(|| (10.0 * UROUND / rtol).max(0.03f64.min(rtol.sqrt()))),
        thet: opts.radau5.jacobian_reuse,
        fixed: opts.fixed_step.is_some(),
    };
    let (quot1, quot2) = opts.radau5.keep_step;
    // Step-size controller of RADAU5: SAFE, FACL, FACR, CFAC.
    let (safe, facl, facr) = (0.9, 5.0, 1.0 / 8.0);
    let cfac = safe * (1 + 2 * np.nit) as f64;

    let span = t_end - t0;
    let hmax = opts.h_max.unwrap_or(span);
    let fixed = opts.fixed_step.map(|h| (h, fixed_step_count(span, h)));
    let mut w = Work::new(n, P::IDENTITY_JP, opts.radau5.newton == RadauNewton::Full);
    // Full Newton iteration (`RadauNewton::Full`) instead of the simplified one.
    let full = w.full.is_some();
    let mut h = match (fixed, opts.h_init) {
        (Some((h, _)), _) => h,
        (None, Some(h)) => h.min(hmax),
        (None, None) => p.initial_step(t, &y, &yp, hmax, tol, &mut w.ys, &mut w.yps),
    };
    if !(h > 0.0 && h.is_finite()) {
        // Only the initial-step choice can get here: its weighted norms of
        // y'0 overflowed although y'0 is finite.
        let ev = p.evals();
        return Err(rec.fail(IntegrateError::NonFinite { t }, t, &y, ev));
    }
    let floor = StepFloor::new(span, h);
    let h_min = |t: f64| floor.at(t);
    // Base error scale atol' + rtol'·|y_n| of the current state.
    let mut sk: Vec<f64> = (0..n).map(|i| tol.scale(i, y[i], 0.0)).collect();

    let mut need_jac = true;
    // The Jacobian was evaluated at the current state (RADAU5's CALJAC).
    let mut caljac = false;
    // Step size of the current factorisation (NaN: none).
    let mut h_lu = f64::NAN;
    let mut nsing = 0;
    let mut reject = false;
    // The last rejection was caused by a non-finite stage, correction or
    // error estimate: a step-size collapse then is reported as `NonFinite`.
    let mut nonfinite_reject = false;
    let mut last = false;
    // Size of the last accepted step (read only after one), and its error
    // for Gustafsson's controller.
    let mut hold = h;
    let mut erracc = 1e-2;

    // A rejected trial step: counted, retried from the same state with step
    // size `$h` (`$nonfinite`: caused by a non-finite stage, correction or
    // error estimate), with a fresh Jacobian unless the current one was taken
    // at this state.
    macro_rules! retry {
        ($h:expr, $nonfinite:expr) => {{
            rec.stats.rejected_steps += 1;
            (h, reject, last) = ($h, true, false);
            nonfinite_reject = $nonfinite;
            need_jac = !caljac;
            continue;
        }};
    }

    loop {
        if let Some(e) = rec.budget_exceeded(opts, t, h, None) {
            let ev = p.evals();
            return Err(rec.fail(e, t, &y, ev));
        }
        let t_new = match fixed {
            Some((hf, nsteps)) => {
                let k = rec.stats.steps + 1;
                last = k >= nsteps;
                let t_new = if last { t_end } else { t0 + k as f64 * hf };
                h = t_new - t;
                t_new
            }
            None => {
                if h.abs() < h_min(t) {
                    let e = if nonfinite_reject {
                        IntegrateError::NonFinite { t }
                    } else {
                        IntegrateError::StepSizeTooSmall { t, h }
                    };
                    let ev = p.evals();
                    return Err(rec.fail(e, t, &y, ev));
                }
                if t + 1.0001 * h - t_end >= 0.0 {
                    h = t_end - t;
                    last = true;
                }
                match rec.next_time() {
                    // Land on the next output time (`Options::hit_output`).
                    Some(tau) if opts.hit_output && !last && tau > t && t + 1.0001 * h >= tau => {
                        h = tau - t;
                        tau
                    }
                    _ if last => t_end,
                    _ => t + h,
                }
            }
        };

        // Full Newton with a fixed step needs neither: no error estimate.
        let step_start_matrix = !(full && fixed.is_some());
        if need_jac && step_start_matrix {
            rec.stats.jacobian_evals += 1;
            let jac = p.jacobians(t, &y, &yp, &res, &mut w.jy, &mut w.jyp);
            let error = match jac {
                Err(source) => Some(IntegrateError::System { t, source }),
                Ok(()) if !all_finite(&w.jy) || !all_finite(&w.jyp) => {
                    Some(IntegrateError::NonFinite { t })
                }
                Ok(()) => None,
            };
            if let Some(e) = error {
                let ev = p.evals();
                return Err(rec.fail(e, t, &y, ev));
            }
            caljac = true;
            h_lu = f64::NAN;
        }
        // NaN (no factorisation) compares false: factor.
        let factored = !step_start_matrix || (h - h_lu).abs() <= 1e-12 * h.abs();
        if !factored {
            rec.stats.lu_decompositions += 1;
            if w.factor(h).is_err() {
                nsing += 1;
                if nsing >= 5 || fixed.is_some() {
                    let source = SystemError::new(format!(
                        "Radau5: the iteration matrix γ/h·∂F/∂y' + ∂F/∂y is singular \
                         (h = {h:e}, {nsing} time(s) in a row)"
                    ));
                    let ev = p.evals();
                    return Err(rec.fail(IntegrateError::System { t, source }, t, &y, ev));
                }
                h_lu = f64::NAN;
                retry!(0.5 * h, false);
            }
            h_lu = h;
        }

        w.set_scale(&sk, &index, h);
        // No step accepted yet: the first step (RADAU5's FIRST).
        let first = rec.stats.steps == 0;
        w.start(h, (!first).then_some(hold));
        let outcome = if full {
            w.newton_full(p, t, &y, h, t_new, np, &mut rec.stats)
        } else {
            w.newton(p, t, &y, h, t_new, np, &mut rec.stats)
        };
        let newt = match outcome {
            Newton::Converged(newt) => newt,
            Newton::Stage(source) => {
                if fixed.is_some() || 0.5 * h.abs() < h_min(t) {
                    let ev = p.evals();
                    return Err(rec.fail(IntegrateError::System { t, source }, t, &y, ev));
                }
                retry!(0.5 * h, false);
            }
            Newton::NonFinite => {
                if fixed.is_some() {
                    let ev = p.evals();
                    return Err(rec.fail(IntegrateError::NonFinite { t }, t, &y, ev));
                }
                retry!(0.5 * h, true);
            }
            Newton::Singular => {
                nsing += 1;
                if nsing >= 5 || fixed.is_some() {
                    let source = SystemError::new(format!(
                        "Radau5: the full Newton matrix ∂G/∂Z of the stage equations is \
                         singular (h = {h:e}, {nsing} time(s) in a row)"
                    ));
                    let ev = p.evals();
                    return Err(rec.fail(IntegrateError::System { t, source }, t, &y, ev));
                }
                retry!(0.5 * h, false);
            }
            Newton::Failed => {
                rec.stats.newton_failures += 1;
                if fixed.is_some() {
                    // A fresh Jacobian cannot change a full Newton iteration.
                    if caljac || full {
                        let kind = if full { "full" } else { "simplified" };
                        let source = SystemError::new(format!(
                            "Radau5: the {kind} Newton iteration does not converge \
                             with the fixed step h = {h:e}"
                        ));
                        let ev = p.evals();
                        return Err(rec.fail(IntegrateError::System { t, source }, t, &y, ev));
                    }
                    // Retry the same step with a fresh Jacobian.
                    need_jac = true;
                    continue;
                }
                retry!(0.5 * h, false);
            }
            Newton::Slow(fac) => {
                rec.stats.newton_failures += 1;
                retry!(fac * h, false);
            }
        };

        // Error estimate and the next step size (adaptive only).
        let mut h_new = h;
        if fixed.is_none() {
            let err = w.estimate(p, t, &y, &yp, &res, h, first || reject);
            if !err.is_finite() {
                retry!(0.5 * h, true);
            }
            // The safety factor decreases with the number of Newton iterations.
            let fac = safe.min(cfac / (newt + 2 * np.nit) as f64);
            let mut quot = (err.powf(0.25) / fac).clamp(facr, facl);
            h_new = h / quot;
            if err >= 1.0 {
                retry!(if first { 0.1 * h } else { h_new }, false);
            }
            // Gustafsson's predictive controller.
            if rec.stats.steps >= 1 {
                let facgus =
                    ((hold / h) * (err * err / erracc).powf(0.25) / safe).clamp(facr, facl);
                quot = quot.max(facgus);
                h_new = h / quot;
            }
            erracc = err.max(1e-2);
        }

        // The step is accepted.
        rec.stats.steps += 1;
        nonfinite_reject = false;
        nsing = 0;
        w.polynomial(&y);
        if let Some(d) = rec.dense.as_mut() {
            d.push(t, h, &w.coef);
        }
        let t_old = t;
        t = t_new;
        hold = h;
        for (yi, zi) in y.iter_mut().zip(&w.z[2]) {
            *yi += zi;
        }
        // y'_{n+1} = Y'_3 for implicit systems; an ODE gets f(t, y) below.
        if !P::IDENTITY_JP {
            yp.copy_from_slice(&w.yp_new);
        }
        let poly = Some((&w.coef[..], t_old, h));

        let error = match p.after_step(t, &mut y) {
            Err(source) => Some(IntegrateError::System { t, source }),
            Ok(_) if !all_finite(&y) => Some(IntegrateError::NonFinite { t }),
            Ok(_) if last => None,
            Ok(_) => match p.accepted_state(t, &y, &mut yp, &mut res) {
                Err(source) => Some(IntegrateError::System { t, source }),
                Ok(()) if !all_finite(&yp) || !all_finite(&res) => {
                    Some(IntegrateError::NonFinite { t })
                }
                Ok(()) => None,
            },
        };
        if let Some(e) = error {
            rec.emit(t, &y, poly, &mut buf);
            let ev = p.evals();
            return Err(rec.fail(e, t, &y, ev));
        }
        caljac = false;
        for (i, (s, &v)) in sk.iter_mut().zip(&y).enumerate() {
            *s = tol.scale(i, v, 0.0);
        }

        let crossing = guard_crossing(
            |tg, yg| p.guard(tg, yg),
            &mut g_prev,
            &w.coef,
            NCOEF,
            t_old,
            t,
            h,
            &y,
            &mut w.ys,
            &mut buf,
        );
        if let Some(t_root) = crossing {
            let y_root = &w.ys;
            let reason = p.guard_reason(t_root, y_root);
            rec.emit(t_root, y_root, poly, &mut buf);
            let e = IntegrateError::Stopped { t: t_root, reason };
            let ev = p.evals();
            return Err(rec.fail(e, t_root, y_root, ev));
        }

        rec.emit(t, &y, poly, &mut buf);
        if last {
            let ev = p.evals();
            return Ok(rec.finish(t, &y, ev));
        }
        // Full Newton: a new step-start Jacobian for the error estimate after
        // every accepted step, and no step keeping (nothing to save).
        let theta_ok = !full && w.theta <= np.thet;
        if fixed.is_none() {
            h_new = h_new.min(hmax);
            if reject {
                h_new = h_new.min(h);
            }
            reject = false;
            let qt = h_new / h;
            if t + h_new / quot1 - t_end >= 0.0 {
                h = t_end - t;
                last = true;
            } else if !(theta_ok && qt >= quot1 && qt <= quot2) {
                h = h_new;
            }
        }
        need_jac = !theta_ok;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dense::eval_nested;

    /// RADAU5's `CONTR5`: the collocation polynomial in Newton form around
    /// the end of the step, `s = (t − t_{n+1})/h`, from the coefficients its
    /// `RADCOR` stores after an accepted step.
    fn contr5(y_new: f64, z: [f64; 3], c: [f64; 3], s: f64) -> f64 {
        let (c1m1, c2m1, c1mc2) = (c[0] - 1.0, c[1] - 1.0, c[0] - c[1]);
        let cont1 = (z[1] - z[2]) / c2m1;
        let ak = (z[0] - z[1]) / c1mc2;
        let acont3 = (ak - z[0] / c[0]) / c[1];
        let cont2 = (ak - cont1) / c1m1;
        let cont3 = cont2 - acont3;
        y_new + s * (cont1 + (s - c2m1) * (cont2 + (s - c1m1) * cont3))
    }

    #[test]
    fn nested_form_is_radau5_collocation_polynomial() {
        let mut w = Work::new(1, true, false);
        let c = w.tab.c;
        let y = [0.7];
        w.z = [vec![0.31], vec![-0.42], vec![0.125]];
        w.polynomial(&y);
        let z = [w.z[0][0], w.z[1][0], w.z[2][0]];
        let mut out = [0.0];
        // Through y_n and the stage values, and equal to CONTR5 everywhere
        // (also outside the step, where it extrapolates).
        for (s, want) in [(0.0, y[0]), (c[0], y[0] + z[0]), (c[1], y[0] + z[1])] {
            eval_nested(&w.coef, 1, NCOEF, s, &mut out);
            assert!((out[0] - want).abs() < 1e-15, "s = {s}");
        }
        for k in 0..=30 {
            let s = -0.5 + 0.1 * f64::from(k);
            eval_nested(&w.coef, 1, NCOEF, s, &mut out);
            let r5 = contr5(y[0] + z[2], z, c, s - 1.0);
            let tol = 1e-14 * r5.abs().max(1.0);
            assert!((out[0] - r5).abs() < tol, "s = {s}: {} vs {r5}", out[0]);
        }
        // Newton starting values of a step of size 1.5 h: p(1 + c_i·1.5) − p(1).
        w.start(1.5, Some(1.0));
        for i in 0..3 {
            let s = 1.0 + c[i] * 1.5;
            let want = contr5(y[0] + z[2], z, c, s - 1.0) - (y[0] + z[2]);
            let tol = 1e-14 * want.abs().max(1.0);
            assert!((w.z[i][0] - want).abs() < tol, "{} vs {want}", w.z[i][0]);
            let back: f64 = (0..3).map(|k| w.tab.t[i][k] * w.w[k][0]).sum();
            assert!((back - w.z[i][0]).abs() < tol, "W = T⁻¹ Z");
        }
    }
}
