//! The boundary-value solver on the sleigh (docs/variational.md): C and A
//! (explicit map) reproduce C's initial-value motion between its ends at the
//! design order; A's end conditions; the stationarity residual of B's
//! motion against C's.

mod common;

use common::*;
use nonholo_scenes::Sleigh;
use nonholo_variational::*;

const Q0: [f64; 3] = [0.0, 0.0, 0.3];
const U0: f64 = 2.0;
const W0: f64 = 0.7;
const LAMBDA0: f64 = 0.5;

fn qd0() -> [f64; 3] {
    [U0 * Q0[2].cos(), U0 * Q0[2].sin(), W0]
}

/// C's motion on `[0, t1]` at `fine + 1` nodes.
fn c_motion(s: &Sleigh, t1: f64, fine: usize) -> (Vec<f64>, Vec<f64>) {
    reference(
        vakonomic(s.clone()),
        &Q0,
        &qd0(),
        &[LAMBDA0],
        &grid(t1, fine),
    )
}

/// Every `step`-th node of a node-major path.
fn every(q: &[f64], n: usize, step: usize) -> Vec<f64> {
    q.chunks(n).step_by(step).flatten().copied().collect()
}

/// The BVP path (Richardson-extrapolated) equals the IVP path at the
/// coarse nodes; the refinement shows the design order 2.
fn check_reproduces(s: &Sleigh, f: Formulation, base: usize, tol: f64) -> Refinement {
    let fine = 4 * base;
    let (q, qd) = c_motion(s, 1.0, fine);
    let ends = ends_of(&q, &qd, 3);
    let r = refine(s, &f, (0.0, 1.0), base, &ends, None, &Options::default()).unwrap();
    let reference = every(&q, 3, 4);
    let raw = max_diff(&sample(&r.solutions[2], &grid(1.0, base)), &reference);
    let extrapolated = max_diff(&r.extrapolated, &reference);
    assert!(
        (r.order - 2.0).abs() <= 0.2,
        "{f:?}: order {} ({:?})",
        r.order,
        r.differences
    );
    assert!(
        extrapolated <= tol,
        "{f:?}: extrapolated error {extrapolated:e} (finest {raw:e})"
    );
    // The error estimate of the finest level is within a factor 2 of its
    // actual error.
    assert!(
        r.error_estimate <= 2.0 * raw && raw <= 2.0 * r.error_estimate,
        "{f:?}: estimate {:e} against {raw:e}",
        r.error_estimate
    );
    r
}

#[test]
fn vakonomic_bvp_reproduces_the_initial_value_motion() {
    for potential in ["paper", "com"] {
        let s: Sleigh = scene(&[("potential", potential)]);
        let r = check_reproduces(&s, Formulation::Vakonomic, 100, 1e-9);
        assert!(r.solutions.iter().all(|x| x.report.iterations <= 8));
    }
}

#[test]
fn embedding_map_with_configuration_ends_reproduces_the_vakonomic_motion() {
    for potential in ["paper", "com"] {
        let s: Sleigh = scene(&[("potential", potential)]);
        for form in [MapForm::Explicit, MapForm::Implicit] {
            check_reproduces(
                &s,
                Formulation::Map {
                    ends: MapEnds::Configuration,
                    form,
                },
                800,
                1e-8,
            );
        }
    }
}

