//! Formulation A (the paper's embedding) against C (vakonomic), matched as the
//! spec prescribes: A's initial derivatives are C's Taylor coefficients at
//! (q0, q̇0, λ0). For constraints of form (14) the embedded problem is the
//! vakonomic problem restricted to constrained curves, so the two must agree
//! — up to the first reversal, where A's embedding map is singular.

use nonholo_core::integrate::IntegrateError;
use nonholo_core::{Run, Scene};
use nonholo_lab::simulate::{SimulateArgs, run};

fn args(
    formulation: &str,
    params: &[&str],
    init: &[&str],
    integrator: &str,
    tol: f64,
    t_end: f64,
    every: f64,
) -> SimulateArgs {
    let own = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    SimulateArgs {
        params: own(params),
        init: own(init),
        t_end,
        output_every: Some(every),
        integrator: integrator.into(),
        rtol: Some(tol),
        atol: Some(tol),
        ..SimulateArgs::new("sleigh-incline", formulation)
    }
}

/// Forward speed u = ẋ cos φ + ẏ sin φ of each sample.
fn speeds(r: &Run) -> Vec<f64> {
    r.samples
        .iter()
        .map(|o| o.qd[0] * o.q[2].cos() + o.qd[1] * o.q[2].sin())
        .collect()
}

/// First time u changes sign, by linear interpolation between samples.
fn first_reversal(r: &Run) -> Option<f64> {
    let u = speeds(r);
    let t = &r.solution.t;
    (1..u.len())
        .find(|&i| u[i - 1] * u[i] <= 0.0)
        .map(|i| t[i - 1] + (t[i] - t[i - 1]) * u[i - 1] / (u[i - 1] - u[i]))
}

const INIT: [&str; 3] = ["phi=0.2", "u=2", "omega=0.7"];

/// The spec's main claim under test: matched A and C agree to 1e-7 in
/// position up to C's first zero of the forward speed, for several λ0 and
/// both potentials; A then stops with the promised error within 1e-3 of
/// that zero (its extrapolated zero is much closer).
#[test]
fn matched_a_and_c_agree_until_the_reversal() {
    for potential in ["paper", "com"] {
        for lambda0 in ["0", "0.5", "-1"] {
            let params = ["a=0.4", "alpha=0.3", &format!("potential={potential}")];
            let mut init = INIT.to_vec();
            let lam = format!("lambda={lambda0}");
            init.push(&lam);
            let (c, _) = run(&args(
                "vakonomic",
                &params,
                &init,
                "dop853",
                1e-12,
                3.0,
                1e-4,
            ))
            .unwrap();
            let t_rev = first_reversal(&c).expect("the vakonomic sleigh reverses within 3 s");
            // A at 1e-10: tighter tolerances ask Newton for more than the
            // round-off floor of (19) allows (see docs/embedding.md).
            let (a, matching) = run(&args(
                "embedding",
                &params,
                &init,
                "radau5",
                1e-10,
                3.0,
                1e-4,
            ))
            .unwrap();
            let matching = matching.unwrap();
            assert_eq!(matching.source, "vakonomic");
            assert_eq!(matching.lambda0, vec![lambda0.parse::<f64>().unwrap()]);
            let stop = match &a.failure {
                Some(IntegrateError::Stopped { t, reason }) => {
                    assert!(
                        reason.contains("zero speed") && reason.contains("extrapolated zero"),
                        "{reason}"
                    );
                    *t
                }
                other => panic!("A should stop at the singular set, got {other:?}"),
            };
            let mut worst = 0.0f64;
            for (oa, oc) in a.samples.iter().zip(&c.samples) {
                for k in 0..2 {
                    worst = worst.max((oa.q[k] - oc.q[k]).abs());
                }
            }
            eprintln!(
                "{potential}, λ0 = {lambda0}: C reverses at {t_rev:.6}, A stops at {stop:.6}, max position difference {worst:.2e} over {} samples",
                a.samples.len()
            );
            assert!(
                (stop - t_rev).abs() < 1e-3,
                "stop {stop} vs reversal {t_rev}"
            );
            assert!(worst < 1e-7, "{potential}, λ0 = {lambda0}: {worst:e}");
        }
    }
}

