//! Start-up of formulation A in two cases of the extreme-sleigh catalogue
//! (`experiments/extreme-sleigh.toml`: α = 0.3, φ0 = 0.2, u0 = 2 m/s, A
//! matched with the vakonomic motion C at λ0 = 0), both of which used to be
//! refused as "inconsistent initial data":
//!
//! * `a = 50 m, J = 2501 m²` (ω0 = 0.7): C's data satisfy A's hidden
//!   constraints to 1e-15, but the completion's Levenberg–Marquardt steps
//!   came from the normal matrix `J Jᵀ` of a scaled Jacobian with condition
//!   ~4e8 and stalled at a relative residual of ~5e-10 (a numerical
//!   artefact; steps now come from the SVD).
//! * `ω0 = 0`: the hidden constraints' Jacobian in `q⃛` is singular (rank 1:
//!   `det ∂(h₁, h₂)/∂(φ̈, ü) = −Jω/u`), so `q⃛` is not fixed by
//!   `(q, q̇, q̈)`. C's `q⃛` lies on A's manifold, but a completion that also
//!   had to find `q⁗ … q⁽⁶⁾` from scratch moved it by 0.78 along the free
//!   direction and the move was then read as an inconsistency. Given `q⃛`
//!   are now kept (the completion starts from the check), and missing ones
//!   are refused with the singular values.

mod common;

use common::*;
use nalgebra::DMatrix;
use nonholo_core::integrate::{IntegrateError, Method};
use nonholo_core::{Error, Model, Params, Run, Scene, simulate};
use nonholo_embedding::analysis::{RANK_TOL, complete, derivative_array, third_determination};
use nonholo_embedding::{Embedding, OPTIONS};
use nonholo_scenes::Sleigh;

fn sleigh(a: f64, j: f64) -> Sleigh {
    let given = vec![
        ("a".to_string(), a.to_string()),
        ("J".to_string(), j.to_string()),
        ("alpha".to_string(), "0.3".to_string()),
    ];
    Sleigh::from_params(&Params::resolve(Sleigh::INFO.params, &given, "parameter").unwrap())
        .unwrap()
}

/// A stopping at the singular set (the start-up is what these tests are about).
fn embedding(s: &Sleigh) -> Embedding<Sleigh> {
    let given = vec![
        ("continuation".to_string(), "none".to_string()),
        ("stab".to_string(), "projection".to_string()),
    ];
    Embedding::new(
        s.clone(),
        Params::resolve(OPTIONS, &given, "option").unwrap(),
    )
    .unwrap()
}

/// `d = (q, q̇, q̈, q⃛, 0, 0, 0)` of `(x, y)` from C at `y`.
fn array_from_c(s: &Sleigh, y: &[f64; 7]) -> Vec<f64> {
    let (second, third) = taylor(s, y);
    let mut d = vec![0.0; 14];
    d[2] = y[3];
    d[3] = y[4];
    d[4..6].copy_from_slice(&second);
    d[6..8].copy_from_slice(&third);
    d
}

fn run_c(s: &Sleigh, y: &[f64; 7], t_end: f64) -> Run {
    let run = run_c_tol(s, y, t_end, 1e-2, 1e-13);
    assert!(run.completed(), "{:?}", run.failure);
    run
}

/// Singular values of the row-scaled Jacobian of `[E; Ė; Ë]` in
/// `(q⃛, q⁗, q⁽⁵⁾, q⁽⁶⁾)` at `d`, largest first.
fn scaled_singular_values(s: &Sleigh, d: &[f64]) -> Vec<f64> {
    let e = Sleigh::INFO.embedding.unwrap();
    let mut v = vec![0.0; 6];
    let mut jac = DMatrix::zeros(6, 14);
    derivative_array(s, &e, 0.0, d, &[], &mut v, &mut jac);
    let scale: Vec<f64> = (0..6)
        .map(|l| 1.0 + (0..14).map(|j| (jac[(l, j)] * d[j]).abs()).sum::<f64>())
        .collect();
    let js = DMatrix::from_fn(6, 8, |l, k| jac[(l, 6 + k)] / scale[l]);
    let mut sv: Vec<f64> = js
        .svd(false, false)
        .singular_values
        .iter()
        .copied()
        .collect();
    sv.sort_by(|a, b| b.total_cmp(a));
    sv
}

