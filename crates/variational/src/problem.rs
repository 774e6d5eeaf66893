//! What is solved: the grid, the admissible variations (a formulation and its
//! end conditions), and the discrete action and constraints as a list of
//! local blocks, each a function of a few node values.
//!
//! The discrete action is the midpoint rule
//! `S = Σ_k h L(t_{k+½}, (q_k + q_{k+1})/2, (q_{k+1} − q_k)/h)`, second
//! order. The constraints are blocks of rows with one multiplier each:
//!
//! * `Midpoint(k)`: `g(t_{k+½}, (q_k + q_{k+1})/2, (q_{k+1} − q_k)/h) = 0`,
//!   the nonholonomic constraints on interval `k` (C, and the general case
//!   of the paper, where they are the discretised eq. 28);
//! * `Holonomic(k)`: `f(t_k, q_k) = 0` at a node with free coordinates;
//! * `Map(k)`: `q_D,k − φ(t_k, q_I,k, D_k q_I) = 0`, the embedding map
//!   (eq. 14) at node `k`, with `D_k` the central difference (one-sided of
//!   second order at the two ends);
//! * `Cyclic(k)`: `(q_c,k+1 − q_c,k)/h − φ_c(t_{k+½}, …)` for a dependent
//!   coordinate of which the map gives only the rate (the disk's `ψ`);
//! * `EndVelocity(k)`: `D_k q_I − q̇_I(t_k) = 0`, the independent
//!   velocities fixed at an end, in place of the map there.
//!
//! A block whose values are all fixed (end data) is not a row: it is checked
//! once, and end data that violate it are refused with the residual.

use nonholo_core::Scene;
use nonholo_core::scene::Scalar;

use crate::Error;

/// Which end values of the dependent coordinates the paper's general case
/// (eq. 27–30) fixes at `t1` (their values at `t0` are always given: (28)
/// is integrated from them).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DependentEnd {
    /// Left free: only the independent coordinates are varied with fixed
    /// ends (the paper's wording); stationarity adds the natural condition
    /// at `t1`.
    Free,
    /// Fixed: Hamilton's principle with fixed ends for every coordinate.
    Fixed,
}

impl DependentEnd {
    pub fn name(self) -> &'static str {
        match self {
            DependentEnd::Free => "free",
            DependentEnd::Fixed => "fixed",
        }
    }
}

/// End conditions of the explicit-map embedding (formulation A with
/// `q_D = φ(q_I, q̇_I, t)`, eq. 14). `Θ` contains `q̈_I`, so the classical
/// statement of a second-order variational problem fixes `q_I` and `q̇_I`
/// at both ends; `rank W = s < m` makes that too many (docs/variational.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapEnds {
    /// `q_I` and the (non-cyclic) dependent coordinates `q_D` at both ends:
    /// `2n − 2c` conditions, the configuration at both ends. Well posed.
    Configuration,
    /// `q_I` at both ends, `q_D` free: the natural conditions
    /// `∂Θ/∂q̈_I = 0` at both ends. Well posed.
    Natural,
    /// `q_I` and `q̇_I` at both ends (the classical statement): `4m`
    /// conditions, more than A's solutions can meet when `s < m`.
    Full,
}

impl MapEnds {
    pub fn name(self) -> &'static str {
        match self {
            MapEnds::Configuration => "configuration",
            MapEnds::Natural => "natural",
            MapEnds::Full => "full",
        }
    }
}

/// How the embedding map is imposed at the nodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapForm {
    /// `q_D,k − φ(t_k, q_I,k, D_k q_I) = 0`: the map as the paper writes it
    /// (eq. 14). Its rows have the roots of the implicit form's (on the
    /// branch the path follows), but their derivatives grow like `1/|v|`
    /// and their second derivatives like `1/|v|²` towards the map's
    /// singular set (the sleigh's zero speed): Newton's method fails on
    /// grids with a node close to a reversal of the motion
    /// (docs/variational.md).
    Explicit,
    /// `r(t_k, q_I,k, D_k q_I, q_D,k) = 0` with the scene's implicit form of
    /// the map ([`Scene::embedding_implicit`]): the same solutions, on the
    /// branch the path follows, and rows that stay regular through the
    /// singular set.
    Implicit,
}

impl MapForm {
    pub fn name(self) -> &'static str {
        match self {
            MapForm::Explicit => "explicit",
            MapForm::Implicit => "implicit",
        }
    }
}

/// The admissible variations and constraints.
#[derive(Debug, Clone, PartialEq)]
pub enum Formulation {
    /// C: all coordinates varied with fixed ends, the nonholonomic
    /// constraints imposed with multipliers on every interval.
    Vakonomic,
    /// A in the paper's general case (eq. 27–30): the dependent coordinates
    /// (indices into `q`) follow the discretised (28) from their values at
    /// `t0`; the independent ones are varied with fixed ends.
    ///
    /// Stationarity of `S(q_I, q_D[q_I])` with `q_D[q_I]` the solution of
    /// the discrete (28) is, by the multiplier rule, stationarity of `S`
    /// under the constraints (28) with one multiplier per interval: the
    /// solver imposes them that way (sparse), and
    /// [`crate::reduced_gradient`] checks the eliminated form.
    General {
        dependent: Vec<usize>,
        end: DependentEnd,
    },
    /// A with the scene's embedding map (eq. 14), imposed in `form`.
    Map { ends: MapEnds, form: MapForm },
}

