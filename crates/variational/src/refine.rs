//! Grid refinement: the same problem on `N`, `2N` and `4N` intervals,
//! compared at the coarse nodes. The midpoint action is symmetric, so its
//! error expands in even powers of `h`: the measured order should be 2, and
//! Richardson's extrapolation `(4 X_{4N} − X_{2N})/3` removes the `h²` term.

use nonholo_core::Scene;

use crate::Error;
use crate::newton::{Options, Solution, Solver};
use crate::problem::{Ends, Formulation, Problem};

/// The design order of the discretisation.
pub const DESIGN_ORDER: f64 = 2.0;

/// Three solves on grids halved twice.
#[derive(Debug, Clone)]
pub struct Refinement {
    /// Coarse to fine.
    pub solutions: Vec<Solution>,
    /// Largest difference at the coarse nodes between levels 0–1 and 1–2.
    pub differences: [f64; 2],
    /// `log2` of their ratio.
    pub order: f64,
    /// Error estimate of the finest solution, `d₂/(2^p − 1)` with the
    /// design order `p = 2`.
    pub error_estimate: f64,
    /// Richardson's extrapolation at the coarse nodes (nodes × n).
    pub extrapolated: Vec<f64>,
    /// Its error estimate: the largest difference from the extrapolation of
    /// the two coarser levels.
    pub extrapolated_error: f64,
}

impl Refinement {
    /// Coarse node times.
    pub fn t(&self) -> &[f64] {
        &self.solutions[0].t
    }
}

/// Solves on `intervals`, `2 intervals` and `4 intervals`, each level
/// started from the previous one interpolated (the first from `start`, or
/// the straight line between the ends).
pub fn refine<S: Scene>(
    scene: &S,
    formulation: &Formulation,
    (t0, t1): (f64, f64),
    intervals: usize,
    ends: &Ends,
    start: Option<&[f64]>,
    options: &Options,
) -> Result<Refinement, Error> {
    let mut solutions: Vec<Solution> = Vec::with_capacity(3);
    for level in 0..3 {
        let nl = intervals << level;
        let problem = Problem::with_limit(
            scene,
            formulation.clone(),
            t0,
            t1,
            nl,
            ends.clone(),
            options.max_bytes,
        )?;
        let path = match (solutions.last(), start) {
            (Some(prev), _) => sample(prev, &problem.times()),
            (None, Some(s)) => s.to_vec(),
            (None, None) => problem.start_line(),
        };
        let mut solver = Solver::new(&problem, options)?;
        solutions.push(solver.solve(&path, options)?);
    }
    let n = solutions[0].n;
    let coarse = solutions[0].t.len();
    let at = |level: usize, k: usize, i: usize| solutions[level].at(k << level, i);
    let (mut d1, mut d2) = (0.0f64, 0.0f64);
    let mut extrapolated = vec![0.0; coarse * n];
    let mut extrapolated_error = 0.0f64;
    for k in 0..coarse {
        for i in 0..n {
            let (a, b, c) = (at(0, k, i), at(1, k, i), at(2, k, i));
            d1 = d1.max((a - b).abs());
            d2 = d2.max((b - c).abs());
            let fine = (4.0 * c - b) / 3.0;
            let coarse_x = (4.0 * b - a) / 3.0;
            extrapolated[k * n + i] = fine;
            extrapolated_error = extrapolated_error.max((fine - coarse_x).abs());
        }
    }
    let order = (d1 / d2).log2();
    Ok(Refinement {
        solutions,
        differences: [d1, d2],
        order,
        error_estimate: d2 / (2f64.powf(DESIGN_ORDER) - 1.0),
        extrapolated,
        extrapolated_error,
    })
}

/// A solution's path at the times `t` (linear interpolation between nodes;
/// constant outside), nodes × n.
pub fn sample(solution: &Solution, t: &[f64]) -> Vec<f64> {
    let n = solution.n;
    let ts = &solution.t;
    let last = ts.len() - 1;
    let mut out = Vec::with_capacity(t.len() * n);
    for &tt in t {
        let j = ts.partition_point(|&x| x <= tt).clamp(1, last);
        let (ta, tb) = (ts[j - 1], ts[j]);
        let w = ((tt - ta) / (tb - ta)).clamp(0.0, 1.0);
        for i in 0..n {
            let (a, b) = (solution.at(j - 1, i), solution.at(j, i));
            out.push(a + w * (b - a));
        }
    }
    out
}
