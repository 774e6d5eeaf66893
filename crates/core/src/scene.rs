//! What a scene is: named coordinates and parameters, one Lagrangian, and
//! only the optional pieces it has.
//!
//! Every function a scene writes is generic over a [`Scalar`] (a num-dual
//! number type), written once, and differentiated by [`crate::ad`]. Mass
//! matrix, forces, constraint Jacobians and their time derivatives are never
//! written by hand.

use num_dual::{Dual, Dual2, Dual3, DualNum, HyperDual, HyperHyperDual, Real};

use crate::Error;
use crate::complex::C64;
use crate::param::{ParamSpec, Params};

/// The number types scene functions are evaluated with: `f64`, the complex
/// [`C64`], and every (nested) num-dual number over them (`Dual`, `Dual2`,
/// `Dual3`, `HyperDual`, `HyperHyperDual`, `Real`; the vector duals need
/// num-dual's `nalgebra` feature, which the workspace does not enable).
pub trait Scalar: DualNum<Primitive = f64> + Copy + Send + Sync + 'static {
    /// The size of the value, for branch decisions (which formula, which
    /// pivot): `|x|` for `f64`, `|z|` for [`C64`], and for a dual number
    /// the modulus of its value part (the derivative parts never decide).
    ///
    /// For `f64` and every dual number over it this is `re().abs()`,
    /// bit for bit.
    fn modulus(&self) -> f64;

    /// The number with this one's value part and every derivative part
    /// zero (itself for `f64`, [`C64`] and a traced number).
    fn value_part(&self) -> Self;

    /// The angle `atan2(y, x)` of the value parts of `y` and `x`, on the
    /// branch nearest to `near` (see [`atan2_near`]), with every derivative
    /// part zero: the branch decisions of [`atan2_near`], in one place (a
    /// traced number records it as one operation, [`crate::graph`]).
    fn angle(y: Self, x: Self, near: Option<f64>) -> Self;

    /// Whether the type records operations into a graph instead of
    /// computing ([`crate::graph::Tracer`], and dual numbers over it): code
    /// that would let a value choose between formulas takes a form without
    /// the choice ([`atan2_near`]).
    const TRACED: bool = false;

    /// Whether the type is plain `f64` (no derivative parts): code that
    /// must leave automatic differentiation (a call into a numerical
    /// library) branches on it.
    const REAL: bool = false;

    /// Whether the type is a first-order dual number over `f64` (`Dual64`,
    /// a value and one directional derivative): [`Scalar::tangent`] and
    /// [`Scalar::from_tangent`] then split and join it, for code that
    /// propagates derivatives through a numerical library by hand (the
    /// sparse KKT solve of [`crate::sparse`]).
    const FIRST_ORDER: bool = false;

    /// The derivative part of a first-order dual number (0 otherwise).
    fn tangent(&self) -> f64 {
        0.0
    }

    /// The number with value `re` and derivative part `eps` (where
    /// [`Scalar::FIRST_ORDER`]; otherwise `re` alone).
    fn from_tangent(re: f64, _eps: f64) -> Self {
        Self::from(re)
    }

    /// The slice as `f64` values if the type is `f64` ([`Scalar::REAL`]),
    /// for code that runs native `f64` code on it
    /// ([`crate::graph::Program::run`]).
    fn as_real_mut(_x: &mut [Self]) -> Option<&mut [f64]> {
        None
    }

    /// [`Scalar::as_real_mut`] for reading.
    fn as_real(_x: &[Self]) -> Option<&[f64]> {
        None
    }

    /// The slice as the pairs `(re, eps)` of its numbers, `2 len` values,
    /// if the type is `Dual64` (laid out as two `f64`): for native code
    /// over dual numbers ([`crate::graph::Program::run`]).
    fn as_pairs_mut(_x: &mut [Self]) -> Option<&mut [f64]> {
        None
    }
}

impl Scalar for f64 {
    const REAL: bool = true;

