//! `visc`: viscous friction against the constraint violation.
//!
//! No constraint is imposed; instead a Rayleigh dissipation `k/2 gᵀg` acts,
//! whose force is `−k Gᵀ g`:
//!
//! ```text
//! M q̈ − Q = −k Gᵀ g          (G = ∂g/∂q̇)
//! ```
//!
//! For a constraint linear in the velocities the violation decays at rates
//! of order `k/m` (the eigenvalues of `−k G M⁻¹ Gᵀ`), so the system is stiff
//! for large `k`; as `k → ∞` motions tend to those of B (Kozlov; Karapetyan).
//! The friction force plays the part of B's constraint force, so the
//! multiplier reported is `λ = −k g` (B's convention `M q̈ − Q = Gᵀλ`), and
//! it tends to B's `λ`. State `y = (q, q̇)`, started on the constraints.

use nonholo_core::consistency::{InitProjection, check_or_project};
use nonholo_core::integrate::{OdeSystem, RadauNewton, SystemError};
use nonholo_core::kkt::{GRows, Kkt};
use nonholo_core::model::{FormulationInfo, Model, Observation, multiplier_names};
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::scene::{Lagrangian, MAX_CONSTRAINTS, Scene, SceneInfo};
use nonholo_core::stab::{SINGULAR_TOL, Stabilisation, StepHooks};
use nonholo_core::{Diagnostics, Error, Initial};
use num_dual::Dual64;

/// The viscous gain `k`.
pub const K: ParamSpec = ParamSpec::real(
    "k",
    "",
    1e4,
    Bound::Exclusive(0.0),
    Bound::Unbounded,
    "viscous gain k of the friction force −k Gᵀg (for a constraint on velocities in m/s: kg/s); \
     the violation decays at rates ~k/m",
);

/// Options of `visc`.
pub const OPTIONS: &[ParamSpec] = &[K, SINGULAR_TOL];

pub const INFO: FormulationInfo = FormulationInfo {
    name: "visc",
    letter: "VISC(k)",
    title: "Viscous realisation: friction −k Gᵀg against constraint violation",
    description: "M q̈ − Q = −k Gᵀ g, no constraint imposed; tends to B as k → ∞; stiff (~k/m); \
                  state (q, q̇)",
    options: OPTIONS,
    applicable: crate::applicable,
};

/// The viscous realisation bound to a scene.
pub struct Visc<S: Scene> {
    scene: S,
    options: Params,
    k: f64,
    n: usize,
    s: usize,
    kkt: Kkt<f64>,
    kkt_dual: Kkt<Dual64>,
    y_dual: Vec<Dual64>,
    g: [f64; MAX_CONSTRAINTS],
    hooks: StepHooks,
}

impl<S: Scene> Visc<S> {
    pub fn new(scene: S, options: Params) -> Result<Self, Error> {
        let info = scene.info();
        crate::applicable(info).map_err(|reason| Error::NotApplicable {
            formulation: INFO.name.into(),
            scene: info.name.into(),
            reason,
        })?;
        let (n, s, k) = (info.n(), info.s(), info.k());
        Ok(Visc {
            k: options.real("k"),
            hooks: StepHooks::unstabilised(&scene, options.real("singular_tol")),
            options,
            n,
            s,
            kkt: Kkt::new(n, s, k),
            kkt_dual: Kkt::new(n, s, k),
            y_dual: vec![Dual64::from_re(0.0); 2 * n],
            g: [0.0; MAX_CONSTRAINTS],
            scene,
        })
    }

    pub fn scene(&self) -> &S {
        &self.scene
    }

    /// The gain `k`.
    pub fn gain(&self) -> f64 {
        self.k
    }

    fn solve_at(&mut self, t: f64, q: &[f64], qd: &[f64]) -> Result<(), SystemError> {
        self.kkt.solve_rows(
            &Lagrangian(&self.scene),
            &[],
            &self.scene,
            Stabilisation::None,
            GRows::Viscous(self.k),
            t,
            q,
            qd,
            "formulation visc",
        )
    }
}

