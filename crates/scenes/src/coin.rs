//! `coin-incline`: a thin disk rolling without slipping on an inclined
//! plane, free to lean and turn (Lemos 2021, arXiv 2105.02113, shows that
//! no non-trivial motion of it under the nonholonomic equations is
//! vakonomic).
//!
//! Axes of the plane: `x` down the slope, `y` across it, `z` into the plane
//! (so that gravity is `g (sin α, 0, cos α)`). Coordinates: contact point
//! `(x, y)`, heading `ψ` (the direction of rolling, from the `x` axis),
//! lean `θ` (about the heading; 0 upright), spin `φ` of the disk about its
//! axle. Disk frame `Rz(ψ) Rx(θ)`, axle its `y` axis, centre `R` from the
//! contact towards the top of the disk.

use nonholo_core::Error;
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::scene::{ConstraintKind, Named, Scalar, Scene, SceneInfo};

use crate::rigid::{
    V, add, c, column, cross, dot, mm, mv, rot_x, rot_z, scale, sub, vc, wheel_spin,
};

/// The coin with its parameters.
#[derive(Debug, Clone)]
pub struct Coin {
    params: Params,
    pub m: f64,
    pub r: f64,
    /// Moments of inertia about a diameter and about the axle.
    pub i_d: f64,
    pub i_a: f64,
    pub g: f64,
    pub alpha: f64,
    /// Gravity in slope axes, `g (sin α, 0, cos α)`, computed once.
    gravity: [f64; 3],
}

const PARAMS: &[ParamSpec] = &[
    ParamSpec::real(
        "m",
        "kg",
        1.0,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "mass of the disk",
    ),
    ParamSpec::real(
        "R",
        "m",
        0.5,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "radius of the disk",
    ),
    ParamSpec::real(
        "Id",
        "kg m^2",
        0.0625,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "moment of inertia about a diameter (a thin uniform disk: m R²/4)",
    ),
    ParamSpec::real(
        "Ia",
        "kg m^2",
        0.125,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "moment of inertia about the axle (a thin uniform disk: m R²/2)",
    ),
    crate::GRAVITY,
    ParamSpec::real(
        "alpha",
        "rad",
        0.2,
        Bound::Inclusive(0.0),
        Bound::Exclusive(std::f64::consts::FRAC_PI_2),
        "slope of the plane",
    ),
];

pub const INFO: SceneInfo = SceneInfo {
    name: "coin-incline",
    title: "Coin rolling on an inclined plane",
    description: "A thin disk rolling without slipping on a plane of slope α, free to lean and \
                  turn: contact point (x, y) with x down the slope, heading ψ, lean θ, spin φ. \
                  Lemos (2021): its only vakonomic nonholonomic motions are trivial.",
    coordinates: &[
        Named::new("x", "m", "contact point, down the slope"),
        Named::new("y", "m", "contact point, across the slope"),
        Named::new(
            "psi",
            "rad",
            "heading: direction of rolling from the x axis",
        ),
        Named::new("theta", "rad", "lean about the heading (0 upright)"),
        Named::new("phi", "rad", "spin of the disk about its axle"),
    ],
    params: PARAMS,
    structural: &[],
    holonomic: &[],
    nonholonomic: &["ẋ + R φ̇ cos ψ = 0", "ẏ + R φ̇ sin ψ = 0"],
    constraint_kind: ConstraintKind::Linear,
    nonholonomic_unit: "m/s",
    constraint_singular_set: None,
    embedding: None,
    velocity_chart: &[
        Named::new(
            "v",
            "m/s",
            "speed of the contact point along the heading, −R φ̇",
        ),
        Named::new("turn_rate", "rad/s", "heading rate ψ̇"),
        Named::new("lean_rate", "rad/s", "lean rate θ̇"),
    ],
    default_q: &[0.0, 0.0, 0.5, 0.0, 0.0],
    default_velocity: &[2.0, 0.3, 0.0],
    closed_form: None,
    invariants: &[],
    contacts: &[],
};

/// The disk's position and motion at `(q, q̇)`.
struct Motion<D> {
    /// Contact point, centre, axle.
    p: V<D>,
    centre: V<D>,
    axle: V<D>,
    /// Angular velocity of the disk, velocity of its centre.
    w: V<D>,
    v_c: V<D>,
}

impl Coin {
    /// Disk frame `Rz(ψ) Rx(θ)`; `ω = ψ̇ n + θ̇ e_heading + φ̇ a`, and the
    /// centre moving with the frame (the spin does not move it).
    fn motion<D: Scalar>(&self, q: &[D], qd: &[D]) -> Motion<D> {
        let z = c::<D>(0.0);
        let frame = mm(&rot_z(q[2]), &rot_x(q[3]));
        let p = [q[0], q[1], z];
        let centre = add(p, mv(&frame, vc([0.0, 0.0, -self.r])));
        let w_frame = add([z, z, qd[2]], scale(column(&frame, 0), qd[3]));
        let axle = column(&frame, 1);
        Motion {
            p,
            centre,
            axle,
            w: add(w_frame, scale(axle, qd[4])),
            v_c: add([qd[0], qd[1], z], cross(w_frame, sub(centre, p))),
        }
    }
}

impl Scene for Coin {
    const INFO: &'static SceneInfo = &INFO;

    fn from_params(params: &Params) -> Result<Self, Error> {
        Ok(Coin {
            params: params.clone(),
            m: params.real("m")?,
            r: params.real("R")?,
            i_d: params.real("Id")?,
            i_a: params.real("Ia")?,
            g: params.real("g")?,
            alpha: params.real("alpha")?,
            gravity: {
                let (g, alpha) = (params.real("g")?, params.real("alpha")?);
                [g * alpha.sin(), 0.0, g * alpha.cos()]
            },
        })
    }

    fn params(&self) -> &Params {
        &self.params
    }

    /// `½ m |v_C|² + ½ (Id |ω⊥|² + Ia (ω·a)²) + m g·r_C`, with `ω = ψ̇ n +
    /// θ̇ e_heading + φ̇ a`.
    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], qd: &[D]) -> D {
        let m = self.motion(q, qd);
        let gravity = vc(self.gravity);
        dot(m.v_c, m.v_c) * (0.5 * self.m)
            + wheel_spin(self.i_d, self.i_a, m.w, m.axle)
            + dot(gravity, m.centre) * self.m
    }

    /// The velocity of the disk's material point at the contact, in the
    /// plane.
    fn nonholonomic<D: Scalar>(&self, _t: D, q: &[D], qd: &[D], out: &mut [D]) {
        let m = self.motion(q, qd);
        let slip = add(m.v_c, cross(m.w, sub(m.p, m.centre)));
        out[0] = slip[0];
        out[1] = slip[1];
    }

    fn velocities_from<D: Scalar>(&self, q: &[D], chart: &[D], qd: &mut [D]) {
        let (v, turn, lean) = (chart[0], chart[1], chart[2]);
        qd[0] = v * q[2].cos();
        qd[1] = v * q[2].sin();
        qd[2] = turn;
        qd[3] = lean;
        qd[4] = -v / self.r;
    }

    fn chart_from(&self, _q: &[f64], qd: &[f64], chart: &mut [f64]) -> bool {
        chart[0] = -self.r * qd[4];
        chart[1] = qd[2];
        chart[2] = qd[3];
        true
    }
}
