//! The portable 16-lane backend: arrays, each lane the scalar operation itself (so it is
//! exact by construction; the compiler vectorises what it can). The fallback on processors
//! without AVX2 and on other targets.

use super::{gather_bound, gather_out_of_bounds, Backend, LaneF32, LaneMask, LaneU32, LaneU64};
use super::{Lanes, MAX_WIDTH};
use std::ops::{Add, BitAnd, BitOr, BitXor, Div, Mul, Neg, Not, Sub};

const W: usize = MAX_WIDTH;

/// Sixteen lanes in arrays.
#[derive(Clone, Copy, Debug, Default)]
pub struct Portable16;

#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct PF32([f32; W]);

#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct PU32([u32; W]);

#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct PU64([u64; W]);

/// Bit i is lane i.
#[derive(Clone, Copy, Debug)]
pub struct PMask(u16);

impl PMask {
    #[inline(always)]
    fn get(self, i: usize) -> bool {
        self.0 >> i & 1 != 0
    }
    #[inline(always)]
    fn from_fn(f: impl Fn(usize) -> bool) -> PMask {
        let mut m = 0u16;
        for i in 0..W {
            m |= (f(i) as u16) << i;
        }
        PMask(m)
    }
}

macro_rules! bitops {
    ($t:ident, $inner:ty) => {
        impl BitAnd for $t {
            type Output = $t;
            #[inline(always)]
            fn bitand(self, o: $t) -> $t {
                $t(std::array::from_fn(|i| self.0[i] & o.0[i]))
            }
        }
        impl BitOr for $t {
            type Output = $t;
            #[inline(always)]
            fn bitor(self, o: $t) -> $t {
                $t(std::array::from_fn(|i| self.0[i] | o.0[i]))
            }
        }
        impl BitXor for $t {
            type Output = $t;
            #[inline(always)]
            fn bitxor(self, o: $t) -> $t {
                $t(std::array::from_fn(|i| self.0[i] ^ o.0[i]))
            }
        }
    };
}
bitops!(PU32, u32);
bitops!(PU64, u64);

impl BitAnd for PMask {
    type Output = PMask;
    #[inline(always)]
    fn bitand(self, o: PMask) -> PMask {
        PMask(self.0 & o.0)
    }
}
impl BitOr for PMask {
    type Output = PMask;
    #[inline(always)]
    fn bitor(self, o: PMask) -> PMask {
        PMask(self.0 | o.0)
    }
}
impl BitXor for PMask {
    type Output = PMask;
    #[inline(always)]
    fn bitxor(self, o: PMask) -> PMask {
        PMask(self.0 ^ o.0)
    }
}
impl Not for PMask {
    type Output = PMask;
    #[inline(always)]
    fn not(self) -> PMask {
        PMask(!self.0)
    }
}

impl LaneMask for PMask {
    #[inline(always)]
    fn bits(self) -> u32 {
        self.0 as u32
    }
    #[inline(always)]
    fn any(self) -> bool {
        self.0 != 0
    }
    #[inline(always)]
    fn all(self) -> bool {
        self.0 == u16::MAX
    }
}

macro_rules! binop {
    ($trait:ident, $f:ident, $op:tt) => {
        impl $trait for PF32 {
            type Output = PF32;
            #[inline(always)]
            fn $f(self, o: PF32) -> PF32 {
                PF32(std::array::from_fn(|i| self.0[i] $op o.0[i]))
            }
        }
    };
}
binop!(Add, add, +);
binop!(Sub, sub, -);
binop!(Mul, mul, *);
binop!(Div, div, /);

impl Neg for PF32 {
    type Output = PF32;
    #[inline(always)]
    fn neg(self) -> PF32 {
        PF32(self.0.map(|x| -x))
    }
}

impl PF32 {
    #[inline(always)]
    fn map(self, f: impl Fn(f32) -> f32) -> PF32 {
        PF32(self.0.map(f))
    }
    #[inline(always)]
    fn zip(self, o: PF32, f: impl Fn(f32, f32) -> f32) -> PF32 {
        PF32(std::array::from_fn(|i| f(self.0[i], o.0[i])))
    }
    #[inline(always)]
    fn test(self, o: PF32, f: impl Fn(f32, f32) -> bool) -> PMask {
        PMask::from_fn(|i| f(self.0[i], o.0[i]))
    }
}

