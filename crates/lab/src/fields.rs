//! The settings of a run and of a sweep, checked in one place for the
//! command line and for experiment files: the same ranges and the same
//! reasons, whichever way a value arrives.
//!
//! Every check returns the value or the reason it is refused; the caller
//! names the field, as the user wrote it: the flag (`--rtol: …`) or the key
//! of the experiment file with its file and line
//! (`experiments/x.toml:31: \`formulation.rtol\`: …`). docs/cli.md lists
//! the ranges.

use nonholo_core::integrate::{Method, RadauDense, RadauNewton};

/// Smallest relative tolerance: below ~100 ε double precision cannot
/// deliver what is asked, and a result file would claim it did.
pub const MIN_RTOL: f64 = 100.0 * f64::EPSILON;

/// Smallest absolute tolerance. Below it the weighted norms of the step
/// size control, `(f / atol)²`, overflow for derivatives of order `1e54`:
/// the run would fail at its first step with "not finite".
pub const MIN_ATOL: f64 = 1e-100;

/// Largest absolute tolerance (symmetric to [`MIN_ATOL`]).
pub const MAX_ATOL: f64 = 1e100;

/// Most output points a run may ask for (each is a row of the result).
pub const MAX_OUTPUT_POINTS: f64 = 1e6;

/// Most points a sweep may have: each is a file and a set of runs, and the
/// whole sweep is checked before anything runs.
pub const MAX_SWEEP_POINTS: usize = 100_000;

/// Most worker threads.
pub const MAX_THREADS: usize = 1024;

/// Most values in a work-precision ladder.
pub const MAX_LADDER: usize = 100;

/// A number for a message: plain digits in the usual range, exponent
/// notation otherwise (`1e-320`, not three hundred digits).
pub fn num(v: f64) -> String {
    nonholo_core::num(v)
}

/// The first name of `names` that repeats an earlier one.
pub fn repeated(names: &[String]) -> Option<&String> {
    names
        .iter()
        .enumerate()
        .find_map(|(i, n)| names[..i].contains(n).then_some(n))
}

pub fn positive_finite(v: f64) -> Result<f64, String> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!("must be a positive finite number, got {}", num(v)))
    }
}

/// Shortest time span: with less, the default output spacing (a
/// hundredth of the span) and the step sizes leave the normal range of
/// doubles.
pub const MIN_T_END: f64 = 1e-100;

/// End of the time span (`--t-end`, `time.t_end`): finite, at least
/// [`MIN_T_END`].
pub fn t_end(v: f64) -> Result<f64, String> {
    let v = positive_finite(v)?;
    if v < MIN_T_END {
        return Err(format!(
            "{} is shorter than the shortest span, {MIN_T_END:e}",
            num(v)
        ));
    }
    Ok(v)
}

/// Spacing of the output grid over `[0, t_end]` (`--output-every`,
/// `time.output_every`): positive, at most [`MAX_OUTPUT_POINTS`] points.
pub fn output_every(v: f64, t_end: f64) -> Result<f64, String> {
    let v = positive_finite(v)?;
    let count = (t_end / v).floor();
    if count.is_nan() || count > MAX_OUTPUT_POINTS {
        return Err(format!(
            "{} over [0, t_end = {}] gives {count:.3e} output points (limit {MAX_OUTPUT_POINTS:e})",
            num(v),
            num(t_end)
        ));
    }
    Ok(v)
}

/// Relative tolerance (`--rtol`, `rtol`, a ladder's `tolerances`):
/// `[MIN_RTOL, 1)`.
pub fn rtol(v: f64) -> Result<f64, String> {
    let v = positive_finite(v)?;
    if v < MIN_RTOL {
        Err(format!(
            "{} is below what double precision can deliver (at least {MIN_RTOL:.1e})",
            num(v)
        ))
    } else if v >= 1.0 {
        Err(format!(
            "{} is not below 1: a relative tolerance of 1 or more controls nothing",
            num(v)
        ))
    } else {
        Ok(v)
    }
}

/// Absolute tolerance (`--atol`, `atol`): `[MIN_ATOL, MAX_ATOL]`.
pub fn atol(v: f64) -> Result<f64, String> {
    let v = positive_finite(v)?;
    if !(MIN_ATOL..=MAX_ATOL).contains(&v) {
        return Err(format!(
            "{} lies outside [{MIN_ATOL:e}, {MAX_ATOL:e}] (below, the step size control's \
             weighted norms overflow)",
            num(v)
        ));
    }
    Ok(v)
}

/// Fixed step size (`--step`, `step`).
pub fn step(v: f64) -> Result<f64, String> {
    positive_finite(v)
}

/// Budget on trial steps (`--max-steps`, `max_steps`): at least 1.
pub fn max_steps(v: u64) -> Result<usize, String> {
    if v == 0 {
        return Err("must be at least 1".into());
    }
    Ok(usize::try_from(v).unwrap_or(usize::MAX))
}

