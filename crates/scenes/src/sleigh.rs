//! `sleigh-incline`: the Chaplygin sleigh on an inclined plane (the paper's
//! example, after Neimark & Fufaev, *Dynamics of Nonholonomic Systems*, 1972).

use std::f64::consts::FRAC_PI_2;

use nonholo_core::Error;
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::scene::{
    ClosedFormInfo, ConstraintKind, ContactInfo, EmbeddingInfo, MAX_SINGULAR, Named, Scalar, Scene,
    SceneInfo, atan2_near,
};

/// Which potential energy the Lagrangian carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Potential {
    /// `−m g x sin α` at the blade only: the paper's eq. (22).
    Paper,
    /// Gravity acting at the centre of mass, `a` ahead of the blade:
    /// eq. (22) plus `m g a sin α cos φ`.
    Com,
}

/// The sleigh: blade contact point `(x, y)` on the plane (`x` down the
/// slope), heading `φ` from the x axis, centre of mass `a` ahead of the blade.
#[derive(Debug, Clone)]
pub struct Sleigh {
    params: Params,
    pub m: f64,
    pub j: f64,
    pub a: f64,
    pub g: f64,
    pub alpha: f64,
    pub potential: Potential,
    /// `m g sin α`, computed once (the Lagrangian is evaluated in every
    /// derivative pass).
    mg_sin_alpha: f64,
}

const PARAMS: &[ParamSpec] = &[
    ParamSpec::real(
        "m",
        "kg",
        1.0,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "mass of the sleigh",
    ),
    ParamSpec::real(
        "J",
        "m^2",
        1.0,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "squared radius of gyration about the blade contact point (physically ρ² + a², so J > a²)",
    ),
    ParamSpec::real(
        "a",
        "m",
        0.4,
        Bound::Unbounded,
        Bound::Unbounded,
        "distance of the centre of mass ahead of the blade",
    ),
    crate::GRAVITY,
    ParamSpec::real(
        "alpha",
        "rad",
        0.3,
        Bound::Inclusive(0.0),
        Bound::Exclusive(FRAC_PI_2),
        "slope of the plane",
    ),
    ParamSpec::choice(
        "potential",
        &["paper", "com"],
        "paper: −m g x sin α as in eq. (22); com: gravity at the centre of mass, adds m g a sin α cos φ",
    ),
];

pub const INFO: SceneInfo = SceneInfo {
    name: "sleigh-incline",
    title: "Chaplygin sleigh on an inclined plane",
    description: "A sleigh on a plane of slope α with a knife-edge blade at (x, y), heading φ, \
                  centre of mass a ahead of the blade; the blade cannot slide sideways. \
                  The seed paper's example (eq. 20–26).",
    coordinates: &[
        Named::new("x", "m", "blade contact point, down the slope"),
        Named::new("y", "m", "blade contact point, across the slope"),
        Named::new("phi", "rad", "heading from the x axis"),
    ],
    params: PARAMS,
    structural: &[],
    holonomic: &[],
    nonholonomic: &["ẏ cos φ − ẋ sin φ = 0"],
    constraint_kind: ConstraintKind::Linear,
    nonholonomic_unit: "m/s",
    constraint_singular_set: None,
    embedding: Some(EmbeddingInfo {
        independent: &[0, 1],
        dependent: &[2],
        cyclic: &[],
        formula: "φ = atan2(ẏ, ẋ) (eq. 21, in the form regular for ẋ < 0)",
        singular_set: "zero speed ẋ² + ẏ² = 0, where the heading is undefined",
        branch_note: "for the sleigh this is backward motion, where the map turns the heading by π",
        undetermined_note: "for the sleigh this is zero turning rate ω = 0, where the first hidden \
                            constraint g sin α cos φ − u̇ − J ω φ̈/u = 0 no longer involves q⃛ (it \
                            fixes u̇) and φ̈ — the vakonomic λ(0) — is free",
    }),
    velocity_chart: &[
        Named::new(
            "u",
            "m/s",
            "forward speed along the heading (ẋ = u cos φ, ẏ = u sin φ)",
        ),
        Named::new("omega", "rad/s", "turning rate φ̇"),
    ],
    default_q: &[0.0, 0.0, 0.2],
    default_velocity: &[2.0, 0.7],
    closed_form: Some(ClosedFormInfo {
        formulation: "chetaev",
        conditions: "a = 0 and ω0 ≠ 0 (either potential), or a horizontal plane (g sin α = 0, any a)",
    }),
    invariants: &[],
    contacts: &[ContactInfo {
        name: "blade",
        rows: &[0],
        load: "m g cos α: the blade carries the whole normal component of the weight (any other \
               support is frictionless and unloaded)",
    }],
};

