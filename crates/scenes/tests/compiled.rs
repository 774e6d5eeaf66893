//! Every scene's KKT system (B's `L` and C's `L + λᵀg`) from the compiled
//! program ([`nonholo_core::compiled`]) against the scalar dual passes of
//! [`nonholo_core::ad`], entry by entry, over `f64` and over `Dual64` (a
//! Jacobian column), at states spread over each scene's coordinates, both
//! as the ideal rows scatter the program's entries and as other rows write
//! theirs from `G`; and the sparse solve (ideal rows, the program's entries
//! straight into the sparse system) against assembling dense and solving.

use nalgebra::DMatrix;
use nonholo_core::compiled::Programs;
use nonholo_core::constraints::ConstraintState;
use nonholo_core::kkt::{GRows, Ideal, Kkt};
use nonholo_core::scene::{Augmented, Lagrangian, Scalar, ScalarField};
use nonholo_core::stab::Stabilisation;
use nonholo_core::{Scene, SceneInfo};
use nonholo_scenes::{SceneVisitor, build};
use num_dual::Dual64;

/// Deterministic states: `q_i`, `q̇_i` and `λ_i` from a linear
/// congruential sequence in `[−2, 2]`.
/// A state `(t, q, q̇, p)`.
type State = (f64, Vec<f64>, Vec<f64>, Vec<f64>);

fn states(n: usize, np: usize, count: usize) -> Vec<State> {
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut next = || {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((x >> 11) as f64 / (1u64 << 53) as f64) * 4.0 - 2.0
    };
    (0..count)
        .map(|_| {
            let t = next().abs();
            let q = (0..n).map(|_| next()).collect();
            let qd = (0..n).map(|_| next()).collect();
            let p = (0..np).map(|_| next()).collect();
            (t, q, qd, p)
        })
        .collect()
}

/// Largest difference between the two systems relative to the largest
/// entry of the passes' system.
fn compare<T: Scalar, F: ScalarField, S: Scene>(
    scene: &S,
    ell: &F,
    np: usize,
    lift: impl Fn(f64, usize) -> T,
    parts: impl Fn(&T) -> Vec<f64>,
) -> f64 {
    let info = scene.info();
    let mut passes: Kkt<T> = Kkt::for_scene(info);
    let mut compiled: Kkt<T> = Kkt::for_scene(info);
    compiled
        .compile(ell, np, scene)
        .unwrap_or_else(|e| panic!("{}: {e}", info.name));
    let mut direct: Kkt<T> = Kkt::for_scene(info);
    direct.compile(ell, np, scene).unwrap();
    let mut worst = 0.0f64;
    for (k, (t, q, qd, p)) in states(info.n(), np, 24).into_iter().enumerate() {
        let l = |v: &[f64], off: usize| -> Vec<T> {
            v.iter()
                .enumerate()
                .map(|(i, &x)| lift(x, off + i + k))
                .collect()
        };
        let (q, qd, p) = (l(&q, 0), l(&qd, 7), l(&p, 13));
        let t = lift(t, 0);
        let rows = Ideal(Stabilisation::Baumgarte {
            alpha: 3.0,
            beta: 4.0,
        });
        // The program's entries scattered (ideal rows), then `G` through
        // the rows' own `write` (the path of the realisations and
        // friction), each against the passes.
        let mut differ = |passes: &Kkt<T>, compiled: &Kkt<T>| {
            let (a, ra) = passes.system();
            let (b, rb) = compiled.system();
            let scale = a
                .iter()
                .chain(ra)
                .flat_map(&parts)
                .fold(1.0f64, |m, v| m.max(v.abs()));
            for (x, y) in a.iter().zip(b.iter()).chain(ra.iter().zip(rb)) {
                for (u, v) in parts(x).into_iter().zip(parts(y)) {
                    worst = worst.max((u - v).abs() / scale);
                }
            }
        };
        passes.assemble(ell, &p, scene, &rows, t, &q, &qd);
        compiled.assemble(ell, &p, scene, &Written(rows), t, &q, &qd);
        differ(&passes, &compiled);
        compiled.assemble(ell, &p, scene, &rows, t, &q, &qd);
        differ(&passes, &compiled);
        if !direct.is_sparse() {
            // The dense solve is `assemble` and `solve_assembled`.
            continue;
        }
        // The sparse solve: another factorisation of the same system.
        let assembled = compiled.solve_assembled().map(|()| compiled.sol.clone());
        let solved = direct
            .solve(ell, &p, scene, &rows, t, &q, &qd)
            .map(|()| direct.sol.clone());
        match (assembled, solved) {
            (Ok(x), Ok(y)) => {
                let (x, y): (Vec<f64>, Vec<f64>) = (
                    x.iter().flat_map(&parts).collect(),
                    y.iter().flat_map(&parts).collect(),
                );
                let size = x.iter().fold(1.0f64, |m, v| m.max(v.abs()));
                // Measured: at most 2.0e-14 of max|x| over the 24 states of
                // the train of 20 (B and C, f64 and Dual64 parts); 1e-12
                // leaves a factor 50 for other platforms.
                for (u, v) in x.iter().zip(&y) {
                    assert!((u - v).abs() < 1e-12 * size, "{}: state {k}", info.name);
                }
            }
            (Err(_), Err(_)) => {}
            (a, b) => panic!(
                "{}: state {k}: {:?} against {:?}",
                info.name,
                a.err(),
                b.err()
            ),
        }
    }
    worst
}

