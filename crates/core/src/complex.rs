//! A complex scalar for scene functions and their automatic differentiation.
//!
//! [`C64`] wraps [`num_complex::Complex64`] and implements num-dual's
//! [`DualNum`] with `Primitive = f64`, so it is a [`Scalar`](crate::Scalar)
//! and so are the num-dual numbers over it (`Dual<C64>`, `Dual2<C64>`,
//! `Dual3<C64>`, `HyperDual<C64>`, `Dual2<Dual2<C64>>`, ...): a scene's
//! Lagrangian, constraints and embedding map, written once over
//! `D: Scalar`, are then evaluated and differentiated at complex states, as
//! continuing a real solution along a path in complex time needs.
//!
//! # Values
//!
//! Arithmetic is num-complex's. Every elementary function is the
//! principal-branch complex function: num-complex's (`sqrt`, `cbrt`, `exp`,
//! `exp2`, `ln`, `log`, `log2`, `log10`, `powi`, `powf`, `powd` = `powc`,
//! `sin`, `cos`, `tan`, `acos`, `sinh`, `cosh`, `tanh`, `acosh`), or the
//! same function written here where num-complex's formula loses relative
//! accuracy at small `|z|` (`exp_m1`, `ln_1p`, `asin`, `atan`, `asinh`,
//! `atanh`, by `ln_1p`), or where num-complex has none (`atan2`,
//! `sph_j0..2`); see each. On the real axis the values are `f64`'s up to
//! rounding wherever `f64` has a real value, with one exception that comes
//! from the principal branch: `cbrt` of a negative real is `∛|x|·e^{iπ/3}`
//! (not `−∛|x|`). `sqrt`, `ln`, `powf`, `asin`, ... outside their real
//! domains give the principal complex values (where `f64` gives NaN).
//!
//! # Derivatives
//!
//! num-dual's derivative formulas are written in terms of the inner type's
//! functions, so over `C64` they give complex derivatives `d/dz` of the
//! values above — with two exceptions, both in num-dual's formulas, which
//! this crate cannot change:
//!
//! * `acosh`: num-dual's derivative is `√(1/(z² − 1))`, which is the
//!   derivative of the principal `acosh` only for `Re z > 0`; for
//!   `Re z < 0` it has the opposite sign (it is the derivative of
//!   `ln(z + √(z² − 1))`, another branch).
//! * `sph_j0`, `sph_j1`, `sph_j2` of a dual number switch to their series at
//!   zero when `|Re z| < ε`, i.e. by the real part only: for a dual number
//!   whose value is (nearly) purely imaginary they return the series'
//!   value, which is wrong. `C64`'s own `sph_j*` decide by `|z|`.
//!
//! # Real-only notions
//!
//! `DualNum` asks for a few notions that only make sense on the real line
//! (`Signed`, `PartialOrd`, `DualStruct::re`). Each is the analytic
//! continuation from the real axis where one exists, and otherwise follows
//! the real part, so that code branching on them takes the branch real
//! code takes at the real part; see [`C64`]'s trait impls.

use std::fmt;
use std::iter::{Product, Sum};
use std::ops::{
    Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Rem, RemAssign, Sub, SubAssign,
};

pub use num_complex::Complex64;
use num_dual::{DualNum, DualStruct, Mappable};
use num_traits::{FromPrimitive, Inv, Num, One, Signed, Zero};

/// A complex number usable wherever scene functions take a
/// [`Scalar`](crate::Scalar); see the [module docs](self) for its values,
/// derivatives and real-only notions.
///
/// `re()` (inherent, and [`DualStruct::re`]) is the real part; a num-dual
/// number over `C64` reports the real part of its value through `re()`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct C64(pub Complex64);

impl C64 {
    /// `re + i·im`.
    #[inline]
    pub const fn new(re: f64, im: f64) -> Self {
        C64(Complex64::new(re, im))
    }

    /// The imaginary unit.
    pub const I: C64 = C64::new(0.0, 1.0);

    /// Real part.
    #[inline]
    pub fn re(&self) -> f64 {
        self.0.re
    }

