//! Every piece of the KKT system of [`crate::kkt`] as one compiled program.
//!
//! [`Compiled::new`] traces a scalar field `ℓ` (the Lagrangian, or `L + λᵀg`)
//! and the scene's constraints `g`, `f` once into a [`Graph`], adds the
//! derivatives the system needs as graph nodes, and keeps one [`Program`]
//! for all of them:
//!
//! * `M = ∂²ℓ/∂q̇²` (the structural nonzeros of its upper triangle) and
//!   `Q = ∂ℓ/∂q − (∂²ℓ/∂q̇∂q) q̇ − ∂²ℓ/∂q̇∂t`,
//! * `g`, `G = ∂g/∂q̇`, `ġ₀ = (∂g/∂q) q̇ + ∂g/∂t`,
//! * `f`, `F = ∂f/∂q`, `ḟ = F q̇ + ∂f/∂t`, `f̈₀ = (∂ḟ/∂q) q̇ + ∂ḟ/∂t`,
//!
//! The matrices `M`, `G` and `F` are kept sparse: an entry is computed (and
//! listed in the [`Pattern`]) only where its derivative is not the constant
//! zero of the graph. The pattern is structural, found once from the trace
//! (an entry that is zero only at some states stays in it); differentiation
//! visits only the inputs a node depends on, so tracing and evaluation grow
//! with the number of nonzeros, not with `n²`.
//!
//! the same quantities, by the same definitions, as the scalar dual passes
//! of [`crate::ad::Jet`] — but every subexpression (each `sin φ`, each
//! product of a parameter with a velocity) is computed once for all of them,
//! where the passes repeat the whole Lagrangian per derivative direction.
//! The scene still writes only its Lagrangian and constraints.
//!
//! A trace holds at every state only if the scene's functions do not branch
//! on values; [`Compiled::new`] refuses (and the passes stay in use) when
//! tracing met a branch or a function the graph does not represent.

use std::sync::{Arc, OnceLock};

use crate::graph::{Graph, Node, Program, Tracer, trace};
use crate::scene::{Holonomic, Nonholonomic, Scalar, ScalarField, Scene, VectorField};

/// The compiled pieces of one field and one scene's constraints.
#[derive(Debug, Clone)]
pub struct Compiled {
    program: Program,
    pattern: Pattern,
    /// The inputs every output depends on (sorted; input numbering of
    /// [`Compiled::dependencies`]), parallel to the outputs.
    deps: Vec<Vec<u32>>,
    /// Where each piece starts among the outputs ([`Pattern::layout`]).
    layout: Layout,
    n: usize,
    s: usize,
    k: usize,
    np: usize,
    /// The field's type, checked by [`crate::kkt::Kkt`] in debug builds.
    pub(crate) field: &'static str,
    graph_nodes: usize,
    /// The KKT system with ideal rows as native code ([`crate::jit`]):
    /// systems of at most [`crate::linalg::BLOCK_MAX`] unknowns.
    #[cfg(feature = "jit")]
    kkt_native: Option<(Arc<crate::jit::KktNative>, crate::jit::KktDims)>,
}

/// The structural nonzeros of the compiled matrices, as `(row, column)`
/// pairs in the order of their values in [`Pieces`] (row by row, columns
/// increasing).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Pattern {
    /// Upper triangle of `M` (`row ≤ column`).
    pub mass: Vec<(u32, u32)>,
    /// `G` (`s × n`).
    pub g_jac: Vec<(u32, u32)>,
    /// `F` (`k × n`).
    pub f_jac: Vec<(u32, u32)>,
}

/// Where an entry of the KKT matrix `K = [M Gᵀ Fᵀ; G 0 0; F 0 0]` takes
/// its value from: the index of that value among the program's outputs
/// ([`KktSource::value`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KktSource(pub u32);

