//! The width-1 backend: the lane traits on `f32`, `u32`, `u64` and `bool` themselves, so that
//! a kernel written once over [`Lanes`] is also the scalar engine's code.

use super::{gather_out_of_bounds, Backend, LaneF32, LaneMask, LaneU32, LaneU64, Lanes};

/// One lane: plain scalars.
#[derive(Clone, Copy, Debug, Default)]
pub struct Scalar;

#[inline(always)]
fn check_lane(i: usize) {
    assert!(i == 0, "lane {i} of a width-1 value");
}

impl LaneMask for bool {
    #[inline(always)]
    fn bits(self) -> u32 {
        self as u32
    }
    #[inline(always)]
    fn any(self) -> bool {
        self
    }
    #[inline(always)]
    fn all(self) -> bool {
        self
    }
}

impl LaneF32 for f32 {
    type M = bool;
    type U = u32;

    #[inline(always)]
    fn lane(&self, i: usize) -> f32 {
        check_lane(i);
        *self
    }
    #[inline(always)]
    fn set_lane(&mut self, i: usize, x: f32) {
        check_lane(i);
        *self = x;
    }
    #[inline(always)]
    fn store(self, out: &mut [f32]) {
        out[0] = self;
    }
    #[inline(always)]
    fn abs(self) -> f32 {
        f32::abs(self)
    }
    #[inline(always)]
    fn sqrt(self) -> f32 {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn floor(self) -> f32 {
        f32::floor(self)
    }
    #[inline(always)]
    fn ceil(self) -> f32 {
        f32::ceil(self)
    }
    #[inline(always)]
    fn trunc(self) -> f32 {
        f32::trunc(self)
    }
    #[inline(always)]
    fn round(self) -> f32 {
        f32::round(self)
    }
    #[inline(always)]
    fn copysign(self, sign: f32) -> f32 {
        f32::copysign(self, sign)
    }
    #[inline(always)]
    fn min(self, o: f32) -> f32 {
        f32::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: f32) -> f32 {
        f32::max(self, o)
    }
    #[inline(always)]
    fn min_lt(self, o: f32) -> f32 {
        if self < o {
            self
        } else {
            o
        }
    }
    #[inline(always)]
    fn max_gt(self, o: f32) -> f32 {
        if self > o {
            self
        } else {
            o
        }
    }
    #[inline(always)]
    fn cmp_eq(self, o: f32) -> bool {
        self == o
    }
    #[inline(always)]
    fn cmp_ne(self, o: f32) -> bool {
        self != o
    }
    #[inline(always)]
    fn cmp_lt(self, o: f32) -> bool {
        self < o
    }
    #[inline(always)]
    fn cmp_le(self, o: f32) -> bool {
        self <= o
    }
    #[inline(always)]
    fn cmp_gt(self, o: f32) -> bool {
        self > o
    }
    #[inline(always)]
    fn cmp_ge(self, o: f32) -> bool {
        self >= o
    }
    #[inline(always)]
    fn is_nan(self) -> bool {
        f32::is_nan(self)
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
    #[inline(always)]
    fn select(m: bool, a: f32, b: f32) -> f32 {
        if m {
            a
        } else {
            b
        }
    }
    #[inline(always)]
    fn to_bits(self) -> u32 {
        f32::to_bits(self)
    }
    #[inline(always)]
    fn from_bits(u: u32) -> f32 {
        f32::from_bits(u)
    }
    #[inline(always)]
    fn to_i32(self) -> u32 {
        self as i32 as u32
    }
    #[inline(always)]
    fn to_u32(self) -> u32 {
        self as u32
    }
    #[inline(always)]
    fn from_i32(u: u32) -> f32 {
        u as i32 as f32
    }
    #[inline(always)]
    fn from_u32(u: u32) -> f32 {
        u as f32
    }
    #[inline(always)]
    fn compress(self, m: bool) -> f32 {
        if m {
            self
        } else {
            0.0
        }
    }
    #[inline(always)]
    fn expand(self, m: bool) -> f32 {
        if m {
            self
        } else {
            0.0
        }
    }
}

impl LaneU32 for u32 {
    type M = bool;

    #[inline(always)]
    fn lane(&self, i: usize) -> u32 {
        check_lane(i);
        *self
    }
    #[inline(always)]
    fn set_lane(&mut self, i: usize, x: u32) {
        check_lane(i);
        *self = x;
    }
    #[inline(always)]
    fn store(self, out: &mut [u32]) {
        out[0] = self;
    }
    #[inline(always)]
    fn wrapping_add(self, o: u32) -> u32 {
        u32::wrapping_add(self, o)
    }
    #[inline(always)]
    fn wrapping_sub(self, o: u32) -> u32 {
        u32::wrapping_sub(self, o)
    }
    #[inline(always)]
    fn wrapping_mul(self, o: u32) -> u32 {
        u32::wrapping_mul(self, o)
    }
    #[inline(always)]
    fn shl(self, n: u32) -> u32 {
        self << n
    }
    #[inline(always)]
    fn shr(self, n: u32) -> u32 {
        self >> n
    }
    #[inline(always)]
    fn shlv(self, n: u32) -> u32 {
        self.checked_shl(n).unwrap_or(0)
    }
    #[inline(always)]
    fn shrv(self, n: u32) -> u32 {
        self.checked_shr(n).unwrap_or(0)
    }
    #[inline(always)]
    fn rotate_right(self, n: u32) -> u32 {
        u32::rotate_right(self, n)
    }
    #[inline(always)]
    fn min(self, o: u32) -> u32 {
        Ord::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: u32) -> u32 {
        Ord::max(self, o)
    }
    #[inline(always)]
    fn cmp_eq(self, o: u32) -> bool {
        self == o
    }
    #[inline(always)]
    fn cmp_lt(self, o: u32) -> bool {
        self < o
    }
    #[inline(always)]
    fn cmp_gt(self, o: u32) -> bool {
        self > o
    }
    #[inline(always)]
    fn select(m: bool, a: u32, b: u32) -> u32 {
        if m {
            a
        } else {
            b
        }
    }
    #[inline(always)]
    fn compress(self, m: bool) -> u32 {
        if m {
            self
        } else {
            0
        }
    }
    #[inline(always)]
    fn expand(self, m: bool) -> u32 {
        if m {
            self
        } else {
            0
        }
    }
}

impl LaneU64 for u64 {
    type M = bool;
    type U32 = u32;

    #[inline(always)]
    fn lane(&self, i: usize) -> u64 {
        check_lane(i);
        *self
    }
    #[inline(always)]
    fn set_lane(&mut self, i: usize, x: u64) {
        check_lane(i);
        *self = x;
    }
    #[inline(always)]
    fn store(self, out: &mut [u64]) {
        out[0] = self;
    }
    #[inline(always)]
    fn wrapping_add(self, o: u64) -> u64 {
        u64::wrapping_add(self, o)
    }
    #[inline(always)]
    fn wrapping_sub(self, o: u64) -> u64 {
        u64::wrapping_sub(self, o)
    }
    #[inline(always)]
    fn wrapping_mul(self, o: u64) -> u64 {
        u64::wrapping_mul(self, o)
    }
    #[inline(always)]
    fn shl(self, n: u32) -> u64 {
        self << n
    }
    #[inline(always)]
    fn shr(self, n: u32) -> u64 {
        self >> n
    }
    #[inline(always)]
    fn cmp_eq(self, o: u64) -> bool {
        self == o
    }
    #[inline(always)]
    fn select(m: bool, a: u64, b: u64) -> u64 {
        if m {
            a
        } else {
            b
        }
    }
    #[inline(always)]
    fn from_u32(u: u32) -> u64 {
        u as u64
    }
    #[inline(always)]
    fn low32(self) -> u32 {
        self as u32
    }
    #[inline(always)]
    fn high32(self) -> u32 {
        (self >> 32) as u32
    }
}

impl Lanes for Scalar {
    const WIDTH: usize = 1;
    type Wavelengths = [glam::Vec4; 1];
    const BACKEND: Backend = Backend::Scalar;
    type M = bool;
    type F = f32;
    type U32 = u32;
    type U64 = u64;

    #[inline(always)]
    fn splat(self, x: f32) -> f32 {
        x
    }
    #[inline(always)]
    fn splat_u32(self, x: u32) -> u32 {
        x
    }
    #[inline(always)]
    fn splat_u64(self, x: u64) -> u64 {
        x
    }
    #[inline(always)]
    fn load(self, a: &[f32]) -> f32 {
        a[0]
    }
    #[inline(always)]
    fn load_u32(self, a: &[u32]) -> u32 {
        a[0]
    }
    #[inline(always)]
    fn load_u64(self, a: &[u64]) -> u64 {
        a[0]
    }
    #[inline(always)]
    fn mask(self, bits: u32) -> bool {
        bits & 1 != 0
    }
    #[inline(always)]
    fn index(self) -> u32 {
        0
    }
    #[inline(always)]
    fn gather(self, table: &[f32], idx: u32, m: bool) -> f32 {
        if !m {
            return 0.0;
        }
        match table.get(idx as usize) {
            Some(&x) if idx < super::gather_bound(table.len()) => x,
            _ => gather_out_of_bounds(table.len()),
        }
    }
    #[inline(always)]
    fn gather_u32(self, table: &[u32], idx: u32, m: bool) -> u32 {
        if !m {
            return 0;
        }
        match table.get(idx as usize) {
            Some(&x) if idx < super::gather_bound(table.len()) => x,
            _ => gather_out_of_bounds(table.len()),
        }
    }
}
