//! Formulation A as a model: its options, its two forms over one scene,
//! the initial data they start from, and the physical reading.
//!
//! The state is `y = (z, q_c)`, `z = (q_I, q̇_I, q̈_I, q⃛_I)` and `q_c` the
//! cyclic dependent coordinates (quadratures of their rates from the map).
//! Radau IIA integrates the
//! implicit form ([`crate::implicit`]: the equations (19) as a
//! differential-algebraic system), the explicit methods the explicit form
//! ([`crate::explicit`]: `ż = (z₁, z₂, z₃, q⁗(z))` with `q⁗` from the
//! derivative array). Both start from the same consistent point
//! ([`crate::setup`]); the rank of `W`, the hidden constraints and the free
//! initial data found there are reported.

use std::sync::Arc;

use nonholo_core::consistency::{InitProjection, check_or_project};
use nonholo_core::init::{ExtraName, lambda_names};
use nonholo_core::integrate::{ImplicitSystem, OdeSystem, RadauNewton, SystemError};
use nonholo_core::model::{Crossing, Description, FormulationInfo, Model, Observation};
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::scene::{Scene, SceneInfo};
use nonholo_core::{Diagnostics, Error, Initial};

use crate::crossing::Continuation;
use crate::elo::MAX_DOF;
use crate::explicit::Explicit;
use crate::implicit::Implicit;
use crate::setup::{InitReport, consistent_start, derivative_name};
use crate::shared::Shared;

/// Where the run stops near the embedding map's singular set.
pub const SINGULAR_TOL: ParamSpec = ParamSpec::real(
    "singular_tol",
    "",
    1e-3,
    Bound::Exclusive(0.0),
    Bound::Unbounded,
    "the run stops where the size |r| of the embedding map's singular vector (the scene names \
     it; the sleigh's is its velocity, |r| the speed in m/s) falls to this value; the equations \
     degenerate near it (the sleigh's like 1/speed²)",
);

/// Whether the map may put the dependent coordinates on another branch than given.
pub const BRANCH: ParamSpec = ParamSpec::choice(
    "branch",
    &["strict", "map"],
    "strict: refuse initial data whose dependent coordinates differ from the embedding map's \
     value (the sleigh moving backwards, where atan2(ẏ, ẋ) = φ + π); map: take the map's \
     value and report the difference (the branch effect of the spec)",
);

/// Stabilisation of the hidden constraints in the explicit form.
pub const STAB: ParamSpec = ParamSpec::choice(
    "stab",
    &["none", "projection"],
    "explicit integrators (RK4, DOPRI5, DOP853) only: let A's hidden constraints drift at the \
     level of the local errors (none), or after every accepted step move q⃛ back onto them with \
     q, q̇, q̈ fixed (projection; ill-posed where q⃛ is not determined by q, q̇, q̈ — the sleigh \
     turning through ω = 0 — where it moves the motion to a neighbouring one); Radau \
     integrates the implicit form and ignores it",
);

/// How the explicit form goes on past the embedding map's singular set.
pub const CONTINUATION: ParamSpec = ParamSpec::choice(
    "continuation",
    &["analytic", "map", "none"],
    "explicit integrators (RK4, DOPRI5, DOP853) only: past the embedding map's singular set (the \
     sleigh's reversals) the solution is continued along a half circle in complex time, then on \
     the real axis again: analytic follows the map's analytic continuation (the heading goes on \
     smoothly, |v| becomes the signed speed); map resumes on its principal branch (the literal \
     atan2, whose heading turns by π at a reversal), q⃛ re-completed on that branch's hidden \
     constraints; none stops there. Radau integrates the implicit form, which stops there",
);

/// Options of formulation A.
pub const OPTIONS: &[ParamSpec] = &[SINGULAR_TOL, BRANCH, STAB, CONTINUATION];

pub const INFO: FormulationInfo = FormulationInfo {
    name: "embedding",
    letter: "A",
    title: "Hamilton-principle embedding (the seed paper)",
    description: "the constraint substituted into L via q_D = φ(q_I, q̇_I, t); Euler–Lagrange–\
                  Ostrogradsky equations (19) of Θ, fourth order in q_I, integrated as an implicit \
                  (differential-algebraic) system in z = (q_I, q̇_I, q̈_I, q⃛_I) by Radau, or by \
                  explicit methods as the ODE z' = (z₁, z₂, z₃, q⁗(z)) with q⁗ from the derivative \
                  array [E; Ė; Ë] = 0",
    options: OPTIONS,
    applicable,
};