impl Formulation {
    /// `vakonomic`, `embedding-general`, `embedding-map`.
    pub fn name(&self) -> &'static str {
        match self {
            Formulation::Vakonomic => "vakonomic",
            Formulation::General { .. } => "embedding-general",
            Formulation::Map { .. } => "embedding-map",
        }
    }

    /// The end condition, by name (`fixed` for C).
    pub fn ends_name(&self) -> &'static str {
        match self {
            Formulation::Vakonomic => "fixed",
            Formulation::General { end, .. } => end.name(),
            Formulation::Map { ends, .. } => ends.name(),
        }
    }
}

/// End data: all coordinates at both ends; the velocities where the end
/// condition needs them (`MapEnds::Full`) or to check them.
#[derive(Debug, Clone, PartialEq)]
pub struct Ends {
    pub q0: Vec<f64>,
    pub q1: Vec<f64>,
    pub qd0: Option<Vec<f64>>,
    pub qd1: Option<Vec<f64>>,
}

/// One local block of the discrete problem.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    Interval,
    Midpoint,
    Holonomic,
    Map,
    Cyclic,
    EndVelocity,
}

#[derive(Debug, Clone)]
pub(crate) struct Block {
    pub kind: Kind,
    /// The node (or the interval's left node).
    pub k: usize,
    /// Its variables: (node, coordinate).
    pub vars: Vec<(usize, usize)>,
    /// Number of rows (1 for the action term, which has no multiplier).
    pub rows: usize,
    /// Index of its first multiplier in the unknown vector (constraints).
    pub offset: usize,
    /// (local index, unknown index) of its free variables.
    pub free: Vec<(usize, usize)>,
}

/// A discrete stationary-action problem on a uniform grid.
#[derive(Debug, Clone)]
pub struct Problem<'a, S: Scene> {
    pub scene: &'a S,
    pub formulation: Formulation,
    pub t0: f64,
    pub t1: f64,
    /// Number of intervals `N` (nodes `N + 1`).
    pub intervals: usize,
    pub ends: Ends,
    pub(crate) n: usize,
    pub(crate) blocks: Vec<Block>,
    /// Unknown index of each (node, coordinate), `usize::MAX` if fixed.
    pub(crate) var_of: Vec<usize>,
    /// Number of free coordinates (the first unknowns).
    pub(crate) n_vars: usize,
    /// Number of unknowns (coordinates and multipliers).
    pub(crate) n_unknowns: usize,
    independent: Vec<usize>,
    dependent: Vec<usize>,
    cyclic: Vec<usize>,
}

/// Largest number of variables of one block (the map's stencil on the
/// largest scene has fewer).
const MAX_LOCAL: usize = 64;

/// Largest number of coordinates.
const MAX_N: usize = 16;

/// Tolerance on end data that should satisfy a constraint exactly.
pub const END_TOL: f64 = 1e-9;

/// Memory limit of [`Problem::new`] (8 GiB).
pub const DEFAULT_MAX_BYTES: f64 = 8.0 * 1024.0 * 1024.0 * 1024.0;

/// Grid of the probe that estimates a large problem's memory.
pub const PROBE_INTERVALS: usize = 64;

/// Bytes per pattern entry (indices, values, sort) and per factor entry,
/// with the factor's fill for banded matrices taken as three times the
/// pattern.
const BYTES_PER_ENTRY: f64 = 16.0 + 8.0 + 8.0 + 3.0 * 16.0;

impl<'a, S: Scene> Problem<'a, S> {
    /// Sets up the blocks for `formulation` on `[t0, t1]` with `intervals`
    /// intervals, checking the end data against the constraints that bind
    /// them alone; refuses a grid whose set-up and Newton matrix would need
    /// more than [`DEFAULT_MAX_BYTES`] ([`Problem::with_limit`]).
    pub fn new(
        scene: &'a S,
        formulation: Formulation,
        t0: f64,
        t1: f64,
        intervals: usize,
        ends: Ends,
    ) -> Result<Self, Error> {
        Self::with_limit(
            scene,
            formulation,
            t0,
            t1,
            intervals,
            ends,
            DEFAULT_MAX_BYTES,
        )
    }

