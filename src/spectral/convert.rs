//! The four values a path carries at its four wavelengths turned into a colour, as Mitsuba
//! 3.9.1's spectral variants do (`cie1931_xyz`, `cie1931_y`, `linear_rgb_rec`,
//! `spectrum_to_xyz`, `spectrum_to_srgb` and `luminance` in `mitsuba/core/spectrum.h`).
//!
//! Every lookup is Mitsuba's single-precision one: the CIE 1931 2° tables (5 nm apart,
//! 360-830 nm) held as `f32`, the linear sRGB table made from them by Mitsuba's `xyz_to_srgb`
//! matrix in `f32`, linear interpolation between neighbouring entries, zero outside
//! [360, 830] nm. A colour is the mean over the four lanes of the matching functions times the
//! value (a one-sample-per-lane Monte Carlo estimate when the values were divided by the
//! sampling density), times `MI_CIE_Y_NORMALIZATION` so that a unit spectrum has luminance 1.

use std::sync::LazyLock;

use glam::{Vec3, Vec4};

use crate::spectrum::{CIE_SAMPLES, CIE_X, CIE_Y, CIE_Y_NORMALIZATION, CIE_Z};

/// The CIE tables as Mitsuba holds them: `[x̄, ȳ, z̄][entry]`, rounded to `f32`.
static XYZ_TABLE: LazyLock<[[f32; CIE_SAMPLES]; 3]> =
    LazyLock::new(|| [CIE_X, CIE_Y, CIE_Z].map(|t| t.map(|v| v as f32)));

/// Mitsuba's linear sRGB table: its `xyz_to_srgb` (single-precision matrix) applied in `f32`
/// to each entry of the `f32` XYZ table.
static SRGB_TABLE: LazyLock<[[f32; CIE_SAMPLES]; 3]> = LazyLock::new(|| {
    const M: [[f32; 3]; 3] = [
        [3.240479, -1.53715, -0.498535],
        [-0.969256, 1.875991, 0.041556],
        [0.055648, -0.204043, 1.057311],
    ];
    let xyz = &*XYZ_TABLE;
    let mut out = [[0.0; CIE_SAMPLES]; 3];
    for i in 0..CIE_SAMPLES {
        for (row, m) in M.iter().enumerate() {
            out[row][i] = m[0] * xyz[0][i] + m[1] * xyz[1][i] + m[2] * xyz[2][i];
        }
    }
    out
});

/// Table position of a wavelength as Mitsuba computes it in `f32`: entry index and the weights
/// of that entry and the next; `None` outside [360, 830] nm.
#[inline]
fn position(wavelength: f32) -> Option<(usize, f32, f32)> {
    if !(360.0..=830.0).contains(&wavelength) {
        return None;
    }
    // (MI_CIE_SAMPLES - 1) / (MI_CIE_MAX - MI_CIE_MIN), evaluated in f32 as in Mitsuba.
    let t = (wavelength - 360.0) * (94.0_f32 / 470.0_f32);
    let i0 = (t as usize).min(CIE_SAMPLES - 2);
    let w1 = t - i0 as f32;
    Some((i0, 1.0 - w1, w1))
}

/// Linear interpolation in `table` at each of four wavelengths (zero outside the range).
#[inline]
fn lookup(table: &[f32; CIE_SAMPLES], wavelengths: Vec4) -> Vec4 {
    Vec4::from_array(wavelengths.to_array().map(|w| match position(w) {
        None => 0.0,
        Some((i, w0, w1)) => w0 * table[i] + w1 * table[i + 1],
    }))
}

/// The CIE 1931 colour matching functions `[x̄, ȳ, z̄]` at four wavelengths (nm), unnormalised
/// (ȳ peaks at 1 at 555 nm), zero outside [360, 830] nm: Mitsuba's `cie1931_xyz`.
#[inline]
pub fn cie1931_xyz(wavelengths: Vec4) -> [Vec4; 3] {
    let t = &*XYZ_TABLE;
    [
        lookup(&t[0], wavelengths),
        lookup(&t[1], wavelengths),
        lookup(&t[2], wavelengths),
    ]
}

