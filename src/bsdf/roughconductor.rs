//! Mitsuba's `roughconductor`: the Cook–Torrance microfacet BRDF in the form of Walter,
//! Marschner, Li and Torrance 2007 ("Microfacet Models for Refraction through Rough
//! Surfaces", eq. 20): f(wi, wo) = F(wi·m) D(m) G(wi, wo, m) / (4 |cos θi| |cos θo|) with the
//! half vector m, the exact conductor Fresnel term of η + ik and `specular_reflectance`.
//! Beckmann or GGX, isotropic or anisotropic (see [`super::microfacet`]); sampled by visible
//! normals (default) or by D(m) cos θm, with the reflection Jacobian 1 / (4 |wo·m|)
//! (Walter et al. eq. 14). One-sided.

use super::conductor::{ETA_K, SPECULAR_REFLECTANCE};
use super::fresnel::{fresnel_conductor, reflect};
use super::microfacet::Microfacet;
use super::microfacet::{ALPHA_UV, DISTRIBUTION, SAMPLE_VISIBLE};
use super::plugin::{ParamSpec, PluginCache, TablePlugin};
use super::{BsdfSample, Spectrum};
use glam::DVec3;
use glam::{Vec2, Vec3};

/// `roughconductor`'s parameters (Mitsuba 3.9.1's names and defaults).
const PARAMS: &[ParamSpec] = &[
    DISTRIBUTION,
    ALPHA_UV[0],
    ALPHA_UV[1],
    SAMPLE_VISIBLE,
    ETA_K[0],
    ETA_K[1],
    SPECULAR_REFLECTANCE,
];

#[derive(Clone, Debug)]
pub struct RoughConductor {
    pub distribution: Microfacet,
    pub eta: Spectrum,
    pub k: Spectrum,
    pub specular_reflectance: Spectrum,
}

impl RoughConductor {
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Spectrum::ZERO;
        }
        let Some(m) = (wi + wo).try_normalize() else {
            return Spectrum::ZERO;
        };
        let d = self.distribution.d(m);
        if d == 0.0 {
            return Spectrum::ZERO;
        }
        let g = self.distribution.g_eval(wi, wo, m);
        let f = fresnel_conductor(wi.dot(m), self.eta, self.k);
        let v = (d as f64 * g as f64 / (4.0 * wi.z as f64)) as f32;
        f * self.specular_reflectance * v
    }

    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let Some(m) = (wi + wo).try_normalize() else {
            return 0.0;
        };
        let dot = wo.dot(m);
        if dot <= 0.0 {
            return 0.0;
        }
        let p = self.distribution.pdf(wi, m) as f64 / (4.0 * dot as f64);
        p as f32
    }

    pub fn sample(&self, wi: Vec3, u2: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let (m, pdf_m) = self.distribution.sample(wi, u2)?;
        let wo = reflect(wi, m);
        let dot = wo.dot(m);
        if wo.z <= 0.0 || dot <= 0.0 {
            return None;
        }
        let pdf = (pdf_m as f64 / (4.0 * dot as f64)) as f32;
        BsdfSample::smooth(wo, pdf, || self.eval(wi, wo), 1.0)
    }
}

impl TablePlugin for RoughConductor {
    const PARAMS: &'static [ParamSpec] = PARAMS;

    fn from_params(v: &[DVec3], _: &mut PluginCache) -> Self {
        RoughConductor {
            distribution: Microfacet::from_params(v[0].x, v[1].x, v[2].x, v[3].x),
            eta: crate::spectrum::from_rgb_f64(v[4]),
            k: crate::spectrum::from_rgb_f64(v[5]),
            specular_reflectance: crate::spectrum::from_rgb_f64(v[6]),
        }
    }
}

impl super::BsdfModel for RoughConductor {
    const NAME: &'static str = "roughconductor";

    fn set_param(&mut self, index: usize, v: Spectrum) {
        match index {
            1 => self.distribution.set_alpha_u(v.x),
            2 => self.distribution.set_alpha_v(v.x),
            4 => self.eta = v,
            5 => self.k = v,
            6 => self.specular_reflectance = v,
            _ => {}
        }
    }

    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        RoughConductor::eval(self, wi, wo)
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        RoughConductor::pdf(self, wi, wo)
    }

    #[inline]
    fn sample(&self, wi: Vec3, _u1: f32, u2: Vec2) -> Option<BsdfSample> {
        RoughConductor::sample(self, wi, u2)
    }
}
