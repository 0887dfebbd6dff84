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

use super::mesh::{MeshAttribute, MeshData};
use std::collections::{HashMap, HashSet};

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

// ---------------------------------------------------------------------------------------------
// Header

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Type {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F16,
    F32,
    F64,
}

impl Type {
    fn from_name(name: &[u8]) -> Option<Type> {
        Some(match name {
            b"char" | b"int8" => Type::I8,
            b"uchar" | b"uint8" => Type::U8,
            b"short" | b"int16" => Type::I16,
            b"ushort" | b"uint16" => Type::U16,
            b"int" | b"int32" => Type::I32,
            b"uint" | b"uint32" => Type::U32,
            b"long" => Type::I64,
            b"ulong" => Type::U64,
            b"half" | b"float16" => Type::F16,
            b"float" | b"float32" => Type::F32,
            b"double" | b"float64" => Type::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Type::I8 | Type::U8 => 1,
            Type::I16 | Type::U16 | Type::F16 => 2,
            Type::I32 | Type::U32 | Type::F32 => 4,
            Type::I64 | Type::U64 | Type::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Type::F16 | Type::F32 | Type::F64)
    }
}

#[derive(Clone, Debug)]
struct Field {
    name: Vec<u8>,
    ty: Type,
    /// The count of a list: must be 3 in the `vertex` and `face` elements.
    list_count: bool,
}

#[derive(Clone, Debug)]
struct Element {
    name: Vec<u8>,
    count: u64,
    fields: Vec<Field>,
}

impl Element {
    fn record_bytes(&self) -> usize {
        self.fields.iter().map(|f| f.ty.size()).sum()
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Ascii,
    Binary { big_endian: bool },
}

struct Header {
    format: Format,
    elements: Vec<Element>,
    data_start: usize,
}

/// Whitespace as C's `isspace` (what `std::istream >>` skips).
fn is_space(c: u8) -> bool {
    matches!(c, b' ' | b'\t' | b'\n' | 0x0b | 0x0c | b'\r')
}

fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|&c| is_space(c)).filter(|t| !t.is_empty())
}

