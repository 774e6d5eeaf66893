//! `mass`: the added-mass realisation, Euler–Lagrange of `L + (N/2) gᵀg`.
//!
//! A large kinetic energy `(N/2) gᵀg` is attached to the constraint
//! violation. With `λ = N g` the Euler–Lagrange equations of
//! `L + (N/2) gᵀg` are exactly C's equations for `L + λᵀg`,
//!
//! ```text
//! d/dt(∂L/∂q̇ + Gᵀλ) − ∂L/∂q − (∂g/∂q)ᵀλ = 0,      λ̇ = N ġ,
//! ```
//!
//! so that as `N → ∞` with `g(0) = λ0/N` the motions tend to C with
//! multiplier `λ0` (Kozlov). The violation oscillates with frequencies of
//! order `√(N/m)`: stiff and oscillatory. Two forms, both generic:
//!
//! * `form = compliance` (default): state `(q, q̇, λ)` and one KKT solve
//!   per right-hand side, C's system with compliance `1/N` in the
//!   constraint block,
//!   ```text
//!   [ M + H_λ   Gᵀ  ] [ q̈ ]   [ Q_ℓ ]
//!   [ G       −1/N ] [ λ̇ ] = [ −ġ₀ ]
//!   ```
//!   well conditioned for every `N` (it is C at `1/N = 0`).
//! * `form = direct`: state `(q, q̇)`, plain Euler–Lagrange of
//!   `L + (N/2) gᵀg` (mass matrix `M + N GᵀG + …`, condition number ~N/m).
//!
//! Initial data: the given `(q0, q̇0)` satisfy `g = 0` (the same data as C);
//! `q̇0` is then moved, nearest in the kinetic-energy metric, to
//! `g(q0, q̇0) = λ0/N` (reported as `init_velocity_shift`), and the
//! compliance form starts with `λ(0) = λ0`. The multiplier reported is
//! `λ` (compliance: the state; direct: `N g`), comparable with C's.

use nonholo_core::consistency::{InitProjection, PROJECT_TOL, check_or_project};
use nonholo_core::init::{ExtraName, lambda_names, lambda0};
use nonholo_core::integrate::{OdeSystem, RadauNewton, SystemError};
use nonholo_core::kkt::{GRows, Kkt};
use nonholo_core::model::{FormulationInfo, Model, Observation};
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::project::Projector;
use nonholo_core::scene::{Augmented, MAX_CONSTRAINTS, Penalised, Scalar, Scene, SceneInfo};
use nonholo_core::stab::{SINGULAR_TOL, Stabilisation, StepHooks};
use nonholo_core::{Diagnostics, Error, Initial};
use num_dual::Dual64;

/// The added-mass gain `N`.
pub const N: ParamSpec = ParamSpec::real(
    "N",
    "",
    1e4,
    Bound::Exclusive(0.0),
    Bound::Unbounded,
    "added-mass gain N of L + (N/2) gᵀg (for a constraint on velocities in m/s: kg); the \
     violation oscillates at frequencies ~√(N/m)",
);

/// Which equations are integrated.
pub const FORM: ParamSpec = ParamSpec::choice(
    "form",
    &["compliance", "direct"],
    "compliance: state (q, q̇, λ = N g), C's KKT system with compliance −1/N (well conditioned); \
     direct: Euler–Lagrange of L + (N/2) gᵀg in (q, q̇) (ill-conditioned for large N)",
);

/// Options of `mass`.
pub const OPTIONS: &[ParamSpec] = &[N, FORM, SINGULAR_TOL];

pub const INFO: FormulationInfo = FormulationInfo {
    name: "mass",
    letter: "MASS(N)",
    title: "Added-mass realisation: Euler–Lagrange of L + (N/2) gᵀg",
    description: "no constraint imposed, g(0) = λ0/N; tends to C with multiplier λ0 as N → ∞; \
                  stiff oscillatory (~√(N/m)); state (q, q̇, λ = N g) or (q, q̇)",
    options: OPTIONS,
    applicable: crate::applicable,
};

