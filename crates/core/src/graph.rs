//! Scene functions traced once into an expression graph, differentiated
//! symbolically on the graph, and evaluated as a straight-line program.
//!
//! A scene's Lagrangian and constraints are written once over
//! [`Scalar`](crate::Scalar). Evaluated with [`Tracer`] numbers they record
//! every operation into a [`Graph`] instead of computing derivatives; the
//! graph is hash-consed (an operation on the same operands is one node:
//! common subexpressions, `sin φ` above all, exist once), folds constants
//! and the identities of `0` and `1`, and puts the operands of `+` and `·`
//! in a canonical order. [`Graph::diff`] adds the derivative of a node with
//! respect to an input as more nodes of the same graph, so second
//! derivatives are derivatives of derivatives and share everything they
//! can. [`Program`] keeps the nodes some outputs need, in order, and
//! evaluates them for any [`Scalar`] — `f64` for values, `Dual64` for a
//! Jacobian column — with no allocation.
//!
//! A trace is valid for every state only if the function's operations do
//! not depend on the values: a branch on a value (`re()`, `modulus()`, a
//! comparison, `is_positive()`) is recorded as a *leak*, and so is a
//! function the graph does not differentiate ([`Graph::unsupported`]); a
//! caller then keeps the scalar dual passes of [`crate::ad`].

use std::cell::RefCell;
use std::collections::HashMap;
use std::fmt;
use std::iter::{Product, Sum};
use std::ops::{
    Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Rem, RemAssign, Sub, SubAssign,
};

use num_dual::{DualNum, DualStruct, Mappable};
use num_traits::{FromPrimitive, Inv, Num, One, Signed, Zero};

use crate::scene::Scalar;

/// One operation of the graph; operands are node indices, which are always
/// smaller than the node's own (the graph is in topological order).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Node {
    /// A constant, by its bits (so that nodes hash).
    Const(u64),
    /// Input `i` of the traced function.
    Input(u32),
    Add(u32, u32),
    Sub(u32, u32),
    Mul(u32, u32),
    Div(u32, u32),
    Neg(u32),
    Recip(u32),
    Powi(u32, i32),
    /// `x^p` for a constant `p` (by its bits).
    Powf(u32, u64),
    Sqrt(u32),
    Exp(u32),
    Ln(u32),
    Sin(u32),
    Cos(u32),
    Tan(u32),
    Asin(u32),
    Acos(u32),
    Atan(u32),
    Sinh(u32),
    Cosh(u32),
    Tanh(u32),
    Abs(u32),
    /// `±1` by the sign of the operand (the derivative of `Abs`).
    Signum(u32),
    /// `atan2(y, x)` of operands `(y, x)` on the branch of `arctan(y/x)`
    /// nearest to a constant (by its bits; NaN: `atan2`'s own branch), as
    /// [`crate::scene::atan2_near`] computes it.
    Angle(u32, u32, u64),
}

/// The `near` of [`Node::Angle`] from its value (NaN: none).
pub(crate) fn near_of(near: f64) -> Option<f64> {
    near.is_finite().then_some(near)
}

/// An expression graph under construction; see the [module docs](self).
#[derive(Debug, Clone, Default)]
pub struct Graph {
    nodes: Vec<Node>,
    /// Value of every node at the state the trace was taken at.
    values: Vec<f64>,
    index: HashMap<Node, u32>,
    /// The inputs every node depends on, sorted: differentiation skips
    /// whatever does not depend on its variable, so a Lagrangian that is a
    /// sum over many bodies is differentiated in time linear in their number.
    deps: Vec<Box<[u32]>>,
    derivatives: HashMap<(u32, u32), u32>,
    leaks: Vec<&'static str>,
    unsupported: Vec<&'static str>,
}

