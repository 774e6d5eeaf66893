//! Test helper: Runge–Kutta order conditions from rooted trees (Butcher).
//!
//! A method with nodes `c`, matrix `A` and weights `b` has order `p` iff
//! `Σ_i b_i Φ_i(τ) = 1/γ(τ)` for every rooted tree `τ` with at most `p`
//! nodes, where `Φ(•) = 1` and `Φ(τ) = Π_{children u} (A Φ(u))`
//! (componentwise), `γ(•) = 1` and `γ(τ) = |τ| Π γ(u)` (Hairer, Nørsett &
//! Wanner, *Solving ODE I*, §II.2, Thm. 2.13). A continuous extension with
//! weights `b(θ)` has order `p*` iff `Σ_i b_i(θ) Φ_i(τ) = θ^|τ|/γ(τ)` for
//! `|τ| ≤ p*` (§II.6, Thm. 6.1).
//!
//! Residuals are compared with `64 ε · S(τ)`, where `S(τ)` is the same sum
//! taken with absolute values of all coefficients: the only error left in
//! a correct tableau is the rounding of its coefficients to binary and of
//! the sums themselves, which is bounded by a small multiple of `ε S(τ)`.

use crate::dense::eval_nested;

/// A rooted tree: number of nodes, children (indices into the tree list), `γ`.
struct Tree {
    order: usize,
    children: Vec<usize>,
    gamma: f64,
}

/// All rooted trees with at most `max_order` nodes, children before parents.
fn trees(max_order: usize) -> Vec<Tree> {
    fn multisets(
        list: &[Tree],
        remaining: usize,
        min: usize,
        stack: &mut Vec<usize>,
        out: &mut Vec<Vec<usize>>,
    ) {
        if remaining == 0 {
            out.push(stack.clone());
            return;
        }
        for i in min..list.len() {
            if list[i].order <= remaining {
                stack.push(i);
                multisets(list, remaining - list[i].order, i, stack, out);
                stack.pop();
            }
        }
    }
    let mut list = vec![Tree {
        order: 1,
        children: Vec::new(),
        gamma: 1.0,
    }];
    for n in 2..=max_order {
        let mut sets = Vec::new();
        multisets(&list, n - 1, 0, &mut Vec::new(), &mut sets);
        for children in sets {
            let gamma = n as f64 * children.iter().map(|&u| list[u].gamma).product::<f64>();
            list.push(Tree {
                order: n,
                children,
                gamma,
            });
        }
    }
    list
}

/// The matrix `A` of an explicit tableau, stored densely (the nodes enter
/// the order conditions only through `c = A·1`, checked separately).
pub(crate) struct Tableau {
    s: usize,
    a: Vec<Vec<f64>>,
}

impl Tableau {
    /// `rows[i]` holds `a_i0 .. a_i,len-1` (missing entries are zero).
    pub(crate) fn new(c: &[f64], rows: &[&[f64]]) -> Self {
        let s = c.len();
        assert_eq!(rows.len(), s);
        let a = rows
            .iter()
            .map(|r| {
                let mut full = vec![0.0; s];
                full[..r.len()].copy_from_slice(r);
                full
            })
            .collect();
        Tableau { s, a }
    }

    /// `Φ(τ)` and its absolute-value counterpart for every tree up to `p` nodes.
    fn weights(&self, p: usize) -> (Vec<Tree>, Vec<Vec<f64>>, Vec<Vec<f64>>) {
        let list = trees(p);
        let mut phi: Vec<Vec<f64>> = Vec::with_capacity(list.len());
        let mut phi_abs: Vec<Vec<f64>> = Vec::with_capacity(list.len());
        for tree in &list {
            let mut v = vec![1.0; self.s];
            let mut va = vec![1.0; self.s];
            for &u in &tree.children {
                for i in 0..self.s {
                    let (mut x, mut xa) = (0.0, 0.0);
                    for j in 0..self.s {
                        x += self.a[i][j] * phi[u][j];
                        xa += self.a[i][j].abs() * phi_abs[u][j];
                    }
                    v[i] *= x;
                    va[i] *= xa;
                }
            }
            phi.push(v);
            phi_abs.push(va);
        }
        (list, phi, phi_abs)
    }

    /// Largest `|Σ b_i Φ_i(τ) − θ^|τ|/γ(τ)|` over trees with exactly `p` nodes.
    pub(crate) fn residual_at_order(&self, b: &[f64], p: usize, theta: f64) -> f64 {
        let (list, phi, _) = self.weights(p);
        list.iter()
            .zip(&phi)
            .filter(|(t, _)| t.order == p)
            .map(|(t, v)| {
                let got: f64 = b.iter().zip(v).map(|(bi, vi)| bi * vi).sum();
                (got - theta.powi(t.order as i32) / t.gamma).abs()
            })
            .fold(0.0, f64::max)
    }