/// a = 50, J = 2501: C's data are on A's manifold to round-off (q⃛ held
/// fixed, the derivatives beyond it reach 1e-14); the scaled Jacobian has
/// condition > 1e8 (its normal matrix > 1e16, no digits left: the old
/// completion stalled at ~5e-10); the completion now reaches 1e-14 moving
/// q⃛ by C's round-off only, and A (explicit form, DOP853) agrees with C
/// to t = 3.
#[test]
fn large_j_starts_and_agrees_with_vakonomic() {
    let s = sleigh(50.0, 2501.0);
    let e = Sleigh::INFO.embedding.unwrap();
    let y0 = c_state(0.2, 2.0, 0.7, 0.0);
    let d0 = array_from_c(&s, &y0);

    let mut fixed = d0.clone();
    let c = complete(&s, &e, 0.0, &mut fixed, false, 1e-14).unwrap();
    assert!(c.residual.1 <= 1e-14, "{c:?}");
    let sv = scaled_singular_values(&s, &fixed);
    let cond = sv[0] / sv[5];
    eprintln!("a = 50, J = 2501: scaled Jacobian in (q⃛, u): σ = {sv:?}, condition {cond:.2e}");
    assert!(cond > 1e8 && cond < 1e10, "{cond:e}");

    let mut d = d0.clone();
    let done = complete(&s, &e, 0.0, &mut d, true, 1e-14).unwrap();
    let third_scale = d[6].abs().max(d[7].abs()).max(1.0);
    eprintln!("completion from C's data: {done:?}");
    assert!(done.residual.1 <= 1e-14, "{done:?}");
    assert!(done.third_unique, "{done:?}");
    assert!(done.third_change < 1e-8 * third_scale, "{done:?}");
    // q⃛ is determined, if poorly conditioned: σ_min/σ_max(h_z) ≈ 9e-7,
    // within three orders of the rank threshold.
    let smallest = done.third_singular_values[1];
    assert!(smallest > 1e2 * RANK_TOL && smallest < 1e-5, "{done:?}");

    // Through the model, as the catalogue starts it.
    let mut a = embedding(&s);
    let init = matched(&s, &y0, true);
    a.initial_state(&init).unwrap();
    let report = a.report().unwrap();
    assert!(report.completion.residual.1 <= 1e-14, "{report:?}");
    assert_eq!(report.structure.hidden_constraints, 2, "{report:?}");
    assert_eq!(report.structure.free_initial_data, 6, "{report:?}");

    let t_end = 3.0;
    let c_run = run_c(&s, &y0, t_end);
    let ode = simulate(
        Box::new(embedding(&s)),
        init.clone(),
        config(Method::Dop853, 1e-10, t_end, 1e-2),
    )
    .unwrap();
    assert!(ode.completed(), "{:?}", ode.failure);
    let vs_c = position_difference(&ode, &c_run);
    let dae = simulate(
        Box::new(embedding(&s)),
        init,
        config(Method::Radau5, 1e-10, t_end, 1e-2),
    )
    .unwrap();
    assert!(dae.completed(), "{:?}", dae.failure);
    let dae_c = position_difference(&dae, &c_run);
    eprintln!(
        "a = 50, J = 2501 to t = {t_end} at rtol 1e-10: A-DOP853 vs C {vs_c:.1e}, \
         A-Radau vs C {dae_c:.1e} (the implicit form's own accuracy at large J)"
    );
    assert!(vs_c < 1e-8, "{vs_c:e}");
}

