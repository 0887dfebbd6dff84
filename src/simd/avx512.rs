//! The AVX-512 backend: sixteen f32 or u32 lanes in one `__m512` (u64: two), masks in a
//! `__mmask16`. Needs AVX-512 F and DQ (64-bit multiplies), detected at run time.
//!
//! The lane values can only be made through an [`Avx512`] token, which exists only after
//! detection; their safe methods therefore only run where the instructions exist (each
//! method is `#[inline(always)]` and is meant to be compiled inside [`super::dispatch`]'s
//! AVX-512 entry).

use super::{gather_bound, gather_out_of_bounds, Backend, LaneF32, LaneMask, LaneU32, LaneU64};
use super::{Lanes, MAX_WIDTH};
use std::arch::x86_64::*;
use std::ops::{Add, BitAnd, BitOr, BitXor, Div, Mul, Neg, Not, Sub};

const W: usize = MAX_WIDTH;

/// Proof that the processor runs AVX-512 F and DQ.
#[derive(Clone, Copy, Debug)]
pub struct Avx512 {
    _detected: (),
}

impl Avx512 {
    /// The token, if this processor has AVX-512 F and DQ.
    pub fn new() -> Option<Avx512> {
        (is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("avx512dq"))
            .then_some(Avx512 { _detected: () })
    }
}

#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct F32x16(__m512);

#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct U32x16(__m512i);

/// Lanes 0–7 in the first register, 8–15 in the second.
#[derive(Clone, Copy)]
#[repr(C)]
pub struct U64x16([__m512i; 2]);

/// Bit i is lane i.
#[derive(Clone, Copy, Debug)]
pub struct M16(__mmask16);

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
debug_lanes!(F32x16, f32);
debug_lanes!(U32x16, u32);
debug_lanes!(U64x16, u64);

/// The lanes of a 64-byte value as an array (`T` is its lane type; the layouts agree).
macro_rules! lanes_ref {
    ($v:expr, $e:ty) => {
        // SAFETY: the value is 64 (u64: 128) bytes of plain lanes, as the array.
        unsafe { &*($v as *const _ as *const [$e; W]) }
    };
}
macro_rules! lanes_mut {
    ($v:expr, $e:ty) => {
        // SAFETY: as `lanes_ref`; every bit pattern is a valid lane.
        unsafe { &mut *($v as *mut _ as *mut [$e; W]) }
    };
}

