//! Hand-written sleigh equations: the baselines of the right-hand-side
//! benchmark. Nothing here is differentiated automatically.
//!
//! - [`ReducedB`], [`ReducedC`]: the spec's reduced equations
//!   (`shared/spec/mechanics.md`, scene `sleigh-incline`) in the state
//!   `(x, y, φ, u, ω)` and `(x, y, φ, u, ω, μ)`, with the kinematics
//!   `ẋ = u cos φ`, `ẏ = u sin φ`, `φ̇ = ω`. They live on the constraint
//!   manifold: one state fewer than B's `(q, q̇)`, no KKT system.
//! - [`BodyFrame`]: the realisations `visc(k)` and `mass(N)` (both forms)
//!   in the formulations' own Cartesian state, through the body-frame
//!   quasi-velocities `(u, w, ω)` and Kirchhoff's equations on SE(2) with
//!   `T = ½m(u² + w² + Jω² + 2aωw) + ½N w²` and friction `−k w` (the
//!   derivation of `crates/realise/tests/sleigh.rs`, written again here).
//!
//! `tests/hand.rs` checks every one of them against the AD formulation it
//! stands in for, so the benchmark compares equal answers.

use nonholo_integrate::{OdeSystem, SystemError};
use nonholo_scenes::Sleigh;
use nonholo_scenes::sleigh::Potential;

/// Scene constants the hand-written equations need.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Constants {
    pub m: f64,
    pub j: f64,
    pub a: f64,
    /// `g sin α`.
    pub gs: f64,
    /// 1 with `potential = com` (gravity at the centre of mass), else 0.
    pub com: f64,
}

impl Constants {
    pub fn of(s: &Sleigh) -> Self {
        Constants {
            m: s.m,
            j: s.j,
            a: s.a,
            gs: s.g * s.alpha.sin(),
            com: match s.potential {
                Potential::Com => 1.0,
                Potential::Paper => 0.0,
            },
        }
    }
}

/// B's reduced equations, state `(x, y, φ, u, ω)`:
///
/// ```text
/// u̇ = aω² + g sin α cos φ
/// ω̇ = −(a u ω + [com] g a sin α sin φ)/J
/// ```
#[derive(Debug, Clone)]
pub struct ReducedB(pub Constants);

impl OdeSystem for ReducedB {
    fn dim(&self) -> usize {
        5
    }

    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let Constants { j, a, gs, com, .. } = self.0;
        let (phi, u, om) = (y[2], y[3], y[4]);
        let (s, c) = phi.sin_cos();
        dy[0] = u * c;
        dy[1] = u * s;
        dy[2] = om;
        dy[3] = a * om * om + gs * c;
        dy[4] = -(a * u * om + com * gs * a * s) / j;
        Ok(())
    }

    /// The analytic Jacobian, row-major 5 × 5.
    fn jacobian(&mut self, _t: f64, y: &[f64], jac: &mut [f64]) -> Result<bool, SystemError> {
        let Constants { j, a, gs, com, .. } = self.0;
        let (phi, u, om) = (y[2], y[3], y[4]);
        let (s, c) = phi.sin_cos();
        jac.fill(0.0);
        jac[2] = -u * s;
        jac[3] = c;
        jac[5 + 2] = u * c;
        jac[5 + 3] = s;
        jac[10 + 4] = 1.0;
        jac[15 + 2] = -gs * s;
        jac[15 + 4] = 2.0 * a * om;
        jac[20 + 2] = -com * gs * a * c / j;
        jac[20 + 3] = -a * om / j;
        jac[20 + 4] = -a * u / j;
        Ok(true)
    }
}

/// C's reduced equations, state `(x, y, φ, u, ω, μ)` with `μ = λ + m a ω`:
///
/// ```text
/// u̇ = μω/m + g sin α cos φ
/// ω̇ = −(μ u/m + [com] g a sin α sin φ)/J
/// μ̇ = −m u ω − m g sin α sin φ
/// ```
#[derive(Debug, Clone)]
pub struct ReducedC(pub Constants);

impl OdeSystem for ReducedC {
    fn dim(&self) -> usize {
        6
    }

    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let Constants { m, j, a, gs, com } = self.0;
        let (phi, u, om, mu) = (y[2], y[3], y[4], y[5]);
        let (s, c) = phi.sin_cos();
        dy[0] = u * c;
        dy[1] = u * s;
        dy[2] = om;
        dy[3] = mu * om / m + gs * c;
        dy[4] = -(mu * u / m + com * gs * a * s) / j;
        dy[5] = -m * u * om - m * gs * s;
        Ok(())
    }
}

/// Which realisation [`BodyFrame`] writes out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Realisation {
    /// `visc(k)`, state `(q, q̇)`.
    Visc,
    /// `mass(N)`, `form = direct`, state `(q, q̇)`.
    MassDirect,
    /// `mass(N)`, `form = compliance`, state `(q, q̇, λ)` with `λ` in place
    /// of `N w` in the sideways momentum, and `λ̇ = N ẇ`.
    MassCompliance,
}

