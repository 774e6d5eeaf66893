//! The mechanical pieces of the spec by automatic differentiation.
//!
//! For a scalar field `ℓ(t, q, q̇)` (a Lagrangian, possibly augmented by
//! multipliers):
//!
//! * `M = ∂²ℓ/∂q̇²`,
//! * `Q = ∂ℓ/∂q − (∂²ℓ/∂q̇∂q) q̇ − ∂²ℓ/∂q̇∂t`, so that the Euler–Lagrange
//!   expression is `d/dt ∂ℓ/∂q̇ − ∂ℓ/∂q = M q̈ − Q`,
//! * the energy `E = q̇·∂ℓ/∂q̇ − ℓ`;
//!
//! for a vector field `v(t, q, q̇)` (constraints):
//!
//! * `∂v/∂q̇` (the `G` of the spec), `∂v/∂q` (the `F` of holonomic constraints),
//! * total time derivatives along the motion with `q̈ = 0`: `v̇₀ = (∂v/∂q) q̇ + ∂v/∂t`
//!   and, for `v = f(q, t)`, `f̈₀ = (d/dt F) q̇ + d/dt ∂f/∂t`.
//!
//! Each quantity is read off scalar dual numbers: `Dual64` for first
//! derivatives, `HyperDual64` for mixed second derivatives and `Dual2_64`
//! for second derivatives along a time jet `(q + q̇τ, t + τ)`. Scalar
//! directional passes avoid the heap (vector duals of runtime size allocate)
//! and were the fastest option measured for these small systems
//! (`../shared/deps.md`).
//! [`Jet`] owns the seed buffers, so no evaluation allocates.
//!
//! The passes repeat the whole field per direction; [`crate::compiled`]
//! computes the same pieces by one program with every subexpression
//! shared, and is what [`crate::kkt::Kkt`] uses once compiled. The passes
//! remain the definition (the compiled pieces are tested against them) and
//! the fallback for fields whose trace branches on values.
//!
//! The base scalar `T` is `f64` for values, or itself a dual number: with
//! `T = Dual64` every piece carries one more directional derivative, which is
//! how right-hand-side Jacobians (for implicit integrators) and Taylor
//! coefficients along a motion are obtained from the same code.

use nalgebra::DMatrixViewMut;
use num_dual::{Dual, Dual2, HyperDual};

use crate::scene::{Scalar, ScalarField, VectorField};

#[inline]
fn one<T: Scalar>() -> T {
    T::from(1.0)
}

#[inline]
fn zero<T: Scalar>() -> T {
    T::from(0.0)
}

/// Which variables a Jacobian is taken with respect to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Wrt {
    Positions,
    Velocities,
}

/// Seed buffers for one dual number type.
#[derive(Debug, Clone)]
struct Seeds<D> {
    q: Vec<D>,
    qd: Vec<D>,
    /// Parameters of a scalar field, lifted to `D` (no derivative parts).
    p: Vec<D>,
    out: Vec<D>,
}

impl<D: Scalar> Seeds<D> {
    fn new(n: usize, m: usize) -> Self {
        Seeds {
            q: vec![D::from(0.0); n],
            qd: vec![D::from(0.0); n],
            p: Vec::new(),
            out: vec![D::from(0.0); m],
        }
    }

    /// Lifts the field parameters `p` into the `D` buffer.
    #[inline]
    fn params(&mut self, p: &[D::InnerDual])
    where
        D::InnerDual: Copy,
    {
        self.p.clear();
        self.p.extend(p.iter().map(|&x| D::from_re(x)));
    }

    /// Sets every seed to the constant `(q, q̇)` (no derivative parts).
    #[inline]
    fn constant(&mut self, q: &[D::InnerDual], qd: &[D::InnerDual])
    where
        D::InnerDual: Copy,
    {
        for (s, &x) in self.q.iter_mut().zip(q) {
            *s = D::from_re(x);
        }
        for (s, &x) in self.qd.iter_mut().zip(qd) {
            *s = D::from_re(x);
        }
    }
}

