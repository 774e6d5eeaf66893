use serde::{Deserialize, Serialize};

/// The integration method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Method {
    /// Classical Runge–Kutta of order 4, fixed step `Options::fixed_step`.
    Rk4,
    /// Dormand–Prince 5(4), adaptive (or fixed step if `Options::fixed_step` is set).
    Dopri5,
    /// Dormand–Prince 8(5,3), adaptive (or fixed step if `Options::fixed_step` is set).
    Dop853,
    /// Radau IIA of order 5 (three stages), implicit, adaptive; for stiff
    /// ODEs and, through [`crate::solve_implicit`], implicit DAEs of index ≤ 3.
    Radau5,
}

impl Method {
    /// Every method, in order of increasing order.
    pub const ALL: [Method; 4] = [Method::Rk4, Method::Dopri5, Method::Dop853, Method::Radau5];

    /// The name used on command lines and in result files.
    pub fn name(self) -> &'static str {
        match self {
            Method::Rk4 => "rk4",
            Method::Dopri5 => "dopri5",
            Method::Dop853 => "dop853",
            Method::Radau5 => "radau5",
        }
    }

    /// The method called `name` (see [`Method::name`]).
    pub fn from_name(name: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.name() == name)
    }

    /// Classical order of the method.
    pub fn order(self) -> u32 {
        match self {
            Method::Rk4 => 4,
            Method::Dopri5 => 5,
            Method::Dop853 => 8,
            Method::Radau5 => 5,
        }
    }

    /// Whether the method is implicit (solves nonlinear stage equations).
    pub fn is_implicit(self) -> bool {
        matches!(self, Method::Radau5)
    }

    /// Whether the method needs `Options::fixed_step`.
    pub fn needs_fixed_step(self) -> bool {
        matches!(self, Method::Rk4)
    }
}

/// How [`Method::Radau5`] solves the nonlinear stage equations of a step.
///
/// Both variants solve the same collocation equations
/// `G_k(Z) = F(t_n + c_k h, y_n + Z_k, h⁻¹ Σ_j (A⁻¹)_kj Z_j) = 0` (`k = 1, 2, 3`)
/// with the same starting values, convergence monitor (`θ`, `η`, the
/// index-scaled norm, [`Radau5Options::newton_tol`], [`Radau5Options::newton_max_iter`])
/// and the same error estimate; they differ in the Jacobian of the iteration.
///
/// Serialised by [`RadauNewton::name`] (`"auto"`, `"simplified"`, `"full"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RadauNewton {
    /// The caller decides (`nonholo_core::simulate` asks the model being
    /// integrated); the integrator itself treats it as [`RadauNewton::Simplified`].
    #[default]
    Auto,
    /// RADAU5's simplified Newton iteration (the default): one pair
    /// `J = ∂F/∂y`, `J' = ∂F/∂y'` taken at the step start (and reused across
    /// steps while the iteration contracts fast), decoupled through
    /// `T⁻¹ A⁻¹ T` into one real and one complex `n × n` system. Cheap
    /// (`O(n³)` once per Jacobian/step size, `O(n²)` per iteration) and
    /// linearly convergent.
    Simplified,
    /// Full Newton iteration: every iteration evaluates `J_k`, `J'_k` at the
    /// three stage points and solves the `3n × 3n` system with blocks
    /// `∂G_k/∂Z_j = δ_kj J_k + h⁻¹ (A⁻¹)_kj J'_k` by real LU with partial
    /// pivoting (`O(27 n³)` and 3 Jacobians per iteration). Quadratically
    /// convergent; meant for fully implicit index-3 systems outside
    /// Hessenberg form (e.g. `M(y) y' = f(y)` with a state-dependent
    /// singular `M`), on which the simplified iteration can stall with
    /// `θ ≈ 1`: there the change of the Jacobian over the step, `O(h)`, is
    /// amplified by the `O(h⁻³)` inverse of the iteration matrix.
    /// Jacobian reuse and [`Radau5Options::keep_step`] do not apply; the error
    /// estimate still factors `γ/h J' + J` at the step start once per step
    /// (not with [`Options::fixed_step`], which has no error estimate).
    Full,
}

impl RadauNewton {
    /// Name on the command line and in result files.
    pub fn name(self) -> &'static str {
        match self {
            RadauNewton::Auto => "auto",
            RadauNewton::Simplified => "simplified",
            RadauNewton::Full => "full",
        }
    }

    /// The variant called `name`.
    pub fn from_name(name: &str) -> Option<RadauNewton> {
        [
            RadauNewton::Auto,
            RadauNewton::Simplified,
            RadauNewton::Full,
        ]
        .into_iter()
        .find(|v| v.name() == name)
    }
}

