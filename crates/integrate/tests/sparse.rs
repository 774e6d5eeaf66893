//! Radau IIA with sparse Jacobians (`ImplicitSystem::sparsity`): the
//! iteration matrices stored sparse and factored by faer, against the same
//! system with dense Jacobians. Both runs take the same steps (the two LU
//! factorisations differ only in rounding), so they agree to a small
//! multiple of the rounding error, and no counter differs.

use nonholo_integrate::{
    Failure, ImplicitSystem, IntegrateError, Options, Radau5Options, RadauNewton, Sparsity,
    SystemError, solve_implicit,
};

/// A stiff reaction–diffusion chain of `m` cells as an index-1 DAE of
/// dimension `m + 1`: `u_i' = k (u_{i−1} − 2u_i + u_{i+1}) − u_i³` with
/// `u_{−1} = sin t`, `u_m = v`, and the algebraic boundary
/// `0 = v − u_{m−1}/2 − u_0²/10` (nonlinear, so that the Jacobian changes
/// with the state in both kinds of rows).
struct Chain {
    m: usize,
    k: f64,
    sparse: bool,
}

impl Chain {
    /// `(row, column)` of every entry of `∂F/∂y`, and of `∂F/∂y'`.
    fn entries(&self) -> Sparsity {
        let m = self.m;
        let mut jy = Vec::new();
        for i in 0..m {
            if i > 0 {
                jy.push((i, i - 1));
            }
            jy.push((i, i));
            jy.push((i, i + 1));
        }
        jy.push((m, 0));
        jy.push((m, m - 1));
        jy.push((m, m));
        Sparsity {
            jy,
            jyp: (0..m).map(|i| (i, i)).collect(),
        }
    }

    /// The values at `entries()`, in its order.
    fn values(&self, y: &[f64], jy: &mut [f64], jyp: &mut [f64]) {
        let (m, k) = (self.m, self.k);
        let mut p = 0;
        for i in 0..m {
            if i > 0 {
                jy[p] = -k;
                p += 1;
            }
            jy[p] = 2.0 * k + 3.0 * y[i] * y[i];
            jy[p + 1] = -k;
            p += 2;
        }
        jy[p] = -y[0] / 5.0;
        jy[p + 1] = -0.5;
        jy[p + 2] = 1.0;
        jyp.fill(1.0);
    }
}

impl ImplicitSystem for Chain {
    fn dim(&self) -> usize {
        self.m + 1
    }

    fn residual(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        res: &mut [f64],
    ) -> Result<(), SystemError> {
        let (m, k) = (self.m, self.k);
        for i in 0..m {
            let left = if i == 0 { t.sin() } else { y[i - 1] };
            let lap = left - 2.0 * y[i] + y[i + 1];
            res[i] = yp[i] - (k * lap - y[i].powi(3));
        }
        res[m] = y[m] - y[m - 1] / 2.0 - y[0] * y[0] / 10.0;
        Ok(())
    }

    fn jacobians(
        &mut self,
        _t: f64,
        y: &[f64],
        _yp: &[f64],
        jy: &mut [f64],
        jyp: &mut [f64],
    ) -> Result<(), SystemError> {
        let sp = self.entries();
        let (mut vy, mut vyp) = (vec![0.0; sp.jy.len()], vec![0.0; sp.jyp.len()]);
        self.values(y, &mut vy, &mut vyp);
        if self.sparse {
            jy.copy_from_slice(&vy);
            jyp.copy_from_slice(&vyp);
            return Ok(());
        }
        let n = self.dim();
        jy.fill(0.0);
        jyp.fill(0.0);
        for (&(r, c), v) in sp.jy.iter().zip(&vy) {
            jy[r * n + c] = *v;
        }
        for (&(r, c), v) in sp.jyp.iter().zip(&vyp) {
            jyp[r * n + c] = *v;
        }
        Ok(())
    }

    fn sparsity(&self) -> Option<Sparsity> {
        self.sparse.then(|| self.entries())
    }
}

/// Consistent initial data: `u = 0`, `v = 0`, `u' = 0` (with `s(0) = 0`).
fn run(
    m: usize,
    sparse: bool,
    opts: &Options,
) -> Result<nonholo_integrate::Solution, Box<Failure>> {
    let mut sys = Chain {
        m,
        k: 400.0,
        sparse,
    };
    let y0 = vec![0.0; m + 1];
    let yp0 = vec![0.0; m + 1];
    solve_implicit(&mut sys, 0.0, &y0, &yp0, 3.0, opts).map_err(Box::new)
}

