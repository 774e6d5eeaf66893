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
//! those of Baumgarte stabilisation, zero otherwise; how the rows of `g`
//! enter is a [`GRows`] (the ideal constraint here, other kinds in the
//! realisations). The matrix is solved by
//! [`crate::linalg::solve_saddle`]: by block elimination where `M` is
//! clearly positive definite and the solution's backward error small,
//! otherwise equilibrated (so that singularity is judged independently of
//! units) and factorised by LU with partial pivoting, in a reused
//! workspace; over
//! `T = Dual64` the same solve yields directional derivatives (Jacobian
//! columns, time derivatives).

use std::sync::Arc;

use nalgebra::DMatrix;

use crate::ad::Jet;
use crate::compiled::{Compiled, KktSource, Pieces, Programs, Refused, Workspace};
use crate::constraints::ConstraintState;
use crate::linalg::{Lu, Singular, solve_saddle};
use crate::scene::{Scalar, ScalarField, Scene, SceneInfo};
use crate::sparse::{SPARSE_FROM, SparseKkt};
use crate::stab::Stabilisation;

/// How the rows of the nonholonomic constraints `g` enter the system: the
/// one place where formulations differ in the KKT system.
///
/// [`Ideal`] is the constraint itself (B, C); the realisations (crate
/// `nonholo-realise`) write compliant rows, or none with the constraint
/// acting through a force or through the field `ℓ`.
pub trait GRows {
    /// Whether `g`, `G` and `ġ₀` are evaluated before [`GRows::write`]
    /// (not when `g` acts only through the field `ℓ`).
    fn needs_g(&self) -> bool {
        true
    }

    /// Baumgarte gains `(α, β)` of the holonomic rows (zero: `f̈ = 0`).
    fn holonomic_gains(&self) -> (f64, f64) {
        (0.0, 0.0)
    }

    /// Writes rows and right-hand side `n..n + s` of the system, and may add
    /// to the force part `rhs[..n]`; `cs` holds `g`, `G`, `ġ₀` if
    /// [`GRows::needs_g`].
    fn write<T: Scalar>(
        &self,
        n: usize,
        cs: &ConstraintState<T>,
        matrix: &mut DMatrix<T>,
        rhs: &mut [T],
    );

    /// `Some(α)` if the rows are the ideal constraint `G q̈ = −ġ₀ − 2α g`:
    /// with a compiled program, [`Kkt::assemble`] then takes `G` from the
    /// program's entries (not from [`GRows::write`]) and [`Kkt::solve`]
    /// may go sparse.
    fn ideal_gain(&self) -> Option<f64> {
        None
    }
}

/// The ideal constraint, `G q̈ = −ġ₀ − 2α g`, with the holonomic rows
/// `F q̈ = −f̈₀ − 2α ḟ − β² f`; the gains are those of Baumgarte
/// stabilisation, zero otherwise (B, C).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ideal(pub Stabilisation);

impl GRows for Ideal {
    fn holonomic_gains(&self) -> (f64, f64) {
        self.0.gains()
    }

    fn ideal_gain(&self) -> Option<f64> {
        Some(self.0.gains().0)
    }

    fn write<T: Scalar>(
        &self,
        n: usize,
        cs: &ConstraintState<T>,
        matrix: &mut DMatrix<T>,
        rhs: &mut [T],
    ) {
        let alpha = self.0.gains().0;
        cs.write_rows(0..cs.s, matrix, n);
        for i in 0..cs.s {
            rhs[n + i] = -cs.g_rate0[i] - cs.g[i] * (2.0 * alpha);
        }
    }
}

/// The program's force into `force` and its constraint values into `cs`
/// (the Jacobians stay in the pieces: dense users scatter them).
fn load<T: Scalar>(pc: &Pieces<'_, T>, cs: &mut ConstraintState<T>, force: &mut [T]) {
    force.copy_from_slice(pc.force);
    cs.g.copy_from_slice(pc.g);
    cs.g_rate0.copy_from_slice(pc.g_rate0);
    cs.f.copy_from_slice(pc.f);
    cs.f_rate.copy_from_slice(pc.f_rate);
    cs.f_accel0.copy_from_slice(pc.f_accel0);
}

