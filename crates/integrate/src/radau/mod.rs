//! RADAU5 — the implicit Runge–Kutta method Radau IIA of order 5 with
//! step-size control and continuous output, for stiff ODEs `y' = f(t, y)`
//! ([`crate::solve`] with [`Method::Radau5`]; solver state [`Radau5`]) and
//! fully implicit systems `F(t, y, y') = 0`, including
//! differential-algebraic equations of index up to 3
//! ([`crate::solve_implicit`]; solver state [`crate::Solver::implicit`]).
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
//! **Full Newton iteration** (`Options::radau5.newton =`
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
//! the nested form of [`crate::Dense`] (`y_n + s(b + (1 − s)(c + s d))`, converted
//! from the values at the nodes) for `Options::dense`, output samples,
//! guard location and the Newton starting values. With
//! `radau5.dense_output = hermite` ([`crate::RadauDense::Hermite`], ODEs
//! only; the default [`crate::RadauDense::Auto`] is `hermite` for ODEs and
//! the collocation polynomial for implicit systems) the first three uses
//! take instead, component by component, the
//! quintic through `(y, y')` at `t_{n−1}`, `t_n`, `t_{n+1}` (a quartic
//! without the value at `t_{n−1}` after a more than twofold step growth)
//! where the component's row of the Jacobian is not stiff over the step
//! (`hermite.rs` says how that is decided), six coefficient vectors per step; the Newton
//! starting values still extrapolate the collocation polynomial, so the
//! steps, and every counter, are those of the collocation polynomial's run
//! (unless a guard or event, located on the extension, ends a step).
//!
//! # Settings ([`Options`], and [`crate::Radau5Options`] in `Options::radau5`)
//!
//! | setting | meaning here | default |
//! |---|---|---|
//! | `rtol`, `atol` | tolerances, transformed as above | `1e-6`, `1e-6` |
//! | `atol_components` | per-component `atol` (transformed like `atol`) | `None` |
//! | `fixed_step` | fixed step mode | `None` |
//! | `h_init` | first step | `HINIT` / first guess |
//! | `h_max` | largest step | `t_end − t0` |
//! | `max_steps` | budget on trial steps (accepted + rejected) | `10⁷` |
//! | `max_wall_time_s` | budget, checked every 8 trial steps | `None` |
//! | `output`, `dense`, `hit_output` | samples and continuous extension, as for the explicit methods | `[]`, `true`, `false` |
//! | `radau5.newton` | simplified (RADAU5) or full Newton iteration | `Auto` (here: simplified) |
//! | `radau5.newton_max_iter` | `NIT` | 7 |
//! | `radau5.newton_tol` | `FNEWT` (a given value is raised to `10·uround/rtol'`, where RADAU5 stops with an error) | `max(10·uround/rtol', min(0.03, sqrt(rtol')))`, uround = 1e-16 |
//! | `radau5.jacobian_reuse` | `THET` (negative: new Jacobian every step) | `0.001` |
//! | `radau5.keep_step` | `(QUOT1, QUOT2)` | `(1.0, 1.2)` |
//! | `radau5.dense_output` | collocation polynomial or the Hermite quintic | `auto` (Hermite for ODEs) |
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
//! # A step and its failures
//!
//! [`crate::Solver::step`] runs the loop head
//! shared with the explicit methods (`crate::driver`: budgets, minimum
//! step, landing on `t_end` with RADAU5's `t + 1.0001 h >= t_end` and on
//! output times), then trial steps of [`RadauCore`] in RADAU5's order until
//! one is accepted:
//!
//! 1. **Iteration matrices** ([`RadauCore::iteration_matrix`]): `J`, `J'`
//!    at the step start when a new Jacobian is due, and the factorisations
//!    of `γ/h J' + J` and `(α + iβ)/h J' + J` when `h` or `J` changed.
//! 2. **Starting values**: the last collocation polynomial extrapolated
//!    (zero at the first step), with the error scale of the step.
//! 3. **Newton iteration** ([`RadauCore::newton`]): simplified or full, with
//!    RADAU5's convergence monitor.
//! 4. **Error estimate and step-size control** ([`RadauCore::error_control`];
//!    not with a fixed step): accept, or reject with the next trial size.
//!
//! Every rejection goes through [`RadauCore::reject`] (counted, retried
//! from the same state, with a fresh Jacobian unless the current one was
//! taken there). After the accepted step the driver calls `after_step`,
//! then [`RadauCore`] evaluates `f` (or `F`) at the new state, the guard is
//! watched and the next step size settled (keep `h` within `keep_step`,
//! land on `t_end`).
//!
//! A budget ends the run with [`crate::StopReason::Budget`], a guard zero
//! with [`crate::StopReason::Guard`], every other failure with
//! [`crate::StopReason::Failed`]; from `solve` every failure is a
//! [`Failure`] whose partial solution holds the samples, step polynomials
//! and counters up to `error.time()`.
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
//! vectors) are allocated once per run, by [`crate::Solver::new`] and
//! [`crate::Solver::implicit`]; a step allocates only when it stores samples
//! and step polynomials.