/// A realisation in Cartesian state through the body frame:
///
/// ```text
/// d/dt ∂T/∂u = ω ∂T/∂w + F_u
/// d/dt ∂T/∂w = −ω ∂T/∂u + F_w − k w
/// d/dt ∂T/∂ω = w ∂T/∂u − u ∂T/∂w + τ
/// ```
///
/// with gravity `F = m g sin α (cos φ, −sin φ)` at the blade and
/// `τ = −[com] m g a sin α sin φ`; then `q̈` from `(u̇, ẇ, ω̇)`.
#[derive(Debug, Clone)]
pub struct BodyFrame {
    pub c: Constants,
    pub which: Realisation,
    /// The gain: `k` for [`Realisation::Visc`], `N` for the mass forms.
    pub gain: f64,
}

impl OdeSystem for BodyFrame {
    fn dim(&self) -> usize {
        match self.which {
            Realisation::MassCompliance => 7,
            _ => 6,
        }
    }

    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let Constants { m, j, a, gs, com } = self.c;
        let (phi, xd, yd, om) = (y[2], y[3], y[4], y[5]);
        let (s, c) = phi.sin_cos();
        let u = xd * c + yd * s;
        let w = yd * c - xd * s;
        let (k, n, side) = match self.which {
            Realisation::Visc => (self.gain, 0.0, 0.0),
            Realisation::MassDirect => (0.0, self.gain, self.gain * w),
            Realisation::MassCompliance => (0.0, self.gain, y[6]),
        };
        // Sideways momentum ∂T/∂w.
        let pw = m * (w + a * om) + side;
        let ud = (om * pw + m * gs * c) / m;
        // [m + N, m a; m a, m J] (ẇ, ω̇) = (r1, r2)
        let r1 = -om * m * u - m * gs * s - k * w;
        let r2 = w * m * u - u * pw - com * m * gs * a * s;
        let (a11, a12, a22) = (m + n, m * a, m * j);
        let det = a11 * a22 - a12 * a12;
        let wd = (r1 * a22 - a12 * r2) / det;
        let omd = (a11 * r2 - a12 * r1) / det;
        dy[0] = xd;
        dy[1] = yd;
        dy[2] = om;
        dy[3] = ud * c - u * om * s - wd * s - w * om * c;
        dy[4] = ud * s + u * om * c + wd * c - w * om * s;
        dy[5] = omd;
        if self.which == Realisation::MassCompliance {
            dy[6] = n * wd;
        }
        Ok(())
    }
}

/// `visc(k)` in the adapted state `(x, y, φ, u, w, ω)`: body-frame
/// velocities, in which the violation `w = g` is a coordinate of its own
/// (the spec: "visc behaves much better in velocities adapted to the
/// constraint"). The same motion as `visc` in `(q, q̇)`, by a different
/// state and different (hand-written) code: the second reference of the
/// stiff peer comparison, where no solver in Cartesian velocities gets
/// through.
#[derive(Debug, Clone)]
pub struct BodyVisc {
    pub c: Constants,
    pub k: f64,
}

impl BodyVisc {
    /// `(x, y, φ, ẋ, ẏ, φ̇)` from `(x, y, φ, u, w, ω)`, in place.
    pub fn to_cartesian(y: &mut [f64]) {
        let (s, c) = y[2].sin_cos();
        let (u, w) = (y[3], y[4]);
        y[3] = u * c - w * s;
        y[4] = u * s + w * c;
    }

    /// `(x, y, φ, u, w, ω)` from `(x, y, φ, ẋ, ẏ, φ̇)`, in place.
    pub fn from_cartesian(y: &mut [f64]) {
        let (s, c) = y[2].sin_cos();
        let (xd, yd) = (y[3], y[4]);
        y[3] = xd * c + yd * s;
        y[4] = yd * c - xd * s;
    }
}

impl OdeSystem for BodyVisc {
    fn dim(&self) -> usize {
        6
    }

    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), SystemError> {
        let Constants { m, j, a, gs, com } = self.c;
        let (phi, u, w, om) = (y[2], y[3], y[4], y[5]);
        let (s, c) = phi.sin_cos();
        let pw = m * (w + a * om);
        let ud = (om * pw + m * gs * c) / m;
        let r1 = -om * m * u - m * gs * s - self.k * w;
        let r2 = w * m * u - u * pw - com * m * gs * a * s;
        let (a11, a12, a22) = (m, m * a, m * j);
        let det = a11 * a22 - a12 * a12;
        dy[0] = u * c - w * s;
        dy[1] = u * s + w * c;
        dy[2] = om;
        dy[3] = ud;
        dy[4] = (r1 * a22 - a12 * r2) / det;
        dy[5] = (a11 * r2 - a12 * r1) / det;
        Ok(())
    }
}
