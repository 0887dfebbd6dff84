//! File input and output: images (and texture images, [`image`]), the mesh formats Mitsuba reads (PLY, serialized; OBJ goes
//! through tobj) and Mitsuba's `.vol` grid files.
//!
//! Every input file is opened through [`open_regular`]: only regular files (after
//! following symbolic links) of at most a loader's size limit are read. Devices (a scene
//! naming `/dev/zero` must fail, not fill the memory), FIFOs (which would block the open
//! until a writer comes), sockets and directories are refused before the file is opened.
pub mod atomic;
pub mod exr;
pub mod image;
pub mod mesh;
pub mod ply;
pub mod png;
pub mod serialized;
pub mod tev;
pub mod vol;

use std::fs::File;
use std::io::Read;
use std::path::Path;

/// Largest scene file read (XML, including included files, and `.spd` spectrum files).
/// Fixed: it guards against hostile files, not real scenes (the other file limits are
/// [`crate::limits`]'s).
pub const MAX_SCENE_FILE_BYTES: u64 = 1 << 28;

/// A bound on a file's size: its bytes and, for the limits `PENUMBRA_LIMITS` sets (see
/// [`crate::limits`]), which one, so that the message refusing a larger file says how to
/// raise it. A fixed limit converts from its bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FileLimit {
    pub bytes: u64,
    pub limit: Option<crate::limits::Limit>,
}

impl From<u64> for FileLimit {
    fn from(bytes: u64) -> Self {
        FileLimit { bytes, limit: None }
    }
}

impl FileLimit {
    /// `the limit of N bytes`, or `the mesh_bytes limit of 8 GiB (raise it with ...)`.
    fn describe(&self) -> String {
        match self.limit {
            None => format!("the limit of {} bytes", self.bytes),
            Some(limit) => limit.exceeded(self.bytes),
        }
    }
}

/// Why a file that is not a regular file is refused, from its type.
fn not_regular(kind: std::fs::FileType) -> std::io::Error {
    #[cfg(unix)]
    let what = {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_fifo() {
            "a FIFO"
        } else if kind.is_char_device() || kind.is_block_device() {
            "a device"
        } else if kind.is_socket() {
            "a socket"
        } else if kind.is_dir() {
            "a directory"
        } else {
            "a special file"
        }
    };
    #[cfg(not(unix))]
    let what = if kind.is_dir() {
        "a directory"
    } else {
        "a special file"
    };
    std::io::Error::other(format!("is {what}, not a regular file"))
}

/// Opens a regular file of at most `limit` bytes and returns it with its size. Anything
/// else (a device, a FIFO, a socket, a directory) and a larger file are refused with an
/// error saying which (and, for a named limit, how to raise it). The type is checked before
/// the file is opened, so that a FIFO's open cannot block waiting for a writer, and again on
/// the opened file.
pub fn open_regular(path: &Path, limit: impl Into<FileLimit>) -> std::io::Result<(File, u64)> {
    let limit = limit.into();
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(not_regular(meta.file_type()));
    }
    let file = File::open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(not_regular(meta.file_type()));
    }
    if meta.len() > limit.bytes {
        return Err(std::io::Error::other(format!(
            "file of {} bytes exceeds {}",
            meta.len(),
            limit.describe()
        )));
    }
    Ok((file, meta.len()))
}

fn grew_past(limit: &FileLimit) -> std::io::Error {
    std::io::Error::other(format!("file exceeds {}", limit.describe()))
}

/// Reads a whole regular file of at most `limit` bytes ([`open_regular`]'s checks; a file
/// that grows past the limit while being read is refused too).
pub fn read_file_limited(path: &Path, limit: impl Into<FileLimit>) -> std::io::Result<Vec<u8>> {
    let limit = limit.into();
    let (file, len) = open_regular(path, limit)?;
    let mut bytes = Vec::new();
    bytes
        .try_reserve_exact(usize::try_from(len).unwrap_or(usize::MAX))
        .map_err(|_| {
            std::io::Error::other(format!("cannot allocate {len} bytes to read the file"))
        })?;
    file.take(limit.bytes.saturating_add(1))
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit.bytes {
        return Err(grew_past(&limit));
    }
    Ok(bytes)
}

/// Streams a regular file of at most `limit` bytes into `consume`, 64 KiB at a time
/// ([`open_regular`]'s checks; memory stays bounded whatever the file's size). Returns the
/// number of bytes read.
pub fn read_file_chunks(
    path: &Path,
    limit: impl Into<FileLimit>,
    mut consume: impl FnMut(&[u8]),
) -> std::io::Result<u64> {
    let limit = limit.into();
    let (file, _) = open_regular(path, limit)?;
    let mut reader = file.take(limit.bytes.saturating_add(1));
    let mut buf = vec![0u8; 1 << 16];
    let mut total = 0u64;
    loop {
        let n = match reader.read(&mut buf) {
            Ok(0) => return Ok(total),
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        total += n as u64;
        if total > limit.bytes {
            return Err(grew_past(&limit));
        }
        consume(&buf[..n]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("penumbra-io-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn regular_files_are_read_whole_or_in_chunks_within_the_limit() {
        let dir = temp_dir("regular");
        let path = dir.join("f.bin");
        let data: Vec<u8> = (0..200_000u32).map(|i| (i * 7 % 251) as u8).collect();
        std::fs::write(&path, &data).unwrap();
        assert_eq!(read_file_limited(&path, 200_000).unwrap(), data);
        let mut streamed = Vec::new();
        let n = read_file_chunks(&path, 200_000, |c| streamed.extend_from_slice(c)).unwrap();
        assert_eq!((n, streamed), (200_000, data));
        for e in [
            read_file_limited(&path, 199_999).unwrap_err(),
            read_file_chunks(&path, 199_999, |_| panic!("read past the limit")).unwrap_err(),
        ] {
            assert_eq!(
                e.to_string(),
                "file of 200000 bytes exceeds the limit of 199999 bytes"
            );
        }
        // a limit PENUMBRA_LIMITS sets says so
        let named = FileLimit {
            bytes: 199_999,
            limit: Some(crate::limits::Limit::MeshBytes),
        };
        for e in [
            read_file_limited(&path, named).unwrap_err(),
            read_file_chunks(&path, named, |_| panic!("read past the limit")).unwrap_err(),
        ] {
            assert_eq!(
                e.to_string(),
                "file of 200000 bytes exceeds the mesh_bytes limit of 199999 bytes (raise it \
                 with PENUMBRA_LIMITS=mesh_bytes=...)"
            );
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    #[cfg(unix)]
    #[test]
    fn devices_fifos_and_directories_are_refused_without_reading_or_blocking() {
        let dir = temp_dir("special");
        let fifo = dir.join("fifo");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        let mut cases = vec![
            (
                std::path::PathBuf::from("/dev/zero"),
                "is a device, not a regular file",
            ),
            (dir.clone(), "is a directory, not a regular file"),
        ];
        if made.is_ok_and(|s| s.success()) {
            cases.push((fifo, "is a FIFO, not a regular file"));
        } else {
            eprintln!("mkfifo is missing: the FIFO case is skipped");
        }
        for (path, message) in cases {
            // no reader may come: a blocking open of the FIFO would hang the test
            let e = read_file_limited(&path, u64::MAX).unwrap_err();
            assert_eq!(e.to_string(), message, "{}", path.display());
            let e = read_file_chunks(&path, u64::MAX, |_| panic!("read a special file"));
            assert_eq!(e.unwrap_err().to_string(), message, "{}", path.display());
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
