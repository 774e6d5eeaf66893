//! Diagnostics accumulated along a run: constraint residuals, energy and
//! invariant drift, measured at the initial state and after every accepted step.

use num_dual::Dual64;

use crate::ad::Jet;
use crate::constraints::nan_max;
use crate::scene::{Lagrangian, Scene};

/// Drift of one scene invariant.
#[derive(Debug, Clone, PartialEq)]
pub struct InvariantDrift {
    pub name: String,
    pub initial: f64,
    /// `max |I(t) − I(0)|`.
    pub drift_max: f64,
}

/// Diagnostics of a run. Residuals are maxima over the checked states.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Diagnostics {
    /// `max(nonholonomic, holonomic, holonomic velocity)` residuals.
    pub constraint_residual_max: f64,
    /// `max |g(q, q̇, t)|`.
    pub nonholonomic_residual_max: f64,
    /// `max |f(q, t)|`.
    pub holonomic_residual_max: f64,
    /// `max |ḟ(q, q̇, t)|`.
    pub holonomic_velocity_residual_max: f64,
    /// `E = q̇·∂L/∂q̇ − L` at the start.
    pub energy_initial: f64,
    /// `E` at the last checked state.
    pub energy_final: f64,
    /// `max |E(t) − E(0)|`.
    pub energy_drift_max: f64,
    pub invariants: Vec<InvariantDrift>,
    /// Number of states checked (initial state plus accepted steps).
    pub states_checked: usize,
}

/// Accumulates [`Diagnostics`] from physical states `(t, q, q̇)`.
#[derive(Debug, Clone)]
pub struct Monitor {
    jet: Jet,
    g: Vec<f64>,
    fd: Vec<Dual64>,
    qdual: Vec<Dual64>,
    diag: Diagnostics,
    /// The diagnostics before the last [`Monitor::record`], for
    /// [`Monitor::rewind`].
    prev: Diagnostics,
}

impl Monitor {
    pub fn new<S: Scene>(scene: &S) -> Self {
        let info = scene.info();
        let n = info.n();
        let diag = Diagnostics {
            invariants: info
                .invariants
                .iter()
                .map(|i| InvariantDrift {
                    name: i.name.to_string(),
                    initial: f64::NAN,
                    drift_max: 0.0,
                })
                .collect(),
            ..Diagnostics::default()
        };
        Monitor {
            jet: Jet::new(n, info.s().max(info.k())),
            g: vec![0.0; info.s()],
            fd: vec![Dual64::from_re(0.0); info.k()],
            qdual: vec![Dual64::from_re(0.0); n],
            prev: diag.clone(),
            diag,
        }
    }

    /// Replaces the state of the last [`Monitor::record`] by `(t, q, q̇)`: a
    /// step whose end lies past a located stop of the guard (a change of
    /// mode inside it) must not count its end state, computed with the
    /// equations of the mode before.
    pub fn rewind<S: Scene>(&mut self, scene: &S, t: f64, q: &[f64], qd: &[f64]) {
        self.diag.clone_from(&self.prev);
        self.record(scene, t, q, qd);
    }

    /// Records one state. The first call fixes the initial energy and invariants.
    pub fn record<S: Scene>(&mut self, scene: &S, t: f64, q: &[f64], qd: &[f64]) {
        self.prev.clone_from(&self.diag);
        let info = scene.info();
        let d = &mut self.diag;
        if info.s() > 0 {
            scene.nonholonomic(t, q, qd, &mut self.g);
            let r = self.g.iter().fold(0.0f64, |m, v| nan_max(m, v.abs()));
            d.nonholonomic_residual_max = nan_max(d.nonholonomic_residual_max, r);
        }
        if info.k() > 0 {
            // One dual pass along q̇ gives f and ḟ.
            for ((s, &x), &v) in self.qdual.iter_mut().zip(q).zip(qd) {
                *s = Dual64::new(x, v);
            }
            scene.holonomic(Dual64::new(t, 1.0), &self.qdual, &mut self.fd);
            let (rf, rfd) = self.fd.iter().fold((0.0f64, 0.0f64), |(a, b), v| {
                (nan_max(a, v.re.abs()), nan_max(b, v.eps.abs()))
            });
            d.holonomic_residual_max = nan_max(d.holonomic_residual_max, rf);
            d.holonomic_velocity_residual_max = nan_max(d.holonomic_velocity_residual_max, rfd);
        }
        d.constraint_residual_max = nan_max(
            nan_max(d.nonholonomic_residual_max, d.holonomic_residual_max),
            d.holonomic_velocity_residual_max,
        );

        let e = self.jet.energy(&Lagrangian(scene), t, q, qd, &[]);
        if d.states_checked == 0 {
            d.energy_initial = e;
            for (i, inv) in d.invariants.iter_mut().enumerate() {
                inv.initial = scene.invariant(i, t, q, qd);
            }
        } else {
            d.energy_drift_max = nan_max(d.energy_drift_max, (e - d.energy_initial).abs());
            for (i, inv) in d.invariants.iter_mut().enumerate() {
                let v = scene.invariant(i, t, q, qd);
                inv.drift_max = nan_max(inv.drift_max, (v - inv.initial).abs());
            }
        }
        d.energy_final = e;
        d.states_checked += 1;
    }

    pub fn diagnostics(&self) -> &Diagnostics {
        &self.diag
    }
}

/// `(max(|g|, |f|, |ḟ|), E)` at one state: the constraint residual and the
/// energy `E = q̇·∂L/∂q̇ − L`, for time series of results (not a hot path).
pub fn state_measures<S: Scene>(scene: &S, t: f64, q: &[f64], qd: &[f64]) -> (f64, f64) {
    let mut m = Monitor::new(scene);
    m.record(scene, t, q, qd);
    let d = m.diagnostics();
    (d.constraint_residual_max, d.energy_initial)
}
