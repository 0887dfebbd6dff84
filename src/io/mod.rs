//! File input and output: images (and texture images, [`image`]), the mesh formats Mitsuba reads (PLY, serialized; OBJ goes
//! through tobj) and Mitsuba's `.vol` grid files.
pub mod exr;
pub mod image;
pub mod mesh;
pub mod ply;
pub mod png;
pub mod serialized;
pub mod vol;

use std::io::Read;
use std::path::Path;

/// Largest scene file read (XML, including included files).
pub const MAX_SCENE_FILE_BYTES: u64 = 1 << 28;
/// Largest mesh file read.
pub const MAX_MESH_FILE_BYTES: u64 = 1 << 33;

/// Reads a whole regular file of at most `limit` bytes. Devices, FIFOs and directories are
/// refused before reading (a scene naming /dev/zero must fail, not fill the memory).
pub fn read_file_limited(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(std::io::Error::other("not a regular file"));
    }
    if meta.len() > limit {
        return Err(std::io::Error::other(format!(
            "file of {} bytes exceeds the limit of {limit} bytes",
            meta.len()
        )));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(std::io::Error::other(format!(
            "file exceeds the limit of {limit} bytes"
        )));
    }
    Ok(bytes)
}
