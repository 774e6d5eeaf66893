//! `nonholo compare A B`: whether two results directories hold the same
//! results. For a change of code that should not move any result, a
//! regeneration on another machine, or CI's check that the committed
//! results are what the code computes.
//!
//! Compared: every table (`*.csv`) at the top of each experiment directory
//! found in both, cell by cell — except what depends on the machine:
//! `timing.csv` and the columns whose names begin with `wall_` (wall times
//! of work-precision and boundary-value runs). Cells are equal if their
//! text is, or, with `rtol > 0`, if both are numbers within `rtol` of each
//! other (relative to the larger magnitude). Subdirectories (`references/`,
//! `trajectories/`, `plots/`) and JSON files are not compared: the tables
//! hold the numbers the figures and claims are drawn from.
//!
//! `A` and `B` are either two results directories (`results/`: their
//! experiment directories with the same name are paired; an experiment's
//! directory, one with a `manifest.json`, found in only one of them is a
//! difference, and other directories with tables, such as the benchmarks'
//! outputs, are listed, not compared) or two experiment directories.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use clap::Args;

use crate::CliError;

#[derive(Debug, Clone, Args)]
pub struct CompareArgs {
    /// A results directory (or one experiment's directory).
    pub a: PathBuf,
    /// The results directory to compare with it (or an experiment's).
    pub b: PathBuf,
    /// Numbers within this relative difference count as equal (default 0:
    /// the same text).
    #[arg(long, default_value_t = 0.0)]
    pub rtol: f64,
}

/// The machine-dependent columns, left out of the comparison.
pub fn is_timing_column(name: &str) -> bool {
    name.starts_with("wall_")
}

/// One cell that differs.
#[derive(Debug, Clone, PartialEq)]
pub struct Difference {
    /// `<experiment>/<table>`.
    pub table: String,
    /// Data row, from 1.
    pub row: usize,
    /// The row's `point` and `label` where the table has them.
    pub key: String,
    pub column: String,
    pub a: String,
    pub b: String,
}

/// What a comparison found.
#[derive(Debug, Default)]
pub struct Report {
    /// Experiments compared (found in both).
    pub experiments: Vec<String>,
    /// Experiments found in only one directory (not compared).
    pub only_in_a: Vec<String>,
    pub only_in_b: Vec<String>,
    /// Tables compared and cells compared in them.
    pub tables: usize,
    pub cells: usize,
    /// Structural differences: a table missing on one side, another
    /// header, another number of rows.
    pub mismatches: Vec<String>,
    pub differences: Vec<Difference>,
}

impl Report {
    pub fn equal(&self) -> bool {
        self.mismatches.is_empty() && self.differences.is_empty()
    }

    /// The largest relative difference among numeric cells that differ.
    pub fn largest_relative(&self) -> Option<f64> {
        self.differences
            .iter()
            .filter_map(|d| relative(&d.a, &d.b))
            .fold(None, |m, r| Some(m.map_or(r, |m: f64| m.max(r))))
    }
}

/// `|a − b| / max(|a|, |b|)` if both parse as numbers (0 if both are 0 or
/// the same non-finite value).
fn relative(a: &str, b: &str) -> Option<f64> {
    let (x, y) = (a.parse::<f64>().ok()?, b.parse::<f64>().ok()?);
    if x == y || (x.is_nan() && y.is_nan()) {
        return Some(0.0);
    }
    let scale = x.abs().max(y.abs());
    Some(if scale.is_finite() {
        (x - y).abs() / scale
    } else {
        f64::INFINITY
    })
}

fn cells_equal(a: &str, b: &str, rtol: f64) -> bool {
    a == b || (rtol > 0.0 && relative(a, b).is_some_and(|r| r <= rtol))
}

/// The `*.csv` files at the top of `dir`, by name.
fn tables(dir: &Path) -> Result<BTreeSet<String>, String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut names = BTreeSet::new();
    for entry in entries {
        let entry = entry.map_err(|e| format!("{}: {e}", dir.display()))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.ends_with(".csv") && entry.path().is_file() {
            names.insert(name);
        }
    }
    Ok(names)
}

/// The subdirectories of `dir` that hold tables, by name.
fn experiments(dir: &Path) -> Result<BTreeSet<String>, String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut names = BTreeSet::new();
    for entry in entries {
        let entry = entry.map_err(|e| format!("{}: {e}", dir.display()))?;
        let path = entry.path();
        if path.is_dir() && !tables(&path)?.is_empty() {
            names.insert(entry.file_name().to_string_lossy().into_owned());
        }
    }
    Ok(names)
}

