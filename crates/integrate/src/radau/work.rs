//! Workspaces of Radau IIA and the pieces of a step around the Newton
//! iteration: the iteration matrices, the error scale, the starting values,
//! the error estimate and the collocation polynomial.

use super::NCOEF;
use super::linalg::{ComplexLu, RealLu};
use super::problem::Problem;
use super::sparse::SparseIteration;
use super::tableau::Tableau;
use crate::explicit::control::all_finite;

/// Workspaces of the full Newton iteration (`RadauNewton::Full`).
pub(super) struct FullNewton {
    /// `∂G/∂Z`, `3n × 3n`, row block `k` = stage equation `k`, column
    /// block `j` = `Z_j`; factored in place.
    pub(super) lu: RealLu,
    /// `J_k`, `J'_k` at the current stage point (`J'_k` empty for explicit
    /// ODEs, where `J' = I`).
    pub(super) jy: Vec<f64>,
    pub(super) jyp: Vec<f64>,
    /// `−G(Z)`, then the correction `ΔZ` (stage-major, length `3n`).
    pub(super) rhs: Vec<f64>,
}

/// Workspaces and the per-run state of the core, allocated once per run.
pub(super) struct Work {
    pub(super) n: usize,
    pub(super) tab: Tableau,
    /// `J = ∂F/∂y`, row-major; with [`Work::sparse`] its values at the
    /// system's listed entries.
    pub(super) jy: Vec<f64>,
    /// `J' = ∂F/∂y'` (empty for explicit ODEs, where `J' = I`), as `jy`.
    pub(super) jyp: Vec<f64>,
    /// `γ/h J' + J`, factored (dense; empty with [`Work::sparse`]).
    pub(super) e1: RealLu,
    /// `(α + iβ)/h J' + J`, factored (dense; empty with [`Work::sparse`]).
    pub(super) e2: ComplexLu,
    /// Both iteration matrices stored sparse, for a system with sparse
    /// Jacobians (simplified Newton only).
    pub(super) sparse: Option<Box<SparseIteration>>,
    /// Transformed stage increments `W = (T⁻¹ ⊗ I) Z`.
    pub(super) w: [Vec<f64>; 3],
    /// Stage increments `Z_i = Y_i − y_n`.
    pub(super) z: [Vec<f64>; 3],
    /// Stage residuals, then the Newton corrections `ΔW`.
    pub(super) dw: [Vec<f64>; 3],
    /// Stage state and derivative.
    pub(super) ys: Vec<f64>,
    pub(super) yps: Vec<f64>,
    /// The three stage derivatives `Y'_k` of a simplified Newton iteration.
    pub(super) yp_stage: [Vec<f64>; 3],
    /// Error scale of the current step (index-2/3 components divided by `h`, `h²`).
    pub(super) scal: Vec<f64>,
    /// Error estimate and its right-hand side.
    pub(super) err: Vec<f64>,
    pub(super) err_rhs: Vec<f64>,
    /// Collocation polynomial of the last converged step (nested form).
    pub(super) coef: Vec<f64>,
    /// `y'` at the end of the last converged step: `h⁻¹ (A⁻¹ Z)_3`.
    pub(super) yp_new: Vec<f64>,
    /// `FACCON`: `θ/(1 − θ)` of the last iteration (kept across steps).
    pub(super) faccon: f64,
    /// `θ`, the contraction rate of the last Newton iteration.
    pub(super) theta: f64,
    /// Full Newton workspaces (`None` in simplified mode).
    pub(super) full: Option<FullNewton>,
}