/// Workspace of the KKT solve over base scalar `T`.
#[derive(Debug, Clone)]
pub struct Kkt<T: Scalar = f64> {
    n: usize,
    pub jet: Jet<T>,
    /// Constraint values and rates of the last evaluation. Its dense
    /// Jacobian `cs.jac` is filled where the rows need it (the scalar
    /// passes, or rows other than [`Ideal`]): with ideal rows from a
    /// compiled program it is unallocated or stale, and `G`, `F` live in
    /// the system's matrix.
    pub cs: ConstraintState<T>,
    matrix: DMatrix<T>,
    lu: Lu,
    /// Equilibration of the last solve that went through the LU (see
    /// [`crate::linalg::solve_saddle`]; stale after block elimination).
    scale: Vec<f64>,
    /// Right-hand side, then solution `(q̈, μ_g, μ_f)`.
    pub sol: Vec<T>,
    /// The field and constraints compiled into one program
    /// ([`Kkt::compile`]), with its buffers; `None`: the scalar passes of
    /// [`Jet`].
    compiled: Option<(Arc<Compiled>, Workspace<T>)>,
    /// The program's entries of the KKT matrix
    /// ([`crate::compiled::Pattern::kkt_entries`]) by their place in the
    /// dense matrix's column-major storage, scattered straight into it with
    /// ideal rows; made with the dense storage (a sparse system keeps its
    /// own list).
    entries: Vec<(usize, KktSource)>,
    /// The system stored sparse ([`crate::sparse`]): systems of at least
    /// [`SPARSE_FROM`] rows with a compiled program, over `f64` or `Dual64`
    /// (Jacobian columns).
    sparse: Option<SparseKkt>,
}

impl<T: Scalar> Kkt<T> {
    pub fn new(n: usize, s: usize, k: usize) -> Self {
        let dim = n + s + k;
        let mut kkt = Kkt {
            n,
            jet: Jet::new(n, s.max(k)),
            cs: ConstraintState::new(0, s, k),
            matrix: DMatrix::from_element(0, 0, T::from(0.0)),
            lu: Lu::new(dim),
            scale: vec![1.0; dim],
            sol: vec![T::from(0.0); dim],
            compiled: None,
            entries: Vec::new(),
            sparse: None,
        };
        // Large systems get their dense storage when a dense path first
        // needs it (never, when they solve sparse).
        if dim < SPARSE_FROM {
            kkt.dense();
        }
        kkt
    }

    /// The dense matrix, constraint Jacobian and the program's entries,
    /// made if not yet.
    fn dense(&mut self) {
        let dim = self.sol.len();
        if self.matrix.nrows() != dim {
            self.matrix = DMatrix::from_element(dim, dim, T::from(0.0));
        }
        if self.cs.jac.ncols() != self.n {
            self.cs.jac = DMatrix::from_element(self.cs.s + self.cs.k, self.n, T::from(0.0));
        }
        if let (true, Some((c, _))) = (self.entries.is_empty(), &self.compiled) {
            let place = |r: u32, col: u32| r as usize + col as usize * dim;
            self.entries = (c.kkt_entries().into_iter())
                .map(|(r, col, src)| (place(r, col), src))
                .collect();
        }
    }

    /// Whether [`Kkt::solve`] solves sparse ([`crate::sparse`]).
    pub fn is_sparse(&self) -> bool {
        self.sparse.is_some()
    }

    /// Solve dense whatever the size (a reference for the sparse path).
    pub fn force_dense(&mut self) {
        self.sparse = None;
        self.dense();
    }

    /// Solve sparse whatever the size, if the program compiled and `T` is
    /// real (for measuring where [`SPARSE_FROM`] should be); `Err` says
    /// why not.
    pub fn force_sparse(&mut self) -> Result<(), String> {
        let Some((c, _)) = &self.compiled else {
            return Err("no compiled program: the scalar passes solve dense".into());
        };
        if !(T::REAL || T::FIRST_ORDER) {
            return Err(
                "the sparse path is real or first-order dual; higher duals solve dense".into(),
            );
        }
        self.sparse = Some(SparseKkt::new(c.kkt_entries(), self.n, self.sol.len())?);
        Ok(())
    }

    /// Compiles the field `ell` (with `np` parameters) and `scene`'s
    /// constraints into one program ([`crate::compiled`]) that every later
    /// [`Kkt::assemble`] evaluates instead of the scalar passes; keeps the
    /// passes, and says why, where the trace does not hold at every state.
    /// `assemble` must then be called with the same field.
    pub fn compile<F: ScalarField, S: Scene>(
        &mut self,
        ell: &F,
        np: usize,
        scene: &S,
    ) -> Result<(), Refused> {
        self.use_program(Arc::new(Compiled::new(ell, np, scene)?));
        Ok(())
    }

