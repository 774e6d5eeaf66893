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

use nalgebra::DMatrix;
use nonholo_core::ad::Jet;
use nonholo_core::consistency::{InitProjection, check_or_project};
use nonholo_core::constraints::ConstraintState;
use nonholo_core::integrate::{OdeSystem, SystemError};
use nonholo_core::linalg::Lu;
use nonholo_core::model::{FormulationInfo, Model, Observation, multiplier_names};
use nonholo_core::monitor::Monitor;
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::project::Projector;
use nonholo_core::scene::{Lagrangian, Scalar, Scene, SceneInfo};
use nonholo_core::{Diagnostics, Error, Initial, consistency};
use num_dual::Dual64;

/// Options of formulation B.
pub const OPTIONS: &[ParamSpec] = &[
    ParamSpec::choice(
        "stab",
        &["none", "baumgarte", "projection"],
        "constraint stabilisation: none; Baumgarte (ġ + 2α g = 0, f̈ + 2α ḟ + β² f = 0); \
         projection onto the constraints after every step",
    ),
    ParamSpec::real(
        "baumgarte_alpha",
        "1/s",
        5.0,
        Bound::Inclusive(0.0),
        Bound::Unbounded,
        "Baumgarte damping gain α",
    ),
    ParamSpec::real(
        "baumgarte_beta",
        "1/s",
        5.0,
        Bound::Inclusive(0.0),
        Bound::Unbounded,
        "Baumgarte stiffness gain β (holonomic constraints)",
    ),
    ParamSpec::real(
        "singular_tol",
        "",
        1e-8,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "the run stops where the constraint's regularity measure (appell-hamel: horizontal speed) falls to this value",
    ),
];

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

/// Constraint stabilisation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stabilisation {
    None,
    /// `ġ + 2α g = 0`, `f̈ + 2α ḟ + β² f = 0`.
    Baumgarte {
        alpha: f64,
        beta: f64,
    },
    /// Projection onto `f = 0`, `g = 0`, `ḟ = 0` after every accepted step.
    Projection,
}

/// Workspace of one KKT solve of B over base scalar `T` (`f64` for values,
/// `Dual64` for Jacobian columns).
struct Kkt<T: Scalar> {
    jet: Jet<T>,
    cs: ConstraintState<T>,
    matrix: DMatrix<T>,
    lu: Lu,
    /// Right-hand side, then solution `(q̈, −λ, −ν)`.
    sol: Vec<T>,
}

impl<T: Scalar> Kkt<T> {
    fn new(n: usize, s: usize, k: usize) -> Self {
        Kkt {
            jet: Jet::new(n, s.max(k)),
            cs: ConstraintState::new(n, s, k),
            matrix: DMatrix::from_element(n + s + k, n + s + k, T::from(0.0)),
            lu: Lu::new(n + s + k),
            sol: vec![T::from(0.0); n + s + k],
        }
    }

    /// Assembles and solves the KKT system at `(t, q, q̇)`; leaves `q̈` in
    /// `sol[..n]` and `(−λ, −ν)` in `sol[n..]`.
    fn solve<S: Scene>(
        &mut self,
        scene: &S,
        stab: Stabilisation,
        t: T,
        q: &[T],
        qd: &[T],
    ) -> Result<(), SystemError> {
        let n = q.len();
        let (s, k) = (self.cs.s, self.cs.k);
        self.matrix.fill(T::from(0.0));
        self.jet.mass_and_force(
            &Lagrangian(scene),
            t,
            q,
            qd,
            &mut self.matrix.view_mut((0, 0), (n, n)),
            &mut self.sol[..n],
        );
        if s + k > 0 {
            self.cs.evaluate(&mut self.jet, scene, t, q, qd);
            for r in 0..s + k {
                for j in 0..n {
                    let c = self.cs.jac[(r, j)];
                    self.matrix[(n + r, j)] = c;
                    self.matrix[(j, n + r)] = c;
                }
            }
            let (alpha, beta) = match stab {
                Stabilisation::Baumgarte { alpha, beta } => (alpha, beta),
                _ => (0.0, 0.0),
            };
            for i in 0..s {
                self.sol[n + i] = -self.cs.g_rate0[i] - self.cs.g[i] * (2.0 * alpha);
            }
            for i in 0..k {
                self.sol[n + s + i] = -self.cs.f_accel0[i]
                    - self.cs.f_rate[i] * (2.0 * alpha)
                    - self.cs.f[i] * (beta * beta);
            }
        }
        self.lu.factor(&mut self.matrix).map_err(|e| {
            SystemError::new(format!(
                "KKT system of formulation B singular ({e}): constraints dependent, \
                 or the kinetic energy degenerate on the admissible velocities"
            ))
        })?;
        self.lu.solve(&self.matrix, &mut self.sol);
        Ok(())
    }
}

