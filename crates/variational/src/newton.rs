//! Newton's method on the stationarity conditions, with the KKT matrix
//! assembled sparse from the blocks' local derivatives and factored by
//! faer's sparse LU (symbolic analysis once, numeric factorisation per
//! iteration).
//!
//! Unknowns `z = (free coordinates, multipliers μ)`; conditions
//! `F = (∇S + Σ μ_b ∇c_b, c)`; Newton matrix
//! `K = [∇²S + Σ μ_b ∇²c_b, ∇cᵀ; ∇c, 0]`. Each block's gradient, Jacobian
//! and Hessian come from hyper-dual passes over its free local variables
//! (`p(p + 1)/2` passes for `p` of them; `p` without the Hessian).

use std::time::Instant;

use faer::Conj;
use faer::Mat;
use faer::linalg::solvers::SolveCore;
use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::sparse::{Argsort, Pair, SparseColMat, SymbolicSparseColMat};
use nonholo_core::Scene;
use num_dual::HyperDual;

use crate::Error;
use crate::problem::{Kind, Problem};

/// Newton's options.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// Largest number of Newton iterations.
    pub max_iter: usize,
    /// Converged when the scaled residual (stationarity rows over `h`, in
    /// force units; constraint rows as they are) is at most this.
    pub tol: f64,
    /// Refuse a grid whose matrices would need more memory than this
    /// (bytes, estimated before anything is allocated).
    pub max_bytes: f64,
    /// Stop Newton's method once this much wall time (seconds) has gone
    /// (checked before every factorisation); `None`: no limit.
    pub max_wall_time: Option<f64>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            max_iter: 40,
            tol: 1e-10,
            max_bytes: crate::problem::DEFAULT_MAX_BYTES,
            max_wall_time: None,
        }
    }
}

/// What a solve did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Report {
    pub nodes: usize,
    pub unknowns: usize,
    /// Stored entries of the Newton matrix (after summing duplicates).
    pub nonzeros: usize,
    pub iterations: usize,
    /// Scaled residual before each iteration and at the end.
    pub residual_history: Vec<f64>,
    /// Largest coordinate change of each Newton step.
    pub step_history: Vec<f64>,
    /// Steps shortened by the line search.
    pub damped_steps: usize,
    pub assembly_seconds: f64,
    pub factor_seconds: f64,
    pub wall_seconds: f64,
}

/// A stationary path.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// Node times.
    pub t: Vec<f64>,
    /// Coordinates at the nodes, node after node (`n` each).
    pub q: Vec<f64>,
    pub n: usize,
    /// The multipliers, in the order of the constraint blocks.
    pub multipliers: Vec<f64>,
    pub report: Report,
}

impl Solution {
    /// Coordinate `i` at node `k`.
    pub fn at(&self, k: usize, i: usize) -> f64 {
        self.q[k * self.n + i]
    }

    /// Velocities at the nodes: central differences, one-sided of second
    /// order at the ends.
    pub fn velocities(&self) -> Vec<f64> {
        let nodes = self.t.len();
        let h = (self.t[nodes - 1] - self.t[0]) / (nodes - 1) as f64;
        crate::problem::node_velocities(&self.q, self.n, h)
    }
}

/// Assembly state: the sparsity pattern (symbolic, once) and buffers.
pub struct Solver<'p, 'a, S: Scene> {
    pub problem: &'p Problem<'a, S>,
    symbolic: SymbolicSparseColMat<usize>,
    argsort: Argsort<usize>,
    lu_symbolic: Option<SymbolicLu<usize>>,
    values: Vec<f64>,
    residual: Vec<f64>,
    /// The largest single term of a stationarity row at the last assembly.
    terms: f64,
    /// The largest `|∂c/∂x| |x|` of a constraint row at the last assembly.
    constraint_terms: f64,
}

/// Round-off of the stationarity rows counted as converged: this many
/// times its estimate ([`Solver::solve`]).
const FLOOR_MARGIN: f64 = 10.0;

