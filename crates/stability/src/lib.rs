//! Linearisation about steady motions, for any formulation whose state
//! begins with `(q, q̇)` (B, C, Gauss, the realisations).
//!
//! A steady motion (relative equilibrium) has its cyclic coordinates moving
//! uniformly and everything else at rest. The linearisation
//! (docs/stability.md) takes three steps, all exact up to rounding:
//!
//! 1. **Jacobian.** `J = ∂f/∂y` of the formulation's right-hand side at the
//!    state, by automatic differentiation (the model's own Jacobian).
//! 2. **Reduction to the constraint manifold.** A formulation that keeps
//!    `f = ḟ = g = 0` along every motion has its motions on that manifold.
//!    The rows of the Jacobian `D` of `(f, ḟ, g)` with respect to `y` are
//!    solved for as many dependent components — positions for `f`,
//!    velocities for `ḟ` and `g`, chosen by pivoting — and the other
//!    components `z` chart the manifold: `y(z)` on it with `∂y/∂z = E`,
//!    `D E = 0`. On the manifold the motion is `ż = P f(y(z))`, `P`
//!    selecting the independent components, whose Jacobian at `y*` is
//!    `J_z = P J E`.
//! 3. **Quotient by the cyclic coordinates.** An independent coordinate on
//!    which no other remaining component's rate depends (its column of
//!    `J_z` vanishes off the diagonal and on it) is cyclic at this motion
//!    (tested at `y*`, not along the orbit: the scenes' cyclic coordinates
//!    are symmetries of their Lagrangians and constraints by construction):
//!    with it ordered last, `J_z` is block triangular, its own eigenvalue is
//!    zero, and it is dropped. Repeated until none is left (the bicycle's
//!    `x`, `y` go first, then its heading `ψ`, whose only influence was on
//!    them).
//!
//! What remains is the essential dynamics; its eigenvalues and eigenvectors
//! (faer's dense eigendecomposition) are the result.

use faer::c64;
use nalgebra::DMatrix;
use nonholo_core::{Error, Initial, Model};

/// Choices and tolerances of a linearisation.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// State components (`phi_dot`, ...) to keep independent where the
    /// constraints leave a choice (the others are picked by pivoting).
    pub independent: Vec<String>,
    /// Largest rate allowed of an essential component at a steady motion,
    /// in its units per second.
    pub steady_tol: f64,
    /// Relative size (to the largest entry of the reduced matrix) below
    /// which a column counts as zero when cyclic coordinates are found.
    pub zero_tol: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            independent: Vec::new(),
            steady_tol: 1e-8,
            zero_tol: 1e-11,
        }
    }
}

/// One eigenvalue of the essential dynamics with its eigenvector.
#[derive(Debug, Clone, PartialEq)]
pub struct Mode {
    /// The eigenvalue (1/s).
    pub value: c64,
    /// The eigenvector over the essential components, scaled so that its
    /// largest component is 1.
    pub vector: Vec<c64>,
}

/// The linearisation of a formulation about a steady motion.
#[derive(Debug, Clone)]
pub struct Linearisation {
    /// Time of the state.
    pub t: f64,
    /// The formulation's state `y*` at the steady motion.
    pub state: Vec<f64>,
    /// Names of the essential components (rows and columns of `matrix`).
    pub names: Vec<String>,
    /// The essential dynamics: `ż = A z` for perturbations `z` of the
    /// essential components.
    pub matrix: DMatrix<f64>,
    /// `dim × m`: the perturbation of the full state `y` that a unit
    /// perturbation of each essential component stands for (on the
    /// constraint manifold, dependent components following).
    pub basis: DMatrix<f64>,
    /// Eigenvalues, by decreasing real part (then decreasing imaginary part).
    pub modes: Vec<Mode>,
    /// The coordinates found cyclic and quotiented out, with their rates
    /// (their uniform motion along the steady motion).
    pub cyclic: Vec<(String, f64)>,
    /// Components of `y` eliminated by the constraints.
    pub dependent: Vec<String>,
    /// Largest rate of an essential component at the state (zero at an
    /// exact steady motion).
    pub residual: f64,
}