impl Sleigh {
    /// The horizontal sleigh's motion (see [`Scene::closed_form`]): `u̇ = a ω²`,
    /// `J ω̇ = −a u ω`, energy `½ m (u² + J ω²)` conserved; called with
    /// `a ≠ 0` or `ω0 = 0`.
    fn horizontal(&self, q0: &[f64], qd0: &[f64], t: f64, q: &mut [f64], qd: &mut [f64]) {
        let (a, j) = (self.a, self.j);
        let phi0 = q0[2];
        let (u0, w0) = (qd0[0] * phi0.cos() + qd0[1] * phi0.sin(), qd0[2]);
        if w0 == 0.0 {
            q[0] = q0[0] + u0 * phi0.cos() * t;
            q[1] = q0[1] + u0 * phi0.sin() * t;
            q[2] = phi0;
            qd[0] = u0 * phi0.cos();
            qd[1] = u0 * phi0.sin();
            qd[2] = 0.0;
            return;
        }
        let v = (u0 * u0 + j * w0 * w0).sqrt();
        let sign = w0.signum();
        let c = (u0 / (j.sqrt() * w0.abs())).asinh();
        let gd = |s: f64| s.sinh().atan();
        let phi_at = |s: f64| phi0 + sign * (j.sqrt() / a) * (gd(s) - gd(c));
        let s_t = a * v * t / j + c;
        // x, y: (J/a) ∫ tanh σ (cos φ, sin φ) dσ from c to s(t), by 16-point
        // Gauss–Legendre panels no wider than 1/4 of a turn of φ's fastest
        // rate over |σ| ≤ 36; beyond, sech σ < 5e-16 and φ is constant to
        // rounding, so the rest is (ln cosh) times a fixed direction.
        const FAR: f64 = 36.0;
        static RULE: std::sync::OnceLock<(Vec<f64>, Vec<f64>)> = std::sync::OnceLock::new();
        let (nodes, weights) = RULE.get_or_init(|| nonholo_core::quadrature::gauss_legendre(16));
        let (lo, hi) = (c.clamp(-FAR, FAR), s_t.clamp(-FAR, FAR));
        let rate = (j.sqrt() / a.abs()).max(1.0);
        let panels = (((hi - lo).abs() * rate * 4.0).ceil() as usize).max(1);
        let h = (hi - lo) / panels as f64;
        let (mut ix, mut iy) = (0.0, 0.0);
        for p in 0..panels {
            let mid = lo + (p as f64 + 0.5) * h;
            for (x, w) in nodes.iter().zip(weights) {
                let sigma = mid + 0.5 * h * x;
                let (sp, cp) = phi_at(sigma).sin_cos();
                let f = sigma.tanh() * 0.5 * h * w;
                ix += f * cp;
                iy += f * sp;
            }
        }
        // ∫ tanh = ln cosh, stable for large arguments.
        let ln_cosh = |x: f64| x.abs() + (-2.0 * x.abs()).exp().ln_1p() - std::f64::consts::LN_2;
        for (from, to) in [(c, lo), (hi, s_t)] {
            if from != to {
                let (sp, cp) = phi_at(to).sin_cos();
                let area = ln_cosh(to) - ln_cosh(from);
                ix += area * cp;
                iy += area * sp;
            }
        }
        let phi = phi_at(s_t);
        let u = v * s_t.tanh();
        q[0] = q0[0] + j / a * ix;
        q[1] = q0[1] + j / a * iy;
        q[2] = phi;
        qd[0] = u * phi.cos();
        qd[1] = u * phi.sin();
        qd[2] = sign * v / j.sqrt() / s_t.cosh();
    }
}

