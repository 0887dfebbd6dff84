//! penumbra's own elementary functions for the render's per-sample code: sine and cosine,
//! exp, ln, atan2 and acos, in f64 and (rounded from the f64 evaluation) f32.
//!
//! Why: the lane engine (issue 42) must give the scalar engine's images bit for bit, and a
//! SIMD kernel cannot reproduce the platform libm's results (glibc's differ between versions
//! and use table lookups). So every function here is a fixed sequence of IEEE operations
//! (additions, multiplications, one division at most, one square root at most, integer bit
//! operations and selects): no table lookup, no data-dependent loop, no fused multiply-add
//! (rustc never contracts `a * b + c`). A SIMD version that performs the same operations in
//! the same order, lane by lane, returns the same bits. The only branch that is not a select
//! is sine and cosine's hand-off to `std` above |x| = 2¹⁹ (see [`sin_cos`]): the renderer
//! never passes such angles, and a lane kernel runs those lanes through this scalar code.
//!
//! Each function reduces its argument to a short interval and evaluates a polynomial there.
//! The coefficients were fitted for penumbra by `validation/math/fit_coefficients.py`
//! (mpmath's Chebyshev least-squares fit in 60-digit arithmetic, rounded to f64): the
//! polynomials are within a small factor of minimax, and their approximation error is well
//! below half an ulp, so the error left is the rounding of the few operations around them.
//!
//! Accuracy (each function's documentation gives its figures; measured 2026-12-04): the f64
//! functions against 50-digit values from mpmath (`validation/math/ulp_f64.py`, 20,000–40,000
//! points per function, dumped by the ignored `exhaustive` test) and against glibc's f64
//! functions on 10⁷ points each; the f32 functions against glibc's f64 functions (whose own
//! error is below 2⁻²⁸ of an f32 ulp) on every f32 of the domain for sine and cosine and
//! every 7th f32 for the others. All are within 1.31 ulp; the f32 ones are correctly rounded
//! but within 2.2·10⁻⁴ ulp of a tie. The `*_ulp` unit tests assert the bounds on dense
//! sweeps (every 61st f32 of sine and cosine's domain, 4·10⁶ f64 points per function): each
//! goes red when one coefficient of its polynomial is changed in the sixth digit.
//!
//! Build-time code (scene loading, tables, tests) may keep calling `std`; what runs per
//! sample calls these.

/// 2/π, rounded to f64.
const FRAC_2_PI: f64 = std::f64::consts::FRAC_2_PI;
/// π/2 as PIO2_1 + PIO2_2 + PIO2_3: the first two have 33 significant bits, so k·PIO2_1
/// and k·PIO2_2 are exact for |k| < 2²⁰ (Cody and Waite's reduction).
const PIO2_1: f64 = 1.5707963267341256;
const PIO2_2: f64 = 6.077100506303966e-11;
const PIO2_3: f64 = 2.0222662487959506e-21;
/// π/2 − PIO2_1 rounded to f64: the two-part reduction of f32 arguments.
const PIO2_2T: f64 = 6.077100506506192e-11;
/// Above this |x|, [`sin_cos`] hands off to `std` (|k| < 2²⁰ holds up to about 1.6e6).
const SIN_COS_LIMIT: f64 = 524_288.0;
/// 1.5 · 2⁵²: adding it to |v| < 2⁵¹ rounds v to an integer (ties to even), held in the low
/// bits of the sum.
const ROUND_SHIFT: f64 = 6_755_399_441_055_744.0;
const LOG2_E: f64 = std::f64::consts::LOG2_E;
/// ln 2 as LN2_HI + LN2_LO; LN2_HI has 42 significant bits, so k·LN2_HI is exact for
/// |k| < 2¹¹.
const LN2_HI: f64 = 0.6931471805598903;
const LN2_LO: f64 = 5.497923018708371e-14;
/// π, π/2 and π/4 as f64 plus their remainders.
const PI_HI: f64 = std::f64::consts::PI;
const PI_LO: f64 = 1.2246467991473532e-16;
const FRAC_PI_2_HI: f64 = std::f64::consts::FRAC_PI_2;
const FRAC_PI_2_LO: f64 = 6.123233995736766e-17;
const FRAC_PI_4_HI: f64 = std::f64::consts::FRAC_PI_4;
const FRAC_PI_4_LO: f64 = 3.061616997868383e-17;
/// atan ½ as f64 plus its remainder.
const ATAN_HALF_HI: f64 = 0.4636476090008061;
const ATAN_HALF_LO: f64 = 2.2698777452961687e-17;

