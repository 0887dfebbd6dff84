//! The XML syntax of scene files, read the way Mitsuba 3.9.1 reads it.
//!
//! Mitsuba parses scene files with pugixml and its default options, which accept a good deal
//! that strict XML (and so roxmltree, which penumbra used before) refuses, and published
//! scenes rely on some of it: the mitsuba-blender exporter's files (NVIDIA sionna's scenes)
//! open with a comment whose lines start with `--`. This module is a small reader with
//! pugixml's acceptance, written from pugixml's documented and observed behaviour (checked
//! against Mitsuba 3.9.1 itself):
//!
//! - A comment ends at the first `-->`; `--` inside it is fine. Comments, processing
//!   instructions (`<?xml ...?>` included, anywhere), CDATA sections, text and a DOCTYPE
//!   (before the document element) are skipped: Mitsuba ignores every node but elements, and
//!   entities a DOCTYPE declares are not expanded.
//! - Text is never checked: `&`, `>` and unknown entities in it are fine. Text outside the
//!   document element is skipped without looking at it, up to the next `<`.
//! - In attribute values, `&lt;`, `&gt;`, `&amp;`, `&apos;`, `&quot;`, `&#N;` and `&#xN;` are
//!   decoded and any other `&` is kept as it is; `<` is allowed; tabs, line feeds and carriage
//!   returns become spaces (a CR LF pair one space).
//! - An element may repeat an attribute (the first one counts as its value; all of them are
//!   seen by the scene parser's checks) and there are no namespaces: `a:b` is just a name.
//! - Only the first top-level element is the document; later ones are checked for syntax and
//!   dropped.
//! - The file may be UTF-8 (with or without a byte order mark), UTF-16 or UTF-32 (with a byte
//!   order mark, or starting with `<`), or Latin-1 when its XML declaration says
//!   `encoding="ISO-8859-1"` or `"latin1"`. Bytes that are not UTF-8 are fine where they are
//!   skipped (comments, text); in a name or an attribute value, where penumbra needs text,
//!   they are an error (pugixml would pass the bytes on).
//! - A NUL byte ends the document, as it ends pugixml's buffer.
//!
//! What it refuses is what pugixml refuses, with pugixml's description of the problem: an
//! unterminated comment, CDATA section, processing instruction or attribute value, a malformed
//! tag, a closing tag that does not match, an element left open, a DOCTYPE inside an element,
//! no element at all.
//!
//! The reader is iterative (no recursion), linear in the input, and bounded: at most
//! [`MAX_DEPTH`] open elements and [`MAX_ELEMENTS`] elements.

use std::borrow::Cow;
use std::ops::Range;

/// Maximum depth of open elements (the scene parser allows less; this bounds the reader).
pub(super) const MAX_DEPTH: usize = 128;

/// Maximum number of elements kept for the document (about 40 bytes each).
pub(super) const MAX_ELEMENTS: usize = 1 << 22;

/// No element (for the links between elements).
const NONE: u32 = u32::MAX;

/// A syntax error: what is wrong and the byte offset where it was found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct SyntaxError {
    pub message: Cow<'static, str>,
    pub offset: usize,
}

/// One element of the document: its name, attributes and place in the tree.
#[derive(Debug, Clone)]
struct ElementData {
    /// Offset of the `<` that opens it.
    start: usize,
    name: Range<usize>,
    /// Range of its attributes in [`Markup::attributes`].
    attributes: Range<u32>,
    first_child: u32,
    last_child: u32,
    next_sibling: u32,
}

/// An attribute as written: the byte ranges of its name and of its raw value (between the
/// quotes, not yet decoded).
#[derive(Debug, Clone)]
struct AttributeData {
    name: Range<usize>,
    value: Range<usize>,
}

/// A parsed document: the elements of its document element's tree.
#[derive(Debug)]
pub(super) struct Markup<'t> {
    text: &'t [u8],
    elements: Vec<ElementData>,
    attributes: Vec<AttributeData>,
}

/// An element of a [`Markup`].
#[derive(Clone, Copy)]
pub(super) struct Element<'m, 't> {
    markup: &'m Markup<'t>,
    index: u32,
}

