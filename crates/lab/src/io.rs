//! Where the command line's output goes, and how result files are written.
//!
//! - Notes on stderr (progress, warnings, the final error) go through
//!   [`note`]: a closed or broken stderr loses the note but never stops the
//!   program, so a sweep whose progress nobody reads still writes its
//!   results.
//! - Output on stdout goes through [`print_stdout`], which reports a closed
//!   stdout (broken pipe included) as an error: what was asked for did not
//!   arrive, and the exit status says so.
//! - Result files are written by [`write_atomic`] (one file) or
//!   [`write_group`] (files that belong together, such as a CSV and its
//!   `.meta.json`): each into a temporary `.NAME.PID.tmp` beside its target,
//!   locked while it is written, flushed and renamed over the target. A
//!   reader never sees a half-written file; a symbolic link is written
//!   through (the link stays, its target is replaced), an existing file
//!   keeps its permissions, and no directory is created. A temporary left
//!   by a killed writer is unlocked, and [`clean_stale_temporaries`] removes
//!   it.
//! - [`check_target`] checks, before anything runs, that a result file can
//!   be written where it is asked for.

use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// Writes a note to stderr; a failure to write is ignored (see the module
/// documentation).
pub fn note(args: std::fmt::Arguments) {
    let mut err = io::stderr().lock();
    let _ = err.write_fmt(args).and_then(|_| err.write_all(b"\n"));
}

/// `note!("…", args)`: [`note`] with `format!` arguments and a final newline.
#[macro_export]
macro_rules! note {
    ($($arg:tt)*) => {
        $crate::io::note(format_args!($($arg)*))
    };
}

/// Writes `text` to stdout and flushes it; a broken pipe or any other
/// failure to write is an error naming stdout. (A descriptor closed before
/// the program started, `>&-`, cannot be told apart: the standard library
/// reopens it on /dev/null before `main`, and the output is discarded as
/// with `>/dev/null`.)
pub fn print_stdout(text: &str) -> Result<(), String> {
    let mut out = io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|_| out.flush())
        .map_err(|e| format!("cannot write to stdout: {e}"))
}

/// Symbolic links followed at most (as the kernel does).
const MAX_LINKS: usize = 40;

/// The file that writing to `path` replaces: `path` itself, or the file a
/// chain of symbolic links ends at (which need not exist yet).
pub fn resolve(path: &Path) -> io::Result<PathBuf> {
    let mut p = path.to_path_buf();
    for _ in 0..MAX_LINKS {
        match fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let target = fs::read_link(&p)?;
                p = if target.is_absolute() {
                    target
                } else {
                    p.parent().unwrap_or(Path::new("")).join(target)
                };
            }
            _ => return Ok(p),
        }
    }
    Err(io::Error::other(format!(
        "more than {MAX_LINKS} symbolic links from {}",
        path.display()
    )))
}

/// The directory holding `path` (`.` for a bare file name).
fn parent_of(path: &Path) -> &Path {
    path.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// `.NAME.PID.tmp` beside `path`.
fn temporary(path: &Path) -> io::Result<PathBuf> {
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::other(format!("not a file path: {}", path.display())))?;
    Ok(path.with_file_name(format!(
        ".{}.{}.tmp",
        name.to_string_lossy(),
        std::process::id()
    )))
}

/// Checks, before a run, that a file can be written at `path`: its
/// directory exists and takes new files, and `path` is not a directory.
/// Returns the file that will be replaced (symbolic links followed).
pub fn check_target(path: &Path) -> Result<PathBuf, String> {
    let text = path.as_os_str().to_string_lossy();
    if text.ends_with('/') || text.ends_with(std::path::MAIN_SEPARATOR) {
        return Err("names a directory (it ends in a separator), not a file".into());
    }
    let target = resolve(path).map_err(|e| e.to_string())?;
    let dir = parent_of(&target);
    match fs::metadata(dir) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => return Err(format!("{} is not a directory", dir.display())),
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            return Err(format!(
                "directory {} does not exist (it is not created: create it first)",
                dir.display()
            ));
        }
        Err(e) => return Err(format!("{}: {e}", dir.display())),
    }
    if fs::metadata(&target).is_ok_and(|m| m.is_dir()) {
        return Err(format!("{} is a directory", target.display()));
    }
    let probe = temporary(&target).map_err(|e| e.to_string())?;
    File::create(&probe).map_err(|e| format!("cannot create a file in {}: {e}", dir.display()))?;
    let _ = fs::remove_file(&probe);
    Ok(target)
}

/// A temporary file written and locked, waiting to be renamed over `target`.
struct Pending {
    tmp: PathBuf,
    target: PathBuf,
    /// Held open (and locked) until the rename.
    _file: File,
}

impl Pending {
    fn write(path: &Path, bytes: &[u8]) -> io::Result<Pending> {
        let target = resolve(path)?;
        if fs::metadata(&target).is_ok_and(|m| m.is_dir()) {
            return Err(io::Error::other(format!(
                "{} is a directory",
                target.display()
            )));
        }
        let tmp = temporary(&target)?;
        let result = (|| {
            let mut f = File::create(&tmp)?;
            // Marks the temporary as in use (see `clean_stale_temporaries`);
            // a file system without locks just loses that mark.
            let _ = f.try_lock();
            if let Ok(m) = fs::metadata(&target)
                && m.is_file()
            {
                f.set_permissions(m.permissions())?;
            }
            f.write_all(bytes)?;
            f.sync_all()?;
            Ok(f)
        })();
        match result {
            Ok(file) => Ok(Pending {
                tmp,
                target,
                _file: file,
            }),
            Err(e) => {
                let _ = fs::remove_file(&tmp);
                Err(e)
            }
        }
    }