/// Budget on wall-clock time in seconds (`--max-wall-time`, `max_wall_time`).
pub fn max_wall_time(v: f64) -> Result<f64, String> {
    positive_finite(v)
}

/// Worker threads (`--threads`): `1..=MAX_THREADS`.
pub fn threads(n: usize) -> Result<usize, String> {
    if (1..=MAX_THREADS).contains(&n) {
        Ok(n)
    } else {
        Err(format!("must be between 1 and {MAX_THREADS}, got {n}"))
    }
}

/// The integrator called `name` (`--integrator`, `integrator`).
pub fn method(name: &str) -> Result<Method, String> {
    Method::from_name(name).ok_or_else(|| {
        format!(
            "unknown integrator `{name}`; valid names: {}",
            Method::ALL.map(|m| m.name()).join(", ")
        )
    })
}

/// The Newton iteration of Radau IIA called `name` (`--radau-newton`,
/// `radau_newton`).
pub fn radau_newton(name: &str) -> Result<RadauNewton, String> {
    RadauNewton::from_name(name).ok_or_else(|| {
        format!("unknown Radau Newton iteration `{name}`; valid: auto, simplified, full")
    })
}

/// The continuous extension of Radau IIA called `name` (`--radau-dense`,
/// `radau_dense`).
pub fn radau_dense(name: &str) -> Result<RadauDense, String> {
    RadauDense::from_name(name).ok_or_else(|| {
        format!("unknown Radau continuous extension `{name}`; valid: auto, collocation, hermite")
    })
}

/// RADAU5's `THET` (`--radau-jacobian-reuse`, `radau_jacobian_reuse`): the
/// Jacobian is kept after a Newton contraction rate at most this; negative
/// asks for a new one every step. Finite and below 1.
pub fn radau_jacobian_reuse(v: f64) -> Result<f64, String> {
    if v.is_finite() && v < 1.0 {
        Ok(v)
    } else {
        Err(format!(
            "{v} must be a finite number below 1 (the Newton contraction rate up to which \
             the Jacobian is kept; negative: a new Jacobian every step)"
        ))
    }
}

/// RADAU5's `FNEWT` (`--radau-newton-tol`, `radau_newton_tol`): the
/// Newton iteration stops when its estimated remaining error, in the
/// error scale, is at most this. Positive and below 1.
pub fn radau_newton_tol(v: f64) -> Result<f64, String> {
    if v > 0.0 && v < 1.0 {
        Ok(v)
    } else {
        Err(format!(
            "{v} must be a number between 0 and 1, exclusive (the Newton iteration's \
             stopping test, in units of the error scale; RADAU5's FNEWT)"
        ))
    }
}

/// Whether a tolerance given with a fixed step would be ignored: an explicit
/// method with a fixed step has no error control (Radau IIA still uses
/// `rtol` and `atol` for its Newton iteration). The reason names `step_field`.
pub fn tolerance_with_step(method: Method, step_field: &str) -> Result<(), String> {
    if method.is_implicit() {
        Ok(())
    } else {
        Err(format!(
            "has no effect with {step_field}: {} with a fixed step has no error control \
             (give one or the other)",
            method.name()
        ))
    }
}

/// Points of a sweep (`sweep.samples`, the product of a grid's axis
/// lengths): `1..=MAX_SWEEP_POINTS`. `None`: the count overflowed.
pub fn sweep_points(n: Option<u64>) -> Result<usize, String> {
    match n {
        Some(n) if n >= 1 && n <= MAX_SWEEP_POINTS as u64 => Ok(n as usize),
        Some(0) => Err("the sweep has no point".into()),
        Some(n) => Err(format!(
            "{n} sweep points is more than the limit of {MAX_SWEEP_POINTS}"
        )),
        None => Err(format!(
            "the sweep has more points than can be counted (limit {MAX_SWEEP_POINTS})"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_in_messages_stay_short() {
        assert_eq!(num(0.3), "0.3");
        assert_eq!(num(2.0), "2");
        assert_eq!(num(1e-320), "1e-320");
        assert_eq!(num(1e300), "1e300");
        assert_eq!(num(-1e-6), "-1e-6");
        assert_eq!(num(f64::NAN), "NaN");
    }

    #[test]
    fn ranges() {
        assert!(rtol(1e-10).is_ok());
        assert!(rtol(1e-20).unwrap_err().contains("double precision"));
        assert!(rtol(1e300).unwrap_err().contains("not below 1"));
        assert!(rtol(-1e-6).unwrap_err().contains("positive"));
        assert!(atol(1e-320).unwrap_err().contains("1e-320"));
        assert!(atol(1e-12).is_ok());
        assert!(max_steps(0).is_err());
        assert!(threads(0).is_err());
        assert_eq!(sweep_points(Some(42)), Ok(42));
        assert!(sweep_points(Some(u64::MAX)).is_err());
        assert!(sweep_points(None).is_err());
        assert!(
            output_every(1e-300, 10.0)
                .unwrap_err()
                .contains("limit 1e6")
        );
    }
}
