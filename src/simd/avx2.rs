//! The AVX2 backend: sixteen lanes as two 256-bit halves (f32, u32 and masks: two registers;
//! u64: four), for x86-64 processors without AVX-512. Masks are vectors of all-ones lanes.
//! What AVX2 lacks is built from exact pieces: `as u32` by an offset of 2³¹, `u32 as f32`
//! from two exact 16-bit halves added once, 64-bit multiplies from three 32-bit ones,
//! compress and expand from a permutation table per 8-lane half.
//!
//! As in the AVX-512 backend, the lane values can only be made through an [`Avx2`] token,
//! which exists only after detection.

use super::{gather_bound, gather_out_of_bounds, Backend, LaneF32, LaneMask, LaneU32, LaneU64};
use super::{Lanes, MAX_WIDTH};
use std::arch::x86_64::*;
use std::ops::{Add, BitAnd, BitOr, BitXor, Div, Mul, Neg, Not, Sub};

const W: usize = MAX_WIDTH;

/// Proof that the processor runs AVX2.
#[derive(Clone, Copy, Debug)]
pub struct Avx2 {
    _detected: (),
}

impl Avx2 {
    /// The token, if this processor has AVX2.
    pub fn new() -> Option<Avx2> {
        is_x86_feature_detected!("avx2").then_some(Avx2 { _detected: () })
    }
}

/// Lanes 0–7 in the first register, 8–15 in the second.
#[derive(Clone, Copy)]
#[repr(C)]
pub struct F32x8x2([__m256; 2]);

#[derive(Clone, Copy)]
#[repr(C)]
pub struct U32x8x2([__m256i; 2]);

/// Lanes 0–3, 4–7, 8–11, 12–15.
#[derive(Clone, Copy)]
#[repr(C)]
pub struct U64x4x4([__m256i; 4]);

/// All-ones lanes where set, as the two halves of the f32 lanes.
#[derive(Clone, Copy)]
#[repr(C)]
pub struct M8x2([__m256; 2]);

macro_rules! debug_lanes {
    ($t:ident, $e:ty) => {
        impl std::fmt::Debug for $t {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                let a: [$e; W] = std::array::from_fn(|i| self.lane(i));
                f.debug_tuple(stringify!($t)).field(&a).finish()
            }
        }
    };
}
debug_lanes!(F32x8x2, f32);
debug_lanes!(U32x8x2, u32);
debug_lanes!(U64x4x4, u64);

impl std::fmt::Debug for M8x2 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "M8x2({:#06x})", self.bits())
    }
}

macro_rules! lanes_ref {
    ($v:expr, $e:ty) => {
        // SAFETY: the value is its lanes in order, as the array.
        unsafe { &*($v as *const _ as *const [$e; W]) }
    };
}
macro_rules! lanes_mut {
    ($v:expr, $e:ty) => {
        // SAFETY: as `lanes_ref`; every bit pattern is a valid lane.
        unsafe { &mut *($v as *mut _ as *mut [$e; W]) }
    };
}

// SAFETY (every `unsafe` block below): the intrinsics need AVX2 (and what it implies), which
// the existence of a lane value proves (only an `Avx2` token makes them); pointers are to
// arrays of at least the lanes read or written.

/// For compress: entry m lists the set lanes of the 8-bit mask m, in order (then zeros).
const COMPRESS: [[u32; 8]; 256] = {
    let mut t = [[0u32; 8]; 256];
    let mut m = 0;
    while m < 256 {
        let (mut j, mut k) = (0, 0);
        while j < 8 {
            if m >> j & 1 != 0 {
                t[m][k] = j as u32;
                k += 1;
            }
            j += 1;
        }
        m += 1;
    }
    t
};

/// For expand: entry m gives each set lane of m its rank among the set lanes (unset: 0).
const EXPAND: [[u32; 8]; 256] = {
    let mut t = [[0u32; 8]; 256];
    let mut m = 0;
    while m < 256 {
        let (mut j, mut k) = (0, 0);
        while j < 8 {
            if m >> j & 1 != 0 {
                t[m][j] = k;
                k += 1;
            }
            j += 1;
        }
        m += 1;
    }
    t
};

#[inline(always)]
fn table(row: &[u32; 8]) -> __m256i {
    unsafe { _mm256_loadu_si256(row.as_ptr() as *const __m256i) }
}

/// All-ones in the lanes of the 8-bit mask `bits`.
#[inline(always)]
fn half_mask(bits: u32) -> __m256 {
    unsafe {
        let lane_bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let b = _mm256_and_si256(_mm256_set1_epi32(bits as i32), lane_bits);
        _mm256_castsi256_ps(_mm256_cmpeq_epi32(b, lane_bits))
    }
}

