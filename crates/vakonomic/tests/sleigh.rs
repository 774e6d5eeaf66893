//! Formulation C on the sleigh against the spec's reduced equations, and on
//! Appell–Hamel against B's closed form.

use nonholo_core::integrate::{Method, OdeSystem, Options, SystemError, solve};
use nonholo_core::{Params, RunConfig, Scene, init, simulate};
use nonholo_scenes::{AppellHamel, Sleigh};
use nonholo_vakonomic::{OPTIONS, Vakonomic};
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

fn vakonomic<S: Scene>(s: S) -> Vakonomic<S> {
    Vakonomic::new(s, Params::defaults(OPTIONS)).unwrap()
}

/// The spec's reduced vakonomic sleigh, in (u, ω, μ) with μ = λ + m a ω:
/// u̇ = μω/m + g sin α cos φ, ω̇ = −(μu/m + [com] g a sin α sin φ)/J,
/// μ̇ = −m u ω − m g sin α sin φ.
struct Reduced {
    m: f64,
    j: f64,
    a: f64,
    g: f64,
    alpha: f64,
    com: f64,
}

impl Reduced {
    fn of(s: &Sleigh, potential: &str) -> Self {
        Reduced {
            m: s.m,
            j: s.j,
            a: s.a,
            g: s.g,
            alpha: s.alpha,
            com: if potential == "com" { 1.0 } else { 0.0 },
        }
    }

    /// (u̇, ω̇, μ̇) at (φ, u, ω, μ).
    fn rates(&self, phi: f64, u: f64, w: f64, mu: f64) -> (f64, f64, f64) {
        let gs = self.g * self.alpha.sin();
        let ud = mu * w / self.m + gs * phi.cos();
        let wd = -(mu * u / self.m + self.com * gs * self.a * phi.sin()) / self.j;
        let mud = -self.m * u * w - self.m * gs * phi.sin();
        (ud, wd, mud)
    }
}

/// State (x, y, φ, u, ω, μ).
impl OdeSystem for Reduced {
    fn dim(&self) -> usize {
        6
    }
    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let (phi, u, w, mu) = (y[2], y[3], y[4], y[5]);
        let (ud, wd, mud) = self.rates(phi, u, w, mu);
        dy.copy_from_slice(&[u * phi.cos(), u * phi.sin(), w, ud, wd, mud]);
        Ok(())
    }
}

/// C's AD-derived (q̈, λ̇) equal the reduced equations at random states,
/// both potentials, to 1e-12.
#[test]
fn accelerations_match_reduced_equations() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    for potential in ["paper", "com"] {
        for _ in 0..300 {
            let a: f64 = rng.random_range(-1.0..1.0);
            let j = a * a + rng.random_range(0.1..2.0);
            let m: f64 = rng.random_range(0.5..3.0);
            let alpha: f64 = rng.random_range(0.0..1.4);
            let s: Sleigh = scene(&[
                ("a", &a.to_string()),
                ("J", &j.to_string()),
                ("m", &m.to_string()),
                ("alpha", &alpha.to_string()),
                ("potential", potential),
            ]);
            let red = Reduced::of(&s, potential);
            let mut c = vakonomic(s);
            let phi: f64 = rng.random_range(-4.0..4.0);
            let (u, w, lambda): (f64, f64, f64) = (
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
            );
            let y = [
                rng.random_range(-5.0..5.0),
                rng.random_range(-5.0..5.0),
                phi,
                u * phi.cos(),
                u * phi.sin(),
                w,
                lambda,
            ];
            let mut dy = [0.0; 7];
            c.rhs(0.0, &y, &mut dy).unwrap();
            let mu = lambda + m * a * w;
            let (ud, wd, mud) = red.rates(phi, u, w, mu);
            let expect = [
                ud * phi.cos() - u * w * phi.sin(),
                ud * phi.sin() + u * w * phi.cos(),
                wd,
                mud - m * a * wd,
            ];
            for (i, e) in expect.iter().enumerate() {
                let got = dy[3 + i];
                assert!(
                    (got - e).abs() < 1e-12 * (1.0 + e.abs()),
                    "{potential}: component {i}: {got} vs {e}"
                );
            }
        }
    }
}

