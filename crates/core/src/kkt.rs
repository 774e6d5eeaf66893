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

use crate::ad::Jet;
use crate::constraints::ConstraintState;
use crate::linalg::{Lu, equilibrate};
use crate::scene::{Scalar, ScalarField, Scene};
use crate::stab::Stabilisation;

/// How the rows of the nonholonomic constraints `g` enter the system.
///
/// * `Ideal`: `G q̈ = −ġ₀ − 2α g` (B, C: the constraint holds).
/// * `Compliant(c)`: `G q̈ − c μ_g = −ġ₀`, the constraint with compliance
///   `c = 1/N` (the added-mass realisation carrying `λ = N g`, `μ_g = λ̇`).
/// * `Absent`: no constraint row (`μ_g = 0`); `g` acts only through the
///   field `ℓ` (the added-mass realisation written directly, `ℓ = L + (N/2) gᵀg`).
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
    /// Equilibration of the last solve (see [`equilibrate`]).
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
        if s + k > 0 {
            self.cs.evaluate(&mut self.jet, scene, t, q, qd);
            for r in 0..s + k {
                for j in 0..n {
                    let c = self.cs.jac[(r, j)];
                    self.matrix[(n + r, j)] = c;
                    self.matrix[(j, n + r)] = c;
                }
            }
            let (alpha, beta) = stab.gains();
            match rows {
                GRows::Ideal => {
                    for i in 0..s {
                        self.sol[n + i] = -self.cs.g_rate0[i] - self.cs.g[i] * (2.0 * alpha);
                    }
                }
                GRows::Compliant(c) => {
                    for i in 0..s {
                        self.matrix[(n + i, n + i)] = T::from(-c);
                        self.sol[n + i] = -self.cs.g_rate0[i];
                    }
                }
                GRows::Absent | GRows::Viscous(_) => {
                    let k = match rows {
                        GRows::Viscous(k) => k,
                        _ => 0.0,
                    };
                    for i in 0..s {
                        for j in 0..n {
                            if k != 0.0 {
                                self.sol[j] -= self.cs.jac[(i, j)] * self.cs.g[i] * k;
                            }
                            self.matrix[(n + i, j)] = T::from(0.0);
                            self.matrix[(j, n + i)] = T::from(0.0);
                        }
                        self.matrix[(n + i, n + i)] = T::from(1.0);
                        self.sol[n + i] = T::from(0.0);
                    }
                }
            }
            for i in 0..k {
                self.sol[n + s + i] = -self.cs.f_accel0[i]
                    - self.cs.f_rate[i] * (2.0 * alpha)
                    - self.cs.f[i] * (beta * beta);
            }
        }
        equilibrate(&mut self.matrix, n, &mut self.scale);
        for (x, d) in self.sol.iter_mut().zip(&self.scale) {
            *x *= *d;
        }
        self.lu.factor(&mut self.matrix).map_err(|e| {
            SystemError::new(format!(
                "KKT system of {what} singular ({e}): constraints dependent, \
                 or the kinetic energy degenerate on the admissible velocities"
            ))
        })?;
        self.lu.solve(&self.matrix, &mut self.sol);
        for (x, d) in self.sol.iter_mut().zip(&self.scale) {
            *x *= *d;
        }
        Ok(())
    }
}
