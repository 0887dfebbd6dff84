//! Exact sums of f64 values at any scale, canonical so that any grouping of the same terms
//! gives the same bits (issue 40; design note `exact-film.md`, §3.4 and §4).
//!
//! A value is m · 2^e with m an odd `i128` of fewer than [`INLINE_BITS`] bits and e an `i16`
//! (zero is (0, 0)): the exponent only ever goes down to the lowest set bit of the exact sum,
//! and no bit is ever dropped. When the sum does not fit (its span from lowest to highest set
//! bit exceeds the inline capacity, e.g. the square of a 1e30 firefly added to unit squares),
//! it spills to a [`Big`]: an exact multi-limb integer times 2^(64·base), also canonical.
//! Whether a value is inline or spilled depends only on its exact value, so the whole state
//! is a function of the exact sums: adding the same passes in any order, in parts merged in
//! any tree, gives the same bytes. Read-out rounds the exact sum once to the nearest f64
//! (ties to even), so it is correctly rounded over the whole f64 range, subnormals included.
//!
//! Non-finite terms are refused ([`ExactError::NonFinite`]), never absorbed.

use super::{Film, Filter};
use rayon::prelude::*;
use std::collections::BTreeMap;

/// Sums per pixel in an [`ExactFilm`]: sum (3), sum_sq (3), sum_w2 (3), sum_sq_w2 (3),
/// weight, weight_sq, weight_cube, in [`Film`]'s order.
pub const EXACT_VALUES: usize = 15;

/// The widest inline mantissa: |m| < 2^125, so that two aligned mantissas add in an i128
/// without overflow.
pub const INLINE_BITS: u32 = 125;

/// The exponent of an inline slot whose value lives in the spill table.
const SPILLED: i16 = i16::MIN;

/// The lowest bit any sum of f64 values can have (the smallest subnormal, 2⁻¹⁰⁷⁴).
pub const LOWEST_BIT: i64 = -1074;

/// The highest bit a stored value may have when read from a file (a sum of f64 values below
/// 2¹⁰²⁴ reaches 2¹²⁰⁰ only after 2¹⁷⁶ terms): bounds a hostile file's spill entries.
pub const HIGHEST_BIT: i64 = 1200;

/// The most limbs a spilled value within [LOWEST_BIT, HIGHEST_BIT] needs (with a sign limb).
const MAX_LIMBS: usize = ((HIGHEST_BIT - LOWEST_BIT) / 64 + 3) as usize;

/// Pixels per chunk: the unit of parallel work, each with its own spill table.
const CHUNK: usize = 1024;

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ExactError {
    #[error("pixel ({x}, {y}): sum {index} is not finite ({value}); an exact film only adds finite values")]
    NonFinite {
        x: usize,
        y: usize,
        index: usize,
        value: f64,
    },
    #[error("a term is not finite ({0}); an exact sum only adds finite values")]
    NonFiniteTerm(f64),
    #[error("cannot add a {0}x{1} film to a {2}x{3} one")]
    Size(usize, usize, usize, usize),
    #[error("exact film state: {0}")]
    Corrupt(&'static str),
}

/// An exact integer times 2^(64·base), in 64-bit limbs (little-endian two's complement: the
/// top limb's top bit is the sign). Canonical: no zero lowest limb, no top limb that only
/// repeats the sign of the one below, zero as no limbs and base 0. So equal values have equal
/// representations.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub struct Big {
    base: i32,
    limbs: Vec<u64>,
}

impl Big {
    /// m · 2^e.
    pub fn from_parts(m: i128, e: i32) -> Big {
        if m == 0 {
            return Big::default();
        }
        let (base, sh) = (e.div_euclid(64), e.rem_euclid(64) as u32);
        let (lo, mid, top) = (m as u64, (m >> 64) as u64, (m >> 127) as u64);
        // |m| ≤ 2^127 and sh < 64: the 192-bit two's complement holds m · 2^sh.
        let limbs = if sh == 0 {
            vec![lo, mid, top]
        } else {
            vec![
                lo << sh,
                (mid << sh) | (lo >> (64 - sh)),
                (top << sh) | (mid >> (64 - sh)),
            ]
        };
        let mut b = Big { base, limbs };
        b.canonicalize();
        b
    }

    pub fn is_zero(&self) -> bool {
        self.limbs.is_empty()
    }

    fn negative(&self) -> bool {
        self.limbs.last().is_some_and(|&l| (l as i64) < 0)
    }

    /// The limb at absolute index k (zero below, the sign above).
    #[inline]
    fn limb(&self, k: i64) -> u64 {
        let i = k - self.base as i64;
        if i < 0 {
            0
        } else if (i as usize) < self.limbs.len() {
            self.limbs[i as usize]
        } else if self.negative() {
            u64::MAX
        } else {
            0
        }
    }

    fn canonicalize(&mut self) {
        while let [.., a, b] = self.limbs[..] {
            if (b == 0 && (a as i64) >= 0) || (b == u64::MAX && (a as i64) < 0) {
                self.limbs.pop();
            } else {
                break;
            }
        }
        let zeros = self.limbs.iter().take_while(|&&l| l == 0).count();
        if zeros == self.limbs.len() {
            self.limbs.clear();
            self.base = 0;
        } else if zeros > 0 {
            self.limbs.drain(..zeros);
            self.base += zeros as i32;
        }
    }

