//! The spec: for constraints of form (14) the embedded problem is the
//! vakonomic problem restricted to constrained curves, so the equations (19)
//! of A must vanish along every vakonomic motion. Checked pointwise with C's
//! Taylor coefficients (q̈, q⃛, q⁗ from C's own right-hand side).

use nonholo_core::{Params, Scene};
use nonholo_embedding::elo::{elo_array, theta};
use nonholo_scenes::Sleigh;
use nonholo_vakonomic::{OPTIONS, Vakonomic};
use num_dual::{Dual, Dual2_64};
use rand::{Rng, SeedableRng};

fn sleigh(a: f64, j: f64, alpha: f64, potential: &str) -> Sleigh {
    let given: Vec<(String, String)> = [
        ("a", a.to_string()),
        ("J", j.to_string()),
        ("alpha", alpha.to_string()),
        ("potential", potential.to_string()),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    Sleigh::from_params(&Params::resolve(Sleigh::INFO.params, &given, "parameter").unwrap())
        .unwrap()
}

/// max over μ of |∂Θ/∂q_μ|, |d/dt ∂Θ/∂q̇_μ|, |d²/dt² ∂Θ/∂q̈_μ|.
fn term_scale(s: &Sleigh, d: &[f64]) -> f64 {
    let e = Sleigh::INFO.embedding.unwrap();
    let jet = |k: usize, r: usize| {
        Dual::from_re(Dual2_64::new(
            d[r * 2 + k],
            d[(r + 1) * 2 + k],
            d[(r + 2) * 2 + k],
        ))
    };
    let mut scale = 0.0f64;
    for mu in 0..2 {
        for r in 0..3 {
            let mut args = [
                [jet(0, 0), jet(1, 0)],
                [jet(0, 1), jet(1, 1)],
                [jet(0, 2), jet(1, 2)],
            ];
            args[r][mu].eps = Dual2_64::from_re(1.0);
            let v = theta(
                s,
                &e,
                Dual::from_re(Dual2_64::new(0.0, 1.0, 0.0)),
                &args[0],
                &args[1],
                &args[2],
                &[],
            );
            let part = [v.eps.re, v.eps.v1, v.eps.v2][r];
            scale = scale.max(part.abs());
        }
    }
    scale.max(1.0)
}

#[test]
fn elo_residual_vanishes_on_vakonomic_motions() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(19);
    let e = Sleigh::INFO.embedding.unwrap();
    let mut worst = 0.0f64;
    for potential in ["paper", "com"] {
        for _ in 0..200 {
            let a: f64 = rng.random_range(-1.0..1.0);
            let s = sleigh(
                a,
                a * a + rng.random_range(0.2..2.0),
                rng.random_range(0.0..1.3),
                potential,
            );
            let mut c = Vakonomic::new(s.clone(), Params::defaults(OPTIONS)).unwrap();
            // Forward motion (u > 0), so that atan2(ẏ, ẋ) is the heading φ itself.
            let phi: f64 = rng.random_range(-3.0..3.0);
            let u: f64 = rng.random_range(0.3..3.0);
            let y = [
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
                phi,
                u * phi.cos(),
                u * phi.sin(),
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
            ];
            let (mut yd, mut ydd, mut yddd) = ([0.0; 7], [0.0; 7], [0.0; 7]);
            c.taylor(0.0, &y, &mut yd, &mut ydd, &mut yddd).unwrap();
            // q_I = (x, y) and its derivatives 0..4.
            let d = [
                y[0], y[1], y[3], y[4], yd[3], yd[4], ydd[3], ydd[4], yddd[3], yddd[4],
            ];
            let mut res = [0.0; 2];
            elo_array::<_, f64, Dual2_64>(&s, &e, 0.0, &d, &[], &mut res);
            // Tolerance from the conditioning at this state: how far E moves
            // when the Taylor data move by ~1e-15 relative (their own round-off
            // level, coming out of C's KKT solves). A systematic error in E
            // would exceed it; round-off cannot.
            let mut sensitivity = 0.0f64;
            for trial in 0..8 {
                let dp: Vec<f64> = d
                    .iter()
                    .enumerate()
                    .map(|(i, v)| {
                        v * (1.0 + 1e-15 * (((i * 7 + trial * 13) % 11) as f64 - 5.0) / 5.0)
                    })
                    .collect();
                let mut rp = [0.0; 2];
                elo_array::<_, f64, Dual2_64>(&s, &e, 0.0, &dp, &[], &mut rp);
                sensitivity = sensitivity
                    .max((rp[0] - res[0]).abs())
                    .max((rp[1] - res[1]).abs());
            }
            let scale = term_scale(&s, &d);
            let r = res[0].abs().max(res[1].abs());
            worst = worst.max(r / scale);
            assert!(
                r <= 8.0 * sensitivity + 1e-14 * scale,
                "{potential}: E = {res:?}, terms up to {scale:e}, round-off sensitivity {sensitivity:e}"
            );
        }
    }
    eprintln!("worst relative ELO residual on C's motions: {worst:e}");
}

