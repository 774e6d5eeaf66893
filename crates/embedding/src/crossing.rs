//! A's explicit form across the singular set of its embedding map, along a
//! path in complex time.
//!
//! The equations (19) are singular where the map is (the sleigh: zero
//! speed, where `φ = arctan(ẏ/ẋ)` has no value and `W ~ 1/|v|²`), but their
//! solution is analytic there: the motion reverses smoothly. Where the real
//! integration stops at its guard, `t_a`, the singular instant `t*` is
//! estimated from the Taylor polynomial of the velocity (the zero of `|v|`),
//! and the solution is continued along the half circle in the upper half
//! plane from `t_a` to `t_b = t_a + 3(t* − t_a)`, centred at
//! `(t_a + t_b)/2`: it passes `t*` at the distance `t* − t_a` at which the
//! real integration stopped, where the equations are as well resolved as
//! there. Along the path the same explicit form is integrated — the
//! derivative array solved for `q⁗` over complex numbers, `q⃛` projected onto
//! the hidden constraints after every step — by an adaptive Runge–Kutta
//! method in the path parameter, with the run's tolerances (Fornberg &
//! Weideman's "pole vaulting", here around an apparent singularity of the
//! equations rather than a pole of the solution). Nothing of C enters.
//!
//! The solution is real on the real axis, so the imaginary part left at
//! `t_b` measures the continuation's error, and is reported. Between `t_a`
//! and `t_b` (the diameter of the path's circle) the states are the
//! polynomial interpolating them at equispaced points of the whole circle —
//! the path's continuous extension above, its mirror image below (the
//! solution is real on the real axis) — which converges geometrically on
//! the closed disk; the upper half of its coefficients estimates its error,
//! reported as the gap error.
//!
//! The branch of the map (`continuation`): `analytic` follows it
//! continuously along the path (the heading is continued, `|v|` becomes the
//! signed speed); `map` resumes on the map's principal branch (the sleigh:
//! `atan2`, whose heading turns by π at a reversal, which flips the gravity
//! torque of `potential = com`), the third derivatives re-completed on its
//! hidden constraints.

use nonholo_core::Scene;
use nonholo_core::complex::C64;
use nonholo_core::integrate::{Method, OdeSystem, Options, Stats, SystemError, solve};
use nonholo_core::model::{Crossed, CrossingRecord, GapFill};
use num_complex::Complex64;

use crate::elo::{MAX_DOF, cyclic_rates, reconstruct};
use crate::ode::{Field, ODE_RESOLUTION, Reduction};

/// Where the explicit form leaves the real axis when it continues: `q⁗`
/// resolved to this relative accuracy (ten times better than where it
/// stops without continuation, [`ODE_RESOLUTION`]).
pub const CROSS_RESOLUTION: f64 = 1e-10;

/// Where the resolution of `q⁗` is already worse than [`CROSS_RESOLUTION`]
/// when an approach to the singular set begins (a fast-turning motion), the
/// real integration leaves the axis when it has worsened by this factor.
/// A path in complex time, in turn, stops where `q⁗` is resolved this
/// factor worse than where it left the axis ([`Path::start_at`]).
pub const APPROACH_FACTOR: f64 = 10.0;

/// Relative imaginary part allowed on the state where the path returns to
/// the real axis, as a multiple of the relative tolerance.
pub const RETURN_FACTOR: f64 = 1e3;

/// How A continues past the singular set of its embedding map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Continuation {
    /// It does not: the run stops there.
    None,
    /// Along the map's analytic continuation.
    Analytic,
    /// Resuming on the map's principal branch.
    Map,
}

impl Continuation {
    pub fn from_name(name: &str) -> Continuation {
        match name {
            "analytic" => Continuation::Analytic,
            "map" => Continuation::Map,
            _ => Continuation::None,
        }
    }
}

