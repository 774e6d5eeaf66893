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
//! it tends to B's `λ`. Started on the constraints, from the same data as B.
//!
//! Two states for the same equations (`form`):
//!
//! * `cartesian`: `y = (q, q̇)`. The stiff direction `Gᵀ(q)` turns with the
//!   configuration, so the friction's Jacobian has entries `~k·|q̇|` that
//!   change along a step: implicit solvers see Newton failures from
//!   `k ~ 1e4` on.
//! * `adapted`: `y = (q, c, w)` with `q̇ = K(q) c + N(q) w` (module
//!   [`crate::adapted`]): `c` the scene's velocity chart, `w = g` the
//!   violation itself; the friction acts on `ẇ` only and linearly. For
//!   constraints linear and homogeneous in `q̇`, no holonomic constraints,
//!   and a chart linear in its values.

use nonholo_core::consistency::{InitProjection, check_or_project};
use nonholo_core::integrate::{OdeSystem, RadauNewton, SystemError};
use nonholo_core::kkt::{GRows, Kkt};
use nonholo_core::model::{FormulationInfo, Model, Observation};
use nonholo_core::param::{Bound, ParamSpec, Params, Value};
use nonholo_core::scene::{Lagrangian, MAX_CONSTRAINTS, Scalar, Scene, SceneInfo};
use nonholo_core::stab::{SINGULAR_TOL, Stabilisation, StepHooks};
use nonholo_core::{Diagnostics, Error, Initial};
use num_dual::Dual64;

use crate::adapted::Rates;

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

/// Which state the equations are integrated in.
pub const FORM: ParamSpec = ParamSpec::choice(
    "form",
    &["auto", "adapted", "cartesian"],
    "adapted: state (q, c, w), q̇ = K c + N w with c the scene's velocity chart and w = g the \
     violation (N = M⁻¹Gᵀ(G M⁻¹ Gᵀ)⁻¹), in which the friction is linear in w alone: no Newton \
     failures at any k; needs constraints linear and homogeneous in q̇, no holonomic \
     constraints and a chart linear in its values. cartesian: state (q, q̇), every scene. \
     auto: adapted where it applies, else cartesian (the run records which)",
);

/// Options of `visc`.
pub const OPTIONS: &[ParamSpec] = &[K, FORM, SINGULAR_TOL];

pub const INFO: FormulationInfo = FormulationInfo {
    name: "visc",
    letter: "VISC(k)",
    title: "Viscous realisation: friction −k Gᵀg against constraint violation",
    description: "M q̈ − Q = −k Gᵀ g, no constraint imposed; tends to B as k → ∞; stiff (~k/m); \
                  state (q, q̇) or, form = adapted, (q, c, w) with w = g",
    options: OPTIONS,
    applicable: crate::applicable,
};

/// The two states of `visc`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Form {
    /// `(q, q̇)`.
    Cartesian,
    /// `(q, c, w)`, `q̇ = K c + N w`, `w = g`.
    Adapted,
}

/// Workspaces of the Cartesian form: the KKT solve over `f64`, and over
/// `Dual64` for the Jacobian.
struct CartesianWs {
    kkt: Kkt<f64>,
    kkt_dual: Kkt<Dual64>,
    y_dual: Vec<Dual64>,
    g: [f64; MAX_CONSTRAINTS],
}

/// Workspaces of the adapted form: the right-hand side over `f64`, and over
/// `Dual64` for the Jacobian.
struct AdaptedWs {
    rates: Rates<f64>,
    rates_dual: Rates<Dual64>,
    y_dual: Vec<Dual64>,
    dy_dual: Vec<Dual64>,
    /// `q̇` at `(hook_at, hook_y)` for the hooks and observations: after an
    /// accepted step `after_step`, `guard` (and `guard_reason`, `observe`)
    /// ask at the same state, and each `q̇ = T v` costs a frame evaluation.
    hook_at: Option<f64>,
    hook_y: Vec<f64>,
    hook_qd: Vec<f64>,
}

