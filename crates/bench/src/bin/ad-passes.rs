//! A measurement for the open issue on derivative cost: `M = ∂²L/∂q̇²`
//! and `Q = ∂L/∂q − (∂²L/∂q̇∂q) q̇ − ∂²L/∂q̇∂t` of the sleigh's Lagrangian,
//! by the workbench's scalar passes (`Jet::mass_and_force`: `n(n+3)/2`
//! hyper-dual and `n` dual evaluations, each recomputing the trigonometry)
//! against one evaluation with a static-size vector hyper-dual number
//! (`HyperDualSVec64<n, 2n+1>`: `ε₁` along `q̇`, `ε₂` along `(q, q̇, t)`).
//!
//! `cargo run --release -p nonholo-bench --features vector-duals --bin ad-passes`
//!
//! A third line is a bound on what a vector hyper-dual number can cost
//! without num-dual's `Option`-wrapped nalgebra parts: [`Arr`], plain
//! arrays with the few operations the sleigh's Lagrangian uses, and the
//! Lagrangian (eq. 22 with the centre-of-mass term) transcribed for it —
//! a measurement for the design, not a way to write scenes.
//!
//! All three must agree to 1e-13 relative; the line gives the median
//! nanoseconds per evaluation, timed in alternating batches.

use std::process::ExitCode;

use nalgebra::{Const, DMatrix};
use nonholo_bench::timing::{batch_args, keep, paired_ns};
use nonholo_core::Scene;
use nonholo_core::ad::Jet;
use nonholo_core::scene::Lagrangian;
use nonholo_scenes::Sleigh;
use num_dual::{Derivative, HyperDualVec};

const N: usize = 3;
const N2: usize = 2 * N + 1;
type H = HyperDualVec<f64, Const<N>, Const<N2>>;

/// `M` and `Q` from one vector hyper-dual evaluation.
fn one_pass(
    s: &Sleigh,
    t: f64,
    q: &[f64; N],
    qd: &[f64; N],
    m: &mut [[f64; N]; N],
    f: &mut [f64; N],
) {
    let e2 = |k: usize| {
        let mut v = nalgebra::SMatrix::<f64, 1, N2>::zeros();
        v[k] = 1.0;
        Derivative::some(v)
    };
    let e1 = |k: usize| {
        let mut v = nalgebra::SVector::<f64, N>::zeros();
        v[k] = 1.0;
        Derivative::some(v)
    };
    let qh: [H; N] =
        std::array::from_fn(|i| H::new(q[i], Derivative::none(), e2(i), Derivative::none()));
    let qdh: [H; N] = std::array::from_fn(|i| H::new(qd[i], e1(i), e2(N + i), Derivative::none()));
    let th = H::new(t, Derivative::none(), e2(2 * N), Derivative::none());
    let l = s.lagrangian(th, &qh, &qdh);
    let grad = l.eps2.unwrap_generic(Const::<1>, Const::<N2>);
    let mixed = l.eps1eps2.unwrap_generic(Const::<N>, Const::<N2>);
    for i in 0..N {
        let mut qi = grad[i] - mixed[(i, 2 * N)];
        for j in 0..N {
            m[i][j] = mixed[(i, N + j)];
            qi -= mixed[(i, j)] * qd[j];
        }
        f[i] = qi;
    }
}

/// A vector hyper-dual number in plain arrays: `ε₁` along `N` velocity
/// directions, `ε₂` along `K` directions, their products `ε₁ε₂`.
#[derive(Clone, Copy)]
struct Arr {
    re: f64,
    e1: [f64; N],
    e2: [f64; N2],
    e12: [[f64; N2]; N],
}

impl Arr {
    fn constant(re: f64) -> Self {
        Arr {
            re,
            e1: [0.0; N],
            e2: [0.0; N2],
            e12: [[0.0; N2]; N],
        }
    }
    fn add(self, o: Arr) -> Arr {
        let mut r = self;
        r.re += o.re;
        for i in 0..N {
            r.e1[i] += o.e1[i];
            for k in 0..N2 {
                r.e12[i][k] += o.e12[i][k];
            }
        }
        for k in 0..N2 {
            r.e2[k] += o.e2[k];
        }
        r
    }
    fn scale(self, a: f64) -> Arr {
        let mut r = self;
        r.re *= a;
        r.e1.iter_mut().for_each(|x| *x *= a);
        r.e2.iter_mut().for_each(|x| *x *= a);
        r.e12.iter_mut().flatten().for_each(|x| *x *= a);
        r
    }
    fn mul(self, o: Arr) -> Arr {
        let mut r = Arr::constant(self.re * o.re);
        for i in 0..N {
            r.e1[i] = self.e1[i] * o.re + self.re * o.e1[i];
        }
        for k in 0..N2 {
            r.e2[k] = self.e2[k] * o.re + self.re * o.e2[k];
        }
        for i in 0..N {
            for k in 0..N2 {
                r.e12[i][k] = self.e12[i][k] * o.re
                    + self.re * o.e12[i][k]
                    + self.e1[i] * o.e2[k]
                    + o.e1[i] * self.e2[k];
            }
        }
        r
    }
    /// `f(self)` from `f`, `f'`, `f''` at the value.
    fn chain(self, f0: f64, f1: f64, f2: f64) -> Arr {
        let mut r = Arr::constant(f0);
        for i in 0..N {
            r.e1[i] = f1 * self.e1[i];
        }
        for k in 0..N2 {
            r.e2[k] = f1 * self.e2[k];
        }
        for i in 0..N {
            for k in 0..N2 {
                r.e12[i][k] = f1 * self.e12[i][k] + f2 * self.e1[i] * self.e2[k];
            }
        }
        r
    }
    fn sin_cos(self) -> (Arr, Arr) {
        let (s, c) = self.re.sin_cos();
        (self.chain(s, c, -s), self.chain(c, -s, -c))
    }
}