impl Field for C64 {
    const PARTS: usize = 2;
    fn part(self, k: usize) -> f64 {
        if k == 0 { self.re() } else { self.im() }
    }
    fn from_parts(p: &[f64]) -> Self {
        C64(Complex64::new(p[0], p[1]))
    }
    fn norm(self) -> f64 {
        C64::norm(&self)
    }
}

/// The half circle `γ(s) = c − r e^{−iπs}`, `s ∈ [0, 1]`, from `c − r` to
/// `c + r` through `c + ir`.
#[derive(Debug, Clone, Copy)]
pub struct HalfCircle {
    pub centre: f64,
    pub radius: f64,
}

impl HalfCircle {
    pub fn at(&self, s: f64) -> C64 {
        let e = Complex64::from_polar(1.0, -std::f64::consts::PI * s);
        C64(Complex64::new(self.centre, 0.0) - e * self.radius)
    }

    /// `γ'(s) = iπr e^{−iπs}`.
    pub fn rate(&self, s: f64) -> C64 {
        let e = Complex64::from_polar(1.0, -std::f64::consts::PI * s);
        C64(Complex64::new(0.0, std::f64::consts::PI * self.radius) * e)
    }
}

/// A's explicit form along a path in complex time, as a real ODE in the
/// path parameter `s`: `Z` holds the real and imaginary parts of
/// `y = (z, q_c)`, `z = (q_I, q̇_I, q̈_I, q⃛_I)` and `q_c` the cyclic
/// dependent coordinates, `dy/ds = γ'(s) (z₁, z₂, z₃, w(z), φ_c(z))`.
pub struct Path<'a, S: Scene> {
    pub scene: &'a S,
    pub e: &'a nonholo_core::scene::EmbeddingInfo,
    pub path: HalfCircle,
    pub m: usize,
    /// Cyclic dependent coordinates.
    pub c: usize,
    pub reduction: &'a mut Reduction<C64>,
    /// The branch reference (the real parts of the dependent coordinates at
    /// the last accepted step), updated as the path turns.
    pub near: Vec<f64>,
    /// The resolution of `q⁗` at which the path stops: [`ODE_RESOLUTION`],
    /// or [`APPROACH_FACTOR`] times the resolution where it leaves the
    /// real axis if that is worse (the real integration may leave at
    /// `ODE_RESOLUTION` itself, [`Path::start_at`]).
    limit: f64,
    z: Vec<C64>,
    /// Scratch for the map's value and the cyclic rates.
    dep: Vec<C64>,
    rates: Vec<C64>,
}

impl<'a, S: Scene> Path<'a, S> {
    pub fn new(
        scene: &'a S,
        e: &'a nonholo_core::scene::EmbeddingInfo,
        path: HalfCircle,
        reduction: &'a mut Reduction<C64>,
        near: Vec<f64>,
    ) -> Self {
        let (m, c) = (e.independent.len(), e.cyclic.len());
        Path {
            scene,
            e,
            path,
            m,
            c,
            reduction,
            near,
            limit: ODE_RESOLUTION,
            z: vec![C64::from(0.0); 4 * m + c],
            dep: vec![C64::from(0.0); e.dependent.len()],
            rates: vec![C64::from(0.0); c],
        }
    }

    /// Fixes the path's limit ([`Path::limit`]) from the resolution at its
    /// start `y` (parts): a path stops where `q⁗` is resolved
    /// [`APPROACH_FACTOR`] times worse than where it left the real axis
    /// (another singular point), and never before [`ODE_RESOLUTION`].
    pub fn start_at(&mut self, y: &[f64]) -> Result<(), String> {
        self.load(y);
        let t = self.path.at(0.0);
        let rho = self
            .reduction
            .resolution(self.scene, self.e, t, &self.z)?
            .rho;
        self.limit = ODE_RESOLUTION.max(APPROACH_FACTOR * rho);
        Ok(())
    }

    /// `z` from its parts `y`.
    fn load(&mut self, y: &[f64]) {
        for (k, z) in self.z.iter_mut().enumerate() {
            *z = C64(Complex64::new(y[2 * k], y[2 * k + 1]));
        }
    }

