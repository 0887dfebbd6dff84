//! Spectral maths as Mitsuba 3.9.1's `*_spectral` variants do it: a path carries four
//! wavelengths and four values (`glam::Vec4`), RGB reflectances become smooth spectra by the
//! sigmoid-polynomial model of Jakob and Hanika (2019), RGB emission becomes a D65-weighted
//! spectrum, and the four values become a colour through the CIE 1931 matching functions.
//! Nothing here renders; the integrators, textures, emitters and film call it.
//!
//! | function | Mitsuba 3.9.1 | what it does |
//! |---|---|---|
//! | [`sample_wavelengths`] | `sample_wavelength` | four stratified wavelengths (nm) and weights from one number |
//! | [`sample_rgb_spectrum`], [`pdf_rgb_spectrum`] | same names | one wavelength from the cosh⁻² importance spectrum (Radziszewski et al. 2009), its density |
//! | [`spectrum_to_srgb`], [`spectrum_to_xyz`] | same names | four values at four wavelengths → linear sRGB / XYZ |
//! | [`luminance`], [`cie1931_y`], [`cie1931_xyz`] | same names | luminance of four values; the matching functions |
//! | [`srgb_model_fetch`] | `srgb_model_fetch` | sRGB reflectance → 3 coefficients (penumbra's own fitted table, see [`upsample`]) |
//! | [`srgb_model_eval`], [`srgb_model_mean`] | same names | the upsampled spectrum at four wavelengths; its mean (`eval_1`) |
//! | [`D65Emission`] | `d65` plugin | RGB (or scale-only) emission × normalised D65 |
//! | [`uniform`] | `uniform` plugin | a constant spectrum |
//! | [`eval_spectrum_value`], [`PreparedSpectrum`] | `regular` / `irregular` plugins | a `<spectrum>` list at four wavelengths |
//!
//! Single precision throughout, in Mitsuba's order of operations, except the coefficient fit
//! ([`fit`]), which is penumbra's own (double precision) and is checked against the values
//! Mitsuba's upsampling produces in `tests/spectral.rs`.

mod convert;
mod emission;
pub mod fit;
mod list;
pub mod upsample;
mod wavelengths;

pub use convert::{
    cie1931_xyz, cie1931_y, linear_rgb_rec, luminance, spectrum_to_srgb, spectrum_to_xyz,
};
pub use emission::{blackbody, uniform, D65Emission};
pub use list::{eval_spectrum_value, PreparedSpectrum};
pub use upsample::{
    scaled_coefficients, scaled_coefficients_with, srgb_model_eval, srgb_model_fetch,
    srgb_model_mean, Coefficients,
};
pub use wavelengths::{
    pdf_rgb_spectrum, pdf_rgb_spectrum4, sample_rgb_spectrum, sample_wavelengths, shifted_samples,
};
