//! Structure of the equations (19): rank of `W`, hidden constraints, free
//! initial data, and consistent completion of initial data.
//!
//! The equations are linear in `q_I⁗` with coefficient `W = ∂²Θ/∂q̈_I²`,
//! `rank W ≤ s`. When `W` is singular, (19) is a differential-algebraic
//! system in `z = (q_I, q̇_I, q̈_I, q⃛_I)` and some combinations of `z` are
//! fixed by the equations and their time derivatives (hidden constraints).
//! Both are read off the derivative array `D = [E; Ė; Ë]` as a function of
//! `(z, u)`, `u = (q⁗, q⁽⁵⁾, q⁽⁶⁾)`, at a consistent point:
//!
//! * `rank W` — the rank of `∂E/∂q⁗`;
//! * hidden constraints — `rank [∂D/∂z  ∂D/∂u] − rank ∂D/∂u`: the number of
//!   independent conditions `D = 0` places on `z` once every derivative
//!   beyond `z` is free to adjust (Campbell's derivative-array count);
//! * free initial data — `4m` minus that.
//!
//! Ranks use the singular values of the AD Jacobian with a relative
//! threshold (`RANK_TOL`), and the gap at the threshold is reported.

use nalgebra::{DMatrix, DVector};
use nonholo_core::Scene;
use nonholo_core::scene::EmbeddingInfo;
use num_dual::Dual64;

use crate::elo::elo_array;
use crate::jet::Jet4;

/// Relative singular-value threshold for numerical ranks.
pub const RANK_TOL: f64 = 1e-9;

/// Number of levels of the derivative array used (E, Ė, Ë).
pub const LEVELS: usize = 3;

/// What the structure analysis found at one point.
#[derive(Debug, Clone, PartialEq)]
pub struct Structure {
    /// Number of independent coordinates `m`.
    pub m: usize,
    /// `rank W`, `W = ∂²Θ/∂q̈_I²` (m×m).
    pub rank_w: usize,
    /// Independent hidden constraints on `z = (q_I, q̇_I, q̈_I, q⃛_I)`.
    pub hidden_constraints: usize,
    /// `4m − hidden_constraints`: initial data that can be chosen freely.
    pub free_initial_data: usize,
    /// Singular values of `W`, largest first.
    pub w_singular_values: Vec<f64>,
    /// Smallest singular value counted in a rank and largest one below the
    /// threshold, over the three rank decisions (how clear the decision was).
    pub rank_gap: (f64, f64),
}

/// The derivative array `D = [E; Ė; Ë]` at `d = (q_I⁽⁰⁾ … q_I⁽⁶⁾)` (7m
/// numbers) into `value` (3m) and its Jacobian `∂D/∂d` (3m × 7m), by one
/// dual pass per column.
pub fn derivative_array<S: Scene>(
    scene: &S,
    e: &EmbeddingInfo,
    t: f64,
    d: &[f64],
    value: &mut [f64],
    jac: &mut DMatrix<f64>,
) {
    let m = e.independent.len();
    let cols = 7 * m;
    let mut dd = vec![Dual64::from_re(0.0); cols];
    let mut out = vec![Dual64::from_re(0.0); LEVELS * m];
    for j in 0..cols {
        for (x, &v) in dd.iter_mut().zip(d) {
            *x = Dual64::from_re(v);
        }
        dd[j].eps = 1.0;
        elo_array::<_, Dual64, Jet4<Dual64>>(scene, e, Dual64::from_re(t), &dd, &mut out);
        for i in 0..LEVELS * m {
            jac[(i, j)] = out[i].eps;
            value[i] = out[i].re;
        }
    }
}

/// Numerical rank and the singular values on either side of the threshold.
fn rank(a: &DMatrix<f64>) -> (usize, Vec<f64>, (f64, f64)) {
    let sv = a.clone().svd(false, false).singular_values;
    let mut s: Vec<f64> = sv.iter().copied().collect();
    s.sort_by(|x, y| y.total_cmp(x));
    let top = s.first().copied().unwrap_or(0.0);
    let r = s.iter().filter(|&&v| v > RANK_TOL * top).count();
    let kept = if r > 0 { s[r - 1] } else { 0.0 };
    let dropped = s.get(r).copied().unwrap_or(0.0);
    (r, s, (kept, dropped))
}

