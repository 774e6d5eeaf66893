//! The iteration matrices `γ/h J' + J` (real) and `(α + iβ)/h J' + J`
//! (complex) stored sparse and factored by faer's sparse LU, for implicit
//! systems that give their Jacobians sparse ([`crate::Sparsity`]).
//!
//! The stored pattern is the union of the patterns of `J` and `J'`, fixed
//! for the run: the fill-reducing ordering and the symbolic factorisation
//! are computed once, and both matrices share them (the complex matrix has
//! the real one's pattern). Every factorisation scatters the values of `J`
//! and `J'` into the stored entries and refactors numerically in reused
//! workspaces. faer refuses only a structurally singular matrix; a zero
//! pivot of a numerically singular one turns into a non-finite solution,
//! which the Newton iteration reports as a singular matrix, as the dense LU
//! does (a nearly singular one gives a huge correction, rejected as
//! divergence by both).

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::sparse::linalg::lu::{LuRef, NumericLu, SymbolicLu, factorize_symbolic_lu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, MatMut, Par, c64};

use crate::Sparsity;

/// The sparse real and complex iteration matrices of one run.
pub(super) struct SparseIteration {
    dim: usize,
    symbolic: SymbolicSparseColMat<usize>,
    /// Storage position of every entry of `J` and of `J'`, in the order of
    /// the system's value lists.
    at_jy: Vec<usize>,
    at_jyp: Vec<usize>,
    /// `J'`'s entries `(row, column)`, for `J' x`.
    jyp: Vec<(usize, usize)>,
    lu: SymbolicLu<usize>,
    real: NumericLu<usize, f64>,
    complex: NumericLu<usize, c64>,
    real_values: Vec<f64>,
    complex_values: Vec<c64>,
    /// The right-hand side of a complex solve.
    complex_rhs: Vec<c64>,
    buffer: MemBuffer,
    /// Whether `real` and `complex` hold factors of the last `factor`
    /// (the solves read them unchecked).
    factored: (bool, bool),
}

impl SparseIteration {
    /// The pattern of `J ∪ J'` for a system of dimension `dim`, ordered and
    /// analysed once; `Err` says why faer refused it.
    pub fn new(dim: usize, sp: &Sparsity) -> Result<SparseIteration, String> {
        if let Some(&(r, c)) = sp
            .jy
            .iter()
            .chain(&sp.jyp)
            .find(|&&(r, c)| r >= dim || c >= dim)
        {
            return Err(format!(
                "the sparse Jacobian names entry ({r}, {c}) of a {dim} × {dim} system"
            ));
        }
        let mut all: Vec<(usize, usize)> = sp.jy.iter().chain(&sp.jyp).copied().collect();
        all.sort_unstable_by_key(|&(r, c)| (c, r));
        all.dedup();
        let mut col_ptr = vec![0usize; dim + 1];
        for &(_, c) in &all {
            col_ptr[c + 1] += 1;
        }
        for j in 0..dim {
            col_ptr[j + 1] += col_ptr[j];
        }
        let row_idx: Vec<usize> = all.iter().map(|&(r, _)| r).collect();
        let position = |e: &(usize, usize)| {
            all.binary_search_by_key(&(e.1, e.0), |&(r, c)| (c, r))
                .expect("every entry is stored")
        };
        let at_jy = sp.jy.iter().map(position).collect();
        let at_jyp = sp.jyp.iter().map(position).collect();
        let symbolic = SymbolicSparseColMat::new_checked(dim, dim, col_ptr, None, row_idx);
        let lu = factorize_symbolic_lu(symbolic.as_ref(), Default::default())
            .map_err(|e| format!("faer's symbolic LU refused the iteration matrix: {e:?}"))?;
        let scratch = |lu: &SymbolicLu<usize>| {
            StackReq::any_of(&[
                lu.factorize_numeric_lu_scratch::<f64>(Par::Seq, Default::default()),
                lu.factorize_numeric_lu_scratch::<c64>(Par::Seq, Default::default()),
                lu.solve_in_place_scratch::<f64>(1, Par::Seq),
                lu.solve_in_place_scratch::<c64>(1, Par::Seq),
            ])
        };
        Ok(SparseIteration {
            dim,
            at_jy,
            at_jyp,
            jyp: sp.jyp.clone(),
            real: NumericLu::new(),
            complex: NumericLu::new(),
            real_values: vec![0.0; all.len()],
            complex_values: vec![c64::new(0.0, 0.0); all.len()],
            complex_rhs: vec![c64::new(0.0, 0.0); dim],
            buffer: MemBuffer::new(scratch(&lu)),
            lu,
            symbolic,
            factored: (false, false),
        })
    }