impl M8x2 {
    #[inline(always)]
    fn from_bits(bits: u32) -> M8x2 {
        M8x2([half_mask(bits & 0xff), half_mask(bits >> 8 & 0xff)])
    }
    #[inline(always)]
    fn int(self, h: usize) -> __m256i {
        unsafe { _mm256_castps_si256(self.0[h]) }
    }
}

impl BitAnd for M8x2 {
    type Output = M8x2;
    #[inline(always)]
    fn bitand(self, o: M8x2) -> M8x2 {
        M8x2(unsafe {
            [
                _mm256_and_ps(self.0[0], o.0[0]),
                _mm256_and_ps(self.0[1], o.0[1]),
            ]
        })
    }
}
impl BitOr for M8x2 {
    type Output = M8x2;
    #[inline(always)]
    fn bitor(self, o: M8x2) -> M8x2 {
        M8x2(unsafe {
            [
                _mm256_or_ps(self.0[0], o.0[0]),
                _mm256_or_ps(self.0[1], o.0[1]),
            ]
        })
    }
}
impl BitXor for M8x2 {
    type Output = M8x2;
    #[inline(always)]
    fn bitxor(self, o: M8x2) -> M8x2 {
        M8x2(unsafe {
            [
                _mm256_xor_ps(self.0[0], o.0[0]),
                _mm256_xor_ps(self.0[1], o.0[1]),
            ]
        })
    }
}
impl Not for M8x2 {
    type Output = M8x2;
    #[inline(always)]
    fn not(self) -> M8x2 {
        let ones = unsafe { _mm256_castsi256_ps(_mm256_set1_epi32(-1)) };
        M8x2(unsafe {
            [
                _mm256_xor_ps(self.0[0], ones),
                _mm256_xor_ps(self.0[1], ones),
            ]
        })
    }
}
impl LaneMask for M8x2 {
    #[inline(always)]
    fn bits(self) -> u32 {
        unsafe {
            _mm256_movemask_ps(self.0[0]) as u32 | (_mm256_movemask_ps(self.0[1]) as u32) << 8
        }
    }
    #[inline(always)]
    fn any(self) -> bool {
        self.bits() != 0
    }
    #[inline(always)]
    fn all(self) -> bool {
        self.bits() == 0xffff
    }
}

macro_rules! f_binop {
    ($trait:ident, $f:ident, $intr:ident) => {
        impl $trait for F32x8x2 {
            type Output = F32x8x2;
            #[inline(always)]
            fn $f(self, o: F32x8x2) -> F32x8x2 {
                F32x8x2(unsafe { [$intr(self.0[0], o.0[0]), $intr(self.0[1], o.0[1])] })
            }
        }
    };
}
f_binop!(Add, add, _mm256_add_ps);
f_binop!(Sub, sub, _mm256_sub_ps);
f_binop!(Mul, mul, _mm256_mul_ps);
f_binop!(Div, div, _mm256_div_ps);

impl Neg for F32x8x2 {
    type Output = F32x8x2;
    #[inline(always)]
    fn neg(self) -> F32x8x2 {
        // flips the sign bit, as scalar negation does
        let s = unsafe { _mm256_set1_ps(-0.0) };
        self.map(|a| unsafe { _mm256_xor_ps(a, s) })
    }
}

/// `[e(0), e(1), ..]` written out (N = 2 or 4), so that every element is computed in place
/// under the caller's target features: `std::array::from_fn` was left as a call of its own,
/// with the intrinsics of its closure as calls too (callgrind: +13% instructions a path when
/// the PCG32 draws ran in these lanes).
macro_rules! each {
    (2, |$i:ident| $e:expr) => {
        [{ let $i = 0usize; $e }, { let $i = 1usize; $e }]
    };
    (4, |$i:ident| $e:expr) => {
        [
            { let $i = 0usize; $e },
            { let $i = 1usize; $e },
            { let $i = 2usize; $e },
            { let $i = 3usize; $e },
        ]
    };
}

macro_rules! u_bitop {
    ($t:ident, $n:tt, $trait:ident, $f:ident, $intr:ident) => {
        impl $trait for $t {
            type Output = $t;
            #[inline(always)]
            fn $f(self, o: $t) -> $t {
                $t(each!($n, |h| unsafe { $intr(self.0[h], o.0[h]) }))
            }
        }
    };
}
u_bitop!(U32x8x2, 2, BitAnd, bitand, _mm256_and_si256);
u_bitop!(U32x8x2, 2, BitOr, bitor, _mm256_or_si256);
u_bitop!(U32x8x2, 2, BitXor, bitxor, _mm256_xor_si256);
u_bitop!(U64x4x4, 4, BitAnd, bitand, _mm256_and_si256);
u_bitop!(U64x4x4, 4, BitOr, bitor, _mm256_or_si256);
u_bitop!(U64x4x4, 4, BitXor, bitxor, _mm256_xor_si256);

