//! Every piece of the KKT system of [`crate::kkt`] as one compiled program.
//!
//! [`Compiled::new`] traces a scalar field `ℓ` (the Lagrangian, or `L + λᵀg`)
//! and the scene's constraints `g`, `f` once into a [`Graph`], adds the
//! derivatives the system needs as graph nodes, and keeps one [`Program`]
//! for all of them:
//!
//! * `M = ∂²ℓ/∂q̇²` (upper triangle) and
//!   `Q = ∂ℓ/∂q − (∂²ℓ/∂q̇∂q) q̇ − ∂²ℓ/∂q̇∂t`,
//! * `g`, `G = ∂g/∂q̇`, `ġ₀ = (∂g/∂q) q̇ + ∂g/∂t`,
//! * `f`, `F = ∂f/∂q`, `ḟ = F q̇ + ∂f/∂t`, `f̈₀ = (∂ḟ/∂q) q̇ + ∂ḟ/∂t`,
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
    n: usize,
    s: usize,
    k: usize,
    np: usize,
    /// The field's type, checked by [`crate::kkt::Kkt`] in debug builds.
    pub(crate) field: &'static str,
    graph_nodes: usize,
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
        if !g.is_exact() {
            let mut what: Vec<&str> = g.leaks().iter().chain(g.unsupported()).copied().collect();
            what.sort_unstable();
            what.dedup();
            return Err(Refused(format!(
                "the trace depends on values ({}): scalar passes",
                what.join(", ")
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
        // M (upper triangle) and Q.
        let momenta: Vec<u32> = (0..n).map(|i| g.diff(ell_id, qd_var(i))).collect();
        for i in 0..n {
            for j in i..n {
                outputs.push(g.diff(momenta[i], qd_var(j)));
            }
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
        for &gi in &g_ids {
            for j in 0..n {
                outputs.push(g.diff(gi, qd_var(j)));
            }
        }
        for &gi in &g_ids {
            outputs.push(rate(&mut g, gi, &q_vars, &qd_node, t_var));
        }
        // f, F, ḟ, f̈₀.
        outputs.extend(&f_ids);
        for &fi in &f_ids {
            for j in 0..n {
                outputs.push(g.diff(fi, q_var(j)));
            }
        }
        let f_rates: Vec<u32> = f_ids
            .iter()
            .map(|&fi| rate(&mut g, fi, &q_vars, &qd_node, t_var))
            .collect();
        outputs.extend(&f_rates);
        for &r in &f_rates {
            outputs.push(rate(&mut g, r, &q_vars, &qd_node, t_var));
        }
        Ok(Compiled {
            program: Program::new(&g, &outputs, inputs),
            n,
            s,
            k,
            np,
            field: std::any::type_name::<F>(),
            graph_nodes: g.len(),
        })
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

/// The pieces of the last [`Compiled::eval`], as slices of its outputs.
pub struct Pieces<'a, T> {
    /// Upper triangle of `M`, row by row.
    pub mass_upper: &'a [T],
    pub force: &'a [T],
    pub g: &'a [T],
    /// `G`, row-major (`s × n`).
    pub g_jac: &'a [T],
    pub g_rate0: &'a [T],
    pub f: &'a [T],
    /// `F`, row-major (`k × n`).
    pub f_jac: &'a [T],
    pub f_rate: &'a [T],
    pub f_accel0: &'a [T],
}

impl<T: Copy> Pieces<'_, T> {
    /// `M` (both triangles) into the `n × n` block at the top left of `m`.
    pub fn mass_into(&self, m: &mut nalgebra::DMatrix<T>, n: usize) {
        let mut o = 0;
        for i in 0..n {
            for j in i..n {
                m[(i, j)] = self.mass_upper[o];
                m[(j, i)] = self.mass_upper[o];
                o += 1;
            }
        }
    }
}

impl<T> Workspace<T> {
    /// The outputs of the last evaluation, split into the pieces.
    pub fn pieces(&self, c: &Compiled) -> Pieces<'_, T> {
        let (n, s, k) = (c.n, c.s, c.k);
        let mut rest: &[T] = &self.out;
        let mut take = |len: usize| {
            let (a, b) = rest.split_at(len);
            rest = b;
            a
        };
        Pieces {
            mass_upper: take(n * (n + 1) / 2),
            force: take(n),
            g: take(s),
            g_jac: take(s * n),
            g_rate0: take(s),
            f: take(k),
            f_jac: take(k * n),
            f_rate: take(k),
            f_accel0: take(k),
        }
    }
}