impl<'p, 'a, S: Scene> Solver<'p, 'a, S> {
    /// Builds the sparsity pattern; refuses grids that would not fit in
    /// `options.max_bytes`.
    pub fn new(problem: &'p Problem<'a, S>, options: &Options) -> Result<Self, Error> {
        let u = problem.unknowns();
        let entries = problem.newton_entries();
        let bytes = problem.newton_bytes();
        if bytes > options.max_bytes {
            return Err(Error::TooLarge {
                nodes: problem.nodes(),
                unknowns: u,
                bytes,
                limit: options.max_bytes,
            });
        }
        let mut pairs = Vec::with_capacity(entries);
        let path = problem.start_line();
        let mu = vec![0.0; u - problem.free_coordinates()];
        let mut residual = vec![0.0; u];
        assemble(
            problem,
            &path,
            &mu,
            true,
            &mut residual,
            &mut |row, col, _| {
                pairs.push(Pair { row, col });
            },
        );
        let (symbolic, argsort) = SymbolicSparseColMat::try_new_from_indices(u, u, &pairs)
            .map_err(|e| Error::Input {
                field: "nodes".into(),
                reason: format!("the sparsity pattern could not be built: {e:?}"),
            })?;
        Ok(Solver {
            problem,
            symbolic,
            argsort,
            lu_symbolic: None,
            values: Vec::with_capacity(entries),
            residual,
            terms: 0.0,
            constraint_terms: 0.0,
        })
    }

    /// Stored entries of the Newton matrix.
    pub fn nonzeros(&self) -> usize {
        self.symbolic.compute_nnz()
    }

    /// Assembles `F` (into the solver's residual) and, with `hessian`, the
    /// Newton matrix; without it the matrix `[I, ∇cᵀ; ∇c, 0]` of the
    /// projection onto the constraints' tangent space.
    fn assemble_at(&mut self, path: &[f64], mu: &[f64], hessian: bool) {
        self.values.clear();
        let values = &mut self.values;
        (self.terms, self.constraint_terms) = assemble(
            self.problem,
            path,
            mu,
            hessian,
            &mut self.residual,
            &mut |_, _, v| values.push(v),
        );
    }

    /// Factors the matrix of the last assembly and solves with `rhs`.
    fn factor_solve(&mut self, rhs: &mut [f64]) -> Result<(), Error> {
        let mat =
            SparseColMat::new_from_argsort(self.symbolic.clone(), &self.argsort, &self.values)
                .map_err(|e| Error::Input {
                    field: "nodes".into(),
                    reason: format!("the Newton matrix could not be stored: {e:?}"),
                })?;
        if self.lu_symbolic.is_none() {
            self.lu_symbolic =
                Some(SymbolicLu::try_new(mat.symbolic()).map_err(|e| self.singular_lu(e))?);
        }
        let symbolic = self.lu_symbolic.clone().expect("set above");
        let lu =
            Lu::try_new_with_symbolic(symbolic, mat.as_ref()).map_err(|e| self.singular_lu(e))?;
        let mut b = Mat::<f64>::zeros(rhs.len(), 1);
        for (i, v) in rhs.iter().enumerate() {
            b[(i, 0)] = *v;
        }
        lu.solve_in_place_with_conj(Conj::No, b.as_mut());
        for (i, v) in rhs.iter_mut().enumerate() {
            *v = b[(i, 0)];
        }
        if let Some(bad) = rhs.iter().position(|v| !v.is_finite()) {
            let (node, t, what) = self.problem.describe_unknown(bad);
            return Err(Error::Singular { node, t, what });
        }
        Ok(())
    }

    fn singular_lu<E: std::fmt::Debug>(&self, e: E) -> Error {
        let text = format!("{e:?}");
        let index = text
            .split(|c: char| !c.is_ascii_digit())
            .find_map(|w| w.parse::<usize>().ok())
            .unwrap_or(0);
        let (node, t, what) = self.problem.describe_unknown(index);
        Error::Singular { node, t, what }
    }

    /// The round-off floors of the scaled residual's two parts (with a
    /// margin of [`FLOOR_MARGIN`]). The stationarity rows are differences of
    /// momenta, each with the round-off of its velocity
    /// `(q_{k+1} − q_k)/h`, about `ε M |q|/h`, and over `h` — `ε M |q|/h²`,
    /// above `tol` on fine grids (2e-10 N at h = 1.25 ms for unit mass and
    /// positions). A constraint row carries its velocities' round-off,
    /// `ε |∂g/∂q̇| |q|/h`.
    fn floors(&self) -> (f64, f64) {
        (
            FLOOR_MARGIN * f64::EPSILON * self.terms / self.problem.h(),
            FLOOR_MARGIN * f64::EPSILON * self.constraint_terms,
        )
    }

    /// Scaled residual of the last assembly: stationarity rows over `h`
    /// (force units), constraint rows as they are.
    fn scaled_norm(&self) -> f64 {
        let (s, c) = self.norms();
        if s.is_nan() || c.is_nan() {
            f64::NAN
        } else {
            s.max(c)
        }
    }

