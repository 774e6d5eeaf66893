//! `sleigh-train`: its size parameter, its structure (the sparsity the
//! compiled program finds), the sparse KKT solve against the dense one, and
//! `N = 1` against `sleigh-incline`.

use nonholo_core::compiled::Compiled;
use nonholo_core::kkt::{Ideal, Kkt};
use nonholo_core::scene::{Holonomic, Lagrangian, Nonholonomic, VectorField};
use nonholo_core::stab::Stabilisation;
use nonholo_core::{Error, Params, Scene};
use nonholo_scenes::{Sleigh, Train, build};

fn train(params: &[(&str, &str)]) -> Result<Train, Error> {
    let given: Vec<(String, String)> = params
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    Train::from_params(&Params::resolve(
        nonholo_scenes::trailer::INFO.params,
        &given,
        "parameter",
    )?)
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

#[test]
fn size_follows_n_and_bad_n_is_refused_by_name() {
    let t = train(&[("N", "7")]).unwrap();
    let info = t.info();
    assert_eq!((info.n(), info.s(), info.k()), (21, 7, 12));
    assert_eq!(info.coordinates[20].name, "phi7");
    assert_eq!(info.contacts.len(), 7);
    assert_eq!(t.default_q().len(), 21);
    // The same N gives the same description (built once).
    assert!(std::ptr::eq(info, train(&[("N", "7")]).unwrap().info()));
    let e = train(&[("N", "2.5")]).unwrap_err().to_string();
    assert!(e.contains("N") && e.contains("whole"), "{e}");
    let e = train(&[("N", "0")]).unwrap_err().to_string();
    assert!(e.contains("N"), "{e}");
    let e = train(&[("N", "3"), ("J", "0.1")]).unwrap_err().to_string();
    assert!(e.contains("J > a²"), "{e}");
    assert!(build("sleigh-train", &[("N".into(), "4".into())]).is_ok());
}

/// Every scene states its structural parameters in its description: each
/// is one of its parameters, and only they change the description
/// `describe` returns (the registry's otherwise).
#[test]
fn structural_parameters_are_declared_and_read_from_the_description() {
    for info in nonholo_scenes::ALL {
        for p in info.structural {
            assert!(
                info.params.iter().any(|s| s.name == *p),
                "{}: structural `{p}` is not a parameter",
                info.name
            );
        }
        assert_eq!(nonholo_scenes::structural(info.name), info.structural);
        let d = nonholo_scenes::describe(info.name, &[]).unwrap();
        assert_eq!(d.n(), info.n(), "{}", info.name);
    }
    assert_eq!(nonholo_scenes::structural("sleigh-train"), ["N"]);
    let d = nonholo_scenes::describe("sleigh-train", &[("N".into(), "5".into())]).unwrap();
    assert_eq!((d.n(), d.s(), d.k()), (15, 5, 8));
    let d = nonholo_scenes::describe("sleigh-incline", &[("a".into(), "0.2".into())]).unwrap();
    assert!(std::ptr::eq(
        d,
        nonholo_scenes::info("sleigh-incline").unwrap()
    ));
}

/// The velocities of the chart satisfy every blade (`g = 0`) and every
/// hitch at velocity level (`ḟ = F q̇ = 0`) at any positions: the trailers'
/// rates are found from the pin velocities exactly.
#[test]
fn chart_velocities_satisfy_the_constraints() {
    let t = train(&[("N", "6"), ("h", "0.25"), ("l", "0.7")]).unwrap();
    let info = t.info();
    let n = info.n();
    for seed in 1..6 {
        let q: Vec<f64> = values(n, seed).iter().map(|v| 3.0 * v).collect();
        let chart = values(2, 100 + seed);
        let mut qd = vec![0.0; n];
        t.velocities_from(&q, &chart, &mut qd);
        let mut g = vec![0.0; info.s()];
        Nonholonomic(&t).eval(0.0, &q, &qd, &mut g);
        assert!(g.iter().all(|v| v.abs() < 1e-14), "g = {g:?}");
        // ḟ by a central difference of f along q + τ q̇ (f is trigonometric:
        // the difference is exact to O(τ²) ≈ 1e-12 of its scale).
        let tau = 1e-6;
        let shifted = |sgn: f64| -> Vec<f64> {
            let qs: Vec<f64> = q.iter().zip(&qd).map(|(a, b)| a + sgn * tau * b).collect();
            let mut f = vec![0.0; info.k()];
            Holonomic(&t).eval(0.0, &qs, &qd, &mut f);
            f
        };
        let (fp, fm) = (shifted(1.0), shifted(-1.0));
        for (a, b) in fp.iter().zip(&fm) {
            assert!(
                ((a - b) / (2.0 * tau)).abs() < 1e-8,
                "ḟ = {}",
                (a - b) / (2.0 * tau)
            );
        }
        let mut chart_back = [0.0; 2];
        assert!(t.chart_from(&q, &qd, &mut chart_back));
        assert!(
            (chart_back[0] - chart[0]).abs() < 1e-15 && (chart_back[1] - chart[1]).abs() < 1e-15
        );
    }
}

/// The structural nonzeros the compiled program finds at `N = 20`: per
/// sleigh the five entries `(x,x) (x,φ) (y,y) (y,φ) (φ,φ)` of the upper
/// triangle of `M`; per blade `∂g/∂ẋ`, `∂g/∂ẏ`; per hitch row the four
/// entries `xᵢ, φᵢ, xᵢ₊₁, φᵢ₊₁` (or `y`). With `h = 0` the pin sits on the
/// blade and `∂f/∂φᵢ` vanishes from the pattern.
#[test]
fn sparsity_pattern_at_n_20() {
    for (h, per_hitch_row) in [("0.3", 4), ("0", 3)] {
        let t = train(&[("N", "20"), ("h", h)]).unwrap();
        let c = Compiled::new(&Lagrangian(&t), 0, &t).unwrap();
        let p = c.pattern();
        let mut mass = Vec::new();
        let mut g = Vec::new();
        let mut f = Vec::new();
        for i in 0..20u32 {
            let (x, y, phi) = (3 * i, 3 * i + 1, 3 * i + 2);
            mass.extend([(x, x), (x, phi), (y, y), (y, phi), (phi, phi)]);
            g.extend([(i, x), (i, y)]);
        }
        for i in 0..19u32 {
            let (a, b) = (3 * i, 3 * i + 3);
            for (r, c) in [(2 * i, 0), (2 * i + 1, 1)] {
                if per_hitch_row == 4 {
                    f.extend([(r, a + c), (r, a + 2), (r, b + c), (r, b + 2)]);
                } else {
                    f.extend([(r, a + c), (r, b + c), (r, b + 2)]);
                }
            }
        }
        assert_eq!(p.mass, mass, "h = {h}");
        assert_eq!(p.g_jac, g, "h = {h}");
        assert_eq!(p.f_jac, f, "h = {h}");
    }
}

/// The sparse KKT solve (faer's LU) and the dense one (partial pivoting)
/// give the same `q̈` and multipliers to 1e-12 relative, at `N = 20`, with
/// and without Baumgarte gains.
#[test]
fn sparse_and_dense_solves_agree_at_n_20() {
    let t = train(&[("N", "20")]).unwrap();
    let info = t.info();
    let n = info.n();
    let c = std::sync::Arc::new(Compiled::new(&Lagrangian(&t), 0, &t).unwrap());
    let mut sparse: Kkt<f64> = Kkt::for_scene(info);
    sparse.use_program(c.clone());
    assert!(sparse.is_sparse());
    let mut dense: Kkt<f64> = Kkt::for_scene(info);
    dense.use_program(c);
    dense.force_dense();
    assert!(!dense.is_sparse());
    for (seed, stab) in [
        (1, Stabilisation::None),
        (2, Stabilisation::None),
        (
            3,
            Stabilisation::Baumgarte {
                alpha: 3.0,
                beta: 4.0,
            },
        ),
    ] {
        let q: Vec<f64> = values(n, seed).iter().map(|v| 2.0 * v).collect();
        let qd = values(n, 50 + seed);
        for k in [&mut sparse, &mut dense] {
            k.solve(&Lagrangian(&t), &[], &t, &Ideal(stab), 0.3, &q, &qd)
                .unwrap();
        }
        let scale = dense.sol_mut().iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let worst = sparse
            .qdd()
            .iter()
            .chain(sparse.mu())
            .zip(dense.qdd().iter().chain(dense.mu()))
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(
            worst < 1e-12 * scale,
            "seed {seed}: {worst:e} against {scale:e}"
        );
    }
}

/// One sleigh is `sleigh-incline` with gravity at the centre of mass: the
/// same `q̈` and `λ` at any state.
#[test]
fn one_sleigh_is_the_sleigh_on_the_incline() {
    let t = train(&[("N", "1"), ("a", "0.3"), ("J", "1.4"), ("alpha", "0.4")]).unwrap();
    let s = Sleigh::from_params(
        &Params::resolve(
            nonholo_scenes::sleigh::INFO.params,
            &[
                ("a".into(), "0.3".into()),
                ("J".into(), "1.4".into()),
                ("alpha".into(), "0.4".into()),
                ("potential".into(), "com".into()),
            ],
            "parameter",
        )
        .unwrap(),
    )
    .unwrap();
    let mut kt: Kkt<f64> = Kkt::for_scene(t.info());
    let mut ks: Kkt<f64> = Kkt::for_scene(s.info());
    for seed in 1..8 {
        let q: Vec<f64> = values(3, seed).iter().map(|v| 3.0 * v).collect();
        let qd = values(3, 20 + seed);
        let rows = Ideal(Stabilisation::None);
        kt.solve(&Lagrangian(&t), &[], &t, &rows, 0.0, &q, &qd)
            .unwrap();
        ks.solve(&Lagrangian(&s), &[], &s, &rows, 0.0, &q, &qd)
            .unwrap();
        for (a, b) in kt.sol_mut().iter().zip(ks.sol_mut().iter()) {
            assert!((a - b).abs() < 1e-13 * (1.0 + b.abs()), "{a} against {b}");
        }
    }
}

/// Over `Dual64` (a Jacobian column: the state moved along a direction)
/// the sparse solve's derivative part, from one real factorisation, equals
/// the dense LU run on dual numbers, to 1e-12 relative, at `N = 20`.
#[test]
fn sparse_and_dense_dual_solves_agree_at_n_20() {
    use num_dual::Dual64;
    let t = train(&[("N", "20")]).unwrap();
    let info = t.info();
    let n = info.n();
    let c = std::sync::Arc::new(Compiled::new(&Lagrangian(&t), 0, &t).unwrap());
    let mut sparse: Kkt<Dual64> = Kkt::for_scene(info);
    sparse.use_program(c.clone());
    assert!(sparse.is_sparse());
    let mut dense: Kkt<Dual64> = Kkt::for_scene(info);
    dense.use_program(c);
    dense.force_dense();
    for seed in 1..4 {
        let (q0, qd0) = (values(n, seed), values(n, 70 + seed));
        let (dq, dqd) = (values(n, 30 + seed), values(n, 90 + seed));
        let q: Vec<Dual64> = q0
            .iter()
            .zip(&dq)
            .map(|(a, b)| Dual64::new(2.0 * a, *b))
            .collect();
        let qd: Vec<Dual64> = qd0
            .iter()
            .zip(&dqd)
            .map(|(a, b)| Dual64::new(*a, *b))
            .collect();
        let rows = Ideal(Stabilisation::Baumgarte {
            alpha: 2.0,
            beta: 3.0,
        });
        for k in [&mut sparse, &mut dense] {
            k.solve(&Lagrangian(&t), &[], &t, &rows, Dual64::from(0.2), &q, &qd)
                .unwrap();
        }
        let (a, b) = (sparse.sol_mut().to_vec(), dense.sol_mut().to_vec());
        for part in [|x: &Dual64| x.re, |x: &Dual64| x.eps] {
            let scale = b.iter().map(part).fold(0.0f64, |m, v| m.max(v.abs()));
            let worst = a
                .iter()
                .zip(&b)
                .fold(0.0f64, |m, (x, y)| m.max((part(x) - part(y)).abs()));
            assert!(
                worst < 1e-12 * scale,
                "seed {seed}: {worst:e} against {scale:e}"
            );
        }
    }
}

/// The check of initial data reads the same distances from the compiled
/// program (sparse rows) as from the scalar passes (a dense Jacobian):
/// consistent data pass both ways, data off a blade or off a hitch are
/// refused both ways at the same level, with the same distance and
/// residuals.
#[test]
fn compiled_check_of_initial_data_matches_the_dense_one() {
    use nonholo_core::consistency::check_or_project_with;
    use nonholo_core::{Initial, Level};
    let t = train(&[("N", "5"), ("h", "0.3"), ("alpha", "0.2")]).unwrap();
    let program = Compiled::new(&Lagrangian(&t), 0, &t).unwrap();
    let q = t.default_q();
    let mut qd = vec![0.0; q.len()];
    t.velocities_from(&q, &[1.0, 0.4], &mut qd);
    let base = Initial {
        t0: 0.0,
        q,
        qd,
        extra: Vec::new(),
    };
    let verdict = |init: &Initial, program: Option<&Compiled>| {
        check_or_project_with(&t, &mut init.clone(), false, program)
    };
    assert!(verdict(&base, None).unwrap().is_none());
    assert!(verdict(&base, Some(&program)).unwrap().is_none());
    let mut off_blade = base.clone();
    off_blade.qd[4] += 1e-5;
    let mut off_hitch = base.clone();
    off_hitch.q[7] += 1e-5;
    for (init, level) in [
        (off_blade, Level::Velocities),
        (off_hitch, Level::Positions),
    ] {
        let dense = verdict(&init, None).unwrap_err();
        let sparse = verdict(&init, Some(&program)).unwrap_err();
        match (dense, sparse) {
            (
                Error::OffConstraints {
                    level: a,
                    residuals: ra,
                    distance: da,
                    ..
                },
                Error::OffConstraints {
                    level: b,
                    residuals: rb,
                    distance: db,
                    ..
                },
            ) => {
                assert_eq!((a, b), (level, level));
                assert!((da - db).abs() <= 1e-12 * da, "{da} against {db}");
                assert_eq!(ra.len(), rb.len());
                for ((na, va), (nb, vb)) in ra.iter().zip(&rb) {
                    assert_eq!(na, nb);
                    assert!((va - vb).abs() <= 1e-14, "{na}: {va} against {vb}");
                }
            }
            other => panic!("{other:?}"),
        }
    }
}

/// Headings alone state a train's shape: trailers whose blades are not
/// given are put where their hitches hold them (folded, bent), the default
/// line is left to the last bit, and a blade that is given stays where it
/// is (then refused later if its hitch does not hold).
#[test]
fn trailers_follow_their_headings_when_their_blades_are_not_given() {
    use nonholo_core::init::resolve;
    let t = train(&[("N", "4"), ("h", "0.3"), ("l", "0.5")]).unwrap();
    let given = |pairs: &[(&str, &str)]| -> Vec<(String, String)> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    };
    let hitches = |q: &[f64]| {
        let mut f = vec![0.0; 6];
        Holonomic(&t).eval(0.0, q, &[], &mut f);
        f.iter().fold(0.0_f64, |m, v| m.max(v.abs()))
    };
    // The default line, untouched.
    let line = resolve(&t, &[], &[]).unwrap();
    assert_eq!(line.q, t.default_q());
    // Folded behind the lead, bent after it, the lead moved and turned.
    let bent = resolve(
        &t,
        &given(&[
            ("x1", "2"),
            ("y1", "-1"),
            ("phi1", "0.4"),
            ("phi2", "3.141592653589793"),
            ("phi3", "-1.1"),
            ("phi4", "2.5"),
        ]),
        &[],
    )
    .unwrap();
    assert!(hitches(&bent.q) < 1e-15, "{:?}", bent.q);
    // Trailer 2's blade: the pin 0.3 m behind blade 1, then 0.5 m back along
    // heading π, i.e. 0.5 m forward along the lead's x axis.
    let (s, c) = 0.4_f64.sin_cos();
    assert!((bent.q[3] - (2.0 - 0.3 * c + 0.5)).abs() < 1e-15);
    assert!((bent.q[4] - (-1.0 - 0.3 * s)).abs() < 1e-15);
    // The chart's velocities hold on the placed train.
    let mut g = vec![0.0; 4];
    Nonholonomic(&t).eval(0.0, &bent.q, &bent.qd, &mut g);
    assert!(g.iter().all(|v| v.abs() < 1e-14), "{g:?}");
    // A blade given stays given: the hitch then fails the consistency check.
    let kept = resolve(&t, &given(&[("phi2", "1.0"), ("x2", "-0.8")]), &[]).unwrap();
    assert_eq!(kept.q[3], -0.8);
    assert!(hitches(&kept.q) > 0.1);
}