fn applicable(scene: &SceneInfo) -> Result<(), String> {
    let Some(e) = &scene.embedding else {
        return Err(if scene.s() == 0 {
            "the scene has no nonholonomic constraints to embed".into()
        } else {
            "the scene provides no embedding map q_D = φ(q_I, q̇_I, t) (eq. 14): for general \
             constraints (eq. 27–30) the dependent coordinates follow from integrating eq. (28) \
             along the whole path, which an initial-value problem cannot do; the paper's general \
             case is solved as a boundary-value problem by `nonholo bvp --formulation embedding \
             --dependent …` (docs/variational.md)"
                .into()
        });
    };
    if scene.k() > 0 {
        return Err("holonomic constraints are not part of the paper's embedding (§3)".into());
    }
    if scene.n() > MAX_DOF {
        return Err(format!("at most {MAX_DOF} coordinates are supported"));
    }
    if e.dependent.len() != scene.s() {
        return Err("the embedding map must solve every nonholonomic constraint".into());
    }
    if e.cyclic.iter().any(|c| !e.dependent.contains(c)) {
        return Err("the map's cyclic coordinates must be dependent ones".into());
    }
    Ok(())
}

/// Which form was handed to an integrator last.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Form {
    Implicit,
    Explicit,
}

/// Formulation A bound to a scene: both forms, started together.
pub struct Embedding<S: Scene> {
    scene: Arc<S>,
    options: Params,
    implicit: Implicit<S>,
    explicit: Explicit<S>,
    /// The form whose diagnostics and readings count.
    active: Form,
    continuation: Continuation,
    /// `ż(0)` of the implicit form.
    yp0: Vec<f64>,
    report: Option<InitReport>,
}

impl<S: Scene> Embedding<S> {
    pub fn new(scene: S, options: Params) -> Result<Self, Error> {
        let info = scene.info();
        applicable(info).map_err(|reason| Error::NotApplicable {
            formulation: INFO.name.into(),
            scene: info.name.into(),
            reason,
        })?;
        let singular_tol = options.real(SINGULAR_TOL.name)?;
        let project_hidden = options.choice(STAB.name)? == "projection";
        let continuation = Continuation::from_name(options.choice(CONTINUATION.name)?);
        options.choice(BRANCH.name)?;
        let scene = Arc::new(scene);
        Ok(Embedding {
            implicit: Implicit::new(Shared::new(scene.clone(), singular_tol)),
            explicit: Explicit::new(
                Shared::new(scene.clone(), singular_tol),
                project_hidden,
                continuation,
            ),
            continuation,
            active: Form::Implicit,
            yp0: Vec::new(),
            report: None,
            options,
            scene,
        })
    }

    /// What the initial-data set-up found (after [`Model::initial_state`]).
    pub fn report(&self) -> Option<&InitReport> {
        self.report.as_ref()
    }

    /// The implicit form (Radau IIA).
    pub fn implicit_form(&mut self) -> &mut Implicit<S> {
        &mut self.implicit
    }

    /// The explicit form (RK4, DOPRI5, DOP853).
    pub fn explicit_form(&mut self) -> &mut Explicit<S> {
        &mut self.explicit
    }

    /// The explicit form alone, started where the model was.
    pub fn into_explicit(self) -> Explicit<S> {
        self.explicit
    }

    fn shared(&mut self) -> &mut Shared<S> {
        match self.active {
            Form::Implicit => &mut self.implicit.shared,
            Form::Explicit => &mut self.explicit.shared,
        }
    }
}

impl<S: Scene> Model for Embedding<S> {
    /// The explicit form, for explicit methods (`simulate` integrates with
    /// Radau the implicit form whenever a model has one).
    fn ode(&mut self) -> Option<&mut dyn OdeSystem> {
        self.active = Form::Explicit;
        Some(&mut self.explicit)
    }

    fn implicit(&mut self) -> Option<&mut dyn ImplicitSystem> {
        self.active = Form::Implicit;
        Some(&mut self.implicit)
    }

    /// The explicit form crosses the singular set unless `continuation = none`.
    fn crossing(&mut self) -> Option<&mut dyn Crossing> {
        match self.continuation {
            Continuation::None => None,
            _ => Some(&mut self.explicit),
        }
    }

    /// (19) is fully implicit and not in Hessenberg form: Radau's simplified
    /// Newton iteration stalls on it (contraction factor ≈ 1 after a few
    /// steps, measured), while the collocation equations are solvable.
    fn radau_newton(&self) -> RadauNewton {
        RadauNewton::Full
    }

    fn initial_slope(&mut self) -> Result<Vec<f64>, Error> {
        if self.yp0.is_empty() {
            return Err(Error::numerical(
                "the initial slope",
                "initial_state was not called",
            ));
        }
        Ok(self.yp0.clone())
    }

