//! DOP853 — explicit Runge–Kutta method of order 8 due to Dormand & Prince,
//! with error estimators of orders 5 and 3, step-size control, stiffness
//! detection and dense output of order 7.
//!
//! Follows E. Hairer & G. Wanner's `dop853.f` (Hairer, Nørsett & Wanner,
//! *Solving Ordinary Differential Equations I*, 2nd ed., Springer 1993,
//! §II.10); tableau in [`super::tableau::dop853`].
//!
//! **Method.** 12 stages; `f(t + h, y_{n+1})` is evaluated once the error
//! test has passed and is reused as the first stage of the next step:
//! 12 evaluations per accepted step, 11 per rejected one.
//!
//! **Error estimate.** With `sk_i = atol + rtol·max(|y_n,i|, |y_n+1,i|)`,
//! `err5 = Σ_i (Σ_j er_j k_ji / sk_i)²` (difference to an order-5 solution)
//! and `err3 = Σ_i (Σ_j (b_j − bhh_j) k_ji / sk_i)²` (difference to an
//! order-3 solution):
//! `err = |h|·err5 / sqrt(n·(err5 + 0.01·err3))`, which behaves like `h⁸`
//! for small `h` yet stays reliable for large `h`. Accept when `err <= 1`.
//!
//! **Step-size control** (defaults of `dop853.f`): `safe = 0.9`,
//! `fac1 = 0.333 <= h_new/h <= fac2 = 6`, `beta = 0` (no Lund
//! stabilisation), `expo1 = 1/8 − 0.2·beta`; after a rejection the step may
//! not grow. Initial step by `HINIT` with `iord = 8` unless
//! `Options::h_init` is given; `h_max` defaults to `|t_end − t0|`. These
//! constants are fixed: the method reads only the shared
//! [`crate::Options`] (no settings of its own), and runs as the solver
//! state [`crate::Solver`].
//!
//! **Stiffness test.** After every 1000th accepted step (and then after each
//! step while it fires): `h·ρ` with `ρ = ‖f(t+h, y_{n+1}) − k_12‖/‖y_{n+1} − y_12‖`
//! (both at node 1). Fifteen values `h·ρ > 6.1` before six successive
//! smaller ones record `Stats::stiffness_detected`; the run goes on.
//!
//! **Dense output** of order 7 with 8 coefficients in the nested form of
//! [`crate::Dense`]: the Hermite part, then `h Σ_j d_kj k_j` for `k = 4..7`
//! over the 12 stages, `f(t + h, y_{n+1})` and three extra stages
//! (`c = 0.1, 0.2, 7/9`). The extra stages cost 3 evaluations and are only
//! computed for steps whose polynomial is needed (`Options::dense`, a
//! guard, or an output time inside the step).
//!
//! **Counters.** `rhs_evals` adds up 1 at `t0`, 1 for `HINIT` (unless a
//! step is given), 11 per trial step, 1 per accepted step (`f` at the new
//! point), 3 per step with dense output (counted again, apart, in
//! `dense_rhs_evals`) and 1 per projected step (fewer when `f` fails on a
//! stage); `rejected_steps` counts every rejection, also in
//! the first step (`dop853.f` does not count those).

use super::control::{ControlParams, Rhs, Tol, combine, stage, stage_time, stiffness_ratio};
use super::tableau::dop853::{A, B, C, D, E3, ER};
use super::{Scheme, Start, StepData, hermite};
use crate::{OdeSystem, SystemError};

/// Stage vectors of DOP853.
pub(super) struct Dop853 {
    /// `k[0..12]`: the stages; `k[12] = f(t + h, y_{n+1})`; `k[13..16]`: dense-output stages.
    k: Vec<Vec<f64>>,
    /// Stage states.
    ys: Vec<f64>,
    /// Stage state 12 (node 1), kept for the stiffness test.
    y12: Vec<f64>,
    /// `Σ er_j k_j` and `Σ (b_j − bhh_j) k_j`.
    e5: Vec<f64>,
    e3: Vec<f64>,
}

impl Scheme for Dop853 {
    const NCOEF: usize = 8;
    const CONTROL: Option<ControlParams> = Some(ControlParams {
        safe: 0.9,
        fac1: 0.333,
        fac2: 6.0,
        beta: 0.0,
        expo1: 1.0 / 8.0,
        hinit_order: 8,
        stiff_bound: 6.1,
    });

    fn new(dim: usize) -> Self {
        Dop853 {
            k: vec![vec![0.0; dim]; 16],
            ys: vec![0.0; dim],
            y12: vec![0.0; dim],
            e5: vec![0.0; dim],
            e3: vec![0.0; dim],
        }
    }

    fn step<S: OdeSystem + ?Sized>(
        &mut self,
        rhs: &mut Rhs<'_, S>,
        from: Start<'_>,
        h: f64,
        t_new: f64,
        y_new: &mut [f64],
        tol: Option<Tol<'_>>,
    ) -> Result<f64, SystemError> {
        let Start { t, y, f } = from;
        self.k[0].copy_from_slice(f);
        for s in 1..11 {
            stage(&mut self.ys, y, h, A[s], &self.k[..s]);
            rhs.eval(stage_time(t, h, C[s], t_new), &self.ys, &mut self.k[s])?;
        }
        stage(&mut self.y12, y, h, A[11], &self.k[..11]);
        rhs.eval(t_new, &self.y12, &mut self.k[11])?;
        stage(y_new, y, h, &B, &self.k[..12]);
        let Some(tol) = tol else {
            return Ok(0.0);
        };
        combine(&mut self.e5, &ER, &self.k[..12]);
        combine(&mut self.e3, &E3, &self.k[..12]);
        let (mut err5, mut err3) = (0.0, 0.0);
        for (i, (&y0, &y1)) in y.iter().zip(y_new.iter()).enumerate() {
            let sk = tol.scale(i, y0, y1);
            err5 += (self.e5[i] / sk) * (self.e5[i] / sk);
            err3 += (self.e3[i] / sk) * (self.e3[i] / sk);
        }
        let mut deno = err5 + 0.01 * err3;
        if deno <= 0.0 {
            deno = 1.0;
        }
        Ok(h.abs() * err5 * (1.0 / (y.len() as f64 * deno)).sqrt())
    }

    fn f_new<S: OdeSystem + ?Sized>(
        &mut self,
        rhs: &mut Rhs<'_, S>,
        t_new: f64,
        y_new: &[f64],
        f_new: &mut [f64],
    ) -> Result<(), SystemError> {
        rhs.eval(t_new, y_new, f_new)
    }

    fn stiffness(&self, h: f64, y_new: &[f64], f_new: &[f64]) -> Option<f64> {
        stiffness_ratio(h, f_new, &self.k[11], y_new, &self.y12)
    }

    fn dense<S: OdeSystem + ?Sized>(
        &mut self,
        rhs: &mut Rhs<'_, S>,
        step: StepData<'_>,
        coef: &mut [f64],
    ) -> Result<(), SystemError> {
        let dim = step.y.len();
        let (t, h, y) = (step.t, step.h, step.y);
        self.k[12].copy_from_slice(step.f_new);
        for s in 13..16 {
            stage(&mut self.ys, y, h, A[s], &self.k[..s]);
            rhs.eval(t + C[s] * h, &self.ys, &mut self.k[s])?;
        }
        hermite(coef, step);
        for (r, d) in D.iter().enumerate() {
            let c = &mut coef[(4 + r) * dim..(5 + r) * dim];
            combine(c, d, &self.k);
            for v in c {
                *v *= h;
            }
        }
        Ok(())
    }
}
