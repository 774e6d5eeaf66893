//! Formulation A as an explicit ODE: index reduction by the derivative array.
//!
//! The state is the same `z = (q_I, q̇_I, q̈_I, q⃛_I)` as in the implicit form
//! ([`crate::implicit`]); the right-hand side of the explicit form
//! ([`crate::explicit`]) is
//!
//! ```text
//! ż = (z₁, z₂, z₃, w(z)),   w = q_I⁗
//! ```
//!
//! **What is solved per right-hand side.** (19) alone does not give `q⁗`
//! (`W = ∂E/∂q⁗` is singular, rank 1 for the sleigh). With
//! `u = (q⁗, q⁽⁵⁾, q⁽⁶⁾)` the derivative array of order 2,
//! `D(z, u) = [E; Ė; Ë] = 0` (3m equations from [`crate::elo::elo_array`],
//! the same code as the implicit form), fixes `q⁗` uniquely, while parts of
//! `q⁽⁵⁾, q⁽⁶⁾` stay free. `D` is solved for `u` by a Newton-type iteration
//! with the automatic-differentiation Jacobian `∂D/∂u` only (never `∂D/∂z`)
//! and a truncated pseudo-inverse (minimum-norm steps; one-sided Jacobi SVD
//! in preallocated buffers), warm-started from the previous call's `u`.
//!
//! **Why the answer is A's own.** Nothing but A's equations and their exact
//! time derivatives enter; on A's constraint manifold (`z` consistent) the
//! solution `D = 0` is exact and its `q⁗` is the one of the consistent
//! completion ([`crate::analysis::complete`], used for the implicit form's
//! `y'0`). Along vakonomic motions it is C's `q⁗` although C is never
//! consulted (`tests/ode_form.rs`).
//!
//! **Off the manifold** (the stages of an explicit Runge–Kutta step lie off
//! it by the stage error), `D = 0` has no solution: the combinations of `D`
//! in the left null space of `∂D/∂u` are the hidden constraints `h(z)`. `w`
//! is then the Gauss–Newton (least-squares) solution with one weight per
//! derivative level. The weights depend on `z` only, and so does the left
//! null space (for the sleigh it lies in the levels `E, Ė`, where `D` is
//! affine in `u` with `u`-independent coefficients). So an iteration with
//! the Jacobian taken at the current `z` converges to the same `q⁗` whatever
//! the `u` its `u`-dependent block was taken at (the warm start): `w` is a
//! smooth function of `z` alone (checked in this module's tests), and
//! explicit methods keep their order.
//!
//! **Cost.** `D` is affine in `q⁽⁵⁾, q⁽⁶⁾` and the identities of derivative
//! arrays (`∂E⁽ˡ⁾/∂q⁽ᵏ⁾ = Σᵢ C(l, i) dˡ⁻ⁱ/dtˡ⁻ⁱ ∂E/∂q⁽ᵏ⁻ⁱ⁾`) give
//!
//! ```text
//!           q⁗   q⁽⁵⁾         q⁽⁶⁾
//! ∂D/∂u = [ W    0            0 ]     W = ∂E/∂q⁗   (E is linear in q⁗)
//!         [ Q    W            0 ]     Q = ∂Ė/∂q⁗ = Ẇ + ∂E/∂q⃛
//!         [ V    2Q − ∂E/∂q⃛  W ]     V = ∂Ë/∂q⁗
//! ```
//!
//! Only `V` depends on `u` (through `q⁗`), so the iteration is a chord
//! iteration: one Jacobian at the warm start per call, then plain
//! evaluations of `D`, with a Newton restart if it contracts slowly.
//!
//! `D` and the columns the Jacobian needs (`∂D/∂q⁗`, and `∂E/∂q⃛` for the
//! structural columns; `∂D/∂q⃛` too in a projection) come from programs
//! traced once per scene and branch of the map ([`crate::traced`]) and run
//! as native code over `f64`, in the interpreter over complex numbers (the
//! continuation's paths, [`crate::crossing`]): one run for a Jacobian, one
//! for an evaluation. Without a trace (a scene whose functions branch on
//! values) they come from dual passes over the order-4 jet: `m` order-4
//! passes for the `q⁗` columns (which also give `D`) and `m` order-2 passes
//! for `∂E/∂q⃛`. The pseudo-inverse comes from a one-sided Jacobi SVD of
//! the equilibrated `∂D/∂u` in preallocated buffers (nalgebra's SVD
//! allocates per call and measured 22 % slower per right-hand side with
//! the dual passes, `docs/embedding.md` section 4), warm-started from the right singular
//! vectors of the previous solve of its kind, which are made orthonormal
//! again only after [`REORTHONORMALIZE_AFTER`] rotations, and rotating only
//! pairs whose inner product exceeds [`PINV_RTOL`] of the smaller squared
//! norm: a repeated solve at one state takes one sweep (six from the
//! identity, on the sleigh; `warm_started_solves_take_one_sweep`).
//! Tracing and the warm start are on by default; [`Reduction::set_traced`]
//! switches both off, for timing and as the definition the traced programs
//! are checked against. No allocation per call.
//!
//! **Accuracy.** The terms of `[E; Ė; Ë]` grow towards the map's singular
//! set (for the sleigh like powers of the turning rate `|q̈|/|v|`) and
//! cancel in `D`, so the round-off of `w` grows there. Steps that no longer
//! contract even with a fresh Jacobian are accepted as that round-off when
//! they are below [`STAGNATION`]; beyond that the solve fails. The map's own
//! derivatives must be accurate to order 4 (the sleigh evaluates its
//! arctangent with [`nonholo_core::scene::atan2`] for that).
//!
//! **Where it stops** ([`Reduction::resolution`]). So that the explicit form
//! ends by design (`IntegrateError::Stopped`) rather than by a failing
//! solve, its guard ([`crate::explicit`]) stops the run where the estimated
//! relative round-off `ρ` of `q⁗` reaches [`ODE_RESOLUTION`]. `ρ` is the
//! larger of `NOISE_FACTOR · ε · κ`, with `κ` the condition number of the
//! equilibrated `∂D/∂u` of the solve (free: its singular values are
//! computed for the pseudo-inverse), and, only where that is within
//! [`PROBE_FROM`] of the limit, an observed round-off: `D` at `z` and at
//! four copies of `z` changed by ~1e-15 relative, the differences mapped to
//! `q⁗` by the solve's pseudo-inverse (five evaluations of `D`, once per
//! state). At an accepted state the guard uses the solve the right-hand
//! side made there (a solve at the `(t, z)` of the previous one returns
//! it), so away from the limit the guard costs nothing. The calibration of
//! `NOISE_FACTOR` against C's `q⁗` and the measured stops are in
//! `docs/embedding.md`, section 4.
//!
//! **Projection** ([`Reduction::project`]). An explicit integrator keeps `D`'s
//! solvable part exactly but lets `h(z)` drift. After each accepted step the
//! projection moves `q⃛` only (`q, q̇, q̈` fixed) back onto the hidden
//! constraints: Newton on `D = 0` in the unknowns `(q⃛, u)` (full row rank,
//! minimum-norm steps), the same Jacobian plus `m` dual passes for the `q⃛`
//! columns. On the manifold `q⃛` is fixed by `(q, q̇, q̈)` (locally unique),
//! so the result does not depend on how the step was split between `q⃛`
//! and `u`.

use nalgebra::DMatrix;
use nonholo_core::Scene;
use nonholo_core::scene::{EmbeddingInfo, Scalar};
use num_dual::{Dual, Dual2};

use crate::analysis::{LEVELS, derivative_array, relative, row_scales};
use crate::elo::elo_array;
use crate::jet::{Jet4, TimeJet};
use crate::traced::{ArrayWorkspace, TracedArray};

