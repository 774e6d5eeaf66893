//! A results directory: nonholo's own, and written by one process at a time.
//!
//! Before an experiment writes (or `nonholo plot` redraws) anything, its
//! directory is opened here:
//! - it is created if missing; an existing one must be empty or nonholo's
//!   own (it holds a `manifest.json` of schema `nonholo.manifest/…`, or the
//!   lock file below): results are never written into a directory of other
//!   files, where they would replace or delete what they did not create;
//! - it is locked: `.nonholo.lock` holds an advisory lock (`flock`) for as
//!   long as the process runs, and says who holds it. A second process
//!   writing the same directory stops at once with a message naming the
//!   holder (exit status 5). The kernel releases the lock when its holder
//!   exits, killed or not, so a lock left by a dead process never blocks;
//! - temporaries left by a killed run (`.NAME.PID.tmp` that no writer
//!   holds) are removed.
//!
//! When the process lets go of the directory ([`ResultsDir::finish`] once
//! the results are complete, or on an error: a `nonholo plot` that stops at
//! a missing trajectory) and the directory holds a manifest, the lock file
//! is removed: the manifest marks the directory as nonholo's. Without a
//! manifest (a first run that did not finish), or after a killed process,
//! it stays, unlocked, as that mark.

use std::fs::{self, File, OpenOptions, TryLockError};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use crate::{CliError, io};

/// The lock file of a results directory.
pub const LOCK: &str = ".nonholo.lock";

/// An open results directory, locked for this process.
#[derive(Debug)]
pub struct ResultsDir {
    path: PathBuf,
    /// Holds the lock until dropped.
    lock: Option<File>,
}

