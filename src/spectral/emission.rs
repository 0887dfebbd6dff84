//! Emitted spectra as Mitsuba 3.9.1's spectral variants make them from RGB or from a scale:
//! its `d65` spectrum plugin (`src/spectra/d65.cpp`), which an emitter's `radiance`,
//! `intensity` or `irradiance` becomes when given as an RGB colour or a plain number, and the
//! `uniform` plugin (a `<spectrum value="v"/>`).
//!
//! `d65` with a colour: the colour is divided by twice its largest component (so that the
//! largest is ½, where the sigmoid-polynomial fit of Jakob and Hanika 2019 gives smooth
//! spectra), the divisor goes into the scale, and the emitted spectrum is
//! `scale · D65(λ) · S(λ)` with `S` the upsampled normalised colour
//! ([`srgb_model_fetch`](super::srgb_model_fetch)) and `D65` the CIE illuminant normalised to
//! luminance 1, held as Mitsuba holds it: a 95-entry `regular` spectrum whose entries are
//! `d65 · scale · MI_CIE_D65_NORMALIZATION` computed in double precision and stored as f32,
//! interpolated linearly in f32 and zero outside [360, 830] nm. Without a colour (an emitter's
//! default radiance of 1, or `<spectrum type="d65">`) the spectrum is `scale · D65(λ)`.

use glam::Vec4;

use super::upsample::{srgb_model_eval, srgb_model_fetch, Coefficients};
use crate::spectrum::{CIE_SAMPLES, D65, D65_NORMALIZATION};

/// A D65-based emission spectrum (Mitsuba's `d65` plugin in a spectral variant).
#[derive(Clone, Debug, PartialEq)]
pub struct D65Emission {
    /// `d65[i] · scale · MI_CIE_D65_NORMALIZATION`, rounded to f32.
    table: [f32; CIE_SAMPLES],
    /// The upsampled normalised colour, if a colour was given.
    coefficients: Option<Coefficients>,
}

impl D65Emission {
    /// `scale · D65(λ)`, no colour (Mitsuba's `d65` with only `scale`).
    pub fn new(scale: f32) -> Self {
        Self {
            table: D65.map(|d| (d as f64 * scale as f64 * D65_NORMALIZATION) as f32),
            coefficients: None,
        }
    }

    /// An RGB emission `color` (linear sRGB, any non-negative size) times `scale`, as Mitsuba's
    /// `d65` plugin with `color` builds it: `color` over twice its largest component,
    /// upsampled, and the factor moved into the scale. A black colour gives zero emission.
    pub fn from_rgb(color: [f32; 3], scale: f32) -> Self {
        let factor = color[0].max(color[1]).max(color[2]) * 2.0;
        let (color, scale) = if factor != 0.0 {
            (color.map(|c| c / factor), scale * factor)
        } else {
            (color, scale)
        };
        Self {
            coefficients: Some(srgb_model_fetch(color)),
            ..Self::new(scale)
        }
    }

    /// The emitted spectrum at four wavelengths (nm).
    #[inline]
    pub fn eval(&self, wavelengths: Vec4) -> Vec4 {
        let d65 = Vec4::from_array(wavelengths.to_array().map(|w| self.d65_at(w)));
        match self.coefficients {
            Some(c) => d65 * srgb_model_eval(c, wavelengths),
            None => d65,
        }
    }

    /// The scaled D65 table at one wavelength: Mitsuba's `regular` spectrum lookup over
    /// [360, 830] nm (interval 470/94 nm, its reciprocal in f32).
    #[inline]
    fn d65_at(&self, w: f32) -> f32 {
        if !(360.0..=830.0).contains(&w) {
            return 0.0;
        }
        let inv_interval = 1.0 / (470.0_f64 / 94.0) as f32;
        let x = (w - 360.0) * inv_interval;
        let i = (x as usize).min(CIE_SAMPLES - 2);
        let w1 = x - i as f32;
        (1.0 - w1) * self.table[i] + w1 * self.table[i + 1]
    }

    /// The upsampling coefficients of the normalised colour (`None` without a colour).
    pub fn coefficients(&self) -> Option<Coefficients> {
        self.coefficients
    }
}