    /// [`Problem::new`] with a memory limit in bytes: the memory of the
    /// layout and of the Newton matrix and its factors is estimated from
    /// the same problem on a grid of [`PROBE_INTERVALS`] (they grow
    /// linearly with the grid) and a larger grid is refused before it is
    /// laid out.
    pub fn with_limit(
        scene: &'a S,
        formulation: Formulation,
        t0: f64,
        t1: f64,
        intervals: usize,
        ends: Ends,
        max_bytes: f64,
    ) -> Result<Self, Error> {
        Self::check_size(
            scene,
            formulation.clone(),
            t0,
            t1,
            intervals,
            ends.clone(),
            max_bytes,
        )?;
        Self::build(scene, formulation, t0, t1, intervals, ends)
    }

    /// Refuses a grid whose set-up and Newton matrix would need more than
    /// `max_bytes`, from a probe of [`PROBE_INTERVALS`] (nothing of the
    /// size of the grid is allocated).
    pub fn check_size(
        scene: &'a S,
        formulation: Formulation,
        t0: f64,
        t1: f64,
        intervals: usize,
        ends: Ends,
        max_bytes: f64,
    ) -> Result<(), Error> {
        if intervals > PROBE_INTERVALS {
            let probe = Self::build(
                scene,
                formulation.clone(),
                t0,
                t1,
                PROBE_INTERVALS,
                ends.clone(),
            );
            // A probe that cannot be set up says nothing about the size;
            // the full set-up reports the error itself.
            if let Ok(p) = probe {
                let scale = intervals as f64 / PROBE_INTERVALS as f64;
                let bytes = p.memory_estimate() * scale;
                if bytes > max_bytes {
                    return Err(Error::TooLarge {
                        nodes: intervals + 1,
                        unknowns: (p.unknowns() as f64 * scale) as usize,
                        bytes,
                        limit: max_bytes,
                    });
                }
            }
        }
        Ok(())
    }

    fn build(
        scene: &'a S,
        formulation: Formulation,
        t0: f64,
        t1: f64,
        intervals: usize,
        ends: Ends,
    ) -> Result<Self, Error> {
        let info = scene.info();
        let n = info.n();
        if !(t0.is_finite() && t1.is_finite() && t1 > t0) {
            return Err(Error::Input {
                field: "t-end".into(),
                reason: format!("the horizon [{t0}, {t1}] is empty or not finite"),
            });
        }
        for (name, v) in [("q0", &ends.q0), ("q1", &ends.q1)] {
            check_vector(name, v, n)?;
        }
        for (name, v) in [("qd0", &ends.qd0), ("qd1", &ends.qd1)] {
            if let Some(v) = v {
                check_vector(name, v, n)?;
            }
        }
        if n > MAX_N {
            return Err(Error::NotApplicable {
                formulation: formulation.name(),
                scene: info.name,
                reason: format!("{n} coordinates; the solver takes at most {MAX_N}"),
            });
        }
        let s = info.s();
        let (independent, dependent, cyclic, min_intervals) = match &formulation {
            Formulation::Vakonomic => {
                if s == 0 {
                    return Err(Error::NotApplicable {
                        formulation: formulation.name(),
                        scene: info.name,
                        reason: "the scene has no nonholonomic constraint".into(),
                    });
                }
                ((0..n).collect(), Vec::new(), Vec::new(), 2)
            }
            Formulation::General { dependent, .. } => {
                if s == 0 {
                    return Err(Error::NotApplicable {
                        formulation: formulation.name(),
                        scene: info.name,
                        reason: "the scene has no nonholonomic constraint".into(),
                    });
                }
                if dependent.len() != s {
                    return Err(Error::Input {
                        field: "dependent".into(),
                        reason: format!(
                            "{} dependent coordinate(s) given; the scene has {s} nonholonomic \
                             constraint(s), so (28) determines exactly {s}",
                            dependent.len()
                        ),
                    });
                }
                let mut seen = vec![false; n];
                for &d in dependent {
                    if d >= n || seen[d] {
                        return Err(Error::Input {
                            field: "dependent".into(),
                            reason: format!("coordinate index {d} out of range or repeated"),
                        });
                    }
                    seen[d] = true;
                }
                let ind = (0..n).filter(|i| !seen[*i]).collect();
                (ind, dependent.clone(), Vec::new(), 2)
            }
            Formulation::Map { ends: me, form } => {
                let Some(e) = info.embedding else {
                    return Err(Error::NotApplicable {
                        formulation: formulation.name(),
                        scene: info.name,
                        reason: "the scene provides no embedding map (eq. 14); the general \
                                 case (eq. 27–30) applies instead"
                            .into(),
                    });
                };
                if *form == MapForm::Implicit && !has_implicit_map(scene, &e) {
                    return Err(Error::NotApplicable {
                        formulation: formulation.name(),
                        scene: info.name,
                        reason: "the scene gives no implicit form of its embedding map: use the \
                                 explicit form"
                            .into(),
                    });
                }
                if *me == MapEnds::Full && (ends.qd0.is_none() || ends.qd1.is_none()) {
                    return Err(Error::Input {
                        field: "ends".into(),
                        reason: "end condition `full` fixes the independent velocities at both \
                                 ends: give them (q̇ at t0 and t1)"
                            .into(),
                    });
                }
                (
                    e.independent.to_vec(),
                    e.dependent.to_vec(),
                    e.cyclic.to_vec(),
                    4,
                )
            }
        };
        if intervals < min_intervals {
            return Err(Error::Input {
                field: "nodes".into(),
                reason: format!(
                    "{} nodes: {} needs at least {}",
                    intervals + 1,
                    formulation.name(),
                    min_intervals + 1
                ),
            });
        }
        let mut p = Problem {
            scene,
            formulation,
            t0,
            t1,
            intervals,
            ends,
            n,
            blocks: Vec::new(),
            var_of: Vec::new(),
            n_vars: 0,
            n_unknowns: 0,
            independent,
            dependent,
            cyclic,
        };
        p.layout()?;
        if let Formulation::Map {
            ends: MapEnds::Full,
            ..
        } = p.formulation
        {
            p.check_end_velocities()?;
        }
        Ok(p)
    }

