//! `Θ` and the Euler–Lagrange–Ostrogradsky equations (19) of the paper, by
//! automatic differentiation only.
//!
//! With the embedding map `q_D = φ(q_I, q̇_I, t)` (eq. 14) and its total time
//! derivative `q̇_D = ∂φ/∂q_I q̇_I + ∂φ/∂q̇_I q̈_I + ∂φ/∂t` (eq. 15),
//!
//! ```text
//! Θ(t, q_I, q̇_I, q̈_I) = L(t, q_I ⊕ φ, q̇_I ⊕ q̇_D)                  (eq. 16–17)
//! E_μ = ∂Θ/∂q_μ − d/dt ∂Θ/∂q̇_μ + d²/dt² ∂Θ/∂q̈_μ = 0,  μ ∈ I        (eq. 19)
//! ```
//!
//! `q̇_D` is read off one evaluation of the scene's map on a first-order time
//! jet. Each `E_μ` takes three evaluations of `Θ` on a time jet with a
//! gradient direction on top: the direction picks `∂/∂q_μ`, `∂/∂q̇_μ` or
//! `∂/∂q̈_μ`, and the jet carries that partial derivative along the curve,
//! so the total time derivatives come out exactly, without any hand-derived
//! term. A jet of order `2 + L` yields the derivative array
//! `[E, Ė, …, E⁽ᴸ⁾]` from the same evaluations.

use nonholo_core::scene::EmbeddingInfo;
use nonholo_core::{Scalar, Scene};
use num_dual::Dual;

use crate::jet::TimeJet;

/// Largest number of coordinates formulation A supports (stack buffers).
pub const MAX_DOF: usize = 12;

/// `Θ(t, q_I, q̇_I, q̈_I)`: the Lagrangian with the embedding map substituted
/// (on the branch of the map nearest to `near`, its principal one if empty).
pub fn theta<S: Scene, D: Scalar>(
    scene: &S,
    e: &EmbeddingInfo,
    t: D,
    qi: &[D],
    qdi: &[D],
    qddi: &[D],
    near: &[f64],
) -> D {
    let n = scene.info().n();
    let zero = D::from(0.0);
    let mut q = [zero; MAX_DOF];
    let mut qd = [zero; MAX_DOF];
    reconstruct(scene, e, t, qi, qdi, qddi, near, &mut q, &mut qd);
    scene.lagrangian(t, &q[..n], &qd[..n])
}

/// The full coordinates `(q, q̇)` from `(q_I, q̇_I, q̈_I)`: `q_D = φ`,
/// `q̇_D = dφ/dt` (`φ` on the branch nearest to `near`, see
/// [`Scene::embedding`]). A cyclic dependent coordinate
/// ([`EmbeddingInfo::cyclic`]) gets its velocity `q̇_c = φ_c`; its value
/// `q[c]` is left as it is (`L` does not depend on it; A integrates it as
/// a quadrature of `φ_c`).
#[allow(clippy::too_many_arguments)]
pub fn reconstruct<S: Scene, D: Scalar>(
    scene: &S,
    e: &EmbeddingInfo,
    t: D,
    qi: &[D],
    qdi: &[D],
    qddi: &[D],
    near: &[f64],
    q: &mut [D],
    qd: &mut [D],
) {
    let (m, s) = (e.independent.len(), e.dependent.len());
    let dzero = Dual::from_re(D::from(0.0));
    let mut qi_jet = [dzero; MAX_DOF];
    let mut qdi_jet = [dzero; MAX_DOF];
    for k in 0..m {
        qi_jet[k] = Dual::new(qi[k], qdi[k]);
        qdi_jet[k] = Dual::new(qdi[k], qddi[k]);
    }
    let mut dep = [dzero; MAX_DOF];
    scene.embedding(
        Dual::new(t, D::from(1.0)),
        &qi_jet[..m],
        &qdi_jet[..m],
        near,
        &mut dep[..s],
    );
    for (k, &i) in e.independent.iter().enumerate() {
        q[i] = qi[k];
        qd[i] = qdi[k];
    }
    for (j, &i) in e.dependent.iter().enumerate() {
        if e.cyclic.contains(&i) {
            qd[i] = dep[j].re;
        } else {
            q[i] = dep[j].re;
            qd[i] = dep[j].eps;
        }
    }
}