    /// The exact sum.
    pub fn add(&self, o: &Big) -> Big {
        if self.is_zero() {
            return o.clone();
        }
        if o.is_zero() {
            return self.clone();
        }
        let lo = self.base.min(o.base) as i64;
        // One limb more than the wider operand: the sum of two sign-extended numbers fits.
        let hi = (self.base as i64 + self.limbs.len() as i64)
            .max(o.base as i64 + o.limbs.len() as i64)
            + 1;
        let mut limbs = Vec::with_capacity((hi - lo) as usize);
        let mut carry = 0u64;
        for k in lo..hi {
            let (s1, c1) = self.limb(k).overflowing_add(o.limb(k));
            let (s2, c2) = s1.overflowing_add(carry);
            limbs.push(s2);
            carry = (c1 | c2) as u64;
        }
        let mut b = Big {
            base: lo as i32,
            limbs,
        };
        b.canonicalize();
        b
    }

    /// The magnitude's limbs (unsigned, from `base`) and the sign.
    fn magnitude(&self) -> (bool, Vec<u64>) {
        let neg = self.negative();
        if !neg {
            return (false, self.limbs.clone());
        }
        let mut v: Vec<u64> = self.limbs.iter().map(|l| !l).collect();
        for x in v.iter_mut() {
            let (s, c) = x.overflowing_add(1);
            *x = s;
            if !c {
                break;
            }
        }
        (true, v)
    }

    /// (negative, lowest set bit, highest set bit) of a non-zero value, and its magnitude.
    fn span(&self) -> Option<(bool, i64, i64, Vec<u64>)> {
        let (neg, mag) = self.magnitude();
        let top_i = mag.iter().rposition(|&l| l != 0)?;
        let low_i = mag.iter().position(|&l| l != 0)?;
        let b = self.base as i64 * 64;
        let top = b + top_i as i64 * 64 + 63 - mag[top_i].leading_zeros() as i64;
        let low = b + low_i as i64 * 64 + mag[low_i].trailing_zeros() as i64;
        Some((neg, low, top, mag))
    }

    /// The value as an inline (m, e), if it fits `cap` bits.
    fn to_inline(&self, cap: u32) -> Option<(i128, i16)> {
        if self.is_zero() {
            return Some((0, 0));
        }
        if self.limbs.len() > 3 {
            return None;
        }
        let tz = self.limbs[0].trailing_zeros();
        let k = self.base as i64;
        let (a, b, c) = (self.limb(k), self.limb(k + 1), self.limb(k + 2));
        let (a, b, c) = if tz == 0 {
            (a, b, c)
        } else {
            (
                (a >> tz) | (b << (64 - tz)),
                (b >> tz) | (c << (64 - tz)),
                ((c as i64) >> tz) as u64,
            )
        };
        if c != ((b as i64) >> 63) as u64 {
            return None;
        }
        let m = (((b as u128) << 64) | a as u128) as i128;
        if m.unsigned_abs() >> cap != 0 {
            return None;
        }
        let e = i16::try_from(k * 64 + tz as i64)
            .ok()
            .filter(|&e| e != SPILLED)?;
        Some((m, e))
    }

    /// The nearest f64 (ties to even; ±∞ beyond the largest finite value).
    pub fn to_f64(&self) -> f64 {
        let Some((neg, low, top, mag)) = self.span() else {
            return 0.0;
        };
        let b = self.base as i64 * 64;
        round_bits(neg, top, low, |p| {
            let rel = p - b;
            let (li, sh) = (rel.div_euclid(64), rel.rem_euclid(64) as u32);
            let get = |i: i64| {
                if i < 0 || i as usize >= mag.len() {
                    0
                } else {
                    mag[i as usize]
                }
            };
            if sh == 0 {
                get(li)
            } else {
                (get(li) >> sh) | (get(li + 1) << (64 - sh))
            }
        })
    }

    /// Whether the value's bits lie within [LOWEST_BIT, HIGHEST_BIT].
    fn in_range(&self) -> bool {
        self.span()
            .is_none_or(|(_, low, top, _)| low >= LOWEST_BIT && top <= HIGHEST_BIT)
    }
}

/// Rounds the magnitude whose highest set bit is `top` and lowest `low` to the nearest f64
/// (ties to even); `window(p)` gives its bits [p, p + 64).
fn round_bits(neg: bool, top: i64, low: i64, window: impl Fn(i64) -> u64) -> f64 {
    let sign = if neg { 1u64 << 63 } else { 0 };
    const INF: u64 = 0x7ff0_0000_0000_0000;
    if top >= 1024 {
        return f64::from_bits(sign | INF);
    }
    let q = (top - 52).max(-1074); // the lowest bit kept
    let width = top - q + 1; // at most 53; ≤ 0 below the smallest subnormal
    let mut mant = if width <= 0 {
        0
    } else {
        window(q) & (u64::MAX >> (64 - width))
    };
    if low < q {
        let guard = window(q - 1) & 1 == 1;
        let sticky = low < q - 1;
        if guard && (sticky || mant & 1 == 1) {
            mant += 1;
        }
    }
    let (mant, q) = if mant == 1 << 53 {
        (1u64 << 52, q + 1)
    } else {
        (mant, q)
    };
    let bits = if mant < 1 << 52 {
        mant // subnormal (q = -1074) or zero
    } else {
        let biased = q + 1075;
        if biased >= 2047 {
            INF
        } else {
            ((biased as u64) << 52) | (mant & ((1 << 52) - 1))
        }
    };
    f64::from_bits(sign | bits)
}

