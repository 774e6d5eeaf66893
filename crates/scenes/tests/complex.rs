//! The sleigh's functions, written once over `D: Scalar`, evaluated at
//! complex states (`C64`) against the same formulas written with num-complex
//! directly; its mass matrix and forces by core's automatic differentiation
//! over `C64` (hyper-dual and dual numbers over complex values) against
//! their hand derivation.

use nalgebra::DMatrix;
use nonholo_core::ad::Jet;
use nonholo_core::complex::Complex64 as Cx;
use nonholo_core::scene::Lagrangian;
use nonholo_core::{C64, Params, Scene};
use nonholo_scenes::Sleigh;
use num_dual::Dual;

const G: f64 = 9.81;

fn sleigh(potential: &str) -> Sleigh {
    let given: Vec<(String, String)> = [
        ("m", "1.7"),
        ("J", "1.3"),
        ("a", "0.4"),
        ("alpha", "0.3"),
        ("potential", potential),
    ]
    .iter()
    .map(|(a, b)| (a.to_string(), b.to_string()))
    .collect();
    Sleigh::from_params(&Params::resolve(Sleigh::INFO.params, &given, "parameter").unwrap())
        .unwrap()
}

const M: f64 = 1.7;
const J: f64 = 1.3;
const A: f64 = 0.4;
const ALPHA: f64 = 0.3;

fn c(re: f64, im: f64) -> Cx {
    Cx::new(re, im)
}

/// Complex states `(q, q̇)`: headings near 0, ±π/2 and π with imaginary
/// parts, velocities with real, imaginary and mixed parts (none isotropic:
/// the map is singular where `ẋ² + ẏ² = 0`, e.g. at `(1 + i, 1 − i)`).
fn states() -> Vec<([Cx; 3], [Cx; 3])> {
    vec![
        (
            [c(0.3, 0.1), c(-1.2, 0.0), c(0.4, -0.3)],
            [c(1.1, 0.2), c(-0.7, 0.5), c(0.9, -0.1)],
        ),
        (
            [
                c(-2.0, -0.5),
                c(0.5, 0.2),
                c(std::f64::consts::FRAC_PI_2 - 1e-7, 0.2),
            ],
            [c(0.0, 1e-3), c(0.0, 0.8), c(-1.4, 0.3)],
        ),
        (
            [c(0.0, 0.0), c(0.0, 1.0), c(-1.7, 0.0)],
            [c(0.0, 2.0), c(0.1, 0.0), c(0.0, -0.6)],
        ),
        (
            [c(5.0, 1.0), c(3.0, -1.0), c(3.1, 0.7)],
            [c(-1.5, -1.5), c(-1.5, 0.5), c(0.3, 0.0)],
        ),
    ]
}

fn rel(a: Cx, b: Cx) -> f64 {
    (a - b).norm() / b.norm().max(1.0)
}

fn lift<const N: usize>(v: [Cx; N]) -> [C64; N] {
    v.map(C64)
}

/// Eq. (22) with num-complex: `½m[ẋ² + ẏ² + Jφ̇² + 2aφ̇(ẏ cos φ − ẋ sin φ)]
/// + m g x sin α (+ m g a sin α cos φ)`.
fn lagrangian(q: [Cx; 3], qd: [Cx; 3], com: bool) -> Cx {
    let (s, co) = (q[2].sin(), q[2].cos());
    let kinetic = 0.5
        * M
        * (qd[0] * qd[0]
            + qd[1] * qd[1]
            + J * qd[2] * qd[2]
            + 2.0 * A * qd[2] * (qd[1] * co - qd[0] * s));
    let mgs = M * G * ALPHA.sin();
    kinetic + mgs * q[0] + if com { mgs * A * co } else { c(0.0, 0.0) }
}

