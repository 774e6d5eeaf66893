//! The paper's general case (eq. 27–30) on Appell–Hamel (`z` dependent) and
//! the vertical rolling disk (`x, y` dependent): which motions it produces
//! with the dependent end values free (the paper's wording) or fixed, how
//! they depend on the horizon `t1`, and the eliminated form of the recipe
//! (docs/variational.md).

mod common;

use common::*;
use nonholo_core::Scene;
use nonholo_scenes::{AppellHamel, RollingDisk};
use nonholo_variational::*;

fn general(dependent: &[usize], end: DependentEnd) -> Formulation {
    Formulation::General {
        dependent: dependent.to_vec(),
        end,
    }
}

/// The general case solved on `[0, t1]` with ends from a reference path
/// (`fine + 1` nodes): the extrapolated BVP path, and its largest
/// difference from the reference at the coarse nodes.
fn solve_against<S: Scene>(
    s: &S,
    f: &Formulation,
    t1: f64,
    q: &[f64],
    qd: &[f64],
    base: usize,
) -> (Refinement, f64) {
    let n = s.info().n();
    let fine = q.len() / n - 1;
    let r = refine(
        s,
        f,
        (0.0, t1),
        base,
        &ends_of(q, qd, n),
        None,
        &Options::default(),
    )
    .unwrap();
    let coarse: Vec<f64> = q
        .chunks(n)
        .step_by(fine / base)
        .flatten()
        .copied()
        .collect();
    let d = max_diff(&r.extrapolated, &coarse);
    (r, d)
}

/// Appell–Hamel: the paper's recipe with `z(t1)` free gives B's motion
/// (which is also every vakonomic motion, docs/formulations.md) for every
/// horizon: the midpoint scheme is exact on it (a straight line at uniform
/// acceleration), so the BVP path equals B's to round-off.
#[test]
fn appell_hamel_general_case_gives_b_for_every_horizon() {
    let s: AppellHamel = scene(&[]);
    let q0 = [0.0, 0.0, 0.0];
    let qd0 = [1.0, 0.5, -0.5 * 1.25f64.sqrt()];
    for t1 in [0.5, 1.0, 2.0] {
        let (q, qd) = reference(chetaev(s.clone()), &q0, &qd0, &[], &grid(t1, 400));
        let (r, d) = solve_against(&s, &general(&[2], DependentEnd::Free), t1, &q, &qd, 100);
        assert!(d < 1e-12, "t1 {t1}: {d:e}");
        assert!(r.differences[1] < 1e-12, "{:?}", r.differences);
    }
}

/// The rolling disk with `x, y` dependent: with their end values free the
/// recipe adds the natural conditions `p_x + λ₁ = p_y + λ₂ = 0` at `t1`,
/// which make `λ = −m v` for all time, and the motion is B's (uniform
/// turning and rolling) through the given `θ, ψ` ends. With them fixed it
/// is C's boundary-value problem and reproduces C's motion.
#[test]
fn disk_general_case_free_end_gives_b_and_fixed_end_gives_c() {
    let s: RollingDisk = scene(&[]);
    let (th, wth, wpsi) = (0.4f64, 0.5, 1.0);
    let q0 = [0.0, 0.0, th, 0.0];
    let qd0 = [s.r * wpsi * th.cos(), s.r * wpsi * th.sin(), wth, wpsi];
    let t1 = 1.0;
    // Ends from B: both end conditions reproduce B.
    let (qb, qdb) = reference(chetaev(s.clone()), &q0, &qd0, &[], &grid(t1, 400));
    for end in [DependentEnd::Free, DependentEnd::Fixed] {
        let (r, d) = solve_against(&s, &general(&[0, 1], end), t1, &qb, &qdb, 100);
        assert!(d < 1e-9, "{end:?}: {d:e}");
        assert!(
            (r.order - 2.0).abs() < 0.2 || r.differences[1] < 1e-12,
            "{end:?}: {}",
            r.order
        );
    }
    // Ends from a vakonomic motion that is not B's (λ0 = (0, 0.3)).
    let (qc, qdc) = reference(vakonomic(s.clone()), &q0, &qd0, &[0.0, 0.3], &grid(t1, 400));
    let (r, d) = solve_against(
        &s,
        &general(&[0, 1], DependentEnd::Fixed),
        t1,
        &qc,
        &qdc,
        100,
    );
    assert!(d < 1e-9, "fixed: {d:e}");
    assert!((r.order - 2.0).abs() < 0.2, "fixed: {}", r.order);
    let (r, d) = solve_against(
        &s,
        &general(&[0, 1], DependentEnd::Free),
        t1,
        &qc,
        &qdc,
        100,
    );
    assert!(d > 1e-2, "free: {d:e}");
    // θ and ψ are linear in time between their ends (B's uniform rates).
    let n = 4;
    let last = r.t().len() - 1;
    for k in 0..=last {
        let w = k as f64 / last as f64;
        for i in [2, 3] {
            let line = qc[i] + w * (qc[400 * n + i] - qc[i]);
            assert!(
                (r.extrapolated[k * n + i] - line).abs() < 1e-11,
                "k {k} i {i}"
            );
        }
    }
}