mod hermite;
mod linalg;
mod newton;
mod problem;
mod sparse;
mod tableau;
mod work;

use crate::driver::{Attempt, Core, Driver, Landing, Run, Trial};
use crate::explicit::control::{Tol, all_finite};
use crate::record::Record;
use crate::validate::{atol_vector, validate};
use crate::{
    Failure, ImplicitSystem, IntegrateError, Method, OdeSystem, Options, RadauDense, RadauNewton,
    Stats, SystemError,
};
use hermite::{Hermite, Step};
use newton::{Newton, NewtonParams};
pub(crate) use problem::UROUND;
use problem::{Dae, Ode, Problem};
use sparse::SparseIteration;
use work::Work;

/// Number of coefficient vectors of the collocation polynomial in the
/// nested form of [`crate::Dense`].
const NCOEF: usize = 4;

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
/// tolerances: `|F_i| <= atol + rtol·|y0_i|` for every `i`; `name(i)` names
/// component `i` (and the equation paired with it).
fn inconsistency(
    res: &[f64],
    y0: &[f64],
    atol: &[f64],
    rtol: f64,
    name: impl Fn(usize) -> String,
) -> Option<String> {
    let mut worst: Option<(usize, f64)> = None;
    for (i, (&r, &y)) in res.iter().zip(y0).enumerate() {
        let q = r.abs() / (atol[i] + rtol * y.abs());
        if !q.is_finite() {
            return Some(format!(
                "inconsistent initial values: F[{i}](t0, y0, y'0) = {r} (the equation paired \
                 with {}) is not finite",
                name(i)
            ));
        }
        if worst.is_none_or(|(_, w)| q > w) {
            worst = Some((i, q));
        }
    }
    let (i, q) = worst?;
    (q > 1.0).then(|| {
        format!(
            "inconsistent initial values: |F[{i}](t0, y0, y'0)| = {:.3e} (the equation paired \
             with {}) exceeds atol + rtol·|y0[{i}]| = {:.3e}, the largest residual relative to \
             its tolerance; where the equations cannot be satisfied more closely in floating \
             point than this, a looser tolerance may start",
            res[i].abs(),
            name(i),
            atol[i] + rtol * y0[i].abs()
        )
    })
}

/// A Radau IIA (RADAU5) run on the stiff ODE `y' = f(t, y)` of `sys` from
/// `(t0, y0)` to `t_end`, with the settings and checks of [`crate::solve`]
/// (invalid input comes back as a [`Failure`] at once; nothing of `sys` is
/// evaluated before the first step).
pub(crate) fn run_ode<'a, S: OdeSystem + ?Sized + 'a>(
    sys: &'a mut S,
    t0: f64,
    y0: &[f64],
    t_end: f64,
    opts: &Options,
) -> Result<Box<dyn Run + 'a>, Failure> {
    Ok(Box::new(driver(Ode::new(sys), t0, y0, None, t_end, opts)?))
}

/// A Radau IIA run on the implicit system `F(t, y, y') = 0` of `sys` (a DAE
/// of index up to 3) from the consistent initial values `(t0, y0, y'0)` to
/// `t_end`, with the settings and checks of [`crate::solve_implicit`]:
/// invalid input, including inconsistent initial values (one evaluation of
/// `F`), comes back as a [`Failure`] at once.
pub(crate) fn run_implicit<'a, S: ImplicitSystem + ?Sized + 'a>(
    sys: &'a mut S,
    t0: f64,
    y0: &[f64],
    yp0: &[f64],
    t_end: f64,
    opts: &Options,
) -> Result<Box<dyn Run + 'a>, Failure> {
    let dae = Dae { sys, evals: 0 };
    Ok(Box::new(driver(dae, t0, y0, Some(yp0), t_end, opts)?))
}