impl Graph {
    pub fn new() -> Self {
        Graph::default()
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The operations whose value decided a branch during tracing (the
    /// trace then holds only on that branch).
    pub fn leaks(&self) -> &[&'static str] {
        &self.leaks
    }

    /// The functions met during tracing that the graph does not represent.
    pub fn unsupported(&self) -> &[&'static str] {
        &self.unsupported
    }

    /// Whether the trace holds at every state: no leak, nothing unsupported.
    pub fn is_exact(&self) -> bool {
        self.leaks.is_empty() && self.unsupported.is_empty()
    }

    /// Where the trace does not hold at every state: the leaks and the
    /// unsupported functions, each named once, sorted (`None`: exact).
    pub fn inexact(&self) -> Option<String> {
        if self.is_exact() {
            return None;
        }
        let mut what: Vec<&str> = self
            .leaks
            .iter()
            .chain(&self.unsupported)
            .copied()
            .collect();
        what.sort_unstable();
        what.dedup();
        Some(what.join(", "))
    }

    /// The node of a constant.
    pub fn constant(&mut self, c: f64) -> u32 {
        self.push(Node::Const(c.to_bits()), c)
    }

    /// The node of input `i`, whose value at the trace point is `value`.
    pub fn input(&mut self, i: u32, value: f64) -> u32 {
        self.push(Node::Input(i), value)
    }

    fn value(&self, id: u32) -> f64 {
        self.values[id as usize]
    }

    fn as_const(&self, id: u32) -> Option<f64> {
        match self.nodes[id as usize] {
            Node::Const(b) => Some(f64::from_bits(b)),
            _ => None,
        }
    }

    fn push(&mut self, node: Node, value: f64) -> u32 {
        if let Some(&id) = self.index.get(&node) {
            return id;
        }
        let id = u32::try_from(self.nodes.len()).expect("graph larger than u32 nodes");
        let deps: Box<[u32]> = match node {
            Node::Input(i) => Box::new([i]),
            _ => match operands(&node) {
                [Some(a), Some(b)] => union(&self.deps[a as usize], &self.deps[b as usize]),
                [Some(a), None] => self.deps[a as usize].clone(),
                _ => Box::new([]),
            },
        };
        self.nodes.push(node);
        self.values.push(value);
        self.deps.push(deps);
        self.index.insert(node, id);
        id
    }

    /// Adds `node` after folding constants and the identities of 0 and 1;
    /// operands of `+` and `·` in canonical order.
    pub fn op(&mut self, node: Node) -> u32 {
        use Node::*;
        let c = |g: &Graph, a: u32| g.as_const(a);
        let node = match node {
            Add(a, b) | Mul(a, b) if a > b => match node {
                Add(..) => Add(b, a),
                _ => Mul(b, a),
            },
            n => n,
        };
        // Fold when every operand is constant.
        let folds = !matches!(node, Const(_) | Input(_))
            && operands(&node)
                .into_iter()
                .flatten()
                .all(|a| c(self, a).is_some());
        let value: f64 = apply(&node, |i| self.values[i as usize]);
        if folds {
            return self.constant(value);
        }
        let zero = |g: &Graph, a: u32| c(g, a) == Some(0.0);
        let one = |g: &Graph, a: u32| c(g, a) == Some(1.0);
        match node {
            Add(a, b) if zero(self, a) => b,
            Add(a, b) if zero(self, b) => a,
            Sub(a, b) if zero(self, b) => a,
            Sub(a, b) if zero(self, a) => self.op(Neg(b)),
            Sub(a, b) if a == b => self.constant(0.0),
            Mul(a, b) if zero(self, a) || zero(self, b) => self.constant(0.0),
            Mul(a, b) if one(self, a) => b,
            Mul(a, b) if one(self, b) => a,
            Mul(a, b) if c(self, a) == Some(-1.0) => self.op(Neg(b)),
            Div(a, _) if zero(self, a) => self.constant(0.0),
            Div(a, b) if one(self, b) => a,
            Neg(a) => match self.nodes[a as usize] {
                Neg(x) => x,
                _ => self.push(node, value),
            },
            Powi(a, 1) => a,
            Powi(_, 0) => self.constant(1.0),
            _ => self.push(node, value),
        }
    }

    /// The inputs node `id` depends on, in increasing order.
    pub fn deps(&self, id: u32) -> &[u32] {
        &self.deps[id as usize]
    }

    /// Whether node `id` depends on input `var`.
    pub fn depends(&self, id: u32, var: u32) -> bool {
        self.deps[id as usize].binary_search(&var).is_ok()
    }

    /// Whether node `id` is the constant zero (a structural zero).
    pub fn is_zero(&self, id: u32) -> bool {
        self.as_const(id) == Some(0.0)
    }

    /// The derivative of node `root` with respect to input `var`, as a node
    /// of the same graph (memoised: asking again costs a lookup; a node that
    /// does not depend on `var` has derivative zero without a walk).
    pub fn diff(&mut self, root: u32, var: u32) -> u32 {
        if !self.depends(root, var) {
            return self.constant(0.0);
        }
        if let Some(&d) = self.derivatives.get(&(root, var)) {
            return d;
        }
        // Children first, without recursion: a depth-first walk that
        // differentiates a node once all its operands (those that depend on
        // `var`) have derivatives.
        let mut stack = vec![root];
        while let Some(&id) = stack.last() {
            if self.derivatives.contains_key(&(id, var)) {
                stack.pop();
                continue;
            }
            let node = self.nodes[id as usize];
            let pending: Vec<u32> = operands(&node)
                .into_iter()
                .flatten()
                .filter(|&a| self.depends(a, var) && !self.derivatives.contains_key(&(a, var)))
                .collect();
            if pending.is_empty() {
                let d = self.derivative_of(id, node, var);
                self.derivatives.insert((id, var), d);
                stack.pop();
            } else {
                stack.extend(pending);
            }
        }
        self.derivatives[&(root, var)]
    }

    /// One step of the chain rule, operands' derivatives already known.
    fn derivative_of(&mut self, id: u32, node: Node, var: u32) -> u32 {
        use Node::*;
        let zero_id = self.constant(0.0);
        let d = |g: &Graph, a: u32| {
            if g.depends(a, var) {
                g.derivatives[&(a, var)]
            } else {
                zero_id
            }
        };
        let zero = |g: &mut Graph| g.constant(0.0);
        match node {
            Const(_) => zero(self),
            Input(i) => self.constant(if i == var { 1.0 } else { 0.0 }),
            Add(a, b) => {
                let (da, db) = (d(self, a), d(self, b));
                self.op(Add(da, db))
            }
            Sub(a, b) => {
                let (da, db) = (d(self, a), d(self, b));
                self.op(Sub(da, db))
            }
            Mul(a, b) => {
                let (da, db) = (d(self, a), d(self, b));
                let x = self.op(Mul(da, b));
                let y = self.op(Mul(a, db));
                self.op(Add(x, y))
            }
            Div(a, b) => {
                // (a/b)' = (a' − (a/b) b') / b
                let (da, db) = (d(self, a), d(self, b));
                let x = self.op(Mul(id, db));
                let num = self.op(Sub(da, x));
                self.op(Div(num, b))
            }
            Neg(a) => {
                let da = d(self, a);
                self.op(Neg(da))
            }
            Recip(a) => {
                let da = d(self, a);
                let r2 = self.op(Mul(id, id));
                let x = self.op(Mul(da, r2));
                self.op(Neg(x))
            }
            Powi(a, n) => {
                let da = d(self, a);
                let p = self.op(Powi(a, n - 1));
                let k = self.constant(n as f64);
                let x = self.op(Mul(k, p));
                self.op(Mul(x, da))
            }
            Powf(a, pb) => {
                let p = f64::from_bits(pb);
                let da = d(self, a);
                let q = self.op(Powf(a, (p - 1.0).to_bits()));
                let k = self.constant(p);
                let x = self.op(Mul(k, q));
                self.op(Mul(x, da))
            }
            Sqrt(a) => {
                let da = d(self, a);
                let two = self.constant(2.0);
                let den = self.op(Mul(two, id));
                self.op(Div(da, den))
            }
            Exp(a) => {
                let da = d(self, a);
                self.op(Mul(id, da))
            }
            Ln(a) => {
                let da = d(self, a);
                self.op(Div(da, a))
            }
            Sin(a) => {
                let da = d(self, a);
                let c = self.op(Cos(a));
                self.op(Mul(c, da))
            }
            Cos(a) => {
                let da = d(self, a);
                let s = self.op(Sin(a));
                let x = self.op(Mul(s, da));
                self.op(Neg(x))
            }
            Tan(a) => {
                // (1 + tan²) a'
                let da = d(self, a);
                let t2 = self.op(Mul(id, id));
                let one = self.constant(1.0);
                let k = self.op(Add(one, t2));
                self.op(Mul(k, da))
            }
            Asin(a) | Acos(a) => {
                // ±a' / √(1 − a²)
                let da = d(self, a);
                let a2 = self.op(Mul(a, a));
                let one = self.constant(1.0);
                let r = self.op(Sub(one, a2));
                let s = self.op(Sqrt(r));
                let x = self.op(Div(da, s));
                if matches!(node, Acos(_)) {
                    self.op(Neg(x))
                } else {
                    x
                }
            }
            Atan(a) => {
                let da = d(self, a);
                let a2 = self.op(Mul(a, a));
                let one = self.constant(1.0);
                let den = self.op(Add(one, a2));
                self.op(Div(da, den))
            }
            Sinh(a) => {
                let da = d(self, a);
                let c = self.op(Cosh(a));
                self.op(Mul(c, da))
            }
            Cosh(a) => {
                let da = d(self, a);
                let s = self.op(Sinh(a));
                self.op(Mul(s, da))
            }
            Tanh(a) => {
                let da = d(self, a);
                let t2 = self.op(Mul(id, id));
                let one = self.constant(1.0);
                let k = self.op(Sub(one, t2));
                self.op(Mul(k, da))
            }
            Abs(a) => {
                let da = d(self, a);
                let s = self.op(Signum(a));
                self.op(Mul(s, da))
            }
            Signum(_) => zero(self),
            Angle(y, x, _) => {
                // (x y′ − y x′) / (x² + y²)
                let (dy, dx) = (d(self, y), d(self, x));
                let a = self.op(Mul(x, dy));
                let b = self.op(Mul(y, dx));
                let num = self.op(Sub(a, b));
                let xx = self.op(Mul(x, x));
                let yy = self.op(Mul(y, y));
                let den = self.op(Add(xx, yy));
                self.op(Div(num, den))
            }
        }
    }

    /// `Σ_j ∂root/∂(input vars[j]) · weights[j]`: a directional derivative
    /// as one node. `vars` must be increasing; only those `root` depends on
    /// are visited (the others add zero), in the same order.
    pub fn directional(&mut self, root: u32, vars: &[u32], weights: &[u32]) -> u32 {
        assert!(
            vars.windows(2).all(|w| w[0] < w[1]),
            "directional: vars must increase"
        );
        let mut acc = self.constant(0.0);
        let deps = self.deps[root as usize].clone();
        for v in deps.iter() {
            let Ok(j) = vars.binary_search(v) else {
                continue;
            };
            let d = self.diff(root, *v);
            let x = self.op(Node::Mul(d, weights[j]));
            acc = self.op(Node::Add(acc, x));
        }
        acc
    }
}

/// The union of two increasing lists.
fn union(a: &[u32], b: &[u32]) -> Box<[u32]> {
    if a.is_empty() || a == b {
        return b.into();
    }
    if b.is_empty() {
        return a.into();
    }
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => {
                out.push(a[i]);
                i += 1;
            }
            std::cmp::Ordering::Greater => {
                out.push(b[j]);
                j += 1;
            }
            std::cmp::Ordering::Equal => {
                out.push(a[i]);
                i += 1;
                j += 1;
            }
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out.into()
}

fn operands(node: &Node) -> [Option<u32>; 2] {
    use Node::*;
    match *node {
        Const(_) | Input(_) => [None, None],
        Add(a, b) | Sub(a, b) | Mul(a, b) | Div(a, b) | Angle(a, b, _) => [Some(a), Some(b)],
        Neg(a)
        | Recip(a)
        | Powi(a, _)
        | Powf(a, _)
        | Sqrt(a)
        | Exp(a)
        | Ln(a)
        | Sin(a)
        | Cos(a)
        | Tan(a)
        | Asin(a)
        | Acos(a)
        | Atan(a)
        | Sinh(a)
        | Cosh(a)
        | Tanh(a)
        | Abs(a)
        | Signum(a) => [Some(a), None],
    }
}

/// The value of one node from its operands' values `x(a)`, over any
/// [`Scalar`]: the trace folds constants with it (`f64`), and a
/// [`Program`] runs its instructions with it. `Input` has no value here
/// (NaN): the trace and the program place inputs themselves.
#[inline(always)]
fn apply<T: Scalar>(node: &Node, x: impl Fn(u32) -> T) -> T {
    use Node::*;
    match *node {
        Const(b) => T::from(f64::from_bits(b)),
        Input(_) => T::from(f64::NAN),
        Add(a, b) => x(a) + x(b),
        Sub(a, b) => x(a) - x(b),
        Mul(a, b) => x(a) * x(b),
        Div(a, b) => x(a) / x(b),
        Neg(a) => -x(a),
        Recip(a) => x(a).recip(),
        Powi(a, n) => x(a).powi(n),
        Powf(a, p) => x(a).powf(f64::from_bits(p)),
        Sqrt(a) => x(a).sqrt(),
        Exp(a) => x(a).exp(),
        Ln(a) => x(a).ln(),
        Sin(a) => x(a).sin(),
        Cos(a) => x(a).cos(),
        Tan(a) => x(a).tan(),
        Asin(a) => x(a).asin(),
        Acos(a) => x(a).acos(),
        Atan(a) => x(a).atan(),
        Sinh(a) => x(a).sinh(),
        Cosh(a) => x(a).cosh(),
        Tanh(a) => x(a).tanh(),
        Abs(a) => x(a).abs(),
        Signum(a) => x(a).signum(),
        Angle(y, a, near) => crate::scene::atan2_near(x(y), x(a), near_of(f64::from_bits(near))),
    }
}

/// `node` with its operands renamed by `r`.
fn remap(node: Node, r: impl Fn(u32) -> u32) -> Node {
    use Node::*;
    match node {
        Const(_) | Input(_) => node,
        Add(a, b) => Add(r(a), r(b)),
        Sub(a, b) => Sub(r(a), r(b)),
        Mul(a, b) => Mul(r(a), r(b)),
        Div(a, b) => Div(r(a), r(b)),
        Neg(a) => Neg(r(a)),
        Recip(a) => Recip(r(a)),
        Powi(a, k) => Powi(r(a), k),
        Powf(a, p) => Powf(r(a), p),
        Sqrt(a) => Sqrt(r(a)),
        Exp(a) => Exp(r(a)),
        Ln(a) => Ln(r(a)),
        Sin(a) => Sin(r(a)),
        Cos(a) => Cos(r(a)),
        Tan(a) => Tan(r(a)),
        Asin(a) => Asin(r(a)),
        Acos(a) => Acos(r(a)),
        Atan(a) => Atan(r(a)),
        Sinh(a) => Sinh(r(a)),
        Cosh(a) => Cosh(r(a)),
        Tanh(a) => Tanh(r(a)),
        Abs(a) => Abs(r(a)),
        Signum(a) => Signum(r(a)),
        Angle(y, x, near) => Angle(r(y), r(x), near),
    }
}

/* ---------------------------------------------------------------------- */
/* Tracing                                                                */
/* ---------------------------------------------------------------------- */

thread_local! {
    static TAPE: RefCell<Option<Graph>> = const { RefCell::new(None) };
}

/// Runs `f` with `graph` as the graph [`Tracer`] numbers record into, and
/// gives the graph back with what `f` returned.
pub fn trace<R>(graph: Graph, f: impl FnOnce() -> R) -> (Graph, R) {
    let previous = TAPE.with(|t| t.borrow_mut().replace(graph));
    assert!(previous.is_none(), "graph::trace does not nest");
    // The tape is taken back even if `f` panics.
    struct Restore;
    impl Drop for Restore {
        fn drop(&mut self) {
            TAPE.with(|t| t.borrow_mut().take());
        }
    }
    let guard = Restore;
    let r = f();
    let graph = TAPE
        .with(|t| t.borrow_mut().take())
        .expect("the tape is present until trace returns");
    std::mem::forget(guard);
    (graph, r)
}

fn with_tape<R>(f: impl FnOnce(&mut Graph) -> R) -> R {
    TAPE.with(|t| {
        let mut t = t.borrow_mut();
        f(t.as_mut()
            .expect("Tracer arithmetic outside graph::trace (a Tracer only exists inside a trace)"))
    })
}

/// A number that records its operations into the graph of the enclosing
/// [`trace`]; it carries its value at the trace point so that code run
/// during the trace sees real numbers. Reading that value (`re()`,
/// [`Scalar::modulus`], a comparison, a sign test) records a leak unless
/// the number is a constant.
#[derive(Clone, Copy, Debug)]
pub struct Tracer {
    pub id: u32,
    pub value: f64,
}

impl Tracer {
    /// Input `i` with value `value` at the trace point.
    pub fn input(i: u32, value: f64) -> Self {
        Tracer {
            id: with_tape(|g| g.input(i, value)),
            value,
        }
    }

    fn constant(c: f64) -> Self {
        Tracer {
            id: with_tape(|g| g.constant(c)),
            value: c,
        }
    }

    fn op(node: Node) -> Self {
        with_tape(|g| {
            let id = g.op(node);
            Tracer {
                id,
                value: g.value(id),
            }
        })
    }

    fn unary(self, f: fn(u32) -> Node) -> Self {
        Tracer::op(f(self.id))
    }

    /// A function the graph does not represent: recorded, and the value
    /// carried as a constant so that the trace can finish.
    fn unsupported(self, name: &'static str, value: f64) -> Self {
        with_tape(|g| g.unsupported.push(name));
        Tracer::constant(value)
    }

    /// The value decides something: a leak, unless it is a constant.
    fn read(&self, what: &'static str) -> f64 {
        with_tape(|g| {
            if g.as_const(self.id).is_none() {
                g.leaks.push(what);
            }
        });
        self.value
    }
}

impl From<f64> for Tracer {
    fn from(c: f64) -> Self {
        Tracer::constant(c)
    }
}

impl fmt::Display for Tracer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (node {})", self.value, self.id)
    }
}

