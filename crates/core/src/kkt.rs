//! The constrained-acceleration KKT system shared by formulations B and C.
//!
//! For a scalar field `ℓ` (B: `L`; C: `L + λᵀg`) with `M_ℓ = ∂²ℓ/∂q̇²` and
//! `Q_ℓ`, and the scene's constraints differentiated to acceleration level:
//!
//! ```text
//! [ M_ℓ  Gᵀ  Fᵀ ] [ q̈  ]   [ Q_ℓ               ]
//! [ G    0   0  ] [ μ_g ] = [ −ġ₀ − 2α g        ]
//! [ F    0   0  ] [ μ_f ]   [ −f̈₀ − 2α ḟ − β² f ]
//! ```
//!
//! B reads `μ = (−λ, −ν)`; C reads `μ_g = λ̇` and `μ_f = −ν`. The gains are
//! those of Baumgarte stabilisation, zero otherwise. The matrix is
//! equilibrated (so that singularity is judged independently of units), then
//! factorised by LU with partial pivoting, in a reused workspace; over
//! `T = Dual64` the same solve yields directional derivatives (Jacobian
//! columns, time derivatives).

use nalgebra::DMatrix;
use nonholo_integrate::SystemError;
use num_dual::Dual64;

use crate::ad::Jet;
use crate::constraints::ConstraintState;
use crate::linalg::{Lu, solve_saddle};
use crate::scene::{Scalar, ScalarField, Scene};
use crate::stab::Stabilisation;

/// How the rows of the nonholonomic constraints `g` enter the system.
///
/// * `Ideal`: `G q̈ = −ġ₀ − 2α g` (B, C: the constraint holds).
/// * `Compliant(c)`: `G q̈ − c μ_g = −ġ₀`, the constraint with compliance
///   `c = 1/N` (the added-mass realisation carrying `λ = N g`, `μ_g = λ̇`).
/// * `Absent`: no constraint row (an identity block, `μ_g = 0`); `g` acts
///   only through the field `ℓ` (the added-mass realisation written
///   directly, `ℓ = L + (N/2) gᵀg`), so `g` and `G` are not evaluated.
/// * `Viscous(k)`: no constraint row; the viscous force `−k Gᵀ g` joins the
///   right-hand side (the viscous realisation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GRows {
    Ideal,
    Compliant(f64),
    Absent,
    Viscous(f64),
}

/// Workspace of the KKT solve over base scalar `T`.
#[derive(Debug, Clone)]
pub struct Kkt<T: Scalar = f64> {
    n: usize,
    pub jet: Jet<T>,
    pub cs: ConstraintState<T>,
    matrix: DMatrix<T>,
    lu: Lu,
    /// Equilibration of the last solve (see [`crate::linalg::equilibrate`]).
    scale: Vec<f64>,
    /// Right-hand side, then solution `(q̈, μ_g, μ_f)`.
    pub sol: Vec<T>,
}

impl<T: Scalar> Kkt<T> {
    pub fn new(n: usize, s: usize, k: usize) -> Self {
        Kkt {
            n,
            jet: Jet::new(n, s.max(k)),
            cs: ConstraintState::new(n, s, k),
            matrix: DMatrix::from_element(n + s + k, n + s + k, T::from(0.0)),
            lu: Lu::new(n + s + k),
            scale: vec![1.0; n + s + k],
            sol: vec![T::from(0.0); n + s + k],
        }
    }

    /// `q̈` of the last solve.
    pub fn qdd(&self) -> &[T] {
        &self.sol[..self.n]
    }

    /// `(μ_g, μ_f)` of the last solve.
    pub fn mu(&self) -> &[T] {
        &self.sol[self.n..]
    }

    /// Assembles and solves the system at `(t, q, q̇)` for the field `ell`
    /// with parameters `p`; `what` names the formulation in messages.
    #[allow(clippy::too_many_arguments)]
    pub fn solve<F: ScalarField, S: Scene>(
        &mut self,
        ell: &F,
        p: &[T],
        scene: &S,
        stab: Stabilisation,
        t: T,
        q: &[T],
        qd: &[T],
        what: &str,
    ) -> Result<(), SystemError> {
        self.solve_rows(ell, p, scene, stab, GRows::Ideal, t, q, qd, what)
    }

