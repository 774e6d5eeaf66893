//! The hand-written baselines compute what the AD formulations compute, so
//! the benchmark compares equal answers: at pseudo-random states and
//! sleighs, both potentials.

use nonholo_bench::hand::{BodyFrame, Constants, Realisation, ReducedB, ReducedC};
use nonholo_bench::setup::{cartesian, options, sleigh};
use nonholo_chetaev::Chetaev;
use nonholo_core::Params;
use nonholo_core::integrate::OdeSystem;
use nonholo_realise::{Mass, Visc, mass, visc};
use nonholo_vakonomic::Vakonomic;

/// A small deterministic generator (no dependency needed).
struct Lcg(u64);

impl Lcg {
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        lo + (hi - lo) * ((self.0 >> 11) as f64 / (1u64 << 53) as f64)
    }
}

fn close(got: f64, expect: f64, scale: f64, what: &str) {
    assert!(
        (got - expect).abs() <= 1e-12 * (scale + expect.abs()),
        "{what}: {got} vs {expect}"
    );
}

const CASES: usize = 100;

/// A pseudo-random sleigh and state: offset `a ∈ [−0.9, 0.9]`, slope
/// `α ∈ [0, 1.4]`, heading, speed, turning rate, position, and (with
/// `slip`) a sideways slip `w ∈ [−0.5, 0.5]` violating the constraint.
struct Case {
    s: nonholo_scenes::Sleigh,
    c: Constants,
    phi: f64,
    u: f64,
    w: f64,
    om: f64,
    q: [f64; 3],
}

fn draw(r: &mut Lcg, potential: &str, slip: bool) -> Case {
    let s = sleigh(r.uniform(-0.9, 0.9), r.uniform(0.0, 1.4), potential).unwrap();
    let c = Constants::of(&s);
    let phi = r.uniform(-3.0, 3.0);
    let u = r.uniform(-3.0, 3.0);
    let w = if slip { r.uniform(-0.5, 0.5) } else { 0.0 };
    let om = r.uniform(-2.0, 2.0);
    let q = [r.uniform(-1.0, 1.0), r.uniform(-1.0, 1.0), phi];
    Case {
        s,
        c,
        phi,
        u,
        w,
        om,
        q,
    }
}

#[test]
fn reduced_b_is_b_on_the_constraint() {
    let mut r = Lcg(1);
    for potential in ["paper", "com"] {
        for _ in 0..CASES {
            let Case {
                s,
                c,
                phi,
                u,
                om,
                q,
                ..
            } = draw(&mut r, potential, false);
            let mut b = Chetaev::new(s, Params::defaults(nonholo_chetaev::OPTIONS)).unwrap();
            let mut dy = [0.0; 6];
            b.rhs(0.0, &cartesian(q, u, 0.0, om), &mut dy).unwrap();
            let mut dr = [0.0; 5];
            ReducedB(c)
                .rhs(0.0, &[q[0], q[1], phi, u, om], &mut dr)
                .unwrap();
            let (sn, cs) = phi.sin_cos();
            let (ud, omd) = (dr[3], dr[4]);
            let expect = [ud * cs - u * om * sn, ud * sn + u * om * cs, omd];
            for i in 0..3 {
                close(dy[3 + i], expect[i], 1.0, &format!("B q̈[{i}] {potential}"));
            }
            close(dr[0], dy[0], 1.0, "ẋ");
            close(dr[1], dy[1], 1.0, "ẏ");
        }
    }
}

#[test]
fn reduced_b_jacobian_matches_central_differences() {
    let s = sleigh(0.4, 0.3, "com").unwrap();
    let mut sys = ReducedB(Constants::of(&s));
    let y = [0.3, -0.2, 0.2, 2.0, 0.7];
    let mut jac = [0.0; 25];
    assert!(sys.jacobian(0.0, &y, &mut jac).unwrap());
    let (mut fp, mut fm) = ([0.0; 5], [0.0; 5]);
    for j in 0..5 {
        let h = 1e-6;
        let (mut yp, mut ym) = (y, y);
        yp[j] += h;
        ym[j] -= h;
        sys.rhs(0.0, &yp, &mut fp).unwrap();
        sys.rhs(0.0, &ym, &mut fm).unwrap();
        for i in 0..5 {
            let fd = (fp[i] - fm[i]) / (2.0 * h);
            assert!(
                (jac[i * 5 + j] - fd).abs() < 1e-8,
                "∂f{i}/∂y{j}: {} vs {fd}",
                jac[i * 5 + j]
            );
        }
    }
}