macro_rules! tracer_binop {
    ($op:ident, $method:ident, $op_assign:ident, $method_assign:ident, $node:ident) => {
        impl $op for Tracer {
            type Output = Tracer;
            fn $method(self, rhs: Tracer) -> Tracer {
                Tracer::op(Node::$node(self.id, rhs.id))
            }
        }
        impl $op<&Tracer> for Tracer {
            type Output = Tracer;
            fn $method(self, rhs: &Tracer) -> Tracer {
                Tracer::op(Node::$node(self.id, rhs.id))
            }
        }
        impl $op<f64> for Tracer {
            type Output = Tracer;
            fn $method(self, rhs: f64) -> Tracer {
                $op::$method(self, Tracer::constant(rhs))
            }
        }
        impl $op_assign for Tracer {
            fn $method_assign(&mut self, rhs: Tracer) {
                *self = $op::$method(*self, rhs)
            }
        }
        impl $op_assign<&Tracer> for Tracer {
            fn $method_assign(&mut self, rhs: &Tracer) {
                *self = $op::$method(*self, *rhs)
            }
        }
        impl $op_assign<f64> for Tracer {
            fn $method_assign(&mut self, rhs: f64) {
                *self = $op::$method(*self, rhs)
            }
        }
    };
}

tracer_binop!(Add, add, AddAssign, add_assign, Add);
tracer_binop!(Sub, sub, SubAssign, sub_assign, Sub);
tracer_binop!(Mul, mul, MulAssign, mul_assign, Mul);
tracer_binop!(Div, div, DivAssign, div_assign, Div);

