//! A formulation's equations bound to a scene: everything a formulation
//! needs to be integrated and read, written once.
//!
//! A formulation supplies its [`Equations`]: the state layout, the
//! right-hand side split into its two physical halves (`q̇`, then the rest:
//! `q̈` and whatever the state carries besides), generic over the scalar
//! type, its initial state and its multipliers. [`Binding`] turns that into
//! a [`Model`] and an [`OdeSystem`]:
//!
//! * the right-hand side over `f64`, with the stage check of the
//!   constraints' singular set between the two halves;
//! * the Jacobian `∂f/∂y`, one [`Dual64`] pass of the same equations per
//!   column of `y`;
//! * Taylor coefficients of the motion (`ẏ`, `ÿ`, `y⃛`) by Taylor-mode
//!   passes ([`Binding::taylor`]);
//! * the step hooks (projection, diagnostics, guard) on the physical state
//!   `(q, q̇)`, read from `y` or, where the state does not hold `q̇`,
//!   computed and kept for the hooks that ask at the same state;
//! * the [`Model`] accessors, initial-data checks and observations.
//!
//! A formulation file is then its equations and what is particular to it.

use nonholo_integrate::{OdeSystem, RadauNewton, SystemError};
use num_dual::{Dual2_64, Dual64};

use crate::Error;
use crate::consistency::{InitProjection, check_or_project_with, check_positions};
use crate::init::{ExtraName, Initial};
use crate::linalg::Singular;
use crate::model::{
    Description, FormulationInfo, Model, Observation, StateChart, Switch, SwitchRecord,
    multiplier_names,
};
use crate::monitor::Diagnostics;
use crate::param::Params;
use crate::scene::{Scalar, Scene, SceneInfo};
use crate::stab::{Stabilisation, StepHooks};

/// Why the equations could not be evaluated at a state.
#[derive(Debug, Clone, PartialEq)]
pub enum EvalError {
    /// The KKT system is singular there.
    Kkt(Singular),
    /// Anything else, in the formulation's words.
    System(SystemError),
}

impl From<Singular> for EvalError {
    fn from(e: Singular) -> Self {
        EvalError::Kkt(e)
    }
}

impl From<SystemError> for EvalError {
    fn from(e: SystemError) -> Self {
        EvalError::System(e)
    }
}

impl EvalError {
    /// The error as the integrator reports it, naming the formulation.
    pub fn into_system(self, info: &FormulationInfo) -> SystemError {
        match self {
            EvalError::Kkt(e) if e.pivot.is_nan() => SystemError::new(format!(
                "the KKT system of formulation {} is not finite here (a NaN entry, or a solution \
                 that is not finite): a derivative of the Lagrangian or of the constraints is not \
                 defined at this state, or a value overflowed",
                info.letter
            )),
            EvalError::Kkt(e) => SystemError::new(format!(
                "KKT system of formulation {} singular ({e}): constraints dependent, or the \
                 kinetic energy degenerate on the admissible velocities",
                info.letter
            )),
            EvalError::System(e) => e,
        }
    }
}