#[test]
fn reduced_c_is_c() {
    let mut r = Lcg(2);
    for potential in ["paper", "com"] {
        for _ in 0..CASES {
            let Case {
                s,
                c,
                phi,
                u,
                om,
                q,
                ..
            } = draw(&mut r, potential, false);
            let lambda = r.uniform(-2.0, 2.0);
            let mut cc = Vakonomic::new(s, Params::defaults(nonholo_vakonomic::OPTIONS)).unwrap();
            let mut y = cartesian(q, u, 0.0, om).to_vec();
            y.push(lambda);
            let mut dy = [0.0; 7];
            cc.rhs(0.0, &y, &mut dy).unwrap();
            let mu = lambda + c.m * c.a * om;
            let mut dr = [0.0; 6];
            ReducedC(c)
                .rhs(0.0, &[q[0], q[1], phi, u, om, mu], &mut dr)
                .unwrap();
            let (sn, cs) = phi.sin_cos();
            let (ud, omd, mud) = (dr[3], dr[4], dr[5]);
            let expect = [ud * cs - u * om * sn, ud * sn + u * om * cs, omd];
            for i in 0..3 {
                close(dy[3 + i], expect[i], 1.0, &format!("C q̈[{i}] {potential}"));
            }
            // λ = μ − m a ω
            close(
                dy[6],
                mud - c.m * c.a * omd,
                1.0,
                &format!("C λ̇ {potential}"),
            );
        }
    }
}

#[test]
fn body_frame_is_the_realisations() {
    let mut r = Lcg(3);
    for potential in ["paper", "com"] {
        for _ in 0..CASES {
            let Case {
                s,
                c,
                phi: _,
                u,
                w,
                om,
                q,
            } = draw(&mut r, potential, true);
            let gain = 10f64.powf(r.uniform(0.0, 6.0));
            let y = cartesian(q, u, w, om);
            // The friction / added-mass term sets the scale of round-off.
            let scale = 1.0 + gain * w.abs() * (1.0 + u.abs() + om.abs()) / c.m;
            let g = gain.to_string();

            let mut v = Visc::new(
                s.clone(),
                options(visc::OPTIONS, &[("k", &g), ("form", "cartesian")]).unwrap(),
            )
            .unwrap();
            let (mut ad, mut hand) = ([0.0; 6], [0.0; 6]);
            v.rhs(0.0, &y, &mut ad).unwrap();
            let mut bv = BodyFrame {
                c,
                which: Realisation::Visc,
                gain,
            };
            bv.rhs(0.0, &y, &mut hand).unwrap();
            for i in 0..6 {
                close(
                    ad[i],
                    hand[i],
                    scale,
                    &format!("visc {potential} k={gain:e} [{i}]"),
                );
            }

            let mut md = Mass::new(
                s.clone(),
                options(mass::OPTIONS, &[("N", &g), ("form", "direct")]).unwrap(),
            )
            .unwrap();
            md.rhs(0.0, &y, &mut ad).unwrap();
            let mut bd = BodyFrame {
                c,
                which: Realisation::MassDirect,
                gain,
            };
            bd.rhs(0.0, &y, &mut hand).unwrap();
            // The direct form's mass matrix has condition ~N/m.
            let cond = 1.0 + gain / c.m;
            for i in 0..6 {
                assert!(
                    (ad[i] - hand[i]).abs()
                        <= 1e-12 * (scale + hand[i].abs())
                            + 8.0 * f64::EPSILON * cond * hand[i].abs(),
                    "mass direct {potential} N={gain:e} [{i}]: {} vs {}",
                    ad[i],
                    hand[i]
                );
            }

            let mut mc = Mass::new(s, options(mass::OPTIONS, &[("N", &g)]).unwrap()).unwrap();
            let mut yc = y.to_vec();
            yc.push(gain * w);
            let (mut adc, mut handc) = ([0.0; 7], [0.0; 7]);
            mc.rhs(0.0, &yc, &mut adc).unwrap();
            let mut bc = BodyFrame {
                c,
                which: Realisation::MassCompliance,
                gain,
            };
            bc.rhs(0.0, &yc, &mut handc).unwrap();
            for i in 0..6 {
                close(
                    adc[i],
                    handc[i],
                    scale,
                    &format!("mass compliance {potential} [{i}]"),
                );
            }
            close(
                adc[6],
                handc[6],
                gain * scale,
                &format!("mass compliance λ̇ {potential}"),
            );
        }
    }
}

