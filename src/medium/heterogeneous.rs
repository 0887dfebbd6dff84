//! Mitsuba's `heterogeneous` medium: extinction σt(p) = `scale` · `sigma_t`(p) and albedo
//! `albedo`(p) from volumes ([`crate::volume`]: grids or constants), tracked against one
//! constant majorant m = `scale` · max(`sigma_t`) over the bounding box of `sigma_t`
//! (outside that box the medium does not interact, as in Mitsuba). Collisions are real with
//! probability mean(σt / m), null (σn = m − σt) otherwise: delta tracking for paths, ratio
//! tracking for shadow rays (Novák et al. 2014).
//!
//! Parameters as [`super::homogeneous`], with `sigma_t` and `albedo` usually `gridvolume`s.
//!
//! In spectral mode the majorant is Mitsuba's too: `scale` times the volume's `max()`, the
//! largest cell scale of a three-channel grid ([`crate::volume::grid`]) and, for a constant
//! `<rgb>` volume, the *mean* of its upsampled spectrum, which lies below the spectrum's peak:
//! there σn is negative at some wavelengths and the null-collision probability mean(σn / m)
//! can fall below zero for a path, as in Mitsuba 3.9.1 (whose references penumbra matches).
//!
//! ```xml
//! <medium type="heterogeneous" id="smoke">
//!     <volume name="sigma_t" type="gridvolume"> <string name="filename" value="smoke.vol"/> </volume>
//!     <rgb name="albedo" value="0.9"/>  <float name="scale" value="5"/>
//! </medium>
//! ```

use crate::geometry::Ray;
use crate::spectrum::Spectrum;
use crate::volume::Volume;
use glam::{Vec3, Vec4};

#[derive(Clone, Debug)]
pub struct Heterogeneous {
    pub sigma_t: Volume,
    pub albedo: Volume,
    pub scale: f32,
    /// `scale` · max(`sigma_t`).
    pub majorant: f32,
    bbox: [Vec3; 2],
}

impl Heterogeneous {
    pub fn new(sigma_t: Volume, albedo: Volume, scale: f32) -> Self {
        let majorant = scale * sigma_t.max();
        let bbox = sigma_t.bbox();
        Heterogeneous {
            sigma_t,
            albedo,
            scale,
            majorant,
            bbox,
        }
    }

    /// (σs, σn, σt) at `p` and `wavelengths`.
    #[inline]
    pub fn coefficients(&self, p: Vec3, wavelengths: Vec4) -> (Spectrum, Spectrum, Spectrum) {
        let sigma_t = self.sigma_t.eval(p, wavelengths) * self.scale;
        let sigma_s = sigma_t * self.albedo.eval(p, wavelengths);
        (sigma_s, Spectrum::splat(self.majorant) - sigma_t, sigma_t)
    }

    /// The slab test of the ray against the box of `sigma_t`: (hit, t_near, t_far), t_near
    /// negative when the ray starts inside.
    #[inline]
    pub fn intersect_aabb(&self, ray: &Ray) -> (bool, f32, f32) {
        let [lo, hi] = self.bbox;
        let mut t0 = f32::NEG_INFINITY;
        let mut t1 = f32::INFINITY;
        for a in 0..3 {
            let o = ray.o[a];
            let d = ray.d[a];
            if d == 0.0 {
                if o < lo[a] || o > hi[a] {
                    return (false, f32::NAN, f32::NAN);
                }
                continue;
            }
            let inv = 1.0 / d;
            let (mut near, mut far) = ((lo[a] - o) * inv, (hi[a] - o) * inv);
            if near > far {
                std::mem::swap(&mut near, &mut far);
            }
            t0 = t0.max(near);
            t1 = t1.min(far);
        }
        (t0 <= t1, t0, t1)
    }
}