impl F32x8x2 {
    #[inline(always)]
    fn map(self, f: impl Fn(__m256) -> __m256) -> F32x8x2 {
        F32x8x2([f(self.0[0]), f(self.0[1])])
    }
    #[inline(always)]
    fn zip(self, o: F32x8x2, f: impl Fn(__m256, __m256) -> __m256) -> F32x8x2 {
        F32x8x2([f(self.0[0], o.0[0]), f(self.0[1], o.0[1])])
    }
    #[inline(always)]
    fn cmp<const P: i32>(self, o: F32x8x2) -> M8x2 {
        M8x2(unsafe {
            [
                _mm256_cmp_ps::<P>(self.0[0], o.0[0]),
                _mm256_cmp_ps::<P>(self.0[1], o.0[1]),
            ]
        })
    }
    #[inline(always)]
    fn splat(x: f32) -> F32x8x2 {
        let v = unsafe { _mm256_set1_ps(x) };
        F32x8x2([v, v])
    }
}

impl U32x8x2 {
    #[inline(always)]
    fn map(self, f: impl Fn(__m256i) -> __m256i) -> U32x8x2 {
        U32x8x2([f(self.0[0]), f(self.0[1])])
    }
    #[inline(always)]
    fn zip(self, o: U32x8x2, f: impl Fn(__m256i, __m256i) -> __m256i) -> U32x8x2 {
        U32x8x2([f(self.0[0], o.0[0]), f(self.0[1], o.0[1])])
    }
    #[inline(always)]
    fn splat(x: u32) -> U32x8x2 {
        let v = unsafe { _mm256_set1_epi32(x as i32) };
        U32x8x2([v, v])
    }
    #[inline(always)]
    fn mask(self) -> M8x2 {
        M8x2(unsafe {
            [
                _mm256_castsi256_ps(self.0[0]),
                _mm256_castsi256_ps(self.0[1]),
            ]
        })
    }
}

/// The lanes of the 8-lane half `v` (as f32 bits) chosen by `m`'s 8 bits, in order, first.
#[inline(always)]
fn compress_half(v: __m256i, m: u32) -> __m256i {
    unsafe { _mm256_permutevar8x32_epi32(v, table(&COMPRESS[m as usize])) }
}

/// compress on the two halves of 32-bit lanes.
#[inline(always)]
fn compress32(v: [__m256i; 2], m: u32) -> [__m256i; 2] {
    let (m0, m1) = (m & 0xff, m >> 8 & 0xff);
    let (lo, hi) = (compress_half(v[0], m0), compress_half(v[1], m1));
    let c = m0.count_ones() as usize;
    let total = c + m1.count_ones() as usize;
    let mut buf = [0u32; W];
    unsafe {
        _mm256_storeu_si256(buf.as_mut_ptr() as *mut __m256i, lo);
        _mm256_storeu_si256(buf[c..c + 8].as_mut_ptr() as *mut __m256i, hi);
        let keep = M8x2::from_bits((1u32 << total) - 1);
        [
            _mm256_and_si256(
                _mm256_loadu_si256(buf.as_ptr() as *const __m256i),
                keep.int(0),
            ),
            _mm256_and_si256(
                _mm256_loadu_si256(buf[8..].as_ptr() as *const __m256i),
                keep.int(1),
            ),
        ]
    }
}

/// expand on the two halves of 32-bit lanes.
#[inline(always)]
fn expand32(v: [__m256i; 2], m: u32) -> [__m256i; 2] {
    let (m0, m1) = (m & 0xff, m >> 8 & 0xff);
    let c = m0.count_ones() as usize;
    let mut buf = [0u32; W + 8];
    unsafe {
        _mm256_storeu_si256(buf.as_mut_ptr() as *mut __m256i, v[0]);
        _mm256_storeu_si256(buf[8..].as_mut_ptr() as *mut __m256i, v[1]);
        let hi_src = _mm256_loadu_si256(buf[c..c + 8].as_ptr() as *const __m256i);
        let keep = M8x2::from_bits(m);
        [
            _mm256_and_si256(
                _mm256_permutevar8x32_epi32(v[0], table(&EXPAND[m0 as usize])),
                keep.int(0),
            ),
            _mm256_and_si256(
                _mm256_permutevar8x32_epi32(hi_src, table(&EXPAND[m1 as usize])),
                keep.int(1),
            ),
        ]
    }
}

impl LaneF32 for F32x8x2 {
    type M = M8x2;
    type U = U32x8x2;