    #[inline]
    fn as_real_mut(x: &mut [f64]) -> Option<&mut [f64]> {
        Some(x)
    }

    #[inline]
    fn as_real(x: &[f64]) -> Option<&[f64]> {
        Some(x)
    }

    #[inline]
    fn modulus(&self) -> f64 {
        self.abs()
    }

    #[inline]
    fn value_part(&self) -> Self {
        *self
    }

    fn angle(y: Self, x: Self, near: Option<f64>) -> Self {
        angle_of_values(y, x, near)
    }
}

impl Scalar for C64 {
    #[inline]
    fn modulus(&self) -> f64 {
        self.norm()
    }

    #[inline]
    fn value_part(&self) -> Self {
        *self
    }

    fn angle(y: Self, x: Self, near: Option<f64>) -> Self {
        angle_of_values(y, x, near)
    }
}

macro_rules! scalar_over_inner {
    ($($dual:ident),*) => {
        $(
            impl<T: Scalar> Scalar for $dual<T> {
                const TRACED: bool = T::TRACED;

                #[inline]
                fn modulus(&self) -> f64 {
                    self.re.modulus()
                }

                #[inline]
                fn value_part(&self) -> Self {
                    Self::from_re(self.re.value_part())
                }

                fn angle(y: Self, x: Self, near: Option<f64>) -> Self {
                    Self::from_re(T::angle(y.re, x.re, near))
                }
            }
        )*
    };
}

scalar_over_inner!(Real, Dual2, Dual3, HyperDual, HyperHyperDual);

impl<T: Scalar> Scalar for Dual<T> {
    const FIRST_ORDER: bool = T::REAL;
    const TRACED: bool = T::TRACED;

    #[inline]
    fn modulus(&self) -> f64 {
        self.re.modulus()
    }

    #[inline]
    fn value_part(&self) -> Self {
        Self::from_re(self.re.value_part())
    }

    fn angle(y: Self, x: Self, near: Option<f64>) -> Self {
        Self::from_re(T::angle(y.re, x.re, near))
    }

    #[inline]
    fn tangent(&self) -> f64 {
        self.eps.re()
    }

    #[inline]
    fn from_tangent(re: f64, eps: f64) -> Self {
        Dual::new(T::from(re), T::from(eps))
    }

    #[inline]
    fn as_pairs_mut(x: &mut [Self]) -> Option<&mut [f64]> {
        use std::mem::{offset_of, size_of};
        let pairs = std::any::TypeId::of::<Self>() == std::any::TypeId::of::<num_dual::Dual64>()
            && size_of::<Self>() == 16
            && offset_of!(Dual<T>, re) == 0
            && offset_of!(Dual<T>, eps) == 8;
        // SAFETY: `Self` is `Dual<f64>`, whose two `f64` fields lie at
        // offsets 0 and 8 of its 16 bytes (checked above): a slice of `len`
        // of them is `2 len` `f64` values, `re` first.
        pairs.then(|| unsafe {
            std::slice::from_raw_parts_mut(x.as_mut_ptr().cast::<f64>(), 2 * x.len())
        })
    }
}

/// Static-size vector duals (feature `vector-duals`): every first and
/// mixed second derivative along `M × N` directions in one evaluation.
#[cfg(feature = "vector-duals")]
impl<const M: usize, const N: usize> Scalar
    for num_dual::HyperDualVec<f64, nalgebra::Const<M>, nalgebra::Const<N>>
{
    #[inline]
    fn modulus(&self) -> f64 {
        self.re.abs()
    }

    #[inline]
    fn value_part(&self) -> Self {
        Self::from_re(self.re)
    }

    fn angle(y: Self, x: Self, near: Option<f64>) -> Self {
        Self::from_re(f64::angle(y.re, x.re, near))
    }
}

/// `atan2(y, x)` whose derivatives stay accurate in every quadrant:
/// [`atan2_near`] on `atan2`'s own branch `(−π, π]`.
pub fn atan2<D: Scalar>(y: D, x: D) -> D {
    atan2_near(y, x, None)
}

