//! Realisation `friction`: the nonholonomic constraints enforced by dry
//! (Coulomb) friction at the scene's contacts.
//!
//! A contact ([`nonholo_core::ContactInfo`]) is a blade or a wheel's contact
//! point whose slip velocity `v` (its rows of `g`, one or two components in
//! an orthonormal frame, m/s) an ideal constraint keeps at zero. Under a
//! normal load `N` with friction coefficient `μ` it is in one of two modes:
//!
//! * **stick**: `v = 0` is imposed as in B (no stabilisation), and the
//!   constraint force `λ` it needs is watched: the mode holds while
//!   `‖λ‖ < μN`;
//! * **slip**: no constraint; the kinetic friction force `f = −μN v/‖v‖`
//!   (maximal dissipation, power `fᵀv = −μN‖v‖ ≤ 0`) joins the generalised
//!   forces as `Gᵀf`. The mode holds until the slip velocity returns to zero.
//!
//! Transitions are events located on the integrator's continuous extension
//! (the guard of [`nonholo_core::integrate::OdeSystem`]), and the run goes
//! on from the located state in the new mode ([`nonholo_core::Switch`]), so
//! between events any integrator keeps its order and the events are found to
//! ~1e-14 in time. Which mode follows an event is decided by the friction
//! cone at the contact: with the slip acceleration affine in the contact
//! force, `a_s = W f + c`, Coulomb's law at zero slip velocity is the
//! second-order cone program `min ½ fᵀWf + cᵀf` over `‖f‖ ≤ μN`
//! ([`crate::conic::FrictionCone`], solved by Clarabel): a force inside the
//! cone means stick, one on its boundary means slip, starting in the
//! direction `−f`.
//!
//! So that a step may pass the instant the slip stops and the event be
//! located inside it, the kinetic force is continued smoothly through
//! `v = 0` along the current direction of slip `d` (the direction at the
//! start of the step): `f = −μN (v/‖v‖) sign(v·d)`, constant for a blade.
//! The slip velocity is measured from its value at the onset of slip (a
//! stick phase leaves `v` at round-off, not exactly zero), and at the onset
//! instant itself, where `v = 0`, the direction is the cone's `−f`.
//!
//! Initial data may violate the constraints: a contact with `v ≠ 0` at `t0`
//! starts slipping. Chattering — more than `max_switch_rate` switches within
//! one second — stops the run with the count, not a loop.

use nonholo_core::binding::{Binding, Equations, EvalError};
use nonholo_core::compiled::Programs;
use nonholo_core::constraints::ConstraintState;
use nonholo_core::integrate::SystemError;
use nonholo_core::kkt::{GRows, Kkt};
use nonholo_core::model::{FormulationInfo, SwitchRecord};
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::scene::{Lagrangian, Scalar, Scene, SceneInfo};
use nonholo_core::stab::{SINGULAR_TOL, Stabilisation};
use nonholo_core::{Error, Initial};

use crate::conic::{ConeSolution, FrictionCone};

/// The friction coefficient (required).
pub const MU: ParamSpec = ParamSpec::real(
    "mu",
    "",
    f64::NAN,
    Bound::Inclusive(0.0),
    Bound::Unbounded,
    "Coulomb friction coefficient μ at every contact (required): the contact sticks while the \
     force that keeps it from slipping is below μN, and slides against the force μN otherwise",
);

/// The normal load, where the scene does not give it.
pub const NORMAL: ParamSpec = ParamSpec::real(
    "normal",
    "N",
    f64::NAN,
    Bound::Exclusive(0.0),
    Bound::Unbounded,
    "normal load N at every contact; by default the scene's (sleigh-incline: m g cos α); \
     required where the scene has none (rolling-disk, whose plane carries no gravity in L)",
);

/// The chattering bound.
pub const MAX_SWITCH_RATE: ParamSpec = ParamSpec::real(
    "max_switch_rate",
    "1/s",
    1000.0,
    Bound::Exclusive(0.0),
    Bound::Unbounded,
    "largest number of stick–slip switches within any second of the run; one more stops it as \
     chattering",
);

