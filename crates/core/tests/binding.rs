//! [`Binding`] against closed forms: the right-hand side, its Jacobian and
//! the Taylor coefficients of the motion of a harmonic oscillator, in a
//! state that holds `q̇` and in one that holds the momentum `p = μ q̇`
//! instead (whose `q̇` the binding computes for the hooks and observations,
//! once per state).

use nonholo_core::binding::{Binding, Equations, EvalError};
use nonholo_core::integrate::OdeSystem;
use nonholo_core::model::{FormulationInfo, Model, Observation};
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::scene::{ConstraintKind, Named, Scalar, Scene, SceneInfo};
use nonholo_core::stab::{SINGULAR_TOL, Stabilisation};
use nonholo_core::{Error, Initial, init};

/// `L = ½ μ q̇² − ½ κ q²`: `q̈ = −ω² q`, `ω² = κ/μ`.
#[derive(Clone)]
struct Oscillator {
    params: Params,
    mu: f64,
    kappa: f64,
}

const PARAMS: &[ParamSpec] = &[
    ParamSpec::real(
        "mu",
        "kg",
        2.0,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "mass",
    ),
    ParamSpec::real(
        "kappa",
        "N/m",
        8.0,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "stiffness",
    ),
];

const INFO: SceneInfo = SceneInfo {
    name: "oscillator",
    title: "harmonic oscillator",
    description: "",
    coordinates: &[Named::new("q", "m", "")],
    params: PARAMS,
    structural: &[],
    holonomic: &[],
    nonholonomic: &[],
    constraint_kind: ConstraintKind::Linear,
    nonholonomic_unit: "",
    constraint_singular_set: None,
    embedding: None,
    velocity_chart: &[],
    default_q: &[0.5],
    default_velocity: &[0.3],
    closed_form: None,
    invariants: &[],
    contacts: &[],
};

impl Scene for Oscillator {
    const INFO: &'static SceneInfo = &INFO;
    fn from_params(params: &Params) -> Result<Self, Error> {
        Ok(Oscillator {
            mu: params.real("mu")?,
            kappa: params.real("kappa")?,
            params: params.clone(),
        })
    }
    fn params(&self) -> &Params {
        &self.params
    }
    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], qd: &[D]) -> D {
        (qd[0] * qd[0] * self.mu - q[0] * q[0] * self.kappa) * 0.5
    }
}

const STATE: ParamSpec = ParamSpec::choice(
    "state",
    &["velocity", "momentum"],
    "y = (q, q̇) or y = (q, μ q̇)",
);
const OPTIONS: &[ParamSpec] = &[SINGULAR_TOL, STATE];

/// The oscillator's equations in `y = (q, q̇)` (`momentum = false`) or in
/// `y = (q, p)`, `p = μ q̇` (`momentum = true`); the "multiplier" reported
/// is the spring force `−κ q`. Counts its evaluations of `q̇` over `f64`.
struct Hooke {
    momentum: bool,
    velocity_evals: std::sync::atomic::AtomicUsize,
}

const HOOKE: FormulationInfo = FormulationInfo {
    name: "hooke",
    letter: "H",
    title: "",
    description: "",
    options: OPTIONS,
    applicable: |_| Ok(()),
};

fn coefficients<S: Scene>(scene: &S) -> (f64, f64) {
    let p = scene.params();
    (p.real("mu").unwrap(), p.real("kappa").unwrap())
}

impl Equations for Hooke {
    type Work<T: Scalar> = ();
    const INFO: &'static FormulationInfo = &HOOKE;

    fn new<S: Scene>(_scene: &S, options: &mut Params) -> Result<Self, Error> {
        Ok(Hooke {
            momentum: options.choice(STATE.name)? == "momentum",
            velocity_evals: 0.into(),
        })
    }

    fn work<S: Scene, T: Scalar>(&self, _scene: &S) {}

    fn dim(&self, _info: &SceneInfo) -> usize {
        2
    }

    fn cartesian(&self) -> bool {
        !self.momentum
    }

