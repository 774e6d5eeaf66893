//! Formulation B on the sleigh in process against the hand-written reduced
//! equations under the same integrator, at matched error: the workbench's
//! price for deriving the equations from the Lagrangian.
//!
//! The generic sleigh (`a = 0.4`, `α = 0.3`, gravity at the centre of mass;
//! `φ0 = 0.2`, `u0 = 2`, `ω0 = 0.7`) over `t ∈ [0, 20]` by DOP853 at
//! `rtol = atol = 1e-6 … 1e-13`: B through `nonholo_chetaev::Chetaev`
//! (state `(q, q̇)`, KKT solve from the compiled Lagrangian) and the spec's
//! reduced B (`nonholo_bench::hand::ReducedB`, state `(x, y, φ, u, ω)`).
//! The error is `max |(x, y, φ) − reference|` at `t = 20` (a step point:
//! no dense output is read); the reference is the reduced B by DOP853 at
//! 3e-14, and its own error is bounded by its distance to the same at
//! 1e-13 (printed). Each pair of runs is timed in alternating repeats
//! (medians). At matched error each side's tolerance for the target error
//! is interpolated as a power law between the two rungs that bracket it
//! (errors are deterministic), and the two sides run again at those
//! tolerances in alternating repeats (three times the rungs' repeats): the
//! ratio is the median of the paired ratios, so a machine whose speed
//! drifts between rungs does not enter it. The errors reached there, and
//! the number of paired repeats, are printed and written beside it.
//!
//! With `--scipy PYTHON`, `crates/bench/scipy/sleigh_b.py` runs under that
//! interpreter (it needs NumPy and SciPy) as one process serving one run per
//! request: the same problem as a SciPy user writes it, a KKT right-hand
//! side in NumPy integrated by `solve_ivp`'s DOP853, each run timed inside
//! the script (`solve_ivp` alone). Its runs take turns with B's and the
//! hand-written equations' in every repeat of every rung, and at matched
//! error SciPy runs at its own interpolated tolerance in the same paired
//! repeats: the speed-up is the median of the repeats' ratios. The process
//! gets `OPENBLAS_NUM_THREADS=1` (and the same for OpenMP and MKL): a 4 × 4
//! `dgesv` runs on one thread anyway, and BLAS threads left spinning would
//! take the second core from the runs being timed.
//!
//! `cargo run --release -p nonholo-bench --bin sleigh-floor [-- --repeats N --error E --scipy PYTHON]`,
//! from the repository root: the ladder and the matched-error line are also
//! written to `results/sleigh-floor/{ladder,matched}.csv`, and with `--scipy`
//! SciPy's ladder and the matched-error comparison to
//! `results/sleigh-floor/{scipy,scipy-matched}.csv`, whose numbers
//! docs/performance.md quotes.

use std::process::ExitCode;
use std::time::Instant;

use nonholo_bench::hand::{Constants, ReducedB};
use nonholo_bench::setup::{OMEGA, Q, U, cartesian, generic_sleigh};
use nonholo_bench::timing::{at_error, median};
use nonholo_chetaev::Chetaev;
use nonholo_core::Params;
use nonholo_core::integrate::{Method, OdeSystem, Options, solve};

const T_END: f64 = 20.0;

/// One tolerance: B (side 0), the hand-written equations (1) and, with
/// `--scipy`, SciPy (2).
struct Rung {
    tol: f64,
    error: [f64; 3],
    ms: [f64; 3],
    evals: [usize; 3],
}

/// Path of the SciPy peer, in this crate.
const SCIPY_SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scipy/sleigh_b.py");

/// SciPy's DOP853: `sleigh_b.py` under `python`, one run per request.
struct Scipy {
    child: std::process::Child,
    /// `None` once closed (in `drop`).
    requests: Option<std::process::ChildStdin>,
    answers: std::io::BufReader<std::process::ChildStdout>,
}

