//! Physical realisations of the nonholonomic constraints (spec,
//! "Realisations"): no ideal constraint, but a stiff physical mechanism that
//! enforces it approximately. They are the referees of the bench: as their
//! gain grows their motions tend to B ([`visc`]) or to C ([`mass`]), so they
//! say which of the ideal formulations a physical sleigh follows.
//!
//! Both are built from the scene's Lagrangian and constraints only; nothing
//! here knows a scene. `visc` is integrated in `(q, q̇)` or, where the
//! constraints allow it, in velocities adapted to them ([`adapted`]: the
//! scene's velocity chart and the violation `w = g` itself), the default. Holonomic constraints `f`, if a scene has them, stay
//! ideal and are enforced at acceleration level as in B (without
//! stabilisation; their drift is in the diagnostics).

pub mod adapted;
pub mod mass;
pub mod rows;
pub mod visc;

pub use mass::Mass;
pub use visc::Visc;

use nonholo_core::scene::{MAX_CONSTRAINTS, SceneInfo};

/// A realisation applies to every scene with nonholonomic constraints.
fn applicable(scene: &SceneInfo) -> Result<(), String> {
    if scene.s() == 0 {
        return Err(
            "the scene has no nonholonomic constraints to realise; its motion is B's".into(),
        );
    }
    if scene.s() > MAX_CONSTRAINTS {
        return Err(format!(
            "the scene has {} nonholonomic constraints; realisations support at most {MAX_CONSTRAINTS}",
            scene.s()
        ));
    }
    Ok(())
}