/// An attribute of an [`Element`].
#[derive(Clone, Copy)]
pub(super) struct Attribute<'m, 't> {
    markup: &'m Markup<'t>,
    index: u32,
}

impl<'t> Markup<'t> {
    /// The document element (the first top-level element).
    pub fn root<'m>(&'m self) -> Element<'m, 't> {
        Element {
            markup: self,
            index: 0,
        }
    }

    fn str(&self, range: &Range<usize>) -> &'t str {
        // Names are checked to be UTF-8 when parsed.
        self.text
            .get(range.clone())
            .and_then(|b| std::str::from_utf8(b).ok())
            .unwrap_or_default()
    }
}

impl<'m, 't> Element<'m, 't> {
    fn data(&self) -> Option<&'m ElementData> {
        self.markup.elements.get(self.index as usize)
    }

    /// The tag, as written (`a:b` included).
    pub fn name(&self) -> &'t str {
        self.data().map_or("", |d| self.markup.str(&d.name))
    }

    /// The byte offset of the `<` that opens the element.
    pub fn start(&self) -> usize {
        self.data().map_or(0, |d| d.start)
    }

    /// The child elements, in document order.
    pub fn children(&self) -> impl Iterator<Item = Element<'m, 't>> + 'm {
        let markup = self.markup;
        let mut next = self.data().map_or(NONE, |d| d.first_child);
        std::iter::from_fn(move || {
            let index = next;
            let data = markup.elements.get(index as usize)?;
            next = data.next_sibling;
            Some(Element { markup, index })
        })
    }

    /// The attributes, in document order (repeated names included).
    pub fn attributes(&self) -> impl Iterator<Item = Attribute<'m, 't>> + 'm {
        let markup = self.markup;
        let range = self.data().map_or(0..0, |d| d.attributes.clone());
        range.map(move |index| Attribute { markup, index })
    }
}

impl<'m, 't> Attribute<'m, 't> {
    fn data(&self) -> Option<&'m AttributeData> {
        self.markup.attributes.get(self.index as usize)
    }

    pub fn name(&self) -> &'t str {
        self.data().map_or("", |d| self.markup.str(&d.name))
    }

    /// The value, decoded as pugixml decodes it (see the module documentation); an error
    /// (with the offset of the value) if it is not UTF-8.
    pub fn value(&self) -> Result<Cow<'t, str>, SyntaxError> {
        let Some(data) = self.data() else {
            return Ok(Cow::Borrowed(""));
        };
        let raw = self.markup.text.get(data.value.clone()).unwrap_or_default();
        let decoded = decode_attribute(raw);
        let not_utf8 = SyntaxError {
            message: Cow::Borrowed("attribute value is not valid UTF-8"),
            offset: data.value.start,
        };
        match decoded {
            Cow::Borrowed(bytes) => std::str::from_utf8(bytes)
                .map(Cow::Borrowed)
                .map_err(|_| not_utf8),
            Cow::Owned(bytes) => String::from_utf8(bytes)
                .map(Cow::Owned)
                .map_err(|_| not_utf8),
        }
    }
}

/// pugixml's whitespace: space, tab, line feed, carriage return.
fn is_space(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\n' | b'\r')
}

/// A byte that may start a name: a letter, `_`, `:` or any byte of a non-ASCII character.
fn is_start_symbol(b: u8) -> bool {
    b.is_ascii_alphabetic() || b == b'_' || b == b':' || b >= 0x80
}

/// A byte that may continue a name: a start symbol, a digit, `-` or `.`.
fn is_symbol(b: u8) -> bool {
    is_start_symbol(b) || b.is_ascii_digit() || b == b'-' || b == b'.'
}

