//! Stanford PLY meshes, read the way Mitsuba 3.9.1's `ply` shape plugin reads them.
//!
//! Format: Greg Turk, "The PLY Polygon File Format" (1994), ASCII and binary little/big
//! endian, version 1.0. Behaviour: Mitsuba 3.9.1 `src/shapes/ply.cpp` and `ply.h`, checked
//! against the installed Mitsuba 3.9.1 (scalar_rgb) on hand-made files; where the two
//! disagree, the running Mitsuba wins (noted below). Mitsuba's later development sources
//! (b45b0a9, the PackedMesh rewrite) differ in places, e.g. they reject out-of-range indices.
//!
//! # What is read, as Mitsuba reads it
//!
//! - **Header.** `ply`, then `format ascii|binary_little_endian|binary_big_endian 1.0`,
//!   `element NAME COUNT`, `property TYPE NAME`, `property list COUNT_TYPE ITEM_TYPE NAME`,
//!   `comment ...`, `end_header`. Any other keyword (including `obj_info`) is an error, as in
//!   Mitsuba. Types: `char uchar short ushort int uint float double` and Mitsuba's extras
//!   `int8 uint8 int16 uint16 int32 uint32 long ulong half float16 float32 float64`. Names
//!   are case-sensitive; two properties of one element may not share a name.
//! - **Lists are exactly three items.** Mitsuba lays a list out as a count followed by three
//!   items, wherever it occurs, and in the `vertex` and `face` elements requires every count
//!   to be 3: quads and polygons are **not** triangulated but rejected ("is this a triangle
//!   mesh?"). An element can hold at most one list. Lists in other elements are skipped as
//!   count + 3 items, whatever the count says.
//! - **`vertex`**: `x y z` (required); `nx ny nz` (all three, else no normals); texture
//!   coordinates `u v`, else `texture_u texture_v`, else `s t`.
//! - **`face`**: needs a list called `vertex_indices` or `vertex_index`.
//! - **Other elements** are skipped (with a warning). A second `vertex` or `face` element is
//!   an error.
//! - **Attributes** (Mitsuba's `find_other_fields`), for the `vertex` and `face` elements:
//!   `r g b [a]` or `red green blue [alpha]` become `vertex_color`/`face_color` (3 or 4
//!   channels). Other properties named `PREFIX_C` group into `vertex_PREFIX`/`face_PREFIX` when
//!   consecutive with suffixes `x y z [w]`, `r g b [a]` (named `..._PREFIX_color`), `0 1 2 [3]`
//!   or `1 2 3 [4]`, and only with 1 or 3 channels (2 or 4 are dropped with a warning).
//!   Properties without `_`, with a longer suffix, a repeated prefix or a broken sequence are
//!   dropped; the quirks of Mitsuba's scan (a broken sequence also swallows the property after
//!   it) are reproduced.
//! - **Conversion to `f32`** (what the installed Mitsuba's struct converter does, measured):
//!   `uchar` and `long` values are taken as they are (colours in `uchar` stay 0..255; Mitsuba
//!   only warns). `char short ushort int uint ulong` are divided by their type's maximum and
//!   then decoded from sRGB to linear. `half float double` are rounded to `f32`. This applies
//!   to every scalar property, positions included. sRGB is evaluated exactly here; Mitsuba's
//!   JIT uses an approximation, so such values agree to ~3e-6 relative, not bit for bit.
//! - **Face indices**: `uint` items are taken as they are; every other item type goes through
//!   `f32` (so `int` indices above 2^24 round, as in Mitsuba), rounds half to even, and clamps
//!   to [0, 4294967040]: `-1` becomes vertex 0, as in Mitsuba. A NaN index is an error.
//! - **ASCII** values are whitespace-separated tokens, each a whole number of its type (C++
//!   stream rules: unsigned types wrap a leading `-`, floats reject `nan`/`inf` and overflow).
//!   Mitsuba's stream would split a token like `1.0` for an integer field into `1` and `.0`;
//!   here that is an error.
//! - Trailing data after the last element is an error (binary and ASCII).
//!
//! # Checks beyond Mitsuba, and limits
//!
//! - Non-finite positions are an error (Mitsuba checks them after `to_world`); normals, UVs
//!   and attributes may be non-finite, as in Mitsuba.
//! - A face index `>=` the vertex count is an error. Mitsuba 3.9.1 does not check and later
//!   reads out of bounds (crashes while computing normals, or renders garbage).
//! - Degenerate triangles are kept (as in Mitsuba); the caller drops them.
//! - Hostile input: never panics, no recursion; every count from the header is checked
//!   against the bytes actually present before anything is allocated, so memory stays within
//!   a small multiple of the file size. Normals are returned as stored; Mitsuba normalises
//!   them after `to_world`, which is the caller's job (see [`super::mesh`]).
//!
//! Why not the `ply-rs-bw` crate: it reads lists of any length (Mitsuba reads exactly three,
//! which decides which files load), has no `half`/`long`/`ulong` types, accepts `obj_info`,
//! keeps one hash map per vertex, and cannot reproduce Mitsuba's attribute grouping and
//! integer conversions; a reader of Mitsuba's semantics is about as long as the glue.
//!
//! The reader is in three parts: `header` parses the header (format, elements, properties and
//! their types); `values` reads the stored values (binary and ASCII) and converts them to `f32`
//! and vertex indices; `elements` assembles the `vertex` and `face` elements into the mesh
//! (positions, normals, texture coordinates, triangles and Mitsuba's attribute grouping).