impl BitAnd for M16 {
    type Output = M16;
    #[inline(always)]
    fn bitand(self, o: M16) -> M16 {
        M16(self.0 & o.0)
    }
}
impl BitOr for M16 {
    type Output = M16;
    #[inline(always)]
    fn bitor(self, o: M16) -> M16 {
        M16(self.0 | o.0)
    }
}
impl BitXor for M16 {
    type Output = M16;
    #[inline(always)]
    fn bitxor(self, o: M16) -> M16 {
        M16(self.0 ^ o.0)
    }
}
impl Not for M16 {
    type Output = M16;
    #[inline(always)]
    fn not(self) -> M16 {
        M16(!self.0)
    }
}
impl LaneMask for M16 {
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

impl M16 {
    /// The mask of the lanes 0–7 and 8–15 (for the two u64 registers).
    #[inline(always)]
    fn halves(self) -> (__mmask8, __mmask8) {
        (self.0 as u8, (self.0 >> 8) as u8)
    }
}

// SAFETY (every `unsafe` block below): the intrinsics need AVX-512 F (or DQ where named),
// which the existence of a lane value proves (only an `Avx512` token makes them); pointers
// are to arrays of 16 lanes.

macro_rules! f_binop {
    ($trait:ident, $f:ident, $intr:ident) => {
        impl $trait for F32x16 {
            type Output = F32x16;
            #[inline(always)]
            fn $f(self, o: F32x16) -> F32x16 {
                F32x16(unsafe { $intr(self.0, o.0) })
            }
        }
    };
}
f_binop!(Add, add, _mm512_add_ps);
f_binop!(Sub, sub, _mm512_sub_ps);
f_binop!(Mul, mul, _mm512_mul_ps);
f_binop!(Div, div, _mm512_div_ps);

impl Neg for F32x16 {
    type Output = F32x16;
    #[inline(always)]
    fn neg(self) -> F32x16 {
        // flips the sign bit, as scalar negation does
        F32x16(unsafe { _mm512_xor_ps(self.0, _mm512_set1_ps(-0.0)) })
    }
}

macro_rules! u_bitop {
    ($t:ident, $trait:ident, $f:ident, $intr:ident) => {
        impl $trait for $t {
            type Output = $t;
            #[inline(always)]
            fn $f(self, o: $t) -> $t {
                $t(unsafe { $intr(self.0, o.0) })
            }
        }
    };
}
u_bitop!(U32x16, BitAnd, bitand, _mm512_and_si512);
u_bitop!(U32x16, BitOr, bitor, _mm512_or_si512);
u_bitop!(U32x16, BitXor, bitxor, _mm512_xor_si512);

macro_rules! u64_bitop {
    ($trait:ident, $f:ident, $intr:ident) => {
        impl $trait for U64x16 {
            type Output = U64x16;
            #[inline(always)]
            fn $f(self, o: U64x16) -> U64x16 {
                U64x16(unsafe { [$intr(self.0[0], o.0[0]), $intr(self.0[1], o.0[1])] })
            }
        }
    };
}
u64_bitop!(BitAnd, bitand, _mm512_and_si512);
u64_bitop!(BitOr, bitor, _mm512_or_si512);
u64_bitop!(BitXor, bitxor, _mm512_xor_si512);

impl F32x16 {
    #[inline(always)]
    fn cmp<const P: i32>(self, o: F32x16) -> M16 {
        M16(unsafe { _mm512_cmp_ps_mask::<P>(self.0, o.0) })
    }
}

impl LaneF32 for F32x16 {
    type M = M16;
    type U = U32x16;

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
        unsafe { _mm512_storeu_ps(out.as_mut_ptr(), self.0) }
    }
    #[inline(always)]
    fn abs(self) -> F32x16 {
        F32x16(unsafe { _mm512_abs_ps(self.0) })
    }
    #[inline(always)]
    fn sqrt(self) -> F32x16 {
        F32x16(unsafe { _mm512_sqrt_ps(self.0) })
    }
    #[inline(always)]
    fn floor(self) -> F32x16 {
        F32x16(unsafe {
            _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(self.0)
        })
    }
    #[inline(always)]
    fn ceil(self) -> F32x16 {
        F32x16(unsafe {
            _mm512_roundscale_ps::<{ _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC }>(self.0)
        })
    }
    #[inline(always)]
    fn trunc(self) -> F32x16 {
        F32x16(unsafe {
            _mm512_roundscale_ps::<{ _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC }>(self.0)
        })
    }
    #[inline(always)]
    fn round(self) -> F32x16 {
        // t = trunc(x); x − t is exact; t ± 1 where |x − t| ≥ ½ (exact: |t| < 2²³ then).
        let t = self.trunc();
        let d = (self - t).abs();
        let up = d.cmp_ge(F32x16(unsafe { _mm512_set1_ps(0.5) }));
        let one = F32x16(unsafe { _mm512_maskz_mov_ps(up.0, _mm512_set1_ps(1.0)) });
        t + one.copysign(self)
    }
    #[inline(always)]
    fn copysign(self, sign: F32x16) -> F32x16 {
        // (self & 0x7fffffff) | (sign & 0x80000000)
        F32x16(unsafe {
            let mask = _mm512_set1_epi32(i32::MAX);
            _mm512_castsi512_ps(_mm512_or_si512(
                _mm512_and_si512(_mm512_castps_si512(self.0), mask),
                _mm512_andnot_si512(mask, _mm512_castps_si512(sign.0)),
            ))
        })
    }
    #[inline(always)]
    fn min(self, o: F32x16) -> F32x16 {
        // rustc's f32::min on x86-64: isnan(a) ? b : minss(b, a)
        let m = unsafe { _mm512_min_ps(o.0, self.0) };
        F32x16(unsafe { _mm512_mask_blend_ps(self.is_nan().0, m, o.0) })
    }
    #[inline(always)]
    fn max(self, o: F32x16) -> F32x16 {
        let m = unsafe { _mm512_max_ps(o.0, self.0) };
        F32x16(unsafe { _mm512_mask_blend_ps(self.is_nan().0, m, o.0) })
    }
    #[inline(always)]
    fn min_lt(self, o: F32x16) -> F32x16 {
        F32x16(unsafe { _mm512_min_ps(self.0, o.0) })
    }
    #[inline(always)]
    fn max_gt(self, o: F32x16) -> F32x16 {
        F32x16(unsafe { _mm512_max_ps(self.0, o.0) })
    }
    #[inline(always)]
    fn cmp_eq(self, o: F32x16) -> M16 {
        self.cmp::<_CMP_EQ_OQ>(o)
    }
    #[inline(always)]
    fn cmp_ne(self, o: F32x16) -> M16 {
        self.cmp::<_CMP_NEQ_UQ>(o)
    }
    #[inline(always)]
    fn cmp_lt(self, o: F32x16) -> M16 {
        self.cmp::<_CMP_LT_OQ>(o)
    }
    #[inline(always)]
    fn cmp_le(self, o: F32x16) -> M16 {
        self.cmp::<_CMP_LE_OQ>(o)
    }
    #[inline(always)]
    fn cmp_gt(self, o: F32x16) -> M16 {
        self.cmp::<_CMP_GT_OQ>(o)
    }
    #[inline(always)]
    fn cmp_ge(self, o: F32x16) -> M16 {
        self.cmp::<_CMP_GE_OQ>(o)
    }
    #[inline(always)]
    fn is_nan(self) -> M16 {
        self.cmp::<_CMP_UNORD_Q>(self)
    }
    #[inline(always)]
    fn is_finite(self) -> M16 {
        self.abs()
            .cmp_lt(F32x16(unsafe { _mm512_set1_ps(f32::INFINITY) }))
    }
    #[inline(always)]
    fn select(m: M16, a: F32x16, b: F32x16) -> F32x16 {
        F32x16(unsafe { _mm512_mask_blend_ps(m.0, b.0, a.0) })
    }
    #[inline(always)]
    fn to_bits(self) -> U32x16 {
        U32x16(unsafe { _mm512_castps_si512(self.0) })
    }
    #[inline(always)]
    fn from_bits(u: U32x16) -> F32x16 {
        F32x16(unsafe { _mm512_castsi512_ps(u.0) })
    }
    #[inline(always)]
    fn to_i32(self) -> U32x16 {
        // vcvttps2dq gives 0x80000000 for NaN and out of range: positive overflow saturates
        // to i32::MAX and NaN goes to 0, as `as i32` does.
        unsafe {
            let c = _mm512_cvttps_epi32(self.0);
            let big = self.cmp_ge(F32x16(_mm512_set1_ps(2147483648.0))).0;
            let c = _mm512_mask_mov_epi32(c, big, _mm512_set1_epi32(i32::MAX));
            U32x16(_mm512_maskz_mov_epi32(!self.is_nan().0, c))
        }
    }
    #[inline(always)]
    fn to_u32(self) -> U32x16 {
        // vcvttps2udq gives 0xffffffff for NaN and out of range: that is `as u32` from 2³²
        // on; NaN and x ≤ −1 go to 0.
        unsafe {
            let c = _mm512_cvttps_epu32(self.0);
            let keep = self.cmp_gt(F32x16(_mm512_set1_ps(-1.0))).0;
            U32x16(_mm512_maskz_mov_epi32(keep, c))
        }
    }
    #[inline(always)]
    fn from_i32(u: U32x16) -> F32x16 {
        F32x16(unsafe { _mm512_cvtepi32_ps(u.0) })
    }
    #[inline(always)]
    fn from_u32(u: U32x16) -> F32x16 {
        F32x16(unsafe { _mm512_cvtepu32_ps(u.0) })
    }
    #[inline(always)]
    fn compress(self, m: M16) -> F32x16 {
        F32x16(unsafe { _mm512_maskz_compress_ps(m.0, self.0) })
    }
    #[inline(always)]
    fn expand(self, m: M16) -> F32x16 {
        F32x16(unsafe { _mm512_maskz_expand_ps(m.0, self.0) })
    }
}