/// 2^e for e in [-1022, 1023].
#[inline(always)]
fn pow2(e: i32) -> f64 {
    f64::from_bits(((e + 1023) as u64) << 52)
}

/// The nearest f64 to m · 2^e.
#[inline]
fn inline_to_f64(m: i128, e: i16) -> f64 {
    if m == 0 {
        return 0.0;
    }
    let e = e as i32;
    let mag = m.unsigned_abs();
    let top = 127 - mag.leading_zeros() as i32 + e;
    if (-1022..=1023).contains(&top) {
        // |m| rounds once to 53 bits (ties to even, at any exponent): as an i64 directly, or
        // its top 63 bits with the rest as a sticky bit (below the rounding position, so
        // the rounding is the same; an i64 conversion is one instruction, an i128 one a
        // call). The scaling by 2^e is then exact, or overflows to ∞ exactly when the
        // rounded value does.
        let lz = mag.leading_zeros();
        let (r, e) = if lz >= 65 {
            (mag as u64 as i64 as f64, e)
        } else {
            let sh = 65 - lz;
            let sticky = (mag & ((1u128 << sh) - 1) != 0) as u64;
            ((((mag >> sh) as u64) | sticky) as i64 as f64, e + sh as i32)
        };
        let r = if m < 0 { -r } else { r };
        if e >= -1022 {
            r * pow2(e)
        } else {
            r * pow2(e + 200) * pow2(-200)
        }
    } else {
        let low = (mag.trailing_zeros() as i32 + e) as i64;
        round_bits(m < 0, top as i64, low, |p| {
            let rel = p - e as i64;
            if rel >= 128 || rel <= -64 {
                0
            } else if rel >= 0 {
                (mag >> rel) as u64
            } else {
                (mag << -rel) as u64
            }
        })
    }
}

/// A finite f64 as (odd integer, exponent), or (0, 0).
#[inline(always)]
fn decompose(x: f64) -> (i128, i32) {
    let bits = x.to_bits();
    let exp = ((bits >> 52) & 0x7ff) as i32;
    let frac = bits & ((1 << 52) - 1);
    let (mant, e) = if exp == 0 {
        (frac, -1074)
    } else {
        (frac | (1 << 52), exp - 1075)
    };
    if mant == 0 {
        return (0, 0);
    }
    let tz = mant.trailing_zeros();
    let a = (mant >> tz) as i64;
    let a = if bits >> 63 == 1 { -a } else { a };
    (a as i128, e + tz as i32)
}

/// m · 2^e + a · 2^f for canonical inline operands (odd or zero mantissas), if the sum is
/// inline within `cap` bits; None sends the caller to the exact slow path.
///
/// Only a sum of two terms with the same exponent can have trailing zeros (both odd): with
/// different exponents the lower term's lowest bit is the sum's, so the sum is already odd.
#[inline(always)]
fn add_inline(cap: Cap, m: i128, e: i32, a: i128, f: i32) -> Option<(i128, i16)> {
    if a == 0 {
        return Some((m, e as i16));
    }
    let limit = cap.limit;
    if a.unsigned_abs() >= limit {
        return None;
    }
    let exponent = |x: i32| i16::try_from(x).ok().filter(|&x| x != SPILLED);
    if m == 0 {
        return Some((a, exponent(f)?));
    }
    if e == f {
        // Both below 2^cap ≤ 2^125 in magnitude: no overflow.
        let s = m + a;
        if s == 0 {
            return Some((0, 0));
        }
        let tz = s.trailing_zeros();
        let r = s >> tz;
        if r.unsigned_abs() >= limit {
            return None;
        }
        return Some((r, exponent(e + tz as i32)?));
    }
    let (hi, ehi, lo, elo) = if e > f { (m, e, a, f) } else { (a, f, m, e) };
    let d = (ehi - elo) as u32;
    let bits = 128 - hi.unsigned_abs().leading_zeros();
    if d + bits > cap.bits {
        return None;
    }
    // Both terms below 2^cap ≤ 2^125 in magnitude: no overflow; lo is odd, so is the sum.
    let s = (hi << d) + lo;
    if s.unsigned_abs() >= limit {
        return None;
    }
    Some((s, exponent(elo)?))
}

/// Adds a · 2^f (a canonical term) to an inline slot; false when the slot is spilled or the
/// sum does not fit inline.
#[inline(always)]
fn add_fast(cap: Cap, m: &mut i128, e: &mut i16, a: i128, f: i32) -> bool {
    if *e == SPILLED {
        return false;
    }
    match add_inline(cap, *m, *e as i32, a, f) {
        Some((nm, ne)) => {
            *m = nm;
            *e = ne;
            true
        }
        None => false,
    }
}

/// The exact sum of a slot (its spilled value `stored`, or its inline one) and `term`:
/// stored back inline if it fits, else returned as the slot's new spilled value.
#[cold]
#[inline(never)]
fn add_slow(cap: u32, m: &mut i128, e: &mut i16, stored: Option<Big>, term: &Big) -> Option<Big> {
    let current = match stored {
        Some(b) => b,
        None if *e == SPILLED => Big::default(),
        None => Big::from_parts(*m, *e as i32),
    };
    let sum = current.add(term);
    match sum.to_inline(cap) {
        Some((nm, ne)) => {
            *m = nm;
            *e = ne;
            None
        }
        None => {
            *m = 0;
            *e = SPILLED;
            Some(sum)
        }
    }
}