/// Relative accuracy to which the iteration determines `q⁗` (and, in the
/// projection, `q⃛`): estimated remaining error of the chord iteration.
pub const SOLVE_RTOL: f64 = 1e-13;

/// Steps below this (relative) that do not contract even after a fresh
/// Jacobian are the round-off of `w` at this state, and accepted. That
/// round-off grows towards the singular set (see the module documentation).
const STAGNATION: f64 = 1e-7;

/// Iterations (chord steps, including restarts) per solve.
const MAX_ITER: usize = 40;

/// Newton restarts (fresh Jacobians) per solve beyond the first Jacobian.
const MAX_RESTARTS: usize = 4;

/// A restart is made when the steps contract slower than this.
const SLOW: f64 = 0.5;

/// Relative singular-value threshold for a numerical rank.
const RANK_RTOL: f64 = 1e-10;

/// The Jacobi SVD leaves two columns of `A·V` unrotated once their inner
/// product is below this fraction of the smaller squared norm (besides the
/// full-accuracy test `|γ| ≤ ε·rows·√(αβ)`). For a pair this test skips,
/// the pseudo-inverse `P` satisfies `P·A = I + E` on the kept space with
/// `|E_ij| ≤ PINV_RTOL`, whatever the condition number (`‖E‖ ≲ cols ·
/// PINV_RTOL`), so a chord step still contracts, and the span of the kept
/// columns, which fixes the least-squares solution, is unchanged. The test
/// is looser than the full-accuracy one only for pairs whose norms are
/// within a factor ~1e5 of each other, never for a kept and a dropped
/// column (ratio ≤ [`RANK_RTOL`]): the rank decision, and κ, move by at
/// most ~`PINV_RTOL` relative. Singular values come out accurate to
/// `PINV_RTOL²` where they are well separated, to ~`PINV_RTOL` (in σ²)
/// where they cluster. With warm starts it saves the last, confirming
/// sweep (1 sweep instead of 2 per repeated solve).
const PINV_RTOL: f64 = 1e-10;

/// Rotations applied to a stored set of right singular vectors before it
/// is made orthonormal again (each rotation adds a few ε of departure from
/// orthonormality: at most ~1e-13 before a refresh).
const REORTHONORMALIZE_AFTER: usize = 256;

/// The explicit form stops where `q⁗` is resolved only to this relative
/// accuracy ([`Resolution::rho`]; see the module documentation): the
/// round-off of the derivative array grows like a power of `1/|v|` towards
/// the embedding map's singular set, and about an order of magnitude
/// further the solve no longer converges.
pub const ODE_RESOLUTION: f64 = 1e-8;

/// The round-off of `q⁗` estimated from the conditioning is
/// `NOISE_FACTOR · ε · κ`, `κ = σ₁/σ_r` of the equilibrated `∂D/∂u`: the
/// upper end of the error of `w` measured against C's `q⁗` along C's
/// motions, 0.02–1.7 `εκ` (`docs/embedding.md`, section 4).
pub const NOISE_FACTOR: f64 = 2.0;

/// The observed round-off ([`Resolution::observed`], five evaluations of
/// `D`) is measured only where the conditioning estimate is above this
/// fraction of [`ODE_RESOLUTION`]; below it the estimate alone is used.
pub const PROBE_FROM: f64 = 1e-2;

/// Relative size of the changes of `z` by which the observed round-off is
/// measured (a pattern of multiples of it, up to five, per component).
const PROBE_SIZE: f64 = 2e-16;

/// Changed copies of `z` per measurement of the observed round-off (the
/// largest response counts: single responses scatter by a factor of ~5
/// about the error measured against C).
const PROBE_TRIALS: usize = 4;

/// How well `q⁗ = w(z)` is resolved at a state: estimates of its relative
/// round-off ([`Reduction::resolution`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Resolution {
    /// The estimate in use: the larger of the two below.
    pub rho: f64,
    /// `NOISE_FACTOR · ε · κ` from the condition number `κ` of the
    /// equilibrated Jacobian `∂D/∂u` of the solve (free: its singular values
    /// are computed for the pseudo-inverse anyway).
    pub conditioning: f64,
    /// Observed: `D` evaluated at `z` and at four copies of `z` changed by
    /// about 1e-15 relative (`u` kept), the differences mapped to `q⁗` by
    /// the solve's pseudo-inverse, relative to `|q⁗|∞`. It catches round-off
    /// of `D` itself that `κ` does not show (e.g. a map whose jets lose
    /// accuracy). Measured only where `conditioning ≥ PROBE_FROM ·
    /// ODE_RESOLUTION`.
    pub observed: Option<f64>,
}

/// Work counters of the reduction (not part of any result file).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ReductionStats {
    /// Solves for `q⁗` (right-hand sides).
    pub solves: usize,
    /// Projections onto the hidden constraints.
    pub projections: usize,
    /// Jacobians of `D` in the unknowns (each one run of a traced program,
    /// or without a trace `m` order-4 dual passes plus `m` order-2 passes
    /// for a solve, `2m` order-4 passes for a projection), each with one
    /// SVD.
    pub jacobians: usize,
    /// Evaluations of `D` alone (one run of the traced value program, or
    /// without a trace the order-4 jet).
    pub evaluations: usize,
    /// Chord steps.
    pub iterations: usize,
    /// Sweeps of the Jacobi SVDs behind the pseudo-inverses (the last one
    /// of each rotates nothing).
    pub sweeps: usize,
    /// Largest relative change of `q⃛` made by a projection.
    pub max_third_change: f64,
    /// Solves and projections that ended at their round-off level (steps
    /// that no longer contract with a fresh Jacobian) rather than at
    /// [`SOLVE_RTOL`], and the largest such step (relative).
    pub stagnations: usize,
    pub max_stagnation: f64,
    /// Solves answered from the previous one (same `t` and `z`; e.g. the
    /// guard at an accepted state, then the right-hand side there).
    pub cache_hits: usize,
    /// Measurements of the observed round-off ([`Resolution::observed`]),
    /// `1 + PROBE_TRIALS` evaluations of `D` each (not counted in
    /// `evaluations`).
    pub probes: usize,
}

/// The numbers the derivative array is solved over: `f64` on the real time
/// axis, complex numbers along a path in complex time. The linear algebra
/// is done on the realified system, in which a number is `PARTS` reals and
/// a complex coefficient the real block `[[re, −im], [im, re]]`; the
/// minimum-norm least-squares solution of the realified system is that of
/// the complex one.
pub trait Field: Scalar + PartialEq {
    /// Reals per number: 1 (real) or 2 (complex).
    const PARTS: usize;
    /// Part `k < PARTS` (real part, then imaginary part).
    fn part(self, k: usize) -> f64;
    /// The number with parts `p` (`PARTS` of them).
    fn from_parts(p: &[f64]) -> Self;
    /// `|x|`.
    fn norm(self) -> f64;
}

impl Field for f64 {
    const PARTS: usize = 1;
    fn part(self, _k: usize) -> f64 {
        self
    }
    fn from_parts(p: &[f64]) -> Self {
        p[0]
    }
    fn norm(self) -> f64 {
        self.abs()
    }
}

/// The derivative array's traced programs ([`crate::traced`]) for the
/// scene and branch in use.
enum Trace<T> {
    /// Not tried yet (or not asked for, or dropped with a change of scene
    /// or branch): built where a Jacobian first needs it.
    NotYet,
    Traced(Box<(TracedArray, ArrayWorkspace<T>)>),
    /// The scene's functions branch on values: why.
    Refused(String),
}