    /// The dependent coordinates at `z`, time `t`, on the branch nearest to
    /// `near`; `near` follows them when they have turned by more than π/4.
    fn track_branch(&mut self, t: C64) {
        let m = self.m;
        let n = self.scene.info().n();
        let zero = C64::from(0.0);
        let (mut q, mut qd) = ([zero; MAX_DOF], [zero; MAX_DOF]);
        reconstruct(
            self.scene,
            self.e,
            t,
            &self.z[..m],
            &self.z[m..2 * m],
            &self.z[2 * m..3 * m],
            &self.near,
            &mut q[..n],
            &mut qd[..n],
        );
        let turned = self.e.dependent.iter().enumerate().any(|(j, &i)| {
            !self.e.cyclic.contains(&i)
                && (q[i].re() - self.near[j]).abs() > std::f64::consts::FRAC_PI_4
        });
        if turned {
            for (j, &i) in self.e.dependent.iter().enumerate() {
                self.near[j] = q[i].re();
            }
            self.reduction.set_branch(&self.near);
        }
    }
}

impl<S: Scene> OdeSystem for Path<'_, S> {
    fn dim(&self) -> usize {
        2 * (4 * self.m + self.c)
    }

    fn rhs(&mut self, s: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let m = self.m;
        self.load(y);
        let (t, rate) = (self.path.at(s), self.path.rate(s));
        let w = self
            .reduction
            .fourth(self.scene, self.e, t, &self.z)
            .map_err(SystemError::new)?;
        for k in 0..4 * m {
            let dz = (if k < 3 * m {
                self.z[m + k]
            } else {
                w[k - 3 * m]
            }) * rate;
            dy[2 * k] = dz.re();
            dy[2 * k + 1] = dz.im();
        }
        if self.c > 0 {
            cyclic_rates(
                self.scene,
                self.e,
                t,
                &self.z[..m],
                &self.z[m..2 * m],
                &self.near,
                &mut self.dep,
                &mut self.rates,
            );
            for (k, r) in self.rates.iter().enumerate() {
                let dq = *r * rate;
                dy[2 * (4 * m + k)] = dq.re();
                dy[2 * (4 * m + k) + 1] = dq.im();
            }
        }
        if dy.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(SystemError::new(
                "the equations (19) are not finite on the path",
            ))
        }
    }

    /// `q⃛` back onto the hidden constraints (complex), the branch followed,
    /// the state recorded.
    fn after_step(&mut self, s: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        self.load(y);
        let t = self.path.at(s);
        self.reduction
            .project(self.scene, self.e, t, &mut self.z)
            .map_err(SystemError::new)?;
        for (k, z) in self.z.iter().enumerate() {
            y[2 * k] = z.re();
            y[2 * k + 1] = z.im();
        }
        self.track_branch(t);
        Ok(true)
    }

    /// Positive while `q⁗` is resolved better than the path's limit
    /// ([`Path::start_at`]): a path that meets a poorly resolved region
    /// (another singular point) stops instead of carrying its round-off
    /// across.
    fn guard(&mut self, s: f64, y: &[f64]) -> Option<f64> {
        self.load(y);
        let t = self.path.at(s);
        match self.reduction.resolution(self.scene, self.e, t, &self.z) {
            Ok(r) => Some((self.limit / r.rho).ln()),
            Err(_) => Some(-1.0),
        }
    }

    fn guard_reason(&mut self, s: f64, y: &[f64]) -> String {
        self.load(y);
        let t = self.path.at(s);
        match self.reduction.resolution(self.scene, self.e, t, &self.z) {
            Ok(r) => format!(
                "the path met a region where the derivative array resolves q⁗ only to {:.2e} \
                 (limit {:.1e}) at t = {:.6} + {:.6}i",
                r.rho,
                self.limit,
                t.re(),
                t.im()
            ),
            Err(msg) => format!("the derivative array could not be solved on the path: {msg}"),
        }
    }
}