/// All of `q_I`, `q̇_I` fixed at both ends: with end speeds that C's motion
/// has, the BVP reproduces it; with the end speed 10 % larger, every grid
/// has a solution, but it meets the extra conditions only in a layer of
/// one step at the end and converges at first order to the motion with the
/// configuration ends, whose end speed is C's, not the prescribed one.
#[test]
fn embedding_map_with_full_ends_is_over_determined() {
    let s: Sleigh = scene(&[]);
    let fine = 1600;
    let (q, qd) = c_motion(&s, 1.0, fine);
    let speed1 = qd[fine * 3].hypot(qd[fine * 3 + 1]);
    let mut diffs = Vec::new();
    let mut inside = Vec::new();
    for perturb in [1.0, 1.1] {
        let mut ends = ends_of(&q, &qd, 3);
        ends.qd1.as_mut().unwrap()[..2]
            .iter_mut()
            .for_each(|v| *v *= perturb);
        let mut row = Vec::new();
        let mut insides = Vec::new();
        for nint in [100, 200, 400] {
            let reference = every(&q, 3, fine / nint);
            let f = Formulation::Map {
                ends: MapEnds::Full,
                form: MapForm::Explicit,
            };
            let p = Problem::new(&s, f, 0.0, 1.0, nint, ends.clone()).unwrap();
            let o = Options::default();
            let sol = Solver::new(&p, &o).unwrap().solve(&reference, &o).unwrap();
            row.push(max_diff(&sol.q, &reference));
            let v = sol.velocities();
            // The prescribed end speed holds for the one-sided difference...
            let end = v[nint * 3].hypot(v[nint * 3 + 1]);
            assert!((end - perturb * speed1).abs() < 1e-9, "{end} {speed1}");
            // The speed two steps inside, and at t = 0.9.
            let k9 = nint * 9 / 10;
            insides.push((
                v[(nint - 2) * 3].hypot(v[(nint - 2) * 3 + 1]),
                v[k9 * 3].hypot(v[k9 * 3 + 1]),
            ));
        }
        diffs.push(row);
        inside.push(insides);
    }
    // The extra speed condition is met in a layer of a few steps: two steps
    // from the end the speed differs by the same amount on every grid,
    // at t = 0.9 by less and less.
    let layer: Vec<f64> = (0..3)
        .map(|i| (inside[1][i].0 - inside[0][i].0).abs())
        .collect();
    let at_09: Vec<f64> = (0..3)
        .map(|i| (inside[1][i].1 - inside[0][i].1).abs())
        .collect();
    assert!(layer[0] > 0.05 * 0.1 * speed1, "{layer:?}");
    assert!((layer[2] / layer[0] - 1.0).abs() < 0.1, "{layer:?}");
    assert!(at_09[2] < 0.3 * at_09[0] && at_09[2] < 1e-3, "{at_09:?}");
    let order = |d: &[f64]| (d[0] / d[2]).log2() / 2.0;
    assert!((order(&diffs[0]) - 2.0).abs() < 0.2, "{diffs:?}");
    assert!((order(&diffs[1]) - 1.0).abs() < 0.2, "{diffs:?}");
    assert!(diffs[1][2] > 1e-4, "{diffs:?}");
}

/// Only `q_I` fixed, `q_D` free: the natural condition `∂Θ/∂q̈_I = 0` is
/// `p_φ = mJω = 0` at both ends (paper's potential): the turning rate at
/// the ends falls like `h`, and the motion is another one than C's.
#[test]
fn embedding_map_with_natural_ends_stops_turning_at_the_ends() {
    let s: Sleigh = scene(&[]);
    let fine = 1600;
    let (q, qd) = c_motion(&s, 1.0, fine);
    let ends = ends_of(&q, &qd, 3);
    let mut rates = Vec::new();
    for nint in [100, 200, 400] {
        let reference = every(&q, 3, fine / nint);
        let f = Formulation::Map {
            ends: MapEnds::Natural,
            form: MapForm::Explicit,
        };
        let p = Problem::new(&s, f, 0.0, 1.0, nint, ends.clone()).unwrap();
        let o = Options::default();
        let sol = Solver::new(&p, &o).unwrap().solve(&reference, &o).unwrap();
        let v = sol.velocities();
        rates.push(v[2].abs().max(v[nint * 3 + 2].abs()));
        assert!(max_diff(&sol.q, &reference) > 0.5);
    }
    assert!(rates[0] < 0.01, "{rates:?}");
    let order = (rates[0] / rates[2]).log2() / 2.0;
    assert!((order - 1.0).abs() < 0.2, "{rates:?}");
}