/// Options of `friction`.
pub const OPTIONS: &[ParamSpec] = &[MU, NORMAL, MAX_SWITCH_RATE, SINGULAR_TOL];

pub const INFO: FormulationInfo = FormulationInfo {
    name: "friction",
    letter: "FRICTION(μ)",
    title: "Dry-friction realisation: contacts stick inside the friction cone and slip outside it",
    description: "stick: B's constraint, while ‖λ‖ < μN; slip: kinetic friction −μN v/‖v‖; \
                  transitions located as events, the next mode from the friction cone (a \
                  second-order cone program, Clarabel); state (q, q̇)",
    options: OPTIONS,
    applicable,
};

/// `friction` applies to scenes that declare their contacts, with at most
/// [`nonholo_core::scene::MAX_CONSTRAINTS`] nonholonomic rows (its
/// per-row state is held in fixed arrays).
fn applicable(scene: &SceneInfo) -> Result<(), String> {
    if scene.contacts.is_empty() {
        return Err(
            "the scene declares no contacts whose sliding its constraints forbid, so there is \
             no friction to realise them"
                .into(),
        );
    }
    let most = nonholo_core::scene::MAX_CONSTRAINTS;
    if scene.s() > most {
        return Err(format!(
            "the scene has {} nonholonomic constraints; friction supports at most {most}",
            scene.s()
        ));
    }
    Ok(())
}

/// Where the slip velocity counts as zero at `t0`, relative to `max(1, |q̇|∞)`
/// (as initial data are checked against the constraints).
const START_SLIP_TOL: f64 = 1e-9;

/// A force ratio `‖f‖/(μN)` of the cone at or above `1 − STICK_MARGIN` is on
/// the cone's boundary (slip); below, inside (stick). Clarabel's solution is
/// accurate to ~1e-10 here.
const STICK_MARGIN: f64 = 1e-8;

/// The margin where Clarabel reached only its reduced accuracy
/// (`AlmostSolved`, ~1e-5 relative): a ratio within it of 1 is slip.
const STICK_MARGIN_REDUCED: f64 = 1e-4;

/// The dry-friction realisation bound to a scene.
pub type Friction<S> = Binding<S, FrictionEquations>;

/// The mode of a contact.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Mode {
    /// `v = 0` imposed.
    Stick,
    /// Sliding against the kinetic force.
    Slip {
        /// Unit direction of the slip velocity at the start of the current
        /// step (the force is opposite).
        dir: [f64; 2],
        /// The slip velocity at the onset, from which it is measured.
        origin: [f64; 2],
        /// The onset time (`NaN` for a slip given at `t0`).
        since: f64,
    },
}

impl Mode {
    fn name(&self) -> &'static str {
        match self {
            Mode::Stick => "stick",
            Mode::Slip { .. } => "slip",
        }
    }
}

/// One contact: its rows of `g`, its friction bound `μN`, its mode.
#[derive(Debug, Clone)]
struct Contact {
    name: &'static str,
    rows: Vec<usize>,
    /// `μN`.
    bound: f64,
    mode: Mode,
}

impl Contact {
    fn d(&self) -> usize {
        self.rows.len()
    }

    /// The slip velocity from the onset, `v − origin`, of constraint values `g`.
    fn slip<T: Scalar>(&self, g: &[T]) -> [T; 2] {
        let origin = match self.mode {
            Mode::Slip { origin, .. } => origin,
            Mode::Stick => [0.0; 2],
        };
        let mut u = [T::from(0.0); 2];
        for (a, &r) in self.rows.iter().enumerate() {
            u[a] = g[r] - origin[a];
        }
        u
    }