/// The singular instant ahead of `t_a`: the first `τ > 0` at which the
/// speed of the Taylor polynomial `v(τ) = q̇ + q̈τ + q⃛τ²/2 + q⁗τ³/6`
/// (per independent coordinate, `d[k]` the k-th derivatives) is least,
/// by Newton on `v·v̇ = 0` from the linear estimate `−(v·v)/(v·v̇)`.
pub fn singular_instant(d: &[Vec<f64>]) -> Option<f64> {
    let m = d[0].len();
    let v = |tau: f64, k: usize| -> f64 {
        (0..m)
            .map(|i| {
                let x = d[1][i]
                    + d[2][i] * tau
                    + d[3][i] * tau * tau / 2.0
                    + d[4][i] * tau.powi(3) / 6.0;
                let dx = d[2][i] + d[3][i] * tau + d[4][i] * tau * tau / 2.0;
                let ddx = d[3][i] + d[4][i] * tau;
                match k {
                    0 => x * dx,
                    _ => dx * dx + x * ddx,
                }
            })
            .sum()
    };
    let speed2: f64 = (0..m).map(|i| d[1][i] * d[1][i]).sum();
    let slope = v(0.0, 0);
    if slope.is_nan() || slope >= 0.0 {
        return None;
    }
    let mut tau = -speed2 / slope;
    for _ in 0..50 {
        let (g, dg) = (v(tau, 0), v(tau, 1));
        if dg <= 0.0 || !g.is_finite() {
            break;
        }
        let step = g / dg;
        tau -= step;
        if step.abs() <= 1e-14 * tau.abs() {
            break;
        }
    }
    (tau > 0.0 && tau.is_finite()).then_some(tau)
}

/// Points on the circle for the gap's interpolant (a power of two).
pub const CIRCLE_POINTS: usize = 64;

/// The polynomial of degree `N − 1` interpolating the state at `N`
/// equispaced points of the circle `|t − c| = r`: on the upper half from the
/// path, on the lower half their mirror images (the solution is real on the
/// real axis, so `z(t̄) = z̄(t)`). For a state analytic in a disk of radius
/// `R > r` it converges like `(r/R)^N` on the whole closed disk, the real
/// segment `[c − r, c + r]` (the gap) included; the size of its upper half
/// of coefficients estimates its error.
pub struct CircleInterpolant {
    pub centre: f64,
    pub radius: f64,
    /// `coef[i][k]`: coefficient of `((t − c)/r)^k` for component `i`.
    pub coef: Vec<Vec<Complex64>>,
}

impl CircleInterpolant {
    /// From `values[j][i]`, component `i` at `t_j = c + r e^{2πij/N}`.
    pub fn new(centre: f64, radius: f64, values: &[Vec<Complex64>]) -> CircleInterpolant {
        let n = values.len();
        let dim = values[0].len();
        let mut coef = vec![vec![Complex64::new(0.0, 0.0); n]; dim];
        for (i, c) in coef.iter_mut().enumerate() {
            for (k, ck) in c.iter_mut().enumerate() {
                let mut acc = Complex64::new(0.0, 0.0);
                for (j, v) in values.iter().enumerate() {
                    let angle = -2.0 * std::f64::consts::PI * ((j * k) % n) as f64 / n as f64;
                    acc += v[i] * Complex64::from_polar(1.0, angle);
                }
                *ck = acc / n as f64;
            }
        }
        CircleInterpolant {
            centre,
            radius,
            coef,
        }
    }

    /// Component `i` at `t` (complex allowed).
    pub fn eval(&self, i: usize, t: Complex64) -> Complex64 {
        let sigma = (t - self.centre) / self.radius;
        let mut acc = Complex64::new(0.0, 0.0);
        for c in self.coef[i].iter().rev() {
            acc = acc * sigma + c;
        }
        acc
    }

