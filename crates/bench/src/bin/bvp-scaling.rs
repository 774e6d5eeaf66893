//! The cost of one Newton step of the boundary-value solver against the
//! number of grid nodes, from 1e2 to 1e5 (issue 14; docs/performance.md §8).
//!
//! `cargo run --release -p nonholo-bench --bin bvp-scaling [-- --rounds R --out DIR]`
//!
//! The problem: the sleigh (a = 0.4, α = 0.3, paper potential) from φ0 = 0.2,
//! u0 = 2 m/s, ω0 = 0.7 rad/s, λ0 = 0.5 over [0, 1] s, as C's boundary-value
//! problem and as A's with the implicit map, with the ends and the starting
//! path from C's initial-value motion (DOP853 at 1e-13) at the nodes. Every
//! size is timed once per round, the sizes interleaved, `R` rounds (default
//! 3): exactly [`STEPS`] Newton steps (`Solver::timed_steps`: each one
//! assembly of the sparse KKT system with its Hessian by automatic
//! differentiation, faer's sparse LU with the symbolic analysis reused, the
//! solve and the line search's residuals), then Newton's method to
//! convergence for the error column. The table gives medians of the wall
//! time per step, its split, and the one-off symbolic set-up; the exponent
//! is the least-squares slope of log(step time) against log(nodes). `scaling.csv` in DIR (default
//! `results/bvp-scaling`) keeps the numbers that docs/performance.md quotes.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use nonholo_core::integrate::{Method, Options};
use nonholo_core::{RunConfig, simulate};
use nonholo_scenes::Sleigh;
use nonholo_variational as var;

const SIZES: [usize; 7] = [100, 316, 1000, 3162, 10_000, 31_623, 100_000];

/// Newton steps timed per size and round.
const STEPS: usize = 2;
const T1: f64 = 1.0;

struct Row {
    line: &'static str,
    intervals: usize,
    unknowns: usize,
    nonzeros: usize,
    setup_s: Vec<f64>,
    step_s: Vec<f64>,
    assembly_s: Vec<f64>,
    factor_s: Vec<f64>,
    iterations: usize,
    error: f64,
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[s.len() / 2]
}

/// Least-squares slope of `ln y` against `ln x`.
fn slope(x: &[f64], y: &[f64]) -> f64 {
    let (lx, ly): (Vec<f64>, Vec<f64>) = x.iter().zip(y).map(|(a, b)| (a.ln(), b.ln())).unzip();
    let n = lx.len() as f64;
    let (mx, my) = (lx.iter().sum::<f64>() / n, ly.iter().sum::<f64>() / n);
    let sxy: f64 = lx.iter().zip(&ly).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = lx.iter().map(|a| (a - mx) * (a - mx)).sum();
    sxy / sxx
}

/// C's motion at `intervals + 1` nodes on [0, T1]: positions and velocities.
fn reference(s: &Sleigh, intervals: usize) -> Result<(Vec<f64>, Vec<f64>), String> {
    let initial =
        nonholo_bench::setup::initial(s, 0.2, 2.0, 0.7, Some(0.5)).map_err(|e| e.to_string())?;
    let model = nonholo_vakonomic::Vakonomic::new(
        s.clone(),
        nonholo_core::Params::defaults(nonholo_vakonomic::OPTIONS),
    )
    .map_err(|e| e.to_string())?;
    let grid: Vec<f64> = (0..=intervals)
        .map(|k| T1 * k as f64 / intervals as f64)
        .collect();
    let run = simulate(
        Box::new(model),
        initial,
        RunConfig {
            method: Method::Dop853,
            options: Options {
                rtol: 1e-13,
                atol: 1e-13,
                output: grid,
                ..Options::default()
            },
            t_end: T1,
            project_init: false,
        },
    )
    .map_err(|e| e.to_string())?;
    if let Some(f) = &run.failure {
        return Err(f.to_string());
    }
    Ok((
        run.samples.iter().flat_map(|o| o.q.clone()).collect(),
        run.samples.iter().flat_map(|o| o.qd.clone()).collect(),
    ))
}