fn read_csv(path: &Path) -> Result<(Vec<String>, Vec<Vec<String>>), String> {
    let mut reader =
        csv::Reader::from_path(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let header = reader
        .headers()
        .map_err(|e| format!("{}: {e}", path.display()))?
        .iter()
        .map(str::to_string)
        .collect();
    let mut rows = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| format!("{}: {e}", path.display()))?;
        rows.push(record.iter().map(str::to_string).collect());
    }
    Ok((header, rows))
}

/// Compares one table of one experiment.
fn compare_table(
    name: &str,
    a: &Path,
    b: &Path,
    rtol: f64,
    report: &mut Report,
) -> Result<(), String> {
    let (ha, ra) = read_csv(a)?;
    let (hb, rb) = read_csv(b)?;
    report.tables += 1;
    if ha != hb {
        report.mismatches.push(format!(
            "{name}: the columns differ ({} against {})",
            ha.join(","),
            hb.join(",")
        ));
        return Ok(());
    }
    if ra.len() != rb.len() {
        report
            .mismatches
            .push(format!("{name}: {} rows against {}", ra.len(), rb.len()));
        return Ok(());
    }
    let col = |c: &str| ha.iter().position(|h| h == c);
    let (point, label) = (col("point"), col("label"));
    for (i, (x, y)) in ra.iter().zip(&rb).enumerate() {
        for (j, column) in ha.iter().enumerate() {
            if is_timing_column(column) {
                continue;
            }
            report.cells += 1;
            let (u, v) = (
                x.get(j).map_or("", String::as_str),
                y.get(j).map_or("", String::as_str),
            );
            if !cells_equal(u, v, rtol) {
                let key = [("point", point), ("label", label)]
                    .iter()
                    .filter_map(|(k, c)| c.and_then(|c| x.get(c)).map(|v| format!("{k} {v}")))
                    .collect::<Vec<_>>()
                    .join(", ");
                report.differences.push(Difference {
                    table: name.to_string(),
                    row: i + 1,
                    key,
                    column: column.clone(),
                    a: u.to_string(),
                    b: v.to_string(),
                });
            }
        }
    }
    Ok(())
}

/// Compares one experiment directory's tables (`timing.csv` aside).
fn compare_experiment(
    name: &str,
    a: &Path,
    b: &Path,
    rtol: f64,
    report: &mut Report,
) -> Result<(), String> {
    let (ta, tb) = (tables(a)?, tables(b)?);
    for t in ta.union(&tb) {
        if t == "timing.csv" {
            continue;
        }
        let label = if name.is_empty() {
            t.clone()
        } else {
            format!("{name}/{t}")
        };
        match (ta.contains(t), tb.contains(t)) {
            (true, true) => compare_table(&label, &a.join(t), &b.join(t), rtol, report)?,
            (true, false) => report
                .mismatches
                .push(format!("{label}: only in {}", a.display())),
            _ => report
                .mismatches
                .push(format!("{label}: only in {}", b.display())),
        }
    }
    Ok(())
}

/// What a directory given to `compare` is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    /// Tables at its top: one experiment's results.
    Experiment,
    /// Experiment directories below it: a results directory.
    Results,
}

fn kind(dir: &Path) -> Result<Kind, String> {
    if !dir.is_dir() {
        return Err(format!("{}: not a directory", dir.display()));
    }
    if !tables(dir)?.is_empty() {
        Ok(Kind::Experiment)
    } else if !experiments(dir)?.is_empty() {
        Ok(Kind::Results)
    } else {
        Err(format!(
            "{}: holds no results (neither tables nor experiment directories with tables)",
            dir.display()
        ))
    }
}

/// Compares two results directories, or two experiment directories. An
/// experiment found in only one results directory is a difference if it
/// was written by an experiment (it has a `manifest.json`); other
/// directories with tables (the benchmarks' outputs, which `reproduce`
/// does not write) are listed, not compared.
pub fn compare(a: &Path, b: &Path, rtol: f64) -> Result<Report, String> {
    let (ka, kb) = (kind(a)?, kind(b)?);
    if !(0.0..1.0).contains(&rtol) {
        return Err(format!("--rtol: {rtol} must be at least 0 and below 1"));
    }
    let mut report = Report::default();
    match (ka, kb) {
        (Kind::Experiment, Kind::Experiment) => {
            compare_experiment("", a, b, rtol, &mut report)?;
            report.experiments.push(a.display().to_string());
            return Ok(report);
        }
        (Kind::Results, Kind::Results) => {}
        _ => {
            let name = |k| match k {
                Kind::Experiment => "an experiment directory (tables at its top)",
                Kind::Results => "a results directory (experiment directories below it)",
            };
            return Err(format!(
                "{} is {} and {} is {}: give two of the same kind",
                a.display(),
                name(ka),
                b.display(),
                name(kb)
            ));
        }
    }
    let (ea, eb) = (experiments(a)?, experiments(b)?);
    for name in ea.intersection(&eb) {
        compare_experiment(name, &a.join(name), &b.join(name), rtol, &mut report)?;
        report.experiments.push(name.clone());
    }
    for (side, only, dir) in [
        (&mut report.only_in_a, ea.difference(&eb), a),
        (&mut report.only_in_b, eb.difference(&ea), b),
    ] {
        for name in only {
            if dir.join(name).join("manifest.json").is_file() {
                report
                    .mismatches
                    .push(format!("{name}: an experiment only in {}", dir.display()));
            } else {
                side.push(name.clone());
            }
        }
    }
    if report.experiments.is_empty() {
        return Err(format!(
            "{} and {} have no experiment in common: nothing to compare",
            a.display(),
            b.display()
        ));
    }
    Ok(report)
}