impl KktSource {
    /// The entry's value among `outputs` (all outputs of one evaluation, as
    /// [`Workspace::outputs`] or [`Pieces::outputs`]).
    #[inline]
    pub fn value<T>(self, outputs: &[T]) -> &T {
        &outputs[self.0 as usize]
    }
}

/// The program's outputs in order, one per [`Pieces`] field: the upper
/// triangle of `M`, `Q`, `g`, `G`, `ġ₀`, `f`, `F`, `ḟ`, `f̈₀`.
const PIECES: usize = 9;

/// Where each of the [`PIECES`] starts among the outputs, and (last) the
/// number of outputs.
pub(crate) type Layout = [usize; PIECES + 1];

impl Pattern {
    /// Where each piece starts among the outputs of a program for `n`
    /// coordinates, `s` velocity and `k` position constraints, and (last)
    /// the number of outputs.
    pub(crate) fn layout(&self, n: usize, s: usize, k: usize) -> Layout {
        let lens = [
            self.mass.len(),
            n,
            s,
            self.g_jac.len(),
            s,
            k,
            self.f_jac.len(),
            k,
            k,
        ];
        let mut at = [0; PIECES + 1];
        for (i, len) in lens.into_iter().enumerate() {
            at[i + 1] = at[i] + len;
        }
        at
    }

    /// The structural nonzeros of `K` for `n` coordinates, `s` velocity and
    /// `k` position constraints, both triangles, as `(row, column,
    /// source)`: `M` (mirrored off its diagonal), then `G` at rows
    /// `n..n + s` with `Gᵀ`, then `F` at rows `n + s..` with `Fᵀ`, each in
    /// pattern order.
    pub fn kkt_entries(&self, n: usize, s: usize, k: usize) -> Vec<(u32, u32, KktSource)> {
        let at = self.layout(n, s, k);
        let mut entries =
            Vec::with_capacity(2 * (self.mass.len() + self.g_jac.len() + self.f_jac.len()));
        for (i, &(r, c)) in self.mass.iter().enumerate() {
            let src = KktSource((at[0] + i) as u32);
            entries.push((r, c, src));
            if r != c {
                entries.push((c, r, src));
            }
        }
        for (rows, row0, start) in [(&self.g_jac, n, at[3]), (&self.f_jac, n + s, at[6])] {
            for (i, &(r, c)) in rows.iter().enumerate() {
                let (r, src) = (r + row0 as u32, KktSource((start + i) as u32));
                entries.push((r, c, src));
                entries.push((c, r, src));
            }
        }
        entries
    }
}

/// Where the pieces of the KKT system's right-hand side start among a
/// program's outputs: `Q` (`n` values), `g` and `ġ₀` (`s` each), `f`, `ḟ`
/// and `f̈₀` (`k` each).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct RhsAt {
    pub force: usize,
    pub g: usize,
    pub g_rate0: usize,
    pub f: usize,
    pub f_rate: usize,
    pub f_accel0: usize,
}

/// Why a field was not compiled.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Refused(pub String);

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// Values of the inputs at the trace point: irregular, so that no
/// coincidence (a zero, two equal coordinates) shapes the trace. They only
/// matter where a trace is refused anyway (a branch read them).
fn trace_value(i: usize) -> f64 {
    0.3 + 0.137 * i as f64 - 0.011 * (i * i) as f64
}

