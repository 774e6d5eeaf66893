//! Native code for the straight-line programs of [`crate::graph`] and for
//! the small KKT systems of [`crate::kkt`] built from them.
//!
//! **Programs.** A [`crate::graph::Program`] over `f64` is compiled once by
//! Cranelift into a function that reads the inputs and the constants,
//! computes every instruction into a machine register or a stack slot, and
//! writes the outputs. The instructions are the interpreter's, one for one
//! and in its order: `+ − · /`, negation, `1/x`, `√x` and `|x|` are single
//! IEEE operations, exact, and every other function (`sin`, `cos`, `powi`,
//! ...) is a call of the same Rust function the interpreter calls — `sin`
//! and `cos` of one argument as one call of the C library's `sincos`,
//! whose results are the separate calls' bit for bit. So native code
//! computes what the interpreter computes, bit for bit (the tests below, and
//! `crates/lab/tests/native.rs` for every formulation on every scene), and
//! switching it on moves no result.
//!
//! **KKT systems.** For a system of at most [`crate::linalg::BLOCK_MAX`]
//! unknowns with ideal rows ([`crate::kkt::Ideal`]), [`KktNative`] is the
//! program followed by the assembly of `K` and its right-hand side from the
//! program's outputs and the block elimination of
//! [`crate::linalg::solve_saddle`], unrolled, with its three tests: the
//! same operations in the same order. Where any test fails it declines,
//! and the caller solves as before (the interpreter's way); where it
//! accepts, its solution is the one `solve_saddle` would have returned.
//!
//! Native code depends only on a program's *shape* — its instructions,
//! outputs and numbers of inputs and constants, and for a KKT system its
//! entries and dimensions — not on the constants' values, which it reads at
//! run time. Programs of one shape (the same scene and formulation at other
//! parameter values, as in a sweep) share one compiled function through a
//! process-wide cache; a parameter value that changes the shape (a zero or
//! a one the trace folds away) gets its own.

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicU8, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use cranelift_codegen::Context;
use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::types::{F64, I32};
use cranelift_codegen::ir::{
    AbiParam, Block, InstBuilder, MemFlagsData, SigRef, Signature, StackSlot, StackSlotData,
    StackSlotKind, Type, Value,
};
use cranelift_codegen::settings::{self, Configurable};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext};
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{Linkage, Module, default_libcall_names};
use num_dual::DualNum;

use crate::graph::Node;
use crate::linalg::{BACKWARD, BLOCK_MAX, PRIMAL_PIVOT, SCHUR_MARGIN};

/// A program's function: `entry(inputs, outputs)`, `inputs` pointing to
/// one pointer per input segment.
type ProgramFn = unsafe extern "C" fn(*const *const f64, *mut f64);

/// A KKT system's function: `entry(inputs, gains, outputs, solution,
/// constraint values)`, 1 where it solved, 0 where it declined; the last
/// points to one pointer per piece `g`, `ġ₀`, `f`, `ḟ`, `f̈₀`.
type KktFn =
    unsafe extern "C" fn(*const *const f64, *const f64, *mut f64, *mut f64, *const *mut f64) -> i32;

/// Compiled code, alive as long as a program or the cache holds it.
pub(crate) struct Native<F> {
    entry: F,
    /// The code's memory, released when the last holder drops it.
    module: Mutex<Option<JITModule>>,
}

impl<F> std::fmt::Debug for Native<F> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Native")
    }
}

impl<F> Drop for Native<F> {
    fn drop(&mut self) {
        if let Some(module) = self.module.get_mut().ok().and_then(Option::take) {
            // SAFETY: `entry` is reachable only through this value, which
            // is being dropped: nothing can call into the memory any more.
            unsafe { module.free_memory() };
        }
    }
}

/// A program as native code ([module docs](self)).
pub(crate) type ProgramNative = Native<ProgramFn>;

/// A KKT system as native code ([module docs](self)).
pub(crate) type KktNative = Native<KktFn>;

impl ProgramNative {
    /// Runs the code on `regs` (the program's register file: inputs, then
    /// constants, then scratch it does not touch) into `out`.
    ///
    /// The caller ([`crate::graph::Program::run`]) has checked that `regs`
    /// and `out` have the program's lengths; the code reads only registers
    /// below the program's first instruction register and writes exactly
    /// `out.len()` values.
    ///
    /// Over dual numbers ([`dual_program`]) `regs` and `out` hold the pairs
    /// `(re, eps)` of every register and output, twice as many values.
    #[inline]
    pub(crate) fn run(&self, regs: &[f64], out: &mut [f64]) {
        let inputs = [regs.as_ptr()];
        // SAFETY: the function was compiled for this program's shape (the
        // cache key), one input segment of the registers before the first
        // instruction, which the caller checked `regs` holds, as it
        // checked `out`'s length; the code reads and writes nothing else.
        unsafe { (self.entry)(inputs.as_ptr(), out.as_mut_ptr()) }
    }
}

/// The inputs of a KKT system's code, in the order of the program's
/// inputs ([`crate::compiled::Compiled::eval`]), and its constants.
pub(crate) struct KktInputs<'a> {
    pub t: f64,
    pub q: &'a [f64],
    pub qd: &'a [f64],
    pub p: &'a [f64],
    pub constants: &'a [f64],
}

impl KktNative {
    /// Evaluates the program and, where the block elimination accepts the
    /// system, writes its solution `(q̈, μ)` into `sol` and the constraint
    /// values into `pieces` (`g`, `ġ₀`, `f`, `ḟ`, `f̈₀`, as
    /// [`crate::constraints::ConstraintState`] holds them), and returns
    /// `true`; where it declines, writes every output into `out` (`sol`
    /// and `pieces` untouched) and returns `false`. `gains` are
    /// `(α_g, α_f, β)`: the rows of `g` read `−ġ₀ − 2α_g g`, those of `f`
    /// read `−f̈₀ − 2α_f ḟ − β² f`.
    ///
    /// # Panics
    ///
    /// If a slice's length is not the one the code was compiled for.
    #[inline]
    pub(crate) fn solve(
        &self,
        dims: &KktDims,
        x: &KktInputs<'_>,
        gains: [f64; 3],
        out: &mut [f64],
        sol: &mut [f64],
        pieces: [&mut [f64]; 5],
    ) -> bool {
        let (s, k) = (dims.s, dims.k);
        assert!(
            x.q.len() == dims.n
                && x.qd.len() == dims.n
                && x.p.len() == dims.np
                && x.constants.len() == dims.constants
                && out.len() == dims.outputs
                && sol.len() == dims.n + s + k
                && pieces
                    .iter()
                    .zip([s, s, k, k, k])
                    .all(|(p, len)| p.len() == len),
            "KKT code called with other lengths than it was compiled for"
        );
        let inputs = [
            &x.t as *const f64,
            x.q.as_ptr(),
            x.qd.as_ptr(),
            x.p.as_ptr(),
            x.constants.as_ptr(),
        ];
        let pieces = pieces.map(|p| p.as_mut_ptr());
        // SAFETY: compiled for these dimensions (the cache key), which the
        // assertion above checked; the code reads the five input segments
        // and the three gains within those lengths and writes `out`, `sol`
        // and the five pieces within theirs.
        unsafe {
            (self.entry)(
                inputs.as_ptr(),
                gains.as_ptr(),
                out.as_mut_ptr(),
                sol.as_mut_ptr(),
                pieces.as_ptr(),
            ) == 1
        }
    }
}

/// A program's shape: what its native code depends on.
#[derive(Clone, PartialEq, Eq, Hash)]
struct Shape {
    ops: Vec<Node>,
    outputs: Vec<u32>,
    /// Lengths of the input segments, the constants last: the registers
    /// before the first instruction, in order.
    segments: Vec<usize>,
}

/// The dimensions of a KKT system's code.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct KktDims {
    pub n: usize,
    pub s: usize,
    pub k: usize,
    pub np: usize,
    pub constants: usize,
    pub outputs: usize,
    /// Where the right-hand side's pieces start among the outputs:
    /// `Q`, `g`, `ġ₀`, `f`, `ḟ`, `f̈₀`.
    pub rhs_at: [usize; 6],
    /// The matrix entries: place in the column-major storage, output index.
    pub entries: Vec<(usize, u32)>,
}

