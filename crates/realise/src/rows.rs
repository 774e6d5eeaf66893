//! How the rows of the nonholonomic constraints enter the KKT system of the
//! realisations ([`GRows`] kinds beside the ideal constraint of B and C).

use nalgebra::DMatrix;
use nonholo_core::constraints::ConstraintState;
use nonholo_core::kkt::GRows;
use nonholo_core::scene::Scalar;

/// The constraint with compliance `c = 1/N`: `G q̈ − c μ_g = −ġ₀` (the
/// added-mass realisation carrying `λ = N g`, `μ_g = λ̇`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Compliant(pub f64);

impl GRows for Compliant {
    fn write<T: Scalar>(
        &self,
        n: usize,
        cs: &ConstraintState<T>,
        matrix: &mut DMatrix<T>,
        rhs: &mut [T],
    ) {
        cs.write_rows(0..cs.s, matrix, n);
        for i in 0..cs.s {
            matrix[(n + i, n + i)] = T::from(-self.0);
            rhs[n + i] = -cs.g_rate0[i];
        }
    }
}

/// No constraint row (an identity block, `μ_g = 0`): `g` acts only through
/// the field `ℓ` (the added-mass realisation written directly,
/// `ℓ = L + (N/2) gᵀg`), so `g` and `G` are not evaluated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Absent;

impl GRows for Absent {
    fn needs_g(&self) -> bool {
        false
    }

    fn write<T: Scalar>(
        &self,
        n: usize,
        cs: &ConstraintState<T>,
        matrix: &mut DMatrix<T>,
        rhs: &mut [T],
    ) {
        identity_rows(n, cs.s, matrix, rhs);
    }
}

/// No constraint row; the viscous force `−k Gᵀ g` joins the right-hand
/// side (the viscous realisation with gain `k`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Viscous(pub f64);

impl GRows for Viscous {
    fn write<T: Scalar>(
        &self,
        n: usize,
        cs: &ConstraintState<T>,
        matrix: &mut DMatrix<T>,
        rhs: &mut [T],
    ) {
        for i in 0..cs.s {
            for j in 0..n {
                rhs[j] -= cs.jac[(i, j)] * cs.g[i] * self.0;
            }
        }
        identity_rows(n, cs.s, matrix, rhs);
    }
}

/// `μ_g = 0` from an identity block in rows `n..n + s`.
fn identity_rows<T: Scalar>(n: usize, s: usize, matrix: &mut DMatrix<T>, rhs: &mut [T]) {
    for i in 0..s {
        matrix[(n + i, n + i)] = T::from(1.0);
        rhs[n + i] = T::from(0.0);
    }
}