/// Workspace and warm start of the derivative-array solve over the field
/// `T` (see the module documentation). Everything is allocated once, in
/// [`Reduction::new`].
pub struct Reduction<T: Field = f64> {
    m: usize,
    /// Rank of the realified `∂D/∂u` (`PARTS · (3m − hidden constraints)`),
    /// fixed at a consistent point by [`Reduction::reset`]; `None` before
    /// (numerical rank then).
    rank_u: Option<usize>,
    /// `(z, u) = (q_I⁽⁰⁾ … q_I⁽⁶⁾)` of the last solve: `u` is the warm start.
    d: Vec<T>,
    /// `u` of the last successful solve, restored after a failure.
    u_good: Vec<T>,
    d_dual: Vec<Dual<T>>,
    out_dual: Vec<Dual<T>>,
    /// `D` at `d`, and its parts (realified).
    value: Vec<T>,
    value_parts: Vec<f64>,
    /// `∂D/∂(unknowns)`, column-major, `3m` rows, up to `4m` columns.
    jac: Vec<T>,
    /// `∂E/∂q⃛` (`m × m`, column-major).
    e3: Vec<T>,
    /// Realified equilibrated Jacobian, rotated in place by the Jacobi SVD.
    a: Vec<f64>,
    /// Right singular vectors (`cols × cols` realified, column-major).
    v: Vec<f64>,
    /// Those of the last SVD of a solve (0) and of a projection (1), the
    /// next one's starting point where `warm` says they are valid.
    warm_v: [Vec<f64>; 2],
    warm: [bool; 2],
    /// Rotations applied to each `warm_v` since it was last made
    /// orthonormal ([`REORTHONORMALIZE_AFTER`]).
    drift: [usize; 2],
    norms: Vec<f64>,
    order: Vec<usize>,
    /// Realified pseudo-inverse with the scalings folded in (`PARTS·cols ×
    /// PARTS·3m`, row-major): a step is `Δ = P · D`.
    pinv: Vec<f64>,
    /// One scale per (complex) row and column.
    row_scale: Vec<f64>,
    col_scale: Vec<f64>,
    /// Realified step of the last iteration.
    step: Vec<f64>,
    /// Condition number `σ₁/σ_r` of the equilibrated `∂D/∂u` of the last
    /// solve's Jacobian.
    kappa: f64,
    /// Time of the solve whose `(z, u)` is in `d` (`None` after a failure,
    /// a projection or a reset): a solve at the same `(t, z)` returns it.
    solved_at: Option<T>,
    /// The observed round-off at that solve, once measured.
    probed: Option<f64>,
    /// `D` (parts) at the solve and `z` of the solve, for the probe.
    probe_base: Vec<f64>,
    probe_z: Vec<T>,
    /// Reference values of the dependent coordinates: the map's branch in
    /// use ([`Scene::embedding`]; empty: its principal branch).
    near: Vec<f64>,
    /// Whether to trace and warm-start the SVDs (on by default; see
    /// [`Reduction::set_traced`]).
    trace_on: bool,
    /// The derivative array traced for the scene and branch in use.
    trace: Trace<T>,
    stats: ReductionStats,
}

