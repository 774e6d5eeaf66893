//! Quadrature rules.

/// Nodes and weights of the `n`-point Gauss–Legendre rule on `[−1, 1]`
/// (Newton on the Legendre polynomial from Tricomi's estimate of each root).
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let (mut nodes, mut weights) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 1..=n {
        let mut x = (std::f64::consts::PI * (i as f64 - 0.25) / (n as f64 + 0.5)).cos();
        let mut dp = 0.0;
        for _ in 0..100 {
            // P_n(x) and P_n'(x) by the three-term recurrence.
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let k = k as f64;
                (p0, p1) = (p1, ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k);
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let step = p1 / dp;
            x -= step;
            if step.abs() < 1e-16 {
                break;
            }
        }
        nodes.push(x);
        weights.push(2.0 / ((1.0 - x * x) * dp * dp));
    }
    (nodes, weights)
}

#[cfg(test)]
mod tests {
    /// The rule integrates polynomials up to degree 2n − 1 exactly and
    /// its weights sum to 2.
    #[test]
    fn gauss_legendre_is_exact_to_degree_2n_minus_1() {
        let (x, w) = super::gauss_legendre(20);
        assert!((w.iter().sum::<f64>() - 2.0).abs() < 1e-14);
        for degree in [2, 10, 38] {
            let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(degree)).sum();
            let exact = 2.0 / (degree as f64 + 1.0);
            assert!((q - exact).abs() < 1e-14, "degree {degree}: {q} vs {exact}");
        }
        let odd: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(39)).sum();
        assert!(odd.abs() < 1e-14);
    }
}
