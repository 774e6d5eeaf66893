//! The conic programs of this crate, solved with Clarabel (an interior-point
//! solver for convex quadratic and conic programs, pure Rust):
//!
//! ```text
//! minimise ½ xᵀ P x + qᵀ x   subject to   A x + s = b,  s ∈ K
//! ```
//!
//! with `K` a product of zero cones (equalities) and second-order cones.
//! [`ConicProgram`] keeps dense sparsity patterns (every entry stored), so
//! that after the first solve the data are updated in place and no solve
//! allocates a new solver.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};

/// Tolerances of every solve: the programs here are small and well scaled,
/// and their solutions must agree with a direct KKT solve to ~1e-12.
fn settings() -> DefaultSettings<f64> {
    DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(1e-13)
        .tol_gap_rel(1e-13)
        .tol_feas(1e-13)
        .tol_ktratio(1e-10)
        .iterative_refinement_reltol(1e-15)
        .iterative_refinement_abstol(1e-15)
        .max_iter(100)
        .presolve_enable(false)
        .build()
        .expect("valid Clarabel settings")
}

/// A dense `rows × cols` pattern in compressed columns: every entry
/// (`upper`: only `i <= j`) stored, column by column.
fn dense_pattern(rows: usize, cols: usize, upper: bool) -> CscMatrix<f64> {
    let mut colptr = Vec::with_capacity(cols + 1);
    let mut rowval = Vec::new();
    colptr.push(0);
    for j in 0..cols {
        let end = if upper { (j + 1).min(rows) } else { rows };
        rowval.extend(0..end);
        colptr.push(rowval.len());
    }
    let nnz = rowval.len();
    CscMatrix::new(rows, cols, colptr, rowval, vec![0.0; nnz])
}

/// Why a conic program has no usable solution.
#[derive(Debug, Clone, PartialEq)]
pub struct ConicError {
    /// Clarabel's status (`PrimalInfeasible`, `MaxIterations`, …) or the
    /// set-up error.
    pub status: String,
    pub iterations: u32,
}

impl std::fmt::Display for ConicError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Clarabel returned {} after {} iterations",
            self.status, self.iterations
        )
    }
}

/// A convex program with `n` variables and dense data, re-solved with new
/// values of the same shape.
pub struct ConicProgram {
    n: usize,
    m: usize,
    cones: Vec<SupportedConeT<f64>>,
    p: CscMatrix<f64>,
    a: CscMatrix<f64>,
    q: Vec<f64>,
    b: Vec<f64>,
    solver: Option<DefaultSolver<f64>>,
    /// Interior-point iterations of the last solve.
    pub iterations: u32,
}

impl ConicProgram {
    /// `n` variables, `m` rows of `A` split into `cones` (their dimensions
    /// must add up to `m`).
    pub fn new(n: usize, m: usize, cones: Vec<SupportedConeT<f64>>) -> Self {
        ConicProgram {
            n,
            m,
            cones,
            p: dense_pattern(n, n, true),
            a: dense_pattern(m, n, false),
            q: vec![0.0; n],
            b: vec![0.0; m],
            solver: None,
            iterations: 0,
        }
    }

    /// Sets `P` (symmetric; only `p(i, j)` with `i <= j` is read), `q`, `A`
    /// and `b` from the closures and vectors given.
    pub fn set(
        &mut self,
        p: impl Fn(usize, usize) -> f64,
        q: &[f64],
        a: impl Fn(usize, usize) -> f64,
        b: &[f64],
    ) {
        let mut k = 0;
        for j in 0..self.n {
            for i in 0..=j {
                self.p.nzval[k] = p(i, j);
                k += 1;
            }
        }
        let mut k = 0;
        for j in 0..self.n {
            for i in 0..self.m {
                self.a.nzval[k] = a(i, j);
                k += 1;
            }
        }
        self.q.copy_from_slice(q);
        self.b.copy_from_slice(b);
    }

