//! Matching formulation A with C (spec, section A).
//!
//! A's initial data `(q_I, q̇_I, q̈_I, q⃛_I)` for a physical state
//! `(q0, q̇0)` are taken from the vakonomic motion started at `(q0, q̇0, λ0)`:
//! its Taylor coefficients `q̈(0)`, `q⃛(0)` (Taylor-mode passes through C's
//! right-hand side). Conversely, from A's explicit data the multiplier `λ0`
//! of the vakonomic motion with the same `q̈_I(0)` is found by Gauss–Newton
//! on C's `∂q̈/∂λ` (exact, from its AD Jacobian), and the agreement of the
//! third derivatives is reported. A's equations are never built on C's:
//! C only supplies (or receives) the initial data.
//!
//! A cyclic dependent coordinate `q_c` of the map (the rolling disk's `ψ`,
//! absent from `L` and `g`) makes A's motions a subfamily of C's: A
//! eliminates `q_c` altogether, so its end value is free, and a free end
//! adds the transversality condition `P_c = ∂(L + λᵀg)/∂q̇_c = 0` to C's
//! extremals; `P_c` is C's conserved momentum of the cyclic coordinate, so
//! it vanishes along the whole motion. `P_c` is affine in `λ`: the
//! multipliers not given are completed from `P_c = 0` (minimum norm), given
//! ones that violate it are refused, and the inverse map solves for it with
//! `q̈_I`.

use nonholo_core::integrate::OdeSystem;
use nonholo_core::{Error, Initial, Params, Scene};
use nonholo_embedding::analysis::svd_of;
use nonholo_scenes::{AnyScene, SceneVisitor};
use nonholo_vakonomic::Vakonomic;

/// How A's initial derivatives were obtained.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MatchReport {
    /// `vakonomic` (from λ0) or `explicit` (given).
    pub source: &'static str,
    /// The multiplier of the matched vakonomic motion (given, or found).
    pub lambda0: Vec<f64>,
    /// `|q̈_I^C(λ0) − q̈_I^A|∞` (zero when matched from λ0).
    pub second_residual: f64,
    /// `|q⃛_I^C(λ0) − q⃛_I^A|∞` when A's third derivatives were given.
    pub third_residual: Option<f64>,
    /// `P_c = ∂(L + λ0ᵀg)/∂q̇_c` per cyclic coordinate of the map (zero for
    /// the C motions A reproduces; empty without cyclic coordinates).
    pub cyclic_momentum: Vec<f64>,
}

/// `P_c(λ) = a + B λ` per cyclic coordinate `c` of the embedding map at
/// `(t, q, q̇)`: `a_c = ∂L/∂q̇_c`, `B_ci = ∂g_i/∂q̇_c` (one dual pass each).
pub struct CyclicMomentum {
    pub names: Vec<String>,
    pub a: Vec<f64>,
    pub b: nalgebra::DMatrix<f64>,
}

impl CyclicMomentum {
    pub fn new<S: Scene>(scene: &S, t: f64, q: &[f64], qd: &[f64]) -> CyclicMomentum {
        use num_dual::Dual64;
        let info = scene.info();
        let e = info
            .embedding
            .expect("A applies only to scenes with an embedding map");
        let s = info.s();
        let qq: Vec<Dual64> = q.iter().map(|&v| Dual64::from_re(v)).collect();
        let mut a = Vec::new();
        let mut b = nalgebra::DMatrix::zeros(e.cyclic.len(), s);
        let mut g = vec![Dual64::from_re(0.0); s];
        for (k, &c) in e.cyclic.iter().enumerate() {
            let mut v: Vec<Dual64> = qd.iter().map(|&x| Dual64::from_re(x)).collect();
            v[c].eps = 1.0;
            let tt = Dual64::from_re(t);
            a.push(scene.lagrangian(tt, &qq, &v).eps);
            scene.nonholonomic(tt, &qq, &v, &mut g);
            for i in 0..s {
                b[(k, i)] = g[i].eps;
            }
        }
        let names = e
            .cyclic
            .iter()
            .map(|&c| format!("P_{}", info.coordinates[c].name))
            .collect();
        CyclicMomentum { names, a, b }
    }

