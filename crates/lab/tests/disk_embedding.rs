//! Formulation A on the rolling disk, whose map gives the heading
//! `θ = atan2(ẏ, ẋ)` and only the rate of the cyclic rolling angle,
//! `ψ̇ = (ẋ cos θ + ẏ sin θ)/R` (docs/embedding.md §7).
//!
//! Oracles written here, from C's Euler–Lagrange equations for
//! `ℓ = ½m|v|² + ½Iθ̇² + ½J_rψ̇² + λ₁(ẋ − Rψ̇ cos θ) + λ₂(ẏ − Rψ̇ sin θ)`:
//! `mẍ + λ̇₁ = 0`, `mÿ + λ̇₂ = 0`, and `ψ` cyclic, so that
//! `P_ψ = J_rψ̇ − R(λ₁ cos θ + λ₂ sin θ)` is conserved. A eliminates `ψ`
//! (its end value is free), which adds `P_ψ = 0`: A's motions are the C
//! motions with `P_ψ = 0`. Along A's motion the multipliers are
//! `λ(t) = λ(0) − m(v(t) − v(0))`, so `P_ψ` can be evaluated from A's own
//! state. Scene defaults: `m = 1`, `I = 0.25`, `J_r = 0.5`, `R = 1`.

use nonholo_core::Run;
use nonholo_lab::matching::MatchReport;
use nonholo_lab::simulate::{SimulateArgs, run};

fn args(formulation: &str, init: &[&str], tol: f64, t_end: f64) -> SimulateArgs {
    SimulateArgs {
        init: init.iter().map(|s| s.to_string()).collect(),
        t_end,
        output_every: Some(0.05),
        rtol: Some(tol),
        atol: Some(tol),
        ..SimulateArgs::new("rolling-disk", formulation)
    }
}

fn simulate(formulation: &str, init: &[&str], tol: f64, t_end: f64) -> (Run, Option<MatchReport>) {
    let (r, m) = run(&args(formulation, init, tol, t_end)).expect("the run starts");
    assert!(r.failure.is_none(), "{formulation}: {:?}", r.failure);
    (r, m)
}

/// Largest distance between the contact points of two runs on one grid.
fn distance(a: &Run, b: &Run) -> f64 {
    assert_eq!(a.samples.len(), b.samples.len());
    a.samples
        .iter()
        .zip(&b.samples)
        .map(|(p, q)| (p.q[0] - q.q[0]).hypot(p.q[1] - q.q[1]))
        .fold(0.0, f64::max)
}

/// Largest difference of the angles `(θ, ψ)` and of all velocities.
fn angle_and_rate_difference(a: &Run, b: &Run) -> f64 {
    a.samples
        .iter()
        .zip(&b.samples)
        .flat_map(|(p, q)| {
            [
                p.q[2] - q.q[2],
                p.q[3] - q.q[3],
                p.qd[0] - q.qd[0],
                p.qd[1] - q.qd[1],
                p.qd[2] - q.qd[2],
                p.qd[3] - q.qd[3],
            ]
        })
        .fold(0.0f64, |m, d| m.max(d.abs()))
}

/// `P_ψ` at every sample of A's motion, with `λ(t) = λ0 − m(v(t) − v(0))`.
fn rolling_momentum(a: &Run, lambda0: &[f64]) -> Vec<f64> {
    let v0 = &a.samples[0].qd;
    a.samples
        .iter()
        .map(|o| {
            let l1 = lambda0[0] - (o.qd[0] - v0[0]);
            let l2 = lambda0[1] - (o.qd[1] - v0[1]);
            0.5 * o.qd[3] - (l1 * o.q[2].cos() + l2 * o.q[2].sin())
        })
        .collect()
}

