//! Pieces shared by the explicit methods: counted evaluation of `f`, stage
//! sums, the error scale, Hairer's initial step `HINIT`, the step-size
//! controller and the stiffness test of `dopri5.f`/`dop853.f`.

use crate::driver::Hooks;
use crate::{OdeSystem, SystemError};

/// The system with a counter of `f` evaluations.
pub(crate) struct Rhs<'a, S: ?Sized> {
    pub sys: &'a mut S,
    pub evals: usize,
}

impl<S: OdeSystem + ?Sized> Rhs<'_, S> {
    /// Writes `f(t, y)` into `dy` and counts the evaluation.
    pub fn eval(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        self.evals += 1;
        self.sys.rhs(t, y, dy)
    }
}

impl<S: OdeSystem + ?Sized> Hooks for Rhs<'_, S> {
    fn evals(&self) -> usize {
        self.evals
    }

    fn after_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        self.sys.after_step(t, y)
    }

    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        self.sys.guard(t, y)
    }

    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        self.sys.guard_reason(t, y)
    }
}

/// Writes `Σ_j a_j k_j` into `out` (`a.len() <= k.len()`, zero weights skipped).
///
/// Four components at a time, summed over the stages in registers: for the
/// small states of the workbench a running sum kept in `out` costs a store
/// and a load per stage, which took a quarter of a DOP853 run on the
/// sleigh's B. The terms are added in the same order as by a running sum,
/// so the result is the same to the bit.
pub(crate) fn combine(out: &mut [f64], a: &[f64], k: &[Vec<f64>]) {
    let n = out.len();
    let mut i = 0;
    while i + 4 <= n {
        combine_at::<4>(out, a, k, i);
        i += 4;
    }
    if i + 2 <= n {
        combine_at::<2>(out, a, k, i);
        i += 2;
    }
    if i < n {
        combine_at::<1>(out, a, k, i);
    }
}

/// [`combine`] for the `W` components from `i` on.
#[inline(always)]
fn combine_at<const W: usize>(out: &mut [f64], a: &[f64], k: &[Vec<f64>], i: usize) {
    let mut acc = [0.0; W];
    for (&aj, kj) in a.iter().zip(k) {
        if aj != 0.0 {
            for (s, &v) in acc.iter_mut().zip(&kj[i..i + W]) {
                *s += aj * v;
            }
        }
    }
    out[i..i + W].copy_from_slice(&acc);
}

/// Writes the stage state `y + h Σ_j a_j k_j` into `out` (the sum is formed
/// first and added to `y` last, as in Hairer's codes).
pub(crate) fn stage(out: &mut [f64], y: &[f64], h: f64, a: &[f64], k: &[Vec<f64>]) {
    combine(out, a, k);
    for (o, &yi) in out.iter_mut().zip(y) {
        *o = yi + h * *o;
    }
}

/// Time of a stage with node `c`: the end of the step exactly when `c = 1`.
pub(crate) fn stage_time(t: f64, h: f64, c: f64, t_new: f64) -> f64 {
    if c == 1.0 { t_new } else { t + c * h }
}

/// Whether every entry is finite.
pub(crate) fn all_finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Tolerances; the scale of component `i` is `atol_i + rtol·max(|y_i|, |y_new,i|)`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tol<'a> {
    pub rtol: f64,
    /// Absolute tolerance of every component (length `dim`).
    pub atol: &'a [f64],
}

impl Tol<'_> {
    /// Error scale of component `i` between the values `y` and `y_new`.
    pub fn scale(&self, i: usize, y: f64, y_new: f64) -> f64 {
        self.atol[i] + self.rtol * y.abs().max(y_new.abs())
    }
}

/// Parameters of an adaptive method (Hairer's `WORK(2..5)`, `IORD`, stiffness bound).
#[derive(Debug, Clone, Copy)]
pub(crate) struct ControlParams {
    /// Safety factor `SAFE`.
    pub safe: f64,
    /// `FAC1 <= h_new/h`.
    pub fac1: f64,
    /// `h_new/h <= FAC2`.
    pub fac2: f64,
    /// Lund stabilisation `BETA`.
    pub beta: f64,
    /// Exponent `EXPO1` applied to the error.
    pub expo1: f64,
    /// `IORD` of `HINIT`.
    pub hinit_order: i32,
    /// The stiffness test fires when `h·ρ` exceeds this bound.
    pub stiff_bound: f64,
}