impl LaneU32 for U32x16 {
    type M = M16;

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
        unsafe { _mm512_storeu_si512(out.as_mut_ptr() as *mut _, self.0) }
    }
    #[inline(always)]
    fn wrapping_add(self, o: U32x16) -> U32x16 {
        U32x16(unsafe { _mm512_add_epi32(self.0, o.0) })
    }
    #[inline(always)]
    fn wrapping_sub(self, o: U32x16) -> U32x16 {
        U32x16(unsafe { _mm512_sub_epi32(self.0, o.0) })
    }
    #[inline(always)]
    fn wrapping_mul(self, o: U32x16) -> U32x16 {
        U32x16(unsafe { _mm512_mullo_epi32(self.0, o.0) })
    }
    #[inline(always)]
    fn shl(self, n: u32) -> U32x16 {
        U32x16(unsafe { _mm512_sll_epi32(self.0, _mm_cvtsi32_si128(n as i32)) })
    }
    #[inline(always)]
    fn shr(self, n: u32) -> U32x16 {
        U32x16(unsafe { _mm512_srl_epi32(self.0, _mm_cvtsi32_si128(n as i32)) })
    }
    #[inline(always)]
    fn shlv(self, n: U32x16) -> U32x16 {
        U32x16(unsafe { _mm512_sllv_epi32(self.0, n.0) })
    }
    #[inline(always)]
    fn shrv(self, n: U32x16) -> U32x16 {
        U32x16(unsafe { _mm512_srlv_epi32(self.0, n.0) })
    }
    #[inline(always)]
    fn rotate_right(self, n: U32x16) -> U32x16 {
        U32x16(unsafe { _mm512_rorv_epi32(self.0, n.0) })
    }
    #[inline(always)]
    fn min(self, o: U32x16) -> U32x16 {
        U32x16(unsafe { _mm512_min_epu32(self.0, o.0) })
    }
    #[inline(always)]
    fn max(self, o: U32x16) -> U32x16 {
        U32x16(unsafe { _mm512_max_epu32(self.0, o.0) })
    }
    #[inline(always)]
    fn cmp_eq(self, o: U32x16) -> M16 {
        M16(unsafe { _mm512_cmpeq_epu32_mask(self.0, o.0) })
    }
    #[inline(always)]
    fn cmp_lt(self, o: U32x16) -> M16 {
        M16(unsafe { _mm512_cmplt_epu32_mask(self.0, o.0) })
    }
    #[inline(always)]
    fn cmp_gt(self, o: U32x16) -> M16 {
        M16(unsafe { _mm512_cmpgt_epu32_mask(self.0, o.0) })
    }
    #[inline(always)]
    fn select(m: M16, a: U32x16, b: U32x16) -> U32x16 {
        U32x16(unsafe { _mm512_mask_blend_epi32(m.0, b.0, a.0) })
    }
    #[inline(always)]
    fn compress(self, m: M16) -> U32x16 {
        U32x16(unsafe { _mm512_maskz_compress_epi32(m.0, self.0) })
    }
    #[inline(always)]
    fn expand(self, m: M16) -> U32x16 {
        U32x16(unsafe { _mm512_maskz_expand_epi32(m.0, self.0) })
    }
}

