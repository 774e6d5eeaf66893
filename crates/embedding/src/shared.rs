//! What both forms of A share: the scene and its embedding map, the
//! physical reading of a state `y = (z, q_c)`, `z = (q_I, q̇_I, q̈_I, q⃛_I)`
//! and `q_c` the cyclic dependent coordinates (integrated as quadratures of
//! their rates from the map), the diagnostics, and the guard at the map's
//! singular set.

use std::sync::Arc;

use nonholo_core::guard::{SingularGuard, magnitude};
use nonholo_core::integrate::SystemError;
use nonholo_core::monitor::{Diagnostics, Monitor};
use nonholo_core::scene::{EmbeddingInfo, MAX_SINGULAR, Scene};

use crate::elo::{cyclic_rates, reconstruct};

/// The scene, its map, and the per-run state every form of A keeps.
pub struct Shared<S: Scene> {
    pub scene: Arc<S>,
    pub e: EmbeddingInfo,
    /// Number of coordinates `n`, of independent ones `m`, and of cyclic
    /// dependent ones `c` (the state has `4m + c` components).
    pub n: usize,
    pub m: usize,
    pub c: usize,
    pub guard: SingularGuard,
    r: [f64; MAX_SINGULAR],
    monitor: Monitor,
    /// Physical `(q, q̇)` of the last reading.
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    /// Last reported dependent coordinates, for unwrapping angles.
    last_dep: Vec<f64>,
    /// Reference values of the dependent coordinates: the branch of the
    /// map in use ([`Scene::embedding`]; empty: its principal branch).
    pub near: Vec<f64>,
    /// Scratch for the map's value, and the cyclic rates.
    dep: Vec<f64>,
    rates: Vec<f64>,
    /// The branch along the run, for readings after it ([`Shared::read`]):
    /// the times of the start, of every accepted step and of every return
    /// from a crossing, the dependent coordinates there (`s` per entry) and
    /// whether the branch was followed (`near` not empty) from there on.
    log_t: Vec<f64>,
    log_dep: Vec<f64>,
    log_following: Vec<bool>,
}

impl<S: Scene> Shared<S> {
    /// For `scene` (which has an embedding map), stopping `singular_tol`
    /// from the map's singular set.
    pub fn new(scene: Arc<S>, singular_tol: f64) -> Self {
        let info = scene.info();
        let e = info.embedding.expect("checked by applicable");
        let (n, m, c) = (info.n(), e.independent.len(), e.cyclic.len());
        Shared {
            e,
            n,
            m,
            c,
            guard: SingularGuard::new(singular_tol),
            r: [0.0; MAX_SINGULAR],
            monitor: Monitor::new(&*scene),
            q: vec![0.0; n],
            qd: vec![0.0; n],
            last_dep: vec![0.0; e.dependent.len()],
            near: Vec::new(),
            dep: vec![0.0; e.dependent.len()],
            rates: vec![0.0; c],
            log_t: Vec::new(),
            log_dep: Vec::new(),
            log_following: Vec::new(),
            scene,
        }
    }

    /// Components of the state: `z` (4m) and the cyclic coordinates.
    pub fn dim(&self) -> usize {
        4 * self.m + self.c
    }

    /// Whether dependent coordinate `i` (an index into `q`) is cyclic.
    pub fn is_cyclic(&self, i: usize) -> bool {
        self.e.cyclic.contains(&i)
    }

    /// The rates of the cyclic coordinates at `(t, y)` (the map's value on
    /// the branch in use).
    pub fn cyclic_rates(&mut self, t: f64, y: &[f64]) -> &[f64] {
        let m = self.m;
        cyclic_rates(
            &*self.scene,
            &self.e,
            t,
            &y[..m],
            &y[m..2 * m],
            &self.near,
            &mut self.dep,
            &mut self.rates,
        );
        &self.rates
    }