impl Scipy {
    fn start(python: &str, c: &Constants, y0: &[f64], reference: [f64; 3]) -> Result<Self, String> {
        use std::process::{Command, Stdio};
        let mut cmd = Command::new(python);
        cmd.arg(SCIPY_SCRIPT);
        for (name, v) in [
            ("--m", c.m),
            ("--j", c.j),
            ("--a", c.a),
            ("--gs", c.gs),
            ("--com", c.com),
            ("--t-end", T_END),
        ] {
            // `--name=value`: argparse would take a separate `-2.9e0` for an option.
            cmd.arg(format!("{name}={v:e}"));
        }
        // Plain decimals (round-trip exact): argparse takes `-2e-1` for an option.
        cmd.arg("--y0").args(y0.iter().map(|v| v.to_string()));
        cmd.arg("--reference")
            .args(reference.iter().map(|v| v.to_string()));
        for var in ["OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"] {
            cmd.env(var, "1");
        }
        let mut child = cmd
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .map_err(|e| format!("--scipy: cannot run `{python}`: {e}"))?;
        let (Some(requests), Some(answers)) = (child.stdin.take(), child.stdout.take()) else {
            return Err("--scipy: no pipe to the script".into());
        };
        Ok(Scipy {
            child,
            requests: Some(requests),
            answers: std::io::BufReader::new(answers),
        })
    }

    /// `(error, rhs evaluations, ms)` of one run at `tol`.
    fn run(&mut self, tol: f64) -> Result<(f64, usize, f64), String> {
        use std::io::{BufRead, Write};
        let failed = |what: &str| {
            format!("--scipy: {SCIPY_SCRIPT} {what} at tol {tol:e} (its message is above)")
        };
        let requests = self.requests.as_mut().ok_or_else(|| failed("was closed"))?;
        writeln!(requests, "{tol:e}")
            .and_then(|()| requests.flush())
            .map_err(|_| failed("stopped"))?;
        let mut line = String::new();
        match self.answers.read_line(&mut line) {
            Ok(n) if n > 0 => {}
            _ => return Err(failed("stopped")),
        }
        let cells: Vec<&str> = line.trim().split(',').collect();
        let bad = || format!("--scipy: unexpected output `{}`", line.trim());
        if cells.len() != 4 {
            return Err(bad());
        }
        let error: f64 = cells[1].parse().map_err(|_| bad())?;
        let evals: usize = cells[2].parse().map_err(|_| bad())?;
        let ms: f64 = cells[3].parse().map_err(|_| bad())?;
        Ok((error, evals, ms))
    }
}

impl Drop for Scipy {
    fn drop(&mut self) {
        // The script ends when its stdin closes.
        drop(self.requests.take());
        let _ = self.child.wait();
    }
}

/// `(position at T_END, rhs evaluations, wall ms)` of one DOP853 run.
fn run(sys: &mut dyn OdeSystem, y0: &[f64], tol: f64) -> Result<([f64; 3], usize, f64), String> {
    let opts = Options {
        rtol: tol,
        atol: tol,
        output: vec![0.0, T_END],
        ..Options::default()
    };
    let start = Instant::now();
    let sol = solve(Method::Dop853, sys, 0.0, y0, T_END, &opts).map_err(|f| f.error.to_string())?;
    let ms = start.elapsed().as_secs_f64() * 1e3;
    let y = &sol.y_last;
    Ok(([y[0], y[1], y[2]], sol.stats.rhs_evals, ms))
}

fn args() -> Result<(usize, f64, Option<String>), String> {
    let (mut repeats, mut error, mut scipy) = (15usize, 1e-10f64, None);
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or_else(|| format!("{name} needs a value"));
        match a.as_str() {
            "--repeats" => {
                repeats = value("--repeats")?
                    .parse()
                    .map_err(|e| format!("--repeats: {e}"))?
            }
            "--error" => {
                error = value("--error")?
                    .parse()
                    .map_err(|e| format!("--error: {e}"))?
            }
            "--scipy" => scipy = Some(value("--scipy")?),
            "--help" | "-h" => {
                println!("sleigh-floor [--repeats N] [--error E] [--scipy PYTHON]");
                std::process::exit(0);
            }
            other => return Err(format!("unknown argument `{other}`")),
        }
    }
    if repeats == 0 || !(error > 0.0 && error.is_finite()) {
        return Err("--repeats must be at least 1 and --error positive".into());
    }
    Ok((repeats, error, scipy))
}

