//! Mitsuba's `.serialized` meshes, read the way Mitsuba 3.9.1's `serialized` shape plugin
//! reads them.
//!
//! Format (Mitsuba 3 documentation of the `serialized` plugin, and 3.9.1
//! `src/shapes/serialized.cpp`, `src/core/zstream.cpp`), little endian throughout:
//!
//! | bytes | content |
//! | --- | --- |
//! | u16 | magic `0x041C` |
//! | u16 | version, 3 or 4 |
//! | ... | a zlib stream (RFC 1950/1951) holding the shape: |
//! | u32 | flags: `0x1` normals, `0x2` texture coordinates, `0x8` vertex colours, `0x10` face normals, `0x1000` single, `0x2000` double precision |
//! | bytes, NUL | the shape's name (version 4 only) |
//! | u64, u64 | vertex count, triangle count |
//! | f32/f64 x 3n | positions; then normals (3n), texture coordinates (2n), colours (3n) when flagged |
//! | u32 x 3m | triangles |
//!
//! Several shapes are concatenated, each with its own magic/version and zlib stream; the file
//! ends with the offset of every shape (u64 in version 4, u32 in version 3) and the shape
//! count (u32). Shape 0 is read from the start of the file; any other from its offset.
//!
//! # Mitsuba's behaviour, matched
//!
//! - Only the file's first magic/version is checked; the four bytes at a later shape's
//!   offset are skipped unchecked. The zlib stream is read only as far as the shape needs
//!   (its end and checksum are not required).
//! - Vertex colours (`0x8`) are skipped: Mitsuba 3.9.1 reads past them and keeps no
//!   attribute, so [`MeshData::vertex_attributes`] stays empty. The face-normals flag (`0x10`)
//!   and the single-precision flag are ignored, as in Mitsuba (face normals come from the
//!   scene's `face_normals` parameter only); `0x2000` selects doubles, rounded to `f32`.
//! - Triangles are always `u32`. Positions and normals are returned as stored: Mitsuba does
//!   not check positions for NaN/inf here (unlike `ply`), and normalises normals after
//!   `to_world`, which is the caller's job. Degenerate triangles are kept.
//!
//! # Checks beyond Mitsuba, and limits
//!
//! - An index `>=` the vertex count is an error (Mitsuba 3.9.1 does not check).
//! - Counts above `u32::MAX` are an error (Mitsuba truncates them to 32 bits), and so is a
//!   shape name longer than 64 KiB.
//! - `shape_index` must be below the count at the end of the file (Mitsuba's check lets
//!   `shape_index == count` through; it then fails reading version 4 and takes the count
//!   for an offset in version 3).
//! - Hostile input: never panics, no recursion. Before anything is inflated, the bytes the
//!   counts and flags ask for are checked against the `shape_bytes` limit of
//!   [`crate::limits`] (default 8 GiB, as a mesh file) and against what the
//!   compressed bytes can hold ([`MAX_ZLIB_EXPANSION`], deflate's 1032:1), so a
//!   decompression bomb is refused at once; then exactly those bytes are inflated (never
//!   more), collected as they arrive (nothing is allocated from a header count), and a short
//!   stream is an error.

use super::mesh::MeshData;
use std::io::Read;

const MAGIC: u16 = 0x041C;
const HAS_NORMALS: u32 = 0x0001;
const HAS_TEXCOORDS: u32 = 0x0002;
const HAS_COLORS: u32 = 0x0008;
const DOUBLE_PRECISION: u32 = 0x2000;
/// Longest shape name read (a guard against a name that never ends).
const MAX_NAME_BYTES: usize = 1 << 16;
/// Most bytes one compressed byte can inflate to: deflate's maximum ratio (a 258-byte match
/// in two bits) is 1032:1.
pub const MAX_ZLIB_EXPANSION: u64 = 1032;
/// Decompressed bytes always allowed whatever the compressed length (tiny meshes).
const EXPANSION_SLACK: u64 = 1 << 16;

