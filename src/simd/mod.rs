//! Lanes: f32, u32 and u64 values side by side, one per path, for the lane engine (issue 42;
//! the design note `lane-engine.md`, §3 and §4). One trait, [`Lanes`], with four instances:
//!
//! | backend | width | representation | chosen when |
//! |---|---:|---|---|
//! | [`Scalar`] | 1 | `f32`, `u32`, `u64`, `bool` | the scalar engine's instance of a lane kernel |
//! | [`Portable16`] | 16 | `[f32; 16]` … and a 16-bit mask | no AVX2 (other targets) |
//! | `Avx2` | 16 | two `__m256` halves | x86-64 with AVX2 |
//! | `Avx512` | 16 | one `__m512`, masks in `__mmask16` | x86-64 with AVX-512 F and DQ |
//!
//! The backend is chosen once per render by run-time feature detection ([`Backend::best`])
//! and entered through [`dispatch`], which compiles the generic body ([`LaneProgram::run`])
//! with that backend's target features. The x86 types can only be made through a token that
//! exists after detection, so their safe methods never run on a processor without them.
//!
//! **Every operation gives, lane by lane, the bits of the scalar Rust operation** it is named
//! after (`src/simd/tests.rs` checks each one on random inputs with NaNs, infinities,
//! subnormals and signed zeros, on every backend the machine runs). That is what lets the
//! lane engine reproduce the scalar engine's image bit for bit:
//! - only correctly rounded IEEE operations: add, sub, mul, div, sqrt, exact roundings and
//!   conversions; no fused multiply-add and no reciprocal or square-root approximation;
//! - [`LaneF32::min`] / [`LaneF32::max`] are Rust's `f32::min` / `f32::max` (the non-NaN
//!   operand; on equal operands such as ±0 the first, as rustc compiles them on x86-64),
//!   while [`LaneF32::min_lt`] / [`LaneF32::max_gt`] are `if a < b { a } else { b }` and
//!   `if a > b { a } else { b }`, as glam's `Vec3::min`, `max` and `max_element` are written;
//! - conversions are Rust's `as`: `as i32` and `as u32` saturate and send NaN to 0,
//!   `u32 as f32` rounds once to nearest even;
//! - integer arithmetic wraps;
//! - where a computed result is NaN, it is a NaN: Rust leaves the sign and payload of an
//!   arithmetic NaN unspecified (RFC 3514), and two compilations of the same scalar code
//!   differ in them (LLVM commutes additions). Moves, selects, negation, `abs` and
//!   `copysign` keep NaN bits exactly. A render drops non-finite samples, so no image
//!   depends on a payload.
//!
//! [`V3`] is a vector of three lane values (structure of arrays) whose operations follow
//! glam's `Vec3` operation by operation (`dot` = (x·x′ + y·y′) + z·z′, `normalize` =
//! v · (1 / √dot)), and [`Spectrum`] the RGB spectrum over it, as [`crate::spectrum::Spectrum`]
//! is glam's `Vec3`.

use std::fmt::Debug;
use std::ops::{Add, BitAnd, BitOr, BitXor, Div, Mul, Neg, Not, Sub};

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
mod portable;
mod scalar;
mod v3;
mod v4;

#[cfg(test)]
mod tests;

#[cfg(target_arch = "x86_64")]
pub use avx2::Avx2;
#[cfg(target_arch = "x86_64")]
pub use avx512::Avx512;
pub use portable::Portable16;
pub use scalar::Scalar;
pub use v3::V3;
pub use v4::V4;

/// A spectrum over lanes, as [`crate::spectrum::Spectrum`] is glam's `Vec4`.
pub type Spectrum<F> = V4<F>;

/// The widest backend's lane count: what fixed-size lane buffers hold.
pub const MAX_WIDTH: usize = 16;

/// A mask: one boolean per lane.
pub trait LaneMask:
    Copy
    + Debug
    + BitAnd<Output = Self>
    + BitOr<Output = Self>
    + BitXor<Output = Self>
    + Not<Output = Self>
{
    /// Bit i is lane i.
    fn bits(self) -> u32;
    /// Some lane is set.
    fn any(self) -> bool;
    /// Every lane is set.
    fn all(self) -> bool;
    /// Lanes set.
    #[inline(always)]
    fn count(self) -> u32 {
        self.bits().count_ones()
    }
    /// `self & !o`.
    #[inline(always)]
    fn and_not(self, o: Self) -> Self {
        self & !o
    }
}