/// Validates the input (for an implicit system also the consistency of
/// `(y0, y'0)`) and sets up the driver.
fn driver<P: Problem>(
    mut p: P,
    t0: f64,
    y0: &[f64],
    yp0: Option<&[f64]>,
    t_end: f64,
    opts: &Options,
) -> Result<Driver<P, RadauCore>, Failure> {
    let n = p.dim();
    let hermite = opts.radau5.dense_output.hermite(P::IDENTITY_JP);
    let rec = Record::new(Method::Radau5, n, ncoef(hermite), opts, t_end);
    let mut index = vec![1u8; n];
    p.variable_index(&mut index);
    if let Err(msg) = validate(Method::Radau5.needs_fixed_step(), n, t0, y0, t_end, opts)
        .and_then(|()| validate_radau(opts, yp0, &index))
    {
        return Err(rec.fail(IntegrateError::InvalidInput(msg), t0, y0, 0));
    }
    if opts.radau5.dense_output == RadauDense::Hermite && !P::IDENTITY_JP {
        let msg = "dense_output = hermite interpolates the derivatives of y' = f(t, y): an \
                   implicit system F(t, y, y') = 0 keeps the collocation polynomial \
                   (dense_output = collocation)"
            .to_string();
        return Err(rec.fail(IntegrateError::InvalidInput(msg), t0, y0, 0));
    }
    // Sparse iteration matrices for a system with sparse Jacobians.
    let sparse = match p.sparsity() {
        None => None,
        Some(_) if opts.radau5.newton == RadauNewton::Full => {
            let msg = "full Newton (`newton = full`) forms dense stage Jacobians: it is not \
                       available for a system that gives its Jacobians sparse"
                .to_string();
            return Err(rec.fail(IntegrateError::InvalidInput(msg), t0, y0, 0));
        }
        Some(sp) => match SparseIteration::new(n, &sp) {
            Ok(it) => Some((it, sp.jy.len(), sp.jyp.len())),
            Err(msg) => return Err(rec.fail(IntegrateError::InvalidInput(msg), t0, y0, 0)),
        },
    };
    let mut core = RadauCore::new(index, opts, P::IDENTITY_JP, sparse);
    if let Some(yp0) = yp0 {
        if let Err(e) = core.consistent(&mut p, t0, y0, yp0, opts) {
            let evals = p.evals();
            return Err(rec.fail(e, t0, y0, evals));
        }
    }
    Ok(Driver::new(p, core, rec, t0, y0, t_end, opts))
}

/// Coefficient vectors per step of the dense output: the collocation
/// polynomial's, or the Hermite extension's.
fn ncoef(hermite: bool) -> usize {
    if hermite { hermite::NCOEF } else { NCOEF }
}

/// Step-size controller of RADAU5: `SAFE`, `FACL`, `FACR`.
const SAFE: f64 = 0.9;
const FACL: f64 = 5.0;
const FACR: f64 = 1.0 / 8.0;

