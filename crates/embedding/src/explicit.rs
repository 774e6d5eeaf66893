//! A's explicit form `ż = (z₁, z₂, z₃, w(z))`, `w = q_I⁗` from the
//! derivative array, and `q̇_c = φ_c(z)` for the cyclic dependent
//! coordinates (the solve is [`crate::ode::Reduction`]), for RK4,
//! DOPRI5 and DOP853 (Radau integrates the implicit form).
//!
//! Option `stab = projection` moves `q⃛` back onto A's hidden constraints
//! after every accepted step. The guard stops the run at the embedding
//! map's singular set, as in the implicit form, or earlier, where `q⁗` is
//! no longer resolved to [`ODE_RESOLUTION`] (the derivative array's
//! round-off grows towards the singular set), before its solve would fail.

use nonholo_core::Scene;
use nonholo_core::complex::C64;
use nonholo_core::integrate::{Method, OdeSystem, Options, SystemError};
use nonholo_core::model::{Crossed, Crossing, GapFill};
use nonholo_core::scene::EmbeddingInfo;

use crate::crossing::{APPROACH_FACTOR, CROSS_RESOLUTION, Continuation, Stop, cross, crossed};
use crate::ode::{ODE_RESOLUTION, Reduction, ReductionStats, Resolution};
use crate::shared::Shared;

/// A's explicit form bound to a scene.
pub struct Explicit<S: Scene> {
    pub shared: Shared<S>,
    /// The solve for `q⁗` and its warm start.
    reduction: Reduction,
    /// `stab = projection`.
    project_hidden: bool,
    /// `(t, before, after)` hidden-constraint residuals per accepted step,
    /// if asked for ([`Explicit::record_hidden`]).
    hidden_log: Option<Vec<[f64; 3]>>,
    /// What the last guard evaluation that was `<= 0` measured: the
    /// integrator asks for the reason at that very state (a contract of
    /// `OdeSystem::guard_reason`), and the solve behind it, warm-started,
    /// could not be repeated bitwise.
    stop_record: Option<Result<Resolution, String>>,
    /// How the run goes on past the singular set.
    continuation: Continuation,
    /// Crossings made in this run.
    crossings: usize,
    /// The solve along paths in complex time (built at the first crossing).
    complex: Option<Box<Reduction<C64>>>,
    /// While the motion approaches the singular set (the speed falls): the
    /// resolution of `q⁗` at which the real integration stops for a
    /// crossing — [`CROSS_RESOLUTION`], or [`APPROACH_FACTOR`] times the
    /// resolution where the approach began if that is worse.
    approach: Option<f64>,
}

/// The error of a failed solve for `q⁗`.
fn unsolved(msg: String) -> SystemError {
    SystemError::new(format!(
        "the derivative array of (19) could not be solved for q⁗: {msg}"
    ))
}

impl<S: Scene> Explicit<S> {
    pub fn new(shared: Shared<S>, project_hidden: bool, continuation: Continuation) -> Self {
        Explicit {
            reduction: Reduction::new(shared.m),
            shared,
            project_hidden,
            hidden_log: None,
            stop_record: None,
            continuation,
            crossings: 0,
            complex: None,
            approach: None,
        }
    }

    /// Whether to evaluate the derivative array by traced programs (the
    /// default) or by dual passes over the jets
    /// ([`Reduction::set_traced`]): the same solve to round-off.
    pub fn set_traced(&mut self, on: bool) {
        self.reduction.set_traced(on);
    }

    /// Why the derivative array could not be traced (`None`: it was, or
    /// no solve has been made yet, or tracing is off).
    pub fn trace_refused(&self) -> Option<&str> {
        self.reduction.trace_refused()
    }

    /// Follows the map's branch nearest to `near` from now on.
    pub fn follow_from(&mut self, near: &[f64]) {
        self.reduction.set_branch(near);
    }

    /// The resolution of `q⁗` at which the guard stops the real integration:
    /// earlier when the run is to go on along a complex path, so that the
    /// path passes where the equations are well resolved.
    fn limit(&self) -> f64 {
        match (self.continuation, self.approach) {
            (Continuation::None, _) | (_, None) => ODE_RESOLUTION,
            (_, Some(limit)) => limit.min(ODE_RESOLUTION),
        }
    }

