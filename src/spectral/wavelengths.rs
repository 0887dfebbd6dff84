//! Wavelength sampling as Mitsuba 3.9.1's spectral variants do it (`sample_wavelength`,
//! `sample_rgb_spectrum`, `pdf_rgb_spectrum` in `mitsuba/core/spectrum.h`).
//!
//! A path carries four wavelengths. One uniform number `u` gives four stratified numbers
//! `frac(u + i/4)` (i = 0..3; a value above 1 wraps by subtracting 1, as Mitsuba's
//! `math::sample_shifted`), and each is mapped through the inverse CDF of the importance
//! spectrum of Radziszewski, Boryczko and Alda, "An Improved Technique for Full Spectral
//! Rendering" (2009): a density proportional to `cosh⁻²(0.0072 (λ − 538))` over
//! [360, 830] nm, which follows the sensitivity of the sRGB colour matching functions.

use glam::Vec4;

// Mitsuba's single-precision literals, written as in its source (each rounded once to f32).
#[allow(clippy::excessive_precision)]
const CDF_OFFSET: f32 = 0.8569106254698279;
#[allow(clippy::excessive_precision)]
const CDF_SLOPE: f32 = 1.8275019724092267;
#[allow(clippy::excessive_precision)]
const INV_RATE: f32 = 138.88888888888889;
#[allow(clippy::excessive_precision)]
const PDF_SCALE: f32 = 0.003939804229326285;

/// Importance-samples one wavelength (nm) from `u` in [0, 1]: returns the wavelength and its
/// weight, the inverse of [`pdf_rgb_spectrum`] there (Mitsuba's `sample_rgb_spectrum`, the same
/// single-precision constants). `u = 0` gives ≈360 nm and `u = 1` ≈830 nm.
#[inline]
pub fn sample_rgb_spectrum(u: f32) -> (f32, f32) {
    let wavelength = 538.0 - (CDF_OFFSET - CDF_SLOPE * u).atanh() * INV_RATE;
    let c = (0.0072_f32 * (wavelength - 538.0)).cosh();
    (wavelength, 253.82_f32 * c * c)
}

/// The density (1/nm) with which [`sample_rgb_spectrum`] draws `wavelength`; zero outside
/// [360, 830] nm (Mitsuba's `pdf_rgb_spectrum`).
#[inline]
pub fn pdf_rgb_spectrum(wavelength: f32) -> f32 {
    if !(360.0..=830.0).contains(&wavelength) {
        return 0.0;
    }
    let r = 1.0 / (0.0072_f32 * (wavelength - 538.0)).cosh();
    PDF_SCALE * r * r
}

/// The four stratified numbers `frac(u + i/4)`, i = 0..3, as Mitsuba's `math::sample_shifted`
/// makes them (a value strictly above 1 has 1 subtracted; exactly 1 stays 1).
#[inline]
pub fn shifted_samples(u: f32) -> Vec4 {
    let shifted = Vec4::splat(u) + Vec4::new(0.0, 0.25, 0.5, 0.75);
    Vec4::select(shifted.cmpgt(Vec4::ONE), shifted - Vec4::ONE, shifted)
}

/// The four wavelengths (nm) of one path and their weights (inverse densities), from one
/// uniform number `u` in [0, 1): Mitsuba's `sample_wavelength` / `Sensor::sample_wavelengths`
/// for a sensor without a spectral response function.
#[inline]
pub fn sample_wavelengths(u: f32) -> (Vec4, Vec4) {
    let s = shifted_samples(u).to_array();
    let mut wavelengths = [0.0; 4];
    let mut weights = [0.0; 4];
    for i in 0..4 {
        (wavelengths[i], weights[i]) = sample_rgb_spectrum(s[i]);
    }
    (Vec4::from_array(wavelengths), Vec4::from_array(weights))
}

/// [`pdf_rgb_spectrum`] of each of four wavelengths.
#[inline]
pub fn pdf_rgb_spectrum4(wavelengths: Vec4) -> Vec4 {
    Vec4::from_array(wavelengths.to_array().map(pdf_rgb_spectrum))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_of_the_range() {
        // The inverse CDF maps [0, 1] onto [360, 830] nm (to single-precision rounding).
        let (lo, _) = sample_rgb_spectrum(0.0);
        let (hi, _) = sample_rgb_spectrum(1.0);
        assert!((lo - 360.0).abs() < 0.05, "{lo}");
        assert!((hi - 830.0).abs() < 0.05, "{hi}");
    }

    #[test]
    fn weight_is_inverse_pdf() {
        for i in 0..=100 {
            let u = i as f32 / 100.0 * 0.999;
            let (w, weight) = sample_rgb_spectrum(u);
            let p = pdf_rgb_spectrum(w.clamp(360.0, 830.0));
            assert!((weight * p - 1.0).abs() < 1e-4, "u {u}: {weight} * {p}");
        }
    }

    #[test]
    fn shifted_wraps_like_mitsuba() {
        let s = shifted_samples(0.3).to_array();
        let u = 0.3_f32;
        assert_eq!(s[..3], [u, u + 0.25, u + 0.5]);
        assert_eq!(s[3], (u + 0.75) - 1.0);
        // Exactly 1 is not wrapped (Mitsuba tests `> 1`).
        assert_eq!(shifted_samples(0.25).to_array()[3], 1.0);
    }
}
