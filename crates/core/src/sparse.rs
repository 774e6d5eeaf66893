//! The KKT system of [`crate::kkt`] stored sparse and factored by faer's
//! sparse LU, for scenes whose size makes the dense `O((n + s + k)³)` solve
//! the cost of a right-hand side.
//!
//! The pattern is the compiled program's ([`crate::compiled::Pattern`]):
//! `M` (both triangles), `G` and `Gᵀ`, `F` and `Fᵀ`, fixed once, so the
//! fill-reducing ordering and the symbolic factorisation are computed once
//! too; every solve scatters the program's values into the stored entries,
//! equilibrates them as the dense path does ([`crate::linalg::equilibrate`]:
//! `dᵢ = 1/√|Mᵢᵢ|` on the primal block, each constraint row by its largest
//! scaled entry), refactors numerically in a reused workspace and solves in
//! place. Over `Dual64` (a Jacobian column) the same factors also give the
//! derivative part of the solution. Only the ideal constraint rows (B and
//! C) are written here; the realisations' rows stay dense.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::lu::{NumericLu, SymbolicLu, factorize_symbolic_lu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, MatMut, Par};

use crate::compiled::{KktSource, Pieces};
use crate::linalg::Singular;
use crate::scene::Scalar;

/// Size of the KKT system `n + s + k` from which [`crate::kkt::Kkt`] solves
/// sparse when the program compiled: between the sizes where the two solves
/// were measured to cross on `sleigh-train` (`scale-report` of
/// `nonholo-bench`, docs/performance.md §9), the dense LU faster at 16 rows,
/// the sparse one at 22 and beyond.
pub const SPARSE_FROM: usize = 20;

/// The sparse KKT system of one compiled program, with its factorisation
/// workspace.
pub struct SparseKkt {
    n: usize,
    dim: usize,
    symbolic: SymbolicSparseColMat<usize>,
    /// Row, column and source of every stored entry, in storage order.
    entries: Vec<(u32, u32, KktSource)>,
    values: Vec<f64>,
    lu_symbolic: SymbolicLu<usize>,
    numeric: NumericLu<usize, f64>,
    buffer: MemBuffer,
    /// Storage position of each `Mᵢᵢ`.
    diagonal: Vec<usize>,
    scale: Vec<f64>,
    /// The right-hand side, then the solution, in `f64`.
    rhs: Vec<f64>,
    /// Their derivative parts (first-order dual numbers).
    tangent: Vec<f64>,
}

impl std::fmt::Debug for SparseKkt {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseKkt")
            .field("dim", &self.dim)
            .field("nonzeros", &self.entries.len())
            .finish_non_exhaustive()
    }
}

impl Clone for SparseKkt {
    /// A fresh workspace for the same pattern (the factors are not copied).
    fn clone(&self) -> Self {
        SparseKkt {
            n: self.n,
            dim: self.dim,
            symbolic: self.symbolic.clone(),
            entries: self.entries.clone(),
            values: self.values.clone(),
            lu_symbolic: self.lu_symbolic.clone(),
            numeric: NumericLu::new(),
            buffer: MemBuffer::new(scratch(&self.lu_symbolic)),
            diagonal: self.diagonal.clone(),
            scale: self.scale.clone(),
            rhs: self.rhs.clone(),
            tangent: self.tangent.clone(),
        }
    }
}

fn scratch(lu: &SymbolicLu<usize>) -> faer::dyn_stack::StackReq {
    lu.factorize_numeric_lu_scratch::<f64>(Par::Seq, Default::default())
        .or(lu.solve_in_place_scratch::<f64>(1, Par::Seq))
}