/// Radau IIA in the step loop: the workspaces, `y'` and `F` at the current
/// state, RADAU5's tolerances and the state it keeps between steps
/// (Jacobian, factorisation, step-size history). Allocated once per run.
struct RadauCore {
    w: Work,
    /// Index class (1, 2, 3) of every component.
    index: Vec<u8>,
    /// `y'_n`: `f(t_n, y_n)` for an ODE; for an implicit system `y'0`, then
    /// the derivative of the last collocation polynomial at its end.
    yp: Vec<f64>,
    /// `F(t_n, y_n, y'_n)` (zero for an ODE).
    res: Vec<f64>,
    /// `y'0` was given (an implicit system): nothing to evaluate at `t0`.
    yp_given: bool,
    /// RADAU5's internal tolerances `rtol' = 0.1 rtol^(2/3)`,
    /// `atol' = rtol'·atol/rtol` (component by component).
    rtol: f64,
    atol: Vec<f64>,
    /// Base error scale `atol' + rtol'·|y_n|` of the current state.
    sk: Vec<f64>,
    np: NewtonParams,
    /// `(QUOT1, QUOT2)`.
    keep_step: (f64, f64),
    /// `CFAC = SAFE·(1 + 2·NIT)`.
    cfac: f64,
    fixed: bool,
    /// Full Newton iteration (`RadauNewton::Full`) instead of the simplified one.
    full: bool,
    /// A new Jacobian is needed before the next trial step.
    need_jac: bool,
    /// The Jacobian was evaluated at the current state (RADAU5's `CALJAC`).
    caljac: bool,
    /// Step size of the current factorisation (NaN: none).
    h_lu: f64,
    /// Singular iteration matrices in a row.
    nsing: usize,
    /// Size of the last accepted step (read only after one).
    hold: f64,
    /// `max(‖err‖, 1e-2)` of the last accepted step (Gustafsson).
    erracc: f64,
    /// The step size proposed after the last accepted step.
    h_new: f64,
    /// The Hermite continuous extension ([`RadauDense::Hermite`]).
    hermite: Option<Box<Hermite>>,
    /// `w.jy` holds a Jacobian evaluated in this run (the Hermite extension
    /// reads its rows). Not the Jacobian count: full Newton with a fixed
    /// step evaluates its stage Jacobians elsewhere and never writes `w.jy`.
    jy_valid: bool,
}

impl RadauCore {
    fn new(
        index: Vec<u8>,
        opts: &Options,
        identity_jp: bool,
        sparse: Option<(SparseIteration, usize, usize)>,
    ) -> Self {
        let n = index.len();
        let rtol = 0.1 * opts.rtol.powf(2.0 / 3.0);
        let atol = atol_vector(opts, n)
            .iter()
            .map(|a| rtol * a / opts.rtol)
            .collect();
        let np = NewtonParams {
            nit: opts.radau5.newton_max_iter,
            // Never below 10·uround/rtol', where rounding ends the iteration.
            fnewt: opts.radau5.newton_tol_at(opts.rtol),
            thet: opts.radau5.jacobian_reuse,
            fixed: opts.fixed_step.is_some(),
        };
        let full = opts.radau5.newton == RadauNewton::Full;
        RadauCore {
            w: Work::new(n, identity_jp, full, sparse),
            index,
            yp: vec![0.0; n],
            res: vec![0.0; n],
            yp_given: false,
            rtol,
            atol,
            sk: vec![0.0; n],
            np,
            keep_step: opts.radau5.keep_step,
            cfac: SAFE * (1 + 2 * np.nit) as f64,
            fixed: opts.fixed_step.is_some(),
            full,
            need_jac: true,
            caljac: false,
            h_lu: f64::NAN,
            nsing: 0,
            hold: f64::NAN,
            erracc: 1e-2,
            h_new: f64::NAN,
            hermite: opts
                .radau5
                .dense_output
                .hermite(identity_jp)
                .then(|| Box::new(Hermite::new(n))),
            jy_valid: false,
        }
    }

    /// Takes the given `y'0` and checks `F(t0, y0, y'0) = 0` against the
    /// user's tolerances (one evaluation of `F`).
    fn consistent<P: Problem>(
        &mut self,
        p: &mut P,
        t0: f64,
        y0: &[f64],
        yp0: &[f64],
        opts: &Options,
    ) -> Result<(), IntegrateError> {
        self.yp.copy_from_slice(yp0);
        self.yp_given = true;
        if let Err(source) = p.residual(t0, y0, yp0, &mut self.res) {
            return Err(IntegrateError::System { t: t0, source });
        }
        let atol_user = atol_vector(opts, y0.len());
        match inconsistency(&self.res, y0, &atol_user, opts.rtol, |i| {
            p.component_name(i)
        }) {
            Some(msg) => Err(IntegrateError::InvalidInput(msg)),
            None => Ok(()),
        }
    }

    /// The Jacobian is kept for the next step: the last Newton iteration
    /// contracted fast (`θ <= THET`; never with full Newton).
    fn theta_ok(&self) -> bool {
        !self.full && self.w.theta <= self.np.thet
    }

