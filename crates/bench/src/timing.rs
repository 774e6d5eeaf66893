//! Plain timers for the report binary (criterion does the
//! benchmark proper; this gives one number per evaluation for tables).

use std::hint::black_box;
use std::time::Instant;

/// Median of `v` (sorted in place); NaN if empty.
pub fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The cost at error `e` of a solver run through its tolerances: `points`
/// are `(error, cost)` in tolerance order (loosest first); the cost is
/// interpolated as a power law (linearly in log cost against log error)
/// between the first two successive points whose errors bracket `e`
/// (`None` if none do: the error was not reached, or not passed through
/// monotonically; a zero or non-finite error brackets nothing).
pub fn at_error(points: &[(f64, f64)], e: f64) -> Option<f64> {
    points.windows(2).find_map(|w| {
        let ((ea, ca), (eb, cb)) = (w[0], w[1]);
        let finite = ea.is_finite() && eb > 0.0 && ca > 0.0 && cb > 0.0;
        (finite && ea >= e && e >= eb && ea > eb).then(|| {
            let s = (ea.ln() - e.ln()) / (ea.ln() - eb.ln());
            (ca.ln() + s * (cb.ln() - ca.ln())).exp()
        })
    })
}

/// Keeps `x` observable to the optimiser.
pub fn keep<T>(x: T) -> T {
    black_box(x)
}

/// Calls per batch so that one batch of `f` takes about `batch_ms`.
fn calibrate<F: FnMut()>(f: &mut F, batch_ms: f64) -> usize {
    let mut calls = 1usize;
    loop {
        let start = Instant::now();
        for _ in 0..calls {
            f();
        }
        let ms = start.elapsed().as_secs_f64() * 1e3;
        if ms >= batch_ms / 4.0 || calls > 1 << 30 {
            return ((calls as f64) * batch_ms / ms.max(1e-6)).ceil().max(1.0) as usize;
        }
        calls *= 4;
    }
}

/// Times `a` and `b` in alternating batches (so both see the same load on
/// a shared machine): `(median ns per call of a, of b, median of the
/// per-pair ratios a/b)`.
pub fn paired_ns<A: FnMut(), B: FnMut()>(
    mut a: A,
    mut b: B,
    batches: usize,
    batch_ms: f64,
) -> (f64, f64, f64) {
    let (na, nb) = (calibrate(&mut a, batch_ms), calibrate(&mut b, batch_ms));
    let time = |f: &mut dyn FnMut(), n: usize| {
        let start = Instant::now();
        for _ in 0..n {
            f();
        }
        start.elapsed().as_secs_f64() * 1e9 / n as f64
    };
    let (mut ta, mut tb, mut ratio) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..batches.max(1) {
        let x = time(&mut a, na);
        let y = time(&mut b, nb);
        ta.push(x);
        tb.push(y);
        ratio.push(x / y);
    }
    (median(&mut ta), median(&mut tb), median(&mut ratio))
}

/// `--batches N --batch-ms MS` of the report binaries (defaults 31 and
/// 20 ms); `--help` prints `usage` and exits.
pub fn batch_args(usage: &str) -> Result<(usize, f64), String> {
    let (mut batches, mut batch_ms) = (31usize, 20.0f64);
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or_else(|| format!("{name} needs a value"));
        match a.as_str() {
            "--batches" => {
                let v = value("--batches")?;
                batches = v
                    .parse()
                    .map_err(|_| format!("--batches: cannot read `{v}` as a count"))?;
            }
            "--batch-ms" => {
                let v = value("--batch-ms")?;
                batch_ms = v
                    .parse()
                    .map_err(|_| format!("--batch-ms: cannot read `{v}` as milliseconds"))?;
            }
            "-h" | "--help" => {
                println!("usage: {usage}");
                std::process::exit(0);
            }
            other => return Err(format!("unknown argument `{other}` (try --help)")),
        }
    }
    Ok((batches, batch_ms))
}

#[cfg(test)]
mod tests {
    use super::at_error;

    #[test]
    fn cost_at_error_interpolates_log_linearly_between_bracketing_rungs() {
        // cost ∝ error^(-1/4) through 1e-4 … 1e-8: exact on the power law.
        let pts: Vec<(f64, f64)> = (4..=8)
            .map(|k| {
                let e = 10f64.powi(-k);
                (e, e.powf(-0.25))
            })
            .collect();
        let c = at_error(&pts, 3e-7).unwrap();
        assert!((c / 3e-7f64.powf(-0.25) - 1.0).abs() < 1e-12, "{c}");
        // Endpoints are bracketed, outside is not.
        assert!(at_error(&pts, 1e-4).is_some() && at_error(&pts, 1e-8).is_some());
        assert!(at_error(&pts, 1e-3).is_none() && at_error(&pts, 1e-9).is_none());
        // A rung whose error grew is skipped, not interpolated across.
        assert!(at_error(&[(1e-6, 1.0), (1e-5, 2.0)], 3e-6).is_none());
        // An exact run (error 0) brackets nothing.
        assert!(at_error(&[(1e-6, 1.0), (0.0, 2.0)], 1e-7).is_none());
    }
}
