//! Result files of an experiment: tables, trajectories, summary, manifest,
//! and the HTML page. Every file is written atomically.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde_json::{Value as Json, json};
use sha2::{Digest, Sha256};

use super::point::{PointResult, Samples};
use super::spec::Experiment;
use crate::record::write_atomic;

pub(crate) fn write(path: &Path, bytes: &[u8]) -> Result<(), String> {
    write_atomic(path, bytes).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

pub(crate) fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<(), String> {
    let mut bytes = serde_json::to_vec_pretty(value).map_err(|e| e.to_string())?;
    bytes.push(b'\n');
    write(path, &bytes)
}

/// `points/<index>.json`: one point's stored result (either kind).
pub(crate) fn point_path(dir: &Path, index: usize) -> PathBuf {
    dir.join("points").join(format!("{index}.json"))
}

/// The stored results of every point of `exp` in `dir` (for redrawing).
pub(crate) fn load_points<T: serde::de::DeserializeOwned>(
    exp: &Experiment,
    dir: &Path,
) -> Result<Vec<T>, String> {
    exp.points()
        .iter()
        .map(|p| {
            let path = point_path(dir, p.index);
            let text = std::fs::read_to_string(&path)
                .map_err(|e| format!("{}: {e} (run the experiment first)", path.display()))?;
            serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
        })
        .collect()
}

/// Shortest round-trip text of a number; empty for none.
pub(crate) fn num(v: Option<f64>) -> String {
    v.map(|x| x.to_string()).unwrap_or_default()
}

/// `trajectories/<index>-<label>.csv`.
pub fn trajectory_path(dir: &Path, index: usize, label: &str) -> PathBuf {
    dir.join("trajectories")
        .join(format!("{index}-{label}.csv"))
}

/// Writes one formulation's samples: `t, q…, q_dot…, multipliers…, residual, energy`.
pub fn write_trajectory(dir: &Path, index: usize, s: &Samples) -> Result<(), String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["t".to_string()];
    header.extend(s.coordinates.iter().map(|(c, _)| c.clone()));
    header.extend(s.coordinates.iter().map(|(c, _)| format!("{c}_dot")));
    header.extend(s.multipliers.iter().cloned());
    header.extend(["residual".into(), "energy".into()]);
    w.write_record(&header).map_err(|e| e.to_string())?;
    for (i, o) in s.obs.iter().enumerate() {
        let mut row = vec![s.t[i].to_string()];
        row.extend(
            o.q.iter()
                .chain(&o.qd)
                .chain(&o.multipliers)
                .map(|v| v.to_string()),
        );
        let (r, e) = s.physics.get(i).copied().unwrap_or((f64::NAN, f64::NAN));
        row.push(r.to_string());
        row.push(e.to_string());
        w.write_record(&row).map_err(|e| e.to_string())?;
    }
    let bytes = w.into_inner().map_err(|e| e.to_string())?;
    write(&trajectory_path(dir, index, &s.label), &bytes)
}

/// A trajectory file read back: column names and rows.
pub struct Trajectory {
    pub header: Vec<String>,
    pub rows: Vec<Vec<f64>>,
}

impl Trajectory {
    pub fn read(path: &Path) -> Result<Trajectory, String> {
        let mut r = csv::Reader::from_path(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let header = r
            .headers()
            .map_err(|e| e.to_string())?
            .iter()
            .map(String::from)
            .collect();
        let mut rows = Vec::new();
        for rec in r.records() {
            let rec = rec.map_err(|e| format!("{}: {e}", path.display()))?;
            rows.push(rec.iter().map(|v| v.parse().unwrap_or(f64::NAN)).collect());
        }
        Ok(Trajectory { header, rows })
    }

    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let i = self.header.iter().position(|h| h == name)?;
        Some(self.rows.iter().map(|r| r[i]).collect())
    }
}

/// The divergence of formulation `label` from the reference at one point.
fn vs_reference<'a>(
    r: &'a PointResult,
    label: &str,
    reference: &str,
) -> Option<&'a super::PairResult> {
    r.pairs
        .iter()
        .find(|p| (p.a == reference && p.b == label) || (p.b == reference && p.a == label))
}