/// One shape of a `.serialized` file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SerializedShape {
    /// The shape's name (version 4 files; `None` in version 3).
    pub name: Option<String>,
    pub mesh: MeshData,
}

/// Reads shape `shape_index` of a `.serialized` file held in memory.
pub fn read_serialized(bytes: &[u8], shape_index: usize) -> Result<MeshData, String> {
    read_serialized_shape(bytes, shape_index).map(|s| s.mesh)
}

/// The number of shapes in a `.serialized` file, from the table at its end.
pub fn serialized_shape_count(bytes: &[u8]) -> Result<usize, String> {
    let version = read_version(bytes)?;
    let count = table_count(bytes)?;
    let entry = if version == 4 { 8 } else { 4 };
    // The table and the header of the first shape must fit in the file.
    let table = (count as u64) * entry + 4;
    if table + 4 > bytes.len() as u64 {
        return Err(format!(
            "the file ({} bytes) is too short for a table of {count} shapes",
            bytes.len()
        ));
    }
    Ok(count as usize)
}

/// [`read_serialized`], also returning the shape's name.
pub fn read_serialized_shape(bytes: &[u8], shape_index: usize) -> Result<SerializedShape, String> {
    let version = read_version(bytes)?;
    let start = if shape_index == 0 {
        4
    } else {
        let count = serialized_shape_count(bytes)?;
        if shape_index >= count {
            return Err(format!(
                "shape index {shape_index} is out of range (the file has {count} shapes)"
            ));
        }
        let from_end = (count - shape_index) as u64;
        let len = bytes.len() as u64;
        let offset = if version == 4 {
            read_u64(bytes, len - 8 * from_end - 4)
        } else {
            read_u32(bytes, len - 4 * (from_end + 1)).map(u64::from)
        }
        .ok_or("the shape table is truncated")?;
        // Skip the shape's (unchecked) magic and version, as Mitsuba does.
        match offset.checked_add(4) {
            Some(s) if s <= len => s as usize,
            _ => {
                return Err(format!(
                    "shape {shape_index} starts at offset {offset}, beyond the end of the file"
                ))
            }
        }
    };
    let mut z = Inflate {
        decoder: flate2::read::ZlibDecoder::new(&bytes[start..]),
        shape_index,
    };
    let flags = u32::from_le_bytes(z.array::<4>("flags")?);
    let name = if version == 4 { Some(z.name()?) } else { None };
    let vertex_count = u64::from_le_bytes(z.array::<8>("vertex count")?);
    let face_count = u64::from_le_bytes(z.array::<8>("triangle count")?);
    let limit = u64::from(u32::MAX);
    if vertex_count > limit || face_count > limit {
        return Err(format!(
            "{vertex_count} vertices and {face_count} triangles: more than 2^32 - 1 is not \
             supported (Mitsuba truncates the counts)"
        ));
    }
    let (nv, nf) = (vertex_count as usize, face_count as usize);
    let double = flags & DOUBLE_PRECISION != 0;
    check_shape_size(flags, vertex_count, face_count, bytes.len() - start)
        .map_err(|e| format!("shape {shape_index}: {e}"))?;
    let positions = z.vectors::<3>(nv, double, "positions")?;
    let normals = if flags & HAS_NORMALS != 0 {
        Some(z.vectors::<3>(nv, double, "normals")?)
    } else {
        None
    };
    let uvs = if flags & HAS_TEXCOORDS != 0 {
        Some(z.vectors::<2>(nv, double, "texture coordinates")?)
    } else {
        None
    };
    if flags & HAS_COLORS != 0 {
        z.vectors::<3>(nv, double, "vertex colours")?;
    }
    let raw = z.bytes(nf * 12, "triangles")?;
    let triangles = raw
        .chunks_exact(12)
        .map(|c| {
            let u = |i: usize| u32::from_le_bytes([c[i], c[i + 1], c[i + 2], c[i + 3]]);
            [u(0), u(4), u(8)]
        })
        .collect();
    let mesh = MeshData {
        positions,
        normals,
        uvs,
        triangles,
        vertex_attributes: Vec::new(),
        face_attributes: Vec::new(),
    };
    mesh.validate()
        .map_err(|e| format!("shape {shape_index}: {e}"))?;
    Ok(SerializedShape { name, mesh })
}

