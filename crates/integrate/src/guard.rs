//! The guard watch: a sign change of [`crate::OdeSystem::guard`] across an
//! accepted step, located on the step polynomial.

use crate::dense::eval_nested;

/// Watches the guard across an accepted step `[t_old, t]` of size `h =
/// t − t_old` whose polynomial (nested form of [`crate::Dense`], `ncoef` vectors of
/// length `y.len()`) is `coef`, `(t, y)` being the state after
/// `after_step`. `g_prev` holds the guard at the step start (`None`: no
/// guard, nothing is evaluated).
///
/// If the guard changed from `> 0` to `<= 0` (or NaN), the crossing is located on
/// the polynomial (Illinois iteration to `~1e-14` relative in `t`): its
/// time is returned and the state there written into `y_root` (`y` itself
/// when it is the step end). Otherwise `g_prev` takes the new value (kept
/// if the guard returned `None`). `buf` is a workspace.
#[allow(clippy::too_many_arguments)]
pub(crate) fn guard_crossing(
    mut guard: impl FnMut(f64, &[f64]) -> Option<f64>,
    g_prev: &mut Option<f64>,
    coef: &[f64],
    ncoef: usize,
    t_old: f64,
    t: f64,
    h: f64,
    y: &[f64],
    y_root: &mut [f64],
    buf: &mut [f64],
) -> Option<f64> {
    let gp = (*g_prev)?;
    let gn = guard(t, y)?;
    // A NaN guard counts as not positive: a guard that can no longer be
    // evaluated stops the run rather than switching itself off.
    let crossed = gp > 0.0 && (gn <= 0.0 || gn.is_nan());
    if !crossed {
        *g_prev = Some(gn);
        return None;
    }
    let dim = y.len();
    let g = |s: f64| {
        eval_nested(coef, dim, ncoef, s, buf);
        guard(t_old + s * h, buf).unwrap_or(f64::NAN)
    };
    let tol_t = (1e-14 * t_old.abs().max(t.abs())).max(4.0 * f64::EPSILON * h);
    let s = locate_root(g, gp, gn, tol_t / h);
    Some(if s >= 1.0 {
        y_root.copy_from_slice(y);
        t
    } else {
        eval_nested(coef, dim, ncoef, s, y_root);
        t_old + s * h
    })
}

/// Illinois iteration for a zero of `g(s)` on `[0, 1]` with `g(0) = ga > 0 >= g(1) = gb`.
/// Returns `s` with `g(s) <= 0` (or NaN) within `tol` of the last `s` with `g > 0`.
pub(crate) fn locate_root(
    mut g: impl FnMut(f64) -> f64,
    mut ga: f64,
    mut gb: f64,
    tol: f64,
) -> f64 {
    let (mut a, mut b) = (0.0_f64, 1.0_f64);
    // Which end moved last: +1 for a, -1 for b.
    let mut side = 0;
    for _ in 0..200 {
        if b - a <= tol || gb == 0.0 {
            break;
        }
        let mut s = b - gb * (b - a) / (gb - ga);
        if !(s > a && s < b) {
            s = 0.5 * (a + b);
        }
        let gs = g(s);
        if gs > 0.0 {
            a = s;
            ga = gs;
            if side == 1 {
                gb *= 0.5;
            }
            side = 1;
        } else {
            b = s;
            gb = gs;
            if side == -1 {
                ga *= 0.5;
            }
            side = -1;
        }
    }
    b
}
