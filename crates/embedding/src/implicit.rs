//! A's implicit form: `F(t, y, ẏ) = 0` in `y = (z, q_c)`,
//! `z = (q_I, q̇_I, q̈_I, q⃛_I)`, `q_c` the cyclic dependent coordinates,
//!
//! ```text
//! F = [ ż₀ − z₁ ;  ż₁ − z₂ ;  ż₂ − z₃ ;  E(z, ż₃) ;  q̇_c − φ_c(z) ]   (E: eq. 19)
//! ```
//!
//! integrated by Radau IIA as a differential-algebraic system. `∂F/∂z` and
//! `∂F/∂ż` come from dual passes through `E` (the block `∂E/∂ż₃ = W`
//! included).

use nonholo_core::Scene;
use nonholo_core::integrate::{ImplicitSystem, SystemError};
use num_dual::{Dual2, Dual2_64, Dual64};

use crate::analysis::svd_of;
use crate::elo::{cyclic_rates, elo_array};
use crate::shared::Shared;

/// A's implicit form bound to a scene.
pub struct Implicit<S: Scene> {
    pub shared: Shared<S>,
    /// `(z, q⁗)` for one evaluation of `E`.
    d: Vec<f64>,
    d_dual: Vec<Dual64>,
    e_out: Vec<f64>,
    e_dual: Vec<Dual64>,
    /// Scratch for the cyclic rates' derivatives.
    dep_dual: Vec<Dual64>,
    rates_dual: Vec<Dual64>,
}

impl<S: Scene> Implicit<S> {
    pub fn new(shared: Shared<S>) -> Self {
        let (m, s, c) = (shared.m, shared.e.dependent.len(), shared.c);
        Implicit {
            shared,
            d: vec![0.0; 5 * m],
            d_dual: vec![Dual64::from_re(0.0); 5 * m],
            e_out: vec![0.0; m],
            e_dual: vec![Dual64::from_re(0.0); m],
            dep_dual: vec![Dual64::from_re(0.0); s],
            rates_dual: vec![Dual64::from_re(0.0); c],
        }
    }

    /// `E` at `d = self.d` into `self.e_out`.
    fn evaluate(&mut self, t: f64) {
        let sh = &self.shared;
        elo_array::<_, f64, Dual2_64>(&*sh.scene, &sh.e, t, &self.d, &sh.near, &mut self.e_out);
    }

    /// `∂E/∂d_j` at `d = self.d` (`(z, q⁗)`, 5m numbers): one dual pass
    /// of the equations (19) seeded along `d_j`, into `self.e_dual[..m]`
    /// (the `eps` parts).
    fn e_direction(&mut self, t: f64, j: usize) {
        for (v, &x) in self.d_dual.iter_mut().zip(&self.d) {
            *v = Dual64::from_re(x);
        }
        self.d_dual[j].eps = 1.0;
        let sh = &self.shared;
        elo_array::<_, Dual64, Dual2<Dual64>>(
            &*sh.scene,
            &sh.e,
            Dual64::from_re(t),
            &self.d_dual,
            &sh.near,
            &mut self.e_dual,
        );
    }

    /// Makes `E(z, q⁗) = 0` hold to round-off at a consistent point
    /// `d = (z, q⁗, …)`: E is linear in q⁗ with coefficient W, so a
    /// least-squares correction `W δ = −E` (minimum norm, W singular)
    /// removes what the completion's relative tolerance left; the integrator
    /// then starts from `F = 0`.
    pub fn polish_fourth(&mut self, t: f64, d: &mut [f64]) {
        let m = self.shared.m;
        for _ in 0..3 {
            self.d.copy_from_slice(&d[..5 * m]);
            self.evaluate(t);
            let mut w = nalgebra::DMatrix::zeros(m, m);
            for j in 0..m {
                self.e_direction(t, 4 * m + j);
                for mu in 0..m {
                    w[(mu, j)] = self.e_dual[mu].eps;
                }
            }
            let Ok(svd) = svd_of(w, true, true) else {
                return;
            };
            let top = svd.singular_values.max();
            let Ok(delta) = svd.solve(
                &nalgebra::DVector::from_column_slice(&self.e_out),
                1e-12 * top,
            ) else {
                return;
            };
            for k in 0..m {
                d[4 * m + k] -= delta[k];
            }
        }
    }
}

impl<S: Scene> ImplicitSystem for Implicit<S> {
    fn dim(&self) -> usize {
        self.shared.dim()
    }

