//! Formulation C: the vakonomic variant (spec section C).
//!
//! Hamilton's principle for `L + λᵀg` with `λ(t)` unknown, the constraints
//! imposed on the admissible curves:
//!
//! ```text
//! d/dt(∂L/∂q̇ + Gᵀλ) − ∂L/∂q − (∂g/∂q)ᵀλ = Fᵀν,   g = 0,   f = 0
//! ```
//!
//! Expanded with `ℓ = L + λᵀg` at frozen `λ` — whose `∂²ℓ/∂q̇² = M + H_λ`,
//! `H_λ = Σ λ_i ∂²g_i/∂q̇²`, and whose `Q_ℓ = Q + (∂g/∂q)ᵀλ − (∂G/∂q q̇ + ∂G/∂t)ᵀλ`
//! are exactly the terms of the spec — one KKT solve gives `(q̈, λ̇, ν)`:
//!
//! ```text
//! [ M + H_λ  Gᵀ  Fᵀ ] [ q̈  ]   [ Q_ℓ             ]
//! [ G        0   0  ] [ λ̇  ] = [ −ġ₀ − 2α g      ]
//! [ F        0   0  ] [ −ν ]   [ −f̈₀ − 2α ḟ − β² f ]
//! ```
//!
//! State `y = (q, q̇, λ)`; `λ(0)` is free initial data (`--init lambda=…`,
//! default 0), so one physical state starts a whole family of motions.
//! Holonomic constraints enter as in B (their multiplier `ν` is algebraic).
//! The multipliers reported are the `λ` of `L + λᵀg` as written.

use nonholo_core::consistency::{InitProjection, check_or_project};
use nonholo_core::init::{ExtraName, lambda0};
use nonholo_core::integrate::{OdeSystem, SystemError};
use nonholo_core::kkt::Kkt;
use nonholo_core::model::{FormulationInfo, Model, Observation};
use nonholo_core::param::{ParamSpec, Params};
use nonholo_core::scene::{Augmented, MAX_CONSTRAINTS, Scalar, Scene, SceneInfo};
use nonholo_core::stab::{
    BAUMGARTE_ALPHA, BAUMGARTE_BETA, SINGULAR_TOL, STAB, Stabilisation, StepHooks,
};
use nonholo_core::{Diagnostics, Error, Initial};
use num_dual::{Dual2_64, Dual64};

/// Options of formulation C.
pub const OPTIONS: &[ParamSpec] = &[STAB, BAUMGARTE_ALPHA, BAUMGARTE_BETA, SINGULAR_TOL];

pub const INFO: FormulationInfo = FormulationInfo {
    name: "vakonomic",
    letter: "C",
    title: "Vakonomic: Hamilton's principle for L + λᵀg",
    description: "(M + H_λ) q̈ + Gᵀλ̇ = Q_λ with ġ = 0; one KKT solve per right-hand side; \
                  state (q, q̇, λ), λ(0) free",
    options: OPTIONS,
    applicable,
};

fn applicable(scene: &SceneInfo) -> Result<(), String> {
    if scene.s() == 0 {
        return Err(
            "the scene has no nonholonomic constraints, so the vakonomic variant \
                    is the same motion as B"
                .into(),
        );
    }
    if scene.s() > MAX_CONSTRAINTS {
        return Err(format!(
            "the scene has {} nonholonomic constraints; L + λᵀg supports at most {MAX_CONSTRAINTS}",
            scene.s()
        ));
    }
    Ok(())
}

/// Formulation C bound to a scene.
pub struct Vakonomic<S: Scene> {
    scene: S,
    options: Params,
    n: usize,
    s: usize,
    kkt: Kkt<f64>,
    /// The same solve carrying one directional derivative: Jacobian columns
    /// and time derivatives along the motion.
    kkt_dual: Kkt<Dual64>,
    y_dual: Vec<Dual64>,
    /// Second-order time jets through the solve, for the third Taylor coefficient.
    kkt_jet2: Kkt<Dual2_64>,
    y_jet2: Vec<Dual2_64>,
    hooks: StepHooks,
}