    /// Makes [`Kkt::assemble`] evaluate `c` (see [`Kkt::compile`]).
    pub fn use_program(&mut self, c: Arc<Compiled>) {
        debug_assert_eq!(c.dims(), (self.n, self.cs.s, self.cs.k));
        let w = c.workspace();
        self.sparse = None;
        if (T::REAL || T::FIRST_ORDER) && self.sol.len() >= SPARSE_FROM {
            // A pattern faer refuses stays dense (and its solve then says
            // where the matrix is singular).
            self.sparse = SparseKkt::new(c.kkt_entries(), self.n, self.sol.len()).ok();
        }
        self.entries.clear();
        self.compiled = Some((c, w));
    }

    /// [`Kkt::use_program`] with the program of `programs` (compiled by the
    /// first workspace that asks), keeping the scalar passes where it was
    /// refused (the refusal is then in [`Kkt::compiled`]'s `None`).
    pub fn compiled_for<F: ScalarField, S: Scene>(
        mut self,
        programs: &Programs,
        ell: &F,
        np: usize,
        scene: &S,
    ) -> Self {
        if let Ok(c) = programs.get(ell, np, scene) {
            self.use_program(c);
        }
        self
    }

    /// The compiled program in use, if any.
    pub fn compiled(&self) -> Option<&Compiled> {
        self.compiled.as_ref().map(|(c, _)| &**c)
    }

    /// A workspace for the constraints of a scene.
    pub fn for_scene(info: &SceneInfo) -> Self {
        Kkt::new(info.n(), info.s(), info.k())
    }

    /// `q̈` of the last solve.
    pub fn qdd(&self) -> &[T] {
        &self.sol[..self.n]
    }

    /// The assembled matrix and right-hand side of [`Kkt::assemble`]
    /// (before any solve overwrites the right-hand side with the solution).
    /// Only [`Kkt::assemble`] fills it: a sparse [`Kkt::solve`] leaves it
    /// empty (`0 × 0`) or stale, so call `assemble` before reading it.
    pub fn system(&self) -> (&DMatrix<T>, &[T]) {
        (&self.matrix, &self.sol)
    }

    /// Mutable access to the solution vector, for a solver other than the
    /// LU of [`Kkt::solve`] that writes `(q̈, μ_g, μ_f)` there.
    pub fn sol_mut(&mut self) -> &mut [T] {
        &mut self.sol
    }

    /// `(μ_g, μ_f)` of the last solve.
    pub fn mu(&self) -> &[T] {
        &self.sol[self.n..]
    }

    /// Assembles the system at `(t, q, q̇)` for the field `ell` with
    /// parameters `p`, the rows of `g` entering as `rows` says, without
    /// solving it: [`Kkt::system`] then reads it (Gauss's principle hands
    /// it to a conic solver), [`Kkt::solve`] assembles and solves. Ideal
    /// rows from a compiled program scatter its entries straight into the
    /// matrix; other rows write theirs from `G` in [`Kkt::cs`].
    #[allow(clippy::too_many_arguments)]
    pub fn assemble<F: ScalarField, S: Scene, R: GRows>(
        &mut self,
        ell: &F,
        p: &[T],
        scene: &S,
        rows: &R,
        t: T,
        q: &[T],
        qd: &[T],
    ) {
        self.dense();
        let n = self.n;
        let (s, k) = (self.cs.s, self.cs.k);
        if let (Some(alpha), Some(_)) = (rows.ideal_gain(), &self.compiled) {
            self.eval_ideal::<F, R>(p, rows, alpha, t, q, qd);
            self.scatter_entries();
            return;
        }
        self.matrix.as_mut_slice().fill(T::from(0.0));
        if let Some((c, w)) = &mut self.compiled {
            c.check_field::<F>();
            c.eval(w, t, q, qd, p);
            let pc = w.pieces(c);
            pc.mass_into(&mut self.matrix, n);
            load(&pc, &mut self.cs, &mut self.sol[..n]);
            pc.jacobians_into(&mut self.cs.jac, 0, n);
            if s > 0 {
                rows.write(n, &self.cs, &mut self.matrix, &mut self.sol);
            }
            if k > 0 {
                self.holonomic_rows(rows);
            }
            return;
        }
        self.jet.mass_and_force(
            ell,
            t,
            q,
            qd,
            p,
            &mut self.matrix.view_mut((0, 0), (n, n)),
            &mut self.sol[..n],
        );
        if s > 0 {
            if rows.needs_g() {
                self.cs
                    .evaluate_nonholonomic(&mut self.jet, scene, t, q, qd);
            }
            rows.write(n, &self.cs, &mut self.matrix, &mut self.sol);
        }
        if k > 0 {
            self.cs.evaluate_holonomic(&mut self.jet, scene, t, q, qd);
            self.holonomic_rows(rows);
        }
    }