    pub fn nodes(&self) -> usize {
        self.intervals + 1
    }

    /// Stored entries of the Newton matrix before duplicates are summed:
    /// the diagonal, each block's Hessian and its constraint rows twice.
    pub fn newton_entries(&self) -> usize {
        self.n_unknowns
            + self
                .blocks
                .iter()
                .map(|b| {
                    let p = b.free.len();
                    p * p
                        + if b.kind == Kind::Interval {
                            0
                        } else {
                            2 * b.rows * p
                        }
                })
                .sum::<usize>()
    }

    /// Estimated bytes of the Newton matrix and its sparse LU factors.
    pub fn newton_bytes(&self) -> f64 {
        self.newton_entries() as f64 * BYTES_PER_ENTRY + self.n_unknowns as f64 * 64.0
    }

    /// Estimated bytes of the whole solve: the layout and the Newton
    /// matrix with its factors (what [`Problem::with_limit`] bounds).
    pub fn memory_estimate(&self) -> f64 {
        self.layout_bytes() + self.newton_bytes()
    }

    /// Bytes of the layout itself (blocks, their variables, the index).
    fn layout_bytes(&self) -> f64 {
        let per_block = std::mem::size_of::<Block>() as f64;
        self.blocks
            .iter()
            .map(|b| per_block + 16.0 * (b.vars.len() + b.free.len()) as f64)
            .sum::<f64>()
            + 8.0 * self.var_of.len() as f64
    }

    pub fn h(&self) -> f64 {
        (self.t1 - self.t0) / self.intervals as f64
    }

    /// Time of node `k`.
    pub fn t(&self, k: usize) -> f64 {
        node_time(self.t0, self.t1, self.intervals, k)
    }

    /// Node times.
    pub fn times(&self) -> Vec<f64> {
        (0..self.nodes()).map(|k| self.t(k)).collect()
    }

    /// Number of unknowns (free coordinates and multipliers).
    pub fn unknowns(&self) -> usize {
        self.n_unknowns
    }

    /// Number of free coordinates.
    pub fn free_coordinates(&self) -> usize {
        self.n_vars
    }

    /// Number of multipliers.
    pub fn multipliers(&self) -> usize {
        self.n_unknowns - self.n_vars
    }

    /// Whether coordinate `i` is fixed at node `k`.
    fn fixed_at(&self, k: usize, i: usize) -> bool {
        let last = self.intervals;
        if k != 0 && k != last {
            return false;
        }
        match &self.formulation {
            Formulation::Vakonomic => true,
            Formulation::General { end, .. } => {
                k == 0 || *end == DependentEnd::Fixed || !self.dependent.contains(&i)
            }
            Formulation::Map { ends, .. } => {
                if self.cyclic.contains(&i) {
                    // A eliminates a cyclic coordinate: its value at t0 is
                    // given, at t1 it follows from the quadrature.
                    k == 0
                } else if self.dependent.contains(&i) {
                    *ends != MapEnds::Natural
                } else {
                    true
                }
            }
        }
    }

