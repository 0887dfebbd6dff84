//! `<spectrum>` wavelength lists evaluated at a path's wavelengths, as Mitsuba 3.9.1's spectral
//! variants do: a list becomes a `regular` spectrum when its wavelengths are evenly spaced
//! (every gap within 1e-3 of the first one, Mitsuba's `Properties::Spectrum` test) and an
//! `irregular` one otherwise (`src/spectra/{regular,irregular}.cpp`). Both hold the values in
//! f32 and interpolate linearly; outside [first, last wavelength] the value is zero (the list is
//! not extended). A uniform value is the same at every wavelength.
//!
//! The regular form interpolates by index over [first, last], so a list that is only nearly
//! evenly spaced is read as if it were exactly so, as in Mitsuba.
//!
//! Mitsuba additionally refuses, in spectral variants, a list with a negative value or with
//! only zeros (its `ContinuousDistribution` checks); the evaluator does not check this.

use glam::Vec4;

use crate::spectrum::SpectrumValue;

/// A parsed spectrum prepared for evaluation at wavelengths (f32 data, regularity decided).
#[derive(Clone, Debug, PartialEq)]
pub enum PreparedSpectrum {
    /// The same value everywhere.
    Uniform(f32),
    /// Evenly spaced: values over [`min`, `max`] nm.
    Regular {
        /// First wavelength (nm).
        min: f32,
        /// Last wavelength (nm).
        max: f32,
        /// 1 / (gap between entries), as Mitsuba computes it (f64 gap, f32 reciprocal).
        inv_interval: f32,
        /// Values at the evenly spaced wavelengths.
        values: Vec<f32>,
    },
    /// Arbitrary increasing wavelengths.
    Irregular {
        /// Wavelengths (nm), increasing.
        wavelengths: Vec<f32>,
        /// Values at those wavelengths.
        values: Vec<f32>,
    },
}

/// Whether Mitsuba's `Properties::Spectrum` counts these wavelengths as evenly spaced.
fn is_regular(wavelengths: &[f64]) -> bool {
    let gap = wavelengths[1] - wavelengths[0];
    wavelengths
        .windows(2)
        .all(|w| ((w[1] - w[0]) - gap).abs() <= 1e-3 * gap)
}

impl PreparedSpectrum {
    /// Prepares a parsed `<spectrum>`. A list with fewer than two entries or mismatched lengths
    /// (impossible through [`SpectrumValue::sampled`]) is zero everywhere.
    pub fn new(spectrum: &SpectrumValue) -> Self {
        match spectrum {
            SpectrumValue::Uniform(v) => Self::Uniform(*v as f32),
            SpectrumValue::Sampled {
                wavelengths,
                values,
            } => {
                if wavelengths.len() < 2 || wavelengths.len() != values.len() {
                    return Self::Uniform(0.0);
                }
                let values32 = values.iter().map(|&v| v as f32).collect();
                if is_regular(wavelengths) {
                    let (min, max) = (
                        wavelengths[0] as f32,
                        wavelengths[wavelengths.len() - 1] as f32,
                    );
                    let interval = (max as f64 - min as f64) / (values.len() - 1) as f64;
                    Self::Regular {
                        min,
                        max,
                        inv_interval: 1.0 / interval as f32,
                        values: values32,
                    }
                } else {
                    Self::Irregular {
                        wavelengths: wavelengths.iter().map(|&w| w as f32).collect(),
                        values: values32,
                    }
                }
            }
        }
    }

    /// The value at one wavelength (nm).
    pub fn eval1(&self, w: f32) -> f32 {
        match self {
            Self::Uniform(v) => *v,
            Self::Regular {
                min,
                max,
                inv_interval,
                values,
            } => {
                if !(*min..=*max).contains(&w) {
                    return 0.0;
                }
                let x = (w - min) * inv_interval;
                let i = (x as usize).min(values.len() - 2);
                let w1 = x - i as f32;
                (1.0 - w1) * values[i] + w1 * values[i + 1]
            }
            Self::Irregular {
                wavelengths,
                values,
            } => {
                let n = wavelengths.len();
                if !(wavelengths[0]..=wavelengths[n - 1]).contains(&w) {
                    return 0.0;
                }
                // The interval [x_i, x_{i+1}] with x_i < w <= x_{i+1} (the first one at w = x_0).
                let i = wavelengths.partition_point(|&x| x < w).clamp(1, n - 1) - 1;
                let (x0, x1) = (wavelengths[i], wavelengths[i + 1]);
                let t = (w - x0) / (x1 - x0);
                t * (values[i + 1] - values[i]) + values[i]
            }
        }
    }

    /// The values at four wavelengths (nm).
    pub fn eval(&self, wavelengths: Vec4) -> Vec4 {
        Vec4::from_array(wavelengths.to_array().map(|w| self.eval1(w)))
    }
}

/// `spectrum` at four wavelengths (nm), as Mitsuba's spectral variants evaluate a `<spectrum>`
/// (uniform, `regular` or `irregular`). Prepares the spectrum on each call: for repeated use,
/// keep a [`PreparedSpectrum`].
pub fn eval_spectrum_value(spectrum: &SpectrumValue, wavelengths: Vec4) -> Vec4 {
    PreparedSpectrum::new(spectrum).eval(wavelengths)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn list(pairs: &[(f64, f64)]) -> SpectrumValue {
        SpectrumValue::sampled(
            pairs.iter().map(|p| p.0).collect(),
            pairs.iter().map(|p| p.1).collect(),
        )
        .expect("valid list")
    }

    #[test]
    fn regular_and_irregular_interpolate_linearly_and_vanish_outside() {
        let reg = list(&[(400.0, 0.2), (500.0, 0.6), (600.0, 0.4)]);
        let irr = list(&[(400.0, 0.2), (450.0, 0.6), (600.0, 0.4)]);
        assert!(matches!(
            PreparedSpectrum::new(&reg),
            PreparedSpectrum::Regular { .. }
        ));
        assert!(matches!(
            PreparedSpectrum::new(&irr),
            PreparedSpectrum::Irregular { .. }
        ));
        let w = Vec4::new(399.0, 400.0, 475.0, 600.0);
        let r = eval_spectrum_value(&reg, w);
        assert_eq!(r.x, 0.0);
        assert!((r.y - 0.2).abs() < 1e-7 && (r.z - 0.5).abs() < 1e-6 && (r.w - 0.4).abs() < 1e-7);
        let i = eval_spectrum_value(&irr, w);
        assert_eq!(i.x, 0.0);
        let want = 0.6 + (475.0 - 450.0) / 150.0 * (0.4 - 0.6);
        assert!((i.z - want as f32).abs() < 1e-6, "{i}");
        assert!((i.w - 0.4).abs() < 1e-7);
        assert_eq!(eval_spectrum_value(&irr, Vec4::splat(600.1)), Vec4::ZERO);
    }

    #[test]
    fn uniform_is_everywhere() {
        let u = SpectrumValue::Uniform(0.25);
        assert_eq!(
            eval_spectrum_value(&u, Vec4::new(100.0, 500.0, 900.0, 0.0)),
            Vec4::splat(0.25)
        );
    }

    #[test]
    fn nearly_even_spacing_counts_as_regular() {
        // Gaps 100 and 100.05 (within 1e-3 of 100): regular, interpolated by index.
        let s = list(&[(400.0, 0.0), (500.0, 1.0), (600.05, 0.0)]);
        assert!(matches!(
            PreparedSpectrum::new(&s),
            PreparedSpectrum::Regular { .. }
        ));
    }
}
