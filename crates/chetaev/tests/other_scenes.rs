//! Formulation B on the rolling disk, Appell–Hamel and the Cartesian pendulum.

mod common;

use common::*;
use nonholo_core::integrate::{IntegrateError, Method, OdeSystem, Options, SystemError, solve};
use nonholo_core::{Observation, Scene};
use nonholo_scenes::{AppellHamel, Pendulum, RollingDisk};
use rand::{Rng, SeedableRng};

/// B gives θ̈ = ψ̈ = 0 for the vertical disk at any state on the constraints.
#[test]
fn disk_turning_and_rolling_rates_are_constant() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let disk: RollingDisk = scene(&[("R", "0.7"), ("I", "0.3"), ("Jr", "0.6"), ("m", "2")]);
    let mut b = chetaev(disk.clone(), &[]);
    for _ in 0..200 {
        let q = [
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
            rng.random_range(-4.0..4.0),
            rng.random_range(-4.0..4.0),
        ];
        let chart = [rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0)];
        let mut qd = [0.0; 4];
        disk.velocities_from(&q, &chart, &mut qd);
        let (mut qdd, mut lam) = ([0.0; 4], [0.0; 2]);
        accelerations(&mut b, 0.0, &q, &qd, &mut qdd, &mut lam).unwrap();
        assert!(
            qdd[2].abs() < 1e-14 && qdd[3].abs() < 1e-14,
            "θ̈ = {}, ψ̈ = {}",
            qdd[2],
            qdd[3]
        );
        // The contact point turns with the disk: ẍ = −R ψ̇ θ̇ sin θ, ÿ = R ψ̇ θ̇ cos θ.
        let (s, c) = q[2].sin_cos();
        assert!((qdd[0] + 0.7 * qd[3] * qd[2] * s).abs() < 1e-13);
        assert!((qdd[1] - 0.7 * qd[3] * qd[2] * c).abs() < 1e-13);
    }
}

/// At tight tolerance the disk follows its closed form; energy, constraint
/// residual and the invariants θ̇, ψ̇ stay at round-off.
#[test]
fn disk_trajectory_invariants_and_closed_form() {
    let disk: RollingDisk = scene(&[]);
    let mut run = run_b(
        &disk,
        &[],
        &[("omega_theta", "0.5"), ("omega_psi", "1.3")],
        Method::Dop853,
        1e-13,
        50.0,
        grid(50.0, 0.5),
    );
    assert!(run.completed());
    let d = &run.diagnostics;
    assert!(
        d.constraint_residual_max < 1e-13,
        "residual {:e}",
        d.constraint_residual_max
    );
    assert!(
        d.energy_drift_max < 1e-13,
        "energy drift {:e}",
        d.energy_drift_max
    );
    for inv in &d.invariants {
        assert!(
            inv.drift_max < 1e-13,
            "{} drift {:e}",
            inv.name,
            inv.drift_max
        );
    }
    let (mut q, mut qd) = ([0.0; 4], [0.0; 4]);
    let mut obs = Observation::new(4, 2);
    let (mut err_q, mut err_lambda) = (0.0f64, 0.0f64);
    for t in [0.3, 7.7, 31.4, 50.0] {
        run.observe_at(t, &mut obs).unwrap();
        disk.closed_form(&run.initial.q, &run.initial.qd, t, &mut q, &mut qd)
            .unwrap();
        for i in 0..4 {
            err_q = err_q.max((obs.q[i] - q[i]).abs());
        }
        // The multipliers are the contact force on the disk: m ẍ = λ1, m ÿ = λ2 (m = 1).
        let (s, c) = q[2].sin_cos();
        let (ax, ay) = (-qd[3] * qd[2] * s, qd[3] * qd[2] * c);
        err_lambda = err_lambda
            .max((obs.multipliers[0] - ax).abs())
            .max((obs.multipliers[1] - ay).abs());
    }
    eprintln!("disk: closed-form error q {err_q:e}, λ {err_lambda:e}");
    // Measured 8.3e-13 (q, after 50 s at tolerance 1e-13) and 2.3e-15 (λ,
    // an O(1) force: round-off); bounds about 10× and 40× above.
    assert!(err_q < 1e-11, "q error {err_q:e}");
    assert!(err_lambda < 1e-13, "λ error {err_lambda:e}");
}

