//! `rolling-disk`: a vertical disk rolling without slipping on a plane.

use nonholo_core::Error;
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::scene::{
    ClosedFormInfo, ConstraintKind, ContactInfo, EmbeddingInfo, MAX_SINGULAR, Named, Scalar, Scene,
    SceneInfo, atan2_near,
};

/// Contact point `(x, y)`, heading `θ`, rolling angle `ψ`; radius `R`.
#[derive(Debug, Clone)]
pub struct RollingDisk {
    params: Params,
    pub m: f64,
    pub i: f64,
    pub jr: f64,
    pub r: f64,
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
        "I",
        "kg m^2",
        0.25,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "moment of inertia about the vertical diameter (turning, θ)",
    ),
    ParamSpec::real(
        "Jr",
        "kg m^2",
        0.5,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "moment of inertia about the rolling axis (ψ)",
    ),
    ParamSpec::real(
        "R",
        "m",
        1.0,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "radius of the disk",
    ),
];

pub const INFO: SceneInfo = SceneInfo {
    name: "rolling-disk",
    title: "Vertical rolling disk",
    description: "A disk kept vertical, rolling without slipping: contact point (x, y), heading θ, \
                  rolling angle ψ. Under B, θ̈ = ψ̈ = 0; the vakonomic motions reproduce it only \
                  for particular initial multipliers (Fernandez & Bloch). A embeds the heading \
                  θ = atan2(ẏ, ẋ) and the rolling rate ψ̇ = ±|v|/R (ψ is cyclic).",
    coordinates: &[
        Named::new("x", "m", "contact point"),
        Named::new("y", "m", "contact point"),
        Named::new("theta", "rad", "heading of the disk plane from the x axis"),
        Named::new("psi", "rad", "rolling angle"),
    ],
    params: PARAMS,
    structural: &[],
    holonomic: &[],
    nonholonomic: &["ẋ − R ψ̇ cos θ = 0", "ẏ − R ψ̇ sin θ = 0"],
    constraint_kind: ConstraintKind::Linear,
    nonholonomic_unit: "m/s",
    constraint_singular_set: None,
    // θ from the direction of the contact point's velocity, like the
    // sleigh's heading; ψ is cyclic, and the constraint gives its rate.
    embedding: Some(EmbeddingInfo {
        independent: &[0, 1],
        dependent: &[2, 3],
        cyclic: &[3],
        formula: "θ = atan2(ẏ, ẋ), ψ̇ = (ẋ cos θ + ẏ sin θ)/R",
        singular_set: "zero speed ẋ² + ẏ² = 0, where the heading is undefined",
        branch_note: "for the disk this is rolling backwards (ψ̇ < 0), where the map turns the \
                      heading by π",
        undetermined_note: "for the disk this is zero turning rate θ̇ = 0, where the hidden \
                            constraints no longer fix q⃛ (rolling along a straight line, the \
                            rate at which it starts to turn is free)",
    }),
    velocity_chart: &[
        Named::new("omega_theta", "rad/s", "turning rate θ̇"),
        Named::new(
            "omega_psi",
            "rad/s",
            "rolling rate ψ̇ (ẋ = R ψ̇ cos θ, ẏ = R ψ̇ sin θ)",
        ),
    ],
    default_q: &[0.0, 0.0, 0.0, 0.0],
    default_velocity: &[0.5, 1.0],
    closed_form: Some(ClosedFormInfo {
        formulation: "chetaev",
        conditions: "always: θ̇ and ψ̇ constant, the contact point on a circle (a line if θ̇ = 0)",
    }),
    invariants: &[
        Named::new("theta_dot", "rad/s", "turning rate θ̇ (constant under B)"),
        Named::new("psi_dot", "rad/s", "rolling rate ψ̇ (constant under B)"),
    ],
    contacts: &[ContactInfo {
        name: "contact point",
        rows: &[0, 1],
        load: "not modelled: the plane is horizontal and L has no potential, so a friction \
               realisation takes the normal load as given (m g for a disk of weight m g)",
    }],
};

impl Scene for RollingDisk {
    const INFO: &'static SceneInfo = &INFO;

    fn from_params(params: &Params) -> Result<Self, Error> {
        Ok(RollingDisk {
            params: params.clone(),
            m: params.real("m")?,
            i: params.real("I")?,
            jr: params.real("Jr")?,
            r: params.real("R")?,
        })
    }