/// C's motion sampled at the nodes is stationary up to the discretisation
/// (the residual falls like h²); B's motion from the same state is not
/// (the residual stays of order one: a force in newtons).
#[test]
fn stationarity_residual_of_b_against_c() {
    let s: Sleigh = scene(&[]);
    let mut c_res = Vec::new();
    let mut b_res = Vec::new();
    for nint in [100, 200, 400] {
        let t = grid(1.0, nint);
        let (qc, qdc) = reference(vakonomic(s.clone()), &Q0, &qd0(), &[LAMBDA0], &t);
        let (qb, qdb) = reference(chetaev(s.clone()), &Q0, &qd0(), &[], &t);
        for (q, qd, out) in [(&qc, &qdc, &mut c_res), (&qb, &qdb, &mut b_res)] {
            let p = Problem::new(
                &s,
                Formulation::Vakonomic,
                0.0,
                1.0,
                nint,
                ends_of(q, qd, 3),
            )
            .unwrap();
            let st = Solver::new(&p, &Options::default())
                .unwrap()
                .stationarity(q)
                .unwrap();
            out.push(st.max);
        }
    }
    let order = (c_res[0] / c_res[2]).log2() / 2.0;
    assert!((order - 2.0).abs() < 0.2, "C: {c_res:?}");
    assert!(c_res[2] < 1e-3, "C: {c_res:?}");
    assert!(b_res.iter().all(|r| *r > 0.1), "B: {b_res:?}");
    assert!((b_res[0] / b_res[2] - 1.0).abs() < 0.05, "B: {b_res:?}");
}

#[test]
fn bad_input_is_refused_with_the_reason() {
    let s: Sleigh = scene(&[]);
    let (q, qd) = c_motion(&s, 1.0, 100);
    let ends = ends_of(&q, &qd, 3);
    // The heading at an end disagrees with the fixed end velocity.
    let mut bad = ends.clone();
    bad.q1[2] += 0.1;
    let full = Formulation::Map {
        ends: MapEnds::Full,
        form: MapForm::Explicit,
    };
    match Problem::new(&s, full.clone(), 0.0, 1.0, 100, bad) {
        Err(Error::InconsistentEnds { t, residual, .. }) => {
            assert_eq!(t, 1.0);
            assert!((residual - 0.1).abs() < 1e-9);
        }
        other => panic!("{other:?}"),
    }
    // Full ends need the velocities.
    let mut no_v = ends.clone();
    no_v.qd1 = None;
    assert!(matches!(
        Problem::new(&s, full, 0.0, 1.0, 100, no_v),
        Err(Error::Input { .. })
    ));
    // Non-finite data, an empty horizon, too few nodes.
    let mut nan = ends.clone();
    nan.q0[1] = f64::NAN;
    assert!(matches!(
        Problem::new(&s, Formulation::Vakonomic, 0.0, 1.0, 10, nan),
        Err(Error::Input { field, .. }) if field == "q0"
    ));
    assert!(Problem::new(&s, Formulation::Vakonomic, 1.0, 1.0, 10, ends.clone()).is_err());
    assert!(matches!(
        Problem::new(&s, Formulation::Map { ends: MapEnds::Configuration, form: MapForm::Implicit }, 0.0, 1.0, 3, ends.clone()),
        Err(Error::Input { field, .. }) if field == "nodes"
    ));
    // A grid too large for the memory limit is refused before allocating.
    let p = Problem::new(&s, Formulation::Vakonomic, 0.0, 1.0, 1000, ends.clone()).unwrap();
    let small = Options {
        max_bytes: 1e6,
        ..Options::default()
    };
    assert!(matches!(
        Solver::new(&p, &small),
        Err(Error::TooLarge { nodes: 1001, .. })
    ));
    // Newton that cannot converge names the iterations and the worst nodes.
    let p = Problem::new(&s, Formulation::Vakonomic, 0.0, 1.0, 50, ends.clone()).unwrap();
    let few = Options {
        max_iter: 1,
        ..Options::default()
    };
    match Solver::new(&p, &few).unwrap().solve(&p.start_line(), &few) {
        Err(Error::NotConverged {
            iterations,
            history,
            worst,
        }) => {
            assert_eq!(iterations, 1);
            assert_eq!(history.len(), 2);
            assert_eq!(worst.len(), 3);
        }
        other => panic!("{other:?}"),
    }
}

