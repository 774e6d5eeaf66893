//! Each scene's Lagrangian, constraints, maps and closed forms against
//! values written here independently of the scene code (other forms of the
//! same physics: kinetic energy of the centre of mass, the rolling
//! condition, time derivatives by central differences).

use nonholo_core::scene::MAX_SINGULAR;
use nonholo_core::{Error, Params, Scene};
use nonholo_scenes::{AppellHamel, Pendulum, RollingDisk, Sleigh};

fn scene<S: Scene>(params: &[(&str, &str)]) -> Result<S, Error> {
    let given: Vec<(String, String)> = params
        .iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect();
    S::from_params(&Params::resolve(S::INFO.params, &given, "parameter")?)
}

/// States `(q, q̇)` of the sleigh at several headings, in every quadrant.
const SLEIGH_STATES: [([f64; 3], [f64; 3]); 4] = [
    ([0.3, -1.2, 0.4], [1.1, -0.7, 0.9]),
    ([-2.0, 0.5, 2.9], [-0.3, 0.2, -1.4]),
    ([0.0, 0.0, -1.7], [0.0, 2.0, 0.0]),
    ([5.0, 3.0, 4.5], [-1.5, -1.5, 0.3]),
];

/// `L = ½m|v_G|² + ½m(J − a²)φ̇² + m g sin α (x + [com] a cos φ)`, the
/// centre of mass `G` at `a` ahead of the blade: `v_G = (ẋ − aφ̇ sin φ,
/// ẏ + aφ̇ cos φ)`, the moment of inertia about `G` `m(J − a²)`.
#[test]
fn sleigh_lagrangian_is_the_rigid_body_energy() {
    let (m, j, a, g, alpha): (f64, f64, f64, f64, f64) = (1.7, 1.3, 0.4, 9.81, 0.3);
    for potential in ["paper", "com"] {
        let s: Sleigh = scene(&[
            ("m", "1.7"),
            ("J", "1.3"),
            ("a", "0.4"),
            ("alpha", "0.3"),
            ("potential", potential),
        ])
        .unwrap();
        let com = if potential == "com" { 1.0 } else { 0.0 };
        for (q, qd) in SLEIGH_STATES {
            let (sp, cp) = q[2].sin_cos();
            let vg = (qd[0] - a * qd[2] * sp, qd[1] + a * qd[2] * cp);
            let kinetic =
                0.5 * m * (vg.0 * vg.0 + vg.1 * vg.1) + 0.5 * m * (j - a * a) * qd[2] * qd[2];
            let expect = kinetic + m * g * alpha.sin() * (q[0] + com * a * cp);
            let l = s.lagrangian(0.0f64, &q, &qd);
            assert!(
                (l - expect).abs() < 1e-13 * (1.0 + expect.abs()),
                "{l} vs {expect}"
            );
        }
    }
}

/// The blade's lateral velocity `g = ẏ cos φ − ẋ sin φ`, zero on the chart
/// `(u, ω)`; the map `φ = atan2(ẏ, ẋ)` and its singular vector `(ẋ, ẏ)`.
#[test]
fn sleigh_constraint_chart_and_embedding_map() {
    let s: Sleigh = scene(&[]).unwrap();
    for (q, qd) in SLEIGH_STATES {
        let mut g = [0.0f64];
        s.nonholonomic(0.0, &q, &qd, &mut g);
        // Lateral velocity: the velocity's component along the normal (−sin φ, cos φ).
        let lateral = -qd[0] * q[2].sin() + qd[1] * q[2].cos();
        assert!((g[0] - lateral).abs() < 1e-15);

        let (u, w) = (qd[0] + 0.5, qd[2]);
        let mut on = [0.0; 3];
        s.velocities_from(&q, &[u, w], &mut on);
        s.nonholonomic(0.0, &q, &on, &mut g);
        assert!(g[0].abs() < 1e-15);
        assert!(((on[0] * on[0] + on[1] * on[1]).sqrt() - u.abs()).abs() < 1e-15);
        assert_eq!(on[2], w);

        if qd[0] != 0.0 || qd[1] != 0.0 {
            let mut phi = [0.0];
            s.embedding(0.0, &q[..2], &qd[..2], &[], &mut phi);
            assert!((phi[0] - qd[1].atan2(qd[0])).abs() < 1e-15);
            // The map's heading points along the velocity.
            let speed = qd[0].hypot(qd[1]);
            assert!((phi[0].cos() * speed - qd[0]).abs() < 1e-14);
            assert!((phi[0].sin() * speed - qd[1]).abs() < 1e-14);
        }
        let mut r = [0.0; MAX_SINGULAR];
        assert_eq!(s.embedding_singularity(0.0, &q[..2], &qd[..2], &mut r), 2);
        assert_eq!(&r[..2], &qd[..2]);
    }
}

