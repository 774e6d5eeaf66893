//! Initial data against the constraints: accept, refuse with the residual,
//! or project onto the constraint manifold when asked.

use crate::compiled::Compiled;
use crate::constraints::nan_max;
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
    check_or_project_with(scene, init, project, None)
}

/// [`check_or_project`] with the scene's compiled program, if the caller
/// has one: the check (not the projection) then reads `g`, `f`, `ḟ` and
/// the rows of `G`, `F` from one evaluation of the program, in time and
/// memory proportional to their structural nonzeros, instead of `n` dual
/// passes into a dense `(s + k) × n` Jacobian. The verdict and the message
/// are the same.
pub fn check_or_project_with<S: Scene>(
    scene: &S,
    init: &mut Initial,
    project: bool,
    program: Option<&Compiled>,
) -> Result<Option<InitProjection>, Error> {
    let info = scene.info();
    if info.s() == 0 && info.k() == 0 {
        return Ok(None);
    }
    if let (false, Some(c)) = (project, program) {
        return check(scene, init, Residuals::compiled(c, init), true);
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
    check(scene, init, Residuals::dense(scene, init, p), true)
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
    let r = Residuals::dense(scene, init, Projector::new(scene));
    check(scene, init, r, false)
}

/// What the check reads: `g`, `f`, `ḟ`, and the Euclidean norm of every
/// row of `G` (first `s`) and `F` (last `k`).
struct Residuals {
    g: Vec<f64>,
    f: Vec<f64>,
    f_rate: Vec<f64>,
    norms: Vec<f64>,
}

impl Residuals {
    /// By the scalar passes of a [`Projector`] (a dense Jacobian).
    fn dense<S: Scene>(scene: &S, init: &Initial, mut p: Projector) -> Residuals {
        p.residuals(scene, init.t0, &init.q, &init.qd);
        let cs = &p.cs;
        let norms = (0..cs.s + cs.k).map(|r| cs.row_norm(r)).collect();
        Residuals {
            g: cs.g.clone(),
            f: cs.f.clone(),
            f_rate: cs.f_rate.clone(),
            norms,
        }
    }

    /// From one evaluation of the compiled program (sparse rows). The
    /// constraints do not depend on the field's parameters (C's
    /// multipliers): they are evaluated at zero.
    fn compiled(c: &Compiled, init: &Initial) -> Residuals {
        let mut w = c.workspace::<f64>();
        let p = vec![0.0; c.parameters()];
        c.eval(&mut w, init.t0, &init.q, &init.qd, &p);
        let pc = w.pieces(c);
        let s = pc.g.len();
        let mut norms = vec![0.0; s + pc.f.len()];
        for (&(r, _), v) in pc.pattern.g_jac.iter().zip(pc.g_jac) {
            norms[r as usize] += v * v;
        }
        for (&(r, _), v) in pc.pattern.f_jac.iter().zip(pc.f_jac) {
            norms[s + r as usize] += v * v;
        }
        norms.iter_mut().for_each(|x| *x = x.sqrt());
        Residuals {
            g: pc.g.to_vec(),
            f: pc.f.to_vec(),
            f_rate: pc.f_rate.to_vec(),
            norms,
        }
    }

    /// Largest `|f_i|/‖F_i‖`.
    fn position_distance(&self) -> f64 {
        let s = self.g.len();
        self.f
            .iter()
            .enumerate()
            .map(|(i, f)| f.abs() / self.norms[s + i].max(f64::MIN_POSITIVE))
            .fold(0.0, nan_max)
    }

    /// Largest `|g_i − target_i|/‖G_i‖` and `|ḟ_i|/‖F_i‖` (an empty
    /// `target` means zero).
    fn velocity_distance_to(&self, target: &[f64]) -> f64 {
        let g = self
            .g
            .iter()
            .enumerate()
            .map(|(i, g)| g - target.get(i).copied().unwrap_or(0.0));
        g.chain(self.f_rate.iter().copied())
            .enumerate()
            .map(|(r, v)| v.abs() / self.norms[r].max(f64::MIN_POSITIVE))
            .fold(0.0, nan_max)
    }
}

/// The check of [`check_or_project`], of `g = 0` too if `nonholonomic`.
fn check<S: Scene>(
    scene: &S,
    init: &Initial,
    p: Residuals,
    nonholonomic: bool,
) -> Result<Option<InitProjection>, Error> {
    let info = scene.info();
    let own: Vec<f64> = if nonholonomic {
        Vec::new()
    } else {
        p.g.clone()
    };
    let (pos, v) = (p.position_distance(), p.velocity_distance_to(&own));
    let tol = INIT_TOL * scale(&init.q);
    if pos.is_nan() || pos > tol {
        return Err(Error::OffConstraints {
            level: Level::Positions,
            residuals: info
                .holonomic
                .iter()
                .zip(&p.f)
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
            .zip(&p.g)
            .map(|(g, r)| (g.to_string(), *r))
            .collect();
        residuals.extend(
            info.holonomic
                .iter()
                .zip(&p.f_rate)
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
