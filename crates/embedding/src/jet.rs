//! Truncated Taylor polynomials in time carried by (nested) dual numbers.
//!
//! A curve `x(τ)` with derivatives `x⁽⁰⁾ … x⁽ᴷ⁾` at `τ = 0` is seeded into a
//! dual number whose arithmetic then propagates every derivative up to
//! order `K` exactly. `Dual2` and `Dual3` carry orders 2 and 3; order 4 uses
//! `Dual2<Dual2<T>>` with `τ = ε₁ + ε₂`, since `∂ᵃ_ε₁ ∂ᵇ_ε₂ x(ε₁ + ε₂) = x⁽ᵃ⁺ᵇ⁾`.

use nonholo_core::Scalar;
use num_dual::{Dual2, Dual3};

/// A time jet of order [`TimeJet::ORDER`] over base scalar `T`.
pub trait TimeJet<T: Scalar>: Scalar {
    const ORDER: usize;
    /// The jet of a curve with derivatives `d[k]` (missing ones are zero).
    fn from_derivatives(d: &[T]) -> Self;
    /// The `k`-th time derivative at `τ = 0`.
    fn time_derivative(&self, k: usize) -> T;
}

fn at<T: Scalar>(d: &[T], k: usize) -> T {
    d.get(k).copied().unwrap_or(T::from(0.0))
}

impl<T: Scalar> TimeJet<T> for Dual2<T> {
    const ORDER: usize = 2;
    fn from_derivatives(d: &[T]) -> Self {
        Dual2::new(at(d, 0), at(d, 1), at(d, 2))
    }
    fn time_derivative(&self, k: usize) -> T {
        match k {
            0 => self.re,
            1 => self.v1,
            2 => self.v2,
            _ => T::from(0.0),
        }
    }
}

impl<T: Scalar> TimeJet<T> for Dual3<T> {
    const ORDER: usize = 3;
    fn from_derivatives(d: &[T]) -> Self {
        Dual3::new(at(d, 0), at(d, 1), at(d, 2), at(d, 3))
    }
    fn time_derivative(&self, k: usize) -> T {
        match k {
            0 => self.re,
            1 => self.v1,
            2 => self.v2,
            3 => self.v3,
            _ => T::from(0.0),
        }
    }
}

impl<T: Scalar> TimeJet<T> for Dual2<Dual2<T>> {
    const ORDER: usize = 4;
    fn from_derivatives(d: &[T]) -> Self {
        Dual2::new(
            Dual2::new(at(d, 0), at(d, 1), at(d, 2)),
            Dual2::new(at(d, 1), at(d, 2), at(d, 3)),
            Dual2::new(at(d, 2), at(d, 3), at(d, 4)),
        )
    }
    fn time_derivative(&self, k: usize) -> T {
        match k {
            0 => self.re.re,
            1 => self.re.v1,
            2 => self.re.v2,
            3 => self.v1.v2,
            4 => self.v2.v2,
            _ => T::from(0.0),
        }
    }
}

/// Order-4 time jet over `T`.
pub type Jet4<T> = Dual2<Dual2<T>>;

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::DualNum;

    /// Along the polynomial x(τ) = 0.3 + τ − 0.4τ² + 0.2τ³ + 0.05τ⁴ the
    /// order-4 jet of x² equals the product polynomial's derivatives, and the
    /// order-3 and order-4 jets of x² sin x agree up to order 3.
    #[test]
    fn jets_agree_with_each_other_and_with_polynomials() {
        // A polynomial: x(τ) = Σ c_k τ^k, derivatives x^(k)(0) = k! c_k.
        let c = [0.3, 1.0, -0.4, 0.2, 0.05];
        let fact = [1.0, 1.0, 2.0, 6.0, 24.0];
        let d: Vec<f64> = c.iter().zip(fact).map(|(c, f)| c * f).collect();
        // f(x) = x² has f(x(τ))^(k) known from the product of polynomials.
        let sq = |x: Jet4<f64>| x * x;
        let j4 = sq(Jet4::from_derivatives(&d));
        let mut prod = [0.0; 9];
        for i in 0..5 {
            for j in 0..5 {
                prod[i + j] += c[i] * c[j];
            }
        }
        for k in 0..=4 {
            let got: f64 = TimeJet::<f64>::time_derivative(&j4, k);
            assert!((got - prod[k] * fact[k]).abs() < 1e-14, "k = {k}");
        }
        let g3 = |x: Dual3<f64>| x * x * x.sin();
        let g4 = |x: Jet4<f64>| x * x * x.sin();
        let (a, b) = (
            g3(Dual3::from_derivatives(&d)),
            g4(Jet4::from_derivatives(&d)),
        );
        for k in 0..=3 {
            let (x, y): (f64, f64) = (
                TimeJet::<f64>::time_derivative(&a, k),
                TimeJet::<f64>::time_derivative(&b, k),
            );
            assert!((x - y).abs() < 1e-13, "k = {k}");
        }
    }

    /// The same jets over complex numbers (`C64`): along the complex
    /// polynomial x(τ) = Σ cₖ τᵏ the order-4 jet of x² is the product
    /// polynomial's, and the order-3 and order-4 jets of x² sin x agree.
    #[test]
    fn jets_over_complex_numbers() {
        use nonholo_core::C64;
        let c = [
            C64::new(0.3, -0.2),
            C64::new(1.0, 0.5),
            C64::new(-0.4, 0.1),
            C64::new(0.2, 0.0),
            C64::new(0.0, 0.05),
        ];
        let fact = [1.0, 1.0, 2.0, 6.0, 24.0];
        let d: Vec<C64> = c.iter().zip(fact).map(|(c, f)| *c * f).collect();
        let j4 = Jet4::from_derivatives(&d);
        let sq = j4 * j4;
        let mut prod = [C64::from(0.0); 9];
        for i in 0..5 {
            for j in 0..5 {
                prod[i + j] += c[i] * c[j];
            }
        }
        for k in 0..=4 {
            let got: C64 = TimeJet::<C64>::time_derivative(&sq, k);
            assert!((got - prod[k] * fact[k]).norm() < 1e-14, "k = {k}");
        }
        let a = Dual3::from_derivatives(&d);
        let (a, b) = (a * a * a.sin(), j4 * j4 * j4.sin());
        for k in 0..=3 {
            let (x, y): (C64, C64) = (
                TimeJet::<C64>::time_derivative(&a, k),
                TimeJet::<C64>::time_derivative(&b, k),
            );
            assert!((x - y).norm() < 1e-13, "k = {k}");
        }
    }
}
