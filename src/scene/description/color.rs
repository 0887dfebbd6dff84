//! A colour parameter as the scene gave it, kept in the two forms penumbra renders: the RGB
//! triple of Mitsuba's RGB variants and the spectrum of its spectral variants.
//!
//! Mitsuba decides both in `Properties::get_texture_impl` (3.9.1) from the kind of value the
//! file wrote and from how the plugin reads it ([`ColorRole`]); the spectral column is what
//! `--mode spectral` evaluates at each path's wavelengths:
//!
//! | value in the file | role | RGB ([`crate::spectrum`]) | spectral ([`SpectralDesc`]) |
//! |---|---|---|---|
//! | `<float>`, `<integer>` `x` | reflectance, unbounded | `(x, x, x)` | `uniform` x |
//! | `<float>`, `<integer>` `x` | emission | `(x, x, x)` | `d65` of colour `(x, x, x)` |
//! | `<rgb>` `c` | reflectance, unbounded | `c` | `srgb` of `c` (sigmoid upsampling) |
//! | `<rgb>` `c` | emission | `c` | `d65` of colour `c` |
//! | `<spectrum value="v">` | any | see [`crate::spectrum`] | `uniform` v |
//! | `<spectrum>` pairs or `.spd` | any | integrated, see [`crate::spectrum`] | the list, interpolated |
//! | absent, default `d` | emission | `(d, d, d)` | `d65` scaled by d |
//! | absent, default `d` | other | `(d, d, d)` | `uniform` d |

use crate::spectrum::{ColorRole, SpectrumValue};
use glam::DVec3;

/// What Mitsuba's spectral variants make of a colour parameter: a spectrum over wavelength.
#[derive(Clone, Debug, PartialEq)]
pub enum SpectralDesc {
    /// Mitsuba's `srgb`: the sigmoid-polynomial spectrum of an RGB reflectance (Jakob and
    /// Hanika 2019, "A Low-Dimensional Function Space for Efficient Spectral Upsampling").
    Srgb(DVec3),
    /// Mitsuba's `d65` with a `color`: an RGB emission, upsampled at half its largest
    /// component and scaled back, times the CIE D65 illuminant normalised to luminance 1.
    D65(DVec3),
    /// Mitsuba's `d65` with only a `scale`: the normalised D65 illuminant times a number (the
    /// default radiance of an emitter).
    D65Scale(f64),
    /// Mitsuba's `uniform`: `value` at every wavelength in `[lo, hi]` nm, 0 outside.
    Uniform { value: f64, lo: f64, hi: f64 },
    /// Mitsuba's `regular` / `irregular`: wavelength-value pairs, interpolated linearly.
    Sampled(SpectrumValue),
    /// Mitsuba's `blackbody`: Planck's law at `temperature` kelvins in W m⁻² sr⁻¹ nm⁻¹,
    /// inside [`lo`, `hi`] nm, 0 outside (spectral mode only).
    Blackbody { temperature: f64, lo: f64, hi: f64 },
}

impl SpectralDesc {
    /// The same value at every visible wavelength.
    pub fn uniform(value: f64) -> Self {
        SpectralDesc::Uniform {
            value,
            lo: crate::spectrum::CIE_MIN,
            hi: crate::spectrum::CIE_MAX,
        }
    }

    /// What a number `x` given for a parameter read in `role` becomes.
    pub fn number(x: f64, role: ColorRole) -> Self {
        match role {
            ColorRole::Emission => SpectralDesc::D65(DVec3::splat(x)),
            ColorRole::Reflectance | ColorRole::Unbounded => SpectralDesc::uniform(x),
        }
    }

    /// What an `<rgb>` given for a parameter read in `role` becomes.
    pub fn rgb(c: DVec3, role: ColorRole) -> Self {
        match role {
            ColorRole::Emission => SpectralDesc::D65(c),
            ColorRole::Reflectance | ColorRole::Unbounded => SpectralDesc::Srgb(c),
        }
    }

    /// What a `<spectrum>` becomes (the role does not matter to spectral variants).
    pub fn spectrum(s: &SpectrumValue) -> Self {
        match s {
            SpectrumValue::Uniform(v) => SpectralDesc::uniform(*v),
            _ => SpectralDesc::Sampled(s.clone()),
        }
    }

    /// The value of a parameter that was not given and defaults to `d`.
    pub fn default_for(d: f64, role: ColorRole) -> Self {
        match role {
            ColorRole::Emission => SpectralDesc::D65Scale(d),
            ColorRole::Reflectance | ColorRole::Unbounded => SpectralDesc::uniform(d),
        }
    }
}

/// A colour parameter: its RGB-mode value and its spectral-mode spectrum.
#[derive(Clone, Debug, PartialEq)]
pub struct ColorDesc {
    pub rgb: DVec3,
    pub spectral: SpectralDesc,
}

impl ColorDesc {
    /// A parameter that was not given and defaults to `d`, read in `role`.
    pub fn default_for(d: f64, role: ColorRole) -> Self {
        ColorDesc {
            rgb: DVec3::splat(d),
            spectral: SpectralDesc::default_for(d, role),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn emission_numbers_and_colours_are_d65_reflectances_are_not() {
        assert_eq!(
            SpectralDesc::number(2.0, ColorRole::Emission),
            SpectralDesc::D65(DVec3::splat(2.0))
        );
        assert_eq!(
            SpectralDesc::number(0.5, ColorRole::Reflectance),
            SpectralDesc::uniform(0.5)
        );
        let c = DVec3::new(0.1, 0.2, 0.3);
        assert_eq!(
            SpectralDesc::rgb(c, ColorRole::Emission),
            SpectralDesc::D65(c)
        );
        assert_eq!(
            SpectralDesc::rgb(c, ColorRole::Unbounded),
            SpectralDesc::Srgb(c)
        );
        // A uniform <spectrum> stays flat even for an emitter (Mitsuba's `uniform`, not D65).
        assert_eq!(
            SpectralDesc::spectrum(&SpectrumValue::Uniform(3.0)),
            SpectralDesc::uniform(3.0)
        );
        assert_eq!(
            ColorDesc::default_for(1.0, ColorRole::Emission).spectral,
            SpectralDesc::D65Scale(1.0)
        );
    }
}
