//! Dense LU factorisation with partial pivoting, in place, for the real
//! iteration matrix `γ/h J' + J` and the complex one `(α + iβ)/h J' + J`.
//!
//! Matrices are row-major `n × n` (`a[i * n + j]`); the complex matrix is
//! held as separate real and imaginary parts. Nothing allocates after
//! construction. Row `k` is exchanged with the row of the largest pivot
//! candidate (by `|re| + |im|` in the complex case, as LAPACK's `ZGETRF`);
//! the factorisation fails (the matrix is treated as singular) when that
//! candidate is zero or not finite.

/// `P A = L U` of a real matrix, `L` unit lower triangular.
#[derive(Debug, Clone)]
pub(super) struct RealLu {
    n: usize,
    /// The matrix to factor; after [`RealLu::factor`] `L` (strictly below
    /// the diagonal) and `U`.
    pub a: Vec<f64>,
    piv: Vec<usize>,
}

impl RealLu {
    pub fn new(n: usize) -> Self {
        RealLu {
            n,
            a: vec![0.0; n * n],
            piv: vec![0; n],
        }
    }

    /// Factors `self.a` in place; `Err(k)` if the pivot of column `k` is
    /// zero or not finite.
    pub fn factor(&mut self) -> Result<(), usize> {
        let n = self.n;
        let a = &mut self.a;
        for k in 0..n {
            let mut p = k;
            let mut big = a[k * n + k].abs();
            for i in k + 1..n {
                let v = a[i * n + k].abs();
                if v > big {
                    big = v;
                    p = i;
                }
            }
            if big == 0.0 || !big.is_finite() {
                return Err(k);
            }
            self.piv[k] = p;
            if p != k {
                for j in 0..n {
                    a.swap(k * n + j, p * n + j);
                }
            }
            let inv = 1.0 / a[k * n + k];
            for i in k + 1..n {
                let l = a[i * n + k] * inv;
                a[i * n + k] = l;
                if l != 0.0 {
                    for j in k + 1..n {
                        a[i * n + j] -= l * a[k * n + j];
                    }
                }
            }
        }
        Ok(())
    }

    /// Overwrites `b` with the solution of `A x = b`.
    pub fn solve(&self, b: &mut [f64]) {
        let n = self.n;
        let a = &self.a;
        for k in 0..n {
            b.swap(k, self.piv[k]);
        }
        for i in 1..n {
            let mut s = b[i];
            for j in 0..i {
                s -= a[i * n + j] * b[j];
            }
            b[i] = s;
        }
        for i in (0..n).rev() {
            let mut s = b[i];
            for j in i + 1..n {
                s -= a[i * n + j] * b[j];
            }
            b[i] = s / a[i * n + i];
        }
    }
}

/// `P A = L U` of a complex matrix held as `re + i im`.
#[derive(Debug, Clone)]
pub(super) struct ComplexLu {
    n: usize,
    /// Real part of the matrix (of the factors after [`ComplexLu::factor`]).
    pub re: Vec<f64>,
    /// Imaginary part.
    pub im: Vec<f64>,
    piv: Vec<usize>,
    /// `1/U_kk` (real and imaginary parts), set by [`ComplexLu::factor`].
    dinv_re: Vec<f64>,
    dinv_im: Vec<f64>,
}

/// `(a + ib)(c + id)`.
#[inline]
fn cmul(a: f64, b: f64, c: f64, d: f64) -> (f64, f64) {
    (a * c - b * d, a * d + b * c)
}

/// `1/(a + ib)` (Smith's formula, no overflow for large parts).
#[inline]
fn cinv(a: f64, b: f64) -> (f64, f64) {
    if a.abs() >= b.abs() {
        let r = b / a;
        let den = a + b * r;
        (1.0 / den, -r / den)
    } else {
        let r = a / b;
        let den = a * r + b;
        (r / den, -1.0 / den)
    }
}

impl ComplexLu {
    pub fn new(n: usize) -> Self {
        ComplexLu {
            n,
            re: vec![0.0; n * n],
            im: vec![0.0; n * n],
            piv: vec![0; n],
            dinv_re: vec![0.0; n],
            dinv_im: vec![0.0; n],
        }
    }