    /// After an accepted step of a run that continues: whether the motion
    /// approaches the singular set (`|v|` falls: `v · v̇ < 0`), and the
    /// resolution at which it will leave the real axis if so, fixed where
    /// the approach begins (so that the guard is continuous along it).
    fn watch_approach(&mut self, t: f64, y: &[f64]) -> Result<(), SystemError> {
        let m = self.shared.m;
        let falling = (0..m).map(|k| y[m + k] * y[2 * m + k]).sum::<f64>() < 0.0;
        if !falling {
            self.approach = None;
        } else if self.approach.is_none() {
            let rho = self.resolution(t, y)?.rho;
            self.approach = Some(CROSS_RESOLUTION.max(APPROACH_FACTOR * rho));
        }
        Ok(())
    }

    /// Starts from a consistent completion `d = (q_I⁽⁰⁾ … q_I⁽⁶⁾)`: its `u`
    /// is the first warm start, and the rank of `∂D/∂u` is fixed here.
    pub fn reset(&mut self, t0: f64, d: &[f64]) -> Result<(), String> {
        let sh = &self.shared;
        self.reduction.reset(&*sh.scene, &sh.e, t0, d)?;
        if let Some(log) = self.hidden_log.as_mut() {
            log.clear();
        }
        self.stop_record = None;
        self.crossings = 0;
        self.approach = None;
        Ok(())
    }

    /// `q_I⁗ = w(z)` at `(t, z)` (see [`crate::ode`]): the derivative array
    /// `[E; Ė; Ë] = 0` solved for `(q⁗, q⁽⁵⁾, q⁽⁶⁾)`, warm-started from the
    /// previous solve.
    pub fn fourth_derivative(&mut self, t: f64, z: &[f64]) -> Result<&[f64], SystemError> {
        let sh = &self.shared;
        self.reduction
            .fourth(&*sh.scene, &sh.e, t, z)
            .map_err(unsolved)
    }

    /// How well `q⁗ = w(z)` is resolved at `(t, z)` (see [`Resolution`]);
    /// the explicit form stops where `rho` reaches [`ODE_RESOLUTION`].
    pub fn resolution(&mut self, t: f64, z: &[f64]) -> Result<Resolution, SystemError> {
        let sh = &self.shared;
        self.reduction
            .resolution(&*sh.scene, &sh.e, t, z)
            .map_err(unsolved)
    }

    /// How far `z` is from A's hidden constraints: the derivative array's
    /// residual left by the least-squares solve, relative to the terms that
    /// cancel in each row ([`Reduction::hidden_residual`]). Round-off level
    /// on the constraint manifold. A diagnostic, not for hot paths.
    pub fn hidden_residual(&mut self, t: f64, z: &[f64]) -> Result<f64, SystemError> {
        let sh = &self.shared;
        self.reduction
            .hidden_residual(&*sh.scene, &sh.e, t, z)
            .map_err(SystemError::new)
    }

    /// Work counters since the last [`Explicit::reset`].
    pub fn reduction_stats(&self) -> ReductionStats {
        self.reduction.stats()
    }

    /// Whether to record, after every accepted step, the hidden-constraint
    /// residual before and after the projection (see
    /// [`Explicit::hidden_log`]). Costs a full derivative-array Jacobian per
    /// step; for studies of the drift, off by default. Clears the log.
    pub fn record_hidden(&mut self, on: bool) {
        self.hidden_log = on.then(Vec::new);
    }

    /// `(t, before, after)` per accepted step, where `before` is
    /// [`Explicit::hidden_residual`] of the state the integrator produced and
    /// `after` that of the state it continues from (after the projection if
    /// `stab = projection`, else the same).
    pub fn hidden_log(&self) -> &[[f64; 3]] {
        self.hidden_log.as_deref().unwrap_or(&[])
    }

    /// The guard from its two parts: the singular set's signed distance (if
    /// the scene has one) and the resolution margin
    /// `singular_tol · ln(ODE_RESOLUTION / ρ)` (`−singular_tol` where the
    /// solve fails), in the units of the first. The smaller counts; NaN
    /// stops the run.
    fn combined_guard(
        &self,
        singular: Option<f64>,
        resolution: &Result<Resolution, String>,
    ) -> f64 {
        let tol = self.shared.guard.tol;
        let margin = match resolution {
            Ok(r) => tol * (self.limit() / r.rho).ln(),
            Err(_) => -tol,
        };
        match singular {
            Some(g) if g.is_nan() || g < margin => g,
            _ => margin,
        }
    }
}

impl<S: Scene> OdeSystem for Explicit<S> {
    fn dim(&self) -> usize {
        self.shared.dim()
    }