/// Workspace for the derivatives of fields on `n` coordinates with vector
/// fields of at most `m` components, over base scalar `T`.
#[derive(Debug, Clone)]
pub struct Jet<T: Scalar = f64> {
    n: usize,
    d: Seeds<Dual<T>>,
    hd: Seeds<HyperDual<T>>,
    d2: Seeds<Dual2<T>>,
}

impl<T: Scalar> Jet<T> {
    pub fn new(n: usize, m: usize) -> Self {
        Jet {
            n,
            d: Seeds::new(n, m),
            hd: Seeds::new(n, m),
            d2: Seeds::new(n, m),
        }
    }

    /// `M = ∂²ℓ/∂q̇²` into `mass` (n×n) and `Q = ∂ℓ/∂q − (∂²ℓ/∂q̇∂q) q̇ − ∂²ℓ/∂q̇∂t`
    /// into `force` (length n).
    ///
    /// Cost: `n(n+3)/2` hyper-dual and `n` dual evaluations of `ℓ`.
    pub fn mass_and_force<F: ScalarField>(
        &mut self,
        f: &F,
        t: T,
        q: &[T],
        qd: &[T],
        p: &[T],
        mass: &mut DMatrixViewMut<T>,
        force: &mut [T],
    ) {
        self.mass(f, t, q, qd, p, mass);
        self.force(f, t, q, qd, p, force);
    }

    /// `M = ∂²ℓ/∂q̇²` into `mass` (n×n): `n(n+1)/2` hyper-dual evaluations.
    pub fn mass<F: ScalarField>(
        &mut self,
        f: &F,
        t: T,
        q: &[T],
        qd: &[T],
        p: &[T],
        mass: &mut DMatrixViewMut<T>,
    ) {
        let n = self.n;
        debug_assert_eq!(f.n(), n);
        let hd = &mut self.hd;
        hd.params(p);
        let t_const = HyperDual::from_re(t);
        for i in 0..n {
            for j in i..n {
                hd.constant(q, qd);
                if i == j {
                    hd.qd[i] = HyperDual::new(qd[i], one(), one(), zero());
                } else {
                    hd.qd[i].eps1 = one();
                    hd.qd[j].eps2 = one();
                }
                let v = f.eval(t_const, &hd.q, &hd.qd, &hd.p);
                mass[(i, j)] = v.eps1eps2;
                mass[(j, i)] = v.eps1eps2;
            }
        }
    }

    /// `Q = ∂ℓ/∂q − (∂²ℓ/∂q̇∂q) q̇ − ∂²ℓ/∂q̇∂t` into `force`: `n` hyper-dual and
    /// `n` dual evaluations.
    pub fn force<F: ScalarField>(
        &mut self,
        f: &F,
        t: T,
        q: &[T],
        qd: &[T],
        p: &[T],
        force: &mut [T],
    ) {
        let n = self.n;
        let hd = &mut self.hd;
        hd.params(p);
        // d/dt (∂ℓ/∂q̇_i) along (q̇, q̈ = 0, 1): eps1 picks ∂/∂q̇_i, eps2 is the time jet.
        let t_jet = HyperDual::new(t, zero(), one(), zero());
        for (i, fi) in force.iter_mut().enumerate().take(n) {
            hd.constant(q, qd);
            for (s, &v) in hd.q.iter_mut().zip(qd) {
                s.eps2 = v;
            }
            hd.qd[i].eps1 = one();
            let v = f.eval(t_jet, &hd.q, &hd.qd, &hd.p);
            *fi = -v.eps1eps2;
        }
        let d = &mut self.d;
        d.params(p);
        let t_const = Dual::from_re(t);
        for (i, fi) in force.iter_mut().enumerate().take(n) {
            d.constant(q, qd);
            d.q[i].eps = one();
            *fi += f.eval(t_const, &d.q, &d.qd, &d.p).eps;
        }
    }