/// f32 lanes.
pub trait LaneF32:
    Copy
    + Debug
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    type M: LaneMask;
    type U: LaneU32<M = Self::M>;

    /// Lane `i` (panics if `i` is not below the width).
    fn lane(&self, i: usize) -> f32;
    fn set_lane(&mut self, i: usize, x: f32);
    /// Writes the lanes to `out[..width]`.
    fn store(self, out: &mut [f32]);

    /// `f32::abs`.
    fn abs(self) -> Self;
    /// `f32::sqrt` (correctly rounded).
    fn sqrt(self) -> Self;
    fn floor(self) -> Self;
    fn ceil(self) -> Self;
    fn trunc(self) -> Self;
    /// `f32::round`: half-way cases away from zero.
    fn round(self) -> Self;
    /// `f32::copysign`.
    fn copysign(self, sign: Self) -> Self;
    /// `f32::min`: the other operand where one is NaN; `self` where they compare equal.
    fn min(self, o: Self) -> Self;
    /// `f32::max`, as [`LaneF32::min`].
    fn max(self, o: Self) -> Self;
    /// `if self < o { self } else { o }` (glam's `Vec3::min`; x86 `minps`).
    fn min_lt(self, o: Self) -> Self;
    /// `if self > o { self } else { o }` (glam's `Vec3::max` and `max_element`).
    fn max_gt(self, o: Self) -> Self;
    /// `f32::clamp` where `lo <= hi`: `if x < lo { lo }`, then `if x > hi { hi }` (NaN stays
    /// NaN; −0 stays −0 against a bound of +0).
    #[inline(always)]
    fn clamp(self, lo: Self, hi: Self) -> Self {
        let x = Self::select(self.cmp_lt(lo), lo, self);
        Self::select(x.cmp_gt(hi), hi, x)
    }

    /// `==` (false where either is NaN).
    fn cmp_eq(self, o: Self) -> Self::M;
    /// `!=` (true where either is NaN).
    fn cmp_ne(self, o: Self) -> Self::M;
    fn cmp_lt(self, o: Self) -> Self::M;
    fn cmp_le(self, o: Self) -> Self::M;
    fn cmp_gt(self, o: Self) -> Self::M;
    fn cmp_ge(self, o: Self) -> Self::M;
    fn is_nan(self) -> Self::M;
    /// Neither infinite nor NaN.
    fn is_finite(self) -> Self::M;

    /// `if m { a } else { b }` lane by lane.
    fn select(m: Self::M, a: Self, b: Self) -> Self;

    /// `f32::to_bits`.
    fn to_bits(self) -> Self::U;
    fn from_bits(u: Self::U) -> Self;
    /// `x as i32` (saturating, NaN to 0), as the bits of the i32.
    fn to_i32(self) -> Self::U;
    /// `x as u32` (saturating, NaN and negatives to 0).
    fn to_u32(self) -> Self::U;
    /// `(u as i32) as f32`.
    fn from_i32(u: Self::U) -> Self;
    /// `u as f32`.
    fn from_u32(u: Self::U) -> Self;

    /// The lanes of `m`, in order, moved to the lowest lanes; the rest 0.
    fn compress(self, m: Self::M) -> Self;
    /// The inverse of [`LaneF32::compress`]: the lowest lanes, in order, moved to the lanes of
    /// `m`; the rest 0.
    fn expand(self, m: Self::M) -> Self;
}