impl Compiled {
    /// Traces `ell` (with `np` parameters `p`) and `scene`'s constraints
    /// and compiles the KKT pieces listed in the [module docs](self).
    pub fn new<F: ScalarField, S: Scene>(
        ell: &F,
        np: usize,
        scene: &S,
    ) -> Result<Compiled, Refused> {
        let info = scene.info();
        let (n, s, k) = (info.n(), info.s(), info.k());
        let inputs = 1 + 2 * n + np;
        let (mut g, (ell_id, g_ids, f_ids)) = trace(Graph::new(), || {
            let var = |i: usize| Tracer::input(i as u32, trace_value(i));
            let t = var(0);
            let q: Vec<Tracer> = (0..n).map(|i| var(1 + i)).collect();
            let qd: Vec<Tracer> = (0..n).map(|i| var(1 + n + i)).collect();
            let p: Vec<Tracer> = (0..np).map(|i| var(1 + 2 * n + i)).collect();
            let l = ell.eval(t, &q, &qd, &p);
            let mut gv = vec![Tracer::from(0.0); s];
            if s > 0 {
                Nonholonomic(scene).eval(t, &q, &qd, &mut gv);
            }
            let mut fv = vec![Tracer::from(0.0); k];
            if k > 0 {
                Holonomic(scene).eval(t, &q, &qd, &mut fv);
            }
            (
                l.id,
                gv.iter().map(|x| x.id).collect::<Vec<_>>(),
                fv.iter().map(|x| x.id).collect::<Vec<_>>(),
            )
        });
        if let Some(what) = g.inexact() {
            return Err(Refused(format!(
                "the trace depends on values ({what}): scalar passes"
            )));
        }
        let t_var = 0u32;
        let q_var = |j: usize| (1 + j) as u32;
        let qd_var = |j: usize| (1 + n + j) as u32;
        let qd_node: Vec<u32> = (0..n)
            .map(|j| g.input(qd_var(j), trace_value(1 + n + j)))
            .collect();
        let q_vars: Vec<u32> = (0..n).map(q_var).collect();

        let mut outputs = Vec::new();
        let mut pattern = Pattern::default();
        // The nonzero derivatives of `x` with respect to the inputs `range`
        // (columns `input - range.start`), in increasing order.
        let row = |g: &mut Graph,
                   x: u32,
                   r: usize,
                   range: std::ops::Range<u32>,
                   from: u32,
                   outputs: &mut Vec<u32>,
                   entries: &mut Vec<(u32, u32)>| {
            let deps: Vec<u32> = g
                .deps(x)
                .iter()
                .copied()
                .filter(|v| range.contains(v) && *v >= from)
                .collect();
            for v in deps {
                let d = g.diff(x, v);
                if !g.is_zero(d) {
                    outputs.push(d);
                    entries.push((r as u32, v - range.start));
                }
            }
        };
        let qd_range = qd_var(0)..qd_var(0) + n as u32;
        let q_range = q_var(0)..q_var(0) + n as u32;
        // M (upper triangle) and Q.
        let momenta: Vec<u32> = (0..n).map(|i| g.diff(ell_id, qd_var(i))).collect();
        for (i, &p_i) in momenta.iter().enumerate() {
            let (r, o, e) = (i, &mut outputs, &mut pattern.mass);
            row(&mut g, p_i, r, qd_range.clone(), qd_var(i), o, e);
        }
        for (i, &p_i) in momenta.iter().enumerate() {
            let dl = g.diff(ell_id, q_var(i));
            let conv = g.directional(p_i, &q_vars, &qd_node);
            let explicit = g.diff(p_i, t_var);
            let x = g.op(Node::Sub(dl, conv));
            outputs.push(g.op(Node::Sub(x, explicit)));
        }
        // g, G, ġ₀.
        outputs.extend(&g_ids);
        for (r, &gi) in g_ids.iter().enumerate() {
            let (o, e) = (&mut outputs, &mut pattern.g_jac);
            row(&mut g, gi, r, qd_range.clone(), 0, o, e);
        }
        for &gi in &g_ids {
            outputs.push(rate(&mut g, gi, &q_vars, &qd_node, t_var));
        }
        // f, F, ḟ, f̈₀.
        outputs.extend(&f_ids);
        for (r, &fi) in f_ids.iter().enumerate() {
            let (o, e) = (&mut outputs, &mut pattern.f_jac);
            row(&mut g, fi, r, q_range.clone(), 0, o, e);
        }
        let f_rates: Vec<u32> = f_ids
            .iter()
            .map(|&fi| rate(&mut g, fi, &q_vars, &qd_node, t_var))
            .collect();
        outputs.extend(&f_rates);
        for &r in &f_rates {
            outputs.push(rate(&mut g, r, &q_vars, &qd_node, t_var));
        }
        let deps = outputs.iter().map(|&o| g.deps(o).to_vec()).collect();
        let mut c = Compiled {
            program: Program::new(&g, &outputs, inputs),
            layout: pattern.layout(n, s, k),
            pattern,
            deps,
            n,
            s,
            k,
            np,
            field: std::any::type_name::<F>(),
            graph_nodes: g.len(),
            #[cfg(feature = "jit")]
            kkt_native: None,
        };
        #[cfg(feature = "jit")]
        {
            c.kkt_native = c.compile_kkt();
        }
        Ok(c)
    }

