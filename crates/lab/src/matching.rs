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
}

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
/// `λ0 = lambda` (default 0); otherwise finds the matching `λ0`.
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
        let mut c = Vakonomic::new(scene, Params::defaults(nonholo_vakonomic::OPTIONS))?;
        let dim = 2 * n + s;
        let mut y: Vec<f64> = self.init.q.iter().chain(&self.init.qd).copied().collect();
        let fail = |e: nonholo_core::integrate::SystemError| {
            Error::numerical("matching A with the vakonomic motion", e)
        };
        let (mut yd, mut ydd, mut yddd) = (vec![0.0; dim], vec![0.0; dim], vec![0.0; dim]);

        if !self.explicit {
            let lambda0: Vec<f64> = self
                .lambda_names
                .iter()
                .map(|nm| self.init.extra(nm).unwrap_or(0.0))
                .collect();
            y.extend(&lambda0);
            c.taylor(self.init.t0, &y, &mut yd, &mut ydd, &mut yddd)
                .map_err(fail)?;
            for (k, &i) in e.independent.iter().enumerate() {
                self.init.extra.push((self.second[k].clone(), yd[n + i]));
                self.init.extra.push((self.third[k].clone(), ydd[n + i]));
            }
            return Ok(MatchReport {
                source: "vakonomic",
                lambda0,
                second_residual: 0.0,
                third_residual: None,
            });
        }

        // Inverse map: λ0 with C's q̈_I(λ0) = A's q̈_I, by Gauss–Newton on the
        // exact ∂q̈/∂λ columns of C's Jacobian.
        let want: Vec<f64> = self
            .second
            .iter()
            .map(|nm| self.init.extra(nm).unwrap_or(0.0))
            .collect();
        y.extend(std::iter::repeat_n(0.0, s));
        let mut jac = vec![0.0; dim * dim];
        let m = e.independent.len();
        let mut residual = f64::INFINITY;
        for _ in 0..20 {
            c.rhs(self.init.t0, &y, &mut yd).map_err(fail)?;
            let r: Vec<f64> = e
                .independent
                .iter()
                .enumerate()
                .map(|(k, &i)| yd[n + i] - want[k])
                .collect();
            residual = r.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            if residual <= 1e-13 * (1.0 + want.iter().fold(0.0f64, |a, v| a.max(v.abs()))) {
                break;
            }
            c.jacobian(self.init.t0, &y, &mut jac).map_err(fail)?;
            let a = nalgebra::DMatrix::from_fn(m, s, |k, j| {
                jac[(n + e.independent[k]) * dim + 2 * n + j]
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
            lambda0,
            second_residual: residual,
            third_residual,
        })
    }
}