    /// The scaled residual's two parts: the stationarity rows over `h`,
    /// and the constraint rows.
    fn norms(&self) -> (f64, f64) {
        let (h, nv) = (self.problem.h(), self.problem.free_coordinates());
        let max = |v: &[f64]| {
            v.iter().fold(0.0f64, |m, x| {
                if x.is_nan() || m.is_nan() {
                    f64::NAN
                } else {
                    m.max(x.abs())
                }
            })
        };
        (max(&self.residual[..nv]) / h, max(&self.residual[nv..]))
    }

    /// Newton's method from the path `start` (nodes × n; end data are
    /// imposed on it).
    pub fn solve(&mut self, start: &[f64], options: &Options) -> Result<Solution, Error> {
        self.newton(start, options, None)
    }

    /// Exactly `steps` Newton iterations from `start`, whatever the
    /// residual (for timing a step: each is one assembly with the Hessian,
    /// one numeric factorisation and solve, and the line search's
    /// residuals). Only a non-finite residual or a singular matrix stops
    /// them early.
    pub fn timed_steps(
        &mut self,
        start: &[f64],
        steps: usize,
        options: &Options,
    ) -> Result<Report, Error> {
        Ok(self.newton(start, options, Some(steps))?.report)
    }

    fn newton(
        &mut self,
        start: &[f64],
        options: &Options,
        fixed_steps: Option<usize>,
    ) -> Result<Solution, Error> {
        let wall = Instant::now();
        let p = self.problem;
        let (n, nv, u) = (p.n, p.free_coordinates(), p.unknowns());
        if start.len() != p.nodes() * n || start.iter().any(|v| !v.is_finite()) {
            return Err(Error::Input {
                field: "start".into(),
                reason: format!(
                    "a starting path needs {} finite values ({} nodes × {n})",
                    p.nodes() * n,
                    p.nodes()
                ),
            });
        }
        let mut path = start.to_vec();
        p.impose_ends(&mut path);
        let mut mu = vec![0.0; u - nv];
        let mut report = Report {
            nodes: p.nodes(),
            unknowns: u,
            nonzeros: self.nonzeros(),
            ..Report::default()
        };
        let mut dz = vec![0.0; u];
        let (mut trial, mut trial_mu) = (path.clone(), mu.clone());
        loop {
            let t = Instant::now();
            self.assemble_at(&path, &mu, true);
            report.assembly_seconds += t.elapsed().as_secs_f64();
            let norm = self.scaled_norm();
            report.residual_history.push(norm);
            if !norm.is_finite() {
                let bad = self
                    .residual
                    .iter()
                    .position(|v| !v.is_finite())
                    .unwrap_or(0);
                let (node, t, what) = p.describe_unknown(bad);
                return Err(Error::NotFinite { node, t, what });
            }
            if let Some(k) = fixed_steps {
                if report.iterations >= k {
                    break;
                }
            } else {
                // Converged: at the tolerance; or, where the round-off floor
                // is above it (fine grids), near the floor (the
                // stationarity rows at theirs, the constraint rows at
                // theirs) once an iteration no longer halves the residual.
                if norm <= options.tol {
                    break;
                }
                let (stationarity, constraints) = self.norms();
                let (floor_s, floor_c) = self.floors();
                if let [.., before, _] = report.residual_history[..]
                    && stationarity <= floor_s
                    && constraints <= options.tol.max(floor_c)
                    && norm > 0.5 * before
                {
                    break;
                }
                if report.iterations >= options.max_iter {
                    return Err(self.not_converged(&report));
                }
            }
            if let Some(limit) = options.max_wall_time
                && wall.elapsed().as_secs_f64() > limit
            {
                return Err(Error::TimeBudget {
                    seconds: limit,
                    iterations: report.iterations,
                    residual: norm,
                });
            }
            report.iterations += 1;
            for (d, r) in dz.iter_mut().zip(&self.residual) {
                *d = -r;
            }
            let t = Instant::now();
            self.factor_solve(&mut dz)?;
            report.factor_seconds += t.elapsed().as_secs_f64();
            // Backtracking on the scaled residual.
            let mut alpha = 1.0;
            let mut halvings = 0;
            let step = loop {
                let mut step = 0.0f64;
                trial.copy_from_slice(&path);
                for (idx, &v) in p.var_of.iter().enumerate() {
                    if v != usize::MAX {
                        trial[idx] = path[idx] + alpha * dz[v];
                        step = step.max((alpha * dz[v]).abs());
                    }
                }
                for (j, m) in trial_mu.iter_mut().enumerate() {
                    *m = mu[j] + alpha * dz[nv + j];
                }
                let t = Instant::now();
                assemble(
                    p,
                    &trial,
                    &trial_mu,
                    false,
                    &mut self.residual,
                    &mut |_, _, _| {},
                );
                report.assembly_seconds += t.elapsed().as_secs_f64();
                let trial_norm = self.scaled_norm();
                if trial_norm <= (1.0 - 1e-4 * alpha) * norm || halvings >= 10 {
                    break step;
                }
                alpha *= 0.5;
                halvings += 1;
            };
            if halvings > 0 {
                report.damped_steps += 1;
            }
            report.step_history.push(step);
            std::mem::swap(&mut path, &mut trial);
            std::mem::swap(&mut mu, &mut trial_mu);
        }
        report.wall_seconds = wall.elapsed().as_secs_f64();
        Ok(Solution {
            t: p.times(),
            q: path,
            n,
            multipliers: mu,
            report,
        })
    }