    fn params(&self) -> &Params {
        &self.params
    }

    /// `L = ½m(ẋ² + ẏ²) + ½I θ̇² + ½Jr ψ̇²`.
    fn lagrangian<D: Scalar>(&self, _t: D, _q: &[D], qd: &[D]) -> D {
        (qd[0] * qd[0] + qd[1] * qd[1]) * (0.5 * self.m)
            + qd[2] * qd[2] * (0.5 * self.i)
            + qd[3] * qd[3] * (0.5 * self.jr)
    }

    /// `ẋ − R ψ̇ cos θ`, `ẏ − R ψ̇ sin θ`.
    fn nonholonomic<D: Scalar>(&self, _t: D, q: &[D], qd: &[D], out: &mut [D]) {
        let (s, c) = q[2].sin_cos();
        out[0] = qd[0] - qd[3] * c * self.r;
        out[1] = qd[1] - qd[3] * s * self.r;
    }

    /// `θ = atan2(ẏ, ẋ)` on the branch nearest to `near[0]` (its principal
    /// branch without `near`), and the rate of the cyclic `ψ` from the
    /// constraint, `ψ̇ = (ẋ cos θ + ẏ sin θ)/R`: `|v|/R` on the principal
    /// branch, the signed speed over `R` where the heading is continued
    /// through a reversal.
    fn embedding<D: Scalar>(
        &self,
        _t: D,
        _q_ind: &[D],
        qd_ind: &[D],
        near: &[f64],
        q_dep: &mut [D],
    ) {
        let theta = atan2_near(qd_ind[1], qd_ind[0], near.first().copied());
        let (s, c) = theta.sin_cos();
        q_dep[0] = theta;
        q_dep[1] = (qd_ind[0] * c + qd_ind[1] * s) / self.r;
    }

    /// The heading's defining equation, the combination of the two rolling
    /// constraints free of `ψ̇`: `−sin θ g₁ + cos θ g₂ = ẏ cos θ − ẋ sin θ = 0`
    /// (both branches of the heading satisfy it; smooth at zero speed); and
    /// the rolling rate at the given heading, `ψ̇ = (ẋ cos θ + ẏ sin θ)/R`
    /// (the signed speed over `R`, smooth through a reversal).
    fn embedding_implicit<D: Scalar>(
        &self,
        _t: D,
        _q_ind: &[D],
        qd_ind: &[D],
        q_dep: &[D],
        out: &mut [D],
    ) -> bool {
        let (s, c) = q_dep[0].sin_cos();
        out[0] = qd_ind[1] * c - qd_ind[0] * s;
        out[1] = (qd_ind[0] * c + qd_ind[1] * s) / self.r;
        true
    }

    /// The velocity `(ẋ, ẏ)`: the heading has no value at zero speed.
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
        let (s, c) = q[2].sin_cos();
        qd[0] = chart[1] * c * self.r;
        qd[1] = chart[1] * s * self.r;
        qd[2] = chart[0];
        qd[3] = chart[1];
    }

    /// `(θ̇, ψ̇)`.
    fn chart_from(&self, _q: &[f64], qd: &[f64], chart: &mut [f64]) -> bool {
        chart[0] = qd[2];
        chart[1] = qd[3];
        true
    }

    fn closed_form(
        &self,
        q0: &[f64],
        qd0: &[f64],
        t: f64,
        q: &mut [f64],
        qd: &mut [f64],
    ) -> Result<(), String> {
        let (wt, wp) = (qd0[2], qd0[3]);
        let th = q0[2] + wt * t;
        let (s, c) = th.sin_cos();
        let (s0, c0) = q0[2].sin_cos();
        let v = self.r * wp;
        if wt == 0.0 {
            q[0] = q0[0] + v * c0 * t;
            q[1] = q0[1] + v * s0 * t;
        } else {
            q[0] = q0[0] + v / wt * (s - s0);
            q[1] = q0[1] - v / wt * (c - c0);
        }
        q[2] = th;
        q[3] = q0[3] + wp * t;
        qd.copy_from_slice(&[v * c, v * s, wt, wp]);
        Ok(())
    }

    fn invariant(&self, i: usize, _t: f64, _q: &[f64], qd: &[f64]) -> f64 {
        qd[2 + i]
    }
}