/// Structure of the equations at a consistent point `d` (7m numbers).
pub fn structure<S: Scene>(scene: &S, e: &EmbeddingInfo, t: f64, d: &[f64]) -> Structure {
    let m = e.independent.len();
    let mut value = vec![0.0; LEVELS * m];
    let mut jac = DMatrix::zeros(LEVELS * m, 7 * m);
    derivative_array(scene, e, t, d, &mut value, &mut jac);
    let b = balanced(&jac, d);
    // W alone, scaled like its own entries (it is symmetric, no row terms needed).
    let w = jac.view((0, 4 * m), (m, m)).clone_owned();
    let (rank_w, w_sv, gap_w) = rank(&w);
    let (rank_all, _, gap_all) = rank(&b);
    let ju = b.view((0, 4 * m), (LEVELS * m, 3 * m)).clone_owned();
    let (rank_u, _, gap_u) = rank(&ju);
    let hidden = rank_all - rank_u;
    let kept = gap_w.0.min(gap_all.0).min(gap_u.0);
    let dropped = gap_w.1.max(gap_all.1).max(gap_u.1);
    Structure {
        m,
        rank_w,
        hidden_constraints: hidden,
        free_initial_data: 4 * m - hidden,
        w_singular_values: w_sv,
        rank_gap: (kept, dropped),
    }
}

/// Outcome of a consistent completion.
#[derive(Debug, Clone, PartialEq)]
pub struct Completion {
    /// `|D|∞` before and after.
    pub residual: (f64, f64),
    /// Gauss–Newton iterations.
    pub iterations: usize,
    /// `|Δq⃛|∞`: how far the third derivatives moved.
    pub third_change: f64,
    /// Whether `q⃛` is fixed uniquely by `(q, q̇, q̈)` (the Jacobian in the
    /// unknowns has no null direction that moves `q⃛`).
    pub third_unique: bool,
}

/// Scale of each row of the derivative array: `1 + Σ_j |∂D_l/∂d_j · d_j|`,
/// the size of the terms that cancel in it.
fn row_scales(jac: &DMatrix<f64>, d: &[f64], scales: &mut [f64]) {
    for (l, sc) in scales.iter_mut().enumerate() {
        *sc = 1.0
            + (0..d.len())
                .map(|j| (jac[(l, j)] * d[j]).abs())
                .sum::<f64>();
    }
}

/// `R⁻¹ J C`: rows divided by their term scale, columns multiplied by
/// `max(1, |d_j|)`, so that each entry is the relative contribution of one
/// variable to one equation. Rank decisions are made on this matrix.
fn balanced(jac: &DMatrix<f64>, d: &[f64]) -> DMatrix<f64> {
    let mut scales = vec![0.0; jac.nrows()];
    row_scales(jac, d, &mut scales);
    DMatrix::from_fn(jac.nrows(), jac.ncols(), |l, j| {
        jac[(l, j)] * d[j].abs().max(1.0) / scales[l]
    })
}