impl<S: Scene> OdeSystem for Visc<S> {
    fn dim(&self) -> usize {
        2 * self.n
    }

    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let n = self.n;
        let (q, qd) = y.split_at(n);
        self.hooks.check_stage(&self.scene, t, q, qd)?;
        self.solve_at(t, q, qd)?;
        dy[..n].copy_from_slice(qd);
        dy[n..].copy_from_slice(self.kkt.qdd());
        Ok(())
    }

    /// `∂f/∂y`: the solve repeated with one dual direction per column of `y`.
    fn jacobian(&mut self, t: f64, y: &[f64], jac: &mut [f64]) -> Result<bool, SystemError> {
        let n = self.n;
        let dim = 2 * n;
        jac.fill(0.0);
        for i in 0..n {
            jac[i * dim + n + i] = 1.0;
        }
        for j in 0..dim {
            for (d, &v) in self.y_dual.iter_mut().zip(y) {
                *d = Dual64::from_re(v);
            }
            self.y_dual[j].eps = 1.0;
            let (q, qd) = self.y_dual.split_at(n);
            self.kkt_dual.solve_rows(
                &Lagrangian(&self.scene),
                &[],
                &self.scene,
                Stabilisation::None,
                GRows::Viscous(self.k),
                Dual64::from_re(t),
                q,
                qd,
                "formulation visc",
            )?;
            for i in 0..n {
                jac[(n + i) * dim + j] = self.kkt_dual.qdd()[i].eps;
            }
        }
        Ok(true)
    }

    fn after_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        let (q, qd) = y.split_at_mut(self.n);
        self.hooks.after_step(&self.scene, t, q, qd)
    }

    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        let (q, qd) = y.split_at(self.n);
        self.hooks.guard(&self.scene, t, q, qd)
    }

    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        let (q, qd) = y.split_at(self.n);
        self.hooks.guard_reason(&self.scene, t, q, qd)
    }
}

impl<S: Scene> Model for Visc<S> {
    fn ode(&mut self) -> Option<&mut dyn OdeSystem> {
        Some(self)
    }

    /// Full Newton: the stiff force `−k Gᵀ g` turns with the configuration
    /// (for the sleigh `∂(k Gᵀ g)/∂φ` is of order `k u`), so the Jacobian
    /// frozen at the step start stops contracting. Measured on the sleigh over
    /// 5 s at tolerance 1e-10: the simplified iteration rejects 794 of 1368
    /// steps at k = 1e6 (2123 of 3661 at k = 1e8) and errs by 5e-8 (2e-7);
    /// full Newton takes 84 (99) steps with 0 (17) rejections and errs by 9e-10 (3e-10).
    fn radau_newton(&self) -> RadauNewton {
        RadauNewton::Full
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

    /// `λ = −k g` (the friction force is `Gᵀλ`), then `ν` of holonomic constraints.
    fn multiplier_names(&self) -> Vec<String> {
        multiplier_names(self.s, self.scene.info().k())
    }

    /// Starts on the constraints, from the same data as B.
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
        let (n, s) = (self.n, self.s);
        let (q, qd) = y.split_at(n);
        obs.q.copy_from_slice(q);
        obs.qd.copy_from_slice(qd);
        if obs.multipliers.is_empty() {
            return Ok(());
        }
        self.scene.nonholonomic(t, q, qd, &mut self.g[..s]);
        for (m, g) in obs.multipliers.iter_mut().zip(&self.g[..s]) {
            *m = -self.k * g;
        }
        if obs.multipliers.len() > s {
            self.solve_at(t, q, qd)?;
            for (m, v) in obs.multipliers[s..].iter_mut().zip(&self.kkt.mu()[s..]) {
                *m = -v;
            }
        }
        Ok(())
    }

    fn diagnostics(&self) -> Diagnostics {
        self.hooks.diagnostics().clone()
    }
}