/// A uniform spectrum (`<spectrum value="v"/>`, Mitsuba's `uniform` plugin): `v` at every
/// wavelength, inside or outside the visible range.
#[inline]
pub fn uniform(value: f32) -> Vec4 {
    Vec4::splat(value)
}

/// Planck's law: the spectral radiance of a black body at `temperature` kelvins, in
/// W m⁻² sr⁻¹ nm⁻¹, at four `wavelengths` (nm), as Mitsuba 3.9.1's `blackbody` spectrum
/// computes it in single precision: 2hc² / (λ⁵ (exp(hc / (λ k T)) − 1)) · 10⁻⁹ with λ in
/// metres and CODATA 2014's h, c, k (Mitsuba's constants).
pub fn blackbody(wavelengths: Vec4, temperature: f32) -> Vec4 {
    const C: f32 = 2.997_924_5e8;
    const H: f32 = 6.626_07e-34;
    const K: f32 = 1.380_648_6e-23;
    const C0: f32 = 2.0 * H * C * C;
    const C1: f32 = H * C / K;
    let lambda = wavelengths * 1e-9;
    let lambda2 = lambda * lambda;
    let lambda5 = lambda2 * lambda2 * lambda;
    let e = Vec4::new(
        (C1 / (lambda.x * temperature)).exp(),
        (C1 / (lambda.y * temperature)).exp(),
        (C1 / (lambda.z * temperature)).exp(),
        (C1 / (lambda.w * temperature)).exp(),
    );
    Vec4::splat(1e-9 * C0) / (lambda5 * (e - Vec4::ONE))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectrum::cie_d65;

    #[test]
    fn d65_table_agrees_with_the_double_lookup() {
        let e = D65Emission::new(1.0);
        for i in 0..=470 {
            let w = 360.0 + i as f32;
            let got = e.eval(Vec4::splat(w)).x as f64;
            let want = cie_d65(w as f64);
            assert!((got - want).abs() < 1e-6 * want, "{w}: {got} vs {want}");
        }
        assert_eq!(e.eval(Vec4::splat(830.5)), Vec4::ZERO);
    }

    #[test]
    fn grey_emission_is_scaled_d65() {
        // A grey (v, v, v) becomes (½, ½, ½) times 2v: exactly flat ½ from the closed form.
        let e = D65Emission::from_rgb([3.0; 3], 1.0);
        let d = D65Emission::new(3.0);
        let w = Vec4::new(400.0, 500.0, 600.0, 700.0);
        let (a, b) = (e.eval(w), d.eval(w));
        for k in 0..4 {
            assert!((a[k] - b[k]).abs() <= 1e-6 * b[k], "{a} vs {b}");
        }
        assert_eq!(D65Emission::from_rgb([0.0; 3], 5.0).eval(w), Vec4::ZERO);
    }

    /// Planck's law against its f64 form and against Mitsuba 3.9.1's `blackbody` (5000 K,
    /// scalar_spectral, `eval` at 400, 500, 600, 700 nm: 8743.57, 12107.2, 12762.4, 11812).
    #[test]
    fn blackbody_is_plancks_law_as_mitsuba_evaluates_it() {
        let wl = Vec4::new(400.0, 500.0, 600.0, 700.0);
        let got = blackbody(wl, 5000.0);
        let (h, c, k) = (6.62607004e-34f64, 2.99792458e8f64, 1.38064852e-23f64);
        for (i, mitsuba) in [8743.57f32, 12107.2, 12762.4, 11812.0]
            .into_iter()
            .enumerate()
        {
            let l = wl[i] as f64 * 1e-9;
            let planck =
                2.0 * h * c * c / (l.powi(5) * ((h * c / (l * k * 5000.0)).exp() - 1.0)) * 1e-9;
            assert!(
                (got[i] as f64 / planck - 1.0).abs() < 2e-6,
                "{} vs {planck}",
                got[i]
            );
            assert!(
                (got[i] / mitsuba - 1.0).abs() < 1e-5,
                "{} vs Mitsuba {mitsuba}",
                got[i]
            );
        }
    }
}
