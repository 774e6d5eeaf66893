//! The Hermite continuous extension of Radau IIA
//! ([`crate::RadauDense::Hermite`]).
//!
//! RADAU5's collocation polynomial has the stage order 3 inside the step,
//! while the step points carry order 5: on smooth solutions its error
//! between the step points is many times the error at them (measured in
//! `docs/integrators.md`). This extension interpolates, on the step
//! `[t_n, t_{n+1}]`, the values and derivatives at `t_{n−1}`, `t_n` and
//! `t_{n+1}`: a quintic, whose interpolation error `O(h⁶)` stays below
//! the step points' own error.
//!
//! Derivative data are safe only where `f` does not amplify the state's
//! error: a component `j` whose row of the Jacobian is stiff gets
//! `f_j(y + δ) − f_j(y) = Σ_k J_jk δ_k` far above the error of the values
//! (in a boundary layer, or off a slow manifold by the tolerance), and the
//! collocation polynomial, which uses no derivative at `t_n`, is the
//! accurate one there. So the quintic is taken component by component where
//! `h_max Σ_k |J_jk| sc_k <= STIFF_ROW · sc_j` (`h_max` the longer of the
//! two steps, `sc` the error scale at the step start, `J` the last Jacobian
//! evaluated, which with Jacobian reuse may be some steps old), and the
//! collocation polynomial elsewhere: at the first step, after a projection,
//! and where no Jacobian has been evaluated (full Newton with a fixed step).
//! On `[0, 1]` the quintic weighs the data at `s = a = −h_{n−1}/h_n`, 0, 1
//! by at most 0.72, 1, 1 (values) and 0.11, 0.50, 0.10 (derivatives, per
//! unit of `s`) for `a <= −1/2`; at `a = −1/8`, which RADAU5's controller
//! allows, the values at `t_{n−1}` and `t_n` would weigh 40 each,
//! amplifying whatever of their error the derivatives do not explain. So a
//! step more than twice the previous one (`a > −1/2`) drops the value at
//! `t_{n−1}` and keeps its derivative: a quartic, interpolation error
//! `O(h⁵)`, whose weights stay at most 0.18 (derivative at `t_{n−1}`), 1, 1
//! (values) and 0.41, 0.12 (derivatives) for every `a` in `(−1/2, 0)`.
//!
//! In the nested form of [`crate::Dense`] with six coefficients,
//! `y = c1 + s (c2 + s1 (c3 + s (c4 + s1 (c5 + s c6))))` with `s1 = 1 − s`,
//! the first four terms are the cubic Hermite interpolant of the values and
//! derivatives at `s = 0` and `s = 1`, and the last two,
//! `s² s1² (c5 + c6 s)`, vanish there with their derivatives: `c5` and `c6`
//! take the value and the derivative at `s = a` (the quartic: `c6 = 0`
//! and `c5` from the derivative alone).

/// Coefficient vectors of the quintic in the nested form.
pub(super) const NCOEF: usize = 6;

/// The largest `h_max Σ_k |J_jk| sc_k / sc_j` at which component `j` takes
/// the quintic. Were every value off by its full scale `sc_k`, the
/// derivatives would be off by up to `Σ_k |J_jk| sc_k`, which the
/// derivative weights (together at most 0.71 for `a <= −1/2`) turn into at
/// most `7 sc_j` at this bound. Chosen by measurement: on `visc` in its
/// adapted form (`k = 1e4 … 1e8`) a bound of 1 sent a third of the smooth
/// rows' samples back to the collocation polynomial and kept a third of the
/// gain, 10 kept all of it; the stiff rows (`h k >= 1e2`) and Van der Pol's
/// at `ε = 1e-6` lie far above either.
pub(super) const STIFF_ROW: f64 = 10.0;

/// The smallest `h_{n−1}/h_n` at which the quintic is taken; below it the
/// quartic (see the module documentation).
pub(super) const MIN_STEP_RATIO: f64 = 0.5;

/// Coefficients 5 and 6 of the nested form: with `c1 … c4` the cubic
/// Hermite interpolant on `[0, 1]`, the quintic that also takes the value
/// `ya` and the derivative `da` (per unit of `s`) at `s = a < 0`.
pub(super) fn outer(c: [f64; 4], a: f64, ya: f64, da: f64) -> (f64, f64) {
    let [c1, c2, c3, c4] = c;
    let a1 = 1.0 - a;
    // The cubic H(s) = c1 + c2 s + c3 s(1 − s) + c4 s²(1 − s) and its slope.
    let h = c1 + a * (c2 + a1 * (c3 + a * c4));
    let dh = c2 + c3 * (1.0 - 2.0 * a) + c4 * a * (2.0 - 3.0 * a);
    // B(s) = s²(1 − s)² and its slope.
    let b = a * a * a1 * a1;
    let db = 2.0 * a * a1 * (1.0 - 2.0 * a);
    // y = H + B (c5 + c6 s): L = c5 + c6 a from the value, c6 from the slope.
    let l = (ya - h) / b;
    let c6 = (da - dh - db * l) / b;
    (l - c6 * a, c6)
}

