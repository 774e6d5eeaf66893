//! RK4 — the classical Runge–Kutta method of order 4 with fixed step.
//!
//! **Method.** Four stages (Kutta 1901, tableau in [`super::tableau::rk4`]),
//! no error estimate: the step is `Options::fixed_step` (required, positive),
//! and the last step is shortened to land exactly on `t_end`. No settings
//! of its own; solver state [`crate::Solver`].
//!
//! **Continuous extension.** Cubic Hermite interpolation of `y_n, y_{n+1}`
//! and `f_n, f_{n+1}` (order 3, local error `O(h⁴)`), in the nested form of
//! [`crate::Dense`] with 4 coefficients: `c1 = y_n`, `c2 = y_{n+1} − y_n`,
//! `c3 = h f_n − c2`, `c4 = c2 − h f_{n+1} − c3`.
//!
//! **Cost.** `f_{n+1}` is computed at the end of every step and reused as
//! the first stage of the next one, so a step costs 4 evaluations of `f`;
//! one more at `t0`, and one after each step whose state `after_step`
//! projected.
//!
//! **Failures.** Any error of `f` is fatal (`System` at the start of the
//! step), and so is a non-finite stage or state (`NonFinite`).

use super::control::{ControlParams, Rhs, Tol, stage, stage_time};
use super::tableau::rk4::{A, B, C};
use super::{Scheme, Start, StepData};
use crate::{OdeSystem, SystemError};

/// Stage vectors of RK4.
pub(super) struct Rk4 {
    k: Vec<Vec<f64>>,
    ys: Vec<f64>,
}

impl Scheme for Rk4 {
    const NCOEF: usize = 4;
    const CONTROL: Option<ControlParams> = None;

    fn new(dim: usize) -> Self {
        Rk4 {
            k: vec![vec![0.0; dim]; 4],
            ys: vec![0.0; dim],
        }
    }

    fn step<S: OdeSystem + ?Sized>(
        &mut self,
        rhs: &mut Rhs<'_, S>,
        from: Start<'_>,
        h: f64,
        t_new: f64,
        y_new: &mut [f64],
        _tol: Option<Tol<'_>>,
    ) -> Result<f64, SystemError> {
        let Start { t, y, f } = from;
        self.k[0].copy_from_slice(f);
        for s in 1..4 {
            stage(&mut self.ys, y, h, A[s], &self.k[..s]);
            rhs.eval(stage_time(t, h, C[s], t_new), &self.ys, &mut self.k[s])?;
        }
        stage(y_new, y, h, &B, &self.k);
        Ok(0.0)
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

    fn stiffness(&self, _h: f64, _y_new: &[f64], _f_new: &[f64]) -> Option<f64> {
        None
    }

    fn dense<S: OdeSystem + ?Sized>(
        &mut self,
        _rhs: &mut Rhs<'_, S>,
        step: StepData<'_>,
        coef: &mut [f64],
    ) -> Result<(), SystemError> {
        super::hermite(coef, step);
        Ok(())
    }
}