/// How Radau IIA fills its steps between the step points: the continuous
/// extension, output samples and guard location. Serialised by
/// [`RadauDense::name`] (`"auto"`, `"collocation"`, `"hermite"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RadauDense {
    /// The default: [`RadauDense::Hermite`] for `y' = f(t, y)`,
    /// [`RadauDense::Collocation`] for an implicit system `F(t, y, y') = 0`
    /// (which has no Hermite extension).
    #[default]
    Auto,
    /// RADAU5's collocation polynomial (`CONTR5`): degree 3, stage order 3
    /// inside the step, stiffly accurate; the Newton starting values
    /// extrapolate it whatever this setting.
    Collocation,
    /// A quintic through the values and derivatives at the last three step
    /// points (a quartic without the value at `t_{n−1}` after a more than
    /// twofold step growth), in the components whose row of the last
    /// Jacobian evaluated is not stiff over the step; the collocation
    /// polynomial in the others, at the first step, after a projection and
    /// while no Jacobian has been evaluated (full Newton with a fixed step).
    /// For `y' = f(t, y)` only (an implicit system is refused). No extra evaluation: `y'_n` is the `f(t_n, y_n)` RADAU5
    /// evaluates at every accepted state, `y'_{n+1}` the collocation
    /// polynomial's derivative at the step's end.
    Hermite,
}

impl RadauDense {
    /// Name on the command line and in result files.
    pub fn name(self) -> &'static str {
        match self {
            RadauDense::Auto => "auto",
            RadauDense::Collocation => "collocation",
            RadauDense::Hermite => "hermite",
        }
    }

    /// The variant called `name`.
    pub fn from_name(name: &str) -> Option<RadauDense> {
        [
            RadauDense::Auto,
            RadauDense::Collocation,
            RadauDense::Hermite,
        ]
        .into_iter()
        .find(|v| v.name() == name)
    }

    /// Whether a run takes the Hermite extension: `explicit` says the
    /// system is `y' = f(t, y)`.
    pub fn hermite(self, explicit: bool) -> bool {
        match self {
            RadauDense::Auto => explicit,
            RadauDense::Collocation => false,
            RadauDense::Hermite => true,
        }
    }
}