    /// A rejected trial step, retried from the same state with step size
    /// `h`, with a fresh Jacobian unless the current one was taken at this
    /// state.
    fn reject(&mut self, h: f64, nonfinite: bool) -> Attempt {
        self.need_jac = !self.caljac;
        Attempt::Rejected { h, nonfinite }
    }

    /// Iteration matrices of the trial step: `J`, `J'` at the step start if
    /// needed, and the factorisations for this `h` unless current. A
    /// singular matrix rejects the step (`h/2`; ends the run the 5th time
    /// in a row, or at once with a fixed step).
    fn iteration_matrix<P: Problem>(
        &mut self,
        p: &mut P,
        tr: Trial,
        y: &[f64],
        stats: &mut Stats,
    ) -> Result<(), Attempt> {
        let (t, h) = (tr.t, tr.h);
        // Full Newton with a fixed step needs neither: no error estimate.
        let step_start_matrix = !(self.full && self.fixed);
        if self.need_jac && step_start_matrix {
            stats.jacobian_evals += 1;
            let w = &mut self.w;
            let jac = p.jacobians(t, y, &self.yp, &self.res, &mut w.jy, &mut w.jyp);
            let error = match jac {
                Err(source) => Some(IntegrateError::System { t, source }),
                Ok(()) if !all_finite(&w.jy) || !all_finite(&w.jyp) => {
                    Some(IntegrateError::NonFinite { t })
                }
                Ok(()) => None,
            };
            if let Some(e) = error {
                return Err(Attempt::Failed(e));
            }
            self.caljac = true;
            self.jy_valid = true;
            self.h_lu = f64::NAN;
        }
        // NaN (no factorisation) compares false: factor.
        let factored = !step_start_matrix || (h - self.h_lu).abs() <= 1e-12 * h.abs();
        if factored {
            return Ok(());
        }
        stats.lu_decompositions += 1;
        if self.w.factor(h).is_ok() {
            self.h_lu = h;
            return Ok(());
        }
        self.nsing += 1;
        if self.nsing >= 5 || self.fixed {
            let source = SystemError::new(format!(
                "Radau5: the iteration matrix γ/h·∂F/∂y' + ∂F/∂y is singular \
                 (h = {h:e}, {} time(s) in a row)",
                self.nsing
            ));
            return Err(Attempt::Failed(IntegrateError::System { t, source }));
        }
        self.h_lu = f64::NAN;
        Err(self.reject(0.5 * h, false))
    }

    /// The Newton iteration (simplified or full) from the starting values;
    /// `Ok` with the number of iterations when it converged, else how the
    /// trial step ends: a failing stage halves `h` (ends the run below
    /// `h_min` or with a fixed step), so does a non-finite one; a failed
    /// iteration halves `h` (fixed step: one retry with a fresh Jacobian),
    /// a slow one takes RADAU5's reduction.
    fn newton<P: Problem>(
        &mut self,
        p: &mut P,
        tr: Trial,
        y: &[f64],
        stats: &mut Stats,
    ) -> Result<usize, Attempt> {
        let (t, h) = (tr.t, tr.h);
        let outcome = if self.full {
            self.w.newton_full(p, t, y, h, tr.t_new, self.np, stats)
        } else {
            self.w.newton(p, t, y, h, tr.t_new, self.np, stats)
        };
        let fail = |e| Err(Attempt::Failed(e));
        match outcome {
            Newton::Converged(newt) => Ok(newt),
            Newton::Stage(source) => {
                if self.fixed || 0.5 * h.abs() < tr.h_min {
                    return fail(IntegrateError::System { t, source });
                }
                Err(self.reject(0.5 * h, false))
            }
            Newton::NonFinite => {
                if self.fixed {
                    return fail(IntegrateError::NonFinite { t });
                }
                Err(self.reject(0.5 * h, true))
            }
            Newton::Singular => {
                self.nsing += 1;
                self.h_lu = f64::NAN;
                if self.nsing >= 5 || self.fixed {
                    let matrix = if self.full {
                        "the full Newton matrix ∂G/∂Z of the stage equations"
                    } else {
                        "the iteration matrix γ/h·∂F/∂y' + ∂F/∂y"
                    };
                    let source = SystemError::new(format!(
                        "Radau5: {matrix} is singular (h = {h:e}, {} time(s) in a row)",
                        self.nsing
                    ));
                    return fail(IntegrateError::System { t, source });
                }
                Err(self.reject(0.5 * h, false))
            }
            Newton::Failed => {
                stats.newton_failures += 1;
                if !self.fixed {
                    return Err(self.reject(0.5 * h, false));
                }
                // A fresh Jacobian cannot change a full Newton iteration.
                if self.caljac || self.full {
                    let kind = if self.full { "full" } else { "simplified" };
                    let source = SystemError::new(format!(
                        "Radau5: the {kind} Newton iteration does not converge \
                         with the fixed step h = {h:e}"
                    ));
                    return fail(IntegrateError::System { t, source });
                }
                // Retry the same step with a fresh Jacobian.
                self.need_jac = true;
                Err(Attempt::Repeat)
            }
            Newton::Slow(fac) => {
                stats.newton_failures += 1;
                Err(self.reject(fac * h, false))
            }
        }
    }