    /// The energy `E = q̇·∂ℓ/∂q̇ − ℓ` (one dual evaluation).
    pub fn energy<F: ScalarField>(&mut self, f: &F, t: T, q: &[T], qd: &[T], p: &[T]) -> T {
        let d = &mut self.d;
        d.params(p);
        d.constant(q, qd);
        for (s, &v) in d.qd.iter_mut().zip(qd) {
            s.eps = v;
        }
        let v = f.eval(Dual::from_re(t), &d.q, &d.qd, &d.p);
        v.eps - v.re
    }

    /// The momenta `p = ∂ℓ/∂q̇` into `p` (n dual evaluations).
    pub fn momentum<F: ScalarField>(
        &mut self,
        f: &F,
        t: T,
        q: &[T],
        qd: &[T],
        params: &[T],
        p: &mut [T],
    ) {
        let d = &mut self.d;
        d.params(params);
        for (i, pi) in p.iter_mut().enumerate().take(self.n) {
            d.constant(q, qd);
            d.qd[i].eps = one();
            *pi = f.eval(Dual::from_re(t), &d.q, &d.qd, &d.p).eps;
        }
    }

    /// For a vector field `v`: its value, `∂v/∂q̇` into `jac` (m×n) and
    /// `v̇₀ = (∂v/∂q) q̇ + ∂v/∂t` into `rate0` (n + 1 dual evaluations).
    pub fn velocity_jacobian<V: VectorField>(
        &mut self,
        v: &V,
        t: T,
        q: &[T],
        qd: &[T],
        value: &mut [T],
        jac: &mut DMatrixViewMut<T>,
        rate0: &mut [T],
    ) {
        let m = v.m();
        self.jacobian(v, Wrt::Velocities, t, q, qd, jac);
        let d = &mut self.d;
        d.constant(q, qd);
        for (s, &x) in d.q.iter_mut().zip(qd) {
            s.eps = x;
        }
        v.eval(Dual::new(t, one()), &d.q, &d.qd, &mut d.out[..m]);
        for i in 0..m {
            value[i] = d.out[i].re;
            rate0[i] = d.out[i].eps;
        }
    }

    /// For a field that depends on `(q, t)` only (holonomic constraints `f`):
    /// its value, `F = ∂f/∂q` into `jac` (m×n), `ḟ = F q̇ + ∂f/∂t` into `rate`
    /// and `f̈₀ = (d/dt F) q̇ + d/dt ∂f/∂t` (the part of `f̈` without `q̈`) into
    /// `accel0` (n dual and one second-order dual evaluation).
    pub fn position_jacobian<V: VectorField>(
        &mut self,
        v: &V,
        t: T,
        q: &[T],
        qd: &[T],
        value: &mut [T],
        jac: &mut DMatrixViewMut<T>,
        rate: &mut [T],
        accel0: &mut [T],
    ) {
        let m = v.m();
        self.jacobian(v, Wrt::Positions, t, q, qd, jac);
        let d2 = &mut self.d2;
        d2.constant(q, qd);
        for (s, &x) in d2.q.iter_mut().zip(qd) {
            s.v1 = x;
        }
        v.eval(
            Dual2::new(t, one(), zero()),
            &d2.q,
            &d2.qd,
            &mut d2.out[..m],
        );
        for i in 0..m {
            value[i] = d2.out[i].re;
            rate[i] = d2.out[i].v1;
            accel0[i] = d2.out[i].v2;
        }
    }

    /// `∂v/∂q̇` or `∂v/∂q` into `jac` (m×n), one dual evaluation per column.
    fn jacobian<V: VectorField>(
        &mut self,
        v: &V,
        wrt: Wrt,
        t: T,
        q: &[T],
        qd: &[T],
        jac: &mut DMatrixViewMut<T>,
    ) {
        let m = v.m();
        let d = &mut self.d;
        let t_const = Dual::from_re(t);
        for j in 0..self.n {
            d.constant(q, qd);
            match wrt {
                Wrt::Positions => d.q[j].eps = one(),
                Wrt::Velocities => d.qd[j].eps = one(),
            }
            v.eval(t_const, &d.q, &d.qd, &mut d.out[..m]);
            for i in 0..m {
                jac[(i, j)] = d.out[i].eps;
            }
        }
    }
}
