//! Formulation A as a model: the implicit system `F(t, z, ż) = 0` in
//! `z = (q_I, q̇_I, q̈_I, q⃛_I)`, its initial data, and its physical reading.
//!
//! ```text
//! F = [ ż₀ − z₁ ;  ż₁ − z₂ ;  ż₂ − z₃ ;  E(z, ż₃) ]        (E: eq. 19)
//! ```
//!
//! `∂F/∂z` and `∂F/∂ż` come from dual passes through `E` (the block
//! `∂E/∂ż₃ = W` included). Integrated by Radau IIA as a differential-algebraic
//! system; the rank of `W`, the hidden constraints and the free initial data
//! are computed at the start and reported.
//!
//! The same model also offers an explicit form `ż = (z₁, z₂, z₃, w(z))`, with
//! `w = q_I⁗` from A's derivative array (see [`crate::ode`]), for RK4, DOPRI5
//! and DOP853; option `stab` projects `q⃛` back onto the hidden constraints
//! after every accepted step. Both forms share the guard at the embedding
//! map's singular set and the refusal of stages that cross it; the explicit
//! form's guard also stops it where `q⁗` is no longer resolved to
//! [`ODE_RESOLUTION`] (the derivative array's round-off grows towards the
//! singular set), before its solve would fail.

use nonholo_core::consistency::{InitProjection, check_or_project};
use nonholo_core::guard::{SingularGuard, magnitude};
use nonholo_core::init::{ExtraName, lambda_names};
use nonholo_core::integrate::{ImplicitSystem, OdeSystem, RadauNewton, SystemError};
use nonholo_core::model::{Description, FormulationInfo, Model, Observation};
use nonholo_core::monitor::Monitor;
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::scene::{EmbeddingInfo, MAX_SINGULAR, Scene, SceneInfo};
use nonholo_core::{Diagnostics, Error, Initial};
use num_dual::{Dual2, Dual2_64, Dual64};

use crate::analysis::{Completion, RANK_TOL, Structure, complete, structure, svd_of};
use crate::elo::{MAX_DOF, elo_array, reconstruct};
use crate::ode::{ODE_RESOLUTION, Reduction, ReductionStats, Resolution};

/// Where the run stops near the embedding map's singular set.
pub const SINGULAR_TOL: ParamSpec = ParamSpec::real(
    "singular_tol",
    "",
    1e-3,
    Bound::Exclusive(0.0),
    Bound::Unbounded,
    "the run stops where the embedding map's regularity measure (sleigh: speed √(ẋ² + ẏ²), m/s) \
     falls to this value; the equations scale like 1/speed² near it",
);

/// Whether the map may put the dependent coordinates on another branch than given.
pub const BRANCH: ParamSpec = ParamSpec::choice(
    "branch",
    &["strict", "map"],
    "strict: refuse initial data whose dependent coordinates differ from the embedding map's \
     value (e.g. a sleigh moving backwards, where atan2(ẏ, ẋ) = φ + π); map: take the map's \
     value and report the difference (the branch effect of the spec)",
);

/// Stabilisation of the hidden constraints in the explicit form.
pub const STAB: ParamSpec = ParamSpec::choice(
    "stab",
    &["projection", "none"],
    "explicit integrators (RK4, DOPRI5, DOP853) only: after every accepted step move q⃛ back \
     onto A's hidden constraints with q, q̇, q̈ fixed (projection), or let them drift (none); \
     Radau integrates the implicit form and ignores it",
);

/// Relative tolerance to which initial data are made consistent with the
/// hidden constraints (round-off level of the derivative array's terms).
pub const HIDDEN_RTOL: f64 = 1e-14;

/// Relative residual of the hidden constraints above which given third
/// derivatives are refused as inconsistent (rather than refined).
pub const HIDDEN_CHECK_RTOL: f64 = 1e-8;

/// Options of formulation A.
pub const OPTIONS: &[ParamSpec] = &[SINGULAR_TOL, BRANCH, STAB];

pub const INFO: FormulationInfo = FormulationInfo {
    name: "embedding",
    letter: "A",
    title: "Hamilton-principle embedding (the seed paper)",
    description: "the constraint substituted into L via q_D = φ(q_I, q̇_I, t); Euler–Lagrange–\
                  Ostrogradsky equations (19) of Θ, fourth order in q_I, integrated as an implicit \
                  (differential-algebraic) system in z = (q_I, q̇_I, q̈_I, q⃛_I) by Radau, or by \
                  explicit methods as the ODE z' = (z₁, z₂, z₃, q⁗(z)) with q⁗ from the derivative \
                  array [E; Ė; Ë] = 0",
    options: OPTIONS,
    applicable,
};