impl AdaptedWs {
    /// `q̇` of `y = (q, v)` at `t` into `hook_qd` (reused while `(t, y)` is
    /// that of the previous call).
    fn hook_velocities<S: Scene>(
        &mut self,
        scene: &S,
        t: f64,
        y: &[f64],
    ) -> Result<(), SystemError> {
        if self.hook_at == Some(t) && self.hook_y == y {
            return Ok(());
        }
        self.hook_at = None;
        let (q, v) = y.split_at(self.hook_qd.len());
        self.rates.velocities(scene, t, q, v)?;
        self.hook_qd.copy_from_slice(&self.rates.qd);
        self.hook_y.copy_from_slice(y);
        self.hook_at = Some(t);
        Ok(())
    }
}

/// The workspaces of the form in use.
enum Workspace {
    Cartesian(Box<CartesianWs>),
    Adapted(Box<AdaptedWs>),
}

/// The viscous realisation bound to a scene.
pub struct Visc<S: Scene> {
    scene: S,
    options: Params,
    k: f64,
    n: usize,
    s: usize,
    hooks: StepHooks,
    ws: Workspace,
}

impl<S: Scene> Visc<S> {
    /// Binds `visc` to `scene`; `form = auto` resolves here (and
    /// [`Model::options`] then says which form runs).
    pub fn new(scene: S, options: Params) -> Result<Self, Error> {
        let info = scene.info();
        crate::applicable(info).map_err(|reason| Error::NotApplicable {
            formulation: INFO.name.into(),
            scene: info.name.into(),
            reason,
        })?;
        let (n, s, k) = (info.n(), info.s(), info.k());
        let gain = options.real("k");
        let mut options = options;
        let form = match options.choice("form") {
            "cartesian" => Form::Cartesian,
            "adapted" => {
                crate::adapted::applicable(&scene).map_err(|reason| Error::NotApplicable {
                    formulation: INFO.name.into(),
                    scene: info.name.into(),
                    reason: format!("form = adapted: {reason} (form = cartesian applies)"),
                })?;
                Form::Adapted
            }
            _ => match crate::adapted::applicable(&scene) {
                Ok(()) => Form::Adapted,
                Err(_) => Form::Cartesian,
            },
        };
        // `auto` is recorded as what it resolved to.
        options.set(
            "form",
            Value::Choice(match form {
                Form::Adapted => "adapted",
                Form::Cartesian => "cartesian",
            }),
            "option",
        )?;
        let ws = match form {
            Form::Cartesian => Workspace::Cartesian(Box::new(CartesianWs {
                kkt: Kkt::new(n, s, k),
                kkt_dual: Kkt::new(n, s, k),
                y_dual: vec![Dual64::from_re(0.0); 2 * n],
                g: [0.0; MAX_CONSTRAINTS],
            })),
            Form::Adapted => Workspace::Adapted(Box::new(AdaptedWs {
                rates: Rates::new(n, s, gain),
                rates_dual: Rates::new(n, s, gain),
                y_dual: vec![Dual64::from_re(0.0); 2 * n],
                dy_dual: vec![Dual64::from_re(0.0); 2 * n],
                hook_at: None,
                hook_y: vec![0.0; 2 * n],
                hook_qd: vec![0.0; n],
            })),
        };
        Ok(Visc {
            k: gain,
            hooks: StepHooks::unstabilised(&scene, options.real("singular_tol")),
            options,
            n,
            s,
            ws,
            scene,
        })
    }

    /// The state the equations are integrated in.
    pub fn form(&self) -> Form {
        match self.ws {
            Workspace::Cartesian(_) => Form::Cartesian,
            Workspace::Adapted(_) => Form::Adapted,
        }
    }

    /// `(q, q̇)` of state `y` at `t` into `out` (length `2n`): a copy in the
    /// Cartesian form, `q̇ = T(q, t) v` in the adapted one.
    pub fn to_cartesian(&mut self, t: f64, y: &[f64], out: &mut [f64]) -> Result<(), SystemError> {
        let n = self.n;
        match &mut self.ws {
            Workspace::Cartesian(_) => out.copy_from_slice(y),
            Workspace::Adapted(a) => {
                a.hook_velocities(&self.scene, t, y)?;
                out[..n].copy_from_slice(&y[..n]);
                out[n..].copy_from_slice(&a.hook_qd);
            }
        }
        Ok(())
    }
}

