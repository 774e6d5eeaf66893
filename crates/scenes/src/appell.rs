//! `appell-hamel`: the Appell–Hamel example, a constraint nonlinear in the velocities.

use nonholo_core::Error;
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::scene::{
    ClosedFormInfo, ConstraintKind, MAX_SINGULAR, Named, Scalar, Scene, SceneInfo,
};

/// A weight at height `z` coupled to a wheel at `(x, y)`: `ż + c √(ẋ² + ẏ²) = 0`.
#[derive(Debug, Clone)]
pub struct AppellHamel {
    params: Params,
    pub m: f64,
    pub g: f64,
    pub c: f64,
}

const PARAMS: &[ParamSpec] = &[
    ParamSpec::real(
        "m",
        "kg",
        1.0,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "mass",
    ),
    crate::GRAVITY,
    ParamSpec::real(
        "c",
        "",
        0.5,
        Bound::Unbounded,
        Bound::Unbounded,
        "signed ratio of radii in g = ż + c √(ẋ² + ẏ²): c > 0 the weight descends as the wheel rolls, \
         c < 0 it climbs (other authors use the reciprocal ratio, or square the constraint)",
    ),
];

pub const INFO: SceneInfo = SceneInfo {
    name: "appell-hamel",
    title: "Appell–Hamel (nonlinear constraint)",
    description: "A particle (x, y, z) under gravity with ż = −c √(ẋ² + ẏ²): Appell's weight on a \
                  thread wound on the axle of a rolling wheel. Nonlinear in the velocities; not \
                  differentiable at zero horizontal speed, which c < 0 reaches in finite time.",
    coordinates: &[
        Named::new("x", "m", "horizontal position"),
        Named::new("y", "m", "horizontal position"),
        Named::new("z", "m", "height of the weight"),
    ],
    params: PARAMS,
    structural: &[],
    holonomic: &[],
    nonholonomic: &["ż + c √(ẋ² + ẏ²) = 0"],
    constraint_kind: ConstraintKind::Nonlinear,
    nonholonomic_unit: "m/s",
    constraint_singular_set: Some(
        "zero horizontal speed ρ = √(ẋ² + ẏ²) = 0, where the constraint is not differentiable",
    ),
    embedding: None,
    velocity_chart: &[
        Named::new(
            "rho",
            "m/s",
            "horizontal speed ρ = √(ẋ² + ẏ²) (then ż = −c ρ)",
        ),
        Named::new(
            "beta",
            "rad",
            "direction of the horizontal velocity from the x axis",
        ),
    ],
    default_q: &[0.0, 0.0, 0.0],
    default_velocity: &[1.0, 0.0],
    closed_form: Some(ClosedFormInfo {
        formulation: "chetaev",
        conditions: "ρ0 > 0, up to the stop t* = ρ0 (1 + c²)/(|c| g) when c < 0",
    }),
    invariants: &[Named::new(
        "heading",
        "rad",
        "direction atan2(ẏ, ẋ) of the horizontal velocity (constant under B)",
    )],
    contacts: &[],
};

impl AppellHamel {
    /// Horizontal acceleration `ρ̇ = c g/(1 + c²)` under B.
    pub fn rho_dot(&self) -> f64 {
        self.c * self.g / (1.0 + self.c * self.c)
    }
}

impl Scene for AppellHamel {
    const INFO: &'static SceneInfo = &INFO;

    fn from_params(params: &Params) -> Result<Self, Error> {
        Ok(AppellHamel {
            params: params.clone(),
            m: params.real("m")?,
            g: params.real("g")?,
            c: params.real("c")?,
        })
    }

    fn params(&self) -> &Params {
        &self.params
    }

    /// `L = ½m(ẋ² + ẏ² + ż²) − m g z`.
    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], qd: &[D]) -> D {
        (qd[0] * qd[0] + qd[1] * qd[1] + qd[2] * qd[2]) * (0.5 * self.m) - q[2] * (self.m * self.g)
    }

    /// `g = ż + c √(ẋ² + ẏ²)`; for `c = 0` just `ż` (the square root's
    /// derivatives are not defined at zero horizontal speed, and `0 · NaN`
    /// would carry that into a constraint that is regular there).
    fn nonholonomic<D: Scalar>(&self, _t: D, _q: &[D], qd: &[D], out: &mut [D]) {
        out[0] = if self.c == 0.0 {
            qd[2]
        } else {
            qd[2] + (qd[0] * qd[0] + qd[1] * qd[1]).sqrt() * self.c
        };
    }

    /// The horizontal velocity `(ẋ, ẏ)`: the constraint is not differentiable
    /// where it vanishes (unless `c = 0`, when the constraint is `ż = 0`).
    fn constraint_singularity(
        &self,
        _t: f64,
        _q: &[f64],
        qd: &[f64],
        r: &mut [f64; MAX_SINGULAR],
    ) -> usize {
        if self.c == 0.0 {
            return 0;
        }
        r[0] = qd[0];
        r[1] = qd[1];
        2
    }

    /// Nonlinear in the chart `(ρ, β)` (as the constraint is in `q̇`).
    fn velocities_from<D: Scalar>(&self, _q: &[D], chart: &[D], qd: &mut [D]) {
        let (rho, beta) = (chart[0], chart[1]);
        qd[0] = rho * beta.cos();
        qd[1] = rho * beta.sin();
        qd[2] = rho * (-self.c);
    }

    /// `ρ = √(ẋ² + ẏ²)`, `β = atan2(ẏ, ẋ)`.
    fn chart_from(&self, _q: &[f64], qd: &[f64], chart: &mut [f64]) -> bool {
        chart[0] = qd[0].hypot(qd[1]);
        chart[1] = qd[1].atan2(qd[0]);
        true
    }

    /// Under B the horizontal path is a straight line with `ρ̇ = c g/(1 + c²)`
    /// and `ż = −c ρ`.
    fn closed_form(
        &self,
        q0: &[f64],
        qd0: &[f64],
        t: f64,
        q: &mut [f64],
        qd: &mut [f64],
    ) -> Result<(), String> {
        let rho0 = qd0[0].hypot(qd0[1]);
        if rho0 == 0.0 {
            return Err("the closed form needs a nonzero initial horizontal speed".to_string());
        }
        let (cb, sb) = (qd0[0] / rho0, qd0[1] / rho0);
        let a = self.rho_dot();
        let rho = rho0 + a * t;
        if rho < 0.0 {
            return Err(format!(
                "t = {t} is past the stop at t* = {} where the horizontal speed vanishes",
                -rho0 / a
            ));
        }
        let dist = rho0 * t + 0.5 * a * t * t;
        q[0] = q0[0] + cb * dist;
        q[1] = q0[1] + sb * dist;
        q[2] = q0[2] - self.c * dist;
        qd[0] = cb * rho;
        qd[1] = sb * rho;
        qd[2] = -self.c * rho;
        Ok(())
    }

    fn invariant(&self, _i: usize, _t: f64, _q: &[f64], qd: &[f64]) -> f64 {
        qd[1].atan2(qd[0])
    }
}