fn check_cap(bits: u32) -> u32 {
    bits.clamp(1, INLINE_BITS)
}

/// An inline capacity: mantissas below 2^bits (`limit`, computed once per film add instead of
/// a 128-bit shift per value).
#[derive(Clone, Copy)]
struct Cap {
    bits: u32,
    limit: u128,
}

impl Cap {
    fn new(bits: u32) -> Cap {
        Cap {
            bits,
            limit: 1u128 << bits,
        }
    }
}

/// One exact sum: the accumulator of an [`ExactFilm`] value, on its own.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExactSum {
    cap: u32,
    m: i128,
    e: i16,
    big: Option<Big>,
}

impl Default for ExactSum {
    fn default() -> Self {
        Self::new()
    }
}

impl ExactSum {
    pub fn new() -> Self {
        Self::with_inline_bits(INLINE_BITS)
    }

    /// An accumulator whose inline mantissa holds fewer than `bits` bits (1 to
    /// [`INLINE_BITS`]): small capacities send nearly every sum to the spill path, for tests.
    pub fn with_inline_bits(bits: u32) -> Self {
        ExactSum {
            cap: check_cap(bits),
            m: 0,
            e: 0,
            big: None,
        }
    }

    /// The exact sum of m · 2^e (any integer m, any exponent).
    pub fn from_parts(m: i128, e: i32, bits: u32) -> Self {
        let mut s = Self::with_inline_bits(bits);
        s.add_parts(m, e);
        s
    }

    fn add_parts(&mut self, m: i128, e: i32) {
        if m == 0 {
            return;
        }
        let tz = m.trailing_zeros();
        let (a, f) = (m >> tz, e.saturating_add(tz as i32));
        if !add_fast(Cap::new(self.cap), &mut self.m, &mut self.e, a, f) {
            let stored = self.big.take();
            self.big = add_slow(
                self.cap,
                &mut self.m,
                &mut self.e,
                stored,
                &Big::from_parts(a, f),
            );
        }
    }

    /// Adds a finite f64 exactly; a non-finite one is refused and changes nothing.
    pub fn add_f64(&mut self, x: f64) -> Result<(), ExactError> {
        if !x.is_finite() {
            return Err(ExactError::NonFiniteTerm(x));
        }
        let (a, f) = decompose(x);
        self.add_parts(a, f);
        Ok(())
    }

    /// Adds another exact sum exactly (any capacities).
    pub fn add(&mut self, o: &ExactSum) {
        match &o.big {
            Some(b) if o.e == SPILLED => {
                let stored = self.big.take();
                self.big = add_slow(self.cap, &mut self.m, &mut self.e, stored, b);
            }
            _ => self.add_parts(o.m, o.e as i32),
        }
    }

    /// The exact sum rounded once to the nearest f64 (ties to even).
    pub fn to_f64(&self) -> f64 {
        match &self.big {
            Some(b) if self.e == SPILLED => b.to_f64(),
            _ => inline_to_f64(self.m, self.e),
        }
    }

    /// Whether the sum lives in the spill path.
    pub fn is_spilled(&self) -> bool {
        self.e == SPILLED
    }

    /// The exact value: (negative, magnitude limbs little-endian, exponent of their bit 0).
    pub fn to_magnitude(&self) -> (bool, Vec<u64>, i64) {
        let big = match &self.big {
            Some(b) if self.e == SPILLED => b.clone(),
            _ => Big::from_parts(self.m, self.e as i32),
        };
        let (neg, mag) = big.magnitude();
        (neg, mag, big.base as i64 * 64)
    }

    /// The accumulator's state as stored: capacity, inline (m, e), and the spilled value's
    /// base and limbs. A function of the exact value (and capacity) alone.
    pub fn state_bytes(&self) -> Vec<u8> {
        let mut out = vec![self.cap as u8];
        out.extend_from_slice(&self.m.to_le_bytes());
        out.extend_from_slice(&self.e.to_le_bytes());
        if let (Some(b), true) = (&self.big, self.e == SPILLED) {
            write_big(&mut out, b);
        }
        out
    }
}

fn write_big(out: &mut Vec<u8>, b: &Big) {
    out.extend_from_slice(&b.base.to_le_bytes());
    out.extend_from_slice(&(b.limbs.len() as u32).to_le_bytes());
    for l in &b.limbs {
        out.extend_from_slice(&l.to_le_bytes());
    }
}

/// A film's sums held exactly, at any scale: every one of a pixel's [`EXACT_VALUES`] sums is
/// an exact, canonical m · 2^e (module docs), so adding films is associative and the sum of
/// a render's passes does not depend on how they are grouped. Renders accumulate their passes
/// here: a render split into parts (`--part i/N`, each part summing its own passes), resumed
/// from checkpoints, or merged in any order gives the image of the same render made in one
/// process, bit for bit, and the same state bytes.
///
/// Layout: the mantissas (i128) and exponents (i16) in two arrays, 270 B per pixel, and per
/// chunk of [`CHUNK`] pixels a table of the values that spilled (keyed by index in the chunk).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExactFilm {
    pub width: usize,
    pub height: usize,
    pub samples: u64,
    cap: u32,
    m: Vec<i128>,
    e: Vec<i16>,
    spill: Vec<BTreeMap<u32, Big>>,
}

