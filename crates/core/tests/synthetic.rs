//! The AD pieces of the core against finite differences, on a synthetic
//! scene that has everything: explicit time dependence, a Lagrangian that is
//! not quadratic in q̇, a nonlinear nonholonomic and a holonomic constraint.

use nalgebra::DMatrix;
use nonholo_core::Error;
use nonholo_core::ad::Jet;
use nonholo_core::consistency::check_or_project;
use nonholo_core::constraints::ConstraintState;
use nonholo_core::init;
use nonholo_core::param::{ParamSpec, Params};
use nonholo_core::scene::{ConstraintKind, Lagrangian, Named, Scalar, Scene, SceneInfo};
use rand::{Rng, SeedableRng};

struct Synthetic {
    params: Params,
}

const PARAMS: &[ParamSpec] = &[];

const INFO: SceneInfo = SceneInfo {
    name: "synthetic",
    title: "synthetic test scene",
    description: "",
    coordinates: &[
        Named::new("a", "m", ""),
        Named::new("b", "m", ""),
        Named::new("c", "rad", ""),
    ],
    params: PARAMS,
    structural: &[],
    holonomic: &["a² + b sin t − 1 = 0"],
    nonholonomic: &["ċ + sin(a) ḃ² + t b = 0"],
    constraint_kind: ConstraintKind::Nonlinear,
    nonholonomic_unit: "",
    constraint_singular_set: None,
    embedding: None,
    velocity_chart: &[],
    default_q: &[1.0, 0.0, 0.0],
    default_velocity: &[0.0, 0.3, 0.0],
    closed_form: None,
    invariants: &[],
    contacts: &[],
};

impl Scene for Synthetic {
    const INFO: &'static SceneInfo = &INFO;
    fn from_params(params: &Params) -> Result<Self, Error> {
        Ok(Synthetic {
            params: params.clone(),
        })
    }
    fn params(&self) -> &Params {
        &self.params
    }
    fn lagrangian<D: Scalar>(&self, t: D, q: &[D], qd: &[D]) -> D {
        let m0 = q[1].sin() + 2.0;
        let m1 = (q[0] * t).cos() * 0.2 + 1.5;
        (qd[0] * qd[0] * m0 + qd[1] * qd[1] * m1 + qd[2] * qd[2]) * 0.5
            + qd[0] * qd[1] * q[2].cos() * 0.3
            + qd[0].powi(3) * qd[2] * 0.1
            + t * q[0] * qd[2]
            - q[0].cos() * q[1]
            + t * t * q[2] * 0.05
    }
    fn holonomic<D: Scalar>(&self, t: D, q: &[D], out: &mut [D]) {
        out[0] = q[0] * q[0] + q[1] * t.sin() - 1.0;
    }
    fn nonholonomic<D: Scalar>(&self, t: D, q: &[D], qd: &[D], out: &mut [D]) {
        out[0] = qd[2] + q[0].sin() * qd[1] * qd[1] + t * q[1];
    }
}

fn scene() -> Synthetic {
    Synthetic::from_params(&Params::defaults(PARAMS)).unwrap()
}

fn lag(s: &Synthetic, t: f64, q: &[f64], qd: &[f64]) -> f64 {
    s.lagrangian(t, q, qd)
}

/// ∂L/∂q̇ by central differences.
fn momentum_fd(s: &Synthetic, t: f64, q: &[f64], qd: &[f64]) -> [f64; 3] {
    let h = 1e-5;
    let mut p = [0.0; 3];
    for i in 0..3 {
        let (mut a, mut b) = (qd.to_vec(), qd.to_vec());
        a[i] += h;
        b[i] -= h;
        p[i] = (lag(s, t, q, &a) - lag(s, t, q, &b)) / (2.0 * h);
    }
    p
}

fn random_state(rng: &mut impl Rng) -> (f64, [f64; 3], [f64; 3], [f64; 3]) {
    let mut v = || rng.random_range(-1.5..1.5);
    (v(), [v(), v(), v()], [v(), v(), v()], [v(), v(), v()])
}