impl SparseKkt {
    /// The pattern of a system of dimension `dim`, with `n` coordinates and
    /// the structural nonzeros `entries`
    /// ([`crate::compiled::Pattern::kkt_entries`],
    /// [`crate::compiled::Compiled::kkt_entries`]), ordered and analysed
    /// once. `Err` says why not: an entry outside the system, or faer
    /// refused the pattern (a structurally singular system).
    pub fn new(
        mut entries: Vec<(u32, u32, KktSource)>,
        n: usize,
        dim: usize,
    ) -> Result<SparseKkt, String> {
        let outside = |&(r, c, _): &(u32, u32, KktSource)| r as usize >= dim || c as usize >= dim;
        if n > dim || entries.iter().any(outside) {
            return Err(format!(
                "KKT entries outside a system of dimension {dim} with {n} coordinates"
            ));
        }
        entries.sort_unstable_by_key(|&(r, c, _)| (c, r));
        let mut col_ptr = vec![0usize; dim + 1];
        for &(_, c, _) in &entries {
            col_ptr[c as usize + 1] += 1;
        }
        for j in 0..dim {
            col_ptr[j + 1] += col_ptr[j];
        }
        let row_idx: Vec<usize> = entries.iter().map(|&(r, _, _)| r as usize).collect();
        let mut diagonal = vec![usize::MAX; n];
        for (p, &(r, c, _)) in entries.iter().enumerate() {
            if r == c && (r as usize) < n {
                diagonal[r as usize] = p;
            }
        }
        if let Some(i) = diagonal.iter().position(|&p| p == usize::MAX) {
            return Err(format!(
                "the mass matrix has no entry on its diagonal at row {i}"
            ));
        }
        let symbolic = SymbolicSparseColMat::new_checked(dim, dim, col_ptr, None, row_idx);
        let lu_symbolic = factorize_symbolic_lu(symbolic.as_ref(), Default::default())
            .map_err(|e| format!("faer's symbolic LU refused the KKT pattern: {e:?}"))?;
        Ok(SparseKkt {
            n,
            dim,
            values: vec![0.0; entries.len()],
            buffer: MemBuffer::new(scratch(&lu_symbolic)),
            numeric: NumericLu::new(),
            lu_symbolic,
            symbolic,
            entries,
            diagonal,
            scale: vec![1.0; dim],
            rhs: Vec::with_capacity(dim),
            tangent: Vec::with_capacity(dim),
        })
    }

    /// Stored entries.
    pub fn nonzeros(&self) -> usize {
        self.entries.len()
    }

    /// The stored entries `(row, column)` in storage order (by column).
    pub fn entries(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.entries
            .iter()
            .map(|&(r, c, _)| (r as usize, c as usize))
    }