    /// `P(λ)`.
    pub fn at(&self, lambda: &[f64]) -> Vec<f64> {
        let l = nalgebra::DVector::from_column_slice(lambda);
        (&self.b * l)
            .iter()
            .zip(&self.a)
            .map(|(bl, a)| a + bl)
            .collect()
    }

    /// The scale against which `P` counts as zero.
    fn scale(&self, lambda: &[f64]) -> f64 {
        let big = |v: &mut dyn Iterator<Item = f64>| v.fold(0.0f64, |x, y| x.max(y.abs()));
        1.0 + big(&mut self.a.iter().copied())
            + big(&mut self.b.iter().copied()) * big(&mut lambda.iter().copied())
    }

    /// `λ` with the components not given (`None`) chosen, minimum norm,
    /// so that `P(λ) = 0`; refuses given values that leave `P ≠ 0`. Without
    /// cyclic coordinates, the components not given are 0.
    pub fn complete(&self, given: &[Option<f64>], names: &[String]) -> Result<Vec<f64>, Error> {
        let mut lambda: Vec<f64> = given.iter().map(|g| g.unwrap_or(0.0)).collect();
        if self.a.is_empty() {
            return Ok(lambda);
        }
        let refuse = |reason: String| Error::InconsistentInit {
            formulation: "embedding",
            reason,
        };
        let coefficients = || {
            (0..names.len())
                .map(|i| {
                    let c: Vec<String> = (0..self.a.len())
                        .map(|k| format!("{:.3e}", self.b[(k, i)]))
                        .collect();
                    format!("∂P/∂{} = {}", names[i], c.join(", "))
                })
                .collect::<Vec<_>>()
                .join("; ")
        };
        let b_size = self.b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let free: Vec<usize> = (0..given.len()).filter(|&i| given[i].is_none()).collect();
        if !free.is_empty() {
            let p = self.at(&lambda);
            let sub =
                nalgebra::DMatrix::from_fn(self.a.len(), free.len(), |k, j| self.b[(k, free[j])]);
            let svd = svd_of(sub, true, true)
                .map_err(|msg| Error::numerical("completing λ0 from P_c = 0", msg))?;
            // The multipliers left out must move P by a fair share of what
            // any multiplier does, or the completed ones are huge and
            // ill-determined (the disk heading along y: P_ψ hardly depends
            // on λ₁).
            let weakest = svd.singular_values.min();
            if self.a.len() <= free.len()
                && (weakest.is_nan() || weakest <= COMPLETION_RCOND * b_size)
            {
                let left_out: Vec<&str> = free.iter().map(|&i| names[i].as_str()).collect();
                return Err(refuse(format!(
                    "the momenta {} of the cyclic coordinates, which A's motions keep at zero, \
                     hardly depend here on the multipliers left out ({}: smallest singular \
                     value {weakest:.3e} against {b_size:.3e}); give those and leave out others \
                     ({})",
                    self.names.join(", "),
                    left_out.join(", "),
                    coefficients()
                )));
            }
            let x = svd
                .solve(&nalgebra::DVector::from_vec(p), COMPLETION_RCOND * b_size)
                .map_err(|msg| Error::numerical("completing λ0 from P_c = 0", msg))?;
            for (j, &i) in free.iter().enumerate() {
                lambda[i] -= x[j];
            }
        }
        let p = self.at(&lambda);
        if p.iter()
            .any(|v| !v.is_finite() || v.abs() > 1e-10 * self.scale(&lambda))
        {
            // A valid choice: the given λ moved by the least amount.
            let fix = svd_of(self.b.clone(), true, true)
                .and_then(|svd| {
                    svd.solve(
                        &nalgebra::DVector::from_vec(p.clone()),
                        COMPLETION_RCOND * b_size,
                    )
                    .map_err(str::to_string)
                })
                .map(|x| {
                    names
                        .iter()
                        .zip(lambda.iter().zip(x.iter()))
                        .map(|(n, (l, d))| format!("{n} = {:.12}", l - d))
                        .collect::<Vec<_>>()
                        .join(", ")
                })
                .unwrap_or_else(|msg| format!("none found ({msg})"));
            let momentum: Vec<String> = self
                .names
                .iter()
                .zip(&p)
                .map(|(n, v)| format!("{n} = {v:.6e}"))
                .collect();
            let values: Vec<String> = names
                .iter()
                .zip(&lambda)
                .zip(given)
                .map(|((n, v), g)| {
                    let how = if g.is_some() { "given" } else { "completed" };
                    format!("{n} = {v} ({how})")
                })
                .collect();
            return Err(refuse(format!(
                "A's motions are the vakonomic ones whose momenta of the cyclic coordinates \
                 vanish ({} = ∂(L + λᵀg)/∂q̇_c = 0), but {} gives {}; the nearest valid \
                 multipliers are {fix}; leave out the ones to be computed",
                self.names.join(", "),
                values.join(", "),
                momentum.join(", ")
            )));
        }
        Ok(lambda)
    }
}