/// `atan2(y, x)` on the branch of `arctan(y/x)` nearest to `near` (its
/// branches differ by multiples of π; `atan2`'s own branch `(−π, π]` if
/// `near` is `None` or not finite), with derivatives accurate in every
/// quadrant. A heading continued through a reversal of the motion (where
/// `atan2` turns it by π) is the branch nearest to its last value.
///
/// num-dual 0.15 differentiates `atan2` through `y/x`; its high-order
/// derivatives then lose accuracy like `(√(x² + y²)/x)ᵏ` as `x → 0` (the
/// sleigh's heading through ±π/2: formulation A's fourth-order jets failed
/// there at `ẋ ≈ 0.002 m/s`). Numbers that compute (`f64`, [`C64`] and dual
/// numbers over them) evaluate `atan(y/x)` where `|x| ≥ |y|` and
/// `±π/2 − atan(x/y)` elsewhere, plus the constants that put the value on
/// the branch (see [`Scalar::angle`], which is that formula): a ratio of at
/// most one inside the arctangent, the cheapest accurate form.
///
/// A traced number ([`Scalar::TRACED`]) may not let a value choose the
/// formula (the trace must hold at every state), and takes the form that is
/// accurate everywhere without a choice: with `(x₀, y₀)` the value parts of
/// `(x, y)` (derivative parts zero),
///
/// ```text
/// atan2(y, x) = θ₀ + atan((x₀ y − y₀ x) / (x₀ x + y₀ y)),   θ₀ = Scalar::angle(y₀, x₀)
/// ```
///
/// (the arctangent is the angle from `(x₀, y₀)` to `(x, y)`: its argument
/// has value zero and derivatives with the denominator `x₀² + y₀²`). The
/// branch decisions are all in `θ₀`, which the trace records as one
/// operation ([`crate::graph::Node::Angle`]). The two forms are the same
/// function; their derivatives differ by round-off.
pub fn atan2_near<D: Scalar>(y: D, x: D, near: Option<f64>) -> D {
    if D::TRACED {
        let (y0, x0) = (y.value_part(), x.value_part());
        return D::angle(y0, x0, near) + ((x0 * y - y0 * x) / (x0 * x + y0 * y)).atan();
    }
    angle_of_values(y, x, near)
}

/// [`atan2_near`] for numbers that compute, and [`Scalar::angle`] for those
/// without derivative parts (`f64`, [`C64`]): `atan(y/x)` where
/// `|x| ≥ |y|` and `±π/2 − atan(x/y)` elsewhere, plus the constant that
/// puts the value on `atan2`'s branch `(−π, π]`, then the multiple of π
/// that brings its real part nearest to `near` (if finite).
///
/// The formula is chosen by [`Scalar::modulus`] of `x` and `y`, the
/// constant by signs of real parts (`re()`): of `x`, then where `|x| ≥ |y|`
/// and `Re x < 0` of `atan(y/x)`, and elsewhere of `y`. For real arguments
/// (`f64` and dual numbers over it) these are the comparisons above (with
/// `x < 0`, `atan(y/x)` has the opposite sign of `y`, signed zeros
/// included), and the value is `f64::atan2`'s up to rounding.
///
/// For complex arguments the ratio inside the arctangent has modulus at
/// most one, so it stays off `atan`'s branch cuts `±i·[1, ∞)` (it reaches
/// `±i` only where `x² + y² = 0`, where every `atan2` is singular). The
/// result is an analytic function of `(x, y)` whose tangent is `y/x` and
/// whose real part is in `[−π, π]`: it equals the principal value
/// (`−i ln((x + iy)/√(x² + y²))`) up to a constant multiple of `π`, and that
/// constant may change where the formula switches (`|x| = |y|`) or where a
/// real part that picks it changes sign (`Re x` or `Re atan(y/x)` where
/// `|x| ≥ |y|`, `Re y` elsewhere). A continuation along a path must track
/// that multiple itself. The derivatives (dual parts) do not see the
/// constant: they are exact everywhere off `x² + y² = 0`.
fn angle_of_values<D: Scalar>(y: D, x: D, near: Option<f64>) -> D {
    use std::f64::consts::{FRAC_PI_2, PI};
    let (yr, xr) = (y.re(), x.re());
    let principal = if x.modulus() >= y.modulus() {
        let a = (y / x).atan();
        // For real arguments with x < 0, atan(y/x) has the opposite sign of
        // y (signed zeros included): the same offset as by the sign of y.
        let offset = if xr >= 0.0 {
            0.0
        } else if a.re().is_sign_positive() {
            -PI
        } else {
            PI
        };
        a + offset
    } else {
        let offset = if yr > 0.0 { FRAC_PI_2 } else { -FRAC_PI_2 };
        -(x / y).atan() + offset
    };
    match near {
        Some(r) if r.is_finite() => {
            let k = ((r - principal.re()) / PI).round();
            if k == 0.0 {
                principal
            } else {
                principal + k * PI
            }
        }
        _ => principal,
    }
}

