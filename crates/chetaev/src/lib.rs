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
//!
//! [`dae`] writes the same equations as an index-1 differential-algebraic
//! system in `(q, q̇, q̈, −λ, −ν)` with sparse Jacobians, for Radau IIA on
//! large scenes ([`nonholo_core::dae`]).

use nonholo_core::Error;
use nonholo_core::binding::{Binding, Equations, EvalError};
use nonholo_core::compiled::{Compiled, Programs};
use nonholo_core::dae::{FORM, Field, KktDae};
use nonholo_core::kkt::{Ideal, Kkt};
use nonholo_core::model::{FormulationInfo, Model};
use nonholo_core::param::{ParamSpec, Params};
use nonholo_core::scene::{Lagrangian, Scalar, Scene, SceneInfo};
use nonholo_core::stab::{BAUMGARTE_ALPHA, BAUMGARTE_BETA, SINGULAR_TOL, STAB, Stabilisation};

/// Options of formulation B.
pub const OPTIONS: &[ParamSpec] = &[STAB, BAUMGARTE_ALPHA, BAUMGARTE_BETA, SINGULAR_TOL, FORM];

/// B on `scene` as an index-1 DAE with sparse Jacobians
/// ([`nonholo_core::dae`]; `form = "dae"`), with B's `options`.
pub fn dae<S: Scene>(scene: S, options: Params) -> Result<KktDae<S>, Error> {
    KktDae::new(scene, options, &INFO, Field::Lagrangian)
}

/// B bound to `scene` in the form its `options` choose ([`FORM`]).
pub fn model<S: Scene>(scene: S, options: Params) -> Result<Box<dyn Model>, Error> {
    Ok(match options.choice(FORM.name)? {
        "dae" => Box::new(dae(scene, options)?),
        _ => Box::new(Chetaev::new(scene, options)?),
    })
}

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
pub type Chetaev<S> = Binding<S, ChetaevEquations>;

/// The equations of B: `q̈` and the multipliers from one KKT solve of `L`.
#[derive(Debug, Clone, Default)]
pub struct ChetaevEquations {
    /// `L` and the constraints, compiled once for every workspace.
    programs: Programs,
}

/// B's KKT solve at `(t, q, q̇)`: `(q̈, −λ, −ν)` in `kkt.sol`.
fn solve<S: Scene, T: Scalar>(
    kkt: &mut Kkt<T>,
    scene: &S,
    stab: Stabilisation,
    t: T,
    q: &[T],
    qd: &[T],
) -> Result<(), EvalError> {
    kkt.solve(&Lagrangian(scene), &[], scene, &Ideal(stab), t, q, qd)?;
    Ok(())
}

impl Equations for ChetaevEquations {
    type Work<T: Scalar> = Kkt<T>;
    const INFO: &'static FormulationInfo = &INFO;

    fn new<S: Scene>(_scene: &S, _options: &mut Params) -> Result<Self, Error> {
        Ok(ChetaevEquations::default())
    }

    /// The KKT workspace with `L` and the constraints compiled into one
    /// program ([`nonholo_core::compiled`]) where the trace holds.
    fn work<S: Scene, T: Scalar>(&self, scene: &S) -> Kkt<T> {
        Kkt::for_scene(scene.info()).compiled_for(&self.programs, &Lagrangian(scene), 0, scene)
    }

    fn program<'w>(&self, work: &'w Kkt<f64>) -> Option<&'w Compiled> {
        work.compiled()
    }

    fn keeps_constraints(&self) -> bool {
        true
    }

    fn dim(&self, info: &SceneInfo) -> usize {
        2 * info.n()
    }

    /// `q̈` of the KKT solve.
    fn accelerations<S: Scene, T: Scalar>(
        &self,
        scene: &S,
        stab: Stabilisation,
        kkt: &mut Kkt<T>,
        t: T,
        y: &[T],
        qdd: &mut [T],
    ) -> Result<(), EvalError> {
        let (q, qd) = y.split_at(qdd.len());
        solve(kkt, scene, stab, t, q, qd)?;
        nonholo_core::linalg::copy_small(qdd, kkt.qdd());
        Ok(())
    }

    /// `λ` then `ν`: minus the KKT solution's multiplier part.
    fn multipliers<S: Scene>(
        &self,
        scene: &S,
        stab: Stabilisation,
        kkt: &mut Kkt<f64>,
        t: f64,
        y: &[f64],
        qd: &[f64],
        out: &mut [f64],
    ) -> Result<(), EvalError> {
        solve(kkt, scene, stab, t, &y[..qd.len()], qd)?;
        for (m, v) in out.iter_mut().zip(kkt.mu()) {
            *m = -v;
        }
        Ok(())
    }
}