/// Appell–Hamel under B: straight horizontal path, ρ̇ = c g/(1 + c²),
/// z̈ = −c² g/(1 + c²), λ = m g/(1 + c²) (spec, closed form).
#[test]
fn appell_hamel_matches_closed_form() {
    for c in ["0.5", "2", "-0.3"] {
        let s: AppellHamel = scene(&[("c", c), ("m", "1.5")]);
        let cv: f64 = c.parse().unwrap();
        // Up to just before the stop for c < 0.
        let t_end = if cv < 0.0 {
            0.9 * 3.0 * (1.0 + cv * cv) / (cv.abs() * 9.81)
        } else {
            5.0
        };
        let run = run_b(
            &s,
            &[],
            &[("rho", "3"), ("beta", "0.4")],
            Method::Dop853,
            1e-12,
            t_end,
            grid(t_end, t_end / 50.0),
        );
        assert!(run.completed(), "c = {c}: {:?}", run.failure);
        let (mut q, mut qd) = ([0.0; 3], [0.0; 3]);
        let (mut err_q, mut err_qd, mut err_lambda) = (0.0f64, 0.0f64, 0.0f64);
        for (t, o) in run.solution.t.iter().zip(&run.samples) {
            s.closed_form(&run.initial.q, &run.initial.qd, *t, &mut q, &mut qd)
                .unwrap();
            for i in 0..3 {
                err_q = err_q.max((o.q[i] - q[i]).abs());
                err_qd = err_qd.max((o.qd[i] - qd[i]).abs());
            }
            let lambda = 1.5 * 9.81 / (1.0 + cv * cv);
            err_lambda = err_lambda.max((o.multipliers[0] - lambda).abs());
        }
        let (energy, invariant) = (
            run.diagnostics.energy_drift_max,
            run.diagnostics.invariants[0].drift_max,
        );
        eprintln!(
            "appell-hamel c = {c}: error q {err_q:e}, q̇ {err_qd:e}, λ {err_lambda:e}; \
             drift energy {energy:e}, invariant {invariant:e}"
        );
        // Measured at tolerance 1e-12, worst over c: q 1.6e-13, q̇ 2.9e-14,
        // λ 3.6e-15 (round-off of an O(10) force), energy drift 2.3e-12
        // (c = 2), invariant drift 1.0e-13 (c = −0.3). Bounds about 10× above;
        // the energy's is the previous 1e-11 (4×).
        assert!(
            err_q < 2e-12 && err_qd < 5e-13,
            "c = {c}: q {err_q:e}, q̇ {err_qd:e}"
        );
        assert!(err_lambda < 1e-13, "c = {c}: λ {err_lambda:e}");
        assert!(energy < 1e-11, "c = {c}: energy drift {energy:e}");
        assert!(invariant < 1e-12, "c = {c}: invariant drift {invariant:e}");
    }
}

/// With c < 0 the horizontal speed reaches zero at t* = ρ0 (1 + c²)/(|c| g),
/// where the constraint is not differentiable: the run stops there with an
/// error naming the time and the reason, and keeps the trajectory before it.
#[test]
fn appell_hamel_stops_at_zero_horizontal_speed() {
    let s: AppellHamel = scene(&[("c", "-0.5")]);
    let t_star = 2.0 * (1.0 + 0.25) / (0.5 * 9.81);
    let run = run_b(
        &s,
        &[],
        &[("rho", "2")],
        Method::Dop853,
        1e-10,
        3.0,
        grid(3.0, 0.01),
    );
    match &run.failure {
        Some(e @ IntegrateError::Stopped { t, reason }) => {
            // The stop is where ρ = singular_tol = 1e-8, i.e. 1e-8/|ρ̇| before t*.
            let rho_dot = 0.5 * 9.81 / 1.25;
            assert!(
                (t - (t_star - 1e-8 / rho_dot)).abs() < 1e-9,
                "stopped at {t}, t* = {t_star}"
            );
            assert!(reason.contains("horizontal speed"), "{reason}");
            let msg = e.to_string();
            assert!(msg.contains(&format!("{t}")), "{msg}");
        }
        other => panic!("expected a stop at t*, got {other:?}"),
    }
    assert!(*run.solution.t.last().unwrap() <= t_star);
    assert!(run.samples.len() > 50);
}

/// The pendulum angle equation θ̈ = −(g/l) sin θ, integrated independently.
struct AngleEquation {
    g_over_l: f64,
}

impl OdeSystem for AngleEquation {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        dy[0] = y[1];
        dy[1] = -self.g_over_l * y[0].sin();
        Ok(())
    }
}