impl Work {
    /// Workspaces for dimension `n`; `sparse` with the sparse iteration
    /// matrices and the number of entries of `J` and of `J'`.
    pub(super) fn new(
        n: usize,
        identity_jp: bool,
        full: bool,
        sparse: Option<(SparseIteration, usize, usize)>,
    ) -> Self {
        let v = || vec![0.0; n];
        let (jy, jyp, dense) = match &sparse {
            Some((_, jy, jyp)) => (*jy, *jyp, 0),
            None => (n * n, if identity_jp { 0 } else { n * n }, n),
        };
        Work {
            n,
            tab: Tableau::new(),
            jy: vec![0.0; jy],
            jyp: vec![0.0; jyp],
            e1: RealLu::new(dense),
            e2: ComplexLu::new(dense),
            sparse: sparse.map(|(s, _, _)| Box::new(s)),
            w: [v(), v(), v()],
            z: [v(), v(), v()],
            dw: [v(), v(), v()],
            ys: v(),
            yps: v(),
            yp_stage: [v(), v(), v()],
            scal: v(),
            err: v(),
            err_rhs: v(),
            coef: vec![0.0; NCOEF * n],
            yp_new: v(),
            faccon: 1.0,
            theta: 0.0,
            full: full.then(|| FullNewton {
                lu: RealLu::new(3 * n),
                jy: vec![0.0; n * n],
                jyp: if identity_jp {
                    Vec::new()
                } else {
                    vec![0.0; n * n]
                },
                rhs: vec![0.0; 3 * n],
            }),
        }
    }

    /// Forms `γ/h J' + J` and `(α + iβ)/h J' + J` and factors them; in full
    /// Newton mode only the first, which the error estimate needs.
    pub(super) fn factor(&mut self, h: f64) -> Result<(), usize> {
        let n = self.n;
        // `J' = I` (an explicit ODE) exactly when no `J'` is stored.
        let identity_jp = self.jyp.is_empty();
        let (g, a, b) = (self.tab.gamma / h, self.tab.alpha / h, self.tab.beta / h);
        let complex = self.full.is_none();
        if let Some(sp) = &mut self.sparse {
            return sp.factor(&self.jy, &self.jyp, g, complex.then_some((a, b)));
        }
        self.e1.a.copy_from_slice(&self.jy);
        if identity_jp {
            for i in 0..n {
                self.e1.a[i * n + i] += g;
            }
        } else {
            for (k, &m) in self.jyp.iter().enumerate() {
                self.e1.a[k] += g * m;
            }
        }
        self.e1.factor()?;
        if !complex {
            return Ok(());
        }
        self.e2.re.copy_from_slice(&self.jy);
        if identity_jp {
            self.e2.im.fill(0.0);
            for i in 0..n {
                self.e2.re[i * n + i] += a;
                self.e2.im[i * n + i] = b;
            }
        } else {
            for (k, &m) in self.jyp.iter().enumerate() {
                self.e2.re[k] += a * m;
                self.e2.im[k] = b * m;
            }
        }
        self.e2.factor()
    }

    /// `err ← (γ/h J' + J)⁻¹ err`.
    fn solve_real_err(&mut self) {
        match &mut self.sparse {
            Some(sp) => sp.solve_real(&mut self.err),
            None => self.e1.solve(&mut self.err),
        }
    }

    /// The two linear systems of a simplified Newton iteration: `d0` with
    /// the real matrix, `d1 + i d2` with the complex one, in place. `false`
    /// when finite right-hand sides gave a non-finite solution: a
    /// numerically singular matrix (faer's sparse LU refuses only a
    /// structurally singular one; a zero pivot becomes an infinite
    /// reciprocal), reported as singular as the dense LU reports it.
    pub(super) fn solve_stages(&mut self) -> bool {
        let finite = |dw: &[Vec<f64>; 3]| dw.iter().all(|d| all_finite(d));
        let rhs_finite = finite(&self.dw);
        let [d0, d1, d2] = &mut self.dw;
        match &mut self.sparse {
            Some(sp) => {
                sp.solve_real(d0);
                sp.solve_complex(d1, d2);
            }
            None => {
                self.e1.solve(d0);
                self.e2.solve(d1, d2);
            }
        }
        !rhs_finite || finite(&self.dw)
    }