    #[inline(always)]
    fn lane(&self, i: usize) -> f32 {
        lanes_ref!(self, f32)[i]
    }
    #[inline(always)]
    fn set_lane(&mut self, i: usize, x: f32) {
        lanes_mut!(self, f32)[i] = x;
    }
    #[inline(always)]
    fn store(self, out: &mut [f32]) {
        let out = &mut out[..W];
        unsafe {
            _mm256_storeu_ps(out.as_mut_ptr(), self.0[0]);
            _mm256_storeu_ps(out[8..].as_mut_ptr(), self.0[1]);
        }
    }
    #[inline(always)]
    fn abs(self) -> F32x8x2 {
        let m = unsafe { _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX)) };
        self.map(|a| unsafe { _mm256_and_ps(a, m) })
    }
    #[inline(always)]
    fn sqrt(self) -> F32x8x2 {
        self.map(|a| unsafe { _mm256_sqrt_ps(a) })
    }
    #[inline(always)]
    fn floor(self) -> F32x8x2 {
        self.map(|a| unsafe { _mm256_round_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(a) })
    }
    #[inline(always)]
    fn ceil(self) -> F32x8x2 {
        self.map(|a| unsafe { _mm256_round_ps::<{ _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC }>(a) })
    }
    #[inline(always)]
    fn trunc(self) -> F32x8x2 {
        self.map(|a| unsafe { _mm256_round_ps::<{ _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC }>(a) })
    }
    #[inline(always)]
    fn round(self) -> F32x8x2 {
        // t = trunc(x); x − t is exact; t ± 1 where |x − t| ≥ ½ (exact: |t| < 2²³ then).
        let t = self.trunc();
        let up = (self - t).abs().cmp_ge(F32x8x2::splat(0.5));
        let one = F32x8x2::select(up, F32x8x2::splat(1.0), F32x8x2::splat(0.0));
        t + one.copysign(self)
    }
    #[inline(always)]
    fn copysign(self, sign: F32x8x2) -> F32x8x2 {
        let m = unsafe { _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX)) };
        self.zip(sign, |a, s| unsafe {
            _mm256_or_ps(_mm256_and_ps(a, m), _mm256_andnot_ps(m, s))
        })
    }
    #[inline(always)]
    fn min(self, o: F32x8x2) -> F32x8x2 {
        // rustc's f32::min on x86-64: isnan(a) ? b : minss(b, a)
        let m = o.zip(self, |b, a| unsafe { _mm256_min_ps(b, a) });
        F32x8x2::select(self.is_nan(), o, m)
    }
    #[inline(always)]
    fn max(self, o: F32x8x2) -> F32x8x2 {
        let m = o.zip(self, |b, a| unsafe { _mm256_max_ps(b, a) });
        F32x8x2::select(self.is_nan(), o, m)
    }
    #[inline(always)]
    fn min_lt(self, o: F32x8x2) -> F32x8x2 {
        self.zip(o, |a, b| unsafe { _mm256_min_ps(a, b) })
    }
    #[inline(always)]
    fn max_gt(self, o: F32x8x2) -> F32x8x2 {
        self.zip(o, |a, b| unsafe { _mm256_max_ps(a, b) })
    }
    #[inline(always)]
    fn cmp_eq(self, o: F32x8x2) -> M8x2 {
        self.cmp::<_CMP_EQ_OQ>(o)
    }
    #[inline(always)]
    fn cmp_ne(self, o: F32x8x2) -> M8x2 {
        self.cmp::<_CMP_NEQ_UQ>(o)
    }
    #[inline(always)]
    fn cmp_lt(self, o: F32x8x2) -> M8x2 {
        self.cmp::<_CMP_LT_OQ>(o)
    }
    #[inline(always)]
    fn cmp_le(self, o: F32x8x2) -> M8x2 {
        self.cmp::<_CMP_LE_OQ>(o)
    }
    #[inline(always)]
    fn cmp_gt(self, o: F32x8x2) -> M8x2 {
        self.cmp::<_CMP_GT_OQ>(o)
    }
    #[inline(always)]
    fn cmp_ge(self, o: F32x8x2) -> M8x2 {
        self.cmp::<_CMP_GE_OQ>(o)
    }
    #[inline(always)]
    fn is_nan(self) -> M8x2 {
        self.cmp::<_CMP_UNORD_Q>(self)
    }
    #[inline(always)]
    fn is_finite(self) -> M8x2 {
        self.abs().cmp_lt(F32x8x2::splat(f32::INFINITY))
    }
    #[inline(always)]
    fn select(m: M8x2, a: F32x8x2, b: F32x8x2) -> F32x8x2 {
        F32x8x2(unsafe {
            [
                _mm256_blendv_ps(b.0[0], a.0[0], m.0[0]),
                _mm256_blendv_ps(b.0[1], a.0[1], m.0[1]),
            ]
        })
    }
    #[inline(always)]
    fn to_bits(self) -> U32x8x2 {
        U32x8x2(unsafe {
            [
                _mm256_castps_si256(self.0[0]),
                _mm256_castps_si256(self.0[1]),
            ]
        })
    }
    #[inline(always)]
    fn from_bits(u: U32x8x2) -> F32x8x2 {
        F32x8x2(unsafe { [_mm256_castsi256_ps(u.0[0]), _mm256_castsi256_ps(u.0[1])] })
    }
    #[inline(always)]
    fn to_i32(self) -> U32x8x2 {
        // vcvttps2dq gives 0x80000000 for NaN and out of range: positive overflow saturates
        // to i32::MAX and NaN goes to 0, as `as i32` does.
        let c = U32x8x2(self.0.map(|a| unsafe { _mm256_cvttps_epi32(a) }));
        let big = self.cmp_ge(F32x8x2::splat(2147483648.0));
        let c = U32x8x2::select(big, U32x8x2::splat(i32::MAX as u32), c);
        U32x8x2::select(self.is_nan(), U32x8x2::splat(0), c)
    }
    #[inline(always)]
    fn to_u32(self) -> U32x8x2 {
        // [2³¹, 2³²): convert x − 2³¹ (exact there) and set the top bit; from 2³² on
        // u32::MAX; NaN and x ≤ −1 give 0 (on (−1, 0) truncation gives 0 already).
        let two31 = F32x8x2::splat(2147483648.0);
        let big = self.cmp_ge(two31);
        let v = F32x8x2::select(big, self - two31, self);
        let c = U32x8x2(v.0.map(|a| unsafe { _mm256_cvttps_epi32(a) }));
        let top = U32x8x2::select(big, U32x8x2::splat(1 << 31), U32x8x2::splat(0));
        let c = c ^ top;
        let c = U32x8x2::select(
            self.cmp_ge(F32x8x2::splat(4294967296.0)),
            U32x8x2::splat(u32::MAX),
            c,
        );
        U32x8x2::select(self.cmp_gt(F32x8x2::splat(-1.0)), c, U32x8x2::splat(0))
    }
    #[inline(always)]
    fn from_i32(u: U32x8x2) -> F32x8x2 {
        F32x8x2(u.0.map(|a| unsafe { _mm256_cvtepi32_ps(a) }))
    }
    #[inline(always)]
    fn from_u32(u: U32x8x2) -> F32x8x2 {
        // hi·2¹⁶ and lo are exact; their sum rounds once, as `u as f32`.
        let hi = F32x8x2::from_i32(u.shr(16));
        let lo = F32x8x2::from_i32(u & U32x8x2::splat(0xffff));
        hi * F32x8x2::splat(65536.0) + lo
    }
    #[inline(always)]
    fn compress(self, m: M8x2) -> F32x8x2 {
        F32x8x2::from_bits(U32x8x2(compress32(self.to_bits().0, m.bits())))
    }
    #[inline(always)]
    fn expand(self, m: M8x2) -> F32x8x2 {
        F32x8x2::from_bits(U32x8x2(expand32(self.to_bits().0, m.bits())))
    }
}

