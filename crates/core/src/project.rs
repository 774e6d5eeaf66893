//! Projection onto the constraint manifold, in the kinetic-energy metric.
//!
//! Positions: the nearest `q` with `f(q, t) = 0`; velocities: the nearest
//! `q̇` with `g(q, q̇, t) = 0` and `ḟ(q, q̇, t) = 0`, distances measured with the
//! mass matrix `M = ∂²L/∂q̇²` (the velocity projection is then the impulsive
//! action of ideal constraints). Each is a Newton iteration on the KKT system
//!
//! ```text
//! [ M  Cᵀ ] [Δ]   [ 0 ]
//! [ C  0  ] [μ] = [−r ]
//! ```
//!
//! with `C = F` (positions) or `C = [G; F]` (velocities), `M` and `C` taken
//! at the current iterate (Gauss–Newton). When the constraints are linear in
//! the projected variable and `M` does not depend on it (the velocity
//! projection of every linear nonholonomic scene), one step lands on the
//! `M`-nearest point exactly. Otherwise the limit lies on the constraints and
//! is the nearest point to second order in the size of the correction.
//!
//! Used for `--project-init` and for the projection stabilisation of formulation B.

use nalgebra::DMatrix;

use crate::ad::Jet;
use crate::constraints::ConstraintState;
use crate::linalg::{Lu, solve_saddle};
use crate::scene::{Lagrangian, Scene};

/// Newton iterations allowed per projection.
const MAX_ITER: usize = 12;

/// What a projection did.
#[derive(Debug, Clone, PartialEq)]
pub struct Projection {
    /// `max(|g|, |ḟ|)` before and after.
    pub velocity_residual: (f64, f64),
    /// `|f|` before and after.
    pub position_residual: (f64, f64),
    /// Euclidean norm of the change in `q` and in `q̇`.
    pub dq_norm: f64,
    pub dqd_norm: f64,
    pub iterations: usize,
}

/// Workspace for projections of one scene.
#[derive(Debug, Clone)]
pub struct Projector {
    n: usize,
    jet: Jet,
    pub cs: ConstraintState,
    /// KKT matrices and factorisations for positions (`C = F`, size n + k)
    /// and velocities (`C = [G; F]`, size n + s + k).
    kkt_pos: DMatrix<f64>,
    lu_pos: Lu,
    kkt_vel: DMatrix<f64>,
    lu_vel: Lu,
    rhs: Vec<f64>,
    scale: Vec<f64>,
    q0: Vec<f64>,
    qd0: Vec<f64>,
    /// Value of `g` the velocity projection aims at (zero but for
    /// [`Projector::shift_velocity`]).
    g_target: Vec<f64>,
}

/// Which constraints a Newton step enforces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Level {
    Position,
    Velocity,
}

impl Projector {
    pub fn new<S: Scene>(scene: &S) -> Self {
        let info = scene.info();
        let (n, s, k) = (info.n(), info.s(), info.k());
        Projector {
            n,
            jet: Jet::new(n, s.max(k)),
            cs: ConstraintState::new(n, s, k),
            kkt_pos: DMatrix::zeros(n + k, n + k),
            lu_pos: Lu::new(n + k),
            kkt_vel: DMatrix::zeros(n + s + k, n + s + k),
            lu_vel: Lu::new(n + s + k),
            rhs: vec![0.0; n + s + k],
            scale: vec![1.0; n + s + k],
            q0: vec![0.0; n],
            qd0: vec![0.0; n],
            g_target: vec![0.0; s],
        }
    }

    /// Constraint residuals at a state: `(max(|g|, |ḟ|), |f|)`.
    pub fn residuals<S: Scene>(&mut self, scene: &S, t: f64, q: &[f64], qd: &[f64]) -> (f64, f64) {
        self.cs.evaluate(&mut self.jet, scene, t, q, qd);
        (self.cs.velocity_residual(), self.cs.position_residual())
    }

    /// One Newton step at the state last passed to [`Projector::residuals`]:
    /// solves the KKT system and leaves the correction `Δ` in `rhs[..n]`.
    fn newton_step<S: Scene>(
        &mut self,
        scene: &S,
        t: f64,
        q: &[f64],
        qd: &[f64],
        level: Level,
    ) -> Result<(), String> {
        let (n, s, k) = (self.n, self.cs.s, self.cs.k);
        let (kkt, lu, rows) = match level {
            Level::Position => (&mut self.kkt_pos, &mut self.lu_pos, s..s + k),
            Level::Velocity => (&mut self.kkt_vel, &mut self.lu_vel, 0..s + k),
        };
        let size = n + rows.len();
        kkt.fill(0.0);
        self.jet.mass(
            &Lagrangian(scene),
            t,
            q,
            qd,
            &[],
            &mut kkt.view_mut((0, 0), (n, n)),
        );
        self.cs.write_rows(rows, kkt, n);
        let rhs = &mut self.rhs[..size];
        rhs[..n].fill(0.0);
        match level {
            Level::Position => {
                for (a, f) in self.cs.f.iter().enumerate() {
                    rhs[n + a] = -f;
                }
            }
            Level::Velocity => {
                for (a, (g, t)) in self.cs.g.iter().zip(&self.g_target).enumerate() {
                    rhs[n + a] = t - g;
                }
                for (a, r) in self.cs.f_rate.iter().enumerate() {
                    rhs[n + s + a] = -r;
                }
            }
        }
        solve_saddle(kkt, n, lu, &mut self.scale[..size], rhs)
            .map_err(|e| format!("projection KKT system singular: {e}"))
    }

