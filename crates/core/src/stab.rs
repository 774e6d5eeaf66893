//! Constraint stabilisation, shared by the formulations with multipliers,
//! and the options that select it.

use nonholo_integrate::SystemError;

use crate::Error;
use crate::consistency::PROJECT_TOL;
use crate::guard::{SingularGuard, magnitude};
use crate::monitor::{Diagnostics, Monitor};
use crate::param::{Bound, ParamSpec, Params};
use crate::project::Projector;
use crate::scene::{MAX_SINGULAR, Scene};

/// `--option stab=none|baumgarte|projection`.
pub const STAB: ParamSpec = ParamSpec::choice(
    "stab",
    &["none", "baumgarte", "projection"],
    "constraint stabilisation: none; Baumgarte (ġ + 2α g = 0, f̈ + 2α ḟ + β² f = 0); \
     projection onto the constraints after every step",
);

/// Baumgarte damping gain `α`.
pub const BAUMGARTE_ALPHA: ParamSpec = ParamSpec::real(
    "baumgarte_alpha",
    "1/s",
    5.0,
    Bound::Inclusive(0.0),
    Bound::Unbounded,
    "Baumgarte damping gain α",
);

/// Baumgarte stiffness gain `β` (holonomic constraints).
pub const BAUMGARTE_BETA: ParamSpec = ParamSpec::real(
    "baumgarte_beta",
    "1/s",
    5.0,
    Bound::Inclusive(0.0),
    Bound::Unbounded,
    "Baumgarte stiffness gain β (holonomic constraints)",
);

/// Where a run stops near a singular set of the constraints.
pub const SINGULAR_TOL: ParamSpec = ParamSpec::real(
    "singular_tol",
    "",
    1e-8,
    Bound::Exclusive(0.0),
    Bound::Unbounded,
    "the run stops where the constraint's regularity measure (appell-hamel: horizontal speed) \
     falls to this value",
);

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

impl Stabilisation {
    /// From options that include [`STAB`], [`BAUMGARTE_ALPHA`],
    /// [`BAUMGARTE_BETA`]; [`Stabilisation::None`] for options without
    /// [`STAB`] (formulations that do not enforce the constraints).
    pub fn from_options(options: &Params) -> Result<Self, Error> {
        if options.get(STAB.name).is_none() {
            return Ok(Stabilisation::None);
        }
        Ok(match options.choice(STAB.name)? {
            "baumgarte" => Stabilisation::Baumgarte {
                alpha: options.real(BAUMGARTE_ALPHA.name)?,
                beta: options.real(BAUMGARTE_BETA.name)?,
            },
            "projection" => Stabilisation::Projection,
            _ => Stabilisation::None,
        })
    }

    /// Baumgarte gains `(α, β)`; zero unless Baumgarte is chosen.
    pub fn gains(self) -> (f64, f64) {
        match self {
            Stabilisation::Baumgarte { alpha, beta } => (alpha, beta),
            _ => (0.0, 0.0),
        }
    }
}

/// What a formulation on `(q, q̇)` does between steps: projection (if
/// chosen), diagnostics, and the guard on the constraints' singular set.
#[derive(Debug, Clone)]
pub struct StepHooks {
    pub stab: Stabilisation,
    /// Only with [`Stabilisation::Projection`].
    projector: Option<Projector>,
    monitor: Monitor,
    guard: SingularGuard,
    r: [f64; MAX_SINGULAR],
}

impl StepHooks {
    /// From options that include [`SINGULAR_TOL`] and, for formulations that
    /// enforce the constraints, the stabilisation options (see
    /// [`Stabilisation::from_options`]).
    pub fn new<S: Scene>(scene: &S, options: &Params) -> Result<Self, Error> {
        let stab = Stabilisation::from_options(options)?;
        Ok(StepHooks {
            stab,
            projector: (stab == Stabilisation::Projection).then(|| Projector::new(scene)),
            monitor: Monitor::new(scene),
            guard: SingularGuard::new(options.real(SINGULAR_TOL.name)?),
            r: [0.0; MAX_SINGULAR],
        })
    }

    /// Starts the diagnostics and the guard of a new run at the initial state.
    pub fn start<S: Scene>(&mut self, scene: &S, t: f64, q: &[f64], qd: &[f64]) {
        self.monitor = Monitor::new(scene);
        self.monitor.record(scene, t, q, qd);
        let p = scene.constraint_singularity(t, q, qd, &mut self.r);
        self.guard.start(&self.r, p);
    }

    /// After an accepted step: projects `(q, q̇)` if projection is chosen
    /// (returns whether anything moved), records diagnostics, moves the guard on.
    pub fn after_step<S: Scene>(
        &mut self,
        scene: &S,
        t: f64,
        q: &mut [f64],
        qd: &mut [f64],
    ) -> Result<bool, SystemError> {
        let mut changed = false;
        if let Some(projector) = self.projector.as_mut() {
            let p = projector
                .project(scene, t, q, qd, PROJECT_TOL)
                .map_err(SystemError::new)?;
            changed = p.iterations > 0;
        }
        self.monitor.record(scene, t, q, qd);
        let p = scene.constraint_singularity(t, q, qd, &mut self.r);
        self.guard.accept(&self.r, p);
        Ok(changed)
    }

    /// Replaces the last accepted step's end state in the diagnostics by the
    /// located stop `(t, q, q̇)` inside that step (see [`Monitor::rewind`]).
    pub fn rewind<S: Scene>(&mut self, scene: &S, t: f64, q: &[f64], qd: &[f64]) {
        self.monitor.rewind(scene, t, q, qd);
    }

    /// Refuses a stage state on the far side of the singular set (the
    /// direction of `r` reversed relative to the start of the step): the
    /// right-hand side is not defined across it, and evaluating it there would
    /// put a wrong polynomial under the crossing. Adaptive methods reject the
    /// step and approach the set from before; fixed steps stop with this reason.
    pub fn check_stage<S: Scene>(
        &mut self,
        scene: &S,
        t: f64,
        q: &[f64],
        qd: &[f64],
    ) -> Result<(), SystemError> {
        let p = scene.constraint_singularity(t, q, qd, &mut self.r);
        if self.guard.crossed(&self.r, p) {
            return Err(SystemError::singular(format!(
                "a stage crossed the singular set of the constraints of `{}`: {}",
                scene.info().name,
                scene
                    .info()
                    .constraint_singular_set
                    .unwrap_or("constraint singular")
            )));
        }
        Ok(())
    }

    /// Signed distance from the constraints' singular set (see [`crate::guard`]).
    pub fn guard<S: Scene>(&mut self, scene: &S, t: f64, q: &[f64], qd: &[f64]) -> Option<f64> {
        let p = scene.constraint_singularity(t, q, qd, &mut self.r);
        (p > 0).then(|| self.guard.value(&self.r, p))
    }

    /// Why the guard stopped the run.
    pub fn guard_reason<S: Scene>(&mut self, scene: &S, t: f64, q: &[f64], qd: &[f64]) -> String {
        let p = scene.constraint_singularity(t, q, qd, &mut self.r);
        let info = scene.info();
        format!(
            "the motion came within singular_tol = {:.1e} of the singular set of the \
             constraints of `{}`: {} (|r| = {:.3e})",
            self.guard.tol,
            info.name,
            info.constraint_singular_set
                .unwrap_or("constraint singular"),
            magnitude(&self.r, p),
        )
    }

    pub fn diagnostics(&self) -> &Diagnostics {
        self.monitor.diagnostics()
    }
}