/// The Cartesian form's KKT solve at `(t, y = (q, q̇))` over any scalar,
/// results in `kkt`.
fn solve<S: Scene, T: Scalar>(
    kkt: &mut Kkt<T>,
    scene: &S,
    gain: f64,
    t: T,
    y: &[T],
) -> Result<(), SystemError> {
    let (q, qd) = y.split_at(scene.info().n());
    kkt.solve_rows(
        &Lagrangian(scene),
        &[],
        scene,
        Stabilisation::None,
        GRows::Viscous(gain),
        t,
        q,
        qd,
        "formulation visc",
    )
}

impl<S: Scene> OdeSystem for Visc<S> {
    fn dim(&self) -> usize {
        2 * self.n
    }

    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let n = self.n;
        match &mut self.ws {
            Workspace::Adapted(a) => {
                let (q, v) = y.split_at(n);
                a.rates.velocities(&self.scene, t, q, v)?;
                self.hooks.check_stage(&self.scene, t, q, &a.rates.qd)?;
                dy[..n].copy_from_slice(&a.rates.qd);
                a.rates.accelerations(&self.scene, t, q, v, &mut dy[n..])
            }
            Workspace::Cartesian(c) => {
                self.hooks.check_stage_y(&self.scene, t, y)?;
                solve(&mut c.kkt, &self.scene, self.k, t, y)?;
                dy[..n].copy_from_slice(&y[n..]);
                dy[n..].copy_from_slice(c.kkt.qdd());
                Ok(())
            }
        }
    }

    /// `∂f/∂y`: the right-hand side repeated with one dual direction per
    /// column of `y` (Cartesian: the KKT solve; adapted: the whole
    /// right-hand side, its inner time-jet pass over `Dual<Dual64>`).
    fn jacobian(&mut self, t: f64, y: &[f64], jac: &mut [f64]) -> Result<bool, SystemError> {
        let dim = 2 * self.n;
        let (scene, gain) = (&self.scene, self.k);
        match &mut self.ws {
            Workspace::Adapted(a) => {
                for j in 0..dim {
                    for (d, &v) in a.y_dual.iter_mut().zip(y) {
                        *d = Dual64::from_re(v);
                    }
                    a.y_dual[j].eps = 1.0;
                    a.rates_dual
                        .eval(scene, Dual64::from_re(t), &a.y_dual, &mut a.dy_dual)?;
                    for i in 0..dim {
                        jac[i * dim + j] = a.dy_dual[i].eps;
                    }
                }
            }
            Workspace::Cartesian(c) => {
                c.kkt_dual.jacobian(y, &mut c.y_dual, 0, jac, |kkt, y| {
                    solve(kkt, scene, gain, Dual64::from_re(t), y)
                })?;
            }
        }
        Ok(true)
    }

    /// Diagnostics and the guard on `(q, q̇)` (nothing is projected: the
    /// hooks are unstabilised, so the state is never changed).
    fn after_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        match &mut self.ws {
            Workspace::Cartesian(_) => self.hooks.after_step_y(&self.scene, t, y),
            Workspace::Adapted(a) => {
                a.hook_velocities(&self.scene, t, y)?;
                let q = &mut y[..self.n];
                let changed = self.hooks.after_step(&self.scene, t, q, &mut a.hook_qd)?;
                debug_assert!(!changed, "visc's hooks never project");
                Ok(false)
            }
        }
    }

    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        match &mut self.ws {
            Workspace::Cartesian(_) => self.hooks.guard_y(&self.scene, t, y),
            Workspace::Adapted(a) => {
                a.hook_velocities(&self.scene, t, y).ok()?;
                self.hooks.guard(&self.scene, t, &y[..self.n], &a.hook_qd)
            }
        }
    }

    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        match &mut self.ws {
            Workspace::Cartesian(_) => self.hooks.guard_reason_y(&self.scene, t, y),
            Workspace::Adapted(a) => match a.hook_velocities(&self.scene, t, y) {
                Ok(()) => self
                    .hooks
                    .guard_reason(&self.scene, t, &y[..self.n], &a.hook_qd),
                Err(e) => e.message,
            },
        }
    }
}

impl<S: Scene> Model for Visc<S> {
    fn ode(&mut self) -> Option<&mut dyn OdeSystem> {
        Some(self)
    }

