//! `bicycle`: the Whipple bicycle — rear frame with rider, front fork and
//! handlebar, two knife-edge wheels rolling without slipping on a level
//! ground — with the benchmark parameters of Meijaard, Papadopoulos, Ruina
//! & Schwab (2007, Proc. R. Soc. A 463, Table 1) as defaults.
//!
//! Axes as in the benchmark: `x` forward, `y` to the right, `z` down
//! (gravity `+z`), origin on the ground. In the reference configuration
//! (upright, straight ahead, all angles zero) the rear contact is at the
//! origin, the rear wheel centre at `(0, 0, −rR)`, the front wheel centre at
//! `(w, 0, −rF)`, the steering axis, tilted back by `λ` from the vertical,
//! meets the ground at `(w + c, 0, 0)` (`c` the trail), and every body's
//! centre of mass and inertia tensor are given in these axes (Table 1).
//!
//! Coordinates: rear contact `(x, y)`, heading `ψ` (yaw), lean `φ` (roll,
//! to the right positive), pitch `θ` of the rear frame about the rear axle
//! (dependent: the holonomic constraint keeps the front wheel on the
//! ground), steer `δ` (front frame about the steering axis, to the right
//! positive), wheel angles `θR`, `θF` relative to their frames. Rear frame
//! orientation `Rz(ψ) Rx(φ) Ry(θ)`; front frame that times a rotation by `δ`
//! about the steering axis. The Lagrangian is written once from these
//! rigid-body kinematics; everything else (mass matrix, forces, constraint
//! Jacobians, the benchmark's linearised matrices) comes from automatic
//! differentiation.

use std::f64::consts::{FRAC_PI_2, PI};

use nonholo_core::Error;
use nonholo_core::param::{Bound, ParamSpec, Params};
use nonholo_core::scene::{ConstraintKind, Named, Scalar, Scene, SceneInfo};
use num_dual::Dual;

/// The Whipple bicycle with its parameters (names of Meijaard et al. 2007).
#[derive(Debug, Clone)]
pub struct Bicycle {
    params: Params,
    /// Wheelbase, trail, steer-axis tilt, gravity.
    pub w: f64,
    pub c: f64,
    pub lambda: f64,
    pub g: f64,
    /// Rear wheel: radius, mass, moments about a diameter and the axle.
    pub r_r: f64,
    pub m_r: f64,
    pub i_rxx: f64,
    pub i_ryy: f64,
    /// Rear frame with rider: centre of mass `(xB, 0, zB)`, mass, inertia.
    pub x_b: f64,
    pub z_b: f64,
    pub m_b: f64,
    pub i_b: [[f64; 3]; 3],
    /// Front frame (fork and handlebar).
    pub x_h: f64,
    pub z_h: f64,
    pub m_h: f64,
    pub i_h: [[f64; 3]; 3],
    /// Front wheel.
    pub r_f: f64,
    pub m_f: f64,
    pub i_fxx: f64,
    pub i_fyy: f64,
}

/// A real parameter bounded below by `lo` only.
const fn real(
    name: &'static str,
    unit: &'static str,
    default: f64,
    lo: Bound,
    description: &'static str,
) -> ParamSpec {
    ParamSpec::real(name, unit, default, lo, Bound::Unbounded, description)
}

const POSITIVE: Bound = Bound::Exclusive(0.0);
const ANY: Bound = Bound::Unbounded;

