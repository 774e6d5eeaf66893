//! Peers side by side, in one run: `visc(k)` on the sleigh by our Radau IIA
//! and diffsol's BDF, ESDIRK34 and TR-BDF2, in three states (Cartesian and
//! adapted by AD, body frame by hand); B on the sleigh by our DOP853
//! and ode_solvers' DOP853; errors against references whose own error is
//! measured, wall time (median of repeats, every solver of a case timed
//! once per round), work counters.
//!
//! `cargo run --release -p nonholo-bench --features peers --bin peers [-- OPTIONS]`
//!
//! Writes `results/peers/peers.csv` and `results/peers/peers.md` (each by a
//! temporary file and a rename), the page `results/peers/index.html` with
//! its figures ([`nonholo_bench::page`]), and prints the markdown tables.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use nonholo_bench::peers::{
    Against, DIFFSOL_DEFAULT_CAP, DiffsolMethod, Formulation, Problem, Reference, Reuse, Row,
    Solver, measure, measure_all, measure_all_retrying, reference_distance,
};
use nonholo_bench::setup::sleigh;
use nonholo_core::integrate::Method;

struct Args {
    out: PathBuf,
    repeats: usize,
    quick: bool,
    /// Only rebuild index.html from the stored peers.csv and peers.md.
    page: bool,
    reuse: bool,
}

const USAGE: &str = "usage: peers [--out DIR] [--repeats N] [--quick] [--page]
  --out DIR      where peers.csv, peers.md and index.html go (default results/peers)
  --repeats N    timed repeats per case, in rounds over the case's solvers; the median
                 is reported (default 7)
  --quick        k = 1e2, 1e6 and tolerances 1e-6 only (a smoke run)
  --page         run nothing: rebuild index.html and its figures from the stored files
  --reuse        run only the Jacobian-reuse study: our Radau IIA with RADAU5's reuse
                 threshold θ ≤ 0.001 and with 0.01 and 0.1, and with the Hermite dense
                 output (θ ≤ 0.001 and 0.1; 0.1 also with a Newton test ten times
                 tighter), beside diffsol's BDF, on visc in the adapted form and the
                 body frame, timed interleaved (reuse.csv, reuse-matched.csv; the page
                 is rebuilt with it where peers.csv is beside them)";

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        out: PathBuf::from("results/peers"),
        repeats: 7,
        quick: false,
        page: false,
        reuse: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--out" => args.out = PathBuf::from(it.next().ok_or("--out needs a directory")?),
            "--repeats" => {
                let v = it.next().ok_or("--repeats needs a count")?;
                args.repeats = v
                    .parse()
                    .ok()
                    .filter(|&n: &usize| n >= 1)
                    .ok_or_else(|| format!("--repeats: `{v}` is not a count ≥ 1"))?;
            }
            "--quick" => args.quick = true,
            "--page" => args.page = true,
            "--reuse" => args.reuse = true,
            "-h" | "--help" => {
                println!("{USAGE}");
                std::process::exit(0);
            }
            other => return Err(format!("unknown argument `{other}`\n{USAGE}")),
        }
    }
    Ok(args)
}

fn grid(t_end: f64, intervals: usize) -> Vec<f64> {
    (0..=intervals)
        .map(|i| t_end * i as f64 / intervals as f64)
        .collect()
}

/// Writes `text` to `path` through a temporary file in the same directory,
/// flushed before the rename (as `nonholo`'s result files: a killed run
/// leaves the old file or the new one, never half of one).
fn write_atomic(path: &Path, text: &str) -> Result<(), String> {
    use std::io::Write;
    let dir = path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let name = path
        .file_name()
        .ok_or_else(|| format!("{} has no file name", path.display()))?;
    let tmp = dir.join(format!(
        ".{}.{}.tmp",
        name.to_string_lossy(),
        std::process::id()
    ));
    let result = std::fs::File::create(&tmp)
        .and_then(|mut f| f.write_all(text.as_bytes()).and_then(|_| f.sync_all()))
        .and_then(|_| std::fs::rename(&tmp, path));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(|e| format!("cannot write {}: {e}", path.display()))
}

fn sci(x: f64) -> String {
    if x.is_nan() {
        "—".into()
    } else {
        format!("{x:.2e}")
    }
}

fn short(msg: &str) -> String {
    let first: String = msg.chars().take(90).collect();
    if first.len() < msg.len() {
        format!("{first}…")
    } else {
        first
    }
}

