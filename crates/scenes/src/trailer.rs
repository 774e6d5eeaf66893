//! `sleigh-train`: `N` Chaplygin sleighs hitched in a line on an inclined
//! plane (an N-trailer: the lead sleigh and `N − 1` trailers), the scene
//! whose size is a parameter.
//!
//! Sleigh `i` (`i = 1 … N`, sleigh 1 leads) has its blade at `(xᵢ, yᵢ)`,
//! heading `φᵢ`, its centre of mass `a` ahead of the blade, and the
//! Lagrangian of `sleigh-incline` with gravity at the centre of mass. Its
//! blade cannot slide sideways (one nonholonomic constraint each). Sleigh
//! `i + 1` is pulled at its drawbar end, `l` ahead of its blade, by a pin at
//! `h` behind the blade of sleigh `i` (two holonomic constraints per hitch).
//! The train has `3N` coordinates, `N` nonholonomic and `2(N − 1)`
//! holonomic constraints, and two degrees of freedom whatever `N`: the lead
//! sleigh's forward speed and turning rate. With `N = 1` it is
//! `sleigh-incline` with `potential = com`.
//!
//! It is an n-trailer of the kind Bravo-Doddoli & García-Naranjo (2015,
//! *The dynamics of an articulated n-trailer vehicle*, Regular and Chaotic
//! Dynamics 20, 497–517) study, with every body a Chaplygin sleigh of the
//! same parameters.
//!
//! Every constraint couples at most two neighbouring sleighs, so `M`, `G`
//! and `F` are block-banded: the scene exists to measure how the cost of the
//! formulations grows with `N` (`nonholo_bench`'s `scale-report`).

use std::collections::HashMap;
use std::f64::consts::FRAC_PI_2;
use std::sync::{Mutex, OnceLock};

use nonholo_core::Error;
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::scene::{ConstraintKind, ContactInfo, Named, Scalar, Scene, SceneInfo};

/// Largest number of sleighs: ten times the scaling study's largest train.
/// Setting a train up (tracing its Lagrangian and constraints, the sparsity
/// of its KKT system) happens before any budget of a run applies, and grows
/// faster than `N`: B's set-up and one short step took 0.34 s at 1000,
/// 5.5 s and 0.34 GB at 10 000, 28 s and 1.0 GB at 30 000, 175 s at
/// 100 000 (`simulate --t-end 0.001`, one run each, 2026-12-05).
pub const MAX_SLEIGHS: usize = 10_000;

