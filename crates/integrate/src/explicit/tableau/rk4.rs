//! Classical Runge–Kutta method of order 4 (Kutta 1901).
//!
//! Source: W. Kutta, *Beitrag zur näherungsweisen Integration totaler
//! Differentialgleichungen*, Z. Math. Phys. 46 (1901); tabulated in Hairer,
//! Nørsett & Wanner, *Solving ODE I*, 2nd ed., Table II.1.2 (left).

/// Nodes `c_i`.
pub(crate) const C: [f64; 4] = [0.0, 0.5, 0.5, 1.0];

/// Rows `a_i1 .. a_i,i-1` of the strictly lower triangular matrix.
pub(crate) const A: [&[f64]; 4] = [&[], &[0.5], &[0.0, 0.5], &[0.0, 0.0, 1.0]];

/// Weights `b_i`.
pub(crate) const B: [f64; 4] = [1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::explicit::tableau::conditions::{
        Tableau, assert_order, assert_row_sums, hermite_weights,
    };

    #[test]
    fn rows_sum_to_nodes() {
        assert_row_sums(&C, &A);
        assert!((B.iter().sum::<f64>() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn order_four() {
        let tab = Tableau::new(&C, &A);
        assert_order(&tab, &B, 4);
        assert!(tab.order_residual(&B, 5) > 1e-3, "RK4 is not of order 5");
    }

    #[test]
    fn hermite_extension_is_order_three() {
        // Extended tableau: stage 5 is f(t + h, y_{n+1}) with a_5j = b_j.
        let c = [0.0, 0.5, 0.5, 1.0, 1.0];
        let a: [&[f64]; 5] = [A[0], A[1], A[2], A[3], &B];
        let tab = Tableau::new(&c, &a);
        for &theta in &[0.1, 0.37, 0.5, 0.81, 1.0] {
            let bt = hermite_weights(&B, 5, 4, &[], theta);
            tab.assert_continuous_order(&bt, 3, theta);
        }
    }
}