    /// Lays out unknowns and blocks; checks blocks on fixed data only.
    fn layout(&mut self) -> Result<(), Error> {
        let (n, last) = (self.n, self.intervals);
        let nodes = last + 1;
        let mut var_of = vec![usize::MAX; nodes * n];
        let mut n_vars = 0;
        for k in 0..nodes {
            for i in 0..n {
                if !self.fixed_at(k, i) {
                    var_of[k * n + i] = n_vars;
                    n_vars += 1;
                }
            }
        }
        self.var_of = var_of;
        self.n_vars = n_vars;
        let info = self.scene.info();
        let (s, kh) = (info.s(), info.k());
        let all = |k: usize| (0..n).map(move |i| (k, i));
        let mut blocks = Vec::new();
        let mut push = |kind: Kind, k: usize, vars: Vec<(usize, usize)>, rows: usize| {
            blocks.push(Block {
                kind,
                k,
                vars,
                rows,
                offset: 0,
                free: Vec::new(),
            });
        };
        for k in 0..last {
            push(Kind::Interval, k, all(k).chain(all(k + 1)).collect(), 1);
        }
        match &self.formulation {
            Formulation::Vakonomic | Formulation::General { .. } => {
                for k in 0..last {
                    push(Kind::Midpoint, k, all(k).chain(all(k + 1)).collect(), s);
                }
            }
            Formulation::Map { ends, form } => {
                let implicit = *form == MapForm::Implicit;
                let non_cyclic: Vec<usize> = self
                    .dependent
                    .iter()
                    .copied()
                    .filter(|d| !self.cyclic.contains(d))
                    .collect();
                for k in 0..=last {
                    let stencil = stencil(k, last);
                    let ind_vars = stencil
                        .iter()
                        .flat_map(|&j| self.independent.iter().map(move |&i| (j, i)));
                    // The map holds at every node: with central differences
                    // inside and one-sided ones at the ends. (Without rows
                    // at the ends, the dependent end values are tied to the
                    // path only through the action, and the solution
                    // oscillates between odd and even nodes with an
                    // amplitude of order h².)
                    let end = k == 0 || k == last;
                    if *ends == MapEnds::Full && end {
                        push(
                            Kind::EndVelocity,
                            k,
                            ind_vars.collect(),
                            self.independent.len(),
                        );
                    } else if !non_cyclic.is_empty() {
                        let vars = non_cyclic.iter().map(|&d| (k, d)).chain(ind_vars);
                        push(Kind::Map, k, vars.collect(), non_cyclic.len());
                    }
                }
                if !self.cyclic.is_empty() {
                    for k in 0..last {
                        let vars = self
                            .cyclic
                            .iter()
                            .map(|&c| (k, c))
                            .chain(self.cyclic.iter().map(|&c| (k + 1, c)))
                            .chain(self.independent.iter().map(|&i| (k, i)))
                            .chain(self.independent.iter().map(|&i| (k + 1, i)));
                        // The implicit form takes the rate at the path's
                        // other dependent values (the disk's heading).
                        let others = non_cyclic
                            .iter()
                            .map(|&d| (k, d))
                            .chain(non_cyclic.iter().map(|&d| (k + 1, d)))
                            .filter(|_| implicit);
                        push(
                            Kind::Cyclic,
                            k,
                            vars.chain(others).collect(),
                            self.cyclic.len(),
                        );
                    }
                }
            }
        }
        if kh > 0 {
            for k in 0..=last {
                push(Kind::Holonomic, k, all(k).collect(), kh);
            }
        }
        // Free variables; blocks on fixed data are checks, not rows.
        let mut offset = n_vars;
        let mut kept = Vec::with_capacity(blocks.len());
        for mut b in blocks {
            if b.vars.len() > MAX_LOCAL {
                return Err(Error::Input {
                    field: "scene".into(),
                    reason: format!(
                        "a block has {} variables (at most {MAX_LOCAL})",
                        b.vars.len()
                    ),
                });
            }
            b.free = b
                .vars
                .iter()
                .enumerate()
                .filter_map(|(l, &(k, i))| {
                    let v = self.var_of[k * n + i];
                    (v != usize::MAX).then_some((l, v))
                })
                .collect();
            if b.free.is_empty() {
                if b.kind != Kind::Interval {
                    self.check_fixed_block(&b)?;
                }
                continue;
            }
            if b.kind != Kind::Interval {
                b.offset = offset;
                offset += b.rows;
            }
            kept.push(b);
        }
        self.blocks = kept;
        self.n_unknowns = offset;
        Ok(())
    }

    /// A constraint block on end data alone must hold.
    fn check_fixed_block(&self, b: &Block) -> Result<(), Error> {
        let path = self.start_line();
        let mut x = vec![0.0; b.vars.len()];
        self.gather(b, &path, &mut x);
        let mut out = vec![0.0; b.rows];
        self.eval(b, &path, &x, &mut out);
        let worst = out.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        if worst.is_nan() || worst > END_TOL {
            return Err(Error::InconsistentEnds {
                t: self.t(b.k),
                what: self.block_name(b),
                residual: worst,
            });
        }
        Ok(())
    }

    /// With the velocities fixed, the dependent coordinates at the ends are
    /// the map's values there: given ones must agree.
    fn check_end_velocities(&self) -> Result<(), Error> {
        let m = self.independent.len();
        let s = self.dependent.len();
        for (k, q, qd) in [
            (0, &self.ends.q0, self.ends.qd0.as_ref()),
            (self.intervals, &self.ends.q1, self.ends.qd1.as_ref()),
        ] {
            let qd = qd.expect("checked in Problem::new");
            let qi: Vec<f64> = self.independent.iter().map(|&i| q[i]).collect();
            let vi: Vec<f64> = self.independent.iter().map(|&i| qd[i]).collect();
            let near: Vec<f64> = self.dependent.iter().map(|&d| q[d]).collect();
            let mut c = vec![0.0; s];
            self.scene
                .embedding(self.t(k), &qi[..m], &vi[..m], &near, &mut c);
            for (j, &d) in self.dependent.iter().enumerate() {
                let given = if self.cyclic.contains(&d) {
                    qd[d]
                } else {
                    q[d]
                };
                let r = (given - c[j]).abs();
                if r.is_nan() || r > END_TOL * (1.0 + c[j].abs()) {
                    return Err(Error::InconsistentEnds {
                        t: self.t(k),
                        what: format!(
                            "the embedding map for {} (given {given}, map {})",
                            self.coordinate(d),
                            c[j]
                        ),
                        residual: r,
                    });
                }
            }
        }
        Ok(())
    }