impl LaneU32 for U32x8x2 {
    type M = M8x2;

    #[inline(always)]
    fn lane(&self, i: usize) -> u32 {
        lanes_ref!(self, u32)[i]
    }
    #[inline(always)]
    fn set_lane(&mut self, i: usize, x: u32) {
        lanes_mut!(self, u32)[i] = x;
    }
    #[inline(always)]
    fn store(self, out: &mut [u32]) {
        let out = &mut out[..W];
        unsafe {
            _mm256_storeu_si256(out.as_mut_ptr() as *mut __m256i, self.0[0]);
            _mm256_storeu_si256(out[8..].as_mut_ptr() as *mut __m256i, self.0[1]);
        }
    }
    #[inline(always)]
    fn wrapping_add(self, o: U32x8x2) -> U32x8x2 {
        self.zip(o, |a, b| unsafe { _mm256_add_epi32(a, b) })
    }
    #[inline(always)]
    fn wrapping_sub(self, o: U32x8x2) -> U32x8x2 {
        self.zip(o, |a, b| unsafe { _mm256_sub_epi32(a, b) })
    }
    #[inline(always)]
    fn wrapping_mul(self, o: U32x8x2) -> U32x8x2 {
        self.zip(o, |a, b| unsafe { _mm256_mullo_epi32(a, b) })
    }
    #[inline(always)]
    fn shl(self, n: u32) -> U32x8x2 {
        let c = unsafe { _mm_cvtsi32_si128(n as i32) };
        self.map(|a| unsafe { _mm256_sll_epi32(a, c) })
    }
    #[inline(always)]
    fn shr(self, n: u32) -> U32x8x2 {
        let c = unsafe { _mm_cvtsi32_si128(n as i32) };
        self.map(|a| unsafe { _mm256_srl_epi32(a, c) })
    }
    #[inline(always)]
    fn shlv(self, n: U32x8x2) -> U32x8x2 {
        self.zip(n, |a, b| unsafe { _mm256_sllv_epi32(a, b) })
    }
    #[inline(always)]
    fn shrv(self, n: U32x8x2) -> U32x8x2 {
        self.zip(n, |a, b| unsafe { _mm256_srlv_epi32(a, b) })
    }
    #[inline(always)]
    fn rotate_right(self, n: U32x8x2) -> U32x8x2 {
        // (x >> r) | (x << (32 − r)), r = n mod 32; a shift by 32 gives 0
        let r = n & U32x8x2::splat(31);
        self.shrv(r) | self.shlv(U32x8x2::splat(32).wrapping_sub(r))
    }
    #[inline(always)]
    fn min(self, o: U32x8x2) -> U32x8x2 {
        self.zip(o, |a, b| unsafe { _mm256_min_epu32(a, b) })
    }
    #[inline(always)]
    fn max(self, o: U32x8x2) -> U32x8x2 {
        self.zip(o, |a, b| unsafe { _mm256_max_epu32(a, b) })
    }
    #[inline(always)]
    fn cmp_eq(self, o: U32x8x2) -> M8x2 {
        self.zip(o, |a, b| unsafe { _mm256_cmpeq_epi32(a, b) })
            .mask()
    }
    #[inline(always)]
    fn cmp_lt(self, o: U32x8x2) -> M8x2 {
        o.cmp_gt(self)
    }
    #[inline(always)]
    fn cmp_gt(self, o: U32x8x2) -> M8x2 {
        // unsigned >: signed > with both top bits flipped
        let flip = U32x8x2::splat(1 << 31);
        (self ^ flip)
            .zip(o ^ flip, |a, b| unsafe { _mm256_cmpgt_epi32(a, b) })
            .mask()
    }
    #[inline(always)]
    fn select(m: M8x2, a: U32x8x2, b: U32x8x2) -> U32x8x2 {
        F32x8x2::select(m, F32x8x2::from_bits(a), F32x8x2::from_bits(b)).to_bits()
    }
    #[inline(always)]
    fn compress(self, m: M8x2) -> U32x8x2 {
        U32x8x2(compress32(self.0, m.bits()))
    }
    #[inline(always)]
    fn expand(self, m: M8x2) -> U32x8x2 {
        U32x8x2(expand32(self.0, m.bits()))
    }
}

