//! The Newton iteration on the stage equations of a Radau IIA step,
//! simplified (RADAU5) or full, and RADAU5's convergence monitor.

use super::problem::{Problem, UROUND};
use super::tableau::Tableau;
use super::work::{FullNewton, Work};
use crate::explicit::control::all_finite;
use crate::{Stats, SystemError};

/// Settings of the Newton iteration.
#[derive(Debug, Clone, Copy)]
pub(super) struct NewtonParams {
    /// `NIT`.
    pub(super) nit: usize,
    /// `FNEWT`.
    pub(super) fnewt: f64,
    /// `THET`.
    pub(super) thet: f64,
    /// Fixed step: no step-size reduction is possible, so the prediction
    /// "will not converge in time" (`DYTH >= 1`) does not stop the iteration.
    pub(super) fixed: bool,
}

/// Outcome of the Newton iteration of a trial step.
pub(super) enum Newton {
    /// Converged after this many iterations.
    Converged(usize),
    /// Converging, but predicted not to reach `FNEWT` within `NIT`
    /// iterations: RADAU5 retries with `h` times this factor.
    Slow(f64),
    /// Diverged (`θ >= 0.99`) or not converged after `NIT` iterations.
    Failed,
    /// `F` could not be evaluated at a stage.
    Stage(SystemError),
    /// A residual or a Newton correction is not finite (full Newton: also
    /// a stage Jacobian).
    NonFinite,
    /// The matrix of the iteration is singular: full Newton's `3n × 3n`
    /// one, or (simplified) an iteration matrix whose solve turned finite
    /// right-hand sides into a non-finite solution.
    Singular,
}

/// RADAU5's convergence monitor of one Newton iteration.
struct Monitor {
    /// Corrections computed so far.
    newt: usize,
    /// Norm of the previous correction.
    dynold: f64,
    /// Previous quotient of successive norms.
    thqold: f64,
}

impl FullNewton {
    /// Row block `k` of `∂G/∂Z` from `J_k`, `J'_k` (in `jy`, `jyp`):
    /// `[h⁻¹ (A⁻¹)_k1 J'_k, h⁻¹ (A⁻¹)_k2 J'_k, h⁻¹ (A⁻¹)_k3 J'_k]` plus `J_k`
    /// in column block `k` (`J'_k = I` when `identity_jp`); and `−G_k` (`gk`)
    /// into the right-hand side.
    fn row_block(&mut self, k: usize, ainv: &[[f64; 3]; 3], h: f64, identity_jp: bool, gk: &[f64]) {
        let n = gk.len();
        let nn = 3 * n;
        for i in 0..n {
            let r = k * n + i;
            let row = &mut self.lu.a[r * nn..(r + 1) * nn];
            for (j, blk) in row.chunks_exact_mut(n).enumerate() {
                let a = ainv[k][j] / h;
                if identity_jp {
                    blk.fill(0.0);
                    blk[i] = a;
                } else {
                    for (b, &jp) in blk.iter_mut().zip(&self.jyp[i * n..(i + 1) * n]) {
                        *b = a * jp;
                    }
                }
                if j == k {
                    for (b, &jv) in blk.iter_mut().zip(&self.jy[i * n..(i + 1) * n]) {
                        *b += jv;
                    }
                }
            }
            self.rhs[r] = -gk[i];
        }
    }
}

impl Work {
    /// Starts a Newton iteration: RADAU5's `FACCON` for the first
    /// correction, `θ` reset.
    fn begin_newton(&mut self, np: NewtonParams) -> Monitor {
        self.faccon = self.faccon.max(UROUND).powf(0.8);
        self.theta = np.thet.abs();
        Monitor {
            newt: 0,
            dynold: 1.0,
            thqold: 1.0,
        }
    }

    /// The scaled RMS norm of the correction `ΔW` in `dw` over the `3n`
    /// components (RADAU5's `DYNO`).
    fn correction_norm(&self) -> f64 {
        let n = self.n;
        let [d0, d1, d2] = &self.dw;
        let mut dyno = 0.0;
        for i in 0..n {
            let s = self.scal[i];
            dyno += (d0[i] / s).powi(2) + (d1[i] / s).powi(2) + (d2[i] / s).powi(2);
        }
        (dyno / (3 * n) as f64).sqrt()
    }