/// ω0 = 0: the derivation of `third_determination`'s documentation, checked.
/// On C's data (λ0 = 0) the first hidden constraint reads `u̇ = g sin α cos φ`;
/// the hidden constraints' Jacobian in q⃛ has one zero singular value at
/// ω = 0, and the smallest grows linearly in ω (det = −Jω/u).
#[test]
fn zero_turning_rate_leaves_third_derivatives_free() {
    let s = sleigh(0.4, 1.0);
    let e = Sleigh::INFO.embedding.unwrap();
    let (phi, g_s) = (0.2f64, 9.81 * 0.3f64.sin());
    let y0 = c_state(0.2, 2.0, 0.0, 0.0);
    let d = array_from_c(&s, &y0);
    let tangential = d[4] * phi.cos() + d[5] * phi.sin();
    let normal = -d[4] * phi.sin() + d[5] * phi.cos();
    assert!(
        (tangential - g_s * phi.cos()).abs() < 1e-14,
        "u̇ = {tangential}"
    );
    assert!(normal.abs() < 1e-15, "u ω = {normal}");

    let mut smallest = Vec::new();
    for omega in [0.0, 1e-3, 1e-2, 1e-1] {
        let mut d = array_from_c(&s, &c_state(0.2, 2.0, omega, 0.0));
        let done = complete(&s, &e, 0.0, &mut d, false, 1e-14).unwrap();
        assert!(done.residual.1 <= 1e-14, "{done:?}");
        let mut v = vec![0.0; 6];
        let mut jac = DMatrix::zeros(6, 14);
        derivative_array(&s, &e, 0.0, &d, &[], &mut v, &mut jac);
        let sv = third_determination(&jac, &d, 2).unwrap();
        eprintln!("ω = {omega:e}: singular values of the hidden constraints in q⃛ {sv:?}");
        assert!(sv[0] > 0.05, "{sv:?}");
        smallest.push(sv[1]);
    }
    assert!(smallest[0] < 1e-14, "{smallest:?}");
    // Linear in ω: σ_min/ω the same to 1 % over two decades.
    let slope: Vec<f64> = smallest[1..]
        .iter()
        .zip([1e-3, 1e-2, 1e-1])
        .map(|(s, w)| s / w)
        .collect();
    eprintln!("σ_min/ω = {slope:?}");
    assert!(
        (slope[0] / slope[1] - 1.0).abs() < 0.01,
        "{slope:?} (ω = 1e-3, 1e-2)"
    );
    assert!(
        (slope[0] / slope[2] - 1.0).abs() < 0.05,
        "{slope:?} (ω = 1e-3, 1e-1)"
    );
    assert!(slope[0] > 1e2 * RANK_TOL, "{slope:?}");
}

/// ω0 = 0 with C's q̈ and q⃛ (λ0 = 0, as in the catalogue, and λ0 = 0.5,
/// where φ̈(0) ≠ 0 is the free datum): A keeps the given q⃛ (moved by less
/// than 1e-9), reports that q⃛ is not determined by (q, q̇, q̈), and agrees
/// with C to 1e-8 until its stop (λ0 = 0: DOP853 and Radau at 1e-10 to
/// t = 1.19, just before the explicit form's resolution limit at 1.194).
#[test]
fn zero_turning_rate_starts_from_given_third_derivatives() {
    let s = sleigh(0.4, 1.0);
    for (lambda, t_end) in [(0.0, 1.19), (0.5, 0.5)] {
        let y0 = c_state(0.2, 2.0, 0.0, lambda);
        let init = matched(&s, &y0, true);
        let mut a = embedding(&s);
        a.initial_state(&init).unwrap();
        let report = a.report().unwrap().clone();
        eprintln!("ω0 = 0, λ0 = {lambda}: {:?}", report.completion);
        assert!(!report.completion.third_unique, "{report:?}");
        assert!(
            report.completion.third_singular_values[1] < 1e-14,
            "{report:?}"
        );
        assert!(report.completion.third_change < 1e-9, "{report:?}");
        assert!(report.completion.residual.1 <= 1e-14, "{report:?}");
        assert_eq!(report.structure.hidden_constraints, 2, "{report:?}");
        // The result record carries the same number.
        let listed = a
            .init_report()
            .into_iter()
            .find(|(k, _)| *k == "third_determination")
            .map(|(_, v)| v);
        assert!(listed.is_some_and(|v| v < 1e-14), "{listed:?}");

        let c_run = run_c(&s, &y0, t_end);
        for method in [Method::Dop853, Method::Radau5] {
            let run = simulate(
                Box::new(embedding(&s)),
                init.clone(),
                config(method, 1e-10, t_end, 1e-2),
            )
            .unwrap();
            assert!(run.completed(), "{method:?}: {:?}", run.failure);
            let vs_c = position_difference(&run, &c_run);
            eprintln!("  {method:?} 1e-10 to t = {t_end}: A vs C {vs_c:.1e}");
            assert!(vs_c < 1e-8, "{method:?} λ0 = {lambda}: {vs_c:e}");
        }
    }
    // Run on, both forms stop by design before C's reversal.
    let y0 = c_state(0.2, 2.0, 0.0, 0.0);
    for (method, what) in [
        (Method::Dop853, "resolution limit"),
        (Method::Radau5, "singular set"),
    ] {
        let run = simulate(
            Box::new(embedding(&s)),
            matched(&s, &y0, true),
            config(method, 1e-9, 3.0, 1e-2),
        )
        .unwrap();
        match &run.failure {
            Some(IntegrateError::Stopped { t, reason }) => {
                eprintln!("  {method:?} 1e-9 stops at {t:.6}");
                assert!(reason.contains(what), "{reason}");
                assert!(*t > 1.19 && *t < 1.21, "{t}");
            }
            other => panic!("{method:?}: should stop by design, got {other:?}"),
        }
    }
}