/// A runs on the disk over [0, 10] — through four instants of zero speed —
/// with the structure the set-up reports, and is C's motion with the
/// matching `λ0` (`λ₁` completed from `P_ψ = 0`) to 1e-8 m; `P_ψ` stays 0
/// along A's motion to 1e-10.
#[test]
fn a_on_the_disk_is_the_vakonomic_motion_with_zero_rolling_momentum() {
    let theta0 = 0.4f64;
    let init = ["theta=0.4", "lambda2=0.3"];
    let (a, matching) = simulate("embedding", &init, 1e-12, 10.0);
    let matching = matching.unwrap();
    // P_ψ = J_r ψ̇ − R(λ₁ cos θ + λ₂ sin θ) = 0 at θ = 0.4, ψ̇ = 1, λ₂ = 0.3.
    let lambda1 = (0.5 - 0.3 * theta0.sin()) / theta0.cos();
    assert!(
        (matching.lambda0[0] - lambda1).abs() < 1e-14,
        "{matching:?}"
    );
    assert_eq!(matching.lambda0[1], 0.3);
    assert!(matching.cyclic_momentum[0].abs() < 1e-15, "{matching:?}");

    let report: std::collections::HashMap<_, _> = a.model.init_report().into_iter().collect();
    // W = ∂²Θ/∂q̈² = I/|v|² (n̂ n̂ᵀ) with n̂ ⊥ v: rank 1. Two hidden
    // constraints leave 8 − 2 = 6 free data: (x, y, ẋ, ẏ) and two more —
    // as many as C's motions with P_ψ = 0 have besides ψ (θ̇ and one
    // multiplier).
    assert_eq!(report["rank_w"], 1.0);
    assert_eq!(report["hidden_constraints"], 2.0);
    assert_eq!(report["free_initial_data"], 6.0);
    assert_eq!(report["state_dimension"], 9.0);

    let lambda_init = [
        format!("lambda1={}", matching.lambda0[0]),
        "lambda2=0.3".to_string(),
    ];
    let (c, _) = simulate(
        "vakonomic",
        &["theta=0.4", &lambda_init[0], &lambda_init[1]],
        1e-12,
        10.0,
    );
    let speeds: Vec<f64> = c.samples.iter().map(|o| o.qd[3]).collect();
    let reversals = speeds.windows(2).filter(|w| w[0] * w[1] < 0.0).count();
    assert_eq!(a.crossings.len(), reversals, "{:?}", a.crossings);
    assert!(reversals >= 2, "the test is meant to pass zero speed");
    let d = distance(&a, &c);
    assert!(d < 1e-8, "A and C differ by {d:e} m");
    let da = angle_and_rate_difference(&a, &c);
    assert!(da < 1e-8, "A's angles and rates differ from C's by {da:e}");
    let p = rolling_momentum(&a, &matching.lambda0);
    let worst = p.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    eprintln!(
        "disk, [0, 10], rtol 1e-12: {} crossings; A–C {d:.1e} m, angles and rates {da:.1e}; \
         max |P_ψ| along A {worst:.1e}",
        a.crossings.len()
    );
    assert!(worst < 1e-10, "P_ψ along A reaches {worst:e}");
}

/// With `P_ψ ≠ 0` the C motion is not one of A's: given multipliers that
/// violate `P_ψ = 0` are refused with the value of `P_ψ` and valid ones.
/// B's circles are C's motions with `λ = −mRψ̇(cos θ, sin θ)`
/// (`θ̈ = 0` needs `λ ∥ (cos θ, sin θ)` with no constant part), whose
/// `P_ψ = (J_r + mR²)ψ̇` = 1.5 here: A reproduces no circle of B.
#[test]
fn a_refuses_multipliers_with_rolling_momentum_and_so_every_circle_of_b() {
    let Err(e) = run(&args("embedding", &["lambda1=-1", "lambda2=0"], 1e-10, 1.0)) else {
        panic!("A accepted multipliers with P_ψ ≠ 0");
    };
    let e = e.to_string();
    assert!(e.contains("P_psi = 1.5"), "{e}");
    assert!(
        e.contains("nearest valid multipliers are lambda1 = 0.5"),
        "{e}"
    );
    assert!(e.contains("lambda1 = -1 (given)"), "{e}");
    // Heading along y, λ₂ given: P_ψ hardly depends on λ₁ (∂P/∂λ₁ =
    // −R cos θ0 ≈ −2.7e-8), so completing λ₁ is refused rather than made
    // huge; likewise λ₂ at θ0 = 0, where ∂P/∂λ₂ = 0.
    for init in [["theta=1.5707963", "lambda2=0.1"], ["theta=0", "lambda1=0"]] {
        let Err(e) = run(&args("embedding", &init, 1e-10, 1.0)) else {
            panic!("{init:?}: completed an ill-determined multiplier");
        };
        let e = e.to_string();
        assert!(
            e.contains("hardly depend here on the multipliers left out"),
            "{e}"
        );
    }
    // C with those multipliers is B's circle.
    let (b, _) = simulate("chetaev", &[], 1e-12, 5.0);
    let (c, _) = simulate("vakonomic", &["lambda1=-1", "lambda2=0"], 1e-12, 5.0);
    let d = distance(&b, &c);
    assert!(
        d < 1e-9,
        "C with λ = −mRψ̇(cos θ, sin θ) is B's circle: {d:e}"
    );
}