/// Checks, before anything is inflated, that the bytes the header's counts and flags ask for
/// are at most the `shape_bytes` limit and can come out of the `compressed` bytes from the
/// shape's start to the end of the file ([`MAX_ZLIB_EXPANSION`]): a decompression bomb whose
/// counts claim more than its stream can hold is refused here, not after inflating it.
fn check_shape_size(
    flags: u32,
    vertices: u64,
    faces: u64,
    compressed: usize,
) -> Result<(), String> {
    let scalar = if flags & DOUBLE_PRECISION != 0 { 8 } else { 4 };
    let mut per_vertex = 3 * scalar;
    for (flag, n) in [(HAS_NORMALS, 3), (HAS_TEXCOORDS, 2), (HAS_COLORS, 3)] {
        if flags & flag != 0 {
            per_vertex += n * scalar;
        }
    }
    let needed = vertices
        .saturating_mul(per_vertex)
        .saturating_add(faces.saturating_mul(12));
    let limits = crate::limits::current().map_err(|e| e.to_string())?;
    if needed > limits.shape_bytes {
        return Err(format!(
            "{vertices} vertices and {faces} triangles need {needed} bytes of mesh data, more \
             than {}",
            limits.exceeded(crate::limits::Limit::ShapeBytes)
        ));
    }
    let bound = (compressed as u64)
        .saturating_mul(MAX_ZLIB_EXPANSION)
        .saturating_add(EXPANSION_SLACK);
    if needed > bound {
        return Err(format!(
            "{vertices} vertices and {faces} triangles need {needed} bytes, more than \
             {compressed} compressed bytes can hold (deflate expands at most \
             {MAX_ZLIB_EXPANSION} times)"
        ));
    }
    Ok(())
}

fn read_u32(bytes: &[u8], at: u64) -> Option<u32> {
    let at = usize::try_from(at).ok()?;
    Some(u32::from_le_bytes(
        bytes.get(at..at.checked_add(4)?)?.try_into().ok()?,
    ))
}

fn read_u64(bytes: &[u8], at: u64) -> Option<u64> {
    let at = usize::try_from(at).ok()?;
    Some(u64::from_le_bytes(
        bytes.get(at..at.checked_add(8)?)?.try_into().ok()?,
    ))
}

fn read_version(bytes: &[u8]) -> Result<u16, String> {
    let (Some(magic), Some(version)) = (bytes.get(0..2), bytes.get(2..4)) else {
        return Err("not a serialized mesh: the file is shorter than its header".into());
    };
    let magic = u16::from_le_bytes([magic[0], magic[1]]);
    let version = u16::from_le_bytes([version[0], version[1]]);
    if magic != MAGIC {
        return Err(format!(
            "not a serialized mesh: magic number {magic:#06x}, expected {MAGIC:#06x}"
        ));
    }
    if version != 3 && version != 4 {
        return Err(format!(
            "unsupported serialized mesh version {version} (Mitsuba reads 3 and 4)"
        ));
    }
    Ok(version)
}

/// The shape count in the last four bytes.
fn table_count(bytes: &[u8]) -> Result<u32, String> {
    let len = bytes.len() as u64;
    if len < 8 {
        return Err("the file is too short for a shape table".into());
    }
    read_u32(bytes, len - 4).ok_or_else(|| "the file is too short for a shape table".into())
}

