//! A formulation applied to a scene: an ODE system with a physical reading.
//!
//! Every formulation maps its state back to the same physical columns
//! `(t, q, q̇)` plus its multipliers, so code that compares runs never
//! special-cases a formulation.

use nonholo_integrate::{
    ImplicitSystem, Method, OdeSystem, Options, RadauNewton, Stats, SystemError,
};

use crate::Error;
use crate::consistency::InitProjection;
use crate::init::ExtraName;
use crate::init::Initial;
use crate::monitor::Diagnostics;
use crate::param::{ParamSpec, Params};
use crate::scene::SceneInfo;

/// Static description of a formulation.
#[derive(Debug, Clone, Copy)]
pub struct FormulationInfo {
    /// Name used on the command line (`chetaev`).
    pub name: &'static str,
    /// Letter in the spec (`B`).
    pub letter: &'static str,
    pub title: &'static str,
    pub description: &'static str,
    /// Options accepted through `--option name=value`.
    pub options: &'static [ParamSpec],
    /// Whether it applies to a scene, and if not, why.
    pub applicable: fn(&SceneInfo) -> Result<(), String>,
}

/// The physical reading of a state.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Observation {
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    /// Multipliers, named by [`Model::multiplier_names`].
    pub multipliers: Vec<f64>,
}

impl Observation {
    pub fn new(n: usize, multipliers: usize) -> Self {
        Observation {
            q: vec![0.0; n],
            qd: vec![0.0; n],
            multipliers: vec![0.0; multipliers],
        }
    }
}

/// What a model binds: the scene and the formulation, with their resolved
/// parameters and options.
#[derive(Debug, Clone, Copy)]
pub struct Description<'a> {
    pub scene: &'static SceneInfo,
    pub formulation: &'static FormulationInfo,
    /// Resolved scene parameters.
    pub params: &'a Params,
    /// Resolved formulation options.
    pub options: &'a Params,
}

