//! `nonholo compare A B`: whether two results directories hold the same
//! results. For a change of code that should not move any result, a
//! regeneration on another machine, or CI's check that the committed
//! results are what the code computes.
//!
//! Compared: every table (`*.csv`) at the top of each experiment's results
//! directory, cell by cell — except what depends on the machine:
//! `timing.csv` and the columns whose names begin with `wall_` (wall times
//! of work-precision and boundary-value runs). Cells are equal if their
//! text is, or, with `rtol > 0`, if both are numbers within `rtol` of each
//! other (relative to the larger magnitude). Not compared: the other files
//! (`summary.json`, `config.json`, `manifest.json`, pages, figures, which
//! are drawn from the tables) and subdirectories (`points/`,
//! `references/`, `trajectories/`, `plots/`).
//!
//! `A` and `B` are either two results directories (`results/`) or two
//! experiment directories. In results directories an experiment is a
//! directory with a nonholo manifest; those of the same name are paired,
//! and one found on one side only is a difference; two results directories
//! with no experiment in common, or two experiment directories of different
//! experiments, are refused (there is nothing to compare). Other directories with
//! tables (the benchmarks' outputs, whose time columns have other names)
//! are listed, not compared.

use std::collections::BTreeSet;
use std::ffi::OsString;
use std::path::{Path, PathBuf};

use clap::Args;

use crate::CliError;
use crate::experiment::dir::{stored_experiment, written_by_an_experiment};
use crate::table::read_csv;

#[derive(Debug, Clone, Args)]
pub struct CompareArgs {
    /// A results directory (or one experiment's directory).
    pub a: PathBuf,
    /// The results directory to compare with it (or an experiment's).
    pub b: PathBuf,
    /// Numbers within this relative difference count as equal, 0 ≤ R < 1
    /// (default 0: the same text).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub rtol: f64,
}

/// The machine-dependent columns, left out of the comparison.
fn is_timing_column(name: &str) -> bool {
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
    /// Directories with tables that no experiment wrote, listed.
    pub not_compared: Vec<String>,
    /// Tables compared and cells compared in them.
    pub tables: usize,
    pub cells: usize,
    /// Structural differences: an experiment or a table on one side only,
    /// other columns, another number of rows.
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
            .reduce(f64::max)
    }
}

/// `|a − b| / max(|a|, |b|)` if both parse as numbers: 0 if they are equal
/// (or both NaN), infinite if either is not finite.
fn relative(a: &str, b: &str) -> Option<f64> {
    let (x, y) = (a.parse::<f64>().ok()?, b.parse::<f64>().ok()?);
    if x == y || (x.is_nan() && y.is_nan()) {
        return Some(0.0);
    }
    let scale = x.abs().max(y.abs());
    Some(if x.is_finite() && y.is_finite() {
        (x - y).abs() / scale
    } else {
        f64::INFINITY
    })
}

fn cells_equal(a: &str, b: &str, rtol: f64) -> bool {
    a == b || (rtol > 0.0 && relative(a, b).is_some_and(|r| r <= rtol))
}

fn entries(dir: &Path) -> Result<Vec<(OsString, PathBuf)>, String> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))? {
        let entry = entry.map_err(|e| format!("{}: {e}", dir.display()))?;
        out.push((entry.file_name(), entry.path()));
    }
    Ok(out)
}

/// The `*.csv` files at the top of `dir`.
fn tables(dir: &Path) -> Result<BTreeSet<OsString>, String> {
    Ok(entries(dir)?
        .into_iter()
        .filter(|(name, path)| name.to_string_lossy().ends_with(".csv") && path.is_file())
        .map(|(name, _)| name)
        .collect())
}

/// What a directory given to `compare` is.
enum Kind {
    /// Tables at its top: one experiment's results.
    Experiment,
    /// A results directory: its experiments, and the other directories
    /// with tables.
    Results {
        experiments: BTreeSet<OsString>,
        others: Vec<String>,
    },
}

