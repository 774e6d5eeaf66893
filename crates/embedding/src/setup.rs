//! A's initial data, in named steps: the given derivatives, away from the
//! map's singular set, the dependent coordinates checked against the map,
//! the hidden constraints satisfied to round-off, and the structure found
//! there (rank of `W`, hidden constraints, free data).
//!
//! The result is a consistent point `d = (q_I⁽⁰⁾ … q_I⁽⁶⁾)` (7m numbers)
//! from which both forms start.

use nonholo_core::Error;
use nonholo_core::init::Initial;
use nonholo_core::scene::{EmbeddingInfo, Scene};

use crate::analysis::{Completion, RANK_TOL, Structure, complete, structure};
use crate::elo::reconstruct;

/// Relative tolerance to which initial data are made consistent with the
/// hidden constraints (round-off level of the derivative array's terms).
pub const HIDDEN_RTOL: f64 = 1e-14;

/// Relative residual of the hidden constraints above which given third
/// derivatives are refused as inconsistent (rather than refined).
pub const HIDDEN_CHECK_RTOL: f64 = 1e-8;

/// What the set-up of A's initial data found and did.
#[derive(Debug, Clone, PartialEq)]
pub struct InitReport {
    pub structure: Structure,
    /// The completion or check of the hidden constraints.
    pub completion: Completion,
    /// Whether `q⃛_I(0)` was given (else computed from the hidden constraints).
    pub third_given: bool,
    /// `map value − given value` of each dependent coordinate (0 unless
    /// `branch = map` moved it).
    pub branch_shift: Vec<f64>,
}

/// Initial data that contradict A's own equations.
pub(crate) fn inconsistent(reason: String) -> Error {
    Error::InconsistentInit {
        formulation: crate::INFO.name,
        reason,
    }
}

/// Names of the derivatives A accepts in `--init` for coordinate `c`.
pub(crate) fn derivative_name(c: &str, order: usize) -> String {
    match order {
        2 => format!("{c}_ddot"),
        3 => format!("{c}_dddot"),
        _ => unreachable!("only second and third derivatives are initial data"),
    }
}

/// The names of the derivatives of order `order` of the independent coordinates.
fn derivative_names<S: Scene>(scene: &S, e: &EmbeddingInfo, order: usize) -> Vec<String> {
    let coords = scene.info().coordinates;
    e.independent
        .iter()
        .map(|&i| derivative_name(coords[i].name, order))
        .collect()
}

/// A consistent point for `init` (which gives `q, q̇` and the second, and
/// possibly the third, derivatives of the independent coordinates), with
/// the report of what was found. `branch_map` accepts dependent coordinates
/// on another branch of the map; `singular_tol` is the distance from the
/// map's singular set below which A cannot start.
pub fn consistent_start<S: Scene>(
    scene: &S,
    init: &Initial,
    branch_map: bool,
    singular_tol: f64,
) -> Result<(Vec<f64>, InitReport), Error> {
    let e = scene.info().embedding.expect("checked by applicable");
    let (mut d, third_given) = given_derivatives(scene, &e, init)?;
    away_from_singular_set(scene, &e, init.t0, &d, singular_tol)?;
    let branch_shift = dependent_coordinates(scene, &e, init, &d, branch_map)?;
    let completion = hidden_constraints(scene, &e, init.t0, &mut d, third_given)?;
    let structure = structure(scene, &e, init.t0, &d).map_err(inconsistent)?;
    Ok((
        d,
        InitReport {
            structure,
            completion,
            third_given,
            branch_shift,
        },
    ))
}

