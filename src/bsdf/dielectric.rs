//! Mitsuba's `dielectric`: a smooth interface between two dielectrics (relative IOR
//! η = int_ior / ext_ior), two Dirac-delta lobes: mirror reflection with the Fresnel
//! reflectance F and refraction (Snell's law) with 1 − F, picked with probabilities F and
//! 1 − F so that the weights are `specular_reflectance` and `specular_transmittance`.
//! Two-sided: from inside (cos θi < 0) the relative IOR is 1/η, with total internal
//! reflection.
//!
//! Radiance is not conserved across refraction but radiance / η² is (Veach 1997 §5.2): the
//! transmitted weight carries (η_i / η_t)², as Mitsuba applies in its radiance mode, and the
//! sample reports η_t / η_i so that the path integrator's Russian roulette can undo it.

use super::fresnel::{fresnel_dielectric, refract};
use super::{BsdfSample, Spectrum};
use glam::Vec3;

#[derive(Clone, Debug)]
pub struct Dielectric {
    /// int_ior / ext_ior.
    pub eta: f32,
    pub specular_reflectance: Spectrum,
    pub specular_transmittance: Spectrum,
}

impl Dielectric {
    pub fn eval(&self, _wi: Vec3, _wo: Vec3) -> Spectrum {
        Spectrum::ZERO
    }

    pub fn pdf(&self, _wi: Vec3, _wo: Vec3) -> f32 {
        0.0
    }

    pub fn sample(&self, wi: Vec3, u1: f32) -> Option<BsdfSample> {
        if wi.z == 0.0 || !wi.is_finite() {
            return None;
        }
        let fr = fresnel_dielectric(wi.z, self.eta);
        if u1 < fr.f {
            Some(BsdfSample {
                wo: Vec3::new(-wi.x, -wi.y, wi.z),
                pdf: fr.f,
                weight: self.specular_reflectance,
                eta: 1.0,
                delta: true,
                null: false,
            })
        } else {
            let wo = refract(wi, Vec3::Z, fr.cos_theta_t, fr.eta_ti);
            Some(BsdfSample {
                wo,
                pdf: 1.0 - fr.f,
                weight: self.specular_transmittance * (fr.eta_ti * fr.eta_ti),
                eta: fr.eta_it,
                delta: true,
                null: false,
            })
        }
    }
}