    /// The KKT system with ideal rows as native code, where it is small
    /// enough and Cranelift compiled it.
    #[cfg(feature = "jit")]
    fn compile_kkt(&self) -> Option<(Arc<crate::jit::KktNative>, crate::jit::KktDims)> {
        let (ops, outputs, inputs, constants) = self.program.parts();
        let dim = self.n + self.s + self.k;
        let at = self.rhs_at();
        let dims = crate::jit::KktDims {
            n: self.n,
            s: self.s,
            k: self.k,
            np: self.np,
            constants: constants.len(),
            outputs: outputs.len(),
            rhs_at: [at.force, at.g, at.g_rate0, at.f, at.f_rate, at.f_accel0],
            entries: (self.kkt_entries().into_iter())
                .map(|(r, c, src)| (r as usize + c as usize * dim, src.0))
                .collect(),
        };
        let native = crate::jit::kkt(ops, outputs, inputs, dims.clone())?;
        Some((native, dims))
    }

    /// The KKT system with ideal rows as native code ([`crate::jit`]), if
    /// it was compiled.
    #[cfg(feature = "jit")]
    pub(crate) fn kkt_native(&self) -> Option<&(Arc<crate::jit::KktNative>, crate::jit::KktDims)> {
        self.kkt_native.as_ref()
    }

    /// Checks (in debug builds) that the program was compiled for the field
    /// type `F`.
    pub(crate) fn check_field<F>(&self) {
        debug_assert_eq!(
            self.field,
            std::any::type_name::<F>(),
            "compiled for another field"
        );
    }

    /// Where the right-hand side's pieces start among the outputs.
    pub(crate) fn rhs_at(&self) -> RhsAt {
        let at = &self.layout;
        RhsAt {
            force: at[1],
            g: at[2],
            g_rate0: at[4],
            f: at[5],
            f_rate: at[7],
            f_accel0: at[8],
        }
    }

    /// Compiles the program's native code over `f64` and `Dual64` now
    /// ([`Program::prepare_native`]).
    pub fn prepare_native(&self) {
        self.program.prepare_native();
    }

    /// Whether the KKT system with ideal rows runs as native code over
    /// `f64` ([`crate::jit`]).
    pub fn has_native_kkt(&self) -> bool {
        #[cfg(feature = "jit")]
        return self.kkt_native.is_some();
        #[cfg(not(feature = "jit"))]
        false
    }

    /// Instructions per evaluation, of them transcendental calls, and the
    /// size of the graph they were taken from.
    pub fn size(&self) -> (usize, usize, usize) {
        (
            self.program.len(),
            self.program.transcendentals(),
            self.graph_nodes,
        )
    }

    /// Buffers for [`Compiled::eval`] over `T`.
    pub fn workspace<T: Scalar>(&self) -> Workspace<T> {
        let (_, outputs) = self.program.shape();
        Workspace {
            regs: self.program.registers(),
            out: vec![T::from(0.0); outputs],
        }
    }

