//! Coefficient tableaux of the explicit methods, one file each, with the
//! source of the numbers and unit tests of their order conditions.

#[cfg(test)]
mod conditions;
pub(crate) mod dop853;
pub(crate) mod dopri5;
pub(crate) mod rk4;