    /// The kinetic force of a slipping contact, continued through `v = 0`
    /// along `dir` (module docs).
    fn kinetic<T: Scalar>(&self, g: &[T], dir: [f64; 2]) -> [T; 2] {
        let u = self.slip(g);
        let d = self.d();
        let norm2 = (0..d).fold(T::from(0.0), |s, a| s + u[a] * u[a]);
        let mut f = [T::from(0.0); 2];
        if norm2.re() == 0.0 {
            for a in 0..d {
                f[a] = T::from(-self.bound * dir[a]);
            }
            return f;
        }
        let along: f64 = (0..d).map(|a| u[a].re() * dir[a]).sum();
        let scale = if along >= 0.0 {
            -self.bound
        } else {
            self.bound
        };
        let norm = norm2.sqrt();
        for a in 0..d {
            f[a] = u[a] / norm * scale;
        }
        f
    }
}

/// The rows of `g` in the KKT system: a sticking contact's as B's, a
/// slipping contact's replaced by its kinetic force (and `free`, if given,
/// makes one contact slip with a given force: the columns of `W`).
struct Rows<'a> {
    contacts: &'a [Contact],
    free: Option<(usize, [f64; 2])>,
}

impl GRows for Rows<'_> {
    fn write<T: Scalar>(
        &self,
        n: usize,
        cs: &ConstraintState<T>,
        matrix: &mut nalgebra::DMatrix<T>,
        rhs: &mut [T],
    ) {
        let mut ideal = [true; nonholo_core::scene::MAX_CONSTRAINTS];
        for (ci, c) in self.contacts.iter().enumerate() {
            let force = match (self.free, c.mode) {
                (Some((k, f)), _) if k == ci => [T::from(f[0]), T::from(f[1])],
                (_, Mode::Stick) => continue,
                (_, Mode::Slip { dir, .. }) => c.kinetic(&cs.g, dir),
            };
            for (a, &r) in c.rows.iter().enumerate() {
                ideal[r] = false;
                matrix[(n + r, n + r)] = T::from(1.0);
                rhs[n + r] = T::from(0.0);
                for j in 0..n {
                    rhs[j] += cs.jac[(r, j)] * force[a];
                }
            }
        }
        for r in 0..cs.s {
            if ideal[r] {
                cs.write_rows(r..r + 1, matrix, n + r);
                rhs[n + r] = -cs.g_rate0[r];
            }
        }
    }
}

/// The KKT solve at `(t, y)` with `contacts` in their modes.
fn solve_with<S: Scene, T: Scalar>(
    contacts: &[Contact],
    scene: &S,
    kkt: &mut Kkt<T>,
    free: Option<(usize, [f64; 2])>,
    t: T,
    y: &[T],
) -> Result<(), EvalError> {
    let n = y.len() / 2;
    let rows = Rows { contacts, free };
    kkt.solve(&Lagrangian(scene), &[], scene, &rows, t, &y[..n], &y[n..])?;
    Ok(())
}

/// The equations of `friction`: the contacts and their modes.
pub struct FrictionEquations {
    mu: f64,
    contacts: Vec<Contact>,
    /// One cone program per contact.
    cones: Vec<FrictionCone>,
    max_rate: f64,
    /// Times of the switches made.
    switch_times: Vec<f64>,
    /// Every mode each contact has had, from `t0`: `(since, contact,
    /// mode)` in time order, so that a state observed after the run (the
    /// output grid is read at the end) is read in the mode of its time.
    history: Vec<(f64, usize, Mode)>,
    /// The velocity change of a unit impulse on each slip component of the
    /// contact of the last [`FrictionEquations::cone`] (`n × 2`, column by
    /// column): `Δq̇ = A P`.
    impulse: Vec<f64>,
    /// The `W` of that cone (`d × d`, row-major).
    w: [f64; 4],
    /// The initial modes, for the record.
    sticking_at_start: usize,
    /// `L` and the constraints, compiled once for every workspace.
    programs: Programs,
}

