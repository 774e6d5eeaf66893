//! The sleigh, its initial data, and every formulation at one fixed generic
//! state: what the benchmark, the report binary and the allocation test
//! evaluate.
//!
//! The generic state: sleigh `a = 0.4`, `α = 0.3`, `potential = com`
//! (every term of the equations is live), `q = (0.3, −0.2, 0.2)`, forward
//! speed `u = 2`, turning rate `ω = 0.7`. B and C start on the constraint
//! (C with `λ = 0.5`); the realisations get a small sideways slip
//! `w = g = 0.01` so that their friction / added-mass terms are non-zero
//! (the compliance form with `λ = N w`, its invariant value; `visc`'s
//! adapted form at the same motion, in its own state).

use nonholo_chetaev::Chetaev;
use nonholo_core::integrate::{ImplicitSystem, OdeSystem, SystemError};
use nonholo_core::{Error, Initial, Model, ParamSpec, Params, Scene, init};
use nonholo_embedding::Embedding;
use nonholo_realise::{Mass, Visc, mass, visc};
use nonholo_scenes::Sleigh;
use nonholo_vakonomic::Vakonomic;

use crate::hand::{BodyFrame, BodyVisc, Constants, Realisation, ReducedB, ReducedC};

fn pairs(items: &[(&str, &str)]) -> Vec<(String, String)> {
    items
        .iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect()
}

/// The sleigh with these parameters (the others at their defaults:
/// `m = 1`, `J = 1`, `g = 9.81`).
pub fn sleigh(a: f64, alpha: f64, potential: &str) -> Result<Sleigh, Error> {
    let (a, alpha) = (a.to_string(), alpha.to_string());
    let params = Params::resolve(
        Sleigh::INFO.params,
        &pairs(&[("a", &a), ("alpha", &alpha), ("potential", potential)]),
        "parameter",
    )?;
    Sleigh::from_params(&params)
}

/// Formulation options from `name=value` pairs.
pub fn options(specs: &'static [ParamSpec], given: &[(&str, &str)]) -> Result<Params, Error> {
    Params::resolve(specs, &pairs(given), "option")
}

/// Initial data `φ`, `u`, `ω` at `(x, y) = (0, 0)`, and `λ0` if given.
pub fn initial(
    scene: &Sleigh,
    phi: f64,
    u: f64,
    omega: f64,
    lambda: Option<f64>,
) -> Result<Initial, Error> {
    let (phi, u, omega) = (phi.to_string(), u.to_string(), omega.to_string());
    let mut given = vec![("phi", phi.as_str()), ("u", &u), ("omega", &omega)];
    let lambda_text = lambda.map(|l| l.to_string());
    let extra = match &lambda_text {
        Some(l) => {
            given.push(("lambda", l));
            nonholo_vakonomic::lambda_names(1)
        }
        None => Vec::new(),
    };
    init::resolve(scene, &pairs(&given), &extra)
}

/// The scene of the generic state.
pub fn generic_sleigh() -> Result<Sleigh, Error> {
    sleigh(0.4, 0.3, "com")
}

/// Position of the generic state.
pub const Q: [f64; 3] = [0.3, -0.2, 0.2];
/// Forward speed, turning rate, C's multiplier and the realisations' slip.
pub const U: f64 = 2.0;
pub const OMEGA: f64 = 0.7;
pub const LAMBDA: f64 = 0.5;
pub const SLIP: f64 = 0.01;
/// Gains of the realisations in the benchmark.
pub const K: f64 = 1e4;
pub const N: f64 = 1e4;

/// `(x, y, φ, ẋ, ẏ, φ̇)` for forward speed `u`, slip `w`, turning rate `ω`.
pub fn cartesian(q: [f64; 3], u: f64, w: f64, omega: f64) -> [f64; 6] {
    let (s, c) = q[2].sin_cos();
    [q[0], q[1], q[2], u * c - w * s, u * s + w * c, omega]
}

/// The state of `visc` with `form = adapted` on the sleigh, `(x, y, φ, u,
/// c_ω, w)`, for forward speed `u`, slip `w` and turning rate `ω`: its frame
/// column for `w` is `N = M⁻¹Gᵀ/(G M⁻¹ Gᵀ) = (−sin φ, cos φ, −a/J)`, so
/// `φ̇ = c_ω − a w/J` (checked against the AD form in `tests/hand.rs`).
pub fn adapted_state(c: &Constants, q: [f64; 3], u: f64, w: f64, omega: f64) -> [f64; 6] {
    [q[0], q[1], q[2], u, omega + c.a * w / c.j, w]
}