    /// Error estimate and step-size control of a converged step (adaptive
    /// only): rejects when the estimate is not finite (`h/2`) or `>= 1`
    /// (`h_new`, `h/10` at the first step); else proposes `h_new`, with
    /// Gustafsson's predictive controller from the second accepted step on.
    fn error_control<P: Problem>(
        &mut self,
        p: &mut P,
        tr: Trial,
        y: &[f64],
        newt: usize,
    ) -> Attempt {
        let h = tr.h;
        let second = tr.first || tr.after_reject;
        let err = self.w.estimate(p, tr.t, y, &self.yp, &self.res, h, second);
        if !err.is_finite() {
            return self.reject(0.5 * h, true);
        }
        // The safety factor decreases with the number of Newton iterations.
        let fac = SAFE.min(self.cfac / (newt + 2 * self.np.nit) as f64);
        let mut quot = (err.powf(0.25) / fac).clamp(FACR, FACL);
        let mut h_new = h / quot;
        if err >= 1.0 {
            return self.reject(if tr.first { 0.1 * h } else { h_new }, false);
        }
        // Gustafsson's predictive controller.
        if !tr.first {
            let facgus =
                ((self.hold / h) * (err * err / self.erracc).powf(0.25) / SAFE).clamp(FACR, FACL);
            quot = quot.max(facgus);
            h_new = h / quot;
        }
        self.erracc = err.max(1e-2);
        self.h_new = h_new;
        Attempt::Accepted
    }
}

impl<P: Problem> Core<P> for RadauCore {
    fn ncoef(&self) -> usize {
        ncoef(self.hermite.is_some())
    }
    const LANDING: Landing = Landing {
        stretch: 1.0001,
        inclusive: true,
    };

    /// For an ODE `y'0 = f(t0, y0)`, which must be finite; the base error scale.
    fn start(&mut self, p: &mut P, t0: f64, y0: &[f64]) -> Result<(), IntegrateError> {
        if !self.yp_given {
            match p.accepted_state(t0, y0, &mut self.yp, &mut self.res) {
                Err(source) => return Err(IntegrateError::System { t: t0, source }),
                Ok(()) => {
                    if let Some(i) = self.yp.iter().position(|v| !v.is_finite()) {
                        return Err(IntegrateError::InvalidInput(format!(
                            "f(t0, y0) is not finite: component {i} is {} at t0 = {t0}",
                            self.yp[i]
                        )));
                    }
                }
            }
        }
        let tol = Tol {
            rtol: self.rtol,
            atol: &self.atol,
        };
        for (i, s) in self.sk.iter_mut().enumerate() {
            *s = tol.scale(i, y0[i], 0.0);
        }
        Ok(())
    }

    /// `HINIT` with the exponent 4 of the error estimate (ODE), or its
    /// first guess `0.01‖y0‖/‖y'0‖` (implicit system).
    fn initial_step(&mut self, p: &mut P, t0: f64, y0: &[f64], h_max: f64) -> f64 {
        let tol = Tol {
            rtol: self.rtol,
            atol: &self.atol,
        };
        let w = &mut self.w;
        p.initial_step(t0, y0, &self.yp, h_max, tol, &mut w.ys, &mut w.yps)
    }