/// The rates `φ_c(t, q_I, q̇_I)` of the cyclic dependent coordinates
/// ([`EmbeddingInfo::cyclic`], in that order) into `out`, the map on the
/// branch nearest to `near`; `dep` is scratch of length `s`.
#[allow(clippy::too_many_arguments)]
pub fn cyclic_rates<S: Scene, D: Scalar>(
    scene: &S,
    e: &EmbeddingInfo,
    t: D,
    qi: &[D],
    qdi: &[D],
    near: &[f64],
    dep: &mut [D],
    out: &mut [D],
) {
    scene.embedding(t, qi, qdi, near, dep);
    for (o, c) in out.iter_mut().zip(e.cyclic) {
        let j = e
            .dependent
            .iter()
            .position(|i| i == c)
            .expect("cyclic coordinates are dependent ones");
        *o = dep[j];
    }
}

/// The derivative array `[E, Ė, …, E⁽ᴸ⁾]`, `L = J::ORDER − 2`, of the
/// equations (19) along the curve `q_I(τ)` whose derivatives at `τ = 0` are
/// `d[k·m .. (k+1)·m] = q_I⁽ᵏ⁾`, `k = 0 ..= J::ORDER + 2`.
///
/// Writes `out[l·m + μ] = E_μ⁽ˡ⁾` for `l = 0 ..= L`; 3m evaluations of `Θ`,
/// the map on the branch nearest to `near` (its principal one if empty).
pub fn elo_array<S: Scene, T: Scalar, J: TimeJet<T>>(
    scene: &S,
    e: &EmbeddingInfo,
    t: T,
    d: &[T],
    near: &[f64],
    out: &mut [T],
) {
    let m = e.independent.len();
    let order = J::ORDER;
    let levels = order - 1;
    debug_assert!(d.len() >= (order + 3) * m);
    debug_assert!(out.len() >= levels * m);
    let zero = T::from(0.0);
    // Jets of q_I, q̇_I, q̈_I: component k of level r (0: q, 1: q̇, 2: q̈)
    // has derivatives d[(r + j)·m + k], j = 0 ..= order.
    let gzero: Dual<J> = Dual::from_re(J::from(0.0));
    let mut base = [[gzero; MAX_DOF]; 3];
    let mut derivs = [zero; 8];
    for (r, level) in base.iter_mut().enumerate() {
        for (k, slot) in level.iter_mut().enumerate().take(m) {
            for (j, dj) in derivs.iter_mut().enumerate().take(order + 1) {
                *dj = d[(r + j) * m + k];
            }
            *slot = Dual::from_re(J::from_derivatives(&derivs[..=order]));
        }
    }
    let t_jet: Dual<J> = Dual::from_re(J::from_derivatives(&[t, T::from(1.0)]));
    for o in out.iter_mut().take(levels * m) {
        *o = zero;
    }
    for mu in 0..m {
        // r = 0: +∂Θ/∂q_μ; r = 1: −d/dt ∂Θ/∂q̇_μ; r = 2: +d²/dt² ∂Θ/∂q̈_μ.
        for r in 0..3 {
            // The direction seeded in place (and cleared below), not in a
            // copy of the jets: over nested duals they are kilobytes.
            base[r][mu].eps = J::from(1.0);
            let v = theta(
                scene,
                e,
                t_jet,
                &base[0][..m],
                &base[1][..m],
                &base[2][..m],
                near,
            );
            base[r][mu].eps = J::from(0.0);
            let sign = if r == 1 { -1.0 } else { 1.0 };
            for l in 0..levels {
                out[l * m + mu] += v.eps.time_derivative(l + r) * sign;
            }
        }
    }
}
