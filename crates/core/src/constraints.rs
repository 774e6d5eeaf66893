//! The constraint pieces of a scene at one state, by automatic differentiation.

use nalgebra::DMatrix;

use crate::ad::Jet;
use crate::scene::{Holonomic, Nonholonomic, Scalar, Scene};

/// Nonholonomic `g` (s rows) and holonomic `f` (k rows) with the
/// derivatives the formulations need, evaluated at one `(t, q, q̇)`.
///
/// `jac` stacks the velocity Jacobians of the velocity-level constraints
/// `[g; ḟ]`: rows `0..s` hold `G = ∂g/∂q̇`, rows `s..s+k` hold `F = ∂f/∂q = ∂ḟ/∂q̇`.
#[derive(Debug, Clone)]
pub struct ConstraintState<T: Scalar = f64> {
    pub s: usize,
    pub k: usize,
    /// `g(q, q̇, t)`.
    pub g: Vec<T>,
    /// `ġ` without its `q̈` term: `(∂g/∂q) q̇ + ∂g/∂t`.
    pub g_rate0: Vec<T>,
    /// `f(q, t)`.
    pub f: Vec<T>,
    /// `ḟ = F q̇ + ∂f/∂t`.
    pub f_rate: Vec<T>,
    /// `f̈` without its `q̈` term: `(d/dt F) q̇ + d/dt ∂f/∂t`.
    pub f_accel0: Vec<T>,
    /// `[G; F]`, `(s + k) × n`.
    pub jac: DMatrix<T>,
}

impl<T: Scalar> ConstraintState<T> {
    pub fn new(n: usize, s: usize, k: usize) -> Self {
        ConstraintState {
            s,
            k,
            g: vec![T::from(0.0); s],
            g_rate0: vec![T::from(0.0); s],
            f: vec![T::from(0.0); k],
            f_rate: vec![T::from(0.0); k],
            f_accel0: vec![T::from(0.0); k],
            jac: DMatrix::from_element(s + k, n, T::from(0.0)),
        }
    }

    /// Evaluates every piece the scene has (nothing for absent ones).
    pub fn evaluate<S: Scene>(&mut self, jet: &mut Jet<T>, scene: &S, t: T, q: &[T], qd: &[T]) {
        self.evaluate_nonholonomic(jet, scene, t, q, qd);
        self.evaluate_holonomic(jet, scene, t, q, qd);
    }

    /// `g`, `G` and `ġ₀` only (nothing if the scene has no `g`).
    pub fn evaluate_nonholonomic<S: Scene>(
        &mut self,
        jet: &mut Jet<T>,
        scene: &S,
        t: T,
        q: &[T],
        qd: &[T],
    ) {
        if self.s > 0 {
            let n = q.len();
            jet.velocity_jacobian(
                &Nonholonomic(scene),
                t,
                q,
                qd,
                &mut self.g,
                &mut self.jac.view_mut((0, 0), (self.s, n)),
                &mut self.g_rate0,
            );
        }
    }

    /// `f`, `F`, `ḟ` and `f̈₀` only (nothing if the scene has no `f`).
    pub fn evaluate_holonomic<S: Scene>(
        &mut self,
        jet: &mut Jet<T>,
        scene: &S,
        t: T,
        q: &[T],
        qd: &[T],
    ) {
        if self.k > 0 {
            let n = q.len();
            jet.position_jacobian(
                &Holonomic(scene),
                t,
                q,
                qd,
                &mut self.f,
                &mut self.jac.view_mut((self.s, 0), (self.k, n)),
                &mut self.f_rate,
                &mut self.f_accel0,
            );
        }
    }

    /// Rows `rows` of `[G; F]` into the constraint block of a saddle-point
    /// matrix `[M Cᵀ; C 0]` (primal block of size `n`), from row and column
    /// `at`, and into its transpose.
    pub fn write_rows(&self, rows: std::ops::Range<usize>, a: &mut DMatrix<T>, at: usize) {
        let n = self.jac.ncols();
        for (p, r) in rows.enumerate() {
            for j in 0..n {
                let c = self.jac[(r, j)];
                a[(at + p, j)] = c;
                a[(j, at + p)] = c;
            }
        }
    }

    /// Largest velocity-level residual `max(|g|, |ḟ|)` (of the real parts).
    pub fn velocity_residual(&self) -> f64 {
        self.g
            .iter()
            .chain(&self.f_rate)
            .fold(0.0, |m, v| nan_max(m, v.re().abs()))
    }

