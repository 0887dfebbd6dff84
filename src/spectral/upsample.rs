//! RGB reflectances as smooth spectra: the sigmoid-polynomial model of Jakob and Hanika, "A
//! Low-Dimensional Function Space for Efficient Spectral Upsampling" (Computer Graphics Forum
//! 38(2), 2019), as Mitsuba 3.9.1 uses it (`srgb_model_eval`, `srgb_model_mean`,
//! `srgb_model_fetch` in `mitsuba/render/srgb.h`, the lookup of its `rgb2spec` library).
//!
//! A colour maps to three coefficients `c` and the spectrum
//! `S(λ) = ½ + ½ x / √(1 + x²)`, `x = (c₀λ + c₁)λ + c₂` (λ in nm), always in [0, 1].
//!
//! The coefficients come from a table of 3 × 64³ entries: which channel is largest picks one
//! of three blocks; that channel's value `z` is located on the nonlinear brightness axis
//! [`brightness`](super::fit::brightness); the other two channels, as fractions of `z` (taken
//! cyclically after the largest), scaled to [0, 63], give the two other axes; the coefficients
//! are interpolated trilinearly between the 8 surrounding entries. Greys (r = g = b) skip the
//! table: black gives `c₂ = −8192`, white `+8192` (0 and 1 in single precision), a grey `v`
//! the constant spectrum `c₂ = (v − ½)/√(v(1 − v))`. Channels are clamped to [0, 1] first.
//!
//! # How the table is obtained
//!
//! penumbra fits the table itself ([`fit`](super::fit)) and fits it lazily, one column (the 64
//! brightness entries of one block at one pair of ratios) at a time, on first use: a lookup
//! needs 4 columns, each solved once per process and memoised in a [`OnceLock`] (thread-safe;
//! a column is a pure function of its indices, so results do not depend on which thread or in
//! which order columns are fitted). A scene with a handful of colours fits a few dozen columns
//! (about 2-3 ms each in release builds here); the whole table (12288 columns) is never needed
//! at once, nothing is stored on disk and nothing is computed at build time.

use std::sync::{LazyLock, OnceLock};

use glam::Vec4;

use super::fit::{brightness, fit_column, RES};

/// The coefficients of one colour's spectrum (nm domain), as [`srgb_model_eval`] takes them.
pub type Coefficients = [f32; 3];

/// `S(λ)` of the coefficients at four wavelengths (nm): Mitsuba's `srgb_model_eval`, in `f32`.
/// An infinite `c₂` gives 0 or 1 (its sign), as in Mitsuba.
#[inline]
pub fn srgb_model_eval(c: Coefficients, wavelengths: Vec4) -> Vec4 {
    if c[2].is_infinite() {
        return Vec4::splat(if c[2] > 0.0 { 1.0 } else { 0.0 });
    }
    let x = (Vec4::splat(c[0]) * wavelengths + Vec4::splat(c[1])) * wavelengths + Vec4::splat(c[2]);
    let s = (0.5 * x) * (x * x + Vec4::ONE).sqrt().recip() + Vec4::splat(0.5);
    s.max(Vec4::ZERO)
}

/// The mean of `S(λ)` over [360, 830] nm as Mitsuba estimates it (`srgb_model_mean`): the
/// average at 16 evenly spaced wavelengths, both ends included. Mitsuba's `eval_1` and
/// `mean()` of an `srgb` texture in spectral mode.
pub fn srgb_model_mean(c: Coefficients) -> f32 {
    let step = (830.0_f32 - 360.0) / 15.0;
    let mut sum = 0.0;
    for q in 0..4 {
        let base = (4 * q) as f32;
        let w = Vec4::new(
            360.0 + base * step,
            360.0 + (base + 1.0) * step,
            360.0 + (base + 2.0) * step,
            360.0 + (base + 3.0) * step,
        );
        let v = srgb_model_eval(c, w);
        sum += ((v.x + v.y) + v.z) + v.w;
    }
    sum / 16.0
}

/// Closed form for greys (r = g = b after clamping), as Mitsuba's rgb2spec has it.
fn grey(v: f32) -> Coefficients {
    let c2 = if v <= 0.0 {
        -8192.0
    } else if v >= 1.0 {
        8192.0
    } else {
        (v - 0.5) / (v * (1.0 - v)).sqrt()
    };
    [0.0, 0.0, c2]
}

/// The lazily fitted table: one slot per column (block, j, i).
static COLUMNS: LazyLock<Vec<OnceLock<Box<[Coefficients; RES]>>>> =
    LazyLock::new(|| (0..3 * RES * RES).map(|_| OnceLock::new()).collect());

/// Column (block `largest`, ratio indices `j`, `i`), fitted on first use.
fn column(largest: usize, j: usize, i: usize) -> &'static [Coefficients; RES] {
    COLUMNS[(largest * RES + j) * RES + i].get_or_init(|| Box::new(fit_column(largest, j, i)))
}

/// The brightness axis as f32 values.
static SCALE: LazyLock<[f32; RES]> = LazyLock::new(|| std::array::from_fn(brightness));

/// Index of the brightness interval holding `z`: the last `k ≤ RES − 2` with `scale[k] ≤ z`.
fn interval(z: f32) -> usize {
    let scale = &*SCALE;
    scale[1..RES - 1].partition_point(|&s| s <= z)
}