impl U64x16 {
    #[inline(always)]
    fn map2(self, o: U64x16, f: impl Fn(__m512i, __m512i) -> __m512i) -> U64x16 {
        U64x16([f(self.0[0], o.0[0]), f(self.0[1], o.0[1])])
    }
}

impl LaneU64 for U64x16 {
    type M = M16;
    type U32 = U32x16;

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
        unsafe {
            _mm512_storeu_si512(out.as_mut_ptr() as *mut _, self.0[0]);
            _mm512_storeu_si512(out[8..].as_mut_ptr() as *mut _, self.0[1]);
        }
    }
    #[inline(always)]
    fn wrapping_add(self, o: U64x16) -> U64x16 {
        self.map2(o, |a, b| unsafe { _mm512_add_epi64(a, b) })
    }
    #[inline(always)]
    fn wrapping_sub(self, o: U64x16) -> U64x16 {
        self.map2(o, |a, b| unsafe { _mm512_sub_epi64(a, b) })
    }
    #[inline(always)]
    fn wrapping_mul(self, o: U64x16) -> U64x16 {
        // vpmullq (AVX-512 DQ)
        self.map2(o, |a, b| unsafe { _mm512_mullo_epi64(a, b) })
    }
    #[inline(always)]
    fn shl(self, n: u32) -> U64x16 {
        let c = unsafe { _mm_cvtsi32_si128(n as i32) };
        U64x16(self.0.map(|a| unsafe { _mm512_sll_epi64(a, c) }))
    }
    #[inline(always)]
    fn shr(self, n: u32) -> U64x16 {
        let c = unsafe { _mm_cvtsi32_si128(n as i32) };
        U64x16(self.0.map(|a| unsafe { _mm512_srl_epi64(a, c) }))
    }
    #[inline(always)]
    fn cmp_eq(self, o: U64x16) -> M16 {
        let lo = unsafe { _mm512_cmpeq_epu64_mask(self.0[0], o.0[0]) };
        let hi = unsafe { _mm512_cmpeq_epu64_mask(self.0[1], o.0[1]) };
        M16(lo as u16 | (hi as u16) << 8)
    }
    #[inline(always)]
    fn select(m: M16, a: U64x16, b: U64x16) -> U64x16 {
        let (lo, hi) = m.halves();
        U64x16(unsafe {
            [
                _mm512_mask_blend_epi64(lo, b.0[0], a.0[0]),
                _mm512_mask_blend_epi64(hi, b.0[1], a.0[1]),
            ]
        })
    }
    #[inline(always)]
    fn from_u32(u: U32x16) -> U64x16 {
        U64x16(unsafe {
            [
                _mm512_cvtepu32_epi64(_mm512_castsi512_si256(u.0)),
                _mm512_cvtepu32_epi64(_mm512_extracti64x4_epi64::<1>(u.0)),
            ]
        })
    }
    #[inline(always)]
    fn low32(self) -> U32x16 {
        // vpmovqd truncates each u64 lane
        U32x16(unsafe {
            _mm512_inserti64x4::<1>(
                _mm512_castsi256_si512(_mm512_cvtepi64_epi32(self.0[0])),
                _mm512_cvtepi64_epi32(self.0[1]),
            )
        })
    }
    #[inline(always)]
    fn high32(self) -> U32x16 {
        self.shr(32).low32()
    }
}