/// Rolling straight ahead (`θ̇ = 0`), A reproduces B: the C motion with
/// `λ = (J_rψ̇/R)(cos θ, sin θ)` (`P_ψ = 0`, `θ̈ = 0`, `λ̇ = 0`) is the
/// straight line at constant speed, and A, matched with it, follows it.
#[test]
fn a_reproduces_b_on_straight_lines() {
    let theta0 = 0.4f64;
    let l2 = format!("lambda2={}", 0.5 * theta0.sin());
    let init = ["theta=0.4", "omega_theta=0", &l2];
    let (a, matching) = simulate("embedding", &init, 1e-12, 10.0);
    let (b, _) = simulate("chetaev", &["theta=0.4", "omega_theta=0"], 1e-12, 10.0);
    assert!((matching.unwrap().lambda0[0] - 0.5 * theta0.cos()).abs() < 1e-14);
    let d = distance(&a, &b);
    assert!(d < 1e-9, "A and B differ by {d:e} m on the straight line");
    let da = angle_and_rate_difference(&a, &b);
    assert!(da < 1e-9, "{da:e}");
}

/// A's initial data given as derivatives: the inverse map finds the
/// multipliers from `q̈_I` together with `P_ψ = 0`.
#[test]
fn inverse_map_on_the_disk_solves_for_zero_rolling_momentum() {
    let (a, matching) = simulate("embedding", &["theta=0.4", "lambda2=0.3"], 1e-10, 0.1);
    let matching = matching.unwrap();
    let given: Vec<String> = ["x_ddot", "y_ddot", "x_dddot", "y_dddot"]
        .iter()
        .map(|n| format!("{n}={}", a.initial.extra(n).unwrap()))
        .collect();
    let mut init = vec!["theta=0.4"];
    init.extend(given.iter().map(String::as_str));
    let (_, inverse) = simulate("embedding", &init, 1e-10, 0.1);
    let inverse = inverse.unwrap();
    assert_eq!(inverse.source, "explicit");
    for k in 0..2 {
        assert!(
            (inverse.lambda0[k] - matching.lambda0[k]).abs() < 1e-10,
            "{inverse:?} {matching:?}"
        );
    }
    assert!(inverse.cyclic_momentum[0].abs() < 1e-12);
    assert!(inverse.third_residual.unwrap() < 1e-10, "{inverse:?}");
}

/// ψ is the integral of the ψ̇ a run reports, on either continuation: on
/// the analytic one ψ̇ is the signed speed over R, on the map's principal
/// branch |v|/R, also across the gaps of the crossings (where the path in
/// complex time carried the analytic rate). Checked by the trapezoid rule
/// on a 1 ms grid over [0, 4] (two crossings).
#[test]
fn the_rolling_angle_integrates_its_reported_rate_on_both_branches() {
    for continuation in ["analytic", "map"] {
        let mut a = args("embedding", &["lambda2=0"], 1e-11, 4.0);
        a.output_every = Some(1e-3);
        a.options = vec![format!("continuation={continuation}")];
        let (r, _) = run(&a).expect("the run starts");
        assert!(r.failure.is_none(), "{continuation}: {:?}", r.failure);
        assert_eq!(r.crossings.len(), 2, "{continuation}");
        let t = &r.solution.t;
        let s = &r.samples;
        let mut integral = 0.0;
        let mut worst = 0.0f64;
        for i in 1..s.len() {
            integral += 0.5 * (t[i] - t[i - 1]) * (s[i].qd[3] + s[i - 1].qd[3]);
            worst = worst.max((s[i].q[3] - s[0].q[3] - integral).abs());
        }
        eprintln!("{continuation}: max |ψ − ψ0 − ∫ψ̇| = {worst:.2e}");
        assert!(worst < 1e-5, "{continuation}: ψ − ∫ψ̇ reaches {worst:e}");
        let lowest = s.iter().map(|o| o.qd[3]).fold(f64::INFINITY, f64::min);
        match continuation {
            "map" => assert!(lowest >= 0.0, "{lowest}"),
            _ => assert!(lowest < -0.5, "{lowest}"),
        }
    }
}