    /// The straight line between the end values (the start of the
    /// dependent coordinates at `t0` where their end at `t1` is free).
    pub fn start_line(&self) -> Vec<f64> {
        let n = self.n;
        let mut path = vec![0.0; self.nodes() * n];
        for k in 0..self.nodes() {
            let s = k as f64 / self.intervals as f64;
            for i in 0..n {
                let free_end = !self.fixed_at(self.intervals, i);
                let (a, b) = (self.ends.q0[i], self.ends.q1[i]);
                path[k * n + i] = if free_end && self.dependent.contains(&i) {
                    // Integrate (28) roughly: the end value is unknown.
                    a
                } else {
                    a + (b - a) * s
                };
            }
        }
        if let Formulation::Map {
            ends: MapEnds::Natural,
            ..
        } = self.formulation
        {
            // The dependent end values are unknowns: start them (and the
            // rest) on the map.
            self.fill_dependent(&mut path);
        }
        self.impose_ends(&mut path);
        path
    }

    /// Sets the dependent coordinates of `path` from its independent ones
    /// by the map (non-cyclic ones at the nodes, cyclic ones by summing
    /// their rates), so that a starting path satisfies the map.
    pub fn fill_dependent(&self, path: &mut [f64]) {
        let (n, last, h) = (self.n, self.intervals, self.h());
        let (m, s) = (self.independent.len(), self.dependent.len());
        let mut c = vec![0.0; s];
        let mut qi = vec![0.0; m];
        let mut vi = vec![0.0; m];
        for k in 0..=last {
            let st = stencil(k, last);
            let (w, centre) = weights(k, last, h);
            for (j, &i) in self.independent.iter().enumerate() {
                qi[j] = path[st[centre] * n + i];
                vi[j] = (0..3).map(|r| w[r] * path[st[r] * n + i]).sum();
            }
            let near: Vec<f64> = self.dependent.iter().map(|&d| path[k * n + d]).collect();
            self.scene.embedding(self.t(k), &qi, &vi, &near, &mut c);
            for (j, &d) in self.dependent.iter().enumerate() {
                if self.cyclic.contains(&d) {
                    if k < last {
                        path[(k + 1) * n + d] = path[k * n + d] + h * c[j];
                    }
                } else {
                    path[k * n + d] = c[j];
                }
            }
        }
    }

    /// Puts the end data into the fixed entries of `path`.
    pub fn impose_ends(&self, path: &mut [f64]) {
        let n = self.n;
        for i in 0..n {
            path[i] = self.ends.q0[i];
            if self.fixed_at(self.intervals, i) {
                path[self.intervals * n + i] = self.ends.q1[i];
            }
        }
    }

    /// What a block is, for messages.
    pub(crate) fn block_name(&self, b: &Block) -> String {
        match b.kind {
            Kind::Interval => format!("action on interval {}", b.k),
            Kind::Midpoint => format!("constraint (28) on interval {}", b.k),
            Kind::Holonomic => format!("holonomic constraint at node {}", b.k),
            Kind::Map => format!("embedding map at node {}", b.k),
            Kind::Cyclic => format!("rate of the cyclic coordinate on interval {}", b.k),
            Kind::EndVelocity => format!("end velocity at node {}", b.k),
        }
    }