fn applicable(scene: &SceneInfo) -> Result<(), String> {
    let Some(e) = &scene.embedding else {
        return Err(if scene.s() == 0 {
            "the scene has no nonholonomic constraints to embed".into()
        } else {
            "the scene provides no embedding map q_D = φ(q_I, q̇_I, t) (eq. 14); for general \
             constraints (eq. 27–30) the map needs ψ from integrating eq. (28), which this scene \
             cannot provide"
                .into()
        });
    };
    if scene.k() > 0 {
        return Err("holonomic constraints are not part of the paper's embedding (§3)".into());
    }
    if scene.n() > MAX_DOF {
        return Err(format!("at most {MAX_DOF} coordinates are supported"));
    }
    if e.dependent.len() != scene.s() {
        return Err("the embedding map must solve every nonholonomic constraint".into());
    }
    Ok(())
}

/// What the set-up of A's initial data found and did.
#[derive(Debug, Clone, PartialEq)]
pub struct InitReport {
    pub structure: Structure,
    /// The completion or check of the hidden constraints.
    pub completion: Completion,
    /// Whether `q⃛_I(0)` was given (else computed from the hidden constraints).
    pub third_given: bool,
    /// `map value − given value` of each dependent coordinate (0 unless
    /// `branch = map` moved it).
    pub branch_shift: Vec<f64>,
}

/// Formulation A bound to a scene.
pub struct Embedding<S: Scene> {
    scene: S,
    options: Params,
    e: EmbeddingInfo,
    n: usize,
    m: usize,
    guard: SingularGuard,
    r: [f64; MAX_SINGULAR],
    branch_map: bool,
    /// Derivatives `(q_I⁽⁰⁾ … q_I⁽⁴⁾)` for one residual.
    d: Vec<f64>,
    d_dual: Vec<Dual64>,
    e_out: Vec<f64>,
    e_dual: Vec<Dual64>,
    monitor: Monitor,
    q: Vec<f64>,
    qd: Vec<f64>,
    /// Last reported dependent coordinates, for unwrapping angles.
    last_dep: Vec<f64>,
    yp0: Vec<f64>,
    report: Option<InitReport>,
    /// The explicit form's solve for `q⁗` and its warm start.
    reduction: Reduction,
    /// `stab = projection` (explicit form only).
    project_hidden: bool,
    /// `(t, before, after)` hidden-constraint residuals per accepted step of
    /// the explicit form, if asked for ([`Embedding::record_hidden`]).
    hidden_log: Option<Vec<[f64; 3]>>,
    /// What the explicit form's last guard evaluation that was `<= 0` (or
    /// NaN) measured: the integrator asks for the reason at exactly that
    /// state (the contract of `OdeSystem::guard_reason`), which then reports
    /// what fired there.
    stop_record: Option<Result<Resolution, String>>,
}

/// Initial data that contradict A's own equations.
fn inconsistent(reason: String) -> Error {
    Error::InconsistentInit {
        formulation: INFO.name,
        reason,
    }
}

/// Names of the derivatives A accepts in `--init` for coordinate `c`.
fn derivative_name(c: &str, order: usize) -> String {
    match order {
        2 => format!("{c}_ddot"),
        3 => format!("{c}_dddot"),
        _ => unreachable!("only second and third derivatives are initial data"),
    }
}

impl<S: Scene> Embedding<S> {
    pub fn new(scene: S, options: Params) -> Result<Self, Error> {
        let info = scene.info();
        applicable(info).map_err(|reason| Error::NotApplicable {
            formulation: INFO.name.into(),
            scene: info.name.into(),
            reason,
        })?;
        let e = info.embedding.expect("checked by applicable");
        let (n, m) = (info.n(), e.independent.len());
        Ok(Embedding {
            guard: SingularGuard::new(options.real(SINGULAR_TOL.name)?),
            r: [0.0; MAX_SINGULAR],
            branch_map: options.choice(BRANCH.name)? == "map",
            project_hidden: options.choice(STAB.name)? == "projection",
            options,
            e,
            n,
            m,
            d: vec![0.0; 5 * m],
            d_dual: vec![Dual64::from_re(0.0); 5 * m],
            e_out: vec![0.0; m],
            e_dual: vec![Dual64::from_re(0.0); m],
            monitor: Monitor::new(&scene),
            q: vec![0.0; n],
            qd: vec![0.0; n],
            last_dep: vec![0.0; e.dependent.len()],
            yp0: Vec::new(),
            report: None,
            reduction: Reduction::new(m),
            hidden_log: None,
            stop_record: None,
            scene,
        })
    }

    /// What the initial-data set-up found (after [`Model::initial_state`]).
    pub fn report(&self) -> Option<&InitReport> {
        self.report.as_ref()
    }