mod elements;
mod header;
mod values;

use super::mesh::MeshData;
use elements::{read_faces, read_vertices};
use header::{lossy, parse_header};
use values::Data;

/// Reads a PLY file held in memory. Errors are one line, without the file name.
pub fn read_ply(bytes: &[u8]) -> Result<MeshData, String> {
    read_ply_with_warnings(bytes, &mut Vec::new())
}

/// [`read_ply`], also collecting the warnings Mitsuba would log (skipped elements, dropped
/// properties, integer colours).
pub fn read_ply_with_warnings(
    bytes: &[u8],
    warnings: &mut Vec<String>,
) -> Result<MeshData, String> {
    let header = parse_header(bytes)?;
    let mut data = Data::new(bytes, header.data_start, header.format);
    let mut mesh = MeshData::default();
    let (mut seen_vertex, mut seen_face) = (false, false);
    for el in header.elements {
        match el.name.as_slice() {
            b"vertex" => {
                if std::mem::replace(&mut seen_vertex, true) {
                    return Err("the file has two \"vertex\" elements".into());
                }
                read_vertices(el, &mut data, &mut mesh, warnings)?;
            }
            b"face" => {
                if std::mem::replace(&mut seen_face, true) {
                    return Err("the file has two \"face\" elements".into());
                }
                read_faces(el, &mut data, &mut mesh, warnings)?;
            }
            _ => {
                warnings.push(format!("skipping unknown element \"{}\"", lossy(&el.name)));
                data.skip_element(&el)?;
            }
        }
    }
    data.finish()?;
    mesh.validate()?;
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    //! Expected values come from Mitsuba 3.9.1 (scalar_rgb): `mi.traverse` of the loaded
    //! `ply` shape gives the positions, texture coordinates, faces and attributes compared
    //! here exactly; vertex normals are compared with the file's raw values (Mitsuba
    //! normalises them). Hand-made files check the behaviours listed in the module doc, each
    //! of which was first observed in Mitsuba on the same input.
    use super::header::{lossy, parse_count, Type};
    use super::values::{ascii_value, to_index, Value};
    use super::*;
    use crate::io::mesh::MeshAttribute;

    fn data(name: &str) -> Vec<u8> {
        let path = format!("{}/tests/data/meshes/{name}", env!("CARGO_MANIFEST_DIR"));
        std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
    }

    fn attr<'a>(attrs: &'a [MeshAttribute], name: &str) -> &'a MeshAttribute {
        attrs
            .iter()
            .find(|a| a.name == name)
            .unwrap_or_else(|| panic!("no attribute {name}"))
    }

    /// A triangle with extra vertex properties `props` (each row of `rows` holds the values
    /// after x y z) and face properties after the index list.
    fn ascii(vprops: &[&str], vrows: &[&str], fprops: &[&str], frows: &[&str]) -> Vec<u8> {
        let mut s = format!("ply\nformat ascii 1.0\nelement vertex {}\n", vrows.len());
        for p in ["float x", "float y", "float z"].iter().chain(vprops) {
            s += &format!("property {p}\n");
        }
        s += &format!("element face {}\n", frows.len());
        for p in fprops {
            s += &format!("property {p}\n");
        }
        s += "end_header\n";
        for r in vrows.iter().chain(frows) {
            s += r;
            s += "\n";
        }
        s.into_bytes()
    }

    fn tri(vprops: &[&str], extra: [&str; 3]) -> Vec<u8> {
        let rows = [
            format!("0 0 0 {}", extra[0]),
            format!("1 0 0 {}", extra[1]),
            format!("0 1 0 {}", extra[2]),
        ];
        let rows: Vec<&str> = rows.iter().map(|s| s.as_str()).collect();
        ascii(
            vprops,
            &rows,
            &["list uchar int vertex_indices"],
            &["3 0 1 2"],
        )
    }

    fn names(attrs: &[MeshAttribute]) -> Vec<(&str, usize)> {
        attrs
            .iter()
            .map(|a| (a.name.as_str(), a.channels))
            .collect()
    }

    #[test]
    #[allow(clippy::approx_constant)] // the file stores 0.707107, not 1/sqrt(2)
    fn sphere_attribute_binary_with_vertex_and_face_attributes() {
        let m = read_ply(&data("sphere_attribute.ply")).unwrap();
        assert_eq!((m.positions.len(), m.triangles.len()), (1192, 528));
        assert_eq!(names(&m.vertex_attributes), [("vertex_color", 3)]);
        assert_eq!(
            names(&m.face_attributes),
            [("face_color", 3), ("face_weight", 1)]
        );
        assert_eq!(m.positions[0], [0.0, 0.707107, 0.707107]);
        assert_eq!(m.positions[1], [0.129409, 0.482963, 0.866025]);
        assert_eq!(m.positions[1191], [0.0, 0.965926, 0.258819]);
        let uvs = m.uvs.as_ref().unwrap();
        assert_eq!(uvs[1], [0.708333, 0.833333]);
        assert_eq!(uvs[1191], [0.75, 0.583333]);
        let normals = m.normals.as_ref().unwrap();
        assert_eq!(normals[0], [0.07988803, 0.60681623, 0.7908173]);
        // As stored: Mitsuba's normalised value is -0.12074197, 0.9171208, 0.3798829.
        assert_eq!(normals[1191], [-0.120741956, 0.91712064, 0.37988284]);
        let vc = attr(&m.vertex_attributes, "vertex_color");
        assert_eq!(vc.row(0).unwrap(), [0.018073346, 0.624337, 0.7462374]);
        assert_eq!(vc.row(1).unwrap(), [0.116306, 0.3923358, 0.17795]);
        assert_eq!(vc.row(1191).unwrap(), [0.8257195, 0.6472402, 0.8643507]);
        assert_eq!(m.triangles[0], [0, 1, 2]);
        assert_eq!(m.triangles[527], [1189, 1190, 1191]);
        let fc = attr(&m.face_attributes, "face_color");
        assert_eq!(fc.row(0).unwrap(), [0.1322356, 0.29995632, 0.7800926]);
        assert_eq!(fc.row(527).unwrap(), [0.37340894, 0.7001264, 0.42939427]);
        let fw = attr(&m.face_attributes, "face_weight");
        assert_eq!(fw.row(0).unwrap(), [0.6110702]);
        assert_eq!(fw.row(527).unwrap(), [0.37478322]);
    }

    #[test]
    fn teapot_ascii_positions_and_faces() {
        let m = read_ply(&data("teapot.ply")).unwrap();
        assert_eq!((m.positions.len(), m.triangles.len()), (1177, 2256));
        assert!(m.normals.is_none() && m.uvs.is_none());
        assert!(m.vertex_attributes.is_empty() && m.face_attributes.is_empty());
        assert_eq!(m.positions[0], [1.38137, 0.0, 2.45469]);
        assert_eq!(m.positions[1176], [0.228728, 0.063803, 2.88333]);
        assert_eq!(m.triangles[0], [0, 1, 2]);
        assert_eq!(m.triangles[2255], [623, 1087, 578]);
    }

    #[test]
    fn rectangle_texture_u_v_are_the_uvs() {
        let m = read_ply(&data("rectangle_normals_uv.ply")).unwrap();
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
        assert_eq!(
            m.uvs,
            Some(vec![
                [0.950589, 0.988416],
                [0.025105, 0.988416],
                [0.025105, 0.689127],
                [0.950589, 0.689127]
            ])
        );
        assert_eq!(m.triangles, [[0, 1, 2], [0, 2, 3]]);
        assert!(m.vertex_attributes.is_empty());
    }

    /// The same mesh in both binary byte orders.
    fn binary(big_endian: bool) -> Vec<u8> {
        let order = if big_endian { "big" } else { "little" };
        let mut b = format!(
            "ply\nformat binary_{order}_endian 1.0\ncomment colours in uchar\n\
             element vertex 4\nproperty float x\nproperty double y\nproperty half z\n\
             property uchar red\nproperty uchar green\nproperty uchar blue\n\
             property long w_0\nproperty short s_0\n\
             element edge 1\nproperty int a\nproperty list uchar int b\n\
             element face 2\nproperty list uchar uint vertex_indices\nproperty float q_x\n\
             end_header\n"
        )
        .into_bytes();
        fn put(b: &mut Vec<u8>, le: &[u8], big: bool) {
            if big {
                b.extend(le.iter().rev());
            } else {
                b.extend(le);
            }
        }
        for (i, p) in [
            [0.0f32, 0.0, 0.0],
            [1.0, 0.0, 0.5],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 2.0],
        ]
        .iter()
        .enumerate()
        {
            put(&mut b, &p[0].to_le_bytes(), big_endian);
            put(&mut b, &(p[1] as f64).to_le_bytes(), big_endian);
            put(&mut b, &half::f16::from_f32(p[2]).to_le_bytes(), big_endian);
            b.extend([10 * i as u8, 128, 255]);
            put(&mut b, &(-5i64 * i as i64).to_le_bytes(), big_endian);
            put(
                &mut b,
                &[-1i16, 16383, 0, 32767][i].to_le_bytes(),
                big_endian,
            );
        }
        put(&mut b, &7i32.to_le_bytes(), big_endian);
        b.push(2); // an unknown element's list: skipped as count + 3 items, as in Mitsuba
        for v in [1i32, 2, 3] {
            put(&mut b, &v.to_le_bytes(), big_endian);
        }
        for (f, q) in [([0u32, 1, 2], 0.5f32), ([2, 1, 3], -1.0)] {
            b.push(3);
            for v in f {
                put(&mut b, &v.to_le_bytes(), big_endian);
            }
            put(&mut b, &q.to_le_bytes(), big_endian);
        }
        b
    }

    #[test]
    fn binary_little_and_big_endian_give_the_same_mesh() {
        let mut warnings = Vec::new();
        let le = read_ply_with_warnings(&binary(false), &mut warnings).unwrap();
        assert!(warnings
            .iter()
            .any(|w| w.contains("unknown element \"edge\"")));
        assert!(warnings.iter().any(|w| w.contains("integer components")));
        assert_eq!(le, read_ply(&binary(true)).unwrap());
        assert_eq!(le.positions[1], [1.0, 0.0, 0.5]);
        assert_eq!(le.positions[3], [1.0, 1.0, 2.0]);
        assert_eq!(le.triangles, [[0, 1, 2], [2, 1, 3]]);
        assert_eq!(
            names(&le.vertex_attributes),
            [("vertex_color", 3), ("vertex_w", 1), ("vertex_s", 1)]
        );
        // uchar colours stay 0..255 and `long` is not rescaled (measured in Mitsuba 3.9.1).
        let c = attr(&le.vertex_attributes, "vertex_color");
        assert_eq!(c.row(2).unwrap(), [20.0, 128.0, 255.0]);
        assert_eq!(
            attr(&le.vertex_attributes, "vertex_w").values,
            [0.0, -5.0, -10.0, -15.0]
        );
        // `short`: divided by 32767 and decoded from sRGB. Mitsuba 3.9.1 gives
        // -2.3621137e-6 for -1 and 0.21402693 for 16383 (checked against the exact formula).
        let s = &attr(&le.vertex_attributes, "vertex_s").values;
        assert!((s[0] - -2.362_113_7e-6).abs() < 1e-11, "{}", s[0]);
        let expect = ((16383.0 / 32767.0 + 0.055f64) / 1.055).powf(2.4) as f32;
        assert_eq!(s[1], expect);
        assert!((s[1] - 0.214_026_93).abs() < 1e-6, "{}", s[1]);
        assert_eq!(&s[2..], [0.0, 1.0]);
        assert_eq!(attr(&le.face_attributes, "face_q").values, [0.5, -1.0]);
    }

    #[test]
    fn integer_properties_convert_as_mitsuba_does() {
        // Values printed by Mitsuba 3.9.1 for `char a_0` / `b_0` = -128, -1, 0, 1, 64, 127
        // (and likewise for the other types); agreement to 1e-5 relative (Mitsuba's JIT
        // approximates the sRGB curve).
        let cases: [(&str, [&str; 6], [f32; 6]); 4] = [
            (
                "char",
                ["-128", "-1", "0", "1", "64", "127"],
                [
                    -0.078_008_82,
                    -0.000_609_443_9,
                    0.0,
                    0.000_609_443_9,
                    0.217_703_16,
                    1.0,
                ],
            ),
            (
                "ushort",
                ["0", "1", "10", "1000", "40000", "65535"],
                [
                    0.0,
                    1.181_038_9e-6,
                    1.181_038_8e-5,
                    0.001_181_038_8,
                    0.330_774_04,
                    1.0,
                ],
            ),
            (
                "uint",
                ["0", "1", "10", "1000000", "3000000000", "4294967295"],
                [
                    0.0,
                    1.802_094_8e-11,
                    1.802_094_7e-10,
                    1.802_094_8e-5,
                    0.445_843_94,
                    1.0,
                ],
            ),
            (
                "uchar",
                ["0", "1", "10", "128", "200", "255"],
                [0.0, 1.0, 10.0, 128.0, 200.0, 255.0],
            ),
        ];
        for (ty, text, expected) in cases {
            let a = format!("{ty} a_0");
            let b = format!("{ty} b_0");
            let rows = [
                format!("{} {}", text[0], text[1]),
                format!("{} {}", text[2], text[3]),
                format!("{} {}", text[4], text[5]),
            ];
            let m = read_ply(&tri(&[&a, &b], [&rows[0], &rows[1], &rows[2]])).unwrap();
            let (va, vb) = (
                &attr(&m.vertex_attributes, "vertex_a").values,
                &attr(&m.vertex_attributes, "vertex_b").values,
            );
            let got = [va[0], vb[0], va[1], vb[1], va[2], vb[2]];
            for (g, e) in got.iter().zip(expected) {
                assert!(
                    (g - e).abs() <= 1e-5 * e.abs(),
                    "{ty}: {got:?} vs {expected:?}"
                );
            }
        }
    }

    #[test]
    fn texture_coordinate_names_and_their_priority() {
        for (props, uv) in [
            (["float u", "float v"], [1.0, 2.0]),
            (["float s", "float t"], [1.0, 2.0]),
            (["float texture_u", "float texture_v"], [1.0, 2.0]),
            (["float texture_v", "float texture_u"], [2.0, 1.0]),
        ] {
            let m = read_ply(&tri(&props, ["1 2", "1 2", "1 2"])).unwrap();
            assert_eq!(m.uvs, Some(vec![uv; 3]), "{props:?}");
            assert!(m.vertex_attributes.is_empty());
        }
        // u, v win over s, t (Mitsuba: s, t, u, v = 1 2 3 4 gives 3, 4).
        let m = read_ply(&tri(
            &["float s", "float t", "float u", "float v"],
            ["1 2 3 4"; 3],
        ))
        .unwrap();
        assert_eq!(m.uvs, Some(vec![[3.0, 4.0]; 3]));
        // u alone is no texture coordinate; nx alone no normal.
        let m = read_ply(&tri(&["float u", "float nx"], ["1 1"; 3])).unwrap();
        assert_eq!((m.uvs, m.normals), (None, None));
        // A rename that leaves two fields called v: Mitsuba's converter refuses the element.
        assert!(read_ply(&tri(&["float s", "float t", "float v"], ["1 2 3"; 3])).is_err());
    }

    #[test]
    fn attribute_grouping_follows_mitsuba() {
        // Each case was loaded in Mitsuba 3.9.1; the expected names are what it created.
        type Case<'a> = (&'a [&'a str], &'a [(&'a str, usize)]);
        let cases: [Case; 10] = [
            (
                &["float r", "float g", "float b", "float a"],
                &[("vertex_color", 4)],
            ),
            (
                &["float red", "float green", "float blue"],
                &[("vertex_color", 3)],
            ),
            (
                &["float color_r", "float color_g", "float color_b"],
                &[("vertex_color_color", 3)],
            ),
            (
                &["float a_b_x", "float a_b_y", "float a_b_z"],
                &[("vertex_a_b", 3)],
            ),
            (
                &["float w_1", "float k_x"],
                &[("vertex_w", 1), ("vertex_k", 1)],
            ),
            // 2 or 4 channels are dropped; so is a property without '_'.
            (&["float f_x", "float f_y", "float f_z", "float f_w"], &[]),
            (&["float f_x", "float f_y", "float weight"], &[]),
            // A repeated prefix is dropped, and Mitsuba's scan skips the property after it.
            (
                &[
                    "float foo_x",
                    "float bar_x",
                    "float foo_y",
                    "float baz_x",
                    "float qux_x",
                ],
                &[("vertex_foo", 1), ("vertex_bar", 1), ("vertex_qux", 1)],
            ),
            // A broken sequence drops the attribute and swallows the next property.
            (
                &[
                    "float foo_x",
                    "float foo_q",
                    "float bar_x",
                    "float bar_y",
                    "float bar_z",
                ],
                &[],
            ),
            (&["float a_y", "float b_1", "float b_2"], &[]),
        ];
        for (props, expected) in cases {
            let values = vec!["1"; props.len()].join(" ");
            let m = read_ply(&tri(props, [&values, &values, &values])).unwrap();
            assert_eq!(names(&m.vertex_attributes), expected, "{props:?}");
        }
        // Face properties group the same way, with the face_ prefix.
        let m = read_ply(&ascii(
            &[],
            &["0 0 0", "1 0 0", "0 1 0"],
            &[
                "list uchar int vertex_indices",
                "uchar red",
                "uchar green",
                "uchar blue",
            ],
            &["3 0 1 2 255 128 0"],
        ))
        .unwrap();
        assert_eq!(m.face_attributes[0].values, [255.0, 128.0, 0.0]);
        assert_eq!(m.face_attributes[0].name, "face_color");
    }

    #[test]
    fn indices_convert_as_mitsuba_does() {
        // Mitsuba 3.9.1: int -1 -> 0, float 1.4/1.6 -> 1/2, half 2.5 -> 2 (ties to even).
        for (ty, row, expected) in [
            ("int", "3 0 1 -1", [0, 1, 0]),
            ("float", "3 0 1.4 1.6", [0, 1, 2]),
            ("half", "3 0 1.5 2.5", [0, 2, 2]),
            ("uchar", "3 2 1 0", [2, 1, 0]),
        ] {
            let list = format!("list uchar {ty} vertex_index");
            let m = read_ply(&ascii(&[], &["0 0 0", "1 0 0", "0 1 0"], &[&list], &[row])).unwrap();
            assert_eq!(m.triangles, [expected], "{ty}");
        }
        // Large values, as Mitsuba converted them (with normals in the file, so that its
        // out-of-range indices were not touched while loading).
        assert_eq!(
            to_index(Value::Int(16_777_219), Type::I32),
            Some(16_777_220)
        );
        assert_eq!(
            to_index(Value::Int(2_147_483_647), Type::I32),
            Some(2_147_483_648)
        );
        assert_eq!(to_index(Value::Int(-2_147_483_648), Type::I32), Some(0));
        assert_eq!(
            to_index(Value::Int(16_777_217), Type::U32),
            Some(16_777_217)
        );
        assert_eq!(
            to_index(Value::Int(4_294_967_295), Type::U32),
            Some(4_294_967_295)
        );
        assert_eq!(
            to_index(Value::Int(16_777_217), Type::I64),
            Some(16_777_216)
        );
        assert_eq!(
            to_index(Value::Float(16_777_217.0), Type::F64),
            Some(16_777_216)
        );
        assert_eq!(
            to_index(Value::Float(4_294_967_296.0), Type::F32),
            Some(4_294_967_040)
        );
        assert_eq!(to_index(Value::Float(-3.5), Type::F32), Some(0));
        assert_eq!(to_index(Value::Float(f64::NAN), Type::F32), None);
    }

    #[test]
    fn ascii_numbers_follow_cpp_streams() {
        assert_eq!(ascii_value(b"-1", Type::U16), Some(Value::Int(65535)));
        assert_eq!(ascii_value(b"-65535", Type::U16), Some(Value::Int(1)));
        assert_eq!(ascii_value(b"65536", Type::U16), None);
        assert_eq!(ascii_value(b"+3", Type::U8), Some(Value::Int(3)));
        assert_eq!(ascii_value(b"-1", Type::U8), None);
        assert_eq!(ascii_value(b"128", Type::I8), None);
        assert_eq!(ascii_value(b"1.0", Type::I32), None);
        assert_eq!(ascii_value(b"1e-50", Type::F32), Some(Value::Float(0.0)));
        assert_eq!(
            ascii_value(b"0.1", Type::F16),
            Some(Value::Float(0.0999755859375))
        );
        for bad in [&b"nan"[..], b"inf", b"1e39", b"0x10", b"1.5e", b"."] {
            assert_eq!(ascii_value(bad, Type::F32), None, "{}", lossy(bad));
        }
        assert_eq!(ascii_value(b"1e300", Type::F64), Some(Value::Float(1e300)));
        assert_eq!(ascii_value(b"99999999999999999999", Type::U64), None);
        assert_eq!(
            ascii_value(b"-1", Type::U64),
            Some(Value::Int(u64::MAX.into()))
        );
        assert_eq!(parse_count(b"12abc"), Some(12));
        assert_eq!(parse_count(b"-1"), Some(u64::MAX));
        assert_eq!(parse_count(b"abc"), None);
    }

    #[test]
    fn header_variants_mitsuba_accepts() {
        let base = String::from_utf8(tri(&[], ["", "", ""])).unwrap();
        for text in [
            base.replace('\n', "\r\n"),
            format!("comment before the magic\n{base}"),
            base.replace("property float z", "  property\tfloat\tz  "),
            base.replace("element face 1", "element face 1 ignored"),
            base.replace("end_header", "\n \nend_header"),
            base.replace(
                "list uchar int vertex_indices",
                "list uint8 int32 vertex_index",
            ),
        ] {
            let m = read_ply(text.as_bytes()).unwrap_or_else(|e| panic!("{e}\n{text}"));
            assert_eq!(m.triangles, [[0, 1, 2]]);
        }
        // No faces, or an empty file body: an empty mesh (Mitsuba then fails to compute
        // normals for it; that is the caller's business).
        let m = read_ply(b"ply\nformat ascii 1.0\nend_header\n").unwrap();
        assert_eq!(m, MeshData::default());
        // Degenerate faces are kept.
        let m = read_ply(&ascii(
            &[],
            &["0 0 0", "1 0 0", "0 1 0"],
            &["list uchar int vertex_indices"],
            &["3 0 0 1", "3 0 1 2"],
        ))
        .unwrap();
        assert_eq!(m.triangles, [[0, 0, 1], [0, 1, 2]]);
    }

    fn err(bytes: &[u8]) -> String {
        match read_ply(bytes) {
            Ok(m) => panic!("accepted: {m:?}"),
            Err(e) => e,
        }
    }

    #[test]
    fn malformed_files_are_errors() {
        let good = tri(&[], ["", "", ""]);
        let text = String::from_utf8(good.clone()).unwrap();
        let body_start = text.find("end_header\n").unwrap() + 11;
        let cases: Vec<(Vec<u8>, &str)> = vec![
            (Vec::new(), "end_header"),
            (
                b"ply\nformat ascii 1.0\nelement vertex 3\n".to_vec(),
                "end_header",
            ),
            (
                text.as_bytes()[..body_start - 5].to_vec(),
                "invalid PLY header",
            ),
            (good[..good.len() - 3].to_vec(), "ends inside \"face\""),
            (text.as_bytes()[..body_start + 10].to_vec(), "too short"),
            (format!("{text}7\n").into_bytes(), "trailing"),
            (text.replacen("ply\n", "", 1).into_bytes(), "before \"ply\""),
            (
                text.replacen("ply\n", "PLY\n", 1).into_bytes(),
                "unknown keyword",
            ),
            (text.replace("1.0", "1.1").into_bytes(), "version"),
            (
                text.replace("ascii", "binary").into_bytes(),
                "unknown format",
            ),
            (
                text.replace("float y", "vec3 y").into_bytes(),
                "unknown type",
            ),
            (text.replace("float y", "float x").into_bytes(), "twice"),
            (text.replace("float y", "float").into_bytes(), "missing"),
            (
                text.replace("vertex 3", "vertex").into_bytes(),
                "missing count",
            ),
            (
                text.replace("vertex 3", "vertex x").into_bytes(),
                "invalid element count",
            ),
            (
                text.replace("end_header", "obj_info x\nend_header")
                    .into_bytes(),
                "obj_info",
            ),
            (text.replace("3 0 1 2", "3 0 1 3").into_bytes(), "vertex 3"),
            (
                text.replace("3 0 1 2", "4 0 1 2 2").into_bytes(),
                "triangles only",
            ),
            (text.replace("0 1 0", "0 1 1e39").into_bytes(), "1e39"),
            (text.replace("0 1 0", "0 1 nan").into_bytes(), "nan"),
            (
                text.replace("property float z\n", "").into_bytes(),
                "no property \"z\"",
            ),
            (
                text.replace("vertex_indices", "corners").into_bytes(),
                "vertex_indices",
            ),
            (
                text.replace(
                    "vertex_indices",
                    "vertex_indices\nproperty list uchar int more",
                )
                .into_bytes(),
                "more than one list",
            ),
            (
                text.replace(
                    "element face",
                    "element vertex 1\nproperty float x\nelement face",
                )
                .replace("3 0 1 2", "5\n3 0 1 2")
                .into_bytes(),
                "two \"vertex\"",
            ),
        ];
        for (bytes, expected) in cases {
            let e = err(&bytes);
            assert!(e.contains(expected), "{e:?} lacks {expected:?}");
            assert!(!e.contains('\n'), "{e:?}");
        }
    }

    #[test]
    fn binary_errors_truncation_counts_and_non_finite_positions() {
        let good = binary(false);
        assert!(read_ply(&good).is_ok());
        assert!(err(&good[..good.len() - 1]).contains("too short"));
        let mut longer = good.clone();
        longer.push(0);
        assert!(err(&longer).contains("trailing"));
        // A count of 2^60 in a small file fails before anything is allocated.
        let text = String::from_utf8_lossy(&good).into_owned();
        for count in ["1152921504606846976", "18446744073709551615", "-1"] {
            let mut huge = text.replacen("element vertex 4", &format!("element vertex {count}"), 1);
            huge.truncate(huge.find("end_header\n").unwrap() + 11);
            assert!(err(&[huge.as_bytes(), &[0; 100]].concat()).contains("too short"));
            let ascii = format!(
                "ply\nformat ascii 1.0\nelement vertex {count}\nproperty float x\n\
                 property float y\nproperty float z\nend_header\n1 2 3\n"
            );
            assert!(err(ascii.as_bytes()).contains("too short"));
        }
        // count x record size overflowing u64
        let over = "ply\nformat binary_little_endian 1.0\nelement v 9223372036854775807\n\
                    property double x\nend_header\n";
        assert!(err(over.as_bytes()).contains("too short"));
        // A NaN position (Mitsuba: "mesh contains invalid vertex position data").
        let mut nan = good.clone();
        let at = nan.len() - (4 + 8 + 2 + 3 + 8 + 2) * 4 - (4 + 1 + 12) - 2 * 17;
        nan[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(err(&nan).contains("non-finite"));
        // A quad in a binary file (Mitsuba: "is this a triangle mesh?").
        let quad = b"ply\nformat binary_little_endian 1.0\nelement face 1\n\
                     property list uchar uchar vertex_indices\nend_header\n\x04\0\x01\x02";
        assert!(err(quad).contains("4 vertices"));
    }

    #[test]
    fn garbage_never_panics() {
        // A cheap stand-in for the fuzz target: every prefix and a few byte flips of valid
        // files must give Ok or Err.
        for file in [
            binary(false),
            binary(true),
            data("rectangle_normals_uv.ply"),
        ] {
            for n in 0..file.len() {
                let _ = read_ply(&file[..n]);
            }
            for i in (0..file.len()).step_by(3) {
                for x in [0u8, 0xff, b'\n', b' ', b'9'] {
                    let mut f = file.clone();
                    f[i] = x;
                    let _ = read_ply(&f);
                }
            }
        }
    }
}
