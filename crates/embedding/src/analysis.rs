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
/// dual pass per column; the map on the branch nearest to `near` (its
/// principal one if empty).
pub fn derivative_array<S: Scene>(
    scene: &S,
    e: &EmbeddingInfo,
    t: f64,
    d: &[f64],
    near: &[f64],
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
        elo_array::<_, Dual64, Jet4<Dual64>>(scene, e, Dual64::from_re(t), &dd, near, &mut out);
        for i in 0..LEVELS * m {
            jac[(i, j)] = out[i].eps;
            value[i] = out[i].re;
        }
    }
}

/// Largest number of QR sweeps of an SVD before it is given up as not
/// converging (nalgebra iterates for ever by default: with a NaN entry it
/// never converges). Converging decompositions of the small matrices here
/// take a few dozen.
const SVD_MAX_ITER: usize = 10_000;

/// The singular value decomposition of `a`, or why there is none: entries
/// that are not finite (the equations evaluated on the singular set of the
/// embedding map), or no convergence within [`SVD_MAX_ITER`] sweeps.
pub fn svd_of(
    a: DMatrix<f64>,
    compute_u: bool,
    compute_v: bool,
) -> Result<nalgebra::SVD<f64, nalgebra::Dyn, nalgebra::Dyn>, String> {
    if let Some(((i, j), v)) = a
        .iter()
        .enumerate()
        .map(|(k, v)| ((k % a.nrows(), k / a.nrows()), v))
        .find(|(_, v)| !v.is_finite())
    {
        return Err(format!(
            "the equations are not finite here (entry ({i}, {j}) of a {}×{} Jacobian is {v})",
            a.nrows(),
            a.ncols()
        ));
    }
    let (r, c) = a.shape();
    // nalgebra's own convergence threshold (that of `Matrix::svd`).
    a.try_svd(compute_u, compute_v, 5.0 * f64::EPSILON, SVD_MAX_ITER)
        .ok_or_else(|| format!("the SVD of a {r}×{c} Jacobian did not converge"))
}

/// Numerical rank, the singular values (largest first), and the last kept
/// and first dropped of them.
type Rank = (usize, Vec<f64>, (f64, f64));

/// Numerical rank and the singular values on either side of the threshold.
fn rank(a: &DMatrix<f64>) -> Result<Rank, String> {
    let sv = svd_of(a.clone(), false, false)?.singular_values;
    let mut s: Vec<f64> = sv.iter().copied().collect();
    s.sort_by(|x, y| y.total_cmp(x));
    let top = s.first().copied().unwrap_or(0.0);
    let r = s.iter().filter(|&&v| v > RANK_TOL * top).count();
    let kept = if r > 0 { s[r - 1] } else { 0.0 };
    let dropped = s.get(r).copied().unwrap_or(0.0);
    Ok((r, s, (kept, dropped)))
}

/// Structure of the equations at a consistent point `d` (7m numbers).
pub fn structure<S: Scene>(
    scene: &S,
    e: &EmbeddingInfo,
    t: f64,
    d: &[f64],
) -> Result<Structure, String> {
    let m = e.independent.len();
    let mut value = vec![0.0; LEVELS * m];
    let mut jac = DMatrix::zeros(LEVELS * m, 7 * m);
    derivative_array(scene, e, t, d, &[], &mut value, &mut jac);
    let b = balanced(&jac, d);
    // W alone, scaled like its own entries (it is symmetric, no row terms needed).
    let w = jac.view((0, 4 * m), (m, m)).clone_owned();
    let (rank_w, w_sv, gap_w) = rank(&w)?;
    let (rank_all, _, gap_all) = rank(&b)?;
    let ju = b.view((0, 4 * m), (LEVELS * m, 3 * m)).clone_owned();
    let (rank_u, _, gap_u) = rank(&ju)?;
    let hidden = rank_all - rank_u;
    let kept = gap_w.0.min(gap_all.0).min(gap_u.0);
    let dropped = gap_w.1.max(gap_all.1).max(gap_u.1);
    Ok(Structure {
        m,
        rank_w,
        hidden_constraints: hidden,
        free_initial_data: 4 * m - hidden,
        w_singular_values: w_sv,
        rank_gap: (kept, dropped),
    })
}