    /// Imaginary part.
    #[inline]
    pub fn im(&self) -> f64 {
        self.0.im
    }

    /// `|z|`.
    #[inline]
    pub fn norm(&self) -> f64 {
        self.0.norm()
    }

    /// Principal argument in `(−π, π]`.
    #[inline]
    pub fn arg(&self) -> f64 {
        self.0.arg()
    }

    /// Complex conjugate.
    #[inline]
    pub fn conj(&self) -> Self {
        C64(self.0.conj())
    }

    /// `r·e^{iθ}`.
    #[inline]
    pub fn from_polar(r: f64, theta: f64) -> Self {
        C64(Complex64::from_polar(r, theta))
    }
}

impl From<f64> for C64 {
    #[inline]
    fn from(re: f64) -> Self {
        C64::new(re, 0.0)
    }
}

impl From<Complex64> for C64 {
    #[inline]
    fn from(z: Complex64) -> Self {
        C64(z)
    }
}

impl From<C64> for Complex64 {
    #[inline]
    fn from(z: C64) -> Self {
        z.0
    }
}

impl fmt::Display for C64 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.0, f)
    }
}

impl fmt::LowerExp for C64 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::LowerExp::fmt(&self.0, f)
    }
}

/* arithmetic: num-complex's, with C64, &C64 and f64 right-hand sides */

macro_rules! binop {
    ($op:ident, $method:ident, $op_assign:ident, $method_assign:ident) => {
        impl $op for C64 {
            type Output = C64;
            #[inline]
            fn $method(self, rhs: C64) -> C64 {
                C64($op::$method(self.0, rhs.0))
            }
        }
        impl $op<&C64> for C64 {
            type Output = C64;
            #[inline]
            fn $method(self, rhs: &C64) -> C64 {
                C64($op::$method(self.0, rhs.0))
            }
        }
        impl $op<C64> for &C64 {
            type Output = C64;
            #[inline]
            fn $method(self, rhs: C64) -> C64 {
                C64($op::$method(self.0, rhs.0))
            }
        }
        impl $op<&C64> for &C64 {
            type Output = C64;
            #[inline]
            fn $method(self, rhs: &C64) -> C64 {
                C64($op::$method(self.0, rhs.0))
            }
        }
        impl $op<f64> for C64 {
            type Output = C64;
            #[inline]
            fn $method(self, rhs: f64) -> C64 {
                C64($op::$method(self.0, rhs))
            }
        }
        impl $op_assign for C64 {
            #[inline]
            fn $method_assign(&mut self, rhs: C64) {
                $op_assign::$method_assign(&mut self.0, rhs.0)
            }
        }
        impl $op_assign<&C64> for C64 {
            #[inline]
            fn $method_assign(&mut self, rhs: &C64) {
                $op_assign::$method_assign(&mut self.0, rhs.0)
            }
        }
        impl $op_assign<f64> for C64 {
            #[inline]
            fn $method_assign(&mut self, rhs: f64) {
                $op_assign::$method_assign(&mut self.0, rhs)
            }
        }
    };
}

binop!(Add, add, AddAssign, add_assign);
binop!(Sub, sub, SubAssign, sub_assign);
binop!(Mul, mul, MulAssign, mul_assign);
binop!(Div, div, DivAssign, div_assign);
// num-complex's remainder (of the Gaussian-integer-like quotient); not
// analytic, required by `Num`, never used by scene functions.
binop!(Rem, rem, RemAssign, rem_assign);

impl Neg for C64 {
    type Output = C64;
    #[inline]
    fn neg(self) -> C64 {
        C64(-self.0)
    }
}

impl Neg for &C64 {
    type Output = C64;
    #[inline]
    fn neg(self) -> C64 {
        C64(-self.0)
    }
}

impl Inv for C64 {
    type Output = C64;
    #[inline]
    fn inv(self) -> C64 {
        self.recip()
    }
}

impl Sum for C64 {
    fn sum<I: Iterator<Item = C64>>(iter: I) -> C64 {
        iter.fold(C64::zero(), |a, b| a + b)
    }
}

