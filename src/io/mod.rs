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
pub mod vol;

use std::fs::File;
use std::io::Read;
use std::path::Path;

/// Largest scene file read (XML, including included files, and `.spd` spectrum files).
pub const MAX_SCENE_FILE_BYTES: u64 = 1 << 28;
/// Largest mesh file read.
pub const MAX_MESH_FILE_BYTES: u64 = 1 << 33;
/// Largest file any loader reads (the largest of [`MAX_SCENE_FILE_BYTES`],
/// [`MAX_MESH_FILE_BYTES`], [`image::MAX_IMAGE_FILE_BYTES`] and [`vol::MAX_VOL_FILE_BYTES`]):
/// what the scene's identity hash (`progressive::scene_hash`) reads of a file at most.
pub const MAX_INPUT_FILE_BYTES: u64 = max(
    max(MAX_SCENE_FILE_BYTES, MAX_MESH_FILE_BYTES),
    max(image::MAX_IMAGE_FILE_BYTES, vol::MAX_VOL_FILE_BYTES),
);

const fn max(a: u64, b: u64) -> u64 {
    if a > b {
        a
    } else {
        b
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
/// error saying which. The type is checked before the file is opened, so that a FIFO's open
/// cannot block waiting for a writer, and again on the opened file.
pub fn open_regular(path: &Path, limit: u64) -> std::io::Result<(File, u64)> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(not_regular(meta.file_type()));
    }
    let file = File::open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(not_regular(meta.file_type()));
    }
    if meta.len() > limit {
        return Err(std::io::Error::other(format!(
            "file of {} bytes exceeds the limit of {limit} bytes",
            meta.len()
        )));
    }
    Ok((file, meta.len()))
}

fn grew_past(limit: u64) -> std::io::Error {
    std::io::Error::other(format!("file exceeds the limit of {limit} bytes"))
}

/// Reads a whole regular file of at most `limit` bytes ([`open_regular`]'s checks; a file
/// that grows past the limit while being read is refused too).
pub fn read_file_limited(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    let (file, len) = open_regular(path, limit)?;
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(grew_past(limit));
    }
    Ok(bytes)
}

/// Streams a regular file of at most `limit` bytes into `consume`, 64 KiB at a time
/// ([`open_regular`]'s checks; memory stays bounded whatever the file's size). Returns the
/// number of bytes read.
pub fn read_file_chunks(
    path: &Path,
    limit: u64,
    mut consume: impl FnMut(&[u8]),
) -> std::io::Result<u64> {
    let (file, _) = open_regular(path, limit)?;
    let mut reader = file.take(limit + 1);
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
        if total > limit {
            return Err(grew_past(limit));
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