/// How many differing cells the report prints per table.
const SHOWN_PER_TABLE: usize = 5;

/// The report as text: what was compared, what differs.
pub fn render(report: &Report, a: &Path, b: &Path) -> String {
    let mut out = String::new();
    for (side, names) in [(a, &report.only_in_a), (b, &report.only_in_b)] {
        if !names.is_empty() {
            out.push_str(&format!(
                "only in {} (not written by an experiment, not compared): {}\n",
                side.display(),
                names.join(", ")
            ));
        }
    }
    for m in &report.mismatches {
        out.push_str(&format!("{m}\n"));
    }
    let mut shown: Vec<(&str, usize)> = Vec::new();
    for d in &report.differences {
        let n = match shown.iter_mut().find(|(t, _)| *t == d.table) {
            Some((_, n)) => {
                *n += 1;
                *n
            }
            None => {
                shown.push((&d.table, 1));
                1
            }
        };
        if n <= SHOWN_PER_TABLE {
            let key = if d.key.is_empty() {
                String::new()
            } else {
                format!(" ({})", d.key)
            };
            out.push_str(&format!(
                "{} row {}{key}, {}: {} | {}\n",
                d.table, d.row, d.column, d.a, d.b
            ));
        }
    }
    for (table, n) in &shown {
        if *n > SHOWN_PER_TABLE {
            out.push_str(&format!(
                "{table}: {n} cells differ ({} shown)\n",
                SHOWN_PER_TABLE
            ));
        }
    }
    let what = format!(
        "{} experiment(s), {} table(s), {} cells compared (timing.csv and wall_* columns aside)",
        report.experiments.len(),
        report.tables,
        report.cells
    );
    if report.equal() {
        out.push_str(&format!("equal: {what}\n"));
    } else {
        let largest = report
            .largest_relative()
            .map(|r| format!("; largest relative difference {r:.1e}"))
            .unwrap_or_default();
        out.push_str(&format!(
            "different: {what}; {} cell(s) differ, {} table(s) do not match{largest}\n",
            report.differences.len(),
            report.mismatches.len()
        ));
    }
    out
}

