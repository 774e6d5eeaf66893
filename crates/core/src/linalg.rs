//! Dense LU factorisation with partial pivoting, in place and allocation-free.
//!
//! The KKT systems of the formulations are small (n + s + k ≤ a few dozen)
//! and solved once per right-hand side. nalgebra's `LU` takes its matrix by
//! value and allocates a permutation for dynamic sizes; here the matrix and
//! the pivot vector live in the caller's workspace and are reused.
//!
//! The entries may be dual numbers: pivots are chosen on the real parts, and
//! the derivative parts then follow the same elimination, which is exactly
//! forward-mode differentiation of the solve.

use nalgebra::DMatrix;

use crate::scene::Scalar;

/// A pivot that is zero relative to the matrix: the matrix is (numerically) singular.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Singular {
    /// Elimination step at which no usable pivot was left.
    pub column: usize,
    /// Largest available pivot magnitude at that step.
    pub pivot: f64,
    /// Largest magnitude in the matrix before factorisation.
    pub scale: f64,
}

impl std::fmt::Display for Singular {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "matrix singular at elimination step {} (pivot {:.3e} against entries up to {:.3e})",
            self.column, self.pivot, self.scale
        )
    }
}

/// Pivot vector and factorisation state for an `n×n` matrix.
#[derive(Debug, Clone)]
pub struct Lu {
    piv: Vec<usize>,
}

impl Lu {
    pub fn new(n: usize) -> Self {
        Lu { piv: vec![0; n] }
    }

    /// Factorises `a` in place as `P a = L U` (unit `L` below the diagonal,
    /// `U` on and above it).
    ///
    /// A pivot below `n·ε·max|a|` is reported as [`Singular`]: beyond that the
    /// solution would carry no correct digits.
    pub fn factor<T: Scalar>(&mut self, a: &mut DMatrix<T>) -> Result<(), Singular> {
        let n = a.nrows();
        debug_assert_eq!(a.ncols(), n);
        debug_assert_eq!(self.piv.len(), n);
        let (a, piv) = (a.as_mut_slice(), &mut self.piv[..]);
        // The sizes of the scenes' KKT systems get their own copy with the
        // size a constant (loops unrolled): the general loops cost several
        // times the arithmetic at n ≤ 8.
        sized!(n, factor_core(a, piv))
    }

    /// Solves `A x = b` in place with the factors from [`Lu::factor`].
    pub fn solve<T: Scalar>(&self, lu: &DMatrix<T>, b: &mut [T]) {
        let n = lu.nrows();
        let (lu, piv) = (lu.as_slice(), &self.piv[..]);
        sized!(n, solve_core(lu, piv, b))
    }
}

/// Calls `$f(args.., n)` with `n` a literal for the sizes 1 to 8, so that
/// the always-inlined core is compiled once per small size.
macro_rules! sized {
    ($n:expr, $f:ident($($arg:expr),*)) => {
        match $n {
            1 => $f($($arg,)* 1),
            2 => $f($($arg,)* 2),
            3 => $f($($arg,)* 3),
            4 => $f($($arg,)* 4),
            5 => $f($($arg,)* 5),
            6 => $f($($arg,)* 6),
            7 => $f($($arg,)* 7),
            8 => $f($($arg,)* 8),
            n => $f($($arg,)* n),
        }
    };
}
use sized;