    fn not_converged(&self, report: &Report) -> Error {
        let (h, nv) = (self.problem.h(), self.problem.free_coordinates());
        let mut order: Vec<(usize, f64)> = self
            .residual
            .iter()
            .enumerate()
            .map(|(u, v)| (u, if u < nv { v.abs() / h } else { v.abs() }))
            .collect();
        order.sort_by(|a, b| b.1.total_cmp(&a.1));
        let worst = order
            .iter()
            .take(3)
            .map(|&(u, r)| {
                let (node, t, what) = self.problem.describe_unknown(u);
                (node, t, what, r)
            })
            .collect();
        Error::NotConverged {
            iterations: report.iterations,
            history: report.residual_history.clone(),
            worst,
        }
    }

    /// The scaled residual of the stationarity conditions and constraints
    /// (what Newton's method drives to zero) at a path and multipliers
    /// (`μ`, in the order of the constraint blocks).
    pub fn residual_at(&mut self, path: &[f64], mu: &[f64]) -> Result<f64, Error> {
        let p = self.problem;
        let need = (p.nodes() * p.n, p.multipliers());
        if (path.len(), mu.len()) != need {
            return Err(Error::Input {
                field: "path".into(),
                reason: format!(
                    "{} path values and {} multipliers; the problem has {} and {}",
                    path.len(),
                    mu.len(),
                    need.0,
                    need.1
                ),
            });
        }
        self.assemble_at(path, mu, false);
        Ok(self.scaled_norm())
    }

    /// The stationarity residual of a given path: the component of `∇S`
    /// orthogonal to the constraints' normals (the least-squares
    /// multipliers removed), per free coordinate, over `h` (force units).
    /// Zero up to the discretisation error on a stationary path.
    pub fn stationarity(&mut self, path: &[f64]) -> Result<Stationarity, Error> {
        let p = self.problem;
        if path.len() != p.nodes() * p.n || path.iter().any(|v| !v.is_finite()) {
            return Err(Error::Input {
                field: "path".into(),
                reason: format!(
                    "a path needs {} finite values ({} nodes × {})",
                    p.nodes() * p.n,
                    p.nodes(),
                    p.n
                ),
            });
        }
        let (nv, u) = (p.free_coordinates(), p.unknowns());
        let mu = vec![0.0; u - nv];
        self.assemble_at(path, &mu, false);
        let constraint_max = self.residual[nv..]
            .iter()
            .fold(0.0f64, |a, v| a.max(v.abs()));
        let mut rhs = self.residual.clone();
        for r in &mut rhs[nv..] {
            *r = 0.0;
        }
        self.factor_solve(&mut rhs)?;
        let h = p.h();
        let (mut worst, mut at, mut sum2) = (0.0f64, 0, 0.0);
        for (v, r) in rhs[..nv].iter().enumerate() {
            let f = r.abs() / h;
            sum2 += f * f;
            if f > worst {
                worst = f;
                at = v;
            }
        }
        let (node, t, what) = p.describe_unknown(at);
        Ok(Stationarity {
            max: worst,
            rms: (sum2 / nv.max(1) as f64).sqrt(),
            node,
            t,
            coordinate: what,
            constraint_max,
        })
    }
}

