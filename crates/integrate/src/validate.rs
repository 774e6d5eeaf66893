//! Checks of the initial data and of the settings every method reads.

use crate::Options;
use crate::explicit::control::all_finite;

/// Refuses a fixed step `h` that needs more than `max_steps` steps over
/// `[t0, t_end]` (checked before the first step, and by callers that
/// check their input before building a run).
pub fn fixed_step_budget(t0: f64, t_end: f64, h: f64, max_steps: usize) -> Result<(), String> {
    let steps = (t_end - t0) / h;
    if steps > max_steps as f64 {
        return Err(format!(
            "fixed_step = {h:e} over [{t0}, {t_end}] takes {steps:.3e} steps, more than the \
             step budget max_steps = {max_steps}"
        ));
    }
    Ok(())
}

/// Checks the initial data and options; the message says what is wrong.
pub(crate) fn validate(
    needs_fixed_step: bool,
    dim: usize,
    t0: f64,
    y0: &[f64],
    t_end: f64,
    opts: &Options,
) -> Result<(), String> {
    let positive = |x: f64| x > 0.0 && x.is_finite();
    if dim == 0 {
        return Err("the system has dimension 0".into());
    }
    if y0.len() != dim {
        return Err(format!(
            "y0 has length {} but the system has dimension {dim}",
            y0.len()
        ));
    }
    if !t0.is_finite() || !t_end.is_finite() {
        return Err(format!("t0 = {t0} and t_end = {t_end} must be finite"));
    }
    if t_end < t0 {
        return Err(format!(
            "t_end = {t_end} < t0 = {t0}: backward integration is not supported"
        ));
    }
    if !all_finite(y0) {
        return Err("y0 is not finite".into());
    }
    if !positive(opts.rtol) || !positive(opts.atol) {
        return Err(format!(
            "rtol = {} and atol = {} must be positive and finite",
            opts.rtol, opts.atol
        ));
    }
    if opts.rtol < RTOL_MIN {
        return Err(format!(
            "rtol = {:e} is below 100·ε = {RTOL_MIN:.2e}: double precision (ε = {:.2e}) \
             cannot deliver a relative accuracy finer than about that (rounding in the \
             stages and in t alone is of order ε per step); use rtol >= {RTOL_MIN:.2e}",
            opts.rtol,
            f64::EPSILON
        ));
    }
    if let Some(a) = &opts.atol_components {
        if a.len() != dim {
            return Err(format!(
                "atol_components has length {} but the system has dimension {dim}",
                a.len()
            ));
        }
        if let Some((i, v)) = a.iter().enumerate().find(|(_, v)| !positive(**v)) {
            return Err(format!(
                "atol_components[{i}] = {v} must be positive and finite"
            ));
        }
    }
    match opts.fixed_step {
        None if needs_fixed_step => return Err("this method needs Options::fixed_step".into()),
        Some(h) if !positive(h) => {
            return Err(format!("fixed_step = {h} must be positive and finite"));
        }
        // Refused before the first step rather than at the budget.
        Some(h) => fixed_step_budget(t0, t_end, h, opts.max_steps)?,
        _ => {}
    }
    for (name, v) in [("h_init", opts.h_init), ("h_max", opts.h_max)] {
        if let Some(h) = v {
            if !positive(h) {
                return Err(format!("{name} = {h} must be positive and finite"));
            }
        }
    }
    if let Some(s) = opts.max_wall_time_s {
        if s.is_nan() || s < 0.0 {
            return Err(format!("max_wall_time_s = {s} must be >= 0"));
        }
    }
    let mut prev = f64::NEG_INFINITY;
    for &tau in &opts.output {
        if !(tau >= t0 && tau <= t_end) {
            return Err(format!("output time {tau} lies outside [{t0}, {t_end}]"));
        }
        if tau <= prev {
            return Err(format!("output times must increase ({prev} then {tau})"));
        }
        prev = tau;
    }
    Ok(())
}

/// The smallest relative tolerance accepted: `100·ε ≈ 2.2e-14`.
pub(crate) const RTOL_MIN: f64 = 100.0 * f64::EPSILON;

/// The absolute tolerance of every component: `Options::atol_components`,
/// else `Options::atol` repeated (validated before).
pub(crate) fn atol_vector(opts: &Options, dim: usize) -> Vec<f64> {
    match &opts.atol_components {
        Some(a) => a.clone(),
        None => vec![opts.atol; dim],
    }
}