const PARAMS: &[ParamSpec] = &[
    real("w", "m", 1.02, POSITIVE, "wheelbase"),
    real(
        "c",
        "m",
        0.08,
        ANY,
        "trail (steering axis meets the ground ahead of the front contact)",
    ),
    ParamSpec::real(
        "lambda",
        "rad",
        PI / 10.0,
        Bound::Exclusive(-FRAC_PI_2),
        Bound::Exclusive(FRAC_PI_2),
        "steer-axis tilt back from the vertical",
    ),
    crate::GRAVITY,
    real("rR", "m", 0.3, POSITIVE, "rear wheel radius"),
    real("mR", "kg", 2.0, POSITIVE, "rear wheel mass"),
    real(
        "IRxx",
        "kg m^2",
        0.0603,
        POSITIVE,
        "rear wheel moment about a diameter",
    ),
    real(
        "IRyy",
        "kg m^2",
        0.12,
        POSITIVE,
        "rear wheel moment about its axle",
    ),
    real("xB", "m", 0.3, ANY, "rear frame centre of mass, x"),
    real("zB", "m", -0.9, ANY, "rear frame centre of mass, z (down)"),
    real("mB", "kg", 85.0, POSITIVE, "rear frame (with rider) mass"),
    real("IBxx", "kg m^2", 9.2, POSITIVE, "rear frame inertia, xx"),
    real("IByy", "kg m^2", 11.0, POSITIVE, "rear frame inertia, yy"),
    real("IBzz", "kg m^2", 2.8, POSITIVE, "rear frame inertia, zz"),
    real("IBxz", "kg m^2", 2.4, ANY, "rear frame inertia, xz"),
    real("xH", "m", 0.9, ANY, "front frame centre of mass, x"),
    real("zH", "m", -0.7, ANY, "front frame centre of mass, z (down)"),
    real("mH", "kg", 4.0, POSITIVE, "front frame mass"),
    real(
        "IHxx",
        "kg m^2",
        0.05892,
        POSITIVE,
        "front frame inertia, xx",
    ),
    real("IHyy", "kg m^2", 0.06, POSITIVE, "front frame inertia, yy"),
    real(
        "IHzz",
        "kg m^2",
        0.00708,
        POSITIVE,
        "front frame inertia, zz",
    ),
    real("IHxz", "kg m^2", -0.00756, ANY, "front frame inertia, xz"),
    real("rF", "m", 0.35, POSITIVE, "front wheel radius"),
    real("mF", "kg", 3.0, POSITIVE, "front wheel mass"),
    real(
        "IFxx",
        "kg m^2",
        0.1405,
        POSITIVE,
        "front wheel moment about a diameter",
    ),
    real(
        "IFyy",
        "kg m^2",
        0.28,
        POSITIVE,
        "front wheel moment about its axle",
    ),
];

pub const INFO: SceneInfo = SceneInfo {
    name: "bicycle",
    title: "Whipple bicycle (benchmark of Meijaard et al. 2007)",
    description: "Four rigid bodies — rear frame with rider, front frame, two knife-edge wheels \
                  — on level ground; the front contact stays on the ground (holonomic) and both \
                  wheels roll without slipping (four nonholonomic constraints). Defaults: \
                  Table 1 of Meijaard, Papadopoulos, Ruina & Schwab (2007).",
    coordinates: &[
        Named::new("x", "m", "rear contact point, forward"),
        Named::new("y", "m", "rear contact point, to the right"),
        Named::new("psi", "rad", "heading (yaw) of the rear frame"),
        Named::new(
            "phi",
            "rad",
            "lean (roll) of the rear frame, to the right positive",
        ),
        Named::new(
            "theta",
            "rad",
            "pitch of the rear frame about the rear axle (dependent)",
        ),
        Named::new(
            "delta",
            "rad",
            "steer angle about the steering axis, to the right positive",
        ),
        Named::new(
            "thetaR",
            "rad",
            "rear wheel rotation relative to the rear frame",
        ),
        Named::new(
            "thetaF",
            "rad",
            "front wheel rotation relative to the front frame",
        ),
    ],
    params: PARAMS,
    structural: &[],
    holonomic: &["z of the front contact point = 0 (the front wheel touches the ground)"],
    nonholonomic: &[
        "rear contact point of the wheel at rest, x",
        "rear contact point of the wheel at rest, y",
        "front contact point of the wheel at rest, x",
        "front contact point of the wheel at rest, y",
    ],
    constraint_kind: ConstraintKind::Linear,
    nonholonomic_unit: "m/s",
    constraint_singular_set: Some(
        "the front wheel's plane horizontal (its lowest point undefined)",
    ),
    embedding: None,
    velocity_chart: &[
        Named::new(
            "v",
            "m/s",
            "forward speed of the rear contact point along the heading, −rR (θ̇R + θ̇)",
        ),
        Named::new("roll_rate", "rad/s", "lean rate φ̇"),
        Named::new("steer_rate", "rad/s", "steer rate δ̇"),
    ],
    default_q: &[0.0; 8],
    // The second manoeuvre of the nonlinear benchmark comparisons
    // (Basu-Mandal, Chatterjee & Papadopoulos 2007): 4.6 m/s with a lean
    // rate of 0.5 rad/s, inside the self-stable speed range.
    default_velocity: &[4.6, 0.5, 0.0],
    closed_form: None,
    invariants: &[],
    contacts: &[],
};