/// sin r = r + r·z·S(z), z = r², |r| ≤ π/4: degree 5, |error of S| ≤ 2.1e-17.
const SIN: [f64; 6] = [
    1.5918129294866608e-10,
    -2.5051131845003624e-08,
    2.755731610255244e-06,
    -0.00019841269836758574,
    0.008333333333330948,
    -0.16666666666666666,
];
/// cos r = 1 − z/2 + z²·C(z): degree 5, |error of C| ≤ 1.3e-18.
const COS: [f64; 6] = [
    -1.1382632425521717e-11,
    2.08761462684032e-09,
    -2.7557317271729793e-07,
    2.480158729876569e-05,
    -0.0013888888888887398,
    0.041666666666666664,
];
/// The same for results rounded to f32: degree 3, |error| ≤ 2.9e-11 (S) and 2.4e-12 (C),
/// below 2⁻³⁴ relative to the result.
const SIN_F32: [f64; 4] = [
    2.724992580305979e-06,
    -0.00019840086735384846,
    0.008333331874710208,
    -0.1666666666385529,
];
const COS_F32: [f64; 4] = [
    -2.730095920390147e-07,
    2.480060037715673e-05,
    -0.001388888767201679,
    0.0416666666643212,
];
/// eʳ = 1 + r + r²/2 + r³·E(r), |r| ≤ ln2/2: degree 9, |error of E| ≤ 8.1e-18.
const EXP: [f64; 10] = [
    2.091122972975856e-09,
    2.5100375832561234e-08,
    2.755728298405588e-07,
    2.7557268480310024e-06,
    2.4801587317135164e-05,
    0.00019841269863040545,
    0.0013888888888886554,
    0.008333333333330065,
    0.041666666666666664,
    0.16666666666666669,
];
/// ln(1 + f) = 2 atanh s, s = f / (2 + f), |s| ≤ (√2 − 1)/(√2 + 1): the part beyond 2s is
/// s·R with R = z·L(z), z = s²: degree 6, |error of L| ≤ 3.1e-16.
const LN: [f64; 7] = [
    0.14616449685043406,
    0.15331721600556042,
    0.18182889125261723,
    0.2222221113479508,
    0.28571428625975487,
    0.39999999999899505,
    0.666666666666667,
];
/// atan u = u + u·z·A(z), z = u², |u| ≤ 7/16: degree 11, |error of A| ≤ 3.9e-18.
const ATAN: [f64; 12] = [
    0.014773184616983806,
    -0.033128134256069586,
    0.04492259293193656,
    -0.05216679739313656,
    0.05876946456755061,
    -0.06666241923359964,
    0.07692285554889286,
    -0.09090908355602592,
    0.11111111096645038,
    -0.14285714285566806,
    0.1999999999999941,
    -0.3333333333333333,
];
/// asin s = s + s·z·P(z), z = s², |s| ≤ 1/2: degree 12, |error of P| ≤ 1.5e-17.
const ASIN: [f64; 13] = [
    0.028757851367421566,
    -0.014851887071247204,
    0.01740087944269402,
    0.005457506718640358,
    0.01032281435018578,
    0.011479177415184906,
    0.013971212973552933,
    0.017352392720869973,
    0.02237217294214989,
    0.030381944138531247,
    0.04464285714635543,
    0.07499999999998433,
    0.16666666666666669,
];

/// Σ c[i] z^(N−1−i) by Horner's rule, highest degree first: a fixed order of N − 1
/// multiplications and additions.
#[inline(always)]
fn horner<const N: usize>(z: f64, c: &[f64; N]) -> f64 {
    let mut p = c[0];
    for &ci in &c[1..] {
        p = p * z + ci;
    }
    p
}

/// v rounded to an integer (ties to even), as f64 and as i64, for |v| < 2⁵¹ (other inputs
/// give some integer, or NaN, deterministically): no libm `round`, no float-to-int
/// conversion whose out-of-range result differs between scalar and SIMD code.
#[inline(always)]
fn round_to_int(v: f64) -> (f64, i64) {
    let t = v + ROUND_SHIFT;
    let k = (t.to_bits() as i64).wrapping_sub(ROUND_SHIFT.to_bits() as i64);
    (t - ROUND_SHIFT, k)
}

/// x = k·π/2 + r + δ with |r| ≤ π/4 (a little more at the quadrant boundaries, from the
/// rounding of x·2/π), δ the rounding error of r (|δ| ≤ ulp(r)/2), and k mod 4. r + δ is
/// exact to about 2⁻⁶⁰ relative for |x| ≤ [`SIN_COS_LIMIT`].
#[inline(always)]
fn reduce_half_pi(x: f64) -> (f64, f64, i64) {
    let (k, ki) = round_to_int(x * FRAC_2_PI);
    // exact: k·PIO2_1 and k·PIO2_2 are exact and x − k·PIO2_1 cancels exactly (Sterbenz)
    let w = x - k * PIO2_1;
    let t = k * PIO2_2;
    let r1 = w - t;
    // the rounding error of w − t (exact: |t| ≤ |w| or the two are within a factor 2)
    let e1 = (w - r1) - t;
    let tail = e1 - k * PIO2_3;
    let r = r1 + tail;
    let delta = tail - (r - r1);
    (r, delta, ki & 3)
}

/// Places the reduced sine and cosine in the quadrant: (sin, cos) of r + n·π/2.
#[inline(always)]
fn quadrant(s: f64, c: f64, n: i64) -> (f64, f64) {
    let (s1, c1) = if n & 1 == 1 { (c, s) } else { (s, c) };
    // n = 1: (c, −s); n = 2: (−s, −c); n = 3: (−c, s): the sign bits are bit 1 of n and
    // of n + 1.
    let s_sign = ((n as u64) << 62) & (1 << 63);
    let c_sign = (((n + 1) as u64) << 62) & (1 << 63);
    (
        f64::from_bits(s1.to_bits() ^ s_sign),
        f64::from_bits(c1.to_bits() ^ c_sign),
    )
}

/// (sin x, cos x) in f64.
///
/// Algorithm: x = k·π/2 + r + δ by Cody and Waite's reduction with π/2 in three parts
/// (exact products for |k| < 2²⁰), δ the rounding error of r; then sin r = r + r·z·S(z) and
/// cos r = (1 − z/2) + z²·C(z) with z = r² and S, C of degree 5, δ added to first order,
/// and 1 − z/2's rounding error added back; the quadrant k mod 4 swaps and negates the pair.
///
/// Domain and accuracy: |x| ≤ 2¹⁹; measured max error 0.75 ulp (sin) and 0.75 ulp (cos) on
/// [−2π, 2π] and [−2¹⁹, 2¹⁹]; at most 1 ulp from glibc's on 10⁷ points of [−2π, 2π]. Above
/// 2¹⁹ it returns `std`'s result (the renderer's angles are at most a few π). NaN and ±∞ give NaN; sin(±0) = ±0
/// and cos(±0) = 1; subnormal x gives (x, 1).
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    if x.abs() > SIN_COS_LIMIT {
        return x.sin_cos();
    }
    let (r, delta, n) = reduce_half_pi(x);
    let z = r * r;
    let hz = 0.5 * z;
    // sin(r + δ) = sin r + δ cos r, cos(r + δ) = cos r − δ sin r, to first order in δ
    let s = r + (r * (z * horner(z, &SIN)) + delta * (1.0 - hz));
    // 1 − z/2 rounded, then its rounding error added back
    let w = 1.0 - hz;
    let c = w + (((1.0 - w) - hz) + ((z * z) * horner(z, &COS) - r * delta));
    // sin(±0) = ±0 (the reduction gives +0 for both).
    let s = if x == 0.0 { x } else { s };
    quadrant(s, c, n)
}

