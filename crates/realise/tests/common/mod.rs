//! Shared by the realisation tests: scenes and options from pairs, the
//! sleigh's body-frame equations (the independent oracle), Jacobian checks,
//! runs.

#![allow(dead_code)]

use nonholo_core::integrate::{Method, OdeSystem, Options};
use nonholo_core::{Initial, Model, Params, RunConfig, Scene, init, simulate};
use nonholo_scenes::Sleigh;
use rand::Rng;

pub fn pairs(items: &[(&str, &str)]) -> Vec<(String, String)> {
    items
        .iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect()
}

pub fn scene<S: Scene>(params: &[(&str, &str)]) -> S {
    S::from_params(&Params::resolve(S::INFO.params, &pairs(params), "parameter").unwrap()).unwrap()
}

pub fn options(specs: &'static [nonholo_core::ParamSpec], given: &[(&str, &str)]) -> Params {
    Params::resolve(specs, &pairs(given), "option").unwrap()
}

/// The sleigh in body-frame quasi-velocities `u` (forward), `w = g`
/// (sideways) and `ω`, for any kinetic energy `T = ½m(u² + w² + Jω² + 2aωw)
/// + ½N w²`, by Kirchhoff's equations on SE(2):
///
/// ```text
/// d/dt ∂T/∂u = ω ∂T/∂w + F_u
/// d/dt ∂T/∂w = −ω ∂T/∂u + F_w − k w
/// d/dt ∂T/∂ω = w ∂T/∂u − u ∂T/∂w + τ
/// ```
///
/// with gravity `F = m g sin α (cos φ, −sin φ)` at the blade, `τ = −[com] m g a
/// sin α sin φ`. `N = 0` is `visc(k)`, `k = 0` is `mass(N)`. Derived by
/// hand, independently of the automatic differentiation under test.
pub struct Body {
    pub m: f64,
    pub j: f64,
    pub a: f64,
    pub gs: f64,
    pub com: f64,
    pub k: f64,
    pub n: f64,
}

impl Body {
    pub fn of(s: &Sleigh, potential: &str, k: f64, n: f64) -> Self {
        Body {
            m: s.m,
            j: s.j,
            a: s.a,
            gs: s.g * s.alpha.sin(),
            com: if potential == "com" { 1.0 } else { 0.0 },
            k,
            n,
        }
    }

    /// `(u̇, ẇ, ω̇)` at `(φ, u, w, ω)`.
    pub fn rates(&self, phi: f64, u: f64, w: f64, om: f64) -> (f64, f64, f64) {
        let (m, a, j) = (self.m, self.a, self.j);
        let pw = m * (w + a * om) + self.n * w;
        let ud = (om * pw + m * self.gs * phi.cos()) / m;
        // [m + N, m a; m a, m J] (ẇ, ω̇) = (r1, r2)
        let r1 = -om * m * u - m * self.gs * phi.sin() - self.k * w;
        let r2 = w * m * u - u * pw - self.com * m * self.gs * a * phi.sin();
        let (a11, a12, a22) = (m + self.n, m * a, m * j);
        let det = a11 * a22 - a12 * a12;
        let wd = (r1 * a22 - a12 * r2) / det;
        let omd = (a11 * r2 - a12 * r1) / det;
        (ud, wd, omd)
    }

    /// `q̈` at `(φ, u, w, ω)`.
    pub fn qdd(&self, phi: f64, u: f64, w: f64, om: f64) -> [f64; 3] {
        let (ud, wd, omd) = self.rates(phi, u, w, om);
        let (c, s) = (phi.cos(), phi.sin());
        [
            ud * c - u * om * s - wd * s - w * om * c,
            ud * s + u * om * c + wd * c - w * om * s,
            omd,
        ]
    }
}

/// A random sleigh (both potentials) and a random state off the constraint.
pub fn random_case(rng: &mut impl Rng, potential: &str) -> (Sleigh, [f64; 4]) {
    let a: f64 = rng.random_range(-1.0..1.0);
    let j = a * a + rng.random_range(0.1..2.0);
    let m: f64 = rng.random_range(0.5..3.0);
    let alpha: f64 = rng.random_range(0.0..1.4);
    let s: Sleigh = scene(&[
        ("a", &a.to_string()),
        ("J", &j.to_string()),
        ("m", &m.to_string()),
        ("alpha", &alpha.to_string()),
        ("potential", potential),
    ]);
    let state = [
        rng.random_range(-4.0..4.0),
        rng.random_range(-3.0..3.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-3.0..3.0),
    ];
    (s, state)
}

/// `(x, y, φ, ẋ, ẏ, φ̇)` from `(φ, u, w, ω)`.
pub fn cartesian(phi: f64, u: f64, w: f64, om: f64) -> [f64; 6] {
    let (c, s) = (phi.cos(), phi.sin());
    [0.3, -0.2, phi, u * c - w * s, u * s + w * c, om]
}

pub fn assert_close(got: f64, expect: f64, scale: f64, what: &str) {
    assert!(
        (got - expect).abs() <= 1e-12 * (scale + expect.abs()),
        "{what}: {got} vs {expect}"
    );
}

/// Central differences of the right-hand side against the AD Jacobians
/// (to 1e-7 of each column's largest entry: the differences' own error).
pub fn check_jacobian(sys: &mut dyn OdeSystem, y: &[f64], what: &str) {
    let (e, i, j) = nonholo_core::integrate::jacobian_mismatch(sys, 0.0, y)
        .unwrap()
        .expect("an AD Jacobian");
    assert!(
        e < 1e-7,
        "{what}: ∂f{i}/∂y{j} off central differences by {e:e}"
    );
}

/// Initial data; `lambda` is accepted when `with_lambda`.
pub fn initial<S: Scene>(s: &S, given: &[(&str, &str)], with_lambda: bool) -> Initial {
    let extra = if with_lambda {
        nonholo_vakonomic::lambda_names(1)
    } else {
        Vec::new()
    };
    init::resolve(s, &pairs(given), &extra).unwrap()
}

pub fn run_model(
    model: Box<dyn Model>,
    init: Initial,
    method: Method,
    tol: f64,
    t_end: f64,
    grid: &[f64],
) -> nonholo_core::Run {
    simulate(
        model,
        init,
        RunConfig {
            method,
            options: Options {
                rtol: tol,
                atol: tol,
                output: grid.to_vec(),
                ..Options::default()
            },
            t_end,
            project_init: false,
        },
    )
    .unwrap()
}

pub fn sci(v: &[f64]) -> String {
    v.iter()
        .map(|x| format!("{x:.4e}"))
        .collect::<Vec<_>>()
        .join(", ")
}

pub const SLEIGH_INIT: &[(&str, &str)] = &[("phi", "0.2"), ("u", "2"), ("omega", "0.7")];