/// [`Lu::factor`] on column-major storage: entry (i, j) at `i + j n`.
#[inline(always)]
fn factor_core<T: Scalar>(a: &mut [T], piv: &mut [usize], n: usize) -> Result<(), Singular> {
    // Slices of the exact lengths: with `n` a constant the index checks
    // below fold away.
    let (a, piv) = (&mut a[..n * n], &mut piv[..n]);
    // Column maxima first: `n` independent chains instead of one of `n²`
    // dependent comparisons (the same maximum).
    let scale = a
        .chunks_exact(n.max(1))
        .map(|col| col.iter().fold(0.0f64, |m, v| m.max(v.re().abs())))
        .fold(0.0f64, f64::max);
    let tiny = (n.max(1) as f64) * f64::EPSILON * scale;
    for k in 0..n {
        let col = &a[k * n..(k + 1) * n];
        let mut p = k;
        let mut best = col[k].re().abs();
        for (i, v) in col.iter().enumerate().skip(k + 1) {
            let v = v.re().abs();
            if v > best {
                best = v;
                p = i;
            }
        }
        // Also catches NaN entries (every comparison with NaN is false).
        if best.is_nan() || best <= tiny {
            return Err(Singular {
                column: k,
                pivot: best,
                scale,
            });
        }
        piv[k] = p;
        if p != k {
            for j in 0..n {
                a.swap(k + j * n, p + j * n);
            }
        }
        let pivot = a[k + k * n];
        for i in k + 1..n {
            a[i + k * n] /= pivot;
        }
        for j in k + 1..n {
            let u = a[k + j * n];
            let (left, right) = a.split_at_mut(j * n);
            let lcol = &left[k * n..(k + 1) * n];
            let col = &mut right[..n];
            for i in k + 1..n {
                col[i] -= lcol[i] * u;
            }
        }
    }
    Ok(())
}

/// [`Lu::solve`] on column-major factors.
#[inline(always)]
fn solve_core<T: Scalar>(lu: &[T], piv: &[usize], b: &mut [T], n: usize) {
    let (lu, piv, b) = (&lu[..n * n], &piv[..n], &mut b[..n]);
    for k in 0..n {
        b.swap(k, piv[k]);
    }
    // Column-oriented substitutions (contiguous columns).
    for j in 0..n {
        let x = b[j];
        let col = &lu[j * n..(j + 1) * n];
        for i in j + 1..n {
            b[i] -= col[i] * x;
        }
    }
    for j in (0..n).rev() {
        let col = &lu[j * n..(j + 1) * n];
        let x = b[j] / col[j];
        b[j] = x;
        for i in 0..j {
            b[i] -= col[i] * x;
        }
    }
}

/// Scales a saddle-point matrix `[M Cᵀ; C 0]` (primal block of size `n`)
/// symmetrically, `a ← D a D`, and returns the scaling `d` (length of `a`):
/// `d_i = 1/√|M_ii|` on the primal block, and on each constraint row the
/// inverse of the largest entry of that row of `C D`. The scaled matrix has
/// entries of order one whatever the units (masses of 1e8 or 1e-8), so the
/// pivot test of [`Lu::factor`] means the same thing for every scene. The
/// caller scales the right-hand side by `d` before solving and the solution
/// by `d` after.
pub fn equilibrate<T: Scalar>(a: &mut DMatrix<T>, n: usize, d: &mut [f64]) {
    let size = a.nrows();
    let a = a.as_mut_slice();
    sized!(size, equilibrate_core(a, n, d))
}

/// [`equilibrate`] on column-major storage of a `size × size` matrix.
#[inline(always)]
fn equilibrate_core<T: Scalar>(a: &mut [T], n: usize, d: &mut [f64], size: usize) {
    let (a, d) = (&mut a[..size * size], &mut d[..size]);
    let diag_max = (0..n).fold(0.0f64, |m, i| m.max(a[i + i * size].re().abs()));
    let floor = (f64::EPSILON * diag_max).max(f64::MIN_POSITIVE);
    for i in 0..n {
        d[i] = 1.0 / a[i + i * size].re().abs().max(floor).sqrt();
    }
    for r in n..size {
        let row = (0..n).fold(0.0f64, |m, j| m.max((a[r + j * size].re() * d[j]).abs()));
        d[r] = if row > 0.0 { 1.0 / row } else { 1.0 };
    }
    for (j, col) in a.chunks_exact_mut(size.max(1)).enumerate() {
        for (i, x) in col.iter_mut().enumerate() {
            *x *= d[i] * d[j];
        }
    }
}

