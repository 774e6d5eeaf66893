//! `C64` against num-complex; num-dual numbers over `C64` against complex
//! derivatives written here by hand (and against central differences of the
//! values, which checks value and derivative formulas against each other);
//! an order-4 time jet over `C64`; and `scene::atan2` along complex paths of
//! the velocity through purely imaginary speeds.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, LN_2, LN_10, PI};

use nonholo_core::complex::Complex64 as Cx;
use nonholo_core::scene::atan2;
use nonholo_core::{C64, Scalar};
use num_dual::{
    Dual, Dual2, Dual3, Dual64, DualNum, DualStruct, HyperDual, first_derivative,
    second_derivative, third_derivative,
};
use num_traits::Zero;

fn c(re: f64, im: f64) -> Cx {
    Cx::new(re, im)
}

/// `|a − b| / |b|`.
fn rel(a: Cx, b: Cx) -> f64 {
    (a - b).norm() / b.norm()
}

/// Points off the real axis in every quadrant, small and large.
const POINTS: [(f64, f64); 7] = [
    (0.7, -1.3),
    (-0.4, 0.9),
    (1.8, 0.25),
    (-2.1, -0.6),
    (0.05, 0.02),
    (3.0, 2.0),
    (0.3, 0.5),
];

/// Every elementary function of `DualNum`, by name.
const FUNS: [&str; 34] = [
    "recip",
    "powi3",
    "powi-4",
    "powf",
    "powd",
    "sqrt",
    "cbrt",
    "exp",
    "exp2",
    "exp_m1",
    "ln",
    "log",
    "log2",
    "log10",
    "ln_1p",
    "sin",
    "cos",
    "tan",
    "sin_cos.0",
    "sin_cos.1",
    "asin",
    "acos",
    "atan",
    "sinh",
    "cosh",
    "tanh",
    "asinh",
    "acosh",
    "atanh",
    "sph_j0",
    "sph_j1",
    "sph_j2",
    "mul_add",
    "inv",
];

fn apply<D: Scalar>(f: &str, z: D) -> D {
    match f {
        "recip" => z.recip(),
        "powi3" => z.powi(3),
        "powi-4" => z.powi(-4),
        "powf" => z.powf(2.5),
        "powd" => z.powd(D::from(1.7)),
        "sqrt" => z.sqrt(),
        "cbrt" => z.cbrt(),
        "exp" => z.exp(),
        "exp2" => z.exp2(),
        "exp_m1" => z.exp_m1(),
        "ln" => z.ln(),
        "log" => z.log(3.0),
        "log2" => z.log2(),
        "log10" => z.log10(),
        "ln_1p" => z.ln_1p(),
        "sin" => z.sin(),
        "cos" => z.cos(),
        "tan" => z.tan(),
        "sin_cos.0" => z.sin_cos().0,
        "sin_cos.1" => z.sin_cos().1,
        "asin" => z.asin(),
        "acos" => z.acos(),
        "atan" => z.atan(),
        "sinh" => z.sinh(),
        "cosh" => z.cosh(),
        "tanh" => z.tanh(),
        "asinh" => z.asinh(),
        "acosh" => z.acosh(),
        "atanh" => z.atanh(),
        "sph_j0" => z.sph_j0(),
        "sph_j1" => z.sph_j1(),
        "sph_j2" => z.sph_j2(),
        "mul_add" => z.mul_add(z, D::from(2.0)),
        "inv" => num_traits::Inv::inv(z),
        _ => unreachable!("{f}"),
    }
}

/// `j_n(z) = zⁿ Σ_k (−z²/2)ᵏ / (k! (2n + 2k + 1)!!)`.
fn sph_j(n: i32, z: Cx) -> Cx {
    let mut dfact = 1.0;
    for m in (1..=2 * n + 1).step_by(2) {
        dfact *= m as f64;
    }
    let (mut term, mut sum) = (Cx::new(1.0 / dfact, 0.0), Cx::new(0.0, 0.0));
    for k in 0..60 {
        sum += term;
        term *= -z * z / 2.0 / ((k + 1) as f64 * (2 * n + 2 * k + 3) as f64);
    }
    sum * z.powi(n)
}