fn run() -> Result<(), String> {
    let mut rounds = 3usize;
    let mut out = PathBuf::from("results/bvp-scaling");
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--rounds" => {
                rounds = args
                    .next()
                    .and_then(|v| v.parse().ok())
                    .filter(|r| *r >= 1)
                    .ok_or("--rounds: a positive integer")?;
            }
            "--out" => out = PathBuf::from(args.next().ok_or("--out: a directory")?),
            other => {
                return Err(format!(
                    "unknown argument `{other}` (--rounds R, --out DIR)"
                ));
            }
        }
    }
    let s = nonholo_bench::setup::sleigh(0.4, 0.3, "paper").map_err(|e| e.to_string())?;
    let lines: [(&str, var::Formulation); 2] = [
        ("C (vakonomic)", var::Formulation::Vakonomic),
        (
            "A (implicit map)",
            var::Formulation::Map {
                ends: var::MapEnds::Configuration,
                form: var::MapForm::Implicit,
            },
        ),
    ];
    let mut data = Vec::new();
    for &n in &SIZES {
        data.push(reference(&s, n)?);
    }
    let mut rows: Vec<Row> = Vec::new();
    for (line, _) in &lines {
        for &n in &SIZES {
            rows.push(Row {
                line,
                intervals: n,
                unknowns: 0,
                nonzeros: 0,
                setup_s: Vec::new(),
                step_s: Vec::new(),
                assembly_s: Vec::new(),
                factor_s: Vec::new(),
                iterations: 0,
                error: 0.0,
            });
        }
    }
    let options = var::Options::default();
    for _ in 0..rounds {
        for (il, (_, f)) in lines.iter().enumerate() {
            for (is, &n) in SIZES.iter().enumerate() {
                let (q, qd) = &data[is];
                let ends = var::Ends {
                    q0: q[..3].to_vec(),
                    q1: q[3 * n..].to_vec(),
                    qd0: Some(qd[..3].to_vec()),
                    qd1: Some(qd[3 * n..].to_vec()),
                };
                let p = var::Problem::new(&s, f.clone(), 0.0, T1, n, ends)
                    .map_err(|e| e.to_string())?;
                let started = Instant::now();
                let mut solver = var::Solver::new(&p, &options).map_err(|e| e.to_string())?;
                let setup = started.elapsed().as_secs_f64();
                let timed = solver
                    .timed_steps(q, STEPS, &options)
                    .map_err(|e| format!("{n}: {e}"))?;
                let sol = solver.solve(q, &options).map_err(|e| format!("{n}: {e}"))?;
                let r = &mut rows[il * SIZES.len() + is];
                let k = STEPS as f64;
                r.unknowns = sol.report.unknowns;
                r.nonzeros = sol.report.nonzeros;
                r.iterations = sol.report.iterations;
                r.setup_s.push(setup);
                r.step_s.push(timed.wall_seconds / k);
                r.assembly_s.push(timed.assembly_seconds / k);
                r.factor_s.push(timed.factor_seconds / k);
                r.error = sol
                    .q
                    .iter()
                    .zip(q)
                    .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            }
        }
    }
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "One Newton step of the boundary-value solver on the sleigh over [0, {T1}] s, medians of \
         {rounds} interleaved rounds; load average before: {}.\n",
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    println!(
        "| problem | intervals | unknowns | stored entries | Newton steps to converge | per step (ms) | assembly (ms) | LU and solve (ms) | symbolic set-up (ms) | max |q − q_C| at the nodes |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut csv = String::from(
        "problem,intervals,unknowns,nonzeros,iterations,step_s,assembly_s,factor_s,setup_s,error\n",
    );
    for r in &rows {
        let (st, a, f, su) = (
            median(&r.step_s),
            median(&r.assembly_s),
            median(&r.factor_s),
            median(&r.setup_s),
        );
        println!(
            "| {} | {} | {} | {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.1e} |",
            r.line,
            r.intervals,
            r.unknowns,
            r.nonzeros,
            r.iterations,
            st * 1e3,
            a * 1e3,
            f * 1e3,
            su * 1e3,
            r.error
        );
        csv.push_str(&format!(
            "{},{},{},{},{},{st:e},{a:e},{f:e},{su:e},{:e}\n",
            r.line, r.intervals, r.unknowns, r.nonzeros, r.iterations, r.error
        ));
    }
    println!();
    let mut fits = String::from("problem,exponent_step,exponent_assembly,exponent_factor\n");
    for (line, _) in &lines {
        let mine: Vec<&Row> = rows.iter().filter(|r| r.line == *line).collect();
        let x: Vec<f64> = mine.iter().map(|r| r.intervals as f64 + 1.0).collect();
        let fit =
            |f: &dyn Fn(&Row) -> f64| slope(&x, &mine.iter().map(|r| f(r)).collect::<Vec<_>>());
        let (es, ea, ef) = (
            fit(&|r| median(&r.step_s)),
            fit(&|r| median(&r.assembly_s)),
            fit(&|r| median(&r.factor_s)),
        );
        println!(
            "{line}: cost per Newton step ∝ nodes^{es:.3} (assembly {ea:.3}, LU and solve {ef:.3}) \
             from {} to {} intervals",
            SIZES[0],
            SIZES[SIZES.len() - 1]
        );
        fits.push_str(&format!("{line},{es:.4},{ea:.4},{ef:.4}\n"));
    }
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    for (name, text) in [("scaling.csv", &csv), ("fits.csv", &fits)] {
        let path = out.join(name);
        std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(())
}

fn main() -> ExitCode {
    nonholo_bench::report_main(run)
}
