//! Atomic file output, shared by every file a render writes (EXR images, PNG previews,
//! statistics JSON, checkpoints and part files): the bytes go to a temporary file of a
//! unique name in the destination's directory, which is flushed to disk (fsync) and renamed
//! over the destination, and the directory is synced so that the rename itself survives a
//! crash. A reader of the destination sees the old file or the new one, whole, never a
//! mixture or a truncated file, even while other processes write the same path; a writer
//! killed mid-way leaves the old file in place (and, killed by SIGKILL, a hidden temporary
//! file `.NAME.*.tmp`, removed on any error that the process lives through).
//!
//! The temporary names hold the process id, a per-process counter and a random number, and
//! are created with `O_EXCL` (`create_new`), so that two writers (threads, processes, or
//! jobs on two hosts sharing a file system) never write into the same temporary file.

use std::fs::File;
use std::hash::{BuildHasher, Hasher};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Names handed out by this process so far (part of each temporary name).
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// How many names are tried when a temporary name is taken already.
const NAME_TRIES: u32 = 16;

/// The directory `path` is in ("." for a bare file name).
fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// The file name of `path`, or an error if it names no file (`dir/`, `..`, `/`).
fn file_name(path: &Path) -> io::Result<String> {
    match path.file_name() {
        Some(n) => Ok(n.to_string_lossy().into_owned()),
        None => Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "not a file path",
        )),
    }
}

/// A fresh temporary path next to `path`: `.NAME.PID-COUNT-RANDOM.tmp`.
fn temp_path(path: &Path, name: &str) -> PathBuf {
    let count = COUNTER.fetch_add(1, Ordering::Relaxed);
    // std's RandomState is seeded randomly per process (and varies per instance).
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(count);
    h.write_u128(
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos()),
    );
    let random = h.finish() & 0xffff_ffff;
    path.with_file_name(format!(
        ".{name}.{}-{count}-{random:08x}.tmp",
        std::process::id()
    ))
}

/// Creates a new temporary file next to `path` (never opening an existing one).
fn create_temp(path: &Path) -> io::Result<(PathBuf, File)> {
    let name = file_name(path)?;
    let mut last = None;
    for _ in 0..NAME_TRIES {
        let tmp = temp_path(path, &name);
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
        {
            Ok(f) => return Ok((tmp, f)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(explain(path, e)),
        }
    }
    Err(last.unwrap_or_else(|| io::Error::other("no free temporary name")))
}

/// `e` (from creating a file next to `path`) with the directory named when it is missing.
fn explain(path: &Path, e: io::Error) -> io::Error {
    let dir = parent_dir(path);
    match std::fs::metadata(dir) {
        Err(_) => io::Error::new(
            io::ErrorKind::NotFound,
            format!("no such directory {}", dir.display()),
        ),
        Ok(m) if !m.is_dir() => io::Error::new(
            io::ErrorKind::NotADirectory,
            format!("{} is not a directory", dir.display()),
        ),
        Ok(_) => io::Error::new(
            e.kind(),
            format!("cannot create a file in {}: {e}", dir.display()),
        ),
    }
}

/// Removes the temporary file unless it was renamed (on errors and panics alike).
struct TempGuard(Option<PathBuf>);

impl Drop for TempGuard {
    fn drop(&mut self) {
        if let Some(p) = self.0.take() {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// Syncs the directory `dir` (so that a rename in it is on disk). Best effort: some file
/// systems cannot sync a directory, and the file is in place already.
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

/// Writes `path` atomically: `write` fills a new temporary file next to it (it may seek),
/// which is synced to disk and renamed over `path`; then the directory is synced. On any
/// error `path` is left as it was and the temporary file is removed.
pub fn write_with(path: &Path, write: impl FnOnce(&mut File) -> io::Result<()>) -> io::Result<()> {
    if path.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::IsADirectory,
            "is a directory",
        ));
    }
    let (tmp, mut file) = create_temp(path)?;
    let mut guard = TempGuard(Some(tmp.clone()));
    write(&mut file)?;
    file.flush()?;
    file.sync_all()?;
    drop(file);
    std::fs::rename(&tmp, path)?;
    guard.0 = None;
    sync_dir(parent_dir(path));
    Ok(())
}

/// Writes `bytes` to `path` atomically (see [`write_with`]).
pub fn write_bytes(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_with(path, |f| f.write_all(bytes))
}

/// Checks, before any work is done, that `path` can be written as [`write_with`] writes it:
/// its directory exists and a file can be created there (a temporary file is created and
/// removed), and `path` is not a directory. The error says which of these failed.
pub fn check_writable(path: &Path) -> io::Result<()> {
    if path.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::IsADirectory,
            "is a directory",
        ));
    }
    let (tmp, file) = create_temp(path)?;
    drop(file);
    std::fs::remove_file(&tmp)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("penumbra-atomic-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn entries(d: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn replaces_the_file_and_leaves_no_temporary_file() {
        let d = dir("replace");
        let p = d.join("a.txt");
        write_bytes(&p, b"one").unwrap();
        write_bytes(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        assert_eq!(entries(&d), ["a.txt"]);
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn a_failed_write_keeps_the_old_file_and_removes_its_temporary_file() {
        let d = dir("fail");
        let p = d.join("a.txt");
        write_bytes(&p, b"old").unwrap();
        let e = write_with(&p, |f| {
            f.write_all(b"half")?;
            Err(io::Error::other("disk full"))
        })
        .unwrap_err();
        assert_eq!(e.to_string(), "disk full");
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        assert_eq!(entries(&d), ["a.txt"]);
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn temporary_names_are_unique() {
        let p = Path::new("x/out.exr");
        let a = temp_path(p, "out.exr");
        let b = temp_path(p, "out.exr");
        assert_ne!(a, b);
        let name = a.file_name().unwrap().to_string_lossy().into_owned();
        assert!(
            name.starts_with(".out.exr.") && name.ends_with(".tmp"),
            "{name}"
        );
        assert_eq!(a.parent(), Some(Path::new("x")));
    }

    #[test]
    fn check_writable_names_what_is_wrong() {
        let d = dir("check");
        check_writable(&d.join("out.exr")).unwrap();
        assert_eq!(
            entries(&d),
            Vec::<String>::new(),
            "the probe file is removed"
        );
        let missing = d.join("no/such");
        let e = check_writable(&missing.join("out.exr")).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("no such directory {}", missing.display())
        );
        let e = check_writable(&d).unwrap_err();
        assert_eq!(e.to_string(), "is a directory");
        std::fs::write(d.join("file"), b"").unwrap();
        let e = check_writable(&d.join("file/out.exr")).unwrap_err();
        assert!(e.to_string().ends_with("is not a directory"), "{e}");
        std::fs::remove_dir_all(&d).ok();
    }
}