/// The holonomic path of B: the Cartesian pendulum follows the angle
/// equation, and ν is the rod tension: Fᵀν = 2(x, y) ν = −T r̂ with
/// T = m(l θ̇² + g cos θ), so ν = −T/(2l).
#[test]
fn pendulum_matches_angle_equation_and_tension() {
    let (m, g, l) = (1.3, 9.81, 0.8);
    let p: Pendulum = scene(&[("m", "1.3"), ("l", "0.8")]);
    let run = run_b(
        &p,
        &[],
        &[("omega", "1.1")],
        Method::Dop853,
        1e-12,
        10.0,
        grid(10.0, 0.1),
    );
    assert!(run.completed());
    let theta0 = 0.5f64;
    let reference = solve(
        Method::Dop853,
        &mut AngleEquation { g_over_l: g / l },
        0.0,
        &[theta0, 1.1],
        10.0,
        &Options {
            rtol: 1e-13,
            atol: 1e-13,
            output: run.solution.t.clone(),
            ..Options::default()
        },
    )
    .unwrap();
    let (mut err_q, mut err_nu) = (0.0f64, 0.0f64);
    for (i, o) in run.samples.iter().enumerate() {
        let (th, thd) = (reference.row(i)[0], reference.row(i)[1]);
        err_q = err_q
            .max((o.q[0] - l * th.sin()).abs())
            .max((o.q[1] + l * th.cos()).abs());
        let tension = m * (l * thd * thd + g * th.cos());
        err_nu = err_nu.max((o.multipliers[0] + tension / (2.0 * l)).abs());
    }
    eprintln!("pendulum: error (x, y) {err_q:e}, ν {err_nu:e}");
    // Measured 3.7e-11 ((x, y)) and 4.3e-10 (ν, which involves θ̇²) over
    // 10 s at tolerance 1e-12 (both B and the angle equation's reference
    // carry global error); bounds about 12× above.
    assert!(err_q < 5e-10, "(x, y) error {err_q:e}");
    assert!(err_nu < 5e-9, "ν error {err_nu:e}");
}

/// Stabilisation on a long pendulum run at loose tolerance: without it |f|
/// drifts; Baumgarte bounds it; projection holds it at round-off. The choice
/// is recorded in the model's options.
#[test]
fn stabilisation_controls_holonomic_drift() {
    let p: Pendulum = scene(&[]);
    let residual = |opts: &[(&str, &str)]| {
        let run = run_b(
            &p,
            opts,
            &[("omega", "2")],
            Method::Dopri5,
            1e-6,
            200.0,
            grid(200.0, 1.0),
        );
        assert!(run.completed());
        let d = &run.diagnostics;
        assert_eq!(
            run.model.options().choice("stab"),
            Ok(opts.first().map(|o| o.1).unwrap_or("none"))
        );
        (d.holonomic_residual_max, d.holonomic_velocity_residual_max)
    };
    let none = residual(&[]);
    let baumgarte = residual(&[
        ("stab", "baumgarte"),
        ("baumgarte_alpha", "5"),
        ("baumgarte_beta", "5"),
    ]);
    let projection = residual(&[("stab", "projection")]);
    eprintln!("|f|, |ḟ| max: none {none:?}, baumgarte {baumgarte:?}, projection {projection:?}");
    assert!(none.0 > 1e-5, "drift without stabilisation {:e}", none.0);
    assert!(baumgarte.0 < none.0 / 10.0);
    assert!(
        projection.0 < 1e-13 && projection.1 < 1e-12,
        "{projection:?}"
    );
}

/// Projection on the sleigh keeps the nonholonomic residual at round-off
/// even at a loose tolerance.
#[test]
fn projection_holds_the_sleigh_on_its_constraint() {
    let s: nonholo_scenes::Sleigh = scene(&[]);
    let init_values = [("phi", "0.2"), ("u", "2"), ("omega", "0.7")];
    let loose = run_b(
        &s,
        &[],
        &init_values,
        Method::Dopri5,
        1e-5,
        20.0,
        grid(20.0, 1.0),
    );
    let projected = run_b(
        &s,
        &[("stab", "projection")],
        &init_values,
        Method::Dopri5,
        1e-5,
        20.0,
        grid(20.0, 1.0),
    );
    eprintln!(
        "residual none {:e}, projection {:e}",
        loose.diagnostics.nonholonomic_residual_max,
        projected.diagnostics.nonholonomic_residual_max
    );
    // The sleigh reaches ~60 m/s: round-off of g = ẏ cos φ − ẋ sin φ is ~1e-14 × 60.
    assert!(projected.diagnostics.nonholonomic_residual_max < 1e-12 * 60.0);
    assert!(
        loose.diagnostics.nonholonomic_residual_max
            > 1e3 * projected.diagnostics.nonholonomic_residual_max
    );
}

/// A scene whose constraint Jacobian vanishes at the start: g = x ẏ, G = (0, x)
/// is zero at x = 0, so the KKT system is singular and the run must stop at
/// t = 0 with that reason (not produce NaN).
mod degenerate {
    use nonholo_core::Error;
    use nonholo_core::param::{ParamSpec, Params};
    use nonholo_core::scene::{ConstraintKind, Named, Scalar, Scene, SceneInfo};

