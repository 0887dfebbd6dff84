//! Mitsuba's binary `.vol` grid format (`VolumeGrid::read` in Mitsuba 3's
//! `src/render/volumegrid.cpp`, documented with the `gridvolume` plugin), read by the
//! `sdfgrid` shape and, later, by grid-based media.
//!
//! Layout, all little endian:
//!
//! | bytes  | content                                                           |
//! |--------|-------------------------------------------------------------------|
//! | 0–2    | ASCII `VOL`                                                       |
//! | 3      | version, must be 3                                                |
//! | 4–7    | encoding (i32); Mitsuba 3 reads only 1 = float32                  |
//! | 8–19   | xres, yres, zres (i32 each)                                       |
//! | 20–23  | channel count (i32)                                               |
//! | 24–47  | bounding box, 6 × f32: xmin, ymin, zmin, xmax, ymax, zmax         |
//! | 48–    | xres·yres·zres·channels f32 values, `((z·yres + y)·xres + x)·channels + c` |
//!
//! Bytes after the data are ignored, as Mitsuba does. The reader is safe on hostile input:
//! it never panics, and allocates only for values whose bytes are present in the input.

use std::path::Path;

/// Size of the fixed header.
pub const HEADER_BYTES: usize = 48;
// The largest `.vol` file read is the `vol_bytes` limit of `crate::limits` (default 8 GiB).

/// A dense grid of `channels`-vectors of f32, as stored in a `.vol` file.
#[derive(Clone, Debug, PartialEq)]
pub struct VolData {
    /// Number of samples along x, y and z (each at least 1).
    pub res: [usize; 3],
    /// Values per sample (at least 1).
    pub channels: usize,
    /// The bounding box stored in the file: `[min, max]`. Mitsuba's `gridvolume` uses it only
    /// with `use_grid_bbox`; the `sdfgrid` shape ignores it.
    pub bbox: [[f32; 3]; 2],
    /// `res[0]·res[1]·res[2]·channels` values, x fastest, channels interleaved.
    pub data: Vec<f32>,
}

impl VolData {
    /// Index of channel `c` of sample `(x, y, z)` in `data`.
    #[inline]
    pub fn index(&self, x: usize, y: usize, z: usize, c: usize) -> usize {
        ((z * self.res[1] + y) * self.res[0] + x) * self.channels + c
    }
}

