//! Mitsuba's `volume` texture: a volume (`constvolume`, `gridvolume`) looked up at the shading
//! point's position, in world space, to texture a surface (Mitsuba's `VolumeAdapter`,
//! src/textures/volume.cpp). For surfaces without a useful uv parameterisation, and for solid
//! textures: Mitsuba's tutorial LEGO scene colours its bricks with it.
//!
//! | parameter | type | default |
//! |---|---|---|
//! | `volume` | volume (`constvolume` or `gridvolume`, nested or referenced) | required |
//!
//! The three lookups, as Mitsuba's RGB variants do them:
//! - `eval` (colours): the volume's value, a one-channel grid as grey;
//! - `eval_1` (roughness, weights): a one-channel grid's value, a three-channel grid's
//!   luminance (Mitsuba's `GridVolume::eval_1`), a constant volume's own one-value lookup
//!   (the mean of its colour; a grey's value exactly, as for a constant texture);
//! - `eval_3`: the raw three values.
//!
//! ```xml
//! <texture type="volume" name="reflectance">
//!     <volume type="gridvolume" name="volume">
//!         <string name="filename" value="textures/red.vol"/>
//!     </volume>
//! </texture>
//! ```

use crate::spectrum::luminance_rgb as luminance;
use crate::volume::Volume;
use glam::Vec3;
use std::sync::Arc;

#[derive(Clone, Debug)]
pub struct VolumeTexture {
    /// Shared by every copy of the texture (a grid can be large).
    pub volume: Arc<Volume>,
    /// The one-value lookup of a constant volume.
    constant_scalar: f32,
}

impl VolumeTexture {
    /// A texture looking up `volume`; `constant_scalar` is a constant volume's one-value
    /// lookup (ignored for grids).
    pub fn new(volume: Volume, constant_scalar: f32) -> Self {
        VolumeTexture {
            volume: Arc::new(volume),
            constant_scalar,
        }
    }

    /// The colour at point `p` (camera-relative world space, as the scene is built).
    #[inline]
    pub fn eval(&self, p: Vec3) -> Vec3 {
        self.volume.eval_rgb(p)
    }

    /// The colour at point `p` and `wavelengths` (a spectrum in spectral mode).
    #[inline]
    pub fn eval_spectrum(&self, p: Vec3, wavelengths: glam::Vec4) -> crate::spectrum::Spectrum {
        self.volume.eval(p, wavelengths)
    }

    /// Why spectral mode cannot look the texture up as `lookup` (Mitsuba's `gridvolume`
    /// refuses the same): a three-channel grid converted to spectra looked up as one value
    /// or three raw values, or a `raw` one looked up as a spectrum.
    pub fn spectral_refusal(&self, lookup: super::Lookup) -> Option<String> {
        use super::Lookup;
        match (&*self.volume, lookup) {
            (Volume::Grid(g), Lookup::One | Lookup::Three) if g.is_spectral() => Some(format!(
                "a volume texture is looked up as {} here, but spectral mode converts a three-channel gridvolume into spectra (Mitsuba refuses this lookup too): use a one-channel grid, or raw=\"true\"",
                if lookup == Lookup::One { "one value" } else { "raw RGB (a normal map)" }
            )),
            (Volume::Grid(g), Lookup::Spectrum) if g.channels() == 3 && !g.is_spectral() => Some(
                "a volume texture's gridvolume has raw=\"true\" and three channels: spectral mode cannot look it up as a spectrum (Mitsuba refuses it too); drop raw=\"true\"".into(),
            ),
            _ => None,
        }
    }

    /// One value at point `p`.
    #[inline]
    pub fn eval_1(&self, p: Vec3) -> f32 {
        match &*self.volume {
            Volume::Constant(_) => self.constant_scalar,
            Volume::Grid(g) if g.channels() == 1 => g.eval(p).x,
            Volume::Grid(g) => luminance(g.eval(p)),
        }
    }

    /// The mean over the volume's cells (per channel), for what needs one value of the whole
    /// texture (a BSDF's template, an emitter's power).
    pub fn mean(&self) -> f32 {
        match &*self.volume {
            Volume::Constant(_) => self.constant_scalar,
            Volume::Grid(g) if g.channels() == 1 => g.mean().x,
            Volume::Grid(g) => luminance(g.mean()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::vol::VolData;
    use crate::texture::bitmap::Wrap;
    use crate::volume::GridVolume;
    use glam::Mat4;

    /// A 2x1x1 grid: (0.2, 0.4, 0.6) in the cell x < 0.5 and (1, 0, 0) in the other, nearest
    /// lookups.
    fn grid() -> Volume {
        let data = VolData {
            res: [2, 1, 1],
            channels: 3,
            bbox: [[0.0; 3], [1.0; 3]],
            data: vec![0.2, 0.4, 0.6, 1.0, 0.0, 0.0],
        };
        Volume::Grid(Box::new(
            GridVolume::new(data, Mat4::IDENTITY, false, false, Wrap::Clamp).unwrap(),
        ))
    }

    #[test]
    fn grid_lookups_follow_the_point_and_mitsubas_rules() {
        let t = VolumeTexture::new(grid(), 0.0);
        let a = Vec3::new(0.25, 0.5, 0.5);
        let b = Vec3::new(0.75, 0.5, 0.5);
        assert_eq!(t.eval(a), Vec3::new(0.2, 0.4, 0.6));
        assert_eq!(t.eval(b), Vec3::new(1.0, 0.0, 0.0));
        // eval_1 of a three-channel grid is its luminance (0.212671 r + 0.715160 g + 0.072169 b).
        let lum = 0.212671 * 0.2 + 0.715160 * 0.4 + 0.072169 * 0.6;
        assert!((t.eval_1(a) - lum).abs() < 1e-7, "{}", t.eval_1(a));
        assert!((t.eval_1(b) - 0.212671).abs() < 1e-7);
        let mean = (lum + 0.212671) / 2.0;
        assert!((t.mean() - mean).abs() < 1e-6, "{}", t.mean());
    }

    #[test]
    fn constant_volumes_use_their_one_value_lookup() {
        let v = Volume::constant(Vec3::new(0.1, 0.2, 0.3));
        let t = VolumeTexture::new(v, 0.2);
        assert_eq!(t.eval(Vec3::splat(7.0)), Vec3::new(0.1, 0.2, 0.3));
        assert_eq!(t.eval_1(Vec3::splat(-3.0)), 0.2);
    }
}
