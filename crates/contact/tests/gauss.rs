//! Formulation `gauss` (Gauss's principle as a quadratic program solved by
//! Clarabel) against B (`chetaev`, an LU of the same KKT system): the same
//! accelerations and multipliers, state by state, on every scene.

use nonholo_chetaev::Chetaev;
use nonholo_contact::gauss::{self, Gauss};
use nonholo_core::integrate::{OdeSystem, jacobian_mismatch};
use nonholo_core::{Model, Observation, Params, Scene};
use nonholo_scenes::{SceneVisitor, build};
use rand::{Rng, SeedableRng};

/// The largest difference of `q̈` and of the multipliers between `gauss`
/// and `chetaev` over `count` random states, each relative to the size of
/// what it compares (`1 + |·|∞`).
struct Compare {
    count: usize,
    seed: u64,
}

impl SceneVisitor for Compare {
    type Output = (f64, f64);

    fn visit<S: Scene>(self, scene: S) -> (f64, f64) {
        let none = |specs| Params::resolve(specs, &[], "option").unwrap();
        let copy = S::from_params(scene.params()).unwrap();
        let mut b = Chetaev::new(copy, none(nonholo_chetaev::OPTIONS)).unwrap();
        let mut g = Gauss::new(scene, none(gauss::OPTIONS)).unwrap();
        let info = b.scene_info();
        let n = info.n();
        let m = info.s() + info.k();
        let mut rng = rand::rngs::StdRng::seed_from_u64(self.seed);
        let (mut dy_b, mut dy_g) = (vec![0.0f64; 2 * n], vec![0.0f64; 2 * n]);
        let (mut ob, mut og) = (Observation::new(n, m), Observation::new(n, m));
        let (mut worst_qdd, mut worst_mult) = (0.0f64, 0.0f64);
        for _ in 0..self.count {
            let y: Vec<f64> = (0..2 * n).map(|_| rng.random_range(-2.0..2.0)).collect();
            let t = rng.random_range(0.0..5.0);
            b.rhs(t, &y, &mut dy_b).unwrap();
            g.rhs(t, &y, &mut dy_g).unwrap();
            let scale = 1.0 + dy_b.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for i in 0..2 * n {
                worst_qdd = worst_qdd.max((dy_b[i] - dy_g[i]).abs() / scale);
            }
            b.observe(t, &y, &mut ob).unwrap();
            g.observe(t, &y, &mut og).unwrap();
            let scale = 1.0 + ob.multipliers.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (x, z) in ob.multipliers.iter().zip(&og.multipliers) {
                worst_mult = worst_mult.max((x - z).abs() / scale);
            }
        }
        (worst_qdd, worst_mult)
    }
}

/// With equality constraints only, Gauss's principle is B: `q̈` and the
/// multipliers agree to 1e-10 at 300 random states (positions and
/// velocities in [−2, 2], off the constraints too) of every scene, both
/// sleigh potentials.
#[test]
fn gauss_equals_chetaev_on_every_scene() {
    let cases: &[(&str, &[(&str, &str)])] = &[
        ("sleigh-incline", &[("potential", "paper")]),
        ("sleigh-incline", &[("potential", "com")]),
        ("rolling-disk", &[]),
        ("appell-hamel", &[]),
        ("pendulum", &[]),
    ];
    for (k, (name, params)) in cases.iter().enumerate() {
        let pairs: Vec<(String, String)> = params
            .iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect();
        let scene = build(name, &pairs).unwrap();
        let (qdd, mult) = scene.visit(Compare {
            count: 300,
            seed: 7 + k as u64,
        });
        assert!(qdd < 1e-10, "{name} {params:?}: q̈ differs by {qdd:e}");
        assert!(
            mult < 1e-10,
            "{name} {params:?}: multipliers differ by {mult:e}"
        );
    }
}

/// The Jacobian of `gauss` (the solution map's derivative through the
/// linearised optimality conditions) equals central differences of its
/// Clarabel right-hand side.
#[test]
fn gauss_jacobian_matches_differences_of_the_conic_solve() {
    struct Jac;
    impl SceneVisitor for Jac {
        type Output = f64;
        fn visit<S: Scene>(self, scene: S) -> f64 {
            let opts = Params::resolve(gauss::OPTIONS, &[], "option").unwrap();
            let mut g = Gauss::new(scene, opts).unwrap();
            let n = g.scene_info().n();
            let y: Vec<f64> = (0..2 * n).map(|i| 0.3 + 0.17 * i as f64).collect();
            let (worst, _, _) = jacobian_mismatch(&mut g, 0.4, &y).unwrap().unwrap();
            worst
        }
    }
    for name in ["sleigh-incline", "rolling-disk", "appell-hamel", "pendulum"] {
        let worst = build(name, &[]).unwrap().visit(Jac);
        assert!(
            worst < 1e-6,
            "{name}: Jacobian off differences by {worst:e}"
        );
    }
}