/// With the paper's potential `a` drops out of Θ, so A's trajectory from the
/// same explicit initial derivatives is the same for every `a` (spec). The
/// derivatives: tangential acceleration 0.3 and q̈ consistent with ω = 0.7,
/// q⃛ completed by A from its hidden constraints.
#[test]
fn a_does_not_depend_on_a_with_the_paper_potential() {
    let (phi, u, omega, at): (f64, f64, f64, f64) = (0.2, 2.0, 0.7, 0.3);
    let xdd = at * phi.cos() - u * omega * phi.sin();
    let ydd = at * phi.sin() + u * omega * phi.cos();
    let (xs, ys) = (format!("x_ddot={xdd}"), format!("y_ddot={ydd}"));
    let init = ["phi=0.2", "u=2", "omega=0.7", &xs, &ys];
    let mut runs = Vec::new();
    for a in ["0", "0.4", "0.9"] {
        let p = format!("a={a}");
        // Over 0.4 s, before this sleigh's reversal at 0.419 s.
        let (r, m) = run(&args(
            "embedding",
            &[&p, "J=1.5", "potential=paper"],
            &init,
            "radau5",
            1e-10,
            0.4,
            0.01,
        ))
        .unwrap();
        assert_eq!(m.unwrap().source, "explicit");
        assert!(r.completed(), "a = {a}: {:?}", r.failure);
        runs.push(r);
    }
    for r in &runs[1..] {
        assert_eq!(r.samples.len(), runs[0].samples.len());
        for (o, p) in r.samples.iter().zip(&runs[0].samples) {
            for k in 0..3 {
                // a enters the arithmetic (multiplied by g ≡ 0 at round-off)
                // but not the equations.
                assert!((o.q[k] - p.q[k]).abs() < 1e-12, "{} vs {}", o.q[k], p.q[k]);
            }
        }
    }
}

/// A sleigh launched up the slope (heading ≈ π, gravity against the motion):
/// its forward speed passes through zero. B and C are regular there and carry
/// on through the reversal; A stops at its embedding map's singular set with
/// the promised error, within 1e-3 of C's zero.
#[test]
fn launched_up_the_slope() {
    let params = ["a=0.4", "alpha=0.3", "potential=com"];
    let init = ["phi=3.0", "u=2", "omega=0.3"];
    let (b, _) = run(&args("chetaev", &params, &init, "dop853", 1e-11, 3.0, 1e-3)).unwrap();
    assert!(b.completed(), "{:?}", b.failure);
    let b_rev = first_reversal(&b).expect("B's speed passes through zero");
    // B is regular through the reversal: energy conserved to round-off across it.
    assert!(
        b.diagnostics.energy_drift_max < 1e-9,
        "{:e}",
        b.diagnostics.energy_drift_max
    );
    let (c, _) = run(&args(
        "vakonomic",
        &params,
        &init,
        "dop853",
        1e-11,
        3.0,
        1e-4,
    ))
    .unwrap();
    assert!(c.completed(), "{:?}", c.failure);
    let c_rev = first_reversal(&c).unwrap();
    assert!(
        c.diagnostics.energy_drift_max < 1e-9,
        "{:e}",
        c.diagnostics.energy_drift_max
    );
    let (a, _) = run(&args(
        "embedding",
        &params,
        &init,
        "radau5",
        1e-10,
        3.0,
        1e-4,
    ))
    .unwrap();
    let stop = match &a.failure {
        Some(IntegrateError::Stopped { t, .. }) => *t,
        other => panic!("A should stop at the reversal, got {other:?}"),
    };
    eprintln!("up the slope: B reverses at {b_rev:.6}, C at {c_rev:.6}, A stops at {stop:.6}");
    assert!((stop - c_rev).abs() < 1e-3);
}