/// Hairer's step-size controller (PI control with Lund stabilisation).
pub(crate) struct Controller {
    p: ControlParams,
    facold: f64,
}

impl Controller {
    pub fn new(p: ControlParams) -> Self {
        Controller { p, facold: 1e-4 }
    }

    /// Next step after an accepted step of size `h` with scaled error `err <= 1`.
    pub fn accepted(&mut self, h: f64, err: f64) -> f64 {
        let fac11 = err.powf(self.p.expo1);
        let fac = fac11 / self.facold.powf(self.p.beta);
        let fac = (fac / self.p.safe).clamp(1.0 / self.p.fac2, 1.0 / self.p.fac1);
        self.facold = err.max(1e-4);
        h / fac
    }

    /// Next trial step after a step of size `h` was rejected with `err > 1`.
    pub fn rejected(&self, h: f64, err: f64) -> f64 {
        let fac11 = err.powf(self.p.expo1);
        h / (1.0 / self.p.fac1).min(fac11 / self.p.safe)
    }
}

/// Hairer's stiffness test: `h·ρ` with `ρ = ‖k_s − k_s'‖ / ‖y_s − y_s'‖` from
/// two stages at the same node, tried every `NSTIFF = 1000` accepted steps
/// and then after every step while it keeps firing; 15 hits before 6
/// successive misses declare the problem stiff.
pub(crate) struct StiffnessTest {
    bound: f64,
    hits: u32,
    misses: u32,
    h_rho: f64,
}

impl StiffnessTest {
    const NSTIFF: usize = 1000;

    pub fn new(bound: f64) -> Self {
        StiffnessTest {
            bound,
            hits: 0,
            misses: 0,
            h_rho: 0.0,
        }
    }

    /// Whether the test is due after accepted step number `accepted`.
    pub fn due(&self, accepted: usize) -> bool {
        accepted % Self::NSTIFF == 0 || self.hits > 0
    }

    /// Feeds a new estimate (`None` when the stage difference vanished: the
    /// previous estimate is kept); returns `h·ρ` on the 15th hit.
    pub fn update(&mut self, h_rho: Option<f64>) -> Option<f64> {
        if let Some(v) = h_rho {
            self.h_rho = v;
        }
        if self.h_rho > self.bound {
            self.misses = 0;
            self.hits += 1;
            if self.hits == 15 {
                return Some(self.h_rho);
            }
        } else {
            self.misses += 1;
            if self.misses == 6 {
                self.hits = 0;
            }
        }
        None
    }
}

/// `|h|·sqrt(Σ(k_i − k'_i)² / Σ(y_i − y'_i)²)`, or `None` if the denominator is zero.
pub(crate) fn stiffness_ratio(h: f64, k: &[f64], k2: &[f64], y: &[f64], y2: &[f64]) -> Option<f64> {
    let num: f64 = k.iter().zip(k2).map(|(a, b)| (a - b) * (a - b)).sum();
    let den: f64 = y.iter().zip(y2).map(|(a, b)| (a - b) * (a - b)).sum();
    (den > 0.0).then(|| h.abs() * (num / den).sqrt())
}

/// The first guess of Hairer's `HINIT`, `h0 = 0.01 ‖y0‖/‖f0‖` in the weighted
/// norms of `tol` (`1e-6` if either norm is tiny), at most `hmax`; returns
/// `(h0, ‖f0‖²)`. Also the whole initial-step choice of Radau5 for implicit
/// systems, which cannot estimate a second derivative.
pub(crate) fn hinit_guess(y: &[f64], f0: &[f64], hmax: f64, tol: Tol<'_>) -> (f64, f64) {
    let (mut dnf, mut dny) = (0.0, 0.0);
    for (i, (&yi, &fi)) in y.iter().zip(f0).enumerate() {
        let sk = tol.scale(i, yi, 0.0);
        dnf += (fi / sk) * (fi / sk);
        dny += (yi / sk) * (yi / sk);
    }
    let h0 = if dnf <= 1e-10 || dny <= 1e-10 {
        1e-6
    } else {
        (dny / dnf).sqrt() * 0.01
    };
    (h0.min(hmax), dnf)
}

