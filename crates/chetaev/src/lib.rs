//! Formulation B: D'Alembert–Lagrange with multipliers and Chetaev's
//! conditions (eq. 4–5 of the paper; spec section B).
//!
//! Virtual displacements satisfy `G δq = 0` and `F δq = 0`, so the
//! constraint forces are `Gᵀλ + Fᵀν`. One KKT solve per right-hand side:
//!
//! ```text
//! [ M  Gᵀ  Fᵀ ] [ q̈  ]   [ Q             ]
//! [ G  0   0  ] [ −λ ] = [ −ġ₀ − 2α g    ]
//! [ F  0   0  ] [ −ν ]   [ −f̈₀ − 2α ḟ − β² f ]
//! ```
//!
//! with `M`, `Q`, `G = ∂g/∂q̇`, `F = ∂f/∂q`, `ġ₀`, `f̈₀` from automatic
//! differentiation of the scene's `L`, `g`, `f` ([`nonholo_core::ad`]). The
//! gains `α`, `β` are zero unless Baumgarte stabilisation is chosen;
//! projection stabilisation moves the state back onto the constraints after
//! every accepted step instead. State `y = (q, q̇)`.

use nonholo_core::consistency::{InitProjection, check_or_project};
use nonholo_core::integrate::{OdeSystem, SystemError};
use nonholo_core::kkt::Kkt;
use nonholo_core::model::{FormulationInfo, Model, Observation};
use nonholo_core::param::{ParamSpec, Params};
use nonholo_core::scene::{Lagrangian, Scene, SceneInfo};
use nonholo_core::stab::{BAUMGARTE_ALPHA, BAUMGARTE_BETA, SINGULAR_TOL, STAB, StepHooks};
use nonholo_core::{Diagnostics, Error, Initial};
use num_dual::Dual64;

/// Options of formulation B.
pub const OPTIONS: &[ParamSpec] = &[STAB, BAUMGARTE_ALPHA, BAUMGARTE_BETA, SINGULAR_TOL];

pub const INFO: FormulationInfo = FormulationInfo {
    name: "chetaev",
    letter: "B",
    title: "D'Alembert–Lagrange with multipliers and Chetaev's conditions",
    description: "M q̈ − Q = Gᵀλ + Fᵀν with ġ = 0, f̈ = 0; one KKT solve per right-hand side; \
                  state (q, q̇)",
    options: OPTIONS,
    applicable,
};

/// B applies to every scene: constraints are optional, and without any it is
/// plain Euler–Lagrange.
fn applicable(_scene: &SceneInfo) -> Result<(), String> {
    Ok(())
}

/// Formulation B bound to a scene.
pub struct Chetaev<S: Scene> {
    scene: S,
    options: Params,
    n: usize,
    kkt: Kkt<f64>,
    /// The same solve carrying one directional derivative, for Jacobians.
    kkt_dual: Kkt<Dual64>,
    y_dual: Vec<Dual64>,
    hooks: StepHooks,
}

impl<S: Scene> Chetaev<S> {
    pub fn new(scene: S, options: Params) -> Result<Self, Error> {
        let info = scene.info();
        (INFO.applicable)(info).map_err(|reason| Error::NotApplicable {
            formulation: INFO.name.into(),
            scene: info.name.into(),
            reason,
        })?;
        let (n, s, k) = (info.n(), info.s(), info.k());
        Ok(Chetaev {
            hooks: StepHooks::new(&scene, &options),
            options,
            n,
            kkt: Kkt::new(n, s, k),
            kkt_dual: Kkt::new(n, s, k),
            y_dual: vec![Dual64::from_re(0.0); 2 * n],
            scene,
        })
    }

    /// Solves the KKT system at `(t, q, q̇)`: `q̈` into `qdd`; `λ` then `ν`
    /// into `multipliers` (at most `s + k` of them are written).
    pub fn accelerations(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        qdd: &mut [f64],
        multipliers: &mut [f64],
    ) -> Result<(), SystemError> {
        let n = self.n;
        self.kkt.solve(
            &Lagrangian(&self.scene),
            &[],
            &self.scene,
            self.hooks.stab,
            t,
            q,
            qd,
            "formulation B",
        )?;
        qdd.copy_from_slice(&self.kkt.sol[..n]);
        for (m, v) in multipliers.iter_mut().zip(&self.kkt.sol[n..]) {
            *m = -v;
        }
        Ok(())
    }
}

impl<S: Scene> OdeSystem for Chetaev<S> {
    fn dim(&self) -> usize {
        2 * self.n
    }

    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let n = self.n;
        self.hooks.check_stage_y(&self.scene, t, y)?;
        let (q, qd) = y.split_at(n);
        let (dq, dqd) = dy.split_at_mut(n);
        dq.copy_from_slice(qd);
        self.accelerations(t, q, qd, dqd, &mut [])
    }

    /// `∂f/∂y` of `f(q, q̇) = (q̇, q̈)`: the KKT solve repeated with one dual
    /// direction per column of `y` (2n solves in `Dual64`).
    fn jacobian(&mut self, t: f64, y: &[f64], jac: &mut [f64]) -> Result<bool, SystemError> {
        let (n, scene, stab) = (self.n, &self.scene, self.hooks.stab);
        self.kkt_dual
            .jacobian(y, &mut self.y_dual, 0, jac, |kkt, y| {
                let (q, qd) = y.split_at(n);
                kkt.solve(
                    &Lagrangian(scene),
                    &[],
                    scene,
                    stab,
                    Dual64::from_re(t),
                    q,
                    qd,
                    "formulation B",
                )
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

impl<S: Scene> Model for Chetaev<S> {
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

    fn make_consistent(
        &mut self,
        init: &mut Initial,
        project: bool,
    ) -> Result<Option<InitProjection>, Error> {
        check_or_project(&self.scene, init, project)
    }

    fn initial_state(&mut self, init: &Initial) -> Result<Vec<f64>, Error> {
        self.hooks.start(&self.scene, init.t0, &init.q, &init.qd);
        Ok(init.q.iter().chain(&init.qd).copied().collect())
    }

    fn observe(&mut self, t: f64, y: &[f64], obs: &mut Observation) -> Result<(), SystemError> {
        let n = self.n;
        let (q, qd) = y.split_at(n);
        obs.q.copy_from_slice(q);
        obs.qd.copy_from_slice(qd);
        if obs.multipliers.is_empty() {
            return Ok(());
        }
        self.kkt.solve(
            &Lagrangian(&self.scene),
            &[],
            &self.scene,
            self.hooks.stab,
            t,
            q,
            qd,
            "formulation B",
        )?;
        for (m, v) in obs.multipliers.iter_mut().zip(self.kkt.mu()) {
            *m = -v;
        }
        Ok(())
    }

    fn diagnostics(&self) -> Diagnostics {
        self.hooks.diagnostics().clone()
    }
}
