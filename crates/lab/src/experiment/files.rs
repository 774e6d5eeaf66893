//! Files every experiment writes the same way, whatever its kind: atomic
//! writes, JSON, and the stored point files (`points/<i>.json`) that let a
//! sweep resume.

use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use super::spec::Experiment;
use crate::record::write_atomic;

/// Writes `bytes` to `path` atomically.
pub(crate) fn write(path: &Path, bytes: &[u8]) -> Result<(), String> {
    write_atomic(path, bytes).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// Removes the figures (`*.png`, `*.svg`) in `plots` that are not in
/// `written`: those of an earlier version of the experiment or of the code
/// (a figure dropped, a stem renamed), which would otherwise stay on its
/// page as if current.
pub(crate) fn remove_other_figures(plots: &Path, written: &[PathBuf]) -> Result<(), String> {
    let Ok(entries) = std::fs::read_dir(plots) else {
        return Ok(());
    };
    for e in entries.filter_map(Result::ok) {
        let p = e.path();
        let figure = p.extension().is_some_and(|x| x == "png" || x == "svg");
        if figure && p.is_file() && !written.contains(&p) {
            std::fs::remove_file(&p).map_err(|e| format!("cannot remove {}: {e}", p.display()))?;
        }
    }
    Ok(())
}

/// Writes `value` as pretty JSON with a final newline.
pub(crate) fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), String> {
    let mut bytes = serde_json::to_vec_pretty(value).map_err(|e| e.to_string())?;
    bytes.push(b'\n');
    write(path, &bytes)
}

/// `points/<index>.json`: one point's stored result (either kind).
pub(crate) fn point_path(dir: &Path, index: usize) -> PathBuf {
    dir.join("points").join(format!("{index}.json"))
}

/// One point's stored result, either kind: which point it is, the key of
/// the computation it holds, and what the kind stores (`B`, whose fields
/// follow at the top level of the file).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StoredPoint<B> {
    /// The kind's schema (`nonholo.point/1`, `nonholo.wp-point/1`).
    pub schema: String,
    pub index: usize,
    /// The swept values of the point, as text.
    pub values: Vec<String>,
    /// The point's resume key ([`super::key`]): a stored result is reused
    /// only if the experiment still asks for the same computation.
    pub hash: String,
    #[serde(flatten)]
    pub body: B,
}

/// The stored result of point `index` in `dir` if it is of `schema` and
/// holds the computation `key` names.
pub(crate) fn stored<B: DeserializeOwned>(
    dir: &Path,
    index: usize,
    schema: &str,
    key: &str,
) -> Option<StoredPoint<B>> {
    let text = std::fs::read_to_string(point_path(dir, index)).ok()?;
    let r: StoredPoint<B> = serde_json::from_str(&text).ok()?;
    (r.schema == schema && r.hash == key).then_some(r)
}

/// The stored results of every point of `exp` in `dir` (for redrawing):
/// each must be there, of `schema`, and hold the computation the point
/// asks for now (its resume key); a stale or missing point is an error
/// naming its file.
pub(crate) fn load_points<B: DeserializeOwned>(
    exp: &Experiment,
    dir: &Path,
    schema: &str,
) -> Result<Vec<StoredPoint<B>>, String> {
    let rerun = format!("run `nonholo experiment {}` first", exp.path.display());
    exp.points()
        .iter()
        .map(|p| {
            let path = point_path(dir, p.index);
            let text = std::fs::read_to_string(&path)
                .map_err(|e| format!("{}: {e} ({rerun})", path.display()))?;
            let r: StoredPoint<B> = serde_json::from_str(&text)
                .map_err(|e| format!("{}: {e} ({rerun})", path.display()))?;
            let key = super::key::point_key(exp, p, schema)?;
            if r.schema != schema || r.index != p.index || r.hash != key {
                return Err(format!(
                    "{}: holds results of another computation than point {} of {} asks for \
                     now (the experiment file or nonholo changed since it ran): {rerun}",
                    path.display(),
                    p.index,
                    exp.path.display()
                ));
            }
            Ok(r)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    /// A float read back from a point file is the float written (serde_json
    /// with `float_roundtrip`; without it about one value in a few hundred
    /// came back one ulp off, and a resumed sweep differed from a fresh one).
    #[test]
    fn floats_read_back_exactly() {
        let stored: f64 = serde_json::from_str("2.2653599263122715e-7").unwrap();
        assert_eq!(stored.to_bits(), 2.2653599263122715e-7f64.to_bits());
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        let values: Vec<f64> = (0..20_000)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                let v = f64::from_bits(x);
                if v.is_finite() { v } else { 1.0 / (x as f64) }
            })
            .collect();
        let text = serde_json::to_string(&values).unwrap();
        let back: Vec<f64> = serde_json::from_str(&text).unwrap();
        for (a, b) in values.iter().zip(&back) {
            assert_eq!(a.to_bits(), b.to_bits(), "{a:e} read back as {b:e}");
        }
    }
}
