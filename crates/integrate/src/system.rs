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

    /// Called once after every accepted step with the new state.
    ///
    /// The system may modify `y` in place (projection onto a manifold) and
    /// then returns `Ok(true)`, so that the integrator discards any value of
    /// `f` it would otherwise reuse. It may also just observe the state (to
    /// accumulate diagnostics) and return `Ok(false)`.
    fn after_step(&mut self, _t: f64, _y: &mut [f64]) -> Result<bool, SystemError> {
        Ok(false)
    }

    /// A continuous function of the state that is positive where the system
    /// is regular. The run stops with [`IntegrateError::Stopped`](crate::IntegrateError::Stopped) at the first
    /// time it reaches zero; that time is located on the continuous extension.
    /// `None` (the default) means there is nothing to watch.
    fn guard(&mut self, _t: f64, _y: &[f64]) -> Option<f64> {
        None
    }

    /// Why the run stopped, for a state at which [`OdeSystem::guard`] is zero.
    fn guard_reason(&mut self, _t: f64, _y: &[f64]) -> String {
        "guard function reached zero".to_string()
    }
}
