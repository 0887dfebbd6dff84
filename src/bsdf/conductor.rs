//! Mitsuba's `conductor`: a perfectly smooth metal, a Dirac-delta mirror reflection weighted
//! by the exact conductor Fresnel reflectance of the complex IOR η + ik (see
//! [`super::fresnel::fresnel_conductor`]) and by `specular_reflectance`. One-sided (front side
//! of the shading frame). With Mitsuba's default `material` "none" (η = 0, k = 1) it is an
//! ideal mirror whose reflectance is exactly `specular_reflectance`.

use super::fresnel::fresnel_conductor;
use super::{BsdfSample, Spectrum};
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Conductor {
    /// Real part of the relative IOR, per channel.
    pub eta: Spectrum,
    /// Imaginary part (absorption), per channel.
    pub k: Spectrum,
    pub specular_reflectance: Spectrum,
}

impl Conductor {
    /// A delta lobe only: the density of any given direction is zero.
    pub fn eval(&self, _wi: Vec3, _wo: Vec3) -> Spectrum {
        Spectrum::ZERO
    }

    pub fn pdf(&self, _wi: Vec3, _wo: Vec3) -> f32 {
        0.0
    }

    pub fn sample(&self, wi: Vec3, _u2: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let f = fresnel_conductor(wi.z, self.eta, self.k);
        Some(BsdfSample {
            wo: Vec3::new(-wi.x, -wi.y, wi.z),
            pdf: 1.0,
            weight: f * self.specular_reflectance,
            eta: 1.0,
            delta: true,
            null: false,
        })
    }
}

impl super::BsdfModel for Conductor {
    const NAME: &'static str = "conductor";

    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        Conductor::eval(self, wi, wo)
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        Conductor::pdf(self, wi, wo)
    }

    #[inline]
    fn sample(&self, wi: Vec3, _u1: f32, u2: Vec2) -> Option<BsdfSample> {
        Conductor::sample(self, wi, u2)
    }

    #[inline]
    fn has_smooth_lobe(&self, _wi: Vec3) -> bool {
        false
    }
}