impl<'a> Sum<&'a C64> for C64 {
    fn sum<I: Iterator<Item = &'a C64>>(iter: I) -> C64 {
        iter.fold(C64::zero(), |a, b| a + b)
    }
}

impl Product for C64 {
    fn product<I: Iterator<Item = C64>>(iter: I) -> C64 {
        iter.fold(C64::one(), |a, b| a * b)
    }
}

impl<'a> Product<&'a C64> for C64 {
    fn product<I: Iterator<Item = &'a C64>>(iter: I) -> C64 {
        iter.fold(C64::one(), |a, b| a * b)
    }
}

impl Zero for C64 {
    #[inline]
    fn zero() -> Self {
        C64::new(0.0, 0.0)
    }
    /// Both parts zero.
    #[inline]
    fn is_zero(&self) -> bool {
        self.0.is_zero()
    }
}

impl One for C64 {
    #[inline]
    fn one() -> Self {
        C64::new(1.0, 0.0)
    }
}

impl Num for C64 {
    type FromStrRadixErr = <Complex64 as Num>::FromStrRadixErr;
    /// num-complex's parser (`a+bi`, `a`, `bi`).
    fn from_str_radix(s: &str, radix: u32) -> Result<Self, Self::FromStrRadixErr> {
        Complex64::from_str_radix(s, radix).map(C64)
    }
}

macro_rules! from_primitive {
    ($($method:ident: $t:ty),*) => {
        $(
            #[inline]
            fn $method(n: $t) -> Option<Self> {
                f64::$method(n).map(C64::from)
            }
        )*
    };
}

/// Real values, as `f64`'s conversions give them.
impl FromPrimitive for C64 {
    from_primitive!(
        from_isize: isize, from_i8: i8, from_i16: i16, from_i32: i32, from_i64: i64,
        from_i128: i128, from_usize: usize, from_u8: u8, from_u16: u16, from_u32: u32,
        from_u64: u64, from_u128: u128, from_f32: f32, from_f64: f64
    );
}

/// `|x|` and the sign have no analytic continuation through `x = 0`, but on
/// either side of it they do: `|x| = x·sign(x)` with a constant sign. Off
/// the real axis that constant is taken from the real part, as num-dual
/// does for dual numbers (`|a + bε| = (a + bε)·sign(a)`); the imaginary part
/// never decides a sign.
impl Signed for C64 {
    /// `z·sign(Re z)`: `z` if `Re z` has its sign bit clear (`Re z > 0` or
    /// `+0`), else `−z`. The analytic continuation of `|x|` from the side of
    /// the real axis that `Re z` is on; on the real axis `f64::abs`'s value.
    #[inline]
    fn abs(&self) -> Self {
        if self.0.re.is_sign_positive() {
            *self
        } else {
            -*self
        }
    }

    /// `a − b` if `Re a > Re b`, else `0` (on the real axis `f64`'s
    /// `abs_sub`).
    #[inline]
    fn abs_sub(&self, other: &Self) -> Self {
        if self.0.re <= other.0.re {
            C64::zero()
        } else {
            *self - *other
        }
    }

    /// `sign(Re z)` as `±1` (`f64::signum` of the real part, NaN for NaN): a
    /// constant, the analytic continuation of `sign(x)` from the side of the
    /// real axis that `Re z` is on, with `abs(z) = z·signum(z)`.
    #[inline]
    fn signum(&self) -> Self {
        C64::new(self.0.re.signum(), 0.0)
    }

    /// The sign bit of `Re z` is clear (as `f64::is_positive` of the real part).
    #[inline]
    fn is_positive(&self) -> bool {
        self.0.re.is_sign_positive()
    }

    /// The sign bit of `Re z` is set (as `f64::is_negative` of the real part).
    #[inline]
    fn is_negative(&self) -> bool {
        self.0.re.is_sign_negative()
    }
}