    /// Makes `E(z, q⁗) = 0` hold to round-off at the initial state: E is
    /// linear in q⁗ with coefficient W, so a least-squares correction
    /// `W δ = −E` (minimum norm, W singular) removes what the completion's
    /// relative tolerance left; the integrator then starts from `F = 0`.
    fn polish_fourth(&mut self, t: f64, d: &mut [f64]) {
        let m = self.m;
        for _ in 0..3 {
            self.d.copy_from_slice(&d[..5 * m]);
            elo_array::<_, f64, Dual2_64>(&self.scene, &self.e, t, &self.d, &mut self.e_out);
            let mut w = nalgebra::DMatrix::zeros(m, m);
            for j in 0..m {
                self.e_direction(t, 4 * m + j);
                for mu in 0..m {
                    w[(mu, j)] = self.e_dual[mu].eps;
                }
            }
            let Ok(svd) = svd_of(w, true, true) else {
                return;
            };
            let top = svd.singular_values.max();
            let Ok(delta) = svd.solve(
                &nalgebra::DVector::from_column_slice(&self.e_out),
                1e-12 * top,
            ) else {
                return;
            };
            for k in 0..m {
                d[4 * m + k] -= delta[k];
            }
        }
    }

    /// `∂E/∂d_j` at `d = self.d` (`(z, q⁗)`, 5m numbers): one dual pass
    /// of the equations (19) seeded along `d_j`, into `self.e_dual[..m]`
    /// (the `eps` parts).
    fn e_direction(&mut self, t: f64, j: usize) {
        for (v, &x) in self.d_dual.iter_mut().zip(&self.d) {
            *v = Dual64::from_re(x);
        }
        self.d_dual[j].eps = 1.0;
        elo_array::<_, Dual64, Dual2<Dual64>>(
            &self.scene,
            &self.e,
            Dual64::from_re(t),
            &self.d_dual,
            &mut self.e_dual,
        );
    }

    /// Physical `(q, q̇)` from `z` into the model's buffers, dependent angles
    /// unwrapped to the branch nearest the last reported value.
    fn physical(&mut self, t: f64, z: &[f64]) {
        let m = self.m;
        reconstruct(
            &self.scene,
            &self.e,
            t,
            &z[..m],
            &z[m..2 * m],
            &z[2 * m..3 * m],
            &mut self.q,
            &mut self.qd,
        );
        let coords = self.scene.info().coordinates;
        for (j, &i) in self.e.dependent.iter().enumerate() {
            if coords[i].unit == "rad" {
                let two_pi = std::f64::consts::TAU;
                let k = ((self.last_dep[j] - self.q[i]) / two_pi).round();
                self.q[i] += k * two_pi;
            }
            self.last_dep[j] = self.q[i];
        }
    }

    /// The embedding map's singular-set vector at `z` into `self.r`.
    fn singular_vector(&mut self, t: f64, z: &[f64]) -> usize {
        let m = self.m;
        self.scene
            .embedding_singularity(t, &z[..m], &z[m..2 * m], &mut self.r)
    }

    /// Refuses a stage beyond the singular set (both forms): the guard's
    /// signed distance, measured along the direction at the step start,
    /// has fallen below zero.
    fn check_stage(&mut self, t: f64, z: &[f64]) -> Result<(), SystemError> {
        let p = self.singular_vector(t, z);
        if self.guard.crossed(&self.r, p) {
            return Err(SystemError::new(format!(
                "a stage crossed the singular set of the embedding map {} ({})",
                self.e.formula, self.e.singular_set
            )));
        }
        Ok(())
    }

    /// The error for equations that are not finite at `z`.
    fn not_finite(&mut self, t: f64, z: &[f64]) -> SystemError {
        let p = self.singular_vector(t, z);
        SystemError::new(format!(
            "the equations (19) are not finite here (|r| = {:.3e}): the embedding map is singular",
            magnitude(&self.r, p)
        ))
    }

    /// After an accepted step (both forms): diagnostics of the physical
    /// state, and the guard's reference direction.
    fn accept_state(&mut self, t: f64, z: &[f64]) {
        self.physical(t, z);
        self.monitor.record(&self.scene, t, &self.q, &self.qd);
        let p = self.singular_vector(t, z);
        self.guard.accept(&self.r, p);
    }

    /// Signed distance from the embedding map's singular set (see
    /// `nonholo_core::guard`): for the sleigh, the velocity's component along
    /// its direction at the start of the step, minus `singular_tol`.
    fn guard_value(&mut self, t: f64, z: &[f64]) -> Option<f64> {
        let p = self.singular_vector(t, z);
        (p > 0).then(|| self.guard.value(&self.r, p))
    }

