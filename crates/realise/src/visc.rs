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

use nonholo_core::binding::{Binding, Equations, EvalError};
use nonholo_core::compiled::Programs;
use nonholo_core::integrate::RadauNewton;
use nonholo_core::kkt::Kkt;
use nonholo_core::model::FormulationInfo;
use nonholo_core::param::{Bound, ParamSpec, Params, Value};
use nonholo_core::scene::{Lagrangian, MAX_CONSTRAINTS, Scalar, Scene, SceneInfo};
use nonholo_core::stab::{SINGULAR_TOL, Stabilisation};
use nonholo_core::{Error, Initial};

use crate::adapted::Rates;
use crate::rows::Viscous;

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

/// The viscous realisation bound to a scene.
pub type Visc<S> = Binding<S, ViscEquations>;

/// The equations of `visc`: the gain `k` and the state they are integrated in.
#[derive(Debug, Clone)]
pub struct ViscEquations {
    k: f64,
    form: Form,
    /// `L` and the constraints, compiled once (Cartesian form).
    programs: Programs,
}

impl ViscEquations {
    /// The state the equations are integrated in.
    pub fn form(&self) -> Form {
        self.form
    }
}

/// The workspace of the form in use, over the scalar `T`.
pub enum ViscWork<T: Scalar> {
    /// The KKT solve of the Cartesian form.
    Cartesian(Box<Kkt<T>>),
    /// The frame and KKT solve of the adapted form.
    Adapted(Box<Rates<T>>),
}

/// The Cartesian form's KKT solve at `(t, q, q̇)` over any scalar, results in `kkt`.
fn solve<S: Scene, T: Scalar>(
    kkt: &mut Kkt<T>,
    scene: &S,
    gain: f64,
    t: T,
    q: &[T],
    qd: &[T],
) -> Result<(), EvalError> {
    kkt.solve(&Lagrangian(scene), &[], scene, &Viscous(gain), t, q, qd)?;
    Ok(())
}

impl Equations for ViscEquations {
    type Work<T: Scalar> = ViscWork<T>;
    const INFO: &'static FormulationInfo = &INFO;

    /// `form = auto` resolves here, and is recorded as what it resolved to.
    fn new<S: Scene>(scene: &S, options: &mut Params) -> Result<Self, Error> {
        let info = scene.info();
        let form = match options.choice(FORM.name)? {
            "cartesian" => Form::Cartesian,
            "adapted" => {
                crate::adapted::applicable(scene).map_err(|reason| Error::NotApplicable {
                    formulation: INFO.name.into(),
                    scene: info.name.into(),
                    reason: format!("form = adapted: {reason} (form = cartesian applies)"),
                })?;
                Form::Adapted
            }
            _ => match crate::adapted::applicable(scene) {
                Ok(()) => Form::Adapted,
                Err(_) => Form::Cartesian,
            },
        };
        options.set(
            FORM.name,
            Value::Choice(match form {
                Form::Adapted => "adapted",
                Form::Cartesian => "cartesian",
            }),
            "option",
        )?;
        Ok(ViscEquations {
            k: options.real(K.name)?,
            form,
            programs: Programs::default(),
        })
    }

    fn work<S: Scene, T: Scalar>(&self, scene: &S) -> ViscWork<T> {
        let info = scene.info();
        let (n, s) = (info.n(), info.s());
        match self.form {
            Form::Cartesian => ViscWork::Cartesian(Box::new(
                Kkt::new(n, s, info.k()).compiled_for(&self.programs, &Lagrangian(scene), 0, scene),
            )),
            Form::Adapted => ViscWork::Adapted(Box::new(Rates::new(scene, self.k, &self.programs))),
        }
    }

    fn dim(&self, info: &SceneInfo) -> usize {
        2 * info.n()
    }

    fn cartesian(&self) -> bool {
        self.form == Form::Cartesian
    }

    /// Cartesian: `q̇` from the state; adapted: `q̇ = T(q, t) v`.
    fn velocities<S: Scene, T: Scalar>(
        &self,
        scene: &S,
        work: &mut ViscWork<T>,
        t: T,
        y: &[T],
        qd: &mut [T],
    ) -> Result<(), EvalError> {
        let n = qd.len();
        let (q, v) = y.split_at(n);
        match work {
            ViscWork::Cartesian(_) => qd.copy_from_slice(v),
            ViscWork::Adapted(rates) => {
                rates.velocities(scene, t, q, v)?;
                qd.copy_from_slice(&rates.qd);
            }
        }
        Ok(())
    }

    /// Cartesian: `q̈` of `M q̈ − Q = −k Gᵀ g`; adapted: `v̇ = T⁻¹(q̈ − Ṫ v)`.
    fn accelerations<S: Scene, T: Scalar>(
        &self,
        scene: &S,
        _stab: Stabilisation,
        work: &mut ViscWork<T>,
        t: T,
        y: &[T],
        rest: &mut [T],
    ) -> Result<(), EvalError> {
        let (q, v) = y.split_at(rest.len());
        match work {
            ViscWork::Cartesian(kkt) => {
                solve(kkt, scene, self.k, t, q, v)?;
                rest.copy_from_slice(kkt.qdd());
                Ok(())
            }
            ViscWork::Adapted(rates) => rates.accelerations(scene, t, q, v, rest),
        }
    }

    /// `λ = −k g` (the friction force is `Gᵀλ`; in the adapted form `g = w`,
    /// the state itself), then `ν` of holonomic constraints.
    fn multipliers<S: Scene>(
        &self,
        scene: &S,
        _stab: Stabilisation,
        work: &mut ViscWork<f64>,
        t: f64,
        y: &[f64],
        qd: &[f64],
        out: &mut [f64],
    ) -> Result<(), EvalError> {
        let info = scene.info();
        let (n, s) = (info.n(), info.s());
        match work {
            ViscWork::Adapted(_) => {
                // No holonomic constraints in this form: the multipliers are λ only.
                for (m, w) in out.iter_mut().zip(&y[2 * n - s..]) {
                    *m = -self.k * w;
                }
            }
            ViscWork::Cartesian(kkt) => {
                let q = &y[..n];
                let mut g = [0.0; MAX_CONSTRAINTS];
                scene.nonholonomic(t, q, qd, &mut g[..s]);
                for (m, g) in out.iter_mut().zip(&g[..s]) {
                    *m = -self.k * g;
                }
                if out.len() > s {
                    solve(kkt, scene, self.k, t, q, qd)?;
                    for (m, v) in out[s..].iter_mut().zip(&kkt.mu()[s..]) {
                        *m = -v;
                    }
                }
            }
        }
        Ok(())
    }

    /// `(q0, q̇0)`; in the adapted form `(q0, v0)` with `T(q0, t0) v0 = q̇0`,
    /// so that `w0 = g(q0, q̇0)` (zero to rounding for consistent data).
    fn initial_state<S: Scene>(
        &mut self,
        scene: &S,
        work: &mut ViscWork<f64>,
        init: &Initial,
    ) -> Result<Vec<f64>, Error> {
        let n = init.q.len();
        let mut y: Vec<f64> = init.q.iter().chain(&init.qd).copied().collect();
        if let ViscWork::Adapted(rates) = work {
            rates
                .adapted(scene, init.t0, &init.q, &init.qd, &mut y[n..])
                .map_err(|e| Error::numerical("visc: initial velocities", e))?;
        }
        Ok(y)
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
        match self.form {
            Form::Cartesian => RadauNewton::Full,
            Form::Adapted => RadauNewton::Simplified,
        }
    }
}
