//! `visc` in velocities adapted to the constraint (`form = adapted`).
//!
//! The state is `(q, v)` with `q̇ = T(q, t) v`, `v = (c, w)`:
//!
//! * `c ∈ R^{n−s}`: the values of the scene's velocity chart
//!   ([`Scene::velocities_from`], e.g. the sleigh's `(u, ω)`); the chart must
//!   be linear in them, and its columns `K(q) = ∂q̇/∂c` are read off it
//!   (`K e_j = velocities_from(q, e_j)`);
//! * `w ∈ R^s`: along `N(q, t) = M⁻¹Gᵀ(G M⁻¹ Gᵀ)⁻¹`, the velocities that
//!   violate the constraint, nearest to the admissible ones in the kinetic
//!   metric (`Kᵀ M N = (G K)ᵀ (G M⁻¹ Gᵀ)⁻¹ = 0`).
//!
//! For constraints linear and homogeneous in `q̇` (`g = G(q, t) q̇`) with a
//! chart on them (`G K = 0`), `g(q, T v) = G N w = w`: the violation is a
//! coordinate of the state. The friction force `−k Gᵀ w` enters
//! `v̇ = T⁻¹ M⁻¹(…)` as `T⁻¹ N (G M⁻¹ Gᵀ)(−k w)`, i.e. in `ẇ` only,
//! `ẇ = −k (G M⁻¹ Gᵀ) w + …`: the stiff part of the equations is a block of
//! its own, linear in `w`, which no longer turns with the configuration.
//!
//! Right-hand side: `q̈` from the KKT solve of the Cartesian form at
//! `(q, T v)` ([`crate::rows::Viscous`]), then `v̇ = T⁻¹(q̈ − Ṫ v)` with `Ṫ v` the
//! derivative of `T(q, t) v` along `(q̇, 1)` at fixed `v`, by one pass of the
//! frame over dual numbers. Everything is generic over the scalar, so the
//! Jacobian is the same code over `Dual64` (nested with the inner pass:
//! `Dual<Dual64>`, and `HyperDual<Dual<Dual64>>` inside the mass matrix).
//! `M` and `G` of the frame are evaluated at `q̇ = 0` (they depend on `q`
//! and `t` only for a kinetic energy quadratic in `q̇` and constraints linear
//! in it; in any case `T` is then a function of `(q, t)`, which is all the
//! construction needs).

use std::sync::Arc;

use nalgebra::DMatrix;
use nonholo_core::ad::Jet;
use nonholo_core::binding::EvalError;
use nonholo_core::compiled::{Compiled, Programs, Workspace};
use nonholo_core::integrate::SystemError;
use nonholo_core::kkt::Kkt;
use nonholo_core::linalg::Lu;
use nonholo_core::scene::{ConstraintKind, Lagrangian, Nonholonomic, Scalar, Scene};
use num_dual::Dual;

use crate::rows::Viscous;

const WHAT: &str = "formulation visc (form = adapted)";

/// The velocity frame `T(q, t) = [K | N]` over the scalar `D`, with its workspace.
#[derive(Debug, Clone)]
pub(crate) struct Frame<D: Scalar> {
    n: usize,
    s: usize,
    jet: Jet<D>,
    /// `q̇ = 0`, where `M` and `G` are evaluated.
    zeros: Vec<D>,
    /// A unit chart vector (length `n − s`).
    unit: Vec<D>,
    /// `M`, then its LU factors.
    mass: DMatrix<D>,
    lu_m: Lu,
    /// `g` and `ġ₀` at `q̇ = 0` (by-products of the Jacobian pass).
    gval: Vec<D>,
    grate: Vec<D>,
    /// `G`, `s × n`.
    g: DMatrix<D>,
    /// `M⁻¹Gᵀ`, column `j` at `x[j n..(j + 1) n]`.
    x: Vec<D>,
    /// `(G M⁻¹ Gᵀ)ᵀ`, then its LU factors.
    schur_t: DMatrix<D>,
    lu_s: Lu,
    /// Buffer of length `max(n, s)`.
    col: Vec<D>,
    /// `T = [K | N]`, `n × n`.
    pub t: DMatrix<D>,
    /// `L` and the constraints compiled ([`nonholo_core::compiled`]): `M`
    /// and `G` from one program run instead of the dual passes of `jet`.
    program: Option<(Arc<Compiled>, Workspace<D>)>,
}