/// Required by `Num`; no scene function takes a remainder, so it is
/// recorded as unsupported.
impl Rem for Tracer {
    type Output = Tracer;
    fn rem(self, rhs: Tracer) -> Tracer {
        self.unsupported("rem", self.value % rhs.value)
    }
}
impl Rem<&Tracer> for Tracer {
    type Output = Tracer;
    fn rem(self, rhs: &Tracer) -> Tracer {
        self % *rhs
    }
}
impl Rem<f64> for Tracer {
    type Output = Tracer;
    fn rem(self, rhs: f64) -> Tracer {
        self % Tracer::constant(rhs)
    }
}
impl RemAssign for Tracer {
    fn rem_assign(&mut self, rhs: Tracer) {
        *self = *self % rhs
    }
}
impl RemAssign<&Tracer> for Tracer {
    fn rem_assign(&mut self, rhs: &Tracer) {
        *self = *self % *rhs
    }
}
impl RemAssign<f64> for Tracer {
    fn rem_assign(&mut self, rhs: f64) {
        *self = *self % rhs
    }
}

impl Neg for Tracer {
    type Output = Tracer;
    fn neg(self) -> Tracer {
        self.unary(Node::Neg)
    }
}

impl Inv for Tracer {
    type Output = Tracer;
    fn inv(self) -> Tracer {
        self.unary(Node::Recip)
    }
}

