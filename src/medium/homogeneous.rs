//! Mitsuba's `homogeneous` medium: the same extinction σt = `scale` · `sigma_t` everywhere
//! and scattering albedo `albedo` (σs = σt · albedo). σt is its own majorant, so sampled
//! collisions are always real; with RGB σt the distance is sampled in one channel per path
//! and weighed by the other channels' transmittance (Mitsuba's RGB mode).
//!
//! | parameter | type | default |
//! |---|---|---|
//! | `sigma_t` | rgb, float or volume | 1 |
//! | `albedo` | rgb, float or volume | 0.75 |
//! | `scale` | float | 1 |
//! | `sample_emitters` | boolean | true |
//! | `has_spectral_extinction` | boolean (accepted; the spectral code path serves both) | true |
//! | `<phase>` | phase function | isotropic |
//!
//! ```xml
//! <medium type="homogeneous" id="fog">
//!     <rgb name="sigma_t" value="1, 0.5, 0.25"/>  <rgb name="albedo" value="0.9"/>
//!     <phase type="hg"> <float name="g" value="0.7"/> </phase>
//! </medium>
//! ```

use crate::spectrum::Spectrum;
use crate::volume::Volume;
use glam::{Vec3, Vec4};

#[derive(Clone, Debug)]
pub struct Homogeneous {
    pub sigma_t: Volume,
    pub albedo: Volume,
    pub scale: f32,
}

impl Homogeneous {
    #[inline]
    pub fn sigma_t(&self, p: Vec3, wavelengths: Vec4) -> Spectrum {
        self.sigma_t.eval(p, wavelengths) * self.scale
    }

    /// (σs, σn, σt) at `p` and `wavelengths`.
    #[inline]
    pub fn coefficients(&self, p: Vec3, wavelengths: Vec4) -> (Spectrum, Spectrum, Spectrum) {
        let sigma_t = self.sigma_t(p, wavelengths);
        (
            sigma_t * self.albedo.eval(p, wavelengths),
            Spectrum::ZERO,
            sigma_t,
        )
    }
}
