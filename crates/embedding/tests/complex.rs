//! Formulation A's pieces at complex states of the sleigh, where its
//! heading map is evaluated by `scene::atan2` on complex velocities: the
//! paper's eqs. (23) and (24), and the equations (19) on complex time jets —
//! `f64`'s values on the real axis, analytic off it (central differences
//! along the real and the imaginary axis agree), and differentiable by
//! num-dual over `C64` (`Dual<C64>` inside the jets).

use nonholo_core::complex::Complex64 as Cx;
use nonholo_core::{C64, Params, Scene};
use nonholo_embedding::elo::{elo_array, reconstruct, theta};
use nonholo_scenes::Sleigh;
use num_dual::{Dual, Dual2};

const M: f64 = 1.3;
const J: f64 = 2.5;
const ALPHA: f64 = 0.4;

fn sleigh(potential: &str) -> Sleigh {
    let given: Vec<(String, String)> = [
        ("a", "0.6"),
        ("J", "2.5"),
        ("m", "1.3"),
        ("alpha", "0.4"),
        ("potential", potential),
    ]
    .iter()
    .map(|(k, v)| (k.to_string(), v.to_string()))
    .collect();
    Sleigh::from_params(&Params::resolve(Sleigh::INFO.params, &given, "parameter").unwrap())
        .unwrap()
}

fn c(re: f64, im: f64) -> Cx {
    Cx::new(re, im)
}

/// `(x, y, ẋ, ẏ, ẍ, ÿ)`, complex; the speeds `ẋ² + ẏ²` away from zero.
fn states() -> Vec<[Cx; 6]> {
    let mut v = vec![];
    // (ẋ, ẏ) = u (cos φ, sin φ) with u = ρ e^{iθ} through imaginary values.
    for (k, phi) in [
        c(0.3, 0.0),
        c(std::f64::consts::FRAC_PI_2 - 1e-7, 0.2),
        c(2.8, -0.4),
        c(-1.2, 0.1),
    ]
    .into_iter()
    .enumerate()
    {
        for th in [0.9 * std::f64::consts::PI, std::f64::consts::FRAC_PI_2, 0.2] {
            let u = Cx::from_polar(0.7 + 0.3 * k as f64, th);
            v.push([
                c(0.4, -0.1),
                c(-1.0, 0.3),
                u * phi.cos(),
                u * phi.sin(),
                c(0.3, 0.2),
                c(-0.5, 0.1),
            ]);
        }
    }
    v
}

fn lift<const N: usize>(v: [Cx; N]) -> [C64; N] {
    v.map(C64)
}

/// Eq. (23): `φ̇ = (ẋÿ − ẏẍ)/(ẋ² + ẏ²)` at complex states; the heading
/// itself points along the velocity (up to a multiple of π).
#[test]
fn eq23_heading_rate_at_complex_states() {
    let s = sleigh("paper");
    let e = Sleigh::INFO.embedding.unwrap();
    for st in states() {
        let [x, y, xd, yd, xdd, ydd] = lift(st);
        let (mut q, mut qd) = ([C64::from(0.0); 3], [C64::from(0.0); 3]);
        reconstruct(
            &s,
            &e,
            C64::from(0.0),
            &[x, y],
            &[xd, yd],
            &[xdd, ydd],
            &[],
            &mut q,
            &mut qd,
        );
        let phid = (st[2] * st[5] - st[3] * st[4]) / (st[2] * st[2] + st[3] * st[3]);
        assert!(
            (qd[2].0 - phid).norm() < 1e-14 * phid.norm().max(1.0),
            "{} vs {phid}",
            qd[2]
        );
        let speed = (st[2].norm_sqr() + st[3].norm_sqr()).sqrt();
        assert!((st[3] * q[2].0.cos() - st[2] * q[2].0.sin()).norm() < 1e-15 * speed);
    }
}

/// Eq. (24): `Θ = ½m[ẋ² + ẏ² + Jφ̇²] + m g x sin α` (paper's potential; it
/// does not depend on which multiple of π the heading carries).
#[test]
fn eq24_theta_at_complex_states() {
    let s = sleigh("paper");
    let e = Sleigh::INFO.embedding.unwrap();
    for st in states() {
        let [x, y, xd, yd, xdd, ydd] = lift(st);
        let th = theta(&s, &e, C64::from(0.0), &[x, y], &[xd, yd], &[xdd, ydd], &[]);
        let v2 = st[2] * st[2] + st[3] * st[3];
        let phid = (st[2] * st[5] - st[3] * st[4]) / v2;
        let expect = 0.5 * M * (v2 + J * phid * phid) + M * 9.81 * ALPHA.sin() * st[0];
        assert!(
            (th.0 - expect).norm() < 1e-13 * expect.norm().max(1.0),
            "{th} vs {expect}"
        );
    }
}

