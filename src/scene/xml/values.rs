//! Mitsuba 3.9.1's syntax for numbers, lists of numbers and version numbers in attribute
//! values (`string::stof`, `string::tokenize`, `std::from_chars` and `util::Version` as the
//! parser uses them).

/// Splits a list at commas and spaces (Mitsuba's `tokenize` with its default delimiters; a
/// tab or line feed written as a character reference does not separate).
pub(super) fn tokenize(text: &str) -> impl Iterator<Item = &str> {
    text.split([',', ' ']).filter(|token| !token.is_empty())
}

/// Mitsuba's `string::stof`: spaces and tabs around the number, one optional leading `+`,
/// then a decimal number, `inf`, `infinity` or `nan` (any case); an empty or blank text is 0.
/// The result may be non-finite (the caller decides).
pub(super) fn parse_float(text: &str) -> Option<f64> {
    const BLANK: [char; 2] = [' ', '\t'];
    let trimmed = text.trim_matches(BLANK);
    if trimmed.is_empty() {
        // Mitsuba's parse fails and leaves its end pointer at the start, so only blanks
        // follow: a success with the value 0.
        return Some(0.0);
    }
    let number = trimmed.strip_prefix('+').unwrap_or(trimmed);
    if number.starts_with('+') {
        return None;
    }
    number.parse::<f64>().ok()
}

/// C's `isspace` in the C locale.
fn is_c_space(c: char) -> bool {
    matches!(c, ' ' | '\t' | '\n' | '\x0B' | '\x0C' | '\r')
}

/// Mitsuba's `<integer>`: optional whitespace, an optional `-` (no `+`), decimal digits that
/// fit in 64 bits, optional whitespace.
pub(super) fn parse_integer(text: &str) -> Option<i64> {
    let t = text.trim_matches(is_c_space);
    let digits = t.strip_prefix('-').unwrap_or(t);
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    t.parse::<i64>().ok()
}

/// C++'s `std::stoul` on one part of a version: leading whitespace, an optional sign, at
/// least one digit, anything after the digits ignored; a negative value wraps, and Mitsuba
/// keeps the low 32 bits (`unsigned int`).
fn stoul_u32(text: &str) -> Option<u32> {
    let t = text.trim_start_matches(is_c_space);
    let (negative, t) = match t.as_bytes().first() {
        Some(b'-') => (true, t.get(1..)?),
        Some(b'+') => (false, t.get(1..)?),
        _ => (false, t),
    };
    let len = t.bytes().take_while(u8::is_ascii_digit).count();
    let value: u64 = t.get(..len)?.parse().ok()?;
    let value = if negative {
        value.wrapping_neg()
    } else {
        value
    };
    Some(value as u32)
}

/// Mitsuba's `util::Version`: exactly three non-empty parts separated by `.` or spaces, each
/// read by `std::stoul` (so `3a.0.0` is 3.0.0 and `1..2.3` is 1.2.3).
pub(super) fn parse_version(text: &str) -> Option<(u32, u32, u32)> {
    let parts: Vec<&str> = text.split(['.', ' ']).filter(|p| !p.is_empty()).collect();
    match parts.as_slice() {
        [major, minor, patch] => Some((stoul_u32(major)?, stoul_u32(minor)?, stoul_u32(patch)?)),
        _ => None,
    }
}