impl ResultsDir {
    /// Opens `dir` for results (see the module documentation): created if
    /// missing when `create`, else it must exist. `what` names the
    /// directory in messages (`--out results/x`, `results directory
    /// results/x`).
    pub fn open(dir: &Path, what: &str, create: bool) -> Result<ResultsDir, CliError> {
        match fs::metadata(dir) {
            Ok(m) if !m.is_dir() => {
                return Err(CliError::Input(format!(
                    "{what}: {} is not a directory",
                    dir.display()
                )));
            }
            Ok(_) => check_ours(dir, what)?,
            Err(_) if create => fs::create_dir_all(dir).map_err(|e| {
                CliError::Output(format!("{what}: cannot create {}: {e}", dir.display()))
            })?,
            Err(e) => {
                return Err(CliError::Input(format!(
                    "{what}: {}: {e} (no stored results: run the experiment first)",
                    dir.display()
                )));
            }
        }
        let lock = take_lock(dir, what)?;
        Ok(ResultsDir {
            path: dir.to_path_buf(),
            lock,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Refuses a directory that holds the results of another experiment
    /// (its `summary.json`, or a shard's `shard.json`, names it), so that
    /// `--out` never mixes two.
    pub fn check_experiment(&self, name: &str, what: &str) -> Result<(), CliError> {
        match stored_experiment(&self.path).as_deref() {
            Some(other) if other != name => Err(CliError::Input(format!(
                "{what}: {} holds the results of experiment `{other}`, not `{name}`",
                self.path.display()
            ))),
            _ => Ok(()),
        }
    }

    /// Creates the subdirectories `subs` and removes the temporaries a
    /// killed run left in the directory and in them.
    pub fn prepare(&self, subs: &[&str]) -> Result<(), CliError> {
        for sub in subs {
            let d = self.path.join(sub);
            fs::create_dir_all(&d)
                .map_err(|e| CliError::Output(format!("cannot create {}: {e}", d.display())))?;
            io::clean_stale_temporaries(&d, None);
        }
        io::clean_stale_temporaries(&self.path, None);
        Ok(())
    }

    /// The results are complete: lets go of the directory (see [`Drop`]).
    pub fn finish(self) {}
}

impl Drop for ResultsDir {
    /// Removes the lock file if nonholo's manifest, which marks the
    /// directory as nonholo's, is there; the lock itself is released when
    /// the file handle drops after this.
    fn drop(&mut self) {
        let path = self.path.join(LOCK);
        let ours = self.lock.as_ref().is_some_and(|f| same_file(f, &path));
        if ours && written_by_an_experiment(&self.path) {
            // Removed while still held: a process that opened the file
            // before sees that it is gone once it holds the lock, and
            // starts again on a new one.
            let _ = fs::remove_file(&path);
        }
    }
}

/// The name of the experiment whose results `dir` holds, as its
/// `summary.json` (or a shard's `shard.json`) names it.
pub fn stored_experiment(dir: &Path) -> Option<String> {
    let summary = fs::read_to_string(dir.join("summary.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok());
    summary
        .as_ref()
        .and_then(|s| s["name"].as_str().or(s["experiment"].as_str()))
        .map(str::to_string)
        .or_else(|| super::shard::shard_of(dir))
}

/// Whether `dir` holds an experiment's results: a `manifest.json` of
/// nonholo's schema.
pub fn written_by_an_experiment(dir: &Path) -> bool {
    fs::read_to_string(dir.join("manifest.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .as_ref()
        .and_then(|m| m["schema"].as_str())
        .is_some_and(|s| s.starts_with("nonholo.manifest/"))
}

/// Refuses a directory that holds files nonholo did not write.
fn check_ours(dir: &Path, what: &str) -> Result<(), CliError> {
    let entries: Vec<String> = fs::read_dir(dir)
        .map_err(|e| CliError::Input(format!("{what}: {}: {e}", dir.display())))?
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    if entries.is_empty() || entries.iter().any(|e| e == LOCK) {
        return Ok(());
    }
    if written_by_an_experiment(dir) {
        return Ok(());
    }
    let mut shown: Vec<String> = entries.iter().take(3).map(|e| format!("`{e}`")).collect();
    if entries.len() > 3 {
        shown.push("…".into());
    }
    Err(CliError::Input(format!(
        "{what}: {} holds files nonholo did not write ({}): results are only written into a \
         new or empty directory, or one nonholo wrote (with its manifest.json)",
        dir.display(),
        shown.join(", ")
    )))
}

/// Whether `f` is the file now at `path`.
#[cfg(unix)]
fn same_file(f: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (f.metadata(), fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_: &File, path: &Path) -> bool {
    path.exists()
}

/// Takes the lock of `dir` (`None` where the file system has no locks).
fn take_lock(dir: &Path, what: &str) -> Result<Option<File>, CliError> {
    let path = dir.join(LOCK);
    let output =
        |e: std::io::Error| CliError::Output(format!("cannot lock {}: {e}", path.display()));
    for _ in 0..8 {
        let mut f = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(output)?;
        match f.try_lock() {
            Ok(()) if same_file(&f, &path) => {
                let holder = format!(
                    "pid {}, `{}`, since {}",
                    std::process::id(),
                    std::env::args().collect::<Vec<_>>().join(" "),
                    humantime::format_rfc3339_seconds(std::time::SystemTime::now())
                );
                f.set_len(0).map_err(output)?;
                f.write_all(holder.as_bytes()).map_err(output)?;
                return Ok(Some(f));
            }
            // Removed by a holder that finished: try again on a new file.
            Ok(()) => continue,
            Err(TryLockError::WouldBlock) => {
                let mut holder = String::new();
                let _ = f.read_to_string(&mut holder);
                let holder = holder.trim();
                return Err(CliError::Busy(format!(
                    "{what}: {} is in use by another nonholo process ({}); wait for it to \
                     finish, or write elsewhere with --out",
                    dir.display(),
                    if holder.is_empty() {
                        "starting"
                    } else {
                        holder
                    }
                )));
            }
            Err(TryLockError::Error(e)) if e.kind() == std::io::ErrorKind::Unsupported => {
                crate::note!(
                    "warning: {} cannot be locked ({e}): nothing stops a second process \
                     from writing the same results",
                    dir.display()
                );
                return Ok(None);
            }
            Err(TryLockError::Error(e)) => return Err(output(e)),
        }
    }
    Err(CliError::Busy(format!(
        "{what}: {}: the lock file keeps being replaced",
        dir.display()
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("nonholo-dir-{tag}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn a_held_directory_is_refused_and_released_after() {
        let d = scratch("held");
        let first = ResultsDir::open(&d, "--out", true).unwrap();
        let second = ResultsDir::open(&d, "--out", true).unwrap_err();
        assert_eq!(second.exit_code(), 5, "{second}");
        assert!(second.to_string().contains("in use"), "{second}");
        assert!(
            second
                .to_string()
                .contains(&format!("pid {}", std::process::id()))
        );
        drop(first);
        // Dropped without a manifest (a first run that did not finish, or
        // a killed one): the lock file stays, unlocked, and does not block.
        assert!(d.join(LOCK).exists());
        let third = ResultsDir::open(&d, "--out", true).unwrap();
        third.finish();
        assert!(
            d.join(LOCK).exists(),
            "kept as the mark until a manifest is written"
        );
        // A file of that name that is not nonholo's manifest is no mark.
        fs::write(d.join("manifest.json"), "{}").unwrap();
        ResultsDir::open(&d, "--out", true).unwrap().finish();
        assert!(d.join(LOCK).exists());
        fs::write(
            d.join("manifest.json"),
            r#"{"schema": "nonholo.manifest/1"}"#,
        )
        .unwrap();
        ResultsDir::open(&d, "--out", true).unwrap().finish();
        assert!(!d.join(LOCK).exists());
        // A process that stops on an error in a directory with a manifest
        // (`nonholo plot` at a missing trajectory) leaves no lock file
        // behind either.
        let failed = ResultsDir::open(&d, "--out", true).unwrap();
        assert!(d.join(LOCK).exists());
        drop(failed);
        assert!(!d.join(LOCK).exists());
    }

    #[test]
    fn foreign_directories_are_refused() {
        let d = scratch("foreign");
        fs::create_dir_all(&d).unwrap();
        fs::write(d.join("notes.txt"), "mine").unwrap();
        let e = ResultsDir::open(&d, "--out", true).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        assert!(e.to_string().contains("`notes.txt`"), "{e}");
        fs::write(
            d.join("manifest.json"),
            r#"{"schema": "nonholo.manifest/1"}"#,
        )
        .unwrap();
        ResultsDir::open(&d, "--out", true).unwrap().finish();
    }
}
