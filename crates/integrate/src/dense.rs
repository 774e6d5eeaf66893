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