/// (sin x, cos x) in f32: a two-part Cody–Waite reduction in f64, degree-3 polynomials
/// evaluated in f64, each result rounded once to f32.
///
/// Domain and accuracy: |x| ≤ 2¹⁹ (beyond, `std`'s f32 sin_cos); measured on every f32 of
/// [−2π, 2π] (the renderer's angles: 2π·u, π·v, the concentric map's wedges): max error
/// 0.50020 ulp (sin) and 0.50021 ulp (cos), i.e. correctly rounded but within 2.2·10⁻⁴ ulp
/// of a tie. NaN and ±∞ give NaN; sin(±0) = ±0; subnormal x gives (x, 1).
#[inline]
pub fn sin_cosf(x: f32) -> (f32, f32) {
    if x.abs() > SIN_COS_LIMIT_F32 {
        return x.sin_cos();
    }
    let (s, c) = sin_cosf_f64(x as f64);
    (s as f32, c as f32)
}

/// [`sin_cosf`] above this |x| hands off to `std`.
pub(crate) const SIN_COS_LIMIT_F32: f32 = SIN_COS_LIMIT as f32;

/// f64 values side by side (a scalar `f64` or a SIMD register of them) with what
/// [`sin_cosf_f64`] does to them: the lane backends evaluate [`sin_cosf`] in f64 lanes by
/// the same operations, hence to the same bits.
pub(crate) trait F64Ops: Copy {
    /// i64 lanes (two's complement, wrapping).
    type I: Copy;
    fn splat(x: f64) -> Self;
    fn add(self, o: Self) -> Self;
    fn sub(self, o: Self) -> Self;
    fn mul(self, o: Self) -> Self;
    fn to_bits(self) -> Self::I;
    fn from_bits(i: Self::I) -> Self;
    fn splat_i(x: i64) -> Self::I;
    fn i_sub(a: Self::I, b: Self::I) -> Self::I;
    fn i_add(a: Self::I, b: Self::I) -> Self::I;
    fn i_and(a: Self::I, b: Self::I) -> Self::I;
    fn i_xor(a: Self::I, b: Self::I) -> Self::I;
    /// `a << 62`.
    fn i_shl62(a: Self::I) -> Self::I;
    /// `if n & 1 == 1 { a } else { b }` lane by lane.
    fn select_odd(n: Self::I, a: Self, b: Self) -> Self;
}

impl F64Ops for f64 {
    type I = i64;
    #[inline(always)]
    fn splat(x: f64) -> f64 {
        x
    }
    #[inline(always)]
    fn add(self, o: f64) -> f64 {
        self + o
    }
    #[inline(always)]
    fn sub(self, o: f64) -> f64 {
        self - o
    }
    #[inline(always)]
    fn mul(self, o: f64) -> f64 {
        self * o
    }
    #[inline(always)]
    fn to_bits(self) -> i64 {
        f64::to_bits(self) as i64
    }
    #[inline(always)]
    fn from_bits(i: i64) -> f64 {
        f64::from_bits(i as u64)
    }
    #[inline(always)]
    fn splat_i(x: i64) -> i64 {
        x
    }
    #[inline(always)]
    fn i_sub(a: i64, b: i64) -> i64 {
        a.wrapping_sub(b)
    }
    #[inline(always)]
    fn i_add(a: i64, b: i64) -> i64 {
        a.wrapping_add(b)
    }
    #[inline(always)]
    fn i_and(a: i64, b: i64) -> i64 {
        a & b
    }
    #[inline(always)]
    fn i_xor(a: i64, b: i64) -> i64 {
        a ^ b
    }
    #[inline(always)]
    fn i_shl62(a: i64) -> i64 {
        a << 62
    }
    #[inline(always)]
    fn select_odd(n: i64, a: f64, b: f64) -> f64 {
        if n & 1 == 1 {
            a
        } else {
            b
        }
    }
}

/// [`sin_cosf`]'s evaluation in f64 for |x| ≤ [`SIN_COS_LIMIT`] (x an f32 widened): the
/// reduction x = k·π/2 + r with two parts of π/2, enough for a result rounded to f32 (r's
/// absolute error is below |k|·2⁻⁸⁶ plus half an ulp of r; the `sin_cosf_ulp` sweep up to
/// 2¹⁹ checks what that leaves), the two polynomials and [`quadrant`]'s rule, written once
/// over [`F64Ops`] so that the scalar function and the lane backends share it.
#[inline(always)]
pub(crate) fn sin_cosf_f64<D: F64Ops>(x: D) -> (D, D) {
    let horner = |z: D, c: &[f64; 4]| {
        let mut p = D::splat(c[0]);
        for &ci in &c[1..] {
            p = p.mul(z).add(D::splat(ci));
        }
        p
    };
    // the reduction, with round_to_int's rounding
    let v = x.mul(D::splat(FRAC_2_PI));
    let t = v.add(D::splat(ROUND_SHIFT));
    let ki = D::i_sub(t.to_bits(), D::splat_i(ROUND_SHIFT.to_bits() as i64));
    let k = t.sub(D::splat(ROUND_SHIFT));
    let r = x.sub(k.mul(D::splat(PIO2_1))).sub(k.mul(D::splat(PIO2_2T)));
    let n = D::i_and(ki, D::splat_i(3));
    let z = r.mul(r);
    // r·(1 + z·S) rather than r + r·z·S: the same to 2⁻⁵¹, and sin(±0) = ±0
    let s = r.mul(D::splat(1.0).add(z.mul(horner(z, &SIN_F32))));
    let c = D::splat(1.0)
        .sub(D::splat(0.5).mul(z))
        .add(z.mul(z).mul(horner(z, &COS_F32)));
    // quadrant: n odd swaps; the sign bits are bit 1 of n and of n + 1
    let s1 = D::select_odd(n, c, s);
    let c1 = D::select_odd(n, s, c);
    let sign = D::splat_i(i64::MIN);
    let s_sign = D::i_and(D::i_shl62(n), sign);
    let c_sign = D::i_and(D::i_shl62(D::i_add(n, D::splat_i(1))), sign);
    (
        D::from_bits(D::i_xor(s1.to_bits(), s_sign)),
        D::from_bits(D::i_xor(c1.to_bits(), c_sign)),
    )
}

