//! `pendulum`: a planar pendulum in Cartesian coordinates (holonomic constraint).

use nonholo_core::Error;
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::scene::{ConstraintKind, Named, Scalar, Scene, SceneInfo};

/// Bob at `(x, y)`, `y` up, on a rod of length `l` from the origin.
#[derive(Debug, Clone)]
pub struct Pendulum {
    params: Params,
    pub m: f64,
    pub g: f64,
    pub l: f64,
}

const PARAMS: &[ParamSpec] = &[
    ParamSpec::real(
        "m",
        "kg",
        1.0,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "mass of the bob",
    ),
    crate::GRAVITY,
    ParamSpec::real(
        "l",
        "m",
        1.0,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "length of the rod",
    ),
];

/// Default initial angle from the downward vertical.
const THETA0: f64 = 0.5;

pub const INFO: SceneInfo = SceneInfo {
    name: "pendulum",
    title: "Planar pendulum in Cartesian coordinates",
    description: "A bob on a rigid rod, written in Cartesian coordinates with the holonomic \
                  constraint x² + y² − l² = 0: the classical index-3 test problem, and the check \
                  of the holonomic path of every formulation.",
    coordinates: &[
        Named::new("x", "m", "horizontal position of the bob"),
        Named::new("y", "m", "height of the bob above the pivot"),
    ],
    params: PARAMS,
    structural: &[],
    holonomic: &["x² + y² − l² = 0"],
    nonholonomic: &[],
    constraint_kind: ConstraintKind::Linear,
    nonholonomic_unit: "",
    constraint_singular_set: None,
    embedding: None,
    velocity_chart: &[Named::new(
        "omega",
        "rad/s",
        "angular velocity about the pivot (ẋ = −ω y, ẏ = ω x)",
    )],
    // l sin θ0, −l cos θ0 for l = 1 (see `default_q` for other l).
    default_q: &[0.479_425_538_604_203, -0.877_582_561_890_372_8],
    default_velocity: &[0.0],
    closed_form: None,
    invariants: &[],
    contacts: &[],
};

impl Scene for Pendulum {
    const INFO: &'static SceneInfo = &INFO;

    fn from_params(params: &Params) -> Result<Self, Error> {
        Ok(Pendulum {
            params: params.clone(),
            m: params.real("m")?,
            g: params.real("g")?,
            l: params.real("l")?,
        })
    }

    fn params(&self) -> &Params {
        &self.params
    }

    /// `L = ½m(ẋ² + ẏ²) − m g y`.
    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], qd: &[D]) -> D {
        (qd[0] * qd[0] + qd[1] * qd[1]) * (0.5 * self.m) - q[1] * (self.m * self.g)
    }

    /// `f = x² + y² − l²`.
    fn holonomic<D: Scalar>(&self, _t: D, q: &[D], out: &mut [D]) {
        out[0] = q[0] * q[0] + q[1] * q[1] - self.l * self.l;
    }

    /// The bob at angle 0.5 rad from the downward vertical.
    fn default_q(&self) -> Vec<f64> {
        vec![self.l * THETA0.sin(), -self.l * THETA0.cos()]
    }

    fn velocities_from<D: Scalar>(&self, q: &[D], chart: &[D], qd: &mut [D]) {
        qd[0] = -chart[0] * q[1];
        qd[1] = chart[0] * q[0];
    }

    /// `ω = (x ẏ − y ẋ)/(x² + y²)`.
    fn chart_from(&self, q: &[f64], qd: &[f64], chart: &mut [f64]) -> bool {
        chart[0] = (q[0] * qd[1] - q[1] * qd[0]) / (q[0] * q[0] + q[1] * q[1]);
        true
    }
}