/// A formulation's equations `y' = f(t, y)`, with `y` starting with the
/// coordinates `q` (length `n`) and `f` starting with `q̇`.
///
/// The right-hand side comes in two halves, evaluated in this order at the
/// same `(t, y)` and with the same workspace: [`Equations::velocities`]
/// (`q̇`, the first `n` components of `f`) and
/// [`Equations::accelerations`] (the rest). Both are generic over the
/// scalar type, so the same code gives the value (`f64`), Jacobian columns
/// and time derivatives (dual numbers).
pub trait Equations: Sized + Send + 'static {
    /// Workspace of one evaluation over the scalar `T`.
    type Work<T: Scalar>: Send;

    /// Name, letter, options and applicability of the formulation.
    const INFO: &'static FormulationInfo;

    /// The equations for `scene` with resolved `options`; a choice that
    /// resolves here (e.g. `form = auto`) is written back into `options`.
    fn new<S: Scene>(scene: &S, options: &mut Params) -> Result<Self, Error>;

    /// A workspace over `T` for `scene`.
    fn work<S: Scene, T: Scalar>(&self, scene: &S) -> Self::Work<T>;

    /// The compiled program of `work`, if the equations compiled the scene
    /// (the check of initial data then reads the constraints from it,
    /// [`crate::consistency::check_or_project_with`]).
    fn program<'w>(&self, _work: &'w Self::Work<f64>) -> Option<&'w crate::compiled::Compiled> {
        None
    }

    /// Length of the state `y`.
    fn dim(&self, info: &SceneInfo) -> usize;

    /// Whether `y` begins with `(q, q̇)`: then the hooks act on `y` in place
    /// (projection included), and [`Equations::velocities`] must copy
    /// `y[n..2n]`.
    fn cartesian(&self) -> bool {
        true
    }

    /// `q̇` at `(t, y)` into `qd` (length `n`).
    fn velocities<S: Scene, T: Scalar>(
        &self,
        _scene: &S,
        _work: &mut Self::Work<T>,
        _t: T,
        y: &[T],
        qd: &mut [T],
    ) -> Result<(), EvalError> {
        let n = qd.len();
        crate::linalg::copy_small(qd, &y[n..2 * n]);
        Ok(())
    }

    /// The rest of `f(t, y)` (components `n..`) into `rest`, after
    /// [`Equations::velocities`] at the same `(t, y)` with the same `work`.
    #[allow(clippy::too_many_arguments)]
    fn accelerations<S: Scene, T: Scalar>(
        &self,
        scene: &S,
        stab: Stabilisation,
        work: &mut Self::Work<T>,
        t: T,
        y: &[T],
        rest: &mut [T],
    ) -> Result<(), EvalError>;

    /// The multipliers at `(t, y)` (physical velocities `qd`) into `out`,
    /// named by [`Model::multiplier_names`] (never called with `out` empty).
    #[allow(clippy::too_many_arguments)]
    fn multipliers<S: Scene>(
        &self,
        scene: &S,
        stab: Stabilisation,
        work: &mut Self::Work<f64>,
        t: f64,
        y: &[f64],
        qd: &[f64],
        out: &mut [f64],
    ) -> Result<(), EvalError>;

    /// The state for consistent initial data; `(q0, q̇0)` by default.
    fn initial_state<S: Scene>(
        &mut self,
        _scene: &S,
        _work: &mut Self::Work<f64>,
        init: &Initial,
    ) -> Result<Vec<f64>, Error> {
        Ok(init.q.iter().chain(&init.qd).copied().collect())
    }

    /// Names `--init` accepts beyond the scene's (the multipliers `λ(0)`).
    fn extra_init_names(&self, _info: &SceneInfo) -> Vec<ExtraName> {
        Vec::new()
    }

    /// Whether the equations have modes that change at stops of their
    /// guard ([`Equations::event`], [`Equations::switch`]): the friction
    /// realisation's stick and slip.
    fn has_modes(&self) -> bool {
        false
    }

    /// Whether initial data must satisfy the nonholonomic constraints
    /// (a friction realisation may start slipping).
    fn needs_consistent_velocities(&self) -> bool {
        true
    }

    /// The equations' own guard at `(t, y)`, watched beside the
    /// constraints' singular set: positive while the current mode holds
    /// (only called if [`Equations::has_modes`]).
    fn event<S: Scene>(
        &self,
        _scene: &S,
        _work: &mut Self::Work<f64>,
        _t: f64,
        _y: &[f64],
    ) -> Option<f64> {
        None
    }

    /// Why the equations' guard stopped the run at `(t, y)`.
    fn event_reason<S: Scene>(
        &self,
        _scene: &S,
        _work: &mut Self::Work<f64>,
        _t: f64,
        _y: &[f64],
    ) -> String {
        "the mode's guard reached zero".to_string()
    }

    /// Called after every accepted step, before the guard (see
    /// [`nonholo_integrate::OdeSystem::after_step`]), with the new state.
    fn step_accepted<S: Scene>(
        &mut self,
        _scene: &S,
        _work: &mut Self::Work<f64>,
        _t: f64,
        _y: &[f64],
    ) -> Result<(), EvalError> {
        Ok(())
    }

    /// Changes the mode at a stop `(t, y)` of the guard, correcting `y` in
    /// place if it must (see [`crate::model::Switch`]).
    fn switch<S: Scene>(
        &mut self,
        _scene: &S,
        _work: &mut Self::Work<f64>,
        _t: f64,
        _y: &mut [f64],
    ) -> Result<Option<SwitchRecord>, SystemError> {
        Ok(None)
    }

    /// The Newton iteration Radau IIA should use (see [`Model::radau_newton`]).
    fn radau_newton(&self) -> RadauNewton {
        RadauNewton::Simplified
    }

    /// Numbers found while setting up the initial state, for the record.
    fn init_report(&self) -> Vec<(&'static str, f64)> {
        Vec::new()
    }

    /// Whether every motion keeps the scene's constraints `f = ḟ = g = 0`
    /// (B, C, Gauss; not a realisation, which only approaches them): a
    /// linearisation then reduces to the constraint manifold.
    fn keeps_constraints(&self) -> bool {
        false
    }

    /// Names of the components of `y` after `(q, q̇)` (`lambda`, ...), for
    /// linearisations; `y[i]` by default.
    fn extra_state_names(&self, info: &SceneInfo) -> Vec<String> {
        (2 * info.n()..self.dim(info))
            .map(|i| format!("y[{i}]"))
            .collect()
    }
}