    fn velocities<S: Scene, T: Scalar>(
        &self,
        scene: &S,
        _work: &mut (),
        _t: T,
        y: &[T],
        qd: &mut [T],
    ) -> Result<(), EvalError> {
        if std::any::TypeId::of::<T>() == std::any::TypeId::of::<f64>() {
            self.velocity_evals
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
        let mu = coefficients(scene).0;
        qd[0] = if self.momentum { y[1] / mu } else { y[1] };
        Ok(())
    }

    fn accelerations<S: Scene, T: Scalar>(
        &self,
        scene: &S,
        _stab: Stabilisation,
        _work: &mut (),
        _t: T,
        y: &[T],
        rest: &mut [T],
    ) -> Result<(), EvalError> {
        let (mu, kappa) = coefficients(scene);
        // p' = −κ q; q̈ = −(κ/μ) q.
        rest[0] = if self.momentum {
            -y[0] * kappa
        } else {
            -y[0] * (kappa / mu)
        };
        Ok(())
    }

    fn multipliers<S: Scene>(
        &self,
        scene: &S,
        _stab: Stabilisation,
        _work: &mut (),
        _t: f64,
        y: &[f64],
        _qd: &[f64],
        out: &mut [f64],
    ) -> Result<(), EvalError> {
        out[0] = -coefficients(scene).1 * y[0];
        Ok(())
    }

    fn initial_state<S: Scene>(
        &mut self,
        scene: &S,
        _work: &mut (),
        init: &Initial,
    ) -> Result<Vec<f64>, Error> {
        let scale = if self.momentum {
            coefficients(scene).0
        } else {
            1.0
        };
        Ok(vec![init.q[0], scale * init.qd[0]])
    }
}

fn bound(momentum: bool) -> (Binding<Oscillator, Hooke>, Initial) {
    let scene = Oscillator::from_params(&Params::defaults(PARAMS)).unwrap();
    let init = init::resolve(&scene, &[], &[]).unwrap();
    let state = if momentum { "momentum" } else { "velocity" };
    let options = Params::resolve(OPTIONS, &[("state".into(), state.into())], "option").unwrap();
    (Binding::new(scene, options).unwrap(), init)
}

/// `ẏ`, `ÿ`, `y⃛` of `q = A cos ωt + B sin ωt` at `t = 0`, in the state's
/// second component `q̇` (or `p = μ q̇`).
fn closed_form(momentum: bool, q0: f64, qd0: f64) -> [[f64; 2]; 3] {
    let (mu, kappa) = (2.0, 8.0);
    let w2 = kappa / mu;
    let s = if momentum { mu } else { 1.0 };
    // q', q'', q''', q'''' at 0.
    let d = [qd0, -w2 * q0, -w2 * qd0, w2 * w2 * q0];
    [[d[0], s * d[1]], [d[1], s * d[2]], [d[2], s * d[3]]]
}

#[test]
fn rhs_jacobian_and_taylor_coefficients_match_the_closed_form() {
    for momentum in [false, true] {
        let (mut b, init) = bound(momentum);
        let y = b.initial_state(&init).unwrap();
        let (mut yd, mut ydd, mut yddd) = ([0.0; 2], [0.0; 2], [0.0; 2]);
        b.taylor(0.0, &y, &mut yd, &mut ydd, &mut yddd).unwrap();
        let expect = closed_form(momentum, init.q[0], init.qd[0]);
        for (got, want) in [yd, ydd, yddd].iter().zip(expect) {
            for i in 0..2 {
                assert!(
                    (got[i] - want[i]).abs() < 1e-14,
                    "momentum = {momentum}: {got:?} against {want:?}"
                );
            }
        }
        let mut jac = [0.0; 4];
        assert!(b.jacobian(0.0, &y, &mut jac).unwrap());
        let expect = if momentum {
            [0.0, 0.5, -8.0, 0.0]
        } else {
            [0.0, 1.0, -4.0, 0.0]
        };
        assert_eq!(jac, expect, "momentum = {momentum}");
    }
}

/// The hooks, the guard and the observation read the physical `q̇`; where
/// the state does not hold it, it is computed once per state.
#[test]
fn physical_velocities_are_computed_once_per_state() {
    let (mut b, init) = bound(true);
    let mut y = b.initial_state(&init).unwrap();
    let evals = |b: &Binding<Oscillator, Hooke>| {
        b.equations()
            .velocity_evals
            .load(std::sync::atomic::Ordering::Relaxed)
    };
    let before = evals(&b);
    assert!(!b.after_step(0.1, &mut y).unwrap());
    assert_eq!(b.guard(0.1, &y), None);
    let mut obs = Observation::new(1, 1);
    b.observe(0.1, &y, &mut obs).unwrap();
    assert_eq!(evals(&b), before + 1);
    assert_eq!(obs.q, [init.q[0]]);
    assert!((obs.qd[0] - init.qd[0]).abs() < 1e-16);
    assert_eq!(obs.multipliers, [-8.0 * init.q[0]]);
    // Another state: evaluated again.
    y[1] += 1.0;
    b.observe(0.1, &y, &mut obs).unwrap();
    assert_eq!(evals(&b), before + 2);
    assert!((obs.qd[0] - (init.qd[0] + 0.5)).abs() < 1e-15);
    // The diagnostics start from the given velocities.
    assert_eq!(
        b.diagnostics().energy_initial,
        0.5 * 2.0 * 0.09 + 0.5 * 8.0 * 0.25
    );
}

#[test]
fn describe_names_scene_and_formulation() {
    let (b, _) = bound(false);
    let d = b.describe();
    assert_eq!((d.scene.name, d.formulation.name), ("oscillator", "hooke"));
    assert_eq!(d.options.real("singular_tol"), Ok(1e-8));
    assert_eq!(b.scene_params().real("kappa"), Ok(8.0));
}