    /// `|r|` at `(t, y)` and the zero of the guard's signed distance,
    /// extrapolated linearly from the rate at which `r` falls along its own
    /// direction (for the sleigh: `d|v|/dt = v·a/|v|`), as text.
    fn approach(&mut self, t: f64, y: &[f64]) -> (f64, String) {
        let m = self.m;
        let p = self.singular_vector(t, y);
        let size = magnitude(&self.r, p);
        if p == 0 {
            return (size, String::new());
        }
        let h = 1e-7 * (1.0 + t.abs());
        let later: Vec<f64> = (0..2 * m).map(|i| y[i] + h * y[m + i]).collect();
        let along_now = self.guard.value(&self.r, p);
        let pl = self.singular_vector(t + h, &later);
        let rate = (self.guard.value(&self.r, pl) - along_now) / h;
        let crossing = if rate < 0.0 {
            format!(
                "; extrapolated zero at t ≈ {:.9}",
                t - (along_now + self.guard.tol) / rate
            )
        } else {
            String::new()
        };
        (size, crossing)
    }

    fn guard_text(&mut self, t: f64, y: &[f64]) -> String {
        let (size, crossing) = self.approach(t, y);
        format!(
            "the motion reached the singular set of the embedding map {} — {} \
             (|r| = {size:.3e}, singular_tol = {:.1e}{crossing})",
            self.e.formula, self.e.singular_set, self.guard.tol
        )
    }

    /// The explicit form's guard from its two parts: the singular set's
    /// signed distance (if the scene has one) and the resolution margin
    /// `singular_tol · ln(ODE_RESOLUTION / ρ)` (`−singular_tol` where the
    /// solve fails), in the units of the first. The smaller counts; NaN
    /// stops the run.
    fn explicit_guard(
        &self,
        singular: Option<f64>,
        resolution: &Result<Resolution, String>,
    ) -> f64 {
        let margin = match resolution {
            Ok(r) => self.guard.tol * (ODE_RESOLUTION / r.rho).ln(),
            Err(_) => -self.guard.tol,
        };
        match singular {
            Some(g) if g.is_nan() || g < margin => g,
            _ => margin,
        }
    }

    /// `q_I⁗ = w(z)` of the explicit form at `(t, z)` (see [`crate::ode`]):
    /// the derivative array `[E; Ė; Ë] = 0` solved for `(q⁗, q⁽⁵⁾, q⁽⁶⁾)`,
    /// warm-started from the previous solve.
    pub fn fourth_derivative(&mut self, t: f64, z: &[f64]) -> Result<&[f64], SystemError> {
        self.reduction
            .fourth(&self.scene, &self.e, t, z)
            .map_err(|msg| {
                SystemError::new(format!(
                    "the derivative array of (19) could not be solved for q⁗: {msg}"
                ))
            })
    }

    /// How well the explicit form's `q⁗ = w(z)` is resolved at `(t, z)`
    /// (see [`Resolution`]); the explicit form stops where `rho` reaches
    /// [`ODE_RESOLUTION`].
    pub fn resolution(&mut self, t: f64, z: &[f64]) -> Result<Resolution, SystemError> {
        self.reduction
            .resolution(&self.scene, &self.e, t, z)
            .map_err(|msg| {
                SystemError::new(format!(
                    "the derivative array of (19) could not be solved for q⁗: {msg}"
                ))
            })
    }

    /// How far `z` is from A's hidden constraints: the derivative array's
    /// residual left by the least-squares solve, relative to the terms that
    /// cancel in each row ([`Reduction::hidden_residual`]). Round-off level on
    /// the constraint manifold. A diagnostic, not for hot paths.
    pub fn hidden_residual(&mut self, t: f64, z: &[f64]) -> Result<f64, SystemError> {
        self.reduction
            .hidden_residual(&self.scene, &self.e, t, z)
            .map_err(SystemError::new)
    }

    /// Work counters of the explicit form since [`Model::initial_state`].
    pub fn reduction_stats(&self) -> ReductionStats {
        self.reduction.stats()
    }

    /// Whether the explicit form records, after every accepted step, the
    /// hidden-constraint residual before and after the projection (see
    /// [`Embedding::hidden_log`]). Costs a full derivative-array Jacobian per
    /// step; for studies of the drift, off by default. Clears the log.
    pub fn record_hidden(&mut self, on: bool) {
        self.hidden_log = on.then(Vec::new);
    }

    /// `(t, before, after)` per accepted step of the explicit form, where
    /// `before` is [`Embedding::hidden_residual`] of the state the integrator
    /// produced and `after` that of the state it continues from (after the
    /// projection if `stab = projection`, else the same).
    pub fn hidden_log(&self) -> &[[f64; 3]] {
        self.hidden_log.as_deref().unwrap_or(&[])
    }
}

impl<S: Scene> ImplicitSystem for Embedding<S> {
    fn dim(&self) -> usize {
        4 * self.m
    }