/// u32 lanes (wrapping arithmetic).
pub trait LaneU32:
    Copy + Debug + BitAnd<Output = Self> + BitOr<Output = Self> + BitXor<Output = Self>
{
    type M: LaneMask;

    fn lane(&self, i: usize) -> u32;
    fn set_lane(&mut self, i: usize, x: u32);
    fn store(self, out: &mut [u32]);

    fn wrapping_add(self, o: Self) -> Self;
    fn wrapping_sub(self, o: Self) -> Self;
    fn wrapping_mul(self, o: Self) -> Self;
    /// `self << n` for `n` below 32.
    fn shl(self, n: u32) -> Self;
    /// `self >> n` for `n` below 32.
    fn shr(self, n: u32) -> Self;
    /// `self << n` lane by lane, 0 where `n` ≥ 32 (`checked_shl(n).unwrap_or(0)`).
    fn shlv(self, n: Self) -> Self;
    /// `self >> n` lane by lane, 0 where `n` ≥ 32.
    fn shrv(self, n: Self) -> Self;
    /// `u32::rotate_right` lane by lane.
    fn rotate_right(self, n: Self) -> Self;
    fn min(self, o: Self) -> Self;
    fn max(self, o: Self) -> Self;

    fn cmp_eq(self, o: Self) -> Self::M;
    fn cmp_lt(self, o: Self) -> Self::M;
    fn cmp_gt(self, o: Self) -> Self::M;

    fn select(m: Self::M, a: Self, b: Self) -> Self;
    fn compress(self, m: Self::M) -> Self;
    fn expand(self, m: Self::M) -> Self;
}

/// u64 lanes (wrapping arithmetic): what a PCG32 state needs.
pub trait LaneU64:
    Copy + Debug + BitAnd<Output = Self> + BitOr<Output = Self> + BitXor<Output = Self>
{
    type M: LaneMask;
    type U32: LaneU32<M = Self::M>;

    fn lane(&self, i: usize) -> u64;
    fn set_lane(&mut self, i: usize, x: u64);
    fn store(self, out: &mut [u64]);

    fn wrapping_add(self, o: Self) -> Self;
    fn wrapping_sub(self, o: Self) -> Self;
    fn wrapping_mul(self, o: Self) -> Self;
    /// `self << n` for `n` below 64.
    fn shl(self, n: u32) -> Self;
    /// `self >> n` for `n` below 64.
    fn shr(self, n: u32) -> Self;
    fn cmp_eq(self, o: Self) -> Self::M;
    fn select(m: Self::M, a: Self, b: Self) -> Self;

    /// `u as u64`.
    fn from_u32(u: Self::U32) -> Self;
    /// `x as u32`.
    fn low32(self) -> Self::U32;
    /// `(x >> 32) as u32`.
    fn high32(self) -> Self::U32;
}

/// A backend: its lane types and what makes them. A value of the type is the proof that
/// the processor runs them (the x86 backends' constructors detect their features).
pub trait Lanes: Copy + Debug + Send + Sync + 'static {
    const WIDTH: usize;
    const BACKEND: Backend;
    type M: LaneMask;
    type F: LaneF32<M = Self::M, U = Self::U32>;
    type U32: LaneU32<M = Self::M>;
    type U64: LaneU64<M = Self::M, U32 = Self::U32>;
    /// One set of four wavelengths (nm) per lane (spectral mode's paths): `[Vec4; WIDTH]`.
    type Wavelengths: Copy
        + Debug
        + Default
        + Send
        + Sync
        + AsRef<[glam::Vec4]>
        + AsMut<[glam::Vec4]>;

    fn splat(self, x: f32) -> Self::F;
    fn splat_u32(self, x: u32) -> Self::U32;
    fn splat_u64(self, x: u64) -> Self::U64;
    /// Lanes from `a[..width]` (panics if `a` is shorter).
    fn load(self, a: &[f32]) -> Self::F;
    fn load_u32(self, a: &[u32]) -> Self::U32;
    fn load_u64(self, a: &[u64]) -> Self::U64;
    /// The mask of the lanes whose bit is set in `bits` (bits from the width on ignored).
    fn mask(self, bits: u32) -> Self::M;
    /// Lane i holds i.
    fn index(self) -> Self::U32;
    /// `if m { table[idx] } else { 0.0 }` lane by lane. Panics, as slice indexing does, if
    /// a lane of `m` has an index out of `table` (or of 2³¹: the x86 gathers take i32).
    fn gather(self, table: &[f32], idx: Self::U32, m: Self::M) -> Self::F;
    /// [`Lanes::gather`] of u32.
    fn gather_u32(self, table: &[u32], idx: Self::U32, m: Self::M) -> Self::U32;

    /// [`crate::math::sin_cosf`] lane by lane, the same bits: (sin x, cos x). The x86
    /// backends evaluate it in f64 lanes ([`crate::math::sin_cosf_f64`]); the others, and
    /// lanes above its hand-off to `std`, call the scalar function.
    #[inline(always)]
    fn sin_cos(self, x: Self::F) -> (Self::F, Self::F) {
        let (mut s, mut c) = (x, x);
        for i in 0..Self::WIDTH {
            let (si, ci) = crate::math::sin_cosf(x.lane(i));
            s.set_lane(i, si);
            c.set_lane(i, ci);
        }
        (s, c)
    }
}