/// `Σ_{k ≥ 1} zᵏ/k!` and `Σ_{k ≥ 1} (−1)^{k+1} zᵏ/k`, for small `|z|`.
fn exp_m1_series(z: Cx) -> Cx {
    let (mut term, mut sum) = (z, Cx::new(0.0, 0.0));
    for k in 2..40 {
        sum += term;
        term *= z / k as f64;
    }
    sum
}

fn ln_1p_series(z: Cx) -> Cx {
    let (mut zk, mut sum) = (z, Cx::new(0.0, 0.0));
    for k in 1..60 {
        let t = zk / k as f64;
        sum += if k % 2 == 1 { t } else { -t };
        zk *= z;
    }
    sum
}

/// The value and complex derivative `d/dz` of `f` at `z`, written with
/// num-complex (the principal branch of every multivalued function).
fn reference(f: &str, z: Cx) -> (Cx, Cx) {
    let one = Cx::new(1.0, 0.0);
    match f {
        "recip" | "inv" => (one / z, -one / (z * z)),
        "powi3" => (z * z * z, 3.0 * z * z),
        "powi-4" => (one / (z * z * z * z), -4.0 / z.powi(5)),
        "powf" => (z.powf(2.5), 2.5 * z.powf(1.5)),
        "powd" => (z.powf(1.7), 1.7 * z.powf(0.7)),
        "sqrt" => (z.sqrt(), 0.5 / z.sqrt()),
        "cbrt" => (z.cbrt(), z.cbrt() / (3.0 * z)),
        "exp" => (z.exp(), z.exp()),
        "exp2" => (z.exp2(), LN_2 * z.exp2()),
        "exp_m1" if z.norm() < 0.1 => (exp_m1_series(z), z.exp()),
        "exp_m1" => (z.exp() - 1.0, z.exp()),
        "ln" => (z.ln(), one / z),
        "log" => (z.ln() / 3f64.ln(), one / (z * 3f64.ln())),
        "log2" => (z.ln() / LN_2, one / (z * LN_2)),
        "log10" => (z.ln() / LN_10, one / (z * LN_10)),
        "ln_1p" if z.norm() < 0.1 => (ln_1p_series(z), one / (one + z)),
        "ln_1p" => ((one + z).ln(), one / (one + z)),
        "sin" | "sin_cos.0" => (z.sin(), z.cos()),
        "cos" | "sin_cos.1" => (z.cos(), -z.sin()),
        "tan" => (z.tan(), one / (z.cos() * z.cos())),
        "asin" => (z.asin(), one / (one - z * z).sqrt()),
        "acos" => (z.acos(), -one / (one - z * z).sqrt()),
        "atan" => (z.atan(), one / (one + z * z)),
        "sinh" => (z.sinh(), z.cosh()),
        "cosh" => (z.cosh(), z.sinh()),
        "tanh" => (z.tanh(), one / (z.cosh() * z.cosh())),
        "asinh" => (z.asinh(), one / (one + z * z).sqrt()),
        "acosh" => (z.acosh(), one / ((z - 1.0).sqrt() * (z + 1.0).sqrt())),
        "atanh" => (z.atanh(), one / (one - z * z)),
        "sph_j0" => (sph_j(0, z), -sph_j(1, z)),
        "sph_j1" => (sph_j(1, z), sph_j(0, z) - 2.0 * sph_j(1, z) / z),
        "sph_j2" => (sph_j(2, z), sph_j(1, z) - 3.0 * sph_j(2, z) / z),
        "mul_add" => (z * z + 2.0, 2.0 * z),
        _ => unreachable!("{f}"),
    }
}