/// eˣ in f64.
///
/// Algorithm: x is clamped to [−746, 710] (beyond, the result is 0 or ∞ either way),
/// x = k·ln2 + r with k = round(x/ln2), |r| ≤ ln2/2, ln 2 in two parts (k·LN2_HI exact);
/// then eʳ = 1 + (r + (r²/2 + r³·E(r))) with E of degree 9, and the result is
/// eʳ · 2^⌊k/2⌋ · 2^(k − ⌊k/2⌋): two normal powers of two, so that a subnormal result is
/// rounded only once.
///
/// Domain and accuracy: all f64; measured max error 0.90 ulp on [−8, 0] (the gaussian
/// filter's arguments) and [−745, 709.7]; at most 1 ulp from glibc's on 10⁷ points of
/// [−8, 0]; subnormal results are within one subnormal step of e^x. NaN gives NaN, +∞ gives +∞, −∞ gives +0, ±0 and subnormal x give 1.
#[inline]
pub fn exp(x: f64) -> f64 {
    let x = x.clamp(-746.0, 710.0);
    let (k, ki) = round_to_int(x * LOG2_E);
    let r = (x - k * LN2_HI) - k * LN2_LO;
    let r2 = r * r;
    let p = 1.0 + (r + (0.5 * r2 + (r2 * r) * horner(r, &EXP)));
    let k1 = ki >> 1;
    let k2 = ki.wrapping_sub(k1);
    let scale = |e: i64| f64::from_bits((e.wrapping_add(1023) as u64) << 52);
    p * scale(k1) * scale(k2)
}

/// eˣ in f32: [`exp`] rounded to f32: correctly rounded on every 7th f32 of [−104, 89]
/// (max error 0.5 ulp), but for results in f32's subnormal range, rounded twice (within one
/// subnormal step).
#[inline]
pub fn expf(x: f32) -> f32 {
    exp(x as f64) as f32
}

/// ln x in f64.
///
/// Algorithm: x = 2ᵏ·m with m in [√½, √2) (from the bits; subnormals scaled by 2⁵⁴ first),
/// f = m − 1 (exact), s = f/(2 + f), z = s², R = z·L(z) with L of degree 6; ln(1 + f) =
/// 2 atanh s = f − (f²/2 − s·(f²/2 + R)), and ln x = k·LN2_HI + (ln(1 + f) + k·LN2_LO) with
/// the two-part ln 2 of [`exp`].
///
/// Domain and accuracy: x > 0; measured max error 0.76 ulp on 2⁻¹⁰⁰⁰–2¹⁰⁰⁰ and [½, 2]; at
/// most 1 ulp from glibc's on 10⁷ points of [½, 2].
/// ln(±0) = −∞, ln(x < 0) = NaN, ln(NaN) = NaN, ln(+∞) = +∞; subnormal x is exact to the same
/// bound.
#[inline]
pub fn ln(x: f64) -> f64 {
    let subnormal = x < f64::MIN_POSITIVE;
    let xs = if subnormal {
        x * 18_014_398_509_481_984.0
    } else {
        x
    }; // 2⁵⁴
    let bits = xs.to_bits();
    // The bits of √½: subtracting them carries into the exponent exactly when m ≥ √2.
    let tmp = bits.wrapping_sub(0x3FE6_A09E_667F_3BCD);
    let k = ((tmp as i64) >> 52) - if subnormal { 54 } else { 0 };
    let m = f64::from_bits(bits.wrapping_sub(tmp & (0xFFF << 52)));
    let f = m - 1.0;
    let s = f / (2.0 + f);
    let z = s * s;
    let r = z * horner(z, &LN);
    let hfsq = 0.5 * f * f;
    let kf = k as f64;
    let y = kf * LN2_HI + (f - (hfsq - (s * (hfsq + r) + kf * LN2_LO)));
    if x == f64::INFINITY {
        x
    } else if x == 0.0 {
        f64::NEG_INFINITY
    } else if x > 0.0 {
        y
    } else {
        f64::NAN
    }
}

/// ln x in f32: [`ln`] rounded to f32: correctly rounded on every 7th positive f32.
#[inline]
pub fn lnf(x: f32) -> f32 {
    ln(x as f64) as f32
}