impl<S: Scene> Vakonomic<S> {
    pub fn new(scene: S, options: Params) -> Result<Self, Error> {
        let info = scene.info();
        applicable(info).map_err(|reason| Error::NotApplicable {
            formulation: INFO.name.into(),
            scene: info.name.into(),
            reason,
        })?;
        let (n, s, k) = (info.n(), info.s(), info.k());
        Ok(Vakonomic {
            hooks: StepHooks::new(&scene, &options),
            options,
            n,
            s,
            kkt: Kkt::new(n, s, k),
            kkt_dual: Kkt::new(n, s, k),
            y_dual: vec![Dual64::from_re(0.0); 2 * n + s],
            kkt_jet2: Kkt::new(n, s, k),
            y_jet2: vec![Dual2_64::from_re(0.0); 2 * n + s],
            scene,
        })
    }

    /// The KKT solve at `y = (q, q̇, λ)`, results in `self.kkt`.
    fn solve_at(&mut self, t: f64, y: &[f64]) -> Result<(), SystemError> {
        solve(&mut self.kkt, &self.scene, self.hooks.stab, t, y)
    }

    /// Solves the KKT system at `(t, q, q̇, λ)`: `q̈` into `qdd`, `λ̇` into
    /// `lambda_dot`, and `ν` (if the scene has holonomic constraints) into `nu`.
    pub fn accelerations(
        &mut self,
        t: f64,
        y: &[f64],
        qdd: &mut [f64],
        lambda_dot: &mut [f64],
        nu: &mut [f64],
    ) -> Result<(), SystemError> {
        let s = self.s;
        self.solve_at(t, y)?;
        qdd.copy_from_slice(self.kkt.qdd());
        lambda_dot.copy_from_slice(&self.kkt.mu()[..s]);
        for (v, m) in nu.iter_mut().zip(&self.kkt.mu()[s..]) {
            *v = -m;
        }
        Ok(())
    }

    /// Taylor coefficients of the motion through `(t, y)`: `ẏ = f(t, y)`,
    /// `ÿ` and `y⃛`, by Taylor-mode differentiation of the right-hand side:
    /// one dual pass along the first-order jet `(y + ẏτ, t + τ)` gives `ÿ`,
    /// one second-order dual pass along `y + ẏτ + ÿτ²/2` gives `y⃛`. So
    /// `q̈ = ẏ[n..2n]`, `q⃛ = ÿ[n..2n]`, `q⁗ = y⃛[n..2n]`.
    pub fn taylor(
        &mut self,
        t: f64,
        y: &[f64],
        yd: &mut [f64],
        ydd: &mut [f64],
        yddd: &mut [f64],
    ) -> Result<(), SystemError> {
        let (n, s) = (self.n, self.s);
        self.rhs(t, y, yd)?;
        for i in 0..2 * n + s {
            self.y_dual[i] = Dual64::new(y[i], yd[i]);
        }
        solve(
            &mut self.kkt_dual,
            &self.scene,
            self.hooks.stab,
            Dual64::new(t, 1.0),
            &self.y_dual,
        )?;
        ydd[..n].copy_from_slice(&yd[n..2 * n]);
        for i in 0..n {
            ydd[n + i] = self.kkt_dual.qdd()[i].eps;
        }
        for i in 0..s {
            ydd[2 * n + i] = self.kkt_dual.mu()[i].eps;
        }
        for i in 0..2 * n + s {
            self.y_jet2[i] = Dual2_64::new(y[i], yd[i], ydd[i]);
        }
        solve(
            &mut self.kkt_jet2,
            &self.scene,
            self.hooks.stab,
            Dual2_64::new(t, 1.0, 0.0),
            &self.y_jet2,
        )?;
        yddd[..n].copy_from_slice(&ydd[n..2 * n]);
        for i in 0..n {
            yddd[n + i] = self.kkt_jet2.qdd()[i].v2;
        }
        for i in 0..s {
            yddd[2 * n + i] = self.kkt_jet2.mu()[i].v2;
        }
        Ok(())
    }
}