/// `runs.csv`, `pairs.csv`, `timing.csv` and `config.json`.
pub fn write_tables(exp: &Experiment, dir: &Path, results: &[PointResult]) -> Result<(), String> {
    let axes: Vec<String> = exp.axes.iter().map(|a| a.name.clone()).collect();

    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header: Vec<String> = vec!["point".into()];
    header.extend(axes.iter().cloned());
    header.extend(
        [
            "label",
            "formulation",
            "integrator",
            "rtol",
            "atol",
            "status",
            "t_last",
            "error_t",
            "error",
            "steps",
            "rejected_steps",
            "rhs_evals",
            "jacobian_evals",
            "lu_decompositions",
            "newton_failures",
            "constraint_residual_max",
            "energy_initial",
            "energy_drift_max",
            "reference",
            "div_xy_end",
            "div_xy_max",
            "div_q_end",
            "div_q_max",
            "t_exceed",
        ]
        .map(String::from),
    );
    w.write_record(&header).map_err(|e| e.to_string())?;
    for r in results {
        for f in &r.formulations {
            let mut row = vec![r.index.to_string()];
            row.extend(r.values.iter().cloned());
            row.extend([
                f.label.clone(),
                f.formulation.clone(),
                f.integrator.clone(),
                f.rtol.to_string(),
                f.atol.to_string(),
                f.status.clone(),
                num(f.t_last),
                num(f.error_t),
                f.error.clone().unwrap_or_default(),
                f.steps.to_string(),
                f.rejected_steps.to_string(),
                f.rhs_evals.to_string(),
                f.jacobian_evals.to_string(),
                f.lu_decompositions.to_string(),
                f.newton_failures.to_string(),
                num(f.constraint_residual_max),
                num(f.energy_initial),
                num(f.energy_drift_max),
            ]);
            match vs_reference(r, &f.label, &exp.reference) {
                Some(p) if f.label != exp.reference => row.extend([
                    exp.reference.clone(),
                    num(p.div_xy_end),
                    num(p.div_xy_max),
                    num(p.div_q_end),
                    num(p.div_q_max),
                    num(p.t_exceed),
                ]),
                _ => row.extend(std::iter::repeat_n(String::new(), 6)),
            }
            w.write_record(&row).map_err(|e| e.to_string())?;
        }
    }
    write(
        &dir.join("runs.csv"),
        &w.into_inner().map_err(|e| e.to_string())?,
    )?;

    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header: Vec<String> = vec!["point".into()];
    header.extend(axes.iter().cloned());
    header.extend(
        [
            "a",
            "b",
            "span_end",
            "div_xy_end",
            "div_xy_max",
            "div_q_end",
            "div_q_max",
            "t_exceed",
        ]
        .map(String::from),
    );
    w.write_record(&header).map_err(|e| e.to_string())?;
    for r in results {
        for p in &r.pairs {
            let mut row = vec![r.index.to_string()];
            row.extend(r.values.iter().cloned());
            row.extend([
                p.a.clone(),
                p.b.clone(),
                num(p.span_end),
                num(p.div_xy_end),
                num(p.div_xy_max),
                num(p.div_q_end),
                num(p.div_q_max),
                num(p.t_exceed),
            ]);
            w.write_record(&row).map_err(|e| e.to_string())?;
        }
    }
    write(
        &dir.join("pairs.csv"),
        &w.into_inner().map_err(|e| e.to_string())?,
    )?;

    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(["point", "label", "wall_time_s"])
        .map_err(|e| e.to_string())?;
    for r in results {
        for f in &r.formulations {
            w.write_record([
                r.index.to_string(),
                f.label.clone(),
                f.wall_time_s.to_string(),
            ])
            .map_err(|e| e.to_string())?;
        }
    }
    write(
        &dir.join("timing.csv"),
        &w.into_inner().map_err(|e| e.to_string())?,
    )?;

    let config = json!({
        "name": exp.name,
        "title": exp.title,
        "claim": exp.claim,
        "scene": exp.scene,
        "params": exp.params,
        "init": exp.init,
        "time": {"t_end": exp.t_end, "output_every": exp.output_every},
        "formulations": exp.formulations.iter().map(|f| json!({
            "label": f.label,
            "formulation": f.formulation,
            "integrator": f.settings.integrator,
            "rtol": f.settings.rtol,
            "atol": f.settings.atol,
            "step": f.settings.step,
            "max_steps": f.settings.max_steps,
            "max_wall_time": f.settings.max_wall_time,
            "project_init": f.settings.project_init,
            "options": f.options,
            "init": f.init,
            "params": f.params,
        })).collect::<Vec<_>>(),
        "sweep": {
            "mode": format!("{:?}", exp.mode),
            "axes": exp.axes.iter().map(|a| json!({"name": a.name, "values": a.values})).collect::<Vec<_>>(),
        },
        "measures": {"threshold": exp.threshold, "reference": exp.reference},
        "plots": {"point": exp.plot_point, "all_trajectories": exp.all_trajectories},
    });
    write_json(&dir.join("config.json"), &config)
}