/// Coefficient 5 of the nested form (6 is zero): with `c1 … c4` the cubic
/// Hermite interpolant on `[0, 1]`, the quartic that also takes the
/// derivative `da` (per unit of `s`) at `s = a < 0`.
pub(super) fn outer_slope(c: [f64; 4], a: f64, da: f64) -> f64 {
    let [_, c2, c3, c4] = c;
    let dh = c2 + c3 * (1.0 - 2.0 * a) + c4 * a * (2.0 - 3.0 * a);
    (da - dh) / (2.0 * a * (1.0 - a) * (1.0 - 2.0 * a))
}

/// The cubic Hermite interpolant on `[0, 1]` in nested form: values `y0`,
/// `y1`, derivatives (per unit of `s`) `d0`, `d1`.
pub(super) fn cubic(y0: f64, y1: f64, d0: f64, d1: f64) -> [f64; 4] {
    let c2 = y1 - y0;
    let c3 = d0 - c2;
    [y0, c2, c3, c2 - c3 - d1]
}

/// What the extension keeps between accepted steps.
pub(super) struct Hermite {
    /// Start `t_{n−1}` of the previous accepted step, its state and
    /// derivative; `None` at the first step and after a projection.
    prev: Option<f64>,
    y_prev: Vec<f64>,
    yp_prev: Vec<f64>,
    /// The step polynomial: six coefficient vectors.
    pub(super) coef: Vec<f64>,
    /// `Σ_k |J_jk| sc_k` per row.
    row: Vec<f64>,
    /// Components that took the quintic or the quartic, over the run (for tests).
    pub(super) taken: usize,
}

/// One accepted step as the extension sees it.
pub(super) struct Step<'a> {
    pub t: f64,
    pub h: f64,
    /// `y_n` and `y'_n` at the step start.
    pub y: &'a [f64],
    pub yp: &'a [f64],
    /// `y_{n+1} − y_n` and `y'_{n+1}` (the collocation polynomial's end).
    pub z3: &'a [f64],
    pub yp_end: &'a [f64],
    /// The collocation polynomial, four coefficient vectors.
    pub collocation: &'a [f64],
    /// `J = ∂F/∂y = −∂f/∂y`, row-major; `None` if not evaluated.
    pub jy: Option<&'a [f64]>,
    /// Error scale at the step start.
    pub sc: &'a [f64],
}

impl Hermite {
    pub(super) fn new(n: usize) -> Self {
        Hermite {
            prev: None,
            y_prev: vec![0.0; n],
            yp_prev: vec![0.0; n],
            coef: vec![0.0; 6 * n],
            row: vec![0.0; n],
            taken: 0,
        }
    }

    /// Forgets the previous step: the next one takes the collocation polynomial.
    pub(super) fn reset(&mut self) {
        self.prev = None;
    }