impl<D: Scalar> Frame<D> {
    pub(crate) fn new(n: usize, s: usize, program: Option<Arc<Compiled>>) -> Self {
        let z = D::from(0.0);
        Frame {
            n,
            s,
            jet: Jet::new(n, s),
            zeros: vec![z; n],
            unit: vec![z; n - s],
            mass: DMatrix::from_element(n, n, z),
            lu_m: Lu::new(n),
            gval: vec![z; s],
            grate: vec![z; s],
            g: DMatrix::from_element(s, n, z),
            x: vec![z; n * s],
            schur_t: DMatrix::from_element(s, s, z),
            lu_s: Lu::new(s),
            col: vec![z; n.max(s)],
            t: DMatrix::from_element(n, n, z),
            program: program.map(|c| {
                let w = c.workspace();
                (c, w)
            }),
        }
    }

    /// `T(q, t)` into [`Frame::t`].
    pub(crate) fn evaluate<S: Scene>(
        &mut self,
        scene: &S,
        t: D,
        q: &[D],
    ) -> Result<(), SystemError> {
        let (n, s) = (self.n, self.s);
        let r = n - s;
        // K: the chart is linear in its values (checked at construction).
        for j in 0..r {
            self.unit.fill(D::from(0.0));
            self.unit[j] = D::from(1.0);
            scene.velocities_from(q, &self.unit, &mut self.col[..n]);
            for i in 0..n {
                self.t[(i, j)] = self.col[i];
            }
        }
        // N = M⁻¹Gᵀ (G M⁻¹ Gᵀ)⁻¹.
        if let Some((c, w)) = &mut self.program {
            c.eval(w, t, q, &self.zeros, &[]);
            let p = w.pieces(c);
            p.mass_into(&mut self.mass, n);
            p.g_jac_into(&mut self.g, 0, n);
        } else {
            self.jet.mass(
                &Lagrangian(scene),
                t,
                q,
                &self.zeros,
                &[],
                &mut self.mass.view_mut((0, 0), (n, n)),
            );
            self.jet.velocity_jacobian(
                &Nonholonomic(scene),
                t,
                q,
                &self.zeros,
                &mut self.gval,
                &mut self.g.view_mut((0, 0), (s, n)),
                &mut self.grate,
            );
        }
        self.lu_m.factor(&mut self.mass).map_err(|e| {
            SystemError::new(format!(
                "{WHAT}: mass matrix singular ({e}): the kinetic energy is degenerate"
            ))
        })?;
        for j in 0..s {
            let xj = &mut self.x[j * n..(j + 1) * n];
            for i in 0..n {
                xj[i] = self.g[(j, i)];
            }
            self.lu_m.solve(&self.mass, xj);
        }
        for a in 0..s {
            for b in 0..s {
                let mut v = D::from(0.0);
                for i in 0..n {
                    v += self.g[(b, i)] * self.x[a * n + i];
                }
                // (G M⁻¹ Gᵀ)_{ba}, stored transposed.
                self.schur_t[(a, b)] = v;
            }
        }
        self.lu_s.factor(&mut self.schur_t).map_err(|e| {
            SystemError::new(format!(
                "{WHAT}: G M⁻¹ Gᵀ singular ({e}): the constraints are dependent"
            ))
        })?;
        // Row i of N = X S⁻¹: Sᵀ N_iᵀ = X_iᵀ.
        for i in 0..n {
            for a in 0..s {
                self.col[a] = self.x[a * n + i];
            }
            self.lu_s.solve(&self.schur_t, &mut self.col[..s]);
            for a in 0..s {
                self.t[(i, r + a)] = self.col[a];
            }
        }
        Ok(())
    }
}