    /// Solves the program with the data last [`ConicProgram::set`]; only
    /// Clarabel's `Solved` counts.
    pub fn solve(&mut self) -> Result<(), ConicError> {
        self.solve_accepting(false).map(|_| ())
    }

    /// As [`ConicProgram::solve`]; with `almost`, Clarabel's `AlmostSolved`
    /// (its reduced tolerances, ~1e-5 relative) counts too: degenerate
    /// programs (a solution on a cone's boundary with a zero multiplier)
    /// converge only that far. Returns whether the accuracy is reduced.
    pub fn solve_accepting(&mut self, almost: bool) -> Result<bool, ConicError> {
        let updated = match self.solver.as_mut() {
            Some(s) if s.is_data_update_allowed() => s
                .update_P(&self.p.nzval)
                .and_then(|()| s.update_q(&self.q))
                .and_then(|()| s.update_A(&self.a.nzval))
                .and_then(|()| s.update_b(&self.b))
                .is_ok(),
            _ => false,
        };
        if !updated {
            let solver =
                DefaultSolver::new(&self.p, &self.q, &self.a, &self.b, &self.cones, settings())
                    .map_err(|e| ConicError {
                        status: format!("a set-up error ({e})"),
                        iterations: 0,
                    })?;
            self.solver = Some(solver);
        }
        let solver = self.solver.as_mut().expect("set above");
        solver.solve();
        self.iterations = solver.solution.iterations;
        match solver.solution.status {
            SolverStatus::Solved => Ok(false),
            SolverStatus::AlmostSolved if almost => Ok(true),
            status => Err(ConicError {
                status: format!("{status:?}"),
                iterations: self.iterations,
            }),
        }
    }

    /// The primal solution `x` of the last solve.
    pub fn x(&self) -> &[f64] {
        self.solver.as_ref().map_or(&[], |s| &s.solution.x[..])
    }

    /// The dual solution `z` (multipliers of `A x + s = b`): `P x + q + Aᵀz = 0`.
    pub fn z(&self) -> &[f64] {
        self.solver.as_ref().map_or(&[], |s| &s.solution.z[..])
    }
}

/// The friction force at a contact whose slip velocity is zero, by the
/// principle of maximal dissipation at acceleration level: with the slip
/// acceleration affine in the contact force, `a_s = W f + c` (`W`
/// symmetric positive definite: the contact's inverse inertia),
///
/// ```text
/// f = argmin ½ fᵀ W f + cᵀ f   over   ‖f‖ ≤ r = μN,
/// ```
///
/// whose optimality conditions are Coulomb's law: `a_s = 0` with `‖f‖ ≤ r`
/// (stick), or `‖f‖ = r` with `f` opposite to `a_s` (slip starts). A
/// second-order cone program in `d` variables (`d` = 1 for a blade, 2 for a
/// wheel's contact point).
pub struct FrictionCone {
    d: usize,
    program: ConicProgram,
}

/// The force and slip acceleration found by [`FrictionCone::solve`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConeSolution {
    /// The friction force (components `0..d`).
    pub force: [f64; 2],
    /// The slip acceleration `W f + c` it leaves (components `0..d`).
    pub slip_accel: [f64; 2],
    /// `‖f‖/r`: below 1 the contact sticks.
    pub ratio: f64,
    /// Whether Clarabel reached only its reduced accuracy (`AlmostSolved`,
    /// ~1e-5 relative): a degenerate program.
    pub reduced: bool,
}

impl FrictionCone {
    /// A cone for a contact with `d` (1 or 2) slip components.
    pub fn new(d: usize) -> Self {
        assert!((1..=2).contains(&d), "a contact has 1 or 2 slip components");
        FrictionCone {
            d,
            program: ConicProgram::new(d, d + 1, vec![SupportedConeT::SecondOrderConeT(d + 1)]),
        }
    }

