//! Mitsuba's `diffuse`: the Lambertian reflector f = R / π, one-sided (front side of the
//! shading frame only; wrap it in `twosided` for both sides), sampled with a cosine-weighted
//! hemisphere (Malley's method).

use super::plugin::{ParamKind, ParamSpec, PluginCache, TablePlugin};
use super::{BsdfSample, Spectrum};
use crate::sampling::{square_to_cosine_hemisphere, square_to_cosine_hemisphere_pdf};
use crate::spectrum::ColorRole;
use glam::DVec3;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// `diffuse`'s parameters (Mitsuba 3.9.1's names and defaults).
const PARAMS: &[ParamSpec] = &[ParamSpec::new(
    "reflectance",
    ParamKind::Color(ColorRole::Reflectance),
    0.5,
    "R, the albedo",
)];

#[derive(Clone, Debug)]
pub struct Diffuse {
    pub reflectance: Spectrum,
}

impl Diffuse {
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Spectrum::ZERO;
        }
        self.reflectance * (FRAC_1_PI * wo.z)
    }

    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        if wi.z <= 0.0 {
            return 0.0;
        }
        square_to_cosine_hemisphere_pdf(wo)
    }

    pub fn sample(&self, wi: Vec3, u: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let wo = square_to_cosine_hemisphere(u);
        let pdf = square_to_cosine_hemisphere_pdf(wo);
        (pdf > 0.0).then_some(BsdfSample {
            wo,
            pdf,
            weight: self.reflectance,
            eta: 1.0,
            delta: false,
            null: false,
        })
    }
}

impl TablePlugin for Diffuse {
    const PARAMS: &'static [ParamSpec] = PARAMS;

    fn from_params(v: &[DVec3], _: &mut PluginCache) -> Self {
        Diffuse {
            reflectance: crate::spectrum::from_rgb_f64(v[0]),
        }
    }
}

impl super::BsdfModel for Diffuse {
    const NAME: &'static str = "diffuse";

    fn set_param(&mut self, index: usize, v: Spectrum) {
        if index == 0 {
            self.reflectance = v;
        }
    }

    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        Diffuse::eval(self, wi, wo)
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        Diffuse::pdf(self, wi, wo)
    }

    #[inline]
    fn sample(&self, wi: Vec3, _u1: f32, u2: Vec2) -> Option<BsdfSample> {
        Diffuse::sample(self, wi, u2)
    }

    #[inline]
    fn has_smooth_lobe(&self, _wi: Vec3) -> bool {
        true
    }
}