/// The decompressed stream of one shape.
struct Inflate<'a> {
    decoder: flate2::read::ZlibDecoder<&'a [u8]>,
    shape_index: usize,
}

impl Inflate<'_> {
    /// Reads exactly `n` bytes, growing the buffer only as data arrives.
    fn bytes(&mut self, n: usize, what: &str) -> Result<Vec<u8>, String> {
        const CHUNK: usize = 1 << 20;
        let mut out = Vec::with_capacity(n.min(CHUNK));
        let got = (&mut self.decoder)
            .take(n as u64)
            .read_to_end(&mut out)
            .map_err(|e| {
                format!(
                    "shape {}: corrupt zlib stream while reading the {what}: {e}",
                    self.shape_index
                )
            })?;
        if got != n {
            return Err(format!(
                "shape {}: the compressed data ends after {got} of the {n} bytes of the {what}",
                self.shape_index
            ));
        }
        Ok(out)
    }

    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], String> {
        let v = self.bytes(N, what)?;
        let mut a = [0u8; N];
        a.copy_from_slice(&v);
        Ok(a)
    }

    /// The NUL-terminated name, at most [`MAX_NAME_BYTES`] long (Mitsuba has no limit).
    fn name(&mut self) -> Result<String, String> {
        let mut name = Vec::new();
        let mut c = [0u8; 1];
        loop {
            match self.decoder.read(&mut c) {
                Ok(1) if c[0] == 0 => return Ok(String::from_utf8_lossy(&name).into_owned()),
                Ok(1) if name.len() < MAX_NAME_BYTES => name.push(c[0]),
                Ok(1) => {
                    return Err(format!(
                        "shape {}: the shape name is longer than {MAX_NAME_BYTES} bytes",
                        self.shape_index
                    ))
                }
                Ok(_) => {
                    return Err(format!(
                        "shape {}: the compressed data ends inside the shape name",
                        self.shape_index
                    ))
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    return Err(format!(
                        "shape {}: corrupt zlib stream while reading the shape name: {e}",
                        self.shape_index
                    ))
                }
            }
        }
    }

    /// `count` vectors of `N` floats, stored as f32 or f64.
    fn vectors<const N: usize>(
        &mut self,
        count: usize,
        double: bool,
        what: &str,
    ) -> Result<Vec<[f32; N]>, String> {
        let size = if double { 8 } else { 4 };
        let n = count
            .checked_mul(N * size)
            .ok_or_else(|| format!("shape {}: too many {what}", self.shape_index))?;
        let raw = self.bytes(n, what)?;
        Ok(raw
            .chunks_exact(N * size)
            .map(|v| {
                std::array::from_fn(|k| {
                    let c = &v[k * size..(k + 1) * size];
                    if double {
                        f64::from_le_bytes(c.try_into().unwrap_or([0; 8])) as f32
                    } else {
                        f32::from_le_bytes(c.try_into().unwrap_or([0; 4]))
                    }
                })
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    //! Expected values: the two Mitsuba files were decoded independently (Python's zlib and
    //! struct) and that decoding was checked against Mitsuba 3.9.1's `mi.traverse` of the
    //! loaded shapes (positions, faces, texture coordinates equal; normals equal after
    //! normalisation). The synthetic files below were also loaded in Mitsuba 3.9.1.
    use super::*;
    use std::io::Write;

    fn data(name: &str) -> Vec<u8> {
        let path = format!("{}/tests/data/meshes/{name}", env!("CARGO_MANIFEST_DIR"));
        std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
    }

    #[test]
    fn rectangle_v4_with_normals_and_uvs() {
        let bytes = data("rectangle_normals_uv.serialized");
        assert_eq!(serialized_shape_count(&bytes), Ok(1));
        let s = read_serialized_shape(&bytes, 0).unwrap();
        assert_eq!(s.name.as_deref(), Some("rectangle_normals_uv"));
        let m = s.mesh;
        assert_eq!(
            m.positions,
            [
                [-2.85, 0.0, -7.6],
                [-2.85, 0.0, 0.599999],
                [2.85, 0.0, 0.599999],
                [2.85, 0.0, -7.6]
            ]
        );
        assert_eq!(m.normals, Some(vec![[0.0, 1.0, 0.0]; 4]));
        let uvs = m.uvs.unwrap();
        assert_eq!(
            (uvs[0], uvs[3]),
            ([0.950589, 0.011583984], [0.950589, 0.31087297])
        );
        assert_eq!(m.triangles, [[0, 1, 2], [0, 2, 3]]);
        assert!(m.vertex_attributes.is_empty() && m.face_attributes.is_empty());
        assert!(read_serialized(&bytes, 1)
            .unwrap_err()
            .contains("out of range"));
    }

    #[test]
    fn matpreview_v3_three_shapes() {
        let bytes = data("matpreview.serialized");
        assert_eq!(serialized_shape_count(&bytes), Ok(3));
        let expected = [
            (
                289,
                512,
                [-0.50486624, 0.57472086, 0.784379],
                [285, 288, 286],
            ),
            (
                2078,
                3936,
                [0.66702855, 0.27629226, 0.06282294],
                [1861, 2077, 1865],
            ),
            (
                29439,
                57152,
                [0.047490597, -0.44950318, -0.90268445],
                [29438, 29380, 29428],
            ),
        ];
        for (i, (nv, nf, p0, f_last)) in expected.into_iter().enumerate() {
            let s = read_serialized_shape(&bytes, i).unwrap();
            assert_eq!(s.name, None);
            let m = s.mesh;
            assert_eq!(
                (m.positions.len(), m.triangles.len()),
                (nv, nf),
                "shape {i}"
            );
            assert_eq!(m.positions[0], p0, "shape {i}");
            assert_eq!(m.triangles[0], [0, 1, 2]);
            assert_eq!(m.triangles[nf - 1], f_last, "shape {i}");
            assert_eq!(m.normals.as_ref().map(|n| n.len()), Some(nv));
            assert_eq!(m.uvs.as_ref().map(|n| n.len()), Some(nv));
        }
        let m = read_serialized(&bytes, 2).unwrap();
        assert_eq!(
            m.normals.unwrap()[29438],
            [0.48664814, 0.52055424, 0.70152897]
        );
        assert_eq!(m.uvs.unwrap()[0], [0.903927, 0.86437035]);
        let m = read_serialized(&bytes, 0).unwrap();
        assert_eq!(
            m.normals.unwrap()[0],
            [-0.000549333, -0.98907435, 0.14722127]
        );
        assert_eq!(m.uvs.unwrap()[288], [0.030994356, 0.030993223]);
        assert!(read_serialized(&bytes, 3)
            .unwrap_err()
            .contains("out of range"));
    }

    const P: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.5],
    ];
    const F: [[u32; 3]; 2] = [[0, 1, 2], [2, 1, 3]];

    struct Shape<'a> {
        flags: u32,
        name: &'a str,
        counts: Option<(u64, u64)>,
        arrays: Vec<Vec<f64>>,
        faces: &'a [[u32; 3]],
    }

    fn shape(version: u16, s: &Shape) -> Vec<u8> {
        let mut d = s.flags.to_le_bytes().to_vec();
        if version == 4 {
            d.extend(s.name.as_bytes());
            d.push(0);
        }
        let (nv, nf) = s.counts.unwrap_or((4, s.faces.len() as u64));
        d.extend(nv.to_le_bytes());
        d.extend(nf.to_le_bytes());
        for a in &s.arrays {
            for &x in a {
                if s.flags & DOUBLE_PRECISION != 0 {
                    d.extend(x.to_le_bytes());
                } else {
                    d.extend((x as f32).to_le_bytes());
                }
            }
        }
        for f in s.faces {
            for i in f {
                d.extend(i.to_le_bytes());
            }
        }
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&d).unwrap();
        [
            &MAGIC.to_le_bytes()[..],
            &version.to_le_bytes(),
            &z.finish().unwrap(),
        ]
        .concat()
    }

    fn file(version: u16, shapes: &[Shape]) -> Vec<u8> {
        let mut out = Vec::new();
        let mut offsets = Vec::new();
        for s in shapes {
            offsets.push(out.len() as u64);
            out.extend(shape(version, s));
        }
        for o in offsets {
            if version == 4 {
                out.extend(o.to_le_bytes());
            } else {
                out.extend((o as u32).to_le_bytes());
            }
        }
        out.extend((shapes.len() as u32).to_le_bytes());
        out
    }

    fn flat<const N: usize>(v: &[[f32; N]]) -> Vec<f64> {
        v.iter().flatten().map(|&x| x as f64).collect()
    }

    fn plain(flags: u32, arrays: Vec<Vec<f64>>) -> Shape<'static> {
        Shape {
            flags,
            name: "plain",
            counts: None,
            arrays,
            faces: &F,
        }
    }

    #[test]
    fn flags_select_the_arrays_and_colours_are_skipped() {
        let normals = [
            [0.0, 0.0, 2.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.5, 1.0],
            [0.0, 0.0, 3.0],
        ];
        let uvs = [[0.0f32, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
        let colours = flat(&[[9.0f32; 3]; 4]);
        let bytes = file(
            4,
            &[
                plain(0x1003, vec![flat(&P), flat(&normals), flat(&uvs)]),
                // Double precision with colours and the face-normals flag: both ignored by
                // Mitsuba 3.9.1 (no attribute, normals still read).
                plain(
                    0x2000 | 0x10 | 0x8 | 0x1,
                    vec![flat(&P), flat(&normals), colours],
                ),
                plain(0, vec![flat(&P)]),
            ],
        );
        assert_eq!(serialized_shape_count(&bytes), Ok(3));
        let a = read_serialized_shape(&bytes, 0).unwrap();
        assert_eq!(a.name.as_deref(), Some("plain"));
        assert_eq!(a.mesh.positions, P);
        assert_eq!(a.mesh.normals.as_deref(), Some(&normals[..]));
        assert_eq!(a.mesh.uvs.as_deref(), Some(&uvs[..]));
        assert_eq!(a.mesh.triangles, F);
        let b = read_serialized(&bytes, 1).unwrap();
        assert_eq!(b.positions, P);
        assert_eq!(b.normals.as_deref(), Some(&normals[..]));
        assert_eq!((b.uvs, b.vertex_attributes.len()), (None, 0));
        assert_eq!(b.triangles, F);
        let c = read_serialized(&bytes, 2).unwrap();
        assert_eq!((c.positions.len(), c.normals, c.uvs), (4, None, None));
        // Version 3: no names, u32 offsets.
        let v3 = file(
            3,
            &[
                plain(0x1000, vec![flat(&P)]),
                plain(0x1002, vec![flat(&P), flat(&uvs)]),
            ],
        );
        assert_eq!(serialized_shape_count(&v3), Ok(2));
        let s = read_serialized_shape(&v3, 1).unwrap();
        assert_eq!((s.name, s.mesh.uvs.as_deref()), (None, Some(&uvs[..])));
        // Non-finite positions and degenerate faces are kept, as in Mitsuba.
        let mut p = P;
        p[1][0] = f32::NAN;
        let m = read_serialized(&file(4, &[plain(0, vec![flat(&p)])]), 0).unwrap();
        assert!(m.positions[1][0].is_nan());
        let degenerate = [[0, 0, 1]];
        let s = Shape {
            faces: &degenerate,
            ..plain(0, vec![flat(&P)])
        };
        assert_eq!(
            read_serialized(&file(4, &[s]), 0).unwrap().triangles,
            degenerate
        );
    }

    #[test]
    fn shape_zero_needs_no_table_but_the_count_does() {
        let single = shape(4, &plain(0, vec![flat(&P)]));
        assert_eq!(read_serialized(&single, 0).unwrap().positions, P);
        assert!(serialized_shape_count(&single).is_err());
        assert!(read_serialized(&single, 1).is_err());
    }

    fn err(bytes: &[u8], index: usize) -> String {
        match read_serialized(bytes, index) {
            Ok(m) => panic!("accepted: {m:?}"),
            Err(e) => {
                assert!(!e.contains('\n'), "{e:?}");
                e
            }
        }
    }

    #[test]
    fn malformed_files_are_errors() {
        let good = file(
            4,
            &[plain(0x1000, vec![flat(&P)]), plain(0x1000, vec![flat(&P)])],
        );
        assert!(err(&[], 0).contains("shorter than its header"));
        assert!(err(&good[..3], 0).contains("shorter than its header"));
        let mut wrong = good.clone();
        wrong[0] = 0x1d;
        assert!(err(&wrong, 0).contains("magic"));
        let mut v5 = good.clone();
        v5[2] = 5;
        assert!(err(&v5, 0).contains("version 5"));
        // A broken zlib header, then a broken deflate body.
        let mut bad = good.clone();
        bad[4] ^= 0xff;
        assert!(err(&bad, 0).contains("corrupt zlib"));
        let mut bad = good.clone();
        for b in &mut bad[6..30] {
            *b = 0xff;
        }
        assert!(err(&bad, 0).contains("zlib") || err(&bad, 0).contains("ends"));
        // Truncated inside the compressed data.
        let one = shape(4, &plain(0x1000, vec![flat(&P)]));
        for n in [5, 12, one.len() - 10] {
            let e = err(&one[..n], 0);
            assert!(e.contains("ends") || e.contains("zlib"), "{n}: {e}");
        }
        // Huge counts in a tiny stream: an error, not an allocation.
        for counts in [(1u64 << 60, 2), (4, 1 << 60), (1 << 32, 1)] {
            let s = Shape {
                counts: Some(counts),
                ..plain(0, vec![flat(&P)])
            };
            let e = err(&shape(4, &s), 0);
            assert!(e.contains("ends after") || e.contains("2^32"), "{e}");
        }
        // An index out of range.
        let oob = [[0, 1, 4]];
        let s = Shape {
            faces: &oob,
            ..plain(0, vec![flat(&P)])
        };
        assert!(err(&shape(4, &s), 0).contains("vertex 4"));
        // Table entries that point nowhere, and a count larger than the file.
        let mut far = good.clone();
        let at = far.len() - 4 - 8;
        far[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(err(&far, 1).contains("beyond the end"));
        let mut many = good.clone();
        let at = many.len() - 4;
        many[at..].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(err(&many, 1).contains("too short for a table"));
        // A name that never ends.
        let mut d = 0u32.to_le_bytes().to_vec();
        d.extend(vec![b'a'; MAX_NAME_BYTES + 10]);
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&d).unwrap();
        let long = [&[0x1c, 0x04, 4, 0][..], &z.finish().unwrap()].concat();
        assert!(err(&long, 0).contains("longer than"));
    }

    #[test]
    fn garbage_never_panics() {
        let good = file(
            4,
            &[
                plain(0x1003, vec![flat(&P), flat(&P), flat(&P)[..8].to_vec()]),
                plain(0, vec![flat(&P)]),
            ],
        );
        for n in 0..good.len() {
            for i in 0..3 {
                let _ = read_serialized(&good[..n], i);
            }
            let _ = serialized_shape_count(&good[..n]);
        }
        for i in 0..good.len() {
            for x in [0u8, 0xff, 0x01] {
                let mut f = good.clone();
                f[i] = x;
                let _ = read_serialized(&f, 0);
                let _ = read_serialized(&f, 1);
            }
        }
    }
}
