//! Coefficients of the three-stage Radau IIA method (order 5) and of its
//! implementation in the manner of RADAU5.
//!
//! Sources: the Butcher tableau is Table IV.5.6 of E. Hairer & G. Wanner,
//! *Solving Ordinary Differential Equations II*, 2nd ed., Springer 1996;
//! the eigenvalues of `A⁻¹`, the transformation `T`, `T⁻¹` (given there to
//! 20 digits) and the error-estimate weights `dd` are those of subroutine
//! `RADCOR` in Hairer's `radau5.f` (version of July 9, 1996, latest
//! correction January 18, 2002; §IV.8 of the book, eqs. (8.16)–(8.20)).
//! The unit tests check them against the definitions rather than trusting
//! the digits.
#![allow(clippy::excessive_precision)] // the published digits are kept as printed

/// The constants of the method, computed once per run (square and cube
/// roots are not `const`).
#[derive(Debug, Clone)]
pub(super) struct Tableau {
    /// Nodes `c = ((4 − √6)/10, (4 + √6)/10, 1)`.
    pub c: [f64; 3],
    /// Real eigenvalue `γ` of `A⁻¹` (RADAU5's `U1` after inversion).
    pub gamma: f64,
    /// Real part `α` of the complex eigenvalues `α ± iβ` of `A⁻¹`.
    pub alpha: f64,
    /// Imaginary part `β` (positive).
    pub beta: f64,
    /// `T` with `T⁻¹ A⁻¹ T = [[γ, 0, 0], [0, α, −β], [0, β, α]]`.
    pub t: [[f64; 3]; 3],
    /// `T⁻¹`.
    pub ti: [[f64; 3]; 3],
    /// Error-estimate weights: `y'_n + h⁻¹ Σ dd_i Z_i` is `O(h³)`.
    pub dd: [f64; 3],
    /// `A⁻¹ = T Λ T⁻¹` (full Newton iteration: `Y'_k = h⁻¹ Σ_j (A⁻¹)_kj Z_j`).
    pub ainv: [[f64; 3]; 3],
}

impl Tableau {
    pub fn new() -> Self {
        let sq6 = 6f64.sqrt();
        let cbrt81 = 81f64.cbrt();
        let cbrt9 = 9f64.cbrt();
        // Eigenvalues of A: u1 (real), alph ± i beta; those of A⁻¹ are their
        // inverses.
        let u1 = (6.0 + cbrt81 - cbrt9) / 30.0;
        let alph = (12.0 - cbrt81 + cbrt9) / 60.0;
        let beta = (cbrt81 + cbrt9) * 3f64.sqrt() / 60.0;
        let cno = alph * alph + beta * beta;
        let mut tab = Tableau {
            c: [(4.0 - sq6) / 10.0, (4.0 + sq6) / 10.0, 1.0],
            gamma: 1.0 / u1,
            alpha: alph / cno,
            beta: beta / cno,
            t: [
                [
                    9.123_239_487_089_294_279_2e-2,
                    -0.141_255_295_020_954_208_43,
                    -3.002_919_410_514_742_449_2e-2,
                ],
                [
                    0.241_717_932_707_107_018_96,
                    0.204_129_352_293_799_931_99,
                    0.382_942_112_757_261_937_79,
                ],
                [0.966_048_182_615_092_936_19, 1.0, 0.0],
            ],
            ti: [
                [
                    4.325_579_890_063_155_351_0,
                    0.339_199_251_815_809_869_54,
                    0.541_770_539_935_874_871_19,
                ],
                [
                    -4.178_718_591_551_904_727_3,
                    -0.327_682_820_761_062_387_08,
                    0.476_623_554_500_550_451_96,
                ],
                [
                    -0.502_872_634_945_786_875_95,
                    2.571_926_949_855_605_429_2,
                    -0.596_039_204_828_224_924_97,
                ],
            ],
            dd: [
                -(13.0 + 7.0 * sq6) / 3.0,
                (-13.0 + 7.0 * sq6) / 3.0,
                -1.0 / 3.0,
            ],
            ainv: [[0.0; 3]; 3],
        };
        // A⁻¹ = T Λ T⁻¹ with Λ = [[γ, 0, 0], [0, α, −β], [0, β, α]], from
        // the same digits as the simplified iteration, which forms
        // Y' = h⁻¹ (T Λ W) with W = T⁻¹ Z.
        let (g, a, b) = (tab.gamma, tab.alpha, tab.beta);
        let lam = [[g, 0.0, 0.0], [0.0, a, -b], [0.0, b, a]];
        for i in 0..3 {
            for j in 0..3 {
                tab.ainv[i][j] = (0..3)
                    .map(|k| {
                        let tl: f64 = (0..3).map(|m| tab.t[i][m] * lam[m][k]).sum();
                        tl * tab.ti[k][j]
                    })
                    .sum();
            }
        }
        tab
    }