#[derive(Clone, PartialEq, Eq, Hash)]
enum Key {
    Program(Shape),
    Dual(Shape),
    Kkt(Shape, KktDims),
}

#[derive(Clone)]
enum Made {
    Program(Option<Arc<ProgramNative>>),
    Kkt(Option<Arc<KktNative>>),
}

/// Native code is made for programs of at most this many instructions
/// (about 0.4 s of Cranelift's time over `f64` at this size,
/// [`CAREFUL_UP_TO`]); larger ones, which would take longer to compile
/// than most runs take to evaluate them, and whose values would fill
/// large stack frames, run in the interpreter.
pub const MAX_INSTRUCTIONS: usize = 20_000;

/// `Dual64` programs (an instruction counted twice) and KKT functions of at
/// most this many instructions get Cranelift's careful register allocator
/// (backtracking), larger ones its single-pass one ([`CAREFUL_REAL_UP_TO`]
/// for programs over `f64`).
/// Measured (f64 and `Dual64` code of B's program together): the careful
/// one takes 1.6 ms for the sleigh's 31 instructions, 37 ms for 700, 0.20 s
/// for 2180 and 2.5 s for 7360 (the train of 100) — time growing about like
/// the square of the size — where the single-pass one takes about 20 µs per
/// instruction (0.14 s for 7360); but its code is slower: the sleigh's
/// right-hand side 213 ns against 139 ns, the coin's KKT solve 717 ns
/// against 458 ns, the bicycle's 5.2 µs against 4.2 µs.
pub const CAREFUL_UP_TO: usize = 1000;

/// The same bound for programs over `f64` alone, which run at every
/// evaluation where their `Dual64` code runs once per Jacobian column.
/// Measured on A's explicit form (the sleigh's traced derivative array,
/// whose `f64` programs hold 2003 and 2958 instructions; `rhs-report`'s
/// state, solves repeated, best of 40 batches, interleaved): the careful
/// allocator took one right-hand side from 1.64–1.71 µs to 1.40 µs, for
/// 0.08–0.13 s of Cranelift's time once per process instead of 0.02 s
/// ([`compile_stats`], the four functions of that run).
pub const CAREFUL_REAL_UP_TO: usize = 3000;

/// The cache is emptied (programs keep their code) when the shapes it
/// holds exceed this many instructions together.
const CACHE_INSTRUCTIONS: usize = 1 << 21;

/// 0 until first read, then 1 (on) or 2 (off): see [`enabled`].
static ENABLED: AtomicU8 = AtomicU8::new(0);

/// Functions compiled, the instructions they held and the nanoseconds
/// Cranelift took, since the process started ([`compile_stats`]).
static COMPILED: [AtomicU64; 3] = [AtomicU64::new(0), AtomicU64::new(0), AtomicU64::new(0)];

/// How many functions were compiled, of how many program instructions
/// together, in how many seconds, since the process started (cache hits
/// compile nothing): for measuring what native code costs to make.
pub fn compile_stats() -> (u64, u64, f64) {
    let [count, ops, nanos] = COMPILED.each_ref().map(|c| c.load(Ordering::Relaxed));
    (count, ops, nanos as f64 * 1e-9)
}

type Cache = Mutex<(HashMap<Key, Made>, usize)>;

fn cache() -> &'static Cache {
    static CACHE: OnceLock<Cache> = OnceLock::new();
    CACHE.get_or_init(Default::default)
}

/// Whether programs built from now on get native code (on by default):
/// off, they run in the interpreter and their KKT systems in the Rust
/// solve, for measuring one against the other (programs built before and
/// after can run side by side). Programs already built keep what they
/// have.
pub fn set_enabled(on: bool) {
    ENABLED.store(if on { 1 } else { 2 }, Ordering::Relaxed);
}

/// Whether programs built now get native code ([`set_enabled`]); until
/// that is called, on unless the environment variable `NONHOLO_NATIVE` is
/// `0` or `off` (so a whole `nonholo` run can be timed without it; the
/// results are the same bit for bit either way).
pub fn enabled() -> bool {
    match ENABLED.load(Ordering::Relaxed) {
        1 => true,
        2 => false,
        _ => {
            let on = requested(std::env::var("NONHOLO_NATIVE").ok().as_deref());
            // A racing set_enabled wins: store only over "unset".
            let _ = ENABLED.compare_exchange(
                0,
                if on { 1 } else { 2 },
                Ordering::Relaxed,
                Ordering::Relaxed,
            );
            ENABLED.load(Ordering::Relaxed) == 1
        }
    }
}

/// Whether `NONHOLO_NATIVE` asks for native code: unless it is `0` or `off`.
fn requested(value: Option<&str>) -> bool {
    !matches!(value, Some("0" | "off"))
}

/// The cached code of `key`, or `make`'s (cached as well, a refusal too).
fn cached(key: Key, size: usize, make: impl FnOnce() -> Made) -> Made {
    let mut guard = cache().lock().unwrap_or_else(|e| e.into_inner());
    if let Some(found) = guard.0.get(&key) {
        return found.clone();
    }
    let start = std::time::Instant::now();
    let made = make();
    let nanos = u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX);
    for (c, v) in COMPILED.iter().zip([1, size as u64, nanos]) {
        c.fetch_add(v, Ordering::Relaxed);
    }
    if guard.1 + size > CACHE_INSTRUCTIONS {
        *guard = Default::default();
    }
    guard.1 += size;
    guard.0.insert(key, made.clone());
    made
}

fn worth_compiling(ops: &[Node]) -> bool {
    enabled() && !ops.is_empty() && ops.len() <= MAX_INSTRUCTIONS
}

/// Native code for the program with instructions `ops` (operands are
/// register numbers; the first instruction's register is `base`, after the
/// inputs and constants) and `outputs` (register numbers). `None` where
/// native code is switched off, the program is empty or larger than
/// [`MAX_INSTRUCTIONS`], or Cranelift declined (the host is not
/// supported); the interpreter then runs it.
pub(crate) fn program(ops: &[Node], outputs: &[u32], base: usize) -> Option<Arc<ProgramNative>> {
    if !worth_compiling(ops) {
        return None;
    }
    let shape = Shape {
        ops: ops.to_vec(),
        outputs: outputs.to_vec(),
        segments: vec![base],
    };
    let made = cached(Key::Program(shape.clone()), ops.len(), || {
        Made::Program(compile_program(&shape, Lanes::Real).ok().map(Arc::new))
    });
    match made {
        Made::Program(p) => p,
        Made::Kkt(_) => None,
    }
}

/// [`program`] over first-order dual numbers (`Dual64`: a value and one
/// directional derivative, a Jacobian column): every instruction as
/// num-dual computes it — the value as over `f64`, the derivative part by
/// num-dual's rule for the operation, the same operations in the same
/// order — so again the interpreter's results bit for bit. The code reads
/// and writes each register as the pair `(re, eps)`.
pub(crate) fn dual_program(
    ops: &[Node],
    outputs: &[u32],
    base: usize,
) -> Option<Arc<ProgramNative>> {
    if !worth_compiling(ops) {
        return None;
    }
    let shape = Shape {
        ops: ops.to_vec(),
        outputs: outputs.to_vec(),
        segments: vec![base],
    };
    let made = cached(Key::Dual(shape.clone()), 2 * ops.len(), || {
        Made::Program(compile_program(&shape, Lanes::Dual).ok().map(Arc::new))
    });
    match made {
        Made::Program(p) => p,
        Made::Kkt(_) => None,
    }
}

/// Native code for the KKT system of `dims` whose pieces the program
/// (`ops`, `outputs`, `inputs`, `constants` as in [`program`]) computes;
/// `None` as for [`program`], or where the system has more than
/// [`BLOCK_MAX`] unknowns.
pub(crate) fn kkt(
    ops: &[Node],
    outputs: &[u32],
    inputs: usize,
    dims: KktDims,
) -> Option<Arc<KktNative>> {
    let size = dims.n + dims.s + dims.k;
    if !worth_compiling(ops) || size > BLOCK_MAX || inputs != 1 + 2 * dims.n + dims.np {
        return None;
    }
    let shape = Shape {
        ops: ops.to_vec(),
        outputs: outputs.to_vec(),
        segments: vec![1, dims.n, dims.n, dims.np, dims.constants],
    };
    let made = cached(Key::Kkt(shape.clone(), dims.clone()), ops.len(), || {
        Made::Kkt(compile_kkt(&shape, &dims).ok().map(Arc::new))
    });
    match made {
        Made::Kkt(k) => k,
        Made::Program(_) => None,
    }
}