use crate::rigid::{
    R, V, add, c, column, cross, dot, mm, mtv, mv, rot_x, rot_y, rot_z, rotation, scale, spin, sub,
    vc, wheel_spin,
};

/// Positions, velocities and angular velocities of the four bodies.
struct Kinematics<D> {
    /// Rear contact point `(x, y, 0)` and its velocity.
    p_r: V<D>,
    c_r: V<D>,
    v_cr: V<D>,
    a_r: V<D>,
    w_r: V<D>,
    r_b: R<D>,
    w_b: V<D>,
    b_cm: V<D>,
    v_b: V<D>,
    r_h: R<D>,
    w_h: V<D>,
    h_cm: V<D>,
    v_h: V<D>,
    f_c: V<D>,
    v_fc: V<D>,
    a_f: V<D>,
    w_f: V<D>,
    /// Front contact point (the wheel's lowest point).
    p_f: V<D>,
}

impl Bicycle {
    /// The steering axis, pointing down, in rear-frame axes.
    fn steer_axis(&self) -> [f64; 3] {
        [self.lambda.sin(), 0.0, self.lambda.cos()]
    }

    /// The steering axis's ground point `(w + c, 0, 0)`, from the rear
    /// wheel centre, in rear-frame axes (reference configuration).
    fn hinge(&self) -> [f64; 3] {
        [self.w + self.c, 0.0, self.r_r]
    }

    /// Orientation of the rear frame and of the front frame, and the rear
    /// wheel centre and the hinge point, from positions only.
    #[allow(clippy::type_complexity)]
    fn frames<D: Scalar>(&self, q: &[D]) -> (R<D>, R<D>, R<D>, V<D>, V<D>) {
        let z = c::<D>(0.0);
        let lean = mm(&rot_z(q[2]), &rot_x(q[3]));
        let r_b = mm(&lean, &rot_y(q[4]));
        let r_h = mm(&r_b, &rotation(self.steer_axis(), q[5]));
        let p_r = [q[0], q[1], z];
        let c_r = add(p_r, mv(&lean, vc([0.0, 0.0, -self.r_r])));
        let hinge = add(c_r, mv(&r_b, vc(self.hinge())));
        (lean, r_b, r_h, c_r, hinge)
    }

    /// The front wheel centre and contact point from positions only.
    fn front<D: Scalar>(&self, r_h: &R<D>, hinge: V<D>) -> (V<D>, V<D>, V<D>) {
        let f_c = add(hinge, mv(r_h, vc([-self.c, 0.0, -self.r_f])));
        let a_f = [r_h[0][1], r_h[1][1], r_h[2][1]];
        // The lowest point of the wheel: down (+z) within the wheel plane.
        let s = (c::<D>(1.0) - a_f[2] * a_f[2]).sqrt();
        let down = scale(sub(vc([0.0, 0.0, 1.0]), scale(a_f, a_f[2])), s.recip());
        (f_c, a_f, add(f_c, scale(down, c(self.r_f))))
    }

    fn kinematics<D: Scalar>(&self, q: &[D], qd: &[D]) -> Kinematics<D> {
        let z = c::<D>(0.0);
        let (lean, r_b, r_h, c_r, hinge) = self.frames(q);
        let p_r = [q[0], q[1], z];
        // ω of the leaning frame, of the rear frame (pitch about the axle),
        // of the front frame (steer about the steering axis) and the wheels.
        let w_lean = add([z, z, qd[2]], scale(column(&lean, 0), qd[3]));
        let a_r = column(&lean, 1);
        let w_b = add(w_lean, scale(a_r, qd[4]));
        let w_h = add(w_b, scale(mv(&r_b, vc(self.steer_axis())), qd[5]));
        let w_r = add(w_b, scale(a_r, qd[6]));
        let v_cr = add([qd[0], qd[1], z], cross(w_lean, sub(c_r, p_r)));
        let b_cm = add(c_r, mv(&r_b, vc([self.x_b, 0.0, self.z_b + self.r_r])));
        let v_b = add(v_cr, cross(w_b, sub(b_cm, c_r)));
        let v_hinge = add(v_cr, cross(w_b, sub(hinge, c_r)));
        let h_ref = [self.x_h - self.w - self.c, 0.0, self.z_h];
        let h_cm = add(hinge, mv(&r_h, vc(h_ref)));
        let v_h = add(v_hinge, cross(w_h, sub(h_cm, hinge)));
        let (f_c, a_f, p_f) = self.front(&r_h, hinge);
        let v_fc = add(v_hinge, cross(w_h, sub(f_c, hinge)));
        let w_f = add(w_h, scale(a_f, qd[7]));
        Kinematics {
            p_r,
            c_r,
            v_cr,
            a_r,
            w_r,
            r_b,
            w_b,
            b_cm,
            v_b,
            r_h,
            w_h,
            h_cm,
            v_h,
            f_c,
            v_fc,
            a_f,
            w_f,
            p_f,
        }
    }

