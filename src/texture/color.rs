//! A colour that does not vary over a surface, in the form the render's [`Mode`] evaluates:
//! the (R, G, B, G) lanes in RGB mode, a spectrum evaluated at the path's four wavelengths in
//! spectral mode (Mitsuba's `srgb`, `d65`, `uniform`, `regular`/`irregular` plugins of its
//! `*_spectral` variants; see [`crate::scene::description::SpectralDesc`]).

use crate::scene::description::{ColorDesc, SpectralDesc};
use crate::spectral::{self, Coefficients, D65Emission, PreparedSpectrum};
use crate::spectrum::{from_rgb_f64, Mode, Spectrum};
use glam::Vec4;

/// A constant colour, ready to be evaluated.
#[derive(Clone, Debug, PartialEq)]
pub enum ColorValue {
    /// RGB mode: the value, whatever the wavelengths.
    Rgb(Spectrum),
    /// Mitsuba's `srgb`: the sigmoid-polynomial spectrum of these coefficients.
    Srgb(Coefficients),
    /// Mitsuba's `d65`: a D65-weighted emission.
    D65(Box<D65Emission>),
    /// Mitsuba's `uniform`: `value` inside [`lo`, `hi`] nm, 0 outside.
    Uniform { value: f32, lo: f32, hi: f32 },
    /// Mitsuba's `regular` / `irregular`: a wavelength list.
    Sampled(Box<PreparedSpectrum>),
    /// Mitsuba's `blackbody`: Planck's law at `temperature` K inside [`lo`, `hi`] nm.
    Blackbody { temperature: f32, lo: f32, hi: f32 },
}

impl ColorValue {
    /// The colour parameter `c` as `mode` renders it.
    pub fn new(c: &ColorDesc, mode: Mode) -> Self {
        match mode {
            Mode::Rgb => ColorValue::Rgb(from_rgb_f64(c.rgb)),
            Mode::Spectral => Self::spectral(&c.spectral),
        }
    }

    /// The spectrum `s` (spectral mode).
    pub fn spectral(s: &SpectralDesc) -> Self {
        let rgb32 = |c: glam::DVec3| [c.x as f32, c.y as f32, c.z as f32];
        match s {
            SpectralDesc::Srgb(c) => ColorValue::Srgb(spectral::srgb_model_fetch(rgb32(*c))),
            SpectralDesc::D65(c) => {
                ColorValue::D65(Box::new(D65Emission::from_rgb(rgb32(*c), 1.0)))
            }
            SpectralDesc::D65Scale(s) => ColorValue::D65(Box::new(D65Emission::new(*s as f32))),
            SpectralDesc::Uniform { value, lo, hi } => ColorValue::Uniform {
                value: *value as f32,
                lo: *lo as f32,
                hi: *hi as f32,
            },
            SpectralDesc::Sampled(v) => ColorValue::Sampled(Box::new(PreparedSpectrum::new(v))),
            SpectralDesc::Blackbody {
                temperature,
                lo,
                hi,
            } => ColorValue::Blackbody {
                temperature: *temperature as f32,
                lo: *lo as f32,
                hi: *hi as f32,
            },
        }
    }

    /// The value at `wavelengths` (nm; ignored in RGB mode).
    #[inline]
    pub fn eval(&self, wavelengths: Vec4) -> Spectrum {
        match self {
            ColorValue::Rgb(s) => *s,
            ColorValue::Srgb(c) => spectral::srgb_model_eval(*c, wavelengths),
            ColorValue::D65(d) => d.eval(wavelengths),
            ColorValue::Uniform { value, lo, hi } => Vec4::select(
                wavelengths.cmpge(Vec4::splat(*lo)) & wavelengths.cmple(Vec4::splat(*hi)),
                Vec4::splat(*value),
                Vec4::ZERO,
            ),
            ColorValue::Sampled(s) => s.eval(wavelengths),
            ColorValue::Blackbody {
                temperature,
                lo,
                hi,
            } => Vec4::select(
                wavelengths.cmpge(Vec4::splat(*lo)) & wavelengths.cmple(Vec4::splat(*hi)),
                spectral::blackbody(wavelengths, *temperature),
                Vec4::ZERO,
            ),
        }
    }

    /// Whether the value is the same at every wavelength (RGB mode, or a uniform spectrum
    /// over the whole visible range), so that it can be evaluated once.
    pub fn is_constant(&self) -> bool {
        match self {
            ColorValue::Rgb(_) => true,
            ColorValue::Uniform { lo, hi, .. } => {
                *lo <= crate::spectrum::CIE_MIN as f32 && *hi >= crate::spectrum::CIE_MAX as f32
            }
            _ => false,
        }
    }

    /// The mean that a one-value lookup (`eval_1`) of the colour returns in spectral mode:
    /// Mitsuba's `mean()` of the spectrum plugins (the spectrum's mean over the visible
    /// range for `srgb`, the value for `uniform`); `None` where Mitsuba has no such mean and
    /// the RGB-mode value stands.
    pub fn spectral_mean(&self) -> Option<f32> {
        match self {
            ColorValue::Srgb(c) => Some(spectral::srgb_model_mean(*c)),
            ColorValue::Uniform { value, .. } => Some(*value),
            _ => None,
        }
    }

    /// The mean value, for estimates of an emitter's power (which only decide how often it
    /// is chosen): in RGB mode the mean of R, G, B (in f64, as before), in spectral mode the
    /// mean over 360..830 nm at 5 nm steps.
    pub fn mean_for_power(&self) -> f64 {
        match self {
            ColorValue::Rgb(s) => (s.x as f64 + s.y as f64 + s.z as f64) / 3.0,
            _ => {
                let mut sum = 0.0;
                for k in 0..24 {
                    // 4 wavelengths at a time: 96 points from 360 nm in 5 nm steps (the
                    // last one, 835 nm, outside the range and weighted out below)
                    let w = Vec4::new(0.0, 5.0, 10.0, 15.0) + (360.0 + 20.0 * k as f32);
                    let v = self.eval(w);
                    let inside = w.cmple(Vec4::splat(830.0));
                    sum += Vec4::select(inside, v, Vec4::ZERO).element_sum() as f64;
                }
                sum / 95.0
            }
        }
    }
}