impl Sum for Tracer {
    fn sum<I: Iterator<Item = Tracer>>(iter: I) -> Tracer {
        iter.fold(Tracer::constant(0.0), |a, b| a + b)
    }
}

impl<'a> Sum<&'a Tracer> for Tracer {
    fn sum<I: Iterator<Item = &'a Tracer>>(iter: I) -> Tracer {
        iter.fold(Tracer::constant(0.0), |a, b| a + *b)
    }
}

impl Product for Tracer {
    fn product<I: Iterator<Item = Tracer>>(iter: I) -> Tracer {
        iter.fold(Tracer::constant(1.0), |a, b| a * b)
    }
}

impl<'a> Product<&'a Tracer> for Tracer {
    fn product<I: Iterator<Item = &'a Tracer>>(iter: I) -> Tracer {
        iter.fold(Tracer::constant(1.0), |a, b| a * b)
    }
}

impl Zero for Tracer {
    fn zero() -> Self {
        Tracer::constant(0.0)
    }
    fn is_zero(&self) -> bool {
        self.read("is_zero") == 0.0
    }
}

impl One for Tracer {
    fn one() -> Self {
        Tracer::constant(1.0)
    }
}

impl Num for Tracer {
    type FromStrRadixErr = <f64 as Num>::FromStrRadixErr;
    fn from_str_radix(s: &str, radix: u32) -> Result<Self, Self::FromStrRadixErr> {
        f64::from_str_radix(s, radix).map(Tracer::constant)
    }
}

macro_rules! tracer_from_primitive {
    ($($method:ident: $t:ty),*) => {
        $(
            fn $method(n: $t) -> Option<Self> {
                f64::$method(n).map(Tracer::constant)
            }
        )*
    };
}

impl FromPrimitive for Tracer {
    tracer_from_primitive!(
        from_isize: isize, from_i8: i8, from_i16: i16, from_i32: i32, from_i64: i64,
        from_i128: i128, from_usize: usize, from_u8: u8, from_u16: u16, from_u32: u32,
        from_u64: u64, from_u128: u128, from_f32: f32, from_f64: f64
    );
}

/// `abs` and `signum` are nodes (evaluated at every state); the sign tests
/// read the value and leak.
impl Signed for Tracer {
    fn abs(&self) -> Self {
        self.unary(Node::Abs)
    }
    fn abs_sub(&self, other: &Self) -> Self {
        if self.read("abs_sub") <= other.read("abs_sub") {
            Tracer::constant(0.0)
        } else {
            *self - *other
        }
    }
    fn signum(&self) -> Self {
        self.unary(Node::Signum)
    }
    fn is_positive(&self) -> bool {
        self.read("is_positive").is_sign_positive()
    }
    fn is_negative(&self) -> bool {
        self.read("is_negative").is_sign_negative()
    }
}

impl PartialEq for Tracer {
    fn eq(&self, other: &Self) -> bool {
        self.id == other.id || self.read("==") == other.read("==")
    }
}

impl PartialOrd for Tracer {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        self.read("comparison")
            .partial_cmp(&other.read("comparison"))
    }
}

impl PartialEq<f64> for Tracer {
    fn eq(&self, other: &f64) -> bool {
        self.read("==") == *other
    }
}

impl PartialOrd<f64> for Tracer {
    fn partial_cmp(&self, other: &f64) -> Option<std::cmp::Ordering> {
        self.read("comparison").partial_cmp(other)
    }
}

impl DualStruct for Tracer {
    type Real = f64;
    type Inner = Tracer;
    fn re(&self) -> f64 {
        self.read("re()")
    }
    fn from_inner(inner: &Tracer) -> Self {
        *inner
    }
}

impl Mappable<Tracer> for Tracer {
    type Output<O> = O;
    fn map_dual<M: Fn(Tracer) -> O, O>(self, f: M) -> O {
        f(self)
    }
}

impl DualNum for Tracer {
    type Primitive = f64;
    const NDERIV: usize = 0;
    type InnerDual = Tracer;

