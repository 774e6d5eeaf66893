//! The paper's general case (eq. 27–30) done literally: the dependent
//! coordinates are eliminated by integrating the discretised (28) from
//! their initial values, and the action becomes a function of the
//! independent coordinates alone. Its gradient, computed here by forward
//! sensitivities through the recursion, is dense (each `q_I,j` moves every
//! later `q_D`): this is the check of the sparse multiplier form that
//! [`crate::Solver`] solves, for grids small enough to afford it.

use nonholo_core::Scene;
use num_dual::Dual;

use crate::Error;
use crate::problem::{DependentEnd, Formulation, Problem};

/// The dependent coordinates of `path` recomputed from (28), and the
/// gradient of the eliminated action `S̃(q_I)` over `h` with respect to
/// the interior independent coordinates (node-major); with the dependent
/// end fixed, its component orthogonal to the gradients of `q_D(t1)`.
/// Zero (to the discretisation's round-off) at a stationary path of the
/// general case.
pub fn reduced_gradient<S: Scene>(
    problem: &Problem<'_, S>,
    path: &[f64],
) -> Result<Vec<f64>, Error> {
    let Formulation::General { dependent, end } = &problem.formulation else {
        return Err(Error::Input {
            field: "formulation".into(),
            reason: "the reduced gradient is defined for the general case".into(),
        });
    };
    let (n, last, h) = (problem.n, problem.intervals, problem.h());
    let ind = problem.independent().to_vec();
    let s = dependent.len();
    // Directions: interior independent coordinates.
    let dirs: Vec<(usize, usize)> = (1..last)
        .flat_map(|k| ind.iter().map(move |&i| (k, i)))
        .collect();
    let mut grad = Vec::with_capacity(dirs.len());
    let mut end_sens: Vec<Vec<f64>> = Vec::with_capacity(dirs.len());
    for &(kd, id) in &dirs {
        let mut q: Vec<Dual<f64>> = path.iter().map(|&v| Dual::from_re(v)).collect();
        q[kd * n + id].eps = 1.0;
        let mut action = Dual::from_re(0.0);
        for k in 0..last {
            solve_step(problem, dependent, k, &mut q, s)?;
            let tm = Dual::from_re(0.5 * (problem.t(k) + problem.t(k + 1)));
            let mid: Vec<_> = (0..n)
                .map(|i| (q[k * n + i] + q[(k + 1) * n + i]) * 0.5)
                .collect();
            let vel: Vec<_> = (0..n)
                .map(|i| (q[(k + 1) * n + i] - q[k * n + i]) / h)
                .collect();
            action += problem.scene.lagrangian(tm, &mid, &vel) * h;
        }
        grad.push(action.eps / h);
        end_sens.push(dependent.iter().map(|&d| q[last * n + d].eps).collect());
    }
    if *end == DependentEnd::Fixed {
        // Remove the components along the s gradients of q_D(t1)
        // (Gram–Schmidt).
        let mut basis: Vec<Vec<f64>> = Vec::new();
        for j in 0..s {
            let mut v: Vec<f64> = end_sens.iter().map(|e| e[j]).collect();
            for b in &basis {
                let c: f64 = v.iter().zip(b).map(|(x, y)| x * y).sum();
                v.iter_mut().zip(b).for_each(|(x, y)| *x -= c * y);
            }
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm > 0.0 {
                v.iter_mut().for_each(|x| *x /= norm);
                basis.push(v);
            }
        }
        for b in &basis {
            let c: f64 = grad.iter().zip(b).map(|(x, y)| x * y).sum();
            grad.iter_mut().zip(b).for_each(|(x, y)| *x -= c * y);
        }
    }
    Ok(grad)
}

