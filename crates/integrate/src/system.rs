use crate::SystemError;

/// A first-order system `y' = f(t, y)` of fixed dimension.
///
/// Implementations own their workspaces: [`OdeSystem::rhs`] is the hot path and
/// should not allocate.
pub trait OdeSystem {
    /// Dimension of `y`.
    fn dim(&self) -> usize;

    /// Writes `f(t, y)` into `dy` (length [`OdeSystem::dim`]).
    ///
    /// An error here is the system's way to say that `f` is not defined at
    /// `(t, y)` (a singular matrix, a state outside the domain).
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError>;

    /// The Jacobian `∂f/∂y` at `(t, y)`, row-major into `jac` (`dim × dim`,
    /// `jac[i * dim + j] = ∂f_i/∂y_j`). Returns `Ok(false)` if the system does
    /// not provide one (implicit methods then use finite differences and say
    /// so in their counters).
    fn jacobian(&mut self, _t: f64, _y: &[f64], _jac: &mut [f64]) -> Result<bool, SystemError> {
        Ok(false)
    }

    /// Called once after every accepted step with the new state.
    ///
    /// The system may modify `y` in place (projection onto a manifold) and
    /// then returns `Ok(true)`, so that the integrator discards any value of
    /// `f` it would otherwise reuse. It may also just observe the state (to
    /// accumulate diagnostics) and return `Ok(false)`.
    ///
    /// **Order of calls** (a guaranteed contract of every method): within
    /// one accepted step ending at `t`, `after_step(t, y)` is called first
    /// and [`OdeSystem::guard`]`(t, y)` afterwards, on the state as
    /// `after_step` left it. So a guard may rely on state that `after_step`
    /// updated for this step (e.g. the sign convention of a signed guard).
    /// Neither is called for rejected trial steps. Guard evaluations made
    /// to locate a zero inside the step come after both.
    fn after_step(&mut self, _t: f64, _y: &mut [f64]) -> Result<bool, SystemError> {
        Ok(false)
    }

    /// A continuous function of the state that is positive where the system
    /// is regular. The run stops with [`IntegrateError::Stopped`](crate::IntegrateError::Stopped) at the first
    /// time it reaches zero; that time is located on the continuous extension.
    /// `None` (the default) means there is nothing to watch.
    ///
    /// Called once at `t0` (before any step; a value `<= 0` stops the run at
    /// once, `None` there switches the watch off for the run) and then once
    /// per accepted step, **after** [`OdeSystem::after_step`] of that step,
    /// with the (possibly projected) new state; then, only if the sign
    /// changed from `> 0` to `<= 0`, at points of the step polynomial to
    /// locate the zero. NaN counts as `<= 0`: a guard that cannot be
    /// evaluated stops the run.
    fn guard(&mut self, _t: f64, _y: &[f64]) -> Option<f64> {
        None
    }

    /// Why the run stopped, for a state at which [`OdeSystem::guard`] is zero.
    ///
    /// **Contract** (guaranteed by every method): called once, when the
    /// guard stops the run, with exactly the `t` and `y` (bitwise) of the
    /// last guard evaluation that did not return a positive value (`<= 0`,
    /// NaN or `None`) — the one that located the stop, at `t0`, at the end
    /// of the step or inside it — and with no call to the system in between
    /// except guard evaluations that returned `> 0`. So a system can explain
    /// the stop with what its guard measured there (remembered whenever the
    /// guard is not positive) instead of measuring again.
    fn guard_reason(&mut self, _t: f64, _y: &[f64]) -> String {
        "guard function reached zero".to_string()
    }
}

/// The entries `(row, column)` that may be nonzero in the Jacobians of an
/// [`ImplicitSystem`] (see [`ImplicitSystem::sparsity`]); no entry twice in
/// one list.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Sparsity {
    /// Entries of `∂F/∂y`.
    pub jy: Vec<(usize, usize)>,
    /// Entries of `∂F/∂y'`.
    pub jyp: Vec<(usize, usize)>,
}

/// A fully implicit system `F(t, y, y') = 0` of fixed dimension, including
/// differential-algebraic systems (`∂F/∂y'` singular) of index up to 3.
///
/// Implementations own their workspaces; [`ImplicitSystem::residual`] and
/// [`ImplicitSystem::jacobians`] should not allocate.
pub trait ImplicitSystem {
    /// Dimension of `y` (and of `F`).
    fn dim(&self) -> usize;