fn lossy(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// `std::stoull`: optional sign, then the longest run of decimal digits (at least one);
/// anything after it is ignored. A `-` wraps, as in C.
fn parse_count(token: &[u8]) -> Option<u64> {
    let (neg, digits) = match token.first() {
        Some(b'-') => (true, &token[1..]),
        Some(b'+') => (false, &token[1..]),
        _ => (false, token),
    };
    let len = digits.iter().take_while(|c| c.is_ascii_digit()).count();
    if len == 0 {
        return None;
    }
    let mut v: u64 = 0;
    for &c in &digits[..len] {
        v = v.checked_mul(10)?.checked_add(u64::from(c - b'0'))?;
    }
    Some(if neg { v.wrapping_neg() } else { v })
}

fn parse_header(bytes: &[u8]) -> Result<Header, String> {
    let err = |m: String| Err(format!("invalid PLY header: {m}"));
    let mut pos = 0usize;
    let mut ply_seen = false;
    let mut format: Option<Format> = None;
    let mut elements: Vec<Element> = Vec::new();
    // Field names of the last element, for the duplicate check (a set: headers can be long).
    let mut declared: HashSet<Vec<u8>> = HashSet::new();
    loop {
        // Mitsuba's Stream::read_line: up to '\n', dropping every '\r'; a last line without
        // '\n' still counts.
        if pos >= bytes.len() {
            return err("the file ends before \"end_header\"".into());
        }
        let rest = &bytes[pos..];
        let (line, next) = match rest.iter().position(|&c| c == b'\n') {
            Some(n) => (&rest[..n], pos + n + 1),
            None => (rest, bytes.len()),
        };
        pos = next;
        let mut toks = tokens(line);
        let Some(keyword) = toks.next() else {
            continue;
        };
        match keyword {
            b"comment" => continue,
            b"ply" => {
                if ply_seen {
                    return err("duplicate \"ply\" tag".into());
                }
                ply_seen = true;
                if toks.next().is_some() {
                    return err("excess tokens after \"ply\"".into());
                }
            }
            b"format" => {
                if !ply_seen {
                    return err("\"format\" before \"ply\" tag".into());
                }
                if format.is_some() {
                    return err("duplicate \"format\" tag".into());
                }
                format = Some(match toks.next() {
                    Some(b"ascii") => Format::Ascii,
                    Some(b"binary_little_endian") => Format::Binary { big_endian: false },
                    Some(b"binary_big_endian") => Format::Binary { big_endian: true },
                    Some(t) => return err(format!("unknown format \"{}\"", lossy(t))),
                    None => return err("missing token after \"format\"".into()),
                });
                match toks.next() {
                    Some(b"1.0") => {}
                    Some(t) => return err(format!("unknown version number \"{}\"", lossy(t))),
                    None => return err("missing version number after \"format\"".into()),
                }
                if toks.next().is_some() {
                    return err("excess tokens after \"format\"".into());
                }
            }
            b"element" => {
                let Some(name) = toks.next() else {
                    return err("missing name after \"element\"".into());
                };
                let Some(count) = toks.next() else {
                    return err("missing count after \"element\"".into());
                };
                // Like Mitsuba (std::stoull), tokens after the count are ignored.
                let Some(count) = parse_count(count) else {
                    return err(format!("invalid element count \"{}\"", lossy(count)));
                };
                elements.push(Element {
                    name: name.to_vec(),
                    count,
                    fields: Vec::new(),
                });
                declared.clear();
            }
            b"property" => {
                if format.is_none() {
                    return err("\"property\" before \"format\"".into());
                }
                let Some(el) = elements.last_mut() else {
                    return err("\"property\" before \"element\"".into());
                };
                let ty_of = |t: Option<&[u8]>| -> Result<Type, String> {
                    let t = t.ok_or("invalid PLY header: missing token after \"property\"")?;
                    Type::from_name(t)
                        .ok_or_else(|| format!("invalid PLY header: unknown type \"{}\"", lossy(t)))
                };
                let Some(first) = toks.next() else {
                    return err("missing token after \"property\"".into());
                };
                let new_fields = if first == b"list" {
                    let count_ty = ty_of(toks.next())?;
                    let item_ty = ty_of(toks.next())?;
                    let Some(name) = toks.next() else {
                        return err("missing name after \"property list\"".into());
                    };
                    if declared.contains(&b"i0"[..]) {
                        return err(format!(
                            "element \"{}\" has more than one list property (Mitsuba reads one)",
                            lossy(&el.name)
                        ));
                    }
                    let mut fields = vec![Field {
                        name: [name, b".count"].concat(),
                        ty: count_ty,
                        list_count: true,
                    }];
                    for i in [b"i0", b"i1", b"i2"] {
                        fields.push(Field {
                            name: i.to_vec(),
                            ty: item_ty,
                            list_count: false,
                        });
                    }
                    fields
                } else {
                    let ty = ty_of(Some(first))?;
                    let Some(name) = toks.next() else {
                        return err("missing name after \"property\"".into());
                    };
                    vec![Field {
                        name: name.to_vec(),
                        ty,
                        list_count: false,
                    }]
                };
                if toks.next().is_some() {
                    return err("excess tokens after \"property\"".into());
                }
                for f in new_fields {
                    if !declared.insert(f.name.clone()) {
                        return err(format!(
                            "element \"{}\" declares \"{}\" twice",
                            lossy(&el.name),
                            lossy(&f.name)
                        ));
                    }
                    el.fields.push(f);
                }
            }
            b"end_header" => {
                if toks.next().is_some() {
                    return err("excess tokens after \"end_header\"".into());
                }
                break;
            }
            other => return err(format!("unknown keyword \"{}\"", lossy(other))),
        }
    }
    let Some(format) = format else {
        return err("no \"format\" line".into());
    };
    Ok(Header {
        format,
        elements,
        data_start: pos,
    })
}

// ---------------------------------------------------------------------------------------------
// Values

/// One stored value, widened without loss.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Value {
    Int(i128),
    Float(f64),
}

