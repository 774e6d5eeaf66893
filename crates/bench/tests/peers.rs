//! Smoke tests of the peer adapters (feature `peers` only; CI does not
//! build them): `cargo test --release -p nonholo-bench --features peers`.
#![cfg(feature = "peers")]

use nonholo_bench::peers::{
    DIFFSOL_DEFAULT_CAP, DiffsolMethod, Formulation, Problem, Reference, Solver, errors,
};
use nonholo_bench::setup::sleigh;
use nonholo_core::integrate::Method;

fn problem(a: f64, formulation: Formulation, t_end: f64) -> Problem {
    Problem {
        name: "test".into(),
        scene: sleigh(a, 0.3, "paper").unwrap(),
        potential: "paper",
        formulation,
        phi: 0.2,
        u: 2.0,
        omega: 0.7,
        t_end,
    }
}

fn grid(t_end: f64) -> Vec<f64> {
    (0..=100).map(|i| t_end * i as f64 / 100.0).collect()
}

fn reference(p: &Problem, method: Method, g: &[f64]) -> Reference {
    let r = Solver::Ours(method).run(p, 1e-12, g, true).unwrap();
    Reference::Dense {
        dense: r.dense.unwrap(),
        map: std::cell::RefCell::new(p.to_cartesian().unwrap()),
    }
}

/// ode_solvers' DOP853 is Hairer's code as ours is: on B the same steps
/// and the same final state; its end-of-grid dense sample is not used.
#[test]
fn ode_solvers_dop853_takes_our_steps_on_b() {
    let p = problem(0.4, Formulation::B, 20.0);
    let g = grid(20.0);
    let r = reference(&p, Method::Dop853, &g);
    let ours = Solver::Ours(Method::Dop853)
        .run(&p, 1e-6, &g, false)
        .unwrap();
    let peer = Solver::OdeSolversDop853.run(&p, 1e-6, &g, false).unwrap();
    assert_eq!(ours.work.steps, peer.work.steps);
    assert_eq!(ours.work.rejected, peer.work.rejected);
    // Same method, same steps: the final states differ by summation order
    // only, round-off accumulated over the steps (measured 3.0e-13 relative;
    // bound 1e-11).
    let d_end = ours
        .y_end
        .iter()
        .zip(&peer.y_end)
        .map(|(a, b)| (a - b).abs() / (1.0 + a.abs()))
        .fold(0.0, f64::max);
    eprintln!("final states differ by {d_end:.1e} (relative)");
    assert!(d_end < 1e-11, "{:?} vs {:?}", ours.y_end, peer.y_end);
    let (e_ours, _, _) = errors(&ours, &r, 20.0).unwrap();
    let (e_peer, _, _) = errors(&peer, &r, 20.0).unwrap();
    eprintln!("errors at the end {e_ours:.3e} / {e_peer:.3e}");
    // Both errors are the method's (measured 9.443e-5 both) and differ by
    // no more than the final states do.
    assert!((e_ours - e_peer).abs() < 1e-11, "{e_ours} vs {e_peer}");
}

/// diffsol's BDF on `visc(1e2)` through the closure adapter, on the same
/// motion in body-frame velocities (forward-difference Jacobian) and in the
/// generic adapted form (AD Jacobian).
#[test]
fn diffsol_bdf_solves_mild_visc_in_every_state() {
    let g = grid(5.0);
    let cart = problem(0.4, Formulation::Visc { k: 1e2 }, 5.0);
    let body = problem(0.4, Formulation::ViscBody { k: 1e2 }, 5.0);
    let adapted = problem(0.4, Formulation::ViscAdapted { k: 1e2 }, 5.0);
    let r = reference(&cart, Method::Radau5, &g);
    let bdf = Solver::Diffsol {
        method: DiffsolMethod::Bdf,
        max_fails: DIFFSOL_DEFAULT_CAP,
    };
    for p in [&cart, &body, &adapted] {
        let out = bdf.run(p, 1e-8, &g, false).unwrap();
        let (e_end, e_max, _) = errors(&out, &r, 5.0).unwrap();
        eprintln!("{:?}: largest error {e_max:.2e}", p.formulation);
        // Measured (docs/peers.md, k = 1e2, tol 1e-8): 4.5e-7 (body frame)
        // to 1.1e-6 (Cartesian); BDF is not tolerance-proportional beyond
        // a factor ~100, hence 1e-5.
        assert!(
            e_max < 1e-5 && e_end <= e_max,
            "{:?}: {e_end:e} {e_max:e}",
            p.formulation
        );
        assert!(out.work.jac > 0 && out.work.steps > 0);
    }
    // The three references agree: the other states are the same motion.
    for other in [&body, &adapted] {
        let rb = reference(other, Method::Radau5, &g);
        let (mut a, mut b) = ([0.0; 6], [0.0; 6]);
        for &t in &g {
            r.eval(t, &mut a).unwrap();
            rb.eval(t, &mut b).unwrap();
            // Three Radau runs at 1e-12: docs/peers.md measures the
            // references 2.8e-10 – 3.5e-10 apart at 1e-13; 1e-8 allows the
            // looser tolerance here.
            for i in 0..6 {
                assert!((a[i] - b[i]).abs() < 1e-8, "t = {t}: {a:?} vs {b:?}");
            }
        }
    }
}