    fn residual(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        res: &mut [f64],
    ) -> Result<(), SystemError> {
        let m = self.m;
        self.check_stage(t, y)?;
        for i in 0..3 * m {
            res[i] = yp[i] - y[m + i];
        }
        self.d[..4 * m].copy_from_slice(y);
        self.d[4 * m..].copy_from_slice(&yp[3 * m..]);
        elo_array::<_, f64, Dual2_64>(&self.scene, &self.e, t, &self.d, &mut self.e_out);
        res[3 * m..].copy_from_slice(&self.e_out);
        if res.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(self.not_finite(t, y))
        }
    }

    fn jacobians(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        jy: &mut [f64],
        jyp: &mut [f64],
    ) -> Result<(), SystemError> {
        let m = self.m;
        let dim = 4 * m;
        jy.fill(0.0);
        jyp.fill(0.0);
        for i in 0..3 * m {
            jyp[i * dim + i] = 1.0;
            jy[i * dim + m + i] = -1.0;
        }
        // Columns of ∂E/∂(z, ż₃): one dual pass each.
        self.d[..4 * m].copy_from_slice(&y[..4 * m]);
        self.d[4 * m..].copy_from_slice(&yp[3 * m..4 * m]);
        for j in 0..5 * m {
            self.e_direction(t, j);
            for mu in 0..m {
                let v = self.e_dual[mu].eps;
                if j < 4 * m {
                    jy[(3 * m + mu) * dim + j] = v;
                } else {
                    jyp[(3 * m + mu) * dim + (j - m)] = v;
                }
            }
        }
        Ok(())
    }

    /// Index classes for Radau's error estimate: `q_I, q̇_I` → 1, `q̈_I` → 2,
    /// `q⃛_I` → 3. The hidden constraints tie `q⃛_I` to `(q, q̇, q̈)` over two
    /// differentiation levels, so the chain `q̈ → q⃛` carries the algebraic
    /// part. Measured on the sleigh (rtol 1e-10, λ0 ∈ {0, 0.5, −1}): with
    /// (1, 1, 2, 3) every run reaches the singular set in ~100 steps and
    /// agrees with C to 7e-8; with (1, 1, 1, 3) or (1, 1, 1, 2) the error
    /// estimate of the unscaled q̈ stays O(1) as h → 0 and two of three runs
    /// collapse to h ~ 1e-21 at t ~ 1e-9.
    fn variable_index(&self, index: &mut [u8]) {
        let m = self.m;
        index[..2 * m].fill(1);
        index[2 * m..3 * m].fill(2);
        index[3 * m..].fill(3);
    }

    /// The implicit form ignores `stab`: the collocation equations impose
    /// `E = 0` at every stage, and Radau treats `(q̈, q⃛)` as index-2 and
    /// index-3 variables.
    fn after_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        self.accept_state(t, y);
        Ok(false)
    }

    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        self.guard_value(t, y)
    }

    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        self.guard_text(t, y)
    }
}

/// The explicit form `ż = (z₁, z₂, z₃, w(z))`, `w = q_I⁗` from the derivative
/// array ([`crate::ode`]), for RK4, DOPRI5 and DOP853 (Radau uses the
/// implicit form).
impl<S: Scene> OdeSystem for Embedding<S> {
    fn dim(&self) -> usize {
        4 * self.m
    }

