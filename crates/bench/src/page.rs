//! `results/peers/index.html`: the peer comparison as a result page —
//! error against wall time for every solver on each problem (one figure per
//! problem, stiffness and potential, drawn from `peers.csv`), then the
//! tables of `peers.md` rendered as HTML.
//!
//! The page is built from the two files the `peers` binary writes, so it can
//! be rebuilt without running the peers again (`peers --page`). It also
//! writes `matched.csv`: every solver's wall time at matched errors
//! ([`MATCHED_ERRORS`]), interpolated (as a power law) between the tolerances
//! that bracket each, so that solvers are compared at the same accuracy and not only at
//! the same tolerance (which buys different errors from different methods).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nonholo_lab::plot::{LinePlot, Series, line_plot};
use nonholo_lab::table::escape;

/// One row of `peers.csv`, the fields the figures use.
#[derive(Debug, Clone, PartialEq)]
struct Run {
    problem: String,
    potential: String,
    param: String,
    solver: String,
    tol: f64,
    status: String,
    err_max: f64,
    wall_median_s: f64,
}

fn read_runs(csv_path: &Path) -> Result<Vec<Run>, String> {
    let mut reader = csv::Reader::from_path(csv_path)
        .map_err(|e| format!("cannot read {}: {e}", csv_path.display()))?;
    let header = reader
        .headers()
        .map_err(|e| format!("{}: {e}", csv_path.display()))?
        .clone();
    let column = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| format!("{}: no column `{name}`", csv_path.display()))
    };
    let [
        problem,
        potential,
        param,
        krate,
        method,
        tol,
        status,
        err_max,
        wall,
    ] = [
        "problem",
        "potential",
        "param",
        "crate",
        "method",
        "tol",
        "status",
        "err_max",
        "wall_median_s",
    ]
    .map(column);
    let (problem, potential, param, krate, method) =
        (problem?, potential?, param?, krate?, method?);
    let (tol, status, err_max, wall) = (tol?, status?, err_max?, wall?);
    let mut runs = Vec::new();
    for (line, record) in reader.records().enumerate() {
        let r = record.map_err(|e| format!("{}: {e}", csv_path.display()))?;
        let number = |i: usize| -> Result<f64, String> {
            r[i].parse().map_err(|_| {
                format!(
                    "{} row {}: `{}` is not a number",
                    csv_path.display(),
                    line + 2,
                    &r[i]
                )
            })
        };
        runs.push(Run {
            problem: r[problem].to_string(),
            potential: r[potential].to_string(),
            param: r[param].to_string(),
            solver: format!("{} {}", &r[krate], &r[method]),
            tol: number(tol)?,
            status: r[status].to_string(),
            err_max: number(err_max)?,
            wall_median_s: number(wall)?,
        });
    }
    Ok(runs)
}

/// The errors at which [`matched`] compares the solvers.
pub const MATCHED_ERRORS: [f64; 3] = [1e-4, 1e-6, 1e-8];

/// `(problem, potential, param)`: one problem of the comparison.
type Problem = (String, String, String);

/// Wall time (s) of every solver at each of [`MATCHED_ERRORS`], per
/// problem: the completed runs in tolerance order, the largest error over
/// the samples, interpolated by [`crate::timing::at_error`]; `None` where
/// no two successive tolerances bracket the error.
fn matched(runs: &[Run]) -> BTreeMap<Problem, BTreeMap<String, [Option<f64>; 3]>> {
    completed(runs)
        .into_iter()
        .map(|(problem, solvers)| {
            let times = solvers
                .into_iter()
                .map(|(solver, rs)| {
                    let pts: Vec<(f64, f64)> =
                        rs.iter().map(|r| (r.err_max, r.wall_median_s)).collect();
                    (
                        solver,
                        MATCHED_ERRORS.map(|e| crate::timing::at_error(&pts, e)),
                    )
                })
                .collect();
            (problem, times)
        })
        .collect()
}

