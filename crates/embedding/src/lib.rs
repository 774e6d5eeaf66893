//! Formulation A: the seed paper's Hamilton-principle embedding (§3–4).
//!
//! See [`elo`] for `Θ` and the Euler–Lagrange–Ostrogradsky equations.

pub mod analysis;
pub mod elo;
pub mod jet;
pub mod model;
pub mod ode;

pub use model::{Embedding, INFO, OPTIONS};
