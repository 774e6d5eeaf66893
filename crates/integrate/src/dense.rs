/// Continuous extension of a run: one polynomial per accepted step.
///
/// Every method writes its step polynomial in the same nested form (Hairer's
/// `CONTD5`/`CONTD8` form), with `s = (t - t_n)/h_n` and `s1 = 1 - s`:
///
/// ```text
/// y(t) = c1 + s (c2 + s1 (c3 + s (c4 + s1 (c5 + ...))))
/// ```
///
/// so that `c1 = y_n` and `c1 + c2 = y_{n+1}`. The factors alternate between
/// `s` and `s1`; `ncoef` coefficient vectors of length `dim` per step.
#[derive(Debug, Clone, PartialEq)]
pub struct Dense {
    dim: usize,
    ncoef: usize,
    /// Step start times `t_n`, increasing.
    t: Vec<f64>,
    /// Step sizes `h_n`.
    h: Vec<f64>,
    /// Coefficients: step `n`, coefficient `k`, component `j` at
    /// `coef[(n * ncoef + k) * dim + j]`.
    coef: Vec<f64>,
}

impl Dense {
    /// An empty extension for states of dimension `dim` and polynomials of `ncoef` coefficients.
    pub fn new(dim: usize, ncoef: usize) -> Self {
        Dense {
            dim,
            ncoef,
            t: Vec::new(),
            h: Vec::new(),
            coef: Vec::new(),
        }
    }

    /// Dimension of the state.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of steps stored.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether no step is stored.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Time span `[t_first, t_last]` covered.
    pub fn span(&self) -> Option<(f64, f64)> {
        let n = self.t.len();
        (n > 0).then(|| (self.t[0], self.t[n - 1] + self.h[n - 1]))
    }

    /// Appends the polynomial of the step `[t, t + h]`; `coef` holds
    /// `ncoef * dim` numbers, coefficient-major.
    pub fn push(&mut self, t: f64, h: f64, coef: &[f64]) {
        debug_assert_eq!(coef.len(), self.ncoef * self.dim);
        self.t.push(t);
        self.h.push(h);
        self.coef.extend_from_slice(coef);
    }

    /// Number of coefficient vectors per step.
    pub fn ncoef(&self) -> usize {
        self.ncoef
    }

    /// Appends the steps of `other` (same `dim` and `ncoef`, starting where
    /// this one ends).
    pub fn append(&mut self, other: &Dense) {
        debug_assert_eq!((self.dim, self.ncoef), (other.dim, other.ncoef));
        self.t.extend_from_slice(&other.t);
        self.h.extend_from_slice(&other.h);
        self.coef.extend_from_slice(&other.coef);
    }

    /// Appends a step `[t, t + h]` whose polynomial interpolates `f` (a
    /// function of time writing `dim` values) at `ncoef` Chebyshev–Lobatto
    /// points of the step, ends included: for states known by another
    /// interpolant (a continuation across a singular set), in the form every
    /// method writes.
    pub fn push_fitted(&mut self, t: f64, h: f64, mut f: impl FnMut(f64, &mut [f64])) {
        let (n, dim) = (self.ncoef, self.dim);
        // Basis b_0 = 1, b_k = b_{k−1}·(s or s1, alternating from s).
        let mut basis = vec![0.0; n * n];
        let mut values = vec![0.0; n * dim];
        for i in 0..n {
            let s = if n == 1 {
                0.0
            } else {
                0.5 * (1.0 - (std::f64::consts::PI * i as f64 / (n - 1) as f64).cos())
            };
            let mut b = 1.0;
            for k in 0..n {
                basis[i * n + k] = b;
                b *= if k % 2 == 0 { s } else { 1.0 - s };
            }
            f(t + s * h, &mut values[i * dim..(i + 1) * dim]);
        }
        // Gaussian elimination with partial pivoting, all components at once.
        for k in 0..n {
            let p = (k..n)
                .max_by(|&a, &b| basis[a * n + k].abs().total_cmp(&basis[b * n + k].abs()))
                .unwrap_or(k);
            if p != k {
                for c in 0..n {
                    basis.swap(k * n + c, p * n + c);
                }
                for c in 0..dim {
                    values.swap(k * dim + c, p * dim + c);
                }
            }
            for r in k + 1..n {
                let l = basis[r * n + k] / basis[k * n + k];
                for c in k..n {
                    basis[r * n + c] -= l * basis[k * n + c];
                }
                for c in 0..dim {
                    values[r * dim + c] -= l * values[k * dim + c];
                }
            }
        }
        for k in (0..n).rev() {
            for c in 0..dim {
                let mut x = values[k * dim + c];
                for j in k + 1..n {
                    x -= basis[k * n + j] * values[j * dim + c];
                }
                values[k * dim + c] = x / basis[k * n + k];
            }
        }
        self.push(t, h, &values);
    }

