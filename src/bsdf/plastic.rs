//! Mitsuba's `plastic`: a diffuse base under a smooth dielectric coating (relative IOR
//! η = int_ior / ext_ior). Two lobes:
//!
//! - specular: a Dirac-delta mirror reflection at the coating, F(cos θi) · specular_reflectance;
//! - diffuse: light refracted into the coating, scattered by the Lambertian base, possibly
//!   reflected back by the coating many times, and refracted out:
//!   f cos θo = (1 − F(cos θi)) (1 − F(cos θo)) / η² · R' cos θo / π, where the internal
//!   reflections sum to R' = R / (1 − Fdr_int) (the default) or, with `nonlinear`,
//!   R' = R / (1 − R Fdr_int) (the geometric series of bounces between base and coating,
//!   which also shifts colours). Fdr_int is the cosine-weighted average internal Fresnel
//!   reflectance at 1/η (Weidlich and Wilkie 2007, "Arbitrarily Layered Micro-Facet
//!   Surfaces"; Mitsuba's documented plastic model), by the published fits Mitsuba uses
//!   ([`super::fresnel::diffuse_fresnel_reflectance_fit`]).
//!
//! Sampling picks the specular lobe with probability ∝ F(cos θi) · w_s against
//! (1 − F(cos θi)) (1 − w_s), with w_s = mean(specular_reflectance) divided by the sum
//! mean(specular_reflectance) + mean(diffuse_reflectance), as Mitsuba does. eval and pdf
//! cover the diffuse (smooth) lobe only; the delta lobe is reported by `sample` with `delta` set. One-sided.

use super::conductor::SPECULAR_REFLECTANCE;
use super::fresnel::{diffuse_fresnel_reflectance_fit, fresnel_dielectric};
use super::plugin::{ParamKind, ParamSpec, PluginCache, TablePlugin};
use super::{BsdfSample, Spectrum};
use crate::sampling::{square_to_cosine_hemisphere, square_to_cosine_hemisphere_pdf};
use crate::spectrum::{to_rgb, ColorRole};
use glam::DVec3;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// The coating's IORs, `int_ior` (default polypropylene) and `ext_ior`.
pub const IORS: [ParamSpec; 2] = [
    ParamSpec::new(
        "int_ior",
        ParamKind::Ior("polypropylene"),
        1.49,
        "the coating's IOR",
    ),
    ParamSpec::new(
        "ext_ior",
        ParamKind::Ior("air"),
        1.000277,
        "the IOR outside",
    ),
];

/// `diffuse_reflectance`: the base's albedo (default 0.5).
pub const DIFFUSE_REFLECTANCE: ParamSpec = ParamSpec::new(
    "diffuse_reflectance",
    ParamKind::Color(ColorRole::Reflectance),
    0.5,
    "R, the diffuse base's albedo",
);

/// `nonlinear`: the internal reflections' geometric series R / (1 − R Fdr_int).
pub const NONLINEAR: ParamSpec = ParamSpec::new(
    "nonlinear",
    ParamKind::Bool,
    0.0,
    "account for the colour shift of internal reflections",
);

/// `plastic`'s parameters (Mitsuba 3.9.1's names and defaults).
const PARAMS: &[ParamSpec] = &[
    IORS[0],
    IORS[1],
    DIFFUSE_REFLECTANCE,
    SPECULAR_REFLECTANCE,
    NONLINEAR,
];

#[derive(Clone, Debug)]
pub struct Plastic {
    pub eta: f32,
    pub diffuse_reflectance: Spectrum,
    pub specular_reflectance: Spectrum,
    pub nonlinear: bool,
    /// Internal diffuse Fresnel reflectance Fdr(1/η).
    pub fdr_int: f32,
    /// Probability weight of the specular lobe.
    pub specular_sampling_weight: f32,
}

/// w_s = mean(specular) / (mean(specular) + mean(diffuse)); 0.5 if both are black.
pub(super) fn specular_sampling_weight(specular: Spectrum, diffuse: Spectrum) -> f32 {
    let (s, d) = (
        to_rgb(specular).element_sum() / 3.0,
        to_rgb(diffuse).element_sum() / 3.0,
    );
    if s + d > 0.0 {
        s / (s + d)
    } else {
        0.5
    }
}