/// Ordered by the real part, so that a comparison takes the branch real code
/// takes at `Re z` (num-dual orders its dual numbers by their value the same
/// way). Consistent with `==`, which compares both parts: two different
/// values with equal real parts are unordered (`None`; every `<`, `<=`, `>`,
/// `>=` between them is false).
impl PartialOrd for C64 {
    #[inline]
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        if self == other {
            Some(std::cmp::Ordering::Equal)
        } else {
            match self.0.re.partial_cmp(&other.0.re) {
                Some(std::cmp::Ordering::Equal) => None,
                o => o,
            }
        }
    }
}

/// `z == x` iff `Re z == x` and `Im z == 0`.
impl PartialEq<f64> for C64 {
    #[inline]
    fn eq(&self, other: &f64) -> bool {
        self.0.re == *other && self.0.im == 0.0
    }
}

/// As comparing with `C64::from(x)`: by the real part, unordered when the
/// real parts are equal and `Im z ≠ 0`.
impl PartialOrd<f64> for C64 {
    #[inline]
    fn partial_cmp(&self, other: &f64) -> Option<std::cmp::Ordering> {
        self.partial_cmp(&C64::from(*other))
    }
}

/// `re()` is the real part; the inner type is `C64` itself.
impl DualStruct for C64 {
    type Real = f64;
    type Inner = C64;
    #[inline]
    fn re(&self) -> f64 {
        self.0.re
    }
    #[inline]
    fn from_inner(inner: &C64) -> Self {
        *inner
    }
}

impl Mappable<C64> for C64 {
    type Output<O> = O;
    #[inline]
    fn map_dual<M: Fn(C64) -> O, O>(self, f: M) -> O {
        f(self)
    }
}

impl DualNum for C64 {
    type Primitive = f64;

    const NDERIV: usize = 0;

    type InnerDual = C64;

    #[inline]
    fn from_re(re: C64) -> Self {
        re
    }

    #[inline]
    fn scale(self, factor: &C64) -> Self {
        self * factor
    }

    /// `1/z` (num-complex's `inv`: `z̄/|z|²`).
    #[inline]
    fn recip(&self) -> Self {
        C64(self.0.inv())
    }

    /// `zⁿ` by repeated squaring (of `1/z` for `n < 0`).
    #[inline]
    fn powi(&self, n: i32) -> Self {
        C64(self.0.powi(n))
    }

    /// Principal `zⁿ = |z|ⁿ e^{i n arg z}`.
    #[inline]
    fn powf(&self, n: f64) -> Self {
        C64(self.0.powf(n))
    }

    /// Principal `zʷ = e^{w ln z}` (`1` for `w = 0`).
    #[inline]
    fn powd(&self, exp: Self) -> Self {
        C64(self.0.powc(exp.0))
    }

    /// Principal square root (cut along `(−∞, 0)`).
    #[inline]
    fn sqrt(&self) -> Self {
        C64(self.0.sqrt())
    }

    /// Principal cube root (cut along `(−∞, 0)`): not `f64::cbrt` for
    /// negative reals, e.g. `cbrt(−8) = 1 + i√3`.
    #[inline]
    fn cbrt(&self) -> Self {
        C64(self.0.cbrt())
    }

    #[inline]
    fn exp(&self) -> Self {
        C64(self.0.exp())
    }

    #[inline]
    fn exp2(&self) -> Self {
        C64(self.0.exp2())
    }

    /// `eᶻ − 1` without cancellation for small `|z|`:
    /// `(eᵃ − 1) cos b − 2 sin²(b/2) + i eᵃ sin b` for `z = a + ib`
    /// (`f64::exp_m1`'s value on the real axis).
    #[inline]
    fn exp_m1(&self) -> Self {
        let (a, b) = (self.0.re, self.0.im);
        let (sb, cb) = b.sin_cos();
        let h = (0.5 * b).sin();
        C64::new(a.exp_m1() * cb - 2.0 * h * h, a.exp() * sb)
    }

    /// Principal logarithm (cut along `(−∞, 0]`).
    #[inline]
    fn ln(&self) -> Self {
        C64(self.0.ln())
    }

    #[inline]
    fn log(&self, base: f64) -> Self {
        C64(self.0.log(base))
    }

