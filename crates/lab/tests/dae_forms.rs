//! B and C as index-1 DAEs with sparse Jacobians (`nonholo_core::dae`,
//! `nonholo_chetaev::dae`, `nonholo_vakonomic::dae`): the coloured
//! Jacobian against central differences of the residual (every entry
//! outside the pattern zero too), the number of colours against the
//! train's length, and the motion under Radau IIA against the ODE form
//! under DOP853 at a tight tolerance.

use nonholo_chetaev::Chetaev;
use nonholo_core::dae::KktDae;
use nonholo_core::integrate::{ImplicitSystem, Method, Options, solve, solve_implicit};
use nonholo_core::{Error, Initial, Model, ParamSpec, Params, RunConfig, Scene, simulate};
use nonholo_scenes::{Sleigh, Train};
use nonholo_vakonomic::Vakonomic;

/// B or C.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Formulation {
    B,
    C,
}
use Formulation::{B, C};

impl Formulation {
    fn specs(self) -> &'static [ParamSpec] {
        match self {
            B => nonholo_chetaev::OPTIONS,
            C => nonholo_vakonomic::OPTIONS,
        }
    }

    fn dae<S: Scene>(self, scene: S, options: Params) -> Result<KktDae<S>, Error> {
        match self {
            B => nonholo_chetaev::dae(scene, options),
            C => nonholo_vakonomic::dae(scene, options),
        }
    }

    fn model<S: Scene>(self, scene: S, options: Params) -> Result<Box<dyn Model>, Error> {
        match self {
            B => nonholo_chetaev::model(scene, options),
            C => nonholo_vakonomic::model(scene, options),
        }
    }
}

fn train(n: usize, h: f64) -> Train {
    let given = vec![
        ("N".to_string(), n.to_string()),
        ("h".to_string(), h.to_string()),
        ("alpha".to_string(), "0.2".to_string()),
    ];
    let p = Params::resolve(nonholo_scenes::trailer::INFO.params, &given, "parameter").unwrap();
    Train::from_params(&p).unwrap()
}

/// B's options with these overrides.
fn options(given: &[(&str, &str)]) -> Params {
    options_of(B, given)
}

/// The options of `f` with these overrides.
fn options_of(f: Formulation, given: &[(&str, &str)]) -> Params {
    let given: Vec<(String, String)> = given
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    Params::resolve(f.specs(), &given, "option").unwrap()
}

