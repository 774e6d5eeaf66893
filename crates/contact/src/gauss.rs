//! Formulation `gauss`: Gauss's principle of least constraint as a
//! quadratic program.
//!
//! Among the accelerations the constraints allow, the motion takes the one
//! closest to the free acceleration `M⁻¹Q` in the kinetic-energy metric:
//!
//! ```text
//! q̈ = argmin ½ (a − M⁻¹Q)ᵀ M (a − M⁻¹Q) = argmin ½ aᵀ M a − Qᵀ a
//!     subject to   G a = −ġ₀,   F a = −f̈₀
//! ```
//!
//! (the rows of B's KKT system, Baumgarte terms included when chosen). The
//! program is solved by Clarabel; its multipliers `z` of the equality rows
//! satisfy `M q̈ − Q = −Gᵀ z_g − Fᵀ z_f`, so `λ = −z_g`, `ν = −z_f` in B's
//! convention. With equality constraints only, the optimality conditions
//! of the program are B's KKT system: `gauss` and `chetaev` are the same
//! motion computed two ways, which the tests check state by state.
//!
//! Derivatives (the right-hand side's Jacobian for implicit methods, Taylor
//! coefficients) are those of the program's solution map; by the implicit
//! function theorem they solve the linearised optimality conditions, which
//! for equality rows is the KKT system over dual numbers. So over `f64` the
//! value comes from Clarabel, over dual numbers from the KKT solve.
//!
//! One solve costs tens of microseconds against ~1 µs for B's LU: the
//! formulation is the check that the conic machinery reproduces B, and the
//! base that the friction cones of [`crate::friction`] build on.

use clarabel::solver::SupportedConeT;
use nonholo_core::Error;
use nonholo_core::binding::{Binding, Equations, EvalError};
use nonholo_core::compiled::Programs;
use nonholo_core::integrate::SystemError;
use nonholo_core::kkt::{Ideal, Kkt};
use nonholo_core::model::FormulationInfo;
use nonholo_core::param::{ParamSpec, Params};
use nonholo_core::scene::{Lagrangian, Scalar, Scene, SceneInfo};
use nonholo_core::stab::{BAUMGARTE_ALPHA, BAUMGARTE_BETA, SINGULAR_TOL, STAB, Stabilisation};

use crate::conic::ConicProgram;

/// Options of `gauss`: B's.
pub const OPTIONS: &[ParamSpec] = &[STAB, BAUMGARTE_ALPHA, BAUMGARTE_BETA, SINGULAR_TOL];

pub const INFO: FormulationInfo = FormulationInfo {
    name: "gauss",
    letter: "GAUSS",
    title: "Gauss's principle of least constraint, a quadratic program solved by Clarabel",
    description: "q̈ minimises ½ (q̈ − M⁻¹Q)ᵀ M (q̈ − M⁻¹Q) subject to the constraint rows of B; \
                  the same motion as B (chetaev), one conic solve per right-hand side; state (q, q̇)",
    options: OPTIONS,
    applicable,
};

/// Gauss's principle needs constraints to minimise over.
fn applicable(scene: &SceneInfo) -> Result<(), String> {
    if scene.s() + scene.k() == 0 {
        return Err("the scene has no constraints: Gauss's principle is Newton's law, B".into());
    }
    Ok(())
}

/// Formulation `gauss` bound to a scene.
pub type Gauss<S> = Binding<S, GaussEquations>;

/// The equations of `gauss`.
#[derive(Debug, Clone, Default)]
pub struct GaussEquations {
    /// `L` and the constraints, compiled once for every workspace.
    programs: Programs,
}

/// The workspace: the KKT system's pieces and, over `f64`, the program.
pub struct GaussWork<T: Scalar> {
    kkt: Kkt<T>,
    program: Option<Box<ConicProgram>>,
    /// `−Q` and the rows' right-hand side, as the program takes them.
    neg_force: Vec<f64>,
    rows: Vec<f64>,
}

