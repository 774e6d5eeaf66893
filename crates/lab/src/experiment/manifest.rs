//! `manifest.json`: how an experiment's results were made (either kind).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::Deserialize;
use serde_json::{Value as Json, json};
use sha2::{Digest, Sha256};

use super::files::write_json;
use super::spec::Experiment;

/// The crates whose code the results pass through, besides nonholo's own:
/// the numbers (nalgebra, num-dual), the experiment file read (toml), the
/// files written (serde_json, csv) and the figures (plotters). Listed only
/// if the lab links them (thread scheduling and peers for benchmarks, e.g.
/// faer behind diffsol, compute no result).
const RESULT_CRATES: [&str; 6] = [
    "nalgebra",
    "num-dual",
    "toml",
    "serde_json",
    "csv",
    "plotters",
];

/// The package whose dependencies are listed.
const LAB: &str = "nonholo-lab";

#[derive(Deserialize)]
struct Lock {
    #[serde(default)]
    package: Vec<Package>,
}

#[derive(Deserialize)]
struct Package {
    name: String,
    version: String,
    /// `name`, `name version` or `name version (source)`.
    #[serde(default)]
    dependencies: Vec<String>,
}

/// Versions of the [`RESULT_CRATES`] the lab depends on (directly or not),
/// read from the text of a `Cargo.lock`; several versions of one crate are
/// joined with `, `.
pub fn locked_versions(lock: &str) -> Result<BTreeMap<String, String>, String> {
    let lock: Lock = toml::from_str(lock).map_err(|e| format!("Cargo.lock: {e}"))?;
    let find = |dep: &str| -> Option<usize> {
        let mut parts = dep.split(' ');
        let name = parts.next()?;
        let version = parts.next();
        lock.package
            .iter()
            .position(|p| p.name == name && version.is_none_or(|v| p.version == v))
    };
    let mut seen = BTreeSet::new();
    let mut todo: Vec<usize> = lock
        .package
        .iter()
        .position(|p| p.name == LAB)
        .into_iter()
        .collect();
    while let Some(i) = todo.pop() {
        if seen.insert(i) {
            todo.extend(lock.package[i].dependencies.iter().filter_map(|d| find(d)));
        }
    }
    let mut out = BTreeMap::new();
    for name in RESULT_CRATES {
        let versions: Vec<&str> = seen
            .iter()
            .map(|&i| &lock.package[i])
            .filter(|p| p.name == name)
            .map(|p| p.version.as_str())
            .collect();
        if !versions.is_empty() {
            out.insert(name.to_string(), versions.join(", "));
        }
    }
    Ok(out)
}

/// Versions of nonholo and of the crates that compute results, the latter
/// read from `Cargo.lock` when the experiment lives in a checkout.
fn versions(root: &Path) -> Json {
    let mut map = serde_json::Map::new();
    map.insert("nonholo".into(), Json::from(env!("CARGO_PKG_VERSION")));
    if let Ok(text) = std::fs::read_to_string(root.join("Cargo.lock")) {
        match locked_versions(&text) {
            Ok(v) => map.extend(v.into_iter().map(|(k, v)| (k, Json::from(v)))),
            Err(e) => crate::note!("warning: {e}; manifest.json lists no dependency versions"),
        }
    }
    Json::Object(map)
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

/// The git revision of the checkout holding `dir`, and whether tracked
/// files differ from it (both none outside a git checkout).
pub fn git_revision(dir: &Path) -> (Option<String>, Option<bool>) {
    let rev = command_output("git", &["rev-parse", "HEAD"], dir);
    let dirty = command_output(
        "git",
        &["status", "--porcelain", "--untracked-files=no"],
        dir,
    )
    .map(|s| !s.is_empty());
    (rev, dirty)
}

/// Writes `manifest.json`: the command, the experiment file and its hash,
/// the git revision, versions, the machine, and when the run started and
/// finished.
pub fn write_manifest(
    exp: &Experiment,
    dir: &Path,
    started: std::time::SystemTime,
    threads: usize,
) -> Result<(), String> {
    let root = exp
        .path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let hash: String = Sha256::digest(exp.source.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let (rev, dirty) = git_revision(root);
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
            "versions": versions(top.as_deref().unwrap_or(root)),
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Only crates the lab reaches are listed, each at the version it
    /// reaches (faer, behind a benchmark peer, is not).
    #[test]
    fn versions_follow_the_lab_dependency_graph() {
        let lock = r#"
version = 4

[[package]]
name = "nonholo-lab"
version = "0.1.0"
dependencies = ["nonholo-core", "nalgebra 0.35.0", "serde_json"]

[[package]]
name = "nonholo-core"
version = "0.1.0"
dependencies = ["num-dual"]

[[package]]
name = "nonholo-bench"
version = "0.1.0"
dependencies = ["diffsol"]

[[package]]
name = "diffsol"
version = "0.18.0"
dependencies = ["faer", "nalgebra 0.34.2"]

[[package]]
name = "faer"
version = "0.24.4"
source = "registry+https://github.com/rust-lang/crates.io-index"

[[package]]
name = "nalgebra"
version = "0.34.2"

[[package]]
name = "nalgebra"
version = "0.35.0"

[[package]]
name = "num-dual"
version = "0.15.1"

[[package]]
name = "serde_json"
version = "1.0.154"
"#;
        let v = locked_versions(lock).unwrap();
        let expected: BTreeMap<String, String> = [
            ("nalgebra", "0.35.0"),
            ("num-dual", "0.15.1"),
            ("serde_json", "1.0.154"),
        ]
        .into_iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect();
        assert_eq!(v, expected);
    }

    /// The workspace's own lock file parses, and faer is not among the
    /// crates that compute results.
    #[test]
    fn the_workspace_lock_file_reads() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../Cargo.lock");
        let v = locked_versions(&std::fs::read_to_string(path).unwrap()).unwrap();
        assert!(
            v.contains_key("nalgebra") && v.contains_key("num-dual"),
            "{v:?}"
        );
        assert!(!v.contains_key("faer"));
    }
}
