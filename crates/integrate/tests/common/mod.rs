//! Test problems with closed-form solutions, and small helpers.
#![allow(dead_code)] // each test binary uses a subset

use nonholo_integrate::{Method, OdeSystem, Options, Solution, SystemError, solve};

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

/// Adaptive run that must succeed.
pub fn adaptive(
    method: Method,
    sys: &mut dyn OdeSystem,
    y0: &[f64],
    t_end: f64,
    tol: f64,
) -> Solution {
    let opts = Options {
        rtol: tol,
        atol: tol,
        ..Options::default()
    };
    solve(method, sys, 0.0, y0, t_end, &opts).expect("adaptive run")
}