    #[inline]
    fn log2(&self) -> Self {
        C64(self.0.log2())
    }

    #[inline]
    fn log10(&self) -> Self {
        C64(self.0.log10())
    }

    /// Principal `ln(1 + z)` without cancellation for small `|z|`:
    /// `½ ln_1p(2a + a² + b²) + i atan2(b, 1 + a)` for `|z| < ½`
    /// (`f64::ln_1p` on the real axis), `ln(1 + z)` elsewhere.
    #[inline]
    fn ln_1p(&self) -> Self {
        let (a, b) = (self.0.re, self.0.im);
        if b == 0.0 && a > -1.0 {
            C64::new(a.ln_1p(), b)
        } else if self.0.norm() < 0.5 {
            C64::new(
                0.5 * (a.mul_add(a, 2.0 * a) + b * b).ln_1p(),
                b.atan2(1.0 + a),
            )
        } else {
            C64((self.0 + 1.0).ln())
        }
    }

    #[inline]
    fn sin(&self) -> Self {
        C64(self.0.sin())
    }

    #[inline]
    fn cos(&self) -> Self {
        C64(self.0.cos())
    }

    #[inline]
    fn tan(&self) -> Self {
        C64(self.0.tan())
    }

    /// `(sin z, cos z)`, num-complex's values from one `sin_cos` of `Re z`
    /// and one `sinh`, `cosh` of `Im z`.
    #[inline]
    fn sin_cos(&self) -> (Self, Self) {
        let (a, b) = (self.0.re, self.0.im);
        let (sa, ca) = a.sin_cos();
        let (shb, chb) = (b.sinh(), b.cosh());
        (C64::new(sa * chb, ca * shb), C64::new(ca * chb, -sa * shb))
    }

    /// Principal arcsine (cuts along `(−∞, −1)` and `(1, ∞)`):
    /// num-complex's `−i ln(√(1 − z²) + iz)`, written as
    /// `−i ln_1p(iz − z²/(1 + √(1 − z²)))` (the same function, since
    /// `1 − z²/(1 + s) = s` for `s² = 1 − z²`) to keep its relative accuracy
    /// at small `|z|`.
    #[inline]
    fn asin(&self) -> Self {
        let z = self.0;
        let s = (Complex64::new(1.0, 0.0) - z * z).sqrt();
        let w = Complex64::new(-z.im, z.re) - z * z / (s + 1.0);
        let l = C64(w).ln_1p().0;
        // −i·l
        C64::new(l.im, -l.re)
    }

    /// Principal arccosine (cuts along `(−∞, −1)` and `(1, ∞)`).
    #[inline]
    fn acos(&self) -> Self {
        C64(self.0.acos())
    }

    /// Principal arctangent (cuts along `±i·[1, ∞)`): num-complex's
    /// `(ln(1 + iz) − ln(1 − iz))/(2i)`, evaluated as `−i atanh(iz)` with
    /// `ln_1p` (relative accuracy at small `|z|`, `f64::atan`'s value up to
    /// rounding on the real axis, `±i∞` at `±i`).
    #[inline]
    fn atan(&self) -> Self {
        let t = C64::new(-self.0.im, self.0.re).atanh().0;
        // −i·t
        C64::new(t.im, -t.re)
    }

    /// Principal two-argument arctangent of `y = self` and `x = other`:
    /// `−i ln((x + iy)/√(x² + y²))`, the analytic continuation of
    /// `f64::atan2` off the real plane (with whose value it agrees exactly
    /// when both arguments are real). Singular where `x² + y² = 0`, with
    /// cuts where `x² + y² ≤ 0` or `(x + iy)/√(x² + y²) ≤ 0`. For the
    /// quadrant-switching arctangent of scenes see
    /// [`crate::scene::atan2`].
    #[inline]
    fn atan2(&self, other: Self) -> Self {
        let (y, x) = (self.0, other.0);
        if y.im == 0.0 && x.im == 0.0 {
            return C64::new(y.re.atan2(x.re), 0.0);
        }
        let w = ((x + Complex64::i() * y) / (x * x + y * y).sqrt()).ln();
        // −i·w
        C64::new(w.im, -w.re)
    }