/// The completed runs by problem and solver, each solver's in tolerance
/// order (loosest first).
fn completed(runs: &[Run]) -> BTreeMap<Problem, BTreeMap<String, Vec<&Run>>> {
    let mut groups: BTreeMap<Problem, BTreeMap<String, Vec<&Run>>> = BTreeMap::new();
    for r in runs.iter().filter(|r| r.status == "ok") {
        groups
            .entry((r.problem.clone(), r.potential.clone(), r.param.clone()))
            .or_default()
            .entry(r.solver.clone())
            .or_default()
            .push(r);
    }
    for solvers in groups.values_mut() {
        for rs in solvers.values_mut() {
            rs.sort_by(|a, b| b.tol.total_cmp(&a.tol));
        }
    }
    groups
}

/// `matched.csv` (one row per problem, solver and reached error) and the
/// HTML tables of the same, one per error.
fn matched_outputs(runs: &[Run]) -> (String, String) {
    // The tables alone: the caller heads them and names their CSV file.
    let m = matched(runs);
    let mut w = csv::Writer::from_writer(Vec::new());
    let _ = w.write_record(["problem", "potential", "param", "solver", "error", "wall_s"]);
    for ((problem, potential, param), solvers) in &m {
        for (solver, times) in solvers {
            for (e, t) in MATCHED_ERRORS.iter().zip(times) {
                if let Some(t) = t {
                    let (e, t) = (format!("{e:e}"), format!("{t:.6e}"));
                    let _ = w.write_record([problem, potential, param, solver, &e, &t]);
                }
            }
        }
    }
    let csv = w
        .into_inner()
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .unwrap_or_default();
    let mut html = String::new();
    for (k, e) in MATCHED_ERRORS.iter().enumerate() {
        let solvers: std::collections::BTreeSet<&String> =
            m.values().flat_map(|s| s.keys()).collect();
        let _ = write!(
            html,
            "<table><caption>error {e:.0e}</caption><tr><th>problem</th>"
        );
        for s in &solvers {
            let _ = write!(html, "<th>{}</th>", escape(s));
        }
        html.push_str("</tr>\n");
        for ((problem, potential, param), times) in &m {
            let _ = write!(
                html,
                "<tr><td>{}</td>",
                escape(&format!("{problem} {param} {potential}"))
            );
            for s in &solvers {
                let cell = match times.get(*s).and_then(|t| t[k]) {
                    Some(t) => format!("{:.3}", t * 1e3),
                    None => "—".into(),
                };
                let _ = write!(html, "<td>{cell}</td>");
            }
            html.push_str("</tr>\n");
        }
        html.push_str("</table>\n");
    }
    (csv, html)
}

/// Appends a figure element per plot (paths under `dir`, with captions).
fn push_figures(h: &mut String, dir: &Path, plots: &[(PathBuf, String)]) {
    for (p, caption) in plots {
        let rel = p.strip_prefix(dir).unwrap_or(p).display().to_string();
        let stem = p
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default();
        h.push_str(&nonholo_lab::experiment::page::figure_html(
            &rel, &stem, caption,
        ));
    }
}

/// What the matched-error tables hold.
const MATCHED_INTRO: &str = "Wall time (ms, median of the repeats) at which each solver \
     reaches the same largest error over the samples, interpolated as a power law (linearly in log \
     time against log error) between the two successive tolerances whose errors bracket it; \
     “—”: no two tolerances bracket it (not reached, or the error did not fall monotonically). \
     Equal tolerances buy different errors from different methods; this is the comparison at \
     equal accuracy.";