    /// The velocity of the material point of each wheel at its contact
    /// (rear then front; zero when rolling without slipping).
    fn slip<D: Scalar>(k: &Kinematics<D>) -> (V<D>, V<D>) {
        (
            add(k.v_cr, cross(k.w_r, sub(k.p_r, k.c_r))),
            add(k.v_fc, cross(k.w_f, sub(k.p_f, k.f_c))),
        )
    }
}

/// Solves the `N × N` system `a x = b` (augmented as `a[i][N]`) by Gaussian
/// elimination with partial pivoting, over any scalar, without allocating;
/// `false` if a pivot vanishes.
fn solve_small<D: Scalar, const N: usize, const M: usize>(a: &mut [[D; M]; N]) -> bool {
    for k in 0..N {
        let p = (k..N)
            .max_by(|&i, &j| a[i][k].modulus().total_cmp(&a[j][k].modulus()))
            .unwrap_or(k);
        if a[p][k].modulus() == 0.0 {
            return false;
        }
        a.swap(k, p);
        for i in k + 1..N {
            let f = a[i][k] / a[k][k];
            for j in k..M {
                let v = a[k][j];
                a[i][j] -= f * v;
            }
        }
    }
    for k in (0..N).rev() {
        let mut v = a[k][N];
        for j in k + 1..N {
            v -= a[k][j] * a[j][N];
        }
        a[k][N] = v / a[k][k];
    }
    true
}

impl Scene for Bicycle {
    const INFO: &'static SceneInfo = &INFO;

    fn from_params(params: &Params) -> Result<Self, Error> {
        let r = |n: &str| params.real(n);
        let sym =
            |xx: f64, yy: f64, zz: f64, xz: f64| [[xx, 0.0, xz], [0.0, yy, 0.0], [xz, 0.0, zz]];
        let b = Bicycle {
            params: params.clone(),
            w: r("w")?,
            c: r("c")?,
            lambda: r("lambda")?,
            g: r("g")?,
            r_r: r("rR")?,
            m_r: r("mR")?,
            i_rxx: r("IRxx")?,
            i_ryy: r("IRyy")?,
            x_b: r("xB")?,
            z_b: r("zB")?,
            m_b: r("mB")?,
            i_b: sym(r("IBxx")?, r("IByy")?, r("IBzz")?, r("IBxz")?),
            x_h: r("xH")?,
            z_h: r("zH")?,
            m_h: r("mH")?,
            i_h: sym(r("IHxx")?, r("IHyy")?, r("IHzz")?, r("IHxz")?),
            r_f: r("rF")?,
            m_f: r("mF")?,
            i_fxx: r("IFxx")?,
            i_fyy: r("IFyy")?,
        };
        for (body, i, names) in [
            ("rear frame", b.i_b, ["IBxx", "IBzz", "IBxz"]),
            ("front frame", b.i_h, ["IHxx", "IHzz", "IHxz"]),
        ] {
            if i[0][0] * i[2][2] <= i[0][2] * i[0][2] {
                return Err(Error::InconsistentParams {
                    requirement: format!("{} · {} > {}²", names[0], names[1], names[2]),
                    values: names
                        .iter()
                        .map(|n| (n.to_string(), params.real(n).unwrap_or(f64::NAN)))
                        .collect(),
                    why: format!("the {body}'s inertia tensor must be positive definite"),
                });
            }
        }
        Ok(b)
    }

