//! The two kinds of problem the Radau core integrates, seen through one
//! interface: `F(t, y, y') = 0` with `J = ∂F/∂y`, `J' = ∂F/∂y'`.
//!
//! - [`Ode`] wraps an [`OdeSystem`] as `F = y' − f(t, y)`: `J' = I`,
//!   `J = −∂f/∂y` (from [`OdeSystem::jacobian`], or forward differences).
//! - [`Dae`] wraps an [`ImplicitSystem`] as it is.
//!
//! Both count their evaluations of `F` (for [`Ode`], of `f`, including
//! those of the finite-difference Jacobian and of `HINIT`; [`Hooks::evals`]).

use crate::driver::Hooks;
use crate::explicit::control::{Rhs, Tol, hinit, hinit_guess};
use crate::{ImplicitSystem, OdeSystem, Sparsity, SystemError};

/// The rounding unit of RADAU5 (`WORK(1)` default `1e-16`).
pub(crate) const UROUND: f64 = 1e-16;

/// What the Radau core needs from a problem (besides the hooks of the step
/// loop, [`Hooks`], whose `evals` counts the evaluations of `F` or `f`).
pub(super) trait Problem: Hooks {
    /// `J' = I` (an explicit ODE): `jyp` is never filled nor read.
    const IDENTITY_JP: bool;

    fn dim(&self) -> usize;

    /// Writes `F(t, y, y')` into `res`.
    fn residual(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        res: &mut [f64],
    ) -> Result<(), SystemError>;

    /// `J = ∂F/∂y` into `jy` and (unless [`Problem::IDENTITY_JP`]) `J' =
    /// ∂F/∂y'` into `jyp` at the point `(t, y, y')`, where `F(t, y, y') =
    /// res` is known (zero at an accepted state of an explicit ODE; the
    /// stage residual inside a full Newton iteration). The finite
    /// differences of an ODE take `f(t, y) = y' − res` from it.
    fn jacobians(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        res: &[f64],
        jy: &mut [f64],
        jyp: &mut [f64],
    ) -> Result<(), SystemError>;

    /// At an accepted state `(t, y)`: what the error estimate of the next
    /// step needs. For an explicit ODE, `y' = f(t, y)` into `yp` (one
    /// evaluation) and `res` left at zero. An implicit system cannot be
    /// solved for `y'` (`J'` may be singular): `yp` holds the derivative of
    /// the collocation polynomial, and `res = F(t, y, y')` (one evaluation)
    /// measures how far the pair is from consistent (Newton error, projection).
    fn accepted_state(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &mut [f64],
        res: &mut [f64],
    ) -> Result<(), SystemError>;

    /// The initial step when none is given, at least not above `hmax`;
    /// `(t, y, y')` consistent, `y1`, `f1` workspaces.
    fn initial_step(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        hmax: f64,
        tol: Tol<'_>,
        y1: &mut [f64],
        f1: &mut [f64],
    ) -> f64;

    /// The index class (1, 2, 3) of every component.
    fn variable_index(&self, index: &mut [u8]);

    /// The sparsity of `J` and `J'` when the problem gives them sparse
    /// ([`ImplicitSystem::sparsity`]); `None`: dense.
    fn sparsity(&self) -> Option<Sparsity> {
        None
    }

    /// A name for component `i`, for messages.
    fn component_name(&self, i: usize) -> String {
        format!("y[{i}]")
    }
}

/// An [`OdeSystem`] as `F(t, y, y') = y' − f(t, y)`.
pub(super) struct Ode<'a, S: ?Sized> {
    /// The system and its count of `f` evaluations.
    rhs: Rhs<'a, S>,
    /// Whether [`OdeSystem::jacobian`] provides the Jacobian (`None`: not asked yet).
    analytic: Option<bool>,
    /// Workspaces of the finite-difference Jacobian: `f(t, y + δ e_j)`,
    /// `y + δ e_j`, and `f(t, y)`.
    f: Vec<f64>,
    y: Vec<f64>,
    f0: Vec<f64>,
}

impl<'a, S: OdeSystem + ?Sized> Ode<'a, S> {
    pub fn new(sys: &'a mut S) -> Self {
        let n = sys.dim();
        Ode {
            rhs: Rhs { sys, evals: 0 },
            analytic: None,
            f: vec![0.0; n],
            y: vec![0.0; n],
            f0: vec![0.0; n],
        }
    }
}

impl<S: OdeSystem + ?Sized> Hooks for Ode<'_, S> {
    fn evals(&self) -> usize {
        self.rhs.evals
    }

    fn after_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        self.rhs.after_step(t, y)
    }

    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        self.rhs.guard(t, y)
    }

    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        self.rhs.guard_reason(t, y)
    }
}