/// Integrator settings shared by every method (the base), with the
/// settings of [`Method::Radau5`] in [`Options::radau5`].
/// `Options::default()` is a reasonable start.
///
/// Serialisable (`serde`): missing fields take their defaults, unknown
/// fields are refused. The defaults, as in Hairer's headers:
///
/// | field | default |
/// |---|---|
/// | `rtol`, `atol` | `1e-6`, `1e-6` |
/// | `atol_components` | `None` (`atol` for every component) |
/// | `fixed_step` | `None` (adaptive) |
/// | `h_init` | `None` (`HINIT`) |
/// | `h_max` | `None` (`t_end − t0`) |
/// | `max_steps` | `10⁷` |
/// | `max_wall_time_s` | `None` (unlimited) |
/// | `stiff_stop` | `false` |
/// | `output` | `[]` (only `t_end`) |
/// | `dense` | `true` |
/// | `hit_output` | `false` |
/// | `radau5` | [`Radau5Options::default()`] |
///
/// The explicit methods (RK4, DOPRI5, DOP853) take no settings of their
/// own: their step-size controllers use the constants of `dopri5.f` and
/// `dop853.f`, listed in the method modules' documentation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Options {
    /// Relative tolerance of the local error estimate. Must be at least
    /// `100·ε ≈ 2.2e-14` (double precision cannot deliver more; smaller
    /// values are refused with [`crate::IntegrateError::InvalidInput`]).
    /// Default `1e-6`.
    pub rtol: f64,
    /// Absolute tolerance of the local error estimate (positive, finite).
    /// Overridden component by component by [`Options::atol_components`].
    /// Default `1e-6`.
    pub atol: f64,
    /// Per-component absolute tolerances (length `dim`, each positive and
    /// finite). When set they replace [`Options::atol`] in every error norm
    /// (the error scale of component `i` is `atol_i + rtol·|y_i|`), in
    /// Hairer's initial-step choice, in Radau5's transformed tolerances and
    /// in the consistency check of [`crate::solve_implicit`]. A large
    /// `atol_i` effectively removes component `i` from step-size control.
    /// Default `None`.
    pub atol_components: Option<Vec<f64>>,
    /// Fixed step size: required for RK4; for the embedded methods and
    /// Radau5 it turns step-size control off (used to measure convergence
    /// orders; Radau5 still iterates Newton to `newton_tol`). Default `None`.
    pub fixed_step: Option<f64>,
    /// Initial step size; `None` (default) chooses it as Hairer's `HINIT`.
    pub h_init: Option<f64>,
    /// Largest step size; `None` (default) means `|t_end - t0|`.
    pub h_max: Option<f64>,
    /// Budget on accepted plus rejected steps. Default `10_000_000`.
    pub max_steps: usize,
    /// Budget on wall-clock time in seconds (`None`, the default: unlimited).
    pub max_wall_time_s: Option<f64>,
    /// Explicit methods stop with [`crate::IntegrateError::Stiff`] when
    /// their stiffness test has fired 15 times in a row (Hairer's
    /// `dopri5.f`/`dop853.f` interrupt there, `IDID = -4`, when not
    /// printing): stability, not accuracy, then limits the step, and the
    /// run would spend its whole budget on steps of that size. A
    /// deterministic stop, unlike a wall-time budget. Default `false` (run
    /// on, recording where the test fired in `Stats::stiffness_detected`).
    pub stiff_stop: bool,
    /// Times at which to sample the solution (increasing, within the span).
    /// The final time is always sampled as the last row if not listed.
    /// Default empty.
    pub output: Vec<f64>,
    /// Keep the continuous extension of every step ([`crate::Dense`]).
    /// Default `true`.
    pub dense: bool,
    /// Adaptive methods shorten a step that would pass the next time of
    /// `output` so that it lands on it: the samples are then step end points,
    /// free of the continuous extension's interpolation error (which for
    /// Radau IIA's collocation polynomial, of degree 3, dominates at tight
    /// tolerances; on ODEs the default is the Hermite extension, whose
    /// error stays near the step points').
    /// For reference solutions; costs the extra steps. Default `false`.
    pub hit_output: bool,
    /// Settings of [`Method::Radau5`] only (the Newton iteration and
    /// Jacobian reuse); ignored by the explicit methods.
    pub radau5: Radau5Options,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            rtol: 1e-6,
            atol: 1e-6,
            atol_components: None,
            fixed_step: None,
            h_init: None,
            h_max: None,
            max_steps: 10_000_000,
            max_wall_time_s: None,
            stiff_stop: false,
            output: Vec::new(),
            dense: true,
            hit_output: false,
            radau5: Radau5Options::default(),
        }
    }
}

/// Settings of [`Method::Radau5`] (RADAU5's `IWORK`/`WORK` entries for the
/// Newton iteration and the reuse of Jacobians and step sizes).
///
/// Serialisable as [`Options`]; defaults (RADAU5's, and the Hermite
/// extension where there is one):
///
/// | field | RADAU5 | default |
/// |---|---|---|
/// | `newton` | — | [`RadauNewton::Auto`] (the integrator: simplified) |
/// | `newton_max_iter` | `NIT`, `IWORK(3)` | `7` |
/// | `newton_tol` | `FNEWT`, `WORK(4)` | `None`: `max(10·uround/rtol', min(0.03, sqrt(rtol')))` |
/// | `jacobian_reuse` | `THET`, `WORK(3)` | `0.001` |
/// | `keep_step` | `QUOT1`, `QUOT2`, `WORK(5)`, `WORK(6)` | `(1.0, 1.2)` |
/// | `dense_output` | — (`CONTR5`) | [`RadauDense::Auto`] |
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Radau5Options {
    /// Simplified (RADAU5, default) or full Newton iteration on the stage
    /// equations; see [`RadauNewton`]. Default [`RadauNewton::Auto`].
    pub newton: RadauNewton,
    /// Largest number of Newton iterations per step, simplified or full
    /// (RADAU5's `NIT`, `IWORK(3)`). At least 1. Default 7.
    pub newton_max_iter: usize,
    /// The Newton iteration stops when its estimated remaining error
    /// `θ/(1 − θ)·‖ΔZ‖` is at most this, in units of the error scale
    /// (RADAU5's `FNEWT`, `WORK(4)`); positive and finite. `None` (default):
    /// `max(10·uround/rtol', min(0.03, sqrt(rtol')))` with RADAU5's internal
    /// tolerance `rtol' = 0.1·rtol^(2/3)`. A given value is raised to
    /// `10·uround/rtol'` (below it rounding ends the iteration; RADAU5
    /// refuses such a value). The error the iteration leaves can build up
    /// over the steps: with the Jacobian kept for many steps it can
    /// dominate the global error (`docs/integrators.md`, "Jacobian reuse").
    pub newton_tol: Option<f64>,
    /// After a step whose Newton iteration converged with rate
    /// `θ <= jacobian_reuse` the Jacobian is kept for the next step
    /// (RADAU5's `THET`, `WORK(3)`); a negative value asks for a new
    /// Jacobian after every accepted step. Must be `< 1`. Default `0.001`.
    /// RADAU5's documentation advises `0.1` "when Jacobian evaluations are
    /// costly". Measured (experiments `radau-reuse-1`, `radau-reuse-10`; the
    /// numbers in `docs/integrators.md`): on ten hitched sleighs `0.1` cuts
    /// B's time at matched error severalfold; on one sleigh it gains B little
    /// and costs C accuracy and time, accuracy that a tighter
    /// [`Radau5Options::newton_tol`] gives back (the loss is Newton
    /// iteration error). So the default stays RADAU5's and a large system
    /// sets `0.1` itself.
    pub jacobian_reuse: f64,
    /// `(lo, hi)` with `0 < lo <= 1 <= hi < ∞`; when the Jacobian is kept
    /// and the proposed step ratio `h_new/h` lies in `[lo, hi]`, the step
    /// size is left unchanged, which saves the LU decompositions (RADAU5's
    /// `QUOT1`, `QUOT2`, `WORK(5)`, `WORK(6)`). Default `(1.0, 1.2)`.
    pub keep_step: (f64, f64),
    /// The continuous extension between step points; see [`RadauDense`].
    /// Default [`RadauDense::Auto`]: the Hermite extension where there is
    /// one. Records made before 2026-12-03 leave this field out and were
    /// made with [`RadauDense::Collocation`]; read back, such a record gives
    /// the default, [`RadauDense::Auto`].
    pub dense_output: RadauDense,
}