    /// Largest position-level residual `|f|` (of the real parts).
    pub fn position_residual(&self) -> f64 {
        self.f.iter().fold(0.0, |m, v| nan_max(m, v.re().abs()))
    }

    /// Euclidean norm of row `r` of `[G; F]` (real parts).
    pub(crate) fn row_norm(&self, r: usize) -> f64 {
        (0..self.jac.ncols())
            .map(|j| self.jac[(r, j)].re().powi(2))
            .sum::<f64>()
            .sqrt()
    }

    /// Largest distance, in velocity units, from the velocity-level
    /// constraints: `|g_i|/‖G_i‖` and `|ḟ_i|/‖F_i‖` (exact for constraints
    /// linear in q̇). Independent of how each constraint is scaled.
    pub fn velocity_distance(&self) -> f64 {
        self.velocity_distance_to(&[])
    }

    /// [`ConstraintState::velocity_distance`] from `g = target` instead of
    /// `g = 0` (an empty `target` means zero).
    pub fn velocity_distance_to(&self, target: &[f64]) -> f64 {
        let s = self.s;
        (0..s + self.k)
            .map(|r| {
                let v = if r < s {
                    self.g[r].re() - target.get(r).copied().unwrap_or(0.0)
                } else {
                    self.f_rate[r - s].re()
                };
                v.abs() / self.row_norm(r).max(f64::MIN_POSITIVE)
            })
            .fold(0.0, nan_max)
    }

    /// Largest distance, in coordinate units, from the holonomic constraints:
    /// `|f_i|/‖F_i‖` (first-order distance to the surface `f_i = 0`).
    pub fn position_distance(&self) -> f64 {
        (0..self.k)
            .map(|i| self.f[i].re().abs() / self.row_norm(self.s + i).max(f64::MIN_POSITIVE))
            .fold(0.0, nan_max)
    }
}

/// `max` that propagates NaN (a NaN residual must not be hidden).
pub fn nan_max(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else {
        a.max(b)
    }
}

/// The Jacobian, with respect to `(q, q̇)`, of the functions whose common
/// zero set is the constraint manifold in phase space: `f` (rows `0..k`),
/// `ḟ = F q̇ + ∂f/∂t` (rows `k..2k`) and `g` (rows `2k..2k+s`), a
/// `(2k + s) × 2n` matrix (columns `q` then `q̇`).
///
/// Positions of `f` by hyper-dual passes seeded with `e_j` and with the
/// motion `(q̇, 1)` in `(q, t)`, which give `∂f/∂q_j` and `∂ḟ/∂q_j` at once
/// (`∂ḟ/∂q̇_j = ∂f/∂q_j`); `g` by one dual pass per column. Used once per
/// linearisation, not in right-hand sides.
pub fn invariant_jacobian<S: Scene>(scene: &S, t: f64, q: &[f64], qd: &[f64]) -> DMatrix<f64> {
    use num_dual::{Dual64, HyperDual64};
    let info = scene.info();
    let (n, s, k) = (info.n(), info.s(), info.k());
    let mut d = DMatrix::zeros(2 * k + s, 2 * n);
    if k > 0 {
        let mut qh = vec![HyperDual64::from_re(0.0); n];
        let mut fh = vec![HyperDual64::from_re(0.0); k];
        let th = HyperDual64::new(t, 0.0, 1.0, 0.0);
        for j in 0..n {
            for i in 0..n {
                qh[i] = HyperDual64::new(q[i], if i == j { 1.0 } else { 0.0 }, qd[i], 0.0);
            }
            scene.holonomic(th, &qh, &mut fh);
            for r in 0..k {
                d[(r, j)] = fh[r].eps1;
                d[(k + r, j)] = fh[r].eps1eps2;
                d[(k + r, n + j)] = fh[r].eps1;
            }
        }
    }
    if s > 0 {
        let mut qx = vec![Dual64::from_re(0.0); n];
        let mut qdx = vec![Dual64::from_re(0.0); n];
        let mut gx = vec![Dual64::from_re(0.0); s];
        for j in 0..2 * n {
            for i in 0..n {
                qx[i] = Dual64::new(q[i], if j == i { 1.0 } else { 0.0 });
                qdx[i] = Dual64::new(qd[i], if j == n + i { 1.0 } else { 0.0 });
            }
            scene.nonholonomic(Dual64::from_re(t), &qx, &qdx, &mut gx);
            for r in 0..s {
                d[(2 * k + r, j)] = gx[r].eps;
            }
        }
    }
    d
}
