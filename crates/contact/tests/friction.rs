//! The dry-friction realisation against independent oracles: the sleigh's
//! body-frame equations with Coulomb friction (derived by hand), B's motion
//! and multiplier (stick, and where slip must start), the energy balance,
//! and the rolling disk's slip-to-roll closed form.

use nonholo_chetaev::Chetaev;
use nonholo_contact::friction::{self, Friction};
use nonholo_core::ad::Jet;
use nonholo_core::integrate::{Method, OdeSystem, Options, jacobian_mismatch};
use nonholo_core::scene::Lagrangian;
use nonholo_core::{
    Error, Initial, Model, Observation, Params, Run, RunConfig, Scene, init, simulate,
};
use nonholo_scenes::{RollingDisk, Sleigh};
use rand::{Rng, SeedableRng};

fn pairs(items: &[(&str, &str)]) -> Vec<(String, String)> {
    items
        .iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect()
}

fn scene<S: Scene>(params: &[(&str, &str)]) -> S {
    S::from_params(&Params::resolve(S::INFO.params, &pairs(params), "parameter").unwrap()).unwrap()
}

fn friction<S: Scene>(s: S, given: &[(&str, &str)]) -> Result<Friction<S>, Error> {
    let opts = Params::resolve(friction::OPTIONS, &pairs(given), "option")?;
    Friction::new(s, opts)
}

fn run(model: Box<dyn Model>, init: Initial, tol: f64, t_end: f64, every: f64) -> Run {
    let steps = (t_end / every).round() as usize;
    simulate(
        model,
        init,
        RunConfig {
            method: Method::Dop853,
            options: Options {
                rtol: tol,
                atol: tol,
                output: (0..=steps).map(|i| i as f64 * every).collect(),
                dense: true,
                ..Options::default()
            },
            t_end,
            project_init: false,
        },
    )
    .unwrap()
}

const SLEIGH_INIT: &[(&str, &str)] = &[("phi", "0.2"), ("u", "2"), ("omega", "0.7")];

/// The normal load on the default sleigh's blade, `m g cos α`.
fn sleigh_load() -> f64 {
    9.81 * 0.3f64.cos()
}

/// The sleigh slipping sideways (`w ≠ 0`) with Coulomb friction, in body
/// velocities `(u, w, ω)` by Kirchhoff's equations on SE(2) (derived by
/// hand): `T = ½m(u² + w² + Jω² + 2aωw)`, gravity `m g sin α (cos φ, −sin φ)`
/// at the blade (the paper's potential), the friction `−μN sign(w)` on `w`:
///
/// ```text
/// m u̇ = ω m (w + aω) + m g' cos φ
/// m ẇ + m a ω̇ = −ω m u − m g' sin φ − μN sign(w)
/// m a ẇ + m J ω̇ = w m u − u m (w + aω)
/// ```
///
/// Returns `q̈ = (ẍ, ÿ, φ̈)`.
fn coulomb_qdd(s: &Sleigh, mu_n: f64, phi: f64, u: f64, w: f64, om: f64) -> [f64; 3] {
    let (m, a, j) = (s.m, s.a, s.j);
    let gs = s.g * s.alpha.sin();
    let pw = m * (w + a * om);
    let ud = (om * pw + m * gs * phi.cos()) / m;
    let r1 = -om * m * u - m * gs * phi.sin() - mu_n * w.signum();
    let r2 = w * m * u - u * pw;
    let det = m * m * j - m * a * m * a;
    let wd = (r1 * m * j - m * a * r2) / det;
    let omd = (m * r2 - m * a * r1) / det;
    let (c, sn) = (phi.cos(), phi.sin());
    [
        ud * c - u * om * sn - wd * sn - w * om * c,
        ud * sn + u * om * c + wd * c - w * om * sn,
        omd,
    ]
}