/// An explicit right-hand side and the state it is evaluated at.
pub struct RhsCase {
    /// Short name (`B`, `visc`, …).
    pub name: &'static str,
    /// What it is, for tables.
    pub what: &'static str,
    pub sys: Box<dyn OdeSystem>,
    pub t: f64,
    pub y: Vec<f64>,
}

impl RhsCase {
    fn new(name: &'static str, what: &'static str, sys: Box<dyn OdeSystem>, y: Vec<f64>) -> Self {
        RhsCase {
            name,
            what,
            sys,
            t: 0.0,
            y,
        }
    }

    pub fn dim(&self) -> usize {
        self.sys.dim()
    }

    /// One evaluation into `dy` (length [`RhsCase::dim`]).
    pub fn eval(&mut self, dy: &mut [f64]) -> Result<(), SystemError> {
        self.sys.rhs(self.t, &self.y, dy)
    }

    /// One Jacobian into `jac` (`dim²`); `Ok(false)` if there is none.
    pub fn jacobian(&mut self, jac: &mut [f64]) -> Result<bool, SystemError> {
        self.sys.jacobian(self.t, &self.y, jac)
    }
}

/// The automatic-differentiation formulations at the generic state, each
/// with its hand-written baseline: `(AD case, baseline case)`.
pub fn rhs_pairs() -> Result<Vec<(RhsCase, RhsCase)>, Error> {
    let s = generic_sleigh()?;
    let c = Constants::of(&s);
    let on = cartesian(Q, U, 0.0, OMEGA);
    let off = cartesian(Q, U, SLIP, OMEGA);
    let (k, n) = (K.to_string(), N.to_string());

    let b = Chetaev::new(s.clone(), Params::defaults(nonholo_chetaev::OPTIONS))?;
    let cc = Vakonomic::new(s.clone(), Params::defaults(nonholo_vakonomic::OPTIONS))?;
    let v = Visc::new(
        s.clone(),
        options(visc::OPTIONS, &[("k", &k), ("form", "cartesian")])?,
    )?;
    let va = Visc::new(
        s.clone(),
        options(visc::OPTIONS, &[("k", &k), ("form", "adapted")])?,
    )?;
    let mc = Mass::new(s.clone(), options(mass::OPTIONS, &[("N", &n)])?)?;
    let md = Mass::new(s, options(mass::OPTIONS, &[("N", &n), ("form", "direct")])?)?;

    let reduced_b = vec![Q[0], Q[1], Q[2], U, OMEGA];
    // μ = λ + m a ω
    let mu = LAMBDA + c.m * c.a * OMEGA;
    let reduced_c = vec![Q[0], Q[1], Q[2], U, OMEGA, mu];
    let mut c_state = on.to_vec();
    c_state.push(LAMBDA);
    let mut compliance = off.to_vec();
    compliance.push(N * SLIP);
    let body = |which, gain| Box::new(BodyFrame { c, which, gain });

    Ok(vec![
        (
            RhsCase::new("B", "B (Chetaev): KKT solve", Box::new(b), on.to_vec()),
            RhsCase::new(
                "B reduced",
                "spec's reduced B (x, y, φ, u, ω)",
                Box::new(ReducedB(c)),
                reduced_b,
            ),
        ),
        (
            RhsCase::new("C", "C (vakonomic): KKT solve", Box::new(cc), c_state),
            RhsCase::new(
                "C reduced",
                "spec's reduced C (x, y, φ, u, ω, μ)",
                Box::new(ReducedC(c)),
                reduced_c.clone(),
            ),
        ),
        (
            RhsCase::new("visc", "visc (k = 1e4)", Box::new(v), off.to_vec()),
            RhsCase::new(
                "visc body",
                "body-frame visc, same state",
                body(Realisation::Visc, K),
                off.to_vec(),
            ),
        ),
        (
            RhsCase::new(
                "visc adapted",
                "visc (k = 1e4), adapted form (q, u, c_ω, w)",
                Box::new(va),
                adapted_state(&c, Q, U, SLIP, OMEGA).to_vec(),
            ),
            RhsCase::new(
                "visc body-frame",
                "body-frame visc in (x, y, φ, u, w, ω), same motion",
                Box::new(BodyVisc { c, k: K }),
                vec![Q[0], Q[1], Q[2], U, SLIP, OMEGA],
            ),
        ),
        (
            RhsCase::new(
                "mass compliance",
                "mass (N = 1e4), compliance",
                Box::new(mc),
                compliance.clone(),
            ),
            RhsCase::new(
                "mass compliance body",
                "body-frame mass, compliance, same state",
                body(Realisation::MassCompliance, N),
                compliance,
            ),
        ),
        (
            RhsCase::new(
                "mass direct",
                "mass (N = 1e4), direct",
                Box::new(md),
                off.to_vec(),
            ),
            RhsCase::new(
                "mass direct body",
                "body-frame mass, direct, same state",
                body(Realisation::MassDirect, N),
                off.to_vec(),
            ),
        ),
    ])
}