    fn from_re(re: Tracer) -> Self {
        re
    }
    fn scale(self, factor: &Tracer) -> Self {
        self * *factor
    }
    fn recip(&self) -> Self {
        self.unary(Node::Recip)
    }
    fn powi(&self, n: i32) -> Self {
        Tracer::op(Node::Powi(self.id, n))
    }
    fn powf(&self, n: f64) -> Self {
        Tracer::op(Node::Powf(self.id, n.to_bits()))
    }
    fn powd(&self, exp: Self) -> Self {
        (self.ln() * exp).exp()
    }
    fn sqrt(&self) -> Self {
        self.unary(Node::Sqrt)
    }
    fn cbrt(&self) -> Self {
        self.unsupported("cbrt", self.value.cbrt())
    }
    fn exp(&self) -> Self {
        self.unary(Node::Exp)
    }
    fn exp2(&self) -> Self {
        (*self * std::f64::consts::LN_2).exp()
    }
    fn exp_m1(&self) -> Self {
        self.unsupported("exp_m1", self.value.exp_m1())
    }
    fn ln(&self) -> Self {
        self.unary(Node::Ln)
    }
    fn log(&self, base: f64) -> Self {
        self.ln() / base.ln()
    }
    fn log2(&self) -> Self {
        self.ln() / std::f64::consts::LN_2
    }
    fn log10(&self) -> Self {
        self.ln() / std::f64::consts::LN_10
    }
    fn ln_1p(&self) -> Self {
        self.unsupported("ln_1p", self.value.ln_1p())
    }
    fn sin(&self) -> Self {
        self.unary(Node::Sin)
    }
    fn cos(&self) -> Self {
        self.unary(Node::Cos)
    }
    fn tan(&self) -> Self {
        self.unary(Node::Tan)
    }
    fn sin_cos(&self) -> (Self, Self) {
        (self.sin(), self.cos())
    }
    fn asin(&self) -> Self {
        self.unary(Node::Asin)
    }
    fn acos(&self) -> Self {
        self.unary(Node::Acos)
    }
    fn atan(&self) -> Self {
        self.unary(Node::Atan)
    }
    fn atan2(&self, other: Self) -> Self {
        self.unsupported("atan2", self.value.atan2(other.value))
    }
    fn sinh(&self) -> Self {
        self.unary(Node::Sinh)
    }
    fn cosh(&self) -> Self {
        self.unary(Node::Cosh)
    }
    fn tanh(&self) -> Self {
        self.unary(Node::Tanh)
    }
    fn asinh(&self) -> Self {
        self.unsupported("asinh", self.value.asinh())
    }
    fn acosh(&self) -> Self {
        self.unsupported("acosh", self.value.acosh())
    }
    fn atanh(&self) -> Self {
        self.unsupported("atanh", self.value.atanh())
    }
    fn sph_j0(&self) -> Self {
        self.unsupported("sph_j0", f64::NAN)
    }
    fn sph_j1(&self) -> Self {
        self.unsupported("sph_j1", f64::NAN)
    }
    fn sph_j2(&self) -> Self {
        self.unsupported("sph_j2", f64::NAN)
    }
}

impl Scalar for Tracer {
    const TRACED: bool = true;

    fn modulus(&self) -> f64 {
        self.read("modulus()").abs()
    }

    fn value_part(&self) -> Self {
        *self
    }

    /// One operation, [`Node::Angle`]: no branch is decided in the trace.
    fn angle(y: Self, x: Self, near: Option<f64>) -> Self {
        let bits = near.filter(|r| r.is_finite()).unwrap_or(f64::NAN).to_bits();
        Tracer::op(Node::Angle(y.id, x.id, bits))
    }
}

/* ---------------------------------------------------------------------- */
/* Programs                                                               */
/* ---------------------------------------------------------------------- */

/// The nodes that some outputs need, as a straight-line program over any
/// [`Scalar`]. The register file holds the inputs first, then the
/// constants (written once, by [`Program::registers`]), then one register
/// per instruction: an evaluation copies the inputs and runs only the
/// instructions.
#[derive(Debug, Clone)]
pub struct Program {
    /// The instructions: nodes whose operands are register numbers.
    ops: Vec<Node>,
    constants: Vec<f64>,
    outputs: Vec<u32>,
    inputs: usize,
    /// The same instructions as native code over `f64` and over `Dual64`
    /// ([`crate::jit`]), compiled where first run over that type; `None`:
    /// the interpreter runs them.
    #[cfg(feature = "jit")]
    native: Native,
}

#[cfg(feature = "jit")]
type NativeCell = std::sync::OnceLock<Option<std::sync::Arc<crate::jit::ProgramNative>>>;

#[cfg(feature = "jit")]
#[derive(Debug, Clone, Default)]
struct Native {
    /// Whether native code was on ([`crate::jit::enabled`]) when the
    /// program was built: a program built while it was off stays in the
    /// interpreter.
    allowed: bool,
    real: NativeCell,
    dual: NativeCell,
}

/// Two programs are equal when their instructions, constants and outputs
/// are (native code or not).
impl PartialEq for Program {
    fn eq(&self, other: &Program) -> bool {
        (&self.ops, &self.constants, &self.outputs, self.inputs)
            == (&other.ops, &other.constants, &other.outputs, other.inputs)
    }
}

impl Program {
    /// The program computing `outputs` (node ids of `graph`) from the
    /// graph's inputs `0..inputs`.
    pub fn new(graph: &Graph, outputs: &[u32], inputs: usize) -> Program {
        let n = graph.nodes.len();
        let mut needed = vec![false; n];
        for &o in outputs {
            needed[o as usize] = true;
        }
        for id in (0..n).rev() {
            if needed[id] {
                for a in operands(&graph.nodes[id]).into_iter().flatten() {
                    needed[a as usize] = true;
                }
            }
        }
        let mut register = vec![u32::MAX; n];
        let mut constants = Vec::new();
        for id in 0..n {
            match graph.nodes[id] {
                Node::Input(i) => {
                    assert!(
                        (i as usize) < inputs,
                        "input {i} beyond the program's {inputs}"
                    );
                    register[id] = i;
                }
                Node::Const(b) if needed[id] => {
                    register[id] = (inputs + constants.len()) as u32;
                    constants.push(f64::from_bits(b));
                }
                _ => {}
            }
        }
        let base = inputs + constants.len();
        let mut ops = Vec::new();
        for id in 0..n {
            if !needed[id] || matches!(graph.nodes[id], Node::Input(_) | Node::Const(_)) {
                continue;
            }
            let op = remap(graph.nodes[id], |a| register[a as usize]);
            register[id] = (base + ops.len()) as u32;
            ops.push(op);
        }
        let outputs: Vec<u32> = outputs.iter().map(|&o| register[o as usize]).collect();
        Program {
            #[cfg(feature = "jit")]
            native: Native {
                allowed: crate::jit::enabled(),
                ..Native::default()
            },
            outputs,
            ops,
            constants,
            inputs,
        }
    }