/// A named quantity: coordinate, convenience value or invariant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Named {
    pub name: &'static str,
    pub unit: &'static str,
    pub description: &'static str,
}

impl Named {
    pub const fn new(name: &'static str, unit: &'static str, description: &'static str) -> Self {
        Named {
            name,
            unit,
            description,
        }
    }
}

/// Largest number of components of a singular-set vector.
pub const MAX_SINGULAR: usize = 4;

/// How the nonholonomic constraints depend on the velocities.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConstraintKind {
    /// `g = A(q, t) q̇ + b(q, t)` (eq. 3 of the paper).
    Linear,
    /// General `g(q, q̇, t)`.
    Nonlinear,
}

/// The embedding map `q_D = φ(q_I, q̇_I, t)` of the paper (eq. 14).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmbeddingInfo {
    /// Indices of the independent coordinates `q_I` in `q`.
    pub independent: &'static [usize],
    /// Indices of the dependent coordinates `q_D` in `q`.
    pub dependent: &'static [usize],
    /// The dependent coordinates (a subset of `dependent`) of which the map
    /// gives only the velocity `q̇_c = φ_c(q_I, q̇_I, t)`: cyclic ones,
    /// absent from `L`, `f` and `g` (the rolling disk's angle `ψ`).
    /// Formulation A integrates them as quadratures of their rates.
    pub cyclic: &'static [usize],
    /// The map, as a formula.
    pub formula: &'static str,
    /// Where the map is singular.
    pub singular_set: &'static str,
    /// What it means in this scene when given dependent coordinates are on
    /// another branch of the map than its value (for messages).
    pub branch_note: &'static str,
    /// Where the third derivatives of the independent coordinates are not
    /// fixed by the lower ones, and what is free there (for messages).
    pub undetermined_note: &'static str,
}

/// A closed-form solution the scene knows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosedFormInfo {
    /// Formulation whose motion it is (`"chetaev"` for B).
    pub formulation: &'static str,
    /// Conditions under which it holds.
    pub conditions: &'static str,
}

/// A point of contact whose sliding the scene's nonholonomic constraints
/// forbid (a blade, a rolling wheel), for the realisations that let it slide
/// under dry friction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactInfo {
    /// Name in messages and records (`blade`).
    pub name: &'static str,
    /// The rows of `g` that are the contact's slip velocity in the contact
    /// plane, in an orthonormal frame (`m/s`): one row for a blade (lateral
    /// slip only), two for a wheel's contact point. The friction force on
    /// these components then does the power `fᵀg`.
    pub rows: &'static [usize],
    /// The normal load the scene puts on the contact ([`Scene::normal_load`]),
    /// as a formula with its modelling assumption.
    pub load: &'static str,
}