/// M and Q against finite differences: M from differences of the momentum,
/// and M q̈ − Q against d/dt ∂L/∂q̇ − ∂L/∂q along the curve
/// q(τ) = q + q̇τ + q̈τ²/2 by differences in time.
#[test]
fn mass_and_force_match_finite_differences() {
    let s = scene();
    let mut jet = Jet::new(3, 1);
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    for _ in 0..50 {
        let (t, q, qd, qdd) = random_state(&mut rng);
        let mut m = DMatrix::zeros(3, 3);
        let mut force = [0.0; 3];
        jet.mass_and_force(
            &Lagrangian(&s),
            t,
            &q,
            &qd,
            &[],
            &mut m.view_mut((0, 0), (3, 3)),
            &mut force,
        );
        let h = 1e-4;
        for j in 0..3 {
            let (mut a, mut b) = (qd, qd);
            a[j] += h;
            b[j] -= h;
            let (pa, pb) = (momentum_fd(&s, t, &q, &a), momentum_fd(&s, t, &q, &b));
            for i in 0..3 {
                let fd = (pa[i] - pb[i]) / (2.0 * h);
                assert!(
                    (m[(i, j)] - fd).abs() < 1e-5 * (1.0 + fd.abs()),
                    "M[{i},{j}] {} vs {fd}",
                    m[(i, j)]
                );
            }
        }
        let curve = |tau: f64| {
            let qc: Vec<f64> = (0..3)
                .map(|i| q[i] + qd[i] * tau + 0.5 * qdd[i] * tau * tau)
                .collect();
            let qdc: Vec<f64> = (0..3).map(|i| qd[i] + qdd[i] * tau).collect();
            (qc, qdc)
        };
        let (qa, qda) = curve(h);
        let (qb, qdb) = curve(-h);
        let (pa, pb) = (
            momentum_fd(&s, t + h, &qa, &qda),
            momentum_fd(&s, t - h, &qb, &qdb),
        );
        for i in 0..3 {
            let dpdt = (pa[i] - pb[i]) / (2.0 * h);
            let (mut a, mut b) = (q, q);
            a[i] += 1e-6;
            b[i] -= 1e-6;
            let dldq = (lag(&s, t, &a, &qd) - lag(&s, t, &b, &qd)) / 2e-6;
            let el = dpdt - dldq;
            let ad = (0..3).map(|j| m[(i, j)] * qdd[j]).sum::<f64>() - force[i];
            assert!(
                (ad - el).abs() < 1e-5 * (1.0 + el.abs()),
                "EL[{i}] {ad} vs {el}"
            );
        }
        // Energy q̇·∂L/∂q̇ − L.
        let p = momentum_fd(&s, t, &q, &qd);
        let e = (0..3).map(|i| qd[i] * p[i]).sum::<f64>() - lag(&s, t, &q, &qd);
        let e_ad = jet.energy(&Lagrangian(&s), t, &q, &qd, &[]);
        assert!((e - e_ad).abs() < 1e-8 * (1.0 + e.abs()));
        let mut p_ad = [0.0; 3];
        jet.momentum(&Lagrangian(&s), t, &q, &qd, &[], &mut p_ad);
        for i in 0..3 {
            assert!((p_ad[i] - p[i]).abs() < 1e-8);
        }
    }
}

/// Constraint pieces against finite differences: G = ∂g/∂q̇, ġ₀, F = ∂f/∂q,
/// ḟ, f̈₀ (time derivatives along q(τ) = q + q̇τ with q̈ = 0).
#[test]
fn constraint_pieces_match_finite_differences() {
    let s = scene();
    let mut jet = Jet::new(3, 1);
    let mut cs = ConstraintState::new(3, 1, 1);
    let mut rng = rand::rngs::StdRng::seed_from_u64(2);
    let g = |t: f64, q: &[f64], qd: &[f64]| {
        let mut o = [0.0];
        s.nonholonomic(t, q, qd, &mut o);
        o[0]
    };
    let f = |t: f64, q: &[f64]| {
        let mut o = [0.0];
        s.holonomic(t, q, &mut o);
        o[0]
    };
    let h = 1e-5;
    for _ in 0..50 {
        let (t, q, qd, _) = random_state(&mut rng);
        cs.evaluate(&mut jet, &s, t, &q, &qd);
        assert_eq!(cs.g[0], g(t, &q, &qd));
        assert_eq!(cs.f[0], f(t, &q));
        for j in 0..3 {
            let (mut a, mut b) = (qd, qd);
            a[j] += h;
            b[j] -= h;
            let fd = (g(t, &q, &a) - g(t, &q, &b)) / (2.0 * h);
            assert!((cs.jac[(0, j)] - fd).abs() < 1e-8, "G[{j}]");
            let (mut a, mut b) = (q, q);
            a[j] += h;
            b[j] -= h;
            let fd = (f(t, &a) - f(t, &b)) / (2.0 * h);
            assert!((cs.jac[(1, j)] - fd).abs() < 1e-8, "F[{j}]");
        }
        let along = |tau: f64| -> Vec<f64> { (0..3).map(|i| q[i] + qd[i] * tau).collect() };
        let fd = (g(t + h, &along(h), &qd) - g(t - h, &along(-h), &qd)) / (2.0 * h);
        assert!(
            (cs.g_rate0[0] - fd).abs() < 1e-8,
            "ġ₀ {} vs {fd}",
            cs.g_rate0[0]
        );
        let fd = (f(t + h, &along(h)) - f(t - h, &along(-h))) / (2.0 * h);
        assert!((cs.f_rate[0] - fd).abs() < 1e-8, "ḟ");
        let h2 = 1e-4;
        let fd = (f(t + h2, &along(h2)) - 2.0 * f(t, &q) + f(t - h2, &along(-h2))) / (h2 * h2);
        assert!(
            (cs.f_accel0[0] - fd).abs() < 1e-5,
            "f̈₀ {} vs {fd}",
            cs.f_accel0[0]
        );
    }
}