const PARAMS: &[ParamSpec] = &[
    ParamSpec::real(
        "N",
        "",
        1.0,
        Bound::Inclusive(1.0),
        Bound::Inclusive(MAX_SLEIGHS as f64),
        "number of sleighs (a whole number): the lead sleigh and N − 1 trailers",
    ),
    ParamSpec::real(
        "m",
        "kg",
        1.0,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "mass of each sleigh",
    ),
    ParamSpec::real(
        "J",
        "m^2",
        1.0,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "squared radius of gyration of each sleigh about its blade (ρ² + a², so J > a²)",
    ),
    ParamSpec::real(
        "a",
        "m",
        0.4,
        Bound::Unbounded,
        Bound::Unbounded,
        "distance of each centre of mass ahead of its blade",
    ),
    ParamSpec::real(
        "l",
        "m",
        0.5,
        Bound::Exclusive(0.0),
        Bound::Unbounded,
        "drawbar: the hitch of a trailer is this far ahead of its blade",
    ),
    ParamSpec::real(
        "h",
        "m",
        0.3,
        Bound::Inclusive(0.0),
        Bound::Unbounded,
        "the pin that pulls the next sleigh is this far behind a blade",
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
];

const DESCRIPTION: &str = "N Chaplygin sleighs in a line on a plane of slope α: sleigh i has its \
    blade at (xi, yi), heading phii, centre of mass a ahead of the blade; no blade slides \
    sideways, and the drawbar end of sleigh i + 1 (l ahead of its blade) is pinned h behind the \
    blade of sleigh i. Two degrees of freedom for every N; N = 1 is sleigh-incline with \
    potential = com.";

/// The description of the scene for `N = 1`, the one the registry lists
/// (its parameters are those of every `N`); a built train answers
/// [`Scene::info`] with the description of its own `N`.
pub const INFO: SceneInfo = SceneInfo {
    name: "sleigh-train",
    title: "N Chaplygin sleighs hitched in a line",
    description: DESCRIPTION,
    coordinates: &[
        Named::new("x1", "m", "blade of sleigh 1, down the slope"),
        Named::new("y1", "m", "blade of sleigh 1, across the slope"),
        Named::new("phi1", "rad", "heading of sleigh 1 from the x axis"),
    ],
    params: PARAMS,
    structural: &["N"],
    holonomic: &[],
    nonholonomic: &["ẏ1 cos φ1 − ẋ1 sin φ1 = 0"],
    constraint_kind: ConstraintKind::Linear,
    nonholonomic_unit: "m/s",
    constraint_singular_set: None,
    embedding: None,
    velocity_chart: CHART,
    default_q: &[0.0, 0.0, 0.0],
    default_velocity: &[1.0, 0.3],
    closed_form: None,
    invariants: &[],
    contacts: &[ContactInfo {
        name: "blade 1",
        rows: &[0],
        load: LOAD,
    }],
};

const CHART: &[Named] = &[
    Named::new(
        "u",
        "m/s",
        "forward speed of the lead sleigh along its heading",
    ),
    Named::new("omega", "rad/s", "turning rate of the lead sleigh"),
];

const LOAD: &str = "m g cos α: each blade carries the normal component of its own sleigh's \
                    weight (the hitches transmit no vertical force)";

/// The description of a train of `n` sleighs: built once per `n` and kept
/// for the life of the process (its names are `'static`, as a scene's are).
fn info_for(n: usize) -> &'static SceneInfo {
    if n == 1 {
        return &INFO;
    }
    static TABLE: OnceLock<Mutex<HashMap<usize, &'static SceneInfo>>> = OnceLock::new();
    let mut table = TABLE
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    table
        .entry(n)
        .or_insert_with(|| Box::leak(Box::new(build_info(n))))
}

fn leak(s: String) -> &'static str {
    Box::leak(s.into_boxed_str())
}

fn build_info(n: usize) -> SceneInfo {
    let mut coordinates = Vec::with_capacity(3 * n);
    for i in 1..=n {
        coordinates.push(Named::new(
            leak(format!("x{i}")),
            "m",
            "blade of a sleigh, down the slope",
        ));
        coordinates.push(Named::new(
            leak(format!("y{i}")),
            "m",
            "blade of a sleigh, across the slope",
        ));
        coordinates.push(Named::new(
            leak(format!("phi{i}")),
            "rad",
            "heading of a sleigh from the x axis",
        ));
    }
    let nonholonomic: Vec<&'static str> = (1..=n)
        .map(|i| leak(format!("ẏ{i} cos φ{i} − ẋ{i} sin φ{i} = 0")))
        .collect();
    let mut holonomic = Vec::with_capacity(2 * (n - 1));
    for i in 1..n {
        let j = i + 1;
        holonomic.push(leak(format!("x{i} − h cos φ{i} − x{j} − l cos φ{j} = 0")));
        holonomic.push(leak(format!("y{i} − h sin φ{i} − y{j} − l sin φ{j} = 0")));
    }
    let rows: &'static [usize] = Box::leak((0..n).collect::<Vec<_>>().into_boxed_slice());
    let contacts: Vec<ContactInfo> = (0..n)
        .map(|i| ContactInfo {
            name: leak(format!("blade {}", i + 1)),
            rows: &rows[i..i + 1],
            load: LOAD,
        })
        .collect();
    SceneInfo {
        name: INFO.name,
        title: INFO.title,
        description: DESCRIPTION,
        coordinates: Box::leak(coordinates.into_boxed_slice()),
        params: PARAMS,
        structural: &["N"],
        holonomic: Box::leak(holonomic.into_boxed_slice()),
        nonholonomic: Box::leak(nonholonomic.into_boxed_slice()),
        constraint_kind: ConstraintKind::Linear,
        nonholonomic_unit: "m/s",
        constraint_singular_set: None,
        embedding: None,
        velocity_chart: CHART,
        default_q: Box::leak(default_q(n, 0.5, 0.3).into_boxed_slice()),
        default_velocity: INFO.default_velocity,
        closed_form: None,
        invariants: &[],
        contacts: Box::leak(contacts.into_boxed_slice()),
    }
}