    #[inline]
    fn sinh(&self) -> Self {
        C64(self.0.sinh())
    }

    #[inline]
    fn cosh(&self) -> Self {
        C64(self.0.cosh())
    }

    #[inline]
    fn tanh(&self) -> Self {
        C64(self.0.tanh())
    }

    /// Principal area sine (cuts along `±i·(1, ∞)`): num-complex's
    /// `ln(z + √(1 + z²))`, evaluated as `ln_1p(z + z²/(1 + √(1 + z²)))`
    /// where the sign bit of `Re z` is clear and as `−asinh(−z)` elsewhere
    /// (the same function, odd; num-complex's form loses the relative
    /// accuracy at small `|z|` and all of it for large negative `Re z`).
    #[inline]
    fn asinh(&self) -> Self {
        if self.0.re.is_sign_negative() {
            return -(-*self).asinh();
        }
        let z = self.0;
        let s = (z * z + 1.0).sqrt();
        C64(z + z * z / (s + 1.0)).ln_1p()
    }

    /// Principal area cosine (cut along `(−∞, 1)`). num-dual differentiates
    /// it correctly only for `Re z > 0` (module docs).
    #[inline]
    fn acosh(&self) -> Self {
        C64(self.0.acosh())
    }

    /// Principal area tangent (cuts along `(−∞, −1]` and `[1, ∞)`):
    /// num-complex's `(ln(1 + z) − ln(1 − z))/2`, with `ln_1p` for relative
    /// accuracy at small `|z|` (`±∞` at `±1`).
    #[inline]
    fn atanh(&self) -> Self {
        (self.ln_1p() - (-*self).ln_1p()) * 0.5
    }

    /// `sin z / z`; `1 − z²/6` for `|z| < ε`.
    #[inline]
    fn sph_j0(&self) -> Self {
        if self.0.norm() < f64::EPSILON {
            C64::one() - *self * *self / 6.0
        } else {
            self.sin() / *self
        }
    }

    /// `(sin z / z − cos z)/z`; `z/3` for `|z| < ε`.
    #[inline]
    fn sph_j1(&self) -> Self {
        if self.0.norm() < f64::EPSILON {
            *self / 3.0
        } else {
            let (s, c) = self.sin_cos();
            let rec = self.recip();
            (s * rec - c) * rec
        }
    }