impl FrictionEquations {
    /// The KKT solve with the current modes at `(t, y)`.
    fn solve<S: Scene, T: Scalar>(
        &self,
        scene: &S,
        kkt: &mut Kkt<T>,
        free: Option<(usize, [f64; 2])>,
        t: T,
        y: &[T],
    ) -> Result<(), EvalError> {
        solve_with(&self.contacts, scene, kkt, free, t, y)
    }

    /// The contacts in the modes they had at time `t` of the run.
    fn contacts_at(&self, t: f64) -> Vec<Contact> {
        let mut contacts = self.contacts.clone();
        for &(since, ci, mode) in &self.history {
            if since <= t {
                contacts[ci].mode = mode;
            }
        }
        contacts
    }

    /// The slip acceleration `a_s = G_c q̈ + ġ₀_c` of contact `ci` after a
    /// solve.
    fn slip_accel(&self, kkt: &Kkt<f64>, ci: usize) -> [f64; 2] {
        let n = kkt.qdd().len();
        let mut a_s = [0.0; 2];
        for (a, &r) in self.contacts[ci].rows.iter().enumerate() {
            a_s[a] = kkt.cs.g_rate0[r]
                + (0..n)
                    .map(|j| kkt.cs.jac[(r, j)] * kkt.qdd()[j])
                    .sum::<f64>();
        }
        a_s
    }

    /// The friction cone of contact `ci` at `(t, y)`, the other contacts in
    /// their modes: `W` and `c` from `d + 1` KKT solves, then the program.
    fn cone<S: Scene>(
        &mut self,
        scene: &S,
        kkt: &mut Kkt<f64>,
        t: f64,
        y: &[f64],
        ci: usize,
    ) -> Result<ConeSolution, SystemError> {
        let d = self.contacts[ci].d();
        let fail = |e: EvalError| e.into_system(&INFO);
        let n = y.len() / 2;
        self.solve(scene, kkt, Some((ci, [0.0; 2])), t, y)
            .map_err(fail)?;
        let c = self.slip_accel(kkt, ci);
        self.impulse.resize(2 * n, 0.0);
        self.impulse[..n].copy_from_slice(kkt.qdd());
        self.impulse[n..].copy_from_slice(kkt.qdd());
        let mut w = [0.0; 4];
        for k in 0..d {
            let mut e = [0.0; 2];
            e[k] = 1.0;
            self.solve(scene, kkt, Some((ci, e)), t, y).map_err(fail)?;
            let col = self.slip_accel(kkt, ci);
            for a in 0..d {
                w[a * d + k] = col[a] - c[a];
            }
            // A unit force's acceleration is a unit impulse's velocity change.
            for (dst, v) in self.impulse[k * n..(k + 1) * n].iter_mut().zip(kkt.qdd()) {
                *dst = v - *dst;
            }
        }
        self.w = w;
        let bound = self.contacts[ci].bound;
        self.cones[ci]
            .solve(&w[..d * d], &c[..d], bound)
            .map_err(|e| {
                SystemError::new(format!(
                    "friction: the friction cone of the {} at t = {t} has no solution: {e}",
                    self.contacts[ci].name
                ))
            })
    }

    /// The mode that follows a cone's solution at `(t, g)`: stick inside the
    /// cone, else slip starting against the force.
    fn mode_from(&self, ci: usize, sol: &ConeSolution, g: &[f64], t: f64) -> Mode {
        let margin = if sol.reduced {
            STICK_MARGIN_REDUCED
        } else {
            STICK_MARGIN
        };
        if sol.ratio < 1.0 - margin {
            return Mode::Stick;
        }
        let c = &self.contacts[ci];
        let d = c.d();
        let norm = sol.force[..d].iter().map(|v| v * v).sum::<f64>().sqrt();
        let mut dir = [0.0; 2];
        let mut origin = [0.0; 2];
        for (a, &r) in c.rows.iter().enumerate() {
            dir[a] = -sol.force[a] / norm;
            origin[a] = g[r];
        }
        Mode::Slip {
            dir,
            origin,
            since: t,
        }
    }