/// The adapted right-hand side over base scalar `T`: `(q̇, v̇)` from `(q, v)`.
#[derive(Debug, Clone)]
pub struct Rates<T: Scalar> {
    n: usize,
    k: f64,
    frame: Frame<T>,
    /// The frame along the time jet `(q + τ q̇, t + τ)`.
    frame_jet: Frame<Dual<T>>,
    kkt: Kkt<T>,
    q_jet: Vec<Dual<T>>,
    /// `T`, then its LU factors.
    t_lu: DMatrix<T>,
    lu_t: Lu,
    /// `q̇ = T v`.
    pub qd: Vec<T>,
    /// `q̈ − Ṫ v`, then `v̇`.
    b: Vec<T>,
}

impl<T: Scalar> Rates<T> {
    /// For `scene` (no holonomic constraints: checked where the form is
    /// chosen) with friction gain `k`; `L` and the constraints are compiled
    /// once in `programs` and shared by the KKT solve and both frames.
    pub(crate) fn new<S: Scene>(scene: &S, k: f64, programs: &Programs) -> Self {
        let z = T::from(0.0);
        let (n, s) = (scene.info().n(), scene.info().s());
        let program = programs.get(&Lagrangian(scene), 0, scene).ok();
        let mut kkt = Kkt::new(n, s, 0);
        if let Some(c) = &program {
            kkt.use_program(c.clone());
        }
        Rates {
            n,
            k,
            frame: Frame::new(n, s, program.clone()),
            frame_jet: Frame::new(n, s, program),
            kkt,
            q_jet: vec![Dual::from_re(z); n],
            t_lu: DMatrix::from_element(n, n, z),
            lu_t: Lu::new(n),
            qd: vec![z; n],
            b: vec![z; n],
        }
    }

    /// `q̇ = T(q, t) v` into [`Rates::qd`].
    pub(crate) fn velocities<S: Scene>(
        &mut self,
        scene: &S,
        t: T,
        q: &[T],
        v: &[T],
    ) -> Result<(), SystemError> {
        self.frame.evaluate(scene, t, q)?;
        for i in 0..self.n {
            let mut x = T::from(0.0);
            for j in 0..self.n {
                x += self.frame.t[(i, j)] * v[j];
            }
            self.qd[i] = x;
        }
        Ok(())
    }

    /// LU factors of the frame of the last evaluation.
    fn factor_frame(&mut self) -> Result<(), SystemError> {
        self.t_lu.copy_from(&self.frame.t);
        self.lu_t.factor(&mut self.t_lu).map_err(|e| {
            SystemError::new(format!(
                "{WHAT}: velocity frame [K | N] singular ({e}): the chart's velocities are \
                 dependent here"
            ))
        })
    }

    /// `v = T(q, t)⁻¹ q̇` into `v`: the adapted velocities of `(q, q̇)`.
    pub(crate) fn adapted<S: Scene>(
        &mut self,
        scene: &S,
        t: T,
        q: &[T],
        qd: &[T],
        v: &mut [T],
    ) -> Result<(), SystemError> {
        self.frame.evaluate(scene, t, q)?;
        self.factor_frame()?;
        v.copy_from_slice(qd);
        self.lu_t.solve(&self.t_lu, v);
        Ok(())
    }

    /// `v̇` at `(t, q, v)` into `vd`, after [`Rates::velocities`] at the same
    /// point (`q̇` in [`Rates::qd`]).
    pub(crate) fn accelerations<S: Scene>(
        &mut self,
        scene: &S,
        t: T,
        q: &[T],
        v: &[T],
        vd: &mut [T],
    ) -> Result<(), EvalError> {
        let n = self.n;
        self.kkt.solve(
            &Lagrangian(scene),
            &[],
            scene,
            &Viscous(self.k),
            t,
            q,
            &self.qd,
        )?;
        // Ṫ v: T(q + τ q̇, t + τ) v at fixed v, its τ-derivative.
        for i in 0..n {
            self.q_jet[i] = Dual::new(q[i], self.qd[i]);
        }
        self.frame_jet
            .evaluate(scene, Dual::new(t, T::from(1.0)), &self.q_jet)?;
        for i in 0..n {
            let mut tv = T::from(0.0);
            for j in 0..n {
                tv += self.frame_jet.t[(i, j)].eps * v[j];
            }
            self.b[i] = self.kkt.qdd()[i] - tv;
        }
        self.factor_frame()?;
        self.lu_t.solve(&self.t_lu, &mut self.b);
        vd.copy_from_slice(&self.b);
        Ok(())
    }
}