    /// RADAU5's monitor after correction number `m.newt` of norm `dyno`:
    /// updates `θ` and `η = FACCON`; `Some` ends the iteration (divergence,
    /// predicted too slow, not finite) before the correction is applied.
    fn monitor(&mut self, m: &mut Monitor, dyno: f64, np: NewtonParams) -> Option<Newton> {
        if !dyno.is_finite() {
            return Some(Newton::NonFinite);
        }
        let newt = m.newt;
        if newt > 1 && newt < np.nit {
            let thq = dyno / m.dynold;
            self.theta = if newt == 2 {
                thq
            } else {
                (thq * m.thqold).sqrt()
            };
            m.thqold = thq;
            if self.theta < 0.99 {
                self.faccon = self.theta / (1.0 - self.theta);
                let left = (np.nit - 1 - newt) as i32;
                let dyth = self.faccon * dyno * self.theta.powi(left) / np.fnewt;
                if dyth >= 1.0 && !np.fixed {
                    let qnewt = dyth.clamp(1e-4, 20.0);
                    return Some(Newton::Slow(
                        0.8 * qnewt.powf(-1.0 / (4.0 + f64::from(left))),
                    ));
                }
            } else {
                return Some(Newton::Failed);
            }
        }
        m.dynold = dyno.max(UROUND);
        None
    }

    /// The simplified Newton iteration for the stage equations of the step
    /// `[t, t_new]` of size `h` from `y` (starting values set by [`Work::start`]).
    pub(super) fn newton<P: Problem>(
        &mut self,
        p: &mut P,
        t: f64,
        y: &[f64],
        h: f64,
        t_new: f64,
        np: NewtonParams,
        stats: &mut Stats,
    ) -> Newton {
        let n = self.n;
        let Tableau {
            c,
            gamma,
            alpha,
            beta,
            t: tm,
            ti,
            ..
        } = self.tab;
        let mut m = self.begin_newton(np);
        loop {
            if m.newt >= np.nit {
                return Newton::Failed;
            }
            // Stage derivatives Y'_k = h⁻¹ (T Λ W)_k, with Λ W formed once per
            // component for the three stages.
            for i in 0..n {
                let (w1, w2, w3) = (self.w[0][i], self.w[1][i], self.w[2][i]);
                let v = [gamma * w1, alpha * w2 - beta * w3, beta * w2 + alpha * w3];
                for k in 0..3 {
                    self.yp_stage[k][i] = (tm[k][0] * v[0] + tm[k][1] * v[1] + tm[k][2] * v[2]) / h;
                }
            }
            // Residuals G_k = F(t + c_k h, y + Z_k, Y'_k).
            for k in 0..3 {
                let tk = if k == 2 { t_new } else { t + c[k] * h };
                for i in 0..n {
                    self.ys[i] = y[i] + self.z[k][i];
                }
                if let Err(e) = p.residual(tk, &self.ys, &self.yp_stage[k], &mut self.dw[k]) {
                    return Newton::Stage(e);
                }
            }
            // Right-hand sides −(T⁻¹ ⊗ I) G, then the two linear systems.
            let [d0, d1, d2] = &mut self.dw;
            for i in 0..n {
                let (g1, g2, g3) = (d0[i], d1[i], d2[i]);
                d0[i] = -(ti[0][0] * g1 + ti[0][1] * g2 + ti[0][2] * g3);
                d1[i] = -(ti[1][0] * g1 + ti[1][1] * g2 + ti[1][2] * g3);
                d2[i] = -(ti[2][0] * g1 + ti[2][1] * g2 + ti[2][2] * g3);
            }
            if !self.solve_stages() {
                return Newton::Singular;
            }
            m.newt += 1;
            stats.newton_iterations += 1;
            let dyno = self.correction_norm();
            if let Some(out) = self.monitor(&mut m, dyno, np) {
                return out;
            }
            for i in 0..n {
                let w1 = self.w[0][i] + self.dw[0][i];
                let w2 = self.w[1][i] + self.dw[1][i];
                let w3 = self.w[2][i] + self.dw[2][i];
                self.w[0][i] = w1;
                self.w[1][i] = w2;
                self.w[2][i] = w3;
                for k in 0..3 {
                    self.z[k][i] = tm[k][0] * w1 + tm[k][1] * w2 + tm[k][2] * w3;
                }
            }
            if self.faccon * dyno <= np.fnewt {
                // y' at the end of the step, h⁻¹ (A⁻¹ Z)_3 = h⁻¹ (T Λ W)_3.
                for i in 0..n {
                    let (w1, w2, w3) = (self.w[0][i], self.w[1][i], self.w[2][i]);
                    let v = [gamma * w1, alpha * w2 - beta * w3, beta * w2 + alpha * w3];
                    self.yp_new[i] = (tm[2][0] * v[0] + tm[2][1] * v[1] + tm[2][2] * v[2]) / h;
                }
                return Newton::Converged(m.newt);
            }
        }
    }

