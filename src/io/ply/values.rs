//! The stored values: reading records (binary little/big endian and ASCII tokens, bounded by
//! the bytes present), and converting values to `f32` and vertex indices as Mitsuba 3.9.1's
//! struct converter does.

use super::header::{is_space, lossy, Element, Field, Format, Type};

/// One stored value, widened without loss.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Value {
    Int(i128),
    Float(f64),
}

pub(super) struct Data<'a> {
    bytes: &'a [u8],
    pos: usize,
    format: Format,
}

impl<'a> Data<'a> {
    pub(super) fn new(bytes: &'a [u8], pos: usize, format: Format) -> Self {
        Data { bytes, pos, format }
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos.min(self.bytes.len())
    }

    /// Checks that `el.count` records can possibly be present, so that a huge count from the
    /// header fails here instead of in an allocation. Returns the count as usize.
    pub(super) fn check_count(&self, el: &Element) -> Result<usize, String> {
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

    pub(super) fn skip_element(&mut self, el: &Element) -> Result<(), String> {
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
    pub(super) fn record(
        &mut self,
        el: &Element,
        r: usize,
        out: &mut Vec<Value>,
    ) -> Result<(), String> {
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

    pub(super) fn finish(&mut self) -> Result<(), String> {
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
pub(super) fn ascii_value(token: &[u8], ty: Type) -> Option<Value> {
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

/// A scalar property as Mitsuba 3.9.1's converter turns it into an `f32` (module doc).
pub(super) fn to_f32(v: Value, ty: Type) -> f32 {
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
            crate::spectrum::srgb_to_linear(i as f64 / max) as f32
        }
    }
}

/// The largest `f32` below 2^32: Mitsuba's clamp when converting a float to `u32`.
const MAX_INDEX_F32: f32 = 4_294_967_040.0;

/// A list item as Mitsuba 3.9.1 turns it into a `u32` vertex index (module doc).
pub(super) fn to_index(v: Value, ty: Type) -> Option<u32> {
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
pub(super) fn is_three(v: Value) -> bool {
    match v {
        Value::Int(i) => i == 3,
        Value::Float(x) => x == 3.0,
    }
}