/* The functions the code calls: the interpreter's, for `f64`. */

extern "C" fn powi(x: f64, n: i32) -> f64 {
    DualNum::powi(&x, n)
}
extern "C" fn powf(x: f64, p: f64) -> f64 {
    DualNum::powf(&x, p)
}

macro_rules! unary {
    ($($name:ident),*) => {
        $(extern "C" fn $name(x: f64) -> f64 {
            DualNum::$name(&x)
        })*
    };
}
unary!(exp, ln, sin, cos, tan, asin, acos, atan, sinh, cosh, tanh);

/// [`Node::Angle`] over `f64`: the interpreter's function.
extern "C" fn angle(y: f64, x: f64, near: f64) -> f64 {
    crate::scene::atan2_near(y, x, crate::graph::near_of(near))
}

/// [`Node::Angle`] over `Dual64` into `out[0]`, `out[1]` (value and
/// derivative part): the interpreter's function, so the same bits.
extern "C" fn angle_dual(y: f64, dy: f64, x: f64, dx: f64, near: f64, out: *mut f64) {
    let (y, x) = (num_dual::Dual64::new(y, dy), num_dual::Dual64::new(x, dx));
    let a = crate::scene::atan2_near(y, x, crate::graph::near_of(near));
    // SAFETY: `out` is the code's 16-byte stack slot.
    unsafe {
        *out = a.re;
        *out.add(1) = a.eps;
    }
}

extern "C" fn signum(x: f64) -> f64 {
    num_traits::Signed::signum(&x)
}

/// `sin x` and `cos x` into `out[0]`, `out[1]` by one call of the C
/// library's `sincos` (which LLVM makes of `f64::sin_cos`): its results are
/// the separate `sin` and `cos` bit for bit (glibc computes all three by the
/// same routines; checked on 2·10⁸ arguments up to 1e300 in magnitude), and
/// it costs about one of them.
extern "C" fn sin_cos(x: f64, out: *mut f64) {
    let (s, c) = x.sin_cos();
    // SAFETY: `out` is the code's 16-byte stack slot.
    unsafe {
        *out = s;
        *out.add(1) = c;
    }
}

fn text(e: impl std::fmt::Display) -> String {
    e.to_string()
}

/// A fresh module, one function declared with `params` and `returns`, its
/// body built by `body` (which receives the function's parameters) and
/// compiled; the function's address.
fn compile_with(
    params: &[Type],
    returns: &[Type],
    instructions: usize,
    careful_up_to: usize,
    body: impl FnOnce(&mut FunctionBuilder, &[Value], Type) -> Result<(), String>,
) -> Result<(*const u8, JITModule), String> {
    let mut flags = settings::builder();
    flags.set("opt_level", "speed").map_err(text)?;
    if instructions > careful_up_to {
        flags
            .set("regalloc_algorithm", "single_pass")
            .map_err(text)?;
    }
    let isa = cranelift_native::builder()
        .map_err(text)?
        .finish(settings::Flags::new(flags))
        .map_err(text)?;
    let mut module = JITModule::new(JITBuilder::with_isa(isa, default_libcall_names()));
    let pointer = module.target_config().pointer_type();
    let mut signature = module.make_signature();
    signature
        .params
        .extend(params.iter().map(|&t| AbiParam::new(t)));
    signature
        .returns
        .extend(returns.iter().map(|&t| AbiParam::new(t)));
    let id = module
        .declare_function("nonholo", Linkage::Local, &signature)
        .map_err(text)?;
    let mut ctx: Context = module.make_context();
    ctx.func.signature = signature;
    let frontend = module.target_config();
    let mut fctx = FunctionBuilderContext::new();
    {
        let mut b = FunctionBuilder::new(&mut ctx.func, &mut fctx);
        let block = b.create_block();
        b.append_block_params_for_function_params(block);
        b.switch_to_block(block);
        let args = b.block_params(block).to_vec();
        body(&mut b, &args, pointer)?;
        b.seal_all_blocks();
        b.finalize(frontend);
    }
    module.define_function(id, &mut ctx).map_err(text)?;
    module.clear_context(&mut ctx);
    module.finalize_definitions().map_err(text)?;
    Ok((module.get_finalized_function(id), module))
}

/// What one register of a program holds in native code.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Lanes {
    /// An `f64`.
    Real,
    /// A `Dual64`, as the pair `(re, eps)`.
    Dual,
}

fn compile_program(shape: &Shape, lanes: Lanes) -> Result<ProgramNative, String> {
    let (size, careful_up_to) = match lanes {
        Lanes::Real => (shape.ops.len(), CAREFUL_REAL_UP_TO),
        Lanes::Dual => (2 * shape.ops.len(), CAREFUL_UP_TO),
    };
    let (code, module) = compile_with(
        &[pointer_type(), pointer_type()],
        &[],
        size,
        careful_up_to,
        |b, args, ptr| {
            let (inputs, out) = (args[0], args[1]);
            let store = |b: &mut FunctionBuilder, value, at: usize| {
                b.ins()
                    .store(MemFlagsData::trusted(), value, out, (8 * at) as i32);
            };
            match lanes {
                Lanes::Real => {
                    let mut v = Program::emit(b, shape, inputs, ptr)?;
                    for (k, &r) in shape.outputs.iter().enumerate() {
                        let value = v.get(b, r);
                        store(b, value, k);
                    }
                }
                Lanes::Dual => {
                    let mut v = DualProgram::emit(b, shape, inputs, ptr)?;
                    for (k, &r) in shape.outputs.iter().enumerate() {
                        let (re, eps) = v.get(b, r);
                        store(b, re, 2 * k);
                        store(b, eps, 2 * k + 1);
                    }
                }
            }
            b.ins().return_(&[]);
            Ok(())
        },
    )?;
    // SAFETY: `code` is the function compiled above, with the signature
    // (pointer, pointer) -> () in the host's calling convention.
    let entry = unsafe { std::mem::transmute::<*const u8, ProgramFn>(code) };
    Ok(Native {
        entry,
        module: Mutex::new(Some(module)),
    })
}

/// The host's pointer type (the JIT runs only on 64-bit hosts here).
fn pointer_type() -> Type {
    cranelift_codegen::ir::types::I64
}

/* Programs */

/// The IR values of a program's registers: inputs and constants loaded
/// from their segments where first used, instructions as they are emitted.
struct Program {
    values: Vec<Option<Value>>,
    /// For every register before the first instruction: its segment and
    /// place in it.
    place: Vec<(usize, usize)>,
    /// The segments' pointers, loaded where first used.
    segment: Vec<Option<Value>>,
    inputs: Value,
}