/// The contact crate's right-hand sides at the generic sleigh state:
/// `gauss` on the constraint, `friction` sticking there (μ = 1) and
/// slipping off it (lateral velocity `SLIP`, μ = 0.3).
pub fn contact_cases() -> Result<Vec<RhsCase>, Error> {
    use nonholo_contact::friction::{self, Friction};
    use nonholo_contact::gauss::{self, Gauss};
    let s = generic_sleigh()?;
    let on = cartesian(Q, U, 0.0, OMEGA);
    let off = cartesian(Q, U, SLIP, OMEGA);
    let g = Gauss::new(s.clone(), Params::defaults(gauss::OPTIONS))?;
    let mut cases = vec![RhsCase::new(
        "gauss",
        "gauss: quadratic program (Clarabel)",
        Box::new(g),
        on.to_vec(),
    )];
    for (name, what, mu, y) in [
        ("friction stick", "friction, sticking (μ = 1)", "1", on),
        ("friction slip", "friction, slipping (μ = 0.3)", "0.3", off),
    ] {
        let mut f = Friction::new(s.clone(), options(friction::OPTIONS, &[("mu", mu)])?)?;
        let mut init = Initial {
            t0: 0.0,
            q: y[..3].to_vec(),
            qd: y[3..].to_vec(),
            extra: Vec::new(),
        };
        f.make_consistent(&mut init, false)?;
        let y = f.initial_state(&init)?;
        cases.push(RhsCase::new(name, what, Box::new(f), y));
    }
    Ok(cases)
}

/// The spec's reduced C at the state matching C's generic state (the
/// baseline for formulation A, whose motions are C's).
pub fn reduced_c_case() -> Result<RhsCase, Error> {
    let s = generic_sleigh()?;
    let c = Constants::of(&s);
    let mu = LAMBDA + c.m * c.a * OMEGA;
    Ok(RhsCase::new(
        "C reduced",
        "spec's reduced C (x, y, φ, u, ω, μ)",
        Box::new(ReducedC(c)),
        vec![Q[0], Q[1], Q[2], U, OMEGA, mu],
    ))
}

/// Formulation A at consistent data matched with the vakonomic motion
/// through `(q0, q̇0, λ0 = 0.5)` of the generic state: `q̈_I(0)`, `q⃛_I(0)`
/// from C's Taylor coefficients (as the lab does), then A's own
/// `initial_state` and `initial_slope`.
pub struct ResidualCase {
    pub sys: Embedding<Sleigh>,
    pub t: f64,
    pub y: Vec<f64>,
    pub yp: Vec<f64>,
}

impl ResidualCase {
    pub fn dim(&self) -> usize {
        self.y.len()
    }

    /// One residual `F(t, y, y')` into `res`.
    pub fn eval(&mut self, res: &mut [f64]) -> Result<(), SystemError> {
        self.sys
            .implicit_form()
            .residual(self.t, &self.y, &self.yp, res)
    }
}