/// `d` with `q_I, q̇_I` and the given `q̈_I` (and `q⃛_I`, if given); whether
/// `q⃛_I` was given.
fn given_derivatives<S: Scene>(
    scene: &S,
    e: &EmbeddingInfo,
    init: &Initial,
) -> Result<(Vec<f64>, bool), Error> {
    let m = e.independent.len();
    let mut d = vec![0.0; 7 * m];
    for (k, &i) in e.independent.iter().enumerate() {
        d[k] = init.q[i];
        d[m + k] = init.qd[i];
    }
    let value =
        |names: &[String]| -> Vec<Option<f64>> { names.iter().map(|n| init.extra(n)).collect() };
    let second_names = derivative_names(scene, e, 2);
    let second = value(&second_names);
    if second.iter().any(Option::is_none) {
        return Err(Error::MissingInit {
            formulation: crate::INFO.letter,
            needs: "q̈_I(0)".into(),
            names: second_names,
            hint: Some("or `lambda`, from which they are matched with the vakonomic motion".into()),
        });
    }
    let third = value(&derivative_names(scene, e, 3));
    let third_given = third.iter().all(Option::is_some);
    if third.iter().any(Option::is_some) && !third_given {
        return Err(inconsistent(
            "give every third derivative of the independent coordinates, or none".into(),
        ));
    }
    for k in 0..m {
        d[2 * m + k] = second[k].expect("checked");
        if third_given {
            d[3 * m + k] = third[k].expect("checked");
        }
    }
    Ok((d, third_given))
}

/// Refuses a start within `singular_tol` of the map's singular set, where
/// the map has no value and nothing of A can be evaluated.
fn away_from_singular_set<S: Scene>(
    scene: &S,
    e: &EmbeddingInfo,
    t0: f64,
    d: &[f64],
    singular_tol: f64,
) -> Result<(), Error> {
    let m = e.independent.len();
    let mut r = [0.0; nonholo_core::scene::MAX_SINGULAR];
    let p = scene.embedding_singularity(t0, &d[..m], &d[m..2 * m], &mut r);
    let size = nonholo_core::guard::magnitude(&r, p);
    if p > 0 && (size.is_nan() || size <= singular_tol) {
        return Err(inconsistent(format!(
            "the initial state lies within singular_tol = {singular_tol:.1e} of the singular set \
             of the embedding map {} — {} (|r| = {size:.3e}), where A stops: start it further \
             away (or with a smaller singular_tol)",
            e.formula, e.singular_set
        )));
    }
    Ok(())
}

/// The dependent coordinates are the map's: checks the given ones against
/// it (and their rates against eq. 15; of a cyclic coordinate only its rate,
/// which is what the map gives); returns `map − given` per dependent
/// coordinate (of a cyclic one, of its rate; non-zero only with
/// `branch_map`).
fn dependent_coordinates<S: Scene>(
    scene: &S,
    e: &EmbeddingInfo,
    init: &Initial,
    d: &[f64],
    branch_map: bool,
) -> Result<Vec<f64>, Error> {
    let m = e.independent.len();
    let info = scene.info();
    let coords = info.coordinates;
    let (mut q, mut qd) = (vec![0.0; info.n()], vec![0.0; info.n()]);
    reconstruct(
        scene,
        e,
        init.t0,
        &d[..m],
        &d[m..2 * m],
        &d[2 * m..3 * m],
        &[],
        &mut q,
        &mut qd,
    );
    let mut branch_shift = Vec::new();
    for &i in e.dependent {
        if e.cyclic.contains(&i) {
            // Only the rate is the map's; the coordinate itself is free.
            let dd = qd[i] - init.qd[i];
            if dd.abs() > 1e-8 * (1.0 + init.qd[i].abs()) && !branch_map {
                return Err(inconsistent(format!(
                    "the embedding map {} gives {}_dot = {:.12} but {}_dot = {} was given \
                     (difference {dd:.6}); {} — pass --option branch=map to study that branch",
                    e.formula, coords[i].name, qd[i], coords[i].name, init.qd[i], e.branch_note
                )));
            }
            branch_shift.push(dd);
            continue;
        }
        let mut diff = q[i] - init.q[i];
        if coords[i].unit == "rad" {
            diff -= (diff / std::f64::consts::TAU).round() * std::f64::consts::TAU;
        }
        if diff.abs() > 1e-9 * (1.0 + init.q[i].abs()) && !branch_map {
            return Err(inconsistent(format!(
                "the embedding map {} gives {} = {:.12} but {} = {} was given (difference \
                 {diff:.6}); {} — pass --option branch=map to study that branch",
                e.formula, coords[i].name, q[i], coords[i].name, init.q[i], e.branch_note
            )));
        }
        branch_shift.push(diff);
        let dd = qd[i] - init.qd[i];
        if dd.abs() > 1e-8 * (1.0 + init.qd[i].abs()) {
            return Err(inconsistent(format!(
                "{}_dot = {} does not match the embedding map's rate {:.12} for the given \
                 second derivatives (eq. 15)",
                coords[i].name, init.qd[i], qd[i]
            )));
        }
    }
    Ok(branch_shift)
}