    /// Factors in place; `Err(k)` if the pivot of column `k` is zero or not finite.
    pub fn factor(&mut self) -> Result<(), usize> {
        let n = self.n;
        let (re, im) = (&mut self.re, &mut self.im);
        for k in 0..n {
            let mut p = k;
            let mut big = re[k * n + k].abs() + im[k * n + k].abs();
            for i in k + 1..n {
                let v = re[i * n + k].abs() + im[i * n + k].abs();
                if v > big {
                    big = v;
                    p = i;
                }
            }
            if big == 0.0 || !big.is_finite() {
                return Err(k);
            }
            self.piv[k] = p;
            if p != k {
                for j in 0..n {
                    re.swap(k * n + j, p * n + j);
                    im.swap(k * n + j, p * n + j);
                }
            }
            let (ir, ii) = cinv(re[k * n + k], im[k * n + k]);
            (self.dinv_re[k], self.dinv_im[k]) = (ir, ii);
            for i in k + 1..n {
                let (lr, li) = cmul(re[i * n + k], im[i * n + k], ir, ii);
                re[i * n + k] = lr;
                im[i * n + k] = li;
                if lr != 0.0 || li != 0.0 {
                    for j in k + 1..n {
                        let (pr, pi) = cmul(lr, li, re[k * n + j], im[k * n + j]);
                        re[i * n + j] -= pr;
                        im[i * n + j] -= pi;
                    }
                }
            }
        }
        Ok(())
    }

    /// Overwrites `(br, bi)` with the solution of `A x = b`.
    pub fn solve(&self, br: &mut [f64], bi: &mut [f64]) {
        let n = self.n;
        let (re, im) = (&self.re, &self.im);
        for k in 0..n {
            br.swap(k, self.piv[k]);
            bi.swap(k, self.piv[k]);
        }
        for i in 1..n {
            let (mut sr, mut si) = (br[i], bi[i]);
            for j in 0..i {
                let (pr, pi) = cmul(re[i * n + j], im[i * n + j], br[j], bi[j]);
                sr -= pr;
                si -= pi;
            }
            br[i] = sr;
            bi[i] = si;
        }
        for i in (0..n).rev() {
            let (mut sr, mut si) = (br[i], bi[i]);
            for j in i + 1..n {
                let (pr, pi) = cmul(re[i * n + j], im[i * n + j], br[j], bi[j]);
                sr -= pr;
                si -= pi;
            }
            let (xr, xi) = cmul(sr, si, self.dinv_re[i], self.dinv_im[i]);
            br[i] = xr;
            bi[i] = xi;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic, non-symmetric test matrix that needs pivoting
    /// (zero in the top-left corner).
    fn matrix(n: usize, phase: f64) -> Vec<f64> {
        (0..n * n)
            .map(|k| {
                let (i, j) = (k / n, k % n);
                if i == 0 && j == 0 {
                    0.0
                } else {
                    ((i * 7 + j * 3) as f64 + phase).sin() + if i == j { 0.5 } else { 0.0 }
                }
            })
            .collect()
    }

    #[test]
    fn real_lu_solves_a_pivoting_system() {
        let n = 6;
        let a = matrix(n, 0.3);
        let x: Vec<f64> = (0..n).map(|i| 1.0 + i as f64 * 0.25).collect();
        let mut b: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| a[i * n + j] * x[j]).sum())
            .collect();
        let mut lu = RealLu::new(n);
        lu.a.copy_from_slice(&a);
        lu.factor().unwrap();
        lu.solve(&mut b);
        for i in 0..n {
            assert!((b[i] - x[i]).abs() < 1e-12, "{i}: {} vs {}", b[i], x[i]);
        }
        // A singular matrix is reported.
        let mut lu = RealLu::new(2);
        lu.a.copy_from_slice(&[1.0, 2.0, 2.0, 4.0]);
        assert_eq!(lu.factor(), Err(1));
    }

    #[test]
    fn complex_lu_solves_a_pivoting_system() {
        let n = 5;
        let (ar, ai) = (matrix(n, 0.1), matrix(n, 1.7));
        let (xr, xi): (Vec<f64>, Vec<f64>) = (0..n)
            .map(|i| (1.0 - i as f64 * 0.3, 0.5 + i as f64))
            .unzip();
        let mut br = vec![0.0; n];
        let mut bi = vec![0.0; n];
        for i in 0..n {
            for j in 0..n {
                let (pr, pi) = cmul(ar[i * n + j], ai[i * n + j], xr[j], xi[j]);
                br[i] += pr;
                bi[i] += pi;
            }
        }
        let mut lu = ComplexLu::new(n);
        lu.re.copy_from_slice(&ar);
        lu.im.copy_from_slice(&ai);
        lu.factor().unwrap();
        lu.solve(&mut br, &mut bi);
        for i in 0..n {
            assert!((br[i] - xr[i]).abs() < 1e-12 && (bi[i] - xi[i]).abs() < 1e-12);
        }
        let (r, i) = cinv(0.0, 2.0);
        assert!(r == 0.0 && (i + 0.5).abs() < 1e-16);
    }
}