/// Relative tolerance of the closed forms of `j_n`, which cancel like
/// `|z|^{−2n}` at small `|z|` (as `f64`'s do).
fn tol(f: &str, z: Cx, base: f64) -> f64 {
    let n = match f {
        "sph_j1" => 1,
        "sph_j2" => 2,
        _ => 0,
    };
    let sph = if n > 0 { 4.0 } else { 1.0 };
    sph * base * z.norm().powi(-2 * n).max(1.0)
}

/// num-dual differentiates `tan` and `tanh` as quotients `sin/cos`: the
/// derivative `(cos² + sin²)/cos²` cancels by `|f|²/|f′|` where `|f| ≈ 1`
/// and `|f′| ≪ 1` (large `|Im z|` for `tan`, large `|Re z|` for `tanh`).
fn quotient_conditioning(f: &str, z: Cx) -> f64 {
    match f {
        "tan" | "tanh" => {
            let (v, d) = reference(f, z);
            (v.norm_sqr() / d.norm()).max(1.0)
        }
        _ => 1.0,
    }
}

#[test]
#[allow(clippy::op_ref)] // the by-reference operators num-dual uses are under test
fn arithmetic_is_num_complexs() {
    for &(ar, ai) in &POINTS {
        for &(br, bi) in &POINTS {
            let (a, b) = (c(ar, ai), c(br, bi));
            let (x, y) = (C64(a), C64(b));
            assert_eq!((x + y).0, a + b);
            assert_eq!((x - y).0, a - b);
            assert_eq!((x * y).0, a * b);
            assert_eq!((x / y).0, a / b);
            assert_eq!((x + &y).0, a + b);
            assert_eq!((x * &y).0, a * b);
            assert_eq!((&x - &y).0, a - b);
            assert_eq!((x * 1.7).0, a * 1.7);
            assert_eq!((x / -0.3).0, a / -0.3);
            assert_eq!((x + 2.0).0, a + 2.0);
            assert_eq!((x - 2.0).0, a - 2.0);
            assert_eq!((-x).0, -a);
            let mut z = x;
            z += y;
            z *= y;
            z -= 0.5;
            z /= y;
            z *= 3.0;
            assert_eq!(z.0, (((a + b) * b - 0.5) / b) * 3.0);
            assert_eq!(x.recip().0, a.inv());
        }
    }
}

#[test]
fn elementary_functions_are_the_principal_complex_functions() {
    let mut worst = 0.0f64;
    for f in FUNS {
        for &(re, im) in &POINTS {
            let z = c(re, im);
            let v = apply(f, C64(z)).0;
            let (expect, _) = reference(f, z);
            let e = rel(v, expect);
            assert!(
                e < tol(f, z, 4e-15),
                "{f}({z}) = {v}, expected {expect}: {e:e}"
            );
            if tol(f, z, 1.0) == 1.0 {
                worst = worst.max(e);
            }
        }
    }
    println!("worst relative error of the values: {worst:e}");
    // Small arguments: no cancellation in exp_m1 and ln_1p.
    for z in [c(1e-9, 3e-10), c(-2e-12, 1e-12), c(0.0, 1e-8)] {
        assert!(rel(C64(z).exp_m1().0, exp_m1_series(z)) < 1e-15);
        assert!(rel(C64(z).ln_1p().0, ln_1p_series(z)) < 1e-15);
    }
    // sph_j at (and near) zero by the series.
    assert_eq!(C64::new(0.0, 0.0).sph_j0(), C64::new(1.0, 0.0));
    assert_eq!(C64::new(0.0, 0.0).sph_j1(), C64::new(0.0, 0.0));
    let z = C64::new(1e-17, -1e-17);
    assert!(rel(z.sph_j1().0, sph_j(1, z.0)) < 1e-15);
}