/// The lanes of `m`, in order, moved to the front; the rest `zero`.
#[inline(always)]
fn compress<T: Copy>(v: [T; W], m: PMask, zero: T) -> [T; W] {
    let mut out = [zero; W];
    let mut k = 0;
    for (i, &x) in v.iter().enumerate() {
        if m.get(i) {
            out[k] = x;
            k += 1;
        }
    }
    out
}

#[inline(always)]
fn expand<T: Copy>(v: [T; W], m: PMask, zero: T) -> [T; W] {
    let mut out = [zero; W];
    let mut k = 0;
    for (i, o) in out.iter_mut().enumerate() {
        if m.get(i) {
            *o = v[k];
            k += 1;
        }
    }
    out
}

impl LaneF32 for PF32 {
    type M = PMask;
    type U = PU32;

    #[inline(always)]
    fn lane(&self, i: usize) -> f32 {
        self.0[i]
    }
    #[inline(always)]
    fn set_lane(&mut self, i: usize, x: f32) {
        self.0[i] = x;
    }
    #[inline(always)]
    fn store(self, out: &mut [f32]) {
        out[..W].copy_from_slice(&self.0);
    }
    #[inline(always)]
    fn abs(self) -> PF32 {
        self.map(f32::abs)
    }
    #[inline(always)]
    fn sqrt(self) -> PF32 {
        self.map(f32::sqrt)
    }
    #[inline(always)]
    fn floor(self) -> PF32 {
        self.map(f32::floor)
    }
    #[inline(always)]
    fn ceil(self) -> PF32 {
        self.map(f32::ceil)
    }
    #[inline(always)]
    fn trunc(self) -> PF32 {
        self.map(f32::trunc)
    }
    #[inline(always)]
    fn round(self) -> PF32 {
        self.map(f32::round)
    }
    #[inline(always)]
    fn copysign(self, sign: PF32) -> PF32 {
        self.zip(sign, f32::copysign)
    }
    #[inline(always)]
    fn min(self, o: PF32) -> PF32 {
        self.zip(o, f32::min)
    }
    #[inline(always)]
    fn max(self, o: PF32) -> PF32 {
        self.zip(o, f32::max)
    }
    #[inline(always)]
    fn min_lt(self, o: PF32) -> PF32 {
        self.zip(o, <f32 as LaneF32>::min_lt)
    }
    #[inline(always)]
    fn max_gt(self, o: PF32) -> PF32 {
        self.zip(o, <f32 as LaneF32>::max_gt)
    }
    #[inline(always)]
    fn cmp_eq(self, o: PF32) -> PMask {
        self.test(o, |a, b| a == b)
    }
    #[inline(always)]
    fn cmp_ne(self, o: PF32) -> PMask {
        self.test(o, |a, b| a != b)
    }
    #[inline(always)]
    fn cmp_lt(self, o: PF32) -> PMask {
        self.test(o, |a, b| a < b)
    }
    #[inline(always)]
    fn cmp_le(self, o: PF32) -> PMask {
        self.test(o, |a, b| a <= b)
    }
    #[inline(always)]
    fn cmp_gt(self, o: PF32) -> PMask {
        self.test(o, |a, b| a > b)
    }
    #[inline(always)]
    fn cmp_ge(self, o: PF32) -> PMask {
        self.test(o, |a, b| a >= b)
    }
    #[inline(always)]
    fn is_nan(self) -> PMask {
        PMask::from_fn(|i| self.0[i].is_nan())
    }
    #[inline(always)]
    fn is_finite(self) -> PMask {
        PMask::from_fn(|i| self.0[i].is_finite())
    }
    #[inline(always)]
    fn select(m: PMask, a: PF32, b: PF32) -> PF32 {
        PF32(std::array::from_fn(
            |i| if m.get(i) { a.0[i] } else { b.0[i] },
        ))
    }
    #[inline(always)]
    fn to_bits(self) -> PU32 {
        PU32(self.0.map(f32::to_bits))
    }
    #[inline(always)]
    fn from_bits(u: PU32) -> PF32 {
        PF32(u.0.map(f32::from_bits))
    }
    #[inline(always)]
    fn to_i32(self) -> PU32 {
        PU32(self.0.map(|x| x as i32 as u32))
    }
    #[inline(always)]
    fn to_u32(self) -> PU32 {
        PU32(self.0.map(|x| x as u32))
    }
    #[inline(always)]
    fn from_i32(u: PU32) -> PF32 {
        PF32(u.0.map(|x| x as i32 as f32))
    }
    #[inline(always)]
    fn from_u32(u: PU32) -> PF32 {
        PF32(u.0.map(|x| x as f32))
    }
    #[inline(always)]
    fn compress(self, m: PMask) -> PF32 {
        PF32(compress(self.0, m, 0.0))
    }
    #[inline(always)]
    fn expand(self, m: PMask) -> PF32 {
        PF32(expand(self.0, m, 0.0))
    }
}