#[test]
fn body_visc_is_visc_in_adapted_velocities() {
    use nonholo_bench::hand::BodyVisc;
    let mut r = Lcg(4);
    for potential in ["paper", "com"] {
        for _ in 0..CASES {
            let Case {
                s,
                c,
                phi,
                u,
                w,
                om,
                q,
            } = draw(&mut r, potential, true);
            let k = 10f64.powf(r.uniform(0.0, 8.0));
            let y = cartesian(q, u, w, om);
            let mut yb = y;
            BodyVisc::from_cartesian(&mut yb);
            assert!((yb[3] - u).abs() < 1e-12 && (yb[4] - w).abs() < 1e-12);
            let mut back = yb;
            BodyVisc::to_cartesian(&mut back);
            for i in 0..6 {
                assert!((back[i] - y[i]).abs() < 1e-12);
            }
            let mut v = Visc::new(
                s,
                options(
                    visc::OPTIONS,
                    &[("k", &k.to_string()), ("form", "cartesian")],
                )
                .unwrap(),
            )
            .unwrap();
            let mut ad = [0.0; 6];
            v.rhs(0.0, &y, &mut ad).unwrap();
            let mut db = [0.0; 6];
            BodyVisc { c, k }.rhs(0.0, &yb, &mut db).unwrap();
            // Chain rule: ẍ = u̇ c − u ω s − ẇ s − w ω c, ÿ = u̇ s + u ω c + ẇ c − w ω s.
            let (sn, cs) = phi.sin_cos();
            let (ud, wd, omd) = (db[3], db[4], db[5]);
            let expect = [
                ud * cs - u * om * sn - wd * sn - w * om * cs,
                ud * sn + u * om * cs + wd * cs - w * om * sn,
                omd,
            ];
            let scale = 1.0 + k * w.abs() / c.m;
            for i in 0..3 {
                close(
                    ad[3 + i],
                    expect[i],
                    scale,
                    &format!("body visc {potential} k={k:e} [{i}]"),
                );
                close(db[i], y[3 + i], 1.0, "kinematics");
            }
        }
    }
}

/// The AD adapted form (`visc`, `form = adapted`, state `(q, u, c_ω, w)`)
/// is the body-frame `BodyVisc` (state `(q, u, w, ω)`) in other
/// quasi-velocities: its frame column for `w` is `N = (−sin φ, cos φ, −a/J)`,
/// so `c_ω = ω + a w/J` and `ċ_ω = ω̇ + a ẇ/J`.
#[test]
fn body_visc_is_the_adapted_form() {
    use nonholo_bench::hand::BodyVisc;
    use nonholo_bench::setup::adapted_state;
    let mut r = Lcg(5);
    for potential in ["paper", "com"] {
        for _ in 0..CASES {
            let Case {
                s,
                c,
                phi: _,
                u,
                w,
                om,
                q,
            } = draw(&mut r, potential, true);
            let k = 10f64.powf(r.uniform(0.0, 8.0));
            let ya = adapted_state(&c, q, u, w, om);
            let yb = [q[0], q[1], q[2], u, w, om];
            let mut v = Visc::new(
                s,
                options(visc::OPTIONS, &[("k", &k.to_string()), ("form", "adapted")]).unwrap(),
            )
            .unwrap();
            let (mut da, mut db) = ([0.0; 6], [0.0; 6]);
            v.rhs(0.0, &ya, &mut da).unwrap();
            BodyVisc { c, k }.rhs(0.0, &yb, &mut db).unwrap();
            let expect = [db[0], db[1], db[2], db[3], db[5] + c.a * db[4] / c.j, db[4]];
            let scale = 1.0 + k * w.abs() / c.m;
            for i in 0..6 {
                close(
                    da[i],
                    expect[i],
                    scale,
                    &format!("adapted visc {potential} k={k:e} [{i}]"),
                );
            }
        }
    }
}