impl<T: Field> Reduction<T>
where
    Dual<T>: Scalar,
    Jet4<T>: TimeJet<T>,
    Jet4<Dual<T>>: TimeJet<Dual<T>>,
    Dual2<Dual<T>>: TimeJet<Dual<T>>,
{
    /// Workspace for `m` independent coordinates.
    pub fn new(m: usize) -> Self {
        let p = T::PARTS;
        let rows = LEVELS * m;
        let cols = 4 * m;
        let zero = T::from(0.0);
        Reduction {
            m,
            rank_u: None,
            d: vec![zero; 7 * m],
            u_good: vec![zero; 3 * m],
            d_dual: vec![Dual::from_re(zero); 7 * m],
            out_dual: vec![Dual::from_re(zero); rows],
            value: vec![zero; rows],
            value_parts: vec![0.0; p * rows],
            jac: vec![zero; rows * cols],
            e3: vec![zero; m * m],
            a: vec![0.0; p * rows * p * cols],
            v: vec![0.0; p * cols * p * cols],
            warm_v: [
                vec![0.0; p * cols * p * cols],
                vec![0.0; p * cols * p * cols],
            ],
            warm: [false; 2],
            drift: [0; 2],
            norms: vec![0.0; p * cols],
            order: vec![0; p * cols],
            pinv: vec![0.0; p * rows * p * cols],
            row_scale: vec![1.0; rows],
            col_scale: vec![1.0; cols],
            step: vec![0.0; p * cols],
            kappa: f64::INFINITY,
            solved_at: None,
            probed: None,
            probe_base: vec![0.0; p * rows],
            probe_z: vec![zero; 4 * m],
            near: Vec::new(),
            trace_on: true,
            trace: Trace::NotYet,
            stats: ReductionStats::default(),
        }
    }

    /// Whether to evaluate the derivative array by traced programs
    /// ([`crate::traced`]; native code over `f64`, the interpreter over
    /// complex numbers) and warm-start the Jacobi SVDs
    /// from the previous solve's right singular vectors (the default), or
    /// by dual passes over the order-4 jets with SVDs from the identity:
    /// the same solve to round-off. Off, it is the definition the traced
    /// programs are tested against, and the slow path timed beside them.
    pub fn set_traced(&mut self, on: bool) {
        self.trace_on = on;
        self.warm = [false; 2];
        self.forget_trace();
    }

    /// Why the derivative array could not be traced for the scene and
    /// branch in use (`None`: traced, or not tried yet, or not asked for).
    pub fn trace_refused(&self) -> Option<&str> {
        match &self.trace {
            Trace::Refused(why) => Some(why),
            _ => None,
        }
    }

    /// Whether the derivative array runs on traced programs now.
    #[cfg(test)]
    fn is_traced(&self) -> bool {
        matches!(self.trace, Trace::Traced(_))
    }

    /// Drops the traced programs (a new scene or branch).
    fn forget_trace(&mut self) {
        self.trace = Trace::NotYet;
    }

    /// Traces the derivative array where it is asked for and not yet done
    /// or refused. The trace is taken at the real parts of the state (its
    /// values only label the graph's nodes; a trace that holds is the same
    /// function everywhere) and its programs then run over `T`.
    fn ensure_traced<S: Scene>(&mut self, scene: &S, e: &EmbeddingInfo, t: T) {
        if !(self.trace_on && matches!(self.trace, Trace::NotYet)) {
            return;
        }
        let d: Vec<f64> = self.d.iter().map(|x| x.part(0)).collect();
        self.trace = match TracedArray::new(scene, e, t.part(0), &d, &self.near) {
            Ok(a) => {
                let w = a.workspace::<T>();
                Trace::Traced(Box::new((a, w)))
            }
            Err(why) => Trace::Refused(why),
        };
    }

    /// Starts from a consistent completion `d = (q_I⁽⁰⁾ … q_I⁽⁶⁾)` (7m
    /// numbers, `D(d) = 0`): its `u` becomes the warm start, and the rank of
    /// `∂D/∂u` is fixed there (it is structural: for the sleigh `3m − 2`
    /// everywhere off the singular set). Resets the counters.
    pub fn reset<S: Scene>(
        &mut self,
        scene: &S,
        e: &EmbeddingInfo,
        t: T,
        d: &[T],
    ) -> Result<(), String> {
        let m = self.m;
        self.d.copy_from_slice(&d[..7 * m]);
        self.u_good.copy_from_slice(&d[4 * m..7 * m]);
        self.rank_u = None;
        self.solved_at = None;
        self.probed = None;
        self.stats = ReductionStats::default();
        self.warm = [false; 2];
        self.forget_trace();
        self.jacobian(scene, e, t, 4 * m)?;
        self.rank_u = Some(self.kept_rank());
        Ok(())
    }

    /// Rank of the realified `∂D/∂u` in use.
    #[cfg(test)]
    fn rank_u(&self) -> Option<usize> {
        self.rank_u
    }

    /// Follows the branch of the embedding map nearest to `near` from now
    /// on (empty: the principal branch); forgets the last solve.
    pub fn set_branch(&mut self, near: &[f64]) {
        self.near.clear();
        self.near.extend_from_slice(near);
        self.solved_at = None;
        self.probed = None;
        self.forget_trace();
    }

    /// Work counters since [`Reduction::reset`].
    pub fn stats(&self) -> ReductionStats {
        self.stats
    }

    /// `(z, u)` of the last solve.
    pub fn state(&self) -> &[T] {
        &self.d
    }

    /// `w(z) = q⁗`: solves `D(z, u) = 0` for `u` (least squares off the
    /// manifold, see the module documentation). A call at the `(t, z)` of
    /// the previous solve returns its result.
    pub fn fourth<S: Scene>(
        &mut self,
        scene: &S,
        e: &EmbeddingInfo,
        t: T,
        z: &[T],
    ) -> Result<&[T], String> {
        let m = self.m;
        if self.solved_at == Some(t) && self.d[..4 * m] == z[..4 * m] {
            self.stats.cache_hits += 1;
            return Ok(&self.d[4 * m..5 * m]);
        }
        self.solved_at = None;
        self.probed = None;
        self.d[..4 * m].copy_from_slice(&z[..4 * m]);
        self.stats.solves += 1;
        if let Err(msg) = self.iterate(scene, e, t, 4 * m) {
            self.d[4 * m..].copy_from_slice(&self.u_good);
            return Err(msg);
        }
        self.u_good.copy_from_slice(&self.d[4 * m..]);
        self.solved_at = Some(t);
        Ok(&self.d[4 * m..5 * m])
    }

    /// How well `w(z)` is resolved at `(t, z)` (solving there unless the
    /// last solve was there): see [`Resolution`]. The observed part costs
    /// five evaluations of `D` and is measured once per solve, only near
    /// the limit ([`PROBE_FROM`]). No allocation.
    pub fn resolution<S: Scene>(
        &mut self,
        scene: &S,
        e: &EmbeddingInfo,
        t: T,
        z: &[T],
    ) -> Result<Resolution, String> {
        self.fourth(scene, e, t, z)?;
        let conditioning = NOISE_FACTOR * f64::EPSILON * self.kappa;
        let observed = if conditioning >= PROBE_FROM * ODE_RESOLUTION {
            let p = match self.probed {
                Some(p) => p,
                None => self.probe(scene, e, t),
            };
            self.probed = Some(p);
            Some(p)
        } else {
            None
        };
        // Written so that a NaN in either part gives NaN.
        let rho = match observed {
            Some(o) if o.is_nan() || o > conditioning => o,
            _ => conditioning,
        };
        Ok(Resolution {
            rho,
            conditioning,
            observed,
        })
    }

    /// The parts of `value` into `value_parts`.
    fn split_value(&mut self) {
        let p = T::PARTS;
        for (l, v) in self.value.iter().enumerate() {
            for k in 0..p {
                self.value_parts[p * l + k] = v.part(k);
            }
        }
    }

    /// Row `k` (realified) of the pseudo-inverse applied to `x` (realified).
    fn apply_row(&self, k: usize, x: &[f64]) -> f64 {
        let pr = T::PARTS * LEVELS * self.m;
        let row = &self.pinv[k * pr..(k + 1) * pr];
        row.iter().zip(x).map(|(a, b)| a * b).sum()
    }

    /// The observed part of [`Reduction::resolution`] at the solve in `d`
    /// (its pseudo-inverse in `pinv`).
    fn probe<S: Scene>(&mut self, scene: &S, e: &EmbeddingInfo, t: T) -> f64 {
        let m = self.m;
        let p = T::PARTS;
        self.stats.probes += 1;
        self.probe_z.copy_from_slice(&self.d[..4 * m]);
        self.evaluate(scene, e, t);
        self.split_value();
        self.probe_base.copy_from_slice(&self.value_parts);
        // Relative to |q⁗|∞, with the floor of the iteration's measure.
        let floor = 1e-6
            * self.d[m..4 * m]
                .iter()
                .fold(f64::MIN_POSITIVE, |a, v| a.max(v.norm()));
        let scale = self.d[4 * m..5 * m]
            .iter()
            .fold(floor, |a, v| a.max(v.norm()));
        let mut observed = 0.0f64;
        let mut diff = std::mem::take(&mut self.step);
        for trial in 0..PROBE_TRIALS {
            for (i, x) in self.d[..4 * m].iter_mut().enumerate() {
                let pattern = ((i * 7 + trial * 13) % 11) as f64 - 5.0;
                *x = self.probe_z[i] * (1.0 + PROBE_SIZE * pattern);
            }
            self.evaluate(scene, e, t);
            self.split_value();
            let mut change = std::mem::take(&mut self.value_parts);
            for (c, b) in change.iter_mut().zip(&self.probe_base) {
                *c -= b;
            }
            for k in 0..m {
                for q in 0..p {
                    diff[q] = self.apply_row(p * k + q, &change);
                }
                // NaN propagates (max would drop it).
                let rel = T::from_parts(&diff[..p]).norm() / scale;
                observed = if rel.is_nan() { rel } else { observed.max(rel) };
            }
            self.value_parts = change;
        }
        self.step = diff;
        self.d[..4 * m].copy_from_slice(&self.probe_z);
        observed
    }

    /// Moves `q⃛ = z[3m..4m]` onto A's hidden constraints with `q, q̇, q̈`
    /// fixed (Newton on `D = 0` in `(q⃛, u)`); returns the relative change
    /// `|Δq⃛|∞ / |q⃛|∞`.
    pub fn project<S: Scene>(
        &mut self,
        scene: &S,
        e: &EmbeddingInfo,
        t: T,
        z: &mut [T],
    ) -> Result<f64, String> {
        let m = self.m;
        self.d[..4 * m].copy_from_slice(&z[..4 * m]);
        self.solved_at = None;
        self.probed = None;
        self.stats.projections += 1;
        if let Err(msg) = self.iterate(scene, e, t, 3 * m) {
            self.d[4 * m..].copy_from_slice(&self.u_good);
            return Err(format!(
                "projection onto the hidden constraints failed: {msg}"
            ));
        }
        self.u_good.copy_from_slice(&self.d[4 * m..]);
        let scale = z[3 * m..4 * m]
            .iter()
            .fold(f64::MIN_POSITIVE, |a, v| a.max(v.norm()));
        let change = (0..m).fold(0.0f64, |a, k| {
            a.max((self.d[3 * m + k] - z[3 * m + k]).norm())
        });
        z[3 * m..4 * m].copy_from_slice(&self.d[3 * m..4 * m]);
        let rel = change / scale;
        self.stats.max_third_change = self.stats.max_third_change.max(rel);
        Ok(rel)
    }

    /// The chord iteration on the unknowns `d[first..7m]` (`first = 4m`:
    /// `u`; `first = 3m`: `(q⃛, u)`), from the current `d`.
    fn iterate<S: Scene>(
        &mut self,
        scene: &S,
        e: &EmbeddingInfo,
        t: T,
        first: usize,
    ) -> Result<(), String> {
        let m = self.m;
        let p = T::PARTS;
        let cols = 7 * m - first;
        // Watched blocks: q⁗ (and q⃛ in the projection), each relative to
        // its own size, with a floor for a vanishing block.
        let floor = 1e-6
            * self.d[m..4 * m]
                .iter()
                .fold(f64::MIN_POSITIVE, |a, v| a.max(v.norm()));
        self.jacobian(scene, e, t, first)?;
        let mut restarts = 0;
        let mut prev = f64::INFINITY;
        for _ in 0..MAX_ITER {
            self.stats.iterations += 1;
            // Step Δ = P·D, and its size in the watched blocks, relative.
            self.split_value();
            let mut size = 0.0f64;
            for k in 0..cols {
                for q in 0..p {
                    self.step[q] = self.apply_row(p * k + q, &self.value_parts);
                }
                let s = T::from_parts(&self.step[..p]);
                self.d[first + k] -= s;
                let block = (first + k) / m;
                if block < 5 {
                    let range = block * m..(block + 1) * m;
                    let scale = self.d[range].iter().fold(floor, |a, v| a.max(v.norm()));
                    size = size.max(s.norm() / scale);
                }
            }
            if !size.is_finite() {
                return Err("the iteration produced non-finite values".into());
            }
            if size <= SOLVE_RTOL {
                return Ok(());
            }
            // Contraction of the chord iteration (none right after a Jacobian).
            let theta = if prev.is_finite() { size / prev } else { 0.0 };
            if prev.is_finite() && theta < 1.0 && theta / (1.0 - theta) * size <= SOLVE_RTOL {
                return Ok(());
            }
            if theta >= SLOW {
                if restarts > 0 && size <= STAGNATION {
                    // Even with a fresh Jacobian the steps no longer
                    // contract: they are the round-off of the solution.
                    self.stats.stagnations += 1;
                    self.stats.max_stagnation = self.stats.max_stagnation.max(size);
                    return Ok(());
                }
                if restarts == MAX_RESTARTS {
                    return Err(format!(
                        "no convergence (relative step {size:.3e}, contraction {theta:.2}): \
                         round-off in [E; Ė; Ë] no longer determines q⁗ here — their terms \
                         cancel more and more towards the singular set (stop earlier with a \
                         larger singular_tol); the implicit form (radau5) does not use Ë"
                    ));
                }
                restarts += 1;
                self.jacobian(scene, e, t, first)?;
                prev = f64::INFINITY;
                continue;
            }
            prev = size;
            self.evaluate(scene, e, t);
            self.stats.evaluations += 1;
        }
        Err(format!("no convergence in {MAX_ITER} iterations"))
    }

    /// `D` at `d` into `value` (order-4 jet over `T`).
    fn evaluate<S: Scene>(&mut self, scene: &S, e: &EmbeddingInfo, t: T) {
        if let Trace::Traced(traced) = &mut self.trace {
            let (a, w) = (&traced.0, &mut traced.1);
            self.value.copy_from_slice(a.value(w, t, &self.d));
            return;
        }
        elo_array::<_, T, Jet4<T>>(scene, e, t, &self.d, &self.near, &mut self.value);
    }

    /// `D` and `∂D/∂d[first..7m]` at `d`, equilibrated, and its truncated
    /// pseudo-inverse into `pinv`.
    fn jacobian<S: Scene>(
        &mut self,
        scene: &S,
        e: &EmbeddingInfo,
        t: T,
        first: usize,
    ) -> Result<(), String> {
        let m = self.m;
        let p = T::PARTS;
        let rows = LEVELS * m;
        let cols = 7 * m - first;
        self.stats.jacobians += 1;
        let zero = T::from(0.0);
        self.ensure_traced(scene, e, t);
        if matches!(self.trace, Trace::Traced(_)) {
            self.traced_columns(t, first);
        } else {
            self.dual_columns(scene, e, t, first);
        }
        // A projection has ∂E/∂q⃛ as the top block of its q⃛ columns.
        if first == 3 * m {
            for j in 0..m {
                for mu in 0..m {
                    self.e3[j * m + mu] = self.jac[j * rows + mu];
                }
            }
        }
        // Structural columns: q⁽⁵⁾ → [0; W; 2Q − ∂E/∂q⃛], q⁽⁶⁾ → [0; 0; W].
        let c4 = 4 * m - first;
        let (c5, c6) = (c4 + m, c4 + 2 * m);
        for j in 0..m {
            for mu in 0..m {
                let w = self.jac[(c4 + j) * rows + mu];
                let q = self.jac[(c4 + j) * rows + m + mu];
                let col5 = (c5 + j) * rows;
                let col6 = (c6 + j) * rows;
                self.jac[col5 + mu] = zero;
                self.jac[col5 + m + mu] = w;
                self.jac[col5 + 2 * m + mu] = q * 2.0 - self.e3[j * m + mu];
                self.jac[col6 + mu] = zero;
                self.jac[col6 + m + mu] = zero;
                self.jac[col6 + 2 * m + mu] = w;
            }
        }
        // One weight per derivative level, from the u-independent blocks
        // (W; Q, W; 2Q − ∂E/∂q⃛, W): a function of z alone, invariant under
        // rotations of the coordinates.
        for l in 0..LEVELS {
            let blocks = match l {
                0 => c4..c5,
                1 => c4..c6,
                _ => c5..c6 + m,
            };
            let mut sum = 0.0;
            for c in blocks {
                for mu in 0..m {
                    sum += self.jac[c * rows + l * m + mu].norm().powi(2);
                }
            }
            let s = if sum > 0.0 && sum.is_finite() {
                sum.sqrt()
            } else {
                1.0
            };
            self.row_scale[l * m..(l + 1) * m].fill(s);
        }
        // One scale per block of unknowns (does not change the solution,
        // only the conditioning and the minimum-norm choice of free parts).
        for b in 0..cols / m {
            let mut sum = 0.0;
            for c in b * m..(b + 1) * m {
                for i in 0..rows {
                    sum += (self.jac[c * rows + i].norm() / self.row_scale[i]).powi(2);
                }
            }
            let s = (sum / m as f64).sqrt();
            let s = if s > 0.0 && s.is_finite() { s } else { 1.0 };
            self.col_scale[b * m..(b + 1) * m].fill(s);
        }
        let finite = |x: &T| (0..p).all(|k| x.part(k).is_finite());
        if !self.value[..rows].iter().all(finite) || !self.jac[..rows * cols].iter().all(finite) {
            return Err("the derivative array is not finite here".into());
        }
        // The realified equilibrated matrix: complex entry w at (i, c) is
        // the block [[re, −im], [im, re]] at rows p·i.., columns p·c...
        let pr = p * rows;
        for c in 0..cols {
            for i in 0..rows {
                let w = self.jac[c * rows + i] / (self.row_scale[i] * self.col_scale[c]);
                for b in 0..p {
                    for a in 0..p {
                        // Column p·c + b, row p·i + a: re on the diagonal,
                        // ∓im off it.
                        let x = match (a, b) {
                            (0, 0) | (1, 1) => w.part(0),
                            (1, 0) => w.part(1),
                            _ => -w.part(1),
                        };
                        self.a[(p * c + b) * pr + p * i + a] = x;
                    }
                }
            }
        }
        self.pseudo_inverse(first)
    }

    /// `D` into `value`, the order-4 columns (`q⃛` for a projection, `q⁗`)
    /// of `∂D/∂d[first..]` into `jac` and, for a solve, `∂E/∂q⃛` into `e3`,
    /// by dual passes over the jets: `5m − first` order-4 passes (the first
    /// also gives `D`) and, for a solve, `m` order-2 passes.
    fn dual_columns<S: Scene>(&mut self, scene: &S, e: &EmbeddingInfo, t: T, first: usize) {
        let m = self.m;
        let rows = LEVELS * m;
        let tt = Dual::from_re(t);
        // Order-4 dual passes for the columns that need them: q⃛ (projection
        // only) and q⁗. The first pass also gives D.
        let passes = 5 * m - first;
        for k in 0..passes {
            for (x, &v) in self.d_dual.iter_mut().zip(&self.d) {
                *x = Dual::from_re(v);
            }
            self.d_dual[first + k].eps = T::from(1.0);
            elo_array::<_, Dual<T>, Jet4<Dual<T>>>(
                scene,
                e,
                tt,
                &self.d_dual,
                &self.near,
                &mut self.out_dual,
            );
            for i in 0..rows {
                self.jac[k * rows + i] = self.out_dual[i].eps;
            }
            if k == 0 {
                for i in 0..rows {
                    self.value[i] = self.out_dual[i].re;
                }
            }
        }
        // ∂E/∂q⃛ of a solve: m order-2 passes.
        if first == 4 * m {
            for j in 0..m {
                for (x, &v) in self.d_dual.iter_mut().zip(&self.d) {
                    *x = Dual::from_re(v);
                }
                self.d_dual[3 * m + j].eps = T::from(1.0);
                elo_array::<_, Dual<T>, Dual2<Dual<T>>>(
                    scene,
                    e,
                    tt,
                    &self.d_dual[..5 * m],
                    &self.near,
                    &mut self.out_dual[..m],
                );
                for mu in 0..m {
                    self.e3[j * m + mu] = self.out_dual[mu].eps;
                }
            }
        }
    }

    /// [`Reduction::dual_columns`] by the traced programs: one run.
    fn traced_columns(&mut self, t: T, first: usize) {
        let m = self.m;
        let rows = LEVELS * m;
        let Trace::Traced(traced) = &mut self.trace else {
            unreachable!("called with a trace")
        };
        let (a, w) = (&traced.0, &mut traced.1);
        let out = if first == 4 * m {
            a.solve(w, t, &self.d)
        } else {
            a.project(w, t, &self.d)
        };
        self.value.copy_from_slice(&out[..rows]);
        let columns = (5 * m - first) * rows;
        self.jac[..columns].copy_from_slice(&out[rows..rows + columns]);
        if first == 4 * m {
            let e3 = self.e3.len();
            self.e3
                .copy_from_slice(&out[rows + columns..rows + columns + e3]);
        }
    }

    /// One-sided Jacobi SVD of the realified equilibrated Jacobian in `a`
    /// and the truncated pseudo-inverse (`rank_u` for a solve, numerical
    /// rank for a projection), scalings folded in.
    fn pseudo_inverse(&mut self, first: usize) -> Result<(), String> {
        let m = self.m;
        let p = T::PARTS;
        let rows = p * LEVELS * m;
        let cols = p * (7 * m - first);
        // Warm start: the right singular vectors of the previous SVD of this
        // kind (solve or projection) nearly diagonalise this one's matrix,
        // so the sweeps start from A·V₀ (one sweep for a repeated solve at
        // one state, six from the identity; along a run not measured).
        let kind = usize::from(first != 4 * m);
        if self.warm[kind] && self.drift[kind] >= REORTHONORMALIZE_AFTER {
            self.warm[kind] = orthonormalize(&mut self.warm_v[kind][..cols * cols], cols);
            self.drift[kind] = 0;
        }
        let warm = self.warm[kind];
        if !warm {
            self.drift[kind] = 0;
        }
        let (a, v) = (&mut self.a, &mut self.v);
        if warm {
            let w = &self.warm_v[kind][..cols * cols];
            let row = &mut self.norms[..cols];
            for i in 0..rows {
                for (r, wc) in row.iter_mut().zip(w.chunks_exact(cols)) {
                    *r = a[i..]
                        .iter()
                        .step_by(rows)
                        .zip(wc)
                        .map(|(x, y)| x * y)
                        .sum();
                }
                for (c, &r) in row.iter().enumerate() {
                    a[c * rows + i] = r;
                }
            }
            v[..cols * cols].copy_from_slice(w);
        } else {
            v[..cols * cols].fill(0.0);
            for c in 0..cols {
                v[c * cols + c] = 1.0;
            }
        }
        self.warm[kind] = false;
        let total: f64 = a[..rows * cols].iter().map(|x| x * x).sum();
        let negligible = (f64::EPSILON * f64::EPSILON) * total;
        let tol = f64::EPSILON * rows as f64 / p as f64;
        let mut rotations = 0;
        for _sweep in 0..60 {
            self.stats.sweeps += 1;
            let mut rotated = false;
            for pc in 0..cols - 1 {
                for qc in pc + 1..cols {
                    let (mut alpha, mut beta, mut gamma) = (0.0, 0.0, 0.0);
                    let (ap, aq) = (&a[pc * rows..][..rows], &a[qc * rows..][..rows]);
                    for (&x, &y) in ap.iter().zip(aq) {
                        alpha += x * x;
                        beta += y * y;
                        gamma += x * y;
                    }
                    if alpha <= negligible
                        || beta <= negligible
                        || gamma.abs() <= tol * (alpha * beta).sqrt()
                        || gamma.abs() <= PINV_RTOL * alpha.min(beta)
                    {
                        continue;
                    }
                    rotated = true;
                    rotations += 1;
                    let zeta = (beta - alpha) / (2.0 * gamma);
                    let tan = zeta.signum() / (zeta.abs() + (1.0 + zeta * zeta).sqrt());
                    let cos = 1.0 / (1.0 + tan * tan).sqrt();
                    let sin = cos * tan;
                    for i in 0..rows {
                        let (x, y) = (a[pc * rows + i], a[qc * rows + i]);
                        a[pc * rows + i] = cos * x - sin * y;
                        a[qc * rows + i] = sin * x + cos * y;
                    }
                    for i in 0..cols {
                        let (x, y) = (v[pc * cols + i], v[qc * cols + i]);
                        v[pc * cols + i] = cos * x - sin * y;
                        v[qc * cols + i] = sin * x + cos * y;
                    }
                }
            }
            if !rotated {
                break;
            }
        }
        if self.trace_on && v[..cols * cols].iter().all(|x| x.is_finite()) {
            self.warm_v[kind][..cols * cols].copy_from_slice(&v[..cols * cols]);
            self.warm[kind] = true;
            self.drift[kind] += rotations;
        }
        for c in 0..cols {
            self.norms[c] = a[c * rows..(c + 1) * rows]
                .iter()
                .map(|x| x * x)
                .sum::<f64>()
                .sqrt();
            self.order[c] = c;
        }
        let norms = &self.norms;
        self.order[..cols].sort_unstable_by(|&i, &j| norms[j].total_cmp(&norms[i]));
        let top = norms[self.order[0]];
        let numerical = (0..cols).filter(|&c| norms[c] > RANK_RTOL * top).count();
        let rank = match (first == 4 * m, self.rank_u) {
            (true, Some(r)) => r,
            _ => numerical,
        };
        if rank == 0 || norms[self.order[rank - 1]] <= 1e-14 * top {
            return Err(format!(
                "the Jacobian of the derivative array lost rank (expected {rank}, numerical {numerical})"
            ));
        }
        if first == 4 * m {
            self.kappa = top / norms[self.order[rank - 1]];
        }
        // P = C⁻¹ V Σ⁻² (AV)ᵀ R⁻¹ over the kept singular triplets.
        self.pinv[..cols * rows].fill(0.0);
        for &j in &self.order[..rank] {
            let s2 = norms[j] * norms[j];
            let aj = &self.a[j * rows..][..rows];
            let vj = &self.v[j * cols..][..cols];
            for (&v, pk) in vj.iter().zip(self.pinv.chunks_exact_mut(rows)) {
                let vk = v / s2;
                if vk == 0.0 {
                    continue;
                }
                for (x, &y) in pk.iter_mut().zip(aj) {
                    *x += vk * y;
                }
            }
        }
        for (k, pk) in self.pinv[..cols * rows].chunks_exact_mut(rows).enumerate() {
            let ck = self.col_scale[k / p];
            for (l, x) in pk.iter_mut().enumerate() {
                *x /= ck * self.row_scale[l / p];
            }
        }
        Ok(())
    }

    /// Number of singular values kept by the last pseudo-inverse's rule.
    fn kept_rank(&self) -> usize {
        let cols = T::PARTS * 3 * self.m;
        let top = self.norms[self.order[0]];
        (0..cols)
            .filter(|&c| self.norms[c] > RANK_RTOL * top)
            .count()
    }
}