/// Static description of a scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneInfo {
    /// Name used on the command line (`sleigh-incline`).
    pub name: &'static str,
    pub title: &'static str,
    pub description: &'static str,
    /// Generalised coordinates `q` (length `n`).
    pub coordinates: &'static [Named],
    pub params: &'static [ParamSpec],
    /// The parameters that change the description itself (its coordinates
    /// and constraints), e.g. `sleigh-train`'s `N`: [`Scene::info`] then
    /// depends on the built scene, and an experiment may set them but not
    /// sweep them (its points would not share coordinates). Empty for most
    /// scenes.
    pub structural: &'static [&'static str],
    /// Holonomic constraints `f(q, t) = 0`, as formulas (their number is `k`).
    pub holonomic: &'static [&'static str],
    /// Nonholonomic constraints `g(q, q̇, t) = 0`, as formulas (their number is `s`).
    pub nonholonomic: &'static [&'static str],
    pub constraint_kind: ConstraintKind,
    /// Unit of the values of the nonholonomic constraints `g` (`m/s` for
    /// constraints on velocities; empty without them): it fixes the units of
    /// their multipliers (`J` over it) and of the realisations' gains.
    pub nonholonomic_unit: &'static str,
    /// Where the constraints themselves stop being differentiable, if anywhere.
    pub constraint_singular_set: Option<&'static str>,
    pub embedding: Option<EmbeddingInfo>,
    /// Named convenience values that fix all velocities at once
    /// (the sleigh's `u`, `omega`), see [`Scene::velocities_from`].
    pub velocity_chart: &'static [Named],
    /// Default positions `q0`.
    pub default_q: &'static [f64],
    /// Default convenience values (if the scene has a chart) or default `q̇0`.
    pub default_velocity: &'static [f64],
    pub closed_form: Option<ClosedFormInfo>,
    /// Scene-specific invariants, see [`Scene::invariant`] (energy is always measured).
    pub invariants: &'static [Named],
    /// Contacts that the nonholonomic constraints keep from sliding (empty
    /// if the constraints are not contacts).
    pub contacts: &'static [ContactInfo],
}

impl SceneInfo {
    /// Number of generalised coordinates `n`.
    pub fn n(&self) -> usize {
        self.coordinates.len()
    }

    /// Number of holonomic constraints `k`.
    pub fn k(&self) -> usize {
        self.holonomic.len()
    }

    /// Number of nonholonomic constraints `s`.
    pub fn s(&self) -> usize {
        self.nonholonomic.len()
    }

    pub fn coordinate_index(&self, name: &str) -> Option<usize> {
        self.coordinates.iter().position(|c| c.name == name)
    }
}