    /// Name of coordinate `i`.
    pub fn coordinate(&self, i: usize) -> &'static str {
        self.scene.info().coordinates[i].name
    }

    /// What unknown `u` is: `(node, time, name)`.
    pub fn describe_unknown(&self, u: usize) -> (usize, f64, String) {
        if u < self.n_vars {
            let pos = self.var_of.iter().position(|&v| v == u).unwrap_or(0);
            let (k, i) = (pos / self.n, pos % self.n);
            return (k, self.t(k), self.coordinate(i).to_string());
        }
        for b in &self.blocks {
            if b.kind != Kind::Interval && u >= b.offset && u < b.offset + b.rows {
                return (
                    b.k,
                    self.t(b.k),
                    format!("multiplier {} of the {}", u - b.offset, self.block_name(b)),
                );
            }
        }
        (0, self.t0, format!("unknown {u}"))
    }

    /// The values of a block's variables.
    pub(crate) fn gather<T: Scalar>(&self, b: &Block, path: &[f64], x: &mut [T]) {
        for (l, &(k, i)) in b.vars.iter().enumerate() {
            x[l] = T::from(path[k * self.n + i]);
        }
    }

    /// The block's value (its rows; the action term for `Interval`) at the
    /// local values `x`; `path` gives the branch of a many-valued map.
    pub(crate) fn eval<T: Scalar>(&self, b: &Block, path: &[f64], x: &[T], out: &mut [T]) {
        let n = self.n;
        let h = self.h();
        let zero = T::from(0.0);
        let (mut a, mut bb, mut c) = ([zero; MAX_N], [zero; MAX_N], [zero; MAX_N]);
        match b.kind {
            Kind::Interval | Kind::Midpoint => {
                let tm = T::from(0.5 * (self.t(b.k) + self.t(b.k + 1)));
                for i in 0..n {
                    a[i] = (x[i] + x[n + i]) * 0.5;
                    bb[i] = (x[n + i] - x[i]) / h;
                }
                if b.kind == Kind::Interval {
                    out[0] = self.scene.lagrangian(tm, &a[..n], &bb[..n]) * h;
                } else {
                    self.scene
                        .nonholonomic(tm, &a[..n], &bb[..n], &mut out[..b.rows]);
                }
            }
            Kind::Holonomic => {
                self.scene
                    .holonomic(T::from(self.t(b.k)), &x[..n], &mut out[..b.rows]);
            }
            Kind::Map | Kind::EndVelocity => {
                let m = self.independent.len();
                let d = if b.kind == Kind::Map { b.rows } else { 0 };
                let (w, centre) = weights(b.k, self.intervals, h);
                for j in 0..m {
                    a[j] = x[d + centre * m + j];
                    bb[j] = T::from(0.0);
                    for (r, wr) in w.iter().enumerate() {
                        bb[j] += x[d + r * m + j] * *wr;
                    }
                }
                if b.kind == Kind::EndVelocity {
                    let v = if b.k == 0 {
                        self.ends.qd0.as_ref()
                    } else {
                        self.ends.qd1.as_ref()
                    }
                    .expect("checked in Problem::new");
                    for j in 0..m {
                        out[j] = bb[j] - v[self.independent[j]];
                    }
                    return;
                }
                let t = T::from(self.t(b.k));
                let s = self.dependent.len();
                if self.implicit() {
                    // The non-cyclic dependent values come first in `x`.
                    let mut q_dep = [zero; MAX_N];
                    let mut r = 0;
                    for (jd, dep) in self.dependent.iter().enumerate() {
                        if !self.cyclic.contains(dep) {
                            q_dep[jd] = x[r];
                            r += 1;
                        }
                    }
                    self.scene
                        .embedding_implicit(t, &a[..m], &bb[..m], &q_dep[..s], &mut c[..s]);
                    let mut r = 0;
                    for (jd, dep) in self.dependent.iter().enumerate() {
                        if !self.cyclic.contains(dep) {
                            out[r] = c[jd];
                            r += 1;
                        }
                    }
                    return;
                }
                let near = self.near(path, b.k, b.k);
                self.scene
                    .embedding(t, &a[..m], &bb[..m], &near[..s], &mut c[..s]);
                let mut r = 0;
                for (jd, dep) in self.dependent.iter().enumerate() {
                    if !self.cyclic.contains(dep) {
                        out[r] = x[r] - c[jd];
                        r += 1;
                    }
                }
            }
            Kind::Cyclic => {
                let m = self.independent.len();
                let nc = self.cyclic.len();
                let off = 2 * nc;
                for j in 0..m {
                    a[j] = (x[off + j] + x[off + m + j]) * 0.5;
                    bb[j] = (x[off + m + j] - x[off + j]) / h;
                }
                let s = self.dependent.len();
                let tm = T::from(0.5 * (self.t(b.k) + self.t(b.k + 1)));
                if self.implicit() {
                    // The other dependent values at the midpoint follow
                    // the independent ones in `x`.
                    let ndc = s - nc;
                    let base = off + 2 * m;
                    let mut q_dep = [zero; MAX_N];
                    let mut r = 0;
                    for (jd, dep) in self.dependent.iter().enumerate() {
                        if !self.cyclic.contains(dep) {
                            q_dep[jd] = (x[base + r] + x[base + ndc + r]) * 0.5;
                            r += 1;
                        }
                    }
                    self.scene
                        .embedding_implicit(tm, &a[..m], &bb[..m], &q_dep[..s], &mut c[..s]);
                } else {
                    let near = self.near(path, b.k, b.k + 1);
                    self.scene
                        .embedding(tm, &a[..m], &bb[..m], &near[..s], &mut c[..s]);
                }
                let mut r = 0;
                for (jd, dep) in self.dependent.iter().enumerate() {
                    if self.cyclic.contains(dep) {
                        out[r] = (x[nc + r] - x[r]) / h - c[jd];
                        r += 1;
                    }
                }
            }
        }
    }

    /// The multipliers of the nonholonomic constraints at the nodes (node
    /// after node, `s` each) for the formulations that impose them on every
    /// interval (C and the general case): `λ(t_{k+½}) = μ_k/h`, with `μ_k`
    /// the multipliers of the discrete constraints on interval `k` (so `λ`
    /// is C's, of the action `L + λᵀg`), averaged at interior nodes and
    /// extrapolated linearly at the two ends (second order). `None` for the
    /// map, whose multipliers are not those of `g`.
    pub fn node_multipliers(&self, multipliers: &[f64]) -> Option<Vec<f64>> {
        let s = self.scene.info().s();
        let last = self.intervals;
        let nv = self.n_vars;
        let mut mid = vec![0.0; last * s];
        let mut found = 0;
        for b in self.blocks.iter().filter(|b| b.kind == Kind::Midpoint) {
            for r in 0..s {
                mid[b.k * s + r] = multipliers.get(b.offset - nv + r)? / self.h();
            }
            found += 1;
        }
        if found != last || last < 2 {
            return None;
        }
        let mut out = vec![0.0; (last + 1) * s];
        for r in 0..s {
            let m = |k: usize| mid[k * s + r];
            out[r] = 1.5 * m(0) - 0.5 * m(1);
            out[last * s + r] = 1.5 * m(last - 1) - 0.5 * m(last - 2);
            for k in 1..last {
                out[k * s + r] = 0.5 * (m(k - 1) + m(k));
            }
        }
        Some(out)
    }

    /// Whether the map is imposed in implicit form.
    fn implicit(&self) -> bool {
        matches!(
            self.formulation,
            Formulation::Map {
                form: MapForm::Implicit,
                ..
            }
        )
    }

    /// The branch references of the map: the current dependent values,
    /// averaged over nodes `k0` and `k1`.
    fn near(&self, path: &[f64], k0: usize, k1: usize) -> [f64; MAX_N] {
        let mut near = [0.0; MAX_N];
        for (j, &d) in self.dependent.iter().enumerate() {
            near[j] = 0.5 * (path[k0 * self.n + d] + path[k1 * self.n + d]);
        }
        near
    }

    /// Independent coordinates (A) or all but the dependent ones.
    pub fn independent(&self) -> &[usize] {
        &self.independent
    }

    /// Dependent coordinates (A).
    pub fn dependent(&self) -> &[usize] {
        &self.dependent
    }

    /// Cyclic dependent coordinates (A with a map that gives their rate).
    pub fn cyclic(&self) -> &[usize] {
        &self.cyclic
    }
}