/// A film's 15 sums of pixel `i`, in [`EXACT_VALUES`] order.
#[inline(always)]
fn film_values(f: &Film, i: usize) -> [f64; EXACT_VALUES] {
    let (s, q, s2, q2) = (f.sum[i], f.sum_sq[i], f.sum_w2[i], f.sum_sq_w2[i]);
    [
        s[0],
        s[1],
        s[2],
        q[0],
        q[1],
        q[2],
        s2[0],
        s2[1],
        s2[2],
        q2[0],
        q2[1],
        q2[2],
        f.weight[i],
        f.weight_sq[i],
        f.weight_cube[i],
    ]
}

impl ExactFilm {
    pub fn new(width: usize, height: usize) -> Self {
        Self::with_inline_bits(width, height, INLINE_BITS)
    }

    /// A film whose inline mantissas hold fewer than `bits` bits (see
    /// [`ExactSum::with_inline_bits`]): for tests of the spill path.
    pub fn with_inline_bits(width: usize, height: usize, bits: u32) -> Self {
        let n = width * height;
        ExactFilm {
            width,
            height,
            samples: 0,
            cap: check_cap(bits),
            m: vec![0; n * EXACT_VALUES],
            e: vec![0; n * EXACT_VALUES],
            spill: vec![BTreeMap::new(); n.div_ceil(CHUNK)],
        }
    }

    fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// Adds a film of the same size exactly. A non-finite sum is refused with the pixel it
    /// is in, and nothing is added then.
    pub fn add(&mut self, f: &Film) -> Result<(), ExactError> {
        if (f.width, f.height) != (self.width, self.height) {
            return Err(ExactError::Size(f.width, f.height, self.width, self.height));
        }
        let n = self.pixels();
        let all_finite = |v: &[[f64; 3]]| v.iter().flatten().all(|x| x.is_finite());
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !(all_finite(&f.sum[..n])
            && all_finite(&f.sum_sq[..n])
            && all_finite(&f.sum_w2[..n])
            && all_finite(&f.sum_sq_w2[..n])
            && finite(&f.weight[..n])
            && finite(&f.weight_sq[..n])
            && finite(&f.weight_cube[..n]))
        {
            for i in 0..n {
                if let Some((index, &value)) = film_values(f, i)
                    .iter()
                    .enumerate()
                    .find(|(_, x)| !x.is_finite())
                {
                    return Err(ExactError::NonFinite {
                        x: i % self.width,
                        y: i / self.width,
                        index,
                        value,
                    });
                }
            }
        }
        let (cap, fast) = (self.cap, Cap::new(self.cap));
        self.m
            .par_chunks_mut(CHUNK * EXACT_VALUES)
            .zip(self.e.par_chunks_mut(CHUNK * EXACT_VALUES))
            .zip(self.spill.par_iter_mut())
            .enumerate()
            .for_each(|(c, ((m, e), spill))| {
                let first = c * CHUNK;
                for (p, (m, e)) in m
                    .chunks_exact_mut(EXACT_VALUES)
                    .zip(e.chunks_exact_mut(EXACT_VALUES))
                    .enumerate()
                {
                    let v = film_values(f, first + p);
                    for k in 0..EXACT_VALUES {
                        let (a, fx) = decompose(v[k]);
                        if a == 0 || add_fast(fast, &mut m[k], &mut e[k], a, fx) {
                            continue;
                        }
                        let key = (p * EXACT_VALUES + k) as u32;
                        let stored = spill.remove(&key);
                        if let Some(b) =
                            add_slow(cap, &mut m[k], &mut e[k], stored, &Big::from_parts(a, fx))
                        {
                            spill.insert(key, b);
                        }
                    }
                }
            });
        self.samples = self.samples.saturating_add(f.samples);
        Ok(())
    }

    /// Adds another exact film of the same size, exactly (any inline capacities).
    pub fn add_exact(&mut self, o: &ExactFilm) -> Result<(), ExactError> {
        if (o.width, o.height) != (self.width, self.height) {
            return Err(ExactError::Size(o.width, o.height, self.width, self.height));
        }
        let (cap, fast) = (self.cap, Cap::new(self.cap));
        self.m
            .par_chunks_mut(CHUNK * EXACT_VALUES)
            .zip(self.e.par_chunks_mut(CHUNK * EXACT_VALUES))
            .zip(self.spill.par_iter_mut())
            .zip(o.m.par_chunks(CHUNK * EXACT_VALUES))
            .zip(o.e.par_chunks(CHUNK * EXACT_VALUES))
            .zip(o.spill.par_iter())
            .for_each(|(((((m, e), spill), om), oe), ospill)| {
                for j in 0..m.len() {
                    let key = j as u32;
                    let big;
                    let term = if oe[j] == SPILLED {
                        match ospill.get(&key) {
                            Some(b) => b,
                            None => continue,
                        }
                    } else {
                        if om[j] == 0 || add_fast(fast, &mut m[j], &mut e[j], om[j], oe[j] as i32) {
                            continue;
                        }
                        big = Big::from_parts(om[j], oe[j] as i32);
                        &big
                    };
                    let stored = spill.remove(&key);
                    if let Some(b) = add_slow(cap, &mut m[j], &mut e[j], stored, term) {
                        spill.insert(key, b);
                    }
                }
            });
        self.samples = self.samples.saturating_add(o.samples);
        Ok(())
    }