/// Initial data of A at the generic state (see [`ResidualCase`]).
fn embedding_initial(s: &Sleigh) -> Result<Initial, Error> {
    let mut c = Vakonomic::new(s.clone(), Params::defaults(nonholo_vakonomic::OPTIONS))?;
    let on = cartesian(Q, U, 0.0, OMEGA);
    let mut y = on.to_vec();
    y.push(LAMBDA);
    let (mut yd, mut ydd, mut yddd) = (vec![0.0; 7], vec![0.0; 7], vec![0.0; 7]);
    c.taylor(0.0, &y, &mut yd, &mut ydd, &mut yddd)
        .map_err(|e| Error::numerical("C's Taylor coefficients", e))?;
    let mut names: Vec<nonholo_core::init::ExtraName> = Vec::new();
    let mut given: Vec<(String, String)> = vec![
        ("x".into(), Q[0].to_string()),
        ("y".into(), Q[1].to_string()),
        ("phi".into(), Q[2].to_string()),
        ("u".into(), U.to_string()),
        ("omega".into(), OMEGA.to_string()),
    ];
    // q̈ = ẏ[n..2n], q⃛ = ÿ[n..2n] for the independent coordinates x, y.
    for (i, c) in ["x", "y"].into_iter().enumerate() {
        for (order, value) in [("ddot", yd[3 + i]), ("dddot", ydd[3 + i])] {
            let name = format!("{c}_{order}");
            names.push(nonholo_core::init::ExtraName::new(name.clone(), "", ""));
            given.push((name, value.to_string()));
        }
    }
    // Full precision: `to_string` of an f64 round-trips.
    init::resolve(s, &given, &names)
}

/// Formulation A's residual at consistent data of the generic state.
pub fn residual_case() -> Result<ResidualCase, Error> {
    let s = generic_sleigh()?;
    let init = embedding_initial(&s)?;
    let mut sys = Embedding::new(s, Params::defaults(nonholo_embedding::OPTIONS))?;
    let y = sys.initial_state(&init)?;
    let yp = sys.initial_slope()?;
    Ok(ResidualCase { sys, t: 0.0, y, yp })
}

/// Formulation A's explicit right-hand side (`q⁗` from the derivative
/// array) at the same state as [`residual_case`], solved afresh at every
/// call (see [`Unremembered`]); the array by its traced programs (the
/// default) if `traced`, else by dual passes over the jets.
pub fn embedding_explicit(traced: bool) -> Result<RhsCase, Error> {
    let ResidualCase { sys, y, .. } = residual_case()?;
    let mut inner = sys.into_explicit();
    inner.set_traced(traced);
    Ok(RhsCase::new(
        "A explicit",
        if traced {
            "A's explicit form: derivative array solved for q⁗"
        } else {
            "A's explicit form: derivative array solved for q⁗, dual passes"
        },
        Box::new(Unremembered { inner, flip: false }),
        y,
    ))
}

/// A's explicit form returns its last solve when called again at the same
/// `(t, y)` (the integrators' repeated evaluations cost nothing); timing the
/// same state over and over would time that lookup (21 ns). This wrapper
/// alternates `t` between its value and an adjacent float, so every call is a
/// real solve of the derivative array, warm-started from the previous one
/// at the same state (the sleigh is autonomous): the cheapest real case.
struct Unremembered<S> {
    inner: S,
    flip: bool,
}

impl<S: OdeSystem> OdeSystem for Unremembered<S> {
    fn dim(&self) -> usize {
        self.inner.dim()
    }
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        self.flip = !self.flip;
        // Another float next to t (the next one up for t ≥ 0).
        let t = if self.flip {
            f64::from_bits(t.to_bits() + 1)
        } else {
            t
        };
        self.inner.rhs(t, y, dy)
    }
}

/// B on `sleigh-train` with `n_sleighs` sleighs at its default positions,
/// the lead sleigh at `u = 1`, `ω = 0.3` (the state of `scale-report`).
/// From 20 KKT rows (`N ≥ 4`) B solves its system sparse.
pub fn train_case(n_sleighs: usize) -> Result<RhsCase, Error> {
    let info = nonholo_scenes::trailer::INFO;
    let n = n_sleighs.to_string();
    let train = nonholo_scenes::Train::from_params(&options(info.params, &[("N", &n)])?)?;
    let q = train.default_q();
    let mut qd = vec![0.0; q.len()];
    train.velocities_from(&q, &[1.0, 0.3], &mut qd);
    let b = Chetaev::new(train, Params::defaults(nonholo_chetaev::OPTIONS))?;
    Ok(RhsCase::new(
        "B train",
        "B on sleigh-train",
        Box::new(b),
        [q, qd].concat(),
    ))
}