/// The figures: per (problem, potential, parameter), the largest error over
/// the samples against the median wall time, one line per solver through its
/// tolerances. Only completed runs are drawn (references and failures are in
/// the tables). Returns the PNG paths with their captions.
fn figures(
    runs: &[Run],
    dir: &Path,
    prefix: &str,
    label: fn(String) -> String,
) -> Result<Vec<(PathBuf, String)>, String> {
    let mut files = Vec::new();
    for ((problem, potential, param), solvers) in completed(runs) {
        let series = solvers
            .into_iter()
            .map(|(solver, rs)| Series {
                label: label(solver),
                x: rs.iter().map(|r| r.wall_median_s).collect(),
                y: rs.iter().map(|r| r.err_max).collect(),
                pen: None,
            })
            .collect();
        let plot = LinePlot {
            verticals: Vec::new(),
            title: format!("{problem}, {param}, {potential} potential: error against wall time"),
            x_label: "wall time, median of the repeats [s]".into(),
            y_label: "largest error over the samples [SI]".into(),
            log_x: true,
            log_y: true,
            equal_aspect: false,
            series,
            y_range: None,
        };
        let stem = dir
            .join("plots")
            .join(format!("wp-{prefix}{problem}-{param}-{potential}"));
        let caption = format!(
            "{problem} at {param} with the {potential} potential: the largest error over the \
             samples against the median wall time, each solver through its tolerances \
             (lower left is better)."
        );
        let written = line_plot(&plot, &stem)?;
        files.extend(
            written
                .into_iter()
                .filter(|p| p.extension().is_some_and(|e| e == "png"))
                .map(|p| (p, caption.clone())),
        );
    }
    Ok(files)
}

/// The matched-error table (`matched.csv`'s format) of the runs in the
/// CSV file `runs` (`peers.csv`'s format), for another study than the
/// page's.
pub fn matched_csv(runs: &Path) -> Result<String, String> {
    Ok(matched_outputs(&read_runs(runs)?).0)
}