    /// Evaluates every piece at `(t, q, q̇)` with parameters `p`; read them
    /// with [`Workspace::pieces`].
    pub fn eval<T: Scalar>(&self, w: &mut Workspace<T>, t: T, q: &[T], qd: &[T], p: &[T]) {
        let n = self.n;
        debug_assert_eq!(p.len(), self.np, "compiled field's parameters");
        // The inputs are the first registers (see `Program::run`).
        w.regs[0] = t;
        w.regs[1..1 + n].copy_from_slice(q);
        w.regs[1 + n..1 + 2 * n].copy_from_slice(qd);
        w.regs[1 + 2 * n..1 + 2 * n + self.np].copy_from_slice(p);
        self.program.run(&mut w.regs, &mut w.out);
    }

    /// `(n, s, k)`.
    pub fn dims(&self) -> (usize, usize, usize) {
        (self.n, self.s, self.k)
    }

    /// Number of the field's parameters `p` ([`Compiled::eval`]).
    pub fn parameters(&self) -> usize {
        self.np
    }

    /// The structural nonzeros of `M`, `G` and `F`.
    pub fn pattern(&self) -> &Pattern {
        &self.pattern
    }

    /// The structural nonzeros of this program's KKT matrix
    /// ([`Pattern::kkt_entries`] at its own dimensions).
    pub fn kkt_entries(&self) -> Vec<(u32, u32, KktSource)> {
        self.pattern.kkt_entries(self.n, self.s, self.k)
    }

    /// For every piece's value, the inputs it structurally depends on, in
    /// increasing order: `0` is `t`, `1 + j` is `q_j`, `1 + n + j` is `q̇_j`,
    /// `1 + 2n + j` is parameter `j`. A value whose list lacks an input has
    /// derivative zero with respect to it at every state.
    pub fn dependencies(&self) -> Pieces<'_, Vec<u32>> {
        split(self, &self.deps)
    }
}

/// The program of one formulation's field and scene, compiled on first use
/// and shared by every workspace built from it: the `f64` one of the
/// right-hand side, the `Dual64` one of Jacobian columns, the second-order
/// one of Taylor coefficients. One cache belongs to one scene (a
/// formulation bound to it); a refusal is cached too.
#[derive(Debug, Clone, Default)]
pub struct Programs(OnceLock<Result<Arc<Compiled>, Refused>>);

impl Programs {
    /// The program of `ell` (with `np` parameters) and `scene`'s
    /// constraints: [`Compiled::new`] the first time, the same one after.
    pub fn get<F: ScalarField, S: Scene>(
        &self,
        ell: &F,
        np: usize,
        scene: &S,
    ) -> Result<Arc<Compiled>, Refused> {
        self.0
            .get_or_init(|| Compiled::new(ell, np, scene).map(Arc::new))
            .clone()
    }
}

/// `(∂x/∂q) q̇ + ∂x/∂t`: the rate of a node along the motion with `q̈ = 0`.
fn rate(g: &mut Graph, x: u32, q_vars: &[u32], qd: &[u32], t_var: u32) -> u32 {
    let conv = g.directional(x, q_vars, qd);
    let explicit = g.diff(x, t_var);
    g.op(Node::Add(conv, explicit))
}

/// Registers (inputs first) and outputs of one [`Compiled`] over `T`.
#[derive(Debug, Clone)]
pub struct Workspace<T> {
    regs: Vec<T>,
    out: Vec<T>,
}

/// The pieces of the last [`Compiled::eval`], as slices of its outputs;
/// the matrices hold the values of their [`Pattern`]'s entries.
pub struct Pieces<'a, T> {
    pub pattern: &'a Pattern,
    /// All outputs, the pieces below in order.
    pub outputs: &'a [T],
    /// Upper triangle of `M`, at [`Pattern::mass`].
    pub mass_upper: &'a [T],
    pub force: &'a [T],
    pub g: &'a [T],
    /// `G` at [`Pattern::g_jac`].
    pub g_jac: &'a [T],
    pub g_rate0: &'a [T],
    pub f: &'a [T],
    /// `F` at [`Pattern::f_jac`].
    pub f_jac: &'a [T],
    pub f_rate: &'a [T],
    pub f_accel0: &'a [T],
}