/// Second-order time jets through the equations, for [`Binding::taylor`].
struct Jets<W> {
    work: W,
    y: Vec<Dual2_64>,
    dy: Vec<Dual2_64>,
}

/// `q̇` of the last state the hooks asked about, for equations whose state
/// does not hold `q̇` (after an accepted step the hooks, the guard and the
/// observation ask at the same state, and each `q̇` costs an evaluation).
struct Physical {
    at: Option<f64>,
    y: Vec<f64>,
    qd: Vec<f64>,
}

/// `f(t, y)` of `eq` over any scalar, into `dy`, without the stage check.
fn eval<S: Scene, E: Equations, T: Scalar>(
    eq: &E,
    scene: &S,
    stab: Stabilisation,
    work: &mut E::Work<T>,
    t: T,
    y: &[T],
    dy: &mut [T],
) -> Result<(), SystemError> {
    let (qd, rest) = dy.split_at_mut(scene.info().n());
    eq.velocities(scene, work, t, y, qd)
        .and_then(|()| eq.accelerations(scene, stab, work, t, y, rest))
        .map_err(|e| e.into_system(E::INFO))
}

/// Equations `E` bound to scene `S`: a [`Model`] and an [`OdeSystem`].
pub struct Binding<S: Scene, E: Equations> {
    scene: S,
    options: Params,
    eq: E,
    n: usize,
    dim: usize,
    hooks: StepHooks,
    work: E::Work<f64>,
    /// The equations carrying one directional derivative: Jacobian
    /// columns, first time derivatives.
    work_dual: E::Work<Dual64>,
    y_dual: Vec<Dual64>,
    dy_dual: Vec<Dual64>,
    /// Built on the first [`Binding::taylor`].
    jets: Option<Box<Jets<E::Work<Dual2_64>>>>,
    physical: Physical,
}

impl<S: Scene, E: Equations> Binding<S, E> {
    /// Binds the equations of `E` to `scene` with resolved `options`.
    pub fn new(scene: S, options: Params) -> Result<Self, Error> {
        let info = scene.info();
        let not_applicable = |reason| Error::NotApplicable {
            formulation: E::INFO.name.into(),
            scene: info.name.into(),
            reason,
        };
        (E::INFO.applicable)(info).map_err(not_applicable)?;
        let mut options = options;
        let eq = E::new(&scene, &mut options)?;
        let hooks = StepHooks::new(&scene, &options)?;
        if !eq.cartesian() && hooks.stab == Stabilisation::Projection {
            return Err(not_applicable(
                "projection needs a state holding (q, q̇)".to_string(),
            ));
        }
        let (n, dim) = (info.n(), eq.dim(info));
        Ok(Binding {
            hooks,
            options,
            n,
            dim,
            work: eq.work(&scene),
            work_dual: eq.work(&scene),
            y_dual: vec![Dual64::from_re(0.0); dim],
            dy_dual: vec![Dual64::from_re(0.0); dim],
            jets: None,
            physical: Physical {
                at: None,
                y: vec![0.0; dim],
                qd: vec![0.0; n],
            },
            eq,
            scene,
        })
    }