/// Deterministic values in `[−1, 1]`.
fn values(count: usize, seed: u64) -> Vec<f64> {
    let mut x = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    (0..count)
        .map(|_| {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((x >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        })
        .collect()
}

/// The sparse Jacobian of `dae` at `y` against central differences of the
/// residual (step 1e-6): every listed entry within `1e-7` of the largest
/// entry of its column (at least 1), every other entry below that too.
fn check_jacobian<S: Scene>(dae: &mut KktDae<S>, y: &[f64]) {
    let dim = dae.dim();
    let sp = dae.sparsity().unwrap();
    let yp = values(dim, 7);
    let mut jy = vec![0.0; sp.jy.len()];
    let mut jyp = vec![0.0; sp.jyp.len()];
    dae.jacobians(0.3, y, &yp, &mut jy, &mut jyp).unwrap();
    let mut listed = vec![0.0; dim * dim];
    let mut is_listed = vec![false; dim * dim];
    for (&(r, c), &v) in sp.jy.iter().zip(&jy) {
        assert!(!is_listed[r * dim + c], "entry ({r}, {c}) listed twice");
        listed[r * dim + c] = v;
        is_listed[r * dim + c] = true;
    }
    let (mut plus, mut minus) = (vec![0.0; dim], vec![0.0; dim]);
    let mut yy = y.to_vec();
    for c in 0..dim {
        let step = 1e-6;
        yy[c] = y[c] + step;
        dae.residual(0.3, &yy, &yp, &mut plus).unwrap();
        yy[c] = y[c] - step;
        dae.residual(0.3, &yy, &yp, &mut minus).unwrap();
        yy[c] = y[c];
        let fd: Vec<f64> = (0..dim)
            .map(|r| (plus[r] - minus[r]) / (2.0 * step))
            .collect();
        let scale = fd.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        for r in 0..dim {
            let got = listed[r * dim + c];
            assert!(
                (got - fd[r]).abs() < 1e-7 * scale,
                "∂F[{}]/∂y[{}] ({}): {got} against differences {} (listed: {})",
                r,
                c,
                dae.component_name(c),
                fd[r],
                is_listed[r * dim + c]
            );
        }
    }
    // ∂F/∂y' is the identity on (q, v) (and C's λ), zero on w.
    assert!(jyp.iter().all(|&v| v == 1.0));
    let (n, s, k) = dae.dims();
    assert_eq!(sp.jyp.len(), dim - (n + s + k));
}

#[test]
fn coloured_jacobian_matches_differences_of_the_residual() {
    for f in [B, C] {
        for (h, stab) in [
            (0.3, options_of(f, &[])),
            (
                0.0,
                options_of(
                    f,
                    &[
                        ("stab", "baumgarte"),
                        ("baumgarte_alpha", "2"),
                        ("baumgarte_beta", "3"),
                    ],
                ),
            ),
        ] {
            let mut dae = f.dae(train(5, h), stab).unwrap();
            let y = values(dae.dim(), 11);
            check_jacobian(&mut dae, &y);
        }
        let sleigh =
            Sleigh::from_params(&Params::defaults(nonholo_scenes::sleigh::INFO.params)).unwrap();
        let mut dae = f.dae(sleigh, options_of(f, &[])).unwrap();
        let y = values(dae.dim(), 3);
        check_jacobian(&mut dae, &y);
    }
}

/// The colouring finds a number of groups that does not grow with the
/// train, at the lengths tried (2 to 200): a Jacobian costs a fixed number
/// of program passes (5 from two sleighs on, 8 with Baumgarte
/// stabilisation).
#[test]
fn colours_do_not_grow_with_the_train() {
    let colours: Vec<usize> = [4, 10, 40, 200]
        .iter()
        .map(|&n| {
            nonholo_chetaev::dae(train(n, 0.3), options(&[]))
                .unwrap()
                .colours()
        })
        .collect();
    eprintln!("colours for N = 4, 10, 40, 200: {colours:?}");
    // 5 at each N tried (the (q, v) block has 6N columns); 4 for one sleigh.
    assert!(colours.iter().all(|&c| c == 5), "{colours:?}");
    let one = nonholo_chetaev::dae(train(1, 0.3), options(&[])).unwrap();
    assert_eq!(one.colours(), 4);
    // C's rows also depend on λ (its field L + λᵀg): its λ columns fit
    // into B's 5 groups, at each length tried.
    let c: Vec<usize> = [2, 10, 40, 200]
        .iter()
        .map(|&n| C.dae(train(n, 0.3), options_of(C, &[])).unwrap().colours())
        .collect();
    eprintln!("C's colours for N = 2, 10, 40, 200: {c:?}");
    assert!(c.iter().all(|&x| x == 5), "{c:?}");
    // Baumgarte's terms (g, ḟ, f in the rows) couple more columns: 8.
    let baumgarte = options(&[("stab", "baumgarte")]);
    for n in [2, 10, 40] {
        let dae = nonholo_chetaev::dae(train(n, 0.3), baumgarte.clone()).unwrap();
        assert_eq!(dae.colours(), 8, "N = {n}");
    }
}

/// Five sleighs over 2 s: Radau IIA on the DAE (sparse iteration
/// matrices) against DOP853 on the ODE form at rtol 1e-12, positions and
/// velocities at the end, and the multipliers of the DAE's state against
/// the KKT solve at the ODE's final state.
#[test]
fn dae_motion_is_b_motion() {
    let tr = train(5, 0.3);
    let q = tr.default_q();
    let mut qd = vec![0.0; q.len()];
    tr.velocities_from(&q, &[1.0, 0.6], &mut qd);
    let n = q.len();
    let mut ode = Chetaev::new(tr.clone(), Params::defaults(nonholo_chetaev::OPTIONS)).unwrap();
    let y0 = [q.clone(), qd.clone()].concat();
    let tight = Options {
        rtol: 1e-12,
        atol: 1e-12,
        ..Options::default()
    };
    let reference = solve(Method::Dop853, &mut ode, 0.0, &y0, 2.0, &tight).unwrap();
    let mut dae = nonholo_chetaev::dae(tr, options(&[])).unwrap();
    let (y, yp) = dae.initial(0.0, &q, &qd, &[]).unwrap();
    let opts = Options {
        rtol: 1e-9,
        atol: 1e-9,
        ..Options::default()
    };
    let run = solve_implicit(&mut dae, 0.0, &y, &yp, 2.0, &opts).unwrap();
    let err = reference
        .y_last
        .iter()
        .zip(&run.y_last[..2 * n])
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    let st = &run.stats;
    eprintln!(
        "DAE Radau: steps {} rejected {} F {} jac {} lu {}; error {err:e}",
        st.steps, st.rejected_steps, st.rhs_evals, st.jacobian_evals, st.lu_decompositions
    );
    // Measured 3.2e-11; docs/performance.md §9 says 1e-9.
    assert!(err < 1e-9, "DAE against ODE: {err:e}");
    // w at the end is the KKT solution at the end state.
    let (y_end, _) = dae
        .initial(2.0, &run.y_last[..n], &run.y_last[n..2 * n], &[])
        .unwrap();
    let w_err = y_end[2 * n..]
        .iter()
        .zip(&run.y_last[2 * n..])
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(w_err < 1e-6, "w against the KKT solution: {w_err:e}");
}

/// C on five sleighs over 2 s from `λ0 ≠ 0`: Radau IIA on the DAE against
/// DOP853 on C's ODE form at rtol 1e-12, `(q, q̇, λ)` at the end.
#[test]
fn dae_motion_is_c_motion() {
    let tr = train(5, 0.3);
    let q = tr.default_q();
    let mut qd = vec![0.0; q.len()];
    tr.velocities_from(&q, &[1.0, 0.6], &mut qd);
    let lambda = [0.3, 0.0, -0.2, 0.1, 0.0];
    let n = q.len();
    let mut ode = Vakonomic::new(tr.clone(), Params::defaults(nonholo_vakonomic::OPTIONS)).unwrap();
    let y0 = [&q[..], &qd, &lambda].concat();
    let tight = Options {
        rtol: 1e-12,
        atol: 1e-12,
        ..Options::default()
    };
    let reference = solve(Method::Dop853, &mut ode, 0.0, &y0, 2.0, &tight).unwrap();
    let mut dae = C.dae(tr, options_of(C, &[])).unwrap();
    let (y, yp) = dae.initial(0.0, &q, &qd, &lambda).unwrap();
    let opts = Options {
        rtol: 1e-9,
        atol: 1e-9,
        ..Options::default()
    };
    let run = solve_implicit(&mut dae, 0.0, &y, &yp, 2.0, &opts).unwrap();
    let d = 2 * n + lambda.len();
    let err = reference
        .y_last
        .iter()
        .zip(&run.y_last[..d])
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    let moved = reference.y_last[2 * n..]
        .iter()
        .zip(&lambda)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    let size = reference.y_last.iter().fold(1.0f64, |m, v| m.max(v.abs()));
    eprintln!("C: DAE against ODE {err:e} (largest entry {size:.1}); λ moved by {moved:e}");
    assert!(moved > 1e-2, "λ changes along the motion: {moved:e}");
    // λ grows to tens here: the DAE run's rtol 1e-9 relative to it
    // (measured 4.5e-8 against a largest entry of 26.9, 1.7e-9 of it).
    assert!(err < 1e-8 * size, "DAE against ODE: {err:e}");
}

/// A run as the lab makes it, `form = "dae"` against the ODE form: ten
/// sleighs over 2 s with Radau IIA (DAE, rtol 1e-9) and DOP853 (ODE, rtol
/// 1e-12), sampled at 0, 1, 2 s: positions, velocities and multipliers
/// agree, the diagnostics are B's (constraint residual, energy drift at
/// every accepted step), and an explicit integrator or a projection is
/// refused with the reason.
#[test]
fn dae_form_runs_as_a_model() {
    for f in [B, C] {
        runs_as_a_model(f);
    }
}

/// Both forms take the same initial data by name: C's `lambda1`, … (which
/// `--init` and experiment files give), none beyond the coordinates for B.
#[test]
fn both_forms_take_the_same_initial_names() {
    for f in [B, C] {
        let names = |form: &str| -> Vec<String> {
            f.model(train(3, 0.3), options_of(f, &[("form", form)]))
                .unwrap()
                .extra_init_names()
                .iter()
                .map(|e| e.name.to_string())
                .collect()
        };
        let (ode, dae) = (names("ode"), names("dae"));
        assert_eq!(ode, dae, "{f:?}");
        let expected: Vec<String> = match f {
            B => Vec::new(),
            C => vec!["lambda1".into(), "lambda2".into(), "lambda3".into()],
        };
        assert_eq!(dae, expected, "{f:?}");
    }
}

fn runs_as_a_model(f: Formulation) {
    let options = |given: &[(&str, &str)]| options_of(f, given);
    let tr = train(10, 0.3);
    let q = tr.default_q();
    let mut qd = vec![0.0; q.len()];
    tr.velocities_from(&q, &[1.0, 0.6], &mut qd);
    // C from a λ0 that is not zero on every blade.
    let extra = match f {
        B => Vec::new(),
        C => vec![("lambda1".to_string(), 0.2), ("lambda4".to_string(), -0.1)],
    };
    let initial = Initial {
        t0: 0.0,
        q,
        qd,
        extra,
    };
    let config = |method, tol: f64| RunConfig {
        method,
        options: Options {
            rtol: tol,
            atol: tol,
            output: vec![0.0, 1.0, 2.0],
            ..Options::default()
        },
        t_end: 2.0,
        project_init: false,
    };
    let ode = f.model(tr.clone(), options(&[])).unwrap();
    let reference = simulate(ode, initial.clone(), config(Method::Dop853, 1e-12)).unwrap();
    let dae = f.model(tr.clone(), options(&[("form", "dae")])).unwrap();
    let run = simulate(dae, initial.clone(), config(Method::Radau5, 1e-9)).unwrap();
    assert!(run.failure.is_none(), "{:?}", run.failure);
    assert_eq!(run.samples.len(), 3);
    let mut worst = (0.0f64, 0.0f64);
    // Sizes of the reference's (q, q̇) and multipliers (C's λ grows to
    // tens), against which the differences are read.
    let mut size = (1.0f64, 1.0f64);
    for a in &reference.samples {
        let big = |u: &[f64]| u.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        size.0 = size.0.max(big(&a.q)).max(big(&a.qd));
        size.1 = size.1.max(big(&a.multipliers));
    }
    for (a, b) in reference.samples.iter().zip(&run.samples) {
        let d = |u: &[f64], v: &[f64]| {
            u.iter()
                .zip(v)
                .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        };
        worst.0 = worst.0.max(d(&a.q, &b.q)).max(d(&a.qd, &b.qd));
        worst.1 = worst.1.max(d(&a.multipliers, &b.multipliers));
    }
    let diag = &run.diagnostics;
    eprintln!(
        "{f:?} DAE model: (q, q̇) {:.1e}, multipliers {:.1e} (sizes {:.1}, {:.1}); residual \
         {:.1e}, energy drift {:.1e}, states {}",
        worst.0,
        worst.1,
        size.0,
        size.1,
        diag.constraint_residual_max,
        diag.energy_drift_max,
        diag.states_checked
    );
    assert!(
        // Measured 1.3e-10 and 1.7e-9 of (q, q̇) (B, C: C's λ reaches 1e3,
        // its motion is the more sensitive), 3e-9 of the multipliers (both).
        worst.0 < 1e-8 * size.0 && worst.1 < 1e-7 * size.1,
        "{worst:?} against sizes {size:?}"
    );
    assert_eq!(diag.states_checked, run.solution.stats.steps + 1);
    assert!(diag.constraint_residual_max < 1e-8, "{diag:?}");
    // The train on an incline (α = 0.2) exchanges potential and kinetic
    // energy; the total is conserved by the motion.
    assert!(diag.energy_drift_max < 1e-7, "{diag:?}");
    assert_eq!(run.model.multiplier_names().len(), 10 + 18);

    let dae = f.model(tr.clone(), options(&[("form", "dae")])).unwrap();
    let e = simulate(dae, initial.clone(), config(Method::Dop853, 1e-8))
        .unwrap_err()
        .to_string();
    assert!(e.contains("radau5") && e.contains("dae"), "{e}");
    let dae = f.model(tr.clone(), options(&[("form", "dae")])).unwrap();
    let mut full = config(Method::Radau5, 1e-8);
    full.options.radau5.newton = nonholo_core::integrate::RadauNewton::Full;
    let e = simulate(dae, initial, full).unwrap_err().to_string();
    assert!(
        e.contains("radau_newton = full") && e.contains("sparse"),
        "{e}"
    );
    let e = f
        .model(tr, options(&[("form", "dae"), ("stab", "projection")]))
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("projection"), "{e}");
}