/// Causality: the same start, ends from C's motion at `t1 = 0.5` and `1`.
/// With the dependent end fixed the two solutions agree on `[0, 0.5]` (both
/// are C's motion); with it free they differ by centimetres: the motion the
/// paper's recipe gives on `[0, 0.5]` depends on where the horizon ends.
#[test]
fn disk_free_end_motion_depends_on_the_horizon() {
    let s: RollingDisk = scene(&[]);
    let (th, wth, wpsi) = (0.4f64, 0.5, 1.0);
    let q0 = [0.0, 0.0, th, 0.0];
    let qd0 = [s.r * wpsi * th.cos(), s.r * wpsi * th.sin(), wth, wpsi];
    let n = 4;
    let mut spread = Vec::new();
    for end in [DependentEnd::Fixed, DependentEnd::Free] {
        let mut on_common = Vec::new();
        for (t1, base) in [(0.5, 50), (1.0, 100)] {
            let (qc, qdc) = reference(
                vakonomic(s.clone()),
                &q0,
                &qd0,
                &[0.0, 0.3],
                &grid(t1, 4 * base),
            );
            let (r, _) = solve_against(&s, &general(&[0, 1], end), t1, &qc, &qdc, base);
            on_common.push(r.extrapolated[..51 * n].to_vec());
        }
        spread.push(max_diff(&on_common[0], &on_common[1]));
    }
    assert!(spread[0] < 1e-9, "fixed: {spread:?}");
    assert!(spread[1] > 1e-3, "free: {spread:?}");
}

/// The recipe done literally: the dependent coordinates eliminated by
/// integrating (28), the action a function of `q_I` alone. Its gradient
/// vanishes at the multiplier form's solutions (to 1e-9 of its size on a
/// perturbed path), for both end conditions and both scenes.
#[test]
fn eliminated_form_is_stationary_at_the_solutions() {
    let disk: RollingDisk = scene(&[]);
    let (th, wth, wpsi) = (0.4f64, 0.5, 1.0);
    let q0 = [0.0, 0.0, th, 0.0];
    let qd0 = [
        disk.r * wpsi * th.cos(),
        disk.r * wpsi * th.sin(),
        wth,
        wpsi,
    ];
    let (qc, qdc) = reference(
        vakonomic(disk.clone()),
        &q0,
        &qd0,
        &[0.0, 0.3],
        &grid(1.0, 40),
    );
    check_eliminated(&disk, &[0, 1], &qc, &qdc);
    let ah: AppellHamel = scene(&[]);
    let qd0 = [1.0, 0.5, -0.5 * 1.25f64.sqrt()];
    let (qb, qdb) = reference(chetaev(ah.clone()), &[0.0; 3], &qd0, &[], &grid(1.0, 40));
    let ends = ends_of(&qb, &qdb, 3);
    let p = Problem::new(&ah, general(&[2], DependentEnd::Free), 0.0, 1.0, 40, ends).unwrap();
    let o = Options::default();
    let sol = Solver::new(&p, &o)
        .unwrap()
        .solve(&p.start_line(), &o)
        .unwrap();
    let g = reduced_gradient(&p, &sol.q).unwrap();
    assert!(g.iter().all(|v| v.abs() < 1e-9), "{g:?}");
}

fn check_eliminated<S: Scene>(s: &S, dep: &[usize], q: &[f64], qd: &[f64]) {
    let n = s.info().n();
    for end in [DependentEnd::Free, DependentEnd::Fixed] {
        let p = Problem::new(s, general(dep, end), 0.0, 1.0, 40, ends_of(q, qd, n)).unwrap();
        let o = Options::default();
        let sol = Solver::new(&p, &o)
            .unwrap()
            .solve(&p.start_line(), &o)
            .unwrap();
        let g = reduced_gradient(&p, &sol.q).unwrap();
        let mut off = sol.q.clone();
        off[20 * n + p.independent()[0]] += 1e-3;
        let g_off = reduced_gradient(&p, &off).unwrap();
        let size = g_off.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let at = g.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        assert!(
            size > 0.1 && at < 1e-9 * size,
            "{end:?}: {at:e} against {size:e}"
        );
    }
}