    /// The equations.
    pub fn equations(&self) -> &E {
        &self.eq
    }

    /// The scene.
    pub fn scene(&self) -> &S {
        &self.scene
    }

    /// `q̇` of state `y` at `t` into `self.physical.qd`, unless it is there
    /// already (for equations whose state does not hold `q̇`).
    fn physical_velocities(&mut self, t: f64, y: &[f64]) -> Result<(), SystemError> {
        let p = &mut self.physical;
        if p.at == Some(t) && p.y == y {
            return Ok(());
        }
        p.at = None;
        self.eq
            .velocities(&self.scene, &mut self.work, t, y, &mut p.qd)
            .map_err(|e| e.into_system(E::INFO))?;
        p.y.copy_from_slice(y);
        p.at = Some(t);
        Ok(())
    }

    /// Taylor coefficients of the motion through `(t, y)`: `ẏ = f(t, y)`,
    /// `ÿ` and `y⃛`, by Taylor-mode differentiation of the right-hand side:
    /// one dual pass along the first-order jet `(y + ẏτ, t + τ)` gives `ÿ`,
    /// one second-order pass along `y + ẏτ + ÿτ²/2` gives `y⃛`. So
    /// `q̈ = ẏ[n..2n]`, `q⃛ = ÿ[n..2n]`, `q⁗ = y⃛[n..2n]`.
    pub fn taylor(
        &mut self,
        t: f64,
        y: &[f64],
        yd: &mut [f64],
        ydd: &mut [f64],
        yddd: &mut [f64],
    ) -> Result<(), SystemError> {
        let dim = self.dim;
        self.rhs(t, y, yd)?;
        for i in 0..dim {
            self.y_dual[i] = Dual64::new(y[i], yd[i]);
        }
        let stab = self.hooks.stab;
        eval(
            &self.eq,
            &self.scene,
            stab,
            &mut self.work_dual,
            Dual64::new(t, 1.0),
            &self.y_dual,
            &mut self.dy_dual,
        )?;
        for i in 0..dim {
            ydd[i] = self.dy_dual[i].eps;
        }
        let jets = self.jets.get_or_insert_with(|| {
            Box::new(Jets {
                work: self.eq.work(&self.scene),
                y: vec![Dual2_64::from_re(0.0); dim],
                dy: vec![Dual2_64::from_re(0.0); dim],
            })
        });
        for i in 0..dim {
            jets.y[i] = Dual2_64::new(y[i], yd[i], ydd[i]);
        }
        eval(
            &self.eq,
            &self.scene,
            stab,
            &mut jets.work,
            Dual2_64::new(t, 1.0, 0.0),
            &jets.y,
            &mut jets.dy,
        )?;
        for i in 0..dim {
            yddd[i] = jets.dy[i].v2;
        }
        Ok(())
    }
}

impl<S: Scene, E: Equations> OdeSystem for Binding<S, E> {
    fn dim(&self) -> usize {
        self.dim
    }