    /// The guard value of contact `ci` (positive while its mode holds), or
    /// `None` for a contact without friction (`μN = 0`: it always slips).
    fn contact_event(&self, ci: usize, kkt: &Kkt<f64>, g: &[f64], t: f64) -> Option<f64> {
        let c = &self.contacts[ci];
        if c.bound == 0.0 {
            return None;
        }
        Some(match c.mode {
            Mode::Stick => {
                let mu = kkt.mu();
                let norm = c.rows.iter().map(|&r| mu[r] * mu[r]).sum::<f64>().sqrt();
                1.0 - norm / c.bound
            }
            Mode::Slip { since, .. } if since == t => 1.0,
            Mode::Slip { dir, .. } => {
                let u = c.slip(g);
                (0..c.d()).map(|a| u[a] * dir[a]).sum()
            }
        })
    }

    /// The constraint values `g` at `(t, y)`.
    fn constraint_values<S: Scene>(scene: &S, t: f64, y: &[f64], g: &mut [f64]) {
        let n = y.len() / 2;
        scene.nonholonomic(t, &y[..n], &y[n..], g);
    }

    /// The contact whose guard is smallest at `(t, y)` and that value (a
    /// NaN value wins: a guard that cannot be evaluated stops the run);
    /// `None` if no contact has a guard (all without friction). One KKT
    /// solve, no allocation: the guard is evaluated at every accepted step.
    fn nearest_event<S: Scene>(
        &self,
        scene: &S,
        kkt: &mut Kkt<f64>,
        t: f64,
        y: &[f64],
    ) -> Result<Option<(usize, f64)>, EvalError> {
        self.solve(scene, kkt, None, t, y)?;
        let mut g = [0.0; nonholo_core::scene::MAX_CONSTRAINTS];
        let s = scene.info().s();
        Self::constraint_values(scene, t, y, &mut g[..s]);
        let mut nearest: Option<(usize, f64)> = None;
        for ci in 0..self.contacts.len() {
            let Some(v) = self.contact_event(ci, kkt, &g[..s], t) else {
                continue;
            };
            if v.is_nan() {
                return Ok(Some((ci, v)));
            }
            if nearest.is_none_or(|(_, m)| v < m) {
                nearest = Some((ci, v));
            }
        }
        Ok(nearest)
    }
}

impl Equations for FrictionEquations {
    type Work<T: Scalar> = Kkt<T>;
    const INFO: &'static FormulationInfo = &INFO;

    fn new<S: Scene>(scene: &S, options: &mut Params) -> Result<Self, Error> {
        let info = scene.info();
        let mu = options.real("mu")?;
        if !mu.is_finite() {
            return Err(Error::numerical(
                "option `mu` of `friction`",
                "the friction coefficient is required: give it, e.g. --option mu=0.5".to_string(),
            ));
        }
        let given = options.real("normal")?;
        let mut contacts = Vec::with_capacity(info.contacts.len());
        for (ci, c) in info.contacts.iter().enumerate() {
            let normal = if given.is_finite() {
                given
            } else {
                scene.normal_load(ci).ok_or_else(|| {
                    Error::numerical(
                        "option `normal` of `friction`",
                        format!(
                            "scene `{}` does not model the normal load on its {} ({}): give it \
                             in newtons, e.g. --option normal=9.81",
                            info.name, c.name, c.load
                        ),
                    )
                })?
            };
            contacts.push(Contact {
                name: c.name,
                rows: c.rows.to_vec(),
                bound: mu * normal,
                mode: Mode::Stick,
            });
        }
        let cones = contacts.iter().map(|c| FrictionCone::new(c.d())).collect();
        Ok(FrictionEquations {
            mu,
            contacts,
            cones,
            max_rate: options.real("max_switch_rate")?,
            switch_times: Vec::new(),
            history: Vec::new(),
            impulse: Vec::new(),
            w: [0.0; 4],
            sticking_at_start: 0,
            programs: Programs::default(),
        })
    }