    /// The instructions, the outputs' registers, the number of inputs and
    /// the constants (for compiling the program into something larger,
    /// [`crate::jit::kkt`]).
    #[cfg(feature = "jit")]
    pub(crate) fn parts(&self) -> (&[Node], &[u32], usize, &[f64]) {
        (&self.ops, &self.outputs, self.inputs, &self.constants)
    }

    /// Whether the program runs as native code over `f64` ([`crate::jit`];
    /// compiled now if it was not yet).
    pub fn is_native(&self) -> bool {
        #[cfg(feature = "jit")]
        return self.real_native().is_some();
        #[cfg(not(feature = "jit"))]
        false
    }

    /// Compiles the native code over `f64` and over `Dual64` now (where
    /// allowed), instead of where the program first runs over each: for
    /// measuring the cost of making it.
    pub fn prepare_native(&self) {
        #[cfg(feature = "jit")]
        {
            self.real_native();
            self.dual_native();
        }
    }

    #[cfg(feature = "jit")]
    fn real_native(&self) -> Option<&crate::jit::ProgramNative> {
        let base = self.inputs + self.constants.len();
        let allowed = self.native.allowed;
        (self.native.real)
            .get_or_init(|| allowed.then(|| crate::jit::program(&self.ops, &self.outputs, base))?)
            .as_deref()
    }

    #[cfg(feature = "jit")]
    fn dual_native(&self) -> Option<&crate::jit::ProgramNative> {
        let base = self.inputs + self.constants.len();
        let allowed = self.native.allowed;
        (self.native.dual)
            .get_or_init(|| {
                allowed.then(|| crate::jit::dual_program(&self.ops, &self.outputs, base))?
            })
            .as_deref()
    }

    /// Number of instructions (the cost of one evaluation, in operations;
    /// inputs and constants are not instructions).
    pub fn len(&self) -> usize {
        self.ops.len()
    }

    pub fn is_empty(&self) -> bool {
        self.ops.is_empty()
    }

    /// How many instructions are calls of `sin`, `cos`, `tan`, `exp`, ...
    /// (the expensive ones).
    pub fn transcendentals(&self) -> usize {
        self.ops
            .iter()
            .filter(|op| {
                !matches!(
                    op,
                    Node::Add(..)
                        | Node::Sub(..)
                        | Node::Mul(..)
                        | Node::Div(..)
                        | Node::Neg(_)
                        | Node::Recip(_)
                        | Node::Abs(_)
                        | Node::Signum(_)
                )
            })
            .count()
    }

    /// Number of constants (registers after the inputs).
    pub fn constants(&self) -> usize {
        self.constants.len()
    }

    /// Number of inputs and of outputs.
    pub fn shape(&self) -> (usize, usize) {
        (self.inputs, self.outputs.len())
    }

    /// A register file for [`Program::eval`] over `T`, with the constants
    /// in place.
    pub fn registers<T: Scalar>(&self) -> Vec<T> {
        let mut regs = vec![T::from(0.0); self.inputs + self.constants.len() + self.ops.len()];
        for (r, &c) in regs[self.inputs..].iter_mut().zip(&self.constants) {
            *r = T::from(c);
        }
        regs
    }

    /// Evaluates the program at `inputs` into `out` (one value per output),
    /// using `regs` (from [`Program::registers`] of this program, whose
    /// constants evaluation leaves in place) as its register file.
    pub fn eval<T: Scalar>(&self, inputs: &[T], regs: &mut [T], out: &mut [T]) {
        assert_eq!(inputs.len(), self.inputs, "program inputs");
        regs[..self.inputs].copy_from_slice(inputs);
        self.run(regs, out);
    }

    /// [`Program::eval`] with the inputs already in `regs[..inputs]` (the
    /// first registers), where a caller can write them without a copy.
    pub fn run<T: Scalar>(&self, regs: &mut [T], out: &mut [T]) {
        let base = self.inputs + self.constants.len();
        assert_eq!(regs.len(), base + self.ops.len(), "program registers");
        assert_eq!(out.len(), self.outputs.len(), "program outputs");
        #[cfg(feature = "jit")]
        if let Some(regs) = T::as_real_mut(regs)
            && let Some(native) = self.real_native()
        {
            let out = T::as_real_mut(out).expect("the outputs have the registers' type");
            native.run(regs, out);
            return;
        }
        #[cfg(feature = "jit")]
        if let Some(regs) = T::as_pairs_mut(regs)
            && let Some(native) = self.dual_native()
        {
            let out = T::as_pairs_mut(out).expect("the outputs have the registers' type");
            native.run(regs, out);
            return;
        }
        self.run_interpreted(regs, out);
    }