    /// Error scale of a step of size `h` from the base scale `sk`.
    pub(super) fn set_scale(&mut self, sk: &[f64], index: &[u8], h: f64) {
        for ((s, &k), &ix) in self.scal.iter_mut().zip(sk).zip(index) {
            *s = match ix {
                1 => k,
                2 => k / h,
                _ => k / (h * h),
            };
        }
    }

    /// Starting values of the Newton iteration: zero, or the collocation
    /// polynomial of the previous step (of size `hold`) extrapolated.
    pub(super) fn start(&mut self, h: f64, hold: Option<f64>) {
        let n = self.n;
        let Some(hold) = hold else {
            for k in 0..3 {
                self.w[k].fill(0.0);
                self.z[k].fill(0.0);
            }
            return;
        };
        let ti = self.tab.ti;
        let s = self.tab.c.map(|c| 1.0 + c * h / hold);
        for i in 0..n {
            let (b, c, d) = (self.coef[n + i], self.coef[2 * n + i], self.coef[3 * n + i]);
            // p(s) − p(1) = (s − 1)(b − s(c + s d)) in the nested form.
            let z: [f64; 3] = s.map(|s| (s - 1.0) * (b - s * (c + s * d)));
            for k in 0..3 {
                self.z[k][i] = z[k];
                self.w[k][i] = ti[k][0] * z[0] + ti[k][1] * z[1] + ti[k][2] * z[2];
            }
        }
    }

    /// Scaled RMS norm of `v`.
    pub(super) fn norm(&self, v: &[f64]) -> f64 {
        let s: f64 = v
            .iter()
            .zip(&self.scal)
            .map(|(x, s)| (x / s) * (x / s))
            .sum();
        (s / self.n as f64).sqrt()
    }

    /// The error estimate of the converged step (see the module documentation):
    /// `err = (γ/h J' + J)⁻¹ (J' (y'_n + h⁻¹ Σ dd_i Z_i) − F(t_n, y_n, y'_n))`,
    /// with `res = F(t_n, y_n, y'_n)`; when `second` and the first estimate
    /// is `>= 1`, once more with `F(t_n, y_n + err, y'_n)` in place of `res`.
    pub(super) fn estimate<P: Problem>(
        &mut self,
        p: &mut P,
        t: f64,
        y: &[f64],
        yp: &[f64],
        res: &[f64],
        h: f64,
        second: bool,
    ) -> f64 {
        let n = self.n;
        let dd = self.tab.dd;
        // err_rhs = J'(y'_n + h⁻¹ Σ dd_i Z_i), err = err_rhs − F(t_n, y_n, y'_n).
        for i in 0..n {
            let s = dd[0] * self.z[0][i] + dd[1] * self.z[1][i] + dd[2] * self.z[2][i];
            self.err[i] = yp[i] + s / h;
        }
        if P::IDENTITY_JP {
            self.err_rhs.copy_from_slice(&self.err);
        } else if let Some(sp) = &self.sparse {
            sp.jyp_mul(&self.jyp, &self.err, &mut self.err_rhs);
        } else {
            for i in 0..n {
                let row = &self.jyp[i * n..(i + 1) * n];
                self.err_rhs[i] = row.iter().zip(&self.err).map(|(a, b)| a * b).sum();
            }
        }
        for i in 0..n {
            self.err[i] = self.err_rhs[i] - res[i];
        }
        self.solve_real_err();
        let e = self.norm(&self.err).max(1e-10);
        if !(e >= 1.0 && second) {
            return e;
        }
        for i in 0..n {
            self.ys[i] = y[i] + self.err[i];
        }
        if p.residual(t, &self.ys, yp, &mut self.err).is_err() {
            return e;
        }
        for i in 0..n {
            self.err[i] = self.err_rhs[i] - self.err[i];
        }
        self.solve_real_err();
        let e2 = self.norm(&self.err).max(1e-10);
        if e2.is_finite() { e2 } else { e }
    }