    /// Writes `F(t, y, y')` into `res`.
    fn residual(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        res: &mut [f64],
    ) -> Result<(), SystemError>;

    /// `∂F/∂y` into `jy` and `∂F/∂y'` into `jyp`, both row-major `dim × dim`
    /// (`jy[i * dim + j] = ∂F_i/∂y_j`); or, for a system with a
    /// [`ImplicitSystem::sparsity`], their values at the listed entries, in
    /// the order of the lists (`jy[p]` is the entry `sparsity.jy[p]`).
    fn jacobians(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        jy: &mut [f64],
        jyp: &mut [f64],
    ) -> Result<(), SystemError>;

    /// The structural nonzeros of `∂F/∂y` and `∂F/∂y'`, for a system whose
    /// Jacobians are sparse: Radau IIA then stores and factors its
    /// iteration matrices sparse (faer) and [`ImplicitSystem::jacobians`]
    /// writes values at these entries only. `None` (the default): dense.
    /// Called once per run; the pattern must hold at every state.
    fn sparsity(&self) -> Option<Sparsity> {
        None
    }

    /// A name for component `i` of `y` (and of the equation `F_i` paired
    /// with it), for messages; `y[i]` by default.
    fn component_name(&self, i: usize) -> String {
        format!("y[{i}]")
    }

    /// The index class (1, 2 or 3) of every component of `y`, used as in
    /// RADAU5 to scale the error estimate of index-2 and index-3 variables by
    /// `h` and `h²`. Default: all 1 (an ODE or index-1 system).
    fn variable_index(&self, index: &mut [u8]) {
        index.fill(1);
    }

    /// Called once after every accepted step; may modify `y` (projection),
    /// then returns `Ok(true)`. See [`OdeSystem::after_step`].
    ///
    /// **Order of calls**: as for [`OdeSystem::after_step`], within one
    /// accepted step `after_step` comes first and [`ImplicitSystem::guard`]
    /// afterwards, on the state `after_step` left.
    fn after_step(&mut self, _t: f64, _y: &mut [f64]) -> Result<bool, SystemError> {
        Ok(false)
    }

    /// See [`OdeSystem::guard`]: called at `t0`, then once per accepted step
    /// **after** [`ImplicitSystem::after_step`] of that step, then (only on a
    /// sign change) to locate the zero on the collocation polynomial.
    fn guard(&mut self, _t: f64, _y: &[f64]) -> Option<f64> {
        None
    }

    /// See [`OdeSystem::guard_reason`], whose contract holds here too.
    fn guard_reason(&mut self, _t: f64, _y: &[f64]) -> String {
        "guard function reached zero".to_string()
    }
}

/// The worst entry of a system's Jacobian against central differences of
/// its right-hand side at `(t, y)` (step `1e-6 (1 + |y_j|)`), relative to
/// the largest entry of its column (at least 1): `(mismatch, i, j)`, for
/// checking an analytic or AD Jacobian. `Ok(None)` if the system has no
/// Jacobian of its own.
pub fn jacobian_mismatch(
    sys: &mut dyn OdeSystem,
    t: f64,
    y: &[f64],
) -> Result<Option<(f64, usize, usize)>, SystemError> {
    let dim = y.len();
    let mut jac = vec![0.0; dim * dim];
    if !sys.jacobian(t, y, &mut jac)? {
        return Ok(None);
    }
    let (mut fp, mut fm) = (vec![0.0; dim], vec![0.0; dim]);
    let mut worst = (0.0f64, 0, 0);
    for j in 0..dim {
        let h = 1e-6 * (1.0 + y[j].abs());
        let (mut yp, mut ym) = (y.to_vec(), y.to_vec());
        yp[j] += h;
        ym[j] -= h;
        sys.rhs(t, &yp, &mut fp)?;
        sys.rhs(t, &ym, &mut fm)?;
        let col = (0..dim).fold(1.0f64, |m, i| m.max(jac[i * dim + j].abs()));
        for i in 0..dim {
            let fd = (fp[i] - fm[i]) / (2.0 * h);
            let e = (jac[i * dim + j] - fd).abs() / col;
            if e.is_nan() || e > worst.0 {
                worst = (e, i, j);
            }
        }
    }
    Ok(Some(worst))
}
