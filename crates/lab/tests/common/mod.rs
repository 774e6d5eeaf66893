//! Helpers shared by the tests that drive the `nonholo` binary.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The binary under test: this build's, or `NONHOLO_BIN` (to run these
/// tests against another build, e.g. to see them fail before a fix).
pub fn bin() -> String {
    std::env::var("NONHOLO_BIN").unwrap_or_else(|_| env!("CARGO_BIN_EXE_nonholo").to_string())
}

pub fn nonholo(args: &[&str]) -> Output {
    Command::new(bin())
        .args(args)
        .output()
        .expect("nonholo runs")
}

/// Runs `nonholo` in `dir`.
pub fn nonholo_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(bin())
        .args(args)
        .current_dir(dir)
        .output()
        .expect("nonholo runs")
}

/// Runs a bash command line with `nonholo` standing for the binary and
/// `pipefail` set (the exit status is the pipeline's first failure).
pub fn shell(dir: &Path, line: &str) -> Output {
    Command::new("bash")
        .args([
            "-o",
            "pipefail",
            "-c",
            &format!("nonholo() {{ '{}' \"$@\"; }}\n{line}", bin()),
        ])
        .current_dir(dir)
        .output()
        .expect("bash runs")
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A fresh scratch directory `<tmp>/nonholo-<tag>-<pid>` with `experiments/`.
pub fn scratch(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("nonholo-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(d.join("experiments")).unwrap();
    d
}

/// Writes `experiments/<name>.toml` in `root`; returns its path relative to `root`.
pub fn experiment(root: &Path, name: &str, body: &str) -> String {
    let rel = format!("experiments/{name}.toml");
    std::fs::write(root.join(&rel), body).unwrap();
    rel
}

/// A rolling-disk sweep of `points` values of C's λ1(0) over `[0, t_end]`.
pub fn disk_sweep(name: &str, points: usize, t_end: f64) -> String {
    let values: Vec<String> = (0..points)
        .map(|i| format!("{:.3}", -2.0 + 4.0 * i as f64 / points as f64))
        .collect();
    format!(
        r#"[experiment]
name = "{name}"
title = "test sweep"
claim = "none"
scene = "rolling-disk"

[init]
omega_theta = 0.5
omega_psi = 1.0

[time]
t_end = {t_end:?}
output_every = 0.01

[[formulation]]
label = "B"
formulation = "chetaev"
rtol = 1e-12
atol = 1e-12

[[formulation]]
label = "C"
formulation = "vakonomic"
rtol = 1e-12
atol = 1e-12

[sweep]
mode = "grid"
values = {{ "C.init.lambda1" = [{}] }}
"#,
        values.join(", ")
    )
}

/// A sleigh slope sweep (the shape of `sleigh-slope-sweep`, smaller): B, C
/// and A over a grid of slopes and offsets.
pub fn sleigh_sweep(name: &str) -> String {
    format!(
        r#"[experiment]
name = "{name}"
title = "sleigh sweep"
claim = "none"
scene = "sleigh-incline"

[params]
potential = "com"

[init]
phi = 0.2
u = 2
omega = 0.7

[time]
t_end = 1.0
output_every = 0.01

[[formulation]]
label = "B"
formulation = "chetaev"
rtol = 1e-12
atol = 1e-12

[[formulation]]
label = "C"
formulation = "vakonomic"
rtol = 1e-12
atol = 1e-12
init = {{ lambda = 0 }}

[[formulation]]
label = "A"
formulation = "embedding"
integrator = "radau5"
rtol = 1e-10
atol = 1e-10
init = {{ lambda = 0 }}

[sweep]
mode = "grid"
values = {{ "param.alpha" = [0.1, 0.3, 0.5], "param.a" = [0.0, 0.2, 0.4] }}

[measures]
reference = "B"
"#
    )
}

/// Every file under `dir`.
pub fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                out.extend(walk(&p));
            } else {
                out.push(p);
            }
        }
    }
    out
}

/// The fields of every CSV file under `dir` that are NaN, infinite, or a
/// number written with more than 50 characters (fixed notation stops at
/// magnitude 1e-30: 49 characters at most).
pub fn bad_numbers(dir: &Path) -> Vec<String> {
    let mut bad = Vec::new();
    for p in walk(dir) {
        if p.extension().is_none_or(|e| e != "csv") {
            continue;
        }
        let text = std::fs::read_to_string(&p).unwrap_or_default();
        for (i, line) in text.lines().enumerate() {
            for field in line.split(',') {
                let f = field.trim().to_ascii_lowercase();
                let non_finite = matches!(f.as_str(), "nan" | "inf" | "-inf" | "+inf" | "infinity");
                let long = f.len() > 50 && f.parse::<f64>().is_ok();
                if non_finite || long {
                    bad.push(format!("{}:{}: {field}", p.display(), i + 1));
                }
            }
        }
    }
    bad
}

/// A CSV file with a header as rows of named fields (panics, naming the
/// file, if it cannot be read).
pub fn csv_rows(path: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let mut r = csv::Reader::from_path(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let headers = r.headers().unwrap().clone();
    r.records()
        .map(|rec| {
            headers
                .iter()
                .zip(rec.unwrap().iter())
                .map(|(h, v)| (h.to_string(), v.to_string()))
                .collect()
        })
        .collect()
}