/// Solves the saddle-point system `a x = b` (primal block of size `n`)
/// equilibrated as by [`equilibrate`]: `b` in `rhs`, `x` out. Leaves `a`
/// holding the LU factors of the scaled matrix and `d` the scaling.
pub fn solve_saddle<T: Scalar>(
    a: &mut DMatrix<T>,
    n: usize,
    lu: &mut Lu,
    d: &mut [f64],
    rhs: &mut [T],
) -> Result<(), Singular> {
    equilibrate(a, n, d);
    for (x, s) in rhs.iter_mut().zip(d.iter()) {
        *x *= *s;
    }
    lu.factor(a)?;
    lu.solve(a, rhs);
    for (x, s) in rhs.iter_mut().zip(d.iter()) {
        *x *= *s;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn solves_random_systems_like_nalgebra() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for n in 1..9 {
            let a = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
            let b: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
            let mut f = a.clone();
            let mut lu = Lu::new(n);
            lu.factor(&mut f).unwrap();
            let mut x = b.clone();
            lu.solve(&f, &mut x);
            let r = &a * nalgebra::DVector::from_column_slice(&x)
                - nalgebra::DVector::from_column_slice(&b);
            // Backward stable: residual of the order of n ε ‖A‖ ‖x‖.
            let bound = 1e2
                * n as f64
                * f64::EPSILON
                * a.amax()
                * x.iter().fold(1.0f64, |m, v| m.max(v.abs()));
            assert!(r.amax() < bound, "n = {n}: residual {}", r.amax());
        }
    }

    #[test]
    fn saddle_point_with_zero_block() {
        // [[2, 1], [1, 0]] needs a row exchange-free but zero-diagonal solve.
        let mut a = DMatrix::from_row_slice(3, 3, &[2.0, 0.0, 1.0, 0.0, 3.0, 1.0, 1.0, 1.0, 0.0]);
        let mut lu = Lu::new(3);
        lu.factor(&mut a).unwrap();
        let mut x: [f64; 3] = [1.0, 2.0, 0.5];
        lu.solve(&a, &mut x);
        // Exact solution of 2x + z = 1, 3y + z = 2, x + y = 0.5.
        let (xx, yy, zz): (f64, f64, f64) = (0.1, 0.4, 0.8);
        assert!(
            (x[0] - xx).abs() < 1e-15 && (x[1] - yy).abs() < 1e-15 && (x[2] - zz).abs() < 1e-15
        );
    }

    /// A KKT matrix with masses 1e8 is singular to the raw pivot test but
    /// regular after equilibration, and the solution is unchanged.
    #[test]
    fn equilibration_removes_units() {
        let m = 1e8;
        // [m 0 1; 0 m 1; 1 1 0]: x + y constrained, masses m.
        let a0 = DMatrix::from_row_slice(3, 3, &[m, 0.0, 1.0, 0.0, m, 1.0, 1.0, 1.0, 0.0]);
        let b = [m * 1.0, m * 3.0, 0.0];
        let mut a = a0.clone();
        let mut d = [0.0; 3];
        equilibrate(&mut a, 2, &mut d);
        let mut lu = Lu::new(3);
        lu.factor(&mut a).unwrap();
        let mut x: Vec<f64> = b.iter().zip(&d).map(|(v, s)| v * s).collect();
        lu.solve(&a, &mut x);
        for (v, s) in x.iter_mut().zip(&d) {
            *v *= s;
        }
        // Exact: x = −1, y = 1, μ = 2m.
        assert!(
            (x[0] + 1.0).abs() < 1e-12
                && (x[1] - 1.0).abs() < 1e-12
                && (x[2] / m - 2.0).abs() < 1e-12,
            "{x:?}"
        );
    }

    #[test]
    fn reports_singular_matrices() {
        let mut a = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 4.0]);
        let e = Lu::new(2).factor(&mut a).unwrap_err();
        assert_eq!(e.column, 1);
        let mut z = DMatrix::<f64>::zeros(2, 2);
        assert!(Lu::new(2).factor(&mut z).is_err());
    }
}