/// `nonholo compare A B [--rtol R]`: prints the report; exit status 6 if
/// the results differ.
pub fn command(args: &CompareArgs) -> Result<(), CliError> {
    let report = compare(&args.a, &args.b, args.rtol).map_err(CliError::Input)?;
    let text = render(&report, &args.a, &args.b);
    crate::print_stdout(&text)?;
    if report.equal() {
        Ok(())
    } else {
        Err(CliError::Differ(format!(
            "{} and {} hold different results",
            args.a.display(),
            args.b.display()
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, file: &str, text: &str) {
        std::fs::create_dir_all(dir).unwrap();
        std::fs::write(dir.join(file), text).unwrap();
    }

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("nonholo-compare-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    const RUNS: &str =
        "point,label,err_max,wall_time_median_s\n0,B,1.5e-9,0.001\n0,C,2.0e-9,0.002\n";

    #[test]
    fn equal_tables_with_other_timings_are_equal() {
        let root = scratch("equal");
        let (a, b) = (root.join("a"), root.join("b"));
        write(&a.join("x"), "work_precision.csv", RUNS);
        write(
            &b.join("x"),
            "work_precision.csv",
            &RUNS.replace("0.001", "0.7").replace("0.002", "9"),
        );
        write(
            &a.join("x"),
            "timing.csv",
            "point,label,wall_time_s\n0,B,1\n",
        );
        write(
            &b.join("x"),
            "timing.csv",
            "point,label,wall_time_s\n0,B,2\n",
        );
        // A benchmark's directory on one side only is listed, not compared;
        // an experiment's (it has a manifest) would be a difference.
        write(&a.join("bench"), "scale.csv", "n,rhs_us\n1,0.4\n");
        write(&a.join("x"), "manifest.json", "{}");
        write(&b.join("x"), "manifest.json", "{}");
        let r = compare(&a, &b, 0.0).unwrap();
        assert!(r.equal(), "{r:?}");
        assert_eq!(r.experiments, ["x"]);
        assert_eq!(r.only_in_a, ["bench"]);
        assert_eq!((r.tables, r.cells), (1, 6));
        let text = render(&r, &a, &b);
        assert!(
            text.contains("only in")
                && text.contains("equal: 1 experiment(s), 1 table(s), 6 cells"),
            "{text}"
        );
        write(&a.join("y"), "runs.csv", RUNS);
        write(&a.join("y"), "manifest.json", "{}");
        let r = compare(&a, &b, 0.0).unwrap();
        assert!(!r.equal());
        assert_eq!(r.mismatches.len(), 1);
        assert!(
            r.mismatches[0].starts_with("y: an experiment only in"),
            "{r:?}"
        );
        std::fs::remove_dir_all(root).unwrap();
    }

    #[test]
    fn a_number_that_moved_is_named_with_its_row_and_column() {
        let root = scratch("moved");
        let (a, b) = (root.join("a"), root.join("b"));
        write(&a.join("x"), "runs.csv", RUNS);
        write(
            &b.join("x"),
            "runs.csv",
            &RUNS.replace("2.0e-9", "2.0000001e-9"),
        );
        let r = compare(&a, &b, 0.0).unwrap();
        assert_eq!(
            r.differences,
            [Difference {
                table: "x/runs.csv".into(),
                row: 2,
                key: "point 0, label C".into(),
                column: "err_max".into(),
                a: "2.0e-9".into(),
                b: "2.0000001e-9".into(),
            }]
        );
        let rel = r.largest_relative().unwrap();
        assert!((rel - 5e-8).abs() < 1e-12, "{rel}");
        assert!(
            render(&r, &a, &b)
                .contains("x/runs.csv row 2 (point 0, label C), err_max: 2.0e-9 | 2.0000001e-9")
        );
        // Within a relative tolerance it is the same number.
        assert!(compare(&a, &b, 1e-7).unwrap().equal());
        assert!(!compare(&a, &b, 1e-8).unwrap().equal());
        std::fs::remove_dir_all(root).unwrap();
    }

    #[test]
    fn structure_that_differs_is_a_mismatch() {
        let root = scratch("structure");
        let (a, b) = (root.join("a"), root.join("b"));
        write(&a, "runs.csv", RUNS);
        write(&b, "runs.csv", &format!("{RUNS}1,B,3e-9,0.1\n"));
        write(&a, "pairs.csv", "point,a,b,div\n0,B,C,1\n");
        write(&b, "pairs.csv", "point,a,b,div_xy\n0,B,C,1\n");
        write(&a, "minima.csv", "point,best\n0,1\n");
        // Two experiment directories, compared as one experiment each.
        let r = compare(&a, &b, 0.0).unwrap();
        assert_eq!(r.mismatches.len(), 3, "{:?}", r.mismatches);
        assert!(
            r.mismatches
                .iter()
                .any(|m| m.contains("minima.csv: only in"))
        );
        assert!(
            r.mismatches
                .iter()
                .any(|m| m.contains("runs.csv: 2 rows against 3"))
        );
        assert!(
            r.mismatches
                .iter()
                .any(|m| m.contains("pairs.csv: the columns differ"))
        );
        std::fs::remove_dir_all(root).unwrap();
    }

    #[test]
    fn refuses_what_is_not_results() {
        let root = scratch("refuse");
        std::fs::create_dir_all(root.join("empty")).unwrap();
        let missing = root.join("missing");
        let e = compare(&missing, &root.join("empty"), 0.0).unwrap_err();
        assert!(e.contains("not a directory"), "{e}");
        let e = compare(&root.join("empty"), &root.join("empty"), 0.0).unwrap_err();
        assert!(e.contains("holds no results"), "{e}");
        write(&root.join("x"), "runs.csv", RUNS);
        // A results directory against an experiment's: refused, not a pile
        // of differences.
        let e = compare(&root, &root.join("x"), 0.0).unwrap_err();
        assert!(e.contains("give two of the same kind"), "{e}");
        // Two results directories with no experiment in common.
        write(&root.join("other").join("y"), "runs.csv", RUNS);
        let only_x = root.join("only-x");
        write(&only_x.join("x"), "runs.csv", RUNS);
        let e = compare(&only_x, &root.join("other"), 0.0).unwrap_err();
        assert!(e.contains("nothing to compare"), "{e}");
        for rtol in [-1.0, f64::NAN, 1.0] {
            let e = compare(&root.join("x"), &root.join("x"), rtol).unwrap_err();
            assert!(e.contains("--rtol"), "{e}");
        }
        std::fs::remove_dir_all(root).unwrap();
    }
}