/// A mechanical system: a Lagrangian `L(q, q̇, t)` and the optional pieces it has.
///
/// Only [`Scene::lagrangian`] is required. The optional functions are called
/// only when [`SceneInfo`] declares the piece (non-empty `holonomic`,
/// non-empty `nonholonomic`, `embedding.is_some()`, ...), so a scene without a
/// piece never has anything computed for it.
pub trait Scene: Send + Sync + 'static {
    /// Static description (coordinates, parameters, which pieces exist).
    const INFO: &'static SceneInfo;

    /// [`Scene::INFO`] through an instance.
    fn info(&self) -> &'static SceneInfo {
        Self::INFO
    }

    /// Builds the scene from resolved parameters, checking relations between
    /// them (each value is already in its own range).
    fn from_params(params: &Params) -> Result<Self, Error>
    where
        Self: Sized;

    /// The parameters the scene was built from.
    fn params(&self) -> &Params;

    /// `L(q, q̇, t)`.
    fn lagrangian<D: Scalar>(&self, t: D, q: &[D], qd: &[D]) -> D;

    /// `f(q, t)` into `out` (length `k`).
    fn holonomic<D: Scalar>(&self, _t: D, _q: &[D], _out: &mut [D]) {}

    /// `g(q, q̇, t)` into `out` (length `s`).
    fn nonholonomic<D: Scalar>(&self, _t: D, _q: &[D], _qd: &[D], _out: &mut [D]) {}

    /// A vector `r(t, q, q̇)` (at most [`MAX_SINGULAR`] components) whose zero
    /// set is where the nonholonomic constraints stop being differentiable
    /// (Appell–Hamel: the horizontal velocity). Returns the number of
    /// components written, 0 if the constraints are regular everywhere.
    fn constraint_singularity(
        &self,
        _t: f64,
        _q: &[f64],
        _qd: &[f64],
        _r: &mut [f64; MAX_SINGULAR],
    ) -> usize {
        0
    }

    /// The embedding map `q_D = φ(q_I, q̇_I, t)` into `q_dep` (length `s`,
    /// in the order of [`EmbeddingInfo::dependent`]); for a cyclic dependent
    /// coordinate ([`EmbeddingInfo::cyclic`]) its velocity `q̇_c`.
    ///
    /// A map that is many-valued (the sleigh's `φ = arctan(ẏ/ẋ)`, eq. 21,
    /// whose branches differ by multiples of π) gives the branch nearest to
    /// `near` (one reference value per dependent coordinate), so that it can
    /// be followed continuously — through the map's singular set, or along
    /// a path in complex time; with `near` empty it gives its principal
    /// branch (the sleigh: `atan2(ẏ, ẋ)` in `(−π, π]`).
    fn embedding<D: Scalar>(
        &self,
        _t: D,
        _q_ind: &[D],
        _qd_ind: &[D],
        _near: &[f64],
        _q_dep: &mut [D],
    ) {
    }

    /// The embedding map in implicit form, into `out` (length `s`, in the
    /// order of [`EmbeddingInfo::dependent`]): for a dependent coordinate
    /// that is not cyclic, a residual `r(t, q_I, q̇_I, q_D)` that vanishes
    /// exactly where `q_D` is a value of the map on one of its branches and
    /// stays differentiable on the map's singular set, where the explicit
    /// map has no value (the sleigh: the blade constraint `ẏ cos φ − ẋ sin φ`,
    /// which holds for `φ = atan2(ẏ, ẋ)` and `φ + π` and is smooth at zero
    /// speed); for a cyclic one, its rate computed with the given values of
    /// the others instead of the map's (the disk: `ψ̇ = (ẋ cos θ + ẏ sin θ)/R`
    /// at the given `θ`). `q_dep` has the same layout; its cyclic entries
    /// are not read. Returns `false` if the scene gives none (the default);
    /// the boundary-value solver then uses the explicit map.
    fn embedding_implicit<D: Scalar>(
        &self,
        _t: D,
        _q_ind: &[D],
        _qd_ind: &[D],
        _q_dep: &[D],
        _out: &mut [D],
    ) -> bool {
        false
    }

    /// A vector `r(t, q_I, q̇_I)` whose zero set is the singular set of the
    /// embedding map (the sleigh: the velocity `(ẋ, ẏ)`); see
    /// [`Scene::constraint_singularity`].
    fn embedding_singularity(
        &self,
        _t: f64,
        _q_ind: &[f64],
        _qd_ind: &[f64],
        _r: &mut [f64; MAX_SINGULAR],
    ) -> usize {
        0
    }

    /// The normal load on contact `contact` of [`SceneInfo::contacts`], in
    /// newtons, constant along the motion; `None` if the scene does not
    /// model it (no gravity in its Lagrangian): a friction realisation then
    /// needs it given.
    fn normal_load(&self, _contact: usize) -> Option<f64> {
        None
    }

    /// Default positions `q0` (the static [`SceneInfo::default_q`] unless
    /// they depend on the parameters).
    fn default_q(&self) -> Vec<f64> {
        self.info().default_q.to_vec()
    }

    /// Completes initial positions: `q` holds the values given (where
    /// `given[i]`) and [`Scene::default_q`] elsewhere; a scene whose
    /// holonomic constraints fix some coordinates from others may move
    /// coordinates not given so that the constraints hold for the ones
    /// given (the train's trailers follow its headings). Default: nothing
    /// moves, and inconsistent positions are refused later by name.
    fn place(&self, _q: &mut [f64], _given: &[bool]) {}

    /// Velocities `q̇` from positions `q` and the convenience values of
    /// [`SceneInfo::velocity_chart`] (in chart order).
    ///
    /// Generic like [`Scene::lagrangian`]: `f64` for initial data, dual
    /// numbers where a formulation differentiates the chart (`visc` with
    /// `form = adapted` takes `∂q̇/∂chart` as the columns of its velocity
    /// frame, and their rate along the motion).
    fn velocities_from<D: Scalar>(&self, _q: &[D], _chart: &[D], _qd: &mut [D]) {}

    /// The convenience values of [`SceneInfo::velocity_chart`] at `(q, q̇)`,
    /// in chart order, into `chart`: the inverse of
    /// [`Scene::velocities_from`] on the constraints, for tables and plots
    /// (the sleigh's signed forward speed `u`, whose sign changes are its
    /// reversals). Returns whether the scene reads its chart (default: no,
    /// `chart` untouched).
    fn chart_from(&self, _q: &[f64], _qd: &[f64], _chart: &mut [f64]) -> bool {
        false
    }

    /// The closed-form motion from `(q0, q̇0)` at `t0 = 0`, evaluated at `t`;
    /// `Err` says why it does not apply to these parameters or initial data.
    fn closed_form(
        &self,
        _q0: &[f64],
        _qd0: &[f64],
        _t: f64,
        _q: &mut [f64],
        _qd: &mut [f64],
    ) -> Result<(), String> {
        Err("this scene has no closed-form solution".to_string())
    }

    /// Value of invariant `i` of [`SceneInfo::invariants`].
    fn invariant(&self, _i: usize, _t: f64, _q: &[f64], _qd: &[f64]) -> f64 {
        f64::NAN
    }
}