    /// Stages beyond the singular set are refused as in the implicit form;
    /// so is a state where the derivative array cannot be solved.
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let m = self.shared.m;
        self.shared.check_stage(t, y)?;
        if !y.iter().all(|v| v.is_finite()) {
            return Err(self.shared.not_finite(t, y));
        }
        dy[..3 * m].copy_from_slice(&y[m..4 * m]);
        let w = self.fourth_derivative(t, y)?;
        dy[3 * m..4 * m].copy_from_slice(w);
        if self.shared.c > 0 {
            dy[4 * m..].copy_from_slice(self.shared.cyclic_rates(t, y));
        }
        if dy.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(self.shared.not_finite(t, y))
        }
    }

    /// With `stab = projection`, moves `q⃛` back onto the hidden constraints
    /// (`q, q̇, q̈` fixed) and says so; then records the diagnostics and
    /// promotes the guard's reference direction, as the implicit form does.
    fn after_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        let before = match self.hidden_log {
            Some(_) => Some(self.hidden_residual(t, y)?),
            None => None,
        };
        let mut moved = false;
        if self.project_hidden {
            let sh = &self.shared;
            let change = self
                .reduction
                .project(&*sh.scene, &sh.e, t, y)
                .map_err(SystemError::new)?;
            moved = change > 0.0;
        }
        if let Some(before) = before {
            let after = if moved {
                self.hidden_residual(t, y)?
            } else {
                before
            };
            if let Some(log) = self.hidden_log.as_mut() {
                log.push([t, before, after]);
            }
        }
        self.shared.accept_state(t, y);
        if self.shared.follow_branch() {
            self.reduction.set_branch(&self.shared.near);
        }
        if self.continuation != Continuation::None {
            self.watch_approach(t, y)?;
        }
        Ok(moved)
    }

    /// The singular set's guard and the resolution of `q⁗`
    /// ([`Explicit::resolution`]): the run stops where the first of them
    /// reaches zero, so that it ends by design before the round-off of the
    /// derivative array keeps `q⁗` from being solved for. At an accepted
    /// state the solve is the one the right-hand side made there (after a
    /// projection) or makes next (RK4's first stage), and is not repeated.
    /// No allocation unless the solve fails.
    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        let sh = &self.shared;
        let resolution = self.reduction.resolution(&*sh.scene, &sh.e, t, y);
        let singular = self.shared.guard_value(t, y);
        let g = self.combined_guard(singular, &resolution);
        if g.is_nan() || g <= 0.0 {
            self.stop_record = Some(resolution);
        }
        Some(g)
    }

    /// Names the guard that fired at the stop: the singular set (as in the
    /// implicit form), or the resolution of `q⁗`, with `ρ` and its two
    /// parts, `|r|`, the limit and the extrapolated zero of the guard.
    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        let resolution = match self.stop_record.take() {
            Some(r) => r,
            None => {
                let sh = &self.shared;
                self.reduction.resolution(&*sh.scene, &sh.e, t, y)
            }
        };
        let singular = self.shared.guard_value(t, y);
        if singular.is_some_and(|g| g <= self.combined_guard(None, &resolution)) {
            return self.shared.guard_text(t, y);
        }
        let measured = match resolution {
            Ok(r) => format!(
                "to {:.2e} relative (conditioning {:.2e}, observed {})",
                r.rho,
                r.conditioning,
                r.observed
                    .map_or_else(|| "not measured".to_string(), |o| format!("{o:.2e}"))
            ),
            Err(msg) => format!("no longer ({msg})"),
        };
        let (size, crossing) = self.shared.approach(t, y);
        let sh = &self.shared;
        format!(
            "the explicit form reached its resolution limit: the derivative array [E; Ė; Ë] \
             determines q⁗ only {measured} here, limit {:.0e}; its terms grow like \
             powers of the turning rate and cancel towards the singular set of the embedding map \
             {} — {} (|r| = {size:.3e}, singular_tol = {:.1e}{crossing}); the implicit form \
             (radau5) runs on to singular_tol",
            self.limit(),
            sh.e.formula,
            sh.e.singular_set,
            sh.guard.tol
        )
    }
}