    /// Evaluates the continuous extension at `t` into `out` (length `dim`).
    /// Returns `false` if `t` lies outside the covered span (beyond a
    /// relative slack of a few ulps), leaving `out` untouched.
    pub fn eval(&self, t: f64, out: &mut [f64]) -> bool {
        let Some((a, b)) = self.span() else {
            return false;
        };
        let slack = 8.0 * f64::EPSILON * a.abs().max(b.abs()).max(1.0);
        if !(t >= a - slack && t <= b + slack) {
            return false;
        }
        // Last step whose start is <= t.
        let n = self.t.partition_point(|&tn| tn <= t).saturating_sub(1);
        self.eval_step(n, t, out);
        true
    }

    /// Evaluates the polynomial of step `n` at `t` (extrapolating if `t` is outside the step).
    fn eval_step(&self, n: usize, t: f64, out: &mut [f64]) {
        let s = (t - self.t[n]) / self.h[n];
        eval_nested(
            &self.coef[n * self.ncoef * self.dim..(n + 1) * self.ncoef * self.dim],
            self.dim,
            self.ncoef,
            s,
            out,
        );
    }
}

/// Evaluates `c1 + s (c2 + s1 (c3 + s (c4 + ...)))` for every component.
pub(crate) fn eval_nested(coef: &[f64], dim: usize, ncoef: usize, s: f64, out: &mut [f64]) {
    let s1 = 1.0 - s;
    for (j, o) in out.iter_mut().enumerate().take(dim) {
        let mut acc = coef[(ncoef - 1) * dim + j];
        for k in (1..ncoef - 1).rev() {
            // `acc` holds the bracket that starts at coefficient k+1; the
            // factor in front of it is s after an even k, s1 after an odd k.
            let factor = if k % 2 == 1 { s1 } else { s };
            acc = coef[k * dim + j] + factor * acc;
        }
        *o = coef[j] + s * acc;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fitted step reproduces a polynomial of degree `ncoef − 1` exactly
    /// and evaluates like any other step.
    #[test]
    fn fitted_steps_interpolate() {
        for ncoef in [4, 5, 8] {
            let mut d = Dense::new(2, ncoef);
            let p = |t: f64| {
                let mut v = 1.0;
                let mut acc = 0.0;
                for k in 0..ncoef {
                    acc += (k as f64 + 1.0) * v;
                    v *= t - 0.3;
                }
                acc
            };
            d.push_fitted(0.25, 0.5, |t, out| {
                out[0] = p(t);
                out[1] = (3.0 * t).sin();
            });
            // The interpolation bound for sin(3t): 3ⁿ/n! · max |Π(t − tᵢ)|
            // over the step, with the nodes tᵢ of push_fitted.
            let nodes: Vec<f64> = (0..ncoef)
                .map(|i| {
                    let c = (std::f64::consts::PI * i as f64 / (ncoef - 1) as f64).cos();
                    0.25 + 0.25 * (1.0 - c)
                })
                .collect();
            let factorial: f64 = (1..=ncoef).map(|k| k as f64).product();
            let omega = (0..=200)
                .map(|i| {
                    let t = 0.25 + 0.0025 * i as f64;
                    nodes.iter().map(|x| (t - x).abs()).product::<f64>()
                })
                .fold(0.0f64, f64::max);
            let bound = 3f64.powi(ncoef as i32) / factorial * omega * (1.0 + 1e-9);
            let mut out = [0.0; 2];
            for i in 0..=10 {
                let t = 0.25 + 0.05 * i as f64;
                assert!(d.eval(t, &mut out));
                assert!((out[0] - p(t)).abs() < 1e-12, "{ncoef}: {t}");
                let err = (out[1] - (3.0 * t).sin()).abs();
                assert!(err <= bound + 1e-15, "{ncoef}: {t}: {err} > {bound}");
            }
        }
    }

    #[test]
    fn nested_form_matches_expanded_polynomial() {
        // c = [1, 2, 3, 4]: 1 + s(2 + s1(3 + s·4)).
        let coef = [1.0, 2.0, 3.0, 4.0];
        for &s in &[0.0, 0.3, 1.0, 1.7] {
            let s1 = 1.0 - s;
            let expect = 1.0 + s * (2.0 + s1 * (3.0 + s * 4.0));
            let mut out = [0.0];
            eval_nested(&coef, 1, 4, s, &mut out);
            assert!((out[0] - expect).abs() < 1e-14);
        }
        // Five coefficients: the last factor is s1.
        let coef = [1.0, 2.0, 3.0, 4.0, 5.0];
        let s = 0.4;
        let s1 = 0.6;
        let expect = 1.0 + s * (2.0 + s1 * (3.0 + s * (4.0 + s1 * 5.0)));
        let mut out = [0.0];
        eval_nested(&coef, 1, 5, s, &mut out);
        assert!((out[0] - expect).abs() < 1e-14);
    }
}
