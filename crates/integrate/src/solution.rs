use crate::{Dense, Method};

/// Work counters of one run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Stats {
    /// Accepted steps.
    pub steps: usize,
    /// Rejected steps (error test failed, or a trial stage could not be
    /// evaluated; for Radau5 also a failed Newton iteration or a singular
    /// iteration matrix). `steps + rejected_steps` is the number of trial steps.
    pub rejected_steps: usize,
    /// Evaluations of `f` (of `F` for [`crate::solve_implicit`]), including
    /// those of finite-difference Jacobians and those of
    /// [`Stats::dense_rhs_evals`].
    pub rhs_evals: usize,
    /// The part of `rhs_evals` spent only on the continuous extension: the
    /// three extra stages of DOP853's order-7 dense output, computed for the
    /// steps whose polynomial is needed (`Options::dense`, a guard, or an
    /// output time inside the step). Zero for the other methods, whose
    /// continuous extensions cost no evaluation. Work-precision comparisons
    /// of the integrator proper use `rhs_evals − dense_rhs_evals`.
    pub dense_rhs_evals: usize,
    /// Jacobian evaluations, analytic or by finite differences (zero for
    /// explicit methods). With `RadauNewton::Full` each iteration evaluates
    /// three (one per stage point), and each step one more at its start for
    /// the error estimate.
    pub jacobian_evals: usize,
    /// LU factorisations (zero for explicit methods). Radau5 factors a real
    /// and a complex matrix for each step size; the pair counts as one.
    /// With `RadauNewton::Full` every iteration adds one factorisation of
    /// the `3n × 3n` Newton matrix, and every step one of the `n × n`
    /// matrix `γ/h J' + J` of the error estimate.
    pub lu_decompositions: usize,
    /// Newton iterations of Radau5 (each costs 3 evaluations of `f`/`F`),
    /// in converged and failed attempts alike; zero for explicit methods.
    pub newton_iterations: usize,
    /// Newton iterations that failed to converge (diverged, too slow, or not
    /// converged within `Radau5Options::newton_max_iter`; zero for explicit methods).
    pub newton_failures: usize,
    /// Wall-clock time of the run in seconds.
    pub wall_time_s: f64,
    /// First time at which the stiffness test (Hairer) fired, with the
    /// estimate `h·|λ|` of the dominant eigenvalue times the step.
    pub stiffness_detected: Option<(f64, f64)>,
}

impl Stats {
    /// Adds the counters of `other` (work done after this, e.g. another
    /// segment of the same run); the first stiffness detection is kept.
    pub fn add(&mut self, other: &Stats) {
        self.steps += other.steps;
        self.rejected_steps += other.rejected_steps;
        self.rhs_evals += other.rhs_evals;
        self.dense_rhs_evals += other.dense_rhs_evals;
        self.jacobian_evals += other.jacobian_evals;
        self.lu_decompositions += other.lu_decompositions;
        self.newton_iterations += other.newton_iterations;
        self.newton_failures += other.newton_failures;
        self.wall_time_s += other.wall_time_s;
        if self.stiffness_detected.is_none() {
            self.stiffness_detected = other.stiffness_detected;
        }
    }
}

/// Result of a run: samples on the output grid, optional continuous extension, counters.
#[derive(Debug, Clone)]
pub struct Solution {
    /// The method that computed it.
    pub method: Method,
    /// Dimension of the state.
    pub dim: usize,
    /// Output times reached, increasing.
    pub t: Vec<f64>,
    /// Samples, row-major: `y[i * dim + j]` is component `j` at `t[i]`.
    pub y: Vec<f64>,
    /// Continuous extension over `[t0, t_last]` if `Options::dense` was set.
    pub dense: Option<Dense>,
    /// Last time reached (`t_end` on success).
    pub t_last: f64,
    /// State at `t_last`.
    pub y_last: Vec<f64>,
    /// Work counters.
    pub stats: Stats,
}

impl Solution {
    /// Sample `i` as a slice.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.y[i * self.dim..(i + 1) * self.dim]
    }
}