struct Data<'a> {
    bytes: &'a [u8],
    pos: usize,
    format: Format,
}

impl<'a> Data<'a> {
    fn new(bytes: &'a [u8], pos: usize, format: Format) -> Self {
        Data { bytes, pos, format }
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos.min(self.bytes.len())
    }

    /// Checks that `el.count` records can possibly be present, so that a huge count from the
    /// header fails here instead of in an allocation. Returns the count as usize.
    fn check_count(&self, el: &Element) -> Result<usize, String> {
        let nfields = el.fields.len() as u64;
        let needed = match self.format {
            Format::Binary { .. } => el.count.checked_mul(el.record_bytes() as u64),
            // n tokens need at least 2n - 1 bytes.
            Format::Ascii => el
                .count
                .checked_mul(nfields)
                .and_then(|t| t.checked_mul(2))
                .map(|b| b.saturating_sub(1)),
        };
        match needed {
            Some(n) if n <= self.remaining() as u64 => usize::try_from(el.count)
                .map_err(|_| format!("element \"{}\" is too large", lossy(&el.name))),
            _ => Err(format!(
                "the file is too short for {} \"{}\" records of {} properties",
                el.count,
                lossy(&el.name),
                nfields
            )),
        }
    }

    fn skip_element(&mut self, el: &Element) -> Result<(), String> {
        let count = self.check_count(el)?;
        match self.format {
            Format::Binary { .. } => {
                self.pos += count * el.record_bytes();
            }
            Format::Ascii => {
                if el.fields.is_empty() {
                    return Ok(());
                }
                for r in 0..count {
                    for f in &el.fields {
                        self.next_ascii(f, &el.name, r)?;
                    }
                }
            }
        }
        Ok(())
    }

    /// Reads one record of `el` into `out`.
    fn record(&mut self, el: &Element, r: usize, out: &mut Vec<Value>) -> Result<(), String> {
        out.clear();
        match self.format {
            Format::Binary { big_endian } => {
                for f in &el.fields {
                    let n = f.ty.size();
                    let Some(b) = self.bytes.get(self.pos..self.pos + n) else {
                        return Err(format!(
                            "the file ends inside \"{}\" record {r}",
                            lossy(&el.name)
                        ));
                    };
                    self.pos += n;
                    out.push(binary_value(b, f.ty, big_endian));
                }
            }
            Format::Ascii => {
                for f in &el.fields {
                    out.push(self.next_ascii(f, &el.name, r)?);
                }
            }
        }
        Ok(())
    }

    fn next_ascii(&mut self, f: &Field, el: &[u8], r: usize) -> Result<Value, String> {
        let b = self.bytes;
        let mut p = self.pos;
        while p < b.len() && is_space(b[p]) {
            p += 1;
        }
        let start = p;
        while p < b.len() && !is_space(b[p]) {
            p += 1;
        }
        self.pos = p;
        let token = &b[start..p];
        if token.is_empty() {
            return Err(format!("the file ends inside \"{}\" record {r}", lossy(el)));
        }
        ascii_value(token, f.ty).ok_or_else(|| {
            format!(
                "cannot parse \"{}\" as {:?} for property \"{}\" of \"{}\" record {r}",
                lossy(token),
                f.ty,
                lossy(&f.name),
                lossy(el)
            )
        })
    }

    fn finish(&mut self) -> Result<(), String> {
        let trailing = match self.format {
            Format::Binary { .. } => self.remaining() > 0,
            Format::Ascii => self.bytes[self.pos.min(self.bytes.len())..]
                .iter()
                .any(|&c| !is_space(c)),
        };
        if trailing {
            Err("trailing content after the last element".into())
        } else {
            Ok(())
        }
    }
}

