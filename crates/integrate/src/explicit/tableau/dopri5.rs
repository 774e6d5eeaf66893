//! Dormand–Prince 5(4) "DOPRI5": 7 stages, first same as last.
//!
//! Sources: J. R. Dormand & P. J. Prince, *A family of embedded Runge–Kutta
//! formulae*, J. Comput. Appl. Math. 6 (1980) 19–26; the error coefficients
//! `E = b − b̂` and the dense-output coefficients of Shampine (1986) exactly
//! as in subroutine `CDOPRI` of E. Hairer & G. Wanner's `dopri5.f` (version
//! of 2002; Hairer, Nørsett & Wanner, *Solving ODE I*, Table II.5.2 and
//! §II.6, eq. (6.12)). All numbers are rationals and are written as such.

/// Nodes `c_i` (stage 7 is `f(t + h, y_{n+1})`).
pub(crate) const C: [f64; 7] = [0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0];

/// Rows `a_i1 .. a_i,i-1`; row 7 equals `b` (FSAL).
pub(crate) const A: [&[f64]; 7] = [
    &[],
    &[1.0 / 5.0],
    &[3.0 / 40.0, 9.0 / 40.0],
    &[44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0],
    &[
        19372.0 / 6561.0,
        -25360.0 / 2187.0,
        64448.0 / 6561.0,
        -212.0 / 729.0,
    ],
    &[
        9017.0 / 3168.0,
        -355.0 / 33.0,
        46732.0 / 5247.0,
        49.0 / 176.0,
        -5103.0 / 18656.0,
    ],
    &B,
];

/// Weights `b_i` of the 5th-order solution.
pub(crate) const B: [f64; 6] = [
    35.0 / 384.0,
    0.0,
    500.0 / 1113.0,
    125.0 / 192.0,
    -2187.0 / 6784.0,
    11.0 / 84.0,
];

/// Error coefficients `e_i = b_i − b̂_i` (`b̂`: embedded 4th-order weights, 7 stages).
pub(crate) const E: [f64; 7] = [
    71.0 / 57600.0,
    0.0,
    -71.0 / 16695.0,
    71.0 / 1920.0,
    -17253.0 / 339200.0,
    22.0 / 525.0,
    -1.0 / 40.0,
];

/// Shampine's dense-output coefficients `d_i`: the fifth nested coefficient is `h Σ d_i k_i`.
pub(crate) const D: [f64; 7] = [
    -12715105075.0 / 11282082432.0,
    0.0,
    87487479700.0 / 32700410799.0,
    -10690763975.0 / 1880347072.0,
    701980252875.0 / 199316789632.0,
    -1453857185.0 / 822651844.0,
    69997945.0 / 29380423.0,
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::explicit::tableau::conditions::{
        Tableau, assert_order, assert_row_sums, hermite_weights,
    };

    #[test]
    fn rows_sum_to_nodes() {
        let worst = assert_row_sums(&C, &A);
        eprintln!("DOPRI5: largest |Σ_j a_ij − c_i| = {worst:e}");
        assert!(worst < 4e-15, "largest row-sum residual {worst:e}");
        assert!((B.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        // b̂ = b − e is a quadrature too: Σ e_i = 0.
        assert!(E.iter().sum::<f64>().abs() < 1e-16);
    }

    #[test]
    fn order_five_and_embedded_order_four() {
        let tab = Tableau::new(&C, &A);
        assert_order(&tab, &B, 5);
        assert!(tab.order_residual(&B, 6) > 1e-5, "DOPRI5 is not of order 6");
        let mut bhat = [0.0; 7];
        for i in 0..7 {
            let b = if i < 6 { B[i] } else { 0.0 };
            bhat[i] = b - E[i];
        }
        assert_order(&tab, &bhat, 4);
        assert!(tab.order_residual(&bhat, 5) > 1e-5, "b̂ is not of order 5");
    }

    #[test]
    fn dense_output_is_order_four() {
        let tab = Tableau::new(&C, &A);
        for &theta in &[0.1, 0.3, 0.5, 0.77, 1.0] {
            let bt = hermite_weights(&B, 7, 6, &[&D], theta);
            tab.assert_continuous_order(&bt, 4, theta);
        }
        // Not of order 5 inside the step (it is at θ = 1, where it is b).
        let bt = hermite_weights(&B, 7, 6, &[&D], 0.5);
        assert!(tab.residual_at_order(&bt, 5, 0.5) > 1e-6);
    }
}