    /// Stages beyond the singular set are refused as in the implicit form;
    /// so is a state where the derivative array cannot be solved.
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let m = self.m;
        self.check_stage(t, y)?;
        if !y.iter().all(|v| v.is_finite()) {
            return Err(self.not_finite(t, y));
        }
        dy[..3 * m].copy_from_slice(&y[m..4 * m]);
        let w = self.fourth_derivative(t, y)?;
        dy[3 * m..].copy_from_slice(w);
        if dy.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(self.not_finite(t, y))
        }
    }

    /// With `stab = projection`, moves `q⃛` back onto the hidden constraints
    /// (`q, q̇, q̈` fixed) and says so; then records the diagnostics and
    /// promotes the guard's reference direction, as the implicit form does.
    fn after_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        let before = match self.hidden_log {
            Some(_) => Some(self.hidden_residual(t, y)?),
            None => None,
        };
        let mut moved = false;
        if self.project_hidden {
            let change = self
                .reduction
                .project(&self.scene, &self.e, t, y)
                .map_err(SystemError::new)?;
            moved = change > 0.0;
        }
        if let Some(before) = before {
            let after = if moved {
                self.hidden_residual(t, y)?
            } else {
                before
            };
            if let Some(log) = self.hidden_log.as_mut() {
                log.push([t, before, after]);
            }
        }
        self.accept_state(t, y);
        Ok(moved)
    }

    /// The implicit form's guard at the singular set, and the resolution of
    /// `q⁗` ([`Embedding::resolution`]; see `explicit_guard`): the run stops
    /// where the first of them reaches zero, so that it ends by design
    /// before the round-off of the derivative array keeps `q⁗` from being
    /// solved for. At an accepted state the solve is the one the right-hand
    /// side made there (after a projection) or makes next (RK4's first
    /// stage), and is not repeated. No allocation unless the solve fails.
    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        let resolution = self.reduction.resolution(&self.scene, &self.e, t, y);
        let singular = self.guard_value(t, y);
        let g = self.explicit_guard(singular, &resolution);
        if g.is_nan() || g <= 0.0 {
            self.stop_record = Some(resolution);
        }
        Some(g)
    }

    /// Names the guard that fired at the stop: the singular set (as in the
    /// implicit form), or the resolution of `q⁗`, with `ρ` and its two
    /// parts, the speed, the limit and the extrapolated zero of the speed.
    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        let resolution = match self.stop_record.take() {
            Some(r) => r,
            None => self.reduction.resolution(&self.scene, &self.e, t, y),
        };
        let singular = self.guard_value(t, y);
        if singular.is_some_and(|g| g <= self.explicit_guard(None, &resolution)) {
            return self.guard_text(t, y);
        }
        let measured = match resolution {
            Ok(r) => format!(
                "to {:.2e} relative (conditioning {:.2e}, observed {})",
                r.rho,
                r.conditioning,
                r.observed
                    .map_or_else(|| "not measured".to_string(), |o| format!("{o:.2e}"))
            ),
            Err(msg) => format!("no longer ({msg})"),
        };
        let (size, crossing) = self.approach(t, y);
        format!(
            "the explicit form reached its resolution limit: the derivative array [E; Ė; Ë] \
             determines q⁗ only {measured} here, limit {ODE_RESOLUTION:.0e}; its terms grow like \
             powers of the turning rate and cancel towards the singular set of the embedding map \
             {} — {} (|r| = {size:.3e}, singular_tol = {:.1e}{crossing}); the implicit form \
             (radau5) runs on to singular_tol",
            self.e.formula, self.e.singular_set, self.guard.tol
        )
    }
}

impl<S: Scene> Model for Embedding<S> {
    /// The explicit form, for explicit methods (`simulate` integrates with
    /// Radau the implicit form whenever a model has one).
    fn ode(&mut self) -> Option<&mut dyn OdeSystem> {
        Some(self)
    }

    fn implicit(&mut self) -> Option<&mut dyn ImplicitSystem> {
        Some(self)
    }

    /// (19) is fully implicit and not in Hessenberg form: Radau's simplified
    /// Newton iteration stalls on it (contraction factor ≈ 1 after a few
    /// steps, measured), while the collocation equations are solvable.
    fn radau_newton(&self) -> RadauNewton {
        RadauNewton::Full
    }

    fn initial_slope(&mut self) -> Result<Vec<f64>, Error> {
        if self.yp0.is_empty() {
            return Err(Error::numerical(
                "the initial slope",
                "initial_state was not called",
            ));
        }
        Ok(self.yp0.clone())
    }