impl Program {
    /// Emits the instructions of `shape`, its inputs read through the
    /// array of segment pointers `inputs`.
    fn emit(
        b: &mut FunctionBuilder,
        shape: &Shape,
        inputs: Value,
        pointer: Type,
    ) -> Result<Program, String> {
        let place: Vec<(usize, usize)> = (shape.segments.iter().enumerate())
            .flat_map(|(k, &len)| (0..len).map(move |j| (k, j)))
            .collect();
        let base = place.len();
        let ops = &shape.ops;
        let mut v = Program {
            values: vec![None; base + ops.len()],
            place,
            segment: vec![None; shape.segments.len()],
            inputs,
        };
        let calls = Calls::new(b, pointer);
        // Arguments of both `sin` and `cos`: one `sincos` call for the two.
        let paired = sin_cos_pairs(ops);
        let mut pairs: HashMap<u32, (Value, Value)> = HashMap::new();
        for (i, op) in ops.iter().enumerate() {
            let unary =
                |b: &mut FunctionBuilder, v: &mut Program, a, f: extern "C" fn(f64) -> f64| {
                    let a = v.get(b, a);
                    calls.unary(b, f, a)
                };
            let binary =
                |b: &mut FunctionBuilder, v: &mut Program, a, c| (v.get(b, a), v.get(b, c));
            let r = match *op {
                Node::Add(a, c) => {
                    let (a, c) = binary(b, &mut v, a, c);
                    b.ins().fadd(a, c)
                }
                Node::Sub(a, c) => {
                    let (a, c) = binary(b, &mut v, a, c);
                    b.ins().fsub(a, c)
                }
                Node::Mul(a, c) => {
                    let (a, c) = binary(b, &mut v, a, c);
                    b.ins().fmul(a, c)
                }
                Node::Div(a, c) => {
                    let (a, c) = binary(b, &mut v, a, c);
                    b.ins().fdiv(a, c)
                }
                Node::Neg(a) => {
                    let a = v.get(b, a);
                    b.ins().fneg(a)
                }
                Node::Recip(a) => {
                    let a = v.get(b, a);
                    recip(b, a)
                }
                Node::Sqrt(a) => {
                    let a = v.get(b, a);
                    b.ins().sqrt(a)
                }
                Node::Abs(a) => {
                    let a = v.get(b, a);
                    b.ins().fabs(a)
                }
                Node::Powi(a, n) => {
                    let a = v.get(b, a);
                    calls.powi(b, a, n)
                }
                Node::Powf(a, p) => {
                    let a = v.get(b, a);
                    calls.powf(b, a, f64::from_bits(p))
                }
                Node::Sin(a) | Node::Cos(a) if paired.contains(&a) => {
                    let (s, c) = match pairs.get(&a) {
                        Some(&both) => both,
                        None => {
                            let x = v.get(b, a);
                            let both = calls.sin_cos(b, x);
                            pairs.insert(a, both);
                            both
                        }
                    };
                    if matches!(op, Node::Sin(_)) { s } else { c }
                }
                Node::Sin(a) => unary(b, &mut v, a, sin),
                Node::Cos(a) => unary(b, &mut v, a, cos),
                Node::Exp(a) => unary(b, &mut v, a, exp),
                Node::Ln(a) => unary(b, &mut v, a, ln),
                Node::Tan(a) => unary(b, &mut v, a, tan),
                Node::Asin(a) => unary(b, &mut v, a, asin),
                Node::Acos(a) => unary(b, &mut v, a, acos),
                Node::Atan(a) => unary(b, &mut v, a, atan),
                Node::Sinh(a) => unary(b, &mut v, a, sinh),
                Node::Cosh(a) => unary(b, &mut v, a, cosh),
                Node::Tanh(a) => unary(b, &mut v, a, tanh),
                Node::Signum(a) => unary(b, &mut v, a, signum),
                Node::Angle(y, x, near) => {
                    let (y, x) = binary(b, &mut v, y, x);
                    calls.angle(b, y, x, f64::from_bits(near))
                }
                Node::Const(_) | Node::Input(_) => {
                    return Err("a constant or an input among the instructions".into());
                }
            };
            v.values[base + i] = Some(r);
        }
        Ok(v)
    }

    /// The value of register `r`.
    fn get(&mut self, b: &mut FunctionBuilder, r: u32) -> Value {
        let r = r as usize;
        if let Some(v) = self.values[r] {
            return v;
        }
        let (k, j) = self.place[r];
        // The inputs are read-only for the whole call, and aligned.
        let read = MemFlagsData::trusted().with_readonly();
        let segment = match self.segment[k] {
            Some(s) => s,
            None => {
                let s = b
                    .ins()
                    .load(pointer_type(), read, self.inputs, (8 * k) as i32);
                self.segment[k] = Some(s);
                s
            }
        };
        let v = b.ins().load(F64, read, segment, (8 * j) as i32);
        self.values[r] = Some(v);
        v
    }
}

/// `1 / x`, as `f64::recip` computes it.
fn recip(b: &mut FunctionBuilder, x: Value) -> Value {
    let one = b.ins().f64const(1.0);
    b.ins().fdiv(one, x)
}

/// The registers whose `sin` and `cos` a program both computes.
fn sin_cos_pairs(ops: &[Node]) -> HashSet<u32> {
    let sines: HashSet<u32> = (ops.iter())
        .filter_map(|op| {
            if let Node::Sin(a) = *op {
                Some(a)
            } else {
                None
            }
        })
        .collect();
    (ops.iter())
        .filter_map(|op| {
            if let Node::Cos(a) = *op {
                Some(a)
            } else {
                None
            }
        })
        .filter(|a| sines.contains(a))
        .collect()
}

/// Calls of the Rust functions above from the code.
struct Calls {
    pointer: Type,
    unary: SigRef,
    powi: SigRef,
    powf: SigRef,
    sin_cos: SigRef,
    angle: SigRef,
    angle_dual: SigRef,
    /// The 16 bytes `sin_cos` and `angle_dual` write into.
    slot: StackSlot,
}

impl Calls {
    fn new(b: &mut FunctionBuilder, pointer: Type) -> Calls {
        let mut sig = |params: &[Type], result: bool| {
            let mut s = Signature::new(b.func.signature.call_conv);
            s.params.extend(params.iter().map(|&t| AbiParam::new(t)));
            if result {
                s.returns.push(AbiParam::new(F64));
            }
            b.import_signature(s)
        };
        let (unary, powi, powf) = (
            sig(&[F64], true),
            sig(&[F64, I32], true),
            sig(&[F64, F64], true),
        );
        let sin_cos = sig(&[F64, pointer], false);
        let angle = sig(&[F64, F64, F64], true);
        let angle_dual = sig(&[F64, F64, F64, F64, F64, pointer], false);
        let slot =
            b.create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 16, 3));
        Calls {
            pointer,
            unary,
            powi,
            powf,
            sin_cos,
            angle,
            angle_dual,
            slot,
        }
    }

    fn call(
        &self,
        b: &mut FunctionBuilder,
        f: *const (),
        sig: SigRef,
        args: &[Value],
    ) -> Option<Value> {
        let callee = b.ins().iconst(self.pointer, f as i64);
        let inst = b.ins().call_indirect(sig, callee, args);
        b.inst_results(inst).first().copied()
    }

    fn unary(&self, b: &mut FunctionBuilder, f: extern "C" fn(f64) -> f64, x: Value) -> Value {
        self.call(b, f as *const (), self.unary, &[x])
            .expect("a result")
    }

    fn powi(&self, b: &mut FunctionBuilder, x: Value, n: i32) -> Value {
        let n = b.ins().iconst(I32, i64::from(n));
        self.call(b, powi as *const (), self.powi, &[x, n])
            .expect("a result")
    }

    fn powf(&self, b: &mut FunctionBuilder, x: Value, p: f64) -> Value {
        let p = b.ins().f64const(p);
        self.call(b, powf as *const (), self.powf, &[x, p])
            .expect("a result")
    }

    /// [`Node::Angle`] of `(y, x)` over `f64`.
    fn angle(&self, b: &mut FunctionBuilder, y: Value, x: Value, near: f64) -> Value {
        let near = b.ins().f64const(near);
        self.call(b, angle as *const (), self.angle, &[y, x, near])
            .expect("a result")
    }

    /// [`Node::Angle`] of `(y, x)` over `Dual64`.
    fn angle_dual(&self, b: &mut FunctionBuilder, y: Pair, x: Pair, near: f64) -> Pair {
        let near = b.ins().f64const(near);
        let at = b.ins().stack_addr(self.pointer, self.slot, 0);
        let args = [y.0, y.1, x.0, x.1, near, at];
        self.call(b, angle_dual as *const (), self.angle_dual, &args);
        let re = b.ins().stack_load(self.pointer, F64, self.slot, 0);
        let eps = b.ins().stack_load(self.pointer, F64, self.slot, 8);
        (re, eps)
    }

    /// `(sin x, cos x)` by one `sincos`.
    fn sin_cos(&self, b: &mut FunctionBuilder, x: Value) -> (Value, Value) {
        let at = b.ins().stack_addr(self.pointer, self.slot, 0);
        self.call(b, sin_cos as *const (), self.sin_cos, &[x, at]);
        let s = b.ins().stack_load(self.pointer, F64, self.slot, 0);
        let c = b.ins().stack_load(self.pointer, F64, self.slot, 8);
        (s, c)
    }
}

/* Programs over dual numbers */

/// A `Dual64` in the code: value and derivative part.
type Pair = (Value, Value);

