//! Initial data against the constraints: accept, refuse with the residual,
//! or project onto the constraint manifold when asked.

use crate::error::{Error, Level};
use crate::init::Initial;
use crate::project::{Projection, Projector};
use crate::scene::Scene;

/// Largest accepted distance of initial data from the constraints, relative
/// to `max(1, |q|∞)` for positions (`|f_i|/‖F_i‖`) and `max(1, |q̇|∞)` for
/// velocities (`|g_i|/‖G_i‖`, `|ḟ_i|/‖F_i‖`). Initial data typed by hand to a
/// few digits are rejected; data computed from the scene's convenience
/// values pass.
pub const INIT_TOL: f64 = 1e-9;

/// Distance reached by projection, relative to the same scales.
pub const PROJECT_TOL: f64 = 1e-14;

/// What `--project-init` did to the initial data.
#[derive(Debug, Clone, PartialEq)]
pub struct InitProjection {
    pub q_before: Vec<f64>,
    pub qd_before: Vec<f64>,
    pub projection: Projection,
}

fn scale(v: &[f64]) -> f64 {
    v.iter().fold(1.0f64, |m, x| m.max(x.abs()))
}

/// Checks `init` against the scene's constraints. With `project`, moves `q0`
/// onto `f = 0` and `q̇0` onto `g = 0, ḟ = 0` (nearest in the kinetic-energy
/// metric) and returns what changed; without it, inconsistent data are an
/// error that prints the residual of every constraint.
pub fn check_or_project<S: Scene>(
    scene: &S,
    init: &mut Initial,
    project: bool,
) -> Result<Option<InitProjection>, Error> {
    let info = scene.info();
    if info.s() == 0 && info.k() == 0 {
        return Ok(None);
    }
    let mut p = Projector::new(scene);
    if project {
        let (q_before, qd_before) = (init.q.clone(), init.qd.clone());
        let r = p
            .project(scene, init.t0, &mut init.q, &mut init.qd, PROJECT_TOL)
            .map_err(|e| Error::numerical("--project-init", e))?;
        return Ok(Some(InitProjection {
            q_before,
            qd_before,
            projection: r,
        }));
    }
    check(scene, init, p, true)
}

/// Checks `init` against the holonomic constraints only (`f = 0`, `ḟ = 0`):
/// for realisations that may start off the nonholonomic ones (a contact
/// already slipping).
pub fn check_positions<S: Scene>(
    scene: &S,
    init: &mut Initial,
) -> Result<Option<InitProjection>, Error> {
    let info = scene.info();
    if info.k() == 0 {
        return Ok(None);
    }
    check(scene, init, Projector::new(scene), false)
}

/// The check of [`check_or_project`], of `g = 0` too if `nonholonomic`.
fn check<S: Scene>(
    scene: &S,
    init: &Initial,
    mut p: Projector,
    nonholonomic: bool,
) -> Result<Option<InitProjection>, Error> {
    let info = scene.info();
    p.residuals(scene, init.t0, &init.q, &init.qd);
    let own: Vec<f64> = if nonholonomic {
        Vec::new()
    } else {
        p.cs.g.clone()
    };
    let (pos, v) = (p.cs.position_distance(), p.cs.velocity_distance_to(&own));
    let tol = INIT_TOL * scale(&init.q);
    if pos.is_nan() || pos > tol {
        return Err(Error::OffConstraints {
            level: Level::Positions,
            residuals: info
                .holonomic
                .iter()
                .zip(&p.cs.f)
                .map(|(f, r)| (f.to_string(), *r))
                .collect(),
            distance: pos,
            tolerance: tol,
        });
    }
    let tol = INIT_TOL * scale(&init.qd);
    if v.is_nan() || v > tol {
        let mut residuals: Vec<(String, f64)> = info
            .nonholonomic
            .iter()
            .zip(&p.cs.g)
            .map(|(g, r)| (g.to_string(), *r))
            .collect();
        residuals.extend(
            info.holonomic
                .iter()
                .zip(&p.cs.f_rate)
                .map(|(f, r)| (format!("d/dt of {f}"), *r)),
        );
        return Err(Error::OffConstraints {
            level: Level::Velocities,
            residuals,
            distance: v,
            tolerance: tol,
        });
    }
    Ok(None)
}