/// The branch effect (spec): for a sleigh moving backwards, atan2(ẏ, ẋ) is
/// the heading plus π. A refuses such data unless asked (branch = map). With
/// the paper's potential φ enters Θ only through φ̇, so A still reproduces
/// C; with gravity at the centre of mass the flipped branch flips the sign
/// of the gravity torque in Θ: C's Taylor coefficients then violate A's
/// hidden constraints, and from C's q̈ alone A follows different physics.
#[test]
fn branch_effect_for_backward_motion() {
    let backward = ["phi=0.2", "u=-1", "omega=0.4"];
    let strict = run(&args(
        "embedding",
        &["potential=com"],
        &backward,
        "radau5",
        1e-10,
        0.3,
        1e-3,
    ));
    let msg = strict.expect_err("refused").to_string();
    assert!(
        msg.contains("backward motion") && msg.contains("branch=map"),
        "{msg}"
    );

    let with_map = |potential: &str, init: &[&str]| {
        let mut spec = args(
            "embedding",
            &[&format!("potential={potential}")],
            init,
            "radau5",
            1e-10,
            0.3,
            1e-3,
        );
        spec.options = vec!["branch=map".into()];
        run(&spec)
    };
    // Paper's potential: A matched with C agrees with C.
    let (a, _) = with_map("paper", &backward).unwrap();
    let (c, _) = run(&args(
        "vakonomic",
        &["potential=paper"],
        &backward,
        "dop853",
        1e-12,
        0.3,
        1e-3,
    ))
    .unwrap();
    let n = a.samples.len().min(c.samples.len());
    let worst = (0..n)
        .map(|i| {
            (a.samples[i].q[0] - c.samples[i].q[0])
                .abs()
                .max((a.samples[i].q[1] - c.samples[i].q[1]).abs())
        })
        .fold(0.0, f64::max);
    assert!(worst < 1e-7, "paper potential, backward: {worst:e}");
    // A's heading column is C's plus π.
    let dphi = a.samples[n - 1].q[2] - c.samples[n - 1].q[2];
    assert!((dphi.abs() - std::f64::consts::PI).abs() < 1e-6, "{dphi}");

    // Gravity at the centre of mass: C's q⃛ violates A's hidden constraints.
    let e = with_map("com", &backward).expect_err("refused").to_string();
    assert!(e.contains("hidden constraints"), "{e}");
    // From C's q̈ alone (q⃛ completed by A) A follows different physics.
    let (c, _) = run(&args(
        "vakonomic",
        &["potential=com"],
        &backward,
        "dop853",
        1e-12,
        0.3,
        1e-3,
    ))
    .unwrap();
    let (phi, u, omega): (f64, f64, f64) = (0.2, -1.0, 0.4);
    // C's q̈ at t = 0 by Taylor-mode differentiation of C's right-hand side.
    let mut c_model = nonholo_vakonomic::Vakonomic::new(
        nonholo_scenes::Sleigh::from_params(
            &nonholo_core::Params::resolve(
                nonholo_scenes::sleigh::INFO.params,
                &[("potential".into(), "com".into())],
                "parameter",
            )
            .unwrap(),
        )
        .unwrap(),
        nonholo_core::Params::defaults(nonholo_vakonomic::OPTIONS),
    )
    .unwrap();
    let y = [0.0, 0.0, phi, u * phi.cos(), u * phi.sin(), omega, 0.0];
    let (mut yd, mut ydd, mut yddd) = ([0.0; 7], [0.0; 7], [0.0; 7]);
    c_model
        .taylor(0.0, &y, &mut yd, &mut ydd, &mut yddd)
        .unwrap();
    let (xs, ys) = (format!("x_ddot={}", yd[3]), format!("y_ddot={}", yd[4]));
    let mut init = backward.to_vec();
    init.push(&xs);
    init.push(&ys);
    let (a, _) = with_map("com", &init).unwrap();
    let n = a.samples.len().min(c.samples.len());
    let apart = (0..n)
        .map(|i| {
            (a.samples[i].q[0] - c.samples[i].q[0])
                .abs()
                .max((a.samples[i].q[1] - c.samples[i].q[1]).abs())
        })
        .fold(0.0, f64::max);
    eprintln!(
        "com potential, backward: A and C drift {apart:.3e} apart within {:.2} s",
        a.solution.t_last
    );
    assert!(apart > 1e-4, "{apart:e}");
}

/// The inverse map: from A's explicit q̈ (here: C's at λ0 = 0.7) the lab
/// recovers λ0 through C's exact ∂q̈/∂λ, and reports how far C's q⃛ at that
/// λ0 is from A's given q⃛.
#[test]
fn inverse_map_recovers_lambda0() {
    use nonholo_lab::matching::prepare_embedding;
    let scene =
        nonholo_scenes::build("sleigh-incline", &[("potential".into(), "com".into())]).unwrap();
    let resolve = |given: &[(&str, &str)]| {
        struct R(Vec<(String, String)>);
        impl nonholo_scenes::SceneVisitor for R {
            type Output = nonholo_core::Initial;
            fn visit<S: Scene>(self, s: S) -> Self::Output {
                let extra: Vec<_> = ["lambda", "x_ddot", "y_ddot", "x_dddot", "y_dddot"]
                    .iter()
                    .map(|n| nonholo_core::init::ExtraName::new(*n, "", ""))
                    .collect();
                nonholo_core::init::resolve(&s, &self.0, &extra).unwrap()
            }
        }
        scene.clone().visit(R(given
            .iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect()))
    };
    let mut matched = resolve(&[("lambda", "0.7")]);
    let forward = prepare_embedding(&scene, &mut matched).unwrap();
    assert_eq!(forward.source, "vakonomic");
    let get = |n: &str| matched.extra(n).unwrap().to_string();
    let (xdd, ydd, xddd, yddd) = (get("x_ddot"), get("y_ddot"), get("x_dddot"), get("y_dddot"));
    let mut explicit = resolve(&[
        ("x_ddot", &xdd),
        ("y_ddot", &ydd),
        ("x_dddot", &xddd),
        ("y_dddot", &yddd),
    ]);
    let back = prepare_embedding(&scene, &mut explicit).unwrap();
    assert_eq!(back.source, "explicit");
    assert!((back.lambda0[0] - 0.7).abs() < 1e-12, "{back:?}");
    assert!(
        back.second_residual < 1e-13 && back.third_residual.unwrap() < 1e-12,
        "{back:?}"
    );
}