#[test]
fn sleigh_functions_at_complex_states() {
    for potential in ["paper", "com"] {
        let s = sleigh(potential);
        for (q, qd) in states() {
            let l = s.lagrangian(C64::from(0.3), &lift(q), &lift(qd));
            let expect = lagrangian(q, qd, potential == "com");
            assert!(rel(l.0, expect) < 1e-15, "{potential}: {l} vs {expect}");

            let mut g = [C64::from(0.0)];
            s.nonholonomic(C64::from(0.0), &lift(q), &lift(qd), &mut g);
            let lateral = qd[1] * q[2].cos() - qd[0] * q[2].sin();
            assert!(rel(g[0].0, lateral) < 1e-15);

            // The chart: on the constraint for any complex u, ω.
            let (u, w) = (qd[0] + 0.5, qd[2]);
            let mut on = [C64::from(0.0); 3];
            s.velocities_from(&lift(q), &[C64(u), C64(w)], &mut on);
            assert!(rel(on[0].0, u * q[2].cos()) < 1e-15);
            assert!(rel(on[1].0, u * q[2].sin()) < 1e-15);
            s.nonholonomic(C64::from(0.0), &lift(q), &on, &mut g);
            assert!(g[0].0.norm() < 1e-14 * u.norm().max(1.0));

            // The map: a heading whose tangent is ẏ/ẋ, the principal
            // −i ln((ẋ + iẏ)/√(ẋ² + ẏ²)) up to a multiple of π.
            let mut phi = [C64::from(0.0)];
            s.embedding(
                C64::from(0.0),
                &lift([q[0], q[1]]),
                &lift([qd[0], qd[1]]),
                &[],
                &mut phi,
            );
            let (xd, yd) = (qd[0], qd[1]);
            let (sp, cp) = (phi[0].0.sin(), phi[0].0.cos());
            let speed = (xd.norm_sqr() + yd.norm_sqr()).sqrt();
            assert!((yd * cp - xd * sp).norm() < 1e-15 * speed, "{}", phi[0]);
            let principal =
                Cx::new(0.0, -1.0) * ((xd + Cx::i() * yd) / (xd * xd + yd * yd).sqrt()).ln();
            let k = ((phi[0].0 - principal).re / std::f64::consts::PI).round();
            assert!(
                (phi[0].0 - principal - k * std::f64::consts::PI).norm() < 1e-14,
                "{} vs {principal}",
                phi[0]
            );
            // Round trip through the chart: the map returns the heading
            // up to a multiple of π (u → −u turns it by π).
            s.embedding(
                C64::from(0.0),
                &lift([q[0], q[1]]),
                &[on[0], on[1]],
                &[],
                &mut phi,
            );
            let k = ((phi[0].0 - q[2]).re / std::f64::consts::PI).round();
            assert!((phi[0].0 - q[2] - k * std::f64::consts::PI).norm() < 1e-14);
        }
    }
}

/// The map's derivatives through `Dual<C64>`: `∂φ/∂ẋ = −ẏ/(ẋ² + ẏ²)`,
/// `∂φ/∂ẏ = ẋ/(ẋ² + ẏ²)`, also where `ẋ` is (nearly) zero or imaginary.
#[test]
fn sleigh_map_derivatives_at_complex_velocities() {
    let s = sleigh("paper");
    let zero = Dual::from_re(C64::from(0.0));
    for (_, qd) in states() {
        let (xd, yd) = (qd[0], qd[1]);
        let v2 = xd * xd + yd * yd;
        for (k, expect) in [(0, -yd / v2), (1, xd / v2)] {
            let mut v = [Dual::from_re(C64(xd)), Dual::from_re(C64(yd))];
            v[k].eps = C64::from(1.0);
            let mut phi = [zero];
            s.embedding(zero, &[zero, zero], &v, &[], &mut phi);
            assert!(
                rel(phi[0].eps.0, expect) < 1e-14,
                "{} vs {expect}",
                phi[0].eps
            );
        }
    }
}

/// `M = ∂²L/∂q̇²` and `Q = ∂L/∂q − (∂²L/∂q̇∂q) q̇` by core's automatic
/// differentiation over `C64`, against the hand derivation:
/// `M = m[[1, 0, −a s], [0, 1, a c], [−a s, a c, J]]`,
/// `Q = (m g sin α + m a φ̇² c, m a φ̇² s, [com] −m g a sin α s)`.
#[test]
fn sleigh_mass_and_force_over_c64() {
    for potential in ["paper", "com"] {
        let s = sleigh(potential);
        let mut jet: Jet<C64> = Jet::new(3, 1);
        for (q, qd) in states() {
            let mut mass = DMatrix::from_element(3, 3, C64::from(0.0));
            let mut force = [C64::from(0.0); 3];
            jet.mass_and_force(
                &Lagrangian(&s),
                C64::from(0.0),
                &lift(q),
                &lift(qd),
                &[],
                &mut mass.as_view_mut(),
                &mut force,
            );
            let (sn, cs) = (q[2].sin(), q[2].cos());
            let z = c(0.0, 0.0);
            let one = c(1.0, 0.0);
            let m_expect = [
                [one, z, -A * sn],
                [z, one, A * cs],
                [-A * sn, A * cs, c(J, 0.0)],
            ];
            for i in 0..3 {
                for j in 0..3 {
                    let e = mass[(i, j)].0 - M * m_expect[i][j];
                    assert!(
                        e.norm() < 1e-14,
                        "{potential}: M[{i}{j}] = {}",
                        mass[(i, j)]
                    );
                }
            }
            let mgs = M * G * ALPHA.sin();
            let w2 = qd[2] * qd[2];
            let com = if potential == "com" { 1.0 } else { 0.0 };
            let q_expect = [mgs + M * A * w2 * cs, M * A * w2 * sn, -com * mgs * A * sn];
            for i in 0..3 {
                assert!(
                    (force[i].0 - q_expect[i]).norm() < 1e-13 * (1.0 + q_expect[i].norm()),
                    "{potential}: Q[{i}] = {} vs {}",
                    force[i],
                    q_expect[i]
                );
            }
        }
    }
}