fn le_i32(b: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn le_f32(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Parses the bytes of a `.vol` file.
pub fn parse_vol(bytes: &[u8]) -> Result<VolData, String> {
    if bytes.len() < 4 || &bytes[..3] != b"VOL" {
        return Err("not a .vol file (no 'VOL' magic)".into());
    }
    if bytes[3] != 3 {
        return Err(format!(
            "unsupported .vol version {} (only version 3 is supported)",
            bytes[3]
        ));
    }
    if bytes.len() < HEADER_BYTES {
        return Err(format!(
            "truncated .vol header: {} of {HEADER_BYTES} bytes",
            bytes.len()
        ));
    }
    let encoding = le_i32(bytes, 4);
    if encoding != 1 {
        return Err(format!(
            "unsupported .vol encoding {encoding} (Mitsuba 3 reads only 1, float32)"
        ));
    }
    let mut res = [0usize; 3];
    for (i, r) in res.iter_mut().enumerate() {
        let v = le_i32(bytes, 8 + 4 * i);
        if v < 1 {
            return Err(format!(
                ".vol resolution along {} is {v}, must be at least 1",
                ["x", "y", "z"][i]
            ));
        }
        *r = v as usize;
    }
    let channels = le_i32(bytes, 20);
    if channels < 1 {
        return Err(format!(
            ".vol channel count is {channels}, must be at least 1"
        ));
    }
    let channels = channels as usize;
    let mut bbox = [[0.0f32; 3]; 2];
    for (k, v) in bbox.iter_mut().flatten().enumerate() {
        *v = le_f32(bytes, 24 + 4 * k);
    }
    let count = (res[0] as u64)
        .checked_mul(res[1] as u64)
        .and_then(|n| n.checked_mul(res[2] as u64))
        .and_then(|n| n.checked_mul(channels as u64));
    let present = ((bytes.len() - HEADER_BYTES) / 4) as u64;
    let count = match count {
        Some(n) if n <= present => n as usize,
        _ => {
            return Err(format!(
                "truncated .vol data: {}x{}x{} samples of {channels} channels need more than the {present} values present",
                res[0], res[1], res[2]
            ))
        }
    };
    let data = bytes[HEADER_BYTES..HEADER_BYTES + 4 * count]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok(VolData {
        res,
        channels,
        bbox,
        data,
    })
}

/// Reads and parses a `.vol` file of at most the `vol_bytes` limit
/// ([`crate::limits::current`]); errors are one line and name the file.
pub fn read_vol(path: &Path) -> Result<VolData, String> {
    let limits = crate::limits::current().map_err(|e| e.to_string())?;
    let bytes = super::read_file_limited(path, limits.file(crate::limits::Limit::VolBytes))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    parse_vol(&bytes).map_err(|e| format!("{}: {e}", path.display()))
}

/// Encodes a grid in the `.vol` format (version 3, float32), as Mitsuba's
/// `VolumeGrid::write`. `data.len()` must be `res[0]·res[1]·res[2]·channels`.
pub fn write_vol(res: [usize; 3], channels: usize, bbox: [[f32; 3]; 2], data: &[f32]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_BYTES + 4 * data.len());
    out.extend_from_slice(b"VOL");
    out.push(3);
    out.extend_from_slice(&1i32.to_le_bytes());
    for r in res {
        out.extend_from_slice(&(r as i32).to_le_bytes());
    }
    out.extend_from_slice(&(channels as i32).to_le_bytes());
    for v in bbox.iter().flatten().chain(data) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn torus_path() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/torus_sdfgrid.vol")
    }

    #[test]
    fn reads_mitsubas_torus() {
        let v = read_vol(&torus_path()).unwrap();
        assert_eq!(v.res, [40, 40, 40]);
        assert_eq!(v.channels, 1);
        assert_eq!(v.data.len(), 40 * 40 * 40);
        // the first values of the file, x fastest
        assert_eq!(v.data[0], f32::from_bits(0x41b8c932));
        assert_eq!(v.data[1], f32::from_bits(0x41b50ecd));
        assert_eq!(v.bbox[0], [0.0; 3]);
        // a torus: positive at the cube's corner, negative somewhere inside
        assert!(v.data[v.index(39, 39, 39, 0)] > 0.0);
        assert!(v.data.iter().any(|&x| x < 0.0));
        assert!(v.data.iter().all(|x| x.is_finite()));
    }

    #[test]
    fn round_trips_any_channel_count() {
        let data: Vec<f32> = (0..2 * 3 * 4 * 3).map(|i| i as f32 * 0.5 - 7.0).collect();
        let bbox = [[-1.0, -2.0, -3.0], [1.0, 2.0, 3.0]];
        let bytes = write_vol([2, 3, 4], 3, bbox, &data);
        assert_eq!(bytes.len(), HEADER_BYTES + 4 * data.len());
        let v = parse_vol(&bytes).unwrap();
        assert_eq!((v.res, v.channels, v.bbox), ([2, 3, 4], 3, bbox));
        assert_eq!(v.data, data);
        assert_eq!(v.data[v.index(1, 2, 3, 2)], data[data.len() - 1]);
        assert_eq!(v.data[v.index(1, 0, 0, 0)], data[3]);
        // trailing bytes are ignored, as by Mitsuba
        let mut longer = bytes.clone();
        longer.extend_from_slice(&[1, 2, 3, 4, 5]);
        assert_eq!(parse_vol(&longer).unwrap(), v);
    }

    #[test]
    fn bad_files_are_one_line_errors() {
        let good = write_vol([2, 2, 2], 1, [[0.0; 3], [1.0; 3]], &[1.0; 8]);
        let with = |at: usize, b: &[u8]| {
            let mut v = good.clone();
            v[at..at + b.len()].copy_from_slice(b);
            v
        };
        let cases: Vec<(&str, Vec<u8>)> = vec![
            ("empty", vec![]),
            ("magic", with(0, b"VOX")),
            ("version 2", with(3, &[2])),
            ("float16 encoding", with(4, &2i32.to_le_bytes())),
            ("negative encoding", with(4, &(-1i32).to_le_bytes())),
            ("zero xres", with(8, &0i32.to_le_bytes())),
            ("negative yres", with(12, &(-5i32).to_le_bytes())),
            ("zero channels", with(20, &0i32.to_le_bytes())),
            ("header only", good[..HEADER_BYTES].to_vec()),
            ("short header", good[..30].to_vec()),
            ("one value short", good[..good.len() - 4].to_vec()),
            ("one byte short", good[..good.len() - 1].to_vec()),
            // 2^31-1 cubed channels: must not try to allocate it
            (
                "huge resolution",
                with(
                    8,
                    &[
                        0xff, 0xff, 0xff, 0x7f, 0xff, 0xff, 0xff, 0x7f, 0xff, 0xff, 0xff, 0x7f,
                    ],
                ),
            ),
            ("huge channels", with(20, &i32::MAX.to_le_bytes())),
        ];
        for (name, bytes) in cases {
            let e = parse_vol(&bytes).expect_err(name);
            assert!(!e.is_empty() && !e.contains('\n'), "{name}: {e}");
        }
        assert!(read_vol(Path::new("/nonexistent/x.vol")).is_err());
        assert!(read_vol(Path::new("/dev/zero")).is_err());
    }
}