/// Writes `dir/index.html` (and `dir/plots/`) from `dir/peers.csv` and
/// `dir/peers.md`, then the list of result pages in `dir`'s parent if that
/// is a `results` directory.
pub fn write_page(dir: &Path) -> Result<(), String> {
    let runs = read_runs(&dir.join("peers.csv"))?;
    let md_path = dir.join("peers.md");
    let md = std::fs::read_to_string(&md_path)
        .map_err(|e| format!("cannot read {}: {e}", md_path.display()))?;
    let plots = figures(&runs, dir, "", |s| s)?;
    let (matched_csv, matched_html) = matched_outputs(&runs);
    let matched_path = dir.join("matched.csv");
    nonholo_lab::record::write_atomic(&matched_path, matched_csv.as_bytes())
        .map_err(|e| format!("cannot write {}: {e}", matched_path.display()))?;

    let title = "Peers: our integrators beside diffsol and ode_solvers";
    let mut h = format!(
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{title}</title>\n\
         <style>body{{font-family:sans-serif;max-width:1200px;margin:auto;padding:1em}}\
         table{{border-collapse:collapse;font-size:0.8em}}td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}\
         figure{{margin:1.5em 0}}img{{max-width:100%}}figcaption{{color:#333}}</style></head><body>\n<h1>{title}</h1>\n"
    );
    let _ = writeln!(
        h,
        "<p><b>Reproduce:</b> <code>cargo run --release -p nonholo-bench --features peers --bin peers</code> \
         (<code>--page</code> rebuilds this page from the stored files without running anything).</p>"
    );
    let docs = dir
        .parent()
        .and_then(Path::parent)
        .map(|r| r.join("docs/peers.md"));
    if let Some(d) = docs.filter(|d| d.is_file()) {
        let _ = writeln!(
            h,
            "<p>What is compared and what it shows: <a href=\"{}\">docs/peers.md</a>.</p>",
            escape(&nonholo_lab::experiment::cli::relative(dir, &d))
        );
    }
    let _ = writeln!(
        h,
        "<p>Other experiments: <a href=\"../index.html\">every result page</a>. \
         Files: <a href=\"peers.csv\">peers.csv</a>, <a href=\"peers.md\">peers.md</a>, \
         <a href=\"matched.csv\">matched.csv</a>.</p>"
    );
    let _ = writeln!(
        h,
        "<p>Every figure: one solver per line through its tolerances; errors are the largest over the \
         101 output samples and t_end against the problem's reference (dense output where the solver \
         interpolates); runs that failed are left out of the figures and named in the tables. Colours \
         tell solvers apart here (every line is the same formulation).</p>"
    );
    push_figures(&mut h, dir, &plots);
    let _ = writeln!(
        h,
        "<h2>At matched error</h2>\n<p>{MATCHED_INTRO} (<a href=\"matched.csv\">matched.csv</a>)</p>"
    );
    h.push_str(&matched_html);
    // The Jacobian-reuse study (`peers --reuse`), where it has been run.
    let reuse = dir.join("reuse.csv");
    if reuse.is_file() {
        let runs = read_runs(&reuse)?;
        let _ = writeln!(
            h,
            "<h2>The Jacobian-reuse study</h2>\n<p>Our Radau IIA with RADAU5's Jacobian-reuse \
             threshold and laxer ones, through the collocation polynomial and the Hermite extension, \
             beside diffsol's BDF, on <code>visc</code> in the adapted form and the body frame; every \
             solver of a case timed once per round (<code>peers --reuse</code>; \
             <a href=\"reuse.csv\">reuse.csv</a>, <a href=\"reuse-matched.csv\">reuse-matched.csv</a>; \
             what it shows: docs/peers.md, “Jacobian reuse”).</p>"
        );
        // Seven lines of one formulation: the legend names only what
        // differs (ours is Radau IIA by RADAU5's scheme throughout).
        let short = |s: String| {
            let s = s
                .replace("nonholo Radau IIA (radau5)", "ours")
                .replace("Hermite dense output", "Hermite")
                .replace("ours, ", "ours: ");
            if s == "ours" {
                "ours: RADAU5's settings".to_string()
            } else {
                s
            }
        };
        push_figures(&mut h, dir, &figures(&runs, dir, "reuse-", short)?);
        let _ = writeln!(h, "<h3>At matched error</h3>\n<p>{MATCHED_INTRO}</p>");
        h.push_str(&matched_outputs(&runs).1);
    }
    if !md.contains("git revision") {
        h.push_str(
            "<p>The code revision these runs were made with was not recorded (peers.md \
             predates it); run the peers again to record it.</p>\n",
        );
    }
    let mut body = String::new();
    let options = pulldown_cmark::Options::ENABLE_TABLES;
    pulldown_cmark::html::push_html(&mut body, pulldown_cmark::Parser::new_ext(&md, options));
    let _ = writeln!(
        h,
        "<div style=\"overflow-x:auto\">{body}</div>\n</body></html>"
    );
    let path = dir.join("index.html");
    nonholo_lab::record::write_atomic(&path, h.as_bytes())
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    // The list of result pages beside it, where it is one of them.
    match dir.parent() {
        Some(root) if root.file_name().is_some_and(|n| n == "results") => {
            nonholo_lab::experiment::page::write_index(root)
        }
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn page_has_a_figure_per_problem_and_the_tables() {
        let root = std::env::temp_dir()
            .join(format!("nonholo-peers-page-{}", std::process::id()))
            .join("results");
        let dir = root.join("peers");
        std::fs::create_dir_all(&dir).unwrap();
        let header = "problem,potential,param,t_end,crate,method,tol,status,err_end,err_max,ref_err,\
                      reference,wall_median_s,wall_min_s,repeats,rhs_evals,dense_rhs_evals,jac_evals,\
                      jvp_evals,steps,rejected,newton_iters,newton_fails,lu,message";
        let rows = [
            "visc,paper,k=1e2,5,nonholo,Radau IIA (radau5),1e-13,reference,0e0,0e0,NaN,ours,1e-3,1e-3,1,1,0,1,0,1,0,1,0,1,",
            "visc,paper,k=1e2,5,nonholo,Radau IIA (radau5),1e-6,ok,1e-6,2e-6,1e-12,ours,1e-4,1e-4,3,1,0,1,0,1,0,1,0,1,",
            "visc,paper,k=1e2,5,nonholo,Radau IIA (radau5),1e-8,ok,1e-8,2e-8,1e-12,ours,2e-4,2e-4,3,1,0,1,0,1,0,1,0,1,",
            "visc,paper,k=1e2,5,diffsol,\"BDF (NDF, cap)\",1e-6,failed,NaN,NaN,1e-12,ours,1e-4,1e-4,3,1,0,1,0,1,0,1,0,1,Newton cap",
            "B,paper,a=0.4,20,ode_solvers,DOP853,1e-8,ok,1e-9,2e-9,1e-12,ours,1e-4,1e-4,3,1,0,0,0,1,0,0,0,0,",
        ];
        std::fs::write(
            dir.join("peers.csv"),
            format!("{header}\n{}\n", rows.join("\n")),
        )
        .unwrap();
        std::fs::write(
            dir.join("peers.md"),
            "## Summary\n\n| a | b |\n|---|---|\n| 1 | 2 |\n",
        )
        .unwrap();
        write_page(&dir).unwrap();
        let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
        // One figure per (problem, param, potential) with completed runs.
        assert_eq!(html.matches("<img ").count(), 2, "{html}");
        assert!(dir.join("plots/wp-visc-k=1e2-paper.png").is_file());
        assert!(dir.join("plots/wp-B-a=0.4-paper.png").is_file());
        // The markdown tables are HTML tables.
        assert!(
            html.contains("<table>") && html.contains("<td>2</td>"),
            "{html}"
        );
        // At matched error: Radau's errors 2e-6 and 2e-8 bracket 1e-6 only
        // (1e-4 is not reached, 1e-8 not either); the rest have one run.
        let matched = std::fs::read_to_string(dir.join("matched.csv")).unwrap();
        let lines: Vec<&str> = matched.lines().collect();
        assert_eq!(lines.len(), 2, "{matched}");
        assert!(
            lines[1].starts_with("visc,paper,k=1e2,nonholo Radau IIA (radau5),1e-6,"),
            "{matched}"
        );
        // power law (linear in log-log): 1e-6 is log10(2e-6/1e-6)/2 of the way from 1e-4 s to 2e-4 s.
        let t: f64 = lines[1].rsplit(',').next().unwrap().parse().unwrap();
        let want = (1e-4f64.ln() + (2f64.log10() / 2.0) * 2f64.ln()).exp();
        assert!((t / want - 1.0).abs() < 1e-5, "{t} against {want}");
        assert!(
            html.contains("At matched error") && html.contains("<td>—</td>"),
            "{html}"
        );
        // peers.md without a recorded revision: the page says so.
        assert!(html.contains("was not recorded"), "{html}");
        assert!(!html.contains("Jacobian-reuse study"), "{html}");
        // With a reuse study beside it (the same format), its section: a
        // figure per case with the short legend, and its matched tables.
        std::fs::write(
            dir.join("reuse.csv"),
            format!("{header}\n{}\n", rows[1..3].join("\n")),
        )
        .unwrap();
        write_page(&dir).unwrap();
        let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
        assert!(html.contains("<h2>The Jacobian-reuse study</h2>"), "{html}");
        assert_eq!(html.matches("<img ").count(), 3, "{html}");
        assert!(dir.join("plots/wp-reuse-visc-k=1e2-paper.svg").is_file());
        let svg = std::fs::read_to_string(dir.join("plots/wp-reuse-visc-k=1e2-paper.svg")).unwrap();
        assert!(svg.contains("ours: RADAU5") && !svg.contains("nonholo Radau"));
        assert_eq!(
            html.matches("<h3>At matched error</h3>").count(),
            1,
            "{html}"
        );
        // The list of result pages beside it names the page by its title.
        let index = std::fs::read_to_string(root.join("index.html")).unwrap();
        assert!(index.contains("peers/index.html") && index.contains("Peers: our integrators"));
        std::fs::remove_dir_all(root.parent().unwrap()).unwrap();
    }

    #[test]
    fn a_missing_column_is_named() {
        let dir = std::env::temp_dir().join(format!("nonholo-peers-col-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("peers.csv"), "problem,potential\nvisc,paper\n").unwrap();
        std::fs::write(dir.join("peers.md"), "x").unwrap();
        let e = write_page(&dir).unwrap_err();
        assert!(e.contains("no column `param`"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