/// Tolerance of `side` for error `e` ([`at_error`] over the rungs: the
/// tolerance interpolated as a power law of the error).
fn tol_at_error(rungs: &[Rung], side: usize, e: f64) -> Option<f64> {
    let points: Vec<(f64, f64)> = rungs.iter().map(|r| (r.error[side], r.tol)).collect();
    at_error(&points, e)
}

fn report() -> Result<(), String> {
    let (repeats, target, scipy) = args()?;
    let sleigh = generic_sleigh().map_err(|e| e.to_string())?;
    let c = Constants::of(&sleigh);
    let y_b = cartesian(Q, U, 0.0, OMEGA).to_vec();
    let y_h = vec![Q[0], Q[1], Q[2], U, OMEGA];
    let mut b = Chetaev::new(sleigh.clone(), Params::defaults(nonholo_chetaev::OPTIONS))
        .map_err(|e| e.to_string())?;
    let mut hand = ReducedB(c);
    let (reference, _, _) = run(&mut hand, &y_h, 3e-14)?;
    let (check, _, _) = run(&mut hand, &y_h, 1e-13)?;
    let ref_error = (0..3).fold(0.0f64, |m, i| m.max((reference[i] - check[i]).abs()));
    let dist = |p: [f64; 3]| (0..3).fold(0.0f64, |m, i| m.max((p[i] - reference[i]).abs()));
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "Sleigh, B by DOP853 over [0, {T_END}] s: the workbench (AD, compiled Lagrangian, KKT) \
         against the hand-written reduced B; error at t = {T_END} s (a step point) against the \
         reduced B at 3e-14 (its distance to 1e-13: {ref_error:.1e} m); {repeats} alternating \
         repeats per rung, medians; load average before: {}.\n",
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    println!(
        "| tol | error B (m) | error hand (m) | evaluations B | evaluations hand | B (ms) | hand (ms) | time ratio |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut rungs = Vec::new();
    let mut ladder =
        String::from("tol,error_b,error_hand,evals_b,evals_hand,ms_b,ms_hand,time_ratio\n");
    let mut scipy_ladder = String::from("tol,error,evals,ms,speedup_b\n");
    let mut scipy = match &scipy {
        Some(python) => Some(Scipy::start(python, &c, &y_b, reference)?),
        None => None,
    };
    for k in 6..=13 {
        let tol = 10f64.powi(-k);
        let (mut tb, mut th, mut ts) = (Vec::new(), Vec::new(), Vec::new());
        let (mut pb, mut ph, mut eb, mut eh) = ([0.0; 3], [0.0; 3], 0, 0);
        let (mut es, mut ns) = (f64::NAN, 0);
        for _ in 0..repeats {
            let (p, e, ms) = run(&mut b, &y_b, tol)?;
            (pb, eb) = (p, e);
            tb.push(ms);
            let (p, e, ms) = run(&mut hand, &y_h, tol)?;
            (ph, eh) = (p, e);
            th.push(ms);
            if let Some(peer) = scipy.as_mut() {
                let (e, n, ms) = peer.run(tol)?;
                (es, ns) = (e, n);
                ts.push(ms);
            }
        }
        let r = Rung {
            tol,
            error: [dist(pb), dist(ph), es],
            ms: [median(&mut tb), median(&mut th), median(&mut ts)],
            evals: [eb, eh, ns],
        };
        if scipy.is_some() {
            scipy_ladder.push_str(&format!(
                "{:e},{:.3e},{},{:.4},{:.1}\n",
                r.tol,
                r.error[2],
                r.evals[2],
                r.ms[2],
                r.ms[2] / r.ms[0]
            ));
        }
        let cells = [
            format!("{:e}", r.tol),
            format!("{:.3e}", r.error[0]),
            format!("{:.3e}", r.error[1]),
            r.evals[0].to_string(),
            r.evals[1].to_string(),
            format!("{:.4}", r.ms[0]),
            format!("{:.4}", r.ms[1]),
            format!("{:.3}", r.ms[0] / r.ms[1]),
        ];
        println!("| {} |", cells.join(" | "));
        ladder.push_str(&format!("{}\n", cells.join(",")));
        rungs.push(r);
    }
    let (Some(tol_b), Some(tol_h)) = (
        tol_at_error(&rungs, 0, target),
        tol_at_error(&rungs, 1, target),
    ) else {
        return Err(format!(
            "error {target:.0e} m is not bracketed by both ladders"
        ));
    };
    // SciPy's tolerance for the same error, where it runs.
    let tol_s =
        match scipy {
            Some(_) => Some(tol_at_error(&rungs, 2, target).ok_or_else(|| {
                format!("error {target:.0e} m is not bracketed by SciPy's ladder")
            })?),
            None => None,
        };
    // Every side at its matched tolerance, paired.
    let (mut tb, mut th, mut ts) = (Vec::new(), Vec::new(), Vec::new());
    let (mut ratios, mut speedups) = (Vec::new(), Vec::new());
    let (mut pb, mut ph, mut es) = ([0.0; 3], [0.0; 3], f64::NAN);
    for _ in 0..3 * repeats {
        let (p, _, a) = run(&mut b, &y_b, tol_b)?;
        let (q, _, h) = run(&mut hand, &y_h, tol_h)?;
        (pb, ph) = (p, q);
        tb.push(a);
        th.push(h);
        ratios.push(a / h);
        if let (Some(peer), Some(tol_s)) = (scipy.as_mut(), tol_s) {
            let (e, _, ms) = peer.run(tol_s)?;
            es = e;
            ts.push(ms);
            speedups.push(ms / a);
        }
    }
    let (a, h, ratio) = (median(&mut tb), median(&mut th), median(&mut ratios));
    let (err_b, err_h) = (dist(pb), dist(ph));
    println!(
        "\nAt matched error {target:.0e} m (B at tol {tol_b:.2e}: {err_b:.2e} m; hand-written at \
         {tol_h:.2e}: {err_h:.2e} m; {} paired repeats): B {a:.3} ms, hand-written {h:.4} ms, \
         paired ratio {ratio:.1}×",
        3 * repeats
    );
    let matched = format!(
        "{target:e},{a:.4},{h:.4},{ratio:.3},{ref_error:.2e},{tol_b:.3e},{tol_h:.3e},{err_b:.3e},{err_h:.3e},{}\n",
        ratios.len()
    );
    let mut files = vec![
        ("ladder.csv", ladder),
        (
            "matched.csv",
            format!(
                "error,ms_b,ms_hand,time_ratio,reference_error,tol_b,tol_hand,error_b,error_hand,paired_repeats\n{matched}"
            ),
        ),
    ];
    if let Some(tol_s) = tol_s {
        println!(
            "\nSciPy (solve_ivp DOP853, NumPy KKT right-hand side), same rungs, same repeats:\n"
        );
        println!("| tol | error (m) | evaluations | ms | time / B's |");
        println!("|---|---|---|---|---|");
        for line in scipy_ladder.lines().skip(1) {
            println!("| {} |", line.replace(',', " | "));
        }
        let (p, speedup) = (median(&mut ts), median(&mut speedups));
        println!(
            "\nAt matched error {target:.0e} m (SciPy at tol {tol_s:.2e}: {es:.2e} m; {} paired \
             repeats): B {a:.3} ms, SciPy {p:.2} ms: B {speedup:.0}× faster",
            speedups.len()
        );
        files.push(("scipy.csv", scipy_ladder));
        files.push((
            "scipy-matched.csv",
            format!(
                "error,ms_b,ms_scipy,speedup,tol_scipy,error_scipy,paired_repeats\n\
                 {target:e},{a:.4},{p:.4},{speedup:.1},{tol_s:.3e},{es:.3e},{}\n",
                speedups.len()
            ),
        ));
    }
    let dir = std::path::Path::new("results/sleigh-floor");
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for (name, text) in files {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(())
}

fn main() -> ExitCode {
    nonholo_bench::report_main(report)
}