/// `J ≤ a²` (a centre of mass outside the radius of gyration) is refused
/// with the relation and both values.
#[test]
fn sleigh_refuses_j_below_a_squared() {
    let e = scene::<Sleigh>(&[("J", "0.1"), ("a", "0.5")]).unwrap_err();
    match e {
        Error::InconsistentParams {
            requirement,
            values,
            ..
        } => {
            assert!(requirement.starts_with("J > a²"), "{requirement}");
            assert_eq!(values, [("J".to_string(), 0.1), ("a".to_string(), 0.5)]);
        }
        other => panic!("{other:?}"),
    }
}

/// `(q, q̇)` at `t` by the scene's closed form.
fn closed<S: Scene>(s: &S, q0: &[f64], qd0: &[f64], t: f64) -> (Vec<f64>, Vec<f64>) {
    let n = q0.len();
    let (mut q, mut qd) = (vec![0.0; n], vec![0.0; n]);
    s.closed_form(q0, qd0, t, &mut q, &mut qd).unwrap();
    (q, qd)
}

/// Central difference of a closed form's `q` and `q̇` at `t`: `(q̇, q̈)`.
fn rates<S: Scene>(s: &S, q0: &[f64], qd0: &[f64], t: f64) -> (Vec<f64>, Vec<f64>) {
    let h = 1e-5;
    let (qp, vp) = closed(s, q0, qd0, t + h);
    let (qm, vm) = closed(s, q0, qd0, t - h);
    let d = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y) / (2.0 * h)).collect();
    (d(&qp, &qm), d(&vp, &vm))
}

/// The sleigh's closed form for `a = 0` starts at the data, is consistent
/// (`q̇` is the derivative of `q`, on the constraint), and satisfies B's
/// reduced equations `u̇ = g sin α cos φ`, `ω̇ = 0`.
#[test]
fn sleigh_closed_form_solves_the_reduced_equations() {
    let s: Sleigh = scene(&[("a", "0"), ("alpha", "0.3")]).unwrap();
    let (q0, phi0, u0, w0) = ([0.4, -0.2, 0.2], 0.2, 2.0, 0.7);
    let mut qd0 = [0.0; 3];
    s.velocities_from(&[0.0, 0.0, phi0], &[u0, w0], &mut qd0);
    let (q, qd) = closed(&s, &q0, &qd0, 0.0);
    assert!(q.iter().zip(&q0).all(|(a, b)| (a - b).abs() < 1e-15));
    assert!(qd.iter().zip(&qd0).all(|(a, b)| (a - b).abs() < 1e-15));
    for t in [0.3, 1.7, 6.0] {
        let (q, qd) = closed(&s, &q0, &qd0, t);
        let (dq, dqd) = rates(&s, &q0, &qd0, t);
        for i in 0..3 {
            assert!((dq[i] - qd[i]).abs() < 1e-8, "t = {t}: q̇[{i}]");
        }
        let mut g = [0.0f64];
        s.nonholonomic(t, &q, &qd, &mut g);
        assert!(g[0].abs() < 1e-14);
        let (sp, cp) = q[2].sin_cos();
        let u = qd[0] * cp + qd[1] * sp;
        // u̇ = d/dt(ẋ cos φ + ẏ sin φ) with φ̇ = ω.
        let ud = dqd[0] * cp + dqd[1] * sp + qd[2] * (-qd[0] * sp + qd[1] * cp);
        assert!((ud - 9.81 * 0.3f64.sin() * cp).abs() < 1e-7, "t = {t}: u̇");
        assert!(dqd[2].abs() < 1e-9 && (qd[2] - w0).abs() < 1e-15);
        assert!(u.is_finite());
    }
    assert!(
        s.closed_form(&q0, &[1.0, 0.0, 0.0], 1.0, &mut [0.0; 3], &mut [0.0; 3])
            .is_err()
    );
    let s: Sleigh = scene(&[]).unwrap();
    assert!(
        s.closed_form(&q0, &qd0, 1.0, &mut [0.0; 3], &mut [0.0; 3])
            .is_err()
    );
}