/// Makes `d` consistent: with `q_I, q̇_I, q̈_I` fixed, adjusts
/// `(q⃛, q⁗, q⁽⁵⁾, q⁽⁶⁾)` (or only the derivatives beyond `q⃛` if
/// `move_third` is false) until every row of `D` is below `rtol` relative to
/// the terms that cancel in it.
///
/// Levenberg–Marquardt on the row-scaled residual, with minimum-norm steps in
/// the (underdetermined) unknowns. The hidden constraints can be nonlinear in
/// `q⃛` (quadratic for the sleigh), so a far starting guess may fail; the
/// error then says so.
pub fn complete<S: Scene>(
    scene: &S,
    e: &EmbeddingInfo,
    t: f64,
    d: &mut [f64],
    move_third: bool,
    rtol: f64,
) -> Result<Completion, String> {
    const MAX_ITER: usize = 60;
    let m = e.independent.len();
    let rows = LEVELS * m;
    let first = if move_third { 3 * m } else { 4 * m };
    let unknowns = 7 * m - first;
    let mut value = vec![0.0; rows];
    let mut jac = DMatrix::zeros(rows, 7 * m);
    let mut scales = vec![1.0; rows];
    let third_before: Vec<f64> = d[3 * m..4 * m].to_vec();
    derivative_array(scene, e, t, d, &mut value, &mut jac);
    row_scales(&jac, d, &mut scales);
    // Scales are frozen at the start of each iteration so that the objective
    // compared by the damping logic does not move under it.
    let objective =
        |v: &[f64], sc: &[f64]| v.iter().zip(sc).map(|(x, s)| (x / s).powi(2)).sum::<f64>();
    let relative = |v: &[f64], sc: &[f64]| {
        v.iter()
            .zip(sc)
            .fold(0.0f64, |a, (x, s)| a.max((x / s).abs()))
    };
    let before = relative(&value, &scales);
    let mut res = before;
    let mut iterations = 0;
    let mut mu = 1e-6;
    let mut trial = d.to_vec();
    let mut trial_value = value.clone();
    let mut trial_jac = jac.clone();
    while res > rtol {
        if iterations == MAX_ITER {
            return Err(format!(
                "the hidden constraints could not be satisfied from this starting guess: relative \
                 derivative-array residual {res:.3e} after {MAX_ITER} iterations (tolerance {rtol:.1e})"
            ));
        }
        iterations += 1;
        // Row-scaled Jacobian in the unknowns and residual.
        let js = DMatrix::from_fn(rows, unknowns, |l, k| jac[(l, first + k)] / scales[l]);
        let rs = DVector::from_fn(rows, |l, _| value[l] / scales[l]);
        let current = objective(&value, &scales);
        let jjt0 = &js * js.transpose();
        // Damping relative to the largest diagonal entry of J Jᵀ; it shrinks
        // tenfold after each success and may vanish (pure Gauss–Newton),
        // since a floor comparable to a small σ² slows convergence to linear.
        let diag = (0..rows).fold(0.0f64, |a, l| a.max(jjt0[(l, l)]));
        let mut accepted = false;
        for _ in 0..30 {
            // Minimum-norm damped step: Δ = Jᵀ (J Jᵀ + μ I)⁻¹ r.
            let mut jjt = jjt0.clone();
            for l in 0..rows {
                jjt[(l, l)] += mu * diag;
            }
            let Some(y) = jjt.lu().solve(&rs) else {
                mu = (mu * 10.0).max(1e-12);
                continue;
            };
            let step = js.transpose() * y;
            trial.copy_from_slice(d);
            for k in 0..unknowns {
                trial[first + k] -= step[k];
            }
            derivative_array(scene, e, t, &trial, &mut trial_value, &mut trial_jac);
            if objective(&trial_value, &scales) < current {
                mu /= 10.0;
                accepted = true;
                break;
            }
            mu = (mu * 10.0).max(1e-12);
        }
        if !accepted {
            break;
        }
        d.copy_from_slice(&trial);
        value.copy_from_slice(&trial_value);
        jac.copy_from(&trial_jac);
        row_scales(&jac, d, &mut scales);
        res = relative(&value, &scales);
    }
    if res > rtol * 1e3 {
        return Err(format!(
            "the hidden constraints could not be satisfied from this starting guess: relative \
             derivative-array residual {res:.3e} (tolerance {rtol:.1e})"
        ));
    }
    // Uniqueness of q⃛: null space of ∂D/∂(q⃛, u) must not move q⃛.
    let third_unique = if move_third {
        // Pad to square so that the SVD returns the whole null space.
        let b = balanced(&jac, d);
        let mut ju = DMatrix::zeros(unknowns, unknowns);
        ju.view_mut((0, 0), (LEVELS * m, unknowns))
            .copy_from(&b.view((0, first), (LEVELS * m, unknowns)));
        let svd = ju.svd(false, true);
        let vt = svd.v_t.expect("v_t requested");
        let top = svd.singular_values.max();
        svd.singular_values
            .iter()
            .enumerate()
            .filter(|(_, sv)| **sv <= RANK_TOL * top)
            .all(|(i, _)| (0..m).all(|k| vt[(i, k)].abs() <= 1e-6))
    } else {
        true
    };
    let third_change = d[3 * m..4 * m]
        .iter()
        .zip(&third_before)
        .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
    Ok(Completion {
        residual: (before, res),
        iterations,
        third_change,
        third_unique,
    })
}