    /// Starts a run at `(t0, y0)`: dependent angles are unwrapped from the
    /// given `q0`, the diagnostics and the guard start here.
    pub fn start(&mut self, t0: f64, z0: &[f64], q0: &[f64]) {
        self.last_dep = self.e.dependent.iter().map(|&i| q0[i]).collect();
        self.log_t.clear();
        self.log_dep.clear();
        self.log_following.clear();
        self.physical(t0, z0);
        self.log(t0);
        self.monitor = Monitor::new(&*self.scene);
        self.monitor.record(&*self.scene, t0, &self.q, &self.qd);
        let p = self.singular_vector(t0, z0);
        self.guard.start(&self.r, p);
    }

    /// Resumes a run at `(t, z)` after a crossing: the guard starts again
    /// there (diagnostics and the unwrapping of angles go on).
    pub fn resume(&mut self, t: f64, z: &[f64]) {
        self.physical(t, z);
        self.log(t);
        self.monitor.record(&*self.scene, t, &self.q, &self.qd);
        let p = self.singular_vector(t, z);
        self.guard.start(&self.r, p);
    }

    /// With the branch followed (`near` not empty): moves `near` to the
    /// dependent coordinates of the last reading when they have turned by
    /// more than π/4 from it (the branch nearest to `near` is then still
    /// theirs); returns whether it moved.
    pub fn follow_branch(&mut self) -> bool {
        if self.near.is_empty() {
            return false;
        }
        let turned = self.e.dependent.iter().enumerate().any(|(j, &i)| {
            !self.is_cyclic(i) && (self.q[i] - self.near[j]).abs() > std::f64::consts::FRAC_PI_4
        });
        if turned {
            for (j, &i) in self.e.dependent.iter().enumerate() {
                self.near[j] = self.q[i];
            }
        }
        turned
    }

    /// Physical `(q, q̇)` from the state `y = (z, q_c)` into [`Shared::q`],
    /// [`Shared::qd`], dependent angles unwrapped to the branch nearest the
    /// last reported value (the cyclic ones are the state's).
    pub fn physical(&mut self, t: f64, z: &[f64]) {
        let m = self.m;
        for (k, &i) in self.e.cyclic.iter().enumerate() {
            self.q[i] = z[4 * m + k];
        }
        reconstruct(
            &*self.scene,
            &self.e,
            t,
            &z[..m],
            &z[m..2 * m],
            &z[2 * m..3 * m],
            &self.near,
            &mut self.q,
            &mut self.qd,
        );
        let coords = self.scene.info().coordinates;
        for (j, &i) in self.e.dependent.iter().enumerate() {
            if coords[i].unit == "rad" && !self.e.cyclic.contains(&i) {
                let two_pi = std::f64::consts::TAU;
                let k = ((self.last_dep[j] - self.q[i]) / two_pi).round();
                self.q[i] += k * two_pi;
            }
            self.last_dep[j] = self.q[i];
        }
    }

    /// Follows the branch of the last reading from now on (`near` set to its
    /// dependent coordinates, the log's last entry marked as following);
    /// returns `near`.
    pub fn follow_current(&mut self) -> Vec<f64> {
        self.near = self.e.dependent.iter().map(|&i| self.q[i]).collect();
        if let Some(last) = self.log_following.last_mut() {
            *last = true;
        }
        self.near.clone()
    }

    /// Logs the branch at `t` (after [`Shared::physical`] there).
    fn log(&mut self, t: f64) {
        self.log_t.push(t);
        self.log_dep
            .extend(self.e.dependent.iter().map(|&i| self.q[i]));
        self.log_following.push(!self.near.is_empty());
    }

    /// Physical `(q, q̇)` of a state `y` at `t` read after the run (samples,
    /// dense output), in any order: on the branch the run used at `t`, taken
    /// from its log entry at or before `t` — the branch nearest to the
    /// dependent coordinates there where the run followed the branch, else
    /// the map's principal branch with angles unwrapped to the nearest
    /// turn. Before any entry (no run yet), as [`Shared::physical`].
    pub fn read(&mut self, t: f64, y: &[f64]) {
        let k = self.log_t.partition_point(|&x| x <= t);
        if k == 0 {
            self.physical(t, y);
            return;
        }
        let s = self.e.dependent.len();
        let reference = &self.log_dep[(k - 1) * s..k * s];
        self.last_dep.copy_from_slice(reference);
        let near = if self.log_following[k - 1] {
            reference.to_vec()
        } else {
            Vec::new()
        };
        let kept = std::mem::replace(&mut self.near, near);
        self.physical(t, y);
        self.near = kept;
    }