/// The disk: `L` the translational and two rotational energies, the
/// rolling condition `(ẋ, ẏ) = R ψ̇ (cos θ, sin θ)`, and the closed form
/// (a circle of radius `R ψ̇/θ̇`, a line for `θ̇ = 0`) on it.
#[test]
fn rolling_disk_energy_rolling_condition_and_closed_form() {
    let d: RollingDisk = scene(&[("m", "2"), ("I", "0.3"), ("Jr", "0.6"), ("R", "0.7")]).unwrap();
    let (q, qd) = ([0.3, -0.4, 1.1, 2.0], [0.5, -0.2, 0.9, -1.3]);
    let l = d.lagrangian(0.0f64, &q, &qd);
    let expect = 0.5 * 2.0 * (0.25 + 0.04) + 0.5 * 0.3 * 0.81 + 0.5 * 0.6 * 1.69;
    assert!((l - expect).abs() < 1e-15);
    let mut g = [0.0f64; 2];
    d.nonholonomic(0.0, &q, &qd, &mut g);
    assert!((g[0] - (0.5 + 0.7 * 1.3 * 1.1f64.cos())).abs() < 1e-15);
    assert!((g[1] - (-0.2 + 0.7 * 1.3 * 1.1f64.sin())).abs() < 1e-15);
    let mut on = [0.0; 4];
    d.velocities_from(&q, &[0.9, -1.3], &mut on);
    d.nonholonomic(0.0, &q, &on, &mut g);
    assert!(g[0].abs() < 1e-15 && g[1].abs() < 1e-15);
    assert_eq!((on[2], on[3]), (0.9, -1.3));

    for turning in [0.9, 0.0] {
        let mut qd0 = [0.0; 4];
        d.velocities_from(&q, &[turning, -1.3], &mut qd0);
        for t in [0.0, 0.8, 3.0] {
            let (qt, qdt) = closed(&d, &q, &qd0, t);
            let (dq, dqd) = rates(&d, &q, &qd0, t);
            for i in 0..4 {
                assert!((dq[i] - qdt[i]).abs() < 1e-9, "θ̇ = {turning}, t = {t}");
            }
            d.nonholonomic(t, &qt, &qdt, &mut g);
            assert!(g[0].abs() < 1e-14 && g[1].abs() < 1e-14);
            // B: θ̈ = ψ̈ = 0, the invariants θ̇, ψ̇.
            assert!(dqd[2].abs() < 1e-9 && dqd[3].abs() < 1e-9);
            assert_eq!(d.invariant(0, t, &qt, &qdt), turning);
            assert_eq!(d.invariant(1, t, &qt, &qdt), -1.3);
            if turning != 0.0 {
                // On the circle of radius |R ψ̇/θ̇| about the centre at t = 0.
                let rad = 0.7 * -1.3 / turning;
                let c = (q[0] - rad * q[2].sin(), q[1] + rad * q[2].cos());
                let r = (qt[0] - c.0).hypot(qt[1] - c.1);
                assert!((r - rad.abs()).abs() < 1e-14, "radius {r}");
            }
        }
    }
}