    /// `q̇`, the stage check of the constraints' singular set on `(q, q̇)`,
    /// then the rest of `f`.
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let n = self.n;
        let (qd, rest) = dy.split_at_mut(n);
        self.eq
            .velocities(&self.scene, &mut self.work, t, y, qd)
            .map_err(|e| e.into_system(E::INFO))?;
        self.hooks.check_stage(&self.scene, t, &y[..n], qd)?;
        self.eq
            .accelerations(&self.scene, self.hooks.stab, &mut self.work, t, y, rest)
            .map_err(|e| e.into_system(E::INFO))
    }

    /// `∂f/∂y`: the equations over [`Dual64`], one pass per column of `y`
    /// seeded with `ẏ = e_j`.
    fn jacobian(&mut self, t: f64, y: &[f64], jac: &mut [f64]) -> Result<bool, SystemError> {
        let dim = self.dim;
        for j in 0..dim {
            for (d, &v) in self.y_dual.iter_mut().zip(y) {
                *d = Dual64::from_re(v);
            }
            self.y_dual[j].eps = 1.0;
            eval(
                &self.eq,
                &self.scene,
                self.hooks.stab,
                &mut self.work_dual,
                Dual64::from_re(t),
                &self.y_dual,
                &mut self.dy_dual,
            )?;
            for i in 0..dim {
                jac[i * dim + j] = self.dy_dual[i].eps;
            }
        }
        Ok(true)
    }

    fn after_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        let n = self.n;
        if self.eq.has_modes() {
            self.eq
                .step_accepted(&self.scene, &mut self.work, t, y)
                .map_err(|e| e.into_system(E::INFO))?;
        }
        if self.eq.cartesian() {
            let (q, rest) = y.split_at_mut(n);
            return self.hooks.after_step(&self.scene, t, q, &mut rest[..n]);
        }
        self.physical_velocities(t, y)?;
        let changed = self
            .hooks
            .after_step(&self.scene, t, &mut y[..n], &mut self.physical.qd)?;
        debug_assert!(!changed, "no projection without q̇ in the state");
        Ok(false)
    }

    /// The constraints' singular set, and the equations' own guard if they
    /// have modes: the smaller of the two (NaN if either is).
    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        let hooks = self.hooks_guard(t, y);
        if !self.eq.has_modes() {
            return hooks;
        }
        let own = self.eq.event(&self.scene, &mut self.work, t, y);
        match (hooks, own) {
            (Some(a), Some(b)) if a.is_nan() || b.is_nan() => Some(f64::NAN),
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        if self.eq.has_modes() {
            let own = self.eq.event(&self.scene, &mut self.work, t, y);
            if own.is_some_and(|v| v.is_nan() || v <= 0.0) {
                return self.eq.event_reason(&self.scene, &mut self.work, t, y);
            }
        }
        let n = self.n;
        if self.eq.cartesian() {
            return self
                .hooks
                .guard_reason(&self.scene, t, &y[..n], &y[n..2 * n]);
        }
        match self.physical_velocities(t, y) {
            Ok(()) => self
                .hooks
                .guard_reason(&self.scene, t, &y[..n], &self.physical.qd),
            Err(e) => e.message,
        }
    }
}

impl<S: Scene, E: Equations> Binding<S, E> {
    /// The guard of the constraints' singular set.
    fn hooks_guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        let n = self.n;
        if self.eq.cartesian() {
            return self.hooks.guard(&self.scene, t, &y[..n], &y[n..2 * n]);
        }
        self.physical_velocities(t, y).ok()?;
        self.hooks.guard(&self.scene, t, &y[..n], &self.physical.qd)
    }
}

impl<S: Scene, E: Equations> Switch for Binding<S, E> {
    /// The equations' switch; the diagnostics then count the located stop
    /// instead of the end of the step that passed it.
    fn switch(&mut self, t: f64, y: &mut [f64]) -> Result<Option<SwitchRecord>, SystemError> {
        let record = self.eq.switch(&self.scene, &mut self.work, t, y)?;
        let y = &*y;
        if record.is_some() {
            let n = self.n;
            if self.eq.cartesian() {
                self.hooks.rewind(&self.scene, t, &y[..n], &y[n..2 * n]);
            } else {
                self.physical_velocities(t, y)?;
                self.hooks
                    .rewind(&self.scene, t, &y[..n], &self.physical.qd);
            }
        }
        Ok(record)
    }
}