/// Outcome of a consistent completion.
#[derive(Debug, Clone, PartialEq)]
pub struct Completion {
    /// Relative derivative-array residual before and after (each row of `D`
    /// divided by the size of the terms that cancel in it, largest row).
    pub residual: (f64, f64),
    /// Levenberg–Marquardt iterations.
    pub iterations: usize,
    /// `|Δq⃛|∞`: how far the third derivatives moved.
    pub third_change: f64,
    /// Whether `q⃛` is fixed uniquely by `(q, q̇, q̈)`: the hidden constraints'
    /// Jacobian in `q⃛` has full rank `m` (see [`Completion::third_singular_values`]).
    pub third_unique: bool,
    /// Singular values of the hidden constraints' Jacobian in `q⃛`, largest
    /// first, relative to the largest singular value of their Jacobian in
    /// all of `z` (see [`third_determination`]); `m` values (zeros where
    /// there are fewer hidden constraints than `m`). Empty if `q⃛` was held
    /// fixed.
    pub third_singular_values: Vec<f64>,
}

/// Singular values below this fraction of the largest are dropped from a
/// Levenberg–Marquardt step (directions that no data determine, e.g. where
/// the hidden constraints do not involve `q⃛`): a few hundred round-offs.
const STEP_TRUNCATION: f64 = 1e-13;

/// Scale of each row of the derivative array: `1 + Σ_j |∂D_l/∂d_j · d_j|`,
/// the size of the terms that cancel in it.
pub(crate) fn row_scales(jac: &DMatrix<f64>, d: &[f64], scales: &mut [f64]) {
    for (l, sc) in scales.iter_mut().enumerate() {
        *sc = 1.0
            + (0..d.len())
                .map(|j| (jac[(l, j)] * d[j]).abs())
                .sum::<f64>();
    }
}