    #[derive(Clone)]
    pub struct Degenerate(Params);
    const PARAMS: &[ParamSpec] = &[];
    pub const INFO: SceneInfo = SceneInfo {
        name: "degenerate",
        title: "",
        description: "",
        coordinates: &[Named::new("x", "m", ""), Named::new("y", "m", "")],
        params: PARAMS,
        structural: &[],
        holonomic: &[],
        nonholonomic: &["x ẏ = 0"],
        constraint_kind: ConstraintKind::Linear,
        nonholonomic_unit: "",
        constraint_singular_set: None,
        embedding: None,
        velocity_chart: &[],
        default_q: &[0.0, 0.0],
        default_velocity: &[1.0, 0.0],
        closed_form: None,
        invariants: &[],
        contacts: &[],
    };
    impl Scene for Degenerate {
        const INFO: &'static SceneInfo = &INFO;
        fn from_params(p: &Params) -> Result<Self, Error> {
            Ok(Degenerate(p.clone()))
        }
        fn params(&self) -> &Params {
            &self.0
        }
        fn lagrangian<D: Scalar>(&self, _t: D, _q: &[D], qd: &[D]) -> D {
            (qd[0] * qd[0] + qd[1] * qd[1]) * 0.5
        }
        fn nonholonomic<D: Scalar>(&self, _t: D, q: &[D], qd: &[D], out: &mut [D]) {
            out[0] = q[0] * qd[1];
        }
    }
}

#[test]
fn singular_kkt_stops_the_run_with_its_reason() {
    let s: degenerate::Degenerate = scene(&[]);
    let run = run_b(&s, &[], &[], Method::Dop853, 1e-8, 1.0, grid(1.0, 0.1));
    match &run.failure {
        Some(IntegrateError::System { t, source }) => {
            assert_eq!(*t, 0.0);
            assert!(
                source
                    .message
                    .contains("KKT system of formulation B singular"),
                "{source}"
            );
        }
        other => panic!("expected a singular KKT system, got {other:?}"),
    }
}

/// Baumgarte stabilisation on a nonholonomic constraint enforces
/// ġ + 2α g = 0 at acceleration level: from a violated start g(0) = g0 the
/// residual decays exactly like g0·e^(−2αt), while without stabilisation it
/// stays at g0 (ġ = 0). (On consistent sleigh runs g barely drifts at all —
/// 1.4e-5 at both 20 s and 200 s with DOPRI5 at 1e-5 — so the law itself is
/// what is tested.)
#[test]
fn baumgarte_on_the_sleigh_constraint() {
    use nonholo_core::integrate::solve;
    let s: nonholo_scenes::Sleigh = scene(&[]);
    let g_of = |y: &[f64]| y[4] * y[2].cos() - y[3] * y[2].sin();
    // (x, y, φ, ẋ, ẏ, φ̇) with a lateral slip of 0.01 m/s.
    let (phi, u, slip) = (0.2f64, 2.0, 0.01);
    let y0 = [
        0.0,
        0.0,
        phi,
        u * phi.cos() - slip * phi.sin(),
        u * phi.sin() + slip * phi.cos(),
        0.7,
    ];
    assert!((g_of(&y0) - slip).abs() < 1e-15);
    let opts = Options {
        rtol: 1e-12,
        atol: 1e-12,
        output: vec![0.0, 0.25, 0.5],
        ..Options::default()
    };
    let alpha = 2.0;
    let mut b = chetaev(
        s.clone(),
        &[("stab", "baumgarte"), ("baumgarte_alpha", "2")],
    );
    let sol = solve(Method::Dop853, &mut b, 0.0, &y0, 0.5, &opts).unwrap();
    let mut err = 0.0f64;
    for (i, &t) in sol.t.iter().enumerate().skip(1) {
        let want = slip * (-2.0 * alpha * t).exp();
        err = err.max((g_of(sol.row(i)) - want).abs());
    }
    let mut plain = chetaev(s, &[]);
    let sol = solve(Method::Dop853, &mut plain, 0.0, &y0, 0.5, &opts).unwrap();
    let err_plain = (g_of(sol.row(2)) - slip).abs();
    eprintln!("baumgarte: g error {err:e}, unstabilised {err_plain:e}");
    // Measured 1.2e-13 and 4.9e-14 with atol = 1e-12 on a violation of
    // 1e-2: the bound is the integrator's tolerance.
    assert!(err < 1e-12, "g error {err:e}");
    assert!(err_plain < 1e-12, "unstabilised g error {err_plain:e}");
}