/// Hairer's `HINIT`: initial step such that `h^iord · max(‖f0‖, ‖f'‖) = 0.01`.
///
/// Takes one explicit Euler step of size `h0 = 0.01 ‖y0‖/‖f0‖` to estimate
/// the second derivative; returns `min(100 h0, h1, hmax)`. If `f` cannot be
/// evaluated (or is not finite) at the Euler point, `h0` is returned and the
/// step loop shrinks it as needed. `y1`, `f1` are workspaces.
#[allow(clippy::too_many_arguments)]
pub(crate) fn hinit<S: OdeSystem + ?Sized>(
    rhs: &mut Rhs<'_, S>,
    t: f64,
    y: &[f64],
    f0: &[f64],
    order: i32,
    hmax: f64,
    tol: Tol<'_>,
    y1: &mut [f64],
    f1: &mut [f64],
) -> f64 {
    let (h0, dnf) = hinit_guess(y, f0, hmax, tol);
    for ((o, &yi), &fi) in y1.iter_mut().zip(y).zip(f0) {
        *o = yi + h0 * fi;
    }
    if rhs.eval(t + h0, y1, f1).is_err() {
        return h0;
    }
    let mut der2 = 0.0;
    for (i, ((&yi, &fa), &fb)) in y.iter().zip(f0).zip(f1.iter()).enumerate() {
        let sk = tol.scale(i, yi, 0.0);
        der2 += ((fb - fa) / sk) * ((fb - fa) / sk);
    }
    let der2 = der2.sqrt() / h0;
    if !der2.is_finite() {
        return h0;
    }
    let der12 = der2.max(dnf.sqrt());
    let h1 = if der12 <= 1e-15 {
        (h0 * 1e-3).max(1e-6)
    } else {
        (0.01 / der12).powf(1.0 / f64::from(order))
    };
    (100.0 * h0).min(h1).min(hmax)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The blocked sum equals a running sum over the stages to the bit, at
    /// every state size the blocks split differently (1 … 9), zero weights
    /// included.
    #[test]
    fn combine_is_the_running_sum_to_the_bit() {
        let a = [0.3, 0.0, -1.7, 2.0 / 3.0, 0.0, 1e-3, -0.1];
        for n in 1..=9 {
            let k: Vec<Vec<f64>> = (0..a.len())
                .map(|j| {
                    (0..n)
                        .map(|i| ((i * 7 + j * 3) as f64).sin() * 1e3)
                        .collect()
                })
                .collect();
            let mut running = vec![0.0; n];
            for (&aj, kj) in a.iter().zip(&k) {
                if aj != 0.0 {
                    for (o, &v) in running.iter_mut().zip(kj) {
                        *o += aj * v;
                    }
                }
            }
            let mut out = vec![f64::NAN; n];
            combine(&mut out, &a, &k);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&out), bits(&running), "n = {n}");
        }
    }

    fn params() -> ControlParams {
        ControlParams {
            safe: 0.9,
            fac1: 0.2,
            fac2: 10.0,
            beta: 0.04,
            expo1: 0.2 - 0.04 * 0.75,
            hinit_order: 5,
            stiff_bound: 3.25,
        }
    }

    #[test]
    fn controller_bounds_the_step_ratio() {
        let mut c = Controller::new(params());
        // A zero error allows the largest growth, fac2 = 10.
        assert_eq!(c.accepted(1.0, 0.0), 10.0);
        // A huge error on rejection shrinks by at most fac1 = 0.2.
        assert!((c.rejected(1.0, 1e30) - 0.2).abs() < 1e-15);
        // err = 1 after facold = 1e-4: h·0.9 / 1e-4^0.04 ≈ 0.9·0.692.
        let mut c = Controller::new(params());
        let h = c.accepted(1.0, 1.0);
        assert!((h - 0.9 * 1e-4f64.powf(0.04)).abs() < 1e-14, "{h}");
    }

    #[test]
    fn stiffness_test_needs_fifteen_hits() {
        let mut s = StiffnessTest::new(3.25);
        assert!(s.due(1000) && !s.due(999));
        for _ in 0..14 {
            assert_eq!(s.update(Some(4.0)), None);
        }
        // Five misses do not reset the count, the 15th hit fires.
        for _ in 0..5 {
            assert_eq!(s.update(Some(1.0)), None);
        }
        assert_eq!(s.update(Some(4.0)), Some(4.0));
    }
}