/// C's trajectory over [0, 20] against an independent DOP853 integration of
/// the reduced equations (both at tolerance 1e-13), for several λ0 and both
/// potentials. The vakonomic sleigh reverses repeatedly but C is regular
/// there; positions agree to 1e-9.
#[test]
fn trajectory_matches_reduced_integration() {
    for potential in ["paper", "com"] {
        for lambda0 in [0.0, 0.8, -1.5] {
            let s: Sleigh = scene(&[("a", "0.4"), ("alpha", "0.3"), ("potential", potential)]);
            let red = Reduced::of(&s, potential);
            let grid: Vec<f64> = (0..=200).map(|i| i as f64 * 0.1).collect();
            let initial = init::resolve(
                &s,
                &pairs(&[
                    ("phi", "0.2"),
                    ("u", "2"),
                    ("omega", "0.7"),
                    ("lambda", &lambda0.to_string()),
                ]),
                &nonholo_vakonomic::lambda_names(1),
            )
            .unwrap();
            let opts = Options {
                rtol: 1e-13,
                atol: 1e-13,
                output: grid.clone(),
                ..Options::default()
            };
            let run = simulate(
                Box::new(vakonomic(s.clone())),
                initial,
                RunConfig {
                    method: Method::Dop853,
                    options: opts.clone(),
                    t_end: 20.0,
                    project_init: false,
                },
            )
            .unwrap();
            assert!(run.completed(), "{:?}", run.failure);
            let mu0 = lambda0 + s.m * s.a * 0.7;
            let y0 = [0.0, 0.0, 0.2, 2.0, 0.7, mu0];
            let mut red = red;
            let reference = solve(Method::Dop853, &mut red, 0.0, &y0, 20.0, &opts).unwrap();
            let (mut err_q, mut err_lambda) = (0.0f64, 0.0f64);
            let mut reversals = 0;
            let mut prev_u = 2.0;
            for (i, o) in run.samples.iter().enumerate() {
                let r = reference.row(i);
                for k in 0..3 {
                    err_q = err_q.max((o.q[k] - r[k]).abs());
                }
                let lambda_ref = r[5] - s.m * s.a * r[4];
                err_lambda = err_lambda
                    .max((o.multipliers[0] - lambda_ref).abs() / (1.0 + lambda_ref.abs()));
                let u = o.qd[0] * o.q[2].cos() + o.qd[1] * o.q[2].sin();
                if u * prev_u < 0.0 {
                    reversals += 1;
                }
                prev_u = u;
            }
            eprintln!(
                "{potential}, λ0 = {lambda0}: max deviation q {err_q:e}, λ (relative) \
                 {err_lambda:e}, {reversals} reversals, energy drift {:e}",
                run.diagnostics.energy_drift_max
            );
            // Measured over 20 s (~107 reversals of u) at tolerance 1e-13,
            // worst over potentials and λ0: q 6.3e-11, λ 4.3e-12 relative to
            // 1 + |λ|. Bounds about 8× and 12× above.
            assert!(err_q < 5e-10, "{potential}, λ0 = {lambda0}: q {err_q:e}");
            assert!(
                err_lambda < 5e-11,
                "{potential}, λ0 = {lambda0}: λ {err_lambda:e}"
            );
            let energy_scale = run
                .samples
                .iter()
                .map(|o| 0.5 * (o.qd[0].powi(2) + o.qd[1].powi(2)))
                .fold(1.0f64, f64::max);
            eprintln!(
                "   energy scale {energy_scale:e}, steps {}",
                run.solution.stats.steps
            );
            // Energy is conserved by C for this L and g (homogeneous constraint);
            // what remains is round-off, ~1e-15 of the energy scale per step.
            assert!(
                run.diagnostics.energy_drift_max
                    < 1e-15 * energy_scale * run.solution.stats.steps as f64
            );
            // ġ = 0 holds exactly at acceleration level, so g drifts by round-off
            // only: ~1e-15 of the speed scale per step.
            let speed = (2.0 * energy_scale).sqrt();
            let bound = 1e-15 * speed * run.solution.stats.steps as f64;
            eprintln!(
                "   residual {:e} (bound {bound:e})",
                run.diagnostics.constraint_residual_max
            );
            assert!(run.diagnostics.constraint_residual_max < bound);
        }
    }
}