/// A formulation bound to a scene, ready to integrate: an explicit form
/// `y' = f(t, y)`, an implicit form `F(t, y, y') = 0`, or both.
///
/// The formulations with a KKT right-hand side are [`crate::binding::Binding`]s of
/// their [`crate::binding::Equations`]; formulation A implements it itself.
pub trait Model: Send {
    /// The scene and formulation this model binds.
    fn describe(&self) -> Description<'_>;
    /// The explicit form, if the formulation has one.
    fn ode(&mut self) -> Option<&mut dyn OdeSystem> {
        None
    }
    /// The implicit form, if the formulation has one.
    fn implicit(&mut self) -> Option<&mut dyn ImplicitSystem> {
        None
    }
    /// The Newton iteration Radau IIA should use when the caller leaves it
    /// to the model (`RadauNewton::Auto`): full Newton for systems on which
    /// the simplified iteration (one Jacobian per step) converges badly —
    /// implicit systems outside Hessenberg form, stiff terms whose Jacobian
    /// turns with the state.
    fn radau_newton(&self) -> RadauNewton {
        RadauNewton::Simplified
    }
    /// Whether the model can be integrated by `method` with its options as
    /// given (e.g. A continued through its singular set runs on its
    /// explicit form only); `Err` says why not.
    fn accepts(&self, _method: Method) -> Result<(), Error> {
        Ok(())
    }
    /// What carries the explicit form's solution across a stop of its guard,
    /// if the model has it (A through the singular set of its embedding
    /// map); `None`: the run ends at the stop.
    fn crossing(&mut self) -> Option<&mut dyn Crossing> {
        None
    }
    /// What changes the mode of a model with modes at a stop of its guard
    /// (the friction realisation's stick and slip), if the model has modes;
    /// `None`: a stop of the guard is a crossing or the end of the run.
    fn switch(&mut self) -> Option<&mut dyn Switch> {
        None
    }
    /// Consistent `y'(t0)` for the implicit form, after [`Model::initial_state`].
    fn initial_slope(&mut self) -> Result<Vec<f64>, Error> {
        Err(Error::numerical(
            "the initial slope",
            format!(
                "formulation `{}` has no implicit form",
                self.formulation().name
            ),
        ))
    }
    fn scene_info(&self) -> &'static SceneInfo {
        self.describe().scene
    }
    fn formulation(&self) -> &'static FormulationInfo {
        self.describe().formulation
    }
    /// Resolved scene parameters.
    fn scene_params(&self) -> &Params {
        self.describe().params
    }
    /// Resolved formulation options.
    fn options(&self) -> &Params {
        self.describe().options
    }
    /// Names of the reported multipliers (`lambda`, or `lambda1`, ...; `nu...`
    /// for holonomic constraints), empty if the formulation has none. By
    /// default one per constraint of the scene, `λ` then `ν`.
    fn multiplier_names(&self) -> Vec<String> {
        let info = self.scene_info();
        multiplier_names(info.s(), info.k())
    }
    /// Names `--init` accepts beyond coordinates, velocities and the scene's
    /// convenience values.
    fn extra_init_names(&self) -> Vec<ExtraName> {
        Vec::new()
    }
    /// Checks that the initial data satisfy the constraints; with `project`,
    /// moves them onto the constraints instead and reports the change.
    fn make_consistent(
        &mut self,
        init: &mut Initial,
        project: bool,
    ) -> Result<Option<InitProjection>, Error>;
    /// The state vector for consistent initial data; resets the diagnostics.
    fn initial_state(&mut self, init: &Initial) -> Result<Vec<f64>, Error>;
    /// The physical reading of state `y` at `t`.
    fn observe(&mut self, t: f64, y: &[f64], obs: &mut Observation) -> Result<(), SystemError>;
    /// Numbers the formulation found while setting up its initial state
    /// (A: rank of W, hidden constraints, free initial data, …), for the record.
    fn init_report(&self) -> Vec<(&'static str, f64)> {
        Vec::new()
    }
    /// Diagnostics accumulated since [`Model::initial_state`].
    fn diagnostics(&self) -> Diagnostics;
    /// The structure of the state at `(t, y)` that a linearisation needs
    /// (component names and the constraint manifold the formulation keeps
    /// invariant); `Err` if the formulation's state does not begin with
    /// `(q, q̇)` (formulation A), so that it cannot be linearised this way.
    fn state_chart(&mut self, _t: f64, _y: &[f64]) -> Result<StateChart, Error> {
        Err(self.no_state_chart())
    }
    /// Whether [`Model::state_chart`] is available (checked before any
    /// initial data are asked for).
    fn has_state_chart(&self) -> bool {
        false
    }
    /// Why the model cannot be linearised through a state chart.
    fn no_state_chart(&self) -> Error {
        Error::NotApplicable {
            formulation: self.formulation().name.into(),
            scene: self.scene_info().name.into(),
            reason: "linearisation needs a state that begins with (q, q̇); this formulation's \
                     state holds other quantities"
                .into(),
        }
    }
}

/// What a linearisation needs to know of a formulation's state `y`, which
/// begins with `(q, q̇)` (see [`Model::state_chart`]).
#[derive(Debug, Clone, PartialEq)]
pub struct StateChart {
    /// Number of coordinates `n`.
    pub n: usize,
    /// A name for every component of `y`: the coordinates, `<coord>_dot`,
    /// then the formulation's own (`lambda`, ...).
    pub names: Vec<String>,
    /// The Jacobian, with respect to `y`, of the functions the formulation
    /// keeps at zero along every motion (`f`, `ḟ`, `g` for B and C), one row
    /// each; no rows if it keeps none (a realisation, which only
    /// approaches the constraints).
    pub invariants: nalgebra::DMatrix<f64>,
    /// A name for each row (`f`, `f_dot`, `g1`, ...).
    pub invariant_names: Vec<String>,
    /// How many leading rows constrain positions only (`f`); the others
    /// constrain velocities.
    pub position_rows: usize,
}

/// A continuation of a run's solution across a stop of its guard, where the
/// equations are singular but the solution is not (A's embedding map at
/// zero speed).
pub trait Crossing {
    /// Carries the state `y` of the explicit form, at the stop `t` of its
    /// guard, across, integrating with `method` and `opts` (tolerances, the
    /// budgets left; `opts.output` is ignored). The model is left ready to
    /// go on from [`Crossed::t`] with [`Model::ode`], or says why it cannot
    /// (the error names the time, the crossing's number and the reason).
    fn cross(
        &mut self,
        t: f64,
        y: &[f64],
        method: Method,
        opts: &Options,
    ) -> Result<Crossed, SystemError>;
}