/// Singular values of `∂P/∂λ` below this fraction of its largest entry count
/// as zero when multipliers are completed from `P_c = 0`.
const COMPLETION_RCOND: f64 = 1e-6;

fn derivative_names(scene: &AnyScene, order: &str) -> Vec<String> {
    let info = scene.info();
    let e = info
        .embedding
        .expect("A applies only to scenes with an embedding map");
    e.independent
        .iter()
        .map(|&i| format!("{}_{order}", info.coordinates[i].name))
        .collect()
}

/// Completes `init` for formulation A: if no second derivatives are given,
/// fills `<q_I>_ddot` and `<q_I>_dddot` from the vakonomic motion with
/// `λ0 = lambda` (the multipliers not given: 0, or completed from
/// `P_c = 0` where the map has cyclic coordinates); otherwise finds the
/// matching `λ0`.
pub fn prepare_embedding(scene: &AnyScene, init: &mut Initial) -> Result<MatchReport, Error> {
    let second = derivative_names(scene, "ddot");
    let third = derivative_names(scene, "dddot");
    let s = scene.info().s();
    let lambda_names: Vec<String> = nonholo_vakonomic::lambda_names(s)
        .into_iter()
        .map(|e| e.name)
        .collect();
    let given_lambda = lambda_names.iter().any(|n| init.extra(n).is_some());
    let given_second = second.iter().any(|n| init.extra(n).is_some());
    if given_lambda && given_second {
        return Err(Error::InconsistentInit {
            formulation: "embedding",
            reason: format!(
                "give A's initial data either as {} (matched with the vakonomic motion) or as \
                 explicit derivatives {}, not both",
                lambda_names.join(", "),
                second.join(", ")
            ),
        });
    }
    scene.clone().visit(Match {
        init,
        second,
        third,
        lambda_names,
        explicit: given_second,
    })
}

struct Match<'a> {
    init: &'a mut Initial,
    second: Vec<String>,
    third: Vec<String>,
    lambda_names: Vec<String>,
    explicit: bool,
}