    /// Cartesian form, full Newton: the stiff force `−k Gᵀ g` turns with the
    /// configuration (for the sleigh `∂(k Gᵀ g)/∂φ` is of order `k u`), so the
    /// Jacobian frozen at the step start stops contracting. Measured on the
    /// sleigh over 5 s at tolerance 1e-10: the simplified iteration rejects
    /// 794 of 1368 steps at k = 1e6 (2123 of 3661 at k = 1e8) and errs by
    /// 5e-8 (2e-7); full Newton takes 84 (99) steps with 0 (17) rejections
    /// and errs by 9e-10 (3e-10).
    ///
    /// Adapted form, simplified Newton: the stiff block `−k (G M⁻¹ Gᵀ)` acts
    /// on `w` alone and is (nearly) constant, so the Jacobian frozen at the
    /// step start keeps contracting. Measured on the sleigh over 5 s, k = 1e4
    /// … 1e8: no Newton failure either way; at tolerance 1e-10 simplified
    /// 77–86 steps, 38–39 Jacobians, 2.3–2.6 ms, error 3.3–4.1e-8, full 73–81
    /// steps, 364–408 Jacobians, 10–12 ms, error 3.7–5.5e-8 (the same errors
    /// from 1e-6 on; only at 1e-4 is full Newton more accurate, 3e-4 against
    /// 4e-3 for k ≥ 1e6).
    fn radau_newton(&self) -> RadauNewton {
        match self.form() {
            Form::Cartesian => RadauNewton::Full,
            Form::Adapted => RadauNewton::Simplified,
        }
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

    /// Starts on the constraints, from the same data as B.
    fn make_consistent(
        &mut self,
        init: &mut Initial,
        project: bool,
    ) -> Result<Option<InitProjection>, Error> {
        check_or_project(&self.scene, init, project)
    }

    /// `(q0, q̇0)`; in the adapted form `(q0, v0)` with `T(q0, t0) v0 = q̇0`,
    /// so that `w0 = g(q0, q̇0)` (zero to rounding for consistent data).
    fn initial_state(&mut self, init: &Initial) -> Result<Vec<f64>, Error> {
        self.hooks.start(&self.scene, init.t0, &init.q, &init.qd);
        let mut y: Vec<f64> = init.q.iter().chain(&init.qd).copied().collect();
        if let Workspace::Adapted(a) = &mut self.ws {
            a.hook_at = None;
            a.rates
                .adapted(&self.scene, init.t0, &init.q, &init.qd, &mut y[self.n..])
                .map_err(|e| {
                    Error::Numerical(format!("visc: initial velocities: {}", e.message))
                })?;
        }
        Ok(y)
    }

    /// `(q, q̇)`, and `λ = −k g` (the friction force is `Gᵀλ`), then `ν` of
    /// holonomic constraints: in the adapted form `λ = −k w`, the state itself.
    fn observe(&mut self, t: f64, y: &[f64], obs: &mut Observation) -> Result<(), SystemError> {
        let (n, s) = (self.n, self.s);
        let (q, rest) = y.split_at(n);
        obs.q.copy_from_slice(q);
        match &mut self.ws {
            Workspace::Adapted(a) => {
                a.hook_velocities(&self.scene, t, y)?;
                obs.qd.copy_from_slice(&a.hook_qd);
                // No holonomic constraints in this form: the multipliers are λ only.
                for (m, w) in obs.multipliers.iter_mut().zip(&rest[n - s..]) {
                    *m = -self.k * w;
                }
            }
            Workspace::Cartesian(c) => {
                obs.qd.copy_from_slice(rest);
                if obs.multipliers.is_empty() {
                    return Ok(());
                }
                self.scene.nonholonomic(t, q, rest, &mut c.g[..s]);
                for (m, g) in obs.multipliers.iter_mut().zip(&c.g[..s]) {
                    *m = -self.k * g;
                }
                if obs.multipliers.len() > s {
                    solve(&mut c.kkt, &self.scene, self.k, t, y)?;
                    for (m, v) in obs.multipliers[s..].iter_mut().zip(&c.kkt.mu()[s..]) {
                        *m = -v;
                    }
                }
            }
        }
        Ok(())
    }

    fn diagnostics(&self) -> Diagnostics {
        self.hooks.diagnostics().clone()
    }
}