/// Solves `g(t_{k+½}, (q_k + q_{k+1})/2, (q_{k+1} − q_k)/h) = 0` for the
/// dependent coordinates at node `k + 1` (Newton on their values, started
/// from node `k`; the derivative parts by the implicit function theorem).
fn solve_step<S: Scene>(
    problem: &Problem<'_, S>,
    dependent: &[usize],
    k: usize,
    q: &mut [Dual<f64>],
    s: usize,
) -> Result<(), Error> {
    let (n, h) = (problem.n, problem.h());
    let tm = 0.5 * (problem.t(k) + problem.t(k + 1));
    for &d in dependent {
        q[(k + 1) * n + d] = Dual::from_re(q[k * n + d].re);
    }
    // g and its Jacobian with respect to the dependent values at k + 1,
    // at fixed derivative parts of everything else.
    let eval = |q: &[Dual<f64>], seed: Option<usize>| -> Vec<Dual<f64>> {
        let mut local: Vec<Dual<f64>> = q[k * n..(k + 2) * n].to_vec();
        if let Some(j) = seed {
            // Re-seed: derivative with respect to one dependent value only.
            for x in local.iter_mut() {
                x.eps = 0.0;
            }
            local[n + dependent[j]].eps = 1.0;
        }
        let mid: Vec<_> = (0..n).map(|i| (local[i] + local[n + i]) * 0.5).collect();
        let vel: Vec<_> = (0..n).map(|i| (local[n + i] - local[i]) / h).collect();
        let mut out = vec![Dual::from_re(0.0); s];
        problem
            .scene
            .nonholonomic(Dual::from_re(tm), &mid, &vel, &mut out);
        out
    };
    let mut jac = vec![0.0; s * s];
    for _ in 0..50 {
        let g = eval(q, None);
        for j in 0..s {
            let col = eval(q, Some(j));
            for r in 0..s {
                jac[r * s + j] = col[r].eps;
            }
        }
        let rhs: Vec<f64> = g.iter().map(|v| -v.re).collect();
        let delta = solve_dense(&jac, &rhs, s).ok_or_else(|| Error::Singular {
            node: k + 1,
            t: problem.t(k + 1),
            what: "∂g/∂q̇_D: (28) does not determine the dependent coordinates".into(),
        })?;
        let mut step = 0.0f64;
        for (j, &d) in dependent.iter().enumerate() {
            q[(k + 1) * n + d].re += delta[j];
            step = step.max(delta[j].abs());
        }
        if step <= 1e-15 * (1.0 + q[(k + 1) * n + dependent[0]].re.abs()) {
            break;
        }
    }
    // Derivative parts: J δq_D = −(g's derivative at δq_D = 0).
    for &d in dependent {
        q[(k + 1) * n + d].eps = 0.0;
    }
    let g = eval(q, None);
    let rhs: Vec<f64> = g.iter().map(|v| -v.eps).collect();
    let delta = solve_dense(&jac, &rhs, s).ok_or_else(|| Error::Singular {
        node: k + 1,
        t: problem.t(k + 1),
        what: "∂g/∂q̇_D".into(),
    })?;
    for (j, &d) in dependent.iter().enumerate() {
        q[(k + 1) * n + d].eps = delta[j];
    }
    Ok(())
}

/// Gaussian elimination with partial pivoting on a small dense system.
fn solve_dense(a: &[f64], b: &[f64], s: usize) -> Option<Vec<f64>> {
    let mut m = a.to_vec();
    let mut x = b.to_vec();
    for c in 0..s {
        let p = (c..s).max_by(|&i, &j| m[i * s + c].abs().total_cmp(&m[j * s + c].abs()))?;
        if m[p * s + c].abs() < 1e-300 {
            return None;
        }
        if p != c {
            for j in 0..s {
                m.swap(c * s + j, p * s + j);
            }
            x.swap(c, p);
        }
        for r in c + 1..s {
            let f = m[r * s + c] / m[c * s + c];
            for j in c..s {
                m[r * s + j] -= f * m[c * s + j];
            }
            x[r] -= f * x[c];
        }
    }
    for c in (0..s).rev() {
        let mut v = x[c];
        for j in c + 1..s {
            v -= m[c * s + j] * x[j];
        }
        x[c] = v / m[c * s + c];
    }
    Some(x)
}