/// The low 32 bits of the four u64 lanes of `a` and of `b`, as eight u32 lanes.
#[inline(always)]
fn pack_low(a: __m256i, b: __m256i) -> __m256i {
    unsafe {
        let even = _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6);
        let (a, b) = (
            _mm256_permutevar8x32_epi32(a, even),
            _mm256_permutevar8x32_epi32(b, even),
        );
        _mm256_permute2x128_si256::<0x20>(a, b)
    }
}

impl U64x4x4 {
    #[inline(always)]
    fn map(self, f: impl Fn(__m256i) -> __m256i) -> U64x4x4 {
        U64x4x4(each!(4, |q| f(self.0[q])))
    }
    #[inline(always)]
    fn zip(self, o: U64x4x4, f: impl Fn(__m256i, __m256i) -> __m256i) -> U64x4x4 {
        U64x4x4(each!(4, |q| f(self.0[q], o.0[q])))
    }
}

impl LaneU64 for U64x4x4 {
    type M = M8x2;
    type U32 = U32x8x2;

    #[inline(always)]
    fn lane(&self, i: usize) -> u64 {
        lanes_ref!(self, u64)[i]
    }
    #[inline(always)]
    fn set_lane(&mut self, i: usize, x: u64) {
        lanes_mut!(self, u64)[i] = x;
    }
    #[inline(always)]
    fn store(self, out: &mut [u64]) {
        let out = &mut out[..W];
        for q in 0..4 {
            unsafe {
                _mm256_storeu_si256(out[4 * q..].as_mut_ptr() as *mut __m256i, self.0[q]);
            }
        }
    }
    #[inline(always)]
    fn wrapping_add(self, o: U64x4x4) -> U64x4x4 {
        self.zip(o, |a, b| unsafe { _mm256_add_epi64(a, b) })
    }
    #[inline(always)]
    fn wrapping_sub(self, o: U64x4x4) -> U64x4x4 {
        self.zip(o, |a, b| unsafe { _mm256_sub_epi64(a, b) })
    }
    #[inline(always)]
    fn wrapping_mul(self, o: U64x4x4) -> U64x4x4 {
        // lo·lo + ((hi·lo + lo·hi) << 32), each product of 32-bit halves exact (vpmuludq)
        self.zip(o, |a, b| unsafe {
            let ll = _mm256_mul_epu32(a, b);
            let hl = _mm256_mul_epu32(_mm256_srli_epi64::<32>(a), b);
            let lh = _mm256_mul_epu32(a, _mm256_srli_epi64::<32>(b));
            _mm256_add_epi64(ll, _mm256_slli_epi64::<32>(_mm256_add_epi64(hl, lh)))
        })
    }
    #[inline(always)]
    fn shl(self, n: u32) -> U64x4x4 {
        let c = unsafe { _mm_cvtsi32_si128(n as i32) };
        self.map(|a| unsafe { _mm256_sll_epi64(a, c) })
    }
    #[inline(always)]
    fn shr(self, n: u32) -> U64x4x4 {
        let c = unsafe { _mm_cvtsi32_si128(n as i32) };
        self.map(|a| unsafe { _mm256_srl_epi64(a, c) })
    }
    #[inline(always)]
    fn cmp_eq(self, o: U64x4x4) -> M8x2 {
        let e = self.zip(o, |a, b| unsafe { _mm256_cmpeq_epi64(a, b) });
        U32x8x2([pack_low(e.0[0], e.0[1]), pack_low(e.0[2], e.0[3])]).mask()
    }
    #[inline(always)]
    fn select(m: M8x2, a: U64x4x4, b: U64x4x4) -> U64x4x4 {
        U64x4x4(each!(4, |q| unsafe {
            let h = m.int(q / 2);
            let quarter = if q & 1 == 0 {
                _mm256_castsi256_si128(h)
            } else {
                _mm256_extracti128_si256::<1>(h)
            };
            let wide = _mm256_cvtepi32_epi64(quarter);
            _mm256_blendv_epi8(b.0[q], a.0[q], wide)
        }))
    }
    #[inline(always)]
    fn from_u32(u: U32x8x2) -> U64x4x4 {
        U64x4x4(each!(4, |q| unsafe {
            let h = u.0[q / 2];
            let quarter = if q & 1 == 0 {
                _mm256_castsi256_si128(h)
            } else {
                _mm256_extracti128_si256::<1>(h)
            };
            _mm256_cvtepu32_epi64(quarter)
        }))
    }
    #[inline(always)]
    fn low32(self) -> U32x8x2 {
        U32x8x2([
            pack_low(self.0[0], self.0[1]),
            pack_low(self.0[2], self.0[3]),
        ])
    }
    #[inline(always)]
    fn high32(self) -> U32x8x2 {
        self.shr(32).low32()
    }
}