impl<S: OdeSystem + ?Sized> Problem for Ode<'_, S> {
    const IDENTITY_JP: bool = true;

    fn dim(&self) -> usize {
        self.rhs.sys.dim()
    }

    fn residual(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        res: &mut [f64],
    ) -> Result<(), SystemError> {
        self.rhs.eval(t, y, res)?;
        for (r, &d) in res.iter_mut().zip(yp) {
            *r = d - *r;
        }
        Ok(())
    }

    /// `J = −∂f/∂y`. Forward differences when the system has no Jacobian:
    /// column `j` from `f(t, y + δ_j e_j)` with RADAU5's increment
    /// `δ_j = sqrt(UROUND·max(1e-5, |y_j|))` and `f(t, y) = yp − res`
    /// (`= yp` at an accepted state, where `res` is zero).
    fn jacobians(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        res: &[f64],
        jy: &mut [f64],
        _jyp: &mut [f64],
    ) -> Result<(), SystemError> {
        let n = y.len();
        if self.analytic != Some(false) {
            let has = self.rhs.sys.jacobian(t, y, jy)?;
            self.analytic = Some(has);
            if has {
                jy.iter_mut().for_each(|v| *v = -*v);
                return Ok(());
            }
        }
        self.y.copy_from_slice(y);
        for ((f0, &d), &r) in self.f0.iter_mut().zip(yp).zip(res) {
            *f0 = d - r;
        }
        for j in 0..n {
            let ysafe = y[j];
            let delt = (UROUND * ysafe.abs().max(1e-5)).sqrt();
            self.y[j] = ysafe + delt;
            let res = self.rhs.eval(t, &self.y, &mut self.f);
            self.y[j] = ysafe;
            res?;
            for i in 0..n {
                jy[i * n + j] = -(self.f[i] - self.f0[i]) / delt;
            }
        }
        Ok(())
    }

    fn accepted_state(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &mut [f64],
        _res: &mut [f64],
    ) -> Result<(), SystemError> {
        self.rhs.eval(t, y, yp)
    }

    /// Hairer's `HINIT` with the exponent 4 of RADAU5's error estimate
    /// (one evaluation of `f`).
    fn initial_step(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        hmax: f64,
        tol: Tol<'_>,
        y1: &mut [f64],
        f1: &mut [f64],
    ) -> f64 {
        hinit(&mut self.rhs, t, y, yp, 4, hmax, tol, y1, f1)
    }

    fn variable_index(&self, index: &mut [u8]) {
        index.fill(1);
    }
}

/// An [`ImplicitSystem`] `F(t, y, y') = 0`.
pub(super) struct Dae<'a, S: ?Sized> {
    pub sys: &'a mut S,
    pub evals: usize,
}

impl<S: ImplicitSystem + ?Sized> Hooks for Dae<'_, S> {
    fn evals(&self) -> usize {
        self.evals
    }

    fn after_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        self.sys.after_step(t, y)
    }

    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        self.sys.guard(t, y)
    }

    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        self.sys.guard_reason(t, y)
    }
}

impl<S: ImplicitSystem + ?Sized> Problem for Dae<'_, S> {
    const IDENTITY_JP: bool = false;

    fn dim(&self) -> usize {
        self.sys.dim()
    }

    fn residual(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        res: &mut [f64],
    ) -> Result<(), SystemError> {
        self.evals += 1;
        self.sys.residual(t, y, yp, res)
    }

    fn jacobians(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        _res: &[f64],
        jy: &mut [f64],
        jyp: &mut [f64],
    ) -> Result<(), SystemError> {
        self.sys.jacobians(t, y, yp, jy, jyp)
    }

    fn accepted_state(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &mut [f64],
        res: &mut [f64],
    ) -> Result<(), SystemError> {
        self.evals += 1;
        self.sys.residual(t, y, yp, res)
    }

    /// `HINIT`'s first guess `0.01·‖y0‖/‖y'0‖` (weighted norms; `1e-6` if
    /// either norm is tiny): no second derivative can be estimated without
    /// solving for `y'`.
    fn initial_step(
        &mut self,
        _t: f64,
        y: &[f64],
        yp: &[f64],
        hmax: f64,
        tol: Tol<'_>,
        _y1: &mut [f64],
        _f1: &mut [f64],
    ) -> f64 {
        hinit_guess(y, yp, hmax, tol).0
    }

    fn variable_index(&self, index: &mut [u8]) {
        self.sys.variable_index(index);
    }

    fn sparsity(&self) -> Option<Sparsity> {
        self.sys.sparsity()
    }

    fn component_name(&self, i: usize) -> String {
        self.sys.component_name(i)
    }
}