    /// One trial step in RADAU5's order: iteration matrices, starting
    /// values, Newton iteration, error estimate and step-size control.
    fn attempt(&mut self, p: &mut P, tr: Trial, y: &[f64], stats: &mut Stats) -> Attempt {
        // Iteration matrices (Jacobian at the step start, LU for this h).
        if let Err(end) = self.iteration_matrix(p, tr, y, stats) {
            return end;
        }
        // Starting values: the last collocation polynomial, extrapolated.
        self.w.set_scale(&self.sk, &self.index, tr.h);
        self.w.start(tr.h, (!tr.first).then_some(self.hold));
        // Newton iteration on the stage equations.
        let newt = match self.newton(p, tr, y, stats) {
            Ok(newt) => newt,
            Err(end) => return end,
        };
        // Error estimate and step-size control (a fixed step has neither).
        if self.fixed {
            return Attempt::Accepted;
        }
        self.error_control(p, tr, y, newt)
    }

    /// `y_{n+1} = y_n + Z_3` and, for implicit systems, `y'_{n+1} = Y'_3`;
    /// the collocation polynomial is the step polynomial.
    fn accept(&mut self, tr: Trial, y: &mut Vec<f64>, _stats: &mut Stats) -> bool {
        self.nsing = 0;
        self.w.polynomial(y);
        if let Some(ext) = self.hermite.as_mut() {
            ext.step(&Step {
                t: tr.t,
                h: tr.h,
                y,
                yp: &self.yp,
                z3: &self.w.z[2],
                yp_end: &self.w.yp_new,
                collocation: &self.w.coef,
                jy: self.jy_valid.then_some(&self.w.jy[..]),
                sc: &self.sk,
            });
        }
        self.hold = tr.h;
        for (yi, zi) in y.iter_mut().zip(&self.w.z[2]) {
            *yi += zi;
        }
        // An ODE gets y' = f(t, y) in `new_state`.
        if !P::IDENTITY_JP {
            self.yp.copy_from_slice(&self.w.yp_new);
        }
        true
    }

    /// What the next error estimate needs at the new (possibly projected)
    /// state: `f` (ODE) or `F` (implicit), except at `t_end`; the error
    /// scale; whether to keep the Jacobian.
    fn new_state(
        &mut self,
        p: &mut P,
        t: f64,
        y: &[f64],
        projected: bool,
        last: bool,
    ) -> Result<(), IntegrateError> {
        if projected {
            if let Some(ext) = self.hermite.as_mut() {
                ext.reset();
            }
        }
        if !all_finite(y) {
            return Err(IntegrateError::NonFinite { t });
        }
        if !last {
            match p.accepted_state(t, y, &mut self.yp, &mut self.res) {
                Err(source) => return Err(IntegrateError::System { t, source }),
                Ok(()) if !all_finite(&self.yp) || !all_finite(&self.res) => {
                    return Err(IntegrateError::NonFinite { t });
                }
                Ok(()) => {}
            }
        }
        self.caljac = false;
        let tol = Tol {
            rtol: self.rtol,
            atol: &self.atol,
        };
        for (i, (s, &v)) in self.sk.iter_mut().zip(y).enumerate() {
            *s = tol.scale(i, v, 0.0);
        }
        // Full Newton: a new step-start Jacobian for the error estimate after
        // every accepted step.
        self.need_jac = !self.theta_ok();
        Ok(())
    }

    fn coef(&self) -> &[f64] {
        match &self.hermite {
            Some(ext) => &ext.coef,
            None => &self.w.coef,
        }
    }

    fn proposal(&self) -> Option<f64> {
        (!self.fixed).then_some(self.h_new)
    }

    /// Lands on `t_end` when `t + h_new/QUOT1` reaches it; keeps `h` (and
    /// so the factorisations) when the Jacobian is kept and `h_new/h` lies
    /// in `keep_step` (full Newton: never, nothing to save).
    fn settle(&mut self, t: f64, h: f64, h_new: f64, t_end: f64) -> (f64, bool) {
        let (quot1, quot2) = self.keep_step;
        let qt = h_new / h;
        if t + h_new / quot1 - t_end >= 0.0 {
            (t_end - t, true)
        } else if !(self.theta_ok() && qt >= quot1 && qt <= quot2) {
            (h_new, false)
        } else {
            (h, false)
        }
    }
}