    /// `((3 − z²) sin z − 3z cos z)/z³`; `z²/15` for `|z| < ε`.
    #[inline]
    fn sph_j2(&self) -> Self {
        if self.0.norm() < f64::EPSILON {
            *self * *self / 15.0
        } else {
            let (s, c) = self.sin_cos();
            let z2 = *self * *self;
            ((-z2 + 3.0) * s - *self * c * 3.0) / (*self * z2)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cmp::Ordering;

    const Z: C64 = C64::new(0.7, -1.3);

    #[test]
    fn order_follows_the_real_part_and_agrees_with_equality() {
        let (a, b) = (C64::new(1.0, 5.0), C64::new(2.0, -3.0));
        assert_eq!([a < b, b > a, a <= b, a >= b], [true, true, true, false]);
        assert_eq!(a.partial_cmp(&a), Some(Ordering::Equal));
        // Equal real parts, different values: unordered.
        let c = C64::new(1.0, -5.0);
        assert_ne!(a, c);
        assert_eq!(a.partial_cmp(&c), None);
        assert_eq!([a < c, a > c, a <= c, a >= c], [false; 4]);
        // Against f64.
        assert!(C64::new(0.5, 9.0) < 1.0 && C64::new(1.5, -9.0) > 1.0);
        assert_eq!(C64::new(1.0, 0.0), 1.0);
        assert_ne!(C64::new(1.0, 1e-300), 1.0);
        assert_eq!(C64::new(1.0, 2.0).partial_cmp(&1.0), None);
        assert_eq!(C64::new(1.0, -0.0).partial_cmp(&1.0), Some(Ordering::Equal));
    }

    #[test]
    fn signs_follow_the_real_part() {
        assert_eq!(Z.abs(), Z);
        assert_eq!((-Z).abs(), Z);
        assert_eq!(Z.signum(), C64::one());
        assert_eq!((-Z).signum(), -C64::one());
        assert_eq!(Z.abs(), Z * Z.signum());
        assert!(Z.is_positive() && !Z.is_negative());
        assert!((-Z).is_negative() && !(-Z).is_positive());
        // On the real axis f64's values, signed zeros included.
        for x in [2.5, -2.5, 0.0, -0.0] {
            let z = C64::from(x);
            assert_eq!(z.abs().re().to_bits(), x.abs().to_bits(), "{x}");
            assert_eq!(z.signum().re(), Signed::signum(&x), "{x}");
            assert_eq!(z.is_positive(), Signed::is_positive(&x), "{x}");
            assert_eq!(z.is_negative(), Signed::is_negative(&x), "{x}");
        }
        // Purely imaginary: the sign of the real zero decides.
        assert_eq!(C64::new(0.0, -2.0).abs(), C64::new(0.0, -2.0));
        assert_eq!(C64::new(-0.0, -2.0).abs(), C64::new(0.0, 2.0));
        assert_eq!(
            C64::new(3.0, 1.0).abs_sub(&C64::new(1.0, 4.0)),
            C64::new(2.0, -3.0)
        );
        assert_eq!(C64::new(1.0, 1.0).abs_sub(&C64::new(3.0, 4.0)), C64::zero());
    }

    #[test]
    fn dual_struct_and_conversions() {
        assert_eq!(DualStruct::re(&Z), 0.7);
        assert_eq!(Z.im(), -1.3);
        assert_eq!(<C64 as DualStruct>::from_inner(&Z), Z);
        assert_eq!(<C64 as DualNum>::from_re(Z), Z);
        assert_eq!(Z.scale(&C64::I), Z * C64::I);
        assert_eq!(C64::from_f64(2.5), Some(C64::new(2.5, 0.0)));
        assert_eq!(C64::from_i32(-3), Some(C64::new(-3.0, 0.0)));
        assert_eq!(C64::from_u64(7), Some(C64::new(7.0, 0.0)));
        assert_eq!(
            C64::from_str_radix("1.5-2i", 10).ok(),
            Some(C64::new(1.5, -2.0))
        );
        assert_eq!(format!("{}", C64::new(1.5, -2.0)), "1.5-2i");
        assert!(C64::zero().is_zero() && !C64::new(0.0, 1e-300).is_zero());
        assert!(C64::one().is_one());
        assert_eq!(Z.inv(), Z.recip());
        assert_eq!([Z, C64::I].iter().sum::<C64>(), Z + C64::I);
        assert_eq!([Z, C64::I].into_iter().product::<C64>(), Z * C64::I);
        assert_eq!(Z.map_dual(|z| z.im()), -1.3);
    }

    #[test]
    fn atan2_is_f64s_on_real_arguments_and_the_principal_continuation_off_them() {
        for (y, x) in [
            (1.0, 2.0),
            (-1.0, 2.0),
            (1.0, -2.0),
            (-1.0, -2.0),
            (0.0, -1.0),
        ] {
            let v = C64::from(y).atan2(C64::from(x));
            assert_eq!(v, C64::new(f64::atan2(y, x), 0.0));
        }
        assert_eq!(
            C64::from(-0.0).atan2(C64::from(-1.0)).re(),
            -std::f64::consts::PI
        );
        // Off the real plane: tan of the value is y/x, and the value is
        // continuous with the real one.
        let (y, x) = (C64::new(0.8, 0.3), C64::new(-0.5, 0.2));
        let v = y.atan2(x);
        assert!((v.tan() - y / x).norm() < 1e-14);
        let (y0, x0) = (C64::new(0.8, 1e-9), C64::new(-0.5, -1e-9));
        assert!((y0.atan2(x0).re() - f64::atan2(0.8, -0.5)).abs() < 1e-8);
        assert!(y0.atan2(x0).im().abs() < 1e-8);
    }
}