fn kind(dir: &Path) -> Result<Kind, String> {
    if !dir.is_dir() {
        return Err(format!("{}: not a directory", dir.display()));
    }
    if !tables(dir)?.is_empty() {
        return Ok(Kind::Experiment);
    }
    let (mut experiments, mut others) = (BTreeSet::new(), Vec::new());
    for (name, path) in entries(dir)? {
        if !path.is_dir() || tables(&path)?.is_empty() {
            continue;
        }
        if written_by_an_experiment(&path) {
            experiments.insert(name);
        } else {
            others.push(name.to_string_lossy().into_owned());
        }
    }
    if experiments.is_empty() {
        return Err(format!(
            "{}: holds no results (neither tables nor experiments' directories with tables)",
            dir.display()
        ));
    }
    others.sort();
    Ok(Kind::Results {
        experiments,
        others,
    })
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
        // The reader refuses a record with another number of fields than
        // the header, so the three zip in step.
        for ((column, u), v) in ha.iter().zip(x).zip(y) {
            if is_timing_column(column) {
                continue;
            }
            report.cells += 1;
            if cells_equal(u, v, rtol) {
                continue;
            }
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
        let shown = t.to_string_lossy();
        let label = if name.is_empty() {
            shown.into_owned()
        } else {
            format!("{name}/{shown}")
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

/// Compares two results directories, or two experiment directories.
pub fn compare(a: &Path, b: &Path, rtol: f64) -> Result<Report, String> {
    let (ka, kb) = (kind(a)?, kind(b)?);
    if !(0.0..1.0).contains(&rtol) {
        return Err(format!("--rtol: {rtol} must be at least 0 and below 1"));
    }
    let mut report = Report::default();
    let (
        Kind::Results {
            experiments: ea,
            others: oa,
        },
        Kind::Results {
            experiments: eb,
            others: ob,
        },
    ) = (&ka, &kb)
    else {
        if let (Kind::Experiment, Kind::Experiment) = (&ka, &kb) {
            if let (Some(na), Some(nb)) = (stored_experiment(a), stored_experiment(b))
                && na != nb
            {
                return Err(format!(
                    "{} holds experiment `{na}` and {} holds `{nb}`: nothing in common to compare",
                    a.display(),
                    b.display()
                ));
            }
            compare_experiment("", a, b, rtol, &mut report)?;
            report.experiments.push(a.display().to_string());
            return Ok(report);
        }
        let what = |k: &Kind| match k {
            Kind::Experiment => "an experiment directory (tables at its top)",
            Kind::Results { .. } => "a results directory (experiments' directories below it)",
        };
        return Err(format!(
            "{} is {} and {} is {}: give two of the same kind",
            a.display(),
            what(&ka),
            b.display(),
            what(&kb)
        ));
    };
    if ea.is_disjoint(eb) && !ea.is_empty() && !eb.is_empty() {
        return Err(format!(
            "{} and {} have no experiment in common: nothing to compare",
            a.display(),
            b.display()
        ));
    }
    for name in ea.intersection(eb) {
        let shown = name.to_string_lossy();
        compare_experiment(&shown, &a.join(name), &b.join(name), rtol, &mut report)?;
        report.experiments.push(shown.into_owned());
    }
    for (only, dir) in [(ea.difference(eb), a), (eb.difference(ea), b)] {
        for name in only {
            report.mismatches.push(format!(
                "{}: an experiment only in {}",
                name.to_string_lossy(),
                dir.display()
            ));
        }
    }
    report.not_compared = oa
        .iter()
        .chain(ob)
        .cloned()
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    Ok(report)
}

/// How many differing cells the report prints per table.
const SHOWN_PER_TABLE: usize = 5;

/// The report as text: what was compared, what differs.
pub fn render(report: &Report) -> String {
    let mut out = String::new();
    if !report.not_compared.is_empty() {
        out.push_str(&format!(
            "not compared (no experiment wrote them): {}\n",
            report.not_compared.join(", ")
        ));
    }
    for m in &report.mismatches {
        out.push_str(&format!("{m}\n"));
    }
    // The differences of one table are contiguous.
    for table in report.differences.chunk_by(|x, y| x.table == y.table) {
        for d in table.iter().take(SHOWN_PER_TABLE) {
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
        if table.len() > SHOWN_PER_TABLE {
            out.push_str(&format!(
                "{}: {} cells differ ({SHOWN_PER_TABLE} shown)\n",
                table[0].table,
                table.len()
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
            "different: {what}; {} cell(s) differ, {} table(s) or experiment(s) do not match{largest}\n",
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
    crate::print_stdout(&render(&report))?;
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

    /// `dir` as an experiment's results: a manifest and `runs.csv`.
    fn experiment(dir: &Path, runs: &str) {
        write(dir, "manifest.json", r#"{"schema": "nonholo.manifest/1"}"#);
        write(dir, "runs.csv", runs);
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
        experiment(&a.join("x"), RUNS);
        experiment(
            &b.join("x"),
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
        // A benchmark's tables (no manifest), on one side or both, are
        // listed, not compared: their time columns have other names.
        write(&a.join("bench"), "scale.csv", "n,rhs_us\n1,0.4\n");
        write(&b.join("bench"), "scale.csv", "n,rhs_us\n1,0.5\n");
        let r = compare(&a, &b, 0.0).unwrap();
        assert!(r.equal(), "{r:?}");
        assert_eq!(r.experiments, ["x"]);
        assert_eq!(r.not_compared, ["bench"]);
        assert_eq!((r.tables, r.cells), (1, 6));
        assert_eq!(
            render(&r),
            "not compared (no experiment wrote them): bench\n\
             equal: 1 experiment(s), 1 table(s), 6 cells compared (timing.csv and wall_* columns aside)\n"
        );
        // An experiment on one side only is a difference, whichever side.
        experiment(&b.join("y"), RUNS);
        let r = compare(&a, &b, 0.0).unwrap();
        assert_eq!(
            r.mismatches,
            [format!("y: an experiment only in {}", b.display())]
        );
        assert!(
            render(&r).ends_with("0 cell(s) differ, 1 table(s) or experiment(s) do not match\n")
        );
        std::fs::remove_dir_all(root).unwrap();
    }

    #[test]
    fn a_number_that_moved_is_named_with_its_row_and_column() {
        let root = scratch("moved");
        let (a, b) = (root.join("a"), root.join("b"));
        experiment(&a.join("x"), RUNS);
        experiment(&b.join("x"), &RUNS.replace("2.0e-9", "2.0000001e-9"));
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
        // |2.0e-9 − 2.0000001e-9| / 2.0000001e-9, to the last bits of the
        // parsed numbers.
        assert_eq!(r.largest_relative(), relative("2.0e-9", "2.0000001e-9"));
        let rel = r.largest_relative().unwrap();
        assert!((rel * 2.0000001e-9 / 1e-16 - 1.0).abs() < 1e-6, "{rel}");
        assert!(
            render(&r)
                .contains("x/runs.csv row 2 (point 0, label C), err_max: 2.0e-9 | 2.0000001e-9\n")
        );
        // Within a relative tolerance it is the same number.
        assert!(compare(&a, &b, 1e-7).unwrap().equal());
        assert!(!compare(&a, &b, 1e-8).unwrap().equal());
        std::fs::remove_dir_all(root).unwrap();
    }

    #[test]
    fn many_differences_in_a_table_are_counted_after_the_first_five() {
        let root = scratch("many");
        let (a, b) = (root.join("a"), root.join("b"));
        let rows = |v: f64| -> String {
            let mut t = String::from("point,label,err_max\n");
            for i in 0..8 {
                t.push_str(&format!("{i},B,{}\n", v + i as f64));
            }
            t
        };
        write(&a, "runs.csv", &rows(1.0));
        write(&b, "runs.csv", &rows(2.0));
        let r = compare(&a, &b, 0.0).unwrap();
        assert_eq!(r.differences.len(), 8);
        let text = render(&r);
        assert_eq!(text.matches("runs.csv row").count(), 5, "{text}");
        assert!(
            text.contains("runs.csv: 8 cells differ (5 shown)\n"),
            "{text}"
        );
        // The largest relative difference: 1 against 2.
        assert!(
            text.ends_with("largest relative difference 5.0e-1\n"),
            "{text}"
        );
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
        assert_eq!(
            r.mismatches,
            [
                format!("minima.csv: only in {}", a.display()),
                "pairs.csv: the columns differ (point,a,b,div against point,a,b,div_xy)".into(),
                "runs.csv: 2 rows against 3".into(),
            ]
        );
        // A ragged table is refused with its file's name.
        write(&b, "runs.csv", "point,label,err_max\n0,B\n");
        let e = compare(&a, &b, 0.0).unwrap_err();
        assert!(e.contains("runs.csv") && e.contains("fields"), "{e}");
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
        // Tables that no experiment wrote are not results either.
        write(
            &root.join("bench").join("scale"),
            "scale.csv",
            "n,rhs_us\n1,0.4\n",
        );
        let e = compare(&root.join("bench"), &root.join("bench"), 0.0).unwrap_err();
        assert!(e.contains("holds no results"), "{e}");
        experiment(&root.join("x"), RUNS);
        // A results directory against an experiment's: refused, not a pile
        // of differences.
        let e = compare(&root, &root.join("x"), 0.0).unwrap_err();
        assert!(e.contains("give two of the same kind"), "{e}");
        for rtol in [-1.0, f64::NAN, 1.0] {
            let e = compare(&root.join("x"), &root.join("x"), rtol).unwrap_err();
            assert!(e.contains("--rtol"), "{e}");
        }
        std::fs::remove_dir_all(root).unwrap();
    }
}