/// A scalar function `ℓ(t, q, q̇; p)` written once for every [`Scalar`]; what
/// [`crate::ad`] differentiates (a Lagrangian, or one augmented by
/// multipliers). The parameters `p` (e.g. multipliers `λ`) are held constant
/// by the differentiation.
pub trait ScalarField {
    /// Number of coordinates `n`.
    fn n(&self) -> usize;
    fn eval<D: Scalar>(&self, t: D, q: &[D], qd: &[D], p: &[D]) -> D;
}

/// A vector function `v(t, q, q̇) ∈ R^m` written once for every [`Scalar`].
pub trait VectorField {
    fn n(&self) -> usize;
    /// Number of components `m`.
    fn m(&self) -> usize;
    fn eval<D: Scalar>(&self, t: D, q: &[D], qd: &[D], out: &mut [D]);
}

/// The scene's Lagrangian as a [`ScalarField`].
pub struct Lagrangian<'a, S>(pub &'a S);

impl<S: Scene> ScalarField for Lagrangian<'_, S> {
    fn n(&self) -> usize {
        self.0.info().n()
    }
    #[inline]
    fn eval<D: Scalar>(&self, t: D, q: &[D], qd: &[D], _p: &[D]) -> D {
        self.0.lagrangian(t, q, qd)
    }
}

/// `L + λᵀg`, the Lagrangian augmented by the nonholonomic constraints with
/// multipliers `λ = p` (spec, section C). Needs a workspace for `g`: a
/// buffer on the stack for up to [`MAX_CONSTRAINTS`] rows, one on the heap
/// beyond (where B and C evaluate a compiled program, traced once, and
/// this field is evaluated only by the trace and by the scalar passes).
pub struct Augmented<'a, S>(pub &'a S);

/// Largest number of nonholonomic constraints [`Augmented`] evaluates
/// without allocating, and that the realisations and `friction`, which keep
/// such buffers per evaluation, support.
pub const MAX_CONSTRAINTS: usize = 16;

