//! Formulation A: the seed paper's Hamilton-principle embedding (§3–4).
//!
//! * [`elo`]: `Θ` and the Euler–Lagrange–Ostrogradsky equations (19) on
//!   time jets ([`jet`]); [`analysis`]: their derivative array, structure
//!   and consistent completion.
//! * [`setup`]: initial data; [`implicit`] and [`explicit`]: the two forms
//!   (the explicit one solves the derivative array per right-hand side,
//!   [`ode`], optionally with the array traced into native code,
//!   [`traced`]);
//!   [`model`]: both as one model.

pub mod analysis;
pub mod crossing;
pub mod elo;
pub mod explicit;
pub mod implicit;
pub mod jet;
pub mod model;
pub mod ode;
pub mod setup;
mod shared;
pub mod traced;

pub use model::{Embedding, INFO, OPTIONS};
pub use setup::InitReport;