/// The sleigh's structure at points of vakonomic motions: rank W = 1 (= s),
/// two hidden constraints, 6 free initial data — the count of C's
/// (q, q̇ on the constraint, λ(0)) = 2n. The completion recovers C's q⃛ from
/// (q, q̇, q̈) and a guess 20 % off (q⃛ is locally unique); from the far guess
/// q⃛ = 0 it succeeds in most cases and otherwise says it could not.
#[test]
fn sleigh_structure_and_completion() {
    use nonholo_embedding::analysis::{complete, structure};
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let e = Sleigh::INFO.embedding.unwrap();
    let (mut far_ok, mut far_total) = (0, 0);
    for potential in ["paper", "com"] {
        for _ in 0..20 {
            let a: f64 = rng.random_range(-1.0..1.0);
            let s = sleigh(
                a,
                a * a + rng.random_range(0.2..2.0),
                rng.random_range(0.0..1.3),
                potential,
            );
            let mut c = Vakonomic::new(s.clone(), Params::defaults(OPTIONS)).unwrap();
            let phi: f64 = rng.random_range(-3.0..3.0);
            let u: f64 = rng.random_range(0.5..3.0);
            let y = [
                0.0,
                0.0,
                phi,
                u * phi.cos(),
                u * phi.sin(),
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
            ];
            let (mut yd, mut ydd, mut yddd) = ([0.0; 7], [0.0; 7], [0.0; 7]);
            c.taylor(0.0, &y, &mut yd, &mut ydd, &mut yddd).unwrap();
            let base = [y[0], y[1], y[3], y[4], yd[3], yd[4]];
            let mut d = vec![0.0; 14];
            d[..6].copy_from_slice(&base);
            d[6] = ydd[3] * 1.2 + 0.1;
            d[7] = ydd[4] * 0.8 - 0.1;
            let done = complete(&s, &e, 0.0, &mut d, true, 1e-12).unwrap();
            assert!(done.third_unique, "{done:?}");
            for k in 0..2 {
                let want = ydd[3 + k];
                assert!(
                    (d[6 + k] - want).abs() < 1e-8 * (1.0 + want.abs()),
                    "q⃛[{k}] {} vs C's {want}",
                    d[6 + k]
                );
            }
            let st = structure(&s, &e, 0.0, &d).unwrap();
            assert_eq!(
                (st.rank_w, st.hidden_constraints, st.free_initial_data),
                (1, 2, 6),
                "{st:?}"
            );
            assert!(
                st.rank_gap.1 < 1e-6 * st.rank_gap.0,
                "unclear rank decision {st:?}"
            );
            if far_total == 0 {
                eprintln!("{st:?}");
            }

            let mut far = vec![0.0; 14];
            far[..6].copy_from_slice(&base);
            far_total += 1;
            match complete(&s, &e, 0.0, &mut far, true, 1e-12) {
                Ok(_) if (far[6] - ydd[3]).abs() < 1e-6 * (1.0 + ydd[3].abs()) => far_ok += 1,
                Ok(_) => {}
                Err(msg) => assert!(msg.contains("could not be satisfied"), "{msg}"),
            }
        }
    }
    eprintln!("completion from q⃛ = 0 reached C's q⃛ in {far_ok} of {far_total} cases");
    assert!(far_ok * 10 >= far_total * 9, "{far_ok} of {far_total}");
}