    fn work<S: Scene, T: Scalar>(&self, scene: &S) -> Kkt<T> {
        Kkt::for_scene(scene.info()).compiled_for(&self.programs, &Lagrangian(scene), 0, scene)
    }

    fn dim(&self, info: &SceneInfo) -> usize {
        2 * info.n()
    }

    fn has_modes(&self) -> bool {
        true
    }

    fn needs_consistent_velocities(&self) -> bool {
        false
    }

    fn accelerations<S: Scene, T: Scalar>(
        &self,
        scene: &S,
        _stab: Stabilisation,
        kkt: &mut Kkt<T>,
        t: T,
        y: &[T],
        qdd: &mut [T],
    ) -> Result<(), EvalError> {
        self.solve(scene, kkt, None, t, y)?;
        qdd.copy_from_slice(kkt.qdd());
        Ok(())
    }

    /// The contact forces at time `t` of the run, in the modes of that time
    /// (observations are read after the run): `λ` of a sticking contact,
    /// the kinetic force of a slipping one (both in B's convention,
    /// generalised force `Gᵀλ`).
    fn multipliers<S: Scene>(
        &self,
        scene: &S,
        _stab: Stabilisation,
        kkt: &mut Kkt<f64>,
        t: f64,
        y: &[f64],
        _qd: &[f64],
        out: &mut [f64],
    ) -> Result<(), EvalError> {
        let contacts = self.contacts_at(t);
        solve_with(&contacts, scene, kkt, None, t, y)?;
        for (m, v) in out.iter_mut().zip(kkt.mu()) {
            *m = -v;
        }
        let g = &kkt.cs.g;
        for c in &contacts {
            if let Mode::Slip { dir, .. } = c.mode {
                // Inside a slip phase the slip never passes zero (that is a
                // switch): the force is against the slip itself, and along
                // the phase's direction only where the slip is exactly zero.
                let u = c.slip(g);
                let norm = u[..c.d()].iter().map(|v| v * v).sum::<f64>().sqrt();
                let along = if norm > 0.0 {
                    [u[0] / norm, u[1] / norm]
                } else {
                    dir
                };
                let f = c.kinetic(g, along);
                for (a, &r) in c.rows.iter().enumerate() {
                    out[r] = f[a];
                }
            }
        }
        Ok(())
    }

    /// `(q0, q̇0)`, and each contact's first mode: slipping if its slip
    /// velocity is not zero, else as its friction cone says.
    fn initial_state<S: Scene>(
        &mut self,
        scene: &S,
        kkt: &mut Kkt<f64>,
        init: &Initial,
    ) -> Result<Vec<f64>, Error> {
        let y: Vec<f64> = init.q.iter().chain(&init.qd).copied().collect();
        let s = scene.info().s();
        let mut g = vec![0.0; s];
        Self::constraint_values(scene, init.t0, &y, &mut g);
        let scale = init.qd.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        // Rows of g that belong to no contact stay ideal: they must hold.
        for r in 0..s {
            if !self.contacts.iter().any(|c| c.rows.contains(&r))
                && g[r].abs() > START_SLIP_TOL * scale
            {
                return Err(Error::numerical(
                    "friction: the initial data",
                    format!(
                        "constraint {} of `{}` belongs to no contact and stays ideal, but its \
                         value is {:e} at t0",
                        scene.info().nonholonomic[r],
                        scene.info().name,
                        g[r]
                    ),
                ));
            }
        }
        self.switch_times.clear();
        self.history.clear();
        // First the contacts that slip from the start, then the friction
        // cones of the others (each with the slipping ones already slipping).
        let mut at_rest = Vec::new();
        for c in &mut self.contacts {
            let norm = c.rows.iter().map(|&r| g[r] * g[r]).sum::<f64>().sqrt();
            c.mode = if norm > START_SLIP_TOL * scale || c.bound == 0.0 {
                let mut dir = [0.0; 2];
                for (a, &r) in c.rows.iter().enumerate() {
                    dir[a] = if norm > 0.0 { g[r] / norm } else { 0.0 };
                }
                Mode::Slip {
                    dir,
                    origin: [0.0; 2],
                    since: f64::NAN,
                }
            } else {
                Mode::Stick
            };
            at_rest.push(c.mode == Mode::Stick);
        }
        for ci in (0..self.contacts.len()).filter(|&ci| at_rest[ci]) {
            let sol = self
                .cone(scene, kkt, init.t0, &y, ci)
                .map_err(|e| Error::numerical("friction: the initial mode", e.message))?;
            self.contacts[ci].mode = self.mode_from(ci, &sol, &g, init.t0);
        }
        for (ci, c) in self.contacts.iter().enumerate() {
            self.history.push((init.t0, ci, c.mode));
        }
        self.sticking_at_start = self
            .contacts
            .iter()
            .filter(|c| c.mode == Mode::Stick)
            .count();
        Ok(y)
    }