/// Prints progress for one finished row.
fn progress(row: &Row) {
    eprintln!(
        "  {:<8} {:<22} tol {:.0e}: {} err_end {} max {} wall {:.3} ms rhs {} jac {} steps {} rej {}{}",
        row.crate_name,
        row.method,
        row.tol,
        row.status,
        sci(row.err_end),
        sci(row.err_max),
        row.wall_median_s * 1e3,
        row.work.rhs,
        row.work.jac,
        row.work.steps,
        row.work.rejected,
        if row.message.is_empty() {
            String::new()
        } else {
            format!(" [{}]", short(&row.message))
        }
    );
}

fn table(rows: &[Row], title: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "### {title}\n");
    let _ = writeln!(
        s,
        "| problem | tol | solver | method | error at t_end | max error (101 pts) | wall, median (ms) | rhs | Jacobians | JVPs | steps | rejected | Newton fails | note |"
    );
    let _ = writeln!(
        s,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for r in rows {
        let w = &r.work;
        let note = if r.status == "failed" {
            format!("**failed**: {}", short(&r.message))
        } else {
            short(&r.message)
        };
        let _ = writeln!(
            s,
            "| {} {} {} | {:.0e} | {} | {} | {} | {} | {:.3} | {} | {} | {} | {} | {} | {} | {} |",
            r.problem,
            r.param,
            r.potential,
            r.tol,
            r.crate_name,
            r.method,
            sci(r.err_end),
            sci(r.err_max),
            r.wall_median_s * 1e3,
            w.rhs,
            w.jac,
            w.jvp,
            w.steps,
            w.rejected,
            w.newton_fails,
            note
        );
    }
    s
}

/// A column of a pivot table: crate and method name as in [`Row`].
struct Col {
    label: &'static str,
    krate: &'static str,
    method: &'static str,
}

const fn col(label: &'static str, krate: &'static str, method: &'static str) -> Col {
    Col {
        label,
        krate,
        method,
    }
}

/// A failure in a pivot cell: where it happened, if the message says.
fn failure_cell(r: &Row) -> String {
    let at = r
        .message
        .split("at time = ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|t| {
            t.trim_end_matches(|c: char| !c.is_ascii_digit())
                .parse::<f64>()
                .ok()
        });
    match at {
        Some(t) if r.message.contains("nonlinear solver failures") => {
            format!("failed: Newton cap, t = {t:.2}")
        }
        Some(t) => format!("failed at t = {t:.2}"),
        None => "failed".into(),
    }
}

/// Rows `(param, tol)` × the given columns, one value per cell.
fn pivot(rows: &[Row], problem: &str, cols: &[Col], cell: &dyn Fn(&Row) -> String) -> String {
    let mut keys: Vec<(String, f64)> = Vec::new();
    for r in rows
        .iter()
        .filter(|r| r.problem == problem && r.status != "reference")
    {
        let key = (format!("{} {}", r.param, r.potential), r.tol);
        if !keys.contains(&key) {
            keys.push(key);
        }
    }
    let mut s = String::new();
    let _ = write!(s, "| {problem} | tol |");
    for c in cols {
        let _ = write!(s, " {} |", c.label);
    }
    s.push('\n');
    s.push_str("|---|---|");
    for _ in cols {
        s.push_str("---|");
    }
    s.push('\n');
    for (param, tol) in keys {
        let _ = write!(s, "| {param} | {tol:.0e} |");
        for c in cols {
            let found = rows.iter().find(|r| {
                r.problem == problem
                    && format!("{} {}", r.param, r.potential) == param
                    && r.tol == tol
                    && r.crate_name == c.krate
                    && r.method == c.method
                    && r.status != "reference"
            });
            let text = match found {
                None => "".into(),
                Some(r) if r.status == "failed" => failure_cell(r),
                Some(r) => cell(r),
            };
            let _ = write!(s, " {text} |");
        }
        s.push('\n');
    }
    s
}

const VISC_COLS: &[Col] = &[
    col("ours Radau IIA", "nonholo", "Radau IIA (radau5)"),
    col(
        "ours, full Newton",
        "nonholo",
        "Radau IIA (radau5), full Newton",
    ),
    col("diffsol BDF", "diffsol", "BDF (NDF, order 1-5)"),
    col("BDF, no cap", "diffsol", "BDF, no failure cap"),
    col("ESDIRK34", "diffsol", "ESDIRK34"),
    col("ESDIRK34, no cap", "diffsol", "ESDIRK34, no failure cap"),
    col("TR-BDF2", "diffsol", "TR-BDF2"),
    col("TR-BDF2, no cap", "diffsol", "TR-BDF2, no failure cap"),
];