    /// Forms and factors `g J' + J` from the values `jy`, `jyp` (parallel
    /// to the system's [`Sparsity`]), and, if `complex` is `Some((a, b))`,
    /// `(a + ib) J' + J`. `Err(0)` if faer refuses a factorisation or the
    /// values are not finite.
    pub fn factor(
        &mut self,
        jy: &[f64],
        jyp: &[f64],
        g: f64,
        complex: Option<(f64, f64)>,
    ) -> Result<(), usize> {
        self.factored = (false, false);
        self.real_values.fill(0.0);
        for (&p, &v) in self.at_jy.iter().zip(jy) {
            self.real_values[p] += v;
        }
        for (&p, &v) in self.at_jyp.iter().zip(jyp) {
            self.real_values[p] += g * v;
        }
        if !self.real_values.iter().all(|v| v.is_finite()) {
            return Err(0);
        }
        let a = SparseColMatRef::new(self.symbolic.as_ref(), &self.real_values);
        self.lu
            .factorize_numeric_lu(
                &mut self.real,
                a,
                Par::Seq,
                MemStack::new(&mut self.buffer),
                Default::default(),
            )
            .map_err(|_| 0usize)?;
        self.factored.0 = true;
        let Some((re, im)) = complex else {
            return Ok(());
        };
        self.complex_values.fill(c64::new(0.0, 0.0));
        for (&p, &v) in self.at_jy.iter().zip(jy) {
            self.complex_values[p].re += v;
        }
        for (&p, &v) in self.at_jyp.iter().zip(jyp) {
            self.complex_values[p] += c64::new(re * v, im * v);
        }
        let a = SparseColMatRef::new(self.symbolic.as_ref(), &self.complex_values);
        self.lu
            .factorize_numeric_lu(
                &mut self.complex,
                a,
                Par::Seq,
                MemStack::new(&mut self.buffer),
                Default::default(),
            )
            .map_err(|_| 0usize)?;
        self.factored.1 = true;
        Ok(())
    }

    /// Overwrites `b` with the solution of the real system.
    pub fn solve_real(&mut self, b: &mut [f64]) {
        assert!(self.factored.0, "a solve with no real factorisation");
        // Called only after a successful `factor` (the core solves with
        // factors it has), so `real` holds the factors of `lu`'s pattern.
        let lu = LuRef::new_unchecked(&self.lu, &self.real);
        lu.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(b, self.dim, 1),
            Par::Seq,
            MemStack::new(&mut self.buffer),
        );
    }

    /// Overwrites `(br, bi)` with the solution of the complex system with
    /// right-hand side `br + i bi`.
    pub fn solve_complex(&mut self, br: &mut [f64], bi: &mut [f64]) {
        assert!(self.factored.1, "a solve with no complex factorisation");
        for ((z, &r), &i) in self.complex_rhs.iter_mut().zip(br.iter()).zip(bi.iter()) {
            *z = c64::new(r, i);
        }
        let lu = LuRef::new_unchecked(&self.lu, &self.complex);
        lu.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut self.complex_rhs, self.dim, 1),
            Par::Seq,
            MemStack::new(&mut self.buffer),
        );
        for ((z, r), i) in self
            .complex_rhs
            .iter()
            .zip(br.iter_mut())
            .zip(bi.iter_mut())
        {
            *r = z.re;
            *i = z.im;
        }
    }

    /// `out = J' x` from the values `jyp`.
    pub fn jyp_mul(&self, jyp: &[f64], x: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for (&(r, c), &v) in self.jyp.iter().zip(jyp) {
            out[r] += v * x[c];
        }
    }
}