/// The IR pairs of a program's registers over `Dual64`, read from one
/// segment of pairs (the register file).
struct DualProgram {
    values: Vec<Option<Pair>>,
    regs: Value,
}

impl DualProgram {
    fn emit(
        b: &mut FunctionBuilder,
        shape: &Shape,
        inputs: Value,
        pointer: Type,
    ) -> Result<DualProgram, String> {
        let [base] = shape.segments[..] else {
            return Err("a dual program reads one segment".into());
        };
        let read = MemFlagsData::trusted().with_readonly();
        let regs = b.ins().load(pointer, read, inputs, 0);
        let ops = &shape.ops;
        let mut v = DualProgram {
            values: vec![None; base + ops.len()],
            regs,
        };
        let calls = Calls::new(b, pointer);
        let paired = sin_cos_pairs(ops);
        let mut trig: HashMap<u32, (Value, Value)> = HashMap::new();
        let mut sin_cos = |b: &mut FunctionBuilder, v: &mut DualProgram, a: u32| {
            if let Some(&both) = trig.get(&a) {
                return both;
            }
            let x = v.get(b, a).0;
            let both = calls.sin_cos(b, x);
            if paired.contains(&a) {
                trig.insert(a, both);
            }
            both
        };
        for (i, op) in ops.iter().enumerate() {
            let r = match *op {
                Node::Add(a, c) => {
                    let (x, y) = (v.get(b, a), v.get(b, c));
                    (b.ins().fadd(x.0, y.0), b.ins().fadd(x.1, y.1))
                }
                Node::Sub(a, c) => {
                    let (x, y) = (v.get(b, a), v.get(b, c));
                    (b.ins().fsub(x.0, y.0), b.ins().fsub(x.1, y.1))
                }
                Node::Mul(a, c) => {
                    let (x, y) = (v.get(b, a), v.get(b, c));
                    dual_mul(b, x, y)
                }
                Node::Div(a, c) => {
                    let (x, y) = (v.get(b, a), v.get(b, c));
                    dual_div(b, x, y)
                }
                Node::Neg(a) => {
                    let x = v.get(b, a);
                    (b.ins().fneg(x.0), b.ins().fneg(x.1))
                }
                Node::Recip(a) => {
                    // rec = 1/re, f1 = −rec·rec
                    let x = v.get(b, a);
                    let rec = recip(b, x.0);
                    let minus = b.ins().fneg(rec);
                    let f1 = b.ins().fmul(minus, rec);
                    chain(b, x, rec, f1)
                }
                Node::Powi(a, n) => {
                    let x = v.get(b, a);
                    match n {
                        0 => one(b),
                        1 => x,
                        2 => dual_mul(b, x, x),
                        _ => {
                            let pow3 = calls.powi(b, x.0, n - 3);
                            let p2 = b.ins().fmul(pow3, x.0);
                            let p1 = b.ins().fmul(p2, x.0);
                            let f0 = b.ins().fmul(p1, x.0);
                            let nf = b.ins().f64const(f64::from(n));
                            let f1 = b.ins().fmul(p1, nf);
                            chain(b, x, f0, f1)
                        }
                    }
                }
                Node::Powf(a, p) => {
                    let (x, p) = (v.get(b, a), f64::from_bits(p));
                    if p == 0.0 {
                        one(b)
                    } else if p == 1.0 {
                        x
                    } else if (p - 1.0 - 1.0).abs() < f64::EPSILON {
                        dual_mul(b, x, x)
                    } else {
                        let n3 = p - 1.0 - 1.0 - 1.0;
                        let pow3 = calls.powf(b, x.0, n3);
                        let p2 = b.ins().fmul(pow3, x.0);
                        let p1 = b.ins().fmul(p2, x.0);
                        let f0 = b.ins().fmul(p1, x.0);
                        let pf = b.ins().f64const(p);
                        let f1 = b.ins().fmul(p1, pf);
                        chain(b, x, f0, f1)
                    }
                }
                Node::Sqrt(a) => {
                    // f0 = √re, f1 = f0·(1/re)·½
                    let x = v.get(b, a);
                    let rec = recip(b, x.0);
                    let f0 = b.ins().sqrt(x.0);
                    let half = b.ins().f64const(0.5);
                    let f1 = b.ins().fmul(f0, rec);
                    let f1 = b.ins().fmul(f1, half);
                    chain(b, x, f0, f1)
                }
                Node::Exp(a) => {
                    let x = v.get(b, a);
                    let f = calls.unary(b, exp, x.0);
                    chain(b, x, f, f)
                }
                Node::Ln(a) => {
                    let x = v.get(b, a);
                    let rec = recip(b, x.0);
                    let f0 = calls.unary(b, ln, x.0);
                    chain(b, x, f0, rec)
                }
                Node::Sin(a) => {
                    let x = v.get(b, a);
                    let (s, c) = sin_cos(b, &mut v, a);
                    chain(b, x, s, c)
                }
                Node::Cos(a) => {
                    let x = v.get(b, a);
                    let (s, c) = sin_cos(b, &mut v, a);
                    let minus = b.ins().fneg(s);
                    chain(b, x, c, minus)
                }
                Node::Tan(a) => {
                    // sin / cos of the dual number
                    let x = v.get(b, a);
                    let (s, c) = sin_cos(b, &mut v, a);
                    let sine = chain(b, x, s, c);
                    let minus = b.ins().fneg(s);
                    let cosine = chain(b, x, c, minus);
                    dual_div(b, sine, cosine)
                }
                Node::Asin(a) | Node::Acos(a) => {
                    // rec = 1/(1 − re²), f1 = ±√rec
                    let x = v.get(b, a);
                    let one = b.ins().f64const(1.0);
                    let sq = b.ins().fmul(x.0, x.0);
                    let d = b.ins().fsub(one, sq);
                    let rec = recip(b, d);
                    let is_asin = matches!(op, Node::Asin(_));
                    let f0 = calls.unary(b, if is_asin { asin } else { acos }, x.0);
                    let root = b.ins().sqrt(rec);
                    let f1 = if is_asin { root } else { b.ins().fneg(root) };
                    chain(b, x, f0, f1)
                }
                Node::Atan(a) => {
                    // rec = 1/(1 + re²)
                    let x = v.get(b, a);
                    let one = b.ins().f64const(1.0);
                    let sq = b.ins().fmul(x.0, x.0);
                    let d = b.ins().fadd(one, sq);
                    let rec = recip(b, d);
                    let f0 = calls.unary(b, atan, x.0);
                    chain(b, x, f0, rec)
                }
                Node::Sinh(a) | Node::Cosh(a) | Node::Tanh(a) => {
                    let x = v.get(b, a);
                    let s = calls.unary(b, sinh, x.0);
                    let c = calls.unary(b, cosh, x.0);
                    match op {
                        Node::Sinh(_) => chain(b, x, s, c),
                        Node::Cosh(_) => chain(b, x, c, s),
                        _ => {
                            // sinh() / cosh() of the dual number
                            let sh = chain(b, x, s, c);
                            let ch = chain(b, x, c, s);
                            dual_div(b, sh, ch)
                        }
                    }
                }
                Node::Abs(a) => {
                    // `self` where re has a clear sign bit, `−self` elsewhere
                    let x = v.get(b, a);
                    let positive = sign_positive(b, x.0);
                    let (nr, ne) = (b.ins().fneg(x.0), b.ins().fneg(x.1));
                    (
                        b.ins().select(positive, x.0, nr),
                        b.ins().select(positive, x.1, ne),
                    )
                }
                Node::Signum(a) => {
                    // 1 where re has a clear sign bit, 0 at −0, −1 elsewhere
                    // (with derivative parts 0, 0 and −0)
                    let x = v.get(b, a);
                    let positive = sign_positive(b, x.0);
                    let zero = b.ins().f64const(0.0);
                    let is_zero = b.ins().fcmp(FloatCC::Equal, x.0, zero);
                    let (p1, m1, m0) = (
                        b.ins().f64const(1.0),
                        b.ins().f64const(-1.0),
                        b.ins().f64const(-0.0),
                    );
                    let re = b.ins().select(is_zero, zero, m1);
                    let re = b.ins().select(positive, p1, re);
                    let eps = b.ins().select(is_zero, zero, m0);
                    let eps = b.ins().select(positive, zero, eps);
                    (re, eps)
                }
                Node::Angle(y, x, near) => {
                    let (y, x) = (v.get(b, y), v.get(b, x));
                    calls.angle_dual(b, y, x, f64::from_bits(near))
                }
                Node::Const(_) | Node::Input(_) => {
                    return Err("a constant or an input among the instructions".into());
                }
            };
            v.values[base + i] = Some(r);
        }
        Ok(v)
    }

