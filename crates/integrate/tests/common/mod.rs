//! Test problems with closed-form solutions, and small helpers.
#![allow(dead_code)] // each test binary uses a subset

use nonholo_integrate::{Method, OdeSystem, Options, Solution, Stats, SystemError, solve};

/// Harmonic oscillator `y1' = y2, y2' = −y1`, `y(0) = (1, 0)`: `y = (cos t, −sin t)`.
pub struct Oscillator;

impl Oscillator {
    pub fn exact(t: f64) -> [f64; 2] {
        [t.cos(), -t.sin()]
    }
}

impl OdeSystem for Oscillator {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        dy[0] = y[1];
        dy[1] = -y[0];
        Ok(())
    }
}

/// Kepler problem `q'' = −q/|q|³` with eccentricity `e`, semi-major axis 1,
/// period 2π, starting at pericentre: `q(0) = (1 − e, 0)`,
/// `p(0) = (0, sqrt((1 + e)/(1 − e)))`.
pub struct Kepler {
    pub e: f64,
}

impl Kepler {
    pub fn y0(&self) -> [f64; 4] {
        let e = self.e;
        [1.0 - e, 0.0, 0.0, ((1.0 + e) / (1.0 - e)).sqrt()]
    }

    /// Closed form through the eccentric anomaly `E − e sin E = t` (Newton).
    pub fn exact(&self, t: f64) -> [f64; 4] {
        let e = self.e;
        let mut ea = t;
        for _ in 0..50 {
            let d = (ea - e * ea.sin() - t) / (1.0 - e * ea.cos());
            ea -= d;
            if d.abs() < 1e-16 {
                break;
            }
        }
        let (s, c) = ea.sin_cos();
        let b = (1.0 - e * e).sqrt();
        let r = 1.0 - e * c;
        [c - e, b * s, -s / r, b * c / r]
    }

    /// Energy `|p|²/2 − 1/|q|` (exact value −1/2).
    pub fn energy(y: &[f64]) -> f64 {
        0.5 * (y[2] * y[2] + y[3] * y[3]) - 1.0 / (y[0] * y[0] + y[1] * y[1]).sqrt()
    }
}

impl OdeSystem for Kepler {
    fn dim(&self) -> usize {
        4
    }
    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let r2 = y[0] * y[0] + y[1] * y[1];
        let r3 = r2 * r2.sqrt();
        dy[0] = y[2];
        dy[1] = y[3];
        dy[2] = -y[0] / r3;
        dy[3] = -y[1] / r3;
        Ok(())
    }
}

/// Max-norm distance.
pub fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Least-squares slope of `log(err)` against `log(h)`.
pub fn slope(h: &[f64], err: &[f64]) -> f64 {
    let n = h.len() as f64;
    let xs: Vec<f64> = h.iter().map(|v| v.ln()).collect();
    let ys: Vec<f64> = err.iter().map(|v| v.ln()).collect();
    let mx = xs.iter().sum::<f64>() / n;
    let my = ys.iter().sum::<f64>() / n;
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

/// Fixed-step run that must succeed.
pub fn fixed(method: Method, sys: &mut dyn OdeSystem, y0: &[f64], t_end: f64, h: f64) -> Solution {
    let opts = Options {
        fixed_step: Some(h),
        ..Options::default()
    };
    solve(method, sys, 0.0, y0, t_end, &opts).expect("fixed-step run")
}

/// `rtol = atol = tol`, every other option at its default.
pub fn tol_opts(tol: f64) -> Options {
    Options {
        rtol: tol,
        atol: tol,
        ..Options::default()
    }
}

/// Adaptive run that must succeed.
pub fn adaptive(
    method: Method,
    sys: &mut dyn OdeSystem,
    y0: &[f64],
    t_end: f64,
    tol: f64,
) -> Solution {
    solve(method, sys, 0.0, y0, t_end, &tol_opts(tol)).expect("adaptive run")
}

/// Least-squares order of `err(h)` over the step sizes `h = span/n`, `n` in
/// `ns`. Every error must lie in `[1e-12, max_err]`: in the asymptotic
/// regime (below `max_err`) and well above the round-off floor of ~1e-15.
/// Prints the ladder (`--nocapture`).
pub fn measured_order(
    ns: &[usize],
    span: f64,
    max_err: f64,
    mut err: impl FnMut(f64) -> f64,
) -> f64 {
    let hs: Vec<f64> = ns.iter().map(|&n| span / n as f64).collect();
    let es: Vec<f64> = hs.iter().map(|&h| err(h)).collect();
    let es_txt: Vec<String> = es.iter().map(|e| format!("{e:.3e}")).collect();
    eprintln!("h {hs:.3?}\nerr {es_txt:?}");
    for (h, e) in hs.iter().zip(&es) {
        assert!(
            *e < max_err && *e > 1e-12,
            "h = {h}: error {e:e} is outside the window [1e-12, {max_err:e}]"
        );
    }
    slope(&hs, &es)
}

/// Largest error of the continuous extension of one fixed step
/// `[0.3, 0.3 + h]` of `method` on the oscillator, started from the exact
/// state, over 39 interior points (`opts` with `fixed_step = h`; its
/// tolerances matter only to Radau5's Newton iteration). Also checks that
/// the extension interpolates the step: `y_n` exactly at `t_n`, `y_{n+1}`
/// within 1e-15 at `t_n + h`.
pub fn local_dense_error(method: Method, h: f64, opts: &Options) -> f64 {
    let t0 = 0.3;
    let opts = Options {
        fixed_step: Some(h),
        ..opts.clone()
    };
    let y0 = Oscillator::exact(t0);
    let s = solve(method, &mut Oscillator, t0, &y0, t0 + h, &opts).unwrap();
    let d = s.dense.unwrap();
    let mut out = [0.0; 2];
    assert!(d.eval(t0, &mut out) && out == y0, "{method:?}");
    assert!(d.eval(t0 + h, &mut out) && dist(&out, &s.y_last) < 1e-15);
    (1..40)
        .map(|i| {
            let t = t0 + h * i as f64 / 40.0;
            assert!(d.eval(t, &mut out));
            dist(&out, &Oscillator::exact(t))
        })
        .fold(0.0, f64::max)
}

/// Checks Radau5's count of `f` evaluations for an ODE run without
/// `Options::h_init` (the counters documented in `src/radau/mod.rs`): 3 per
/// Newton iteration, 1 at every accepted state but the last (`t0`
/// included; a projection by `after_step` adds none), 1 for `HINIT`,
/// `fd_per_jacobian` (the dimension `n` for finite differences, else 0)
/// per Jacobian, and 1 per second filtering of the error estimate — at most
/// one per trial step at the start or after a rejection, so at most
/// `1 + rejected_steps`. Returns the number of second filterings.
pub fn radau_ode_second_filterings(st: &Stats, fd_per_jacobian: usize) -> usize {
    let counted = 3 * st.newton_iterations + st.steps + 1 + fd_per_jacobian * st.jacobian_evals;
    let rest = st.rhs_evals as i64 - counted as i64;
    assert!(
        (0..=1 + st.rejected_steps as i64).contains(&rest),
        "rhs_evals {} = 3·{} Newton iterations + {} steps + 1 + {fd_per_jacobian}·{} \
         Jacobians + {rest} second filterings (at most 1 + {} rejected steps)",
        st.rhs_evals,
        st.newton_iterations,
        st.steps,
        st.jacobian_evals,
        st.rejected_steps
    );
    rest as usize
}