/// On the real axis (inside each function's real domain) the values are
/// `f64`'s and the derivatives through `Dual<C64>` are `Dual64`'s.
#[test]
fn real_axis_values_and_derivatives_are_f64s() {
    for f in FUNS {
        let xs: &[f64] = match f {
            "acosh" => &[1.3, 2.7],
            "asin" | "acos" | "atanh" => &[-0.6, 0.2, 0.9],
            "sqrt" | "cbrt" | "ln" | "log" | "log2" | "log10" | "powf" | "powd" => &[0.2, 3.5],
            "ln_1p" => &[-0.5, 1e-9, 0.4, 3.0],
            _ => &[-2.3, -0.4, 1e-9, 0.6, 3.1],
        };
        for &x in xs {
            let v = apply(f, C64::from(x));
            let w = apply(f, x);
            assert!(v.im().abs() <= 1e-16 * w.abs(), "{f}({x}) = {v}");
            assert!(
                (v.re() - w).abs() <= tol(f, c(x, 0.0), 2e-15) * w.abs(),
                "{f}({x}) = {v} against {w}"
            );
            let dv = apply(f, Dual::new(C64::from(x), C64::from(1.0)));
            let dw = apply(f, Dual64::new(x, 1.0));
            assert!(
                (dv.eps.0 - c(dw.eps, 0.0)).norm() <= tol(f, c(x, 0.0), 2e-15) * dw.eps.abs(),
                "{f}'({x}) = {} against {}",
                dv.eps,
                dw.eps
            );
        }
    }
}

/// `Dual<C64>` carries `f′(z)`, the complex derivative, for every function
/// (`acosh`: only for `Re z > 0`, see `acosh_derivative_is_num_duals_branch`).
#[test]
fn first_derivatives_are_the_complex_derivatives() {
    let mut worst = 0.0f64;
    for f in FUNS {
        for &(re, im) in &POINTS {
            if f == "acosh" && re < 0.0 {
                continue;
            }
            let z = c(re, im);
            let d = apply(f, Dual::new(C64(z), C64::from(1.0)));
            let (v, dv) = reference(f, z);
            assert!(rel(d.re.0, v) < tol(f, z, 4e-15), "{f}({z})");
            let e = rel(d.eps.0, dv) / quotient_conditioning(f, z);
            // The derivatives of the closed forms of j_n cancel one order more.
            let sph = if f.starts_with("sph") {
                z.norm().powi(-2).max(1.0)
            } else {
                1.0
            };
            assert!(
                e < sph * tol(f, z, 1e-14),
                "{f}'({z}) = {} vs {dv}: {e:e}",
                d.eps
            );
            if !f.starts_with("sph") {
                worst = worst.max(e);
            }
        }
    }
    println!("worst relative error of the first derivatives: {worst:e}");
}

/// Cauchy–Riemann: the derivative along the real seed `1` is the complex
/// derivative, the one along `i` is `i` times it, and both equal central
/// differences of the values along the real and the imaginary axis — which
/// checks num-dual's derivative formulas against C64's values
/// independently of the hand-written references.
#[test]
fn cauchy_riemann_and_central_differences() {
    let i = C64::I;
    for f in FUNS {
        for &(re, im) in &POINTS {
            // acosh: see below; sph_j1, sph_j2: their closed forms cancel
            // at small |z| more than central differences tolerate.
            if f == "acosh" && re < 0.0 || tol(f, c(re, im), 1.0) > 1.0 {
                continue;
            }
            let z = C64::new(re, im);
            let along_re = apply(f, Dual::new(z, C64::from(1.0))).eps;
            let along_im = apply(f, Dual::new(z, i)).eps;
            assert!(rel(along_im.0, (i * along_re).0) < 1e-15, "{f}({z})");
            let h = 1e-5 * z.norm().max(0.1);
            let dx = (apply(f, z + h) - apply(f, z - h)) / (2.0 * h);
            let dy = (apply(f, z + i * h) - apply(f, z - i * h)) / (i * (2.0 * h));
            assert!(rel(dx.0, along_re.0) < 1e-8, "{f}({z}): {dx} vs {along_re}");
            assert!(rel(dy.0, along_re.0) < 1e-8, "{f}({z}): {dy} vs {along_re}");
        }
    }
}

