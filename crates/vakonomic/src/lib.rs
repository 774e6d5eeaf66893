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

use nonholo_core::Error;
use nonholo_core::Initial;
use nonholo_core::binding::{Binding, Equations, EvalError};
use nonholo_core::compiled::{Compiled, Programs};
use nonholo_core::dae::{FORM, Field, KktDae};
use nonholo_core::init::{ExtraName, lambda0};
use nonholo_core::kkt::{Ideal, Kkt};
use nonholo_core::linalg::copy_small;
use nonholo_core::model::{FormulationInfo, Model};
use nonholo_core::param::{ParamSpec, Params};
use nonholo_core::scene::{Augmented, Scalar, Scene, SceneInfo};
use nonholo_core::stab::{BAUMGARTE_ALPHA, BAUMGARTE_BETA, SINGULAR_TOL, STAB, Stabilisation};

/// Options of formulation C.
pub const OPTIONS: &[ParamSpec] = &[STAB, BAUMGARTE_ALPHA, BAUMGARTE_BETA, SINGULAR_TOL, FORM];

/// C on `scene` as an index-1 DAE with sparse Jacobians
/// ([`nonholo_core::dae`]; `form = "dae"`): `y = (q, q̇, λ, q̈, λ̇, −ν)`,
/// with C's `options`.
pub fn dae<S: Scene>(scene: S, options: Params) -> Result<KktDae<S>, Error> {
    KktDae::new(scene, options, &INFO, Field::Augmented)
}

/// C bound to `scene` in the form its `options` choose ([`FORM`]).
pub fn model<S: Scene>(scene: S, options: Params) -> Result<Box<dyn Model>, Error> {
    Ok(match options.choice(FORM.name)? {
        "dae" => Box::new(dae(scene, options)?),
        _ => Box::new(Vakonomic::new(scene, options)?),
    })
}

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
    Ok(())
}

/// Formulation C bound to a scene ([`Binding::taylor`] gives the Taylor
/// coefficients of its motions, with which A is matched).
pub type Vakonomic<S> = Binding<S, VakonomicEquations>;

/// The equations of C: `(q̈, λ̇)` from one KKT solve of `L + λᵀg` at frozen `λ`.
#[derive(Debug, Clone, Default)]
pub struct VakonomicEquations {
    /// `L + λᵀg` and the constraints, compiled once for every workspace.
    programs: Programs,
}

/// C's KKT solve at `y = (q, q̇, λ)` over any scalar: `(q̈, λ̇, −ν)` in `kkt.sol`.
fn solve<S: Scene, T: Scalar>(
    kkt: &mut Kkt<T>,
    scene: &S,
    stab: Stabilisation,
    t: T,
    y: &[T],
) -> Result<(), EvalError> {
    let n = scene.info().n();
    let (q, rest) = y.split_at(n);
    let (qd, lambda) = rest.split_at(n);
    kkt.solve(&Augmented(scene), lambda, scene, &Ideal(stab), t, q, qd)?;
    Ok(())
}

impl Equations for VakonomicEquations {
    type Work<T: Scalar> = Kkt<T>;
    const INFO: &'static FormulationInfo = &INFO;

    fn new<S: Scene>(_scene: &S, _options: &mut Params) -> Result<Self, Error> {
        Ok(VakonomicEquations::default())
    }

    /// The KKT workspace with `L + λᵀg` and the constraints compiled
    /// into one program ([`nonholo_core::compiled`]) where the trace holds.
    fn work<S: Scene, T: Scalar>(&self, scene: &S) -> Kkt<T> {
        let s = scene.info().s();
        Kkt::for_scene(scene.info()).compiled_for(&self.programs, &Augmented(scene), s, scene)
    }

    fn program<'w>(&self, work: &'w Kkt<f64>) -> Option<&'w Compiled> {
        work.compiled()
    }

    fn keeps_constraints(&self) -> bool {
        true
    }

    fn extra_state_names(&self, info: &SceneInfo) -> Vec<String> {
        nonholo_core::model::multiplier_names(info.s(), 0)
    }

    fn dim(&self, info: &SceneInfo) -> usize {
        2 * info.n() + info.s()
    }

    /// `(q̈, λ̇)` of the KKT solve.
    fn accelerations<S: Scene, T: Scalar>(
        &self,
        scene: &S,
        stab: Stabilisation,
        kkt: &mut Kkt<T>,
        t: T,
        y: &[T],
        rest: &mut [T],
    ) -> Result<(), EvalError> {
        let info = scene.info();
        let (n, s) = (info.n(), info.s());
        solve(kkt, scene, stab, t, y)?;
        copy_small(&mut rest[..n], kkt.qdd());
        copy_small(&mut rest[n..], &kkt.mu()[..s]);
        Ok(())
    }

    /// `λ` from the state; `ν` of holonomic constraints from the KKT solve.
    fn multipliers<S: Scene>(
        &self,
        scene: &S,
        stab: Stabilisation,
        kkt: &mut Kkt<f64>,
        t: f64,
        y: &[f64],
        _qd: &[f64],
        out: &mut [f64],
    ) -> Result<(), EvalError> {
        let info = scene.info();
        let (n, s) = (info.n(), info.s());
        out[..s].copy_from_slice(&y[2 * n..]);
        if out.len() > s {
            solve(kkt, scene, stab, t, y)?;
            for (v, m) in out[s..].iter_mut().zip(&kkt.mu()[s..]) {
                *v = -m;
            }
        }
        Ok(())
    }

    /// `(q0, q̇0, λ0)`, `λ0` from `--init lambda=…` (0 where not given).
    fn initial_state<S: Scene>(
        &mut self,
        scene: &S,
        _kkt: &mut Kkt<f64>,
        init: &Initial,
    ) -> Result<Vec<f64>, Error> {
        let mut y: Vec<f64> = init.q.iter().chain(&init.qd).copied().collect();
        y.extend(lambda0(init, scene.info().s()));
        Ok(y)
    }

    /// `lambda` (or `lambda1`, …): the initial multipliers `λ(0)`.
    fn extra_init_names(&self, info: &SceneInfo) -> Vec<ExtraName> {
        lambda_names(info.s())
    }
}

/// The names of the initial multipliers: `lambda`, or `lambda1..s`.
pub fn lambda_names(s: usize) -> Vec<ExtraName> {
    nonholo_core::init::lambda_names(s, "initial multiplier λ(0) of L + λᵀg")
}