    /// The rows of `f` from the evaluated constraint state.
    fn holonomic_rows<R: GRows>(&mut self, rows: &R) {
        let (n, s, k) = (self.n, self.cs.s, self.cs.k);
        self.cs.write_rows(s..s + k, &mut self.matrix, n + s);
        self.holonomic_rhs(rows);
    }

    /// The right-hand side of the rows of `f`.
    fn holonomic_rhs<R: GRows>(&mut self, rows: &R) {
        let (n, s, k) = (self.n, self.cs.s, self.cs.k);
        let (alpha, beta) = rows.holonomic_gains();
        for i in 0..k {
            self.sol[n + s + i] = -self.cs.f_accel0[i]
                - self.cs.f_rate[i] * (2.0 * alpha)
                - self.cs.f[i] * (beta * beta);
        }
    }

    /// Assembles and solves the system at `(t, q, q̇)` for the field `ell`
    /// with parameters `p`, the rows of `g` entering as `rows` says: one
    /// sparse LU where the system is sparse (ideal rows from a compiled
    /// program), [`Kkt::assemble`] and [`Kkt::solve_assembled`] otherwise.
    #[allow(clippy::too_many_arguments)]
    pub fn solve<F: ScalarField, S: Scene, R: GRows>(
        &mut self,
        ell: &F,
        p: &[T],
        scene: &S,
        rows: &R,
        t: T,
        q: &[T],
        qd: &[T],
    ) -> Result<(), Singular> {
        if let (Some(alpha), true) = (rows.ideal_gain(), self.sparse.is_some()) {
            self.eval_ideal::<F, R>(p, rows, alpha, t, q, qd);
            let (Some((c, w)), Some(sparse)) = (&self.compiled, &mut self.sparse) else {
                unreachable!("a sparse system has a program");
            };
            return sparse.solve(&w.pieces(c), &mut self.sol);
        }
        #[cfg(feature = "jit")]
        if let Some(alpha) = rows.ideal_gain()
            && let Some(done) = self.solve_native::<F, R>(p, rows, alpha, t, q, qd)
        {
            return done;
        }
        self.assemble(ell, p, scene, rows, t, q, qd);
        self.solve_in_place()
    }

    /// Ideal rows over `f64` by the KKT system's native code
    /// ([`crate::jit`]): the program, the assembly and the block
    /// elimination of [`solve_saddle`] in one call, the same arithmetic.
    /// Where the elimination declines, the system is assembled from the
    /// program's outputs and solved as [`Kkt::solve_assembled`] does.
    /// `None` where there is no such code (`T` is not `f64`, the system is
    /// larger than [`crate::linalg::BLOCK_MAX`], native code is off).
    #[cfg(feature = "jit")]
    fn solve_native<F, R: GRows>(
        &mut self,
        p: &[T],
        rows: &R,
        alpha: f64,
        t: T,
        q: &[T],
        qd: &[T],
    ) -> Option<Result<(), Singular>> {
        let Kkt {
            compiled, sol, cs, ..
        } = self;
        let (c, w) = compiled.as_mut()?;
        let (native, dims) = c.kkt_native()?;
        c.check_field::<F>();
        let (q, qd, p) = (T::as_real(q)?, T::as_real(qd)?, T::as_real(p)?);
        let (alpha_f, beta) = rows.holonomic_gains();
        let (constants, out) = w.constants_and_outputs(c);
        let inputs = crate::jit::KktInputs {
            t: t.re(),
            q,
            qd,
            p,
            constants: T::as_real(constants)?,
        };
        let pieces = [
            T::as_real_mut(&mut cs.g)?,
            T::as_real_mut(&mut cs.g_rate0)?,
            T::as_real_mut(&mut cs.f)?,
            T::as_real_mut(&mut cs.f_rate)?,
            T::as_real_mut(&mut cs.f_accel0)?,
        ];
        let gains = [alpha, alpha_f, beta];
        let (out, sol) = (T::as_real_mut(out)?, T::as_real_mut(sol)?);
        if native.solve(dims, &inputs, gains, out, sol, pieces) {
            // As after the Rust solve: an infinite solution can pass the
            // backward-error test (∞ ≤ 1e-13·∞) where no term is 0·∞.
            return Some(self.finite());
        }
        self.load_constraints();
        self.dense();
        self.ideal_rhs(rows, alpha);
        self.scatter_entries();
        Some(self.solve_in_place())
    }