/// The coefficients of an sRGB reflectance: Mitsuba's `srgb_model_fetch` (rgb2spec's lookup),
/// with penumbra's own fitted table. Components are clamped to [0, 1]; NaN counts as 0.
pub fn srgb_model_fetch(rgb: [f32; 3]) -> Coefficients {
    // `max(min(x, 1), 0)` in C order: NaN becomes 0 here (C would keep it; penumbra never
    // passes NaN on).
    let rgb = rgb.map(|v| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) });
    if rgb[0] == rgb[1] && rgb[1] == rgb[2] {
        return grey(rgb[0]);
    }
    // The largest channel; ties go to the later channel, as in rgb2spec.
    let mut largest = 0;
    for k in 1..3 {
        if rgb[k] >= rgb[largest] {
            largest = k;
        }
    }
    let z = rgb[largest];
    let scale = (RES - 1) as f32 / z;
    let x = rgb[(largest + 1) % 3] * scale;
    let y = rgb[(largest + 2) % 3] * scale;
    let xi = (x as usize).min(RES - 2);
    let yi = (y as usize).min(RES - 2);
    let zi = interval(z);
    let s = &*SCALE;
    let (x1, y1) = (x - xi as f32, y - yi as f32);
    let z1 = (z - s[zi]) / (s[zi + 1] - s[zi]);
    let (x0, y0, z0) = (1.0 - x1, 1.0 - y1, 1.0 - z1);
    let c00 = column(largest, yi, xi);
    let c01 = column(largest, yi, xi + 1);
    let c10 = column(largest, yi + 1, xi);
    let c11 = column(largest, yi + 1, xi + 1);
    std::array::from_fn(|n| {
        let at = |k: usize| {
            (c00[k][n] * x0 + c01[k][n] * x1) * y0 + (c10[k][n] * x0 + c11[k][n] * x1) * y1
        };
        at(zi) * z0 + at(zi + 1) * z1
    })
}

/// An unbounded colour as Mitsuba's spectral variants store it in an `envmap` or a
/// three-channel `gridvolume`: the scale s = 2 max(rgb) and the coefficients of
/// rgb / max(s, 10⁻⁸) (a reflectance in [0, ½]) given by `fetch`, as `[c₀, c₁, c₂, s]`; the
/// colour's spectrum is s · S(λ).
pub fn scaled_coefficients_with(
    rgb: [f32; 3],
    fetch: impl FnOnce([f32; 3]) -> Coefficients,
) -> [f32; 4] {
    let s = rgb[0].max(rgb[1]).max(rgb[2]) * 2.0;
    let d = s.max(1e-8);
    let c = fetch([rgb[0] / d, rgb[1] / d, rgb[2] / d]);
    [c[0], c[1], c[2], s]
}

/// [`scaled_coefficients_with`] penumbra's own upsampling ([`srgb_model_fetch`]).
pub fn scaled_coefficients(rgb: [f32; 3]) -> [f32; 4] {
    scaled_coefficients_with(rgb, srgb_model_fetch)
}

/// Fits every column of the table now (in parallel with rayon) instead of on first use; for
/// measuring the table's cost and comparing it with Mitsuba's whole table.
pub fn fit_whole_table() {
    use rayon::prelude::*;
    (0..3 * RES * RES).into_par_iter().for_each(|c| {
        column(c / (RES * RES), (c / RES) % RES, c % RES);
    });
}

/// The table entry (block `largest`, brightness index `k`, ratio indices `j`, `i`), fitting
/// its column if needed: for comparisons with Mitsuba's table.
pub fn table_entry(largest: usize, k: usize, j: usize, i: usize) -> Coefficients {
    column(largest, j, i)[k]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn greys_are_flat() {
        let w = Vec4::new(360.0, 450.0, 600.0, 830.0);
        for v in [0.0, 0.1, 0.5, 0.77, 1.0] {
            let s = srgb_model_eval(srgb_model_fetch([v, v, v]), w);
            for l in s.to_array() {
                assert!((l - v).abs() < 1e-6, "grey {v}: {s}");
            }
        }
        // Clamped first: (2, 2, 2) is white, (-1, -1, -1) black.
        assert_eq!(srgb_model_fetch([2.0; 3]), [0.0, 0.0, 8192.0]);
        assert_eq!(srgb_model_fetch([-1.0; 3]), [0.0, 0.0, -8192.0]);
    }

    #[test]
    fn infinite_constant_is_a_step() {
        let w = Vec4::splat(500.0);
        assert_eq!(srgb_model_eval([0.0, 0.0, f32::INFINITY], w), Vec4::ONE);
        assert_eq!(
            srgb_model_eval([0.0, 0.0, f32::NEG_INFINITY], w),
            Vec4::ZERO
        );
    }

    #[test]
    fn interval_brackets() {
        let s = &*SCALE;
        for z in [1e-6, 0.001, 0.3, 0.5, 0.999, 1.0] {
            let k = interval(z);
            assert!(
                k <= RES - 2 && s[k] <= z && (z <= s[k + 1] || k == RES - 2),
                "{z}: {k}"
            );
        }
    }
}