/// Ideal rows written through [`GRows::write`] (no ideal gain): the
/// compiled path that fills `G` in [`Kkt::cs`] and lets the rows write
/// their own, as the realisations and friction do.
struct Written(Ideal);

impl GRows for Written {
    fn holonomic_gains(&self) -> (f64, f64) {
        self.0.holonomic_gains()
    }

    fn write<T: Scalar>(
        &self,
        n: usize,
        cs: &ConstraintState<T>,
        matrix: &mut DMatrix<T>,
        rhs: &mut [T],
    ) {
        self.0.write(n, cs, matrix, rhs);
    }
}

struct Check;

impl SceneVisitor for Check {
    type Output = (&'static SceneInfo, [f64; 4]);
    fn visit<S: Scene>(self, scene: S) -> Self::Output {
        let info = scene.info();
        let s = info.s();
        let re = |x: &f64| vec![*x];
        let du = |x: &Dual64| vec![x.re, x.eps];
        // Dual inputs: every third input carries a unit derivative part.
        let lift_d = |x: f64, i: usize| Dual64::new(x, if i.is_multiple_of(3) { 1.0 } else { 0.0 });
        let r = [
            compare(&scene, &Lagrangian(&scene), 0, |x, _| x, re),
            compare(&scene, &Augmented(&scene), s, |x, _| x, re),
            compare(&scene, &Lagrangian(&scene), 0, lift_d, du),
            compare(&scene, &Augmented(&scene), s, lift_d, du),
        ];
        (info, r)
    }
}

#[test]
fn compiled_systems_equal_the_passes_for_every_scene() {
    for info in nonholo_scenes::ALL {
        let scene = build(info.name, &[]).unwrap();
        let (info, r) = scene.visit(Check);
        eprintln!(
            "{}: B {:.1e}, C {:.1e}, B over Dual64 {:.1e}, C over Dual64 {:.1e}",
            info.name, r[0], r[1], r[2], r[3]
        );
        for (what, e) in ["B", "C", "B dual", "C dual"].iter().zip(r) {
            assert!(
                e < 1e-12,
                "{} {what}: compiled and passes differ by {e:e}",
                info.name
            );
        }
    }
}

/// The train of 20 sleighs: more nonholonomic constraints (20) than `L + λᵀg`
/// keeps on the stack, so the passes evaluate it with a buffer on the heap;
/// its systems (a sparse KKT solve, B and C) equal the passes' as on every
/// scene.
#[test]
fn a_train_longer_than_the_stack_buffer_compiles_for_b_and_c() {
    let scene = build("sleigh-train", &[("N".into(), "20".into())]).unwrap();
    let (info, r) = scene.visit(Check);
    assert!(info.s() > nonholo_core::scene::MAX_CONSTRAINTS);
    for (what, e) in ["B", "C", "B dual", "C dual"].iter().zip(r) {
        assert!(e < 1e-12, "{what}: compiled and passes differ by {e:e}");
    }
}

/// A field that branches on a value (here `|q̇₀|` by a comparison) holds
/// only on one branch: compiling it is refused with the reason, and the
/// workspace keeps the scalar passes.
#[test]
fn a_field_that_branches_on_values_is_refused_and_the_passes_stay() {
    struct Branching<'a, S>(&'a S);
    impl<S: Scene> ScalarField for Branching<'_, S> {
        fn n(&self) -> usize {
            self.0.info().n()
        }
        fn eval<D: Scalar>(&self, t: D, q: &[D], qd: &[D], _p: &[D]) -> D {
            let l = self.0.lagrangian(t, q, qd);
            if qd[0].re() > 0.0 { l } else { l * 2.0 }
        }
    }
    let scene = nonholo_scenes::Pendulum::from_params(&nonholo_core::Params::defaults(
        nonholo_scenes::pendulum::INFO.params,
    ))
    .unwrap();
    let mut kkt: Kkt<f64> = Kkt::for_scene(scene.info());
    let e = kkt.compile(&Branching(&scene), 0, &scene).unwrap_err();
    assert!(e.0.contains("re()"), "{e}");
    assert!(kkt.compiled().is_none());
    let kkt = Kkt::<f64>::for_scene(scene.info()).compiled_for(
        &Programs::default(),
        &Branching(&scene),
        0,
        &scene,
    );
    assert!(kkt.compiled().is_none());
}

/// One program serves every workspace of a formulation: the `f64` and the
/// dual workspaces read the same compiled program, not two traces of it.
#[test]
fn one_program_per_formulation() {
    let scene = nonholo_scenes::Pendulum::from_params(&nonholo_core::Params::defaults(
        nonholo_scenes::pendulum::INFO.params,
    ))
    .unwrap();
    let programs = Programs::default();
    let ell = Lagrangian(&scene);
    let a = Kkt::<f64>::for_scene(scene.info()).compiled_for(&programs, &ell, 0, &scene);
    let b = Kkt::<Dual64>::for_scene(scene.info()).compiled_for(&programs, &ell, 0, &scene);
    let (a, b) = (a.compiled().unwrap(), b.compiled().unwrap());
    assert!(std::ptr::eq(a, b), "two programs for one formulation");
}