/// Makes the columns of the `n × n` column-major `v`, orthonormal up to
/// the round-off of the rotations that made it, orthonormal again (one pass
/// of modified Gram–Schmidt: the error does not grow from SVD to SVD);
/// `false` (and `v` unusable) where a column has lost its direction or is
/// not finite.
fn orthonormalize(v: &mut [f64], n: usize) -> bool {
    for c in 0..n {
        for k in 0..c {
            let dot: f64 = (0..n).map(|i| v[k * n + i] * v[c * n + i]).sum();
            for i in 0..n {
                v[c * n + i] -= dot * v[k * n + i];
            }
        }
        let norm = v[c * n..(c + 1) * n]
            .iter()
            .map(|x| x * x)
            .sum::<f64>()
            .sqrt();
        if norm.is_nan() || norm < 0.5 {
            return false;
        }
        for x in &mut v[c * n..(c + 1) * n] {
            *x /= norm;
        }
    }
    true
}

impl Reduction<f64> {
    /// How far `z` is from A's hidden constraints: after solving for `u` as
    /// the right-hand side does, `max_l |D_l(z, u)| / (1 + Σ_j |∂D_l/∂d_j d_j|)`
    /// — the residual left in each row relative to the terms that cancel in
    /// it (the measure of [`crate::analysis::complete`]). Round-off level on
    /// the manifold. A diagnostic (full derivative-array Jacobian; allocates).
    pub fn hidden_residual<S: Scene>(
        &mut self,
        scene: &S,
        e: &EmbeddingInfo,
        t: f64,
        z: &[f64],
    ) -> Result<f64, String> {
        let m = self.m;
        self.fourth(scene, e, t, z)?;
        let rows = LEVELS * m;
        let mut value = vec![0.0; rows];
        let mut jac = DMatrix::zeros(rows, 7 * m);
        derivative_array(scene, e, t, &self.d, &self.near, &mut value, &mut jac);
        let mut scales = vec![0.0; rows];
        row_scales(&jac, &self.d, &mut scales);
        Ok(relative(&value, &scales))
    }