impl<S: Scene, E: Equations> Model for Binding<S, E> {
    fn describe(&self) -> Description<'_> {
        Description {
            scene: self.scene.info(),
            formulation: E::INFO,
            params: self.scene.params(),
            options: &self.options,
        }
    }

    fn ode(&mut self) -> Option<&mut dyn OdeSystem> {
        Some(self)
    }

    fn radau_newton(&self) -> RadauNewton {
        self.eq.radau_newton()
    }

    fn switch(&mut self) -> Option<&mut dyn Switch> {
        if self.eq.has_modes() {
            Some(self)
        } else {
            None
        }
    }

    fn extra_init_names(&self) -> Vec<ExtraName> {
        self.eq.extra_init_names(self.scene.info())
    }

    fn make_consistent(
        &mut self,
        init: &mut Initial,
        project: bool,
    ) -> Result<Option<InitProjection>, Error> {
        if !project && !self.eq.needs_consistent_velocities() {
            return check_positions(&self.scene, init);
        }
        let program = self.eq.program(&self.work);
        check_or_project_with(&self.scene, init, project, program)
    }

    /// The equations' initial state; the hooks start at `(q0, q̇)` with `q̇`
    /// as the state holds it (or as given, if it holds other velocities).
    fn initial_state(&mut self, init: &Initial) -> Result<Vec<f64>, Error> {
        let n = self.n;
        let y = self.eq.initial_state(&self.scene, &mut self.work, init)?;
        self.physical.at = None;
        let qd = if self.eq.cartesian() {
            &y[n..2 * n]
        } else {
            &init.qd[..]
        };
        self.hooks.start(&self.scene, init.t0, &y[..n], qd);
        Ok(y)
    }

    fn observe(&mut self, t: f64, y: &[f64], obs: &mut Observation) -> Result<(), SystemError> {
        let n = self.n;
        obs.q.copy_from_slice(&y[..n]);
        if self.eq.cartesian() {
            obs.qd.copy_from_slice(&y[n..2 * n]);
        } else {
            self.physical_velocities(t, y)?;
            obs.qd.copy_from_slice(&self.physical.qd);
        }
        if obs.multipliers.is_empty() {
            return Ok(());
        }
        self.eq
            .multipliers(
                &self.scene,
                self.hooks.stab,
                &mut self.work,
                t,
                y,
                &obs.qd,
                &mut obs.multipliers,
            )
            .map_err(|e| e.into_system(E::INFO))
    }

    fn init_report(&self) -> Vec<(&'static str, f64)> {
        self.eq.init_report()
    }

    fn diagnostics(&self) -> Diagnostics {
        self.hooks.diagnostics().clone()
    }

    fn has_state_chart(&self) -> bool {
        self.eq.cartesian()
    }

    fn no_state_chart(&self) -> Error {
        Error::NotApplicable {
            formulation: self.formulation().name.into(),
            scene: self.scene_info().name.into(),
            reason: "linearisation needs a state that begins with (q, q̇), and this form's \
                     state is the adapted one, (q, c, w): use the Cartesian form (option \
                     form = cartesian, `--option form=cartesian`)"
                .into(),
        }
    }

    fn state_chart(&mut self, t: f64, y: &[f64]) -> Result<StateChart, Error> {
        let info = self.scene.info();
        if !self.eq.cartesian() {
            return Err(self.no_state_chart());
        }
        let (n, k, s) = (self.n, info.k(), info.s());
        let mut names: Vec<String> = info.coordinates.iter().map(|c| c.name.into()).collect();
        names.extend(info.coordinates.iter().map(|c| format!("{}_dot", c.name)));
        names.extend(self.eq.extra_state_names(info));
        let (invariants, invariant_names, position_rows) = if self.eq.keeps_constraints() {
            let d = crate::constraints::invariant_jacobian(&self.scene, t, &y[..n], &y[n..2 * n]);
            let mut full = nalgebra::DMatrix::zeros(d.nrows(), self.dim);
            full.view_mut((0, 0), (d.nrows(), 2 * n)).copy_from(&d);
            let holo = multiplier_names(0, k);
            let mut rows: Vec<String> = holo.iter().map(|v| v.replacen("nu", "f", 1)).collect();
            rows.extend(
                holo.iter()
                    .map(|v| format!("{}_dot", v.replacen("nu", "f", 1))),
            );
            rows.extend(
                multiplier_names(s, 0)
                    .iter()
                    .map(|v| v.replacen("lambda", "g", 1)),
            );
            (full, rows, k)
        } else {
            (nalgebra::DMatrix::zeros(0, self.dim), Vec::new(), 0)
        };
        Ok(StateChart {
            n,
            names,
            invariants,
            invariant_names,
            position_rows,
        })
    }
}