/// The stationarity residual of a path ([`Solver::stationarity`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Stationarity {
    /// Largest component (force units: N, or N m for an angle).
    pub max: f64,
    /// Root mean square over the free coordinates.
    pub rms: f64,
    /// Where the largest is.
    pub node: usize,
    pub t: f64,
    pub coordinate: String,
    /// Largest constraint value of the path (the discrete constraints).
    pub constraint_max: f64,
}

/// Walks the blocks: adds their contributions to `residual` (zeroed here)
/// and hands each matrix entry to `sink` in a fixed order (diagonal first).
/// Returns the sizes of the round-off of a stationarity row and of a
/// constraint row over `ε`: the largest single term of a stationarity row
/// (about the largest momentum) or, with the Hessian, the largest
/// `|∂²S/∂x²| |x|` of the action if larger (the velocities' round-off
/// `ε|q|/h` carried into the momenta); and the largest `|∂c/∂x| |x|` of a
/// constraint row.
fn assemble<S: Scene>(
    p: &Problem<'_, S>,
    path: &[f64],
    mu: &[f64],
    hessian: bool,
    residual: &mut [f64],
    sink: &mut dyn FnMut(usize, usize, f64),
) -> (f64, f64) {
    let nv = p.free_coordinates();
    let (mut terms, mut cterms) = (0.0f64, 0.0f64);
    residual.iter_mut().for_each(|r| *r = 0.0);
    for u in 0..p.unknowns() {
        sink(u, u, if !hessian && u < nv { 1.0 } else { 0.0 });
    }
    let mut xf = [0.0f64; 64];
    let mut xs = [HyperDual::<f64>::from(0.0); 64];
    let mut out = [HyperDual::<f64>::from(0.0); 64];
    let mut value = [0.0f64; 64];
    let mut jac = vec![0.0f64; 64 * 64];
    let mut hess = vec![0.0f64; 64 * 64];
    for b in &p.blocks {
        let nl = b.vars.len();
        p.gather::<f64>(b, path, &mut xf[..nl]);
        let np = b.free.len();
        let is_action = b.kind == Kind::Interval;
        let weights: &[f64] = if is_action {
            &[1.0]
        } else {
            &mu[b.offset - nv..b.offset - nv + b.rows]
        };
        for ia in 0..np {
            let last = if hessian { np } else { ia + 1 };
            for ib in ia..last {
                for l in 0..nl {
                    xs[l] = HyperDual::new(xf[l], 0.0, 0.0, 0.0);
                }
                xs[b.free[ia].0].eps1 = 1.0;
                xs[b.free[ib].0].eps2 = 1.0;
                p.eval(b, path, &xs[..nl], &mut out[..b.rows]);
                if ia == ib {
                    for r in 0..b.rows {
                        value[r] = out[r].re;
                        jac[r * np + ia] = out[r].eps1;
                    }
                }
                if hessian {
                    let hv: f64 = (0..b.rows).map(|r| weights[r] * out[r].eps1eps2).sum();
                    hess[ia * np + ib] = hv;
                    hess[ib * np + ia] = hv;
                    if ia == ib && is_action {
                        // The round-off of a velocity (q_{k+1} − q_k)/h is
                        // ε|q|/h: in the gradient, ε|q| times the action's
                        // curvature (about 2M/h).
                        terms = terms.max((hv * xf[b.free[ia].0]).abs());
                    }
                }
            }
        }
        // Residual.
        for (a, &(_, ga)) in b.free.iter().enumerate() {
            let term = (0..b.rows)
                .map(|r| weights[r] * jac[r * np + a])
                .sum::<f64>();
            residual[ga] += term;
            terms = terms.max(term.abs());
        }
        if !is_action {
            for r in 0..b.rows {
                residual[b.offset + r] = value[r];
                for (a, &(l, _)) in b.free.iter().enumerate() {
                    cterms = cterms.max((jac[r * np + a] * xf[l]).abs());
                }
            }
        }
        // Matrix entries.
        for (a, &(_, ga)) in b.free.iter().enumerate() {
            for (c, &(_, gc)) in b.free.iter().enumerate() {
                sink(ga, gc, if hessian { hess[a * np + c] } else { 0.0 });
            }
        }
        if !is_action {
            for r in 0..b.rows {
                for (a, &(_, ga)) in b.free.iter().enumerate() {
                    let j = jac[r * np + a];
                    sink(b.offset + r, ga, j);
                    sink(ga, b.offset + r, j);
                }
            }
        }
    }
    (terms, cterms)
}