/// The train in a straight line along the x axis, heading 0, the lead
/// blade at the origin (drawbar `l`, pin offset `h`).
fn default_q(n: usize, l: f64, h: f64) -> Vec<f64> {
    (0..n)
        .flat_map(|i| [-(i as f64) * (l + h), 0.0, 0.0])
        .collect()
}

/// The train; see the [module docs](self).
#[derive(Debug, Clone)]
pub struct Train {
    params: Params,
    info: &'static SceneInfo,
    /// Number of sleighs.
    pub sleighs: usize,
    pub m: f64,
    pub j: f64,
    pub a: f64,
    pub l: f64,
    pub h: f64,
    pub g: f64,
    pub alpha: f64,
    mg_sin_alpha: f64,
}

impl Train {
    /// `Σ term(i)` over sleighs `lo..hi`, summed pairwise (halves, then
    /// their sum): a traced sum is then a tree of depth `log₂ N`, not a
    /// chain of `N` partial sums each depending on every sleigh before it,
    /// so differentiating it by each coordinate visits `log N` partial sums
    /// and compiling the train costs time about linear in `N`.
    fn sum<D: Scalar>(&self, lo: usize, hi: usize, term: &impl Fn(usize) -> D) -> D {
        match hi - lo {
            0 => D::from(0.0),
            1 => term(lo),
            len => {
                let mid = lo + len / 2;
                self.sum(lo, mid, term) + self.sum(mid, hi, term)
            }
        }
    }
}

impl Scene for Train {
    const INFO: &'static SceneInfo = &INFO;