impl Lanes for Avx512 {
    const WIDTH: usize = W;
    type Wavelengths = [glam::Vec4; W];
    const BACKEND: Backend = Backend::Avx512;
    type M = M16;
    type F = F32x16;
    type U32 = U32x16;
    type U64 = U64x16;

    #[inline(always)]
    fn splat(self, x: f32) -> F32x16 {
        F32x16(unsafe { _mm512_set1_ps(x) })
    }
    #[inline(always)]
    fn splat_u32(self, x: u32) -> U32x16 {
        U32x16(unsafe { _mm512_set1_epi32(x as i32) })
    }
    #[inline(always)]
    fn splat_u64(self, x: u64) -> U64x16 {
        let v = unsafe { _mm512_set1_epi64(x as i64) };
        U64x16([v, v])
    }
    #[inline(always)]
    fn load(self, a: &[f32]) -> F32x16 {
        let a = &a[..W];
        F32x16(unsafe { _mm512_loadu_ps(a.as_ptr()) })
    }
    #[inline(always)]
    fn load_u32(self, a: &[u32]) -> U32x16 {
        let a = &a[..W];
        U32x16(unsafe { _mm512_loadu_si512(a.as_ptr() as *const _) })
    }
    #[inline(always)]
    fn load_u64(self, a: &[u64]) -> U64x16 {
        let a = &a[..W];
        U64x16(unsafe {
            [
                _mm512_loadu_si512(a.as_ptr() as *const _),
                _mm512_loadu_si512(a[8..].as_ptr() as *const _),
            ]
        })
    }
    #[inline(always)]
    fn mask(self, bits: u32) -> M16 {
        M16(bits as u16)
    }
    #[inline(always)]
    fn index(self) -> U32x16 {
        U32x16(unsafe { _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15) })
    }
    #[inline(always)]
    fn gather(self, table: &[f32], idx: U32x16, m: M16) -> F32x16 {
        let inside = idx.cmp_lt(self.splat_u32(gather_bound(table.len())));
        if m.and_not(inside).any() {
            gather_out_of_bounds(table.len());
        }
        // SAFETY: every lane read is below the table's length and below 2³¹.
        F32x16(unsafe {
            _mm512_mask_i32gather_ps::<4>(_mm512_setzero_ps(), m.0, idx.0, table.as_ptr())
        })
    }
    #[inline(always)]
    fn gather_u32(self, table: &[u32], idx: U32x16, m: M16) -> U32x16 {
        let inside = idx.cmp_lt(self.splat_u32(gather_bound(table.len())));
        if m.and_not(inside).any() {
            gather_out_of_bounds(table.len());
        }
        // SAFETY: as `gather`.
        U32x16(unsafe {
            _mm512_mask_i32gather_epi32::<4>(
                _mm512_setzero_si512(),
                m.0,
                idx.0,
                table.as_ptr() as *const _,
            )
        })
    }
    #[inline(always)]
    fn sin_cos(self, x: F32x16) -> (F32x16, F32x16) {
        // SAFETY (all intrinsics here): the token proves AVX-512 F and DQ.
        let halves = unsafe {
            [
                _mm512_cvtps_pd(_mm512_castps512_ps256(x.0)),
                _mm512_cvtps_pd(_mm512_extractf32x8_ps::<1>(x.0)),
            ]
        };
        let [(s0, c0), (s1, c1)] = halves.map(|h| crate::math::sin_cosf_f64(F64x8(h)));
        let join = |a: F64x8, b: F64x8| unsafe {
            F32x16(_mm512_insertf32x8::<1>(
                _mm512_castps256_ps512(_mm512_cvtpd_ps(a.0)),
                _mm512_cvtpd_ps(b.0),
            ))
        };
        let (mut s, mut c) = (join(s0, s1), join(c0, c1));
        super::sin_cos_beyond_limit(self, x, &mut s, &mut c);
        (s, c)
    }
}