    fn init_report(&self) -> Vec<(&'static str, f64)> {
        vec![
            ("friction_mu", self.mu),
            ("contacts_sticking_at_t0", self.sticking_at_start as f64),
        ]
    }

    fn event<S: Scene>(&self, scene: &S, kkt: &mut Kkt<f64>, t: f64, y: &[f64]) -> Option<f64> {
        match self.nearest_event(scene, kkt, t, y) {
            Ok(e) => Some(e.map_or(1.0, |(_, v)| v)),
            Err(_) => Some(f64::NAN),
        }
    }

    fn event_reason<S: Scene>(&self, scene: &S, kkt: &mut Kkt<f64>, t: f64, y: &[f64]) -> String {
        let ci = match self.nearest_event(scene, kkt, t, y) {
            Ok(Some((ci, _))) => ci,
            Ok(None) => return "no contact with friction".into(),
            Err(e) => return e.into_system(&INFO).message,
        };
        let c = &self.contacts[ci];
        match c.mode {
            Mode::Stick => format!(
                "the force keeping the {} from slipping reached μN = {} N",
                c.name, c.bound
            ),
            Mode::Slip { .. } => format!("the slip velocity of the {} returned to zero", c.name),
        }
    }

    /// The direction of a slip, followed from step to step (kept where the
    /// slip reversed inside the step, so that the guard locates it).
    fn step_accepted<S: Scene>(
        &mut self,
        scene: &S,
        _kkt: &mut Kkt<f64>,
        t: f64,
        y: &[f64],
    ) -> Result<(), EvalError> {
        let mut g = [0.0; nonholo_core::scene::MAX_CONSTRAINTS];
        let s = scene.info().s();
        Self::constraint_values(scene, t, y, &mut g[..s]);
        for c in &mut self.contacts {
            let u = c.slip(&g[..s]);
            if let Mode::Slip { dir, .. } = &mut c.mode {
                let d = c.rows.len();
                let along: f64 = (0..d).map(|a| u[a] * dir[a]).sum();
                let norm = (0..d).map(|a| u[a] * u[a]).sum::<f64>().sqrt();
                if along > 0.0 && norm > 0.0 {
                    for a in 0..d {
                        dir[a] = u[a] / norm;
                    }
                }
            }
        }
        Ok(())
    }