    fn info(&self) -> &'static SceneInfo {
        self.info
    }

    fn from_params(params: &Params) -> Result<Self, Error> {
        let count = params.real("N")?;
        if count.fract() != 0.0 {
            return Err(Error::InconsistentParams {
                requirement: "N a whole number".into(),
                values: vec![("N".into(), count)],
                why: "N counts the sleighs".into(),
            });
        }
        let (j, a) = (params.real("J")?, params.real("a")?);
        if j <= a * a {
            return Err(Error::InconsistentParams {
                requirement: format!("J > a² = {}", nonholo_core::num(a * a)),
                values: vec![("J".into(), j), ("a".into(), a)],
                why: "J is the squared radius of gyration about the blade, ρ² + a², and each \
                      sleigh's mass matrix has determinant m³(J − a²)"
                    .into(),
            });
        }
        let sleighs = count as usize;
        let (m, g, alpha) = (params.real("m")?, params.real("g")?, params.real("alpha")?);
        Ok(Train {
            params: params.clone(),
            info: info_for(sleighs),
            sleighs,
            m,
            j,
            a,
            l: params.real("l")?,
            h: params.real("h")?,
            g,
            alpha,
            mg_sin_alpha: m * g * alpha.sin(),
        })
    }

    fn params(&self) -> &Params {
        &self.params
    }

    fn normal_load(&self, _contact: usize) -> Option<f64> {
        Some(self.m * self.g * self.alpha.cos())
    }

    /// `Σᵢ ½m[ẋᵢ² + ẏᵢ² + Jφ̇ᵢ² + 2aφ̇ᵢ(ẏᵢ cos φᵢ − ẋᵢ sin φᵢ)] + m g sin α (xᵢ + a cos φᵢ)`,
    /// summed pairwise (see [`Train::sum`]).
    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], qd: &[D]) -> D {
        self.sum(0, self.sleighs, &|i| {
            let (x, phi) = (q[3 * i], q[3 * i + 2]);
            let (xd, yd, phid) = (qd[3 * i], qd[3 * i + 1], qd[3 * i + 2]);
            let (s, c) = phi.sin_cos();
            let kinetic = (xd * xd
                + yd * yd
                + phid * phid * self.j
                + phid * (yd * c - xd * s) * (2.0 * self.a))
                * (0.5 * self.m);
            kinetic + (x + c * self.a) * self.mg_sin_alpha
        })
    }

    /// Hitch `i`: `(xᵢ − h cos φᵢ, yᵢ − h sin φᵢ) = (xᵢ₊₁ + l cos φᵢ₊₁, yᵢ₊₁ + l sin φᵢ₊₁)`.
    fn holonomic<D: Scalar>(&self, _t: D, q: &[D], out: &mut [D]) {
        for (i, f) in out.chunks_exact_mut(2).enumerate() {
            let (front, back) = (&q[3 * i..3 * i + 3], &q[3 * i + 3..3 * i + 6]);
            let (s0, c0) = front[2].sin_cos();
            let (s1, c1) = back[2].sin_cos();
            f[0] = front[0] - c0 * self.h - back[0] - c1 * self.l;
            f[1] = front[1] - s0 * self.h - back[1] - s1 * self.l;
        }
    }

    /// Blade `i`: `ẏᵢ cos φᵢ − ẋᵢ sin φᵢ = 0`.
    fn nonholonomic<D: Scalar>(&self, _t: D, q: &[D], qd: &[D], out: &mut [D]) {
        for (i, g) in out.iter_mut().enumerate() {
            let (s, c) = q[3 * i + 2].sin_cos();
            *g = qd[3 * i + 1] * c - qd[3 * i] * s;
        }
    }

    fn default_q(&self) -> Vec<f64> {
        default_q(self.sleighs, self.l, self.h)
    }

    /// A trailer whose blade is not given (neither `xᵢ` nor `yᵢ`) and whose
    /// hitch does not hold is put where the hitch holds it: its drawbar end
    /// on the pin of the sleigh ahead, along its own heading, front to
    /// back, so that headings alone state a train's shape (`phi2 =
    /// 3.14159…` folds it). A hitch that holds to round-off (the default
    /// line) is left as it is.
    fn place(&self, q: &mut [f64], given: &[bool]) {
        for i in 1..self.sleighs {
            let (front, back) = (3 * (i - 1), 3 * i);
            if given[back] || given[back + 1] {
                continue;
            }
            let (s0, c0) = q[front + 2].sin_cos();
            let (s1, c1) = q[back + 2].sin_cos();
            let x = q[front] - c0 * self.h - c1 * self.l;
            let y = q[front + 1] - s0 * self.h - s1 * self.l;
            let scale = q[front].abs() + q[front + 1].abs() + self.h + self.l;
            if (x - q[back]).hypot(y - q[back + 1]) > 1e-12 * scale {
                (q[back], q[back + 1]) = (x, y);
            }
        }
    }

    /// The lead sleigh moves at `u` along its heading and turns at `ω`;
    /// each trailer's blade moves along its heading, at the component of its
    /// hitch's velocity along it, and turns at the normal component over
    /// `l` (its hitch is `l` ahead of the blade).
    fn velocities_from<D: Scalar>(&self, q: &[D], chart: &[D], qd: &mut [D]) {
        let (mut u, mut w) = (chart[0], chart[1]);
        for i in 0..self.sleighs {
            let (s, c) = q[3 * i + 2].sin_cos();
            if i > 0 {
                // The pin of sleigh i − 1 moves at (vx, vy), set below.
                let (vx, vy) = (qd[3 * i], qd[3 * i + 1]);
                u = vx * c + vy * s;
                w = (vy * c - vx * s) / self.l;
            }
            qd[3 * i] = u * c;
            qd[3 * i + 1] = u * s;
            qd[3 * i + 2] = w;
            if i + 1 < self.sleighs {
                // Velocity of the pin h behind this blade, handed on.
                qd[3 * i + 3] = u * c + w * s * self.h;
                qd[3 * i + 4] = u * s - w * c * self.h;
            }
        }
    }

    /// `u` and `ω` of the lead sleigh.
    fn chart_from(&self, q: &[f64], qd: &[f64], chart: &mut [f64]) -> bool {
        let (s, c) = q[2].sin_cos();
        chart[0] = qd[0] * c + qd[1] * s;
        chart[1] = qd[2];
        true
    }
}