    /// The pair of register `r`.
    fn get(&mut self, b: &mut FunctionBuilder, r: u32) -> Pair {
        let r = r as usize;
        if let Some(v) = self.values[r] {
            return v;
        }
        // The register file is read-only for the whole call, and aligned.
        let read = MemFlagsData::trusted().with_readonly();
        let re = b.ins().load(F64, read, self.regs, (16 * r) as i32);
        let eps = b.ins().load(F64, read, self.regs, (16 * r + 8) as i32);
        self.values[r] = Some((re, eps));
        (re, eps)
    }
}

/// num-dual's `Dual::one()`: `(1, 0)`.
fn one(b: &mut FunctionBuilder) -> Pair {
    (b.ins().f64const(1.0), b.ins().f64const(0.0))
}

/// num-dual's chain rule: `(f0, eps·f1)`.
fn chain(b: &mut FunctionBuilder, x: Pair, f0: Value, f1: Value) -> Pair {
    (f0, b.ins().fmul(x.1, f1))
}

/// num-dual's product rule: `(a·b, ε_a·b + ε_b·a)`.
fn dual_mul(b: &mut FunctionBuilder, x: Pair, y: Pair) -> Pair {
    let re = b.ins().fmul(x.0, y.0);
    let e1 = b.ins().fmul(x.1, y.0);
    let e2 = b.ins().fmul(y.1, x.0);
    (re, b.ins().fadd(e1, e2))
}

/// num-dual's quotient rule: `inv = 1/b`, `(a·inv, (ε_a·b − ε_b·a)·inv·inv)`.
fn dual_div(b: &mut FunctionBuilder, x: Pair, y: Pair) -> Pair {
    let inv = recip(b, y.0);
    let re = b.ins().fmul(x.0, inv);
    let e1 = b.ins().fmul(x.1, y.0);
    let e2 = b.ins().fmul(y.1, x.0);
    let e = b.ins().fsub(e1, e2);
    let e = b.ins().fmul(e, inv);
    (re, b.ins().fmul(e, inv))
}

/// `x.is_sign_positive()`: the sign bit clear (NaN included).
fn sign_positive(b: &mut FunctionBuilder, x: Value) -> Value {
    let bits = b
        .ins()
        .bitcast(cranelift_codegen::ir::types::I64, MemFlagsData::new(), x);
    b.ins().icmp_imm_s(IntCC::SignedGreaterThanOrEqual, bits, 0)
}

/* KKT systems */

fn compile_kkt(shape: &Shape, d: &KktDims) -> Result<KktNative, String> {
    let ptr = pointer_type();
    let (code, module) = compile_with(
        &[ptr; 5],
        &[I32],
        shape.ops.len(),
        CAREFUL_UP_TO,
        |b, args, ptr| {
            let (inputs, gains, out, sol, pieces) = (args[0], args[1], args[2], args[3], args[4]);
            let mut v = Program::emit(b, shape, inputs, ptr)?;
            let outputs: Vec<Value> = shape.outputs.iter().map(|&r| v.get(b, r)).collect();
            let store = |b: &mut FunctionBuilder, range: std::ops::Range<usize>| {
                for k in range {
                    let at = (8 * k) as i32;
                    b.ins().store(MemFlagsData::trusted(), outputs[k], out, at);
                }
            };
            let read = MemFlagsData::trusted().with_readonly();
            let gain = |b: &mut FunctionBuilder, i: i32| b.ins().load(F64, read, gains, 8 * i);
            let (alpha_g, alpha_f, beta) = (gain(b, 0), gain(b, 1), gain(b, 2));
            // The matrix, zero where no entry is (Kkt::assemble), and the
            // right-hand side (Kkt::eval_ideal, Kkt::holonomic_rhs).
            let size = d.n + d.s + d.k;
            let zero = b.ins().f64const(0.0);
            let mut a = vec![zero; size * size];
            for &(at, src) in &d.entries {
                a[at] = outputs[src as usize];
            }
            let [force, g, g_rate0, f, f_rate, f_accel0] = d.rhs_at;
            let mut rhs: Vec<Value> = outputs[force..force + d.n].to_vec();
            let two = b.ins().f64const(2.0);
            let two_alpha_g = b.ins().fmul(two, alpha_g);
            for i in 0..d.s {
                let minus = b.ins().fneg(outputs[g_rate0 + i]);
                let damp = b.ins().fmul(outputs[g + i], two_alpha_g);
                rhs.push(b.ins().fsub(minus, damp));
            }
            let two_alpha_f = b.ins().fmul(two, alpha_f);
            let beta2 = b.ins().fmul(beta, beta);
            for i in 0..d.k {
                let minus = b.ins().fneg(outputs[f_accel0 + i]);
                let damp = b.ins().fmul(outputs[f_rate + i], two_alpha_f);
                let x = b.ins().fsub(minus, damp);
                let spring = b.ins().fmul(outputs[f + i], beta2);
                rhs.push(b.ins().fsub(x, spring));
            }
            let decline = b.create_block();
            let x = block_elimination(b, &a, rhs, d.n, decline);
            for (i, &xi) in x.iter().enumerate() {
                b.ins()
                    .store(MemFlagsData::trusted(), xi, sol, (8 * i) as i32);
            }
            // Solved: the constraint values, into the caller's constraint state.
            let lens = [
                (g, d.s),
                (g_rate0, d.s),
                (f, d.k),
                (f_rate, d.k),
                (f_accel0, d.k),
            ];
            for (i, &(start, len)) in lens.iter().enumerate() {
                if len == 0 {
                    continue;
                }
                let to = b.ins().load(ptr, read, pieces, (8 * i) as i32);
                for j in 0..len {
                    let at = (8 * j) as i32;
                    b.ins()
                        .store(MemFlagsData::trusted(), outputs[start + j], to, at);
                }
            }
            let one = b.ins().iconst(I32, 1);
            b.ins().return_(&[one]);
            // Declined: every output, for the caller's assembly and solve.
            b.switch_to_block(decline);
            store(b, 0..outputs.len());
            let none = b.ins().iconst(I32, 0);
            b.ins().return_(&[none]);
            Ok(())
        },
    )?;
    // SAFETY: `code` is the function compiled above, with the signature
    // (pointer × 5) -> i32 in the host's calling convention.
    let entry = unsafe { std::mem::transmute::<*const u8, KktFn>(code) };
    Ok(Native {
        entry,
        module: Mutex::new(Some(module)),
    })
}

/// Continues in a new block if `ok`, jumps to `decline` otherwise.
fn require(b: &mut FunctionBuilder, ok: Value, decline: Block) {
    let next = b.create_block();
    b.ins().brif(ok, next, &[], decline, &[]);
    b.switch_to_block(next);
}