/// Formulation B bound to a scene.
pub struct Chetaev<S: Scene> {
    scene: S,
    options: Params,
    stab: Stabilisation,
    singular_tol: f64,
    n: usize,
    kkt: Kkt<f64>,
    /// The same solve carrying one directional derivative, for Jacobians.
    kkt_dual: Kkt<Dual64>,
    y_dual: Vec<Dual64>,
    projector: Projector,
    monitor: Monitor,
}

impl<S: Scene> Chetaev<S> {
    pub fn new(scene: S, options: Params) -> Result<Self, Error> {
        let info = scene.info();
        (INFO.applicable)(info).map_err(|reason| Error::NotApplicable {
            formulation: INFO.name.into(),
            scene: info.name.into(),
            reason,
        })?;
        let stab = match options.choice("stab") {
            "baumgarte" => Stabilisation::Baumgarte {
                alpha: options.real("baumgarte_alpha"),
                beta: options.real("baumgarte_beta"),
            },
            "projection" => Stabilisation::Projection,
            _ => Stabilisation::None,
        };
        let (n, s, k) = (info.n(), info.s(), info.k());
        Ok(Chetaev {
            singular_tol: options.real("singular_tol"),
            options,
            stab,
            n,
            kkt: Kkt::new(n, s, k),
            kkt_dual: Kkt::new(n, s, k),
            y_dual: vec![Dual64::from_re(0.0); 2 * n],
            projector: Projector::new(&scene),
            monitor: Monitor::new(&scene),
            scene,
        })
    }

    pub fn scene(&self) -> &S {
        &self.scene
    }

    pub fn stabilisation(&self) -> Stabilisation {
        self.stab
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
        self.kkt.solve(&self.scene, self.stab, t, q, qd)?;
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
        let (q, qd) = y.split_at(n);
        let (dq, dqd) = dy.split_at_mut(n);
        dq.copy_from_slice(qd);
        self.accelerations(t, q, qd, dqd, &mut [])
    }

    /// `∂f/∂y` of `f(q, q̇) = (q̇, q̈)`: the KKT solve repeated with one dual
    /// direction per column of `y` (2n solves in `Dual64`).
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
            self.kkt_dual
                .solve(&self.scene, self.stab, Dual64::from_re(t), q, qd)?;
            for i in 0..n {
                jac[(n + i) * dim + j] = self.kkt_dual.sol[i].eps;
            }
        }
        Ok(true)
    }

    fn after_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        let n = self.n;
        let mut changed = false;
        if self.stab == Stabilisation::Projection {
            let (q, qd) = y.split_at_mut(n);
            let p = self
                .projector
                .project(&self.scene, t, q, qd, consistency::PROJECT_TOL)
                .map_err(SystemError::new)?;
            changed = p.iterations > 0;
        }
        let (q, qd) = y.split_at(n);
        self.monitor.record(&self.scene, t, q, qd);
        Ok(changed)
    }

    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        let (q, qd) = y.split_at(self.n);
        self.scene
            .constraint_regularity(t, q, qd)
            .map(|r| r - self.singular_tol)
    }

    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        let (q, qd) = y.split_at(self.n);
        let r = self
            .scene
            .constraint_regularity(t, q, qd)
            .unwrap_or(f64::NAN);
        format!(
            "the motion reached the singular set of the constraints of `{}`: {} (regularity measure {r:.3e} ≤ singular_tol = {:.1e})",
            self.scene.info().name,
            self.scene
                .info()
                .constraint_singular_set
                .unwrap_or("constraint singular"),
            self.singular_tol
        )
    }
}

impl<S: Scene> Model for Chetaev<S> {
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

    fn multiplier_names(&self) -> Vec<String> {
        multiplier_names(self.kkt.cs.s, self.kkt.cs.k)
    }

    fn make_consistent(
        &mut self,
        init: &mut Initial,
        project: bool,
    ) -> Result<Option<InitProjection>, Error> {
        check_or_project(&self.scene, init, project)
    }

    fn initial_state(&mut self, init: &Initial) -> Result<Vec<f64>, Error> {
        self.monitor = Monitor::new(&self.scene);
        self.monitor.record(&self.scene, init.t0, &init.q, &init.qd);
        Ok(init.q.iter().chain(&init.qd).copied().collect())
    }

    fn observe(&mut self, t: f64, y: &[f64], obs: &mut Observation) -> Result<(), SystemError> {
        let n = self.n;
        let (q, qd) = y.split_at(n);
        obs.q.copy_from_slice(q);
        obs.qd.copy_from_slice(qd);
        let mut qdd = vec![0.0; n];
        self.accelerations(t, q, qd, &mut qdd, &mut obs.multipliers)
    }

    fn diagnostics(&self) -> Diagnostics {
        self.monitor.diagnostics().clone()
    }
}