/// Slipping, the right-hand side is the body-frame Coulomb equations at
/// 300 random sleighs (the paper's potential) and states with `w ≠ 0`, to
/// 1e-12; and its Jacobian matches central differences.
#[test]
fn slip_rhs_matches_body_frame_coulomb_equations() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    for case in 0..300 {
        let a: f64 = rng.random_range(-1.0..1.0);
        let j = a * a + rng.random_range(0.1..2.0);
        let m: f64 = rng.random_range(0.5..3.0);
        let alpha: f64 = rng.random_range(0.0..1.4);
        let mu: f64 = rng.random_range(0.0..1.5);
        let s: Sleigh = scene(&[
            ("a", &a.to_string()),
            ("J", &j.to_string()),
            ("m", &m.to_string()),
            ("alpha", &alpha.to_string()),
        ]);
        let (phi, u, om) = (
            rng.random_range(-4.0..4.0),
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
        );
        let w = rng.random_range(0.05..1.0) * if case % 2 == 0 { 1.0 } else { -1.0 };
        let mu_n = mu * m * s.g * alpha.cos();
        let expect = coulomb_qdd(&s, mu_n, phi, u, w, om);
        let (c, sn) = (phi.cos(), phi.sin());
        let given = [
            ("phi", phi),
            ("x_dot", u * c - w * sn),
            ("y_dot", u * sn + w * c),
            ("phi_dot", om),
        ];
        let given: Vec<(String, String)> = given
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        let mut init = init::resolve(&s, &given, &[]).unwrap();
        let mut f = friction(s, &[("mu", &mu.to_string())]).unwrap();
        f.make_consistent(&mut init, false).unwrap();
        let y = f.initial_state(&init).unwrap();
        let mut dy = [0.0; 6];
        f.rhs(0.0, &y, &mut dy).unwrap();
        for i in 0..3 {
            let scale = 1.0 + expect[i].abs() + mu_n / m;
            assert!(
                (dy[3 + i] - expect[i]).abs() < 1e-12 * scale,
                "case {case}: q̈{i} = {} vs {}",
                dy[3 + i],
                expect[i]
            );
        }
        if case < 20 {
            check_jacobian(&mut f, &y);
        }
    }
}

/// Central differences of the right-hand side against the AD Jacobian (to
/// 1e-7 of each column's largest entry: the differences' own error).
fn check_jacobian(sys: &mut dyn OdeSystem, y: &[f64]) {
    let (e, i, j) = jacobian_mismatch(sys, 0.0, y)
        .unwrap()
        .expect("an AD Jacobian");
    assert!(e < 1e-7, "∂f{i}/∂y{j} off central differences by {e:e}");
}

/// B's run of the default sleigh on [0, 5] with its multiplier.
fn b_run(tol: f64) -> Run {
    let s: Sleigh = scene(&[]);
    let init = init::resolve(&s, &pairs(SLEIGH_INIT), &[]).unwrap();
    let opts = Params::resolve(nonholo_chetaev::OPTIONS, &[], "option").unwrap();
    run(
        Box::new(Chetaev::new(s, opts).unwrap()),
        init,
        tol,
        5.0,
        0.01,
    )
}

/// `|λ_B(t)|/N` from B's continuous extension.
fn need(b: &mut Run, t: f64) -> f64 {
    let mut obs = Observation::new(3, 1);
    b.observe_at(t, &mut obs).unwrap();
    obs.multipliers[0].abs() / sleigh_load()
}

fn friction_run(mu: f64, tol: f64, extra: &[(&str, &str)]) -> Result<Run, Error> {
    let s: Sleigh = scene(&[]);
    let init = init::resolve(&s, &pairs(SLEIGH_INIT), &[]).unwrap();
    let mut given = vec![("mu", mu.to_string())];
    given.extend(extra.iter().map(|(a, b)| (*a, b.to_string())));
    let given: Vec<(&str, &str)> = given.iter().map(|(a, b)| (*a, b.as_str())).collect();
    let model = friction(s, &given)?;
    Ok(run(Box::new(model), init, tol, 5.0, 0.01))
}

/// With `μ` above `μ* = max |λ_B|/N` (sampled every 1 ms on [0, 5] s, plus
/// 1 %) the blade never slips and the motion is B's to the tolerance.
#[test]
fn friction_above_the_largest_need_is_b() {
    let mut b = b_run(1e-12);
    let mu_star = (0..=5000)
        .map(|i| need(&mut b, i as f64 * 1e-3))
        .fold(0.0, f64::max);
    assert!((0.26..0.28).contains(&mu_star), "μ* = {mu_star}");
    let f = friction_run(1.01 * mu_star, 1e-12, &[]).unwrap();
    assert!(f.completed() && f.switches.is_empty(), "{:?}", f.switches);
    let mut worst = 0.0f64;
    for (sb, sf) in b.samples.iter().zip(&f.samples) {
        for (x, y) in sb.q.iter().chain(&sb.qd).zip(sf.q.iter().chain(&sf.qd)) {
            worst = worst.max((x - y).abs());
        }
    }
    assert!(worst < 1e-9, "friction differs from B by {worst:e}");
}