/// `max_l |v_l / scales_l|`: the largest residual relative to its row's scale.
pub(crate) fn relative(v: &[f64], scales: &[f64]) -> f64 {
    v.iter()
        .zip(scales)
        .fold(0.0f64, |a, (x, s)| a.max((x / s).abs()))
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
/// Levenberg–Marquardt on the row-scaled residual, in unknowns scaled by
/// `max(1, |d_j|)`, with minimum-norm steps in the (underdetermined)
/// unknowns. The step is formed from the singular value decomposition of the
/// scaled Jacobian (filter factors `σ/(σ² + μσ₁²)`), never from the normal
/// matrix `J Jᵀ`, whose condition number is the square of `J`'s: for the
/// sleigh with `J = 2501 m²` the scaled Jacobian has condition ~4e8, so
/// `J Jᵀ` (~1e17) carried no digits and the iteration stalled at a relative
/// residual of ~5e-10 while moving `q⃛` by 1e-2 away from consistent data.
/// The hidden constraints can be nonlinear in `q⃛` (quadratic for the sleigh),
/// so a far starting guess may fail; the error then says so.
///
/// With `move_third`, the result also says whether `q⃛` is determined by
/// `(q, q̇, q̈)` ([`third_determination`]); where it is not (the sleigh at
/// zero turning rate), the completion's `q⃛` is one point of a family and
/// only given third derivatives fix the motion.
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
    let mut cols = vec![1.0; unknowns];
    let third_before: Vec<f64> = d[3 * m..4 * m].to_vec();
    derivative_array(scene, e, t, d, &[], &mut value, &mut jac);
    row_scales(&jac, d, &mut scales);
    // Scales are frozen at the start of each iteration so that the objective
    // compared by the damping logic does not move under it.
    let objective =
        |v: &[f64], sc: &[f64]| v.iter().zip(sc).map(|(x, s)| (x / s).powi(2)).sum::<f64>();
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
                "the hidden constraints could not be satisfied{}: relative derivative-array \
                 residual {res:.3e} after {MAX_ITER} iterations (tolerance {rtol:.1e})",
                unreachable_text(&jac, &value, &scales, first, move_third)
            ));
        }
        iterations += 1;
        // Row-scaled, column-scaled Jacobian in the unknowns and its SVD.
        for (k, c) in cols.iter_mut().enumerate() {
            *c = d[first + k].abs().max(1.0);
        }
        let js = DMatrix::from_fn(rows, unknowns, |l, k| {
            jac[(l, first + k)] * cols[k] / scales[l]
        });
        let rs = DVector::from_fn(rows, |l, _| value[l] / scales[l]);
        let current = objective(&value, &scales);
        let svd = svd_of(js, true, true)?;
        let (u, vt) = (
            svd.u.as_ref().expect("u requested"),
            svd.v_t.as_ref().expect("v_t requested"),
        );
        let sv = &svd.singular_values;
        let top = sv.max();
        let utr = u.tr_mul(&rs);
        // Damping relative to σ₁²; it shrinks tenfold after each success and
        // may vanish (pure Gauss–Newton), since a floor comparable to a small
        // σ² slows convergence to linear.
        let mut accepted = false;
        for _ in 0..30 {
            // Minimum-norm damped step in the scaled unknowns:
            // Δ = Σ v_i σ_i/(σ_i² + μσ₁²) (u_iᵀ r).
            trial.copy_from_slice(d);
            for (i, &s) in sv.iter().enumerate() {
                if s <= STEP_TRUNCATION * top {
                    continue;
                }
                let f = s / (s * s + mu * top * top) * utr[i];
                for k in 0..unknowns {
                    trial[first + k] -= f * vt[(i, k)] * cols[k];
                }
            }
            derivative_array(scene, e, t, &trial, &[], &mut trial_value, &mut trial_jac);
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
            "the hidden constraints could not be satisfied{}: relative derivative-array residual \
             {res:.3e} (tolerance {rtol:.1e})",
            unreachable_text(&jac, &value, &scales, first, move_third)
        ));
    }
    let (third_unique, third_singular_values) = if move_third {
        let sv = third_determination(&jac, d, m)?;
        let unique = sv.last().is_some_and(|&s| s > RANK_TOL);
        (unique, sv)
    } else {
        (true, Vec::new())
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
        third_singular_values,
    })
}

/// Why a completion failed: " from this starting guess" when the linearised
/// problem can still remove the residual, or, when most of the row-scaled
/// residual lies outside the range of `∂D/∂(unknowns)` (the combinations of
/// `[E; Ė; Ë]` that the unknowns cannot change at all), that the fixed data
/// themselves violate a hidden constraint, with the fraction.
fn unreachable_text(
    jac: &DMatrix<f64>,
    value: &[f64],
    scales: &[f64],
    first: usize,
    move_third: bool,
) -> String {
    let (rows, unknowns) = (jac.nrows(), jac.ncols() - first);
    let js = DMatrix::from_fn(rows, unknowns, |l, k| jac[(l, first + k)] / scales[l]);
    let rs = DVector::from_fn(rows, |l, _| value[l] / scales[l]);
    let Ok(svd) = svd_of(js, true, false) else {
        return String::new();
    };
    let u = svd.u.as_ref().expect("u requested");
    let top = svd.singular_values.max();
    let mut reachable = DVector::zeros(rows);
    for (i, &s) in svd.singular_values.iter().enumerate() {
        if s > STEP_TRUNCATION * top {
            let c = u.column(i).dot(&rs);
            reachable.axpy(c, &u.column(i), 1.0);
        }
    }
    let total = rs.norm();
    let fraction = if total > 0.0 {
        (&rs - reachable).norm() / total
    } else {
        0.0
    };
    if fraction < 0.5 {
        return " from this starting guess".into();
    }
    if !move_third {
        return format!(
            " with q⃛ held fixed: {:.0}% of the row-scaled residual lies in the combinations of \
             [E; Ė; Ë] that q⁗, q⁽⁵⁾, q⁽⁶⁾ cannot change (the hidden constraints)",
            100.0 * fraction
        );
    }
    format!(
        ": the given (q, q̇, q̈) violate a hidden constraint that does not involve q⃛ here \
         ({:.0}% of the row-scaled residual lies outside the range of \
         ∂[E; Ė; Ë]/∂(q⃛, q⁗, q⁽⁵⁾, q⁽⁶⁾); for the sleigh at turning rate ω = 0 the first hidden \
         constraint fixes the tangential acceleration u̇ = g sin α cos φ)",
        100.0 * fraction
    )
}