/// Eight f64 lanes, for [`crate::math::sin_cosf_f64`].
#[derive(Clone, Copy)]
struct F64x8(__m512d);

// SAFETY (every method): only called from `Avx512::sin_cos`, which runs where AVX-512 F and
// DQ exist.
impl crate::math::F64Ops for F64x8 {
    type I = __m512i;
    #[inline(always)]
    fn splat(x: f64) -> Self {
        F64x8(unsafe { _mm512_set1_pd(x) })
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        F64x8(unsafe { _mm512_add_pd(self.0, o.0) })
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        F64x8(unsafe { _mm512_sub_pd(self.0, o.0) })
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        F64x8(unsafe { _mm512_mul_pd(self.0, o.0) })
    }
    #[inline(always)]
    fn to_bits(self) -> __m512i {
        unsafe { _mm512_castpd_si512(self.0) }
    }
    #[inline(always)]
    fn from_bits(i: __m512i) -> Self {
        F64x8(unsafe { _mm512_castsi512_pd(i) })
    }
    #[inline(always)]
    fn splat_i(x: i64) -> __m512i {
        unsafe { _mm512_set1_epi64(x) }
    }
    #[inline(always)]
    fn i_sub(a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_sub_epi64(a, b) }
    }
    #[inline(always)]
    fn i_add(a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_add_epi64(a, b) }
    }
    #[inline(always)]
    fn i_and(a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_and_si512(a, b) }
    }
    #[inline(always)]
    fn i_xor(a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_xor_si512(a, b) }
    }
    #[inline(always)]
    fn i_shl62(a: __m512i) -> __m512i {
        unsafe { _mm512_slli_epi64::<62>(a) }
    }
    #[inline(always)]
    fn select_odd(n: __m512i, a: Self, b: Self) -> Self {
        unsafe {
            let odd = _mm512_test_epi64_mask(n, _mm512_set1_epi64(1));
            F64x8(_mm512_mask_blend_pd(odd, b.0, a.0))
        }
    }
}