/// The two forms of the equations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Form {
    Compliance,
    Direct,
}

/// The added-mass realisation bound to a scene.
pub struct Mass<S: Scene> {
    scene: S,
    options: Params,
    gain: f64,
    form: Form,
    n: usize,
    s: usize,
    kkt: Kkt<f64>,
    kkt_dual: Kkt<Dual64>,
    y_dual: Vec<Dual64>,
    g: [f64; MAX_CONSTRAINTS],
    hooks: StepHooks,
    /// `‖Δq̇0‖` of the initial shift to `g = λ0/N`.
    shift: f64,
}

impl<S: Scene> Mass<S> {
    pub fn new(scene: S, options: Params) -> Result<Self, Error> {
        let info = scene.info();
        crate::applicable(info).map_err(|reason| Error::NotApplicable {
            formulation: INFO.name.into(),
            scene: info.name.into(),
            reason,
        })?;
        let (n, s, k) = (info.n(), info.s(), info.k());
        let form = match options.choice("form") {
            "direct" => Form::Direct,
            _ => Form::Compliance,
        };
        let dim = match form {
            Form::Compliance => 2 * n + s,
            Form::Direct => 2 * n,
        };
        Ok(Mass {
            gain: options.real("N"),
            form,
            hooks: StepHooks::unstabilised(&scene, options.real("singular_tol")),
            options,
            n,
            s,
            kkt: Kkt::new(n, s, k),
            kkt_dual: Kkt::new(n, s, k),
            y_dual: vec![Dual64::from_re(0.0); dim],
            g: [0.0; MAX_CONSTRAINTS],
            shift: 0.0,
            scene,
        })
    }

    /// The KKT solve at `y` (`(q, q̇, λ)` or `(q, q̇)`), results in `self.kkt`.
    fn solve_at(&mut self, t: f64, y: &[f64]) -> Result<(), SystemError> {
        solve(&mut self.kkt, &self.scene, self.form, self.gain, t, y)
    }
}

/// The solve of `form` at `y` (`(q, q̇, λ)` or `(q, q̇)`) over any scalar,
/// results in `kkt`.
fn solve<S: Scene, T: Scalar>(
    kkt: &mut Kkt<T>,
    scene: &S,
    form: Form,
    gain: f64,
    t: T,
    y: &[T],
) -> Result<(), SystemError> {
    let n = scene.info().n();
    let (q, rest) = y.split_at(n);
    let (qd, lambda) = rest.split_at(n);
    match form {
        Form::Compliance => kkt.solve_rows(
            &Augmented(scene),
            lambda,
            scene,
            Stabilisation::None,
            GRows::Compliant(1.0 / gain),
            t,
            q,
            qd,
            "formulation mass",
        ),
        Form::Direct => kkt.solve_rows(
            &Penalised(scene),
            &[T::from(gain)],
            scene,
            Stabilisation::None,
            GRows::Absent,
            t,
            q,
            qd,
            "formulation mass",
        ),
    }
}