fn binary_value(b: &[u8], ty: Type, big_endian: bool) -> Value {
    let mut raw = [0u8; 8];
    let n = ty.size();
    raw[..n].copy_from_slice(&b[..n]);
    if big_endian {
        raw[..n].reverse();
    }
    let u = u64::from_le_bytes(raw);
    match ty {
        Type::I8 => Value::Int(i128::from(u as u8 as i8)),
        Type::U8 => Value::Int(i128::from(u as u8)),
        Type::I16 => Value::Int(i128::from(u as u16 as i16)),
        Type::U16 => Value::Int(i128::from(u as u16)),
        Type::I32 => Value::Int(i128::from(u as u32 as i32)),
        Type::U32 => Value::Int(i128::from(u as u32)),
        Type::I64 => Value::Int(i128::from(u as i64)),
        Type::U64 => Value::Int(i128::from(u)),
        Type::F16 => Value::Float(f64::from(half::f16::from_bits(u as u16).to_f32())),
        Type::F32 => Value::Float(f64::from(f32::from_bits(u as u32))),
        Type::F64 => Value::Float(f64::from_bits(u)),
    }
}

/// Parses one ASCII token as `std::istream >> T` would accept it as a whole.
fn ascii_value(token: &[u8], ty: Type) -> Option<Value> {
    let text = std::str::from_utf8(token).ok()?;
    if ty.is_float() {
        // Digits, sign, point and exponent only: Rust would accept "inf" and "nan", C++ not.
        if !token
            .iter()
            .all(|c| c.is_ascii_digit() || matches!(c, b'+' | b'-' | b'.' | b'e' | b'E'))
        {
            return None;
        }
        return match ty {
            Type::F64 => text
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .map(Value::Float),
            // `half` is read as a float and then rounded to half precision.
            _ => {
                let v = text.parse::<f32>().ok().filter(|v| v.is_finite())?;
                let v = if ty == Type::F16 {
                    half::f16::from_f32(v).to_f32()
                } else {
                    v
                };
                Some(Value::Float(f64::from(v)))
            }
        };
    }
    let (neg, digits) = match token.first()? {
        b'-' => (true, &token[1..]),
        b'+' => (false, &token[1..]),
        _ => (false, token),
    };
    if digits.is_empty() || !digits.iter().all(|c| c.is_ascii_digit()) {
        return None;
    }
    let mut mag: u128 = 0;
    for &c in digits {
        mag = mag.checked_mul(10)?.checked_add(u128::from(c - b'0'))?;
        if mag > u128::from(u64::MAX) + 1 {
            return None;
        }
    }
    let signed = |min: i128, max: i128| {
        let v = if neg { -(mag as i128) } else { mag as i128 };
        (min..=max).contains(&v).then_some(Value::Int(v))
    };
    // Unsigned extraction in C++ accepts a '-' and negates modulo 2^bits.
    let unsigned = |bits: u32| {
        let max = (1u128 << bits) - 1;
        if mag > max {
            return None;
        }
        let v = if neg { (max + 1 - mag) & max } else { mag };
        Some(Value::Int(v as i128))
    };
    match ty {
        // Mitsuba reads char and uchar through an int and range-checks it.
        Type::I8 => signed(-128, 127),
        Type::U8 => signed(0, 255),
        Type::I16 => signed(i16::MIN.into(), i16::MAX.into()),
        Type::I32 => signed(i32::MIN.into(), i32::MAX.into()),
        Type::I64 => signed(i64::MIN.into(), i64::MAX.into()),
        Type::U16 => unsigned(16),
        Type::U32 => unsigned(32),
        Type::U64 => unsigned(64),
        Type::F16 | Type::F32 | Type::F64 => None,
    }
}

fn srgb_to_linear(s: f64) -> f64 {
    if s <= 0.04045 {
        s / 12.92
    } else {
        ((s + 0.055) / 1.055).powf(2.4)
    }
}