/// A change of mode at a stop of the guard, after which the run goes on
/// from the same time and state with other equations (a contact that
/// starts or stops slipping).
pub trait Switch {
    /// At the stop `(t, y)` of the guard: `Ok(Some(record))` if the model
    /// changed its mode and goes on from `(t, y)` — which it may correct in
    /// place (an impulse that removes what is left of a slip when a contact
    /// sticks), saying so in the record; `Ok(None)` if the stop is not a
    /// change of mode (the run then crosses or ends as without modes);
    /// `Err` if the model cannot go on (the error says why).
    fn switch(&mut self, t: f64, y: &mut [f64]) -> Result<Option<SwitchRecord>, SystemError>;
}

/// One change of mode of a run (written as is in the run's JSON,
/// `switches[]`, docs/schema.md).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct SwitchRecord {
    /// 1 for the first switch of a run.
    pub number: usize,
    /// The located stop of the guard where the mode changed.
    pub t: f64,
    /// The part that changed (a contact's name).
    pub part: String,
    /// The modes before and after (`stick`, `slip`).
    pub from: String,
    pub to: String,
    /// The size of the force the new mode needs, relative to what the
    /// mode allows (friction: `‖f‖/(μN)` of the conic solve at the switch;
    /// below 1 the contact sticks).
    pub force_ratio: f64,
    /// The size of the rate that starts the new mode (friction: the slip
    /// acceleration `‖a_s‖` in m/s² that the cone finds at a slip onset; 0
    /// when sticking, and at a slip that starts from sticking, where the
    /// transition is continuous).
    pub rate: f64,
    /// What decided the new mode: `cone` (the friction cone, solved to
    /// Clarabel's full accuracy), `cone, reduced accuracy` (Clarabel's
    /// `AlmostSolved`, decided with a wider margin), `stick force` (the
    /// force of the stick phase reached the cone's boundary).
    pub decided_by: String,
    /// The change the switch made to the state: the norm of the velocity
    /// jump that removes the slip left at a located stick (its size is the
    /// error of the location; 0 otherwise).
    pub velocity_jump: f64,
}

/// The state at a time of a crossing's gap, written into the slice.
pub type GapFill = Box<dyn Fn(f64, &mut [f64]) + Send>;

/// A crossing made: where the run goes on, the solution in between, the
/// work and the record.
pub struct Crossed {
    /// Where the run goes on (after the singular instant).
    pub t: f64,
    /// The state there.
    pub y: Vec<f64>,
    /// The state at any time of `[t_stop, t]` into `out` (the gap between
    /// the stop and the restart, on the real axis).
    pub gap: GapFill,
    /// Work done by the crossing.
    pub stats: Stats,
    pub record: CrossingRecord,
}

/// What one crossing did and how well, for the results (written as is in
/// the run's JSON, `crossings[]`, docs/schema.md).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct CrossingRecord {
    /// 1 for the first crossing of a run.
    pub number: usize,
    /// The stop of the guard, where the crossing starts.
    pub t_stop: f64,
    /// The singular instant as estimated before the crossing.
    pub t_singular: f64,
    /// Where the run goes on.
    pub t_resume: f64,
    /// How close to the singular instant the crossing passed (in time).
    pub clearance: f64,
    /// A bound on the error of the crossing's states between `t_stop` and
    /// `t_resume` (relative to the state's size).
    pub gap_error: f64,
    /// The imaginary part left on the state where it returns to the real
    /// axis, relative to its size (zero for an exact continuation).
    pub return_residual: f64,
    /// Change of the state's highest derivatives made at the restart (the
    /// literal-map continuation re-completes them on the map's branch).
    pub restart_change: f64,
}

/// Multiplier names for `s` nonholonomic and `k` holonomic constraints:
/// `lambda` (or `lambda1..s`) then `nu` (or `nu1..k`).
pub fn multiplier_names(s: usize, k: usize) -> Vec<String> {
    let numbered = |base: &str, count: usize| -> Vec<String> {
        match count {
            0 => Vec::new(),
            1 => vec![base.to_string()],
            _ => (1..=count).map(|i| format!("{base}{i}")).collect(),
        }
    };
    let mut names = numbered("lambda", s);
    names.extend(numbered("nu", k));
    names
}