    /// The collocation polynomial through `y`, `y + Z_1`, `y + Z_2`, `y + Z_3`
    /// in the nested form `a + s(b + (1 − s)(c + s d))` of [`crate::Dense`].
    pub(super) fn polynomial(&mut self, y: &[f64]) {
        let n = self.n;
        let [c1, c2, _] = self.tab.c;
        let (w1, w2) = (c1 * (1.0 - c1), c2 * (1.0 - c2));
        for i in 0..n {
            let (z1, z2, z3) = (self.z[0][i], self.z[1][i], self.z[2][i]);
            let q1 = (z1 - c1 * z3) / w1;
            let q2 = (z2 - c2 * z3) / w2;
            let d = (q2 - q1) / (c2 - c1);
            self.coef[i] = y[i];
            self.coef[n + i] = z3;
            self.coef[2 * n + i] = q1 - c1 * d;
            self.coef[3 * n + i] = d;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dense::eval_nested;
    use crate::radau::NCOEF;

    /// RADAU5's `CONTR5`: the collocation polynomial in Newton form around
    /// the end of the step, `s = (t − t_{n+1})/h`, from the coefficients its
    /// `RADCOR` stores after an accepted step.
    fn contr5(y_new: f64, z: [f64; 3], c: [f64; 3], s: f64) -> f64 {
        let (c1m1, c2m1, c1mc2) = (c[0] - 1.0, c[1] - 1.0, c[0] - c[1]);
        let cont1 = (z[1] - z[2]) / c2m1;
        let ak = (z[0] - z[1]) / c1mc2;
        let acont3 = (ak - z[0] / c[0]) / c[1];
        let cont2 = (ak - cont1) / c1m1;
        let cont3 = cont2 - acont3;
        y_new + s * (cont1 + (s - c2m1) * (cont2 + (s - c1m1) * cont3))
    }

    #[test]
    fn nested_form_is_radau5_collocation_polynomial() {
        let mut w = Work::new(1, true, false, None);
        let c = w.tab.c;
        let y = [0.7];
        w.z = [vec![0.31], vec![-0.42], vec![0.125]];
        w.polynomial(&y);
        let z = [w.z[0][0], w.z[1][0], w.z[2][0]];
        let mut out = [0.0];
        // Through y_n and the stage values, and equal to CONTR5 everywhere
        // (also outside the step, where it extrapolates).
        for (s, want) in [(0.0, y[0]), (c[0], y[0] + z[0]), (c[1], y[0] + z[1])] {
            eval_nested(&w.coef, 1, NCOEF, s, &mut out);
            assert!((out[0] - want).abs() < 1e-15, "s = {s}");
        }
        for k in 0..=30 {
            let s = -0.5 + 0.1 * f64::from(k);
            eval_nested(&w.coef, 1, NCOEF, s, &mut out);
            let r5 = contr5(y[0] + z[2], z, c, s - 1.0);
            let tol = 1e-14 * r5.abs().max(1.0);
            assert!((out[0] - r5).abs() < tol, "s = {s}: {} vs {r5}", out[0]);
        }
        // Newton starting values of a step of size 1.5 h: p(1 + c_i·1.5) − p(1).
        w.start(1.5, Some(1.0));
        for i in 0..3 {
            let s = 1.0 + c[i] * 1.5;
            let want = contr5(y[0] + z[2], z, c, s - 1.0) - (y[0] + z[2]);
            let tol = 1e-14 * want.abs().max(1.0);
            assert!((w.z[i][0] - want).abs() < tol, "{} vs {want}", w.z[i][0]);
            let back: f64 = (0..3).map(|k| w.tab.t[i][k] * w.w[k][0]).sum();
            assert!((back - w.z[i][0]).abs() < tol, "W = T⁻¹ Z");
        }
    }
}