/// Past a stop of its guard: along a half circle in complex time
/// ([`crate::crossing`]), then on the real axis again from where it
/// returns, on the branch of the map that `continuation` says.
impl<S: Scene> Crossing for Explicit<S> {
    fn cross(
        &mut self,
        t: f64,
        y: &[f64],
        method: Method,
        opts: &Options,
    ) -> Result<Crossed, SystemError> {
        let number = self.crossings + 1;
        let formula = self.shared.e.formula;
        let fail = |msg: String| {
            SystemError::new(format!(
                "crossing {number} of the singular set of the embedding map {formula} from \
                 t = {t}: {msg}"
            ))
        };
        let m = self.shared.m;
        self.fourth_derivative(t, y).map_err(|e| fail(e.message))?;
        let u = self.reduction.state()[4 * m..].to_vec();
        let complex = self
            .complex
            .get_or_insert_with(|| Box::new(Reduction::new(m)));
        let sh = &self.shared;
        let near = if sh.near.is_empty() {
            sh.e.dependent.iter().map(|&i| sh.q[i]).collect()
        } else {
            sh.near.clone()
        };
        let across = cross(
            Stop {
                scene: &*sh.scene,
                e: &sh.e,
                t,
                z: y,
                u: &u,
                near: &near,
                number,
            },
            complex,
            method,
            opts,
        )
        .map_err(fail)?;
        // Resume on the branch the continuation says: q⃛ onto its hidden
        // constraints (a round-off change on the analytic branch; on the
        // map's principal branch the constraints themselves may differ).
        let t_b = across.t;
        self.shared.near = match self.continuation {
            Continuation::Map => Vec::new(),
            _ => across.near.clone(),
        };
        self.reduction.set_branch(&self.shared.near);
        let mut across = across;
        if self.continuation == Continuation::Map && self.shared.c > 0 {
            // The map's principal branch from the stop on: its cyclic rates
            // (the disk's |v|/R), not the analytic ones the path carried.
            let sh = &self.shared;
            let gap = principal_cyclic(
                sh.scene.clone(),
                sh.e,
                std::mem::replace(&mut across.gap, Box::new(|_, _| {})),
                (t, across.record.t_singular),
                y[4 * m..].to_vec(),
            );
            let mut at_b = across.z.clone();
            gap(t_b, &mut at_b);
            across.z[4 * m..].copy_from_slice(&at_b[4 * m..]);
            across.gap = gap;
        }
        let mut z = across.z.clone();
        let change = {
            let sh = &self.shared;
            self.reduction
                .project(&*sh.scene, &sh.e, t_b, &mut z[..4 * m])
                .map_err(fail)?
        };
        let d = self.reduction.state().to_vec();
        {
            let sh = &self.shared;
            self.reduction
                .reset(&*sh.scene, &sh.e, t_b, &d)
                .map_err(fail)?;
        }
        self.shared.resume(t_b, &z);
        self.approach = None;
        let rho = self.resolution(t_b, &z).map_err(|e| fail(e.message))?.rho;
        if rho.is_nan() || rho >= self.limit() {
            return Err(fail(format!(
                "where the path returns, t = {t_b}, q⁗ is resolved only to {rho:.2e}, not \
                 better than where the real integration stopped ({:.0e})",
                self.limit()
            )));
        }
        self.crossings = number;
        across.z = z;
        Ok(crossed(across, change))
    }
}

/// The gap of a crossing with the cyclic coordinates on the map's principal
/// branch: `q_c(t) = q_c(t_a) + ∫ φ_c` from the stop `t_a`, `φ_c` evaluated
/// at the gap's own `(q_I, q̇_I)` without a branch reference, by
/// Gauss–Legendre quadrature on each side of the singular instant `t*`
/// (where the principal branch's rate has a kink, the disk's `|v|/R`); the
/// other components as `gap` gives them.
fn principal_cyclic<S: Scene>(
    scene: std::sync::Arc<S>,
    e: EmbeddingInfo,
    gap: GapFill,
    (t_a, t_s): (f64, f64),
    start: Vec<f64>,
) -> GapFill {
    let m = e.independent.len();
    let (nodes, weights) = nonholo_core::quadrature::gauss_legendre(GAP_QUADRATURE);
    Box::new(move |t, out| {
        gap(t, out);
        let mut tmp = vec![0.0; out.len()];
        let (mut dep, mut rates) = (vec![0.0; e.dependent.len()], vec![0.0; start.len()]);
        let mut integral = start.clone();
        let pieces = [(t_a, t.min(t_s)), (t_s, t)];
        for (a, b) in pieces.into_iter().filter(|(a, b)| b > a) {
            let (mid, half) = ((a + b) / 2.0, (b - a) / 2.0);
            for (x, w) in nodes.iter().zip(&weights) {
                let tau = mid + half * x;
                gap(tau, &mut tmp);
                crate::elo::cyclic_rates(
                    &*scene,
                    &e,
                    tau,
                    &tmp[..m],
                    &tmp[m..2 * m],
                    &[],
                    &mut dep,
                    &mut rates,
                );
                for (acc, r) in integral.iter_mut().zip(&rates) {
                    *acc += half * w * r;
                }
            }
        }
        out[4 * m..].copy_from_slice(&integral);
    })
}

/// Nodes of the Gauss–Legendre rule for a gap's cyclic coordinates: exact
/// for polynomials of degree 39 on each side of the singular instant.
const GAP_QUADRATURE: usize = 20;