    /// Largest residual over trees of exactly `p` nodes for the quadrature at `θ = 1`.
    pub(crate) fn order_residual(&self, b: &[f64], p: usize) -> f64 {
        self.residual_at_order(b, p, 1.0)
    }

    /// Asserts `Σ b_i(θ) Φ_i(τ) = θ^|τ|/γ(τ)` for all trees with at most `p` nodes.
    pub(crate) fn assert_continuous_order(&self, b: &[f64], p: usize, theta: f64) {
        assert_eq!(b.len(), self.s);
        let (list, phi, phi_abs) = self.weights(p);
        let mut worst: f64 = 0.0;
        for ((tree, v), va) in list.iter().zip(&phi).zip(&phi_abs) {
            let got: f64 = b.iter().zip(v).map(|(bi, vi)| bi * vi).sum();
            let scale: f64 = b.iter().zip(va).map(|(bi, vi)| bi.abs() * vi).sum();
            let want = theta.powi(tree.order as i32) / tree.gamma;
            let res = (got - want).abs();
            worst = worst.max(res / (scale + want.abs()));
            assert!(
                res <= 64.0 * f64::EPSILON * (scale + want.abs()),
                "order condition of a tree with {} nodes (γ = {}) fails at θ = {theta}: \
                 {got:e} vs {want:e} (residual {res:e}, scale {scale:e})",
                tree.order,
                tree.gamma
            );
        }
        // Relative residuals stay at the rounding level.
        assert!(worst < 64.0 * f64::EPSILON);
    }

    /// Number of stages.
    pub(crate) fn stages(&self) -> usize {
        self.s
    }
}

/// Asserts the order conditions of the weights `b` up to order `p`.
pub(crate) fn assert_order(tab: &Tableau, b: &[f64], p: usize) {
    let mut full = vec![0.0; tab.stages()];
    full[..b.len()].copy_from_slice(b);
    tab.assert_continuous_order(&full, p, 1.0);
}

/// Asserts `Σ_j a_ij = c_i` for each row, to the rounding level `4 ε Σ_j |a_ij|`.
/// Returns the largest residual (for reporting).
pub(crate) fn assert_row_sums(c: &[f64], rows: &[&[f64]]) -> f64 {
    let mut worst: f64 = 0.0;
    for (i, (ci, row)) in c.iter().zip(rows).enumerate() {
        let sum: f64 = row.iter().sum();
        let abs: f64 = row.iter().map(|a| a.abs()).sum();
        let res = (sum - ci).abs();
        worst = worst.max(res);
        assert!(
            res <= 4.0 * f64::EPSILON * abs.max(1.0),
            "row {} sums to {sum} instead of c = {ci} (residual {res:e})",
            i + 1
        );
    }
    worst
}

/// Weights `b_i(θ)` of a continuous extension in the nested form of
/// [`crate::Dense`], on a tableau whose stage `fsal` is `f(t + h, y_{n+1})`:
/// the coefficients are `c2 = h Σ b k`, `c3 = h k_1 − c2`,
/// `c4 = c2 − h k_fsal − c3`, then `h Σ d_r k` for each row of `d`.
pub(crate) fn hermite_weights(
    b: &[f64],
    s: usize,
    fsal: usize,
    d: &[&[f64]],
    theta: f64,
) -> Vec<f64> {
    let ncoef = 4 + d.len();
    let mut coef = vec![0.0; ncoef * s];
    for j in 0..b.len() {
        coef[s + j] = b[j];
        coef[2 * s + j] = -b[j];
        coef[3 * s + j] = 2.0 * b[j];
    }
    coef[2 * s] += 1.0;
    coef[3 * s] -= 1.0;
    coef[3 * s + fsal] -= 1.0;
    for (r, row) in d.iter().enumerate() {
        coef[(4 + r) * s..(4 + r) * s + row.len()].copy_from_slice(row);
    }
    let mut out = vec![0.0; s];
    eval_nested(&coef, s, ncoef, theta, &mut out);
    out
}

#[test]
fn tree_counts_are_cayley_numbers() {
    // Number of rooted trees with n nodes: OEIS A000081.
    let list = trees(8);
    let counts: Vec<usize> = (1..=8)
        .map(|n| list.iter().filter(|t| t.order == n).count())
        .collect();
    assert_eq!(counts, [1, 1, 2, 4, 9, 20, 48, 115]);
}
