//! Contacts as conic programs, solved with Clarabel.
//!
//! * [`gauss`]: formulation `gauss`, Gauss's principle of least constraint —
//!   the constrained acceleration minimises `½ (q̈ − M⁻¹Q)ᵀ M (q̈ − M⁻¹Q)`
//!   over the accelerations the constraints allow — solved as a quadratic
//!   program. With equality constraints only it is B (formulation
//!   `chetaev`) computed another way.
//! * [`friction`]: realisation `friction`, the constraint enforced by dry
//!   (Coulomb) friction at the scene's contacts, which stick while the
//!   needed force stays inside the friction cone and slip otherwise; the
//!   friction cone at a transition is a second-order cone program.
//! * [`conic`]: the programs and their solver.

pub mod conic;
pub mod friction;
pub mod gauss;