/// num-dual differentiates `acosh` as `√(1/(z² − 1))`: the derivative of the
/// principal `acosh` for `Re z > 0`, its negative for `Re z < 0` (the
/// derivative of the branch `ln(z + √(z² − 1))`). Pinned here so that a
/// change in num-dual shows.
#[test]
fn acosh_derivative_is_num_duals_branch() {
    for (re, im) in [(-0.4, 0.9), (-2.1, -0.6), (-1.5, 0.1)] {
        let z = c(re, im);
        let d = Dual::new(C64(z), C64::from(1.0)).acosh();
        let (_, principal) = reference("acosh", z);
        assert!(rel(d.eps.0, -principal) < 1e-14, "{z}");
        let h = 1e-6;
        let fd = (C64(z + h).acosh() - C64(z - h).acosh()) / (2.0 * h);
        assert!(rel(fd.0, principal) < 1e-8, "{z}");
    }
}

/// num-dual's `sph_j*` of a dual number take the series at zero when
/// `|Re z| < ε`, by the real part only: at a purely imaginary value they
/// are wrong (`C64`'s own, which decide by `|z|`, are right). Pinned.
#[test]
fn sph_j_of_duals_decide_by_the_real_part() {
    let z = C64::new(0.0, 3.0);
    assert!(rel(z.sph_j0().0, sph_j(0, z.0)) < 1e-15);
    let d = Dual::new(z, C64::from(1.0)).sph_j0();
    assert_eq!(d.re, C64::from(1.0) - z * z / 6.0);
    assert!(rel(d.re.0, sph_j(0, z.0)) > 0.1);
    // Off the imaginary axis the dual's value and derivative are right.
    let z = C64::new(1e-3, 2.0);
    let d = Dual::new(z, C64::from(1.0)).sph_j0();
    assert!(rel(d.re.0, sph_j(0, z.0)) < 1e-15);
    assert!(rel(d.eps.0, -sph_j(1, z.0)) < 1e-14);
}

