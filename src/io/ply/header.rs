//! The PLY header: the format line, the elements with their counts, and their properties
//! (scalar types and three-item lists), parsed as Mitsuba 3.9.1 parses them; and the
//! whitespace and token rules the ASCII body shares.

use std::collections::HashSet;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Type {
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

    pub(super) fn size(self) -> usize {
        match self {
            Type::I8 | Type::U8 => 1,
            Type::I16 | Type::U16 | Type::F16 => 2,
            Type::I32 | Type::U32 | Type::F32 => 4,
            Type::I64 | Type::U64 | Type::F64 => 8,
        }
    }

    pub(super) fn is_float(self) -> bool {
        matches!(self, Type::F16 | Type::F32 | Type::F64)
    }
}

#[derive(Clone, Debug)]
pub(super) struct Field {
    pub(super) name: Vec<u8>,
    pub(super) ty: Type,
    /// The count of a list: must be 3 in the `vertex` and `face` elements.
    pub(super) list_count: bool,
}

#[derive(Clone, Debug)]
pub(super) struct Element {
    pub(super) name: Vec<u8>,
    pub(super) count: u64,
    pub(super) fields: Vec<Field>,
}

impl Element {
    pub(super) fn record_bytes(&self) -> usize {
        self.fields.iter().map(|f| f.ty.size()).sum()
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Format {
    Ascii,
    Binary { big_endian: bool },
}

pub(super) struct Header {
    pub(super) format: Format,
    pub(super) elements: Vec<Element>,
    pub(super) data_start: usize,
}

/// Whitespace as C's `isspace` (what `std::istream >>` skips).
pub(super) fn is_space(c: u8) -> bool {
    matches!(c, b' ' | b'\t' | b'\n' | 0x0b | 0x0c | b'\r')
}

fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|&c| is_space(c)).filter(|t| !t.is_empty())
}

pub(super) fn lossy(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// `std::stoull`: optional sign, then the longest run of decimal digits (at least one);
/// anything after it is ignored. A `-` wraps, as in C.
pub(super) fn parse_count(token: &[u8]) -> Option<u64> {
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

pub(super) fn parse_header(bytes: &[u8]) -> Result<Header, String> {
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