/// The sleigh's Lagrangian (eq. 22, centre-of-mass term) transcribed for
/// [`Arr`]: `½m[ẋ² + ẏ² + Jφ̇² + 2aφ̇(ẏ cos φ − ẋ sin φ)] + m g x sin α + m g a sin α cos φ`.
fn arr_lagrangian(s: &Sleigh, q: &[Arr; N], qd: &[Arr; N]) -> Arr {
    let (x, phi) = (q[0], q[2]);
    let (xd, yd, phid) = (qd[0], qd[1], qd[2]);
    let (sn, cs) = phi.sin_cos();
    let cross = yd.mul(cs).add(xd.mul(sn).scale(-1.0));
    let kinetic = xd
        .mul(xd)
        .add(yd.mul(yd))
        .add(phid.mul(phid).scale(s.j))
        .add(phid.mul(cross).scale(2.0 * s.a))
        .scale(0.5 * s.m);
    let mg_sin = s.m * s.g * s.alpha.sin();
    kinetic.add(x.scale(mg_sin)).add(cs.scale(mg_sin * s.a))
}

/// `M` and `Q` from one [`Arr`] evaluation.
fn arrays(s: &Sleigh, q: &[f64; N], qd: &[f64; N], m: &mut [[f64; N]; N], f: &mut [f64; N]) {
    let qa: [Arr; N] = std::array::from_fn(|i| {
        let mut a = Arr::constant(q[i]);
        a.e2[i] = 1.0;
        a
    });
    let qda: [Arr; N] = std::array::from_fn(|i| {
        let mut a = Arr::constant(qd[i]);
        a.e1[i] = 1.0;
        a.e2[N + i] = 1.0;
        a
    });
    let l = arr_lagrangian(s, &qa, &qda);
    for i in 0..N {
        let mut qi = l.e2[i] - l.e12[i][2 * N];
        for j in 0..N {
            m[i][j] = l.e12[i][N + j];
            qi -= l.e12[i][j] * qd[j];
        }
        f[i] = qi;
    }
}

fn run() -> Result<(), String> {
    let (batches, batch_ms) = batch_args("ad-passes [--batches N] [--batch-ms MS]")?;
    let s = nonholo_bench::setup::generic_sleigh().map_err(|e| e.to_string())?;
    let (t, q, qd) = (0.3, [0.4, -0.2, 0.7], [1.3, 0.6, -0.4]);
    let field = Lagrangian(&s);
    let mut jet = Jet::<f64>::new(N, 1);
    let mut mass = DMatrix::<f64>::zeros(N, N);
    let mut force = vec![0.0; N];
    let (mut m1, mut f1) = ([[0.0; N]; N], [0.0; N]);
    jet.mass_and_force(&field, t, &q, &qd, &[], &mut mass.as_view_mut(), &mut force);
    one_pass(&s, t, &q, &qd, &mut m1, &mut f1);
    let (mut m2, mut f2) = ([[0.0; N]; N], [0.0; N]);
    arrays(&s, &q, &qd, &mut m2, &mut f2);
    let (mass_ref, force_ref) = (&mass, &force);
    let disagreement = |m: &[[f64; N]; N], f: &[f64; N]| {
        (0..N)
            .flat_map(|i| {
                let row = (0..N).map(move |j| (mass_ref[(i, j)], m[i][j]));
                std::iter::once((force_ref[i], f[i])).chain(row)
            })
            .map(|(a, b)| (a - b).abs() / (1.0 + a.abs()))
            .fold(0.0f64, f64::max)
    };
    let worst = disagreement(&m1, &f1).max(disagreement(&m2, &f2));
    if worst > 1e-13 {
        return Err(format!(
            "they disagree: {worst:e}\n{mass}\n{force:?}\n{m1:?}\n{f1:?}\n{m2:?}\n{f2:?}"
        ));
    }
    // The scalar passes, timed against each alternative in turn.
    let mut scalar = || {
        jet.mass_and_force(
            &field,
            keep(t),
            keep(&q),
            keep(&qd),
            &[],
            &mut mass.as_view_mut(),
            &mut force,
        );
        keep(&force);
    };
    let (_, vector, ratio) = paired_ns(
        &mut scalar,
        || {
            one_pass(&s, keep(t), keep(&q), keep(&qd), &mut m1, &mut f1);
            keep(&f1);
        },
        batches,
        batch_ms,
    );
    let (base, arr, ratio2) = paired_ns(
        &mut scalar,
        || {
            arrays(&s, keep(&q), keep(&qd), &mut m2, &mut f2);
            keep(&f2);
        },
        batches,
        batch_ms,
    );
    println!(
        "sleigh (n = 3, potential = com): M and Q agree to {worst:.1e}\n\
         | evaluation | ns | speed-up over the scalar passes |\n|---|---|---|\n\
         | scalar passes (Jet::mass_and_force, {} hyper-dual and {N} dual) | {base:.0} | 1 |\n\
         | one num-dual HyperDualSVec64<{N}, {N2}> pass | {vector:.0} | {:.2} |\n\
         | one plain-array vector hyper-dual pass (Lagrangian transcribed) | {arr:.0} | {:.1} |",
        N * (N + 1) / 2 + N,
        ratio,
        ratio2,
    );
    Ok(())
}

fn main() -> ExitCode {
    nonholo_bench::report_main(run)
}
