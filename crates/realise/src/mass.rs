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

use nonholo_core::binding::{Binding, Equations, EvalError};
use nonholo_core::compiled::Programs;
use nonholo_core::consistency::PROJECT_TOL;
use nonholo_core::init::{ExtraName, lambda_names, lambda0};
use nonholo_core::integrate::RadauNewton;
use nonholo_core::kkt::Kkt;
use nonholo_core::model::FormulationInfo;
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::project::Projector;
use nonholo_core::scene::{Augmented, MAX_CONSTRAINTS, Scalar, ScalarField, Scene, SceneInfo};
use nonholo_core::stab::{SINGULAR_TOL, Stabilisation};
use nonholo_core::{Error, Initial};

use crate::rows::{Absent, Compliant};

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
pub type Mass<S> = Binding<S, MassEquations>;

/// The equations of `mass`: the form, the gain `N`, and the initial shift.
#[derive(Debug, Clone)]
pub struct MassEquations {
    gain: f64,
    form: Form,
    /// `‖Δq̇0‖` of the initial shift to `g = λ0/N`.
    shift: f64,
    /// The form's field and the constraints, compiled once.
    programs: Programs,
}

impl MassEquations {
    /// The form of the equations.
    pub fn form(&self) -> Form {
        self.form
    }
}

/// `L + (N/2) gᵀg` with `N = p[0]`: the Lagrangian of the added-mass
/// realisation written directly.
struct Penalised<'a, S>(&'a S);

impl<S: Scene> ScalarField for Penalised<'_, S> {
    fn n(&self) -> usize {
        self.0.info().n()
    }
    #[inline]
    fn eval<D: Scalar>(&self, t: D, q: &[D], qd: &[D], p: &[D]) -> D {
        let s = self.0.info().s();
        let mut g = [D::from(0.0); MAX_CONSTRAINTS];
        self.0.nonholonomic(t, q, qd, &mut g[..s]);
        let mut l = self.0.lagrangian(t, q, qd);
        for gi in &g[..s] {
            l += p[0] * *gi * *gi * 0.5;
        }
        l
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
) -> Result<(), EvalError> {
    let n = scene.info().n();
    let (q, rest) = y.split_at(n);
    let (qd, lambda) = rest.split_at(n);
    match form {
        Form::Compliance => kkt.solve(
            &Augmented(scene),
            lambda,
            scene,
            &Compliant(1.0 / gain),
            t,
            q,
            qd,
        )?,
        Form::Direct => kkt.solve(
            &Penalised(scene),
            &[T::from(gain)],
            scene,
            &Absent,
            t,
            q,
            qd,
        )?,
    }
    Ok(())
}

impl Equations for MassEquations {
    type Work<T: Scalar> = Kkt<T>;
    const INFO: &'static FormulationInfo = &INFO;

    fn new<S: Scene>(_scene: &S, options: &mut Params) -> Result<Self, Error> {
        let form = match options.choice(FORM.name)? {
            "direct" => Form::Direct,
            _ => Form::Compliance,
        };
        Ok(MassEquations {
            gain: options.real(N.name)?,
            form,
            shift: 0.0,
            programs: Programs::default(),
        })
    }

    /// The KKT workspace with the form's field and the constraints
    /// compiled into one program where the trace holds.
    fn work<S: Scene, T: Scalar>(&self, scene: &S) -> Kkt<T> {
        let kkt = Kkt::for_scene(scene.info());
        match self.form {
            Form::Compliance => {
                kkt.compiled_for(&self.programs, &Augmented(scene), scene.info().s(), scene)
            }
            Form::Direct => kkt.compiled_for(&self.programs, &Penalised(scene), 1, scene),
        }
    }

    fn dim(&self, info: &SceneInfo) -> usize {
        match self.form {
            Form::Compliance => 2 * info.n() + info.s(),
            Form::Direct => 2 * info.n(),
        }
    }

    /// `q̈`, and `λ̇` in the compliance form.
    fn accelerations<S: Scene, T: Scalar>(
        &self,
        scene: &S,
        _stab: Stabilisation,
        kkt: &mut Kkt<T>,
        t: T,
        y: &[T],
        rest: &mut [T],
    ) -> Result<(), EvalError> {
        let info = scene.info();
        let (n, s) = (info.n(), info.s());
        solve(kkt, scene, self.form, self.gain, t, y)?;
        rest[..n].copy_from_slice(kkt.qdd());
        if self.form == Form::Compliance {
            rest[n..].copy_from_slice(&kkt.mu()[..s]);
        }
        Ok(())
    }

    /// `λ` (compliance: the state; direct: `N g`), then `ν` of holonomic
    /// constraints from the solve.
    fn multipliers<S: Scene>(
        &self,
        scene: &S,
        _stab: Stabilisation,
        kkt: &mut Kkt<f64>,
        t: f64,
        y: &[f64],
        qd: &[f64],
        out: &mut [f64],
    ) -> Result<(), EvalError> {
        let info = scene.info();
        let (n, s) = (info.n(), info.s());
        match self.form {
            Form::Compliance => out[..s].copy_from_slice(&y[2 * n..]),
            Form::Direct => {
                let mut g = [0.0; MAX_CONSTRAINTS];
                scene.nonholonomic(t, &y[..n], qd, &mut g[..s]);
                for (m, g) in out.iter_mut().zip(&g[..s]) {
                    *m = self.gain * g;
                }
            }
        }
        if out.len() > s {
            solve(kkt, scene, self.form, self.gain, t, y)?;
            for (m, v) in out[s..].iter_mut().zip(&kkt.mu()[s..]) {
                *m = -v;
            }
        }
        Ok(())
    }

    /// `q̇0` moved, nearest in the kinetic-energy metric, to `g = λ0/N`;
    /// the compliance form starts with `λ(0) = λ0`.
    fn initial_state<S: Scene>(
        &mut self,
        scene: &S,
        _kkt: &mut Kkt<f64>,
        init: &Initial,
    ) -> Result<Vec<f64>, Error> {
        let lambda0 = lambda0(init, scene.info().s());
        let target: Vec<f64> = lambda0.iter().map(|l| l / self.gain).collect();
        let mut qd = init.qd.clone();
        let shift = Projector::new(scene)
            .shift_velocity(scene, init.t0, &init.q, &mut qd, &target, PROJECT_TOL)
            .map_err(|e| {
                Error::numerical(format!("mass: moving q̇0 to g = λ0/N = {target:?}"), e)
            })?;
        self.shift = shift.dqd_norm;
        let mut y: Vec<f64> = init.q.iter().chain(&qd).copied().collect();
        if self.form == Form::Compliance {
            y.extend(&lambda0);
        }
        Ok(y)
    }

    /// `lambda` (or `lambda1`, …): `λ0`, the limit multiplier; `g(0) = λ0/N`.
    fn extra_init_names(&self, info: &SceneInfo) -> Vec<ExtraName> {
        lambda_names(
            info.s(),
            "initial multiplier λ0 = N g(0) (the motion tends to C's with this λ0)",
        )
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

    fn init_report(&self) -> Vec<(&'static str, f64)> {
        vec![("init_velocity_shift", self.shift)]
    }
}