    /// Adds m · 2^e to value `k` of pixel `pixel` (e.g. an old checkpoint's count q of 2⁻⁴⁸
    /// is (q, −48)); out-of-range indices are ignored.
    pub fn add_parts(&mut self, pixel: usize, k: usize, m: i128, e: i32) {
        if pixel >= self.pixels() || k >= EXACT_VALUES || m == 0 {
            return;
        }
        let j = pixel * EXACT_VALUES + k;
        let tz = m.trailing_zeros();
        let (a, f) = (m >> tz, e.saturating_add(tz as i32));
        if add_fast(Cap::new(self.cap), &mut self.m[j], &mut self.e[j], a, f) {
            return;
        }
        let spill = &mut self.spill[pixel / CHUNK];
        let key = ((pixel % CHUNK) * EXACT_VALUES + k) as u32;
        let stored = spill.remove(&key);
        if let Some(b) = add_slow(
            self.cap,
            &mut self.m[j],
            &mut self.e[j],
            stored,
            &Big::from_parts(a, f),
        ) {
            spill.insert(key, b);
        }
    }

    /// Value `k` of pixel `pixel`, exactly.
    pub fn value(&self, pixel: usize, k: usize) -> ExactSum {
        let mut s = ExactSum::with_inline_bits(self.cap);
        let j = pixel * EXACT_VALUES + k;
        if j >= self.m.len() || k >= EXACT_VALUES {
            return s;
        }
        s.m = self.m[j];
        s.e = self.e[j];
        if s.e == SPILLED {
            s.big = self.spill[pixel / CHUNK]
                .get(&(((pixel % CHUNK) * EXACT_VALUES + k) as u32))
                .cloned();
        }
        s
    }

    /// How many sums spilled out of the inline representation.
    pub fn spilled(&self) -> usize {
        self.spill.iter().map(BTreeMap::len).sum()
    }

    /// The f64 film of these sums (each rounded once to the nearest f64).
    pub fn to_film(&self, filter: Filter) -> Film {
        let mut f = Film::new(self.width, self.height, filter);
        f.samples = self.samples;
        f.sum
            .par_chunks_mut(CHUNK)
            .zip(f.sum_sq.par_chunks_mut(CHUNK))
            .zip(f.sum_w2.par_chunks_mut(CHUNK))
            .zip(f.sum_sq_w2.par_chunks_mut(CHUNK))
            .zip(f.weight.par_chunks_mut(CHUNK))
            .zip(f.weight_sq.par_chunks_mut(CHUNK))
            .zip(f.weight_cube.par_chunks_mut(CHUNK))
            .zip(self.m.par_chunks(CHUNK * EXACT_VALUES))
            .zip(self.e.par_chunks(CHUNK * EXACT_VALUES))
            .zip(self.spill.par_iter())
            .for_each(|(((((((((s, q), s2), q2), w), w2), w3), m), e), spill)| {
                let g = |j: usize| {
                    if e[j] == SPILLED {
                        spill.get(&(j as u32)).map_or(0.0, Big::to_f64)
                    } else {
                        inline_to_f64(m[j], e[j])
                    }
                };
                for p in 0..s.len() {
                    let j = p * EXACT_VALUES;
                    for c in 0..3 {
                        s[p][c] = g(j + c);
                        q[p][c] = g(j + 3 + c);
                        s2[p][c] = g(j + 6 + c);
                        q2[p][c] = g(j + 9 + c);
                    }
                    w[p] = g(j + 12);
                    w2[p] = g(j + 13);
                    w3[p] = g(j + 14);
                }
            });
        f
    }

    /// The exact state, canonical (equal for equal sums, whatever their grouping):
    ///
    /// - u8: the inline capacity in bits ([`INLINE_BITS`]);
    /// - per value (pixel-major, [`EXACT_VALUES`] per pixel): the mantissa, i128;
    /// - per value: the exponent, i16 (−32768 for a spilled value, mantissa 0);
    /// - u64: the number of spilled values, then each, by increasing index: u64 index
    ///   (pixel · 15 + value), i32 base, u32 limb count, the limbs (u64 each), meaning the
    ///   two's-complement integer of the limbs times 2^(64·base).
    ///
    /// All little-endian. `width`, `height` and `samples` are the caller's to store.
    pub fn write_state(&self, out: &mut Vec<u8>) {
        out.reserve(1 + self.m.len() * 18 + 8);
        out.push(self.cap as u8);
        for m in &self.m {
            out.extend_from_slice(&m.to_le_bytes());
        }
        for e in &self.e {
            out.extend_from_slice(&e.to_le_bytes());
        }
        out.extend_from_slice(&(self.spilled() as u64).to_le_bytes());
        for (c, table) in self.spill.iter().enumerate() {
            for (key, b) in table {
                let index = (c * CHUNK * EXACT_VALUES) as u64 + *key as u64;
                out.extend_from_slice(&index.to_le_bytes());
                write_big(out, b);
            }
        }
    }