    /// The Butcher matrix `A` (weights `b` = last row: stiffly accurate).
    #[cfg(test)]
    pub fn a() -> [[f64; 3]; 3] {
        let s = 6f64.sqrt();
        [
            [
                (88.0 - 7.0 * s) / 360.0,
                (296.0 - 169.0 * s) / 1800.0,
                (-2.0 + 3.0 * s) / 225.0,
            ],
            [
                (296.0 + 169.0 * s) / 1800.0,
                (88.0 + 7.0 * s) / 360.0,
                (-2.0 - 3.0 * s) / 225.0,
            ],
            [(16.0 - s) / 36.0, (16.0 + s) / 36.0, 1.0 / 9.0],
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type M3 = [[f64; 3]; 3];

    fn mul(a: &M3, b: &M3) -> M3 {
        let mut c = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                c[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
            }
        }
        c
    }

    /// Inverse by the adjugate (A is well conditioned: ‖A‖‖A⁻¹‖ ≈ 20).
    fn inv(a: &M3) -> M3 {
        let cof = |i: usize, j: usize| {
            let (r0, r1) = ((i + 1) % 3, (i + 2) % 3);
            let (c0, c1) = ((j + 1) % 3, (j + 2) % 3);
            a[r0][c0] * a[r1][c1] - a[r0][c1] * a[r1][c0]
        };
        let det: f64 = (0..3).map(|j| a[0][j] * cof(0, j)).sum();
        let mut r = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                r[j][i] = cof(i, j) / det;
            }
        }
        r
    }

    fn max_dev(a: &M3, b: &M3) -> f64 {
        let mut m: f64 = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                m = m.max((a[i][j] - b[i][j]).abs());
            }
        }
        m
    }

    #[test]
    fn collocation_conditions_and_stiff_accuracy() {
        // C(3): Σ_j a_ij c_j^(k−1) = c_i^k / k for k = 1, 2, 3.
        let tab = Tableau::new();
        let a = Tableau::a();
        for i in 0..3 {
            for k in 1..=3 {
                let lhs: f64 = (0..3).map(|j| a[i][j] * tab.c[j].powi(k - 1)).sum();
                let rhs = tab.c[i].powi(k) / f64::from(k);
                assert!((lhs - rhs).abs() < 1e-15, "C({k}) row {i}: {lhs} vs {rhs}");
            }
        }
        // b = last row of A: B(5), Σ b_j c_j^(k−1) = 1/k for k = 1..5 (order 5).
        for k in 1..=5 {
            let s: f64 = (0..3).map(|j| a[2][j] * tab.c[j].powi(k - 1)).sum();
            assert!((s - 1.0 / f64::from(k)).abs() < 1e-15, "B({k}): {s}");
        }
        // ... and not B(6): the order is exactly 5.
        let s6: f64 = (0..3).map(|j| a[2][j] * tab.c[j].powi(5)).sum();
        assert!((s6 - 1.0 / 6.0).abs() > 1e-4);
    }

    #[test]
    fn transformation_block_diagonalises_a_inverse() {
        let tab = Tableau::new();
        let ainv = inv(&Tableau::a());
        let ti_t = mul(&tab.ti, &tab.t);
        let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(max_dev(&ti_t, &id) < 1e-14, "T⁻¹T = {ti_t:?}");
        let lambda = mul(&tab.ti, &mul(&ainv, &tab.t));
        let want = [
            [tab.gamma, 0.0, 0.0],
            [0.0, tab.alpha, -tab.beta],
            [0.0, tab.beta, tab.alpha],
        ];
        let dev = max_dev(&lambda, &want);
        assert!(dev < 2e-14, "T⁻¹A⁻¹T = {lambda:?}, deviation {dev:e}");
        // Known values (HW §IV.8): γ ≈ 3.6378, α ≈ 2.6811, β ≈ 3.0504.
        assert!((tab.gamma - 3.637_834_252_744_496).abs() < 1e-14);
        assert!((tab.alpha - 2.681_082_873_627_752).abs() < 1e-14);
        assert!((tab.beta - 3.050_430_199_247_410_5).abs() < 1e-14);
        // The eigenvalues: det(A⁻¹ − γI) = 0, trace = γ + 2α.
        let tr = ainv[0][0] + ainv[1][1] + ainv[2][2];
        assert!((tr - (tab.gamma + 2.0 * tab.alpha)).abs() < 1e-13);
        // The stored A⁻¹ (full Newton) is A's inverse.
        let dev = max_dev(&tab.ainv, &ainv);
        assert!(dev < 1e-13, "A⁻¹ = {:?}, deviation {dev:e}", tab.ainv);
    }

    #[test]
    fn error_weights_annihilate_cubics() {
        // y'(0) + h⁻¹ Σ dd_i (y(c_i h) − y(0)) vanishes for y = t^k, k ≤ 3:
        // Σ dd_i c_i = −1 and Σ dd_i c_i^k = 0 for k = 2, 3; not for k = 4,
        // so the estimate is O(h³)·h⁻¹·h⁴ ... = O(h⁴) after the factor h/γ.
        let tab = Tableau::new();
        let m = |k: i32| (0..3).map(|i| tab.dd[i] * tab.c[i].powi(k)).sum::<f64>();
        assert!((m(1) + 1.0).abs() < 1e-14, "{}", m(1));
        assert!(
            m(2).abs() < 1e-14 && m(3).abs() < 1e-14,
            "{} {}",
            m(2),
            m(3)
        );
        assert!(m(4).abs() > 1e-3);
    }
}