/// Decodes a raw attribute value: entity and character references, whitespace to spaces. A
/// decoded NUL ends the value (pugixml's values are C strings).
fn decode_attribute(raw: &[u8]) -> Cow<'_, [u8]> {
    if !raw
        .iter()
        .any(|&b| matches!(b, b'&' | b'\t' | b'\n' | b'\r'))
    {
        return Cow::Borrowed(raw);
    }
    let mut out = Vec::with_capacity(raw.len());
    let mut i = 0;
    while let Some(&b) = raw.get(i) {
        match b {
            b'\r' => {
                out.push(b' ');
                i += if raw.get(i + 1) == Some(&b'\n') { 2 } else { 1 };
            }
            b'\t' | b'\n' => {
                out.push(b' ');
                i += 1;
            }
            b'&' => match decode_reference(raw.get(i..).unwrap_or_default()) {
                Some((bytes, len)) => {
                    out.extend_from_slice(&bytes);
                    i += len;
                }
                None => {
                    out.push(b'&');
                    i += 1;
                }
            },
            _ => {
                out.push(b);
                i += 1;
            }
        }
    }
    if let Some(nul) = out.iter().position(|&b| b == 0) {
        out.truncate(nul);
    }
    Cow::Owned(out)
}

/// The bytes a reference at the start of `s` (which starts with `&`) stands for and its
/// length, or `None` if it is not one (then the `&` stands for itself).
fn decode_reference(s: &[u8]) -> Option<(Vec<u8>, usize)> {
    for (name, c) in [
        (&b"&lt;"[..], b'<'),
        (b"&gt;", b'>'),
        (b"&amp;", b'&'),
        (b"&apos;", b'\''),
        (b"&quot;", b'"'),
    ] {
        if s.starts_with(name) {
            return Some((vec![c], name.len()));
        }
    }
    let (digits_start, radix) = if s.starts_with(b"&#x") {
        (3, 16)
    } else if s.starts_with(b"&#") {
        (2, 10)
    } else {
        return None;
    };
    let digits = s.get(digits_start..)?;
    let count = digits.iter().take_while(|b| b.is_ascii_hexdigit()).count();
    let count = if radix == 10 {
        digits.iter().take_while(|b| b.is_ascii_digit()).count()
    } else {
        count
    };
    // At least one digit, then ';'.
    if count == 0 || digits.get(count) != Some(&b';') {
        return None;
    }
    // pugixml accumulates in 32-bit unsigned arithmetic, wrapping.
    let mut code: u32 = 0;
    for &d in digits.get(..count)? {
        let v = (d as char).to_digit(radix).unwrap_or(0);
        code = code.wrapping_mul(radix).wrapping_add(v);
    }
    Some((encode_utf8_like_pugixml(code), digits_start + count + 1))
}

/// pugixml's UTF-8 writer, which encodes any 32-bit value (surrogates and values past
/// U+10FFFF give bytes that are not UTF-8, which the caller then refuses).
fn encode_utf8_like_pugixml(c: u32) -> Vec<u8> {
    if c < 0x80 {
        vec![c as u8]
    } else if c < 0x800 {
        vec![0xC0 | (c >> 6) as u8, 0x80 | (c & 0x3F) as u8]
    } else if c < 0x10000 {
        vec![
            0xE0 | (c >> 12) as u8,
            0x80 | ((c >> 6) & 0x3F) as u8,
            0x80 | (c & 0x3F) as u8,
        ]
    } else {
        vec![
            0xF0 | ((c >> 18) & 0xFF) as u8,
            0x80 | ((c >> 12) & 0x3F) as u8,
            0x80 | ((c >> 6) & 0x3F) as u8,
            0x80 | (c & 0x3F) as u8,
        ]
    }
}