    /// [`ExactFilm::write_state`]'s bytes.
    pub fn state_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        self.write_state(&mut out);
        out
    }

    /// Reads a state written by [`ExactFilm::write_state`] from the start of `bytes`; returns
    /// the film and the bytes read. Checks the sizes against `bytes` before allocating, and
    /// refuses any state that is not canonical or out of range: never panics.
    pub fn read_state(
        bytes: &[u8],
        width: usize,
        height: usize,
        samples: u64,
    ) -> Result<(ExactFilm, usize), ExactError> {
        let bad = ExactError::Corrupt;
        let values = width
            .checked_mul(height)
            .and_then(|n| n.checked_mul(EXACT_VALUES))
            .ok_or(bad("resolution"))?;
        let fixed = values
            .checked_mul(18)
            .and_then(|b| b.checked_add(9))
            .ok_or(bad("resolution"))?;
        if bytes.len() < fixed {
            return Err(bad("shorter than its resolution"));
        }
        let cap = bytes[0] as u32;
        if !(1..=INLINE_BITS).contains(&cap) {
            return Err(bad("inline capacity"));
        }
        let mut film = ExactFilm::with_inline_bits(width, height, cap);
        film.samples = samples;
        let (mb, rest) = bytes[1..].split_at(values * 16);
        let (eb, rest) = rest.split_at(values * 2);
        let mut spilled_slots = 0usize;
        for (j, (mc, ec)) in mb.chunks_exact(16).zip(eb.chunks_exact(2)).enumerate() {
            let m = i128::from_le_bytes(mc.try_into().map_err(|_| bad("truncated"))?);
            let e = i16::from_le_bytes(ec.try_into().map_err(|_| bad("truncated"))?);
            if e == SPILLED {
                if m != 0 {
                    return Err(bad("spilled value with a mantissa"));
                }
                spilled_slots += 1;
            } else if m == 0 {
                if e != 0 {
                    return Err(bad("zero not canonical"));
                }
            } else {
                let top = 127 - m.unsigned_abs().leading_zeros() as i64 + e as i64;
                if m & 1 == 0 || m.unsigned_abs() >> cap != 0 {
                    return Err(bad("value not canonical"));
                }
                if (e as i64) < LOWEST_BIT || top > HIGHEST_BIT {
                    return Err(bad("value out of range"));
                }
            }
            film.m[j] = m;
            film.e[j] = e;
        }
        let count = u64::from_le_bytes(rest[..8].try_into().map_err(|_| bad("truncated"))?);
        if count != spilled_slots as u64 {
            return Err(bad("spill count"));
        }
        let mut pos = fixed;
        let mut last: Option<u64> = None;
        for _ in 0..count {
            let head = bytes.get(pos..pos + 16).ok_or(bad("truncated spill"))?;
            let index = u64::from_le_bytes(head[..8].try_into().map_err(|_| bad("truncated"))?);
            let base = i32::from_le_bytes(head[8..12].try_into().map_err(|_| bad("truncated"))?);
            let len =
                u32::from_le_bytes(head[12..16].try_into().map_err(|_| bad("truncated"))?) as usize;
            pos += 16;
            if len == 0 || len > MAX_LIMBS {
                return Err(bad("spill size"));
            }
            let body = bytes
                .get(pos..pos + len * 8)
                .ok_or(bad("truncated spill"))?;
            pos += len * 8;
            if index >= values as u64 || last.is_some_and(|l| index <= l) {
                return Err(bad("spill index"));
            }
            last = Some(index);
            let j = index as usize;
            if film.e[j] != SPILLED {
                return Err(bad("spill of an inline value"));
            }
            let limbs: Vec<u64> = body
                .chunks_exact(8)
                .map(|c| u64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
                .collect();
            let b = Big { base, limbs };
            let mut canon = b.clone();
            canon.canonicalize();
            if canon != b || b.is_zero() || b.to_inline(cap).is_some() {
                return Err(bad("spilled value not canonical"));
            }
            if !b.in_range() {
                return Err(bad("spilled value out of range"));
            }
            let pixel = j / EXACT_VALUES;
            let key = ((pixel % CHUNK) * EXACT_VALUES + j % EXACT_VALUES) as u32;
            film.spill[pixel / CHUNK].insert(key, b);
        }
        Ok((film, pos))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn film(values: &[f64]) -> Film {
        let mut f = Film::new(values.len(), 1, Filter::Box);
        for (i, v) in values.iter().enumerate() {
            f.sum[i] = [*v, -*v, v * 3.0];
            f.sum_sq[i] = [v * v; 3];
            f.weight[i] = 1.0;
        }
        f.samples = values.len() as u64;
        f
    }

    #[test]
    fn exact_sums_do_not_depend_on_grouping() {
        // f64 addition of these is not associative: (a + b) + c != a + (b + c).
        let (a, b, c) = (film(&[0.1, 1e9]), film(&[0.2, -1e9]), film(&[0.3, 1e-7]));
        let mut fa = a.clone();
        fa.add(&b);
        fa.add(&c);
        let mut fb = b.clone();
        fb.add(&c);
        let mut fb2 = a.clone();
        fb2.add(&fb);
        assert_ne!(fa.sum, fb2.sum, "the f64 sums differ with the grouping");
        let mut left = ExactFilm::new(2, 1);
        left.add(&a).unwrap();
        left.add(&b).unwrap();
        left.add(&c).unwrap();
        let mut bc = ExactFilm::new(2, 1);
        bc.add(&b).unwrap();
        bc.add(&c).unwrap();
        let mut right = ExactFilm::new(2, 1);
        right.add(&a).unwrap();
        right.add_exact(&bc).unwrap();
        assert_eq!(left, right);
        assert_eq!(left.state_bytes(), right.state_bytes());
        let f = left.to_film(Filter::Box);
        // The exact sum of the doubles 0.1, 0.2 and 0.3 is 0.60000000000000000555..., within
        // half an ulp of the double 0.6 (0.59999999999999997780...), which f64 addition in
        // this order misses (0.6000000000000001).
        assert_eq!(f.sum[0][0], 0.6);
        assert_eq!(f.sum[1][0], 1e-7);
        assert_eq!(f.samples, 6);
    }

    /// Every one of the 15 sums per pixel comes back from the exact film in its own slot.
    #[test]
    fn every_sum_round_trips_through_the_exact_film() {
        let mut f = Film::new(2, 1, Filter::Box);
        let mut k = 0.0;
        let mut next = || {
            k += 1.0;
            k * 0.125
        };
        for i in 0..2 {
            f.sum[i] = [next(), next(), next()];
            f.sum_sq[i] = [next(), next(), next()];
            f.sum_w2[i] = [next(), next(), next()];
            f.sum_sq_w2[i] = [next(), next(), next()];
            f.weight[i] = next();
            f.weight_sq[i] = next();
            f.weight_cube[i] = next();
        }
        f.samples = 7;
        let mut e = ExactFilm::new(2, 1);
        e.add(&f).unwrap();
        let g = e.to_film(Filter::Box);
        assert_eq!(g.sum, f.sum);
        assert_eq!(g.sum_sq, f.sum_sq);
        assert_eq!(g.sum_w2, f.sum_w2);
        assert_eq!(g.sum_sq_w2, f.sum_sq_w2);
        assert_eq!(g.weight, f.weight);
        assert_eq!(g.weight_sq, f.weight_sq);
        assert_eq!(g.weight_cube, f.weight_cube);
        assert_eq!(g.samples, 7);
    }

    /// `add_parts` (an old checkpoint's values) ignores a pixel or value index out of range:
    /// a value index past the last must not land in the next pixel's first value.
    #[test]
    fn add_parts_ignores_indices_out_of_range() {
        let mut e = ExactFilm::new(2, 1);
        e.add_parts(0, EXACT_VALUES, 1, 0);
        e.add_parts(2, 0, 1, 0);
        e.add_parts(0, 0, 0, 5);
        for pixel in 0..2 {
            for k in 0..EXACT_VALUES {
                assert_eq!(e.value(pixel, k).to_f64(), 0.0, "pixel {pixel} value {k}");
            }
        }
        e.add_parts(1, EXACT_VALUES - 1, 3, -2);
        assert_eq!(e.value(1, EXACT_VALUES - 1).to_f64(), 0.75);
    }

    /// A non-finite sum is refused with its pixel, and the film is left as it was.
    #[test]
    fn non_finite_sums_are_refused_and_leave_the_film_unchanged() {
        let mut e = ExactFilm::new(2, 1);
        e.add(&film(&[1e9, 2.0])).unwrap();
        let before = e.clone();
        for bad in [f64::INFINITY, f64::NEG_INFINITY, f64::NAN] {
            let err = e.add(&film(&[3.0, bad])).unwrap_err();
            assert!(
                matches!(
                    err,
                    ExactError::NonFinite {
                        x: 1,
                        y: 0,
                        index: 0,
                        ..
                    }
                ),
                "{err}"
            );
            assert_eq!(e, before);
            let mut s = ExactSum::new();
            s.add_f64(1.0).unwrap();
            assert!(s.add_f64(bad).is_err());
            assert_eq!(s.to_f64(), 1.0);
        }
        // Today's limit (2^78 per sum) is gone: 6e11 squared accumulates.
        e.add(&film(&[6e11, 1.0])).unwrap();
        assert_eq!(e.to_film(Filter::Box).sum_sq[0][0], 1e18 + 6e11 * 6e11);
    }

    /// The read-out is correctly rounded at the edges of the range: subnormal sums, ties to
    /// even, overflow to infinity, values whose inline mantissa exceeds 53 bits.
    #[test]
    fn read_out_rounds_once_to_nearest_even() {
        let tiny = f64::from_bits(1); // 2^-1074
        let mut s = ExactSum::new();
        for _ in 0..3 {
            s.add_f64(tiny).unwrap();
        }
        assert_eq!(s.to_f64(), 3.0 * tiny);
        // 1 + 2^-53 is a tie between 1 and 1 + 2^-52: to even, 1.
        let s = ExactSum::from_parts((1 << 53) + 1, -53, INLINE_BITS);
        assert_eq!(s.to_f64(), 1.0);
        // 1 + 3·2^-54 is above the tie: 1 + 2^-52.
        let s = ExactSum::from_parts((1 << 54) + 3, -54, INLINE_BITS);
        assert_eq!(s.to_f64(), 1.0 + f64::EPSILON);
        // 1.5 and 0.5 times the smallest subnormal: ties, to even (2 and 0 of them).
        let s = ExactSum::from_parts(3, -1075, INLINE_BITS);
        assert_eq!(s.to_f64(), 2.0 * tiny);
        let s = ExactSum::from_parts(1, -1075, INLINE_BITS);
        assert_eq!(s.to_f64(), 0.0);
        let mut s = ExactSum::new();
        s.add_f64(f64::MAX).unwrap();
        s.add_f64(f64::MAX).unwrap();
        assert_eq!(s.to_f64(), f64::INFINITY);
        s.add_f64(-f64::MAX).unwrap();
        assert_eq!(s.to_f64(), f64::MAX);
    }
}