    fn describe(&self) -> Description<'_> {
        Description {
            scene: self.scene.info(),
            formulation: &INFO,
            params: self.scene.params(),
            options: &self.options,
        }
    }

    /// A has no multipliers.
    fn multiplier_names(&self) -> Vec<String> {
        Vec::new()
    }

    /// `lambda` (matched with C by the lab) and the second and third
    /// derivatives of the independent coordinates (`x_ddot`, `x_dddot`, …).
    fn extra_init_names(&self) -> Vec<ExtraName> {
        let coords = self.scene.info().coordinates;
        let mut names = lambda_names(
            self.e.dependent.len(),
            "multiplier λ(0) of the vakonomic motion A is matched with (spec, section A)",
        );
        for order in [2, 3] {
            for &i in self.e.independent {
                names.push(ExtraName::new(
                    derivative_name(coords[i].name, order),
                    "",
                    "initial derivative of an independent coordinate",
                ));
            }
        }
        names
    }

    fn make_consistent(
        &mut self,
        init: &mut Initial,
        project: bool,
    ) -> Result<Option<InitProjection>, Error> {
        check_or_project(&self.scene, init, project)
    }

    fn initial_state(&mut self, init: &Initial) -> Result<Vec<f64>, Error> {
        let m = self.m;
        let coords = self.scene.info().coordinates;
        let t0 = init.t0;
        let mut d = vec![0.0; 7 * m];
        for (k, &i) in self.e.independent.iter().enumerate() {
            d[k] = init.q[i];
            d[m + k] = init.qd[i];
        }
        let value = |order: usize, i: usize| init.extra(&derivative_name(coords[i].name, order));
        let second: Vec<Option<f64>> = self.e.independent.iter().map(|&i| value(2, i)).collect();
        let third: Vec<Option<f64>> = self.e.independent.iter().map(|&i| value(3, i)).collect();
        if second.iter().any(Option::is_none) {
            let names: Vec<String> = self
                .e
                .independent
                .iter()
                .map(|&i| derivative_name(coords[i].name, 2))
                .collect();
            return Err(Error::MissingInit {
                formulation: INFO.letter,
                needs: "q̈_I(0)".into(),
                names,
                hint: Some(
                    "or `lambda`, from which they are matched with the vakonomic motion".into(),
                ),
            });
        }
        for k in 0..m {
            d[2 * m + k] = second[k].expect("checked");
        }
        let third_given = third.iter().all(Option::is_some);
        if third.iter().any(Option::is_some) && !third_given {
            return Err(inconsistent(
                "give every third derivative of the independent coordinates, or none".into(),
            ));
        }
        if third_given {
            for k in 0..m {
                d[3 * m + k] = third[k].expect("checked");
            }
        }

        // The map has no value on its singular set (the sleigh at zero
        // speed): nothing below can be evaluated there.
        let p = self
            .scene
            .embedding_singularity(t0, &d[..m], &d[m..2 * m], &mut self.r);
        let size = magnitude(&self.r, p);
        if p > 0 && (size.is_nan() || size <= self.guard.tol) {
            return Err(inconsistent(format!(
                "the initial state lies on the singular set of the embedding map {} — {} \
                 (|r| = {size:.3e}, singular_tol = {:.1e}): the map gives no dependent \
                 coordinates there; start A away from it",
                self.e.formula, self.e.singular_set, self.guard.tol
            )));
        }

        // The dependent coordinates are the map's: check the given ones.
        let mut q = vec![0.0; self.n];
        let mut qd = vec![0.0; self.n];
        reconstruct(
            &self.scene,
            &self.e,
            t0,
            &d[..m],
            &d[m..2 * m],
            &d[2 * m..3 * m],
            &mut q,
            &mut qd,
        );
        let mut branch_shift = Vec::new();
        for &i in self.e.dependent {
            let mut diff = q[i] - init.q[i];
            if coords[i].unit == "rad" {
                diff -= (diff / std::f64::consts::TAU).round() * std::f64::consts::TAU;
            }
            if diff.abs() > 1e-9 * (1.0 + init.q[i].abs()) && !self.branch_map {
                {
                    return Err(inconsistent(format!(
                        "the embedding map {} gives {} = {:.12} but {} = {} was given (difference \
                         {diff:.6}); for the sleigh this is backward motion, where the map turns \
                         the heading by π — pass --option branch=map to study that branch",
                        self.e.formula, coords[i].name, q[i], coords[i].name, init.q[i]
                    )));
                }
            }
            branch_shift.push(diff);
            let dd = qd[i] - init.qd[i];
            if dd.abs() > 1e-8 * (1.0 + init.qd[i].abs()) {
                return Err(inconsistent(format!(
                    "{}_dot = {} does not match the embedding map's rate {:.12} for the given \
                     second derivatives (eq. 15)",
                    coords[i].name, init.qd[i], qd[i]
                )));
            }
        }

        // Hidden constraints. Given q⃛ is first checked (only the derivatives
        // beyond it may move); then, given or not, q⃛ is moved onto A's own
        // constraint manifold to round-off: data consistent to another
        // formulation's round-off (C's Taylor coefficients) are not consistent
        // enough for an index-3 system, where an inconsistency δ forces
        // corrections of order δ/h² in the first steps. The completion starts
        // from the check's derivatives beyond q⃛, so that its minimum-norm
        // steps move q⃛ only by what the given data lack: where q⃛ is not
        // determined by (q, q̇, q̈) (the sleigh at ω = 0), steps that also
        // had to find q⁗ … q⁽⁶⁾ from scratch would move q⃛ along the free
        // direction, to another motion.
        let mut checked = None;
        if third_given {
            let mut check = d.clone();
            let c = complete(
                &self.scene,
                &self.e,
                t0,
                &mut check,
                false,
                HIDDEN_CHECK_RTOL,
            )
            .map_err(|msg| {
                inconsistent(format!(
                    "the given third derivatives violate the hidden constraints of A: {msg}; \
                     omit them to have them computed"
                ))
            })?;
            // The check stops at HIDDEN_CHECK_RTOL; where the given data
            // allow it, solve for the derivatives beyond q⃛ to round-off, so
            // that the completion below has only the data's own
            // inconsistency left to remove.
            let mut refined = check.clone();
            if complete(&self.scene, &self.e, t0, &mut refined, false, HIDDEN_RTOL).is_ok() {
                check = refined;
            }
            d.copy_from_slice(&check);
            checked = Some(c);
        }
        let completion =
            complete(&self.scene, &self.e, t0, &mut d, true, HIDDEN_RTOL).map_err(inconsistent)?;
        let sv_text = |c: &Completion| {
            c.third_singular_values
                .iter()
                .map(|v| format!("{v:.3e}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        if !third_given && !completion.third_unique {
            return Err(inconsistent(format!(
                "q⃛_I(0) is not determined by (q, q̇, q̈) at this state: the hidden constraints' \
                 Jacobian in q⃛ has singular values [{}] relative to their gradient in \
                 (q, q̇, q̈, q⃛) (rank < {m}, threshold {RANK_TOL:.0e}), so the completion's q⃛ is \
                 one point of a family of motions; for the sleigh this is zero turning rate \
                 ω = 0, where the first hidden constraint g sin α cos φ − u̇ − J ω φ̈/u = 0 no \
                 longer involves q⃛ (it fixes u̇) and φ̈ — the vakonomic λ(0) — is free. Give \
                 the third derivatives ({}) or `lambda`",
                sv_text(&completion),
                self.e
                    .independent
                    .iter()
                    .map(|&i| derivative_name(coords[i].name, 3))
                    .collect::<Vec<_>>()
                    .join(", ")
            )));
        }
        let third_scale = d[3 * m..4 * m].iter().fold(1.0f64, |a, v| a.max(v.abs()));
        if let Some(check) = checked
            && completion.third_change > 1e-6 * third_scale
        {
            return Err(inconsistent(format!(
                "the given third derivatives satisfy A's hidden constraints to {:.3e} relative, \
                 but making them consistent to {HIDDEN_RTOL:.0e} moved them by {:.3e} \
                 (max(1, |q⃛|) = {third_scale:.3e}): q⃛ is ill-determined here (singular values \
                 of the hidden constraints' Jacobian in q⃛, relative to their gradient in \
                 (q, q̇, q̈, q⃛): [{}])",
                check.residual.1,
                completion.third_change,
                sv_text(&completion)
            )));
        }
        let structure = structure(&self.scene, &self.e, t0, &d).map_err(inconsistent)?;
        self.polish_fourth(t0, &mut d);
        // The explicit form starts from the same completion: its u is the
        // first warm start, and the rank of ∂D/∂u is fixed here.
        self.reduction
            .reset(&self.scene, &self.e, t0, &d)
            .map_err(|msg| {
                Error::numerical(
                    "solving the derivative array of (19) at the initial state",
                    msg,
                )
            })?;
        if let Some(log) = self.hidden_log.as_mut() {
            log.clear();
        }

        self.last_dep = self.e.dependent.iter().map(|&i| init.q[i]).collect();
        self.physical(t0, &d[..4 * m]);
        self.monitor = Monitor::new(&self.scene);
        self.monitor.record(&self.scene, t0, &self.q, &self.qd);
        let p = self.singular_vector(t0, &d[..4 * m]);
        self.guard.start(&self.r, p);
        self.yp0 = d[m..5 * m].to_vec();
        self.report = Some(InitReport {
            structure,
            completion,
            third_given,
            branch_shift,
        });
        Ok(d[..4 * m].to_vec())
    }

    fn observe(&mut self, t: f64, y: &[f64], obs: &mut Observation) -> Result<(), SystemError> {
        self.physical(t, y);
        obs.q.copy_from_slice(&self.q);
        obs.qd.copy_from_slice(&self.qd);
        Ok(())
    }

    fn init_report(&self) -> Vec<(&'static str, f64)> {
        let Some(r) = &self.report else {
            return Vec::new();
        };
        let mut v = vec![
            ("rank_w", r.structure.rank_w as f64),
            ("hidden_constraints", r.structure.hidden_constraints as f64),
            ("free_initial_data", r.structure.free_initial_data as f64),
            ("state_dimension", (4 * self.m) as f64),
            (
                "third_derivatives_given",
                if r.third_given { 1.0 } else { 0.0 },
            ),
            ("hidden_residual_before", r.completion.residual.0),
            ("hidden_residual_after", r.completion.residual.1),
            ("completion_iterations", r.completion.iterations as f64),
            ("third_derivative_change", r.completion.third_change),
        ];
        // How well (q, q̇, q̈) determine q⃛: the smallest relative singular
        // value of the hidden constraints' Jacobian in q⃛ (0 where q⃛ is free,
        // as for the sleigh at ω = 0; see `analysis::third_determination`).
        if let Some(&s) = r.completion.third_singular_values.last() {
            v.push(("third_determination", s));
        }
        for shift in &r.branch_shift {
            v.push(("branch_shift", *shift));
        }
        v
    }

    fn diagnostics(&self) -> Diagnostics {
        self.monitor.diagnostics().clone()
    }
}