impl PU32 {
    #[inline(always)]
    fn zip(self, o: PU32, f: impl Fn(u32, u32) -> u32) -> PU32 {
        PU32(std::array::from_fn(|i| f(self.0[i], o.0[i])))
    }
}

impl LaneU32 for PU32 {
    type M = PMask;

    #[inline(always)]
    fn lane(&self, i: usize) -> u32 {
        self.0[i]
    }
    #[inline(always)]
    fn set_lane(&mut self, i: usize, x: u32) {
        self.0[i] = x;
    }
    #[inline(always)]
    fn store(self, out: &mut [u32]) {
        out[..W].copy_from_slice(&self.0);
    }
    #[inline(always)]
    fn wrapping_add(self, o: PU32) -> PU32 {
        self.zip(o, u32::wrapping_add)
    }
    #[inline(always)]
    fn wrapping_sub(self, o: PU32) -> PU32 {
        self.zip(o, u32::wrapping_sub)
    }
    #[inline(always)]
    fn wrapping_mul(self, o: PU32) -> PU32 {
        self.zip(o, u32::wrapping_mul)
    }
    #[inline(always)]
    fn shl(self, n: u32) -> PU32 {
        PU32(self.0.map(|x| x << n))
    }
    #[inline(always)]
    fn shr(self, n: u32) -> PU32 {
        PU32(self.0.map(|x| x >> n))
    }
    #[inline(always)]
    fn shlv(self, n: PU32) -> PU32 {
        self.zip(n, <u32 as LaneU32>::shlv)
    }
    #[inline(always)]
    fn shrv(self, n: PU32) -> PU32 {
        self.zip(n, <u32 as LaneU32>::shrv)
    }
    #[inline(always)]
    fn rotate_right(self, n: PU32) -> PU32 {
        self.zip(n, u32::rotate_right)
    }
    #[inline(always)]
    fn min(self, o: PU32) -> PU32 {
        self.zip(o, Ord::min)
    }
    #[inline(always)]
    fn max(self, o: PU32) -> PU32 {
        self.zip(o, Ord::max)
    }
    #[inline(always)]
    fn cmp_eq(self, o: PU32) -> PMask {
        PMask::from_fn(|i| self.0[i] == o.0[i])
    }
    #[inline(always)]
    fn cmp_lt(self, o: PU32) -> PMask {
        PMask::from_fn(|i| self.0[i] < o.0[i])
    }
    #[inline(always)]
    fn cmp_gt(self, o: PU32) -> PMask {
        PMask::from_fn(|i| self.0[i] > o.0[i])
    }
    #[inline(always)]
    fn select(m: PMask, a: PU32, b: PU32) -> PU32 {
        PU32(std::array::from_fn(
            |i| if m.get(i) { a.0[i] } else { b.0[i] },
        ))
    }
    #[inline(always)]
    fn compress(self, m: PMask) -> PU32 {
        PU32(compress(self.0, m, 0))
    }
    #[inline(always)]
    fn expand(self, m: PMask) -> PU32 {
        PU32(expand(self.0, m, 0))
    }
}

impl LaneU64 for PU64 {
    type M = PMask;
    type U32 = PU32;

