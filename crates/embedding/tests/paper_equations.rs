//! The paper's equations (23), (24) and (26) for the sleigh, reproduced by
//! automatic differentiation of the scene's Lagrangian and embedding map
//! (no hand-derived term inside the formulation), at random states.

use nonholo_core::{Params, Scene};
use nonholo_embedding::elo::{reconstruct, theta};
use nonholo_scenes::Sleigh;
use num_dual::{Dual64, HyperDual64};
use rand::{Rng, SeedableRng};

fn sleigh(a: f64, j: f64, m: f64, alpha: f64, potential: &str) -> Sleigh {
    let given: Vec<(String, String)> = [
        ("a", a.to_string()),
        ("J", j.to_string()),
        ("m", m.to_string()),
        ("alpha", alpha.to_string()),
        ("potential", potential.to_string()),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    Sleigh::from_params(&Params::resolve(Sleigh::INFO.params, &given, "parameter").unwrap())
        .unwrap()
}

struct State {
    x: f64,
    y: f64,
    xd: f64,
    yd: f64,
    xdd: f64,
    ydd: f64,
}

fn random_state(rng: &mut impl Rng) -> State {
    // Speeds kept away from the singular set |v| = 0 (the paper's equations
    // divide by ẋ² + ẏ²); both signs of ẋ so that atan2's branch is exercised.
    let speed: f64 = rng.random_range(0.2..4.0);
    let dir: f64 = rng.random_range(-3.1..3.1);
    State {
        x: rng.random_range(-5.0..5.0),
        y: rng.random_range(-5.0..5.0),
        xd: speed * dir.cos(),
        yd: speed * dir.sin(),
        xdd: rng.random_range(-3.0..3.0),
        ydd: rng.random_range(-3.0..3.0),
    }
}

/// Eq. (23): φ̇ = (ẋÿ − ẏẍ)/(ẋ² + ẏ²), and φ = atan2(ẏ, ẋ) (eq. 21).
#[test]
fn eq23_heading_rate() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(23);
    let s = sleigh(0.4, 1.0, 1.0, 0.3, "paper");
    let e = Sleigh::INFO.embedding.unwrap();
    for _ in 0..300 {
        let st = random_state(&mut rng);
        let (mut q, mut qd) = ([0.0; 3], [0.0; 3]);
        reconstruct(
            &s,
            &e,
            0.0,
            &[st.x, st.y],
            &[st.xd, st.yd],
            &[st.xdd, st.ydd],
            &[],
            &mut q,
            &mut qd,
        );
        let v2 = st.xd * st.xd + st.yd * st.yd;
        let phid = (st.xd * st.ydd - st.yd * st.xdd) / v2;
        assert!(
            (qd[2] - phid).abs() < 1e-12 * (1.0 + phid.abs()),
            "φ̇ {} vs {phid}",
            qd[2]
        );
        assert!((q[2] - st.yd.atan2(st.xd)).abs() < 1e-15);
        assert_eq!((q[0], q[1], qd[0], qd[1]), (st.x, st.y, st.xd, st.yd));
    }
}

/// Eq. (24): Θ = ½m[ẋ² + ẏ² + Jφ̇²] + m g x sin α for the paper's potential
/// (the a-term of eq. 22 vanishes on the constraint); with potential = com,
/// Θ also carries m g a sin α cos(atan2(ẏ, ẋ)).
#[test]
fn eq24_theta() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(24);
    for potential in ["paper", "com"] {
        for _ in 0..300 {
            let (a, m, alpha) = (
                rng.random_range(-1.0..1.0),
                rng.random_range(0.5..3.0),
                rng.random_range(0.0..1.4),
            );
            let j = a * a + rng.random_range(0.1..2.0);
            let s = sleigh(a, j, m, alpha, potential);
            let e = Sleigh::INFO.embedding.unwrap();
            let st = random_state(&mut rng);
            let th = theta(
                &s,
                &e,
                0.0,
                &[st.x, st.y],
                &[st.xd, st.yd],
                &[st.xdd, st.ydd],
                &[],
            );
            let v2 = st.xd * st.xd + st.yd * st.yd;
            let phid = (st.xd * st.ydd - st.yd * st.xdd) / v2;
            let mut expect = 0.5 * m * (v2 + j * phid * phid) + m * 9.81 * st.x * alpha.sin();
            if potential == "com" {
                expect += m * 9.81 * a * alpha.sin() * st.yd.atan2(st.xd).cos();
            }
            assert!(
                (th - expect).abs() < 1e-12 * (1.0 + expect.abs()),
                "{potential}: Θ {th} vs {expect}"
            );
        }
    }
}