/// How well the hidden constraints determine `q⃛` at `d` (7m numbers, `jac`
/// its derivative-array Jacobian): the singular values of `Hᵀ ∂D/∂q⃛`,
/// `H` an orthonormal basis of the left null space of `∂D/∂u` (the
/// combinations of `[E; Ė; Ë]` free of `q⁗, q⁽⁵⁾, q⁽⁶⁾`: the hidden
/// constraints), relative to the largest singular value of `Hᵀ ∂D/∂z`; all on
/// the balanced Jacobian (rows by term size, columns by `max(1, |d_j|)`). `m` values, largest first; the
/// ones beyond the number of hidden constraints are 0. `q⃛` is fixed by
/// `(q, q̇, q̈)` where the smallest exceeds [`RANK_TOL`].
///
/// For the sleigh (`q_I = (x, y)`, speed `u`, heading `φ`, turning rate
/// `ω = φ̇`, `g_s = g sin α`, paper's potential) the two hidden constraints
/// are, in the tangential/normal parts of (19) and its derivative,
///
/// ```text
/// h₁ = g_s cos φ − u̇ − J ω φ̈ / u
/// h₂ = ü + 2 g_s ω sin φ + u ω² + J φ̈² / u
/// ```
///
/// with `φ̈ = (n̂·q⃛ − 2u̇ω)/u`, `ü = t̂·q⃛ + uω²`. Their Jacobian in
/// `(φ̈, ü)` is `[[−Jω/u, 0], [2Jφ̈/u, 1]]`, determinant `−Jω/u`: at `ω = 0`
/// it has rank 1, `h₁` no longer involves `q⃛` (it fixes `u̇ = g_s cos φ`
/// instead) and `φ̈` — C's `λ(0)` — is free.
pub fn third_determination(jac: &DMatrix<f64>, d: &[f64], m: usize) -> Result<Vec<f64>, String> {
    let b = balanced(jac, d);
    let rows = b.nrows();
    let bu = b.view((0, 4 * m), (rows, 3 * m)).clone_owned();
    let mut bu_sq = DMatrix::zeros(rows.max(3 * m), 3 * m);
    bu_sq.view_mut((0, 0), (rows, 3 * m)).copy_from(&bu);
    let svd = svd_of(bu_sq, true, false)?;
    let u = svd.u.expect("u requested");
    let sv = &svd.singular_values;
    let top = sv.max();
    // Left singular vectors of the rows' space with σ below the threshold.
    let null: Vec<usize> = (0..rows)
        .filter(|&i| i >= sv.len() || sv[i] <= RANK_TOL * top)
        .collect();
    let mut out = vec![0.0; m];
    if null.is_empty() {
        return Ok(out);
    }
    let h = DMatrix::from_fn(rows, null.len(), |l, k| u[(l, null[k])]);
    let hz = h.tr_mul(&b.view((0, 0), (rows, 4 * m)).clone_owned());
    let hq = hz.view((0, 3 * m), (null.len(), m)).clone_owned();
    let scale = svd_of(hz, false, false)?.singular_values.max();
    if scale == 0.0 {
        return Ok(out);
    }
    let mut s: Vec<f64> = svd_of(hq, false, false)?
        .singular_values
        .iter()
        .copied()
        .collect();
    s.sort_by(|x, y| y.total_cmp(x));
    for (o, v) in out.iter_mut().zip(s) {
        *o = v / scale;
    }
    Ok(out)
}