/// Appell–Hamel: `L` with gravity along `z`, `g = ż + c ρ`, its singular
/// vector, the chart `(ρ, β)`, and B's closed form (a straight horizontal
/// path, `ρ̇ = c g/(1 + c²)`, `z̈ = −c² g/(1 + c²)`).
#[test]
fn appell_hamel_constraint_chart_and_closed_form() {
    for c in [0.5f64, -0.5] {
        let c_text = c.to_string();
        let s: AppellHamel = scene(&[("m", "1.5"), ("c", &c_text)]).unwrap();
        let (q, qd) = ([1.0, 2.0, 3.0], [0.6, -0.8, 0.1]);
        let l = s.lagrangian(0.0f64, &q, &qd);
        assert!((l - (0.5 * 1.5 * 1.01 - 1.5 * 9.81 * 3.0)).abs() < 1e-13);
        let mut g = [0.0f64];
        s.nonholonomic(0.0, &q, &qd, &mut g);
        assert!((g[0] - (0.1 + c * 1.0)).abs() < 1e-15);
        let mut r = [0.0; MAX_SINGULAR];
        assert_eq!(s.constraint_singularity(0.0, &q, &qd, &mut r), 2);
        assert_eq!(&r[..2], &qd[..2]);

        let mut qd0 = [0.0; 3];
        s.velocities_from(&q, &[2.0, 0.4], &mut qd0);
        s.nonholonomic(0.0, &q, &qd0, &mut g);
        assert!(g[0].abs() < 1e-15);
        let k = 1.0 + c * c;
        assert!((s.rho_dot() - c * 9.81 / k).abs() < 1e-15);
        for t in [0.0, 0.2, 0.35] {
            let (qt, qdt) = closed(&s, &q, &qd0, t);
            let (dq, dqd) = rates(&s, &q, &qd0, t);
            for i in 0..3 {
                assert!((dq[i] - qdt[i]).abs() < 1e-9, "c = {c}, t = {t}");
            }
            s.nonholonomic(t, &qt, &qdt, &mut g);
            assert!(g[0].abs() < 1e-14);
            assert!((dqd[2] + c * c * 9.81 / k).abs() < 1e-7, "z̈ at t = {t}");
            assert!((s.invariant(0, t, &qt, &qdt) - 0.4).abs() < 1e-15);
        }
    }
    // c < 0: the horizontal speed stops at t* = ρ0 (1 + c²)/(|c| g).
    let s: AppellHamel = scene(&[("c", "-0.5")]).unwrap();
    let t_stop = 2.0 * 1.25 / (0.5 * 9.81);
    let (_, qd) = closed(&s, &[0.0; 3], &[2.0, 0.0, 1.0], t_stop * (1.0 - 1e-12));
    assert!(qd[0].abs() < 1e-10);
    assert!(
        s.closed_form(
            &[0.0; 3],
            &[2.0, 0.0, 1.0],
            1.01 * t_stop,
            &mut [0.0; 3],
            &mut [0.0; 3]
        )
        .is_err()
    );
    // c = 0: ż = 0 is regular everywhere.
    let s: AppellHamel = scene(&[("c", "0")]).unwrap();
    assert_eq!(
        s.constraint_singularity(0.0, &[0.0; 3], &[0.0; 3], &mut [0.0; MAX_SINGULAR]),
        0
    );
}

/// The pendulum: `L = ½m|v|² − m g y`, the rod `x² + y² = l²` at the default
/// position, and the chart's velocities tangent to it.
#[test]
fn pendulum_rod_and_chart() {
    let p: Pendulum = scene(&[("m", "2"), ("l", "1.5")]).unwrap();
    let q = p.default_q();
    let mut f = [0.0f64];
    p.holonomic(0.0, &q, &mut f);
    assert!(f[0].abs() < 1e-15);
    assert!(q[1] < 0.0 && (q[0].atan2(-q[1]) - 0.5).abs() < 1e-15);
    let mut qd = [0.0; 2];
    p.velocities_from(&q, &[0.8], &mut qd);
    assert!((q[0] * qd[0] + q[1] * qd[1]).abs() < 1e-15);
    assert!((qd[0].hypot(qd[1]) - 0.8 * 1.5).abs() < 1e-15);
    let l = p.lagrangian(0.0f64, &q, &qd);
    assert!((l - (0.5 * 2.0 * 1.44 - 2.0 * 9.81 * q[1])).abs() < 1e-13);
    p.holonomic(0.0, &[1.0, 1.0], &mut f);
    assert!((f[0] - (2.0 - 2.25)).abs() < 1e-15);
}

/// The registry builds every scene from its defaults and names the valid
/// scenes for an unknown one.
#[test]
fn registry_builds_every_scene() {
    for info in nonholo_scenes::ALL {
        let s = nonholo_scenes::build(info.name, &[]).unwrap();
        assert_eq!(s.info().name, info.name);
        assert_eq!(s.info().default_q.len(), info.n());
    }
    match nonholo_scenes::build("sleigh", &[]) {
        Err(Error::UnknownName { name, valid, .. }) => {
            assert_eq!(name, "sleigh");
            assert_eq!(valid.len(), nonholo_scenes::ALL.len());
        }
        other => panic!("{other:?}"),
    }
}