/// The order-2 jets give `E` (eq. 19) from `d = [q_I, q̇_I, …, q_I⁽⁴⁾]`.
fn residual(s: &Sleigh, d: &[C64; 10]) -> [C64; 2] {
    let e = Sleigh::INFO.embedding.unwrap();
    let mut out = [C64::from(0.0); 2];
    elo_array::<_, C64, Dual2<C64>>(s, &e, C64::from(0.1), d, &[], &mut out);
    out
}

fn jet_data(st: [Cx; 6]) -> [C64; 10] {
    let mut d = [C64::from(0.0); 10];
    for (k, v) in st.into_iter().enumerate() {
        d[k] = C64(v);
    }
    d[6] = C64::new(0.2, -0.1);
    d[7] = C64::new(-0.3, 0.05);
    d[8] = C64::new(0.1, 0.0);
    d[9] = C64::new(0.0, 0.2);
    d
}

/// On the real axis `E` over `C64` is `E` over `f64`.
#[test]
fn equations_over_c64_are_f64s_on_the_real_axis() {
    for potential in ["paper", "com"] {
        let s = sleigh(potential);
        let e = Sleigh::INFO.embedding.unwrap();
        for st in states() {
            let real = jet_data(st).map(|z| z.re());
            let mut want = [0.0; 2];
            elo_array::<_, f64, Dual2<f64>>(&s, &e, 0.1, &real, &[], &mut want);
            let got = residual(&s, &real.map(C64::from));
            for k in 0..2 {
                assert!(got[k].im() == 0.0, "{potential}: {}", got[k]);
                assert!(
                    (got[k].re() - want[k]).abs() < 1e-13 * want[k].abs().max(1.0),
                    "{potential}: {} vs {}",
                    got[k],
                    want[k]
                );
            }
        }
    }
}

/// `E` is analytic in every input off the real axis: its derivative along
/// a real seed through `Dual<C64>` equals central differences along the real
/// and along the imaginary axis (Cauchy–Riemann).
///
/// With `potential = com`, `E` involves `cos φ`, which changes sign with the
/// multiple of π that `scene::atan2` adds; some states (purely imaginary
/// speeds) lie where that multiple switches, and differences across a
/// switch jump. With it, a difference is compared only where the heading at
/// both shifted points is the base heading's; with the paper's potential `E`
/// does not depend on the multiple and every difference is compared.
#[test]
fn equations_are_analytic_and_differentiable_over_c64() {
    let heading = |d: &[C64; 10]| {
        let s = sleigh("paper");
        let e = Sleigh::INFO.embedding.unwrap();
        let (mut q, mut qd) = ([C64::from(0.0); 3], [C64::from(0.0); 3]);
        reconstruct(
            &s,
            &e,
            C64::from(0.1),
            &d[0..2],
            &d[2..4],
            &d[4..6],
            &[],
            &mut q,
            &mut qd,
        );
        q[2]
    };
    let (mut compared, mut across) = (0, 0);
    for potential in ["paper", "com"] {
        let s = sleigh(potential);
        let e = Sleigh::INFO.embedding.unwrap();
        for st in states() {
            let d = jet_data(st);
            for j in 0..10 {
                let mut dd = d.map(Dual::from_re);
                dd[j].eps = C64::from(1.0);
                let mut ad = [Dual::from_re(C64::from(0.0)); 2];
                elo_array::<_, Dual<C64>, Dual2<Dual<C64>>>(
                    &s,
                    &e,
                    Dual::from_re(C64::from(0.1)),
                    &dd,
                    &[],
                    &mut ad,
                );
                let h = 1e-5 * d[j].0.norm().max(1.0);
                let phi = heading(&d);
                for dir in [C64::from(1.0), C64::I] {
                    let shift = |sign: f64| {
                        let mut p = d;
                        p[j] += dir * (sign * h);
                        (residual(&s, &p), heading(&p))
                    };
                    let ((ep, php), (em, phm)) = (shift(1.0), shift(-1.0));
                    let switches = (php - phi).norm() > 1.0 || (phm - phi).norm() > 1.0;
                    if switches && potential == "com" {
                        across += 1;
                        continue;
                    }
                    compared += 1;
                    for k in 0..2 {
                        let fd = (ep[k] - em[k]) / (dir * (2.0 * h));
                        let scale = ad[k].eps.norm().max(1.0);
                        assert!(
                            (fd - ad[k].eps).norm() < 1e-7 * scale,
                            "{potential}: ∂E{k}/∂d{j} along {dir}: {fd} vs {}",
                            ad[k].eps
                        );
                    }
                }
            }
        }
    }
    println!("{compared} differences compared, {across} across a switch of the multiple of π");
    assert!(across < compared / 10);
}