/// Second and third derivatives through `Dual2`, `Dual3`, `HyperDual` over
/// `C64` and num-dual's drivers.
#[test]
fn higher_derivatives_over_c64() {
    const ONE: Cx = Cx::new(1.0, 0.0);
    // f, f′′, f′′′ by hand.
    type Derivs = fn(Cx) -> (Cx, Cx);
    let cases: [(&str, Derivs); 8] = [
        ("exp", |z| (z.exp(), z.exp())),
        ("sin", |z| (-z.sin(), -z.cos())),
        ("ln", |z| (-ONE / (z * z), 2.0 / z.powi(3))),
        ("recip", |z| (2.0 / z.powi(3), -6.0 / z.powi(4))),
        ("sqrt", |z| {
            (-0.25 / (z * z.sqrt()), 0.375 / (z * z * z.sqrt()))
        }),
        ("atan", |z| {
            let w = ONE + z * z;
            (-2.0 * z / (w * w), (6.0 * z * z - 2.0) / (w * w * w))
        }),
        ("powi-4", |z| (20.0 / z.powi(6), -120.0 / z.powi(7))),
        ("asin", |z| {
            let w = ONE - z * z;
            (z / (w * w.sqrt()), (ONE + 2.0 * z * z) / (w * w * w.sqrt()))
        }),
    ];
    for (f, derivs) in cases {
        for &(re, im) in &POINTS {
            let z = c(re, im);
            let (_, d1) = reference(f, z);
            let (d2, d3) = derivs(z);
            let x2 = apply(f, Dual2::new(C64(z), C64::from(1.0), C64::from(0.0)));
            assert!(rel(x2.v1.0, d1) < 1e-14, "{f}'({z})");
            assert!(rel(x2.v2.0, d2) < 1e-14, "{f}''({z}): {} vs {d2}", x2.v2);
            let x3 = apply(
                f,
                Dual3::new(C64(z), C64::from(1.0), C64::zero(), C64::zero()),
            );
            assert!(rel(x3.v2.0, d2) < 1e-14, "{f}''({z})");
            assert!(rel(x3.v3.0, d3) < 1e-14, "{f}'''({z}): {} vs {d3}", x3.v3);
            let hd = apply(
                f,
                HyperDual::new(C64(z), C64::from(1.0), C64::from(1.0), C64::zero()),
            );
            assert!(rel(hd.eps1eps2.0, d2) < 1e-14, "{f}''({z})");
            // Along a complex direction w: w² f′′.
            let w = C64::new(0.3, -0.8);
            let x2w = apply(f, Dual2::new(C64(z), w, C64::zero()));
            assert!(rel(x2w.v2.0, w.0 * w.0 * d2) < 1e-14, "{f}''({z})");
        }
    }
    // num-dual's drivers accept C64.
    let z = C64::new(0.4, -0.9);
    let (v, d) = first_derivative(|x| x.sin() * x, z);
    assert_eq!(v, z.sin() * z);
    assert!(rel(d.0, (z.cos() * z + z.sin()).0) < 1e-15);
    let (_, _, d2) = second_derivative(|x| x.powi(4), z);
    assert!(rel(d2.0, (z * z * 12.0).0) < 1e-15);
    let (_, _, _, d3) = third_derivative(|x| x.exp() * x, z);
    assert!(rel(d3.0, (z.exp() * (z + 3.0)).0) < 1e-14);
}

/// An order-4 time jet `Dual2<Dual2<C64>>` (τ = ε₁ + ε₂, as the embedding's
/// `Jet4`) of functions of a complex time `t = t0 + τ`.
#[test]
fn order_four_time_jets_over_c64() {
    type Jet4 = Dual2<Dual2<C64>>;
    fn seed(d: [Cx; 5]) -> Jet4 {
        let d = d.map(C64);
        Dual2::new(
            Dual2::new(d[0], d[1], d[2]),
            Dual2::new(d[1], d[2], d[3]),
            Dual2::new(d[2], d[3], d[4]),
        )
    }
    fn read(j: Jet4) -> [Cx; 5] {
        [j.re.re.0, j.re.v1.0, j.re.v2.0, j.v1.v2.0, j.v2.v2.0]
    }
    fn check(name: &str, got: [Cx; 5], expect: [Cx; 5]) {
        let scale = expect.iter().map(|e| e.norm()).fold(0.0, f64::max);
        for k in 0..5 {
            let e = (got[k] - expect[k]).norm() / scale;
            assert!(
                e < 1e-14,
                "{name}: d^{k} = {} vs {}: {e:e}",
                got[k],
                expect[k]
            );
        }
    }
    let zero = c(0.0, 0.0);
    let t0 = c(0.3, 0.4);
    let t = seed([t0, c(1.0, 0.0), zero, zero, zero]);

    // sin(a t + b): the k-th derivative is aᵏ sin(a t + b + kπ/2).
    let (a, b) = (c(1.3, -0.2), c(0.1, 0.5));
    let lift = |z: Cx| Jet4::from_re(Dual2::from_re(C64(z)));
    let got = read((t * lift(a) + lift(b)).sin());
    let expect: [Cx; 5] =
        std::array::from_fn(|k| a.powi(k as i32) * (a * t0 + b + k as f64 * FRAC_PI_2).sin());
    check("sin(a t + b)", got, expect);

    // p(t)³ for p(t) = Σ cₖ (t − t0)ᵏ: the coefficients of the cubed polynomial.
    let cp = [
        c(0.3, -0.1),
        c(1.0, 0.5),
        c(-0.4, 0.0),
        c(0.2, 0.3),
        c(0.05, -0.02),
    ];
    let fact = [1.0, 1.0, 2.0, 6.0, 24.0];
    let p = seed(std::array::from_fn(|k| cp[k] * fact[k]));
    let mut sq = [zero; 9];
    for i in 0..5 {
        for j in 0..5 {
            sq[i + j] += cp[i] * cp[j];
        }
    }
    let mut cube = [zero; 5];
    for i in 0..5 {
        for j in 0..5 - i {
            cube[i + j] += sq[i] * cp[j];
        }
    }
    check(
        "p³",
        read(p * p * p),
        std::array::from_fn(|k| cube[k] * fact[k]),
    );

    // t⁴ e^{w t} by Leibniz: Σ_j C(k, j) (t⁴)^{(j)} w^{k−j} e^{w t}.
    let w = c(-0.7, 1.1);
    let t4 = [
        t0.powi(4),
        4.0 * t0.powi(3),
        12.0 * t0 * t0,
        24.0 * t0,
        c(24.0, 0.0),
    ];
    let binom = |k: usize, j: usize| fact[k] / (fact[j] * fact[k - j]);
    let expect: [Cx; 5] = std::array::from_fn(|k| {
        (0..=k)
            .map(|j| binom(k, j) * t4[j] * w.powi((k - j) as i32) * (w * t0).exp())
            .sum()
    });
    check("t⁴ e^{wt}", read(t.powi(4) * (t * lift(w)).exp()), expect);
}

