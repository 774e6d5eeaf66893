//! Sweeps beyond one machine: a shard computes a deterministic slice of an
//! experiment's points into its own results directory, and a merge gathers
//! the shards' stored points into one directory and writes the tables,
//! figures and pages from them, as a single run would (docs/cluster.md).
//!
//! Shard `i` of `n` (1-based) holds the points whose index is `i − 1`
//! modulo `n`: every point in exactly one shard, the slices balanced for
//! any sweep order. A shard directory holds `points/`, the trajectories of
//! the plotted points, `manifest.json` and `shard.json`; no tables or
//! figures. The merged results equal a single run's (`runs.csv`,
//! `pairs.csv` byte for byte); only the wall times, measured on each
//! shard's machine, differ as they do between two single runs.

use std::fs;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::{Experiment, ResultsDir, files, output, sweep};
use crate::CliError;

/// Shard `index` of `count` (1-based).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// Parses `I/N` (`--shard 2/4`): `1 ≤ I ≤ N`.
    pub fn parse(text: &str) -> Result<Shard, CliError> {
        let bad = |why: &str| {
            CliError::Input(format!(
                "--shard {text}: {why} (expected I/N with 1 ≤ I ≤ N, e.g. --shard 2/4)"
            ))
        };
        let (i, n) = text.split_once('/').ok_or_else(|| bad("no `/`"))?;
        let index: usize = i.trim().parse().map_err(|_| bad("I is not a count"))?;
        let count: usize = n.trim().parse().map_err(|_| bad("N is not a count"))?;
        if count == 0 || index == 0 || index > count {
            return Err(bad("out of range"));
        }
        Ok(Shard { index, count })
    }

    /// Whether point `index` (0-based) is in this shard.
    pub fn holds(&self, index: usize) -> bool {
        index % self.count == self.index - 1
    }

    /// The default directory of this shard: `results/<name>.shard-I-of-N`
    /// beside the experiment's default results directory.
    pub fn default_dir(&self, exp: &Experiment) -> PathBuf {
        let d = super::default_dir(exp);
        d.with_file_name(format!(
            "{}.shard-{}-of-{}",
            exp.name, self.index, self.count
        ))
    }
}

/// `shard.json`: which slice a shard directory holds.
#[derive(Debug, Serialize, Deserialize)]
pub struct ShardRecord {
    pub schema: String,
    pub experiment: String,
    pub shard: [usize; 2],
    /// The point indices computed (or reused) here.
    pub points: Vec<usize>,
}

pub const SHARD_SCHEMA: &str = "nonholo.shard/1";

/// Writes `shard.json` into `dir`.
pub fn write_record(
    exp: &Experiment,
    dir: &Path,
    shard: Shard,
    points: &[usize],
) -> Result<(), String> {
    files::write_json(
        &dir.join("shard.json"),
        &ShardRecord {
            schema: SHARD_SCHEMA.into(),
            experiment: exp.name.clone(),
            shard: [shard.index, shard.count],
            points: points.to_vec(),
        },
    )
}

/// Copies every point of `exp` from the shard directories into `out`
/// (the point files and the trajectories of the points whose time series
/// are drawn), checking that each point is stored, for the computation the
/// experiment asks for now, in one of them. A missing point is an error
/// naming it and the shard that computes it.
pub fn gather(exp: &Experiment, shards: &[ResultsDir], out: &Path) -> Result<usize, CliError> {
    let mut count = None;
    for s in shards {
        let path = s.path().join("shard.json");
        let text = fs::read_to_string(&path).map_err(|e| {
            CliError::Input(format!(
                "{}: {e} (not a shard directory: run `nonholo experiment FILE --shard I/N`)",
                path.display()
            ))
        })?;
        let r: ShardRecord = serde_json::from_str(&text)
            .map_err(|e| CliError::Input(format!("{}: {e}", path.display())))?;
        if r.schema != SHARD_SCHEMA || r.experiment != exp.name {
            return Err(CliError::Input(format!(
                "{}: a shard of `{}` ({}), not of `{}`",
                path.display(),
                r.experiment,
                r.schema,
                exp.name
            )));
        }
        match count {
            None => count = Some(r.shard[1]),
            Some(n) if n != r.shard[1] => {
                return Err(CliError::Input(format!(
                    "{}: shard {}/{} does not belong with shards of {n}",
                    path.display(),
                    r.shard[0],
                    r.shard[1]
                )));
            }
            _ => {}
        }
    }
    let n = count.unwrap_or(1).max(1);
    let points = exp.points();
    // Where each point is stored, all of them found before anything is
    // written (a refused merge writes nothing).
    let mut found = Vec::with_capacity(points.len());
    let mut missing = Vec::new();
    for p in &points {
        let needs_traj = super::needs_trajectories(exp, p);
        match shards
            .iter()
            .map(ResultsDir::path)
            .find(|d| super::complete(d, exp, p).is_some())
        {
            Some(dir) => found.push((p.index, dir, needs_traj)),
            None => missing.push(p.index),
        }
    }
    if let Some(&first) = missing.first() {
        let shown: Vec<String> = missing.iter().take(10).map(|i| i.to_string()).collect();
        return Err(CliError::Input(format!(
            "merge: {} of {} points are stored in none of the shard directories (points {}{}); \
             point {first} is computed by `nonholo experiment {} --shard {}/{n}`",
            missing.len(),
            points.len(),
            shown.join(", "),
            if missing.len() > 10 { ", …" } else { "" },
            exp.path.display(),
            first % n + 1,
        )));
    }
    fs::create_dir_all(out.join("points"))
        .and_then(|()| fs::create_dir_all(out.join("trajectories")))
        .map_err(|e| CliError::Output(format!("cannot create {}: {e}", out.display())))?;
    for (index, dir, needs_traj) in found {
        copy(
            &files::point_path(dir, index),
            &files::point_path(out, index),
        )?;
        if needs_traj {
            for f in &exp.formulations {
                let from = output::trajectory_path(dir, index, &f.label);
                if from.exists() {
                    copy(&from, &output::trajectory_path(out, index, &f.label))?;
                }
            }
        }
    }
    Ok(points.len())
}

/// The experiment a shard directory holds (its `shard.json`), if it is one.
pub fn shard_of(dir: &Path) -> Option<String> {
    let text = fs::read_to_string(dir.join("shard.json")).ok()?;
    let r: ShardRecord = serde_json::from_str(&text).ok()?;
    Some(r.experiment)
}

fn copy(from: &Path, to: &Path) -> Result<(), CliError> {
    let bytes = fs::read(from)
        .map_err(|e| CliError::Input(format!("cannot read {}: {e}", from.display())))?;
    files::write(to, &bytes).map_err(CliError::Output)
}

/// The points of `exp` in `shard`.
pub fn slice(points: Vec<sweep::Point>, shard: Option<Shard>) -> Vec<sweep::Point> {
    match shard {
        Some(s) => points.into_iter().filter(|p| s.holds(p.index)).collect(),
        None => points,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_the_points() {
        for n in 1..6 {
            for idx in 0..23 {
                let holders = (1..=n)
                    .filter(|&i| Shard { index: i, count: n }.holds(idx))
                    .count();
                assert_eq!(holders, 1, "point {idx} of {n} shards");
            }
        }
        assert_eq!(Shard::parse("2/4").unwrap(), Shard { index: 2, count: 4 });
        for bad in ["0/4", "5/4", "1/0", "2", "a/b", "-1/3"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
    }
}