/// atan2(y, x) in f64: the angle of (x, y) in [−π, π].
///
/// Algorithm: with n = min(|x|, |y|) and d = max(|x|, |y|), θ = atan(n/d) ∈ [0, π/4] is
/// atan u (n/d < 7/16, u = n/d), atan ½ + atan u (n/d < 11/16, u = (2n − d)/(2d + n)) or
/// π/4 + atan u (u = (n − d)/(n + d)); 2n − d and n − d are exact (Sterbenz), |u| ≤ 7/16,
/// and atan u = u + u·z·A(z), z = u², A of degree 11. The angle is then c + σθ: c = 0,
/// σ = 1 for |y| ≤ |x|, x ≥ 0; c = π/2, σ = −1 for |y| > |x|, x ≥ 0; c = π, σ = −1 for
/// |y| ≤ |x|, x < 0 (or −0); c = π/2, σ = 1 for |y| > |x|, x < 0; and it takes y's sign.
/// c + σθ is summed as c_hi + (σ·off_hi + (c_lo + σ·(off_lo + atan u))), the constants in
/// two parts, so only the last two additions round at the result's scale.
///
/// Domain and accuracy: all (y, x); measured max error 1.31 ulp over angles in [−π, π] at
/// magnitudes 2⁻³⁰–2³⁰; at most 1 ulp from glibc's on 10⁷ points of the unit circle. IEEE's special values: atan2(±0, +0)
/// = ±0, atan2(±0, −0) = ±π, ±∞ arguments give the multiples of π/4, NaN gives NaN.
#[inline]
pub fn atan2(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let swap = ay > ax;
    let (n, d) = if swap { (ax, ay) } else { (ay, ax) };
    // Both zero: the angle of (1, 0); both infinite: of (1, 1).
    let (n, d) = if d == 0.0 {
        (0.0, 1.0)
    } else if n == f64::INFINITY {
        (1.0, 1.0)
    } else {
        (n, d)
    };
    let t = n / d;
    let (u, off_hi, off_lo) = if t < 0.4375 {
        (t, 0.0, 0.0)
    } else if t < 0.6875 {
        ((2.0 * n - d) / (2.0 * d + n), ATAN_HALF_HI, ATAN_HALF_LO)
    } else {
        ((n - d) / (n + d), FRAC_PI_4_HI, FRAC_PI_4_LO)
    };
    let z = u * u;
    let a = u + u * (z * horner(z, &ATAN));
    let negative_x = x.is_sign_negative();
    let (c_hi, c_lo) = if swap {
        (FRAC_PI_2_HI, FRAC_PI_2_LO)
    } else if negative_x {
        (PI_HI, PI_LO)
    } else {
        (0.0, 0.0)
    };
    let sigma = if swap == negative_x { 1.0 } else { -1.0 };
    let angle = c_hi + (sigma * off_hi + (c_lo + sigma * (off_lo + a)));
    angle.copysign(y)
}

/// atan2(y, x) in f32: [`atan2`] on the exact f64 values, rounded to f32: max error 0.4999998
/// ulp on 10⁷ points (angles in [−π, π], magnitudes 2⁻³⁰–2³⁰).
#[inline]
pub fn atan2f(y: f32, x: f32) -> f32 {
    atan2(y as f64, x as f64) as f32
}

/// acos x in f64, in [0, π].
///
/// Algorithm: for |x| ≤ ½, acos x = π/2 − asin x; above, with s = √((1 − |x|)/2) (1 − |x| is
/// exact), acos x = 2 asin s for x > 0 and π − 2 asin s for x < 0; asin s = s + s·z·P(z),
/// z = s², P of degree 12. π/2 and π are added in two parts.
///
/// Domain and accuracy: [−1, 1]; measured max error 1.03 ulp (points of [−1, 1], half of
/// them crowded towards ±1 as ±(1 − u⁸)); at most 1 ulp from glibc's on 10⁷ points. |x| > 1 and NaN give NaN; acos(±0) = π/2.
#[inline]
pub fn acos(x: f64) -> f64 {
    let ax = x.abs();
    let small = ax <= 0.5;
    let z = if small { x * x } else { (1.0 - ax) * 0.5 };
    let s = if small { x } else { z.sqrt() };
    let p = s + s * (z * horner(z, &ASIN));
    if small {
        FRAC_PI_2_HI - (p - FRAC_PI_2_LO)
    } else if x > 0.0 {
        2.0 * p
    } else {
        PI_HI - (2.0 * p - PI_LO)
    }
}