/// The disk's embedding map: the heading is the direction of the contact
/// point's velocity, `ψ̇` its speed over `R` (signed by the branch), so that
/// `(θ, ψ̇)` satisfy the rolling condition; `ψ` is cyclic — absent from `L`
/// and `g` (their derivatives in `ψ` vanish at states in every quadrant).
#[test]
fn rolling_disk_embedding_map_and_cyclic_angle() {
    use num_dual::Dual64;
    let d: RollingDisk = scene(&[("m", "2"), ("I", "0.3"), ("Jr", "0.6"), ("R", "0.7")]).unwrap();
    let e = RollingDisk::INFO.embedding.unwrap();
    assert_eq!(
        (e.independent, e.dependent, e.cyclic),
        (&[0, 1][..], &[2, 3][..], &[3][..])
    );
    for (v, heading) in [
        ([0.5f64, 0.2], 0.2f64.atan2(0.5)),
        ([-0.3, 0.8], 0.8f64.atan2(-0.3)),
        ([-1.1, -0.4], (-0.4f64).atan2(-1.1)),
        ([0.2, -2.0], (-2.0f64).atan2(0.2)),
    ] {
        let speed = v[0].hypot(v[1]);
        // Principal branch, then the branch continued through a reversal
        // (heading turned by π: the disk rolls backwards).
        for (near, sign, shift) in [(vec![], 1.0, 0.0), (vec![heading + 3.0], -1.0, 1.0)] {
            let mut dep = [0.0; 2];
            d.embedding(0.0, &[0.1, -0.2], &v, &near, &mut dep);
            let theta = heading + shift * std::f64::consts::PI;
            assert!((dep[0] - theta).abs() < 1e-14, "{dep:?} {theta}");
            assert!((dep[1] - sign * speed / 0.7).abs() < 1e-14, "{dep:?}");
            let mut g = [0.0; 2];
            d.nonholonomic(
                0.0,
                &[0.1, -0.2, dep[0], 0.0],
                &[v[0], v[1], 0.4, dep[1]],
                &mut g,
            );
            assert!(g[0].abs() < 1e-15 && g[1].abs() < 1e-15, "{g:?}");
        }
        let mut r = [0.0; MAX_SINGULAR];
        assert_eq!(d.embedding_singularity(0.0, &[0.0, 0.0], &v, &mut r), 2);
        assert_eq!((r[0], r[1]), (v[0], v[1]));
        // ∂L/∂ψ = ∂g/∂ψ = 0.
        for psi in [-2.0, 0.3, 7.0] {
            let q = [0.3, v[0], heading, psi].map(Dual64::from_re);
            let mut qs = q;
            qs[3].eps = 1.0;
            let qd = [v[0], v[1], 0.9, -1.3].map(Dual64::from_re);
            assert_eq!(d.lagrangian(Dual64::from_re(0.0), &qs, &qd).eps, 0.0);
            let mut g = [Dual64::from_re(0.0); 2];
            d.nonholonomic(Dual64::from_re(0.0), &qs, &qd, &mut g);
            assert_eq!((g[0].eps, g[1].eps), (0.0, 0.0));
        }
    }
}

/// `chart_from` inverts `velocities_from` on the constraints, for every
/// scene, at chart values of both signs (the sleigh's `u < 0` is a motion
/// backwards; Appell–Hamel's `ρ ≥ 0` by its definition).
#[test]
fn every_chart_reading_inverts_the_chart() {
    fn check<S: Scene>(s: &S, q: &[f64], charts: &[&[f64]]) {
        for chart in charts {
            let mut qd = vec![0.0; q.len()];
            s.velocities_from(q, chart, &mut qd);
            let mut back = vec![0.0; chart.len()];
            assert!(s.chart_from(q, &qd, &mut back), "{}", s.info().name);
            for (a, b) in chart.iter().zip(&back) {
                assert!(
                    (a - b).abs() < 1e-14,
                    "{}: {chart:?} → {back:?}",
                    s.info().name
                );
            }
        }
    }
    let sleigh: Sleigh = scene(&[]).unwrap();
    check(&sleigh, &[0.3, 1.0, 2.5], &[&[1.5, -0.4], &[-0.7, 2.0]]);
    let disk: RollingDisk = scene(&[]).unwrap();
    check(&disk, &[0.3, 1.0, -2.0, 4.0], &[&[0.5, 1.0], &[-0.2, -3.0]]);
    let appell: AppellHamel = scene(&[]).unwrap();
    check(&appell, &[0.3, 1.0, 0.2], &[&[1.5, 0.4], &[0.2, -2.8]]);
    let pendulum: Pendulum = scene(&[]).unwrap();
    check(&pendulum, &[0.6, -0.8], &[&[1.5], &[-0.3]]);
}