    /// At a stop of the guard: the contact whose guard reached zero changes
    /// mode as its friction cone says. A contact that sticks keeps no slip:
    /// what is left of it at the located stop (the error of the location)
    /// is removed by the impulse `P = −W⁻¹v` inside the contact, `Δq̇ = A P`
    /// (the kinetic-energy projection onto `v = 0` with the other contacts
    /// in their modes), which the record reports.
    fn switch<S: Scene>(
        &mut self,
        scene: &S,
        kkt: &mut Kkt<f64>,
        t: f64,
        y: &mut [f64],
    ) -> Result<Option<SwitchRecord>, SystemError> {
        let Some((ci, value)) = self
            .nearest_event(scene, kkt, t, y)
            .map_err(|e| e.into_system(&INFO))?
        else {
            return Ok(None);
        };
        if value.is_nan() {
            return Err(SystemError::new(format!(
                "friction: the guard of the {} is not finite at t = {t}",
                self.contacts[ci].name
            )));
        }
        if value > 0.0 {
            return Ok(None);
        }
        self.switch_times.push(t);
        let recent = self.switch_times.iter().filter(|&&s| s > t - 1.0).count();
        if recent as f64 > self.max_rate {
            return Err(SystemError::new(format!(
                "friction: chattering at t = {t}: {recent} stick–slip switches within the last \
                 second (max_switch_rate = {}); the {} is at the edge of its friction cone",
                self.max_rate, self.contacts[ci].name
            )));
        }
        let s = scene.info().s();
        let mut g = vec![0.0; s];
        Self::constraint_values(scene, t, y, &mut g);
        let from = self.contacts[ci].mode;
        let d = self.contacts[ci].d();
        let (sol, decided_by) = if from == Mode::Stick {
            // The guard located ‖λ‖ = μN: the force sits on the cone's
            // boundary with zero slip acceleration (the transition is
            // continuous), and slip starts against it. The stick solve gives
            // that force exactly; the cone program would be degenerate there.
            self.solve(scene, kkt, None, t, y)
                .map_err(|e| e.into_system(&INFO))?;
            let mu = kkt.mu();
            let mut force = [0.0; 2];
            for (a, &r) in self.contacts[ci].rows.iter().enumerate() {
                force[a] = -mu[r];
            }
            let norm = force[..d].iter().map(|v| v * v).sum::<f64>().sqrt();
            let sol = ConeSolution {
                force,
                slip_accel: [0.0; 2],
                ratio: (norm / self.contacts[ci].bound).max(1.0),
                reduced: false,
            };
            (sol, "stick force")
        } else {
            let sol = self.cone(scene, kkt, t, y, ci)?;
            let by = if sol.reduced {
                "cone, reduced accuracy"
            } else {
                "cone"
            };
            (sol, by)
        };
        let to = self.mode_from(ci, &sol, &g, t);
        let mut jump = 0.0;
        if to == Mode::Stick {
            // P = −W⁻¹ v (d = 1 or 2) with v the slip velocity left, then
            // Δq̇ = A P.
            let c = &self.contacts[ci];
            let mut u = [0.0; 2];
            for (a, &r) in c.rows.iter().enumerate() {
                u[a] = g[r];
            }
            let w = &self.w;
            let p = if d == 1 {
                [-u[0] / w[0], 0.0]
            } else {
                let det = w[0] * w[3] - w[1] * w[2];
                [
                    -(w[3] * u[0] - w[1] * u[1]) / det,
                    -(-w[2] * u[0] + w[0] * u[1]) / det,
                ]
            };
            let n = y.len() / 2;
            let mut sq = 0.0;
            for j in 0..n {
                let dv: f64 = (0..d).map(|k| self.impulse[k * n + j] * p[k]).sum();
                y[n + j] += dv;
                sq += dv * dv;
            }
            jump = sq.sqrt();
        }
        self.contacts[ci].mode = to;
        self.history.push((t, ci, to));
        Ok(Some(SwitchRecord {
            number: self.switch_times.len(),
            t,
            part: self.contacts[ci].name.to_string(),
            from: from.name().to_string(),
            to: to.name().to_string(),
            force_ratio: sol.ratio,
            rate: match to {
                Mode::Stick => 0.0,
                Mode::Slip { .. } => sol.slip_accel[..d]
                    .iter()
                    .map(|v| v * v)
                    .sum::<f64>()
                    .sqrt(),
            },
            decided_by: decided_by.to_string(),
            velocity_jump: jump,
        }))
    }
}