    /// Ideal rows from the compiled program: evaluates it at `(t, q, q̇)`,
    /// loads its constraint values into [`Kkt::cs`] and writes the
    /// right-hand side straight from its outputs; its entries
    /// ([`crate::compiled::Pattern::kkt_entries`]) make the matrix.
    fn eval_ideal<F: ScalarField, R: GRows>(
        &mut self,
        p: &[T],
        rows: &R,
        alpha: f64,
        t: T,
        q: &[T],
        qd: &[T],
    ) {
        let Some((c, w)) = &mut self.compiled else {
            unreachable!("the ideal path needs a program");
        };
        c.check_field::<F>();
        c.eval(w, t, q, qd, p);
        self.load_constraints();
        self.ideal_rhs(rows, alpha);
    }

    /// The constraint values of the program's last outputs into [`Kkt::cs`].
    fn load_constraints(&mut self) {
        let Some((c, w)) = &self.compiled else {
            unreachable!("the ideal path needs a program");
        };
        // Index by index rather than by `load`: these pieces hold a few
        // values each, and a copy per piece costs more than the values.
        let (at, out, cs) = (c.rhs_at(), w.outputs(), &mut self.cs);
        for i in 0..cs.s {
            cs.g[i] = out[at.g + i];
            cs.g_rate0[i] = out[at.g_rate0 + i];
        }
        for i in 0..cs.k {
            cs.f[i] = out[at.f + i];
            cs.f_rate[i] = out[at.f_rate + i];
            cs.f_accel0[i] = out[at.f_accel0 + i];
        }
    }

    /// The right-hand side of ideal rows from the program's last outputs
    /// and [`Kkt::cs`] ([`Kkt::load_constraints`]).
    fn ideal_rhs<R: GRows>(&mut self, rows: &R, alpha: f64) {
        let Some((c, w)) = &self.compiled else {
            unreachable!("the ideal path needs a program");
        };
        let (n, at, out, cs) = (self.n, c.rhs_at(), w.outputs(), &self.cs);
        self.sol[..n].copy_from_slice(&out[at.force..at.force + n]);
        for i in 0..cs.s {
            self.sol[n + i] = -cs.g_rate0[i] - cs.g[i] * (2.0 * alpha);
        }
        self.holonomic_rhs(rows);
    }

    /// The matrix from the program's entries (ideal rows), zero elsewhere.
    fn scatter_entries(&mut self) {
        let Some((_, w)) = &self.compiled else {
            unreachable!("the ideal path needs a program");
        };
        let (m, out) = (self.matrix.as_mut_slice(), w.outputs());
        m.fill(T::from(0.0));
        for &(at, src) in &self.entries {
            m[at] = *src.value(out);
        }
    }

    /// Solves the system of the last [`Kkt::assemble`] in place.
    ///
    /// A solution with a non-finite entry (a right-hand side that
    /// overflowed, or a NaN from a derivative not defined at the state) is
    /// reported as a [`Singular`] with a NaN pivot, as a non-finite matrix is.
    pub fn solve_assembled(&mut self) -> Result<(), Singular> {
        self.dense();
        self.solve_in_place()
    }

    /// [`Kkt::solve_assembled`] on a dense storage already made.
    fn solve_in_place(&mut self) -> Result<(), Singular> {
        let n = self.n;
        solve_saddle(
            &mut self.matrix,
            n,
            &mut self.lu,
            &mut self.scale,
            &mut self.sol,
        )?;
        self.finite()
    }

    /// A [`Singular`] with a NaN pivot at the first non-finite entry of the
    /// solution, if any.
    fn finite(&self) -> Result<(), Singular> {
        match self.sol.iter().position(|x| !x.re().is_finite()) {
            Some(column) => Err(Singular {
                column,
                pivot: f64::NAN,
                scale: f64::NAN,
            }),
            None => Ok(()),
        }
    }
}