const B_COLS: &[Col] = &[
    col("ours DOP853", "nonholo", "DOP853"),
    col("ode_solvers DOP853", "ode_solvers", "DOP853"),
];

/// The summary: pivot tables of error, time and work.
fn summary(visc: &[Row], b: &[Row], refs: &[Row]) -> String {
    let err = |r: &Row| sci(r.err_max);
    let err2 = |r: &Row| format!("{} / {}", sci(r.err_end), sci(r.err_max));
    let ms = |r: &Row| format!("{:.3}", r.wall_median_s * 1e3);
    let work = |r: &Row| {
        format!(
            "{} st, {} rej, {} NF, {} J",
            r.work.steps, r.work.rejected, r.work.newton_fails, r.work.jac
        )
    };
    let evals = |r: &Row| {
        format!(
            "{} ({} st, {} rej)",
            r.work.rhs, r.work.steps, r.work.rejected
        )
    };
    let mut s = String::new();
    for (problem, what) in [
        ("visc", "state (q, q̇), right-hand side and Jacobian by AD"),
        (
            "visc-body",
            "state (x, y, φ, u, w, ω), hand-written, forward-difference Jacobian",
        ),
        (
            "visc-adapted",
            "form = adapted, state (q, c, w), generic: right-hand side and Jacobian by AD",
        ),
    ] {
        let _ = writeln!(s, "#### `{problem}`: {what}\n");
        let _ = writeln!(
            s,
            "Largest error over the 101 samples and t_end, ‖y − y_ref‖∞ in (q, q̇):\n"
        );
        s.push_str(&pivot(visc, problem, VISC_COLS, &err));
        let _ = writeln!(s, "\nWall time, median of the repeats (ms):\n");
        s.push_str(&pivot(visc, problem, VISC_COLS, &ms));
        let _ = writeln!(
            s,
            "\nWork: accepted steps, rejected steps, Newton failures (NF), Jacobians (J):\n"
        );
        s.push_str(&pivot(visc, problem, VISC_COLS, &work));
        s.push('\n');
    }
    let _ = writeln!(s, "#### B by DOP853\n");
    let _ = writeln!(s, "Error at t_end / largest error over the 101 samples:\n");
    s.push_str(&pivot(b, "B", B_COLS, &err2));
    let _ = writeln!(s, "\nWall time, median of the repeats (ms):\n");
    s.push_str(&pivot(b, "B", B_COLS, &ms));
    let _ = writeln!(s, "\nRight-hand-side evaluations (steps, rejected):\n");
    s.push_str(&pivot(b, "B", B_COLS, &evals));
    s.push('\n');
    let _ = writeln!(s, "#### References\n");
    let _ = writeln!(
        s,
        "| problem | run | tol | max distance to the primary reference | steps | rejected | Newton fails | wall (ms) | note |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    for r in refs {
        let _ = writeln!(
            s,
            "| {} {} {} | {} {} | {:.0e} | {} | {} | {} | {} | {:.1} | {} |",
            r.problem,
            r.param,
            r.potential,
            r.crate_name,
            r.method,
            r.tol,
            if r.status == "failed" {
                "failed".into()
            } else {
                sci(r.err_max)
            },
            r.work.steps,
            r.work.rejected,
            r.work.newton_fails,
            r.wall_median_s * 1e3,
            short(&r.message)
        );
    }
    s
}

/// A reference by one of our methods at `tol`, kept as a continuous extension.
fn our_reference(
    problem: &Problem,
    method: Method,
    tol: f64,
    g: &[f64],
) -> Result<Reference, String> {
    reference_by(problem, Solver::Ours(method), tol, g)
}

/// A reference by one of our solvers at `tol`, kept as a continuous extension.
fn reference_by(
    problem: &Problem,
    solver: Solver,
    tol: f64,
    g: &[f64],
) -> Result<Reference, String> {
    let method = solver.method_name();
    match solver.run(problem, tol, g, true) {
        Ok(out) => {
            let map = std::cell::RefCell::new(problem.to_cartesian()?);
            out.dense
                .map(|dense| Reference::Dense { dense, map })
                .ok_or_else(|| "the reference run kept no continuous extension".to_string())
        }
        Err(f) => Err(format!(
            "reference {method} at {tol:e} failed: {}",
            f.message
        )),
    }
}