/// A scalar property as Mitsuba 3.9.1's converter turns it into an `f32` (module doc).
fn to_f32(v: Value, ty: Type) -> f32 {
    match v {
        Value::Float(x) => x as f32,
        Value::Int(i) => {
            let max = match ty {
                Type::I8 => i8::MAX as f64,
                Type::I16 => i16::MAX as f64,
                Type::U16 => u16::MAX as f64,
                Type::I32 => i32::MAX as f64,
                Type::U32 => u32::MAX as f64,
                Type::U64 => u64::MAX as f64,
                // uchar and long: not normalised by the installed Mitsuba.
                _ => return i as f32,
            };
            srgb_to_linear(i as f64 / max) as f32
        }
    }
}

/// The largest `f32` below 2^32: Mitsuba's clamp when converting a float to `u32`.
const MAX_INDEX_F32: f32 = 4_294_967_040.0;

/// A list item as Mitsuba 3.9.1 turns it into a `u32` vertex index (module doc).
fn to_index(v: Value, ty: Type) -> Option<u32> {
    if ty == Type::U32 {
        if let Value::Int(i) = v {
            return u32::try_from(i).ok();
        }
    }
    let f = match v {
        Value::Int(i) => i as f32,
        Value::Float(x) => x as f32,
    };
    if f.is_nan() {
        return None;
    }
    Some(f.round_ties_even().clamp(0.0, MAX_INDEX_F32) as u32)
}

/// Whether a list count equals 3 in its own type (Mitsuba's `Check` flag).
fn is_three(v: Value) -> bool {
    match v {
        Value::Int(i) => i == 3,
        Value::Float(x) => x == 3.0,
    }
}

// ---------------------------------------------------------------------------------------------
// Elements

fn find(names: &[Vec<u8>], name: &[u8]) -> Option<usize> {
    names.iter().position(|n| n == name)
}

fn has(names: &[Vec<u8>], name: &[u8]) -> bool {
    find(names, name).is_some()
}

/// Renames the first field called `from` to `to` (Mitsuba renames in place, by name).
fn rename(names: &mut [Vec<u8>], from: &[u8], to: &[u8]) {
    if let Some(i) = find(names, from) {
        names[i] = to.to_vec();
    }
}

/// An attribute to fill: its name and the source field of each channel.
struct AttributePlan {
    name: String,
    fields: Vec<usize>,
}

const POSTFIXES: [&[u8; 4]; 4] = [b"xr01", b"yg12", b"zb23", b"wa34"];