    /// The embedding map's singular-set vector at `(q_I, q̇_I)` into `r`.
    fn singular_vector(&mut self, t: f64, z: &[f64]) -> usize {
        let m = self.m;
        self.scene
            .embedding_singularity(t, &z[..m], &z[m..2 * m], &mut self.r)
    }

    /// `|r|` at `(t, z)`: the distance from the map's singular set.
    pub fn distance(&mut self, t: f64, z: &[f64]) -> Option<f64> {
        let p = self.singular_vector(t, z);
        (p > 0).then(|| magnitude(&self.r, p))
    }

    /// Refuses a stage beyond the singular set: the guard's signed distance,
    /// measured along the direction at the step start, has fallen below zero.
    pub fn check_stage(&mut self, t: f64, z: &[f64]) -> Result<(), SystemError> {
        let p = self.singular_vector(t, z);
        if self.guard.crossed(&self.r, p) {
            return Err(SystemError::new(format!(
                "a stage crossed the singular set of the embedding map {} ({})",
                self.e.formula, self.e.singular_set
            )));
        }
        Ok(())
    }

    /// The error for equations that are not finite at `z`.
    pub fn not_finite(&mut self, t: f64, z: &[f64]) -> SystemError {
        let p = self.singular_vector(t, z);
        SystemError::new(format!(
            "the equations (19) are not finite here (|r| = {:.3e}): the embedding map is singular",
            magnitude(&self.r, p)
        ))
    }

    /// After an accepted step: diagnostics of the physical state, and the
    /// guard's reference direction.
    pub fn accept_state(&mut self, t: f64, z: &[f64]) {
        self.physical(t, z);
        self.log(t);
        self.monitor.record(&*self.scene, t, &self.q, &self.qd);
        let p = self.singular_vector(t, z);
        self.guard.accept(&self.r, p);
    }

    /// Signed distance from the embedding map's singular set (see
    /// `nonholo_core::guard`): the singular vector's component along its
    /// direction at the start of the step, minus `singular_tol`.
    pub fn guard_value(&mut self, t: f64, z: &[f64]) -> Option<f64> {
        let p = self.singular_vector(t, z);
        (p > 0).then(|| self.guard.value(&self.r, p))
    }

    /// `|r|` at `(t, z)` and the zero of the guard's signed distance,
    /// extrapolated linearly from the rate at which `r` falls along its own
    /// direction, as text.
    pub fn approach(&mut self, t: f64, z: &[f64]) -> (f64, String) {
        let m = self.m;
        let p = self.singular_vector(t, z);
        let size = magnitude(&self.r, p);
        if p == 0 {
            return (size, String::new());
        }
        let h = 1e-7 * (1.0 + t.abs());
        let later: Vec<f64> = (0..2 * m).map(|i| z[i] + h * z[m + i]).collect();
        let along_now = self.guard.value(&self.r, p);
        let pl = self.singular_vector(t + h, &later);
        let rate = (self.guard.value(&self.r, pl) - along_now) / h;
        let crossing = if rate < 0.0 {
            format!(
                "; extrapolated zero at t ≈ {:.9}",
                t - (along_now + self.guard.tol) / rate
            )
        } else {
            String::new()
        };
        (size, crossing)
    }

    /// Why the guard at the singular set stopped the run.
    pub fn guard_text(&mut self, t: f64, z: &[f64]) -> String {
        let (size, crossing) = self.approach(t, z);
        format!(
            "the motion came within singular_tol = {:.1e} of the singular set of the embedding \
             map {} — {} (|r| = {size:.3e}{crossing})",
            self.guard.tol, self.e.formula, self.e.singular_set
        )
    }

    pub fn diagnostics(&self) -> &Diagnostics {
        self.monitor.diagnostics()
    }
}