impl<S: Scene> ScalarField for Augmented<'_, S> {
    fn n(&self) -> usize {
        self.0.info().n()
    }
    #[inline]
    fn eval<D: Scalar>(&self, t: D, q: &[D], qd: &[D], p: &[D]) -> D {
        let s = self.0.info().s();
        let augmented = |g: &mut [D]| {
            self.0.nonholonomic(t, q, qd, g);
            let mut l = self.0.lagrangian(t, q, qd);
            for (pi, gi) in p.iter().zip(g.iter()) {
                l += *pi * *gi;
            }
            l
        };
        if s <= MAX_CONSTRAINTS {
            augmented(&mut [D::from(0.0); MAX_CONSTRAINTS][..s])
        } else {
            augmented(&mut vec![D::from(0.0); s])
        }
    }
}

/// The scene's nonholonomic constraints `g` as a [`VectorField`].
pub struct Nonholonomic<'a, S>(pub &'a S);

impl<S: Scene> VectorField for Nonholonomic<'_, S> {
    fn n(&self) -> usize {
        self.0.info().n()
    }
    fn m(&self) -> usize {
        self.0.info().s()
    }
    #[inline]
    fn eval<D: Scalar>(&self, t: D, q: &[D], qd: &[D], out: &mut [D]) {
        self.0.nonholonomic(t, q, qd, out)
    }
}

/// The scene's holonomic constraints `f` as a [`VectorField`] (independent of `q̇`).
pub struct Holonomic<'a, S>(pub &'a S);

impl<S: Scene> VectorField for Holonomic<'_, S> {
    fn n(&self) -> usize {
        self.0.info().n()
    }
    fn m(&self) -> usize {
        self.0.info().k()
    }
    #[inline]
    fn eval<D: Scalar>(&self, t: D, q: &[D], _qd: &[D], out: &mut [D]) {
        self.0.holonomic(t, q, out)
    }
}

#[cfg(test)]
mod tests {
    use super::atan2;
    use num_dual::{Dual3_64, DualNum};

    /// The value is `f64::atan2`'s in every quadrant and on the axes.
    #[test]
    fn atan2_values_match_the_standard_branch() {
        for i in 0..720 {
            let th = -std::f64::consts::PI + (i as f64 + 0.5) * std::f64::consts::PI / 360.0;
            for r in [1e-3, 1.0, 7.0] {
                let (y, x) = (r * th.sin(), r * th.cos());
                assert!((atan2(y, x) - y.atan2(x)).abs() < 2e-15, "θ = {th}");
            }
        }
        for (y, x) in [
            (0.0, 1.0),
            (1.0, 0.0),
            (0.0, -1.0),
            (-1.0, 0.0),
            (-0.0, -1.0),
        ] {
            assert_eq!(atan2(y, x), f64::atan2(y, x), "({y}, {x})");
        }
    }

    /// Along `(x, y) = r(t)(cos θ(t), sin θ(t))` the function is `θ(t)`, so
    /// its derivatives are `θ̇ = ω`, `θ̈ = α`, `θ⃛ = 0` — also with `x ≈ 0`,
    /// where differentiating through `y/x` loses them.
    #[test]
    fn atan2_derivatives_are_accurate_near_the_vertical() {
        let (w, a) = (0.7, -1.3);
        for th0 in [
            0.3,
            std::f64::consts::FRAC_PI_2 - 1e-7,
            2.0,
            -std::f64::consts::FRAC_PI_2 + 3e-8,
            3.1,
        ] {
            let t = Dual3_64::new(0.0, 1.0, 0.0, 0.0);
            let th = t * t * (0.5 * a) + t * w + th0;
            let r = t * 0.3 + 1.0;
            let v = atan2(r * th.sin(), r * th.cos());
            assert!((v.re - th0).abs() < 1e-15);
            assert!((v.v1 - w).abs() < 1e-13, "θ0 = {th0}: {}", v.v1);
            assert!((v.v2 - a).abs() < 1e-12, "θ0 = {th0}: {}", v.v2);
            assert!(v.v3.abs() < 1e-11, "θ0 = {th0}: {}", v.v3);
        }
    }
}