/// ω0 = 0 without q⃛: refused, naming the singular Jacobian; with a
/// tangential acceleration other than g sin α cos φ: refused as a violated
/// hidden constraint that q⃛ cannot repair (not "from this starting guess").
#[test]
fn zero_turning_rate_errors_name_the_singular_quantity() {
    let s = sleigh(0.4, 1.0);
    let y0 = c_state(0.2, 2.0, 0.0, 0.0);
    let msg = match embedding(&s).initial_state(&matched(&s, &y0, false)) {
        Err(Error::InconsistentInit { reason, .. }) => reason,
        other => panic!("{other:?}"),
    };
    eprintln!("{msg}");
    assert!(
        msg.contains("q⃛_I(0) is not determined by (q, q̇, q̈)"),
        "{msg}"
    );
    assert!(msg.contains("Jacobian in q⃛ has singular values ["), "{msg}");
    let values = &msg[msg.find('[').unwrap() + 1..msg.find(']').unwrap()];
    let sv: Vec<f64> = values.split(", ").map(|v| v.parse().unwrap()).collect();
    assert!(sv[0] > 0.05 && sv[1] < 1e-14, "{sv:?}");
    assert!(msg.contains("x_dddot, y_dddot"), "{msg}");

    // u̇ = 2 m/s² along the heading instead of g sin α cos φ = 2.84.
    let mut init = matched(&s, &y0, false);
    init.extra = vec![
        ("x_ddot".into(), 2.0 * 0.2f64.cos()),
        ("y_ddot".into(), 2.0 * 0.2f64.sin()),
    ];
    let msg = match embedding(&s).initial_state(&init) {
        Err(Error::InconsistentInit { reason, .. }) => reason,
        other => panic!("{other:?}"),
    };
    eprintln!("{msg}");
    assert!(
        msg.contains("violate a hidden constraint that does not involve q⃛ here (100%"),
        "{msg}"
    );
    assert!(!msg.contains("starting guess"), "{msg}");
}

/// Zero speed, where the map `φ = atan2(ẏ, ẋ)` has no value: refused at
/// once with the distance from the singular set (it used to send nalgebra's
/// SVD into an endless loop on the non-finite derivative array).
#[test]
fn zero_speed_is_refused_not_looped_on() {
    let s = sleigh(0.4, 1.0);
    let y0 = c_state(0.2, 0.0, 0.7, 0.0);
    let msg = match embedding(&s).initial_state(&matched(&s, &y0, false)) {
        Err(Error::InconsistentInit { reason, .. }) => reason,
        other => panic!("{other:?}"),
    };
    assert!(msg.contains("singular set of the embedding map"), "{msg}");
    assert!(
        msg.contains("within singular_tol = 1.0e-3") && msg.contains("(|r| = 0.000e0)"),
        "{msg}"
    );
}

/// The decomposition behind A's structure analysis refuses non-finite
/// matrices instead of iterating on them.
#[test]
fn svd_of_a_non_finite_matrix_is_an_error() {
    let mut a = DMatrix::from_element(3, 2, 1.0);
    a[(2, 1)] = f64::NAN;
    let e = nonholo_embedding::analysis::svd_of(a, true, true).unwrap_err();
    assert!(e.contains("entry (2, 1)") && e.contains("NaN"), "{e}");
    let ok = nonholo_embedding::analysis::svd_of(DMatrix::identity(3, 3), false, false).unwrap();
    assert_eq!(ok.singular_values.as_slice(), &[1.0, 1.0, 1.0]);
}