/// acos x in f32: [`acos`] rounded to f32: correctly rounded on every 7th f32 of [−1, 1].
#[inline]
pub fn acosf(x: f32) -> f32 {
    acos(x as f64) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// |got − exact| in units of the last place of f32 at `exact` (f32's subnormal spacing
    /// below its smallest normal).
    fn ulps_f32(got: f32, exact: f64) -> f64 {
        // beyond f32's range by at least half an ulp of f32::MAX: ∞ is the rounded value
        let overflow = f32::MAX as f64 * (1.0 + f32::EPSILON as f64 / 2.0);
        if got as f64 == exact
            || (exact.abs() >= overflow && got as f64 == exact.signum() * f64::INFINITY)
        {
            return 0.0;
        }
        let e = exact.abs().max(f32::MIN_POSITIVE as f64);
        let ulp = 2f64.powi(e.log2().floor() as i32 - 23);
        (got as f64 - exact).abs() / ulp
    }

    /// |got − reference| in units of the last place of f64 at `reference`.
    fn ulps_f64(got: f64, reference: f64) -> f64 {
        if got == reference {
            return 0.0;
        }
        // 2^(exponent of reference − 52), at least the smallest subnormal
        let binade = f64::from_bits(reference.abs().to_bits() & 0x7FF0_0000_0000_0000);
        let ulp = (binade * f64::EPSILON).max(f64::from_bits(1));
        (got - reference).abs() / ulp
    }

    /// Every `stride`-th f32 in [lo, hi] (lo ≤ 0 ≤ hi or both of one sign), both signs
    /// walked from zero outwards, plus the two ends.
    fn sweep_f32(lo: f32, hi: f32, stride: u32, mut f: impl FnMut(f32)) {
        let walk = |from: f32, to: f32, f: &mut dyn FnMut(f32)| {
            // from and to of one sign, |from| ≤ |to|
            let (a, b) = (from.to_bits(), to.to_bits());
            let mut bits = a;
            while bits <= b {
                f(f32::from_bits(bits));
                bits = match bits.checked_add(stride) {
                    Some(n) => n,
                    None => break,
                };
            }
            f(to);
        };
        if hi >= 0.0 {
            walk(lo.max(0.0), hi, &mut f);
        }
        if lo < 0.0 {
            walk(hi.min(-0.0), lo, &mut f);
        }
    }

    /// A fixed-seed stream of f64 in [lo, hi) (uniform), from splitmix64.
    fn uniform_f64(seed: u64, n: usize, lo: f64, hi: f64) -> impl Iterator<Item = f64> {
        let mut s = seed;
        (0..n).map(move |_| {
            s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = s;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            lo + (hi - lo) * ((z >> 11) as f64 * 2f64.powi(-53))
        })
    }

    /// A dense stride in release builds, a sparse one in debug builds (same code path).
    fn stride(release: u32) -> u32 {
        if cfg!(debug_assertions) {
            release * 64
        } else {
            release
        }
    }

    /// Max error of `f` against `reference` (both f32 in, the reference in f64).
    fn max_f32(
        lo: f32,
        hi: f32,
        step: u32,
        f: impl Fn(f32) -> f32,
        reference: impl Fn(f64) -> f64,
    ) -> (f64, f32) {
        let mut worst = (0.0, 0.0);
        sweep_f32(lo, hi, step, |x| {
            let e = ulps_f32(f(x), reference(x as f64));
            // (a NaN error counts as the worst)
            if e.is_nan() || e > worst.0 {
                worst = (e, x);
            }
        });
        worst
    }

    /// sin and cos rounded to f32 over [−2π, 2π] (every angle the renderer samples: 2π·u,
    /// π·v, the concentric map's π/4-wide wedges): within 0.5 ulp + 2⁻¹⁰ of sin and cos,
    /// i.e. correctly rounded but where the exact value lies within 2⁻¹⁰ ulp of a tie.
    #[test]
    fn sin_cosf_ulp() {
        let bound = 0.5 + 2f64.powi(-10);
        let two_pi = (2.0 * PI) as f32;
        let s = max_f32(-two_pi, two_pi, stride(61), |x| sin_cosf(x).0, f64::sin);
        let c = max_f32(-two_pi, two_pi, stride(61), |x| sin_cosf(x).1, f64::cos);
        assert!(s.0 <= bound && c.0 <= bound, "sin {s:?}, cos {c:?}");
        // and beyond, up to the hand-off to std at 2¹⁹ (a sparser sweep)
        let s = max_f32(
            -524_288.0,
            524_288.0,
            stride(4099),
            |x| sin_cosf(x).0,
            f64::sin,
        );
        let c = max_f32(
            -524_288.0,
            524_288.0,
            stride(4099),
            |x| sin_cosf(x).1,
            f64::cos,
        );
        assert!(s.0 <= bound && c.0 <= bound, "sin {s:?}, cos {c:?}");
    }

    /// sin and cos in f64 within 1.5 ulp of glibc's (itself within 0.52 ulp of the exact
    /// value: `validation/math/ulp_f64.py` measures ours against 50-digit values).
    #[test]
    fn sin_cos_ulp() {
        let n = if cfg!(debug_assertions) {
            20_000
        } else {
            2_000_000
        };
        let mut worst = (0.0f64, 0.0f64, 0.0f64);
        for (range, seed) in [(2.0 * PI, 1), (524_288.0, 2)] {
            for x in uniform_f64(seed, n, -range, range) {
                let (s, c) = sin_cos(x);
                let es = ulps_f64(s, x.sin());
                let ec = ulps_f64(c, x.cos());
                if es.max(ec) > worst.0 {
                    worst = (es.max(ec), x, es);
                }
            }
        }
        assert!(worst.0 <= 1.5, "{worst:?}");
    }

    /// e^x in f64 on the gaussian filter's arguments [−8, 0] and on the whole range, and
    /// rounded to f32 on every f32 from f32's underflow to its overflow (sparse sweep).
    #[test]
    fn exp_ulp() {
        let n = if cfg!(debug_assertions) {
            20_000
        } else {
            2_000_000
        };
        let mut worst = (0.0f64, 0.0f64);
        for (lo, hi, seed) in [(-8.0, 0.0, 3), (-708.0, 709.78, 4), (-1e-6, 1e-6, 5)] {
            for x in uniform_f64(seed, n, lo, hi) {
                let e = ulps_f64(exp(x), x.exp());
                if e > worst.0 {
                    worst = (e, x);
                }
            }
        }
        assert!(worst.0 <= 1.5, "{worst:?}");
        let f = max_f32(-87.0, 88.7, stride(257), expf, f64::exp);
        assert!(f.0 <= 0.5 + 2f64.powi(-10), "{f:?}");
    }

    /// ln in f64 over every binade of the normal and subnormal range, and rounded to f32.
    #[test]
    fn ln_ulp() {
        let n = if cfg!(debug_assertions) {
            20_000
        } else {
            2_000_000
        };
        let mut worst = (0.0f64, 0.0f64);
        for (k, u) in uniform_f64(6, n, 0.0, 1.0).enumerate() {
            let e2 = -1074 + (k % 2098) as i32;
            let x = (1.0 + u)
                * 2f64.powi(e2.max(-1022))
                * if e2 < -1022 {
                    2f64.powi(e2 + 1022)
                } else {
                    1.0
                };
            let e = ulps_f64(ln(x), x.ln());
            if e > worst.0 {
                worst = (e, x);
            }
        }
        for x in uniform_f64(7, n, 0.5, 2.0) {
            let e = ulps_f64(ln(x), x.ln());
            if e > worst.0 {
                worst = (e, x);
            }
        }
        assert!(worst.0 <= 1.5, "{worst:?}");
        let f = max_f32(1e-30, 1e30, stride(257), lnf, f64::ln);
        assert!(f.0 <= 0.5 + 2f64.powi(-10), "{f:?}");
    }

    /// atan2 in f64 over all angles at magnitudes 2⁻³⁰–2³⁰, and rounded to f32.
    #[test]
    fn atan2_ulp() {
        let n = if cfg!(debug_assertions) {
            20_000
        } else {
            2_000_000
        };
        let mut worst = (0.0f64, 0.0f64, 0.0f64);
        let mut worst32 = (0.0f64, 0.0f32, 0.0f32);
        let angles = uniform_f64(8, n, -PI, PI);
        let scales = uniform_f64(9, n, -30.0, 30.0);
        for (a, m) in angles.zip(scales) {
            let r = 2f64.powf(m);
            let (y, x) = (r * a.sin(), r * a.cos());
            let e = ulps_f64(atan2(y, x), y.atan2(x));
            if e > worst.0 {
                worst = (e, y, x);
            }
            let (y, x) = (y as f32, x as f32);
            let e = ulps_f32(atan2f(y, x), (y as f64).atan2(x as f64));
            if e > worst32.0 {
                worst32 = (e, y, x);
            }
        }
        assert!(worst.0 <= 2.0, "{worst:?}");
        assert!(worst32.0 <= 0.5 + 2f64.powi(-10), "{worst32:?}");
    }

    /// acos in f64 on [−1, 1] (densest near ±1, where it is steep), and rounded to f32 on
    /// every f32 of [−1, 1] (sparse sweep).
    #[test]
    fn acos_ulp() {
        let n = if cfg!(debug_assertions) {
            20_000
        } else {
            2_000_000
        };
        let mut worst = (0.0f64, 0.0f64);
        for (k, u) in uniform_f64(10, n, -1.0, 1.0).enumerate() {
            let x = if k % 2 == 0 {
                u
            } else {
                u.signum() * (1.0 - u.abs().powi(8))
            };
            let e = ulps_f64(acos(x), x.acos());
            if e > worst.0 {
                worst = (e, x);
            }
        }
        assert!(worst.0 <= 1.5, "{worst:?}");
        let f = max_f32(-1.0, 1.0, stride(257), acosf, f64::acos);
        assert!(f.0 <= 0.5 + 2f64.powi(-10), "{f:?}");
    }

    /// The figures quoted in the documentation: every f32 of each f32 function's domain
    /// (minutes in a release build; `cargo test --release --lib elementary::tests::measure_ulp_exhaustive
    /// -- --ignored --nocapture`), and the f64 functions on 10⁸ points each against glibc.
    /// Optionally writes inputs and results for `validation/math/ulp_f64.py`
    /// (PENUMBRA_ULP_DUMP=file).
    #[test]
    #[ignore = "a measurement, not a test: left out of the full tier (--skip measure_)"]
    fn measure_ulp_exhaustive() {
        // PENUMBRA_ULP_STRIDE=k: every k-th f32 of exp, ln and acos (default 1: all of them)
        let k = std::env::var("PENUMBRA_ULP_STRIDE").map_or(1, |s| s.parse().unwrap());
        let two_pi = (2.0 * PI) as f32;
        let sin = max_f32(-two_pi, two_pi, 1, |x| sin_cosf(x).0, f64::sin);
        println!("sinf [-2pi, 2pi], every f32: {sin:?}");
        let cos = max_f32(-two_pi, two_pi, 1, |x| sin_cosf(x).1, f64::cos);
        println!("cosf [-2pi, 2pi], every f32: {cos:?}");
        let e = max_f32(-104.0, 89.0, k, expf, f64::exp);
        println!("expf [-104, 89], stride {k}: {e:?}");
        let l = max_f32(f32::from_bits(1), f32::MAX, k, lnf, f64::ln);
        println!("lnf (0, inf), stride {k}: {l:?}");
        let a = max_f32(-1.0, 1.0, k, acosf, f64::acos);
        println!("acosf [-1, 1], stride {k}: {a:?}");
        let n = 10_000_000;
        let worst =
            |name: &str, xs: &mut dyn Iterator<Item = f64>, f: &dyn Fn(f64) -> (f64, f64)| {
                let mut w = (0.0f64, 0.0f64);
                for x in xs {
                    let (got, want) = f(x);
                    let e = ulps_f64(got, want);
                    if e > w.0 {
                        w = (e, x);
                    }
                }
                println!("{name} vs glibc {w:?}");
            };
        worst(
            "sin [-2pi, 2pi]",
            &mut uniform_f64(11, n, -2.0 * PI, 2.0 * PI),
            &|x| (sin_cos(x).0, x.sin()),
        );
        worst(
            "cos [-2pi, 2pi]",
            &mut uniform_f64(12, n, -2.0 * PI, 2.0 * PI),
            &|x| (sin_cos(x).1, x.cos()),
        );
        worst("exp [-8, 0]", &mut uniform_f64(13, n, -8.0, 0.0), &|x| {
            (exp(x), x.exp())
        });
        worst("ln [0.5, 2]", &mut uniform_f64(14, n, 0.5, 2.0), &|x| {
            (ln(x), x.ln())
        });
        worst("acos [-1, 1]", &mut uniform_f64(15, n, -1.0, 1.0), &|x| {
            (acos(x), x.acos())
        });
        worst("atan2 angles", &mut uniform_f64(16, n, -PI, PI), &|a| {
            let (y, x) = (a.sin(), a.cos());
            (atan2(y, x), y.atan2(x))
        });
        let mut w32 = (0.0f64, 0.0f32, 0.0f32);
        for (a, m) in uniform_f64(17, n, -PI, PI).zip(uniform_f64(18, n, -30.0, 30.0)) {
            let r = 2f64.powf(m);
            let (y, x) = ((r * a.sin()) as f32, (r * a.cos()) as f32);
            let e = ulps_f32(atan2f(y, x), (y as f64).atan2(x as f64));
            if e > w32.0 {
                w32 = (e, y, x);
            }
        }
        println!("atan2f {w32:?}");
        if let Ok(path) = std::env::var("PENUMBRA_ULP_DUMP") {
            use std::io::Write;
            let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
            let m = 20_000;
            let mut put = |name: &str, args: &[f64], got: f64| {
                write!(out, "{name}").unwrap();
                for a in args {
                    write!(out, " {:016x}", a.to_bits()).unwrap();
                }
                writeln!(out, " {:016x}", got.to_bits()).unwrap();
            };
            for x in uniform_f64(21, m, -2.0 * PI, 2.0 * PI).chain(uniform_f64(
                22,
                m / 4,
                -524_288.0,
                524_288.0,
            )) {
                put("sin", &[x], sin_cos(x).0);
                put("cos", &[x], sin_cos(x).1);
            }
            for x in uniform_f64(23, m, -8.0, 0.0).chain(uniform_f64(24, m / 4, -745.0, 709.7)) {
                put("exp", &[x], exp(x));
            }
            for (k, u) in uniform_f64(25, m, 0.0, 1.0).enumerate() {
                let x = (1.0 + u) * 2f64.powi(-1000 + (k % 2000) as i32);
                put("ln", &[x], ln(x));
            }
            for x in uniform_f64(26, m, 0.5, 2.0) {
                put("ln", &[x], ln(x));
            }
            for (a, mg) in uniform_f64(27, m, -PI, PI).zip(uniform_f64(28, m, -30.0, 30.0)) {
                let r = 2f64.powf(mg);
                let (y, x) = (r * a.sin(), r * a.cos());
                put("atan2", &[y, x], atan2(y, x));
            }
            for (k, u) in uniform_f64(29, m, -1.0, 1.0).enumerate() {
                let x = if k % 2 == 0 {
                    u
                } else {
                    u.signum() * (1.0 - u.abs().powi(8))
                };
                put("acos", &[x], acos(x));
            }
        }
    }

    /// NaN, infinities, signed zeros and subnormals, as documented.
    #[test]
    fn special_values() {
        let nan = f64::NAN;
        let inf = f64::INFINITY;
        let tiny = f64::from_bits(1); // the smallest subnormal
        for x in [nan, inf, -inf] {
            let (s, c) = sin_cos(x);
            assert!(s.is_nan() && c.is_nan(), "{x}");
            let (s, c) = sin_cosf(x as f32);
            assert!(s.is_nan() && c.is_nan(), "{x}");
        }
        assert_eq!(sin_cos(0.0).0.to_bits(), 0.0f64.to_bits());
        assert_eq!(sin_cos(-0.0).0.to_bits(), (-0.0f64).to_bits());
        assert_eq!(sin_cos(-0.0).1, 1.0);
        assert_eq!(sin_cosf(-0.0).0.to_bits(), (-0.0f32).to_bits());
        assert_eq!(sin_cos(-tiny), (-tiny, 1.0));
        let tiny32 = f32::from_bits(1);
        assert_eq!(sin_cosf(tiny32), (tiny32, 1.0));
        // beyond the reduction's range: std's value
        assert_eq!(sin_cos(1e10), 1e10f64.sin_cos());

        assert!(exp(nan).is_nan());
        assert_eq!(exp(inf), inf);
        assert_eq!(exp(-inf).to_bits(), 0);
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(exp(-0.0), 1.0);
        assert_eq!(exp(tiny), 1.0);
        assert_eq!(exp(709.79), inf);
        assert_eq!(exp(1000.0), inf);
        assert_eq!(exp(-746.0), 0.0);
        assert_eq!(exp(-1000.0), 0.0);
        // the subnormal range, rounded once: e^−740 = 4.2e−322 (85 subnormal steps)
        let want = (-740.0f64).exp();
        assert!(
            (exp(-740.0) - want).abs() <= tiny,
            "{} vs {want}",
            exp(-740.0)
        );
        assert_eq!(expf(-200.0), 0.0);
        assert_eq!(expf(100.0), f32::INFINITY);

        assert_eq!(ln(1.0), 0.0);
        assert_eq!(ln(0.0), -inf);
        assert_eq!(ln(-0.0), -inf);
        assert!(ln(-1.0).is_nan() && ln(nan).is_nan() && ln(-inf).is_nan());
        assert_eq!(ln(inf), inf);
        assert!(ulps_f64(ln(tiny), tiny.ln()) <= 1.0);
        assert!(ulps_f64(ln(f64::MAX), f64::MAX.ln()) <= 1.0);
        assert_eq!(
            lnf(f32::from_bits(1)),
            (f32::from_bits(1) as f64).ln() as f32
        );

        for (y, x, want) in [
            (0.0, 0.0, 0.0),
            (-0.0, 0.0, -0.0),
            (0.0, -0.0, PI),
            (-0.0, -0.0, -PI),
            (1.0, 0.0, PI / 2.0),
            (-1.0, -0.0, -PI / 2.0),
            (0.0, -1.0, PI),
            (-0.0, -1.0, -PI),
            (inf, inf, PI / 4.0),
            (inf, -inf, 3.0 * PI / 4.0),
            (-inf, -inf, -3.0 * PI / 4.0),
            (1.0, inf, 0.0),
            (1.0, -inf, PI),
            (-inf, 1.0, -PI / 2.0),
        ] {
            let got = atan2(y, x);
            assert_eq!(got.to_bits(), want.to_bits(), "atan2({y}, {x}) = {got}");
            assert_eq!(
                got.to_bits(),
                y.atan2(x).to_bits(),
                "std differs at ({y}, {x})"
            );
        }
        assert!(atan2(nan, 1.0).is_nan() && atan2(1.0, nan).is_nan());

        assert_eq!(acos(1.0).to_bits(), 0);
        assert_eq!(acos(-1.0), PI);
        assert_eq!(acos(0.0), PI / 2.0);
        assert_eq!(acos(-0.0), PI / 2.0);
        assert!(acos(1.0 + f64::EPSILON).is_nan() && acos(-2.0).is_nan() && acos(nan).is_nan());
    }
}