impl<S: Scene> OdeSystem for Vakonomic<S> {
    fn dim(&self) -> usize {
        2 * self.n + self.s
    }

    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let n = self.n;
        self.hooks.check_stage_y(&self.scene, t, y)?;
        dy[..n].copy_from_slice(&y[n..2 * n]);
        let (qdd, lambda_dot) = dy[n..].split_at_mut(n);
        self.accelerations(t, y, qdd, lambda_dot, &mut [])
    }

    /// `∂f/∂y` for `y = (q, q̇, λ)`: the KKT solve repeated with one dual
    /// direction per column (2n + s solves in `Dual64`).
    fn jacobian(&mut self, t: f64, y: &[f64], jac: &mut [f64]) -> Result<bool, SystemError> {
        let (scene, stab) = (&self.scene, self.hooks.stab);
        self.kkt_dual
            .jacobian(y, &mut self.y_dual, self.s, jac, |kkt, y| {
                solve(kkt, scene, stab, Dual64::from_re(t), y)
            })?;
        Ok(true)
    }

    fn after_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        self.hooks.after_step_y(&self.scene, t, y)
    }

    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        self.hooks.guard_y(&self.scene, t, y)
    }

    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        self.hooks.guard_reason_y(&self.scene, t, y)
    }
}

impl<S: Scene> Model for Vakonomic<S> {
    fn ode(&mut self) -> Option<&mut dyn OdeSystem> {
        Some(self)
    }

    fn scene_info(&self) -> &'static SceneInfo {
        self.scene.info()
    }

    fn formulation(&self) -> &'static FormulationInfo {
        &INFO
    }

    fn scene_params(&self) -> &Params {
        self.scene.params()
    }

    fn options(&self) -> &Params {
        &self.options
    }

    /// `lambda` (or `lambda1`, …): the initial multipliers `λ(0)`.
    fn extra_init_names(&self) -> Vec<ExtraName> {
        lambda_names(self.s)
    }

    fn make_consistent(
        &mut self,
        init: &mut Initial,
        project: bool,
    ) -> Result<Option<InitProjection>, Error> {
        check_or_project(&self.scene, init, project)
    }

    fn initial_state(&mut self, init: &Initial) -> Result<Vec<f64>, Error> {
        self.hooks.start(&self.scene, init.t0, &init.q, &init.qd);
        let mut y: Vec<f64> = init.q.iter().chain(&init.qd).copied().collect();
        y.extend(lambda0(init, self.s));
        Ok(y)
    }

    fn observe(&mut self, t: f64, y: &[f64], obs: &mut Observation) -> Result<(), SystemError> {
        let (n, s) = (self.n, self.s);
        obs.q.copy_from_slice(&y[..n]);
        obs.qd.copy_from_slice(&y[n..2 * n]);
        obs.multipliers[..s].copy_from_slice(&y[2 * n..]);
        if obs.multipliers.len() > s {
            // ν of the holonomic constraints: from the KKT solve at this state.
            self.solve_at(t, y)?;
            for (v, m) in obs.multipliers[s..].iter_mut().zip(&self.kkt.mu()[s..]) {
                *v = -m;
            }
        }
        Ok(())
    }

    fn diagnostics(&self) -> Diagnostics {
        self.hooks.diagnostics().clone()
    }
}

/// C's KKT solve at `y = (q, q̇, λ)` over any scalar, results in `kkt`.
fn solve<S: Scene, T: Scalar>(
    kkt: &mut Kkt<T>,
    scene: &S,
    stab: Stabilisation,
    t: T,
    y: &[T],
) -> Result<(), SystemError> {
    let n = scene.info().n();
    let (q, rest) = y.split_at(n);
    let (qd, lambda) = rest.split_at(n);
    kkt.solve(
        &Augmented(scene),
        lambda,
        scene,
        stab,
        t,
        q,
        qd,
        "formulation C",
    )
}

/// The names of the initial multipliers: `lambda`, or `lambda1..s`.
pub fn lambda_names(s: usize) -> Vec<ExtraName> {
    nonholo_core::init::lambda_names(s, "initial multiplier λ(0) of L + λᵀg")
}