/// Below `μ*` the blade sticks until the first time `|λ_B(t)| = μN` — found
/// on B's continuous extension by a scan every 1 ms and bisection — and the
/// located onset agrees to 1e-8 s; during the slip that follows the
/// mechanical energy never increases (at every output point, 10 ms apart),
/// and it is constant while the blade sticks.
#[test]
fn slip_starts_where_b_needs_mu_n_and_dissipates() {
    let mu = 0.25;
    let mut b = b_run(1e-12);
    // friction.md: below |λ_B(0)|/N = 0.187 the blade slides from the start.
    let at_start = need(&mut b, 0.0);
    assert!((at_start - 0.187).abs() < 5e-4, "|λ_B(0)|/N = {at_start}");
    assert!(at_start < mu, "the blade must stick at first");
    let mut lo = 0.0;
    while need(&mut b, lo + 1e-3) < mu {
        lo += 1e-3;
    }
    let mut hi = lo + 1e-3;
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if need(&mut b, mid) < mu {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let onset = 0.5 * (lo + hi);
    let f = friction_run(mu, 1e-12, &[]).unwrap();
    assert!(f.completed());
    let first = &f.switches[0];
    assert_eq!((first.from.as_str(), first.to.as_str()), ("stick", "slip"));
    assert!(
        (first.t - onset).abs() < 1e-8,
        "slip onset at {} s, B needs μN at {onset} s",
        first.t
    );
    // It sticks again later (the slip velocity returns to zero inside the cone).
    let second = &f.switches[1];
    assert_eq!(
        (second.from.as_str(), second.to.as_str()),
        ("slip", "stick")
    );
    assert!(second.force_ratio < 1.0);
    let s: Sleigh = scene(&[]);
    let mut jet = Jet::<f64>::new(3, 1);
    let energy = |i: usize, jet: &mut Jet<f64>| {
        let o = &f.samples[i];
        jet.energy(&Lagrangian(&s), f.solution.t[i], &o.q, &o.qd, &[])
    };
    let (mut slip_drop, mut stick_drift) = (0.0f64, 0.0f64);
    for i in 1..f.samples.len() {
        let (t0, t1) = (f.solution.t[i - 1], f.solution.t[i]);
        let (e0, e1) = (energy(i - 1, &mut jet), energy(i, &mut jet));
        if t0 >= first.t && t1 <= second.t {
            assert!(
                e1 <= e0 + 1e-12,
                "energy rose during slip: {e0} → {e1} at t = {t1}"
            );
            slip_drop += e0 - e1;
        } else if t1 <= first.t || t0 >= second.t {
            stick_drift = stick_drift.max((e1 - e0).abs());
        }
    }
    assert!(slip_drop > 1e-3, "slip dissipated only {slip_drop} J");
    // The recorded contact force is read in the mode of each sample's time:
    // μN while slipping, inside the cone and B's λ before the onset.
    let bound = mu * sleigh_load();
    for (i, o) in f.samples.iter().enumerate() {
        let (t, lam) = (f.solution.t[i], o.multipliers[0].abs());
        if t > first.t && t < second.t {
            assert!(
                (lam - bound).abs() < 1e-12,
                "t = {t}: |λ| = {lam}, μN = {bound}"
            );
        } else {
            assert!(lam < bound, "t = {t}: |λ| = {lam} outside the cone {bound}");
        }
        if t < first.t {
            assert!(
                (lam - need(&mut b, t) * sleigh_load()).abs() < 1e-9,
                "t = {t}"
            );
        }
    }
    assert!(
        stick_drift < 1e-10,
        "energy changed by {stick_drift} J while sticking"
    );
}

/// The rolling disk launched along its heading with `v0 = 2 m/s` and `R ψ̇0 =
/// 0.5 m/s` slides, then rolls. With `m = 1 kg`, `R = 1 m`, `Jr = 0.5 kg m²`,
/// `N = 9.81 N`: the slip `s = v − Rψ̇` obeys `ṡ = −(μN/m)(1 + mR²/Jr)`, so
/// rolling starts at `t_r = s0/((μN/m)(1 + mR²/Jr))` with speed `v_r = v0 −
/// (μN/m) t_r`, and slip has dissipated `μN s0 t_r/2`; then the disk rolls
/// on at `v_r` (B). Located to 1e-8, for three `μ`.
#[test]
fn disk_slip_to_roll_matches_the_closed_form() {
    let (m, r, jr, normal, v0, w0) = (1.0, 1.0, 0.5, 9.81, 2.0, 0.5);
    for mu in [0.1, 0.3, 0.9] {
        let s: RollingDisk = scene(&[]);
        let init = init::resolve(
            &s,
            &pairs(&[
                ("x_dot", "2"),
                ("y_dot", "0"),
                ("theta_dot", "0"),
                ("psi_dot", "0.5"),
            ]),
            &[],
        )
        .unwrap();
        let model = friction(
            s,
            &[("mu", &mu.to_string()), ("normal", &normal.to_string())],
        )
        .unwrap();
        let mut f = run(Box::new(model), init, 1e-12, 1.0, 0.01);
        assert!(f.completed());
        let decel = mu * normal / m;
        let s0 = v0 - r * w0;
        let t_r = s0 / (decel * (1.0 + m * r * r / jr));
        let v_r = v0 - decel * t_r;
        assert_eq!(f.switches.len(), 1, "{:?}", f.switches);
        let sw = &f.switches[0];
        assert_eq!((sw.from.as_str(), sw.to.as_str()), ("slip", "stick"));
        assert!(
            (sw.t - t_r).abs() < 1e-8,
            "μ = {mu}: rolls at {} s, closed form {t_r} s",
            sw.t
        );
        let mut obs = Observation::new(4, 2);
        f.observe_at(sw.t, &mut obs).unwrap();
        assert!(
            (obs.qd[0] - v_r).abs() < 1e-8,
            "μ = {mu}: v_r = {} vs {v_r}",
            obs.qd[0]
        );
        assert!(
            (r * obs.qd[3] - v_r).abs() < 1e-8,
            "μ = {mu}: R ψ̇ = {}",
            r * obs.qd[3]
        );
        let loss = mu * normal * s0 * t_r / 2.0;
        let e0 = 0.5 * m * v0 * v0 + 0.5 * jr * w0 * w0;
        let last = f.samples.last().unwrap();
        let e1 = 0.5 * m * last.qd[0].powi(2) + 0.5 * jr * last.qd[3].powi(2);
        assert!(
            (e0 - e1 - loss).abs() < 1e-8,
            "μ = {mu}: lost {} J, closed form {loss} J",
            e0 - e1
        );
        assert!(
            (last.qd[0] - v_r).abs() < 1e-9,
            "μ = {mu}: rolling speed drifted"
        );
    }
}

/// The disk sliding in two dimensions while it turns, by fixed-step RK4:
/// the stick is located where some slip is left (the approach to rolling is
/// not smooth), and the switch removes it by an impulse inside the contact
/// that the record reports; rolling then holds the constraint to round-off
/// instead of carrying the slip on.
#[test]
fn stick_removes_the_slip_left_at_the_located_stop() {
    let s: RollingDisk = scene(&[]);
    let init = init::resolve(
        &s,
        &pairs(&[
            ("x_dot", "2"),
            ("y_dot", "0.5"),
            ("theta_dot", "0.8"),
            ("psi_dot", "0.5"),
        ]),
        &[],
    )
    .unwrap();
    let model = friction(s, &[("mu", "0.3"), ("normal", "9.81")]).unwrap();
    let f = simulate(
        Box::new(model),
        init,
        RunConfig {
            method: Method::Rk4,
            options: Options {
                fixed_step: Some(0.0025),
                output: (0..=200).map(|i| i as f64 * 0.01).collect(),
                ..Options::default()
            },
            t_end: 2.0,
            project_init: false,
        },
    )
    .unwrap();
    assert!(f.completed());
    assert_eq!(f.switches.len(), 1);
    let sw = &f.switches[0];
    assert_eq!(sw.to, "stick");
    assert!(sw.velocity_jump > 1e-6, "{sw:?}");
    let last = f.samples.last().unwrap();
    let (c, sn) = (last.q[2].cos(), last.q[2].sin());
    let slip = (last.qd[0] - last.qd[3] * c).hypot(last.qd[1] - last.qd[3] * sn);
    assert!(slip < 1e-12, "slip {slip} m/s left after sticking");
}

/// friction.md, wp-friction-disk: on the way to rolling the slip direction
/// of the disk's contact point still turns by about 0.2 rad while the slip
/// speed falls from 9e-3 to 2e-4 m/s (read every 2 µs on the continuous
/// extension of a DOP853 run at 1e-13): the approach is not smooth.
#[test]
fn two_dimensional_slip_turns_as_it_vanishes() {
    let s: RollingDisk = scene(&[]);
    let init = init::resolve(
        &s,
        &pairs(&[
            ("x_dot", "2"),
            ("y_dot", "0.5"),
            ("theta_dot", "0.8"),
            ("psi_dot", "0.5"),
        ]),
        &[],
    )
    .unwrap();
    let model = friction(s, &[("mu", "0.3"), ("normal", "9.81")]).unwrap();
    let mut f = run(Box::new(model), init, 1e-13, 1.0, 0.01);
    let t_r = f.switches[0].t;
    let mut obs = Observation::new(4, 2);
    let (mut at_9e3, mut at_2e4) = (None, None);
    let mut t = 0.15;
    while t < t_r {
        f.observe_at(t, &mut obs).unwrap();
        let (c, sn) = (obs.q[2].cos(), obs.q[2].sin());
        let u = (obs.qd[0] - obs.qd[3] * c, obs.qd[1] - obs.qd[3] * sn);
        let (r, angle) = (u.0.hypot(u.1), u.1.atan2(u.0));
        if r <= 9e-3 && at_9e3.is_none() {
            at_9e3 = Some(angle);
        }
        if r <= 2e-4 && at_2e4.is_none() {
            at_2e4 = Some(angle);
        }
        t += 2e-6;
    }
    let turn = at_2e4.unwrap() - at_9e3.unwrap();
    assert!(
        (turn - 0.2).abs() < 0.03,
        "the slip direction turned by {turn} rad"
    );
}

/// A slipping contact point of the disk in two dimensions (sideways and
/// forward slip while turning): its Jacobian matches differences.
#[test]
fn disk_jacobian_in_two_dimensional_slip() {
    let s: RollingDisk = scene(&[]);
    let mut init = init::resolve(
        &s,
        &pairs(&[
            ("theta", "0.4"),
            ("x_dot", "1.2"),
            ("y_dot", "-0.7"),
            ("theta_dot", "0.9"),
            ("psi_dot", "0.3"),
        ]),
        &[],
    )
    .unwrap();
    let mut f = friction(s, &[("mu", "0.4"), ("normal", "9.81")]).unwrap();
    f.make_consistent(&mut init, false).unwrap();
    let y = f.initial_state(&init).unwrap();
    check_jacobian(&mut f, &y);
}

/// Missing, negative or non-finite `μ`, a missing normal load, a scene
/// without contacts: clear errors naming the option; chattering beyond
/// `max_switch_rate` stops the run with the count.
#[test]
fn bad_input_and_chattering_are_reported() {
    let msg = |r: Result<Friction<Sleigh>, Error>| r.err().expect("refused").to_string();
    let m = msg(friction(scene(&[]), &[]));
    assert!(m.contains("`mu`") && m.contains("required"), "{m}");
    let m = msg(friction(scene(&[]), &[("mu", "-0.1")]));
    assert!(m.contains("`mu`") && m.contains("outside its range"), "{m}");
    let m = msg(friction(scene(&[]), &[("mu", "NaN")]));
    assert!(m.contains("`mu`"), "{m}");
    let m = friction(scene::<RollingDisk>(&[]), &[("mu", "0.3")])
        .err()
        .expect("refused")
        .to_string();
    assert!(m.contains("`normal`") && m.contains("rolling-disk"), "{m}");
    let m = friction(scene::<nonholo_scenes::AppellHamel>(&[]), &[("mu", "0.3")])
        .err()
        .expect("refused")
        .to_string();
    assert!(m.contains("no contacts"), "{m}");
    // μ = 0.265 switches at ≈ 0.47 s and ≈ 1.00 s: two within a second.
    let f = friction_run(0.265, 1e-10, &[("max_switch_rate", "1")]).unwrap();
    let err = f.failure.expect("stopped").to_string();
    assert!(
        err.contains("chattering") && err.contains("2 stick–slip switches"),
        "{err}"
    );
    let f = friction_run(0.265, 1e-10, &[("max_switch_rate", "2")]).unwrap();
    assert!(f.completed() && f.switches.len() == 2);
}