#[test]
fn sparse_and_dense_iteration_matrices_take_the_same_steps() {
    for m in [5, 60] {
        let opts = Options {
            rtol: 1e-8,
            atol: 1e-8,
            ..Options::default()
        };
        let dense = run(m, false, &opts).unwrap();
        let sparse = run(m, true, &opts).unwrap();
        let (a, b) = (&dense.stats, &sparse.stats);
        eprintln!(
            "m = {m}: steps {} rejected {} F {} jac {} lu {}",
            a.steps, a.rejected_steps, a.rhs_evals, a.jacobian_evals, a.lu_decompositions
        );
        assert!(a.steps > 20, "a stiff run takes steps: {}", a.steps);
        assert_eq!(
            (
                a.steps,
                a.rejected_steps,
                a.rhs_evals,
                a.jacobian_evals,
                a.lu_decompositions
            ),
            (
                b.steps,
                b.rejected_steps,
                b.rhs_evals,
                b.jacobian_evals,
                b.lu_decompositions
            )
        );
        let diff = dense
            .y_last
            .iter()
            .zip(&sparse.y_last)
            .fold(0.0f64, |d, (u, v)| d.max((u - v).abs()));
        let size = dense.y_last.iter().fold(0.0f64, |d, u| d.max(u.abs()));
        assert!(size > 0.1, "the chain moves: {size}");
        assert!(diff < 1e-12, "m = {m}: sparse and dense differ by {diff:e}");
    }
}

#[test]
fn sparse_jacobians_refuse_full_newton_and_bad_entries() {
    let opts = Options {
        radau5: Radau5Options {
            newton: RadauNewton::Full,
            ..Radau5Options::default()
        },
        ..Options::default()
    };
    let e = run(5, true, &opts).unwrap_err();
    match &e.error {
        IntegrateError::InvalidInput(msg) => assert!(msg.contains("full Newton"), "{msg}"),
        other => panic!("{other:?}"),
    }
    struct Outside(Chain);
    impl ImplicitSystem for Outside {
        fn dim(&self) -> usize {
            self.0.dim()
        }
        fn residual(
            &mut self,
            t: f64,
            y: &[f64],
            yp: &[f64],
            r: &mut [f64],
        ) -> Result<(), SystemError> {
            self.0.residual(t, y, yp, r)
        }
        fn jacobians(
            &mut self,
            t: f64,
            y: &[f64],
            yp: &[f64],
            a: &mut [f64],
            b: &mut [f64],
        ) -> Result<(), SystemError> {
            self.0.jacobians(t, y, yp, a, b)
        }
        fn sparsity(&self) -> Option<Sparsity> {
            let mut sp = self.0.entries();
            sp.jy.push((0, 99));
            Some(sp)
        }
    }
    let mut sys = Outside(Chain {
        m: 5,
        k: 1.0,
        sparse: true,
    });
    let e = solve_implicit(
        &mut sys,
        0.0,
        &[0.0; 6],
        &[0.0; 6],
        1.0,
        &Options::default(),
    )
    .unwrap_err();
    match &e.error {
        IntegrateError::InvalidInput(msg) => assert!(msg.contains("(0, 99)"), "{msg}"),
        other => panic!("{other:?}"),
    }
}

/// `y₀' = 1`, `0 = y₀ y₁`: at `y = 0` the algebraic row of `∂F/∂y` is
/// zero, so both iteration matrices have an exactly zero pivot while their
/// pattern is structurally regular.
struct Pinch {
    sparse: bool,
}

impl ImplicitSystem for Pinch {
    fn dim(&self) -> usize {
        2
    }

    fn residual(
        &mut self,
        _t: f64,
        y: &[f64],
        yp: &[f64],
        res: &mut [f64],
    ) -> Result<(), SystemError> {
        res[0] = yp[0] - 1.0;
        res[1] = y[0] * y[1];
        Ok(())
    }

    fn jacobians(
        &mut self,
        _t: f64,
        y: &[f64],
        _yp: &[f64],
        jy: &mut [f64],
        jyp: &mut [f64],
    ) -> Result<(), SystemError> {
        // Entries (1, 0), (1, 1) of ∂F/∂y and (0, 0) of ∂F/∂y'.
        let (a, b) = (y[1], y[0]);
        if self.sparse {
            jy.copy_from_slice(&[a, b]);
            jyp.copy_from_slice(&[1.0]);
        } else {
            jy.copy_from_slice(&[0.0, 0.0, a, b]);
            jyp.copy_from_slice(&[1.0, 0.0, 0.0, 0.0]);
        }
        Ok(())
    }

    fn sparsity(&self) -> Option<Sparsity> {
        self.sparse.then(|| Sparsity {
            jy: vec![(1, 0), (1, 1)],
            jyp: vec![(0, 0)],
        })
    }
}

#[test]
fn a_numerically_singular_sparse_matrix_is_reported_as_the_dense_one_is() {
    let mut messages = Vec::new();
    for sparse in [false, true] {
        let e = solve_implicit(
            &mut Pinch { sparse },
            0.0,
            &[0.0, 0.0],
            &[1.0, 0.0],
            1.0,
            &Options::default(),
        )
        .unwrap_err();
        match e.error {
            IntegrateError::System { t, source } => {
                assert_eq!(t, 0.0);
                messages.push(source.to_string());
            }
            other => panic!("sparse = {sparse}: {other:?}"),
        }
    }
    let first = messages[0].split(" (h = ").next().unwrap().to_string();
    assert!(first.contains("singular"), "{first}");
    for m in &messages {
        assert!(
            m.starts_with(&first) && m.contains("5 time(s) in a row"),
            "{m}"
        );
    }
}