    /// Writes the polynomial of the step `s` into [`Hermite::coef`] and
    /// keeps its start for the next one.
    pub(super) fn step(&mut self, s: &Step) {
        let n = self.y_prev.len();
        let (head, tail) = self.coef.split_at_mut(4 * n);
        head.copy_from_slice(s.collocation);
        tail.fill(0.0);
        let h_prev = self.prev.map(|t_prev| s.t - t_prev);
        if let (Some(h_prev), Some(jy)) = (h_prev, s.jy) {
            let quintic = h_prev >= MIN_STEP_RATIO * s.h;
            let h_max = s.h.max(h_prev);
            for (j, r) in self.row.iter_mut().enumerate() {
                let line = &jy[j * n..(j + 1) * n];
                *r = line.iter().zip(s.sc).map(|(v, sc)| v.abs() * sc).sum();
            }
            let a = -h_prev / s.h;
            for j in 0..n {
                // False also for a NaN row or scale.
                let smooth = h_max * self.row[j] <= STIFF_ROW * s.sc[j];
                if !smooth {
                    continue;
                }
                let c = cubic(s.y[j], s.y[j] + s.z3[j], s.h * s.yp[j], s.h * s.yp_end[j]);
                let (c5, c6) = if quintic {
                    outer(c, a, self.y_prev[j], s.h * self.yp_prev[j])
                } else {
                    (outer_slope(c, a, s.h * self.yp_prev[j]), 0.0)
                };
                if !(c5.is_finite() && c6.is_finite()) {
                    continue;
                }
                for (k, ck) in c.into_iter().chain([c5, c6]).enumerate() {
                    self.coef[k * n + j] = ck;
                }
                self.taken += 1;
            }
        }
        self.prev = Some(s.t);
        self.y_prev.copy_from_slice(s.y);
        self.yp_prev.copy_from_slice(s.yp);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dense::eval_nested;

    fn nested(c: &[f64; 6], s: f64) -> f64 {
        let mut out = [0.0];
        eval_nested(c, 1, 6, s, &mut out);
        out[0]
    }

    /// The nested coefficients reproduce every quintic from its values and
    /// slopes at `a`, 0 and 1, for steps growing and shrinking 8-fold.
    #[test]
    fn quintic_is_reproduced() {
        let p = |s: f64| {
            0.3 - 1.1 * s + 0.7 * s * s + 2.0 * s.powi(3) - 1.3 * s.powi(4) + 0.9 * s.powi(5)
        };
        let dp = |s: f64| -1.1 + 1.4 * s + 6.0 * s * s - 5.2 * s.powi(3) + 4.5 * s.powi(4);
        for a in [-8.0, -1.0, -0.125] {
            let c4 = cubic(p(0.0), p(1.0), dp(0.0), dp(1.0));
            let (c5, c6) = outer(c4, a, p(a), dp(a));
            let c = [c4[0], c4[1], c4[2], c4[3], c5, c6];
            for k in 0..=20 {
                let s = a + (1.0 - a) * k as f64 / 20.0;
                let scale = 1.0 + p(s).abs();
                assert!(
                    (nested(&c, s) - p(s)).abs() <= 1e-12 * scale * (1.0 + a * a).powi(3),
                    "a = {a}, s = {s}: {} against {}",
                    nested(&c, s),
                    p(s)
                );
            }
        }
    }

    /// The quartic reproduces every quartic from its slope at `a` and its
    /// values and slopes at 0 and 1.
    #[test]
    fn quartic_is_reproduced() {
        let p = |s: f64| 0.3 - 1.1 * s + 0.7 * s * s + 2.0 * s.powi(3) - 1.3 * s.powi(4);
        let dp = |s: f64| -1.1 + 1.4 * s + 6.0 * s * s - 5.2 * s.powi(3);
        for a in [-0.49, -0.125, -0.01] {
            let c4 = cubic(p(0.0), p(1.0), dp(0.0), dp(1.0));
            let c5 = outer_slope(c4, a, dp(a));
            let c = [c4[0], c4[1], c4[2], c4[3], c5, 0.0];
            for k in 0..=20 {
                let s = a + (1.0 - a) * k as f64 / 20.0;
                assert!((nested(&c, s) - p(s)).abs() <= 1e-12, "a = {a}, s = {s}");
            }
        }
    }

    /// A stiff row keeps the collocation polynomial; the first step too.
    #[test]
    fn stiff_rows_and_first_step_keep_collocation() {
        let n = 2;
        let mut e = Hermite::new(n);
        let collocation: Vec<f64> = (0..4 * n).map(|k| k as f64 * 0.1).collect();
        // J = [[0, 1], [−1e6, −1e6]], sc = 1e-6: row 0 is 1e-6, row 1 2e0.
        let jy = [0.0, 1.0, -1e6, -1e6];
        let step = |t: f64| Step {
            t,
            h: 0.1,
            y: &[1.0, 2.0],
            yp: &[0.5, 0.5],
            z3: &[0.1, 0.1],
            yp_end: &[0.5, 0.5],
            collocation: &collocation,
            jy: Some(&jy),
            sc: &[1e-6, 1e-6],
        };
        e.step(&step(0.0));
        assert_eq!(&e.coef[..4 * n], &collocation[..]);
        assert!(e.coef[4 * n..].iter().all(|&c| c == 0.0));
        e.step(&step(0.1));
        assert_eq!(e.taken, 1);
        // Component 1 (stiff row): the collocation polynomial, padded.
        for k in 0..4 {
            assert_eq!(e.coef[k * n + 1], collocation[k * n + 1]);
        }
        assert_eq!((e.coef[4 * n + 1], e.coef[5 * n + 1]), (0.0, 0.0));
        // Component 0: the cubic Hermite part.
        let c = cubic(1.0, 1.1, 0.05, 0.05);
        for k in 0..4 {
            assert_eq!(e.coef[k * n], c[k]);
        }
        // A step of 0.1 after one of 0.01 (more than twofold growth): the
        // quartic, which has no c6, in the smooth row.
        e.step(&step(0.11));
        assert_eq!(e.taken, 2);
        assert_eq!(e.coef[5 * n], 0.0);
        assert_eq!(e.coef[4 * n], outer_slope(c, -(0.11 - 0.1) / 0.1, 0.05));
    }
}