const BDF: Solver = Solver::Diffsol {
    method: DiffsolMethod::Bdf,
    max_fails: DIFFSOL_DEFAULT_CAP,
};
const ESDIRK34: Solver = Solver::Diffsol {
    method: DiffsolMethod::Esdirk34,
    max_fails: DIFFSOL_DEFAULT_CAP,
};
const TR_BDF2: Solver = Solver::Diffsol {
    method: DiffsolMethod::TrBdf2,
    max_fails: DIFFSOL_DEFAULT_CAP,
};

/// `visc(k)` in one of its states: `visc` (`(q, q̇)`, AD), `visc-body`
/// (body frame, hand-written), `visc-adapted` (the generic adapted form, AD).
fn visc_problem(scene: &nonholo_scenes::Sleigh, k: f64, name: &str) -> Problem {
    Problem {
        name: name.into(),
        scene: scene.clone(),
        potential: "paper",
        formulation: match name {
            "visc-body" => Formulation::ViscBody { k },
            "visc-adapted" => Formulation::ViscAdapted { k },
            _ => Formulation::Visc { k },
        },
        phi: 0.2,
        u: 2.0,
        omega: 0.7,
        t_end: 5.0,
    }
}

/// Marks a row as a reference run.
fn as_reference(row: Row) -> Row {
    Row {
        status: if row.status == "ok" {
            "reference"
        } else {
            row.status
        },
        ..row
    }
}

fn visc_part(args: &Args, rows: &mut Vec<Row>, refs: &mut Vec<Row>) -> Result<(), String> {
    let ks: &[f64] = if args.quick {
        &[1e2, 1e6]
    } else {
        &[1e2, 1e4, 1e6, 1e8]
    };
    let tols: &[f64] = if args.quick {
        &[1e-6]
    } else {
        &[1e-4, 1e-6, 1e-8, 1e-10]
    };
    let g = grid(5.0, 100);
    let scene = sleigh(0.4, 0.3, "paper").map_err(|e| e.to_string())?;
    for &k in ks {
        let problem = visc_problem(&scene, k, "visc");
        let body = visc_problem(&scene, k, "visc-body");
        let adapted = visc_problem(&scene, k, "visc-adapted");
        eprintln!("visc k = {k:e}: reference Radau IIA at 1e-13");
        let reference = our_reference(&problem, Method::Radau5, 1e-13, &g)?;
        // Reference runs: no estimate of the reference's error yet.
        let against = Against {
            grid: &g,
            reference: &reference,
            name: "ours radau5 @1e-13",
            ref_err: f64::NAN,
        };
        // The primary reference's own work (its errors are against itself).
        let row = measure(&problem, Solver::Ours(Method::Radau5), 1e-13, against, 1);
        progress(&row);
        refs.push(Row {
            message: "primary reference (errors against itself)".into(),
            ..as_reference(row)
        });
        // Second references, each measured against the first: the same
        // motion in body-frame velocities (hand-written, Radau at 1e-13),
        // our DOP853 at 1e-13 where the stiffness allows, diffsol's BDF at
        // the tightest tolerance at which it finishes.
        let mut distances = Vec::new();
        let mut second = |row: Row, refs: &mut Vec<Row>| {
            progress(&row);
            if row.status == "ok" {
                distances.push(row.err_max);
            }
            refs.push(as_reference(row));
        };
        eprintln!("  second reference: Radau IIA at 1e-13 in body-frame velocities");
        second(
            measure(&body, Solver::Ours(Method::Radau5), 1e-13, against, 1),
            refs,
        );
        eprintln!("  second reference: Radau IIA at 1e-13 in the adapted form (AD)");
        second(
            measure(&adapted, Solver::Ours(Method::Radau5), 1e-13, against, 1),
            refs,
        );
        if k <= 1e6 {
            eprintln!("  second reference: our DOP853 at 1e-13");
            second(
                measure(&problem, Solver::Ours(Method::Dop853), 1e-13, against, 1),
                refs,
            );
        }
        'bdf: for cap in [BDF, BDF.uncapped()] {
            for tight in [1e-12, 1e-11, 1e-10] {
                eprintln!(
                    "  second reference: diffsol {} at {tight:e}",
                    cap.method_name()
                );
                let row = measure(&problem, cap, tight, against, 1);
                let ok = row.status == "ok";
                second(row, refs);
                if ok {
                    break 'bdf;
                }
            }
        }
        let against = Against {
            ref_err: distances.iter().copied().fold(f64::NAN, f64::min),
            ..against
        };
        // Timed interleaved: every solver once per round, diffsol's methods
        // that give up at their failure cap followed by the same without
        // the cap.
        let capped_out = |solver: Solver, row: &Row| {
            (row.status == "failed" && row.message.contains("nonlinear solver failures"))
                .then(|| solver.uncapped())
        };
        for &tol in tols {
            for p in [&problem, &body, &adapted] {
                for row in measure_all_retrying(
                    p,
                    &[
                        Solver::Ours(Method::Radau5),
                        Solver::OursFullNewton,
                        BDF,
                        ESDIRK34,
                        TR_BDF2,
                    ],
                    capped_out,
                    tol,
                    against,
                    args.repeats,
                ) {
                    progress(&row);
                    rows.push(row);
                }
            }
        }
    }
    Ok(())
}