/// The disk's map (the heading; the rolling angle `ψ` cyclic, its end value
/// free): A's boundary-value problem reproduces the vakonomic motion whose
/// rolling momentum `P_ψ = J_r ψ̇ − R(λ₁ cos θ + λ₂ sin θ)` vanishes
/// (docs/embedding.md §7) — `ψ` included — at order 2, with the map
/// explicit or implicit, over a span with an instant of zero speed (the
/// disk reverses its rolling at t ≈ 1.2 s) for the implicit form.
#[test]
fn disk_map_reproduces_the_vakonomic_motion_with_zero_rolling_momentum() {
    let s: RollingDisk = scene(&[]);
    let (th, wth, wpsi) = (0.4f64, 0.5, 1.0);
    let q0 = [0.0, 0.0, th, 0.0];
    let qd0 = [s.r * wpsi * th.cos(), s.r * wpsi * th.sin(), wth, wpsi];
    let l2 = 0.3;
    let l1 = (s.jr * wpsi / s.r - l2 * th.sin()) / th.cos();
    let n = 4;
    for (t1, form, base) in [
        (1.0, MapForm::Explicit, 200),
        (1.0, MapForm::Implicit, 200),
        (2.0, MapForm::Implicit, 400),
    ] {
        let (q, qd) = reference(
            vakonomic(s.clone()),
            &q0,
            &qd0,
            &[l1, l2],
            &grid(t1, 4 * base),
        );
        let speed: Vec<f64> = qd.chunks(n).map(|v| v[3]).collect();
        let reverses = speed.windows(2).any(|w| w[0] * w[1] < 0.0);
        assert_eq!(reverses, t1 > 1.5, "{t1}: ψ̇ {:?}", speed.last());
        let f = Formulation::Map {
            ends: MapEnds::Configuration,
            form,
        };
        // Started on C's motion (from the straight line Newton does not
        // find its way through the reversal).
        let coarse: Vec<f64> = q.chunks(n).step_by(4).flatten().copied().collect();
        let o = Options::default();
        let ends = ends_of(&q, &qd, n);
        let r = refine(&s, &f, (0.0, t1), base, &ends, Some(&coarse), &o).unwrap();
        let d = max_diff(&r.extrapolated, &coarse);
        assert!(
            (r.order - 2.0).abs() < 0.2,
            "{form:?} {t1}: order {}",
            r.order
        );
        assert!(d < 1e-8, "{form:?} {t1}: {d:e}");
    }
}

/// Appell–Hamel with the dependent end fixed (and C's fixed-end problem):
/// every vakonomic motion from a state is B's (docs/formulations.md), so
/// B's motion is stationary with the multipliers `λ(t) = λ0 − m g t/(1 + c²)`
/// for every `λ0` — the Newton matrix is singular there, and Newton's
/// method from the straight line fails on most grids (the experiment
/// bvp-general). With the end free, the natural condition at `t1` fixes
/// `λ0`: only one of them is stationary.
#[test]
fn appell_hamel_fixed_end_leaves_the_multiplier_undetermined() {
    let s: AppellHamel = scene(&[]);
    let (m, g, c) = (1.0, 9.81, 0.5);
    let qd0 = [1.0, 0.5, -0.5 * 1.25f64.sqrt()];
    let (t1, nint) = (1.0, 40);
    let (q, qd) = reference(chetaev(s.clone()), &[0.0; 3], &qd0, &[], &grid(t1, nint));
    let h = t1 / nint as f64;
    let o = Options::default();
    for (end, stationary) in [
        (DependentEnd::Fixed, [true, true, true]),
        (DependentEnd::Free, [false, true, false]),
    ] {
        let p = Problem::new(&s, general(&[2], end), 0.0, t1, nint, ends_of(&q, &qd, 3)).unwrap();
        let mut solver = Solver::new(&p, &o).unwrap();
        // The free end's λ0: m ż(t1) + λ(t1) = 0.
        let lambda_free = -m * qd[nint * 3 + 2] + m * g * t1 / (1.0 + c * c);
        for (l0, expect) in [-2.0, lambda_free, 3.0].into_iter().zip(stationary) {
            let mu: Vec<f64> = (0..nint)
                .map(|k| h * (l0 - m * g * (k as f64 + 0.5) * h / (1.0 + c * c)))
                .collect();
            let r = solver.residual_at(&q, &mu).unwrap();
            assert_eq!(r < 1e-9, expect, "{end:?}, λ0 = {l0}: residual {r:e}");
        }
    }
}