    /// [`Kkt::solve`] with the rows of `g` entering as `rows` says.
    #[allow(clippy::too_many_arguments)]
    pub fn solve_rows<F: ScalarField, S: Scene>(
        &mut self,
        ell: &F,
        p: &[T],
        scene: &S,
        stab: Stabilisation,
        rows: GRows,
        t: T,
        q: &[T],
        qd: &[T],
        what: &str,
    ) -> Result<(), SystemError> {
        let n = self.n;
        let (s, k) = (self.cs.s, self.cs.k);
        self.matrix.fill(T::from(0.0));
        self.jet.mass_and_force(
            ell,
            t,
            q,
            qd,
            p,
            &mut self.matrix.view_mut((0, 0), (n, n)),
            &mut self.sol[..n],
        );
        let (alpha, beta) = stab.gains();
        if s > 0 {
            // `g` and `G` are needed unless `g` enters through `ℓ` alone.
            if rows != GRows::Absent {
                self.cs
                    .evaluate_nonholonomic(&mut self.jet, scene, t, q, qd);
            }
            match rows {
                GRows::Ideal => {
                    self.cs.write_rows(0..s, &mut self.matrix, n);
                    for i in 0..s {
                        self.sol[n + i] = -self.cs.g_rate0[i] - self.cs.g[i] * (2.0 * alpha);
                    }
                }
                GRows::Compliant(c) => {
                    self.cs.write_rows(0..s, &mut self.matrix, n);
                    for i in 0..s {
                        self.matrix[(n + i, n + i)] = T::from(-c);
                        self.sol[n + i] = -self.cs.g_rate0[i];
                    }
                }
                GRows::Absent | GRows::Viscous(_) => {
                    if let GRows::Viscous(gain) = rows {
                        // The friction force `−k Gᵀ g` joins `Q`.
                        for i in 0..s {
                            for j in 0..n {
                                self.sol[j] -= self.cs.jac[(i, j)] * self.cs.g[i] * gain;
                            }
                        }
                    }
                    // No constraint row: `μ_g = 0` from an identity block.
                    for i in 0..s {
                        self.matrix[(n + i, n + i)] = T::from(1.0);
                        self.sol[n + i] = T::from(0.0);
                    }
                }
            }
        }
        if k > 0 {
            self.cs.evaluate_holonomic(&mut self.jet, scene, t, q, qd);
            self.cs.write_rows(s..s + k, &mut self.matrix, n + s);
            for i in 0..k {
                self.sol[n + s + i] = -self.cs.f_accel0[i]
                    - self.cs.f_rate[i] * (2.0 * alpha)
                    - self.cs.f[i] * (beta * beta);
            }
        }
        solve_saddle(
            &mut self.matrix,
            n,
            &mut self.lu,
            &mut self.scale,
            &mut self.sol,
        )
        .map_err(|e| {
            SystemError::new(format!(
                "KKT system of {what} singular ({e}): constraints dependent, \
                 or the kinetic energy degenerate on the admissible velocities"
            ))
        })?;
        Ok(())
    }
}

impl Kkt<Dual64> {
    /// `∂f/∂y` into `jac` (row-major, `dim × dim`, `dim = y.len()`) for a
    /// right-hand side `f(y) = (q̇, q̈, μ_g[..lambda_rows])` of
    /// `y = (q, q̇, λ)` with `λ` of length `lambda_rows` (0: `y = (q, q̇)`):
    /// `∂q̇/∂q̇ = I`, then per column `j` one dual pass of `solve` — which
    /// solves this system at its dual `y` — seeded with `ẏ = e_j` in `y_dual`.
    pub fn jacobian<F>(
        &mut self,
        y: &[f64],
        y_dual: &mut [Dual64],
        lambda_rows: usize,
        jac: &mut [f64],
        mut solve: F,
    ) -> Result<(), SystemError>
    where
        F: FnMut(&mut Self, &[Dual64]) -> Result<(), SystemError>,
    {
        let n = self.n;
        let dim = y.len();
        debug_assert_eq!(dim, 2 * n + lambda_rows);
        jac.fill(0.0);
        for i in 0..n {
            jac[i * dim + n + i] = 1.0;
        }
        for j in 0..dim {
            for (d, &v) in y_dual.iter_mut().zip(y) {
                *d = Dual64::from_re(v);
            }
            y_dual[j].eps = 1.0;
            solve(self, &y_dual[..dim])?;
            for i in 0..n {
                jac[(n + i) * dim + j] = self.sol[i].eps;
            }
            for i in 0..lambda_rows {
                jac[(2 * n + i) * dim + j] = self.sol[n + i].eps;
            }
        }
        Ok(())
    }
}