    fn residual(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        res: &mut [f64],
    ) -> Result<(), SystemError> {
        let m = self.shared.m;
        self.shared.check_stage(t, y)?;
        for i in 0..3 * m {
            res[i] = yp[i] - y[m + i];
        }
        self.d[..4 * m].copy_from_slice(&y[..4 * m]);
        self.d[4 * m..].copy_from_slice(&yp[3 * m..4 * m]);
        self.evaluate(t);
        res[3 * m..4 * m].copy_from_slice(&self.e_out);
        if self.shared.c > 0 {
            let rates = self.shared.cyclic_rates(t, y);
            for (k, r) in rates.iter().enumerate() {
                res[4 * m + k] = yp[4 * m + k] - r;
            }
        }
        if res.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(self.shared.not_finite(t, y))
        }
    }

    fn jacobians(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        jy: &mut [f64],
        jyp: &mut [f64],
    ) -> Result<(), SystemError> {
        let m = self.shared.m;
        let dim = self.shared.dim();
        jy.fill(0.0);
        jyp.fill(0.0);
        for i in 0..3 * m {
            jyp[i * dim + i] = 1.0;
            jy[i * dim + m + i] = -1.0;
        }
        // Columns of ∂E/∂(z, ż₃): one dual pass each.
        self.d[..4 * m].copy_from_slice(&y[..4 * m]);
        self.d[4 * m..].copy_from_slice(&yp[3 * m..4 * m]);
        for j in 0..5 * m {
            self.e_direction(t, j);
            for mu in 0..m {
                let v = self.e_dual[mu].eps;
                if j < 4 * m {
                    jy[(3 * m + mu) * dim + j] = v;
                } else {
                    jyp[(3 * m + mu) * dim + (j - m)] = v;
                }
            }
        }
        // The cyclic rows: q̇_c − φ_c(q_I, q̇_I), one dual pass of the map
        // per component of (q_I, q̇_I).
        let c = self.shared.c;
        for k in 0..c {
            jyp[(4 * m + k) * dim + 4 * m + k] = 1.0;
        }
        for j in (0..2 * m).filter(|_| c > 0) {
            for (v, &x) in self.d_dual.iter_mut().zip(&y[..2 * m]) {
                *v = Dual64::from_re(x);
            }
            self.d_dual[j].eps = 1.0;
            let sh = &self.shared;
            cyclic_rates(
                &*sh.scene,
                &sh.e,
                Dual64::from_re(t),
                &self.d_dual[..m],
                &self.d_dual[m..2 * m],
                &sh.near,
                &mut self.dep_dual,
                &mut self.rates_dual,
            );
            for k in 0..c {
                jy[(4 * m + k) * dim + j] = -self.rates_dual[k].eps;
            }
        }
        Ok(())
    }

    /// `x`, `y_dot`, `x_ddot`, … for the components of `z`; the last `m`
    /// are paired with the equations (19).
    fn component_name(&self, i: usize) -> String {
        let sh = &self.shared;
        let m = sh.m;
        if i >= 4 * m {
            let coord = sh.scene.info().coordinates[sh.e.cyclic[i - 4 * m]].name;
            return format!("{coord}: its rate from the embedding map");
        }
        let coord = sh.scene.info().coordinates[sh.e.independent[i % m]].name;
        let suffix = ["", "_dot", "_ddot", "_dddot"][i / m];
        if i >= 3 * m {
            format!("{coord}{suffix}: equation (19) in {coord}")
        } else {
            format!("{coord}{suffix}")
        }
    }

    /// Index classes for Radau's error estimate: `q_I, q̇_I` and the cyclic
    /// coordinates → 1, `q̈_I` → 2, `q⃛_I` → 3. The hidden constraints tie `q⃛_I` to `(q, q̇, q̈)` over two
    /// differentiation levels, so the chain `q̈ → q⃛` carries the algebraic
    /// part (with `q̈` as index 1 the error estimate of the unscaled `q̈`
    /// stays O(1) as h → 0 and the step size collapses; `docs/embedding.md`,
    /// section 4).
    fn variable_index(&self, index: &mut [u8]) {
        let m = self.shared.m;
        index[..2 * m].fill(1);
        index[2 * m..3 * m].fill(2);
        index[3 * m..4 * m].fill(3);
        index[4 * m..].fill(1);
    }

    /// The implicit form has nothing to stabilise: the collocation equations
    /// impose `E = 0` at every stage, and Radau treats `(q̈, q⃛)` as index-2
    /// and index-3 variables.
    fn after_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        self.shared.accept_state(t, y);
        Ok(false)
    }

    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        self.shared.guard_value(t, y)
    }

    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        self.shared.guard_text(t, y)
    }
}