    /// The full Newton iteration for the stage equations of the step
    /// `[t, t_new]` of size `h` from `y` (starting values set by
    /// [`Work::start`]): each iteration evaluates `J_k`, `J'_k` at the three
    /// stage points `(t + c_k h, y + Z_k, h⁻¹ (A⁻¹ Z)_k)`, forms
    /// `∂G_k/∂Z_j = δ_kj J_k + h⁻¹ (A⁻¹)_kj J'_k`, factors it and solves
    /// for `ΔZ`. The monitor sees `ΔW = (T⁻¹ ⊗ I) ΔZ` in the same norm as
    /// the simplified iteration, so `newton_tol` means the same in both.
    pub(super) fn newton_full<P: Problem>(
        &mut self,
        p: &mut P,
        t: f64,
        y: &[f64],
        h: f64,
        t_new: f64,
        np: NewtonParams,
        stats: &mut Stats,
    ) -> Newton {
        let n = self.n;
        let Tableau { c, ti, ainv, .. } = self.tab;
        let mut m = self.begin_newton(np);
        loop {
            if m.newt >= np.nit {
                return Newton::Failed;
            }
            let full = self.full.as_mut().expect("full Newton workspace");
            for k in 0..3 {
                let tk = if k == 2 { t_new } else { t + c[k] * h };
                for i in 0..n {
                    let s = ainv[k][0] * self.z[0][i]
                        + ainv[k][1] * self.z[1][i]
                        + ainv[k][2] * self.z[2][i];
                    self.yps[i] = s / h;
                    self.ys[i] = y[i] + self.z[k][i];
                }
                let gk = &mut self.dw[k];
                if let Err(e) = p.residual(tk, &self.ys, &self.yps, gk) {
                    return Newton::Stage(e);
                }
                if !all_finite(gk) {
                    return Newton::NonFinite;
                }
                stats.jacobian_evals += 1;
                let res = p.jacobians(tk, &self.ys, &self.yps, gk, &mut full.jy, &mut full.jyp);
                if let Err(e) = res {
                    return Newton::Stage(e);
                }
                if !all_finite(&full.jy) || (!P::IDENTITY_JP && !all_finite(&full.jyp)) {
                    return Newton::NonFinite;
                }
                full.row_block(k, &ainv, h, P::IDENTITY_JP, gk);
            }
            stats.lu_decompositions += 1;
            if full.lu.factor().is_err() {
                return Newton::Singular;
            }
            full.lu.solve(&mut full.rhs);
            // ΔW = (T⁻¹ ⊗ I) ΔZ for the monitor.
            let dz = &full.rhs;
            for i in 0..n {
                let (a, b, cc) = (dz[i], dz[n + i], dz[2 * n + i]);
                for k in 0..3 {
                    self.dw[k][i] = ti[k][0] * a + ti[k][1] * b + ti[k][2] * cc;
                }
            }
            m.newt += 1;
            stats.newton_iterations += 1;
            let dyno = self.correction_norm();
            if let Some(out) = self.monitor(&mut m, dyno, np) {
                return out;
            }
            let dz = &self.full.as_ref().expect("full Newton workspace").rhs;
            for k in 0..3 {
                for i in 0..n {
                    self.z[k][i] += dz[k * n + i];
                    self.w[k][i] += self.dw[k][i];
                }
            }
            if self.faccon * dyno <= np.fnewt {
                // y' at the end of the step, h⁻¹ (A⁻¹ Z)_3.
                for i in 0..n {
                    let s = ainv[2][0] * self.z[0][i]
                        + ainv[2][1] * self.z[1][i]
                        + ainv[2][2] * self.z[2][i];
                    self.yp_new[i] = s / h;
                }
                return Newton::Converged(m.newt);
            }
        }
    }
}
