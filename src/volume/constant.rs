//! Mitsuba's `constvolume`: one value everywhere (inside and outside its box).
//!
//! | parameter | type | default |
//! |---|---|---|
//! | `value` | rgb, spectrum or float | 1 |
//! | `to_world` | transform (sets only the bounding box) | identity |
//!
//! In spectral mode the value is the parameter's spectrum (an `<rgb>` upsampled as Mitsuba's
//! `srgb` texture, a float or `<spectrum>` kept as such), and its largest value
//! ([`ConstVolume::max`], the majorant of a heterogeneous medium) is what Mitsuba's texture
//! `max()` returns: for an upsampled colour the *mean* of its spectrum over the visible
//! range (`srgb_model_mean`), for a list its largest entry.
//!
//! ```xml
//! <volume type="constvolume" name="sigma_t"> <rgb name="value" value="0.5, 0.4, 0.3"/> </volume>
//! ```

use crate::texture::ColorValue;
use glam::{Mat4, Vec3};

#[derive(Clone, Debug)]
pub struct ConstVolume {
    pub value: ColorValue,
    /// The largest value (see the module's documentation).
    pub max: f32,
    pub bbox: [Vec3; 2],
}

impl ConstVolume {
    pub fn new(value: ColorValue, to_world: Mat4) -> Self {
        ConstVolume {
            max: value_max(&value),
            value,
            bbox: super::unit_cube_bbox(&to_world),
        }
    }
}

/// Mitsuba's `Texture::max()` of a constant colour.
fn value_max(v: &ColorValue) -> f32 {
    use crate::spectral::PreparedSpectrum;
    match v {
        ColorValue::Rgb(s) => crate::spectrum::to_rgb(*s).max_element(),
        ColorValue::Srgb(c) => crate::spectral::srgb_model_mean(*c),
        ColorValue::Uniform { value, .. } => *value,
        ColorValue::Sampled(p) => match &**p {
            PreparedSpectrum::Uniform(v) => *v,
            PreparedSpectrum::Regular { values, .. }
            | PreparedSpectrum::Irregular { values, .. } => {
                values.iter().copied().fold(0.0, f32::max)
            }
        },
        // An emission spectrum is never a volume's value; its largest value at 5 nm steps.
        ColorValue::D65(_) | ColorValue::Blackbody { .. } => {
            let mut m = 0.0f32;
            for k in 0..95 {
                m = m.max(v.eval(glam::Vec4::splat(360.0 + 5.0 * k as f32)).x);
            }
            m
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::description::SpectralDesc;
    use crate::spectrum::SpectrumValue;

    /// The majorant-relevant largest value: RGB mode the largest channel; spectral mode
    /// Mitsuba's `max()`: an upsampled colour's mean over the range (below its peak), a
    /// uniform value itself, a list's largest entry.
    #[test]
    fn the_largest_value_is_mitsubas_max_in_each_mode() {
        let rgb = ConstVolume::new(
            ColorValue::Rgb(crate::spectrum::rgb(0.5, 0.4, 0.3)),
            Mat4::IDENTITY,
        );
        assert_eq!(rgb.max, 0.5);
        let c = crate::spectral::srgb_model_fetch([0.5, 0.4, 0.3]);
        let srgb = ConstVolume::new(ColorValue::Srgb(c), Mat4::IDENTITY);
        assert_eq!(srgb.max, crate::spectral::srgb_model_mean(c));
        let peak = (0..95)
            .map(|k| {
                crate::spectral::srgb_model_eval(c, glam::Vec4::splat(360.0 + 5.0 * k as f32)).x
            })
            .fold(0.0, f32::max);
        assert!(srgb.max < peak, "{} vs peak {peak}", srgb.max);
        let list = SpectrumValue::sampled(vec![400.0, 500.0, 600.0], vec![0.2, 0.7, 0.4]).unwrap();
        let list = ConstVolume::new(
            ColorValue::spectral(&SpectralDesc::Sampled(list)),
            Mat4::IDENTITY,
        );
        assert_eq!(list.max, 0.7);
    }
}