/// Mitsuba's `find_other_fields`: colours first, then the `PREFIX_C` groups, in field order.
/// `names` are the element's field names (after the texture-coordinate renames); colour
/// renames are applied to it too.
fn find_attributes(
    kind: &str,
    names: &mut [Vec<u8>],
    types: &[Type],
    reserved: &[&[u8]],
    warnings: &mut Vec<String>,
) -> Result<Vec<AttributePlan>, String> {
    let mut plans: Vec<(String, Vec<Vec<u8>>)> = Vec::new();
    if !(has(names, b"r") && has(names, b"g") && has(names, b"b"))
        && has(names, b"red")
        && has(names, b"green")
        && has(names, b"blue")
    {
        rename(names, b"red", b"r");
        rename(names, b"green", b"g");
        rename(names, b"blue", b"b");
        if has(names, b"alpha") {
            rename(names, b"alpha", b"a");
        }
    }
    if let (Some(r), true, true) = (find(names, b"r"), has(names, b"g"), has(names, b"b")) {
        let mut channels: Vec<Vec<u8>> = vec![b"r".to_vec(), b"g".to_vec(), b"b".to_vec()];
        if has(names, b"a") {
            channels.push(b"a".to_vec());
        }
        if !types[r].is_float() {
            warnings.push(format!(
                "attribute \"{kind}color\" has integer components: Mitsuba expects colours \
                 in [0, 1] and does not rescale them"
            ));
        }
        plans.push((format!("{kind}color"), channels));
    }
    let is_reserved = |n: &[u8]| reserved.contains(&n) || matches!(n, b"r" | b"g" | b"b" | b"a");

    struct Scan {
        prefix: Vec<u8>,
        category: usize,
        level: usize,
        reading: bool,
        encountered: HashSet<Vec<u8>>,
    }
    impl Scan {
        fn reset(&mut self) {
            self.prefix.clear();
            self.category = 0;
            self.level = 0;
            self.reading = false;
        }
        fn flush(
            &mut self,
            kind: &str,
            out: &mut Vec<(String, Vec<Vec<u8>>)>,
            w: &mut Vec<String>,
        ) {
            let full = format!("{kind}{}", lossy(&self.prefix));
            if self.level != 1 && self.level != 3 {
                w.push(format!(
                    "attribute \"{full}\" ignored: it must have 1 or 3 fields (had {})",
                    self.level
                ));
                self.reset();
                return;
            }
            let channels = (0..self.level)
                .map(|k| {
                    let mut n = self.prefix.clone();
                    n.push(b'_');
                    n.push(POSTFIXES[k][self.category]);
                    n
                })
                .collect();
            let suffix = if self.category == 1 { "_color" } else { "" };
            out.push((format!("{full}{suffix}"), channels));
            self.encountered.insert(std::mem::take(&mut self.prefix));
            self.reset();
        }
    }
    let mut s = Scan {
        prefix: Vec::new(),
        category: 0,
        level: 0,
        reading: false,
        encountered: HashSet::new(),
    };
    let n = names.len();
    let mut i = 0;
    'scan: while i < n {
        'field: {
            let name = &names[i];
            if is_reserved(name) {
                break 'field;
            }
            let Some(us) = name.iter().rposition(|&c| c == b'_') else {
                warnings.push(format!(
                    "property \"{}\" ignored: attributes need a \"_\" suffix",
                    lossy(name)
                ));
                if s.reading {
                    s.flush(kind, &mut plans, warnings);
                }
                break 'field;
            };
            if name.len() - us - 1 != 1 {
                warnings.push(format!(
                    "property \"{}\" ignored: the suffix must be one character",
                    lossy(name)
                ));
                if s.reading {
                    s.flush(kind, &mut plans, warnings);
                }
                break 'field;
            }
            let prefix = name[..us].to_vec();
            let ch = name[us + 1];
            if s.reading && prefix != s.prefix {
                s.flush(kind, &mut plans, warnings);
            }
            if !s.reading && s.encountered.contains(&prefix) {
                warnings.push(format!(
                    "property \"{}\" ignored: prefix already used",
                    lossy(name)
                ));
                while i < n && names[i].starts_with(&prefix) {
                    i += 1;
                }
                if i == n {
                    break 'scan;
                }
                break 'field; // Mitsuba's loop increment then skips one more field.
            }
            if !s.reading {
                let Some(category) = POSTFIXES[0].iter().position(|&c| c == ch) else {
                    warnings.push(format!(
                        "property \"{}\" ignored: an attribute cannot start with suffix '{}'",
                        lossy(name),
                        ch as char
                    ));
                    break 'field;
                };
                s.reading = true;
                s.category = category;
                s.prefix = prefix;
            } else if POSTFIXES.get(s.level).map(|p| p[s.category]) != Some(ch) {
                warnings.push(format!(
                    "attribute \"{kind}{}\" ignored: invalid suffix sequence",
                    lossy(&prefix)
                ));
                s.reset();
                while i < n && names[i].starts_with(&prefix) {
                    i += 1;
                }
                if i == n {
                    break 'scan;
                }
                // No `continue` in Mitsuba here: the level is counted up for the next
                // attribute and the field at `i` is skipped by the loop increment.
            }
            s.level += 1;
        }
        i += 1;
    }
    if s.reading {
        s.flush(kind, &mut plans, warnings);
    }

    let mut first: HashMap<&[u8], usize> = HashMap::new();
    for (i, n) in names.iter().enumerate().rev() {
        first.insert(n, i);
    }
    let mut out: Vec<AttributePlan> = Vec::new();
    let mut used = HashSet::new();
    for (name, channels) in plans {
        if !used.insert(name.clone()) {
            return Err(format!("attribute \"{name}\" defined twice"));
        }
        let fields = channels
            .iter()
            .map(|c| {
                first
                    .get(c.as_slice())
                    .copied()
                    .ok_or_else(|| format!("missing property \"{}\"", lossy(c)))
            })
            .collect::<Result<Vec<_>, _>>()?;
        out.push(AttributePlan { name, fields });
    }
    Ok(out)
}