impl SceneVisitor for Match<'_> {
    type Output = Result<MatchReport, Error>;

    fn visit<S: Scene>(self, scene: S) -> Self::Output {
        let info = scene.info();
        let e = info.embedding.expect("checked by the caller");
        let (n, s) = (info.n(), info.s());
        let momentum = CyclicMomentum::new(&scene, self.init.t0, &self.init.q, &self.init.qd);
        let mut c = Vakonomic::new(scene, Params::defaults(nonholo_vakonomic::OPTIONS))?;
        let dim = 2 * n + s;
        let mut y: Vec<f64> = self.init.q.iter().chain(&self.init.qd).copied().collect();
        let fail = |e: nonholo_core::integrate::SystemError| {
            Error::numerical("matching A with the vakonomic motion", e)
        };
        let (mut yd, mut ydd, mut yddd) = (vec![0.0; dim], vec![0.0; dim], vec![0.0; dim]);

        if !self.explicit {
            let given: Vec<Option<f64>> = self
                .lambda_names
                .iter()
                .map(|nm| self.init.extra(nm))
                .collect();
            let lambda0 = momentum.complete(&given, &self.lambda_names)?;
            y.extend(&lambda0);
            c.taylor(self.init.t0, &y, &mut yd, &mut ydd, &mut yddd)
                .map_err(fail)?;
            for (k, &i) in e.independent.iter().enumerate() {
                self.init.extra.push((self.second[k].clone(), yd[n + i]));
                self.init.extra.push((self.third[k].clone(), ydd[n + i]));
            }
            return Ok(MatchReport {
                source: "vakonomic",
                cyclic_momentum: momentum.at(&lambda0),
                lambda0,
                second_residual: 0.0,
                third_residual: None,
            });
        }

        // Inverse map: λ0 with C's q̈_I(λ0) = A's q̈_I (and P_c(λ0) = 0), by
        // Gauss–Newton on the exact ∂q̈/∂λ columns of C's Jacobian.
        let want: Vec<f64> = self
            .second
            .iter()
            .map(|nm| self.init.extra(nm).unwrap_or(0.0))
            .collect();
        y.extend(std::iter::repeat_n(0.0, s));
        let mut jac = vec![0.0; dim * dim];
        let m = e.independent.len();
        let nc = momentum.a.len();
        let mut residual = f64::INFINITY;
        for _ in 0..20 {
            c.rhs(self.init.t0, &y, &mut yd).map_err(fail)?;
            let mut r: Vec<f64> = e
                .independent
                .iter()
                .enumerate()
                .map(|(k, &i)| yd[n + i] - want[k])
                .collect();
            r.extend(momentum.at(&y[2 * n..]));
            residual = r.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            if residual <= 1e-13 * (1.0 + want.iter().fold(0.0f64, |a, v| a.max(v.abs()))) {
                break;
            }
            c.jacobian(self.init.t0, &y, &mut jac).map_err(fail)?;
            let a = nalgebra::DMatrix::from_fn(m + nc, s, |k, j| {
                if k < m {
                    jac[(n + e.independent[k]) * dim + 2 * n + j]
                } else {
                    momentum.b[(k - m, j)]
                }
            });
            let step = svd_of(a, true, true)
                .and_then(|svd| {
                    svd.solve(&nalgebra::DVector::from_vec(r), 1e-12)
                        .map_err(str::to_string)
                })
                .map_err(|msg| Error::numerical("inverse map", msg))?;
            for j in 0..s {
                y[2 * n + j] -= step[j];
            }
        }
        let lambda0 = y[2 * n..].to_vec();
        let third_residual = if self.third.iter().all(|nm| self.init.extra(nm).is_some()) {
            c.taylor(self.init.t0, &y, &mut yd, &mut ydd, &mut yddd)
                .map_err(fail)?;
            Some(
                e.independent
                    .iter()
                    .zip(&self.third)
                    .map(|(&i, nm)| (ydd[n + i] - self.init.extra(nm).unwrap_or(0.0)).abs())
                    .fold(0.0f64, f64::max),
            )
        } else {
            None
        };
        Ok(MatchReport {
            source: "explicit",
            cyclic_momentum: momentum.at(&lambda0),
            lambda0,
            second_residual: residual,
            third_residual,
        })
    }
}