/// Over `[0, 1.5]` C's motion reverses once (its forward speed changes
/// sign). C's boundary-value problem reproduces it through the reversal,
/// and so does A's with the map in implicit form (the blade constraint at
/// the nodes), both at order 2. With the explicit map `φ = atan2(ẏ, ẋ)`
/// (on the branch nearest the current heading), started on C's motion,
/// Newton's method fails on some of six grids (its largest residuals within
/// 0.04 s of the reversal), and on the others it finds the implicit form's
/// path to round-off: the two forms have the same discrete solutions, and
/// the explicit one's Newton matrix degenerates at the reversal
/// (docs/variational.md).
#[test]
fn a_reversal_stops_the_explicit_map_but_not_the_implicit_map_or_the_vakonomic_bvp() {
    for potential in ["paper", "com"] {
        let s: Sleigh = scene(&[("potential", potential)]);
        let (t1, fine) = (1.5, 3200);
        let (q, qd) = c_motion(&s, t1, fine);
        let u: Vec<f64> = q
            .chunks(3)
            .zip(qd.chunks(3))
            .map(|(q, v)| v[0] * q[2].cos() + v[1] * q[2].sin())
            .collect();
        let reversals: Vec<f64> = (0..fine)
            .filter(|&k| u[k] * u[k + 1] < 0.0)
            .map(|k| t1 * k as f64 / fine as f64)
            .collect();
        assert_eq!(reversals.len(), 1, "{potential}: {reversals:?}");
        let ends = ends_of(&q, &qd, 3);
        // Started on C's motion: from the straight line Newton finds
        // another stationary path with the same ends (1.6 m away).
        let start = every(&q, 3, fine / 400);
        let o = Options::default();
        let r = refine(
            &s,
            &Formulation::Vakonomic,
            (0.0, t1),
            400,
            &ends,
            Some(&start),
            &o,
        )
        .unwrap();
        assert!((r.order - 2.0).abs() < 0.2, "{potential}: {}", r.order);
        let d = max_diff(&r.extrapolated, &every(&q, 3, fine / 400));
        assert!(
            d < 1e-8,
            "{potential}: {d:e}, estimate {:e}",
            r.extrapolated_error
        );
        let raw_c = max_diff(&sample(&r.solutions[2], &grid(t1, 400)), &start);
        assert!(raw_c < 1e-5, "{potential}: C's BVP {raw_c:e}");
        let implicit = Formulation::Map {
            ends: MapEnds::Configuration,
            form: MapForm::Implicit,
        };
        // Its error constant is 5–20 times C's (the map rows' central
        // differences): grids from 1600 intervals bring the extrapolation
        // to 1e-8 (at 400: 1e-6 and 6e-8).
        let start = every(&q, 3, fine / 1600);
        let r = refine(&s, &implicit, (0.0, t1), 1600, &ends, Some(&start), &o).unwrap();
        assert!(
            (r.order - 2.0).abs() < 0.2,
            "{potential}: A implicit, order {}",
            r.order
        );
        let d = max_diff(&r.extrapolated, &start);
        assert!(
            d < 1e-8,
            "{potential}: A implicit {d:e}, estimate {:e}",
            r.extrapolated_error
        );
        // The explicit rows `φ_k − atan2(D_k y, D_k x)` have the roots of the
        // implicit ones (on the branch the path follows), but derivatives
        // ~1/|D_k q_I| and second derivatives ~1/|D_k q_I|²: where Newton
        // converges, the two paths agree to round-off; on the grids whose
        // nodes come close to the reversal it fails there.
        // (On 100 intervals, h = 0.015 s, neither form converges with the
        // paper's potential: the grid is too coarse for the reversal.)
        let (mut failed, mut agree) = (0, Vec::new());
        for base in [160, 200, 320, 400, 800] {
            let start = every(&q, 3, fine / base);
            let solve = |form| {
                let f = Formulation::Map {
                    ends: MapEnds::Configuration,
                    form,
                };
                let p = Problem::new(&s, f, 0.0, t1, base, ends.clone()).unwrap();
                Solver::new(&p, &o).unwrap().solve(&start, &o)
            };
            let implicit = solve(MapForm::Implicit).unwrap();
            assert!(implicit.report.iterations <= 6, "{potential} {base}");
            match solve(MapForm::Explicit) {
                Err(Error::NotConverged { worst, .. }) => {
                    failed += 1;
                    for (_, t, _, _) in &worst {
                        assert!((t - reversals[0]).abs() < 0.04, "{potential}: {worst:?}");
                    }
                }
                Ok(sol) => agree.push(max_diff(&sol.q, &implicit.q)),
                Err(e) => panic!("{potential} {base}: {e}"),
            }
        }
        assert!(failed >= 2, "{potential}: {failed} failures");
        assert!(agree.iter().all(|d| *d < 1e-11), "{potential}: {agree:?}");
    }
}