impl Lanes for Avx2 {
    const WIDTH: usize = W;
    type Wavelengths = [glam::Vec4; W];
    const BACKEND: Backend = Backend::Avx2;
    type M = M8x2;
    type F = F32x8x2;
    type U32 = U32x8x2;
    type U64 = U64x4x4;

    #[inline(always)]
    fn splat(self, x: f32) -> F32x8x2 {
        F32x8x2::splat(x)
    }
    #[inline(always)]
    fn splat_u32(self, x: u32) -> U32x8x2 {
        U32x8x2::splat(x)
    }
    #[inline(always)]
    fn splat_u64(self, x: u64) -> U64x4x4 {
        let v = unsafe { _mm256_set1_epi64x(x as i64) };
        U64x4x4([v; 4])
    }
    #[inline(always)]
    fn load(self, a: &[f32]) -> F32x8x2 {
        let a = &a[..W];
        F32x8x2(unsafe {
            [
                _mm256_loadu_ps(a.as_ptr()),
                _mm256_loadu_ps(a[8..].as_ptr()),
            ]
        })
    }
    #[inline(always)]
    fn load_u32(self, a: &[u32]) -> U32x8x2 {
        let a = &a[..W];
        U32x8x2(unsafe {
            [
                _mm256_loadu_si256(a.as_ptr() as *const __m256i),
                _mm256_loadu_si256(a[8..].as_ptr() as *const __m256i),
            ]
        })
    }
    #[inline(always)]
    fn load_u64(self, a: &[u64]) -> U64x4x4 {
        let a = &a[..W];
        U64x4x4(each!(4, |q| unsafe {
            _mm256_loadu_si256(a[4 * q..].as_ptr() as *const __m256i)
        }))
    }
    #[inline(always)]
    fn mask(self, bits: u32) -> M8x2 {
        M8x2::from_bits(bits)
    }
    #[inline(always)]
    fn index(self) -> U32x8x2 {
        U32x8x2(unsafe {
            [
                _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
                _mm256_setr_epi32(8, 9, 10, 11, 12, 13, 14, 15),
            ]
        })
    }
    #[inline(always)]
    fn gather(self, table: &[f32], idx: U32x8x2, m: M8x2) -> F32x8x2 {
        let inside = idx.cmp_lt(U32x8x2::splat(gather_bound(table.len())));
        if m.and_not(inside).any() {
            gather_out_of_bounds(table.len());
        }
        // SAFETY: every lane read is below the table's length and below 2³¹.
        F32x8x2(each!(2, |h| unsafe {
            _mm256_mask_i32gather_ps::<4>(_mm256_setzero_ps(), table.as_ptr(), idx.0[h], m.0[h])
        }))
    }
    #[inline(always)]
    fn gather_u32(self, table: &[u32], idx: U32x8x2, m: M8x2) -> U32x8x2 {
        let inside = idx.cmp_lt(U32x8x2::splat(gather_bound(table.len())));
        if m.and_not(inside).any() {
            gather_out_of_bounds(table.len());
        }
        // SAFETY: as `gather`.
        U32x8x2(each!(2, |h| unsafe {
            _mm256_mask_i32gather_epi32::<4>(
                _mm256_setzero_si256(),
                table.as_ptr() as *const i32,
                idx.0[h],
                m.int(h),
            )
        }))
    }
    #[inline(always)]
    fn sin_cos(self, x: F32x8x2) -> (F32x8x2, F32x8x2) {
        // SAFETY (all intrinsics here): the token proves AVX2.
        let quarters: [F64x4; 4] = each!(4, |q| unsafe {
            let h = x.0[q / 2];
            F64x4(_mm256_cvtps_pd(if q & 1 == 0 {
                _mm256_castps256_ps128(h)
            } else {
                _mm256_extractf128_ps::<1>(h)
            }))
        });
        let sc = quarters.map(crate::math::sin_cosf_f64);
        let join = |a: F64x4, b: F64x4| unsafe {
            _mm256_insertf128_ps::<1>(
                _mm256_castps128_ps256(_mm256_cvtpd_ps(a.0)),
                _mm256_cvtpd_ps(b.0),
            )
        };
        let mut s = F32x8x2([join(sc[0].0, sc[1].0), join(sc[2].0, sc[3].0)]);
        let mut c = F32x8x2([join(sc[0].1, sc[1].1), join(sc[2].1, sc[3].1)]);
        super::sin_cos_beyond_limit(self, x, &mut s, &mut c);
        (s, c)
    }
}