/// Converts a file's bytes to the UTF-8 text the reader parses, as pugixml's encoding
/// detection does: UTF-32 and UTF-16 by byte order mark or by a leading `<`, Latin-1 when the
/// XML declaration says so, UTF-8 otherwise (left as it is, byte order mark included).
pub(super) fn to_utf8(bytes: &[u8]) -> Cow<'_, [u8]> {
    let b = |i: usize| bytes.get(i).copied().unwrap_or(0xAA);
    if bytes.len() < 4 {
        return Cow::Borrowed(bytes);
    }
    let (d0, d1, d2, d3) = (b(0), b(1), b(2), b(3));
    let utf32 = |big: bool| -> Cow<'_, [u8]> {
        let text: String = bytes
            .chunks(4)
            .filter(|c| c.len() == 4)
            .map(|c| {
                let a = [c[0], c[1], c[2], c[3]];
                let v = if big {
                    u32::from_be_bytes(a)
                } else {
                    u32::from_le_bytes(a)
                };
                char::from_u32(v).unwrap_or(char::REPLACEMENT_CHARACTER)
            })
            .collect();
        Cow::Owned(text.into_bytes())
    };
    let utf16 = |big: bool| -> Cow<'_, [u8]> {
        let units = bytes.chunks(2).filter(|c| c.len() == 2).map(|c| {
            if big {
                u16::from_be_bytes([c[0], c[1]])
            } else {
                u16::from_le_bytes([c[0], c[1]])
            }
        });
        let text: String = char::decode_utf16(units)
            .map(|r| r.unwrap_or(char::REPLACEMENT_CHARACTER))
            .collect();
        Cow::Owned(text.into_bytes())
    };
    match (d0, d1, d2, d3) {
        (0, 0, 0xFE, 0xFF) | (0, 0, 0, 0x3C) => utf32(true),
        (0xFF, 0xFE, 0, 0) | (0x3C, 0, 0, 0) => utf32(false),
        (0xFE, 0xFF, _, _) | (0, 0x3C, _, _) => utf16(true),
        (0xFF, 0xFE, _, _) | (0x3C, 0, _, _) => utf16(false),
        (0xEF, 0xBB, 0xBF, _) => Cow::Borrowed(bytes),
        _ if declares_latin1(bytes) => {
            let text: String = bytes.iter().map(|&b| b as char).collect();
            Cow::Owned(text.into_bytes())
        }
        _ => Cow::Borrowed(bytes),
    }
}

/// Whether the text starts with an XML declaration whose encoding is ISO-8859-1 or latin1
/// (any case), as pugixml's detection reads it.
fn declares_latin1(bytes: &[u8]) -> bool {
    if bytes.len() < 6 || !bytes.starts_with(b"<?xml") || !is_space(bytes[5]) {
        return false;
    }
    let mut i = 6;
    while i + 1 < bytes.len() {
        match bytes[i] {
            b'?' => return false,
            b'e' if bytes[i + 1] == b'n' => {
                let rest = &bytes[i..];
                let Some(mut rest) = rest.strip_prefix(b"encoding") else {
                    return false;
                };
                let skip_ws =
                    |r: &[u8]| -> usize { r.iter().take_while(|&&b| is_space(b)).count() };
                rest = &rest[skip_ws(rest)..];
                let Some(r) = rest.strip_prefix(b"=") else {
                    return false;
                };
                rest = &r[skip_ws(r)..];
                let quote = if rest.first() == Some(&b'"') {
                    b'"'
                } else {
                    b'\''
                };
                let Some(r) = rest.strip_prefix(&[quote]) else {
                    return false;
                };
                let len = r.iter().take_while(|&&b| is_symbol(b)).count();
                if r.get(len) != Some(&quote) {
                    return false;
                }
                let name = r[..len].to_ascii_lowercase();
                return name == b"iso-8859-1" || name == b"latin1";
            }
            _ => i += 1,
        }
    }
    false
}

/// The parser's state: the text, the position and the elements built so far.
struct Reader<'t> {
    text: &'t [u8],
    pos: usize,
    elements: Vec<ElementData>,
    attributes: Vec<AttributeData>,
    /// The open elements, innermost last: the name and the index of the element (`NONE`
    /// for elements after the document element, which are checked but not kept).
    open: Vec<(Range<usize>, u32)>,
    /// Whether the document element has been closed (later elements are not kept).
    document_done: bool,
}