/// The lanes of `x` above [`crate::math::sin_cosf`]'s hand-off to `std`, set in `(s, c)`
/// from the scalar function (never, for the renderer's angles).
#[inline(always)]
fn sin_cos_beyond_limit<L: Lanes>(l: L, x: L::F, s: &mut L::F, c: &mut L::F) {
    let far = x.abs().cmp_gt(l.splat(crate::math::SIN_COS_LIMIT_F32));
    let mut bits = far.bits();
    while bits != 0 {
        let i = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        let (si, ci) = crate::math::sin_cosf(x.lane(i));
        s.set_lane(i, si);
        c.set_lane(i, ci);
    }
}

/// The mask of indices a gather may read: below `len` and below 2³¹.
#[inline(always)]
fn gather_bound(len: usize) -> u32 {
    len.min(1 << 31) as u32
}

/// Panics as an out-of-bounds slice index does (a gather with an index past its table).
#[cold]
#[inline(never)]
fn gather_out_of_bounds(len: usize) -> ! {
    panic!("lane gather: an active lane's index is out of bounds for a table of {len}")
}

/// The set lanes of `bits`, lowest first.
#[inline(always)]
pub fn lanes_of(mut bits: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (bits != 0).then(|| {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            i
        })
    })
}

/// Runs `f` on every set lane of `m`, lowest first: the per-lane part of a kernel (what is
/// not ported yet, or is mostly scattered loads). On the width-1 backend it is one `if`.
#[inline(always)]
pub fn for_each_lane<M: LaneMask>(width: usize, m: M, mut f: impl FnMut(usize)) {
    if width == 1 {
        if m.any() {
            f(0);
        }
        return;
    }
    // The loop of `lanes_of` written out: through the iterator the lane engine ran 0.5% more
    // instructions a path (Cornell box, callgrind).
    let mut bits = m.bits();
    while bits != 0 {
        f(bits.trailing_zeros() as usize);
        bits &= bits - 1;
    }
}

/// Runs `f(v, mv)` once per distinct value `v` of `idx` among the set lanes of `m`, with
/// `mv` the lanes of `m` holding it, in the order of their lowest lane: dynamic dispatch as
/// a masked loop over what the lanes hold (one pass where they agree).
#[inline(always)]
pub fn for_each_distinct<L: Lanes>(l: L, idx: L::U32, m: L::M, mut f: impl FnMut(u32, L::M)) {
    if L::WIDTH == 1 {
        if m.any() {
            f(idx.lane(0), m);
        }
        return;
    }
    let mut rest = m;
    while rest.any() {
        let v = idx.lane(rest.bits().trailing_zeros() as usize);
        let mv = rest & idx.cmp_eq(l.splat_u32(v));
        f(v, mv);
        rest = rest.and_not(mv);
    }
}

/// `table[idx]` lane by lane where `m` is set, else zero: three gathers of a vertex table.
/// Panics, as [`Lanes::gather`] does, where an active lane's row is out of the table.
#[inline(always)]
pub fn gather_vec3<L: Lanes>(l: L, table: &[glam::Vec3], idx: L::U32, m: L::M) -> V3<L::F> {
    let mut out = V3::splat(l.splat(0.0));
    if L::WIDTH == 1 {
        // The width-1 instance: one row load, as scalar code indexes a `Vec<Vec3>`.
        if m.any() {
            out.set_lane(0, table[idx.lane(0) as usize]);
        }
        return out;
    }
    let flat: &[f32] = bytemuck::cast_slice(table);
    // (a row index from 2³² / 3 on would wrap: no table holds that many rows, see the bound
    // of `gather`, which panics from 2³¹ entries on)
    let base = idx.wrapping_mul(l.splat_u32(3));
    let one = l.splat_u32(1);
    let two = l.splat_u32(2);
    out.x = l.gather(flat, base, m);
    out.y = l.gather(flat, base.wrapping_add(one), m);
    out.z = l.gather(flat, base.wrapping_add(two), m);
    out
}