impl Scene for Sleigh {
    const INFO: &'static SceneInfo = &INFO;

    fn from_params(params: &Params) -> Result<Self, Error> {
        let (j, a) = (params.real("J")?, params.real("a")?);
        if j <= a * a {
            return Err(Error::InconsistentParams {
                requirement: format!("J > a² = {}", nonholo_core::num(a * a)),
                values: vec![("J".into(), j), ("a".into(), a)],
                why: "J is the squared radius of gyration about the blade, ρ² + a², and the mass \
                      matrix has determinant m³(J − a²)"
                    .into(),
            });
        }
        Ok(Sleigh {
            params: params.clone(),
            m: params.real("m")?,
            j,
            a,
            g: params.real("g")?,
            alpha: params.real("alpha")?,
            mg_sin_alpha: params.real("m")? * params.real("g")? * params.real("alpha")?.sin(),
            potential: match params.choice("potential")? {
                "com" => Potential::Com,
                _ => Potential::Paper,
            },
        })
    }

    fn params(&self) -> &Params {
        &self.params
    }

    /// `m g cos α` on the blade.
    fn normal_load(&self, _contact: usize) -> Option<f64> {
        Some(self.m * self.g * self.alpha.cos())
    }

    /// Eq. (22): `L = ½m[ẋ² + ẏ² + Jφ̇² + 2aφ̇(ẏ cos φ − ẋ sin φ)] + m g x sin α`,
    /// plus `m g a sin α cos φ` with `potential = com`.
    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], qd: &[D]) -> D {
        let (x, phi) = (q[0], q[2]);
        let (xd, yd, phid) = (qd[0], qd[1], qd[2]);
        let (s, c) = phi.sin_cos();
        let kinetic =
            (xd * xd + yd * yd + phid * phid * self.j + phid * (yd * c - xd * s) * (2.0 * self.a))
                * (0.5 * self.m);
        let mg_sin = self.mg_sin_alpha;
        let potential = match self.potential {
            Potential::Paper => x * mg_sin,
            Potential::Com => x * mg_sin + c * (mg_sin * self.a),
        };
        kinetic + potential
    }

    /// Eq. (20) in a form regular at φ = π/2: `g = ẏ cos φ − ẋ sin φ`.
    fn nonholonomic<D: Scalar>(&self, _t: D, q: &[D], qd: &[D], out: &mut [D]) {
        let (s, c) = q[2].sin_cos();
        out[0] = qd[1] * c - qd[0] * s;
    }

    /// Eq. (21) with the quadrant-correct arctangent: `φ = atan2(ẏ, ẋ)`
    /// (evaluated so that its derivatives stay accurate at every heading,
    /// see [`nonholo_core::scene::atan2`]).
    ///
    /// The branches of `arctan(ẏ/ẋ)` differ by multiples of π: with `near`
    /// the one nearest to `near[0]` (continuing the heading through a
    /// reversal, where `atan2` turns it by π), else `atan2`'s.
    fn embedding<D: Scalar>(
        &self,
        _t: D,
        _q_ind: &[D],
        qd_ind: &[D],
        near: &[f64],
        q_dep: &mut [D],
    ) {
        q_dep[0] = atan2_near(qd_ind[1], qd_ind[0], near.first().copied());
    }

    /// The map's defining equation: the blade constraint itself,
    /// `ẏ cos φ − ẋ sin φ = 0`, which both branches `atan2(ẏ, ẋ)` and
    /// `atan2(ẏ, ẋ) + π` satisfy and which stays smooth at zero speed.
    fn embedding_implicit<D: Scalar>(
        &self,
        t: D,
        q_ind: &[D],
        qd_ind: &[D],
        q_dep: &[D],
        out: &mut [D],
    ) -> bool {
        let q = [q_ind[0], q_ind[1], q_dep[0]];
        let qd = [qd_ind[0], qd_ind[1], D::from(0.0)];
        self.nonholonomic(t, &q, &qd, out);
        true
    }

    /// The velocity `(ẋ, ẏ)`: atan2 has no value at zero speed.
    fn embedding_singularity(
        &self,
        _t: f64,
        _q_ind: &[f64],
        qd_ind: &[f64],
        r: &mut [f64; MAX_SINGULAR],
    ) -> usize {
        r[0] = qd_ind[0];
        r[1] = qd_ind[1];
        2
    }

    fn velocities_from<D: Scalar>(&self, q: &[D], chart: &[D], qd: &mut [D]) {
        let (u, omega) = (chart[0], chart[1]);
        let (s, c) = q[2].sin_cos();
        qd[0] = u * c;
        qd[1] = u * s;
        qd[2] = omega;
    }

    /// `u = ẋ cos φ + ẏ sin φ` (signed), `ω = φ̇`.
    fn chart_from(&self, q: &[f64], qd: &[f64], chart: &mut [f64]) -> bool {
        let (s, c) = q[2].sin_cos();
        chart[0] = qd[0] * c + qd[1] * s;
        chart[1] = qd[2];
        true
    }

    /// Two closed forms (docs/scenes.md, docs/stability.md):
    ///
    /// * `a = 0`, `ω0 ≠ 0` (the spec's): `ω = ω0`, `φ = φ0 + ω0 t`,
    ///   `u = C + K sin φ` with `K = g sin α/ω0`, `C = u0 − K sin φ0`;
    /// * a horizontal plane (`g sin α = 0`), any `a ≠ 0`: with
    ///   `V² = u0² + J ω0²` and `sinh c = u0/(√J |ω0|)`,
    ///   `u = V tanh s`, `ω = sgn(ω0) (V/√J) sech s`, `s = a V t/J + c`,
    ///   `φ = φ0 + sgn(ω0) (√J/a) (gd s − gd c)` (`gd s = atan(sinh s)`);
    ///   `x`, `y` by Gauss–Legendre quadrature of `u (cos φ, sin φ)` in `s`
    ///   (to rounding). With `ω0 = 0` the sleigh goes straight at `u0`.
    fn closed_form(
        &self,
        q0: &[f64],
        qd0: &[f64],
        t: f64,
        q: &mut [f64],
        qd: &mut [f64],
    ) -> Result<(), String> {
        let level = self.g * self.alpha.sin() == 0.0;
        if self.a != 0.0 || (level && qd0[2] == 0.0) {
            if !level {
                return Err(format!(
                    "the closed forms need a = 0 or a horizontal plane (a = {}, g sin α = {})",
                    self.a,
                    self.g * self.alpha.sin()
                ));
            }
            self.horizontal(q0, qd0, t, q, qd);
            return Ok(());
        }
        let (x0, y0, phi0) = (q0[0], q0[1], q0[2]);
        let omega0 = qd0[2];
        if omega0 == 0.0 {
            return Err("the closed form needs ω0 ≠ 0".to_string());
        }
        let u0 = qd0[0] * phi0.cos() + qd0[1] * phi0.sin();
        let k = self.g * self.alpha.sin() / omega0;
        let c = u0 - k * phi0.sin();
        let phi = phi0 + omega0 * t;
        let (s, co) = phi.sin_cos();
        let (s0, c0) = phi0.sin_cos();
        q[0] = x0 + (c * (s - s0) + 0.5 * k * (s * s - s0 * s0)) / omega0;
        q[1] = y0
            + (-c * (co - c0)
                + k * (0.5 * (phi - phi0) - 0.25 * ((2.0 * phi).sin() - (2.0 * phi0).sin())))
                / omega0;
        q[2] = phi;
        let u = c + k * s;
        qd[0] = u * co;
        qd[1] = u * s;
        qd[2] = omega0;
        Ok(())
    }
}