    fn describe(&self) -> Description<'_> {
        Description {
            scene: self.scene.info(),
            formulation: &INFO,
            params: self.scene.params(),
            options: &self.options,
        }
    }

    /// A has no multipliers.
    fn multiplier_names(&self) -> Vec<String> {
        Vec::new()
    }

    /// `lambda` (matched with C by the lab) and the second and third
    /// derivatives of the independent coordinates (`x_ddot`, `x_dddot`, …).
    fn extra_init_names(&self) -> Vec<ExtraName> {
        let info = self.scene.info();
        let e = info.embedding.expect("checked by applicable");
        let mut names = lambda_names(
            e.dependent.len(),
            "multiplier λ(0) of the vakonomic motion A is matched with (spec, section A)",
        );
        for order in [2, 3] {
            for &i in e.independent {
                names.push(ExtraName::new(
                    derivative_name(info.coordinates[i].name, order),
                    "",
                    "initial derivative of an independent coordinate",
                ));
            }
        }
        names
    }

    fn make_consistent(
        &mut self,
        init: &mut Initial,
        project: bool,
    ) -> Result<Option<InitProjection>, Error> {
        check_or_project(&*self.scene, init, project)
    }

    /// The consistent point of [`crate::setup`], `E = 0` polished to
    /// round-off; both forms start there.
    fn initial_state(&mut self, init: &Initial) -> Result<Vec<f64>, Error> {
        let branch_map = self.options.choice(BRANCH.name)? == "map";
        let tol = self.implicit.shared.guard.tol;
        let (mut d, report) = consistent_start(&*self.scene, init, branch_map, tol)?;
        let m = self.implicit.shared.m;
        let t0 = init.t0;
        self.implicit.polish_fourth(t0, &mut d);
        self.explicit.reset(t0, &d).map_err(|msg| {
            Error::numerical(
                "solving the derivative array of (19) at the initial state",
                msg,
            )
        })?;
        // y = (z, q_c): the cyclic coordinates start where given.
        let mut y0 = d[..4 * m].to_vec();
        y0.extend(self.implicit.shared.e.cyclic.iter().map(|&i| init.q[i]));
        self.implicit.shared.start(t0, &y0, &init.q);
        self.explicit.shared.start(t0, &y0, &init.q);
        // The analytic continuation follows the map's branch from the start.
        if self.continuation == Continuation::Analytic {
            let near = self.explicit.shared.follow_current();
            self.explicit.follow_from(&near);
        }
        self.yp0 = d[m..5 * m].to_vec();
        let rates = self.implicit.shared.cyclic_rates(t0, &y0).to_vec();
        self.yp0.extend(rates);
        self.report = Some(report);
        Ok(y0)
    }

    fn observe(&mut self, t: f64, y: &[f64], obs: &mut Observation) -> Result<(), SystemError> {
        let shared = self.shared();
        shared.read(t, y);
        obs.q.copy_from_slice(&shared.q);
        obs.qd.copy_from_slice(&shared.qd);
        Ok(())
    }

    fn init_report(&self) -> Vec<(&'static str, f64)> {
        let Some(r) = &self.report else {
            return Vec::new();
        };
        let m = r.structure.m;
        let mut v = vec![
            ("rank_w", r.structure.rank_w as f64),
            ("hidden_constraints", r.structure.hidden_constraints as f64),
            ("free_initial_data", r.structure.free_initial_data as f64),
            ("state_dimension", (4 * m + self.implicit.shared.c) as f64),
            (
                "third_derivatives_given",
                if r.third_given { 1.0 } else { 0.0 },
            ),
            ("hidden_residual_before", r.completion.residual.0),
            ("hidden_residual_after", r.completion.residual.1),
            ("completion_iterations", r.completion.iterations as f64),
            ("third_derivative_change", r.completion.third_change),
        ];
        // How well (q, q̇, q̈) determine q⃛: the smallest relative singular
        // value of the hidden constraints' Jacobian in q⃛ (0 where q⃛ is free,
        // as for the sleigh at ω = 0; see `analysis::third_determination`).
        if let Some(&s) = r.completion.third_singular_values.last() {
            v.push(("third_determination", s));
        }
        // One name per dependent coordinate, in the map's order (the first
        // keeps the name it had when maps had one).
        const SHIFT: [&str; MAX_DOF] = [
            "branch_shift",
            "branch_shift_2",
            "branch_shift_3",
            "branch_shift_4",
            "branch_shift_5",
            "branch_shift_6",
            "branch_shift_7",
            "branch_shift_8",
            "branch_shift_9",
            "branch_shift_10",
            "branch_shift_11",
            "branch_shift_12",
        ];
        for (name, shift) in SHIFT.iter().zip(&r.branch_shift) {
            v.push((name, *shift));
        }
        v
    }

    fn diagnostics(&self) -> Diagnostics {
        match self.active {
            Form::Implicit => self.implicit.shared.diagnostics().clone(),
            Form::Explicit => self.explicit.shared.diagnostics().clone(),
        }
    }
}