    #[inline(always)]
    fn lane(&self, i: usize) -> u64 {
        self.0[i]
    }
    #[inline(always)]
    fn set_lane(&mut self, i: usize, x: u64) {
        self.0[i] = x;
    }
    #[inline(always)]
    fn store(self, out: &mut [u64]) {
        out[..W].copy_from_slice(&self.0);
    }
    #[inline(always)]
    fn wrapping_add(self, o: PU64) -> PU64 {
        PU64(std::array::from_fn(|i| self.0[i].wrapping_add(o.0[i])))
    }
    #[inline(always)]
    fn wrapping_sub(self, o: PU64) -> PU64 {
        PU64(std::array::from_fn(|i| self.0[i].wrapping_sub(o.0[i])))
    }
    #[inline(always)]
    fn wrapping_mul(self, o: PU64) -> PU64 {
        PU64(std::array::from_fn(|i| self.0[i].wrapping_mul(o.0[i])))
    }
    #[inline(always)]
    fn shl(self, n: u32) -> PU64 {
        PU64(self.0.map(|x| x << n))
    }
    #[inline(always)]
    fn shr(self, n: u32) -> PU64 {
        PU64(self.0.map(|x| x >> n))
    }
    #[inline(always)]
    fn cmp_eq(self, o: PU64) -> PMask {
        PMask::from_fn(|i| self.0[i] == o.0[i])
    }
    #[inline(always)]
    fn select(m: PMask, a: PU64, b: PU64) -> PU64 {
        PU64(std::array::from_fn(
            |i| if m.get(i) { a.0[i] } else { b.0[i] },
        ))
    }
    #[inline(always)]
    fn from_u32(u: PU32) -> PU64 {
        PU64(u.0.map(|x| x as u64))
    }
    #[inline(always)]
    fn low32(self) -> PU32 {
        PU32(self.0.map(|x| x as u32))
    }
    #[inline(always)]
    fn high32(self) -> PU32 {
        PU32(self.0.map(|x| (x >> 32) as u32))
    }
}

impl Lanes for Portable16 {
    const WIDTH: usize = W;
    type Wavelengths = [glam::Vec4; W];
    const BACKEND: Backend = Backend::Portable;
    type M = PMask;
    type F = PF32;
    type U32 = PU32;
    type U64 = PU64;

    #[inline(always)]
    fn splat(self, x: f32) -> PF32 {
        PF32([x; W])
    }
    #[inline(always)]
    fn splat_u32(self, x: u32) -> PU32 {
        PU32([x; W])
    }
    #[inline(always)]
    fn splat_u64(self, x: u64) -> PU64 {
        PU64([x; W])
    }
    #[inline(always)]
    fn load(self, a: &[f32]) -> PF32 {
        PF32(a[..W].try_into().expect("16 lanes"))
    }
    #[inline(always)]
    fn load_u32(self, a: &[u32]) -> PU32 {
        PU32(a[..W].try_into().expect("16 lanes"))
    }
    #[inline(always)]
    fn load_u64(self, a: &[u64]) -> PU64 {
        PU64(a[..W].try_into().expect("16 lanes"))
    }
    #[inline(always)]
    fn mask(self, bits: u32) -> PMask {
        PMask(bits as u16)
    }
    #[inline(always)]
    fn index(self) -> PU32 {
        PU32(std::array::from_fn(|i| i as u32))
    }
    #[inline(always)]
    fn gather(self, table: &[f32], idx: PU32, m: PMask) -> PF32 {
        let bound = gather_bound(table.len());
        PF32(std::array::from_fn(|i| {
            if !m.get(i) {
                0.0
            } else if idx.0[i] < bound {
                table[idx.0[i] as usize]
            } else {
                gather_out_of_bounds(table.len())
            }
        }))
    }
    #[inline(always)]
    fn gather_u32(self, table: &[u32], idx: PU32, m: PMask) -> PU32 {
        let bound = gather_bound(table.len());
        PU32(std::array::from_fn(|i| {
            if !m.get(i) {
                0
            } else if idx.0[i] < bound {
                table[idx.0[i] as usize]
            } else {
                gather_out_of_bounds(table.len())
            }
        }))
    }
}
