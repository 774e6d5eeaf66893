//! DOPRI5 — explicit Runge–Kutta method of order 5(4) due to Dormand & Prince,
//! with step-size control, stiffness detection and dense output of order 4.
//!
//! Follows E. Hairer & G. Wanner's `dopri5.f` (Hairer, Nørsett & Wanner,
//! *Solving Ordinary Differential Equations I*, 2nd ed., Springer 1993,
//! §II.4–II.6 and §IV.2); tableau in [`super::tableau::dopri5`].
//!
//! **Method.** 7 stages, the last one is `f(t + h, y_{n+1})` and is reused
//! as the first stage of the next step (FSAL): 6 evaluations per step.
//!
//! **Error estimate.** `err = sqrt(1/n Σ_i (h Σ_j e_j k_ji / sk_i)²)` with
//! `e = b − b̂` (embedded order 4) and `sk_i = atol + rtol·max(|y_n,i|, |y_n+1,i|)`.
//! A step is accepted when `err <= 1`.
//!
//! **Step-size control** (defaults of `dopri5.f`): `safe = 0.9`,
//! `fac1 = 0.2 <= h_new/h <= fac2 = 10`, Lund stabilisation `beta = 0.04`,
//! `expo1 = 0.2 − 0.75·beta`: `h_new = h / clamp(err^expo1 / err_old^beta / safe)`;
//! after a rejection the step may not grow. Initial step by `HINIT` with
//! `iord = 5` unless `Options::h_init` is given; `h_max` defaults to
//! `|t_end − t0|`. These constants are fixed: the method reads only the
//! shared [`crate::Options`] (no settings of its own), and runs as the
//! solver state [`crate::Solver`].
//!
//! **Stiffness test.** After every 1000th accepted step (and then after each
//! step while it fires): `h·ρ` with `ρ = ‖k_7 − k_6‖/‖y_{n+1} − y_6‖` (stages
//! 6 and 7 share the node `c = 1`). Fifteen values `h·ρ > 3.25` before six
//! successive smaller ones record `Stats::stiffness_detected` — the run
//! goes on.
//!
//! **Dense output** (Shampine 1986), 5 coefficients in the nested form of
//! [`crate::Dense`]: Hermite part `y_n, y_{n+1} − y_n, …` plus
//! `c5 = h Σ d_j k_j`; no extra evaluation of `f`.
//!
//! **Counters.** `rhs_evals` adds up 1 at `t0`, 1 for `HINIT` (unless a
//! step is given), 6 per trial step, accepted or rejected (fewer when `f`
//! fails on a stage), and 1 per projected step; `rejected_steps` counts
//! every rejection, also in the first step (`dopri5.f` does not count
//! those).

use super::control::{ControlParams, Rhs, Tol, combine, stage, stage_time, stiffness_ratio};
use super::tableau::dopri5::{A, B, C, D, E};
use super::{Scheme, Start, StepData, hermite};
use crate::{OdeSystem, SystemError};

/// Stage vectors of DOPRI5.
pub(super) struct Dopri5 {
    /// `k[0..7]`: the stages; `k[6] = f(t + h, y_{n+1})`.
    k: Vec<Vec<f64>>,
    /// Stage states 2–5.
    ys: Vec<f64>,
    /// Stage state 6 (node 1), kept for the stiffness test.
    ysti: Vec<f64>,
    /// `Σ e_j k_j`.
    err: Vec<f64>,
}

impl Scheme for Dopri5 {
    const NCOEF: usize = 5;
    const CONTROL: Option<ControlParams> = Some(ControlParams {
        safe: 0.9,
        fac1: 0.2,
        fac2: 10.0,
        beta: 0.04,
        expo1: 0.2 - 0.04 * 0.75,
        hinit_order: 5,
        stiff_bound: 3.25,
    });

    fn new(dim: usize) -> Self {
        Dopri5 {
            k: vec![vec![0.0; dim]; 7],
            ys: vec![0.0; dim],
            ysti: vec![0.0; dim],
            err: vec![0.0; dim],
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
        for s in 1..5 {
            stage(&mut self.ys, y, h, A[s], &self.k[..s]);
            rhs.eval(stage_time(t, h, C[s], t_new), &self.ys, &mut self.k[s])?;
        }
        stage(&mut self.ysti, y, h, A[5], &self.k[..5]);
        rhs.eval(t_new, &self.ysti, &mut self.k[5])?;
        stage(y_new, y, h, &B, &self.k[..6]);
        rhs.eval(t_new, y_new, &mut self.k[6])?;
        let Some(tol) = tol else {
            return Ok(0.0);
        };
        combine(&mut self.err, &E, &self.k);
        let mut sum = 0.0;
        for (i, ((&e, &y0), &y1)) in self.err.iter().zip(y).zip(y_new.iter()).enumerate() {
            let r = h * e / tol.scale(i, y0, y1);
            sum += r * r;
        }
        Ok((sum / y.len() as f64).sqrt())
    }

    fn f_new<S: OdeSystem + ?Sized>(
        &mut self,
        _rhs: &mut Rhs<'_, S>,
        _t_new: f64,
        _y_new: &[f64],
        f_new: &mut [f64],
    ) -> Result<(), SystemError> {
        f_new.copy_from_slice(&self.k[6]);
        Ok(())
    }

    fn stiffness(&self, h: f64, y_new: &[f64], _f_new: &[f64]) -> Option<f64> {
        stiffness_ratio(h, &self.k[6], &self.k[5], y_new, &self.ysti)
    }

    fn dense<S: OdeSystem + ?Sized>(
        &mut self,
        _rhs: &mut Rhs<'_, S>,
        step: StepData<'_>,
        coef: &mut [f64],
    ) -> Result<(), SystemError> {
        let dim = step.y.len();
        hermite(coef, step);
        let c5 = &mut coef[4 * dim..5 * dim];
        combine(c5, &D, &self.k);
        for c in c5 {
            *c *= step.h;
        }
        Ok(())
    }
}
