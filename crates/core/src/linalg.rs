//! Dense LU factorisation with partial pivoting, in place and allocation-free.
//!
//! The KKT systems of the formulations are small (n + s + k ≤ a few dozen)
//! and solved once per right-hand side. nalgebra's `LU` takes its matrix by
//! value and allocates a permutation for dynamic sizes; here the matrix and
//! the pivot vector live in the caller's workspace and are reused.
//!
//! [`solve_saddle`] solves the small saddle-point systems of the
//! formulations by block elimination where that is clearly safe, and by
//! the equilibrated LU otherwise.
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

/// Solves the saddle-point system `a x = b` (primal block of size `n`):
/// `b` in `rhs`, `x` out.
///
/// Up to [`BLOCK_MAX`] unknowns, and where the primal block `M` is clearly
/// positive definite and the constraint block clearly regular, by block
/// elimination (`block_core`: `M`'s columns without exchanges, then the
/// Schur complement with them), leaving `a` and `d` as they were.
/// Otherwise — and for every system where that test fails, so that a
/// singular system is reported by one rule — equilibrated as by
/// [`equilibrate`] and factorised by [`Lu::factor`], leaving `a` holding the
/// LU factors of the scaled matrix and `d` the scaling.
pub fn solve_saddle<T: Scalar>(
    a: &mut DMatrix<T>,
    n: usize,
    lu: &mut Lu,
    d: &mut [f64],
    rhs: &mut [T],
) -> Result<(), Singular> {
    if block(a.as_slice(), n, rhs, a.nrows()) {
        return Ok(());
    }
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

/// `dst.copy_from_slice(src)` for the few values of a right-hand side's
/// pieces: up to 8 values the copy has a constant length, which the
/// compiler turns into moves, where a slice copy of unknown length calls
/// `memmove` (a few nanoseconds, against tens for a whole right-hand side).
#[inline(always)]
pub fn copy_small<T: Copy>(dst: &mut [T], src: &[T]) {
    macro_rules! fixed {
        ($($len:literal)*) => {
            match dst.len() {
                $($len => dst[..$len].copy_from_slice(&src[..$len]),)*
                _ => dst.copy_from_slice(src),
            }
        };
    }
    assert_eq!(
        dst.len(),
        src.len(),
        "copy between slices of different lengths"
    );
    fixed!(1 2 3 4 5 6 7 8)
}

/// Largest system [`solve_saddle`] solves by block elimination (its scratch
/// lives on the stack).
pub const BLOCK_MAX: usize = 8;

/// Smallest pivot of `M`'s elimination in [`block_core`], as a fraction of
/// the diagonal entry of `M` it came from (the pivot of `M` scaled to unit
/// diagonal: 1 for a diagonal `M`, in `(0, 1]` when `M` is positive
/// definite). Below it — `M` nearly singular, indefinite, or a NaN — the
/// pivoted LU solves instead: block elimination would lose up to the
/// inverse of this fraction in accuracy where the LU loses nothing.
pub(crate) const PRIMAL_PIVOT: f64 = 1e-2;

/// Largest componentwise backward error of a solution [`block_core`]
/// accepts: the residual of every row against the size of its terms
/// (`|b_i − Σ a_ij x_j| ≤ BACKWARD (|b_i| + Σ |a_ij x_j|)`), a few hundred
/// units of round-off.
pub(crate) const BACKWARD: f64 = 1e-13;

/// `block_core` refuses a Schur complement pivot below this many times
/// `m ε max|S|` (the form of [`Lu::factor`]'s singularity threshold, on the
/// unscaled `m × m` complement), so that a nearly singular system goes to
/// the LU, which then decides whether it is singular. A heuristic margin,
/// not a proof that the two paths draw the line at the same place.
pub(crate) const SCHUR_MARGIN: f64 = 1e3;

/// [`block_core`] with the size and the primal block constants, up to
/// [`BLOCK_MAX`] (so that every loop has constant bounds and unrolls);
/// `false` beyond.
pub(crate) fn block<T: Scalar>(a: &[T], n: usize, rhs: &mut [T], size: usize) -> bool {
    macro_rules! sizes {
        ($(($size:literal, $area:literal: $($n:literal)*))*) => {
            match (size, n) {
                $($(($size, $n) => block_core::<T, $size, $area, $n>(a, rhs),)*)*
                _ => false,
            }
        };
    }
    sizes! {
        (1, 1: 0 1)
        (2, 4: 0 1 2)
        (3, 9: 0 1 2 3)
        (4, 16: 0 1 2 3 4)
        (5, 25: 0 1 2 3 4 5)
        (6, 36: 0 1 2 3 4 5 6)
        (7, 49: 0 1 2 3 4 5 6 7)
        (8, 64: 0 1 2 3 4 5 6 7 8)
    }
}

/// One step of Gaussian elimination on the column-major `size × size`
/// matrix `w` with the pivot at `(k, k)`: the multipliers below it into
/// column `k`, the update of the trailing columns; returns `1 / pivot`.
#[inline(always)]
fn eliminate<T: Scalar>(w: &mut [T], k: usize, size: usize) -> T {
    let r = T::from(1.0) / w[k + k * size];
    let (left, right) = w.split_at_mut((k + 1) * size);
    let lcol = &mut left[k * size..];
    for x in &mut lcol[k + 1..] {
        *x *= r;
    }
    for col in right.chunks_exact_mut(size) {
        let u = col[k];
        for i in k + 1..size {
            col[i] -= lcol[i] * u;
        }
    }
    r
}

/// The fast path of [`solve_saddle`] on the column-major `size × size`
/// matrix `a` with primal block `n`; `false` (with `rhs` as it was) where
/// it declines.
///
/// Gaussian elimination of `M`'s `n` columns in order, without exchanges,
/// leaves the Schur complement `S = D − C M⁻¹ B` of `a = [M B; C D]` in the
/// trailing block; `S` is factorised with row exchanges. It divides
/// `n + s + k` times and needs no scaling: on the sleigh's 4 × 4 systems
/// (B and C, a sweep of 20 random states' runs) `solve_saddle` took 710
/// instructions per solve this way against 986 equilibrated and pivoted
/// (callgrind, residual check included).
///
/// `SIZE` is `size`, `AREA` its square (the scratch on the stack holds
/// exactly the matrix) and `N` is `n`.
#[inline(always)]
fn block_core<T: Scalar, const SIZE: usize, const AREA: usize, const N: usize>(
    a: &[T],
    rhs: &mut [T],
) -> bool {
    let (size, n) = (SIZE, N);
    let zero = T::from(0.0);
    let mut w = [zero; AREA];
    let mut inverse = [zero; SIZE];
    let mut piv = [0usize; SIZE];
    let a = &a[..AREA];
    w.copy_from_slice(a);
    // M's columns, with the pivot test relative to M's own diagonal.
    for k in 0..n {
        let (pivot, diagonal) = (w[k + k * size].re(), a[k + k * size].re());
        if !(diagonal > 0.0 && pivot > PRIMAL_PIVOT * diagonal) {
            return false;
        }
        inverse[k] = eliminate(&mut w, k, size);
    }
    // The Schur complement in rows and columns n.., with row exchanges
    // inside it.
    let scale = (n..size).fold(0.0f64, |m, j| {
        w[n + j * size..(j + 1) * size]
            .iter()
            .fold(m, |m, v| m.max(v.re().abs()))
    });
    let tiny = SCHUR_MARGIN * ((size - n).max(1) as f64) * f64::EPSILON * scale;
    for k in n..size {
        let mut p = k;
        let mut best = w[k + k * size].re().abs();
        for i in k + 1..size {
            let v = w[i + k * size].re().abs();
            if v > best {
                best = v;
                p = i;
            }
        }
        if best.is_nan() || best <= tiny {
            return false;
        }
        piv[k] = p;
        if p != k {
            // Columns k.. only: the multipliers of earlier columns were
            // applied to the right-hand side before this exchange (the
            // forward pass below exchanges step by step).
            for j in k..size {
                w.swap(k + j * size, p + j * size);
            }
        }
        inverse[k] = eliminate(&mut w, k, size);
    }
    // Forward: M's multipliers, then the exchanges and multipliers of S.
    let rhs = &mut rhs[..size];
    let mut b = [zero; SIZE];
    b.copy_from_slice(rhs);
    for k in 0..size {
        if k >= n {
            rhs.swap(k, piv[k]);
        }
        let x = rhs[k];
        let col = &w[k * size..(k + 1) * size];
        for i in k + 1..size {
            rhs[i] -= col[i] * x;
        }
    }
    // Back substitution through the whole upper triangle.
    for j in (0..size).rev() {
        let x = rhs[j] * inverse[j];
        rhs[j] = x;
        let col = &w[j * size..(j + 1) * size];
        for i in 0..j {
            rhs[i] -= col[i] * x;
        }
    }
    // Accepted only with a componentwise backward error (Oettli–Prager)
    // below BACKWARD in every row: block elimination squares the
    // conditioning of the constraints, and a Schur complement that lost
    // its digits shows here, not in its pivots.
    let x = &*rhs;
    let mut residual = [0.0f64; SIZE];
    let mut size_of = [0.0f64; SIZE];
    for i in 0..size {
        residual[i] = -b[i].re();
        size_of[i] = b[i].re().abs();
    }
    for (col, xj) in a.chunks_exact(size).zip(x) {
        let xj = xj.re();
        for i in 0..size {
            let v = col[i].re() * xj;
            residual[i] += v;
            size_of[i] += v.abs();
        }
    }
    if (0..size).all(|i| residual[i].abs() <= BACKWARD * size_of[i]) {
        return true;
    }
    rhs.copy_from_slice(&b);
    false
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

    /// A saddle system `[M Cᵀ; C 0]` with a right-hand side `b`, in units
    /// spread over decades: `M = D M₀ D` and `C = E C₀ D` with
    /// `M₀ = 0.3 R Rᵀ + I` and `C₀`, `R` and `b₀` uniform in `[-1, 1]`;
    /// `D` (the coordinates' units) over 12 decades and `E` (the
    /// constraints') over 4, and `b = (D b₀, E b₀)`. Returns the system,
    /// `b` and the units `u = (D, E)`: the system divided by `u_i u_j` is
    /// the unit-free `[M₀ C₀ᵀ; C₀ 0]`, whose solution is `u ⊙ x`, of order
    /// one.
    fn saddle(
        rng: &mut rand::rngs::StdRng,
        n: usize,
        m: usize,
    ) -> (DMatrix<f64>, Vec<f64>, Vec<f64>) {
        let r = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
        let mut units: Vec<f64> = (0..n)
            .map(|_| 10f64.powf(rng.random_range(-6.0..6.0)))
            .collect();
        units.extend((0..m).map(|_| 10f64.powf(rng.random_range(-2.0..2.0))));
        let m0 = &r * r.transpose() * 0.3 + DMatrix::identity(n, n);
        let mut a = DMatrix::zeros(n + m, n + m);
        for i in 0..n {
            for j in 0..n {
                a[(i, j)] = m0[(i, j)] * units[i] * units[j];
            }
            for k in n..n + m {
                let c = rng.random_range(-1.0..1.0) * units[k] * units[i];
                a[(k, i)] = c;
                a[(i, k)] = c;
            }
        }
        let b = units
            .iter()
            .map(|u| u * rng.random_range(-1.0..1.0))
            .collect();
        (a, b, units)
    }

    /// Equilibrated LU (the path block elimination stands in for).
    fn by_lu(a: &DMatrix<f64>, n: usize, b: &[f64]) -> Result<Vec<f64>, Singular> {
        let (mut f, size) = (a.clone(), a.nrows());
        let mut d = vec![0.0; size];
        equilibrate(&mut f, n, &mut d);
        let mut x: Vec<f64> = b.iter().zip(&d).map(|(v, s)| v * s).collect();
        let mut lu = Lu::new(size);
        lu.factor(&mut f)?;
        lu.solve(&f, &mut x);
        Ok(x.iter().zip(&d).map(|(v, s)| v * s).collect())
    }

    /// Block elimination takes random saddle systems up to `BLOCK_MAX`
    /// unknowns (20 per shape, units spread as in `saddle`; its residual
    /// test is part of what `block` checks before it takes one) and agrees
    /// with the equilibrated LU within `100 κ ε ‖x‖`, in units where the
    /// solution is of order one (κ the condition number there): two
    /// backward-stable solutions lie within about `N κ ε ‖x‖` of the exact
    /// one each. Where it declines, `solve_saddle` gives the LU's solution.
    #[test]
    fn block_elimination_solves_saddle_systems_like_the_lu() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let (mut worst, mut declined) = (0.0f64, Vec::new());
        for n in 1..=BLOCK_MAX {
            for m in 0..=(BLOCK_MAX - n).min(n) {
                for _ in 0..20 {
                    let (a, b, units) = saddle(&mut rng, n, m);
                    let lu = by_lu(&a, n, &b).unwrap();
                    let mut x = b.clone();
                    if !block(a.as_slice(), n, &mut x, n + m) {
                        declined.push((n, m));
                        assert_eq!(x, b);
                        let mut k = a.clone();
                        let mut d = vec![0.0; n + m];
                        solve_saddle(&mut k, n, &mut Lu::new(n + m), &mut d, &mut x).unwrap();
                        assert_eq!(x, lu);
                        continue;
                    }
                    let unit_free =
                        DMatrix::from_fn(n + m, n + m, |i, j| a[(i, j)] / (units[i] * units[j]));
                    let sv = unit_free.singular_values();
                    let cond = sv.max() / sv.min();
                    let size = lu
                        .iter()
                        .zip(&units)
                        .fold(0.0f64, |s, (v, u)| s.max((v * u).abs()));
                    for ((v, w), u) in x.iter().zip(&lu).zip(&units) {
                        worst = worst.max((v - w).abs() * u / (cond * f64::EPSILON * size));
                    }
                }
            }
        }
        // Of the 480 systems it declined one, with as many constraints as
        // coordinates (n = m = 4), where the Schur complement carries the
        // square of the constraints' condition number.
        assert!(
            declined.len() <= 1 && declined.iter().all(|&(n, m)| n == m),
            "declined (n, m): {declined:?}"
        );
        // 20 measured.
        assert!(worst < 100.0, "{worst}");
    }

    /// Where `M` is nearly singular (the sleigh with `J = a² + 1e-6`),
    /// indefinite, or the constraints are dependent, block elimination
    /// declines and `solve_saddle` answers as the equilibrated LU does: the
    /// same solution, or the same `Singular`.
    #[test]
    fn block_elimination_declines_where_the_lu_decides() {
        let (a, phi) = (0.4, 0.7f64);
        let (s, c) = phi.sin_cos();
        let sleigh = |j: f64, second_row: f64| {
            #[rustfmt::skip]
            let k = DMatrix::from_row_slice(5, 5, &[
                1.0, 0.0, -a * s, -s, -s,
                0.0, 1.0, a * c, c, c,
                -a * s, a * c, j, 0.0, second_row,
                -s, c, 0.0, 0.0, 0.0,
                -s, c, second_row, 0.0, 0.0,
            ]);
            k
        };
        let b = [0.3, -0.2, 0.5, 0.1, -0.4];
        // Nearly singular M: declined, solved by the LU.
        let near = sleigh(a * a + 1e-6, 1.0);
        let mut x = b;
        assert!(!block(near.as_slice(), 3, &mut x, 5));
        assert_eq!(x, b, "a declined system leaves the right-hand side");
        let mut k = near.clone();
        solve_saddle(&mut k, 3, &mut Lu::new(5), &mut [0.0; 5], &mut x).unwrap();
        assert_eq!(x.to_vec(), by_lu(&near, 3, &b).unwrap());
        // The same with J = 1 is taken.
        let regular = sleigh(1.0, 1.0);
        assert!(block(regular.as_slice(), 3, &mut b.clone(), 5));
        // Indefinite M, with a negative diagonal entry and with a positive
        // diagonal (J < a²: the third pivot J − a² is negative): declined.
        for j in [-1.0, 0.1] {
            let indefinite = sleigh(j, 1.0);
            assert!(!block(indefinite.as_slice(), 3, &mut b.clone(), 5));
        }
        // Dependent constraints (two equal rows): declined, and the error
        // is the LU's.
        let dependent = sleigh(1.0, 0.0);
        assert!(!block(dependent.as_slice(), 3, &mut b.clone(), 5));
        let mut k = dependent.clone();
        let e = solve_saddle(&mut k, 3, &mut Lu::new(5), &mut [0.0; 5], &mut b.clone());
        assert_eq!(e, by_lu(&dependent, 3, &b).map(|_| ()));
        assert!(e.is_err());
        // A NaN anywhere: declined.
        let mut nan = regular;
        nan[(4, 1)] = f64::NAN;
        assert!(!block(nan.as_slice(), 3, &mut b.clone(), 5));
    }

    /// The derivative parts of dual numbers follow the elimination: a
    /// directional derivative of the solution by block elimination equals
    /// the LU's.
    #[test]
    fn block_elimination_differentiates_like_the_lu() {
        use num_dual::Dual64;
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let (n, m) = (4, 2);
        let (a, _, _) = saddle(&mut rng, n, m);
        let da = DMatrix::from_fn(n + m, n + m, |_, _| rng.random_range(-1.0..1.0));
        let dual = DMatrix::from_fn(n + m, n + m, |i, j| Dual64::new(a[(i, j)], da[(i, j)]));
        let b: Vec<Dual64> = (0..n + m)
            .map(|_| Dual64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)))
            .collect();
        let mut x = b.clone();
        assert!(block(dual.as_slice(), n, &mut x, n + m));
        let (mut f, mut y, mut d) = (dual.clone(), b.clone(), vec![0.0; n + m]);
        equilibrate(&mut f, n, &mut d);
        for (v, s) in y.iter_mut().zip(&d) {
            *v *= *s;
        }
        let mut lu = Lu::new(n + m);
        lu.factor(&mut f).unwrap();
        lu.solve(&f, &mut y);
        for ((u, v), s) in x.iter().zip(&y).zip(&d) {
            let v = *v * *s;
            assert!((u.re - v.re).abs() < 1e-12 * (1.0 + v.re.abs()), "{u} {v}");
            assert!(
                (u.eps - v.eps).abs() < 1e-10 * (1.0 + v.eps.abs()),
                "{u} {v}"
            );
        }
    }
}