/// The Taylor coefficients along C's motion: ÿ and y⃛ from dual passes
/// equal central differences of f and of ÿ along the motion (DOP853 at 1e-13
/// gives the states at t ± h).
#[test]
fn taylor_coefficients_match_differences() {
    let s: Sleigh = scene(&[("a", "0.4"), ("potential", "com")]);
    let mut c = vakonomic(s);
    let y = [
        0.1,
        0.2,
        0.3,
        1.9 * 0.3f64.cos(),
        1.9 * 0.3f64.sin(),
        0.6,
        0.4,
    ];
    let (mut yd, mut ydd, mut yddd) = ([0.0; 7], [0.0; 7], [0.0; 7]);
    c.taylor(0.0, &y, &mut yd, &mut ydd, &mut yddd).unwrap();
    let h = 1e-5;
    let (mut fp, mut fm) = ([0.0; 7], [0.0; 7]);
    let yp: Vec<f64> = (0..7).map(|i| y[i] + h * yd[i]).collect();
    let ym: Vec<f64> = (0..7).map(|i| y[i] - h * yd[i]).collect();
    c.rhs(0.0, &yp, &mut fp).unwrap();
    c.rhs(0.0, &ym, &mut fm).unwrap();
    for i in 0..7 {
        let fd = (fp[i] - fm[i]) / (2.0 * h);
        assert!(
            (ydd[i] - fd).abs() < 1e-8 * (1.0 + fd.abs()),
            "ÿ[{i}] {} vs {fd}",
            ydd[i]
        );
    }
    // y⃛ = d/dt ÿ along the motion: one-sided second-order difference of ÿ at
    // the states reached after h and 2h (DOP853 at 1e-13):
    // (−3ÿ(0) + 4ÿ(h) − ÿ(2h))/(2h), error ~h² y⁽⁵⁾/3.
    let h = 1e-4;
    let opts = Options {
        rtol: 1e-13,
        atol: 1e-13,
        output: vec![h, 2.0 * h],
        ..Options::default()
    };
    let later = solve(
        Method::Dop853,
        &mut vakonomic(scene::<Sleigh>(&[("a", "0.4"), ("potential", "com")])),
        0.0,
        &y,
        2.0 * h,
        &opts,
    )
    .unwrap();
    let mut second = [[0.0; 7]; 2];
    for k in 0..2 {
        let (mut a, mut b) = ([0.0; 7], [0.0; 7]);
        c.taylor(0.0, later.row(k), &mut a, &mut second[k], &mut b)
            .unwrap();
    }
    for i in 0..7 {
        let fd = (-3.0 * ydd[i] + 4.0 * second[0][i] - second[1][i]) / (2.0 * h);
        assert!(
            (yddd[i] - fd).abs() < 1e-6 * (1.0 + fd.abs()),
            "y⃛[{i}] {} vs {fd}",
            yddd[i]
        );
    }
}

/// Appell–Hamel: C gives B's motion (straight line, ρ̇ = c g/(1 + c²)) for
/// any λ0 while regular (spec), through H_λ of the nonlinear constraint.
#[test]
fn appell_hamel_any_lambda0_gives_b() {
    for lambda0 in ["0", "0.7", "-0.3"] {
        let s: AppellHamel = scene(&[("c", "0.5")]);
        let initial = init::resolve(
            &s,
            &pairs(&[("rho", "2"), ("beta", "0.3"), ("lambda", lambda0)]),
            &nonholo_vakonomic::lambda_names(1),
        )
        .unwrap();
        let grid: Vec<f64> = (0..=50).map(|i| i as f64 * 0.1).collect();
        let run = simulate(
            Box::new(vakonomic(s.clone())),
            initial,
            RunConfig {
                method: Method::Dop853,
                options: Options {
                    rtol: 1e-12,
                    atol: 1e-12,
                    output: grid,
                    ..Options::default()
                },
                t_end: 5.0,
                project_init: false,
            },
        )
        .unwrap();
        assert!(run.completed());
        let (mut q, mut qd) = ([0.0; 3], [0.0; 3]);
        let mut err = 0.0f64;
        for (t, o) in run.solution.t.iter().zip(&run.samples) {
            s.closed_form(&run.initial.q, &run.initial.qd, *t, &mut q, &mut qd)
                .unwrap();
            for i in 0..3 {
                err = err.max((o.q[i] - q[i]).abs());
            }
        }
        eprintln!("closed form, λ0 = {lambda0}: q error {err:e}");
        // Measured 1.1e-13 (worst λ0) over 5 s at tolerance 1e-12; bound 9× above.
        assert!(err < 1e-12, "λ0 = {lambda0}: q error {err:e}");
    }
}