/// The median (the mean of the two middle values for an even count).
pub fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

/// `summary.json`: counts and, for every pair, the spread of the end divergence.
pub fn write_summary(
    exp: &Experiment,
    dir: &Path,
    results: &[PointResult],
    plots: &[PathBuf],
) -> Result<(), String> {
    let labels: Vec<&str> = exp.formulations.iter().map(|f| f.label.as_str()).collect();
    let per_label: Vec<Json> = labels
        .iter()
        .map(|l| {
            let rows: Vec<_> = results
                .iter()
                .flat_map(|r| &r.formulations)
                .filter(|f| f.label == *l)
                .collect();
            json!({
                "label": l,
                "completed": rows.iter().filter(|f| f.status == "completed").count(),
                "stopped": rows.iter().filter(|f| f.status == "stopped").count(),
                "failed": rows.iter().filter(|f| f.status == "failed").count(),
            })
        })
        .collect();
    let mut pairs = Vec::new();
    for (i, a) in labels.iter().enumerate() {
        for b in &labels[i + 1..] {
            let ends: Vec<f64> = results
                .iter()
                .flat_map(|r| &r.pairs)
                .filter(|p| p.a == *a && p.b == *b)
                .filter_map(|p| p.div_xy_end)
                .collect();
            pairs.push(json!({
                "a": a,
                "b": b,
                "points": ends.len(),
                "div_xy_end_min": ends.iter().copied().reduce(f64::min),
                "div_xy_end_median": median(ends.clone()),
                "div_xy_end_max": ends.iter().copied().reduce(f64::max),
            }));
        }
    }
    let runs: usize = results.iter().map(|r| r.formulations.len()).sum();
    let failed = results
        .iter()
        .flat_map(|r| &r.formulations)
        .filter(|f| f.status == "failed")
        .count();
    let stopped = results
        .iter()
        .flat_map(|r| &r.formulations)
        .filter(|f| f.status == "stopped")
        .count();
    write_json(
        &dir.join("summary.json"),
        &json!({
            "schema": "nonholo.experiment-summary/1",
            "name": exp.name,
            "title": exp.title,
            "claim": exp.claim,
            "points": results.len(),
            "runs": runs,
            "failed_runs": failed,
            "stopped_runs": stopped,
            "formulations": per_label,
            "pairs": pairs,
            "plots": plots.iter().map(|p| p.strip_prefix(dir).unwrap_or(p).display().to_string()).collect::<Vec<_>>(),
        }),
    )
}