/// Four f64 lanes, for [`crate::math::sin_cosf_f64`].
#[derive(Clone, Copy)]
struct F64x4(__m256d);

// SAFETY (every method): only called from `Avx2::sin_cos`, which runs where AVX2 exists.
impl crate::math::F64Ops for F64x4 {
    type I = __m256i;
    #[inline(always)]
    fn splat(x: f64) -> Self {
        F64x4(unsafe { _mm256_set1_pd(x) })
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        F64x4(unsafe { _mm256_add_pd(self.0, o.0) })
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        F64x4(unsafe { _mm256_sub_pd(self.0, o.0) })
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        F64x4(unsafe { _mm256_mul_pd(self.0, o.0) })
    }
    #[inline(always)]
    fn to_bits(self) -> __m256i {
        unsafe { _mm256_castpd_si256(self.0) }
    }
    #[inline(always)]
    fn from_bits(i: __m256i) -> Self {
        F64x4(unsafe { _mm256_castsi256_pd(i) })
    }
    #[inline(always)]
    fn splat_i(x: i64) -> __m256i {
        unsafe { _mm256_set1_epi64x(x) }
    }
    #[inline(always)]
    fn i_sub(a: __m256i, b: __m256i) -> __m256i {
        unsafe { _mm256_sub_epi64(a, b) }
    }
    #[inline(always)]
    fn i_add(a: __m256i, b: __m256i) -> __m256i {
        unsafe { _mm256_add_epi64(a, b) }
    }
    #[inline(always)]
    fn i_and(a: __m256i, b: __m256i) -> __m256i {
        unsafe { _mm256_and_si256(a, b) }
    }
    #[inline(always)]
    fn i_xor(a: __m256i, b: __m256i) -> __m256i {
        unsafe { _mm256_xor_si256(a, b) }
    }
    #[inline(always)]
    fn i_shl62(a: __m256i) -> __m256i {
        unsafe { _mm256_slli_epi64::<62>(a) }
    }
    #[inline(always)]
    fn select_odd(n: __m256i, a: Self, b: Self) -> Self {
        unsafe {
            let one = _mm256_set1_epi64x(1);
            let odd = _mm256_cmpeq_epi64(_mm256_and_si256(n, one), one);
            F64x4(_mm256_blendv_pd(b.0, a.0, _mm256_castsi256_pd(odd)))
        }
    }
}