    /// Solves the system with the matrix of `pieces` and right-hand side
    /// `sol`, in place, for `T` real ([`Scalar::REAL`]: the values pass
    /// through `re()`, exactly) or a first-order dual number
    /// ([`Scalar::FIRST_ORDER`], a Jacobian column): with `K = K₀ + εK₁`,
    /// `b = b₀ + εb₁`, the solution is `x₀ = K₀⁻¹b₀` and
    /// `x₁ = K₀⁻¹(b₁ − K₁x₀)` — forward differentiation of the solve, as the
    /// dense LU does it by running on dual numbers, with one factorisation.
    pub fn solve<T: Scalar>(
        &mut self,
        pieces: &Pieces<'_, T>,
        sol: &mut [T],
    ) -> Result<(), Singular> {
        debug_assert!(T::REAL || T::FIRST_ORDER, "the sparse KKT path");
        let (n, dim) = (self.n, self.dim);
        self.rhs.clear();
        self.rhs.extend(sol.iter().map(|x| x.re()));
        let rhs = &mut self.rhs[..];
        for (v, &(_, _, src)) in self.values.iter_mut().zip(&self.entries) {
            *v = src.value(pieces.outputs).re();
        }
        // Equilibration, as `linalg::equilibrate`.
        let d = &mut self.scale;
        let diag_max = self
            .diagonal
            .iter()
            .fold(0.0f64, |m, &p| m.max(self.values[p].abs()));
        let floor = (f64::EPSILON * diag_max).max(f64::MIN_POSITIVE);
        for (i, &p) in self.diagonal.iter().enumerate() {
            d[i] = 1.0 / self.values[p].abs().max(floor).sqrt();
        }
        d[n..].fill(0.0);
        for (&(r, c, _), &v) in self.entries.iter().zip(&self.values) {
            let (r, c) = (r as usize, c as usize);
            if r >= n && c < n {
                d[r] = d[r].max((v * d[c]).abs());
            }
        }
        for x in &mut d[n..dim] {
            *x = if *x > 0.0 { 1.0 / *x } else { 1.0 };
        }
        for (v, &(r, c, _)) in self.values.iter_mut().zip(&self.entries) {
            *v *= d[r as usize] * d[c as usize];
        }
        for (x, s) in rhs.iter_mut().zip(d.iter()) {
            *x *= *s;
        }
        let scale = self.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let b_max = rhs.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        // faer refuses only a structurally singular matrix; its column is
        // not reported (0 here).
        let singular = |column: usize| Singular {
            column,
            pivot: 0.0,
            scale,
        };
        let a = SparseColMatRef::new(self.symbolic.as_ref(), &self.values);
        let stack = MemStack::new(&mut self.buffer);
        let lu = self
            .lu_symbolic
            .factorize_numeric_lu(&mut self.numeric, a, Par::Seq, stack, Default::default())
            .map_err(|_| singular(0))?;
        let stack = MemStack::new(&mut self.buffer);
        lu.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(rhs, dim, 1),
            Par::Seq,
            stack,
        );
        if T::FIRST_ORDER {
            // y₁ = A₀⁻¹(D b₁ − A₁ y₀), A = D K D, with the same factors.
            let t = &mut self.tangent;
            t.clear();
            t.extend(sol.iter().zip(&self.scale).map(|(x, s)| x.tangent() * s));
            for &(r, c, src) in &self.entries {
                let (r, c) = (r as usize, c as usize);
                t[r] -=
                    src.value(pieces.outputs).tangent() * self.scale[r] * self.scale[c] * rhs[c];
            }
            let stack = MemStack::new(&mut self.buffer);
            lu.solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(t, dim, 1),
                Par::Seq,
                stack,
            );
            for (x, s) in t.iter_mut().zip(self.scale.iter()) {
                *x *= *s;
            }
        }
        // A numerically singular matrix gives faer's LU a tiny pivot and a
        // large, finite solution where the dense LU refuses any pivot below
        // `dim ε max|A|`. The same verdict here, from the solution: with
        // `A y = b`, `cond(A) ≥ |y| |A| / |b|`; beyond `1/(dim ε)` no digit of
        // `y` is right, and the system is reported singular at the largest
        // entry of `y`.
        let y_max = rhs.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if b_max > 0.0 && y_max * scale > b_max / (dim as f64 * f64::EPSILON) {
            let column = rhs
                .iter()
                .position(|v| v.abs() == y_max)
                .unwrap_or_default();
            return Err(Singular {
                column,
                pivot: b_max / y_max,
                scale,
            });
        }
        for (x, s) in rhs.iter_mut().zip(self.scale.iter()) {
            *x *= *s;
        }
        let bad = |v: &[f64]| v.iter().position(|x| !x.is_finite());
        if let Some(column) = bad(rhs).or_else(|| bad(&self.tangent).filter(|_| T::FIRST_ORDER)) {
            return Err(Singular {
                column,
                pivot: f64::NAN,
                scale,
            });
        }
        for (i, x) in sol.iter_mut().enumerate() {
            *x = if T::FIRST_ORDER {
                T::from_tangent(rhs[i], self.tangent[i])
            } else {
                T::from(rhs[i])
            };
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compiled::Pattern;
    use crate::linalg::{Lu, solve_saddle};

    /// `M = I₂` and two constraint rows that are equal up to `δ` in one
    /// entry: regular for `δ = 0.5`, singular to working precision for
    /// `δ = 2 ulp`. The sparse solve agrees with the dense one on the first
    /// and refuses the second, as the dense LU does.
    #[test]
    fn near_singular_systems_are_refused_as_the_dense_lu_refuses_them() {
        let pattern = Pattern {
            mass: vec![(0, 0), (1, 1)],
            g_jac: vec![(0, 0), (0, 1), (1, 0), (1, 1)],
            f_jac: vec![],
        };
        // Dimensions that do not hold the entries are refused.
        for (n, dim) in [(2, 3), (5, 4)] {
            assert!(SparseKkt::new(pattern.kkt_entries(2, 2, 0), n, dim).is_err());
        }
        let mut sparse = SparseKkt::new(pattern.kkt_entries(2, 2, 0), 2, 4).unwrap();
        for (delta, regular) in [(0.5, true), (4.0 * f64::EPSILON, false)] {
            let g11 = 1.0 + delta;
            // M, Q, g, G, ġ₀ (no position constraint).
            #[rustfmt::skip]
            let outputs = [1.0, 1.0, 0.3, -0.2, 0.0, 0.0, 1.0, 1.0, 1.0, g11, 0.0, 0.0];
            let pieces = Pieces::new(&pattern, &pattern.layout(2, 2, 0), &outputs);
            let rhs = [0.3, -0.2, 0.1, 0.7];
            let mut x = rhs;
            let got = sparse.solve(&pieces, &mut x);
            let mut a = nalgebra::DMatrix::from_row_slice(
                4,
                4,
                &[
                    1.0, 0.0, 1.0, 1.0, //
                    0.0, 1.0, 1.0, g11, //
                    1.0, 1.0, 0.0, 0.0, //
                    1.0, g11, 0.0, 0.0,
                ],
            );
            let mut y = rhs;
            let dense = solve_saddle(&mut a, 2, &mut Lu::new(4), &mut [0.0; 4], &mut y);
            assert_eq!(got.is_ok(), regular, "δ = {delta}: {got:?}");
            assert_eq!(dense.is_ok(), regular, "δ = {delta}: {dense:?}");
            if regular {
                for (u, v) in x.iter().zip(&y) {
                    assert!(
                        (u - v).abs() < 1e-13 * v.abs().max(1.0),
                        "{x:?} against {y:?}"
                    );
                }
            }
        }
    }
}