/// Parses `text` (UTF-8 bytes, or at least ASCII-compatible ones; see [`to_utf8`]).
pub(super) fn parse(text: &[u8]) -> Result<Markup<'_>, SyntaxError> {
    // A NUL byte ends the document.
    let end = text.iter().position(|&b| b == 0).unwrap_or(text.len());
    let text = text.get(..end).unwrap_or_default();
    let start = if text.starts_with(b"\xEF\xBB\xBF") {
        3
    } else {
        0
    };
    let mut reader = Reader {
        text,
        pos: start,
        elements: Vec::new(),
        attributes: Vec::new(),
        open: Vec::new(),
        document_done: false,
    };
    reader.run()?;
    if reader.elements.is_empty() {
        return Err(SyntaxError {
            message: Cow::Borrowed("No document element found"),
            offset: text.len(),
        });
    }
    Ok(Markup {
        text,
        elements: reader.elements,
        attributes: reader.attributes,
    })
}

impl<'t> Reader<'t> {
    fn byte(&self, i: usize) -> Option<u8> {
        self.text.get(i).copied()
    }

    fn error<T>(&self, message: &'static str, offset: usize) -> Result<T, SyntaxError> {
        Err(SyntaxError {
            message: Cow::Borrowed(message),
            offset,
        })
    }

    /// The offset of the first occurrence of `pattern` at or after `from`.
    fn find(&self, from: usize, pattern: &[u8]) -> Option<usize> {
        let hay = self.text.get(from..)?;
        if pattern.len() == 1 {
            return hay.iter().position(|&b| b == pattern[0]).map(|p| from + p);
        }
        hay.windows(pattern.len())
            .position(|w| w == pattern)
            .map(|p| from + p)
    }

    fn skip_space(&mut self) {
        while self.byte(self.pos).is_some_and(is_space) {
            self.pos += 1;
        }
    }

    /// The end of the run of name bytes starting at `from`.
    fn symbol_end(&self, from: usize) -> usize {
        let mut i = from;
        while self.byte(i).is_some_and(is_symbol) {
            i += 1;
        }
        i
    }

    fn run(&mut self) -> Result<(), SyntaxError> {
        // Text, inside elements or outside: nothing in it matters until the next '<'.
        while let Some(lt) = self.find(self.pos, b"<") {
            self.pos = lt + 1;
            match self.byte(self.pos) {
                Some(b) if is_start_symbol(b) => self.start_tag(lt)?,
                Some(b'/') => self.end_tag()?,
                Some(b'?') => self.processing_instruction()?,
                Some(b'!') => self.exclamation(lt)?,
                _ => return self.error("Could not determine tag type", self.pos),
            }
        }
        if !self.open.is_empty() {
            return self.error("Start-end tags mismatch", self.text.len());
        }
        Ok(())
    }

    /// `<name attributes... >` or `/>`, with `self.pos` at the name.
    fn start_tag(&mut self, lt: usize) -> Result<(), SyntaxError> {
        let name = self.pos..self.symbol_end(self.pos);
        if std::str::from_utf8(self.text.get(name.clone()).unwrap_or_default()).is_err() {
            return self.error("element name is not valid UTF-8", name.start);
        }
        self.pos = name.end;
        let keep = !self.document_done;
        let first_attribute = self.attributes.len();
        let index = if keep {
            if self.elements.len() >= MAX_ELEMENTS {
                return Err(SyntaxError {
                    message: Cow::Owned(format!(
                        "the document has more than {MAX_ELEMENTS} elements"
                    )),
                    offset: lt,
                });
            }
            u32::try_from(self.elements.len()).unwrap_or(NONE)
        } else {
            NONE
        };
        if self.open.len() >= MAX_DEPTH {
            return Err(SyntaxError {
                message: Cow::Owned(format!(
                    "elements are nested more than {MAX_DEPTH} levels deep"
                )),
                offset: lt,
            });
        }
        let mut empty = false;
        match self.byte(self.pos) {
            Some(b'>') => self.pos += 1,
            Some(b'/') => {
                if self.byte(self.pos + 1) != Some(b'>') {
                    return self.error("Error parsing start element tag", self.pos + 1);
                }
                self.pos += 2;
                empty = true;
            }
            Some(b) if is_space(b) => {
                empty = self.attributes_of_tag(keep)?;
            }
            _ => return self.error("Error parsing start element tag", self.pos),
        }
        if keep {
            let parent = self.open.last().map_or(NONE, |(_, i)| *i);
            let attributes = u32::try_from(first_attribute).unwrap_or(NONE)
                ..u32::try_from(self.attributes.len()).unwrap_or(NONE);
            self.elements.push(ElementData {
                start: lt,
                name: name.clone(),
                attributes,
                first_child: NONE,
                last_child: NONE,
                next_sibling: NONE,
            });
            if let Some(p) = self.elements.get_mut(parent as usize) {
                let previous = std::mem::replace(&mut p.last_child, index);
                if previous == NONE {
                    p.first_child = index;
                } else if let Some(prev) = self.elements.get_mut(previous as usize) {
                    prev.next_sibling = index;
                }
            }
        }
        if empty {
            self.closed();
        } else {
            self.open.push((name, index));
        }
        Ok(())
    }