/// Mitsuba's converter rejects an element whose renames (`s`/`t`/`texture_u`/`texture_v` to
/// `u`/`v`, `red`... to `r`...) left two fields with one name.
fn check_unique(names: &[Vec<u8>], el: &str) -> Result<(), String> {
    let mut seen = HashSet::new();
    for n in names {
        if !seen.insert(n) {
            return Err(format!(
                "the \"{el}\" element has two properties that Mitsuba both calls \"{}\"",
                lossy(n)
            ));
        }
    }
    Ok(())
}

fn require(names: &[Vec<u8>], name: &[u8], el: &str) -> Result<usize, String> {
    find(names, name)
        .ok_or_else(|| format!("the \"{el}\" element has no property \"{}\"", lossy(name)))
}

/// Checks the list counts of one record of a converted element.
fn check_lists(el: &Element, values: &[Value], r: usize) -> Result<(), String> {
    for (f, v) in el.fields.iter().zip(values) {
        if f.list_count && !is_three(*v) {
            let n = match v {
                Value::Int(i) => i.to_string(),
                Value::Float(x) => x.to_string(),
            };
            return Err(if el.name == b"face" {
                format!(
                    "face {r} has {n} vertices: Mitsuba reads triangles only (no quads or \
                     polygons)"
                )
            } else {
                format!(
                    "list \"{}\" of \"{}\" record {r} has {n} items; Mitsuba reads exactly 3",
                    lossy(&f.name[..f.name.len() - ".count".len()]),
                    lossy(&el.name)
                )
            });
        }
    }
    Ok(())
}

fn new_attributes(plans: &[AttributePlan], rows: usize) -> Vec<MeshAttribute> {
    plans
        .iter()
        .map(|p| MeshAttribute {
            name: p.name.clone(),
            channels: p.fields.len(),
            values: Vec::with_capacity(rows * p.fields.len()),
        })
        .collect()
}

fn push_attributes(
    attrs: &mut [MeshAttribute],
    plans: &[AttributePlan],
    el: &Element,
    values: &[Value],
) {
    for (a, p) in attrs.iter_mut().zip(plans) {
        a.values
            .extend(p.fields.iter().map(|&f| to_f32(values[f], el.fields[f].ty)));
    }
}