/// `x > bound`, or `x` NaN.
fn exceeds(x: f64, bound: f64) -> bool {
    x.is_nan() || x > bound
}

/// Why `form = adapted` does not apply to `scene`, if it does not.
///
/// Structural conditions from [`nonholo_core::SceneInfo`] (constraints
/// linear in `q̇`, no holonomic constraints, a chart of `n − s` values), then
/// numerical ones at three sample configurations (the scene's default `q0`
/// and two displaced ones, `t = 0`): the constraints homogeneous
/// (`g(q, 0) = 0`), the chart linear in its values
/// (`velocities_from(q, c) = Σ c_j velocities_from(q, e_j)` at two
/// pseudo-random `c`), on the constraints (`G K = 0`), and the frame
/// `[K | N]` regular.
pub(crate) fn applicable<S: Scene>(scene: &S) -> Result<(), String> {
    let info = scene.info();
    let (n, s, k) = (info.n(), info.s(), info.k());
    let mut reasons: Vec<String> = Vec::new();
    if info.constraint_kind == ConstraintKind::Nonlinear {
        reasons.push(format!(
            "the constraint {} is nonlinear in the velocities, so no velocity coordinates \
             make the violation g a coordinate (g(q, T v) = w needs g linear and homogeneous \
             in q̇)",
            info.nonholonomic.join(", ")
        ));
    }
    if k > 0 {
        reasons.push(format!(
            "the scene has holonomic constraints ({}), which the adapted velocities do not \
             carry",
            info.holonomic.join(", ")
        ));
    }
    let chart: Vec<&str> = info.velocity_chart.iter().map(|c| c.name).collect();
    if s >= n || chart.len() != n - s {
        reasons.push(format!(
            "its velocity chart ({}) has {} values, not n − s = {n} − {s}",
            chart.join(", "),
            chart.len(),
        ));
        return Err(reasons.join("; "));
    }
    let q0 = scene.default_q();
    let mut samples = vec![q0.clone()];
    for f in [1.0, -2.0] {
        samples.push(
            q0.iter()
                .enumerate()
                .map(|(i, x)| x + f * (0.31 + 0.17 * i as f64))
                .collect(),
        );
    }
    let r = n - s;
    let mut unit = vec![0.0; r];
    let mut kcols = vec![0.0; n * r];
    let (mut qd, mut lin, mut g) = (vec![0.0; n], vec![0.0; n], vec![0.0; s]);
    let mut nonlinear_chart = None;
    let mut off_constraint = None;
    let mut affine = None;
    for q in &samples {
        let zeros = vec![0.0; n];
        scene.nonholonomic(0.0, q, &zeros, &mut g);
        if g.iter().any(|x| exceeds(x.abs(), 1e-12)) && affine.is_none() {
            affine = Some(format!("g(q, 0) = {g:?} ≠ 0 at q = {q:?}"));
        }
        for j in 0..r {
            unit.fill(0.0);
            unit[j] = 1.0;
            scene.velocities_from(q, &unit, &mut kcols[j * n..(j + 1) * n]);
            scene.nonholonomic(0.0, q, &kcols[j * n..(j + 1) * n], &mut g);
            let scale = 1.0
                + kcols[j * n..(j + 1) * n]
                    .iter()
                    .fold(0.0f64, |m, x| m.max(x.abs()));
            if g.iter().any(|x| exceeds(x.abs(), 1e-10 * scale)) && off_constraint.is_none() {
                off_constraint = Some(format!(
                    "chart value {} = 1 gives velocities with g = {g:?} at q = {q:?}",
                    chart[j]
                ));
            }
        }
        for seed in [0.0, 1.0] {
            let c: Vec<f64> = (0..r)
                .map(|j| 0.73 - 1.37 * seed + 0.61 * (j as f64 + 1.0) * (1.0 - 2.0 * seed))
                .collect();
            scene.velocities_from(q, &c, &mut qd);
            for i in 0..n {
                lin[i] = (0..r).map(|j| kcols[j * n + i] * c[j]).sum();
            }
            let scale = 1.0 + qd.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let dev = qd
                .iter()
                .zip(&lin)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            if exceeds(dev, 1e-10 * scale) && nonlinear_chart.is_none() {
                nonlinear_chart = Some(format!(
                    "its velocity chart ({}) is not linear in its values: at q = {q:?}, \
                     chart {c:?} gives q̇ = {qd:?}, the linear combination of the unit \
                     charts {lin:?}",
                    chart.join(", ")
                ));
            }
        }
    }
    reasons.extend(nonlinear_chart);
    if info.constraint_kind == ConstraintKind::Linear {
        if let Some(a) = affine {
            reasons.push(format!(
                "the constraints are affine, not homogeneous, in the velocities ({a})"
            ));
        }
        if let Some(o) = off_constraint {
            reasons.push(format!(
                "the chart's velocities violate the constraints ({o})"
            ));
        }
    }
    if reasons.is_empty() {
        let mut frame = Frame::<f64>::new(n, s, None);
        for q in &samples {
            frame
                .evaluate(scene, 0.0, q)
                .map_err(|e| format!("at q = {q:?}: {}", e.message))?;
            let mut t = frame.t.clone();
            if let Err(e) = Lu::new(n).factor(&mut t) {
                reasons.push(format!(
                    "the velocity frame [K | N] is singular at q = {q:?} ({e})"
                ));
                break;
            }
        }
    }
    if reasons.is_empty() {
        Ok(())
    } else {
        Err(reasons.join("; "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nonholo_core::Params;
    use num_dual::Dual64;

    /// The frame from the compiled program equals the frame from the dual
    /// passes (its definition), over `f64` and along a time jet, for the
    /// scenes the adapted form applies to (the sleigh under both potentials,
    /// the rolling disk), at 20 scattered configurations each.
    fn program_frame_equals_passes<S: Scene>(scene: &S) {
        applicable(scene).unwrap();
        let (n, s) = (scene.info().n(), scene.info().s());
        let c = Arc::new(Compiled::new(&Lagrangian(scene), 0, scene).unwrap());
        let (mut a, mut b) = (
            Frame::<f64>::new(n, s, None),
            Frame::<f64>::new(n, s, Some(c.clone())),
        );
        let (mut da, mut db) = (
            Frame::<Dual64>::new(n, s, None),
            Frame::<Dual64>::new(n, s, Some(c)),
        );
        for trial in 0..20 {
            let q: Vec<f64> = (0..n)
                .map(|i| ((trial * 7 + i * 3) as f64 * 0.37).sin() * 1.3)
                .collect();
            let qd: Vec<f64> = (0..n).map(|i| 0.5 - 0.2 * i as f64).collect();
            a.evaluate(scene, 0.4, &q).unwrap();
            b.evaluate(scene, 0.4, &q).unwrap();
            let jet: Vec<Dual64> = q
                .iter()
                .zip(&qd)
                .map(|(&x, &v)| Dual64::new(x, v))
                .collect();
            da.evaluate(scene, Dual64::new(0.4, 1.0), &jet).unwrap();
            db.evaluate(scene, Dual64::new(0.4, 1.0), &jet).unwrap();
            let scale = a.t.amax().max(1.0);
            for i in 0..n * n {
                assert!(
                    (a.t[i] - b.t[i]).abs() < 1e-13 * scale,
                    "{}: T",
                    scene.info().name
                );
                let (x, y) = (da.t[i], db.t[i]);
                assert!((x.re - y.re).abs() < 1e-13 * scale);
                assert!(
                    (x.eps - y.eps).abs() < 1e-12 * scale,
                    "{}: Ṫ",
                    scene.info().name
                );
            }
        }
    }

    #[test]
    fn compiled_frame_equals_the_passes() {
        use nonholo_scenes::{RollingDisk, Sleigh};
        for potential in ["paper", "com"] {
            let p = Params::resolve(
                Sleigh::INFO.params,
                &[("potential".to_string(), potential.to_string())],
                "parameter",
            )
            .unwrap();
            program_frame_equals_passes(&Sleigh::from_params(&p).unwrap());
        }
        program_frame_equals_passes(
            &RollingDisk::from_params(&Params::defaults(RollingDisk::INFO.params)).unwrap(),
        );
    }
}