/// `modulus` is `|z|` of the value part at every nesting level, and for real
/// dual numbers `re().abs()` bit for bit.
#[test]
fn modulus_of_every_family() {
    let z = C64::new(-3.0, 4.0);
    assert_eq!(z.modulus(), 5.0);
    assert_eq!(Dual::new(z, C64::I).modulus(), 5.0);
    assert_eq!(
        Dual2::new(Dual::new(z, z), Dual::from_re(z), Dual::from_re(z)).modulus(),
        5.0
    );
    assert_eq!(HyperDual::new(z, z, z, z).modulus(), 5.0);
    for x in [-2.5f64, -0.0, 1e-300, 7.0, f64::NAN] {
        let d = Dual3::new(
            Dual::new(x, 3.0),
            Dual::from_re(1.0),
            Dual::from_re(0.0),
            Dual::from_re(0.0),
        );
        assert_eq!(d.modulus().to_bits(), d.re().abs().to_bits());
        assert_eq!(x.modulus().to_bits(), x.abs().to_bits());
    }
}

/// The sleigh's map `φ = atan2(ẏ, ẋ)` along `(ẋ, ẏ) = u (cos φ, sin φ)` with
/// `u = ρ e^{iθ}`, θ from π to 0 (through purely imaginary speeds), at real
/// and complex headings φ — among them `±π/2`, where `ẋ` vanishes with `u`
/// or not at all. Everything is an order-4 time jet in τ, with
/// `φ(τ) = φ0 + ωτ + ατ²/2 + jτ³/6 + sτ⁴/24` and `u(τ) = u0 (1 + 0.3τ − 0.2τ²)`:
/// the jet of `atan2` must be `φ`'s (its tangent is `ẏ/ẋ` whatever `u`), the
/// value up to a multiple of π.
#[test]
fn atan2_along_paths_through_imaginary_speeds() {
    type Jet4 = Dual2<Dual2<C64>>;
    fn seed(d: [C64; 5]) -> Jet4 {
        Dual2::new(
            Dual2::new(d[0], d[1], d[2]),
            Dual2::new(d[1], d[2], d[3]),
            Dual2::new(d[2], d[3], d[4]),
        )
    }
    fn read(j: Jet4) -> [C64; 5] {
        [j.re.re, j.re.v1, j.re.v2, j.v1.v2, j.v2.v2]
    }
    let rates = [
        C64::new(0.7, -0.1),
        C64::new(-1.3, 0.2),
        C64::new(0.4, 0.0),
        C64::new(0.0, -0.25),
    ];
    let mut headings = vec![];
    for h in [
        0.0,
        0.3,
        FRAC_PI_4,
        1.0,
        FRAC_PI_2 - 1e-9,
        FRAC_PI_2,
        FRAC_PI_2 + 1e-7,
        2.0,
        3.0 * FRAC_PI_4,
        PI - 1e-9,
        PI,
        -FRAC_PI_2,
        -FRAC_PI_2 + 3e-8,
        -FRAC_PI_4,
        -2.5,
    ] {
        headings.push(C64::from(h));
        for im in [0.3, -0.7, 1.2] {
            headings.push(C64::new(h, im));
        }
    }
    let mut speeds = vec![];
    for rho in [1e-3, 1.0, 30.0] {
        for k in 0..=64 {
            speeds.push(C64::from_polar(rho, PI * (64 - k) as f64 / 64.0));
        }
        speeds.push(C64::new(0.0, rho));
        speeds.push(C64::new(-0.0, rho));
        speeds.push(C64::new(0.0, -rho));
    }
    let (mut worst_value, mut worst_rate) = (0.0f64, 0.0f64);
    let mut worst_at = (C64::from(0.0), C64::from(0.0), 0);
    let mut multiples = std::collections::BTreeSet::new();
    for &phi0 in &headings {
        let phi = seed([phi0, rates[0], rates[1], rates[2], rates[3]]);
        let (s, co) = phi.sin_cos();
        for &u0 in &speeds {
            let u = seed([u0, u0 * 0.3, u0 * -0.4, C64::from(0.0), C64::from(0.0)]);
            let v = read(atan2(u * s, u * co));
            assert!(v.iter().all(|x| x.re().is_finite() && x.im().is_finite()));
            // The value: φ0 + kπ.
            let k = ((v[0] - phi0).re() / PI).round();
            multiples.insert(k as i64);
            let e = (v[0] - phi0 - k * PI).norm();
            assert!(
                e < 1e-14,
                "φ0 = {phi0}, u0 = {u0}: {} = φ0 + {k}π + {e:e}",
                v[0]
            );
            // The real part in [−π, π] (−π where a zero's sign says so).
            assert!(v[0].re().abs() <= PI, "φ0 = {phi0}, u0 = {u0}: {}", v[0]);
            worst_value = worst_value.max(e);
            // The derivatives: φ's exactly.
            for n in 1..5 {
                let e = (v[n] - rates[n - 1]).norm();
                assert!(
                    e < 1e-13,
                    "φ0 = {phi0}, u0 = {u0}: d^{n} = {} vs {}: {e:e}",
                    v[n],
                    rates[n - 1]
                );
                if e > worst_rate {
                    worst_rate = e;
                    worst_at = (phi0, u0, n);
                }
            }
        }
    }
    println!(
        "worst errors: value {worst_value:e}, derivatives {worst_rate:e} at {worst_at:?}; multiples of π {multiples:?}"
    );
}

/// Real `C64` arguments: `f64::atan2`'s value up to rounding.
#[test]
fn atan2_on_real_c64_arguments_is_f64s() {
    for k in 0..720 {
        let th = -PI + (k as f64 + 0.5) * PI / 360.0;
        for r in [1e-3, 1.0, 7.0] {
            let (y, x) = (r * th.sin(), r * th.cos());
            let v = atan2(C64::from(y), C64::from(x));
            assert!((v.re() - atan2(y, x)).abs() <= 4.5e-16, "θ = {th}");
            assert!((v.re() - y.atan2(x)).abs() <= 2e-15, "θ = {th}");
            assert_eq!(v.im(), 0.0);
        }
    }
}