    /// The state at real time `t` into `out` (real parts).
    pub fn state(&self, t: f64, out: &mut [f64]) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.eval(i, Complex64::new(t, 0.0)).re;
        }
    }

    /// The error estimate on the closed disk: the sum of the moduli of the
    /// upper half of the coefficients, per component, relative to `scale[i]`.
    pub fn tail(&self, scale: &[f64]) -> f64 {
        let n = self.coef.first().map_or(0, Vec::len);
        self.coef
            .iter()
            .zip(scale)
            .map(|(c, s)| c[n / 2..].iter().map(|x| x.norm()).sum::<f64>() / s)
            .fold(0.0, f64::max)
    }
}

/// What [`cross`] needs of the explicit form that calls it.
pub struct Stop<'a, S: Scene> {
    pub scene: &'a S,
    pub e: &'a nonholo_core::scene::EmbeddingInfo,
    /// The stop and the state `y = (z, q_c)` there (with
    /// `u = (q⁗, q⁽⁵⁾, q⁽⁶⁾)` of its solve).
    pub t: f64,
    pub z: &'a [f64],
    pub u: &'a [f64],
    /// The branch reference at the stop.
    pub near: &'a [f64],
    pub number: usize,
}

/// What the path found: the state where it returns to the real axis, the
/// branch reference there, the gap and the record (the restart is the
/// explicit form's).
pub struct Across {
    pub t: f64,
    pub z: Vec<f64>,
    /// `q⁗` at the return (real part).
    pub fourth: Vec<f64>,
    pub near: Vec<f64>,
    pub gap: GapFill,
    pub stats: Stats,
    pub record: CrossingRecord,
}