/// `table[idx]` of a table of index triples, lane by lane where `m` is set, else zeros.
#[inline(always)]
pub fn gather_u32x3<L: Lanes>(l: L, table: &[[u32; 3]], idx: L::U32, m: L::M) -> [L::U32; 3] {
    let mut out = [l.splat_u32(0); 3];
    if L::WIDTH == 1 {
        if m.any() {
            let row = table[idx.lane(0) as usize];
            for (o, v) in out.iter_mut().zip(row) {
                o.set_lane(0, v);
            }
        }
        return out;
    }
    let flat: &[u32] = table.as_flattened();
    let base = idx.wrapping_mul(l.splat_u32(3));
    for (k, o) in out.iter_mut().enumerate() {
        *o = l.gather_u32(flat, base.wrapping_add(l.splat_u32(k as u32)), m);
    }
    out
}

/// The backends, by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Backend {
    Scalar,
    Portable,
    Avx2,
    Avx512,
}

impl Backend {
    pub const ALL: [Backend; 4] = [
        Backend::Scalar,
        Backend::Portable,
        Backend::Avx2,
        Backend::Avx512,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Backend::Scalar => "scalar",
            Backend::Portable => "portable",
            Backend::Avx2 => "avx2",
            Backend::Avx512 => "avx512",
        }
    }

    pub fn from_name(name: &str) -> Option<Backend> {
        Backend::ALL.into_iter().find(|b| b.name() == name)
    }

    /// Lanes side by side.
    pub fn width(self) -> usize {
        match self {
            Backend::Scalar => 1,
            _ => MAX_WIDTH,
        }
    }

    /// Whether this processor runs the backend.
    pub fn supported(self) -> bool {
        match self {
            Backend::Scalar | Backend::Portable => true,
            #[cfg(target_arch = "x86_64")]
            Backend::Avx2 => Avx2::new().is_some(),
            #[cfg(target_arch = "x86_64")]
            Backend::Avx512 => Avx512::new().is_some(),
            #[cfg(not(target_arch = "x86_64"))]
            Backend::Avx2 | Backend::Avx512 => false,
        }
    }

    /// The backends this processor runs, in [`Backend::ALL`]'s order (what the tests that
    /// compare every backend with the scalar code loop over).
    pub fn all_supported() -> impl Iterator<Item = Backend> {
        Backend::ALL.into_iter().filter(|b| b.supported())
    }

    /// The widest 16-lane backend this processor runs: AVX-512, else AVX2, else portable.
    pub fn best() -> Backend {
        [Backend::Avx512, Backend::Avx2]
            .into_iter()
            .find(|b| b.supported())
            .unwrap_or(Backend::Portable)
    }
}

impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A body generic over the backend, for [`dispatch`]. Mark `run` `#[inline(always)]` (and
/// what it calls on lane values) so that it is compiled inside the backend's entry, with
/// its target features: otherwise every lane operation is a function call.
pub trait LaneProgram {
    type Output;
    fn run<L: Lanes>(self, lanes: L) -> Self::Output;
}

/// Runs `program` on `backend`; `None` if this processor does not run it.
pub fn dispatch<P: LaneProgram>(backend: Backend, program: P) -> Option<P::Output> {
    match backend {
        Backend::Scalar => Some(program.run(Scalar)),
        Backend::Portable => Some(program.run(Portable16)),
        #[cfg(target_arch = "x86_64")]
        Backend::Avx2 => Avx2::new().map(|l| {
            // SAFETY: the token exists, so the processor has AVX2.
            unsafe { run_avx2(program, l) }
        }),
        #[cfg(target_arch = "x86_64")]
        Backend::Avx512 => Avx512::new().map(|l| {
            // SAFETY: the token exists, so the processor has AVX-512 F and DQ.
            unsafe { run_avx512(program, l) }
        }),
        #[cfg(not(target_arch = "x86_64"))]
        Backend::Avx2 | Backend::Avx512 => None,
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn run_avx2<P: LaneProgram>(program: P, l: Avx2) -> P::Output {
    program.run(l)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq")]
unsafe fn run_avx512<P: LaneProgram>(program: P, l: Avx512) -> P::Output {
    program.run(l)
}