    /// Notes that an element was closed: after the document element, nothing more is kept.
    fn closed(&mut self) {
        if self.open.is_empty() {
            self.document_done = true;
        }
    }

    /// The attributes of a start tag, from the whitespace after its name to its `>` or `/>`;
    /// returns whether the element is empty (`/>`).
    fn attributes_of_tag(&mut self, keep: bool) -> Result<bool, SyntaxError> {
        loop {
            self.skip_space();
            match self.byte(self.pos) {
                Some(b) if is_start_symbol(b) => {
                    let name = self.pos..self.symbol_end(self.pos);
                    if std::str::from_utf8(self.text.get(name.clone()).unwrap_or_default()).is_err()
                    {
                        return self.error("attribute name is not valid UTF-8", name.start);
                    }
                    self.pos = name.end;
                    self.skip_space();
                    if self.byte(self.pos) != Some(b'=') {
                        return self.error("Error parsing element attribute", self.pos);
                    }
                    self.pos += 1;
                    self.skip_space();
                    let quote = match self.byte(self.pos) {
                        Some(q @ (b'"' | b'\'')) => q,
                        _ => return self.error("Error parsing element attribute", self.pos),
                    };
                    let value_start = self.pos + 1;
                    let Some(value_end) = self.find(value_start, &[quote]) else {
                        return self.error("Error parsing element attribute", value_start);
                    };
                    self.pos = value_end + 1;
                    if self.byte(self.pos).is_some_and(is_start_symbol) {
                        return self.error("Error parsing element attribute", self.pos);
                    }
                    if keep {
                        self.attributes.push(AttributeData {
                            name,
                            value: value_start..value_end,
                        });
                    }
                }
                Some(b'/') => {
                    if self.byte(self.pos + 1) != Some(b'>') {
                        return self.error("Error parsing start element tag", self.pos + 1);
                    }
                    self.pos += 2;
                    return Ok(true);
                }
                Some(b'>') => {
                    self.pos += 1;
                    return Ok(false);
                }
                _ => return self.error("Error parsing start element tag", self.pos),
            }
        }
    }

    /// `</name>`, with `self.pos` at the `/`.
    fn end_tag(&mut self) -> Result<(), SyntaxError> {
        self.pos += 1;
        let mark = self.pos;
        let end = self.symbol_end(self.pos);
        let matches = self
            .open
            .last()
            .is_some_and(|(name, _)| self.text.get(name.clone()) == self.text.get(mark..end));
        if !matches {
            return self.error("Start-end tags mismatch", mark);
        }
        self.open.pop();
        self.pos = end;
        self.skip_space();
        if self.byte(self.pos) != Some(b'>') {
            return self.error("Error parsing end element tag", self.pos);
        }
        self.pos += 1;
        self.closed();
        Ok(())
    }

    /// `<?target ...?>`, with `self.pos` at the `?`.
    fn processing_instruction(&mut self) -> Result<(), SyntaxError> {
        let target = self.pos + 1;
        const BAD: &str = "Error parsing document declaration/processing instruction";
        if !self.byte(target).is_some_and(is_start_symbol) {
            return self.error(BAD, target);
        }
        let after = self.symbol_end(target);
        if after >= self.text.len() {
            return self.error(BAD, after);
        }
        match self.find(after, b"?>") {
            Some(end) => {
                self.pos = end + 2;
                Ok(())
            }
            None => self.error(BAD, self.text.len()),
        }
    }