fn read_vertices(
    el: Element,
    data: &mut Data,
    mesh: &mut MeshData,
    warnings: &mut Vec<String>,
) -> Result<(), String> {
    let count = data.check_count(&el)?;
    let mut names: Vec<Vec<u8>> = el.fields.iter().map(|f| f.name.clone()).collect();
    let types: Vec<Type> = el.fields.iter().map(|f| f.ty).collect();
    let pos = [
        require(&names, b"x", "vertex")?,
        require(&names, b"y", "vertex")?,
        require(&names, b"z", "vertex")?,
    ];
    let normal = match (
        find(&names, b"nx"),
        find(&names, b"ny"),
        find(&names, b"nz"),
    ) {
        (Some(a), Some(b), Some(c)) => Some([a, b, c]),
        _ => None,
    };
    if !(has(&names, b"u") && has(&names, b"v")) {
        if has(&names, b"texture_u") && has(&names, b"texture_v") {
            rename(&mut names, b"texture_u", b"u");
            rename(&mut names, b"texture_v", b"v");
        } else if has(&names, b"s") && has(&names, b"t") {
            rename(&mut names, b"s", b"u");
            rename(&mut names, b"t", b"v");
        }
    }
    let uv = match (find(&names, b"u"), find(&names, b"v")) {
        (Some(a), Some(b)) => Some([a, b]),
        _ => None,
    };
    let reserved: [&[u8]; 8] = [b"x", b"y", b"z", b"nx", b"ny", b"nz", b"u", b"v"];
    let plans = find_attributes("vertex_", &mut names, &types, &reserved, warnings)?;
    check_unique(&names, "vertex")?;

    let f = |values: &[Value], i: usize| to_f32(values[i], el.fields[i].ty);
    mesh.positions = Vec::with_capacity(count);
    let mut normals = normal.map(|_| Vec::with_capacity(count));
    let mut uvs = uv.map(|_| Vec::with_capacity(count));
    let mut attrs = new_attributes(&plans, count);
    let mut values = Vec::with_capacity(el.fields.len());
    for r in 0..count {
        data.record(&el, r, &mut values)?;
        check_lists(&el, &values, r)?;
        let p = pos.map(|i| f(&values, i));
        if !p.iter().all(|c| c.is_finite()) {
            return Err(format!("vertex {r} has a non-finite position {p:?}"));
        }
        mesh.positions.push(p);
        if let (Some(out), Some(idx)) = (normals.as_mut(), normal) {
            out.push(idx.map(|i| f(&values, i)));
        }
        if let (Some(out), Some(idx)) = (uvs.as_mut(), uv) {
            out.push(idx.map(|i| f(&values, i)));
        }
        push_attributes(&mut attrs, &plans, &el, &values);
    }
    mesh.normals = normals;
    mesh.uvs = uvs;
    mesh.vertex_attributes = attrs;
    Ok(())
}

fn read_faces(
    el: Element,
    data: &mut Data,
    mesh: &mut MeshData,
    warnings: &mut Vec<String>,
) -> Result<(), String> {
    let count = data.check_count(&el)?;
    let mut names: Vec<Vec<u8>> = el.fields.iter().map(|f| f.name.clone()).collect();
    let types: Vec<Type> = el.fields.iter().map(|f| f.ty).collect();
    if !has(&names, b"vertex_index.count") && !has(&names, b"vertex_indices.count") {
        return Err("the \"face\" element has no vertex_index/vertex_indices list".into());
    }
    let idx = [
        require(&names, b"i0", "face")?,
        require(&names, b"i1", "face")?,
        require(&names, b"i2", "face")?,
    ];
    let reserved: [&[u8]; 5] = [
        b"vertex_index.count",
        b"vertex_indices.count",
        b"i0",
        b"i1",
        b"i2",
    ];
    let plans = find_attributes("face_", &mut names, &types, &reserved, warnings)?;
    check_unique(&names, "face")?;
    mesh.triangles = Vec::with_capacity(count);
    let mut attrs = new_attributes(&plans, count);
    let mut values = Vec::with_capacity(el.fields.len());
    for r in 0..count {
        data.record(&el, r, &mut values)?;
        check_lists(&el, &values, r)?;
        let mut tri = [0u32; 3];
        for (t, &i) in tri.iter_mut().zip(&idx) {
            *t = to_index(values[i], el.fields[i].ty)
                .ok_or_else(|| format!("face {r} has a vertex index that is not a number"))?;
        }
        mesh.triangles.push(tri);
        push_attributes(&mut attrs, &plans, &el, &values);
    }
    mesh.face_attributes = attrs;
    Ok(())
}

#[cfg(test)]
mod tests {
    //! Expected values come from Mitsuba 3.9.1 (scalar_rgb): `mi.traverse` of the loaded
    //! `ply` shape gives the positions, texture coordinates, faces and attributes compared
    //! here exactly; vertex normals are compared with the file's raw values (Mitsuba
    //! normalises them). Hand-made files check the behaviours listed in the module doc, each
    //! of which was first observed in Mitsuba on the same input.
    use super::*;

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