fn b_part(args: &Args, rows: &mut Vec<Row>, refs: &mut Vec<Row>) -> Result<(), String> {
    let tols: &[f64] = if args.quick {
        &[1e-6]
    } else {
        &[1e-6, 1e-9, 1e-12]
    };
    let g = grid(20.0, 100);
    for a in [0.0, 0.4] {
        for potential in ["paper", "com"] {
            let scene = sleigh(a, 0.3, potential).map_err(|e| e.to_string())?;
            let problem = Problem {
                name: "B".into(),
                scene,
                potential,
                formulation: Formulation::B,
                phi: 0.2,
                u: 2.0,
                omega: 0.7,
                t_end: 20.0,
            };
            eprintln!("B a = {a}, {potential}");
            let (reference, ref_name, ref_err) = if a == 0.0 {
                let closed = Reference::Closed(problem.clone());
                // Our tight run against the closed form, for the record.
                let against = Against {
                    grid: &g,
                    reference: &closed,
                    name: "closed form",
                    ref_err: 0.0,
                };
                let row = measure(&problem, Solver::Ours(Method::Dop853), 1e-13, against, 1);
                progress(&row);
                refs.push(as_reference(row));
                (closed, "closed form", 0.0)
            } else {
                let first = our_reference(&problem, Method::Dop853, 1e-13, &g)?;
                let second = our_reference(&problem, Method::Radau5, 1e-13, &g)?;
                let d = reference_distance(&first, &second, &g, 6);
                let against = Against {
                    grid: &g,
                    reference: &first,
                    name: "ours dop853 @1e-13",
                    ref_err: f64::NAN,
                };
                let row = measure(&problem, Solver::Ours(Method::Radau5), 1e-13, against, 1);
                progress(&row);
                refs.push(as_reference(row));
                (first, "ours dop853 @1e-13", d)
            };
            let against = Against {
                grid: &g,
                reference: &reference,
                name: ref_name,
                ref_err,
            };
            for &tol in tols {
                for row in measure_all(
                    &problem,
                    &[Solver::Ours(Method::Dop853), Solver::OdeSolversDop853],
                    tol,
                    against,
                    args.repeats,
                ) {
                    progress(&row);
                    rows.push(row);
                }
            }
        }
    }
    Ok(())
}

/// `/proc/loadavg`'s three averages (empty where there is none).
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .unwrap_or_default()
        .split_whitespace()
        .take(3)
        .collect::<Vec<_>>()
        .join(" ")
}