impl Radau5Options {
    /// The Newton stopping tolerance (RADAU5's `FNEWT`) a run at the
    /// user's relative tolerance `rtol` uses: [`Radau5Options::newton_tol`]
    /// where given, else RADAU5's default `min(0.03, sqrt(rtol'))`, and
    /// never below `10·uround/rtol'` (RADAU5's internal tolerance
    /// `rtol' = 0.1·rtol^(2/3)`). A study that tightens the test by a
    /// factor reads the baseline from the default options here.
    pub fn newton_tol_at(&self, rtol: f64) -> f64 {
        let internal = 0.1 * rtol.powf(2.0 / 3.0);
        (10.0 * crate::radau::UROUND / internal).max(
            self.newton_tol
                .unwrap_or_else(|| 0.03f64.min(internal.sqrt())),
        )
    }
}

impl Default for Radau5Options {
    fn default() -> Self {
        Radau5Options {
            newton: RadauNewton::Auto,
            newton_max_iter: 7,
            newton_tol: None,
            jacobian_reuse: 0.001,
            keep_step: (1.0, 1.2),
            dense_output: RadauDense::Auto,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Radau5Options;

    /// RADAU5's `FNEWT` by hand: its internal tolerance `rtol' =
    /// 0.1·rtol^(2/3)`, then `max(10·uround/rtol', min(0.03, sqrt(rtol')))`
    /// with uround = 1e-16; a given value is raised to the floor only.
    #[test]
    fn newton_tol_is_radau5s_fnewt() {
        let default = Radau5Options::default();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b;
        // rtol 1e-6: rtol' = 1e-5, sqrt = 3.1623e-3 (the floor is 1e-10).
        assert!(close(default.newton_tol_at(1e-6), 1e-5f64.sqrt()));
        // rtol 1e-2: sqrt(rtol') = 0.068 is capped at 0.03.
        assert_eq!(default.newton_tol_at(1e-2), 0.03);
        // rtol 1e-14: rtol' = 4.64e-11, whose floor 2.15e-5 beats 6.8e-6.
        let internal = 0.1 * 1e-14f64.powf(2.0 / 3.0);
        assert!(close(default.newton_tol_at(1e-14), 1e-15 / internal));
        // The ladder of docs/integrators.md: 1.5e-4 at 1e-10, 6.8e-3 at 1e-5.
        assert_eq!(format!("{:.1e}", default.newton_tol_at(1e-10)), "1.5e-4");
        assert_eq!(format!("{:.1e}", default.newton_tol_at(1e-5)), "6.8e-3");
        let given = |f: f64| Radau5Options {
            newton_tol: Some(f),
            ..Radau5Options::default()
        };
        assert_eq!(given(1e-5).newton_tol_at(1e-6), 1e-5);
        assert!(close(given(1e-12).newton_tol_at(1e-6), 1e-10));
    }
}