    /// Newton iterations on `q̇` towards `g = g_target, ḟ = 0` (see
    /// [`Projector::project`] for the stopping rule); returns their number.
    fn velocity_loop<S: Scene>(
        &mut self,
        scene: &S,
        t: f64,
        q: &[f64],
        qd: &mut [f64],
        rtol: f64,
    ) -> Result<usize, String> {
        let tol = rtol * qd.iter().fold(1.0f64, |m, x| m.max(x.abs()));
        self.residuals(scene, t, q, qd);
        let mut dist = self.cs.velocity_distance_to(&self.g_target);
        let mut count = 0;
        while dist > tol {
            if count == MAX_ITER {
                return Err(format!(
                    "projection onto the velocity constraints did not converge: distance {dist:.3e} after {MAX_ITER} iterations"
                ));
            }
            self.newton_step(scene, t, q, qd, Level::Velocity)?;
            for (x, d) in qd.iter_mut().zip(&self.rhs[..self.n]) {
                *x += d;
            }
            count += 1;
            self.residuals(scene, t, q, qd);
            let new = self.cs.velocity_distance_to(&self.g_target);
            if new > 0.5 * dist && new <= 1e3 * tol {
                break;
            }
            dist = new;
        }
        Ok(count)
    }

    /// Moves `q̇` (nearest in the kinetic-energy metric, `q` fixed) so that
    /// `g(q, q̇, t) = target` and `ḟ = 0`: the initial constraint violation of
    /// the added-mass realisation. Same stopping rule as [`Projector::project`].
    pub fn shift_velocity<S: Scene>(
        &mut self,
        scene: &S,
        t: f64,
        q: &[f64],
        qd: &mut [f64],
        target: &[f64],
        rtol: f64,
    ) -> Result<Projection, String> {
        self.qd0.copy_from_slice(qd);
        let (v_before, p) = self.residuals(scene, t, q, qd);
        self.g_target.copy_from_slice(target);
        let iterations = self.velocity_loop(scene, t, q, qd, rtol);
        self.g_target.fill(0.0);
        let iterations = iterations?;
        let dqd_norm = qd
            .iter()
            .zip(&self.qd0)
            .map(|(x, y)| (x - y).powi(2))
            .sum::<f64>()
            .sqrt();
        Ok(Projection {
            velocity_residual: (v_before, self.cs.velocity_residual()),
            position_residual: (p, p),
            dq_norm: 0.0,
            dqd_norm,
            iterations,
        })
    }

    /// Projects `q` onto `f = 0` (if the scene has holonomic constraints) and
    /// then `q̇` onto `g = 0, ḟ = 0`, until the distances to the constraints
    /// (see [`ConstraintState::position_distance`]) are at most
    /// `rtol·max(1, |q|∞)` and `rtol·max(1, |q̇|∞)`, or stop improving within
    /// a thousand times that (the round-off floor).
    pub fn project<S: Scene>(
        &mut self,
        scene: &S,
        t: f64,
        q: &mut [f64],
        qd: &mut [f64],
        rtol: f64,
    ) -> Result<Projection, String> {
        let scale = |v: &[f64]| v.iter().fold(1.0f64, |m, x| m.max(x.abs()));
        self.q0.copy_from_slice(q);
        self.qd0.copy_from_slice(qd);
        let (v_before, p_before) = self.residuals(scene, t, q, qd);
        let mut iterations = 0;

        let tol = rtol * scale(q);
        let mut dist = self.cs.position_distance();
        let mut count = 0;
        while dist > tol {
            if count == MAX_ITER {
                return Err(format!(
                    "projection onto f = 0 did not converge: distance {dist:.3e} after {MAX_ITER} iterations"
                ));
            }
            self.newton_step(scene, t, q, qd, Level::Position)?;
            for (x, d) in q.iter_mut().zip(&self.rhs[..self.n]) {
                *x += d;
            }
            iterations += 1;
            count += 1;
            self.residuals(scene, t, q, qd);
            let new = self.cs.position_distance();
            if new > 0.5 * dist && new <= 1e3 * tol {
                break;
            }
            dist = new;
        }

        iterations += self.velocity_loop(scene, t, q, qd, rtol)?;
        let res = self.cs.velocity_residual();
        let (v_after, p_after) = (res, self.cs.position_residual());
        let dist = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        Ok(Projection {
            velocity_residual: (v_before, v_after),
            position_residual: (p_before, p_after),
            dq_norm: dist(q, &self.q0),
            dqd_norm: dist(qd, &self.qd0),
            iterations,
        })
    }
}