impl Linearisation {
    /// Index of essential component `name`.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// The eigenvalues.
    pub fn eigenvalues(&self) -> Vec<c64> {
        self.modes.iter().map(|m| m.value).collect()
    }

    /// The largest real part of an eigenvalue (the spectral abscissa).
    pub fn abscissa(&self) -> f64 {
        self.modes
            .iter()
            .map(|m| m.value.re)
            .fold(f64::NEG_INFINITY, f64::max)
    }
}

/// Linearises `model` about the steady motion starting at `init` (which
/// must satisfy the constraints: it is checked, not projected).
pub fn linearize(
    model: &mut dyn Model,
    init: &Initial,
    opts: &Options,
) -> Result<Linearisation, Error> {
    if !model.has_state_chart() {
        return Err(model.no_state_chart());
    }
    let mut init = init.clone();
    model.make_consistent(&mut init, false)?;
    let y = model.initial_state(&init)?;
    let t = init.t0;
    let chart = model.state_chart(t, &y)?;
    let dim = y.len();
    for name in &opts.independent {
        if !chart.names.contains(name) {
            return Err(Error::UnknownName {
                what: "state component".into(),
                name: name.clone(),
                valid: chart.names.clone(),
            });
        }
    }

    // Step 1: J and f at the state.
    let (jac, rate) = {
        let ode = model.ode().ok_or_else(|| {
            Error::numerical(
                "the linearisation",
                "the formulation has no explicit form y' = f(t, y)",
            )
        })?;
        let mut jac = vec![0.0; dim * dim];
        let mut rate = vec![0.0; dim];
        ode.rhs(t, &y, &mut rate).map_err(|e| {
            Error::numerical("the right-hand side at the steady motion", e.to_string())
        })?;
        let has = ode
            .jacobian(t, &y, &mut jac)
            .map_err(|e| Error::numerical("the Jacobian at the steady motion", e.to_string()))?;
        if !has {
            return Err(Error::numerical(
                "the linearisation",
                "the formulation gives no Jacobian of its right-hand side",
            ));
        }
        let jac = DMatrix::from_row_slice(dim, dim, &jac);
        for (i, j) in (0..dim).flat_map(|i| (0..dim).map(move |j| (i, j))) {
            if !jac[(i, j)].is_finite() {
                return Err(Error::numerical(
                    "the Jacobian at the steady motion",
                    format!(
                        "∂(rate of {})/∂{} is not finite at t = {t}: the state is at a singular \
                         configuration",
                        chart.names[i], chart.names[j]
                    ),
                ));
            }
        }
        (jac, rate)
    };

    // Step 2: the chart of the constraint manifold.
    let preferred: Vec<bool> = chart
        .names
        .iter()
        .map(|c| opts.independent.contains(c))
        .collect();
    let n = chart.n;
    let d = &chart.invariants;
    let mut dependent = Vec::with_capacity(d.nrows());
    let levels = [
        (0..chart.position_rows, 0..n),
        (chart.position_rows..d.nrows(), n..2 * n),
    ];
    for (rows, cols) in levels {
        dependent.extend(pivot_columns(
            d,
            rows,
            cols,
            &preferred,
            &chart.invariant_names,
        )?);
    }
    let independent: Vec<usize> = (0..dim).filter(|c| !dependent.contains(c)).collect();
    let m = independent.len();
    let mut e = DMatrix::zeros(dim, m);
    for (col, &i) in independent.iter().enumerate() {
        e[(i, col)] = 1.0;
    }
    if !dependent.is_empty() {
        let dd = d.select_columns(&dependent);
        let di = d.select_columns(&independent);
        let lu = dd.lu();
        let x = lu.solve(&(-di)).ok_or_else(|| {
            Error::numerical(
                "the reduction to the constraint manifold",
                "the constraint rows are dependent at this state",
            )
        })?;
        for (r, &i) in dependent.iter().enumerate() {
            for col in 0..m {
                e[(i, col)] = x[(r, col)];
            }
        }
    }
    let jz = jac.select_rows(&independent) * &e;

    // Step 3: the quotient by cyclic coordinates.
    let scale = jz.amax().max(f64::MIN_POSITIVE);
    let mut keep: Vec<usize> = (0..m).collect();
    let mut cyclic = Vec::new();
    loop {
        let found = keep.iter().position(|&c| {
            independent[c] < n
                && keep
                    .iter()
                    .all(|&r| jz[(r, c)].abs() <= opts.zero_tol * scale)
        });
        match found {
            Some(p) => {
                let c = keep.remove(p);
                cyclic.push((chart.names[independent[c]].clone(), rate[independent[c]]));
            }
            None => break,
        }
    }
    let names: Vec<String> = keep
        .iter()
        .map(|&c| chart.names[independent[c]].clone())
        .collect();
    let (residual, worst) = keep
        .iter()
        .map(|&c| (rate[independent[c]].abs(), independent[c]))
        .fold((0.0, usize::MAX), |a, b| {
            if b.0 > a.0 || b.0.is_nan() { b } else { a }
        });
    if residual.is_nan() || residual > opts.steady_tol {
        return Err(Error::InconsistentInit {
            formulation: model.formulation().name,
            reason: format!(
                "not a steady motion: `{}` changes at {residual:.3e} per second at t = {t} \
                 (allowed {:.0e}); a steady motion has its non-cyclic coordinates at rest and \
                 its velocities constant{}",
                chart.names[worst],
                opts.steady_tol,
                if cyclic.is_empty() {
                    " (no coordinate is cyclic here)".to_string()
                } else {
                    format!(
                        " (cyclic here: {})",
                        cyclic
                            .iter()
                            .map(|c| c.0.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                }
            ),
        });
    }
    let matrix = jz.select_rows(&keep).select_columns(&keep);
    let basis = e.select_columns(&keep);
    let modes = modes(&matrix)?;
    Ok(Linearisation {
        t,
        state: y,
        names,
        matrix,
        basis,
        modes,
        cyclic,
        dependent: dependent.iter().map(|&i| chart.names[i].clone()).collect(),
        residual,
    })
}

/// Dependent columns for `rows` of `d` among `cols`, by Gaussian
/// elimination with full pivoting; a preferred-independent column is chosen
/// only where no other will do. Dependent rows are an error naming them.
fn pivot_columns(
    d: &DMatrix<f64>,
    rows: std::ops::Range<usize>,
    cols: std::ops::Range<usize>,
    preferred: &[bool],
    row_names: &[String],
) -> Result<Vec<usize>, Error> {
    /// Weight of a column the caller wants independent.
    const AVOID: f64 = 1e-6;
    /// Relative size of a pivot below which the rows left are dependent.
    const RANK_TOL: f64 = 1e-12;
    let mut w = d
        .view((rows.start, cols.start), (rows.len(), cols.len()))
        .into_owned();
    let scale = w.amax().max(f64::MIN_POSITIVE);
    let mut left: Vec<usize> = (0..w.nrows()).collect();
    let mut chosen = Vec::new();
    // `is_chosen[c]` for column `cols.start + c`: a lookup, not a search of
    // `chosen` (that made the pivot search grow like N⁴ on a train).
    let mut is_chosen = vec![false; w.ncols()];
    while !left.is_empty() {
        let mut best: Option<(usize, usize, f64)> = None;
        for &r in &left {
            for c in 0..w.ncols() {
                if is_chosen[c] {
                    continue;
                }
                let weight = if preferred[cols.start + c] {
                    AVOID
                } else {
                    1.0
                };
                let score = w[(r, c)].abs() * weight;
                if best.is_none_or(|b| score > b.2) {
                    best = Some((r, c, score));
                }
            }
        }
        let Some((r, c, _)) = best.filter(|&(r, c, _)| w[(r, c)].abs() > RANK_TOL * scale) else {
            let name = |r: usize| row_names[rows.start + r].as_str();
            let dependent: Vec<&str> = left.iter().map(|&r| name(r)).collect();
            let others: Vec<&str> = (0..rows.len())
                .filter(|r| !left.contains(r))
                .map(name)
                .collect();
            return Err(Error::numerical(
                "the reduction to the constraint manifold",
                format!(
                    "the constraint rows {} depend on {} at this state (singular reduction)",
                    dependent.join(", "),
                    if others.is_empty() {
                        "nothing: they vanish".to_string()
                    } else {
                        others.join(", ")
                    }
                ),
            ));
        };
        let pivot = w[(r, c)];
        for &o in &left {
            // A row with a zero in the pivot column is left as it is (the
            // constraint rows of a chain are sparse).
            if o != r && w[(o, c)] != 0.0 {
                let factor = w[(o, c)] / pivot;
                for j in 0..w.ncols() {
                    let v = w[(r, j)];
                    w[(o, j)] -= factor * v;
                }
            }
        }
        left.retain(|&o| o != r);
        is_chosen[c] = true;
        chosen.push(cols.start + c);
    }
    Ok(chosen)
}

/// Eigenvalues and eigenvectors of `a` (faer's dense eigendecomposition),
/// by decreasing real part, then decreasing imaginary part.
pub fn modes(a: &DMatrix<f64>) -> Result<Vec<Mode>, Error> {
    let m = a.nrows();
    if m == 0 {
        return Ok(Vec::new());
    }
    let fa = faer::Mat::<f64>::from_fn(m, m, |i, j| a[(i, j)]);
    let evd = faer::linalg::solvers::Eigen::new_from_real(fa.as_ref())
        .map_err(|e| Error::numerical("the eigendecomposition", format!("{e:?}")))?;
    let (s, u) = (evd.S(), evd.U());
    let mut modes: Vec<Mode> = (0..m)
        .map(|k| {
            let mut vector: Vec<c64> = (0..m).map(|i| u[(i, k)]).collect();
            let big = vector
                .iter()
                .copied()
                .max_by(|x, y| x.norm().total_cmp(&y.norm()))
                .unwrap_or(c64::new(1.0, 0.0));
            if big.norm() > 0.0 {
                for v in &mut vector {
                    *v /= big;
                }
            }
            Mode {
                value: s[k],
                vector,
            }
        })
        .collect();
    modes.sort_by(|x, y| {
        y.value
            .re
            .total_cmp(&x.value.re)
            .then(y.value.im.total_cmp(&x.value.im))
    });
    Ok(modes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows that depend on the others are refused, naming them; a
    /// column the caller prefers independent is avoided where the others
    /// will do.
    #[test]
    fn pivoting_names_dependent_rows_and_avoids_preferred_columns() {
        let names: Vec<String> = ["f", "g1", "g2"].map(String::from).to_vec();
        // g2 = 2 g1 in the velocity columns 2..4.
        let d = DMatrix::from_row_slice(
            3,
            4,
            &[1.0, 0.5, 0.0, 0.0, 0.0, 0.0, 1.0, 3.0, 0.0, 0.0, 2.0, 6.0],
        );
        let err = pivot_columns(&d, 1..3, 2..4, &[false; 4], &names).unwrap_err();
        assert!(err.to_string().contains("rows g1 depend on g2"), "{err}");
        assert!(err.to_string().contains("singular reduction"), "{err}");
        // Column 3 has the larger entry but is preferred independent: 2 is chosen.
        let chosen = pivot_columns(&d, 1..2, 2..4, &[false, false, false, true], &names).unwrap();
        assert_eq!(chosen, vec![2]);
        let chosen = pivot_columns(&d, 1..2, 2..4, &[false; 4], &names).unwrap();
        assert_eq!(chosen, vec![3]);
    }
}