    fn params(&self) -> &Params {
        &self.params
    }

    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], qd: &[D]) -> D {
        let k = self.kinematics(q, qd);
        let kinetic = (dot(k.v_cr, k.v_cr) * self.m_r
            + dot(k.v_b, k.v_b) * self.m_b
            + dot(k.v_h, k.v_h) * self.m_h
            + dot(k.v_fc, k.v_fc) * self.m_f)
            * 0.5
            + wheel_spin(self.i_rxx, self.i_ryy, k.w_r, k.a_r)
            + spin(&self.i_b, mtv(&k.r_b, k.w_b))
            + spin(&self.i_h, mtv(&k.r_h, k.w_h))
            + wheel_spin(self.i_fxx, self.i_fyy, k.w_f, k.a_f);
        // z points down: the potential is −g Σ m z.
        let weight =
            k.c_r[2] * self.m_r + k.b_cm[2] * self.m_b + k.h_cm[2] * self.m_h + k.f_c[2] * self.m_f;
        kinetic + weight * self.g
    }

    fn holonomic<D: Scalar>(&self, _t: D, q: &[D], out: &mut [D]) {
        let (_, _, r_h, _, hinge) = self.frames(q);
        out[0] = self.front(&r_h, hinge).2[2];
    }

    fn nonholonomic<D: Scalar>(&self, _t: D, q: &[D], qd: &[D], out: &mut [D]) {
        let (rear, front) = Self::slip(&self.kinematics(q, qd));
        out[0] = rear[0];
        out[1] = rear[1];
        out[2] = front[0];
        out[3] = front[1];
    }

    /// Solves `ḟ = 0`, `g = 0` and `−rR (θ̇R + θ̇) = v` for the six
    /// velocities other than the lean and steer rates.
    fn velocities_from<D: Scalar>(&self, q: &[D], chart: &[D], qd: &mut [D]) {
        const UNKNOWN: [usize; 6] = [0, 1, 2, 4, 6, 7];
        let z = c::<D>(0.0);
        let mut a = [[z; 7]; 6];
        // ḟ = ∇f · q̇: the gradient of f by one dual pass per coordinate.
        let mut grad = [z; 8];
        let mut qx = [Dual::<D>::from_re(z); 8];
        for j in 0..8 {
            for i in 0..8 {
                qx[i] = Dual::new(q[i], if i == j { c(1.0) } else { z });
            }
            let mut f = [Dual::from_re(z)];
            self.holonomic(Dual::from_re(z), &qx, &mut f);
            grad[j] = f[0].eps;
        }
        for (col, &j) in UNKNOWN.iter().enumerate() {
            a[0][col] = grad[j];
        }
        // g is linear in q̇: its columns from unit velocities.
        let mut unit = [z; 8];
        let mut g = [z; 4];
        for (col, &j) in UNKNOWN.iter().enumerate() {
            unit.fill(z);
            unit[j] = c(1.0);
            self.nonholonomic(z, q, &unit, &mut g);
            for r in 0..4 {
                a[1 + r][col] = g[r];
            }
        }
        unit.fill(z);
        unit[3] = chart[1];
        unit[5] = chart[2];
        self.nonholonomic(z, q, &unit, &mut g);
        let f_known = grad[3] * chart[1] + grad[5] * chart[2];
        a[0][6] = -f_known;
        for r in 0..4 {
            a[1 + r][6] = -g[r];
        }
        // −rR (θ̇R + θ̇) = v.
        a[5][3] = c(-self.r_r);
        a[5][4] = c(-self.r_r);
        a[5][6] = chart[0];
        qd[3] = chart[1];
        qd[5] = chart[2];
        if solve_small(&mut a) {
            for (r, &j) in UNKNOWN.iter().enumerate() {
                qd[j] = a[r][6];
            }
        } else {
            for &j in &UNKNOWN {
                qd[j] = c(f64::NAN);
            }
        }
    }

    fn chart_from(&self, _q: &[f64], qd: &[f64], chart: &mut [f64]) -> bool {
        chart[0] = -self.r_r * (qd[6] + qd[4]);
        chart[1] = qd[3];
        chart[2] = qd[5];
        true
    }
}
