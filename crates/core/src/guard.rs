//! Stopping at a singular set, located even when the motion passes through
//! it within one step.
//!
//! A singular set is the zero set of a vector `r(t, q, q̇)` (the horizontal
//! velocity of Appell–Hamel, the sleigh's velocity for the embedding map). Its
//! size `|r|` never changes sign, so an integrator that watches it can step
//! straight across a zero. The guard here is signed:
//!
//! ```text
//! g = r · r̂_ref − tol
//! ```
//!
//! with `r̂_ref` the direction of `r` at the start of the current step. When
//! `r` passes through zero inside a step it reverses, `g` turns negative at
//! the step's end, and the crossing is located on the step polynomial where
//! `g = 0`, i.e. where `r`'s component along its previous direction falls to `tol`.
//!
//! The integrators call `after_step` before the guard of the same step, so
//! the reference is promoted lazily: [`SingularGuard::accept`] (from
//! `after_step`) makes the direction saved at the previous accepted state
//! current and saves the new one.

use crate::scene::MAX_SINGULAR;

/// Signed guard for one singular set.
#[derive(Debug, Clone, PartialEq)]
pub struct SingularGuard {
    pub tol: f64,
    current: [f64; MAX_SINGULAR],
    pending: [f64; MAX_SINGULAR],
}

fn unit(r: &[f64; MAX_SINGULAR], p: usize) -> [f64; MAX_SINGULAR] {
    let norm = r[..p].iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut u = [0.0; MAX_SINGULAR];
    if norm > 0.0 {
        for i in 0..p {
            u[i] = r[i] / norm;
        }
    }
    u
}

impl SingularGuard {
    pub fn new(tol: f64) -> Self {
        SingularGuard {
            tol,
            current: [0.0; MAX_SINGULAR],
            pending: [0.0; MAX_SINGULAR],
        }
    }

    /// At the initial state: the reference is the initial direction.
    pub fn start(&mut self, r: &[f64; MAX_SINGULAR], p: usize) {
        self.current = unit(r, p);
        self.pending = self.current;
    }

    /// After an accepted step at state `r`.
    pub fn accept(&mut self, r: &[f64; MAX_SINGULAR], p: usize) {
        self.current = self.pending;
        self.pending = unit(r, p);
    }

    /// `r · r̂_ref − tol` (`r̂_ref` is `r`'s own direction at the start).
    pub fn value(&self, r: &[f64; MAX_SINGULAR], p: usize) -> f64 {
        let along: f64 = (0..p).map(|i| r[i] * self.current[i]).sum();
        along - self.tol
    }

    /// Whether `r` (of `p` components) lies on the far side of the singular
    /// set: its component along the reference direction has turned negative
    /// by more than `tol` (`p = 0`: no singular set, never).
    pub fn crossed(&self, r: &[f64; MAX_SINGULAR], p: usize) -> bool {
        p > 0 && self.value(r, p) + self.tol < 0.0
    }
}

/// `|r|`.
pub fn magnitude(r: &[f64; MAX_SINGULAR], p: usize) -> f64 {
    r[..p].iter().map(|v| v * v).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A velocity that reverses inside one "step" turns the guard negative
    /// although |r| is positive at both ends.
    #[test]
    fn reversal_within_a_step_changes_the_sign() {
        let mut g = SingularGuard::new(1e-8);
        let before = [0.6, 0.8, 0.0, 0.0];
        g.start(&before, 2);
        assert!(g.value(&before, 2) > 0.0);
        // The integrator accepts the step, calls after_step, then the guard.
        let after = [-0.3, -0.4, 0.0, 0.0];
        g.accept(&after, 2);
        assert!(g.value(&after, 2) < 0.0, "{}", g.value(&after, 2));
        assert!(magnitude(&after, 2) > 0.4);
        // Next step: the reference has moved to the reversed direction.
        g.accept(&after, 2);
        assert!(g.value(&after, 2) > 0.0);
    }
}