/// Continues the solution from the stop along the half circle; see the
/// module documentation.
pub fn cross<S: Scene>(
    stop: Stop<'_, S>,
    reduction: &mut Reduction<C64>,
    method: Method,
    opts: &Options,
) -> Result<Across, String> {
    let m = stop.e.independent.len();
    let dim = 4 * m + stop.e.cyclic.len();
    let t_a = stop.t;
    // Derivatives 0..4 of q_I at the stop.
    let mut at_a: Vec<Vec<f64>> = (0..4)
        .map(|k| stop.z[k * m..(k + 1) * m].to_vec())
        .collect();
    at_a.push(stop.u[..m].to_vec());
    let tau = singular_instant(&at_a).ok_or_else(|| {
        "the speed's Taylor polynomial at the stop does not fall to a minimum ahead".to_string()
    })?;
    let path = HalfCircle {
        centre: t_a + 1.5 * tau,
        radius: 1.5 * tau,
    };
    // The complex solve starts from the real consistent point.
    let mut d = vec![C64::from(0.0); 7 * m];
    for (x, &v) in d.iter_mut().zip(stop.z[..4 * m].iter().chain(stop.u)) {
        *x = C64::from(v);
    }
    reduction.set_branch(stop.near);
    reduction.reset(stop.scene, stop.e, C64::from(t_a), &d)?;
    let mut sys = Path::new(stop.scene, stop.e, path, reduction, stop.near.to_vec());
    let mut y0 = vec![0.0; 2 * dim];
    for (k, &v) in stop.z.iter().enumerate() {
        y0[2 * k] = v;
    }
    sys.start_at(&y0)?;
    let method = if method == Method::Dopri5 {
        Method::Dopri5
    } else {
        Method::Dop853
    };
    let path_opts = Options {
        rtol: opts.rtol,
        atol: opts.atol,
        max_steps: opts.max_steps,
        max_wall_time_s: opts.max_wall_time_s,
        dense: true,
        ..Options::default()
    };
    let sol = solve(method, &mut sys, 0.0, &y0, 1.0, &path_opts).map_err(|f| {
        // The integrator's "t" is the path parameter s ∈ [0, 1].
        let why = f.error.to_string();
        format!(
            "the path in complex time did not reach its end: {}",
            why.strip_prefix("at t = ")
                .map_or(why.clone(), |rest| format!("at path parameter s = {rest}"))
        )
    })?;
    let t_b = t_a + 3.0 * tau;
    let z_b: Vec<C64> = (0..dim)
        .map(|k| C64(Complex64::new(sol.y_last[2 * k], sol.y_last[2 * k + 1])))
        .collect();
    let w_b: Vec<C64> = sys
        .reduction
        .fourth(stop.scene, stop.e, C64::from(t_b), &z_b)?
        .to_vec();
    // Imaginary parts left on the real axis, relative to each component.
    let return_residual = z_b
        .iter()
        .map(|z| z.im().abs() / z.re().abs().max(1.0))
        .fold(0.0f64, f64::max);
    let allowed = RETURN_FACTOR * opts.rtol.max(opts.atol);
    if return_residual.is_nan() || return_residual > allowed {
        return Err(format!(
            "the path returned to the real axis at t = {t_b} with an imaginary part of \
             {return_residual:.3e} relative to the state (allowed {:.1e}): the continuation \
             does not meet the tolerance",
            RETURN_FACTOR * opts.rtol.max(opts.atol)
        ));
    }
    // The gap's interpolant: the path's continuous extension at N points of
    // the circle's upper half, their mirror images below.
    let dense = sol
        .dense
        .as_ref()
        .ok_or_else(|| "the path kept no continuous extension".to_string())?;
    let n = CIRCLE_POINTS;
    let mut zs = vec![0.0; 2 * dim];
    let mut values = vec![vec![Complex64::new(0.0, 0.0); dim]; n];
    for j in 0..=n / 2 {
        // t_j = c + r e^{iθ}, θ = 2πj/N = π(1 − s).
        let s = 1.0 - 2.0 * j as f64 / n as f64;
        if !dense.eval(s.clamp(0.0, 1.0), &mut zs) {
            return Err(format!(
                "the path's continuous extension has no value at s = {s}"
            ));
        }
        for k in 0..dim {
            let z = Complex64::new(zs[2 * k], zs[2 * k + 1]);
            values[j][k] = z;
            if j > 0 && j < n / 2 {
                values[n - j][k] = z.conj();
            }
        }
    }
    // The ends lie on the real axis: there the states are real.
    for k in 0..dim {
        values[n / 2][k] = Complex64::new(stop.z[k], 0.0);
        values[0][k] = Complex64::new(z_b[k].re(), 0.0);
    }
    let interpolant = CircleInterpolant::new(path.centre, path.radius, &values);
    let scale: Vec<f64> = (0..dim)
        .map(|k| stop.z[k].abs().max(z_b[k].norm()).max(1.0))
        .collect();
    let gap_error = interpolant.tail(&scale);
    if gap_error.is_nan() || gap_error > allowed {
        return Err(format!(
            "the interpolant of the states between t = {t_a} and {t_b} (degree {}, on the \
             circle through both) is accurate only to {gap_error:.3e} relative (allowed \
             {:.1e}): the solution is not analytic far enough around the singular instant",
            n - 1,
            RETURN_FACTOR * opts.rtol.max(opts.atol)
        ));
    }
    let _ = &w_b;
    let near = sys.near.clone();
    let z: Vec<f64> = z_b.iter().map(|z| z.re()).collect();
    let fourth = w_b.iter().map(|w| w.re()).collect();
    let gap: GapFill = Box::new(move |t, out| interpolant.state(t, out));
    Ok(Across {
        t: t_b,
        z,
        fourth,
        near,
        gap,
        stats: sol.stats,
        record: CrossingRecord {
            number: stop.number,
            t_stop: t_a,
            t_singular: t_a + tau,
            t_resume: t_b,
            clearance: tau,
            gap_error,
            return_residual,
            restart_change: 0.0,
        },
    })
}

/// The explicit form's crossing, packaged for the run.
pub fn crossed(across: Across, restart_change: f64) -> Crossed {
    let mut record = across.record;
    record.restart_change = restart_change;
    Crossed {
        t: across.t,
        y: across.z,
        gap: across.gap,
        stats: across.stats,
        record,
    }
}