/// Satisfies A's hidden constraints to round-off, moving `q⃛` (unless it
/// was given) and the derivatives beyond it in `d`.
///
/// Given `q⃛` is first checked (only the derivatives beyond it may move);
/// then, given or not, `q⃛` is moved onto A's own constraint manifold to
/// round-off: data consistent to another formulation's round-off (C's
/// Taylor coefficients) are not consistent enough for an index-3 system,
/// where an inconsistency δ forces corrections of order δ/h² in the first
/// steps. The completion starts from the check's derivatives beyond `q⃛`,
/// so that its minimum-norm steps move `q⃛` only by what the given data
/// lack: where `q⃛` is not determined by `(q, q̇, q̈)`, steps that also had
/// to find `q⁗ … q⁽⁶⁾` from scratch would move `q⃛` along the free
/// direction, to another motion.
fn hidden_constraints<S: Scene>(
    scene: &S,
    e: &EmbeddingInfo,
    t0: f64,
    d: &mut [f64],
    third_given: bool,
) -> Result<Completion, Error> {
    let m = e.independent.len();
    let mut checked = None;
    if third_given {
        let mut check = d.to_vec();
        let c = complete(scene, e, t0, &mut check, false, HIDDEN_CHECK_RTOL).map_err(|msg| {
            inconsistent(format!(
                "the given third derivatives violate the hidden constraints of A: {msg}; \
                 omit them to have them computed"
            ))
        })?;
        // The check stops at HIDDEN_CHECK_RTOL; where the given data allow
        // it, solve for the derivatives beyond q⃛ to round-off, so that the
        // completion below has only the data's own inconsistency left.
        let mut refined = check.clone();
        if complete(scene, e, t0, &mut refined, false, HIDDEN_RTOL).is_ok() {
            check = refined;
        }
        d.copy_from_slice(&check);
        checked = Some(c);
    }
    let completion = complete(scene, e, t0, d, true, HIDDEN_RTOL).map_err(inconsistent)?;
    let sv_text = |c: &Completion| {
        c.third_singular_values
            .iter()
            .map(|v| format!("{v:.3e}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if !third_given && !completion.third_unique {
        return Err(inconsistent(format!(
            "q⃛_I(0) is not determined by (q, q̇, q̈) at this state: the hidden constraints' \
             Jacobian in q⃛ has singular values [{}] relative to their gradient in \
             (q, q̇, q̈, q⃛) (rank < {m}, threshold {RANK_TOL:.0e}), so the completion's q⃛ is \
             one point of a family of motions; {}. Give the third derivatives ({}) or `lambda`",
            sv_text(&completion),
            e.undetermined_note,
            derivative_names(scene, e, 3).join(", ")
        )));
    }
    let third_scale = d[3 * m..4 * m].iter().fold(1.0f64, |a, v| a.max(v.abs()));
    if let Some(check) = checked
        && completion.third_change > 1e-6 * third_scale
    {
        return Err(inconsistent(format!(
            "the given third derivatives satisfy A's hidden constraints to {:.3e} relative, \
             but making them consistent to {HIDDEN_RTOL:.0e} moved them by {:.3e} \
             (max(1, |q⃛|) = {third_scale:.3e}): q⃛ is ill-determined here (singular values \
             of the hidden constraints' Jacobian in q⃛, relative to their gradient in \
             (q, q̇, q̈, q⃛): [{}])",
            check.residual.1,
            completion.third_change,
            sv_text(&completion)
        )));
    }
    Ok(completion)
}
