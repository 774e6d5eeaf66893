//! The horizontal Chaplygin sleigh under B: straight motion at speed `u0`
//! has the essential eigenvalues `0` (the speed) and `−a u0 / J` (the
//! turning rate), derived in docs/stability.md.

use nonholo_core::{Error, Initial, Params, Scene};
use nonholo_scenes::Sleigh;
use nonholo_stability::{Options, linearize};

fn sleigh(a: f64, j: f64, m: f64) -> Sleigh {
    let p = Params::resolve(
        nonholo_scenes::sleigh::INFO.params,
        &[
            ("a".into(), a.to_string()),
            ("J".into(), j.to_string()),
            ("m".into(), m.to_string()),
            ("alpha".into(), "0".into()),
        ],
        "parameter",
    )
    .unwrap();
    Sleigh::from_params(&p).unwrap()
}

fn straight(phi: f64, u: f64, omega: f64) -> Initial {
    Initial {
        t0: 0.0,
        q: vec![0.3, -0.2, phi],
        qd: vec![u * phi.cos(), u * phi.sin(), omega],
        extra: Vec::new(),
    }
}

fn chetaev(s: Sleigh) -> nonholo_chetaev::Chetaev<Sleigh> {
    let o = Params::resolve(nonholo_chetaev::INFO.options, &[], "option").unwrap();
    nonholo_chetaev::Chetaev::new(s, o).unwrap()
}

#[test]
fn straight_motion_has_eigenvalues_zero_and_minus_a_u0_over_j() {
    for (a, j, m) in [(0.4, 1.0, 1.0), (-0.3, 0.5, 2.5), (0.1, 0.02, 0.7)] {
        for u0 in [2.0, -1.5, 0.3] {
            for phi in [0.0, 0.7, -2.9] {
                let mut model = chetaev(sleigh(a, j, m));
                let lin =
                    linearize(&mut model, &straight(phi, u0, 0.0), &Options::default()).unwrap();
                let cyclic: Vec<&str> = lin.cyclic.iter().map(|c| c.0.as_str()).collect();
                assert_eq!(cyclic.len(), 3, "{cyclic:?}");
                assert_eq!(lin.names.len(), 2, "{:?}", lin.names);
                let want = -a * u0 / j;
                let ev = lin.eigenvalues();
                let near_zero = ev.iter().filter(|v| v.norm() < 1e-12).count();
                let turning = ev
                    .iter()
                    .filter(|v| (v.re - want).abs() <= 1e-12 * want.abs() && v.im == 0.0)
                    .count();
                assert_eq!((near_zero, turning), (1, 1), "a {a} J {j} u0 {u0}: {ev:?}");
            }
        }
    }
}

/// A turning sleigh (ω ≠ 0, a ≠ 0) is not a steady motion: refused with
/// the rate that makes it so.
#[test]
fn a_turning_sleigh_is_refused_with_its_residual() {
    let mut model = chetaev(sleigh(0.4, 1.0, 1.0));
    let err = linearize(&mut model, &straight(0.2, 1.0, 0.5), &Options::default()).unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, Error::InconsistentInit { .. }), "{text}");
    assert!(text.contains("not a steady motion"), "{text}");
}