    /// [`Program::run`] by the interpreter, whatever native code the
    /// program has: the definition native code is tested against.
    pub fn run_interpreted<T: Scalar>(&self, regs: &mut [T], out: &mut [T]) {
        let base = self.inputs + self.constants.len();
        assert_eq!(regs.len(), base + self.ops.len(), "program registers");
        assert_eq!(out.len(), self.outputs.len(), "program outputs");
        // Every operand register is below the instruction's own (by
        // construction): cells let the loop read the registers before
        // it while it writes the next one, without an index per store.
        let cells = std::cell::Cell::from_mut(regs).as_slice_of_cells();
        for (op, slot) in self.ops.iter().zip(&cells[base..]) {
            slot.set(apply(op, |a| cells[a as usize].get()));
        }
        for (o, &r) in out.iter_mut().zip(&self.outputs) {
            *o = cells[r as usize].get();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::{Dual64, HyperDual64};

    /// A function using every operation the graph represents. The angle
    /// `atan2(c, a − 1)` lies in another quadrant at each of [`POINTS`],
    /// where [`crate::scene::atan2`]'s value takes other branches.
    fn f<D: Scalar>(x: &[D]) -> D {
        let (a, b, c) = (x[0], x[1], x[2]);
        let s = a.sin() * b.cos() + (a * b).tan() - c.asin()
            + c.acos() * 0.5
            + (a / b).atan()
            + crate::scene::atan2(c, a - 1.0) * b
            + crate::scene::atan2_near(a * c, b - 1.5, Some(7.0));
        let h = b.sinh() * c.cosh() - (a * c).tanh() + (-b).abs() * b.signum();
        let p =
            a.powi(3) - b.powf(2.5) + a.recip() + (b * b + 1.0).sqrt() + c.exp() * (a + 2.0).ln();
        s * h + p / (c * c + 1.0) - a.sin() * a.sin()
    }

    fn traced(x: &[f64]) -> (Graph, u32) {
        let (g, id) = trace(Graph::new(), || {
            let v: Vec<Tracer> = x
                .iter()
                .enumerate()
                .map(|(i, &v)| Tracer::input(i as u32, v))
                .collect();
            f(&v).id
        });
        (g, id)
    }

    const POINTS: [[f64; 3]; 3] = [[0.7, 1.3, 0.2], [1.9, 0.4, -0.6], [0.3, 2.2, 0.9]];

    /// Values, first derivatives and every second derivative of the graph
    /// equal num-dual's (dual and hyper-dual numbers through the same
    /// function), to round-off.
    #[test]
    fn derivatives_on_the_graph_equal_dual_numbers() {
        let (mut g, root) = traced(&POINTS[0]);
        assert!(g.is_exact(), "{:?} {:?}", g.leaks(), g.unsupported());
        let mut outputs = vec![root];
        for i in 0..3u32 {
            let d = g.diff(root, i);
            outputs.push(d);
            for j in 0..3u32 {
                outputs.push(g.diff(d, j));
            }
        }
        let program = Program::new(&g, &outputs, 3);
        let mut regs = program.registers::<f64>();
        let mut out = vec![0.0; outputs.len()];
        for x in POINTS {
            program.eval(&x, &mut regs, &mut out);
            let close = |a: f64, b: f64, what: &str| {
                assert!(
                    (a - b).abs() <= 1e-13 * (1.0 + b.abs()),
                    "{what} at {x:?}: {a} against {b}"
                );
            };
            close(out[0], f(&x), "value");
            for i in 0..3 {
                let xd: Vec<Dual64> = (0..3)
                    .map(|k| Dual64::new(x[k], if k == i { 1.0 } else { 0.0 }))
                    .collect();
                close(out[1 + 4 * i], f(&xd).eps, "first derivative");
                for j in 0..3 {
                    let xh: Vec<HyperDual64> = (0..3)
                        .map(|k| {
                            HyperDual64::new(
                                x[k],
                                if k == i { 1.0 } else { 0.0 },
                                if k == j { 1.0 } else { 0.0 },
                                0.0,
                            )
                        })
                        .collect();
                    close(out[2 + 4 * i + j], f(&xh).eps1eps2, "second derivative");
                }
            }
        }
    }

    /// The program over `Dual64` carries a directional derivative through
    /// every instruction: the same as differentiating on the graph.
    #[test]
    fn the_program_over_dual_numbers_differentiates_it() {
        let (mut g, root) = traced(&POINTS[1]);
        let d1 = g.diff(root, 1);
        let program = Program::new(&g, &[root], 3);
        let derivative = Program::new(&g, &[d1], 3);
        let mut regs = program.registers::<Dual64>();
        let mut rf = derivative.registers::<f64>();
        for x in POINTS {
            let xd: Vec<Dual64> = (0..3)
                .map(|k| Dual64::new(x[k], if k == 1 { 1.0 } else { 0.0 }))
                .collect();
            let mut out = [Dual64::from(0.0)];
            program.eval(&xd, &mut regs, &mut out);
            let mut o = [0.0];
            derivative.eval(&x, &mut rf, &mut o);
            assert!((out[0].eps - o[0]).abs() <= 1e-13 * (1.0 + o[0].abs()));
        }
    }

    /// Hash-consing: `sin a` traced twice and needed by the derivative is one
    /// node; constants fold; `x − x`, `0·x`, `1·x` vanish.
    #[test]
    fn common_subexpressions_are_one_node_and_identities_fold() {
        let (mut g, (root, zero, same)) = trace(Graph::new(), || {
            let a = Tracer::input(0, 0.4);
            let b = Tracer::input(1, 1.1);
            let s = a.sin() * a.sin() + a.sin() * b;
            let zero = (b - b) * a + (a * 0.0) + Tracer::from(2.0) * 3.0 - 6.0;
            let same = (a * 1.0 + 0.0) / 1.0;
            (s.id, zero.id, same.id)
        });
        assert_eq!(g.as_const(zero), Some(0.0));
        assert_eq!(same, g.input(0, 0.4));
        let d = g.diff(root, 0);
        let p = Program::new(&g, &[root, d], 2);
        // sin a, and cos a for the derivative: two calls, whatever the
        // number of times the trace asked for them.
        assert_eq!(p.transcendentals(), 2);
    }

    /// A branch on a value and an unrepresented function are recorded; a
    /// branch on a constant is not.
    #[test]
    fn branches_on_values_and_unsupported_functions_are_recorded() {
        let (g, _) = trace(Graph::new(), || {
            let a = Tracer::input(0, 0.4);
            let c = Tracer::from(2.0);
            let _ = c.re() > 1.0;
            a
        });
        assert!(g.is_exact());
        let (g, _) = trace(Graph::new(), || {
            let a = Tracer::input(0, 0.4);
            if a.re() > 0.0 { a } else { -a }
        });
        assert_eq!(g.leaks(), &["re()"]);
        let (g, _) = trace(Graph::new(), || {
            let a = Tracer::input(0, 0.4);
            let _ = a > Tracer::from(0.0);
            a.cbrt()
        });
        assert_eq!(g.leaks(), &["comparison"]);
        assert_eq!(g.unsupported(), &["cbrt"]);
    }
}
