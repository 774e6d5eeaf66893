//! Radau IIA of order 5. (To be implemented.)
use crate::{Failure, ImplicitSystem, OdeSystem, Options, Solution};

pub(crate) fn solve_ode<S: OdeSystem + ?Sized>(
    _sys: &mut S,
    _t0: f64,
    _y0: &[f64],
    _t_end: f64,
    _opts: &Options,
) -> Result<Solution, Failure> {
    unimplemented!()
}

pub(crate) fn solve_implicit<S: ImplicitSystem + ?Sized>(
    _sys: &mut S,
    _t0: f64,
    _y0: &[f64],
    _yp0: &[f64],
    _t_end: f64,
    _opts: &Options,
) -> Result<Solution, Failure> {
    unimplemented!()
}