/// The Jacobian-reuse study: RADAU5 refreshes its Jacobian after every
/// accepted step whose Newton contraction exceeded θ = 0.001; on `visc` in
/// the adapted form that is nearly every step. Our Radau IIA at three
/// thresholds, with the Hermite continuous extension at two of them (at
/// θ ≤ 0.1 also with a Newton stopping test ten times tighter than
/// RADAU5's), and diffsol's BDF, every solver of a case timed once per
/// round, on the adapted form (AD Jacobian, ~11 right-hand sides)
/// and the body frame (forward differences), k = 1e4 … 1e8, errors against
/// our Radau IIA at 1e-13 with the Hermite extension on the adapted form
/// (its distance to the same at 3e-14 in `ref_err`); `reuse.csv` has every
/// run, `reuse-matched.csv` the times at matched error.
fn reuse_study(args: &Args) -> Result<(), String> {
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    let tols: &[f64] = if args.quick {
        &[1e-6]
    } else {
        &[1e-4, 1e-6, 1e-8, 1e-10]
    };
    let ks: &[f64] = if args.quick { &[1e6] } else { &[1e4, 1e6, 1e8] };
    let g = grid(5.0, 100);
    let scene = sleigh(0.4, 0.3, "paper").map_err(|e| e.to_string())?;
    let load_before = load_average();
    let mut csv = String::from(Row::HEADER);
    csv.push('\n');
    for &k in ks {
        let adapted = visc_problem(&scene, k, "visc-adapted");
        let body = visc_problem(&scene, k, "visc-body");
        // The collocation polynomial of Radau IIA at 1e-13 is 4e-10 off
        // between its step points; the Hermite extension is not (docs/peers.md).
        eprintln!("visc k = {k:e}: reference Radau IIA at 1e-13 (Hermite), checked at 3e-14");
        let reference = reference_by(&adapted, Solver::OursHermite(None), 1e-13, &g)?;
        let check = reference_by(&adapted, Solver::OursHermite(None), 3e-14, &g)?;
        let against = Against {
            grid: &g,
            reference: &reference,
            name: "ours radau5 @1e-13, Hermite dense output, adapted form",
            ref_err: reference_distance(&reference, &check, &g, 6),
        };
        let solvers = [
            Solver::Ours(Method::Radau5),
            Solver::OursReuse(Reuse::Hundredth),
            Solver::OursReuse(Reuse::Tenth),
            Solver::OursHermite(None),
            Solver::OursHermite(Some(Reuse::Tenth)),
            Solver::OursTightNewton,
            BDF,
        ];
        for &tol in tols {
            for p in [&adapted, &body] {
                // Timed interleaved: every solver once per round.
                for row in measure_all(p, &solvers, tol, against, args.repeats) {
                    progress(&row);
                    csv.push_str(&row.csv());
                    csv.push('\n');
                }
            }
        }
    }
    let path = args.out.join("reuse.csv");
    write_atomic(&path, &csv)?;
    let matched = nonholo_bench::page::matched_csv(&path)?;
    write_atomic(&args.out.join("reuse-matched.csv"), &matched)?;
    eprintln!(
        "wrote {} and reuse-matched.csv (load average before / after: {load_before} / {})",
        path.display(),
        load_average()
    );
    println!("{matched}");
    // The page shows the study beside the main comparison, where that has
    // been run into the same directory.
    if args.out.join("peers.csv").is_file() {
        nonholo_bench::page::write_page(&args.out)?;
    }
    Ok(())
}

fn run() -> Result<(), String> {
    let args = parse_args()?;
    if args.page {
        return nonholo_bench::page::write_page(&args.out);
    }
    if args.reuse {
        return reuse_study(&args);
    }
    // Fail before the runs, not after them, if the results cannot be written.
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    let load_before = load_average();
    let (mut visc_rows, mut b_rows, mut refs) = (Vec::new(), Vec::new(), Vec::new());
    visc_part(&args, &mut visc_rows, &mut refs)?;
    b_part(&args, &mut b_rows, &mut refs)?;

    let mut csv = String::from(Row::HEADER);
    csv.push('\n');
    for r in refs.iter().chain(&visc_rows).chain(&b_rows) {
        csv.push_str(&r.csv());
        csv.push('\n');
    }
    let revision = match nonholo_lab::experiment::manifest::git_revision(&args.out) {
        (Some(rev), Some(true)) => format!("{rev} with uncommitted changes"),
        (Some(rev), _) => rev,
        (None, _) => "unknown (not run in a git checkout)".into(),
    };
    let mut md = format!(
        "Code: git revision {revision}. Load average before / after the run: {load_before} / {}; {} timed repeats per case.\n\n## Summary\n\n",
        load_average(),
        args.repeats
    );
    md.push_str(&summary(&visc_rows, &b_rows, &refs));
    md.push_str("\n## Every run\n\n");
    md.push_str(&table(
        &visc_rows,
        "visc(k) on the sleigh, t ∈ [0, 5]: our Radau IIA against diffsol (rtol = atol = tol)",
    ));
    md.push('\n');
    md.push_str(&table(
        &b_rows,
        "B on the sleigh, t ∈ [0, 20]: our DOP853 against ode_solvers' DOP853 (rtol = atol = tol)",
    ));
    let csv_path = args.out.join("peers.csv");
    write_atomic(&csv_path, &csv)?;
    write_atomic(&args.out.join("peers.md"), &md)?;
    nonholo_bench::page::write_page(&args.out)?;
    // The summary part (every run is in the files).
    let summary_part = md.split("\n## Every run").next().unwrap_or(&md);
    println!("{summary_part}");
    eprintln!(
        "wrote {}, peers.md (every run in both) and index.html",
        csv_path.display()
    );
    Ok(())
}

fn main() -> ExitCode {
    nonholo_bench::report_main(run)
}