/// ȳ at four wavelengths: Mitsuba's `cie1931_y`.
#[inline]
pub fn cie1931_y(wavelengths: Vec4) -> Vec4 {
    lookup(&XYZ_TABLE[1], wavelengths)
}

/// The linear sRGB (Rec. 709) matching functions `[r̄, ḡ, b̄]` at four wavelengths: Mitsuba's
/// `linear_rgb_rec`, an interpolation in its `xyz_to_srgb`-converted table.
#[inline]
pub fn linear_rgb_rec(wavelengths: Vec4) -> [Vec4; 3] {
    let t = &*SRGB_TABLE;
    [
        lookup(&t[0], wavelengths),
        lookup(&t[1], wavelengths),
        lookup(&t[2], wavelengths),
    ]
}

/// Mean of the four lanes, summed in lane order as Mitsuba's `dr::mean` does.
#[inline]
fn mean(v: Vec4) -> f32 {
    (((v.x + v.y) + v.z) + v.w) / 4.0
}

/// `MI_CIE_Y_NORMALIZATION` as Mitsuba multiplies by it (cast to `f32`).
const Y_NORM: f32 = CIE_Y_NORMALIZATION as f32;

/// CIE XYZ of the values `values` at `wavelengths`: the lane mean of `x̄ȳz̄(λ) · value`, times
/// `MI_CIE_Y_NORMALIZATION` (Mitsuba's `spectrum_to_xyz`).
#[inline]
pub fn spectrum_to_xyz(values: Vec4, wavelengths: Vec4) -> Vec3 {
    let [x, y, z] = cie1931_xyz(wavelengths);
    Vec3::new(mean(x * values), mean(y * values), mean(z * values)) * Y_NORM
}

/// Linear sRGB of the values `values` at `wavelengths`: the lane mean of
/// `r̄ḡb̄(λ) · value`, times `MI_CIE_Y_NORMALIZATION` (Mitsuba's `spectrum_to_srgb`, what its
/// film accumulates in spectral mode for a sample's radiance times its wavelength weights).
#[inline]
pub fn spectrum_to_srgb(values: Vec4, wavelengths: Vec4) -> Vec3 {
    let [r, g, b] = linear_rgb_rec(wavelengths);
    Vec3::new(mean(r * values), mean(g * values), mean(b * values)) * Y_NORM
}

/// Mitsuba's spectral `luminance(value, wavelengths)`: the lane mean of `ȳ(λ) · value`
/// (without `MI_CIE_Y_NORMALIZATION`, as in Mitsuba; Russian roulette and the like use it).
#[inline]
pub fn luminance(values: Vec4, wavelengths: Vec4) -> f32 {
    mean(cie1931_y(wavelengths) * values)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectrum::cie1931_xyz as cie1931_xyz_f64;

    #[test]
    fn table_lookup_agrees_with_the_double_precision_one() {
        // The f64 lookup of src/spectrum.rs interpolates the same f32-rounded entries; the
        // f32 table position t ∈ [0, 94] is off by up to ulp(94)/2 ≈ 3.8e-6, times a table
        // step of at most 0.4 (z̄ near 440 nm): 1.5e-6, plus f32 rounding of the result.
        for i in 0..=470 {
            let w = 360.0 + i as f32;
            let [x, y, z] = cie1931_xyz(Vec4::splat(w));
            let d = cie1931_xyz_f64(w as f64);
            for (a, b) in [(x.x, d.x), (y.x, d.y), (z.x, d.z)] {
                assert!((a as f64 - b).abs() <= 2e-6, "{w}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn zero_outside_the_visible_range() {
        let w = Vec4::new(359.9, 830.1, -1.0, f32::NAN);
        assert_eq!(cie1931_y(w), Vec4::ZERO);
        assert_eq!(spectrum_to_srgb(Vec4::ONE, w), Vec3::ZERO);
    }

    #[test]
    fn luminance_has_no_normalisation() {
        let w = Vec4::splat(555.0);
        assert_eq!(luminance(Vec4::splat(2.0), w), 2.0 * cie1931_y(w).x);
    }
}