/// C's multipliers read off the boundary-value problem (`λ = μ/h` at the
/// midpoints, averaged to the nodes) are the initial-value run's state `λ`
/// to second order.
#[test]
fn vakonomic_bvp_multipliers_are_cs_lambda() {
    let s: Sleigh = scene(&[]);
    let mut errs = Vec::new();
    for nint in [100, 200, 400] {
        let t = grid(1.0, nint);
        let run = nonholo_core::simulate(
            vakonomic(s.clone()),
            nonholo_core::Initial {
                t0: 0.0,
                q: Q0.to_vec(),
                qd: qd0().to_vec(),
                extra: vec![("lambda".into(), LAMBDA0)],
            },
            nonholo_core::RunConfig {
                method: nonholo_core::integrate::Method::Dop853,
                options: nonholo_core::integrate::Options {
                    rtol: 1e-13,
                    atol: 1e-13,
                    output: t.clone(),
                    ..Default::default()
                },
                t_end: 1.0,
                project_init: false,
            },
        )
        .unwrap();
        let q: Vec<f64> = run.samples.iter().flat_map(|o| o.q.clone()).collect();
        let qd: Vec<f64> = run.samples.iter().flat_map(|o| o.qd.clone()).collect();
        let lambda: Vec<f64> = run.samples.iter().map(|o| o.multipliers[0]).collect();
        let p = Problem::new(
            &s,
            Formulation::Vakonomic,
            0.0,
            1.0,
            nint,
            ends_of(&q, &qd, 3),
        )
        .unwrap();
        let o = Options::default();
        let sol = Solver::new(&p, &o).unwrap().solve(&q, &o).unwrap();
        let l = p.node_multipliers(&sol.multipliers).unwrap();
        errs.push(max_diff(&l, &lambda));
    }
    let order = (errs[0] / errs[2]).log2() / 2.0;
    assert!((order - 2.0).abs() < 0.2 && errs[2] < 1e-3, "{errs:?}");
}

/// A grid too large for the memory limit is refused before it is laid out
/// (a billion intervals: set up, it would need hundreds of gigabytes), and
/// the probe's estimate is within 10 % of the full problem's own count.
#[test]
fn large_grids_are_refused_before_layout() {
    let s: Sleigh = scene(&[]);
    let (q, qd) = c_motion(&s, 1.0, 100);
    let ends = ends_of(&q, &qd, 3);
    match Problem::new(
        &s,
        Formulation::Vakonomic,
        0.0,
        1.0,
        1_000_000_000,
        ends.clone(),
    ) {
        Err(Error::TooLarge { bytes, limit, .. }) => {
            assert!(bytes > 1e11 && limit == DEFAULT_MAX_BYTES, "{bytes:e}");
        }
        other => panic!("{other:?}"),
    }
    let n = 10 * PROBE_INTERVALS;
    let p = Problem::new(&s, Formulation::Vakonomic, 0.0, 1.0, n, ends.clone()).unwrap();
    let exact = p.memory_estimate();
    match Problem::with_limit(&s, Formulation::Vakonomic, 0.0, 1.0, n, ends, exact / 2.0) {
        Err(Error::TooLarge { bytes, .. }) => {
            assert!(
                (bytes / exact - 1.0).abs() < 0.1,
                "{bytes:e} against {exact:e}"
            );
        }
        other => panic!("{other:?}"),
    }
}