    /// Solves for `W` (`d × d`, row-major), `c` and the radius `r > 0`.
    pub fn solve(&mut self, w: &[f64], c: &[f64], r: f64) -> Result<ConeSolution, ConicError> {
        let d = self.d;
        // s = (r, f) ∈ SOC: A = [0; −I], b = (r, 0).
        let mut b = [0.0; 3];
        b[0] = r;
        self.program.set(
            |i, j| 0.5 * (w[i * d + j] + w[j * d + i]),
            &c[..d],
            |i, j| if i == j + 1 { -1.0 } else { 0.0 },
            &b[..d + 1],
        );
        // At a transition the solution may lie on the cone's boundary with
        // a zero slip acceleration (degenerate): accept reduced accuracy.
        let reduced = self.program.solve_accepting(true)?;
        let x = self.program.x();
        let mut out = ConeSolution {
            force: [0.0; 2],
            slip_accel: [0.0; 2],
            ratio: 0.0,
            reduced,
        };
        out.force[..d].copy_from_slice(&x[..d]);
        for i in 0..d {
            out.slip_accel[i] = c[i] + (0..d).map(|j| w[i * d + j] * x[j]).sum::<f64>();
        }
        out.ratio = x[..d].iter().map(|v| v * v).sum::<f64>().sqrt() / r;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An equality-constrained QP equals its KKT solution.
    #[test]
    fn equality_qp_is_its_kkt_solution() {
        let m = [[2.0, 0.3, 0.0], [0.3, 1.0, 0.1], [0.0, 0.1, 0.5]];
        let q = [-1.0, 2.0, -0.5];
        let a = [[1.0, 2.0, -1.0]];
        let mut p = ConicProgram::new(3, 1, vec![SupportedConeT::ZeroConeT(1)]);
        for round in 0..2 {
            // The second round re-solves with updated data.
            let b = [0.3 + round as f64];
            p.set(|i, j| m[i][j], &q, |i, j| a[i][j], &b);
            p.solve().unwrap();
            let (x, z) = (p.x(), p.z());
            for i in 0..3 {
                let r = (0..3).map(|j| m[i][j] * x[j]).sum::<f64>() + q[i] + a[0][i] * z[0];
                assert!(r.abs() < 1e-12, "stationarity {i}: {r:e}");
            }
            let g = (0..3).map(|j| a[0][j] * x[j]).sum::<f64>() - b[0];
            assert!(g.abs() < 1e-12, "feasibility: {g:e}");
        }
    }

    /// Coulomb's law in one dimension: stick while |c|/W ≤ r, else the force
    /// saturates at r against the slip acceleration.
    #[test]
    fn one_dimensional_cone_is_coulomb() {
        let mut cone = FrictionCone::new(1);
        let w = [2.0];
        // Stick: the force that zeroes the slip acceleration, f = −c/W.
        let s = cone.solve(&w, &[1.0], 1.0).unwrap();
        assert!((s.force[0] + 0.5).abs() < 1e-9, "{s:?}");
        assert!(s.slip_accel[0].abs() < 1e-9 && s.ratio < 1.0);
        // Slip: |c|/W = 2 > r = 1.
        let s = cone.solve(&w, &[4.0], 1.0).unwrap();
        assert!((s.force[0] + 1.0).abs() < 1e-9, "{s:?}");
        assert!((s.slip_accel[0] - 2.0).abs() < 1e-8 && (s.ratio - 1.0).abs() < 1e-9);
    }

    /// In two dimensions with W = w I the force opposes c and saturates.
    #[test]
    fn two_dimensional_cone_opposes_the_free_slip() {
        let mut cone = FrictionCone::new(2);
        let w = [1.0, 0.0, 0.0, 1.0];
        let s = cone.solve(&w, &[3.0, 4.0], 2.0).unwrap();
        assert!(
            (s.force[0] + 1.2).abs() < 1e-8 && (s.force[1] + 1.6).abs() < 1e-8,
            "{s:?}"
        );
        assert!((s.slip_accel[0] - 1.8).abs() < 1e-8 && (s.slip_accel[1] - 2.4).abs() < 1e-8);
    }
}