impl<T: Scalar> Pieces<'_, T> {
    /// `M` (both triangles) into the `n × n` block at the top left of `m`,
    /// zeros included.
    pub fn mass_into(&self, m: &mut nalgebra::DMatrix<T>, n: usize) {
        m.view_mut((0, 0), (n, n)).fill(T::from(0.0));
        for (&(i, j), &v) in self.pattern.mass.iter().zip(self.mass_upper) {
            let (i, j) = (i as usize, j as usize);
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }

    /// `G` into rows `row..row + s` of `m` (`n` columns, zeros included).
    pub fn g_jac_into(&self, m: &mut nalgebra::DMatrix<T>, row: usize, n: usize) {
        scatter(m, row, n, self.g.len(), &self.pattern.g_jac, self.g_jac);
    }

    /// `G` into rows `row..row + s` of `m`, then `F` into the `k` rows
    /// after them (`n` columns, zeros included).
    pub fn jacobians_into(&self, m: &mut nalgebra::DMatrix<T>, row: usize, n: usize) {
        self.g_jac_into(m, row, n);
        let s = self.g.len();
        scatter(m, row + s, n, self.f.len(), &self.pattern.f_jac, self.f_jac);
    }
}

/// The `rows × n` block at row `row` of `m`: zeros, then `values` at `entries`.
fn scatter<T: Scalar>(
    m: &mut nalgebra::DMatrix<T>,
    row: usize,
    n: usize,
    rows: usize,
    entries: &[(u32, u32)],
    values: &[T],
) {
    m.view_mut((row, 0), (rows, n)).fill(T::from(0.0));
    for (&(r, j), &v) in entries.iter().zip(values) {
        m[(row + r as usize, j as usize)] = v;
    }
}

impl<T> Workspace<T> {
    /// The outputs of the last evaluation, split into the pieces.
    pub fn pieces<'a>(&'a self, c: &'a Compiled) -> Pieces<'a, T> {
        split(c, &self.out)
    }

    /// All outputs of the last evaluation, in the order of [`Pieces`].
    pub fn outputs(&self) -> &[T] {
        &self.out
    }

    /// The program's constants (the registers after the inputs, where
    /// [`crate::graph::Program::registers`] put them) and the outputs, for
    /// code that evaluates the program itself ([`crate::jit`]).
    pub(crate) fn constants_and_outputs(&mut self, c: &Compiled) -> (&[T], &mut [T]) {
        let inputs = 1 + 2 * c.n + c.np;
        (
            &self.regs[inputs..inputs + c.program.constants()],
            &mut self.out,
        )
    }
}

/// Outputs of `c` (values, or anything kept per output) split into the pieces.
fn split<'a, T>(c: &'a Compiled, out: &'a [T]) -> Pieces<'a, T> {
    Pieces::new(&c.pattern, &c.layout, out)
}

impl<'a, T> Pieces<'a, T> {
    /// The outputs `out` of a program with `pattern` and `layout`
    /// ([`Pattern::layout`]), split into the pieces.
    pub(crate) fn new(pattern: &'a Pattern, at: &Layout, out: &'a [T]) -> Self {
        debug_assert_eq!(out.len(), at[PIECES]);
        let piece = |i: usize| &out[at[i]..at[i + 1]];
        Pieces {
            pattern,
            outputs: out,
            mass_upper: piece(0),
            force: piece(1),
            g: piece(2),
            g_jac: piece(3),
            g_rate0: piece(4),
            f: piece(5),
            f_jac: piece(6),
            f_rate: piece(7),
            f_accel0: piece(8),
        }
    }
}