/// Probability of sampling the specular lobe of a coated BSDF (plastic, roughplastic):
/// ps / (ps + pd) with ps = `specular` · w and pd = `diffuse` · (1 − w), where `specular` is the
/// fraction reflected by the coating at the incident angle and `diffuse` the fraction it lets
/// through, and w is [`specular_sampling_weight`] (Mitsuba's rule).
pub(super) fn specular_lobe_probability(specular: f32, diffuse: f32, weight: f32) -> f32 {
    let ps = specular * weight;
    let pd = diffuse * (1.0 - weight);
    if ps + pd > 0.0 {
        ps / (ps + pd)
    } else {
        0.0
    }
}

/// R' of the diffuse base with internal reflections at the coating.
pub(super) fn diffuse_with_internal_scattering(
    r: Spectrum,
    fdr_int: f32,
    nonlinear: bool,
) -> Spectrum {
    if nonlinear {
        r / (Spectrum::ONE - r * fdr_int)
    } else {
        r / (1.0 - fdr_int)
    }
}

impl Plastic {
    pub fn new(
        eta: f32,
        diffuse_reflectance: Spectrum,
        specular_reflectance: Spectrum,
        nonlinear: bool,
    ) -> Self {
        Plastic {
            eta,
            diffuse_reflectance,
            specular_reflectance,
            nonlinear,
            fdr_int: diffuse_fresnel_reflectance_fit(1.0 / eta as f64) as f32,
            specular_sampling_weight: specular_sampling_weight(
                specular_reflectance,
                diffuse_reflectance,
            ),
        }
    }

    /// Probability of sampling the specular lobe, given F(cos θi).
    fn prob_specular(&self, f_i: f32) -> f32 {
        specular_lobe_probability(f_i, 1.0 - f_i, self.specular_sampling_weight)
    }

    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Spectrum::ZERO;
        }
        let f_i = fresnel_dielectric(wi.z, self.eta).f;
        let f_o = fresnel_dielectric(wo.z, self.eta).f;
        let diff = diffuse_with_internal_scattering(
            self.diffuse_reflectance,
            self.fdr_int,
            self.nonlinear,
        );
        diff * ((1.0 - f_i) * (1.0 - f_o) / (self.eta * self.eta) * FRAC_1_PI * wo.z)
    }

    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let f_i = fresnel_dielectric(wi.z, self.eta).f;
        (1.0 - self.prob_specular(f_i)) * square_to_cosine_hemisphere_pdf(wo)
    }

    pub fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let f_i = fresnel_dielectric(wi.z, self.eta).f;
        let ps = self.prob_specular(f_i);
        if u1 < ps {
            return Some(BsdfSample {
                wo: Vec3::new(-wi.x, -wi.y, wi.z),
                pdf: ps,
                weight: self.specular_reflectance * (f_i / ps),
                eta: 1.0,
                delta: true,
                null: false,
            });
        }
        let wo = square_to_cosine_hemisphere(u2);
        let pdf = (1.0 - ps) * square_to_cosine_hemisphere_pdf(wo);
        BsdfSample::smooth(wo, pdf, || self.eval(wi, wo), 1.0)
    }
}

impl TablePlugin for Plastic {
    const PARAMS: &'static [ParamSpec] = PARAMS;

    fn from_params(v: &[DVec3], _: &mut PluginCache) -> Self {
        Plastic::new(
            (v[0].x / v[1].x) as f32,
            crate::spectrum::from_rgb_f64(v[2]),
            crate::spectrum::from_rgb_f64(v[3]),
            v[4].x != 0.0,
        )
    }
}

impl super::BsdfModel for Plastic {
    const NAME: &'static str = "plastic";

    fn set_param(&mut self, index: usize, v: Spectrum) {
        match index {
            2 => self.diffuse_reflectance = v,
            3 => self.specular_reflectance = v,
            _ => {}
        }
    }

    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        Plastic::eval(self, wi, wo)
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        Plastic::pdf(self, wi, wo)
    }

    #[inline]
    fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        Plastic::sample(self, wi, u1, u2)
    }
}