fn command_output(cmd: &str, args: &[&str], cwd: &Path) -> Option<String> {
    let out = std::process::Command::new(cmd)
        .args(args)
        .current_dir(cwd)
        .output()
        .ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

/// Versions of the crates that compute results, read from `Cargo.lock` when
/// the experiment lives in a checkout.
fn dependency_versions(root: &Path) -> Json {
    let wanted = [
        "nalgebra",
        "num-dual",
        "faer",
        "plotters",
        "rayon",
        "serde_json",
        "toml",
    ];
    let mut map = serde_json::Map::new();
    map.insert("nonholo".into(), Json::from(env!("CARGO_PKG_VERSION")));
    if let Ok(lock) = std::fs::read_to_string(root.join("Cargo.lock")) {
        let mut name = None;
        for line in lock.lines() {
            if let Some(n) = line.strip_prefix("name = ") {
                name = Some(n.trim_matches('"').to_string());
            } else if let (Some(v), Some(n)) = (line.strip_prefix("version = "), &name)
                && wanted.contains(&n.as_str())
            {
                map.insert(n.clone(), Json::from(v.trim_matches('"')));
            }
        }
    }
    Json::Object(map)
}

/// `manifest.json`: how the results were made.
pub fn write_manifest(
    exp: &Experiment,
    dir: &Path,
    started: std::time::SystemTime,
    threads: usize,
) -> Result<(), String> {
    let root = exp
        .path
        .parent()
        .and_then(|p| {
            if p.as_os_str().is_empty() {
                None
            } else {
                Some(p)
            }
        })
        .unwrap_or(Path::new("."));
    let hash: String = Sha256::digest(exp.source.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let rev = command_output("git", &["rev-parse", "HEAD"], root);
    let dirty = command_output(
        "git",
        &["status", "--porcelain", "--untracked-files=no"],
        root,
    )
    .map(|s| !s.is_empty());
    let top = command_output("git", &["rev-parse", "--show-toplevel"], root).map(PathBuf::from);
    let hostname = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|s| s.trim().to_string())
        .or_else(|_| std::env::var("HOSTNAME"))
        .unwrap_or_default();
    write_json(
        &dir.join("manifest.json"),
        &json!({
            "schema": "nonholo.manifest/1",
            "command": std::env::args().collect::<Vec<_>>().join(" "),
            "experiment_file": exp.path.display().to_string(),
            "experiment_sha256": hash,
            "git_revision": rev,
            "git_dirty": dirty,
            "versions": dependency_versions(top.as_deref().unwrap_or(root)),
            "machine": {
                "hostname": hostname,
                "os": std::env::consts::OS,
                "arch": std::env::consts::ARCH,
                "cores": std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
                "threads": threads,
            },
            "started": humantime::format_rfc3339_seconds(started).to_string(),
            "finished": humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
        }),
    )
}

pub(crate) fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// `index.html`: every plot with its caption, then the tables.
pub fn write_html(
    exp: &Experiment,
    dir: &Path,
    results: &[PointResult],
    plots: &[PathBuf],
) -> Result<(), String> {
    let mut h = String::new();
    let _ = write!(
        h,
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\n\
         <style>body{{font-family:sans-serif;max-width:1200px;margin:auto;padding:1em}}\
         table{{border-collapse:collapse;font-size:0.85em}}td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}\
         figure{{margin:1.5em 0}}img{{max-width:100%}}figcaption{{color:#333}}</style></head><body>\n",
        escape(&exp.title)
    );
    let _ = writeln!(
        h,
        "<h1>{}</h1>\n<p><b>Claim tested:</b> {}</p>",
        escape(&exp.title),
        escape(&exp.claim)
    );
    if !exp.description.is_empty() {
        let _ = writeln!(h, "<p>{}</p>", escape(&exp.description));
    }
    let _ = writeln!(
        h,
        "<p>Scene <code>{}</code>; {} point(s); formulations: {}. Files: \
         <a href=\"runs.csv\">runs.csv</a>, <a href=\"pairs.csv\">pairs.csv</a>, \
         <a href=\"summary.json\">summary.json</a>, <a href=\"config.json\">config.json</a>, \
         <a href=\"manifest.json\">manifest.json</a>.</p>",
        escape(&exp.scene),
        results.len(),
        exp.formulations
            .iter()
            .map(|f| format!(
                "{} = {} ({})",
                escape(&f.label),
                escape(&f.formulation),
                escape(&f.settings.integrator)
            ))
            .collect::<Vec<_>>()
            .join(", ")
    );
    for p in plots
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
    {
        let rel = p.strip_prefix(dir).unwrap_or(p).display().to_string();
        let stem = p
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default();
        let _ = writeln!(
            h,
            "<figure><img src=\"{rel}\" alt=\"{stem}\"><figcaption>{}</figcaption></figure>",
            escape(&super::plots::caption(exp, &stem))
        );
    }
    let _ = writeln!(h, "<h2>Runs</h2>\n<table>");
    if let Ok(text) = std::fs::read_to_string(dir.join("runs.csv")) {
        for (i, line) in csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(text.as_bytes())
            .records()
            .flatten()
            .enumerate()
        {
            let tag = if i == 0 { "th" } else { "td" };
            let cells: String = line
                .iter()
                .map(|c| format!("<{tag}>{}</{tag}>", escape(c)))
                .collect();
            let _ = writeln!(h, "<tr>{cells}</tr>");
        }
    }
    let _ = writeln!(h, "</table>\n</body></html>");
    write(&dir.join("index.html"), h.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::median;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(vec![]), None);
        assert_eq!(median(vec![3.0, 1.0, 2.0]), Some(2.0));
        // Even count: the mean of the middle two, not the upper one.
        assert_eq!(median(vec![4.0, 1.0, 3.0, 2.0]), Some(2.5));
    }
}