/// Eq. (26): ∂Θ/∂x = m g sin α, ∂Θ/∂y = 0, ∂Θ/∂ẍ = mJẏ(ẏẍ − ẋÿ)/(ẋ² + ẏ²)²,
/// ∂Θ/∂ÿ = mJẋ(ẋÿ − ẏẍ)/(ẋ² + ẏ²)² (paper's potential).
#[test]
fn eq26_partial_derivatives() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(26);
    for _ in 0..300 {
        let (a, m, alpha) = (
            rng.random_range(-1.0..1.0),
            rng.random_range(0.5..3.0),
            rng.random_range(0.0..1.4),
        );
        let j = a * a + rng.random_range(0.1..2.0);
        let s = sleigh(a, j, m, alpha, "paper");
        let e = Sleigh::INFO.embedding.unwrap();
        let st = random_state(&mut rng);
        let grad = |which: usize, k: usize| -> f64 {
            let mut qi = [Dual64::from_re(st.x), Dual64::from_re(st.y)];
            let mut qdi = [Dual64::from_re(st.xd), Dual64::from_re(st.yd)];
            let mut qddi = [Dual64::from_re(st.xdd), Dual64::from_re(st.ydd)];
            match which {
                0 => qi[k].eps = 1.0,
                1 => qdi[k].eps = 1.0,
                _ => qddi[k].eps = 1.0,
            }
            theta(&s, &e, Dual64::from_re(0.0), &qi, &qdi, &qddi, &[]).eps
        };
        let v2 = st.xd * st.xd + st.yd * st.yd;
        let cross = st.xd * st.ydd - st.yd * st.xdd;
        let expect = [
            (grad(0, 0), m * 9.81 * alpha.sin()),
            (grad(0, 1), 0.0),
            (grad(2, 0), m * j * st.yd * (-cross) / (v2 * v2)),
            (grad(2, 1), m * j * st.xd * cross / (v2 * v2)),
        ];
        for (i, (got, want)) in expect.iter().enumerate() {
            assert!(
                (got - want).abs() < 1e-12 * (1.0 + want.abs()),
                "term {i}: {got} vs {want}"
            );
        }
    }
}

/// With the paper's potential `a` drops out of Θ entirely (spec): Θ and its
/// Hessian in q̈ (the W of eq. 19) are the same for every a.
#[test]
fn a_drops_out_of_theta_with_paper_potential() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(27);
    let e = Sleigh::INFO.embedding.unwrap();
    for _ in 0..200 {
        let st = random_state(&mut rng);
        let th = |a: f64| {
            let s = sleigh(a, 2.5, 1.3, 0.4, "paper");
            let qddi = [
                HyperDual64::new(st.xdd, 1.0, 1.0, 0.0),
                HyperDual64::from_re(st.ydd),
            ];
            theta(
                &s,
                &e,
                HyperDual64::from_re(0.0),
                &[HyperDual64::from_re(st.x), HyperDual64::from_re(st.y)],
                &[HyperDual64::from_re(st.xd), HyperDual64::from_re(st.yd)],
                &qddi,
                &[],
            )
        };
        let (t0, t1) = (th(0.0), th(1.2));
        assert!((t0.re - t1.re).abs() < 1e-12 * (1.0 + t0.re.abs()));
        assert!((t0.eps1eps2 - t1.eps1eps2).abs() < 1e-12 * (1.0 + t0.eps1eps2.abs()));
    }
}