impl<S: Scene> OdeSystem for Mass<S> {
    fn dim(&self) -> usize {
        self.y_dual.len()
    }

    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let (n, s) = (self.n, self.s);
        self.hooks.check_stage_y(&self.scene, t, y)?;
        self.solve_at(t, y)?;
        dy[..n].copy_from_slice(&y[n..2 * n]);
        dy[n..2 * n].copy_from_slice(self.kkt.qdd());
        if self.form == Form::Compliance {
            dy[2 * n..].copy_from_slice(&self.kkt.mu()[..s]);
        }
        Ok(())
    }

    /// `∂f/∂y`: the solve repeated with one dual direction per column of `y`.
    fn jacobian(&mut self, t: f64, y: &[f64], jac: &mut [f64]) -> Result<bool, SystemError> {
        let (scene, form, gain) = (&self.scene, self.form, self.gain);
        let lambda_rows = match form {
            Form::Compliance => self.s,
            Form::Direct => 0,
        };
        self.kkt_dual
            .jacobian(y, &mut self.y_dual, lambda_rows, jac, |kkt, y| {
                solve(kkt, scene, form, gain, Dual64::from_re(t), y)
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

impl<S: Scene> Model for Mass<S> {
    fn ode(&mut self) -> Option<&mut dyn OdeSystem> {
        Some(self)
    }

    /// The direct form's Jacobian turns with the state at rate ~N (as for
    /// `visc`): full Newton. Measured on the sleigh over 2 s at 1e-10, N = 1e6:
    /// simplified 7856 steps with 11144 Newton failures and 1e-4 off C's
    /// limit; full 3104 steps, 2 failures, on the limit (5e-6 ≈ the 1/N
    /// distance). The compliance form is not stiff: simplified.
    fn radau_newton(&self) -> RadauNewton {
        match self.form {
            Form::Direct => RadauNewton::Full,
            Form::Compliance => RadauNewton::Simplified,
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

    /// `lambda` (or `lambda1`, …): `λ0`, the limit multiplier; `g(0) = λ0/N`.
    fn extra_init_names(&self) -> Vec<ExtraName> {
        lambda_names(
            self.s,
            "initial multiplier λ0 = N g(0) (the motion tends to C's with this λ0)",
        )
    }

    /// The given data must satisfy the constraints (as for C); the shift to
    /// `g = λ0/N` is part of the realisation and made in `initial_state`.
    fn make_consistent(
        &mut self,
        init: &mut Initial,
        project: bool,
    ) -> Result<Option<InitProjection>, Error> {
        check_or_project(&self.scene, init, project)
    }

    fn initial_state(&mut self, init: &Initial) -> Result<Vec<f64>, Error> {
        let lambda0 = lambda0(init, self.s);
        let target: Vec<f64> = lambda0.iter().map(|l| l / self.gain).collect();
        let mut qd = init.qd.clone();
        let shift = Projector::new(&self.scene)
            .shift_velocity(&self.scene, init.t0, &init.q, &mut qd, &target, PROJECT_TOL)
            .map_err(|e| {
                Error::Numerical(format!(
                    "mass: moving q̇0 to g = λ0/N = {target:?} failed: {e}"
                ))
            })?;
        self.shift = shift.dqd_norm;
        self.hooks.start(&self.scene, init.t0, &init.q, &qd);
        let mut y: Vec<f64> = init.q.iter().chain(&qd).copied().collect();
        if self.form == Form::Compliance {
            y.extend(&lambda0);
        }
        Ok(y)
    }

    fn observe(&mut self, t: f64, y: &[f64], obs: &mut Observation) -> Result<(), SystemError> {
        let (n, s) = (self.n, self.s);
        let (q, qd) = (&y[..n], &y[n..2 * n]);
        obs.q.copy_from_slice(q);
        obs.qd.copy_from_slice(qd);
        if obs.multipliers.is_empty() {
            return Ok(());
        }
        match self.form {
            Form::Compliance => obs.multipliers[..s].copy_from_slice(&y[2 * n..]),
            Form::Direct => {
                self.scene.nonholonomic(t, q, qd, &mut self.g[..s]);
                for (m, g) in obs.multipliers.iter_mut().zip(&self.g[..s]) {
                    *m = self.gain * g;
                }
            }
        }
        if obs.multipliers.len() > s {
            self.solve_at(t, y)?;
            for (m, v) in obs.multipliers[s..].iter_mut().zip(&self.kkt.mu()[s..]) {
                *m = -v;
            }
        }
        Ok(())
    }

    fn init_report(&self) -> Vec<(&'static str, f64)> {
        vec![("init_velocity_shift", self.shift)]
    }

    fn diagnostics(&self) -> Diagnostics {
        self.hooks.diagnostics().clone()
    }
}