/// Whether `scene` gives the implicit form of its map (asked once, at zero).
fn has_implicit_map<S: Scene>(scene: &S, e: &nonholo_core::scene::EmbeddingInfo) -> bool {
    let (m, s) = (e.independent.len(), e.dependent.len());
    let (z, mut out) = ([0.0f64; MAX_N], [0.0f64; MAX_N]);
    scene.embedding_implicit(0.0, &z[..m], &z[..m], &z[..s], &mut out[..s])
}

/// Time of node `k` of a uniform grid of `intervals` on `[t0, t1]` (`t1`
/// exactly at the last node).
pub fn node_time(t0: f64, t1: f64, intervals: usize, k: usize) -> f64 {
    if k == intervals {
        t1
    } else {
        t0 + (t1 - t0) * (k as f64 / intervals as f64)
    }
}

/// Velocities of a node-major path (`n` per node) on a uniform grid of
/// spacing `h`: the differences `D_k` of the map's rows (central, one-sided
/// of second order at the ends).
pub fn node_velocities(q: &[f64], n: usize, h: f64) -> Vec<f64> {
    let last = q.len() / n - 1;
    let mut v = vec![0.0; q.len()];
    for k in 0..=last {
        let st = stencil(k, last);
        let (w, _) = weights(k, last, h);
        for i in 0..n {
            v[k * n + i] = (0..3).map(|r| w[r] * q[st[r] * n + i]).sum();
        }
    }
    v
}

/// Nodes of the difference stencil at node `k` of `0..=last`.
fn stencil(k: usize, last: usize) -> [usize; 3] {
    if k == 0 {
        [0, 1, 2]
    } else if k == last {
        [last - 2, last - 1, last]
    } else {
        [k - 1, k, k + 1]
    }
}

/// Weights of the second-order difference `D_k` on [`stencil`] and the
/// stencil position of node `k`.
fn weights(k: usize, last: usize, h: f64) -> ([f64; 3], usize) {
    let c = 0.5 / h;
    if k == 0 {
        ([-3.0 * c, 4.0 * c, -c], 0)
    } else if k == last {
        ([c, -4.0 * c, 3.0 * c], 2)
    } else {
        ([-c, 0.0, c], 1)
    }
}

fn check_vector(name: &str, v: &[f64], n: usize) -> Result<(), Error> {
    if v.len() != n {
        return Err(Error::Input {
            field: name.into(),
            reason: format!("{} values for {n} coordinates", v.len()),
        });
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(Error::Input {
            field: name.into(),
            reason: format!("component {i} is not finite ({})", v[i]),
        });
    }
    Ok(())
}