    /// `<!--...-->`, `<![CDATA[...]]>` or `<!DOCTYPE ...>`, with `self.pos` at the `!`.
    fn exclamation(&mut self, lt: usize) -> Result<(), SyntaxError> {
        let rest = self.text.get(self.pos..).unwrap_or_default();
        if rest.starts_with(b"!--") {
            match self.find(self.pos + 3, b"-->") {
                Some(end) => {
                    self.pos = end + 3;
                    Ok(())
                }
                None => self.error("Error parsing comment", self.pos + 3),
            }
        } else if rest.starts_with(b"!-") {
            self.error("Error parsing comment", self.pos + 2)
        } else if rest.starts_with(b"![CDATA[") {
            match self.find(self.pos + 8, b"]]>") {
                Some(end) => {
                    self.pos = end + 3;
                    Ok(())
                }
                None => self.error("Error parsing CDATA section", self.pos + 8),
            }
        } else if rest.starts_with(b"![") {
            self.error("Error parsing CDATA section", self.pos + 1)
        } else if rest.starts_with(b"!DOCTYPE") {
            if !self.open.is_empty() {
                return self.error("Error parsing document type declaration", lt);
            }
            self.doctype()
        } else {
            self.error("Could not determine tag type", self.pos)
        }
    }

    /// A DOCTYPE (skipped), with `self.pos` at its `!`: nested `<!...>` groups, `<![...]]>`
    /// sections, quoted strings, comments and processing instructions, up to the `>` that
    /// closes it.
    fn doctype(&mut self) -> Result<(), SyntaxError> {
        const BAD: &str = "Error parsing document type declaration";
        let mut depth = 0usize;
        let mut s = self.pos + 1;
        while let Some(b) = self.byte(s) {
            let next = self.byte(s + 1);
            let next2 = self.byte(s + 2);
            if b == b'<' && next == Some(b'!') && next2 != Some(b'-') {
                if next2 == Some(b'[') {
                    s = self.doctype_ignore(s)?;
                } else {
                    s += 2;
                    depth += 1;
                }
            } else if b == b'"' || b == b'\'' {
                match self.find(s + 1, &[b]) {
                    Some(end) => s = end + 1,
                    None => return self.error(BAD, self.text.len()),
                }
            } else if b == b'<' && next == Some(b'?') {
                match self.find(s + 2, b"?>") {
                    Some(end) => s = end + 2,
                    None => return self.error(BAD, self.text.len()),
                }
            } else if b == b'<' && next == Some(b'!') && next2 == Some(b'-') {
                if self.byte(s + 3) != Some(b'-') {
                    return self.error(BAD, s);
                }
                match self.find(s + 4, b"-->") {
                    Some(end) => s = end + 3,
                    None => return self.error(BAD, self.text.len()),
                }
            } else if b == b'<' {
                return self.error(BAD, s);
            } else if b == b'>' {
                if depth == 0 {
                    self.pos = s + 1;
                    return Ok(());
                }
                depth -= 1;
                s += 1;
            } else {
                s += 1;
            }
        }
        self.error(BAD, self.text.len())
    }

    /// A `<![ ... ]]>` section inside a DOCTYPE (nested ones counted), starting at `s`;
    /// returns the offset after it.
    fn doctype_ignore(&self, s: usize) -> Result<usize, SyntaxError> {
        let mut depth = 0usize;
        let mut i = s + 3;
        while i < self.text.len() {
            let rest = self.text.get(i..).unwrap_or_default();
            if rest.starts_with(b"<![") {
                i += 3;
                depth += 1;
            } else if rest.starts_with(b"]]>") {
                i += 3;
                if depth == 0 {
                    return Ok(i);
                }
                depth -= 1;
            } else {
                i += 1;
            }
        }
        self.error("Error parsing document type declaration", self.text.len())
    }
}