    /// The Jacobian of the last solve in the unknowns (`3m × cols`), for tests.
    #[cfg(test)]
    fn jacobian_matrix(&self, first: usize) -> DMatrix<f64> {
        let rows = LEVELS * self.m;
        let cols = 7 * self.m - first;
        DMatrix::from_column_slice(rows, cols, &self.jac[..rows * cols])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::complete;
    use nonholo_core::{Params, Scene};
    use nonholo_scenes::Sleigh;

    /// The default sleigh with `potential`.
    fn sleigh(potential: &str) -> Sleigh {
        let given = vec![("potential".to_string(), potential.to_string())];
        Sleigh::from_params(&Params::resolve(Sleigh::INFO.params, &given, "parameter").unwrap())
            .unwrap()
    }

    /// A consistent point of the sleigh: `(q, q̇, q̈)` given, `q⃛` and `u`
    /// completed.
    fn consistent(s: &Sleigh) -> Vec<f64> {
        let e = Sleigh::INFO.embedding.unwrap();
        let mut d = vec![0.0; 14];
        d[..6].copy_from_slice(&[0.3, -0.2, 1.9, 0.5, 0.4, 2.6]);
        complete(s, &e, 0.0, &mut d, true, 1e-14).unwrap();
        d
    }

    /// The structural Jacobian (identities of the derivative array) equals
    /// the full AD Jacobian of `derivative_array` column by column, for the
    /// solve (`u`) and the projection (`q⃛, u`), with the array from the
    /// traced programs and from the dual passes (`D` to round-off of the
    /// terms that cancel in it: 1e-13 of the largest term of its row,
    /// `Σ_j |∂D/∂d_j d_j|`).
    #[test]
    fn structural_jacobian_matches_full_ad() {
        for potential in ["paper", "com"] {
            let s = sleigh(potential);
            let e = Sleigh::INFO.embedding.unwrap();
            let mut d = consistent(&s);
            // Off the manifold and away from the solution: the identities
            // hold everywhere.
            d[7] += 0.01;
            d[9] -= 0.3;
            d[11] += 0.7;
            let mut value = vec![0.0; 6];
            let mut full = DMatrix::zeros(6, 14);
            derivative_array(&s, &e, 0.0, &d, &[], &mut value, &mut full);
            let terms: Vec<f64> = (0..6)
                .map(|l| (0..14).map(|j| (full[(l, j)] * d[j]).abs()).sum())
                .collect();
            for traced in [true, false] {
                let mut r = Reduction::new(2);
                r.set_traced(traced);
                for first in [8, 6] {
                    r.d.copy_from_slice(&d);
                    r.jacobian(&s, &e, 0.0, first).unwrap();
                    let jac = r.jacobian_matrix(first);
                    let want = full.columns(first, 14 - first);
                    let scale = want.amax();
                    assert!(
                        (&jac - want).amax() <= 1e-13 * scale,
                        "traced {traced}, first = {first}:\n{jac:.6e}\n{want:.6e}"
                    );
                    for l in 0..6 {
                        let err = (r.value[l] - value[l]).abs();
                        assert!(err <= 1e-13 * terms[l], "traced {traced}, row {l}: {err:e}");
                    }
                }
                assert_eq!(r.trace_refused(), None);
            }
        }
    }

    /// Over complex numbers (the continuation's half circles) the traced
    /// programs, run in the interpreter over `C64`, give `D` and the
    /// Jacobian's columns of the dual passes over `Dual<C64>` to round-off
    /// (1e-13 of the largest entry), for the solve and the projection, on
    /// the principal branch and on the next one, at a state whose
    /// imaginary parts are a tenth of its real parts and at one with the
    /// velocity nearly imaginary (near the singular set, where a reversal
    /// is passed).
    #[test]
    fn traced_programs_over_complex_numbers_match_the_dual_passes() {
        use nonholo_core::complex::C64;
        for potential in ["paper", "com"] {
            let s = sleigh(potential);
            let e = Sleigh::INFO.embedding.unwrap();
            let d = consistent(&s);
            let tilted: Vec<C64> = d
                .iter()
                .enumerate()
                .map(|(j, &x)| C64::new(x, 0.1 * x * if j % 2 == 0 { 1.0 } else { -1.0 }))
                .collect();
            let mut turning = tilted.clone();
            // ẋ, ẏ: a small real part and a larger imaginary one.
            turning[2] = C64::new(0.02, 0.3);
            turning[3] = C64::new(-0.01, 0.2);
            for (state, near) in [(&tilted, vec![]), (&turning, vec![]), (&tilted, vec![8.0])] {
                let t = C64::new(0.1, 0.05);
                let mut runs = Vec::new();
                for traced in [true, false] {
                    let mut r = Reduction::<C64>::new(2);
                    r.set_traced(traced);
                    r.set_branch(&near);
                    let mut out = Vec::new();
                    for first in [8, 6] {
                        r.d.copy_from_slice(state);
                        r.jacobian(&s, &e, t, first).unwrap();
                        out.extend_from_slice(&r.value);
                        out.extend_from_slice(&r.jac[..6 * (14 - first)]);
                    }
                    assert_eq!(r.is_traced(), traced);
                    assert_eq!(r.stats().jacobians, 2);
                    runs.push(out);
                }
                let scale = runs[1].iter().fold(0.0f64, |s, x| s.max(x.norm()));
                for (k, (a, b)) in runs[0].iter().zip(&runs[1]).enumerate() {
                    assert!(
                        (*a - *b).norm() <= 1e-13 * scale,
                        "{potential}, near {near:?}, entry {k}: traced {a}, dual passes {b}"
                    );
                }
            }
        }
    }

    /// Off the manifold `w` is the weighted least-squares solution with the
    /// Jacobian at the solution (`Jᵀ R⁻² D = 0`), whatever the warm start:
    /// a function of `z` alone.
    #[test]
    fn off_manifold_solution_is_independent_of_the_warm_start() {
        let s = Sleigh::from_params(&Params::defaults(Sleigh::INFO.params)).unwrap();
        let e = Sleigh::INFO.embedding.unwrap();
        let d = consistent(&s);
        let mut z = d[..8].to_vec();
        // Off the hidden constraints by 1e-3 relative in q⃛.
        z[6] *= 1.001;
        z[7] *= 0.999;
        let mut r = Reduction::new(2);
        r.reset(&s, &e, 0.0, &d).unwrap();
        let w1 = r.fourth(&s, &e, 0.0, &z).unwrap().to_vec();
        // Warm start far off: u scaled by 1.3 and shifted.
        let mut far = d.clone();
        for v in far[8..].iter_mut() {
            *v = 1.3 * *v + 0.5;
        }
        r.reset(&s, &e, 0.0, &far).unwrap();
        let w2 = r.fourth(&s, &e, 0.0, &z).unwrap().to_vec();
        let scale = w1[0].abs().max(w1[1].abs());
        assert!(
            (w1[0] - w2[0]).abs().max((w1[1] - w2[1]).abs()) <= 1e-12 * scale,
            "{w1:?} vs {w2:?}"
        );
        // Stationarity with the Jacobian at the solution: Jᵀ R⁻² D = 0
        // relative to the terms of the product (whose round-off, through
        // the large level-2 entries, is ~1e-10 of them).
        let (mut value, mut full) = (vec![0.0; 6], DMatrix::zeros(6, 14));
        derivative_array(&s, &e, 0.0, &r.d, &[], &mut value, &mut full);
        let hidden = value.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        assert!(hidden > 1e-6, "the point is off the manifold: {value:?}");
        let ju = full.columns(8, 6);
        let (mut worst, mut size) = (0.0f64, 0.0f64);
        for k in 0..6 {
            let mut g = 0.0;
            for l in 0..6 {
                let term = ju[(l, k)] * value[l] / r.row_scale[l].powi(2);
                g += term;
                size = size.max(term.abs());
            }
            worst = worst.max(g.abs());
        }
        assert!(worst <= 1e-8 * size, "{worst:e} of {size:e}");
    }

    /// The resolution at a well-resolved state: the conditioning estimate
    /// alone (no probe), the solve reused at the same `(t, z)`; the probe
    /// leaves the solve untouched and sees round-off only.
    #[test]
    fn resolution_reuses_the_solve_and_probe_restores_it() {
        let s = Sleigh::from_params(&Params::defaults(Sleigh::INFO.params)).unwrap();
        let e = Sleigh::INFO.embedding.unwrap();
        let d = consistent(&s);
        let mut r = Reduction::new(2);
        r.reset(&s, &e, 0.0, &d).unwrap();
        let z = d[..8].to_vec();
        let w = r.fourth(&s, &e, 0.0, &z).unwrap().to_vec();
        let before = r.stats();
        let res = r.resolution(&s, &e, 0.0, &z).unwrap();
        assert_eq!(r.stats().solves, before.solves);
        assert_eq!(r.stats().cache_hits, before.cache_hits + 1);
        assert!(res.observed.is_none() && res.rho == res.conditioning);
        assert!(res.rho > f64::EPSILON && res.rho < 1e-12, "{res:?}");
        // Another time or state is solved anew.
        r.fourth(&s, &e, 1e-9, &z).unwrap();
        assert_eq!(r.stats().solves, before.solves + 1);
        r.fourth(&s, &e, 0.0, &z).unwrap();
        let solved = r.d.clone();
        let observed = r.probe(&s, &e, 0.0);
        assert_eq!(r.d, solved);
        assert!(observed > 0.0 && observed < 1e-12, "{observed:e}");
        let again = r.fourth(&s, &e, 0.0, &z).unwrap();
        assert_eq!(again, &solved[8..10]);
        assert!((again[0] - w[0]).abs() <= 1e-12 * w[0].abs().max(w[1].abs()));
    }

    /// Warm-started SVDs: from the identity an SVD takes six sweeps here;
    /// repeated solves at one state (the time moved by one unit in the last
    /// place, so that the cache does not answer) take one sweep each once
    /// the stored vectors diagonalise the matrix, also right after the
    /// vectors are made orthonormal again (as after
    /// [`REORTHONORMALIZE_AFTER`] rotations), and give the `q⁗` of a solve
    /// by the dual passes with an SVD from the identity to round-off (1e-13
    /// relative).
    #[test]
    fn warm_started_solves_take_one_sweep() {
        let s = Sleigh::from_params(&Params::defaults(Sleigh::INFO.params)).unwrap();
        let e = Sleigh::INFO.embedding.unwrap();
        let d = consistent(&s);
        let z = d[..8].to_vec();
        let mut cold = Reduction::new(2);
        cold.set_traced(false);
        cold.reset(&s, &e, 0.0, &d).unwrap();
        let want = cold.fourth(&s, &e, 0.0, &z).unwrap().to_vec();
        // Without warm starts every SVD starts from the identity: six
        // sweeps each here (measured: 12 in the 2 SVDs of reset and solve).
        let c = cold.stats();
        assert!(
            (5 * c.jacobians..=7 * c.jacobians).contains(&c.sweeps),
            "{c:?}"
        );
        let scale = want[0].abs().max(want[1].abs());
        let mut r = Reduction::new(2);
        r.set_traced(true);
        r.reset(&s, &e, 0.0, &d).unwrap();
        let mut t = 0.0f64;
        for _ in 0..3 {
            t = f64::from_bits(t.to_bits() ^ 1);
            r.fourth(&s, &e, t, &z).unwrap();
        }
        // A solve that rotates nothing adds no drift: make the next one
        // start from re-orthonormalised vectors, as after 256 rotations.
        r.drift = [REORTHONORMALIZE_AFTER; 2];
        let (before, repeats) = (r.stats(), 2 * REORTHONORMALIZE_AFTER);
        for k in 0..repeats {
            t = f64::from_bits(t.to_bits() ^ 1);
            let w = r.fourth(&s, &e, t, &z).unwrap();
            let err = (w[0] - want[0]).abs().max((w[1] - want[1]).abs());
            assert!(err <= 1e-13 * scale, "{err:e} of {scale:e}");
            if k == 0 {
                assert_eq!(r.drift[0], 0, "the solve re-orthonormalised");
                assert!(r.warm[0]);
            }
        }
        let after = r.stats();
        assert_eq!(after.solves - before.solves, repeats);
        let per_svd =
            (after.sweeps - before.sweeps) as f64 / (after.jacobians - before.jacobians) as f64;
        assert_eq!(per_svd, 1.0, "{before:?}\n{after:?}");
    }

    /// The pseudo-inverse is the Moore–Penrose inverse of the (weighted)
    /// Jacobian: `J P J = J`, `P J P = P`, with the structural rank 4.
    #[test]
    fn pseudo_inverse_properties() {
        let s = Sleigh::from_params(&Params::defaults(Sleigh::INFO.params)).unwrap();
        let e = Sleigh::INFO.embedding.unwrap();
        let d = consistent(&s);
        let mut r = Reduction::new(2);
        r.reset(&s, &e, 0.0, &d).unwrap();
        assert_eq!(r.rank_u(), Some(4));
        for first in [8, 6] {
            r.d.copy_from_slice(&d);
            r.jacobian(&s, &e, 0.0, first).unwrap();
            let j = r.jacobian_matrix(first);
            let cols = 14 - first;
            let p = DMatrix::from_row_slice(cols, 6, &r.pinv[..cols * 6]);
            let jpj = &j * &p * &j;
            assert!((&jpj - &j).amax() <= 1e-10 * j.amax(), "first = {first}");
            let pjp = &p * &j * &p;
            assert!((&pjp - &p).amax() <= 1e-10 * p.amax(), "first = {first}");
        }
    }
}