/// `crate::linalg::block_core` on the column-major `a` (`size × size`,
/// primal block `n`) and right-hand side `b0`, unrolled: the same
/// operations in the same order, each test jumping to `decline` where it
/// fails. Returns the solution's values.
fn block_elimination(
    b: &mut FunctionBuilder,
    a: &[Value],
    b0: Vec<Value>,
    n: usize,
    decline: Block,
) -> Vec<Value> {
    let size = b0.len();
    let at = |i: usize, j: usize| i + j * size;
    let c = |b: &mut FunctionBuilder, x: f64| b.ins().f64const(x);
    let mut w = a.to_vec();
    let mut inverse = vec![None; size];
    // One elimination step at (k, k): `eliminate` of linalg.rs.
    let eliminate = |b: &mut FunctionBuilder, w: &mut [Value], k: usize| {
        let one = b.ins().f64const(1.0);
        let r = b.ins().fdiv(one, w[at(k, k)]);
        for i in k + 1..size {
            w[at(i, k)] = b.ins().fmul(w[at(i, k)], r);
        }
        for j in k + 1..size {
            let u = w[at(k, j)];
            for i in k + 1..size {
                let l = b.ins().fmul(w[at(i, k)], u);
                w[at(i, j)] = b.ins().fsub(w[at(i, j)], l);
            }
        }
        r
    };
    // M's columns, the pivot at least PRIMAL_PIVOT of M's own diagonal.
    let primal = c(b, PRIMAL_PIVOT);
    let zero = c(b, 0.0);
    for k in 0..n {
        let (pivot, diagonal) = (w[at(k, k)], a[at(k, k)]);
        let positive = b.ins().fcmp(FloatCC::GreaterThan, diagonal, zero);
        let floor = b.ins().fmul(primal, diagonal);
        let large = b.ins().fcmp(FloatCC::GreaterThan, pivot, floor);
        let ok = b.ins().band(positive, large);
        require(b, ok, decline);
        inverse[k] = Some(eliminate(b, &mut w, k));
    }
    // The Schur complement's scale: f64::max over |w| (a NaN is passed over).
    let mut scale = zero;
    for j in n..size {
        for i in n..size {
            let v = b.ins().fabs(w[at(i, j)]);
            let larger = b.ins().fcmp(FloatCC::GreaterThan, v, scale);
            scale = b.ins().select(larger, v, scale);
        }
    }
    let margin = c(b, SCHUR_MARGIN);
    let count = c(b, (size - n).max(1) as f64);
    let eps = c(b, f64::EPSILON);
    let tiny = b.ins().fmul(margin, count);
    let tiny = b.ins().fmul(tiny, eps);
    let tiny = b.ins().fmul(tiny, scale);
    // Its columns with row exchanges: the first largest |w| at or below
    // the diagonal, by strict comparison, as a register of row numbers.
    let mut piv: Vec<Option<Value>> = vec![None; size];
    for k in n..size {
        let mut best = b.ins().fabs(w[at(k, k)]);
        let mut p = b.ins().iconst(I32, k as i64);
        for i in k + 1..size {
            let v = b.ins().fabs(w[at(i, k)]);
            let larger = b.ins().fcmp(FloatCC::GreaterThan, v, best);
            best = b.ins().select(larger, v, best);
            let row = b.ins().iconst(I32, i as i64);
            p = b.ins().select(larger, row, p);
        }
        // !(best is NaN || best <= tiny): `best > tiny` is false for NaN.
        let ok = b.ins().fcmp(FloatCC::GreaterThan, best, tiny);
        require(b, ok, decline);
        piv[k] = Some(p);
        for i in k + 1..size {
            let row = b.ins().iconst(I32, i as i64);
            let here = b.ins().icmp(IntCC::Equal, p, row);
            for j in k..size {
                let (top, other) = (w[at(k, j)], w[at(i, j)]);
                w[at(k, j)] = b.ins().select(here, other, top);
                w[at(i, j)] = b.ins().select(here, top, other);
            }
        }
        inverse[k] = Some(eliminate(b, &mut w, k));
    }
    // Forward: M's multipliers, then the exchanges and multipliers of S.
    let mut x = b0.clone();
    for k in 0..size {
        if let Some(p) = piv[k] {
            for i in k + 1..size {
                let row = b.ins().iconst(I32, i as i64);
                let here = b.ins().icmp(IntCC::Equal, p, row);
                let (top, other) = (x[k], x[i]);
                x[k] = b.ins().select(here, other, top);
                x[i] = b.ins().select(here, top, other);
            }
        }
        let xk = x[k];
        for i in k + 1..size {
            let l = b.ins().fmul(w[at(i, k)], xk);
            x[i] = b.ins().fsub(x[i], l);
        }
    }
    // Back substitution through the whole upper triangle.
    for j in (0..size).rev() {
        let xj = b
            .ins()
            .fmul(x[j], inverse[j].expect("every column eliminated"));
        x[j] = xj;
        for i in 0..j {
            let u = b.ins().fmul(w[at(i, j)], xj);
            x[i] = b.ins().fsub(x[i], u);
        }
    }
    // The componentwise backward error, below BACKWARD in every row.
    let mut residual: Vec<Value> = b0.iter().map(|&bi| b.ins().fneg(bi)).collect();
    let mut size_of: Vec<Value> = b0.iter().map(|&bi| b.ins().fabs(bi)).collect();
    for j in 0..size {
        for i in 0..size {
            let v = b.ins().fmul(a[at(i, j)], x[j]);
            residual[i] = b.ins().fadd(residual[i], v);
            let av = b.ins().fabs(v);
            size_of[i] = b.ins().fadd(size_of[i], av);
        }
    }
    let backward = c(b, BACKWARD);
    for i in 0..size {
        let r = b.ins().fabs(residual[i]);
        let bound = b.ins().fmul(backward, size_of[i]);
        let ok = b.ins().fcmp(FloatCC::LessThanOrEqual, r, bound);
        require(b, ok, decline);
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::{Graph, Program as Straight, Tracer, trace};
    use num_dual::Dual64;
    use rand::{Rng, SeedableRng};

    /// Every operation the graph represents (and `sin`, `cos` of one
    /// argument, which native code pairs into one `sincos`).
    fn every_op<D: crate::Scalar>(x: &[D]) -> D {
        let (a, b, c) = (x[0], x[1], x[2]);
        let s = a.sin() * a.cos() + b.cos() + (a * b).tan() - c.asin()
            + c.acos() * 0.5
            + (a / b).atan()
            + crate::scene::atan2(c, a - 0.3) * b
            + crate::scene::atan2_near(a, b - 1.0, Some(-7.0));
        let h = b.sinh() * c.cosh() - (a * c).tanh() + (-b).abs() * b.signum() + c.abs();
        let p = a.powi(3) - b.powf(2.5)
            + a.powi(-2)
            + b.powi(2)
            + a.powf(2.0)
            + a.recip()
            + (b * b + 1.0).sqrt()
            + c.exp() * (a + 2.0).ln();
        s * h + p / (c * c + 1.0) - a.sin() * c.signum()
    }

    /// The function, its gradient and its Hessian as one program.
    fn program() -> Straight {
        let (mut g, root) = trace(Graph::new(), || {
            let v: Vec<Tracer> = [0.7, 1.3, 0.2]
                .iter()
                .enumerate()
                .map(|(i, &v)| Tracer::input(i as u32, v))
                .collect();
            every_op(&v).id
        });
        assert!(g.is_exact());
        let mut outputs = vec![root];
        for i in 0..3u32 {
            let d = g.diff(root, i);
            outputs.push(d);
            for j in 0..3u32 {
                outputs.push(g.diff(d, j));
            }
        }
        Straight::new(&g, &outputs, 3)
    }

    /// Bit for bit, NaN matching NaN (its payload is not specified).
    fn same(a: f64, b: f64) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    /// Points inside and outside the functions' domains, signed zeros,
    /// large values.
    fn points(rng: &mut impl Rng) -> Vec<[f64; 3]> {
        let special = [0.0, -0.0, 1.0, -1.0, 0.5, -2.5, 1e300, -1e-300, 3.0];
        // Inside the domains (asin, acos need |c| ≤ 1, powf b ≥ 0, ln a > −2).
        let mut all: Vec<[f64; 3]> = (0..400)
            .map(|_| {
                [
                    rng.random_range(-1.5..1.5),
                    rng.random_range(0.1..2.0),
                    rng.random_range(-0.95..0.95),
                ]
            })
            .collect();
        for &x in &special {
            all.push([x, 1.1, 0.3]);
            all.push([0.4, x, -0.2]);
            all.push([0.9, -0.7, x]);
        }
        all
    }

    /// `NONHOLO_NATIVE` switches native code off with `0` or `off` only.
    #[test]
    fn environment_switch() {
        for (value, on) in [
            (None, true),
            (Some("0"), false),
            (Some("off"), false),
            (Some("1"), true),
            (Some("on"), true),
            (Some(""), true),
        ] {
            assert_eq!(requested(value), on, "{value:?}");
        }
    }

    /// Native code computes what the interpreter computes, bit for bit,
    /// over `f64` and over `Dual64`, on every operation.
    #[test]
    fn native_programs_equal_the_interpreter() {
        let p = program();
        assert!(p.is_native(), "the program compiled to native code");
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let (_, outputs) = p.shape();
        let (mut regs, mut native, mut interpreted) =
            (p.registers::<f64>(), vec![0.0; outputs], vec![0.0; outputs]);
        let mut dregs = p.registers::<Dual64>();
        let mut dnative = vec![Dual64::from(0.0); outputs];
        let mut dinterp = dnative.clone();
        let mut compared = 0;
        for x in points(&mut rng) {
            regs[..3].copy_from_slice(&x);
            p.run(&mut regs, &mut native);
            p.run_interpreted(&mut regs, &mut interpreted);
            for (k, (a, b)) in native.iter().zip(&interpreted).enumerate() {
                assert!(
                    same(*a, *b),
                    "output {k} at {x:?}: native {a:e}, interpreter {b:e}"
                );
            }
            for i in 0..3 {
                dregs[i] = Dual64::new(x[i], rng.random_range(-2.0..2.0));
            }
            p.run(&mut dregs, &mut dnative);
            p.run_interpreted(&mut dregs, &mut dinterp);
            for (k, (a, b)) in dnative.iter().zip(&dinterp).enumerate() {
                assert!(
                    same(a.re, b.re) && same(a.eps, b.eps),
                    "dual output {k} at {x:?}: native {a}, interpreter {b}"
                );
            }
            compared += native.iter().filter(|v| v.is_finite()).count();
        }
        // Most outputs are finite numbers, not NaN against NaN.
        assert!(compared > 13 * 400, "{compared} finite outputs compared");
    }

    /// A KKT system's code whose program passes its parameters through:
    /// the values of `M`'s upper triangle, `Q`, `g`, `G`, `ġ₀`, `f`, `F`,
    /// `ḟ`, `f̈₀` (dense, in the layout of `crate::compiled::Pattern`).
    fn pass_through(n: usize, s: usize, k: usize) -> (Arc<KktNative>, KktDims) {
        let lens = [n * (n + 1) / 2, n, s, s * n, s, k, k * n, k, k];
        let mut at = [0; 10];
        for i in 0..9 {
            at[i + 1] = at[i] + lens[i];
        }
        let np = at[9];
        let inputs = 1 + 2 * n + np;
        let one = inputs as u32; // the constant 1.0, after the inputs
        let ops: Vec<Node> = (0..np)
            .map(|i| Node::Mul((1 + 2 * n + i) as u32, one))
            .collect();
        let base = inputs + 1;
        let outputs: Vec<u32> = (0..np).map(|i| (base + i) as u32).collect();
        let size = n + s + k;
        let mut entries = Vec::new();
        let mut m = at[0];
        for r in 0..n {
            for c in r..n {
                entries.push((r + c * size, m as u32));
                if r != c {
                    entries.push((c + r * size, m as u32));
                }
                m += 1;
            }
        }
        for (rows, row0, start) in [(s, n, at[3]), (k, n + s, at[6])] {
            for r in 0..rows {
                for c in 0..n {
                    let src = (start + r * n + c) as u32;
                    entries.push((row0 + r + c * size, src));
                    entries.push((c + (row0 + r) * size, src));
                }
            }
        }
        let dims = KktDims {
            n,
            s,
            k,
            np,
            constants: 1,
            outputs: np,
            rhs_at: [at[1], at[2], at[4], at[5], at[7], at[8]],
            entries,
        };
        let native = kkt(&ops, &outputs, inputs, dims.clone()).expect("compiled");
        (native, dims)
    }

    /// The KKT code's block elimination accepts exactly the systems
    /// `linalg::block` accepts, and solves them bit for bit as it does:
    /// random systems of 1 to 8 unknowns, well posed, with `M` indefinite
    /// or nearly singular, with dependent constraints, with a NaN.
    #[test]
    fn native_kkt_equals_block_elimination() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let (mut accepted, mut declined) = (0, 0);
        for trial in 0..3000 {
            let n = rng.random_range(1..=5usize);
            let m = rng.random_range(0..=(8 - n).min(3));
            let s = rng.random_range(0..=m);
            let k = m - s;
            let size = n + m;
            let (native, dims) = pass_through(n, s, k);
            // M = A Aᵀ + d I with units over decades; C random rows.
            let unit: Vec<f64> = (0..n)
                .map(|_| 10f64.powf(rng.random_range(-3.0..3.0)))
                .collect();
            let a: Vec<f64> = (0..n * n).map(|_| rng.random_range(-1.0..1.0)).collect();
            let shift = match trial % 5 {
                0 => -1.5, // indefinite, mostly
                1 => 1e-9, // nearly singular, sometimes
                _ => 0.1,
            };
            let mut mass = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    let v: f64 = (0..n).map(|l| a[i * n + l] * a[j * n + l]).sum::<f64>()
                        + if i == j { shift } else { 0.0 };
                    mass[i * n + j] = v * unit[i] * unit[j];
                }
            }
            let mut rows: Vec<f64> = (0..m * n).map(|_| rng.random_range(-1.0..1.0)).collect();
            if trial % 7 == 0 && m >= 2 {
                // the last row a multiple of the first
                for c in 0..n {
                    rows[(m - 1) * n + c] = 3.0 * rows[c];
                }
            }
            let mut values = Vec::with_capacity(dims.np);
            for r in 0..n {
                for c in r..n {
                    values.push(mass[r * n + c]);
                }
            }
            values.extend((0..n).map(|_| rng.random_range(-5.0..5.0)));
            let mut piece = |len: usize, values: &mut Vec<f64>| {
                values.extend((0..len).map(|_| rng.random_range(-2.0..2.0)));
            };
            piece(s, &mut values);
            values.extend_from_slice(&rows[..s * n]);
            piece(s, &mut values);
            piece(k, &mut values);
            values.extend_from_slice(&rows[s * n..]);
            piece(k, &mut values);
            piece(k, &mut values);
            if trial % 11 == 0 {
                let at = rng.random_range(0..values.len());
                values[at] = f64::NAN;
            }
            let gains = [0.3, 0.7, 2.0];
            // The system as Kkt assembles it.
            let mut matrix = vec![0.0; size * size];
            for &(place, src) in &dims.entries {
                matrix[place] = values[src as usize];
            }
            let [force, g, g_rate0, f, f_rate, f_accel0] = dims.rhs_at;
            let mut rhs: Vec<f64> = values[force..force + n].to_vec();
            for i in 0..s {
                rhs.push(-values[g_rate0 + i] - values[g + i] * (2.0 * gains[0]));
            }
            for i in 0..k {
                rhs.push(
                    -values[f_accel0 + i]
                        - values[f_rate + i] * (2.0 * gains[1])
                        - values[f + i] * (gains[2] * gains[2]),
                );
            }
            let block_accepts = crate::linalg::block(&matrix, n, &mut rhs, size);
            let (q, qd) = (vec![0.1; n], vec![0.2; n]);
            let x = KktInputs {
                t: 0.0,
                q: &q,
                qd: &qd,
                p: &values,
                constants: &[1.0],
            };
            let (mut out, mut sol) = (vec![0.0; dims.outputs], vec![0.0; size]);
            let mut pieces = [s, s, k, k, k].map(|l| vec![0.0; l]);
            let native_accepts = native.solve(
                &dims,
                &x,
                gains,
                &mut out,
                &mut sol,
                pieces.each_mut().map(|p| p.as_mut_slice()),
            );
            assert_eq!(
                native_accepts, block_accepts,
                "trial {trial}: n {n}, s {s}, k {k}"
            );
            // Declined, every output; solved, the constraint values.
            if native_accepts {
                let starts = [g, g_rate0, f, f_rate, f_accel0];
                for (piece, start) in pieces.iter().zip(starts) {
                    let expected = &values[start..start + piece.len()];
                    assert!(piece.iter().zip(expected).all(|(a, b)| same(*a, *b)));
                }
            } else {
                assert!(out.iter().zip(&values).all(|(a, b)| same(*a, *b)));
            }
            if native_accepts {
                accepted += 1;
                for (i, (a, b)) in sol.iter().zip(&rhs).enumerate() {
                    assert!(
                        same(*a, *b),
                        "trial {trial}: unknown {i}: native {a:e}, block {b:e}"
                    );
                }
            } else {
                declined += 1;
            }
        }
        assert!(
            accepted > 1000 && declined > 300,
            "{accepted} accepted, {declined} declined"
        );
    }
}