    fn commit(self) -> io::Result<()> {
        let r = fs::rename(&self.tmp, &self.target);
        if r.is_err() {
            let _ = fs::remove_file(&self.tmp);
        }
        r
    }

    fn abandon(self) {
        let _ = fs::remove_file(&self.tmp);
    }
}

/// Writes `bytes` to `path` atomically (see the module documentation).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    Pending::write(path, bytes)?.commit()
}

/// Writes files that belong together: every one is written to its
/// temporary first, and only when all are complete are they renamed over
/// their targets, so a failure to write one leaves every target as it was.
pub fn write_group(files: &[(&Path, &[u8])]) -> Result<(), String> {
    let mut pending = Vec::new();
    for (path, bytes) in files {
        match Pending::write(path, bytes) {
            Ok(p) => pending.push(p),
            Err(e) => {
                pending.into_iter().for_each(Pending::abandon);
                return Err(format!("cannot write {}: {e}", path.display()));
            }
        }
    }
    for p in pending {
        let shown = p.target.display().to_string();
        p.commit()
            .map_err(|e| format!("cannot write {shown}: {e}"))?;
    }
    Ok(())
}

/// Whether `name` is a temporary of [`write_atomic`] (`.NAME.PID.tmp`),
/// of the file `target` if given.
fn is_temporary(name: &str, target: Option<&str>) -> bool {
    let Some(inner) = name.strip_prefix('.').and_then(|n| n.strip_suffix(".tmp")) else {
        return false;
    };
    let Some((file, pid)) = inner.rsplit_once('.') else {
        return false;
    };
    !file.is_empty()
        && !pid.is_empty()
        && pid.bytes().all(|b| b.is_ascii_digit())
        && target.is_none_or(|t| t == file)
}

/// Removes the temporaries in `dir` (of the file named `target`, or all)
/// that no writer holds: what a killed writer left behind.
pub fn clean_stale_temporaries(dir: &Path, target: Option<&str>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        if !is_temporary(&name.to_string_lossy(), target) {
            continue;
        }
        let path = e.path();
        let Ok(f) = OpenOptions::new().read(true).open(&path) else {
            continue;
        };
        // Unlocked: its writer is gone. Locked (`WouldBlock`): in use.
        if f.try_lock().is_ok() {
            let _ = fs::remove_file(&path);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("nonholo-io-{tag}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn temporaries_are_recognised_by_their_pattern() {
        assert!(is_temporary(".run.json.123.tmp", None));
        assert!(is_temporary(".run.json.123.tmp", Some("run.json")));
        assert!(!is_temporary(".run.json.123.tmp", Some("run.csv")));
        assert!(!is_temporary(".notes.tmp", None));
        assert!(!is_temporary("run.json.123.tmp", None));
        assert!(!is_temporary(".x.12a.tmp", None));
    }

    #[test]
    fn a_stale_temporary_is_removed_and_a_held_one_kept() {
        let d = scratch("stale");
        let stale = d.join(".a.json.1.tmp");
        fs::write(&stale, b"half").unwrap();
        let held = d.join(".b.json.2.tmp");
        let f = File::create(&held).unwrap();
        f.try_lock().unwrap();
        let other = d.join(".notes.tmp");
        fs::write(&other, b"mine").unwrap();
        clean_stale_temporaries(&d, None);
        assert!(!stale.exists());
        assert!(held.exists(), "a temporary being written is kept");
        assert!(other.exists(), "a file not of our pattern is kept");
        drop(f);
    }

    #[cfg(unix)]
    #[test]
    fn links_are_written_through_and_modes_kept() {
        use std::os::unix::fs::{PermissionsExt, symlink};
        let d = scratch("link");
        let real = d.join("real.json");
        fs::write(&real, b"old").unwrap();
        fs::set_permissions(&real, fs::Permissions::from_mode(0o640)).unwrap();
        let link = d.join("link.json");
        symlink("real.json", &link).unwrap();
        write_atomic(&link, b"new").unwrap();
        assert!(
            fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(fs::read(&real).unwrap(), b"new");
        assert_eq!(
            fs::metadata(&real).unwrap().permissions().mode() & 0o777,
            0o640
        );
    }

    #[test]
    fn no_directory_is_created_and_a_group_is_all_or_nothing() {
        let d = scratch("group");
        assert!(write_atomic(&d.join("missing/x.json"), b"x").is_err());
        assert!(!d.join("missing").exists());
        assert!(check_target(&d.join("missing/x.json")).is_err());
        let a = d.join("a.csv");
        let b = d.join("b.json");
        fs::write(&a, b"old a").unwrap();
        fs::create_dir(&b).unwrap();
        assert!(write_group(&[(&a, b"new a"), (&b, b"new b")]).is_err());
        assert_eq!(fs::read(&a).unwrap(), b"old a", "nothing replaced");
        let left: Vec<_> = fs::read_dir(&d)
            .unwrap()
            .flatten()
            .map(|e| e.file_name())
            .collect();
        assert_eq!(left.len(), 2, "{left:?}");
    }
}