/// Inconsistent initial data are refused with the residual of each
/// constraint; `--project-init` moves them onto the constraints, and for
/// velocities the result is the kinetic-energy-nearest consistent one.
#[test]
fn consistency_check_and_projection() {
    let s = scene();
    let mut initial = init::resolve(&s, &[("a".into(), "0.9".into())], &[]).unwrap();
    initial.t0 = 0.4;
    let e = check_or_project(&s, &mut initial.clone(), false).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("holonomic")
            && msg.contains("a² + b sin t − 1")
            && msg.contains("--project-init"),
        "{msg}"
    );

    let p = check_or_project(&s, &mut initial, true).unwrap().unwrap();
    assert!(
        p.projection.position_residual.1 < 1e-14 && p.projection.velocity_residual.1 < 1e-14,
        "{p:?}"
    );
    // Now consistent: accepted as is.
    assert!(
        check_or_project(&s, &mut initial.clone(), false)
            .unwrap()
            .is_none()
    );

    // Nearest in the M metric: at the nearest point M Δ lies in the row space
    // of C = [G; F]. This scene's g is nonlinear in q̇ and its M depends on q̇,
    // so the Gauss–Newton projection meets that only to second order in |Δ|.
    let mut jet = Jet::new(3, 1);
    let mut cs = ConstraintState::new(3, 1, 1);
    let (q, qd) = (initial.q.clone(), initial.qd.clone());
    cs.evaluate(&mut jet, &s, initial.t0, &q, &qd);
    let mut m = DMatrix::zeros(3, 3);
    let mut force = [0.0; 3];
    jet.mass_and_force(
        &Lagrangian(&s),
        initial.t0,
        &q,
        &qd,
        &[],
        &mut m.view_mut((0, 0), (3, 3)),
        &mut force,
    );
    // Project q̇ from a perturbed velocity and check M Δ ∈ span(Cᵀ).
    let mut moved = initial.clone();
    moved.qd[0] += 0.2;
    moved.qd[2] -= 0.1;
    let before = moved.qd.clone();
    check_or_project(&s, &mut moved, true).unwrap();
    let delta: Vec<f64> = (0..3).map(|i| moved.qd[i] - before[i]).collect();
    let delta_norm2: f64 = delta.iter().map(|d| d * d).sum();
    let md = &m * nalgebra::DVector::from_vec(delta);
    cs.evaluate(&mut jet, &s, moved.t0, &moved.q, &moved.qd);
    let c = cs.jac.clone();
    // Least-squares residual of M Δ = Cᵀ μ.
    let ct = c.transpose();
    let mu = (c.clone() * ct.clone())
        .lu()
        .solve(&(c.clone() * md.clone()))
        .unwrap();
    let r = md - ct * mu;
    assert!(
        r.amax() < 0.1 * delta_norm2,
        "M Δ off span(Cᵀ) by {:e} for |Δ|² = {delta_norm2:e}",
        r.amax()
    );
}

#[test]
fn initial_values_resolve_by_name() {
    let s = scene();
    let i = init::resolve(
        &s,
        &[("c".into(), "90deg".into()), ("a_dot".into(), "2".into())],
        &[init::ExtraName::new("lambda", "", "")],
    )
    .unwrap();
    assert!((i.q[2] - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    assert_eq!(i.qd, vec![2.0, 0.3, 0.0]);
    let e = init::resolve(
        &s,
        &[("d".into(), "1".into())],
        &[init::ExtraName::new("lambda", "", "")],
    )
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("a, b, c, a_dot, b_dot, c_dot, lambda"),
        "{e}"
    );
    let e = init::resolve(&s, &[("a".into(), "x1".into())], &[]).unwrap_err();
    assert!(
        e.to_string().contains("`a`") && e.to_string().contains("x1"),
        "{e}"
    );
    let e = init::resolve(&s, &[("a".into(), "inf".into())], &[]).unwrap_err();
    assert!(e.to_string().contains("finite"), "{e}");
    let i = init::resolve(
        &s,
        &[("lambda".into(), "0.5".into())],
        &[init::ExtraName::new("lambda", "", "")],
    )
    .unwrap();
    assert_eq!(i.extra("lambda"), Some(0.5));
}