/// `(q̈, μ)` at `(t, q, q̇)` into `work.kkt.sol`, with `μ = (−λ, −ν)` as in
/// B's KKT solve: by Clarabel over `f64`, by the linearised optimality
/// conditions (the KKT system) over dual numbers.
fn solve<S: Scene, T: Scalar>(
    work: &mut GaussWork<T>,
    scene: &S,
    stab: Stabilisation,
    t: T,
    q: &[T],
    qd: &[T],
) -> Result<(), EvalError> {
    let GaussWork {
        kkt,
        program,
        neg_force,
        rows,
    } = work;
    kkt.assemble(&Lagrangian(scene), &[], scene, &Ideal(stab), t, q, qd);
    let Some(program) = program.as_mut().filter(|_| T::REAL) else {
        kkt.solve_assembled()?;
        return Ok(());
    };
    let n = q.len();
    let (matrix, rhs) = kkt.system();
    let m = rhs.len() - n;
    for (b, v) in neg_force.iter_mut().zip(&rhs[..n]) {
        *b = -v.re();
    }
    for (b, v) in rows.iter_mut().zip(&rhs[n..]) {
        *b = v.re();
    }
    program.set(
        |i, j| matrix[(i, j)].re(),
        neg_force,
        |i, j| matrix[(n + i, j)].re(),
        rows,
    );
    program.solve().map_err(|e| {
        EvalError::System(SystemError::new(format!(
            "formulation GAUSS: the quadratic program has no solution here ({e})"
        )))
    })?;
    let (x, z) = (program.x(), program.z());
    let sol = kkt.sol_mut();
    for i in 0..n {
        sol[i] = T::from(x[i]);
    }
    for i in 0..m {
        sol[n + i] = T::from(z[i]);
    }
    Ok(())
}

impl Equations for GaussEquations {
    type Work<T: Scalar> = GaussWork<T>;
    const INFO: &'static FormulationInfo = &INFO;

    fn new<S: Scene>(_scene: &S, _options: &mut Params) -> Result<Self, Error> {
        Ok(GaussEquations::default())
    }

    fn work<S: Scene, T: Scalar>(&self, scene: &S) -> GaussWork<T> {
        let info = scene.info();
        let (n, m) = (info.n(), info.s() + info.k());
        GaussWork {
            kkt: Kkt::for_scene(info).compiled_for(&self.programs, &Lagrangian(scene), 0, scene),
            program: T::REAL
                .then(|| Box::new(ConicProgram::new(n, m, vec![SupportedConeT::ZeroConeT(m)]))),
            neg_force: vec![0.0; n],
            rows: vec![0.0; m],
        }
    }

    fn keeps_constraints(&self) -> bool {
        true
    }

    fn dim(&self, info: &SceneInfo) -> usize {
        2 * info.n()
    }

    fn accelerations<S: Scene, T: Scalar>(
        &self,
        scene: &S,
        stab: Stabilisation,
        work: &mut GaussWork<T>,
        t: T,
        y: &[T],
        qdd: &mut [T],
    ) -> Result<(), EvalError> {
        let (q, qd) = y.split_at(qdd.len());
        solve(work, scene, stab, t, q, qd)?;
        qdd.copy_from_slice(work.kkt.qdd());
        Ok(())
    }

    /// `λ` then `ν`: minus the program's multipliers.
    fn multipliers<S: Scene>(
        &self,
        scene: &S,
        stab: Stabilisation,
        work: &mut GaussWork<f64>,
        t: f64,
        y: &[f64],
        qd: &[f64],
        out: &mut [f64],
    ) -> Result<(), EvalError> {
        solve(work, scene, stab, t, &y[..qd.len()], qd)?;
        for (m, v) in out.iter_mut().zip(work.kkt.mu()) {
            *m = -v;
        }
        Ok(())
    }
}
